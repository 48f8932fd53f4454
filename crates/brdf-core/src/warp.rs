//! Analytic warps from [0,1)² to the hemisphere, each a pbrt-style triad:
//! `sample_*` (forward), `*_pdf` (density, measure named), `invert_*` (back to [0,1)²).
//! Every lobe here is about +z; rotate it with a [`Frame`](crate::Frame) for other axes.

use crate::maps::{disk_to_square_concentric, square_to_disk_concentric};
use crate::math as m;
use core::f64::consts::{FRAC_1_PI, PI};
use glam::{DVec3, Vec2, Vec3};

const INV_2PI: f64 = 0.5 * FRAC_1_PI;

#[inline]
fn wrap_unit(x: f64) -> f64 {
    if x < 0.0 { x + 1.0 } else { x }
}

/// Uniform direction on the upper hemisphere: z = u₀, φ = 2πu₁.
/// Density: [`uniform_hemisphere_pdf`]; inverse: [`invert_uniform_hemisphere`].
#[inline]
#[must_use]
pub fn sample_uniform_hemisphere(u: Vec2) -> Vec3 {
    // u.x outside [0, 1] (or NaN) would give z outside it: a direction that is not unit or
    // not above the horizon. Clamped (NaN to 0: the horizon, which a sample refuses).
    let z = if u.x > 0.0 {
        f64::from(u.x.min(1.0))
    } else {
        0.0
    };
    let r = m::sqrt((1.0 - z * z).max(0.0));
    let phi = 2.0 * PI * f64::from(u.y);
    DVec3::new(r * m::cos(phi), r * m::sin(phi), z).as_vec3()
}

/// Density of [`sample_uniform_hemisphere`], per unit solid angle: 1/(2π).
#[inline]
#[must_use]
pub fn uniform_hemisphere_pdf() -> f32 {
    INV_2PI as f32
}

/// Inverse of [`sample_uniform_hemisphere`].
#[inline]
#[must_use]
pub fn invert_uniform_hemisphere(w: Vec3) -> Vec2 {
    let phi = m::atan2(f64::from(w.y), f64::from(w.x)) * INV_2PI;
    Vec2::new(w.z, wrap_unit(phi) as f32)
}

/// Cosine-weighted direction on the upper hemisphere (Malley: concentric disk, then lift).
/// Density: [`cosine_hemisphere_pdf`]; inverse: [`invert_cosine_hemisphere`].
#[inline]
#[must_use]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = square_to_disk_concentric(u * 2.0 - Vec2::ONE);
    let z = m::sqrt((1.0 - f64::from(d.length_squared())).max(0.0)) as f32;
    Vec3::new(d.x, d.y, z)
}

/// Density of [`sample_cosine_hemisphere`], per unit solid angle: max(cos θ, 0)/π.
#[inline]
#[must_use]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI as f32
}

/// Inverse of [`sample_cosine_hemisphere`].
#[inline]
#[must_use]
pub fn invert_cosine_hemisphere(w: Vec3) -> Vec2 {
    (disk_to_square_concentric(Vec2::new(w.x, w.y)) + Vec2::ONE) * 0.5
}

/// Power-cosine lobe about +z: cos α = u₀^{1/(n+1)}, φ = 2πu₁; computed in f64 so that the
/// inversion stays exact for n up to 10⁵. Density: [`power_cosine_pdf`]; inverse:
/// [`invert_power_cosine`]. Valid for n ≥ 0; the lobe covers the whole hemisphere about +z.
#[inline]
#[must_use]
pub fn sample_power_cosine(u: Vec2, n: f32) -> Vec3 {
    sample_power_cosine64(u, f64::from(n)).as_vec3()
}

/// f64 core of [`sample_power_cosine`].
#[inline]
#[must_use]
pub(crate) fn sample_power_cosine64(u: Vec2, n: f64) -> DVec3 {
    // cos α = exp(ln u₀/(n+1)); 1 − cos α = −expm1(·) avoids cancellation for large n.
    let l = m::ln(f64::from(u.x).max(f64::MIN_POSITIVE)) / (n + 1.0);
    let one_minus_c = -m::exp_m1(l);
    let c = 1.0 - one_minus_c;
    let s = m::sqrt((one_minus_c * (1.0 + c)).max(0.0));
    let phi = 2.0 * PI * f64::from(u.y);
    DVec3::new(s * m::cos(phi), s * m::sin(phi), c)
}

/// Density of [`sample_power_cosine`], per unit solid angle about the lobe axis:
/// (n+1)/(2π)·cos^n α, 0 for cos α ≤ 0 (which the sampler never draws, n = 0 included).
#[inline]
#[must_use]
pub fn power_cosine_pdf(cos_alpha: f32, n: f32) -> f32 {
    let (c, n) = (f64::from(cos_alpha), f64::from(n));
    let p = if c <= 0.0 { 0.0 } else { m::pow(c, n) };
    ((n + 1.0) * INV_2PI * p) as f32
}

/// Inverse of [`sample_power_cosine`].
#[inline]
#[must_use]
pub fn invert_power_cosine(w: Vec3, n: f32) -> Vec2 {
    let c = f64::from(w.z).max(0.0);
    let u0 = m::pow(c, f64::from(n) + 1.0);
    let phi = m::atan2(f64::from(w.y), f64::from(w.x)) * INV_2PI;
    Vec2::new(u0 as f32, wrap_unit(phi) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::hemisphere_integral;

    fn uniforms() -> impl Iterator<Item = Vec2> {
        (0..23).flat_map(|i| {
            (0..19).map(move |j| Vec2::new((i as f32 + 0.5) / 23.0, (j as f32 + 0.37) / 19.0))
        })
    }

    #[test]
    fn triads_round_trip() {
        for u in uniforms() {
            let w = sample_uniform_hemisphere(u);
            assert!((invert_uniform_hemisphere(w) - u).length() < 1e-5);
            let w = sample_cosine_hemisphere(u);
            assert!((w.length() - 1.0).abs() < 1e-5);
            assert!((invert_cosine_hemisphere(w) - u).length() < 1e-4, "{u}");
            for n in [0.0f32, 3.0, 50.0] {
                let w = sample_power_cosine(u, n);
                assert!((w.length() - 1.0).abs() < 1e-5);
                assert!((invert_power_cosine(w, n) - u).length() < 1e-4, "n={n} {u}");
            }
        }
    }

    #[test]
    fn pdfs_integrate_to_one() {
        let one = |f: &dyn Fn(Vec3) -> f64| hemisphere_integral(64, 6, f);
        assert!((one(&|_| f64::from(uniform_hemisphere_pdf())) - 1.0).abs() < 1e-6);
        assert!((one(&|w| f64::from(cosine_hemisphere_pdf(w.z))) - 1.0).abs() < 1e-6);
        for n in [0.0f32, 1.0, 20.0, 1000.0] {
            let i = one(&|w| f64::from(power_cosine_pdf(w.z, n)));
            assert!((i - 1.0).abs() < 1e-6, "n={n}: {i}");
        }
    }

    #[test]
    fn huge_exponent_lobe_is_resolved() {
        // For n = 1e5 the lobe's mean 1 − cos α is 1/(n+2); an f32 inversion would collapse it.
        let n = 1e5;
        let mut acc = 0.0;
        let k = 1000;
        for i in 0..k {
            let w = sample_power_cosine64(Vec2::new((i as f32 + 0.5) / k as f32, 0.3), n);
            acc += 1.0 - w.z;
        }
        let mean = acc / f64::from(k);
        assert!(
            (mean * (n + 2.0) - 1.0).abs() < 0.02,
            "{}",
            mean * (n + 2.0)
        );
    }
}
