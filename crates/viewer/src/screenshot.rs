//! Headless and windowed screenshots of the full viewer, for scripts and tests.
//!
//! [`offscreen`] drives the app with egui_kittest's harness and renders with wgpu without a
//! window (a software adapter such as lavapipe is preferred, so it runs on CI machines
//! without a GPU). [`windowed`] opens a real eframe window, waits for the work to finish,
//! captures the window's framebuffer and closes it.

use crate::app::ViewerApp;
use crate::launch::Resolved;
use eframe::egui;
use eframe::egui_wgpu;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

/// What a screenshot run produced.
pub struct Shot {
    /// The full window, RGBA.
    pub image: image::RgbaImage,
    /// Files written by `--export`, if asked.
    pub exported: Vec<PathBuf>,
    /// [`ViewerApp::summary`] at the moment of the capture.
    pub summary: String,
}

fn render_state() -> Result<egui_wgpu::RenderState, String> {
    let setup = egui_kittest::wgpu::default_wgpu_setup();
    let instance = pollster::block_on(setup.new_instance());
    pollster::block_on(egui_wgpu::RenderState::create(
        &egui_wgpu::WgpuConfiguration {
            wgpu_setup: setup,
            ..Default::default()
        },
        &instance,
        None,
        egui_wgpu::RendererOptions::PREDICTABLE,
    ))
    .map_err(|e| format!("no wgpu adapter for offscreen rendering: {e}"))
}

/// Renders the viewer for `launch` at `size` points offscreen, once every job has finished
/// (or `timeout` passed: then an error). Optionally exports each view and the raw maps.
pub fn offscreen(
    launch: Resolved,
    size: egui::Vec2,
    timeout: Duration,
    export: Option<&Path>,
) -> Result<Shot, String> {
    let renderer = egui_kittest::wgpu::WgpuTestRenderer::from_render_state(render_state()?);
    let mut harness = egui_kittest::Harness::builder()
        .with_size(size)
        .renderer(renderer)
        .build_eframe(move |cc| ViewerApp::new(cc, launch));
    let start = Instant::now();
    // A few frames first so the first job is submitted, then until it is done.
    harness.run_steps(3);
    while !harness.state().is_idle() {
        if start.elapsed() > timeout {
            return Err(format!(
                "the viewer's work did not finish within {} s",
                timeout.as_secs()
            ));
        }
        std::thread::sleep(Duration::from_millis(5));
        harness.step();
    }
    // Two more frames: the last results become textures, then they are drawn.
    harness.run_steps(2);
    let image = harness.render()?;
    let exported = match export {
        Some(dir) => {
            let color = egui::ColorImage::from_rgba_unmultiplied(
                [image.width() as usize, image.height() as usize],
                image.as_raw(),
            );
            harness.state().export_to(dir, &color, 1.0)?
        }
        None => Vec::new(),
    };
    let summary = harness.state().summary();
    Ok(Shot {
        image,
        exported,
        summary,
    })
}

/// eframe's options for a window of `size` points. The egui pass stays single-sampled
/// (`multisampling` 0), which the lobe view's copy pipeline assumes.
#[must_use]
pub fn native_options(size: egui::Vec2, title: &str) -> eframe::NativeOptions {
    eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_inner_size(size)
            .with_title(title),
        multisampling: 0,
        ..Default::default()
    }
}

/// Wraps the app: once it is idle, asks for a screenshot and closes the window.
struct Capture {
    app: ViewerApp,
    frames_idle: u32,
    requested: bool,
    shot: Arc<std::sync::Mutex<Option<Arc<egui::ColorImage>>>>,
    done: Receiver<()>,
    notify: std::sync::mpsc::Sender<()>,
    start: Instant,
    timeout: Duration,
    export: Option<PathBuf>,
    exported: Arc<std::sync::Mutex<Result<Vec<PathBuf>, String>>>,
    summary: Arc<std::sync::Mutex<String>>,
}

impl eframe::App for Capture {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.app.ui(ui, frame);
        let ctx = ui.ctx().clone();
        if self.done.try_recv().is_ok() {
            if let Ok(mut s) = self.summary.lock() {
                *s = self.app.summary();
            }
            // The same export as the UI's button, from the captured window.
            if let Some(dir) = self.export.take() {
                let image = self.shot.lock().ok().and_then(|s| s.clone());
                let result = match image {
                    Some(image) => self.app.export_to(&dir, &image, ctx.pixels_per_point()),
                    None => Err("no screenshot to export from".into()),
                };
                if let Ok(mut slot) = self.exported.lock() {
                    *slot = result;
                }
            }
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        if self.start.elapsed() > self.timeout {
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        if self.app.is_idle() {
            self.frames_idle += 1;
        }
        if self.frames_idle >= 3 && !self.requested {
            self.requested = true;
            let (slot, notify) = (Arc::clone(&self.shot), self.notify.clone());
            let repaint = ctx.clone();
            ctx.request_screenshot(move |image| {
                if let Ok(mut s) = slot.lock() {
                    *s = Some(image);
                }
                let _ = notify.send(());
                repaint.request_repaint();
            });
        }
        ctx.request_repaint_after(Duration::from_millis(20));
    }
}

/// Opens a real window at `size` points, waits until the work is done, captures the
/// window's framebuffer, optionally exports each view and the raw maps into `export`, and
/// closes. Needs a display (an X server such as Xvfb).
pub fn windowed(
    launch: Resolved,
    size: egui::Vec2,
    timeout: Duration,
    export: Option<&Path>,
) -> Result<Shot, String> {
    let shot = Arc::new(std::sync::Mutex::new(None));
    let slot = Arc::clone(&shot);
    let exported = Arc::new(std::sync::Mutex::new(Ok(Vec::new())));
    let exported_slot = Arc::clone(&exported);
    let export = export.map(Path::to_path_buf);
    let summary = Arc::new(std::sync::Mutex::new(String::new()));
    let summary_slot = Arc::clone(&summary);
    let (notify, done) = channel();
    let options = native_options(size, "brdf-sampling viewer (screenshot)");
    eframe::run_native(
        "brdf-sampling viewer",
        options,
        Box::new(move |cc| {
            Ok(Box::new(Capture {
                app: ViewerApp::new(cc, launch),
                frames_idle: 0,
                requested: false,
                shot: slot,
                done,
                notify,
                start: Instant::now(),
                timeout,
                export,
                exported: exported_slot,
                summary: summary_slot,
            }))
        }),
    )
    .map_err(|e| format!("opening the window failed: {e}"))?;
    let image = shot
        .lock()
        .map_err(|_| "screenshot slot poisoned".to_string())?
        .take()
        .ok_or_else(|| format!("no screenshot within {} s", timeout.as_secs()))?;
    let image = crate::export::to_rgba(&image);
    let exported = exported
        .lock()
        .map_err(|_| "export slot poisoned".to_string())?
        .clone()?;
    let summary = summary
        .lock()
        .map_err(|_| "summary slot poisoned".to_string())?
        .clone();
    Ok(Shot {
        image,
        exported,
        summary,
    })
}

/// Whether an image has real content: more than `min_colors` distinct colours and not
/// one colour covering more than 95 % of it.
#[must_use]
pub fn looks_rendered(image: &image::RgbaImage, min_colors: usize) -> bool {
    let mut counts = std::collections::HashMap::new();
    for p in image.pixels() {
        *counts.entry(p.0).or_insert(0usize) += 1;
    }
    let total = (image.width() * image.height()) as usize;
    let top = counts.values().copied().max().unwrap_or(0);
    counts.len() > min_colors && top * 100 < total * 95
}
