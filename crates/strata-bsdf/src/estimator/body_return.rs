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
/// similarity relations). The channels' divisions, square roots and
/// exponentials run in the lanes of one vector.
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
        let r = (under * (f64x4::splat(-2.0) * k).exp()).to_array();
        return [r[0], r[1], r[2]];
    }
    let ratio = (s + k) / s;
    let b = (ratio * ratio - one).max(f64x4::ZERO).sqrt();
    let bs = b * s;
    // Per channel: `e^(−2k)` where the layer scatters too little to count
    // (Kubelka–Munk's transmittance alone), else `e^(−2bs)` for
    // `b coth(bs) = b (1 + e) / (1 − e)`.
    let thin = s.simd_lt(f64x4::splat(1e-9));
    let e = (f64x4::splat(-2.0) * thin.select(k, bs)).exp();
    // `b coth(bs)`, and its limit s⁻¹ where the layer does not absorb.
    let bc = bs
        .simd_lt(f64x4::splat(1e-6))
        .select(one / s, b * (one + e) / (one - e));
    let km = ((one - under * (ratio - bc)) / (ratio - under + bc))
        .max(f64x4::ZERO)
        .min(one);
    let r = thin.select(under * e, km).to_array();
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

#[cfg(test)]
mod tests {
    use super::kubelka_munk;

    /// Kubelka–Munk's reflectance written out per channel with the
    /// hyperbolic cotangent, independently of the vector form.
    fn textbook(tau: f64, albedo: f64, g: f64, under: f64) -> f64 {
        let reduced = 1.0 - albedo * g;
        let a = albedo * (1.0 - g) / reduced;
        let (k, s) = (2.0 * (1.0 - a) * tau * reduced, a * tau * reduced);
        let ratio = (s + k) / s;
        let b = (ratio * ratio - 1.0).sqrt();
        let bc = b / (b * s).tanh();
        (1.0 - under * (ratio - bc)) / (ratio - under + bc)
    }

    /// The vector form agrees with the textbook form where every channel
    /// scatters and absorbs, and with its limits: a layer that does not
    /// absorb, `(ρ + s(1 − ρ)) / (1 + s(1 − ρ))`; a thick layer, the
    /// semi-infinite `R∞ = 1 + K/S − √((K/S)² + 2K/S)`; a layer that does
    /// not scatter, the background seen through it twice, `ρ e^(−2k)`.
    #[test]
    fn kubelka_munk_agrees_with_its_textbook_form_and_limits() {
        let close = |x: f64, y: f64, tol: f64, what: &str| {
            assert!(
                (x - y).abs() <= tol * y.abs().max(1e-300),
                "{what}: {x} vs {y}"
            );
        };
        let (tau, albedo, g, under) = ([0.3, 1.7, 6.0], [0.5, 0.9, 0.99], 0.4, [0.2, 0.6, 0.9]);
        let r = kubelka_munk(tau, albedo, g, under);
        for c in 0..3 {
            let want = textbook(tau[c], albedo[c], g, under[c]);
            close(r[c], want, 1e-12, &format!("channel {c}"));
        }
        // No absorption: s = τ, K = 0.
        let r = kubelka_munk([0.5, 2.0, 10.0], [1.0; 3], 0.0, [0.3; 3]);
        for (c, s) in [0.5f64, 2.0, 10.0].into_iter().enumerate() {
            let want = (0.3 + s * 0.7) / (1.0 + s * 0.7);
            close(r[c], want, 1e-12, &format!("no absorption, s {s}"));
        }
        // Thick: the background no longer shows.
        let r = kubelka_munk([200.0; 3], [0.3, 0.8, 0.95], 0.0, [0.0, 0.5, 1.0]);
        for (c, a) in [0.3f64, 0.8, 0.95].into_iter().enumerate() {
            let ks = 2.0 * (1.0 - a) / a;
            let want = 1.0 + ks - (ks * ks + 2.0 * ks).sqrt();
            close(r[c], want, 1e-12, &format!("thick, albedo {a}"));
        }
        // No scattering: k = 2τ.
        let r = kubelka_munk([0.1, 0.5, 2.0], [0.0; 3], 0.0, [0.8; 3]);
        for (c, t) in [0.1f64, 0.5, 2.0].into_iter().enumerate() {
            close(
                r[c],
                0.8 * (-4.0 * t).exp(),
                1e-15,
                &format!("absorber, τ {t}"),
            );
        }
    }
}
