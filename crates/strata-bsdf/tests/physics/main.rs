//! The physics: kernels against closed forms and chi-square tests, layered
//! stacks against analytic oracles, furnaces, reciprocity, single scattering
//! and extremes, and strata against references made by other tools
//! (validation).
//!
//! One test binary per theme, so that the suite links a handful of times;
//! each file below is a module whose doc says what it checks.

#[path = "../common/mod.rs"]
mod common;

mod anisotropic_media;
mod kernels_chi2;
mod kernels_closed_forms;
mod layered_extremes;
mod layered_furnace;
mod layered_one_interface;
mod layered_oracles;
mod layered_reciprocity;
mod layered_single_scattering;
mod phase_sggx;
mod rough_coat;
mod spectra;
mod tilted_normals;
mod validation;
