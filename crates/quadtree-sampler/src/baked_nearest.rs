//! Where a baked sampler in rejection mode answers with one tree: the cells of its grid
//! whose corner trees agree, measured once per bake ([`measure`]).
//!
//! A query blends the trees around it (see `baked_mixture`), and its exact pdf costs one
//! density per blended tree: in rejection mode a model evaluation, for the sample and for
//! every `pdf`. The weights may be any function of wi (the mixture stays exact), so where the
//! nearest tree alone, rotated onto wi's mirror, samples wi's density as well as a blend
//! would, blending costs an evaluation and buys nothing. Whether it does is measured for
//! each pair of neighbouring trees a and b: how a (rotated onto b's mirror) samples b's exact
//! density T_b ∝ Y(f_r(wi_b, ·))·cos θ, which b's own tree samples exactly. Two numbers, and
//! a cell snaps to its nearer tree along θ (or φ) only where both stay small for every pair
//! on that axis, in both directions:
//!
//! - the χ² distance ∫ T_b²/q_a − 1, the excess of the weight's variance under uniform light
//!   (at most [`NEAREST_REJECTION_EXCESS`]), including the band along the horizon that a's
//!   tilted directions cannot reach, where q_a is the defensive share alone (integrated on
//!   its own: the stratified points below never come within 6° of the horizon, and a tail
//!   that reaches it, Schlick r = 0.01, snapped cells whose samples there weighed 10⁶ times
//!   their due);
//! - the largest ratio T_b/q_a where T_b is at least 10⁻⁶ of its peak (at most
//!   [`NEAREST_MAX_RATIO`]): under a small bright source (a sun) the variance is the
//!   source's share times that ratio at the source, so a neighbour whose lobe tails differ
//!   from b's costs variance there however small its χ². Measured on the default grid this is
//!   what decides: for ward α = 0.05 and cook-torrance m = 0.1 the ratio (where T_b is at
//!   least 10⁻³ of its peak) reaches 1.1 by θi ≈ 10° and 2 by 45° while χ² stays under 0.01,
//!   and snapping on χ² alone raised the variance of the benches' sky-and-sun estimate by up
//!   to 49 % at off-grid wi (ward, rejection). A mirror lobe, rotated exactly onto its
//!   neighbours, passes: phong n = 1000 and lewis-phong n = 1000 snap 25 of the default
//!   grid's 31 cells (to θi ≈ 72°), ward α = 0.05 and cook-torrance m = 0.1 two (next to the
//!   normal), diffuse parts none.
//!
//! Warp mode always blends: its proxies step at each tree's own leaf edges, so two
//! neighbours' proxies differ by their layouts (pointwise ratios of 2–13 anywhere on the
//! default grid, measured with flat leaves), and blending two of them smooths those steps
//! (off the grid, the blend's variance is below the single on-grid tree's).
//!
//! The χ² is ∫ (T − q)²/q + 1 − Q (Q: q's mass over the hemisphere, short of 1 where the
//! rotation carries part of a tree below the horizon), an integrand that vanishes where the
//! two densities agree: no cancellation between large terms. Both it and the ratio are taken
//! at fixed stratified points, half through b's warp and half cosine-distributed (the tails
//! a proxy rarely visits), each weighed by the mixture of the two densities; the lost mass
//! at a's own warp points. Fixed points keep the bake a pure function of its model and
//! configuration (serial and parallel bakes stay bit-identical).

use crate::bake_grid::{
    BakeGrid, Nearest, PhiDomain, isotropic_to_local, rotation_arc, rotation_between_mirrors_xz,
};
use crate::baked::Slice;
use crate::baked_mixture::HalfMap;
use alloc::vec::Vec;
use brdf_core::geometry::luminance;
use brdf_core::math as m;
use core::f64::consts::FRAC_1_PI;
use glam::{DMat3, DVec2, DVec3, Vec3};

/// Points per axis of each pair's two stratified sets (the target's proxy, the cosine):
/// 2 × 2 304 points, two model evaluations each. Against a converged quadrature (ward
/// α = 0.05, 16 rows) the χ² estimate is within 10 % at χ² ≈ 0.01–0.18 and about 25 % low at
/// χ² ≈ 0.4–2 (near grazing, where every pair blends anyway).
const POINTS_PER_AXIS: usize = 48;

/// The most χ² distance a pair may show over a whole grid step for its cells to snap:
/// 4 %, about 1 % at a snapped query half a step from its tree.
pub const NEAREST_REJECTION_EXCESS: f64 = 0.04;

/// The largest ratio T_b/q_a a pair may show over a whole grid step, where T_b is at least
/// 10⁻⁶ of its peak, for its cells to snap: 1.1 (the 10 % of variance, for light
/// from any one direction).
pub const NEAREST_MAX_RATIO: f64 = 1.1;

/// Where the ratio is watched: T at least this fraction of its largest value met.
const RATIO_FLOOR: f64 = 1e-6;

/// How tree `other`, carried to `target`'s frame by `to_target`, samples `target`'s exact
/// density (see the module doc): its χ² distance and its largest ratio T/q. Infinite where
/// either tree holds no volume (such a pair always blends).
fn agreement(
    target: &Slice,
    other: &Slice,
    to_target: &DMat3,
    half: bool,
    eval: &(dyn Fn(Vec3, Vec3) -> Vec3 + Sync),
    defensive: f64,
) -> (f64, f64) {
    if !(target.live && other.live) {
        return (f64::INFINITY, f64::INFINITY);
    }
    let back = to_target.transpose();
    // On an anisotropic grid, `other` reaches `target` by the half-vector transport the
    // mixture uses (`HalfMap`, both trees in the folded frame): `onto_target` carries one of
    // its directions there, `from_target` finds the direction a target one comes from and
    // the density's Jacobian factor.
    let incident = |s: &Slice| DVec3::new(-s.mirror.x, -s.mirror.y, s.mirror.z);
    let map = half.then(|| HalfMap {
        tree: incident(other),
        given: incident(target),
        unfold: DVec3::ONE,
    });
    let from_target = |w: DVec3| match &map {
        None => Some((back * w, 1.0)),
        Some(m) => m.back(w),
    };
    let onto_target = |w: DVec3| match &map {
        None => Some(*to_target * w),
        Some(m) => m.forward(w),
    };
    let n = POINTS_PER_AXIS;
    let density = |s: &Slice, w: DVec3| {
        f64::from(luminance(eval(s.wi, w.as_vec3()))) * w.z * s.rejection_scale
    };
    let keep = 1.0 - defensive;
    // Half the points follow the target's proxy, half the cosine: each weighs 1/(the
    // mixture's density), ½(W + cos θ/π).
    let proxy = |w: DVec3| {
        target
            .warp
            .density_flat(target.map.direction_to_square_f64(w))
            * target.warp_scale
            * w.z
    };
    let cosine = (0..n * n).filter_map(|k| {
        let u = glam::Vec2::new(
            ((k / n) as f32 + 0.5) / n as f32,
            ((k % n) as f32 + 0.5) / n as f32,
        );
        let w = unit(brdf_core::warp::sample_cosine_hemisphere(u))?;
        Some((w, proxy(w)))
    });
    let mut chi = 0.0;
    let mut seen: Vec<(f64, f64)> = Vec::with_capacity(2 * n * n);
    for (w, own) in warp_points(target, n).chain(cosine) {
        let mixture = 0.5 * (own + w.z * FRAC_1_PI);
        let t = density(target, w);
        let (reached, r) = match from_target(w) {
            Some((v, jacobian)) if v.z > 0.0 => (true, density(other, v) * jacobian),
            _ => (false, 0.0),
        };
        let q = defensive * w.z * FRAC_1_PI + keep * r;
        // The band `other` cannot reach is integrated below (these points rarely see it).
        if reached {
            chi += (t - q) * (t - q) / (q * mixture);
        }
        seen.push((t, t / q));
    }
    // The target's density in the band above the horizon that `other`'s directions cannot
    // reach (see `unreached_excess`).
    let reach = m::acos(target.mirror.dot(other.mirror).clamp(-1.0, 1.0));
    let unreached = unreached_excess(
        reach,
        |w| matches!(from_target(w), Some((v, _)) if v.z > 0.0),
        |w| density(target, w),
        defensive,
    );
    // The other tree's mass its map carries below the horizon.
    let lost: f64 = warp_points(other, n)
        .filter(|&(w, _)| onto_target(w).is_none_or(|v| v.z <= 0.0))
        .map(|(w, own)| density(other, w) / own)
        .sum();
    let count = (n * n) as f64;
    let chi = chi / (2.0 * count) + keep * lost / count + unreached;
    let peak = seen.iter().map(|x| x.0).fold(0.0, f64::max);
    let ratio = seen
        .iter()
        .filter(|x| x.0 >= RATIO_FLOOR * peak)
        .map(|x| x.1)
        .fold(0.0, f64::max);
    // NaN (a model returning one) counts as disagreement.
    let finite = |e: f64| if e.is_nan() { f64::INFINITY } else { e };
    (finite(chi), finite(ratio))
}

/// Columns in φ and rows in elevation of [`unreached_excess`]'s midpoint rule.
const BAND_COLUMNS: usize = 128;
const BAND_ROWS: usize = 8;

/// ∫ T²/q over the directions above the horizon that the other tree cannot reach, where q
/// is the defensive share δ·cos θ/π alone: (π/δ)·∫ T²/cos θ dω. A tree carried onto its
/// neighbour (rotated by the angle `reach` between their mirror directions, or by the
/// half-vector transport, which moves no direction by more than the angle between their
/// incident directions, the same angle) leaves a band along the horizon, at most `reach`
/// high, that its directions do not reach. Blended, the neighbour on the other side covers
/// it; snapped, nothing but δ does, and where f·cos θ is not negligible there (a tail
/// that reaches the horizon: Schlick r = 0.001 at θi ≈ 10°), a sample in the band weighs
/// 1/δ = 10⁶ times its due: R = 58–173 at the snapped queries of that material's default
/// grid, which the stratified points above, none within 6° of the horizon, did not see.
/// A midpoint rule over the band's elevations e ∈ (0, reach] and all φ, the model
/// evaluated only where `reached` says no.
fn unreached_excess(
    reach: f64,
    reached: impl Fn(DVec3) -> bool,
    target: impl Fn(DVec3) -> f64,
    defensive: f64,
) -> f64 {
    if reach.is_nan() || reach <= 0.0 {
        return 0.0;
    }
    let de = reach / BAND_ROWS as f64;
    let rows = (0..BAND_ROWS).map(|i| (de * (i as f64 + 0.5), de));
    let mut sum = 0.0;
    for (w, dw) in band_directions(rows, BAND_COLUMNS) {
        if reached(w) {
            continue;
        }
        let t = target(w);
        // cos θ = w.z.
        sum += t * t / w.z * dw;
    }
    let excess = core::f64::consts::PI / defensive * sum;
    if excess.is_nan() {
        f64::INFINITY
    } else {
        excess
    }
}

/// The midpoints of a rule over a band along the horizon: for each row (its elevation e
/// above the horizon and its width de, radians) and each of `columns` equal steps of φ, the
/// direction and the solid angle it stands for, cos e·de·dφ. What the snap measure's
/// unreached band and the coverage check's horizon band (`baked_coverage`) integrate over.
pub(crate) fn band_directions(
    rows: impl IntoIterator<Item = (f64, f64)>,
    columns: usize,
) -> impl Iterator<Item = (DVec3, f64)> {
    let dphi = core::f64::consts::TAU / columns as f64;
    rows.into_iter().flat_map(move |(e, de)| {
        let (se, ce) = m::sin_cos(e);
        (0..columns).map(move |j| {
            let (sp, cp) = m::sin_cos(dphi * (j as f64 + 0.5));
            (DVec3::new(ce * cp, ce * sp, se), ce * de * dphi)
        })
    })
}

/// The directions of `n` × `n` stratified points (cell centres of [0, 1)²) through a tree's
/// warp with flat leaves ([`crate::warp_table::WarpTable::warp_flat`]: the measurement is
/// the same whether or not the bake fits the warp's shapes), with that proxy's density there
/// per unit solid angle; a point whose warp leaves the
/// disk (part of a rim leaf's square) or finds no volume gives none.
fn warp_points(s: &Slice, n: usize) -> impl Iterator<Item = (DVec3, f64)> + '_ {
    (0..n * n).filter_map(move |k| {
        let u = DVec2::new(
            ((k / n) as f64 + 0.5) / n as f64,
            ((k % n) as f64 + 0.5) / n as f64,
        );
        let (p, leaf) = s.warp.warp_flat(u)?;
        let w = s.map.square_to_direction_f64(p)?;
        (w.z > 0.0).then_some((w, leaf.density * s.warp_scale * w.z))
    })
}

/// A unit f64 direction above the horizon from an f32 one, or `None`.
fn unit(w: Vec3) -> Option<DVec3> {
    let w = brdf_core::geometry::normalize_f64(w.as_dvec3());
    (w.z > 0.0).then_some(w)
}

/// Whether the pair (trees `a`, `b`) agrees in both directions.
fn pair_agrees(
    grid: &BakeGrid,
    slices: &[Slice],
    (a, b): (usize, usize),
    half: bool,
    eval: &(dyn Fn(Vec3, Vec3) -> Vec3 + Sync),
    defensive: f64,
) -> bool {
    let (sa, sb) = (&slices[a], &slices[b]);
    let onto = |from: &Slice, to: &Slice| {
        if grid.domain() == PhiDomain::Rotation {
            isotropic_to_local(
                (1.0, 0.0),
                rotation_between_mirrors_xz(from.wi.as_dvec3(), to.wi.as_dvec3()),
            )
        } else {
            rotation_arc(from.mirror, to.mirror)
        }
    };
    let ok =
        |(chi, ratio): (f64, f64)| chi <= NEAREST_REJECTION_EXCESS && ratio <= NEAREST_MAX_RATIO;
    ok(agreement(sb, sa, &onto(sa, sb), half, eval, defensive))
        && ok(agreement(sa, sb, &onto(sb, sa), half, eval, defensive))
}

/// The rejection mode's nearest-tree cells of a bake's trees `slices` on `grid` (`eval`: f of
/// the trees' model, forward or adjoint, as (tree's wi, direction)). Each pair of
/// neighbouring trees is measured once; in parallel with rayon when `parallel` (the result
/// does not depend on it). `half`: the bake's neighbours reach a query by the half-vector
/// transport (an anisotropic grid), not by rotations.
pub(crate) fn measure(
    grid: &BakeGrid,
    slices: &[Slice],
    eval: &(dyn Fn(Vec3, Vec3) -> Vec3 + Sync),
    defensive: f64,
    parallel: bool,
    half: bool,
) -> Nearest {
    // Every θ-pair (rows i, i + 1 of column j) and φ-pair (columns j0, j1 of row i) once.
    let (rows, columns, pc) = (grid.rows(), grid.columns(), grid.phi_cells());
    let iso = grid.domain() == PhiDomain::Rotation;
    let at = |i: usize, j: usize| i * columns + j;
    let mut pairs: Vec<(usize, usize)> = (0..rows - 1)
        .flat_map(|i| (0..columns).map(move |j| (at(i, j), at(i + 1, j))))
        .collect();
    let theta_pairs = pairs.len();
    if !iso {
        pairs.extend(
            (0..rows).flat_map(|i| (0..pc).map(move |j| (at(i, j), at(i, (j + 1) % columns)))),
        );
    }
    let one = |&p: &(usize, usize)| pair_agrees(grid, slices, p, half, eval, defensive);
    let _ = parallel;
    #[cfg(feature = "rayon")]
    let agrees: Vec<bool> = if parallel {
        use rayon::prelude::*;
        pairs.par_iter().map(one).collect()
    } else {
        pairs.iter().map(one).collect()
    };
    #[cfg(not(feature = "rayon"))]
    let agrees: Vec<bool> = pairs.iter().map(one).collect();
    let (mut theta, mut phi) = (Vec::with_capacity(grid.cells()), Vec::new());
    for i in 0..rows - 1 {
        for j in 0..pc {
            let j1 = if iso { j } else { (j + 1) % columns };
            theta.push(agrees[at(i, j)] && agrees[at(i, j1)]);
            if !iso {
                let phi_pair = |r: usize| theta_pairs + r * pc + j;
                phi.push(agrees[phi_pair(i)] && agrees[phi_pair(i + 1)]);
            }
        }
    }
    Nearest { theta, phi }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baked::Role;
    use crate::{BakeConfig, BakedMode, BakedSampler};

    fn bake(name: &str, params: &[&str], theta_steps: u16, phi_steps: u16) -> BakedSampler {
        let b = brdf_core::registry::create(name, params.iter().copied()).unwrap();
        let config = BakeConfig {
            theta_steps,
            phi_steps,
            ..BakeConfig::default()
        };
        BakedSampler::new(b.into(), config).unwrap()
    }

    /// The measured excess is the χ² distance it claims: against a brute-force midpoint
    /// quadrature of ∫ T_b²/q_a − 1 over the orthographic disk (1 024² points, converged to
    /// 6 digits) for pairs of ward α = 0.05 trees on a 16-row grid. Near the limits that
    /// decide (χ² 0.01–0.2) the estimate is within 15 %; near grazing (χ² ≈ 2) it stays far
    /// above them.
    #[test]
    fn the_rejection_excess_is_the_chi_square_distance() {
        let baked = bake("ward", &["alpha_x=0.05", "alpha_y=0.05", "kd=0"], 16, 1);
        let (tables, _) = baked.tables_for(Role::Importance);
        let eval = |wi: Vec3, w: Vec3| baked.brdf.eval(wi, w);
        let delta = baked.config.defensive;
        for (a, b, tolerance) in [(6, 7, 0.15), (10, 11, 0.15), (12, 13, 0.15), (14, 15, 0.5)] {
            let (sa, sb) = (&tables.slices[a], &tables.slices[b]);
            let onto = isotropic_to_local(
                (1.0, 0.0),
                rotation_between_mirrors_xz(sa.wi.as_dvec3(), sb.wi.as_dvec3()),
            );
            let measured = agreement(sb, sa, &onto, false, &eval, delta).0;
            let n = 1024;
            let h = 2.0 / n as f64;
            let mut sum = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let (x, y) = (-1.0 + h * (i as f64 + 0.5), -1.0 + h * (j as f64 + 0.5));
                    let r2 = x * x + y * y;
                    if r2 >= 1.0 {
                        continue;
                    }
                    let z = brdf_core::math::sqrt(1.0 - r2);
                    let w = glam::DVec3::new(x, y, z);
                    let t = f64::from(luminance(eval(sb.wi, w.as_vec3()))) * z * sb.rejection_scale;
                    let v = onto.transpose() * w;
                    let r = if v.z > 0.0 {
                        f64::from(luminance(eval(sa.wi, v.as_vec3()))) * v.z * sa.rejection_scale
                    } else {
                        0.0
                    };
                    let q = delta * z * FRAC_1_PI + (1.0 - delta) * r;
                    sum += t * t / q * h * h / z;
                }
            }
            let brute = sum - 1.0;
            assert!(
                (measured - brute).abs() <= tolerance * brute,
                "trees {a}, {b}: measured {measured}, quadrature {brute}"
            );
        }
    }

    /// A tail that reaches the horizon keeps its cells blended: Schlick r = 0.01 snapped
    /// ten of its default grid's cells, and a snapped query's one tree, tilted onto wi's
    /// mirror, left a band along the horizon with f·cos θ in it that only the defensive
    /// share covered: a direction there drawn by the exact per-wi tree had 10⁶ times the
    /// mixture's density (a firefly: the weight's R was 32–58 at snapped wi, though the
    /// bake's coverage check, 2 048 samples a cell, saw none). Now no cell snaps, and at
    /// mid-cell wi no direction the exact tree draws has over 10 times the mixture's
    /// density.
    #[test]
    fn a_tail_on_the_horizon_keeps_its_cells_blended() {
        use rand_core::SeedableRng;
        let baked = bake("schlick", &["r=0.01"], 16, 1).with_mode(BakedMode::Rejection);
        assert_eq!(baked.nearest_cells(BakedMode::Rejection), (0, 15));
        let step = crate::GRID_THETA_MAX_DEG / 15.0;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for cell in [0.5, 1.6, 3.5, 6.4] {
            let t = (cell * step).to_radians();
            let wi = glam::DVec3::new(t.sin(), 0.0, t.cos()).as_vec3();
            let exact = crate::QuadtreeSampler::new(
                baked.brdf().clone(),
                wi,
                crate::BuildConfig::default(),
            )
            .unwrap();
            let mut worst = 0.0f64;
            for _ in 0..40_000 {
                let Some(s) = exact.sample(&mut rng) else {
                    continue;
                };
                let mixture = baked.pdf(wi, s.wo).unwrap();
                worst = worst.max(f64::from(s.pdf) / f64::from(mixture));
            }
            assert!(worst < 10.0, "θi = {:.2}°: ratio {worst:e}", cell * step);
        }
    }

    /// Where neighbouring trees agree the cells snap, where they do not they blend: a
    /// mirror lobe (phong n = 1000, rotated exactly onto its neighbours' mirrors) snaps its
    /// rows from the normal on and blends the last ones before grazing; a half-vector lobe
    /// (ward α = 0.05), whose tails change shape from row to row, blends at mid rows; warp
    /// mode blends everywhere; an anisotropic grid measures both axes. A snapped query has
    /// one tree, a blended one two.
    #[test]
    fn cells_snap_where_the_trees_agree() {
        let mut phong = bake("phong", &["n=1000", "kd=0"], 16, 1);
        let cells = &phong.forward.nearest.theta;
        assert!(cells[..12].iter().all(|&b| b), "{cells:?}");
        assert!(!cells[14], "{cells:?}");
        let step = crate::GRID_THETA_MAX_DEG / 15.0;
        let at = |b: &BakedSampler, theta_deg: f64| {
            let t = theta_deg.to_radians();
            let w = glam::DVec3::new(t.sin(), 0.0, t.cos()).as_vec3();
            b.mixture_at(Role::Importance, w).unwrap()
        };
        let one = at(&phong, 4.4 * step);
        assert_eq!(one.len(), 1, "{one:?}");
        assert_eq!(one[0].weight, 1.0);
        assert!((one[0].theta_deg - 4.0 * step).abs() < 1e-9);
        assert_eq!(at(&phong, 14.5 * step).len(), 2);
        phong.set_mode(BakedMode::Warp);
        assert_eq!(at(&phong, 4.4 * step).len(), 2);
        assert_eq!(phong.nearest_cells(BakedMode::Warp), (0, 15));
        let ward = bake("ward", &["alpha_x=0.05", "alpha_y=0.05", "kd=0"], 16, 1);
        assert_eq!(at(&ward, 7.4 * step).len(), 2);
        let aniso = bake("ward", &["alpha_x=0.05", "alpha_y=0.2", "kd=0"], 6, 3);
        let n = &aniso.forward.nearest;
        assert!(n.fits(&aniso.grid) && !n.phi.is_empty());
    }
}
