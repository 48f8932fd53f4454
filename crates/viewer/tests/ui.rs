//! Pixel-free interaction tests (egui_kittest drives the real app; the worker thread runs
//! for real) and a small snapshot of the rendered window (wgpu on a software adapter).

use eframe::egui;
use egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use std::time::{Duration, Instant};
use viewer::{Launch, ViewerApp};

fn harness(launch: Launch) -> Harness<'static, ViewerApp> {
    let resolved = launch.resolve().expect("a valid launch");
    Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_eframe(move |cc| ViewerApp::new(cc, resolved))
}

/// Steps frames until the app's newest job is done (the worker runs on its own thread).
fn settle(h: &mut Harness<'_, ViewerApp>) {
    let start = Instant::now();
    h.run_steps(2);
    while !h.state().is_idle() {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "the worker did not finish"
        );
        std::thread::sleep(Duration::from_millis(5));
        h.step();
    }
    h.run_steps(2);
}

fn small(model: &str) -> Launch {
    Launch {
        model: model.into(),
        samples: 20_000,
        ..Launch::default()
    }
}

#[test]
fn picking_a_model_in_the_combo_box_rebuilds_the_tree_and_the_histograms() {
    let mut h = harness(small("ward"));
    settle(&mut h);
    let ward = h.state().tree_stats().expect("a tree for ward").clone();
    assert!(h.state().live_test().is_some());
    h.get_by_role_and_label(Role::ComboBox, "model").click();
    h.run_steps(2);
    h.get_by_label("phong").click();
    h.run_steps(2);
    assert_eq!(h.state().model_name(), "phong");
    settle(&mut h);
    let phong = h.state().tree_stats().expect("a tree for phong").clone();
    assert_ne!(
        ward.nodes, phong.nodes,
        "the tree did not change with the model"
    );
    let test = h.state().live_test().expect("histograms for phong");
    assert_eq!(test.samples, 20_000);
    assert!(test.passed(), "{:?}", test.chi2);
}

#[test]
fn moving_the_theta_slider_moves_wi_and_rebuilds() {
    let mut h = harness(small("phong"));
    settle(&mut h);
    let before = h.state().tree_stats().unwrap().clone();
    h.get_by_role_and_label(Role::Slider, "θi (deg)")
        .set_value_accesskit(70.0);
    h.run_steps(2);
    assert!(
        (h.state().inputs().theta_deg - 70.0).abs() < 1e-3,
        "θ = {}",
        h.state().inputs().theta_deg
    );
    settle(&mut h);
    let after = h.state().tree_stats().unwrap().clone();
    assert_ne!(before, after, "the tree did not follow wi");
    // The drawn samples are for the new direction. Samples left over from θ = 45° (a lobe
    // 25° away) give a p-value of essentially zero against the new f·cos; samples for 70°
    // pass a test at 1e-4 but for a one-in-ten-thousand draw. (The panel's verdict is at
    // ALPHA = 0.01, which one fixed seed in a hundred rejects by design.)
    let test = h.state().live_test().unwrap();
    let p = test.chi2.as_ref().map(|c| c.p_value);
    assert!(p.is_some_and(|p| p >= 1e-4), "{:?}", test.chi2);
}

#[test]
fn dragging_on_the_disk_sets_the_incident_direction() {
    let mut h = harness(small("phong"));
    settle(&mut h);
    let rect = h
        .state()
        .view_rect("disk")
        .expect("the disk view was drawn");
    // The square point (−0.5, 0.5): θ = asin(|p|) = 45°, φ = 135°.
    let target = egui::pos2(
        rect.center().x - 0.25 * rect.width(),
        rect.center().y - 0.25 * rect.height(),
    );
    h.drag_at(target);
    h.run_steps(1);
    h.drop_at(target);
    h.run_steps(2);
    let (theta, phi) = (h.state().inputs().theta_deg, h.state().inputs().phi_deg);
    assert!((theta - 45.0).abs() < 1.0, "θ = {theta}");
    assert!((phi - 135.0).abs() < 1.0, "φ = {phi}");
    let p = h.state().wi_square_point();
    assert!(
        (p.x + 0.5).abs() < 0.02 && (p.y - 0.5).abs() < 0.02,
        "{p:?}"
    );
    settle(&mut h);
}

#[test]
fn a_delta_model_says_why_it_has_no_tree() {
    let mut h = harness(small("ward"));
    settle(&mut h);
    h.state_mut().set_model("mirror").unwrap();
    settle(&mut h);
    let e = h.state().error().expect("an error for a delta model");
    assert!(e.contains("Dirac delta"), "{e}");
    assert!(h.state().tree_stats().is_none());
    // And back to a continuous model: the error clears.
    h.state_mut().set_model("lambert").unwrap();
    settle(&mut h);
    assert!(h.state().error().is_none());
    assert!(h.state().tree_stats().is_some());
}

#[test]
fn bad_launches_are_typed_errors() {
    let bad = |l: Launch| l.resolve().expect_err("should be refused");
    assert!(
        bad(Launch {
            model: "nope".into(),
            ..Launch::default()
        })
        .contains("nope")
    );
    let e = bad(Launch {
        params: vec!["alpha_x=-1".into()],
        ..Launch::default()
    });
    assert!(e.contains("alpha_x"), "{e}");
    let e = bad(Launch {
        wi: Some(glam::Vec3::new(0.0, 0.5, -1.0)),
        ..Launch::default()
    });
    assert!(e.contains("--wi"), "{e}");
    let e = bad(Launch {
        wi: Some(glam::Vec3::new(f32::NAN, 0.0, 1.0)),
        ..Launch::default()
    });
    assert!(e.contains("--wi"), "{e}");
    assert!(
        bad(Launch {
            samples: 0,
            ..Launch::default()
        })
        .contains("--samples")
    );
    // Beyond the sliders' 89°: refused, not moved to 89° behind the user's back.
    let e = bad(Launch {
        wi: Some(glam::Vec3::new(1.0, 0.0, 1e-3)),
        ..Launch::default()
    });
    assert!(e.contains("--wi") && e.contains("89"), "{e}");
    // At 89° exactly it is used as given.
    let at89 = Launch {
        wi: Some(glam::Vec3::new(
            89f32.to_radians().sin(),
            0.0,
            89f32.to_radians().cos(),
        )),
        ..Launch::default()
    };
    assert!(at89.resolve().is_ok());
}

#[test]
fn snapshot_of_the_window() {
    let resolved = Launch {
        model: "phong".into(),
        params: vec!["n=200".into()],
        samples: 5_000,
        ..Launch::default()
    }
    .resolve()
    .unwrap();
    let mut h = Harness::builder()
        .with_size(egui::vec2(900.0, 560.0))
        .wgpu()
        .build_eframe(move |cc| ViewerApp::new(cc, resolved));
    settle(&mut h);
    // The disk view's caption wraps inside the view instead of running past its edge.
    let (disk, caption) = (
        h.state().view_rect("disk").unwrap(),
        h.state().disk_caption_rect(),
    );
    assert!(
        caption.height() > 0.0 && disk.contains_rect(caption),
        "{caption:?} outside {disk:?}"
    );
    h.snapshot("viewer_phong");
}

#[test]
fn a_newer_request_abandons_the_stale_job() {
    use brdf_validate::CellGrid;
    use quadtree_sampler::BuildConfig;
    use std::sync::Arc;
    use viewer::worker::{Request, SamplerKind, Update, Worker};
    let phong: Arc<dyn brdf_core::Brdf> =
        Arc::from(brdf_core::registry::create("phong", ["n=100"]).unwrap());
    let request = |generation, samples| Request {
        generation,
        brdf: Arc::clone(&phong),
        wi: glam::Vec3::new(0.5, 0.0, 0.866),
        config: BuildConfig::default(),
        sampler: SamplerKind::Rejection,
        samples,
        grid: CellGrid::Square { res: 8 },
        seed: 3,
        map_res: 32,
        lobe_res: 8,
    };
    let worker = Worker::spawn(|| {});
    // 10⁹ samples would take minutes; the newer request must cut it short.
    worker.submit(request(1, 1_000_000_000));
    std::thread::sleep(Duration::from_millis(200));
    worker.submit(request(2, 20_000));
    let start = Instant::now();
    let mut stale_drawn = 0;
    loop {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "generation 2 never finished"
        );
        let mut done = false;
        for u in worker.poll() {
            match u {
                Update::Done(1) => panic!("the stale job ran to completion"),
                Update::Samples(1, s) => stale_drawn = s.drawn,
                Update::Done(2) => done = true,
                _ => {}
            }
        }
        if done {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(stale_drawn < 1_000_000_000);
}

#[test]
fn the_live_verdict_rejects_a_sampler_that_does_not_follow_f_cos() {
    // Cosine sampling of a Phong lobe (n = 200): the histograms must reject it.
    let mut h = harness(Launch {
        params: vec!["n=200".into()],
        ..small("phong")
    });
    settle(&mut h);
    let tree = h.state().live_test().unwrap();
    assert!(tree.passed());
    // The tree's own rejection sampler is judged against f·cos alone.
    assert!(tree.chi2_own.is_none());
    h.get_by_role_and_label(Role::ComboBox, "sampler").click();
    h.run_steps(2);
    h.get_by_label("cosine").click();
    h.run_steps(2);
    settle(&mut h);
    let test = h
        .state()
        .live_test()
        .expect("histograms for the cosine sampler");
    assert_eq!(test.samples, 20_000);
    let p = test.chi2.as_ref().unwrap().p_value;
    assert!(
        !test.passed() && p < 1e-6,
        "cosine vs phong n=200 passed: p = {p}"
    );
    // Against its own pdf (cos θ/π, integrated over the cells) the same samples pass: the
    // second χ² looks at the density the sampler claims, not at f·cos.
    assert!(
        test.passed_own(),
        "cosine vs its own pdf: {:?}",
        test.chi2_own
    );
}

#[test]
fn the_baked_sampler_follows_the_lobe_off_its_grid() {
    // The baked sampler at wi between its grid rows (θ = 45°): its histograms follow f·cos,
    // and it says so by the same live χ² that rejects cosine sampling above.
    let mut h = harness(Launch {
        params: vec!["n=200".into()],
        ..small("phong")
    });
    settle(&mut h);
    h.get_by_role_and_label(Role::ComboBox, "sampler").click();
    h.run_steps(2);
    h.get_by_label("baked").click();
    h.run_steps(2);
    settle(&mut h);
    let test = h
        .state()
        .live_test()
        .expect("histograms for the baked sampler");
    // A few samples are lost: a neighbour's rotation sends them below the horizon.
    assert!(
        (19_900..=20_000).contains(&test.samples),
        "{}",
        test.samples
    );
    // Both χ² are judged at 10⁻³ here, not at the panel's ALPHA = 0.01: one fixed seed in a
    // hundred fails that by design, and any change to the sampling stream draws anew. Over
    // seeds 1–2000 of this job, replicated outside the viewer with the corner-hat draw's
    // stream, both p-values were uniform (Kolmogorov–Smirnov D = 0.017 and 0.019 against
    // 0.030 at 5 %; 10 and 11 of 2000 under 0.01), and seed 1 gave p = 0.0077 against f·cos:
    // chance, not a bias.
    let p = |c: &Option<brdf_validate::ChiSquare>| c.as_ref().map(|c| c.p_value);
    assert!(
        p(&test.chi2).is_some_and(|p| p >= 1e-3),
        "baked vs phong n=200: {:?}",
        test.chi2
    );
    // And against its own pdf, the exact mixture of its rotated neighbours (issue #18,
    // item 8), with the lost samples in a bin of their own.
    assert!(
        p(&test.chi2_own).is_some_and(|p| p >= 1e-3),
        "baked vs its own pdf: {:?}",
        test.chi2_own
    );
}

/// A file dropped on the window, as an integration delivers it.
#[derive(Debug)]
struct Dropped(std::path::PathBuf);

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &std::path::Path {
        &self.0
    }
    fn bytes(&self) -> Result<Vec<u8>, String> {
        std::fs::read(&self.0).map_err(|e| e.to_string())
    }
}

/// A measured BRDF opens by dropping its file on the window: the model becomes `merl`, the
/// tree and the live test follow it like any model; a malformed file's error shows in the
/// window (naming the file) beside the path field, and a good file then opens.
#[test]
fn a_dropped_measured_file_opens_as_merl_and_errors_show_in_the_window() {
    use brdf_core::models::merl;
    let dir = std::env::temp_dir().join(format!("viewer-merl-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let good = dir.join("phong.binary");
    let phong = brdf_core::registry::create("phong", ["n=50"]).unwrap();
    let bytes = merl::encode(&merl::tabulate(&*phong));
    std::fs::write(&good, &bytes).unwrap();
    let bad = dir.join("truncated.binary");
    std::fs::write(&bad, &bytes[..1000]).unwrap();

    let mut h = harness(small("lambert"));
    settle(&mut h);
    h.input_mut()
        .dropped_files
        .push(std::sync::Arc::new(Dropped(bad.clone())));
    h.run_steps(2);
    assert_eq!(h.state().model_name(), "merl");
    let e = h
        .state()
        .model_error()
        .expect("a truncated file is an error");
    assert!(
        e.contains("truncated") && e.contains("truncated.binary"),
        "{e}"
    );
    // Shown in the window: the error names the file, and the path field is there to fix it.
    assert!(
        h.get_all_by_label_contains("truncated: 1000 bytes")
            .next()
            .is_some()
    );
    h.get_by_label("open");
    h.state_mut().open_file(&good);
    settle(&mut h);
    assert!(h.state().model_error().is_none());
    let stats = h
        .state()
        .tree_stats()
        .expect("a tree for the measured file");
    assert!(stats.expected_trials <= 2.0, "{stats:?}");
    assert!(h.state().live_test().unwrap().passed());
    std::fs::remove_dir_all(&dir).unwrap();
}
