//! The statistics of a test: Pearson's χ² with pooling, its p-value through the regularised
//! upper incomplete gamma function, Šidák's per-test significance, and the seed's a_i spread.

use brdf_core::math as m;

/// The regularised upper incomplete gamma function Q(a, x) = Γ(a, x)/Γ(a), a > 0, x ≥ 0,
/// from `statrs` (series below x = a, continued fraction above; within 2·10⁻¹¹ relative of
/// 40-digit values for a ≤ 10⁴ down to Q ~ 10⁻²⁵⁰, and exactly 0 below e⁻⁷⁰⁹). Q(a, 0) = 1,
/// Q(a, ∞) = 0; NaN for invalid arguments (never a panic).
#[must_use]
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if a.is_nan() || x.is_nan() || a <= 0.0 || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return 1.0;
    }
    if x == f64::INFINITY {
        return 0.0;
    }
    statrs::function::gamma::checked_gamma_ur(a, x).unwrap_or(f64::NAN)
}

/// The per-test significance that keeps the family-wise rate of `tests` independent tests at
/// `alpha` (Šidák): 1 − (1 − α)^(1/k).
#[must_use]
pub fn sidak(alpha: f64, tests: usize) -> f64 {
    1.0 - m::exp(m::ln_1p(-alpha) / tests.max(1) as f64)
}

/// A Pearson χ² goodness-of-fit result.
#[derive(Clone, Debug, PartialEq)]
pub struct ChiSquare {
    /// The statistic Σ (O − E)²/E over the bins after pooling.
    pub statistic: f64,
    /// Degrees of freedom: bins − 1.
    pub dof: usize,
    /// P(χ²_dof ≥ statistic): Q(dof/2, statistic/2).
    pub p_value: f64,
    /// Bins after pooling (cells expected below 5 are merged, smallest first).
    pub bins: usize,
}

/// How far the cells' probabilities under a sampler's own pdf may fall short of what they
/// should sum to before [`chi_square_with_lost`] counts the shortfall against the sampler:
/// the error of those probabilities themselves (each cell's integral has its tolerance, and a
/// warp's piecewise-constant pdf with thousands of leaf edges has left 1.4·10⁻⁴ over a
/// 25 × 25 grid), and a quadtree's volume, exact only to its leaf integrals (10⁻⁴ on
/// Poulin–Fournier at 88°). The same as the tolerance of a pdf above 1
/// ([`crate::Reason::PdfAboveOne`]).
pub const NORMALISATION_TOLERANCE: f64 = 1e-3;

/// Pearson's χ² against a sampler's own pdf: `observed` counts per cell and `lost` samples
/// (no direction, or none in a cell) out of `samples` drawn, against `samples` × each cell's
/// `probability` under that pdf, the lost bin expecting what the cells leave of 1 (their
/// sum is at most 1; [`crate::Validation::own_probability`] gives them), known to within
/// [`NORMALISATION_TOLERANCE`]: the lost bin expects the count in that range nearest
/// `lost`. (Without it, a pdf that integrates to 1 − 10⁻⁴ from rounding alone, of a sampler
/// that loses nothing, expects 100 of 10⁶ samples lost and is rejected; a sampler that loses
/// 2 % with a pdf that says so still expects them, and a pdf 0.5 % short is still
/// rejected.) Pooled as [`chi_square`].
#[must_use]
pub fn chi_square_with_lost(
    observed: &[u64],
    lost: u64,
    samples: u64,
    probability: &[f64],
) -> Option<ChiSquare> {
    let m = samples as f64;
    let mut expected: Vec<f64> = probability.iter().map(|x| m * x).collect();
    let short = (1.0 - probability.iter().sum::<f64>()).max(0.0);
    let least = (short - NORMALISATION_TOLERANCE).max(0.0);
    expected.push((lost as f64).clamp(m * least, m * short));
    let mut observed = observed.to_vec();
    observed.push(lost);
    chi_square(&observed, &expected)
}

/// Pearson's χ² of `observed` counts against `expected` counts (same length), pooling
/// cells whose expected count is below 5 (in increasing order of expectation, until each pool
/// reaches 5; a last short pool joins the previous bin). `None` when fewer than two bins
/// remain (no degree of freedom).
#[must_use]
pub fn chi_square(observed: &[u64], expected: &[f64]) -> Option<ChiSquare> {
    let mut order: Vec<usize> = (0..expected.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]).then(a.cmp(&b)));
    let mut bins: Vec<(f64, f64)> = Vec::new();
    let (mut pe, mut po) = (0.0, 0.0);
    for k in order {
        let (e, o) = (expected[k], observed[k] as f64);
        if e >= 5.0 && pe == 0.0 {
            bins.push((o, e));
            continue;
        }
        pe += e;
        po += o;
        if pe >= 5.0 {
            bins.push((po, pe));
            (pe, po) = (0.0, 0.0);
        }
    }
    if pe > 0.0 || po > 0.0 {
        match bins.last_mut() {
            Some(last) => {
                last.0 += po;
                last.1 += pe;
            }
            None => bins.push((po, pe)),
        }
    }
    if bins.len() < 2 {
        return None;
    }
    let statistic: f64 = bins.iter().map(|&(o, e)| (o - e) * (o - e) / e).sum();
    let dof = bins.len() - 1;
    Some(ChiSquare {
        statistic,
        dof,
        p_value: gamma_q(0.5 * dof as f64, 0.5 * statistic),
        bins: bins.len(),
    })
}

/// The seed's §4 statistic: a_i = (n_i/m)/I_i over the cells expected to receive at least
/// [`Spread::MIN_EXPECTED`] samples, relative to the constant a = 1/Σ I.
#[derive(Clone, Debug, PartialEq)]
pub struct Spread {
    /// a = 1/Σ I_i (I_i = ∫ over cell i of the luminance of f_r, per disk area).
    pub a: f64,
    /// Cells counted.
    pub cells: usize,
    /// min over the counted cells of a_i/a.
    pub min: f64,
    /// max of a_i/a.
    pub max: f64,
    /// Root mean square of a_i/a − 1.
    pub rms: f64,
    /// The RMS that counting noise alone gives, √(mean of 1/E_i) over the counted cells:
    /// an exact sampler has `rms` ≈ `noise`.
    pub noise: f64,
}

impl Spread {
    /// Cells expected to receive fewer samples than this are left out of the spread (their
    /// a_i is noise: the relative standard deviation of a count of 100 is 10 %).
    pub const MIN_EXPECTED: f64 = 100.0;
}

/// The seed's a_i spread of `observed` counts over cells of integral `mass` (I_i), with
/// `expected` = m·I_i/Σ I and m samples.
pub(crate) fn spread(observed: &[u64], mass: &[f64], expected: &[f64], m: f64) -> Option<Spread> {
    let total: f64 = mass.iter().sum();
    let a = 1.0 / total;
    let ratios: Vec<(f64, f64)> = observed
        .iter()
        .zip(mass)
        .zip(expected)
        .filter(|&(_, &e)| e >= Spread::MIN_EXPECTED)
        .map(|((&o, &i), &e)| ((o as f64 / m) / i / a, e))
        .collect();
    if ratios.is_empty() {
        return None;
    }
    let (mut min, mut max, mut ss, mut inv) = (f64::INFINITY, f64::NEG_INFINITY, 0.0, 0.0);
    for &(r, e) in &ratios {
        min = min.min(r);
        max = max.max(r);
        ss += (r - 1.0) * (r - 1.0);
        inv += 1.0 / e;
    }
    let k = ratios.len() as f64;
    Some(Spread {
        a,
        cells: ratios.len(),
        min,
        max,
        rms: m::sqrt(ss / k),
        noise: m::sqrt(inv / k),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_q_matches_published_values() {
        // Q(1, x) = e^{-x}; Q(1/2, x) = erfc(√x).
        for x in [0.1, 1.0, 5.0, 30.0] {
            assert!((gamma_q(1.0, x) - m::exp(-x)).abs() < 1e-15 * 10.0);
            let e = brdf_core::special::erfc(m::sqrt(x));
            assert!((gamma_q(0.5, x) - e).abs() <= 1e-13 * e);
        }
        // χ² critical values at α = 0.05 (Abramowitz & Stegun table 26.8; NIST handbook).
        for (dof, crit) in [
            (1.0, 3.841_459),
            (10.0, 18.307_04),
            (100.0, 124.342_1),
            (1000.0, 1_074.679),
        ] {
            let p = gamma_q(0.5 * dof, 0.5 * crit);
            assert!((p - 0.05).abs() < 2e-6, "dof {dof}: p = {p}");
        }
        // The χ² tests' range (a = dof/2 up to ~10⁴, x near a, deep tails): 40-digit values
        // (mpmath's gammainc, regularized).
        for (a, x, q) in [
            (265.5, 278.775, 0.205_570_323_437_821_6),
            (1000.0, 1050.0, 0.058_671_111_377_318_08),
            (2500.0, 2750.0, 6.203_019_945_328_596e-7),
            (8192.0, 8601.6, 4.178_021_004_034_395e-6),
            (6322.5, 7879.25, 4.224_462_903_644_894e-74),
        ] {
            let got = gamma_q(a, x);
            assert!(
                (got - q).abs() <= 2e-11 * q,
                "Q({a}, {x}) = {got}, want {q}"
            );
        }
        assert_eq!(gamma_q(637.0, 400.0), 1.0);
        assert!(gamma_q(-1.0, 1.0).is_nan());
        assert!(gamma_q(1.0, f64::NAN).is_nan());
        assert!(gamma_q(f64::INFINITY, 1.0).is_nan());
        assert_eq!(gamma_q(2.0, 0.0), 1.0);
        assert_eq!(gamma_q(2.0, f64::INFINITY), 0.0);
    }

    #[test]
    fn sidak_correction() {
        assert!((sidak(0.01, 1) - 0.01).abs() < 1e-15);
        let a = sidak(0.01, 100);
        assert!((1.0 - m::pow(1.0 - a, 100.0) - 0.01).abs() < 1e-12);
    }

    #[test]
    fn pooling_and_dof() {
        let expected = [100.0, 100.0, 2.0, 2.0, 2.0, 0.5];
        let observed = [95, 105, 3, 1, 2, 1];
        let c = chi_square(&observed, &expected).unwrap();
        // bins: pool {0.5, 2, 2, 2} = 6.5 vs 7 observed, and the two big cells.
        assert_eq!(c.bins, 3);
        assert_eq!(c.dof, 2);
        let want = 0.25 + 0.25 + (7.0 - 6.5) * (7.0 - 6.5) / 6.5;
        assert!((c.statistic - want).abs() < 1e-12);
        assert!(chi_square(&[1, 2], &[1.0, 2.0]).is_none());
    }

    /// The lost bin forgives a pdf at most [`NORMALISATION_TOLERANCE`] short of 1, and
    /// nothing more; a sampler that loses what its pdf says passes.
    #[test]
    fn the_lost_bin_knows_the_normalisation_to_its_tolerance() {
        // 10 cells; counts exactly at their expectation under `p`, `lost` lost.
        let run = |p: f64, drawn: f64, lost: u64| {
            let probability = vec![p / 10.0; 10];
            let observed = vec![(1e6 * drawn / 10.0).round() as u64; 10];
            chi_square_with_lost(&observed, lost, 1_000_000, &probability)
                .unwrap()
                .p_value
        };
        // A pdf 10⁻⁴ short, of a sampler that loses nothing: passes (before, the lost bin
        // expected 100 and χ² was 100 on 10 dof, p = 10⁻¹⁶).
        assert!(run(1.0 - 1e-4, 1.0, 0) > 0.5);
        // 0.5 % short, nothing lost: 5 000 of the lost bin's expected 4 000 or more missing.
        assert!(run(0.995, 1.0, 0) < 1e-100);
        // 2 % lost, and the pdf says so.
        assert!(run(0.98, 0.98, 20_000) > 0.5);
        // 2 % lost, a pdf that says nothing is: rejected.
        assert!(run(1.0, 0.98, 20_000) < 1e-100);
    }
}
