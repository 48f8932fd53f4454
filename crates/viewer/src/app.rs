//! The viewer's state and UI: controls on the left; the disk view, the 3D lobe and the
//! three histogram panels in the centre.

use crate::export;
use crate::lobe::{LobeMesh, LobePaint, LobeResources, OrbitCamera, project};
use crate::panels::{
    Command, ExportPanel, GridKind, IncidentPanel, Inputs, MAX_THETA_DEG, ModelPanel, SamplesPanel,
    StatsPanel, StatsView, Style, TreePanel, ViewPanel,
};
use crate::views::{self, Background};
use crate::worker::{FrMap, Request, SampleState, SamplerKind, TreeView, Update, Worker};
use brdf_core::geometry::spherical_angles;
use brdf_core::registry::{self, ModelInfo};
use brdf_core::{Brdf, DiskMap, ParamKind, ParamSet, ParamValue};
use brdf_validate::{CellGrid, ChiSquare, Histogram, chi_square};
use eframe::egui::scroll_area::ScrollBarVisibility;
use eframe::egui::{self, Color32, Rect, Sense, Stroke, TextureHandle, TextureOptions, vec2};
use eframe::egui_wgpu;
use glam::{Vec2, Vec3};
use quadtree_sampler::TreeStats;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};

/// Significance of the live χ² verdict (one test).
pub const ALPHA: f64 = 0.01;

/// How the viewer starts: the model, its parameters and the incident direction.
#[derive(Clone, Debug)]
pub struct Launch {
    /// Registry name of the model.
    pub model: String,
    /// `name=value` parameter assignments, as the `brdf` CLI takes them.
    pub params: Vec<String>,
    /// Incident direction (local frame); `None`: θ = 45°, φ = 30°.
    pub wi: Option<Vec3>,
    /// Samples to draw.
    pub samples: u64,
}

impl Default for Launch {
    fn default() -> Self {
        Self {
            model: "ward".into(),
            params: Vec::new(),
            wi: None,
            samples: 100_000,
        }
    }
}

/// A checked [`Launch`]: everything [`ViewerApp::new`] needs, already validated.
#[derive(Clone, Debug)]
pub struct Resolved {
    model: &'static ModelInfo,
    params: ParamSet,
    theta_deg: f32,
    phi_deg: f32,
    samples: u64,
}

impl Launch {
    /// Checks the model name, the parameters and the incident direction; the error says
    /// which is wrong and why.
    pub fn resolve(&self) -> Result<Resolved, String> {
        let model = registry::find(&self.model).map_err(|e| e.to_string())?;
        let params = model
            .parse_params(self.params.iter().map(String::as_str))
            .map_err(|e| e.to_string())?;
        model.build(&params).map_err(|e| e.to_string())?;
        let (theta_deg, phi_deg) = match self.wi {
            Some(wi) => {
                let wi = brdf_core::geometry::unit_direction_above(wi)
                    .map_err(|e| format!("--wi: {e}"))?;
                let (t, p) = spherical_angles(wi);
                let t = t.to_degrees();
                // Used as given or refused, never moved: the sliders stop at 89°.
                // (A thousandth of a degree of slack for the f32 round trip of 89° itself.)
                if t > MAX_THETA_DEG + 1e-3 {
                    return Err(format!(
                        "--wi: θ = {t:.4}° is beyond the viewer's {MAX_THETA_DEG}° limit (`brdf sample` takes any wi above the horizon)"
                    ));
                }
                (t.min(MAX_THETA_DEG), p.to_degrees())
            }
            None => (45.0, 30.0),
        };
        if !(1..=100_000_000).contains(&self.samples) {
            return Err(format!(
                "--samples {}: must be in 1..=100000000",
                self.samples
            ));
        }
        Ok(Resolved {
            model,
            params,
            theta_deg,
            phi_deg: if phi_deg > 180.0 {
                phi_deg - 360.0
            } else {
                phi_deg
            },
            samples: self.samples,
        })
    }
}

/// The results of the current (or last) job, as they arrive.
#[derive(Default)]
struct Results {
    fr: Option<Arc<FrMap>>,
    tree: Option<(Arc<TreeView>, TreeStats, f64, f64)>,
    /// Expected mass per cell, with the grid it was integrated on.
    expected: Option<(CellGrid, Arc<Vec<f64>>)>,
    samples: Option<Arc<SampleState>>,
    samples_grid: Option<CellGrid>,
    error: Option<String>,
}

/// The live χ² of the current samples against f·cos.
#[derive(Clone, Debug)]
pub struct LiveTest {
    /// Samples that landed in cells.
    pub samples: u64,
    /// Observed and expected counts per cell (expected for the samples that landed).
    pub histogram: Histogram,
    /// Pearson's χ² (`None` with fewer than two pooled bins).
    pub chi2: Option<ChiSquare>,
}

impl LiveTest {
    /// Whether the χ² test accepts at [`ALPHA`].
    #[must_use]
    pub fn passed(&self) -> bool {
        self.chi2.as_ref().is_some_and(|c| c.p_value >= ALPHA)
    }
}

/// The whole state of the viewer.
pub struct ViewerApp {
    /// What the user chose (the model, wi, the tree's and the sampler's options).
    inputs: Inputs,
    brdf: Result<Arc<dyn Brdf>, String>,
    style: Style,
    camera: OrbitCamera,

    worker: Worker,
    generation: u64,
    finished: u64,
    dirty: bool,
    results: Results,
    fr_texture: Option<TextureHandle>,
    leaf_texture: Option<TextureHandle>,
    textures_stale: bool,
    lobe: Option<Arc<LobeMesh>>,
    lobe_versions: u64,
    has_wgpu: bool,

    /// Where each view was drawn in the last frame (points), for exports.
    view_rects: BTreeMap<&'static str, Rect>,
    /// Where the disk view's caption was laid out (wrapped inside the view).
    caption_rect: Rect,
    export: ExportPanel,
    screenshots: (
        Sender<Arc<egui::ColorImage>>,
        Receiver<Arc<egui::ColorImage>>,
    ),
    export_pending: Option<PathBuf>,
}

impl ViewerApp {
    /// The viewer for a checked launch. With a wgpu render state in `cc` the lobe view's GPU
    /// resources are created; without one (pixel-free tests) the lobe view says so.
    pub fn new(cc: &eframe::CreationContext<'_>, launch: Resolved) -> Self {
        let has_wgpu = if let Some(rs) = cc.wgpu_render_state.as_ref() {
            let resources = LobeResources::new(&rs.device, rs.target_format);
            rs.renderer.write().callback_resources.insert(resources);
            true
        } else {
            false
        };
        let ctx = cc.egui_ctx.clone();
        let Resolved {
            model,
            params,
            theta_deg,
            phi_deg,
            samples,
        } = launch;
        let mut app = Self {
            inputs: Inputs {
                model,
                params,
                path_text: String::new(),
                theta_deg,
                phi_deg,
                map: DiskMap::Orthographic,
                split_threshold: 0.5,
                max_depth: 20,
                use_target: false,
                target_trials: 1.25,
                sampler: SamplerKind::Rejection,
                samples,
                grid_kind: GridKind::Square,
                cells: 16,
                seed: 1,
            },
            brdf: Err(String::new()),
            style: Style::default(),
            camera: OrbitCamera::default(),
            worker: Worker::spawn(move || ctx.request_repaint()),
            generation: 0,
            finished: 0,
            dirty: true,
            results: Results::default(),
            fr_texture: None,
            leaf_texture: None,
            textures_stale: true,
            lobe: None,
            lobe_versions: 0,
            has_wgpu,
            view_rects: BTreeMap::new(),
            caption_rect: Rect::NOTHING,
            export: ExportPanel {
                dir: "viewer-export".into(),
                status: None,
            },
            screenshots: channel(),
            export_pending: None,
        };
        if let Some(p) = app.inputs.params.iter().find_map(|(s, v)| {
            (s.kind == ParamKind::Path).then(|| v.text().unwrap_or("").to_owned())
        }) {
            app.inputs.path_text = p;
        }
        app.rebuild_brdf();
        app
    }

    /// The current model's registry name.
    #[must_use]
    pub fn model_name(&self) -> &'static str {
        self.inputs.model.name
    }

    /// Switches to model `name` with its default parameters.
    pub fn set_model(&mut self, name: &str) -> Result<(), String> {
        self.inputs.model = registry::find(name).map_err(|e| e.to_string())?;
        self.inputs.params = self.inputs.model.defaults();
        if self.inputs.model.measured && !self.inputs.path_text.is_empty() {
            // Back to the measured model: the file last named is still the one meant.
            if let Some(spec) = self
                .inputs
                .model
                .params
                .iter()
                .find(|p| p.kind == ParamKind::Path)
            {
                let _ = self
                    .inputs
                    .params
                    .set(spec.name, ParamValue::Path(self.inputs.path_text.clone()));
            }
        }
        self.rebuild_brdf();
        Ok(())
    }

    /// What the user chose (the model, wi, the tree's and the sampler's options).
    #[must_use]
    pub fn inputs(&self) -> &Inputs {
        &self.inputs
    }

    /// The incident direction (local frame).
    #[must_use]
    pub fn wi(&self) -> Vec3 {
        self.inputs.wi()
    }

    /// Sets the incident direction from angles in degrees (θ clamped to [0, 89°]).
    pub fn set_angles(&mut self, theta_deg: f32, phi_deg: f32) {
        self.inputs.theta_deg = theta_deg.clamp(0.0, MAX_THETA_DEG);
        self.inputs.phi_deg = phi_deg;
        self.dirty = true;
    }

    /// True when the newest job has finished (or failed) and no input changed since.
    #[must_use]
    pub fn is_idle(&self) -> bool {
        !self.dirty && self.finished == self.generation
    }

    /// The current tree's statistics, when one is built.
    #[must_use]
    pub fn tree_stats(&self) -> Option<&TreeStats> {
        self.results.tree.as_ref().map(|t| &t.1)
    }

    /// The current sample tallies.
    #[must_use]
    pub fn sample_state(&self) -> Option<&SampleState> {
        self.results.samples.as_deref()
    }

    /// Where the disk view's caption was drawn in the last frame (inside the disk view).
    #[must_use]
    pub fn disk_caption_rect(&self) -> Rect {
        self.caption_rect
    }

    /// Where view `name` (`disk`, `lobe`, `observed`, `expected`, `difference`) was drawn in
    /// the last frame, in points.
    #[must_use]
    pub fn view_rect(&self, name: &str) -> Option<Rect> {
        self.view_rects.get(name).copied()
    }

    /// The square point (of the current map) where wi is marked on the disk view.
    #[must_use]
    pub fn wi_square_point(&self) -> Vec2 {
        self.inputs.map.direction_to_square(self.wi())
    }

    /// One line per result for scripts: the tree's statistics, the sampling tallies and
    /// the live χ² (what the Stats panel and the histogram caption show).
    #[must_use]
    pub fn summary(&self) -> String {
        let mut out = format!(
            "model {} wi theta={:.2} phi={:.2} sampler {}\n",
            self.inputs.model.name,
            self.inputs.theta_deg,
            self.inputs.phi_deg,
            self.inputs.sampler.name()
        );
        if let Some((_, s, seconds, albedo)) = &self.results.tree {
            out += &format!(
                "tree: {} nodes, {} leaves ({} live), depth {}, E[T] {:.3}, {} bytes, build {:.2} ms, albedo {:.4}\n",
                s.nodes,
                s.leaves,
                s.live_leaves,
                s.max_depth,
                s.expected_trials,
                s.bytes,
                seconds * 1e3,
                albedo
            );
        }
        if let Some(s) = &self.results.samples {
            out += &format!(
                "samples: {} drawn, {} lost, {:.3} trials/sample, {:.0} ns/sample, {} bound violations\n",
                s.drawn,
                s.lost,
                s.trials as f64 / (s.drawn - s.lost).max(1) as f64,
                s.seconds * 1e9 / s.drawn.max(1) as f64,
                s.bound_violations
            );
        }
        if let Some(t) = self.live_test()
            && let Some(c) = &t.chi2
        {
            out += &format!(
                "chi2: {:.2}, dof {}, p {:.4}, {} at alpha {ALPHA}\n",
                c.statistic,
                c.dof,
                c.p_value,
                if t.passed() { "pass" } else { "reject" }
            );
        }
        if let Some(e) = &self.results.error {
            out += &format!("error: {e}\n");
        }
        out
    }

    /// The last error (a delta model, a failed build), if any.
    #[must_use]
    pub fn error(&self) -> Option<&str> {
        self.results.error.as_deref()
    }

    /// The χ² of the current samples against the current expected masses, when both belong
    /// to the same job.
    #[must_use]
    pub fn live_test(&self) -> Option<LiveTest> {
        let (grid, mass) = self.results.expected.as_ref()?;
        let samples = self.results.samples.as_ref()?;
        if self.results.samples_grid != Some(*grid) || samples.counts.len() != mass.len() {
            return None;
        }
        let landed: u64 = samples.counts.iter().sum();
        let total: f64 = mass.iter().sum();
        if landed == 0 || total <= 0.0 {
            return None;
        }
        let histogram = Histogram::of_counts(*grid, samples.counts.clone(), mass.to_vec());
        Some(LiveTest {
            samples: landed,
            chi2: chi_square(&histogram.observed, &histogram.expected),
            histogram,
        })
    }

    /// Opens a measured BRDF file: switches to the model with a path parameter (`merl`) and
    /// sets it; errors (a malformed file) show in the window like every other model error.
    pub fn open_file(&mut self, path: &std::path::Path) {
        let Some(info) = registry::models()
            .iter()
            .find(|m| m.params.iter().any(|p| p.kind == ParamKind::Path))
        else {
            return;
        };
        if self.inputs.model.name != info.name {
            self.inputs.model = info;
            self.inputs.params = info.defaults();
        }
        self.inputs.path_text = path.display().to_string();
        if let Some(spec) = info.params.iter().find(|p| p.kind == ParamKind::Path) {
            let _ = self
                .inputs
                .params
                .set(spec.name, ParamValue::Path(self.inputs.path_text.clone()));
        }
        self.rebuild_brdf();
    }

    /// The model's error as the window shows it (`None` when it built).
    #[must_use]
    pub fn model_error(&self) -> Option<&str> {
        self.brdf.as_ref().err().map(String::as_str)
    }

    fn rebuild_brdf(&mut self) {
        self.brdf = self
            .inputs
            .model
            .build(&self.inputs.params)
            .map(Arc::from)
            .map_err(|e| e.to_string());
        self.dirty = true;
    }

    /// Sends a job for the current inputs (if any changed) and takes in the worker's updates.
    fn pump(&mut self) {
        if self.dirty {
            self.dirty = false;
            self.generation += 1;
            match &self.brdf {
                Ok(brdf) => self.worker.submit(Request {
                    generation: self.generation,
                    brdf: Arc::clone(brdf),
                    wi: self.wi(),
                    config: self.inputs.config(),
                    sampler: self.inputs.sampler,
                    samples: self.inputs.samples,
                    grid: self.inputs.grid(),
                    seed: self.inputs.seed,
                    map_res: 256,
                    lobe_res: 64,
                }),
                Err(e) => {
                    self.results.error = Some(e.clone());
                    self.finished = self.generation;
                }
            }
        }
        for update in self.worker.poll() {
            if update.generation() != self.generation {
                continue;
            }
            match update {
                Update::Map(_, map) => {
                    self.results.fr = Some(map);
                    self.results.error = None;
                    self.textures_stale = true;
                }
                Update::Lobe(_, grid) => {
                    self.lobe_versions += 1;
                    self.lobe = Some(Arc::new(LobeMesh::from_grid(&grid, self.lobe_versions)));
                }
                Update::Tree {
                    tree,
                    stats,
                    seconds,
                    albedo,
                    ..
                } => {
                    self.results.tree = Some((tree, stats, seconds, albedo));
                    self.textures_stale = true;
                }
                Update::Expected(_, mass) => {
                    self.results.expected = Some((self.inputs.grid(), mass));
                    self.results.samples = None;
                }
                Update::Samples(_, state) => {
                    self.results.samples = Some(state);
                    self.results.samples_grid = Some(self.inputs.grid());
                }
                Update::Done(g) => self.finished = g,
                Update::Failed(g, message) => {
                    self.results.error = Some(message);
                    self.results.tree = None;
                    self.results.expected = None;
                    self.results.samples = None;
                    self.textures_stale = true;
                    self.finished = g;
                }
            }
        }
    }

    /// Carries out what the panels asked for this frame, in order: the one place their side
    /// effects happen.
    fn execute(&mut self, ctx: &egui::Context, commands: Vec<Command>) {
        for command in commands {
            match command {
                Command::SetModel(name) => {
                    // Picked from the registry's own list, so it is there.
                    let _ = self.set_model(name);
                }
                Command::RebuildModel => self.rebuild_brdf(),
                Command::Resubmit => self.dirty = true,
                Command::Restyle => self.textures_stale = true,
                Command::Export(dir) => {
                    self.export_pending = Some(dir);
                    let tx = self.screenshots.0.clone();
                    ctx.request_screenshot(move |image| {
                        let _ = tx.send(image);
                    });
                }
            }
        }
    }

    fn refresh_textures(&mut self, ctx: &egui::Context) {
        if !self.textures_stale {
            return;
        }
        self.textures_stale = false;
        if let Some(fr) = &self.results.fr {
            let image = views::fr_image(fr, self.style.log_scale);
            self.fr_texture = Some(ctx.load_texture("f_r", image, TextureOptions::NEAREST));
            self.leaf_texture = match (&self.results.tree, self.style.background) {
                (_, Background::Fr) | (None, _) => None,
                (Some((tree, ..)), bg) => Some(ctx.load_texture(
                    "leaves",
                    views::leaf_image(tree, bg, fr),
                    TextureOptions::NEAREST,
                )),
            };
        }
    }

    fn disk_view(&mut self, ui: &mut egui::Ui, side: f32) {
        let (response, painter) = ui.allocate_painter(vec2(side, side), Sense::click_and_drag());
        let rect = response.rect;
        self.view_rects.insert("disk", rect);
        painter.rect_filled(rect, 0.0, views::OUTSIDE);
        let uv = Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        let texture = match self.style.background {
            Background::Fr => self.fr_texture.as_ref(),
            _ => self.leaf_texture.as_ref().or(self.fr_texture.as_ref()),
        };
        if let Some(tex) = texture {
            painter.image(tex.id(), rect, uv, Color32::WHITE);
        }
        if let Some((tree, ..)) = &self.results.tree
            && self.style.outlines
            && tree.map() == self.inputs.map
        {
            let stroke = Stroke::new(0.6, Color32::from_rgba_unmultiplied(255, 255, 255, 110));
            painter.extend(views::leaf_outlines(tree, rect, stroke));
        }
        if self.style.points
            && let Some(s) = &self.results.samples
        {
            let color = Color32::from_rgba_unmultiplied(255, 150, 60, 200);
            for p in &s.points {
                painter.circle_filled(views::to_screen(rect, *p), 1.0, color);
            }
        }
        // Markers: the normal (+), wi (circle) and its mirror (ring).
        let wi = self.wi();
        let normal = views::to_screen(rect, self.inputs.map.direction_to_square(Vec3::Z));
        let cross = Stroke::new(1.5, Color32::WHITE);
        painter.line_segment([normal - vec2(6.0, 0.0), normal + vec2(6.0, 0.0)], cross);
        painter.line_segment([normal - vec2(0.0, 6.0), normal + vec2(0.0, 6.0)], cross);
        let wi_pos = views::to_screen(rect, self.inputs.map.direction_to_square(wi));
        painter.circle(
            wi_pos,
            5.0,
            Color32::from_rgb(80, 200, 255),
            Stroke::new(1.5, Color32::BLACK),
        );
        let mirror = Vec3::new(-wi.x, -wi.y, wi.z);
        let mirror_pos = views::to_screen(rect, self.inputs.map.direction_to_square(mirror));
        painter.circle_stroke(
            mirror_pos,
            7.0,
            Stroke::new(2.0, Color32::from_rgb(255, 80, 200)),
        );
        self.caption_rect = caption(
            &painter,
            rect,
            format!(
                "{} square [−1,1]²: + normal, blue dot wi, pink ring mirror (drag to move wi)",
                self.inputs.map.name()
            ),
        );
        if (response.dragged() || response.clicked())
            && let Some(pos) = response.interact_pointer_pos()
        {
            self.drag_wi(views::from_screen(rect, pos));
        }
    }

    /// Sets wi to the direction whose square point is `p` (clamped into the domain).
    fn drag_wi(&mut self, p: Vec2) {
        let p = p.clamp(Vec2::splat(-1.0), Vec2::splat(1.0));
        let dir = match self.inputs.map.square_to_direction(p) {
            Some(d) => d,
            // Outside the orthographic disk: the rim point in that azimuth.
            None => Vec3::new(p.x, p.y, 0.0).normalize_or(Vec3::X),
        };
        let (theta, phi) = spherical_angles(dir);
        self.set_angles(theta.to_degrees(), phi.to_degrees().rem_euclid(360.0));
        if self.inputs.phi_deg > 180.0 {
            self.inputs.phi_deg -= 360.0;
        }
    }

    fn lobe_view(&mut self, ui: &mut egui::Ui, size: egui::Vec2) {
        let (response, painter) = ui.allocate_painter(size, Sense::drag());
        let rect = response.rect;
        self.view_rects.insert("lobe", rect);
        if response.dragged() {
            let d = response.drag_delta();
            self.camera.drag(d.x, d.y);
        }
        painter.rect_filled(rect, 0.0, Color32::from_rgb(23, 23, 28));
        let view_proj = self.camera.view_proj(rect.width() / rect.height().max(1.0));
        if let (true, Some(mesh)) = (self.has_wgpu, &self.lobe) {
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
        } else if !self.has_wgpu {
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "the 3D lobe needs the wgpu renderer",
                egui::FontId::proportional(12.0),
                Color32::GRAY,
            );
        }
        // The incident and mirror vectors, projected with the same camera.
        let wi = self.wi();
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
    }

    fn histograms(&mut self, ui: &mut egui::Ui, side: f32) {
        let test = self.live_test();
        let grid = self.results.expected.as_ref().map(|(g, _)| *g);
        ui.horizontal(|ui| {
            for (name, title) in [
                ("observed", "observed n_i"),
                ("expected", "expected e_i (integrator)"),
                ("difference", "(n - e)/sqrt(e), ±4"),
            ] {
                ui.vertical(|ui| {
                    ui.label(title);
                    let (response, painter) = ui.allocate_painter(vec2(side, side), Sense::hover());
                    let rect = response.rect;
                    self.view_rects.insert(name, rect);
                    painter.rect_filled(rect, 0.0, views::OUTSIDE);
                    if let (Some(t), Some(grid)) = (&test, grid) {
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
        match &test {
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
            }
            None => {
                ui.label("waiting for samples…");
            }
        }
    }

    fn finish_export(&mut self, ctx: &egui::Context) {
        let Ok(image) = self.screenshots.1.try_recv() else {
            return;
        };
        let Some(dir) = self.export_pending.take() else {
            return;
        };
        self.export.status = Some(match self.export_to(&dir, &image, ctx.pixels_per_point()) {
            Ok(files) => format!("wrote {} files to {}", files.len(), dir.display()),
            Err(e) => format!("export failed: {e}"),
        });
    }

    /// Writes a PNG of each view, cropped from `screenshot` (a full-window image at
    /// `pixels_per_point`), and the raw maps as EXR into `dir`. Returns the files written.
    pub fn export_to(
        &self,
        dir: &std::path::Path,
        screenshot: &egui::ColorImage,
        pixels_per_point: f32,
    ) -> Result<Vec<PathBuf>, String> {
        let mut files = export::write_views(dir, screenshot, pixels_per_point, &self.view_rects)?;
        if let Some(fr) = &self.results.fr {
            let tree = self.results.tree.as_ref().map(|t| &*t.0);
            files.push(export::write_maps(dir, fr, tree)?);
        }
        if let Some(t) = self.live_test() {
            files.push(export::write_cells(dir, &t.histogram)?);
        }
        Ok(files)
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

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        // A file dropped on the window opens as a measured BRDF.
        let dropped = ctx.input(|i| i.raw.dropped_files.first().map(|f| f.path().to_path_buf()));
        if let Some(path) = dropped {
            self.open_file(&path);
        }
        self.pump();
        self.refresh_textures(&ctx);
        self.finish_export(&ctx);
        let mut commands = Vec::new();
        egui::Panel::left("controls")
            .default_size(310.0)
            .show(ui, |ui| {
                // The stats keep their own resizable strip at the bottom, each part scrolling
                // with a solid, always visible bar (they used to run off the window's bottom
                // edge with nothing to say there was more).
                ui.spacing_mut().scroll = egui::style::ScrollStyle::solid();
                let stats_height = (0.35 * ui.available_height()).clamp(120.0, 300.0);
                egui::Panel::bottom("stats")
                    .resizable(true)
                    .default_size(stats_height)
                    .show(ui, |ui| {
                        egui::ScrollArea::vertical()
                            .id_salt("stats")
                            .scroll_bar_visibility(ScrollBarVisibility::AlwaysVisible)
                            .auto_shrink([false, false])
                            .show(ui, |ui| {
                                let tree = self.results.tree.as_ref();
                                StatsPanel::ui(
                                    ui,
                                    &StatsView {
                                        busy: !self.is_idle(),
                                        error: self.results.error.as_deref(),
                                        tree: tree.map(|(_, s, secs, albedo)| (s, *secs, *albedo)),
                                        samples: self.results.samples.as_deref(),
                                    },
                                );
                            });
                    });
                egui::ScrollArea::vertical()
                    .id_salt("controls")
                    .scroll_bar_visibility(ScrollBarVisibility::AlwaysVisible)
                    .show(ui, |ui| {
                        let error = self.brdf.as_ref().err().map(String::as_str);
                        ModelPanel::ui(ui, &mut self.inputs, error, &mut commands);
                        ui.separator();
                        IncidentPanel::ui(ui, &mut self.inputs, &mut commands);
                        ui.separator();
                        TreePanel::ui(ui, &mut self.inputs, &mut commands);
                        ui.separator();
                        SamplesPanel::ui(ui, &mut self.inputs, &mut commands);
                        ui.separator();
                        ViewPanel::ui(ui, &mut self.style, &mut commands);
                        ui.separator();
                        self.export.ui(ui, &mut commands);
                    });
            });
        self.execute(&ctx, commands);
        egui::CentralPanel::default().show(ui, |ui| {
            let avail = ui.available_size();
            let top = (avail.y * 0.58).min(avail.x * 0.5).max(120.0);
            ui.horizontal(|ui| {
                self.disk_view(ui, top);
                let lobe_w = (ui.available_width()).max(120.0);
                self.lobe_view(ui, vec2(lobe_w, top));
            });
            let rest = ui.available_height() - 44.0;
            let side = (rest).min((avail.x - 24.0) / 3.0).max(80.0);
            self.histograms(ui, side);
        });
        if !self.is_idle() {
            ctx.request_repaint_after(std::time::Duration::from_millis(50));
        }
    }
}
