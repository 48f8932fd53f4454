//! Why a validation could not be set up.

use brdf_core::DirectionError;
use std::fmt;

/// Why a validation (or a suite of them) could not be set up. A test that ran but could not
/// judge is not an error: see [`crate::Verdict::Inconclusive`].
#[derive(Clone, Debug, PartialEq)]
pub enum ValidateError {
    /// The incident direction is not valid: NaN, zero, at or below the horizon.
    Direction(DirectionError),
    /// The model is a pure Dirac delta (the perfect mirror): it has no density over cells.
    DeltaModel {
        /// The model's name.
        model: &'static str,
    },
    /// A cell grid has a dimension outside 1..=[`crate::CellGrid::MAX_DIMENSION`].
    GridDimension {
        /// The dimension given.
        value: usize,
    },
    /// The relative tolerance of the cell masses is not in (0, 1).
    Tolerance {
        /// The value given.
        value: f64,
    },
    /// The family-wise significance is not in (0, 1).
    Significance {
        /// The value given.
        value: f64,
    },
    /// A test of zero samples was asked for.
    NoSamples,
    /// More samples per test than [`crate::MAX_SAMPLES`] were asked for.
    TooManySamples {
        /// The count given.
        value: u64,
    },
    /// A suite was given no incident direction or no cell grid.
    EmptySuite,
}

impl fmt::Display for ValidateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Direction(e) => write!(f, "incident direction: {e}"),
            Self::DeltaModel { model } => write!(
                f,
                "model `{model}` is a Dirac delta: it has no density over cells to validate"
            ),
            Self::GridDimension { value } => write!(
                f,
                "cell grid dimension {value} must be in 1..={}",
                crate::CellGrid::MAX_DIMENSION
            ),
            Self::Tolerance { value } => {
                write!(f, "validation tolerance {value} must be in (0, 1)")
            }
            Self::Significance { value } => write!(f, "significance {value} must be in (0, 1)"),
            Self::NoSamples => f.write_str("a test needs at least one sample"),
            Self::TooManySamples { value } => write!(
                f,
                "{value} samples per test is more than the {} (2^36) a test may draw",
                crate::MAX_SAMPLES
            ),
            Self::EmptySuite => {
                f.write_str("a suite needs at least one incident direction and one cell grid")
            }
        }
    }
}

impl std::error::Error for ValidateError {}

impl From<DirectionError> for ValidateError {
    fn from(e: DirectionError) -> Self {
        Self::Direction(e)
    }
}
