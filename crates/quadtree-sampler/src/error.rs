//! Typed errors of the quadtree builder, the baked sampler and its calls.

use crate::MAX_TREES;
use brdf_core::DirectionError;
use core::fmt;

/// Why a quadtree could not be built.
#[derive(Clone, Debug, PartialEq)]
pub enum BuildError {
    /// The incident direction (or the normal or tangent) is not valid: NaN, zero, below the
    /// horizon.
    Direction(DirectionError),
    /// The model is a pure Dirac delta (the perfect mirror): it has no continuous part to
    /// tabulate. Sample it analytically (`Brdf::sample`, or [`crate::refleja`]).
    DeltaModel {
        /// The model's name.
        model: &'static str,
    },
    /// A build option is out of its range.
    OutOfRange {
        /// The option.
        option: &'static str,
        /// The value given.
        value: f64,
        /// The range it must lie in, in words (`"in (0, 1]"`).
        expected: &'static str,
    },
    /// f_r(wi, ·) is 0 everywhere above the horizon for this wi (after integration, every
    /// node's integral and bound are 0): there is no density to sample.
    ZeroBrdf {
        /// The model's name.
        model: &'static str,
    },
    /// The node budget (or the build's memory budget) stopped the build before the tree
    /// could bound f_r tightly enough to be sampled: its expected number of rejection trials
    /// per sample would exceed [`crate::MAX_USABLE_EXPECTED_TRIALS`]. f_r is sharper than
    /// the tree's resolution (depth and budget), or only rounding noise.
    Exhausted {
        /// The model's name.
        model: &'static str,
        /// Nodes built when the budget stopped the build.
        nodes: usize,
        /// The expected trials per sample of the tree at that point.
        expected_trials: f64,
    },
}

impl fmt::Display for BuildError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Direction(e) => write!(f, "incident direction: {e}"),
            Self::DeltaModel { model } => write!(
                f,
                "model `{model}` is a Dirac delta: no quadtree can represent it (sample it analytically)"
            ),
            Self::OutOfRange {
                option,
                value,
                expected,
            } => write!(f, "build option: {option} = {value} must be {expected}"),
            Self::ZeroBrdf { model } => write!(
                f,
                "f_r of `{model}` is 0 everywhere above the horizon for this wi: nothing to sample"
            ),
            Self::Exhausted {
                model,
                nodes,
                expected_trials,
            } => write!(
                f,
                "the quadtree of `{model}` ran out of its budget at {nodes} nodes with {expected_trials:.3e} expected trials per sample (f_r is sharper than the tree can resolve, or rounding noise): raise the node budget or use another sampler"
            ),
        }
    }
}

impl core::error::Error for BuildError {}

impl From<DirectionError> for BuildError {
    fn from(e: DirectionError) -> Self {
        Self::Direction(e)
    }
}

/// Why a [`crate::BakedSampler`] could not be built.
#[derive(Clone, Debug, PartialEq)]
pub enum BakeError {
    /// `theta_steps` is below 2.
    ThetaSteps(u16),
    /// `phi_steps` is below what the folded φ range needs (2, or 3 on the full circle).
    PhiSteps {
        /// The value given.
        got: u16,
        /// The least allowed.
        min: u16,
    },
    /// The grid would hold more than [`MAX_TREES`] trees.
    TooManyTrees(usize),
    /// The grid's trees cannot fit the bake's limit ([`crate::BakeConfig::max_bytes`], even
    /// pruned as far as a tree may be, or [`crate::MAX_BAKE_BYTES`] as built): too many
    /// trees, or too fine ones, for one bake.
    TooLarge {
        /// The trees the grid asked for (twice the grid for a non-reciprocal model).
        trees: usize,
        /// The limit they passed, bytes.
        limit: usize,
    },
    /// `defensive` is not in (0, 1).
    Defensive(f64),
    /// [`crate::BakeConfig::max_bytes`] is 0 or over [`crate::MAX_BAKE_BYTES`].
    MaxBytes(usize),
    /// The model has no continuous part (the perfect mirror): nothing to bake.
    DeltaModel(&'static str),
    /// A grid tree could not be built.
    Tree {
        /// Its θi, degrees.
        theta_deg: f64,
        /// Its φi, degrees.
        phi_deg: f64,
        /// Why.
        source: BuildError,
    },
}

impl fmt::Display for BakeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::ThetaSteps(n) => write!(f, "theta steps = {n}: at least 2 are needed"),
            Self::PhiSteps { got, min } => {
                write!(
                    f,
                    "phi steps = {got}: this model's φ range needs at least {min}"
                )
            }
            Self::TooManyTrees(n) => {
                write!(
                    f,
                    "a grid of {n} trees is more than the {MAX_TREES} allowed"
                )
            }
            Self::TooLarge { trees, limit } => write!(
                f,
                "the grid's {trees} trees cannot be held in the {limit} bytes ({:.1} MiB) this bake may hold: use fewer θ or φ steps, a smaller node budget, or more bytes (max_bytes, at most 2 GiB)",
                *limit as f64 / (1u64 << 20) as f64
            ),
            Self::Defensive(d) => write!(f, "defensive share = {d} must be in (0, 1)"),
            Self::MaxBytes(b) => write!(
                f,
                "max_bytes = {b} must be between 1 and {} (2 GiB)",
                crate::MAX_BAKE_BYTES
            ),
            Self::DeltaModel(m) => write!(
                f,
                "model `{m}` is a Dirac delta: it has no continuous part to bake (sample it analytically)"
            ),
            Self::Tree {
                theta_deg,
                phi_deg,
                source,
            } => write!(
                f,
                "the tree at θi = {theta_deg:.3}°, φi = {phi_deg:.3}°: {source}"
            ),
        }
    }
}

impl core::error::Error for BakeError {}

/// Why a call on a [`crate::BakedSampler`] has no answer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BakedError {
    /// The given direction is NaN, infinite, zero or below the horizon.
    Direction(DirectionError),
    /// A coverage check asked for this many samples per checked direction: 0, or more than
    /// [`crate::MAX_COVERAGE_SAMPLES`].
    CoverageSamples(u32),
}

impl fmt::Display for BakedError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Direction(e) => write!(f, "given direction: {e}"),
            Self::CoverageSamples(n) => write!(
                f,
                "coverage samples = {n} must be in [1, {}]",
                crate::MAX_COVERAGE_SAMPLES
            ),
        }
    }
}

impl core::error::Error for BakedError {}

impl From<DirectionError> for BakedError {
    fn from(e: DirectionError) -> Self {
        Self::Direction(e)
    }
}
