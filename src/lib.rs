//! # brdf-sampling
//!
//! Importance sampling of BRDFs with the adaptive quadtree of Montes (2003) over the projected
//! unit disk, validated statistically. This crate is the facade: it re-exports the workspace's
//! libraries and ships the `brdf` command-line tool (SPEC §6).
//!
//! - [`brdf_core`] (re-exported at the root too): BRDF models, the [`Brdf`] trait, the
//!   [`registry`], frames, disk maps and analytic warps. `no_std` + `alloc`.
//! - [`quadtree_sampler`]: the seed's quadtree and its samplers.
//! - [`mod@bench`]: the model sets and the environment the benchmarks share.
//! - [`text`]: the command line's parsers of direction lines and `x,y,z` vectors.
//!
//! ```
//! use brdf_sampling::{Brdf, registry};
//! use brdf_sampling::glam::{Vec2, Vec3};
//!
//! let phong = registry::create("phong", ["n=200"]).unwrap();
//! let wi = Vec3::new(0.6, 0.0, 0.8);
//! let s = phong.sample(wi, 0.5, Vec2::new(0.3, 0.7)).unwrap();
//! assert!(s.wo.z > 0.0 && s.pdf > 0.0);
//! ```

pub mod bench;
pub mod text;

/// The random number generator of the examples (PCG64) and the traits that seed it and draw
/// from it: what the samplers' `rng` arguments take, re-exported so that the one dependency
/// line of the README is the whole set-up.
pub mod rng {
    pub use rand_core::{Rng, SeedableRng};
    pub use rand_pcg::Pcg64;
}

pub use brdf_core;
pub use brdf_core::*;
/// The statistical validation of samplers (the `brdf-validate` crate).
pub use brdf_validate as validate;
pub use quadtree_sampler;

/// The README's examples, compiled and run as doc tests so that they stay true.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
