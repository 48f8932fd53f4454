//! The bound search: M for a node's proposal (SPEC §3) — the largest height f·Jacobian found
//! on a dense grid, at the model's peak hints, at the integration's largest value and by
//! compass searches climbing from the best of them, times the safety factor; and the rim
//! probe that tells whether f stays bounded at the disk's rim inside a node.

use crate::chart::{Chart, Rect};
use crate::evaluate::Context;
use crate::integrate::{Peak, join};
use crate::proposal::Proposal;
use alloc::vec::Vec;
use brdf_core::{Brdf, DiskMap, math as m};
use glam::{DVec2, DVec3};

/// Rows of a polar box's bound search near its centre edge (see `bound`).
const POLAR_CENTRE_ROWS: i32 = 12;

/// Scales of the probe around a peak hint in or near a node (see `bound`): the grid's spacing
/// halved 23 times, to 10⁻⁷ of it.
const HINT_PROBE_SCALES: usize = 24;

/// Where a grid point's unit coordinate counts as on the upper edge (the grid pulls those in
/// by 10⁻¹²).
const EDGE: f64 = 1.0 - 1e-9;

/// The heights z above the rim at which the rim band ([`Context::rim_heights`]) looks: the
/// rim probe's two, then a geometric ladder up to where a root child's grid has its last
/// row before the rim (z ≈ 0.35 on either map).
const RIM_BAND_HEIGHTS: [f64; 13] = [
    1e-9, 1e-5, 1e-4, 1e-3, 3e-3, 1e-2, 3e-2, 0.05, 0.08, 0.12, 0.18, 0.27, 0.4,
];

/// How many of an edge's local maxima on the grid the bound search looks between grid points
/// around (the highest ones).
const EDGE_PEAKS: usize = 3;

/// The evaluations the edge searches of one shaped box take at most (the build's budget
/// counts them): four edges, [`EDGE_PEAKS`] golden-section searches each, of two starting
/// points and ⌈ln 1000 / ln φ⌉ = 15 steps down to 10⁻³ of their stretch.
pub(crate) const EDGE_SEARCH_EVALS: u64 = 4 * EDGE_PEAKS as u64 * 17;

/// The evaluations of one rim band ([`Context::rim_heights`]): 33 points on each of at most
/// two arcs (or edges), at every height of [`RIM_BAND_HEIGHTS`].
pub(crate) const RIM_BAND_EVALS: u64 = 66 * RIM_BAND_HEIGHTS.len() as u64;

/// A tangent axis of the disk (the local frame's x or y).
#[derive(Clone, Copy)]
enum Axis {
    X,
    Y,
}

/// Rows (or columns) of a concentric node at which [`hint_line_points`] finds its line.
const HINT_LINE_ROWS: usize = 17;

/// The directions of the node `rect` on the line of the disk through the hint `w` parallel
/// to a tangent axis (x = w.x for [`Axis::X`], y = w.y for [`Axis::Y`]): one on each of
/// [`HINT_LINE_ROWS`] evenly spaced rows of the node's square (columns for [`Axis::Y`])
/// that the line crosses; on the concentric map found by bisection (along a row of the
/// square its disk x grows monotonically, and its disk y along a column).
///
/// Why: an anisotropic lobe that is narrow along a tangent axis is a ridge along such a
/// line (Ward with α_x = 0.001: wo.x = −wi.x wherever h.x = 0, a ridge 10⁻³ wide across the
/// disk; Schlick with p = 0.001 likewise). On the orthographic map, clamping the hint into a
/// node keeps its x or y, so it lands on the ridge wherever the ridge crosses the node; the
/// concentric map bends the line, and the clamped hint misses it, as do the grid and the
/// integration of a node wider than the ridge: such nodes looked flat and never split, and
/// the tree lost up to 17 % of the volume with no bound violation to show it. And one point
/// of the ridge is not enough where the box is shaped, on either map: h/S along the ridge
/// peaks where the shape is lowest (Schlick p = 0.001, concentric: bounds 6–12 % short).
fn hint_line_points(map: DiskMap, rect: &Rect, w: DVec3, axis: Axis, out: &mut Vec<DVec3>) {
    let hi = rect.max - (rect.max - rect.min) * 1e-9;
    let (target, along, across) = match axis {
        Axis::X => (w.x, 0, 1),
        Axis::Y => (w.y, 1, 0),
    };
    let coordinate =
        |p: DVec2| -> Option<f64> { map.square_to_direction_f64(p).map(|d| d.truncate()[along]) };
    let point = |t: f64, s: f64| {
        let mut p = DVec2::ZERO;
        p[along] = t;
        p[across] = s;
        p
    };
    let (t0, t1) = (rect.min[along], hi[along]);
    for j in 0..HINT_LINE_ROWS {
        let s = rect.min[across]
            + (hi[across] - rect.min[across]) * j as f64 / (HINT_LINE_ROWS - 1) as f64;
        let (Some(c0), Some(c1)) = (coordinate(point(t0, s)), coordinate(point(t1, s))) else {
            continue;
        };
        if !(c0 <= target && target <= c1) {
            continue;
        }
        if map == DiskMap::Orthographic {
            // The line is the square's own.
            if let Some(d) = map.square_to_direction_f64(point(target, s)) {
                out.push(d);
            }
            continue;
        }
        let (mut a, mut b) = (t0, t1);
        for _ in 0..HINT_LINE_BISECTIONS {
            let mid = 0.5 * (a + b);
            match coordinate(point(mid, s)) {
                Some(c) if c < target => a = mid,
                _ => b = mid,
            }
        }
        if let Some(d) = map.square_to_direction_f64(point(0.5 * (a + b), s)) {
            out.push(d);
        }
    }
}

/// Bisection steps of [`hint_line_points`]: 2⁻²⁴ of the node's width, far inside any ridge
/// a node that wide can hold.
const HINT_LINE_BISECTIONS: usize = 24;

/// Orthographic: azimuths of points on the unit circle inside `rect`: `n` per arc, ends
/// included (nudged inside). The arcs' ends are where the circle crosses the rectangle's edges.
fn rim_arc_points(rect: &Rect, n: usize) -> Vec<f64> {
    use core::f64::consts::{PI, TAU};
    let mut cuts: Vec<f64> = Vec::with_capacity(10);
    for x in [rect.min.x, rect.max.x] {
        if x.abs() <= 1.0 {
            let a = m::acos(x);
            cuts.extend([a, TAU - a]);
        }
    }
    for y in [rect.min.y, rect.max.y] {
        if y.abs() <= 1.0 {
            let a = m::asin(y);
            // a ∈ [−π/2, π/2] and π − a ∈ [π/2, 3π/2]: only a may need wrapping into [0, 2π).
            cuts.extend([if a < 0.0 { a + TAU } else { a }, PI - a]);
        }
    }
    cuts.sort_unstable_by(f64::total_cmp);
    let inside = |phi: f64| rect.contains(DVec2::new(m::cos(phi), m::sin(phi)));
    let mut points = Vec::new();
    if cuts.is_empty() {
        if inside(0.0) {
            points.extend((0..64).map(|k| TAU * k as f64 / 64.0));
        }
        return points;
    }
    for k in 0..cuts.len() {
        let a = cuts[k];
        let b = if k + 1 < cuts.len() {
            cuts[k + 1]
        } else {
            cuts[0] + TAU
        };
        if b - a < 1e-15 || !inside(0.5 * (a + b)) {
            continue;
        }
        let pad = (b - a) * 1e-9;
        let last = (n - 1) as f64;
        points.extend((0..n).map(|j| a + pad + (b - a - 2.0 * pad) * j as f64 / last));
    }
    points
}

/// Concentric: the rim is the square's edge. Points (cos φ, sin φ) of the rim directions of the
/// node's stretches of it: `n` per edge it lies on, ends included (nudged inside).
fn edge_rim_points(rect: &Rect, n: usize) -> Vec<(f64, f64)> {
    let mut points = Vec::new();
    let mut stretch = |p0: DVec2, p1: DVec2| {
        let pad = (p1 - p0) * 1e-9;
        for j in 0..n {
            let p = p0 + pad + (p1 - p0 - 2.0 * pad) * (j as f64 / (n - 1) as f64);
            let w = DiskMap::Concentric
                .square_to_direction_f64(p)
                .unwrap_or(DVec3::Z);
            let r = m::sqrt(w.x * w.x + w.y * w.y);
            if r > 0.0 {
                points.push((w.x / r, w.y / r));
            }
        }
    };
    let (lo, hi) = (rect.min, rect.max);
    if lo.x <= -1.0 {
        stretch(DVec2::new(-1.0, lo.y), DVec2::new(-1.0, hi.y));
    }
    if hi.x >= 1.0 {
        stretch(DVec2::new(1.0, lo.y), DVec2::new(1.0, hi.y));
    }
    if lo.y <= -1.0 {
        stretch(DVec2::new(lo.x, -1.0), DVec2::new(hi.x, -1.0));
    }
    if hi.y >= 1.0 {
        stretch(DVec2::new(lo.x, 1.0), DVec2::new(hi.x, 1.0));
    }
    points
}

/// The node's rim points (cos φ, sin φ) under `map`, `n` per arc or edge ([`rim_arc_points`],
/// [`edge_rim_points`]).
fn rim_points(map: DiskMap, rect: &Rect, n: usize) -> Vec<(f64, f64)> {
    match map {
        DiskMap::Orthographic => rim_arc_points(rect, n)
            .into_iter()
            .map(|phi| (m::cos(phi), m::sin(phi)))
            .collect(),
        DiskMap::Concentric => edge_rim_points(rect, n),
    }
}

/// The range of the chart's second coordinate that the node's region covers at first
/// coordinate `a`: in the angle charts, t between the node's edges at that a (`None` where
/// the row holds no direction); elsewhere the box's own range.
fn node_row(prop: &Proposal, rect: &Rect, a: f64) -> Option<(f64, f64)> {
    match prop.chart {
        Chart::Angle | Chart::AngleY => {
            let ca = m::cos(a);
            if ca <= 0.0 {
                return None;
            }
            let lim = |y: f64| m::asin((y / ca).clamp(-1.0, 1.0));
            let (ylo, yhi) = if prop.chart == Chart::Angle {
                (rect.min.y, rect.max.y)
            } else {
                (rect.min.x, rect.max.x)
            };
            Some((lim(ylo), lim(yhi).min(prop.hi.y)))
        }
        Chart::Square | Chart::Sine | Chart::Polar => Some((prop.lo.y, prop.hi.y)),
    }
}

/// Coordinates a compass search climbs in ([`Context::compass_search`]): the chart's own, or
/// in the angle charts the node's rows, (a, v) with v ∈ [0, 1) the fraction of the node's
/// row at a ([`node_row`]), in which the node's region is the rectangle [lo.x, hi.x] × [0, 1).
///
/// Why the rows: in the angle charts the node's edges across the rows are curves
/// (t = asin(y/cos a)). A maximum on such an edge (Strauss at grazing incidence, its lobe cut
/// by the node's edge) is a corner for axis steps in (a, t): one step leaves the node, the
/// other goes down, and the climb stops short (a bound 5 % low). In (a, v) the edge is a
/// coordinate line, which the climb follows.
#[derive(Clone, Copy)]
struct SearchSpace<'p> {
    prop: &'p Proposal,
    rect: Rect,
    rows: bool,
}

/// The largest fraction of a node's row a search point takes: the node's upper edges are open.
const ROW_TOP: f64 = 1.0 - 1e-12;

impl<'p> SearchSpace<'p> {
    /// The chart's own coordinates.
    fn chart(prop: &'p Proposal, rect: &Rect) -> Self {
        Self {
            prop,
            rect: *rect,
            rows: false,
        }
    }

    /// The node's row coordinates (the chart's own outside the angle charts).
    fn rows(prop: &'p Proposal, rect: &Rect) -> Self {
        Self {
            prop,
            rect: *rect,
            rows: matches!(prop.chart, Chart::Angle | Chart::AngleY),
        }
    }

    /// The search box's corners.
    fn bounds(&self) -> (DVec2, DVec2) {
        if self.rows {
            (
                DVec2::new(self.prop.lo.x, 0.0),
                DVec2::new(self.prop.hi.x, ROW_TOP),
            )
        } else {
            (self.prop.lo, self.prop.hi)
        }
    }

    /// The search point of chart point `q`.
    fn search_point(&self, q: DVec2) -> DVec2 {
        if !self.rows {
            return q;
        }
        match node_row(self.prop, &self.rect, q.x) {
            Some((t0, t1)) if t1 > t0 => {
                DVec2::new(q.x, ((q.y - t0) / (t1 - t0)).clamp(0.0, ROW_TOP))
            }
            _ => DVec2::new(q.x, 0.0),
        }
    }

    /// The chart point of search point `v` (`None` where its row is empty).
    fn chart_point(&self, v: DVec2) -> Option<DVec2> {
        if !self.rows {
            return Some(v);
        }
        let (t0, t1) = node_row(self.prop, &self.rect, v.x)?;
        Some(DVec2::new(v.x, t0 + (t1 - t0) * v.y))
    }
}

/// Applies `fill` to every item, in halves side by side when `parallel` (down to 32 items a
/// part): each item is filled alone, so the results do not depend on the split.
fn fill_in_halves<T: Send>(items: &mut [T], parallel: bool, fill: &(impl Fn(&mut T) + Sync)) {
    if items.len() <= 32 || !parallel {
        items.iter_mut().for_each(fill);
        return;
    }
    let (a, b) = items.split_at_mut(items.len() / 2);
    join(
        true,
        || fill_in_halves(a, true, fill),
        || fill_in_halves(b, true, fill),
    );
}

/// `m` as an f32 no smaller than it (an upper bound stays one).
pub(crate) fn round_up_f32(m: f64) -> f32 {
    let b = m as f32;
    if f64::from(b) < m { b.next_up() } else { b }
}

/// What a node's bound search may borrow from the searches before it
/// ([`Context::proposal_bound`]).
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Known<'a> {
    /// The flat box's grid, whose heights a shaped box's finer grid shares.
    pub(crate) coarse: Option<&'a [(DVec2, f64)]>,
    /// The heights in the band along the rim ([`Context::rim_heights`]), which a shaped
    /// square or polar box with a rim limit must bound.
    pub(crate) rim_band: &'a [(DVec2, f64)],
}

/// What [`Context::rim_probe`] found: f's behaviour approaching the rim inside a node.
#[derive(Clone, Copy, Debug)]
pub(crate) enum RimProbe {
    /// f grows without bound toward the rim (1/√z or faster).
    Unbounded,
    /// f stays bounded; the largest value seen near the rim.
    Bounded(f64),
}

impl<B: Brdf + ?Sized> Context<'_, B> {
    /// The proposal's height function h = f·Jacobian at chart point q (0 outside the node).
    ///
    /// A point on the box's lower edge that rounding carries out of the node is looked at a
    /// hair (10⁻¹² of the box) inside instead, where sampling can draw it: the polar box of the
    /// root's child x < 0, y ≥ 0 starts at φ = π/2, where cos φ rounds to +6·10⁻¹⁷ and the
    /// point falls on the far side of x = 0, so the grid's whole first column read 0 there.
    /// Schlick's lobe near the disk's centre, over a shape lowest at that corner, peaked on
    /// that edge: a bound 5.8 % short (r = 0.667, p = 0.201, cos θi = 0.0096).
    #[inline]
    fn height(&self, prop: &Proposal, rect: &Rect, q: DVec2) -> f64 {
        let map = self.config.map;
        match prop.point(map, rect, q) {
            Some(c) => self.f(c.w) * c.jacobian,
            // (Only the lower edges, which the node holds: its upper ones are open.)
            None if q.cmple(prop.lo).any() => self.just_inside(prop, rect, q),
            None => 0.0,
        }
    }

    /// The height a hair inside the lower edges that `q` lies on (see [`Self::height`]).
    #[cold]
    #[inline(never)]
    fn just_inside(&self, prop: &Proposal, rect: &Rect, q: DVec2) -> f64 {
        let hair = (prop.hi - prop.lo) * 1e-12;
        let inside = DVec2::select(q.cmple(prop.lo), prop.lo + hair, q);
        prop.point(self.config.map, rect, inside)
            .map_or(0.0, |c| self.f(c.w) * c.jacobian)
    }

    /// What the bound search maximises at chart point q: the height over the proposal's
    /// shape, h/S (the height itself for a flat box, where S ≡ 1 exactly).
    #[inline]
    fn score(&self, prop: &Proposal, rect: &Rect, q: DVec2) -> f64 {
        let h = self.height(prop, rect, q);
        if prop.shape.is_flat() {
            h
        } else {
            h / prop.shape.value(prop.unit(q))
        }
    }

    /// The bound search's grid over a node's proposal box ((g + 1)² points, edges and
    /// corners included, following the node's own region in the angle charts) with the
    /// height at each: g = the configured `bound_grid` for a flat box, twice it for a shaped
    /// one, whose best point alone is then climbed (h/S has more local maxima than h: a corner
    /// where S is low lifts small heights).
    ///
    /// `coarse`, the grid of the same box at half the steps (the flat box's, for a shaped
    /// one), lends its heights to the points they share: the same coordinates, bit for bit
    /// (j/g and 2j/2g round alike), so nothing is evaluated twice. Only a full grid (no
    /// column skipped) is borrowed from.
    pub(crate) fn grid(
        &self,
        prop: &Proposal,
        rect: &Rect,
        coarse: Option<&[(DVec2, f64)]>,
    ) -> Vec<(DVec2, f64)> {
        let g = self.grid_steps(prop);
        let (lo, hi) = (prop.lo, prop.hi);
        let span = hi - lo;
        let half = g / 2;
        let coarse = coarse.filter(|c| g.is_multiple_of(2) && c.len() == (half + 1) * (half + 1));
        let mut points = Vec::with_capacity((g + 1) * (g + 1));
        // The grid follows the node's own region: in the angle chart, t runs between the
        // node's edges at each a (a sliver of the box may hold all of the node).
        for i in 0..=g {
            let a = lo.x + span.x * i as f64 / g as f64;
            let Some((t0, t1)) = node_row(prop, rect, a) else {
                continue;
            };
            for j in 0..=g {
                // Pull the upper ends in by a hair: the node's upper edges are open.
                let t = t0 + (t1 - t0) * (j as f64 / g as f64).min(ROW_TOP);
                let q = DVec2::new(a, t);
                let known = coarse
                    .filter(|_| i % 2 == 0 && j % 2 == 0)
                    .map(|c| c[(i / 2) * (half + 1) + j / 2])
                    .filter(|&(p, _)| p == q);
                // (NaN marks a height still to evaluate.)
                points.push((q, known.map_or(f64::NAN, |k| k.1)));
            }
        }
        self.fill_heights(prop, rect, &mut points);
        points
    }

    /// Evaluates the height of every point whose height is NaN (the same values in any
    /// order, [`fill_in_halves`]).
    fn fill_heights(&self, prop: &Proposal, rect: &Rect, points: &mut [(DVec2, f64)]) {
        fill_in_halves(points, self.par_levels > 0, &|p: &mut (DVec2, f64)| {
            if p.1.is_nan() {
                p.1 = self.height(prop, rect, p.0);
            }
        });
    }

    /// The grid's steps per axis for `prop` (see [`Self::grid`]).
    pub(crate) fn grid_steps(&self, prop: &Proposal) -> usize {
        let g = usize::from(self.config.bound_grid);
        if prop.shape.is_flat() { g } else { 2 * g }
    }

    /// The heights in the band along the node's stretch of the rim, with their chart points:
    /// 33 points an arc (or edge), each at the rim probe's heights above the rim
    /// ([`Self::rim_probe`]) and at eleven more up to z = 0.4 ([`RIM_BAND_HEIGHTS`]). What a
    /// shaped square or polar box must bound where f stays bounded at the rim (f·Jacobian: f
    /// times the polar chart's constant, [`crate::chart::polar_jacobian`]):
    /// the grid's rows do not reach into that band, where f may still climb or bend (Schlick's
    /// Fresnel at grazing wo; Poulin–Fournier's cylinders), and a shape, unlike the flat box,
    /// may be low there. (The band reaches the grid's last row: on the concentric map the
    /// last column of a leaf of side ¼ before the rim is at z = 0.18, and Poulin–Fournier's
    /// cylinders (n = 8.5, gap 1.3) peaked at z = 0.07 on such a shaped leaf, 3.6 % over a
    /// band that stopped at z = 0.03.)
    pub(crate) fn rim_heights(&self, prop: &Proposal, rect: &Rect) -> Vec<(DVec2, f64)> {
        let map = self.config.map;
        let jacobian = if prop.chart == Chart::Polar {
            crate::chart::polar_jacobian(map)
        } else {
            1.0
        };
        let mut at = Vec::new();
        for (c, s) in rim_points(map, rect, 33) {
            for z in RIM_BAND_HEIGHTS {
                let r = m::sqrt((1.0 - z) * (1.0 + z));
                at.push((DVec3::new(r * c, r * s, z), f64::NAN));
            }
        }
        self.fill_f(&mut at);
        at.into_iter()
            .map(|(w, f)| {
                (
                    prop.coordinates(map, w).clamp(prop.lo, prop.hi),
                    f * jacobian,
                )
            })
            .collect()
    }

    /// f at every direction of `at` ([`fill_in_halves`]).
    fn fill_f(&self, at: &mut [(DVec3, f64)]) {
        fill_in_halves(at, self.par_levels > 0, &|p: &mut (DVec3, f64)| {
            p.1 = self.f(p.0)
        });
    }

    /// The largest h/S in the band along the node's stretch of the rim (`rim`: what
    /// [`Self::rim_heights`] found for the box's chart): what a shaped square or polar box
    /// must bound where f stays bounded at the rim (the flat box
    /// takes the probe's largest f instead).
    fn rim_score(&self, prop: &Proposal, rim: &[(DVec2, f64)]) -> f64 {
        rim.iter()
            .map(|&(q, h)| h / prop.shape.value(prop.unit(q)))
            .fold(0.0, f64::max)
    }

    /// M for `prop` on a node of integral `v1` whose integration met `peak`: the bound
    /// search ([`Self::bound`]) from the integration's largest height, no less than f's limit
    /// at the rim where one is given (a shaped box looks at h/S in `known`'s rim band instead,
    /// [`Self::rim_score`]) times the safety factor, rounded up to f32. `known`'s coarse grid
    /// lends its heights to the grid ([`Self::grid`]), which is returned with M.
    pub(crate) fn proposal_bound(
        &self,
        prop: &Proposal,
        rect: &Rect,
        peak: &Peak,
        v1: f64,
        rim_limit: Option<f64>,
        known: Known<'_>,
    ) -> (f64, Vec<(DVec2, f64)>) {
        let Known { coarse, rim_band } = known;
        if prop.chart == Chart::Polar && prop.shape.is_flat() {
            // The same points as the square's part of the disk, each with height f times the
            // chart's constant Jacobian: the square's bound times it bounds them. (Its grid is
            // the square's: none of the polar box's own is returned.)
            let square = Proposal::in_chart(rect, Chart::Square);
            let (m, _) = self.proposal_bound(&square, rect, peak, v1, rim_limit, Known::default());
            return (crate::evaluate::polar_bound(self.config.map, m), Vec::new());
        }
        // A bound below the node's mean height is certainly wrong (a peak between the points
        // looked at): take four times the mean instead, so that P = ¼ splits the node.
        // (Over a shape, the mean of h/S that would fill the volume: v1 / (area·mean S);
        // a flat shape's mean is exactly 1.)
        let mean = if prop.area() > 0.0 {
            v1 / prop.area() / prop.shape.mean()
        } else {
            0.0
        };
        // The integration refined itself into every sharp feature of the node: its largest
        // value (in the proposal's chart) is a bound candidate and a search seed.
        let seed = match prop.chart {
            Chart::Square => (peak.f, peak.p),
            // (Flat polar boxes took the square's bound above; a shaped one looks at the
            // peak in its own coordinates.)
            Chart::Polar => {
                let map = self.config.map;
                let q = map
                    .square_to_direction_f64(peak.p)
                    .map_or(prop.lo, |w| prop.coordinates(map, w));
                (self.height(prop, rect, q.clamp(prop.lo, prop.hi)), q)
            }
            Chart::Angle | Chart::Sine => (peak.fj, peak.q),
            Chart::AngleY => (peak.fjy, peak.qy),
        };
        let (mut found, grid) = self.bound(prop, rect, seed, coarse);
        if let Some(limit) = rim_limit {
            let limit = if prop.shape.is_flat() {
                limit
            } else {
                self.rim_score(prop, rim_band)
            };
            found = found.max(limit * self.config.bound_safety);
        }
        // (The comparison allows for rounding: a constant f integrates to its value times
        // the area only up to the rule's last bits, and must not be taken for a missed peak.)
        let bound = if found >= mean * self.config.bound_safety * (1.0 - 1e-9) {
            found
        } else {
            4.0 * mean
        };
        // The sampling layout keeps M in f32: round it up here, so that the tree's E[T] (and
        // every decision taken on it) is the one sampling will see.
        (f64::from(round_up_f32(bound)), grid)
    }

    /// M: the largest h/S (h for a flat box) found on a dense grid (edges and corners
    /// included), at the peak hints inside the node, and by a compass search from the best of
    /// those, times the safety factor (SPEC §3). `seed` is a height and where it was seen;
    /// `coarse` lends heights to the grid ([`Self::grid`]), which is returned with M.
    fn bound(
        &self,
        prop: &Proposal,
        rect: &Rect,
        seed: (f64, DVec2),
        coarse: Option<&[(DVec2, f64)]>,
    ) -> (f64, Vec<(DVec2, f64)>) {
        let map = self.config.map;
        let g = self.grid_steps(prop);
        let (lo, hi) = (prop.lo, prop.hi);
        let span = hi - lo;
        let flat = prop.shape.is_flat();
        let over_shape = |h: f64, q: DVec2| {
            if flat {
                h
            } else {
                h / prop.shape.value(prop.unit(q))
            }
        };
        let mut best = [(f64::NEG_INFINITY, lo); 3];
        let mut consider = |h: f64, q: DVec2| {
            if h > best[2].0 {
                best[2] = (h, q);
                best.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
            }
        };
        let grid = self.grid(prop, rect, coarse);
        // A fine shape's quarters are bilinear pieces of their own, each steep where the
        // shape rises to its peak: h/S may have a maximum in each, so each quarter's best
        // grid point is climbed.
        let fine = prop.shape.grid().is_some();
        let mut quarters = [(f64::NEG_INFINITY, lo); 4];
        // Each edge's grid points (x = lo, x = hi, y = lo, y = hi) for a shaped box, as
        // (unit coordinate along the edge, h/S).
        let mut edges: [Vec<(f64, f64)>; 4] = Default::default();
        for &(q, h) in &grid {
            let r = over_shape(h, q);
            consider(r, q);
            if !flat {
                let t = prop.unit(q);
                let on = [t.x <= 0.0, t.x >= EDGE, t.y <= 0.0, t.y >= EDGE];
                for (e, _) in on.iter().enumerate().filter(|o| *o.1) {
                    edges[e].push((if e < 2 { t.y } else { t.x }, r));
                }
            }
            if fine {
                let ([i, j], _) = crate::proposal::quarter(prop.unit(q));
                let k = i + 2 * j;
                if r > quarters[k].0 {
                    quarters[k] = (r, q);
                }
            }
        }
        // A polar box's heights near its centre edge s = 0 move as √s (r = √s), so h/S can
        // peak a few thousandths of the box from it, between the grid's first two rows (and
        // a shape that falls along that edge makes it likelier): Cook–Torrance m = 0.67 near
        // grazing had a bound 3.5 % short there. Rows at s = span·4⁻ᵏ, k = 1…12, at the
        // grid's azimuths look at it (a polar box is the root's or one of its children's).
        if prop.chart == Chart::Polar {
            for k in 1..=POLAR_CENTRE_ROWS {
                let s = lo.x + span.x * m::pow(0.25, f64::from(k));
                for j in 0..=g {
                    let q = DVec2::new(s, lo.y + span.y * j as f64 / g as f64);
                    consider(self.score(prop, rect, q), q);
                }
            }
        }
        let seed = (seed.0, seed.1.clamp(lo, hi));
        consider(over_shape(seed.0, seed.1), seed.1);
        // Peak hints: inside the node, or projected onto its closest point (a lobe peaked just
        // outside is largest on the near edge). A hint inside the node is also climbed from
        // below, whatever its rank: in a chart whose Jacobian vanishes at the rim, a lobe
        // peaked on the rim has a small height there and its maximum just inside, which a
        // climb from the grid's best points (on the diffuse plateau) never reaches. So is a
        // hint outside the node but within the node's width of it: its projection need not
        // be where the node's part of the lobe is largest (Cook–Torrance m = 0.037 at
        // cos θi = 0.02: masking zeroes the lobe at the mirror direction, which lies just
        // beyond the node's edge, and the lobe's tail along that edge peaks 0.007 further in,
        // twice the diffuse level the rest of the node has: a bound of the diffuse level).
        // (`PeakHints` holds at most four.)
        let mut climbed: [Option<(f64, DVec2)>; 4] = [None; 4];
        let width = (rect.max - rect.min).max_element();
        let mut on_lines = Vec::new();
        for (k, w) in self.hints.iter().enumerate() {
            // In f64: a grazing lobe's peak sits 10⁻¹⁰ inside the square's edge, and can be
            // narrower than f32's resolution there (10⁻⁷ in angle).
            let p = map.direction_to_square_f64(*w);
            let pc = p.clamp(rect.min, rect.max - (rect.max - rect.min) * 1e-9);
            let Some(wc) = map.square_to_direction_f64(pc) else {
                continue;
            };
            let q = prop.coordinates(map, wc).clamp(lo, hi);
            let h = self.score(prop, rect, q);
            consider(h, q);
            if (pc == p || (p - pc).length() <= width) && k < climbed.len() {
                climbed[k] = Some((h, q));
            }
            if self.hint_lines {
                on_lines.clear();
                hint_line_points(map, rect, *w, Axis::X, &mut on_lines);
                hint_line_points(map, rect, *w, Axis::Y, &mut on_lines);
                for &d in &on_lines {
                    let q = prop.coordinates(map, d).clamp(lo, hi);
                    consider(self.score(prop, rect, q), q);
                }
            }
        }
        // The three searches are independent: run them side by side (the largest of three
        // is the same in any order).
        let climb = |(h0, q0): (f64, DVec2)| {
            if h0 > 0.0 {
                self.compass_search(prop, rect, q0, h0, span / g as f64)
            } else {
                0.0
            }
        };
        let par = self.par_levels > 0;
        // The climbs from the hints, beside those from the grid's best points (the largest
        // of them all is the same in any order). A hint's climb starts from the best of a
        // probe at every scale along the chart's axes (steps of the grid's spacing halved
        // down to 2⁻²³ of it): the lobe's width is unknown, and where the chart's Jacobian
        // vanishes at the rim the hint's own height is nearly 0, so the grid-sized first
        // step of a plain climb lands on the diffuse slope inward (higher than that), and
        // climbs it away from the lobe (Blinn–Phong n = 3 129 at cos θi = 10⁻⁴ on the
        // concentric map: a bound 12 times too low).
        let hints = || {
            climbed
                .iter()
                .flatten()
                .map(|&(h0, q0)| {
                    let (mut best, mut step) = ((h0, q0), span / g as f64);
                    let mut s = step;
                    for _ in 0..HINT_PROBE_SCALES {
                        for d in [
                            DVec2::new(s.x, 0.0),
                            DVec2::new(-s.x, 0.0),
                            DVec2::new(0.0, s.y),
                            DVec2::new(0.0, -s.y),
                        ] {
                            let c = (q0 + d).clamp(lo, hi);
                            let hc = self.score(prop, rect, c);
                            if hc > best.0 {
                                (best, step) = ((hc, c), s);
                            }
                        }
                        s *= 0.5;
                    }
                    if best.0 > 0.0 {
                        self.compass_search(prop, rect, best.1, best.0, step)
                    } else {
                        0.0
                    }
                })
                .fold(0.0, f64::max)
        };
        // A shape lifts the heights most where it is lowest, on its corners and edges, and
        // there h/S can peak between the grid's points where a climb, which stops at the
        // box's edge, does not reach from the grid's best (Phong n = 5.75, concentric: a
        // polar box whose shape falls to 9/63 at (rim, φ edge) peaked at s = 0.9907 on that
        // edge, between the rows at 0.9375 and 1, higher than the edge's best grid point near
        // s = 0: a maximum 2.5 % over the search's; Oren–Nayar σ = 0.24 at cos θi = 0.05: a
        // square leaf's left edge peaked between two grid points, 2.5 % over). Along each
        // edge, the highest local maxima of the grid that come near the best of all are
        // searched between their neighbours.
        let edge_climbs = || {
            edges
                .iter()
                .enumerate()
                .map(|(k, e)| self.edge_peaks(prop, rect, k, e, 0.9 * best[0].0, &over_shape))
                .fold(0.0, f64::max)
        };
        // (A shaped box's grid is twice as fine: its best point alone is climbed, and a fine
        // shape's best point in each quarter; its edges are searched along.)
        let ((h0, from_hints), (h1, h2)) = if flat {
            join(
                par,
                || join(par, || climb(best[0]), hints),
                || join(par, || climb(best[1]), || climb(best[2])),
            )
        } else if fine {
            // (Only quarters whose best point comes near the best of all: a maximum of h/S
            // far below it at the grid cannot pass it between grid points.)
            let near = |k: usize| {
                let q = quarters[k];
                if q.0 >= 0.9 * best[0].0 && q.1 != best[0].1 {
                    climb(q)
                } else {
                    0.0
                }
            };
            let pair = |a: usize, b: usize| near(a).max(near(b));
            join(
                par,
                || join(par, || climb(best[0]), hints),
                || join(par, || pair(0, 1).max(edge_climbs()), || pair(2, 3)),
            )
        } else {
            join(
                par,
                || join(par, || climb(best[0]), hints),
                || (edge_climbs(), 0.0),
            )
        };
        let m = best[0].0.max(0.0).max(h0).max(h1).max(h2).max(from_hints);
        (m * self.config.bound_safety, grid)
    }

    /// The largest h/S found along edge `k` of `prop`'s box (x = lo, x = hi, y = lo, y = hi;
    /// an upper edge, which the node leaves open, a hair inside as the grid has it) between
    /// its grid points: around each of the [`EDGE_PEAKS`] highest local maxima of the grid's
    /// `profile` along it (unit coordinate, h/S) that reach `floor`, a golden-section search
    /// of the stretch between that point's two neighbours.
    fn edge_peaks(
        &self,
        prop: &Proposal,
        rect: &Rect,
        k: usize,
        profile: &[(f64, f64)],
        floor: f64,
        over_shape: &impl Fn(f64, DVec2) -> f64,
    ) -> f64 {
        const INV_PHI: f64 = 0.618_033_988_749_894_9;
        let mut profile = profile.to_vec();
        profile.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let n = profile.len();
        let mut peaks: Vec<usize> = (0..n)
            .filter(|&i| {
                let r = profile[i].1;
                r >= floor
                    && (i == 0 || profile[i - 1].1 <= r)
                    && (i + 1 == n || profile[i + 1].1 <= r)
            })
            .collect();
        peaks.sort_unstable_by(|&a, &b| profile[b].1.total_cmp(&profile[a].1));
        let (lo, span) = (prop.lo, prop.hi - prop.lo);
        // h/S at unit coordinate u along the edge.
        let at = |u: f64| {
            let t = match k {
                0 => DVec2::new(0.0, u),
                1 => DVec2::new(ROW_TOP, u),
                2 => DVec2::new(u, 0.0),
                _ => DVec2::new(u, ROW_TOP),
            };
            let q = lo + span * t;
            over_shape(self.height(prop, rect, q), q)
        };
        let mut found = 0.0f64;
        for &i in peaks.iter().take(EDGE_PEAKS) {
            let mut a = profile[i.saturating_sub(1)].0;
            let mut b = profile[(i + 1).min(n - 1)].0;
            let stop = (b - a) * 1e-3;
            let (mut c, mut d) = (b - INV_PHI * (b - a), a + INV_PHI * (b - a));
            let (mut fc, mut fd) = (at(c), at(d));
            found = found.max(fc).max(fd);
            while b - a > stop {
                if fc >= fd {
                    (b, d, fd) = (d, c, fc);
                    c = b - INV_PHI * (b - a);
                    fc = at(c);
                    found = found.max(fc);
                } else {
                    (a, c, fc) = (c, d, fd);
                    d = a + INV_PHI * (b - a);
                    fd = at(d);
                    found = found.max(fd);
                }
            }
        }
        found
    }

    /// Looks at f along the node's own stretch of the rim ([`rim_points`]: its arcs of the
    /// circle, orthographic; its parts of the square's edge, concentric), at heights z = 1e-5
    /// and 1e-9 above it. If f still grows between them (Ward's 1/√z, even under a diffuse
    /// term) it is treated as unbounded; otherwise the largest value seen is its limit at the
    /// rim.
    pub(crate) fn rim_probe(&self, rect: &Rect) -> RimProbe {
        let mut limit: f64 = 0.0;
        for (c, s) in rim_points(self.config.map, rect, 9) {
            let at = |z: f64| {
                let r = m::sqrt((1.0 - z) * (1.0 + z));
                self.f(DVec3::new(r * c, r * s, z))
            };
            // z = 1e-9 is below the smallest height a sample can have (f64 positions give
            // z ≳ 1e-8); any growth toward it means f is still climbing there: unbounded.
            let (near, nearer) = (at(1e-5), at(1e-9));
            if nearer > near * (1.0 + 1e-3) && nearer > 0.0 {
                return RimProbe::Unbounded;
            }
            limit = limit.max(near).max(nearer);
        }
        RimProbe::Bounded(limit)
    }

    /// Hill-climbs h/S (h for a flat box) from q0 with axis steps of the chart, halving them
    /// when no step improves; in the angle charts the climb then goes on from where it
    /// stopped in the node's row coordinates ([`SearchSpace`]), which follow the node's
    /// curved edges. (Each climb alone misses maxima the other finds: the chart's steps stop
    /// at a curved edge, and the rows, whose lengths vary with a, bend the chart's straight
    /// ridges.)
    fn compass_search(
        &self,
        prop: &Proposal,
        rect: &Rect,
        q0: DVec2,
        h0: f64,
        step0: DVec2,
    ) -> f64 {
        let (q, h) = self.climb(&SearchSpace::chart(prop, rect), q0, h0, step0);
        let rows = SearchSpace::rows(prop, rect);
        if !rows.rows {
            return h;
        }
        let span = prop.hi.y - prop.lo.y;
        let step = DVec2::new(step0.x, if span > 0.0 { step0.y / span } else { 0.0 });
        self.climb(&rows, q, h, step).1
    }

    /// The compass search itself in `space`, from chart point q0 of score h0 with first steps
    /// `step0` (in `space`'s coordinates): the chart point where it stopped and its score.
    fn climb(&self, space: &SearchSpace<'_>, q0: DVec2, h0: f64, step0: DVec2) -> (DVec2, f64) {
        let (prop, rect) = (space.prop, &space.rect);
        let (lo, hi) = space.bounds();
        let (mut v, mut q, mut h, mut step) = (space.search_point(q0), q0, h0, step0);
        let stop = step0 * 1e-4;
        let mut evals = 0;
        while (step.x > stop.x || step.y > stop.y) && evals < 400 {
            let mut moved = false;
            for d in [
                DVec2::new(step.x, 0.0),
                DVec2::new(-step.x, 0.0),
                DVec2::new(0.0, step.y),
                DVec2::new(0.0, -step.y),
            ] {
                let c = (v + d).clamp(lo, hi);
                evals += 1;
                let Some(qc) = space.chart_point(c) else {
                    continue;
                };
                let hc = self.score(prop, rect, qc);
                if hc > h {
                    (v, q, h, moved) = (c, qc, hc, true);
                    break;
                }
            }
            if !moved {
                step *= 0.5;
            }
        }
        (q, h)
    }
}
