//! What an opaque stack returns of the light that crosses its entry
//! interface, in closed form: the weight of the lobe pdf's cosine lobe
//! (`super::lobe_pdf`).

use crate::stack::{InterfaceKind, LayerStack, Phase};

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
/// similarity relations).
fn kubelka_munk(tau: [f64; 3], albedo: [f64; 3], g: f64, under: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|c| {
        let reduced = (1.0 - albedo[c] * g).max(1e-9);
        let a = albedo[c] * (1.0 - g) / reduced;
        let tau = tau[c] * reduced;
        let (k, s) = (2.0 * (1.0 - a) * tau, a * tau);
        if s < 1e-9 {
            return under[c] * (-2.0 * k).exp();
        }
        let ratio = (s + k) / s;
        let b = (ratio * ratio - 1.0).max(0.0).sqrt();
        // b coth(b s) = b (1 + e) / (1 - e), e = exp(−2 b s), and its limit
        // s⁻¹ where the layer does not absorb.
        let bs = b * s;
        let bc = if bs < 1e-6 {
            1.0 / s
        } else {
            let e = (-2.0 * bs).exp();
            b * (1.0 + e) / (1.0 - e)
        };
        ((1.0 - under[c] * (ratio - bc)) / (ratio - under[c] + bc)).clamp(0.0, 1.0)
    })
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
