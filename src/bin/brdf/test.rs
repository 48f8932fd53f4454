//! `brdf test`: the §5 tests of SPEC (the seed's a_i convergence and Pearson χ², against
//! f·cos and against the sampler's own pdf) for one model and any `--mode` of `brdf sample`.

use crate::CliError;
use crate::images;
use crate::sample::{self, SamplerOptions};
use brdf_sampling::Brdf;
use brdf_sampling::geometry::spherical_direction;
use brdf_sampling::glam::Vec3;
use brdf_sampling::quadtree_sampler::DirectionSampler;
use brdf_sampling::quadtree_sampler::validate::{
    CellGrid, ChiSquare, Report, Validation, Verdict, sidak,
};
use rand_core::SeedableRng;
use serde_json::{Value, json};
use std::fmt::Write as _;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

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

/// The relative floor of the mean-weight test (see its use).
const WEIGHT_FLOOR: f64 = 1e-4;

/// The baked sampler's mean weight against the quadrature albedo at one wi (SPEC §7).
struct WeightTest {
    wi: Vec3,
    mean: f64,
    se: f64,
    albedo: f64,
    p: f64,
    passed: bool,
}

/// One finished test.
struct Row {
    against: Against,
    wi: Vec3,
    grid: CellGrid,
    report: Report,
    seconds: f64,
    images: Vec<PathBuf>,
}

/// SplitMix64's finaliser: decorrelates the seeds of tests and chunks.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl Row {
    /// The reasons for the verdict `--against` asks for: what rejected, then what could not
    /// be judged.
    fn reasons(&self) -> Vec<&String> {
        let (rejects, unjudged) = match self.against {
            Against::Fcos => (&self.report.reasons, &self.report.inconclusive),
            Against::Own => (&self.report.own_reasons, &self.report.own_inconclusive),
        };
        rejects.iter().chain(unjudged).collect()
    }

    /// The verdict `--against` asks for.
    fn verdict(&self) -> Verdict {
        match self.against {
            Against::Fcos => self.report.verdict(),
            Against::Own => self.report.verdict_own(),
        }
    }

    fn passed(&self) -> bool {
        self.verdict() == Verdict::Passed
    }
}

/// The run's outcome: rejected when any test rejected, else inconclusive when any could not
/// be judged, else passed (exit status 1, 3, 0).
pub(crate) fn overall(verdicts: impl IntoIterator<Item = Verdict>) -> Verdict {
    let mut out = Verdict::Passed;
    for v in verdicts {
        match v {
            Verdict::Rejected => return Verdict::Rejected,
            Verdict::Inconclusive => out = Verdict::Inconclusive,
            Verdict::Passed => {}
        }
    }
    out
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

/// Runs the tests; returns the run's verdict ([`overall`]).
pub(crate) fn run(
    brdf: &dyn Brdf,
    params: &[String],
    args: &TestArgs,
    mut stdout: impl Write,
) -> Result<Verdict, CliError> {
    if args.samples == 0 {
        return Err(CliError::Usage("--samples must be at least 1".into()));
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
    let tests = wis.len() * grids.len() + if baked { wis.len() } else { 0 };
    let alpha = sidak(args.alpha, tests);
    let mut weight_tests = Vec::new();
    let mode = format!("{:?}", args.options.mode).to_lowercase();
    let mut rows = Vec::with_capacity(tests);
    let mut builds = Vec::with_capacity(wis.len());
    let bar = crate::progress::Progress::new("testing", tests as u64);
    for (k, &wi) in wis.iter().enumerate() {
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
        for (g, &grid) in grids.iter().enumerate() {
            let t0 = Instant::now();
            let v = Validation::new(brdf, wi, grid, args.tol)?;
            let index = (k * grids.len() + g) as u64;
            let test_seed = splitmix64(args.seed ^ splitmix64(index));
            let report = v.test_chunked(
                &built.sampler,
                args.samples,
                |chunk| rand_pcg::Pcg64::seed_from_u64(splitmix64(test_seed ^ splitmix64(chunk))),
                alpha,
            );
            let seconds = t0.elapsed().as_secs_f64();
            let mut images = Vec::new();
            if let Some(dir) = &args.out {
                let stem = format!("{}-{mode}-wi{k}-{}", brdf.name(), grid_slug(grid));
                let png = dir.join(format!("{stem}.png"));
                images::write_png(&png, grid, &report)
                    .map_err(|e| CliError::Usage(format!("writing {}: {e}", png.display())))?;
                let exr = dir.join(format!("{stem}.exr"));
                images::write_exr(&exr, grid, &report, v.mass())
                    .map_err(|e| CliError::Usage(format!("writing {}: {e}", exr.display())))?;
                images.push(png);
                images.push(exr);
            }
            rows.push(Row {
                against,
                wi,
                grid,
                report,
                seconds,
                images,
            });
            bar.step();
        }
    }
    if baked {
        for (k, &wi) in wis.iter().enumerate() {
            bar.note(&format!("mean weight at wi {}/{}", k + 1, wis.len()));
            let built = sample::build(brdf, wi, &args.options)?;
            let seed = splitmix64(args.seed ^ splitmix64(0xba4e_0000 + k as u64));
            let (mean, se) = mean_weight(&built.sampler, args.samples, seed);
            let albedo = f64::from(brdf_sampling::geometry::luminance(
                brdf_sampling::quadrature::directional_albedo(brdf, wi, 96, 6).as_vec3(),
            ));
            // The trees' leaf integrals and the quadrature are exact to about 10⁻⁶; a sampler
            // this close to ∝ f·cos has a standard error far below that, so the difference is
            // judged against the counting error and a 10⁻⁴ relative floor together.
            let scale = (se * se + (WEIGHT_FLOOR * albedo).powi(2)).sqrt();
            let z = if scale > 0.0 {
                (mean - albedo).abs() / scale
            } else if mean == albedo {
                0.0
            } else {
                f64::INFINITY
            };
            let p = brdf_sampling::special::erfc(z / std::f64::consts::SQRT_2);
            bar.step();
            weight_tests.push(WeightTest {
                wi,
                mean,
                se,
                albedo,
                p,
                passed: p >= alpha,
            });
        }
    }
    drop(bar);
    let verdict = overall(
        rows.iter()
            .map(Row::verdict)
            .chain(weight_tests.iter().map(|w| {
                if w.passed {
                    Verdict::Passed
                } else {
                    Verdict::Rejected
                }
            })),
    );
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
        for w in &weight_tests {
            table.push_str(&format!(
                "| {:.4},{:.4},{:.4} | {:.6} | {:.2e} | {:.6} | {:.3e} | {} |\n",
                w.wi.x,
                w.wi.y,
                w.wi.z,
                w.mean,
                w.se,
                w.albedo,
                w.p,
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
            "weight_tests": weight_tests.iter().map(|w| json!({
                "wi": [w.wi.x, w.wi.y, w.wi.z],
                "mean_weight": w.mean,
                "standard_error": w.se,
                "albedo": w.albedo,
                "p_value": w.p,
                "passed": w.passed,
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
        let (theta, phi) = angles(r.wi);
        let rep = &r.report;
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
            r.wi.x,
            r.wi.y,
            r.wi.z,
            grid_name(r.grid),
            p_text(rep.chi2.as_ref()),
            p_text(rep.chi2_own.as_ref()),
            r.seconds,
            verdict_text(r.verdict())
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
    let rep = &r.report;
    let (theta, phi) = angles(r.wi);
    let (rows, cols) = r.grid.dims();
    json!({
        "wi": [r.wi.x, r.wi.y, r.wi.z],
        "theta_deg": theta,
        "phi_deg": phi,
        "grid": {"kind": grid_slug(r.grid), "rows": rows, "cols": cols},
        "chi2": chi_json(rep.chi2.as_ref()),
        "chi2_own": chi_json(rep.chi2_own.as_ref()),
        "spread": rep.spread.as_ref().map_or(Value::Null, |s| json!({
            "a": s.a, "cells": s.cells, "min": s.min, "max": s.max, "rms": s.rms, "noise": s.noise,
        })),
        "lost": rep.lost,
        "outside": rep.outside,
        "inconsistent": rep.inconsistent,
        "in_empty_cells": rep.in_empty_cells,
        "seconds": r.seconds,
        "passed": r.passed(),
        "verdict": verdict_slug(r.verdict()),
        "reasons": r.reasons(),
        "images": r.images.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
    })
}

/// The mean luminance weight and its standard error over `samples` draws (lost samples
/// score 0), in chunks of 65536 with their own generators, summed in order.
fn mean_weight(sampler: &dyn DirectionSampler, samples: u64, seed: u64) -> (f64, f64) {
    use rayon::prelude::*;
    let chunk = 1u64 << 16;
    let parts: Vec<(f64, f64)> = (0..samples.div_ceil(chunk))
        .into_par_iter()
        .map(|k| {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(splitmix64(seed ^ splitmix64(k)));
            let n = chunk.min(samples - k * chunk);
            let (mut s, mut q) = (0.0, 0.0);
            for _ in 0..n {
                let w = sampler.sample(&mut rng).map_or(0.0, |s| {
                    f64::from(brdf_sampling::geometry::luminance(s.weight))
                });
                s += w;
                q += w * w;
            }
            (s, q)
        })
        .collect();
    let (s, q) = parts.iter().fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    let n = samples as f64;
    let m = s / n;
    (m, ((q / n - m * m).max(0.0) / n).sqrt())
}
