//! `viewer`: the live BRDF sampling laboratory (egui/eframe on wgpu).
//!
//! This first version shows f_r(wi, ·) over the seed's square [−1,1]² (the orthographic disk)
//! for any registry model, with sliders generated from the parameter metadata and the
//! incident direction as θ/φ sliders. The quadtree, samples and histograms join it as the
//! sampler and validation crates land.

mod heatmap;

use brdf_core::registry::{self, ModelInfo};
use brdf_core::{Brdf, ParamKind, ParamSet, ParamValue, geometry::spherical_direction};
use eframe::egui;

fn main() -> eframe::Result {
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size([1100.0, 720.0])
            .with_title("brdf-sampling viewer"),
        ..Default::default()
    };
    eframe::run_native(
        "brdf-sampling viewer",
        options,
        Box::new(|_cc| Ok(Box::new(ViewerApp::new()))),
    )
}

/// The whole state of the viewer.
struct ViewerApp {
    model: &'static ModelInfo,
    params: ParamSet,
    brdf: Result<Box<dyn Brdf>, String>,
    theta_deg: f32,
    phi_deg: f32,
    log_scale: bool,
    texture: Option<egui::TextureHandle>,
    dirty: bool,
}

impl ViewerApp {
    fn new() -> Self {
        let model = registry::find("ward").expect("ward is registered");
        let mut app = Self {
            model,
            params: model.defaults(),
            brdf: Err(String::new()),
            theta_deg: 45.0,
            phi_deg: 0.0,
            log_scale: false,
            texture: None,
            dirty: true,
        };
        app.rebuild();
        app
    }

    fn rebuild(&mut self) {
        self.brdf = self.model.build(&self.params).map_err(|e| e.to_string());
        self.dirty = true;
    }

    fn wi(&self) -> glam::Vec3 {
        spherical_direction(self.theta_deg.to_radians(), self.phi_deg.to_radians())
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        ui.heading("Model");
        let mut chosen = self.model.name;
        egui::ComboBox::from_id_salt("model")
            .selected_text(chosen)
            .show_ui(ui, |ui| {
                for m in registry::models() {
                    ui.selectable_value(&mut chosen, m.name, m.name);
                }
            });
        if chosen != self.model.name {
            self.model = registry::find(chosen).expect("picked from the registry");
            self.params = self.model.defaults();
            self.rebuild();
        }
        ui.label(self.model.summary);
        ui.separator();
        let mut changed = false;
        for spec in self.model.params {
            let value = self.params.get(spec.name).expect("spec of this model");
            let mut v = value.rgb().to_array();
            let channels = match spec.kind {
                ParamKind::Scalar => 1,
                ParamKind::Rgb => 3,
            };
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
                        .changed();
                }
            });
            let new = match spec.kind {
                ParamKind::Scalar => ParamValue::Scalar(v[0]),
                ParamKind::Rgb => ParamValue::Rgb(glam::Vec3::from_array(v)),
            };
            // Values outside an open range end (e.g. (0, 1]) are refused by `set`: keep the old.
            let _ = self.params.set(spec.name, new);
        }
        if changed {
            self.rebuild();
        }
        ui.separator();
        ui.heading("Incident direction");
        self.dirty |= ui
            .add(egui::Slider::new(&mut self.theta_deg, 0.0..=89.9).text("θi (deg)"))
            .changed();
        self.dirty |= ui
            .add(egui::Slider::new(&mut self.phi_deg, -180.0..=180.0).text("φi (deg)"))
            .changed();
        self.dirty |= ui.checkbox(&mut self.log_scale, "log scale").changed();
        if let Err(e) = &self.brdf {
            ui.colored_label(egui::Color32::RED, e);
        }
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        egui::Panel::left("controls")
            .default_size(300.0)
            .show(ui, |ui| self.controls(ui));
        if self.dirty {
            if let Ok(brdf) = &self.brdf {
                let image = heatmap::luminance_map(&**brdf, self.wi(), 256, self.log_scale);
                self.texture = Some(ui.ctx().load_texture(
                    "f_r",
                    image,
                    egui::TextureOptions::NEAREST,
                ));
            }
            self.dirty = false;
        }
        egui::CentralPanel::default().show(ui, |ui| {
            ui.label(
                "f_r(wi, wo) over the projected disk (the seed's square [-1,1]², x right, y up)",
            );
            if let Some(tex) = &self.texture {
                let side = ui.available_width().min(ui.available_height()).max(64.0);
                ui.image((tex.id(), egui::vec2(side, side)));
            }
        });
    }
}
