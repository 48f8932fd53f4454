//! The two maps of SPEC §2 between the square [−1,1]² and the upper hemisphere, both sending
//! uniform area to uniform *projected* solid angle (dA ∝ cosθ dω):
//!
//! - [`DiskMap::Orthographic`], the seed's `Codificador`: drop z, (u, v) = (x, y). The square's
//!   corners outside the unit disk map to nothing (f = 0 there by definition).
//! - [`DiskMap::Concentric`]: Shirley–Chiu (1997), a bijection square ↔ disk with constant
//!   Jacobian, followed by the same vertical lift; no part of the square is wasted.
//!
//! Each map is a forward / inverse / Jacobian triad, with round-trip tests.

use crate::math as m;
use core::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};
use glam::{DVec2, DVec3, Vec2, Vec3};

/// Concentric map (Shirley–Chiu 1997) from the square [−1,1]² onto the unit disk.
/// Area scales by the constant [`CONCENTRIC_DISK_AREA_PER_SQUARE_AREA`] = π/4.
/// Inverse: [`disk_to_square_concentric`].
#[inline]
#[must_use]
pub fn square_to_disk_concentric(p: Vec2) -> Vec2 {
    let (a, b) = (p.x, p.y);
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, FRAC_PI_4 * (b / a))
    } else {
        (b, FRAC_PI_2 - FRAC_PI_4 * (a / b))
    };
    Vec2::new(r * m::cosf(phi), r * m::sinf(phi))
}

/// Inverse of [`square_to_disk_concentric`]: unit disk → square [−1,1]².
#[inline]
#[must_use]
pub fn disk_to_square_concentric(d: Vec2) -> Vec2 {
    let r = m::sqrtf(d.x * d.x + d.y * d.y);
    if r == 0.0 {
        return Vec2::ZERO;
    }
    let mut phi = m::atan2f(d.y, d.x);
    if phi < -FRAC_PI_4 {
        phi += 2.0 * PI;
    }
    if phi < FRAC_PI_4 {
        Vec2::new(r, r * phi / FRAC_PI_4)
    } else if phi < 3.0 * FRAC_PI_4 {
        Vec2::new(-r * (phi - FRAC_PI_2) / FRAC_PI_4, r)
    } else if phi < 5.0 * FRAC_PI_4 {
        Vec2::new(-r, -r * (phi - PI) / FRAC_PI_4)
    } else {
        Vec2::new(-r * (3.0 * FRAC_PI_2 - phi) / FRAC_PI_4, -r)
    }
}

/// [`disk_to_square_concentric`] in f64: unit disk → square [−1,1]², the inverse of
/// [`concentric_direction_f64`]'s (x, y). f32 cannot place a point of the disk's rim band
/// (a direction a few 10⁻⁵ above the horizon has 1 − r ≈ 10⁻¹⁰, below f32's resolution of
/// 1), nor a lobe narrower than its 10⁻⁷ in angle: the quadtree's peak hints go through this.
#[inline]
#[must_use]
pub fn disk_to_square_concentric_f64(d: DVec2) -> DVec2 {
    let r = m::sqrt(d.x * d.x + d.y * d.y);
    if r == 0.0 {
        return DVec2::ZERO;
    }
    // The sector is the larger coordinate's: |x| ≥ |y| gives the square's x = ±r and
    // y = ±r·φ/(π/4), φ = atan(y/x) the angle from the nearer x half-axis (the same for the
    // y sectors with the roles swapped); the ratio's arctangent alone, in plain arithmetic.
    let x_sector = d.x.abs() >= d.y.abs();
    let (along, across) = if x_sector { (d.x, d.y) } else { (d.y, d.x) };
    let side = r.copysign(along);
    let t = m::atan_ratio(across, along) * (1.0 / core::f64::consts::FRAC_PI_4);
    let (big, small) = (side, side * t);
    if x_sector {
        DVec2::new(big, small)
    } else {
        DVec2::new(small, big)
    }
}

/// The concentric map in f64 at square point `p`, lifted to the hemisphere with the given z
/// (the caller knows z = √(1 − r²), r = max(|a|, |b|), often without cancellation: the sine
/// chart of a rim node has it as the cosine of an angle). The one f64 copy of the map: the
/// quadtree's charts and the f64 [`DiskMap::square_to_direction_f64`] use it.
#[inline]
#[must_use]
pub fn concentric_direction_f64(p: DVec2, z: f64) -> DVec3 {
    let (a, b) = (p.x, p.y);
    if a == 0.0 && b == 0.0 {
        return DVec3::new(0.0, 0.0, 1.0);
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, core::f64::consts::FRAC_PI_4 * (b / a))
    } else {
        (
            b,
            core::f64::consts::FRAC_PI_2 - core::f64::consts::FRAC_PI_4 * (a / b),
        )
    };
    let (sp, cp) = m::sin_cos_reduced(phi);
    DVec3::new(r * cp, r * sp, z)
}

/// The constant Jacobian of [`square_to_disk_concentric`]: disk area per unit square area.
pub const CONCENTRIC_DISK_AREA_PER_SQUARE_AREA: f32 = FRAC_PI_4;

/// Lifts a point of the unit disk to the upper hemisphere, z = √(1 − x² − y²) (Malley).
/// Points outside the disk give `None`. Unit disk area = unit projected solid angle.
/// Inverse: [`hemisphere_to_disk`].
#[inline]
#[must_use]
pub fn disk_to_hemisphere(d: Vec2) -> Option<Vec3> {
    let r2 = d.length_squared();
    if r2 > 1.0 {
        return None;
    }
    Some(Vec3::new(d.x, d.y, m::sqrtf((1.0 - r2).max(0.0))))
}

/// Inverse of [`disk_to_hemisphere`]: drops z (the seed's `deCartesianasAlCirculo`).
#[inline]
#[must_use]
pub fn hemisphere_to_disk(w: Vec3) -> Vec2 {
    Vec2::new(w.x, w.y)
}

/// Which map sends the square [−1,1]² to the hemisphere (SPEC §2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum DiskMap {
    /// The seed's `Codificador`: (u, v) = (x, y); corners outside the disk are empty.
    #[default]
    Orthographic,
    /// Shirley–Chiu concentric square → disk, then the vertical lift.
    Concentric,
}

impl DiskMap {
    /// Square point → local direction in the closed upper hemisphere, or `None` for the
    /// orthographic map's corners outside the disk. Inverse: [`DiskMap::direction_to_square`].
    #[inline]
    #[must_use]
    pub fn square_to_direction(self, p: Vec2) -> Option<Vec3> {
        match self {
            Self::Orthographic => disk_to_hemisphere(p),
            Self::Concentric => {
                let d = square_to_disk_concentric(p);
                // The concentric map lands on the disk up to rounding: clamp onto it.
                let r2 = d.length_squared();
                if r2 >= 1.0 {
                    let d = d / m::sqrtf(r2);
                    return Some(Vec3::new(d.x, d.y, 0.0));
                }
                Some(Vec3::new(d.x, d.y, m::sqrtf(1.0 - r2)))
            }
        }
    }

    /// [`DiskMap::square_to_direction`] in f64 (what the quadtree's integration and bounds
    /// evaluate), with z computed without cancellation: √((1 − r)(1 + r)).
    #[inline]
    #[must_use]
    pub fn square_to_direction_f64(self, p: DVec2) -> Option<DVec3> {
        match self {
            Self::Orthographic => {
                let r2 = p.length_squared();
                if r2 > 1.0 {
                    return None;
                }
                Some(DVec3::new(p.x, p.y, m::sqrt((1.0 - r2).max(0.0))))
            }
            Self::Concentric => {
                let r = p.x.abs().max(p.y.abs()).min(1.0);
                Some(concentric_direction_f64(p, m::sqrt((1.0 - r) * (1.0 + r))))
            }
        }
    }

    /// Local direction (z ≥ 0) → square point. Inverse of [`DiskMap::square_to_direction`].
    #[inline]
    #[must_use]
    pub fn direction_to_square(self, w: Vec3) -> Vec2 {
        match self {
            Self::Orthographic => hemisphere_to_disk(w),
            Self::Concentric => disk_to_square_concentric(hemisphere_to_disk(w)),
        }
    }

    /// [`DiskMap::direction_to_square`] in f64, the inverse of
    /// [`DiskMap::square_to_direction_f64`]: (x, y) on the orthographic map, its concentric
    /// square point ([`disk_to_square_concentric_f64`]) on the other.
    #[inline]
    #[must_use]
    pub fn direction_to_square_f64(self, w: DVec3) -> DVec2 {
        match self {
            Self::Orthographic => w.truncate(),
            Self::Concentric => disk_to_square_concentric_f64(w.truncate()),
        }
    }

    /// The map's constant Jacobian: square area per unit *projected* solid angle
    /// (dA_square = J · cosθ dω). 1 for the orthographic map, 4/π for the concentric one.
    #[inline]
    #[must_use]
    pub fn square_area_per_projected_solid_angle(self) -> f32 {
        match self {
            Self::Orthographic => 1.0,
            Self::Concentric => 1.0 / CONCENTRIC_DISK_AREA_PER_SQUARE_AREA,
        }
    }

    /// Converts a density per unit square area into a density per unit solid angle at a
    /// direction with the given cos θ: pdf_ω = pdf_A · J · cosθ.
    #[inline]
    #[must_use]
    pub fn square_pdf_to_solid_angle(self, pdf_area: f32, cos_theta: f32) -> f32 {
        pdf_area * self.square_area_per_projected_solid_angle() * cos_theta.max(0.0)
    }

    /// The name used on the command line and in the viewer.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Orthographic => "orthographic",
            Self::Concentric => "concentric",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> impl Iterator<Item = Vec2> {
        (0..41).flat_map(|i| {
            (0..41).map(move |j| Vec2::new(i as f32 / 20.0 - 1.0, j as f32 / 20.0 - 1.0))
        })
    }

    #[test]
    fn concentric_round_trip_and_stays_on_the_disk() {
        for p in grid() {
            let d = square_to_disk_concentric(p);
            assert!(d.length() <= 1.0 + 1e-6);
            let q = disk_to_square_concentric(d);
            assert!((p - q).length() < 1e-5, "{p} -> {d} -> {q}");
        }
    }

    #[test]
    fn concentric_jacobian_is_pi_over_4() {
        // Finite-difference area of a small square at several points.
        let h = 1e-3f32;
        for p in [
            Vec2::new(0.3, 0.1),
            Vec2::new(-0.7, 0.5),
            Vec2::new(0.2, -0.9),
        ] {
            let a = square_to_disk_concentric(p);
            let du = square_to_disk_concentric(p + Vec2::X * h) - a;
            let dv = square_to_disk_concentric(p + Vec2::Y * h) - a;
            let area = du.perp_dot(dv) / (h * h);
            assert!(
                (area - CONCENTRIC_DISK_AREA_PER_SQUARE_AREA).abs() < 2e-3,
                "{area}"
            );
        }
    }

    #[test]
    fn maps_round_trip_through_the_hemisphere() {
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            for p in grid() {
                let Some(w) = map.square_to_direction(p) else {
                    assert_eq!(map, DiskMap::Orthographic);
                    assert!(p.length() > 1.0);
                    continue;
                };
                assert!((w.length() - 1.0).abs() < 1e-5 && w.z >= 0.0);
                let q = map.direction_to_square(w);
                assert!((p - q).length() < 1e-4, "{map:?}: {p} -> {w} -> {q}");
            }
        }
        assert_eq!(DiskMap::Orthographic.square_to_direction(Vec2::ONE), None);
        assert!(DiskMap::Concentric.square_to_direction(Vec2::ONE).is_some());
    }

    #[test]
    fn the_f64_map_is_the_f32_one() {
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            for p in grid() {
                let lo = map.square_to_direction(p);
                let hi = map.square_to_direction_f64(p.as_dvec2());
                // On the orthographic rim, f32 and f64 round r² to either side of 1.
                let on_rim = (p.as_dvec2().length_squared() - 1.0).abs() < 1e-6;
                assert!(on_rim || lo.is_some() == hi.is_some(), "{map:?} {p}");
                if let (Some(lo), Some(hi)) = (lo, hi) {
                    assert!((hi.length() - 1.0).abs() < 1e-12, "{map:?} {p}: {hi}");
                    // f32's z cancels at the rim (1 − r²); f64's does not: compare z off it.
                    let tol_z = if hi.z > 0.01 { 1e-6 } else { 1e-3 };
                    let d = lo.as_dvec3() - hi;
                    assert!(
                        d.truncate().length() < 1e-6 && d.z.abs() < tol_z,
                        "{map:?} {p}: {lo} vs {hi}"
                    );
                }
            }
        }
    }

    /// The f64 inverse undoes the f64 map to 8·10⁻¹⁵ everywhere, the rim band included: square
    /// points 10⁻¹² inside the edge, directions 10⁻⁶ above the horizon, where f32's inverse
    /// cannot tell the point from the edge.
    #[test]
    fn the_f64_inverse_round_trips_to_the_rim() {
        let edge = 1.0 - 1e-12;
        let rim = (0..=400).flat_map(|i| {
            let t = 2.0 * f64::from(i) / 400.0 - 1.0;
            [
                DVec2::new(edge, t * edge),
                DVec2::new(-edge, t * edge),
                DVec2::new(t * edge, edge),
                DVec2::new(t * edge, -edge),
            ]
        });
        let inner: alloc::vec::Vec<DVec2> = grid().map(|p| p.as_dvec2() * 0.999).collect();
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            for p in rim.clone().chain(inner.iter().copied()) {
                let Some(w) = map.square_to_direction_f64(p) else {
                    continue;
                };
                let q = map.direction_to_square_f64(w);
                assert!((p - q).length() < 1e-15 * 8.0, "{map:?}: {p} -> {w} -> {q}");
            }
        }
        // A direction 10⁻⁶ above the horizon: f64 keeps it off the edge, f32 does not.
        let w = DVec3::new(0.6, -0.8, 0.0) * (1.0 - 0.5e-12) + DVec3::Z * 1e-6;
        let w = w.normalize();
        let q = DiskMap::Concentric.direction_to_square_f64(w);
        assert!(q.x.abs().max(q.y.abs()) < 1.0, "{q}");
        assert!(q.x.abs().max(q.y.abs()) > 1.0 - 1e-11, "{q}");
        // Back again, z to the conditioning of √(1 − r²) there (an ulp of r moves z by
        // 10⁻¹⁰), yet well above the horizon.
        let back = DiskMap::Concentric.square_to_direction_f64(q).unwrap();
        assert!(
            (back - w).length() < 1e-9 && back.z > 0.9e-6,
            "{back} vs {w}"
        );
    }

    #[test]
    fn jacobians_integrate_the_projected_hemisphere() {
        // ∫ cosθ dω over the hemisphere = π; the square's usable area / J must equal it.
        let ortho_usable = PI; // the unit disk
        assert!(
            (ortho_usable / DiskMap::Orthographic.square_area_per_projected_solid_angle() - PI)
                .abs()
                < 1e-6
        );
        assert!(
            (4.0 / DiskMap::Concentric.square_area_per_projected_solid_angle() - PI).abs() < 1e-6
        );
    }
}
