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

    /// (Z(t)·A(w)/(4π (r + (1−r)cosθi)(r + (1−r)cosθo)), u = wi·h) for f64 unit directions
    /// in the upper hemisphere, from the unnormalised half vector v = wi + wo: with l = |v|²,
    /// u = √l/2, t² = v_z²/l, so q = 1 + (r − 1)t² is (l + (r − 1)v_z²)/l, and w² = v_x²/r²
    /// with r² = v_x² + v_y²: A = √(N/D), N = p·r², D = p²·r² + (1 − p²)·v_x², which is
    /// √(N·D)/D. So the whole factor is r·√(N·D)·l²/(D·(q l)²·4πg): one square root and one
    /// division side by side, where normalising h, w², A and Z made a chain of two square
    /// roots and four divisions (a rejection trial waits on it). At the normal (r² below
    /// 10⁻¹⁰⁰, where w has no direction) w² = 1, as before. Equal to the chained form to
    /// rounding (a test).
    #[inline(always)]
    fn zag(&self, wi: DVec3, wo: DVec3) -> (f64, f64) {
        let (r, p) = (f64::from(self.r), f64::from(self.p));
        let v = wi + wo;
        let l = v.length_squared();
        let (vx2, r2) = (v.x * v.x, v.x * v.x + v.y * v.y);
        let ql = l + (r - 1.0) * (v.z * v.z);
        let (n, d) = if r2 > 1e-100 {
            (p * r2, p * p * r2 + (1.0 - p * p) * vx2)
        } else {
            (p, 1.0)
        };
        let g = (r + (1.0 - r) * wi.z) * (r + (1.0 - r) * wo.z);
        let k = r * m::sqrt(n * d) * (l * l) / (d * ql * ql * (4.0 * PI * g));
        (k, 0.5 * m::sqrt(l))
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
        let (k, u) = self.zag(wi, wo);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::GRAZING_COS;

    /// The factor as it was chained before: h normalised, w² from it, A, Z, then the
    /// division by the cosines' terms.
    fn chained(s: &Schlick, wi: DVec3, wo: DVec3) -> (f64, f64) {
        let (h, u) = half64(wi, wo);
        let (r, p) = (f64::from(s.r), f64::from(s.p));
        let t = h.z;
        let q = 1.0 + r * t * t - t * t;
        let hxy2 = h.x * h.x + h.y * h.y;
        let w2 = if hxy2 > 0.0 { h.x * h.x / hxy2 } else { 1.0 };
        let a = m::sqrt(p / (p * p + (1.0 - p * p) * w2));
        let g = (r + (1.0 - r) * wi.z) * (r + (1.0 - r) * wo.z);
        (r * a / (q * q * (4.0 * PI * g)), u)
    }

    /// One square root and one division give the chained form's factor and Fresnel factor
    /// to 10⁻¹² relative over the hemisphere, the grazing floor, the normal's half vector (both
    /// directions mirrored: w² = 1) and r, p from sharp to flat and anisotropic.
    #[test]
    fn side_by_side_form_is_the_chained_one() {
        let dir = |t: f64, p: f64| {
            let (st, ct) = (m::sin(t), m::cos(t).max(GRAZING_COS));
            crate::geometry::normalize_f64(DVec3::new(st * m::cos(p), st * m::sin(p), ct))
        };
        let mut worst = 0.0f64;
        for (r, p) in [
            (0.001f32, 1.0f32),
            (0.01, 0.05),
            (0.2, 0.5),
            (1.0, 1.0),
            (0.5, 0.001),
        ] {
            let s = Schlick::new(Vec3::splat(0.5), r, p).unwrap();
            for i in 0..=30 {
                for j in 0..=30 {
                    for ph in [0.0, 0.4, 1.5, 2.5, core::f64::consts::PI] {
                        let ti = core::f64::consts::FRAC_PI_2 * f64::from(i) / 30.0;
                        let to = core::f64::consts::FRAC_PI_2 * f64::from(j) / 30.0;
                        let (wi, wo) = (dir(ti, 0.7), dir(to, 0.7 + ph));
                        let (k, u) = s.zag(wi, wo);
                        let (kc, uc) = chained(&s, wi, wo);
                        // u itself is ill-conditioned where wi and wo are nearly opposite
                        // at grazing (u → 0: both forms carry the inputs' unit-norm
                        // rounding, 10⁻⁹ relative there); it enters f only through
                        // S(u) = c + (1 − c)(1 − u)⁵, which is compared.
                        let sf = |u: f64| 0.5 + 0.5 * (1.0 - u).powi(5);
                        worst = worst
                            .max((k - kc).abs() / kc)
                            .max((sf(u) - sf(uc)).abs() / sf(uc));
                    }
                }
            }
            // The normal's half vector: a direction and its mirror.
            let wi = dir(0.6, 1.1);
            let wo = DVec3::new(-wi.x, -wi.y, wi.z);
            let (k, _) = s.zag(wi, wo);
            let (kc, _) = chained(&s, wi, wo);
            worst = worst.max((k - kc).abs() / kc);
        }
        assert!(worst < 1e-12, "worst relative difference {worst:e}");
    }
}
