//! Typed errors: every bad input gets one of these, with a message that says what was wrong.

use alloc::string::String;
use core::fmt;

/// What was wrong with a direction handed to the library.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DirectionError {
    /// A component is NaN or infinite.
    NotFinite,
    /// The vector is zero, so it has no direction.
    ZeroLength,
    /// The direction is at or below the horizon (z ≤ 0 in the local frame) where it must not be.
    BelowHorizon,
    /// A tangent is parallel to the normal, so no frame can be built from the pair.
    ParallelTangent,
}

impl fmt::Display for DirectionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::NotFinite => "direction has a NaN or infinite component",
            Self::ZeroLength => "direction has zero length",
            Self::BelowHorizon => {
                "direction is at or below the horizon (z <= 0 in the local frame)"
            }
            Self::ParallelTangent => "tangent is parallel to the normal",
        })
    }
}

impl core::error::Error for DirectionError {}

/// What was wrong with a model parameter or a model name.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamError {
    /// No model of this name is registered.
    UnknownModel {
        /// The name asked for.
        name: String,
    },
    /// The model has no parameter of this name.
    UnknownParam {
        /// The model.
        model: &'static str,
        /// The name given.
        name: String,
        /// The names the model does have, comma-separated.
        known: String,
    },
    /// An assignment was not of the form `name=value`.
    Malformed {
        /// The text as given.
        text: String,
    },
    /// A value could not be parsed as a number, or had the wrong number of components.
    BadValue {
        /// The parameter.
        name: &'static str,
        /// The text as given.
        text: String,
        /// What was expected instead.
        expected: &'static str,
    },
    /// A value is NaN or outside the parameter's range.
    OutOfRange {
        /// The parameter.
        name: &'static str,
        /// The offending value (one channel of an RGB value).
        value: f32,
        /// The range, written as in MODELS.md (for example `[0, 1]` or `(0, 1]`).
        range: String,
    },
    /// A parameter the model cannot do without was not given (a measured model's `file`).
    Required {
        /// The model.
        model: &'static str,
        /// The parameter.
        name: &'static str,
    },
    /// The data file a parameter names cannot be used.
    Data {
        /// The parameter.
        name: &'static str,
        /// The file and what is wrong with it.
        error: DataError,
    },
    /// Values that are each in range break a constraint between parameters.
    Constraint {
        /// The model.
        model: &'static str,
        /// The constraint that failed.
        constraint: Constraint,
    },
}

/// A constraint between parameters (or between a parameter set and its model) that failed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Constraint {
    /// kd + ks ≤ 1 in every channel (energy conservation of Lewis–Phong, Poulin–Fournier).
    EnergyConservation {
        /// kd + ks as given, RGB.
        kd_plus_ks: [f32; 3],
    },
    /// The parameter set was made for another model.
    OtherModel {
        /// The model the parameters are for.
        params_of: &'static str,
    },
}

impl fmt::Display for Constraint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::EnergyConservation {
                kd_plus_ks: [r, g, b],
            } => write!(
                f,
                "kd + ks must be <= 1 in every channel (got {r}, {g}, {b})"
            ),
            Self::OtherModel { params_of } => write!(f, "parameters are for model `{params_of}`"),
        }
    }
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::UnknownModel { name } => {
                write!(f, "unknown model `{name}` (run `brdf models` for the list)")
            }
            Self::UnknownParam { model, name, known } => write!(
                f,
                "model `{model}` has no parameter `{name}` (it has: {known})"
            ),
            Self::Malformed { text } => {
                write!(f, "malformed parameter `{text}`: expected name=value")
            }
            Self::BadValue {
                name,
                text,
                expected,
            } => write!(f, "parameter `{name}`: cannot read `{text}` as {expected}"),
            Self::OutOfRange { name, value, range } => write!(
                f,
                "parameter `{name}` = {value} is out of its range {range}"
            ),
            Self::Required { model, name } => write!(
                f,
                "model `{model}` needs parameter `{name}` (for example --param {name}=PATH)"
            ),
            Self::Data { name, error } => write!(f, "parameter `{name}`: {error}"),
            Self::Constraint { model, constraint } => write!(f, "model `{model}`: {constraint}"),
        }
    }
}

impl core::error::Error for ParamError {}

/// What is wrong with a measured BRDF's data file (SPEC §8).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DataFault {
    /// No file at the path.
    Missing,
    /// The path is a directory.
    Directory,
    /// The path is not a regular file (a device, a pipe, a socket): never read, since
    /// reading one could block or never end.
    NotRegular,
    /// The file exists but may not be read.
    PermissionDenied,
    /// Reading failed for another reason.
    Unreadable,
    /// The file ends early: `bytes` of the `expected`.
    Truncated {
        /// The file's size.
        bytes: u64,
        /// The size the format fixes.
        expected: u64,
    },
    /// The file is longer than the format allows (bytes after the last value).
    WrongSize {
        /// The file's size.
        bytes: u64,
        /// The size the format fixes.
        expected: u64,
    },
    /// The header's dimensions are not (90, 90, 180).
    Dimensions {
        /// The three dimensions as stored.
        found: [i32; 3],
    },
    /// A stored value is NaN or infinite.
    NotFinite {
        /// 0 red, 1 green, 2 blue.
        channel: u8,
        /// The bin within the channel.
        bin: u32,
    },
    /// Built without `std`: there is no file system to read from.
    NoFileSystem,
}

impl fmt::Display for DataFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Missing => f.write_str("no such file"),
            Self::Directory => f.write_str("is a directory, not a file"),
            Self::NotRegular => f.write_str("is not a regular file (a device or a pipe)"),
            Self::PermissionDenied => f.write_str("permission denied"),
            Self::Unreadable => f.write_str("cannot be read"),
            Self::Truncated { bytes, expected } => write!(
                f,
                "truncated: {bytes} bytes, a MERL file has exactly {expected}"
            ),
            Self::WrongSize { bytes, expected } => write!(
                f,
                "wrong size: {bytes} bytes, a MERL file has exactly {expected}"
            ),
            Self::Dimensions { found: [a, b, c] } => write!(
                f,
                "wrong dimensions {a} x {b} x {c} in the header (a MERL file has 90 x 90 x 180)"
            ),
            Self::NotFinite { channel, bin } => write!(
                f,
                "value {bin} of the {} channel is NaN or infinite",
                ["red", "green", "blue"][usize::from(*channel).min(2)]
            ),
            Self::NoFileSystem => f.write_str("cannot be read: built without std"),
        }
    }
}

/// A data file that cannot be used: which file, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DataError {
    /// The path as given.
    pub path: String,
    /// What is wrong.
    pub fault: DataFault,
}

impl fmt::Display for DataError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path, self.fault)
    }
}

impl core::error::Error for DataError {}
