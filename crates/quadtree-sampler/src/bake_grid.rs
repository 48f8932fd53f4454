//! The grid of incident directions a [`crate::BakedSampler`] bakes trees at (SPEC §7): θi
//! rows to [`crate::GRID_THETA_MAX_DEG`], φi columns over the [`PhiDomain`] the model's
//! declared symmetries leave, each wi folded into that domain; the neighbour weights of any
//! wi (linear in θ; in (θ, φ) linear on the two triangles of each cell, snapped to the
//! nearest tree along an axis in the cells where the bake measured that its neighbours
//! agree: [`Nearest`]); and the rotations that carry a neighbour's tree onto wi's mirror
//! direction (the isotropic ones written out).

use crate::baked::{GRID_THETA_MAX_DEG, MAX_TREES};
use crate::error::BakeError;
use alloc::vec::Vec;
use brdf_core::Symmetry;
use brdf_core::math as m;
use core::f64::consts::{FRAC_PI_2, PI, TAU};
use glam::{DMat3, DQuat, DVec3, Vec3};

/// The part of the φi circle a grid covers, from the model's declared symmetries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PhiDomain {
    /// Isotropic: one row, φi = 0; any wi is rotated about z onto it.
    Rotation,
    /// Mirror-symmetric in x and y: φi ∈ [0°, 90°] (wi reflected into x, y ≥ 0).
    Quadrant,
    /// Mirror-symmetric in y only: φi ∈ [0°, 180°] (wi reflected into y ≥ 0).
    UpperHalf,
    /// Mirror-symmetric in x only: φi ∈ [−90°, 90°] (wi reflected into x ≥ 0).
    RightHalf,
    /// No symmetry: the whole circle, periodic.
    Circle,
}

impl PhiDomain {
    /// The domain a model's symmetries allow.
    #[must_use]
    pub fn of(s: Symmetry) -> Self {
        match (s.isotropic, s.mirror_x, s.mirror_y) {
            (true, _, _) => Self::Rotation,
            (false, true, true) => Self::Quadrant,
            (false, false, true) => Self::UpperHalf,
            (false, true, false) => Self::RightHalf,
            (false, false, false) => Self::Circle,
        }
    }

    /// Its φ interval in radians (`Circle`: [0, 2π), periodic).
    pub(crate) fn range(self) -> (f64, f64) {
        match self {
            Self::Rotation => (0.0, 0.0),
            Self::Quadrant => (0.0, FRAC_PI_2),
            Self::UpperHalf => (0.0, PI),
            Self::RightHalf => (-FRAC_PI_2, FRAC_PI_2),
            Self::Circle => (0.0, TAU),
        }
    }

    /// The orthogonal map F (a rotation about z or reflections) that brings `w` into the
    /// domain; F is its own kind of symmetry of f_r, so f_r(F wi, F wo) = f_r(wi, wo).
    /// (The mixture applies it in parts: the isotropic fold written out, the others as
    /// their [`PhiDomain::reflection`]; the tests hold those to this matrix.)
    #[cfg(test)]
    pub(crate) fn fold(self, w: DVec3) -> DMat3 {
        match self {
            Self::Rotation => {
                let r = m::sqrt(w.x * w.x + w.y * w.y);
                if r == 0.0 {
                    DMat3::IDENTITY
                } else {
                    // The rotation about z by −φ, from cos φ and sin φ without trigonometry.
                    let (c, s) = (w.x / r, w.y / r);
                    DMat3::from_cols(DVec3::new(c, -s, 0.0), DVec3::new(s, c, 0.0), DVec3::Z)
                }
            }
            _ => DMat3::from_diagonal(self.reflection(w)),
        }
    }

    /// The fold of a domain other than [`PhiDomain::Rotation`] (a reflection in x, in y, in
    /// both, or none) as the diagonal of its matrix: ±1 per axis. (It is its own inverse.)
    pub(crate) fn reflection(self, w: DVec3) -> DVec3 {
        let sx = if w.x < 0.0 { -1.0 } else { 1.0 };
        let sy = if w.y < 0.0 { -1.0 } else { 1.0 };
        match self {
            Self::Quadrant => DVec3::new(sx, sy, 1.0),
            Self::UpperHalf => DVec3::new(1.0, sy, 1.0),
            Self::RightHalf => DVec3::new(sx, 1.0, 1.0),
            Self::Rotation | Self::Circle => DVec3::ONE,
        }
    }
}

/// The grid of incident directions of a bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeGrid {
    domain: PhiDomain,
    /// θi of each row, radians, uniform from 0 to [`GRID_THETA_MAX_DEG`].
    thetas: Vec<f64>,
    /// φi of each column, radians.
    phis: Vec<f64>,
    /// 1/(θ step): rows per radian, so a query's row position is one multiply.
    rows_per_radian: f64,
    /// cos θ of a direction 10⁻³ rad before the last row: above it no direction is beyond
    /// the last row, whatever `fast_acos`'s error (7·10⁻⁵), so most queries skip its arc
    /// cosine (derived).
    within_z: f64,
    /// [`BakeGrid::beyond_last_row`] is θ·`beyond_scale` − `beyond_offset`: in row spacings
    /// (`rows_per_radian` and the last row's index) on a grid as fine as the default one or
    /// finer; in the default grid's spacings past the last row on a coarser one (derived).
    beyond_scale: f64,
    beyond_offset: f64,
}

impl BakeGrid {
    /// The grid for a model of these symmetries.
    pub fn new(symmetry: Symmetry, theta_steps: u16, phi_steps: u16) -> Result<Self, BakeError> {
        if theta_steps < 2 {
            return Err(BakeError::ThetaSteps(theta_steps));
        }
        let domain = PhiDomain::of(symmetry);
        let t_max = GRID_THETA_MAX_DEG.to_radians();
        let nt = usize::from(theta_steps);
        let thetas: Vec<f64> = (0..nt)
            .map(|i| t_max * i as f64 / (nt - 1) as f64)
            .collect();
        let (lo, hi) = domain.range();
        let phis = match domain {
            PhiDomain::Rotation => alloc::vec![0.0],
            PhiDomain::Circle => {
                if phi_steps < 3 {
                    return Err(BakeError::PhiSteps {
                        got: phi_steps,
                        min: 3,
                    });
                }
                let n = usize::from(phi_steps);
                (0..n).map(|j| TAU * j as f64 / n as f64).collect()
            }
            _ => {
                if phi_steps < 2 {
                    return Err(BakeError::PhiSteps {
                        got: phi_steps,
                        min: 2,
                    });
                }
                let n = usize::from(phi_steps);
                (0..n)
                    .map(|j| lo + (hi - lo) * j as f64 / (n - 1) as f64)
                    .collect()
            }
        };
        let rows_per_radian = 1.0 / (thetas[1] - thetas[0]);
        let within_z = m::cos(t_max - 1e-3);
        // The default grid's rows per radian, computed as `rows_per_radian` is: a grid this
        // fine or finer measures the way beyond the last row in its own spacings (the
        // default grid's bits unchanged), a coarser one in these.
        let default_per_radian =
            1.0 / (t_max * 1.0 / f64::from(crate::baked::DEFAULT_THETA_STEPS - 1));
        let (beyond_scale, beyond_offset) = if rows_per_radian >= default_per_radian {
            (rows_per_radian, (nt - 1) as f64)
        } else {
            (default_per_radian, t_max * default_per_radian)
        };
        let grid = Self {
            domain,
            thetas,
            phis,
            rows_per_radian,
            within_z,
            beyond_scale,
            beyond_offset,
        };
        if grid.len() > MAX_TREES {
            return Err(BakeError::TooManyTrees(grid.len()));
        }
        Ok(grid)
    }

    /// The folded φ range this grid covers.
    #[must_use]
    pub fn domain(&self) -> PhiDomain {
        self.domain
    }

    /// θi of the rows, degrees.
    #[must_use]
    pub fn thetas_deg(&self) -> Vec<f64> {
        self.thetas.iter().map(|t| t.to_degrees()).collect()
    }

    /// φi of the columns, degrees.
    #[must_use]
    pub fn phis_deg(&self) -> Vec<f64> {
        self.phis.iter().map(|p| p.to_degrees()).collect()
    }

    /// Number of trees (rows × columns).
    #[must_use]
    pub fn len(&self) -> usize {
        self.thetas.len() * self.phis.len()
    }

    /// Whether the grid holds no tree (never, for a grid [`BakeGrid::new`] made).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The incident direction of tree `k` (row-major: θ row × columns + φ column), as the
    /// unit f32 vector its tree was built for.
    #[must_use]
    pub fn direction(&self, k: usize) -> Vec3 {
        let (t, p) = (
            self.thetas[k / self.phis.len()],
            self.phis[k % self.phis.len()],
        );
        let (st, ct) = (m::sin(t), m::cos(t));
        let (sp, cp) = (m::sin(p), m::cos(p));
        DVec3::new(st * cp, st * sp, ct).as_vec3().normalize()
    }

    /// θi and φi of tree `k`, degrees.
    #[must_use]
    pub fn angles_deg(&self, k: usize) -> (f64, f64) {
        (
            self.thetas[k / self.phis.len()].to_degrees(),
            self.phis[k % self.phis.len()].to_degrees(),
        )
    }

    /// Rows of trees (θi values).
    #[must_use]
    pub(crate) fn rows(&self) -> usize {
        self.thetas.len()
    }

    /// Columns of trees (φi values; 1 for an isotropic grid).
    #[must_use]
    pub(crate) fn columns(&self) -> usize {
        self.phis.len()
    }

    /// Cells of the grid along φ: 1 without columns (isotropic), one per column on the
    /// periodic circle (the last cell wraps to the first column), else one fewer than the
    /// columns.
    #[must_use]
    pub(crate) fn phi_cells(&self) -> usize {
        match self.domain {
            PhiDomain::Rotation => 1,
            PhiDomain::Circle => self.phis.len(),
            _ => self.phis.len() - 1,
        }
    }

    /// Cells of the grid, row-major: (rows − 1) × the cells along φ (1 for an isotropic
    /// grid, one per column on the periodic circle, else one fewer than the columns). Cell
    /// (i, j) lies between rows i, i + 1 and columns j, j + 1 (mod the columns on the
    /// circle).
    #[must_use]
    pub fn cells(&self) -> usize {
        (self.thetas.len() - 1) * self.phi_cells()
    }

    /// How far beyond the last row a folded direction `w` (unit, z > 0) lies, at most 1: 0
    /// within the grid. Measured in row spacings, but never in spacings wider than the
    /// default grid's (2.87°): the share the last tree takes untilted there (see
    /// `baked_mixture`) is what lets the mixture draw the band above the horizon that the
    /// tilted tree leaves, and weights there scale as 1/share. On a 3-row grid (spacing
    /// 44.5°) the share at 89.5° was 1.1 %, and Oren–Nayar's mean weight (albedo 1) came out
    /// 4.3 to 6.0 standard errors low at four of fourteen seeds, the band's mass drawn too
    /// rarely to count; in the default grid's spacings it is 17 %, as on the default grid
    /// (and the standard error of that mean fell from 0.9–3.7·10⁻⁴ to 0.9–1.0·10⁻⁴ at 10⁶
    /// samples). A function of `w` alone, so a mixture weighted by it stays exact.
    #[inline]
    pub(crate) fn beyond_last_row(&self, w: DVec3) -> f64 {
        if w.z >= self.within_z {
            return 0.0;
        }
        (fast_acos(w.z) * self.beyond_scale - self.beyond_offset).clamp(0.0, 1.0)
    }

    /// The neighbouring trees of a folded direction `w` (unit, z > 0) and their weights
    /// (summing to 1; linear in θ, linear on a cell's triangles in (θ, φ), except along an
    /// axis that `nearest` snaps in `w`'s cell: there the nearer tree takes the whole
    /// weight); unused entries have weight 0. Any weights that are a function of `w` alone
    /// keep the mixture exact.
    #[inline]
    pub(crate) fn neighbours(&self, w: DVec3, nearest: &Nearest) -> [(usize, f64); 4] {
        let theta = fast_acos(w.z);
        let nt = self.thetas.len();
        let t = (theta * self.rows_per_radian).clamp(0.0, (nt - 1) as f64);
        let i = (t as usize).min(nt - 2);
        let ft = (t - i as f64).clamp(0.0, 1.0);
        let np = self.phis.len();
        let (j0, j1, fp) = match self.domain {
            PhiDomain::Rotation => (0, 0, 0.0),
            PhiDomain::Circle => {
                let dp = TAU / np as f64;
                let mut phi = fast_atan2(w.y, w.x);
                if phi < 0.0 {
                    phi += TAU;
                }
                let p = phi / dp;
                let j = (p as usize).min(np - 1);
                (j, (j + 1) % np, (p - j as f64).clamp(0.0, 1.0))
            }
            _ => {
                let (lo, hi) = self.domain.range();
                let phi = fast_atan2(w.y, w.x).clamp(lo, hi);
                let p = ((phi - lo) / (hi - lo) * (np - 1) as f64).clamp(0.0, (np - 1) as f64);
                let j = (p as usize).min(np - 2);
                (j, j + 1, (p - j as f64).clamp(0.0, 1.0))
            }
        };
        let cell = i * self.phi_cells() + j0;
        let ft = nearest.snap_theta(cell, ft);
        let fp = nearest.snap_phi(cell, fp);
        let at = |r: usize, c: usize| r * np + c;
        // Linear on the cell's two triangles either side of its diagonal from (i, j0) to
        // (i + 1, j1): three trees at most where bilinear weights blend four, so a query
        // costs one density (a look-up, or a model evaluation in rejection mode) fewer.
        // Along a snapped axis (ft or fp 0 or 1) it is the same linear blend along the
        // other axis as the bilinear weights give; on an isotropic grid (fp = 0) it is
        // linear in θ.
        if ft >= fp {
            [
                (at(i, j0), 1.0 - ft),
                (at(i + 1, j0), ft - fp),
                (at(i + 1, j1), fp),
                (at(i, j1), 0.0),
            ]
        } else {
            [
                (at(i, j0), 1.0 - fp),
                (at(i, j1), fp - ft),
                (at(i + 1, j1), ft),
                (at(i + 1, j0), 0.0),
            ]
        }
    }
}

/// The cells of a grid where a rejection-mode query is answered by the nearest tree along θ,
/// or along φ, instead of by blending the two (see `baked_nearest`, which measures where
/// that costs no variance; warp mode blends everywhere). A rejection-mode query costs one
/// model evaluation per neighbour it blends, beyond its draw; a cell snapped along θ (an
/// isotropic grid's only axis) has one neighbour. Empty: blend everywhere.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Nearest {
    /// Per cell (row-major, [`BakeGrid::cells`]): whether θ snaps to the nearer row.
    pub(crate) theta: Vec<bool>,
    /// Per cell: whether φ snaps to the nearer column (empty for an isotropic grid).
    pub(crate) phi: Vec<bool>,
}

impl Nearest {
    /// The fraction `f` ∈ [0, 1] between the cell's rows, snapped to the nearer (0 below ½,
    /// else 1) where the cell says so.
    #[inline(always)]
    fn snap_theta(&self, cell: usize, f: f64) -> f64 {
        if self.theta.get(cell).copied().unwrap_or(false) {
            snap(f)
        } else {
            f
        }
    }

    /// The same along φ.
    #[inline(always)]
    fn snap_phi(&self, cell: usize, f: f64) -> f64 {
        if self.phi.get(cell).copied().unwrap_or(false) {
            snap(f)
        } else {
            f
        }
    }

    /// Whether these cells fit `grid` (a file's record is checked with this): one θ flag a
    /// cell, and one φ flag a cell for a grid with columns, none without; or none at all
    /// (nothing measured: every cell blends, as a version 5 bake file's sampler does).
    pub(crate) fn fits(&self, grid: &BakeGrid) -> bool {
        let phi = if grid.domain() == PhiDomain::Rotation {
            0
        } else {
            grid.cells()
        };
        (self.theta.is_empty() && self.phi.is_empty())
            || (self.theta.len() == grid.cells() && self.phi.len() == phi)
    }
}

/// The nearer end of [0, 1]: 0 below ½, else 1.
#[inline(always)]
fn snap(f: f64) -> f64 {
    if f < 0.5 { 0.0 } else { 1.0 }
}

/// atan2(y, x) to within 2·10⁻⁵ rad (Abramowitz & Stegun 4.4.49 on the octant's ratio),
/// without a libm call: like [`fast_acos`], it only places a query among the grid's φ
/// columns, where any function of wi that `sample` and `pdf` share keeps the mixture exact.
/// 0 at the origin.
#[inline]
pub(crate) fn fast_atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = (ax.min(ay), ax.max(ay));
    if hi == 0.0 {
        return 0.0;
    }
    let t = lo / hi;
    let t2 = t * t;
    let a = t
        * (0.999_866_0
            + t2 * (-0.330_299_5 + t2 * (0.180_141_0 + t2 * (-0.085_133_0 + 0.020_835_1 * t2))));
    let a = if ay > ax { FRAC_PI_2 - a } else { a };
    let a = if x < 0.0 { PI - a } else { a };
    if y < 0.0 { -a } else { a }
}

/// acos(x) for x ∈ [−1, 1] to within 7·10⁻⁵ rad (Abramowitz & Stegun 4.4.45), without a
/// libm call. The neighbour weights may be any function of wi that `sample` and `pdf` share
/// (the mixture is exact whatever they are), so its error costs nothing but a shift of the
/// weights by less than 0.01 % of a grid step.
#[inline]
pub(crate) fn fast_acos(x: f64) -> f64 {
    let a = x.abs().min(1.0);
    let p =
        m::sqrt(1.0 - a) * (1.570_728_8 + a * (-0.212_114_4 + a * (0.074_261_0 - 0.018_729_3 * a)));
    if x >= 0.0 { p } else { PI - p }
}

/// The rotation about y that carries the mirror direction of `from` onto that of `to`, both
/// in the xz-plane with x ≥ 0 (an isotropic grid's directions, and a wi folded onto φ = 0):
/// the rotation by θ_from − θ_to, as its (cosine, sine), from the directions' sines and
/// cosines without trigonometry. Its matrix, columns (c, 0, −s), (0, 1, 0), (s, 0, c), equals
/// `DQuat::from_rotation_arc` of the two mirrors (a test says so), at a fraction of its cost:
/// it runs for every neighbour of every `sample` and `pdf`. Both are unit vectors (to
/// rounding): their x and z are their polar angles' sine and cosine.
#[inline]
pub(crate) fn rotation_between_mirrors_xz(from: DVec3, to: DVec3) -> (f64, f64) {
    let (sf, cf) = (from.x, from.z);
    let (st, ct) = (to.x, to.z);
    (cf * ct + sf * st, sf * ct - cf * st)
}

/// The rotation matrix carrying unit `a` onto unit `b` about their common normal (the one
/// `DQuat::from_rotation_arc` gives, a test says so), by Rodrigues' formula with
/// v = a × b, c = a·b: R = c·I + [v]× + v vᵀ/(1 + c). One division and no square root, where
/// the quaternion's construction and its matrix take a normalisation and twice the products;
/// it runs for every neighbour of every anisotropic `sample` and `pdf`. Mirror directions
/// of upper-hemisphere directions that are grid neighbours are never near antipodal; for
/// 1 + c below 10⁻⁹ the quaternion's construction takes over (it picks an axis).
#[inline]
pub(crate) fn rotation_arc(a: DVec3, b: DVec3) -> DMat3 {
    let c = a.dot(b);
    if 1.0 + c < 1e-9 {
        return DMat3::from_quat(DQuat::from_rotation_arc(a, b));
    }
    let v = a.cross(b);
    let k = 1.0 / (1.0 + c);
    let (kx, ky, kz) = (k * v.x, k * v.y, k * v.z);
    DMat3::from_cols(
        DVec3::new(c + kx * v.x, v.z + kx * v.y, -v.y + kx * v.z),
        DVec3::new(-v.z + ky * v.x, c + ky * v.y, v.x + ky * v.z),
        DVec3::new(v.y + kz * v.x, -v.x + kz * v.y, c + kz * v.z),
    )
}

/// R_z(φ)·R_y(α) from (cos φ, sin φ) and (cos α, sin α), written out: an isotropic
/// neighbour's map from its tree's frame to the local frame (the rotation between the
/// mirrors, then the unfolding rotation about z). Equal to the product of the two matrices
/// (a test says so) at a quarter of its multiplications.
#[inline]
pub(crate) fn isotropic_to_local((c, s): (f64, f64), (ca, sa): (f64, f64)) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(c * ca, s * ca, -sa),
        DVec3::new(-s, c, 0.0),
        DVec3::new(c * sa, s * sa, ca),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The isotropic fast path is the minimal rotation between the two mirror directions.
    /// Each reflection domain's fold is the diagonal of its signs and brings every direction
    /// into the domain's φ range.
    #[test]
    fn reflections_are_the_folds() {
        for d in [
            PhiDomain::Quadrant,
            PhiDomain::UpperHalf,
            PhiDomain::RightHalf,
            PhiDomain::Circle,
        ] {
            for k in 0..64 {
                let phi = core::f64::consts::TAU * (f64::from(k) + 0.5) / 64.0;
                let w = DVec3::new(0.6 * phi.cos(), 0.6 * phi.sin(), 0.8);
                assert_eq!(d.fold(w), DMat3::from_diagonal(d.reflection(w)));
                let f = w * d.reflection(w);
                let (lo, hi) = d.range();
                let p = f.y.atan2(f.x);
                let p = if d == PhiDomain::Circle && p < 0.0 {
                    p + core::f64::consts::TAU
                } else {
                    p
                };
                assert!(p >= lo - 1e-12 && p <= hi + 1e-12, "{d:?} {phi}: {p}");
            }
        }
    }

    /// Rodrigues' matrix is the quaternion's minimal rotation, and carries a onto b, for
    /// pairs of upper-hemisphere mirror directions near and far apart (down to 1 + c just
    /// above the switch) and for the antipodal fallback.
    #[test]
    fn rotation_arc_is_the_quaternion_arc() {
        let dir = |t: f64, p: f64| DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        let mut pairs = alloc::vec::Vec::new();
        for i in 0..40 {
            for j in 0..40 {
                let (t0, p0) = (1.55 * f64::from(i) / 39.0, 0.7 * f64::from(i));
                let (t1, p1) = (1.55 * f64::from(j) / 39.0, 0.3 + 0.45 * f64::from(j));
                pairs.push((dir(t0, p0), dir(t1, p1)));
            }
        }
        let a = dir(1.5, 0.0);
        pairs.push((a, dir(1.5, core::f64::consts::PI - 1e-4)));
        pairs.push((a, -a));
        for (a, b) in pairs {
            let (fast, arc) = (
                rotation_arc(a, b),
                DMat3::from_quat(DQuat::from_rotation_arc(a, b)),
            );
            assert!((fast * a - b).length() < 1e-12, "{a} → {b}");
            if 1.0 + a.dot(b) > 1e-6 {
                for v in [DVec3::X, DVec3::Y, DVec3::Z, a.cross(b), a + b] {
                    assert!((fast * v - arc * v).length() < 1e-9, "{a} → {b} on {v}");
                }
            }
        }
    }

    #[test]
    fn fast_atan2_is_within_its_bound() {
        for k in 0..=20_000 {
            let phi = -core::f64::consts::PI + core::f64::consts::TAU * f64::from(k) / 20_000.0;
            for r in [1e-300, 0.3, 1.0, 1e3] {
                let (y, x) = (r * phi.sin(), r * phi.cos());
                let (got, want) = (fast_atan2(y, x), y.atan2(x));
                // ±π are the same direction.
                let d = (got - want).abs();
                assert!(
                    d < 2e-5 || (d - core::f64::consts::TAU).abs() < 2e-5,
                    "{y}, {x}: {got} vs {want}"
                );
            }
        }
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
        assert_eq!(fast_atan2(0.0, 1.0), 0.0);
    }

    /// On an anisotropic grid a query blends at most three trees (the corners of the
    /// triangle of its cell that holds it), with weights that are non-negative, sum to one
    /// and reproduce its own place in the grid (linear interpolation: the weighted mean of
    /// the trees' row and column indices is the query's), over every φ domain, wrap-around
    /// included; where a cell snaps along an axis, that axis takes the nearer tree's index.
    #[test]
    fn anisotropic_queries_blend_a_triangle_linearly() {
        let domains = [
            (true, true, PhiDomain::Quadrant),
            (false, true, PhiDomain::UpperHalf),
            (true, false, PhiDomain::RightHalf),
            (false, false, PhiDomain::Circle),
        ];
        for (mirror_x, mirror_y, domain) in domains {
            let sym = Symmetry {
                mirror_x,
                mirror_y,
                ..Symmetry::default()
            };
            let g = BakeGrid::new(sym, 7, 5).unwrap();
            assert_eq!(g.domain(), domain);
            let np = g.phis.len();
            let mut snapped = Nearest {
                theta: alloc::vec![false; g.cells()],
                phi: alloc::vec![false; g.cells()],
            };
            for k in 0..g.cells() {
                snapped.theta[k] = k % 3 == 1;
                snapped.phi[k] = k % 4 == 2;
            }
            let (lo, hi) = domain.range();
            let hi = if domain == PhiDomain::Circle { TAU } else { hi };
            for k in 0..4000u32 {
                // θ over the grid's rows (not beyond), φ over the domain.
                let theta = GRID_THETA_MAX_DEG.to_radians() * (f64::from(k % 61) + 0.5) / 61.0;
                let phi = lo + (hi - lo) * (f64::from(k / 61) + 0.37) / 66.0;
                let w = DVec3::new(
                    theta.sin() * phi.cos(),
                    theta.sin() * phi.sin(),
                    theta.cos(),
                );
                for nearest in [&Nearest::default(), &snapped] {
                    let n = g.neighbours(w, nearest);
                    let used: alloc::vec::Vec<_> = n.iter().filter(|e| e.1 > 0.0).collect();
                    assert!(used.len() <= 3, "{domain:?} {theta} {phi}: {n:?}");
                    assert!(n.iter().all(|e| e.1 >= 0.0), "{n:?}");
                    let sum: f64 = n.iter().map(|e| e.1).sum();
                    assert!((sum - 1.0).abs() < 1e-12, "{n:?}");
                    // The query's place, as `neighbours` finds it (fast_acos, fast_atan2).
                    let t = (fast_acos(w.z) * g.rows_per_radian).clamp(0.0, 6.0);
                    let mut a = fast_atan2(w.y, w.x);
                    if domain == PhiDomain::Circle && a < 0.0 {
                        a += TAU;
                    }
                    let p = if domain == PhiDomain::Circle {
                        a / (TAU / np as f64)
                    } else {
                        (a.clamp(lo, hi) - lo) / (hi - lo) * (np - 1) as f64
                    };
                    let (i, j) = (
                        (t as usize).min(5),
                        (p as usize).min(np - 2 + usize::from(domain == PhiDomain::Circle)),
                    );
                    // Unwrap the column past the last one on the circle.
                    let col = |slice: usize| {
                        let c = slice % np;
                        if c < j { c + np } else { c }
                    };
                    let (mut mt, mut mp) = (0.0, 0.0);
                    for &&(slice, wt) in &used {
                        mt += wt * (slice / np) as f64;
                        mp += wt * col(slice) as f64;
                    }
                    let cell = i * g.phi_cells() + j;
                    let want_t = if nearest.theta.get(cell) == Some(&true) {
                        i as f64 + snap(t - i as f64)
                    } else {
                        t
                    };
                    let want_p = if nearest.phi.get(cell) == Some(&true) {
                        j as f64 + snap(p - j as f64)
                    } else {
                        p
                    };
                    assert!((mt - want_t).abs() < 1e-9, "{domain:?} θ {mt} vs {want_t}");
                    assert!((mp - want_p).abs() < 1e-9, "{domain:?} φ {mp} vs {want_p}");
                }
            }
        }
    }

    #[test]
    fn beyond_the_last_row_is_measured_in_row_spacings() {
        let sym = Symmetry {
            isotropic: true,
            ..Symmetry::default()
        };
        let last = GRID_THETA_MAX_DEG.to_radians();
        let default_spacing = last / f64::from(crate::baked::DEFAULT_THETA_STEPS - 1);
        for steps in [2u16, 3, 8, 32, 64] {
            let g = BakeGrid::new(sym, steps, 9).unwrap();
            // The grid's own spacing, or the default grid's where that is finer.
            let spacing = (last / f64::from(steps - 1)).min(default_spacing);
            let at = |t: f64| g.beyond_last_row(DVec3::new(t.sin(), 0.0, t.cos()));
            assert_eq!(at(0.0), 0.0);
            assert_eq!(at(last - 2e-3), 0.0);
            let half = (last + FRAC_PI_2) / 2.0;
            // (Within `fast_acos`'s 7·10⁻⁵ rad, in spacings.)
            assert!(
                (at(half) - (half - last) / spacing).abs() < 7e-5 / spacing,
                "{steps}"
            );
            assert!(at(FRAC_PI_2 - 1e-9) > 0.0 && at(FRAC_PI_2 - 1e-9) <= 1.0);
            // The shortcut above `within_z` changes nothing: the formula alone agrees, and
            // on a grid as fine as the default one it is the row position's own (the
            // default grid's bits as before the coarse grids' cap).
            let formula =
                |z: f64| (fast_acos(z) * g.beyond_scale - g.beyond_offset).clamp(0.0, 1.0);
            let rows =
                |z: f64| (fast_acos(z) * g.rows_per_radian - (steps - 1) as f64).clamp(0.0, 1.0);
            for k in 0..20_000 {
                let t = last - 5e-3 + 1e-2 * f64::from(k) / 20_000.0;
                assert_eq!(at(t), formula(t.cos()), "{steps} {t}");
                if steps >= crate::baked::DEFAULT_THETA_STEPS {
                    assert_eq!(at(t).to_bits(), rows(t.cos()).to_bits(), "{steps} {t}");
                }
            }
        }
        // A 3-row grid at 89.5°: 0.5° of the default grid's 2.87° (17 %), not of its own
        // 44.5° (1.1 %).
        let g = BakeGrid::new(sym, 3, 9).unwrap();
        let t = 89.5f64.to_radians();
        let share = g.beyond_last_row(DVec3::new(t.sin(), 0.0, t.cos()));
        assert!((share - 0.5 / (89.0 / 31.0)).abs() < 1e-3, "{share}");
    }

    #[test]
    fn fast_acos_is_within_its_bound() {
        for k in 0..=2000 {
            let x = -1.0 + f64::from(k) / 1000.0;
            assert!((fast_acos(x) - x.acos()).abs() < 7e-5, "{x}");
        }
    }

    #[test]
    fn the_xz_rotation_is_the_rotation_arc_of_the_mirrors() {
        for (a, b) in [
            (0.0f64, 0.3f64),
            (0.3, 0.0),
            (1.2, 0.4),
            (0.05, 1.55),
            (1.55, 1.5),
            (0.7, 0.7),
        ] {
            let from = DVec3::new(a.sin(), 0.0, a.cos());
            let to = DVec3::new(b.sin(), 0.0, b.cos());
            let m = |w: DVec3| DVec3::new(-w.x, -w.y, w.z);
            let arc = DMat3::from_quat(DQuat::from_rotation_arc(m(from), m(to)));
            let (ca, sa) = rotation_between_mirrors_xz(from, to);
            let fast =
                DMat3::from_cols(DVec3::new(ca, 0.0, -sa), DVec3::Y, DVec3::new(sa, 0.0, ca));
            assert!((fast * m(from) - m(to)).length() < 1e-12);
            for v in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(0.3, -0.4, 0.866)] {
                assert!((arc * v - fast * v).length() < 1e-12, "{a} {b} {v}");
            }
            // The isotropic neighbour's map is the unfolding (the fold's transpose) after it
            // (at θ = 0 the fold is the identity, and so φ is 0).
            let phis: &[f64] = if to.x > 0.0 {
                &[0.0, 0.4, 2.0, -1.3, 3.1]
            } else {
                &[0.0]
            };
            for &phi in phis {
                let g = DVec3::new(phi.cos() * to.x, phi.sin() * to.x, to.z);
                let unfold = PhiDomain::Rotation.fold(g).transpose();
                let d = unfold * fast - isotropic_to_local((phi.cos(), phi.sin()), (ca, sa));
                let err = d.x_axis.length() + d.y_axis.length() + d.z_axis.length();
                assert!(err < 1e-12, "{a} {b} {phi}: {err}");
            }
        }
    }
}
