//! The box a leaf is rejection-sampled in ([`Proposal`]): the seed's square, or, for a leaf
//! on the disk's rim, the smallest box of an angle or sine chart (see [`crate::chart`]).

use crate::chart::{
    Chart, ChartPoint, Rect, angle_point, angle_point_y, angle_y_coordinates,
    concentric_polar_point, polar_point, sine_point,
};
use brdf_core::DiskMap;
use brdf_core::math as m;
use core::f64::consts::{FRAC_PI_2, PI};
use glam::{DVec2, DVec3};

/// The (a, t) box of the rectangle [lo, hi] (x = sin a, y = cos a·sin t); `chart` names the
/// chart it is for (the transposed chart passes the rectangle with x and y exchanged).
fn angle_box(lo: DVec2, hi: DVec2, chart: Chart) -> Proposal {
    let (xa, xb) = (lo.x.clamp(-1.0, 1.0), hi.x.clamp(-1.0, 1.0));
    let (a0, a1) = (m::asin(xa), m::asin(xb));
    // t = asin(y / cos a) over the node: extremes at the a-ends or at a = 0.
    let (mut tlo, mut thi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut consider = |a: f64| {
        let ca = m::cos(a);
        if ca <= 0.0 {
            return;
        }
        tlo = tlo.min(m::asin((lo.y / ca).clamp(-1.0, 1.0)));
        thi = thi.max(m::asin((hi.y / ca).clamp(-1.0, 1.0)));
    };
    consider(a0);
    consider(a1);
    if a0 < 0.0 && a1 > 0.0 {
        consider(0.0);
    }
    if tlo.is_nan() || thi.is_nan() || tlo >= thi {
        (tlo, thi) = (-FRAC_PI_2, FRAC_PI_2);
    }
    Proposal {
        chart,
        lo: DVec2::new(a0, tlo),
        hi: DVec2::new(a1, thi),
        shape: Shape::FLAT,
    }
}

/// The largest value [`Shape::warp`] returns on an axis: the box's upper edges are open.
const BELOW_ONE: f64 = 1.0 - f64::EPSILON / 2.0;

/// How a leaf's height bound varies over its proposal box: a profile S over the box's unit
/// coordinates t ∈ [0, 1]², given by levels 1–63 of 63 (so S ∈ (0, 1], 1 where the profile
/// is highest) at control points. A *coarse* shape is bilinear over the box, from its four
/// corners in the child order of [`crate::chart::child_index`] ((0,0), (1,0), (0,1),
/// (1,1)); its six-bit levels fit the packed leaf's spare link bits. A *fine* shape has a
/// 3 × 3 grid of control points t = (i/2, j/2) and is bilinear in each quarter of the box,
/// so it can rise to a peak inside the box, which no bilinear profile can (its largest
/// value is at a corner); its five further levels go in the packed leaf's third data word.
///
/// A leaf whose f·Jacobian leans across its box (a lobe's flank, a Fresnel rise toward the
/// rim, a radial fall-off in the polar box) or peaks inside it wastes much of a flat box: its
/// height bound is the largest value, met in one place. Under M·S the trials are drawn with
/// density ∝ S ([`Shape::draw`]) and accepted when a height uniform in [0, M·S(t)) falls
/// below f·J, so what is accepted is still exactly ∝ f·J, for any S with M·S ≥ f·J; the
/// box's volume becomes area·M·mean(S) ([`Proposal::volume`]). [`Shape::FLAT`] (every level
/// 63) is the seed's flat box.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Shape {
    /// Levels at the control points t = (i/2, j/2), index 3j + i. A coarse shape uses the
    /// corners (0, 2, 6, 8) and keeps 0 elsewhere.
    grid: [u8; 9],
    /// Whether the edge midpoints and the centre are control points too.
    fine: bool,
}

/// The corners' places in a [`Shape`]'s control grid, in child order.
const CORNERS: [usize; 4] = [0, 2, 6, 8];

/// The places a fine [`Shape`] adds to its corners (edge midpoints and centre), in the
/// order of its packed word.
const FINE_EXTRA: [usize; 5] = [1, 3, 4, 5, 7];

/// Level k (six bits from bit 6k) of a packed shape word.
#[inline(always)]
fn packed_level(bits: u32, k: usize) -> u8 {
    ((bits >> (6 * k)) & 63) as u8
}

/// Marks a fine [`Shape`]'s packed word (bit 31; bit 30 stays clear).
const FINE_FLAG: u32 = 1 << 31;

impl Shape {
    /// The seed's flat box: S ≡ 1.
    pub const FLAT: Self = Self {
        grid: [63, 0, 63, 0, 0, 0, 63, 0, 63],
        fine: false,
    };

    /// A coarse shape from its corner levels (each 1–63, of 63), in child order; `None`
    /// when one is out of range.
    #[must_use]
    pub fn from_levels(levels: [u8; 4]) -> Option<Self> {
        if !levels.iter().all(|l| (1..=63).contains(l)) {
            return None;
        }
        let mut grid = [0; 9];
        for (&at, l) in CORNERS.iter().zip(levels) {
            grid[at] = l;
        }
        Some(Self { grid, fine: false })
    }

    /// A fine shape from the levels (each 1–63, of 63) at its 3 × 3 control points
    /// t = (i/2, j/2), index 3j + i; `None` when one is out of range. All 63 is
    /// [`Shape::FLAT`].
    #[must_use]
    pub fn from_grid(grid: [u8; 9]) -> Option<Self> {
        if !grid.iter().all(|l| (1..=63).contains(l)) {
            return None;
        }
        if grid == [63; 9] {
            return Some(Self::FLAT);
        }
        Some(Self { grid, fine: true })
    }

    /// The corner levels (each 1–63, of 63), in child order.
    #[must_use]
    pub fn levels(&self) -> [u8; 4] {
        CORNERS.map(|at| self.grid[at])
    }

    /// A fine shape's nine control levels (index 3j + i at t = (i/2, j/2)); `None` for a
    /// coarse one.
    #[must_use]
    pub fn grid(&self) -> Option<[u8; 9]> {
        self.fine.then_some(self.grid)
    }

    /// Whether this is [`Shape::FLAT`].
    #[inline]
    #[must_use]
    pub fn is_flat(&self) -> bool {
        // Byte by byte, not as one 10-byte comparison: a shape just decoded from its packed
        // words was stored a byte at a time, and a wide load over those stores waits for
        // them to retire (a store-forwarding stall: perf put 8.7 % of the baked warp pdf's
        // samples on it, though the pdf went only from 144 to 141 ns without it).
        // A coarse shape holds 0 off its corners and a fine one is never all 63, so the
        // corners and the flag decide.
        !self.fine && CORNERS.iter().all(|&at| self.grid[at] == 63)
    }

    /// The corner values S(0,0), S(1,0), S(0,1), S(1,1).
    #[inline]
    #[must_use]
    pub fn corners(&self) -> [f64; 4] {
        self.levels().map(|l| f64::from(l) / 63.0)
    }

    /// The levels of the bilinear piece that holds `t` and `t` in that piece's own unit
    /// coordinates: the whole box for a coarse shape, one quarter for a fine one (the upper
    /// quarter on a midline: the pieces agree there).
    #[inline]
    fn piece(&self, t: DVec2) -> ([u8; 4], DVec2) {
        if !self.fine {
            return (self.levels(), t);
        }
        let (q, u) = quarter(t);
        ([0, 1, 2, 3].map(|k| self.grid[piece_corner(q, k)]), u)
    }

    /// S at box coordinates `t` ∈ [0, 1]² (bilinear between the control points).
    #[inline]
    #[must_use]
    pub fn value(&self, t: DVec2) -> f64 {
        let (levels, u) = self.piece(t);
        bilinear(levels.map(|l| f64::from(l) / 63.0), u)
    }

    /// The mean of S over the box: of a coarse shape, the mean of its corners; of a fine
    /// one, the mean of its quarters' (corners once, edge midpoints twice, the centre four
    /// times, over 16).
    #[must_use]
    pub fn mean(&self) -> f64 {
        let l = |at: usize| f64::from(self.grid[at]) / 63.0;
        if !self.fine {
            return CORNERS.iter().map(|&at| l(at)).sum::<f64>() / 4.0;
        }
        let corners: f64 = CORNERS.iter().map(|&at| l(at)).sum();
        let edges = l(1) + l(3) + l(5) + l(7);
        (corners + 2.0 * edges + 4.0 * l(4)) / 16.0
    }

    /// Maps a uniform point `u` ∈ [0, 1)² to box coordinates t ∈ [0, 1)² with density
    /// S(t)/mean(S) (per unit box area, [`Shape::density`]): x from S's marginal, then y
    /// from its conditional at x. For a coarse shape each is linear over the box; for a
    /// fine one, linear in each half. Each axis finds its piece by comparing u's share of
    /// the mass with the first half's (a select, not a branch: the choice is a coin flip)
    /// and inverts the piece's quadratic CDF in the cancellation-free form
    /// s = 2V / (p + √(p² + 2(q − p)V)) (p, q the density's ends over the piece, V the mass
    /// wanted in it, in the piece's own units): one square root and one division an axis,
    /// on the levels as integers (the ratio S/mean(S) does not depend on their scale).
    /// Monotone in each coordinate, so stratified points stay stratified;
    /// [`Shape::invert`] undoes it. The identity for [`Shape::FLAT`]. (The rejection trials
    /// use [`Shape::draw`].)
    #[must_use]
    #[inline]
    pub fn warp(&self, u: DVec2) -> DVec2 {
        warp_levels(self.fine, |at| f64::from(self.grid[at]), u)
    }

    /// [`Shape::warp`] of the shape whose packed words ([`Shape::to_bits`],
    /// [`Shape::fine_bits`]) are `bits` (not 0: a flat leaf does not warp) and `fine`, read
    /// from the words themselves: the same levels in the same operations, so the same bits
    /// as decoding the shape first, without the round trip through memory that costs a
    /// stall where a shape was just decoded a byte at a time (the baked warp's leaf).
    #[must_use]
    #[inline(always)]
    pub(crate) fn warp_packed(bits: u32, fine: u32, u: DVec2) -> DVec2 {
        debug_assert!(bits != 0);
        let level = |at: usize| {
            let (word, k) = match at {
                0 => (bits, 0),
                2 => (bits, 1),
                6 => (bits, 2),
                8 => (bits, 3),
                1 => (fine, 0),
                3 => (fine, 1),
                4 => (fine, 2),
                5 => (fine, 3),
                _ => (fine, 4),
            };
            f64::from(packed_level(word, k))
        };
        warp_levels(fine != 0, level, u)
    }

    /// The inverse of [`Shape::warp`]: the uniform point it maps to box coordinates `t`
    /// (the marginal CDF of S in x at t.x, the conditional CDF in y there at t.y).
    #[must_use]
    pub fn invert(&self, t: DVec2) -> DVec2 {
        let l = |at: usize| f64::from(self.grid[at]);
        let t = t.clamp(DVec2::ZERO, DVec2::ONE);
        if !self.fine {
            let [c00, c10, c01, c11] = CORNERS.map(l);
            let ux = linear_cdf(t.x, c00 + c01, c10 + c11);
            let bottom = c00 + (c10 - c00) * t.x;
            let top = c01 + (c11 - c01) * t.x;
            return DVec2::new(ux, linear_cdf(t.y, bottom, top));
        }
        let column = |i: usize| l(i) + 2.0 * l(3 + i) + l(6 + i);
        let ux = halves_cdf(t.x, column(0), column(1), column(2));
        let row = |j: usize| {
            let (a, b, c) = (l(3 * j), l(3 * j + 1), l(3 * j + 2));
            if t.x < 0.5 {
                a + (b - a) * 2.0 * t.x
            } else {
                b + (c - b) * (2.0 * t.x - 1.0)
            }
        };
        DVec2::new(ux, halves_cdf(t.y, row(0), row(1), row(2)))
    }

    /// S(t)/mean(S) at box coordinates `t` ∈ [0, 1]²: the density per unit box area of
    /// [`Shape::warp`]'s points (1 for [`Shape::FLAT`]). From the integer levels, one
    /// division.
    #[must_use]
    #[inline(always)]
    pub fn density(&self, t: DVec2) -> f64 {
        // On the pdf's path (twice a baked warp pdf), so written out by hand: the piece's
        // corners by index, not through `piece`'s array maps, which the compiler left as a
        // call and a round trip through the stack (phong n = 1000's baked warp pdf spent
        // 22 % of its time here). The same operations in the same order: the same bits.
        let g = &self.grid;
        let l = |at: usize| f64::from(g[at]);
        // The sums of levels in integers (exact in f64 too: the same bits, one conversion).
        let n = |at: usize| u32::from(g[at]);
        let corners = n(0) + n(2) + n(6) + n(8);
        if !self.fine {
            let value = bilinear([l(0), l(2), l(6), l(8)], t);
            return 4.0 * value / f64::from(corners);
        }
        let ([i, j], u) = quarter(t);
        let base = 3 * j + i;
        let value = bilinear([l(base), l(base + 1), l(base + 3), l(base + 4)], u);
        let edges = n(1) + n(3) + n(5) + n(7);
        16.0 * value / f64::from(corners + 2 * edges + 4 * n(4))
    }

    /// Draws box coordinates t ∈ [0, 1)² with density S(t)/mean(S), as [`Shape::warp`] does,
    /// without its square roots and divisions: `pick` chooses a bilinear piece's corner k
    /// with probability level_k / Σ levels (over the four pieces of a fine shape, each
    /// piece's own corners: the pieces have equal areas), and `xy` (two 64-bit words: four
    /// 32-bit uniforms) places t under that corner's tensor-product hat 4·w_k over its piece
    /// — on each axis the larger of two uniforms (density 2x) toward the corner's high side,
    /// the smaller (2(1 − x)) toward its low side. The hats weighted by the levels sum to
    /// S/mean(S) exactly; the choice rounds `pick` to the levels' integer sum, so its
    /// probabilities are off by at most 2⁻³² each. The rejection trials use this one.
    #[inline]
    #[must_use]
    pub fn draw(&self, xy: [u64; 2], pick: u32) -> DVec2 {
        Prepared::new(*self).draw(xy, pick)
    }

    /// The coarse (bilinear) profile that bounds `points` (box coordinates t and heights
    /// h ≥ 0) with the least volume, as levels relative to its highest corner: the solution
    /// of the linear programme "least mean corner, S(tᵢ) ≥ hᵢ, every corner at least 1/63 of
    /// the largest height" (a simplex on its four-row dual, exact up to rounding), or where
    /// that fails to converge, a coordinate descent from the flat box (each corner in turn
    /// lowered as far as the points allow given the other three). Only the profile matters:
    /// the build's bound search then finds the largest h/S over the leaf, so the shape need
    /// not bound the points itself after rounding to levels. [`Shape::FLAT`] when no point
    /// is positive.
    #[must_use]
    pub fn fit(points: &[(DVec2, f64)]) -> Self {
        let Some((top, floor)) = heights(points) else {
            return Self::FLAT;
        };
        let weighted: alloc::vec::Vec<([f64; 4], f64)> = points
            .iter()
            .filter(|p| p.1 > 0.0)
            .map(|&(t, h)| (bilinear_weights(t.clamp(DVec2::ZERO, DVec2::ONE)), h))
            .collect();
        let c =
            least_bound(&weighted, [floor; 4]).unwrap_or_else(|| descend(&weighted, top, floor));
        let levels = to_levels(c);
        Self::from_levels(levels).unwrap_or(Self::FLAT)
    }

    /// The fine profile (bilinear in each quarter) that bounds `points` with the least
    /// volume, as [`Shape::fit`] finds the coarse one: the linear programme "least mean(S),
    /// S(tᵢ) ≥ hᵢ, every level at least 1/63 of the largest height" over the nine control
    /// values (mean(S) weighs corners 1, edge midpoints 2, the centre 4), solved by the
    /// simplex on its nine-row dual.
    #[must_use]
    pub fn fit_fine(points: &[(DVec2, f64)]) -> Self {
        let Some((top, floor)) = heights(points) else {
            return Self::FLAT;
        };
        // Each point's weights on the nine control values, divided by the control value's
        // share of the mean, so that the programme's objective is their plain sum.
        const SHARE: [f64; 9] = [1.0, 2.0, 1.0, 2.0, 4.0, 2.0, 1.0, 2.0, 1.0];
        let weighted: alloc::vec::Vec<([f64; 9], f64)> = points
            .iter()
            .filter(|p| p.1 > 0.0)
            .map(|&(t, h)| {
                let (q, u) = quarter(t.clamp(DVec2::ZERO, DVec2::ONE));
                let mut w = [0.0; 9];
                for (k, wk) in bilinear_weights(u).into_iter().enumerate() {
                    let place = piece_corner(q, k);
                    w[place] = wk / SHARE[place];
                }
                (w, h)
            })
            .collect();
        // In the scaled variables y = share·c each floor is share × the common one.
        let Some(y) = least_bound(&weighted, SHARE.map(|s| s * floor)) else {
            return Self::FLAT;
        };
        let c: [f64; 9] = core::array::from_fn(|k| y[k] / SHARE[k]);
        let high = c.iter().copied().fold(0.0, f64::max);
        if !(high > 0.0 && high.is_finite() && high >= top / 63.0) {
            return Self::FLAT;
        }
        Self::from_grid(to_levels(c)).unwrap_or(Self::FLAT)
    }

    /// The 24 bits a packed leaf keeps in its link (six a corner, corner 0 lowest); 0 for
    /// the flat box.
    pub(crate) fn to_bits(self) -> u32 {
        if self.is_flat() {
            return 0;
        }
        self.levels()
            .iter()
            .enumerate()
            .fold(0, |bits, (k, &l)| bits | u32::from(l) << (6 * k))
    }

    /// The word a packed leaf keeps for a fine shape's five further levels (edge midpoints
    /// and centre, six bits each from bit 0, [`FINE_FLAG`] set); 0 for a coarse shape.
    pub(crate) fn fine_bits(self) -> u32 {
        if !self.fine {
            return 0;
        }
        FINE_EXTRA
            .iter()
            .enumerate()
            .fold(FINE_FLAG, |bits, (k, &at)| {
                bits | u32::from(self.grid[at]) << (6 * k)
            })
    }

    /// The shape of bits [`Shape::from_bits`] accepted (a packed leaf's, checked when it
    /// was made or read), without checking them again: a sample decodes its leaf's shape.
    #[inline]
    pub(crate) fn from_checked_bits(bits: u32, fine: u32) -> Self {
        if bits == 0 {
            return Self::FLAT;
        }
        let mut grid = [0; 9];
        for (k, &at) in CORNERS.iter().enumerate() {
            grid[at] = packed_level(bits, k);
        }
        if fine != 0 {
            for (k, &at) in FINE_EXTRA.iter().enumerate() {
                grid[at] = packed_level(fine, k);
            }
        }
        Self {
            grid,
            fine: fine != 0,
        }
    }

    /// The shape of [`Shape::to_bits`] and [`Shape::fine_bits`]; `None` for bits that no
    /// shape writes (a level 0 in a non-zero word, bits above the 24 or between the fine
    /// word's levels and its flag, a fine word beside a flat link).
    pub(crate) fn from_bits(bits: u32, fine: u32) -> Option<Self> {
        if bits >> 24 != 0 {
            return None;
        }
        let corner = |k: usize| packed_level(bits, k);
        if fine == 0 {
            if bits == 0 {
                return Some(Self::FLAT);
            }
            return Self::from_levels([0, 1, 2, 3].map(corner));
        }
        if bits == 0 || fine & !(FINE_FLAG | ((1 << 30) - 1)) != 0 || fine & FINE_FLAG == 0 {
            return None;
        }
        let mut grid = [0; 9];
        for (k, &at) in CORNERS.iter().enumerate() {
            grid[at] = corner(k);
        }
        for (k, &at) in FINE_EXTRA.iter().enumerate() {
            grid[at] = packed_level(fine, k);
        }
        Self::from_grid(grid)
    }
}

/// [`Shape::warp`] from the shape's levels at its control points (`l`, by grid index).
#[inline(always)]
fn warp_levels(fine: bool, l: impl Fn(usize) -> f64, u: DVec2) -> DVec2 {
    if !fine {
        let [c00, c10, c01, c11] = CORNERS.map(l);
        let x = linear_inverse(u.x, c00 + c01, c10 + c11);
        let bottom = c00 + (c10 - c00) * x;
        let top = c01 + (c11 - c01) * x;
        return DVec2::new(x, linear_inverse(u.y, bottom, top));
    }
    // The marginal in x at column i (0, ½, 1): ∫ S dy, the trapezoid of its column.
    let column = |i: usize| l(i) + 2.0 * l(3 + i) + l(6 + i);
    let x = halves_inverse(u.x, column(0), column(1), column(2));
    // The conditional in y at x: the column values there, linear in y on each half.
    let (lower, f) = (x < 0.5, 2.0 * x);
    let row = |j: usize| {
        let (a, b, c) = (l(3 * j), l(3 * j + 1), l(3 * j + 2));
        let (p, q, s) = if lower { (a, b, f) } else { (b, c, f - 1.0) };
        p + (q - p) * s
    };
    DVec2::new(x, halves_inverse(u.y, row(0), row(1), row(2)))
}

/// The x ∈ [0, 1) where the CDF of the density ∝ (1 − x)·p + x·q on [0, 1] reaches `u`
/// (p, q > 0): with V = u·(p + q)/2, x = 2V / (p + √(p² + 2(q − p)V)). In f32 (its square
/// root and division are faster, on a warp sample's critical path: per-wi phong n = 1000
/// 182 → 172 ns), which places the point to 10⁻⁷ of the box: the density a sample reports
/// is read where its direction maps back to, so this rounding never makes it disagree with
/// `pdf`.
#[inline(always)]
fn linear_inverse(u: f64, p: f64, q: f64) -> f64 {
    let (p, q) = (p as f32, q as f32);
    let v = u as f32 * 0.5 * (p + q);
    let x = 2.0 * v / (p + m::sqrtf((p * p + 2.0 * (q - p) * v).max(0.0)));
    f64::from(x).min(BELOW_ONE)
}

/// The CDF of the density ∝ (1 − x)·p + x·q on [0, 1] at `x`.
#[inline]
fn linear_cdf(x: f64, p: f64, q: f64) -> f64 {
    ((2.0 * p * x + (q - p) * x * x) / (p + q)).clamp(0.0, 1.0)
}

/// The x ∈ [0, 1) where the CDF of the density linear on each half of [0, 1], with values
/// a, b, c (> 0) at 0, ½, 1, reaches `u`: the half by u's share of the mass (a select),
/// then that half's quadratic, s = 4V / (p + √(p² + 4(q − p)V)) with V the mass wanted in
/// it (its whole is (p + q)/4) and x = x₀ + s/2. In f32, as [`linear_inverse`].
#[inline(always)]
fn halves_inverse(u: f64, a: f64, b: f64, c: f64) -> f64 {
    let first = 0.25 * (a + b);
    let v = u * (first + 0.25 * (b + c));
    let lower = v < first;
    let (p, q, v, x0) = if lower {
        (a, b, v, 0.0)
    } else {
        (b, c, v - first, 0.5)
    };
    let (p, q, v) = (p as f32, q as f32, v as f32);
    let s = 4.0 * v / (p + m::sqrtf((p * p + 4.0 * (q - p) * v).max(0.0)));
    (x0 + 0.5 * f64::from(s)).min(BELOW_ONE)
}

/// The CDF of [`halves_inverse`]'s density at `x`.
#[inline]
fn halves_cdf(x: f64, a: f64, b: f64, c: f64) -> f64 {
    let first = 0.25 * (a + b);
    let total = first + 0.25 * (b + c);
    // The mass of a half's first s ∈ [0, 1] of it, density p to q: ½(p·s + (q − p)·s²/2).
    let part = |s: f64, p: f64, q: f64| 0.5 * (p * s + 0.5 * (q - p) * s * s);
    let mass = if x < 0.5 {
        part(2.0 * x, a, b)
    } else {
        first + part(2.0 * x - 1.0, b, c)
    };
    (mass / total).clamp(0.0, 1.0)
}

/// The quarter [i, j] of the box (column, row: 1 for the upper half, a midline going up)
/// that holds t, and t in that quarter's unit coordinates: a fine [`Shape`]'s piece.
#[inline(always)]
pub(crate) fn quarter(t: DVec2) -> ([usize; 2], DVec2) {
    let (i, j) = (usize::from(t.x >= 0.5), usize::from(t.y >= 0.5));
    (
        [i, j],
        DVec2::new(2.0 * t.x - i as f64, 2.0 * t.y - j as f64),
    )
}

/// The place in a fine [`Shape`]'s control grid of quarter [i, j]'s corner k (child order).
#[inline(always)]
fn piece_corner([i, j]: [usize; 2], k: usize) -> usize {
    3 * j + i + (k & 1) + 3 * (k >> 1)
}

/// The weights of a point t ∈ [0, 1]² on a bilinear piece's corners, in child order.
#[inline]
fn bilinear_weights(t: DVec2) -> [f64; 4] {
    let (x, y) = (t.x, t.y);
    [(1.0 - x) * (1.0 - y), x * (1.0 - y), (1.0 - x) * y, x * y]
}

/// A bilinear piece's value at its unit coordinates `u` from its corner values, in child
/// order (the one expression [`Shape::value`] and [`Prepared::value`] share).
#[inline(always)]
fn bilinear([c00, c10, c01, c11]: [f64; 4], u: DVec2) -> f64 {
    let bottom = c00 + (c10 - c00) * u.x;
    let top = c01 + (c11 - c01) * u.x;
    bottom + (top - bottom) * u.y
}

/// A level's value l/63, for l = 0…63 (the same bits as the division, made once).
const LEVEL_VALUE: [f64; 64] = {
    let mut v = [0.0; 64];
    let mut l = 0;
    while l < 64 {
        v[l] = l as f64 / 63.0;
        l += 1;
    }
    v
};

/// 2⁻³²: a 32-bit uniform (or a 32-bit half of a 64-bit draw) to [0, 1).
pub(crate) const TO_UNIT: f64 = 1.0 / 4_294_967_296.0;

/// The hat (index into `sums`, the running sums of the hats' levels) that `pick` chooses:
/// the first whose running sum passes pick·total/2³² (fixed counts, so the compares
/// unroll).
#[inline(always)]
fn first_hat<const N: usize>(sums: &[u32; N], pick: u32) -> usize {
    let point = (u64::from(pick) * u64::from(sums[N - 1])) >> 32;
    sums[..N - 1]
        .iter()
        .map(|&s| usize::from(point >= u64::from(s)))
        .sum::<usize>()
}

/// A point under hat k (child order) of a bilinear piece, in its unit coordinates: on each
/// axis the larger of the two 32-bit uniforms of a word toward the corner's high side, the
/// smaller toward its low side — chosen by a mask, not a branch: which one a trial takes is
/// a coin flip no predictor learns (as a branch, a simulated predictor missed it once a
/// sample on phong n = 1000).
#[inline(always)]
fn hat_point(xy: [u64; 2], k: usize) -> DVec2 {
    let pair = |r: u64, high: bool| {
        let (a, b) = ((r >> 32) as u32, r as u32);
        let mask = u32::from(high).wrapping_neg();
        f64::from((a.max(b) & mask) | (a.min(b) & !mask)) * TO_UNIT
    };
    DVec2::new(pair(xy[0], k & 1 == 1), pair(xy[1], k >> 1 == 1))
}

/// A coarse [`Shape`] made ready for a leaf's rejection trials: its corner values and its
/// four hats' running level sums (child order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Coarse {
    values: [f64; 4],
    sums: [u32; 4],
}

impl Coarse {
    /// From the corner levels (child order).
    #[inline(always)]
    fn new(levels: [u8; 4]) -> Self {
        let mut total = 0u32;
        Self {
            values: levels.map(|l| LEVEL_VALUE[usize::from(l & 63)]),
            sums: levels.map(|l| {
                total += u32::from(l);
                total
            }),
        }
    }

    /// [`Shape::value`].
    #[inline(always)]
    pub(crate) fn value(&self, t: DVec2) -> f64 {
        bilinear(self.values, t)
    }

    /// [`Shape::draw`].
    #[inline(always)]
    pub(crate) fn draw(&self, xy: [u64; 2], pick: u32) -> DVec2 {
        hat_point(xy, first_hat(&self.sums, pick))
    }
}

/// A fine [`Shape`] made ready for a leaf's rejection trials: its nine control values and
/// its sixteen (piece, corner) hats' running level sums.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Fine {
    /// The control values at t = (i/2, j/2), index 3j + i.
    values: [f64; 9],
    sums: [u32; 16],
}

impl Fine {
    /// From the nine control levels.
    #[inline]
    fn new(grid: [u8; 9]) -> Self {
        let mut sums = [0u32; 16];
        let mut total = 0u32;
        for (n, sum) in sums.iter_mut().enumerate() {
            let q = [(n >> 2) & 1, n >> 3];
            total += u32::from(grid[piece_corner(q, n & 3)]);
            *sum = total;
        }
        Self {
            values: grid.map(|l| LEVEL_VALUE[usize::from(l & 63)]),
            sums,
        }
    }

    /// [`Shape::value`].
    #[inline]
    pub(crate) fn value(&self, t: DVec2) -> f64 {
        let (q, u) = quarter(t);
        bilinear([0, 1, 2, 3].map(|k| self.values[piece_corner(q, k)]), u)
    }

    /// [`Shape::draw`].
    #[inline]
    pub(crate) fn draw(&self, xy: [u64; 2], pick: u32) -> DVec2 {
        let n = first_hat(&self.sums, pick);
        let (q, k) = (n >> 2, n & 3);
        let u = hat_point(xy, k);
        // (Below ½ in a lower piece; at most ½ + ½·(1 − 2⁻³²) < 1 in an upper one.)
        DVec2::new(0.5 * (u.x + (q & 1) as f64), 0.5 * (u.y + (q >> 1) as f64))
    }
}

/// A [`Shape`] made ready for a leaf's rejection trials: its control values in f64 and its
/// hats' running level sums, found once a sample rather than once a trial (and the kind
/// told apart once, before the trials). Its `draw` *is* [`Shape::draw`] and its `value`
/// gives [`Shape::value`]'s bits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Prepared {
    /// A coarse shape (the flat box included).
    Coarse(Coarse),
    /// A fine shape.
    Fine(Fine),
}

impl Prepared {
    /// The shape of a packed leaf's checked bits (see [`Shape::from_checked_bits`]) made
    /// ready, `None` for the flat box: a coarse shape's four levels are read from the bits
    /// as they are, without the control grid between.
    #[inline(always)]
    pub(crate) fn from_checked_bits(bits: u32, fine: u32) -> Option<Self> {
        if bits == 0 {
            return None;
        }
        if fine == 0 {
            let levels = [0, 1, 2, 3].map(|k| packed_level(bits, k));
            return Some(Self::Coarse(Coarse::new(levels)));
        }
        Some(Self::new(Shape::from_checked_bits(bits, fine)))
    }

    /// Prepares `shape`.
    #[inline]
    pub(crate) fn new(shape: Shape) -> Self {
        if shape.fine {
            Self::Fine(Fine::new(shape.grid))
        } else {
            Self::Coarse(Coarse::new(shape.levels()))
        }
    }

    /// [`Shape::draw`].
    #[inline]
    pub(crate) fn draw(&self, xy: [u64; 2], pick: u32) -> DVec2 {
        match self {
            Self::Coarse(c) => c.draw(xy, pick),
            Self::Fine(f) => f.draw(xy, pick),
        }
    }
}

/// The largest height of `points` and the floor every level keeps (1/63 of it); `None`
/// when no height is positive and finite.
fn heights(points: &[(DVec2, f64)]) -> Option<(f64, f64)> {
    let top = points.iter().map(|p| p.1).fold(0.0, f64::max);
    (top > 0.0 && top.is_finite()).then_some((top, top / 63.0))
}

/// Control values as levels relative to the highest (rounded to the nearest: + ½, then
/// truncated; every value is positive).
fn to_levels<const N: usize>(c: [f64; N]) -> [u8; N] {
    let high = c.iter().copied().fold(0.0, f64::max);
    c.map(|v| (v / high * 63.0 + 0.5).clamp(1.0, 63.0) as u8)
}

/// The box of a leaf in its sampling chart, and the map from chart coordinates back.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Proposal {
    /// The chart.
    pub chart: Chart,
    /// Lower corner of the box in chart coordinates.
    pub lo: DVec2,
    /// Upper corner.
    pub hi: DVec2,
    /// How the height bound varies over the box: M·S(q) bounds the height at q
    /// ([`Shape::FLAT`]: the seed's flat box, S ≡ 1).
    pub shape: Shape,
}

impl Proposal {
    /// The chart proposal for a node: the seed's square unless the node touches the rim
    /// (orthographic: the smaller of the two angle boxes) or the square's edge (concentric: the
    /// sine box). For a rim node the build may still choose the square, where f is bounded
    /// at the rim and the square's box is the smaller.
    #[must_use]
    pub fn for_node(map: DiskMap, rect: &Rect) -> Self {
        match map {
            DiskMap::Orthographic => {
                let (_, far) = rect.radius_range();
                if far < 1.0 - 1e-12 {
                    return Self {
                        chart: Chart::Square,
                        lo: rect.min,
                        hi: rect.max,
                        shape: Shape::FLAT,
                    };
                }
                // The smaller of the two angle boxes (ties to the seed's own chart).
                let (a, b) = (
                    Self::in_chart(rect, Chart::Angle),
                    Self::in_chart(rect, Chart::AngleY),
                );
                if b.area() < a.area() { b } else { a }
            }
            DiskMap::Concentric => {
                let edge = rect.min.x <= -1.0
                    || rect.min.y <= -1.0
                    || rect.max.x >= 1.0
                    || rect.max.y >= 1.0;
                if !edge {
                    return Self {
                        chart: Chart::Square,
                        lo: rect.min,
                        hi: rect.max,
                        shape: Shape::FLAT,
                    };
                }
                Self::in_chart(rect, Chart::Sine)
            }
        }
    }

    /// The polar box of a node whose part of the disk is a sector through the centre
    /// ([`Chart::Polar`], on either map): s ∈ [0, 1] and φ over the whole turn for the root,
    /// over its quadrant for a child of the root; `None` for any other node. (Squares are
    /// dyadic, so these comparisons are exact.)
    #[must_use]
    pub fn polar(rect: &Rect) -> Option<Self> {
        let corner = |v: f64| v == -1.0 || v == 0.0;
        let side = rect.max.x - rect.min.x;
        let sector = (side == 2.0 && rect.min == DVec2::NEG_ONE)
            || (side == 1.0 && corner(rect.min.x) && corner(rect.min.y));
        sector.then(|| Self::polar_box(rect))
    }

    /// The polar box of the root or one of its children (see [`Proposal::polar`]).
    fn polar_box(rect: &Rect) -> Self {
        let (lo, hi) = if rect.max.x - rect.min.x >= 2.0 {
            (-PI, PI)
        } else {
            match (rect.min.x >= 0.0, rect.min.y >= 0.0) {
                (true, true) => (0.0, FRAC_PI_2),
                (false, true) => (FRAC_PI_2, PI),
                (false, false) => (-PI, -FRAC_PI_2),
                (true, false) => (-FRAC_PI_2, 0.0),
            }
        };
        Self {
            chart: Chart::Polar,
            lo: DVec2::new(0.0, lo),
            hi: DVec2::new(1.0, hi),
            shape: Shape::FLAT,
        }
    }

    /// The proposal of `rect` in a given chart (the chart a packed leaf recorded). For the
    /// angle charts: the box of the node's (a, t) or (b, s) coordinates; for the polar chart,
    /// of the root or a child of the root (the only nodes a tree samples in it, and the only
    /// ones a packed tree accepts it for).
    #[must_use]
    pub fn in_chart(rect: &Rect, chart: Chart) -> Self {
        match chart {
            Chart::Polar => Self::polar_box(rect),
            Chart::Square => Self {
                chart,
                lo: rect.min,
                hi: rect.max,
                shape: Shape::FLAT,
            },
            Chart::Angle => angle_box(rect.min, rect.max, chart),
            Chart::AngleY => {
                let swap = |v: DVec2| DVec2::new(v.y, v.x);
                angle_box(swap(rect.min), swap(rect.max), chart)
            }
            Chart::Sine => {
                let s = |x: f64| m::asin(x.clamp(-1.0, 1.0));
                Self {
                    chart,
                    lo: DVec2::new(s(rect.min.x), s(rect.min.y)),
                    hi: DVec2::new(s(rect.max.x), s(rect.max.y)),
                    shape: Shape::FLAT,
                }
            }
        }
    }

    /// The box's area in chart units.
    #[must_use]
    pub fn area(&self) -> f64 {
        let d = self.hi - self.lo;
        d.x * d.y
    }

    /// The volume under the height bound M·S over the box: area × M × the shape's mean
    /// (area × M for a flat box).
    #[must_use]
    pub fn volume(&self, m: f64) -> f64 {
        self.area() * m * self.shape.mean()
    }

    /// The box coordinates (each in [0, 1]) of chart point `q`, the argument of
    /// [`Shape::value`].
    #[inline]
    #[must_use]
    pub fn unit(&self, q: DVec2) -> DVec2 {
        (q - self.lo) / (self.hi - self.lo)
    }

    /// The chart point at box coordinates `q`, or `None` when it falls outside the node or the
    /// disk (an automatic rejection).
    #[inline(always)]
    #[must_use]
    pub fn point(&self, map: DiskMap, rect: &Rect, q: DVec2) -> Option<ChartPoint> {
        match self.chart {
            Chart::Square => map.square_to_direction_f64(q).map(|w| ChartPoint {
                p: q,
                w,
                jacobian: 1.0,
            }),
            Chart::Angle => {
                let c = angle_point(q.x, q.y);
                (c.p.y >= rect.min.y && c.p.y < rect.max.y && c.jacobian > 0.0).then_some(c)
            }
            Chart::AngleY => {
                let c = angle_point_y(q.x, q.y);
                (c.p.x >= rect.min.x && c.p.x < rect.max.x && c.jacobian > 0.0).then_some(c)
            }
            Chart::Sine => Some(sine_point(q.x, q.y)),
            Chart::Polar => {
                // The box's φ-range is the node's quadrant (or the whole turn): only rounding
                // on its edges can carry a point out of the node.
                let c = match map {
                    DiskMap::Orthographic => polar_point(q.x, q.y),
                    DiskMap::Concentric => concentric_polar_point(q.x, q.y),
                };
                rect.contains_half_open(c.p).then_some(c)
            }
        }
    }

    /// Chart coordinates of a direction known to lie in this node (inverse of `point`).
    #[must_use]
    pub fn coordinates(&self, map: DiskMap, w: DVec3) -> DVec2 {
        match self.chart {
            Chart::Square => match map {
                DiskMap::Orthographic => DVec2::new(w.x, w.y),
                DiskMap::Concentric => brdf_core::maps::disk_to_square_concentric_f64(w.truncate()),
            },
            Chart::Angle => {
                let a = m::asin(w.x.clamp(-1.0, 1.0));
                let ca = m::cos(a);
                let t = if ca > 0.0 { m::atan2(w.y, w.z) } else { 0.0 };
                DVec2::new(a, t)
            }
            Chart::AngleY => angle_y_coordinates(w),
            Chart::Polar => DVec2::new(w.x * w.x + w.y * w.y, m::atan2(w.y, w.x)),
            Chart::Sine => {
                let p = brdf_core::maps::disk_to_square_concentric_f64(w.truncate());
                DVec2::new(m::asin(p.x.clamp(-1.0, 1.0)), m::asin(p.y.clamp(-1.0, 1.0)))
            }
        }
    }
}

/// The control values c of the profile Σₖ wₖ(tᵢ)·cₖ with the least sum that bounds every
/// weighted point (`weighted`: weights on the N control values and a height h), each value
/// at least its floor: the linear programme min Σc, W·c ≥ h, c ≥ floors. With
/// c = floors + x it is min Σx, W·x ≥ g (g = h − W·floors; points that the floors already
/// bound bind nothing), x ≥ 0, whose dual max g·y, Wᵀ·y ≤ 1, y ≥ 0 has N rows: the primal
/// simplex on the dual keeps an N × N basis (slacks first), enters the column of largest
/// reduced cost gᵢ − π·wᵢ, and stops when none is positive; the dual prices π are then
/// the optimal x. A coordinate descent (the coarse fit's fallback, [`descend`]) stops at the
/// first corner that cannot move alone, where a point near one corner pins two; the simplex
/// moves values together. `None` where it does not converge in 16·N pivots (degenerate
/// cycling) or meets a singular basis.
fn least_bound<const N: usize>(weighted: &[([f64; N], f64)], floors: [f64; N]) -> Option<[f64; N]> {
    let cols: alloc::vec::Vec<([f64; N], f64)> = weighted
        .iter()
        .map(|&(w, h)| (w, h - w.iter().zip(floors).map(|(a, b)| a * b).sum::<f64>()))
        .filter(|&(_, g)| g > 0.0)
        .collect();
    let scale = cols.iter().map(|c| c.1).fold(0.0, f64::max);
    // Basis: column indices; slack k is `cols.len() + k`.
    let slack = |k: usize| cols.len() + k;
    let column = |j: usize| -> ([f64; N], f64) {
        if j >= cols.len() {
            let mut e = [0.0; N];
            e[j - cols.len()] = 1.0;
            (e, 0.0)
        } else {
            cols[j]
        }
    };
    let mut basis: [usize; N] = core::array::from_fn(slack);
    // [B | I], reduced to [I | B⁻¹] each pivot (N ≤ 9: a few hundred operations).
    let width = 2 * N;
    let mut a = alloc::vec![0.0f64; N * width];
    for _ in 0..16 * N {
        a.fill(0.0);
        for (k, &j) in basis.iter().enumerate() {
            let (w, _) = column(j);
            for (r, wr) in w.iter().enumerate() {
                a[r * width + k] = *wr;
            }
            a[k * width + N + k] = 1.0;
        }
        for col in 0..N {
            let pivot = (col..N).max_by(|&p, &q| {
                a[p * width + col]
                    .abs()
                    .total_cmp(&a[q * width + col].abs())
            })?;
            if a[pivot * width + col].abs() < 1e-12 {
                return None;
            }
            for c in 0..width {
                a.swap(col * width + c, pivot * width + c);
            }
            let d = a[col * width + col];
            for c in 0..width {
                a[col * width + c] /= d;
            }
            for r in (0..N).filter(|&r| r != col) {
                let f = a[r * width + col];
                if f != 0.0 {
                    for c in 0..width {
                        a[r * width + c] -= f * a[col * width + c];
                    }
                }
            }
        }
        let inv = |r: usize, c: usize| a[r * width + N + c];
        // Prices π = c_Bᵀ·B⁻¹ and basic values β = B⁻¹·1.
        let cost: [f64; N] = basis.map(|j| column(j).1);
        let pi: [f64; N] = core::array::from_fn(|c| (0..N).map(|r| cost[r] * inv(r, c)).sum());
        let beta: [f64; N] = core::array::from_fn(|r| (0..N).map(|c| inv(r, c)).sum());
        // Entering: the largest reduced cost (a slack's is −πₖ).
        let mut best = (1e-12 * scale.max(f64::MIN_POSITIVE), None);
        for (k, &p) in pi.iter().enumerate() {
            if -p > best.0 {
                best = (-p, Some(slack(k)));
            }
        }
        for (j, (w, g)) in cols.iter().enumerate() {
            let reduced = g - w.iter().zip(pi).map(|(a, b)| a * b).sum::<f64>();
            if reduced > best.0 {
                best = (reduced, Some(j));
            }
        }
        let Some(enter) = best.1 else {
            return pi
                .iter()
                .all(|x| x.is_finite())
                .then(|| core::array::from_fn(|k| floors[k] + pi[k].max(0.0)));
        };
        // Leaving: the ratio test on d = B⁻¹·a.
        let (w, _) = column(enter);
        let d: [f64; N] = core::array::from_fn(|r| (0..N).map(|c| inv(r, c) * w[c]).sum());
        let leave = (0..N)
            .filter(|&r| d[r] > 1e-12)
            .min_by(|&p, &q| (beta[p] / d[p]).total_cmp(&(beta[q] / d[q])))?;
        basis[leave] = enter;
    }
    None
}

/// The coordinate descent behind [`Shape::fit`] where [`least_bound`] fails: from the
/// flat box at `top`, each corner in turn lowered as far as the points allow given the
/// other three (never below `floor`), until no corner moves by a thousandth of the top.
fn descend(weighted: &[([f64; 4], f64)], top: f64, floor: f64) -> [f64; 4] {
    let mut c = [top; 4];
    for _ in 0..24 {
        let mut moved: f64 = 0.0;
        for k in 0..4 {
            let mut need = floor;
            for (w, h) in weighted {
                if w[k] > 1e-9 {
                    let all = c[0] * w[0] + c[1] * w[1] + c[2] * w[2] + c[3] * w[3];
                    let rest = all - c[k] * w[k];
                    need = need.max((h - rest) / w[k]);
                }
            }
            let lowered = need.min(c[k]);
            moved = moved.max(c[k] - lowered);
            c[k] = lowered;
        }
        if moved <= 1e-3 * top {
            break;
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chart::tests::nodes;
    use rand_core::Rng;

    /// The warp read from a shape's packed words is the shape's own warp, bit for bit, for
    /// coarse and fine shapes (from random levels, and the extremes) at random points and
    /// on the box's edges and seams.
    #[test]
    fn the_packed_warp_is_the_shapes_warp() {
        let mut rng = rand_pcg::Pcg64::new(0x5eed, 0x6);
        let mut level = || 1 + (rng.next_u32() % 63) as u8;
        let mut shapes = alloc::vec![
            Shape::from_levels([1, 63, 1, 63]).unwrap(),
            Shape::from_grid([1, 63, 1, 63, 1, 63, 1, 63, 1]).unwrap(),
        ];
        for _ in 0..50 {
            shapes.push(Shape::from_levels([level(), level(), level(), level()]).unwrap());
            shapes.push(Shape::from_grid(core::array::from_fn(|_| level())).unwrap());
        }
        let mut points = alloc::vec![];
        for x in [0.0, 0.25, 0.5, 0.75, 1.0 - f64::EPSILON] {
            for y in [0.0, 0.5, 1.0 - f64::EPSILON] {
                points.push(DVec2::new(x, y));
            }
        }
        let mut rng = rand_pcg::Pcg64::new(0x5eed, 0x7);
        for _ in 0..200 {
            points.push(DVec2::new(
                crate::sampler::uniform_f64(&mut rng),
                crate::sampler::uniform_f64(&mut rng),
            ));
        }
        for shape in &shapes {
            let (bits, fine) = (shape.to_bits(), shape.fine_bits());
            assert_ne!(bits, 0, "{shape:?}");
            assert_eq!(Shape::from_checked_bits(bits, fine), *shape);
            for &u in &points {
                let (a, b) = (Shape::warp_packed(bits, fine, u), shape.warp(u));
                assert_eq!(
                    a.to_array().map(f64::to_bits),
                    b.to_array().map(f64::to_bits)
                );
            }
        }
    }

    /// `Shape::density` (hand-written for the pdf's path) is S/mean(S) from `value` and
    /// `mean`, on both sides of the fine quarters' seams and at the box's edges, and its
    /// midpoint sum over the box is 1, for coarse and fine shapes of every kind of slope.
    #[test]
    fn the_density_is_the_shape_over_its_mean() {
        let mut rng = rand_pcg::Pcg64::new(0x5eed, 0x5);
        let mut level = || 1 + (rng.next_u32() % 63) as u8;
        let mut shapes = alloc::vec![Shape::FLAT];
        for _ in 0..40 {
            shapes.push(Shape::from_levels([level(), level(), level(), level()]).unwrap());
            shapes.push(Shape::from_grid(core::array::from_fn(|_| level())).unwrap());
        }
        let ts = [0.0, 0.1, 0.3, 0.499_999, 0.5, 0.500_001, 0.77, 1.0];
        for shape in &shapes {
            let mean = shape.mean();
            for &x in &ts {
                for &y in &ts {
                    let t = DVec2::new(x, y);
                    let want = shape.value(t) / mean;
                    let got = shape.density(t);
                    assert!(
                        (got - want).abs() <= 1e-12 * want,
                        "{shape:?} at {t}: {got} {want}"
                    );
                }
            }
            let k = 64;
            let sum: f64 = (0..k * k)
                .map(|i| {
                    let t = (DVec2::new(f64::from(i % k), f64::from(i / k)) + 0.5) / f64::from(k);
                    shape.density(t)
                })
                .sum::<f64>()
                / f64::from(k * k);
            assert!((sum - 1.0).abs() < 1e-12, "{shape:?}: {sum}");
        }
    }

    /// At the angle chart's poles (±1, 0) its box keeps a t-range of π/2 however small the
    /// node; the chosen proposal must shrink with the node (area ~ s^{3/2}), at all four
    /// tangent points, and sample the node exactly (round trip).
    #[test]
    fn rim_boxes_shrink_at_the_poles() {
        for k in [4, 10, 19] {
            let s = 2.0f64.powi(-k);
            let nodes = [
                Rect::square(-1.0, 0.0, s),
                Rect::square(-1.0, -s, s),
                Rect::square(1.0 - s, 0.0, s),
                Rect::square(0.0, 1.0 - s, s),
                Rect::square(-s, -1.0, s),
            ];
            for r in nodes {
                let prop = Proposal::for_node(DiskMap::Orthographic, &r);
                assert!(
                    prop.area() <= 4.0 * s * s.sqrt(),
                    "{r:?}: {prop:?} area {} for side {s}",
                    prop.area()
                );
                for (i, j) in [(1, 1), (3, 5), (6, 2), (5, 6)] {
                    let q = prop.lo
                        + (prop.hi - prop.lo) * DVec2::new(f64::from(i) / 7.0, f64::from(j) / 7.0);
                    let Some(c) = prop.point(DiskMap::Orthographic, &r, q) else {
                        continue;
                    };
                    assert!(r.contains(c.p), "{r:?} {q} -> {}", c.p);
                    let back = prop.coordinates(DiskMap::Orthographic, c.w);
                    assert!((back - q).length() < 1e-6, "{r:?} {q} -> {back}");
                }
            }
        }
    }

    /// Every point of a rim node's part of the disk lies in its proposal box (otherwise
    /// rejection never proposes it: a hole in the sampled density).
    #[test]
    fn rim_boxes_cover_their_nodes() {
        let mut seed = 7u64;
        let mut u = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        // Every rim node at shallow depths; at deep ones, the rim nodes around the four
        // tangent points (±1, 0), (0, ±1), where the charts' poles are.
        let mut nodes = alloc::vec::Vec::new();
        for depth in [2i32, 4, 6] {
            let s = 2.0f64.powi(1 - depth);
            let n = 1i64 << depth;
            for k in 0..n * n {
                nodes.push(Rect::square(
                    -1.0 + (k % n) as f64 * s,
                    -1.0 + (k / n) as f64 * s,
                    s,
                ));
            }
        }
        for depth in [10i32, 15, 19] {
            let s = 2.0f64.powi(1 - depth);
            for i in -3..3 {
                for j in 0..4 {
                    let (a, b) = (f64::from(i) * s, f64::from(j) * s);
                    nodes.push(Rect::square(-1.0 + b, a, s));
                    nodes.push(Rect::square(1.0 - s - b, a, s));
                    nodes.push(Rect::square(a, -1.0 + b, s));
                    nodes.push(Rect::square(a, 1.0 - s - b, s));
                }
            }
        }
        for r in nodes {
            {
                let (near, far) = r.radius_range();
                if far < 1.0 - 1e-12 || near >= 1.0 {
                    continue;
                }
                let prop = Proposal::for_node(DiskMap::Orthographic, &r);
                for _ in 0..64 {
                    let p = r.min + (r.max - r.min) * DVec2::new(u(), u());
                    let r2 = p.length_squared();
                    if r2 >= 1.0 {
                        continue;
                    }
                    let w = DVec3::new(p.x, p.y, m::sqrt(1.0 - r2));
                    let q = prop.coordinates(DiskMap::Orthographic, w);
                    let pad = (prop.hi - prop.lo) * 1e-9 + DVec2::splat(1e-12);
                    assert!(
                        q.cmpge(prop.lo - pad).all() && q.cmple(prop.hi + pad).all(),
                        "{r:?} {prop:?}: {p} -> {q}"
                    );
                }
            }
        }
    }

    /// The polar boxes of the root and of its four children hold exactly their parts of the
    /// disk, on both maps: box area × ½ is that part's area (π, π/4) and the Jacobian is the
    /// map's (½, 2/π); every point of the part maps into the box and back; every box point
    /// maps into its node (or is refused), to the square point the map sends to its
    /// direction.
    #[test]
    fn polar_boxes_are_their_nodes_parts_of_the_disk() {
        let root = Rect::square(-1.0, -1.0, 2.0);
        let mut rects = alloc::vec![root];
        rects.extend(root.quadrants());
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            let jacobian = crate::chart::polar_jacobian(map);
            for &r in &rects {
                let prop = Proposal::polar(&r).expect("the root and its children are sectors");
                let part = if r == root { PI } else { PI / 4.0 };
                assert!((prop.area() * 0.5 - part).abs() < 1e-15, "{r:?}: {prop:?}");
                for i in 0..=16 {
                    for j in 0..=16 {
                        let q = prop.lo
                            + (prop.hi - prop.lo) * DVec2::new(f64::from(i), f64::from(j)) / 16.0;
                        let Some(c) = prop.point(map, &r, q) else {
                            // Only on the box's edges: the centre (s = 0), the rim (s = 1) and
                            // the node's own upper edges (half-open squares).
                            assert!(
                                i == 0 || i == 16 || j == 0 || j == 16,
                                "{map:?} {r:?}: {q} refused"
                            );
                            continue;
                        };
                        assert!(r.contains_half_open(c.p) && (c.w.length() - 1.0).abs() < 1e-15);
                        assert_eq!(c.jacobian, jacobian);
                        // (At the rim, s = 1, the rounded r² may not be 1: z is not 0 there,
                        // or the point falls outside the orthographic disk.)
                        if i < 16 {
                            let w = map.square_to_direction_f64(c.p).unwrap();
                            assert!((w - c.w).length() < 1e-14, "{map:?} {r:?}: {q}: {c:?}");
                        }
                        if i > 0 && i < 16 && j > 0 && j < 16 {
                            let back = prop.coordinates(map, c.w);
                            assert!((back - q).length() < 1e-12, "{r:?}: {q} -> {back}");
                        }
                    }
                }
                let mut k = 0u64;
                for _ in 0..512 {
                    k = k
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let u = DVec2::new((k >> 40) as f64, ((k >> 16) & 0xff_ffff) as f64)
                        / f64::from(1u32 << 24);
                    let p = r.min + (r.max - r.min) * u;
                    let Some(w) = map.square_to_direction_f64(p) else {
                        continue;
                    };
                    let q = prop.coordinates(map, w);
                    assert!(
                        q.cmpge(prop.lo).all() && q.cmple(prop.hi).all(),
                        "{map:?} {r:?}: {p} -> {q}"
                    );
                }
            }
        }
        // No other node is a sector.
        assert!(Proposal::polar(&Rect::square(-0.5, -0.5, 1.0)).is_none());
        assert!(Proposal::polar(&Rect::square(0.0, 0.0, 0.5)).is_none());
    }

    #[test]
    fn proposals_round_trip() {
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            for r in nodes(3) {
                let prop = Proposal::for_node(map, &r);
                for (i, j) in [(1, 1), (3, 5), (6, 2)] {
                    let q = prop.lo
                        + (prop.hi - prop.lo) * DVec2::new(f64::from(i) / 7.0, f64::from(j) / 7.0);
                    let Some(c) = prop.point(map, &r, q) else {
                        continue;
                    };
                    assert!((c.w.length() - 1.0).abs() < 1e-12);
                    let back = prop.coordinates(map, c.w);
                    assert!((back - q).length() < 1e-5, "{map:?} {r:?} {q} -> {back}");
                    if let Some(w2) = map.square_to_direction_f64(c.p) {
                        assert!((w2 - c.w).length() < 1e-9);
                    }
                }
            }
        }
    }

    /// Pearson's χ² of `counts` (n draws) against cell probabilities, as Wilson–Hilferty's z
    /// (one-sided: large z rejects).
    fn chi_square_z(counts: &[u64], probabilities: &[f64], n: u64) -> f64 {
        let chi: f64 = counts
            .iter()
            .zip(probabilities)
            .map(|(&c, &p)| {
                let e = p * n as f64;
                (c as f64 - e).powi(2) / e
            })
            .sum();
        let k = (counts.len() - 1) as f64;
        ((chi / k).cbrt() - (1.0 - 2.0 / (9.0 * k))) / (2.0 / (9.0 * k)).sqrt()
    }

    /// Draws 200 000 points through `warp` and histograms them on 8 × 8 cells of the unit
    /// square; returns the χ² z against `shape`'s density (exact per cell: a bilinear
    /// function's mean over a cell is its value at the cell's centre).
    fn warp_z(shape: Shape, warp: impl Fn(DVec2) -> DVec2, seed: u64) -> f64 {
        draws_z(
            shape,
            |rng| {
                let r = rng.next_u64();
                warp(DVec2::new((r >> 32) as f64, (r & 0xffff_ffff) as f64) / 4_294_967_296.0)
            },
            seed,
        )
    }

    /// [`warp_z`] for any draw from the RNG.
    fn draws_z(
        shape: Shape,
        mut draw: impl FnMut(&mut rand_pcg::Pcg64) -> DVec2,
        seed: u64,
    ) -> f64 {
        use rand_core::SeedableRng;
        let (cells, n) = (8usize, 200_000u64);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let mut counts = alloc::vec![0u64; cells * cells];
        for _ in 0..n {
            let t = draw(&mut rng);
            assert!(
                (0.0..1.0).contains(&t.x) && (0.0..1.0).contains(&t.y),
                "{t:?}"
            );
            let (i, j) = ((t.x * 8.0) as usize, (t.y * 8.0) as usize);
            counts[j * cells + i] += 1;
        }
        let probabilities: alloc::vec::Vec<f64> = (0..cells * cells)
            .map(|k| {
                let centre = DVec2::new((k % cells) as f64 + 0.5, (k / cells) as f64 + 0.5) / 8.0;
                shape.value(centre) / shape.mean() / (cells * cells) as f64
            })
            .collect();
        chi_square_z(&counts, &probabilities, n)
    }

    /// `warp` and `draw` draw with density S/mean(S), for steep, skewed and gentle coarse
    /// shapes and peaked, ridged and skewed fine ones, and `warp` for the flat one (χ² on 63
    /// degrees of freedom, one-sided α = 10⁻⁴ per draw: z < 3.72; fixed seeds). Negative
    /// controls: uniform points judged against a leaning shape, and a peak's corners drawn
    /// as a bilinear shape judged against the peak, are rejected.
    #[test]
    fn the_warp_follows_the_bilinear_density() {
        let shapes = [
            [1, 63, 1, 63],
            [63, 1, 1, 20],
            [10, 40, 63, 5],
            [63, 63, 62, 63],
        ];
        for (k, levels) in shapes.into_iter().enumerate() {
            let shape = Shape::from_levels(levels).unwrap();
            let z = warp_z(shape, |u| shape.warp(u), 11 + k as u64);
            assert!(z < 3.72, "{levels:?}: z = {z:.2}");
        }
        let flat = warp_z(Shape::FLAT, |u| Shape::FLAT.warp(u), 3);
        assert!(flat < 3.72, "flat: z = {flat:.2}");
        assert_eq!(
            Shape::FLAT.warp(DVec2::new(0.25, 0.75)),
            DVec2::new(0.25, 0.75)
        );
        // The rejection trials' draw, the same density without square roots.
        for (k, levels) in shapes.into_iter().enumerate() {
            let shape = Shape::from_levels(levels).unwrap();
            let draw = |rng: &mut rand_pcg::Pcg64| {
                shape.draw([rng.next_u64(), rng.next_u64()], rng.next_u32())
            };
            let z = draws_z(shape, draw, 21 + k as u64);
            assert!(z < 3.72, "draw {levels:?}: z = {z:.2}");
        }
        // Fine shapes (bilinear in each quarter): a central peak, a ridge, a skew.
        let fine = [
            [1, 20, 1, 20, 63, 20, 1, 20, 1],
            [5, 63, 5, 5, 63, 5, 5, 63, 5],
            [63, 12, 40, 3, 30, 1, 22, 50, 9],
        ];
        for (k, grid) in fine.into_iter().enumerate() {
            let shape = Shape::from_grid(grid).unwrap();
            let z = warp_z(shape, |u| shape.warp(u), 31 + k as u64);
            assert!(z < 3.72, "warp {grid:?}: z = {z:.2}");
            let draw = |rng: &mut rand_pcg::Pcg64| {
                shape.draw([rng.next_u64(), rng.next_u64()], rng.next_u32())
            };
            let z = draws_z(shape, draw, 41 + k as u64);
            assert!(z < 3.72, "draw {grid:?}: z = {z:.2}");
        }
        let leaning = Shape::from_levels([20, 63, 20, 63]).unwrap();
        let wrong = warp_z(leaning, |u| u, 5);
        assert!(
            wrong > 10.0,
            "uniform points pass as leaning: z = {wrong:.2}"
        );
        // A peak drawn as the bilinear shape of its corners is refused.
        let peak = Shape::from_grid(fine[0]).unwrap();
        let corners = Shape::from_levels(peak.levels()).unwrap();
        let draw = |rng: &mut rand_pcg::Pcg64| {
            corners.draw([rng.next_u64(), rng.next_u64()], rng.next_u32())
        };
        let wrong = draws_z(peak, draw, 6);
        assert!(
            wrong > 10.0,
            "corner draws pass as the peak: z = {wrong:.2}"
        );
    }

    /// [`Shape::invert`] undoes [`Shape::warp`], coarse and fine, and both are monotone.
    #[test]
    fn the_inverse_undoes_the_warp() {
        let shapes = [
            Shape::from_levels([4, 63, 30, 12]).unwrap(),
            Shape::from_grid([1, 20, 1, 20, 63, 20, 1, 20, 1]).unwrap(),
            Shape::from_grid([63, 12, 40, 3, 30, 1, 22, 50, 9]).unwrap(),
            Shape::FLAT,
        ];
        for s in shapes {
            let mut last = -1.0;
            for k in 0..=1000 {
                let u = DVec2::new(k as f64 / 1001.0, (k * 37 % 1001) as f64 / 1001.0);
                let t = s.warp(u);
                if k > 0 {
                    assert!(t.x >= last, "{s:?}: x not monotone at {u}");
                }
                last = t.x;
                let back = s.invert(t);
                // The warp inverts its CDFs in f32 (see `linear_inverse`).
                assert!(
                    (back - u).abs().max_element() < 1e-6,
                    "{s:?}: {u} → {t} → {back}"
                );
            }
        }
    }

    /// A prepared shape's value is [`Shape::value`] to the bit (the trials' height bound
    /// M·S is the bound the build stored), at random points and on the midlines, for
    /// random coarse and fine shapes.
    #[test]
    fn prepared_values_are_the_shapes_bits() {
        let mut rng = <rand_pcg::Pcg64 as rand_core::SeedableRng>::seed_from_u64(8);
        let mut level = || 1 + (rng.next_u32() % 63) as u8;
        for _ in 0..500 {
            let coarse = Shape::from_levels([0; 4].map(|_| level())).unwrap();
            let fine = Shape::from_grid([0; 9].map(|_| level())).unwrap();
            let mut points = <rand_pcg::Pcg64 as rand_core::SeedableRng>::seed_from_u64(9);
            for k in 0..200 {
                let mut t = DVec2::new(
                    crate::uniform_f64(&mut points),
                    crate::uniform_f64(&mut points),
                );
                if k % 4 == 0 {
                    t.x = 0.5;
                }
                let value = match Prepared::new(coarse) {
                    Prepared::Coarse(c) => c.value(t),
                    Prepared::Fine(_) => panic!("a coarse shape prepared as fine"),
                };
                assert_eq!(value.to_bits(), coarse.value(t).to_bits(), "{coarse:?} {t}");
                if let Some(grid) = fine.grid() {
                    let Prepared::Fine(f) = Prepared::new(fine) else {
                        panic!("a fine shape prepared as coarse: {grid:?}");
                    };
                    assert_eq!(
                        f.value(t).to_bits(),
                        fine.value(t).to_bits(),
                        "{grid:?} {t}"
                    );
                }
            }
        }
    }

    /// Shapes keep their levels through the packed bits; the flat box is the zero word; bits
    /// no shape writes (a zero level, anything above bit 23) are refused.
    #[test]
    fn shape_bits_round_trip() {
        assert_eq!(Shape::FLAT.to_bits(), 0);
        assert_eq!(Shape::FLAT.fine_bits(), 0);
        assert_eq!(Shape::from_bits(0, 0), Some(Shape::FLAT));
        for levels in [
            [1, 2, 3, 4],
            [63, 1, 63, 1],
            [40, 63, 17, 9],
            [63, 63, 63, 62],
        ] {
            let s = Shape::from_levels(levels).unwrap();
            assert_eq!(s.fine_bits(), 0);
            assert_eq!(Shape::from_bits(s.to_bits(), 0), Some(s));
            assert_eq!(Shape::from_checked_bits(s.to_bits(), 0), s);
            assert!(s.to_bits() < 1 << 24);
        }
        for grid in [
            [1, 2, 3, 4, 63, 6, 7, 8, 9],
            [63, 63, 63, 63, 62, 63, 63, 63, 63],
            [5, 40, 5, 40, 63, 40, 5, 40, 5],
            [11, 12, 13, 14, 15, 16, 17, 18, 19],
        ] {
            let s = Shape::from_grid(grid).unwrap();
            assert_eq!(s.grid(), Some(grid));
            assert_eq!(s.levels(), [grid[0], grid[2], grid[6], grid[8]]);
            assert_eq!(Shape::from_bits(s.to_bits(), s.fine_bits()), Some(s));
            // The unchecked decoding a sample uses, level for level (every place differs).
            assert_eq!(Shape::from_checked_bits(s.to_bits(), s.fine_bits()), s);
            assert!(s.to_bits() < 1 << 24 && s.fine_bits() >> 30 == 2);
        }
        assert_eq!(Shape::from_grid([63; 9]), Some(Shape::FLAT));
        assert_eq!(Shape::from_levels([0, 5, 5, 5]), None);
        assert_eq!(Shape::from_levels([64, 5, 5, 5]), None);
        assert_eq!(Shape::from_grid([5, 5, 5, 5, 0, 5, 5, 5, 5]), None);
        assert_eq!(Shape::from_bits(5 << 6, 0), None);
        assert_eq!(Shape::from_bits(Shape::FLAT.to_bits() | 1 << 24, 0), None);
        // A fine word needs its flag, no bit 30, levels 1–63 and corners beside it.
        let s = Shape::from_grid([5, 40, 5, 40, 63, 40, 5, 40, 5]).unwrap();
        let (link, fine) = (s.to_bits(), s.fine_bits());
        assert_eq!(Shape::from_bits(link, fine & !FINE_FLAG), None);
        assert_eq!(Shape::from_bits(link, fine | 1 << 30), None);
        assert_eq!(Shape::from_bits(link, fine & !63), None);
        assert_eq!(Shape::from_bits(0, fine), None);
    }

    /// A fine shape is bilinear in each quarter, continuous across the midlines, equal to
    /// its levels at the control points; its mean is the mean of the quarters'; and a fine
    /// grid that is bilinear over the box (midpoints the corners' averages) is the coarse
    /// shape there.
    #[test]
    fn fine_shapes_are_bilinear_in_each_quarter() {
        let s = Shape::from_grid([10, 30, 20, 40, 63, 5, 1, 50, 25]).unwrap();
        for j in 0..3 {
            for i in 0..3 {
                let t = DVec2::new(i as f64, j as f64) / 2.0;
                let want = f64::from(s.grid().unwrap()[3 * j + i]) / 63.0;
                assert!((s.value(t) - want).abs() < 1e-15, "{t}");
            }
        }
        for k in 0..=64 {
            let y = k as f64 / 64.0;
            let (a, b) = (DVec2::new(0.5 - 1e-13, y), DVec2::new(0.5, y));
            assert!(
                (s.value(a) - s.value(b)).abs() < 1e-11,
                "x midline at y {y}"
            );
            let (a, b) = (DVec2::new(y, 0.5 - 1e-13), DVec2::new(y, 0.5));
            assert!(
                (s.value(a) - s.value(b)).abs() < 1e-11,
                "y midline at x {y}"
            );
        }
        let n = 512;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                sum += s.value((DVec2::new(i as f64, j as f64) + 0.5) / n as f64);
            }
        }
        assert!((sum / (n * n) as f64 - s.mean()).abs() < 1e-6);
        let coarse = Shape::from_levels([2, 10, 18, 26]).unwrap();
        let fine = Shape::from_grid([2, 6, 10, 10, 14, 18, 18, 22, 26]).unwrap();
        for k in 0..100 {
            let t = DVec2::new((k % 10) as f64 / 9.0, (k / 10) as f64 / 9.0);
            assert!((coarse.value(t) - fine.value(t)).abs() < 1e-14, "{t}");
        }
        assert!((coarse.mean() - fine.mean()).abs() < 1e-15);
    }

    /// A height that leans linearly across the box gets a shape that leans with it: its
    /// levels follow h (1 + 3x: a quarter at x = 0), and the bound over it (the largest h/S)
    /// leaves under 0.65 of the flat box's volume; a constant or empty height stays flat.
    #[test]
    fn the_fit_follows_a_lean() {
        let grid = |h: &dyn Fn(DVec2) -> f64| {
            (0..=8)
                .flat_map(|i| (0..=8).map(move |j| DVec2::new(i as f64, j as f64) / 8.0))
                .map(|t| (t, h(t)))
                .collect::<alloc::vec::Vec<_>>()
        };
        let lean = grid(&|t| 1.0 + 3.0 * t.x);
        let shape = Shape::fit(&lean);
        let [a, b, c, d] = shape.levels();
        assert!(
            (15..=17).contains(&a) && (15..=17).contains(&c),
            "{shape:?}"
        );
        assert_eq!((b, d), (63, 63));
        let m = lean
            .iter()
            .map(|&(t, h)| h / shape.value(t))
            .fold(0.0, f64::max);
        assert!(
            m * shape.mean() < 0.65 * 4.0,
            "volume {} of 4",
            m * shape.mean()
        );
        assert!(
            lean.iter()
                .all(|&(t, h)| h <= m * shape.value(t) * (1.0 + 1e-12))
        );
        assert!(Shape::fit(&grid(&|_| 2.0)).is_flat());
        assert!(Shape::fit(&grid(&|_| 0.0)).is_flat());
    }

    /// The fit solves its linear programme: on random point sets (heights from random
    /// bilinear, bumpy and spiky functions) its corners bound every point and sum to no more
    /// than the coordinate descent's, and no corner can be lowered alone, nor any pair of
    /// corners traded (one down by δ, another up by less), without uncovering a point. The
    /// case that stalls the descent — a radial fall-off with a rim point just inside the
    /// corner it pins, as the rim band of a polar box on the concentric map has — comes out
    /// flat along the angle, as the profile is.
    #[test]
    fn the_fit_is_the_least_bilinear_bound() {
        use rand_core::{Rng, SeedableRng};
        let weigh = |points: &[(DVec2, f64)]| -> alloc::vec::Vec<([f64; 4], f64)> {
            points
                .iter()
                .map(|&(t, h)| {
                    let (x, y) = (t.x, t.y);
                    (
                        [(1.0 - x) * (1.0 - y), x * (1.0 - y), (1.0 - x) * y, x * y],
                        h,
                    )
                })
                .collect()
        };
        let sum = |c: &[f64; 4]| c.iter().sum::<f64>();
        let covers = |w: &[([f64; 4], f64)], c: &[f64; 4], slack: f64| {
            w.iter()
                .all(|(w, h)| w.iter().zip(c).map(|(a, b)| a * b).sum::<f64>() >= h - slack)
        };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(77);
        let mut unit = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        for case in 0..300 {
            let n = 20 + case % 200;
            let k: [f64; 6] = core::array::from_fn(|_| unit());
            let points: alloc::vec::Vec<(DVec2, f64)> = (0..n)
                .map(|_| {
                    let t = DVec2::new(unit(), unit());
                    let h = match case % 3 {
                        0 => k[0] + k[1] * t.x + k[2] * t.y + k[3] * t.x * t.y,
                        1 => 1.0 + k[4] * m::sin(7.0 * t.x * k[0] + 5.0 * t.y * k[1]),
                        _ => m::exp(-30.0 * (t - DVec2::new(k[2], k[3])).length_squared()),
                    };
                    (t, h * (0.5 + k[5]))
                })
                .collect();
            let w = weigh(&points);
            let top = points.iter().map(|p| p.1).fold(0.0, f64::max);
            let floor = top / 63.0;
            let c = least_bound(&w, [floor; 4]).expect("the simplex converges");
            let slack = 1e-9 * top;
            assert!(covers(&w, &c, slack), "case {case}: {c:?} uncovers a point");
            assert!(c.iter().all(|&v| v >= floor - slack), "case {case}: {c:?}");
            let d = descend(&w, top, floor);
            assert!(
                sum(&c) <= sum(&d) + slack,
                "case {case}: {c:?} vs descent {d:?}"
            );
            // Local optimality: single and paired moves all uncover a point.
            let step = 1e-4 * top;
            for i in 0..4 {
                let mut down = c;
                down[i] -= step;
                assert!(
                    down[i] < floor || !covers(&w, &down, 0.0),
                    "case {case}: corner {i} of {c:?} lowers alone"
                );
                for j in (0..4).filter(|&j| j != i) {
                    let mut trade = down;
                    trade[j] += 0.5 * step;
                    assert!(
                        trade[i] < floor || !covers(&w, &trade, 0.0),
                        "case {case}: corners {i}, {j} of {c:?} trade"
                    );
                }
            }
        }
        // The stalled case: h = 1 − 0.3·x (a fall-off along x, flat along y) on a grid whose
        // rows stay off the edges y = 0 and 1, with a point just above corner (1, 0) and one
        // at corner (1, 1) exactly.
        let mut points: alloc::vec::Vec<(DVec2, f64)> = (0..=8)
            .flat_map(|i| (0..8).map(move |j| DVec2::new(i as f64 / 8.0, (j as f64 + 0.5) / 8.0)))
            .map(|t| (t, 1.0 - 0.3 * t.x))
            .collect();
        points.push((DVec2::new(1.0, 0.0078), 0.7));
        points.push((DVec2::new(1.0, 1.0), 0.7));
        let [a, b, c, d] = Shape::fit(&points).levels();
        assert_eq!((a, c), (63, 63));
        assert!((43..=45).contains(&b) && b == d, "{:?}", [a, b, c, d]);
        let stalled = descend(&weigh(&points), 1.0, 1.0 / 63.0);
        assert!(
            stalled[3] > 0.9,
            "the descent no longer stalls here: {stalled:?}"
        );
    }

    /// The fine fit's programme (nine control values, each point weighing the four of its
    /// quarter, per-value floors) is solved too: feasible and locally optimal on random
    /// instances. A central peak gets a fine shape that rises to it, whose bound over the
    /// grid holds under half the volume of the best bilinear one's.
    #[test]
    fn the_fine_fit_follows_a_peak() {
        use rand_core::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(78);
        let mut unit = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        for case in 0..100 {
            let floors: [f64; 9] = core::array::from_fn(|_| 0.01 + 0.05 * unit());
            let weighted: alloc::vec::Vec<([f64; 9], f64)> = (0..30 + 3 * case)
                .map(|_| {
                    let t = DVec2::new(unit(), unit());
                    let (i, j) = (usize::from(t.x >= 0.5), usize::from(t.y >= 0.5));
                    let u = DVec2::new(2.0 * t.x - i as f64, 2.0 * t.y - j as f64);
                    let mut w = [0.0; 9];
                    for (k, wk) in bilinear_weights(u).into_iter().enumerate() {
                        w[3 * j + i + (k & 1) + 3 * (k >> 1)] = wk;
                    }
                    (w, unit() * (1.0 + m::sin(9.0 * t.x) * m::cos(7.0 * t.y)))
                })
                .collect();
            let c = least_bound(&weighted, floors).expect("the simplex converges");
            let covers = |c: &[f64; 9], slack: f64| {
                weighted
                    .iter()
                    .all(|(w, h)| w.iter().zip(c).map(|(a, b)| a * b).sum::<f64>() >= h - slack)
            };
            assert!(covers(&c, 1e-9), "case {case}: {c:?}");
            for k in 0..9 {
                assert!(c[k] >= floors[k] - 1e-12, "case {case}: {c:?}");
                let mut down = c;
                down[k] -= 1e-5;
                assert!(
                    down[k] < floors[k] || !covers(&down, 0.0),
                    "case {case}: value {k} of {c:?} lowers alone"
                );
            }
        }
        let grid: alloc::vec::Vec<(DVec2, f64)> = (0..=16)
            .flat_map(|i| (0..=16).map(move |j| DVec2::new(i as f64, j as f64) / 16.0))
            .map(|t| (t, m::exp(-12.0 * (t - DVec2::splat(0.5)).length_squared())))
            .collect();
        let volume = |s: Shape| {
            let m = grid
                .iter()
                .map(|&(t, h)| h / s.value(t))
                .fold(0.0, f64::max);
            m * s.mean()
        };
        let (coarse, fine) = (Shape::fit(&grid), Shape::fit_fine(&grid));
        let g = fine.grid().expect("a fine shape");
        assert_eq!(g[4], 63, "{g:?}");
        assert!(CORNERS.iter().all(|&at| g[at] < 20), "{g:?}");
        assert!(
            volume(fine) < 0.5 * volume(coarse),
            "fine {} vs coarse {}",
            volume(fine),
            volume(coarse)
        );
        assert!(Shape::fit_fine(&[(DVec2::ZERO, 0.0)]).is_flat());
    }
}
