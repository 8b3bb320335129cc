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

use super::coat_lambertian::CoatLambertian;
use super::layout::MediumLanes;
use crate::interface::InterfaceLanes;
use crate::lane::{load16, Lane, LaneMask, Rgb, Wide, MAX_LANES, V3};
use crate::microfacet::Microfacet;
use crate::phase::{PhaseKind, PHASE_ROW};
use crate::stack::LayerStack;

/// The numbers of several stacks of one shape, in one-lane form.
#[derive(Clone, Debug, Default)]
pub struct SetTable {
    /// Interfaces per set.
    n: usize,
    /// Per set, its block of lanes: its own, or the first set's where a
    /// lean table gives it none ([`SetTable::set_lean`]).
    block: Vec<u32>,
    /// Block `b`, interface `i` at `b * n + i`.
    ifaces: Vec<InterfaceLanes<f32>>,
    /// Block `b`, layer `l` at `b * (n - 1) + l`, as the stack has them.
    media: Vec<MediumLanes<f32>>,
    /// Per set: the exact part of eval that the walks leave out, when the
    /// control variate is on for it.
    cv: Vec<Option<CoatLambertian>>,
    /// Per set: what its stack returns of the light that enters it
    /// ([`super::body_return::body_return`]), for the lobe pdf.
    body: Vec<f64>,
    /// The numbers of `ifaces` as rows, which a chunk loads with two 8×8
    /// transposes ([`IFACE_ROW`]).
    iface_rows: Vec<[f32; 16]>,
    /// The numbers of `media` as rows ([`MEDIUM_ROW`]).
    medium_rows: Vec<[f32; 8]>,
    /// The phase parameters beyond `g` of `media` as rows ([`PHASE_ROW`]),
    /// read only for the layers whose phase has them.
    phase_rows: Vec<[f32; PHASE_ROW]>,
    /// Sets answered without walks have no lanes of their own: a table
    /// for calls that walk none of them ([`SetTable::set_lean`]).
    lean: bool,
}

/// An interface's row: `n_above`, `n_below`, `alpha_x`, `alpha_y`, `eta`
/// (3), `k` (3), `albedo` (3), `normal` (3).
pub const IFACE_ROW: usize = 16;

/// A medium's row: `sigma_t` (3), `albedo` (3), `g`; one unused.
pub const MEDIUM_ROW: usize = 8;

fn iface_row(t: &InterfaceLanes<f32>) -> [f32; 16] {
    let mut r = [0.0; 16];
    let v = [
        t.n_above,
        t.n_below,
        t.mf.alpha_x,
        t.mf.alpha_y,
        t.eta.r,
        t.eta.g,
        t.eta.b,
        t.k.r,
        t.k.g,
        t.k.b,
        t.albedo.r,
        t.albedo.g,
        t.albedo.b,
        t.normal.x,
        t.normal.y,
        t.normal.z,
    ];
    r[..v.len()].copy_from_slice(&v);
    r
}

fn medium_row(m: &MediumLanes<f32>) -> [f32; 8] {
    let (a, b) = (m.sigma_t, m.albedo);
    [a.r, a.g, a.b, b.r, b.g, b.b, m.phase.g, 0.0]
}

impl SetTable {
    /// An empty table for stacks of `n` interfaces.
    pub fn new(n: usize) -> Self {
        SetTable {
            n,
            ..Self::default()
        }
    }

    /// Makes the sets' interfaces answer for the adjoint of a tilted stack
    /// (`ScalarEngine::set_adjoint`), as the engine that runs them does.
    pub fn set_adjoint(&mut self, on: bool) {
        for it in &mut self.ifaces {
            it.adjoint = on;
        }
    }

    /// Makes the last set's interfaces answer for the adjoint of a tilted
    /// stack, or not ([`SetTable::set_adjoint`]): the last block's, which a
    /// lean table's set without lanes shares with others of the same table,
    /// and so of the same transport mode.
    pub fn set_adjoint_of_last(&mut self, on: bool) {
        let n = self.n;
        let len = self.ifaces.len();
        for it in &mut self.ifaces[len - n..] {
            it.adjoint = on;
        }
    }

    /// Makes the sets added from now on whose eval, sample and pdf read no
    /// lanes (`lanes` false in [`SetTable::push`]) carry none of their own
    /// (they share the first set's), or carry them again: a lean table
    /// serves every call but albedo, which walks every set.
    pub fn set_lean(&mut self, on: bool) {
        self.lean = on;
    }

    /// Whether some sets may lack lanes of their own ([`SetTable::set_lean`]).
    pub fn is_lean(&self) -> bool {
        self.lean
    }

    /// Adds `stack` (of the table's shape) as the next set; with `cv`
    /// (what [`CoatLambertian::unscattered`] gives for it, or `None`), eval
    /// walks of its queries leave out what `cv` holds. `lobe_pdf` says
    /// whether its pdfs may be the lobe pdf, which needs its body's return
    /// (else 1 is stored); `lanes`, whether its eval, sample or pdf read its
    /// lanes (walks, or a rough coat's first-order term): in a lean table
    /// only such a set gets lanes of its own.
    pub fn push(
        &mut self,
        stack: &LayerStack,
        cv: Option<CoatLambertian>,
        lobe_pdf: bool,
        lanes: bool,
    ) {
        debug_assert_eq!(stack.len(), self.n);
        let (n, m) = (self.n, self.n.saturating_sub(1));
        if self.lean && !lanes && !self.is_empty() {
            self.block.push(0);
        } else {
            self.block.push((self.ifaces.len() / n.max(1)) as u32);
            let first = (self.ifaces.len(), self.media.len());
            self.ifaces
                .extend((0..n).map(|i| stack.interface_lanes::<f32>(i)));
            self.media
                .extend((0..m).map(|l| MediumLanes::new(stack, l)));
            let rows = self.ifaces[first.0..].iter().map(iface_row);
            self.iface_rows.extend(rows);
            let rows = self.media[first.1..].iter().map(medium_row);
            self.medium_rows.extend(rows);
            let rows = self.media[first.1..].iter().map(|m| m.phase.p);
            self.phase_rows.extend(rows);
        }
        self.cv.push(cv);
        self.body.push(match lobe_pdf {
            true => super::body_return::body_return(stack),
            false => 1.0,
        });
    }

    /// Empties it for stacks of `n` interfaces, keeping its memory (and
    /// not lean).
    pub fn clear(&mut self, n: usize) {
        self.n = n;
        self.lean = false;
        self.block.clear();
        self.ifaces.clear();
        self.media.clear();
        self.cv.clear();
        self.body.clear();
        self.iface_rows.clear();
        self.medium_rows.clear();
        self.phase_rows.clear();
    }

    /// Reserves room for `sets` more sets.
    pub fn try_reserve(&mut self, sets: usize) -> Result<(), std::collections::TryReserveError> {
        let (n, m) = (self.n * sets, self.n.saturating_sub(1) * sets);
        self.block.try_reserve(sets)?;
        self.ifaces.try_reserve(n)?;
        self.iface_rows.try_reserve(n)?;
        self.media.try_reserve(m)?;
        self.medium_rows.try_reserve(m)?;
        self.phase_rows.try_reserve(m)?;
        self.cv.try_reserve(sets)?;
        self.body.try_reserve(sets)
    }

    /// Makes it a copy of `other`, reusing its memory.
    pub fn copy_from(&mut self, other: &SetTable) {
        self.n = other.n;
        self.lean = other.lean;
        self.block.clone_from(&other.block);
        self.ifaces.clone_from(&other.ifaces);
        self.media.clone_from(&other.media);
        self.cv.clone_from(&other.cv);
        self.body.clone_from(&other.body);
        self.iface_rows.clone_from(&other.iface_rows);
        self.medium_rows.clone_from(&other.medium_rows);
        self.phase_rows.clone_from(&other.phase_rows);
    }

    /// Interfaces per set.
    pub fn interfaces(&self) -> usize {
        self.n
    }

    /// The interfaces of every block of lanes, block by block
    /// ([`LaneSets::block`] is a lane's).
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

    /// The interfaces of set `s`.
    pub fn ifaces_of(&self, s: usize) -> &[InterfaceLanes<f32>] {
        let b = self.block[s] as usize;
        &self.ifaces[b * self.n..(b + 1) * self.n]
    }

    /// The layers of set `s`.
    pub fn media_of(&self, s: usize) -> &[MediumLanes<f32>] {
        let (b, per) = (self.block[s] as usize, self.n - 1);
        &self.media[b * per..(b + 1) * per]
    }

    /// What set `s`'s stack returns of the light that enters it.
    pub fn body(&self, s: usize) -> f64 {
        self.body[s]
    }

    /// Interface `i` of set `s`.
    pub fn iface(&self, s: usize, i: usize) -> &InterfaceLanes<f32> {
        &self.ifaces[self.block[s] as usize * self.n + i]
    }

    /// Layer `l` of set `s`, as the stack has it.
    pub fn medium(&self, s: usize, l: usize) -> &MediumLanes<f32> {
        &self.media[self.block[s] as usize * (self.n - 1) + l]
    }

    /// Set `s`'s exact part of eval, if its walks leave it out.
    pub fn cv(&self, s: usize) -> Option<&CoatLambertian> {
        self.cv[s].as_ref()
    }
}

/// The sets of a chunk's lanes.
#[derive(Clone, Copy)]
pub struct LaneSets<'a> {
    table: &'a SetTable,
    set: [u32; MAX_LANES],
    /// Each lane's block of lanes in the table.
    block: [u32; MAX_LANES],
    /// The set of every lane, when they share one.
    same: Option<u32>,
    /// The block of every lane, when they share one.
    same_block: Option<u32>,
}

impl<'a> LaneSets<'a> {
    /// Lane `j` has set `set(j)` of `table`, for `lanes` lanes.
    pub fn new(table: &'a SetTable, lanes: usize, set: impl Fn(usize) -> u32) -> Self {
        let mut s = [0u32; MAX_LANES];
        for (j, x) in s.iter_mut().enumerate().take(lanes) {
            *x = set(j);
        }
        let b = s.map(|x| table.block.get(x as usize).copied().unwrap_or(0));
        let all = |a: &[u32; MAX_LANES]| a[..lanes].iter().all(|&x| x == a[0]).then_some(a[0]);
        LaneSets {
            table,
            set: s,
            block: b,
            same: all(&s),
            same_block: all(&b),
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

    /// Lane `j`'s block of lanes in the table ([`SetTable::ifaces`]).
    pub fn block(&self, j: usize) -> usize {
        self.block[j] as usize
    }

    /// Row `first + k` of lane `j`'s block, where blocks have `per` rows.
    fn rows(&self, per: usize, first: usize) -> [u32; MAX_LANES] {
        std::array::from_fn(|j| (self.block[j] as usize * per + first) as u32)
    }

    /// Interface `i` in every lane's set; kinds and flags from `own`.
    #[inline(always)]
    pub fn iface<W: Wide>(&self, own: &InterfaceLanes<W>, i: usize) -> InterfaceLanes<W> {
        let t = self.table;
        let f = match self.same_block {
            Some(s) => t.iface_rows[s as usize * t.n + i].map(|x| W::splat(x as f64)),
            None => load16::<W, IFACE_ROW>(&t.iface_rows, &self.rows(t.n, i)[..W::LANES], 0),
        };
        InterfaceLanes {
            n_above: f[0],
            n_below: f[1],
            mf: Microfacet {
                alpha_x: f[2],
                alpha_y: f[3],
                ..own.mf
            },
            eta: Rgb::new(f[4], f[5], f[6]),
            k: Rgb::new(f[7], f[8], f[9]),
            albedo: Rgb::new(f[10], f[11], f[12]),
            normal: V3::new(f[13], f[14], f[15]),
            ..*own
        }
    }

    /// Layer `l` in every lane's set; its class, greyness and depth units
    /// from `own`.
    #[inline(always)]
    pub fn medium<W: Wide>(&self, own: &MediumLanes<W>, l: usize) -> MediumLanes<W> {
        let t = self.table;
        let per = t.n - 1;
        let f = match self.same_block {
            Some(s) => t.medium_rows[s as usize * per + l].map(|x| W::splat(x as f64)),
            None => W::load8(&t.medium_rows, &self.rows(per, l)[..W::LANES], 0),
        };
        let mut phase = own.phase;
        phase.g = f[6];
        if own.phase.kind != PhaseKind::Hg {
            phase.p = match self.same_block {
                Some(s) => t.phase_rows[s as usize * per + l].map(|x| W::splat(x as f64)),
                None => W::load8(&t.phase_rows, &self.rows(per, l)[..W::LANES], 0),
            };
        }
        MediumLanes {
            sigma_t: Rgb::new(f[0], f[1], f[2]),
            albedo: Rgb::new(f[3], f[4], f[5]),
            phase,
            ..*own
        }
    }

    /// Layers `0..own.len()` in every lane's set, into `out`.
    pub fn media_into<W: Wide>(&self, own: &[MediumLanes<W>], out: &mut Vec<MediumLanes<W>>) {
        out.clear();
        out.extend(own.iter().enumerate().map(|(l, m)| self.medium(m, l)));
    }

    /// Interfaces `0..own.len()` in every lane's set, into `out`.
    pub fn ifaces_into<W: Wide>(
        &self,
        own: &[InterfaceLanes<W>],
        out: &mut Vec<InterfaceLanes<W>>,
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
