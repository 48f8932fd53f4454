//! `viewer`: the live BRDF sampling laboratory (egui/eframe on wgpu).
//!
//! Pick a model and its parameters, move the incident direction (sliders or a drag on the
//! disk) and watch, live: f_r over the tree's square [−1,1]² with the quadtree's leaves on
//! top (coloured by selection probability or acceptance P), the sample cloud, the observed
//! and expected histograms with their χ² verdicts (against f·cos and against the sampler's
//! own pdf), and the f_r·cos lobe in 3D. Everything
//! that evaluates the BRDF in bulk runs on a [`worker`] thread; the UI only draws.
//!
//! The binary (`cargo run --release -p viewer`) opens the window; `--screenshot FILE`
//! renders one frame offscreen (egui_kittest's wgpu renderer) and exits.

pub mod app;
pub mod central;
pub mod export;
pub mod grids;
pub mod launch;
pub mod lobe;
pub mod panels;
pub mod screenshot;
pub mod views;
pub mod worker;

pub use app::ViewerApp;
pub use launch::{Launch, Resolved};
