//! Node evaluation, the build's inner loop: each node's integral v1 by adaptive integration
//! continued from the cells its parent left ([`crate::integrate`]), its proposal and bound M
//! ([`crate::bound`]), and the build's budgets (evaluations, remembered cells). Pure
//! functions of a node's square and inherited cells, so levels evaluate in parallel.

use crate::bound::{EDGE_SEARCH_EVALS, Known, RIM_BAND_EVALS, RimProbe};
use crate::chart::{Chart, Rect};
use crate::config::{BuildConfig, IntegrationRule};
use crate::integrate::{Cell, Domain, Peak, UnitRule, refine_cells};
use crate::proposal::{Proposal, Shape};
use alloc::vec::Vec;
use brdf_core::{Brdf, DiskMap};
use core::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering as AtomicOrdering};
use glam::{DVec2, DVec3, Vec3};

/// A node's integration ([`Context::integrate_node`]).
pub(crate) enum Integrated {
    /// The node lies outside the disk: its whole (empty) evaluation.
    Outside(Evaluation),
    /// v1, the peak the integration met, and the cells it leaves for the children.
    Inside { v1: f64, peak: Peak, cell: Cell },
}

/// What a node's evaluation found.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Evaluation {
    pub(crate) v1: f64,
    pub(crate) bound: f64,
    pub(crate) box_bound: f64,
    pub(crate) proposal: Proposal,
}

/// A node tries a height shape's own bound search only where the fitted profile promises
/// at most this fraction of the flat box's volume. At 0.9, a one-leaf tree whose f leans
/// gently (Oren–Nayar at θ = 45°, concentric, whose promise lies between the two) kept its
/// flat box and E[T] 1.27, and target mode split it into five nodes for 1.14; at 0.97 it
/// keeps one shaped leaf (E[T] 1.17 with the coordinate-descent fit of the time). The
/// searches this adds cost little: in the 88-case table (11 models, both maps, θ = 0, 45,
/// 80, 89°) no build time moved beyond run-to-run noise.
pub(crate) const SHAPE_PROMISE: f64 = 0.97;

/// A node takes a fine height shape (bilinear in each quarter) rather than a bilinear one
/// only where it promises less than this fraction of the bilinear one's volume: a fine
/// trial costs a few ns more (its draw picks among sixteen hats). At 0.95, Ward α = 0.05
/// at the benches' wi took fine shapes for E[T] 1.098 → 1.080 and sampled 4 ns slower
/// (75 → 79 ns); at 0.85 it keeps its bilinear ones, and Cook–Torrance m = 0.1 and
/// He–Torrance keep their gains (E[T] 1.44 → 1.11 and 1.35 → 1.10).
pub(crate) const FINE_GAIN: f64 = 0.85;

/// The fine shape is fitted only where the bilinear one promises more than this fraction
/// of the flat volume.
pub(crate) const FINE_TRY: f64 = 0.7;

/// The flat polar box's bound from the square's bound `square` of the same node: the same
/// points with f times the chart's constant Jacobian ([`crate::chart::polar_jacobian`]),
/// rounded up to f32 (orthographic, ½: exact).
pub(crate) fn polar_bound(map: DiskMap, square: f64) -> f64 {
    f64::from(crate::bound::round_up_f32(
        crate::chart::polar_jacobian(map) * square,
    ))
}

/// Points of [`sampled_volume`]'s estimate (a 16 × 16 grid of strata of the model's own
/// sampler's square).
const SAMPLED_POINTS: u32 = 256;

/// A Monte Carlo estimate of the tree's total volume ∫ f_r dx dy over the square (`map`'s
/// measure: projected solid angle on the orthographic map, 4/π of it on the concentric
/// one), from the model's own continuous sampler at a fixed stratified set of uniforms
/// (deterministic). Unbiased wherever that sampler's pdf covers f_r; 0 where it draws
/// nothing. Only a scale for the integration's absolute floor: a factor of a few either way
/// moves nothing a test can see.
fn sampled_volume<B: Brdf + ?Sized>(brdf: &B, wi: Vec3, map: DiskMap) -> f64 {
    let side = 16;
    let mut sum = 0.0;
    for k in 0..SAMPLED_POINTS {
        let (i, j) = (k % side, k / side);
        let u = glam::Vec2::new(
            (i as f32 + 0.5) / side as f32,
            (j as f32 + 0.5) / side as f32,
        );
        // The lobe choice runs through its own strata, in an order unrelated to u's.
        let x = (f64::from(k) + 0.5) * 0.618_033_988_749_894_9;
        let uc = (x - (x as u64) as f64) as f32;
        let Some(s) = brdf.sample_continuous(wi, uc, u) else {
            continue;
        };
        let pdf = f64::from(s.pdf);
        let term = f64::from(brdf.eval_luminance(wi, s.wo)) * f64::from(s.wo.z) / pdf;
        if pdf > 0.0 && term.is_finite() && term > 0.0 {
            sum += term;
        }
    }
    sum / f64::from(SAMPLED_POINTS) * f64::from(map.square_area_per_projected_solid_angle())
}

/// The angular radii of [`hint_cap_volume`]'s caps about each peak hint: 0.1°, 1° and 10°.
const HINT_CAP_RADII: [f64; 3] = [
    0.001_745_329_251_994_33,
    0.017_453_292_519_943_3,
    0.174_532_925_199_432_9,
];

/// Points of [`hint_cap_volume`]'s estimate in each cap (an 8 × 8 grid of strata).
const HINT_CAP_POINTS: u32 = 64;

/// A lower estimate of the tree's total volume (`map`'s measure, as [`sampled_volume`]) from
/// the lobes where the model says f_r may peak: for each peak hint and each radius of
/// [`HINT_CAP_RADII`], ∫ f_r cos θ dω over the cap of that radius about the hint, by
/// stratified uniform points in the cap (deterministic); the largest of them. Each
/// estimates a part of the volume, so together they miss only what lies away from every
/// hint. For a needle on the root's centre that neither the root's rule points nor a model
/// without its own sampler (cosine points) see: HTSG σ0 = 0.05, τ = 100, whose 0.2° lobe at
/// normal incidence gave both estimates ~0 (10⁻³⁷), and with them no absolute floor, so
/// that every node on the lobe's flanks refined its integral to 10⁻⁶ of its own tiny value.
fn hint_cap_volume<B: Brdf + ?Sized>(brdf: &B, wi: Vec3, map: DiskMap) -> f64 {
    let side = 8;
    let mut best = 0.0f64;
    for h in brdf.peak_hints(wi).as_slice() {
        let axis = h.as_dvec3().normalize();
        let (b1, b2) = axis.any_orthonormal_pair();
        for rho in HINT_CAP_RADII {
            // 1 − cos ρ without cancellation, and the cap's solid angle.
            let s = brdf_core::math::sin(0.5 * rho);
            let depth = 2.0 * s * s;
            let solid_angle = core::f64::consts::TAU * depth;
            let mut sum = 0.0;
            for k in 0..HINT_CAP_POINTS {
                let (i, j) = (k % side, k / side);
                let (u, v) = (
                    (f64::from(i) + 0.5) / f64::from(side),
                    (f64::from(j) + 0.5) / f64::from(side),
                );
                // 1 − cos α uniform in [0, 1 − cos ρ]: uniform in solid angle over the cap.
                let t = u * depth;
                let sin_a = brdf_core::math::sqrt(t * (2.0 - t));
                let (sp, cp) = brdf_core::math::sin_cos(core::f64::consts::TAU * v);
                let w = (b1 * cp + b2 * sp) * sin_a + axis * (1.0 - t);
                if w.z <= 0.0 {
                    continue;
                }
                let term = f64::from(brdf.eval_luminance(wi, w.as_vec3())) * w.z;
                if term.is_finite() && term > 0.0 {
                    sum += term;
                }
            }
            best = best.max(sum / f64::from(HINT_CAP_POINTS) * solid_angle);
        }
    }
    best * f64::from(map.square_area_per_projected_solid_angle())
}

/// Integration cells the build may remember for the nodes still to split (88 bytes each:
/// 88 MiB). Past it, a new node keeps only the cells of its children's first rule
/// application, and past twice it none: the memoised cells only save work (a forgotten one
/// is recomputed bit for bit), so the tree does not depend on this, and the build's memory
/// stays below about 2 × 88 MiB plus 88 bytes per node.
pub(crate) const CELL_CACHE_LIMIT: usize = 1 << 20;

/// Parents split per batch of the breadth-first pass (between batches the evaluation budget
/// is checked).
pub(crate) const SPLIT_CHUNK: usize = 256;

/// Everything a node evaluation needs: pure, shared by the worker threads.
pub(crate) struct Context<'a, B: Brdf + ?Sized> {
    pub(crate) brdf: &'a B,
    pub(crate) wi: Vec3,
    pub(crate) config: BuildConfig,
    pub(crate) rule: UnitRule,
    /// The integration's domain: the map and f_r's crease on it, if any.
    pub(crate) domain: Domain,
    pub(crate) hints: Vec<DVec3>,
    /// Whether each bound search also looks along the lines of the disk through each hint
    /// parallel to the tangent axes (`bound::hint_line_points`): for an anisotropic model,
    /// whose lobes can be ridges along those lines. (An isotropic model has no preferred
    /// tangent axis.)
    pub(crate) hint_lines: bool,
    /// Absolute floor of every node's integration tolerance: the relative tolerance times an
    /// estimate of the total volume (a node's error below it cannot be seen by any test).
    pub(crate) tol_floor: f64,
    /// That estimate of the total volume: the root's adaptive integral to a relative 10⁻³
    /// (the waste cut-off's scale for what the look-ahead evaluates alongside the root).
    pub(crate) estimate: f64,
    /// Levels of each node's adaptive integration whose quadrants run in parallel.
    pub(crate) par_levels: u32,
    /// Integration cells remembered for the leaves (see [`CELL_CACHE_LIMIT`]).
    pub(crate) cached: AtomicUsize,
    /// Nodes a parallel build evaluated speculatively, adopted or not (set when the build
    /// ends; what the tests hold speculation to).
    pub(crate) speculated: AtomicUsize,
    /// Set where the evaluation budget stopped the build (at its decision points, which a
    /// parallel build meets as the serial one does: the retry in [`crate::Quadtree::new`]
    /// reads this, not the final count, which speculation may leave different).
    pub(crate) ran_out: AtomicBool,
    /// f_r evaluations spent so far (see [`BuildConfig::evaluation_budget`]).
    pub(crate) spent: AtomicU64,
    /// Evaluations per rule application (n² points; twice that where the angle chart
    /// splits a node into pieces, counted as its mean; the pieces a crease cuts are not
    /// counted: they are the few cells along one ring of each level).
    pub(crate) per_application: u64,
}

/// The base-2 logarithm of the smallest integration cell's side (the square is [−1, 1]²,
/// side 2¹): 2⁻²² ≈ 2.4·10⁻⁷, four f32 steps of a coordinate near 1
/// ([`Context::integration_depth`]).
pub(crate) const FINEST_CELL_LOG2: i32 = -22;

/// The loosest tolerance a model's [`Brdf::integration_tolerance`] may ask for: 10⁻³, the
/// relative noise of 10⁶ samples in one leaf (the default tolerance, 10⁻⁶, is that of 10¹²).
pub(crate) const MAX_MODEL_TOLERANCE: f64 = 1e-3;

impl<'a, B: Brdf + ?Sized> Context<'a, B> {
    /// The context, and the root's integration cells (the estimate of the total volume is an
    /// adaptive integration of the root, which the root's own evaluation then continues).
    pub(crate) fn new(brdf: &'a B, wi: Vec3, config: BuildConfig) -> (Self, Cell) {
        let rule = match config.rule {
            IntegrationRule::Midpoint { n } => UnitRule::midpoint(usize::from(n)),
            IntegrationRule::GaussLegendre { n } => UnitRule::new(usize::from(n)),
        };
        // The model's hints, for wi lifted to the grazing floor as its evaluation lifts it.
        let lifted = brdf_core::geometry::lift_incident(wi);
        let domain =
            Domain::new(config.map, brdf.crease_cosine(lifted)).with_step(brdf.step_width());
        let hints = brdf
            .peak_hints(lifted)
            .as_slice()
            .iter()
            .map(|h| h.as_dvec3().normalize())
            .collect();
        let mut ctx = Self {
            brdf,
            wi,
            config,
            rule,
            domain,
            hints,
            hint_lines: !brdf.symmetry().isotropic,
            tol_floor: 0.0,
            estimate: 0.0,
            // Every level: the work of a sharp lobe sits in one quadrant after another, so a
            // fixed number of top levels would leave one thread with all of it. A join that is
            // not stolen costs far less than the 4 × 36 evaluations of the cell it splits.
            par_levels: if cfg!(feature = "rayon") && config.parallel {
                u32::MAX
            } else {
                0
            },
            cached: AtomicUsize::new(0),
            speculated: AtomicUsize::new(0),
            ran_out: AtomicBool::new(false),
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
        let mut cell = Cell::once(ctx.domain, &root, &ctx.rule, &f);
        let tol = 1e-3 * cell.value.abs();
        let estimate = refine_cells(
            ctx.domain,
            &root,
            &mut cell,
            &ctx.rule,
            tol,
            6,
            &f,
            &mut Peak::default(),
            ctx.par_levels,
        );
        // The root's points can all miss a lobe narrower than their spacing (Ward αx = 0.1,
        // αy = 0.003 at θi = 60°, φi = 22.5°: its sheet passes between all 36 of them and
        // of its quadrants', so the estimate was exactly 0). With no floor, every node along
        // the sheet's flanks was then refined to relative 10⁻⁶ of its own tiny value, below
        // the noise of f evaluated at f32 directions, so to the full integration depth: 2 s
        // for a tree that takes 0.07 s at φi = 0°. The model's own sampler sees such a lobe;
        // where it finds over 1000× the adaptive estimate, it sets the scale instead (every
        // other build keeps the adaptive one, bit for bit).
        let sampled = sampled_volume(brdf, wi, config.map);
        let scale = if estimate.abs() >= 1e-3 * sampled {
            estimate.abs()
        } else {
            sampled
        };
        // Where the model's own sampler missed the lobe too (it draws cosine points when it
        // has none), the hints' caps may still see it; everywhere else their estimate of a
        // part of the volume stays below the scale, which keeps its bits.
        let scale = if estimate.abs() < 1e-3 * sampled || estimate == 0.0 {
            let caps = hint_cap_volume(brdf, wi, config.map);
            if scale >= 1e-3 * caps { scale } else { caps }
        } else {
            scale
        };
        ctx.tol_floor = ctx.tolerance() * 1e-2 * scale;
        ctx.estimate = scale;
        ctx.spend((1 + cell.applications(ctx.domain, &root, tol, 6)) * ctx.per_application);
        (ctx, cell)
    }

    /// The relative tolerance of each node's integration: the configured one, or the
    /// model's [`Brdf::integration_tolerance`] where that is larger, up to
    /// [`MAX_MODEL_TOLERANCE`] (a NaN or negative one is ignored).
    #[inline]
    pub(crate) fn tolerance(&self) -> f64 {
        let own = self.config.integration_tolerance;
        let model = self.brdf.integration_tolerance();
        if model > own {
            model.min(MAX_MODEL_TOLERANCE).max(own)
        } else {
            own
        }
    }

    /// f_r's luminance at a local direction (the density the tree follows).
    #[inline]
    pub(crate) fn f(&self, w: DVec3) -> f64 {
        f64::from(self.brdf.eval_luminance(self.wi, w.as_vec3()))
    }

    /// Evaluates the node `rect`, continuing from the integration cells `cells` its parent
    /// left for it; returns its own cells for its children.
    pub(crate) fn evaluate(&self, rect: &Rect, cells: Option<Cell>) -> (Evaluation, Option<Cell>) {
        let mut spent = 0;
        let r = self.evaluate_counted(rect, cells, &mut spent);
        self.spend(spent);
        r
    }

    /// [`Context::evaluate`], adding the evaluations it spends to `spent` instead of the
    /// build's count (a speculative evaluation is counted only when the build adopts it, so
    /// the budget's verdicts do not depend on what was speculated).
    pub(crate) fn evaluate_counted(
        &self,
        rect: &Rect,
        cells: Option<Cell>,
        spent: &mut u64,
    ) -> (Evaluation, Option<Cell>) {
        match self.integrate_node(rect, cells, spent) {
            Integrated::Outside(e) => (e, None),
            Integrated::Inside { v1, peak, cell } => {
                (self.bound_node(rect, v1, &peak, spent), Some(cell))
            }
        }
    }

    /// A node evaluation's first half: v1 by adaptive integration (continued from `cells`),
    /// with the peak it met and the cells it leaves for the children; adds its evaluations
    /// to `spent`. The children's own evaluations need nothing more from their parent, so
    /// they may run while [`Context::bound_node`] finishes the parent's.
    pub(crate) fn integrate_node(
        &self,
        rect: &Rect,
        cells: Option<Cell>,
        spent: &mut u64,
    ) -> Integrated {
        if self.config.map == DiskMap::Orthographic && rect.radius_range().0 >= 1.0 {
            return Integrated::Outside(Evaluation {
                v1: 0.0,
                bound: 0.0,
                box_bound: 0.0,
                proposal: Proposal::in_chart(rect, Chart::Square),
            });
        }
        let f = |w: DVec3| self.f(w);
        // One application of the rule sets the tolerance and is the refinement's start (the
        // node's points are integrated once, not twice; and not at all when the parent's
        // integration already applied the rule here).
        let mut cell = cells.unwrap_or_else(|| Cell::once(self.domain, rect, &self.rule, &f));
        let mut peak = cell.peak;
        let tol = (self.tolerance() * cell.value.abs()).max(self.tol_floor);
        let depth = self.integration_depth(rect);
        let v1 = refine_cells(
            self.domain,
            rect,
            &mut cell,
            &self.rule,
            tol,
            depth,
            &f,
            &mut peak,
            self.par_levels,
        )
        .max(0.0);
        // The node's integration as if nothing were memoised (so the count, and the budget's
        // verdict, do not depend on the cache).
        *spent += (1 + cell.applications(self.domain, rect, tol, depth)) * self.per_application;
        Integrated::Inside { v1, peak, cell }
    }

    /// The levels of adaptive integration below the node `rect`: the configured
    /// `integration_depth`, but no finer than cells of side 2^[`FINEST_CELL_LOG2`] (at least
    /// one level). f is evaluated at f32 directions, a few 10⁻⁸ apart: a finer cell holds a
    /// handful of distinct directions, and f there is a staircase whose steps the error
    /// estimate never sees converge. A sharp lobe at grazing incidence (Cook–Torrance
    /// m = 0.001 at cos θi = 0.006, concentric map) put depth-18 nodes (side 7.6·10⁻⁶) on it,
    /// each refined to all 8 levels everywhere: 3–9 million evaluations a node, the build
    /// stopped by its evaluation budget after 17 s with 217 nodes.
    pub(crate) fn integration_depth(&self, rect: &Rect) -> u32 {
        // The side is a power of two (dyadic squares): its exponent, read from its bits.
        let side = rect.max.x - rect.min.x;
        let exponent = ((side.to_bits() >> 52) & 0x7ff) as i32 - 1023;
        let room = (exponent - FINEST_CELL_LOG2).max(1) as u32;
        u32::from(self.config.integration_depth).min(room)
    }

    /// A node evaluation's second half: its proposal and bound M, from the v1 and peak of
    /// its integration ([`Context::integrate_node`]); adds its evaluations to `spent`.
    pub(crate) fn bound_node(
        &self,
        rect: &Rect,
        v1: f64,
        peak: &Peak,
        spent: &mut u64,
    ) -> Evaluation {
        let map = self.config.map;
        let square = Proposal::in_chart(rect, Chart::Square);
        let chart = Proposal::for_node(map, rect);
        // Each bound search's grid, hints and three compass searches of at most 400 steps.
        let g = u64::from(self.config.bound_grid) + 1;
        let search = g * g + 1200;
        *spent += search;
        let (chart_bound, chart_grid) =
            self.proposal_bound(&chart, rect, peak, v1, None, Known::default());
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
        let (flat, box_bound, flat_grid) = match rim {
            None | Some(RimProbe::Unbounded) => (chart, chart_bound, chart_grid),
            Some(RimProbe::Bounded(limit)) => {
                *spent += search;
                let (square_bound, square_grid) =
                    self.proposal_bound(&square, rect, peak, v1, Some(limit), Known::default());
                // The root and its children (orthographic) take the polar box in the
                // square's place: the same points, f·½, π/4 of the square's volume.
                let polar = Proposal::polar(rect).filter(|_| map == DiskMap::Orthographic);
                let (square, square_bound, square_grid) = match polar {
                    Some(polar) => (polar, polar_bound(map, square_bound), Vec::new()),
                    None => (square, square_bound, square_grid),
                };
                if square.area() * square_bound <= chart.area() * chart_bound {
                    (square, square_bound, square_grid)
                } else {
                    (chart, chart_bound, chart_grid)
                }
            }
        };
        // The square (or polar) box of a rim node must also bound f's limit at the rim.
        let rim_limit = match (rim, flat.chart) {
            (Some(RimProbe::Bounded(limit)), Chart::Square | Chart::Polar) => Some(limit),
            _ => None,
        };
        let (mut proposal, mut bound) = self.shaped(
            (flat, box_bound, flat_grid),
            rect,
            peak,
            v1,
            rim_limit,
            spent,
        );
        let mut box_bound = box_bound;
        // On the concentric map the polar box of the root or a child has the square's flat
        // volume (both cover the node's part of the disk exactly), but a shape over it follows
        // a radial profile, which one over the square cannot (the map's rings are squares);
        // a lean across the square goes the other way. Both are shaped; the smaller is kept
        // (ties to the square).
        if let (DiskMap::Concentric, Chart::Square, Some(polar)) =
            (map, flat.chart, Proposal::polar(rect))
        {
            let polar_box = polar_bound(map, box_bound);
            let (p, b) = self.shaped(
                (polar, polar_box, Vec::new()),
                rect,
                peak,
                v1,
                rim_limit,
                spent,
            );
            if p.volume(b) < proposal.volume(bound) {
                (proposal, bound, box_bound) = (p, b, polar_box);
            }
        }
        Evaluation {
            v1,
            bound,
            box_bound,
            proposal,
        }
    }

    /// The node's proposal with the height shape that samples it best ([`Shape`]): the flat
    /// box `flat` of bound `box_bound` (whose search evaluated `flat_grid`), unless the
    /// bound search's grid resolves the node (its largest height within 0.9 of the flat
    /// bound) and a bilinear profile fitted to it promises at most [`SHAPE_PROMISE`] of the
    /// flat volume there, and its own bound search (a grid twice as fine, the hints and a
    /// compass search, on h/S; and h/S along the rim where the flat box had to bound f's
    /// limit there, `rim_limit`) confirms a smaller volume.
    fn shaped(
        &self,
        (flat, box_bound, flat_grid): (Proposal, f64, Vec<(DVec2, f64)>),
        rect: &Rect,
        peak: &Peak,
        v1: f64,
        rim_limit: Option<f64>,
        spent: &mut u64,
    ) -> (Proposal, f64) {
        // Only the square and polar boxes. The rim charts (angle, sine) are chosen where f
        // grows without bound at the rim or climbs steeply just short of it, and their
        // Jacobians vanish there: f·J rises from 0 like a square root, which a linear profile
        // through the grid's rows undercuts between the rim and the first row. (An angle box
        // is also a curved sliver, along which axis-stepping climbs follow h/S poorly.)
        if !(box_bound > 0.0 && v1 > 0.0 && matches!(flat.chart, Chart::Square | Chart::Polar)) {
            return (flat, box_bound);
        }
        // The grid, and where the flat box had to bound f's limit at the rim, the rim: a
        // rise in its last sliver (Schlick's Fresnel at grazing wo) is the shape's to follow.
        // (The flat box's own search already evaluated its grid, except the polar box's.)
        let mut grid = if flat_grid.is_empty() {
            self.grid(&flat, rect, None)
        } else {
            flat_grid
        };
        let coarse_len = grid.len();
        let rim_band = if rim_limit.is_some() {
            self.rim_heights(&flat, rect)
        } else {
            Vec::new()
        };
        grid.extend_from_slice(&rim_band);
        let (flat_volume, safety) = (flat.volume(box_bound), self.config.bound_safety);
        // Only a node the grid resolves: where the flat box's search found a peak well above
        // every grid point (a lobe between them), a profile fitted to the grid would sink
        // under it, and its bound would rest on the climbs alone.
        let grid_top = grid.iter().map(|p| p.1).fold(0.0, f64::max);
        if grid_top * safety < 0.9 * box_bound {
            return (flat, box_bound);
        }
        let points: Vec<(DVec2, f64)> = grid.iter().map(|&(q, h)| (flat.unit(q), h)).collect();
        // The volume a shape promises on the grid.
        let promise = |shape: Shape| {
            let on_grid = points
                .iter()
                .map(|&(t, h)| h / shape.value(t))
                .fold(0.0, f64::max);
            Proposal { shape, ..flat }.volume(on_grid * safety)
        };
        // The bilinear profile, or the fine one (bilinear in each quarter: a peak inside the
        // node, which no bilinear profile follows) where it promises clearly less (its draw
        // chooses among sixteen hats, not four).
        let coarse = Shape::fit(&points);
        let coarse_promise = if coarse.is_flat() {
            flat_volume
        } else {
            promise(coarse)
        };
        let fine = if coarse_promise > FINE_TRY * flat_volume {
            Shape::fit_fine(&points)
        } else {
            Shape::FLAT
        };
        let (shape, promised) = if fine.is_flat() {
            (coarse, coarse_promise)
        } else {
            let fine_promise = promise(fine);
            if fine_promise < FINE_GAIN * coarse_promise {
                (fine, fine_promise)
            } else {
                (coarse, coarse_promise)
            }
        };
        if shape.is_flat() || promised >= SHAPE_PROMISE * flat_volume {
            return (flat, box_bound);
        }
        let prop = Proposal { shape, ..flat };
        let g = self.grid_steps(&prop) as u64 + 1;
        // (The grid, hints and searches, four more for a fine shape's quarters, searches
        // along the edges; the rim band where there is one.)
        let quarters = if shape.grid().is_some() { 1600 } else { 0 };
        let rim = if rim_limit.is_some() {
            RIM_BAND_EVALS
        } else {
            0
        };
        *spent += g * g + 1300 + quarters + EDGE_SEARCH_EVALS + rim;
        let known = Known {
            coarse: Some(&grid[..coarse_len]),
            rim_band: &rim_band,
        };
        let (bound, _) = self.proposal_bound(&prop, rect, peak, v1, rim_limit, known);
        if prop.volume(bound) < flat_volume {
            (prop, bound)
        } else {
            (flat, box_bound)
        }
    }

    /// A new leaf's cells as the cache budget allows ([`CELL_CACHE_LIMIT`]), counted in.
    pub(crate) fn remember(&self, cells: Option<Cell>) -> Option<Cell> {
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
    pub(crate) fn spend(&self, n: u64) {
        self.spent.fetch_add(n, AtomicOrdering::Relaxed);
    }

    /// Whether the evaluation budget is spent with `nodes` built (checked between batches
    /// of nodes, whose work does not depend on the order the threads did it in). Only the
    /// build's stop decisions ask, so a `true` is a stop, and it is recorded in `ran_out`.
    pub(crate) fn overspent(&self, nodes: usize) -> bool {
        let allowed = self
            .config
            .evaluation_budget
            .saturating_add((nodes as u64).saturating_mul(crate::config::EVALUATIONS_PER_NODE));
        let out = self.spent.load(AtomicOrdering::Relaxed) > allowed;
        if out {
            self.ran_out.store(true, AtomicOrdering::Relaxed);
        }
        out
    }

    /// Counts out a leaf's cells as it hands them to its children.
    pub(crate) fn forget_cell(&self, cells: &Cell) {
        self.cached
            .fetch_sub(cells.count(), AtomicOrdering::Relaxed);
    }
}
