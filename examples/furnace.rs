//! A glossy sphere (Cook-Torrance, m = 0.1) under the benches' sky-and-sun environment,
//! rendered at **equal time** with cosine sampling and with the quadtree, side by side in one
//! PNG (left: cosine, right: quadtree), plus the RMSE of each against a high-sample reference.
//!
//! `cargo run --release --example furnace [-- OUT.png]` (default `furnace.png`).
//!
//! The quadtree side uses the baked sampler (SPEC §7), baked once for the material inside the
//! timed render: each pixel asks it for a light direction given its own view direction
//! ([`Role::Radiance`], in the pixel's world frame through [`WorldBsdf`]); its pdf is the exact
//! density of what it drew at that view direction, so the estimate is unbiased.

use brdf_sampling::Frame;
use brdf_sampling::bench::Environment;
use brdf_sampling::geometry::{luminance, spherical_direction};
use brdf_sampling::glam::{Vec2, Vec3};
use brdf_sampling::quadtree_sampler::{BakeConfig, BakedSampler, Role, WorldBsdf, uniform_f32};
use brdf_sampling::{Brdf, registry, warp};
use rand_core::SeedableRng;
use std::sync::Arc;
use std::time::Instant;

const SIZE: u32 = 160;
const SPP_QUADTREE: u32 = 64;
const SPP_REFERENCE: u32 = 1024;

/// An orthographic camera looking at the unit sphere from `eye`; world up is +z, as the
/// environment's.
struct Camera {
    eye: Vec3,
    right: Vec3,
    up: Vec3,
}

impl Camera {
    fn new() -> Self {
        let eye = spherical_direction(70f32.to_radians(), -90f32.to_radians());
        let right = Vec3::Z.cross(eye).normalize();
        Self {
            eye,
            right,
            up: eye.cross(right),
        }
    }

    /// The sphere's normal seen through pixel (px, py), or `None` off the sphere (and in a
    /// thin band at its silhouette, where wi is grazing).
    fn normal(&self, px: u32, py: u32) -> Option<Vec3> {
        let u = 2.0 * (px as f32 + 0.5) / SIZE as f32 - 1.0;
        let v = 1.0 - 2.0 * (py as f32 + 0.5) / SIZE as f32;
        let r2 = u * u + v * v;
        (r2 < 0.98)
            .then(|| (u * self.right + v * self.up + (1.0 - r2).sqrt() * self.eye).normalize())
    }
}

/// Renders with `spp` samples per pixel; `quadtree` chooses the sampler. Returns the
/// luminance images under `env` and under its sky alone (the same samples), and the seconds
/// it took.
fn render(
    brdf: &Arc<dyn Brdf>,
    env: &Environment,
    spp: u32,
    quadtree: bool,
    seed: u64,
) -> ([Vec<f64>; 2], f64) {
    let sky = Environment {
        sun_radiance: 0.0,
        ..*env
    };
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let t0 = Instant::now();
    // Baked once per material, inside the timed part.
    let baked =
        quadtree.then(|| BakedSampler::new(brdf.clone(), BakeConfig::default()).expect("a bake"));
    let mut img = [
        vec![0.0f64; (SIZE * SIZE) as usize],
        vec![0.0f64; (SIZE * SIZE) as usize],
    ];
    let camera = Camera::new();
    for py in 0..SIZE {
        for px in 0..SIZE {
            let Some(n) = camera.normal(px, py) else {
                continue;
            };
            let frame = Frame::from_normal(n).expect("a unit normal");
            let view = camera.eye;
            if frame.to_local(view).z <= 1e-4 {
                continue;
            }
            let bsdf = baked
                .as_ref()
                .map(|b| WorldBsdf::new(b, n, None).expect("a unit normal"));
            let mut sum = [0.0f64; 2];
            for _ in 0..spp {
                let uc = uniform_f32(&mut rng);
                let u = Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng));
                // (direction toward the light, world; estimator weight f·cos/pdf)
                let (light, w) = if let Some(bsdf) = &bsdf {
                    match bsdf.sample(Role::Radiance, view, uc, u, &mut rng) {
                        Ok(Some(s)) => (s.wo, f64::from(luminance(s.weight))),
                        _ => continue,
                    }
                } else {
                    let wo = warp::sample_cosine_hemisphere(u);
                    let pdf = warp::cosine_hemisphere_pdf(wo.z);
                    if pdf.is_nan() || pdf <= 0.0 || wo.z <= 0.0 {
                        continue;
                    }
                    let f = f64::from(luminance(brdf.eval(wo, frame.to_local(view))));
                    (frame.to_world(wo), f * f64::from(wo.z) / f64::from(pdf))
                };
                sum[0] += w * env.radiance(light);
                sum[1] += w * sky.radiance(light);
            }
            for k in 0..2 {
                img[k][(py * SIZE + px) as usize] = sum[k] / f64::from(spp);
            }
        }
    }
    (img, t0.elapsed().as_secs_f64())
}

fn rmse(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    (a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>() / n).sqrt()
}

fn tone(v: f64) -> u8 {
    let x = v * 0.8;
    let x = x / (1.0 + x);
    (x.powf(1.0 / 2.2) * 255.0).round().clamp(0.0, 255.0) as u8
}

fn main() {
    let out = std::env::args()
        .nth(1)
        .unwrap_or_else(|| "furnace.png".into());
    let brdf: Arc<dyn Brdf> = registry::create("cook-torrance", ["m=0.1"])
        .expect("a model")
        .into();
    let env = Environment::default();
    let (quad, t_quad) = render(&brdf, &env, SPP_QUADTREE, true, 1);
    // Cosine gets the same time: its samples per pixel from an 8-spp timing run.
    let (_, t_eight) = render(&brdf, &env, 8, false, 2);
    let spp_cos = ((8.0 * t_quad / t_eight).floor() as u32).max(1);
    let (cos, t_cos) = render(&brdf, &env, spp_cos, false, 3);
    let (reference, _) = render(&brdf, &env, SPP_REFERENCE, true, 4);
    println!(
        "cosine: {spp_cos} spp in {t_cos:.2} s; quadtree: {SPP_QUADTREE} spp in {t_quad:.2} s \
         (its bake included)"
    );
    for (k, what) in ["sky and sun", "sky alone"].iter().enumerate() {
        let (e_cos, e_quad) = (rmse(&cos[k], &reference[k]), rmse(&quad[k], &reference[k]));
        println!(
            "{what}: RMSE cosine {e_cos:.4}, quadtree {e_quad:.4}; MSE ratio {:.1}, \
             efficiency ratio (MSE × time) {:.1}",
            (e_cos / e_quad).powi(2),
            (e_cos * e_cos * t_cos) / (e_quad * e_quad * t_quad)
        );
    }
    let (cos, quad) = (&cos[0], &quad[0]);
    let gap = 8;
    let mut png = image::RgbImage::from_pixel(2 * SIZE + gap, SIZE, image::Rgb([0, 0, 0]));
    for (k, img) in [cos, quad].into_iter().enumerate() {
        for py in 0..SIZE {
            for px in 0..SIZE {
                let v = tone(img[(py * SIZE + px) as usize]);
                png.put_pixel(k as u32 * (SIZE + gap) + px, py, image::Rgb([v, v, v]));
            }
        }
    }
    png.save(&out).expect("write the PNG");
    println!("wrote {out} (left: cosine, right: quadtree)");
}
