//! `check` on a sampler outside the workspace (the GGX of `examples/ggx.rs`): the exact
//! sampler passes against its own pdf with an unbiased mean weight, and three broken ones
//! are rejected, each for its own reason. Seeds fixed; the family-wise α is 0.01 per check.

#[allow(dead_code)]
#[path = "../examples/ggx.rs"]
mod ggx;

use brdf_validate::glam::Vec3;
use brdf_validate::{Against, FnSampler, Reason, Sampler, Settings, SuiteReport, Verdict, check};
use ggx::{Ggx, incident};

fn settings(against: Against) -> Settings {
    Settings {
        grids: Settings::both_grids(15),
        samples: 400_000,
        against,
        mean_weight: true,
        ..Settings::default()
    }
}

fn run(
    ggx: Ggx,
    theta: f32,
    sample: &(dyn Fn(f32, brdf_validate::glam::Vec2) -> Option<(Vec3, f32)> + Sync),
    pdf: &(dyn Fn(Vec3) -> f32 + Sync),
    against: Against,
) -> SuiteReport {
    let wi = incident(theta);
    let sampler = FnSampler::new("ggx", sample, pdf);
    let mirror = Vec3::new(-wi.x, -wi.y, wi.z);
    check(
        &sampler,
        |wo| f64::from(ggx.f_cos(wi, wo)),
        &[mirror],
        &settings(against),
    )
    .unwrap()
}

/// The exact sampler passes on its own pdf at three roughnesses, with its mean weight equal
/// to ∫ f·cos dω; it is not ∝ f·cos (G and F are not sampled), so against f·cos it is
/// rejected at the sharpest grazing case, where G matters most.
#[test]
fn an_exact_ggx_sampler_passes_on_its_own_pdf() {
    for (alpha, theta) in [(0.5, 30.0), (0.2, 60.0), (0.05, 75.0)] {
        let g = Ggx { alpha, f0: 0.04 };
        let wi = incident(theta);
        let r = run(
            g,
            theta,
            &|_, u| g.sample(wi, u),
            &|wo| g.pdf(wi, wo),
            Against::OwnPdf,
        );
        assert!(r.passed(), "α {alpha} θ {theta}: {r}");
        assert_eq!(r.weight_tests.len(), 1);
    }
    let g = Ggx {
        alpha: 0.5,
        f0: 0.04,
    };
    let wi = incident(80.0);
    let r = run(
        g,
        80.0,
        &|_, u| g.sample(wi, u),
        &|wo| g.pdf(wi, wo),
        Against::FCos,
    );
    assert_eq!(r.verdict(), Verdict::Rejected, "{r}");
    assert!(r.tests.iter().all(|t| t.report.passed_own()), "{r}");
}

/// A pdf that forgets the reflection's Jacobian 1/(4 |wo·h|): the samples are right, the
/// reported density is not.
#[test]
fn a_pdf_without_the_jacobian_is_rejected() {
    let g = Ggx {
        alpha: 0.3,
        f0: 0.04,
    };
    let wi = incident(40.0);
    let wrong = |wo: Vec3| {
        let h = (wi + wo).normalize();
        g.pdf(wi, wo) * 4.0 * wo.dot(h).abs()
    };
    let r = run(
        g,
        40.0,
        &|_, u| g.sample(wi, u).map(|(w, _)| (w, wrong(w))),
        &wrong,
        Against::OwnPdf,
    );
    assert_eq!(r.verdict(), Verdict::Rejected, "{r}");
    assert!(r.tests.iter().any(|t| {
        t.report
            .rejections(Against::OwnPdf)
            .iter()
            .any(|x| matches!(x, Reason::ChiSquare { .. }))
    }));
}

/// Samples drawn at α = 0.33 but reported with the pdf of α = 0.3: the χ² against the own
/// pdf sees a 10 % wider lobe.
#[test]
fn samples_from_another_roughness_are_rejected() {
    let g = Ggx {
        alpha: 0.3,
        f0: 0.04,
    };
    let wider = Ggx { alpha: 0.33, ..g };
    let wi = incident(40.0);
    let r = run(
        g,
        40.0,
        &|_, u| wider.sample(wi, u).map(|(w, _)| (w, g.pdf(wi, w))),
        &|wo| g.pdf(wi, wo),
        Against::OwnPdf,
    );
    assert_eq!(r.verdict(), Verdict::Rejected, "{r}");
}

/// A sampler exact for its own pdf whose support misses part of f·cos: every direction
/// with x > 0 is folded onto x < 0 (wi lies at x > 0, so the lobe is mostly at x < 0). Its
/// own χ² passes, but its mean weight (f·cos/pdf from the oracle) misses the folded half's
/// share of ∫ f·cos dω.
#[test]
fn a_pdf_missing_part_of_the_support_biases_the_mean_weight() {
    let g = Ggx {
        alpha: 0.3,
        f0: 0.04,
    };
    let wi = incident(40.0);
    let flip = |w: Vec3| Vec3::new(-w.x, w.y, w.z);
    let folded = |wo: Vec3| {
        if wo.x > 0.0 {
            0.0
        } else {
            g.pdf(wi, wo) + g.pdf(wi, flip(wo))
        }
    };
    let r = run(
        g,
        40.0,
        &|_, u| {
            g.sample(wi, u).map(|(w, _)| {
                let w = if w.x > 0.0 { flip(w) } else { w };
                (w, folded(w))
            })
        },
        &folded,
        Against::OwnPdf,
    );
    assert!(r.tests.iter().all(|t| t.report.passed_own()), "{r}");
    assert_eq!(r.weight_tests.len(), 1);
    assert!(!r.weight_tests[0].passed, "{r}");
    assert_eq!(r.verdict(), Verdict::Rejected);
}

/// The exact GGX sampler (α = 0.3) at θi = 40° and its f·cos oracle.
fn exact_ggx() -> (impl Sampler, impl Fn(Vec3) -> f64 + Sync + Copy) {
    let g = Ggx {
        alpha: 0.3,
        f0: 0.04,
    };
    let wi = incident(40.0);
    (
        FnSampler::new("ggx", move |_, u| g.sample(wi, u), move |wo| g.pdf(wi, wo)),
        move |wo: Vec3| f64::from(g.f_cos(wi, wo)),
    )
}

/// Bad settings are typed errors, not panics.
#[test]
fn bad_settings_are_errors() {
    let (sampler, fcos) = exact_ggx();
    for s in [
        Settings {
            samples: 0,
            ..Settings::default()
        },
        Settings {
            alpha: 1.0,
            ..Settings::default()
        },
        Settings {
            grids: vec![],
            ..Settings::default()
        },
        Settings {
            tol: f64::NAN,
            ..Settings::default()
        },
        Settings {
            grids: vec![brdf_validate::CellGrid::Square { res: 5000 }],
            ..Settings::default()
        },
    ] {
        assert!(check(&sampler, fcos, &[], &s).is_err(), "{s:?}");
    }
    // An absurd count is refused at once rather than run for days.
    for samples in [brdf_validate::MAX_SAMPLES + 1, u64::MAX] {
        let s = Settings {
            samples,
            ..Settings::default()
        };
        assert_eq!(
            check(&sampler, fcos, &[], &s).unwrap_err(),
            brdf_validate::ValidateError::TooManySamples { value: samples }
        );
    }
}

/// An f·cos oracle that is NaN or infinite somewhere, or everywhere, is rejected with
/// reasons that say so, never with a NaN p-value: the χ² tests because its masses are not
/// a distribution (where the integration meets the bad values), the mean weight with p = 0
/// (an infinite oracle once gave it p = NaN). The sampler itself is exact.
#[test]
fn a_non_finite_oracle_is_rejected_without_a_nan() {
    let (sampler, fcos) = exact_ggx();
    let settings = Settings {
        grids: Settings::both_grids(5),
        samples: 20_000,
        against: Against::OwnPdf,
        mean_weight: true,
        ..Settings::default()
    };
    let oracles: [(&str, &(dyn Fn(Vec3) -> f64 + Sync)); 4] = [
        ("inf", &|_| f64::INFINITY),
        ("nan", &|_| f64::NAN),
        ("huge", &|_| 1e308),
        ("nan in a band", &|wo: Vec3| {
            if (0.3..0.31).contains(&wo.x) {
                f64::NAN
            } else {
                fcos(wo)
            }
        }),
    ];
    for (name, oracle) in oracles {
        let r = check(&sampler, oracle, &[], &settings).unwrap();
        assert_eq!(r.verdict(), Verdict::Rejected, "{name}: {r}");
        let w = &r.weight_tests[0];
        assert!(!w.passed && w.p_value == 0.0, "{name}: {w:?}");
        let text = r.to_string();
        assert!(text.contains("not finite"), "{name}: {text}");
        // (A band the integrator's nodes miss leaves finite masses: only the weights see it.)
        for t in r.tests.iter().filter(|_| name != "nan in a band") {
            assert!(
                t.reasons()
                    .iter()
                    .any(|reason| reason.to_string().contains("not a distribution")),
                "{name}: {text}"
            );
        }
    }
    // The same sampler with its true oracle passes: the rejections above are the oracle's.
    let r = check(&sampler, fcos, &[], &settings).unwrap();
    assert!(r.passed(), "{r}");
}
