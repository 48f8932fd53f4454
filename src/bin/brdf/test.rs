//! `brdf test`: the §5 tests of SPEC (the seed's a_i convergence and Pearson χ², against
//! f·cos and against the sampler's own pdf) for one model and any `--mode` of `brdf sample`.

use crate::CliError;
use crate::images;
use crate::sample::{self, SamplerOptions};
use brdf_sampling::Brdf;
use brdf_sampling::geometry::spherical_direction;
use brdf_sampling::glam::Vec3;
use brdf_sampling::quadtree_sampler::{
    BakedMode, COVERAGE_LIMIT, CellCoverage, CoverageConfig, Role,
};
use brdf_sampling::validate::{
    self as validate, CellGrid, ChiSquare, Event, Settings, TestOutcome, Verdict,
};
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::io::Write;
use std::path::PathBuf;

/// Which cells (`--grid`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum GridArg {
    /// The seed's R × R squares over [−1,1]².
    Square,
    /// The equal-area polar grid: R rings in r² × (2R + 1) sectors in φ.
    Polar,
    /// Both grids, one test each.
    Both,
}

/// What the verdict judges (`--against`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Against {
    /// SPEC §5: the samples must follow f·cos **and** the sampler's own pdf.
    Fcos,
    /// Only the sampler's own pdf (for samplers not meant to follow f·cos: an analytic lobe
    /// sampler, the warp); the χ² against f·cos is still printed.
    Own,
}

/// The options of `brdf test`.
#[derive(Debug, clap::Args)]
pub(crate) struct TestArgs {
    /// Incident direction x,y,z (repeat for several). Default: θ = 0°, 45° and 80° at φ = 30°.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    wi: Vec<String>,
    #[command(flatten)]
    options: SamplerOptions,
    /// Samples per test.
    #[arg(long, default_value_t = 1_000_000)]
    samples: u64,
    /// Grid resolution R: R × R squares, or R rings × (2R + 1) sectors.
    #[arg(long, value_name = "R", default_value_t = 25)]
    cells: usize,
    /// Which cell grid(s).
    #[arg(long, value_enum, default_value_t = GridArg::Both)]
    grid: GridArg,
    /// What the verdict judges.
    #[arg(long, value_enum, default_value_t = Against::Fcos)]
    against: Against,
    /// Family-wise significance of the run; each test is judged at Šidák's 1 − (1 − α)^(1/k).
    #[arg(long, default_value_t = 0.01)]
    alpha: f64,
    /// RNG seed (PCG64; every test and every chunk of 65536 samples seeds its own generator
    /// from it, so the result does not depend on the thread count).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Relative tolerance of the expected cell masses (per cell, relative to the total).
    #[arg(long, default_value_t = 1e-7)]
    tol: f64,
    /// Directory for the images: per test a PNG (expected | observed | (n − e)/√e) and an EXR
    /// of the raw arrays, and `index.md` with the table.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

impl TestArgs {
    /// The sampler options (for `main` to load `--baked` into).
    pub(crate) fn options_mut(&mut self) -> &mut SamplerOptions {
        &mut self.options
    }
}

impl From<Against> for validate::Against {
    fn from(a: Against) -> Self {
        match a {
            Against::Fcos => Self::FCos,
            Against::Own => Self::OwnPdf,
        }
    }
}

/// One finished test with the pictures written of it.
struct Row {
    test: TestOutcome,
    images: Vec<PathBuf>,
}

impl Row {
    /// The incident direction (every test of a suite has one).
    fn wi(&self) -> Vec3 {
        self.test.wi.unwrap_or(Vec3::Z)
    }

    /// What rejected, then what could not be judged, as text.
    fn reasons(&self) -> Vec<String> {
        self.test
            .reasons()
            .iter()
            .map(ToString::to_string)
            .collect()
    }
}

fn verdict_text(v: Verdict) -> &'static str {
    match v {
        Verdict::Passed => "pass",
        Verdict::Rejected => "REJECT",
        Verdict::Inconclusive => "INCONCLUSIVE",
    }
}

fn verdict_slug(v: Verdict) -> &'static str {
    match v {
        Verdict::Passed => "passed",
        Verdict::Rejected => "rejected",
        Verdict::Inconclusive => "inconclusive",
    }
}

/// The incident directions of a run without `--wi`: θ = 0°, 45°, 80° at φ = 30°.
fn default_wis() -> Vec<Vec3> {
    [0.0f32, 45.0, 80.0]
        .iter()
        .map(|t| spherical_direction(t.to_radians(), 30f32.to_radians()))
        .collect()
}

fn angles(w: Vec3) -> (f64, f64) {
    let w = w.as_dvec3();
    let theta = w.z.clamp(-1.0, 1.0).acos().to_degrees();
    let mut phi = w.y.atan2(w.x).to_degrees();
    if phi < 0.0 {
        phi += 360.0;
    }
    if theta < 1e-9 {
        (0.0, 0.0)
    } else {
        (theta, phi)
    }
}

fn grid_name(g: CellGrid) -> String {
    match g {
        CellGrid::Square { res } => format!("square {res}×{res}"),
        CellGrid::Polar { rings, sectors } => format!("polar {rings}×{sectors}"),
    }
}

fn grid_slug(g: CellGrid) -> &'static str {
    match g {
        CellGrid::Square { .. } => "square",
        CellGrid::Polar { .. } => "polar",
    }
}

/// Runs the tests (the suite of `brdf_validate`); returns the run's verdict.
pub(crate) fn run(
    brdf: &dyn Brdf,
    params: &[String],
    args: &TestArgs,
    mut stdout: impl Write,
) -> Result<Verdict, CliError> {
    if args.samples == 0 {
        return Err(CliError::Usage("--samples must be at least 1".into()));
    }
    if args.samples > brdf_sampling::validate::MAX_SAMPLES {
        return Err(CliError::Usage(format!(
            "--samples {}: at most {} (2^36) per test",
            args.samples,
            brdf_sampling::validate::MAX_SAMPLES
        )));
    }
    if args.cells < 2 || args.cells > 4096 {
        return Err(CliError::Usage(format!(
            "--cells {}: the grid resolution must be in [2, 4096]",
            args.cells
        )));
    }
    if !(args.alpha > 0.0 && args.alpha < 1.0) {
        return Err(CliError::Usage(format!(
            "--alpha {}: the significance must be in (0, 1)",
            args.alpha
        )));
    }
    if !(args.tol > 0.0 && args.tol < 1e-2) {
        return Err(CliError::Usage(format!(
            "--tol {}: the tolerance must be in (0, 0.01)",
            args.tol
        )));
    }
    let wis = if args.wi.is_empty() {
        default_wis()
    } else {
        args.wi
            .iter()
            .map(|w| sample::parse_wi(w))
            .collect::<Result<_, _>>()?
    };
    let r = args.cells;
    let grids: Vec<CellGrid> = match args.grid {
        GridArg::Square => vec![CellGrid::Square { res: r }],
        GridArg::Polar => vec![CellGrid::Polar {
            rings: r,
            sectors: 2 * r + 1,
        }],
        GridArg::Both => vec![
            CellGrid::Square { res: r },
            CellGrid::Polar {
                rings: r,
                sectors: 2 * r + 1,
            },
        ],
    };
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir)
            .map_err(|e| CliError::Usage(format!("--out {}: {e}", dir.display())))?;
    }
    sample::warn_ignored(&args.options);
    let baked = args.options.loaded.is_some();
    // A baked sampler is judged on its own pdf (it follows f·cos only on its grid), plus one
    // test per wi that its mean weight is the albedo.
    let against = if baked { Against::Own } else { args.against };
    let settings = Settings {
        grids,
        samples: args.samples,
        seed: args.seed,
        alpha: args.alpha,
        tol: args.tol,
        against: against.into(),
        mean_weight: baked,
    };
    let tests = settings.tests(wis.len());
    let mode = format!("{:?}", args.options.mode).to_lowercase();
    let mut builds = Vec::with_capacity(wis.len());
    let mut images = Vec::with_capacity(tests);
    let bar = crate::progress::Progress::new("testing", tests as u64);
    let per_wi = settings.grids.len();
    let report = validate::suite(
        brdf,
        &wis,
        &settings,
        |k, wi| {
            bar.note(&format!("wi {}/{}", k + 1, wis.len()));
            let built = sample::build(brdf, wi, &args.options)?;
            let stats = built.sampler.tree_stats();
            builds.push(json!({
                "wi": [wi.x, wi.y, wi.z],
                "build_seconds": built.build_seconds,
                "nodes": stats.as_ref().map(|t| t.nodes),
                "leaves": stats.as_ref().map(|t| t.leaves),
                "max_depth": stats.as_ref().map(|t| t.max_depth),
                "expected_trials": stats.as_ref().filter(|_| built.sampler.bound_violations().is_some()).map(|t| t.expected_trials),
            }));
            Ok::<_, CliError>(built.sampler)
        },
        |event| {
            match event {
                Event::Tested(outcome) => {
                    let mut written = Vec::new();
                    if let Some(dir) = &args.out {
                        let k = images.len() / per_wi;
                        let stem =
                            format!("{}-{mode}-wi{k}-{}", brdf.name(), grid_slug(outcome.grid));
                        let png = dir.join(format!("{stem}.png"));
                        images::write_png(&png, &outcome.report.histogram).map_err(|e| {
                            CliError::Usage(format!("writing {}: {e}", png.display()))
                        })?;
                        let exr = dir.join(format!("{stem}.exr"));
                        outcome
                            .report
                            .histogram
                            .write_exr(&exr, "brdf test")
                            .map_err(|e| {
                                CliError::Usage(format!("writing {}: {e}", exr.display()))
                            })?;
                        written.push(png);
                        written.push(exr);
                    }
                    images.push(written);
                    bar.step();
                }
                Event::WeighingStarts { index, of } => {
                    bar.note(&format!("mean weight at wi {}/{of}", index + 1));
                }
                Event::Weighed(_) => bar.step(),
            }
            Ok(())
        },
    )?;
    drop(bar);
    let verdict = report.verdict();
    let alpha = report.alpha_per_test;
    let weight_tests = &report.weight_tests;
    // How much a baked sample is worth at each tested wi (R, see `brdf bake`'s coverage):
    // the mean-weight test can pass on a heavy tail that R shows.
    let coverage: Vec<Option<CellCoverage>> = match &args.options.loaded {
        Some(bake) => weight_tests
            .iter()
            .map(|w| {
                w.wi.and_then(|wi| {
                    bake.coverage_at::<brdf_sampling::rng::Pcg64>(
                        Role::Importance,
                        wi,
                        CoverageConfig::default(),
                    )
                    .ok()
                })
            })
            .collect(),
        None => Vec::new(),
    };
    let tested = match args.options.mode {
        sample::Mode::Warp => BakedMode::Warp,
        _ => BakedMode::Rejection,
    };
    for (w, c) in weight_tests.iter().zip(&coverage) {
        if let (Some(wi), Some(r)) = (w.wi, c.and_then(|c| c.in_mode(tested)))
            && (r > COVERAGE_LIMIT || r.is_nan())
        {
            eprintln!(
                "brdf: warning: at wi {:.4},{:.4},{:.4} a baked sample is worth 1/{r:.3e} of an exact one in {} mode (R = {r:.3e} > {COVERAGE_LIMIT}): the mean weight's standard error understates a heavy tail there; bake with more {}",
                wi.x,
                wi.y,
                wi.z,
                tested.name(),
                crate::bake::finer_grid_flags(brdf.symmetry().isotropic),
            );
        }
    }
    let rows: Vec<Row> = report
        .tests
        .into_iter()
        .zip(images)
        .map(|(test, images)| Row { test, images })
        .collect();
    let passed = verdict == Verdict::Passed;
    let header = format!(
        "model {}{}{}, sampler {mode}{}, {} samples per test, judged against {}, α = {} over {tests} tests (Šidák: {:.3e} each)",
        brdf.name(),
        if params.is_empty() { "" } else { " " },
        params.join(" "),
        if args.options.mode == sample::Mode::Rejection {
            format!(" ({:?} map)", args.options.map).to_lowercase()
        } else {
            String::new()
        },
        args.samples,
        match (against, baked) {
            (Against::Fcos, _) => "f·cos and its own pdf",
            (Against::Own, false) => "its own pdf",
            (Against::Own, true) => "its own pdf, and its mean weight against the albedo",
        },
        args.alpha,
        alpha
    );
    let mut table = table(&header, &rows);
    if baked {
        table.push_str("\n| wi | mean weight | SE | albedo (quadrature) | p | verdict |\n|---|---:|---:|---:|---:|---|\n");
        for w in weight_tests {
            table.push_str(&format!(
                "| {:.4},{:.4},{:.4} | {:.6} | {:.2e} | {:.6} | {:.3e} | {} |\n",
                w.wi.unwrap_or(Vec3::Z).x,
                w.wi.unwrap_or(Vec3::Z).y,
                w.wi.unwrap_or(Vec3::Z).z,
                w.mean,
                w.standard_error,
                w.albedo,
                w.p_value,
                if w.passed {
                    "pass"
                } else {
                    "REJECT: the mean weight is not the albedo"
                }
            ));
        }
    }
    if let Some(dir) = &args.out {
        let index = dir.join("index.md");
        brdf_sampling::quadtree_sampler::write_atomically(
            &index,
            format!("# brdf test\n\n{table}\n{LEGEND}\n").as_bytes(),
        )
        .map_err(|e| CliError::Usage(format!("writing {}: {e}", index.display())))?;
    }
    if args.json {
        let tests: Vec<Value> = rows.iter().map(row_json).collect();
        let out = json!({
            "model": brdf.name(),
            "params": params,
            "mode": mode,
            "against": format!("{:?}", against).to_lowercase(),
            "baked": baked,
            "weight_tests": weight_tests.iter().enumerate().map(|(k, w)| json!({
                "wi": w.wi.map(|wi| [wi.x, wi.y, wi.z]),
                "mean_weight": w.mean,
                "standard_error": w.standard_error,
                "albedo": w.albedo,
                "p_value": w.p_value,
                "passed": w.passed,
                // R in both modes at this wi (null where unmeasured).
                "coverage": coverage.get(k).copied().flatten().map(|c| json!({
                    "rejection": c.rejection,
                    "warp": c.warp,
                    "limit": COVERAGE_LIMIT,
                })),
            })).collect::<Vec<_>>(),
            "samples": args.samples,
            "alpha": args.alpha,
            "alpha_per_test": alpha,
            "builds": builds,
            "tests": tests,
            "passed": passed,
            "verdict": verdict_slug(verdict),
        });
        serde_json::to_writer(&mut stdout, &out).map_err(std::io::Error::from)?;
        writeln!(stdout)?;
    } else {
        write!(stdout, "{table}")?;
        if args.out.is_some() {
            writeln!(stdout, "\n{LEGEND}")?;
        }
    }
    Ok(verdict)
}

const LEGEND: &str = "Images: expected | observed counts per cell (viridis, linear from 0 to the \
largest count) | (n − e)/√e (RdBu, blue = too few, red = too many, saturating at ±4); grey is \
off the disk. The EXR files hold the raw arrays (channels expected, expected_own, mass, observed, \
residual).";

fn p_text(c: Option<&ChiSquare>) -> String {
    c.map_or_else(|| "–".into(), |c| format!("{:.3e}", c.p_value))
}

fn table(header: &str, rows: &[Row]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{header}\n");
    let _ = writeln!(
        s,
        "| wi | θ° | φ° | grid | χ² | dof | p | p (own pdf) | a_i/a RMS | noise RMS | a_i/a min–max | s | verdict |"
    );
    let _ = writeln!(
        s,
        "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---|---:|---|"
    );
    for r in rows {
        let (theta, phi) = angles(r.wi());
        let rep = &r.test.report;
        let (chi, dof) = rep.chi2.as_ref().map_or_else(
            || ("–".into(), "–".into()),
            |c| (format!("{:.1}", c.statistic), c.dof.to_string()),
        );
        let (rms, noise, range) = rep.spread.as_ref().map_or_else(
            || ("–".into(), "–".into(), "–".into()),
            |s| {
                (
                    format!("{:.4}", s.rms),
                    format!("{:.4}", s.noise),
                    format!("{:.3}–{:.3}", s.min, s.max),
                )
            },
        );
        let _ = writeln!(
            s,
            "| {:.4},{:.4},{:.4} | {theta:.1} | {phi:.1} | {} | {chi} | {dof} | {} | {} | {rms} | {noise} | {range} | {:.2} | {} |",
            r.wi().x,
            r.wi().y,
            r.wi().z,
            grid_name(r.test.grid),
            p_text(rep.chi2.as_ref()),
            p_text(rep.chi2_own.as_ref()),
            r.test.seconds,
            verdict_text(r.test.verdict())
        );
    }
    for (k, r) in rows.iter().enumerate() {
        for reason in r.reasons() {
            let _ = writeln!(s, "\nrow {}: {reason}", k + 1);
        }
    }
    s
}

fn chi_json(c: Option<&ChiSquare>) -> Value {
    c.map_or(
        Value::Null,
        |c| json!({"statistic": c.statistic, "dof": c.dof, "p_value": c.p_value, "bins": c.bins}),
    )
}

fn row_json(r: &Row) -> Value {
    let rep = &r.test.report;
    let wi = r.wi();
    let (theta, phi) = angles(wi);
    let (rows, cols) = r.test.grid.dims();
    json!({
        "wi": [wi.x, wi.y, wi.z],
        "theta_deg": theta,
        "phi_deg": phi,
        "grid": {"kind": grid_slug(r.test.grid), "rows": rows, "cols": cols},
        "chi2": chi_json(rep.chi2.as_ref()),
        "chi2_own": chi_json(rep.chi2_own.as_ref()),
        "spread": rep.spread.as_ref().map_or(Value::Null, |s| json!({
            "a": s.a, "cells": s.cells, "min": s.min, "max": s.max, "rms": s.rms, "noise": s.noise,
        })),
        "lost": rep.lost,
        "outside": rep.outside,
        "inconsistent": rep.inconsistent,
        "in_empty_cells": rep.in_empty_cells,
        "seconds": r.test.seconds,
        "passed": r.test.verdict() == Verdict::Passed,
        "verdict": verdict_slug(r.test.verdict()),
        "reasons": r.reasons(),
        "images": r.images.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
    })
}
