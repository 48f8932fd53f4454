//! A renderer's own GGX reflection sampler, written without this workspace's models, checked
//! by `brdf-validate` against its own f·cos: what a renderer author does with the crate.
//!
//! `cargo run --release -p brdf-validate --example ggx` (prints one report per case).
//!
//! The BSDF: GGX (Trowbridge–Reitz) normals, Smith's separable shadowing, Schlick's Fresnel;
//! sampled by drawing the half vector ∝ D(h)·cos θh and reflecting wi about it, so the pdf
//! of wo is D(h)·cos θh / (4 |wo·h|) per solid angle.

use brdf_validate::glam::{Vec2, Vec3};
use brdf_validate::{FnSampler, Settings, check};
use std::f32::consts::PI;

/// GGX with roughness `alpha` and normal-incidence reflectance `f0`.
#[derive(Clone, Copy, Debug)]
pub struct Ggx {
    /// Roughness α (the slope distribution's width).
    pub alpha: f32,
    /// Fresnel reflectance at normal incidence.
    pub f0: f32,
}

impl Ggx {
    /// The normal distribution D(h).
    fn d(&self, h: Vec3) -> f32 {
        let a2 = self.alpha * self.alpha;
        let t = h.z * h.z * (a2 - 1.0) + 1.0;
        a2 / (PI * t * t)
    }

    /// Smith's masking of one direction.
    fn g1(&self, w: Vec3) -> f32 {
        let tan2 = (1.0 - w.z * w.z).max(0.0) / (w.z * w.z);
        2.0 / (1.0 + (1.0 + self.alpha * self.alpha * tan2).sqrt())
    }

    /// f_r(wi, wo)·cos θo, per unit solid angle (0 below the horizon).
    #[must_use]
    pub fn f_cos(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return 0.0;
        }
        let h = (wi + wo).normalize();
        let fresnel = self.f0 + (1.0 - self.f0) * (1.0 - wi.dot(h).clamp(0.0, 1.0)).powi(5);
        self.d(h) * self.g1(wi) * self.g1(wo) * fresnel / (4.0 * wi.z)
    }

    /// Draws wo from uniforms `u`: the half vector ∝ D(h)·cos θh, then wi reflected about it;
    /// `None` below the horizon. Returns wo and its pdf per unit solid angle.
    #[must_use]
    pub fn sample(&self, wi: Vec3, u: Vec2) -> Option<(Vec3, f32)> {
        let tan2 = self.alpha * self.alpha * u.x / (1.0 - u.x).max(f32::MIN_POSITIVE);
        let cos_t = 1.0 / (1.0 + tan2).sqrt();
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let phi = 2.0 * PI * u.y;
        let h = Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t);
        let wo = 2.0 * wi.dot(h) * h - wi;
        (wo.z > 0.0).then(|| (wo, self.pdf(wi, wo)))
    }

    /// The density of [`Ggx::sample`] at wo, per unit solid angle.
    #[must_use]
    pub fn pdf(&self, wi: Vec3, wo: Vec3) -> f32 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        let h = (wi + wo).normalize();
        self.d(h) * h.z / (4.0 * wo.dot(h).abs())
    }
}

/// The incident direction at polar angle `theta_deg` in the xz plane.
#[must_use]
pub fn incident(theta_deg: f32) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

fn main() {
    for (alpha, theta) in [(0.5, 30.0), (0.2, 60.0), (0.05, 75.0)] {
        let ggx = Ggx { alpha, f0: 0.04 };
        let wi = incident(theta);
        // The five lines of a check: the sampler as two closures, f·cos as an oracle, the
        // mirror direction as a peak hint, and the settings (here judged on the sampler's own
        // pdf, since this sampler is not exactly ∝ f·cos, plus its mean weight).
        let sampler = FnSampler::new("ggx", |_uc, u| ggx.sample(wi, u), |wo| ggx.pdf(wi, wo));
        let fcos = |wo: Vec3| f64::from(ggx.f_cos(wi, wo));
        let mirror = Vec3::new(-wi.x, -wi.y, wi.z);
        let settings = Settings {
            against: brdf_validate::Against::OwnPdf,
            mean_weight: true,
            ..Settings::default()
        };
        let report = check(&sampler, fcos, &[mirror], &settings).expect("valid settings");
        println!("GGX α = {alpha}, θi = {theta}°: {report}");
    }
}
