//! `brdf sample` and `brdf pdf`: the quadtree (rejection) and the baselines.

use crate::CliError;
use brdf_sampling::geometry::{unit_direction, unit_direction_above};
use brdf_sampling::glam::Vec3;
use brdf_sampling::quadtree_sampler::{
    AnySampler, BakedMode, BakedSampler, BuildConfig, DirectionSampler, SamplerMode, TreeStats,
    target_limit,
};
use brdf_sampling::{Brdf, DiskMap};
use rand_core::SeedableRng;
use serde_json::{Value, json};
use std::io::{BufRead, BufWriter, Write};
use std::sync::Arc;

use std::time::Instant;

/// Which sampler (`--mode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Mode {
    /// The seed's quadtree with rejection in the leaves (default).
    Rejection,
    /// The invertible warp of SPEC §4 over the concentric-map tree (no rejection loop).
    Warp,
    /// Uniform on the hemisphere.
    Uniform,
    /// Cosine-weighted.
    Cosine,
    /// The model's own sampler (cosine for models without one).
    Analytic,
    /// A piecewise-constant 256² table over the concentric square (marginal/conditional), the
    /// tabulated baseline renderers use.
    Table,
}

/// The map of the quadtree (`--map`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum MapArg {
    /// The seed's orthographic `Codificador`.
    Orthographic,
    /// Shirley–Chiu concentric.
    Concentric,
}

/// The incident direction and sampler options of `sample` and `pdf`.
#[derive(Debug, clap::Args)]
pub(crate) struct SamplerArgs {
    /// Incident direction x,y,z in the local frame (normalised; must be above the horizon).
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    wi: String,
    #[command(flatten)]
    pub(crate) options: SamplerOptions,
}

/// The sampler options shared by `sample`, `pdf` and `test`.
#[derive(Debug, clap::Args)]
pub(crate) struct SamplerOptions {
    /// Sampler.
    #[arg(long, value_enum, default_value_t = Mode::Rejection)]
    pub(crate) mode: Mode,
    /// Quadtree map (rejection mode).
    #[arg(long, value_enum, default_value_t = MapArg::Orthographic)]
    pub(crate) map: MapArg,
    /// Refine the quadtree until the expected trials per sample are at most this (rejection;
    /// at least 1.02, the bounds' safety factor, below which they cannot fall).
    #[arg(long, value_name = "T")]
    pub(crate) target_trials: Option<f64>,
    /// Sample a baked sampler (a file of `brdf bake`) instead of building a tree for wi
    /// (SPEC §7); `--mode` is then `rejection` or `warp`, and `--model` may be left out.
    #[arg(long, value_name = "FILE")]
    pub(crate) baked: Option<std::path::PathBuf>,
    /// The loaded bake (filled in by `main` from `--baked`).
    #[arg(skip)]
    pub(crate) loaded: Option<Arc<BakedSampler>>,
}

/// Loads `--baked` into `options.loaded` (typed errors exit 2), warns about the flags a bake
/// ignores, and checks `--model`/`--param`, when given, against the bake's model.
pub(crate) fn load_baked(
    options: &mut SamplerOptions,
    model: Option<&str>,
    params: &[String],
) -> Result<Option<Arc<dyn Brdf>>, CliError> {
    let Some(path) = &options.baked else {
        return Ok(None);
    };
    let mode = match options.mode {
        Mode::Rejection => BakedMode::Rejection,
        Mode::Warp => BakedMode::Warp,
        m => {
            return Err(CliError::Usage(format!(
                "--baked samples in mode rejection or warp, not {}",
                format!("{m:?}").to_lowercase()
            )));
        }
    };
    if options.map != MapArg::Orthographic || options.target_trials.is_some() {
        eprintln!(
            "brdf: warning: --map and --target-trials are fixed when baking; ignored with --baked"
        );
    }
    let baked = BakedSampler::load(path)
        .map_err(|e| CliError::Usage(format!("--baked {e}")))?
        .with_mode(mode);
    if let Some(name) = model {
        let want = brdf_sampling::registry::create(name, params.iter().map(String::as_str))?;
        if want.name() != baked.brdf().name() || want.params() != baked.brdf().params() {
            return Err(CliError::Usage(format!(
                "--baked {}: baked for model `{}` with other parameters than --model {name} {}",
                path.display(),
                baked.brdf().name(),
                params.join(" ")
            )));
        }
    }
    let brdf = baked.brdf().clone();
    options.loaded = Some(Arc::new(baked));
    Ok(Some(brdf))
}

/// Parses `x,y,z` into a direction (not yet normalised).
pub(crate) fn parse_vec3(text: &str, what: &str) -> Result<Vec3, CliError> {
    brdf_sampling::text::parse_vec3(text).map_err(|e| CliError::Usage(format!("{what} {e}")))
}

/// A built sampler (the library's factory, [`AnySampler`]) and its build time.
pub(crate) struct Built<'a> {
    /// The sampler, with its statistics.
    pub(crate) sampler: AnySampler<&'a dyn Brdf>,
    /// Seconds spent building (0 for the baselines and a loaded bake).
    pub(crate) build_seconds: f64,
}

/// Parses and checks `--wi`.
pub(crate) fn parse_wi(text: &str) -> Result<Vec3, CliError> {
    unit_direction_above(parse_vec3(text, "--wi")?)
        .map_err(|e| CliError::Usage(format!("--wi {}: {e}", brdf_sampling::text::excerpt(text))))
}

fn build_from<'a>(brdf: &'a dyn Brdf, args: &SamplerArgs) -> Result<Built<'a>, CliError> {
    warn_ignored(&args.options);
    build(brdf, parse_wi(&args.wi)?, &args.options)
}

/// The flags the chosen mode does not use, each with why (empty when all apply). A baked
/// sampler's own warning is [`load_baked`]'s.
pub(crate) fn ignored_flags(options: &SamplerOptions) -> Vec<String> {
    let mut out = Vec::new();
    if options.loaded.is_some() {
        return out;
    }
    let mode = format!("{:?}", options.mode).to_lowercase();
    if options.map != MapArg::Orthographic && options.mode != Mode::Rejection {
        out.push(format!(
            "--map applies to rejection mode only (warp always uses the concentric map); ignored with --mode {mode}"
        ));
    }
    if options.target_trials.is_some() && !matches!(options.mode, Mode::Rejection | Mode::Warp) {
        out.push(format!(
            "--target-trials applies to the quadtree modes (rejection, warp); ignored with --mode {mode}"
        ));
    }
    out
}

/// Prints [`ignored_flags`] on stderr as warnings (the CLI only extends: not an error).
pub(crate) fn warn_ignored(options: &SamplerOptions) {
    for w in ignored_flags(options) {
        eprintln!("brdf: warning: {w}");
    }
}

/// Builds the sampler `args` names for `brdf` at `wi` (unit, above the horizon).
pub(crate) fn build<'a>(
    brdf: &'a dyn Brdf,
    wi: Vec3,
    args: &SamplerOptions,
) -> Result<Built<'a>, CliError> {
    if brdf.is_delta() {
        return Err(CliError::Usage(format!(
            "model `{}` is a Dirac delta: it has no continuous part to sample (its only direction is the mirror of wi)",
            brdf.name()
        )));
    }
    let t0 = Instant::now();
    if let Some(baked) = &args.loaded {
        return Ok(Built {
            sampler: AnySampler::baked(baked.clone(), wi)?,
            build_seconds: 0.0,
        });
    }
    let mode = match args.mode {
        Mode::Uniform => SamplerMode::Uniform,
        Mode::Cosine => SamplerMode::Cosine,
        Mode::Analytic => SamplerMode::Analytic,
        Mode::Table => SamplerMode::Table,
        Mode::Warp => SamplerMode::Warp,
        Mode::Rejection => SamplerMode::Rejection,
    };
    let config = BuildConfig {
        map: match args.map {
            MapArg::Orthographic => DiskMap::Orthographic,
            MapArg::Concentric => DiskMap::Concentric,
        },
        target_trials: args.target_trials,
        ..BuildConfig::default()
    };
    let sampler = AnySampler::new(brdf, wi, mode, config)?;
    let build_seconds = if mode.builds_tree() || mode == SamplerMode::Table {
        t0.elapsed().as_secs_f64()
    } else {
        0.0
    };
    Ok(Built {
        sampler,
        build_seconds,
    })
}

/// The most records one `brdf sample` writes: 2³² (64 GiB of records). A larger `--count`
/// is refused before anything is built or written.
pub(crate) const MAX_COUNT: u64 = 1 << 32;

pub(crate) fn run_sample(
    brdf: &dyn Brdf,
    args: &SamplerArgs,
    count: u64,
    seed: u64,
    out: &std::path::Path,
    mut stdout: impl Write,
) -> Result<(), CliError> {
    if count > MAX_COUNT {
        return Err(CliError::Usage(format!(
            "--count {count}: at most {MAX_COUNT} records (2^32, 64 GiB) per run"
        )));
    }
    let built = build_from(brdf, args)?;
    // Complete or absent: the records go to a temporary file beside `out`, renamed over it
    // once all are written and synced; any failure removes it.
    let tmp = brdf_sampling::quadtree_sampler::temporary_beside(out)
        .map_err(|e| CliError::Usage(format!("--out {}: {e}", out.display())))?;
    let file = std::fs::File::create(&tmp)
        .map_err(|e| CliError::Usage(format!("--out {}: {e}", out.display())))?;
    let guard = RemoveOnDrop(Some(tmp.clone()));
    let mut w = BufWriter::with_capacity(1 << 20, file);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let t0 = Instant::now();
    let (mut trials, mut lost, mut weight_sum) = (0u64, 0u64, 0.0f64);
    for _ in 0..count {
        let rec = match built.sampler.sample(&mut rng) {
            Some(s) => {
                trials += u64::from(s.trials);
                weight_sum += f64::from(brdf_sampling::geometry::luminance(s.weight));
                [s.wo.x, s.wo.y, s.wo.z, s.pdf]
            }
            None => {
                trials += 1;
                lost += 1;
                [0.0; 4]
            }
        };
        for v in rec {
            w.write_all(&v.to_le_bytes())?;
        }
    }
    let file = w.into_inner().map_err(|e| e.into_error())?;
    file.sync_all()?;
    drop(file);
    std::fs::rename(&tmp, out)
        .map_err(|e| CliError::Usage(format!("--out {}: {e}", out.display())))?;
    guard.disarm();
    let sample_seconds = t0.elapsed().as_secs_f64();
    let n = count.max(1) as f64;
    let mut summary = json!({
        "model": brdf.name(),
        "mode": format!("{:?}", args.options.mode).to_lowercase(),
        "count": count,
        "seed": seed,
        "build_seconds": built.build_seconds,
        "sample_seconds": sample_seconds,
        "mean_trials": trials as f64 / n,
        "lost": lost,
        "mean_weight": weight_sum / n,
    });
    let obj = summary.as_object_mut().expect("an object");
    let tree = built
        .sampler
        .tree_stats()
        .zip(built.sampler.albedo())
        .map(|(stats, albedo)| (stats, albedo, built.sampler.bound_violations()));
    match &tree {
        Some((stats, albedo, violations)) => {
            obj.insert("albedo".into(), json!(albedo));
            obj.insert("albedo_method".into(), json!("quadtree volume"));
            obj.insert("nodes".into(), json!(stats.nodes));
            obj.insert("leaves".into(), json!(stats.leaves));
            obj.insert("max_depth".into(), json!(stats.max_depth));
            obj.insert("bytes".into(), json!(stats.bytes));
            obj.insert("budget_exhausted".into(), json!(stats.budget_exhausted));
            let target = args.options.target_trials;
            obj.insert(
                "target_reached".into(),
                match target {
                    Some(t) => json!(stats.expected_trials <= target_limit(t)),
                    None => Value::Null,
                },
            );
            if let Some(warning) = shortfall(stats, target) {
                // stdout stays the JSON scripts read; the shortfall is said on stderr too.
                eprintln!("{warning}");
            }
            match violations {
                Some(v) => {
                    obj.insert("expected_trials".into(), json!(stats.expected_trials));
                    obj.insert("bound_violations".into(), json!(v));
                }
                None => {
                    obj.insert("expected_trials".into(), Value::Null);
                    obj.insert("bound_violations".into(), Value::Null);
                }
            }
        }
        None if built.sampler.bake().is_some() => {
            let b = built.sampler.bake().expect("a bake");
            obj.insert("albedo".into(), json!(weight_sum / n));
            obj.insert(
                "albedo_method".into(),
                json!("monte carlo (mean weight of the baked sampler)"),
            );
            obj.insert("mode".into(), json!(b.mode().name()));
            obj.insert("baked".into(), json!(true));
            obj.insert("trees".into(), json!(b.trees()));
            obj.insert("nodes".into(), json!(b.nodes()));
            obj.insert("bytes".into(), json!(b.bytes()));
            obj.insert("leaves".into(), Value::Null);
            obj.insert("max_depth".into(), Value::Null);
            obj.insert("budget_exhausted".into(), Value::Null);
            obj.insert("target_reached".into(), Value::Null);
            obj.insert("expected_trials".into(), Value::Null);
            obj.insert(
                "bound_violations".into(),
                match b.mode() {
                    BakedMode::Rejection => json!(b.bound_violations()),
                    BakedMode::Warp => Value::Null,
                },
            );
        }
        None => {
            obj.insert("albedo".into(), json!(weight_sum / n));
            obj.insert("albedo_method".into(), json!("monte carlo (mean weight)"));
            for k in [
                "nodes",
                "leaves",
                "max_depth",
                "expected_trials",
                "bytes",
                "bound_violations",
                "budget_exhausted",
                "target_reached",
            ] {
                obj.insert(k.into(), Value::Null);
            }
        }
    }
    serde_json::to_writer(&mut stdout, &summary).map_err(std::io::Error::from)?;
    writeln!(stdout)?;
    Ok(())
}

pub(crate) fn run_pdf(
    brdf: &dyn Brdf,
    args: &SamplerArgs,
    mut input: impl BufRead,
    out: impl Write,
) -> Result<(), CliError> {
    let built = build_from(brdf, args)?;
    let mut out = BufWriter::new(out);
    let mut fmt = ryu::Buffer::new();
    let (mut line, mut lineno) = (String::new(), 0u64);
    while crate::eval::next_line(&mut input, &mut line, lineno)? {
        lineno += 1;
        let bad = |message: String| CliError::Input {
            line: lineno,
            message,
        };
        let v = match brdf_sampling::text::parse_numbers::<3>(&line, "wox woy woz") {
            Ok(Some(v)) => v,
            Ok(None) => continue,
            Err(e) => return Err(bad(e.to_string())),
        };
        // A zero, NaN or infinite direction is an input error. A valid one goes to the
        // sampler as read: each pdf normalises what is not unit to f32 rounding the way the
        // pdf a sample carries was computed, so a record's direction read back gets that
        // pdf bit for bit (normalising here first moved its last bits, and on a sharp lobe
        // the pdf by 2·10⁻⁴).
        let v = Vec3::from_array(v);
        let wo = unit_direction(v)
            .map(|_| v)
            .map_err(|e| bad(format!("wo: {e}")))?;
        out.write_all(fmt.format(built.sampler.pdf(wo)).as_bytes())?;
        out.write_all(b"\n")?;
    }
    out.flush()?;
    Ok(())
}

/// Removes a temporary file when dropped, unless disarmed.
pub(crate) struct RemoveOnDrop(pub(crate) Option<std::path::PathBuf>);

impl RemoveOnDrop {
    /// Keeps the file (it has been renamed into place).
    pub(crate) fn disarm(mut self) {
        self.0 = None;
    }
}

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        if let Some(p) = self.0.take() {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// The warning for a tree its build stopped short: a budget ran out, or a `target` E\[T\]
/// was not reached (within the tolerance target mode stops at) because no leaf was left
/// that could split (all at the depth limit). `None` for a tree built as asked.
fn shortfall(stats: &TreeStats, target: Option<f64>) -> Option<String> {
    let short = target.filter(|&t| stats.expected_trials > target_limit(t));
    if !stats.budget_exhausted && short.is_none() {
        return None;
    }
    let cause = if stats.budget_exhausted {
        String::from("a budget (nodes or f_r evaluations)")
    } else {
        format!(
            "the depth limit (no leaf left that could split; the deepest at depth {})",
            stats.max_depth
        )
    };
    Some(format!(
        "brdf: warning: {cause} stopped the build at {} nodes{}",
        stats.nodes,
        match short {
            Some(t) => format!(
                ", short of --target-trials {t}: E[T] = {:.4}",
                stats.expected_trials
            ),
            None => String::new(),
        }
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A build short of its target says why: the budget, or the depth limit when no budget
    /// ran out; one within the tolerance of its target, or stopped by nothing, is quiet.
    #[test]
    fn a_shortfall_names_its_cause() {
        let stats = |e, budget| TreeStats {
            nodes: 441,
            max_depth: 20,
            expected_trials: e,
            budget_exhausted: budget,
            ..TreeStats::default()
        };
        let depth = shortfall(&stats(1.0515, false), Some(1.03)).expect("short");
        assert!(depth.contains("the depth limit"), "{depth}");
        assert!(depth.contains("deepest at depth 20"), "{depth}");
        assert!(
            depth.contains("short of --target-trials 1.03: E[T] = 1.0515"),
            "{depth}"
        );
        let budget = shortfall(&stats(1.0515, true), Some(1.03)).expect("short");
        assert!(
            budget.contains(
                "a budget (nodes or f_r evaluations) stopped the build at 441 nodes, short of"
            ),
            "{budget}"
        );
        let budget = shortfall(&stats(1.2, true), None).expect("stopped");
        assert!(budget.ends_with("at 441 nodes"), "{budget}");
        assert_eq!(shortfall(&stats(1.020_000_08, false), Some(1.02)), None);
        assert_eq!(shortfall(&stats(1.1, false), Some(1.25)), None);
        assert_eq!(shortfall(&stats(1.9, false), None), None);
    }
}
