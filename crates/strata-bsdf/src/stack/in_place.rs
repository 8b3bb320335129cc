//! Per-query numbers written into a built stack in place: the rows of a
//! material table.
//!
//! A renderer's textures change a few numbers of one material per query.
//! [`LayerStack::with_set`] answers such a query exactly as a material file
//! would, at the cost of a description rebuilt, parsed and validated whole.
//! The fields below need only their own checks, the same functions
//! [`LayerStack::new`] runs on them, so a row can be written over a copy of
//! the built stack: its thickness, extinction and single-scattering albedo,
//! an interface's roughness and albedo, a conductor's `eta` and `k`, and a
//! dielectric's IOR (a dispersive IOR at a query's wavelength). An IOR moves
//! what depends on it as [`LayerStack::new`] derives it: the next
//! interface's IOR above, a conductor's constants relative to it, and which
//! dielectrics are index-matched (invisible); so a row writes its IORs
//! before its other fields ([`SetPath::writes_ior`]). The exterior's IOR,
//! shading normals and phase parameters are not written in place.

use super::description::InterfaceDesc;
use super::error::StackError;
use super::layer_stack::{
    check_conductor, check_depth, conductor_numbers, index_matched, ior_in_range, roughness,
    shading_normal, sigma_t, thickness, unit_rgb, LayerStack, Z,
};
use super::set::{InterfaceField, MediumField, SetPath, Target};
use super::shape::LayerShape;
use super::Roughness;

impl SetPath {
    /// Whether [`LayerStack::write`] takes this path.
    pub fn in_place(&self) -> bool {
        matches!(
            self.target,
            Target::Medium(
                _,
                MediumField::Thickness | MediumField::SigmaT | MediumField::Albedo
            ) | Target::Interface(
                _,
                InterfaceField::Ior
                    | InterfaceField::Roughness
                    | InterfaceField::Albedo
                    | InterfaceField::Eta
                    | InterfaceField::K
            )
        )
    }

    /// Whether this path is a dielectric's IOR: a row writes it before its
    /// other fields, which [`LayerStack::write`] derives from it.
    pub fn writes_ior(&self) -> bool {
        matches!(self.target, Target::Interface(_, InterfaceField::Ior))
    }
}

impl LayerStack {
    /// Writes `v` (one number, or three for a colour) at `path`, a path of
    /// this stack that [`SetPath::in_place`] takes, checking it as
    /// [`LayerStack::new`] checks the field. The stack's description is not
    /// updated: a written stack is a row's numbers, not a material to hand
    /// out. The optical depth, which spans two fields, is checked by
    /// [`LayerStack::check_depths`] once the row is written.
    ///
    /// # Panics
    /// If `path` is not in place or not in this stack (the caller checks
    /// its columns first).
    pub fn write(&mut self, path: &SetPath, v: &[f64]) -> Result<(), StackError> {
        let rgb = match *v {
            [x] => [x; 3],
            [r, g, b] => [r, g, b],
            _ => panic!("a value is 1 or 3 numbers"),
        };
        match path.target {
            Target::Medium(l, f) => {
                let li = Some(l);
                let m = self.media[l].as_mut().expect("a checked path");
                match f {
                    MediumField::Thickness => m.thickness = thickness(li, v[0])?,
                    MediumField::SigmaT => m.sigma_t = sigma_t(li, rgb)?,
                    MediumField::Albedo => m.albedo = unit_rgb(li, "medium.albedo", rgb)?,
                    _ => panic!("not in place: {path}"),
                }
            }
            Target::Interface(i, f) => {
                let li = Some(i);
                let it = &mut self.interfaces[i];
                match f {
                    InterfaceField::Roughness => {
                        let (alpha, smooth) = roughness(i, Roughness::Isotropic(v[0]))?;
                        // An index-matched dielectric stays invisible.
                        let matched = index_matched(it.n_below, it.n_above)
                            && it.kind == super::InterfaceKind::Dielectric;
                        if !matched {
                            it.alpha = alpha;
                            it.smooth = smooth;
                        }
                    }
                    InterfaceField::Albedo => it.albedo = unit_rgb(li, "interface.albedo", rgb)?,
                    InterfaceField::Eta | InterfaceField::K => {
                        // Stored relative to the region above; the other of the two is only checked.
                        let n = it.n_above;
                        let (e, k) = match f {
                            InterfaceField::Eta => (rgb, it.k.map(|x| x * n)),
                            _ => (it.eta.map(|x| x * n), rgb),
                        };
                        check_conductor(li, e, k)?;
                        match f {
                            InterfaceField::Eta => it.eta = rgb.map(|x| x / n),
                            _ => it.k = rgb.map(|x| x / n),
                        }
                    }
                    InterfaceField::Ior => {
                        let n = ior_in_range(li, "interface.ior", v[0])?;
                        self.set_ior(i, n)?;
                    }
                    _ => panic!("not in place: {path}"),
                }
            }
            Target::ExteriorIor => panic!("not in place: {path}"),
        }
        Ok(())
    }

    /// Sets dielectric `i`'s IOR (the region below it) to `n`, and what
    /// [`LayerStack::new`] derives from it: the next interface's IOR above
    /// (a conductor's or a diffuse interface's below too), a conductor's
    /// constants relative to it (from its description: a later column of
    /// its own replaces them), and the index matching of both interfaces.
    fn set_ior(&mut self, i: usize, n: f64) -> Result<(), StackError> {
        self.interfaces[i].n_below = n;
        self.match_index(i)?;
        let Some(next) = self.interfaces.get_mut(i + 1) else {
            return Ok(());
        };
        next.n_above = n;
        match next.kind {
            super::InterfaceKind::Dielectric => self.match_index(i + 1)?,
            super::InterfaceKind::Diffuse => next.n_below = n,
            super::InterfaceKind::Conductor => {
                next.n_below = n;
                let InterfaceDesc::Conductor { preset, eta, k, .. } =
                    &self.desc().layers[i + 1].interface
                else {
                    unreachable!("a conductor's description");
                };
                let (e, k) = conductor_numbers(Some(i + 1), preset.as_deref(), eta, k)?;
                let next = &mut self.interfaces[i + 1];
                next.eta = e.map(|x| x / n);
                next.k = k.map(|x| x / n);
            }
        }
        Ok(())
    }

    /// Dielectric `i` after its IORs changed: invisible (smooth, untilted)
    /// where they match, else with its description's roughness and normal,
    /// as [`LayerStack::new`] builds it.
    fn match_index(&mut self, i: usize) -> Result<(), StackError> {
        let it = &self.interfaces[i];
        let matched = index_matched(it.n_below, it.n_above);
        let (alpha, smooth, normal) = if matched {
            ([0.0; 2], true, Z)
        } else {
            let InterfaceDesc::Dielectric { roughness: r, .. } = &self.desc().layers[i].interface
            else {
                unreachable!("a dielectric's description");
            };
            let (alpha, smooth) = roughness(i, *r)?;
            let normal = self.desc().layers[i].interface.normal();
            (alpha, smooth, shading_normal(Some(i), normal)?)
        };
        let it = &mut self.interfaces[i];
        (it.alpha, it.smooth, it.normal) = (alpha, smooth, normal);
        Ok(())
    }

    /// Checks what [`LayerStack::write`] leaves: every medium's optical
    /// depth within [`super::MAX_OPTICAL_DEPTH`].
    pub fn check_depths(&self) -> Result<(), StackError> {
        for (l, m) in self.media.iter().enumerate() {
            if let Some(m) = m {
                check_depth(Some(l), m.thickness, m.sigma_t)?;
            }
        }
        Ok(())
    }

    /// [`LayerStack::same_shape`] for this stack written from `other` at
    /// `paths` alone (paths [`SetPath::in_place`] takes): only the parts a
    /// write there can change are compared. A write changes no phase
    /// function, distribution, shadowing or interface kind: only a medium's
    /// kind and greyness (its phase's kind follows its kind), an interface's
    /// smoothness, and (an IOR, by index matching) two interfaces'
    /// smoothness and tilt.
    pub fn same_shape_at(&self, other: &LayerStack, paths: &[&SetPath]) -> bool {
        paths.iter().all(|p| match p.target {
            Target::Medium(l, _) => match (&self.media[l], &other.media[l]) {
                (Some(a), Some(b)) => a.kind() == b.kind() && a.grey() == b.grey(),
                (a, b) => a.is_none() && b.is_none(),
            },
            // An IOR matches or unmatches this interface and the next.
            Target::Interface(i, InterfaceField::Ior) => (i..(i + 2).min(self.len()))
                .all(|j| self.interface_shape(j) == other.interface_shape(j)),
            Target::Interface(i, _) => self.interfaces[i].smooth == other.interfaces[i].smooth,
            Target::ExteriorIor => self.same_shape(other),
        })
    }

    /// Whether this stack, written from `other` at `paths`, runs on
    /// `other`'s shape: [`LayerStack::same_shape_at`], or a grey extinction
    /// where `other`'s is chromatic; and the same exterior below. A chromatic walk answers a grey layer
    /// with the same expectation (its channels' free flights then agree),
    /// not bit for bit what a grey walk answers.
    pub fn runs_on_at(&self, other: &LayerStack, paths: &[&SetPath]) -> bool {
        paths.iter().all(|p| match p.target {
            // The last interface's IOR is the exterior's below, which the
            // BSDF reads from its own stack (the transport mode's η²).
            Target::Interface(i, InterfaceField::Ior) if i + 1 == self.len() => {
                self.exterior_below() == other.exterior_below()
            }
            Target::Medium(l, _) => match (&self.media[l], &other.media[l]) {
                (Some(a), Some(b)) => a.kind() == b.kind() && (a.grey() || !b.grey()),
                (a, b) => a.is_none() && b.is_none(),
            },
            _ => self.same_shape_at(other, &[p]),
        })
    }

    /// [`LayerStack::runs_on_at`] for every part: [`LayerStack::same_shape`]
    /// but for grey extinctions where `other`'s are chromatic.
    pub fn runs_on(&self, other: &LayerStack) -> bool {
        let layer = |l: usize| match (self.layer_shape(l), other.layer_shape(l)) {
            (
                LayerShape::Medium { kind, grey, phase },
                LayerShape::Medium {
                    kind: k,
                    grey: g,
                    phase: p,
                },
            ) => kind == k && phase == p && (grey || !g),
            (a, b) => a == b,
        };
        self.two_sided == other.two_sided
            && self.len() == other.len()
            && (0..self.len()).all(|i| self.interface_shape(i) == other.interface_shape(i))
            && (0..self.media.len()).all(layer)
    }

    /// Whether this stack has `other`'s shape: compared part by part,
    /// without building either [`super::Shape`].
    pub fn same_shape(&self, other: &LayerStack) -> bool {
        self.two_sided == other.two_sided
            && self.len() == other.len()
            && (0..self.len()).all(|i| self.interface_shape(i) == other.interface_shape(i))
            && (0..self.media.len()).all(|l| self.layer_shape(l) == other.layer_shape(l))
    }
}
