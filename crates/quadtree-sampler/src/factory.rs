//! The one factory of per-wi samplers: a [`SamplerMode`] (SPEC §6's `--mode`) and a model
//! give an [`AnySampler`], which owns its model and answers every [`DirectionSampler`] call
//! plus the statistics a caller reports (tree counts, albedo, bound violations). The CLI, the
//! viewer's worker and the benches build their samplers here and nowhere else.

use crate::baked::BakedSampler;
use crate::baked_views::BakedAt;
use crate::config::BuildConfig;
use crate::error::BuildError;
use crate::sampler::{
    Baseline, BaselineSampler, DensityHints, DirectionSampler, QuadtreeSampler, Sample,
};
use crate::table::{DEFAULT_TABLE_RES, TableSampler};
use crate::tree::TreeStats;
use crate::warp::{DEFAULT_MIX, WarpSampler};
use alloc::sync::Arc;
use brdf_core::Brdf;
use brdf_core::geometry::unit_direction_above;
use glam::{Vec2, Vec3};
use rand_core::Rng;

/// Which sampler of one incident direction to build.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SamplerMode {
    /// The seed's quadtree with rejection in the leaves ([`QuadtreeSampler`]); the map and the
    /// target trials come from the [`BuildConfig`].
    Rejection,
    /// The hierarchical warp over the concentric map's tree ([`WarpSampler`]).
    Warp,
    /// The 256² piecewise-constant table ([`TableSampler`]).
    Table,
    /// The model's own sampler of its continuous part ([`Baseline::Analytic`]).
    Analytic,
    /// Cosine-weighted hemisphere sampling ([`Baseline::Cosine`]).
    Cosine,
    /// Uniform hemisphere sampling ([`Baseline::Uniform`]).
    Uniform,
}

impl SamplerMode {
    /// Every mode, in the order SPEC §6 lists them.
    pub const ALL: [Self; 6] = [
        Self::Rejection,
        Self::Warp,
        Self::Table,
        Self::Analytic,
        Self::Cosine,
        Self::Uniform,
    ];

    /// The CLI's name of the mode (`rejection`, `warp`, ...), also [`DirectionSampler::name`].
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Rejection => "rejection",
            Self::Warp => "warp",
            Self::Table => "table",
            Self::Analytic => "analytic",
            Self::Cosine => "cosine",
            Self::Uniform => "uniform",
        }
    }

    /// The mode of a CLI name, or `None`.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == name)
    }

    /// Whether the mode builds a quadtree (and so uses the [`BuildConfig`]).
    #[must_use]
    pub fn builds_tree(self) -> bool {
        matches!(self, Self::Rejection | Self::Warp)
    }
}

/// Any sampler of one incident direction, owning its model (`B` = `Arc<dyn Brdf>` by default,
/// `'static + Send + Sync`; `&dyn Brdf` for a borrowed one). Built by [`AnySampler::new`] for
/// a [`SamplerMode`], or by [`AnySampler::baked`] at one wi of a [`BakedSampler`].
#[derive(Debug)]
pub enum AnySampler<B: Brdf = Arc<dyn Brdf>> {
    /// [`SamplerMode::Rejection`].
    Rejection(QuadtreeSampler<B>),
    /// [`SamplerMode::Warp`].
    Warp(WarpSampler<B>),
    /// [`SamplerMode::Table`].
    Table(TableSampler<B>),
    /// [`SamplerMode::Analytic`], [`SamplerMode::Cosine`], [`SamplerMode::Uniform`].
    Baseline(BaselineSampler<B>),
    /// A baked sampler at one incident direction (its continuous part).
    Baked {
        /// The bake.
        baked: Arc<BakedSampler>,
        /// The incident direction, local, unit, above the horizon.
        wi: Vec3,
    },
}

impl<B: Brdf> AnySampler<B> {
    /// Builds the `mode` sampler of `brdf` at local `wi` (normalised here; finite, non-zero,
    /// above the horizon). `config` drives the quadtree modes (rejection: all of it; warp: all
    /// but the map, which is concentric); the table has [`DEFAULT_TABLE_RES`] cells a side and
    /// the warp the defensive weight [`DEFAULT_MIX`]. A delta model is an error in every mode.
    pub fn new(
        brdf: B,
        wi: Vec3,
        mode: SamplerMode,
        config: BuildConfig,
    ) -> Result<Self, BuildError> {
        if brdf.is_delta() {
            return Err(BuildError::DeltaModel { model: brdf.name() });
        }
        Ok(match mode {
            SamplerMode::Rejection => Self::Rejection(QuadtreeSampler::new(brdf, wi, config)?),
            SamplerMode::Warp => Self::Warp(WarpSampler::new(brdf, wi, config, DEFAULT_MIX)?),
            SamplerMode::Table => Self::Table(TableSampler::new(brdf, wi, DEFAULT_TABLE_RES)?),
            SamplerMode::Analytic => {
                Self::Baseline(BaselineSampler::new(brdf, wi, Baseline::Analytic)?)
            }
            SamplerMode::Cosine => {
                Self::Baseline(BaselineSampler::new(brdf, wi, Baseline::Cosine)?)
            }
            SamplerMode::Uniform => {
                Self::Baseline(BaselineSampler::new(brdf, wi, Baseline::Uniform)?)
            }
        })
    }

    /// The continuous part of `baked` at local `wi` (checked as in [`AnySampler::new`]).
    pub fn baked(baked: Arc<BakedSampler>, wi: Vec3) -> Result<Self, BuildError> {
        let wi = unit_direction_above(wi)?;
        Ok(Self::Baked { baked, wi })
    }

    /// The tree's counts and E\[T\] (rejection and warp; `None` for the others, a bake
    /// included: its trees are [`BakedSampler::expected_trials`]).
    #[must_use]
    pub fn tree_stats(&self) -> Option<TreeStats> {
        match self {
            Self::Rejection(q) => Some(q.stats()),
            Self::Warp(w) => Some(w.stats()),
            _ => None,
        }
    }

    /// The directional albedo of f_r's luminance the tree measured (rejection and warp).
    #[must_use]
    pub fn albedo(&self) -> Option<f64> {
        match self {
            Self::Rejection(q) => Some(q.albedo()),
            Self::Warp(w) => Some(w.albedo()),
            _ => None,
        }
    }

    /// How many times rejection met f > M (rejection and baked; `None` for samplers without
    /// rejection bounds). Should stay 0.
    #[must_use]
    pub fn bound_violations(&self) -> Option<u64> {
        match self {
            Self::Rejection(q) => Some(q.bound_violations()),
            Self::Baked { baked, .. } => Some(baked.bound_violations()),
            _ => None,
        }
    }

    /// The bake behind a [`AnySampler::Baked`].
    #[must_use]
    pub fn bake(&self) -> Option<&Arc<BakedSampler>> {
        match self {
            Self::Baked { baked, .. } => Some(baked),
            _ => None,
        }
    }

    fn at(baked: &BakedSampler, wi: Vec3) -> BakedAt<'_> {
        BakedAt { baked, wi }
    }
}

impl<B: Brdf> DirectionSampler for AnySampler<B> {
    fn name(&self) -> &'static str {
        match self {
            Self::Rejection(s) => s.name(),
            Self::Warp(s) => s.name(),
            Self::Table(s) => s.name(),
            Self::Baseline(s) => s.name(),
            Self::Baked { baked, wi } => Self::at(baked, *wi).name(),
        }
    }

    fn sample_with(&self, uc: f32, u: Vec2, rng: &mut dyn Rng) -> Option<Sample> {
        match self {
            Self::Rejection(s) => s.sample_with(uc, u, rng),
            Self::Warp(s) => s.sample_with(uc, u, rng),
            Self::Table(s) => s.sample_with(uc, u, rng),
            Self::Baseline(s) => s.sample_with(uc, u, rng),
            Self::Baked { baked, wi } => Self::at(baked, *wi).sample_with(uc, u, rng),
        }
    }

    fn sample(&self, rng: &mut dyn Rng) -> Option<Sample> {
        match self {
            Self::Rejection(s) => DirectionSampler::sample(s, rng),
            Self::Warp(s) => DirectionSampler::sample(s, rng),
            Self::Table(s) => DirectionSampler::sample(s, rng),
            Self::Baseline(s) => DirectionSampler::sample(s, rng),
            Self::Baked { baked, wi } => Self::at(baked, *wi).sample(rng),
        }
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        match self {
            Self::Rejection(s) => DirectionSampler::pdf(s, wo),
            Self::Warp(s) => DirectionSampler::pdf(s, wo),
            Self::Table(s) => DirectionSampler::pdf(s, wo),
            Self::Baseline(s) => DirectionSampler::pdf(s, wo),
            Self::Baked { baked, wi } => Self::at(baked, *wi).pdf(wo),
        }
    }

    fn density_hints(&self) -> DensityHints {
        match self {
            Self::Baked { baked, wi } => Self::at(baked, *wi).density_hints(),
            _ => DensityHints::default(),
        }
    }
}
