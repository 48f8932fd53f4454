//! Where a baked sampler answers with one tree: the cells of its grid whose corner trees
//! agree, measured once per bake ([`measure`]).
//!
//! A query blends the trees around it (see `baked_mixture`), and its exact pdf then costs
//! one density per blended tree: a model evaluation in rejection mode, a table look-up in
//! warp mode. The weights may be any function of wi (the mixture stays exact), so where the
//! nearest tree alone, rotated onto wi's mirror, samples as well as the blend, blending buys
//! nothing and costs a density. That is decided per cell and per mode by measurement: for
//! each pair of neighbouring trees a and b, how much worse a (rotated onto b's mirror)
//! samples b's exact density T_b ∝ Y(f_r(wi_b, ·))·cos θ than b's own sampler q_b does — the
//! relative excess of the second moment ∫ T_b²/q of the importance weight, which is the
//! variance of f·cos/pdf up to the model's albedo:
//!
//! - rejection (q_b = T_b up to the defensive share): E = ∫ T_b²/q_a − 1, the χ² distance
//!   of the rotated neighbour;
//! - warp (q the piecewise-constant proxies): E = ∫ T_b²/W_a / ∫ T_b²/W_b − 1.
//!
//! Both directions of every pair count (a for b, b for a). A cell snaps along θ where every
//! θ-pair of its corners is within the mode's limit ([`NEAREST_REJECTION_EXCESS`],
//! [`NEAREST_WARP_EXCESS`]); along φ where every φ-pair is. The pair's excess is for a whole
//! grid step; a snapped query is at most half a step from its tree (for a smooth change of
//! lobe shape, about a quarter of that excess).
//!
//! Each second moment is ∫ (T − q)²/q + 2 − Q (Q: q's mass over the hemisphere, short of 1
//! where a rotation carries part of a tree below the horizon or a proxy spreads part of a
//! rim leaf outside the disk), whose integrand vanishes where the two densities agree: no
//! cancellation between large terms. It is estimated at fixed stratified points, half
//! through b's warp and half cosine-distributed (the tails a proxy rarely visits), each
//! weighed by the mixture of the two densities; the lost mass at a's own warp points. Fixed
//! points keep the bake a pure function of its model and configuration (serial and parallel
//! bakes stay bit-identical).

use crate::bake_grid::{
    BakeGrid, Nearest, PhiDomain, isotropic_to_local, rotation_arc, rotation_between_mirrors_xz,
};
use crate::baked::Slice;
use alloc::vec::Vec;
use brdf_core::geometry::luminance;
use core::f64::consts::FRAC_1_PI;
use glam::{DMat3, DVec2, Vec3};

/// Points per axis of each pair's two stratified sets (the target's proxy, the cosine):
/// 2 × 2 304 points, two model evaluations each. Against a converged quadrature (ward
/// α = 0.05, 16 rows) the estimate is within 10 % at χ² ≈ 0.01–0.18 and about 25 % low at
/// χ² ≈ 0.4–2 (near grazing, where every pair blends anyway).
const POINTS_PER_AXIS: usize = 48;

/// The most relative excess of the second moment (a χ² distance) a rejection-mode pair may
/// show over a whole grid step for its cells to snap: 4 %, about 1 % at a snapped query
/// half a step from its tree.
pub const NEAREST_REJECTION_EXCESS: f64 = 0.04;

/// The most relative excess of the second moment a warp-mode pair may show over a whole grid
/// step for its cells to snap: 10 %. A proxy is piecewise constant on its own tree's leaves,
/// so the rotated neighbour's and the tree's own differ by their layouts as much as by the
/// lobe's change (measured on the default grid: 0–15 % for phong n = 1000, ward α = 0.05
/// and cook-torrance m = 0.1 up to θi = 75°, growing beyond).
pub const NEAREST_WARP_EXCESS: f64 = 0.10;

/// The excess (rejection, warp) of tree `other`, carried to `target`'s frame by
/// `to_target`, as a sampler of `target`'s exact density (see the module doc). Infinite where
/// either tree holds no volume (such a pair always blends).
///
/// With T the target's exact density and q a sampler's (defensive share included), whose
/// mass over the hemisphere is Q (less than 1 where the rotation carries part of a tree below
/// the horizon, or a warp proxy spreads part of a rim leaf outside the disk) and ∫ T = 1,
/// ∫ T²/q = ∫ (T − q)²/q + 2 − Q: an integrand that vanishes where the two agree (no
/// cancellation between large terms), estimated over the target's warp points, and the
/// lost mass, counted over the other tree's own warp points.
fn excess(
    target: &Slice,
    other: &Slice,
    to_target: &DMat3,
    eval: &(dyn Fn(Vec3, Vec3) -> Vec3 + Sync),
    defensive: f64,
) -> [f64; 2] {
    if !(target.live && other.live) {
        return [f64::INFINITY; 2];
    }
    let back = to_target.transpose();
    let n = POINTS_PER_AXIS;
    let density = |s: &Slice, w: glam::DVec3| {
        f64::from(luminance(eval(s.wi, w.as_vec3()))) * w.z * s.rejection_scale
    };
    let keep = 1.0 - defensive;
    let (mut chi_rejection, mut chi_near, mut chi_own) = (0.0, 0.0, 0.0);
    let mut inside = 0usize;
    // Half the points follow the target's proxy, half the cosine (which reaches the tails a
    // proxy visits rarely): each weighs 1/(the mixture's density), ½(W + cos θ/π).
    let proxy_at = |s: &Slice, w: glam::DVec3| {
        s.warp.density(s.map.direction_to_square_f64(w)) * s.warp_scale * w.z
    };
    let cosine = (0..n * n).filter_map(|k| {
        let u = glam::Vec2::new(
            ((k / n) as f32 + 0.5) / n as f32,
            ((k % n) as f32 + 0.5) / n as f32,
        );
        let w = unit(brdf_core::warp::sample_cosine_hemisphere(u))?;
        Some((w, proxy_at(target, w), false))
    });
    let proxied = warp_points(target, n).map(|(w, own)| (w, own, true));
    for (w, own, from_proxy) in proxied.chain(cosine) {
        inside += usize::from(from_proxy);
        let floor = defensive * w.z * FRAC_1_PI;
        let mixture = 0.5 * (own + w.z * FRAC_1_PI);
        let t = density(target, w);
        let v = back * w;
        let (r, proxy) = if v.z > 0.0 {
            (density(other, v), proxy_at(other, v))
        } else {
            (0.0, 0.0)
        };
        let chi = |q: f64| (t - q) * (t - q) / (q * mixture);
        chi_rejection += chi(floor + keep * r);
        chi_near += chi(floor + keep * proxy);
        chi_own += chi(floor + keep * own);
    }
    let count = (n * n) as f64;
    let (chi_rejection, chi_near, chi_own) = (
        chi_rejection / (2.0 * count),
        chi_near / (2.0 * count),
        chi_own / (2.0 * count),
    );
    // The other tree's mass the rotation carries below the horizon: its exact density's
    // (rejection) and its proxy's (warp), with the proxy's mass outside the disk.
    let (mut lost, mut kept) = (0.0, 0usize);
    for (w, own) in warp_points(other, n) {
        if (to_target * w).z > 0.0 {
            kept += 1;
        } else {
            lost += density(other, w) / own;
        }
    }
    let rejection = chi_rejection + keep * lost / count;
    let mass = |share: usize| defensive + keep * share as f64 / count;
    let near = chi_near + 2.0 - mass(kept);
    let own = chi_own + 2.0 - mass(inside);
    let warp = (near - own) / own;
    // NaN (a model returning one) counts as disagreement.
    [rejection, warp].map(|e| if e.is_nan() { f64::INFINITY } else { e })
}

/// The directions of `n` × `n` stratified points (cell centres of [0, 1)²) through a tree's
/// warp, with the proxy's density there per unit solid angle; a point whose warp leaves the
/// disk (part of a rim leaf's square) or finds no volume gives none.
fn warp_points(s: &Slice, n: usize) -> impl Iterator<Item = (glam::DVec3, f64)> + '_ {
    (0..n * n).filter_map(move |k| {
        let u = DVec2::new(
            ((k / n) as f64 + 0.5) / n as f64,
            ((k % n) as f64 + 0.5) / n as f64,
        );
        let (p, leaf) = s.warp.warp(u)?;
        let w = s.map.square_to_direction_f64(p)?;
        (w.z > 0.0).then_some((w, leaf.density * s.warp_scale * w.z))
    })
}

/// A unit f64 direction above the horizon from an f32 one, or `None`.
fn unit(w: Vec3) -> Option<glam::DVec3> {
    let w = brdf_core::geometry::normalize_f64(w.as_dvec3());
    (w.z > 0.0).then_some(w)
}

/// The larger excess of the pair (trees `a`, `b`) in both directions, per mode.
fn pair_excess(
    grid: &BakeGrid,
    slices: &[Slice],
    (a, b): (usize, usize),
    eval: &(dyn Fn(Vec3, Vec3) -> Vec3 + Sync),
    defensive: f64,
) -> [f64; 2] {
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
    let x = excess(sb, sa, &onto(sa, sb), eval, defensive);
    let y = excess(sa, sb, &onto(sb, sa), eval, defensive);
    [x[0].max(y[0]), x[1].max(y[1])]
}

/// The nearest-tree cells of a bake's trees `slices` on `grid` (`eval`: f of the trees'
/// model, forward or adjoint, as (tree's wi, direction)), per mode (rejection, warp). Each
/// pair of neighbouring trees is measured once; in parallel with rayon when `parallel`
/// (the result does not depend on it).
pub(crate) fn measure(
    grid: &BakeGrid,
    slices: &[Slice],
    eval: &(dyn Fn(Vec3, Vec3) -> Vec3 + Sync),
    defensive: f64,
    parallel: bool,
) -> [Nearest; 2] {
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
    let one = |&p: &(usize, usize)| pair_excess(grid, slices, p, eval, defensive);
    let _ = parallel;
    #[cfg(feature = "rayon")]
    let measured: Vec<[f64; 2]> = if parallel {
        use rayon::prelude::*;
        pairs.par_iter().map(one).collect()
    } else {
        pairs.iter().map(one).collect()
    };
    #[cfg(not(feature = "rayon"))]
    let measured: Vec<[f64; 2]> = pairs.iter().map(one).collect();
    let limits = [NEAREST_REJECTION_EXCESS, NEAREST_WARP_EXCESS];
    core::array::from_fn(|mode| {
        let ok = |k: usize| measured[k][mode] <= limits[mode];
        let (mut theta, mut phi) = (Vec::with_capacity(grid.cells()), Vec::new());
        for i in 0..rows - 1 {
            for j in 0..pc {
                let j1 = if iso { j } else { (j + 1) % columns };
                theta.push(ok(i * columns + j) && ok(i * columns + j1));
                if !iso {
                    let phi_pair = |r: usize| theta_pairs + r * pc + j;
                    phi.push(ok(phi_pair(i)) && ok(phi_pair(i + 1)));
                }
            }
        }
        Nearest { theta, phi }
    })
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
            let measured = excess(sb, sa, &onto, &eval, delta)[0];
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

    /// Where neighbouring trees agree the cells snap, where they do not they blend: a sharp
    /// lobe (phong n = 1000, rotated exactly onto its neighbours' mirrors) snaps its rows
    /// from the normal on and blends the last ones before grazing (rejection mode); an
    /// anisotropic grid measures both axes. A snapped query has one tree, a blended one two.
    #[test]
    fn cells_snap_where_the_trees_agree() {
        let phong = bake("phong", &["n=1000", "kd=0"], 16, 1);
        let cells = &phong.forward.nearest[BakedMode::Rejection.index()].theta;
        assert!(cells[..10].iter().all(|&b| b), "{cells:?}");
        assert!(!cells[14], "{cells:?}");
        let at = |theta_deg: f64| {
            let t = theta_deg.to_radians();
            let w = glam::DVec3::new(t.sin(), 0.0, t.cos()).as_vec3();
            phong.mixture_at(Role::Importance, w).unwrap()
        };
        let step = crate::GRID_THETA_MAX_DEG / 15.0;
        let one = at(4.4 * step);
        assert_eq!(one.len(), 1, "{one:?}");
        assert_eq!(one[0].weight, 1.0);
        assert!((one[0].theta_deg - 4.0 * step).abs() < 1e-9);
        let two = at(14.5 * step);
        assert_eq!(two.len(), 2, "{two:?}");
        let ward = bake("ward", &["alpha_x=0.05", "alpha_y=0.2", "kd=0"], 6, 3);
        let n = &ward.forward.nearest[0];
        assert!(n.fits(&ward.grid) && !n.phi.is_empty());
    }
}
