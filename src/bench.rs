//! What the benchmarks share (the criterion benches, `brdf bench`, the furnace example): the
//! model sets, the incident direction, and a procedural environment to estimate reflected
//! radiance under.

use crate::geometry::spherical_direction;
use crate::glam::Vec3;
use crate::quadtree_sampler::DirectionSampler;
use crate::{Brdf, ParamError, registry};
use rand_core::SeedableRng;
use std::time::Instant;

/// (label, model, parameters): every model with a continuous part, at its defaults and with a
/// sharp lobe where it has one. The glossy targets of issue #7 are `phong-sharp`
/// (n = 1000), `ward-sharp` (α = 0.05) and `cook-torrance-sharp` (m = 0.1).
pub const SETS: &[(&str, &str, &[&str])] = &[
    ("lambert", "lambert", &[]),
    ("phong", "phong", &[]),
    ("phong-sharp", "phong", &["n=1000", "kd=0"]),
    ("blinn-phong", "blinn-phong", &[]),
    ("blinn-phong-sharp", "blinn-phong", &["n=1000", "kd=0"]),
    ("lewis-phong", "lewis-phong", &[]),
    ("lewis-phong-sharp", "lewis-phong", &["n=1000", "kd=0"]),
    ("cook-torrance", "cook-torrance", &[]),
    ("cook-torrance-sharp", "cook-torrance", &["m=0.1"]),
    ("htsg", "htsg", &[]),
    ("htsg-sharp", "htsg", &["sigma0=0.0318", "tau=0.3"]),
    ("poulin-fournier", "poulin-fournier", &[]),
    ("poulin-fournier-sharp", "poulin-fournier", &["n=1000"]),
    ("oren-nayar", "oren-nayar", &[]),
    ("oren-nayar-rough", "oren-nayar", &["sigma=1.5"]),
    ("ward", "ward", &[]),
    (
        "ward-sharp",
        "ward",
        &["alpha_x=0.05", "alpha_y=0.05", "kd=0"],
    ),
    ("schlick", "schlick", &[]),
    ("schlick-sharp", "schlick", &["r=0.01"]),
    ("strauss", "strauss", &[]),
    ("strauss-sharp", "strauss", &["smoothness=0.9"]),
    // Measured data (SPEC §8): the file is written by [`measured_file`] (no database file is
    // shipped), read with the database's own nearest lookup.
    ("merl-measured", "merl", &["interp=nearest"]),
];

/// The sets `brdf bench --quick` measures: one diffuse, the three glossy targets, and the two
/// models without an analytic sampler.
pub const QUICK_SETS: &[&str] = &[
    "lambert",
    "phong-sharp",
    "cook-torrance-sharp",
    "ward-sharp",
    "htsg",
    "poulin-fournier",
];

/// Models whose eval costs microseconds, or whose piecewise-constant data makes adaptive
/// integration slow: a target-trials build takes minutes on 2 cores.
pub const COSTLY: &[&str] = &["htsg", "poulin-fournier", "merl"];

/// Builds a set's model. A measured model given no `file=` reads [`measured_file`].
pub fn model(name: &str, params: &[&str]) -> Result<Box<dyn Brdf>, ParamError> {
    let measured = registry::find(name)?.measured;
    if measured && !params.iter().any(|p| p.trim_start().starts_with("file=")) {
        let file = format!("file={}", measured_file().display());
        return registry::create(name, params.iter().copied().chain([file.as_str()]));
    }
    registry::create(name, params.iter().copied())
}

/// f_r of a measured-looking material in the MERL layout, channel-major input for
/// [`crate::models::merl::encode`]: `model` tabulated at the bins' centres, each bin scaled
/// by 1 + `noise`·(2u − 1) (u uniform, PCG64 seeded by `seed`), and every bin with θd beyond
/// 85° "not measured" (−1), as real gonioreflectometer data has.
pub fn measured_like(model: &dyn Brdf, noise: f64, seed: u64) -> Vec<[f64; 3]> {
    use rand_core::Rng;
    let mut f = crate::models::merl::tabulate(model);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    for (k, v) in f.iter_mut().enumerate() {
        if (k / crate::models::merl::MERL_PHI_D) % crate::models::merl::MERL_THETA_D >= 85 {
            *v = [-1.0; 3];
            continue;
        }
        let u = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        let n = 1.0 + noise * (2.0 * u - 1.0);
        *v = v.map(|x| x * n);
    }
    f
}

/// The benches' measured file: Cook–Torrance m = 0.1, kd = 0.1 through [`measured_like`]
/// (3 % noise, seed 42), in the temporary directory under one name for every process (its
/// bytes are a pure function of this code): reused when it holds exactly these bytes, else
/// written (complete or absent: written beside and renamed, so processes that write it at
/// once each leave the same file). One 35 MB file, however many runs; a name per process
/// left one behind per `brdf bench` run.
///
/// # Panics
/// When the temporary directory cannot be written.
pub fn measured_file() -> &'static std::path::Path {
    static FILE: std::sync::OnceLock<std::path::PathBuf> = std::sync::OnceLock::new();
    FILE.get_or_init(|| {
        let path = std::env::temp_dir().join("brdf-bench-measured.binary");
        let ct = registry::create("cook-torrance", ["m=0.1", "kd=0.1"]).expect("valid parameters");
        let bytes = crate::models::merl::encode(&measured_like(&*ct, 0.03, 42));
        if std::fs::read(&path).ok().as_deref() != Some(&bytes[..]) {
            crate::quadtree_sampler::write_atomically(&path, &bytes)
                .unwrap_or_else(|e| panic!("writing {}: {e}", path.display()));
        }
        path
    })
}

/// The incident (viewing) direction of the benches: θ = 45°, φ = 30°.
#[must_use]
pub fn wi() -> Vec3 {
    spherical_direction(45f32.to_radians(), 30f32.to_radians())
}

/// A procedural environment in the local frame: a sky whose radiance grows from 0.2 at the
/// horizon to 1 at the zenith, plus a sun of angular radius 2° and radiance 2000 (about 2.5
/// times the sky's irradiance). [`Environment::default`] puts the sun at θ = 60°, φ = 120°,
/// far from the mirror direction of [`wi`] (θ = 45°, φ = 210°): a glossy lobe sees the sky, a
/// diffuse one the sun too. [`Environment::glint`] puts it about 6° from the mirror direction,
/// in the tails of the glossy lobes, where BRDF sampling alone is at its weakest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Environment {
    /// Unit direction toward the sun's centre.
    pub sun: Vec3,
    /// cos of the sun's angular radius.
    pub sun_cos_radius: f32,
    /// Radiance inside the sun's disk (added to the sky).
    pub sun_radiance: f64,
}

impl Default for Environment {
    fn default() -> Self {
        Self::with_sun(60.0, 120.0)
    }
}

impl Environment {
    /// The sun at (θ, φ) in degrees.
    #[must_use]
    pub fn with_sun(theta_deg: f32, phi_deg: f32) -> Self {
        Self {
            sun: spherical_direction(theta_deg.to_radians(), phi_deg.to_radians()),
            sun_cos_radius: 2f32.to_radians().cos(),
            sun_radiance: 2000.0,
        }
    }

    /// The sun at θ = 40°, φ = 215°, about 6° from the mirror direction of [`wi`].
    #[must_use]
    pub fn glint() -> Self {
        Self::with_sun(40.0, 215.0)
    }

    /// Radiance arriving from direction `w` (unit, local frame); 0 below the horizon.
    #[must_use]
    pub fn radiance(&self, w: Vec3) -> f64 {
        if w.z.is_nan() || w.z <= 0.0 {
            return 0.0;
        }
        let sky = 0.2 + 0.8 * f64::from(w.z);
        if w.dot(self.sun) >= self.sun_cos_radius {
            sky + self.sun_radiance
        } else {
            sky
        }
    }
}

/// One sampler's estimate of the reflected radiance ∫ f_r L cos θ dω (luminance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Samples drawn.
    pub samples: u64,
    /// The mean of the one-sample estimator Y(weight)·L(wo).
    pub mean: f64,
    /// The variance of the one-sample estimator (N samples per estimate: divide by N).
    pub variance: f64,
    /// The standard error of `variance` itself, from the sample's fourth central moment
    /// μ₄: √((μ₄ − σ⁴·(n − 3)/(n − 1))/n). Under a sun a few rare samples carry most of the
    /// variance, and the estimate of it is uncertain long after the mean is not (at 10⁵
    /// samples, tens of per cent): every efficiency is only as sure as this.
    pub variance_se: f64,
    /// Seconds per sample of drawing and scoring (one thread).
    pub seconds_per_sample: f64,
}

impl Estimate {
    /// Efficiency 1/(variance · time per sample), with `build_seconds` amortised over
    /// `amortise` samples. It does not depend on the samples per estimate N: variance falls
    /// as 1/N while time grows as N.
    #[must_use]
    pub fn efficiency(&self, build_seconds: f64, amortise: f64) -> f64 {
        1.0 / (self.variance * (self.seconds_per_sample + build_seconds / amortise))
    }

    /// The relative standard error of [`Estimate::efficiency`] from its variance's
    /// ([`Estimate::variance_se`] over `variance`; the time is measured, not estimated):
    /// 0 for a variance of 0.
    #[must_use]
    pub fn efficiency_rse(&self) -> f64 {
        if self.variance > 0.0 {
            self.variance_se / self.variance
        } else {
            0.0
        }
    }
}

/// The relative standard error of the ratio of two [`Estimate::efficiency`]s drawn from
/// independent samples: their relative errors added in quadrature.
#[must_use]
pub fn efficiency_ratio_rse(a: &Estimate, b: &Estimate) -> f64 {
    a.efficiency_rse().hypot(b.efficiency_rse())
}

/// Draws `samples` directions from `sampler` (one thread, PCG64 from `seed`) and scores each
/// by Y(weight)·L(wo) under every environment of `envs` (the same samples for all); a
/// sample the sampler gives no direction for scores 0.
pub fn estimate(
    sampler: &dyn DirectionSampler,
    envs: &[Environment],
    samples: u64,
    seed: u64,
) -> Vec<Estimate> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    // Power sums Σy, Σy², Σy³, Σy⁴: a few multiply-adds a sample beside the sampler's own
    // work (an online central-moment update would divide on every sample).
    let mut sums = vec![[0.0f64; 4]; envs.len()];
    let t0 = Instant::now();
    for _ in 0..samples {
        if let Some(s) = sampler.sample(&mut rng) {
            let w = f64::from(crate::geometry::luminance(s.weight));
            for (acc, env) in sums.iter_mut().zip(envs) {
                add_powers(acc, w * env.radiance(s.wo));
            }
        }
    }
    let seconds = t0.elapsed().as_secs_f64();
    let n = samples.max(1) as f64;
    sums.iter()
        .map(|&sums| {
            let (mean, variance, variance_se) = moments(sums, n);
            Estimate {
                samples,
                mean,
                variance,
                variance_se,
                seconds_per_sample: seconds / n,
            }
        })
        .collect()
}

/// Adds y, y², y³ and y⁴ to the power sums `acc`.
#[inline]
fn add_powers(acc: &mut [f64; 4], y: f64) {
    let y2 = y * y;
    acc[0] += y;
    acc[1] += y2;
    acc[2] += y2 * y;
    acc[3] += y2 * y2;
}

/// (mean, unbiased variance, the variance's standard error) of `n` values from their power
/// sums [Σy, Σy², Σy³, Σy⁴]. μ₄ comes from the raw moments: its cancellation matters only
/// where the variance is tiny against the mean², and its standard error with it.
fn moments([sum, sum2, sum3, sum4]: [f64; 4], n: f64) -> (f64, f64, f64) {
    let mean = sum / n;
    let variance = (sum2 / n - mean * mean).max(0.0) * n / (n - 1.0).max(1.0);
    let (m2, m3, m4) = (sum2 / n, sum3 / n, sum4 / n);
    let mu4 = m4 - 4.0 * mean * m3 + 6.0 * mean * mean * m2 - 3.0 * mean.powi(4);
    let spread = if n > 3.0 {
        mu4 - variance * variance * (n - 3.0) / (n - 1.0)
    } else {
        mu4
    };
    (mean, variance, (spread.max(0.0) / n).sqrt())
}

/// How many times `brdf bench` times each of its bare loops (a [`Floor`]'s parts, the
/// Beckmann yardstick, the baked sampler's random-wi loops); the fastest run counts (the
/// machines are shared and noisy: the minimum is the least disturbed run, and a ratio of
/// minima compares like with like).
pub const TIMING_RUNS: usize = 3;

/// The floor of a sampler's cost per sample (issue #16): its irreducible parts, each timed
/// alone in a bare loop over pre-drawn inputs, and the sampler's own time in the same kind
/// of loop. All times in ns, the fastest of [`TIMING_RUNS`] runs.
///
/// floor = E\[T\] × (one model evaluation + one trial's random numbers) + one descent, with
/// E\[T\] = 1 for the warp (one evaluation: the f a sample reports; its two uniforms; its
/// descent, the hierarchical warp).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Floor {
    /// One f_r evaluation at the sampler's own sample directions.
    pub eval_ns: f64,
    /// Two 64-bit draws from the benches' RNG (a rejection trial's point and height).
    pub uniforms_ns: f64,
    /// One descent: rejection, `PackedTree::select` from a uniform; warp, the warp to the
    /// square.
    pub descent_ns: f64,
    /// E\[T\] of the tree (1 for the warp).
    pub expected_trials: f64,
    /// The sampler's `sample` in the same bare loop.
    pub sample_ns: f64,
}

impl Floor {
    /// E\[T\] × (eval + uniforms) + descent, in ns.
    #[must_use]
    pub fn floor_ns(&self) -> f64 {
        self.expected_trials * (self.eval_ns + self.uniforms_ns) + self.descent_ns
    }

    /// The sampler's time over its floor (issue #16's goal: at most 1.5).
    #[must_use]
    pub fn over_floor(&self) -> f64 {
        self.sample_ns / self.floor_ns()
    }

    /// The JSON object `brdf bench` prints.
    #[must_use]
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "eval_ns": self.eval_ns,
            "uniforms_ns": self.uniforms_ns,
            "descent_ns": self.descent_ns,
            "expected_trials": self.expected_trials,
            "floor_ns": self.floor_ns(),
            "sample_ns": self.sample_ns,
            "sample_over_floor": self.over_floor(),
        })
    }
}

/// The fastest of [`TIMING_RUNS`] timings of `body` over `n` items, in ns per item (`body`'s
/// result goes through `black_box`, so its work is not optimised away).
pub fn fastest_ns<T>(n: usize, mut body: impl FnMut() -> T) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..TIMING_RUNS {
        let t0 = Instant::now();
        std::hint::black_box(body());
        best = best.min(t0.elapsed().as_secs_f64() * 1e9 / n.max(1) as f64);
    }
    best
}

/// The parts every floor shares: the sampler's bare sample loop (which also gives the
/// directions to evaluate at), one evaluation there, two RNG draws. `sample` draws one
/// sample with the benches' RNG as a concrete type, as the draws are timed: through the
/// sampler's own generic method, not `&mut dyn Rng` (a virtual call a draw, which the floor's
/// draws do not pay, would count against the sampler).
fn shared_parts(
    mut sample: impl FnMut(&mut rand_pcg::Pcg64) -> Option<Vec3>,
    brdf: &dyn Brdf,
    wi: Vec3,
    n: usize,
    seed: u64,
) -> (f64, f64, f64) {
    use rand_core::Rng;
    let mut wos = Vec::with_capacity(n);
    let sample_ns = fastest_ns(n, || {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        wos.clear();
        for _ in 0..n {
            if let Some(wo) = sample(&mut rng) {
                wos.push(wo);
            }
        }
        wos.len() as f64
    });
    let eval_ns = fastest_ns(wos.len(), || {
        wos.iter()
            .map(|&wo| f64::from(brdf.eval(wi, wo).x))
            .sum::<f64>()
    });
    let uniforms_ns = fastest_ns(n, || {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        (0..n)
            .map(|_| (rng.next_u64() ^ rng.next_u64()) as f64)
            .sum::<f64>()
    });
    (sample_ns, eval_ns, uniforms_ns)
}

/// The [`Floor`] of the seed's rejection sampler `q` (of `brdf` at `wi`), over `n` samples.
pub fn rejection_floor<B: Brdf>(
    q: &crate::quadtree_sampler::QuadtreeSampler<B>,
    brdf: &dyn Brdf,
    n: usize,
    seed: u64,
) -> Floor {
    let (sample_ns, eval_ns, uniforms_ns) =
        shared_parts(|rng| q.sample(rng).map(|s| s.wo), brdf, q.wi(), n, seed);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let us: Vec<f64> = (0..n)
        .map(|_| crate::quadtree_sampler::uniform_f64(&mut rng))
        .collect();
    let tree = q.tree();
    let descent_ns = fastest_ns(n, || {
        us.iter().map(|&u| tree.select(u).rect.min.x).sum::<f64>()
    });
    Floor {
        eval_ns,
        uniforms_ns,
        descent_ns,
        expected_trials: tree.stats().expected_trials,
        sample_ns,
    }
}

/// The [`Floor`] of the warp sampler `w` (of `brdf` at `wi`), over `n` samples.
pub fn warp_floor<B: Brdf>(
    w: &crate::quadtree_sampler::WarpSampler<B>,
    brdf: &dyn Brdf,
    wi: Vec3,
    n: usize,
    seed: u64,
) -> Floor {
    let draw = |rng: &mut rand_pcg::Pcg64| {
        let u = crate::glam::DVec2::new(
            crate::quadtree_sampler::uniform_f64(rng),
            crate::quadtree_sampler::uniform_f64(rng),
        );
        w.sample_warp(u.as_vec2()).map(|s| s.wo)
    };
    let (sample_ns, eval_ns, uniforms_ns) = shared_parts(draw, brdf, wi, n, seed);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let us: Vec<crate::glam::DVec2> = (0..n)
        .map(|_| {
            crate::glam::DVec2::new(
                crate::quadtree_sampler::uniform_f64(&mut rng),
                crate::quadtree_sampler::uniform_f64(&mut rng),
            )
        })
        .collect();
    let descent_ns = fastest_ns(n, || {
        us.iter().map(|&u| w.warp_to_square(u).0.x).sum::<f64>()
    });
    Floor {
        eval_ns,
        uniforms_ns,
        descent_ns,
        expected_trials: 1.0,
        sample_ns,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_core::Rng;

    /// The moments from power sums agree with two-pass ones, on small integers and on a
    /// heavy-tailed set.
    #[test]
    fn moments_from_power_sums_are_the_two_pass_ones() {
        let sets: [&[f64]; 2] = [
            &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0],
            &[0.1, 0.2, 0.1, 0.3, 0.2, 40.0, 0.1, 0.0, 0.2, 0.1, 0.3, 7.0],
        ];
        for ys in sets {
            let n = ys.len() as f64;
            let mut sums = [0.0; 4];
            for &y in ys {
                add_powers(&mut sums, y);
            }
            let (mean, variance, se) = moments(sums, n);
            let m = ys.iter().sum::<f64>() / n;
            let v = ys.iter().map(|y| (y - m).powi(2)).sum::<f64>() / (n - 1.0);
            let mu4 = ys.iter().map(|y| (y - m).powi(4)).sum::<f64>() / n;
            let want = ((mu4 - v * v * (n - 3.0) / (n - 1.0)) / n).sqrt();
            assert!((mean - m).abs() < 1e-12 * m.abs(), "{ys:?}");
            assert!((variance - v).abs() < 1e-10 * v, "{ys:?}");
            assert!((se - want).abs() < 1e-8 * want, "{ys:?}: {se} vs {want}");
        }
    }

    /// The variance's standard error is how far variances of independent batches spread:
    /// 400 batches of 1000 exponential values (μ₄ = 9σ⁴, so the error is √(8/1000) ≈ 9 % of
    /// σ²), the batches' standard deviation of their variances against the mean predicted
    /// one, within 15 % (the spread's own relative error here is about 6 %; fixed seed).
    /// Taking σ⁴ for μ₄ (the Gaussian error) predicts half the spread and fails.
    #[test]
    fn the_variance_error_predicts_the_spread_of_batches() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(31);
        let (batches, n) = (400, 1000);
        let mut variances = Vec::with_capacity(batches);
        let mut predicted = 0.0;
        for _ in 0..batches {
            let mut sums = [0.0; 4];
            for _ in 0..n {
                let u = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
                add_powers(&mut sums, -(1.0 - u).ln());
            }
            let (_, variance, se) = moments(sums, n as f64);
            variances.push(variance);
            predicted += se / batches as f64;
        }
        let mean = variances.iter().sum::<f64>() / batches as f64;
        let spread = (variances.iter().map(|v| (v - mean).powi(2)).sum::<f64>()
            / (batches - 1) as f64)
            .sqrt();
        assert!(
            (predicted / spread - 1.0).abs() < 0.15,
            "predicted {predicted}, observed {spread}"
        );
    }
}
