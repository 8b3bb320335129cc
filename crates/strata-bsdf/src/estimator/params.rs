//! Parameter sets: the numbers of stacks of one shape, for queries that do
//! not all use the engine's own.
//!
//! An engine is built for a stack's shape ([`crate::stack::Shape`]) and
//! keeps that stack's numbers splatted over its lanes. A call may instead
//! give each query a parameter set: a [`SetTable`] holds the sets' numbers
//! in one-lane form, and a chunk of lanes gathers each lane's numbers from
//! its query's set ([`LaneSets`]), or splats them when every lane of the
//! chunk has the same set. The kinds and flags (smooth, dielectric, a
//! layer's class, grey) come from the engine's own lanes: they are the
//! shape's, the same in every set.

use super::closed_form::SmoothCoatLambertian;
use super::layout::MediumLanes;
use super::Settings;
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, LaneMask, Rgb, MAX_LANES};
use crate::microfacet::Microfacet;
use crate::stack::LayerStack;

/// The numbers of several stacks of one shape, in one-lane form.
#[derive(Clone, Debug, Default)]
pub struct SetTable {
    /// Interfaces per set.
    n: usize,
    /// Set `s`, interface `i` at `s * n + i`.
    ifaces: Vec<InterfaceLanes<f32>>,
    /// Set `s`, layer `l` at `s * (n - 1) + l`, as the stack has them.
    media: Vec<MediumLanes<f32>>,
    /// Per set: the exact part of eval that the walks leave out, when the
    /// control variate is on for it.
    cv: Vec<Option<SmoothCoatLambertian>>,
}

impl SetTable {
    /// An empty table for stacks of `n` interfaces.
    pub fn new(n: usize) -> Self {
        SetTable {
            n,
            ..Self::default()
        }
    }

    /// Adds `stack` (of the table's shape) as the next set; with
    /// `control_variate`, eval walks of its queries leave out what
    /// [`SmoothCoatLambertian::unscattered`] holds (where the stack has it).
    pub fn push(&mut self, stack: &LayerStack, settings: &Settings, control_variate: bool) {
        debug_assert_eq!(stack.len(), self.n);
        let n = self.n;
        self.ifaces
            .extend((0..n).map(|i| stack.interface_lanes::<f32>(i)));
        self.media
            .extend((0..n.saturating_sub(1)).map(|l| MediumLanes::new(stack, l)));
        self.cv.push(
            control_variate
                .then(|| SmoothCoatLambertian::unscattered(stack, settings))
                .flatten(),
        );
    }

    /// Empties it for stacks of `n` interfaces, keeping its memory.
    pub fn clear(&mut self, n: usize) {
        self.n = n;
        self.ifaces.clear();
        self.media.clear();
        self.cv.clear();
    }

    /// Makes it a copy of `other`, reusing its memory.
    pub fn copy_from(&mut self, other: &SetTable) {
        self.n = other.n;
        self.ifaces.clone_from(&other.ifaces);
        self.media.clone_from(&other.media);
        self.cv.clone_from(&other.cv);
    }

    /// Interfaces per set.
    pub fn interfaces(&self) -> usize {
        self.n
    }

    /// The interfaces of every set, set by set.
    pub fn ifaces(&self) -> &[InterfaceLanes<f32>] {
        &self.ifaces
    }

    /// Number of sets.
    pub fn len(&self) -> usize {
        self.cv.len()
    }

    /// No sets.
    pub fn is_empty(&self) -> bool {
        self.cv.is_empty()
    }

    /// Interface `i` of set `s`.
    pub fn iface(&self, s: usize, i: usize) -> &InterfaceLanes<f32> {
        &self.ifaces[s * self.n + i]
    }

    /// Layer `l` of set `s`, as the stack has it.
    pub fn medium(&self, s: usize, l: usize) -> &MediumLanes<f32> {
        &self.media[s * (self.n - 1) + l]
    }

    /// Set `s`'s exact part of eval, if its walks leave it out.
    pub fn cv(&self, s: usize) -> Option<&SmoothCoatLambertian> {
        self.cv[s].as_ref()
    }
}

/// The sets of a chunk's lanes.
#[derive(Clone, Copy)]
pub struct LaneSets<'a> {
    table: &'a SetTable,
    set: [u32; MAX_LANES],
    /// The set of every lane, when they share one.
    same: Option<u32>,
}

impl<'a> LaneSets<'a> {
    /// Lane `j` has set `set(j)` of `table`, for `lanes` lanes.
    pub fn new(table: &'a SetTable, lanes: usize, set: impl Fn(usize) -> u32) -> Self {
        let mut s = [0u32; MAX_LANES];
        for (j, x) in s.iter_mut().enumerate().take(lanes) {
            *x = set(j);
        }
        let same = s[..lanes].iter().all(|&x| x == s[0]).then_some(s[0]);
        LaneSets {
            table,
            set: s,
            same,
        }
    }

    /// The table.
    pub fn table(&self) -> &'a SetTable {
        self.table
    }

    /// Lane `j`'s set.
    pub fn set(&self, j: usize) -> usize {
        self.set[j] as usize
    }

    /// Interface `i` in every lane's set; kinds and flags from `own`.
    pub fn iface<L: Lane>(&self, own: &InterfaceLanes<L>, i: usize) -> InterfaceLanes<L> {
        let t = self.table;
        let numbers = match self.same {
            Some(s) => splat_iface::<L>(t.iface(s as usize, i)),
            None => InterfaceLanes::<L>::gather(&t.ifaces, |j| self.set(j) * t.n + i),
        };
        InterfaceLanes {
            mf: Microfacet {
                beckmann: own.mf.beckmann,
                separable: own.mf.separable,
                ..numbers.mf
            },
            smooth: own.smooth,
            dielectric: own.dielectric,
            conductor: own.conductor,
            diffuse: own.diffuse,
            run_all: own.run_all,
            ..numbers
        }
    }

    /// Layer `l` in every lane's set; its class, greyness and depth units
    /// from `own`.
    pub fn medium<L: Lane>(&self, own: &MediumLanes<L>, l: usize) -> MediumLanes<L> {
        let t = self.table;
        let m = |j: usize| t.medium(self.set(j), l);
        let (sigma_t, albedo, g) = match self.same {
            Some(s) => {
                let x = t.medium(s as usize, l);
                (
                    splat_rgb(x.sigma_t),
                    splat_rgb(x.albedo),
                    L::splat(x.g as f64),
                )
            }
            None => (
                gather_rgb(|j| m(j).sigma_t),
                gather_rgb(|j| m(j).albedo),
                L::from_fn(|j| m(j).g as f64),
            ),
        };
        MediumLanes {
            sigma_t,
            albedo,
            g,
            ..*own
        }
    }

    /// Layers `0..own.len()` in every lane's set, into `out`.
    pub fn media_into<L: Lane>(&self, own: &[MediumLanes<L>], out: &mut Vec<MediumLanes<L>>) {
        out.clear();
        out.extend(own.iter().enumerate().map(|(l, m)| self.medium(m, l)));
    }

    /// Interfaces `0..own.len()` in every lane's set, into `out`.
    pub fn ifaces_into<L: Lane>(
        &self,
        own: &[InterfaceLanes<L>],
        out: &mut Vec<InterfaceLanes<L>>,
    ) {
        out.clear();
        out.extend(own.iter().enumerate().map(|(i, it)| self.iface(it, i)));
    }

    /// The lanes whose set has the control variate on.
    pub fn cv<L: Lane>(&self) -> L::Mask {
        match self.same {
            Some(s) => L::Mask::splat(self.table.cv(s as usize).is_some()),
            None => L::Mask::from_fn(|j| self.table.cv(self.set(j)).is_some()),
        }
    }
}

fn splat_rgb<L: Lane>(c: Rgb<f32>) -> Rgb<L> {
    Rgb::new(
        L::splat(c.r as f64),
        L::splat(c.g as f64),
        L::splat(c.b as f64),
    )
}

fn gather_rgb<L: Lane>(f: impl Fn(usize) -> Rgb<f32>) -> Rgb<L> {
    Rgb::new(
        L::from_fn(|j| f(j).r as f64),
        L::from_fn(|j| f(j).g as f64),
        L::from_fn(|j| f(j).b as f64),
    )
}

/// A one-lane interface in every lane.
fn splat_iface<L: Lane>(t: &InterfaceLanes<f32>) -> InterfaceLanes<L> {
    let s = |x: f32| L::splat(x as f64);
    let m = |b: bool| L::Mask::splat(b);
    InterfaceLanes {
        n_above: s(t.n_above),
        n_below: s(t.n_below),
        mf: Microfacet {
            alpha_x: s(t.mf.alpha_x),
            alpha_y: s(t.mf.alpha_y),
            beckmann: m(t.mf.beckmann),
            separable: m(t.mf.separable),
        },
        smooth: m(t.smooth),
        dielectric: m(t.dielectric),
        conductor: m(t.conductor),
        diffuse: m(t.diffuse),
        eta: splat_rgb(t.eta),
        k: splat_rgb(t.k),
        albedo: splat_rgb(t.albedo),
        run_all: t.run_all,
    }
}
