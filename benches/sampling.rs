//! Samples per second from a cached sampler: the quadtree (seed rule, target-trials mode,
//! warp) against uniform, cosine, each model's analytic sampler and the 256² table, for
//! every model at default and sharp parameters. A batch of 1024 samples per iteration; the
//! RNG is seeded outside the timed closure.

#[macro_use]
mod common;

use brdf_sampling::quadtree_sampler::{AnySampler, BuildConfig, DirectionSampler, SamplerMode};
use criterion::{BenchmarkId, Criterion, Throughput};
use rand_core::SeedableRng;
use std::hint::black_box;

const BATCH: u64 = 1024;

fn bench(c: &mut Criterion) {
    let wi = common::wi();
    for &(label, name, params) in common::SETS {
        let brdf = common::model(name, params);
        let b = &*brdf;
        let config = BuildConfig::default();
        let build = |mode: SamplerMode, config| AnySampler::new(b, wi, mode, config).unwrap();
        let mut samplers: Vec<(&str, AnySampler<_>)> = vec![
            ("quadtree", build(SamplerMode::Rejection, config)),
            ("warp", build(SamplerMode::Warp, config)),
            ("uniform", build(SamplerMode::Uniform, config)),
            ("cosine", build(SamplerMode::Cosine, config)),
            ("analytic", build(SamplerMode::Analytic, config)),
            ("table", build(SamplerMode::Table, config)),
        ];
        if !common::COSTLY.contains(&name) {
            let config = BuildConfig {
                target_trials: Some(1.25),
                ..BuildConfig::default()
            };
            samplers.push((
                "quadtree-target-1.25",
                build(SamplerMode::Rejection, config),
            ));
        }
        let mut group = c.benchmark_group(format!("sample/{label}"));
        group.throughput(Throughput::Elements(BATCH));
        for (kind, sampler) in &samplers {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
            group.bench_function(BenchmarkId::from_parameter(kind), |bench| {
                bench.iter(|| {
                    for _ in 0..BATCH {
                        black_box(sampler.sample(&mut rng));
                    }
                });
            });
        }
        group.finish();
    }
}

bench_main!(bench);
