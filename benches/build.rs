//! Quadtree builds per model (default and sharp parameters, θi = 45°), on one rayon thread
//! (the serial reference) and on all of them; the trees are bit-identical (tested in
//! crates/quadtree-sampler/tests/quadtree.rs), so the ratio is the rayon speedup.

#[macro_use]
mod common;

use brdf_sampling::quadtree_sampler::{BuildConfig, QuadtreeSampler};
use criterion::{BenchmarkId, Criterion};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let wi = common::wi();
    let serial = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let parallel = rayon::ThreadPoolBuilder::new().build().unwrap();
    for &(label, name, params) in common::SETS {
        let brdf = common::model(name, params);
        let mut group = c.benchmark_group(format!("build/{label}"));
        if common::COSTLY.contains(&name) {
            group.sample_size(10);
        }
        for (threads, pool) in [("serial", &serial), ("rayon", &parallel)] {
            group.bench_function(BenchmarkId::from_parameter(threads), |bench| {
                bench.iter(|| {
                    pool.install(|| {
                        black_box(QuadtreeSampler::new(&*brdf, wi, BuildConfig::default()).unwrap())
                    })
                });
            });
        }
        group.finish();
    }
}

bench_main!(bench);
