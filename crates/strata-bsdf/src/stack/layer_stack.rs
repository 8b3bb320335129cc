//! The layer stack: a validated material, ready for the estimators, with
//! the ranges its values are checked against.

use super::description::{
    Distribution, InterfaceDesc, MaterialDesc, MediumDesc, Roughness, Shadowing,
};
use super::error::{MaterialError, StackError};
use super::json;
use super::phase::Phase;
use super::presets;
use super::samples::check_samples;
use super::spectrum::Spectrum;
use crate::interface::InterfaceLanes;
use crate::lane::{Lane, LaneMask, Rgb, V3};
use crate::microfacet::Microfacet;
use std::path::Path;

/// The range of an IOR (dielectric `ior`, `exterior_ior`). Outside it the
/// single-precision kernels cannot hold the relative IOR and its square
/// (docs/numerics.md); no physical material comes near either end.
pub const IOR_RANGE: [f64; 2] = [1e-3, 1e3];

/// An IOR: finite, > 0 and in [`IOR_RANGE`] ([`ior_rule`]).
pub(super) fn ior_in_range(layer: Option<usize>, field: &str, v: f64) -> Result<f64, StackError> {
    match ior_rule(v) {
        Some(why) => Err(StackError::new(layer, field, v, &why)),
        None => Ok(v),
    }
}

/// A conductor's absolute `eta` and `k` (RGB) from its description's
/// `preset`, or `eta` and `k`, checked.
pub(super) fn conductor_numbers(
    li: Option<usize>,
    preset: Option<&str>,
    eta: &Option<Spectrum>,
    k: &Option<Spectrum>,
) -> Result<([f64; 3], [f64; 3]), StackError> {
    let (e, kk) = match (preset, eta, k) {
        (Some(p), None, None) => presets::conductor(p).ok_or_else(|| {
            StackError::msg(
                li,
                "interface.preset",
                &format!(
                    "unknown conductor preset {p:?} (known: {})",
                    presets::names()
                ),
            )
        })?,
        (None, Some(e), Some(k)) => (
            colour(li, "interface.eta", e, in_range(0.0, true, MAX_CONDUCTOR))?,
            colour(li, "interface.k", k, in_range(0.0, false, MAX_CONDUCTOR))?,
        ),
        (Some(_), _, _) => {
            return Err(StackError::msg(
                li,
                "interface.preset",
                "give either a preset or eta and k, not both",
            ))
        }
        _ => {
            return Err(StackError::msg(
                li,
                "interface.eta",
                "a conductor needs a preset, or both eta and k",
            ))
        }
    };
    check_conductor(li, e, kk)?;
    Ok((e, kk))
}

/// Whether two IORs are one to the walks, which hold them in single
/// precision: the interface between them is invisible. (A rough interface of
/// relative IOR 1 refracts nothing and its microfacets have no refraction
/// half-vector; IORs a rounding apart, such as a texture's `1.45f32` and a
/// file's 1.45, are that interface.)
pub(super) fn index_matched(a: f64, b: f64) -> bool {
    a as f32 == b as f32
}

/// The largest optical depth (`thickness × sigma_t`) of a medium: beyond it
/// single precision cannot hold it. (Light does not cross 1e30 mean free
/// paths: at 100 the layer is already opaque to 1e-43.)
pub const MAX_OPTICAL_DEPTH: f64 = 1e30;

/// Largest conductor `eta` and `k`: the conductor Fresnel term squares
/// them (and squares `eta² - k²`) in single precision. Metals have k < 100.
pub const MAX_CONDUCTOR: f64 = 1e6;

/// Largest alpha: GGX and Beckmann lobes are already flat at alpha 3, and
/// beyond this single precision loses `α² tan²θ` near the horizon.
pub const MAX_ALPHA: f64 = 1e3;

/// The most layers a stack may have (the wavefront engine numbers its queues,
/// one per interface and per layer, in 16 bits; no material comes near).
pub const MAX_LAYERS: usize = 1024;

/// Smallest alpha of a rough interface: smaller positive values are raised to
/// it (below it GGX's peak overflows single precision). Zero means smooth.
pub const MIN_ALPHA: f64 = 1e-4;

/// What an interface is made of.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InterfaceKind {
    /// Refracts and reflects.
    Dielectric,
    /// Reflects, opaque.
    Conductor,
    /// Lambertian, opaque.
    Diffuse,
}

/// A validated interface.
#[derive(Clone, Debug, PartialEq)]
pub struct Interface {
    /// Kind.
    pub kind: InterfaceKind,
    /// IOR of the region above.
    pub n_above: f64,
    /// IOR of the region below (dielectric), else equal to `n_above`.
    pub n_below: f64,
    /// `[alpha_x, alpha_y]`; `[0, 0]` when smooth.
    pub alpha: [f64; 2],
    /// Smooth (delta lobes). Also true for an index-matched dielectric, which
    /// is invisible whatever its roughness.
    pub smooth: bool,
    /// Normal distribution.
    pub distribution: Distribution,
    /// Shadowing form.
    pub shadowing: Shadowing,
    /// Conductor IOR relative to the region above (real part).
    pub eta: [f64; 3],
    /// Conductor IOR relative to the region above (imaginary part).
    pub k: [f64; 3],
    /// Diffuse albedo.
    pub albedo: [f64; 3],
    /// Unit shading normal in the slab's frame; `[0, 0, 1]` when untilted
    /// (also for an index-matched dielectric, which no normal can make
    /// visible).
    pub normal: [f64; 3],
}

impl Interface {
    /// Its shading normal is not the slab's.
    pub fn tilted(&self) -> bool {
        self.normal != [0.0, 0.0, 1.0]
    }
}

/// A validated homogeneous medium.
#[derive(Clone, Debug, PartialEq)]
pub struct Medium {
    /// Geometric thickness.
    pub thickness: f64,
    /// Extinction per unit thickness, per channel.
    pub sigma_t: [f64; 3],
    /// Single-scattering albedo per channel.
    pub albedo: [f64; 3],
    /// Phase function.
    pub phase: Phase,
}

impl Medium {
    /// Optical depth per channel.
    pub fn optical_depth(&self) -> [f64; 3] {
        self.sigma_t.map(|s| s * self.thickness)
    }
    /// Some channel scatters (otherwise the medium only absorbs).
    pub fn scatters(&self) -> bool {
        self.albedo
            .iter()
            .zip(self.sigma_t)
            .any(|(&a, s)| a > 0.0 && s > 0.0)
    }
    /// Some channel attenuates at all.
    pub fn attenuates(&self) -> bool {
        self.thickness > 0.0 && self.sigma_t.iter().any(|&s| s > 0.0)
    }
}

/// What a stack contains: the estimators skip what a stack does not use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Features {
    /// Some layer scatters.
    pub scattering: bool,
    /// Some layer attenuates without scattering (pure absorber).
    pub absorbing_only: bool,
    /// Some medium has a different sigma_t per channel.
    pub chromatic_sigma_t: bool,
    /// Some interface is rough.
    pub rough: bool,
    /// Some interface is smooth.
    pub smooth: bool,
    /// The bottom interface is a dielectric.
    pub transmissive: bool,
    /// Number of interfaces.
    pub interfaces: usize,
}

/// A validated layered material: interfaces top to bottom, media between.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerStack {
    pub(super) interfaces: Vec<Interface>,
    /// `media[l]` lies between interfaces `l` and `l + 1`.
    pub(super) media: Vec<Option<Medium>>,
    exterior_above: f64,
    pub(super) two_sided: bool,
    desc: MaterialDesc,
}

#[inline]
fn finite(layer: Option<usize>, field: &str, v: f64) -> Result<f64, StackError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(StackError::new(layer, field, v, "must be a finite number"))
    }
}

/// The slab's normal: an untilted interface's shading normal.
pub(super) const Z: [f64; 3] = [0.0, 0.0, 1.0];

/// A shading normal as given (`None`: untilted), normalized: finite, of
/// nonzero length and pointing into the region above (`z > 0`).
pub(super) fn shading_normal(
    layer: Option<usize>,
    n: Option<[f64; 3]>,
) -> Result<[f64; 3], StackError> {
    let Some(n) = n else { return Ok(Z) };
    let field = "interface.normal";
    if !n.iter().all(|x| x.is_finite()) {
        return Err(StackError::new_rgb(layer, field, n, "must be finite"));
    }
    // Scaled by the largest component first, so no finite vector overflows.
    let m = n.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if m == 0.0 {
        return Err(StackError::new_rgb(layer, field, n, "has zero length"));
    }
    let s = n.map(|x| x / m);
    let l = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
    let u = s.map(|x| x / l);
    if u[2] <= 0.0 {
        return Err(StackError::new_rgb(
            layer,
            field,
            n,
            "must point into the region above the interface (z > 0)",
        ));
    }
    Ok(if u[0] == 0.0 && u[1] == 0.0 { Z } else { u })
}

#[inline]
fn finite_rgb(layer: Option<usize>, field: &str, v: [f64; 3]) -> Result<[f64; 3], StackError> {
    for x in v {
        if !x.is_finite() {
            return Err(StackError::new_rgb(
                layer,
                field,
                v,
                "must be finite numbers",
            ));
        }
    }
    Ok(v)
}

/// Numbers in `[0, 1]` (an albedo).
#[inline]
pub(super) fn unit_rgb(
    layer: Option<usize>,
    field: &str,
    v: [f64; 3],
) -> Result<[f64; 3], StackError> {
    let v = finite_rgb(layer, field, v)?;
    if v.iter().any(|&x| !(0.0..=1.0).contains(&x)) {
        return Err(StackError::new_rgb(layer, field, v, "must be in [0, 1]"));
    }
    Ok(v)
}

/// A conductor's `eta` (> 0) and `k` (>= 0), both at most [`MAX_CONDUCTOR`].
pub(super) fn check_conductor(
    layer: Option<usize>,
    e: [f64; 3],
    kk: [f64; 3],
) -> Result<(), StackError> {
    let e = finite_rgb(layer, "interface.eta", e)?;
    let kk = finite_rgb(layer, "interface.k", kk)?;
    if e.iter().any(|&x| x <= 0.0) {
        return Err(StackError::new_rgb(
            layer,
            "interface.eta",
            e,
            "must be > 0",
        ));
    }
    if kk.iter().any(|&x| x < 0.0) {
        return Err(StackError::new_rgb(
            layer,
            "interface.k",
            kk,
            "must be >= 0",
        ));
    }
    // The message is made only for an error: a per-query row checks its
    // conductor's values on every write.
    let too_big = || format!("must be at most {MAX_CONDUCTOR}");
    if e.iter().any(|&x| x > MAX_CONDUCTOR) {
        return Err(StackError::new_rgb(layer, "interface.eta", e, &too_big()));
    }
    if kk.iter().any(|&x| x > MAX_CONDUCTOR) {
        return Err(StackError::new_rgb(layer, "interface.k", kk, &too_big()));
    }
    Ok(())
}

/// A medium's thickness: finite and >= 0.
#[inline]
pub(super) fn thickness(layer: Option<usize>, h: f64) -> Result<f64, StackError> {
    let h = finite(layer, "medium.thickness", h)?;
    if h < 0.0 {
        return Err(StackError::new(
            layer,
            "medium.thickness",
            h,
            "must be >= 0",
        ));
    }
    Ok(h)
}

/// A medium's extinction: finite and >= 0.
#[inline]
pub(super) fn sigma_t(layer: Option<usize>, st: [f64; 3]) -> Result<[f64; 3], StackError> {
    let st = finite_rgb(layer, "medium.sigma_t", st)?;
    if st.iter().any(|&x| x < 0.0) {
        return Err(StackError::new_rgb(
            layer,
            "medium.sigma_t",
            st,
            "must be >= 0",
        ));
    }
    Ok(st)
}

/// A medium's optical depth `h × sigma_t`: at most [`MAX_OPTICAL_DEPTH`].
#[inline]
pub(super) fn check_depth(layer: Option<usize>, h: f64, st: [f64; 3]) -> Result<(), StackError> {
    if st.iter().any(|&x| x * h > MAX_OPTICAL_DEPTH) {
        return Err(StackError::new_rgb(
            layer,
            "medium.sigma_t",
            st,
            &format!("gives an optical depth (thickness {h} × sigma_t) above {MAX_OPTICAL_DEPTH}"),
        ));
    }
    Ok(())
}

#[inline]
pub(super) fn roughness(layer: usize, r: Roughness) -> Result<([f64; 2], bool), StackError> {
    let a = r.alphas();
    for x in a {
        if !x.is_finite() || x < 0.0 {
            return Err(StackError::new(
                Some(layer),
                "interface.roughness",
                x,
                "must be finite and >= 0",
            ));
        }
        if x > MAX_ALPHA {
            return Err(StackError::new(
                Some(layer),
                "interface.roughness",
                x,
                &format!("must be at most {MAX_ALPHA}"),
            ));
        }
    }
    if a == [0.0, 0.0] {
        Ok(([0.0, 0.0], true))
    } else {
        Ok((a.map(|x| x.max(MIN_ALPHA)), false))
    }
}

/// The problem with one value of an IOR (a sample of a spectrum or of a
/// dispersion law), or `None`.
fn ior_rule(v: f64) -> Option<String> {
    if !v.is_finite() {
        Some("must be a finite number".into())
    } else if v <= 0.0 {
        Some("must be > 0".into())
    } else if !(IOR_RANGE[0]..=IOR_RANGE[1]).contains(&v) {
        Some(format!("must be in [{}, {}]", IOR_RANGE[0], IOR_RANGE[1]))
    } else {
        None
    }
}

/// The wavelengths over which a dispersion law's IOR is checked, in nm: the
/// range of the CIE tables and of spectral renderers' wavelengths. (A
/// two-term Cauchy law is monotonic, so its ends bound it.)
const LAW_RANGE_NM: [f64; 2] = [360.0, 830.0];

/// The one IOR an RGB query uses (the value, or a spectrum's or law's value
/// at the d line), its spectrum's samples or its law checked like a number.
fn ior_value(layer: Option<usize>, ior: &Spectrum) -> Result<f64, StackError> {
    let field = "interface.ior";
    match ior {
        Spectrum::Grey(v) => ior_in_range(layer, field, *v),
        Spectrum::Rgb(c) => Err(StackError::new_rgb(
            layer,
            field,
            *c,
            "an IOR is one number or a spectrum, not one per channel (a refracted direction is one per walk)",
        )),
        Spectrum::Tabulated { nm, values } => {
            check_samples(layer, field, nm, values, ior_rule)?;
            Ok(ior.d_line())
        }
        Spectrum::Cauchy { cauchy } => {
            let law = "interface.ior.cauchy";
            let given = format!("[{}, {}]", cauchy[0], cauchy[1]);
            if !cauchy.iter().all(|x| x.is_finite()) {
                return Err(StackError {
                    value: given,
                    ..StackError::msg(layer, law, "must be finite numbers")
                });
            }
            check_law(layer, law, &given, ior)?;
            Ok(ior.d_line())
        }
        Spectrum::Abbe { nd, abbe } => {
            let nd = ior_in_range(layer, "interface.ior.nd", *nd)?;
            if !abbe.is_finite() || *abbe <= 0.0 {
                return Err(StackError::new(
                    layer,
                    "interface.ior.abbe",
                    *abbe,
                    "must be a finite number > 0",
                ));
            }
            check_law(layer, field, &format!("{{ nd = {nd}, abbe = {abbe} }}"), ior)?;
            Ok(nd)
        }
    }
}

/// A dispersion law's IOR at both ends of [`LAW_RANGE_NM`] passes
/// [`ior_rule`].
fn check_law(
    layer: Option<usize>,
    field: &str,
    given: &str,
    law: &Spectrum,
) -> Result<(), StackError> {
    for nm in LAW_RANGE_NM {
        let n = law.at(nm);
        if let Some(problem) = ior_rule(n) {
            return Err(StackError {
                value: given.to_string(),
                ..StackError::msg(
                    layer,
                    field,
                    &format!("gives n = {n} at {nm} nm, which {problem}"),
                )
            });
        }
    }
    Ok(())
}

/// The RGB numbers of a coloured field: a number or RGB triple as given
/// (checked afterwards, by the field's own checks), a tabulated spectrum's
/// reduction once every sample passes `rule`.
fn colour(
    layer: Option<usize>,
    field: &str,
    v: &Spectrum,
    rule: impl Fn(f64) -> Option<String>,
) -> Result<[f64; 3], StackError> {
    match v {
        Spectrum::Grey(_) | Spectrum::Rgb(_) => Ok(v.rgb()),
        Spectrum::Tabulated { nm, values } => {
            check_samples(layer, field, nm, values, rule)?;
            Ok(v.rgb())
        }
        Spectrum::Cauchy { .. } | Spectrum::Abbe { .. } => Err(StackError::msg(
            layer,
            field,
            "a dispersion law (`cauchy`, or `nd` and `abbe`) is for a dielectric's `ior` only",
        )),
    }
}

/// The rule of one value in `[lo, hi]`, as the RGB checks word it.
fn in_range(lo: f64, lo_open: bool, hi: f64) -> impl Fn(f64) -> Option<String> {
    move |v: f64| {
        if !v.is_finite() {
            Some("must be a finite number".into())
        } else if lo_open && v <= lo {
            Some(format!("must be > {lo}"))
        } else if v < lo {
            Some(format!("must be >= {lo}"))
        } else if v > hi {
            Some(format!("must be at most {hi}"))
        } else {
            None
        }
    }
}

/// The rule of an albedo's values: in [0, 1].
fn unit_rule(v: f64) -> Option<String> {
    if !v.is_finite() {
        Some("must be a finite number".into())
    } else {
        (!(0.0..=1.0).contains(&v)).then(|| "must be in [0, 1]".to_string())
    }
}

impl LayerStack {
    /// Validates a description and builds the stack.
    ///
    /// ```
    /// use strata_bsdf::stack::{LayerStack, MaterialDesc};
    /// let desc: MaterialDesc = toml::from_str(r#"
    ///     [[layers]]
    ///     interface = { kind = "dielectric", ior = 1.5 }
    ///     [[layers]]
    ///     interface = { kind = "diffuse", albedo = 0.8 }
    /// "#).unwrap();
    /// let stack = LayerStack::new(&desc).unwrap();
    /// assert_eq!(stack.interfaces().len(), 2);
    /// ```
    pub fn new(desc: &MaterialDesc) -> Result<Self, StackError> {
        let n0 = ior_in_range(None, "exterior_ior", desc.exterior_ior)?;
        if desc.layers.is_empty() {
            return Err(StackError::msg(
                None,
                "layers",
                "the stack is empty: give at least one layer",
            ));
        }
        let n = desc.layers.len();
        if n > MAX_LAYERS {
            return Err(StackError::msg(
                None,
                "layers",
                &format!("{n} layers: at most {MAX_LAYERS} are supported"),
            ));
        }
        let mut interfaces = Vec::with_capacity(n);
        let mut media = Vec::with_capacity(n.saturating_sub(1));
        let mut n_above = n0;
        for (i, layer) in desc.layers.iter().enumerate() {
            let li = Some(i);
            let last = i + 1 == n;
            let normal = layer.interface.normal();
            let iface = match &layer.interface {
                InterfaceDesc::Dielectric {
                    ior,
                    roughness: r,
                    distribution,
                    shadowing,
                    ..
                } => {
                    let ior = ior_value(li, ior)?;
                    let (alpha, smooth) = roughness(i, *r)?;
                    let matched = index_matched(ior, n_above);
                    Interface {
                        kind: InterfaceKind::Dielectric,
                        n_above,
                        n_below: ior,
                        alpha: if matched { [0.0; 2] } else { alpha },
                        smooth: smooth || matched,
                        distribution: *distribution,
                        shadowing: *shadowing,
                        eta: [1.0; 3],
                        k: [0.0; 3],
                        albedo: [0.0; 3],
                        normal: if matched {
                            Z
                        } else {
                            shading_normal(li, normal)?
                        },
                    }
                }
                InterfaceDesc::Conductor {
                    preset,
                    eta,
                    k,
                    roughness: r,
                    distribution,
                    shadowing,
                    ..
                } => {
                    if !last {
                        return Err(StackError::msg(
                            li,
                            "interface.kind",
                            "a conductor is opaque and must be the last layer",
                        ));
                    }
                    let (e, kk) = conductor_numbers(li, preset.as_deref(), eta, k)?;
                    let (alpha, smooth) = roughness(i, *r)?;
                    Interface {
                        kind: InterfaceKind::Conductor,
                        n_above,
                        n_below: n_above,
                        alpha,
                        smooth,
                        distribution: *distribution,
                        shadowing: *shadowing,
                        eta: e.map(|x| x / n_above),
                        k: kk.map(|x| x / n_above),
                        albedo: [0.0; 3],
                        normal: shading_normal(li, normal)?,
                    }
                }
                InterfaceDesc::Diffuse { albedo, .. } => {
                    if !last {
                        return Err(StackError::msg(
                            li,
                            "interface.kind",
                            "a diffuse interface is opaque and must be the last layer",
                        ));
                    }
                    let field = "interface.albedo";
                    let a = unit_rgb(li, field, colour(li, field, albedo, unit_rule)?)?;
                    Interface {
                        kind: InterfaceKind::Diffuse,
                        n_above,
                        n_below: n_above,
                        alpha: [0.0; 2],
                        smooth: false,
                        distribution: Distribution::Ggx,
                        shadowing: Shadowing::Correlated,
                        eta: [1.0; 3],
                        k: [0.0; 3],
                        albedo: a,
                        normal: shading_normal(li, normal)?,
                    }
                }
            };
            n_above = iface.n_below;
            interfaces.push(iface);

            match (&layer.medium, last) {
                (Some(_), true) => return Err(StackError::msg(
                    li,
                    "medium",
                    "the last layer cannot have a medium: below the last interface is the exterior",
                )),
                (None, true) => {}
                (None, false) => media.push(None),
                (Some(m), false) => media.push(Some(Self::parse_medium(i, m)?)),
            }
        }
        Ok(LayerStack {
            interfaces,
            media,
            exterior_above: n0,
            two_sided: desc.two_sided,
            desc: desc.clone(),
        })
    }

    fn parse_medium(i: usize, m: &MediumDesc) -> Result<Medium, StackError> {
        let li = Some(i);
        let h = thickness(li, m.thickness)?;
        let deep = || {
            format!("gives an optical depth (thickness {h} × sigma_t) above {MAX_OPTICAL_DEPTH}")
        };
        let st_rule = |v: f64| {
            in_range(0.0, false, f64::MAX)(v).or_else(|| (v * h > MAX_OPTICAL_DEPTH).then(deep))
        };
        let st = sigma_t(li, colour(li, "medium.sigma_t", &m.sigma_t, st_rule)?)?;
        check_depth(li, h, st)?;
        let field = "medium.albedo";
        let al = unit_rgb(li, field, colour(li, field, &m.albedo, unit_rule)?)?;
        let phase = Phase::new(i, &m.phase)?;
        Ok(Medium {
            thickness: h,
            sigma_t: st,
            albedo: al,
            phase,
        })
    }

    /// Parses TOML text and builds the stack.
    pub fn from_toml_str(s: &str) -> Result<Self, MaterialError> {
        let d: MaterialDesc = toml::from_str(s).map_err(|e| MaterialError::Parse {
            format: "TOML",
            message: e.to_string(),
        })?;
        Ok(LayerStack::new(&d)?)
    }

    /// Parses JSON text and builds the stack. An error in the values names
    /// their path (`layers[0].interface: invalid type: string "NaN",
    /// expected `ior` to be a number`), a syntax error the line and column.
    pub fn from_json_str(s: &str) -> Result<Self, MaterialError> {
        let parse = |message: String| MaterialError::Parse {
            format: "JSON",
            message,
        };
        let tree: serde_json::Value = serde_json::from_str(s).map_err(|e| parse(e.to_string()))?;
        let d: MaterialDesc = json::from_tree(&tree).map_err(|e| parse(e.to_string()))?;
        Ok(LayerStack::new(&d)?)
    }

    /// Reads a material file: `.json` as JSON, anything else as TOML.
    pub fn from_path(path: impl AsRef<Path>) -> Result<Self, MaterialError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| MaterialError::Io {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        let json = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"));
        if json {
            Self::from_json_str(&text)
        } else {
            Self::from_toml_str(&text)
        }
    }

    /// The description this stack was built from.
    pub fn desc(&self) -> &MaterialDesc {
        &self.desc
    }
    /// Interfaces, top to bottom.
    pub fn interfaces(&self) -> &[Interface] {
        &self.interfaces
    }
    /// Interface `i`.
    ///
    /// # Panics
    /// If `i` is not below [`LayerStack::len`] (as a slice's index).
    pub fn interface(&self, i: usize) -> &Interface {
        &self.interfaces[i]
    }
    /// Number of interfaces.
    pub fn len(&self) -> usize {
        self.interfaces.len()
    }
    /// Always false: a stack has at least one interface.
    pub fn is_empty(&self) -> bool {
        false
    }
    /// The medium between interfaces `l` and `l + 1`, if any.
    pub fn medium(&self, l: usize) -> Option<&Medium> {
        self.media.get(l).and_then(|m| m.as_ref())
    }
    /// IOR of the exterior above.
    pub fn exterior_above(&self) -> f64 {
        self.exterior_above
    }
    /// IOR of the exterior below (for a transmissive stack; otherwise the IOR
    /// of the region above the opaque bottom).
    pub fn exterior_below(&self) -> f64 {
        self.interfaces.last().map(|i| i.n_below).unwrap_or(1.0)
    }
    /// The bottom interface is a dielectric, so light can pass through.
    pub fn transmissive(&self) -> bool {
        self.interfaces.last().map(|i| i.kind) == Some(InterfaceKind::Dielectric)
    }
    /// Mirror light from below an opaque stack (see conventions).
    pub fn two_sided(&self) -> bool {
        self.two_sided
    }

    /// What the stack contains.
    pub fn features(&self) -> Features {
        let mut f = Features {
            transmissive: self.transmissive(),
            interfaces: self.len(),
            ..Features::default()
        };
        for i in &self.interfaces {
            if i.smooth {
                f.smooth = true;
            } else if i.kind != InterfaceKind::Diffuse {
                f.rough = true;
            }
        }
        for m in self.media.iter().flatten() {
            if m.scatters() {
                f.scattering = true;
            } else if m.attenuates() {
                f.absorbing_only = true;
            }
            if m.sigma_t[0] != m.sigma_t[1] || m.sigma_t[1] != m.sigma_t[2] {
                f.chromatic_sigma_t = true;
            }
        }
        f
    }

    /// Interface `i` splatted across lanes.
    pub fn interface_lanes<L: Lane>(&self, i: usize) -> InterfaceLanes<L> {
        let it = &self.interfaces[i];
        let m = |b: bool| L::Mask::splat(b);
        // Smooth lanes get a harmless alpha so no discarded lane divides by zero.
        let alpha = if it.smooth { [1.0, 1.0] } else { it.alpha };
        InterfaceLanes {
            n_above: L::splat(it.n_above),
            n_below: L::splat(it.n_below),
            mf: Microfacet {
                alpha_x: L::splat(alpha[0]),
                alpha_y: L::splat(alpha[1]),
                beckmann: m(it.distribution == Distribution::Beckmann),
                separable: m(it.shadowing == Shadowing::Separable),
            },
            smooth: m(it.smooth),
            dielectric: m(it.kind == InterfaceKind::Dielectric),
            conductor: m(it.kind == InterfaceKind::Conductor),
            diffuse: m(it.kind == InterfaceKind::Diffuse),
            eta: Rgb::from_array(it.eta),
            k: Rgb::from_array(it.k),
            albedo: Rgb::from_array(it.albedo),
            normal: V3::new(
                L::splat(it.normal[0]),
                L::splat(it.normal[1]),
                L::splat(it.normal[2]),
            ),
            tilted: it.tilted(),
            adjoint: false,
            run_all: false,
        }
    }
}
