//! The seed's `refleja` (Fig. 5): the build-select-sample convenience in world coordinates.
//! The seed's `Codificador` (Fig. 1) is two types of brdf-core: [`Frame`] (world ↔ local) and
//! [`DiskMap`] (local ↔ the square: `deCartesianasAlCirculo` / `deCirculoADireccion`).

use crate::config::BuildConfig;
use crate::error::BuildError;
use crate::sampler::{QuadtreeSampler, Sample, uniform_f32};
#[cfg(doc)]
use brdf_core::DiskMap;
use brdf_core::geometry::{above_horizon, luminance, mirror, unit_direction};
use brdf_core::{Brdf, BrdfSample, DirectionError, Frame};
use glam::{Vec2, Vec3};
use rand_core::Rng;

/// The seed's `refleja(wi, normal) -> wo` (Fig. 5), the slow faithful path: encode (the
/// normal's [`Frame`]; `wi` must lie in its hemisphere), build the
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
    let frame = Frame::from_normal(normal)?;
    let wi_l = frame.to_local(unit_direction(wi)?);
    if !above_horizon(wi_l) {
        return Err(DirectionError::BelowHorizon.into());
    }
    let to_world = |s: Sample| Sample {
        wo: frame.to_world(s.wo),
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
    Ok(sampler
        .sample(rng)
        .map(|s| to_world(s.with_pdf(s.pdf * (1.0 - p_delta)))))
}
