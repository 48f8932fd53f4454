//! Sampling (seed §2.2, §3, Fig. 3–5): region selection (`seleccionarRegion`), rejection in
//! the leaf (`muestrear`), and the one interface every sampler of the project implements.

use crate::chart::ChartPoint;
use crate::config::BuildConfig;
use crate::error::BuildError;
use crate::packed::{PackedTree, Selected};
use crate::proposal::{Prepared, Proposal, TO_UNIT};
use crate::tree::{Quadtree, TreeStats, albedo_of_volume};
use alloc::sync::Arc;
use brdf_core::geometry::{above_horizon, luminance, unit_direction_above, unit_for_density};
use brdf_core::{Brdf, BrdfSample, DiskMap};
use core::sync::atomic::{AtomicU64, Ordering};
use glam::{DVec2, DVec3, Vec2, Vec3};
use rand_core::Rng;

/// A uniform f64 in [0, 1) from 53 random bits.
#[inline]
pub fn uniform_f64<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    (rng.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// A uniform f32 in [0, 1) from 24 random bits.
#[inline]
pub fn uniform_f32<R: Rng + ?Sized>(rng: &mut R) -> f32 {
    (rng.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

/// The 48-bit descent uniform of a `u` pair: `u.x`, refined below its last bit by `u.y`, so
/// that a tree deeper than 24 levels of probability is still resolved by 24-bit uniforms.
#[inline]
#[must_use]
pub fn descent_uniform(u: Vec2) -> f64 {
    let d = f64::from(u.x.clamp(0.0, 1.0)) + f64::from(u.y.clamp(0.0, 1.0)) * (1.0 / 16_777_216.0);
    d.min(1.0 - f64::EPSILON)
}

/// One sampled outgoing direction (local frame), as every sampler here returns it: the
/// workspace's one sample type, [`BrdfSample`] (wo, pdf per unit solid angle, f, weight, the
/// delta flag and the rejection trials).
pub type Sample = BrdfSample;

/// A sampler of outgoing directions for one fixed incident direction: the quadtree, the
/// baselines, or a user's own. Pure function of the random numbers drawn from `rng`.
pub trait DirectionSampler: Send + Sync {
    /// A short name (`rejection`, `cosine`, ...).
    fn name(&self) -> &'static str;

    /// Draws one direction from explicit uniforms in [0, 1) (pbrt's `Sample_f(uc, u)`): `uc`
    /// for a discrete choice (a lobe, a neighbour tree; ignored by samplers without one), `u`
    /// for the structure (the quadtree's descent, a warp, a table's inversion), and `rng` only
    /// for what rejection needs beyond them (samplers without rejection draw nothing from it).
    /// A renderer's stratified or low-discrepancy numbers drive it through `uc` and `u`.
    /// `None` when the drawn direction carries no contribution (below the horizon, or the
    /// rejection loop gave up); an estimator then scores 0.
    fn sample_with(&self, uc: f32, u: Vec2, rng: &mut dyn Rng) -> Option<Sample>;

    /// Draws one direction with every number taken from `rng`. The default draws `uc`, `u.x`,
    /// `u.y` (24-bit f32 uniforms, in that order) and calls
    /// [`DirectionSampler::sample_with`]; a sampler may draw its structure's numbers at a
    /// finer resolution instead (the quadtree descends with a 53-bit uniform).
    fn sample(&self, rng: &mut dyn Rng) -> Option<Sample> {
        let uc = uniform_f32(rng);
        let u = Vec2::new(uniform_f32(rng), uniform_f32(rng));
        self.sample_with(uc, u, rng)
    }

    /// The density of [`DirectionSampler::sample`] at `wo` (local), **per unit solid angle**.
    fn pdf(&self, wo: Vec3) -> f32;

    /// Where this sampler's density may be concentrated beyond the model's own peak hints
    /// (local frame), for an integrator of [`DirectionSampler::pdf`] (the validation's cells)
    /// to cut its ranges at: none by default. A baked sampler gives its neighbour trees'
    /// peaks and ridge planes, rotated onto the incident direction.
    fn density_hints(&self) -> DensityHints {
        DensityHints::default()
    }
}

/// A plane {w : `normal`·w = `offset`} of the local frame along which a density may be
/// concentrated: a lobe narrow along one tangent axis lies along such a plane (Ward's as
/// αx → 0 along wo.x = −wi.x, the plane with normal x̂ and offset −wi.x).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ridge {
    /// The plane's normal (any length; an integrator scales it to unit length).
    pub normal: DVec3,
    /// The plane's offset along `normal`.
    pub offset: f64,
}

/// Where a density may be concentrated: directions where it may peak sharply, and
/// [`Ridge`] planes it may lie along (see [`DirectionSampler::density_hints`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DensityHints {
    /// Unit directions (local frame).
    pub peaks: alloc::vec::Vec<DVec3>,
    /// Planes.
    pub ridges: alloc::vec::Vec<Ridge>,
    /// For a density that is a staircase (it follows a table read by nearest bin), the
    /// angular width of its steps in radians, as [`brdf_core::Brdf::step_width`] declares
    /// it: an integrator of the density cuts its ranges to pieces about this narrow before
    /// it trusts an error estimate. `None` for a continuous density.
    pub step: Option<f64>,
}

impl DensityHints {
    /// Peaks alone (f32 directions, as a model's peak hints are), no planes.
    #[must_use]
    pub fn of_peaks(peaks: &[Vec3]) -> Self {
        Self {
            peaks: peaks.iter().map(|h| h.as_dvec3()).collect(),
            ridges: alloc::vec::Vec::new(),
            step: None,
        }
    }
}

/// What `muestrear` accepted in a leaf ([`QuadtreeSampler::sample_leaf`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeafSample {
    /// The accepted point of the leaf's proposal chart (and its direction in f64).
    pub point: ChartPoint,
    /// The accepted direction as the unit f32 vector the sample reports (local frame).
    pub wo: Vec3,
    /// f_r(wi, wo), RGB, evaluated at exactly `wo`.
    pub f: Vec3,
    /// Rejection trials spent.
    pub trials: u32,
}

/// `muestrear` on a packed tree for any f (the quadtree's own model, or a baked sampler's
/// grid model): a point uniform in the leaf's proposal box, a height uniform in [0, M)
/// (for a shaped leaf, the point with density ∝ S and the height in [0, M·S) there:
/// [`crate::proposal::Shape`]); accept when the height is below Y(f)·(chart Jacobian).
/// Returns the accepted chart point, the f32 direction a caller sees (the point's unit f64
/// direction, rounded), f there (RGB, evaluated once per trial at exactly that vector) and
/// the trials; `None` after [`MAX_TRIALS`] or for a leaf that holds nothing. Every f > M
/// (M·S) met is counted in `violations`. One 64-bit draw places a flat leaf's point (32 bits
/// per axis: 2⁻³² of the leaf's side), that draw, one more and a 32-bit one a shaped leaf's
/// ([`crate::proposal::Shape::draw`]), and one more 64-bit draw the height.
pub(crate) fn rejection_in_leaf<R: Rng + ?Sized>(
    tree: &PackedTree,
    leaf: &Selected,
    eval: impl Fn(Vec3) -> Vec3,
    rng: &mut R,
    violations: &AtomicU64,
) -> Option<(ChartPoint, Vec3, Vec3, u32)> {
    // M is 0 for a leaf that holds nothing (selected only when the whole tree is empty).
    let holds = |m: f64| m > 0.0 && !m.is_nan();
    if tree.map() == DiskMap::Orthographic
        && let Some(m) = tree.flat_polar_bound(leaf)
    {
        return if holds(m) {
            polar_disk_trials(leaf, m, eval, rng, violations)
        } else {
            None
        };
    }
    let (prop, m, shape) = tree.leaf_for_trials(leaf);
    if !holds(m) {
        return None;
    }
    // A flat leaf's loop carries no shape; a shaped leaf draws its point with density ∝ S
    // and its height under M·S there, from its shape's sums and values prepared once (a
    // loop for each kind, so that no trial asks which kind it has).
    match shape {
        None => {
            let uv = |r: u64, _: &mut R| {
                let uv = DVec2::new((r >> 32) as f64, (r & 0xffff_ffff) as f64) * TO_UNIT;
                (uv, m)
            };
            trials(tree, leaf, &prop, eval, rng, violations, uv)
        }
        Some(Prepared::Coarse(shape)) => {
            let shaped = |r: u64, rng: &mut R| {
                let t = shape.draw([r, rng.next_u64()], rng.next_u32());
                (t, m * shape.value(t))
            };
            trials(tree, leaf, &prop, eval, rng, violations, shaped)
        }
        Some(Prepared::Fine(shape)) => {
            let shaped = |r: u64, rng: &mut R| {
                let t = shape.draw([r, rng.next_u64()], rng.next_u32());
                (t, m * shape.value(t))
            };
            trials(tree, leaf, &prop, eval, rng, violations, shaped)
        }
    }
}

/// The trials of [`rejection_in_leaf`] in a flat polar leaf on the orthographic map (the
/// root, or one of its children: a quarter of the disk). Its proposal, uniform in (s, φ) over
/// the node's sector, is the uniform density on the node's part of the disk: drawn here as a
/// point uniform in the node's square, drawn again while it falls outside the disk (before
/// any evaluation, and not counted as a trial: it is the proposal's own draw), which spares
/// each trial the sine, cosine and square root of the (s, φ) chart (Lambert's sample went
/// from 52 to 32 ns). Accepted points have the same law, f·(uniform on the disk), so the sample's pdf
/// is unchanged. At most [`MAX_TRIALS`] draws of either kind: an RNG whose points all miss
/// the disk gives `None`, never a hang.
#[inline(always)]
fn polar_disk_trials<R: Rng + ?Sized>(
    leaf: &Selected,
    m: f64,
    eval: impl Fn(Vec3) -> Vec3,
    rng: &mut R,
    violations: &AtomicU64,
) -> Option<(ChartPoint, Vec3, Vec3, u32)> {
    let jacobian = crate::chart::polar_jacobian(DiskMap::Orthographic);
    let (lo, side) = (leaf.rect.min, leaf.rect.max - leaf.rect.min);
    let mut trials = 0;
    for _ in 0..MAX_TRIALS {
        let r = rng.next_u64();
        let p = lo + side * DVec2::new((r >> 32) as f64, (r & 0xffff_ffff) as f64) * TO_UNIT;
        let s = p.length_squared();
        if s >= 1.0 {
            continue;
        }
        trials += 1;
        let z = m * uniform_f64(rng);
        let c = ChartPoint {
            p,
            w: DVec3::new(p.x, p.y, brdf_core::math::sqrt(1.0 - s)),
            jacobian,
        };
        if let Some((wo, f)) = judge(&c, z, m, &eval, violations) {
            return Some((c, wo, f, trials));
        }
    }
    None
}

/// The trials of [`rejection_in_leaf`], `point` giving a trial's box coordinates and its
/// height bound from its first 64-bit draw (and the RNG for more).
#[inline(always)]
fn trials<R: Rng + ?Sized>(
    tree: &PackedTree,
    leaf: &Selected,
    prop: &Proposal,
    eval: impl Fn(Vec3) -> Vec3,
    rng: &mut R,
    violations: &AtomicU64,
    point: impl Fn(u64, &mut R) -> (DVec2, f64),
) -> Option<(ChartPoint, Vec3, Vec3, u32)> {
    let span = prop.hi - prop.lo;
    for trial in 1..=MAX_TRIALS {
        let r = rng.next_u64();
        let (t, top) = point(r, rng);
        let q = prop.lo + span * t;
        let z = top * uniform_f64(rng);
        let Some(c) = prop.point(tree.map(), &leaf.rect, q) else {
            continue;
        };
        if let Some((wo, f)) = judge(&c, z, top, &eval, violations) {
            return Some((c, wo, f, trial));
        }
    }
    None
}

/// One trial's verdict, the one expression every rejection loop shares: f at the chart
/// point's direction (unit in f64; rounded to f32 it is as near unit as an f32
/// renormalisation would make it, without a square root and a division a trial), a height
/// over its bound `top` counted in `violations`, and the point accepted (its f32 direction
/// and f) when the height `z` drawn under `top` is below f·Jacobian.
#[inline(always)]
fn judge(
    c: &ChartPoint,
    z: f64,
    top: f64,
    eval: &impl Fn(Vec3) -> Vec3,
    violations: &AtomicU64,
) -> Option<(Vec3, Vec3)> {
    let wo = c.w.as_vec3();
    let f = eval(wo);
    let h = f64::from(luminance(f)) * c.jacobian;
    if h > top {
        violations.fetch_add(1, Ordering::Relaxed);
    }
    (z < h).then_some((wo, f))
}

/// The seed's sampler: a quadtree built once for `wi`, then any number of samples (`&self`,
/// `Sync`). Rejection mode: the density is ∝ f_r·cos θ up to the leaf-integral error, and the
/// reported pdf is f_r·cos θ·J/V (V the tree's volume, J the map's Jacobian).
#[derive(Debug)]
pub struct QuadtreeSampler<B: Brdf = Arc<dyn Brdf>> {
    brdf: B,
    wi: Vec3,
    config: BuildConfig,
    tree: PackedTree,
    /// J / V: pdf per unit solid angle = f · cos θ · this.
    pdf_scale: f64,
    violations: AtomicU64,
    gave_up: AtomicU64,
}

/// The rejection loop gives up on one sample after this many trials (returns `None`).
pub const MAX_TRIALS: u32 = 1 << 20;

/// A build whose tree would need more than this many rejection trials per sample on average
/// is an error ([`crate::BuildError::Exhausted`]) rather than a sampler that crawls: the seed's
/// rule promises 2, and only a budget (nodes, depth) that stopped the build can leave more.
pub const MAX_USABLE_EXPECTED_TRIALS: f64 = 64.0;

impl<B: Brdf> QuadtreeSampler<B> {
    /// Builds the quadtree of f_r(wi, ·) for a local `wi` (normalised here; it must be finite,
    /// non-zero and above the horizon). Delta models are an error.
    pub fn new(brdf: B, wi: Vec3, config: BuildConfig) -> Result<Self, BuildError> {
        let wi = unit_direction_above(wi)?;
        let tree = PackedTree::new(&Quadtree::from_unit(&brdf, wi, config)?);
        let v = tree.volume();
        let j = f64::from(config.map.square_area_per_projected_solid_angle());
        Ok(Self {
            brdf,
            wi,
            config,
            tree,
            pdf_scale: if v > 0.0 { j / v } else { 0.0 },
            violations: AtomicU64::new(0),
            gave_up: AtomicU64::new(0),
        })
    }

    /// Multiplies every bound M by `factor`: a deliberately broken sampler for negative
    /// controls (a validation harness must reject it for factor < 1). Not for production.
    #[doc(hidden)]
    pub fn scale_bounds_for_testing(&mut self, factor: f64) {
        self.tree.scale_bounds(factor);
    }

    /// The tree, in its sampling layout ([`PackedTree::leaves`] inspects it).
    #[must_use]
    pub fn tree(&self) -> &PackedTree {
        &self.tree
    }

    /// The build options used.
    #[must_use]
    pub fn config(&self) -> &BuildConfig {
        &self.config
    }

    /// The incident direction (local, unit).
    #[must_use]
    pub fn wi(&self) -> Vec3 {
        self.wi
    }

    /// The directional albedo of f_r's luminance, ρ(wi) = ∫ Y(f_r) cos θ dω = V/J (SPEC §2):
    /// the constant weight of every sample in luminance.
    #[must_use]
    pub fn albedo(&self) -> f64 {
        albedo_of_volume(self.config.map, self.tree.volume())
    }

    /// Tree counts and E\[T\].
    #[must_use]
    pub fn stats(&self) -> TreeStats {
        self.tree.stats().clone()
    }

    /// How many times sampling met f > M (a bound that was not one). Should stay 0.
    #[must_use]
    pub fn bound_violations(&self) -> u64 {
        self.violations.load(Ordering::Relaxed)
    }

    /// How many samples hit [`MAX_TRIALS`] and returned `None`.
    #[must_use]
    pub fn gave_up(&self) -> u64 {
        self.gave_up.load(Ordering::Relaxed)
    }

    /// `seleccionarRegion`: descends from the root, choosing child i with probability
    /// v1_i / Σ v1 (stored in 31-bit fixed point, see [`PackedTree`]): one uniform
    /// `u` ∈ [0, 1) picks the leaf whose interval holds it. Returns a leaf with v1 > 0 (or a leaf holding nothing when
    /// the whole tree is empty) and its square.
    #[must_use]
    pub fn select_region(&self, u: f64) -> Selected {
        self.tree.select(u)
    }

    /// `muestrear`: rejection in the selected leaf: a point uniform in the leaf's proposal
    /// box, a height uniform in [0, M); accept when the height is below f (times the chart's
    /// Jacobian). f is evaluated once per trial, at exactly the unit f32 vector a caller
    /// sees, so the accepted value *is* `eval(wi, wo)` and its luminance is what
    /// [`QuadtreeSampler::pdf`] computes: no second evaluation is needed. One 64-bit draw
    /// places the point (32 bits per axis: 2⁻³² of the leaf's side) and one more the height.
    /// `None` after [`MAX_TRIALS`] (counted in [`QuadtreeSampler::gave_up`]) or for a leaf
    /// that holds nothing.
    pub fn sample_leaf<R: Rng + ?Sized>(&self, leaf: &Selected, rng: &mut R) -> Option<LeafSample> {
        let r = rejection_in_leaf(
            &self.tree,
            leaf,
            |wo| self.brdf.eval(self.wi, wo),
            rng,
            &self.violations,
        );
        if r.is_none() {
            self.gave_up.fetch_add(1, Ordering::Relaxed);
        }
        r.map(|(point, wo, f, trials)| LeafSample {
            point,
            wo,
            f,
            trials,
        })
    }

    /// Draws one direction: select a region with a 53-bit uniform from `rng`, then
    /// rejection-sample it. f_r is evaluated once per trial and never again for the accepted
    /// sample.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> Option<Sample> {
        self.sample_from(uniform_f64(rng), rng)
    }

    /// [`QuadtreeSampler::sample`] with the descent driven by the caller's `u` ∈ [0, 1)
    /// (`select_region(u)`, then `sample_leaf` drawing the rejection trials from `rng`).
    pub fn sample_from<R: Rng + ?Sized>(&self, u: f64, rng: &mut R) -> Option<Sample> {
        let leaf = self.select_region(u);
        let LeafSample { wo, f, trials, .. } = self.sample_leaf(&leaf, rng)?;
        if !above_horizon(wo) {
            return None;
        }
        let pdf = self.pdf_of(luminance(f), wo);
        Sample::continuous(wo, f, pdf).map(|s| Sample { trials, ..s })
    }

    /// The density per unit solid angle that [`QuadtreeSampler::sample`] reports for `wo`:
    /// Y(f_r)·cos θ·J/V.
    #[must_use]
    pub fn pdf(&self, wo: Vec3) -> f32 {
        let Some(wo) = unit_for_density(wo).filter(|w| w.z > 0.0) else {
            return 0.0;
        };
        self.pdf_of(self.brdf.eval_luminance(self.wi, wo), wo)
    }

    /// Y(f_r)·cos θ·J/V from the luminance `y` of f_r at `wo`: the one expression behind both
    /// [`QuadtreeSampler::pdf`] and the pdf a sample carries, so the two are bit-identical.
    #[inline]
    fn pdf_of(&self, y: f32, wo: Vec3) -> f32 {
        (f64::from(y) * f64::from(wo.z) * self.pdf_scale) as f32
    }
}

impl<B: Brdf> DirectionSampler for QuadtreeSampler<B> {
    fn name(&self) -> &'static str {
        "rejection"
    }

    fn sample_with(&self, _uc: f32, u: Vec2, rng: &mut dyn Rng) -> Option<Sample> {
        self.sample_from(descent_uniform(u), rng)
    }

    fn sample(&self, rng: &mut dyn Rng) -> Option<Sample> {
        QuadtreeSampler::sample(self, rng)
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        QuadtreeSampler::pdf(self, wo)
    }
}

/// Which baseline: what a renderer would use instead of the quadtree.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Baseline {
    /// Uniform on the hemisphere, pdf 1/(2π).
    Uniform,
    /// Cosine-weighted, pdf cos θ/π.
    Cosine,
    /// The model's own sampler of its continuous part (`Brdf::sample_continuous`; cosine for
    /// models without one).
    Analytic,
}

/// A baseline sampler for one incident direction.
#[derive(Clone, Copy, Debug)]
pub struct BaselineSampler<B: Brdf = Arc<dyn Brdf>> {
    brdf: B,
    wi: Vec3,
    kind: Baseline,
}

impl<B: Brdf> BaselineSampler<B> {
    /// A baseline for local `wi` (normalised; it must be above the horizon).
    pub fn new(brdf: B, wi: Vec3, kind: Baseline) -> Result<Self, BuildError> {
        Ok(Self {
            brdf,
            wi: unit_direction_above(wi)?,
            kind,
        })
    }

    /// Draws one direction with `uc`, `u.x`, `u.y` taken from `rng` (in that order).
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R) -> Option<Sample> {
        let uc = uniform_f32(rng);
        let u = Vec2::new(uniform_f32(rng), uniform_f32(rng));
        self.sample_from(uc, u)
    }

    /// Draws one direction from explicit uniforms: `uc` chooses the model's lobe (analytic
    /// only), `u` places the direction. Draws no other numbers.
    #[must_use]
    pub fn sample_from(&self, uc: f32, u: Vec2) -> Option<Sample> {
        match self.kind {
            Baseline::Analytic => self.brdf.sample_continuous(self.wi, uc, u),
            Baseline::Uniform | Baseline::Cosine => {
                let wo = match self.kind {
                    Baseline::Uniform => brdf_core::warp::sample_uniform_hemisphere(u),
                    _ => brdf_core::warp::sample_cosine_hemisphere(u),
                };
                BrdfSample::continuous(wo, self.brdf.eval(self.wi, wo), self.pdf(wo))
            }
        }
    }

    /// Density per unit solid angle.
    #[must_use]
    pub fn pdf(&self, wo: Vec3) -> f32 {
        let Some(wo) = unit_for_density(wo).filter(|w| w.z > 0.0) else {
            return 0.0;
        };
        match self.kind {
            Baseline::Uniform => brdf_core::warp::uniform_hemisphere_pdf(),
            Baseline::Cosine => brdf_core::warp::cosine_hemisphere_pdf(wo.z),
            Baseline::Analytic => self.brdf.pdf_continuous(self.wi, wo),
        }
    }
}

impl<B: Brdf> DirectionSampler for BaselineSampler<B> {
    fn name(&self) -> &'static str {
        match self.kind {
            Baseline::Uniform => "uniform",
            Baseline::Cosine => "cosine",
            Baseline::Analytic => "analytic",
        }
    }

    fn sample_with(&self, uc: f32, u: Vec2, _rng: &mut dyn Rng) -> Option<Sample> {
        self.sample_from(uc, u)
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        BaselineSampler::pdf(self, wo)
    }
}

/// Luminance of a sample's weight (for mean-weight estimates).
#[must_use]
pub fn weight_luminance(s: &Sample) -> f64 {
    f64::from(luminance(s.weight))
}
