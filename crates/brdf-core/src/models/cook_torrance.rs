use super::{
    cosine_pdf64, diffuse_probability, half64, pdf_pair, reflect_about_half, sample_mixture,
};
use crate::Symmetry;
use crate::brdf::{Brdf, BrdfSample};
use crate::error::ParamError;
use crate::geometry::upper_pair;
use crate::math as m;
use crate::microfacet::Beckmann;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use core::f64::consts::FRAC_1_PI;
use glam::{DVec3, Vec2, Vec3};

/// `cook-torrance`: Cook & Torrance (1982) in the consistent normalised microfacet form
/// (MODELS.md §6): f = kd/π + F(u)·D(h)·G/(4 cosθi cosθo), normalised Beckmann D, V-cavity
/// G, unpolarised dielectric Fresnel with η = (1+√f0)/(1−√f0). Reciprocal, energy-conserving.
/// Analytic sampler: Beckmann half vectors, pdf(wo) = D cosθh/(4u), mixed with cosine for kd.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CookTorrance {
    m: f32,
    f0: Vec3,
    kd: Vec3,
    eta: DVec3,
    dist: Beckmann,
}

impl CookTorrance {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::scalar(
            "m",
            0.2,
            0.001,
            1.0,
            "RMS microfacet slope (Beckmann roughness)",
        ),
        ParamSpec::rgb(
            "f0",
            [0.95, 0.64, 0.54],
            0.0,
            0.999,
            "Fresnel reflectance at normal incidence",
        ),
        ParamSpec::rgb("kd", [0.0; 3], 0.0, 1.0, "diffuse reflectance"),
    ];

    /// A Cook-Torrance BRDF; every value in its range ([`CookTorrance::PARAMS`]).
    pub fn new(m: f32, f0: Vec3, kd: Vec3) -> Result<Self, ParamError> {
        let (m, f0, kd) = (
            Self::PARAMS[0].check_scalar(m)?,
            Self::PARAMS[1].check_rgb(f0)?,
            Self::PARAMS[2].check_rgb(kd)?,
        );
        let eta = f0.as_dvec3().map(|f| {
            let s = m::sqrt(f);
            (1.0 + s) / (1.0 - s)
        });
        Ok(Self {
            m,
            f0,
            kd,
            eta,
            dist: Beckmann { m: f64::from(m) },
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(p.scalar("m")?, p.rgb("f0")?, p.rgb("kd")?)
    }

    /// The unpolarised dielectric Fresnel reflectance per channel at u = cos of the angle
    /// between wi and h.
    #[must_use]
    pub fn fresnel(&self, u: f64) -> DVec3 {
        self.eta.map(|eta| fresnel_dielectric(eta, u))
    }

    /// D·G/(4 cosθi cosθo): the specular term with F ≡ 1 (0 outside the upper hemisphere).
    /// Exposed so that tests can check MODELS.md's F ≡ 1 oracles.
    #[must_use]
    pub fn specular_without_fresnel(&self, wi: Vec3, wo: Vec3) -> f64 {
        upper_pair(wi, wo).map_or(0.0, |(wi, wo)| self.dg(wi, wo).0)
    }

    /// (D·G/(4 cosθi cosθo), u) for f64 unit directions in the upper hemisphere.
    fn dg(&self, wi: DVec3, wo: DVec3) -> (f64, f64) {
        let (h, u) = half64(wi, wo);
        let g = (2.0 * h.z * wo.z / u).min(2.0 * h.z * wi.z / u).min(1.0);
        (self.dist.d(h) * g / (4.0 * wi.z * wo.z), u)
    }

    fn p_diffuse(&self, wi: Vec3) -> f64 {
        diffuse_probability(
            self.kd,
            self.fresnel(f64::from(wi.z).clamp(0.0, 1.0)).as_vec3(),
        )
    }

    fn lobe_pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        let (h, u) = half64(wi, wo);
        self.dist.pdf_h(h) / (4.0 * u)
    }
}

/// F for a dielectric of relative index `eta` at cosine `u` (MODELS.md §6).
///
/// g − u is computed as (η² − 1)/(g + u) (the same value: g² − u² = η² − 1), so that F is
/// exactly 0 at η = 1 (f0 = 0) instead of rounding noise: a tree built on noise never
/// converges.
fn fresnel_dielectric(eta: f64, u: f64) -> f64 {
    let e2 = (eta - 1.0) * (eta + 1.0);
    let g = m::sqrt((e2 + u * u).max(0.0));
    if g + u <= 0.0 {
        return 1.0;
    }
    let gmu = e2 / (g + u);
    let a = gmu / (g + u);
    let b = (u * (g + u) - 1.0) / (u * gmu + 1.0);
    0.5 * a * a * (1.0 + b * b)
}

impl Brdf for CookTorrance {
    fn name(&self) -> &'static str {
        "cook-torrance"
    }

    fn symmetry(&self) -> Symmetry {
        Symmetry::ISOTROPIC_RECIPROCAL
    }

    fn params(&self) -> ParamSet {
        ParamSet::from_checked(
            self.name(),
            Self::PARAMS,
            &[
                ParamValue::Scalar(self.m),
                ParamValue::Rgb(self.f0),
                ParamValue::Rgb(self.kd),
            ],
        )
    }

    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let Some((wi, wo)) = upper_pair(wi, wo) else {
            return Vec3::ZERO;
        };
        let (spec, u) = self.dg(wi, wo);
        (self.kd.as_dvec3() * FRAC_1_PI + self.fresnel(u) * spec).as_vec3()
    }

    fn has_analytic_sampler(&self) -> bool {
        true
    }

    fn sample_continuous(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
        // The lobe is drawn about wi lifted to the grazing floor (as pdf assumes); f and
        // pdf are those of the given wi.
        let wl = crate::geometry::lift_incident(wi);
        sample_mixture(self, wi, uc, u, self.p_diffuse(wl), |u| {
            reflect_about_half(wl, self.dist.sample_h(u))
        })
    }

    fn pdf_continuous(&self, wi: Vec3, wo: Vec3) -> f32 {
        let wi = crate::geometry::lift_incident(wi);
        let p = self.p_diffuse(wi);
        let Some((wi, wo)) = pdf_pair(wi, wo) else {
            return 0.0;
        };
        (p * cosine_pdf64(wo) + (1.0 - p) * self.lobe_pdf(wi, wo)) as f32
    }
}
