//! `brdf`: the command line of SPEC §6, a stable contract that other tools script against.
//! Errors go to stderr with exit status 2; a statistical test that rejects exits 1, and one
//! that could not be judged (too few samples or cells) exits 3.

mod bake;
mod bench;
mod eval;
mod images;
mod models;
mod progress;
mod sample;
mod tabulate;
mod test;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// BRDF models and their importance samplers (Montes 2003 quadtree), from the command line.
///
/// Directions are `x,y,z` in the local frame (z = normal, x = tangent), normalised by the
/// program. Parameters are `--param name=value` with the names of `brdf models`.
#[derive(Debug, Parser)]
#[command(name = "brdf", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// List every model with its parameters, defaults and ranges.
    Models {
        /// Print JSON (an array of models) instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Evaluate f_r: reads lines `wix wiy wiz wox woy woz` from stdin, prints `r g b` per line
    /// (1/sr, no cosine). Blank lines are skipped.
    Eval {
        #[command(flatten)]
        model: ModelArgs,
    },
    /// Draw N outgoing directions for one incident direction; write N records of four
    /// little-endian f32 `wo.x wo.y wo.z pdf` (pdf per unit solid angle; a sample lost below
    /// the horizon is written as four zeros) to --out, and a JSON summary to stdout.
    Sample {
        #[command(flatten)]
        model: OptModelArgs,
        #[command(flatten)]
        sampler: sample::SamplerArgs,
        /// Number of samples.
        #[arg(long)]
        count: u64,
        /// RNG seed (PCG64).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Output file for the binary records.
        #[arg(long)]
        out: std::path::PathBuf,
    },
    /// The sampler's pdf per unit solid angle: reads `wox woy woz` lines from stdin, prints
    /// one pdf per line.
    Pdf {
        #[command(flatten)]
        model: OptModelArgs,
        #[command(flatten)]
        sampler: sample::SamplerArgs,
    },
    /// The performance report: sampling cost and efficiency (1/(variance × time)) of the
    /// quadtree against cosine, analytic and table sampling under a sky-and-sun environment,
    /// build time and rayon speedup, expected trials per sample and bytes per node, as ratios from one run.
    Bench {
        #[command(flatten)]
        bench: bench::BenchArgs,
    },
    /// Bakes a model's sampler for every incident direction into a file (SPEC §7) and prints
    /// one JSON object: trees, nodes, bytes, build_seconds, grid.
    Bake {
        #[command(flatten)]
        model: ModelArgs,
        #[command(flatten)]
        bake: bake::BakeArgs,
    },
    /// Writes any model's f_r in the MERL database's binary format (SPEC §8) at each bin's
    /// centre, so that `--model merl --param file=FILE` reproduces the model there; prints one
    /// JSON object (model, params, file, bytes, bins, zero_bins, seconds).
    Tabulate {
        #[command(flatten)]
        model: ModelArgs,
        /// The file to write (complete or not at all).
        #[arg(long)]
        out: std::path::PathBuf,
    },
    /// The validation of SPEC §5 for any sampler: histogram --samples directions over a cell
    /// grid and compare with ∫f·cos per cell (the seed's a_i spread, Pearson χ²) and with the
    /// sampler's own pdf. Prints a table. Exit status: 0 when every test passed, 1 when any
    /// rejected, 3 when none rejected but one could not be judged (inconclusive: too few
    /// samples or cells for its χ²), 2 for an error.
    Test {
        #[command(flatten)]
        model: OptModelArgs,
        #[command(flatten)]
        test: test::TestArgs,
    },
}

/// The model and its parameters, shared by every subcommand that needs a BRDF.
#[derive(Debug, clap::Args)]
struct ModelArgs {
    /// Model name (see `brdf models`).
    #[arg(long)]
    model: String,
    /// A parameter as name=value (RGB: one value or r,g,b); repeat for several.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    params: Vec<String>,
}

/// `--model` and `--param` where `--baked FILE` may stand instead (the bake names its model).
#[derive(Debug, clap::Args)]
struct OptModelArgs {
    /// The model (MODELS.md name); not needed with --baked.
    #[arg(long, required_unless_present = "baked")]
    model: Option<String>,
    /// A parameter NAME=VALUE (repeat for several).
    #[arg(long = "param", value_name = "NAME=VALUE")]
    params: Vec<String>,
}

impl OptModelArgs {
    /// The model: the bake's when `--baked` is given (checked against --model if both are),
    /// else the one `--model` names.
    fn resolve(
        &self,
        options: &mut sample::SamplerOptions,
    ) -> Result<std::sync::Arc<dyn brdf_sampling::Brdf>, CliError> {
        if let Some(b) = sample::load_baked(options, self.model.as_deref(), &self.params)? {
            return Ok(b);
        }
        let name = self.model.as_deref().unwrap_or_default();
        Ok(brdf_sampling::registry::create(name, self.params.iter().map(String::as_str))?.into())
    }
}

impl ModelArgs {
    fn build(&self) -> Result<Box<dyn brdf_sampling::Brdf>, brdf_sampling::ParamError> {
        brdf_sampling::registry::create(&self.model, self.params.iter().map(String::as_str))
    }
}

/// Any failure of a subcommand: printed to stderr, exit status 2.
#[derive(Debug)]
enum CliError {
    Param(brdf_sampling::ParamError),
    Build(brdf_sampling::quadtree_sampler::BuildError),
    Validate(brdf_sampling::validate::ValidateError),
    Usage(String),
    Io(std::io::Error),
    Input { line: u64, message: String },
}

impl std::fmt::Display for CliError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Param(e) => write!(f, "{e}"),
            Self::Build(e) => write!(f, "{e}"),
            Self::Validate(e) => write!(f, "{e}"),
            Self::Usage(e) => write!(f, "{e}"),
            Self::Io(e) => write!(f, "i/o error: {e}"),
            Self::Input { line, message } => write!(f, "stdin line {line}: {message}"),
        }
    }
}

impl From<brdf_sampling::ParamError> for CliError {
    fn from(e: brdf_sampling::ParamError) -> Self {
        Self::Param(e)
    }
}

impl From<brdf_sampling::quadtree_sampler::BuildError> for CliError {
    fn from(e: brdf_sampling::quadtree_sampler::BuildError) -> Self {
        Self::Build(e)
    }
}

impl From<brdf_sampling::validate::ValidateError> for CliError {
    fn from(e: brdf_sampling::validate::ValidateError) -> Self {
        Self::Validate(e)
    }
}

impl From<std::io::Error> for CliError {
    fn from(e: std::io::Error) -> Self {
        Self::Io(e)
    }
}

/// What a subcommand found: every test passed, one rejected (exit status 1), or none
/// rejected but one could not be judged (exit status 3).
enum Outcome {
    Passed,
    Rejected,
    Inconclusive,
}

fn run(cli: Cli) -> Result<Outcome, CliError> {
    let stdout = std::io::stdout().lock();
    let done = match cli.command {
        Command::Models { json } => models::run(json, stdout),
        Command::Eval { model } => {
            let brdf = model.build()?;
            eval::run(&*brdf, std::io::stdin().lock(), stdout)
        }
        Command::Sample {
            model,
            mut sampler,
            count,
            seed,
            out,
        } => {
            let brdf = model.resolve(&mut sampler.options)?;
            sample::run_sample(&*brdf, &sampler, count, seed, &out, stdout)
        }
        Command::Pdf { model, mut sampler } => {
            let brdf = model.resolve(&mut sampler.options)?;
            sample::run_pdf(&*brdf, &sampler, std::io::stdin().lock(), stdout)
        }
        Command::Bake { model, bake } => {
            let brdf = model.build()?;
            bake::run(brdf.into(), &bake, stdout)
        }
        Command::Bench { bench } => bench::run(&bench, stdout),
        Command::Tabulate { model, out } => {
            let brdf = model.build()?;
            tabulate::run(&*brdf, &out, stdout)
        }
        Command::Test { model, mut test } => {
            let brdf = model.resolve(test.options_mut())?;
            use brdf_sampling::validate::Verdict;
            return Ok(match test::run(&*brdf, &model.params, &test, stdout)? {
                Verdict::Passed => Outcome::Passed,
                Verdict::Rejected => Outcome::Rejected,
                Verdict::Inconclusive => Outcome::Inconclusive,
            });
        }
    };
    done.map(|()| Outcome::Passed)
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(Outcome::Passed) => ExitCode::SUCCESS,
        Ok(Outcome::Rejected) => ExitCode::from(1),
        Ok(Outcome::Inconclusive) => ExitCode::from(3),
        // A closed pipe (`brdf eval | head`) is the reader's choice, not an error.
        Err(CliError::Io(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
