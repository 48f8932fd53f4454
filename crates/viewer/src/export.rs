//! Exports: a PNG of each view (cropped from a full-window image) and the raw maps as EXR.

use crate::grids::{FrMap, TreeView};
use brdf_validate::Histogram;
use eframe::egui::{ColorImage, Rect};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A full-window image as an `image` RGBA buffer.
#[must_use]
pub fn to_rgba(image: &ColorImage) -> image::RgbaImage {
    let [w, h] = image.size;
    let bytes = image.pixels.iter().flat_map(|c| c.to_array()).collect();
    image::RgbaImage::from_raw(w as u32, h as u32, bytes).unwrap_or_default()
}

/// Writes `image` to `path` complete or not at all (encoded in memory, then
/// [`quadtree_sampler::write_atomically`]), in the format the path's extension names.
pub fn save_image(path: &Path, image: &image::RgbaImage) -> Result<(), String> {
    let fault = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let format = image::ImageFormat::from_path(path).map_err(|e| fault(&e))?;
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, format).map_err(|e| fault(&e))?;
    quadtree_sampler::write_atomically(path, bytes.get_ref()).map_err(|e| fault(&e))
}

/// Writes `<name>.png` for every view rectangle (points, scaled by `pixels_per_point`),
/// cropped from `screenshot`.
pub fn write_views(
    dir: &Path,
    screenshot: &ColorImage,
    pixels_per_point: f32,
    rects: &BTreeMap<&'static str, Rect>,
) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let full = to_rgba(screenshot);
    let mut files = Vec::new();
    for (name, rect) in rects {
        let x0 = (rect.left() * pixels_per_point).round().max(0.0) as u32;
        let y0 = (rect.top() * pixels_per_point).round().max(0.0) as u32;
        let x1 = ((rect.right() * pixels_per_point).round() as u32).min(full.width());
        let y1 = ((rect.bottom() * pixels_per_point).round() as u32).min(full.height());
        if x1 <= x0 || y1 <= y0 {
            continue;
        }
        let crop = image::imageops::crop_imm(&full, x0, y0, x1 - x0, y1 - y0).to_image();
        let path = dir.join(format!("{name}.png"));
        save_image(&path, &crop)?;
        files.push(path);
    }
    Ok(files)
}

fn write_exr(
    path: &Path,
    width: usize,
    height: usize,
    channels: Vec<(&str, Vec<f32>)>,
) -> Result<PathBuf, String> {
    use exr::prelude::*;
    let list = channels
        .into_iter()
        .map(|(name, values)| AnyChannel::new(name, FlatSamples::F32(values)))
        .collect::<Vec<_>>();
    let layer = Layer::new(
        (width, height),
        LayerAttributes::named("viewer"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(list.into()),
    );
    let fault = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    let mut bytes = std::io::Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| fault(&e))?;
    quadtree_sampler::write_atomically(path, bytes.get_ref()).map_err(|e| fault(&e))?;
    Ok(path.to_path_buf())
}

/// `maps.exr`: over the tree's square at the f_r map's resolution (row 0 at v = +1), the
/// channels `fr` (Y(f_r), NaN outside the domain) and, with a tree, `leaf_probability` (the
/// exact probability that selection picks the leaf holding the pixel), `leaf_acceptance` (its
/// P) and `leaf_depth`.
pub fn write_maps(dir: &Path, fr: &FrMap, tree: Option<&TreeView>) -> Result<PathBuf, String> {
    let res = fr.res;
    let mut channels = vec![("fr", fr.values.clone())];
    if let Some(tree) = tree {
        let leaves = tree.leaf_per_pixel(res);
        channels.push((
            "leaf_probability",
            leaves.iter().map(|l| l.probability as f32).collect(),
        ));
        channels.push((
            "leaf_acceptance",
            leaves.iter().map(|l| l.acceptance() as f32).collect(),
        ));
        channels.push((
            "leaf_depth",
            leaves.iter().map(|l| f32::from(l.depth)).collect(),
        ));
    }
    write_exr(&dir.join("maps.exr"), res, res, channels)
}

/// `cells.exr`: the histogram cells (square grids with y = +1 in the top row; polar grids one
/// row per ring, centre first) with channels `observed`, `expected`, `mass` and `residual`
/// (`brdf_validate::Histogram::write_exr`, the writer `brdf test --out` uses too).
pub fn write_cells(dir: &Path, histogram: &Histogram) -> Result<PathBuf, String> {
    let path = dir.join("cells.exr");
    histogram
        .write_exr(&path, "viewer")
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path)
}
