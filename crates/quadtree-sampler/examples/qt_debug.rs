//! Prints tree statistics and sampling behaviour for a few models (development aid).
use brdf_core::{DiskMap, registry};
use glam::Vec3;
use quadtree_sampler::{BuildConfig, QuadtreeSampler};
use rand_core::SeedableRng;
use rand_pcg::Pcg64;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map_or("lambert", String::as_str);
    let params: Vec<&str> = args.iter().skip(2).map(String::as_str).collect();
    let theta: f32 = args.get(1).map_or(45.0, |s| s.parse().unwrap());
    let b = registry::create(name, params.iter().copied()).unwrap();
    let wi = Vec3::new(theta.to_radians().sin(), 0.0, theta.to_radians().cos());
    let q = brdf_core::geometry::luminance(
        brdf_core::quadrature::directional_albedo(&*b, wi, 200, 8).as_vec3(),
    );
    println!("quadrature albedo {q:.5}");
    for map in [DiskMap::Orthographic, DiskMap::Concentric] {
        for target in [None, Some(1.25)] {
            let t0 = Instant::now();
            let s = QuadtreeSampler::new(
                &*b,
                wi,
                BuildConfig {
                    map,
                    target_trials: target,
                    ..BuildConfig::default()
                },
            )
            .unwrap();
            let build = t0.elapsed().as_secs_f64();
            let st = s.stats();
            let mut rng = Pcg64::seed_from_u64(1);
            let t0 = Instant::now();
            let (mut none, mut trials) = (0, 0u64);
            let n = 200_000;
            for _ in 0..n {
                match s.sample(&mut rng) {
                    Some(x) => trials += u64::from(x.trials),
                    None => none += 1,
                }
            }
            let samp = t0.elapsed().as_secs_f64();
            println!(
                "{map:?} target {target:?}: nodes {} leaves {} depth {} E[T] {:.3} albedo {:.5} build {:.3}s | {:.2} Msamples/s, mean trials {:.3}, none {none}, violations {}, gave up {}",
                st.nodes,
                st.leaves,
                st.max_depth,
                st.expected_trials,
                s.albedo(),
                build,
                n as f64 / samp / 1e6,
                trials as f64 / n as f64,
                s.bound_violations(),
                s.gave_up()
            );
        }
    }
}
