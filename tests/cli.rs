//! The `brdf` command line as SPEC §6 fixes it: run the real binary.

use crate::reference;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;
use std::io::Write;
use std::process::{Command, Output, Stdio};

fn brdf(args: &[&str], stdin: &str) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_brdf"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run brdf");
    child
        .stdin
        .take()
        .unwrap()
        .write_all(stdin.as_bytes())
        // A child may stop reading early (an error on line 1): not a failure of the test.
        .or_else(|e| match e.kind() {
            std::io::ErrorKind::BrokenPipe => Ok(()),
            _ => Err(e),
        })
        .unwrap();
    child.wait_with_output().unwrap()
}

fn stdout(o: &Output) -> String {
    String::from_utf8(o.stdout.clone()).unwrap()
}

#[test]
fn models_json_lists_every_model_with_parameters() {
    let o = brdf(&["models", "--json"], "");
    assert!(o.status.success());
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let models = v.as_array().unwrap();
    let names: Vec<&str> = models.iter().map(|m| m["name"].as_str().unwrap()).collect();
    for want in [
        "lambert",
        "mirror",
        "phong",
        "blinn-phong",
        "lewis-phong",
        "cook-torrance",
        "htsg",
        "poulin-fournier",
        "oren-nayar",
        "ward",
        "schlick",
        "strauss",
        "merl",
    ] {
        assert!(names.contains(&want), "{want} missing from {names:?}");
    }
    assert_eq!(
        names.len(),
        13,
        "MODELS.md's twelve models and the measured one (SPEC §8): {names:?}"
    );
    let phong = models.iter().find(|m| m["name"] == "phong").unwrap();
    let n = phong["params"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "n")
        .unwrap();
    assert_eq!(n["default"], 50.0);
    assert_eq!(n["min"], 0.0);
    assert_eq!(n["max"], 100000.0);
    assert_eq!(n["kind"], "scalar");
    let ct = models
        .iter()
        .find(|m| m["name"] == "cook-torrance")
        .unwrap();
    assert_eq!(
        ct["params"][1]["default"],
        serde_json::json!([0.95, 0.64, 0.54])
    );
    // The plain listing names every model too.
    let text = stdout(&brdf(&["models"], ""));
    for name in names {
        assert!(text.lines().any(|l| l.starts_with(name)), "{name}");
    }
}

/// Parameter sets per model: the defaults and a sharp or unusual setting.
const SETS: &[(&str, &[&str])] = &[
    ("lambert", &[]),
    ("lambert", &["albedo=0.3"]),
    ("mirror", &[]),
    ("phong", &[]),
    ("phong", &["n=10000", "kd=0.05", "ks=0.9"]),
    ("phong", &["n=0"]),
    ("blinn-phong", &[]),
    ("blinn-phong", &["n=3000", "ks=0.8", "kd=0.1"]),
    ("lewis-phong", &[]),
    ("lewis-phong", &["n=100000", "kd=0", "ks=1"]),
    ("cook-torrance", &[]),
    ("cook-torrance", &["m=0.05", "kd=0.3", "f0=0.04"]),
    ("cook-torrance", &["m=1", "f0=0.999"]),
    ("oren-nayar", &[]),
    ("oren-nayar", &["sigma=1.5", "albedo=0.2"]),
    ("oren-nayar", &["sigma=0"]),
    ("ward", &[]),
    ("ward", &["alpha_x=0.02", "alpha_y=0.4", "kd=0"]),
    ("schlick", &[]),
    ("schlick", &["r=0.01", "p=0.05", "c=0.9"]),
    ("schlick", &["r=1", "p=0.5"]),
    ("htsg", &[]),
    ("htsg", &["sigma0=0.0318", "tau=0.3"]),
    ("htsg", &["sigma0=1", "tau=3", "a=0.1"]),
    ("htsg", &["sigma0=0.05", "tau=1", "kappa=0", "eta=1.5"]),
    ("poulin-fournier", &[]),
    (
        "poulin-fournier",
        &["height=0.4", "gap=1.5", "kd=0.3", "ks=0.6", "n=1000"],
    ),
    ("poulin-fournier", &["kd=1", "ks=0", "n=0"]),
    // A broad local lobe (n < 4, 32 nodes in the Gaussian variable and its own cut).
    (
        "poulin-fournier",
        &["height=0.7", "gap=0.5", "kd=0.1", "ks=0.9", "n=0.5"],
    ),
    ("strauss", &[]),
    (
        "strauss",
        &[
            "smoothness=0.8",
            "metalness=0.5",
            "transparency=0.2",
            "color=0.6",
        ],
    ),
    ("strauss", &["smoothness=0", "metalness=1"]),
];

/// Random direction pairs, a quarter of each direction grazing (z in [1e-6, 1e-2]), some on
/// or below the horizon, some exactly mirrored (the lobes' peaks).
fn directions(rng: &mut Pcg64, count: usize) -> Vec<[f32; 6]> {
    let dir = |rng: &mut Pcg64| -> [f32; 3] {
        let phi = rng.random::<f32>() * std::f32::consts::TAU;
        let z = match rng.random_range(0..8) {
            0 | 1 => 10f32.powf(rng.random_range(-6.0..-2.0)),
            2 => 0.0,
            3 => -rng.random::<f32>(),
            _ => rng.random::<f32>(),
        };
        let r = (1.0 - z * z).max(0.0).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    };
    (0..count)
        .map(|k| {
            let i = dir(rng);
            let o = if k % 10 == 0 {
                [-i[0], -i[1], i[2]]
            } else {
                dir(rng)
            };
            [i[0], i[1], i[2], o[0], o[1], o[2]]
        })
        .collect()
}

#[test]
fn eval_matches_the_formulas_of_models_md() {
    let mut rng = Pcg64::seed_from_u64(7);
    let pairs = directions(&mut rng, 2000);
    let input: String = pairs
        .iter()
        .map(|p| format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], p[3], p[4], p[5]))
        .collect();
    for &(name, params) in SETS {
        let mut args = vec!["eval", "--model", name];
        for p in params {
            args.extend(["--param", p]);
        }
        let o = brdf(&args, &input);
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let info =
            serde_json::from_str::<serde_json::Value>(&stdout(&brdf(&["models", "--json"], "")))
                .unwrap();
        let specs = info
            .as_array()
            .unwrap()
            .iter()
            .find(|m| m["name"] == name)
            .unwrap()["params"]
            .clone();
        let out = stdout(&o);
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), pairs.len());
        for (p, line) in pairs.iter().zip(lines) {
            let got: Vec<f64> = line.split(' ').map(|t| t.parse().unwrap()).collect();
            // Normalised, then lifted to the documented grazing floor (cos θ ≥ 10⁻⁴, same
            // azimuth: `geometry::GRAZING_COS`), which is part of every model's definition.
            let d64 = |a: &[f32]| {
                let v = [f64::from(a[0]), f64::from(a[1]), f64::from(a[2])];
                let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                let w = [v[0] / l, v[1] / l, v[2] / l];
                let floor = 1e-4;
                if w[2] > 0.0 && w[2] < floor {
                    let s = ((1.0 - floor) * (1.0 + floor)).sqrt() / w[0].hypot(w[1]);
                    [w[0] * s, w[1] * s, floor]
                } else {
                    w
                }
            };
            let (wi, wo) = (d64(&p[..3]), d64(&p[3..]));
            for (ch, &g) in got.iter().enumerate() {
                let param = |key: &str| -> f64 {
                    let given = params
                        .iter()
                        .find_map(|a| a.strip_prefix(key).and_then(|r| r.strip_prefix('=')));
                    match given {
                        Some(v) => v.parse::<f32>().unwrap().into(),
                        None => {
                            let s = specs
                                .as_array()
                                .unwrap()
                                .iter()
                                .find(|s| s["name"] == key)
                                .unwrap();
                            let d = &s["default"];
                            let v = if d.is_array() {
                                d[ch].as_f64().unwrap()
                            } else {
                                d.as_f64().unwrap()
                            };
                            f64::from(v as f32)
                        }
                    }
                };
                let want = reference::eval(name, &param, wi, wo);
                assert!(
                    (g - want).abs() <= 1e-5 * want.abs() + 1e-30,
                    "{name} {params:?} channel {ch} at {line:?} <- {p:?}: brdf eval {g} vs formula {want}"
                );
            }
        }
    }
}

#[test]
fn eval_rejects_bad_input_with_status_2() {
    let long_line = format!("0 0 1 0 0 1\n{}0 0 1 0 0 1\n", " ".repeat(70_000));
    for (args, stdin, needle) in [
        (&["eval", "--model", "phong"][..], "0 0 1 0 0\n", "line 1"),
        (
            &["eval", "--model", "phong"],
            "0 0 1 0 0 1\n0 0 1 x 0 1\n",
            "line 2",
        ),
        (
            &["eval", "--model", "phong"],
            "0 0 0 0 0 1\n",
            "zero length",
        ),
        (&["eval", "--model", "phong"], "NaN 0 1 0 0 1\n", "NaN"),
        (
            &["eval", "--model", "phong"],
            "0 0 1 0 0 1 7\n",
            "expected 6 numbers",
        ),
        (&["eval", "--model", "phong", "--param", "n=-1"], "", "`n`"),
        (
            &["eval", "--model", "phong", "--param", "kd=0.5,0.5"],
            "",
            "`kd`",
        ),
        (
            &["eval", "--model", "phong", "--param", "q=1"],
            "",
            "no parameter `q`",
        ),
        (
            &["eval", "--model", "lewis-phong", "--param", "kd=0.9"],
            "",
            "kd + ks",
        ),
        (&["eval", "--model", "nope"], "", "unknown model"),
        (&["eval"], "", "--model"),
        // A line longer than 64 KiB (an endless stream without a newline) is refused.
        (
            &["eval", "--model", "phong"],
            &long_line,
            "line 2: longer than 65536 bytes",
        ),
    ] {
        let o = brdf(args, stdin);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?} {stdin:?}: {err}");
        assert!(
            err.contains(needle),
            "{args:?}: stderr {err:?} lacks {needle:?}"
        );
    }
}

#[test]
fn eval_streams_normalises_and_zeroes_below_the_horizon() {
    let o = brdf(
        &[
            "eval",
            "--model",
            "lambert",
            "--param",
            "albedo=0.9,0.6,0.3",
        ],
        "0 0 1 0 0 1\n\n0 0 5  3 0 4\n0 0 1 0 0 -1\n",
    );
    assert!(o.status.success());
    let out = stdout(&o);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 3, "blank lines are skipped: {out}");
    let got: Vec<f64> = lines[0].split(' ').map(|t| t.parse().unwrap()).collect();
    for (g, a) in got.iter().zip([0.9f32, 0.6, 0.3]) {
        let want = f64::from(a) / std::f64::consts::PI;
        assert!((g - want).abs() < 1e-7 * want, "{g} vs {want}");
    }
    assert_eq!(lines[0], lines[1], "directions are normalised");
    assert_eq!(lines[2], "0.0 0.0 0.0");
}

fn read_records(path: &std::path::Path) -> Vec<[f32; 4]> {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(bytes.len() % 16, 0);
    bytes
        .chunks_exact(16)
        .map(|c| {
            std::array::from_fn(|k| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap()))
        })
        .collect()
}

#[test]
fn sample_writes_records_whose_pdf_brdf_pdf_agrees_with() {
    let dir = std::env::temp_dir().join(format!("brdf-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // HTSG's records are its continuous part only (SPEC §6): its strong specular delta
    // (ρs ≈ 0.5 for this surface) must not leak into them, so `brdf pdf` agrees here too.
    for (model, param) in [
        ("phong", "n=100"),
        ("htsg", "sigma0=0.0318"),
        ("strauss", "smoothness=0.9"),
        ("cook-torrance", "m=0.002"),
    ] {
        for mode in ["rejection", "warp", "uniform", "cosine", "analytic"] {
            let out = dir.join(format!("{model}-{mode}.bin"));
            let args = [
                "sample",
                "--model",
                model,
                "--param",
                param,
                "--wi",
                "0.3,-0.2,0.9",
                "--count",
                "5000",
                "--seed",
                "5",
                "--mode",
                mode,
                "--out",
                out.to_str().unwrap(),
            ];
            let o = brdf(&args, "");
            assert!(
                o.status.success(),
                "{mode}: {}",
                String::from_utf8_lossy(&o.stderr)
            );
            let summary: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
            for key in [
                "albedo",
                "nodes",
                "leaves",
                "max_depth",
                "build_seconds",
                "sample_seconds",
                "mean_trials",
                "bound_violations",
                "budget_exhausted",
            ] {
                assert!(
                    summary.get(key).is_some(),
                    "{mode}: summary lacks {key}: {summary}"
                );
            }
            let recs = read_records(&out);
            assert_eq!(recs.len(), 5000);
            // Same seed, same records.
            let again = brdf(&args, "");
            assert!(again.status.success());
            assert_eq!(
                read_records(&out),
                recs,
                "{mode}: not reproducible from its seed"
            );
            // `brdf pdf` reports the pdf each record carries.
            let kept: Vec<&[f32; 4]> = recs.iter().filter(|r| r[3] > 0.0).take(300).collect();
            assert!(kept.len() >= 250, "{mode}: too many lost samples");
            let input: String = kept
                .iter()
                .map(|r| format!("{} {} {}\n", r[0], r[1], r[2]))
                .collect();
            let p = brdf(
                &[
                    "pdf",
                    "--model",
                    model,
                    "--param",
                    param,
                    "--wi",
                    "0.3,-0.2,0.9",
                    "--mode",
                    mode,
                ],
                &input,
            );
            assert!(p.status.success(), "{}", String::from_utf8_lossy(&p.stderr));
            // Bit for bit: the direction read back is the record's, and `brdf pdf` hands it
            // to the sampler as read (normalising it first moved its last bits, and the pdf
            // by an f32 ulp on most records, by 2·10⁻⁴ on a Cook–Torrance lobe of
            // m = 0.0017 at 88°).
            let text = stdout(&p);
            let lines: Vec<&str> = text.lines().collect();
            assert_eq!(lines.len(), kept.len());
            for (r, line) in kept.iter().zip(lines) {
                let got: f32 = line.parse().unwrap();
                assert_eq!(
                    got.to_bits(),
                    r[3].to_bits(),
                    "{model} {mode}: pdf {got} vs record {}",
                    r[3]
                );
            }
            if mode == "rejection" {
                assert_eq!(summary["bound_violations"], 0);
                assert_eq!(summary["budget_exhausted"], false);
                assert!(
                    !String::from_utf8_lossy(&o.stderr).contains("stopped the build"),
                    "{mode}: a budget warning for a build that stayed within it"
                );
                assert!(summary["nodes"].as_u64().unwrap() > 1);
            } else if mode == "warp" {
                assert!(summary["nodes"].as_u64().unwrap() > 1);
                assert_eq!(summary["mean_trials"], 1.0);
            } else {
                assert!(summary["nodes"].is_null());
            }
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn sample_and_pdf_reject_bad_input_with_status_2() {
    let long_line = "0".repeat(100_000);
    let out = std::env::temp_dir().join(format!("brdf-cli-bad-{}.bin", std::process::id()));
    let o = out.to_str().unwrap();
    for (args, stdin, needle) in [
        (
            vec![
                "sample", "--model", "mirror", "--wi", "0,0,1", "--count", "3", "--out", o,
            ],
            "",
            "Dirac delta",
        ),
        (
            vec![
                "sample", "--model", "phong", "--wi", "0,0,-1", "--count", "3", "--out", o,
            ],
            "",
            "below the horizon",
        ),
        (
            vec![
                "sample", "--model", "phong", "--wi", "0,0", "--count", "3", "--out", o,
            ],
            "",
            "x,y,z",
        ),
        (
            vec![
                "sample", "--model", "phong", "--wi", "0,0,0", "--count", "3", "--out", o,
            ],
            "",
            "zero length",
        ),
        (
            vec![
                "sample",
                "--model",
                "phong",
                "--wi",
                "0,0,1",
                "--count",
                "3",
                "--target-trials",
                "0.5",
                "--out",
                o,
            ],
            "",
            "target_trials",
        ),
        // A target below the bounds' safety factor cannot be reached: refused at once, not
        // split to the node budget (20 s) first.
        (
            vec![
                "sample",
                "--model",
                "lambert",
                "--wi",
                "0,0,1",
                "--count",
                "3",
                "--target-trials",
                "1",
                "--out",
                o,
            ],
            "",
            "bound_safety",
        ),
        // Absurd counts are refused at once (no hang, no file), not run for days.
        (
            vec![
                "sample",
                "--model",
                "phong",
                "--wi",
                "0,0,1",
                "--count",
                "18446744073709551615",
                "--out",
                o,
            ],
            "",
            "at most 4294967296",
        ),
        (
            vec!["test", "--model", "lambert", "--samples", "68719476737"],
            "",
            "at most 68719476736",
        ),
        (
            vec!["pdf", "--model", "phong", "--wi", "0,0,1"],
            "0 0\n",
            "line 1",
        ),
        (
            vec!["pdf", "--model", "phong", "--wi", "0,0,1"],
            "0 0 0\n",
            "zero length",
        ),
        (
            vec!["pdf", "--model", "phong", "--wi", "0,0,1"],
            &long_line,
            "line 1: longer than 65536 bytes",
        ),
    ] {
        let r = brdf(&args, stdin);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err:?} lacks {needle:?}");
    }
    std::fs::remove_file(&out).ok();
}

/// `brdf bench --json` reports every figure it promises, and its estimators agree: each
/// sampler's mean reflected radiance is within 5 standard errors of the quadtree's. The sun
/// makes the one-sample variance large, so it takes 2·10⁶ samples for this to see a 10 %
/// bias (checked: the table sampler with its pdf scaled by 0.9 lands 6.4 SE away; the
/// correct samplers stay within 2.6 SE).
#[test]
fn bench_reports_ratios_from_unbiased_estimates() {
    let o = brdf(
        &[
            "bench",
            "--only",
            "lambert",
            "--samples",
            "2000000",
            "--json",
        ],
        "",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let sets = v["sets"].as_array().unwrap();
    assert_eq!(sets.len(), 1);
    let set = &sets[0];
    for key in ["expected_trials", "bytes_per_node", "rayon_speedup"] {
        assert!(set[key].as_f64().unwrap() > 0.0, "{key}: {set}");
    }
    // The sampling layout: 16 bytes a node, and a selection guide of 16 bytes an entry, no
    // more entries than half the nodes (one entry for a tree of one node).
    let per_node = set["bytes_per_node"].as_f64().unwrap();
    assert!((16.0..=32.0).contains(&per_node), "{per_node}");
    assert!(v["beckmann_analytic_ns_per_sample"].as_f64().unwrap() > 0.0);
    // The baked rows are divided by the Beckmann sample timed in their own loop, in runs
    // taken in turn with the row's own.
    let first = v["beckmann_analytic_random_wi_ns_per_sample"]
        .as_f64()
        .unwrap();
    assert!(first > 0.0 && first.is_finite(), "{first}");
    let b = &set["baked"];
    let yard = b["random_wi_beckmann_ns_per_sample"].as_f64().unwrap();
    assert!(yard > 0.0 && yard.is_finite(), "{yard}");
    for mode in ["rejection", "warp"] {
        let ns = b[format!("random_wi_ns_per_sample_{mode}")]
            .as_f64()
            .unwrap();
        let r = b[format!("time_baked_{mode}_over_beckmann")]
            .as_f64()
            .unwrap();
        assert!((r - ns / yard).abs() <= 1e-12 * r, "{mode}: {b}");
    }
    for key in [
        "time_quadtree_over_analytic",
        "efficiency_quadtree_over_cosine",
        "efficiency_quadtree_over_analytic",
        "efficiency_quadtree_over_table",
        "time_quadtree_over_beckmann",
        "time_target_over_analytic",
        "time_target_over_beckmann",
    ] {
        let r = set["ratios"][key].as_f64().unwrap();
        assert!(r.is_finite() && r > 0.0, "{key}: {r}");
    }
    // The floors (issue #16): every part positive, the floor their stated sum, and E[T]
    // the tree's for rejection, 1 for the warp.
    for mode in ["rejection", "warp"] {
        let f = &set["floor"][mode];
        let part = |k: &str| f[k].as_f64().unwrap_or_else(|| panic!("{mode} {k}: {f}"));
        for k in ["eval_ns", "uniforms_ns", "descent_ns", "sample_ns"] {
            assert!(part(k) > 0.0 && part(k).is_finite(), "{mode} {k}: {f}");
        }
        let t = part("expected_trials");
        let floor = t * (part("eval_ns") + part("uniforms_ns")) + part("descent_ns");
        assert!(
            (part("floor_ns") - floor).abs() <= 1e-9 * floor,
            "{mode}: {f}"
        );
        assert!((part("sample_over_floor") - part("sample_ns") / floor).abs() < 1e-9);
        if mode == "warp" {
            assert_eq!(t, 1.0);
        } else {
            assert_eq!(Some(t), set["expected_trials"].as_f64());
        }
    }
    let samplers = set["samplers"].as_array().unwrap();
    // Each efficiency ratio's relative standard error is its two variances' in quadrature.
    let rel = |name: &str, env: &str| {
        let s = samplers.iter().find(|s| s["sampler"] == name).unwrap();
        let (v, se) = (
            s[env]["variance"].as_f64().unwrap(),
            s[env]["variance_se"].as_f64().unwrap(),
        );
        assert!(se.is_finite() && se >= 0.0, "{name} {env}: {se}");
        se / v
    };
    for (key, a, b, env) in [
        (
            "efficiency_quadtree_over_cosine",
            "quadtree",
            "cosine",
            "sky_and_sun",
        ),
        (
            "efficiency_quadtree_over_analytic",
            "quadtree",
            "analytic",
            "sky_and_sun",
        ),
        (
            "efficiency_quadtree_over_table",
            "quadtree",
            "table",
            "sky_and_sun",
        ),
        (
            "glint_efficiency_quadtree_over_cosine",
            "quadtree",
            "cosine",
            "glint",
        ),
        (
            "efficiency_baked_over_analytic",
            "baked-rejection",
            "analytic",
            "sky_and_sun",
        ),
        (
            "efficiency_baked_warp_over_quadtree",
            "baked-warp",
            "quadtree",
            "sky_and_sun",
        ),
    ] {
        let r = set["ratios_rse"][key].as_f64().unwrap();
        let want = rel(a, env).hypot(rel(b, env));
        assert!(
            r > 0.0 && (r - want).abs() <= 1e-12 * want,
            "{key}: {r} vs {want}"
        );
    }
    let n = 2_000_000.0;
    for env in ["sky_and_sun", "glint"] {
        let q = samplers
            .iter()
            .find(|s| s["sampler"] == "quadtree")
            .unwrap();
        let (qm, qv) = (
            q[env]["mean"].as_f64().unwrap(),
            q[env]["variance"].as_f64().unwrap(),
        );
        for s in samplers {
            let (m, var) = (
                s[env]["mean"].as_f64().unwrap(),
                s[env]["variance"].as_f64().unwrap(),
            );
            let se = ((qv + var) / n).sqrt();
            assert!(
                (m - qm).abs() < 5.0 * se,
                "{env} {}: {m} vs quadtree {qm} (SE {se})",
                s["sampler"]
            );
        }
    }
    let o = brdf(&["bench", "--samples", "1"], "");
    assert_eq!(o.status.code(), Some(2));
    // An absurd count is refused at once, not run for weeks.
    let o = brdf(&["bench", "--samples", "1000000000000000"], "");
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("at most 4294967296"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// A bake whose trees a budget stops short of `--target-trials` says so: the count in its
/// JSON and a warning on stderr (as `brdf sample` warns of one tree), with the E\[T\] it
/// reached; a target the trees meet leaves both quiet.
#[test]
fn bake_reports_trees_a_budget_stopped() {
    let dir = std::env::temp_dir().join(format!("brdf-cli-bake-budget-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("phong.bake");
    let f = file.to_str().unwrap();
    let bake = |target: &str| {
        brdf(
            &[
                "bake",
                "--model",
                "phong",
                "--param",
                "n=100",
                "--theta-steps",
                "2",
                "--target-trials",
                target,
                "--out",
                f,
            ],
            "",
        )
    };
    // 1.02 is the bounds' safety factor: no tree reaches it before its node budget.
    let o = bake("1.02");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["budget_exhausted_trees"].as_u64(), Some(2), "{v}");
    assert!(v["max_expected_trials"].as_f64().unwrap() > 1.02, "{v}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("stopped 2 of 2 trees, short of --target-trials 1.02"),
        "{err}"
    );
    let o = bake("1.1");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["budget_exhausted_trees"].as_u64(), Some(0), "{v}");
    assert!(v["max_expected_trials"].as_f64().unwrap() <= 1.1, "{v}");
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `brdf bake --max-bytes`: a bake over the limit holds at most it (trees pruned, exact
/// still: `test --baked` passes), says so in its JSON (`max_bytes`, the pruned
/// trees counted as budget-stopped) and on stderr; a limit of 0 or past 2 GiB is refused
/// (exit 2) before anything is baked.
#[test]
fn bake_holds_at_most_max_bytes() {
    let dir = std::env::temp_dir().join(format!("brdf-cli-bake-bytes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("ward.bake");
    let f = file.to_str().unwrap();
    let bake = |extra: &[&str]| {
        let mut args = vec![
            "bake",
            "--model",
            "ward",
            "--param",
            "alpha_x=0.3",
            "--param",
            "alpha_y=0.01",
            "--param",
            "kd=0",
            "--theta-steps",
            "4",
            "--phi-steps",
            "2",
            "--coverage-samples",
            "0",
            "--out",
            f,
        ];
        args.extend_from_slice(extra);
        brdf(&args, "")
    };
    let o = bake(&[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["max_bytes"].as_u64(), Some(16 << 20), "{v}");
    // An isotropic model's default is 1 MiB.
    let phong = dir.join("phong.bake");
    let o = brdf(
        &[
            "bake",
            "--model",
            "phong",
            "--theta-steps",
            "3",
            "--coverage-samples",
            "0",
            "--out",
            phong.to_str().unwrap(),
        ],
        "",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let iso: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(iso["max_bytes"].as_u64(), Some(1 << 20), "{iso}");
    let free = v["bytes"].as_u64().unwrap();
    let limit = (free / 2).to_string();
    let o = bake(&["--max-bytes", &limit]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["max_bytes"].as_u64(), Some(free / 2), "{v}");
    assert!(v["bytes"].as_u64().unwrap() <= free / 2, "{v}");
    assert!(v["budget_exhausted_trees"].as_u64().unwrap() > 0, "{v}");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--max-bytes) stopped"), "{err}");
    let o = brdf(
        &[
            "test",
            "--baked",
            f,
            "--wi",
            "0.5,0.2,0.6",
            "--samples",
            "200000",
        ],
        "",
    );
    assert!(
        o.status.success(),
        "{}{}",
        stdout(&o),
        String::from_utf8_lossy(&o.stderr)
    );
    for bad in ["0", "3000000000"] {
        let o = bake(&["--max-bytes", bad]);
        assert_eq!(o.status.code(), Some(2), "{bad}");
        assert!(
            String::from_utf8_lossy(&o.stderr).contains("max_bytes"),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `brdf bake` checks that its grid covers the material between the trees: the JSON's
/// `coverage` says how much a baked sample is worth where the mixture is farthest from its
/// trees, a grid too coarse for the lobe is warned of on stderr (the bake still succeeds:
/// its sampler is exact, only inefficient), `--coverage-samples 0` skips the check, and an
/// absurd count is refused before anything is baked.
#[test]
fn bake_warns_of_a_grid_too_coarse_for_its_lobe() {
    let dir = std::env::temp_dir().join(format!("brdf-cli-bake-cover-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("pf.bake");
    let f = file.to_str().unwrap();
    let bake = |steps: &str, extra: &[&str]| {
        let mut args = vec![
            "bake",
            "--model",
            "poulin-fournier",
            "--param",
            "n=1000",
            "--param",
            "kd=0",
            "--param",
            "gap=0",
            "--param",
            "ks=0.25",
            "--theta-steps",
            steps,
            "--phi-steps",
            "2",
            "--out",
            f,
        ];
        args.extend_from_slice(extra);
        brdf(&args, "")
    };
    // Poulin–Fournier's specular part alone on 5 × 2 trees: the lobe changes with φi
    // faster than columns 90° apart follow (measured: R above 4 at 3 and 2 of the 5 checked
    // directions in rejection and warp mode, 1.2·10⁴ at worst).
    let o = bake("5", &[]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let c = &v["coverage"];
    assert_eq!(c["checked"].as_u64(), Some(5), "{v}");
    assert_eq!(c["samples"].as_u64(), Some(2048), "{v}");
    for mode in ["rejection", "warp"] {
        assert!(c[mode]["above_limit"].as_u64().unwrap() >= 2, "{v}");
        assert!(c[mode]["worst"].as_f64().unwrap() > 1e3, "{v}");
    }
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("the grid is too coarse for this material")
            && err.contains("of 5 checked incident directions")
            && err.contains("--theta-steps and --phi-steps"),
        "{err}"
    );
    // `brdf test --baked` at a poorly covered wi (θi 77.9°, φi 45°: a checked cell's centre)
    // says so in its JSON and on stderr, even where its mean-weight test passes.
    let o = brdf(
        &[
            "test",
            "--baked",
            f,
            "--wi",
            "0.6913324,0.6913324,0.2100452",
            "--samples",
            "20000",
            "--json",
        ],
        "",
    );
    let t: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(
        t["weight_tests"][0]["coverage"]["rejection"]
            .as_f64()
            .unwrap()
            > 1e3,
        "{t}"
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("a baked sample is worth 1/") && err.contains("in rejection mode"),
        "{err}"
    );
    // Skipped: no check, no warning, `coverage` null.
    let o = bake("5", &["--coverage-samples", "0"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(v["coverage"].is_null(), "{v}");
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // Absurd: exit 2 before baking, the old file left as it was.
    let before = std::fs::read(&file).unwrap();
    let o = bake("5", &["--coverage-samples", "4000000000"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr)
            .contains("--coverage-samples 4000000000 must be at most"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(std::fs::read(&file).unwrap(), before);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `brdf bake` writes a bake file and reports it; `sample`, `pdf` and `test` read it with
/// `--baked` (SPEC §7); the pdf `brdf pdf --baked` prints is the one the records carry.
#[test]
fn bake_then_sample_pdf_and_test_baked() {
    let dir = std::env::temp_dir().join(format!("brdf-cli-bake-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("phong.bake");
    let f = file.to_str().unwrap();
    let o = brdf(
        &[
            "bake",
            "--model",
            "phong",
            "--param",
            "n=300",
            "--theta-steps",
            "12",
            "--out",
            f,
        ],
        "",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Progress is drawn only on a terminal: through a pipe, stderr stays empty.
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["trees"].as_u64(), Some(12));
    assert_eq!(v["budget_exhausted_trees"].as_u64(), Some(0), "{v}");
    for key in ["nodes", "bytes", "build_seconds"] {
        assert!(v[key].as_f64().unwrap() > 0.0, "{key}: {v}");
    }
    assert_eq!(v["grid"]["theta_deg"].as_array().unwrap().len(), 12);
    assert_eq!(v["grid"]["theta_deg"][11].as_f64(), Some(89.0));
    // The coverage check: 11 cells and the band beyond the last row, none poor.
    assert_eq!(v["coverage"]["checked"].as_u64(), Some(12), "{v}");
    for mode in ["rejection", "warp"] {
        assert_eq!(v["coverage"][mode]["above_limit"].as_u64(), Some(0), "{v}");
        assert!(v["coverage"][mode]["worst"].as_f64().unwrap() < 2.0, "{v}");
    }
    // Complete: only the bake file in the directory, no temporary left.
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);

    let out = dir.join("s.bin");
    let wi = "0.41,-0.2,0.75";
    for mode in ["rejection", "warp"] {
        let o = brdf(
            &[
                "sample",
                "--baked",
                f,
                "--wi",
                wi,
                "--count",
                "2000",
                "--mode",
                mode,
                "--out",
                out.to_str().unwrap(),
            ],
            "",
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let s: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        assert_eq!(s["mode"], mode);
        assert!(s["albedo_method"].as_str().unwrap().contains("mean weight"));
        assert!(s["albedo"].as_f64().unwrap() > 0.0);
        let recs = read_records(&out);
        assert_eq!(recs.len(), 2000);
        let input: String = recs
            .iter()
            .filter(|r| r[2] > 0.0)
            .map(|r| format!("{:e} {:e} {:e}\n", r[0], r[1], r[2]))
            .collect();
        let o = brdf(&["pdf", "--baked", f, "--wi", wi, "--mode", mode], &input);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let pdfs: Vec<f32> = stdout(&o).lines().map(|l| l.parse().unwrap()).collect();
        let kept: Vec<_> = recs.iter().filter(|r| r[2] > 0.0).collect();
        assert_eq!(pdfs.len(), kept.len());
        for (r, p) in kept.iter().zip(&pdfs) {
            assert_eq!(
                r[3].to_bits(),
                p.to_bits(),
                "record pdf {} vs brdf pdf {p}",
                r[3]
            );
        }
    }
    let o = brdf(
        &[
            "test",
            "--baked",
            f,
            "--wi",
            "0.41,-0.2,0.75",
            "--wi",
            "0.99,0,0.1",
            "--samples",
            "200000",
            "--json",
        ],
        "",
    );
    let t: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(t["against"], "own");
    assert_eq!(t["weight_tests"].as_array().unwrap().len(), 2);
    assert!(o.status.success(), "{t}");
    // R at each tested wi: phong n = 300 on 12 rows is covered.
    for w in t["weight_tests"].as_array().unwrap() {
        for mode in ["rejection", "warp"] {
            let r = w["coverage"][mode].as_f64().unwrap();
            assert!((0.95..2.0).contains(&r), "{mode}: {w}");
        }
    }

    // Bad input: a missing, a truncated or a foreign file; a mode a bake has no tables for;
    // a --model that is not the bake's. Each exits 2 with a message.
    let truncated = dir.join("t.bake");
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let missing = dir.join("missing.bake");
    for args in [
        vec![
            "sample",
            "--baked",
            missing.to_str().unwrap(),
            "--wi",
            wi,
            "--count",
            "1",
            "--out",
            out.to_str().unwrap(),
        ],
        vec!["pdf", "--baked", truncated.to_str().unwrap(), "--wi", wi],
        vec!["pdf", "--baked", out.to_str().unwrap(), "--wi", wi],
        vec!["pdf", "--baked", f, "--wi", wi, "--mode", "cosine"],
        vec![
            "pdf", "--baked", f, "--wi", wi, "--model", "phong", "--param", "n=301",
        ],
        vec!["pdf", "--baked", f, "--wi", "0,0,-1"],
        vec![
            "bake",
            "--model",
            "mirror",
            "--out",
            dir.join("m.bake").to_str().unwrap(),
        ],
        vec![
            "bake",
            "--model",
            "phong",
            "--theta-steps",
            "1",
            "--out",
            dir.join("m.bake").to_str().unwrap(),
        ],
    ] {
        let o = brdf(&args, "");
        assert_eq!(
            o.status.code(),
            Some(2),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(!o.stderr.is_empty(), "{args:?}");
    }
    assert!(!dir.join("m.bake").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The robustness contract at the command line: finite numbers at grazing, a zero f_r as one
/// typed error (exit 2, no file), an inconclusive test as exit 3, and `test --out` files
/// complete or absent.
#[test]
fn grazing_zero_and_inconclusive_runs_have_their_own_outcomes() {
    let parse = |o: &Output| -> Vec<f64> {
        stdout(o)
            .split_whitespace()
            .map(|t| t.parse::<f64>().unwrap())
            .collect()
    };
    let models = brdf_sampling::registry::models()
        .iter()
        .filter(|m| !m.delta && !m.measured);
    for m in models.map(|m| m.name) {
        let o = brdf(
            &["eval", "--model", m],
            "1 0 1e-20 -1 0 1e-20\n1 0 1e-45 -1 0 1e-45\n0.6 0 0.8 -0.6 0 1e-38\n",
        );
        assert!(o.status.success(), "{m}");
        let v = parse(&o);
        assert_eq!(v.len(), 9, "{m}");
        assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0), "{m}: {v:?}");
    }
    for m in ["cook-torrance", "ward", "schlick", "strauss"] {
        for mode in ["rejection", "warp", "analytic", "table"] {
            let o = brdf(
                &["pdf", "--model", m, "--wi", "1,0,1e-40", "--mode", mode],
                "-1 0 1e-40\n-1 0 1e-3\n0 0 1\n",
            );
            assert!(o.status.success(), "{m} {mode}: {:?}", o);
            let v = parse(&o);
            assert!(
                v.len() == 3 && v.iter().all(|x| x.is_finite() && *x >= 0.0),
                "{m} {mode}: {v:?}"
            );
        }
    }
    // f_r ≡ 0: typed, exit 2, and the output file is not created.
    let dir = std::env::temp_dir().join(format!("brdf-cli-robust-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("zero.bin");
    for mode in ["rejection", "warp", "table"] {
        let o = brdf(
            &[
                "sample",
                "--model",
                "cook-torrance",
                "--param",
                "f0=0",
                "--wi",
                "0,0,1",
                "--count",
                "10",
                "--mode",
                mode,
                "--out",
                out.to_str().unwrap(),
            ],
            "",
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{mode}: {err}");
        assert!(err.contains("0 everywhere"), "{mode}: {err}");
        assert!(!out.exists(), "{mode}");
    }
    // Too few samples to judge: exit 3, in the table and in the JSON.
    let o = brdf(&["test", "--model", "lambert", "--samples", "1"], "");
    assert_eq!(o.status.code(), Some(3), "{}", stdout(&o));
    assert!(stdout(&o).contains("INCONCLUSIVE"));
    let o = brdf(
        &["test", "--model", "lambert", "--samples", "1", "--json"],
        "",
    );
    assert_eq!(o.status.code(), Some(3));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["verdict"], "inconclusive");
    assert_eq!(v["passed"], false);
    // An image that cannot be written (its path is a directory): exit 2, no temporary left.
    let images = dir.join("images");
    std::fs::create_dir_all(images.join("lambert-rejection-wi0-square.png")).unwrap();
    let o = brdf(
        &[
            "test",
            "--model",
            "lambert",
            "--samples",
            "20000",
            "--cells",
            "4",
            "--grid",
            "square",
            "--wi",
            "0,0,1",
            "--out",
            images.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let left: Vec<_> = std::fs::read_dir(&images)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    assert_eq!(left, ["lambert-rejection-wi0-square.png"], "{left:?}");
    // A flag the mode ignores: a warning on stderr, the run as before.
    let o = brdf(
        &[
            "sample",
            "--model",
            "phong",
            "--wi",
            "0,0,1",
            "--count",
            "5",
            "--mode",
            "table",
            "--map",
            "concentric",
            "--target-trials",
            "1.2",
            "--out",
            out.to_str().unwrap(),
        ],
        "",
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning: --map") && err.contains("warning: --target-trials"),
        "{err}"
    );
    // A bench filter that selects nothing, and a gigabyte-free error quote.
    let o = brdf(&["bench", "--quick", "--only", "no-such-set"], "");
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("no set matches"));
    let long = format!("{}\n", "9".repeat(100_000));
    let o = brdf(&["eval", "--model", "lambert"], &long);
    assert_eq!(o.status.code(), Some(2));
    assert!(o.stderr.len() < 400, "{} bytes of error", o.stderr.len());
    std::fs::remove_dir_all(&dir).ok();
}
