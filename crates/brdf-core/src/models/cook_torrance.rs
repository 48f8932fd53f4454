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
    /// η² − 1 per channel, Fresnel's `e2` ([`fresnel_dielectric`]).
    eta2_minus_1: DVec3,
    /// 1/m² and 1/(π m²): Beckmann's exponent and normalisation.
    inv_m2: f64,
    inv_pi_m2: f64,
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
        let m2 = f64::from(m) * f64::from(m);
        Ok(Self {
            m,
            f0,
            kd,
            eta2_minus_1: eta.map(|eta| (eta - 1.0) * (eta + 1.0)),
            inv_m2: 1.0 / m2,
            inv_pi_m2: FRAC_1_PI / m2,
            dist: Beckmann { m: f64::from(m) },
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(p.scalar("m")?, p.rgb("f0")?, p.rgb("kd")?)
    }

    /// The unpolarised dielectric Fresnel reflectance per channel at u = cos of the angle
    /// between wi and h.
    #[inline]
    #[must_use]
    pub fn fresnel(&self, u: f64) -> DVec3 {
        self.fresnel_squared(u, u * u)
    }

    /// [`CookTorrance::fresnel`] given u and u² (which `eval` knows without u's square
    /// root, so that the channels' square roots need not wait for it).
    #[inline(always)]
    fn fresnel_squared(&self, u: f64, u2: f64) -> DVec3 {
        self.eta2_minus_1.map(|e2| fresnel_dielectric(e2, u, u2))
    }

    /// D·G/(4 cosθi cosθo): the specular term with F ≡ 1 (0 outside the upper hemisphere).
    /// Exposed so that tests can check MODELS.md's F ≡ 1 oracles.
    #[must_use]
    pub fn specular_without_fresnel(&self, wi: Vec3, wo: Vec3) -> f64 {
        upper_pair(wi, wo).map_or(0.0, |(wi, wo)| self.dg(wi, wo).0)
    }

    /// (D·G/(4 cosθi cosθo), l = |wi + wo|² = 4u²) for f64 unit directions in the upper
    /// hemisphere (both cosines at least [`crate::geometry::GRAZING_COS`], as `upper_pair`
    /// lifts them).
    ///
    /// Written from the unnormalised half vector v = wi + wo, with one division where the
    /// textbook form (normalise h, then tan²θh, D, G and the cosines' product each divide)
    /// has six: the rejection samplers pay this once a trial on their critical path, where a
    /// division's latency is paid in full and their throughput is the divider's. With
    /// l = |v|² = 2(1 + wi·wo) for unit vectors: u = wi·h = √l/2, cos²θh = v_z²/l,
    /// tan²θh = (v_x² + v_y²)/v_z² (no cancellation near the normal), h_z/u = 2v_z/l, so
    ///
    /// D = exp(−tan²θh/m²)·l²/(π m² v_z⁴),  G = min(1, 4 v_z min(cosθi, cosθo)/l),
    ///
    /// and D·G/(4 cosθi cosθo) = exp(−tan²θh/m²)/(π m²)·min(l²/(4 cosθi cosθo),
    /// l·v_z/max(cosθi, cosθo))/v_z⁴, whose divisions share one reciprocal
    /// 1/(4 cosθi cosθo·max·v_z⁴). Equal to the textbook form to rounding (a test).
    #[inline(always)]
    fn dg(&self, wi: DVec3, wo: DVec3) -> (f64, f64) {
        let v = wi + wo;
        let l = v.length_squared();
        let (vz2, r2) = (v.z * v.z, v.x * v.x + v.y * v.y);
        let (c4, big) = (4.0 * wi.z * wo.z, wi.z.max(wo.z));
        let k = 1.0 / (c4 * big * vz2 * vz2);
        let tan2 = r2 * (k * c4 * big * vz2);
        let shadowed = (l * l * big).min(l * v.z * c4) * k;
        (m::exp(-tan2 * self.inv_m2) * self.inv_pi_m2 * shadowed, l)
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

/// F for a dielectric with `e2` = η² − 1 (η its relative index) at cosine `u` ∈ [0, 1]
/// (`u2` = u²; MODELS.md §6): with g = √(η² − 1 + u²) and s = g + u,
///
/// F = ½ (g − u)²/s² · (1 + (u s − 1)²/(u (g − u) + 1)²).
///
/// g − u is written (η² − 1)/s (the same value: g² − u² = η² − 1), so that F is exactly 0
/// at η = 1 (f0 = 0) instead of rounding noise: a tree built on noise never converges. Then
/// a = (g − u)/s = e2/s² and b = (u s − 1)/(u (g − u) + 1) = (u s − 1)·s/(u·e2 + s) share one
/// reciprocal k = 1/(s²·(u·e2 + s)): one division a channel instead of three (Cook–Torrance
/// evaluates three channels a call, on a rejection trial's critical path).
#[inline(always)]
fn fresnel_dielectric(e2: f64, u: f64, u2: f64) -> f64 {
    let g = m::sqrt((e2 + u2).max(0.0));
    let s = g + u;
    if s <= 0.0 {
        return 1.0;
    }
    let d = u * e2 + s;
    let k = 1.0 / (s * s * d);
    let a = e2 * d * k;
    let b = (u * s - 1.0) * (s * s * s) * k;
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
        let (spec, l) = self.dg(wi, wo);
        let f = self.fresnel_squared(0.5 * m::sqrt(l), 0.25 * l);
        (self.kd.as_dvec3() * FRAC_1_PI + f * spec).as_vec3()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::GRAZING_COS;

    /// MODELS.md §6 as written: normalised h, tan²θh, D, G and F each with their own
    /// divisions (tan²θh as (h_x² + h_y²)/h_z², not (1 − h_z²)/h_z², whose cancellation
    /// near the normal costs 10⁻¹⁰ of D at m = 0.001).
    fn textbook(ct: &CookTorrance, wi: DVec3, wo: DVec3) -> (f64, DVec3) {
        let (h, u) = half64(wi, wo);
        let c2 = h.z * h.z;
        let tan2 = (h.x * h.x + h.y * h.y) / c2;
        let m2 = f64::from(ct.m) * f64::from(ct.m);
        let d = m::exp(-tan2 / m2) / (core::f64::consts::PI * m2 * c2 * c2);
        let g = (2.0 * h.z * wo.z / u).min(2.0 * h.z * wi.z / u).min(1.0);
        // η from f0 as MODELS.md §6 gives it, independently of `new`.
        let eta = ct
            .f0
            .as_dvec3()
            .map(|f| (1.0 + m::sqrt(f)) / (1.0 - m::sqrt(f)));
        let f = eta.map(|eta| {
            let g = m::sqrt(eta * eta - 1.0 + u * u);
            let a = (g - u) / (g + u);
            let b = (u * (g + u) - 1.0) / (u * (g - u) + 1.0);
            0.5 * a * a * (1.0 + b * b)
        });
        (d * g / (4.0 * wi.z * wo.z), f)
    }

    /// The one-division forms of D·G/(4 cos cos) and of F agree with the textbook ones to
    /// 10⁻¹² relative over the hemisphere, the grazing floor, both shadowing branches and
    /// every Fresnel extreme (η from 1 to ~4 000), and F is exactly 0 at f0 = 0.
    #[test]
    fn one_division_forms_match_the_textbook() {
        let dir = |t: f64, p: f64| {
            let (st, ct) = (m::sin(t), m::cos(t).max(GRAZING_COS));
            DVec3::new(st * m::cos(p), st * m::sin(p), ct).normalize()
        };
        let mut worst: f64 = 0.0;
        let mut count = 0;
        for (mm, f0) in [(0.001, 0.0), (0.1, 0.04), (0.2, 0.5), (1.0, 0.999)] {
            let ct = CookTorrance::new(mm, Vec3::new(f0, 0.5, 0.999), Vec3::ZERO).unwrap();
            for i in 0..=40 {
                for j in 0..=40 {
                    let ti = core::f64::consts::FRAC_PI_2 * f64::from(i) / 40.0;
                    let to = core::f64::consts::FRAC_PI_2 * f64::from(j) / 40.0;
                    for p in [0.0, 0.7, 2.0, core::f64::consts::PI] {
                        let (wi, wo) = (dir(ti, 0.0), dir(to, p));
                        let (spec, l) = ct.dg(wi, wo);
                        let u = 0.5 * m::sqrt(l);
                        let (want, fw) = textbook(&ct, wi, wo);
                        let rel = |a: f64, b: f64| {
                            if b == 0.0 {
                                a.abs()
                            } else {
                                (a - b).abs() / b.abs()
                            }
                        };
                        // Where D underflows to subnormals, relative error is meaningless.
                        if want > 1e-290 {
                            worst = worst.max(rel(spec, want));
                            count += 1;
                        }
                        let f = ct.fresnel_squared(u, 0.25 * l);
                        for c in 0..3 {
                            worst = worst.max(rel(f[c], fw[c]));
                        }
                    }
                }
            }
        }
        assert!(count > 10_000, "{count} points compared");
        assert!(worst < 1e-12, "worst relative difference {worst:e}");
        let black = CookTorrance::new(0.2, Vec3::ZERO, Vec3::ZERO).unwrap();
        for u in [1e-4, 0.3, 1.0] {
            assert_eq!(black.fresnel(u), DVec3::ZERO);
        }
    }
}
