//! The text the `brdf` command line reads: direction lines on stdin (`eval`, `pdf`) and
//! `x,y,z` vectors (`--wi`). Every malformed input is a [`TextError`] that quotes at most
//! [`QUOTE_LIMIT`] characters of what it got, so a gigabyte line cannot become a gigabyte
//! message; a test feeds these parsers generated input (`tests/fuzz.rs`).

use glam::Vec3;
use std::fmt;

pub use brdf_core::error::QUOTE_LIMIT;

/// `text` as an error message quotes it ([`brdf_core::error::Quoted`]): control characters
/// escaped, so that a line holding a terminal's escape sequence does not reach the terminal
/// as one, and at most [`QUOTE_LIMIT`] characters (then `…` and the full length in bytes).
#[must_use]
pub fn excerpt(text: &str) -> String {
    brdf_core::error::Quoted(text).to_string()
}

/// Why a line or a vector could not be read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TextError {
    /// A token that is not a number (quoted by [`excerpt`]).
    NotANumber {
        /// The token.
        token: String,
    },
    /// A line with the wrong number of numbers.
    WrongCount {
        /// How many the line must hold.
        expected: usize,
        /// What they are, in words (`wox woy woz`).
        names: &'static str,
        /// The line (quoted by [`excerpt`]).
        line: String,
    },
    /// An `x,y,z` vector that is not three comma-separated numbers.
    NotAVector {
        /// The text (quoted by [`excerpt`]).
        text: String,
    },
}

impl fmt::Display for TextError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotANumber { token } => write!(f, "`{token}` is not a number"),
            Self::WrongCount {
                expected,
                names,
                line,
            } => write!(f, "expected {expected} numbers `{names}`, got `{line}`"),
            Self::NotAVector { text } => {
                write!(f, "`{text}`: expected three comma-separated numbers x,y,z")
            }
        }
    }
}

impl std::error::Error for TextError {}

/// The `N` whitespace-separated f32 numbers of `line` (`names` says what they are, for the
/// message), or `None` for a blank line. Never allocates more than the quotation of an
/// error.
pub fn parse_numbers<const N: usize>(
    line: &str,
    names: &'static str,
) -> Result<Option<[f32; N]>, TextError> {
    let mut nums = [0.0f32; N];
    let mut count = 0;
    for tok in line.split_ascii_whitespace() {
        if count == N {
            count += 1;
            break;
        }
        nums[count] = tok.parse().map_err(|_| TextError::NotANumber {
            token: excerpt(tok),
        })?;
        count += 1;
    }
    match count {
        0 => Ok(None),
        c if c == N => Ok(Some(nums)),
        _ => Err(TextError::WrongCount {
            expected: N,
            names,
            line: excerpt(line.trim_end()),
        }),
    }
}

/// Three comma-separated numbers `x,y,z` (spaces around each allowed), not normalised.
pub fn parse_vec3(text: &str) -> Result<Vec3, TextError> {
    let mut v = [0.0f32; 3];
    let mut parts = text.split(',');
    for x in &mut v {
        *x = parts
            .next()
            .and_then(|p| p.trim().parse().ok())
            .ok_or_else(|| TextError::NotAVector {
                text: excerpt(text),
            })?;
    }
    if parts.next().is_some() {
        return Err(TextError::NotAVector {
            text: excerpt(text),
        });
    }
    Ok(Vec3::from_array(v))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_vectors_and_quotes() {
        assert_eq!(parse_numbers::<3>("  \n", "a b c"), Ok(None));
        assert_eq!(
            parse_numbers::<3>("1 2 3\n", "a b c"),
            Ok(Some([1.0, 2.0, 3.0]))
        );
        assert!(matches!(
            parse_numbers::<3>("1 2", "a b c"),
            Err(TextError::WrongCount { expected: 3, .. })
        ));
        assert!(matches!(
            parse_numbers::<3>("1 2 3 4", "a b c"),
            Err(TextError::WrongCount { .. })
        ));
        assert!(matches!(
            parse_numbers::<3>("1 x 3", "a b c"),
            Err(TextError::NotANumber { .. })
        ));
        assert_eq!(parse_vec3(" 1, 2 ,3"), Ok(Vec3::new(1.0, 2.0, 3.0)));
        for bad in ["1,2", "1,2,3,4", "1,,3", "", "a,b,c"] {
            assert!(parse_vec3(bad).is_err(), "{bad}");
        }
        let long = "é".repeat(10_000);
        let e = parse_numbers::<3>(&long, "a b c").unwrap_err().to_string();
        assert!(e.chars().count() < QUOTE_LIMIT + 80, "{}", e.len());
        assert_eq!(excerpt("short"), "short");
        // Control characters are escaped, whatever the line's length.
        let e = parse_numbers::<3>("\u{1b}[31mred 1 2", "a b c")
            .unwrap_err()
            .to_string();
        assert!(!e.chars().any(char::is_control), "{e:?}");
        assert!(e.contains("\\u{1b}[31mred"), "{e:?}");
    }
}
