//! The sampling layout of a quadtree: 16 bytes per node, one cache line holds four (and a
//! selection guide of at most 4 KiB).
//!
//! The build's [`Quadtree`] keeps everything a node's evaluation found, in f64 (88 bytes a
//! node). Sampling needs far less: at an inner node, which child to descend into; at a leaf,
//! its bound M and which chart its proposal uses. Everything else follows from the path:
//!
//! - a node's square is implicit: the root is [−1,1]², child k of a square takes its
//!   quadrant k ((−,−), (+,−), (−,+), (+,+)), computed exactly in f64 on the way down;
//! - a leaf's proposal box is a pure function of its square and its chart
//!   ([`Proposal::in_chart`]), with its height shape in the leaf's spare bits
//!   ([`crate::proposal::Shape`]): the square itself, or for a rim leaf (the only ones whose box
//!   is not their square) a box in angle or sine coordinates, which costs a handful of
//!   inverse sines to find — those are found once, when the tree is packed or read, and kept
//!   beside the nodes (32 bytes per rim leaf), so a sample never recomputes them (the polar
//!   box of the root or a root's child is constants: not stored);
//! - selection is an inverse-CDF lookup: the unit interval, in 2³¹ fixed-point units, is
//!   cut into one interval per leaf, of width ∝ its v1, in tree order; an inner node stores
//!   where its children 1, 2 and 3 start. One 31-bit uniform descends with three integer
//!   comparisons per level and no arithmetic on it at all (the seed's `seleccionarRegion`,
//!   which sums four v1 and rescales the uniform with a division at every level, is the same
//!   distribution up to rounding). It starts a few levels down: a guide holds, for each of
//!   2^g equal parts of the interval (g ≤ 8, and 2^g ≤ half the node count: 4 KiB a tree
//!   at most), the deepest node whose interval holds the whole part — where every x of that
//!   part goes anyway — and its cell, so the leaf and its square are the same either way.
//!
//! The cuts between leaves are their cumulative v1 shares rounded to whole units, with every
//! leaf of v1 > 0 kept at least one unit wide (nothing the tree covers becomes unreachable)
//! and every leaf of v1 = 0 none (never selected). A leaf's selection probability therefore
//! differs from v1/V by at most one unit, 2⁻³¹ ≈ 4.7·10⁻¹⁰ (more only right after a run of
//! leaves each holding less than a unit, which the minimum width pushes along): the total
//! variation distance from the exact selection is about 2⁻³¹ per leaf, 10⁻⁶ for two thousand
//! leaves, far under what any histogram test can see.

use crate::bound::round_up_f32 as round_up;
use crate::chart::{Chart, Rect, child_column, child_row};
use crate::proposal::{Prepared, Proposal, Shape};
use crate::tree::{Node, Quadtree, TreeStats};
use alloc::vec::Vec;
use brdf_core::DiskMap;

/// Marks a packed node as a leaf (its low bits then say the chart).
const LEAF_FLAG: u32 = 1 << 31;
/// Marks a leaf with v1 > 0 (in f64, as the build found it: a v1 under f32's smallest
/// subnormal still counts, since the selection gives such a leaf its unit).
const LIVE_FLAG: u32 = 1 << 30;
/// A leaf's low bits: its chart (0 square, 1 angle, 2 sine, 3 transposed angle, 4 polar).
const CHART_BITS: u32 = 7;
/// Where a leaf's height shape starts in its link ([`Shape::to_bits`]: 24 bits, 0 flat).
const SHAPE_SHIFT: u32 = 3;
/// The shape's 24 bits, in place.
const SHAPE_MASK: u32 = ((1 << 24) - 1) << SHAPE_SHIFT;
/// Fixed-point scale of the selection: probabilities are multiples of 1/`ONE`.
const ONE: u32 = 1 << 31;

/// One node of the sampling layout: 16 bytes.
///
/// Inner node: `link` is the index of the first of its four children (contiguous) and
/// `data` holds where children 1, 2 and 3 start in the fixed-point unit interval
/// (s₁ ≤ s₂ ≤ s₃ ≤ 2³¹; child 0 starts where its parent does, child 3 ends where it ends):
/// a uniform x ∈ [0, 2³¹) in the node's interval goes to child
/// k = [x ≥ s₁] + [x ≥ s₂] + [x ≥ s₃]. Leaf: `link` is `LEAF_FLAG` | `LIVE_FLAG` when
/// v1 > 0 | the height shape's 24 bits from bit 3 (0: flat) | chart, and `data` holds the
/// bits of M (f32, rounded up, so it still bounds), of
/// v1 (f32, for inspection only) and, for a rim leaf, its entry in the tree's table of
/// proposal boxes (0 in bake files, where the table is rebuilt on reading); for a square or
/// polar leaf, a fine height shape's further levels (`Shape::fine_bits`), or 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(16))]
pub struct PackedNode {
    link: u32,
    data: [u32; 3],
}

impl PackedNode {
    /// Whether the node is a leaf.
    #[inline]
    #[must_use]
    pub fn is_leaf(&self) -> bool {
        self.link & LEAF_FLAG != 0
    }

    /// Whether the node is a leaf holding part of the volume (v1 > 0): the leaves selection
    /// can reach (all of them are when the tree is empty, and none is live).
    #[inline]
    #[must_use]
    pub fn is_live_leaf(&self) -> bool {
        self.link & (LEAF_FLAG | LIVE_FLAG) == LEAF_FLAG | LIVE_FLAG
    }

    /// A leaf's bound M (the height of its rejection box), or `None` for an inner node.
    #[must_use]
    pub fn bound(&self) -> Option<f32> {
        self.is_leaf().then(|| f32::from_bits(self.data[0]))
    }

    /// A leaf's v1 (∫ f_r over its square), rounded to f32; `None` for an inner node.
    #[must_use]
    pub fn v1(&self) -> Option<f32> {
        self.is_leaf().then(|| f32::from_bits(self.data[1]))
    }

    /// A leaf's height shape (flat for an inner node; the bits were checked when the node
    /// was made or read). A fine shape's further levels are in the third data word, which
    /// only rim leaves (which take no shape) use otherwise.
    #[inline]
    fn shape(&self) -> Shape {
        if self.is_leaf() && !self.chart().needs_stored_box() {
            Shape::from_checked_bits((self.link & SHAPE_MASK) >> SHAPE_SHIFT, self.data[2])
        } else {
            Shape::FLAT
        }
    }

    /// The chart of a leaf's box, read from a table (a `match` compiled to a jump).
    #[inline]
    fn chart(&self) -> Chart {
        /// The chart of each value of the link's chart bits (4 and above: polar).
        const CHARTS: [Chart; 8] = [
            Chart::Square,
            Chart::Angle,
            Chart::Sine,
            Chart::AngleY,
            Chart::Polar,
            Chart::Polar,
            Chart::Polar,
            Chart::Polar,
        ];
        CHARTS[(self.link & CHART_BITS) as usize]
    }
}

/// Which leaf a uniform selected, with its square (exact, from the descent).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Selected {
    /// The leaf's index in [`PackedTree::nodes`] (the same index as in the build's arena).
    pub index: usize,
    /// The leaf's square.
    pub rect: Rect,
    /// Its depth (root = 0).
    pub depth: u8,
}

/// A node [`PackedTree::select`] starts from, with its cell (depth, column, row).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
struct SelectStart {
    node: u32,
    depth: u32,
    column: u32,
    row: u32,
}

impl SelectStart {
    /// The root, whose interval is all of [0, 2³¹).
    const ROOT: Self = Self {
        node: 0,
        depth: 0,
        column: 0,
        row: 0,
    };

    /// One step of the selection: from this (inner) node into its child `k`, whose first
    /// child is at `link`. The descent and its guide both step with it.
    #[inline(always)]
    fn enter(self, link: u32, k: usize) -> Self {
        Self {
            node: link + k as u32,
            depth: self.depth + 1,
            column: 2 * self.column + child_column(k) as u32,
            row: 2 * self.row + child_row(k) as u32,
        }
    }
}

/// Which child of inner node `n` holds fixed-point `x`: how many of its three cuts `x` is at
/// or past (branch-free). The descent and its guide both choose with it.
#[inline(always)]
fn child_holding(n: &PackedNode, x: u32) -> usize {
    usize::from(x >= n.data[0]) + usize::from(x >= n.data[1]) + usize::from(x >= n.data[2])
}

/// The most bits of the 31-bit uniform the selection's guide reads: 256 parts (4 KiB), and
/// never more parts than half the tree's nodes (the guide adds at most 8 bytes a node).
const GUIDE_BITS: u32 = 8;

/// The selection's guide for a checked tree (see [`PackedTree`]'s `guide`): for each part
/// [j, j + 1)·2^(31 − bits) of the fixed-point interval, the descent every x in it takes,
/// as far as they all take it.
fn select_guide(nodes: &[PackedNode]) -> (Vec<SelectStart>, u32) {
    let mut bits = 0;
    while bits < GUIDE_BITS && (4usize << bits) <= nodes.len() {
        bits += 1;
    }
    let width = ONE >> bits;
    let guide = (0..1u32 << bits)
        .map(|j| {
            let (first, last) = (j * width, j * width + (width - 1));
            let mut at = SelectStart::ROOT;
            loop {
                let n = &nodes[at.node as usize];
                if n.is_leaf() {
                    break at;
                }
                let k = child_holding(n, first);
                if child_holding(n, last) != k {
                    break at;
                }
                at = at.enter(n.link, k);
            }
        })
        .collect();
    (guide, bits)
}

/// One leaf of a [`PackedTree`] as inspection sees it (the viewer, exports, statistics):
/// everything sampling uses, read from the packed layout itself.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PackedLeaf {
    /// The leaf's index in [`PackedTree::nodes`].
    pub index: usize,
    /// Its square (exact, as the descent computes it).
    pub rect: Rect,
    /// Its depth (root = 0).
    pub depth: u8,
    /// Whether selection can reach it (v1 > 0 when packed).
    pub live: bool,
    /// v1 as stored (f32).
    pub v1: f64,
    /// M as sampled (f32, rounded up).
    pub bound: f64,
    /// The box rejection samples it in.
    pub proposal: Proposal,
    /// The exact probability that [`PackedTree::select`] returns it.
    pub probability: f64,
}

impl PackedLeaf {
    /// The rejection box's volume: proposal area × M × the shape's mean.
    #[must_use]
    pub fn box_volume(&self) -> f64 {
        self.proposal.volume(self.bound)
    }

    /// The seed's P = v1 / box volume: the acceptance probability of a trial in this leaf.
    #[must_use]
    pub fn acceptance(&self) -> f64 {
        let b = self.box_volume();
        if b > 0.0 { self.v1 / b } else { 0.0 }
    }
}

/// A quadtree in its sampling layout (see the module doc): 16 bytes per node, the same node
/// order as the [`Quadtree`] it was packed from.
#[derive(Clone, Debug, PartialEq)]
pub struct PackedTree {
    nodes: Vec<PackedNode>,
    /// Where [`PackedTree::select`] starts for each of the 2^`guide_bits` equal parts of the
    /// fixed-point unit interval: the deepest node whose interval holds the whole part, and
    /// its cell. Derived from the nodes.
    guide: Vec<SelectStart>,
    guide_bits: u32,
    /// The proposal boxes (lower and upper corners) of the rim leaves (angle and sine
    /// charts, which take no height shape), in tree order: 32 bytes each.
    rim: Vec<[glam::DVec2; 2]>,
    map: DiskMap,
    volume: f64,
    stats: TreeStats,
}

/// Every inner node's child starts (see [`PackedNode`]). The leaves, in tree order (child 0
/// first), cut [0, 2³¹) at their cumulative v1 share rounded to the nearest unit; each leaf
/// with v1 > 0 is kept at least one unit wide (and none other gets any).
fn child_starts(src: &[Node]) -> Vec<[u32; 3]> {
    let n = src.len();
    // Depth-first, child 0 first: the leaves of any subtree are contiguous; `first[i]` is
    // where node i's leaves begin in that order.
    let mut first = alloc::vec![0usize; n];
    let mut leaves = Vec::new();
    let mut stack = alloc::vec![0usize];
    while let Some(i) = stack.pop() {
        first[i] = leaves.len();
        if src[i].is_leaf() {
            leaves.push(i);
        } else {
            let c = src[i].first_child as usize;
            stack.extend([c + 3, c + 2, c + 1, c]);
        }
    }
    let live = |i: usize| src[i].v1 > 0.0;
    let volume: f64 = leaves
        .iter()
        .filter(|&&i| live(i))
        .map(|&i| src[i].v1)
        .sum();
    let one = u64::from(ONE);
    // cut[j] = where leaf j starts; cut[len] = 2³¹.
    let mut cut = alloc::vec![0u64; leaves.len() + 1];
    let mut cum = 0.0;
    for (j, &i) in leaves.iter().enumerate() {
        if live(i) {
            cum += src[i].v1;
        }
        let ideal = if volume > 0.0 {
            brdf_core::math::round((cum / volume) * one as f64) as u64
        } else {
            0
        };
        let min = cut[j] + u64::from(live(i));
        cut[j + 1] = if live(i) { ideal.max(min) } else { cut[j] };
    }
    // The last live leaf ends at 2³¹; pull back any cut the minimum widths pushed past it
    // (possible only after more than 2³¹ tiny leaves, i.e. never, but kept exact).
    let last = cut.len() - 1;
    cut[last] = one;
    for j in (1..last).rev() {
        let need = u64::from(live(leaves[j]));
        cut[j] = cut[j].min(cut[j + 1] - need.min(cut[j + 1]));
    }
    if let Some(j) = (0..leaves.len()).rev().find(|&j| live(leaves[j])) {
        for c in &mut cut[j + 1..] {
            *c = one;
        }
    } else {
        // An empty tree: every cut at the end, so the descent takes child 0 (never sampled).
        cut.iter_mut().for_each(|c| *c = one);
    }
    let to_u32 = |c: u64| u32::try_from(c.min(one)).unwrap_or(ONE);
    (0..n)
        .map(|i| {
            if src[i].is_leaf() {
                [ONE; 3]
            } else {
                let c = src[i].first_child as usize;
                [1, 2, 3].map(|k| to_u32(cut[first[c + k]]))
            }
        })
        .collect()
}

/// That each leaf's interval of the unit interval (`span`, from the stored cuts) is where
/// [`child_starts`] puts it: its start within 260 units (2⁻³¹ each) of the cumulative v1
/// share before it, computed here from the stored f32 v1 (whose rounding, 2⁻²⁴ of each
/// share, moves a cut by at most 256 units), plus what the minimum width of the tiny live
/// leaves before it may have pushed it along (1 − share for each leaf of share under one
/// unit); a live leaf at least one unit wide, a dead one none. The rejection-mode pdf is
/// f·cos/V: a cut moved further (a writer's bug under a valid checksum) would select the
/// leaves away from their volumes, samples no longer following the pdf reported for them.
/// `total` is the sum of the live leaves' f32 v1 (> 0).
fn check_cuts(raw: &[[u32; 4]], span: &[(u32, u32)], total: f64) -> Result<(), &'static str> {
    let one = f64::from(ONE);
    let (mut cum, mut pushed) = (0.0f64, 0.0f64);
    // Tree order, child 0 first: the leaves' intervals follow one another.
    let mut stack = alloc::vec![0usize];
    while let Some(i) = stack.pop() {
        let w = raw[i];
        if w[0] & LEAF_FLAG == 0 {
            let c = w[0] as usize;
            stack.extend([c + 3, c + 2, c + 1, c]);
            continue;
        }
        let (start, end) = span[i];
        let ideal = brdf_core::math::round(cum / total * one);
        if (f64::from(start) - ideal).abs() > 260.0 + pushed {
            return Err("a leaf whose selection interval is not its share of the volume");
        }
        if w[0] & LIVE_FLAG != 0 {
            let v1 = f64::from(f32::from_bits(w[2]));
            cum += v1;
            pushed += (1.0 - v1 / total * one).max(0.0);
            if end == start {
                return Err("a leaf with volume that selection cannot reach");
            }
        } else if end != start {
            return Err("a leaf without volume that selection can reach");
        }
    }
    Ok(())
}

impl PackedTree {
    /// Packs a built tree (same node order).
    #[must_use]
    pub fn new(tree: &Quadtree) -> Self {
        let src = tree.nodes();
        let starts = child_starts(src);
        let nodes = src
            .iter()
            .zip(starts)
            .map(|(n, starts)| {
                if n.is_leaf() {
                    let chart = match n.proposal.chart {
                        Chart::Square => 0,
                        Chart::Angle => 1,
                        Chart::Sine => 2,
                        Chart::AngleY => 3,
                        Chart::Polar => 4,
                    };
                    let live = if n.v1 > 0.0 { LIVE_FLAG } else { 0 };
                    let shape = n.proposal.shape.to_bits() << SHAPE_SHIFT;
                    PackedNode {
                        link: LEAF_FLAG | live | shape | chart,
                        data: [
                            round_up(n.bound).to_bits(),
                            (n.v1 as f32).to_bits(),
                            n.proposal.shape.fine_bits(),
                        ],
                    }
                } else {
                    PackedNode {
                        link: n.first_child,
                        data: starts,
                    }
                }
            })
            .collect::<Vec<_>>();
        let (guide, guide_bits) = select_guide(&nodes);
        let mut packed = Self {
            nodes,
            guide,
            guide_bits,
            rim: Vec::new(),
            map: tree.map(),
            volume: tree.volume(),
            stats: TreeStats::default(),
        };
        packed.index_rim();
        packed.stats = packed.count(tree.budget_exhausted());
        packed
    }

    /// Every node's square and depth, exactly (squares are dyadic: f64 holds them to any
    /// depth a tree may have), as the descent computes them ([`Rect::quadrants`], child k
    /// taking quadrant k).
    fn squares(&self) -> Vec<(Rect, u8)> {
        let mut out = alloc::vec![(Rect::square(-1.0, -1.0, 2.0), 0u8); self.nodes.len()];
        for (i, n) in self.nodes.iter().enumerate() {
            if n.is_leaf() {
                continue;
            }
            let (r, depth) = out[i];
            for (k, q) in r.quadrants().into_iter().enumerate() {
                out[n.link as usize + k] = (q, depth + 1);
            }
        }
        out
    }

    /// Finds every rim leaf's proposal box (exactly what [`Proposal::in_chart`] gives for
    /// its square, which the descent computes to the same bits) and points the leaf at it.
    fn index_rim(&mut self) {
        self.rim.clear();
        for (i, (rect, _)) in self.squares().into_iter().enumerate() {
            let n = self.nodes[i];
            if !n.is_leaf() {
                continue;
            }
            // (A square or polar leaf keeps its word: a fine shape's levels, or 0.)
            let chart = n.chart();
            if chart.needs_stored_box() {
                let b = Proposal::in_chart(&rect, chart);
                self.rim.push([b.lo, b.hi]);
                self.nodes[i].data[2] = (self.rim.len() - 1) as u32;
            }
        }
    }

    /// The statistics as sampled, from the packed layout itself: counts and depths of the
    /// leaves, the packed size, and E\[T\] with the f32 bounds and v1 of the live leaves.
    fn count(&self, budget_exhausted: bool) -> TreeStats {
        let mut s = TreeStats {
            nodes: self.nodes.len(),
            bytes: core::mem::size_of_val(self.nodes.as_slice())
                + core::mem::size_of_val(self.rim.as_slice())
                + core::mem::size_of_val(self.guide.as_slice()),
            budget_exhausted,
            ..TreeStats::default()
        };
        s.count_leaves(
            self.leaves()
                .into_iter()
                .map(|l| (l.depth, l.live, l.box_volume(), l.v1)),
        );
        s
    }

    /// Every leaf in node order, with its square, stored values, proposal and exact
    /// selection probability: inspection reads the sampling layout, it never unpacks it.
    #[must_use]
    pub fn leaves(&self) -> Vec<PackedLeaf> {
        let probabilities = self.selection_probabilities();
        self.squares()
            .into_iter()
            .enumerate()
            .filter(|&(i, _)| self.nodes[i].is_leaf())
            .map(|(index, (rect, depth))| {
                let n = self.nodes[index];
                let (proposal, _) = self.proposal(&Selected { index, rect, depth });
                PackedLeaf {
                    index,
                    rect,
                    depth,
                    live: n.is_live_leaf(),
                    v1: f64::from(f32::from_bits(n.data[1])),
                    bound: f64::from(f32::from_bits(n.data[0])),
                    proposal,
                    probability: probabilities[index],
                }
            })
            .collect()
    }

    /// The index of the leaf whose square holds the square point `p` (points on a split line
    /// go to the upper child, as in [`Quadtree::leaf_at`]).
    #[must_use]
    pub fn leaf_at(&self, p: glam::DVec2) -> usize {
        let (mut i, mut rect) = (0usize, Rect::square(-1.0, -1.0, 2.0));
        loop {
            let n = self.nodes[i];
            if n.is_leaf() {
                return i;
            }
            let k = rect.quadrant_of(p);
            rect = rect.quadrants()[k];
            i = n.link as usize + k;
        }
    }

    /// The nodes, root first.
    #[must_use]
    pub fn nodes(&self) -> &[PackedNode] {
        &self.nodes
    }

    /// The map the tree was built over.
    #[must_use]
    pub fn map(&self) -> DiskMap {
        self.map
    }

    /// V = ∫ f_r over the square (f64, from the build).
    #[must_use]
    pub fn volume(&self) -> f64 {
        self.volume
    }

    /// Counts, E\[T\] of the packed bounds, and the packed size in bytes.
    #[must_use]
    pub fn stats(&self) -> &TreeStats {
        &self.stats
    }

    /// `seleccionarRegion`: the leaf whose interval holds the uniform `u` ∈ [0, 1) (taken
    /// to 31 bits). Never returns a leaf with v1 = 0 unless the whole tree is empty.
    #[inline]
    #[must_use]
    pub fn select(&self, u: f64) -> Selected {
        self.select_fixed((u.clamp(0.0, 1.0) * f64::from(ONE)).min(f64::from(ONE - 1)) as u32)
    }

    /// [`PackedTree::select`] from a 31-bit uniform integer `x` ∈ [0, 2³¹) (higher bits are
    /// ignored).
    #[inline]
    #[must_use]
    pub fn select_fixed(&self, x: u32) -> Selected {
        let x = x & (ONE - 1);
        self.select_from(self.guide[(x >> (31 - self.guide_bits)) as usize], x)
    }

    /// The selection of `x` (< 2³¹) from `start`, a node whose interval holds it.
    #[inline(always)]
    fn select_from(&self, start: SelectStart, x: u32) -> Selected {
        let mut at = start;
        loop {
            let n = self.nodes[at.node as usize];
            if n.is_leaf() {
                let depth = at.depth as u8;
                return Selected {
                    index: at.node as usize,
                    rect: Rect::dyadic(depth, at.column, at.row),
                    depth,
                };
            }
            at = at.enter(n.link, child_holding(&n, x));
        }
    }

    /// Each node's probability of being passed through by [`PackedTree::select`] (for a
    /// leaf: of being selected), exactly as the fixed-point intervals give it.
    #[must_use]
    pub fn selection_probabilities(&self) -> Vec<f64> {
        let n = self.nodes.len();
        let (mut start, mut end) = (alloc::vec![0u32; n], alloc::vec![ONE; n]);
        for i in 0..n {
            let node = self.nodes[i];
            if node.is_leaf() {
                continue;
            }
            let c = node.link as usize;
            let cuts = [start[i], node.data[0], node.data[1], node.data[2], end[i]];
            start[c..c + 4].copy_from_slice(&cuts[..4]);
            end[c..c + 4].copy_from_slice(&cuts[1..]);
        }
        (0..n)
            .map(|i| f64::from(end[i] - start[i]) / f64::from(ONE))
            .collect()
    }

    /// The bound M of a selected leaf sampled in a flat polar box (0 for a leaf that holds
    /// nothing), `None` for every other leaf: the one proposal
    /// [`crate::sampler::rejection_in_leaf`] draws from without building it (its box is the
    /// node's part of the disk).
    #[inline(always)]
    pub(crate) fn flat_polar_bound(&self, leaf: &Selected) -> Option<f64> {
        let n = self.nodes[leaf.index];
        // (A polar leaf is flat when its shape bits are 0: `PackedNode::shape`.)
        (n.chart() == Chart::Polar && n.link & SHAPE_MASK == 0).then(|| {
            if n.is_live_leaf() {
                f64::from(f32::from_bits(n.data[0]))
            } else {
                0.0
            }
        })
    }

    /// A selected leaf's rejection proposal and bound M (0 for a leaf that holds nothing):
    /// the box and bound a rejection sample reads, with the height shape decoded for
    /// inspection.
    #[must_use]
    pub fn proposal(&self, leaf: &Selected) -> (Proposal, f64) {
        let (prop, m, _) = self.leaf_for_trials(leaf);
        let shape = self.nodes[leaf.index].shape();
        (Proposal { shape, ..prop }, m)
    }

    /// What a rejection sample needs of its selected leaf, straight from the packed words:
    /// the proposal box (its `shape` left flat), the bound M (0 for a leaf that holds
    /// nothing) and the height shape made ready for the trials (`None`: flat), without
    /// decoding the shape's control grid first (a test holds it to the decoded shape); a
    /// square leaf's box is its square, built here (a test holds it to
    /// [`Proposal::in_chart`]).
    #[inline(always)]
    pub(crate) fn leaf_for_trials(&self, leaf: &Selected) -> (Proposal, f64, Option<Prepared>) {
        let n = self.nodes[leaf.index];
        let chart = n.chart();
        let m = if n.is_live_leaf() {
            f64::from(f32::from_bits(n.data[0]))
        } else {
            0.0
        };
        if chart.needs_stored_box() {
            let [lo, hi] = self.rim[n.data[2] as usize];
            let prop = Proposal {
                chart,
                lo,
                hi,
                shape: Shape::FLAT,
            };
            return (prop, m, None);
        }
        let prop = if chart == Chart::Square {
            Proposal {
                chart,
                lo: leaf.rect.min,
                hi: leaf.rect.max,
                shape: Shape::FLAT,
            }
        } else {
            Proposal::in_chart(&leaf.rect, chart)
        };
        let bits = (n.link & SHAPE_MASK) >> SHAPE_SHIFT;
        (prop, m, Prepared::from_checked_bits(bits, n.data[2]))
    }

    /// The raw words of every node (`link`, then `data`), for serialisation.
    #[must_use]
    pub(crate) fn raw_nodes(&self) -> Vec<[u32; 4]> {
        self.nodes
            .iter()
            .map(|n| {
                // (A rim leaf's table entry is rebuilt on reading.)
                let rim = n.is_leaf() && n.chart().needs_stored_box();
                [
                    n.link,
                    n.data[0],
                    n.data[1],
                    if rim { 0 } else { n.data[2] },
                ]
            })
            .collect()
    }

    /// Rebuilds a packed tree from [`PackedTree::raw_nodes`], checking everything selection
    /// and sampling rely on, so that no input can make them index out of range, loop or
    /// return a negative or NaN bound: one root; every inner node's four children lie after
    /// it, inside the arena, and are nobody else's; child starts are ordered and within
    /// [0, 2³¹]; a leaf's chart is one of the four and fits the map; its bound is finite and
    /// ≥ 0; the depth stays within 30; `volume` is finite, ≥ 0, and the sum of the live
    /// leaves' v1 (to their f32 rounding).
    pub(crate) fn from_raw(
        raw: &[[u32; 4]],
        map: DiskMap,
        volume: f64,
        budget_exhausted: bool,
    ) -> Result<Self, &'static str> {
        if raw.is_empty() {
            return Err("a tree with no nodes");
        }
        if !(volume.is_finite() && volume >= 0.0) {
            return Err("a tree volume that is negative or not finite");
        }
        let n = raw.len();
        let mut parent_seen = alloc::vec![false; n];
        let mut depth = alloc::vec![0u8; n];
        // Each node's interval of the fixed-point unit interval (the root's is all of it).
        let mut span = alloc::vec![(0u32, ONE); n];
        for (i, w) in raw.iter().enumerate() {
            let link = w[0];
            if link & LEAF_FLAG != 0 {
                if link & CHART_BITS > 4
                    || link & !(LEAF_FLAG | LIVE_FLAG | SHAPE_MASK | CHART_BITS) != 0
                {
                    return Err("a leaf with an unknown chart");
                }
                // A rim leaf's third word is rebuilt (its table entry); a square or polar
                // leaf's is 0 or a fine shape's further levels.
                let fine = if matches!(link & CHART_BITS, 0 | 4) {
                    w[3]
                } else {
                    0
                };
                if Shape::from_bits((link & SHAPE_MASK) >> SHAPE_SHIFT, fine).is_none() {
                    return Err("a leaf with a height shape that no build writes");
                }
                let chart = link & CHART_BITS;
                // 0 square, 1 angle, 2 sine, 3 transposed angle, 4 polar.
                let fits = match map {
                    DiskMap::Orthographic => chart != 2,
                    DiskMap::Concentric => matches!(chart, 0 | 2 | 4),
                };
                if !fits {
                    return Err("a leaf whose chart does not belong to the tree's map");
                }
                // (Parents come first: the depth is known.)
                if chart == 4 && depth[i] > 1 {
                    return Err("a polar leaf below the root's children");
                }
                let m = f32::from_bits(w[1]);
                if !(m.is_finite() && m >= 0.0) {
                    return Err("a leaf bound that is negative or not finite");
                }
                let v1 = f32::from_bits(w[2]);
                if !(v1.is_finite() && v1 >= 0.0) {
                    return Err("a leaf v1 that is negative or not finite");
                }
            } else {
                let c = link as usize;
                if c <= i || c.checked_add(4).is_none_or(|e| e > n) {
                    return Err("an inner node whose children are out of order or range");
                }
                // The children's intervals cut the node's own, in order (parents come
                // first: the node's interval is known).
                let (start, end) = span[i];
                if !(start <= w[1] && w[1] <= w[2] && w[2] <= w[3] && w[3] <= end) {
                    return Err("an inner node whose child intervals are out of order");
                }
                let cuts = [start, w[1], w[2], w[3], end];
                for k in 0..4 {
                    span[c + k] = (cuts[k], cuts[k + 1]);
                }
                if depth[i] >= 30 {
                    return Err("a tree deeper than 30 levels");
                }
                for k in c..c + 4 {
                    if parent_seen[k] {
                        return Err("a node with two parents");
                    }
                    parent_seen[k] = true;
                    depth[k] = depth[i] + 1;
                }
            }
        }
        if parent_seen[0] || parent_seen[1..].iter().any(|&p| !p) {
            return Err("nodes that are not one tree");
        }
        // V is the f64 sum of the live leaves' v1, and each stored v1 is that v1 rounded to
        // f32 (relative 2⁻²⁴, or under 2⁻¹⁴⁹ where it is subnormal or 0): their sum
        // recovers V to 10⁻⁶ of it. A V that does not (a bit of it flipped by a writer the
        // checksum trusts) scales every rejection-mode pdf by the error: a V flushed to
        // 10⁻³⁰⁰ made the pdf infinite.
        let (mut sum, mut live) = (0.0f64, 0usize);
        for w in raw {
            if w[0] & (LEAF_FLAG | LIVE_FLAG) == LEAF_FLAG | LIVE_FLAG {
                sum += f64::from(f32::from_bits(w[2]));
                live += 1;
            }
        }
        let slack = 1e-6 * volume.max(sum) + live as f64 * 1.5e-45;
        if (live == 0) != (volume == 0.0) || (sum - volume).abs() > slack {
            return Err("a tree volume that is not the sum of its leaves' v1");
        }
        if sum > 0.0 {
            check_cuts(raw, &span, sum)?;
        }
        let nodes = raw
            .iter()
            .map(|w| PackedNode {
                link: w[0],
                data: [w[1], w[2], w[3]],
            })
            .collect::<Vec<_>>();
        let (guide, guide_bits) = select_guide(&nodes);
        let mut packed = Self {
            nodes,
            guide,
            guide_bits,
            rim: Vec::new(),
            map,
            volume,
            stats: TreeStats::default(),
        };
        packed.index_rim();
        packed.stats = packed.count(budget_exhausted);
        Ok(packed)
    }

    /// Multiplies every leaf bound by `factor` (negative controls only).
    pub(crate) fn scale_bounds(&mut self, factor: f64) {
        for n in &mut self.nodes {
            if n.is_leaf() {
                let m = f64::from(f32::from_bits(n.data[0])) * factor;
                n.data[0] = (m as f32).to_bits();
            }
        }
        self.stats = self.count(self.stats.budget_exhausted);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_packed_node_is_16_bytes() {
        assert_eq!(core::mem::size_of::<PackedNode>(), 16);
    }

    /// A constant f_r on the orthographic map is one leaf sampled in the polar chart; its
    /// layout reads back (on either map), a chart of the other map is refused, and the same
    /// leaf marked polar below the root's children (which no
    /// build makes: only the root and its children are sectors of the disk), or with a chart
    /// code past the polar one, is refused.
    #[test]
    fn polar_leaves_read_back_only_where_a_build_makes_them() {
        let lambert = brdf_core::models::Lambert::new(glam::Vec3::splat(0.5)).unwrap();
        let wi = glam::Vec3::new(0.0, 0.6, 0.8);
        let packed =
            PackedTree::new(&Quadtree::new(&lambert, wi, crate::BuildConfig::default()).unwrap());
        assert_eq!(packed.nodes.len(), 1);
        assert_eq!(packed.nodes[0].chart(), Chart::Polar);
        let raw = packed.raw_nodes();
        // (The trees made below repeat the leaf: each read with its leaves' sum as volume.)
        let read = |raw: &[[u32; 4]]| {
            let v = raw
                .iter()
                .filter(|w| w[0] & LEAF_FLAG != 0)
                .map(|w| f64::from(f32::from_bits(w[2])))
                .sum();
            PackedTree::from_raw(raw, DiskMap::Orthographic, v, false)
        };
        assert_eq!(read(&raw).unwrap().nodes, packed.nodes);
        // Polar leaves belong to both maps (the concentric root's is a sector too); the
        // angle chart only to the orthographic one, the sine chart only to the concentric.
        assert!(PackedTree::from_raw(&raw, DiskMap::Concentric, packed.volume, false).is_ok());
        for (code, map) in [(1, DiskMap::Concentric), (2, DiskMap::Orthographic)] {
            let other = [[
                (raw[0][0] & !CHART_BITS) | code,
                raw[0][1],
                raw[0][2],
                raw[0][3],
            ]];
            assert_eq!(
                PackedTree::from_raw(&other, map, packed.volume, false).err(),
                Some("a leaf whose chart does not belong to the tree's map")
            );
        }
        let mut bad = raw.clone();
        bad[0][0] = (bad[0][0] & !CHART_BITS) | 5;
        assert_eq!(read(&bad).err(), Some("a leaf with an unknown chart"));
        // The root split twice down its first child (whose interval is [0, 2²⁹)): polar
        // leaves at depth 1 pass, at 2 not.
        let leaf = raw[0];
        let mut deep = alloc::vec![
            [1, 1 << 29, 1 << 30, 3 << 29],
            [5, 1 << 27, 1 << 28, 3 << 27],
            leaf,
            leaf,
            leaf
        ];
        // (A quarter of the leaf's v1 each, so that the cuts are the volume's shares.)
        let quarter = (f32::from_bits(leaf[2]) / 4.0).to_bits();
        deep.extend([[leaf[0], leaf[1], quarter, leaf[3]]; 4]);
        assert!(read(&deep).is_err_and(|e| e == "a polar leaf below the root's children"));
        let square = [leaf[0] & !CHART_BITS, leaf[1], quarter, leaf[3]];
        deep[5..9].fill(square);
        assert!(read(&deep).is_ok());
        // A child's cuts outside its own interval (which would make its children's
        // intervals negative) are refused.
        deep[1] = [5, 1 << 29, 1 << 30, 3 << 29];
        assert_eq!(
            read(&deep).err(),
            Some("an inner node whose child intervals are out of order")
        );
    }

    /// What the trials read of a leaf straight from its words is what inspection decodes:
    /// the same shape made ready (`None` exactly for the flat box), and a square leaf's box
    /// built in place is [`Proposal::in_chart`]'s, on every leaf of trees that hold square
    /// leaves flat, coarse and fine, rim leaves and a polar one, on both maps.
    #[test]
    fn leaf_for_trials_is_the_leafs_proposal() {
        use brdf_core::models::{CookTorrance, Lambert, Phong, Ward};
        let grey = glam::Vec3::splat(0.5);
        let models: [(alloc::boxed::Box<dyn brdf_core::Brdf>, glam::Vec3); 4] = [
            (
                alloc::boxed::Box::new(
                    Phong::new(glam::Vec3::ZERO, glam::Vec3::ONE, 1000.0).unwrap(),
                ),
                glam::Vec3::new(0.6, 0.0, 0.8),
            ),
            (
                alloc::boxed::Box::new(CookTorrance::new(0.1, grey, grey).unwrap()),
                glam::Vec3::new(0.3, 0.5, 0.81),
            ),
            (
                alloc::boxed::Box::new(Ward::new(grey, grey, 0.05, 0.2).unwrap()),
                glam::Vec3::new(0.9, 0.1, 0.2),
            ),
            (
                alloc::boxed::Box::new(Lambert::new(grey).unwrap()),
                glam::Vec3::Z,
            ),
        ];
        let mut kinds = [0usize; 5];
        for (brdf, wi) in &models {
            for map in [DiskMap::Orthographic, DiskMap::Concentric] {
                let config = crate::BuildConfig {
                    map,
                    ..crate::BuildConfig::default()
                };
                let packed = PackedTree::new(&Quadtree::new(brdf, *wi, config).unwrap());
                for leaf in packed.leaves() {
                    let s = Selected {
                        index: leaf.index,
                        rect: leaf.rect,
                        depth: leaf.depth,
                    };
                    let (want, _) = packed.proposal(&s);
                    let (got, _, shape) = packed.leaf_for_trials(&s);
                    assert_eq!(got.shape, Shape::FLAT);
                    if !got.chart.needs_stored_box() {
                        assert_eq!(
                            got,
                            Proposal::in_chart(&leaf.rect, got.chart),
                            "{} {map:?}",
                            brdf.name()
                        );
                    }
                    let expected = (!want.shape.is_flat()).then(|| Prepared::new(want.shape));
                    assert_eq!(shape, expected, "{} {map:?}", brdf.name());
                    kinds[match (want.chart, shape) {
                        (Chart::Polar, _) => 0,
                        (c, _) if c.needs_stored_box() => 1,
                        (_, None) => 2,
                        (_, Some(Prepared::Coarse(_))) => 3,
                        (_, Some(Prepared::Fine(_))) => 4,
                    }] += 1;
                }
            }
        }
        assert!(
            kinds.iter().all(|&k| k > 0),
            "polar, rim, flat, coarse, fine: {kinds:?}"
        );
    }

    /// The selection through the guide finds the leaf (and square) the descent from the
    /// root finds, for x on and beside every child boundary and every guide part's edges,
    /// on a tree deep enough that most parts start below the root.
    #[test]
    fn the_guide_selects_as_the_root_does() {
        let phong =
            brdf_core::models::Phong::new(glam::Vec3::ZERO, glam::Vec3::ONE, 1000.0).unwrap();
        let wi = glam::Vec3::new(0.6, 0.0, 0.8);
        let tree = Quadtree::new(&phong, wi, crate::BuildConfig::default()).unwrap();
        let packed = PackedTree::new(&tree);
        // The largest guide with no more parts than half the nodes, and a real one.
        let n = packed.nodes.len();
        let want = (0..=GUIDE_BITS).filter(|&b| (2usize << b) <= n).max();
        assert_eq!(Some(packed.guide_bits), want, "{n} nodes");
        assert!(packed.guide_bits >= 5, "{n} nodes");
        let below_root = packed.guide.iter().filter(|g| g.depth >= 2).count();
        assert!(below_root > packed.guide.len() / 2, "{below_root}");
        let mut xs = alloc::vec![0u32, ONE - 1];
        for n in packed.nodes.iter().filter(|n| !n.is_leaf()) {
            for &c in &n.data {
                xs.extend([c.saturating_sub(1), c, c.saturating_add(1)]);
            }
        }
        let width = ONE >> packed.guide_bits;
        for j in 0..1u32 << packed.guide_bits {
            xs.extend([
                j * width,
                j * width + 1,
                j * width + width / 3,
                j * width + width - 1,
            ]);
        }
        for x in xs.into_iter().filter(|&x| x < ONE) {
            assert_eq!(
                packed.select_fixed(x),
                packed.select_from(SelectStart::ROOT, x),
                "x = {x}"
            );
        }
    }

    #[test]
    fn bounds_round_up() {
        for m in [1.0, 0.1, 1e-30, 3.0e9, 123.456_789_012_345] {
            assert!(f64::from(round_up(m)) >= m);
            assert!(f64::from(round_up(m)) <= m * (1.0 + 2.0 * f64::from(f32::EPSILON)));
        }
    }
}
