//! The cells a test histograms samples into (the seed's Celda), and each cell's integral by
//! the independent integrator of [`crate::integrate`](self).

use crate::error::ValidateError;
use crate::integrate::{MAX_BREAKS, MAX_PIECES, adaptive};
use brdf_core::math as m;
use glam::{DVec3, Vec3};
use quadtree_sampler::Ridge;
use std::f64::consts::PI;

/// Most peak directions of a model a cell's integration uses (as many as a model gives).
const MODEL_PEAKS: usize = 4;
/// Most peak directions a cell's integration uses: a model's, then a sampler's own.
const MAX_PEAKS: usize = 12;
/// Most ridge planes a cell's integration uses: the two axis planes of each of a model's
/// peaks, then a sampler's own (see [`Hints`]).
const MAX_RIDGES: usize = 24;

/// How far (radians) the direction moves per unit of a polar cell's outer variable, at
/// most: θ = acos(1 − w²) for w² ≤ ½ and acos(v²) for v² ≤ ½ both move at most
/// 2/√(3/2) ≈ 1.633 radians per unit.
const OUTER_RATE: f64 = 1.633;

/// Where a cell's integration cuts its ranges: directions where the integrand may peak
/// sharply, and planes {w : n·w = c} along which it may be concentrated, as a lobe narrow
/// along one tangent axis is. Each of a model's peaks brings its two axis planes x = h.x
/// and y = h.y (Ward's lobe as αx → 0 lies along wo.x = −wi.x, the mirror direction's x);
/// a sampler may add its own peaks and planes (a baked sampler's neighbour trees, rotated
/// onto wi, carry their lobes along rotated planes).
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct Hints {
    peaks: Vec<DVec3>,
    /// Unit normals.
    ridges: Vec<Ridge>,
    /// The width (radians) of the steps of a staircase integrand, already made usable
    /// ([`brdf_core::usable_step_width`]); `None` for a continuous one. Each range is cut
    /// into pieces whose directions lie no farther apart (see `integrate::adaptive`).
    step: Option<f64>,
}

impl Hints {
    /// A model's peaks (the first [`MODEL_PEAKS`] finite ones) with their axis planes.
    pub(crate) fn of_model(peaks: &[DVec3]) -> Self {
        let peaks: Vec<DVec3> = peaks
            .iter()
            .copied()
            .filter(|h| h.is_finite())
            .take(MODEL_PEAKS)
            .collect();
        let ridges = peaks
            .iter()
            .flat_map(|h| {
                [(DVec3::X, h.x), (DVec3::Y, h.y)].map(|(normal, offset)| Ridge { normal, offset })
            })
            .collect();
        Self {
            peaks,
            ridges,
            step: None,
        }
    }

    /// These hints for a staircase integrand of steps `step` wide (radians, as
    /// [`brdf_core::Brdf::step_width`] declares it): the narrower of this and any step
    /// already held. `None` changes nothing.
    pub(crate) fn with_step(&self, step: Option<f64>) -> Self {
        let step = match (self.step, brdf_core::usable_step_width(step)) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        Self {
            step,
            ..self.clone()
        }
    }

    /// The widest piece, in a variable of integration along which directions move at most
    /// `rate` radians per unit, that a staircase's error estimate is trusted on (∞ for a
    /// continuous integrand or a variable that does not move the direction).
    fn piece(&self, rate: f64) -> f64 {
        match self.step {
            Some(step) if rate > 0.0 => step / rate,
            _ => f64::INFINITY,
        }
    }

    /// These hints and more: `peaks` (without axis planes; non-finite ones dropped) and
    /// `ridges` (normals scaled to unit length; a zero or non-finite normal or offset
    /// dropped), up to [`MAX_PEAKS`] and [`MAX_RIDGES`] in all.
    pub(crate) fn with(&self, peaks: &[DVec3], ridges: &[Ridge]) -> Self {
        let mut h = self.clone();
        h.peaks
            .extend(peaks.iter().copied().filter(|p| p.is_finite()));
        h.peaks.truncate(MAX_PEAKS);
        h.ridges.extend(ridges.iter().filter_map(|r| {
            // Scaled by its largest component first, so that no length overflows or
            // underflows. (`max_element` passes over a NaN component: checked apart.)
            let s = r.normal.abs().max_element();
            let (n, c) = (r.normal / s, r.offset / s);
            let l = n.length();
            (r.normal.is_finite() && s > 0.0 && c.is_finite()).then(|| Ridge {
                normal: n / l,
                offset: c / l,
            })
        }));
        h.ridges.truncate(MAX_RIDGES);
        h
    }

    /// The ridge planes' crossings of the circle of radius r at height z, as angles φ:
    /// r·(n.x·cos φ + n.y·sin φ) = c − n.z·z.
    fn circle_crossings(&self, r: f64, z: f64, mut push: impl FnMut(f64)) {
        for &Ridge {
            normal: n,
            offset: c,
        } in &self.ridges
        {
            cos_sin_roots(n.x, n.y, r, c - n.z * z, &mut push);
        }
    }

    /// The ridge planes' crossings of the square grid chart's line of constant x = sin s,
    /// (x, cs·sin t, cs·cos t), as angles t: cs·(n.z·cos t + n.y·sin t) = c − n.x·x.
    fn line_crossings(&self, x: f64, cs: f64, mut push: impl FnMut(f64)) {
        for &Ridge {
            normal: n,
            offset: c,
        } in &self.ridges
        {
            cos_sin_roots(n.z, n.y, cs, c - n.x * x, &mut push);
        }
    }

    /// The heights z where a ridge plane touches a circle of constant z (where its two
    /// crossings meet).
    fn tangent_heights(&self, mut push: impl FnMut(f64)) {
        for &Ridge {
            normal: n,
            offset: c,
        } in &self.ridges
        {
            touching(n.z, n.x * n.x + n.y * n.y, c, &mut push);
        }
    }

    /// The x where a ridge plane touches a line of constant x of the square grid's chart.
    fn tangent_xs(&self, mut push: impl FnMut(f64)) {
        for &Ridge {
            normal: n,
            offset: c,
        } in &self.ridges
        {
            touching(n.x, n.y * n.y + n.z * n.z, c, &mut push);
        }
    }
}

/// The angles θ with scale·(p·cos θ + q·sin θ) = rhs: atan2(q, p) ± acos(rhs/(scale·|(p, q)|)),
/// none when that is out of [−1, 1].
fn cos_sin_roots(p: f64, q: f64, scale: f64, rhs: f64, push: &mut impl FnMut(f64)) {
    let a = scale * m::sqrt(p * p + q * q);
    if a > 0.0 {
        let k = rhs / a;
        if k.abs() <= 1.0 {
            let (theta0, d) = (m::atan2(q, p), m::acos(k));
            push(theta0 + d);
            push(theta0 - d);
        }
    }
}

/// Where the plane n·w = c (unit n) touches the circles of the unit sphere with a constant
/// coordinate e·w = a (n_e = n·e, `rest2` = 1 − n_e², the square of n's other part): at
/// a = c·n_e ± √rest2·√(1 − c²).
fn touching(n_e: f64, rest2: f64, c: f64, push: &mut impl FnMut(f64)) {
    if c.abs() <= 1.0 {
        let b = m::sqrt(rest2) * m::sqrt(1.0 - c * c);
        push(c * n_e + b);
        push(c * n_e - b);
    }
}

/// Up to [`MAX_BREAKS`] break points, filled by pushes beyond which they are dropped.
struct Breaks {
    at: [f64; MAX_BREAKS],
    len: usize,
}

impl Breaks {
    fn new() -> Self {
        Self {
            at: [f64::NAN; MAX_BREAKS],
            len: 0,
        }
    }

    fn push(&mut self, x: f64) {
        if self.len < MAX_BREAKS && x.is_finite() {
            self.at[self.len] = x;
            self.len += 1;
        }
    }

    fn as_slice(&self) -> &[f64] {
        &self.at[..self.len]
    }
}

/// Cells over the projected disk (SPEC §5).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CellGrid {
    /// The seed's grid: `res` × `res` equal squares over [−1,1]² of (wo.x, wo.y) (the
    /// orthographic map); cells on the rim are cut by it, the corners lie wholly outside.
    Square {
        /// Cells per side.
        res: usize,
    },
    /// An equal-area polar grid on the disk: `rings` in r² and `sectors` in φ, so no cell
    /// straddles the rim. Odd counts keep cell edges off the symmetry planes of most lobes.
    Polar {
        /// Rings, r² ∈ [i/rings, (i+1)/rings).
        rings: usize,
        /// Sectors, φ ∈ [2πj/sectors, 2π(j+1)/sectors).
        sectors: usize,
    },
}

impl CellGrid {
    /// Number of cells.
    #[must_use]
    pub fn len(&self) -> usize {
        let (r, c) = self.dims();
        r * c
    }

    /// Whether the grid has no cells (never, once [`CellGrid::check`] passed).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// (rows, columns): (res, res) with row = y, or (rings, sectors).
    #[must_use]
    pub fn dims(&self) -> (usize, usize) {
        match *self {
            Self::Square { res } => (res, res),
            Self::Polar { rings, sectors } => (rings, sectors),
        }
    }

    /// The cell indices in image order (rows top to bottom, columns left to right): square
    /// grids put y = +1 in the top row, as a picture of the disk; polar grids have one row per
    /// ring, the centre first, and one column per sector from φ = 0. Shared by every writer
    /// of per-cell images (the `brdf test` EXR, the viewer's export).
    #[must_use]
    pub fn image_order(&self) -> Vec<usize> {
        let (rows, cols) = self.dims();
        match *self {
            Self::Square { .. } => (0..rows)
                .rev()
                .flat_map(|r| (0..cols).map(move |c| r * cols + c))
                .collect(),
            Self::Polar { .. } => (0..rows * cols).collect(),
        }
    }

    /// The largest number of rows or columns a grid may have.
    pub const MAX_DIMENSION: usize = 4096;

    /// Every dimension in 1..=[`CellGrid::MAX_DIMENSION`].
    pub fn check(&self) -> Result<(), ValidateError> {
        let (r, c) = self.dims();
        for value in [r, c] {
            if !(1..=Self::MAX_DIMENSION).contains(&value) {
                return Err(ValidateError::GridDimension { value });
            }
        }
        Ok(())
    }

    /// The cell holding direction `wo` (row-major), or `None` when `wo` is not a finite
    /// direction strictly above the horizon.
    #[must_use]
    pub fn cell_of(&self, wo: Vec3) -> Option<usize> {
        if !(wo.is_finite() && wo.z > 0.0) {
            return None;
        }
        let w = wo.as_dvec3().normalize();
        let bin = |t: f64, n: usize| ((t * n as f64) as usize).min(n - 1);
        Some(match *self {
            Self::Square { res } => bin(0.5 * (w.y + 1.0), res) * res + bin(0.5 * (w.x + 1.0), res),
            Self::Polar { rings, sectors } => {
                let r2 = (w.x * w.x + w.y * w.y).min(1.0);
                let mut phi = m::atan2(w.y, w.x);
                if phi < 0.0 {
                    phi += 2.0 * PI;
                }
                bin(r2, rings) * sectors + bin(phi / (2.0 * PI), sectors)
            }
        })
    }

    /// ∫ g(w) dA over cell `i` of the disk (dA = projected solid angle, dω = dA / cos θ), by
    /// nested adaptive Gauss–Kronrod (7–15) to about `tol` absolute, in coordinates where the
    /// rim is a boundary and integrands that grow like 1/√cos θ there (Ward) stay bounded:
    /// polar cells in (v = √z, φ), dA = 2v³ dv dφ, below z = ½ and in (w = √(1 − z), φ),
    /// dA = 2w(1 − w²) dw dφ, above (where v would squeeze a lobe at the pole); square cells
    /// in the angle chart x = sin s, y = cos s · sin t (z = cos s · cos t),
    /// dA = cos²s · cos t ds dt. Each range is first cut where the `hints` say g may peak
    /// (see `integrate::adaptive`): at their peaks' coordinates, where the line or circle of
    /// the inner integral crosses a ridge plane, and where a plane touches such a line or
    /// circle (there its two crossings meet). For a staircase (`hints` with a step) each
    /// range is also cut into pieces over which the direction moves at most one step.
    pub(crate) fn integrate(
        &self,
        i: usize,
        tol: f64,
        hints: &Hints,
        g: &(impl Fn(Vec3) -> f64 + ?Sized),
    ) -> f64 {
        match *self {
            Self::Polar { rings, sectors } => {
                let (ri, sj) = (i / sectors, i % sectors);
                // r² ∈ [a, b] ⇔ z ∈ [√(1 − b), √(1 − a)]; dA = r dr dφ = z dz dφ.
                let z0 = m::sqrt((1.0 - (ri + 1) as f64 / rings as f64).max(0.0));
                let z1 = m::sqrt(1.0 - ri as f64 / rings as f64);
                let p0 = 2.0 * PI * sj as f64 / sectors as f64;
                let p1 = 2.0 * PI * (sj + 1) as f64 / sectors as f64;
                // ∫ over the sector at one height z (radius r = √(1 − z²)), its range cut
                // at each peak's φ and where the circle crosses a ridge plane: a lobe
                // narrower than the nodes' spacing is found only at a break.
                let across = |z: f64, inner_tol: f64| {
                    let r = m::sqrt((1.0 - z * z).max(0.0));
                    let mut breaks = Breaks::new();
                    let mut push = |phi: f64| breaks.push(phi.rem_euclid(2.0 * PI));
                    for h in &hints.peaks {
                        push(m::atan2(h.y, h.x));
                    }
                    hints.circle_crossings(r, z, &mut push);
                    adaptive(
                        &|phi: f64| {
                            g(glam::DVec3::new(r * m::cos(phi), r * m::sin(phi), z).as_vec3())
                        },
                        p0,
                        p1,
                        breaks.as_slice(),
                        // A step of φ moves the direction r times as far.
                        hints.piece(r),
                        inner_tol,
                        MAX_PIECES,
                    )
                };
                // The heights of the peaks, and where the ridge planes touch a circle.
                let mut z_breaks = Breaks::new();
                for h in &hints.peaks {
                    z_breaks.push(h.z);
                }
                hints.tangent_heights(|z| z_breaks.push(z));
                let z_breaks = z_breaks.as_slice();
                if z0 >= 0.5 {
                    // Away from the rim, in w = √(1 − z) (≈ θ/√2 at the pole; dA = 2w(1 − w²)
                    // dw dφ): v = √z squeezes the pole, where a lobe of width δθ (Ward's
                    // α = 0.001 at normal incidence) is δθ²/4 wide in v, narrower than the
                    // spacing of the nodes nearest the end, and was missed whole.
                    let (w0, w1) = (m::sqrt(1.0 - z1), m::sqrt(1.0 - z0));
                    let inner_tol = 0.1 * tol / (w1 - w0).max(1e-300);
                    let mut w_breaks = Breaks::new();
                    for &z in z_breaks {
                        w_breaks.push(m::sqrt((1.0 - z).max(0.0)));
                    }
                    adaptive(
                        &|w: f64| 2.0 * w * (1.0 - w * w) * across(1.0 - w * w, inner_tol),
                        w0,
                        w1,
                        w_breaks.as_slice(),
                        hints.piece(OUTER_RATE),
                        tol,
                        MAX_PIECES,
                    )
                } else {
                    // Toward the rim, in v = √z (dA = 2v³ dv dφ), where Ward's 1/√cos θ
                    // growth is bounded.
                    let (v0, v1) = (m::sqrt(z0), m::sqrt(z1));
                    let inner_tol = 0.1 * tol / (v1 - v0).max(1e-300);
                    let mut v_breaks = Breaks::new();
                    for &z in z_breaks {
                        v_breaks.push(m::sqrt(z.max(0.0)));
                    }
                    adaptive(
                        &|v: f64| {
                            let z = v * v;
                            2.0 * v * z * across(z, inner_tol)
                        },
                        v0,
                        v1,
                        v_breaks.as_slice(),
                        hints.piece(OUTER_RATE),
                        tol,
                        MAX_PIECES,
                    )
                }
            }
            Self::Square { res } => {
                let (iy, ix) = (i / res, i % res);
                let h = 2.0 / res as f64;
                let (x0, x1) = (-1.0 + h * ix as f64, -1.0 + h * (ix + 1) as f64);
                let (y0, y1) = (-1.0 + h * iy as f64, -1.0 + h * (iy + 1) as f64);
                let (s0, s1) = (m::asin(x0.max(-1.0)), m::asin(x1.min(1.0)));
                let inner_tol = 0.1 * tol / (s1 - s0).max(1e-300);
                let mut s_breaks = Breaks::new();
                // Where the cell's rows y = y0 and y = y1 meet the rim (cos s = |y|), the
                // inner range switches between the row and the rim: a kink of the outer
                // integrand, which the rule's error estimate can miss (a rim cell of a
                // constant f·cos/cos θ came out 0.65 % off, 4.4 times its tolerance).
                // Cut there first (never crowded out by the hints' breaks), so that each
                // piece is smooth where the integrand is.
                for y in [y0, y1] {
                    let c = y.abs();
                    if c > 0.0 && c < 1.0 {
                        let s = m::acos(c);
                        s_breaks.push(s);
                        s_breaks.push(-s);
                    }
                }
                // The peaks' x, and where a ridge plane touches a line of constant x (for an
                // axis plane x = h.x, that line itself).
                let mut push_x = |x: f64| s_breaks.push(m::asin(x.clamp(-1.0, 1.0)));
                for p in &hints.peaks {
                    push_x(p.x);
                }
                hints.tangent_xs(&mut push_x);
                adaptive(
                    &|s: f64| {
                        let c = m::cos(s);
                        let (a, b) = (y0.max(-c), y1.min(c));
                        if b <= a || c <= 0.0 {
                            return 0.0;
                        }
                        let (t0, t1) = (
                            m::asin((a / c).clamp(-1.0, 1.0)),
                            m::asin((b / c).clamp(-1.0, 1.0)),
                        );
                        let x = m::sin(s);
                        // Where each peak's y falls on this line of constant x, and where
                        // the line crosses a ridge plane.
                        let mut t_breaks = Breaks::new();
                        for p in &hints.peaks {
                            t_breaks.push(m::asin((p.y / c).clamp(-1.0, 1.0)));
                        }
                        hints.line_crossings(x, c, |t| t_breaks.push(t));
                        c * c
                            * adaptive(
                                &|t: f64| {
                                    let ct = m::cos(t);
                                    let w = glam::DVec3::new(x, c * m::sin(t), c * ct);
                                    if w.z <= 0.0 { 0.0 } else { ct * g(w.as_vec3()) }
                                },
                                t0,
                                t1,
                                t_breaks.as_slice(),
                                // A step of t moves the direction cos s times as far.
                                hints.piece(c),
                                inner_tol,
                                MAX_PIECES,
                            )
                    },
                    s0,
                    s1,
                    s_breaks.as_slice(),
                    // s is an angle along a great circle.
                    hints.piece(1.0),
                    tol,
                    MAX_PIECES,
                )
            }
        }
    }

    /// ∫ g dA over every cell, in parallel with the `rayon` feature (each cell independent,
    /// collected in order: the result does not depend on the thread count).
    pub(crate) fn integrate_all(
        &self,
        tol: f64,
        hints: &Hints,
        g: &(impl Fn(Vec3) -> f64 + Sync + ?Sized),
    ) -> Vec<f64> {
        use rayon::prelude::*;
        (0..self.len())
            .into_par_iter()
            .map(|i| self.integrate(i, tol, hints, g))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Degenerate ridges and peaks (a zero or non-finite normal or offset, a NaN peak) are
    /// dropped; a plane that misses the sphere (|c| > 1) cuts nothing; a huge normal is
    /// scaled to unit length. With what remains the cells still sum to the disk's area.
    #[test]
    fn degenerate_hints_are_dropped_and_cut_nothing() {
        let r = |normal: DVec3, offset: f64| Ridge { normal, offset };
        let h = Hints::default().with(
            &[DVec3::NAN, DVec3::Z],
            &[
                r(DVec3::ZERO, 0.5),
                r(DVec3::X, f64::NAN),
                r(DVec3::new(f64::INFINITY, 0.0, 0.0), 0.1),
                r(DVec3::Y, 5.0),
                r(DVec3::new(1e300, 0.0, 0.0), 5e299),
                r(DVec3::new(0.0, 0.0, 1e-310), 0.0),
                r(DVec3::new(f64::NAN, 0.0, 1.0), 0.2),
            ],
        );
        assert_eq!(h.peaks, vec![DVec3::Z]);
        assert_eq!(
            h.ridges,
            vec![r(DVec3::Y, 5.0), r(DVec3::X, 0.5), r(DVec3::Z, 0.0)]
        );
        for grid in [
            CellGrid::Square { res: 7 },
            CellGrid::Polar {
                rings: 5,
                sectors: 9,
            },
        ] {
            let area: f64 = grid.integrate_all(1e-10, &h, &|_| 1.0).iter().sum();
            assert!((area - PI).abs() < 1e-8, "{grid:?}: {area}");
        }
    }

    #[test]
    fn cells_cover_the_disk_and_sum_to_its_area() {
        for grid in [
            CellGrid::Square { res: 7 },
            CellGrid::Polar {
                rings: 5,
                sectors: 9,
            },
        ] {
            let area: f64 = grid
                .integrate_all(1e-10, &Hints::default(), &|_| 1.0)
                .iter()
                .sum();
            assert!((area - PI).abs() < 1e-8, "{grid:?}: {area}");
            assert_eq!(grid.cell_of(Vec3::new(0.0, 0.0, -1.0)), None);
            assert_eq!(grid.cell_of(Vec3::new(f32::NAN, 0.0, 1.0)), None);
            assert!(grid.cell_of(Vec3::new(0.999, 0.0, 0.0447)).unwrap() < grid.len());
        }
        // Equal-area polar cells.
        let g = CellGrid::Polar {
            rings: 3,
            sectors: 5,
        };
        let cells = g.integrate_all(1e-12, &Hints::default(), &|_| 1.0);
        for c in &cells {
            assert!((c - PI / 15.0).abs() < 1e-10);
        }
        assert!(CellGrid::Square { res: 0 }.check().is_err());
    }
}
