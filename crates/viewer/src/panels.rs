//! The left-hand panels, one small type each with its own `ui` (the shape of egui's demo
//! windows): they edit the part of the state they show ([`Inputs`], [`Style`]) and report
//! every side effect as a [`Command`], which [`crate::ViewerApp`] executes in one place after
//! the frame's panels are drawn.

use crate::views::Background;
use crate::worker::{SampleState, SamplerKind};
use brdf_core::geometry::spherical_direction;
use brdf_core::registry::{self, ModelInfo};
use brdf_core::{DiskMap, ParamKind, ParamSet, ParamSpec, ParamValue};
use brdf_validate::CellGrid;
use eframe::egui::{self, Color32};
use glam::Vec3;
use quadtree_sampler::{BuildConfig, TreeStats};
use std::path::PathBuf;

/// Largest θi the sliders and the disk drag allow, in degrees.
pub const MAX_THETA_DEG: f32 = 89.0;

/// A side effect a panel asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// Switch to the registry model of this name, with its default parameters.
    SetModel(&'static str),
    /// The model's parameters changed: build the BRDF again (and send a new job).
    RebuildModel,
    /// An input of the job changed (wi, the tree's options, the sampler): send a new job.
    Resubmit,
    /// A view option changed: draw the disk view's textures again.
    Restyle,
    /// Move wi to the direction of this point of the tree's square (a drag on the disk view).
    SetWiAt(glam::Vec2),
    /// Export every view and the raw maps into this folder.
    Export(PathBuf),
}

/// Cell layout of the histograms.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridKind {
    /// R × R squares over [−1,1]² (the seed's grid).
    Square,
    /// R rings × (2R+1) sectors of equal area.
    Polar,
}

/// What the user chose: everything a job is made from.
#[derive(Clone, Debug)]
pub struct Inputs {
    /// The model.
    pub model: &'static ModelInfo,
    /// Its parameters.
    pub params: ParamSet,
    /// The text of a path parameter being edited (committed with Enter or "open").
    pub path_text: String,
    /// θi in degrees.
    pub theta_deg: f32,
    /// φi in degrees.
    pub phi_deg: f32,
    /// The tree's map.
    pub map: DiskMap,
    /// Split below this P.
    pub split_threshold: f64,
    /// Deepest level.
    pub max_depth: u8,
    /// Whether the target-E\[T\] mode is on.
    pub use_target: bool,
    /// Its target.
    pub target_trials: f64,
    /// The sampler.
    pub sampler: SamplerKind,
    /// Samples to draw.
    pub samples: u64,
    /// The histograms' cells.
    pub grid_kind: GridKind,
    /// Cells per side, or rings.
    pub cells: usize,
    /// The sampling seed.
    pub seed: u64,
}

impl Inputs {
    /// The incident direction (local frame).
    #[must_use]
    pub fn wi(&self) -> Vec3 {
        spherical_direction(self.theta_deg.to_radians(), self.phi_deg.to_radians())
    }

    /// The histograms' cell grid.
    #[must_use]
    pub fn grid(&self) -> CellGrid {
        match self.grid_kind {
            GridKind::Square => CellGrid::Square { res: self.cells },
            GridKind::Polar => CellGrid::Polar {
                rings: self.cells,
                sectors: 2 * self.cells + 1,
            },
        }
    }

    /// The tree's build options.
    #[must_use]
    pub fn config(&self) -> BuildConfig {
        BuildConfig {
            map: self.map,
            split_threshold: self.split_threshold,
            max_depth: self.max_depth,
            target_trials: self.use_target.then_some(self.target_trials),
            ..BuildConfig::default()
        }
    }
}

/// How the views look (nothing here needs a new job).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Style {
    /// f_r on a log scale.
    pub log_scale: bool,
    /// The disk view's background.
    pub background: Background,
    /// Draw the leaves' outlines.
    pub outlines: bool,
    /// Draw the sample points.
    pub points: bool,
}

impl Default for Style {
    fn default() -> Self {
        Self {
            log_scale: false,
            background: Background::Fr,
            outlines: true,
            points: true,
        }
    }
}

/// The model, its summary and its parameters (scalar and RGB drags, choices, a file path).
pub struct ModelPanel;

impl ModelPanel {
    /// Draws the panel; `error` is the model's build error, if any.
    pub fn ui(ui: &mut egui::Ui, inputs: &mut Inputs, error: Option<&str>, out: &mut Vec<Command>) {
        ui.heading("Model");
        let mut chosen = inputs.model.name;
        egui::ComboBox::from_label("model")
            .selected_text(chosen)
            .show_ui(ui, |ui| {
                for m in registry::models() {
                    ui.selectable_value(&mut chosen, m.name, m.name);
                }
            });
        if chosen != inputs.model.name {
            out.push(Command::SetModel(chosen));
        }
        ui.label(inputs.model.summary);
        let mut changed = false;
        for spec in inputs.model.params {
            let Ok(value) = inputs.params.get(spec.name) else {
                continue;
            };
            match spec.kind {
                ParamKind::Path => {
                    changed |= Self::path_field(ui, inputs, spec);
                    continue;
                }
                ParamKind::Choice(options) => {
                    let mut chosen = value.text().unwrap_or("").to_owned();
                    ui.horizontal(|ui| {
                        ui.label(spec.name).on_hover_text(spec.doc);
                        egui::ComboBox::from_id_salt(spec.name)
                            .selected_text(chosen.clone())
                            .show_ui(ui, |ui| {
                                for o in options {
                                    ui.selectable_value(&mut chosen, (*o).to_owned(), *o);
                                }
                            });
                    });
                    if Some(chosen.as_str()) != value.text()
                        && let Some(o) = options.iter().find(|o| **o == chosen)
                    {
                        changed |= inputs.params.set(spec.name, ParamValue::Choice(o)).is_ok();
                    }
                    continue;
                }
                ParamKind::Scalar | ParamKind::Rgb => {}
            }
            let mut v = value.rgb().to_array();
            let channels = if spec.kind == ParamKind::Rgb { 3 } else { 1 };
            ui.horizontal(|ui| {
                ui.label(spec.name).on_hover_text(spec.doc);
                for c in v.iter_mut().take(channels) {
                    let speed = (spec.max - spec.min) / 300.0;
                    changed |= ui
                        .add(
                            egui::DragValue::new(c)
                                .range(spec.min..=spec.max)
                                .speed(speed),
                        )
                        .on_hover_text(spec.doc)
                        .changed();
                }
            });
            let new = if spec.kind == ParamKind::Rgb {
                ParamValue::Rgb(Vec3::from_array(v))
            } else {
                ParamValue::Scalar(v[0])
            };
            // A value at an open end of its range (e.g. 0 for (0, 1]) is refused: keep the old.
            let _ = inputs.params.set(spec.name, new);
        }
        if changed {
            out.push(Command::RebuildModel);
        }
        if let Some(e) = error {
            ui.colored_label(Color32::LIGHT_RED, e);
        }
    }

    /// A path parameter: a text field committed with Enter or the "open" button (a file is
    /// read once per commit, not per keystroke). Returns whether the value changed.
    fn path_field(ui: &mut egui::Ui, inputs: &mut Inputs, spec: &'static ParamSpec) -> bool {
        let mut commit = false;
        ui.label(spec.name).on_hover_text(spec.doc);
        ui.horizontal(|ui| {
            let edit = ui.add(
                egui::TextEdit::singleline(&mut inputs.path_text)
                    .hint_text("path to a .binary file, or drop one on the window")
                    .desired_width(200.0),
            );
            commit |= edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            commit |= ui.button("open").clicked();
        });
        if !commit {
            return false;
        }
        let path = ParamValue::Path(inputs.path_text.trim().to_owned());
        inputs.params.set(spec.name, path).is_ok()
    }
}

/// θi and φi (also set by dragging on the disk view).
pub struct IncidentPanel;

impl IncidentPanel {
    /// Draws the panel.
    pub fn ui(ui: &mut egui::Ui, inputs: &mut Inputs, out: &mut Vec<Command>) {
        ui.heading("Incident direction");
        let mut moved = ui
            .add(egui::Slider::new(&mut inputs.theta_deg, 0.0..=MAX_THETA_DEG).text("θi (deg)"))
            .changed();
        moved |= ui
            .add(egui::Slider::new(&mut inputs.phi_deg, -180.0..=180.0).text("φi (deg)"))
            .changed();
        ui.small("or drag on the disk view");
        if moved {
            out.push(Command::Resubmit);
        }
    }
}

/// The tree's build options: map, split threshold, depth, target E\[T\].
pub struct TreePanel;

impl TreePanel {
    /// Draws the panel.
    pub fn ui(ui: &mut egui::Ui, inputs: &mut Inputs, out: &mut Vec<Command>) {
        ui.heading("Tree");
        let mut rebuild = false;
        egui::ComboBox::from_label("map")
            .selected_text(inputs.map.name())
            .show_ui(ui, |ui| {
                for m in [DiskMap::Orthographic, DiskMap::Concentric] {
                    rebuild |= ui.selectable_value(&mut inputs.map, m, m.name()).changed();
                }
            });
        rebuild |= ui
            .add(egui::Slider::new(&mut inputs.split_threshold, 0.05..=0.95).text("split below P"))
            .changed();
        rebuild |= ui
            .add(egui::Slider::new(&mut inputs.max_depth, 1..=20).text("max depth"))
            .changed();
        ui.horizontal(|ui| {
            let check = ui.checkbox(&mut inputs.use_target, "target E[T]");
            rebuild |= check.changed();
            rebuild |= ui
                .add_enabled(
                    inputs.use_target,
                    // E[T] cannot fall below the bounds' safety factor (1.02, a build
                    // error below it), and just above it a tree splits to its node budget.
                    egui::DragValue::new(&mut inputs.target_trials)
                        .range(1.05..=4.0)
                        .speed(0.01),
                )
                .labelled_by(check.id)
                .changed();
        });
        if rebuild {
            out.push(Command::Resubmit);
        }
    }
}

/// The sampler, the sample count, the histograms' cells and the seed.
pub struct SamplesPanel;

impl SamplesPanel {
    /// Draws the panel.
    pub fn ui(ui: &mut egui::Ui, inputs: &mut Inputs, out: &mut Vec<Command>) {
        ui.heading("Samples");
        let mut rebuild = false;
        egui::ComboBox::from_label("sampler")
            .selected_text(inputs.sampler.name())
            .show_ui(ui, |ui| {
                for k in SamplerKind::ALL {
                    rebuild |= ui
                        .selectable_value(&mut inputs.sampler, k, k.name())
                        .changed();
                }
            });
        rebuild |= ui
            .add(
                egui::Slider::new(&mut inputs.samples, 1_000..=10_000_000)
                    .logarithmic(true)
                    .text("samples"),
            )
            .changed();
        ui.horizontal(|ui| {
            rebuild |= ui
                .radio_value(&mut inputs.grid_kind, GridKind::Square, "square cells")
                .changed();
            rebuild |= ui
                .radio_value(&mut inputs.grid_kind, GridKind::Polar, "polar cells")
                .changed();
        });
        rebuild |= ui
            .add(egui::Slider::new(&mut inputs.cells, 4..=40).text("cells per side / rings"))
            .changed();
        rebuild |= ui
            .add(egui::DragValue::new(&mut inputs.seed).prefix("seed "))
            .changed();
        if rebuild {
            out.push(Command::Resubmit);
        }
    }
}

/// How the disk view looks.
pub struct ViewPanel;

impl ViewPanel {
    /// Draws the panel.
    pub fn ui(ui: &mut egui::Ui, style: &mut Style, out: &mut Vec<Command>) {
        ui.heading("View");
        let mut restyle = ui.checkbox(&mut style.log_scale, "log scale").changed();
        for (bg, label) in Background::ALL {
            restyle |= ui.radio_value(&mut style.background, bg, label).changed();
        }
        ui.checkbox(&mut style.outlines, "leaf outlines");
        ui.checkbox(&mut style.points, "sample points");
        if restyle {
            out.push(Command::Restyle);
        }
    }
}

/// The export folder and button, and how the last export went.
pub struct ExportPanel {
    /// The folder to export into.
    pub dir: String,
    /// What the last export wrote, or why it failed.
    pub status: Option<String>,
}

impl ExportPanel {
    /// Draws the panel.
    pub fn ui(&mut self, ui: &mut egui::Ui, out: &mut Vec<Command>) {
        ui.heading("Export");
        ui.horizontal(|ui| {
            let label = ui.label("folder");
            ui.text_edit_singleline(&mut self.dir).labelled_by(label.id);
            if ui.button("Export PNG + EXR").clicked() {
                out.push(Command::Export(PathBuf::from(&self.dir)));
            }
        });
        if let Some(s) = &self.status {
            ui.small(s);
        }
    }
}

/// What the stats panel shows.
pub struct StatsView<'a> {
    /// Whether a job is still running.
    pub busy: bool,
    /// The last error, if any.
    pub error: Option<&'a str>,
    /// The tree's statistics, build seconds and albedo.
    pub tree: Option<(&'a TreeStats, f64, f64)>,
    /// The sample tallies.
    pub samples: Option<&'a SampleState>,
}

/// The tree's statistics and the sampling tallies.
pub struct StatsPanel;

impl StatsPanel {
    /// Draws the panel.
    pub fn ui(ui: &mut egui::Ui, view: &StatsView<'_>) {
        ui.heading("Stats");
        if view.busy {
            ui.horizontal(|ui| {
                ui.spinner();
                let progress = view
                    .samples
                    .map_or(0.0, |s| s.drawn as f32 / s.target.max(1) as f32);
                ui.add(egui::ProgressBar::new(progress).show_percentage());
            });
        }
        if let Some(e) = view.error {
            ui.colored_label(Color32::LIGHT_RED, e);
        }
        egui::Grid::new("stats").num_columns(2).show(ui, |ui| {
            if let Some((s, seconds, albedo)) = view.tree {
                row(ui, "nodes", s.nodes.to_string());
                row(
                    ui,
                    "leaves",
                    format!("{} ({} live)", s.leaves, s.live_leaves),
                );
                row(ui, "depth", s.max_depth.to_string());
                row(ui, "E[T] (tree)", format!("{:.3}", s.expected_trials));
                row(
                    ui,
                    "bytes",
                    format!("{} ({} per node)", s.bytes, s.bytes / s.nodes.max(1)),
                );
                row(ui, "build", format!("{:.1} ms", seconds * 1e3));
                row(ui, "albedo", format!("{albedo:.4}"));
            }
            if let Some(s) = view.samples {
                row(ui, "drawn", format!("{} / {}", s.drawn, s.target));
                let ok = s.drawn - s.lost;
                row(
                    ui,
                    "trials / sample",
                    format!("{:.3}", s.trials as f64 / ok.max(1) as f64),
                );
                row(
                    ui,
                    "sampling",
                    format!("{:.0} ns / sample", s.seconds * 1e9 / s.drawn.max(1) as f64),
                );
                row(ui, "lost", s.lost.to_string());
                row(ui, "bound violations", s.bound_violations.to_string());
                if !s.mixture.is_empty() {
                    // The baked sampler's grid trees at wi: one where the bake found that its
                    // neighbours agree (or the first everywhere, for a model that does not
                    // depend on wi), else the blend.
                    let trees: Vec<String> = s
                        .mixture
                        .iter()
                        .map(|t| {
                            if t.phi_deg == 0.0 {
                                format!("θ {:.1}° × {:.2}", t.theta_deg, t.weight)
                            } else {
                                format!(
                                    "θ {:.1}° φ {:.1}° × {:.2}",
                                    t.theta_deg, t.phi_deg, t.weight
                                )
                            }
                        })
                        .collect();
                    row(ui, "baked trees", trees.join(", "));
                }
            }
        });
    }
}

fn row(ui: &mut egui::Ui, name: &str, value: String) {
    ui.label(name);
    ui.monospace(value);
    ui.end_row();
}
