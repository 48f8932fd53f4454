//! The viewer's state and frame: the panels on the left ([`crate::panels`]), the views in
//! the centre ([`crate::central`]), the worker's results as they arrive, and the one place
//! where the panels' commands take effect.

use crate::central::{ALPHA, DiskScene, DiskView, HistogramsView, LiveTest, LobeView};
use crate::export;
use crate::grids::{FrMap, TreeView};
use crate::launch::Resolved;
use crate::lobe::{LobeMesh, LobeResources, OrbitCamera};
use crate::panels::{
    Command, ExportPanel, GridKind, IncidentPanel, Inputs, MAX_THETA_DEG, ModelPanel, SamplesPanel,
    StatsPanel, StatsView, Style, TreePanel, ViewPanel,
};
use crate::views::{self, Background};
use crate::worker::{Request, SampleState, SamplerKind, Update, Worker};
use brdf_core::geometry::spherical_angles;
use brdf_core::registry;
use brdf_core::{Brdf, DiskMap, ParamKind, ParamValue};
use brdf_validate::{CellGrid, Histogram, chi_square, chi_square_with_lost};
use eframe::egui::scroll_area::ScrollBarVisibility;
use eframe::egui::{self, Rect, TextureHandle, TextureOptions, vec2};
use glam::{Vec2, Vec3};
use quadtree_sampler::TreeStats;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};

/// The results of the current (or last) job, as they arrive.
#[derive(Default)]
struct Results {
    fr: Option<Arc<FrMap>>,
    tree: Option<(Arc<TreeView>, TreeStats, f64, f64)>,
    /// Expected mass per cell, with the grid it was integrated on.
    expected: Option<(CellGrid, Arc<Vec<f64>>)>,
    /// Each cell's probability under the sampler's own pdf (not for the tree's rejection
    /// sampler), with its grid.
    expected_own: Option<(CellGrid, Arc<Vec<f64>>)>,
    samples: Option<Arc<SampleState>>,
    samples_grid: Option<CellGrid>,
    error: Option<String>,
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
            // One line per χ²: against f·cos, then (when there is one) against the own pdf.
            let line = |label: &str, c: &brdf_validate::ChiSquare, passed: bool| {
                format!(
                    "{label}: {:.2}, dof {}, p {:.4}, {} at alpha {ALPHA}\n",
                    c.statistic,
                    c.dof,
                    c.p_value,
                    if passed { "pass" } else { "reject" }
                )
            };
            out += &line("chi2", c, t.passed());
            if let Some(c) = &t.chi2_own {
                out += &line("chi2 own pdf", c, t.passed_own());
            }
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
        // Against the sampler's own pdf: every sample drawn, a last bin for those that landed
        // in no cell (lost, as brdf-validate counts them).
        let chi2_own = self
            .results
            .expected_own
            .as_ref()
            .filter(|(g, p)| g == grid && p.len() == mass.len())
            .and_then(|(_, p)| {
                chi_square_with_lost(&samples.counts, samples.drawn - landed, samples.drawn, p)
            });
        Some(LiveTest {
            samples: landed,
            chi2: chi_square(&histogram.observed, &histogram.expected),
            chi2_own,
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
                    self.results.expected_own = None;
                    self.results.samples = None;
                }
                Update::ExpectedOwn(_, probability) => {
                    self.results.expected_own = Some((self.inputs.grid(), probability));
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
                    self.results.expected_own = None;
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
                Command::SetWiAt(p) => self.drag_wi(p),
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
        let mut commands = Vec::new();
        egui::CentralPanel::default().show(ui, |ui| {
            let avail = ui.available_size();
            let top = (avail.y * 0.58).min(avail.x * 0.5).max(120.0);
            ui.horizontal(|ui| {
                let texture = match self.style.background {
                    Background::Fr => self.fr_texture.as_ref(),
                    _ => self.leaf_texture.as_ref().or(self.fr_texture.as_ref()),
                };
                let tree = self.results.tree.as_ref().map(|t| &*t.0);
                let scene = DiskScene {
                    map: self.inputs.map,
                    wi: self.wi(),
                    texture,
                    outlines: tree.filter(|t| self.style.outlines && t.map() == self.inputs.map),
                    points: self
                        .results
                        .samples
                        .as_ref()
                        .filter(|_| self.style.points)
                        .map(|s| s.points.as_slice()),
                };
                let disk = DiskView::ui(ui, top, &scene, &mut commands);
                self.view_rects.insert("disk", disk.rect);
                self.caption_rect = disk.caption;
                let lobe_w = (ui.available_width()).max(120.0);
                let wi = self.wi();
                let lobe = LobeView::ui(
                    ui,
                    vec2(lobe_w, top),
                    &mut self.camera,
                    self.lobe.as_ref(),
                    self.has_wgpu,
                    wi,
                );
                self.view_rects.insert("lobe", lobe);
            });
            let rest = ui.available_height() - 44.0;
            let side = (rest).min((avail.x - 24.0) / 3.0).max(80.0);
            let test = self.live_test();
            let rects = HistogramsView::ui(ui, side, test.as_ref());
            for (name, rect) in ["observed", "expected", "difference"]
                .into_iter()
                .zip(rects)
            {
                self.view_rects.insert(name, rect);
            }
        });
        self.execute(&ctx, commands);
        if !self.is_idle() {
            ctx.request_repaint_after(std::time::Duration::from_millis(50));
        }
    }
}
