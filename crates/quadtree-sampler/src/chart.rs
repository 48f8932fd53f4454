//! Coordinates in which a node is integrated and rejection-sampled.
//!
//! A node is a square of the seed's domain [−1,1]². f_r on that square is smooth in the
//! interior of the disk, but two things break a plain tensor rule or a plain height bound:
//! the disk's rim (f jumps to 0 outside it, z = √(1 − r²) has an infinite slope, and some
//! models — Ward — grow like 1/√z there) and, for the concentric map, the kinks of the map
//! along the square's diagonals. Each is removed by a change of variables:
//!
//! - **Orthographic map**, angle coordinates (a, t): x = sin a, y = cos a·sin t,
//!   z = cos a·cos t, dx dy = cos²a·cos t da dt. The rim is a coordinate boundary, z is a
//!   product of cosines (no cancellation) and f·cos²a·cos t stays bounded where f ~ z^{−1/2}.
//!   Integration is iterated: outer a (split where the rim crosses the node's horizontal
//!   edges, pieces remapped near those points to absorb the limits' square-root
//!   singularities), inner t between the node's edges.
//!   The chart has poles at (±1, 0), where the rim is tangent to the node's vertical edges:
//!   near them a node's t-range stays ±π/2 however small the node, so its rejection box
//!   never shrinks. Leaves there are sampled in the transposed chart (b, s): y = sin b,
//!   x = cos b·sin s, z = cos b·cos s ([`Chart::AngleY`], poles at (0, ±1)); each rim leaf
//!   takes whichever of the two boxes is smaller.
//! - **Concentric map**, sine coordinates (α, β): a = sin α, b = sin β, da db = cos α cos β
//!   dα dβ; z = cos α or cos β exactly. The map's kinks (|a| = |b|) stay straight diagonals,
//!   along which a node is split into triangles.
//!
//! Sampling uses the seed's uniform (x, y) proposal in every leaf that stays off the rim
//! ([`Chart::Square`]). A leaf that touches the rim is offered its angle or sine chart
//! ([`Proposal::for_node`]), which bounds f·Jacobian even where f grows without bound at the
//! rim; where f stays bounded the square is bounded too, and the build keeps whichever box
//! has the smaller volume (usually the square: the charts' Jacobians vanish at the rim).

use brdf_core::DiskMap;
use brdf_core::math as m;
use brdf_core::quadrature::GaussLegendre;
use core::f64::consts::FRAC_PI_2;
use glam::{DVec2, DVec3};

/// An axis-aligned square (or rectangle) of the seed's domain, in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    /// Lower-left corner (u, v).
    pub min: DVec2,
    /// Upper-right corner.
    pub max: DVec2,
}

/// The child order of every quadtree in the crate, written once: child k of a node is the
/// quadrant in column `k & 1` (0: the lower x half) and row `k >> 1` (0: the lower y half),
/// so the order is (−,−), (+,−), (−,+), (+,+). Children are stored contiguously in it.
#[inline]
#[must_use]
pub const fn child_index(column: usize, row: usize) -> usize {
    column + 2 * row
}

/// The column (0: lower x, 1: upper x) of child `k` (see [`child_index`]).
#[inline]
#[must_use]
pub const fn child_column(k: usize) -> usize {
    k & 1
}

/// The row (0: lower y, 1: upper y) of child `k` (see [`child_index`]).
#[inline]
#[must_use]
pub const fn child_row(k: usize) -> usize {
    k >> 1
}

impl Rect {
    /// The square [x, x+s) × [y, y+s).
    #[must_use]
    pub fn square(x: f64, y: f64, s: f64) -> Self {
        Self {
            min: DVec2::new(x, y),
            max: DVec2::new(x + s, y + s),
        }
    }

    /// Its area in square units.
    #[must_use]
    pub fn area(&self) -> f64 {
        let d = self.max - self.min;
        d.x * d.y
    }

    /// The four quadrants in the child order ([`child_column`], [`child_row`]):
    /// (−,−), (+,−), (−,+), (+,+).
    #[must_use]
    pub fn quadrants(&self) -> [Self; 4] {
        let c = 0.5 * (self.min + self.max);
        [0, 1, 2, 3].map(|k| {
            let (x, y) = (child_column(k) == 1, child_row(k) == 1);
            Self {
                min: DVec2::new(
                    if x { c.x } else { self.min.x },
                    if y { c.y } else { self.min.y },
                ),
                max: DVec2::new(
                    if x { self.max.x } else { c.x },
                    if y { self.max.y } else { c.y },
                ),
            }
        })
    }

    /// The child index of the quadrant holding `p` (points on a split line go to the upper
    /// side).
    #[inline]
    #[must_use]
    pub fn quadrant_of(&self, p: DVec2) -> usize {
        let c = 0.5 * (self.min + self.max);
        child_index(usize::from(p.x >= c.x), usize::from(p.y >= c.y))
    }

    /// Distance from the origin of the nearest and the farthest point.
    #[must_use]
    pub fn radius_range(&self) -> (f64, f64) {
        let near = DVec2::new(
            0.0f64.clamp(self.min.x, self.max.x),
            0.0f64.clamp(self.min.y, self.max.y),
        );
        let far = DVec2::new(
            self.min.x.abs().max(self.max.x.abs()),
            self.min.y.abs().max(self.max.y.abs()),
        );
        (near.length(), far.length())
    }

    /// Whether `p` lies in the closed rectangle.
    #[must_use]
    pub fn contains(&self, p: DVec2) -> bool {
        p.x >= self.min.x && p.x <= self.max.x && p.y >= self.min.y && p.y <= self.max.y
    }
}

/// The coordinates a leaf is rejection-sampled in (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Chart {
    /// The seed's proposal: (x, y) uniform in the square, Jacobian 1.
    Square,
    /// Orthographic angle coordinates (a, t), for leaves that touch the rim.
    Angle,
    /// The transposed angle coordinates (b, s) (x and y exchanged), for rim leaves near the
    /// angle chart's poles (±1, 0).
    AngleY,
    /// Concentric sine coordinates (α, β), for leaves that touch the square's edge.
    Sine,
}

/// A point of a chart mapped to the square and the hemisphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChartPoint {
    /// The point of the seed's square [−1,1]².
    pub p: DVec2,
    /// The unit local direction (z ≥ 0).
    pub w: DVec3,
    /// Square area per unit chart area at this point.
    pub jacobian: f64,
}

/// The orthographic map's angle chart: (a, t) → point, direction and Jacobian cos²a·cos t.
#[inline]
#[must_use]
pub fn angle_point(a: f64, t: f64) -> ChartPoint {
    let (sa, ca) = (m::sin(a), m::cos(a));
    let (st, ct) = (m::sin(t), m::cos(t));
    let p = DVec2::new(sa, ca * st);
    ChartPoint {
        p,
        w: DVec3::new(sa, ca * st, ca * ct),
        jacobian: ca * ca * ct,
    }
}

/// The transposed angle chart: (b, s) → point y = sin b, x = cos b·sin s, Jacobian
/// cos²b·cos s ([`angle_point`] with x and y exchanged).
#[inline]
#[must_use]
pub fn angle_point_y(b: f64, s: f64) -> ChartPoint {
    let c = angle_point(b, s);
    ChartPoint {
        p: DVec2::new(c.p.y, c.p.x),
        w: DVec3::new(c.w.y, c.w.x, c.w.z),
        jacobian: c.jacobian,
    }
}

/// The transposed angle chart's coordinates (b, s) of a direction (inverse of
/// [`angle_point_y`]; s = 0 at the chart's poles y = ±1).
#[inline]
fn angle_y_coordinates(w: DVec3) -> DVec2 {
    let b = m::asin(w.y.clamp(-1.0, 1.0));
    let s = if m::cos(b) > 0.0 {
        m::atan2(w.x, w.z)
    } else {
        0.0
    };
    DVec2::new(b, s)
}

/// The concentric map at a square point given by its sine coordinates (α, β), with z exact.
#[inline]
#[must_use]
pub fn sine_point(alpha: f64, beta: f64) -> ChartPoint {
    let (sa, ca) = (m::sin(alpha), m::cos(alpha));
    let (sb, cb) = (m::sin(beta), m::cos(beta));
    let p = DVec2::new(sa, sb);
    // r = max(|a|, |b|), and z = √(1 − r²) is the cosine of the larger angle.
    let z = if sa.abs() >= sb.abs() { ca } else { cb };
    ChartPoint {
        p,
        w: brdf_core::maps::concentric_direction_f64(p, z),
        jacobian: ca * cb,
    }
}

/// A Gauss–Legendre rule on [0, 1] (nodes, weights), shared by all integrations of a build.
#[derive(Clone, Debug)]
pub struct UnitRule {
    nodes: alloc::vec::Vec<f64>,
    weights: alloc::vec::Vec<f64>,
}

impl UnitRule {
    /// The n-point rule on [0, 1].
    #[must_use]
    pub fn new(n: usize) -> Self {
        let gl = GaussLegendre::new(n);
        Self {
            nodes: gl.nodes().iter().map(|x| 0.5 * (x + 1.0)).collect(),
            weights: gl.weights().iter().map(|w| 0.5 * w).collect(),
        }
    }

    /// The n-point midpoint rule on [0, 1] (the seed's uniform grid).
    #[must_use]
    pub fn midpoint(n: usize) -> Self {
        let n = n.max(1);
        Self {
            nodes: (0..n).map(|i| (i as f64 + 0.5) / n as f64).collect(),
            weights: alloc::vec![1.0 / n as f64; n],
        }
    }

    /// (x, w) on [a, b].
    #[inline]
    pub fn on(&self, a: f64, b: f64) -> impl Iterator<Item = (f64, f64)> + '_ {
        let h = b - a;
        self.nodes
            .iter()
            .zip(&self.weights)
            .map(move |(&x, &w)| (a + h * x, h * w))
    }
}

/// The largest integrand values an integration met, for bounding (every point it evaluates
/// lies in the node): f itself (with its square point), f × the chart's Jacobian (with its
/// chart coordinates: (a, t) orthographic, (α, β) concentric) and, orthographic only, f × the
/// transposed angle chart's Jacobian (with its (b, s)): each is the seed of the bound search
/// in that proposal, whose height can peak elsewhere than the others' (f·Jacobian may have a
/// maximum between a lobe on the rim and a diffuse plateau inside).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Peak {
    /// Largest f seen.
    pub f: f64,
    /// Where (square coordinates).
    pub p: DVec2,
    /// Largest f·Jacobian seen.
    pub fj: f64,
    /// Where (chart coordinates).
    pub q: DVec2,
    /// Largest f × the transposed angle chart's Jacobian seen (orthographic; 0 concentric).
    pub fjy: f64,
    /// Where (transposed angle coordinates (b, s)).
    pub qy: DVec2,
}

impl Peak {
    /// Takes `other`'s maxima where they are larger (strictly: on ties the earlier point
    /// stays). Merging the peaks of consecutive runs of points in order gives exactly the
    /// peak of seeing all the points in that order.
    #[inline]
    pub fn merge(&mut self, other: &Self) {
        if other.f > self.f {
            self.f = other.f;
            self.p = other.p;
        }
        if other.fj > self.fj {
            self.fj = other.fj;
            self.q = other.q;
        }
        if other.fjy > self.fjy {
            self.fjy = other.fjy;
            self.qy = other.qy;
        }
    }

    #[inline]
    fn see(&mut self, f: f64, c: &ChartPoint, q: DVec2) {
        if f > self.f {
            self.f = f;
            self.p = c.p;
        }
        let fj = f * c.jacobian;
        if fj > self.fj {
            self.fj = fj;
            self.q = q;
        }
    }

    /// [`Self::see`] for a point of the orthographic angle chart, also in the transposed
    /// chart: its Jacobian cos²b·cos s is √(1 − y²)·z at the same direction.
    #[inline]
    fn see_angle(&mut self, f: f64, c: &ChartPoint, q: DVec2) {
        self.see(f, c, q);
        let fjy = f * m::sqrt((1.0 - c.w.y * c.w.y).max(0.0)) * c.w.z;
        if fjy > self.fjy {
            self.fjy = fjy;
            self.qy = angle_y_coordinates(c.w);
        }
    }
}

/// ∫ f over `rect` ∩ disk with f given per direction (the square measure dx dy), by the map's
/// chart rule (one application, no adaptivity). `f` returns f_r's luminance.
pub fn integrate_once(
    map: DiskMap,
    rect: &Rect,
    rule: &UnitRule,
    f: &impl Fn(DVec3) -> f64,
) -> f64 {
    integrate_once_peak(map, rect, rule, f, &mut Peak::default())
}

/// [`integrate_once`], also recording the largest values met in `peak`.
pub fn integrate_once_peak(
    map: DiskMap,
    rect: &Rect,
    rule: &UnitRule,
    f: &impl Fn(DVec3) -> f64,
    peak: &mut Peak,
) -> f64 {
    match map {
        DiskMap::Orthographic => integrate_angle(rect, rule, f, peak),
        DiskMap::Concentric => integrate_sine(rect, rule, f, peak),
    }
}

fn integrate_angle(
    rect: &Rect,
    rule: &UnitRule,
    f: &impl Fn(DVec3) -> f64,
    peak: &mut Peak,
) -> f64 {
    let (xa, xb) = (rect.min.x.clamp(-1.0, 1.0), rect.max.x.clamp(-1.0, 1.0));
    if xa >= xb {
        return 0.0;
    }
    let (a0, a1) = (m::asin(xa), m::asin(xb));
    // Breakpoints: where the rim crosses the node's horizontal edges, |y| = cos a. There the
    // inner limit asin(y / cos a) has a square-root singularity; a piece ending at one is
    // remapped so that a − a_end ∝ u² (smoothstep at two such ends, u² at one), which removes
    // it. Node edges (x = const) are not singular and keep the plain rule.
    let mut cuts = [(a0, false); 6];
    let mut n = 1;
    for y in [rect.min.y, rect.max.y] {
        if y.abs() < 1.0 {
            let c = m::acos(y.abs());
            for a in [-c, c] {
                if a > a0 && a < a1 {
                    cuts[n] = (a, true);
                    n += 1;
                }
            }
        }
    }
    cuts[n] = (a1, false);
    let cuts = &mut cuts[..=n];
    cuts.sort_unstable_by(|x, y| x.0.total_cmp(&y.0));
    let mut total = 0.0;
    for piece in cuts.windows(2) {
        let ((p0, s0), (p1, s1)) = (piece[0], piece[1]);
        for (u, wu) in rule.on(0.0, 1.0) {
            let (a, wa) = remap(p0, p1, s0, s1, u, wu);
            let ca = m::cos(a);
            let (ylo, yhi) = (rect.min.y.max(-ca), rect.max.y.min(ca));
            if ylo >= yhi || ca <= 0.0 {
                continue;
            }
            let (t0, t1) = (
                m::asin((ylo / ca).clamp(-1.0, 1.0)),
                m::asin((yhi / ca).clamp(-1.0, 1.0)),
            );
            // A limit on the rim (t = ±π/2) is where f may grow like z^{-1/2}: remap it too.
            let (r0, r1) = (ylo <= -ca, yhi >= ca);
            let mut inner = 0.0;
            for (u, wu) in rule.on(0.0, 1.0) {
                let (t, wt) = remap(t0, t1, r0, r1, u, wu);
                let q = angle_point(a, t);
                let fv = f(q.w);
                peak.see_angle(fv, &q, DVec2::new(a, t));
                inner += wt * fv * q.jacobian;
            }
            total += wa * inner;
        }
    }
    total
}

/// Maps u ∈ [0, 1] (weight wu) onto [x0, x1] so that x − end ∝ u² at each end flagged
/// singular (smoothstep for two, a parabola for one): square-root end singularities become
/// smooth for Gauss–Legendre. Returns (x, weight).
#[inline]
fn remap(x0: f64, x1: f64, s0: bool, s1: bool, u: f64, wu: f64) -> (f64, f64) {
    let d = x1 - x0;
    match (s0, s1) {
        (false, false) => (x0 + d * u, wu * d),
        (true, false) => (x0 + d * u * u, wu * d * 2.0 * u),
        (false, true) => (x1 - d * (1.0 - u) * (1.0 - u), wu * d * 2.0 * (1.0 - u)),
        (true, true) => (
            x0 + d * u * u * (3.0 - 2.0 * u),
            wu * d * 6.0 * u * (1.0 - u),
        ),
    }
}

fn integrate_sine(rect: &Rect, rule: &UnitRule, f: &impl Fn(DVec3) -> f64, peak: &mut Peak) -> f64 {
    let s = |x: f64| m::asin(x.clamp(-1.0, 1.0));
    let (al0, al1, be0, be1) = (s(rect.min.x), s(rect.max.x), s(rect.min.y), s(rect.max.y));
    let peak = core::cell::RefCell::new(peak);
    let h = |al: f64, be: f64| {
        let q = sine_point(al, be);
        let fv = f(q.w);
        peak.borrow_mut().see(fv, &q, DVec2::new(al, be));
        fv * q.jacobian
    };
    let diag = rect.min.x == rect.min.y && rect.max.x == rect.max.y;
    let anti = rect.min.x == -rect.max.y && rect.max.x == -rect.min.y;
    let c = DVec2::new(0.5 * (al0 + al1), 0.5 * (be0 + be1));
    let corners = [
        DVec2::new(al0, be0),
        DVec2::new(al1, be0),
        DVec2::new(al1, be1),
        DVec2::new(al0, be1),
    ];
    match (diag, anti) {
        (false, false) => {
            let mut total = 0.0;
            for (al, wa) in rule.on(al0, al1) {
                for (be, wb) in rule.on(be0, be1) {
                    total += wa * wb * h(al, be);
                }
            }
            total
        }
        // Split along the kink line(s): the main diagonal joins corners 0 and 2, the
        // anti-diagonal corners 1 and 3; with both, four triangles meet at the centre.
        (true, false) => {
            triangle(rule, corners[0], corners[1], corners[2], &h)
                + triangle(rule, corners[0], corners[2], corners[3], &h)
        }
        (false, true) => {
            triangle(rule, corners[1], corners[2], corners[3], &h)
                + triangle(rule, corners[1], corners[3], corners[0], &h)
        }
        (true, true) => (0..4)
            .map(|k| triangle(rule, c, corners[k], corners[(k + 1) % 4], &h))
            .sum(),
    }
}

/// ∫ over the triangle (v0, v1, v2) by the collapsed (Duffy) tensor rule: exact for
/// polynomials of the rule's degree, no evaluation on the edges.
fn triangle(rule: &UnitRule, v0: DVec2, v1: DVec2, v2: DVec2, h: &impl Fn(f64, f64) -> f64) -> f64 {
    let det = ((v1 - v0).perp_dot(v2 - v0)).abs();
    let mut total = 0.0;
    for (s, ws) in rule.on(0.0, 1.0) {
        for (t, wt) in rule.on(0.0, 1.0) {
            let p = v0 + s * (v1 - v0) + s * t * (v2 - v1);
            total += ws * wt * s * h(p.x, p.y);
        }
    }
    total * det
}

/// Adaptive ∫ f over `rect` ∩ disk: compares one application of the rule with the sum over
/// the four quadrants and recurses where they differ by more than `tol` (each quadrant with
/// half the tolerance), at most `depth` levels. Returns the refined estimate.
pub fn integrate_adaptive(
    map: DiskMap,
    rect: &Rect,
    rule: &UnitRule,
    tol: f64,
    depth: u32,
    f: &impl Fn(DVec3) -> f64,
) -> f64 {
    integrate_adaptive_peak(map, rect, rule, tol, depth, f, &mut Peak::default())
}

/// [`integrate_adaptive`], also recording the largest values met in `peak`.
pub fn integrate_adaptive_peak(
    map: DiskMap,
    rect: &Rect,
    rule: &UnitRule,
    tol: f64,
    depth: u32,
    f: &impl Fn(DVec3) -> f64,
    peak: &mut Peak,
) -> f64 {
    let coarse = integrate_once_peak(map, rect, rule, f, peak);
    refine(map, rect, coarse, rule, tol, depth, f, peak)
}

/// The refinement of [`integrate_adaptive_peak`] from an already computed one-application
/// estimate `coarse` of `rect` (for callers that needed it first, to set `tol`).
#[allow(clippy::too_many_arguments)]
pub(crate) fn refine(
    map: DiskMap,
    rect: &Rect,
    coarse: f64,
    rule: &UnitRule,
    tol: f64,
    depth: u32,
    f: &impl Fn(DVec3) -> f64,
    peak: &mut Peak,
) -> f64 {
    let quads = rect.quadrants();
    let parts = quads.map(|q| integrate_once_peak(map, &q, rule, f, peak));
    let fine: f64 = parts.iter().sum();
    if depth == 0 || (fine - coarse).abs() <= tol {
        return fine;
    }
    quads
        .iter()
        .zip(parts)
        .map(|(q, c)| refine(map, q, c, rule, 0.5 * tol, depth - 1, f, peak))
        .sum()
}

/// One application of the rule over a cell of an adaptive integration, remembered together
/// with its quadrants' cells once they are computed.
///
/// The build keeps a node's cells and hands each child the subtree of its quadrant, so a
/// child's integration re-uses every application its parent's already made: a rule applied
/// to the same (dyadic, exactly representable) square gives the same value and peak, so the
/// memoised integration is bit-identical to the plain one at a fraction of its cost.
#[derive(Clone, Debug, Default)]
pub(crate) struct Cell {
    /// One application of the rule over the cell.
    pub value: f64,
    /// The largest values that application met.
    pub peak: Peak,
    /// The quadrants' cells, once computed, in [`Rect::quadrants`] order.
    pub quads: Option<alloc::boxed::Box<[Cell; 4]>>,
}

impl Cell {
    /// One application of the rule over `rect`.
    pub fn once(map: DiskMap, rect: &Rect, rule: &UnitRule, f: &impl Fn(DVec3) -> f64) -> Self {
        let mut peak = Peak::default();
        let value = integrate_once_peak(map, rect, rule, f, &mut peak);
        Self {
            value,
            peak,
            quads: None,
        }
    }

    /// The number of cells held (this one and every remembered quadrant below it).
    pub fn count(&self) -> usize {
        1 + self
            .quads
            .as_ref()
            .map_or(0, |q| q.iter().map(Cell::count).sum::<usize>())
    }

    /// The rule applications [`refine_cells`] with this `tol` and `depth` visits below this
    /// cell, memoised or not: the work of a plain adaptive integration, which depends only on
    /// the values (not on what a cache kept). Call it on a cell `refine_cells` just refined.
    pub fn applications(&self, tol: f64, depth: u32) -> u64 {
        let Some(q) = &self.quads else {
            return 0;
        };
        let fine: f64 = q.iter().map(|c| c.value).sum();
        if depth == 0 || (fine - self.value).abs() <= tol {
            return 4;
        }
        4 + q
            .iter()
            .map(|c| c.applications(0.5 * tol, depth - 1))
            .sum::<u64>()
    }

    /// Forgets the remembered quadrants more than `levels` levels below this cell. Values
    /// are unaffected: a forgotten application is recomputed bit for bit when needed.
    pub fn prune(&mut self, levels: u32) {
        if levels == 0 {
            self.quads = None;
        } else if let Some(q) = &mut self.quads {
            for c in q.iter_mut() {
                c.prune(levels - 1);
            }
        }
    }

    /// The four quadrant cells, taken out of this one (`None` when never computed).
    pub fn into_quads(self) -> [Option<Cell>; 4] {
        match self.quads {
            Some(q) => (*q).map(Some),
            None => [None, None, None, None],
        }
    }
}

/// Runs `a` and `b`, on two threads when `par` and the `rayon` feature allow it.
#[inline]
pub(crate) fn join<A: Send, B: Send>(
    par: bool,
    a: impl FnOnce() -> A + Send,
    b: impl FnOnce() -> B + Send,
) -> (A, B) {
    #[cfg(feature = "rayon")]
    if par {
        return rayon::join(a, b);
    }
    let _ = par;
    (a(), b())
}

/// [`refine`] over remembered cells: computes only the applications `cell` does not hold yet
/// (and keeps them in it). Same value and peak as [`refine`] from `cell.value`. The top
/// `par_levels` levels of the recursion run their quadrants in parallel (feature `rayon`);
/// the result does not depend on it.
#[allow(clippy::too_many_arguments)]
pub(crate) fn refine_cells(
    map: DiskMap,
    rect: &Rect,
    cell: &mut Cell,
    rule: &UnitRule,
    tol: f64,
    depth: u32,
    f: &(impl Fn(DVec3) -> f64 + Sync),
    peak: &mut Peak,
    par_levels: u32,
) -> f64 {
    let quads = rect.quadrants();
    let coarse = cell.value;
    let cells = cell
        .quads
        .get_or_insert_with(|| alloc::boxed::Box::new(quads.map(|q| Cell::once(map, &q, rule, f))));
    for c in cells.iter() {
        peak.merge(&c.peak);
    }
    let fine: f64 = cells.iter().map(|c| c.value).sum();
    if depth == 0 || (fine - coarse).abs() <= tol {
        return fine;
    }
    let par = par_levels > 0;
    let next = par_levels.saturating_sub(1);
    let one = |q: &Rect, c: &mut Cell| {
        let mut local = Peak::default();
        let v = refine_cells(map, q, c, rule, 0.5 * tol, depth - 1, f, &mut local, next);
        (v, local)
    };
    let [c0, c1, c2, c3] = &mut **cells;
    let ((r0, r1), (r2, r3)) = join(
        par,
        || join(par, || one(&quads[0], c0), || one(&quads[1], c1)),
        || join(par, || one(&quads[2], c2), || one(&quads[3], c3)),
    );
    let parts = [r0, r1, r2, r3];
    for (_, p) in &parts {
        peak.merge(p);
    }
    parts.iter().map(|(v, _)| v).sum()
}

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
    }
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
                    };
                }
                Self::in_chart(rect, Chart::Sine)
            }
        }
    }

    /// The proposal of `rect` in a given chart (the chart a packed leaf recorded). For the
    /// angle charts: the box of the node's (a, t) or (b, s) coordinates.
    #[must_use]
    pub fn in_chart(rect: &Rect, chart: Chart) -> Self {
        match chart {
            Chart::Square => Self {
                chart,
                lo: rect.min,
                hi: rect.max,
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

    /// The chart point at box coordinates `q`, or `None` when it falls outside the node or the
    /// disk (an automatic rejection).
    #[inline]
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
        }
    }

    /// Chart coordinates of a direction known to lie in this node (inverse of `point`).
    #[must_use]
    pub fn coordinates(&self, map: DiskMap, w: DVec3) -> DVec2 {
        match self.chart {
            Chart::Square => match map {
                DiskMap::Orthographic => DVec2::new(w.x, w.y),
                DiskMap::Concentric => {
                    brdf_core::maps::disk_to_square_concentric(w.truncate().as_vec2()).as_dvec2()
                }
            },
            Chart::Angle => {
                let a = m::asin(w.x.clamp(-1.0, 1.0));
                let ca = m::cos(a);
                let t = if ca > 0.0 { m::atan2(w.y, w.z) } else { 0.0 };
                DVec2::new(a, t)
            }
            Chart::AngleY => angle_y_coordinates(w),
            Chart::Sine => {
                let p =
                    brdf_core::maps::disk_to_square_concentric(w.truncate().as_vec2()).as_dvec2();
                DVec2::new(m::asin(p.x.clamp(-1.0, 1.0)), m::asin(p.y.clamp(-1.0, 1.0)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;

    fn nodes(depth: u32) -> alloc::vec::Vec<Rect> {
        let n = 1usize << depth;
        let s = 2.0 / n as f64;
        (0..n * n)
            .map(|k| Rect::square(-1.0 + (k % n) as f64 * s, -1.0 + (k / n) as f64 * s, s))
            .collect()
    }

    /// ∫ 1 over the disk = π (orthographic); over the square = 4 (concentric); ∫ z = 2π/3 on the
    /// disk; the sums over any dyadic level must reproduce them to near machine precision.
    #[test]
    fn chart_rules_integrate_exactly_across_the_rim() {
        let rule = UnitRule::new(10);
        for depth in 0..5 {
            let one: f64 = nodes(depth)
                .iter()
                .map(|r| integrate_once(DiskMap::Orthographic, r, &rule, &|_| 1.0))
                .sum();
            // The rim remapping trades a little accuracy on the root's single big piece.
            let tol = if depth == 0 { 1e-5 } else { 1e-9 };
            assert!((one - PI).abs() < tol, "depth {depth}: {one}");
            let z: f64 = nodes(depth)
                .iter()
                .map(|r| integrate_once(DiskMap::Orthographic, r, &rule, &|w| w.z))
                .sum();
            assert!((z - 2.0 * PI / 3.0).abs() < tol, "depth {depth}: {z}");
            let sq: f64 = nodes(depth)
                .iter()
                .map(|r| integrate_once(DiskMap::Concentric, r, &rule, &|_| 1.0))
                .sum();
            assert!((sq - 4.0).abs() < 1e-9, "depth {depth}: {sq}");
            // ∫ z over the concentric square = (4/π) ∫ z dA_disk = (4/π)(2π/3) = 8/3.
            let zc: f64 = nodes(depth)
                .iter()
                .map(|r| integrate_once(DiskMap::Concentric, r, &rule, &|w| w.z))
                .sum();
            assert!((zc - 8.0 / 3.0).abs() < 1e-6, "depth {depth}: {zc}");
        }
    }

    #[test]
    fn single_nodes_match_closed_forms() {
        let rule = UnitRule::new(8);
        // Quarter disk [0,1]²: area π/4.
        let r = Rect::square(0.0, 0.0, 1.0);
        assert!(
            (integrate_once(DiskMap::Orthographic, &r, &rule, &|_| 1.0) - PI / 4.0).abs() < 1e-9
        );
        // A node crossing the rim: [0.5,1]×[0.5,1] ∩ disk, area by the closed form.
        let r = Rect::square(0.5, 0.5, 0.5);
        let x0 = (0.75f64).sqrt();
        // ∫_{0.5}^{x0} (√(1−x²) − 0.5) dx
        let prim = |x: f64| 0.5 * (x * (1.0 - x * x).sqrt() + x.asin());
        let exact = prim(x0) - prim(0.5) - 0.5 * (x0 - 0.5);
        let got = integrate_once(DiskMap::Orthographic, &r, &rule, &|_| 1.0);
        assert!((got - exact).abs() < 1e-9, "{got} vs {exact}");
    }

    #[test]
    fn adaptive_integration_resolves_a_sharp_lobe() {
        let rule = UnitRule::new(6);
        // cos^n of the angle to the normal, n = 2000: ∫ z^n dx dy over the disk
        // = ∫ cos^n θ cos θ dω = 2π/(n+2).
        let n = 2000.0;
        let f = |w: DVec3| m::pow(w.z, n);
        let got = integrate_adaptive(
            DiskMap::Orthographic,
            &Rect::square(-1.0, -1.0, 2.0),
            &rule,
            1e-9,
            14,
            &f,
        );
        let want = 2.0 * PI / (n + 2.0);
        assert!((got - want).abs() < 1e-6 * want, "{got} vs {want}");
        let got = integrate_adaptive(
            DiskMap::Concentric,
            &Rect::square(-1.0, -1.0, 2.0),
            &rule,
            1e-9,
            14,
            &f,
        );
        let want = want * 4.0 / PI;
        assert!((got - want).abs() < 1e-6 * want, "{got} vs {want}");
    }

    /// The build's memoised integration is the plain one, bit for bit: from a fresh cell,
    /// again over the cells it kept (serial or parallel), and in each quadrant continuing
    /// from the parent's cells with the child's own tolerance (what a split hands down).
    #[test]
    fn memoised_integration_is_the_plain_one_bit_for_bit() {
        let rule = UnitRule::new(6);
        // A sharp lobe off the centre, which refinement follows deep into one corner, on a
        // flat floor, whose ties in f test that peaks merge in visiting order (first wins).
        let c = DVec3::new(0.5, -0.3, 0.812_403_840_463_596).normalize();
        let f = |w: DVec3| m::pow(w.dot(c).max(0.0), 3000.0).max(0.05);
        let root = Rect::square(-1.0, -1.0, 2.0);
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            let (tol, depth) = (1e-7, 12);
            let mut want_peak = Peak::default();
            let want = integrate_adaptive_peak(map, &root, &rule, tol, depth, &f, &mut want_peak);
            let mut cell = Cell::once(map, &root, &rule, &f);
            for par_levels in [0, u32::MAX, 0] {
                let mut peak = cell.peak;
                let got = refine_cells(
                    map, &root, &mut cell, &rule, tol, depth, &f, &mut peak, par_levels,
                );
                assert_eq!(got.to_bits(), want.to_bits(), "{map:?} par {par_levels}");
                assert_eq!(peak, want_peak, "{map:?} par {par_levels}");
            }
            let quads = root.quadrants();
            for (q, sub) in quads.iter().zip(cell.into_quads()) {
                let mut sub = sub.expect("the root's refinement computed its quadrants");
                let tol = 1e-3 * sub.value.abs();
                let mut want_peak = Peak::default();
                let want = integrate_adaptive_peak(map, q, &rule, tol, depth, &f, &mut want_peak);
                let mut peak = sub.peak;
                let got = refine_cells(map, q, &mut sub, &rule, tol, depth, &f, &mut peak, 1);
                assert_eq!(got.to_bits(), want.to_bits(), "{map:?} {q:?}");
                assert_eq!(peak, want_peak, "{map:?} {q:?}");
            }
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
}
