//! The float backend (`std` or `libm`), glam-style: the one place that chooses it.
//!
//! Every transcendental call in the crate goes through these functions, so a `no_std` build
//! only has to swap this file's backend. Names follow libm: an `f` suffix is the `f32` version.

#[cfg(all(not(feature = "std"), not(feature = "libm")))]
compile_error!(
    "brdf-core needs a float backend: enable its `std` feature (the default) or its `libm` feature"
);

macro_rules! backend {
    ($( $name:ident ( $($arg:ident),* ) : $t:ty => $std:ident, $libm:ident; )*) => {$(
        #[doc = concat!("`", stringify!($name), "` through the selected backend (std's `", stringify!($std), "` or libm's `", stringify!($libm), "`).")]
        #[inline(always)]
        #[must_use]
        pub fn $name($($arg: $t),*) -> $t {
            #[cfg(feature = "std")]
            { <$t>::$std($($arg),*) }
            #[cfg(all(not(feature = "std"), feature = "libm"))]
            { libm::$libm($($arg),*) }
        }
    )*};
}

backend! {
    sqrtf(x): f32 => sqrt, sqrtf;
    sqrt(x): f64 => sqrt, sqrt;
    exp(x): f64 => exp, exp;
    ln(x): f64 => ln, log;
    ln_1p(x): f64 => ln_1p, log1p;
    exp_m1(x): f64 => exp_m1, expm1;
    pow(x, y): f64 => powf, pow;
    sinf(x): f32 => sin, sinf;
    cosf(x): f32 => cos, cosf;
    sin(x): f64 => sin, sin;
    cos(x): f64 => cos, cos;
    tan(x): f64 => tan, tan;
    acos(x): f64 => acos, acos;
    asin(x): f64 => asin, asin;
    atan2f(y, x): f32 => atan2, atan2f;
    atan2(y, x): f64 => atan2, atan2;
    floor(x): f64 => floor, floor;
    ceil(x): f64 => ceil, ceil;
    round(x): f64 => round, round;
}

/// (sin x, cos x) in one call through the selected backend (std's `sin_cos` or libm's
/// `sincos`).
#[inline(always)]
#[must_use]
pub fn sin_cos(x: f64) -> (f64, f64) {
    #[cfg(feature = "std")]
    {
        x.sin_cos()
    }
    #[cfg(all(not(feature = "std"), feature = "libm"))]
    {
        libm::sincos(x)
    }
}

/// ln 2 in two parts: `LN2_HI` has its low bits zero, so k·`LN2_HI` is exact for the |k| of
/// an f64 exponent, and `LN2_LO` carries the rest (Cody and Waite's reduction).
const LN2_HI: f64 = 0.693_147_180_369_123_8;
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;

/// The range reduction of the table-free exponentials: x clamped below at −708 (NaN taken as
/// −708), and k = round(x·log₂e), as an f64 and as the integer whose shift by 52 is 2^k's
/// exponent bits ([`times_pow2`]).
#[inline(always)]
fn ln2_multiple(x: f64) -> (f64, f64, i64) {
    // 1.5·2^52: adding it rounds x·log2(e) to an integer held in the low mantissa bits.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    let x = x.max(-708.0);
    let kf = x * core::f64::consts::LOG2_E + SHIFT;
    // The low bits of kf are k in two's complement; shifted up by 52 they are its exponent.
    (x, kf - SHIFT, kf.to_bits() as i64)
}

/// p·2^k for the k of [`ln2_multiple`], by adding k to p's exponent bits (no overflow or
/// underflow for the results of x ∈ [−708, 0]).
#[inline(always)]
fn times_pow2(p: f64, k: i64) -> f64 {
    f64::from_bits(p.to_bits().wrapping_add((k << 52) as u64))
}

/// e^x for x ≤ 0, in plain arithmetic: no table, no branch and no call, so a loop of them
/// vectorises (the HTSG series sums tens of such terms per evaluation).
///
/// x = k·ln 2 + r with |r| ≤ ½ln 2 (ln 2 split in two parts, so r is exact to rounding), e^r
/// by its Taylor polynomial of degree 13 (truncation below 4·10⁻¹⁸ relative) evaluated by
/// Estrin's scheme, and 2^k put into the exponent bits. Accurate to a few ulp for
/// x ∈ [−708, 0]; below −708 it returns e^−708 ≈ 3·10⁻³⁰⁸ (callers add such a term to a sum
/// of order one, where it vanishes); NaN is taken as −708. Positive x is outside its domain.
#[inline(always)]
#[must_use]
pub fn exp_nonpositive(x: f64) -> f64 {
    let (x, kd, k) = ln2_multiple(x);
    let r = (x - kd * LN2_HI) - kd * LN2_LO;
    let (r2, r4) = (r * r, r * r * r * r);
    let c = |n0: f64, n1: f64| n0 + r * n1;
    let q03 = c(1.0, 1.0) + r2 * c(1.0 / 2.0, 1.0 / 6.0);
    let q47 = c(1.0 / 24.0, 1.0 / 120.0) + r2 * c(1.0 / 720.0, 1.0 / 5040.0);
    let q811 = c(1.0 / 40_320.0, 1.0 / 362_880.0) + r2 * c(1.0 / 3_628_800.0, 1.0 / 39_916_800.0);
    let q1213 = c(1.0 / 479_001_600.0, 1.0 / 6_227_020_800.0);
    let p = (q03 + r4 * q47) + (r4 * r4) * (q811 + r4 * q1213);
    times_pow2(p, k)
}

/// [`exp_nonpositive`] to a relative 1.3·10⁻¹² instead of a few ulp, for sums whose terms
/// need no more (the HTSG series, which stops at 10⁻¹⁰ of its largest term).
///
/// The same reduction to |r| ≤ ½ln 2 but with ln 2 in one constant (r is then off by at most
/// 1.4·10⁻¹³ at x = −708, 10⁻¹⁴ for x ≥ −40), then the polynomial of degree 8 that interpolates e^r at
/// the nine Chebyshev nodes of that interval (near-minimax: 1.06·10⁻¹² relative at most, where
/// the Taylor polynomial of the same degree leaves 2·10⁻¹⁰), by Estrin's scheme: four
/// multiply-adds fewer than [`exp_nonpositive`]'s degree 13.
#[inline(always)]
#[must_use]
pub fn exp_nonpositive_short(x: f64) -> f64 {
    /// The interpolant's monomial coefficients, c0…c8.
    const C: [f64; 9] = [
        1.0,
        0.999_999_999_979_785_2,
        0.499_999_999_997_979_34,
        0.166_666_668_910_457_75,
        0.041_666_666_890_957,
        0.008_333_266_097_949_614,
        0.001_388_882_167_763_036_2,
        0.000_199_158_669_267_826_82,
        2.487_616_402_262_597e-5,
    ];
    let (x, kd, k) = ln2_multiple(x);
    let r = x - kd * core::f64::consts::LN_2;
    let (r2, r4) = (r * r, r * r * r * r);
    let c = |i: usize| C[i] + r * C[i + 1];
    let p = (c(0) + r2 * c(2)) + r4 * (c(4) + r2 * c(6)) + (r4 * r4) * C[8];
    times_pow2(p, k)
}

/// acos c for c ∈ [0, 1] (clamped there; NaN is taken as 1), in plain arithmetic: no call, no
/// table, no branch but a select. For Oren–Nayar's two angles per evaluation, where the
/// backend's `acos` was a third of the model's cost.
///
/// For c ≥ ½, acos c = 2 asin √((1 − c)/2); below, π/2 − asin c: either way asin of
/// x ∈ [0, ½], as x + x·t·g(t), t = x², with g the polynomial of degree 8 interpolating
/// (asin √t/√t − 1)/t at the nine Chebyshev nodes of t ∈ [0, ¼] (4.9·10⁻¹² relative, so
/// asin to 3·10⁻¹³). Within 5·10⁻¹³ of the backend's acos absolutely, and relatively as c → 1.
#[inline]
#[must_use]
pub fn acos_nonnegative(c: f64) -> f64 {
    let c = c.clamp(0.0, 1.0);
    let c = if c.is_nan() { 1.0 } else { c };
    let high = c >= 0.5;
    let x = if high { sqrt(0.5 * (1.0 - c)) } else { c };
    let asin = asin_to_half(x);
    if high {
        2.0 * asin
    } else {
        core::f64::consts::FRAC_PI_2 - asin
    }
}

/// asin x for x ∈ [0, ½], the core of [`acos_nonnegative`] (3·10⁻¹³ relative): x + x·t·g(t),
/// t = x², g its Chebyshev-node interpolant.
#[inline(always)]
#[must_use]
pub(crate) fn asin_to_half(x: f64) -> f64 {
    /// g's monomial coefficients, g0…g8.
    const G: [f64; 9] = [
        0.16666666666738633,
        0.07499999953429712,
        0.044642906474584965,
        0.030379945210024933,
        0.022412417726695433,
        0.016902683886393575,
        0.01686409027396012,
        0.001067506315036309,
        0.028346745231833333,
    ];
    let t = x * x;
    let (t2, t4) = (t * t, t * t * t * t);
    let p = |i: usize| G[i] + t * G[i + 1];
    let g = (p(0) + t2 * p(2)) + t4 * (p(4) + t2 * p(6)) + (t4 * t4) * G[8];
    x + x * t * g
}

/// (sin θ, cos θ) for |θ| ≤ π/2, in plain arithmetic (no call, no table, no branch): the
/// Taylor series to θ²³ and θ²² by Estrin's scheme (truncation below 10⁻¹⁹), within a few ulp
/// of the backend's (absolutely: cos θ near ±π/2 is small, and keeps an absolute error of
/// an ulp of 1). For the short angles of quadrature panels (Poulin–Fournier's, where the
/// backend's `sin_cos` was a third of an evaluation). Outside |θ| ≤ π/2 it is not accurate.
#[inline(always)]
#[must_use]
pub fn sin_cos_small(theta: f64) -> (f64, f64) {
    /// (−1)^k/(2k+1)! and (−1)^k/(2k)! for k = 0…11: the two series' coefficients in θ².
    const COEFFS: ([f64; 12], [f64; 12]) = {
        let (mut s, mut c) = ([0.0; 12], [0.0; 12]);
        let (mut fact, mut k) = (1.0f64, 0);
        while k < 12 {
            // fact = (2k)! here.
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            c[k] = sign / fact;
            s[k] = sign / (fact * (2 * k + 1) as f64);
            fact *= ((2 * k + 1) * (2 * k + 2)) as f64;
            k += 1;
        }
        (s, c)
    };
    // Estrin's scheme in t = θ²: pairs, then pairs of pairs, so the dependency chain is
    // five multiply-adds long instead of twelve.
    let t = theta * theta;
    let (t2, t4) = (t * t, t * t * t * t);
    let t8 = t4 * t4;
    let estrin = |a: &[f64; 12]| {
        let p = |i: usize| a[2 * i] + t * a[2 * i + 1];
        let (q0, q1, q2) = (p(0) + t2 * p(1), p(2) + t2 * p(3), p(4) + t2 * p(5));
        (q0 + t4 * q1) + t8 * q2
    };
    (theta * estrin(&COEFFS.0), estrin(&COEFFS.1))
}

/// π/2 in two parts (fdlibm's `pio2_1`, `pio2_1t`): `PIO2_HI` has its low 20 bits zero, so
/// q·`PIO2_HI` is exact for |q| < 2²⁰, and `PIO2_LO` carries the next 53 bits.
const PIO2_HI: f64 = 1.570_796_326_734_125_6;
const PIO2_LO: f64 = 6.077_100_506_506_192e-11;

/// (sin x, cos x) for |x| ≤ 2²⁰·π/2 in plain arithmetic (no call, no table, no branch but
/// selects): x = q·π/2 + r with |r| ≤ π/4 (π/2 in two parts, so r is exact to rounding),
/// [`sin_cos_small`] of r, and the pair rotated by the quadrant q. Within a few ulp of the
/// backend's (absolutely: near a zero of either one). For the polar charts' angles, on every
/// sample of a polar leaf (the root and its children), where the backend's `sin_cos` call
/// was a quarter of a cheap model's sample. NaN gives NaN; beyond its domain the reduction
/// loses accuracy.
#[inline(always)]
#[must_use]
pub fn sin_cos_reduced(x: f64) -> (f64, f64) {
    // 1.5·2^52: adding it rounds x·2/π to an integer held in the low mantissa bits.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    let qf = x * core::f64::consts::FRAC_2_PI + SHIFT;
    let q = qf.to_bits();
    let qd = qf - SHIFT;
    let r = (x - qd * PIO2_HI) - qd * PIO2_LO;
    let (s, c) = sin_cos_small(r);
    // sin(r + qπ/2), cos(r + qπ/2) for q mod 4 = 0, 1, 2, 3:
    // (s, c), (c, −s), (−s, −c), (−c, s).
    let (s, c) = if q & 1 == 0 { (s, c) } else { (c, -s) };
    let flip = |v: f64, neg: bool| f64::from_bits(v.to_bits() ^ (u64::from(neg) << 63));
    (flip(s, q & 2 != 0), flip(c, q & 2 != 0))
}

/// atan(n/d) for |n| ≤ |d|, d ≠ 0 (so in [−π/4, π/4]), in plain arithmetic: one division, no
/// call, no table, no branch but selects. For the concentric map's inverse, which every warp
/// `pdf` and many warp samples pay, where the backend's `atan2` was 7 % of a per-wi warp
/// sample. NaN gives NaN; |n| > |d| is outside its domain.
///
/// A ratio t above tan(π/8) in size is reduced by atan t = π/4 + atan((t − 1)/(t + 1)), with
/// the two ratios' numerators and denominators selected before the one division, so the
/// argument x of the polynomial has |x| ≤ tan(π/8). There atan x = x + x·s·g(s), s = x², with
/// g the polynomial of degree 10 interpolating (atan √s/√s − 1)/s at the eleven Chebyshev
/// nodes of s ∈ [0, tan²(π/8)] (1.4·10⁻¹⁶ relative, so atan x to 3·10⁻¹⁸ absolutely before
/// rounding). Within a few ulp of the backend's `atan2(n, d)`, less π when d < 0.
#[inline(always)]
#[must_use]
pub fn atan_ratio(n: f64, d: f64) -> f64 {
    /// g's monomial coefficients, s⁰…s¹⁰.
    const G: [f64; 11] = [
        -0.333_333_333_333_333_3,
        0.199_999_999_999_955_2,
        -0.142_857_142_846_665_42,
        0.111_111_110_152_563_61,
        -0.090_909_045_781_239_03,
        0.076_921_831_908_260_87,
        -0.066_645_114_473_819_48,
        0.058_581_489_128_022_1,
        -0.050_854_497_379_402_6,
        0.039_231_658_295_587_19,
        -0.019_176_887_119_062_26,
    ];
    /// tan(π/8) = √2 − 1.
    const TAN_PI_8: f64 = 0.414_213_562_373_095_03;
    let (an, ad) = (n.abs(), d.abs());
    let big = an > TAN_PI_8 * ad;
    let (num, den, base) = if big {
        (an - ad, an + ad, core::f64::consts::FRAC_PI_4)
    } else {
        (an, ad, 0.0)
    };
    let x = num / den;
    let s = x * x;
    let (s2, s4) = (s * s, s * s * s * s);
    let p = |i: usize| G[i] + s * G[i + 1];
    let g = ((p(0) + s2 * p(2)) + s4 * (p(4) + s2 * p(6))) + (s4 * s4) * (p(8) + s2 * G[10]);
    let a = base + (x + x * s * g);
    // The sign of n/d, applied to the non-negative angle of |n|/|d|.
    a.copysign(n) * d.signum()
}

/// ln x for x > 0, in plain arithmetic (no table, no branch, no call), so that a loop of
/// them vectorises; for x^n = e^{n ln x} at many quadrature nodes (Poulin–Fournier's lobe).
///
/// x = 2^e·m with m ∈ [1/√2, √2), ln m = 2 atanh(s), s = (m − 1)/(m + 1), |s| ≤ 0.172, by its
/// odd series to s¹⁹ (truncation below 2·10⁻¹⁷ relative), plus e·ln 2 (split in two parts).
/// Accurate to a few ulp for normal x; subnormal x and 0 are taken as the smallest normal
/// (ln = −708.4), NaN likewise; +∞ is outside its domain.
#[inline(always)]
#[must_use]
pub fn ln_positive(x: f64) -> f64 {
    const MANTISSA: u64 = 0x000f_ffff_ffff_ffff;
    const ONE: u64 = 0x3ff0_0000_0000_0000;
    let bits = x.max(f64::MIN_POSITIVE).to_bits();
    let m1 = f64::from_bits((bits & MANTISSA) | ONE);
    let big = m1 > core::f64::consts::SQRT_2;
    let m = if big { 0.5 * m1 } else { m1 };
    let e = ((bits >> 52) as i64 - 1023 + i64::from(big)) as f64;
    let s = (m - 1.0) / (m + 1.0);
    let (s2, s4) = (s * s, s * s * s * s);
    let c = |a: f64, b: f64| a + s2 * b;
    let p = (c(1.0 / 3.0, 1.0 / 5.0) + s4 * c(1.0 / 7.0, 1.0 / 9.0))
        + (s4 * s4)
            * ((c(1.0 / 11.0, 1.0 / 13.0) + s4 * c(1.0 / 15.0, 1.0 / 17.0))
                + s4 * s4 * (1.0 / 19.0));
    let ln_m = 2.0 * s + 2.0 * s * s2 * p;
    (e * LN2_HI + ln_m) + e * LN2_LO
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Within 2 ulp of the backend's atan2 (less π for d < 0) over |n| ≤ |d|: a dense sweep of
    /// the ratio (the reduction's switch at tan(π/8) and the ends ±1 included), tiny and huge
    /// magnitudes, signed zeros; NaN stays NaN.
    #[test]
    fn atan_ratio_is_atan() {
        let check = |n: f64, d: f64| {
            let want = if d > 0.0 { atan2(n, d) } else { atan2(-n, -d) };
            let got = atan_ratio(n, d);
            assert!(
                (got - want).abs() <= 2.0 * f64::EPSILON * want.abs().max(f64::MIN_POSITIVE),
                "atan({n}/{d}): {got} against {want}"
            );
        };
        for i in -200_000..=200_000 {
            let t = f64::from(i) / 200_000.0;
            for d in [1.0, -1.0, 3.7e-300, -2.5e300, 0.731] {
                check(t * d, d);
            }
        }
        let tan_pi_8 = core::f64::consts::SQRT_2 - 1.0;
        for k in -50..=50 {
            let t = tan_pi_8 + f64::from(k) * f64::EPSILON;
            check(t, 1.0);
            check(-t, 1.0);
        }
        assert_eq!(atan_ratio(1.0, 1.0), core::f64::consts::FRAC_PI_4);
        assert_eq!(atan_ratio(-1.0, 1.0), -core::f64::consts::FRAC_PI_4);
        assert_eq!(atan_ratio(0.0, 1.0), 0.0);
        assert_eq!(atan_ratio(0.0, -1.0).abs(), 0.0);
        assert!(atan_ratio(f64::NAN, 1.0).is_nan());
        assert!(atan_ratio(0.5, f64::NAN).is_nan());
    }

    /// Within 3 ulp of the backend's sin and cos (absolutely, near cos = 0) on [−π/2, π/2].
    #[test]
    fn sin_cos_small_is_sin_cos() {
        for i in -100_000..=100_000 {
            let x = core::f64::consts::FRAC_PI_2 * f64::from(i) / 100_000.0;
            let (s, c) = sin_cos_small(x);
            assert!(
                (s - sin(x)).abs() <= 3.0 * f64::EPSILON * sin(x).abs().max(0.5),
                "sin {x}"
            );
            assert!(
                (c - cos(x)).abs() <= 3.0 * f64::EPSILON * cos(x).max(0.5),
                "cos {x}"
            );
        }
        assert_eq!(sin_cos_small(0.0), (0.0, 1.0));
    }

    /// Within 4 ulp of 1 of the backend's sin and cos (absolutely: each is small near the
    /// other's extremes) on [−8π, 8π], with the quadrant's signs and the exact values at 0;
    /// NaN stays NaN.
    #[test]
    fn sin_cos_reduced_is_sin_cos() {
        for i in -400_000..=400_000 {
            let x = 8.0 * core::f64::consts::PI * f64::from(i) / 400_000.0;
            let (s, c) = sin_cos_reduced(x);
            let tol = 4.0 * f64::EPSILON;
            assert!((s - sin(x)).abs() <= tol, "sin {x}: {s} vs {}", sin(x));
            assert!((c - cos(x)).abs() <= tol, "cos {x}: {c} vs {}", cos(x));
            assert!((s * s + c * c - 1.0).abs() <= tol, "{x}");
        }
        assert_eq!(sin_cos_reduced(0.0), (0.0, 1.0));
        let (s, c) = sin_cos_reduced(3.0);
        assert!(s > 0.0 && c < 0.0);
        let (s, c) = sin_cos_reduced(-2.0);
        assert!(s < 0.0 && c < 0.0);
        let (s, c) = sin_cos_reduced(-1.0);
        assert!(s < 0.0 && c > 0.0);
        let (s, c) = sin_cos_reduced(f64::NAN);
        assert!(s.is_nan() && c.is_nan());
    }

    /// Within 4 ulp of the backend's exp on [−708, 0], exactly 1 at 0, and e^−708 below.
    #[test]
    fn exp_nonpositive_is_exp() {
        for i in 0..=200_000 {
            let x = -708.0 * f64::from(i) / 200_000.0;
            let (got, want) = (exp_nonpositive(x), exp(x));
            assert!(
                (got - want).abs() <= 4.0 * f64::EPSILON * want,
                "e^{x}: {got:e} vs {want:e}"
            );
        }
        for x in [
            -1e-300,
            -1e-17,
            -0.5,
            -0.346_573_590_279_972_6,
            -0.346_573_6,
        ] {
            let (got, want) = (exp_nonpositive(x), exp(x));
            assert!((got - want).abs() <= 2.0 * f64::EPSILON * want, "e^{x}");
        }
        assert_eq!(exp_nonpositive(0.0), 1.0);
        let floor = exp_nonpositive(-708.0);
        for x in [-708.5, -1e4, f64::NEG_INFINITY, f64::NAN] {
            assert_eq!(exp_nonpositive(x), floor, "{x}");
        }
    }

    /// Within 1.3e-12 relative of the backend's exp on [−708, 0] (densest on the [−40, 0] the
    /// HTSG series and shadowing use), exactly 1 at 0, and e^−708 below; and not good to
    /// 1e-13, so the test would see a lower-degree polynomial.
    #[test]
    fn exp_nonpositive_short_is_exp_to_its_bound() {
        let mut worst = 0.0f64;
        let dense = (0..=400_000).map(|i| -40.0 * f64::from(i) / 400_000.0);
        let wide = (0..=100_000).map(|i| -708.0 * f64::from(i) / 100_000.0);
        for x in dense.chain(wide) {
            let (got, want) = (exp_nonpositive_short(x), exp(x));
            let rel = (got - want).abs() / want;
            assert!(rel <= 1.3e-12, "e^{x}: {got:e} vs {want:e} ({rel:e})");
            worst = worst.max(rel);
        }
        assert!(worst > 1e-13, "worst {worst:e}");
        assert_eq!(exp_nonpositive_short(0.0), 1.0);
        let floor = exp_nonpositive_short(-708.0);
        for x in [-708.5, -1e4, f64::NEG_INFINITY, f64::NAN] {
            assert_eq!(exp_nonpositive_short(x), floor, "{x}");
        }
    }

    /// Within 5e-13 of the backend's acos on [0, 1] (relatively near 1, where acos → 0), and
    /// clamped outside; not better than 1e-15 everywhere, so a longer polynomial would show.
    #[test]
    fn acos_nonnegative_is_acos() {
        let mut worst = 0.0f64;
        for i in 0..=400_000 {
            let c = f64::from(i) / 400_000.0;
            let (got, want) = (acos_nonnegative(c), c.acos());
            let err = (got - want).abs();
            assert!(err <= 5e-13 * want.min(1.0), "acos {c}: {got} vs {want}");
            worst = worst.max(err);
        }
        for c in [
            1.0 - 1e-9,
            1.0 - 1e-14,
            1e-300,
            0.5,
            0.499_999_999_999_999_9,
        ] {
            let (got, want) = (acos_nonnegative(c), c.acos());
            assert!(
                (got - want).abs() <= 5e-13 * want,
                "acos {c}: {got} vs {want}"
            );
        }
        assert!(worst > 1e-15, "worst {worst:e}");
        assert_eq!(acos_nonnegative(1.0), 0.0);
        assert_eq!(acos_nonnegative(2.0), 0.0);
        assert_eq!(acos_nonnegative(f64::NAN), 0.0);
        assert_eq!(acos_nonnegative(-1.0), core::f64::consts::FRAC_PI_2);
    }

    /// Within 4 ulp of the backend's ln (2e-16 absolute near 1) from the smallest normal to
    /// 10³⁰⁰, and clamped below.
    #[test]
    fn ln_positive_is_ln() {
        for i in 0..=200_000 {
            let x = 10f64.powf(-307.0 + 607.0 * f64::from(i) / 200_000.0);
            let (got, want) = (ln_positive(x), ln(x));
            assert!(
                (got - want).abs() <= 4.0 * f64::EPSILON * want.abs().max(0.5),
                "ln {x:e}: {got} vs {want}"
            );
        }
        for i in 0..=100_000 {
            let x = 0.5 + f64::from(i) / 100_000.0;
            let (got, want) = (ln_positive(x), ln(x));
            assert!(
                (got - want).abs() <= 2.0 * f64::EPSILON * want.abs().max(0.5),
                "ln {x}"
            );
        }
        assert_eq!(ln_positive(1.0), 0.0);
        let floor = ln_positive(f64::MIN_POSITIVE);
        for x in [0.0, 1e-320, -1.0, f64::NAN] {
            assert_eq!(ln_positive(x), floor, "{x}");
        }
    }
}
