//! Views of a [`BakedSampler`]: prepared at one given direction for a role ([`BakedPoint`],
//! a path vertex's sample, f_r and pdfs), at one incident direction as a
//! [`crate::DirectionSampler`] ([`BakedAt`], what the CLI's `--baked` and the validation
//! use), in world coordinates around a shading frame ([`WorldBsdf`], pbrt's BSDF around a
//! BxDF, and [`WorldPoint`], prepared), and the hidden negative control whose reported pdf
//! drops a neighbour ([`BrokenPdf`]).

use crate::baked::{BakedMode, BakedSampler, Role};
use crate::baked_mixture::{Components, Query};
use crate::error::BakedError;
use crate::sampler::Sample;
use alloc::sync::Arc;
use glam::{Vec2, Vec3};
use rand_core::Rng;

/// A [`BakedSampler`] prepared at one given direction for one role
/// ([`BakedSampler::point`]): the direction checked, its delta probability and its mixture
/// (the neighbour trees, their weights and maps) found once, for any number of samples,
/// pdfs and evaluations there. A path vertex makes one and asks it for a sample and, at a
/// light sample's direction, f_r and the pdf (multiple importance sampling); each answer is
/// bit-identical to the [`BakedSampler`] method of the same name with `_as` at that
/// direction, and costs what that method costs less the mixture's set-up.
///
/// Directions are local (z the normal); `sampled` must be finite and non-zero (a typed
/// error otherwise), and gets a pdf and f_r of 0 below the horizon.
#[derive(Clone, Debug)]
pub struct BakedPoint<'a> {
    pub(crate) baked: &'a BakedSampler,
    /// The model's delta probability at the given direction.
    pub(crate) delta: f32,
    pub(crate) query: Query,
}

impl BakedPoint<'_> {
    /// The role it answers for.
    #[must_use]
    pub fn role(&self) -> Role {
        self.query.role
    }

    /// The given direction, unit (as checked and normalised).
    #[must_use]
    pub fn given(&self) -> Vec3 {
        self.query.given
    }

    /// The mode it samples in (the sampler's when it was prepared).
    #[must_use]
    pub fn mode(&self) -> BakedMode {
        self.query.mode
    }

    /// The probability that [`BakedPoint::sample`] draws the model's Dirac lobe (0 for a
    /// model without one).
    #[must_use]
    pub fn delta_probability(&self) -> f32 {
        self.delta
    }

    /// [`BakedSampler::sample_as`] here: the whole model, the delta lobe included. `None`
    /// when the draw carries nothing (the estimator scores 0).
    pub fn sample<R: Rng + ?Sized>(&self, uc: f32, u: Vec2, rng: &mut R) -> Option<Sample> {
        let b = self.baked;
        b.whole_sample(self.query.given, self.delta, uc, |uc| {
            b.query_sample(&self.query, uc, u, rng)
        })
    }

    /// [`BakedSampler::sample_continuous_as`] here: the continuous part alone.
    pub fn sample_continuous<R: Rng + ?Sized>(
        &self,
        uc: f32,
        u: Vec2,
        rng: &mut R,
    ) -> Option<Sample> {
        self.baked.query_sample(&self.query, uc, u, rng)
    }

    /// [`BakedSampler::pdf_as`] of `sampled`, **per unit solid angle**: the density of a
    /// continuous sample of [`BakedPoint::sample`] there.
    pub fn pdf(&self, sampled: Vec3) -> Result<f32, BakedError> {
        Ok((1.0 - self.delta) * self.pdf_continuous(sampled)?)
    }

    /// [`BakedSampler::pdf_continuous_as`] of `sampled`, **per unit solid angle**: the
    /// density of [`BakedPoint::sample_continuous`] there.
    pub fn pdf_continuous(&self, sampled: Vec3) -> Result<f32, BakedError> {
        brdf_core::geometry::unit_direction(sampled)?;
        Ok(self.baked.query_pdf(&self.query, sampled))
    }

    /// [`BakedSampler::eval_as`] at `sampled`: f_r's continuous part (RGB, 1/sr, no cosine)
    /// in the role's argument order.
    pub fn eval(&self, sampled: Vec3) -> Result<Vec3, BakedError> {
        brdf_core::geometry::unit_direction(sampled)?;
        Ok(self
            .baked
            .eval_unit(self.query.role, self.query.given, sampled))
    }

    /// f_r and the pdf at `sampled` ([`BakedPoint::eval`], [`BakedPoint::pdf`]) in one
    /// call: what a light sample needs for multiple importance sampling.
    pub fn eval_pdf(&self, sampled: Vec3) -> Result<(Vec3, f32), BakedError> {
        Ok((self.eval(sampled)?, self.pdf(sampled)?))
    }
}

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

    /// [`BakedSampler::point`] at a world `given` direction: this shading point prepared for
    /// one role and one given direction (a path vertex's), in world directions.
    pub fn point(&self, role: Role, given: Vec3) -> Result<WorldPoint<'a>, BakedError> {
        Ok(WorldPoint {
            frame: self.frame,
            point: self.baked.point(role, self.frame.to_local(given))?,
        })
    }
}

/// A [`BakedPoint`] in world directions ([`WorldBsdf::point`]): the same answers as the
/// [`WorldBsdf`] methods at its given direction, bit for bit, with the mixture there found
/// once.
#[derive(Clone, Debug)]
pub struct WorldPoint<'a> {
    frame: brdf_core::Frame,
    point: BakedPoint<'a>,
}

impl<'a> WorldPoint<'a> {
    /// The same point in the local frame.
    #[must_use]
    pub fn local(&self) -> &BakedPoint<'a> {
        &self.point
    }

    /// The shading frame.
    #[must_use]
    pub fn frame(&self) -> &brdf_core::Frame {
        &self.frame
    }

    /// [`WorldBsdf::sample`] at this point's given direction (the sample's `wo` is world).
    pub fn sample<R: Rng + ?Sized>(&self, uc: f32, u: Vec2, rng: &mut R) -> Option<Sample> {
        self.point.sample(uc, u, rng).map(|s| Sample {
            wo: self.frame.to_world(s.wo),
            ..s
        })
    }

    /// [`WorldBsdf::pdf`] of a world `sampled`, **per unit solid angle**.
    pub fn pdf(&self, sampled: Vec3) -> Result<f32, BakedError> {
        self.point.pdf(self.frame.to_local(sampled))
    }

    /// [`WorldBsdf::eval`] at a world `sampled` (0 below the surface).
    pub fn eval(&self, sampled: Vec3) -> Result<Vec3, BakedError> {
        self.point.eval(self.frame.to_local(sampled))
    }

    /// f_r and the pdf at a world `sampled` in one call (a light sample's MIS).
    pub fn eval_pdf(&self, sampled: Vec3) -> Result<(Vec3, f32), BakedError> {
        self.point.eval_pdf(self.frame.to_local(sampled))
    }
}
