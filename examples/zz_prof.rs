//! temp
use brdf_sampling::glam::{Vec2, Vec3};
use brdf_sampling::quadtree_sampler::{BakeConfig, BakedMode, BakedSampler, uniform_f32};
use brdf_sampling::warp::sample_cosine_hemisphere;
use rand_core::SeedableRng;
use std::hint::black_box;
use std::sync::Arc;
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let name = &args[1];
    let mode = if args[2] == "warp" {
        BakedMode::Warp
    } else {
        BakedMode::Rejection
    };
    let what = &args[3];
    let params: Vec<&str> = args[4..].iter().map(|s| s.as_str()).collect();
    let brdf: Arc<dyn brdf_sampling::Brdf> =
        brdf_sampling::registry::create(name, params.iter().copied())
            .unwrap()
            .into();
    let s = BakedSampler::new(brdf, BakeConfig::default())
        .unwrap()
        .with_mode(mode);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let inputs: Vec<(Vec3, f32, Vec2)> = (0..1024)
        .map(|_| {
            let wi =
                sample_cosine_hemisphere(Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng)));
            let u = Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng));
            (wi, uniform_f32(&mut rng), u)
        })
        .collect();
    let wos: Vec<Vec3> = inputs
        .iter()
        .map(|&(wi, uc, u)| {
            s.sample(wi, uc, u, &mut rng)
                .ok()
                .flatten()
                .map(|x| x.wo)
                .unwrap_or(Vec3::Z)
        })
        .collect();
    let iters: usize = std::env::var("ITERS")
        .map(|v| v.parse().unwrap())
        .unwrap_or(3000);
    let t = Instant::now();
    for _ in 0..iters {
        match what.as_str() {
            "sample" => {
                for &(wi, uc, u) in &inputs {
                    black_box(s.sample(wi, uc, u, &mut rng).ok());
                }
            }
            "pdf" => {
                for (k, &(wi, _, _)) in inputs.iter().enumerate() {
                    black_box(s.pdf(wi, wos[k]).ok());
                }
            }
            _ => {
                for (k, &(wi, _, _)) in inputs.iter().enumerate() {
                    black_box(s.eval(wi, wos[k]).ok());
                }
            }
        }
    }
    println!(
        "{} ns",
        t.elapsed().as_nanos() as f64 / (iters * 1024) as f64
    );
}
