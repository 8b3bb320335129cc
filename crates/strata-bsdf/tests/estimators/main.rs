//! The estimators: unidirectional and bidirectional walks, the control variate,
//! the closed-form samplers, sample against eval, and the pdfs against the
//! density of sample().
//!
//! One test binary per theme, so that the suite links a handful of times;
//! each file below is a module whose doc says what it checks.

#[path = "../common/mod.rs"]
mod common;

mod bidirectional;
mod closed_form_sampler;
mod layered_control_variate;
mod layered_pdf;
mod layered_sample_vs_eval;
mod mis_direct_lighting;
mod pdf_density;
