use super::{
    cosine_pdf64, diffuse_probability, half64, pdf_pair, reflect_about_half, sample_mixture,
};
use crate::Symmetry;
use crate::brdf::{Brdf, BrdfSample};
use crate::error::ParamError;
use crate::geometry::upper_pair;
use crate::math as m;
use crate::microfacet::WardLobe;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use core::f64::consts::{FRAC_1_PI, PI};
use glam::{DVec3, Vec2, Vec3};

/// `ward`: Ward (1992) anisotropic, original normalisation (MODELS.md §10):
/// f = kd/π + ks·exp(−[(H.x/αx)² + (H.y/αy)²]/H.z²)/(4π αx αy √(cosθi cosθo)), H = wi + wo.
/// f grows as 1/√cosθo toward the horizon (integrable, unbounded). Reciprocal; not
/// energy-conserving near grazing. Analytic sampler: Walter (2005) half vectors, mixed with
/// cosine for kd.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ward {
    kd: Vec3,
    ks: Vec3,
    alpha_x: f32,
    alpha_y: f32,
    lobe: WardLobe,
    p_diffuse: f64,
    /// 1/αx² and 1/αy²: the exponent without a division per axis.
    inv_alpha2: (f64, f64),
    /// 1/(4π αx αy).
    lobe_scale: f64,
}

impl Ward {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::rgb("kd", [0.1; 3], 0.0, 1.0, "diffuse reflectance"),
        ParamSpec::rgb("ks", [0.5; 3], 0.0, 1.0, "specular reflectance"),
        ParamSpec::scalar("alpha_x", 0.1, 0.001, 1.0, "RMS slope along the tangent x"),
        ParamSpec::scalar("alpha_y", 0.3, 0.001, 1.0, "RMS slope along y"),
    ];

    /// A Ward BRDF; every value in its range ([`Ward::PARAMS`]).
    pub fn new(kd: Vec3, ks: Vec3, alpha_x: f32, alpha_y: f32) -> Result<Self, ParamError> {
        let kd = Self::PARAMS[0].check_rgb(kd)?;
        let ks = Self::PARAMS[1].check_rgb(ks)?;
        let alpha_x = Self::PARAMS[2].check_scalar(alpha_x)?;
        let alpha_y = Self::PARAMS[3].check_scalar(alpha_y)?;
        Ok(Self {
            kd,
            ks,
            alpha_x,
            alpha_y,
            lobe: WardLobe {
                alpha_x: f64::from(alpha_x),
                alpha_y: f64::from(alpha_y),
            },
            p_diffuse: diffuse_probability(kd, ks),
            inv_alpha2: (
                1.0 / (f64::from(alpha_x) * f64::from(alpha_x)),
                1.0 / (f64::from(alpha_y) * f64::from(alpha_y)),
            ),
            lobe_scale: 1.0 / (4.0 * PI * f64::from(alpha_x) * f64::from(alpha_y)),
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(
            p.rgb("kd")?,
            p.rgb("ks")?,
            p.scalar("alpha_x")?,
            p.scalar("alpha_y")?,
        )
    }

    fn lobe_pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        let (h, u) = half64(wi, wo);
        self.lobe.pdf_h(h) / (4.0 * u)
    }
}

impl Brdf for Ward {
    fn name(&self) -> &'static str {
        "ward"
    }

    fn symmetry(&self) -> Symmetry {
        if self.alpha_x == self.alpha_y {
            Symmetry::ISOTROPIC_RECIPROCAL
        } else {
            Symmetry::ORTHOTROPIC_RECIPROCAL
        }
    }

    fn params(&self) -> ParamSet {
        ParamSet::from_checked(
            self.name(),
            Self::PARAMS,
            &[
                ParamValue::Rgb(self.kd),
                ParamValue::Rgb(self.ks),
                ParamValue::Scalar(self.alpha_x),
                ParamValue::Scalar(self.alpha_y),
            ],
        )
    }

    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let Some((wi, wo)) = upper_pair(wi, wo) else {
            return Vec3::ZERO;
        };
        // The per-axis divisions are made once in `new`: the rejection samplers call this
        // once a trial, on their critical path, where every division's latency is paid in
        // full. (libm's exp is kept: `exp_nonpositive` timed no faster here.)
        let hv = wi + wo;
        let (ix, iy) = self.inv_alpha2;
        let e = (hv.x * hv.x * ix + hv.y * hv.y * iy) / (hv.z * hv.z);
        let spec = m::exp(-e) * self.lobe_scale / m::sqrt(wi.z * wo.z);
        (self.kd.as_dvec3() * FRAC_1_PI + self.ks.as_dvec3() * spec).as_vec3()
    }

    fn has_analytic_sampler(&self) -> bool {
        true
    }

    fn sample_continuous(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
        // The lobe is drawn about wi lifted to the grazing floor (as pdf assumes); f and
        // pdf are those of the given wi.
        let wl = crate::geometry::lift_incident(wi);
        sample_mixture(self, wi, uc, u, self.p_diffuse, |u| {
            reflect_about_half(wl, self.lobe.sample_h(u))
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
