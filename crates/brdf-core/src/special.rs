//! Special functions the physically based models need: the complementary error function,
//! ln Γ and the principal branch of Lambert's W.
//!
//! `erfc` and `ln_gamma` come from the `libm` crate (a port of musl's, accurate to a few ulp
//! over the whole range; in particular `erfc` keeps full relative precision in the far tail,
//! where 1 − erf would cancel to 0). Lambert W is ours: Halley's iteration, tested below
//! against published values. So is `erfcx_short`, the scaled erfc on [0, 6] by a table of
//! polynomials, for a caller that needs e^{−x²} anyway (HTSG's shadowing: one exponential
//! instead of libm erfc's two).

/// The complementary error function erfc(x) = 1 − erf(x), accurate in the tail (erfc(26) ≈
/// 5.66e-296 to full precision).
#[inline]
#[must_use]
pub fn erfc(x: f64) -> f64 {
    libm::erfc(x)
}

/// Where [`erfcx_short`] holds: [0, `ERFCX_SHORT_MAX`].
pub const ERFCX_SHORT_MAX: f64 = 6.0;

/// erfcx's polynomials on the twelve intervals [i/2, (i + 1)/2] of [0, 6], in s = 4(x − cᵢ) ∈
/// [−1, 1] (cᵢ the interval's centre), lowest power first: the degree-12 interpolants at the
/// Chebyshev nodes, computed offline at 50 digits (mpmath). erfcx is entire, so they converge
/// fast: evaluated in f64 by Horner's rule offline, their worst relative error against erfcx
/// on 201 points an interval was 9.4·10⁻¹⁶; [`erfcx_short`] evaluates them by Estrin's scheme,
/// which its test holds to 2·10⁻¹⁵.
#[allow(clippy::unreadable_literal)]
const ERFCX_POLY: [[f64; 13]; 12] = [
    [
        0.7703465477309968,
        -0.18580147330749627,
        0.03653406715146768,
        -0.0062194752567052616,
        0.0009473309967357329,
        -0.00013180360486534726,
        1.699015381892417e-05,
        -2.0502458027178e-06,
        2.334366455001955e-07,
        -2.5224113349396268e-08,
        2.601714124857212e-09,
        -2.645535522720767e-10,
        2.5084180598363034e-11,
    ],
    [
        0.5069376502931449,
        -0.09199317291394817,
        0.014434883221956088,
        -0.0020286884686890566,
        0.0002609005567498488,
        -3.1149669808397036e-05,
        3.4885738807897664e-06,
        -3.693567406943463e-07,
        3.719543629447327e-08,
        -3.579272112111564e-09,
        3.3061733705972456e-10,
        -3.010096125292678e-11,
        2.581271691748106e-12,
    ],
    [
        0.3678229164523611,
        -0.05220546899115238,
        0.006674723218537419,
        -0.0007846605374382521,
        8.598189160507216e-05,
        -8.868776967725166e-06,
        8.674584711778801e-07,
        -8.09194284279868e-08,
        7.232217406690809e-09,
        -6.215429959552571e-10,
        5.154261278261677e-11,
        -4.214961825526736e-12,
        3.2747182507155396e-13,
    ],
    [
        0.2849722347374364,
        -0.03274408637862129,
        0.0034852268804429535,
        -0.0003478124256469985,
        3.2829371903648855e-05,
        -2.950170555585948e-06,
        2.537120414482415e-07,
        -2.096762028769442e-08,
        1.670918660864194e-09,
        -1.2875251113676387e-10,
        9.61847389834657e-12,
        -7.092030933689514e-13,
        5.0048417345007894e-14,
    ],
    [
        0.23108725873039188,
        -0.022121625702187286,
        0.0019995392131691415,
        -0.00017190719931942612,
        1.4136700602964347e-05,
        -1.1169223469151147e-06,
        8.509165574807611e-08,
        -6.269598619463966e-09,
        4.478950947622092e-10,
        -3.108856441414792e-11,
        2.10082401649295e-12,
        -1.402683891597517e-13,
        9.019823445765036e-15,
    ],
    [
        0.1936620962790687,
        -0.01580940939015871,
        0.001234912061707679,
        -9.272402964060302e-05,
        6.717116739411538e-06,
        -4.708936375997823e-07,
        3.202680676576849e-08,
        -2.117835321201201e-09,
        1.3641597025404525e-10,
        -8.572609778060283e-12,
        5.263802979021472e-13,
        -3.1971258939165315e-14,
        1.8800738604690586e-15,
    ],
    [
        0.16633534842682188,
        -0.011799850580292594,
        0.0008085806801886348,
        -5.367923907668294e-05,
        3.4609553809933582e-06,
        -2.1717047807742037e-07,
        1.3286232619299866e-08,
        -7.937403081265358e-10,
        4.636889929605563e-11,
        -2.651912467909991e-12,
        1.4865485154109668e-13,
        -8.251888719805715e-15,
        4.454562117727668e-16,
    ],
    [
        0.14558972127503855,
        -0.009114064383180883,
        0.0005549222204578311,
        -3.292629484639286e-05,
        1.907118680060835e-06,
        -1.0798786613289054e-07,
        5.985430999920972e-09,
        -3.251143200862901e-10,
        1.732369459208254e-11,
        -9.063500898261399e-13,
        4.659999514606456e-14,
        -2.3750846277556673e-15,
        1.1815817873651303e-16,
    ],
    [
        0.12934527478598792,
        -0.007236082853653833,
        0.00039574164211704684,
        -2.1186455736001674e-05,
        1.1116217064069037e-06,
        -5.722216817598962e-08,
        2.8926009873682308e-09,
        -1.4371342152607251e-10,
        7.023014024445707e-12,
        -3.3780170712636556e-13,
        1.6003168989041294e-14,
        -7.522483388703235e-16,
        3.462294803041272e-17,
    ],
    [
        0.11630270721024731,
        -0.005875862149540788,
        0.00029133289806077125,
        -1.4189045266088957e-05,
        6.794074376588104e-07,
        -3.200759876395623e-08,
        1.4846471070136548e-09,
        -6.784471061780229e-11,
        3.056212968617432e-12,
        -1.3578510096466765e-13,
        5.953169824807012e-15,
        -2.591907760108697e-16,
        1.1078471622899968e-17,
    ],
    [
        0.1056127354688918,
        -0.004861361168037162,
        0.0002202594337569623,
        -9.829710797539752e-06,
        4.323595940196192e-07,
        -1.8753983078086295e-08,
        8.026239453614756e-10,
        -3.390857582363441e-11,
        1.4147478393182942e-12,
        -5.831704153025278e-14,
        2.3759395644914543e-15,
        -9.619931371665538e-17,
        3.832315492243951e-18,
    ],
    [
        0.09669877816971392,
        -0.004085804535950621,
        0.00017032961517810219,
        -7.009307785594627e-06,
        2.8486050341955844e-07,
        -1.1437905173582296e-08,
        4.5393092554672476e-10,
        -1.7812390949431116e-11,
        6.913427648222772e-13,
        -2.6548500183324395e-14,
        1.0090217232526848e-15,
        -3.813643120173001e-17,
        1.4208519269427467e-18,
    ],
];

/// The scaled complementary error function erfcx(x) = e^{x²}·erfc(x) for x ∈ [0, 6], by a
/// table of twelve degree-12 polynomials: no call, no exponential. Within 2·10⁻¹⁵ relative of
/// erfcx (a test compares it with [`erfc`] times e^{x²}). It lets a caller that wants both
/// erfc(x) and e^{−x²} (HTSG's shadowing) pay one exponential for the two. x outside
/// [0, 6] (NaN included) is clamped into it.
#[must_use]
pub fn erfcx_short(x: f64) -> f64 {
    let x = if x >= 0.0 {
        x.min(ERFCX_SHORT_MAX)
    } else {
        0.0
    };
    // 0 ≤ 2x ≤ 12; x = 6 belongs to the last interval.
    let i = ((2.0 * x) as usize).min(ERFCX_POLY.len() - 1);
    let s = 4.0 * x - (2 * i + 1) as f64;
    let c = &ERFCX_POLY[i];
    let (s2, s4) = (s * s, s * s * s * s);
    let p = |k: usize| c[k] + s * c[k + 1];
    let lo = (p(0) + s2 * p(2)) + s4 * (p(4) + s2 * p(6));
    let hi = (p(8) + s2 * p(10)) + s4 * c[12];
    lo + (s4 * s4) * hi
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

    /// erfcx by its table against libm's erfc times e^{x²} (each a few ulp) on a fine grid of
    /// [0, 6] and at every interval's ends.
    #[test]
    fn erfcx_short_is_erfc_scaled() {
        let ends = (0..=12).map(|i| f64::from(i) * 0.5);
        for x in (0..=60_000).map(|i| f64::from(i) * 1e-4).chain(ends) {
            // e^{x²} with x² split exactly into hi + lo (lo by fma), so the reference is not
            // off by x²'s rounding (4·10⁻¹⁵ relative at x = 6).
            let hi = x * x;
            let lo = x.mul_add(x, -hi);
            let want = erfc(x) * hi.exp() * (1.0 + lo);
            let got = erfcx_short(x);
            assert!(close(got, want, 2e-15), "erfcx({x}) = {got}, want {want}");
        }
        assert_eq!(erfcx_short(-1.0), erfcx_short(0.0));
        assert!(close(erfcx_short(0.0), 1.0, 1e-15));
        assert_eq!(erfcx_short(f64::NAN), erfcx_short(0.0));
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
