//! The integration of f_r over a node in its chart (see [`crate::chart`]): a tensor
//! Gauss–Legendre rule in angle coordinates (orthographic) or on the triangles of sine
//! coordinates (concentric), the adaptive rule that refines it, the remembered cells
//! (`Cell`) a child continues from, and the peaks ([`Peak`]) every integration reports
//! to seed the bound search.

use crate::chart::{ChartPoint, Rect, angle_point, angle_y_coordinates, sine_point};
use brdf_core::DiskMap;
use brdf_core::math as m;
use brdf_core::quadrature::GaussLegendre;
use glam::{DVec2, DVec3};

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
/// chart rule (one application, no adaptivity), recording the largest values met in `peak`.
/// `f` returns f_r's luminance.
pub fn integrate_once_peak(
    map: DiskMap,
    rect: &Rect,
    rule: &UnitRule,
    f: &impl Fn(DVec3) -> f64,
    peak: &mut Peak,
) -> f64 {
    integrate_in(Domain::from(map), rect, rule, f, peak)
}

/// What a build integrates over: the map's square and the crease of f_r(wi, ·) that
/// [`Brdf::crease_cosine`](brdf_core::Brdf::crease_cosine) reports, as the ring's radius
/// r_c = sin θc on the disk: a circle on the orthographic map, the square ring |x| = r_c,
/// |y| = r_c on the concentric one.
///
/// A rule applied across a crease converges only as fast as the cells shrink toward it: the
/// target-1.25 tree of Oren–Nayar at θi = 89° (crease at θo = θi), concentric, took 142 ms,
/// nearly all of it refining cells that straddle that ring, and takes 12 ms cut along it
/// (same nodes and E\[T\]). Cut there, each piece is smooth
/// and one application is as good as anywhere else: the concentric node is cut into
/// rectangles along the ring's sides; the orthographic node's outer (a) integral is cut where
/// the circle crosses its horizontal edges and, with the rim's u² remap, where it turns
/// vertical, and each inner (t) integral where its line crosses the circle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Domain {
    /// The disk map the square is the domain of.
    pub map: DiskMap,
    /// r_c ∈ (0, 1); `None` without a crease.
    pub crease: Option<f64>,
    /// The widest cell (side, in square units) whose refinement may stop where its two
    /// levels agree: the integrand's [`brdf_core::Brdf::step_width`] (a square cell of side
    /// s spans at least s radians of directions), ∞ for a continuous integrand. A wider
    /// cell of a staircase is refined further, agreement or not (see [`refine_cells`]).
    pub trusted_side: f64,
}

impl Domain {
    /// The domain of `map` for an integrand creased at cos θo = `crease_cosine`; a cosine
    /// outside (0, 1) (or NaN) names no ring of the upper hemisphere's interior: no crease.
    pub fn new(map: DiskMap, crease_cosine: Option<f64>) -> Self {
        let crease = crease_cosine
            .filter(|c| *c > 0.0 && *c < 1.0)
            .map(|c| m::sqrt((1.0 - c) * (1.0 + c)))
            .filter(|r| *r > 0.0 && *r < 1.0);
        Self {
            map,
            crease,
            trusted_side: f64::INFINITY,
        }
    }

    /// Whether agreement may stop the refinement of the cell `rect`: always for a continuous
    /// integrand; for a staircase only in a cell no wider than its steps (in a wider one,
    /// holding many steps, two levels can agree by chance while both are off).
    #[inline]
    pub fn trusts(&self, rect: &Rect) -> bool {
        rect.max.x - rect.min.x <= self.trusted_side
    }

    /// This domain for an integrand that is a staircase of steps `step` wide (radians; see
    /// [`brdf_core::usable_step_width`]), or continuous (`None`).
    #[must_use]
    pub fn with_step(self, step: Option<f64>) -> Self {
        Self {
            trusted_side: brdf_core::usable_step_width(step).unwrap_or(f64::INFINITY),
            ..self
        }
    }
}

impl From<DiskMap> for Domain {
    fn from(map: DiskMap) -> Self {
        Self::new(map, None)
    }
}

/// [`integrate_once_peak`] over a [`Domain`]: on the concentric map with a crease, the rule
/// is applied to each piece of `rect` that the crease lines cut (each piece still split
/// along the map's own diagonal kinks by [`integrate_sine`]); on the orthographic map
/// [`integrate_angle`] cuts its own pieces.
pub(crate) fn integrate_in(
    dom: Domain,
    rect: &Rect,
    rule: &UnitRule,
    f: &impl Fn(DVec3) -> f64,
    peak: &mut Peak,
) -> f64 {
    match (dom.map, dom.crease) {
        (DiskMap::Orthographic, crease) => integrate_angle(rect, crease, rule, f, peak),
        (DiskMap::Concentric, None) => integrate_sine(rect, rule, f, peak),
        (DiskMap::Concentric, Some(r)) => {
            // The cut positions along one axis: the ends and the crease lines strictly inside.
            let cuts = |lo: f64, hi: f64| {
                let mut c = [lo, hi, hi, hi];
                let mut n = 1;
                for x in [-r, r] {
                    if x > lo && x < hi {
                        c[n] = x;
                        n += 1;
                    }
                }
                c[n] = hi;
                (c, n)
            };
            let ((xs, nx), (ys, ny)) = (cuts(rect.min.x, rect.max.x), cuts(rect.min.y, rect.max.y));
            if nx == 1 && ny == 1 {
                return integrate_sine(rect, rule, f, peak);
            }
            let mut total = 0.0;
            for i in 0..nx {
                for j in 0..ny {
                    let piece = Rect {
                        min: DVec2::new(xs[i], ys[j]),
                        max: DVec2::new(xs[i + 1], ys[j + 1]),
                    };
                    total += integrate_sine(&piece, rule, f, peak);
                }
            }
            total
        }
    }
}

fn integrate_angle(
    rect: &Rect,
    crease: Option<f64>,
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
    //
    // A crease circle of radius r adds the same kind of breakpoint where it turns vertical,
    // x = ±r (there its inner crossings ±√(r² − x²) meet, and the inner integral goes like
    // (r − |x|)^{3/2}), and plain ones where it crosses the horizontal edges (there an inner
    // crossing leaves the node: a jump in the inner integral's second derivative only).
    let mut cuts = [(a0, false); 12];
    let mut n = 1;
    let mut cut = |a: f64, singular: bool| {
        if a > a0 && a < a1 {
            cuts[n] = (a, singular);
            n += 1;
        }
    };
    for y in [rect.min.y, rect.max.y] {
        if y.abs() < 1.0 {
            let c = m::acos(y.abs());
            cut(-c, true);
            cut(c, true);
        }
    }
    if let Some(r) = crease {
        let c = m::asin(r);
        cut(-c, true);
        cut(c, true);
        for y in [rect.min.y, rect.max.y] {
            if y.abs() < r {
                let c = m::asin(m::sqrt((r - y) * (r + y)));
                cut(-c, false);
                cut(c, false);
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
            // The inner pieces: cut where this line x = sin a crosses the crease circle.
            let mut ts = [(t0, r0), (t1, r1), (t1, r1), (t1, r1)];
            let mut k = 1;
            if let Some(r) = crease {
                let sa = m::sin(a);
                if sa.abs() < r {
                    let tc = m::asin((m::sqrt((r - sa) * (r + sa)) / ca).min(1.0));
                    for t in [-tc, tc] {
                        if t > t0 && t < t1 {
                            ts[k] = (t, false);
                            k += 1;
                        }
                    }
                }
            }
            ts[k] = (t1, r1);
            let mut inner = 0.0;
            for part in ts[..=k].windows(2) {
                let ((q0, s0), (q1, s1)) = (part[0], part[1]);
                for (u, wu) in rule.on(0.0, 1.0) {
                    let (t, wt) = remap(q0, q1, s0, s1, u, wu);
                    let q = angle_point(a, t);
                    let fv = f(q.w);
                    peak.see_angle(fv, &q, DVec2::new(a, t));
                    inner += wt * fv * q.jacobian;
                }
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
    pub fn once(dom: Domain, rect: &Rect, rule: &UnitRule, f: &impl Fn(DVec3) -> f64) -> Self {
        let mut peak = Peak::default();
        let value = integrate_in(dom, rect, rule, f, &mut peak);
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
    /// cell (of square `rect` in domain `dom`), memoised or not: the work of a plain adaptive
    /// integration, which depends only on the values (not on what a cache kept). Call it on a
    /// cell `refine_cells` just refined.
    pub fn applications(&self, dom: Domain, rect: &Rect, tol: f64, depth: u32) -> u64 {
        let Some(q) = &self.quads else {
            return 0;
        };
        let fine: f64 = q.iter().map(|c| c.value).sum();
        if depth == 0 || ((fine - self.value).abs() <= tol && dom.trusts(rect)) {
            return 4;
        }
        4 + q
            .iter()
            .zip(rect.quadrants())
            .map(|(c, r)| c.applications(dom, &r, 0.5 * tol, depth - 1))
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
/// (and keeps them in it). Same value and peak as [`refine`] from `cell.value`. A cell stops
/// where one application and its four quadrants' agree to `tol` and the domain trusts that
/// agreement there ([`Domain::trusts`]: a staircase's cells must first be as narrow as its
/// steps), or at `depth` 0; each quadrant refines to half the tolerance. The top
/// `par_levels` levels of the recursion run their quadrants in parallel (feature `rayon`);
/// the result does not depend on it.
#[allow(clippy::too_many_arguments)]
pub(crate) fn refine_cells(
    dom: Domain,
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
    let par = par_levels > 0;
    // The four applications side by side too: they are the recursion's critical path, one
    // level after another down a lobe.
    let cells = cell.quads.get_or_insert_with(|| {
        let once = |k: usize| Cell::once(dom, &quads[k], rule, f);
        let ((a, b), (c, d)) = join(
            par,
            || join(par, || once(0), || once(1)),
            || join(par, || once(2), || once(3)),
        );
        alloc::boxed::Box::new([a, b, c, d])
    });
    for c in cells.iter() {
        peak.merge(&c.peak);
    }
    let fine: f64 = cells.iter().map(|c| c.value).sum();
    if depth == 0 || ((fine - coarse).abs() <= tol && dom.trusts(rect)) {
        return fine;
    }
    let next = par_levels.saturating_sub(1);
    let one = |q: &Rect, c: &mut Cell| {
        let mut local = Peak::default();
        let v = refine_cells(dom, q, c, rule, 0.5 * tol, depth - 1, f, &mut local, next);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chart::tests::nodes;
    use core::f64::consts::PI;

    // The plain (non-memoised) integrations: the references the build's memoised one is
    // held to, bit for bit, and the rules' own checks.

    /// ∫ f over `rect` ∩ disk with f given per direction (the square measure dx dy), by the map's
    /// chart rule (one application, no adaptivity). `f` returns f_r's luminance.
    fn integrate_once(
        dom: impl Into<Domain>,
        rect: &Rect,
        rule: &UnitRule,
        f: &impl Fn(DVec3) -> f64,
    ) -> f64 {
        integrate_in(dom.into(), rect, rule, f, &mut Peak::default())
    }

    /// Adaptive ∫ f over `rect` ∩ disk: compares one application of the rule with the sum over
    /// the four quadrants and recurses where they differ by more than `tol` (each quadrant with
    /// half the tolerance), at most `depth` levels. Returns the refined estimate.
    fn integrate_adaptive(
        dom: impl Into<Domain>,
        rect: &Rect,
        rule: &UnitRule,
        tol: f64,
        depth: u32,
        f: &impl Fn(DVec3) -> f64,
    ) -> f64 {
        integrate_adaptive_peak(dom.into(), rect, rule, tol, depth, f, &mut Peak::default())
    }

    /// `integrate_adaptive`, also recording the largest values met in `peak`.
    fn integrate_adaptive_peak(
        dom: Domain,
        rect: &Rect,
        rule: &UnitRule,
        tol: f64,
        depth: u32,
        f: &impl Fn(DVec3) -> f64,
        peak: &mut Peak,
    ) -> f64 {
        let coarse = integrate_in(dom, rect, rule, f, peak);
        refine(dom, rect, coarse, rule, tol, depth, f, peak)
    }

    /// The refinement of `integrate_adaptive_peak` from an already computed one-application
    /// estimate `coarse` of `rect` (for callers that needed it first, to set `tol`).
    #[allow(clippy::too_many_arguments)]
    fn refine(
        dom: Domain,
        rect: &Rect,
        coarse: f64,
        rule: &UnitRule,
        tol: f64,
        depth: u32,
        f: &impl Fn(DVec3) -> f64,
        peak: &mut Peak,
    ) -> f64 {
        let quads = rect.quadrants();
        let parts = quads.map(|q| integrate_in(dom, &q, rule, f, peak));
        let fine: f64 = parts.iter().sum();
        if depth == 0 || ((fine - coarse).abs() <= tol && dom.trusts(rect)) {
            return fine;
        }
        quads
            .iter()
            .zip(parts)
            .map(|(q, c)| refine(dom, q, c, rule, 0.5 * tol, depth - 1, f, peak))
            .sum()
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

    /// A crease integrates exactly and cheaply once the cells are cut along it: |z² − c²| over
    /// the disk is 2π(r⁴/2 − r²/2 + 1/4), r² = 1 − c² (times 4/π over the concentric
    /// square), on both maps.
    /// Cut, the adaptive rule meets its tolerance (1e-11 concentric, 1e-9 orthographic) with
    /// few cells; uncut (the negative control), the same tolerance takes over twenty times as
    /// many and is still less accurate.
    #[test]
    fn a_declared_crease_is_integrated_along_its_ring() {
        let rule = UnitRule::new(6);
        let root = Rect::square(-1.0, -1.0, 2.0);
        for (map, c) in [0.3, 0.6, 0.017_452_406_437_283_5]
            .into_iter()
            .flat_map(|c| [(DiskMap::Concentric, c), (DiskMap::Orthographic, c)])
        {
            // |z² − c²| = |r² − ρ²|: a polynomial on either side (no z^{1/2} at the rim).
            let f = |w: DVec3| (w.z * w.z - c * c).abs();
            let r2 = (1.0 - c) * (1.0 + c);
            let per_disk = if map == DiskMap::Concentric {
                4.0 / PI
            } else {
                1.0
            };
            let want = per_disk * 2.0 * PI * (0.5 * r2 * r2 - 0.5 * r2 + 0.25);
            // The orthographic rim alone needs cells near 2⁻⁸ wide for 1e-11 (crease or not).
            let tol = if map == DiskMap::Concentric {
                1e-11
            } else {
                1e-9
            };
            let mut err_cells = [(0.0, 0); 2];
            for (k, dom) in [Domain::new(map, Some(c)), map.into()]
                .into_iter()
                .enumerate()
            {
                let mut cell = Cell::once(dom, &root, &rule, &f);
                let mut peak = Peak::default();
                let got = refine_cells(dom, &root, &mut cell, &rule, tol, 12, &f, &mut peak, 0);
                err_cells[k] = ((got - want).abs() / want, cell.count());
            }
            let [(err, cells), (plain_err, plain_cells)] = err_cells;
            assert!(err < 10.0 * tol, "{map:?} c {c}: cut {err:e}");
            assert!(
                plain_cells > 20 * cells && plain_err > err,
                "{map:?} c {c}: cut {cells} cells ({err:e}), uncut {plain_cells} ({plain_err:e})"
            );
        }
        // The unit cosine has no ring.
        assert_eq!(Domain::new(DiskMap::Orthographic, Some(1.0)).crease, None);
        assert_eq!(Domain::new(DiskMap::Concentric, Some(1.0)).crease, None);
        assert_eq!(Domain::new(DiskMap::Concentric, None).crease, None);
        // Nor the horizon, a ring below it, or no number at all.
        for c in [0.0, -0.5, f64::NAN, f64::INFINITY] {
            assert_eq!(
                Domain::new(DiskMap::Orthographic, Some(c)).crease,
                None,
                "{c}"
            );
        }
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
        let creased = |map| Domain::new(map, Some(0.6));
        for map in [
            DiskMap::Orthographic.into(),
            DiskMap::Concentric.into(),
            creased(DiskMap::Orthographic),
            creased(DiskMap::Concentric),
        ] {
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
}
