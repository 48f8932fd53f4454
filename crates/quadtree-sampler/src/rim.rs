//! How a baked warp spreads the share of a leaf on the orthographic disk's rim: uniformly in
//! solid angle over the leaf's part of the hemisphere, not in area over its square.
//!
//! Over the orthographic map the disk's area is projected solid angle, dA = cos θ dω, so a
//! proxy uniform over a square has a density per unit solid angle ∝ cos θ, which falls to 0
//! at the rim. Where f·cos θ does not (Cook–Torrance at m ≈ 1 seen from grazing incidence:
//! f grows like 1/cos θo toward the horizon on the mirror side, and its rejection tree,
//! which bounds f·Jacobian in angle and polar charts there, keeps coarse rim leaves and
//! disk sectors), the weight f·cos/pdf grows like 1/cos θo across such a leaf: the weight's
//! relative second moment at θi = 89° was 10.6 (m = 1, kd = 0.2, default grid; 2.2 with
//! the charts below, nearly all of it from the sectors'), against 1.00 in rejection mode.
//! A rim leaf may therefore be spread in the chart (x, t) of the hemisphere,
//!
//! x = x, y = ρ·sin t, z = ρ·cos t, ρ = √(1 − x²),  dω = dx dt  (Archimedes),
//!
//! x uniform over the leaf's x-range where its column meets the disk, then t uniform over
//! the leaf's y-range at that x: a deterministic, invertible map of the leaf's uniforms onto
//! exactly its part of the hemisphere, whose density per unit solid angle is
//! P / ((x₁ − x₀)·(t₁(x) − t₀(x))) for the leaf's probability P — bounded at the rim, so
//! the weight stays bounded wherever f·cos θ does. (The leaf's [`crate::proposal::Shape`]
//! then follows what is left of f over the chart's unit square.) Near (±1, 0), where ρ
//! vanishes and a small leaf's t-range would span ±π/2, the chart is transposed (x and y
//! exchanged), as the rejection sampler's angle charts are.
//!
//! A disk sector (the root or one of its children, spread uniformly in area, so ∝ cos θ
//! per solid angle) has the same fault and its own chart, (z, φ) with dω = dz dφ
//! ([`SectorChart`]). Either chart is taken only where it scores better at the fit's test
//! points (`bilinear::choose_chart`): where f·cos θ falls like cos θ toward the rim
//! (Lambert), the area spread is exact and stays. The choice is stored in the leaf's shape
//! word (file version 9).

use crate::chart::Rect;
use brdf_core::math as m;
use glam::DVec2;

/// The solid-angle chart of one rim leaf (see the module doc), in the leaf's own axes: the
/// first coordinate is x, or y where `swap`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RimChart {
    /// Whether the chart's first coordinate is y (the leaf lies nearer (±1, 0)).
    swap: bool,
    /// The first coordinate's range where the leaf's column meets the disk.
    lo: f64,
    hi: f64,
    /// The leaf's range of the second coordinate.
    y0: f64,
    y1: f64,
}

impl RimChart {
    /// The chart of a leaf's square, or `None` where the square lies inside the disk (a
    /// plain leaf) or outside it.
    pub(crate) fn of(rect: &Rect) -> Option<Self> {
        let far_x = rect.min.x.abs().max(rect.max.x.abs());
        let far_y = rect.min.y.abs().max(rect.max.y.abs());
        if far_x * far_x + far_y * far_y <= 1.0 {
            return None;
        }
        let centre = (rect.min + rect.max) * 0.5;
        let swap = centre.x.abs() > centre.y.abs();
        let (x0, x1, y0, y1) = if swap {
            (rect.min.y, rect.max.y, rect.min.x, rect.max.x)
        } else {
            (rect.min.x, rect.max.x, rect.min.y, rect.max.y)
        };
        // The columns x where the leaf's y-range meets the disk: |x| < √(1 − y_near²).
        let near = if y0 > 0.0 {
            y0
        } else if y1 < 0.0 {
            -y1
        } else {
            0.0
        };
        if near >= 1.0 {
            return None;
        }
        let reach = m::sqrt((1.0 - near) * (1.0 + near));
        let (lo, hi) = (x0.max(-reach), x1.min(reach));
        (hi > lo).then_some(Self {
            swap,
            lo,
            hi,
            y0,
            y1,
        })
    }

    /// The range of t the leaf holds at first coordinate `x` (t₀ ≤ t₁; empty, t₀ = t₁, at
    /// the ends of the x-range).
    #[inline]
    fn t_range(&self, x: f64) -> (f64, f64, f64) {
        let rho = m::sqrt(((1.0 - x) * (1.0 + x)).max(0.0));
        if rho <= 0.0 {
            return (rho, 0.0, 0.0);
        }
        let t = |y: f64| m::asin((y / rho).clamp(-1.0, 1.0));
        (rho, t(self.y0), t(self.y1))
    }

    /// The square point of the chart's unit coordinates `u` ∈ [0, 1)².
    #[inline]
    pub(crate) fn point(&self, u: DVec2) -> DVec2 {
        let x = self.lo + u.x * (self.hi - self.lo);
        let (rho, t0, t1) = self.t_range(x);
        let y = rho * m::sin(t0 + u.y * (t1 - t0));
        if self.swap {
            DVec2::new(y, x)
        } else {
            DVec2::new(x, y)
        }
    }

    /// The chart's unit coordinates of square point `p` (in the leaf, on the disk), and the
    /// measure of the chart's box in (x, t): the leaf's density per unit solid angle at `p`
    /// is its probability, times its shape at those coordinates, over that measure. `None`
    /// where `p` is off the chart (outside the disk, or where the leaf's t-range is empty).
    #[inline]
    pub(crate) fn unit(&self, p: DVec2) -> Option<(DVec2, f64)> {
        let (x, y) = if self.swap { (p.y, p.x) } else { (p.x, p.y) };
        let (rho, t0, t1) = self.t_range(x);
        let (dx, dt) = (self.hi - self.lo, t1 - t0);
        if !(rho > 0.0 && dt > 0.0 && dx > 0.0) {
            return None;
        }
        let t = m::asin((y / rho).clamp(-1.0, 1.0));
        let u = DVec2::new((x - self.lo) / dx, (t - t0) / dt).clamp(DVec2::ZERO, DVec2::ONE);
        Some((u, dx * dt))
    }
}

/// The solid-angle chart of a disk sector (the orthographic root, or one of its children;
/// see the module doc): (z, φ) with z = cos θ and φ over the sector's angles, dω = dz dφ, so
/// the leaf's unit coordinates (z, (φ − φ₀)/(φ₁ − φ₀)) are uniform in solid angle over its
/// part of the hemisphere, and its density per unit solid angle is its probability, times
/// its shape there, over φ₁ − φ₀.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SectorChart {
    phi0: f64,
    phi1: f64,
}

impl SectorChart {
    /// The chart of a sector's square (the root's, [−1, 1]², or a quadrant's).
    pub(crate) fn of(rect: &Rect) -> Self {
        let b = crate::proposal::Proposal::in_chart(rect, crate::chart::Chart::Polar);
        Self {
            phi0: b.lo.y,
            phi1: b.hi.y,
        }
    }

    /// The sector's angle, φ₁ − φ₀.
    pub(crate) fn span(&self) -> f64 {
        self.phi1 - self.phi0
    }

    /// The square point of unit coordinates `u` ∈ [0, 1)².
    #[inline]
    pub(crate) fn point(&self, u: DVec2) -> DVec2 {
        let z = u.x;
        let r = m::sqrt(((1.0 - z) * (1.0 + z)).max(0.0));
        let (s, c) = m::sin_cos_reduced(self.phi0 + u.y * (self.phi1 - self.phi0));
        DVec2::new(r * c, r * s)
    }

    /// The unit coordinates of square point `p`, whose direction has cosine `z`, and the
    /// chart's measure, φ₁ − φ₀.
    #[inline]
    pub(crate) fn unit(&self, p: DVec2, z: f64) -> (DVec2, f64) {
        let span = self.phi1 - self.phi0;
        let mut phi = m::atan2(p.y, p.x);
        // The root's range is [−π, π); atan2 gives (−π, π]: π is −π's point. (A quadrant's
        // φ₁ is its own edge, clamped to below.)
        if span > core::f64::consts::PI && phi >= self.phi1 {
            phi -= 2.0 * core::f64::consts::PI;
        }
        let u = DVec2::new(z, (phi - self.phi0) / span).clamp(DVec2::ZERO, DVec2::ONE);
        (u, span)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chart maps the unit square onto the leaf's part of the disk, `unit` undoes it,
    /// and its density integrates to one over the leaf: Σ over a fine grid of the square of
    /// (1/measure)/z·dA ≈ 1 (dω = dA/z), for rim leaves in every octant and both axes.
    #[test]
    fn a_rim_chart_is_a_bijection_onto_its_leaf_with_unit_mass() {
        let leaves = [
            Rect::dyadic(2, 1, 3),
            Rect::dyadic(2, 3, 2),
            Rect::dyadic(3, 7, 4),
            Rect::dyadic(3, 0, 3),
            Rect::dyadic(4, 13, 13),
            Rect::dyadic(5, 3, 26),
            Rect::dyadic(6, 63, 33),
        ];
        assert!(
            RimChart::of(&Rect::dyadic(2, 1, 1)).is_none(),
            "inside the disk"
        );
        assert!(
            RimChart::of(&Rect::dyadic(4, 15, 15)).is_none(),
            "outside the disk"
        );
        for rect in leaves {
            let c = RimChart::of(&rect).unwrap_or_else(|| panic!("{rect:?} is on the rim"));
            for i in 0..20 {
                for j in 0..20 {
                    let u = DVec2::new((i as f64 + 0.5) / 20.0, (j as f64 + 0.5) / 20.0);
                    let p = c.point(u);
                    assert!(p.length_squared() < 1.0, "{p}");
                    let side = rect.max - rect.min;
                    let inside = (p - rect.min) / side;
                    assert!(inside.min_element() > -1e-12 && inside.max_element() < 1.0 + 1e-12);
                    let (back, _) = c.unit(p).unwrap();
                    assert!((back - u).length() < 1e-9, "{rect:?} {u} {back}");
                }
            }
            let n = 1500;
            let side = rect.max - rect.min;
            let da = side.x * side.y / (n * n) as f64;
            let mut mass = 0.0;
            for i in 0..n {
                for j in 0..n {
                    let p = rect.min
                        + side
                            * DVec2::new((i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64);
                    let r2 = p.length_squared();
                    if r2 >= 1.0 {
                        continue;
                    }
                    if let Some((_, measure)) = c.unit(p) {
                        mass += da / (measure * m::sqrt(1.0 - r2));
                    }
                }
            }
            assert!((mass - 1.0).abs() < 0.01, "{rect:?}: {mass}");
        }
    }
}
