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
