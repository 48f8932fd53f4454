use crate::Symmetry;
use crate::brdf::{Brdf, BrdfSample, PeakHints};
use crate::error::ParamError;
use crate::geometry::{
    above_horizon, cos_delta_phi64, lift_to_grazing_floor, mirror, normalize_f64, upper_pair,
};
use crate::math as m;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use crate::warp::{cosine_hemisphere_pdf, sample_cosine_hemisphere};
use core::f64::consts::{FRAC_1_PI, PI};
use glam::{Vec2, Vec3};

/// `oren-nayar`: Oren & Nayar (1994), the full model with the inter-reflection term
/// (MODELS.md §9), clamped at 0. σ = 0 is Lambert exactly. Reciprocal; slightly above unit
/// albedo at grazing for ρ = 1. Analytic sampler: cosine-weighted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrenNayar {
    albedo: Vec3,
    sigma: f32,
    c1: f64,
    c2: f64,
    c3: f64,
    c4: f64,
}

impl OrenNayar {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::rgb("albedo", [0.8; 3], 0.0, 1.0, "facet albedo ρ"),
        ParamSpec::scalar(
            "sigma",
            0.35,
            0.0,
            1.5,
            "standard deviation of the facet slope angle, radians",
        ),
    ];

    /// An Oren-Nayar BRDF; every value in its range ([`OrenNayar::PARAMS`]).
    pub fn new(albedo: Vec3, sigma: f32) -> Result<Self, ParamError> {
        let (albedo, sigma) = (
            Self::PARAMS[0].check_rgb(albedo)?,
            Self::PARAMS[1].check_scalar(sigma)?,
        );
        let s2 = f64::from(sigma) * f64::from(sigma);
        Ok(Self {
            albedo,
            sigma,
            c1: 1.0 - 0.5 * s2 / (s2 + 0.33),
            c2: 0.45 * s2 / (s2 + 0.09),
            c3: 0.125 * s2 / (s2 + 0.09),
            c4: 0.17 * s2 / (s2 + 0.13),
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(p.rgb("albedo")?, p.scalar("sigma")?)
    }
}

impl Brdf for OrenNayar {
    fn name(&self) -> &'static str {
        "oren-nayar"
    }

    fn symmetry(&self) -> Symmetry {
        Symmetry::ISOTROPIC_RECIPROCAL
    }

    /// At σ = 0 the model is Lambert's: A = 1, B = 0.
    fn independent_of_incident(&self) -> bool {
        self.sigma == 0.0
    }

    fn params(&self) -> ParamSet {
        ParamSet::from_checked(
            self.name(),
            Self::PARAMS,
            &[ParamValue::Rgb(self.albedo), ParamValue::Scalar(self.sigma)],
        )
    }

    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let Some((wi, wo)) = upper_pair(wi, wo) else {
            return Vec3::ZERO;
        };
        let (ci, co) = (wi.z.min(1.0), wo.z.min(1.0));
        let (ti, to) = (m::acos_nonnegative(ci), m::acos_nonnegative(co));
        let (alpha, beta) = (ti.max(to), ti.min(to));
        // sin β, tan β and sin α from cosines (no tan of an angle near π/2); 1 − c² as
        // (1 − c)(1 + c), which does not cancel for c near 1.
        let (cb, ca) = (ci.max(co), ci.min(co));
        let sin_beta = m::sqrt(((1.0 - cb) * (1.0 + cb)).max(0.0));
        let tan_beta = sin_beta / cb;
        let sin_alpha = m::sqrt(((1.0 - ca) * (1.0 + ca)).max(0.0));
        let cdp = cos_delta_phi64(wi, wo);
        let b2p = 2.0 * beta / PI;
        let c2 = if cdp >= 0.0 {
            self.c2 * sin_alpha
        } else {
            self.c2 * (sin_alpha - b2p * b2p * b2p)
        };
        let q = 4.0 * alpha * beta / (PI * PI);
        let c3 = self.c3 * q * q;
        // tan((α + β)/2) = (sin α + sin β)/(cos α + cos β), exactly: no tangent to call, and
        // the denominator is at least twice the grazing floor's cosine.
        let tan_half_sum = (sin_alpha + sin_beta) / (ca + cb);
        let direct = self.c1 + cdp * c2 * tan_beta + (1.0 - cdp.abs()) * c3 * tan_half_sum;
        let inter = self.c4 * (1.0 - cdp * b2p * b2p);
        self.albedo
            .as_dvec3()
            .map(|rho| (rho * FRAC_1_PI * direct + rho * rho * FRAC_1_PI * inter).max(0.0))
            .as_vec3()
    }

    fn peak_hints(&self, wi: Vec3) -> PeakHints {
        // Rough Oren-Nayar surfaces peak toward the light (backscatter).
        let mut h = PeakHints::new();
        h.push(wi);
        h.push(Vec3::Z);
        h.push(mirror(wi));
        h
    }

    /// θo = θi, where α = max(θi, θo) and β = min(θi, θo) exchange: sin α·tan β has the
    /// slopes sin θi/cos²θi and sin θi on its two sides. The cosine is the one
    /// [`Brdf::eval`] compares with (the unit, lifted wi's z).
    fn crease_cosine(&self, wi: Vec3) -> Option<f64> {
        above_horizon(wi).then(|| {
            lift_to_grazing_floor(normalize_f64(wi.as_dvec3()))
                .z
                .min(1.0)
        })
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
