use crate::Symmetry;
use crate::brdf::{Brdf, BrdfSample};
use crate::error::ParamError;
use crate::geometry::{above_horizon, upper_pair};
use crate::param::{ParamSet, ParamSpec, ParamValue};
use crate::warp::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use core::f32::consts::FRAC_1_PI;
use glam::{Vec2, Vec3};

/// `lambert`: the perfect diffuser, f = albedo/π (MODELS.md §1). Reciprocal; its directional
/// albedo is `albedo` at every angle. Analytic sampler: cosine-weighted (weight = albedo).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    albedo: Vec3,
}

impl Lambert {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[ParamSpec::rgb(
        "albedo",
        [0.8; 3],
        0.0,
        1.0,
        "reflectance: the directional albedo at every angle",
    )];

    /// A Lambertian surface; `albedo` ∈ [0, 1] per channel.
    pub fn new(albedo: Vec3) -> Result<Self, ParamError> {
        Ok(Self {
            albedo: Self::PARAMS[0].check_rgb(albedo)?,
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(p.rgb("albedo")?)
    }
}

impl Brdf for Lambert {
    fn name(&self) -> &'static str {
        "lambert"
    }

    fn symmetry(&self) -> Symmetry {
        Symmetry::ISOTROPIC_RECIPROCAL
    }

    /// f = albedo/π at every pair.
    fn independent_of_incident(&self) -> bool {
        true
    }

    fn params(&self) -> ParamSet {
        ParamSet::from_checked(self.name(), Self::PARAMS, &[ParamValue::Rgb(self.albedo)])
    }

    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        if upper_pair(wi, wo).is_none() {
            return Vec3::ZERO;
        }
        self.albedo * FRAC_1_PI
    }

    fn has_analytic_sampler(&self) -> bool {
        true
    }

    fn sample_continuous(&self, wi: Vec3, _uc: f32, u: Vec2) -> Option<BrdfSample> {
        if !above_horizon(wi) {
            return None;
        }
        let wo = sample_cosine_hemisphere(u);
        BrdfSample::continuous(wo, self.eval(wi, wo), cosine_hemisphere_pdf(wo.z))
    }

    fn pdf_continuous(&self, wi: Vec3, wo: Vec3) -> f32 {
        if upper_pair(wi, wo).is_none() {
            return 0.0;
        }
        cosine_hemisphere_pdf(wo.z)
    }
}
