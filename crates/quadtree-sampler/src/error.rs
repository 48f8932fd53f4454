//! Typed errors of the quadtree builder and samplers.

use alloc::string::String;
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
    Config {
        /// Which option and why.
        message: String,
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
            Self::Config { message } => write!(f, "build option: {message}"),
        }
    }
}

impl core::error::Error for BuildError {}

impl From<DirectionError> for BuildError {
    fn from(e: DirectionError) -> Self {
        Self::Direction(e)
    }
}
