use super::{MirrorLobe, cosine_pdf64, diffuse_probability, pdf_pair, sample_mixture};
use crate::Symmetry;
use crate::brdf::{Brdf, BrdfSample};
use crate::error::ParamError;
use crate::geometry::upper_pair;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use core::f64::consts::{FRAC_1_PI, PI};
use glam::{Vec2, Vec3};

/// `phong`: Phong (1975) in its reciprocal, unnormalised BRDF form, f = kd/π + ks·cos^n α
/// with cos α = max(0, r(wi)·wo) (MODELS.md §3). Reciprocal; **not** energy-conserving in
/// general (lobe albedo at normal incidence ks·2π/(n+2)). Analytic sampler: diffuse or
/// power-cosine lobe about r(wi), chosen by luminance weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phong {
    kd: Vec3,
    ks: Vec3,
    n: f32,
    lobe: MirrorLobe,
    p_diffuse: f64,
}

impl Phong {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::rgb("kd", [0.5; 3], 0.0, 1.0, "diffuse reflectance"),
        ParamSpec::rgb(
            "ks",
            [0.5; 3],
            0.0,
            1.0,
            "specular coefficient (peak value of the lobe, 1/sr)",
        ),
        ParamSpec::scalar(
            "n",
            50.0,
            0.0,
            100_000.0,
            "specular exponent (lobe sharpness)",
        ),
    ];

    /// A Phong BRDF; every value must lie in its range ([`Phong::PARAMS`]).
    pub fn new(kd: Vec3, ks: Vec3, n: f32) -> Result<Self, ParamError> {
        let (kd, ks, n) = (
            Self::PARAMS[0].check_rgb(kd)?,
            Self::PARAMS[1].check_rgb(ks)?,
            Self::PARAMS[2].check_scalar(n)?,
        );
        let lobe_albedo = ks * (2.0 * PI / (f64::from(n) + 2.0)) as f32;
        Ok(Self {
            kd,
            ks,
            n,
            lobe: MirrorLobe { n: f64::from(n) },
            p_diffuse: diffuse_probability(kd, lobe_albedo),
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(p.rgb("kd")?, p.rgb("ks")?, p.scalar("n")?)
    }
}

impl Brdf for Phong {
    fn name(&self) -> &'static str {
        "phong"
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
        let lobe = self.lobe.value(wi, wo);
        (self.kd.as_dvec3() * FRAC_1_PI + self.ks.as_dvec3() * lobe).as_vec3()
    }

    fn has_analytic_sampler(&self) -> bool {
        true
    }

    fn sample_continuous(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
        // The lobe is drawn about wi lifted to the grazing floor (as pdf assumes); f and
        // pdf are those of the given wi.
        let wl = crate::geometry::lift_incident(wi);
        sample_mixture(self, wi, uc, u, self.p_diffuse, |u| self.lobe.sample(wl, u))
    }

    fn pdf_continuous(&self, wi: Vec3, wo: Vec3) -> f32 {
        let wi = crate::geometry::lift_incident(wi);
        let Some((wi, wo)) = pdf_pair(wi, wo) else {
            return 0.0;
        };
        let p = self.p_diffuse;
        (p * cosine_pdf64(wo) + (1.0 - p) * self.lobe.pdf(wi, wo)) as f32
    }
}
