//! The real-window smoke test: the `viewer` binary opens an eframe window under Xvfb (wgpu on
//! Mesa's software Vulkan or GL), waits for its work, captures its framebuffer and exits.
//! `.ci/run` installs `xvfb` and `mesa-vulkan-drivers`; without `xvfb-run` the test fails on
//! CI (`CI` set) and is skipped with a message elsewhere.

use std::process::Command;

#[test]
fn the_viewer_opens_a_real_window_under_xvfb_and_draws_something() {
    let found = Command::new("sh")
        .args(["-c", "command -v xvfb-run"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        assert!(
            std::env::var_os("CI").is_none(),
            "xvfb-run is missing on CI: .ci/run must install xvfb"
        );
        eprintln!("skipped: xvfb-run is not installed (apt-get install xvfb mesa-vulkan-drivers)");
        return;
    }
    let dir = std::env::temp_dir().join(format!("viewer-window-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("window.png");
    let export = dir.join("export");
    let out = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1600x1000x24"])
        .arg(env!("CARGO_BIN_EXE_viewer"))
        .args(["--screenshot"])
        .arg(&png)
        .args([
            "--window",
            "--model",
            "ward",
            "--samples",
            "20000",
            "--size",
            "1200x800",
        ])
        .arg("--export")
        .arg(&export)
        .args(["--timeout", "240"])
        .output()
        .expect("running xvfb-run");
    let log = format!(
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "the viewer failed under Xvfb:\n{log}");
    // The summary printed at the capture: the tree, the 20 000 samples and a passing χ².
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("tree: "), "{log}");
    assert!(stdout.contains("samples: 20000 drawn"), "{log}");
    assert!(stdout.contains(" pass at alpha"), "{log}");
    let image = image::open(&png)
        .expect("the screenshot is a PNG")
        .to_rgba8();
    assert_eq!((image.width(), image.height()), (1200, 800), "{log}");
    assert!(
        viewer::screenshot::looks_rendered(&image, 200),
        "the window screenshot looks blank"
    );
    // The export from the real window: each view is a non-blank crop.
    for view in ["disk", "lobe", "observed", "expected", "difference"] {
        let v = image::open(export.join(format!("{view}.png")))
            .unwrap()
            .to_rgba8();
        assert!(
            viewer::screenshot::looks_rendered(&v, 8),
            "{view} looks blank"
        );
    }
    assert!(export.join("maps.exr").exists() && export.join("cells.exr").exists());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_offscreen_screenshot_mode_writes_a_picture_and_the_exports() {
    let dir = std::env::temp_dir().join(format!("viewer-offscreen-{}", std::process::id()));
    let png = dir.join("shot.png");
    let export = dir.join("export");
    let out = Command::new(env!("CARGO_BIN_EXE_viewer"))
        .arg("--screenshot")
        .arg(&png)
        .arg("--export")
        .arg(&export)
        .args([
            "--model",
            "cook-torrance",
            "--param",
            "m=0.2",
            "--wi",
            "0.5,0.1,0.8",
        ])
        .args(["--samples", "10000", "--size", "1000x700"])
        .output()
        .expect("running the viewer");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("model cook-torrance"), "{stdout}");
    assert!(stdout.contains("samples: 10000 drawn"), "{stdout}");
    let image = image::open(&png).unwrap().to_rgba8();
    assert_eq!((image.width(), image.height()), (1000, 700));
    assert!(viewer::screenshot::looks_rendered(&image, 200));
    for view in ["disk", "lobe", "observed", "expected", "difference"] {
        let v = image::open(export.join(format!("{view}.png")))
            .unwrap()
            .to_rgba8();
        assert!(
            v.width() > 50 && v.height() > 50,
            "{view}: {}x{}",
            v.width(),
            v.height()
        );
        assert!(
            viewer::screenshot::looks_rendered(&v, 8),
            "{view} looks blank"
        );
    }
    // The raw maps read back: f_r is NaN exactly outside the disk, and the cells hold every sample.
    let maps = exr::prelude::read_all_flat_layers_from_file(export.join("maps.exr")).unwrap();
    let layer = &maps.layer_data[0];
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    for n in ["fr", "leaf_probability", "leaf_acceptance", "leaf_depth"] {
        assert!(
            names.iter().any(|x| x == n),
            "maps.exr lacks {n}: {names:?}"
        );
    }
    let cells = exr::prelude::read_all_flat_layers_from_file(export.join("cells.exr")).unwrap();
    let observed = cells.layer_data[0]
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == "observed")
        .unwrap();
    let total: f64 = match &observed.sample_data {
        exr::prelude::FlatSamples::F32(v) => v.iter().map(|&x| f64::from(x)).sum(),
        _ => panic!("observed is not f32"),
    };
    assert_eq!(total, 10_000.0);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_arguments_exit_2_with_a_message() {
    for args in [
        &["--model", "nope", "--screenshot", "/tmp/x.png"][..],
        &["--wi", "0,0,-1", "--screenshot", "/tmp/x.png"],
        &["--wi", "nan,0,1", "--screenshot", "/tmp/x.png"],
        &[
            "--param",
            "n=-3",
            "--model",
            "phong",
            "--screenshot",
            "/tmp/x.png",
        ],
        &["--size", "10x10", "--screenshot", "/tmp/x.png"],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_viewer"))
            .args(args)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.starts_with("viewer: "), "{args:?}: {err}");
    }
}
