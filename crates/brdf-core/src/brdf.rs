//! The [`Brdf`] trait every model implements, and what its samplers return.

use crate::error::DirectionError;
use crate::geometry::{above_horizon, luminance, mirror, unit_direction, unit_direction_above};
use crate::param::ParamSet;
use crate::warp::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use core::fmt;
use glam::{Vec2, Vec3};

/// One sampled direction with everything an estimator needs (pbrt's `BSDFSample`): the one
/// sample type of every sampler in the workspace (the models' analytic samplers, the
/// quadtree, the baselines, the baked sampler; `quadtree_sampler::Sample` is this type).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrdfSample {
    /// The sampled outgoing direction, local frame, unit, z > 0.
    pub wo: Vec3,
    /// For a continuous sample: the density of `wo` **per unit solid angle**, as
    /// [`Brdf::pdf`] reports it. For a delta sample: the discrete probability with which the
    /// delta lobe was chosen (1 when it is the only lobe).
    pub pdf: f32,
    /// f_r(wi, wo), RGB, 1/sr. For a delta sample: reflectance / cos θo (pbrt's convention).
    pub f: Vec3,
    /// The estimator weight f·cos θo / pdf, RGB.
    pub weight: Vec3,
    /// True when `wo` came from a Dirac delta lobe (its pdf is not a density).
    pub delta: bool,
    /// Rejection trials spent on this sample (1 for samplers without rejection).
    pub trials: u32,
}

/// A continuous sample's weight f·cos θo/pdf: f times the quotient cos θo/pdf in f32 where
/// that quotient is finite, bit for bit the plain formula; in f64 where it is not. A pdf
/// among f32's denormals (a lobe's far flank, below 10⁻³⁸ per steradian, which a descent
/// driven by u = 0 or 1 reaches: Phong n = 10⁵ at normal incidence, pdf 1.8·10⁻⁴⁰, f
/// 6·10⁻⁴⁵) overflowed the quotient, and the weight was inf where f·cos θo/pdf is an
/// ordinary number (ρ = 3.1·10⁻⁵ there). A quotient that is inf in f64 too (a zero pdf)
/// still gives inf.
#[inline]
fn continuous_weight(f: Vec3, cos_theta: f32, pdf: f32) -> Vec3 {
    let q = cos_theta / pdf;
    if q.is_finite() {
        f * q
    } else {
        (f.as_dvec3() * (f64::from(cos_theta) / f64::from(pdf))).as_vec3()
    }
}

impl BrdfSample {
    /// Builds a continuous sample from `eval` and `pdf` values (weight = f·cos/pdf), or `None`
    /// when the direction is below the horizon or the pdf is not positive and finite.
    #[inline]
    #[must_use]
    pub fn continuous(wo: Vec3, f: Vec3, pdf: f32) -> Option<Self> {
        if !(wo.z > 0.0 && pdf > 0.0 && pdf.is_finite()) {
            return None;
        }
        Some(Self {
            wo,
            pdf,
            f,
            weight: continuous_weight(f, wo.z, pdf),
            delta: false,
            trials: 1,
        })
    }

    /// The same continuous sample (direction and f_r) reported with density `pdf` (per unit
    /// solid angle), the weight f·cos/pdf following it: how a sampler that chose the
    /// continuous part with some probability scales its pdf. Not for a delta sample, whose
    /// pdf is a probability and whose weight is built by [`BrdfSample::delta`].
    #[inline]
    #[must_use]
    pub fn with_pdf(self, pdf: f32) -> Self {
        debug_assert!(!self.delta, "with_pdf on a delta sample");
        Self {
            pdf,
            weight: continuous_weight(self.f, self.wo.z, pdf),
            ..self
        }
    }

    /// Builds the delta sample toward `wo` with the given reflectance, chosen with probability
    /// `choice_probability`.
    #[inline]
    #[must_use]
    pub fn delta(wo: Vec3, reflectance: Vec3, choice_probability: f32) -> Option<Self> {
        if !(wo.z > 0.0 && choice_probability > 0.0) {
            return None;
        }
        Some(Self {
            wo,
            pdf: choice_probability,
            // The delta's coefficient R/cos θo, with cos θo at the grazing floor (finite for
            // every wo above the horizon); the weight below is exact whatever cos θo is.
            f: reflectance / (wo.z.max(crate::geometry::GRAZING_COS as f32)),
            weight: reflectance / choice_probability,
            delta: true,
            trials: 1,
        })
    }
}

/// Up to four directions where a model's f_r may peak for a given `wi` (the mirror direction,
/// the normal, the retro-reflection direction...). The quadtree evaluates f_r at these points
/// when bounding a node (SPEC §3); they are hints, not guarantees.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PeakHints {
    dirs: [Vec3; 4],
    len: usize,
}

impl PeakHints {
    /// No hints.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            dirs: [Vec3::ZERO; 4],
            len: 0,
        }
    }

    /// Adds a hint if it is a finite direction strictly above the horizon and there is room.
    pub fn push(&mut self, w: Vec3) {
        if self.len < self.dirs.len() && w.z > 0.0 && w.is_finite() {
            self.dirs[self.len] = w;
            self.len += 1;
        }
    }

    /// The hints.
    #[must_use]
    pub fn as_slice(&self) -> &[Vec3] {
        &self.dirs[..self.len]
    }

    /// The default hints: the mirror direction r(wi) and the normal.
    #[must_use]
    pub fn mirror_and_normal(wi: Vec3) -> Self {
        let mut h = Self::new();
        h.push(mirror(wi));
        h.push(Vec3::Z);
        h
    }
}

/// The symmetries a model declares, which a baked sampler uses to fold its grid of incident
/// directions (SPEC §7). Each flag is a promise about the continuous part [`Brdf::eval`]
/// (and the delta part) for *every* pair of directions; a test checks every model's
/// declaration by evaluation. A flag left false is always safe: it only costs a larger grid.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Symmetry {
    /// f_r(R wi, R wo) = f_r(wi, wo) for every rotation R about the normal: f_r depends on φi
    /// and φo only through φi − φo, so one grid row in θi serves every φi.
    pub isotropic: bool,
    /// f_r(Sx wi, Sx wo) = f_r(wi, wo) with Sx(x, y, z) = (−x, y, z): mirror-symmetric about
    /// the plane x = 0.
    pub mirror_x: bool,
    /// f_r(Sy wi, Sy wo) = f_r(wi, wo) with Sy(x, y, z) = (x, −y, z): mirror-symmetric about
    /// the plane y = 0.
    pub mirror_y: bool,
    /// f_r(wi, wo) = f_r(wo, wi) (Helmholtz reciprocity): the same tables serve both
    /// transport roles; a non-reciprocal model needs its adjoint baked as well.
    pub reciprocal: bool,
}

impl Symmetry {
    /// Nothing promised: anisotropic, no mirror planes, not reciprocal (the safe default).
    pub const NONE: Self = Self {
        isotropic: false,
        mirror_x: false,
        mirror_y: false,
        reciprocal: false,
    };

    /// Isotropic and reciprocal (implies both mirror planes).
    pub const ISOTROPIC_RECIPROCAL: Self = Self {
        isotropic: true,
        mirror_x: true,
        mirror_y: true,
        reciprocal: true,
    };

    /// Anisotropic about the tangent, mirror-symmetric about both coordinate planes, and
    /// reciprocal (Ward, Schlick's slab, Poulin–Fournier's cylinders along x).
    pub const ORTHOTROPIC_RECIPROCAL: Self = Self {
        isotropic: false,
        mirror_x: true,
        mirror_y: true,
        reciprocal: true,
    };
}

/// The narrowest [`Brdf::step_width`] an integrator refines to: 2⁻⁸ rad (0.22°). A narrower
/// declaration is read as this, so that no model can ask for unbounded work.
pub const MIN_STEP_WIDTH: f64 = 1.0 / 256.0;

/// The piece width a model's [`Brdf::step_width`] asks integrators for: a finite positive
/// width, at least [`MIN_STEP_WIDTH`]; `None` for no declaration, or one that is zero,
/// negative, infinite or NaN.
#[must_use]
pub fn usable_step_width(declared: Option<f64>) -> Option<f64> {
    declared
        .filter(|w| *w > 0.0 && w.is_finite())
        .map(|w| w.max(MIN_STEP_WIDTH))
}

/// A bidirectional reflectance distribution function in the local shading frame (z = normal,
/// x = tangent). `wi` points toward the light, `wo` toward the viewer; both unit, both away
/// from the surface (SPEC §1).
///
/// Implementations are pure and `Sync`: samplers take their random numbers as arguments.
pub trait Brdf: Send + Sync + fmt::Debug {
    /// The registry name (`phong`, `ward`, ...).
    fn name(&self) -> &'static str;

    /// The parameter values this instance was built with (complete, in spec order).
    fn params(&self) -> ParamSet;

    /// f_r(wi, wo) of the continuous part, RGB, in 1/sr; no cosine factor.
    ///
    /// 0 when either direction is at or below the horizon (z ≤ 0) or not finite. Inputs need
    /// only be approximately unit: every model renormalises them in f64. A delta part (see
    /// [`Brdf::delta_reflectance`]) is not included: its value at any explicit pair is 0.
    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3;

    /// The scalar density the samplers follow: the luminance of [`Brdf::eval`].
    #[inline]
    fn eval_luminance(&self, wi: Vec3, wo: Vec3) -> f32 {
        luminance(self.eval(wi, wo))
    }

    /// True when the model has no continuous part at all (the perfect mirror): nothing to
    /// tabulate, so building a quadtree for it is an error.
    fn is_delta(&self) -> bool {
        false
    }

    /// The reflectance of a Dirac delta lobe toward the mirror direction r(wi), RGB (0 when
    /// the model has none, and for wi below the horizon).
    fn delta_reflectance(&self, wi: Vec3) -> Vec3 {
        let _ = wi;
        Vec3::ZERO
    }

    /// The symmetries this instance has (see [`Symmetry`]). The default promises nothing,
    /// which is always correct; models override it (a test checks every declaration).
    fn symmetry(&self) -> Symmetry {
        Symmetry::NONE
    }

    /// True when f_r(wi, wo) does not depend on wi at all: f_r(wi, wo) = f_r(wi', wo) for
    /// every wi, wi' and wo above the horizon (Lambert, or a glossy model with its glossy
    /// part switched off), and there is no delta part (a mirror lobe follows wi). A baked
    /// sampler then answers every incident direction with one of its trees, as it is: no
    /// neighbour mixture, no rotation, and the sampling quality of a tree built at that very
    /// wi. A promise about every pair, like [`Brdf::symmetry`] (a test checks every model's
    /// by evaluation); false, the default, is always safe. A false promise costs variance,
    /// not correctness: the baked pdf stays the density of what the tree draws.
    fn independent_of_incident(&self) -> bool {
        false
    }

    /// Directions where f_r(wi, ·) may peak, used to bound f_r over a region (SPEC §3).
    fn peak_hints(&self, wi: Vec3) -> PeakHints {
        PeakHints::mirror_and_normal(wi)
    }

    /// cos θc of a crease of f_r(wi, ·): a ring of outgoing directions at polar angle θc
    /// across which f_r is continuous but its derivative in θo jumps (Oren–Nayar's
    /// max(θi, θo) and min(θi, θo) put one at θo = θi). The quadtree's integration cuts its
    /// cells along that ring instead of refining toward it, which a rule converges on only
    /// as fast as the cells shrink. A hint for speed, not for correctness: `None` (the
    /// default) is always right.
    fn crease_cosine(&self, wi: Vec3) -> Option<f64> {
        let _ = wi;
        None
    }

    /// The relative accuracy past which integrals of f_r(wi, ·) are not worth refining: a
    /// quadtree integrates each node to the larger of this and its own configured tolerance.
    /// A model whose f_r is smooth between a few creases converges at any tolerance and
    /// leaves it at 0 (the default). A table read by nearest bin is a staircase of thousands
    /// of steps, on which an adaptive rule converges only as fast as its cells shrink along
    /// every step: a tolerance of 10⁻⁶ spent a build's whole evaluation budget on a few dozen
    /// nodes. A leaf integral within this of the true one leaves a sampler's pdf exact to
    /// about the same relative amount (`merl`'s 10⁻⁴ passed `brdf test` against its own pdf
    /// at 10⁸ samples). The quadtree reads values above 10⁻³ as 10⁻³, and NaN or negative
    /// ones as 0.
    fn integration_tolerance(&self) -> f64 {
        0.0
    }

    /// For an f_r that is a staircase (a table read by nearest bin), the angular width of its
    /// bins, in radians (`merl`: 1°, its θd and φd bins); `None`, the default, for an f_r
    /// that is continuous. An adaptive integrator trusts its error estimate (two rules, or
    /// two levels, agreeing) only on pieces about this narrow or narrower: over a wider piece
    /// that holds many steps, two estimates of a staircase can agree by chance while both are
    /// wrong. Without it a MERL table's quadtree at θi = 89° came out 10⁻³ heavy, one of its
    /// leaves 2.7·10⁻³ (the sampler's pdf that much short of what it draws), and `brdf test`
    /// summed a baked sampler's own pdf over its cells 3–6·10⁻⁴ high. Only a finite positive
    /// width is used, and none below [`MIN_STEP_WIDTH`] (the cost of the integrations grows
    /// with the inverse square of the width).
    fn step_width(&self) -> Option<f64> {
        None
    }

    /// Whether [`Brdf::sample_continuous`] is a model-specific importance sampler. When false,
    /// the continuous part is sampled cosine-weighted (the baseline of MODELS.md).
    fn has_analytic_sampler(&self) -> bool {
        false
    }

    /// A cheap estimate of the continuous part's directional albedo ∫ f_r cos θo dωo at `wi`,
    /// used only to choose between the delta and the continuous part in [`Brdf::sample`] (any
    /// positive value keeps sampling unbiased; a good one lowers variance). The default,
    /// 1 − luminance of the delta reflectance, suits an energy-conserving model.
    fn continuous_albedo_hint(&self, wi: Vec3) -> f32 {
        (1.0 - luminance(self.delta_reflectance(wi))).max(0.0)
    }

    /// The probability with which [`Brdf::sample`] picks the delta lobe for `wi`: 0 without a
    /// delta part, 1 for a pure delta model, else the delta reflectance's share of the luminance
    /// against [`Brdf::continuous_albedo_hint`], kept within [0.05, 0.95] so that neither part
    /// is starved.
    fn delta_probability(&self, wi: Vec3) -> f32 {
        if !above_horizon(wi) {
            return 0.0;
        }
        if self.is_delta() {
            return 1.0;
        }
        let d = luminance(self.delta_reflectance(wi));
        if d.is_nan() || d <= 0.0 {
            return 0.0;
        }
        let c = self.continuous_albedo_hint(wi);
        let c = if c.is_nan() { 0.0 } else { c.max(0.0) };
        (d / (d + c)).clamp(0.05, 0.95)
    }

    /// Draws `wo` from the continuous part alone: `uc` chooses a lobe, `u` places the
    /// direction in it. The returned `pdf` is [`Brdf::pdf_continuous`]. `None` when the drawn
    /// direction falls below the horizon (the estimator then scores 0; nothing is re-drawn) or
    /// `wi` is not above the horizon. The default is cosine-weighted sampling.
    fn sample_continuous(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
        let _ = uc;
        if !above_horizon(wi) {
            return None;
        }
        let wo = sample_cosine_hemisphere(u);
        BrdfSample::continuous(wo, self.eval(wi, wo), cosine_hemisphere_pdf(wo.z))
    }

    /// The density of [`Brdf::sample_continuous`], **per unit solid angle**.
    fn pdf_continuous(&self, wi: Vec3, wo: Vec3) -> f32 {
        if !above_horizon(wi) || !above_horizon(wo) {
            return 0.0;
        }
        cosine_hemisphere_pdf(wo.z)
    }

    /// Draws `wo` given `wi` from the whole model: with probability
    /// [`Brdf::delta_probability`] the delta lobe toward r(wi) (a delta sample), otherwise the
    /// continuous part ([`Brdf::sample_continuous`], `uc` rescaled), whose pdf is then scaled
    /// by the probability of having chosen it. `None` below the horizon, as there.
    fn sample(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
        if !above_horizon(wi) {
            return None;
        }
        let p = self.delta_probability(wi);
        if p <= 0.0 {
            return self.sample_continuous(wi, uc, u);
        }
        if uc < p || p >= 1.0 {
            let wi = wi.normalize();
            return BrdfSample::delta(mirror(wi), self.delta_reflectance(wi), p);
        }
        let uc = ((uc - p) / (1.0 - p)).min(1.0 - f32::EPSILON / 2.0);
        let s = self.sample_continuous(wi, uc, u)?;
        BrdfSample::continuous(s.wo, s.f, s.pdf * (1.0 - p))
    }

    /// The density with which [`Brdf::sample`] draws `wo` given `wi` as a continuous sample,
    /// **per unit solid angle**: (1 − [`Brdf::delta_probability`]) · [`Brdf::pdf_continuous`]
    /// (0 for a pure delta model). Agrees with the `pdf` of the continuous samples.
    fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let p = self.delta_probability(wi);
        if p <= 0.0 {
            self.pdf_continuous(wi, wo)
        } else if p >= 1.0 {
            0.0
        } else {
            (1.0 - p) * self.pdf_continuous(wi, wo)
        }
    }

    /// [`Brdf::eval`] with its inputs checked: NaN, infinite and zero-length directions are
    /// typed errors instead of a silent 0. Directions below the horizon are valid (f_r = 0).
    fn try_eval(&self, wi: Vec3, wo: Vec3) -> Result<Vec3, DirectionError> {
        let (wi, wo) = (unit_direction(wi)?, unit_direction(wo)?);
        Ok(self.eval(wi, wo))
    }

    /// [`Brdf::sample`] with `wi` checked: it must be a finite, non-zero direction above the
    /// horizon ([`DirectionError`] otherwise).
    fn try_sample(&self, wi: Vec3, uc: f32, u: Vec2) -> Result<Option<BrdfSample>, DirectionError> {
        let wi = unit_direction_above(wi)?;
        Ok(self.sample(wi, uc, u))
    }
}

/// Forwards every method of [`Brdf`] (provided ones included, so a model's overrides survive)
/// through a pointer type, so that samplers can hold their model in whatever way the caller
/// owns it: borrowed (`&B`), boxed, or shared (`Arc<dyn Brdf>`, the `'static` choice a scene
/// stores).
macro_rules! forward_brdf {
    ($($ptr:ty),*) => {$(
        impl<T: Brdf + ?Sized> Brdf for $ptr {
            #[inline]
            fn name(&self) -> &'static str {
                (**self).name()
            }
            #[inline]
            fn params(&self) -> ParamSet {
                (**self).params()
            }
            #[inline]
            fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
                (**self).eval(wi, wo)
            }
            #[inline]
            fn eval_luminance(&self, wi: Vec3, wo: Vec3) -> f32 {
                (**self).eval_luminance(wi, wo)
            }
            #[inline]
            fn is_delta(&self) -> bool {
                (**self).is_delta()
            }
            #[inline]
            fn delta_reflectance(&self, wi: Vec3) -> Vec3 {
                (**self).delta_reflectance(wi)
            }
            #[inline]
            fn symmetry(&self) -> Symmetry {
                (**self).symmetry()
            }
            #[inline]
            fn independent_of_incident(&self) -> bool {
                (**self).independent_of_incident()
            }
            #[inline]
            fn peak_hints(&self, wi: Vec3) -> PeakHints {
                (**self).peak_hints(wi)
            }
            #[inline]
            fn crease_cosine(&self, wi: Vec3) -> Option<f64> {
                (**self).crease_cosine(wi)
            }
            #[inline]
            fn integration_tolerance(&self) -> f64 {
                (**self).integration_tolerance()
            }
            #[inline]
            fn step_width(&self) -> Option<f64> {
                (**self).step_width()
            }
            #[inline]
            fn has_analytic_sampler(&self) -> bool {
                (**self).has_analytic_sampler()
            }
            #[inline]
            fn continuous_albedo_hint(&self, wi: Vec3) -> f32 {
                (**self).continuous_albedo_hint(wi)
            }
            #[inline]
            fn delta_probability(&self, wi: Vec3) -> f32 {
                (**self).delta_probability(wi)
            }
            #[inline]
            fn sample_continuous(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
                (**self).sample_continuous(wi, uc, u)
            }
            #[inline]
            fn pdf_continuous(&self, wi: Vec3, wo: Vec3) -> f32 {
                (**self).pdf_continuous(wi, wo)
            }
            #[inline]
            fn sample(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
                (**self).sample(wi, uc, u)
            }
            #[inline]
            fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
                (**self).pdf(wi, wo)
            }
            #[inline]
            fn try_eval(&self, wi: Vec3, wo: Vec3) -> Result<Vec3, DirectionError> {
                (**self).try_eval(wi, wo)
            }
            #[inline]
            fn try_sample(
                &self,
                wi: Vec3,
                uc: f32,
                u: Vec2,
            ) -> Result<Option<BrdfSample>, DirectionError> {
                (**self).try_sample(wi, uc, u)
            }
        }
    )*};
}

forward_brdf!(&T, alloc::boxed::Box<T>, alloc::sync::Arc<T>);

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::{boxed::Box, sync::Arc};

    /// A continuous sample's weight is the plain f32 formula bit for bit where cos θo/pdf is
    /// finite, and finite where only f32's quotient overflows (a denormal pdf: it was inf),
    /// within f32 rounding of the f64 value; `with_pdf` agrees.
    #[test]
    fn a_denormal_pdf_gives_a_finite_weight() {
        let wo = Vec3::new(-0.031_983_294, -0.031_592_365, 0.998_989);
        let f = Vec3::splat(6e-45);
        let pdf = 1.782_42e-40f32;
        let s = BrdfSample::continuous(wo, f, pdf).unwrap();
        assert!(s.weight.is_finite(), "{s:?}");
        let want = f64::from(f.x) * f64::from(wo.z) / f64::from(pdf);
        assert!(
            (f64::from(s.weight.x) / want - 1.0).abs() < 1e-6,
            "{s:?} against {want}"
        );
        assert_eq!(s.with_pdf(pdf).weight, s.weight);
        let (f, pdf) = (Vec3::new(0.3, 0.2, 0.1), 0.7f32);
        let s = BrdfSample::continuous(wo, f, pdf).unwrap();
        assert_eq!(s.weight, f * (wo.z / pdf));
        assert_eq!(s.with_pdf(2.0).weight, f * (wo.z / 2.0));
    }

    /// A staircase declaration is read as a finite positive width, raised to the floor;
    /// anything else is none, and every pointer forwards the model's own.
    #[test]
    fn step_widths_are_sanitised_and_forwarded() {
        assert_eq!(usable_step_width(None), None);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(usable_step_width(Some(bad)), None, "{bad}");
        }
        assert_eq!(usable_step_width(Some(1e-9)), Some(MIN_STEP_WIDTH));
        assert_eq!(usable_step_width(Some(0.02)), Some(0.02));
        let merl_like = crate::models::merl::NEAREST_STEP_WIDTH;
        assert!((merl_like - 1f64.to_radians()).abs() < 1e-15);
        let lambert = crate::registry::create("lambert", core::iter::empty::<&str>()).unwrap();
        assert_eq!(lambert.step_width(), None);
        #[derive(Debug)]
        struct Table;
        impl Brdf for Table {
            fn name(&self) -> &'static str {
                "table"
            }
            fn params(&self) -> ParamSet {
                ParamSet::defaults("table", &[])
            }
            fn eval(&self, _: Vec3, _: Vec3) -> Vec3 {
                Vec3::ONE
            }
            fn step_width(&self) -> Option<f64> {
                Some(0.5)
            }
        }
        let boxed: Box<dyn Brdf> = Box::new(Table);
        assert_eq!(boxed.step_width(), Some(0.5));
        let arc: Arc<dyn Brdf> = Arc::from(boxed);
        assert_eq!(arc.step_width(), Some(0.5));
        let by_ref: &dyn Brdf = &arc;
        assert_eq!(by_ref.step_width(), Some(0.5));
    }
}
