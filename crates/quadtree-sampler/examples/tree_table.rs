//! Prints a markdown table of quadtree statistics for every non-delta model, default and sharp
//! parameters, at several incident angles: nodes, depth, E[T], build time, samples/s,
//! measured mean trials and bound violations. `cargo run --release -p quadtree-sampler
//! --example tree_table [-- concentric]`.

use brdf_core::{DiskMap, registry};
use glam::Vec3;
use quadtree_sampler::{BuildConfig, QuadtreeSampler};
use rand_core::SeedableRng;
use rand_pcg::Pcg64;
use std::time::Instant;

const SETS: &[(&str, &[&str])] = &[
    ("lambert", &[]),
    ("phong", &[]),
    ("phong", &["n=1000"]),
    ("blinn-phong", &[]),
    ("blinn-phong", &["n=1000"]),
    ("lewis-phong", &[]),
    ("cook-torrance", &[]),
    ("cook-torrance", &["m=0.1"]),
    ("oren-nayar", &[]),
    ("ward", &[]),
    ("ward", &["alpha_x=0.05", "alpha_y=0.2"]),
    ("schlick", &[]),
    ("schlick", &["r=0.02", "p=0.3"]),
    ("htsg", &[]),
    ("htsg", &["sigma0=0.0318", "tau=0.3"]),
    ("poulin-fournier", &[]),
    ("poulin-fournier", &["height=0.5", "gap=1", "n=1000"]),
    ("strauss", &[]),
    ("strauss", &["smoothness=0.9", "metalness=1"]),
];

fn main() {
    let map = if std::env::args().any(|a| a == "concentric") {
        DiskMap::Concentric
    } else {
        DiskMap::Orthographic
    };
    println!("map: {map:?}; samples/s over 10^6 samples, one thread\n");
    println!(
        "| model | params | θi | nodes | depth | E[T] | build ms | Msamples/s | mean trials | violations |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for &(name, params) in SETS {
        let b = registry::create(name, params.iter().copied()).unwrap();
        for theta in [0.0f32, 45.0, 80.0, 89.0] {
            let (t, p) = (theta.to_radians(), 30f32.to_radians());
            let wi = Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
            let t0 = Instant::now();
            let s = QuadtreeSampler::new(
                &*b,
                wi,
                BuildConfig {
                    map,
                    ..BuildConfig::default()
                },
            )
            .unwrap();
            let build = t0.elapsed().as_secs_f64();
            let st = s.stats();
            let mut rng = Pcg64::seed_from_u64(1);
            let n = 1_000_000u64;
            let mut trials = 0u64;
            let t0 = Instant::now();
            for _ in 0..n {
                trials += s.sample(&mut rng).map_or(0, |x| u64::from(x.trials));
            }
            let secs = t0.elapsed().as_secs_f64();
            println!(
                "| {name} | {} | {theta} | {} | {} | {:.3} | {:.1} | {:.2} | {:.3} | {} |",
                params.join(" "),
                st.nodes,
                st.max_depth,
                st.expected_trials,
                build * 1e3,
                n as f64 / secs / 1e6,
                trials as f64 / n as f64,
                s.bound_violations()
            );
        }
    }
}
