//! `brdf eval`: a streaming filter from direction pairs to f_r values.

use crate::CliError;
use brdf_sampling::geometry::unit_direction;
use brdf_sampling::{Brdf, glam::Vec3};
use std::io::{BufRead, BufWriter, Write};

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
    loop {
        line.clear();
        if input.read_line(&mut line)? == 0 {
            break;
        }
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
