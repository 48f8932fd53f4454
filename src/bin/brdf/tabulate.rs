//! `brdf tabulate` (SPEC §8): any model's f_r written in the MERL database's format, at each
//! bin's centre, so that `merl` on the file reproduces the model there. The bins are
//! evaluated in parallel (rayon) by the library's own per-bin expression, so the file is the
//! same on any number of threads; it is written complete or not at all.

use crate::CliError;
use brdf_sampling::Brdf;
use brdf_sampling::models::merl::{self, MERL_BINS};
use rayon::prelude::*;
use serde_json::json;
use std::io::Write;
use std::time::Instant;

/// Bins a progress step covers.
const CHUNK: usize = 90 * 180;

pub(crate) fn run(
    brdf: &dyn Brdf,
    out: &std::path::Path,
    mut stdout: impl Write,
) -> Result<(), CliError> {
    if brdf.is_delta() {
        return Err(CliError::Usage(format!(
            "model `{}` is a Dirac delta: f_r is 0 at every pair of directions, there is nothing to tabulate",
            brdf.name()
        )));
    }
    let t0 = Instant::now();
    let bar = crate::progress::Progress::new("tabulating", (MERL_BINS / CHUNK) as u64);
    let mut values = vec![[0.0f64; 3]; MERL_BINS];
    values
        .par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(c, chunk)| {
            for (k, v) in chunk.iter_mut().enumerate() {
                *v = merl::tabulate_bin(brdf, c * CHUNK + k);
            }
            bar.step();
        });
    drop(bar);
    let bad = values
        .iter()
        .position(|v| !v.iter().all(|x| x.is_finite() && *x >= 0.0));
    if let Some(k) = bad {
        return Err(CliError::Usage(format!(
            "model `{}` gives {:?} at bin {k}: not a finite, non-negative f_r",
            brdf.name(),
            values[k]
        )));
    }
    let zero = values
        .iter()
        .filter(|v| v.iter().all(|x| *x == 0.0))
        .count();
    let bytes = merl::encode(&values);
    brdf_sampling::quadtree_sampler::write_atomically(out, &bytes)
        .map_err(|e| CliError::Usage(format!("--out {}: {e}", out.display())))?;
    let summary = json!({
        "model": brdf.name(),
        "params": brdf.params().iter().map(|(s, v)| format!("{}={v}", s.name)).collect::<Vec<_>>(),
        "file": out,
        "bytes": bytes.len(),
        "bins": MERL_BINS,
        "zero_bins": zero,
        "seconds": t0.elapsed().as_secs_f64(),
    });
    serde_json::to_writer(&mut stdout, &summary).map_err(std::io::Error::from)?;
    writeln!(stdout)?;
    Ok(())
}
