//! A validation set-up (the cells and their expected masses, integrated once, independently
//! of any sampler) and one test of a sampler against it: the seed's §4 statistic and a
//! Pearson χ² harness (SPEC §5).
//!
//! The expected mass of every cell comes from an adaptive Gauss–Kronrod integration of f_r
//! over the cell on the disk, which never looks at a tree (otherwise a wrong leaf integral or
//! bound could not be seen). Samples are histogrammed over the same cells; then
//!
//! - the seed's statistic: a_i = (n_i/m)/I_i must be one constant a = 1/Σ I_j; the spread of
//!   a_i/a is reported over cells with enough expected hits;
//! - a Pearson χ² against f·cos (cells expected below 5 pooled, dof = bins − 1, p from the
//!   regularised upper incomplete gamma function), and a second one against the sampler's
//!   *own* reported pdf (a "lost" bin holds the samples it gives no direction for);
//! - per-sample consistency: the pdf a sample carries equals `pdf(wo)`, and its weight equals
//!   f·cos θ/pdf.

use crate::cells::{CellGrid, Hints};
use crate::error::ValidateError;
use crate::histogram::Histogram;
use crate::report::{Against, Reason, Report};
use crate::sampler::Sampler;
use crate::stats::{chi_square, chi_square_with_lost, spread};
use brdf_core::Brdf;
use brdf_core::geometry::unit_direction_above;
use glam::{DVec3, Vec3};
use quadtree_sampler::DensityHints;
use rand_core::Rng;

/// Samples per chunk of [`Validation::test_chunked`].
pub const CHUNK: u64 = 1 << 16;

/// Histogram and tallies of one run of samples.
struct Counts {
    observed: Vec<u64>,
    lost: u64,
    outside: u64,
    inconsistent: u64,
}

impl Counts {
    fn new(cells: usize) -> Self {
        Self {
            observed: vec![0; cells],
            lost: 0,
            outside: 0,
            inconsistent: 0,
        }
    }

    fn add(&mut self, other: &Self) {
        for (a, b) in self.observed.iter_mut().zip(&other.observed) {
            *a += b;
        }
        self.lost += other.lost;
        self.outside += other.outside;
        self.inconsistent += other.inconsistent;
    }
}

/// A validation set-up for one target density: the cells and their expected mass under
/// f_r·cos, integrated once, independently of any sampler.
#[derive(Clone, Debug)]
pub struct Validation {
    grid: CellGrid,
    /// The absolute tolerance the masses were integrated to.
    tol: f64,
    /// The tolerance the caller asked for, relative to the total (where the masses' total is
    /// not a finite positive number, [`Validation::own_probability`] holds its cells to it).
    rel_tol: f64,
    /// Where every cell's integration cuts its ranges: the model's peaks for wi and their
    /// axis planes (or a caller's peaks and ridge planes, [`Validation::of_fcos_with`]).
    hints: Hints,
    /// ∫ Y(f_r) dA per cell (the seed's I_i, unnormalised).
    mass: Vec<f64>,
}

/// ∫ g dA summed over the coarse 8 × 16 polar grid whose total sets the scale of the
/// masses' and of a sampler's own probabilities' tolerances, each cell to `tol` (∞: the
/// rules' first pieces, unrefined).
fn coarse_total(g: &(dyn Fn(Vec3) -> f64 + Sync), hints: &Hints, tol: f64) -> f64 {
    CellGrid::Polar {
        rings: 8,
        sectors: 16,
    }
    .integrate_all(tol, hints, g)
    .iter()
    .sum()
}

impl Validation {
    /// Integrates the luminance of f_r(wi, ·) over every cell. `tol` is the absolute error
    /// allowed per cell **relative to the total** (1e-7: for 10⁶ samples, 0.1 expected sample
    /// per cell at worst; 10⁸ samples on 100 × 100 cells pass at it too). No part of a cell is
    /// refined below the rounding of the f32 values integrated (an error estimate within
    /// 4·2⁻²⁴ of the part's own integral), so a smaller `tol` costs about what that rounding
    /// allows and no more. `wi` must be above the horizon; the model must have a continuous
    /// part.
    pub fn new<B: Brdf + ?Sized>(
        brdf: &B,
        wi: Vec3,
        grid: CellGrid,
        tol: f64,
    ) -> Result<Self, ValidateError> {
        let wi = unit_direction_above(wi)?;
        grid.check()?;
        if brdf.is_delta() {
            return Err(ValidateError::DeltaModel { model: brdf.name() });
        }
        check_tolerance(tol)?;
        // The model's own peak directions (data of the model, not of any sampler): a lobe
        // narrower than a cell's node spacing is found there (see `integrate::adaptive`).
        let peaks: Vec<DVec3> = brdf
            .peak_hints(brdf_core::geometry::lift_incident(wi))
            .as_slice()
            .iter()
            .map(|h| h.as_dvec3())
            .collect();
        let hints = Hints::of_model(&peaks).with_step(brdf.step_width());
        Ok(Self::integrated(
            &|w: Vec3| f64::from(brdf.eval_luminance(wi, w)),
            hints,
            grid,
            tol,
        ))
    }

    /// The same for a BSDF outside this workspace, given as an oracle: `fcos(wo)` is the
    /// luminance of f_r(wi, wo)·cos θo at the fixed incident direction of the sampler under
    /// test (per unit solid angle; 0 at and below the horizon). `peaks`: directions where it
    /// may peak sharply (a mirror direction; up to four are used), so that a lobe narrower
    /// than the integrator's node spacing is not missed. `tol` as in [`Validation::new`].
    pub fn of_fcos(
        fcos: impl Fn(Vec3) -> f64 + Sync,
        peaks: &[Vec3],
        grid: CellGrid,
        tol: f64,
    ) -> Result<Self, ValidateError> {
        Self::of_fcos_with(fcos, &DensityHints::of_peaks(peaks), grid, tol)
    }

    /// [`Validation::of_fcos`] with ridge planes besides the peaks: `hints.peaks` as `peaks`
    /// there (each with its axis planes x = h.x and y = h.y), and `hints.ridges` the planes
    /// n·w = c a lobe narrow along one axis lies along when that axis is not the frame's
    /// (an anisotropic BSDF whose tangent is rotated about the normal). Both the masses and
    /// the sampler's own cell probabilities are cut there. `hints.step`: for a tabulated BSDF
    /// read by nearest bin, its bins' angular width (see [`DensityHints::step`]).
    pub fn of_fcos_with(
        fcos: impl Fn(Vec3) -> f64 + Sync,
        hints: &DensityHints,
        grid: CellGrid,
        tol: f64,
    ) -> Result<Self, ValidateError> {
        grid.check()?;
        check_tolerance(tol)?;
        let hints = Hints::of_model(&hints.peaks)
            .with(&[], &hints.ridges)
            .with_step(hints.step);
        // Per unit projected area: f·cos dω = f dA.
        let per_area = |w: Vec3| {
            if w.z > 0.0 {
                fcos(w) / f64::from(w.z)
            } else {
                0.0
            }
        };
        Ok(Self::integrated(&per_area, hints, grid, tol))
    }

    /// Integrates `g` (per unit projected area) over the cells to `tol` relative to a coarse
    /// total.
    fn integrated(
        g: &(dyn Fn(Vec3) -> f64 + Sync),
        hints: Hints,
        grid: CellGrid,
        tol: f64,
    ) -> Self {
        // A coarse total sets the absolute scale of the tolerance. It is integrated to 10⁻³
        // of the larger of 1 and a first unrefined estimate (the rules' initial pieces): an
        // f·cos of magnitude 10¹⁰⁰ held to 10⁻³ absolute refined every piece to its limit
        // (24 s for a constant; 10³⁰⁰ everywhere made `check` take 352 s), while every f·cos
        // whose total is at most about 1 keeps the tolerance, and the masses, it had.
        let rough = coarse_total(g, &hints, f64::INFINITY);
        let scale = if rough.is_finite() {
            rough.abs().max(1.0)
        } else {
            1.0
        };
        let coarse = coarse_total(g, &hints, 1e-3 * scale);
        // The coarse grid's nodes can miss a lobe whole (a needle narrower than their
        // spacing, with no peak hint to cut at): its total was then 0, the tolerance 0, and
        // every cell of the grid that did see the lobe was refined to every piece's limit (a
        // needle of 10¹² within 0.08° of the normal: `check` had not finished after 380 s).
        // Where the coarse total is 0 (or not finite), the grid's own unrefined total (its
        // nodes many times as dense) takes over if it is larger; elsewhere it is not
        // computed, and nothing changes. Where neither total is finite (an oracle NaN or
        // infinite over part of the hemisphere), the unrefined cells where it is finite set
        // the scale: a NaN total made the tolerance 10⁻³⁰⁷ absolute, and every finite cell
        // was refined to every piece's limit (NaN on half the disk: 5.6–13 s a `check`, for
        // masses that are not a distribution anyway).
        let total = match coarse.abs() {
            c if c > 0.0 && c.is_finite() => c,
            _ => {
                let cells = grid.integrate_all(f64::INFINITY, &hints, g);
                let fine: f64 = cells.iter().sum();
                if fine.is_finite() && fine.abs() > coarse.abs() {
                    fine.abs()
                } else if coarse.is_finite() {
                    coarse.abs()
                } else {
                    cells
                        .iter()
                        .filter(|m| m.is_finite())
                        .map(|m| m.abs())
                        .sum()
                }
            }
        };
        let abs_tol = tol * total.max(1e-300);
        let mass = grid.integrate_all(abs_tol, &hints, g);
        Self {
            grid,
            tol: abs_tol,
            rel_tol: tol,
            hints,
            mass,
        }
    }

    /// The cells.
    #[must_use]
    pub fn grid(&self) -> CellGrid {
        self.grid
    }

    /// ∫ Y(f_r) dA per cell (the seed's I_i).
    #[must_use]
    pub fn mass(&self) -> &[f64] {
        &self.mass
    }

    /// The probability of every cell under a sampler's reported density `pdf` (**per unit
    /// solid angle**, at the incident direction of this set-up): ∫ pdf dω = ∫ pdf/cos θ dA
    /// over the cell, by the same integrator and break points as the masses, to the same
    /// tolerance relative to a total of 1. What is missing from their sum (at most 1) is the
    /// probability the sampler gives no direction. The second χ² of [`Validation::test`] is
    /// taken against these (with the sampler's own [`Sampler::density_hints`]); a caller that
    /// histograms samples itself (the viewer) can take it too.
    #[must_use]
    pub fn own_probability(&self, pdf: &(dyn Fn(Vec3) -> f64 + Sync)) -> Vec<f64> {
        self.own_probability_with(pdf, &DensityHints::default())
    }

    /// [`Validation::own_probability`], the ranges also cut where `hints` say the density may
    /// be concentrated (a sampler's [`Sampler::density_hints`]): peaks and ridge planes
    /// beyond the model's own, such as a baked sampler's rotated neighbour lobes.
    #[must_use]
    pub fn own_probability_with(
        &self,
        pdf: &(dyn Fn(Vec3) -> f64 + Sync),
        hints: &DensityHints,
    ) -> Vec<f64> {
        let all = self
            .hints
            .with(&hints.peaks, &hints.ridges)
            .with_step(hints.step);
        let total: f64 = self.mass.iter().sum();
        // The masses' tolerance relative to their total; an oracle whose masses overflow (an
        // f·cos of 10³⁰⁰ everywhere: an infinite total) made that 0, and the sampler's cells
        // were refined to every piece's limit (149 s for a cosine sampler).
        let rel = self.tol / total.max(1e-300);
        let rel = if rel.is_finite() && rel > 0.0 {
            rel
        } else {
            self.rel_tol
        };
        let per_area = |w: Vec3| {
            if w.z > 0.0 {
                pdf(w) / f64::from(w.z)
            } else {
                0.0
            }
        };
        // The tolerance is relative to a total of 1, what a density sums to; a sampler that
        // reports a density many times too large (3·10³⁸ everywhere) had its cells refined
        // to every piece's limit: `check` took 424 s. So, as for the masses, a coarse 8 × 16
        // polar grid first: unrefined, and only where that exceeds 2 (a density that sums
        // to 1 may, when a node lands on a needle), refined to 10⁻³ of it; where that total
        // still exceeds 4, the tolerance follows it. A density that sums to 1 keeps its
        // tolerance, and its probabilities, bit for bit.
        let rough = coarse_total(&per_area, &all, f64::INFINITY);
        let rel = if rough.is_finite() && rough > 2.0 {
            let total = coarse_total(&per_area, &all, 1e-3 * rough);
            if total.is_finite() && total > 4.0 {
                rel * total
            } else {
                rel
            }
        } else {
            rel
        };
        self.grid.integrate_all(rel, &all, &per_area)
    }

    /// Draws `samples` directions from `sampler` (which must be for this BRDF and `wi`),
    /// histograms them, and judges them at per-test significance `alpha` (see [`crate::sidak`]).
    /// Serial: one random stream for all samples.
    pub fn test<S: Sampler + ?Sized>(
        &self,
        sampler: &S,
        samples: u64,
        rng: &mut dyn Rng,
        alpha: f64,
    ) -> Report {
        let counts = self.count(sampler, 0..samples, rng);
        self.judge(sampler, samples, counts, alpha)
    }

    /// As [`Validation::test`], with the samples split into chunks of [`CHUNK`] drawn from
    /// their own streams: chunk k (samples k·CHUNK ..) uses `rng_for_chunk(k)`. The chunks
    /// run in parallel with rayon; the counts are summed in chunk order, so
    /// the report is bit-identical to the serial run and does not depend on the thread count.
    pub fn test_chunked<S, R, F>(
        &self,
        sampler: &S,
        samples: u64,
        rng_for_chunk: F,
        alpha: f64,
    ) -> Report
    where
        S: Sampler + ?Sized,
        R: Rng,
        F: Fn(u64) -> R + Sync,
    {
        let chunks = samples.div_ceil(CHUNK);
        let one = |k: u64| {
            let mut rng = rng_for_chunk(k);
            self.count(sampler, k * CHUNK..samples.min((k + 1) * CHUNK), &mut rng)
        };
        let parts: Vec<Counts> = {
            use rayon::prelude::*;
            (0..chunks).into_par_iter().map(one).collect()
        };
        let mut total = Counts::new(self.grid.len());
        for p in &parts {
            total.add(p);
        }
        self.judge(sampler, samples, total, alpha)
    }

    /// Histograms the samples with indices in `range` (the index decides which samples get
    /// the consistency check: every one of the first 10⁴, then one in 64).
    fn count<S: Sampler + ?Sized>(
        &self,
        sampler: &S,
        range: std::ops::Range<u64>,
        rng: &mut dyn Rng,
    ) -> Counts {
        let mut c = Counts::new(self.grid.len());
        for k in range {
            let Some(s) = sampler.draw(rng) else {
                c.lost += 1;
                continue;
            };
            let Some(cell) = (!s.delta).then(|| self.grid.cell_of(s.wo)).flatten() else {
                c.outside += 1;
                continue;
            };
            c.observed[cell] += 1;
            if k < 10_000 || k % 64 == 0 {
                let p = sampler.pdf(s.wo);
                let ok_pdf = (p - s.pdf).abs() <= 1e-4 * s.pdf.abs().max(p.abs());
                let ok_w = s.f_and_weight.is_none_or(|(f, weight)| {
                    let w = f * s.wo.z / s.pdf;
                    (weight - w).abs() <= 1e-4 * w.abs() + 1e-30
                });
                if !(ok_pdf && ok_w) {
                    c.inconsistent += 1;
                }
            }
        }
        c
    }

    /// Judges histogrammed counts.
    fn judge<S: Sampler + ?Sized>(
        &self,
        sampler: &S,
        samples: u64,
        counts: Counts,
        alpha: f64,
    ) -> Report {
        let mut reasons: Vec<Reason> = Vec::new();
        let total: f64 = self.mass.iter().sum();
        if !(total > 0.0 && total.is_finite()) || self.mass.iter().any(|&x| x.is_nan() || x < 0.0) {
            reasons.push(Reason::MassesNotADistribution { total });
        }
        let Counts {
            observed,
            lost,
            outside,
            inconsistent,
        } = counts;
        let m = samples as f64;
        let expected: Vec<f64> = self.mass.iter().map(|x| m * x / total).collect();
        let in_empty_cells: u64 = observed
            .iter()
            .zip(&expected)
            .filter(|&(_, &e)| e <= 0.0)
            .map(|(&o, _)| o)
            .sum();
        // χ² against f·cos: lost and outside samples have an expectation of 0 there.
        let chi2 = chi_square(&observed, &expected);
        // χ² against the sampler's own pdf.
        let own = self.own_probability_with(
            &|w: Vec3| f64::from(sampler.pdf(w)),
            &sampler.density_hints(),
        );
        let own_total: f64 = own.iter().sum();
        let chi2_own = chi_square_with_lost(&observed, lost, samples, &own);
        let expected_own: Vec<f64> = own.iter().map(|x| m * x).collect();
        if own_total > 1.0 + crate::stats::NORMALISATION_TOLERANCE {
            reasons.push(Reason::PdfAboveOne {
                integral: own_total,
            });
        }
        for (against, test) in [(Against::FCos, &chi2), (Against::OwnPdf, &chi2_own)] {
            match test {
                None => reasons.push(Reason::TooFewDegreesOfFreedom { against }),
                Some(c) if c.p_value.is_nan() || c.p_value < alpha => {
                    reasons.push(Reason::ChiSquare {
                        against,
                        statistic: c.statistic,
                        dof: c.dof,
                        p_value: c.p_value,
                        alpha,
                    });
                }
                Some(_) => {}
            }
        }
        if samples > 0 && lost == samples {
            reasons.push(Reason::AllLost { samples });
        } else if lost > 0 {
            reasons.push(Reason::Lost { count: lost });
        }
        if outside > 0 {
            reasons.push(Reason::Outside { count: outside });
        }
        if in_empty_cells > 0 {
            reasons.push(Reason::InEmptyCells {
                count: in_empty_cells,
            });
        }
        if inconsistent > 0 {
            reasons.push(Reason::Inconsistent {
                count: inconsistent,
            });
        }
        Report {
            sampler: sampler.name().to_string(),
            samples,
            spread: spread(&observed, &self.mass, &expected, m),
            histogram: Histogram {
                grid: self.grid,
                observed,
                expected,
                expected_own: Some(expected_own),
                mass: self.mass.clone(),
            },
            lost,
            outside,
            inconsistent,
            in_empty_cells,
            chi2,
            chi2_own,
            alpha,
            reasons,
        }
    }
}

fn check_tolerance(tol: f64) -> Result<(), ValidateError> {
    if tol > 0.0 && tol < 1.0 {
        Ok(())
    } else {
        Err(ValidateError::Tolerance { value: tol })
    }
}
