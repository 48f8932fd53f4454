//! `brdf eval`: a streaming filter from direction pairs to f_r values.

use crate::CliError;
use brdf_sampling::geometry::unit_direction;
use brdf_sampling::{Brdf, glam::Vec3};
use std::io::{BufRead, BufWriter, Read, Write};

/// The longest stdin line `eval` and `pdf` read (64 KiB: six numbers need well under 1 KiB).
/// A longer one, such as an endless stream without a newline, is an error naming the line
/// rather than a read until memory runs out.
pub(crate) const MAX_LINE_BYTES: u64 = 1 << 16;

/// Reads the next line into `line` (cleared first), the one after line `lineno`: `false` at
/// the end of the input, an error for a line over [`MAX_LINE_BYTES`].
pub(crate) fn next_line(
    input: &mut impl BufRead,
    line: &mut String,
    lineno: u64,
) -> Result<bool, CliError> {
    line.clear();
    let n = input.take(MAX_LINE_BYTES + 1).read_line(line)?;
    if n as u64 > MAX_LINE_BYTES {
        return Err(CliError::Input {
            line: lineno + 1,
            message: format!("longer than {MAX_LINE_BYTES} bytes"),
        });
    }
    Ok(n > 0)
}

/// Reads `wix wiy wiz wox woy woz` lines, writes `r g b` lines. Directions are normalised;
/// one below the horizon gives `0 0 0`; a malformed line, a NaN or a zero vector is an error
/// naming the line.
pub(crate) fn run(
    brdf: &dyn Brdf,
    mut input: impl BufRead,
    out: impl Write,
) -> Result<(), CliError> {
    let mut out = BufWriter::with_capacity(1 << 16, out);
    let mut line = String::new();
    let mut fmt = ryu::Buffer::new();
    let mut lineno = 0u64;
    while next_line(&mut input, &mut line, lineno)? {
        lineno += 1;
        let nums = match brdf_sampling::text::parse_numbers::<6>(&line, "wix wiy wiz wox woy woz") {
            Ok(Some(n)) => n,
            Ok(None) => continue,
            Err(e) => {
                return Err(CliError::Input {
                    line: lineno,
                    message: e.to_string(),
                });
            }
        };
        // Validate, but hand eval the exact parsed vector: it renormalises in f64 itself, and
        // rounding a normalised copy to f32 first would move deep lobe tails by ~1e-5.
        let dir = |i: usize, name: &str| {
            let v = Vec3::new(nums[i], nums[i + 1], nums[i + 2]);
            unit_direction(v).map(|_| v).map_err(|e| CliError::Input {
                line: lineno,
                message: format!("{name}: {e}"),
            })
        };
        let f = brdf.eval(dir(0, "wi")?, dir(3, "wo")?);
        for (k, c) in f.to_array().into_iter().enumerate() {
            if k > 0 {
                out.write_all(b" ")?;
            }
            out.write_all(fmt.format(c).as_bytes())?;
        }
        out.write_all(b"\n")?;
    }
    out.flush()?;
    Ok(())
}
