use crate::Symmetry;
use crate::brdf::{Brdf, PeakHints};
use crate::error::ParamError;
use crate::geometry::{above_horizon, mirror};
use crate::param::{ParamSet, ParamSpec, ParamValue};
use glam::Vec3;

/// `mirror`: the perfect specular reflector, a Dirac delta toward r(wi) (MODELS.md §2).
/// `eval` and `pdf` of any explicit pair are 0; `sample` returns r(wi) exactly, flagged delta,
/// with weight = reflectance. It has no continuous part, so no quadtree can be built for it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mirror {
    reflectance: Vec3,
}

impl Mirror {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[ParamSpec::rgb(
        "reflectance",
        [1.0; 3],
        0.0,
        1.0,
        "fraction of the radiance reflected into the mirror direction",
    )];

    /// A perfect mirror; `reflectance` ∈ [0, 1] per channel.
    pub fn new(reflectance: Vec3) -> Result<Self, ParamError> {
        Ok(Self {
            reflectance: Self::PARAMS[0].check_rgb(reflectance)?,
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(p.rgb("reflectance")?)
    }
}

impl Brdf for Mirror {
    fn name(&self) -> &'static str {
        "mirror"
    }

    fn symmetry(&self) -> Symmetry {
        Symmetry::ISOTROPIC_RECIPROCAL
    }

    fn params(&self) -> ParamSet {
        ParamSet::from_checked(
            self.name(),
            Self::PARAMS,
            &[ParamValue::Rgb(self.reflectance)],
        )
    }

    fn eval(&self, _wi: Vec3, _wo: Vec3) -> Vec3 {
        Vec3::ZERO
    }

    fn is_delta(&self) -> bool {
        true
    }

    fn delta_reflectance(&self, wi: Vec3) -> Vec3 {
        if above_horizon(wi) {
            self.reflectance
        } else {
            Vec3::ZERO
        }
    }

    fn peak_hints(&self, wi: Vec3) -> PeakHints {
        let mut h = PeakHints::new();
        h.push(mirror(wi));
        h
    }

    fn has_analytic_sampler(&self) -> bool {
        true
    }
}
