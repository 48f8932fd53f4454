//! The seed's `SampleTree`/`testBrdf` loop as a library: incident directions × cell grids,
//! one seeded random stream per test and per chunk of samples, the family-wise significance
//! split by Šidák, and (for a sampler that follows f·cos only on average) a test that its
//! mean weight is the albedo. [`suite`] runs it for a model of this workspace, [`check`] for
//! any sampler at one incident direction against an f·cos oracle.

use crate::cells::CellGrid;
use crate::error::ValidateError;
use crate::report::{Against, Reason, Report, Verdict};
use crate::sampler::{Drawn, Sampler};
use crate::stats::sidak;
use crate::validation::{CHUNK, Validation};
use brdf_core::Brdf;
use glam::Vec3;
use quadtree_sampler::DensityHints;
use rand_core::SeedableRng;
use std::fmt;
use std::time::Instant;

/// The most samples a test of a suite may draw: 2^36 ≈ 6.9·10¹⁰, hours of sampling at
/// typical rates. A larger count is refused ([`ValidateError::TooManySamples`]) rather than
/// left to run for days.
pub const MAX_SAMPLES: u64 = 1 << 36;

/// How a suite (or a [`check`]) runs its tests.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// The cell grids, one test each per incident direction.
    pub grids: Vec<CellGrid>,
    /// Samples per test.
    pub samples: u64,
    /// The seed every test's and every chunk's generator (PCG64) is derived from, so a
    /// result does not depend on the thread count.
    pub seed: u64,
    /// The family-wise significance of the whole run; each test is judged at Šidák's
    /// 1 − (1 − α)^(1/k) for k tests.
    pub alpha: f64,
    /// The relative tolerance of the expected cell masses (per cell, relative to the total;
    /// see [`crate::Validation::new`]: below the rounding of f32 values it costs no more).
    pub tol: f64,
    /// What the verdict judges.
    pub against: Against,
    /// Add one test per incident direction that the mean weight f·cos/pdf equals the albedo
    /// (for a sampler judged on its own pdf whose samples must still estimate the albedo
    /// without bias: a baked sampler off its grid).
    pub mean_weight: bool,
}

impl Default for Settings {
    /// Both grids at R = 25, 10⁶ samples, seed 1, α = 0.01, tolerance 10⁻⁷, against f·cos,
    /// no mean-weight test: what `brdf test` runs.
    fn default() -> Self {
        Self {
            grids: Self::both_grids(25),
            samples: 1_000_000,
            seed: 1,
            alpha: 0.01,
            tol: 1e-7,
            against: Against::FCos,
            mean_weight: false,
        }
    }
}

impl Settings {
    /// The seed's R × R squares and the equal-area polar grid of R rings × (2R + 1) sectors.
    #[must_use]
    pub fn both_grids(r: usize) -> Vec<CellGrid> {
        vec![
            CellGrid::Square { res: r },
            CellGrid::Polar {
                rings: r,
                sectors: 2 * r + 1,
            },
        ]
    }

    /// The number of tests over `directions` incident directions.
    #[must_use]
    pub fn tests(&self, directions: usize) -> usize {
        directions * self.grids.len() + if self.mean_weight { directions } else { 0 }
    }

    fn check(&self, directions: usize) -> Result<(), ValidateError> {
        if self.samples == 0 {
            return Err(ValidateError::NoSamples);
        }
        if self.samples > MAX_SAMPLES {
            return Err(ValidateError::TooManySamples {
                value: self.samples,
            });
        }
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            return Err(ValidateError::Significance { value: self.alpha });
        }
        if directions == 0 || self.grids.is_empty() {
            return Err(ValidateError::EmptySuite);
        }
        for g in &self.grids {
            g.check()?;
        }
        Ok(())
    }
}

/// One finished χ² test of a suite.
#[derive(Clone, Debug)]
pub struct TestOutcome {
    /// The incident direction (`None` in a [`check`], whose sampler's wi is its own).
    pub wi: Option<Vec3>,
    /// The cells.
    pub grid: CellGrid,
    /// What the verdict judges.
    pub against: Against,
    /// What the test found.
    pub report: Report,
    /// Seconds spent integrating the cells and testing.
    pub seconds: f64,
}

impl TestOutcome {
    /// The verdict against what the suite judges.
    #[must_use]
    pub fn verdict(&self) -> Verdict {
        self.report.verdict_against(self.against)
    }

    /// What rejected, then what could not be judged, under the suite's verdict.
    #[must_use]
    pub fn reasons(&self) -> Vec<&Reason> {
        let mut out = self.report.rejections(self.against);
        out.extend(self.report.unjudged(self.against));
        out
    }
}

/// The relative floor of the mean-weight test: the cell masses, whose total is the albedo,
/// are exact to about 10⁻⁶, so a difference below 10⁻⁴ of the albedo is not the sampler's.
/// (A fixed 96-panel quadrature gave the albedo before: 6.4·10⁻⁴ for a Blinn–Phong lobe of
/// n = 39 794 at 89° whose cell masses, on three grids, and quadtree give 1.32·10⁻⁴.)
pub const WEIGHT_FLOOR: f64 = 1e-4;

/// A sampler's mean weight against the albedo at one incident direction.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightTest {
    /// The incident direction (`None` in a [`check`]).
    pub wi: Option<Vec3>,
    /// The mean luminance weight f·cos/pdf (lost samples score 0).
    pub mean: f64,
    /// Its standard error.
    pub standard_error: f64,
    /// The albedo (luminance) it must equal.
    pub albedo: f64,
    /// The two-sided p-value of |mean − albedo| against the standard error and
    /// [`WEIGHT_FLOOR`] together; 0 where the mean, its standard error or the albedo is
    /// NaN or infinite (a weight, or the f·cos oracle, was).
    pub p_value: f64,
    /// Whether p ≥ the per-test significance.
    pub passed: bool,
}

/// What a suite found.
#[derive(Clone, Debug)]
pub struct SuiteReport {
    /// The χ² tests, incident direction by incident direction, grid by grid.
    pub tests: Vec<TestOutcome>,
    /// The mean-weight tests (empty unless [`Settings::mean_weight`]).
    pub weight_tests: Vec<WeightTest>,
    /// The family-wise significance.
    pub alpha: f64,
    /// The significance each test was judged at.
    pub alpha_per_test: f64,
}

impl SuiteReport {
    /// Rejected when any test rejected, else inconclusive when any could not be judged, else
    /// passed.
    #[must_use]
    pub fn verdict(&self) -> Verdict {
        Verdict::overall(self.tests.iter().map(TestOutcome::verdict).chain(
            self.weight_tests.iter().map(|w| {
                if w.passed {
                    Verdict::Passed
                } else {
                    Verdict::Rejected
                }
            }),
        ))
    }

    /// True when every test ran and passed.
    #[must_use]
    pub fn passed(&self) -> bool {
        self.verdict() == Verdict::Passed
    }
}

impl fmt::Display for SuiteReport {
    /// The verdict, then one line per test with its reasons.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{:?}: {} tests at α = {} (Šidák: {:.3e} each)",
            self.verdict(),
            self.tests.len() + self.weight_tests.len(),
            self.alpha,
            self.alpha_per_test
        )?;
        for t in &self.tests {
            let p = |c: &Option<crate::ChiSquare>| {
                c.as_ref()
                    .map_or_else(|| "–".to_string(), |c| format!("{:.3e}", c.p_value))
            };
            write!(
                f,
                "{:?}{}: {:?}, p = {} against f·cos, {} against its own pdf",
                t.grid,
                t.wi.map_or_else(String::new, |w| format!(" at wi {w}")),
                t.verdict(),
                p(&t.report.chi2),
                p(&t.report.chi2_own),
            )?;
            for r in t.reasons() {
                write!(f, "\n  {r}")?;
            }
            writeln!(f)?;
        }
        for w in &self.weight_tests {
            writeln!(
                f,
                "mean weight {:.6} ± {:.2e} against albedo {:.6}: p = {:.3e}, {}{}",
                w.mean,
                w.standard_error,
                w.albedo,
                w.p_value,
                if w.passed { "passed" } else { "REJECTED" },
                if w.mean.is_finite() && w.standard_error.is_finite() && w.albedo.is_finite() {
                    ""
                } else {
                    " (not finite: a weight or the f·cos oracle is NaN or infinite)"
                }
            )?;
        }
        Ok(())
    }
}

/// What a suite reports as it runs (for progress, pictures, logs).
pub enum Event<'a> {
    /// A χ² test finished (its histogram holds the cells and their masses).
    Tested(&'a TestOutcome),
    /// The mean-weight test at incident direction `index` (of `of`) starts.
    WeighingStarts {
        /// Which incident direction, from 0.
        index: usize,
        /// How many there are.
        of: usize,
    },
    /// A mean-weight test finished.
    Weighed(&'a WeightTest),
}

/// SplitMix64's finaliser: decorrelates the seeds of tests and chunks.
#[must_use]
pub fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// The generator of chunk `chunk` of test `test` in a run seeded with `seed`.
fn chunk_rng(seed: u64, test: u64, chunk: u64) -> rand_pcg::Pcg64 {
    let test_seed = splitmix64(seed ^ splitmix64(test));
    rand_pcg::Pcg64::seed_from_u64(splitmix64(test_seed ^ splitmix64(chunk)))
}

/// The seed's testBrdf for a model of this workspace: for every incident direction of `wis`,
/// `sampler_for(k, wi)` builds the sampler under test, which is histogrammed over every grid
/// of `settings` against the model's f·cos (integrated by [`Validation::new`]); with
/// [`Settings::mean_weight`], each sampler's mean weight is then tested against the model's
/// albedo (the cell masses' total at that wi). `on_event` sees every finished test
/// (pictures, progress). Test k·G + g (incident direction k, grid g) draws from seeds
/// derived from `settings.seed`, k and g alone, so a report does not depend on the thread
/// count.
pub fn suite<B, S, E>(
    brdf: &B,
    wis: &[Vec3],
    settings: &Settings,
    mut sampler_for: impl FnMut(usize, Vec3) -> Result<S, E>,
    mut on_event: impl FnMut(Event<'_>) -> Result<(), E>,
) -> Result<SuiteReport, E>
where
    B: Brdf + ?Sized,
    S: Sampler,
    E: From<ValidateError>,
{
    settings.check(wis.len())?;
    let alpha = sidak(settings.alpha, settings.tests(wis.len()));
    let mut tests = Vec::with_capacity(wis.len() * settings.grids.len());
    let mut samplers = Vec::with_capacity(wis.len());
    // ∫ Y(f_r)·cos dω at each wi: the first grid's cell masses summed (adaptive, cut at the
    // model's peaks), what the mean weights must equal.
    let mut albedos = Vec::with_capacity(wis.len());
    for (k, &wi) in wis.iter().enumerate() {
        let sampler = sampler_for(k, wi)?;
        for (g, &grid) in settings.grids.iter().enumerate() {
            let t0 = Instant::now();
            let v = Validation::new(brdf, wi, grid, settings.tol)?;
            if g == 0 {
                albedos.push(v.mass().iter().sum::<f64>());
            }
            let index = (k * settings.grids.len() + g) as u64;
            let report = v.test_chunked(
                &sampler,
                settings.samples,
                |chunk| chunk_rng(settings.seed, index, chunk),
                alpha,
            );
            let outcome = TestOutcome {
                wi: Some(wi),
                grid,
                against: settings.against,
                report,
                seconds: t0.elapsed().as_secs_f64(),
            };
            on_event(Event::Tested(&outcome))?;
            tests.push(outcome);
        }
        if settings.mean_weight {
            samplers.push(sampler);
        }
    }
    let mut weight_tests = Vec::new();
    for (k, (sampler, &wi)) in samplers.iter().zip(wis).enumerate() {
        on_event(Event::WeighingStarts {
            index: k,
            of: wis.len(),
        })?;
        let wi_unit = brdf_core::geometry::unit_direction_above(wi).map_err(ValidateError::from)?;
        let albedo = albedos[k];
        let weight = |d: &Drawn| {
            d.f_and_weight.map_or_else(
                || {
                    f64::from(brdf.eval_luminance(wi_unit, d.wo)) * f64::from(d.wo.z)
                        / f64::from(d.pdf)
                },
                |(_, w)| f64::from(w),
            )
        };
        let seed = splitmix64(settings.seed ^ splitmix64(0xba4e_0000 + k as u64));
        let w = weight_test(
            sampler,
            Some(wi),
            settings.samples,
            seed,
            &weight,
            albedo,
            alpha,
        );
        on_event(Event::Weighed(&w))?;
        weight_tests.push(w);
    }
    Ok(SuiteReport {
        tests,
        weight_tests,
        alpha: settings.alpha,
        alpha_per_test: alpha,
    })
}

/// Validates any sampler at one incident direction against an f·cos oracle: the entry point
/// for a BSDF outside this workspace. `fcos(wo)` is the luminance of f_r(wi, wo)·cos θo per
/// unit solid angle at the sampler's incident direction; `peaks` are directions where it
/// may peak sharply (up to four; see [`Validation::of_fcos`]). One χ² test per grid of
/// `settings`, judged as [`Settings::against`] says; with [`Settings::mean_weight`], one
/// more: the mean weight (the sampler's own, or f·cos/pdf from the oracle) against ∫ f·cos dω.
pub fn check<S: Sampler + ?Sized>(
    sampler: &S,
    fcos: impl Fn(Vec3) -> f64 + Sync,
    peaks: &[Vec3],
    settings: &Settings,
) -> Result<SuiteReport, ValidateError> {
    check_with(sampler, fcos, &DensityHints::of_peaks(peaks), settings)
}

/// [`check`] with ridge planes besides the peaks (see [`Validation::of_fcos_with`]): for a
/// BSDF with a lobe narrow along an axis that is not the frame's x or y.
pub fn check_with<S: Sampler + ?Sized>(
    sampler: &S,
    fcos: impl Fn(Vec3) -> f64 + Sync,
    hints: &DensityHints,
    settings: &Settings,
) -> Result<SuiteReport, ValidateError> {
    settings.check(1)?;
    let alpha = sidak(settings.alpha, settings.tests(1));
    let mut tests = Vec::with_capacity(settings.grids.len());
    let mut albedo = 0.0;
    for (g, &grid) in settings.grids.iter().enumerate() {
        let t0 = Instant::now();
        let v = Validation::of_fcos_with(&fcos, hints, grid, settings.tol)?;
        albedo = v.mass().iter().sum();
        let report = v.test_chunked(
            sampler,
            settings.samples,
            |chunk| chunk_rng(settings.seed, g as u64, chunk),
            alpha,
        );
        tests.push(TestOutcome {
            wi: None,
            grid,
            against: settings.against,
            report,
            seconds: t0.elapsed().as_secs_f64(),
        });
    }
    let mut weight_tests = Vec::new();
    if settings.mean_weight {
        let weight = |d: &Drawn| {
            d.f_and_weight
                .map_or_else(|| fcos(d.wo) / f64::from(d.pdf), |(_, w)| f64::from(w))
        };
        let seed = splitmix64(settings.seed ^ splitmix64(0xba4e_0000));
        weight_tests.push(weight_test(
            sampler,
            None,
            settings.samples,
            seed,
            &weight,
            albedo,
            alpha,
        ));
    }
    Ok(SuiteReport {
        tests,
        weight_tests,
        alpha: settings.alpha,
        alpha_per_test: alpha,
    })
}

/// The mean of `weight` over `samples` draws (lost samples score 0) against
/// `albedo`, in chunks of [`CHUNK`] with their own generators (parallel, summed in order).
fn weight_test<S: Sampler + ?Sized>(
    sampler: &S,
    wi: Option<Vec3>,
    samples: u64,
    seed: u64,
    weight: &(dyn Fn(&Drawn) -> f64 + Sync),
    albedo: f64,
    alpha: f64,
) -> WeightTest {
    use rayon::prelude::*;
    let parts: Vec<(f64, f64)> = (0..samples.div_ceil(CHUNK))
        .into_par_iter()
        .map(|k| {
            let mut rng = rand_pcg::Pcg64::seed_from_u64(splitmix64(seed ^ splitmix64(k)));
            let n = CHUNK.min(samples - k * CHUNK);
            let (mut s, mut q) = (0.0, 0.0);
            for _ in 0..n {
                let w = sampler.draw(&mut rng).map_or(0.0, |d| weight(&d));
                s += w;
                q += w * w;
            }
            (s, q)
        })
        .collect();
    let (s, q) = parts.iter().fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
    let n = samples as f64;
    let mean = s / n;
    let se = ((q / n - mean * mean).max(0.0) / n).sqrt();
    // The difference is judged against the counting error and the relative floor together.
    let scale = (se * se + (WEIGHT_FLOOR * albedo).powi(2)).sqrt();
    // A NaN or infinite weight or oracle is judged as far off as can be (p = 0): with an
    // infinite albedo the quotient below was NaN, and so was the p-value.
    let z = if !(mean.is_finite() && albedo.is_finite() && scale.is_finite()) {
        f64::INFINITY
    } else if scale > 0.0 {
        (mean - albedo).abs() / scale
    } else if mean == albedo {
        0.0
    } else {
        f64::INFINITY
    };
    let p_value = brdf_core::special::erfc(z / std::f64::consts::SQRT_2);
    WeightTest {
        wi,
        mean,
        standard_error: se,
        albedo,
        p_value,
        passed: p_value >= alpha,
    }
}
