//! The box a leaf is rejection-sampled in ([`Proposal`]): the seed's square, or, for a leaf
//! on the disk's rim, the smallest box of an angle or sine chart (see [`crate::chart`]).

use crate::chart::{
    Chart, ChartPoint, Rect, angle_point, angle_point_y, angle_y_coordinates, polar_point,
    sine_point,
};
use brdf_core::DiskMap;
use brdf_core::math as m;
use core::f64::consts::{FRAC_PI_2, PI};
use glam::{DVec2, DVec3};

/// The (a, t) box of the rectangle [lo, hi] (x = sin a, y = cos a·sin t); `chart` names the
/// chart it is for (the transposed chart passes the rectangle with x and y exchanged).
fn angle_box(lo: DVec2, hi: DVec2, chart: Chart) -> Proposal {
    let (xa, xb) = (lo.x.clamp(-1.0, 1.0), hi.x.clamp(-1.0, 1.0));
    let (a0, a1) = (m::asin(xa), m::asin(xb));
    // t = asin(y / cos a) over the node: extremes at the a-ends or at a = 0.
    let (mut tlo, mut thi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut consider = |a: f64| {
        let ca = m::cos(a);
        if ca <= 0.0 {
            return;
        }
        tlo = tlo.min(m::asin((lo.y / ca).clamp(-1.0, 1.0)));
        thi = thi.max(m::asin((hi.y / ca).clamp(-1.0, 1.0)));
    };
    consider(a0);
    consider(a1);
    if a0 < 0.0 && a1 > 0.0 {
        consider(0.0);
    }
    if tlo.is_nan() || thi.is_nan() || tlo >= thi {
        (tlo, thi) = (-FRAC_PI_2, FRAC_PI_2);
    }
    Proposal {
        chart,
        lo: DVec2::new(a0, tlo),
        hi: DVec2::new(a1, thi),
    }
}

/// The box of a leaf in its sampling chart, and the map from chart coordinates back.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Proposal {
    /// The chart.
    pub chart: Chart,
    /// Lower corner of the box in chart coordinates.
    pub lo: DVec2,
    /// Upper corner.
    pub hi: DVec2,
}

impl Proposal {
    /// The chart proposal for a node: the seed's square unless the node touches the rim
    /// (orthographic: the smaller of the two angle boxes) or the square's edge (concentric: the
    /// sine box). For a rim node the build may still choose the square, where f is bounded
    /// at the rim and the square's box is the smaller.
    #[must_use]
    pub fn for_node(map: DiskMap, rect: &Rect) -> Self {
        match map {
            DiskMap::Orthographic => {
                let (_, far) = rect.radius_range();
                if far < 1.0 - 1e-12 {
                    return Self {
                        chart: Chart::Square,
                        lo: rect.min,
                        hi: rect.max,
                    };
                }
                // The smaller of the two angle boxes (ties to the seed's own chart).
                let (a, b) = (
                    Self::in_chart(rect, Chart::Angle),
                    Self::in_chart(rect, Chart::AngleY),
                );
                if b.area() < a.area() { b } else { a }
            }
            DiskMap::Concentric => {
                let edge = rect.min.x <= -1.0
                    || rect.min.y <= -1.0
                    || rect.max.x >= 1.0
                    || rect.max.y >= 1.0;
                if !edge {
                    return Self {
                        chart: Chart::Square,
                        lo: rect.min,
                        hi: rect.max,
                    };
                }
                Self::in_chart(rect, Chart::Sine)
            }
        }
    }

    /// The polar box of an orthographic node whose part of the disk is a sector through the
    /// centre ([`Chart::Polar`]): s ∈ [0, 1] and φ over the whole turn for the root, over its
    /// quadrant for a child of the root; `None` for any other node. (Squares are dyadic, so
    /// these comparisons are exact.)
    #[must_use]
    pub fn polar(map: DiskMap, rect: &Rect) -> Option<Self> {
        let corner = |v: f64| v == -1.0 || v == 0.0;
        let side = rect.max.x - rect.min.x;
        let sector = (side == 2.0 && rect.min == DVec2::NEG_ONE)
            || (side == 1.0 && corner(rect.min.x) && corner(rect.min.y));
        (map == DiskMap::Orthographic && sector).then(|| Self::polar_box(rect))
    }

    /// The polar box of the root or one of its children (see [`Proposal::polar`]).
    fn polar_box(rect: &Rect) -> Self {
        let (lo, hi) = if rect.max.x - rect.min.x >= 2.0 {
            (-PI, PI)
        } else {
            match (rect.min.x >= 0.0, rect.min.y >= 0.0) {
                (true, true) => (0.0, FRAC_PI_2),
                (false, true) => (FRAC_PI_2, PI),
                (false, false) => (-PI, -FRAC_PI_2),
                (true, false) => (-FRAC_PI_2, 0.0),
            }
        };
        Self {
            chart: Chart::Polar,
            lo: DVec2::new(0.0, lo),
            hi: DVec2::new(1.0, hi),
        }
    }

    /// The proposal of `rect` in a given chart (the chart a packed leaf recorded). For the
    /// angle charts: the box of the node's (a, t) or (b, s) coordinates; for the polar chart,
    /// of the root or a child of the root (the only nodes a tree samples in it, and the only
    /// ones a packed tree accepts it for).
    #[must_use]
    pub fn in_chart(rect: &Rect, chart: Chart) -> Self {
        match chart {
            Chart::Polar => Self::polar_box(rect),
            Chart::Square => Self {
                chart,
                lo: rect.min,
                hi: rect.max,
            },
            Chart::Angle => angle_box(rect.min, rect.max, chart),
            Chart::AngleY => {
                let swap = |v: DVec2| DVec2::new(v.y, v.x);
                angle_box(swap(rect.min), swap(rect.max), chart)
            }
            Chart::Sine => {
                let s = |x: f64| m::asin(x.clamp(-1.0, 1.0));
                Self {
                    chart,
                    lo: DVec2::new(s(rect.min.x), s(rect.min.y)),
                    hi: DVec2::new(s(rect.max.x), s(rect.max.y)),
                }
            }
        }
    }

    /// The box's area in chart units.
    #[must_use]
    pub fn area(&self) -> f64 {
        let d = self.hi - self.lo;
        d.x * d.y
    }

    /// The chart point at box coordinates `q`, or `None` when it falls outside the node or the
    /// disk (an automatic rejection).
    #[inline]
    #[must_use]
    pub fn point(&self, map: DiskMap, rect: &Rect, q: DVec2) -> Option<ChartPoint> {
        match self.chart {
            Chart::Square => map.square_to_direction_f64(q).map(|w| ChartPoint {
                p: q,
                w,
                jacobian: 1.0,
            }),
            Chart::Angle => {
                let c = angle_point(q.x, q.y);
                (c.p.y >= rect.min.y && c.p.y < rect.max.y && c.jacobian > 0.0).then_some(c)
            }
            Chart::AngleY => {
                let c = angle_point_y(q.x, q.y);
                (c.p.x >= rect.min.x && c.p.x < rect.max.x && c.jacobian > 0.0).then_some(c)
            }
            Chart::Sine => Some(sine_point(q.x, q.y)),
            Chart::Polar => {
                // The box's φ-range is the node's quadrant (or the whole turn): only rounding
                // on its edges can carry a point out of the node.
                let c = polar_point(q.x, q.y);
                rect.contains_half_open(c.p).then_some(c)
            }
        }
    }

    /// Chart coordinates of a direction known to lie in this node (inverse of `point`).
    #[must_use]
    pub fn coordinates(&self, map: DiskMap, w: DVec3) -> DVec2 {
        match self.chart {
            Chart::Square => match map {
                DiskMap::Orthographic => DVec2::new(w.x, w.y),
                DiskMap::Concentric => {
                    brdf_core::maps::disk_to_square_concentric(w.truncate().as_vec2()).as_dvec2()
                }
            },
            Chart::Angle => {
                let a = m::asin(w.x.clamp(-1.0, 1.0));
                let ca = m::cos(a);
                let t = if ca > 0.0 { m::atan2(w.y, w.z) } else { 0.0 };
                DVec2::new(a, t)
            }
            Chart::AngleY => angle_y_coordinates(w),
            Chart::Polar => DVec2::new(w.x * w.x + w.y * w.y, m::atan2(w.y, w.x)),
            Chart::Sine => {
                let p =
                    brdf_core::maps::disk_to_square_concentric(w.truncate().as_vec2()).as_dvec2();
                DVec2::new(m::asin(p.x.clamp(-1.0, 1.0)), m::asin(p.y.clamp(-1.0, 1.0)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chart::tests::nodes;

    /// At the angle chart's poles (±1, 0) its box keeps a t-range of π/2 however small the
    /// node; the chosen proposal must shrink with the node (area ~ s^{3/2}), at all four
    /// tangent points, and sample the node exactly (round trip).
    #[test]
    fn rim_boxes_shrink_at_the_poles() {
        for k in [4, 10, 19] {
            let s = 2.0f64.powi(-k);
            let nodes = [
                Rect::square(-1.0, 0.0, s),
                Rect::square(-1.0, -s, s),
                Rect::square(1.0 - s, 0.0, s),
                Rect::square(0.0, 1.0 - s, s),
                Rect::square(-s, -1.0, s),
            ];
            for r in nodes {
                let prop = Proposal::for_node(DiskMap::Orthographic, &r);
                assert!(
                    prop.area() <= 4.0 * s * s.sqrt(),
                    "{r:?}: {prop:?} area {} for side {s}",
                    prop.area()
                );
                for (i, j) in [(1, 1), (3, 5), (6, 2), (5, 6)] {
                    let q = prop.lo
                        + (prop.hi - prop.lo) * DVec2::new(f64::from(i) / 7.0, f64::from(j) / 7.0);
                    let Some(c) = prop.point(DiskMap::Orthographic, &r, q) else {
                        continue;
                    };
                    assert!(r.contains(c.p), "{r:?} {q} -> {}", c.p);
                    let back = prop.coordinates(DiskMap::Orthographic, c.w);
                    assert!((back - q).length() < 1e-6, "{r:?} {q} -> {back}");
                }
            }
        }
    }

    /// Every point of a rim node's part of the disk lies in its proposal box (otherwise
    /// rejection never proposes it: a hole in the sampled density).
    #[test]
    fn rim_boxes_cover_their_nodes() {
        let mut seed = 7u64;
        let mut u = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        // Every rim node at shallow depths; at deep ones, the rim nodes around the four
        // tangent points (±1, 0), (0, ±1), where the charts' poles are.
        let mut nodes = alloc::vec::Vec::new();
        for depth in [2i32, 4, 6] {
            let s = 2.0f64.powi(1 - depth);
            let n = 1i64 << depth;
            for k in 0..n * n {
                nodes.push(Rect::square(
                    -1.0 + (k % n) as f64 * s,
                    -1.0 + (k / n) as f64 * s,
                    s,
                ));
            }
        }
        for depth in [10i32, 15, 19] {
            let s = 2.0f64.powi(1 - depth);
            for i in -3..3 {
                for j in 0..4 {
                    let (a, b) = (f64::from(i) * s, f64::from(j) * s);
                    nodes.push(Rect::square(-1.0 + b, a, s));
                    nodes.push(Rect::square(1.0 - s - b, a, s));
                    nodes.push(Rect::square(a, -1.0 + b, s));
                    nodes.push(Rect::square(a, 1.0 - s - b, s));
                }
            }
        }
        for r in nodes {
            {
                let (near, far) = r.radius_range();
                if far < 1.0 - 1e-12 || near >= 1.0 {
                    continue;
                }
                let prop = Proposal::for_node(DiskMap::Orthographic, &r);
                for _ in 0..64 {
                    let p = r.min + (r.max - r.min) * DVec2::new(u(), u());
                    let r2 = p.length_squared();
                    if r2 >= 1.0 {
                        continue;
                    }
                    let w = DVec3::new(p.x, p.y, m::sqrt(1.0 - r2));
                    let q = prop.coordinates(DiskMap::Orthographic, w);
                    let pad = (prop.hi - prop.lo) * 1e-9 + DVec2::splat(1e-12);
                    assert!(
                        q.cmpge(prop.lo - pad).all() && q.cmple(prop.hi + pad).all(),
                        "{r:?} {prop:?}: {p} -> {q}"
                    );
                }
            }
        }
    }

    /// The polar boxes of the root and of its four children hold exactly their parts of the
    /// disk: box area × Jacobian ½ is that part's area (π, π/4), every point of the part maps
    /// into the box and back, and every box point maps into its node (or is refused).
    #[test]
    fn polar_boxes_are_their_nodes_parts_of_the_disk() {
        let root = Rect::square(-1.0, -1.0, 2.0);
        let mut rects = alloc::vec![root];
        rects.extend(root.quadrants());
        let map = DiskMap::Orthographic;
        for r in rects {
            let prop = Proposal::polar(map, &r).expect("the root and its children are sectors");
            let part = if r == root { PI } else { PI / 4.0 };
            assert!((prop.area() * 0.5 - part).abs() < 1e-15, "{r:?}: {prop:?}");
            for i in 0..=16 {
                for j in 0..=16 {
                    let q = prop.lo
                        + (prop.hi - prop.lo) * DVec2::new(f64::from(i), f64::from(j)) / 16.0;
                    let Some(c) = prop.point(map, &r, q) else {
                        // Only on the box's edges: the centre (s = 0), the rim (s = 1) and
                        // the node's own upper edges (half-open squares).
                        assert!(i == 0 || i == 16 || j == 0 || j == 16, "{r:?}: {q} refused");
                        continue;
                    };
                    assert!(r.contains_half_open(c.p) && (c.w.length() - 1.0).abs() < 1e-15);
                    assert_eq!(c.jacobian, 0.5);
                    if i > 0 && i < 16 && j > 0 && j < 16 {
                        let back = prop.coordinates(map, c.w);
                        assert!((back - q).length() < 1e-12, "{r:?}: {q} -> {back}");
                    }
                }
            }
            let mut k = 0u64;
            for _ in 0..512 {
                k = k
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let u = DVec2::new((k >> 40) as f64, ((k >> 16) & 0xff_ffff) as f64)
                    / f64::from(1u32 << 24);
                let p = r.min + (r.max - r.min) * u;
                if p.length_squared() >= 1.0 {
                    continue;
                }
                let w = DVec3::new(p.x, p.y, m::sqrt(1.0 - p.length_squared()));
                let q = prop.coordinates(map, w);
                assert!(
                    q.cmpge(prop.lo).all() && q.cmple(prop.hi).all(),
                    "{r:?}: {p} -> {q}"
                );
            }
        }
        // No other node is a sector, and the concentric map has no polar chart.
        assert!(Proposal::polar(map, &Rect::square(-0.5, -0.5, 1.0)).is_none());
        assert!(Proposal::polar(map, &Rect::square(0.0, 0.0, 0.5)).is_none());
        assert!(Proposal::polar(DiskMap::Concentric, &root).is_none());
    }

    #[test]
    fn proposals_round_trip() {
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            for r in nodes(3) {
                let prop = Proposal::for_node(map, &r);
                for (i, j) in [(1, 1), (3, 5), (6, 2)] {
                    let q = prop.lo
                        + (prop.hi - prop.lo) * DVec2::new(f64::from(i) / 7.0, f64::from(j) / 7.0);
                    let Some(c) = prop.point(map, &r, q) else {
                        continue;
                    };
                    assert!((c.w.length() - 1.0).abs() < 1e-12);
                    let back = prop.coordinates(map, c.w);
                    assert!((back - q).length() < 1e-5, "{map:?} {r:?} {q} -> {back}");
                    if let Some(w2) = map.square_to_direction_f64(c.p) {
                        assert!((w2 - c.w).length() < 1e-9);
                    }
                }
            }
        }
    }
}
