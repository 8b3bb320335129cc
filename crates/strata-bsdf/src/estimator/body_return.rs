//! What an opaque stack returns of the light that crosses its entry
//! interface, in closed form: the weight of the lobe pdf's cosine lobe
//! (`super::lobe_pdf`).

use crate::stack::{InterfaceKind, LayerStack, Phase};
use wide::f64x4;

/// The share of the light that crosses an opaque stack's entry interface
/// and comes back out through it: the lobe pdf's weight of its cosine lobe,
/// so that the lobe pdf integrates, as `sample()`'s density does, to about
/// the stack's albedo (a lobe pdf that integrates to 1 over a dark stack
/// gives MIS weights that favour the BSDF sample where its walks are mostly
/// absorbed). A closed form, mean of the channels, in `[0.01, 1]`: the
/// base's reflectance (a Lambertian albedo, or a conductor's normal
/// Fresnel term), each layer added on top by Kubelka–Munk with the
/// similarity relations, interior interfaces by their diffuse Fresnel
/// reflectances, and the entry interface's internal reflection, which light
/// from a diffusing body meets diffuse and light from a mirror near the
/// normal. Transmissive stacks keep 1.
pub fn body_return(stack: &LayerStack) -> f64 {
    let n = stack.len();
    if n < 2 || stack.transmissive() {
        return 1.0;
    }
    let reflectance = |i: usize| -> Option<[f64; 3]> {
        let it = stack.interface(i);
        match it.kind {
            InterfaceKind::Diffuse => Some(it.albedo),
            InterfaceKind::Conductor => Some(std::array::from_fn(|c| {
                let (e, k) = (it.eta[c], it.k[c]);
                ((e - 1.0) * (e - 1.0) + k * k) / ((e + 1.0) * (e + 1.0) + k * k)
            })),
            InterfaceKind::Dielectric => None,
        }
    };
    let Some(mut r) = reflectance(n - 1) else {
        return 1.0;
    };
    let mut diffusing = stack.interface(n - 1).kind == InterfaceKind::Diffuse;
    for l in (0..n - 1).rev() {
        if let Some(m) = stack.medium(l) {
            diffusing |= m.scatters();
            let g = match &m.phase {
                Phase::Hg { g } => *g,
                Phase::Mixture(lobes) => lobes.iter().map(|(w, g)| w * g).sum(),
                Phase::Sggx { .. } => 0.0,
            };
            r = kubelka_munk(m.optical_depth(), m.albedo, g, r);
        }
        if l == 0 {
            break;
        }
        let it = stack.interface(l);
        match reflectance(l) {
            // An opaque interior interface hides what lies below it.
            Some(own) => {
                r = own;
                diffusing = it.kind == InterfaceKind::Diffuse;
            }
            None => {
                let (ra, rb) = (
                    diffuse_fresnel(it.n_above, it.n_below),
                    diffuse_fresnel(it.n_below, it.n_above),
                );
                r = r.map(|x| ra + (1.0 - ra) * (1.0 - rb) * x / (1.0 - rb * x));
            }
        }
    }
    let top = stack.interface(0);
    let inside = if diffusing {
        diffuse_fresnel(top.n_below, top.n_above)
    } else {
        crate::fresnel::dielectric(-1.0, top.n_below / top.n_above)
    };
    let out = r.map(|x| x * (1.0 - inside) / (1.0 - inside * x));
    ((out[0] + out[1] + out[2]) / 3.0).clamp(0.01, 1.0)
}

/// Diffuse reflectance per channel of a layer of optical depths `tau`,
/// single-scattering albedos `albedo` and phase asymmetry `g` over a
/// background of diffuse reflectances `under` (Kubelka–Munk, with the
/// similarity relations). The channels' divisions and square roots run in
/// the lanes of one vector, their exponentials one by one.
fn kubelka_munk(tau: [f64; 3], albedo: [f64; 3], g: f64, under: [f64; 3]) -> [f64; 3] {
    let v = |x: [f64; 3]| f64x4::new([x[0], x[1], x[2], x[2]]);
    let (tau, albedo, under) = (v(tau), v(albedo), v(under));
    let one = f64x4::ONE;
    let reduced = (one - albedo * g).max(f64x4::splat(1e-9));
    let a = albedo * (1.0 - g) / reduced;
    let tau = tau * reduced;
    let (k, s) = (f64x4::splat(2.0) * (one - a) * tau, a * tau);
    if s.simd_lt(f64x4::splat(1e-9)).all() {
        // An absorber: its transmittance alone.
        let (k, under) = (k.to_array(), under.to_array());
        return std::array::from_fn(|c| under[c] * (-2.0 * k[c]).exp());
    }
    let ratio = (s + k) / s;
    let b = (ratio * ratio - one).max(f64x4::ZERO).sqrt();
    let bs = (b * s).to_array();
    let (k, s3) = (k.to_array(), s.to_array());
    // Per channel: `e^(−2k)` where the layer scatters too little to count
    // (Kubelka–Munk's transmittance alone), else `e^(−2bs)` for
    // `b coth(bs) = b (1 + e) / (1 − e)`.
    let e = f64x4::new(std::array::from_fn(|c| match s3[c] < 1e-9 {
        true => (-2.0 * k[c]).exp(),
        false => (-2.0 * bs[c]).exp(),
    }));
    // `b coth(bs)`, and its limit s⁻¹ where the layer does not absorb.
    let bc = f64x4::new(bs)
        .simd_lt(f64x4::splat(1e-6))
        .select(one / s, b * (one + e) / (one - e));
    let km = ((one - under * (ratio - bc)) / (ratio - under + bc))
        .max(f64x4::ZERO)
        .min(one);
    let r = s
        .simd_lt(f64x4::splat(1e-9))
        .select(under * e, km)
        .to_array();
    [r[0], r[1], r[2]]
}

/// Diffuse (hemispherical) reflectance of a smooth boundary for light that
/// arrives from the side of IOR `from` (Egan and Hilgeman's fit of the
/// internal reflectance, as Jensen et al. 2001 use it, and energy balance,
/// `1 − r_outside = (1 − r_inside) / η²`, from the other side).
fn diffuse_fresnel(from: f64, to: f64) -> f64 {
    let inside = |eta: f64| -1.440 / (eta * eta) + 0.710 / eta + 0.668 + 0.0636 * eta;
    if from >= to {
        inside(from / to).clamp(0.0, 1.0)
    } else {
        let eta = to / from;
        (1.0 - eta * eta * (1.0 - inside(eta))).clamp(0.0, 1.0)
    }
}
