//! # quadtree-sampler
//!
//! The adaptive quadtree sampler of Rosana Montes (2003): f_r(wi, ·) is laid over the square
//! [−1,1]² by a map under which uniform area is uniform projected solid angle (SPEC §2), so a
//! density ∝ f_r on the square is ∝ f_r·cos θ on the hemisphere. Each node of an arena
//! quadtree knows v1 = ∫ f_r over its square, an upper bound M and P = v1/(s²M); a node with
//! P < ½ splits (`particionar`). Sampling descends by v1 (`seleccionarRegion`) and
//! rejection-samples the leaf (`muestrear`). The seed's names, and where they live:
//!
//! | seed | here |
//! | --- | --- |
//! | `Codificador` | [`brdf_core::Frame`] (world ↔ local) and [`brdf_core::DiskMap`] (local ↔ square) |
//! | `Nodo`, `Region` | [`Node`] in the arena [`Quadtree`]; [`PackedNode`] in the sampling layout [`PackedTree`] |
//! | `particionar` | the build inside [`QuadtreeSampler::new`] |
//! | `seleccionarRegion` | [`QuadtreeSampler::select_region`] |
//! | `muestrear` | [`QuadtreeSampler::sample_leaf`] |
//! | `refleja` | [`refleja`] |
//!
//! ## Compared with the alternatives
//!
//! - **Analytic samplers** (pbrt, Mitsuba) are exact and cheapest, but exist only for the
//!   models someone inverted; several models here (He–Torrance, Poulin–Fournier, Strauss)
//!   have none, and mixtures sample only approximately ∝ f·cos.
//! - **Piecewise-constant 2D tables** (marginal/conditional, Mitsuba's `Marginal2D`) are
//!   continuous and invertible but their resolution is fixed: a sharp lobe needs a fine grid
//!   everywhere, and their pdf is only ∝ f·cos up to the table's resolution.
//! - **This quadtree** adapts its resolution to f, so a 10⁵-exponent lobe costs nodes only
//!   where the lobe is; rejection inside the leaves makes the density ∝ f·cos *exactly*
//!   wherever the bound holds (and counts every violation), at the price of a random number of
//!   trials (E\[T\] ≤ 2 with the seed's rule, tunable by the target-trials mode) and of
//!   discontinuity: it cannot warp stratified points.
//!
//! Beyond the seed, for renderers: [`BakedSampler`] bakes a model once (a grid of trees over
//! the incident directions, folded by the model's declared symmetries) and answers `sample`,
//! `pdf` and `eval` at any `wi` with the exact density of what it drew (a mixture of the
//! neighbouring trees, each rotated onto `wi`'s mirror direction, or on an anisotropic grid
//! carried by the half-vector transport), in both transport roles,
//! in rejection or warp mode, in the local frame or through [`WorldBsdf`]; bake files keep it
//! on disk ([`BakedSampler::save`], [`BakedSampler::load`]).
//!
//! Beyond the seed, for exactness: node integrals use charts in which the disk's rim is a
//! coordinate boundary (see [`chart`]), and leaves on the rim are rejection-sampled in those
//! charts, where f·Jacobian stays bounded even for models that grow as 1/√cos θ (Ward).
//!
//! ```
//! use brdf_core::registry;
//! use quadtree_sampler::{BuildConfig, QuadtreeSampler};
//! use glam::Vec3;
//! use rand_pcg::Pcg64;
//! use rand_core::SeedableRng;
//!
//! let phong = registry::create("phong", ["n=300"]).unwrap();
//! let wi = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
//! let sampler = QuadtreeSampler::new(&*phong, wi, BuildConfig::default()).unwrap();
//! let mut rng = Pcg64::seed_from_u64(1);
//! let s = sampler.sample(&mut rng).unwrap();
//! assert!((s.pdf - sampler.pdf(s.wo)).abs() <= 1e-6 * s.pdf);
//! assert!(sampler.stats().expected_trials <= 2.0);
//! ```
#![no_std]
#![deny(missing_docs)]

extern crate alloc;
#[cfg(feature = "std")]
extern crate std;

mod bake_budget;
mod bake_file;
mod bake_grid;
mod baked;
mod baked_coverage;
mod baked_mixture;
mod baked_nearest;
mod baked_views;
mod bilinear;
mod bound;
pub mod chart;
pub mod colormap;
mod config;
mod encoder;
mod error;
mod evaluate;
mod factory;
pub mod integrate;
mod packed;
pub mod proposal;
mod rim;
mod sampler;
mod table;
mod tree;
mod warp;
mod warp_table;

pub use bake_file::{
    BAKE_FORMAT_VERSION, BAKE_MAGIC, BakeFileError, MAX_BAKE_FILE_BYTES, OLDEST_READ_VERSION,
};
#[cfg(feature = "std")]
pub use bake_file::{BakeIoError, temporary_beside, write_atomically};
pub use bake_grid::{BakeGrid, PhiDomain};
pub use baked::{
    BakeConfig, BakedMode, BakedSampler, DEFAULT_BAKE_MAX_BYTES, DEFAULT_BAKE_NODE_BUDGET,
    DEFAULT_DEFENSIVE, DEFAULT_ISOTROPIC_BAKE_MAX_BYTES, DEFAULT_PHI_STEPS, DEFAULT_THETA_STEPS,
    GRID_THETA_MAX_DEG, MAX_BAKE_BYTES, MAX_TREES, MixtureTree, Role,
};
pub use baked_coverage::{
    COVERAGE_LIMIT, CellCoverage, Coverage, CoverageConfig, DEFAULT_COVERAGE_SAMPLES,
    MAX_COVERAGE_SAMPLES,
};
pub use baked_nearest::{NEAREST_MAX_RATIO, NEAREST_REJECTION_EXCESS};
pub use baked_views::{BakedAt, BakedPoint, BrokenAt, BrokenPdf, WorldBsdf, WorldPoint};
pub use brdf_core;
pub use config::{BuildConfig, EVALUATIONS_PER_NODE, IntegrationRule};
pub use encoder::refleja;
pub use error::{BakeError, BakedError, BuildError};
pub use factory::{AnySampler, SamplerMode};
pub use packed::{PackedLeaf, PackedNode, PackedTree, Selected};
pub use sampler::{
    Baseline, BaselineSampler, DensityHints, DirectionSampler, LeafSample, MAX_TRIALS,
    MAX_USABLE_EXPECTED_TRIALS, QuadtreeSampler, Ridge, Sample, descent_uniform, uniform_f32,
    uniform_f64, weight_luminance,
};
pub use table::{DEFAULT_TABLE_RES, TableSampler};
pub use tree::{
    FLOOR_SLACK, LAST_RETRY_TOLERANCE, LEAF, Node, Quadtree, RETRY_TOLERANCE, TARGET_TOLERANCE,
    TreeStats, albedo_of_volume, target_limit,
};
pub use warp::{DEFAULT_MIX, WarpSampler};
