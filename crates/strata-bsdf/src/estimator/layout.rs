//! The stack's topology as the walks see it: which layer a direction leaving an
//! interface enters, how far it is to the next boundary, where the exit is.
//! Shared by every engine so that they take the same decisions.
//!
//! A walk's position is `(layer, z)`: layer `l` lies between interfaces `l` and
//! `l + 1`, and `z` is the depth below interface `l` (so `0 <= z <= thickness`).

use crate::interface::InterfaceLanes;
use crate::lane::{Lane, LaneMask, Rgb, V3};
use crate::phase::PhaseLanes;
pub use crate::stack::LayerKind;
use crate::stack::{LayerStack, Medium};

/// One medium's parameters in a lane type (splatted: the same in every lane).
#[derive(Clone, Copy, Debug)]
pub struct MediumLanes<L: Lane> {
    /// What the layer asks of a walk.
    pub kind: LayerKind,
    /// Thickness in the walk's depth units: 1 for a medium (0 for a clear
    /// layer without one).
    pub thickness: L,
    /// Extinction per unit of that depth: the optical depth, per channel.
    pub sigma_t: Rgb<L>,
    /// Single-scattering albedo per channel.
    pub albedo: Rgb<L>,
    /// Its phase function (and the direction-dependent scale of `sigma_t`).
    pub phase: PhaseLanes<L>,
    /// The extinction depends on the direction (`phase.kind.directional()`).
    pub directional: bool,
    /// The same `sigma_t` in every channel: free flights need no spectral MIS.
    pub grey: bool,
}

impl MediumLanes<f64> {
    /// This layer on every lane of `L` (the lanes [`MediumLanes::new`]
    /// makes of it, bit for bit).
    pub fn splat<L: Lane>(&self) -> MediumLanes<L> {
        MediumLanes {
            kind: self.kind,
            thickness: L::splat(self.thickness),
            sigma_t: Rgb::from_array([self.sigma_t.r, self.sigma_t.g, self.sigma_t.b]),
            albedo: Rgb::from_array([self.albedo.r, self.albedo.g, self.albedo.b]),
            phase: self.phase.splat(),
            directional: self.directional,
            grey: self.grey,
        }
    }
}

impl<L: Lane> MediumLanes<L> {
    /// The medium of layer `l` of `stack` (a clear layer if it has none).
    pub fn new(stack: &LayerStack, l: usize) -> Self {
        match stack.medium(l) {
            Some(m) => Self::from_medium(m),
            None => MediumLanes {
                kind: LayerKind::Clear,
                thickness: L::zero(),
                sigma_t: Rgb::zero(),
                albedo: Rgb::zero(),
                phase: PhaseLanes::isotropic(),
                directional: false,
                grey: true,
            },
        }
    }

    fn from_medium(m: &Medium) -> Self {
        // Walks measure depth in units of the layer's thickness, so the medium
        // enters only through its optical depth (as it does in the physics:
        // σt |Δz| / |d.z|). A thickness or sigma_t that single precision
        // cannot hold (1e-50, 1e300) then cannot overflow or vanish when their
        // product is ordinary (docs/numerics.md).
        MediumLanes {
            kind: m.kind(),
            thickness: L::one(),
            sigma_t: Rgb::from_array(m.optical_depth()),
            albedo: Rgb::from_array(m.albedo),
            phase: PhaseLanes::new(&m.phase, m.phase_kind()),
            directional: m.phase_kind().directional(),
            grey: m.grey(),
        }
    }

    /// The depth at which a walk enters the layer: its bottom where
    /// `from_below` (travelling up), its top elsewhere.
    #[inline]
    pub fn entry(&self, from_below: L::Mask) -> L {
        L::select(from_below, self.thickness, L::zero())
    }

    /// The extinction per channel along the travel direction `d`: `sigma_t`,
    /// scaled by the phase's `sqrt(dᵀSd)` where it is directional.
    #[inline(always)]
    pub fn sigma_along(&self, d: V3<L>) -> Rgb<L> {
        if self.directional {
            self.sigma_t.scale(self.phase.sigma_scale(d))
        } else {
            self.sigma_t
        }
    }

    /// Transmittance over a depth `dz` along the direction `d` (1 in a
    /// clear layer).
    #[inline]
    pub fn transmittance(&self, dz: L, d: V3<L>) -> Rgb<L> {
        let mu = d.z.abs();
        match self.kind {
            LayerKind::Clear => Rgb::one(),
            // Grey: one exponential serves all three channels.
            _ if self.grey => {
                let t = crate::medium::channel_transmittance(self.sigma_along(d).r, dz, mu);
                Rgb::new(t, t, t)
            }
            _ => crate::medium::transmittance(self.sigma_along(d), dz, mu),
        }
    }
}

/// Where a direction leaving an interface goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Next {
    /// Into layer `l`, entering at its bottom (`from_below`, depth = thickness)
    /// or at its top (depth 0).
    Layer {
        /// The layer.
        l: usize,
        /// Entered through its bottom interface (travelling up).
        from_below: bool,
    },
    /// Out of the stack through the top.
    OutTop,
    /// Out of the stack through the bottom.
    OutBottom,
}

/// The interfaces and layers of a stack, as indices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Number of interfaces.
    pub n: usize,
}

impl Layout {
    /// The layout of `stack`.
    pub fn new(stack: &LayerStack) -> Self {
        Layout { n: stack.len() }
    }

    /// Where a direction leaving interface `i` upwards (`up`) or downwards
    /// goes ([`Layout::enter`] on one lane).
    #[inline]
    pub fn next(&self, i: usize, up: bool) -> Next {
        match self.enter(i as f64, up) {
            (_, true) if up => Next::OutTop,
            (_, true) => Next::OutBottom,
            (l, false) => Next::Layer {
                l: l as usize,
                from_below: up,
            },
        }
    }

    /// The interface a walk in layer `l` travelling up (`up`) or down reaches
    /// ([`Layout::arrive`] on one lane).
    #[inline]
    pub fn boundary(&self, l: usize, up: bool) -> usize {
        self.arrive(l as f64, up) as usize
    }

    /// The interface light from direction `w` (pointing away from the stack)
    /// enters or leaves through: the top for `w.z > 0`, the bottom otherwise
    /// ([`Layout::outer_lanes`] on one lane).
    #[inline]
    pub fn outer(&self, above: bool) -> usize {
        self.outer_lanes::<f64>(above) as usize
    }

    /// [`Layout::next`] over lanes, for directions leaving interface `i` (an
    /// index per lane) upwards where `up`: the layer each enters (entered
    /// through its bottom where `up`, at its top elsewhere) and the lanes that
    /// leave the stack instead (their layer is meaningless). Both engines take
    /// this decision here, the scalar one on a single lane, so that a walk
    /// goes where its lane of the wavefront goes.
    #[inline]
    pub fn enter<L: Lane>(&self, i: L, up: L::Mask) -> (L, L::Mask) {
        let layer = L::select(up, i - L::one(), i);
        let last = L::splat(self.n as f64 - 1.0);
        let out = (up & i.eq(L::zero())) | (!up & i.eq(last));
        (layer, out)
    }

    /// [`Layout::boundary`] over lanes: the interface a walk in layer `l`
    /// (per lane) reaches travelling up where `up`, down elsewhere.
    #[inline]
    pub fn arrive<L: Lane>(&self, l: L, up: L::Mask) -> L {
        L::select(up, l, l + L::one())
    }

    /// [`Layout::outer`] over lanes: the interface light from a direction
    /// with `w.z > 0` where `above` enters or leaves through.
    #[inline]
    pub fn outer_lanes<L: Lane>(&self, above: L::Mask) -> L {
        L::select(above, L::zero(), L::splat(self.n as f64 - 1.0))
    }

    /// [`Layout::exit_region`] over lanes, for a stack of two interfaces or
    /// more: the layer next to the exit (the top where `top`, else the
    /// bottom) and the interface across it.
    #[inline]
    pub fn exit_region_lanes<L: Lane>(&self, top: L::Mask) -> (L, L) {
        let inner = L::splat(self.n as f64 - 2.0);
        (
            L::select(top, L::zero(), inner),
            L::select(top, L::one(), inner),
        )
    }

    /// For exit interface `e`: the layer next to it and the interface across
    /// that layer (`None` for a one-interface stack, which has no interior).
    /// Continuations from there reach the exit directly
    /// ([`Layout::exit_region_lanes`] on one lane).
    #[inline]
    pub fn exit_region(&self, e: usize) -> Option<(usize, usize)> {
        (self.n >= 2).then(|| {
            let (l, k) = self.exit_region_lanes::<f64>(e == 0);
            (l as usize, k as usize)
        })
    }
}

/// What `pick` reads of interface `i[j]`, on lane `j`: one lookup when every
/// lane's interface is the same (as on the scalar engine), else a `select`
/// per interface that some lane is at. The lookups below read only what
/// their callers need: a whole interface costs many selects.
#[inline]
pub fn iface_field_at<L: Lane, T>(
    ifaces: &[InterfaceLanes<L>],
    i: L,
    pick: impl Fn(&InterfaceLanes<L>) -> T,
    select: impl Fn(L::Mask, T, T) -> T,
) -> T {
    let n = ifaces.len();
    let i0 = i.lane(0);
    if i.eq(L::splat(i0)).all() {
        return pick(&ifaces[(i0.max(0.0) as usize).min(n - 1)]);
    }
    let mut v = pick(&ifaces[0]);
    for (k, t) in ifaces.iter().enumerate().skip(1) {
        let here = i.eq(L::splat(k as f64));
        if here.any() {
            v = select(here, pick(t), v);
        }
    }
    v
}

/// Interface `i[j]` of `ifaces` on lane `j`.
#[inline]
pub fn iface_at<L: Lane>(ifaces: &[InterfaceLanes<L>], i: L) -> InterfaceLanes<L> {
    iface_field_at(
        ifaces,
        i,
        |it| *it,
        |m, a, b| InterfaceLanes::select(m, &a, &b),
    )
}

/// Whether interface `i[j]` is smooth, on lane `j`.
#[inline]
pub fn iface_smooth_at<L: Lane>(ifaces: &[InterfaceLanes<L>], i: L) -> L::Mask {
    iface_field_at(ifaces, i, |it| it.smooth, |m, a, b| (m & a) | (!m & b))
}

/// The thickness of layer `l[j]` of `media` on lane `j`, in depth units.
#[inline]
pub fn thickness_at<L: Lane>(media: &[MediumLanes<L>], l: L) -> L {
    if media.is_empty() {
        return L::zero();
    }
    let l0 = l.lane(0);
    if l.eq(L::splat(l0)).all() {
        return media[(l0.max(0.0) as usize).min(media.len() - 1)].thickness;
    }
    let mut h = L::zero();
    for (k, m) in media.iter().enumerate() {
        h = L::select(l.eq(L::splat(k as f64)), m.thickness, h);
    }
    h
}

/// Lanes whose travel direction `d` heads for the exit interface: the top
/// where `top`, the bottom elsewhere.
#[inline]
pub fn toward_exit<L: Lane>(d: V3<L>, top: L::Mask) -> L::Mask {
    (top & d.z.gt(L::zero())) | (!top & d.z.lt(L::zero()))
}

/// Depth left to the boundary a direction heads for, from depth `z` in a layer
/// of thickness `h`: `z` going up, `h - z` going down (never negative).
#[inline]
pub fn depth_to_boundary<L: Lane>(z: L, h: L, up: L::Mask) -> L {
    L::select(up, z, (h - z).max(L::zero()))
}

/// The distance along a direction with `|d.z| = mu` to a boundary `dz` away
/// in depth. A direction exactly parallel to the layer (`mu = 0`: single
/// precision rounds a scattered direction's `z` to exactly 0 about once in
/// 3e7 scatterings) never reaches a boundary; its limit is the largest `f32`,
/// so that a free flight in a scattering medium collides, as it must, instead
/// of the walk being lost.
#[inline]
pub fn flight_limit<L: Lane>(dz: L, mu: L) -> L {
    let ok = mu.gt(L::zero());
    L::select(ok, L::div_or_zero(dz, mu, ok), L::splat(f32::MAX as f64))
}

/// Depth after travelling a distance `t` along `d` from depth `z` (depth grows
/// downwards), kept inside the layer.
#[inline]
pub fn move_depth<L: Lane>(z: L, dz: L, t: L, h: L) -> L {
    (z - dz * t).clamp(L::zero(), h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lane::F32x8;

    /// A grey medium's one exponential gives, bit for bit, what the three
    /// channels give computed apart; a chromatic one still computes three.
    /// Both agree with `exp(-σt Δz / μ)` in f64 to a few ulps (or are 0 below
    /// the smallest normal f32).
    #[test]
    fn grey_transmittance_is_the_per_channel_one() {
        for (sigma_t, grey) in [("2.5", true), ("[0.5, 1.0, 4.0]", false)] {
            let toml = format!(
                "[[layers]]\ninterface = {{ kind = \"dielectric\", ior = 1.5 }}\n\
                 medium = {{ thickness = 1.0, sigma_t = {sigma_t}, albedo = 0.5 }}\n\
                 [[layers]]\ninterface = {{ kind = \"diffuse\", albedo = 0.5 }}\n"
            );
            let stack = LayerStack::from_toml_str(&toml).unwrap();
            let m = MediumLanes::<F32x8>::new(&stack, 0);
            assert_eq!(m.grey, grey);
            let dz = F32x8::from_fn(|j| [0.0, 1e-7, 0.1, 0.5, 1.0, 0.3, 0.9, 0.7][j]);
            let mu = F32x8::from_fn(|j| [1.0, 0.5, 1e-7, 0.0, 0.25, 1.0, 0.01, 0.6][j]);
            let got = m.transmittance(dz, V3::new(F32x8::zero(), F32x8::zero(), mu));
            let want = crate::medium::transmittance(m.sigma_t, dz, mu);
            let st = [m.sigma_t.r, m.sigma_t.g, m.sigma_t.b];
            for (c, (g, w)) in [(got.r, want.r), (got.g, want.g), (got.b, want.b)]
                .into_iter()
                .enumerate()
            {
                for j in 0..8 {
                    assert_eq!(
                        g.lane(j).to_bits(),
                        w.lane(j).to_bits(),
                        "{sigma_t} lane {j}"
                    );
                    let exact = (-st[c].lane(j) * dz.lane(j) / mu.lane(j).max(1e-30)).exp();
                    // Below the smallest normal f32, exp gives 0 by design.
                    let err = (g.lane(j) - exact).abs();
                    assert!(
                        err <= 4e-7 * exact + f32::MIN_POSITIVE as f64,
                        "{sigma_t} lane {j}: {} vs {exact}",
                        g.lane(j)
                    );
                }
            }
        }
    }
}
