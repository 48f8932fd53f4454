//! # brdf-core
//!
//! BRDF models, shading frames and the hemisphere ↔ square maps on which the quadtree sampler
//! of Montes (2003) is built. `#![no_std]` + `alloc` when the default `std` feature is off
//! (then enable `libm` for the float functions).
//!
//! - [`Brdf`]: the trait every model implements: RGB `eval` in 1/sr, the luminance density the
//!   samplers follow, peak hints, an optional analytic sampler whose pdf is **per unit solid
//!   angle**, and parameter metadata.
//! - [`registry`]: every model by name, built from `name=value` pairs with typed errors.
//! - [`models`]: the models of MODELS.md.
//! - [`Frame`], [`geometry`]: local frames (z = normal, x = tangent) and direction helpers.
//! - [`maps`]: the orthographic (the seed's `Codificador`) and concentric square ↔ hemisphere
//!   maps; [`warp`]: analytic hemisphere warps; [`microfacet`]: normal distributions.
//! - [`quadrature`]: independent deterministic integrators (the tests' oracles).
//!
//! ```
//! use brdf_core::{Brdf, registry};
//! use glam::{Vec2, Vec3};
//!
//! let ward = registry::create("ward", ["alpha_x=0.05", "alpha_y=0.2"]).unwrap();
//! let wi = Vec3::new(0.5, 0.0, 0.866);
//! let s = ward.sample(wi, 0.7, Vec2::new(0.25, 0.5)).expect("above the horizon");
//! assert!((s.pdf - ward.pdf(wi, s.wo)).abs() <= 1e-6 * s.pdf);
//! ```
#![no_std]
#![deny(missing_docs)]

extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

mod brdf;
pub mod error;
mod frame;
pub mod geometry;
pub mod maps;
pub mod math;
pub mod microfacet;
pub mod models;
pub mod param;
pub mod quadrature;
pub mod registry;
pub mod special;
pub mod warp;

pub use brdf::{Brdf, BrdfSample, MIN_STEP_WIDTH, PeakHints, Symmetry, usable_step_width};
pub use error::{
    Constraint, DataError, DataFault, DirectionError, PATH_QUOTE_LIMIT, ParamError, QUOTE_LIMIT,
    Quoted, QuotedPath,
};
pub use frame::Frame;
pub use glam;
pub use maps::DiskMap;
pub use param::{ParamKind, ParamSet, ParamSpec, ParamValue};
