//! Whether a baked sampler's grid is fine enough for its material: how much an off-grid
//! sample is worth against an exact one, measured where the mixture is farthest from its
//! trees ([`BakedSampler::coverage`]).
//!
//! Between grid rows (and columns) a query draws from its neighbours' trees carried onto it
//! (rotated onto its mirror direction, or by the half-vector transport: `baked_mixture`).
//! That is exact (the pdf says what was drawn) but only as efficient as the carried
//! neighbours are alike to the query's own density T ∝ Y(f_r)·cos θ: a lobe that changes
//! shape faster than the grid follows (a sharp anisotropic lobe on a coarse grid) may lie
//! where no neighbour puts its own, and only the defensive share draws it. The estimator
//! stays unbiased and becomes useless. Measured, while anisotropic grids rotated their
//! trees: Poulin–Fournier n = 28 190 on a 5 × 2 grid gave a mean weight of a third of its
//! albedo at 3·10⁵ samples, and its own-pdf χ² passed.
//!
//! The number that says so is the weight's relative second moment under uniform light,
//! R = ∫ T²/p dω (T and the mixture's density p both normalised), the variance of a furnace
//! estimate being (R − 1)·albedo²/N: 1 for a sampler exact ∝ T, and 1/R is what one baked
//! sample is worth against one exact sample. It is measured at the centre of every cell of
//! the grid (and halfway from the last row to the horizon), both modes, each role the
//! sampler bakes, by drawing from a tree built at that very wi (exact ∝ T, so the estimate
//! sees every part of T, the parts p misses included): R ≈ mean of T/p over its samples.
//! The band within 6° of the horizon is also integrated by a rule (rows crowded toward the
//! horizon), and its share of R is the larger of the two estimates: a tree carried onto a
//! query leaves a thin band there that only the defensive share covers where no other
//! neighbour does, and the samples rarely reach it (Schlick r = 0.01 with snapped cells:
//! R = 32–58, reported as 1.03 from 2 048 samples; 253 with the band integrated).
//!
//! The check trees are built looser than a bake's (integration tolerance 10⁻³, split below
//! acceptance 0.1: a fraction of a grid tree's cost); their v1 set which leaf is drawn, so a
//! check tree is ∝ T within about that tolerance, far below what the check judges. Measured
//! (2 048 samples a cell): phong n = 1000 on the default grid, R ≤ 1.04 in rejection mode;
//! every bench set on its default grid ≤ 1.50 (rejection) and ≤ 1.81 (warp);
//! Poulin–Fournier's specular part alone, n = 28 190, on 5 × 2, R up to 2.3·10⁵ (rejection)
//! and 62 (warp), and 4·10⁷ to 7·10⁸ at every cell while anisotropic grids rotated their
//! trees (see `baked_mixture`'s half-vector transport, which this check found was needed).

use crate::bake_grid::PhiDomain;
use crate::baked::{Adjoint, BakedMode, BakedSampler, GRID_THETA_MAX_DEG, Role};
use crate::baked_nearest::band_directions;
use crate::config::BuildConfig;
use crate::sampler::{QuadtreeSampler, uniform_f64};
use alloc::vec::Vec;
use brdf_core::Brdf;
use brdf_core::math as m;
use glam::DVec3;
use rand_core::{Rng, SeedableRng};

/// Default samples drawn at each checked wi: 2 048 (the standard error of R is then about
/// 1 % where R ≈ 1.4; a missed lobe shows as R of 10³ and more).
pub const DEFAULT_COVERAGE_SAMPLES: u32 = 2048;

/// The most samples a coverage check draws at one wi (a typed error beyond): 2²⁰.
pub const MAX_COVERAGE_SAMPLES: u32 = 1 << 20;

/// The relative second moment above which a cell is reported as poorly covered: 4, where a
/// baked sample is worth less than a quarter of an exact one under uniform light. The glossy
/// sets on the default grid stay under 1.5 in rejection mode (see the module doc).
pub const COVERAGE_LIMIT: f64 = 4.0;

/// The band along the horizon, in degrees of elevation, that a check integrates instead of
/// sampling (see `horizon_band`): twice the default grid's θ step.
const BAND_DEG: f64 = 6.0;

/// Rows (in the square root of the elevation) and columns (in φ) of the band's rule.
const BAND_ROWS: usize = 16;
const BAND_COLUMNS: usize = 64;

/// A check tree's integration tolerance (see the module doc).
const CHECK_TOLERANCE: f64 = 1e-3;

/// A check tree's split threshold: E\[T\] ≤ 10 per check sample.
const CHECK_SPLIT: f64 = 0.1;

/// How a coverage check samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CoverageConfig {
    /// Samples at each checked wi, 1 to [`MAX_COVERAGE_SAMPLES`].
    pub samples: u32,
    /// The seed of every checked wi's random numbers (each wi seeds its own generator from
    /// this and its index, so serial and parallel checks agree bit for bit).
    pub seed: u64,
}

impl CoverageConfig {
    /// A typed error for a sample count out of [1, [`MAX_COVERAGE_SAMPLES`]].
    fn checked(&self) -> Result<(), crate::BakedError> {
        if (1..=MAX_COVERAGE_SAMPLES).contains(&self.samples) {
            Ok(())
        } else {
            Err(crate::BakedError::CoverageSamples(self.samples))
        }
    }
}

impl Default for CoverageConfig {
    fn default() -> Self {
        Self {
            samples: DEFAULT_COVERAGE_SAMPLES,
            seed: 0x00c0_7e7a_9e00,
        }
    }
}

/// The coverage of one checked wi.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellCoverage {
    /// θ of the checked wi, degrees (a cell's centre, or halfway from the last row to 90°).
    pub theta_deg: f64,
    /// φ of the checked wi, degrees (0 on an isotropic grid).
    pub phi_deg: f64,
    /// The role whose trees were checked.
    pub role: Role,
    /// The check tree's albedo at this wi (∫ Y(f_r)·cos θ dω): how much the cell matters.
    pub albedo: f64,
    /// R in rejection mode (see the module doc); `None` where no check tree could be built
    /// or the model reflects nothing here.
    pub rejection: Option<f64>,
    /// R in warp mode.
    pub warp: Option<f64>,
}

impl CellCoverage {
    /// R in `mode`.
    #[must_use]
    pub fn in_mode(&self, mode: BakedMode) -> Option<f64> {
        match mode {
            BakedMode::Rejection => self.rejection,
            BakedMode::Warp => self.warp,
        }
    }
}

/// A coverage check's result ([`BakedSampler::coverage`]): one entry per checked wi and role.
#[derive(Clone, Debug, PartialEq)]
pub struct Coverage {
    /// The checked wi, row-major (θ cells, then φ cells), the forward role's first.
    pub cells: Vec<CellCoverage>,
    /// Samples drawn at each.
    pub samples: u32,
}

impl Coverage {
    /// The cell of largest R in `mode` (a cell without a measurement is skipped).
    #[must_use]
    pub fn worst(&self, mode: BakedMode) -> Option<&CellCoverage> {
        self.cells
            .iter()
            .filter(|c| c.in_mode(mode).is_some())
            .max_by(|a, b| {
                let (a, b) = (a.in_mode(mode), b.in_mode(mode));
                a.partial_cmp(&b).unwrap_or(core::cmp::Ordering::Equal)
            })
    }

    /// How many cells exceed `limit` in `mode` (R > limit, or R not finite).
    #[must_use]
    pub fn above(&self, mode: BakedMode, limit: f64) -> usize {
        self.cells
            .iter()
            .filter(|c| c.in_mode(mode).is_some_and(|r| r > limit || r.is_nan()))
            .count()
    }

    /// How many checked wi had no check tree (its build failed) or nothing to reflect.
    #[must_use]
    pub fn unmeasured(&self) -> usize {
        self.cells.iter().filter(|c| c.rejection.is_none()).count()
    }
}

impl BakedSampler {
    /// Checks how well the grid covers the material between its trees (see the module doc):
    /// at the centre of every cell and halfway from the last row to the horizon, for each
    /// role the sampler bakes, the weight's relative second moment R in both modes, from
    /// `config.samples` draws of a tree built at that wi. A pure function of the sampler,
    /// `config` and the generator type; in parallel with rayon where the bake's build
    /// options say so (bit-identical). It costs a fraction of the bake (a looser tree and
    /// the samples per cell): measured on the bench sets' default grids, 3–35 % (3–7 % for
    /// Poulin–Fournier's, 35 % for a MERL table's, whose 1° steps make each tree costly).
    pub fn coverage<R: Rng + SeedableRng>(
        &self,
        config: CoverageConfig,
    ) -> Result<Coverage, crate::BakedError> {
        self.coverage_with_progress::<R>(config, &|_, _| {})
    }

    /// [`BakedSampler::coverage`], calling `progress(done, total)` as cells finish.
    pub fn coverage_with_progress<R: Rng + SeedableRng>(
        &self,
        config: CoverageConfig,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Coverage, crate::BakedError> {
        config.checked()?;
        let points = self.check_points();
        let roles: &[Role] = if self.adjoint.is_some() {
            &[Role::Importance, Role::Radiance]
        } else {
            &[Role::Importance]
        };
        let jobs: Vec<(Role, usize)> = roles
            .iter()
            .flat_map(|&r| (0..points.len()).map(move |k| (r, k)))
            .collect();
        let total = jobs.len();
        let done = core::sync::atomic::AtomicUsize::new(0);
        let one = |(k, &(role, p)): (usize, &(Role, usize))| {
            let (t, f) = (points[p].0.to_radians(), points[p].1.to_radians());
            let given = DVec3::new(m::sin(t) * m::cos(f), m::sin(t) * m::sin(f), m::cos(t))
                .as_vec3()
                .normalize();
            let c = self.check_one::<R>(role, given, points[p], config, k as u64);
            let d = done.fetch_add(1, core::sync::atomic::Ordering::Relaxed) + 1;
            progress(d, total);
            c
        };
        #[cfg(feature = "rayon")]
        let cells: Vec<CellCoverage> = if self.config.build.parallel {
            use rayon::prelude::*;
            jobs.par_iter().enumerate().map(one).collect()
        } else {
            jobs.iter().enumerate().map(one).collect()
        };
        #[cfg(not(feature = "rayon"))]
        let cells: Vec<CellCoverage> = jobs.iter().enumerate().map(one).collect();
        Ok(Coverage {
            cells,
            samples: config.samples,
        })
    }

    /// R at one given direction (local frame; checked: finite, non-zero, above the horizon)
    /// for a role, both modes, from `config.samples` draws of a tree built there: what
    /// [`BakedSampler::coverage`] measures at its cells, anywhere (`brdf test --baked` reports
    /// it at the directions it tests). Its generator is seeded by `config.seed` alone.
    pub fn coverage_at<R: Rng + SeedableRng>(
        &self,
        role: Role,
        given: glam::Vec3,
        config: CoverageConfig,
    ) -> Result<CellCoverage, crate::BakedError> {
        let given = brdf_core::geometry::unit_direction_above(given)?;
        config.checked()?;
        let g = given.as_dvec3();
        let angles = (
            m::acos(g.z.clamp(-1.0, 1.0)).to_degrees(),
            m::atan2(g.y, g.x).to_degrees(),
        );
        Ok(self.check_one::<R>(role, given, angles, config, 0))
    }

    /// The checked (θ, φ) in degrees: every cell's centre, row-major, then the band beyond
    /// the last row (θ halfway to 90°) at each φ cell's centre.
    fn check_points(&self) -> Vec<(f64, f64)> {
        let thetas = self.grid.thetas_deg();
        let phis = self.grid.phis_deg();
        let phi_centres: Vec<f64> = match self.grid.domain() {
            PhiDomain::Rotation => alloc::vec![0.0],
            PhiDomain::Circle => (0..phis.len())
                .map(|j| {
                    let next = if j + 1 < phis.len() {
                        phis[j + 1]
                    } else {
                        phis[0] + 360.0
                    };
                    0.5 * (phis[j] + next)
                })
                .collect(),
            _ => phis.windows(2).map(|p| 0.5 * (p[0] + p[1])).collect(),
        };
        let theta_centres = thetas
            .windows(2)
            .map(|t| 0.5 * (t[0] + t[1]))
            .chain(core::iter::once(0.5 * (GRID_THETA_MAX_DEG + 90.0)));
        theta_centres
            .flat_map(|t| phi_centres.iter().map(move |&p| (t, p)))
            .collect()
    }

    /// One checked wi: a check tree there, and R in both modes from its samples.
    fn check_one<R: Rng + SeedableRng>(
        &self,
        role: Role,
        given: glam::Vec3,
        (theta_deg, phi_deg): (f64, f64),
        config: CoverageConfig,
        index: u64,
    ) -> CellCoverage {
        let mut cell = CellCoverage {
            theta_deg,
            phi_deg,
            role,
            albedo: 0.0,
            rejection: None,
            warp: None,
        };
        let build = BuildConfig {
            integration_tolerance: self.config.build.integration_tolerance.max(CHECK_TOLERANCE),
            split_threshold: CHECK_SPLIT,
            target_trials: None,
            parallel: false,
            ..self.config.build
        };
        let adjoint = Adjoint(&*self.brdf);
        let model: &dyn Brdf = match role {
            Role::Importance => &*self.brdf,
            Role::Radiance => &adjoint,
        };
        let Ok(tree) = QuadtreeSampler::new(model, given, build) else {
            return cell;
        };
        cell.albedo = tree.albedo();
        if cell.albedo.is_nan() || cell.albedo <= 0.0 {
            return cell;
        }
        // Each checked wi its own generator: a function of the seed and its index alone.
        let mut rng = R::seed_from_u64(config.seed ^ index.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        let n = config.samples;
        // Sums of T/p per mode, apart in the band along the horizon and above it.
        let (mut above, mut band, mut drawn) = ([0.0; 2], [0.0; 2], 0u32);
        let band_top = m::sin(BAND_DEG.to_radians());
        for i in 0..n {
            // Stratified descents: the leaves in proportion, the trials from the generator.
            let u = (f64::from(i) + uniform_f64(&mut rng)) / f64::from(n);
            let Some(s) = tree.sample_from(u.min(1.0 - f64::EPSILON / 2.0), &mut rng) else {
                continue;
            };
            drawn += 1;
            let t = f64::from(s.pdf);
            let sums = if f64::from(s.wo.z) < band_top {
                &mut band
            } else {
                &mut above
            };
            for (sum, q) in sums.iter_mut().zip(self.both_densities(role, given, s.wo)) {
                *sum += if q > 0.0 { t / q } else { f64::INFINITY };
            }
        }
        if drawn > 0 {
            // The band's share: the larger of its sampled and its integrated estimate. The
            // samples see a lobe that lies in the band (at θi = 89.5° a sharp mirror lobe
            // does, finer than the rule's rows); the rule sees a thin part of T that the
            // mixture leaves to its defensive share, which the samples rarely reach.
            let n = f64::from(drawn);
            let rule = self.horizon_band(&tree, role, given, BAND_DEG.to_radians());
            let r = |k: usize| above[k] / n + (band[k] / n).max(rule[k]);
            cell.rejection = Some(r(0));
            cell.warp = Some(r(1));
        }
        cell
    }

    /// The mixture's density at `w` in each mode, rejection then warp (the order of the
    /// check's sums), per unit solid angle.
    fn both_densities(&self, role: Role, given: glam::Vec3, w: glam::Vec3) -> [f64; 2] {
        [BakedMode::Rejection, BakedMode::Warp]
            .map(|mode| f64::from(self.pdf_unit_in(mode, role, given, w)))
    }

    /// ∫ T²/p dω over the band of elevations below `top` (radians), per mode, T the check
    /// tree's density: by a midpoint rule in φ and in the square root of the elevation
    /// (rows crowd toward the horizon, where a tree carried onto a query leaves the band
    /// it cannot reach). Sampled, such a band escapes the check: the samples of its tail
    /// are rare (Schlick r = 0.01 had R = 32–58 at snapped queries from 5·10⁻⁵ of T's mass
    /// weighing 10⁶ times its due, and 2 048 samples reported 1.03).
    fn horizon_band(
        &self,
        tree: &QuadtreeSampler<&dyn Brdf>,
        role: Role,
        given: glam::Vec3,
        top: f64,
    ) -> [f64; 2] {
        // e = top·x², x at the row's midpoint: de = 2·top·x dx.
        let rows = (0..BAND_ROWS).map(|i| {
            let x = (i as f64 + 0.5) / BAND_ROWS as f64;
            (top * x * x, 2.0 * top * x / BAND_ROWS as f64)
        });
        let mut sums = [0.0; 2];
        for (w, dw) in band_directions(rows, BAND_COLUMNS) {
            let w = w.as_vec3();
            let t = f64::from(tree.pdf(w));
            if t.is_nan() || t <= 0.0 {
                continue;
            }
            for (sum, q) in sums.iter_mut().zip(self.both_densities(role, given, w)) {
                *sum += if q > 0.0 {
                    t * t / q * dw
                } else {
                    f64::INFINITY
                };
            }
        }
        sums
    }
}

/// The check's tests live with the bake's (`tests/baked.rs`); these pin its geometry.
#[cfg(test)]
mod tests {
    use super::*;
    use crate::BakeConfig;
    use alloc::sync::Arc;

    /// A mixture that leaves a thin band along the horizon to its defensive share is
    /// reported: Schlick r = 0.01 with every cell snapped to one tree (what the bake's snap
    /// measure allowed before it integrated that band) leaves each tree's tilt band with
    /// f·cos θ in it; rejection mode is flagged at most cells, warp mode (which blends) at
    /// none. Sampled alone (2 048 samples a cell), the bake that snapped 10 cells reported
    /// every cell under 1.03 where the true R was 32–58, and with every cell forced to
    /// snap 8 of 31 were flagged.
    #[test]
    fn a_band_left_to_the_defensive_share_is_reported() {
        let schlick = brdf_core::registry::create("schlick", ["r=0.01"]).unwrap();
        let mut baked = BakedSampler::new(Arc::from(schlick), BakeConfig::default()).unwrap();
        let cells = baked.grid.cells();
        baked.forward.nearest.theta = alloc::vec![true; cells];
        let config = CoverageConfig::default();
        let cov = baked.coverage::<rand_pcg::Pcg64>(config).unwrap();
        let flagged = cov.above(BakedMode::Rejection, COVERAGE_LIMIT);
        assert!(
            flagged >= cells / 2,
            "{flagged} of {cells}: {:?}",
            cov.cells
        );
        assert_eq!(
            cov.above(BakedMode::Warp, COVERAGE_LIMIT),
            0,
            "{:?}",
            cov.cells
        );
    }

    #[test]
    fn check_points_are_the_cell_centres_and_the_band_beyond() {
        let ward = brdf_core::registry::create("ward", ["alpha_x=0.3", "alpha_y=0.6"]).unwrap();
        let config = BakeConfig {
            theta_steps: 3,
            phi_steps: 3,
            ..BakeConfig::default()
        };
        let baked = BakedSampler::new(Arc::from(ward), config).unwrap();
        let p = baked.check_points();
        // Rows 0°, 44.5°, 89°; columns 0°, 45°, 90° (the quadrant).
        let want = [
            (22.25, 22.5),
            (22.25, 67.5),
            (66.75, 22.5),
            (66.75, 67.5),
            (89.5, 22.5),
            (89.5, 67.5),
        ];
        assert_eq!(p.len(), want.len());
        for ((t, f), (wt, wf)) in p.iter().zip(want) {
            assert!((t - wt).abs() < 1e-9 && (f - wf).abs() < 1e-9, "{t} {f}");
        }
    }
}
