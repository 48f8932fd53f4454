//! The tabulated baseline that renderers use today: a piecewise-constant 2D distribution
//! (marginal over rows, conditional within each row) over the concentric square, as in pbrt's
//! `PiecewiseConstant2D` or Mitsuba's `DiscreteDistribution2D`.
//!
//! The concentric map takes uniform area on the square to uniform area on the disk, so a
//! density ∝ f_r on the square is ∝ f_r·cos θ on the hemisphere, the same target as the
//! quadtree. Each cell's value is the mean luminance of f_r at 2 × 2 interior points, floored
//! at 10⁻³ of the mean cell value so no direction where f_r > 0 has density 0 (the estimator
//! stays unbiased when a lobe falls between the points). The result is exact for its own
//! pdf and only approximately ∝ f·cos.

use crate::error::BuildError;
use crate::sampler::{DirectionSampler, Sample, uniform_f64};
use alloc::sync::Arc;
use alloc::vec::Vec;
use brdf_core::geometry::unit_direction_above;
use brdf_core::{Brdf, BrdfSample, DiskMap};
use glam::{Vec2, Vec3};
use rand_core::Rng;

/// Cells per side of the renderers' usual table (256² cells).
pub const DEFAULT_TABLE_RES: usize = 256;

/// A piecewise-constant distribution over `res × res` cells of the concentric square for one
/// incident direction.
#[derive(Clone, Debug)]
pub struct TableSampler<B: Brdf = Arc<dyn Brdf>> {
    brdf: B,
    wi: Vec3,
    res: usize,
    /// Cell values (mean luminance of f_r, floored), row-major, row = v.
    cells: Vec<f32>,
    /// The marginal CDF over rows, `res + 1` entries from 0 to 1.
    marginal: Vec<f64>,
    /// Per row, the conditional CDF over its cells (`res + 1` entries each, 0 to 1).
    conditional: Vec<f32>,
    /// Density per unit square area of a cell of value 1: 1 / (Σ values · cell area).
    scale: f64,
}

impl<B: Brdf> TableSampler<B> {
    /// Tabulates f_r(wi, ·) on `res × res` cells (`res` in [1, 4096]; 4·res² evaluations).
    pub fn new(brdf: B, wi: Vec3, res: usize) -> Result<Self, BuildError> {
        let wi = unit_direction_above(wi)?;
        if brdf.is_delta() {
            return Err(BuildError::DeltaModel { model: brdf.name() });
        }
        if !(1..=4096).contains(&res) {
            return Err(BuildError::OutOfRange {
                option: "table resolution",
                value: res as f64,
                expected: "in [1, 4096]",
            });
        }
        let h = 2.0 / res as f64;
        let mut cells = Vec::with_capacity(res * res);
        for iy in 0..res {
            for ix in 0..res {
                let mut sum = 0.0f64;
                for (dx, dy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                    let p = Vec2::new(
                        (-1.0 + h * (ix as f64 + dx)) as f32,
                        (-1.0 + h * (iy as f64 + dy)) as f32,
                    );
                    if let Some(wo) = DiskMap::Concentric.square_to_direction(p) {
                        let y = f64::from(brdf.eval_luminance(wi, wo));
                        if y.is_finite() && y > 0.0 {
                            sum += y;
                        }
                    }
                }
                cells.push(0.25 * sum);
            }
        }
        let mean = cells.iter().sum::<f64>() / cells.len() as f64;
        if !(mean > 0.0 && mean.is_finite()) {
            return Err(BuildError::ZeroBrdf { model: brdf.name() });
        }
        let floor = 1e-3 * mean;
        let cells: Vec<f32> = cells.iter().map(|&c| c.max(floor) as f32).collect();
        let mut marginal = Vec::with_capacity(res + 1);
        let mut conditional = Vec::with_capacity(res * (res + 1));
        let mut total = 0.0f64;
        marginal.push(0.0);
        let mut row_sums = Vec::with_capacity(res);
        for row in cells.chunks_exact(res) {
            let row_sum: f64 = row.iter().map(|&c| f64::from(c)).sum();
            let mut acc = 0.0f64;
            conditional.push(0.0);
            for &c in row {
                acc += f64::from(c);
                conditional.push((acc / row_sum) as f32);
            }
            *conditional.last_mut().expect("a row") = 1.0;
            total += row_sum;
            row_sums.push(total);
        }
        marginal.extend(row_sums.iter().map(|&s| s / total));
        *marginal.last_mut().expect("rows") = 1.0;
        Ok(Self {
            brdf,
            wi,
            res,
            cells,
            marginal,
            conditional,
            scale: 1.0 / (total * h * h),
        })
    }

    /// Cells per side.
    #[must_use]
    pub fn resolution(&self) -> usize {
        self.res
    }

    /// Bytes of the table (values and CDFs).
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.cells.len() * 4 + self.marginal.len() * 8 + self.conditional.len() * 4
    }

    /// Draws one direction: a row from the marginal, a cell from its conditional, a uniform
    /// point inside the cell (both by continuous inversion of the same two numbers).
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> Option<Sample> {
        let (u, v) = (uniform_f64(rng), uniform_f64(rng));
        self.sample_from(u, v)
    }

    /// [`TableSampler::sample`] from explicit uniforms `u` (the column) and `v` (the row), in
    /// [0, 1). Draws no other numbers.
    #[must_use]
    pub fn sample_from(&self, u: f64, v: f64) -> Option<Sample> {
        // Into [0, 1): a NaN (which `clamp` keeps) to 0.
        let unit = |x: f64| {
            if x > 0.0 {
                x.min(1.0 - f64::EPSILON)
            } else {
                0.0
            }
        };
        let (u, v) = (unit(u), unit(v));
        let res = self.res;
        // Row: the last k with marginal[k] <= v (marginal[0] = 0 ≤ v).
        let row = (self.marginal.partition_point(|&c| c <= v).saturating_sub(1)).min(res - 1);
        let (c0, c1) = (self.marginal[row], self.marginal[row + 1]);
        let fy = ((v - c0) / (c1 - c0)).clamp(0.0, 1.0);
        let cdf = &self.conditional[row * (res + 1)..(row + 1) * (res + 1)];
        let uf = u as f32;
        let col = (cdf.partition_point(|&c| c <= uf).saturating_sub(1)).min(res - 1);
        let (d0, d1) = (f64::from(cdf[col]), f64::from(cdf[col + 1]));
        let fx = ((u - d0) / (d1 - d0)).clamp(0.0, 1.0);
        let h = 2.0 / res as f64;
        let p = Vec2::new(
            (-1.0 + h * (col as f64 + fx)) as f32,
            (-1.0 + h * (row as f64 + fy)) as f32,
        );
        let wo = DiskMap::Concentric.square_to_direction(p)?;
        // The pdf of the returned f32 direction, by the same expression as `pdf`.
        let pdf = self.pdf(wo);
        BrdfSample::continuous(wo, self.brdf.eval(self.wi, wo), pdf)
    }

    /// Density per unit solid angle: the cell's value × `scale` per unit square area, times
    /// the concentric map's Jacobian and cos θ.
    #[must_use]
    pub fn pdf(&self, wo: Vec3) -> f32 {
        // Not an f32 normalisation: of a tiny vector it divides by 0.
        let Some(wo) = brdf_core::geometry::unit_for_density(wo).filter(|w| w.z > 0.0) else {
            return 0.0;
        };
        let p = DiskMap::Concentric.direction_to_square(wo);
        let cell =
            |t: f32| (((f64::from(t) + 1.0) * 0.5 * self.res as f64) as usize).min(self.res - 1);
        let value = f64::from(self.cells[cell(p.y) * self.res + cell(p.x)]);
        DiskMap::Concentric.square_pdf_to_solid_angle((value * self.scale) as f32, wo.z)
    }
}

impl<B: Brdf> DirectionSampler for TableSampler<B> {
    fn name(&self) -> &'static str {
        "table"
    }

    fn sample_with(&self, _uc: f32, u: Vec2, _rng: &mut dyn Rng) -> Option<Sample> {
        self.sample_from(f64::from(u.x), f64::from(u.y))
    }

    fn sample(&self, rng: &mut dyn Rng) -> Option<Sample> {
        TableSampler::sample(self, rng)
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        TableSampler::pdf(self, wo)
    }
}
