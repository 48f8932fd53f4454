//! The baked sampler's warp proxy of one grid tree: the tree's leaves, each holding its share
//! of the volume spread uniformly over its square, sampled by hierarchical warping (a
//! deterministic, stratification-preserving map of [0,1)²) and looked up by point location.
//! (Over the orthographic map the root and its children, if leaves, spread their shares over
//! their parts of the disk instead, uniformly in (r², φ): what a square spread would put in
//! its corners outside the disk is not lost.)
//!
//! ## Layout
//! Each node's share q of the tree's volume (f32) is what bake files store; the sampling
//! layout is derived from the shares when the table is made (so a table read from a file is
//! the table that was baked). A node of it is 16 bytes, everything one level of the warp
//! needs in one load:
//! - `link` — the first child, or a leaf's tag plus its depth (`LEAF_TAG + depth`);
//! - `data` — of a branch: the probability of its left column (children 0 and 2; the child
//!   order is (−,−), (+,−), (−,+), (+,+)) in 32-bit fixed point; of a leaf: **its density**
//!   (f32 bits), the product of the probabilities of the choices that reach it over its
//!   square's area, or a disk sector's (per unit square area; a sector's density holds in
//!   the disk, the only points a direction maps to);
//! - `rows` — of a branch: the probability of the lower row within the left and within the
//!   right column (fixed point); of a leaf: its proxy [`Shape`]'s two words (0, 0 for a
//!   flat leaf), read in the same load as its density. A leaf's column and row are not
//!   stored: the warp carries them down (two shifts a level, off its critical path), the
//!   look-up reads them from the point's bits.
//!
//! ## Warp and look-up
//! The warp keeps the interval of each coordinate of u that the choices so far leave, in
//! 63-bit fixed point, and chooses a column with `u.x` and a row with `u.y` at every level
//! by comparing against the cut ⌊w·p⌋ of that interval: an integer multiply, an add and a
//! compare per level, no division and no branch (the choices are coin flips no branch
//! predictor learns). The warp's first levels come from a **guide table**: for each square of
//! a 2^g × 2^g grid over u, the deepest node that every u in it passes through, with the
//! intervals the choices down to it leave — the very state the descent from the root reaches
//! there, so the warp is bit-identical with or without it, a few dependent levels shorter. At
//! the leaf, `u` maps into its square by the leaf's proxy shape (affinely for a flat leaf; see
//! `bilinear`) or into (r², φ) of a disk sector. The probability of
//! reaching a leaf is the product of the split probabilities up to the cuts' rounding,
//! 2⁻⁶³ of the whole interval per cut (relative 10⁻¹⁰ for a node reached with probability
//! 10⁻⁹), and that product over the leaf's area is the stored density. The look-up
//! ([`WarpTable::density`]) reads the tree's at most 30 levels of midpoints as the bits of
//! the point's fixed-point coordinates, so it is loads alone. Both find the leaf's one
//! stored number (times its shape at the point, [`WarpLeaf::density_at`]), so the density a
//! sample carries and the density of its point asked for later are the same value
//! ([`WarpLeaf::contains`] says when a point is still in the leaf).
//!
//! ## Shapes
//! A leaf may spread its share by a fitted [`Shape`] rather than uniformly (chosen at the
//! bake, where it predicts f better: see `bilinear`); a file stores the shaped leaves beside
//! the shares ([`WarpTable::shaped`]).

use crate::bilinear::leaf_density;
use crate::chart::{Rect, child_column, child_index, child_row};
use crate::proposal::Shape;
use crate::rim::{RimChart, SectorChart};
use alloc::vec::Vec;
use glam::{DVec2, DVec3};

/// Marks a leaf in the stored form ([`WarpTable::shares`], [`WarpTable::from_raw`]).
pub(crate) const WARP_LEAF: u32 = u32::MAX;

/// A leaf's `link` in the sampling layout is `LEAF_TAG + depth` (depth ≤ [`MAX_DEPTH`]);
/// every child index is below it ([`WarpTable::from_raw`] checks).
const LEAF_TAG: u32 = u32::MAX - 31;

/// Marks, in a leaf's first shape word (of the sampling layout, and of a version 9 file's
/// stored shapes), a leaf that spreads its share in its solid-angle chart ([`crate::rim`]);
/// a shape's own bits stop below bit 24.
pub(crate) const RIM_FLAG: u32 = 1 << 31;

/// A rim leaf's proxy density per unit square area at `p`: its mean `density` (per unit
/// square area, so its probability is `density` times its square's area), times its shape
/// at `p`'s chart coordinates, over the chart's measure (a density per unit solid angle),
/// over `z`, the cosine of `p`'s direction (per unit square area again, which the caller's
/// factor z undoes). 0 off the chart.
///
/// A disk sector (side 1 or more) is spread in its own chart, [`SectorChart`], and its
/// `density` is per unit area of its part of the disk (π/4 of its square).
#[inline]
fn rim_density(density: f64, shape: &Shape, rect: &Rect, p: DVec2, z: f64) -> f64 {
    if z.is_nan() || z <= 0.0 {
        return 0.0;
    }
    let side = rect.side();
    let (u, measure, area) = if side >= 1.0 {
        let (u, measure) = SectorChart::of(rect).unit(p, z);
        (u, measure, side * side * core::f64::consts::FRAC_PI_4)
    } else {
        let Some((u, measure)) = RimChart::of(rect).and_then(|c| c.unit(p)) else {
            return 0.0;
        };
        (u, measure, side * side)
    };
    density * area * shape.density(u) / (measure * z)
}

/// Whether a sampling-layout `link` is a leaf's.
#[inline(always)]
fn is_leaf_link(link: u32) -> bool {
    link >= LEAF_TAG
}

/// Where the warp starts for one square of its guide table: a node, its column and row at
/// its depth, and the fixed-point intervals of u's coordinates that reach it (see the module
/// doc).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
struct GuideEntry {
    lx: u64,
    ly: u64,
    wx: u64,
    wy: u64,
    node: u32,
    column: u32,
    row: u32,
}

impl GuideEntry {
    /// The root, reached by all of u.
    const ROOT: Self = Self {
        lx: 0,
        ly: 0,
        wx: 1 << 63,
        wy: 1 << 63,
        node: 0,
        column: 0,
        row: 0,
    };
}

/// The cut of a split of probability `p` (× 2³²) in an interval of width `w`: ⌊w·p⌋.
#[inline(always)]
fn cut(w: u64, p: u32) -> u64 {
    ((u128::from(w) * u128::from(p)) >> 32) as u64
}

/// One axis of a warp step: the interval [l, l + w) of a node narrowed to its part past the
/// cut c (`upper` = 1: [l + c, l + w)) or before it (`upper` = 0: [l, l + c)). Branch-free
/// (the choice is a coin flip a predictor cannot learn); the warp and its guide table both
/// step with it, so a guide entry holds the very intervals the descent reaches.
#[inline(always)]
fn narrow(l: &mut u64, w: &mut u64, c: u64, upper: u64) {
    let mask = upper.wrapping_neg();
    *l += c & mask;
    *w = ((*w - c) & mask) | (c & !mask);
}

/// One node of a [`WarpTable`]'s sampling layout (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(16))]
struct WarpNode {
    /// First child, or `LEAF_TAG` + the leaf's depth.
    link: u32,
    /// A branch's probability of its left column (× 2³²); a leaf's density per unit square
    /// area (f32 bits).
    data: u32,
    /// A branch's probabilities of the lower row in its left and right column (× 2³²); a
    /// leaf's shape words ([`Shape::to_bits`], [`Shape::fine_bits`]; 0, 0 when flat).
    rows: [u32; 2],
}

/// The leaf a warp reached: its square, mean density per unit square area and shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct WarpLeaf {
    pub(crate) index: usize,
    pub(crate) rect: Rect,
    pub(crate) density: f64,
    pub(crate) shape: Shape,
    /// Whether the leaf spreads its share in its solid-angle chart ([`crate::rim`]: a rim
    /// leaf's or a disk sector's).
    pub(crate) rim: bool,
}

impl WarpLeaf {
    /// The proxy's density per unit square area at `p` of this leaf: the one expression
    /// [`WarpTable::density`] ends in.
    /// `z`: the cosine of `p`'s direction (a rim leaf's density is per unit solid angle,
    /// divided by it here).
    #[inline]
    pub(crate) fn density_at(&self, p: DVec2, z: f64) -> f64 {
        if self.rim {
            rim_density(self.density, &self.shape, &self.rect, p, z)
        } else {
            leaf_density(self.density, &self.shape, &self.rect, p)
        }
    }

    /// Whether square point `p` is in this leaf's half-open square, the squares
    /// [`WarpTable::density`]'s descent separates (its cuts are `p ≥ mid`; squares, corners
    /// and midpoints are dyadic, so the two agree exactly).
    #[inline]
    pub(crate) fn contains(&self, p: DVec2) -> bool {
        self.rect.contains_half_open(p)
    }
}

/// The warp proxy of one tree (see the module doc). What a warp reads comes first (one
/// cache line where the table is aligned to one, as a baked sampler's are), then the
/// look-up's jump table.
#[derive(Clone, Debug, PartialEq)]
#[repr(C)]
pub(crate) struct WarpTable {
    nodes: Vec<WarpNode>,
    /// Where the warp starts, for each square of a 2^guide_bits grid over u (row-major).
    /// Derived, like `nodes`.
    guide: Vec<GuideEntry>,
    guide_bits: u32,
    jump_levels: u32,
    /// Whether the tree is over the orthographic map, whose disk leaves the square's corners
    /// out: its root and the root's children, if leaves, spread their shares over their parts
    /// of the disk (the disk, its quarters) rather than over their squares, in polar
    /// coordinates — nothing of them is lost outside the disk.
    disk: bool,
    /// The look-up's first `jump_levels` levels done at once: for each square of that depth
    /// (row-major, 2^jump_levels a side) the node its descent reaches there (or the leaf
    /// that holds it, higher up). Derived, like `nodes`.
    jump: Vec<u32>,
    /// Each node's share of the tree's volume: the stored form.
    shares: Vec<f32>,
}

impl WarpTable {
    /// The proxy of a built tree: each node's share of its volume.
    pub(crate) fn new(tree: &crate::tree::Quadtree) -> Self {
        let disk = tree.map() == brdf_core::DiskMap::Orthographic;
        let v = tree.volume();
        let shares = tree
            .nodes()
            .iter()
            .map(|n| {
                let link = if n.is_leaf() {
                    WARP_LEAF
                } else {
                    n.first_child
                };
                (link, if v > 0.0 { (n.v1 / v) as f32 } else { 0.0 })
            })
            .collect();
        Self::derived(shares, disk)
    }

    /// Rebuilds a table from its stored (first child, share) pairs, checking its shape
    /// (children after parents, in range, one parent each) and that every share is finite
    /// and ≥ 0; `map` is the tree's.
    pub(crate) fn from_raw(
        shares: Vec<(u32, f32)>,
        map: brdf_core::DiskMap,
    ) -> Result<Self, &'static str> {
        let n = shares.len();
        if n == 0 {
            return Err("a warp table with no nodes");
        }
        let mut seen = alloc::vec![false; n];
        let mut depth = alloc::vec![0u32; n];
        for (i, &(link, q)) in shares.iter().enumerate() {
            if !(q.is_finite() && q >= 0.0) {
                return Err("a warp share that is negative or not finite");
            }
            if link != WARP_LEAF {
                let c = link as usize;
                if c <= i || c.checked_add(4).is_none_or(|e| e > n) || link >= LEAF_TAG {
                    return Err("a warp node whose children are out of order or range");
                }
                if depth[i] >= MAX_DEPTH {
                    return Err("a warp table deeper than 30 levels");
                }
                for s in &mut seen[c..c + 4] {
                    if *s {
                        return Err("a warp node with two parents");
                    }
                    *s = true;
                }
                let d = depth[i] + 1;
                depth[c..c + 4].fill(d);
            }
        }
        if seen[0] || seen[1..].iter().any(|&s| !s) {
            return Err("warp nodes that are not one tree");
        }
        Ok(Self::derived(
            shares,
            map == brdf_core::DiskMap::Orthographic,
        ))
    }

    /// The stored form: (first child or [`WARP_LEAF`], share) per node.
    pub(crate) fn shares(&self) -> impl Iterator<Item = (u32, f32)> + '_ {
        self.nodes.iter().zip(&self.shares).map(|(n, &q)| {
            let link = if is_leaf_link(n.link) {
                WARP_LEAF
            } else {
                n.link
            };
            (link, q)
        })
    }

    /// Number of nodes.
    pub(crate) fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether node `i` is a leaf.
    pub(crate) fn is_leaf(&self, i: usize) -> bool {
        is_leaf_link(self.nodes[i].link)
    }

    /// Bytes held by the nodes.
    pub(crate) fn bytes(&self) -> usize {
        core::mem::size_of_val(self.nodes.as_slice())
            + core::mem::size_of_val(self.shares.as_slice())
            + core::mem::size_of_val(self.jump.as_slice())
            + core::mem::size_of_val(self.guide.as_slice())
    }

    /// Whether leaf `i` is a disk sector (spread over its part of the disk, never shaped).
    fn is_sector(&self, i: usize) -> bool {
        self.disk && self.nodes[i].link - LEAF_TAG <= 1
    }

    /// Leaf `i`'s proxy shape.
    #[inline(always)]
    fn shape(&self, i: usize) -> Shape {
        let [bits, fine] = self.nodes[i].rows;
        Shape::from_checked_bits(bits & !RIM_FLAG, fine)
    }

    /// Each node's square (parents before children).
    fn squares(&self) -> Vec<Rect> {
        let mut cells = alloc::vec![(0u8, 0u32, 0u32); self.nodes.len()];
        for i in 0..self.nodes.len() {
            let link = self.nodes[i].link;
            if is_leaf_link(link) {
                continue;
            }
            let (depth, column, row) = cells[i];
            for k in 0..4 {
                let (x, y) = (child_column(k) as u32, child_row(k) as u32);
                cells[link as usize + k] = (depth + 1, 2 * column + x, 2 * row + y);
            }
        }
        cells
            .into_iter()
            .map(|(d, c, r)| Rect::dyadic(d, c, r))
            .collect()
    }

    /// Fits every leaf's proxy shape ([`crate::bilinear::fit_leaf`]) from `f`, the tree's
    /// integrand at a local direction, over `map` (the tree's). Leaves without volume stay
    /// flat. With `charts` (bakes from file version 9 on, orthographic tables), each disk
    /// sector and each leaf on the disk's rim also tries its solid-angle chart
    /// ([`crate::rim`]) and spreads its share there where that lowers the weight's second
    /// moment at the fit's test points ([`crate::bilinear::choose_chart`]); otherwise
    /// sectors stay flat over their part of the disk.
    pub(crate) fn fit_shapes(
        &mut self,
        map: brdf_core::DiskMap,
        f: impl Fn(DVec3) -> f64,
        charts: bool,
    ) {
        use crate::bilinear::{choose_chart, fit_leaf_scored, fit_rim_leaf, fit_sector};
        let charts = charts && self.disk;
        let squares = self.squares();
        for (i, square) in squares.iter().enumerate() {
            if !self.is_leaf(i) || self.nodes[i].data == 0 {
                continue;
            }
            let (shape, chart) = if self.is_sector(i) {
                if !charts {
                    continue;
                }
                let Some(shape) = fit_sector(&SectorChart::of(square), &f) else {
                    continue;
                };
                (shape, true)
            } else {
                let (shape, old) = fit_leaf_scored(map, square, &f);
                match RimChart::of(square).filter(|_| charts) {
                    Some(rim) => {
                        let (chart_shape, score) = fit_rim_leaf(&rim, &f);
                        if choose_chart(old, score) {
                            (chart_shape, true)
                        } else {
                            (shape, false)
                        }
                    }
                    None => (shape, false),
                }
            };
            self.set_proxy(i, shape, chart);
        }
    }

    /// Sets leaf `i`'s proxy: its shape, and whether it spreads in its solid-angle chart.
    fn set_proxy(&mut self, i: usize, shape: Shape, chart: bool) {
        let flag = if chart { RIM_FLAG } else { 0 };
        self.nodes[i].rows = [shape.to_bits() | flag, shape.fine_bits()];
    }

    /// The leaves whose proxy is not flat over their squares (or, for disk sectors, over
    /// their parts of the disk) with their shapes and whether they spread in their
    /// solid-angle chart ([`crate::rim`]), in node order: the stored form of the proxies.
    pub(crate) fn shaped(&self) -> impl Iterator<Item = (u32, Shape, bool)> + '_ {
        (0..self.nodes.len())
            .filter(|&i| self.is_leaf(i) && self.nodes[i].rows != [0, 0])
            .map(|i| {
                (
                    i as u32,
                    self.shape(i),
                    self.nodes[i].rows[0] & RIM_FLAG != 0,
                )
            })
    }

    /// The table with the stored proxies of [`WarpTable::shaped`]: each a leaf's, not flat
    /// (or in its chart), in increasing node order; a chart only on a disk sector or a leaf
    /// on the orthographic disk's rim.
    pub(crate) fn with_shapes(
        mut self,
        shaped: &[(u32, Shape, bool)],
    ) -> Result<Self, &'static str> {
        let squares = if shaped.iter().any(|s| s.2) {
            self.squares()
        } else {
            Vec::new()
        };
        let mut last = None;
        for &(i, shape, chart) in shaped {
            let k = i as usize;
            if k >= self.nodes.len() || last.is_some_and(|l| l >= i) {
                return Err("a warp shape out of node order or range");
            }
            if !self.is_leaf(k) {
                return Err("a warp shape on a node that cannot take one");
            }
            if chart {
                if !(self.disk && (self.is_sector(k) || RimChart::of(&squares[k]).is_some())) {
                    return Err("a warp chart on a leaf off the orthographic disk's rim");
                }
            } else if self.is_sector(k) || shape.is_flat() {
                return Err("a warp shape on a node that cannot take one");
            }
            self.set_proxy(k, shape, chart);
            last = Some(i);
        }
        Ok(self)
    }

    /// The derived fields from the shares of a checked shape (parents before children).
    fn derived(shares: Vec<(u32, f32)>, disk: bool) -> Self {
        let mut nodes: Vec<WarpNode> = shares
            .iter()
            .map(|&(link, _)| WarpNode {
                link,
                data: 0,
                rows: [0; 2],
            })
            .collect();
        let shares: Vec<f32> = shares.into_iter().map(|(_, q)| q).collect();
        // The probability of reaching each node, from the fixed-point split probabilities the
        // warp uses (so a leaf's density is what the warp's choices give it, to f32).
        let mut prob = alloc::vec![0.0f64; nodes.len()];
        let mut area = alloc::vec![4.0f64; nodes.len()];
        // Each node's depth.
        let mut depths = alloc::vec![0u32; nodes.len()];
        prob[0] = if shares[0] > 0.0 { 1.0 } else { 0.0 };
        for i in 0..nodes.len() {
            let link = nodes[i].link;
            if link == WARP_LEAF {
                let depth = depths[i];
                // A disk sector spreads its share over its part of the disk, π/4 of its
                // square.
                let area = if disk && depth <= 1 {
                    area[i] * core::f64::consts::FRAC_PI_4
                } else {
                    area[i]
                };
                nodes[i] = WarpNode {
                    link: LEAF_TAG + depth,
                    data: ((prob[i] / area) as f32).to_bits(),
                    rows: [0, 0],
                };
                continue;
            }
            let c = link as usize;
            let q = [0, 1, 2, 3].map(|k| f64::from(shares[c + k]));
            let col = fixed_ratio(q[0] + q[2], q[1] + q[3]);
            let rows = [fixed_ratio(q[0], q[2]), fixed_ratio(q[1], q[3])];
            nodes[i].data = col;
            nodes[i].rows = rows;
            let first = |p: u32| f64::from(p) * ONE_OVER_2_32;
            let pc = [first(col), 1.0 - first(col)];
            for k in 0..4 {
                let (x, y) = (child_column(k), child_row(k));
                let pr = first(rows[x]);
                let py = if y == 0 { pr } else { 1.0 - pr };
                // A share of 0 gets an empty interval (or one of 2⁻³² of its parent's, where
                // the other side of the split is all: the warp then returns `None`).
                prob[c + k] = if q[k] > 0.0 {
                    prob[i] * pc[x] * py
                } else {
                    0.0
                };
                area[c + k] = area[i] * 0.25;
                depths[c + k] = depths[i] + 1;
            }
        }
        let (jump, jump_levels) = jump_table(&nodes);
        // At most one guide entry (48 bytes) for every two nodes (20 bytes each with their
        // shares): the guide holds at most 1.2× what the tree itself holds.
        let mut guide_bits = jump_levels.min(GUIDE_BITS);
        while guide_bits > 0 && 2 << (2 * guide_bits) > nodes.len() {
            guide_bits -= 1;
        }
        let (guide, guide_bits) = guide_table(&nodes, guide_bits);
        Self {
            nodes,
            guide,
            guide_bits,
            jump_levels,
            disk,
            jump,
            shares,
        }
    }

    /// Hierarchical warping: [0,1)² → a square point and the leaf it lies in (with the
    /// proxy's density there, per unit square area). `None` where no volume is.
    ///
    /// The open interval of each coordinate of u is kept in 63-bit fixed point, so a level
    /// costs an integer multiply, an add and a compare on its critical path and no branch
    /// (the choices are coin flips a predictor cannot learn); the cut of a split of
    /// probability p in an interval of width w is ⌊w·p⌋, exact to 2⁻⁶³ of the whole.
    #[inline]
    pub(crate) fn warp(&self, u: DVec2) -> Option<(DVec2, WarpLeaf)> {
        let (ux, uy) = fixed_uniforms(u);
        let shift = 63 - self.guide_bits;
        let square = ((uy >> shift) << self.guide_bits) | (ux >> shift);
        self.descend(ux, uy, self.guide[square as usize], true)
    }

    /// [`WarpTable::warp`] with every leaf flat (the table as a file without shapes reads):
    /// the bake's nearest-tree measurement draws its points with it, so that what rejection
    /// mode does is the same with or without the warp's shapes.
    pub(crate) fn warp_flat(&self, u: DVec2) -> Option<(DVec2, WarpLeaf)> {
        let (ux, uy) = fixed_uniforms(u);
        let shift = 63 - self.guide_bits;
        let square = ((uy >> shift) << self.guide_bits) | (ux >> shift);
        self.descend(ux, uy, self.guide[square as usize], false)
    }

    /// The warp of fixed-point uniforms from `start`, a node every (ux, uy) passing through
    /// it reaches with the intervals `start` holds; `shaped`: whether leaves take their
    /// shapes (else all are flat).
    #[inline(always)]
    fn descend(
        &self,
        ux: u64,
        uy: u64,
        start: GuideEntry,
        shaped: bool,
    ) -> Option<(DVec2, WarpLeaf)> {
        let GuideEntry {
            mut lx,
            mut ly,
            mut wx,
            mut wy,
            node,
            mut column,
            mut row,
        } = start;
        let mut i = node as usize;
        loop {
            let n = self.nodes[i];
            if is_leaf_link(n.link) {
                let density = f64::from(f32::from_bits(n.data));
                if !(density > 0.0 && wx > 0 && wy > 0) {
                    return None;
                }
                let depth = n.link - LEAF_TAG;
                let rect = Rect::dyadic(depth as u8, column, row);
                let t = DVec2::new((ux - lx) as f64 / wx as f64, (uy - ly) as f64 / wy as f64)
                    .clamp(DVec2::ZERO, DVec2::splat(1.0 - f64::EPSILON));
                let (bits, fine) = if shaped {
                    (n.rows[0] & !RIM_FLAG, n.rows[1])
                } else {
                    (0, 0)
                };
                let shape = Shape::from_checked_bits(bits, fine);
                let rim = shaped && n.rows[0] & RIM_FLAG != 0;
                let leaf = WarpLeaf {
                    index: i,
                    rect,
                    density,
                    shape,
                    rim,
                };
                // The leaf's point from its shape's words, not from the shape just decoded
                // (reading that back waited on its byte stores: see `Shape::warp_packed`);
                // the same points as `shape.warp(t)`, and a flat square leaf's `t` itself.
                let flat = fine == 0 && (bits == 0 || bits == FLAT_CORNERS);
                let warped = |t: DVec2| {
                    if bits == 0 {
                        Shape::FLAT.warp(t)
                    } else {
                        Shape::warp_packed(bits, fine, t)
                    }
                };
                let p = if self.disk && depth <= 1 {
                    if rim {
                        SectorChart::of(&rect).point(warped(t))
                    } else {
                        sector_point(&rect, t)
                    }
                } else if rim {
                    RimChart::of(&rect)?.point(warped(t))
                } else if flat {
                    rect.min + t * rect.side()
                } else {
                    rect.min + warped(t) * rect.side()
                };
                return Some((p, leaf));
            }
            let cx = cut(wx, n.data);
            let col = u64::from(ux - lx >= cx);
            narrow(&mut lx, &mut wx, cx, col);
            // Both rows' cuts are formed before the column is known.
            let cuts = [cut(wy, n.rows[0]), cut(wy, n.rows[1])];
            let cy = cuts[col as usize];
            let up = u64::from(uy - ly >= cy);
            narrow(&mut ly, &mut wy, cy, up);
            column = 2 * column + col as u32;
            row = 2 * row + up as u32;
            i = n.link as usize + child_index(col as usize, up as usize);
        }
    }

    /// The proxy's density at square point `p`, per unit square area (0 outside the square
    /// or where no volume is).
    ///
    /// Trees are at most [`MAX_DEPTH`] deep, so every midpoint the descent compares with is
    /// a multiple of 2^(1 − MAX_DEPTH): p ≥ mid is a bit of ⌊p·2^(MAX_DEPTH − 1)⌋ (exact:
    /// scaling by a power of two), and the descent is loads alone.
    /// `z`: the cosine of `p`'s direction, which a rim leaf's density (per unit solid
    /// angle, [`crate::rim`]) is divided by.
    #[inline]
    pub(crate) fn density(&self, p: DVec2, z: f64) -> f64 {
        self.look_up(p, z, true)
    }

    /// [`WarpTable::density`] with every leaf flat: the density of
    /// [`WarpTable::warp_flat`].
    pub(crate) fn density_flat(&self, p: DVec2) -> f64 {
        self.look_up(p, 1.0, false)
    }

    /// The density at `p`, with the leaves' shapes where `shaped`.
    #[inline(always)]
    fn look_up(&self, p: DVec2, z: f64, shaped: bool) -> f64 {
        if !(p.x >= -1.0 && p.x <= 1.0 && p.y >= -1.0 && p.y <= 1.0) {
            return 0.0;
        }
        let half = f64::from(1u32 << (MAX_DEPTH - 1));
        let top = (1i64 << MAX_DEPTH) - 1;
        // ⌊p·2^(D−1)⌋ + 2^(D−1) ∈ [0, 2^D]; p = 1 (≥ every midpoint) clamps to all ones.
        let fixed = |x: f64| {
            let s = x * half;
            // ⌊s⌋ without a libm call: truncation, less one where that rounded up.
            let t = s as i64;
            let floor = t - i64::from((t as f64) > s);
            (floor + (1i64 << (MAX_DEPTH - 1))).min(top) as u32
        };
        let (kx, ky) = (fixed(p.x), fixed(p.y));
        // The first levels at once (their bits index the jump table), then one per level.
        let mut bit = MAX_DEPTH - self.jump_levels;
        let mut i = self.jump[(((ky >> bit) << self.jump_levels) | (kx >> bit)) as usize] as usize;
        loop {
            let n = self.nodes[i];
            if is_leaf_link(n.link) {
                let density = f64::from(f32::from_bits(n.data));
                if !shaped || n.rows == [0, 0] {
                    return density;
                }
                // The leaf's column and row are the top `depth` bits of the point's.
                let depth = n.link - LEAF_TAG;
                let drop = MAX_DEPTH - depth;
                let rect = Rect::dyadic(depth as u8, kx >> drop, ky >> drop);
                let shape = Shape::from_checked_bits(n.rows[0] & !RIM_FLAG, n.rows[1]);
                return if n.rows[0] & RIM_FLAG != 0 {
                    rim_density(density, &shape, &rect, p, z)
                } else {
                    leaf_density(density, &shape, &rect, p)
                };
            }
            bit -= 1;
            let col = (kx >> bit) & 1;
            let row = (ky >> bit) & 1;
            i = n.link as usize + child_index(col as usize, row as usize);
        }
    }
}

/// A coarse shape's word with every corner at level 63: [`Shape::FLAT`]'s levels (which
/// [`Shape::to_bits`] writes as 0, and a file may spell out).
const FLAT_CORNERS: u32 = (1 << 24) - 1;

/// The deepest tree a table can hold (the build's and the bake file's limit).
const MAX_DEPTH: u32 = 30;

/// The most levels [`WarpTable::density`] skips with its jump table: 4 levels, 256 entries
/// (1 KiB) a table, four dependent loads fewer per look-up.
const JUMP_LEVELS: u32 = 4;

/// The most bits of each coordinate of u the warp's guide table reads: 16 × 16 squares,
/// 256 entries (12 KiB) a table at most, and never more entries than half the tree's nodes.
/// With 16 × 16 squares everywhere, the default grid's sharp lobes start their warp 3.2–4.9
/// levels down (phong n = 1000: 4.9 of the 6.8 levels its samples descend; cook-torrance
/// m = 0.1: 3.5 of 5.0; ward α = 0.05: 3.2 of 4.6); with 8 × 8, 2.5–3.8 levels down, and an
/// interleaved timing put phong's baked warp sample 10 ns slower.
const GUIDE_BITS: u32 = 4;

/// The jump table of a tree's sampling layout: J = min([`JUMP_LEVELS`], the tree's depth,
/// log₄ of its node count) and, for each of the 4^J squares of depth J (row-major, 2^J a
/// side), the node whose square holds it at depth J, or the leaf above that holds it. The
/// nodes are `derived`'s, their leaves already tagged with their depth.
fn jump_table(nodes: &[WarpNode]) -> (Vec<u32>, u32) {
    // Every leaf carries its depth (`derived` put it there): the deepest is the tree's.
    let deepest = nodes
        .iter()
        .filter(|n| is_leaf_link(n.link))
        .map(|n| n.link - LEAF_TAG)
        .max()
        .unwrap_or(0);
    // No more entries than nodes: 4^J ≤ n (the table stays within a quarter of the nodes'
    // bytes; a small tree gains little from skipping levels anyway).
    let mut levels = deepest.min(JUMP_LEVELS);
    while levels > 0 && (1usize << (2 * levels)) > nodes.len() {
        levels -= 1;
    }
    let side = 1u32 << levels;
    let mut jump = Vec::with_capacity((side * side) as usize);
    for cy in 0..side {
        for cx in 0..side {
            let mut i = 0usize;
            for l in (0..levels).rev() {
                let link = nodes[i].link;
                if is_leaf_link(link) {
                    break;
                }
                let (col, row) = ((cx >> l) & 1, (cy >> l) & 1);
                i = link as usize + child_index(col as usize, row as usize);
            }
            jump.push(i as u32);
        }
    }
    (jump, levels)
}

/// The point of a disk sector (the orthographic root or one of its children, see
/// [`WarpTable`]'s `disk`) at t ∈ [0,1)²: uniform in (s, φ), s = r² over [0, 1) and φ over the
/// sector's angles ([`crate::proposal::Proposal::polar`]'s box), so uniform in area over the
/// node's part of the disk.
#[inline]
fn sector_point(rect: &Rect, t: DVec2) -> DVec2 {
    let b = crate::proposal::Proposal::in_chart(rect, crate::chart::Chart::Polar);
    let c = crate::chart::polar_point(t.x, b.lo.y + t.y * (b.hi.y - b.lo.y));
    c.p
}

/// u ∈ [0,1)² in 63-bit fixed point, as the warp reads it (u clamped below 1 first, so
/// each coordinate is below 2⁶³).
#[inline(always)]
fn fixed_uniforms(u: DVec2) -> (u64, u64) {
    const SCALE: f64 = 9_223_372_036_854_775_808.0; // 2⁶³
    let u = u.clamp(DVec2::ZERO, DVec2::splat(1.0 - f64::EPSILON));
    ((u.x * SCALE) as u64, (u.y * SCALE) as u64)
}

/// The guide table of a sampling layout: g = `bits` and, for each square of the 2^g × 2^g
/// grid over u (row-major; square (a, b) holds the fixed-point u with ⌊ux/2^(63−g)⌋ = a and
/// ⌊uy/2^(63−g)⌋ = b), the deepest node every u of that square passes through, with the
/// intervals it is reached with: the warp's own steps, taken while the whole square falls on
/// one side of both of a level's cuts.
fn guide_table(nodes: &[WarpNode], bits: u32) -> (Vec<GuideEntry>, u32) {
    let side = 1u64 << bits;
    let width = 1u64 << (63 - bits);
    let mut guide = Vec::with_capacity((side * side) as usize);
    for b in 0..side {
        for a in 0..side {
            // The square's fixed-point ranges, inclusive.
            let (x0, x1) = (a * width, (a + 1) * width - 1);
            let (y0, y1) = (b * width, (b + 1) * width - 1);
            let mut e = GuideEntry::ROOT;
            loop {
                let n = nodes[e.node as usize];
                if is_leaf_link(n.link) {
                    break;
                }
                // Every u of the square lies in the node's intervals (it got there), so
                // u − l does not wrap.
                let cx = cut(e.wx, n.data);
                let col = match (x0 - e.lx >= cx, x1 - e.lx >= cx) {
                    (true, _) => 1u64,
                    (false, false) => 0,
                    (false, true) => break,
                };
                let cy = cut(e.wy, n.rows[col as usize]);
                let row = match (y0 - e.ly >= cy, y1 - e.ly >= cy) {
                    (true, _) => 1u64,
                    (false, false) => 0,
                    (false, true) => break,
                };
                narrow(&mut e.lx, &mut e.wx, cx, col);
                narrow(&mut e.ly, &mut e.wy, cy, row);
                e.node = n.link + child_index(col as usize, row as usize) as u32;
                e.column = 2 * e.column + col as u32;
                e.row = 2 * e.row + row as u32;
            }
            guide.push(e);
        }
    }
    (guide, bits)
}

/// 2⁻³².
const ONE_OVER_2_32: f64 = 1.0 / 4_294_967_296.0;

/// a/(a + b) in 32-bit fixed point (rounded, at most 2³² − 1); ½ for two zeros.
fn fixed_ratio(a: f64, b: f64) -> u32 {
    if a + b > 0.0 {
        (a / (a + b) * 4_294_967_296.0 + 0.5).min(4_294_967_295.0) as u32
    } else {
        1 << 31
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_core::DiskMap;

    /// The map whose leaves all spread over their squares (the tests of the layout itself).
    const SQUARES: DiskMap = DiskMap::Concentric;

    /// Over the orthographic map the root and its children, if leaves, spread their shares
    /// over their parts of the disk, uniformly in area: every warped point is in the disk and
    /// in its leaf's square, the density is the share over the part's area (π, π/4), and the
    /// points' r² is uniform on [0, 1) (its mean ½, and a quarter of them below ¼) — a
    /// square's spread would put 21 % of them outside the disk.
    #[test]
    fn disk_sectors_spread_their_shares_over_the_disk() {
        let one =
            WarpTable::from_raw(alloc::vec![(WARP_LEAF, 1.0)], DiskMap::Orthographic).unwrap();
        let split = WarpTable::from_raw(
            alloc::vec![
                (1, 1.0),
                (WARP_LEAF, 0.1),
                (WARP_LEAF, 0.2),
                (WARP_LEAF, 0.3),
                (WARP_LEAF, 0.4)
            ],
            DiskMap::Orthographic,
        )
        .unwrap();
        let n = 200;
        for (t, parts) in [
            (&one, &[(0usize, 1.0, 4.0)][..]),
            (
                &split,
                &[(1, 0.1, 1.0), (2, 0.2, 1.0), (3, 0.3, 1.0), (4, 0.4, 1.0)][..],
            ),
        ] {
            let (mut r2_sum, mut below, mut count) = (0.0, 0, 0);
            let mut hits = [0usize; 5];
            for i in 0..n {
                for j in 0..n {
                    let u = DVec2::new(
                        (f64::from(i) + 0.5) / f64::from(n),
                        (f64::from(j) + 0.5) / f64::from(n),
                    );
                    let (p, leaf) = t.warp(u).unwrap();
                    assert!(
                        p.length_squared() < 1.0 && leaf.contains(p),
                        "{u} -> {p} {leaf:?}"
                    );
                    let &(_, share, area) = parts.iter().find(|q| q.0 == leaf.index).unwrap();
                    let want = f64::from(share as f32) / (area * core::f64::consts::FRAC_PI_4);
                    assert!(
                        (leaf.density - want).abs() <= 1e-7 * want,
                        "{leaf:?} vs {want}"
                    );
                    assert_eq!(t.density(p, 1.0), leaf.density);
                    hits[leaf.index] += 1;
                    let r2 = p.length_squared();
                    r2_sum += r2;
                    below += usize::from(r2 < 0.25);
                    count += 1;
                }
            }
            let m = count as f64;
            assert!((r2_sum / m - 0.5).abs() < 2e-3, "mean r² {}", r2_sum / m);
            assert!(
                (below as f64 / m - 0.25).abs() < 2e-3,
                "r² < ¼: {}",
                below as f64 / m
            );
            for &(k, share, _) in parts {
                assert!(
                    (hits[k] as f64 / m - share).abs() < 2e-3,
                    "leaf {k}: {}",
                    hits[k]
                );
            }
        }
        // Every leaf of a concentric tree spreads over its square (its corner is outside the disk).
        let square = WarpTable::from_raw(alloc::vec![(WARP_LEAF, 1.0)], SQUARES).unwrap();
        assert!(square.warp(DVec2::splat(0.999)).unwrap().0.length_squared() > 1.0);
    }

    /// A root split once, its child 3 split again, with uneven shares.
    fn table() -> WarpTable {
        let mut shares = alloc::vec![(1u32, 1.0f32)];
        shares.extend([
            (WARP_LEAF, 0.1),
            (WARP_LEAF, 0.2),
            (WARP_LEAF, 0.0),
            (5, 0.7),
        ]);
        shares.extend([
            (WARP_LEAF, 0.3),
            (WARP_LEAF, 0.1),
            (WARP_LEAF, 0.2),
            (WARP_LEAF, 0.1),
        ]);
        WarpTable::from_raw(shares, SQUARES).unwrap()
    }

    /// Each leaf's stored density is its share over its area, and integrates to 1.
    #[test]
    fn leaf_densities_are_shares_over_area() {
        let t = table();
        let want = [(1, 0.1, 1.0), (2, 0.2, 1.0), (3, 0.0, 1.0), (5, 0.3, 0.25)];
        for (i, q, area) in want {
            let d = f64::from(f32::from_bits(t.nodes[i].data));
            assert!((d - q / area).abs() < 1e-6, "leaf {i}: {d}");
        }
        // Midpoint rule on a fine grid (exact: the density is constant on dyadic squares).
        let n = 64;
        let mut sum = 0.0;
        for a in 0..n {
            for b in 0..n {
                let p = DVec2::new(
                    -1.0 + (a as f64 + 0.5) * 2.0 / n as f64,
                    -1.0 + (b as f64 + 0.5) * 2.0 / n as f64,
                );
                sum += t.density(p, 1.0) * (2.0 / n as f64) * (2.0 / n as f64);
            }
        }
        assert!((sum - 1.0).abs() < 1e-6, "{sum}");
    }

    /// The warp's point lies in the leaf it reports, whose density is `density` there; the
    /// fraction of a uniform grid of u landing in each leaf is its share; an empty leaf is
    /// never reached.
    #[test]
    fn the_warp_lands_in_its_leaf_with_its_share() {
        let t = table();
        let n = 400;
        let mut counts = [0usize; 9];
        for a in 0..n {
            for b in 0..n {
                let u = DVec2::new((a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64);
                let (p, leaf) = t.warp(u).expect("volume everywhere but leaf 3");
                assert!(leaf.contains(p), "{p} outside {leaf:?}");
                assert_eq!(leaf.density, t.density(p, 1.0));
                assert!(t.is_leaf(leaf.index));
                counts[leaf.index] += 1;
            }
        }
        assert_eq!(counts[3], 0);
        for (i, q) in [(1, 0.1), (2, 0.2), (5, 0.3), (6, 0.1), (7, 0.2), (8, 0.1)] {
            let got = counts[i] as f64 / (n * n) as f64;
            assert!((got - q).abs() < 0.01, "leaf {i}: {got} vs {q}");
        }
    }

    /// A solid-angle chart's mark is taken only where a chart can be: on an orthographic
    /// disk sector or a leaf whose square crosses the rim; on a leaf inside the disk, or on
    /// any leaf of a concentric table (whose squares cross r = 1 too), it is refused.
    #[test]
    fn a_chart_mark_is_refused_where_no_chart_can_be() {
        // The root, its four children, and the first child split again: leaf 5 is
        // [−1, −0.5]², across the rim; leaf 8 is [−0.5, 0]², inside the disk.
        let shares = alloc::vec![
            (1, 1.0),
            (5, 0.25),
            (WARP_LEAF, 0.25),
            (WARP_LEAF, 0.25),
            (WARP_LEAF, 0.25),
            (WARP_LEAF, 0.0625),
            (WARP_LEAF, 0.0625),
            (WARP_LEAF, 0.0625),
            (WARP_LEAF, 0.0625),
        ];
        let table = |map| WarpTable::from_raw(shares.clone(), map).unwrap();
        let mark = |map, leaf: u32| table(map).with_shapes(&[(leaf, Shape::FLAT, true)]);
        let orthographic = DiskMap::Orthographic;
        assert!(mark(orthographic, 2).is_ok(), "a sector");
        assert!(mark(orthographic, 5).is_ok(), "across the rim");
        assert!(mark(orthographic, 8).is_err(), "inside the disk");
        for leaf in [2, 5, 8] {
            assert!(
                mark(DiskMap::Concentric, leaf).is_err(),
                "concentric {leaf}"
            );
        }
        // A marked flat leaf spreads in its chart: its point is no longer the square's.
        let (plain, charted) = (table(orthographic), mark(orthographic, 5).unwrap());
        let u = DVec2::new(0.1, 0.15);
        assert_ne!(plain.warp(u).unwrap().0, charted.warp(u).unwrap().0);
    }

    /// Shaped leaves: the density still integrates to 1, the look-up and the drawing leaf
    /// agree on it to the bit, and the warp's points follow it cell by cell (stratified u:
    /// a 16 × 16 grid of cells over the square, each against its own integral). A stored
    /// shape on a branch, a disk sector, out of order or flat is refused.
    #[test]
    fn shaped_leaves_spread_their_shares_by_their_shapes() {
        let coarse = Shape::from_levels([4, 63, 20, 40]).unwrap();
        let fine = Shape::from_grid([5, 20, 5, 20, 63, 20, 5, 20, 9]).unwrap();
        let t = table()
            .with_shapes(&[(1, fine, false), (5, coarse, false), (8, fine, false)])
            .unwrap();
        assert_eq!(t.shaped().count(), 3);
        let cells = 16;
        let sub = 16;
        let mut want = alloc::vec![0.0; cells * cells];
        let mut sum = 0.0;
        for a in 0..cells * sub {
            for b in 0..cells * sub {
                let h = 2.0 / (cells * sub) as f64;
                let p = DVec2::new(-1.0 + (a as f64 + 0.5) * h, -1.0 + (b as f64 + 0.5) * h);
                let d = t.density(p, 1.0) * h * h;
                sum += d;
                want[(b / sub) * cells + a / sub] += d;
            }
        }
        assert!((sum - 1.0).abs() < 1e-4, "{sum}");
        let n = 600;
        let mut got = alloc::vec![0usize; cells * cells];
        for a in 0..n {
            for b in 0..n {
                let u = DVec2::new((a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64);
                let (p, leaf) = t.warp(u).unwrap();
                assert!(leaf.contains(p), "{p} outside {leaf:?}");
                assert_eq!(
                    leaf.density_at(p, 1.0).to_bits(),
                    t.density(p, 1.0).to_bits()
                );
                let cell = |x: f64| (((x + 1.0) * 0.5 * cells as f64) as usize).min(cells - 1);
                got[cell(p.y) * cells + cell(p.x)] += 1;
            }
        }
        for (k, (&g, &w)) in got.iter().zip(&want).enumerate() {
            let g = g as f64 / (n * n) as f64;
            assert!((g - w).abs() < 2e-4 + 0.02 * w, "cell {k}: {g} vs {w}");
        }
        // Flat leaves would not pass: the shapes moved points.
        let flat = table();
        let moved = (0..100)
            .filter(|&k| {
                let u = DVec2::new(0.05 + 0.009 * k as f64, 0.3);
                flat.warp(u).unwrap().0 != t.warp(u).unwrap().0
            })
            .count();
        assert!(moved > 50, "{moved}");
        for bad in [
            &[(0, coarse, false)][..],
            &[(4, coarse, false)],
            &[(5, coarse, false), (1, fine, false)],
            &[(1, Shape::FLAT, false)],
            &[(9, coarse, false)],
        ] {
            assert!(table().with_shapes(bad).is_err(), "{bad:?}");
        }
        let sector =
            WarpTable::from_raw(alloc::vec![(WARP_LEAF, 1.0)], DiskMap::Orthographic).unwrap();
        assert!(sector.with_shapes(&[(0, coarse, false)]).is_err());
    }

    /// On a leaf's edges and corners, `contains` holds exactly where the look-up finds that
    /// leaf: the sampler's shortcut (the drawing leaf's density for a point still in it) and
    /// the look-up agree to the bit.
    #[test]
    fn containment_agrees_with_the_look_up_on_edges() {
        let t = table();
        let mut leaves = Vec::new();
        for a in 0..=20 {
            for b in 0..=20 {
                if let Some((_, leaf)) = t.warp(DVec2::new(a as f64 / 20.0, b as f64 / 20.0)) {
                    leaves.push(leaf);
                }
            }
        }
        for leaf in leaves {
            let (lo, hi) = (leaf.rect.min, leaf.rect.max);
            let xs = [lo.x, hi.x.next_down(), hi.x, lo.x.next_down()];
            let ys = [lo.y, hi.y.next_down(), hi.y, lo.y.next_down()];
            for x in xs {
                for y in ys {
                    let p = DVec2::new(x, y);
                    if leaf.contains(p) {
                        assert_eq!(t.density(p, 1.0), leaf.density, "{p} in {leaf:?}");
                    }
                }
            }
            assert!(leaf.contains(lo) && !leaf.contains(hi));
        }
    }

    /// The warp through the guide table is the warp from the root, to the bit: the same
    /// point and leaf for u on and beside every guide square's edges and at random, on a
    /// tree whose guide skips levels (and a guide that cannot, a one-node table).
    #[test]
    fn the_guide_table_warps_as_the_root_does() {
        let t = deep_table();
        // 8 × 8 squares: the largest guide with no more entries than half its 361 nodes.
        assert_eq!((t.guide_bits, t.nodes.len()), (3, 361));
        let skipped = t.guide.iter().filter(|e| e.node != 0).count();
        assert!(
            skipped > t.guide.len() / 2,
            "{skipped} of {}",
            t.guide.len()
        );
        let from_root = |u: DVec2| {
            let (ux, uy) = fixed_uniforms(u);
            t.descend(ux, uy, GuideEntry::ROOT, true)
        };
        let side = 1u32 << t.guide_bits;
        let mut us = Vec::new();
        for a in 0..=side {
            for e in [0.0, 1e-15, -1e-15, 0.37 / f64::from(side)] {
                us.push(f64::from(a) / f64::from(side) + e);
            }
        }
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..64 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            us.push((state >> 11) as f64 / (1u64 << 53) as f64);
        }
        for &x in &us {
            for &y in &us {
                let u = DVec2::new(x, y);
                assert_eq!(t.warp(u), from_root(u), "{u}");
            }
        }
        let one = WarpTable::from_raw(alloc::vec![(WARP_LEAF, 1.0)], SQUARES).unwrap();
        assert_eq!((one.guide_bits, one.guide.len()), (0, 1));
        let (p, leaf) = one.warp(DVec2::new(0.25, 0.75)).unwrap();
        assert_eq!((p, leaf.density), (DVec2::new(-0.5, 0.5), 0.25));
    }

    /// Malformed tables are refused.
    #[test]
    fn malformed_tables_are_refused() {
        assert!(WarpTable::from_raw(alloc::vec![], SQUARES).is_err());
        assert!(WarpTable::from_raw(alloc::vec![(WARP_LEAF, -1.0)], SQUARES).is_err());
        assert!(WarpTable::from_raw(alloc::vec![(WARP_LEAF, f32::NAN)], SQUARES).is_err());
        assert!(WarpTable::from_raw(alloc::vec![(0, 1.0)], SQUARES).is_err());
        assert!(WarpTable::from_raw(alloc::vec![(1, 1.0), (WARP_LEAF, 1.0)], SQUARES).is_err());
    }

    /// On [`deep_table`] (its jump table skips four levels) the look-up with its jump table
    /// finds the same leaf (the same stored number) as a descent from the root one level at a
    /// time, at points on and off every dyadic edge down to the deepest level.
    #[test]
    fn the_jump_table_finds_the_leaf_a_plain_descent_finds() {
        let t = deep_table();
        assert_eq!(t.jump_levels, JUMP_LEVELS);
        let plain = |p: DVec2| {
            let mut i = 0usize;
            let mut r = Rect::square(-1.0, -1.0, 2.0);
            while !is_leaf_link(t.nodes[i].link) {
                let k = r.quadrant_of(p);
                r = r.quadrants()[k];
                i = t.nodes[i].link as usize + k;
            }
            f64::from(f32::from_bits(t.nodes[i].data))
        };
        let mut checked = 0;
        for a in 0..=512 {
            for b in [0, 1, 7, 255, 256, 300, 511, 512] {
                for e in [0.0, 1e-12, -1e-12] {
                    let p = DVec2::new(a as f64 / 256.0 - 1.0 + e, b as f64 / 256.0 - 1.0 - e);
                    if p.x.abs() <= 1.0 && p.y.abs() <= 1.0 {
                        assert_eq!(t.density(p, 1.0), plain(p), "{p}");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 10_000);
        // A one-node table jumps no level.
        let one = WarpTable::from_raw(alloc::vec![(WARP_LEAF, 1.0)], SQUARES).unwrap();
        assert_eq!((one.jump_levels, one.jump.len()), (0, 1));
        assert_eq!(one.density(DVec2::new(0.3, -0.9), 1.0), 0.25);
    }

    /// A tree complete to depth 4 and, below one of its depth-4 nodes, 9 levels deep, with
    /// uneven shares on every leaf.
    fn deep_table() -> WarpTable {
        // Breadth-first: node i splits when it is above depth 4, or is on the chain (the
        // first child of a depth-4 node's descendants, to depth 8).
        let mut shares: Vec<(u32, f32)> = alloc::vec![(WARP_LEAF, 1.0)];
        let mut depth = alloc::vec![0u32];
        let mut chain = alloc::vec![false];
        let mut i = 0;
        while i < shares.len() {
            let (d, on_chain) = (depth[i], chain[i]);
            let splits = d < 4 || (on_chain && d < 9) || (d == 4 && i == 200);
            if splits {
                shares[i].0 = shares.len() as u32;
                for k in 0..4u32 {
                    shares.push((WARP_LEAF, 0.1 + 0.05 * k as f32 + 0.01 * d as f32));
                    depth.push(d + 1);
                    chain.push((on_chain || (d == 4 && i == 200)) && k == d % 4);
                }
            }
            i += 1;
        }
        assert_eq!(depth.iter().max(), Some(&9));
        WarpTable::from_raw(shares, SQUARES).unwrap()
    }
}
