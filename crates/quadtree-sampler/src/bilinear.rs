//! The warp's proxy inside one leaf: flat, or a [`Shape`] through f at the leaf's control
//! points (SPEC §4: "sampling a proxy (piecewise-constant or bilinear) inside the leaf").
//!
//! A leaf's share of the volume is fixed by the tree (its v1 over the tree's volume); the
//! proxy only says how that share is spread over the leaf's square. Flat spreads it
//! uniformly: under a glossy lobe, where a leaf the seed's rule (P ≥ ½) accepts still holds
//! f varying by 2× across, the weight f·cos/pdf varies by as much: the per-wi warp's
//! variance under the benches' sky (at 45°, defensive share 10⁻⁶) was 250× the rejection
//! sampler's for phong n = 1000, 8× for Cook–Torrance m = 0.1 and 42× for Ward α = 0.05. A
//! fine [`Shape`] (bilinear in each quarter of the leaf, through f at the 3 × 3 points
//! t = (i/2, j/2)) follows such a slope, and a peak inside the leaf too: 23×, 1.2× and
//! 2.5× with them.
//!
//! Each leaf chooses ([`fit_leaf`], at build time): the shape where it predicts f better
//! than flat at the 4 × 4 midpoints of the leaf (the second moment of the weight there, both
//! proxies carrying the leaf's share) by [`MIN_GAIN`], flat otherwise. Levels are kept at
//! least [`FLOOR_LEVEL`] of 63, so that even a poor fit bounds the weight f·cos/pdf to a
//! small multiple of the flat proxy's. The warp inside the leaf is [`Shape::warp`], a
//! deterministic, monotone map of the leaf's uniforms (stratified points stay stratified),
//! undone by [`Shape::invert`]; its density S/mean(S) is exact for the stored levels,
//! whatever they are.
//!
//! On the orthographic disk a baked warp's sectors and rim leaves may instead spread their
//! shares in a solid-angle chart (`rim`), with the shape fitted over that chart's unit
//! square ([`fit_sector`], [`fit_rim_leaf`]); each leaf keeps whichever of the two scores
//! better at the test points ([`choose_chart`]).

use crate::chart::Rect;
use crate::proposal::Shape;
use crate::rim::{RimChart, SectorChart};
use brdf_core::DiskMap;
use brdf_core::geometry::lift_to_grazing_floor;
use glam::{DVec2, DVec3};

/// The least level of a warp shape (of 63): 4, so the proxy is nowhere below 1/16 of its
/// highest point.
pub(crate) const FLOOR_LEVEL: u8 = 4;

/// The least relative gain (in the second moment of the weight at the test points) for a
/// leaf to take a shape: below it the flat proxy's cheaper warp is kept.
pub(crate) const MIN_GAIN: f64 = 0.02;

/// Control point `k` (index 3j + i) of a shape's grid in its unit square: t = (i/2, j/2).
#[inline]
fn control_point(k: usize) -> DVec2 {
    DVec2::new((k % 3) as f64 * 0.5, (k / 3) as f64 * 0.5)
}

/// Test point `k` of a fit: the midpoints of a 4 × 4 grid over the unit square.
#[inline]
fn test_point(k: usize) -> DVec2 {
    DVec2::new(((k % 4) as f64 + 0.5) / 4.0, ((k / 4) as f64 + 0.5) / 4.0)
}

/// A leaf's proxy density per unit square area at square point `p`: its mean `density`
/// times its shape at p's place in its (dyadic) square `rect` — the one expression the
/// per-wi warp, the baked warp's look-up and the leaf a sample was drawn in share.
#[inline(always)]
pub(crate) fn leaf_density(density: f64, shape: &Shape, rect: &Rect, p: DVec2) -> f64 {
    if shape.is_flat() {
        density
    } else {
        density * shape.density((p - rect.min) * rect.inverse_side())
    }
}

/// The shape a leaf's proxy should take ([`Shape::FLAT`] or a fine one), from `f`, the
/// tree's integrand at a direction (the luminance of f_r for the tree's incident
/// direction), over `map`. A control point outside the orthographic disk takes f at the rim
/// point toward it (what the shape continues there is lost with the square's corners, as
/// the flat proxy's is); a test point outside it does not count.
pub(crate) fn fit_leaf(map: DiskMap, rect: &Rect, f: impl Fn(DVec3) -> f64) -> Shape {
    fit_leaf_scored(map, rect, f).0
}

/// [`fit_leaf`], with the choice's score: Σ g²/S over the test points, g = f times the
/// square's area, which is (up to a factor every candidate proxy of the leaf shares) the
/// weight's second moment ∫T²/q dω under this proxy — what [`choose_chart`] compares.
pub(crate) fn fit_leaf_scored(map: DiskMap, rect: &Rect, f: impl Fn(DVec3) -> f64) -> (Shape, f64) {
    let side = rect.max - rect.min;
    let at = |t: DVec2| rect.min + side * t;
    let control: [f64; 9] = core::array::from_fn(|k| {
        let p = at(control_point(k));
        match map.square_to_direction_f64(p) {
            Some(w) => f(w),
            None => {
                let r = p.length();
                f(lift_to_grazing_floor(DVec3::new(p.x / r, p.y / r, 0.0)))
            }
        }
    });
    let tests: [Option<(DVec2, f64)>; 16] = core::array::from_fn(|k| {
        let t = test_point(k);
        map.square_to_direction_f64(at(t)).map(|w| (t, f(w)))
    });
    let area = side.x * side.y;
    let (shape, score) = fit_scored(control, &tests);
    (shape, score * area * area)
}

/// [`fit_leaf`] for a leaf that spreads its share in its rim chart ([`crate::rim`]): the
/// shape over the chart's unit square that follows f·cos θ times the chart's measure at each
/// point (what is left of f·cos θ over the chart's own density). A point on the rim takes
/// f at the grazing floor there; one at an end of the chart's x-range, where the leaf's
/// t-range closes, takes 0.
pub(crate) fn fit_rim_leaf(chart: &RimChart, f: impl Fn(DVec3) -> f64) -> (Shape, f64) {
    let value = |u: DVec2| {
        let p = chart.point(u);
        let (_, measure) = chart.unit(p)?;
        let r2 = p.length_squared();
        let w = if r2 < 1.0 {
            DVec3::new(p.x, p.y, brdf_core::math::sqrt(1.0 - r2))
        } else {
            let r = brdf_core::math::sqrt(r2);
            DVec3::new(p.x / r, p.y / r, 0.0)
        };
        let w = lift_to_grazing_floor(w);
        Some(f(w) * w.z * measure)
    };
    let control: [f64; 9] = core::array::from_fn(|k| value(control_point(k)).unwrap_or(0.0));
    let tests: [Option<(DVec2, f64)>; 16] = core::array::from_fn(|k| {
        let t = test_point(k);
        value(t).map(|v| (t, v))
    });
    fit_scored(control, &tests)
}

/// A disk sector's proxy: its shape in its solid-angle chart ([`SectorChart`], uniform in
/// solid angle), fitted to f·cos θ, where that scores better ([`choose_chart`]) than the
/// sector's spread over its area (flat in (r², φ), as up to version 8); `None` where the
/// area spread stays. A point on the rim takes f at the grazing floor there.
///
/// Both scores come from the same f at the chart's test points (uniform in z), in one
/// normalisation: the area spread's density per unit solid angle is ∝ z where the chart's is
/// ∝ S, and ∫T²/q dω becomes Σ ½·(f·span)²·z against Σ (f·z·span)²/S. There a weight that
/// grows toward the rim shows in the area spread's score; at its own points (uniform in r²,
/// none beyond z = 0.35) it would not (Cook–Torrance m = 1 at θi = 89° kept its area spread
/// and R 10.6, against 2.2 in the chart). Where f·cos θ falls like cos θ toward the rim
/// (Lambert) the area spread is exact and stays.
pub(crate) fn fit_sector(chart: &SectorChart, f: impl Fn(DVec3) -> f64) -> Option<Shape> {
    let span = chart.span();
    let at = |u: DVec2| {
        let p = chart.point(u);
        lift_to_grazing_floor(DVec3::new(p.x, p.y, u.x.max(0.0)))
    };
    let control: [f64; 9] = core::array::from_fn(|k| {
        let w = at(control_point(k));
        f(w) * w.z * span
    });
    let mut area = 0.0;
    let tests: [Option<(DVec2, f64)>; 16] = core::array::from_fn(|k| {
        let t = test_point(k);
        let w = at(t);
        let fw = f(w);
        let g = fw * span;
        area += 0.5 * g * g * t.x;
        Some((t, fw * w.z * span))
    });
    let (shape, score) = fit_scored(control, &tests);
    choose_chart(area, score).then_some(shape)
}

/// Of two proxies for one leaf, with their scores, whether the second (the solid-angle
/// chart, [`crate::rim`]) is taken: where it lowers the score by [`MIN_GAIN`] or more.
pub(crate) fn choose_chart(old: f64, chart: f64) -> bool {
    old.is_finite() && chart.is_finite() && chart < (1.0 - MIN_GAIN) * old
}

#[cfg(test)]
/// [`fit_leaf`]'s choice from f at the control points (index 3j + i at t = (i/2, j/2)) and
/// at test points (t, f; `None`: a point that does not count).
pub(crate) fn fit(control: [f64; 9], tests: &[Option<(DVec2, f64)>]) -> Shape {
    fit_scored(control, tests).0
}

/// [`fit`], with the chosen proxy's Σ f²/S over the test points (infinite where a value
/// is negative or not finite).
pub(crate) fn fit_scored(control: [f64; 9], tests: &[Option<(DVec2, f64)>]) -> (Shape, f64) {
    let ok = |x: f64| x.is_finite() && x >= 0.0;
    if !tests.iter().flatten().all(|&(_, x)| ok(x)) {
        return (Shape::FLAT, f64::INFINITY);
    }
    // Σ f²/q over the points for each proxy, both carrying the same share (a common
    // factor the comparison drops): the weight's second moment there.
    let flat: f64 = tests.iter().flatten().map(|&(_, f)| f * f).sum();
    if !control.iter().all(|&x| ok(x)) {
        return (Shape::FLAT, flat);
    }
    let high = control.iter().copied().fold(0.0, f64::max);
    if high <= 0.0 {
        return (Shape::FLAT, flat);
    }
    let levels = control.map(|v| (v / high * 63.0 + 0.5).clamp(f64::from(FLOOR_LEVEL), 63.0) as u8);
    let Some(shape) = Shape::from_grid(levels).filter(|s| !s.is_flat()) else {
        return (Shape::FLAT, flat);
    };
    let shaped: f64 = tests
        .iter()
        .flatten()
        .map(|&(t, f)| f * f / shape.density(t))
        .sum();
    if flat > 0.0 && shaped < (1.0 - MIN_GAIN) * flat {
        (shape, shaped)
    } else {
        (Shape::FLAT, flat)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tests_of(f: &dyn Fn(DVec2) -> f64) -> [Option<(DVec2, f64)>; 16] {
        core::array::from_fn(|k| {
            let t = test_point(k);
            Some((t, f(t)))
        })
    }

    fn control_of(f: &dyn Fn(DVec2) -> f64) -> [f64; 9] {
        core::array::from_fn(|k| f(control_point(k)))
    }

    #[test]
    fn a_leaf_takes_a_shape_only_where_it_predicts_f_better() {
        // f rising linearly in x from 1 to 3: the shape is f itself (to its levels).
        let lin = |t: DVec2| 1.0 + 2.0 * t.x;
        let s = fit(control_of(&lin), &tests_of(&lin));
        assert!(!s.is_flat());
        assert!((s.density(DVec2::new(1.0, 0.3)) - 1.5).abs() < 0.02);
        // A peak in the middle: the fine shape rises to it.
        let bump = |t: DVec2| 0.05 + (-(t - DVec2::splat(0.5)).length_squared() * 8.0).exp();
        let s = fit(control_of(&bump), &tests_of(&bump));
        assert!(s.density(DVec2::splat(0.5)) > 1.5, "{s:?}");
        // A constant: flat (no gain).
        let one = |_: DVec2| 2.0;
        assert!(fit(control_of(&one), &tests_of(&one)).is_flat());
        // A ridge along the diagonal that the control points miss: flat.
        let ridge = |t: DVec2| {
            let d = (t.x - t.y - 0.25).abs();
            if d < 0.05 { 10.0 } else { 0.1 }
        };
        let s = fit(control_of(&ridge), &tests_of(&ridge));
        assert!(s.is_flat(), "{s:?}");
        // Nothing usable: flat.
        assert!(fit([0.0; 9], &tests_of(&lin)).is_flat());
        let mut nan = control_of(&lin);
        nan[4] = f64::NAN;
        assert!(fit(nan, &tests_of(&lin)).is_flat());
        assert!(fit(control_of(&lin), &[None; 16]).is_flat());
        // The floor: a control value at 0 is stored at level FLOOR_LEVEL.
        let ramp = |t: DVec2| 3.0 * t.x;
        let s = fit(control_of(&ramp), &tests_of(&ramp));
        assert_eq!(s.grid().unwrap()[0], FLOOR_LEVEL);
    }
}
