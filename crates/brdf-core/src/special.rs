//! Special functions the physically based models need: the complementary error function,
//! ln Γ and the principal branch of Lambert's W.
//!
//! `erfc` and `ln_gamma` come from the `libm` crate (a port of musl's, accurate to a few ulp
//! over the whole range; in particular `erfc` keeps full relative precision in the far tail,
//! where 1 − erf would cancel to 0). Lambert W is ours: Halley's iteration, tested below
//! against published values.

/// The complementary error function erfc(x) = 1 − erf(x), accurate in the tail (erfc(26) ≈
/// 5.66e-296 to full precision).
#[inline]
#[must_use]
pub fn erfc(x: f64) -> f64 {
    libm::erfc(x)
}

/// ln Γ(x) for x > 0.
#[inline]
#[must_use]
pub fn ln_gamma(x: f64) -> f64 {
    libm::lgamma_r(x).0
}

/// The principal branch W₀ of Lambert's W function for y ≥ 0: the w ≥ 0 with w·e^w = y.
///
/// Halley's iteration from a log-asymptotic start, to a relative step of 1e-15 (it converges
/// in at most a handful of steps; the loop is capped); below y = 10⁻³, the first six terms
/// of its series, exact to rounding. Returns NaN for y < 0 or NaN, and
/// +∞ for y = +∞.
#[must_use]
pub fn lambert_w0(y: f64) -> f64 {
    if y.is_nan() || y < 0.0 {
        return f64::NAN;
    }
    if y == 0.0 {
        return 0.0;
    }
    if y == f64::INFINITY {
        return f64::INFINITY;
    }
    if y < 1e-3 {
        // The series Σ (−n)^{n−1} yⁿ/n! = y − y² + 3y³/2 − 8y⁴/3 + 125y⁵/24 − 54y⁶/5 + …:
        // the next term, 16807y⁷/720, is below 3·10⁻¹⁷ of y.
        return y * (1.0 - y * (1.0 - y * (1.5 - y * (8.0 / 3.0 - y * (125.0 / 24.0 - y * 10.8)))));
    }
    let mut w = if y < 3.0 {
        crate::math::ln_1p(y) * (1.0 - 0.15 * crate::math::ln_1p(y) / (1.0 + y))
    } else {
        let l1 = crate::math::ln(y);
        let l2 = crate::math::ln(l1);
        l1 - l2 + l2 / l1
    };
    for _ in 0..64 {
        // Halley on F(w) = w − y·e^{−w} (the same root, no overflow of e^w for large y).
        let e = y * crate::math::exp(-w);
        let f = w - e;
        let f1 = 1.0 + e;
        let f2 = -e;
        let step = f / (f1 - 0.5 * f * f2 / f1);
        w -= step;
        if step.abs() <= 1e-15 * w.abs().max(1e-300) {
            break;
        }
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs()
    }

    #[test]
    fn lambert_w_matches_published_values() {
        // Reference values: Newton on w·e^w = y in 50-digit decimal arithmetic.
        for (y, w) in [
            (1e-10, 9.999_999_999e-11),
            // Either side of the series' end at 1e-3.
            (9.99e-4, 9.980_034_918_536_54e-4),
            (1.001e-3, 9.999_995_008_323_757e-4),
            (0.1, 0.091_276_527_160_862_26),
            (1.0, 0.567_143_290_409_783_8),
            (core::f64::consts::E, 1.0),
            (10.0, 1.745_528_002_740_699_4),
            (100.0, 3.385_630_140_290_05),
            (1e6, 11.383_358_086_140_053),
            (1e100, 224.843_106_445_118_5),
        ] {
            let got = lambert_w0(y);
            assert!(close(got, w, 1e-13), "W({y}) = {got}, want {w}");
            assert!(close(got * crate::math::exp(got), y, 1e-13));
        }
        assert_eq!(lambert_w0(0.0), 0.0);
        assert!(lambert_w0(-1.0).is_nan());
        assert!(lambert_w0(f64::NAN).is_nan());
    }

    #[test]
    fn erfc_keeps_relative_precision_in_the_tail() {
        for (x, want) in [
            (0.0, 1.0),
            (0.5, 0.479_500_122_186_953_5),
            (2.0, 4.677_734_981_047_266e-3),
            (5.0, 1.537_459_794_428_035e-12),
            (10.0, 2.088_487_583_762_545e-45),
            (26.0, 5.663_192_408_856_143e-296),
            (-1.0, 1.842_700_792_949_715),
        ] {
            assert!(close(erfc(x), want, 1e-14), "erfc({x}) = {}", erfc(x));
        }
    }

    #[test]
    fn ln_gamma_of_factorials() {
        let mut lf = 0.0f64;
        for m in 1..200u32 {
            lf += f64::from(m).ln();
            assert!(close(ln_gamma(f64::from(m) + 1.0), lf, 1e-13));
        }
    }
}
