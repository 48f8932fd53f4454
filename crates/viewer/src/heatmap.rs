//! f_r(wi, ·) as an image over the square [−1,1]² (orthographic map: pixel = (x, y) of wo).

use brdf_core::{Brdf, DiskMap};
use eframe::egui::{Color32, ColorImage};
use glam::{Vec2, Vec3};

/// Background for the square's corners outside the disk.
pub const OUTSIDE: Color32 = Color32::from_rgb(24, 24, 28);

/// The luminance of f_r(wi, ·) at `res`² pixel centres, normalised by its maximum (linear, or
/// log over four decades), through a perceptual colour ramp. Row 0 is y = +1 (image top).
pub fn luminance_map(brdf: &dyn Brdf, wi: Vec3, res: usize, log: bool) -> ColorImage {
    let mut values = vec![f32::NAN; res * res];
    for (k, v) in values.iter_mut().enumerate() {
        let (i, j) = (k % res, k / res);
        let p = Vec2::new(
            (i as f32 + 0.5) / res as f32 * 2.0 - 1.0,
            1.0 - (j as f32 + 0.5) / res as f32 * 2.0,
        );
        if let Some(wo) = DiskMap::Orthographic.square_to_direction(p) {
            *v = brdf.eval_luminance(wi, wo);
        }
    }
    let max = values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f32, f32::max);
    let pixels = values
        .iter()
        .map(|&v| {
            if v.is_nan() {
                return OUTSIDE;
            }
            let t = if max <= 0.0 {
                0.0
            } else if log {
                ((v / max).max(1e-4).log10() / 4.0 + 1.0).clamp(0.0, 1.0)
            } else {
                (v / max).clamp(0.0, 1.0)
            };
            ramp(t)
        })
        .collect();
    ColorImage::new([res, res], pixels)
}

/// Viridis, t ∈ [0, 1].
fn ramp(t: f32) -> Color32 {
    let [r, g, b] = quadtree_sampler::colormap::viridis(t);
    Color32::from_rgb(r, g, b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use brdf_core::registry;

    #[test]
    fn the_brightest_pixel_is_the_mirror_direction_and_corners_are_empty() {
        let phong = registry::create("phong", ["n=500", "kd=0"]).unwrap();
        let wi = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
        let res = 65;
        let img = luminance_map(&*phong, wi, res, false);
        assert_eq!(img.pixels[0], OUTSIDE, "corner (-1, 1) is outside the disk");
        let brightest = (0..res * res).max_by_key(|&k| img.pixels[k].g()).unwrap();
        let (i, j) = (brightest % res, brightest / res);
        // The mirror direction r(wi) = (-0.5, 0, ·): pixel column 16, row 32 of 65.
        assert_eq!((i, j), (16, 32));
    }
}
