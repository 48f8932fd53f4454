//! Direction helpers in the local shading frame (z = normal): validation, reflection, half
//! vectors, spherical angles and luminance.

use crate::error::DirectionError;
use crate::math as m;
use glam::{DVec3, Vec3};

/// Rec. 709 luminance weights: Y = 0.2126 R + 0.7152 G + 0.0722 B (MODELS.md).
pub const LUMINANCE: Vec3 = Vec3::new(0.2126, 0.7152, 0.0722);

/// The luminance Y of an RGB value; the scalar that every sampler is proportional to.
#[inline]
#[must_use]
pub fn luminance(rgb: Vec3) -> f32 {
    rgb.dot(LUMINANCE)
}

/// Validates and normalises a direction given by a user or a file.
///
/// Errors: [`DirectionError::NotFinite`] for NaN or infinite components,
/// [`DirectionError::ZeroLength`] for the zero vector. Any other finite vector, however short
/// or long, is normalised exactly (in f64).
/// See also [`unit_direction_above`], which also rejects the lower hemisphere.
#[inline]
pub fn unit_direction(v: Vec3) -> Result<Vec3, DirectionError> {
    if !v.is_finite() {
        return Err(DirectionError::NotFinite);
    }
    // Normalise in f64 so that tiny or huge (but finite) inputs keep their direction; a
    // direction already unit to f32 rounding (every one a sampler returns, and most a
    // renderer passes) without a square root and a division, which sat on the critical path
    // of every baked `sample` and `pdf` (see `normalize_f64`).
    let d = v.as_dvec3();
    if d.length_squared() == 0.0 {
        return Err(DirectionError::ZeroLength);
    }
    Ok(normalize_f64(d).as_vec3())
}

/// Like [`unit_direction`], and also rejects directions with z ≤ 0
/// ([`DirectionError::BelowHorizon`]): use it for an incident direction `wi` given to a sampler.
#[inline]
pub fn unit_direction_above(v: Vec3) -> Result<Vec3, DirectionError> {
    let w = unit_direction(v)?;
    if w.z > 0.0 {
        Ok(w)
    } else {
        Err(DirectionError::BelowHorizon)
    }
}

/// True when `w` is finite and strictly above the horizon (z > 0); false for NaN, which a
/// plain `w.z > 0.0` test would also give, but this says why.
#[inline]
#[must_use]
pub fn above_horizon(w: Vec3) -> bool {
    w.z > 0.0 && w.is_finite()
}

/// `w` as the unit direction a density is asked about: `w` itself where it is unit to f32
/// rounding (|w|² within 10⁻⁵ of 1: every direction a sampler returns, which so keeps its
/// bits and its pdf), otherwise `w` normalised in f64 (a tiny or huge vector keeps its
/// direction); `None` for a zero, NaN or infinite `w`.
#[inline]
#[must_use]
pub fn unit_for_density(w: Vec3) -> Option<Vec3> {
    if (w.length_squared() - 1.0).abs() < 1e-5 {
        return Some(w);
    }
    unit_direction(w).ok()
}

/// The local-frame mirror direction r(w) = (−x, −y, z): reflection of `w` about the normal.
#[inline]
#[must_use]
pub fn mirror(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Reflects `w` about the unit vector `n`: 2(w·n)n − w (both pointing away from the surface).
#[inline]
#[must_use]
pub fn reflect(w: Vec3, n: Vec3) -> Vec3 {
    2.0 * w.dot(n) * n - w
}

/// The unit half vector h = (wi + wo)/|wi + wo|, or `None` when wi = −wo (no half vector).
#[inline]
#[must_use]
pub fn half_vector(wi: Vec3, wo: Vec3) -> Option<Vec3> {
    (wi + wo).try_normalize()
}

/// cos θ of a local-frame direction (its z component).
#[inline]
#[must_use]
pub fn cos_theta(w: Vec3) -> f32 {
    w.z
}

/// The unit direction with polar angle `theta` (from the normal) and azimuth `phi` (from x).
#[inline]
#[must_use]
pub fn spherical_direction(theta: f32, phi: f32) -> Vec3 {
    let (st, ct) = (m::sinf(theta), m::cosf(theta));
    Vec3::new(st * m::cosf(phi), st * m::sinf(phi), ct)
}

/// The (θ, φ) of a unit direction: θ ∈ [0, π] from the normal, φ ∈ (−π, π] from x.
/// Inverse of [`spherical_direction`] (φ is 0 at the poles).
#[inline]
#[must_use]
pub fn spherical_angles(w: Vec3) -> (f32, f32) {
    let theta = m::acos(f64::from(w.z).clamp(-1.0, 1.0)) as f32;
    let phi = if w.x == 0.0 && w.y == 0.0 {
        0.0
    } else {
        m::atan2f(w.y, w.x)
    };
    (theta, phi)
}

/// cos Δφ between the azimuths of two directions, 0 when either is the normal (MODELS.md).
#[inline]
#[must_use]
pub fn cos_delta_phi(wi: Vec3, wo: Vec3) -> f32 {
    cos_delta_phi64(wi.as_dvec3(), wo.as_dvec3()) as f32
}

/// f64 version of [`cos_delta_phi`], used inside the models.
#[inline]
#[must_use]
pub(crate) fn cos_delta_phi64(wi: DVec3, wo: DVec3) -> f64 {
    let (li, lo) = (wi.truncate().length(), wo.truncate().length());
    if li == 0.0 || lo == 0.0 {
        0.0
    } else {
        (wi.truncate().dot(wo.truncate()) / (li * lo)).clamp(-1.0, 1.0)
    }
}

/// The smallest cosine at which any model evaluates f_r (θ ≈ 89.9943°): every `eval` first
/// lifts a direction with 0 < cos θ < `GRAZING_COS` to cos θ = `GRAZING_COS` at the same
/// azimuth ([`lift_to_grazing_floor`]); analytic samplers lift `wi` the same way.
///
/// Why: several models' formulas divide by cos θi or cos θo (Cook–Torrance, Ward, Strauss,
/// Oren–Nayar, Poulin–Fournier, He–Torrance), so f_r(wi, ·) becomes a spike of height
/// ~1/cos² θi and width ~cos θi at the horizon that no finite tree (nor f32) holds as
/// cos θi → 0. Measured on Cook–Torrance at wi = (0.8, 0.6, z): z = 10⁻⁶ exhausted a 2²⁰-node
/// tree in about a minute, while z = 10⁻⁴ needs 1 869 nodes and 0.4 s. With the floor, f_r is
/// finite for every pair above the horizon (down to the smallest positive f32 z), the tree of
/// a `wi` below the floor *is* the tree of its lifted direction (so trees, albedos and samples
/// converge as z → 0: they are the floor's), and values where both cosines are at least
/// 10⁻⁴ are exactly MODELS.md's. The floor is symmetric in wi and wo, so it keeps
/// reciprocity and every declared symmetry.
pub const GRAZING_COS: f64 = 1e-4;

/// A unit f64 direction above the horizon lifted to cos θ ≥ [`GRAZING_COS`]: unchanged when
/// its z is at least the floor, else the direction at the same azimuth with z = the floor.
#[inline]
#[must_use]
pub fn lift_to_grazing_floor(w: DVec3) -> DVec3 {
    if w.z >= GRAZING_COS {
        return w;
    }
    let r = w.truncate().length();
    if r == 0.0 {
        return DVec3::Z;
    }
    let s = m::sqrt((1.0 - GRAZING_COS) * (1.0 + GRAZING_COS)) / r;
    DVec3::new(w.x * s, w.y * s, GRAZING_COS)
}

/// An f32 incident direction lifted to the grazing floor (unchanged when its cosine is at
/// least [`GRAZING_COS`], or when it is not above the horizon). f_r(wi, ·) is
/// f_r(lift(wi), ·), so anything built from wi may use the lifted one: analytic samplers draw
/// about it (half-vector samplers divide by wi·h, which a wi at z → 0 sends to 0), and a
/// tree's peak hints come from it (the mirror direction of a wi at z = 10⁻³⁰ lies on the
/// horizon, where every model is 0, and would hide a sharp lobe from the bound search).
#[inline]
#[must_use]
pub fn lift_incident(wi: Vec3) -> Vec3 {
    if !above_horizon(wi) {
        return wi;
    }
    let w = wi.as_dvec3();
    let w = w / w.length();
    if w.z >= GRAZING_COS {
        wi
    } else {
        lift_to_grazing_floor(w).as_vec3()
    }
}

/// The pair (wi, wo) as f64 unit vectors when both are finite and strictly above the horizon,
/// else `None` (where every BRDF is 0), each lifted to the grazing floor
/// ([`GRAZING_COS`]). This is every model's `eval` prologue: inputs need only be
/// approximately unit, they are renormalised here in f64.
#[inline]
#[must_use]
pub(crate) fn upper_pair(wi: Vec3, wo: Vec3) -> Option<(DVec3, DVec3)> {
    unit_pair(wi, wo).map(|(wi, wo)| (lift_to_grazing_floor(wi), lift_to_grazing_floor(wo)))
}

/// The pair (wi, wo) as f64 unit vectors when both are finite and strictly above the horizon,
/// else `None`; not lifted.
#[inline]
#[must_use]
pub(crate) fn unit_pair(wi: Vec3, wo: Vec3) -> Option<(DVec3, DVec3)> {
    if !(above_horizon(wi) && above_horizon(wo)) {
        return None;
    }
    Some((normalize_f64(wi.as_dvec3()), normalize_f64(wo.as_dvec3())))
}

/// `v / |v|` for a finite, non-zero `v`, without a square root or a division when `v` is
/// unit to f32 rounding (as nearly every direction a model or a sampler is handed is):
/// there |v|² = 1 + e with |e| < 10⁻⁵, and 1/|v| = (1 + e)^(−½) = 1 − e/2 + 3e²/8 to
/// within 5|e|³/16 < 4·10⁻¹⁶ — two multiply-adds on an evaluation's critical path instead
/// of a square root and a division (about 30 cycles of latency, twice per `eval`).
/// Elsewhere `v / |v|`. Within 2 ulp of `v / v.length()` for every finite non-zero `v`.
#[inline(always)]
#[must_use]
pub fn normalize_f64(v: DVec3) -> DVec3 {
    let l2 = v.length_squared();
    let e = l2 - 1.0;
    if e.abs() < 1e-5 {
        v * (1.0 - e * (0.5 - 0.375 * e))
    } else {
        v / m::sqrt(l2)
    }
}

/// cos^n α of the angle between two f64 unit vectors, computed without cancellation:
/// 1 − cos α = |a − b|²/2, then exp(n·ln(1 − d)). Clamped at 0 (cos α ≤ 0 gives 0, except
/// n = 0 gives 1: pow(0, 0) = 1).
///
/// `ln`, not `ln_1p(−d)`: rounding 1 − d errs by at most 2⁻⁵³ relative, so ln(1 − d) is off
/// by at most 1.2·10⁻¹⁶ absolute and the result by n·1.2·10⁻¹⁶ relative (10⁻¹¹ at
/// n = 10⁵): the exponent's absolute error is what counts, and `ln_1p`'s relative accuracy
/// for tiny d buys nothing here. The backend's `ln` is the faster of the two (a Phong
/// evaluation at random cosine pairs went from 18.4 to 16.6 ns, and from 30.4 to 27.6 ns
/// when each waits on the last, as a rejection trial does).
#[inline]
#[must_use]
pub(crate) fn cos_power(a: DVec3, b: DVec3, n: f64) -> f64 {
    let d = 0.5 * (a - b).length_squared();
    if n == 0.0 {
        return 1.0;
    }
    // ln(1 − d) ≤ −d − d²/2: where n·(d + d²/2) ≥ 746 the exponent is below −745.2, whose
    // exponential is 0 in f64, so neither the logarithm nor the exponential (whose underflow
    // takes the backend's slow errno path) is paid for, and the result is the same 0 (for
    // n = 1000, everything beyond 67° of the lobe's axis).
    if d >= 1.0 || n * (d + 0.5 * d * d) >= 746.0 {
        return 0.0;
    }
    m::exp(n * m::ln(1.0 - d))
}

/// cos^n θ of the angle between a finite, non-zero `v` (any length: an unnormalised half
/// vector wi + wo) and the normal z, for v.z > 0 (0 otherwise, except n = 0 gives 1):
/// cos^n θ = exp(½n·ln(v_z²/|v|²)), with one division and no square root, where normalising
/// v and calling [`cos_power`] costs a square root, a division and more on an evaluation's
/// critical path. cos²θ = v_z²/|v|² and sin²θ = (v_x² + v_y²)/|v|² are both formed without
/// cancellation (near the normal and at the horizon alike), and the logarithm errs by at
/// most 1.2·10⁻¹⁶ absolute beyond their rounding. Where ½n·sin²θ ≥ 746 (so the exponent,
/// at most −½n·sin²θ, is below −745) the result is 0 without the logarithm and the
/// exponential.
#[inline]
#[must_use]
pub(crate) fn cos_power_z(v: DVec3, n: f64) -> f64 {
    if n == 0.0 {
        return 1.0;
    }
    if v.z <= 0.0 {
        return 0.0;
    }
    let (r2, z2) = (v.x * v.x + v.y * v.y, v.z * v.z);
    let k = 1.0 / (r2 + z2);
    if 0.5 * n * (r2 * k) >= 746.0 {
        return 0.0;
    }
    m::exp(0.5 * n * m::ln(z2 * k))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit direction keeps its bits; a scaled one is normalised (tiny and huge ones
    /// included); a zero or non-finite one has no direction.
    #[test]
    fn unit_for_density_keeps_unit_bits_and_normalises_the_rest() {
        let w = Vec3::new(0.3, -0.2, 0.9).normalize();
        assert_eq!(unit_for_density(w), Some(w));
        for scale in [1e-30f32, 1e-3, 3.0, 1e30] {
            let got = unit_for_density(w * scale).unwrap();
            assert!((got - w).length() < 1e-6, "{scale}: {got}");
        }
        for bad in [Vec3::ZERO, Vec3::NAN, Vec3::splat(f32::INFINITY)] {
            assert_eq!(unit_for_density(bad), None);
        }
    }

    #[test]
    fn unit_direction_rejects_bad_input() {
        assert_eq!(
            unit_direction(Vec3::new(f32::NAN, 0.0, 1.0)),
            Err(DirectionError::NotFinite)
        );
        assert_eq!(unit_direction(Vec3::ZERO), Err(DirectionError::ZeroLength));
        assert_eq!(
            unit_direction_above(Vec3::new(1.0, 0.0, 0.0)),
            Err(DirectionError::BelowHorizon)
        );
        let w = unit_direction(Vec3::new(0.0, 0.0, 1e-40)).unwrap();
        assert_eq!(w, Vec3::Z);
        let w = unit_direction(Vec3::new(3e38, 0.0, 3e38)).unwrap();
        assert!((w.length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn spherical_round_trip() {
        for &(t, p) in &[(0.3f32, 0.2f32), (1.2, -2.0), (0.01, 3.0), (1.5, -0.5)] {
            let (t2, p2) = spherical_angles(spherical_direction(t, p));
            assert!(
                (t - t2).abs() < 1e-5 && (p - p2).abs() < 1e-5,
                "{t},{p} -> {t2},{p2}"
            );
        }
        assert_eq!(spherical_angles(Vec3::Z), (0.0, 0.0));
    }

    #[test]
    fn reflect_and_mirror_agree() {
        let w = Vec3::new(0.3, -0.4, 0.866).normalize();
        assert!((reflect(w, Vec3::Z) - mirror(w)).length() < 1e-6);
        let h = half_vector(w, mirror(w)).unwrap();
        assert!((h - Vec3::Z).length() < 1e-6);
        assert!(half_vector(w, -w).is_none());
    }

    #[test]
    fn normalize_f64_is_division_by_the_length() {
        // Near unit (the polynomial), at its switch, and far from unit (the division).
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for k in 0..200_000 {
            let d = DVec3::new(next(), next(), next());
            if d.length_squared() < 1e-6 {
                continue;
            }
            let scale = match k % 4 {
                0 => 1.0,
                1 => 1.0 + 4.9e-6 * next(),
                2 => 1.0 + 1e-3 * next(),
                _ => 10f64.powf(30.0 * next()),
            };
            let v = d.normalize() * scale;
            let (got, want) = (normalize_f64(v), v / v.length());
            assert!(
                (got - want).abs().max_element() <= 2.0 * f64::EPSILON,
                "{v}: {got} vs {want}"
            );
        }
        let v = Vec3::new(0.3, -0.4, 0.866).normalize();
        let w = normalize_f64(v.as_dvec3());
        assert!((w.length() - 1.0).abs() <= 2.0 * f64::EPSILON);
    }

    #[test]
    fn cos_power_is_accurate_near_one() {
        let a = DVec3::Z;
        let t = 1e-3f64;
        let b = DVec3::new(m::sin(t), 0.0, m::cos(t));
        let exact = m::pow(m::cos(t), 1e5);
        assert!((cos_power(a, b, 1e5) - exact).abs() < 1e-9 * exact);
        // Near the peak, where 1 − d rounds: relative error within n·10⁻¹⁵ (the rounding
        // of cos t in the reference alone is n·1.1·10⁻¹⁶).
        for t in [1e-7, 1e-5, 3e-4, 1e-2, 0.1] {
            let b = DVec3::new(m::sin(t), 0.0, m::cos(t));
            for n in [1.0, 10.0, 1e3, 1e5] {
                let exact = m::pow(m::cos(t), n);
                let got = cos_power(a, b, n);
                assert!(
                    (got - exact).abs() <= (1e-15 * n + 1e-15) * exact,
                    "t {t} n {n}: {got:e} vs {exact:e}"
                );
            }
        }
        assert_eq!(cos_power(a, -a, 0.0), 1.0);
        assert_eq!(cos_power(a, DVec3::X, 3.0), 0.0);
    }

    /// The shortcut to 0 changes no value: bit for bit the plain exp(n·ln(1 − d)) at every
    /// angle and exponent, both sides of where it starts (some of these are subnormal or 0).
    #[test]
    fn cos_power_shortcut_is_the_plain_value() {
        let a = DVec3::Z;
        let mut zeros = 0;
        for n in [1.0, 7.5, 100.0, 1000.0, 1e4, 1e5, 1e6] {
            for i in 0..=20_000 {
                let t = core::f64::consts::FRAC_PI_2 * f64::from(i) / 20_000.0;
                let b = DVec3::new(m::sin(t), 0.0, m::cos(t));
                let d = 0.5 * (a - b).length_squared();
                let plain = if d >= 1.0 {
                    0.0
                } else {
                    m::exp(n * m::ln(1.0 - d))
                };
                let got = cos_power(a, b, n);
                assert_eq!(
                    got.to_bits(),
                    plain.to_bits(),
                    "n {n} θ {t}: {got:e} vs {plain:e}"
                );
                zeros += usize::from(got == 0.0);
            }
        }
        assert!(zeros > 50_000, "the shortcut region is exercised ({zeros})");
    }

    /// `cos_power_z` of an unnormalised vector at angle t from z is pow(cos t, n) to 10⁻¹⁴
    /// relative plus n·10⁻¹⁵ (the exponent's rounding), over angles from 10⁻⁷ rad to within
    /// 10⁻⁴ of the horizon (where `cos_power`'s 1 − d cancels, this does not), lengths from
    /// 10⁻³ to 2 and exponents 0 to 10⁵; it is 0 below the horizon.
    #[test]
    fn cos_power_z_is_cos_power_against_the_normal() {
        let mut compared = 0;
        for n in [0.0, 1.0, 7.5, 100.0, 1000.0, 1e4, 1e5] {
            for t in [1e-7, 1e-5, 1e-3, 0.05, 0.3, 0.8, 1.2, 1.5, 1.570_69] {
                for (len, phi) in [(1e-3, 0.3), (1.0, 2.0), (2.0, -1.0)] {
                    let w = DVec3::new(m::sin(t) * m::cos(phi), m::sin(t) * m::sin(phi), m::cos(t));
                    let want = m::pow(m::cos(t), n);
                    let got = cos_power_z(w * len, n);
                    let tol = (1e-14 + 1e-15 * n) * want;
                    if want > 1e-300 {
                        compared += 1;
                    }
                    assert!(
                        (got - want).abs() <= tol || (want < 1e-300 && got < 1e-300),
                        "n {n} θ {t} |v| {len}: {got:e} vs {want:e}"
                    );
                }
            }
        }
        assert!(compared > 100, "{compared}");
        assert_eq!(cos_power_z(DVec3::new(0.3, 0.0, -0.1), 5.0), 0.0);
        assert_eq!(cos_power_z(DVec3::new(0.3, 0.0, 0.0), 5.0), 0.0);
        assert_eq!(cos_power_z(DVec3::new(0.3, 0.0, 0.0), 0.0), 1.0);
    }

    #[test]
    fn cos_delta_phi_at_the_pole_is_zero() {
        assert_eq!(cos_delta_phi(Vec3::Z, Vec3::X), 0.0);
        let a = Vec3::new(1.0, 0.0, 1.0).normalize();
        assert!((cos_delta_phi(a, mirror(a)) + 1.0).abs() < 1e-6);
    }
}
