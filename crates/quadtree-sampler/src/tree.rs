//! The arena quadtree (seed §2.1, Fig. 1–2): nodes, the split (`particionar`) and the
//! target-trials refinement.

use crate::chart::{Chart, Rect, child_column, child_row};
use crate::config::BuildConfig;
use crate::error::BuildError;
use crate::evaluate::{Context, Evaluation, Integrated, SPLIT_CHUNK};
use crate::integrate::Cell;
use crate::proposal::Proposal;
use alloc::collections::BinaryHeap;
use alloc::vec::Vec;
use brdf_core::{Brdf, DiskMap};
use core::cmp::{Ordering, Reverse};
use core::sync::atomic::{AtomicU64, AtomicUsize, Ordering as AtomicOrdering};
use glam::{DVec2, Vec3};

/// No child: the node is a leaf.
pub const LEAF: u32 = 0;

/// One node of the arena: the seed's `Nodo` with its `Region`.
///
/// The square is the dyadic cell (`column`, `row`) at `depth` of the seed's domain
/// ([`Node::rect`]); `v1` = ∫ f_r over it (square
/// measure), `bound` (M) an upper bound of the proposal's height function over the proposal
/// box, and P = v1 / (box area · M). Children are four contiguous nodes from `first_child`,
/// in the child order of [`crate::chart::child_index`]: (−,−), (+,−), (−,+), (+,+).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    /// Column of the node's square among the 2^depth of its depth (0: at u = −1).
    pub column: u32,
    /// Row of the node's square among the 2^depth of its depth (0: at v = −1).
    pub row: u32,
    /// Depth (root = 0).
    pub depth: u8,
    /// Index of the first of four children, or [`LEAF`].
    pub first_child: u32,
    /// v1: ∫ f_r over the square (f64). For an inner node, the sum of its children's.
    pub v1: f64,
    /// M: the height bound of the rejection test in this node's proposal chart, over the
    /// proposal's shape (f·Jacobian ≤ M·S there; S ≡ 1 for a flat box).
    pub bound: f64,
    /// M of the flat box in the same chart (the seed's P judges the node by it; equal to
    /// `bound` when the proposal is flat).
    pub box_bound: f64,
    /// The rejection proposal of this node (used when it is a leaf).
    pub proposal: Proposal,
}

impl Node {
    /// The node's square, exact ([`Rect::dyadic`]).
    #[inline]
    #[must_use]
    pub fn rect(&self) -> Rect {
        Rect::dyadic(self.depth, self.column, self.row)
    }

    /// Whether the node has no children.
    #[must_use]
    pub fn is_leaf(&self) -> bool {
        self.first_child == LEAF
    }

    /// The volume of the rejection box: proposal area × M × the shape's mean (s²·M for the
    /// seed's flat square).
    #[must_use]
    pub fn box_volume(&self) -> f64 {
        self.proposal.volume(self.bound)
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

    /// The box volume the seed's splitting rule judges the node by: the flat box's (area ×
    /// `box_bound`), except that a polar box counts as the square it stands in for (the same
    /// points, its bound over the chart's Jacobian: [`Chart::Polar`]). A height shape or the
    /// polar box changes how a leaf is sampled, not which nodes the rule splits, so a tree
    /// keeps the shape — and the warp its proxy — it has with the flat square; target mode,
    /// which asks for an E\[T\], counts the volume sampling uses.
    fn seed_box_volume(&self, map: DiskMap) -> f64 {
        if self.proposal.chart == Chart::Polar {
            self.rect().area() * self.box_bound / crate::chart::polar_jacobian(map)
        } else {
            self.proposal.area() * self.box_bound
        }
    }

    /// The seed's rule (`particionar`), with the waste cut-off's scale `total` (the leaves'
    /// total v1): split while the node may go deeper, holds something, has P below the
    /// threshold and wastes more than the cut-off. v1 = 0 with M > 0 counts as holding
    /// something: the bound search met f > 0 where every integration point saw 0 (a lobe
    /// narrower than the rule's spacing, at grazing incidence the whole of f_r), so the
    /// node's integration is too coarse, and its children's finer rules find the mass.
    /// (P and the waste are judged by the box the rule judges by, `seed_box_volume`.)
    fn seed_rule_splits(&self, cfg: &BuildConfig, total: f64) -> bool {
        let seed_box = self.seed_box_volume(cfg.map);
        let p = if seed_box > 0.0 {
            self.v1 / seed_box
        } else {
            0.0
        };
        self.depth < cfg.max_depth
            && (self.v1 > 0.0 || self.bound > 0.0)
            && p < cfg.split_threshold
            && seed_box / cfg.bound_safety - self.v1 > cfg.min_relative_waste * total
    }

    /// The leaf of the dyadic cell (depth, column, row) with evaluation `e`.
    pub(crate) fn leaf((depth, column, row): (u8, u32, u32), e: &Evaluation) -> Self {
        Self {
            column,
            row,
            depth,
            first_child: LEAF,
            v1: e.v1,
            bound: e.bound,
            box_bound: e.box_bound,
            proposal: e.proposal,
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
    /// Bytes of the nodes, in the layout the counts were taken from: 88 per node in the
    /// build's [`Quadtree`], 16 in the sampling layout ([`crate::PackedTree`]).
    pub bytes: usize,
    /// E\[T\] = Σ box volumes / Σ v1 over live leaves: expected rejection trials per sample.
    pub expected_trials: f64,
    /// Whether a budget (nodes, or f_r evaluations) stopped a split. A target E\[T\] can
    /// also be missed with this false, where no leaf is left that can split (every live
    /// leaf at the depth limit): compare `expected_trials` with the target.
    pub budget_exhausted: bool,
}

impl TreeStats {
    /// Counts the leaves — (depth, live, box volume, v1), in node order — into `leaves`,
    /// `live_leaves`, `max_depth`, `depth_histogram` and E\[T\] = Σ box / Σ v1 over the live
    /// ones: the one tally behind the build's statistics and the packed tree's.
    pub(crate) fn count_leaves(&mut self, leaves: impl Iterator<Item = (u8, bool, f64, f64)>) {
        let (mut boxes, mut v1s) = (0.0, 0.0);
        for (depth, live, box_volume, v1) in leaves {
            self.leaves += 1;
            self.max_depth = self.max_depth.max(depth);
            let d = usize::from(depth);
            if self.depth_histogram.len() <= d {
                self.depth_histogram.resize(d + 1, 0);
            }
            self.depth_histogram[d] += 1;
            if live {
                self.live_leaves += 1;
                boxes += box_volume;
                v1s += v1;
            }
        }
        self.expected_trials = if v1s > 0.0 { boxes / v1s } else { 0.0 };
    }
}

/// An f64 ordered totally ([`f64::total_cmp`]), for the build's and the pruning's heaps:
/// keys are finite there, so this is their numeric order.
#[derive(Clone, Copy, Debug)]
pub(crate) struct HeapKey(pub(crate) f64);

impl PartialEq for HeapKey {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}

impl Eq for HeapKey {}

impl PartialOrd for HeapKey {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl Ord for HeapKey {
    fn cmp(&self, o: &Self) -> Ordering {
        self.0.total_cmp(&o.0)
    }
}

/// The seed's `Quadtree` over the square for one incident direction: an arena of nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct Quadtree {
    nodes: Vec<Node>,
    map: DiskMap,
    budget_exhausted: bool,
    integration_tolerance: f64,
}

/// The relative tolerance a build that ran out of its evaluation budget is built again to
/// (see [`Quadtree::new`]). On an integrand that is not smooth at any scale — a table read by
/// nearest bin, Schlick's azimuthal factor at p = 0.001 around the mirror direction — a
/// tolerance of 10⁻⁶ can spend a whole budget on a few dozen nodes while 10⁻⁴ builds the
/// complete tree in a tenth of a second: at r = p = 0.001, wi = (0.7, 0.7, 0.1), 10⁻⁶
/// stopped after 3.6 s with E\[T\] 2.91, 10⁻⁴ completed in 0.18 s with E\[T\] 1.48, and their
/// total volumes agree to 3·10⁻⁶.
pub const RETRY_TOLERANCE: f64 = 1e-4;

/// The tolerance a build is built to when [`RETRY_TOLERANCE`] ran out of its evaluation
/// budget too (or the build asked for that much already): the last retry. A measured table
/// (`merl`, nearest lookup, integrated to 10⁻⁴) within 0.1° of the horizon stopped at its
/// budget, 61–93 nodes after 5.6 s, with E\[T\] 53–166 (over 64 an error, no sampler at
/// all); to 10⁻³ it builds completely, 1 569–7 529 nodes in 1.3–2.3 s. A leaf integral within
/// 10⁻³ leaves the pdf exact to about that, where the alternatives were a sampler dozens of
/// times slower or none.
pub const LAST_RETRY_TOLERANCE: f64 = 1e-3;

/// How near its target E\[T\] target mode counts as reaching it (relative): 10⁻⁶. Every
/// box holds at least the safety factor times its v1, so a target equal to the factor (the
/// least [`BuildConfig::validate`] allows) is reached only by trees whose bounds are all
/// tight, and then only up to the rounding of the stored volumes: Lambert's one node over
/// the concentric map has E\[T\] 1.020000080, and compared exactly with 1.02 it split to
/// the node budget (1 048 533 nodes, 12.6 s, E\[T\] no lower) where one node serves.
pub const TARGET_TOLERANCE: f64 = 1e-6;

/// How close to its floor (the least E\[T\] any number of splits could reach) a tree whose
/// target is out of reach is refined: within 2 %. Closing the rest cost Cook–Torrance
/// m = 0.001, kd = 1 at grazing incidence 10⁶ nodes and 50 s for 0.8 % of E\[T\].
pub const FLOOR_SLACK: f64 = 1.02;

/// The largest E\[T\] that reaches `target`: the target and [`TARGET_TOLERANCE`] of it. The
/// one test target mode stops on and a build's shortfall is reported by.
#[inline]
#[must_use]
pub fn target_limit(target: f64) -> f64 {
    target * (1.0 + TARGET_TOLERANCE)
}

/// What a leaf keeps for its split: nothing, its integration cells (its children start
/// from their quadrants), or its four children already evaluated — speculatively, by a
/// parallel build while the leaf's own level was being evaluated ([`Speculation`]).
pub(crate) enum Pending {
    /// Nothing kept: the children integrate from scratch.
    Nothing,
    /// The leaf's integration cells.
    Cells(Cell),
    /// The four children, in child order, each with what it keeps and what it spent.
    Children(Vec<Evaluated>),
}

impl Pending {
    fn from_cells(cells: Option<Cell>) -> Self {
        cells.map_or(Self::Nothing, Self::Cells)
    }
}

/// A node's evaluation, what it keeps for its own split, and the f_r evaluations it spent
/// (counted when the build adopts it).
pub(crate) struct Evaluated {
    e: Evaluation,
    pending: Pending,
    spent: u64,
}

/// A parallel build's look-ahead: a node whose evaluation shows it will almost surely split
/// evaluates its four children at once, in the same parallel pass, instead of waiting for its
/// level to end. Each node's evaluation is a pure function of its square (and the memoised
/// cells only save work), so the tree is the same bit for bit: the breadth-first pass still
/// decides every split in index order and adopts a speculated child's evaluation, and its
/// spend, only where it splits. What speculation buys is overlap: the children of a level's
/// early finishers fill the time its slowest node would leave a thread idle at the level's
/// end. Serial builds never speculate.
struct Speculation {
    /// The total v1 of the leaves when the pass began: the waste cut-off's scale, unless
    /// [`Speculation::seen`] is larger.
    total: f64,
    /// The largest v1 of any node evaluated in this build so far (the bits of a
    /// non-negative f64, whose order as integers is its order as numbers): a lower bound on
    /// the total that the pass's own `total` can lag far behind. Where the root's points all
    /// miss a needle (HTSG σ0 = 0.05, τ = 100 at θi = 0°: its lobe, 0.2° wide, sits on the
    /// root's centre, a dyadic corner no rule point touches), the first level's total is the
    /// context's estimate, 10⁻³⁷, and a cut-off scaled by it let the root's look-ahead
    /// evaluate every node down the lobe's flanks whose P < ½, however little it held:
    /// 23 949 node evaluations for a tree of 517 (5.4 s on two threads against 0.58 s on
    /// one). Its quadrants' v1, 0.17, sets the scale as soon as they are known.
    seen: AtomicU64,
    /// Nodes speculated so far, against [`Speculation::limit`] (a race on it only changes
    /// how much is speculated).
    made: AtomicUsize,
    limit: usize,
    /// f_r evaluations reserved for speculated nodes (four times their parent's spend
    /// each): see [`Speculation::affords`].
    spent: AtomicU64,
}

impl Speculation {
    /// Whether the node of dyadic `cell` with evaluation `e` (which spent `spent`) is worth
    /// evaluating the children of now: it holds mass and the seed's rule would split it even
    /// against twice the waste cut-off (the breadth-first pass judges against the total of
    /// its own time, which refinement moves a little), and the speculation budgets allow
    /// four more nodes.
    fn wants<B: Brdf + ?Sized>(
        &self,
        ctx: &Context<'_, B>,
        cell: (u8, u32, u32),
        e: &Evaluation,
        spent: u64,
    ) -> bool {
        e.v1 > 0.0
            && Node::leaf(cell, e).seed_rule_splits(&ctx.config, 2.0 * self.scale_with(e.v1))
            && self.reserve(ctx, spent)
    }

    /// Records a node's v1 > 0 in [`Speculation::seen`] and returns the waste cut-off's
    /// scale: the level's total or the largest v1 seen, whichever is larger.
    fn scale_with(&self, v1: f64) -> f64 {
        if v1.is_finite() {
            self.seen.fetch_max(v1.to_bits(), AtomicOrdering::Relaxed);
        }
        self.total
            .max(f64::from_bits(self.seen.load(AtomicOrdering::Relaxed)))
    }

    /// Whether the speculation budgets allow four more nodes, the children of a node that
    /// spent `spent` evaluations (reserving them when they do).
    fn reserve<B: Brdf + ?Sized>(&self, ctx: &Context<'_, B>, spent: u64) -> bool {
        self.affords(ctx, spent)
            && self.made.fetch_add(4, AtomicOrdering::Relaxed) + 4 <= self.limit
    }

    /// Whether four children of a node that spent `spent` evaluations fit the evaluation
    /// budget's first half with everything spent and speculated so far: the budget bounds a
    /// build's time, and work speculated past where it stops the build (a measured BRDF's
    /// bins keep every node's integration at full depth) would only be wasted. (A node's
    /// children inherit its cells, so four of them rarely cost four times its spend.)
    fn affords<B: Brdf + ?Sized>(&self, ctx: &Context<'_, B>, spent: u64) -> bool {
        let estimate = spent.saturating_mul(4);
        let reserved = self.spent.fetch_add(estimate, AtomicOrdering::Relaxed);
        ctx.spent
            .load(AtomicOrdering::Relaxed)
            .saturating_add(reserved)
            .saturating_add(estimate)
            <= ctx.config.evaluation_budget / 2
    }
}

/// The dyadic cells (depth, column, row) of a cell's four children, in child order.
fn children_of((depth, column, row): (u8, u32, u32)) -> [(u8, u32, u32); 4] {
    core::array::from_fn(|k| {
        (
            depth + 1,
            2 * column + child_column(k) as u32,
            2 * row + child_row(k) as u32,
        )
    })
}

/// Evaluates nodes given as (depth, column, row) with their inherited cells, in parallel
/// when the build is; with `speculation`, a node it wants evaluates its children too,
/// recursively.
fn evaluate_nodes<B: Brdf + ?Sized>(
    ctx: &Context<'_, B>,
    nodes: Vec<((u8, u32, u32), Option<Cell>)>,
    speculation: Option<&Speculation>,
) -> Vec<Evaluated> {
    let one = |((depth, column, row), cells): ((u8, u32, u32), Option<Cell>)| {
        let mut spent = 0;
        let (e, cells) = ctx.evaluate_counted(&Rect::dyadic(depth, column, row), cells, &mut spent);
        let pending = match (speculation, cells) {
            (Some(s), Some(cells)) if s.wants(ctx, (depth, column, row), &e, spent) => {
                let kids = children_of((depth, column, row)).into_iter();
                Pending::Children(evaluate_nodes(
                    ctx,
                    kids.zip(cells.into_quads()).collect(),
                    speculation,
                ))
            }
            (_, cells) => Pending::from_cells(ctx.remember(cells)),
        };
        Evaluated { e, pending, spent }
    };
    #[cfg(feature = "rayon")]
    if ctx.config.parallel {
        use rayon::prelude::*;
        return nodes.into_par_iter().map(one).collect();
    }
    nodes.into_iter().map(one).collect()
}

impl Quadtree {
    /// Builds the tree of f_r(wi, ·) for a local `wi` (normalised here; it must be finite,
    /// non-zero and above the horizon). Delta models are an error, and so is an f_r that is 0
    /// for this `wi` ([`BuildError::ZeroBrdf`]) or one the budget cannot bound to at most
    /// [`crate::MAX_USABLE_EXPECTED_TRIALS`] trials per sample ([`BuildError::Exhausted`]).
    /// The build's time is bounded by the node budget and its memory by the node budget and a
    /// fixed cache of integration cells (about 180 MiB). A build the evaluation budget
    /// stops is built again to [`RETRY_TOLERANCE`], then [`LAST_RETRY_TOLERANCE`] (each where
    /// it asked for less, while the budget still stops it), and the first complete tree is
    /// kept, or else the first attempt's result ([`Quadtree::integration_tolerance`] says
    /// which tolerance a tree has). This is the build's own layout, with everything each
    /// node's evaluation found; samplers use its [`crate::PackedTree`].
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
        // The tree, the tolerance it was integrated to, and whether the evaluation budget
        // stopped it (a complete tree, or another error, is never retried).
        let attempt = |config: BuildConfig| {
            let (ctx, cells) = Context::new(brdf, wi, config);
            let tree = Self::build(&ctx, cells);
            let stopped = ctx.ran_out.load(core::sync::atomic::Ordering::Relaxed)
                && matches!(tree, Ok(_) | Err(BuildError::Exhausted { .. }));
            (tree, ctx.tolerance(), stopped)
        };
        // A build the evaluation budget stopped is built again to each looser tolerance in
        // turn while the budget stops it, and the first complete tree kept; every other
        // build is the first attempt's.
        let run = || {
            let (first, mut tolerance, mut stopped) = attempt(config);
            for looser in [RETRY_TOLERANCE, LAST_RETRY_TOLERANCE] {
                if !stopped {
                    break;
                }
                if tolerance >= looser {
                    continue;
                }
                let (tree, t, s) = attempt(BuildConfig {
                    integration_tolerance: looser,
                    ..config
                });
                if let Ok(tree) = tree
                    && !tree.budget_exhausted
                {
                    return Ok(tree);
                }
                (tolerance, stopped) = (t, s);
            }
            first
        };
        // On a worker of the pool: every level's `par_iter` and every join below is then
        // forked from a worker (its own deque, which the other workers steal from), not
        // injected from outside and waited for on a latch — a caller's thread that is not
        // a worker would sleep and be woken at every level, a context switch each time.
        // Serial builds stay on the caller's thread.
        #[cfg(feature = "rayon")]
        if config.parallel {
            return rayon::scope(|_| run());
        }
        run()
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
        // Only where another thread can take the look-ahead's work: on one thread it would
        // only add the evaluations of nodes that do not split in the end.
        #[cfg(feature = "rayon")]
        let look_ahead = cfg.parallel && rayon::current_num_threads() > 1;
        #[cfg(not(feature = "rayon"))]
        let look_ahead = false;
        // Until the root's v1 is known, the waste cut-off's scale is the context's estimate
        // of it: speculation only judges what is worth evaluating early, and the
        // breadth-first pass decides every split with the true total.
        let mut speculation = Speculation {
            total: ctx.estimate,
            seen: AtomicU64::new(0),
            made: AtomicUsize::new(0),
            limit: budget / 4,
            spent: AtomicU64::new(0),
        };
        let (e, pending) = if look_ahead {
            Self::evaluate_root_ahead(ctx, &root_rect, root_cells, &speculation)
        } else {
            let (e, cells) = ctx.evaluate(&root_rect, Some(root_cells));
            (e, Pending::from_cells(ctx.remember(cells)))
        };
        // Each leaf's integration cells, until it splits and hands them to its children (or
        // the children the look-ahead evaluated).
        let mut pending = alloc::vec![pending];
        let mut tree = Self {
            nodes: alloc::vec![Node::leaf((0, 0, 0), &e)],
            map: cfg.map,
            budget_exhausted: false,
            integration_tolerance: ctx.tolerance(),
        };
        // Breadth-first: decide a level's splits serially (in index order), evaluate the new
        // children together (in parallel when enabled). Same tree either way.
        let mut frontier: Vec<u32> = alloc::vec![0];
        let mut total = e.v1;
        // Whether the node budget stopped the breadth-first pass.
        let mut cut_short = false;
        while !frontier.is_empty() {
            // Not below the context's estimate: where the root's integration missed a needle
            // (v1 = 0, split for its bound), the first level's total is 0, so its cut-off is
            // 0 and a speculation judged by it evaluated every node down the needle's
            // flanks whose P < ½, however little it held (f32 denormals): 79 564 nodes for
            // a tree of 381 (Phong n = 10⁵, θi = 45°), 2 s against 0.03 s serial. The pass
            // itself keeps its own total, so the tree is the same.
            speculation.total = total.max(ctx.estimate);
            let split: Vec<u32> = frontier
                .iter()
                .copied()
                .filter(|&i| tree.nodes[i as usize].seed_rule_splits(cfg, total))
                .collect();
            // A level that does not fit in the node budget is not split at all: the whole
            // budget left goes to the greedy refinement below, most wasteful leaves first,
            // where it lowers E[T] the most (splitting the level's first nodes in index
            // order spent it on whichever part of the square came first).
            if tree.nodes.len() + 4 * split.len() > budget {
                cut_short = true;
                break;
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
                let children =
                    tree.split(ctx, chunk, &mut pending, look_ahead.then_some(&speculation));
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
        // Where the node budget stopped the pass, the greedy refinement spends all of it
        // (aiming at E[T]'s floor, the bounds' safety factor), as near the seed's rule as
        // that many nodes get.
        let target = cfg.target_trials.map_or(1.0 / cfg.split_threshold, |t| {
            t.min(1.0 / cfg.split_threshold)
        });
        let target = if cut_short { cfg.bound_safety } else { target };
        tree.refine_to_target(ctx, target, &mut pending);
        tree.sum_up();
        ctx.speculated.store(
            speculation.made.load(AtomicOrdering::Relaxed),
            AtomicOrdering::Relaxed,
        );
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

    /// The root's evaluation in a parallel build: its integration, then its bound searches
    /// side by side with its four children's evaluations (from the root's cells, speculating
    /// further down), which the breadth-first pass adopts if the root splits. The root is a
    /// single node whose integration refines down the lobe one level after another and
    /// whose bound searches run one after another: the other threads would idle through all
    /// of it (0.55 of Schlick's 7.8 ms serial build); now only through its integration (0.37
    /// ms). The children need nothing of the root but its cells, so they are the same bits.
    /// The root's spend is counted at once, as [`Context::evaluate`] counts it; the
    /// children are reserved against the speculation budgets and their spend counted when
    /// adopted, as every speculated node's.
    fn evaluate_root_ahead<B: Brdf + ?Sized>(
        ctx: &Context<'_, B>,
        root: &Rect,
        cells: Cell,
        speculation: &Speculation,
    ) -> (Evaluation, Pending) {
        let mut spent = 0;
        let (v1, peak, cell) = match ctx.integrate_node(root, Some(cells), &mut spent) {
            Integrated::Inside { v1, peak, cell } => (v1, peak, cell),
            Integrated::Outside(e) => {
                ctx.spend(spent);
                return (e, Pending::Nothing);
            }
        };
        // (The root's spend so far is its integration's: the estimate `affords` judges by.)
        if !(v1 > 0.0 && speculation.reserve(ctx, spent)) {
            let e = ctx.bound_node(root, v1, &peak, &mut spent);
            ctx.spend(spent);
            return (e, Pending::from_cells(ctx.remember(Some(cell))));
        }
        let kids = children_of((0, 0, 0)).into_iter().zip(cell.into_quads());
        let (e, kids) = crate::integrate::join(
            true,
            || ctx.bound_node(root, v1, &peak, &mut spent),
            || evaluate_nodes(ctx, kids.collect(), Some(speculation)),
        );
        ctx.spend(spent);
        (e, Pending::Children(kids))
    }

    /// Splits the given leaves into four children each, evaluates the children (each from its
    /// quadrant of the parent's integration cells, or adopted from a speculation), and
    /// returns their indices. With `speculation`, a child that will almost surely split
    /// evaluates its own children in the same pass.
    fn split<B: Brdf + ?Sized>(
        &mut self,
        ctx: &Context<'_, B>,
        parents: &[u32],
        pending: &mut Vec<Pending>,
        speculation: Option<&Speculation>,
    ) -> Vec<u32> {
        // Each new node's cell: (depth, column, row), and its evaluation once known.
        let mut children = Vec::with_capacity(4 * parents.len());
        let mut evaluated: Vec<Option<Evaluated>> = Vec::with_capacity(4 * parents.len());
        // The children no speculation evaluated, with their inherited cells.
        let mut fresh = Vec::new();
        let first_new = self.nodes.len() as u32;
        for (k, &p) in parents.iter().enumerate() {
            let n = self.nodes[p as usize];
            self.nodes[p as usize].first_child = first_new + 4 * k as u32;
            let cells = children_of((n.depth, n.column, n.row));
            children.extend(cells);
            match core::mem::replace(&mut pending[p as usize], Pending::Nothing) {
                Pending::Children(kids) => evaluated.extend(kids.into_iter().map(Some)),
                kept => {
                    let quads = match kept {
                        Pending::Cells(c) => {
                            ctx.forget_cell(&c);
                            c.into_quads()
                        }
                        _ => [None, None, None, None],
                    };
                    evaluated.extend([None, None, None, None]);
                    fresh.extend(cells.into_iter().zip(quads));
                }
            }
        }
        let mut fresh = evaluate_nodes(ctx, fresh, speculation).into_iter();
        for ((depth, column, row), slot) in children.into_iter().zip(evaluated) {
            let Evaluated {
                e,
                pending: kept,
                spent,
            } = slot.unwrap_or_else(|| fresh.next().expect("one evaluation a fresh child"));
            ctx.spend(spent);
            pending.push(kept);
            self.nodes.push(Node::leaf((depth, column, row), &e));
        }
        (first_new..self.nodes.len() as u32).collect()
    }

    /// SPEC §3's target mode: split, in batches, the live leaves with the largest reducible
    /// wasted volume (box/safety − v1: the safety factor's share cannot be split away) until
    /// E\[T\] ≤ [`target_limit`] of the target (where no splitting can reach that, within
    /// [`FLOOR_SLACK`] of the least E\[T\] splitting can), the budget is spent, or no leaf
    /// can split. A
    /// batch holds no more leaves than the excess volume needs (their wastes × safety,
    /// summed): split before the last, they cannot have brought E\[T\] to the target (up to
    /// the children's v1 moving within the integration tolerance), so a batch evaluates in
    /// parallel yet never splits past it. (Where no child's waste exceeds a leaf later in its batch, the tree is the
    /// one-leaf-at-a-time greedy's.)
    fn refine_to_target<B: Brdf + ?Sized>(
        &mut self,
        ctx: &Context<'_, B>,
        target: f64,
        pending: &mut Vec<Pending>,
    ) {
        // Largest waste first; ties by lower index, so the order is total and fixed.
        type Waste = (HeapKey, Reverse<u32>);
        const BATCH: usize = 16;
        let cfg = ctx.config;
        /// The live leaves' box volumes and v1, and `floor`: each counted at the least box
        /// splitting can leave it (see the loop below).
        #[derive(Clone, Copy, Default)]
        struct Sums {
            boxes: f64,
            v1s: f64,
            floor: f64,
        }
        impl Sums {
            /// A live leaf in: into the heap too if it may still split.
            fn admit(&mut self, n: &Node, i: u32, cfg: &BuildConfig, heap: &mut BinaryHeap<Waste>) {
                self.boxes += n.box_volume();
                self.v1s += n.v1;
                let waste = n.reducible_waste(cfg.bound_safety);
                if n.depth < cfg.max_depth && waste > 0.0 {
                    heap.push((HeapKey(waste), Reverse(i)));
                    self.floor += cfg.bound_safety * n.v1;
                } else {
                    self.floor += n.box_volume();
                }
            }

            /// A leaf taken from the heap to split out.
            fn remove(&mut self, n: &Node, safety: f64) {
                self.boxes -= n.box_volume();
                self.v1s -= n.v1;
                self.floor -= safety * n.v1;
            }
        }
        let mut sums = Sums::default();
        let mut heap = BinaryHeap::new();
        for (i, n) in self.nodes.iter().enumerate() {
            if n.is_leaf() && n.v1 > 0.0 {
                sums.admit(n, i as u32, &cfg, &mut heap);
            }
        }
        let target = target_limit(target);
        while sums.v1s > 0.0 {
            // `floor` is the least box volume splitting can reach: each leaf that may still
            // split at safety × its v1 (its children's boxes can do no better), the others
            // at their boxes. Where that is over the target, no number of splits reaches it
            // (leaves at the depth limit on a needle lobe, beside a diffuse part that keeps
            // offering leaves with a little waste each): the goal is then the floor's E[T]
            // plus FLOOR_SLACK. (Cook–Torrance m = 0.001, kd = 1 at cos θi = 10⁻⁴ had E[T]
            // 3.059 after the breadth-first pass over a floor of 3.033, and then split its
            // leaves until the node budget, 10⁶ nodes and 50 s later, to reach 3.033.)
            let Sums { boxes, v1s, floor } = sums;
            let goal = if floor > target * v1s {
                FLOOR_SLACK * floor / v1s
            } else {
                target
            };
            if boxes <= goal * v1s {
                break;
            }
            // A split removes at most safety × its leaf's reducible waste (each child's box
            // is at least safety × its v1): take leaves until that reaches the excess volume
            // (at most BATCH). Far from the goal that is a full batch to evaluate in
            // parallel; near it, no split past the goal.
            let excess = boxes - goal * v1s;
            // As many splits as the node budget still has room for (a batch cut short by
            // it spends the budget to its last four nodes).
            let room = (cfg.node_budget as usize).saturating_sub(self.nodes.len()) / 4;
            if room == 0 || ctx.overspent(self.nodes.len()) {
                self.budget_exhausted = true;
                break;
            }
            let (mut batch, mut removable) = (Vec::with_capacity(BATCH), 0.0);
            while batch.len() < BATCH.min(room) && removable < excess {
                match heap.pop() {
                    Some((HeapKey(w), Reverse(i))) => {
                        batch.push(i);
                        removable += w * cfg.bound_safety;
                    }
                    None => break,
                }
            }
            if batch.is_empty() {
                break;
            }
            for &i in &batch {
                sums.remove(&self.nodes[i as usize], cfg.bound_safety);
            }
            for c in self.split(ctx, &batch, pending, None) {
                let n = &self.nodes[c as usize];
                if n.v1 > 0.0 {
                    sums.admit(n, c, &cfg, &mut heap);
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

    /// Every collapse pruning makes, cheapest first, down to the root alone (what a bake over
    /// its memory limit takes its trees' nodes back with, instead of building them again
    /// with a smaller budget, which costs nearly the whole build again: most of a needle
    /// lobe's build is its first levels): the inner node
    /// whose four children are all leaves (a twig) and whose own box adds the least live
    /// box volume to the leaves' (ties by lower index, so the order is fixed), with that
    /// added volume (E\[T\] grows by it over the tree's volume, which collapsing keeps: a
    /// collapsed node's v1 is its children's sum). Collapsing a twig can make its parent
    /// one, so the added volumes need not rise along the order. Any prefix of it, given to
    /// [`Quadtree::collapse`], is a pruned tree.
    pub(crate) fn collapse_order(&self) -> Vec<(u32, f64)> {
        let nodes = &self.nodes;
        let n = nodes.len();
        let live_box = |node: &Node| {
            if node.v1 > 0.0 {
                node.box_volume()
            } else {
                0.0
            }
        };
        let mut parent = alloc::vec![u32::MAX; n];
        for (i, node) in nodes.iter().enumerate() {
            if !node.is_leaf() {
                let c = node.first_child as usize;
                parent[c..c + 4].fill(i as u32);
            }
        }
        // Whether each node is a leaf as the collapses so far leave it.
        let mut leaf: Vec<bool> = nodes.iter().map(Node::is_leaf).collect();
        // (added box volume, index), smallest first.
        type Twig = Reverse<(HeapKey, u32)>;
        let twig = |leaf: &[bool], i: usize| {
            let c = nodes[i].first_child as usize;
            (!leaf[i] && leaf[c..c + 4].iter().all(|&l| l)).then(|| {
                let children: f64 = nodes[c..c + 4].iter().map(live_box).sum();
                Reverse((HeapKey(live_box(&nodes[i]) - children), i as u32))
            })
        };
        let mut heap: BinaryHeap<Twig> = (0..n).filter_map(|i| twig(&leaf, i)).collect();
        let mut order = Vec::with_capacity(n / 4);
        while let Some(Reverse((HeapKey(added), i))) = heap.pop() {
            order.push((i, added));
            let i = i as usize;
            leaf[i] = true;
            if let Some(p) = parent.get(i).copied().filter(|&p| p != u32::MAX)
                && let Some(t) = twig(&leaf, p as usize)
            {
                heap.push(t);
            }
        }
        order
    }

    /// Collapses the twigs of `steps`, a prefix of [`Quadtree::collapse_order`], into leaves
    /// (each keeps the proposal and bound its own evaluation found, its v1 the sum of its
    /// children's: exact, with more trials) and compacts the arena. Marks the tree
    /// [`Quadtree::budget_exhausted`] where it removed anything; returns whether it did.
    pub(crate) fn collapse(&mut self, steps: &[(u32, f64)]) -> bool {
        if steps.is_empty() {
            return false;
        }
        let n = self.nodes.len();
        let mut removed = alloc::vec![false; n];
        for &(i, _) in steps {
            let i = i as usize;
            let c = self.nodes[i].first_child as usize;
            removed[c..c + 4].fill(true);
            self.nodes[i].first_child = LEAF;
        }
        // Compact: the kept nodes in their order (a collapsed node's four children went
        // together, so every kept group of four stays contiguous, after its parent).
        let mut index = alloc::vec![u32::MAX; n];
        let mut next = 0u32;
        for i in 0..n {
            if !removed[i] {
                index[i] = next;
                next += 1;
            }
        }
        let mut kept = Vec::with_capacity(next as usize);
        for (i, node) in self.nodes.iter().enumerate() {
            if !removed[i] {
                let mut node = *node;
                if !node.is_leaf() {
                    node.first_child = index[node.first_child as usize];
                }
                kept.push(node);
            }
        }
        self.nodes = kept;
        self.budget_exhausted = true;
        true
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

    /// Whether the node budget stopped a split.
    #[must_use]
    pub fn budget_exhausted(&self) -> bool {
        self.budget_exhausted
    }

    /// The relative tolerance its nodes were integrated to: the configuration's, a model's
    /// looser one ([`brdf_core::Brdf::integration_tolerance`]), or [`RETRY_TOLERANCE`] or
    /// [`LAST_RETRY_TOLERANCE`] where the evaluation budget stopped a build to a tighter one
    /// and a retry completed.
    #[must_use]
    pub fn integration_tolerance(&self) -> f64 {
        self.integration_tolerance
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
        s.count_leaves(
            self.leaves()
                .map(|(_, n)| (n.depth, n.v1 > 0.0, n.box_volume(), n.v1)),
        );
        s
    }
}

/// The square-measure density constant: f·cos/pdf = V / J, with J the map's square area per
/// unit projected solid angle.
#[must_use]
pub fn albedo_of_volume(map: DiskMap, volume: f64) -> f64 {
    volume / f64::from(map.square_area_per_projected_solid_angle())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The arena's node: the dyadic cell (8 bytes) instead of f32 corners and side (12)
    /// keeps it at 88 bytes with a fine height shape's nine levels (what `TreeStats::bytes`
    /// reports per node).
    #[test]
    fn a_build_node_is_88_bytes() {
        assert_eq!(core::mem::size_of::<Node>(), 88);
    }

    /// Pruning keeps a tree: at most the nodes asked for, children in groups of four after
    /// their parents, every node's box and bound its own, the live leaves' volume the same
    /// (to rounding); E[T] grows as nodes go, and the cheapest collapse goes first (the
    /// whole of one twig's box added, nothing else). Down to the root alone; a tree already
    /// small enough is untouched.
    #[test]
    fn pruning_keeps_a_valid_tree_and_grows_e_t_least_first() {
        // Collapses, in order, until at most `max_nodes` nodes are left (at least the root).
        let prune_to = |q: &mut Quadtree, max_nodes: usize| {
            let n = q.nodes().len();
            if n <= max_nodes.max(1) {
                return false;
            }
            let order = q.collapse_order();
            let steps = (n - max_nodes.max(1)).div_ceil(4).min(order.len());
            q.collapse(&order[..steps])
        };
        let brdf = brdf_core::registry::create("phong", ["n=1000", "kd=0.1"]).unwrap();
        let wi = Vec3::new(0.6, 0.0, 0.8);
        let full = Quadtree::new(&*brdf, wi, BuildConfig::default()).unwrap();
        let n = full.nodes().len();
        assert!(n > 100, "{n}");
        let live = |q: &Quadtree| -> f64 {
            q.leaves()
                .filter(|(_, l)| l.v1 > 0.0)
                .map(|(_, l)| l.v1)
                .sum()
        };
        let mut untouched = full.clone();
        assert!(!prune_to(&mut untouched, n));
        assert_eq!(untouched, full);
        let mut last = full.stats().expected_trials;
        for keep in [n - 4, 3 * n / 4, n / 2, n / 4, 5, 1] {
            let mut q = full.clone();
            assert!(prune_to(&mut q, keep));
            let nodes = q.nodes();
            assert!(nodes.len() <= keep.max(1) && nodes.len() + 4 > keep.max(1));
            assert!(q.budget_exhausted());
            for (i, node) in nodes.iter().enumerate() {
                if node.is_leaf() {
                    continue;
                }
                let c = node.first_child as usize;
                assert!(c > i && c + 4 <= nodes.len());
                for (k, child) in nodes[c..c + 4].iter().enumerate() {
                    assert_eq!(child.depth, node.depth + 1);
                    assert_eq!(child.column, 2 * node.column + (k % 2) as u32);
                    assert_eq!(child.row, 2 * node.row + (k / 2) as u32);
                }
                // The same node as in the full tree (its own evaluation kept).
                assert!(
                    full.nodes()
                        .iter()
                        .any(|f| (f.depth, f.column, f.row, f.bound.to_bits())
                            == (node.depth, node.column, node.row, node.bound.to_bits()))
                );
            }
            assert!((live(&q) - live(&full)).abs() <= 1e-12 * live(&full));
            let e = q.stats().expected_trials;
            assert!(e >= last, "{keep}: E[T] {e} < {last}");
            last = e;
        }
        assert_eq!(
            {
                let mut q = full.clone();
                prune_to(&mut q, 1);
                q.nodes().len()
            },
            1
        );
        // One collapse: the twig whose box adds least, and nothing else moves.
        let mut one = full.clone();
        prune_to(&mut one, n - 4);
        let added = |q: &Quadtree| -> f64 {
            q.leaves()
                .filter(|(_, l)| l.v1 > 0.0)
                .map(|(_, l)| l.box_volume())
                .sum()
        };
        let least = full
            .nodes()
            .iter()
            .filter(|p| {
                !p.is_leaf() && {
                    let c = p.first_child as usize;
                    full.nodes()[c..c + 4].iter().all(Node::is_leaf)
                }
            })
            .map(|p| {
                let c = p.first_child as usize;
                let kids: f64 = full.nodes()[c..c + 4]
                    .iter()
                    .filter(|k| k.v1 > 0.0)
                    .map(Node::box_volume)
                    .sum();
                (if p.v1 > 0.0 { p.box_volume() } else { 0.0 }) - kids
            })
            .fold(f64::INFINITY, f64::min);
        let grew = added(&one) - added(&full);
        assert!(
            (grew - least).abs() <= 1e-12 * added(&full),
            "{grew} vs {least}"
        );
        // The order: a collapse per inner node, down to the root; any prefix of it is the
        // tree pruning leaves, its E[T] the full tree's grown by the prefix's added volumes
        // (what a bake's allocation across trees reckons with).
        let order = full.collapse_order();
        assert_eq!(order.len(), (n - 1) / 4);
        assert_eq!(order[0].1, least);
        let v = live(&full);
        for steps in [0, 1, order.len() / 3, order.len() - 1, order.len()] {
            let mut q = full.clone();
            assert_eq!(q.collapse(&order[..steps]), steps > 0);
            assert_eq!(q.nodes().len(), n - 4 * steps);
            let mut p = full.clone();
            prune_to(&mut p, n - 4 * steps);
            if steps > 0 {
                assert_eq!(q, p, "{steps}");
            }
            let grown: f64 = order[..steps].iter().map(|s| s.1).sum();
            let e = (added(&full) + grown) / v;
            let got = q.stats().expected_trials;
            assert!((e - got).abs() <= 1e-9 * got, "{steps}: {e} vs {got}");
        }
    }

    /// Lobes narrower than the root's integration points: Phong n = 10⁵ (a needle) and a
    /// Ward sheet (αx = 0.1, αy = 0.003) whose θi = 60°, φi = 22.5° line passes between
    /// every point of the root and of its quadrants. The adaptive estimate of the total
    /// was exactly 0 for both.
    fn missed_lobes() -> [(alloc::boxed::Box<dyn Brdf>, Vec3); 2] {
        let needle = brdf_core::registry::create("phong", ["n=100000", "kd=0"]).unwrap();
        let sheet =
            brdf_core::registry::create("ward", ["kd=0", "ks=1", "alpha_x=0.1", "alpha_y=0.003"])
                .unwrap();
        let (t, p) = (60f32.to_radians(), 22.5f32.to_radians());
        [
            (needle, Vec3::new(0.70710677, 0.0, 0.70710677)),
            (
                sheet,
                Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()),
            ),
        ]
    }

    /// A serial build's estimate of the total volume, its integration floor and the tree's
    /// volume.
    fn serial_estimate(brdf: &dyn Brdf, wi: Vec3, map: DiskMap) -> (f64, f64, f64) {
        let config = BuildConfig {
            map,
            parallel: false,
            ..BuildConfig::default()
        };
        let (ctx, cells) = Context::new(brdf, wi, config);
        let tree = Quadtree::build(&ctx, cells).unwrap();
        (ctx.estimate, ctx.tol_floor, tree.volume())
    }

    /// The scale of the integration's absolute floor is the tree's volume within 10 % even
    /// where the root's points miss the lobe (it was 0 there, and with it the floor: every
    /// node on the lobe's flanks was refined to 10⁻⁶ of its own tiny value, below the noise
    /// of f at f32 directions — 3× the evaluations for the needle, 10× the time for the
    /// sheet).
    #[test]
    fn a_lobe_the_roots_points_miss_still_sets_the_floor() {
        for (brdf, wi) in missed_lobes() {
            for map in [DiskMap::Orthographic, DiskMap::Concentric] {
                let (estimate, tol_floor, volume) = serial_estimate(&*brdf, wi, map);
                let ratio = estimate / volume;
                assert!(
                    (0.9..1.1).contains(&ratio),
                    "{} {map:?}: estimate {estimate:e}, volume {volume:e}",
                    brdf.name(),
                );
                let floor = tol_floor / volume;
                assert!(
                    (0.9e-8..1.1e-8).contains(&floor),
                    "{} {map:?}: floor {floor:e} of the volume",
                    brdf.name()
                );
            }
        }
    }

    /// Where neither the root's rule points nor the model's own sampler see the lobe (HTSG
    /// σ0 = 0.05, τ = 100, which has no sampler but cosine, whose 0.2° lobe sits on the root's
    /// centre at normal incidence and near the mirror elsewhere: both estimates were below
    /// 10⁻³⁶), the caps about its peak hints set the floor's scale within a factor of 4 of
    /// the tree's volume (it was 10⁻³⁷ of it, and with it no floor: the serial builds took
    /// 3–7× as long).
    #[test]
    fn the_hints_caps_see_a_lobe_every_sampler_misses() {
        let smooth = brdf_core::registry::create("htsg", ["sigma0=0.05", "tau=100"]).unwrap();
        for theta in [0.0f32, 30.0, 60.0] {
            let t = theta.to_radians();
            let wi = Vec3::new(t.sin(), 0.0, t.cos());
            let (estimate, _, volume) = serial_estimate(&*smooth, wi, DiskMap::Orthographic);
            let ratio = estimate / volume;
            assert!(
                (0.25..4.0).contains(&ratio),
                "θi {theta}°: estimate {estimate:e}, volume {volume:e}",
            );
        }
    }

    /// A parallel build speculates no more than a few nodes for each one it keeps, even
    /// where the root's integration missed the lobe and the first level's total was 0
    /// (speculation judged by that total took every node down the needle's flanks: 79 564
    /// for a tree of 381). Also where the model's own sampler misses the lobe too, so that
    /// the context's estimate of the total stays near 0: HTSG σ0 = 0.05, τ = 100 at normal
    /// incidence (cosine samples miss its 0.2° lobe; estimate 1.7·10⁻³⁷), where the root's
    /// look-ahead made 23 949 node evaluations for a tree of 517.
    #[cfg(feature = "rayon")]
    #[test]
    fn speculation_stays_near_the_tree() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let smooth = brdf_core::registry::create("htsg", ["sigma0=0.05", "tau=100"]).unwrap();
        let cases = missed_lobes().into_iter().chain([(smooth, Vec3::Z)]);
        for (brdf, wi) in cases {
            let (nodes, speculated) = pool.install(|| {
                rayon::scope(|_| {
                    let (ctx, cells) = Context::new(&*brdf, wi, BuildConfig::default());
                    let tree = Quadtree::build(&ctx, cells).unwrap();
                    (
                        tree.nodes.len(),
                        ctx.speculated.load(AtomicOrdering::Relaxed),
                    )
                })
            });
            assert!(
                speculated > 0,
                "{}: the build did not speculate",
                brdf.name()
            );
            assert!(
                speculated <= 2 * nodes,
                "{}: {speculated} nodes speculated for a tree of {nodes}",
                brdf.name()
            );
        }
    }
}
