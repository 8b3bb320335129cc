//! Estimators of the layered BSDF.
//!
//! * [`scalar`]: the reference, one walk at a time, generic over `f32` (the
//!   reference) and `f64` (the accuracy oracle).
//! * [`events`]: the event kernels both engines call, written once over lanes.
//! * [`layout`]: the stack's topology as the walks see it.
//! * [`bidir`]: the bidirectional estimator of `eval`.
//! * [`density`]: the density walk, the density of `sample` at a direction.
//! * [`pdf`]: the approximate and unbiased pdfs of `sample` from it.
//! * [`coat_lambertian`]: a coat over a layer over a Lambertian base, which
//!   `Auto` answers without walks ([`closed_form`] under a smooth coat,
//!   [`rough_coat`] under a rough one; [`coat_return`], the integral both
//!   need), or with walks of collided paths only.
//!
//! Both follow `docs/method.md`; the differences from the paper and from the
//! authors' code are listed in `docs/architecture.md`.

mod accumulate;
pub mod bidir;
pub mod body_return;
pub mod closed_form;
pub(crate) mod coat_and_base;
pub mod coat_lambertian;
pub mod coat_return;
pub mod density;
mod estimate;
pub mod events;
pub mod layout;
pub mod lobe_pdf;
mod orient;
pub mod params;
pub mod pdf;
pub mod rough_coat;
pub mod scalar;
mod settings;
mod terms;
pub mod wavefront;

pub use crate::math::MIN_COS;
pub use accumulate::{BlockReducer, MeanVar, BLOCK};
pub use estimate::{Albedo, Estimate, WalkSample};
#[doc(hidden)]
pub use orient::orient;
pub use settings::{Settings, MAX_WALKS};
pub use terms::Terms;
