//! The seed's `Codificador` (Fig. 1) and `refleja` (Fig. 5): world directions ↔ the local
//! frame ↔ the square, and the build-select-sample convenience.

use crate::config::BuildConfig;
use crate::error::BuildError;
use crate::sampler::{QuadtreeSampler, Sample, uniform_f32};
use brdf_core::geometry::{above_horizon, luminance, mirror, unit_direction};
use brdf_core::{Brdf, BrdfSample, DirectionError, DiskMap, Frame};
use glam::{Vec2, Vec3};
use rand_core::Rng;

/// The seed's `Codificador(entrante, normal)`: the local frame of a shading point, the
/// incident direction in it, and the map to the square (`deCartesianasAlCirculo` /
/// `deCirculoADireccion`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Encoder {
    frame: Frame,
    wi_local: Vec3,
    map: DiskMap,
}

impl Encoder {
    /// From a world incident direction and normal (any stable tangent). `wi` must lie in the
    /// normal's hemisphere.
    pub fn new(wi: Vec3, normal: Vec3, map: DiskMap) -> Result<Self, DirectionError> {
        Self::from_frame(wi, Frame::from_normal(normal)?, map)
    }

    /// From a world incident direction and a given frame (normal and tangent).
    pub fn from_frame(wi: Vec3, frame: Frame, map: DiskMap) -> Result<Self, DirectionError> {
        let wi_local = frame.to_local(unit_direction(wi)?);
        if !above_horizon(wi_local) {
            return Err(DirectionError::BelowHorizon);
        }
        Ok(Self {
            frame,
            wi_local,
            map,
        })
    }

    /// The frame.
    #[must_use]
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The incident direction in the local frame.
    #[must_use]
    pub fn wi_local(&self) -> Vec3 {
        self.wi_local
    }

    /// `deCartesianasAlCirculo`: a world direction → its point of the square.
    #[must_use]
    pub fn to_square(&self, w: Vec3) -> Vec2 {
        self.map.direction_to_square(self.frame.to_local(w))
    }

    /// `deCirculoADireccion`: a point of the square → the world direction (`None` outside the
    /// orthographic disk).
    #[must_use]
    pub fn to_direction(&self, p: Vec2) -> Option<Vec3> {
        self.map
            .square_to_direction(p)
            .map(|w| self.frame.to_world(w))
    }
}

/// The seed's `refleja(wi, normal) -> wo` (Fig. 5), the slow faithful path: encode, build the
/// quadtree for this `wi`, select a region, sample it; the returned sample is in **world**
/// coordinates. A model's delta part (all of a perfect mirror) is sampled analytically, chosen
/// against the continuous part by luminance. Renderers should keep a [`QuadtreeSampler`] per
/// `wi` instead of rebuilding per sample.
pub fn refleja<B: Brdf + ?Sized, R: Rng + ?Sized>(
    brdf: &B,
    wi: Vec3,
    normal: Vec3,
    rng: &mut R,
) -> Result<Option<Sample>, BuildError> {
    let enc = Encoder::new(wi, normal, DiskMap::Orthographic)?;
    let wi_l = enc.wi_local();
    let to_world = |s: Sample| Sample {
        wo: enc.frame().to_world(s.wo),
        ..s
    };
    let delta = luminance(brdf.delta_reflectance(wi_l));
    if brdf.is_delta() {
        let s = brdf.sample(
            wi_l,
            uniform_f32(rng),
            Vec2::new(uniform_f32(rng), uniform_f32(rng)),
        );
        return Ok(s.map(to_world));
    }
    let sampler = QuadtreeSampler::new(brdf, wi_l, BuildConfig::default())?;
    let rho = sampler.albedo() as f32;
    let p_delta = if delta > 0.0 {
        delta / (delta + rho)
    } else {
        0.0
    };
    if p_delta > 0.0 && uniform_f32(rng) < p_delta {
        let s = BrdfSample::delta(mirror(wi_l), brdf.delta_reflectance(wi_l), p_delta);
        return Ok(s.map(to_world));
    }
    Ok(sampler.sample(rng).map(|s| {
        let pdf = s.pdf * (1.0 - p_delta);
        to_world(Sample {
            pdf,
            weight: s.f * (s.wo.z / pdf),
            ..s
        })
    }))
}
