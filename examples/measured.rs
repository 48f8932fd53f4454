//! A measured BRDF end to end (SPEC §8), with its costs: tabulate an analytic model into the
//! MERL format (as `brdf tabulate` does), load it as the `merl` model, evaluate it, and build
//! the quadtree of one incident direction with both lookups.
//!
//! `cargo run --release --example measured [MODEL [PARAM=VALUE...]]` (default: Cook–Torrance
//! m = 0.1 through the benches' measured-looking noise). Prints one line per figure.

use brdf_sampling::glam::Vec3;
use brdf_sampling::models::merl::{self, MERL_BINS};
use brdf_sampling::quadtree_sampler::{BuildConfig, QuadtreeSampler};
use brdf_sampling::rng::{Pcg64, SeedableRng};
use brdf_sampling::{Brdf, registry};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (name, params) = match args.split_first() {
        Some((n, p)) => (n.as_str(), p.iter().map(String::as_str).collect::<Vec<_>>()),
        None => ("cook-torrance", vec!["m=0.1", "kd=0.1"]),
    };
    let model = registry::create(name, params.iter().copied()).expect("a valid model");
    let t0 = Instant::now();
    let values = if args.is_empty() {
        brdf_sampling::bench::measured_like(&*model, 0.03, 42)
    } else {
        merl::tabulate(&*model)
    };
    let bytes = merl::encode(&values);
    println!("tabulate (1 thread): {:.3} s", t0.elapsed().as_secs_f64());
    let path = std::env::temp_dir().join(format!("measured-example-{}.binary", std::process::id()));
    std::fs::write(&path, &bytes).expect("write the file");
    let file = format!("file={}", path.display());
    let t0 = Instant::now();
    let nearest = registry::create("merl", [file.as_str()]).expect("the file we wrote");
    println!(
        "load: {:.3} s ({} bytes on disk)",
        t0.elapsed().as_secs_f64(),
        bytes.len()
    );
    let t0 = Instant::now();
    let linear = registry::create("merl", [file.as_str(), "interp=linear"]).expect("shared");
    println!(
        "second open of the same file (shared data): {:.6} s; data in memory: {} bytes a material",
        t0.elapsed().as_secs_f64(),
        3 * MERL_BINS * 4
    );
    let mut rng = Pcg64::seed_from_u64(1);
    let pairs: Vec<(Vec3, Vec3)> = (0..1_000_000)
        .map(|_| {
            let u = |r: &mut Pcg64| brdf_sampling::quadtree_sampler::uniform_f32(r);
            let d = |r: &mut Pcg64| {
                brdf_sampling::warp::sample_cosine_hemisphere(brdf_sampling::glam::Vec2::new(
                    u(r),
                    u(r),
                ))
            };
            (d(&mut rng), d(&mut rng))
        })
        .collect();
    for (label, m) in [("nearest", &nearest), ("linear", &linear), (name, &model)] {
        let t0 = Instant::now();
        let mut acc = Vec3::ZERO;
        for &(wi, wo) in &pairs {
            acc += m.eval(wi, wo);
        }
        std::hint::black_box(acc);
        println!(
            "eval {label}: {:.1} ns",
            t0.elapsed().as_secs_f64() * 1e9 / pairs.len() as f64
        );
    }
    let wi = Vec3::new(0.5, 0.2, 0.84).normalize();
    for (label, m) in [("nearest", &nearest), ("linear", &linear), (name, &model)] {
        let t0 = Instant::now();
        match QuadtreeSampler::new(&**m, wi, BuildConfig::default()) {
            Ok(q) => println!(
                "tree {label}: {:.3} s, {} nodes, E[T] {:.2}",
                t0.elapsed().as_secs_f64(),
                q.stats().nodes,
                q.stats().expected_trials
            ),
            Err(e) => println!("tree {label}: {e}"),
        }
    }
    let _ = std::fs::remove_file(&path);
}
