//! Samples per second from a cached sampler: the quadtree (seed rule, target-trials mode,
//! warp) against uniform, cosine, each model's analytic sampler and the 256² table, for
//! every model at default and sharp parameters. A batch of 1024 samples per iteration; the
//! RNG is seeded outside the timed closure.

#[macro_use]
mod common;

use brdf_sampling::quadtree_sampler::{
    Baseline, BaselineSampler, BuildConfig, DEFAULT_MIX, DEFAULT_TABLE_RES, DirectionSampler,
    QuadtreeSampler, TableSampler, WarpSampler,
};
use criterion::{BenchmarkId, Criterion, Throughput};
use rand_core::SeedableRng;
use std::hint::black_box;

const BATCH: u64 = 1024;

fn bench(c: &mut Criterion) {
    let wi = common::wi();
    for &(label, name, params) in common::SETS {
        let brdf = common::model(name, params);
        let b = &*brdf;
        let mut samplers: Vec<(&str, Box<dyn DirectionSampler + '_>)> = vec![
            (
                "quadtree",
                Box::new(QuadtreeSampler::new(b, wi, BuildConfig::default()).unwrap()),
            ),
            (
                "warp",
                Box::new(WarpSampler::new(b, wi, BuildConfig::default(), DEFAULT_MIX).unwrap()),
            ),
            (
                "uniform",
                Box::new(BaselineSampler::new(b, wi, Baseline::Uniform).unwrap()),
            ),
            (
                "cosine",
                Box::new(BaselineSampler::new(b, wi, Baseline::Cosine).unwrap()),
            ),
            (
                "analytic",
                Box::new(BaselineSampler::new(b, wi, Baseline::Analytic).unwrap()),
            ),
            (
                "table",
                Box::new(TableSampler::new(b, wi, DEFAULT_TABLE_RES).unwrap()),
            ),
        ];
        if !common::COSTLY.contains(&name) {
            let config = BuildConfig {
                target_trials: Some(1.25),
                ..BuildConfig::default()
            };
            samplers.push((
                "quadtree-target-1.25",
                Box::new(QuadtreeSampler::new(b, wi, config).unwrap()),
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
