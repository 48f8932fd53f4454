//! Multiple importance sampling in a renderer's shape: direct light at one shading point of a
//! glossy material under a sky with a small, bright sun just off the mirror direction (where
//! BSDF sampling rarely finds the sun and light sampling rarely finds the lobe), estimated by
//! - **BSDF sampling**: the baked sampler (SPEC §7) draws the light direction given the view
//!   direction ([`Role::Radiance`]);
//! - **light sampling**: half the samples uniformly in the sun's cone, half cosine-weighted
//!   on the sky (pdf = ½·cone pdf + ½·cos θ/π);
//! - **MIS**: one sample of each, combined with the balance heuristic, which needs the baked
//!   sampler's pdf at the light sample's direction: `point(Role::Radiance, view)` prepares
//!   the vertex's material once, and its `pdf(light)` answers as `pdf_as(Role::Radiance,
//!   view, light)` would, bit for bit.
//!
//! It prints each estimator's mean ± standard error against a reference (10⁷ MIS pairs,
//! another seed), its time per sample, and its MSE at equal time relative to MIS.
//!
//! `cargo run --release --example mis`

use brdf_sampling::bench::Environment;
use brdf_sampling::geometry::{luminance, spherical_direction};
use brdf_sampling::glam::{Vec2, Vec3};
use brdf_sampling::quadtree_sampler::{BakeConfig, BakedSampler, Role, uniform_f32};
use brdf_sampling::{Brdf, Frame, registry, warp};
use rand_core::SeedableRng;
use std::sync::Arc;
use std::time::Instant;

/// The sun: a cone of half-angle `cos_r` around `dir`, sampled uniformly in solid angle.
struct Sun {
    frame: Frame,
    cos_r: f32,
}

impl Sun {
    fn sample(&self, u: Vec2) -> Vec3 {
        let z = 1.0 - u.x * (1.0 - self.cos_r);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * u.y;
        self.frame
            .to_world(Vec3::new(r * phi.cos(), r * phi.sin(), z))
            .normalize()
    }
    fn pdf(&self, w: Vec3) -> f32 {
        if w.dot(self.frame.to_world(Vec3::Z)) >= self.cos_r {
            1.0 / (std::f32::consts::TAU * (1.0 - self.cos_r))
        } else {
            0.0
        }
    }
}

struct Scene {
    brdf: Arc<dyn Brdf>,
    baked: BakedSampler,
    env: Environment,
    sun: Sun,
    view: Vec3,
}

impl Scene {
    fn light_pdf(&self, w: Vec3) -> f32 {
        0.5 * self.sun.pdf(w) + 0.5 * warp::cosine_hemisphere_pdf(w.z.max(0.0))
    }
    fn sample_light(&self, uc: f32, u: Vec2) -> Vec3 {
        if uc < 0.5 {
            self.sun.sample(u)
        } else {
            warp::sample_cosine_hemisphere(u)
        }
    }
    /// f_r(light, view)·cos θ_light·L(light): the integrand.
    fn integrand(&self, light: Vec3) -> f64 {
        if light.z <= 0.0 {
            return 0.0;
        }
        let f = f64::from(luminance(self.brdf.eval(light, self.view)));
        f * f64::from(light.z) * self.env.radiance(light)
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Technique {
    Bsdf,
    Light,
    Mis,
}

/// One estimate of the integral from one sample (BSDF or light) or one pair (MIS).
fn one(scene: &Scene, t: Technique, rng: &mut rand_pcg::Pcg64) -> f64 {
    let mut u = || uniform_f32(rng);
    let (uc, ub) = (u(), Vec2::new(u(), u()));
    let (lc, lu) = (u(), Vec2::new(u(), u()));
    match t {
        // One question at the view direction: the sampler's own call.
        Technique::Bsdf => scene
            .baked
            .sample_as(Role::Radiance, scene.view, uc, ub, rng)
            .expect("a valid view direction")
            .map_or(0.0, |s| {
                f64::from(luminance(s.weight)) * scene.env.radiance(s.wo)
            }),
        Technique::Light => {
            let w = scene.sample_light(lc, lu);
            let p = scene.light_pdf(w);
            if p > 0.0 {
                scene.integrand(w) / f64::from(p)
            } else {
                0.0
            }
        }
        Technique::Mis => {
            // Balance heuristic, one sample per technique: each contributes g / (p_b + p_l).
            // Two questions at the view direction, a sample and the pdf at the light
            // sample's direction: the vertex's material prepared once for both (the view's
            // neighbour trees found once).
            let point = scene
                .baked
                .point(Role::Radiance, scene.view)
                .expect("a valid view direction");
            let mut sum = 0.0;
            if let Some(s) = point.sample(uc, ub, rng) {
                let p = f64::from(s.pdf) + f64::from(scene.light_pdf(s.wo));
                sum += scene.integrand(s.wo) / p;
            }
            let w = scene.sample_light(lc, lu);
            let pb = point.pdf(w).expect("a finite light direction");
            let p = f64::from(pb) + f64::from(scene.light_pdf(w));
            if p > 0.0 {
                sum += scene.integrand(w) / p;
            }
            sum
        }
    }
}

/// Mean, variance of one estimate, and seconds per estimate over `n` estimates.
fn run(scene: &Scene, t: Technique, n: u64, seed: u64) -> (f64, f64, f64) {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let (mut s, mut q) = (0.0, 0.0);
    let t0 = Instant::now();
    for _ in 0..n {
        let y = one(scene, t, &mut rng);
        s += y;
        q += y * y;
    }
    let secs = t0.elapsed().as_secs_f64() / n as f64;
    let m = s / n as f64;
    (m, q / n as f64 - m * m, secs)
}

fn main() {
    let brdf: Arc<dyn Brdf> = registry::create("lewis-phong", ["n=1000", "kd=0", "ks=0.9"])
        .expect("a model")
        .into();
    let view = spherical_direction(40f32.to_radians(), 25f32.to_radians());
    // The sun 3° from the mirror direction of the view, 0.5° in radius: as much light as the sky.
    let env = Environment {
        sun: spherical_direction(43f32.to_radians(), 205f32.to_radians()),
        sun_cos_radius: 0.5f32.to_radians().cos(),
        sun_radiance: 200.0,
    };
    let t0 = Instant::now();
    let baked = BakedSampler::new(brdf.clone(), BakeConfig::default()).expect("a bake");
    println!(
        "baked lewis-phong n=1000 in {:.2} s: {} trees, {} bytes",
        t0.elapsed().as_secs_f64(),
        baked.trees(),
        baked.bytes()
    );
    let sun = Sun {
        frame: Frame::from_normal(env.sun).expect("a unit direction"),
        cos_r: env.sun_cos_radius,
    };
    let scene = Scene {
        brdf,
        baked,
        env,
        sun,
        view,
    };
    let (reference, rv, _) = run(&scene, Technique::Mis, 10_000_000, 99);
    let se_ref = (rv / 1e7).sqrt();
    println!("reference (10⁷ MIS pairs): {reference:.6} ± {se_ref:.1e}");
    let n = 1_000_000;
    let mis = run(&scene, Technique::Mis, n, 1);
    println!(
        "| technique | mean ± SE | (mean − reference)/SE | ns per estimate | MSE at equal time / MIS's |"
    );
    println!("|---|---:|---:|---:|---:|");
    for (name, t, seed) in [
        ("BSDF sampling (baked)", Technique::Bsdf, 2),
        ("light sampling", Technique::Light, 3),
        ("MIS, balance heuristic", Technique::Mis, 1),
    ] {
        let (m, v, secs) = if t == Technique::Mis {
            mis
        } else {
            run(&scene, t, n, seed)
        };
        let se = (v / n as f64).sqrt();
        println!(
            "| {name} | {m:.6} ± {se:.1e} | {:+.2} | {:.0} | {:.2} |",
            (m - reference) / (se * se + se_ref * se_ref).sqrt(),
            secs * 1e9,
            (v * secs) / (mis.1 * mis.2)
        );
    }
}
