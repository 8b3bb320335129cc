//! # strata-reports
//!
//! The harnesses behind strata's reports, outside the library a renderer
//! compiles: error against run time of every estimator ([`converge`]), the
//! stiff and extreme suite ([`stress`]) and the position-based brute-force
//! baseline they measure against ([`brute_force`]), and the side-by-side
//! comparison with pbrt-v4's layered BxDFs ([`pbrt`]). The CLI (`strata
//! converge`, `strata stress`) and docs/ are their users.

#![warn(missing_docs)]

pub mod brute_force;
pub mod converge;
pub mod pbrt;
pub mod stress;
pub mod vertex;
