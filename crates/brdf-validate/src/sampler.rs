//! What a test draws from: this crate's [`Sampler`] trait, implemented for every
//! [`DirectionSampler`] of the workspace and, through [`FnSampler`], for a pair of closures
//! around a renderer's own BSDF.

use brdf_core::geometry::luminance;
use glam::{Vec2, Vec3};
use quadtree_sampler::{DensityHints, DirectionSampler, uniform_f32};
use rand_core::Rng;

/// One drawn direction, as far as a test needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drawn {
    /// The direction, local frame (z up); a test counts it outside the domain unless it is
    /// finite and strictly above the horizon.
    pub wo: Vec3,
    /// The density the sampler reports for `wo`, **per unit solid angle**.
    pub pdf: f32,
    /// True when `wo` came from a Dirac delta lobe (a test counts it outside the domain).
    pub delta: bool,
    /// The luminances of f_r and of the estimator weight f·cos θ/pdf, when the sampler
    /// reports them: the test then checks the weight against f·cos θ/pdf.
    pub f_and_weight: Option<(f32, f32)>,
}

/// A sampler of outgoing directions at one incident direction, as a test sees it.
pub trait Sampler: Sync {
    /// A short name for reports.
    fn name(&self) -> &str;

    /// Draws one direction with every random number taken from `rng`; `None` when the
    /// sampler gave no direction (a test counts it lost).
    fn draw(&self, rng: &mut dyn Rng) -> Option<Drawn>;

    /// The density of [`Sampler::draw`] at `wo`, **per unit solid angle**.
    fn pdf(&self, wo: Vec3) -> f32;

    /// Where the density may be concentrated beyond the model's peak hints (local frame):
    /// peaks and [`quadtree_sampler::Ridge`] planes, at which the integration of the
    /// sampler's own cell probabilities cuts its ranges (a lobe narrower than the
    /// integrator's node spacing is found only there). None by default; a sampler whose
    /// pdf has needles where its model's f has none (a baked sampler's rotated neighbour
    /// trees) names them.
    fn density_hints(&self) -> DensityHints {
        DensityHints::default()
    }
}

impl<S: DirectionSampler + ?Sized> Sampler for S {
    fn name(&self) -> &str {
        DirectionSampler::name(self)
    }

    fn draw(&self, rng: &mut dyn Rng) -> Option<Drawn> {
        self.sample(rng).map(|s| Drawn {
            wo: s.wo,
            pdf: s.pdf,
            delta: s.delta,
            f_and_weight: Some((luminance(s.f), luminance(s.weight))),
        })
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        DirectionSampler::pdf(self, wo)
    }

    fn density_hints(&self) -> DensityHints {
        DirectionSampler::density_hints(self)
    }
}

/// A sampler made of two closures, for a BSDF outside this workspace: `sample(uc, u)` maps
/// uniforms in [0, 1) (pbrt's `Sample_f(uc, u)`: `uc` for a lobe choice, `u` for the warp) to
/// a direction and its pdf per solid angle, or `None`; `pdf(wo)` is the density per solid
/// angle. The test draws `uc`, `u.x`, `u.y` in that order, 24-bit uniforms each.
pub struct FnSampler<S, P> {
    name: String,
    sample: S,
    pdf: P,
}

impl<S, P> FnSampler<S, P>
where
    S: Fn(f32, Vec2) -> Option<(Vec3, f32)> + Sync,
    P: Fn(Vec3) -> f32 + Sync,
{
    /// The sampler called `name` with the two closures.
    pub fn new(name: impl Into<String>, sample: S, pdf: P) -> Self {
        Self {
            name: name.into(),
            sample,
            pdf,
        }
    }
}

impl<S, P> Sampler for FnSampler<S, P>
where
    S: Fn(f32, Vec2) -> Option<(Vec3, f32)> + Sync,
    P: Fn(Vec3) -> f32 + Sync,
{
    fn name(&self) -> &str {
        &self.name
    }

    fn draw(&self, rng: &mut dyn Rng) -> Option<Drawn> {
        let uc = uniform_f32(rng);
        let u = Vec2::new(uniform_f32(rng), uniform_f32(rng));
        (self.sample)(uc, u).map(|(wo, pdf)| Drawn {
            wo,
            pdf,
            delta: false,
            f_and_weight: None,
        })
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        (self.pdf)(wo)
    }
}
