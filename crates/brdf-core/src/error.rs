//! Typed errors: every bad input gets one of these, with a message that says what was wrong.

use alloc::string::String;
use core::fmt;
use core::fmt::Write as _;

/// Longest quotation of an offending text (a model name, a parameter, a path) in an error
/// message, in characters: see [`Quoted`].
pub const QUOTE_LIMIT: usize = 200;

/// Text an error message quotes, as it is displayed: control characters escaped (`\u{1b}`,
/// `\n`), and at most [`QUOTE_LIMIT`] characters written (an escape counts its own length),
/// cut on a character boundary and followed by `…` and the text's full length in bytes where
/// it was cut. What a message quotes may come from a file (a bake file's parameters, a path
/// inside one) or a pipe, not only from a person: a hundred-megabyte parameter is not a
/// hundred-megabyte message, and an escape sequence in it does not reach the terminal that
/// shows the message as one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Quoted<'a>(pub &'a str);

impl fmt::Display for Quoted<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_quoted(f, self.0, QUOTE_LIMIT)
    }
}

/// Longest quotation of a path in an error message, in characters: Linux's `PATH_MAX`, so
/// that every path a file system can open is quoted whole (its file name, at the end,
/// included), and one read from a file is bounded all the same.
pub const PATH_QUOTE_LIMIT: usize = 4096;

/// A path an error message names, as it is displayed: [`Quoted`] with the limit
/// [`PATH_QUOTE_LIMIT`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QuotedPath<'a>(pub &'a str);

impl fmt::Display for QuotedPath<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_quoted(f, self.0, PATH_QUOTE_LIMIT)
    }
}

/// `text` with control characters escaped, at most `limit` characters of it written (see
/// [`Quoted`]).
fn write_quoted(f: &mut fmt::Formatter<'_>, text: &str, limit: usize) -> fmt::Result {
    let mut written = 0;
    for c in text.chars() {
        let escape = c.is_control().then(|| c.escape_default());
        let len = escape.clone().map_or(1, Iterator::count);
        if written + len > limit {
            return write!(f, "… ({} bytes in all)", text.len());
        }
        written += len;
        match escape {
            Some(e) => {
                for e in e {
                    f.write_char(e)?;
                }
            }
            None => f.write_char(c)?,
        }
    }
    Ok(())
}

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
                let name = Quoted(name);
                write!(f, "unknown model `{name}` (run `brdf models` for the list)")
            }
            Self::UnknownParam { model, name, known } => write!(
                f,
                "model `{model}` has no parameter `{}` (it has: {known})",
                Quoted(name)
            ),
            Self::Malformed { text } => {
                let text = Quoted(text);
                write!(f, "malformed parameter `{text}`: expected name=value")
            }
            Self::BadValue {
                name,
                text,
                expected,
            } => write!(
                f,
                "parameter `{name}`: cannot read `{}` as {expected}",
                Quoted(text)
            ),
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
    /// A stored value is finite but its f_r exceeds
    /// [`crate::models::merl::MERL_MAX_F`] (10²⁰ /sr): no measurement gives that.
    TooLarge {
        /// 0 red, 1 green, 2 blue.
        channel: u8,
        /// The bin within the channel.
        bin: u32,
    },
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
            Self::TooLarge { channel, bin } => write!(
                f,
                "value {bin} of the {} channel is an f_r over 1e20 /sr, which no measurement \
                 gives",
                ["red", "green", "blue"][usize::from(*channel).min(2)]
            ),
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
        write!(f, "{}: {}", QuotedPath(&self.path), self.fault)
    }
}

impl core::error::Error for DataError {}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::ToString;
    use alloc::vec::Vec;

    #[test]
    fn quotes_are_short_and_escape_control_characters() {
        let q = |s: &str| Quoted(s).to_string();
        assert_eq!(q("kd=0.5"), "kd=0.5");
        assert_eq!(q(""), "");
        assert_eq!(q("a\nb\u{1b}[31m"), "a\\nb\\u{1b}[31m");
        // Exactly the limit is quoted whole; one more character is cut.
        let at_limit = "é".repeat(QUOTE_LIMIT);
        assert_eq!(q(&at_limit), at_limit);
        let over = "é".repeat(QUOTE_LIMIT + 1);
        let cut = q(&over);
        assert!(cut.starts_with(&"é".repeat(QUOTE_LIMIT)), "{cut}");
        assert!(cut.ends_with("… (402 bytes in all)"), "{cut}");
        // Escapes count their own length: 200 escape characters are not 1 200 quoted ones.
        let escapes = q(&"\u{1b}".repeat(1000));
        assert!(escapes.chars().count() < QUOTE_LIMIT + 30, "{escapes}");
        assert!(escapes.ends_with("… (1000 bytes in all)"), "{escapes}");
        assert!(!escapes.chars().any(char::is_control));
    }

    #[test]
    fn parameter_errors_quote_what_they_were_given() {
        let huge = ["\u{7}", &"x".repeat(1 << 20)].concat();
        let errors: Vec<ParamError> = Vec::from([
            ParamError::UnknownModel { name: huge.clone() },
            ParamError::UnknownParam {
                model: "phong",
                name: huge.clone(),
                known: "kd, ks, n".into(),
            },
            ParamError::Malformed { text: huge.clone() },
            ParamError::BadValue {
                name: "n",
                text: huge.clone(),
                expected: "a number",
            },
        ]);
        for e in errors {
            let m = e.to_string();
            assert!(
                m.chars().count() < QUOTE_LIMIT + 120,
                "{} characters",
                m.len()
            );
            assert!(m.contains("\\u{7}xxx") && m.contains("(1048577 bytes in all)"));
            assert!(!m.chars().any(char::is_control), "{m}");
        }
        // A path is quoted whole up to PATH_QUOTE_LIMIT (a file name at its end included),
        // and bounded past it.
        let path = |path: String| {
            ParamError::Data {
                name: "file",
                error: DataError {
                    path,
                    fault: DataFault::Missing,
                },
            }
            .to_string()
        };
        let long = ["/d".repeat(1500), "/brass.binary".into()].concat();
        assert!(path(long).ends_with("/d/brass.binary: no such file"));
        let m = path(huge);
        assert!(m.chars().count() < PATH_QUOTE_LIMIT + 120, "{}", m.len());
        assert!(m.starts_with("parameter `file`: \\u{7}xxx"), "{}", &m[..40]);
        assert!(!m.chars().any(char::is_control));
    }
}
