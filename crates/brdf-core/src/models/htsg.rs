use crate::Symmetry;
use crate::brdf::Brdf;
use crate::error::ParamError;
use crate::geometry::{above_horizon, luminance, upper_pair};
use crate::math as m;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use crate::special::{erfcx_short, lambert_w0, ln_gamma};
use core::f64::consts::{FRAC_1_PI, PI};
use glam::{DVec3, Vec3};

/// √π.
const SQRT_PI: f64 = 1.772_453_850_905_516;

/// Above this g the Poisson series is replaced by its second-order expansion (MODELS.md §7).
pub const HTSG_SERIES_LIMIT: f64 = 300.0;

/// ln of the relative size below which the series' remaining terms are dropped (the
/// log-space series the tests check against).
#[cfg(test)]
const LN_REL_TOL: f64 = -36.841_361_487_904_73; // ln(1e-16)

/// ln of the absolute size below which a sum no longer matters: D carries a prefactor of at
/// most π²τ²/(4λ²) ≈ 6.2e5 and f is reported in f32, whose smallest subnormal is e^-103.4.
const LN_ABS_TOL: f64 = -200.0;

/// `htsg`: He, Torrance, Sillion & Greenberg (1991), the physically based model of a rough
/// conductor or dielectric as MODELS.md §7 fixes it: effective roughness σ(θi, θo) from
/// Lambert W, the Poisson series of the directional-diffuse distribution (second-order
/// expansion past g = 300), the simplified geometry factor, Smith-type shadowing with the
/// e^{−a²} term the printed Eq. 25 drops, conductor Fresnel at the local angle, plus a
/// uniform-diffuse term a/π.
///
/// The **specular** part ρs(θi) = F(cos θi)·e^{−gs}·S(θi)² is a Dirac delta toward r(wi):
/// [`Brdf::eval`] excludes it, [`Brdf::delta_reflectance`] reports it, and
/// [`Brdf::sample`] chooses it by luminance against an estimate of the continuous albedo.
/// The continuous part has no analytic sampler (cosine sampling is its baseline; the quadtree
/// is the reason this model is here). Reciprocal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Htsg {
    sigma0: f32,
    tau: f32,
    lambda: Vec3,
    eta: Vec3,
    kappa: Vec3,
    a: Vec3,
    /// What each channel's evaluation needs of its parameters, made once in [`Htsg::new`].
    channels: [Channel; 3],
}

/// One channel's constants: functions of (τ, λ, η, κ) that every evaluation would otherwise
/// recompute.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Channel {
    /// 2·ln(2π/λ): ln g = 2·ln(σ·vz) + this, so the three channels share one logarithm.
    ln_k2: f64,
    /// π²τ²/λ²: A = this · |wi.xy + wo.xy|².
    a_scale: f64,
    /// η² − κ² − 1 (Fresnel's B − c², see [`conductor_fresnel`]).
    fresnel_e: f64,
    /// 4η²κ².
    fresnel_4e2k2: f64,
}

impl Channel {
    fn new(tau: f64, lambda: f64, eta: f64, kappa: f64) -> Self {
        let tl = tau / lambda;
        Self {
            ln_k2: 2.0 * m::ln(2.0 * PI / lambda),
            a_scale: PI * PI * tl * tl,
            fresnel_e: (eta - 1.0) * (eta + 1.0) - kappa * kappa,
            fresnel_4e2k2: 4.0 * eta * eta * kappa * kappa,
        }
    }
}

/// The per-pair quantities shared by the three channels.
struct Geometry {
    /// Effective roughness σ(θi, θo).
    sigma: f64,
    /// cos θi + cos θo.
    vz: f64,
    /// |wi.xy + wo.xy|².
    vxy2: f64,
}

impl Htsg {
    /// The model's parameters (lengths in µm; only their ratios matter).
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::scalar("sigma0", 0.18, 0.001, 10.0, "RMS surface height (um)"),
        ParamSpec::scalar(
            "tau",
            3.0,
            0.05,
            100.0,
            "surface autocorrelation length (um)",
        ),
        ParamSpec::rgb(
            "lambda",
            [0.645, 0.526, 0.444],
            0.2,
            2.0,
            "wavelength per channel (um)",
        ),
        ParamSpec::rgb(
            "eta",
            [1.3211, 0.88045, 0.59765],
            0.01,
            10.0,
            "refractive index per channel (default: aluminium)",
        ),
        ParamSpec::rgb(
            "kappa",
            [7.41785, 6.1455, 5.2337],
            0.0,
            20.0,
            "extinction coefficient per channel (0 = dielectric)",
        ),
        ParamSpec::rgb("a", [0.0; 3], 0.0, 1.0, "uniform-diffuse albedo"),
    ];

    /// An HTSG BRDF; every value must lie in its range ([`Htsg::PARAMS`]).
    pub fn new(
        sigma0: f32,
        tau: f32,
        lambda: Vec3,
        eta: Vec3,
        kappa: Vec3,
        a: Vec3,
    ) -> Result<Self, ParamError> {
        let sigma0 = Self::PARAMS[0].check_scalar(sigma0)?;
        let tau = Self::PARAMS[1].check_scalar(tau)?;
        let lambda = Self::PARAMS[2].check_rgb(lambda)?;
        let eta = Self::PARAMS[3].check_rgb(eta)?;
        let kappa = Self::PARAMS[4].check_rgb(kappa)?;
        let a = Self::PARAMS[5].check_rgb(a)?;
        let channel = |i: usize| {
            Channel::new(
                f64::from(tau),
                f64::from(lambda[i]),
                f64::from(eta[i]),
                f64::from(kappa[i]),
            )
        };
        Ok(Self {
            sigma0,
            tau,
            lambda,
            eta,
            kappa,
            a,
            channels: [channel(0), channel(1), channel(2)],
        })
    }

    /// Builds from a validated parameter set.
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        Self::new(
            p.scalar("sigma0")?,
            p.scalar("tau")?,
            p.rgb("lambda")?,
            p.rgb("eta")?,
            p.rgb("kappa")?,
            p.rgb("a")?,
        )
    }

    fn s0(&self) -> f64 {
        f64::from(self.sigma0)
    }

    fn t0(&self) -> f64 {
        f64::from(self.tau)
    }

    /// K(θ) = tan θ · erfc(τ / (2σ0 tan θ)) and the shadowing S(θ) of one direction (z > 0),
    /// which share erfc: K's argument τ/(2σ0 tan θ) is S's a = τ cot θ/(2σ0).
    ///
    /// K is 0 when tan θ < 1e-6, and when a exceeds 5.5 (erfc is then not paid for): there
    /// K < (τ/2σ0)·e^{−a²}/(a²√π) < 7·10⁻¹¹ for every parameter in range. When the other
    /// direction's K is as small, f0² < 10⁻²⁰ and 1 + W0(f0²) rounds to 1: σ is σ0 to the
    /// last bit either way; otherwise σ moves by less than f0·3·10⁻¹¹/(1 + W0(f0²)), below
    /// 2·10⁻⁹ relative even for f0 ≈ 2000 (the other direction at the 10⁻⁴ grazing floor).
    /// S is 1 for a ≥ 6, where its formula is 1 − 10⁻¹⁷ or closer, which rounds to 1.
    fn k_and_shadowing(&self, w: DVec3) -> (f64, f64) {
        if w.z <= 0.0 {
            return (0.0, 0.0);
        }
        let (s0, t0) = (self.s0(), self.t0());
        let sin2 = w.x * w.x + w.y * w.y;
        // a = τ·cos θ/(2σ0·sin θ) ≥ 6 ⟺ (τ·cos θ)² ≥ (12σ0)²·sin²θ: no root or division on
        // the common path. tan θ < 10⁻⁶ (sin θ = 0 included) is inside it: a > τ/(2σ0·10⁻⁶)
        // ≥ 2500 there.
        let tz = t0 * w.z;
        if tz * tz >= 144.0 * s0 * s0 * sin2 {
            return (0.0, 1.0);
        }
        let sin = m::sqrt(sin2);
        let tan = sin / w.z;
        let a = tz / (2.0 * s0 * sin);
        // erfc a = e^{−a²}·erfcx a: one exponential serves erfc and Λ, and 1/a = (2σ0/τ)·tan θ.
        let e = m::exp_nonpositive_short(-a * a);
        let ex = erfcx_short(a);
        let ec = e * ex;
        let k = if a > 5.5 { 0.0 } else { tan * ec };
        let lambda = 0.5 * e * (2.0 * s0 / (t0 * SQRT_PI) * tan - ex);
        (k, ((1.0 - 0.5 * ec) / (lambda + 1.0)).clamp(0.0, 1.0))
    }

    /// σ0 / √(1 + W0(f0²)), f0 = (K(θi) + K(θo))/√(8π).
    fn sigma_of(&self, k_sum: f64) -> f64 {
        let f0 = k_sum / m::sqrt(8.0 * PI);
        self.s0() / m::sqrt(1.0 + lambert_w0(f0 * f0))
    }

    /// The effective roughness σ(θi, θo) = σ0 / √(1 + W0(f0²)), f0 = (K(θi) + K(θo))/√(8π),
    /// K(θ) = tan θ · erfc(τ / (2σ0 tan θ)).
    #[must_use]
    pub fn effective_roughness(&self, wi: DVec3, wo: DVec3) -> f64 {
        self.sigma_of(self.k_and_shadowing(wi).0 + self.k_and_shadowing(wo).0)
    }

    /// Smith-type shadowing S(θ) with a = τ cot θ / (2σ0): (1 − ½erfc a)/(Λ(a) + 1),
    /// Λ(a) = ½(e^{−a²}/(a√π) − erfc a); 1 at the normal, 0 at the horizon.
    ///
    /// For a ≥ 6 the formula is 1 − 10⁻¹⁷ or closer, which rounds to 1: it returns 1 there
    /// without evaluating it.
    #[must_use]
    pub fn shadowing(&self, w: DVec3) -> f64 {
        self.k_and_shadowing(w).1
    }

    /// The pair's geometry and its shadowing S(θi)·S(θo).
    fn geometry(&self, wi: DVec3, wo: DVec3) -> (Geometry, f64) {
        let ((ki, si), (ko, so)) = (self.k_and_shadowing(wi), self.k_and_shadowing(wo));
        let (sx, sy) = (wi.x + wo.x, wi.y + wo.y);
        let geo = Geometry {
            sigma: self.sigma_of(ki + ko),
            vz: wi.z + wo.z,
            vxy2: sx * sx + sy * sy,
        };
        (geo, si * so)
    }

    /// The directional-diffuse distribution D of the three channels (each the sum, times
    /// its prefactor π²τ²/(4λ²)): g = (2πσ·vz/λ)² with ln g = 2·ln(σ·vz) + 2·ln(2π/λ), one
    /// logarithm for the three.
    fn distribution(&self, geo: &Geometry) -> DVec3 {
        let sv = geo.sigma * geo.vz;
        let ln_sv2 = 2.0 * m::ln(sv);
        let l = self.lambda.as_dvec3().to_array();
        let mut d = [0.0; 3];
        for ((di, ch), lambda) in d.iter_mut().zip(&self.channels).zip(l) {
            let t = 2.0 * PI * sv / lambda;
            let g = t * t;
            let a = ch.a_scale * geo.vxy2;
            *di = 0.25 * ch.a_scale * htsg_sum_ln(g, ln_sv2 + ch.ln_k2, a);
        }
        DVec3::from_array(d)
    }

    /// The per-channel Fresnel reflectance of the conductor at local cosine `c`.
    fn fresnel(&self, c: f64) -> DVec3 {
        let [r, g, b] = self
            .channels
            .map(|ch| fresnel_of(c, ch.fresnel_e, ch.fresnel_4e2k2));
        DVec3::new(r, g, b)
    }

    fn specular(&self, wi: DVec3) -> DVec3 {
        let (k, s) = self.k_and_shadowing(wi);
        let sigma = self.sigma_of(2.0 * k);
        let f = self.fresnel(wi.z);
        let l = self.lambda.as_dvec3();
        let gs = |lambda: f64| {
            let t = 4.0 * PI * sigma * wi.z / lambda;
            m::exp(-t * t)
        };
        f * DVec3::new(gs(l.x), gs(l.y), gs(l.z)) * (s * s)
    }
}

/// Unpolarised Fresnel reflectance of a conductor (η, κ) at incidence cosine `c`
/// (MODELS.md §7, step 6); 1 for c < 1e-7.
#[must_use]
pub fn conductor_fresnel(c: f64, eta: f64, kappa: f64) -> f64 {
    let e = (eta - 1.0) * (eta + 1.0) - kappa * kappa;
    fresnel_of(c, e, 4.0 * eta * eta * kappa * kappa)
}

/// [`conductor_fresnel`] from e = η² − κ² − 1 and 4η²κ², with two divisions (s·t = s²/c,
/// and the last), where MODELS.md's form takes four.
///
/// B = η² − κ² − s² is written e + c², so that for η = 1, κ = 0 (no interface) B, Q and a
/// are exactly c², c², c and F is exactly 0, not rounding noise. The (a − c)² of Fs's
/// numerator is h²/d² with h = (a² − c²) = ½(Q + e − c²) and d = a + c, and
/// F = ½Fs(1 + Fp/Fs) = Fs·(a² + b² + s²t²)/D₂, so F = (h² + b²d²)(a² + b² + s²t²)/(d²D₁D₂)
/// with D₁, D₂ the two denominators of MODELS.md's Fs and Fp/Fs. Every factor stays below
/// 10²⁰ for parameters in range (s²t² ≤ 10¹⁴ at c = 10⁻⁷).
#[inline]
fn fresnel_of(c: f64, e: f64, four_e2k2: f64) -> f64 {
    if c < 1e-7 {
        return 1.0;
    }
    let c = c.min(1.0);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    // s·t = s²/c and s²t² = (s·t)².
    let st = s2 / c;
    let s2t2 = st * st;
    let b = e + c2;
    let q = m::sqrt(b * b + four_e2k2);
    let a2 = 0.5 * (q + b);
    let b2 = 0.5 * (q - b);
    let a = m::sqrt(a2.max(0.0));
    let h = 0.5 * (q + e - c2);
    let d = a + c;
    let d2 = d * d;
    let ab = a2 + b2;
    let d1 = ab + 2.0 * a * c + c2;
    let dp = ab + 2.0 * a * st + s2t2;
    (h * h + b2 * d2) * (ab + s2t2) / (d2 * d1 * dp)
}

/// How many terms the series tables hold. g ≤ [`HTSG_SERIES_LIMIT`] puts the terms' peak
/// past it only for an A so large that the whole sum is below e^−1000; those sums take the
/// ratio recurrence (`htsg_sum_ratio`).
const TABLE_LEN: usize = 1024;

/// ln x for x ≥ 1 at compile time: x = 2^e·m with m ∈ [1/√2, √2], ln m = 2 atanh((m − 1)/(m + 1))
/// by its series (40 terms: |s| ≤ 0.172, so the last is below 10⁻⁶⁰), within a few ulp.
const fn ln_at_compile_time(x: f64) -> f64 {
    let bits = x.to_bits();
    let mut e = ((bits >> 52) & 0x7ff) as i64 - 1023;
    let mut mant = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    if mant > core::f64::consts::SQRT_2 {
        mant *= 0.5;
        e += 1;
    }
    let s = (mant - 1.0) / (mant + 1.0);
    let (s2, mut power, mut sum) = (s * s, s, 0.0);
    let mut j = 0;
    while j < 40 {
        sum += power / (2 * j + 1) as f64;
        power *= s2;
        j += 1;
    }
    2.0 * sum + e as f64 * core::f64::consts::LN_2
}

/// What the series needs of each integer m ≤ [`TABLE_LEN`] + 1, made at compile time.
struct SeriesTable {
    /// ln m.
    ln: [f64; TABLE_LEN + 2],
    /// ln m! + ln m (compensated running sums of ln m, so within an ulp or two).
    ln_fact_m: [f64; TABLE_LEN + 2],
    /// 1/m.
    inv: [f64; TABLE_LEN + 2],
}

static SERIES: SeriesTable = {
    let mut t = SeriesTable {
        ln: [0.0; TABLE_LEN + 2],
        ln_fact_m: [0.0; TABLE_LEN + 2],
        inv: [0.0; TABLE_LEN + 2],
    };
    let (mut acc, mut carry) = (0.0f64, 0.0f64);
    let mut m = 1;
    while m < TABLE_LEN + 2 {
        let l = ln_at_compile_time(m as f64);
        // Kahan: acc + carry is ln m! to well below acc's ulp.
        let y = l - carry;
        let next = acc + y;
        carry = (next - acc) - y;
        acc = next;
        t.ln[m] = l;
        t.ln_fact_m[m] = acc + l;
        t.inv[m] = 1.0 / m as f64;
        m += 1;
    }
    t
};

/// How many terms [`htsg_sum`] evaluates at a time (one SSE2 vector: the first terms past
/// a fast-falling peak are not wasted in fours).
const BLOCK: usize = 2;

/// ln(1e-10): the series stops where its terms fall below this fraction of the largest. f is
/// reported in f32, whose rounding is 6·10⁻⁸; on the test grid the sum stays within 10⁻¹¹ of
/// the plain series (`the_fast_sums_are_the_series` allows 10⁻¹⁰).
const LN_REL_STOP: f64 = -23.025_850_929_940_457;

/// Σ_{m≥1} g^m e^{−g}/m! · e^{−A/m}/m, the sum in HTSG's D (MODELS.md §7, step 3).
///
/// For g ≤ [`HTSG_SERIES_LIMIT`] the exact series. Its log-terms y_m = m ln g − ln m! − ln m −
/// A/m are concave in m (the ratio of consecutive terms, g·m/(m+1)²·e^{A/(m(m+1))}, falls
/// with m), so the largest term is the first m where that ratio drops below one: found by a
/// galloping search from m ≈ g in O(log) steps, with ln m, ln m! and 1/m read from tables
/// made at compile time. The terms are then summed outward from it, `BLOCK` (2) at a time with a
/// table-free exponential good to 1.3·10⁻¹² ([`crate::math::exp_nonpositive_short`], so the
/// blocks vectorise), until they are below 10⁻¹⁰ of the largest; by concavity each neglected
/// tail is below 10⁻¹⁰·D/23 of the largest term (the ratio there is at most e^{−23/D}, D ≤ 1024
/// the distance from the peak), so below 4.5·10⁻⁹ of the sum, far under f32's rounding.
/// A peak beyond the tables takes the ratio recurrence (`htsg_sum_ratio`). Beyond the
/// limit, the second-order expansion h(g) + (g/2)·h''(g), h(μ) = e^{−A/μ}/μ. 0 when g = 0
/// or A = ∞.
#[must_use]
pub fn htsg_sum(g: f64, a: f64) -> f64 {
    htsg_sum_ln(g, m::ln(g), a)
}

/// [`htsg_sum`] given ln g as well (`lg`; the caller's may differ from `ln(g)` by rounding).
fn htsg_sum_ln(g: f64, lg: f64, a: f64) -> f64 {
    if g.is_nan() || g <= 0.0 || a.is_nan() || a == f64::INFINITY {
        return 0.0;
    }
    if g > HTSG_SERIES_LIMIT {
        let e = m::exp(-a / g);
        let (g2, g3) = (g * g, g * g * g);
        return e / g + 0.5 * g * e * (2.0 / g3 - 4.0 * a / (g3 * g) + a * a / (g3 * g2));
    }
    let t = &SERIES;
    // ln of the ratio t_{k+1}/t_k (falling in k), and the log-term without its −g.
    let dy = |k: usize| lg + t.ln[k] - 2.0 * t.ln[k + 1] + a * t.inv[k] * t.inv[k + 1];
    let y = |k: usize, kf: f64| kf * lg - t.ln_fact_m[k] - a * t.inv[k];
    let Some(peak) = first_fall(dy, (g as usize).clamp(1, TABLE_LEN)) else {
        return htsg_sum_ratio(g, a);
    };
    let yp = y(peak, peak as f64);
    let mut acc = [0.0f64; BLOCK];
    // Upward from the peak, BLOCK terms at a time.
    let mut k = peak;
    loop {
        if k + BLOCK > TABLE_LEN + 2 {
            return htsg_sum_ratio(g, a);
        }
        let (mut d, kf) = ([0.0; BLOCK], k as f64);
        for (j, dj) in d.iter_mut().enumerate() {
            *dj = y(k + j, kf + j as f64) - yp;
        }
        for (s, dj) in acc.iter_mut().zip(d) {
            *s += m::exp_nonpositive_short(dj);
        }
        if d[BLOCK - 1] < LN_REL_STOP {
            break;
        }
        k += BLOCK;
    }
    // Downward from just below it, to m = 1 at the most (absent terms count −∞).
    let mut k = peak;
    while k > 1 {
        let (mut d, kf) = ([f64::NEG_INFINITY; BLOCK], k as f64);
        for (j, dj) in d.iter_mut().enumerate() {
            if k > j + 1 {
                *dj = y(k - 1 - j, kf - 1.0 - j as f64) - yp;
            }
        }
        for (s, dj) in acc.iter_mut().zip(d) {
            *s += m::exp_nonpositive_short(dj);
        }
        if k <= BLOCK + 1 || d[BLOCK - 1] < LN_REL_STOP {
            break;
        }
        k -= BLOCK;
    }
    // yp − g ≤ 0 (every term is at most 1; rounding may put it an ulp above, which
    // `exp_nonpositive` takes as it should). Below −708 it gives e^−708: a sum below 10⁻³⁰⁷,
    // which no f32 result can tell from 0.
    m::exp_nonpositive(yp - g) * acc.iter().sum::<f64>()
}

/// The first k ≥ 1 (at most [`TABLE_LEN`]) with `dy(k) < 0`, for a `dy` that falls with k:
/// galloping from `guess` in steps that double, then bisection. `None` when there is none.
fn first_fall(dy: impl Fn(usize) -> f64, guess: usize) -> Option<usize> {
    // Bisection of (lo, hi] with dy(lo) ≥ 0 > dy(hi).
    let bisect = |mut lo: usize, mut hi: usize| {
        while hi - lo > 1 {
            let mid = lo + (hi - lo) / 2;
            if dy(mid) >= 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi
    };
    let mut step = 1;
    if dy(guess) < 0.0 {
        let mut hi = guess;
        loop {
            if hi == 1 {
                return Some(1);
            }
            let lo = hi.saturating_sub(step).max(1);
            if dy(lo) >= 0.0 {
                return Some(bisect(lo, hi));
            }
            hi = lo;
            step *= 2;
        }
    }
    let mut lo = guess;
    loop {
        if lo == TABLE_LEN {
            return None;
        }
        let hi = (lo + step).min(TABLE_LEN);
        if dy(hi) < 0.0 {
            return Some(bisect(lo, hi));
        }
        lo = hi;
        step *= 2;
    }
}

/// The same sum by the ratio of consecutive terms from where the Poisson weights become
/// non-negligible (g − 10√g − 10), r_k = t_{k+1}/t_k = g·k/(k+1)² · e^{A/(k(k+1))}: one
/// exponential a term, in linear space with a running scale. r_k falls with k, so once
/// r_k < 1 the rest of the series is at most t_{k+1}/(1 − r_k): the loop stops when that
/// bound is below 1e-16 of the sum. Slower than [`htsg_sum`] (which uses it only when the
/// terms' peak lies beyond its tables), and needs no tables.
fn htsg_sum_ratio(g: f64, a: f64) -> f64 {
    // Terms are kept as t·e^{ln_scale}; the scale moves to the current term whenever a step
    // would take t above e^RESCALE_LN (a large A can put the mode e^{thousands} above the
    // start, and a single ratio beyond f64's range).
    const RESCALE_LN: f64 = 345.387_763_949_107; // ln(1e150)
    let mut k = m::floor(g - 10.0 * m::sqrt(g) - 10.0).max(1.0);
    let mut ln_scale = k * m::ln(g) - g - ln_gamma(k + 1.0) - m::ln(k) - a / k;
    let (mut t, mut sum) = (1.0f64, 0.0f64);
    // Below e^−200 in absolute terms a tail no longer matters: D carries a prefactor of at
    // most π²τ²/(4λ²) ≈ 6.2e5 and f is reported in f32 (smallest subnormal e^−103.4).
    let mut abs_tol = m::exp(LN_ABS_TOL - ln_scale);
    for _ in 0..100_000 {
        sum += t;
        let base = g * k / ((k + 1.0) * (k + 1.0));
        let e = a / (k * (k + 1.0));
        let r = base * m::exp(e.min(700.0));
        k += 1.0;
        if e >= 700.0 || t * r > 1e150 {
            // Move the scale onto the next term: ln t_next = ln_scale + ln t + ln r.
            let shift = m::ln(t) + m::ln(base) + e;
            sum *= m::exp(-shift);
            ln_scale += shift;
            t = 1.0;
            abs_tol = m::exp((LN_ABS_TOL - ln_scale).min(RESCALE_LN));
            continue;
        }
        t *= r;
        if r < 1.0 && t <= (1.0 - r) * (1e-16 * sum).max(abs_tol) {
            break;
        }
        if t <= 0.0 {
            break;
        }
    }
    m::exp(ln_scale + m::ln(sum))
}

/// The plain series (the former implementation, log space, two logarithms and an
/// exponential a term), kept to check [`htsg_sum`] against in tests.
#[cfg(test)]
fn htsg_sum_log_space(g: f64, a: f64) -> f64 {
    let ln_g = m::ln(g);
    let start = m::floor(g - 10.0 * m::sqrt(g) - 10.0).max(1.0);
    let mut k = start;
    let mut ln_pois = k * ln_g - g - ln_gamma(k + 1.0);
    let mut ln_max = f64::NEG_INFINITY;
    let mut sum = 0.0;
    for _ in 0..100_000 {
        let ln_k = m::ln(k);
        let lt = ln_pois - ln_k - a / k;
        if lt > ln_max {
            sum = sum * m::exp(ln_max - lt) + 1.0;
            ln_max = lt;
        } else {
            sum += m::exp(lt - ln_max);
        }
        ln_pois += ln_g - m::ln(k + 1.0);
        k += 1.0;
        if k > g + 1.0 {
            let ln_tail = ln_pois - m::ln(1.0 - g / (k + 1.0));
            let ln_total = ln_max + m::ln(sum);
            if ln_tail < ln_total + LN_REL_TOL {
                break;
            }
        }
    }
    m::exp(ln_max) * sum
}

impl Brdf for Htsg {
    fn name(&self) -> &'static str {
        "htsg"
    }

    fn symmetry(&self) -> Symmetry {
        Symmetry::ISOTROPIC_RECIPROCAL
    }

    fn params(&self) -> ParamSet {
        ParamSet::from_checked(
            self.name(),
            Self::PARAMS,
            &[
                ParamValue::Scalar(self.sigma0),
                ParamValue::Scalar(self.tau),
                ParamValue::Rgb(self.lambda),
                ParamValue::Rgb(self.eta),
                ParamValue::Rgb(self.kappa),
                ParamValue::Rgb(self.a),
            ],
        )
    }

    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let Some((wi, wo)) = upper_pair(wi, wo) else {
            return Vec3::ZERO;
        };
        let (geo, s) = self.geometry(wi, wo);
        let c = wi.dot(wo);
        let gf = (2.0 + 2.0 * c) / geo.vz;
        let g = gf * gf;
        let common = g * s * FRAC_1_PI / (wi.z * wo.z);
        let d = self.distribution(&geo);
        let f = self.fresnel(m::sqrt((0.5 * (1.0 + c)).max(0.0)));
        (f * d * common + self.a.as_dvec3() * FRAC_1_PI).as_vec3()
    }

    fn delta_reflectance(&self, wi: Vec3) -> Vec3 {
        if !above_horizon(wi) {
            return Vec3::ZERO;
        }
        self.specular(wi.as_dvec3().normalize()).as_vec3()
    }

    /// F(cos θi)·S(θi)²·(1 − e^{−gs}) + a: the energy the specular delta loses to roughness
    /// goes, to first order, to the directional-diffuse lobe.
    fn continuous_albedo_hint(&self, wi: Vec3) -> f32 {
        if !above_horizon(wi) {
            return 0.0;
        }
        let wi = wi.as_dvec3().normalize();
        let s = self.shadowing(wi);
        let total = self.fresnel(wi.z) * (s * s);
        luminance((total - self.specular(wi)).max(DVec3::ZERO).as_vec3()) + luminance(self.a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn alu(sigma0: f32, tau: f32) -> Htsg {
        Htsg::new(
            sigma0,
            tau,
            Vec3::splat(0.526),
            Vec3::splat(0.88045),
            Vec3::splat(6.1455),
            Vec3::ZERO,
        )
        .unwrap()
    }

    fn dir(theta_deg: f64, phi_deg: f64) -> Vec3 {
        let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
        DVec3::new(m::sin(t) * m::cos(p), m::sin(t) * m::sin(p), m::cos(t)).as_vec3()
    }

    fn close(got: f32, want: f64, rel: f64) -> bool {
        (f64::from(got) - want).abs() <= rel * want
    }

    /// f(θi, θo, Δφ) and ρs(θ) of the green channel against MODELS.md to 1e-4.
    fn check(b: &Htsg, f: &[(f64, f64, f64, f64)], rho: &[(f64, f64)], label: &str) {
        for &(ti, to, dp, want) in f {
            let got = b.eval(dir(ti, 0.0), dir(to, dp)).y;
            assert!(
                close(got, want, 1e-4),
                "{label} f({ti},{to},{dp}) = {got}, want {want}"
            );
        }
        for &(t, want) in rho {
            let got = b.delta_reflectance(dir(t, 0.0)).y;
            assert!(
                close(got, want, 1e-4),
                "{label} rho_s({t}) = {got}, want {want}"
            );
        }
    }

    /// Both ways of summing agree with the plain log-space series over g ∈ (0, 300] and A
    /// from 0 to far beyond the Poisson mode (where the sum underflows): the tabled
    /// peak-outward sum to 1e-10 on a 130 × 130 grid (it stops at 10⁻¹⁰ of its largest term
    /// and its exponential is good to 1.3e-12; measured worst 8.5e-12), and the ratio recurrence (now the
    /// fallback past the tables) to 1e-12 on the grid it was checked on before.
    #[test]
    fn the_fast_sums_are_the_series() {
        const GS: [f64; 9] = [1.0, 2.5, 7.0, 18.5, 40.0, 99.0, 150.0, 299.9, 300.0];
        const AS: [f64; 10] = [0.0, 1e-3, 0.5, 3.0, 20.0, 150.0, 1e3, 1e4, 1e5, 3e6];
        let gs = (0..=120).map(|i| 1e-6 * 10f64.powf(f64::from(i) * 8.477 / 120.0));
        for g in gs.chain(GS) {
            let r#as = (0..=120).map(|j| 1e-4 * 10f64.powf(f64::from(j) * 10.5 / 120.0));
            for a in r#as.chain(AS) {
                let (got, want) = (htsg_sum(g, a), htsg_sum_log_space(g, a));
                // Below e^−200 (1.4e-87) nothing matters (see LN_ABS_TOL).
                if want < 1e-80 {
                    assert!(got < 1e-80, "g {g} A {a}: {got} vs {want}");
                    continue;
                }
                let rel = (got - want).abs() / want;
                assert!(rel < 1e-10, "g {g} A {a}: {got} vs {want} ({rel:e})");
            }
        }
        for g in [1e-6, 0.01, 0.3].into_iter().chain(GS) {
            for a in AS {
                let (got, want) = (htsg_sum_ratio(g, a), htsg_sum_log_space(g, a));
                // The ratio recurrence stops early below e^−200.
                if want < 1e-80 {
                    assert!(got < 1e-80, "ratio: g {g} A {a}: {got} vs {want}");
                    continue;
                }
                let rel = (got - want).abs() / want;
                assert!(rel < 1e-12, "ratio: g {g} A {a}: {got} vs {want} ({rel:e})");
            }
        }
    }

    /// The compile-time tables against the run-time logarithm and ln Γ.
    #[test]
    fn series_tables_are_the_logarithms() {
        for k in 1..TABLE_LEN + 2 {
            let x = k as f64;
            assert!(
                (SERIES.ln[k] - x.ln()).abs() <= 2.0 * f64::EPSILON * x.ln(),
                "ln {k}"
            );
            let want = ln_gamma(x + 1.0) + x.ln();
            let got = SERIES.ln_fact_m[k];
            assert!(
                (got - want).abs() <= 1e-14 * want.max(1.0),
                "ln {k}! + ln {k}: {got} vs {want}"
            );
            assert_eq!(SERIES.inv[k], 1.0 / x);
        }
    }

    #[test]
    fn oracles_of_models_md() {
        check(
            &alu(0.18, 3.0),
            &[
                (30.0, 30.0, 180.0, 7.3129),
                (30.0, 40.0, 180.0, 4.5318),
                (10.0, 20.0, 0.0, 0.050_643),
            ],
            &[(60.0, 0.008_841), (80.0, 0.475_99)],
            "rough",
        );
        check(
            &alu(0.0318, 0.3),
            &[
                (30.0, 30.0, 180.0, 0.293_62),
                (45.0, 45.0, 135.0, 0.116_35),
                (60.0, 30.0, 90.0, 0.027_011),
            ],
            &[(0.0, 0.513_61), (30.0, 0.592_88), (60.0, 0.779_06)],
            "smooth",
        );
    }
}
