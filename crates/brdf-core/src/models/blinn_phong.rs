use super::{
    cosine_pdf64, diffuse_probability, half64, pdf_pair, reflect_about_half, sample_mixture,
};
use crate::Symmetry;
use crate::brdf::{Brdf, BrdfSample};
use crate::error::ParamError;
use crate::geometry::{cos_power, cos_power_z, upper_pair};
use crate::math as m;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use crate::warp::sample_power_cosine64;
use core::f64::consts::{FRAC_1_PI, PI};
use glam::{DVec3, Vec2, Vec3};

/// `blinn-phong`: Blinn (1977) half-vector lobe with the exact normalisation,
/// f = kd/π + ks·N(n)·cos^n θh, N(n) = (n+2)(n+4)/(8π(2^{−n/2} + n)) (MODELS.md §4): the
/// lobe's albedo is exactly ks at normal incidence. Reciprocal; energy-conserving iff
/// kd + ks ≤ 1. Analytic sampler: power-cosine half vectors, pdf(wo) = pdf_h/(4 wo·h),
/// mixed with cosine sampling for kd.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlinnPhong {
    kd: Vec3,
    ks: Vec3,
    n: f32,
    norm: f64,
    p_diffuse: f64,
}

impl BlinnPhong {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::rgb("kd", [0.5; 3], 0.0, 1.0, "diffuse reflectance"),
        ParamSpec::rgb(
            "ks",
            [0.5; 3],
            0.0,
            1.0,
            "specular albedo at normal incidence",
        ),
        ParamSpec::scalar(
            "n",
            50.0,
            0.0,
            100_000.0,
            "half-vector exponent (lobe sharpness)",
        ),
    ];

    /// The exact normalisation N(n) = (n+2)(n+4)/(8π(2^{−n/2} + n)).
    #[must_use]
    pub fn normalization(n: f64) -> f64 {
        (n + 2.0) * (n + 4.0) / (8.0 * PI * (m::pow(2.0, -0.5 * n) + n))
    }

    /// A Blinn-Phong BRDF; every value in its range ([`BlinnPhong::PARAMS`]).
    pub fn new(kd: Vec3, ks: Vec3, n: f32) -> Result<Self, ParamError> {
        let (kd, ks, n) = (
            Self::PARAMS[0].check_rgb(kd)?,
            Self::PARAMS[1].check_rgb(ks)?,
            Self::PARAMS[2].check_scalar(n)?,
        );
        Ok(Self {
            kd,
            ks,
            n,
            norm: Self::normalization(f64::from(n)),
            p_diffuse: diffuse_probability(kd, ks),
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(p.rgb("kd")?, p.rgb("ks")?, p.scalar("n")?)
    }

    fn lobe_pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        let (h, u) = half64(wi, wo);
        let n = f64::from(self.n);
        (n + 1.0) * 0.5 * FRAC_1_PI * cos_power(h, DVec3::Z, n) / (4.0 * u)
    }
}

impl Brdf for BlinnPhong {
    fn name(&self) -> &'static str {
        "blinn-phong"
    }

    fn symmetry(&self) -> Symmetry {
        Symmetry::ISOTROPIC_RECIPROCAL
    }

    /// With ks = 0 only the diffuse kd/π is left; with n = 0 the lobe is a constant too.
    fn independent_of_incident(&self) -> bool {
        self.ks == Vec3::ZERO || self.n == 0.0
    }

    fn params(&self) -> ParamSet {
        ParamSet::from_checked(
            self.name(),
            Self::PARAMS,
            &[
                ParamValue::Rgb(self.kd),
                ParamValue::Rgb(self.ks),
                ParamValue::Scalar(self.n),
            ],
        )
    }

    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let Some((wi, wo)) = upper_pair(wi, wo) else {
            return Vec3::ZERO;
        };
        // cos^n θh from the unnormalised half vector: no square root or division to
        // normalise it on a rejection trial's critical path.
        let lobe = self.norm * cos_power_z(wi + wo, f64::from(self.n));
        (self.kd.as_dvec3() * FRAC_1_PI + self.ks.as_dvec3() * lobe).as_vec3()
    }

    fn has_analytic_sampler(&self) -> bool {
        true
    }

    fn sample_continuous(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
        // The lobe is drawn about wi lifted to the grazing floor (as pdf assumes); f and
        // pdf are those of the given wi.
        let wl = crate::geometry::lift_incident(wi);
        sample_mixture(self, wi, uc, u, self.p_diffuse, |u| {
            reflect_about_half(wl, sample_power_cosine64(u, f64::from(self.n)))
        })
    }

    fn pdf_continuous(&self, wi: Vec3, wo: Vec3) -> f32 {
        let wi = crate::geometry::lift_incident(wi);
        let Some((wi, wo)) = pdf_pair(wi, wo) else {
            return 0.0;
        };
        let p = self.p_diffuse;
        (p * cosine_pdf64(wo) + (1.0 - p) * self.lobe_pdf(wi, wo)) as f32
    }
}
