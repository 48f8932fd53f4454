//! `brdf sample` and `brdf pdf`: the quadtree (rejection) and the baselines.

use crate::CliError;
use brdf_sampling::geometry::{unit_direction, unit_direction_above};
use brdf_sampling::glam::Vec3;
use brdf_sampling::quadtree_sampler::{
    BakedMode, BakedSampler, Baseline, BaselineSampler, BuildConfig, DEFAULT_MIX,
    DEFAULT_TABLE_RES, DirectionSampler, QuadtreeSampler, TableSampler, TreeStats, WarpSampler,
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
    /// Refine the quadtree until the expected trials per sample are at most this (rejection).
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

/// A loaded bake at one incident direction.
struct BakedAtWi(Arc<BakedSampler>, Vec3);

impl DirectionSampler for BakedAtWi {
    fn name(&self) -> &'static str {
        match self.0.mode() {
            BakedMode::Rejection => "baked rejection",
            BakedMode::Warp => "baked warp",
        }
    }
    fn sample(
        &self,
        rng: &mut dyn rand_core::Rng,
    ) -> Option<brdf_sampling::quadtree_sampler::Sample> {
        self.0.at(self.1).ok()?.sample(rng)
    }
    fn pdf(&self, wo: Vec3) -> f32 {
        self.0.at(self.1).map_or(0.0, |a| a.pdf(wo))
    }
}

/// Parses `x,y,z` into a direction (not yet normalised).
pub(crate) fn parse_vec3(text: &str, what: &str) -> Result<Vec3, CliError> {
    brdf_sampling::text::parse_vec3(text).map_err(|e| CliError::Usage(format!("{what} {e}")))
}

/// Reads the rejection sampler's bound-violation count after sampling.
pub(crate) type ViolationCounter<'a> = Box<dyn Fn() -> u64 + 'a>;

/// A built sampler and, for the quadtree, its statistics.
pub(crate) struct Built<'a> {
    /// The sampler.
    pub(crate) sampler: Box<dyn DirectionSampler + 'a>,
    /// Tree statistics, albedo, and (rejection only) the bound-violation counter.
    pub(crate) tree: Option<(TreeStats, f64, Option<ViolationCounter<'a>>)>,
    /// Seconds spent building (0 for the baselines).
    pub(crate) build_seconds: f64,
    /// The bake, for `--baked`.
    pub(crate) baked: Option<Arc<BakedSampler>>,
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
        let b = baked.clone();
        return Ok(Built {
            sampler: Box::new(BakedAtWi(baked.clone(), wi)),
            tree: None,
            build_seconds: 0.0,
            baked: Some(b),
        });
    }
    let baseline = |kind| -> Result<Built<'a>, CliError> {
        Ok(Built {
            sampler: Box::new(BaselineSampler::new(brdf, wi, kind)?),
            tree: None,
            build_seconds: 0.0,
            baked: None,
        })
    };
    match args.mode {
        Mode::Uniform => baseline(Baseline::Uniform),
        Mode::Cosine => baseline(Baseline::Cosine),
        Mode::Analytic => baseline(Baseline::Analytic),
        Mode::Table => {
            let t = TableSampler::new(brdf, wi, DEFAULT_TABLE_RES)?;
            Ok(Built {
                sampler: Box::new(t),
                tree: None,
                build_seconds: t0.elapsed().as_secs_f64(),
                baked: None,
            })
        }
        Mode::Warp => {
            let config = BuildConfig {
                target_trials: args.target_trials,
                ..BuildConfig::default()
            };
            let w = WarpSampler::new(brdf, wi, config, DEFAULT_MIX)?;
            let build_seconds = t0.elapsed().as_secs_f64();
            let (stats, albedo) = (w.stats(), w.albedo());
            Ok(Built {
                sampler: Box::new(w),
                tree: Some((stats, albedo, None)),
                build_seconds,
                baked: None,
            })
        }
        Mode::Rejection => {
            let map = match args.map {
                MapArg::Orthographic => DiskMap::Orthographic,
                MapArg::Concentric => DiskMap::Concentric,
            };
            let config = BuildConfig {
                map,
                target_trials: args.target_trials,
                ..BuildConfig::default()
            };
            let q = std::sync::Arc::new(QuadtreeSampler::new(brdf, wi, config)?);
            let build_seconds = t0.elapsed().as_secs_f64();
            let (stats, albedo) = (q.stats(), q.albedo());
            let q2 = q.clone();
            Ok(Built {
                sampler: Box::new(ArcSampler(q)),
                tree: Some((stats, albedo, Some(Box::new(move || q2.bound_violations())))),
                build_seconds,
                baked: None,
            })
        }
    }
}

/// Shares one quadtree sampler between the sampling loop and the statistics.
struct ArcSampler<'a>(std::sync::Arc<QuadtreeSampler<'a, dyn Brdf + 'a>>);

impl DirectionSampler for ArcSampler<'_> {
    fn name(&self) -> &'static str {
        "rejection"
    }
    fn sample(
        &self,
        rng: &mut dyn rand_core::Rng,
    ) -> Option<brdf_sampling::quadtree_sampler::Sample> {
        self.0.sample(rng)
    }
    fn pdf(&self, wo: Vec3) -> f32 {
        self.0.pdf(wo)
    }
}

pub(crate) fn run_sample(
    brdf: &dyn Brdf,
    args: &SamplerArgs,
    count: u64,
    seed: u64,
    out: &std::path::Path,
    mut stdout: impl Write,
) -> Result<(), CliError> {
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
    match &built.tree {
        Some((stats, albedo, violations)) => {
            obj.insert("albedo".into(), json!(albedo));
            obj.insert("albedo_method".into(), json!("quadtree volume"));
            obj.insert("nodes".into(), json!(stats.nodes));
            obj.insert("leaves".into(), json!(stats.leaves));
            obj.insert("max_depth".into(), json!(stats.max_depth));
            obj.insert("bytes".into(), json!(stats.bytes));
            match violations {
                Some(v) => {
                    obj.insert("expected_trials".into(), json!(stats.expected_trials));
                    obj.insert("bound_violations".into(), json!(v()));
                }
                None => {
                    obj.insert("expected_trials".into(), Value::Null);
                    obj.insert("bound_violations".into(), Value::Null);
                }
            }
        }
        None if built.baked.is_some() => {
            let b = built.baked.as_ref().expect("a bake");
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
    loop {
        line.clear();
        if input.read_line(&mut line)? == 0 {
            break;
        }
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
        let wo = unit_direction(Vec3::from_array(v)).map_err(|e| bad(format!("wo: {e}")))?;
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
