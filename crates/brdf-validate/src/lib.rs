//! Statistical validation of BRDF samplers: Montes (2003) §4 and SPEC §5, as a library a
//! renderer author can point at their own BSDF.
//!
//! A test draws many directions from a sampler at one incident direction, counts them over
//! cells of the projected disk ([`CellGrid`]: the seed's squares or an equal-area polar
//! grid), and compares the counts with the cells' masses under f·cos, integrated by an
//! adaptive Gauss–Kronrod rule that never looks at the sampler ([`Validation`]): the seed's
//! a_i = (n_i/m)/I_i spread, a Pearson χ² against f·cos, a second χ² against the sampler's
//! *own* pdf, and a check that every sample's pdf and weight agree with `pdf(wo)` and
//! f·cos/pdf. A [`Report`] holds the [`Histogram`], the statistics and the typed
//! [`Reason`]s behind its [`Verdict`]. [`suite`] runs the seed's testBrdf (incident
//! directions × grids × seeds, family-wise α) for a model of this workspace; [`check`] runs
//! the same for any sampler against an f·cos oracle.
//!
//! Any [`quadtree_sampler::DirectionSampler`] is a [`Sampler`]; a BSDF of your own is two
//! closures away ([`FnSampler`]). Here a cosine-weighted sampler is checked against a
//! Lambertian f·cos (`examples/ggx.rs` checks a hand-written GGX sampler):
//!
//! ```
//! use brdf_core::warp::{cosine_hemisphere_pdf as pdf, sample_cosine_hemisphere as warp};
//! use brdf_validate::{FnSampler, Settings, check, glam::Vec3};
//!
//! let sampler = FnSampler::new("cosine", |_uc, u| Some((warp(u), pdf(warp(u).z))), |wo: Vec3| pdf(wo.z));
//! let fcos = |wo: Vec3| 0.8 * f64::from(wo.z.max(0.0)) / std::f64::consts::PI; // Lambert, albedo 0.8
//! let settings = Settings { samples: 200_000, ..Settings::default() };
//! let report = check(&sampler, fcos, &[], &settings)?;
//! assert!(report.passed(), "{report}");
//! # Ok::<(), brdf_validate::ValidateError>(())
//! ```

mod cells;
mod error;
mod histogram;
mod integrate;
mod report;
mod sampler;
mod stats;
mod suite;
mod validation;

pub use cells::CellGrid;
pub use error::ValidateError;
pub use histogram::Histogram;
pub use quadtree_sampler::{DensityHints, Ridge};
pub use report::{Against, Reason, Report, Verdict};
pub use sampler::{Drawn, FnSampler, Sampler};
pub use stats::{
    ChiSquare, NORMALISATION_TOLERANCE, Spread, chi_square, chi_square_with_lost, gamma_q, sidak,
};
pub use suite::{
    Event, MAX_SAMPLES, Settings, SuiteReport, TestOutcome, WEIGHT_FLOOR, WeightTest, check,
    check_with, splitmix64, suite,
};
pub use validation::{CHUNK, Validation};

pub use glam;
