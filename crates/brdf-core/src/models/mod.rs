//! The models of MODELS.md, one file each, plus the lobe helpers they share.

mod blinn_phong;
mod cook_torrance;
mod htsg;
mod lambert;
mod lewis_phong;
pub mod merl;
mod mirror;
mod oren_nayar;
mod phong;
mod poulin_fournier;
mod schlick;
mod strauss;
mod ward;

pub use blinn_phong::BlinnPhong;
pub use cook_torrance::CookTorrance;
pub use htsg::{HTSG_SERIES_LIMIT, Htsg, conductor_fresnel, htsg_sum};
pub use lambert::Lambert;
pub use lewis_phong::LewisPhong;
pub use merl::{Merl, MerlData, MerlLookup};
pub use mirror::Mirror;
pub use oren_nayar::OrenNayar;
pub use phong::Phong;
pub use poulin_fournier::{PoulinFournier, Visible};
pub use schlick::Schlick;
pub use strauss::{Strauss, strauss_fresnel, strauss_shadow};
pub use ward::Ward;

use crate::brdf::{Brdf, BrdfSample};
use crate::geometry::{above_horizon, luminance};
use crate::warp::{sample_cosine_hemisphere, sample_power_cosine64};
use core::f64::consts::FRAC_1_PI;
use glam::{DVec3, Vec2, Vec3};

/// The probability of choosing the diffuse lobe given the two lobes' (approximate) albedos;
/// 1 when both are 0 (the sample is then scored 0 anyway).
#[inline]
pub(crate) fn diffuse_probability(diffuse: Vec3, lobe: Vec3) -> f64 {
    let (d, l) = (f64::from(luminance(diffuse)), f64::from(luminance(lobe)));
    if d + l > 0.0 { d / (d + l) } else { 1.0 }
}

/// The diffuse-or-lobe mixture sampler shared by the glossy models: with probability
/// `p_diffuse` a cosine-weighted direction, else `lobe(u)`. The returned pdf is `brdf.pdf`,
/// so sample and pdf agree by construction.
#[inline]
pub(crate) fn sample_mixture<B: Brdf + ?Sized>(
    brdf: &B,
    wi: Vec3,
    uc: f32,
    u: Vec2,
    p_diffuse: f64,
    lobe: impl FnOnce(Vec2) -> Option<Vec3>,
) -> Option<BrdfSample> {
    if !above_horizon(wi) {
        return None;
    }
    // A uniform outside [0, 1), or NaN, is read as the nearest value inside it: below 0 it
    // chose the diffuse lobe where that has probability 0 (Strauss at transparency 1,
    // Schlick), whose directions the mixture's pdf barely covers: f and pdf both about
    // 10⁻⁴³ near the horizon, and a weight f·(cos/pdf) that overflowed to ∞. Valid
    // uniforms choose as before.
    let c = f64::from(uc);
    let c = if c >= 0.0 {
        c.min(1.0 - f64::EPSILON)
    } else {
        0.0
    };
    let wo = if c < p_diffuse {
        sample_cosine_hemisphere(u)
    } else {
        lobe(u)?
    };
    BrdfSample::continuous(wo, brdf.eval(wi, wo), brdf.pdf_continuous(wi, wo))
}

/// The f64 unit pair for an analytic pdf (wi above the horizon, wo above it), else `None`.
/// Callers pass wi already lifted to the grazing floor, exactly as their samplers lift it
/// ([`crate::geometry::lift_incident`], once, at the top of `pdf_continuous`); wo is taken
/// as given (the pdf is a density in wo).
#[inline]
pub(crate) fn pdf_pair(wi: Vec3, wo: Vec3) -> Option<(DVec3, DVec3)> {
    crate::geometry::unit_pair(wi, wo)
}

/// Cosine-hemisphere density in f64, per unit solid angle.
#[inline]
pub(crate) fn cosine_pdf64(wo: DVec3) -> f64 {
    wo.z.max(0.0) * FRAC_1_PI
}

/// Reflects `wi` about the unit half vector `h`: the wo with half vector h. `None` when h faces
/// away from wi or wo falls below the horizon.
#[inline]
pub(crate) fn reflect_about_half(wi: Vec3, h: DVec3) -> Option<Vec3> {
    let wi = wi.as_dvec3().normalize();
    let u = wi.dot(h);
    if u <= 0.0 {
        return None;
    }
    let wo = 2.0 * u * h - wi;
    (wo.z > 0.0).then(|| wo.normalize().as_vec3())
}

/// The unit half vector of two f64 unit directions in the upper hemisphere (never degenerate
/// there) and u = wi·h.
#[inline]
pub(crate) fn half64(wi: DVec3, wo: DVec3) -> (DVec3, f64) {
    let h = (wi + wo).normalize();
    (h, wi.dot(h))
}

/// The power-cosine lobe about the mirror direction shared by `phong` and `lewis-phong`:
/// cos^n α with cos α = max(0, r(wi)·wo), its sampler and its pdf.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MirrorLobe {
    pub n: f64,
}

impl MirrorLobe {
    /// cos^n α for f64 unit vectors (accurate for n up to 10⁵).
    #[inline]
    pub fn value(&self, wi: DVec3, wo: DVec3) -> f64 {
        let r = DVec3::new(-wi.x, -wi.y, wi.z);
        crate::geometry::cos_power(r, wo, self.n)
    }

    /// Density of [`MirrorLobe::sample`] per unit solid angle: (n+1)/(2π) cos^n α, 0 where
    /// cos α ≤ 0; for n = 0, cos θo/π (see `sample`).
    #[inline]
    pub fn pdf(&self, wi: DVec3, wo: DVec3) -> f64 {
        if self.n == 0.0 {
            return cosine_pdf64(wo);
        }
        (self.n + 1.0) * 0.5 * FRAC_1_PI * self.value(wi, wo)
    }

    /// A power-cosine direction about r(wi); `None` below the horizon. For n = 0 the lobe is
    /// constant over the whole hemisphere (pow(0, 0) = 1: MODELS.md's convention), also
    /// where cos α ≤ 0, which a lobe about r(wi) never reaches: f·cos is then ∝ cos θo, and
    /// the direction is cosine-distributed about the normal.
    #[inline]
    pub fn sample(&self, wi: Vec3, u: Vec2) -> Option<Vec3> {
        if self.n == 0.0 {
            let wo = crate::warp::sample_cosine_hemisphere(u);
            return (wo.z > 0.0).then_some(wo);
        }
        let wi = wi.as_dvec3().normalize();
        let r = DVec3::new(-wi.x, -wi.y, wi.z);
        let (x, y) = r.any_orthonormal_pair();
        let l = sample_power_cosine64(u, self.n);
        let wo = x * l.x + y * l.y + r * l.z;
        (wo.z > 0.0).then(|| wo.normalize().as_vec3())
    }
}
