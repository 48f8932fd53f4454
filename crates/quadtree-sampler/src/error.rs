//! Typed errors of the quadtree builder and samplers.

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
