//! Views of a [`BakedSampler`]: at one incident direction as a [`crate::DirectionSampler`]
//! ([`BakedAt`], what the CLI's `--baked` and the validation use), in world coordinates
//! around a shading frame ([`WorldBsdf`], pbrt's BSDF around a BxDF), and the hidden negative
//! control whose reported pdf drops a neighbour ([`BrokenPdf`]).

use crate::baked::{BakedMode, BakedSampler, Role};
use crate::baked_mixture::Components;
use crate::error::BakedError;
use crate::sampler::Sample;
use alloc::sync::Arc;
use glam::{Vec2, Vec3};
use rand_core::Rng;

/// A [`BakedSampler`] at one incident direction, as a [`crate::DirectionSampler`].
#[derive(Clone, Copy, Debug)]
pub struct BakedAt<'a> {
    pub(crate) baked: &'a BakedSampler,
    pub(crate) wi: Vec3,
}

impl crate::DirectionSampler for BakedAt<'_> {
    fn name(&self) -> &'static str {
        match self.baked.mode {
            BakedMode::Rejection => "baked rejection",
            BakedMode::Warp => "baked warp",
        }
    }

    fn sample_with(&self, uc: f32, u: Vec2, rng: &mut dyn Rng) -> Option<Sample> {
        self.baked
            .sample_unit(Role::Importance, self.wi, uc, u, rng)
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        if !wo.is_finite() {
            return 0.0;
        }
        self.baked.pdf_unit(Role::Importance, self.wi, wo)
    }

    fn density_hints(&self) -> crate::DensityHints {
        self.baked.density_hints_unit(Role::Importance, self.wi)
    }
}

/// A deliberately wrong sampler for negative controls: samples like its [`BakedSampler`]
/// but reports a pdf that leaves out the first neighbour's share (renormalised over the
/// others), as a mixture bug would.
#[doc(hidden)]
#[derive(Debug)]
pub struct BrokenPdf(pub(crate) Arc<BakedSampler>);

impl BrokenPdf {
    /// The wrong pdf at one wi.
    #[must_use]
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        let b = &self.0;
        let mut comps = Components::new();
        let n = b.components(b.mode, &b.forward, wi, &mut comps);
        if n < 2 {
            return b.pdf_unit(Role::Importance, wi, wo);
        }
        // The mixture's own expression over the other neighbours, renormalised.
        let rest: f64 = comps[1..n].iter().map(|c| c.weight).sum();
        for c in &mut comps[1..n] {
            c.weight /= rest;
        }
        b.pdf_of(b.mode, &b.forward, false, &comps[1..n], wo, None)
    }

    /// The sampler at one wi with the wrong pdf.
    #[must_use]
    pub fn at(&self, wi: Vec3) -> BrokenAt<'_> {
        BrokenAt {
            broken: self,
            wi: wi.normalize(),
        }
    }
}

/// [`BrokenPdf`] at one wi.
#[doc(hidden)]
#[derive(Debug)]
pub struct BrokenAt<'a> {
    broken: &'a BrokenPdf,
    wi: Vec3,
}

impl crate::DirectionSampler for BrokenAt<'_> {
    fn name(&self) -> &'static str {
        "broken baked"
    }

    fn sample_with(&self, uc: f32, u: Vec2, rng: &mut dyn Rng) -> Option<Sample> {
        let s = self
            .broken
            .0
            .sample_unit(Role::Importance, self.wi, uc, u, rng)?;
        let pdf = self.pdf(s.wo);
        (pdf > 0.0).then(|| s.with_pdf(pdf))
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        self.broken.pdf(self.wi, wo)
    }

    fn density_hints(&self) -> crate::DensityHints {
        self.broken.0.density_hints_unit(Role::Importance, self.wi)
    }
}

/// A [`BakedSampler`] in a world-space shading frame, like pbrt's `BSDF` around a `BxDF`:
/// directions in and out are world vectors; the frame is a normal and an optional tangent
/// (the anisotropy axis x). Cheap to make per shading point.
#[derive(Clone, Copy, Debug)]
pub struct WorldBsdf<'a> {
    baked: &'a BakedSampler,
    frame: brdf_core::Frame,
}

impl<'a> WorldBsdf<'a> {
    /// A shading point with normal `n` and, for anisotropic models, tangent `t` (made
    /// orthogonal to `n`); without a tangent any stable one is chosen.
    pub fn new(baked: &'a BakedSampler, n: Vec3, t: Option<Vec3>) -> Result<Self, BakedError> {
        let frame = match t {
            Some(t) => brdf_core::Frame::from_normal_tangent(n, t)?,
            None => brdf_core::Frame::from_normal(n)?,
        };
        Ok(Self { baked, frame })
    }

    /// The shading frame.
    #[must_use]
    pub fn frame(&self) -> &brdf_core::Frame {
        &self.frame
    }

    /// [`BakedSampler::sample_as`] in world directions (the sample's `wo` is world too).
    pub fn sample<R: Rng + ?Sized>(
        &self,
        role: Role,
        given: Vec3,
        uc: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Result<Option<Sample>, BakedError> {
        let s = self
            .baked
            .sample_as(role, self.frame.to_local(given), uc, u, rng)?;
        Ok(s.map(|s| Sample {
            wo: self.frame.to_world(s.wo),
            ..s
        }))
    }

    /// [`BakedSampler::pdf_as`] in world directions, **per unit solid angle**.
    pub fn pdf(&self, role: Role, given: Vec3, sampled: Vec3) -> Result<f32, BakedError> {
        self.baked.pdf_as(
            role,
            self.frame.to_local(given),
            self.frame.to_local(sampled),
        )
    }

    /// [`BakedSampler::eval_as`] in world directions (0 below the surface).
    pub fn eval(&self, role: Role, given: Vec3, sampled: Vec3) -> Result<Vec3, BakedError> {
        self.baked.eval_as(
            role,
            self.frame.to_local(given),
            self.frame.to_local(sampled),
        )
    }
}
