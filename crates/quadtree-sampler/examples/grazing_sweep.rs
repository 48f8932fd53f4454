//! The grazing sweep of the robustness contract: for every non-delta model (defaults and a
//! sharp set), both maps and incident directions with z = 10⁻ᵏ, builds the quadtree and prints
//! a markdown row per build: seconds, nodes, E[T], albedo (tree volume) and the outcome (a
//! sampler, or the typed error). Below the grazing floor (z < 10⁻⁴) every model evaluates at
//! the floor, so rows for k ≥ 5 repeat k = 4's tree.
//!
//! `cargo run --release -p quadtree-sampler --features rayon --example grazing_sweep
//! [-- K1,K2,...]` (default k = 1…45).

use brdf_core::{DiskMap, registry};
use glam::Vec3;
use quadtree_sampler::{BuildConfig, QuadtreeSampler};
use std::time::Instant;

const SETS: &[(&str, &[&str])] = &[
    ("lambert", &[]),
    ("phong", &["n=1000"]),
    ("blinn-phong", &["n=1000"]),
    ("lewis-phong", &[]),
    ("cook-torrance", &[]),
    ("cook-torrance", &["m=0.05"]),
    ("oren-nayar", &[]),
    ("ward", &["alpha_x=0.05", "alpha_y=0.2"]),
    ("schlick", &[]),
    ("htsg", &[]),
    ("poulin-fournier", &[]),
    ("strauss", &[]),
];

fn main() {
    let ks: Vec<i32> = std::env::args()
        .nth(1)
        .map(|a| a.split(',').map(|k| k.parse().expect("k")).collect())
        .unwrap_or_else(|| (1..=45).collect());
    println!("| model | map | k | s | nodes | E[T] | albedo | outcome |");
    println!("|---|---|---:|---:|---:|---:|---:|---|");
    for &(name, params) in SETS {
        let b = registry::create(name, params.iter().copied()).expect("model");
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            for &k in &ks {
                let z = 10f64.powi(-k) as f32;
                let z = if z > 0.0 { z } else { f32::from_bits(1) };
                let wi = Vec3::new(0.8, 0.6, z);
                let cfg = BuildConfig {
                    map,
                    ..BuildConfig::default()
                };
                let t0 = Instant::now();
                let built = QuadtreeSampler::new(&*b, wi, cfg);
                let s = t0.elapsed().as_secs_f64();
                let label = format!("{name} {}", params.join(" "));
                match built {
                    Ok(q) => {
                        let st = q.stats();
                        println!(
                            "| {label} | {map:?} | {k} | {s:.3} | {} | {:.3} | {:.6} | ok |",
                            st.nodes,
                            st.expected_trials,
                            q.albedo()
                        );
                    }
                    Err(e) => println!("| {label} | {map:?} | {k} | {s:.3} | – | – | – | {e} |"),
                }
            }
        }
    }
}
