//! One validation check, timed: build the quadtree for a model and incident direction, draw
//! 10⁶ samples, and judge them on both grids (SPEC §5). Prints the χ², p-values, the seed's
//! a_i spread and how long each stage took. `cargo run --release -p quadtree-sampler --example
//! validate_one [-- MODEL [k=v ...]]` (default: phong n=500, wi at θ = 45°; set THETA and PHI
//! in degrees to move it).

use brdf_core::registry;
use brdf_validate::{CellGrid, Validation, sidak};
use glam::Vec3;
use quadtree_sampler::{BuildConfig, QuadtreeSampler};
use rand_core::SeedableRng;
use rand_pcg::Pcg64;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (name, params): (&str, Vec<&str>) = match args.split_first() {
        Some((n, rest)) => (n.as_str(), rest.iter().map(String::as_str).collect()),
        None => ("phong", vec!["n=500"]),
    };
    let brdf = registry::create(name, params.iter().copied()).unwrap_or_else(|e| {
        eprintln!("error: {e}");
        std::process::exit(2)
    });
    // THETA / PHI (degrees) move wi; default 45°, 0°.
    let angle = |var: &str, default: f32| {
        std::env::var(var)
            .ok()
            .and_then(|v| v.parse::<f32>().ok())
            .unwrap_or(default)
            .to_radians()
    };
    let (t, p) = (angle("THETA", 45.0), angle("PHI", 0.0));
    let wi = Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
    for grid in [
        CellGrid::Square { res: 25 },
        CellGrid::Polar {
            rings: 25,
            sectors: 51,
        },
    ] {
        let t0 = Instant::now();
        let v = Validation::new(&*brdf, wi, grid, 1e-7).expect("validation set-up");
        let t1 = Instant::now();
        let q = QuadtreeSampler::new(&*brdf, wi, BuildConfig::default()).expect("build");
        let t2 = Instant::now();
        let r = v.test(&q, 1_000_000, &mut Pcg64::seed_from_u64(1), sidak(0.01, 2));
        let t3 = Instant::now();
        let c = r.chi2.as_ref().expect("degrees of freedom");
        let o = r.chi2_own.as_ref().expect("degrees of freedom");
        println!(
            "{name} {params:?} {grid:?}: chi2 {:.1}/{} p {:.3}; own-pdf p {:.3}; spread {:?}; {}",
            c.statistic,
            c.dof,
            c.p_value,
            o.p_value,
            r.spread,
            if r.passed() { "PASS" } else { "REJECT" }
        );
        println!(
            "  expected masses {:.3} s, build {:.3} s, sample + own-pdf masses + judge {:.3} s",
            (t1 - t0).as_secs_f64(),
            (t2 - t1).as_secs_f64(),
            (t3 - t2).as_secs_f64()
        );
        for reason in &r.reasons {
            println!("  reason: {reason}");
        }
    }
}
