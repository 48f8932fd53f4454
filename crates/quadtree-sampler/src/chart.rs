//! Coordinates in which a node is integrated ([`crate::integrate`]) and rejection-sampled
//! ([`crate::proposal`]), the node's square ([`Rect`]) and the child order.
//!
//! A node is a square of the seed's domain [−1,1]². f_r on that square is smooth in the
//! interior of the disk, but two things break a plain tensor rule or a plain height bound:
//! the disk's rim (f jumps to 0 outside it, z = √(1 − r²) has an infinite slope, and some
//! models — Ward — grow like 1/√z there) and, for the concentric map, the kinks of the map
//! along the square's diagonals. Each is removed by a change of variables:
//!
//! - **Orthographic map**, angle coordinates (a, t): x = sin a, y = cos a·sin t,
//!   z = cos a·cos t, dx dy = cos²a·cos t da dt. The rim is a coordinate boundary, z is a
//!   product of cosines (no cancellation) and f·cos²a·cos t stays bounded where f ~ z^{−1/2}.
//!   Integration is iterated: outer a (split where the rim crosses the node's horizontal
//!   edges, pieces remapped near those points to absorb the limits' square-root
//!   singularities), inner t between the node's edges.
//!   The chart has poles at (±1, 0), where the rim is tangent to the node's vertical edges:
//!   near them a node's t-range stays ±π/2 however small the node, so its rejection box
//!   never shrinks. Leaves there are sampled in the transposed chart (b, s): y = sin b,
//!   x = cos b·sin s, z = cos b·cos s ([`Chart::AngleY`], poles at (0, ±1)); each rim leaf
//!   takes whichever of the two boxes is smaller.
//! - **Concentric map**, sine coordinates (α, β): a = sin α, b = sin β, da db = cos α cos β
//!   dα dβ; z = cos α or cos β exactly. The map's kinks (|a| = |b|) stay straight diagonals,
//!   along which a node is split into triangles.
//!
//! Sampling uses the seed's uniform (x, y) proposal in every leaf that stays off the rim
//! ([`Chart::Square`]). A leaf that touches the rim is offered its angle or sine chart
//! ([`crate::proposal::Proposal::for_node`]), which bounds f·Jacobian even where f grows without bound at the
//! rim; where f stays bounded the square is bounded too, and the build keeps whichever box
//! has the smaller volume (usually the square: the charts' Jacobians vanish at the rim).
//! The root and its four children, whose parts of the disk are the whole disk and its
//! quarters, may take the square's place with a polar box ([`Chart::Polar`]): the same
//! points with f times a constant Jacobian. On the orthographic map it leaves out the
//! square's corners outside the disk (a constant f_r is one leaf with E\[T\] = the safety
//! factor, not 4/π times it); on both maps a height shape over (s, φ) follows a radial
//! profile (Schlick's Fresnel rise at normal incidence).

use brdf_core::math as m;
use glam::{DVec2, DVec3};

/// An axis-aligned square (or rectangle) of the seed's domain, in f64.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    /// Lower-left corner (u, v).
    pub min: DVec2,
    /// Upper-right corner.
    pub max: DVec2,
}

/// The child order of every quadtree in the crate, written once: child k of a node is the
/// quadrant in column `k & 1` (0: the lower x half) and row `k >> 1` (0: the lower y half),
/// so the order is (−,−), (+,−), (−,+), (+,+). Children are stored contiguously in it.
#[inline]
#[must_use]
pub const fn child_index(column: usize, row: usize) -> usize {
    column + 2 * row
}

/// The column (0: lower x, 1: upper x) of child `k` (see [`child_index`]).
#[inline]
#[must_use]
pub const fn child_column(k: usize) -> usize {
    k & 1
}

/// The row (0: lower y, 1: upper y) of child `k` (see [`child_index`]).
#[inline]
#[must_use]
pub const fn child_row(k: usize) -> usize {
    k >> 1
}

impl Rect {
    /// The square of quadtree cell (`column`, `row`) at `depth` (≤ 30): side s = 2/2^depth,
    /// lower-left corner (−1 + column·s, −1 + row·s). Exact: every corner is a multiple of s
    /// in [−1, 1]. The one way a node's square is formed from its place in the tree.
    #[inline]
    #[must_use]
    pub fn dyadic(depth: u8, column: u32, row: u32) -> Self {
        // 2^(1 − depth) from its exponent bits (a normal number for every u8 depth): the
        // quotient 2/2^depth exactly, without a division on a look-up's path.
        let s = f64::from_bits((1024 - u64::from(depth)) << 52);
        Self::square(f64::from(column) * s - 1.0, f64::from(row) * s - 1.0, s)
    }

    /// 1/side of a dyadic square (a power of two, so exact) from its exponent bits: a
    /// point's coordinates in the square, (p − min)·this, are the quotient (p − min)/side to
    /// the bit, without a division.
    #[inline]
    #[must_use]
    pub fn inverse_side(&self) -> f64 {
        let side = self.side();
        debug_assert!(
            side.to_bits() & ((1 << 52) - 1) == 0,
            "not a power of two: {side}"
        );
        f64::from_bits((2046 - (side.to_bits() >> 52)) << 52)
    }

    /// The side of a square (its width).
    #[inline]
    #[must_use]
    pub fn side(&self) -> f64 {
        self.max.x - self.min.x
    }

    /// The square [x, x+s) × [y, y+s).
    #[must_use]
    pub fn square(x: f64, y: f64, s: f64) -> Self {
        Self {
            min: DVec2::new(x, y),
            max: DVec2::new(x + s, y + s),
        }
    }

    /// Its area in square units.
    #[must_use]
    pub fn area(&self) -> f64 {
        let d = self.max - self.min;
        d.x * d.y
    }

    /// The four quadrants in the child order ([`child_column`], [`child_row`]):
    /// (−,−), (+,−), (−,+), (+,+).
    #[must_use]
    pub fn quadrants(&self) -> [Self; 4] {
        let c = 0.5 * (self.min + self.max);
        [0, 1, 2, 3].map(|k| {
            let (x, y) = (child_column(k) == 1, child_row(k) == 1);
            Self {
                min: DVec2::new(
                    if x { c.x } else { self.min.x },
                    if y { c.y } else { self.min.y },
                ),
                max: DVec2::new(
                    if x { self.max.x } else { c.x },
                    if y { self.max.y } else { c.y },
                ),
            }
        })
    }

    /// The child index of the quadrant holding `p` (points on a split line go to the upper
    /// side).
    #[inline]
    #[must_use]
    pub fn quadrant_of(&self, p: DVec2) -> usize {
        let c = 0.5 * (self.min + self.max);
        child_index(usize::from(p.x >= c.x), usize::from(p.y >= c.y))
    }

    /// Distance from the origin of the nearest and the farthest point.
    #[must_use]
    pub fn radius_range(&self) -> (f64, f64) {
        let near = DVec2::new(
            0.0f64.clamp(self.min.x, self.max.x),
            0.0f64.clamp(self.min.y, self.max.y),
        );
        let far = DVec2::new(
            self.min.x.abs().max(self.max.x.abs()),
            self.min.y.abs().max(self.max.y.abs()),
        );
        (near.length(), far.length())
    }

    /// Whether `p` lies in the closed rectangle.
    #[must_use]
    pub fn contains(&self, p: DVec2) -> bool {
        p.x >= self.min.x && p.x <= self.max.x && p.y >= self.min.y && p.y <= self.max.y
    }

    /// Whether `p` lies in the half-open rectangle [min, max): the cells a descent that sends
    /// points on a split line to the upper side ([`Rect::quadrant_of`]) keeps apart.
    #[inline]
    #[must_use]
    pub fn contains_half_open(&self, p: DVec2) -> bool {
        p.x >= self.min.x && p.y >= self.min.y && p.x < self.max.x && p.y < self.max.y
    }
}

/// The coordinates a leaf is rejection-sampled in (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Chart {
    /// The seed's proposal: (x, y) uniform in the square, Jacobian 1.
    Square,
    /// Orthographic angle coordinates (a, t), for leaves that touch the rim.
    Angle,
    /// The transposed angle coordinates (b, s) (x and y exchanged), for rim leaves near the
    /// angle chart's poles (±1, 0).
    AngleY,
    /// Concentric sine coordinates (α, β), for leaves that touch the square's edge.
    Sine,
    /// Polar coordinates (s, φ) of the disk: x = √s·cos φ, y = √s·sin φ, z = √(1 − s), with
    /// a constant Jacobian ([`polar_jacobian`]: ½ orthographic, [`polar_point`]; 2/π
    /// concentric, [`concentric_polar_point`]). Its boxes cover a node's part of the disk
    /// exactly only where that part is a sector through the centre: the root (the whole
    /// disk) and its four children (quarter disks), on either map. Orthographic, the box
    /// leaves out the square's corners outside the disk (its volume is π/4 of the square's
    /// for a flat bound); on both maps, a height shape over (s, φ) follows a radial profile,
    /// which a bilinear shape over the concentric square, whose rings are squares, cannot.
    Polar,
}

impl Chart {
    /// Whether a leaf's box in this chart is kept beside the packed nodes (found once: the
    /// angle and sine boxes cost inverse sines) rather than formed from its square per
    /// sample (the square; the polar box, whose bounds are constants).
    #[must_use]
    pub fn needs_stored_box(self) -> bool {
        !matches!(self, Self::Square | Self::Polar)
    }
}

/// A point of a chart mapped to the square and the hemisphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChartPoint {
    /// The point of the seed's square [−1,1]².
    pub p: DVec2,
    /// The unit local direction (z ≥ 0).
    pub w: DVec3,
    /// Square area per unit chart area at this point.
    pub jacobian: f64,
}

/// The orthographic map's angle chart: (a, t) → point, direction and Jacobian cos²a·cos t.
#[inline]
#[must_use]
pub fn angle_point(a: f64, t: f64) -> ChartPoint {
    let (sa, ca) = (m::sin(a), m::cos(a));
    let (st, ct) = (m::sin(t), m::cos(t));
    let p = DVec2::new(sa, ca * st);
    ChartPoint {
        p,
        w: DVec3::new(sa, ca * st, ca * ct),
        jacobian: ca * ca * ct,
    }
}

/// The transposed angle chart: (b, s) → point y = sin b, x = cos b·sin s, Jacobian
/// cos²b·cos s ([`angle_point`] with x and y exchanged).
#[inline]
#[must_use]
pub fn angle_point_y(b: f64, s: f64) -> ChartPoint {
    let c = angle_point(b, s);
    ChartPoint {
        p: DVec2::new(c.p.y, c.p.x),
        w: DVec3::new(c.w.y, c.w.x, c.w.z),
        jacobian: c.jacobian,
    }
}

/// The transposed angle chart's coordinates (b, s) of a direction (inverse of
/// [`angle_point_y`]; s = 0 at the chart's poles y = ±1).
#[inline]
pub(crate) fn angle_y_coordinates(w: DVec3) -> DVec2 {
    let b = m::asin(w.y.clamp(-1.0, 1.0));
    let s = if m::cos(b) > 0.0 {
        m::atan2(w.x, w.z)
    } else {
        0.0
    };
    DVec2::new(b, s)
}

/// The orthographic map's polar chart: (s, φ) → point √s·(cos φ, sin φ), direction with
/// z = √(1 − s), Jacobian ½ (dx dy = r dr dφ = ½ ds dφ).
#[inline]
#[must_use]
pub fn polar_point(s: f64, phi: f64) -> ChartPoint {
    let s = s.clamp(0.0, 1.0);
    let r = m::sqrt(s);
    let (sp, cp) = m::sin_cos_reduced(phi);
    let p = DVec2::new(r * cp, r * sp);
    ChartPoint {
        p,
        w: DVec3::new(p.x, p.y, m::sqrt(1.0 - s)),
        jacobian: 0.5,
    }
}

/// The polar chart on the concentric map: the same (s, φ) → direction as [`polar_point`],
/// with the square point the concentric map sends there (from r = √s and φ directly, with no
/// arc tangent) and Jacobian 2/π: ½ (disk area per unit (s, φ) area) times 4/π (square area
/// per unit disk area). The square point's quadrant is the direction's (the map keeps the
/// signs of x and y), so the root's children, quarter disks, are sectors here too.
#[inline]
#[must_use]
pub fn concentric_polar_point(s: f64, phi: f64) -> ChartPoint {
    use core::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let s = s.clamp(0.0, 1.0);
    let r = m::sqrt(s);
    let (sp, cp) = m::sin_cos_reduced(phi);
    // The inverse of the concentric map at (r, φ), φ taken to [−π/4, 7π/4): four wedges,
    // in each of which one coordinate is ±r and the other linear in φ.
    let phi = if phi < -FRAC_PI_4 {
        phi + 2.0 * PI
    } else {
        phi
    };
    let k = r / FRAC_PI_4;
    let p = if phi < FRAC_PI_4 {
        DVec2::new(r, k * phi)
    } else if phi < 3.0 * FRAC_PI_4 {
        DVec2::new(-k * (phi - FRAC_PI_2), r)
    } else if phi < 5.0 * FRAC_PI_4 {
        DVec2::new(-r, -k * (phi - PI))
    } else {
        DVec2::new(k * (phi - 3.0 * FRAC_PI_2), -r)
    };
    ChartPoint {
        p,
        w: DVec3::new(r * cp, r * sp, m::sqrt(1.0 - s)),
        jacobian: core::f64::consts::FRAC_2_PI,
    }
}

/// The polar chart's constant Jacobian on `map` (square area per unit (s, φ) area): ½ on
/// the orthographic map ([`polar_point`]), 2/π on the concentric one
/// ([`concentric_polar_point`]). A square box's height f becomes f times this in a polar box.
#[inline]
#[must_use]
pub fn polar_jacobian(map: brdf_core::DiskMap) -> f64 {
    match map {
        brdf_core::DiskMap::Orthographic => 0.5,
        brdf_core::DiskMap::Concentric => core::f64::consts::FRAC_2_PI,
    }
}

/// The concentric map at a square point given by its sine coordinates (α, β), with z exact.
#[inline]
#[must_use]
pub fn sine_point(alpha: f64, beta: f64) -> ChartPoint {
    let (sa, ca) = (m::sin(alpha), m::cos(alpha));
    let (sb, cb) = (m::sin(beta), m::cos(beta));
    let p = DVec2::new(sa, sb);
    // r = max(|a|, |b|), and z = √(1 − r²) is the cosine of the larger angle.
    let z = if sa.abs() >= sb.abs() { ca } else { cb };
    ChartPoint {
        p,
        w: brdf_core::maps::concentric_direction_f64(p, z),
        jacobian: ca * cb,
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Every square of dyadic level `depth` over [−1,1]² (for the charts' tests).
    pub(crate) fn nodes(depth: u32) -> alloc::vec::Vec<Rect> {
        let n = 1usize << depth;
        let s = 2.0 / n as f64;
        (0..n * n)
            .map(|k| Rect::square(-1.0 + (k % n) as f64 * s, -1.0 + (k / n) as f64 * s, s))
            .collect()
    }

    /// A node's square is exact at every depth the build allows (30): its children tile it
    /// in the child order, the last cell of a row ends at 1, and a point's coordinates in it
    /// by [`Rect::inverse_side`] are the division's to the bit. (Squares kept as f32 corners,
    /// as nodes once were, lose their corners past depth 24.)
    #[test]
    fn dyadic_squares_are_exact_to_the_deepest_level() {
        for depth in [0u8, 1, 7, 24, 25, 29] {
            let n = 1u32 << depth;
            for (column, row) in [(0, 0), (n - 1, 0), (n / 2, n - 1), (n / 3, n / 5 + 1)] {
                let r = Rect::dyadic(depth, column, row);
                assert_eq!(r.side(), 2.0 / f64::from(n));
                assert_eq!(r.max.x - r.min.x, r.max.y - r.min.y);
                // The inverse side gives the quotient's bits.
                assert_eq!(r.inverse_side(), f64::from(n) / 2.0);
                for t in [0.0, 0.3, 0.999_999_9, 1.0 / 3.0] {
                    let p = r.min + DVec2::splat(t) * r.side();
                    let q = (p - r.min) * r.inverse_side();
                    assert_eq!(
                        q.to_array().map(f64::to_bits),
                        ((p - r.min) / r.side()).to_array().map(f64::to_bits)
                    );
                }
                if column == n - 1 {
                    assert_eq!(r.max.x, 1.0);
                }
                for (k, q) in r.quadrants().into_iter().enumerate() {
                    let child = Rect::dyadic(
                        depth + 1,
                        2 * column + child_column(k) as u32,
                        2 * row + child_row(k) as u32,
                    );
                    assert_eq!(child, q, "depth {depth} ({column}, {row}) child {k}");
                    assert_eq!(r.quadrant_of(child.min), k);
                }
            }
        }
        let deepest = Rect::dyadic(30, (1 << 30) - 1, 0);
        assert_eq!((deepest.min.x, deepest.max.x), (1.0 - 0.5f64.powi(29), 1.0));
        assert!(deepest.min.x as f32 == 1.0, "f32 cannot hold this corner");
    }
}
