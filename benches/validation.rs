//! One (model, wi) χ² check of the validation harness: the expected cell masses, 10⁶
//! samples from the quadtree, both χ² tests, on the seed's 25² grid and the 25 × 51 polar
//! grid.

#[macro_use]
mod common;

use brdf_sampling::quadtree_sampler::{BuildConfig, QuadtreeSampler};
use brdf_sampling::validate::{CellGrid, Validation};
use criterion::{BenchmarkId, Criterion, Throughput};
use rand_core::SeedableRng;
use std::hint::black_box;

const SAMPLES: u64 = 1_000_000;

fn bench(c: &mut Criterion) {
    let wi = common::wi();
    for &(label, name, params) in &[
        ("phong-n500", "phong", &["n=500"][..]),
        ("ward", "ward", &[][..]),
        ("cook-torrance", "cook-torrance", &[][..]),
    ] {
        let brdf = common::model(name, params);
        let q = QuadtreeSampler::new(&*brdf, wi, BuildConfig::default()).unwrap();
        let mut group = c.benchmark_group(format!("validate/{label}"));
        group.sample_size(10);
        group.throughput(Throughput::Elements(SAMPLES));
        for grid in [
            CellGrid::Square { res: 25 },
            CellGrid::Polar {
                rings: 25,
                sectors: 51,
            },
        ] {
            let id = match grid {
                CellGrid::Square { .. } => "square-25",
                CellGrid::Polar { .. } => "polar-25x51",
            };
            group.bench_function(BenchmarkId::from_parameter(id), |bench| {
                bench.iter(|| {
                    let v = Validation::new(&*brdf, wi, grid, 1e-7).unwrap();
                    black_box(v.test_chunked(&q, SAMPLES, rand_pcg::Pcg64::seed_from_u64, 0.01))
                });
            });
        }
        group.finish();
    }
}

bench_main!(bench);
