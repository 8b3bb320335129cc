//! The layer stack: a validated material, ready for the estimators.
//!
//! A [`MaterialDesc`] (read from TOML or JSON, or built in code) becomes a
//! [`LayerStack`] through [`LayerStack::new`], which checks every value and
//! reports the first problem as a [`StackError`] naming the layer, the field and
//! the value. Once built, a stack is immutable and the kernels never fail on it.
//!
//! The stack is in `layer_stack`; `shape` (what fixes a walk's schedule) and
//! `set` (a per-query override of a number by its path) add to it. Coloured
//! values and IORs may be spectra (`spectrum`, checked sample by sample in
//! `samples`); the conductor presets are measured spectra (`presets`, with
//! the tables in `measured`); `spectral_fields` lists the fields whose value
//! varies with wavelength.

mod description;
mod error;
mod in_place;
mod json;
mod layer_stack;
mod lobes;
mod measured;
mod phase;
pub mod presets;
mod samples;
mod set;
mod shape;
mod spectral_fields;
pub mod spectrum;

pub(crate) use description::tables_only;
pub use description::{
    ComponentDesc, ComponentKind, Distribution, FlakeScattering, Flakes, InterfaceDesc, LayerDesc,
    MaterialDesc, MediumDesc, PhaseDesc, Roughness, Shadowing,
};
pub use error::{MaterialError, StackError};
pub use layer_stack::{
    Features, Interface, InterfaceKind, LayerStack, Medium, IOR_RANGE, MAX_ALPHA, MAX_CONDUCTOR,
    MAX_LAYERS, MAX_OPTICAL_DEPTH, MIN_ALPHA,
};
pub use lobes::Lobes;
pub use phase::{Phase, PhaseKind, MAX_COMPONENTS, MIN_SGGX_ROUGHNESS};
pub use set::{SetError, SetPath};
pub use shape::{InterfaceShape, LayerKind, LayerShape, Shape};
pub use spectral_fields::SpectralField;
pub use spectrum::{RgbParam, Spectrum};
