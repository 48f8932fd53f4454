//! Render-time sampling at every incident direction (SPEC §7): [`BakedSampler`], built once
//! per material, answers `sample`, `pdf` and `eval` at any `wi` with an exact pdf.
//!
//! ## What is baked
//! A quadtree (SPEC §3) at each direction of a grid of incident directions that reaches
//! grazing: for an isotropic model a 1D grid in θi (φi by rotation about the normal), for an
//! anisotropic one a 2D grid in (θi, φi) over the part of the φ circle its declared mirror
//! symmetries leave ([`brdf_core::Symmetry`]: a quarter for Ward, Schlick's slab and
//! Poulin–Fournier's cylinders). Each grid tree is kept twice, compactly: its 16-byte
//! rejection layout ([`PackedTree`]) and a 20-byte-per-node warp table (the same leaves:
//! each node's share of the volume, and the split probabilities and leaf densities the warp
//! reads, see `warp_table.rs`), so one bake serves both [`BakedMode`]s.
//!
//! ## Sampling at a wi off the grid
//! An exact mixture of the neighbouring grid trees, each carried onto the query: rotated
//! onto its mirror direction (isotropic grids), or by the half-vector transport
//! (anisotropic grids): see `baked_mixture.rs`.
//!
//! ## Transport roles
//! The tables sample `wo` (toward the viewer) given `wi` (toward the light): a light path's
//! step, [`Role::Importance`]. A camera path knows the viewer's direction and samples the
//! light's, [`Role::Radiance`]: for a reciprocal model the same tables serve with the names
//! swapped; for a non-reciprocal one (`strauss`) the bake also holds the adjoint's trees
//! (f*(a, b) = f_r(b, a)), which sample ∝ f_r(wi, wo)·cos θi given `wo`.
//!
//! ## Compared with the alternatives
//! A tree per shading point is exact but costs 1–20 ms (0.4–0.7 s for He–Torrance and
//! Poulin–Fournier) per `wi`; a cache binned in θi (what `examples/furnace.rs` did) returns
//! the pdf of the bin's tree, not of the direction it was asked about, which biases MIS;
//! tabulated BSDFs conditioned on wi (Mitsuba's `Marginal2D`, pbrt's `MeasuredBxDF`)
//! interpolate their tables between slices, which keeps the pdf exact only because the
//! interpolation is linear in a fixed parameterisation — fine for broad data, but a sharp
//! lobe then smears between slices. The maps above keep sharp lobes sharp between slices
//! and the mixture keeps the pdf exact.

use crate::bake_budget::{self, Prunable};
use crate::bake_grid::{BakeGrid, Nearest};
use crate::baked_views::{BakedAt, BakedPoint, BrokenPdf};
use crate::config::BuildConfig;
use crate::error::{BakeError, BakedError, BuildError};
use crate::packed::PackedTree;
use crate::sampler::Sample;
use crate::tree::Quadtree;
use crate::warp_table::WarpTable;
use alloc::sync::Arc;
use alloc::vec::Vec;
use brdf_core::geometry::mirror;
use brdf_core::{Brdf, BrdfSample, DiskMap, ParamSet, PeakHints, Symmetry};
use core::sync::atomic::{AtomicU64, Ordering};
use glam::{DVec3, Vec2, Vec3};
use rand_core::Rng;

/// The polar angle of the grid's last row of trees, in degrees. A `wi` beyond it (up to the
/// horizon) uses that row alone: rotated onto its mirror direction, and, with the share linear
/// interpolation would give a row one spacing further on (a spacing no wider than the
/// default grid's), untilted (turned about the normal only), which covers the band above the
/// horizon that the rotation leaves.
pub const GRID_THETA_MAX_DEG: f64 = 89.0;

/// The node budget of each grid tree in [`BakeConfig::default`] (2¹⁶: at most 1.5 MiB a
/// tree in both layouts), so that no incident direction of the grid can take a bake's memory
/// beyond trees × that.
pub const DEFAULT_BAKE_NODE_BUDGET: u32 = 1 << 16;

/// Default rows of trees in θi (from 0° to [`GRID_THETA_MAX_DEG`]), chosen by measurement
/// (see `examples/bake_grid.rs` and the README's numbers).
pub const DEFAULT_THETA_STEPS: u16 = 32;

/// Default columns of trees in φi over the folded φ range of an anisotropic model.
pub const DEFAULT_PHI_STEPS: u16 = 9;

/// Default defensive share δ of cosine sampling in the mixture: 10⁻⁶. It only has to keep
/// the density positive where no rotated neighbour reaches (beyond the last grid row, and
/// in leaves a tree found empty), and every bit of it costs variance where the mixture is
/// otherwise ∝ f·cos: a share δ of samples weighted ≈ 0 adds ≈ δ·ρ² to the variance of
/// the weight, which for a glossy lobe under a smooth sky is the whole of the exact tree's
/// variance at δ ≈ 10⁻⁵ (measured: `examples/bake_grid.rs`).
pub const DEFAULT_DEFENSIVE: f64 = 1e-6;

/// The memory a bake of an anisotropic model may hold by default ([`BakeConfig::max_bytes`]
/// `None`): 16 MiB, issue #18's goal for an anisotropic material at the default grid. The
/// default grids of the anisotropic bench sets hold 0.6–3.3 MB and are not touched by it;
/// a needle-thin lobe (Ward αx = 1, αy = 0.001: 61 MB) is.
pub const DEFAULT_BAKE_MAX_BYTES: usize = 16 << 20;

/// The memory a bake of an isotropic model may hold by default: 1 MiB, issue #18's goal for
/// an isotropic material at the default grid. The isotropic bench sets hold 0.02–0.75 MB;
/// a very rough He–Torrance surface (σ0 = 10 µm, τ = 0.05 µm: 2.1 MB) is held to it at
/// E\[T\] mean 1.47 → 1.55 and warp mode's mean R − 1 at the cells' centres 0.25 → 0.41.
pub const DEFAULT_ISOTROPIC_BAKE_MAX_BYTES: usize = 1 << 20;

/// Bytes a grid tree holds per node at least: its packed node (16), its warp node (16) and
/// its warp share (4). A first build within [`FIRST_BUILD_SHARES`]× a tree's even share of
/// [`BakeConfig::max_bytes`] is limited to that many bytes' worth of nodes at this rate.
const MIN_NODE_BYTES: usize = 36;

/// How many even shares of [`BakeConfig::max_bytes`] a tree's first build may take (its node
/// budget, at [`MIN_NODE_BYTES`] a node): 8. A tree the pruning would keep whole can hold
/// no more than this; its build layout (88 bytes a node) is kept until the pruning is done,
/// so the bake's memory on the way is bounded by about 20× the limit. At Ward αx = 1,
/// αy = 0.001 (default grid, 16 MiB), 4 shares left one tree's E\[T\] at 9.76 (its build
/// stopped at 6 472 nodes, none of them the pruning's to take), 8 at 4.72, in the same bake
/// time (141 s) and peak memory (484 and 493 MB); αx = 0.5, αy = 0.003 is the same either
/// way.
const FIRST_BUILD_SHARES: usize = 8;

/// The least node budget of a tree's first build under [`BakeConfig::max_bytes`] (where the
/// build's own budget allows it): a limit too small for the grid then shows as trees that
/// cannot be pruned to fit ([`BakeError::TooLarge`]), not as builds cut off by a budget
/// nobody set.
const MIN_FIRST_NODES: u32 = 1024;

/// The most trees one bake may hold (a typed error beyond: a grid of 10⁶ trees is a typo).
pub const MAX_TREES: usize = 1 << 16;

/// The most bytes of trees one bake may hold: 2 GiB. Each grid tree's node budget bounds
/// one tree (1.5 MiB at [`DEFAULT_BAKE_NODE_BUDGET`]), but not a grid of thousands of them:
/// the bake counts what its finished trees hold and stops with [`BakeError::TooLarge`] once
/// they pass this, rather than take a machine's memory. The default grids of the bench sets
/// hold 0.02–7 MiB (measured: `brdf bench`, `examples/bake_grid.rs`).
pub const MAX_BAKE_BYTES: usize = 2 << 30;

/// Which direction is given and which is sampled (pbrt's `TransportMode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Role {
    /// A camera path: the direction toward the viewer (`wo`) is given; the direction toward
    /// the light (`wi`) is sampled ∝ f_r(wi, wo)·cos θi.
    Radiance,
    /// A light path (and SPEC §1's convention): `wi` toward the light is given; `wo` is
    /// sampled ∝ f_r(wi, wo)·cos θo. The tables' own direction.
    Importance,
}

/// How the chosen grid tree is sampled (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BakedMode {
    /// Rejection in the chosen leaf (exact ∝ Y(f_r)·cos θ per tree; an RNG draws the trials).
    #[default]
    Rejection,
    /// The trees' warp proxies, a deterministic function of (uc, u). Each leaf's share is
    /// spread over its whole square (uniformly, or by the shape fitted to f there: see
    /// `bilinear`), so over the orthographic map (the default) the part
    /// of a rim leaf outside the disk is lost — except the root's and its children's, which
    /// are spread over their parts of the disk (a diffuse lobe's one leaf is the disk:
    /// lambert, oren-nayar and strauss lose 0.01 %, where spreading over the square lost
    /// 21.6 %). Measured at θi ≈ 22° and 65° on the default sets, broad lobes with deeper rim
    /// leaves lose 2–5.5 % (schlick, blinn-phong, lewis-phong, poulin-fournier), ward and
    /// cook-torrance up to 1 %, sharp lobes next to nothing. A bake over the concentric map
    /// (`BuildConfig::map`, `brdf bake --map concentric`) loses nothing (0.01 %), and its
    /// rejection mode wastes less under a sharp lobe too (phong n = 1000 about 1.03 against
    /// 1.2); its warp proxy is coarser where a lobe is sharp (at the benches' wi, phong
    /// n = 1000's warp variance is 1.6× the orthographic bake's, Cook–Torrance m = 0.1's and
    /// Ward α = 0.05's 1.05× and 1.01×).
    Warp,
}

impl BakedMode {
    /// The CLI name (`rejection`, `warp`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Rejection => "rejection",
            Self::Warp => "warp",
        }
    }
}

/// One grid tree of a query's mixture ([`BakedSampler::mixture_at`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MixtureTree {
    /// The tree's θi, degrees.
    pub theta_deg: f64,
    /// The tree's φi, degrees (0 for an isotropic grid).
    pub phi_deg: f64,
    /// Its weight in the mixture.
    pub weight: f64,
}

/// How a [`BakedSampler`] is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BakeConfig {
    /// Each grid tree's build options (map, split rule, target trials, ...).
    pub build: BuildConfig,
    /// Rows of trees in θi, from 0° to [`GRID_THETA_MAX_DEG`] inclusive (≥ 2).
    pub theta_steps: u16,
    /// Columns of trees in φi over the folded φ range, for anisotropic models (≥ 2 on an
    /// interval, ≥ 3 on the full circle); ignored for isotropic ones.
    pub phi_steps: u16,
    /// The defensive cosine share δ ∈ (0, 1) of the mixture.
    pub defensive: f64,
    /// The most bytes the bake may hold ([`BakedSampler::bytes`]), in 1 ..=
    /// [`MAX_BAKE_BYTES`]; `None` (the default): the model's default by its symmetry,
    /// [`DEFAULT_ISOTROPIC_BAKE_MAX_BYTES`] (1 MiB) for an isotropic model,
    /// [`DEFAULT_BAKE_MAX_BYTES`] (16 MiB) for an anisotropic one ([`BakeConfig::max_bytes_for`];
    /// a baked sampler's [`BakedSampler::config`] holds the limit it was baked to). A bake whose trees,
    /// built as `build` asks, would hold more has trees pruned back: of the trees over
    /// their even share, the subdivisions that save the fewest rejection trials are
    /// collapsed first, across all of them, until the bake fits (trees under their share
    /// are kept as they are): exact still, with more rejection trials (and a coarser warp
    /// proxy) in the pruned trees. A grid whose trees cannot fit even so, each within
    /// [`crate::MAX_USABLE_EXPECTED_TRIALS`], is [`BakeError::TooLarge`].
    pub max_bytes: Option<usize>,
}

impl BakeConfig {
    /// The memory limit a bake of a model with this isotropy is held to: `max_bytes`, or
    /// its default ([`BakeConfig::max_bytes`]).
    #[must_use]
    pub fn max_bytes_for(&self, isotropic: bool) -> usize {
        self.max_bytes.unwrap_or(if isotropic {
            DEFAULT_ISOTROPIC_BAKE_MAX_BYTES
        } else {
            DEFAULT_BAKE_MAX_BYTES
        })
    }
}

impl Default for BakeConfig {
    fn default() -> Self {
        Self {
            build: BuildConfig {
                node_budget: DEFAULT_BAKE_NODE_BUDGET,
                ..BuildConfig::default()
            },
            theta_steps: DEFAULT_THETA_STEPS,
            phi_steps: DEFAULT_PHI_STEPS,
            defensive: DEFAULT_DEFENSIVE,
            max_bytes: None,
        }
    }
}

/// One grid tree: its direction, rejection layout and warp proxy. Laid out for a sample's
/// loads (each grid tree a sample meets is another one): the warp table's pointers in the
/// first cache line, what the mixture reads of the tree (direction, liveness, map, scales) in
/// the next, the rejection layout after.
#[derive(Clone, Debug, PartialEq)]
#[repr(C, align(64))]
pub(crate) struct Slice {
    pub(crate) warp: WarpTable,
    /// The incident direction the tree was built for (unit f32, as the tree saw it).
    pub(crate) wi: Vec3,
    /// Its mirror direction r(wi), unit in f64: where an anisotropic query's rotation
    /// starts (derived, like the scales).
    pub(crate) mirror: DVec3,
    /// Whether the tree has volume (a mixture skips a neighbour without).
    pub(crate) live: bool,
    /// The tree's square ↔ hemisphere map.
    pub(crate) map: DiskMap,
    /// J: the warp density per unit solid angle is the table's (per square area)·cos θ·this.
    pub(crate) warp_scale: f64,
    /// J/V: the rejection density per unit solid angle is Y(f)·cos θ·this.
    pub(crate) rejection_scale: f64,
    pub(crate) tree: PackedTree,
}

impl Slice {
    /// The slice of `table`'s tree at `wi`, and the build's tree itself when the slice holds
    /// more than `keep_over` bytes (for [`Slice::pruned`]).
    fn build(
        table: &dyn Brdf,
        wi: Vec3,
        config: BuildConfig,
        keep_over: usize,
    ) -> Result<(Self, Option<Quadtree>), BuildError> {
        let q = Quadtree::from_unit(table, wi, config)?;
        let s = Self::of_tree(table, wi, &q);
        let keep = s.bytes() > keep_over;
        Ok((s, keep.then_some(q)))
    }

    /// The slice of a built tree: its packed layout and its warp, the warp's shapes fitted to
    /// `table` at `wi`.
    fn of_tree(table: &dyn Brdf, wi: Vec3, q: &Quadtree) -> Self {
        let mut warp = WarpTable::new(q);
        warp.fit_shapes(
            q.map(),
            |w| f64::from(brdf_core::geometry::luminance(table.eval(wi, w.as_vec3()))),
            true,
        );
        Self::new(wi, PackedTree::new(q), warp)
    }

    /// The bytes the slice of `q` holds ([`Slice::bytes`]), from its layouts alone: the
    /// warp's shapes, which need the model, live in its nodes and add nothing.
    fn bytes_of(q: &Quadtree) -> usize {
        PackedTree::new(q).stats().bytes + WarpTable::new(q).bytes() + core::mem::size_of::<Self>()
    }

    /// A slice from its parts (a bake's, or a file's), with its pdf scales.
    pub(crate) fn new(wi: Vec3, tree: PackedTree, warp: WarpTable) -> Self {
        let map = tree.map();
        let j = f64::from(map.square_area_per_projected_solid_angle());
        let v = tree.volume();
        let w = wi.as_dvec3();
        Self {
            warp,
            wi,
            mirror: DVec3::new(-w.x, -w.y, w.z).normalize(),
            live: v > 0.0,
            map,
            warp_scale: j,
            rejection_scale: if v > 0.0 { j / v } else { 0.0 },
            tree,
        }
    }

    fn bytes(&self) -> usize {
        // The packed tree's own count: its nodes, rim boxes and selection guide.
        self.tree.stats().bytes + self.warp.bytes() + core::mem::size_of::<Self>()
    }
}

/// f*(a, b) = f_r(b, a): the model a non-reciprocal material's [`Role::Radiance`] trees are
/// built from.
#[derive(Debug)]
pub(crate) struct Adjoint<'a>(pub(crate) &'a dyn Brdf);

impl Brdf for Adjoint<'_> {
    fn name(&self) -> &'static str {
        self.0.name()
    }
    fn params(&self) -> ParamSet {
        self.0.params()
    }
    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        self.0.eval(wo, wi)
    }
    fn peak_hints(&self, wi: Vec3) -> PeakHints {
        self.0.peak_hints(wi)
    }
    fn integration_tolerance(&self) -> f64 {
        self.0.integration_tolerance()
    }
    fn step_width(&self) -> Option<f64> {
        self.0.step_width()
    }
    fn symmetry(&self) -> Symmetry {
        Symmetry {
            reciprocal: false,
            ..self.0.symmetry()
        }
    }
}

/// The trees of one transport direction.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Tables {
    pub(crate) slices: Vec<Slice>,
    /// The cells a rejection-mode query answers with its nearest tree (measured by
    /// `baked_nearest` at the bake, recorded in the bake file; warp mode blends everywhere).
    pub(crate) nearest: Nearest,
}

/// A model's sampler at every incident direction, baked once (see the module doc): exact
/// pdf at any (wi, wo), both transport roles, rejection or warp mode. Owns its model, is
/// `Send + Sync + 'static`: share one per material across threads.
///
/// ```
/// use brdf_core::registry;
/// use quadtree_sampler::{BakeConfig, BakedSampler};
/// use glam::{Vec2, Vec3};
/// use rand_core::SeedableRng;
///
/// let phong = registry::create("phong", ["n=300"]).unwrap();
/// let config = BakeConfig { theta_steps: 8, ..BakeConfig::default() };
/// let baked = BakedSampler::new(phong.into(), config).unwrap();
/// let wi = Vec3::new(0.31, 0.2, 0.93).normalize(); // any wi, on the grid or not
/// let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
/// let s = baked.sample(wi, 0.3, Vec2::new(0.6, 0.2), &mut rng).unwrap().expect("a direction");
/// assert!((s.pdf - baked.pdf(wi, s.wo).unwrap()).abs() <= 1e-5 * s.pdf);
/// ```
#[derive(Debug)]
pub struct BakedSampler {
    pub(crate) brdf: Arc<dyn Brdf>,
    pub(crate) config: BakeConfig,
    pub(crate) grid: BakeGrid,
    pub(crate) forward: Tables,
    /// The adjoint's trees, for a non-reciprocal model's [`Role::Radiance`].
    pub(crate) adjoint: Option<Tables>,
    pub(crate) mode: BakedMode,
    pub(crate) violations: AtomicU64,
    pub(crate) gave_up: AtomicU64,
    /// The delta lobe's choice probability over cos θ of the given direction (see
    /// [`DeltaShare`]); `None` for a model without a delta part or an anisotropic one.
    delta_share: Option<DeltaShare>,
    /// Whether an anisotropic grid's neighbours reach a query by the half-vector transport
    /// (`baked_mixture::HalfMap`; bakes of this library and files of format version 8 on)
    /// rather than by rotations onto its mirror direction (files of versions 5–7, which
    /// sample as they did). Isotropic grids always rotate.
    pub(crate) half_vector: bool,
    /// Whether the model declares f_r independent of wi ([`Brdf::independent_of_incident`]):
    /// the forward trees then all hold the same density, and the first answers every query
    /// as it is (`BakedSampler::components`).
    pub(crate) one_tree: bool,
}

/// The probability with which a baked sampler chooses the model's Dirac lobe, tabulated in
/// cos θ for an isotropic model with a delta part. The choice may be any function of the
/// given direction that `sample_as` and `pdf_as` share: the delta sample's weight R/p and
/// the continuous pdf's factor 1 − p are exact for whichever p is used. The model's own
/// [`Brdf::delta_probability`] (the luminance share) is what the table holds at its nodes;
/// He–Torrance's costs a specular reflectance, 130–170 ns a call, where the table is a load
/// and a lerp. Where the table says 0 the model is asked (a delta lobe that lives only
/// between two nodes is never starved): p > 0 wherever the model's p is.
#[derive(Clone, Debug)]
pub(crate) struct DeltaShare(Vec<f32>);

impl DeltaShare {
    /// Intervals of cos θ ∈ [0, 1].
    const INTERVALS: usize = 1024;

    /// The table of `brdf` (isotropic), or `None` where its delta probability is 0 at
    /// every node (no delta part: asking the model then costs what the table would).
    fn new(brdf: &dyn Brdf) -> Option<Self> {
        if !brdf.symmetry().isotropic {
            return None;
        }
        let n = Self::INTERVALS;
        let p: Vec<f32> = (0..=n)
            .map(|i| {
                // cos θ = i/n in the xz-plane; the horizon node asks just above it.
                let z = (i as f64 / n as f64).max(1e-7);
                let w = DVec3::new(brdf_core::math::sqrt((1.0 - z) * (1.0 + z)), 0.0, z);
                brdf.delta_probability(w.as_vec3())
            })
            .collect();
        p.iter().any(|&v| v > 0.0).then_some(Self(p))
    }

    /// The choice probability at a checked unit `given`.
    #[inline]
    fn at(&self, brdf: &dyn Brdf, given: Vec3) -> f32 {
        let t = given.z.clamp(0.0, 1.0) * Self::INTERVALS as f32;
        let i = (t as usize).min(Self::INTERVALS - 1);
        let f = t - i as f32;
        let p = self.0[i] + f * (self.0[i + 1] - self.0[i]);
        if p > 0.0 {
            p
        } else {
            brdf.delta_probability(given)
        }
    }
}

/// `f` over `jobs`, in parallel with rayon when `parallel` (and the feature) is on: the
/// same results in the same order either way.
fn run_jobs<J: Send, T: Send>(
    jobs: Vec<J>,
    parallel: bool,
    f: impl Fn(J) -> T + Sync + Send,
) -> Vec<T> {
    #[cfg(feature = "rayon")]
    if parallel {
        use rayon::prelude::*;
        return jobs.into_par_iter().map(f).collect();
    }
    let _ = parallel;
    jobs.into_iter().map(f).collect()
}

impl BakedSampler {
    /// Bakes `brdf` (any model with a continuous part): a tree per grid direction, built in
    /// parallel with rayon when the `rayon` feature is on and `config.build.parallel` is set
    /// (bit-identical to the serial bake).
    pub fn new(brdf: Arc<dyn Brdf>, config: BakeConfig) -> Result<Self, BakeError> {
        Self::new_with_progress(brdf, config, &|_, _| {})
    }

    /// [`BakedSampler::new`], calling `progress(done, total)` as trees finish (from any
    /// thread, in any order).
    pub fn new_with_progress(
        brdf: Arc<dyn Brdf>,
        config: BakeConfig,
        progress: &(dyn Fn(usize, usize) + Sync),
    ) -> Result<Self, BakeError> {
        Self::bake(brdf, config, progress, MAX_BAKE_BYTES)
    }

    /// The bake behind [`BakedSampler::new_with_progress`], its trees' first builds stopped
    /// once they hold more than `hard_limit` bytes ([`MAX_BAKE_BYTES`]; a test sets less):
    /// the guard against a grid that would take the machine's memory, apart from
    /// [`BakeConfig::max_bytes`], which prunes.
    fn bake(
        brdf: Arc<dyn Brdf>,
        config: BakeConfig,
        progress: &(dyn Fn(usize, usize) + Sync),
        hard_limit: usize,
    ) -> Result<Self, BakeError> {
        let hard = hard_limit.min(MAX_BAKE_BYTES);
        if !(config.defensive > 0.0 && config.defensive < 1.0) {
            return Err(BakeError::Defensive(config.defensive));
        }
        if brdf.is_delta() {
            return Err(BakeError::DeltaModel(brdf.name()));
        }
        config.build.validate().map_err(|source| BakeError::Tree {
            theta_deg: 0.0,
            phi_deg: 0.0,
            source,
        })?;
        let symmetry = brdf.symmetry();
        let grid = BakeGrid::new(symmetry, config.theta_steps, config.phi_steps)?;
        let adjoint_model = Adjoint(&*brdf);
        let mut jobs: Vec<(bool, usize)> = (0..grid.len()).map(|k| (false, k)).collect();
        if !symmetry.reciprocal {
            jobs.extend((0..grid.len()).map(|k| (true, k)));
        }
        let total = jobs.len();
        let max_bytes = config.max_bytes_for(symmetry.isotropic);
        if !(1..=MAX_BAKE_BYTES).contains(&max_bytes) {
            return Err(BakeError::MaxBytes(max_bytes));
        }
        // The sampler keeps the limit it was baked to (and its file records it).
        let config = BakeConfig {
            max_bytes: Some(max_bytes),
            ..config
        };
        // What the trees may hold: the limit less the sampler's own struct.
        let room = max_bytes.saturating_sub(core::mem::size_of::<Self>());
        let too_large = BakeError::TooLarge {
            trees: total,
            limit: max_bytes,
        };
        // The first build of each tree: within FIRST_BUILD_SHARES of its even share of the
        // room (at the least bytes a node can take, and never under MIN_FIRST_NODES), so
        // that a needle lobe's trees stop early rather than grow to the node budget and be
        // pruned from there.
        let share = room / total.max(1);
        let first = BuildConfig {
            node_budget: config.build.node_budget.min(
                u32::try_from(FIRST_BUILD_SHARES * share / MIN_NODE_BYTES)
                    .unwrap_or(u32::MAX)
                    .max(MIN_FIRST_NODES),
            ),
            ..config.build
        };
        let done = AtomicU64::new(0);
        // Bytes the finished trees hold. Once past the hard limit every tree not yet built
        // fails at once; the error names the whole grid, so it is the same whichever trees
        // finished first (serial and parallel bakes still agree).
        let held = AtomicU64::new(0);
        let over_hard = BakeError::TooLarge {
            trees: total,
            limit: hard,
        };
        let model_of = |adj: bool| -> &dyn Brdf { if adj { &adjoint_model } else { &*brdf } };
        let grid_ref = &grid;
        let tree_error = |k: usize| {
            move |source| {
                let (theta_deg, phi_deg) = grid_ref.angles_deg(k);
                BakeError::Tree {
                    theta_deg,
                    phi_deg,
                    source,
                }
            }
        };
        let build = |&(adj, k): &(bool, usize)| {
            if held.load(Ordering::Relaxed) > hard as u64 {
                return Err(over_hard.clone());
            }
            // A tree over its even share may be over the cut below: its build is kept.
            let r = Slice::build(model_of(adj), grid.direction(k), first, share)
                .map_err(tree_error(k))
                .and_then(|(s, q)| {
                    let bytes = s.bytes() as u64;
                    if held.fetch_add(bytes, Ordering::Relaxed) + bytes > hard as u64 {
                        Err(over_hard.clone())
                    } else {
                        Ok((s, q))
                    }
                });
            let d = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(d as usize, total);
            r
        };
        let built = run_jobs(jobs.iter().collect(), config.build.parallel, build)
            .into_iter()
            .collect::<Result<Vec<_>, _>>()?;
        // Over the room: the trees over their even share give up the nodes that save the
        // fewest trials, across all of them, until the bake fits (see `bake_budget`).
        let bytes: Vec<usize> = built.iter().map(|(s, _)| s.bytes()).collect();
        let mut slices = if bytes.iter().sum::<usize>() > room {
            let prunable: Vec<(usize, &Quadtree)> = built
                .iter()
                .enumerate()
                .filter_map(|(j, (_, q))| q.as_ref().map(|q| (j, q)))
                .collect();
            let fixed: usize = built
                .iter()
                .zip(&bytes)
                .filter(|((_, q), _)| q.is_none())
                .map(|(_, b)| b)
                .sum();
            let orders = run_jobs(prunable.clone(), config.build.parallel, |(_, q)| {
                Prunable::new(q)
            });
            let pruned = |q: &Quadtree, p: &Prunable, k: usize| {
                let mut q = q.clone();
                q.collapse(&p.order[..k]);
                q
            };
            let counts = bake_budget::plan(&orders, |counts| {
                let work = prunable.iter().zip(&orders).zip(counts).collect();
                let sizes = run_jobs(work, config.build.parallel, |(((j, q), p), &k)| {
                    if k == 0 {
                        bytes[*j]
                    } else {
                        Slice::bytes_of(&pruned(q, p, k))
                    }
                });
                fixed + sizes.iter().sum::<usize>() <= room
            })
            .ok_or_else(|| too_large.clone())?;
            // Each kept tree's collapses to take, by grid index (none for the others).
            let mut take: Vec<Option<(Prunable, usize)>> = built.iter().map(|_| None).collect();
            for (((j, _), p), k) in prunable.iter().zip(orders).zip(counts) {
                take[*j] = (k > 0).then_some((p, k));
            }
            let work = built.into_iter().zip(take).enumerate().collect();
            run_jobs(work, config.build.parallel, |(j, ((s, q), take))| {
                match (q, take) {
                    (Some(mut q), Some((p, k))) => {
                        q.collapse(&p.order[..k]);
                        let (adj, k) = jobs[j];
                        Slice::of_tree(model_of(adj), grid.direction(k), &q)
                    }
                    _ => s,
                }
            })
        } else {
            built.into_iter().map(|(s, _)| s).collect()
        };
        if slices.iter().map(Slice::bytes).sum::<usize>() > room {
            return Err(too_large);
        }
        let tables = |slices: Vec<Slice>, adjoint: bool| {
            let eval = |wi: Vec3, w: Vec3| {
                if adjoint {
                    brdf.eval(w, wi)
                } else {
                    brdf.eval(wi, w)
                }
            };
            let nearest = crate::baked_nearest::measure(
                &grid,
                &slices,
                &eval,
                config.defensive,
                config.build.parallel,
                !symmetry.isotropic,
            );
            Tables { slices, nearest }
        };
        let adjoint = (!symmetry.reciprocal).then(|| tables(slices.split_off(grid.len()), true));
        let forward = tables(slices, false);
        Ok(Self::from_parts(
            brdf,
            config,
            grid,
            forward,
            adjoint,
            !symmetry.isotropic,
        ))
    }

    pub(crate) fn from_parts(
        brdf: Arc<dyn Brdf>,
        config: BakeConfig,
        grid: BakeGrid,
        forward: Tables,
        adjoint: Option<Tables>,
        half_vector: bool,
    ) -> Self {
        Self {
            half_vector,
            one_tree: brdf.independent_of_incident(),
            delta_share: DeltaShare::new(&*brdf),
            brdf,
            config,
            grid,
            forward,
            adjoint,
            mode: BakedMode::default(),
            violations: AtomicU64::new(0),
            gave_up: AtomicU64::new(0),
        }
    }

    /// The probability of choosing the model's delta lobe at a checked unit `given` (see
    /// [`DeltaShare`]): the one expression `sample_as` and `pdf_as` share.
    #[inline]
    pub(crate) fn delta_probability(&self, given: Vec3) -> f32 {
        match &self.delta_share {
            Some(table) => table.at(&*self.brdf, given),
            None => self.brdf.delta_probability(given),
        }
    }

    pub(crate) fn tables(&self) -> (&Tables, Option<&Tables>) {
        (&self.forward, self.adjoint.as_ref())
    }

    /// The same sampler in another mode (the tables serve both).
    #[must_use]
    pub fn with_mode(mut self, mode: BakedMode) -> Self {
        self.mode = mode;
        self
    }

    /// Switches the mode in place.
    pub fn set_mode(&mut self, mode: BakedMode) {
        self.mode = mode;
    }

    /// The mode `sample` uses.
    #[must_use]
    pub fn mode(&self) -> BakedMode {
        self.mode
    }

    /// The model.
    #[must_use]
    pub fn brdf(&self) -> &Arc<dyn Brdf> {
        &self.brdf
    }

    /// The bake's options (`max_bytes` set to the limit it was baked to).
    #[must_use]
    pub fn config(&self) -> &BakeConfig {
        &self.config
    }

    /// The memory limit the sampler was baked to ([`BakeConfig::max_bytes`], resolved by
    /// the model's symmetry where it was left to its default): [`BakedSampler::bytes`] is at
    /// most this.
    #[must_use]
    pub fn max_bytes(&self) -> usize {
        self.config.max_bytes_for(self.brdf.symmetry().isotropic)
    }

    /// The grid of incident directions.
    #[must_use]
    pub fn grid(&self) -> &BakeGrid {
        &self.grid
    }

    /// Number of trees (twice the grid for a non-reciprocal model: its adjoint's too).
    #[must_use]
    pub fn trees(&self) -> usize {
        self.forward.slices.len() + self.adjoint.as_ref().map_or(0, |t| t.slices.len())
    }

    /// Nodes over all trees.
    #[must_use]
    pub fn nodes(&self) -> usize {
        self.all_slices().map(|s| s.tree.nodes().len()).sum()
    }

    /// Bytes held: both layouts of every tree and their headers.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.all_slices().map(Slice::bytes).sum::<usize>() + core::mem::size_of::<Self>()
    }

    /// How many of the trees (the adjoint's too) a budget stopped: the node or evaluation
    /// budget of [`BakeConfig::build`] ran out before the seed's rule (or the target E\[T\])
    /// was met, so those trees sample exactly but with more trials than asked for.
    #[must_use]
    pub fn budget_stopped_trees(&self) -> usize {
        self.all_slices()
            .filter(|s| s.tree.stats().budget_exhausted)
            .count()
    }

    /// The largest E\[T\] of any tree, the adjoint's included (0 for a bake of no trees).
    #[must_use]
    pub fn max_expected_trials(&self) -> f64 {
        self.all_slices()
            .map(|s| s.tree.stats().expected_trials)
            .fold(0.0, f64::max)
    }

    /// E\[T\] of each forward grid tree (row-major, as [`BakeGrid::direction`]).
    #[must_use]
    pub fn expected_trials(&self) -> Vec<f64> {
        self.forward
            .slices
            .iter()
            .map(|s| s.tree.stats().expected_trials)
            .collect()
    }

    fn all_slices(&self) -> impl Iterator<Item = &Slice> {
        self.forward
            .slices
            .iter()
            .chain(self.adjoint.iter().flat_map(|t| t.slices.iter()))
    }

    /// The grid trees a query answers with at `given` for a role, in the current mode: each
    /// tree's (θi, φi) in degrees and its weight in the mixture (summing to 1; the defensive
    /// share aside). One tree, the first, for a model whose f_r does not depend on wi
    /// ([`Brdf::independent_of_incident`]); one tree in a cell the bake found its neighbours
    /// agree in (see [`BakedSampler::nearest_cells`]); else the two (isotropic) or up to
    /// three trees around (the corners of the triangle of its grid cell that holds it).
    pub fn mixture_at(&self, role: Role, given: Vec3) -> Result<Vec<MixtureTree>, BakedError> {
        let given = brdf_core::geometry::unit_direction_above(given)?;
        let (tables, _) = self.tables_for(role);
        let mut comps = crate::baked_mixture::Components::new();
        let n = self.components(self.mode, tables, given, &mut comps);
        Ok(comps[..n]
            .iter()
            .map(|c| {
                let (theta_deg, phi_deg) = self.grid.angles_deg(c.slice);
                MixtureTree {
                    theta_deg,
                    phi_deg,
                    weight: c.weight,
                }
            })
            .collect())
    }

    /// How many of the grid's cells a query in `mode` answers with one tree along θ (every
    /// cell of an isotropic grid that does has one tree), and how many cells there are, over
    /// the forward trees. Measured at the bake, rejection mode only: a cell snaps where its
    /// corner trees, rotated onto each other's mirror directions, sample each other's exact
    /// densities within [`crate::NEAREST_REJECTION_EXCESS`] (χ²) and
    /// [`crate::NEAREST_MAX_RATIO`] (the largest ratio of the densities). Warp mode: none.
    /// A model independent of wi ([`Brdf::independent_of_incident`]) is answered by one tree
    /// in every cell, in both modes.
    #[must_use]
    pub fn nearest_cells(&self, mode: BakedMode) -> (usize, usize) {
        let cells = self.grid.cells();
        let snapped = match mode {
            _ if self.one_tree => cells,
            BakedMode::Rejection => self.forward.nearest.theta.iter().filter(|&&b| b).count(),
            BakedMode::Warp => 0,
        };
        (snapped, cells)
    }

    /// Test-only: blends the neighbours of every cell again (linear weights everywhere), as
    /// before nearest-tree cells were measured; still an exact mixture. For negative
    /// controls that need two neighbours at a wi. Not for production.
    #[doc(hidden)]
    pub fn blend_everywhere_for_testing(&mut self) {
        for t in core::iter::once(&mut self.forward).chain(self.adjoint.as_mut()) {
            t.nearest = Default::default();
        }
    }

    /// Test-only: an anisotropic grid's neighbours reach a query by rotations onto its
    /// mirror direction, as bake files before format version 8 do, instead of the half-vector
    /// transport (still an exact mixture; its nearest-tree cells stay as measured). For
    /// comparisons and negative controls. Not for production.
    #[doc(hidden)]
    pub fn rotate_neighbours_for_testing(&mut self) {
        self.half_vector = false;
    }

    /// How many rejection trials met f > M (should stay 0).
    #[must_use]
    pub fn bound_violations(&self) -> u64 {
        self.violations.load(Ordering::Relaxed)
    }

    /// How many rejection samples gave up after [`crate::MAX_TRIALS`] trials.
    #[must_use]
    pub fn gave_up(&self) -> u64 {
        self.gave_up.load(Ordering::Relaxed)
    }

    /// Draws the sampled direction of the continuous part for a role, given the other one
    /// (local frame, checked: finite, non-zero, above the horizon). `uc` chooses the
    /// defensive part or a neighbour tree, `u` drives the tree (rejection: its descent, with
    /// u.y refining u.x; warp: the whole warp), `rng` draws the rejection trials (warp mode
    /// draws nothing from it). `Ok(None)` when the drawn direction carries nothing (rotated
    /// below the horizon, or the rejection loop gave up): the estimator scores 0. The
    /// sample's `pdf` is [`BakedSampler::pdf_continuous_as`] at the returned direction, **per
    /// unit solid angle**; `f` is f_r (the role's argument order), `weight` = f·cos/pdf.
    pub fn sample_continuous_as<R: Rng + ?Sized>(
        &self,
        role: Role,
        given: Vec3,
        uc: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Result<Option<Sample>, BakedError> {
        let given = brdf_core::geometry::unit_direction_above(given)?;
        Ok(self.sample_unit(role, given, uc, u, rng))
    }

    /// The density of [`BakedSampler::sample_continuous_as`]: of `sampled` given `given`,
    /// **per unit solid angle** (0 for `sampled` below the horizon).
    pub fn pdf_continuous_as(
        &self,
        role: Role,
        given: Vec3,
        sampled: Vec3,
    ) -> Result<f32, BakedError> {
        let given = brdf_core::geometry::unit_direction_above(given)?;
        brdf_core::geometry::unit_direction(sampled)?;
        Ok(self.pdf_unit(role, given, sampled))
    }

    /// The whole model for a role: with the model's delta probability (at the given
    /// direction) its Dirac lobe toward the mirror direction (a delta sample), otherwise the
    /// continuous part with `uc` rescaled, its pdf scaled by the probability of having chosen
    /// it. See [`BakedSampler::sample_continuous_as`].
    pub fn sample_as<R: Rng + ?Sized>(
        &self,
        role: Role,
        given: Vec3,
        uc: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Result<Option<Sample>, BakedError> {
        let given = brdf_core::geometry::unit_direction_above(given)?;
        let p = self.delta_probability(given);
        Ok(self.whole_sample(given, p, uc, |uc| self.sample_unit(role, given, uc, u, rng)))
    }

    /// The whole model's draw at a checked `given` whose delta probability is `p`: the
    /// Dirac lobe when `uc` < p, else `continuous` (the continuous part's draw) with `uc`
    /// rescaled to [0, 1), its pdf times 1 − p. The one expression behind
    /// [`BakedSampler::sample_as`] and [`BakedPoint::sample`].
    #[inline(always)]
    pub(crate) fn whole_sample(
        &self,
        given: Vec3,
        p: f32,
        uc: f32,
        continuous: impl FnOnce(f32) -> Option<Sample>,
    ) -> Option<Sample> {
        if p <= 0.0 {
            return continuous(uc);
        }
        if uc < p {
            return BrdfSample::delta(mirror(given), self.brdf.delta_reflectance(given), p);
        }
        let uc = ((uc - p) / (1.0 - p)).min(1.0 - f32::EPSILON / 2.0);
        continuous(uc).map(|s| s.with_pdf(s.pdf * (1.0 - p)))
    }

    /// The sampler prepared at one given direction for a role (local frame; finite,
    /// non-zero, above the horizon, else a typed error): what a path vertex asks of its
    /// material, a sample, then f_r and the pdf at a light sample's direction, all at the
    /// same given direction, answered without finding that direction's neighbour trees and
    /// their maps again for each call. Its answers are bit-identical to
    /// [`BakedSampler::sample_as`], [`BakedSampler::pdf_as`] and [`BakedSampler::eval_as`]
    /// at the same direction (a test says so), in the mode the sampler has now (the borrow
    /// keeps it so).
    // Inlined with `query`: the point is then built in its caller's frame, not copied there.
    #[inline(always)]
    pub fn point(&self, role: Role, given: Vec3) -> Result<BakedPoint<'_>, BakedError> {
        let given = brdf_core::geometry::unit_direction_above(given)?;
        Ok(BakedPoint {
            baked: self,
            delta: self.delta_probability(given),
            query: self.query(self.mode, role, given),
        })
    }

    /// The density with which [`BakedSampler::sample_as`] draws `sampled` as a continuous
    /// sample, **per unit solid angle**: (1 − delta probability) × the continuous pdf.
    pub fn pdf_as(&self, role: Role, given: Vec3, sampled: Vec3) -> Result<f32, BakedError> {
        let given = brdf_core::geometry::unit_direction_above(given)?;
        brdf_core::geometry::unit_direction(sampled)?;
        let p = self.delta_probability(given);
        Ok((1.0 - p) * self.pdf_unit(role, given, sampled))
    }

    /// f_r for a role (continuous part, RGB, 1/sr, no cosine): f_r(given, sampled) for
    /// [`Role::Importance`], f_r(sampled, given) for [`Role::Radiance`].
    pub fn eval_as(&self, role: Role, given: Vec3, sampled: Vec3) -> Result<Vec3, BakedError> {
        // The given direction as `sample_as` and `point` use it (checked and normalised), the
        // sampled one checked but as it is (the models renormalise in f64): a sample's `f`
        // and `eval` of the same f32 vectors are then bit-identical, whatever the given
        // vector's length. (With the given one as passed, a world-frame query's rotated
        // vector, unit only to rounding, gave an f one f32 ulp away from its sample's.)
        let given = brdf_core::geometry::unit_direction(given)?;
        brdf_core::geometry::unit_direction(sampled)?;
        Ok(self.eval_unit(role, given, sampled))
    }

    /// f_r and the pdf of `sampled` in one call (what MIS needs at a light sample).
    pub fn eval_pdf_as(
        &self,
        role: Role,
        given: Vec3,
        sampled: Vec3,
    ) -> Result<(Vec3, f32), BakedError> {
        Ok((
            self.eval_as(role, given, sampled)?,
            self.pdf_as(role, given, sampled)?,
        ))
    }

    /// [`BakedSampler::sample_as`] for SPEC §1's convention: `wo` given `wi`.
    pub fn sample<R: Rng + ?Sized>(
        &self,
        wi: Vec3,
        uc: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Result<Option<Sample>, BakedError> {
        self.sample_as(Role::Importance, wi, uc, u, rng)
    }

    /// [`BakedSampler::pdf_as`] of `wo` given `wi`, **per unit solid angle**.
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> Result<f32, BakedError> {
        self.pdf_as(Role::Importance, wi, wo)
    }

    /// f_r(wi, wo), the model's continuous part (RGB, 1/sr).
    pub fn eval(&self, wi: Vec3, wo: Vec3) -> Result<Vec3, BakedError> {
        self.eval_as(Role::Importance, wi, wo)
    }

    /// [`BakedSampler::sample_continuous_as`] for `wo` given `wi` (the delta lobe left out:
    /// what `brdf sample --baked` records).
    pub fn sample_continuous<R: Rng + ?Sized>(
        &self,
        wi: Vec3,
        uc: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Result<Option<Sample>, BakedError> {
        self.sample_continuous_as(Role::Importance, wi, uc, u, rng)
    }

    /// [`BakedSampler::pdf_continuous_as`] of `wo` given `wi`, **per unit solid angle**.
    pub fn pdf_continuous(&self, wi: Vec3, wo: Vec3) -> Result<f32, BakedError> {
        self.pdf_continuous_as(Role::Importance, wi, wo)
    }

    /// A [`crate::DirectionSampler`] of the continuous part at one fixed `wi` (for the
    /// validation harness and the CLI): draws uc, u and the trials from the RNG.
    pub fn at(&self, wi: Vec3) -> Result<BakedAt<'_>, BakedError> {
        Ok(BakedAt {
            baked: self,
            wi: brdf_core::geometry::unit_direction_above(wi)?,
        })
    }

    /// Test-only: drops neighbour `k`'s weight from the reported pdf while still sampling
    /// it (a negative control a validation must reject). Not for production.
    #[doc(hidden)]
    #[must_use]
    pub fn broken_pdf_for_testing(self: Arc<Self>) -> BrokenPdf {
        BrokenPdf(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::string::ToString;

    /// The tabled choice is positive wherever the model's is (so no delta lobe is starved)
    /// and close to it (the tabulation is what it says); a model without a delta part, or
    /// an anisotropic one, has no table.
    #[test]
    fn the_delta_share_follows_the_model() {
        for params in [
            &[][..],
            &["sigma0=0.0318", "tau=0.3"],
            &["sigma0=0.5", "tau=1"],
        ] {
            let htsg = brdf_core::registry::create("htsg", params.iter().copied()).unwrap();
            let table = DeltaShare::new(&*htsg).expect("htsg has a delta part");
            for k in 0..=20_000 {
                let theta = f64::from(k) / 20_000.0 * 0.4999 * core::f64::consts::PI;
                let w = DVec3::new(theta.sin(), 0.0, theta.cos()).as_vec3();
                for w in [w, Vec3::new(-w.x * 0.6, w.x * 0.8, w.z)] {
                    let (got, want) = (table.at(&*htsg, w), htsg.delta_probability(w));
                    assert!(
                        want <= 0.0 || got > 0.0,
                        "{params:?} θ {theta}: {got} vs {want}"
                    );
                    assert!(
                        (got - want).abs() < 0.01,
                        "{params:?} θ {theta}: {got} vs {want}"
                    );
                }
            }
        }
        for (name, params) in [
            ("phong", &[][..]),
            ("ward", &["alpha_x=0.1", "alpha_y=0.3"]),
        ] {
            let b = brdf_core::registry::create(name, params.iter().copied()).unwrap();
            assert!(DeltaShare::new(&*b).is_none(), "{name}");
        }
    }

    /// A grid whose trees pass the byte limit is a typed error, the same from the serial
    /// and the parallel bake; just under the limit the same grid bakes.
    #[test]
    fn a_bake_past_its_byte_limit_is_an_error() {
        let phong: Arc<dyn Brdf> = brdf_core::registry::create("phong", ["n=200"])
            .unwrap()
            .into();
        let config = |parallel| BakeConfig {
            theta_steps: 8,
            build: BuildConfig {
                parallel,
                ..BakeConfig::default().build
            },
            ..BakeConfig::default()
        };
        let whole = BakedSampler::new(phong.clone(), config(false)).unwrap();
        let bytes: usize = whole.all_slices().map(Slice::bytes).sum();
        for parallel in [false, true] {
            let err = BakedSampler::bake(phong.clone(), config(parallel), &|_, _| {}, bytes - 1)
                .unwrap_err();
            assert_eq!(
                err,
                BakeError::TooLarge {
                    trees: 8,
                    limit: bytes - 1
                }
            );
            assert!(err.to_string().contains("fewer θ or φ steps"), "{err}");
            let ok =
                BakedSampler::bake(phong.clone(), config(parallel), &|_, _| {}, bytes).unwrap();
            assert_eq!(ok.bytes(), whole.bytes());
        }
    }
}
