use super::{MirrorLobe, cosine_pdf64, diffuse_probability, pdf_pair, sample_mixture};
use crate::Symmetry;
use crate::brdf::{Brdf, BrdfSample};
use crate::error::ParamError;
use crate::geometry::upper_pair;
use crate::math as m;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use core::f64::consts::{FRAC_1_PI, FRAC_2_PI};
use glam::{DVec3, Vec2, Vec3};

/// Strauss's Fresnel-like constant kf.
const KF: f64 = 1.12;
/// Strauss's shadowing constant ks.
const KS: f64 = 1.01;
/// Strauss's specular boost k.
const K: f64 = 0.1;

/// Strauss's Fresnel approximation F(x) on the **normalised angle** x = θ/(π/2) ∈ [0, 1] (not
/// a cosine): F(0) = 0, F(1) = 1 (MODELS.md §12).
#[must_use]
pub fn strauss_fresnel(x: f64) -> f64 {
    let inv = |t: f64| 1.0 / (t * t);
    (inv(x - KF) - inv(KF)) / (inv(1.0 - KF) - inv(KF))
}

/// Strauss's shadowing approximation G(x) on the normalised angle x = θ/(π/2): G(0) = 1,
/// G(1) = 0 (MODELS.md §12).
#[must_use]
pub fn strauss_shadow(x: f64) -> f64 {
    let inv = |t: f64| 1.0 / (t * t);
    (inv(1.0 - KS) - inv(x - KS)) / (inv(1.0 - KS) - inv(KS))
}

/// The normalised angle θ/(π/2) of a unit direction in the upper hemisphere, in plain
/// arithmetic (the backend's atan2 of the azimuthal length and z cost a third of the
/// evaluation): near the normal (z ≥ ½) θ = 2·asin √(sin²(θ/2)) with sin²(θ/2) =
/// (x² + y²)/(2(1 + z)), which does not cancel (acos z would: a rounded cosine leaves θ an
/// error of 10⁻¹⁶/sin θ), elsewhere θ = π/2 − asin z; both asin of at most ½ by
/// [`m::asin_to_half`] (3·10⁻¹³ relative).
#[inline]
fn normalised_angle(w: DVec3) -> f64 {
    let theta = if w.z >= 0.5 {
        let s2 = w.x * w.x + w.y * w.y;
        2.0 * m::asin_to_half(m::sqrt(s2 / (2.0 * (1.0 + w.z))).min(0.5))
    } else {
        core::f64::consts::FRAC_PI_2 - m::asin_to_half(w.z.max(0.0))
    };
    (theta * FRAC_2_PI).clamp(0.0, 1.0)
}

/// `strauss`: Strauss (1990) in its radiometric BRDF form (MODELS.md §12),
/// f = color·d·rd/π + Cs·rj·cos^hexp α / (π cos θi), with Strauss's F and G evaluated on the
/// normalised angles. **Not reciprocal** (F(xi), Cs and 1/cos θi belong to the light side) and
/// not energy-conserving (the 1/cos θi of the specular term grows without bound at grazing
/// incidence). Analytic sampler: cosine-weighted diffuse or a power-cosine lobe of exponent
/// hexp about r(wi), chosen per `wi` by luminance weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Strauss {
    color: Vec3,
    smoothness: f32,
    metalness: f32,
    transparency: f32,
    diffuse: DVec3,
    rn: f64,
    lobe: MirrorLobe,
}

impl Strauss {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::rgb("color", [0.8; 3], 0.0, 1.0, "surface colour"),
        ParamSpec::scalar(
            "smoothness",
            0.5,
            0.0,
            0.99,
            "0 = rough (wide, dim highlight) .. 0.99 = smooth (sharp highlight)",
        ),
        ParamSpec::scalar(
            "metalness",
            0.0,
            0.0,
            1.0,
            "0 = dielectric (white highlight) .. 1 = metal (highlight takes the colour)",
        ),
        ParamSpec::scalar(
            "transparency",
            0.0,
            0.0,
            1.0,
            "fraction transmitted (removed from the reflection)",
        ),
    ];

    /// A Strauss BRDF; every value must lie in its range ([`Strauss::PARAMS`]; smoothness 1
    /// would make the exponent 3/(1 − s) infinite, so it is out of range).
    pub fn new(
        color: Vec3,
        smoothness: f32,
        metalness: f32,
        transparency: f32,
    ) -> Result<Self, ParamError> {
        let color = Self::PARAMS[0].check_rgb(color)?;
        let smoothness = Self::PARAMS[1].check_scalar(smoothness)?;
        let metalness = Self::PARAMS[2].check_scalar(metalness)?;
        let transparency = Self::PARAMS[3].check_scalar(transparency)?;
        let (s, mt, t) = (
            f64::from(smoothness),
            f64::from(metalness),
            f64::from(transparency),
        );
        let d = 1.0 - mt * s;
        let rd = (1.0 - s * s * s) * (1.0 - t);
        Ok(Self {
            color,
            smoothness,
            metalness,
            transparency,
            diffuse: color.as_dvec3() * (d * rd * FRAC_1_PI),
            rn: (1.0 - t) - rd,
            lobe: MirrorLobe { n: 3.0 / (1.0 - s) },
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(
            p.rgb("color")?,
            p.scalar("smoothness")?,
            p.scalar("metalness")?,
            p.scalar("transparency")?,
        )
    }

    /// The highlight exponent hexp = 3/(1 − smoothness).
    #[must_use]
    pub fn exponent(&self) -> f64 {
        self.lobe.n
    }

    /// Cs/(π cos θi) and F(xi)·G(xi) for a unit `wi` above the horizon.
    fn light_side(&self, wi: DVec3) -> (DVec3, f64) {
        let xi = normalised_angle(wi);
        let fi = strauss_fresnel(xi);
        let cs =
            DVec3::ONE + f64::from(self.metalness) * (1.0 - fi) * (self.color.as_dvec3() - 1.0);
        (cs * (FRAC_1_PI / wi.z), fi * strauss_shadow(xi))
    }

    /// rj = min(1, rn + (rn + k)·j).
    fn rj(&self, j: f64) -> f64 {
        (self.rn + (self.rn + K) * j).min(1.0)
    }

    /// The probability of sampling the diffuse lobe for this `wi`: luminance of the diffuse
    /// albedo against the lobe's approximate albedo Cs·rj·2/(hexp + 1) (rj with G(xo) = 1).
    fn p_diffuse(&self, wi: Vec3) -> f64 {
        let Some(wi) = wi.as_dvec3().try_normalize() else {
            return 1.0;
        };
        if wi.z <= 0.0 {
            return 1.0;
        }
        let (cs, fg) = self.light_side(wi);
        let lobe = cs * (wi.z * core::f64::consts::PI * self.rj(fg) * 2.0 / (self.lobe.n + 1.0));
        diffuse_probability(
            (self.diffuse * core::f64::consts::PI).as_vec3(),
            lobe.as_vec3(),
        )
    }
}

impl Brdf for Strauss {
    fn name(&self) -> &'static str {
        "strauss"
    }

    fn symmetry(&self) -> Symmetry {
        // F(xi), Cs and 1/cos θi depend on the light side (MODELS.md §12).
        Symmetry {
            reciprocal: false,
            ..Symmetry::ISOTROPIC_RECIPROCAL
        }
    }

    fn params(&self) -> ParamSet {
        ParamSet::from_checked(
            self.name(),
            Self::PARAMS,
            &[
                ParamValue::Rgb(self.color),
                ParamValue::Scalar(self.smoothness),
                ParamValue::Scalar(self.metalness),
                ParamValue::Scalar(self.transparency),
            ],
        )
    }

    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let Some((wi, wo)) = upper_pair(wi, wo) else {
            return Vec3::ZERO;
        };
        let (cs, fg) = self.light_side(wi);
        let j = fg * strauss_shadow(normalised_angle(wo));
        let spec = cs * (self.rj(j) * self.lobe.value(wi, wo));
        (self.diffuse + spec).as_vec3()
    }

    fn has_analytic_sampler(&self) -> bool {
        true
    }

    fn sample_continuous(&self, wi: Vec3, uc: f32, u: Vec2) -> Option<BrdfSample> {
        // The lobe is drawn about wi lifted to the grazing floor (as pdf assumes); f and
        // pdf are those of the given wi.
        let wl = crate::geometry::lift_incident(wi);
        sample_mixture(self, wi, uc, u, self.p_diffuse(wl), |u| {
            self.lobe.sample(wl, u)
        })
    }

    fn pdf_continuous(&self, wi: Vec3, wo: Vec3) -> f32 {
        let wi = crate::geometry::lift_incident(wi);
        let p = self.p_diffuse(wi);
        let Some((wi, wo)) = pdf_pair(wi, wo) else {
            return 0.0;
        };
        (p * cosine_pdf64(wo) + (1.0 - p) * self.lobe.pdf(wi, wo)) as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f_and_g_match_the_oracles_of_models_md() {
        for (x, want) in [
            (0.25, 0.007_633),
            (0.5, 0.026_283),
            (0.75, 0.094_795),
            (0.9, 0.289_363),
        ] {
            assert!((strauss_fresnel(x) - want).abs() < 5e-7, "F({x})");
        }
        for (x, want) in [(0.5, 0.999_714), (0.9, 0.991_833)] {
            assert!((strauss_shadow(x) - want).abs() < 5e-7, "G({x})");
        }
        assert!(strauss_fresnel(0.0).abs() < 1e-15 && (strauss_fresnel(1.0) - 1.0).abs() < 1e-12);
        assert!((strauss_shadow(0.0) - 1.0).abs() < 1e-12 && strauss_shadow(1.0).abs() < 1e-12);
    }

    /// θ/(π/2), not the cosine, within 10⁻¹² relative of atan2's from 10⁻¹² rad of the
    /// normal (where acos of the rounded cosine would be 0) through both branches (z = ½ is
    /// θ = π/3) to the horizon.
    #[test]
    fn normalised_angle_is_the_angle_not_the_cosine() {
        let mut worst = 0.0f64;
        for t in [
            1e-12,
            1e-8,
            1e-3,
            0.3,
            1.0,
            core::f64::consts::FRAC_PI_3 - 1e-9,
            core::f64::consts::FRAC_PI_3 + 1e-9,
            1.5,
            core::f64::consts::FRAC_PI_2 - 1e-4,
            core::f64::consts::FRAC_PI_2,
        ] {
            let w = DVec3::new(m::sin(t) * 0.6, m::sin(t) * 0.8, m::cos(t));
            let want = m::atan2(m::sqrt(w.x * w.x + w.y * w.y), w.z) * FRAC_2_PI;
            let got = normalised_angle(w);
            worst = worst.max((got - want).abs() / want);
        }
        assert!(worst < 1e-12, "worst relative difference {worst:e}");
        assert_eq!(normalised_angle(DVec3::Z), 0.0);
    }
}
