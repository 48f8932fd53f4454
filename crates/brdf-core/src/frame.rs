//! Orthonormal shading frames: world ↔ local, where local z is the normal and x the tangent.

use crate::error::DirectionError;
use crate::geometry::unit_direction;
use glam::Vec3;

/// A right-handed orthonormal frame: `x` the tangent (the anisotropy axis), `y = z × x`, `z`
/// the normal (SPEC §1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The tangent: local x.
    pub x: Vec3,
    /// The bitangent: local y = z × x.
    pub y: Vec3,
    /// The normal: local z.
    pub z: Vec3,
}

impl Frame {
    /// The frame whose axes are the world axes.
    pub const IDENTITY: Self = Self {
        x: Vec3::X,
        y: Vec3::Y,
        z: Vec3::Z,
    };

    /// A frame from a normal alone, with a stable tangent (Duff et al. 2017, via glam's
    /// `any_orthonormal_pair`). The normal need not be unit; it must be finite and non-zero.
    pub fn from_normal(normal: Vec3) -> Result<Self, DirectionError> {
        let z = unit_direction(normal)?;
        let (x, _) = z.any_orthonormal_pair();
        Ok(Self {
            x,
            y: z.cross(x),
            z,
        })
    }

    /// A frame from a normal and a tangent; the tangent is made orthogonal to the normal
    /// (Gram–Schmidt). Errors when either is not a direction or they are parallel: within
    /// 10⁻⁴ rad of each other (or of opposite directions), where the tangent's part across
    /// the normal is too small to give a direction.
    pub fn from_normal_tangent(normal: Vec3, tangent: Vec3) -> Result<Self, DirectionError> {
        let z = unit_direction(normal)?;
        let t = unit_direction(tangent)?;
        // |r| is the sine of the angle between t and z. Its direction is only as good as
        // |r| is large against f32 rounding (≈ 10⁻⁷): a tangent equal to the normal left an
        // r of rounding alone, along t itself, and the frame had x = z (until this was
        // tested by length; its direction against t, which it tested before, was 1).
        let r = t - t.dot(z) * z;
        let s = r.length();
        if s <= 1e-4 {
            return Err(DirectionError::ParallelTangent);
        }
        let mut x = r / s;
        // Near the threshold x keeps some 10⁻³ of z from the cancellation: one pass more.
        if x.dot(z).abs() > 1e-6 {
            x = (x - x.dot(z) * z).normalize();
        }
        Ok(Self {
            x,
            y: z.cross(x),
            z,
        })
    }

    /// World → local coordinates. See also [`Frame::to_world`].
    #[inline]
    #[must_use]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.x), v.dot(self.y), v.dot(self.z))
    }

    /// Local → world coordinates. See also [`Frame::to_local`].
    #[inline]
    #[must_use]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.x * v.x + self.y * v.y + self.z * v.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_orthonormal(f: &Frame) {
        for (a, b) in [(f.x, f.y), (f.y, f.z), (f.z, f.x)] {
            assert!(a.dot(b).abs() < 1e-6);
        }
        for a in [f.x, f.y, f.z] {
            assert!((a.length() - 1.0).abs() < 1e-6);
        }
        assert!((f.z.cross(f.x) - f.y).length() < 1e-6, "right-handed");
    }

    #[test]
    fn frames_are_orthonormal_and_round_trip() {
        let normals = [
            Vec3::Z,
            -Vec3::Z,
            Vec3::new(0.3, -0.2, 0.9),
            Vec3::new(-1e-8, 1.0, 0.0),
            Vec3::new(0.0, 0.0, -1.0 + 1e-7),
        ];
        for n in normals {
            let f = Frame::from_normal(n).unwrap();
            check_orthonormal(&f);
            let v = Vec3::new(0.1, 0.7, -0.3);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
            assert!((f.to_local(f.z) - Vec3::Z).length() < 1e-6);
        }
    }

    #[test]
    fn tangent_frame_keeps_the_tangent_direction() {
        let f = Frame::from_normal_tangent(Vec3::Z, Vec3::new(1.0, 1.0, 0.5)).unwrap();
        check_orthonormal(&f);
        assert!((f.x - Vec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-6);
        assert_eq!(
            Frame::from_normal_tangent(Vec3::Z, Vec3::Z * 2.0),
            Err(DirectionError::ParallelTangent)
        );
        // A tangent equal (or opposite) to a normal off the axes: Gram–Schmidt leaves only
        // rounding, which once normalised into x = z (a frame that maps every local
        // direction into a line).
        for n in [
            Vec3::new(1.0, 1.0, 1e-30),
            Vec3::splat(1e-30),
            Vec3::splat(1e30),
            Vec3::new(3e38, 3e38, 1.0),
            Vec3::new(-0.3, 0.8, 0.1),
            Vec3::new(0.6, -0.48, 0.64),
        ] {
            for t in [
                n,
                -n,
                n * 0.5,
                n + Vec3::splat(1e-9 * n.abs().max_element()),
            ] {
                assert_eq!(
                    Frame::from_normal_tangent(n, t),
                    Err(DirectionError::ParallelTangent),
                    "n = {n}, t = {t}"
                );
            }
        }
        // Just beyond the threshold, and far from it: orthonormal, x within the plane of
        // n and t, on t's side.
        for (n, t) in [
            (Vec3::Z, Vec3::new(2e-4, 0.0, 1.0)),
            (Vec3::Z, Vec3::new(-3e-4, 1e-4, -1.0)),
            (Vec3::new(-0.3, 0.8, 0.1), Vec3::new(-0.3, 0.8, 0.1001)),
            (Vec3::new(0.6, -0.48, 0.64), Vec3::X),
        ] {
            let f = Frame::from_normal_tangent(n, t).unwrap();
            check_orthonormal(&f);
            assert!(f.x.dot(t) > 0.0 && f.x.cross(n).dot(t).abs() < 1e-6 * t.length());
        }
        assert_eq!(
            Frame::from_normal(Vec3::ZERO),
            Err(DirectionError::ZeroLength)
        );
    }
}
