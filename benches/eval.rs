//! f_r evaluation per model set, the cost every rejection trial, node integral and pdf
//! pays: `Brdf::eval` over a batch of 1024 direction pairs (wi and wo both cosine-distributed,
//! drawn from a seeded RNG before the clock starts), ns per evaluation with
//! `Throughput::Elements`. Issue #16's goal for HTSG and Poulin–Fournier (5× faster) is read
//! from this bench run on two commits: `cargo bench --bench eval -- 'eval/(htsg|poulin)'`.
//! The measured set is left out (its file is tabulated per process; `brdf bench` times it).

#[macro_use]
mod common;

use brdf_sampling::glam::{Vec2, Vec3};
use brdf_sampling::quadtree_sampler::uniform_f32;
use brdf_sampling::warp::sample_cosine_hemisphere;
use criterion::{BenchmarkId, Criterion, Throughput};
use rand_core::SeedableRng;
use std::hint::black_box;

const BATCH: usize = 1024;

fn bench(c: &mut Criterion) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(16);
    let mut unit = || uniform_f32(&mut rng);
    let pairs: Vec<(Vec3, Vec3)> = (0..BATCH)
        .map(|_| {
            let wi = sample_cosine_hemisphere(Vec2::new(unit(), unit()));
            let wo = sample_cosine_hemisphere(Vec2::new(unit(), unit()));
            (wi, wo)
        })
        .collect();
    let mut group = c.benchmark_group("eval");
    group.throughput(Throughput::Elements(BATCH as u64));
    for &(label, name, params) in common::SETS {
        if brdf_sampling::registry::find(name).is_ok_and(|m| m.measured) {
            continue;
        }
        let brdf = common::model(name, params);
        group.bench_function(BenchmarkId::from_parameter(label), |bench| {
            bench.iter(|| {
                pairs
                    .iter()
                    .map(|&(wi, wo)| brdf.eval(black_box(wi), black_box(wo)))
                    .sum::<Vec3>()
            });
        });
    }
    group.finish();
}

bench_main!(bench);
