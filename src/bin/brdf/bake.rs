//! `brdf bake` (SPEC §7): a model's sampler at every incident direction, written to a file
//! that `brdf sample|pdf|test --baked` read.

use crate::CliError;
use crate::sample::MapArg;
use brdf_sampling::quadtree_sampler::{
    BakeConfig, BakedMode, BakedSampler, COVERAGE_LIMIT, Coverage, CoverageConfig,
    DEFAULT_COVERAGE_SAMPLES, DEFAULT_PHI_STEPS, DEFAULT_THETA_STEPS, MAX_COVERAGE_SAMPLES, Role,
    target_limit,
};
use brdf_sampling::{Brdf, DiskMap};
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

/// The options of `brdf bake`.
#[derive(Debug, clap::Args)]
pub(crate) struct BakeArgs {
    /// The bake file to write (complete or not at all: a temporary file renamed into place).
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Rows of trees in θi, from 0° to 89° (at least 2).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_THETA_STEPS)]
    theta_steps: u16,
    /// Columns of trees in φi over the φ range the model's symmetries leave (anisotropic
    /// models only; at least 2, or 3 on the full circle).
    #[arg(long, value_name = "N", default_value_t = DEFAULT_PHI_STEPS)]
    phi_steps: u16,
    /// Map of every grid tree.
    #[arg(long, value_enum, default_value_t = MapArg::Orthographic)]
    map: MapArg,
    /// Refine each grid tree until its expected trials per sample are at most this (at least
    /// 1.02, the bounds' safety factor, below which the expected trials cannot fall).
    #[arg(long, value_name = "T")]
    target_trials: Option<f64>,
    /// The most bytes the bake may hold in memory (at most 2 GiB; the JSON's `bytes`): a
    /// grid whose trees would hold more has trees pruned back (the subdivisions that save
    /// the fewest rejection trials collapsed first, across the trees over their even
    /// share), exact still but with more rejection trials a sample and a coarser warp proxy
    /// (by default 1 MiB for an isotropic model, 16 MiB for an anisotropic one: the JSON's
    /// `max_bytes`).
    #[arg(long, value_name = "BYTES")]
    max_bytes: Option<usize>,
    /// Samples drawn at each checked incident direction when checking that the grid covers
    /// the material between its trees (a tree built at the centre of every grid cell, and
    /// halfway from the last row to the horizon, draws them; the JSON's `coverage`, and a
    /// warning on stderr where a baked sample is worth under 1/4 of an exact one). 0 skips
    /// the check.
    #[arg(long, value_name = "N", default_value_t = DEFAULT_COVERAGE_SAMPLES)]
    coverage_samples: u32,
}

pub(crate) fn run(
    brdf: Arc<dyn Brdf>,
    args: &BakeArgs,
    mut stdout: impl Write,
) -> Result<(), CliError> {
    let mut config = BakeConfig {
        theta_steps: args.theta_steps,
        phi_steps: args.phi_steps,
        max_bytes: args.max_bytes,
        ..BakeConfig::default()
    };
    config.build.map = match args.map {
        MapArg::Orthographic => DiskMap::Orthographic,
        MapArg::Concentric => DiskMap::Concentric,
    };
    config.build.target_trials = args.target_trials;
    // Checked before the bake, which may take minutes.
    if args.coverage_samples > MAX_COVERAGE_SAMPLES {
        return Err(CliError::Usage(format!(
            "--coverage-samples {} must be at most {MAX_COVERAGE_SAMPLES} (0 skips the check)",
            args.coverage_samples
        )));
    }
    if brdf.symmetry().isotropic && args.phi_steps != DEFAULT_PHI_STEPS {
        eprintln!(
            "brdf: warning: `{}` is isotropic here: one row of trees serves every φi, --phi-steps is ignored",
            brdf.name()
        );
    }
    // Progress on stderr only when it is a terminal, so that scripts see the same output.
    let bar = crate::progress::Progress::new("baking trees", 0);
    let progress = |done: usize, total: usize| bar.set(done as u64, total as u64);
    let t0 = Instant::now();
    let baked = BakedSampler::new_with_progress(brdf.clone(), config, &progress)
        .map_err(|e| CliError::Usage(format!("bake: {e}")))?;
    let build_seconds = t0.elapsed().as_secs_f64();
    drop(bar);
    baked
        .save(&args.out)
        .map_err(|e| CliError::Usage(format!("--out {e}")))?;
    let file_bytes = std::fs::metadata(&args.out).map(|m| m.len()).ok();
    let stopped = baked.budget_stopped_trees();
    let max = baked.max_expected_trials();
    // A target some tree did not reach (within the tolerance target mode stops at): a
    // budget ran out, or no leaf was left that could split (all at the depth limit).
    let short = args.target_trials.filter(|&t| max > target_limit(t));
    if stopped > 0 || short.is_some() {
        // stdout stays the JSON scripts read; the shortfall is said on stderr too, as
        // `brdf sample` says it of one tree.
        let cause = if stopped > 0 {
            format!(
                "a budget (nodes, f_r evaluations or --max-bytes) stopped {stopped} of {} trees",
                baked.trees()
            )
        } else {
            String::from("the depth limit (no leaf left that could split) stopped trees")
        };
        eprintln!(
            "brdf: warning: {cause}{}",
            match short {
                Some(t) => format!(", short of --target-trials {t}: E[T] up to {max:.4}"),
                None => format!(": E[T] up to {max:.4}"),
            }
        );
    }
    let coverage = if args.coverage_samples > 0 {
        let bar = crate::progress::Progress::new("checking coverage", 0);
        let progress = |done: usize, total: usize| bar.set(done as u64, total as u64);
        let t0 = Instant::now();
        let config = CoverageConfig {
            samples: args.coverage_samples,
            ..CoverageConfig::default()
        };
        let c = baked
            .coverage_with_progress::<brdf_sampling::rng::Pcg64>(config, &progress)
            .map_err(|e| CliError::Usage(format!("--coverage-samples: {e}")))?;
        drop(bar);
        // Trees cut short with the bake at its memory limit: pruning, not only the grid,
        // may be what costs (a finer grid at the same limit prunes more).
        let pruned = stopped > 0 && baked.bytes() >= baked.max_bytes() / 10 * 9;
        if let Some(line) = coverage_warning(&c, brdf.symmetry().isotropic, pruned) {
            eprintln!("brdf: warning: {line}");
        }
        Some((c, t0.elapsed().as_secs_f64()))
    } else {
        None
    };
    let grid = baked.grid();
    let summary = json!({
        "model": brdf.name(),
        "params": brdf.params().iter().map(|(s, v)| format!("{}={v}", s.name)).collect::<Vec<_>>(),
        "file": args.out,
        "trees": baked.trees(),
        "nodes": baked.nodes(),
        "bytes": baked.bytes(),
        "file_bytes": file_bytes,
        "build_seconds": build_seconds,
        "adjoint": !brdf.symmetry().reciprocal,
        "grid": {
            "domain": format!("{:?}", grid.domain()).to_lowercase(),
            "theta_deg": grid.thetas_deg(),
            "phi_deg": grid.phis_deg(),
        },
        "map": config.build.map.name(),
        "defensive": config.defensive,
        "max_expected_trials": max,
        // The memory the bake was allowed (`--max-bytes`, or the model's default); `bytes`
        // is at most this.
        "max_bytes": baked.max_bytes(),
        // Trees whose node or evaluation budget ran out before the split rule (or
        // --target-trials) was met: exact still, with more trials a sample.
        "budget_exhausted_trees": stopped,
        // Grid cells a rejection-mode query answers with its nearest tree along θ (one model
        // evaluation fewer a sample and a pdf), of `cells` (warp mode blends everywhere); all
        // of them for a model independent of wi, answered by one tree everywhere.
        "nearest_cells": {
            "rejection": baked.nearest_cells(BakedMode::Rejection).0,
            "cells": grid.cells(),
        },
        // How much a baked sample is worth between the trees (null when skipped).
        "coverage": coverage.as_ref().map(|(c, seconds)| coverage_json(c, *seconds)),
    });
    serde_json::to_writer(&mut stdout, &summary).map_err(std::io::Error::from)?;
    writeln!(stdout)?;
    Ok(())
}

/// The `coverage` object of the bake's JSON: per mode the worst checked incident direction's
/// relative second moment R of the weight (1 for an exact sampler; null where infinite) and
/// where it is, and how many checked directions exceed the limit.
fn coverage_json(c: &Coverage, seconds: f64) -> serde_json::Value {
    let mode = |m: BakedMode| {
        c.worst(m).map(|w| {
            json!({
                "worst": w.in_mode(m),
                "theta_deg": w.theta_deg,
                "phi_deg": w.phi_deg,
                "role": role_name(w.role),
                "above_limit": c.above(m, COVERAGE_LIMIT),
            })
        })
    };
    json!({
        "samples": c.samples,
        "checked": c.cells.len(),
        "unmeasured": c.unmeasured(),
        "limit": COVERAGE_LIMIT,
        "rejection": mode(BakedMode::Rejection),
        "warp": mode(BakedMode::Warp),
        "seconds": seconds,
    })
}

fn role_name(r: Role) -> &'static str {
    match r {
        Role::Importance => "importance",
        Role::Radiance => "radiance",
    }
}

/// The warning for a grid too coarse for its material, if any checked direction is past
/// [`COVERAGE_LIMIT`] in either mode (naming --phi-steps only where the grid has columns;
/// `pruned`: the memory limit cut trees short, so a larger --max-bytes is named first).
fn coverage_warning(c: &Coverage, isotropic: bool, pruned: bool) -> Option<String> {
    let parts: Vec<String> = [BakedMode::Rejection, BakedMode::Warp]
        .into_iter()
        .filter_map(|m| {
            let above = c.above(m, COVERAGE_LIMIT);
            let w = c.worst(m)?;
            let r = w.in_mode(m)?;
            (above > 0).then(|| {
                format!(
                    "{} mode at {above} of {} checked incident directions (worst R = {r:.3e} at θi {:.2}°, φi {:.2}°{})",
                    m.name(),
                    c.cells.len(),
                    w.theta_deg,
                    w.phi_deg,
                    if w.role == Role::Radiance {
                        ", adjoint trees"
                    } else {
                        ""
                    },
                )
            })
        })
        .collect();
    (!parts.is_empty()).then(|| {
        format!(
            "the grid is too coarse for this material: between its trees a baked sample is worth \
             under 1/{COVERAGE_LIMIT} of an exact one (R > {COVERAGE_LIMIT}, R the weight's relative \
             second moment) in {}; bake with {}more {}",
            parts.join(" and "),
            if pruned {
                "a larger --max-bytes (the limit pruned its trees), or "
            } else {
                ""
            },
            finer_grid_flags(isotropic)
        )
    })
}

/// The flags that refine a bake's grid: --phi-steps only where the grid has columns.
pub(crate) fn finer_grid_flags(isotropic: bool) -> &'static str {
    if isotropic {
        "--theta-steps"
    } else {
        "--theta-steps and --phi-steps"
    }
}
