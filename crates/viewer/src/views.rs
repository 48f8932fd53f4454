//! Drawing helpers of the 2D views: the f_r / leaf images of the disk view, the quadtree's
//! leaf outlines, and the histogram cells of the validation grid.

use crate::grids::{FrMap, TreeView};
use brdf_validate::CellGrid;
use eframe::egui::{self, Color32, ColorImage, Mesh, Pos2, Rect, Shape, Stroke};
use glam::Vec2;
use quadtree_sampler::PackedLeaf;
use quadtree_sampler::colormap::{rdbu, viridis};

/// Background for points outside the map's domain (the orthographic corners).
pub const OUTSIDE: Color32 = Color32::from_rgb(24, 24, 28);

/// What the disk view paints under the outlines.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Background {
    /// Y(f_r(wi, ·)).
    Fr,
    /// Each leaf's selection probability v1/Σv1 per unit square area (log scale).
    LeafProbability,
    /// Each leaf's acceptance P = v1/(box volume), 0..1.
    LeafAcceptance,
}

impl Background {
    /// Every option, in UI order, with its label.
    pub const ALL: [(Self, &'static str); 3] = [
        (Self::Fr, "f_r"),
        (Self::LeafProbability, "leaf probability"),
        (Self::LeafAcceptance, "leaf acceptance P"),
    ];
}

fn rgb(c: [u8; 3]) -> Color32 {
    Color32::from_rgb(c[0], c[1], c[2])
}

/// `t` ∈ [0, 1] for `v` relative to `max`: linear, or log over four decades.
#[must_use]
pub fn normalise(v: f32, max: f32, log: bool) -> f32 {
    if max <= 0.0 || !v.is_finite() {
        0.0
    } else if log {
        ((v / max).max(1e-4).log10() / 4.0 + 1.0).clamp(0.0, 1.0)
    } else {
        (v / max).clamp(0.0, 1.0)
    }
}

/// The f_r map through viridis (linear, or log over four decades of its maximum).
#[must_use]
pub fn fr_image(map: &FrMap, log: bool) -> ColorImage {
    let max = map
        .values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f32, f32::max);
    let pixels = map
        .values
        .iter()
        .map(|&v| {
            if v.is_nan() {
                OUTSIDE
            } else {
                rgb(viridis(normalise(v, max, log)))
            }
        })
        .collect();
    ColorImage::new([map.res, map.res], pixels)
}

/// The leaves of `tree` rasterised at the f_r map's resolution: each pixel takes the value of
/// the leaf holding its centre, coloured by `background` (which must not be `Fr`); pixels
/// outside the map's domain keep the background colour.
#[must_use]
pub fn leaf_image(tree: &TreeView, background: Background, fr: &FrMap) -> ColorImage {
    // Selection probability per unit square area.
    let density = |l: &PackedLeaf| l.probability / l.rect.area();
    let max_density = tree.leaves().iter().map(density).fold(0.0f64, f64::max);
    let pixels = tree
        .leaf_per_pixel(fr.res)
        .into_iter()
        .zip(&fr.values)
        .map(|(leaf, v)| {
            if v.is_nan() {
                return OUTSIDE;
            }
            let t = match background {
                Background::LeafAcceptance => leaf.acceptance() as f32,
                _ => normalise(density(leaf) as f32, max_density as f32, true),
            };
            rgb(viridis(t))
        })
        .collect();
    ColorImage::new([fr.res, fr.res], pixels)
}

/// Screen position of square point `p` ∈ [−1,1]² in `rect` (v up).
#[must_use]
pub fn to_screen(rect: Rect, p: Vec2) -> Pos2 {
    egui::pos2(
        rect.center().x + p.x * 0.5 * rect.width(),
        rect.center().y - p.y * 0.5 * rect.height(),
    )
}

/// Square point under screen position `pos` in `rect`.
#[must_use]
pub fn from_screen(rect: Rect, pos: Pos2) -> Vec2 {
    Vec2::new(
        (pos.x - rect.center().x) / (0.5 * rect.width()),
        (rect.center().y - pos.y) / (0.5 * rect.height()),
    )
}

/// The leaf outlines of `tree`, as line segments (one rectangle per leaf).
pub fn leaf_outlines(tree: &TreeView, rect: Rect, stroke: Stroke) -> Vec<Shape> {
    tree.leaves()
        .iter()
        .map(|l| {
            let a = to_screen(rect, Vec2::new(l.rect.min.x as f32, l.rect.max.y as f32));
            let b = to_screen(rect, Vec2::new(l.rect.max.x as f32, l.rect.min.y as f32));
            Shape::rect_stroke(
                Rect::from_two_pos(a, b),
                0.0,
                stroke,
                egui::StrokeKind::Middle,
            )
        })
        .collect()
}

/// The outline of cell `i` of `grid` on the orthographic disk, as an inner and an outer
/// polyline of equal length (a quad strip between them covers the cell).
#[must_use]
pub fn cell_strip(grid: CellGrid, i: usize) -> (Vec<Vec2>, Vec<Vec2>) {
    match grid {
        CellGrid::Square { res } => {
            let (r, c) = (i / res, i % res);
            let s = 2.0 / res as f32;
            let (x0, y0) = (-1.0 + c as f32 * s, -1.0 + r as f32 * s);
            (
                vec![Vec2::new(x0, y0), Vec2::new(x0 + s, y0)],
                vec![Vec2::new(x0, y0 + s), Vec2::new(x0 + s, y0 + s)],
            )
        }
        CellGrid::Polar { rings, sectors } => {
            let (ri, sj) = (i / sectors, i % sectors);
            let (r0, r1) = (
                (ri as f32 / rings as f32).sqrt(),
                ((ri + 1) as f32 / rings as f32).sqrt(),
            );
            let steps = 6;
            let arc = |r: f32| {
                (0..=steps)
                    .map(|k| {
                        let phi = core::f32::consts::TAU * (sj as f32 + k as f32 / steps as f32)
                            / sectors as f32;
                        Vec2::new(r * phi.cos(), r * phi.sin())
                    })
                    .collect::<Vec<_>>()
            };
            (arc(r0), arc(r1))
        }
    }
}

/// Fills every cell of `grid` in `rect` with `color(i)`; the disk's outline on top.
pub fn paint_cells(
    painter: &egui::Painter,
    rect: Rect,
    grid: CellGrid,
    color: &dyn Fn(usize) -> Color32,
) {
    let mut mesh = Mesh::default();
    for i in 0..grid.len() {
        let (inner, outer) = cell_strip(grid, i);
        let c = color(i);
        let base = mesh.vertices.len() as u32;
        for (a, b) in inner.iter().zip(&outer) {
            mesh.colored_vertex(to_screen(rect, *a), c);
            mesh.colored_vertex(to_screen(rect, *b), c);
        }
        for k in 0..inner.len() as u32 - 1 {
            let (a, b, c2, d) = (
                base + 2 * k,
                base + 2 * k + 1,
                base + 2 * k + 2,
                base + 2 * k + 3,
            );
            mesh.add_triangle(a, b, c2);
            mesh.add_triangle(b, d, c2);
        }
    }
    painter.add(Shape::mesh(mesh));
    painter.circle_stroke(
        rect.center(),
        0.5 * rect.width(),
        Stroke::new(1.0, Color32::from_gray(140)),
    );
}

/// Colour of a count relative to the shared maximum of the observed and expected panels.
#[must_use]
pub fn count_color(v: f64, max: f64) -> Color32 {
    rgb(viridis(normalise(v as f32, max as f32, false)))
}

/// Colour of a standardised residual (n − e)/√e, RdBu over ±4 (red: too many samples).
#[must_use]
pub fn residual_color(z: f64) -> Color32 {
    rgb(rdbu((0.5 + z as f32 / 8.0).clamp(0.0, 1.0)))
}
