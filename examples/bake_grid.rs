//! How fine a baked sampler's grid must be (issue: "the grid is chosen by measurement"):
//! for the glossy sets, the variance of the sky-and-sun reflected-radiance estimate at
//! off-grid incident directions, baked over exact, against the grid's steps, with the bytes
//! each grid holds. "Exact" is, per mode, the same sampler at a wi on its own grid (a fine
//! bake: 180 θ rows, and 10 φ columns for the anisotropic set), where the mixture is one tree
//! with no rotation; for rejection mode the per-wi `QuadtreeSampler`'s ratio is shown too.
//!
//! ```sh
//! cargo run --release --example bake_grid            # the curve for the glossy sets
//! cargo run --release --example bake_grid -- ward    # only the sets whose label contains "ward"
//! ```

use brdf_sampling::bench::{Environment, SETS, estimate, model};
use brdf_sampling::geometry::spherical_direction;
use brdf_sampling::quadtree_sampler::{
    BakeConfig, BakedMode, BakedSampler, BuildConfig, GRID_THETA_MAX_DEG, QuadtreeSampler,
};
use rand_core::{Rng, SeedableRng};
use std::sync::Arc;

const GLOSSY: &[&str] = &[
    "phong-sharp",
    "ward-sharp",
    "cook-torrance-sharp",
    "ward-aniso",
];
const SAMPLES: u64 = 200_000;
const FINE_THETA: u16 = 180;
const FINE_PHI: u16 = 10;

fn main() {
    let filter = std::env::args().nth(1).unwrap_or_default();
    let env = [Environment::default()];
    let mut sets: Vec<(&str, &str, &[&str])> = SETS.to_vec();
    sets.push((
        "ward-aniso",
        "ward",
        &["alpha_x=0.05", "alpha_y=0.2", "kd=0"],
    ));
    println!(
        "| set | θ steps | φ steps | trees | bytes | rejection: baked/exact mean · max | (per-wi tree) | warp: baked/exact mean · max |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for (label, name, params) in sets {
        if !GLOSSY.contains(&label) || !label.contains(&filter) {
            continue;
        }
        let b: Arc<dyn brdf_sampling::Brdf> = model(name, params).unwrap().into();
        let iso = b.symmetry().isotropic;
        // Incident directions on the fine grid (179 θ intervals: prime, so on no coarse grid
        // but the ends), θ in [2°, 85°], φ on multiples of 10° (anisotropic) or anywhere.
        let mut rng = rand_pcg::Pcg64::seed_from_u64(2026);
        let wis: Vec<_> = (0..6)
            .map(|_| {
                let dt = GRID_THETA_MAX_DEG / f64::from(FINE_THETA - 1);
                let k = 1 + rng.next_u32() % 170;
                let t = (dt * f64::from(k)).max(2.0);
                let p = if iso {
                    f64::from(rng.next_u32() % 360)
                } else {
                    10.0 * f64::from(1 + rng.next_u32() % 8)
                };
                spherical_direction((t as f32).to_radians(), (p as f32).to_radians())
            })
            .collect();
        let fine = BakedSampler::new(
            b.clone(),
            BakeConfig {
                theta_steps: FINE_THETA,
                phi_steps: FINE_PHI,
                ..BakeConfig::default()
            },
        )
        .unwrap();
        let variances = |baked: &BakedSampler| -> Vec<f64> {
            wis.iter()
                .map(|&wi| estimate(&baked.at(wi).unwrap(), &env, SAMPLES, 7)[0].variance)
                .collect()
        };
        let ratio = |a: &[f64], b: &[f64]| {
            let r: Vec<f64> = a.iter().zip(b).map(|(x, y)| x / y).collect();
            let mean = r.iter().sum::<f64>() / r.len() as f64;
            (mean, r.iter().cloned().fold(0.0, f64::max))
        };
        let per_wi: Vec<f64> = wis
            .iter()
            .map(|&wi| {
                let q = QuadtreeSampler::new(&*b, wi, BuildConfig::default()).unwrap();
                estimate(&q, &env, SAMPLES, 7)[0].variance
            })
            .collect();
        let exact_rej = variances(&fine);
        let fine = fine.with_mode(BakedMode::Warp);
        let exact_warp = variances(&fine);
        for (nt, np) in [(8, 3), (16, 5), (24, 7), (32, 9), (48, 13), (64, 17)] {
            let cfg = BakeConfig {
                theta_steps: nt,
                phi_steps: np,
                ..BakeConfig::default()
            };
            let baked = BakedSampler::new(b.clone(), cfg).unwrap();
            let rej = variances(&baked);
            let baked = baked.with_mode(BakedMode::Warp);
            let warp = variances(&baked);
            let (a, b1) = ratio(&rej, &exact_rej);
            let (c, d) = ratio(&rej, &per_wi);
            let (e, f) = ratio(&warp, &exact_warp);
            println!(
                "| {label} | {nt} | {} | {} | {} | {a:.3} · {b1:.3} | {c:.3} · {d:.3} | {e:.3} · {f:.3} |",
                if iso { 1 } else { np },
                baked.trees(),
                baked.bytes(),
            );
        }
    }
}
