//! Pictures of one validation test for `brdf test --out`: a PNG of expected | observed |
//! difference over the disk (the EXR of the raw per-cell arrays is
//! `brdf_validate::Histogram::write_exr`).

use brdf_sampling::glam::Vec3;
use brdf_sampling::quadtree_sampler::colormap;
use brdf_sampling::validate::{CellGrid, Histogram};
use std::path::Path;

/// Side of one panel in pixels.
const PANEL: u32 = 256;
/// Margin around and between panels.
const MARGIN: u32 = 16;
/// Height of the colour bar under each panel.
const BAR: u32 = 10;
/// The standardised residual (n − e)/√e that saturates the difference map.
pub(crate) const RESIDUAL_RANGE: f64 = 4.0;

const BACKGROUND: [u8; 3] = [32, 32, 32];
/// Panel pixels outside the unit disk (directions that do not exist).
const OFF_DISK: [u8; 3] = [56, 56, 56];

/// A colour map: t ∈ [0, 1] → sRGB.
type ColourMap = fn(f32) -> [u8; 3];

/// One panel: per-cell values, the colour map, and the value range it spans.
type Panel<'a> = (&'a [f64], ColourMap, f64, f64);

/// The cell under every pixel of a panel (`None` off the disk); row 0 is the top (y = +1).
fn cell_map(grid: CellGrid) -> Vec<Option<usize>> {
    let mut cells = Vec::with_capacity((PANEL * PANEL) as usize);
    for j in 0..PANEL {
        for i in 0..PANEL {
            let x = -1.0 + 2.0 * (f64::from(i) + 0.5) / f64::from(PANEL);
            let y = 1.0 - 2.0 * (f64::from(j) + 0.5) / f64::from(PANEL);
            let r2 = x * x + y * y;
            cells.push(if r2 < 1.0 {
                grid.cell_of(Vec3::new(x as f32, y as f32, (1.0 - r2).sqrt() as f32))
            } else {
                None
            });
        }
    }
    cells
}

/// Writes the three panels side by side: expected counts, observed counts (one linear
/// viridis scale from 0 to the largest count of either), and (n − e)/√e on RdBu over
/// ±[`RESIDUAL_RANGE`]; a colour bar under each.
pub(crate) fn write_png(path: &Path, histogram: &Histogram) -> image::ImageResult<()> {
    let width = 3 * PANEL + 4 * MARGIN;
    let height = PANEL + BAR + 3 * MARGIN;
    let mut img = image::RgbImage::from_pixel(width, height, image::Rgb(BACKGROUND));
    let vmax = histogram.count_scale();
    let residual = histogram.residuals();
    let observed: Vec<f64> = histogram.observed.iter().map(|&o| o as f64).collect();
    let panels: [Panel<'_>; 3] = [
        (&histogram.expected, colormap::viridis, 0.0, vmax),
        (&observed, colormap::viridis, 0.0, vmax),
        (&residual, colormap::rdbu, -RESIDUAL_RANGE, RESIDUAL_RANGE),
    ];
    let cells = cell_map(histogram.grid);
    for (k, (values, map, lo, hi)) in panels.into_iter().enumerate() {
        let x0 = MARGIN + k as u32 * (PANEL + MARGIN);
        let t = |v: f64| (v - lo) / (hi - lo);
        for j in 0..PANEL {
            for i in 0..PANEL {
                let colour = match cells[(j * PANEL + i) as usize] {
                    Some(c) => map(t(values[c]) as f32),
                    None => OFF_DISK,
                };
                img.put_pixel(x0 + i, MARGIN + j, image::Rgb(colour));
            }
        }
        for i in 0..PANEL {
            let colour = map((i as f32 + 0.5) / PANEL as f32);
            for j in 0..BAR {
                img.put_pixel(x0 + i, 2 * MARGIN + PANEL + j, image::Rgb(colour));
            }
        }
    }
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)?;
    // Complete or absent: encoded in memory, then renamed into place.
    brdf_sampling::quadtree_sampler::write_atomically(path, bytes.get_ref())
        .map_err(image::ImageError::IoError)
}
