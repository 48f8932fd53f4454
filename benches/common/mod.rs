//! What the criterion benches share beyond `brdf_sampling::bench`.

#![allow(dead_code, unused_imports)]

pub use brdf_sampling::bench::{COSTLY, SETS, wi};

/// Builds a set's model.
pub fn model(name: &str, params: &[&str]) -> Box<dyn brdf_sampling::Brdf> {
    brdf_sampling::bench::model(name, params).expect("a valid parameter set")
}

/// Shorter runs than criterion's defaults: the matrix has ~150 cases, on 2 noisy cores.
pub fn criterion() -> criterion::Criterion {
    criterion::Criterion::default()
        .sample_size(20)
        .warm_up_time(std::time::Duration::from_millis(300))
        .measurement_time(std::time::Duration::from_secs(1))
}

/// The `main` of a bench file: one criterion group running `$bench` with [`criterion`].
macro_rules! bench_main {
    ($bench:path) => {
        criterion::criterion_group! {
            name = benches;
            config = common::criterion();
            targets = $bench
        }
        criterion::criterion_main!(benches);
    };
}
