//! The seed's §4 convergence test and a Pearson χ² harness (SPEC §5), for any
//! [`DirectionSampler`]: the quadtree, the baselines, or a user's own.
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
//!
//! ```
//! use brdf_core::registry;
//! use quadtree_sampler::validate::{CellGrid, Validation, sidak};
//! use quadtree_sampler::{BuildConfig, QuadtreeSampler};
//! use glam::Vec3;
//! use rand_core::SeedableRng;
//!
//! let phong = registry::create("phong", ["n=50"]).unwrap();
//! let wi = Vec3::new(0.3, 0.0, 0.954);
//! let v = Validation::new(&*phong, wi, CellGrid::Polar { rings: 9, sectors: 17 }, 1e-7).unwrap();
//! let q = QuadtreeSampler::new(&*phong, wi, BuildConfig::default()).unwrap();
//! let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
//! let report = v.test(&q, 100_000, &mut rng, sidak(0.01, 1));
//! assert!(report.passed(), "{:?}", report.reasons);
//! ```

use crate::error::BuildError;
use crate::sampler::DirectionSampler;
use alloc::format;
use alloc::string::String;
use alloc::vec;
use alloc::vec::Vec;
use brdf_core::Brdf;
use brdf_core::geometry::{luminance, unit_direction_above};
use brdf_core::math as m;
use brdf_core::special::ln_gamma;
use core::f64::consts::PI;
use glam::DVec3;
use glam::Vec3;
use rand_core::Rng;

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

    /// Every dimension in 1..=4096.
    pub fn check(&self) -> Result<(), BuildError> {
        let (r, c) = self.dims();
        if (1..=4096).contains(&r) && (1..=4096).contains(&c) {
            Ok(())
        } else {
            Err(BuildError::OutOfRange {
                option: "cell grid dimension",
                value: if (1..=4096).contains(&r) { c } else { r } as f64,
                expected: "in 1..=4096",
            })
        }
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
    /// polar cells in (v = √z, φ), dA = 2v³ dv dφ; square cells in the angle chart x = sin s,
    /// y = cos s · sin t (z = cos s · cos t), dA = cos²s · cos t ds dt. Each range is first
    /// cut at the coordinates of the `hints` (directions where g may peak; see [`adaptive`]).
    fn integrate(
        &self,
        i: usize,
        tol: f64,
        hints: &[DVec3],
        g: &(impl Fn(Vec3) -> f64 + ?Sized),
    ) -> f64 {
        // One coordinate of every hint (at most MAX_BREAKS, as `adaptive` uses).
        let coords = |c: &dyn Fn(DVec3) -> f64| {
            let mut out = [f64::NAN; MAX_BREAKS];
            for (o, &h) in out.iter_mut().zip(hints) {
                *o = c(h);
            }
            out
        };
        match *self {
            Self::Polar { rings, sectors } => {
                let (ri, sj) = (i / sectors, i % sectors);
                // r² ∈ [a, b] ⇔ z ∈ [√(1 − b), √(1 − a)]; dA = r dr dφ = z dz dφ.
                let z0 = m::sqrt((1.0 - (ri + 1) as f64 / rings as f64).max(0.0));
                let z1 = m::sqrt(1.0 - ri as f64 / rings as f64);
                let (v0, v1) = (m::sqrt(z0), m::sqrt(z1));
                let p0 = 2.0 * PI * sj as f64 / sectors as f64;
                let p1 = 2.0 * PI * (sj + 1) as f64 / sectors as f64;
                let inner_tol = 0.1 * tol / (v1 - v0).max(1e-300);
                let v_breaks = coords(&|h| m::sqrt(h.z));
                let phi_breaks = coords(&|h| {
                    let phi = m::atan2(h.y, h.x);
                    if phi < 0.0 { phi + 2.0 * PI } else { phi }
                });
                adaptive(
                    &|v: f64| {
                        let z = v * v;
                        let r = m::sqrt((1.0 - z * z).max(0.0));
                        2.0 * v
                            * z
                            * adaptive(
                                &|phi: f64| {
                                    g(glam::DVec3::new(r * m::cos(phi), r * m::sin(phi), z)
                                        .as_vec3())
                                },
                                p0,
                                p1,
                                &phi_breaks,
                                inner_tol,
                                MAX_PIECES,
                            )
                    },
                    v0,
                    v1,
                    &v_breaks,
                    tol,
                    MAX_PIECES,
                )
            }
            Self::Square { res } => {
                let (iy, ix) = (i / res, i % res);
                let h = 2.0 / res as f64;
                let (x0, x1) = (-1.0 + h * ix as f64, -1.0 + h * (ix + 1) as f64);
                let (y0, y1) = (-1.0 + h * iy as f64, -1.0 + h * (iy + 1) as f64);
                let (s0, s1) = (m::asin(x0.max(-1.0)), m::asin(x1.min(1.0)));
                let inner_tol = 0.1 * tol / (s1 - s0).max(1e-300);
                let s_breaks = coords(&|h| m::asin(h.x.clamp(-1.0, 1.0)));
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
                        // Where each hint's y falls on this line of constant x.
                        let t_breaks = coords(&|h| m::asin((h.y / c).clamp(-1.0, 1.0)));
                        c * c
                            * adaptive(
                                &|t: f64| {
                                    let ct = m::cos(t);
                                    let w = glam::DVec3::new(x, c * m::sin(t), c * ct);
                                    if w.z <= 0.0 { 0.0 } else { ct * g(w.as_vec3()) }
                                },
                                t0,
                                t1,
                                &t_breaks,
                                inner_tol,
                                MAX_PIECES,
                            )
                    },
                    s0,
                    s1,
                    &s_breaks,
                    tol,
                    MAX_PIECES,
                )
            }
        }
    }

    /// ∫ g dA over every cell, in parallel with the `rayon` feature (each cell independent,
    /// collected in order: the result does not depend on the thread count).
    fn integrate_all(
        &self,
        tol: f64,
        hints: &[DVec3],
        g: &(impl Fn(Vec3) -> f64 + Sync + ?Sized),
    ) -> Vec<f64> {
        #[cfg(feature = "rayon")]
        {
            use rayon::prelude::*;
            (0..self.len())
                .into_par_iter()
                .map(|i| self.integrate(i, tol, hints, g))
                .collect()
        }
        #[cfg(not(feature = "rayon"))]
        {
            (0..self.len())
                .map(|i| self.integrate(i, tol, hints, g))
                .collect()
        }
    }
}

/// Most intervals one adaptive integration may split its range into.
const MAX_PIECES: usize = 200;
/// Most break points one adaptive integration starts from (a model gives at most four peak
/// hints).
const MAX_BREAKS: usize = 4;

/// Gauss–Kronrod 7–15 nodes on [0, 1] (QUADPACK's qk15), largest first; the last is 0.
const XGK: [f64; 8] = [
    0.991_455_371_120_812_6,
    0.949_107_912_342_758_5,
    0.864_864_423_359_769_1,
    0.741_531_185_599_394_4,
    0.586_087_235_467_691_1,
    0.405_845_151_377_397_2,
    0.207_784_955_007_898_5,
    0.0,
];
/// Kronrod weights for [`XGK`].
const WGK: [f64; 8] = [
    0.022_935_322_010_529_22,
    0.063_092_092_629_978_55,
    0.104_790_010_322_250_2,
    0.140_653_259_715_525_9,
    0.169_004_726_639_267_9,
    0.190_350_578_064_785_4,
    0.204_432_940_075_298_9,
    0.209_482_141_084_727_8,
];
/// Gauss weights for the odd-indexed nodes XGK[1], XGK[3], XGK[5] and XGK[7].
const WG: [f64; 4] = [
    0.129_484_966_168_869_7,
    0.279_705_391_489_276_7,
    0.381_830_050_505_118_9,
    0.417_959_183_673_469_4,
];

/// (Kronrod estimate, |Kronrod − Gauss|) of ∫_a^b f.
fn gk15(f: &(impl Fn(f64) -> f64 + ?Sized), a: f64, b: f64) -> (f64, f64) {
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let fc = f(c);
    let (mut k, mut g) = (WGK[7] * fc, WG[3] * fc);
    for j in 0..7 {
        let (x, w) = (XGK[j] * h, WGK[j]);
        let s = f(c - x) + f(c + x);
        k += w * s;
        if j % 2 == 1 {
            g += WG[j / 2] * s;
        }
    }
    (k * h, (k - g).abs() * h)
}

/// Globally adaptive [`gk15`] (QUADPACK's QAG strategy): keep bisecting the interval with the
/// largest error estimate until the estimates sum to at most `tol`, or `limit` intervals
/// exist. Unlike halving the tolerance per level, this spends evaluations only where the
/// error is: a kink or a jump costs one chain of bisections, not a full-depth tree, and the
/// limit bounds the work on integrands that never meet the tolerance.
///
/// `breaks` (at most [`MAX_BREAKS`] are used): points where f may peak (a model's peak
/// hints). The range is first cut at those inside it, QUADPACK's QAGP: a lobe narrower than
/// the spacing of the 15 nodes then sits at the end of a piece, beside its outermost node,
/// instead of between two nodes, where every node sees 0, the error estimate is 0 and the
/// lobe is lost. Without a break inside (a, b) this is plain QAG, bit for bit.
fn adaptive(
    f: &(impl Fn(f64) -> f64 + ?Sized),
    a: f64,
    b: f64,
    breaks: &[f64],
    tol: f64,
    limit: usize,
) -> f64 {
    /// An interval with its estimate and error, ordered by error (ties by position, so the
    /// order of bisection is fully determined by the integrand).
    struct Piece {
        a: f64,
        b: f64,
        value: f64,
        err: f64,
    }
    impl PartialEq for Piece {
        fn eq(&self, other: &Self) -> bool {
            self.cmp(other) == core::cmp::Ordering::Equal
        }
    }
    impl Eq for Piece {}
    impl PartialOrd for Piece {
        fn partial_cmp(&self, other: &Self) -> Option<core::cmp::Ordering> {
            Some(self.cmp(other))
        }
    }
    impl Ord for Piece {
        fn cmp(&self, other: &Self) -> core::cmp::Ordering {
            self.err
                .total_cmp(&other.err)
                .then(other.a.total_cmp(&self.a))
        }
    }
    // The ends of the first pieces: a, the breaks inside (a, b) in order, b.
    let mut ends = [a; MAX_BREAKS + 2];
    let mut n = 1;
    for &x in breaks.iter().take(MAX_BREAKS) {
        if x > a && x < b {
            ends[n] = x;
            n += 1;
        }
    }
    ends[1..n].sort_unstable_by(f64::total_cmp);
    ends[n] = b;
    n += 1;
    let mut heap = alloc::collections::BinaryHeap::with_capacity(limit.min(1024));
    let (mut total_err, mut finite) = (0.0, true);
    for w in ends[..n].windows(2) {
        if w[1] > w[0] {
            let (value, err) = gk15(f, w[0], w[1]);
            finite &= err.is_finite();
            total_err += err;
            heap.push(Piece {
                a: w[0],
                b: w[1],
                value,
                err,
            });
        }
    }
    while finite && total_err > tol && heap.len() < limit {
        let Some(p) = heap.pop() else { break };
        let c = 0.5 * (p.a + p.b);
        if !(c > p.a && c < p.b) {
            // The interval cannot be split in f64: keep it as it is and stop.
            heap.push(p);
            break;
        }
        let (v0, e0) = gk15(f, p.a, c);
        let (v1, e1) = gk15(f, c, p.b);
        if !(e0.is_finite() && e1.is_finite()) {
            heap.push(p);
            break;
        }
        total_err += e0 + e1 - p.err;
        heap.push(Piece {
            a: p.a,
            b: c,
            value: v0,
            err: e0,
        });
        heap.push(Piece {
            a: c,
            b: p.b,
            value: v1,
            err: e1,
        });
    }
    // Sum in order of position, so the result does not depend on the heap's layout.
    let mut pieces = heap.into_vec();
    pieces.sort_unstable_by(|x, y| x.a.total_cmp(&y.a));
    pieces.iter().map(|p| p.value).sum()
}

/// The regularised upper incomplete gamma function Q(a, x) = Γ(a, x)/Γ(a), a > 0, x ≥ 0:
/// the series for P below x = a + 1, Lentz's continued fraction above (Numerical Recipes
/// §6.2), to full double precision. NaN for invalid arguments.
#[must_use]
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if a.is_nan() || x.is_nan() || a <= 0.0 || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return 1.0;
    }
    if x == f64::INFINITY {
        return 0.0;
    }
    let front = m::exp(-x + a * m::ln(x) - ln_gamma(a));
    if x < a + 1.0 {
        let (mut ap, mut del) = (a, 1.0 / a);
        let mut sum = del;
        for _ in 0..100_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-17 {
                break;
            }
        }
        1.0 - sum * front
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..100_000 {
            let an = -f64::from(i) * (f64::from(i) - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-17 {
                break;
            }
        }
        front * h
    }
}

/// The per-test significance that keeps the family-wise rate of `tests` independent tests at
/// `alpha` (Šidák): 1 − (1 − α)^(1/k).
#[must_use]
pub fn sidak(alpha: f64, tests: usize) -> f64 {
    1.0 - m::exp(m::ln_1p(-alpha) / tests.max(1) as f64)
}

/// A Pearson χ² goodness-of-fit result.
#[derive(Clone, Debug, PartialEq)]
pub struct ChiSquare {
    /// The statistic Σ (O − E)²/E over the bins after pooling.
    pub statistic: f64,
    /// Degrees of freedom: bins − 1.
    pub dof: usize,
    /// P(χ²_dof ≥ statistic): Q(dof/2, statistic/2).
    pub p_value: f64,
    /// Bins after pooling (cells expected below 5 are merged, smallest first).
    pub bins: usize,
}

/// Pearson's χ² of `observed` counts against `expected` counts (same length), pooling
/// cells whose expected count is below 5 (in increasing order of expectation, until each pool
/// reaches 5; a last short pool joins the previous bin). `None` when fewer than two bins
/// remain (no degree of freedom).
#[must_use]
pub fn chi_square(observed: &[u64], expected: &[f64]) -> Option<ChiSquare> {
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]).then(a.cmp(&b)));
    let mut bins: Vec<(f64, f64)> = Vec::new();
    let (mut pe, mut po) = (0.0, 0.0);
    for k in order {
        let (e, o) = (expected[k], observed[k] as f64);
        if e >= 5.0 && pe == 0.0 {
            bins.push((o, e));
            continue;
        }
        pe += e;
        po += o;
        if pe >= 5.0 {
            bins.push((po, pe));
            (pe, po) = (0.0, 0.0);
        }
    }
    if pe > 0.0 || po > 0.0 {
        match bins.last_mut() {
            Some(last) => {
                last.0 += po;
                last.1 += pe;
            }
            None => bins.push((po, pe)),
        }
    }
    if bins.len() < 2 {
        return None;
    }
    let statistic: f64 = bins.iter().map(|&(o, e)| (o - e) * (o - e) / e).sum();
    let dof = bins.len() - 1;
    Some(ChiSquare {
        statistic,
        dof,
        p_value: gamma_q(0.5 * dof as f64, 0.5 * statistic),
        bins: bins.len(),
    })
}

/// The seed's §4 statistic: a_i = (n_i/m)/I_i over the cells expected to receive at least
/// [`Spread::MIN_EXPECTED`] samples, relative to the constant a = 1/Σ I.
#[derive(Clone, Debug, PartialEq)]
pub struct Spread {
    /// a = 1/Σ I_i (I_i = ∫ over cell i of the luminance of f_r, per disk area).
    pub a: f64,
    /// Cells counted.
    pub cells: usize,
    /// min over the counted cells of a_i/a.
    pub min: f64,
    /// max of a_i/a.
    pub max: f64,
    /// Root mean square of a_i/a − 1.
    pub rms: f64,
    /// The RMS that counting noise alone gives, √(mean of 1/E_i) over the counted cells:
    /// an exact sampler has `rms` ≈ `noise`.
    pub noise: f64,
}

impl Spread {
    /// Cells expected to receive fewer samples than this are left out of the spread (their
    /// a_i is noise: the relative standard deviation of a count of 100 is 10 %).
    pub const MIN_EXPECTED: f64 = 100.0;
}

/// Everything one test found.
#[derive(Clone, Debug)]
pub struct Report {
    /// The sampler's name.
    pub sampler: &'static str,
    /// Samples drawn.
    pub samples: u64,
    /// Samples per cell (row-major, as [`CellGrid::dims`]).
    pub observed: Vec<u64>,
    /// Expected samples per cell under f·cos (m · I_i / Σ I).
    pub expected: Vec<f64>,
    /// Expected samples per cell under the sampler's own pdf.
    pub expected_own: Vec<f64>,
    /// Samples the sampler gave no direction for.
    pub lost: u64,
    /// Samples outside the domain (non-finite or at/below the horizon) or flagged delta.
    pub outside: u64,
    /// Samples whose pdf or weight disagreed with `pdf(wo)` or f·cos/pdf.
    pub inconsistent: u64,
    /// Samples in cells where f·cos integrates to 0.
    pub in_empty_cells: u64,
    /// χ² against f·cos (`None`: too few degrees of freedom).
    pub chi2: Option<ChiSquare>,
    /// χ² against the sampler's own pdf, with a bin for lost samples.
    pub chi2_own: Option<ChiSquare>,
    /// The seed's a_i spread (`None` when no cell expects enough samples).
    pub spread: Option<Spread>,
    /// The per-test significance the p-values were judged at.
    pub alpha: f64,
    /// Why the test rejected (empty when nothing rejected).
    pub reasons: Vec<String>,
    /// The reasons that concern the sampler judged against its own pdf alone: invalid
    /// masses, a pdf integrating above 1, the χ² against its own pdf, samples outside the
    /// domain, inconsistent samples, every sample lost. A sampler that is exact for its own
    /// pdf but not ∝ f·cos (an analytic lobe sampler, the warp) has none.
    pub own_reasons: Vec<String>,
    /// Why the test could not judge (too few degrees of freedom for a χ²: too few samples
    /// or cells). Such a test neither passes nor rejects: see [`Verdict::Inconclusive`].
    pub inconclusive: Vec<String>,
    /// The part of [`Report::inconclusive`] that concerns the sampler's own pdf alone.
    pub own_inconclusive: Vec<String>,
}

/// A test's outcome. A rejection outranks an inconclusive test: a sampler that put samples
/// outside the domain is wrong however few samples were drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Every test ran and none rejected.
    Passed,
    /// A test rejected (see [`Report::reasons`]).
    Rejected,
    /// Nothing rejected, but a test could not be run (see [`Report::inconclusive`]).
    Inconclusive,
}

impl Verdict {
    fn of(reasons: &[String], inconclusive: &[String]) -> Self {
        if !reasons.is_empty() {
            Self::Rejected
        } else if !inconclusive.is_empty() {
            Self::Inconclusive
        } else {
            Self::Passed
        }
    }
}

impl Report {
    /// True when every test ran and nothing rejected.
    #[must_use]
    pub fn passed(&self) -> bool {
        self.verdict() == Verdict::Passed
    }

    /// True when the sampler is right about its own pdf (see [`Report::own_reasons`]),
    /// whether or not that pdf follows f·cos.
    #[must_use]
    pub fn passed_own(&self) -> bool {
        self.verdict_own() == Verdict::Passed
    }

    /// The outcome against f·cos and the sampler's own pdf (SPEC §5).
    #[must_use]
    pub fn verdict(&self) -> Verdict {
        Verdict::of(&self.reasons, &self.inconclusive)
    }

    /// The outcome against the sampler's own pdf alone.
    #[must_use]
    pub fn verdict_own(&self) -> Verdict {
        Verdict::of(&self.own_reasons, &self.own_inconclusive)
    }
}

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

/// A validation set-up for one BRDF and incident direction: the cells and their expected
/// mass under f_r·cos, integrated once, independently of any sampler.
#[derive(Clone, Debug)]
pub struct Validation<'a, B: Brdf + ?Sized> {
    brdf: &'a B,
    wi: Vec3,
    grid: CellGrid,
    tol: f64,
    /// The model's peak hints for `wi`, where every cell's integration cuts its ranges.
    hints: Vec<DVec3>,
    /// ∫ Y(f_r) dA per cell (the seed's I_i, unnormalised).
    mass: Vec<f64>,
}

impl<'a, B: Brdf + ?Sized> Validation<'a, B> {
    /// Integrates the luminance of f_r over every cell. `tol` is the absolute error allowed
    /// per cell **relative to the total** (1e-7: for 10⁶ samples, 0.1 expected sample per
    /// cell at worst). `wi` must be above the horizon; the model must have a continuous part.
    pub fn new(brdf: &'a B, wi: Vec3, grid: CellGrid, tol: f64) -> Result<Self, BuildError> {
        let wi = unit_direction_above(wi)?;
        grid.check()?;
        if brdf.is_delta() {
            return Err(BuildError::DeltaModel { model: brdf.name() });
        }
        if !(tol > 0.0 && tol < 1.0) {
            return Err(BuildError::OutOfRange {
                option: "validation tolerance",
                value: tol,
                expected: "in (0, 1)",
            });
        }
        let f = |w: Vec3| f64::from(brdf.eval_luminance(wi, w));
        // The model's own peak directions (data of the model, not of any sampler): a lobe
        // narrower than a cell's node spacing is found there (see `adaptive`).
        let hints: Vec<DVec3> = brdf
            .peak_hints(brdf_core::geometry::lift_incident(wi))
            .as_slice()
            .iter()
            .map(|h| h.as_dvec3())
            .collect();
        // A coarse total sets the absolute scale of the tolerance.
        let coarse: f64 = CellGrid::Polar {
            rings: 8,
            sectors: 16,
        }
        .integrate_all(1e-3, &hints, &f)
        .iter()
        .sum();
        let abs_tol = tol * coarse.abs().max(1e-300);
        let mass = grid.integrate_all(abs_tol, &hints, &f);
        Ok(Self {
            brdf,
            wi,
            grid,
            tol: abs_tol,
            hints,
            mass,
        })
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

    /// Draws `samples` directions from `sampler` (which must be for this BRDF and `wi`),
    /// histograms them, and judges them at per-test significance `alpha` (see [`sidak`]).
    /// Serial: one random stream for all samples.
    pub fn test<S: DirectionSampler + ?Sized>(
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
    /// their own streams: chunk k (samples k·CHUNK ..) uses `rng_for_chunk(k)`. With the
    /// `rayon` feature the chunks run in parallel; the counts are summed in chunk order, so
    /// the report is bit-identical to the serial run and does not depend on the thread count.
    pub fn test_chunked<S, R, F>(
        &self,
        sampler: &S,
        samples: u64,
        rng_for_chunk: F,
        alpha: f64,
    ) -> Report
    where
        S: DirectionSampler + ?Sized,
        R: Rng,
        F: Fn(u64) -> R + Sync,
    {
        let chunks = samples.div_ceil(CHUNK);
        let one = |k: u64| {
            let mut rng = rng_for_chunk(k);
            self.count(sampler, k * CHUNK..samples.min((k + 1) * CHUNK), &mut rng)
        };
        #[cfg(feature = "rayon")]
        let parts: Vec<Counts> = {
            use rayon::prelude::*;
            (0..chunks).into_par_iter().map(one).collect()
        };
        #[cfg(not(feature = "rayon"))]
        let parts: Vec<Counts> = (0..chunks).map(one).collect();
        let mut total = Counts::new(self.grid.len());
        for p in &parts {
            total.add(p);
        }
        self.judge(sampler, samples, total, alpha)
    }

    /// Histograms the samples with indices in `range` (the index decides which samples get
    /// the consistency check: every one of the first 10⁴, then one in 64).
    fn count<S: DirectionSampler + ?Sized>(
        &self,
        sampler: &S,
        range: core::ops::Range<u64>,
        rng: &mut dyn Rng,
    ) -> Counts {
        let mut c = Counts::new(self.grid.len());
        for k in range {
            let Some(s) = sampler.sample(rng) else {
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
                let w = luminance(s.f) * s.wo.z / s.pdf;
                let ok_pdf = (p - s.pdf).abs() <= 1e-4 * s.pdf.abs().max(p.abs());
                let ok_w = (luminance(s.weight) - w).abs() <= 1e-4 * w.abs() + 1e-30;
                if !(ok_pdf && ok_w) {
                    c.inconsistent += 1;
                }
            }
        }
        c
    }

    /// Judges histogrammed counts.
    fn judge<S: DirectionSampler + ?Sized>(
        &self,
        sampler: &S,
        samples: u64,
        counts: Counts,
        alpha: f64,
    ) -> Report {
        // (reason, whether it also concerns the sampler judged against its own pdf)
        let mut reasons: Vec<(String, bool)> = Vec::new();
        let total: f64 = self.mass.iter().sum();
        if !(total > 0.0 && total.is_finite()) || self.mass.iter().any(|&x| x.is_nan() || x < 0.0) {
            reasons.push((format!(
                "the expected masses are not a distribution (total {total}, a negative or NaN cell)"
            ),
                true,
            ));
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
        // χ² against the sampler's own pdf: ∫ pdf dω = ∫ pdf / cos θ dA.
        let own = self
            .grid
            .integrate_all(self.tol / total.max(1e-300), &self.hints, &|w: Vec3| {
                let p = f64::from(sampler.pdf(w));
                if w.z > 0.0 { p / f64::from(w.z) } else { 0.0 }
            });
        let own_total: f64 = own.iter().sum();
        let mut expected_own: Vec<f64> = own.iter().map(|x| m * x).collect();
        let mut observed_own = observed.clone();
        expected_own.push(m * (1.0 - own_total).max(0.0));
        observed_own.push(lost);
        let chi2_own = chi_square(&observed_own, &expected_own);
        expected_own.pop();
        if own_total > 1.0 + 1e-3 {
            reasons.push((
                format!("the sampler's pdf integrates to {own_total:.5} > 1"),
                true,
            ));
        }
        let mut inconclusive: Vec<(String, bool)> = Vec::new();
        for (label, test, is_own) in [("f·cos", &chi2, false), ("its own pdf", &chi2_own, true)] {
            match test {
                None => inconclusive.push((
                    format!(
                        "too few degrees of freedom for the χ² against {label}: use more samples or cells"
                    ),
                    is_own,
                )),
                Some(c) if c.p_value.is_nan() || c.p_value < alpha => reasons.push((
                    format!(
                        "χ² against {label} = {:.1} with {} dof: p = {:.3e} < α = {alpha:.3e}",
                        c.statistic, c.dof, c.p_value
                    ),
                    is_own,
                )),
                Some(_) => {}
            }
        }
        if samples > 0 && lost == samples {
            reasons.push((
                format!("every one of the {samples} samples was lost: the sampler drew nothing"),
                true,
            ));
        } else if lost > 0 {
            reasons.push((
                format!(
                    "{lost} samples carried no direction, though f·cos puts every sample somewhere"
                ),
                false,
            ));
        }
        if outside > 0 {
            reasons.push((format!(
                "{outside} samples outside the domain (non-finite, at or below the horizon, or delta)"
            ), true));
        }
        if in_empty_cells > 0 {
            reasons.push((
                format!("{in_empty_cells} samples in cells where f·cos integrates to 0"),
                false,
            ));
        }
        if inconsistent > 0 {
            reasons.push((
                format!(
                    "{inconsistent} samples whose pdf or weight disagrees with pdf(wo) or f·cos/pdf"
                ),
                true,
            ));
        }
        Report {
            sampler: sampler.name(),
            samples,
            spread: spread(&observed, &self.mass, &expected, m),
            observed,
            expected,
            expected_own,
            lost,
            outside,
            inconsistent,
            in_empty_cells,
            chi2,
            chi2_own,
            alpha,
            own_reasons: reasons
                .iter()
                .filter(|r| r.1)
                .map(|r| r.0.clone())
                .collect(),
            reasons: reasons.into_iter().map(|r| r.0).collect(),
            own_inconclusive: inconclusive
                .iter()
                .filter(|r| r.1)
                .map(|r| r.0.clone())
                .collect(),
            inconclusive: inconclusive.into_iter().map(|r| r.0).collect(),
        }
    }

    /// The BRDF under test.
    #[must_use]
    pub fn brdf(&self) -> &B {
        self.brdf
    }

    /// The (normalised) incident direction.
    #[must_use]
    pub fn wi(&self) -> Vec3 {
        self.wi
    }
}

fn spread(observed: &[u64], mass: &[f64], expected: &[f64], m: f64) -> Option<Spread> {
    let total: f64 = mass.iter().sum();
    let a = 1.0 / total;
    let ratios: Vec<(f64, f64)> = observed
        .iter()
        .zip(mass)
        .zip(expected)
        .filter(|&(_, &e)| e >= Spread::MIN_EXPECTED)
        .map(|((&o, &i), &e)| ((o as f64 / m) / i / a, e))
        .collect();
    if ratios.is_empty() {
        return None;
    }
    let (mut min, mut max, mut ss, mut inv) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0.0);
    for &(r, e) in &ratios {
        min = min.min(r);
        max = max.max(r);
        ss += (r - 1.0) * (r - 1.0);
        inv += 1.0 / e;
    }
    let k = ratios.len() as f64;
    Some(Spread {
        a,
        cells: ratios.len(),
        min,
        max,
        rms: m::sqrt(ss / k),
        noise: m::sqrt(inv / k),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_kronrod_rules_are_exact_to_their_degree() {
        for k in 0..=22 {
            let (kr, _) = gk15(&|x: f64| m::pow(x, f64::from(k)), 0.0, 1.0);
            assert!((kr - 1.0 / f64::from(k + 1)).abs() < 1e-15, "K15 x^{k}");
        }
        // The embedded Gauss rule is exact to degree 13, so the error estimate vanishes there.
        for k in 0..=13 {
            let (_, err) = gk15(&|x: f64| m::pow(x, f64::from(k)), 0.0, 1.0);
            assert!(err < 1e-15, "G7 x^{k}: {err}");
        }
        let s = adaptive(&|x: f64| m::sqrt(x), 0.0, 1.0, &[], 1e-12, 200);
        assert!((s - 2.0 / 3.0).abs() < 1e-11);
    }

    #[test]
    fn adaptive_resolves_kinks_and_jumps_with_few_evaluations() {
        let count = core::cell::Cell::new(0u32);
        let c = 1.0 / PI;
        let kink = |x: f64| {
            count.set(count.get() + 1);
            (x - c).abs()
        };
        let exact = 0.5 * (c * c + (1.0 - c) * (1.0 - c));
        let s = adaptive(&kink, 0.0, 1.0, &[], 1e-12, MAX_PIECES);
        assert!((s - exact).abs() < 1e-12, "{s} vs {exact}");
        // One chain of bisections toward the kink, not a full-depth tree.
        assert!(count.get() < 1500, "{} evaluations", count.get());
        count.set(0);
        let jump = |x: f64| {
            count.set(count.get() + 1);
            if x < c { 1.0 } else { 3.0 }
        };
        let s = adaptive(&jump, 0.0, 1.0, &[], 1e-9, MAX_PIECES);
        assert!((s - (c + 3.0 * (1.0 - c))).abs() < 1e-9, "{s}");
        assert!(count.get() < 2000, "{} evaluations", count.get());
        // The limit bounds the work when the tolerance cannot be met.
        count.set(0);
        let _ = adaptive(&jump, 0.0, 1.0, &[], 0.0, 50);
        assert!(count.get() <= 15 * (2 * 50), "{} evaluations", count.get());
    }

    #[test]
    fn gamma_q_matches_published_values() {
        // Q(1, x) = e^{-x}; Q(1/2, x) = erfc(√x).
        for x in [0.1, 1.0, 5.0, 30.0] {
            assert!((gamma_q(1.0, x) - m::exp(-x)).abs() < 1e-15 * 10.0);
            let e = brdf_core::special::erfc(m::sqrt(x));
            assert!((gamma_q(0.5, x) - e).abs() <= 1e-13 * e);
        }
        // χ² critical values at α = 0.05 (Abramowitz & Stegun table 26.8; NIST handbook).
        for (dof, crit) in [
            (1.0, 3.841_459),
            (10.0, 18.307_04),
            (100.0, 124.342_1),
            (1000.0, 1_074.679),
        ] {
            let p = gamma_q(0.5 * dof, 0.5 * crit);
            assert!((p - 0.05).abs() < 2e-6, "dof {dof}: p = {p}");
        }
        assert!(gamma_q(-1.0, 1.0).is_nan());
        assert_eq!(gamma_q(2.0, 0.0), 1.0);
    }

    #[test]
    fn sidak_correction() {
        assert!((sidak(0.01, 1) - 0.01).abs() < 1e-15);
        let a = sidak(0.01, 100);
        assert!((1.0 - m::pow(1.0 - a, 100.0) - 0.01).abs() < 1e-12);
    }

    #[test]
    fn pooling_and_dof() {
        let expected = [100.0, 100.0, 2.0, 2.0, 2.0, 0.5];
        let observed = [95, 105, 3, 1, 2, 1];
        let c = chi_square(&observed, &expected).unwrap();
        // bins: pool {0.5, 2, 2, 2} = 6.5 vs 7 observed, and the two big cells.
        assert_eq!(c.bins, 3);
        assert_eq!(c.dof, 2);
        let want = 0.25 + 0.25 + (7.0 - 6.5) * (7.0 - 6.5) / 6.5;
        assert!((c.statistic - want).abs() < 1e-12);
        assert!(chi_square(&[1, 2], &[1.0, 2.0]).is_none());
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
            let area: f64 = grid.integrate_all(1e-10, &[], &|_| 1.0).iter().sum();
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
        let cells = g.integrate_all(1e-12, &[], &|_| 1.0);
        for c in &cells {
            assert!((c - PI / 15.0).abs() < 1e-10);
        }
        assert!(CellGrid::Square { res: 0 }.check().is_err());
    }
}
