use super::{half64, pdf_pair, reflect_about_half, sample_mixture};
use crate::Symmetry;
use crate::brdf::{Brdf, BrdfSample};
use crate::error::ParamError;
use crate::geometry::upper_pair;
use crate::math as m;
use crate::microfacet::Ggx;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use core::f64::consts::PI;
use glam::{DVec3, Vec2, Vec3};

/// `schlick`: Schlick (1994) single slab, single scattering (MODELS.md §11):
/// f = S(u)·Z(t)·A(w)/(4π (r + (1−r)cosθi)(r + (1−r)cosθo)), with S the Schlick Fresnel,
/// Z(t) = r/(1 + r t² − t²)², A(w) = √(p/(p² − p²w² + w²)), w = cos φh. No multiple
/// scattering term. Reciprocal. Analytic sampler: Z is GGX with α² = r.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schlick {
    c: Vec3,
    r: f32,
    p: f32,
    ggx: Ggx,
}

impl Schlick {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::rgb("c", [0.5; 3], 0.0, 1.0, "reflectance at normal incidence"),
        ParamSpec::scalar(
            "r",
            0.3,
            0.001,
            1.0,
            "roughness (0 mirror-like, 1 diffuse-like)",
        ),
        ParamSpec::scalar(
            "p",
            1.0,
            0.001,
            1.0,
            "isotropy (1 isotropic; small = anisotropic along x)",
        ),
    ];

    /// A Schlick BRDF; every value in its range ([`Schlick::PARAMS`]).
    pub fn new(c: Vec3, r: f32, p: f32) -> Result<Self, ParamError> {
        let (c, r, p) = (
            Self::PARAMS[0].check_rgb(c)?,
            Self::PARAMS[1].check_scalar(r)?,
            Self::PARAMS[2].check_scalar(p)?,
        );
        Ok(Self {
            c,
            r,
            p,
            ggx: Ggx {
                alpha2: f64::from(r),
            },
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(p.rgb("c")?, p.scalar("r")?, p.scalar("p")?)
    }
}

impl Brdf for Schlick {
    fn name(&self) -> &'static str {
        "schlick"
    }

    fn symmetry(&self) -> Symmetry {
        if self.p == 1.0 {
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
                ParamValue::Rgb(self.c),
                ParamValue::Scalar(self.r),
                ParamValue::Scalar(self.p),
            ],
        )
    }

    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let Some((wi, wo)) = upper_pair(wi, wo) else {
            return Vec3::ZERO;
        };
        let (h, u) = half64(wi, wo);
        let (r, p) = (f64::from(self.r), f64::from(self.p));
        let t = h.z;
        let q = 1.0 + r * t * t - t * t;
        // Z = r/q², A = √(p/(p² − p²w² + w²)) with w = cos φh, so w² = hx²/(hx² + hy²):
        // one square root and one division fewer than through w itself, and Z's division
        // joins the last one.
        let hxy2 = h.x * h.x + h.y * h.y;
        let w2 = if hxy2 > 0.0 { h.x * h.x / hxy2 } else { 1.0 };
        let a = m::sqrt(p / (p * p + (1.0 - p * p) * w2));
        let g = (r + (1.0 - r) * wi.z) * (r + (1.0 - r) * wo.z);
        let k = r * a / (q * q * (4.0 * PI * g));
        // (1 − u)⁵ by three multiplies: a libm pow was a fifth of an evaluation.
        let x = 1.0 - u;
        let x2 = x * x;
        let f5 = x2 * x2 * x;
        self.c
            .as_dvec3()
            .map(|c| (c + (1.0 - c) * f5) * k)
            .as_vec3()
    }

    fn has_analytic_sampler(&self) -> bool {
        true
    }

    fn sample_continuous(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
        // The lobe is drawn about wi lifted to the grazing floor (as pdf assumes); f and
        // pdf are those of the given wi.
        let wl = crate::geometry::lift_incident(wi);
        sample_mixture(self, wi, uc, u, 0.0, |u| {
            reflect_about_half(wl, self.ggx.sample_h(u))
        })
    }

    fn pdf_continuous(&self, wi: Vec3, wo: Vec3) -> f32 {
        let wi = crate::geometry::lift_incident(wi);
        let Some((wi, wo)) = pdf_pair(wi, wo) else {
            return 0.0;
        };
        let (h, u): (DVec3, f64) = half64(wi, wo);
        (self.ggx.pdf_h(h) / (4.0 * u)) as f32
    }
}
