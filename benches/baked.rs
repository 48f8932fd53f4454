//! The baked sampler (SPEC §7) as a renderer calls it: a new incident direction for every
//! call (cosine-distributed, drawn before the clock starts), against the Beckmann analytic
//! sample that #18's goals are stated in (cook-torrance m = 0.1): at the bench's fixed wi
//! (`analytic`) and over the baked rows' own random wi (`analytic-random-wi`, the
//! like-for-like one).
//! Rows per set: `sample` in rejection and warp mode and `pdf(wi, wo)` in both modes, and a
//! path vertex's work (one sample and, at a light sample's direction, f_r and the pdf, at one
//! random given direction) by three calls to the sampler (`vertex-per-call`) and by one
//! `BakedSampler::point` answering all three (`vertex-point`), on batches of 1024. Ratios
//! come from one run: `cargo bench --bench baked`.

#[macro_use]
mod common;

use brdf_sampling::glam::{Vec2, Vec3};
use brdf_sampling::quadtree_sampler::{
    AnySampler, BakeConfig, BakedMode, BakedSampler, BuildConfig, DirectionSampler, Role,
    SamplerMode, uniform_f32,
};
use brdf_sampling::warp::sample_cosine_hemisphere;
use criterion::{BenchmarkId, Criterion, Throughput};
use rand_core::SeedableRng;
use std::hint::black_box;
use std::sync::Arc;

const BATCH: usize = 1024;

/// The sets the speed goals name (the cheap models), plus Lambert as the floor.
const BAKED_SETS: &[&str] = &[
    "lambert",
    "phong-sharp",
    "cook-torrance-sharp",
    "ward-sharp",
];

fn bench(c: &mut Criterion) {
    let beckmann = common::model("cook-torrance", &["m=0.1"]);
    let analytic = AnySampler::new(
        &*beckmann,
        common::wi(),
        SamplerMode::Analytic,
        BuildConfig::default(),
    )
    .unwrap();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let inputs: Vec<(Vec3, f32, Vec2)> = (0..BATCH)
        .map(|_| {
            let wi =
                sample_cosine_hemisphere(Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng)));
            let u = Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng));
            (wi, uniform_f32(&mut rng), u)
        })
        .collect();
    // A light sample's direction for each vertex (cosine-distributed, independent of wi).
    let lights: Vec<Vec3> = (0..BATCH)
        .map(|_| sample_cosine_hemisphere(Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng))))
        .collect();
    let mut group = c.benchmark_group("baked/beckmann");
    group.throughput(Throughput::Elements(BATCH as u64));
    group.bench_function("analytic", |b| {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        b.iter(|| {
            for _ in 0..BATCH {
                black_box(analytic.sample(&mut rng));
            }
        });
    });
    // The same sample with the baked rows' own random wi, in the same kind of loop: the
    // like-for-like yardstick (`brdf bench`'s baked table divides by this one).
    group.bench_function("analytic-random-wi", |b| {
        b.iter(|| {
            for &(wi, uc, u) in &inputs {
                black_box(beckmann.sample(wi, uc, u));
            }
        });
    });
    group.finish();
    for &(label, name, params) in common::SETS {
        if !BAKED_SETS.contains(&label) {
            continue;
        }
        let brdf: Arc<dyn brdf_sampling::Brdf> = common::model(name, params).into();
        let rejection = BakedSampler::new(brdf, BakeConfig::default()).unwrap();
        let warp = BakedSampler::from_bytes(&rejection.to_bytes())
            .unwrap()
            .with_mode(BakedMode::Warp);
        let mut group = c.benchmark_group(format!("baked/{label}"));
        group.throughput(Throughput::Elements(BATCH as u64));
        for (kind, baked) in [("rejection", &rejection), ("warp", &warp)] {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
            group.bench_function(BenchmarkId::new("sample", kind), |b| {
                b.iter(|| {
                    for &(wi, uc, u) in &inputs {
                        black_box(baked.sample(wi, uc, u, &mut rng).ok());
                    }
                });
            });
            let pairs: Vec<(Vec3, Vec3)> = inputs
                .iter()
                .filter_map(|&(wi, uc, u)| {
                    let s = baked.sample(wi, uc, u, &mut rng).ok()??;
                    Some((wi, s.wo))
                })
                .collect();
            group.bench_function(BenchmarkId::new("pdf", kind), |b| {
                b.iter(|| {
                    for &(wi, wo) in &pairs {
                        black_box(baked.pdf(wi, wo).ok());
                    }
                });
            });
            let role = Role::Radiance;
            group.bench_function(BenchmarkId::new("vertex-per-call", kind), |b| {
                b.iter(|| {
                    for (&(wi, uc, u), &light) in inputs.iter().zip(&lights) {
                        black_box(baked.sample_as(role, wi, uc, u, &mut rng).ok());
                        black_box(baked.eval_pdf_as(role, wi, light).ok());
                    }
                });
            });
            group.bench_function(BenchmarkId::new("vertex-point", kind), |b| {
                b.iter(|| {
                    for (&(wi, uc, u), &light) in inputs.iter().zip(&lights) {
                        let Ok(point) = baked.point(role, wi) else {
                            continue;
                        };
                        black_box(point.sample(uc, u, &mut rng));
                        black_box(point.eval_pdf(light).ok());
                    }
                });
            });
        }
        group.finish();
    }
}

bench_main!(bench);
