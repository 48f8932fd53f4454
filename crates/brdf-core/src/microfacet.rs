//! Microfacet normal distributions, separate from the BRDFs that use them (pbrt's habit):
//! each has its density D(h), a half-vector sampler and that sampler's pdf per solid angle
//! of h. The reflection Jacobian dω_h/dω_o = 1/(4 wo·h) is applied by the BRDFs.

use crate::math as m;
use core::f64::consts::{FRAC_1_PI, PI};
use glam::{DVec3, Vec2};

/// The normalised Beckmann distribution with RMS slope `m` (Cook–Torrance):
/// D(h) = exp(−tan²θh/m²)/(π m² cos⁴θh), ∫ D cosθh dω = 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Beckmann {
    /// RMS microfacet slope.
    pub m: f64,
}

impl Beckmann {
    /// D(h) for a unit half vector (0 for cos θh ≤ 0).
    #[inline]
    #[must_use]
    pub fn d(&self, h: DVec3) -> f64 {
        let c2 = h.z * h.z;
        if h.z <= 0.0 {
            return 0.0;
        }
        let tan2 = (1.0 - c2).max(0.0) / c2;
        let m2 = self.m * self.m;
        m::exp(-tan2 / m2) / (PI * m2 * c2 * c2)
    }

    /// Samples h ∝ D(h)·cos θh: tan²θh = −m² ln(1 − u₀), φh = 2πu₁.
    #[inline]
    #[must_use]
    pub fn sample_h(&self, u: Vec2) -> DVec3 {
        let tan2 = -self.m * self.m * m::ln_1p(-f64::from(u.x).min(1.0 - 1e-16));
        let cos_t = 1.0 / m::sqrt(1.0 + tan2);
        let sin_t = m::sqrt(tan2) * cos_t;
        let phi = 2.0 * PI * f64::from(u.y);
        DVec3::new(sin_t * m::cos(phi), sin_t * m::sin(phi), cos_t)
    }

    /// Density of [`Beckmann::sample_h`] per unit solid angle of h: D(h)·cos θh.
    #[inline]
    #[must_use]
    pub fn pdf_h(&self, h: DVec3) -> f64 {
        self.d(h) * h.z.max(0.0)
    }
}

/// Ward's anisotropic elliptical Gaussian lobe in half-vector space, sampled as Walter (2005)
/// corrects it: the density below integrates to 1 over the hemisphere of h.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WardLobe {
    /// RMS slope along the tangent x.
    pub alpha_x: f64,
    /// RMS slope along y.
    pub alpha_y: f64,
}

impl WardLobe {
    /// Samples h: φh = atan2(αy sin 2πu₁, αx cos 2πu₁),
    /// tan²θh = −ln(1−u₀)/(cos²φh/αx² + sin²φh/αy²).
    #[inline]
    #[must_use]
    pub fn sample_h(&self, u: Vec2) -> DVec3 {
        let t = 2.0 * PI * f64::from(u.y);
        let phi = m::atan2(self.alpha_y * m::sin(t), self.alpha_x * m::cos(t));
        let (cp, sp) = (m::cos(phi), m::sin(phi));
        let a = cp * cp / (self.alpha_x * self.alpha_x) + sp * sp / (self.alpha_y * self.alpha_y);
        let tan2 = -m::ln_1p(-f64::from(u.x).min(1.0 - 1e-16)) / a;
        let cos_t = 1.0 / m::sqrt(1.0 + tan2);
        let sin_t = m::sqrt(tan2) * cos_t;
        DVec3::new(sin_t * cp, sin_t * sp, cos_t)
    }

    /// Density of [`WardLobe::sample_h`] per unit solid angle of h:
    /// exp(−tan²θh (cos²φh/αx² + sin²φh/αy²))/(π αx αy cos³θh).
    #[inline]
    #[must_use]
    pub fn pdf_h(&self, h: DVec3) -> f64 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let c2 = h.z * h.z;
        // tan²θ cos²φ = hx²/hz², tan²θ sin²φ = hy²/hz².
        let e = (h.x * h.x / (self.alpha_x * self.alpha_x)
            + h.y * h.y / (self.alpha_y * self.alpha_y))
            / c2;
        m::exp(-e) * FRAC_1_PI / (self.alpha_x * self.alpha_y * c2 * h.z)
    }
}

/// The GGX / Trowbridge–Reitz distribution with α² = `alpha2`, which is Schlick's Z/π:
/// D(h) = α²/(π(1 + (α² − 1)cos²θh)²).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// α², Schlick's roughness r.
    pub alpha2: f64,
}

impl Ggx {
    /// D(h) for a unit half vector (0 for cos θh ≤ 0).
    #[inline]
    #[must_use]
    pub fn d(&self, h: DVec3) -> f64 {
        if h.z <= 0.0 {
            return 0.0;
        }
        let t2 = h.z * h.z;
        let q = 1.0 + (self.alpha2 - 1.0) * t2;
        self.alpha2 * FRAC_1_PI / (q * q)
    }

    /// Samples h ∝ D(h) cos θh: cos θh = √(u₀/(α² + (1 − α²)u₀)), φh = 2πu₁.
    #[inline]
    #[must_use]
    pub fn sample_h(&self, u: Vec2) -> DVec3 {
        let u0 = f64::from(u.x);
        let c2 = u0 / (self.alpha2 + (1.0 - self.alpha2) * u0);
        let c = m::sqrt(c2.clamp(0.0, 1.0));
        let s = m::sqrt((1.0 - c2).max(0.0));
        let phi = 2.0 * PI * f64::from(u.y);
        DVec3::new(s * m::cos(phi), s * m::sin(phi), c)
    }

    /// Density of [`Ggx::sample_h`] per unit solid angle of h: D(h)·cos θh.
    #[inline]
    #[must_use]
    pub fn pdf_h(&self, h: DVec3) -> f64 {
        self.d(h) * h.z.max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::hemisphere_integral;

    fn integral(f: &dyn Fn(DVec3) -> f64) -> f64 {
        hemisphere_integral(96, 6, |w| f(w.as_dvec3()))
    }

    #[test]
    fn half_vector_pdfs_are_normalised() {
        for m in [0.05, 0.2, 0.7] {
            let b = Beckmann { m };
            assert!(
                (integral(&|h| b.pdf_h(h)) - 1.0).abs() < 1e-4,
                "beckmann {m}"
            );
        }
        for (ax, ay) in [(0.1, 0.3), (0.05, 0.2), (0.5, 0.5)] {
            let w = WardLobe {
                alpha_x: ax,
                alpha_y: ay,
            };
            assert!(
                (integral(&|h| w.pdf_h(h)) - 1.0).abs() < 1e-4,
                "ward {ax} {ay}"
            );
        }
        for a2 in [0.01, 0.3, 1.0] {
            let g = Ggx { alpha2: a2 };
            assert!((integral(&|h| g.pdf_h(h)) - 1.0).abs() < 2e-3, "ggx {a2}");
        }
    }

    #[test]
    fn samplers_follow_their_pdfs() {
        // Mean of cos θh under the sampler vs its pdf's integral of cos θh.
        let n = 200;
        let mean = |s: &dyn Fn(Vec2) -> DVec3| {
            let mut a = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    a += s(u).z;
                }
            }
            a / f64::from(n * n)
        };
        let b = Beckmann { m: 0.3 };
        let w = WardLobe {
            alpha_x: 0.1,
            alpha_y: 0.4,
        };
        let g = Ggx { alpha2: 0.2 };
        assert!((mean(&|u| b.sample_h(u)) - integral(&|h| h.z * b.pdf_h(h))).abs() < 1e-3);
        assert!((mean(&|u| w.sample_h(u)) - integral(&|h| h.z * w.pdf_h(h))).abs() < 1e-3);
        assert!((mean(&|u| g.sample_h(u)) - integral(&|h| h.z * g.pdf_h(h))).abs() < 2e-3);
    }
}
