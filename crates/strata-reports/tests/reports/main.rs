//! The report harnesses: the brute-force baseline, the convergence report,
//! the comparison with pbrt-v4 and the stiff suite. One binary, so that the
//! suite links once; each module's doc says what it checks.

#[path = "../../../strata-bsdf/tests/common/mod.rs"]
mod common;

mod brute_force;
mod converge;
mod pbrt;
mod stress;
mod vertex;
