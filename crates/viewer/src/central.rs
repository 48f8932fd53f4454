//! The central views, one small type each with its own `ui`: the disk view (the tree's
//! square with f_r or the leaves, the samples and the markers; a drag asks to move wi), the 3D
//! lobe, and the three histograms with the live χ² of [`LiveTest`].

use crate::grids::TreeView;
use crate::lobe::{LobeMesh, LobePaint, OrbitCamera, project};
use crate::panels::Command;
use crate::views;
use brdf_core::DiskMap;
use brdf_validate::{ChiSquare, Histogram};
use eframe::egui::{self, Color32, Rect, Sense, Stroke, TextureHandle, vec2};
use eframe::egui_wgpu;
use glam::{Vec2, Vec3};
use std::sync::Arc;

/// Significance of the live χ² verdict (one test).
pub const ALPHA: f64 = 0.01;

/// The live χ² of the current samples against f·cos, and against the sampler's own pdf.
#[derive(Clone, Debug)]
pub struct LiveTest {
    /// Samples that landed in cells.
    pub samples: u64,
    /// Observed and expected counts per cell (expected for the samples that landed).
    pub histogram: Histogram,
    /// Pearson's χ² against f·cos (`None` with fewer than two pooled bins).
    pub chi2: Option<ChiSquare>,
    /// Pearson's χ² against the sampler's own pdf, over every sample drawn (a last bin holds
    /// those it gave no direction for). `None` for the tree's rejection sampler (its pdf is
    /// f·cos over the tree's volume: `chi2` judges it), and until the pdf is integrated.
    pub chi2_own: Option<ChiSquare>,
}

impl LiveTest {
    /// Whether the χ² test against f·cos accepts at [`ALPHA`].
    #[must_use]
    pub fn passed(&self) -> bool {
        self.chi2.as_ref().is_some_and(|c| c.p_value >= ALPHA)
    }

    /// Whether the χ² test against the sampler's own pdf accepts at [`ALPHA`] (false while
    /// there is none).
    #[must_use]
    pub fn passed_own(&self) -> bool {
        self.chi2_own.as_ref().is_some_and(|c| c.p_value >= ALPHA)
    }
}

/// What the disk view draws.
pub struct DiskScene<'a> {
    /// The tree's map.
    pub map: DiskMap,
    /// The incident direction.
    pub wi: Vec3,
    /// The background (f_r or the leaves), when drawn.
    pub texture: Option<&'a TextureHandle>,
    /// The tree whose leaf outlines to draw (over the same map), if any.
    pub outlines: Option<&'a TreeView>,
    /// Sample points on the square, if drawn.
    pub points: Option<&'a [Vec2]>,
}

/// Where the disk view and its caption were drawn.
#[derive(Clone, Copy, Debug)]
pub struct DiskResponse {
    /// The view.
    pub rect: Rect,
    /// Its caption (inside the view).
    pub caption: Rect,
}

/// The tree's square [−1,1]²: drag or click to move wi ([`Command::SetWiAt`]).
pub struct DiskView;

impl DiskView {
    /// Draws the view in a `side`² square.
    pub fn ui(
        ui: &mut egui::Ui,
        side: f32,
        scene: &DiskScene<'_>,
        out: &mut Vec<Command>,
    ) -> DiskResponse {
        let (response, painter) = ui.allocate_painter(vec2(side, side), Sense::click_and_drag());
        let rect = response.rect;
        painter.rect_filled(rect, 0.0, views::OUTSIDE);
        let uv = Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        if let Some(tex) = scene.texture {
            painter.image(tex.id(), rect, uv, Color32::WHITE);
        }
        if let Some(tree) = scene.outlines {
            let stroke = Stroke::new(0.6, Color32::from_rgba_unmultiplied(255, 255, 255, 110));
            painter.extend(views::leaf_outlines(tree, rect, stroke));
        }
        if let Some(points) = scene.points {
            let color = Color32::from_rgba_unmultiplied(255, 150, 60, 200);
            for p in points {
                painter.circle_filled(views::to_screen(rect, *p), 1.0, color);
            }
        }
        // Markers: the normal (+), wi (circle) and its mirror (ring).
        let (wi, map) = (scene.wi, scene.map);
        let normal = views::to_screen(rect, map.direction_to_square(Vec3::Z));
        let cross = Stroke::new(1.5, Color32::WHITE);
        painter.line_segment([normal - vec2(6.0, 0.0), normal + vec2(6.0, 0.0)], cross);
        painter.line_segment([normal - vec2(0.0, 6.0), normal + vec2(0.0, 6.0)], cross);
        let wi_pos = views::to_screen(rect, map.direction_to_square(wi));
        painter.circle(
            wi_pos,
            5.0,
            Color32::from_rgb(80, 200, 255),
            Stroke::new(1.5, Color32::BLACK),
        );
        let mirror = Vec3::new(-wi.x, -wi.y, wi.z);
        let mirror_pos = views::to_screen(rect, map.direction_to_square(mirror));
        painter.circle_stroke(
            mirror_pos,
            7.0,
            Stroke::new(2.0, Color32::from_rgb(255, 80, 200)),
        );
        let caption = caption(
            &painter,
            rect,
            format!(
                "{} square [−1,1]²: + normal, blue dot wi, pink ring mirror (drag to move wi)",
                map.name()
            ),
        );
        if (response.dragged() || response.clicked())
            && let Some(pos) = response.interact_pointer_pos()
        {
            out.push(Command::SetWiAt(views::from_screen(rect, pos)));
        }
        DiskResponse { rect, caption }
    }
}

/// f_r·cos θo in 3D (wgpu), with the incident, mirror and normal vectors; drag to orbit.
pub struct LobeView;

impl LobeView {
    /// Draws the view; returns where.
    pub fn ui(
        ui: &mut egui::Ui,
        size: egui::Vec2,
        camera: &mut OrbitCamera,
        mesh: Option<&Arc<LobeMesh>>,
        has_wgpu: bool,
        wi: Vec3,
    ) -> Rect {
        let (response, painter) = ui.allocate_painter(size, Sense::drag());
        let rect = response.rect;
        if response.dragged() {
            let d = response.drag_delta();
            camera.drag(d.x, d.y);
        }
        painter.rect_filled(rect, 0.0, Color32::from_rgb(23, 23, 28));
        let view_proj = camera.view_proj(rect.width() / rect.height().max(1.0));
        if let (true, Some(mesh)) = (has_wgpu, mesh) {
            let ppp = ui.ctx().pixels_per_point();
            painter.add(egui_wgpu::Callback::new_paint_callback(
                rect,
                LobePaint {
                    mesh: Arc::clone(mesh),
                    view_proj,
                    size_px: [
                        (rect.width() * ppp).round() as u32,
                        (rect.height() * ppp).round() as u32,
                    ],
                },
            ));
        } else if !has_wgpu {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "the 3D lobe needs the wgpu renderer",
                egui::FontId::proportional(12.0),
                Color32::GRAY,
            );
        }
        // The incident and mirror vectors, projected with the same camera.
        let o = project(view_proj, rect, Vec3::ZERO);
        let arrow = |v: Vec3, color: Color32| {
            painter.line_segment(
                [o, project(view_proj, rect, v * 1.2)],
                Stroke::new(2.0, color),
            );
        };
        arrow(wi, Color32::from_rgb(80, 200, 255));
        arrow(
            Vec3::new(-wi.x, -wi.y, wi.z),
            Color32::from_rgb(255, 80, 200),
        );
        arrow(Vec3::Z, Color32::WHITE);
        caption(
            &painter,
            rect,
            "f_r·cos θo lobe (drag to orbit) — blue wi, pink mirror, white normal".into(),
        );
        rect
    }
}

/// Observed counts, expected counts and standardised residuals per cell, with the live χ².
pub struct HistogramsView;

impl HistogramsView {
    /// Draws the three panels (observed, expected, difference) and the verdict; returns their
    /// rectangles in that order.
    pub fn ui(ui: &mut egui::Ui, side: f32, test: Option<&LiveTest>) -> [Rect; 3] {
        let mut rects = [Rect::NOTHING; 3];
        ui.horizontal(|ui| {
            for (k, (name, title)) in [
                ("observed", "observed n_i"),
                ("expected", "expected e_i (integrator)"),
                ("difference", "(n - e)/sqrt(e), ±4"),
            ]
            .into_iter()
            .enumerate()
            {
                ui.vertical(|ui| {
                    ui.label(title);
                    let (response, painter) = ui.allocate_painter(vec2(side, side), Sense::hover());
                    let rect = response.rect;
                    rects[k] = rect;
                    painter.rect_filled(rect, 0.0, views::OUTSIDE);
                    if let Some(t) = test {
                        let grid = t.histogram.grid;
                        let h = &t.histogram;
                        let max = h.count_scale();
                        let residuals = h.residuals();
                        let color = |i: usize| match name {
                            _ if h.expected[i] <= 0.0 && h.observed[i] == 0 => views::OUTSIDE,
                            "observed" => views::count_color(h.observed[i] as f64, max),
                            "expected" => views::count_color(h.expected[i], max),
                            _ => views::residual_color(residuals[i]),
                        };
                        views::paint_cells(&painter, rect, grid, &color);
                    }
                });
            }
        });
        match test {
            Some(t) => {
                let (text, color) = match &t.chi2 {
                    Some(c) => (
                        format!(
                            "χ² = {:.1}, dof = {}, p = {:.3}: {} at α = {ALPHA} ({} samples in cells)",
                            c.statistic,
                            c.dof,
                            c.p_value,
                            if t.passed() {
                                "consistent with f·cos"
                            } else {
                                "REJECTED"
                            },
                            t.samples
                        ),
                        if t.passed() {
                            Color32::LIGHT_GREEN
                        } else {
                            Color32::LIGHT_RED
                        },
                    ),
                    None => ("too few samples for a χ² test".into(), Color32::GRAY),
                };
                ui.colored_label(color, text);
                if let Some(c) = &t.chi2_own {
                    let (verdict, color) = if t.passed_own() {
                        ("consistent with its own pdf", Color32::LIGHT_GREEN)
                    } else {
                        ("REJECTED", Color32::LIGHT_RED)
                    };
                    ui.colored_label(
                        color,
                        format!(
                            "against the sampler's own pdf: χ² = {:.1}, dof = {}, p = {:.3}: {verdict}",
                            c.statistic, c.dof, c.p_value
                        ),
                    );
                }
            }
            None => {
                ui.label("waiting for samples…");
            }
        }
        rects
    }
}

/// A view's caption in its top-left corner, wrapped inside the view (a single line was cut
/// off at narrow widths); returns where it was drawn.
fn caption(painter: &egui::Painter, rect: Rect, text: String) -> Rect {
    let galley = painter.layout(
        text,
        egui::FontId::proportional(11.0),
        Color32::WHITE,
        (rect.width() - 8.0).max(40.0),
    );
    let at = rect.left_top() + vec2(4.0, 4.0);
    let drawn = Rect::from_min_size(at, galley.size());
    painter.galley(at, galley, Color32::WHITE);
    drawn
}
