use super::{MirrorLobe, cosine_pdf64, diffuse_probability, pdf_pair, sample_mixture};
use crate::Symmetry;
use crate::brdf::{Brdf, BrdfSample};
use crate::error::{Constraint, ParamError};
use crate::geometry::upper_pair;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use core::f64::consts::FRAC_1_PI;
use glam::{Vec2, Vec3};

/// `lewis-phong`: Lewis (1994) normalised Phong, f = kd/π + ks·(n+2)/(2π)·cos^n α
/// (MODELS.md §5). Reciprocal and energy-conserving (kd + ks ≤ 1 per channel is required).
/// Analytic sampler: as `phong`, lobe sample weight ks(n+2)/(n+1)·cos θo.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LewisPhong {
    kd: Vec3,
    ks: Vec3,
    n: f32,
    lobe: MirrorLobe,
    norm: f64,
    p_diffuse: f64,
}

impl LewisPhong {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::rgb(
            "kd",
            [0.5; 3],
            0.0,
            1.0,
            "diffuse albedo (kd + ks <= 1 per channel)",
        ),
        ParamSpec::rgb(
            "ks",
            [0.5; 3],
            0.0,
            1.0,
            "specular albedo at normal incidence (kd + ks <= 1 per channel)",
        ),
        ParamSpec::scalar(
            "n",
            50.0,
            0.0,
            100_000.0,
            "specular exponent (lobe sharpness)",
        ),
    ];

    /// A Lewis-Phong BRDF; values in range and kd + ks ≤ 1 per channel
    /// ([`ParamError::Constraint`] otherwise).
    pub fn new(kd: Vec3, ks: Vec3, n: f32) -> Result<Self, ParamError> {
        let (kd, ks, n) = (
            Self::PARAMS[0].check_rgb(kd)?,
            Self::PARAMS[1].check_rgb(ks)?,
            Self::PARAMS[2].check_scalar(n)?,
        );
        check_energy("lewis-phong", kd, ks)?;
        Ok(Self {
            kd,
            ks,
            n,
            lobe: MirrorLobe { n: f64::from(n) },
            norm: (f64::from(n) + 2.0) * 0.5 * FRAC_1_PI,
            p_diffuse: diffuse_probability(kd, ks),
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(p.rgb("kd")?, p.rgb("ks")?, p.scalar("n")?)
    }
}

/// kd + ks ≤ 1 per channel (with room for decimal rounding of the inputs).
pub(crate) fn check_energy(model: &'static str, kd: Vec3, ks: Vec3) -> Result<(), ParamError> {
    let s = kd + ks;
    if s.max_element() > 1.0 + 1e-6 {
        return Err(ParamError::Constraint {
            model,
            constraint: Constraint::EnergyConservation {
                kd_plus_ks: s.to_array(),
            },
        });
    }
    Ok(())
}

impl Brdf for LewisPhong {
    fn name(&self) -> &'static str {
        "lewis-phong"
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
        let lobe = self.norm * self.lobe.value(wi, wo);
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
