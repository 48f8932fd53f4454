//! Model tests: hand-computed values, MODELS.md's oracles, properties over random directions,
//! energy, and the analytic samplers' consistency. Every oracle here comes from the formulas
//! (an independent f64 evaluation, or MODELS.md), never from this crate's own code.

use brdf_core::quadrature::{directional_albedo, hemisphere_integral};
use brdf_core::registry::{self, Energy};
use brdf_core::{Brdf, geometry::luminance, models::CookTorrance};
use glam::{Vec2, Vec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

/// The direction with polar angle θ and azimuth φ, in degrees.
fn dir(theta: f64, phi: f64) -> Vec3 {
    let (t, p) = (theta.to_radians(), phi.to_radians());
    Vec3::new(
        (t.sin() * p.cos()) as f32,
        (t.sin() * p.sin()) as f32,
        t.cos() as f32,
    )
}

fn close(got: f64, want: f64, rel: f64) -> bool {
    (got - want).abs() <= rel * want.abs() + 1e-30
}

fn build(name: &str, params: &[&str]) -> Box<dyn Brdf> {
    registry::create(name, params.iter().copied()).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Luminance directional albedo by independent quadrature.
fn albedo(b: &dyn Brdf, wi: Vec3) -> f64 {
    luminance(directional_albedo(b, wi, 96, 6).as_vec3()) as f64
}

mod values {
    use super::*;

    type Case = ((f64, f64), (f64, f64), f64);

    /// Evaluates at (θi, φi), (θo, φo) in degrees; all channels equal, so any channel works.
    fn check(name: &str, params: &[&str], cases: &[Case]) {
        let b = build(name, params);
        for &((ti, pi), (to, po), want) in cases {
            let f = b.eval(dir(ti, pi), dir(to, po));
            assert!(
                f.x == f.y && f.y == f.z,
                "{name}: grey parameters give grey f"
            );
            assert!(
                close(f64::from(f.x), want, 2e-6),
                "{name} {params:?} at ({ti},{pi})->({to},{po}): {} vs {want}",
                f.x
            );
        }
    }

    // Constants: an independent f64 evaluation of MODELS.md's formulas at these angles.
    const PTS: [((f64, f64), (f64, f64)); 4] = [
        ((30., 0.), (25., 180.)),
        ((60., 45.), (50., 200.)),
        ((10., 100.), (75., -60.)),
        ((80., 0.), (85., 170.)),
    ];

    fn cases(values: [f64; 4]) -> Vec<Case> {
        PTS.iter()
            .zip(values)
            .map(|(&(a, b), v)| (a, b, v))
            .collect()
    }

    #[test]
    fn lambert_and_mirror() {
        check(
            "lambert",
            &["albedo=0.6"],
            &cases([0.6 / std::f64::consts::PI; 4]),
        );
        let m = build("mirror", &["reflectance=0.7"]);
        assert_eq!(m.eval(dir(30., 0.), dir(30., 180.)), Vec3::ZERO);
        assert_eq!(m.pdf(dir(30., 0.), dir(30., 180.)), 0.0);
        assert_eq!(m.delta_reflectance(dir(30., 0.)), Vec3::splat(0.7));
    }

    #[test]
    fn phong() {
        check(
            "phong",
            &["kd=0.3", "ks=0.6", "n=20"],
            &cases([
                6.514430122e-01,
                2.154154699e-01,
                9.549297806e-02,
                5.067377277e-01,
            ]),
        );
    }

    #[test]
    fn blinn_phong() {
        check(
            "blinn-phong",
            &["kd=0.2", "ks=0.7", "n=30"],
            &cases([
                1.045317040e+00,
                2.962878840e-01,
                6.896969764e-02,
                6.791044465e-02,
            ]),
        );
        // n = 0: N(0) = 1/π, a constant lobe (pow(0, 0) = 1).
        check(
            "blinn-phong",
            &["kd=0.2", "ks=0.7", "n=0"],
            &cases([2.864788976e-01; 4]),
        );
    }

    #[test]
    fn lewis_phong() {
        check(
            "lewis-phong",
            &["kd=0.25", "ks=0.75", "n=40"],
            &cases([
                4.383849652e+00,
                2.798537723e-01,
                7.957747155e-02,
                2.434783711e+00,
            ]),
        );
    }

    #[test]
    fn cook_torrance() {
        check(
            "cook-torrance",
            &["m=0.25", "f0=0.6", "kd=0.1"],
            &cases([
                9.777533649e-01,
                5.713619019e-01,
                3.612545899e-02,
                9.797578970e-02,
            ]),
        );
        // MODELS.md oracle: m = 0.3, F ≡ 1, θi = θo = 30° mirrored: 1.17893.
        let ct = CookTorrance::new(0.3, Vec3::splat(0.5), Vec3::ZERO).unwrap();
        let f = ct.specular_without_fresnel(dir(30., 0.), dir(30., 180.));
        assert!(close(f, 1.17893, 1e-5), "{f}");
    }

    #[test]
    fn oren_nayar() {
        check(
            "oren-nayar",
            &["albedo=0.7", "sigma=0.5"],
            &cases([
                1.771335767e-01,
                1.421871795e-01,
                1.806694070e-01,
                8.647570978e-02,
            ]),
        );
        // MODELS.md oracles, σ = 0.3, ρ = 1, (θi, θo, Δφ).
        for (ti, to, dphi, want) in [
            (30., 30., 0., 0.324557),
            (30., 30., 180., 0.289659),
            (60., 60., 0., 0.403933),
            (60., 20., 0., 0.327824),
            (60., 20., 180., 0.285146),
        ] {
            let b = build("oren-nayar", &["albedo=1", "sigma=0.3"]);
            let f = f64::from(b.eval(dir(ti, 0.), dir(to, dphi)).x);
            assert!(close(f, want, 3e-6), "ON ({ti},{to},{dphi}): {f} vs {want}");
        }
        // σ = 0 is Lambert exactly.
        let b = build("oren-nayar", &["albedo=0.5", "sigma=0"]);
        for (a, o) in PTS {
            let f = b.eval(dir(a.0, a.1), dir(o.0, o.1)).x;
            assert!(close(f64::from(f), 0.5 / std::f64::consts::PI, 1e-7));
        }
    }

    #[test]
    fn ward() {
        check(
            "ward",
            &["kd=0.1", "ks=0.5", "alpha_x=0.1", "alpha_y=0.3"],
            &cases([
                1.269051511e+00,
                3.717820602e-01,
                3.183117920e-02,
                1.113966521e-01,
            ]),
        );
    }

    #[test]
    fn schlick() {
        check(
            "schlick",
            &["c=0.4", "r=0.2", "p=0.3"],
            &cases([
                1.039632368e-01,
                2.670962989e-01,
                7.426195780e-02,
                1.053197591e+00,
            ]),
        );
    }
}

mod albedo {
    use super::*;

    /// (θi in degrees, expected luminance albedo, tolerance).
    fn check(name: &str, params: &[&str], table: &[(f64, f64, f64)]) {
        let b = build(name, params);
        for &(ti, want, tol) in table {
            let a = albedo(&*b, dir(ti, 0.));
            assert!(
                (a - want).abs() <= tol,
                "{name} {params:?} θi={ti}: albedo {a:.5} vs {want}"
            );
        }
    }

    #[test]
    fn blinn_phong_lobe_is_normalised() {
        // MODELS.md, n = 10, ks = 1 (two digits given).
        check(
            "blinn-phong",
            &["kd=0", "ks=1", "n=10"],
            &[
                (0., 1.0, 1e-4),
                (45., 0.61, 6e-3),
                (70., 0.28, 6e-3),
                (85., 0.13, 6e-3),
            ],
        );
        // Exactly ks at normal incidence for any n.
        for n in ["n=0", "n=2", "n=300"] {
            check("blinn-phong", &["kd=0", "ks=1", n], &[(0., 1.0, 2e-4)]);
        }
    }

    #[test]
    fn lewis_phong_specular_albedo() {
        check(
            "lewis-phong",
            &["kd=0", "ks=1", "n=10"],
            &[
                (0., 1.0, 2e-4),
                (45., 0.707, 1e-3),
                (70., 0.361, 1e-3),
                (85., 0.171, 1e-3),
            ],
        );
        check(
            "lewis-phong",
            &["kd=0", "ks=1", "n=100"],
            &[
                (0., 1.0, 2e-4),
                (45., 0.707, 1e-3),
                (70., 0.342, 1e-3),
                (85., 0.098, 1e-3),
            ],
        );
    }

    #[test]
    fn cook_torrance_with_unit_fresnel() {
        let ct = CookTorrance::new(0.1, Vec3::splat(0.5), Vec3::ZERO).unwrap();
        for (ti, want, tol) in [
            (0., 1.000, 1e-3),
            (45., 1.000, 1e-3),
            (70., 0.989, 1e-3),
            (85., 0.9375, 1e-3),
        ] {
            let wi = dir(ti, 0.);
            let a = hemisphere_integral(96, 6, |wo| {
                ct.specular_without_fresnel(wi, wo) * f64::from(wo.z)
            });
            assert!((a - want).abs() <= tol, "CT F=1 θi={ti}: {a:.5} vs {want}");
        }
    }

    #[test]
    fn oren_nayar_full_model_is_slightly_above_one_at_grazing() {
        check(
            "oren-nayar",
            &["albedo=1", "sigma=0.2"],
            &[
                (0., 0.9859, 5e-4),
                (30., 0.9872, 5e-4),
                (60., 0.9988, 5e-4),
                (80., 1.0188, 5e-4),
                (89., 1.0363, 1e-3),
            ],
        );
    }

    #[test]
    fn ward_albedo() {
        check(
            "ward",
            &["kd=0", "ks=1", "alpha_x=0.1", "alpha_y=0.1"],
            &[
                (0., 0.971, 1e-3),
                (45., 0.688, 1e-3),
                (70., 0.338, 1e-3),
                (85., 0.120, 3e-3),
            ],
        );
    }

    #[test]
    fn schlick_albedo() {
        check(
            "schlick",
            &["c=1", "p=1", "r=0.05"],
            &[
                (0., 0.933, 1e-3),
                (45., 0.897, 1e-3),
                (70., 0.847, 1e-3),
                (85., 1.074, 2e-3),
            ],
        );
        check(
            "schlick",
            &["c=1", "p=1", "r=0.5"],
            &[
                (0., 0.451, 1e-3),
                (45., 0.438, 1e-3),
                (70., 0.438, 1e-3),
                (85., 0.4545, 1e-3),
            ],
        );
        check(
            "schlick",
            &["c=1", "p=1", "r=1"],
            &[(0., 0.25, 1e-6), (45., 0.25, 1e-6), (85., 0.25, 1e-6)],
        );
    }

    /// Energy conservation where the registry claims it, over a grid of parameters and angles.
    #[test]
    fn conserving_models_never_exceed_one() {
        let sets: &[(&str, &[&str])] = &[
            ("lambert", &["albedo=1"]),
            ("lewis-phong", &["kd=0.5", "ks=0.5", "n=0"]),
            ("lewis-phong", &["kd=0", "ks=1", "n=3"]),
            ("lewis-phong", &["kd=0.2", "ks=0.8", "n=200"]),
            ("blinn-phong", &["kd=0.5", "ks=0.5", "n=1"]),
            ("blinn-phong", &["kd=0", "ks=1", "n=100"]),
            ("cook-torrance", &["m=1", "f0=0.999", "kd=0"]),
            ("cook-torrance", &["m=0.2", "f0=0.999", "kd=0"]),
        ];
        for (name, params) in sets {
            let info = registry::find(name).unwrap();
            assert!(!matches!(info.energy, Energy::NotConserving(_)), "{name}");
            let b = build(name, params);
            for ti in [0., 30., 60., 80., 89.] {
                let a = albedo(&*b, dir(ti, 20.));
                assert!(a <= 1.0 + 2e-3, "{name} {params:?} θi={ti}: albedo {a}");
            }
        }
    }
}

mod properties {
    use super::*;
    use brdf_core::ParamKind;
    use proptest::prelude::*;

    /// Directions: uniform on the sphere, grazing (z → 0⁺), exactly on the horizon, just below.
    fn direction() -> impl Strategy<Value = Vec3> {
        let phi = 0.0..std::f32::consts::TAU;
        prop_oneof![
            4 => (-1.0f32..1.0, phi.clone()).prop_map(|(z, p)| {
                let r = (1.0 - z * z).max(0.0).sqrt();
                Vec3::new(r * p.cos(), r * p.sin(), z)
            }),
            2 => (prop_oneof![Just(1e-7f32), Just(1e-4f32), 1e-6f32..1e-2], phi.clone())
                .prop_map(|(z, p)| Vec3::new(p.cos(), p.sin(), z).normalize()),
            1 => phi.clone().prop_map(|p| Vec3::new(p.cos(), p.sin(), 0.0)),
            1 => phi.prop_map(|p| Vec3::new(p.cos(), p.sin(), -1e-6).normalize()),
        ]
    }

    /// A model with random valid parameters (channels drawn independently within range).
    fn model() -> impl Strategy<Value = Box<dyn Brdf>> {
        let n = registry::models().len();
        (
            0..n,
            proptest::collection::vec((0.0f32..=1.0, 0.0f32..=1.0, 0.0f32..=1.0), 8),
        )
            .prop_filter_map("parameters break a cross-constraint", |(i, draws)| {
                let info = &registry::models()[i];
                let mut p = info.defaults();
                for (spec, (a, b, c)) in info.params.iter().zip(draws) {
                    // Log-uniform for wide positive ranges (exponents), else uniform.
                    let lerp = |t: f32| {
                        if spec.max / spec.min.max(1e-3) > 1e3 {
                            ((spec.max + 1.0).ln() * t).exp() - 1.0
                        } else {
                            spec.min + (spec.max - spec.min) * t
                        }
                        .clamp(spec.min, spec.max)
                    };
                    let v = match spec.kind {
                        ParamKind::Scalar => brdf_core::ParamValue::Scalar(lerp(a)),
                        ParamKind::Rgb => {
                            brdf_core::ParamValue::Rgb(Vec3::new(lerp(a), lerp(b), lerp(c)))
                        }
                    };
                    if p.set(spec.name, v).is_err() {
                        return None;
                    }
                }
                info.build(&p).ok()
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 4000, ..ProptestConfig::default() })]

        #[test]
        fn finite_nonnegative_and_zero_below_horizon(b in model(), wi in direction(), wo in direction()) {
            let f = b.eval(wi, wo);
            prop_assert!(f.is_finite() && f.min_element() >= 0.0, "{}: f({wi}, {wo}) = {f} ({:?})", b.name(), b.params());
            if wi.z <= 0.0 || wo.z <= 0.0 {
                prop_assert_eq!(f, Vec3::ZERO);
            }
            let p = b.pdf(wi, wo);
            prop_assert!(p.is_finite() && p >= 0.0);
        }

        #[test]
        fn reciprocal(b in model(), wi in direction(), wo in direction()) {
            prop_assume!(registry::find(b.name()).unwrap().reciprocal);
            let (a, c) = (b.eval(wi, wo), b.eval(wo, wi));
            for k in 0..3 {
                prop_assert!((a[k] - c[k]).abs() <= 2e-5 * a[k].abs().max(c[k].abs()) + 1e-30,
                    "{}: f(wi,wo) = {a} but f(wo,wi) = {c} ({:?})", b.name(), b.params());
            }
        }

        #[test]
        fn samples_agree_with_eval_and_pdf(b in model(), wi in direction(), uc in 0.0f32..1.0, u0 in 0.0f32..1.0, u1 in 0.0f32..1.0) {
            let s = b.sample(wi, uc, Vec2::new(u0, u1));
            if wi.z <= 0.0 {
                prop_assert!(s.is_none());
            }
            if let Some(s) = s {
                prop_assert!((s.wo.length() - 1.0).abs() < 1e-5 && s.wo.z > 0.0);
                prop_assert!(s.pdf > 0.0 && s.pdf.is_finite());
                if s.delta {
                    prop_assert!(b.is_delta());
                    prop_assert!((s.wo - brdf_core::geometry::mirror(wi.normalize())).length() < 1e-6);
                } else {
                    prop_assert_eq!(s.pdf, b.pdf(wi, s.wo));
                    prop_assert_eq!(s.f, b.eval(wi, s.wo));
                    let w = s.f * s.wo.z / s.pdf;
                    prop_assert!((s.weight - w).abs().max_element() <= 1e-6 * w.max_element());
                }
            }
        }
    }
}

mod samplers {
    use super::*;

    /// Parameter sets: defaults and a sharp setting of each glossy model.
    const SETS: &[(&str, &[&str])] = &[
        ("lambert", &[]),
        ("phong", &[]),
        ("phong", &["n=1000", "kd=0.1"]),
        ("blinn-phong", &[]),
        ("blinn-phong", &["n=2000", "kd=0"]),
        ("lewis-phong", &[]),
        ("cook-torrance", &[]),
        ("cook-torrance", &["m=0.1", "kd=0.2"]),
        ("oren-nayar", &[]),
        ("ward", &[]),
        ("ward", &["alpha_x=0.05", "alpha_y=0.2"]),
        ("schlick", &[]),
        ("schlick", &["r=0.02", "p=0.2"]),
    ];

    /// Mean estimator weight ≈ ∫ f cos dω (independent quadrature) within 4 standard errors
    /// (two-sided α ≈ 6e-5 per check; fixed seeds make the outcome deterministic anyway).
    #[test]
    fn mean_weight_matches_albedo() {
        let n = 200_000;
        for (k, &(name, params)) in SETS.iter().enumerate() {
            let b = build(name, params);
            for (j, ti) in [0.0, 45.0, 80.0].into_iter().enumerate() {
                let wi = dir(ti, 30.0);
                let mut rng = Pcg64::seed_from_u64(1000 + 10 * k as u64 + j as u64);
                let (mut s1, mut s2, mut hits) = (0.0f64, 0.0f64, 0usize);
                for _ in 0..n {
                    let u = Vec2::new(rng.random(), rng.random());
                    let w = b.sample(wi, rng.random(), u).map_or(0.0, |s| {
                        hits += 1;
                        f64::from(luminance(s.weight))
                    });
                    s1 += w;
                    s2 += w * w;
                }
                let mean = s1 / n as f64;
                let se = ((s2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
                let a = albedo(&*b, wi);
                assert!(
                    (mean - a).abs() <= 4.0 * se + 1e-4 * a,
                    "{name} {params:?} θi={ti}: mean weight {mean:.5} ± {se:.5} vs albedo {a:.5}"
                );
                // The pdf's mass over the upper hemisphere is the fraction of samples kept.
                let mass = hemisphere_integral(96, 6, |wo| f64::from(b.pdf(wi, wo)));
                let frac = hits as f64 / n as f64;
                let se_frac = (frac * (1.0 - frac) / n as f64).sqrt();
                assert!(mass <= 1.0 + 1e-3, "{name}: pdf mass {mass}");
                assert!(
                    (mass - frac).abs() <= 4.0 * se_frac + 1e-3,
                    "{name} {params:?} θi={ti}: pdf mass {mass:.5} vs kept fraction {frac:.5}"
                );
            }
        }
    }

    #[test]
    fn mirror_sample_is_the_exact_delta() {
        let m = build("mirror", &["reflectance=0.9,0.5,0.1"]);
        let wi = dir(40.0, 10.0);
        let s = m.sample(wi, 0.3, Vec2::new(0.1, 0.9)).unwrap();
        assert!(s.delta);
        assert_eq!(s.wo, brdf_core::geometry::mirror(wi));
        assert_eq!(s.weight, Vec3::new(0.9, 0.5, 0.1));
        assert!(m.is_delta());
    }

    #[test]
    fn checked_entry_points_give_typed_errors() {
        use brdf_core::DirectionError;
        let b = build("phong", &[]);
        assert_eq!(
            b.try_eval(Vec3::new(f32::NAN, 0.0, 1.0), Vec3::Z),
            Err(DirectionError::NotFinite)
        );
        assert_eq!(
            b.try_eval(Vec3::Z, Vec3::ZERO),
            Err(DirectionError::ZeroLength)
        );
        assert_eq!(b.try_eval(Vec3::Z, -Vec3::Z), Ok(Vec3::ZERO));
        assert_eq!(
            b.try_sample(-Vec3::Z, 0.5, Vec2::splat(0.5)),
            Err(DirectionError::BelowHorizon)
        );
        assert!(
            b.try_sample(Vec3::new(0.0, 0.0, 3.0), 0.5, Vec2::splat(0.5))
                .unwrap()
                .is_some()
        );
        // NaN directions in the unchecked hot path give 0, never NaN.
        assert_eq!(b.eval(Vec3::new(0.0, f32::NAN, 1.0), Vec3::Z), Vec3::ZERO);
    }
}

mod registry_tests {
    use super::*;
    use brdf_core::ParamError;

    #[test]
    fn nine_models_with_documented_parameters() {
        let names: Vec<_> = registry::models().iter().map(|m| m.name).collect();
        assert_eq!(
            names,
            [
                "lambert",
                "mirror",
                "phong",
                "blinn-phong",
                "lewis-phong",
                "cook-torrance",
                "oren-nayar",
                "ward",
                "schlick"
            ]
        );
        for info in registry::models() {
            let b = info.build(&info.defaults()).unwrap();
            assert_eq!(b.name(), info.name);
            assert_eq!(
                b.params(),
                info.defaults(),
                "{}: params() round-trips the defaults",
                info.name
            );
            assert_eq!(b.is_delta(), info.delta);
            assert_eq!(b.has_analytic_sampler(), info.analytic_sampler);
            for s in info.params {
                assert!(
                    !s.doc.is_empty() && s.contains(s.default[0]),
                    "{}.{}",
                    info.name,
                    s.name
                );
            }
        }
    }

    #[test]
    fn bad_parameters_are_typed_errors_naming_the_parameter_and_range() {
        let e = registry::create("ward", ["alpha_x=0"]).unwrap_err();
        assert!(matches!(
            e,
            ParamError::OutOfRange {
                name: "alpha_x",
                ..
            }
        ));
        assert!(
            e.to_string().contains("alpha_x") && e.to_string().contains("[0.001, 1]"),
            "{e}"
        );
        let e = registry::create("lewis-phong", ["kd=0.6", "ks=0.5"]).unwrap_err();
        assert!(matches!(e, ParamError::Constraint { .. }), "{e}");
        assert!(registry::create("lewis-phong", ["kd=0.5", "ks=0.5"]).is_ok());
        assert!(matches!(
            registry::create("nope", []),
            Err(ParamError::UnknownModel { .. })
        ));
        assert!(matches!(
            registry::create("phong", ["m=1"]),
            Err(ParamError::UnknownParam { .. })
        ));
        assert!(matches!(
            registry::create("phong", ["n=inf"]),
            Err(ParamError::OutOfRange { .. })
        ));
        assert!(matches!(
            registry::create("cook-torrance", ["f0=1"]),
            Err(ParamError::OutOfRange { .. })
        ));
        let ward = registry::find("ward").unwrap();
        assert!(
            ward.build(&registry::find("phong").unwrap().defaults())
                .is_err()
        );
    }
}
