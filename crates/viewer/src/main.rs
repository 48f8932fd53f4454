//! The `viewer` binary: opens the live BRDF sampling laboratory, or with `--screenshot`
//! renders one frame of the full window and exits.

use clap::Parser;
use eframe::egui;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;
use viewer::{Launch, ViewerApp};

/// The live BRDF sampling laboratory: disk subdivision, leaf probabilities, sample
/// histograms and the lobe, following the incident direction as it moves.
#[derive(Parser, Debug)]
#[command(name = "viewer", version)]
struct Args {
    /// Render one frame of the full window to this PNG once all work is done, and exit
    /// (offscreen with wgpu unless --window).
    #[arg(long, value_name = "FILE")]
    screenshot: Option<PathBuf>,
    /// With --screenshot: capture a real window (needs a display, e.g. Xvfb).
    #[arg(long, requires = "screenshot")]
    window: bool,
    /// With --screenshot: also write each view's PNG and the raw maps (EXR) into DIR.
    #[arg(long, value_name = "DIR", requires = "screenshot")]
    export: Option<PathBuf>,
    /// Model to start with (a registry name, as `brdf models` lists).
    #[arg(long, default_value = "ward")]
    model: String,
    /// A parameter as name=value (repeatable), as for `brdf`.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    params: Vec<String>,
    /// Incident direction x,y,z (local frame; normalised; must be above the horizon).
    #[arg(long, value_name = "X,Y,Z")]
    wi: Option<String>,
    /// Samples to draw.
    #[arg(long, default_value_t = 100_000)]
    samples: u64,
    /// Window size in points, WIDTHxHEIGHT.
    #[arg(long, default_value = "1400x900")]
    size: String,
    /// With --screenshot: give up after this many seconds.
    #[arg(long, default_value_t = 300)]
    timeout: u64,
}

fn parse_wi(text: &str) -> Result<glam::Vec3, String> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let values: Result<Vec<f32>, _> = parts.iter().map(|p| p.parse::<f32>()).collect();
    match values {
        Ok(v) if v.len() == 3 => Ok(glam::Vec3::new(v[0], v[1], v[2])),
        _ => Err(format!("--wi {text}: expected three numbers x,y,z")),
    }
}

fn parse_size(text: &str) -> Result<egui::Vec2, String> {
    let bad = || format!("--size {text}: expected WIDTHxHEIGHT, each in 200..=8192");
    let (w, h) = text.split_once('x').ok_or_else(bad)?;
    let (w, h): (f32, f32) = (
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    );
    if (200.0..=8192.0).contains(&w) && (200.0..=8192.0).contains(&h) {
        Ok(egui::vec2(w, h))
    } else {
        Err(bad())
    }
}

fn run(args: Args) -> Result<(), String> {
    let launch = Launch {
        model: args.model,
        params: args.params,
        wi: args.wi.as_deref().map(parse_wi).transpose()?,
        samples: args.samples,
    }
    .resolve()?;
    let size = parse_size(&args.size)?;
    let timeout = Duration::from_secs(args.timeout);
    match args.screenshot {
        Some(path) => {
            let shot = if args.window {
                viewer::screenshot::windowed(launch, size, timeout, args.export.as_deref())?
            } else {
                viewer::screenshot::offscreen(launch, size, timeout, args.export.as_deref())?
            };
            viewer::export::save_image(&path, &shot.image)?;
            println!(
                "wrote {} ({}x{})",
                path.display(),
                shot.image.width(),
                shot.image.height()
            );
            print!("{}", shot.summary);
            for f in shot.exported {
                println!("wrote {}", f.display());
            }
            Ok(())
        }
        None => {
            let options = viewer::screenshot::native_options(size, "brdf-sampling viewer");
            eframe::run_native(
                "brdf-sampling viewer",
                options,
                Box::new(move |cc| Ok(Box::new(ViewerApp::new(cc, launch)))),
            )
            .map_err(|e| format!("opening the window failed: {e}"))
        }
    }
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("viewer: {e}");
            ExitCode::from(2)
        }
    }
}
