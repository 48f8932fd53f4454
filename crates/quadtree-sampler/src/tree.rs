//! The arena quadtree (seed §2.1, Fig. 1–2): nodes, the split (`particionar`) and the
//! target-trials refinement.

use crate::chart::{Cell, Chart, Peak, Proposal, Rect, UnitRule, join, refine_cells};
use crate::config::{BuildConfig, IntegrationRule};
use crate::error::BuildError;
use alloc::collections::BinaryHeap;
use alloc::vec::Vec;
use brdf_core::{Brdf, DiskMap, math as m};
use core::cmp::Ordering;
use core::sync::atomic::{AtomicU64, AtomicUsize, Ordering as AtomicOrdering};
use glam::{DVec2, DVec3, Vec3};

/// No child: the node is a leaf.
pub const LEAF: u32 = 0;

/// One node of the arena: the seed's `Nodo` with its `Region`.
///
/// The square is [x, x+s) × [y, y+s) of the seed's domain; `v1` = ∫ f_r over it (square
/// measure), `bound` (M) an upper bound of the proposal's height function over the proposal
/// box, and P = v1 / (box area · M). Children are four contiguous nodes from `first_child`,
/// in the child order of [`crate::chart::child_index`]: (−,−), (+,−), (−,+), (+,+).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    /// Lower-left corner u.
    pub x: f32,
    /// Lower-left corner v.
    pub y: f32,
    /// Side s.
    pub size: f32,
    /// Depth (root = 0).
    pub depth: u8,
    /// Index of the first of four children, or [`LEAF`].
    pub first_child: u32,
    /// v1: ∫ f_r over the square (f64). For an inner node, the sum of its children's.
    pub v1: f64,
    /// M: the height bound of the rejection test in this node's proposal chart.
    pub bound: f64,
    /// The rejection proposal of this node (used when it is a leaf).
    pub proposal: Proposal,
}

impl Node {
    /// The node's square in f64.
    #[must_use]
    pub fn rect(&self) -> Rect {
        Rect::square(f64::from(self.x), f64::from(self.y), f64::from(self.size))
    }

    /// Whether the node has no children.
    #[must_use]
    pub fn is_leaf(&self) -> bool {
        self.first_child == LEAF
    }

    /// The volume of the rejection box: proposal area × M (s²·M for the seed's square chart).
    #[must_use]
    pub fn box_volume(&self) -> f64 {
        self.proposal.area() * self.bound
    }

    /// The wasted volume that splitting can remove: box/safety − v1 (the safety factor's
    /// share of the box is the same in every child).
    #[must_use]
    pub fn reducible_waste(&self, safety: f64) -> f64 {
        self.box_volume() / safety - self.v1
    }

    /// The seed's P = v1 / (box volume): the acceptance probability of rejection in this node.
    #[must_use]
    pub fn acceptance(&self) -> f64 {
        let b = self.box_volume();
        if b > 0.0 { self.v1 / b } else { 0.0 }
    }
}

/// Orthographic: azimuths of points on the unit circle inside `rect`: nine per arc, ends
/// included (nudged inside). The arcs' ends are where the circle crosses the rectangle's edges.
fn rim_arc_points(rect: &Rect) -> Vec<f64> {
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
        points.extend((0..9).map(|j| a + pad + (b - a - 2.0 * pad) * j as f64 / 8.0));
    }
    points
}

/// Concentric: the rim is the square's edge. Points (cos φ, sin φ) of the rim directions of the
/// node's stretches of it: nine per edge it lies on, ends included (nudged inside).
fn edge_rim_points(rect: &Rect) -> Vec<(f64, f64)> {
    let mut points = Vec::new();
    let mut stretch = |p0: DVec2, p1: DVec2| {
        let pad = (p1 - p0) * 1e-9;
        for j in 0..9 {
            let p = p0 + pad + (p1 - p0 - 2.0 * pad) * (j as f64 / 8.0);
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

/// The node's rim points (cos φ, sin φ) under `map` ([`rim_arc_points`], [`edge_rim_points`]).
fn rim_points(map: DiskMap, rect: &Rect) -> Vec<(f64, f64)> {
    match map {
        DiskMap::Orthographic => rim_arc_points(rect)
            .into_iter()
            .map(|phi| (m::cos(phi), m::sin(phi)))
            .collect(),
        DiskMap::Concentric => edge_rim_points(rect),
    }
}

/// `m` as an f32 no smaller than it (an upper bound stays one).
pub(crate) fn round_up_f32(m: f64) -> f32 {
    let b = m as f32;
    if f64::from(b) < m { b.next_up() } else { b }
}

/// What [`Context::rim_probe`] found: f's behaviour approaching the rim inside a node.
#[derive(Clone, Copy, Debug)]
enum RimProbe {
    /// f grows without bound toward the rim (1/√z or faster).
    Unbounded,
    /// f stays bounded; the largest value seen near the rim.
    Bounded(f64),
}

/// What a node's evaluation found.
#[derive(Clone, Copy, Debug)]
struct Evaluation {
    v1: f64,
    bound: f64,
    proposal: Proposal,
}

/// Integration cells the build may remember for the nodes still to split (88 bytes each:
/// 88 MiB). Past it, a new node keeps only the cells of its children's first rule
/// application, and past twice it none: the memoised cells only save work (a forgotten one
/// is recomputed bit for bit), so the tree does not depend on this, and the build's memory
/// stays below about 2 × 88 MiB plus 80 bytes per node.
pub(crate) const CELL_CACHE_LIMIT: usize = 1 << 20;

/// Parents split per batch of the breadth-first pass (between batches the evaluation budget
/// is checked).
const SPLIT_CHUNK: usize = 256;

/// Everything a node evaluation needs: pure, shared by the worker threads.
struct Context<'a, B: Brdf + ?Sized> {
    pub brdf: &'a B,
    pub wi: Vec3,
    pub config: BuildConfig,
    rule: UnitRule,
    hints: Vec<DVec3>,
    /// Absolute floor of every node's integration tolerance: the relative tolerance times an
    /// estimate of the total volume (a node's error below it cannot be seen by any test).
    tol_floor: f64,
    /// Levels of each node's adaptive integration whose quadrants run in parallel.
    par_levels: u32,
    /// Integration cells remembered for the leaves (see [`CELL_CACHE_LIMIT`]).
    cached: AtomicUsize,
    /// f_r evaluations spent so far (see [`BuildConfig::evaluation_budget`]).
    spent: AtomicU64,
    /// Evaluations per rule application (n² points; twice that where the angle chart
    /// splits a node into pieces, counted as its mean).
    per_application: u64,
}

impl<'a, B: Brdf + ?Sized> Context<'a, B> {
    /// The context, and the root's integration cells (the estimate of the total volume is an
    /// adaptive integration of the root, which the root's own evaluation then continues).
    fn new(brdf: &'a B, wi: Vec3, config: BuildConfig) -> (Self, Cell) {
        let rule = match config.rule {
            IntegrationRule::Midpoint { n } => UnitRule::midpoint(usize::from(n)),
            IntegrationRule::GaussLegendre { n } => UnitRule::new(usize::from(n)),
        };
        let hints = brdf
            .peak_hints(brdf_core::geometry::lift_incident(wi))
            .as_slice()
            .iter()
            .map(|h| h.as_dvec3().normalize())
            .collect();
        let mut ctx = Self {
            brdf,
            wi,
            config,
            rule,
            hints,
            tol_floor: 0.0,
            // Every level: the work of a sharp lobe sits in one quadrant after another, so a
            // fixed number of top levels would leave one thread with all of it. A join that is
            // not stolen costs far less than the 4 × 36 evaluations of the cell it splits.
            par_levels: if cfg!(feature = "rayon") && config.parallel {
                u32::MAX
            } else {
                0
            },
            cached: AtomicUsize::new(0),
            spent: AtomicU64::new(0),
            per_application: {
                let n = match config.rule {
                    IntegrationRule::Midpoint { n } | IntegrationRule::GaussLegendre { n } => {
                        u64::from(n)
                    }
                };
                2 * n * n
            },
        };
        let root = Rect::square(-1.0, -1.0, 2.0);
        let f = |w: DVec3| ctx.f(w);
        let mut cell = Cell::once(config.map, &root, &ctx.rule, &f);
        let tol = 1e-3 * cell.value.abs();
        let estimate = refine_cells(
            config.map,
            &root,
            &mut cell,
            &ctx.rule,
            tol,
            6,
            &f,
            &mut Peak::default(),
            ctx.par_levels,
        );
        ctx.tol_floor = config.integration_tolerance * 1e-2 * estimate.abs();
        ctx.spend((1 + cell.applications(tol, 6)) * ctx.per_application);
        (ctx, cell)
    }

    /// f_r's luminance at a local direction (the density the tree follows).
    #[inline]
    pub(crate) fn f(&self, w: DVec3) -> f64 {
        f64::from(self.brdf.eval_luminance(self.wi, w.as_vec3()))
    }

    /// The proposal's height function h = f·Jacobian at chart point q (0 outside the node).
    #[inline]
    fn height(&self, prop: &Proposal, rect: &Rect, q: DVec2) -> f64 {
        prop.point(self.config.map, rect, q)
            .map_or(0.0, |c| self.f(c.w) * c.jacobian)
    }

    /// Evaluates the node `rect`, continuing from the integration cells `cells` its parent
    /// left for it; returns its own cells for its children.
    fn evaluate(&self, rect: &Rect, cells: Option<Cell>) -> (Evaluation, Option<Cell>) {
        let map = self.config.map;
        let square = Proposal::in_chart(rect, Chart::Square);
        if map == DiskMap::Orthographic && rect.radius_range().0 >= 1.0 {
            let e = Evaluation {
                v1: 0.0,
                bound: 0.0,
                proposal: square,
            };
            return (e, None);
        }
        let chart = Proposal::for_node(map, rect);
        let f = |w: DVec3| self.f(w);
        // One application of the rule sets the tolerance and is the refinement's start (the
        // node's points are integrated once, not twice; and not at all when the parent's
        // integration already applied the rule here).
        let mut cell = cells.unwrap_or_else(|| Cell::once(map, rect, &self.rule, &f));
        let mut peak = cell.peak;
        let tol = (self.config.integration_tolerance * cell.value.abs()).max(self.tol_floor);
        let v1 = refine_cells(
            map,
            rect,
            &mut cell,
            &self.rule,
            tol,
            u32::from(self.config.integration_depth),
            &f,
            &mut peak,
            self.par_levels,
        )
        .max(0.0);
        // The node's integration as if nothing were memoised (so the count, and the budget's
        // verdict, do not depend on the cache), and each bound search's grid, hints and three
        // compass searches of at most 400 steps.
        let g = u64::from(self.config.bound_grid) + 1;
        let depth = u32::from(self.config.integration_depth);
        let search = g * g + 1200;
        self.spend((1 + cell.applications(tol, depth)) * self.per_application + search);
        let chart_bound = self.proposal_bound(&chart, rect, &peak, v1, None);
        // A rim node is sampled in the proposal with the smaller box it can bound. The angle
        // and sine charts bound f·Jacobian even where f is unbounded at the rim (Ward's 1/√z),
        // but their Jacobians vanish there, so their boxes waste about half of a rim node
        // whatever f does; where f stays bounded the seed's square is usually tighter (its only
        // waste, outside the disk, orthographic; none, concentric). Not always: where f climbs
        // steeply just short of the rim (Oren–Nayar at grazing incidence) the vanishing
        // Jacobian is what flattens the height. So both are bounded and the smaller kept (ties
        // to the square).
        // (Off the rim the chart proposal is the square itself: nothing to compare.)
        let rim = (chart.chart != Chart::Square).then(|| self.rim_probe(rect));
        let (proposal, bound) = match rim {
            None | Some(RimProbe::Unbounded) => (chart, chart_bound),
            Some(RimProbe::Bounded(limit)) => {
                self.spend(search);
                let square_bound = self.proposal_bound(&square, rect, &peak, v1, Some(limit));
                if square.area() * square_bound <= chart.area() * chart_bound {
                    (square, square_bound)
                } else {
                    (chart, chart_bound)
                }
            }
        };
        let e = Evaluation {
            v1,
            bound,
            proposal,
        };
        (e, Some(cell))
    }

    /// M for `prop` on a node of integral `v1` whose integration met `peak`: the bound
    /// search ([`Self::bound`]) from the integration's largest height, no less than f's limit
    /// at the rim where one is given (times the safety factor), rounded up to f32.
    fn proposal_bound(
        &self,
        prop: &Proposal,
        rect: &Rect,
        peak: &Peak,
        v1: f64,
        rim_limit: Option<f64>,
    ) -> f64 {
        // A bound below the node's mean height is certainly wrong (a peak between the points
        // looked at): take four times the mean instead, so that P = ¼ splits the node.
        let mean = if prop.area() > 0.0 {
            v1 / prop.area()
        } else {
            0.0
        };
        // The integration refined itself into every sharp feature of the node: its largest
        // value (in the proposal's chart) is a bound candidate and a search seed.
        let seed = match prop.chart {
            Chart::Square => (peak.f, peak.p),
            Chart::Angle | Chart::Sine => (peak.fj, peak.q),
            Chart::AngleY => (peak.fjy, peak.qy),
        };
        let mut found = self.bound(prop, rect, seed);
        if let Some(limit) = rim_limit {
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
        f64::from(round_up_f32(bound))
    }

    /// M: the largest h found on a dense grid (edges and corners included), at the peak hints
    /// inside the node, and by a compass search from the best of those, times the safety
    /// factor (SPEC §3).
    fn bound(&self, prop: &Proposal, rect: &Rect, seed: (f64, DVec2)) -> f64 {
        let map = self.config.map;
        let g = usize::from(self.config.bound_grid);
        let (lo, hi) = (prop.lo, prop.hi);
        let span = hi - lo;
        let mut best = [(f64::NEG_INFINITY, lo); 3];
        let mut consider = |h: f64, q: DVec2| {
            if h > best[2].0 {
                best[2] = (h, q);
                best.sort_unstable_by(|a, b| b.0.total_cmp(&a.0));
            }
        };
        // The grid follows the node's own region: in the angle chart, t runs between the
        // node's edges at each a (a sliver of the box may hold all of the node).
        for i in 0..=g {
            let a = lo.x + span.x * i as f64 / g as f64;
            let (t0, t1) = match prop.chart {
                Chart::Angle | Chart::AngleY => {
                    let ca = m::cos(a);
                    if ca <= 0.0 {
                        continue;
                    }
                    let lim = |y: f64| m::asin((y / ca).clamp(-1.0, 1.0));
                    let (ylo, yhi) = if prop.chart == Chart::Angle {
                        (rect.min.y, rect.max.y)
                    } else {
                        (rect.min.x, rect.max.x)
                    };
                    (lim(ylo), lim(yhi).min(hi.y))
                }
                Chart::Square | Chart::Sine => (lo.y, hi.y),
            };
            for j in 0..=g {
                // Pull the upper ends in by a hair: the node's upper edges are open.
                let t = t0 + (t1 - t0) * (j as f64 / g as f64).min(1.0 - 1e-12);
                let q = DVec2::new(a, t);
                consider(self.height(prop, rect, q), q);
            }
        }
        consider(seed.0, seed.1.clamp(lo, hi));
        // Peak hints: inside the node, or projected onto its closest point (a lobe peaked just
        // outside is largest on the near edge). A hint inside the node is also climbed from
        // below, whatever its rank: in a chart whose Jacobian vanishes at the rim, a lobe
        // peaked on the rim has a small height there and its maximum just inside, which a
        // climb from the grid's best points (on the diffuse plateau) never reaches.
        // (`PeakHints` holds at most four.)
        let mut inside: [Option<(f64, DVec2)>; 4] = [None; 4];
        for (k, w) in self.hints.iter().enumerate() {
            let p = match map {
                DiskMap::Orthographic => DVec2::new(w.x, w.y),
                DiskMap::Concentric => {
                    brdf_core::maps::disk_to_square_concentric(w.truncate().as_vec2()).as_dvec2()
                }
            };
            let pc = p.clamp(rect.min, rect.max - (rect.max - rect.min) * 1e-9);
            let Some(wc) = map.square_to_direction_f64(pc) else {
                continue;
            };
            let q = prop.coordinates(map, wc).clamp(lo, hi);
            let h = self.height(prop, rect, q);
            consider(h, q);
            if pc == p && k < inside.len() {
                inside[k] = Some((h, q));
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
        let (h0, (h1, h2)) = join(
            par,
            || climb(best[0]),
            || join(par, || climb(best[1]), || climb(best[2])),
        );
        let from_hints = inside
            .iter()
            .flatten()
            .map(|&x| climb(x))
            .fold(0.0, f64::max);
        best[0].0.max(0.0).max(h0).max(h1).max(h2).max(from_hints) * self.config.bound_safety
    }

    /// Looks at f along the node's own stretch of the rim ([`rim_points`]: its arcs of the
    /// circle, orthographic; its parts of the square's edge, concentric), at heights z = 1e-5
    /// and 1e-9 above it. If f still grows between them (Ward's 1/√z, even under a diffuse
    /// term) it is treated as unbounded; otherwise the largest value seen is its limit at the
    /// rim.
    fn rim_probe(&self, rect: &Rect) -> RimProbe {
        let mut limit: f64 = 0.0;
        for (c, s) in rim_points(self.config.map, rect) {
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

    /// Hill-climbs h from q0 with axis steps, halving them when no step improves.
    fn compass_search(
        &self,
        prop: &Proposal,
        rect: &Rect,
        q0: DVec2,
        h0: f64,
        step0: DVec2,
    ) -> f64 {
        let (mut q, mut h, mut step) = (q0, h0, step0);
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
                let c = (q + d).clamp(prop.lo, prop.hi);
                let hc = self.height(prop, rect, c);
                evals += 1;
                if hc > h {
                    (q, h, moved) = (c, hc, true);
                    break;
                }
            }
            if !moved {
                step *= 0.5;
            }
        }
        h
    }

    /// Evaluates nodes (in parallel when enabled), each from its inherited cells.
    fn evaluate_all(&self, nodes: Vec<(Rect, Option<Cell>)>) -> Vec<(Evaluation, Option<Cell>)> {
        let one = |(r, c): (Rect, Option<Cell>)| {
            let (e, cells) = self.evaluate(&r, c);
            (e, self.remember(cells))
        };
        #[cfg(feature = "rayon")]
        if self.config.parallel {
            use rayon::prelude::*;
            return nodes.into_par_iter().map(one).collect();
        }
        nodes.into_iter().map(one).collect()
    }

    /// A new leaf's cells as the cache budget allows ([`CELL_CACHE_LIMIT`]), counted in.
    fn remember(&self, cells: Option<Cell>) -> Option<Cell> {
        let mut cell = cells?;
        let held = self.cached.load(AtomicOrdering::Relaxed);
        if held > 2 * CELL_CACHE_LIMIT {
            return None;
        }
        if held > CELL_CACHE_LIMIT {
            cell.prune(1);
        }
        self.cached.fetch_add(cell.count(), AtomicOrdering::Relaxed);
        Some(cell)
    }

    /// Counts `n` evaluations spent.
    fn spend(&self, n: u64) {
        self.spent.fetch_add(n, AtomicOrdering::Relaxed);
    }

    /// Whether the evaluation budget is spent with `nodes` built (checked between batches
    /// of nodes, whose work does not depend on the order the threads did it in).
    fn overspent(&self, nodes: usize) -> bool {
        let allowed = self
            .config
            .evaluation_budget
            .saturating_add((nodes as u64).saturating_mul(crate::config::EVALUATIONS_PER_NODE));
        self.spent.load(AtomicOrdering::Relaxed) > allowed
    }

    /// Counts out a leaf's cells as it hands them to its children.
    fn forget(&self, cells: &Option<Cell>) {
        if let Some(c) = cells {
            self.cached.fetch_sub(c.count(), AtomicOrdering::Relaxed);
        }
    }
}

/// Counts that describe a built tree.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TreeStats {
    /// Number of nodes.
    pub nodes: usize,
    /// Number of leaves.
    pub leaves: usize,
    /// Leaves with v1 > 0 (the ones that can be chosen).
    pub live_leaves: usize,
    /// Deepest leaf.
    pub max_depth: u8,
    /// Leaves per depth.
    pub depth_histogram: Vec<usize>,
    /// Bytes of the nodes, in the layout the counts were taken from: 80 per node in the
    /// build's [`Quadtree`], 16 in the sampling layout ([`crate::PackedTree`]).
    pub bytes: usize,
    /// E\[T\] = Σ box volumes / Σ v1 over live leaves: expected rejection trials per sample.
    pub expected_trials: f64,
    /// Whether the node budget stopped a split.
    pub budget_exhausted: bool,
}

/// The seed's `Quadtree` over the square for one incident direction: an arena of nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct Quadtree {
    nodes: Vec<Node>,
    map: DiskMap,
    budget_exhausted: bool,
}

impl Quadtree {
    /// Builds the tree of f_r(wi, ·) for a local `wi` (normalised here; it must be finite,
    /// non-zero and above the horizon). Delta models are an error, and so is an f_r that is 0
    /// for this `wi` ([`BuildError::ZeroBrdf`]) or one the budget cannot bound to at most
    /// [`crate::MAX_USABLE_EXPECTED_TRIALS`] trials per sample ([`BuildError::Exhausted`]).
    /// The build's time is bounded by the node budget and its memory by the node budget and a
    /// fixed cache of integration cells (about 180 MiB). This is the build's own
    /// layout, with everything each node's evaluation found; samplers use its
    /// [`crate::PackedTree`].
    pub fn new<B: Brdf + ?Sized>(
        brdf: &B,
        wi: Vec3,
        config: BuildConfig,
    ) -> Result<Self, BuildError> {
        Self::from_unit(brdf, brdf_core::geometry::unit_direction_above(wi)?, config)
    }

    /// [`Quadtree::new`] for a `wi` its caller already checked and normalised (normalising
    /// twice may move its last bit, and the tree must be built for the very `wi` the caller
    /// keeps).
    pub(crate) fn from_unit<B: Brdf + ?Sized>(
        brdf: &B,
        wi: Vec3,
        config: BuildConfig,
    ) -> Result<Self, BuildError> {
        let (ctx, cells) = Context::new(brdf, wi, config);
        Self::build(&ctx, cells)
    }

    /// Builds the tree of f_r(wi, ·) (`wi` local, above the horizon), splitting every node
    /// whose P is below the threshold (`particionar`), then, in target mode, refining the
    /// leaves with the largest wasted volume until E\[T\] ≤ target.
    fn build<B: Brdf + ?Sized>(ctx: &Context<'_, B>, root_cells: Cell) -> Result<Self, BuildError> {
        ctx.config.validate()?;
        if ctx.brdf.is_delta() {
            return Err(BuildError::DeltaModel {
                model: ctx.brdf.name(),
            });
        }
        let cfg = &ctx.config;
        let budget = cfg.node_budget as usize;
        let root_rect = Rect::square(-1.0, -1.0, 2.0);
        let (e, cells) = ctx.evaluate(&root_rect, Some(root_cells));
        // Each leaf's integration cells, until it splits and hands them to its children.
        let mut pending = alloc::vec![ctx.remember(cells)];
        let mut tree = Self {
            nodes: alloc::vec![Node {
                x: -1.0,
                y: -1.0,
                size: 2.0,
                depth: 0,
                first_child: LEAF,
                v1: e.v1,
                bound: e.bound,
                proposal: e.proposal
            }],
            map: cfg.map,
            budget_exhausted: false,
        };
        // Breadth-first: decide a level's splits serially (in index order), evaluate the new
        // children together (in parallel when enabled). Same tree either way.
        let mut frontier: Vec<u32> = alloc::vec![0];
        let mut total = e.v1;
        while !frontier.is_empty() {
            let mut split = Vec::new();
            for &i in &frontier {
                let n = &tree.nodes[i as usize];
                // v1 = 0 with M > 0: the bound search met f > 0 where every integration
                // point saw 0 (a lobe narrower than the rule's spacing, at grazing incidence
                // the whole of f_r): the node is not empty, its integration is too coarse.
                // Split it, and let its children's finer rules find the mass.
                let wants = n.depth < cfg.max_depth
                    && (n.v1 > 0.0 || n.bound > 0.0)
                    && n.acceptance() < cfg.split_threshold
                    && n.reducible_waste(cfg.bound_safety) > cfg.min_relative_waste * total;
                if wants {
                    if tree.nodes.len() + 4 * (split.len() + 1) > budget {
                        tree.budget_exhausted = true;
                        break;
                    }
                    split.push(i);
                }
            }
            // In chunks, so that the evaluation budget stops a wide level part-way; the
            // children are the same nodes in the same order either way.
            let mut next = Vec::with_capacity(4 * split.len());
            for chunk in split.chunks(SPLIT_CHUNK) {
                if ctx.overspent(tree.nodes.len()) {
                    tree.budget_exhausted = true;
                    break;
                }
                let before: f64 = chunk.iter().map(|&i| tree.nodes[i as usize].v1).sum();
                let children = tree.split(ctx, chunk, &mut pending);
                let after: f64 = children.iter().map(|&i| tree.nodes[i as usize].v1).sum();
                total += after - before;
                next.extend(children);
            }
            frontier = if tree.budget_exhausted {
                Vec::new()
            } else {
                next
            };
        }
        // The seed's rule promises E[T] ≤ 1/threshold; the waste cut-off above can leave rim
        // leaves with P < threshold, so enforce the promise (and any stricter target).
        let target = cfg.target_trials.map_or(1.0 / cfg.split_threshold, |t| {
            t.min(1.0 / cfg.split_threshold)
        });
        tree.refine_to_target(ctx, target, &mut pending);
        tree.sum_up();
        let empty = tree.volume().is_nan() || tree.volume() <= 0.0;
        // Nothing integrated and nothing seen by any bound search: f_r is 0 for this wi.
        // (Nothing integrated but a bound > 0: f_r is there, narrower than the budget let
        // the integration look: exhausted.)
        if empty && tree.leaves().all(|(_, n)| n.bound <= 0.0) {
            return Err(BuildError::ZeroBrdf {
                model: ctx.brdf.name(),
            });
        }
        let expected_trials = if empty {
            f64::INFINITY
        } else {
            tree.stats().expected_trials
        };
        if expected_trials.is_nan() || expected_trials > crate::MAX_USABLE_EXPECTED_TRIALS {
            return Err(BuildError::Exhausted {
                model: ctx.brdf.name(),
                nodes: tree.nodes.len(),
                expected_trials,
            });
        }
        Ok(tree)
    }

    /// Splits the given leaves into four children each, evaluates the children (each from its
    /// quadrant of the parent's integration cells), and returns their indices.
    fn split<B: Brdf + ?Sized>(
        &mut self,
        ctx: &Context<'_, B>,
        parents: &[u32],
        pending: &mut Vec<Option<Cell>>,
    ) -> Vec<u32> {
        let mut rects = Vec::with_capacity(4 * parents.len());
        let mut inherited = Vec::with_capacity(4 * parents.len());
        let first_new = self.nodes.len() as u32;
        for (k, &p) in parents.iter().enumerate() {
            let n = self.nodes[p as usize];
            self.nodes[p as usize].first_child = first_new + 4 * k as u32;
            let cells = pending[p as usize].take();
            ctx.forget(&cells);
            inherited.extend(cells.map_or([None, None, None, None], Cell::into_quads));
            let h = 0.5 * n.size;
            for (dx, dy) in [(0.0, 0.0), (h, 0.0), (0.0, h), (h, h)] {
                let (x, y) = (n.x + dx, n.y + dy);
                rects.push((
                    Rect::square(f64::from(x), f64::from(y), f64::from(h)),
                    x,
                    y,
                    h,
                    n.depth + 1,
                ));
            }
        }
        let evals = ctx.evaluate_all(rects.iter().map(|r| r.0).zip(inherited).collect());
        for ((_, x, y, s, depth), (e, cells)) in rects.into_iter().zip(evals) {
            pending.push(cells);
            self.nodes.push(Node {
                x,
                y,
                size: s,
                depth,
                first_child: LEAF,
                v1: e.v1,
                bound: e.bound,
                proposal: e.proposal,
            });
        }
        (first_new..self.nodes.len() as u32).collect()
    }

    /// SPEC §3's target mode: split, in batches, the live leaves with the largest reducible
    /// wasted volume (box/safety − v1: the safety factor's share cannot be split away) until E\[T\] ≤ target, the budget is spent, or no leaf can split.
    fn refine_to_target<B: Brdf + ?Sized>(
        &mut self,
        ctx: &Context<'_, B>,
        target: f64,
        pending: &mut Vec<Option<Cell>>,
    ) {
        #[derive(PartialEq)]
        struct Waste(f64, u32);
        impl Eq for Waste {}
        impl PartialOrd for Waste {
            fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
                Some(self.cmp(o))
            }
        }
        impl Ord for Waste {
            // Largest waste first; ties by lower index, so the order is total and fixed.
            fn cmp(&self, o: &Self) -> Ordering {
                self.0.total_cmp(&o.0).then(o.1.cmp(&self.1))
            }
        }
        const BATCH: usize = 16;
        let cfg = ctx.config;
        let (mut boxes, mut v1s) = (0.0, 0.0);
        let mut heap = BinaryHeap::new();
        for (i, n) in self.nodes.iter().enumerate() {
            if n.is_leaf() && n.v1 > 0.0 {
                boxes += n.box_volume();
                v1s += n.v1;
                if n.depth < cfg.max_depth && n.reducible_waste(cfg.bound_safety) > 0.0 {
                    heap.push(Waste(n.reducible_waste(cfg.bound_safety), i as u32));
                }
            }
        }
        while v1s > 0.0 && boxes / v1s > target {
            let mut batch = Vec::with_capacity(BATCH);
            while batch.len() < BATCH {
                match heap.pop() {
                    Some(Waste(_, i)) => batch.push(i),
                    None => break,
                }
            }
            if batch.is_empty() {
                break;
            }
            if self.nodes.len() + 4 * batch.len() > cfg.node_budget as usize
                || ctx.overspent(self.nodes.len())
            {
                self.budget_exhausted = true;
                break;
            }
            for &i in &batch {
                let n = &self.nodes[i as usize];
                boxes -= n.box_volume();
                v1s -= n.v1;
            }
            for c in self.split(ctx, &batch, pending) {
                let n = &self.nodes[c as usize];
                if n.v1 > 0.0 {
                    boxes += n.box_volume();
                    v1s += n.v1;
                    if n.depth < cfg.max_depth && n.reducible_waste(cfg.bound_safety) > 0.0 {
                        heap.push(Waste(n.reducible_waste(cfg.bound_safety), c));
                    }
                }
            }
        }
    }

    /// Sets every inner node's v1 to the sum of its children's (children follow parents).
    fn sum_up(&mut self) {
        for i in (0..self.nodes.len()).rev() {
            let c = self.nodes[i].first_child as usize;
            if c != LEAF as usize {
                self.nodes[i].v1 = (c..c + 4).map(|k| self.nodes[k].v1).sum();
            }
        }
    }

    /// The arena, root first.
    #[must_use]
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }

    /// The map the tree was built over.
    #[must_use]
    pub fn map(&self) -> DiskMap {
        self.map
    }

    /// The total volume V = Σ leaf v1 = ∫ f_r over the square (the root's v1).
    #[must_use]
    pub fn volume(&self) -> f64 {
        self.nodes[0].v1
    }

    /// Iterator over the leaves (index, node).
    pub fn leaves(&self) -> impl Iterator<Item = (usize, &Node)> + '_ {
        self.nodes.iter().enumerate().filter(|(_, n)| n.is_leaf())
    }

    /// The leaf whose square contains the square point `p` (ties to the upper child).
    #[must_use]
    pub fn leaf_at(&self, p: DVec2) -> usize {
        let mut i = 0;
        loop {
            let n = &self.nodes[i];
            if n.is_leaf() {
                return i;
            }
            i = n.first_child as usize + n.rect().quadrant_of(p);
        }
    }

    /// Counts: nodes, leaves, depths, bytes, E\[T\].
    #[must_use]
    pub fn stats(&self) -> TreeStats {
        let mut s = TreeStats {
            nodes: self.nodes.len(),
            bytes: self.nodes.len() * core::mem::size_of::<Node>(),
            budget_exhausted: self.budget_exhausted,
            ..TreeStats::default()
        };
        let (mut boxes, mut v1s) = (0.0, 0.0);
        for (_, n) in self.leaves() {
            s.leaves += 1;
            s.max_depth = s.max_depth.max(n.depth);
            let d = usize::from(n.depth);
            if s.depth_histogram.len() <= d {
                s.depth_histogram.resize(d + 1, 0);
            }
            s.depth_histogram[d] += 1;
            if n.v1 > 0.0 {
                s.live_leaves += 1;
                boxes += n.box_volume();
                v1s += n.v1;
            }
        }
        s.expected_trials = if v1s > 0.0 { boxes / v1s } else { 0.0 };
        s
    }
}

/// The square-measure density constant: f·cos/pdf = V / J, with J the map's square area per
/// unit projected solid angle.
#[must_use]
pub fn albedo_of_volume(map: DiskMap, volume: f64) -> f64 {
    volume / f64::from(map.square_area_per_projected_solid_angle())
}
