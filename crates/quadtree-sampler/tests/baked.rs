//! The baked sampler (SPEC §7): its pdf is the density of what it draws at any wi (χ² against
//! its own pdf, every continuous model, both modes, on- and off-grid, to grazing), its mean
//! weight is the albedo, the checks can fail (a mixture that drops a neighbour's weight from
//! its pdf), both transport roles, the world frame, serial == parallel bakes, and bake files
//! (round trip, and a typed error for every kind of damage).

use brdf_core::quadrature::directional_albedo;
use brdf_core::{Brdf, geometry::luminance, registry};
use brdf_validate::{CellGrid, Validation, sidak};
use glam::{Quat, Vec2, Vec3};
use quadtree_sampler::{
    BakeConfig, BakeError, BakeFileError, BakedError, BakedMode, BakedSampler, DirectionSampler,
    GRID_THETA_MAX_DEG, Role, Sample, WorldBsdf, uniform_f32,
};
use rand_core::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::sync::Arc;

fn dir(theta: f64, phi: f64) -> Vec3 {
    let (t, p) = (theta.to_radians(), phi.to_radians());
    Vec3::new(
        (t.sin() * p.cos()) as f32,
        (t.sin() * p.sin()) as f32,
        t.cos() as f32,
    )
}

fn model(name: &str, params: &[&str]) -> Arc<dyn Brdf> {
    registry::create(name, params.iter().copied())
        .unwrap()
        .into()
}

/// A small grid (8 θ rows, 3 φ columns): neighbours far apart, so the mixture and its
/// rotations are exercised hard.
fn small() -> BakeConfig {
    BakeConfig {
        theta_steps: 8,
        phi_steps: 3,
        ..BakeConfig::default()
    }
}

/// Every continuous model at its defaults, plus a sharp lobe and an anisotropic Ward.
fn models() -> Vec<(&'static str, Vec<&'static str>)> {
    let mut v: Vec<_> = registry::models()
        .iter()
        .filter(|m| !m.delta && !m.measured)
        .map(|m| (m.name, vec![]))
        .collect();
    v.push(("phong", vec!["n=1000", "kd=0"]));
    v.push(("ward", vec!["alpha_x=0.05", "alpha_y=0.2"]));
    v
}

fn costly(name: &str) -> bool {
    matches!(name, "htsg" | "poulin-fournier")
}

/// On-grid (row 3 of 8: 38.14°, φ = 0, and the last row at another φ), off-grid, grazing
/// and beyond the last row.
fn incident(name: &str) -> Vec<Vec3> {
    let row3 = 3.0 * GRID_THETA_MAX_DEG / 7.0;
    if costly(name) {
        vec![dir(52.3, 37.0), dir(85.0, 200.0)]
    } else {
        vec![
            dir(row3, 0.0),
            dir(52.3, 37.0),
            dir(85.0, 200.0),
            dir(GRID_THETA_MAX_DEG, 123.0),
            dir(89.6, 301.0),
        ]
    }
}

/// Every sample's pdf is `pdf(wi, wo)` and its f is `eval(wi, wo)`, every model, both
/// modes, on- and off-grid wi (both roles for the non-reciprocal model).
#[test]
fn sample_pdf_and_eval_agree_with_pdf_and_eval() {
    for (name, params) in models() {
        let b = model(name, &params);
        let config = BakeConfig {
            theta_steps: 4,
            phi_steps: 2,
            ..BakeConfig::default()
        };
        let mut baked = BakedSampler::new(b.clone(), config).unwrap();
        for mode in [BakedMode::Rejection, BakedMode::Warp] {
            baked.set_mode(mode);
            let mut rng = Pcg64::seed_from_u64(3);
            for wi in incident(name) {
                for role in [Role::Importance, Role::Radiance] {
                    // The same answers prepared once at wi: bit for bit, the same numbers
                    // drawn from the RNG.
                    let point = baked.point(role, wi).unwrap();
                    assert_eq!((point.role(), point.mode()), (role, mode));
                    let mut got = 0;
                    for _ in 0..300 {
                        let uc = uniform_f32(&mut rng);
                        let u = Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng));
                        let mut twin = rng.clone();
                        let s = baked.sample_as(role, wi, uc, u, &mut rng).unwrap();
                        assert_eq!(
                            point.sample(uc, u, &mut twin),
                            s,
                            "{name} {mode:?} {role:?}"
                        );
                        assert_eq!(twin, rng);
                        let mut twin = rng.clone();
                        assert_eq!(
                            point.sample_continuous(uc, u, &mut twin),
                            baked
                                .sample_continuous_as(role, wi, uc, u, &mut rng.clone())
                                .unwrap()
                        );
                        // And at a direction no sample came from (a light sample's).
                        let light = Vec3::new(
                            uniform_f32(&mut twin) - 0.5,
                            uniform_f32(&mut twin) - 0.5,
                            uniform_f32(&mut twin),
                        );
                        let (f, p) = point.eval_pdf(light).unwrap();
                        let at = format!("{name} {mode:?} {role:?} wi {wi} light {light}");
                        assert_eq!(f, baked.eval_as(role, wi, light).unwrap(), "{at}");
                        let want = baked.pdf_as(role, wi, light).unwrap();
                        assert_eq!(p.to_bits(), want.to_bits(), "{at}: {p} vs {want}");
                        assert_eq!(
                            point.pdf_continuous(light).unwrap().to_bits(),
                            baked.pdf_continuous_as(role, wi, light).unwrap().to_bits(),
                            "{at}"
                        );
                        let Some(s) = s else {
                            continue;
                        };
                        got += 1;
                        if s.delta {
                            continue;
                        }
                        let pdf = baked.pdf_as(role, wi, s.wo).unwrap();
                        assert_eq!(point.pdf(s.wo).unwrap().to_bits(), pdf.to_bits());
                        // Bit-identical: one expression behind both, and in warp mode
                        // the drawing leaf's stored density is the one a look-up finds.
                        assert_eq!(
                            s.pdf.to_bits(),
                            pdf.to_bits(),
                            "{name} {mode:?} {role:?} wi {wi}: sample pdf {} vs pdf {pdf}",
                            s.pdf
                        );
                        assert_eq!(s.f, baked.eval_as(role, wi, s.wo).unwrap());
                        let want = match role {
                            Role::Importance => b.eval(wi, s.wo),
                            Role::Radiance => b.eval(s.wo, wi),
                        };
                        assert_eq!(s.f, want);
                        assert!(s.weight.is_finite() && s.pdf > 0.0);
                    }
                    // The warp proxy over the orthographic square spreads a leaf's share over
                    // all of its square: the part outside the disk (at most 1 − π/4 of a
                    // one-leaf tree) is lost. Rejection re-draws there; what it loses is
                    // what the neighbours' maps carry below the horizon, which on a grid
                    // this coarse (4 × 2) the half-vector transport does more of for a broad
                    // anisotropic lobe than a rotation did (Poulin–Fournier at 85°: 266 of
                    // 300 samples returned, where rotations returned over 270).
                    let least = if mode == BakedMode::Warp { 200 } else { 255 };
                    assert!(got > least, "{name} {mode:?}: only {got} of 300 samples");
                }
            }
        }
    }
}

/// χ² of the baked sampler against its own pdf at family-wise α = 0.01 (Šidák over the
/// run's tests): every continuous model, both modes, on-grid, off-grid, 85°, the last row
/// (89°) and beyond it (89.6°), 10⁶ samples a test (2·10⁵ for the costly models, at two wi).
/// 118 tests, about 3 minutes on 2 cores.
#[test]
fn chi2_against_its_own_pdf() {
    let plan = |name: &str| -> Vec<(Vec3, BakedMode)> {
        incident(name)
            .into_iter()
            .flat_map(|w| [(w, BakedMode::Rejection), (w, BakedMode::Warp)])
            .collect()
    };
    let tests: usize = models().iter().map(|(n, _)| plan(n).len()).sum();
    let alpha = sidak(0.01, tests);
    let grid = CellGrid::Polar {
        rings: 16,
        sectors: 33,
    };
    let mut seed = 100;
    for (name, params) in models() {
        let cases = plan(name);
        let b = model(name, &params);
        let mut baked = BakedSampler::new(b.clone(), small()).unwrap();
        let samples = if costly(name) { 200_000 } else { 1_000_000 };
        for (wi, mode) in cases {
            let v = Validation::new(&*b, wi, grid, 1e-7).unwrap();
            baked.set_mode(mode);
            seed += 1;
            let at = baked.at(wi).unwrap();
            let r = v.test_chunked(
                &at,
                samples,
                |k| Pcg64::seed_from_u64(seed * 1000 + k),
                alpha,
            );
            let c = r.chi2_own.as_ref().unwrap();
            println!(
                "{name} {params:?} {mode:?} wi {wi}: own χ² {:.1} dof {} p {:.4}, lost {}",
                c.statistic, c.dof, c.p_value, r.lost
            );
            assert!(
                r.passed_own(),
                "{name} {params:?} {mode:?} wi {wi}: {:?}",
                r.rejections(brdf_validate::Against::OwnPdf)
            );
        }
        assert_eq!(baked.bound_violations(), 0, "{name}");
    }
}

/// The negative control: a mixture whose reported pdf leaves out one neighbour's weight is
/// rejected by the same test (and its weights are biased).
#[test]
fn a_pdf_that_drops_a_neighbour_is_rejected() {
    let b = model("phong", &["n=200", "kd=0.1"]);
    // Linear weights everywhere: the control needs two neighbours at its wi, whichever cells
    // the bake found a nearest tree enough for (there, there is no neighbour to drop).
    let mut baked = BakedSampler::new(b.clone(), small()).unwrap();
    baked.blend_everywhere_for_testing();
    let baked = Arc::new(baked);
    // Halfway between rows 3 and 4: both neighbours weigh ½.
    let wi = dir(3.5 * GRID_THETA_MAX_DEG / 7.0, 20.0);
    let broken = baked.clone().broken_pdf_for_testing();
    let p = assert_broken_rejected(&*b, &broken, wi, 1_000_000, 7);
    assert!(p < 1e-10);
}

/// χ² of `broken` at `wi` against its own (wrong) pdf, `samples` in chunks seeded from
/// `seed`, at α = 0.01: asserts the test rejects it, and returns the p-value.
fn assert_broken_rejected(
    b: &dyn Brdf,
    broken: &quadtree_sampler::BrokenPdf,
    wi: Vec3,
    samples: u64,
    seed: u64,
) -> f64 {
    let grid = CellGrid::Polar {
        rings: 16,
        sectors: 33,
    };
    let v = Validation::new(b, wi, grid, 1e-7).unwrap();
    let r = v.test_chunked(
        &broken.at(wi),
        samples,
        |k| Pcg64::seed_from_u64(seed + k),
        sidak(0.01, 1),
    );
    let c = r.chi2_own.as_ref().unwrap();
    println!(
        "broken: own χ² {:.1} dof {} p {:e}",
        c.statistic, c.dof, c.p_value
    );
    assert!(!r.passed_own(), "the broken pdf passed: {c:?}");
    c.p_value
}

/// The mean luminance weight f·cos/pdf of `n` samples (lost samples score 0, every number
/// drawn from a generator seeded by `seed`) and its standard error, with 10⁻⁶ of the mean
/// in quadrature for the rounding of the f32 weights and of the quadrature albedo: Lambert's
/// one exact tree draws weights equal to the albedo to within that rounding (1.9·10⁻⁸ of it,
/// a standard error of 8.8·10⁻¹⁰ alone).
fn mean_weight(s: &dyn DirectionSampler, n: u32, seed: u64) -> (f64, f64) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (mut sum, mut sq) = (0.0f64, 0.0f64);
    for _ in 0..n {
        let w = s
            .sample(&mut rng)
            .map_or(0.0, |s: Sample| f64::from(luminance(s.weight)));
        sum += w;
        sq += w * w;
    }
    let m = sum / f64::from(n);
    let var = (sq / f64::from(n) - m * m) / f64::from(n);
    (m, (var + (1e-6 * m).powi(2)).sqrt())
}

/// The mean weight f·cos/pdf at off-grid wi (beyond the last row too) equals the quadrature
/// albedo within 4 standard errors at 10⁶ samples (lost samples score 0), both modes; the
/// broken pdf's does not.
#[test]
fn mean_weight_is_the_albedo() {
    let cases = [
        ("phong", vec!["n=1000", "kd=0"], dir(52.3, 37.0)),
        ("cook-torrance", vec!["m=0.1"], dir(71.0, 250.0)),
        (
            "ward",
            vec!["alpha_x=0.05", "alpha_y=0.2"],
            dir(63.0, 100.0),
        ),
        ("oren-nayar", vec![], dir(84.0, 10.0)),
        ("strauss", vec!["smoothness=0.9"], dir(30.0, 300.0)),
        ("lambert", vec![], dir(89.6, 0.0)),
        // Beyond the last row, where the retro-reflection lies in the band above the
        // horizon that the last row's tree, tilted onto wi's mirror, leaves uncovered.
        ("oren-nayar", vec!["sigma=0.5"], dir(89.9, 200.0)),
    ];
    for (k, (name, params, wi)) in cases.into_iter().enumerate() {
        let b = model(name, &params);
        let albedo = f64::from(luminance(directional_albedo(&*b, wi, 96, 6).as_vec3()));
        let mut baked = BakedSampler::new(b.clone(), small()).unwrap();
        for mode in [BakedMode::Rejection, BakedMode::Warp] {
            baked.set_mode(mode);
            let (m, se) = mean_weight(&baked.at(wi).unwrap(), 1_000_000, k as u64);
            println!("{name} {mode:?}: mean weight {m:.6} ± {se:.1e}, albedo {albedo:.6}");
            assert!(
                (m - albedo).abs() <= 4.0 * se,
                "{name} {mode:?}: {m} ± {se} vs {albedo}"
            );
        }
    }
    // A coarse grid beyond its last row: 3 rows, 44.5° apart. Measured in that grid's own
    // spacings, the last tree's untilted share at 89.5° was 1.1 %, the band above the
    // horizon it covers was drawn too rarely to count, and this mean (rejection) came out
    // 1.044193 ± 9.0·10⁻⁵: 6.0 standard errors low (4.3 to 5.9 at three of six seeds of
    // `brdf test` at 3·10⁵ samples). Now 1.044668 ± 8.9·10⁻⁵.
    let b = model("oren-nayar", &["albedo=1"]);
    let wi = dir(89.5, 71.0);
    let albedo = f64::from(luminance(directional_albedo(&*b, wi, 96, 6).as_vec3()));
    let coarse = BakeConfig {
        theta_steps: 3,
        ..BakeConfig::default()
    };
    let mut baked = BakedSampler::new(b, coarse).unwrap();
    for mode in [BakedMode::Rejection, BakedMode::Warp] {
        baked.set_mode(mode);
        let (m, se) = mean_weight(&baked.at(wi).unwrap(), 1_000_000, 5);
        println!("coarse oren-nayar {mode:?}: mean weight {m:.6} ± {se:.1e}, albedo {albedo:.6}");
        assert!(
            (m - albedo).abs() <= 4.0 * se,
            "coarse oren-nayar {mode:?}: {m} ± {se} vs {albedo}"
        );
    }
    let b = model("phong", &["n=200", "kd=0.1"]);
    let mut baked = BakedSampler::new(b.clone(), small()).unwrap();
    baked.blend_everywhere_for_testing();
    let baked = Arc::new(baked);
    let wi = dir(3.5 * GRID_THETA_MAX_DEG / 7.0, 20.0);
    let albedo = f64::from(luminance(directional_albedo(&*b, wi, 96, 6).as_vec3()));
    let broken = baked.broken_pdf_for_testing();
    let (m, se) = mean_weight(&broken.at(wi), 1_000_000, 99);
    assert!(
        (m - albedo).abs() > 4.0 * se,
        "broken: {m} ± {se} vs {albedo}"
    );
}

/// A model that declares f_r independent of wi is answered at every wi by one tree, not
/// rotated: at any wi, grazing included, its rejection-mode weight is the albedo itself
/// (the tree is exact ∝ f·cos, and so is the defensive cosine share), and its pdf at a wo is
/// the same whatever wi is, in both modes. Blended and rotated neighbours (as before the
/// declaration existed) gave weights spread around the albedo. A model with a faint
/// glossy part, which does not declare it, still blends.
#[test]
fn a_model_independent_of_wi_is_answered_by_one_tree() {
    let wis = [
        dir(0.0, 0.0),
        dir(37.1, 20.0),
        dir(85.0, 200.0),
        dir(89.9, 301.0),
    ];
    for (name, params, albedo) in [
        ("lambert", vec!["albedo=0.6"], 0.6),
        ("phong", vec!["kd=0.7", "ks=0", "n=1000"], 0.7),
        ("oren-nayar", vec!["sigma=0"], 0.8),
    ] {
        let mut baked = BakedSampler::new(model(name, &params), small()).unwrap();
        let cells = baked.grid().cells();
        for mode in [BakedMode::Rejection, BakedMode::Warp] {
            assert_eq!(baked.nearest_cells(mode), (cells, cells), "{name}");
        }
        for (k, &wi) in wis.iter().enumerate() {
            let trees = baked.mixture_at(Role::Importance, wi).unwrap();
            assert_eq!(trees.len(), 1, "{name} at {wi}: {trees:?}");
            assert_eq!(trees[0].weight, 1.0);
            for mode in [BakedMode::Rejection, BakedMode::Warp] {
                baked.set_mode(mode);
                let mut rng = Pcg64::seed_from_u64(k as u64);
                let (mut worst, mut drawn) = (0.0f64, 0);
                for _ in 0..20_000 {
                    let Some(s) = baked
                        .sample(
                            wi,
                            uniform_f32(&mut rng),
                            Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng)),
                            &mut rng,
                        )
                        .unwrap()
                    else {
                        continue;
                    };
                    drawn += 1;
                    let other = wis[(k + 1) % wis.len()];
                    assert_eq!(baked.pdf(other, s.wo).unwrap(), s.pdf, "{name} {mode:?}");
                    let w = f64::from(luminance(s.weight));
                    worst = worst.max((w / albedo - 1.0).abs());
                }
                // Nothing is lost below the horizon: no rotation tilts the tree.
                assert_eq!(drawn, 20_000, "{name} {mode:?} at {wi}");
                if mode == BakedMode::Rejection {
                    assert!(
                        worst < 1e-4,
                        "{name} at {wi}: weight off the albedo by {worst}"
                    );
                }
            }
        }
    }
    let faint = BakedSampler::new(model("phong", &["ks=0.01"]), small()).unwrap();
    assert_eq!(
        faint
            .mixture_at(Role::Importance, dir(37.1, 20.0))
            .unwrap()
            .len(),
        2
    );
}

/// A false promise of independence costs variance, not correctness: Oren–Nayar (σ = 0.5)
/// claimed independent of wi is sampled by its θi = 0 tree at θi = 70°, and the reported pdf
/// is still the density of what is drawn (its mean weight is the albedo, within 4 standard
/// errors at 2·10⁵ samples, both modes).
#[test]
fn a_false_promise_of_independence_stays_unbiased() {
    #[derive(Debug)]
    struct Claims(Arc<dyn Brdf>);
    impl Brdf for Claims {
        fn name(&self) -> &'static str {
            self.0.name()
        }
        fn params(&self) -> brdf_core::ParamSet {
            self.0.params()
        }
        fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
            self.0.eval(wi, wo)
        }
        fn symmetry(&self) -> brdf_core::Symmetry {
            self.0.symmetry()
        }
        fn independent_of_incident(&self) -> bool {
            true
        }
    }
    let b = model("oren-nayar", &["sigma=0.5"]);
    let wi = dir(70.0, 40.0);
    let albedo = f64::from(luminance(directional_albedo(&*b, wi, 96, 6).as_vec3()));
    let mut baked = BakedSampler::new(Arc::new(Claims(b)), small()).unwrap();
    assert_eq!(baked.mixture_at(Role::Importance, wi).unwrap().len(), 1);
    for mode in [BakedMode::Rejection, BakedMode::Warp] {
        baked.set_mode(mode);
        let mut rng = Pcg64::seed_from_u64(7);
        for _ in 0..10_000 {
            if let Some(s) = baked.at(wi).unwrap().sample(&mut rng) {
                assert_eq!(s.pdf, baked.pdf(wi, s.wo).unwrap());
            }
        }
        let (m, se) = mean_weight(&baked.at(wi).unwrap(), 200_000, 7);
        println!("{mode:?}: mean weight {m:.6} ± {se:.1e}, albedo {albedo:.6}");
        assert!(
            (m - albedo).abs() <= 4.0 * se,
            "{mode:?}: {m} ± {se} vs {albedo}"
        );
        // The weights vary (the θi = 0 tree is not the 70° density): not a constant test.
        assert!(se > 1e-5, "{mode:?}: {se}");
    }
}

/// The non-reciprocal model's camera-path role samples the light direction by its adjoint:
/// χ² against f_r(wi, given)·cos θi (judged on its own pdf), and its adjoint trees differ from
/// the forward ones; a reciprocal model's two roles draw the same directions.
#[test]
fn transport_roles() {
    #[derive(Debug)]
    struct Swap(Arc<dyn Brdf>);
    impl Brdf for Swap {
        fn name(&self) -> &'static str {
            "adjoint"
        }
        fn params(&self) -> brdf_core::ParamSet {
            self.0.params()
        }
        fn eval(&self, a: Vec3, b: Vec3) -> Vec3 {
            self.0.eval(b, a)
        }
    }
    struct AsRadiance<'a>(&'a BakedSampler, Vec3);
    impl DirectionSampler for AsRadiance<'_> {
        fn name(&self) -> &'static str {
            "radiance"
        }
        fn sample_with(&self, uc: f32, u: Vec2, rng: &mut dyn Rng) -> Option<Sample> {
            self.0
                .sample_as(Role::Radiance, self.1, uc, u, rng)
                .unwrap()
        }
        fn pdf(&self, w: Vec3) -> f32 {
            self.0.pdf_as(Role::Radiance, self.1, w).unwrap()
        }
    }
    let strauss = model("strauss", &["smoothness=0.8", "metalness=0.5"]);
    let baked = BakedSampler::new(strauss.clone(), small()).unwrap();
    assert_eq!(baked.trees(), 2 * baked.grid().len());
    let given = dir(52.3, 37.0);
    let adjoint = Swap(strauss.clone());
    let v = Validation::new(&adjoint, given, CellGrid::Square { res: 20 }, 1e-7).unwrap();
    let r = v.test_chunked(
        &AsRadiance(&baked, given),
        1_000_000,
        Pcg64::seed_from_u64,
        sidak(0.01, 2),
    );
    println!("strauss radiance: {:?} {:?}", r.chi2, r.chi2_own);
    assert!(
        r.passed_own(),
        "{:?}",
        r.rejections(brdf_validate::Against::OwnPdf)
    );
    // The forward tables would be the wrong density for this role: judged as if they were
    // the adjoint's, they are rejected (the adjoint is not optional).
    let r = v.test_chunked(
        &baked.at(given).unwrap(),
        1_000_000,
        Pcg64::seed_from_u64,
        sidak(0.01, 2),
    );
    assert!(
        !r.passed(),
        "forward tables pass as the adjoint: {:?}",
        r.chi2
    );

    let phong = model("phong", &["n=100"]);
    let baked = BakedSampler::new(phong, small()).unwrap();
    assert_eq!(baked.trees(), baked.grid().len());
    let mut a = Pcg64::seed_from_u64(1);
    let mut b = Pcg64::seed_from_u64(1);
    for _ in 0..200 {
        let (uc, u) = (
            uniform_f32(&mut a),
            Vec2::new(uniform_f32(&mut a), uniform_f32(&mut a)),
        );
        let _ = (
            uniform_f32(&mut b),
            uniform_f32(&mut b),
            uniform_f32(&mut b),
        );
        let x = baked
            .sample_as(Role::Importance, given, uc, u, &mut a)
            .unwrap();
        let y = baked
            .sample_as(Role::Radiance, given, uc, u, &mut b)
            .unwrap();
        assert_eq!(x.map(|s| s.wo), y.map(|s| s.wo));
    }
}

/// The world-frame wrapper is the local sampler seen through its frame.
#[test]
fn world_frame() {
    let ward = model("ward", &["alpha_x=0.05", "alpha_y=0.2"]);
    let baked = BakedSampler::new(ward.clone(), small()).unwrap();
    let r = Quat::from_euler(glam::EulerRot::XYZ, 0.4, -1.1, 2.0);
    let (n, t) = (r * Vec3::Z, r * Vec3::X);
    let world = WorldBsdf::new(&baked, n, Some(t)).unwrap();
    let wi_local = dir(40.0, 75.0);
    let wi = r * wi_local;
    let mut a = Pcg64::seed_from_u64(4);
    let mut b = Pcg64::seed_from_u64(4);
    for _ in 0..200 {
        let (uc, u) = (0.37, Vec2::new(uniform_f32(&mut a), uniform_f32(&mut a)));
        let _ = (uniform_f32(&mut b), uniform_f32(&mut b));
        let sw = world.sample(Role::Importance, wi, uc, u, &mut a).unwrap();
        let sl = baked
            .sample(world.frame().to_local(wi), uc, u, &mut b)
            .unwrap();
        let (Some(sw), Some(sl)) = (sw, sl) else {
            continue;
        };
        assert!(
            (sw.wo - r * sl.wo).length() < 1e-5,
            "{} vs {}",
            sw.wo,
            r * sl.wo
        );
        let p = world.pdf(Role::Importance, wi, sw.wo).unwrap();
        assert!((p - sl.pdf).abs() <= 1e-3 * sl.pdf, "{p} vs {}", sl.pdf);
        let f = world.eval(Role::Importance, wi, sw.wo).unwrap();
        assert!((f - sl.f).abs().max_element() <= 1e-3 * sl.f.max_element());
    }
    // Prepared at wi, the world point answers as the wrapper does, bit for bit.
    for role in [Role::Importance, Role::Radiance] {
        let point = world.point(role, wi).unwrap();
        assert!((point.local().given() - world.frame().to_local(wi).normalize()).length() < 1e-6);
        let mut a = Pcg64::seed_from_u64(5);
        for _ in 0..100 {
            let (uc, u) = (
                uniform_f32(&mut a),
                Vec2::new(uniform_f32(&mut a), uniform_f32(&mut a)),
            );
            let mut b = a.clone();
            let sw = world.sample(role, wi, uc, u, &mut a).unwrap();
            assert_eq!(point.sample(uc, u, &mut b), sw);
            let Some(sw) = sw else { continue };
            assert_eq!(
                point.eval_pdf(sw.wo).unwrap(),
                (
                    world.eval(role, wi, sw.wo).unwrap(),
                    world.pdf(role, wi, sw.wo).unwrap()
                )
            );
        }
    }
    assert!(WorldBsdf::new(&baked, Vec3::ZERO, None).is_err());
    assert!(world.point(Role::Importance, -n).is_err());
}

/// A bake with rayon (1 and 4 threads) is bit-identical to the serial bake. (Only with the
/// `rayon` feature, which `cargo test --workspace` turns on: without it the "parallel" bake
/// is the serial one.)
#[cfg(feature = "rayon")]
#[test]
fn serial_and_parallel_bakes_are_identical() {
    for (name, params) in [
        ("ward", vec!["alpha_x=0.05", "alpha_y=0.2"]),
        ("strauss", vec![]),
    ] {
        let b = model(name, &params);
        let mut serial = small();
        serial.build.parallel = false;
        let reference = BakedSampler::new(b.clone(), serial).unwrap().to_bytes();
        for threads in [1, 4] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let par = pool.install(|| BakedSampler::new(b.clone(), small()).unwrap());
            assert!(par.to_bytes() == reference, "{name} on {threads} threads");
        }
    }
}

/// Round trip: a loaded bake is the same sampler (same bytes, same samples).
#[test]
fn bake_file_round_trip() {
    for (name, params) in [
        ("strauss", vec![]),
        ("ward", vec!["alpha_x=0.05", "alpha_y=0.2"]),
    ] {
        let b = model(name, &params);
        let baked = BakedSampler::new(b, small()).unwrap();
        let bytes = baked.to_bytes();
        let back = BakedSampler::from_bytes(&bytes).unwrap();
        assert_eq!(back.to_bytes(), bytes);
        assert_eq!(back.nodes(), baked.nodes());
        let wi = dir(33.0, 71.0);
        for mode in [BakedMode::Rejection, BakedMode::Warp] {
            let (x, y) = (
                BakedSampler::from_bytes(&bytes).unwrap().with_mode(mode),
                BakedSampler::from_bytes(&bytes).unwrap().with_mode(mode),
            );
            let mut a = Pcg64::seed_from_u64(9);
            let mut c = Pcg64::seed_from_u64(9);
            for _ in 0..100 {
                let u = Vec2::new(0.3, 0.8);
                assert_eq!(
                    x.sample(wi, 0.5, u, &mut a).unwrap(),
                    y.sample(wi, 0.5, u, &mut c).unwrap()
                );
            }
        }
        let dir = std::env::temp_dir().join(format!("bake-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("m.bake");
        baked.save(&path).unwrap();
        let loaded = BakedSampler::load(&path).unwrap();
        assert_eq!(loaded.to_bytes(), bytes);
        // No temporary file is left beside it.
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        // A directory, a missing file: typed I/O errors.
        assert!(BakedSampler::load(&dir).is_err());
        assert!(BakedSampler::load(dir.join("missing")).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// Every kind of damage is its own typed error, and none panics.
#[test]
fn damaged_bake_files_are_typed_errors() {
    let b = model("phong", &["n=50"]);
    let bytes = BakedSampler::new(
        b,
        BakeConfig {
            theta_steps: 3,
            ..BakeConfig::default()
        },
    )
    .unwrap()
    .to_bytes();
    // Truncated anywhere.
    for cut in [
        0,
        3,
        8,
        11,
        12,
        19,
        20,
        21,
        bytes.len() / 2,
        bytes.len() - 5,
        bytes.len() - 1,
    ] {
        let e = BakedSampler::from_bytes(&bytes[..cut]).unwrap_err();
        assert!(
            matches!(
                e,
                BakeFileError::Truncated { .. } | BakeFileError::NotABakeFile
            ),
            "cut at {cut}: {e:?}"
        );
    }
    // Trailing bytes.
    let mut long = bytes.clone();
    long.push(0);
    assert!(matches!(
        BakedSampler::from_bytes(&long),
        Err(BakeFileError::TrailingBytes { .. })
    ));
    // Every single bit flipped past the magic and version: checksum, length or decode errors.
    let mut rng = Pcg64::seed_from_u64(5);
    for _ in 0..2000 {
        let mut x = bytes.clone();
        let at = 12 + (rng.next_u64() as usize) % (bytes.len() - 12);
        x[at] ^= 1 << (rng.next_u32() % 8);
        let e = BakedSampler::from_bytes(&x).unwrap_err();
        assert!(
            matches!(
                e,
                BakeFileError::Checksum { .. }
                    | BakeFileError::Truncated { .. }
                    | BakeFileError::TrailingBytes { .. }
                    | BakeFileError::TooLarge { .. }
            ),
            "flip at {at}: {e:?}"
        );
    }
    // Another version, a foreign file, random bytes.
    for other in [1u8, 2, 3, 4, 12] {
        let mut v = bytes.clone();
        v[8] = other;
        assert!(matches!(
            BakedSampler::from_bytes(&v),
            Err(BakeFileError::Version { found, .. }) if found == u32::from(other)
        ));
    }
    assert!(matches!(
        BakedSampler::from_bytes(b"\x89PNG\r\n\x1a\n0000000000000000000000"),
        Err(BakeFileError::NotABakeFile)
    ));
    for len in [0usize, 7, 100, 10_000] {
        let junk: Vec<u8> = (0..len).map(|_| rng.next_u32() as u8).collect();
        assert!(BakedSampler::from_bytes(&junk).is_err());
    }
    // A well-formed file (valid checksum) whose records do not match: an unknown model, and
    // garbage where the payload should be.
    // (Its length too: the header's word at bytes 12–20, header and checksum left out.)
    let reseal = |mut x: Vec<u8>| {
        let n = x.len();
        x[12..20].copy_from_slice(&(n as u64 - 24).to_le_bytes());
        let crc = crc32fast::hash(&x[..n - 4]);
        x[n - 4..].copy_from_slice(&crc.to_le_bytes());
        x
    };
    let at = bytes.windows(5).position(|w| w == b"phong").unwrap();
    let mut unknown = bytes.clone();
    unknown[at..at + 5].copy_from_slice(b"phang");
    assert!(matches!(
        BakedSampler::from_bytes(&reseal(unknown)),
        Err(BakeFileError::Model(_))
    ));
    // A resealed file whose parameter is 100 kB long and holds a terminal escape sequence:
    // the message quotes at most QUOTE_LIMIT characters of it, the escape escaped.
    let (at, old) = (0..bytes.len())
        .find_map(|i| {
            let len = usize::from(bytes[i]);
            let text = bytes.get(i + 1..i + 1 + len)?;
            (len > 0 && text.starts_with(b"n=")).then_some((i, len))
        })
        .expect("the parameter n= in the payload");
    // The file's own encoding of a string: its length (LEB128), then its bytes.
    let evil = postcard::to_allocvec(&["n=\u{1b}[31m", &"9".repeat(100_000)].concat()).unwrap();
    let long = [&bytes[..at], &evil, &bytes[at + 1 + old..]].concat();
    let e = BakedSampler::from_bytes(&reseal(long)).unwrap_err();
    assert!(matches!(e, BakeFileError::Model(_)), "{e:?}");
    let message = e.to_string();
    assert!(
        message.chars().count() < brdf_core::QUOTE_LIMIT + 120,
        "{} characters",
        message.chars().count()
    );
    assert!(!message.chars().any(char::is_control), "{message:?}");
    assert!(message.contains("\\u{1b}[31m999"), "{message}");
    let mut garbage = bytes.clone();
    let n = garbage.len();
    for b in &mut garbage[20..n - 4] {
        *b = 0xff;
    }
    assert!(matches!(
        BakedSampler::from_bytes(&reseal(garbage)),
        Err(BakeFileError::Decode | BakeFileError::Model(_) | BakeFileError::Config(_))
    ));
    // A resealed file with a tree's child link pointing outside the arena: a tree error.
    // (The record's last byte: the payload ends with the bake's max_bytes, a LEB128 varint.)
    let mut bad_tree = bytes.clone();
    // (An isotropic model's default limit.)
    let varint = (64 - (quadtree_sampler::DEFAULT_ISOTROPIC_BAKE_MAX_BYTES as u64).leading_zeros())
        .div_ceil(7);
    let last_payload = n - 5 - varint as usize;
    bad_tree[last_payload] ^= 0x40;
    let r = BakedSampler::from_bytes(&reseal(bad_tree));
    assert!(r.is_err(), "a changed tree byte was accepted");
    // A recorded max_bytes of 0 (a one-byte varint in place of the bake's): a config error.
    let zero = [&bytes[..n - 4 - varint as usize], &[0u8], &[0u8; 4][..]].concat();
    assert!(matches!(
        BakedSampler::from_bytes(&reseal(zero)),
        Err(BakeFileError::Config(_))
    ));
    // A header that declares more than a bake may hold is refused before anything is read
    // past it: from bytes, and from a file whose length word says 2⁴⁰ bytes.
    let mut huge = bytes.clone();
    huge[12..20].copy_from_slice(&(1u64 << 40).to_le_bytes());
    let limit = quadtree_sampler::MAX_BAKE_FILE_BYTES;
    assert_eq!(
        BakedSampler::from_bytes(&huge).unwrap_err(),
        BakeFileError::TooLarge {
            declared: (1 << 40) + 24,
            limit
        }
    );
    let dir = std::env::temp_dir().join(format!("bake-huge-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("huge.bake");
    std::fs::write(&path, &huge).unwrap();
    let e = BakedSampler::load(&path).unwrap_err();
    assert!(
        matches!(
            e,
            quadtree_sampler::BakeIoError::Format {
                source: BakeFileError::TooLarge { .. },
                ..
            }
        ),
        "{e}"
    );
    // An endless device is not read to its end (it is not a bake file).
    #[cfg(target_os = "linux")]
    assert!(matches!(
        BakedSampler::load("/dev/zero").unwrap_err(),
        quadtree_sampler::BakeIoError::Format {
            source: BakeFileError::NotABakeFile,
            ..
        }
    ));
    // A file exactly as written loads; with a byte more or less it does not.
    std::fs::write(&path, &bytes).unwrap();
    assert!(BakedSampler::load(&path).is_ok());
    std::fs::write(&path, [&bytes[..], &[0]].concat()).unwrap();
    assert!(BakedSampler::load(&path).is_err());
    // With many more, the error names the file's length, not the one byte past the
    // declared length that `load` reads to tell them apart.
    let n = bytes.len() as u64;
    std::fs::write(&path, [&bytes[..], &[0; 1000]].concat()).unwrap();
    assert!(
        matches!(
            BakedSampler::load(&path).unwrap_err(),
            quadtree_sampler::BakeIoError::Format {
                source: BakeFileError::TrailingBytes { expected, found },
                ..
            } if expected == n && found == n + 1000
        ),
        "a file 1000 bytes too long"
    );
    std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
    assert!(BakedSampler::load(&path).is_err());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Bad input to the baked sampler is a typed error.
#[test]
fn bad_input_is_a_typed_error() {
    let b = model("phong", &[]);
    let baked = BakedSampler::new(
        b,
        BakeConfig {
            theta_steps: 3,
            ..BakeConfig::default()
        },
    )
    .unwrap();
    let mut rng = Pcg64::seed_from_u64(1);
    for bad in [
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::ZERO,
        Vec3::new(f32::NAN, 0.0, 1.0),
        Vec3::new(1.0, 0.0, 0.0),
    ] {
        assert!(matches!(
            baked.sample(bad, 0.5, Vec2::splat(0.5), &mut rng),
            Err(BakedError::Direction(_))
        ));
        assert!(baked.pdf(bad, Vec3::Z).is_err());
        for role in [Role::Importance, Role::Radiance] {
            assert!(matches!(
                baked.point(role, bad),
                Err(BakedError::Direction(_))
            ));
        }
    }
    let point = baked
        .point(Role::Importance, Vec3::new(0.3, 0.1, 1.0))
        .unwrap();
    for bad in [
        Vec3::ZERO,
        Vec3::new(f32::NAN, 0.0, 1.0),
        Vec3::new(0.0, f32::INFINITY, 1.0),
    ] {
        assert!(matches!(point.pdf(bad), Err(BakedError::Direction(_))));
        assert!(matches!(
            point.pdf_continuous(bad),
            Err(BakedError::Direction(_))
        ));
        assert!(matches!(point.eval(bad), Err(BakedError::Direction(_))));
        assert!(point.eval_pdf(bad).is_err());
    }
    assert_eq!(point.pdf(Vec3::new(0.0, 0.0, -1.0)).unwrap(), 0.0);
    assert_eq!(point.eval(Vec3::new(0.0, 0.0, -1.0)).unwrap(), Vec3::ZERO);
    assert!(
        baked
            .pdf(Vec3::Z, Vec3::new(f32::INFINITY, 0.0, 1.0))
            .is_err()
    );
    assert_eq!(baked.pdf(Vec3::Z, Vec3::new(0.0, 0.0, -1.0)).unwrap(), 0.0);
    let mirror = model("mirror", &[]);
    assert!(matches!(
        BakedSampler::new(mirror, BakeConfig::default()),
        Err(BakeError::DeltaModel("mirror"))
    ));
    let phong = model("phong", &[]);
    for (t, p) in [(1, 9), (0, 9)] {
        let c = BakeConfig {
            theta_steps: t,
            phi_steps: p,
            ..BakeConfig::default()
        };
        assert!(matches!(
            BakedSampler::new(phong.clone(), c),
            Err(BakeError::ThetaSteps(_))
        ));
    }
    let ward = model("ward", &["alpha_x=0.05", "alpha_y=0.2"]);
    let c = BakeConfig {
        phi_steps: 1,
        ..BakeConfig::default()
    };
    assert!(matches!(
        BakedSampler::new(ward.clone(), c),
        Err(BakeError::PhiSteps { .. })
    ));
    let c = BakeConfig {
        theta_steps: u16::MAX,
        phi_steps: u16::MAX,
        ..BakeConfig::default()
    };
    assert!(matches!(
        BakedSampler::new(ward.clone(), c),
        Err(BakeError::TooManyTrees(_))
    ));
    for d in [0.0, 1.0, f64::NAN, -0.1] {
        let c = BakeConfig {
            defensive: d,
            ..BakeConfig::default()
        };
        assert!(matches!(
            BakedSampler::new(ward.clone(), c),
            Err(BakeError::Defensive(_))
        ));
    }
}

/// The coverage check (`BakedSampler::coverage`): it tells a grid too coarse for its lobe
/// from one that follows it, its R agrees with the weight's second moment measured through
/// the baked sampler's own samples, serial and parallel checks are identical, and a bad
/// sample count is a typed error.
#[test]
fn coverage_tells_a_coarse_grid_from_a_fine_one() {
    use quadtree_sampler::{COVERAGE_LIMIT, CoverageConfig, MAX_COVERAGE_SAMPLES};
    let config = CoverageConfig::default();
    // Poulin–Fournier's specular part alone, n = 1000, on 5 × 2 trees: its lobe changes
    // with φi far faster than two columns 90° apart follow, and from θi ≈ 55° on much of its
    // mass lies where no neighbour (carried by the half-vector transport) puts its own
    // (measured: R of 18, 1.2·10⁴ and 53 at the last three checked wi in rejection mode,
    // 1.0·10⁴ and 49 at the last two in warp mode; by rotations up to 3·10⁷).
    let coarse = |parallel: bool| {
        let mut c = BakeConfig {
            theta_steps: 5,
            phi_steps: 2,
            ..BakeConfig::default()
        };
        c.build.parallel = parallel;
        BakedSampler::new(
            model("poulin-fournier", &["n=1000", "kd=0", "gap=0", "ks=0.25"]),
            c,
        )
        .unwrap()
    };
    let serial = coarse(false);
    let cov = serial.coverage::<Pcg64>(config).unwrap();
    assert_eq!(
        cov.cells.len(),
        5,
        "four cells and the band beyond the last row"
    );
    for mode in [BakedMode::Rejection, BakedMode::Warp] {
        assert!(
            cov.above(mode, COVERAGE_LIMIT) >= 2,
            "{mode:?}: {:?}",
            cov.cells
        );
        assert!(
            cov.worst(mode).unwrap().in_mode(mode).unwrap() > 1e3,
            "{mode:?}: {:?}",
            cov.cells
        );
    }
    // At any one wi: the same measure (a checked cell's centre, and near the normal).
    let at = |theta: f64| {
        serial
            .coverage_at::<Pcg64>(Role::Importance, dir(theta, 45.0), config)
            .unwrap()
    };
    assert!(at(77.875).rejection.unwrap() > 1e3, "{:?}", at(77.875));
    assert!(at(11.125).rejection.unwrap() < 2.0, "{:?}", at(11.125));
    assert!(matches!(
        serial.coverage_at::<Pcg64>(Role::Importance, Vec3::new(0.0, 0.0, -1.0), config),
        Err(BakedError::Direction(_))
    ));
    // Serial and parallel: the same bits (each checked wi seeds its own generator).
    assert_eq!(coarse(true).coverage::<Pcg64>(config).unwrap(), cov);
    for samples in [0, MAX_COVERAGE_SAMPLES + 1] {
        let bad = CoverageConfig { samples, ..config };
        assert_eq!(
            serial.coverage::<Pcg64>(bad),
            Err(BakedError::CoverageSamples(samples))
        );
    }

    // Phong n = 1000 on 5 rows: a mirror lobe, rotated onto each query's mirror, is followed
    // by any grid (measured R ≤ 1.16 rejection, ≤ 1.35 warp). Independent check of each R:
    // the weight's second moment over its squared mean, from the baked sampler's own
    // samples at the same wi (E_p[w²]/E_p[w]² = ∫T²/p too, by another route).
    let phong = BakedSampler::new(
        model("phong", &["n=1000", "kd=0"]),
        BakeConfig {
            theta_steps: 5,
            ..BakeConfig::default()
        },
    )
    .unwrap();
    let cov = phong.coverage::<Pcg64>(config).unwrap();
    assert_eq!(cov.cells.len(), 5);
    assert_eq!(cov.unmeasured(), 0);
    let mut rng = Pcg64::seed_from_u64(31);
    for mode in [BakedMode::Rejection, BakedMode::Warp] {
        assert_eq!(
            cov.above(mode, COVERAGE_LIMIT),
            0,
            "{mode:?}: {:?}",
            cov.cells
        );
        let sampler = BakedSampler::new(
            model("phong", &["n=1000", "kd=0"]),
            BakeConfig {
                theta_steps: 5,
                ..BakeConfig::default()
            },
        )
        .unwrap()
        .with_mode(mode);
        for c in &cov.cells {
            let r = c.in_mode(mode).unwrap();
            assert!((0.97..1.5).contains(&r), "{mode:?}: {c:?}");
            let wi = dir(c.theta_deg, c.phi_deg);
            let (mut s1, mut s2, n) = (0.0, 0.0, 200_000);
            for _ in 0..n {
                let u = Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng));
                if let Some(s) = sampler
                    .sample(wi, uniform_f32(&mut rng), u, &mut rng)
                    .unwrap()
                {
                    let w = f64::from(luminance(s.f)) * f64::from(s.wo.z) / f64::from(s.pdf);
                    s1 += w;
                    s2 += w * w;
                }
            }
            let own = (s2 / f64::from(n)) / (s1 / f64::from(n)).powi(2);
            assert!(
                (r / own - 1.0).abs() < 0.03,
                "{mode:?} at θ {}: check {r}, own samples {own}",
                c.theta_deg
            );
        }
    }
}

/// An anisotropic grid's neighbours reach a query by the half-vector transport, which
/// carries a microfacet lobe onto the query's own however its shape turns with φi; the
/// rotations onto the query's mirror direction that bake files before version 8 use do not
/// (the negative control). Ward αx = 0.05, αy = 0.5 on 3 × 2 trees, R at every checked wi
/// (measured: 1.00–1.83 against 300–4·10⁷).
#[test]
fn the_half_vector_transport_follows_an_anisotropic_lobe() {
    use quadtree_sampler::CoverageConfig;
    let mut baked = BakedSampler::new(
        model("ward", &["alpha_x=0.05", "alpha_y=0.5", "kd=0"]),
        BakeConfig {
            theta_steps: 3,
            phi_steps: 2,
            ..BakeConfig::default()
        },
    )
    .unwrap();
    let config = CoverageConfig::default();
    let half = baked.coverage::<Pcg64>(config).unwrap();
    baked.rotate_neighbours_for_testing();
    let rotated = baked.coverage::<Pcg64>(config).unwrap();
    for mode in [BakedMode::Rejection, BakedMode::Warp] {
        for (h, r) in half.cells.iter().zip(&rotated.cells) {
            let (h, r) = (h.in_mode(mode).unwrap(), r.in_mode(mode).unwrap());
            assert!(h < 2.0 && r > 100.0, "{mode:?}: half {h}, rotated {r}");
        }
    }
}

/// A warp leaf on the orthographic disk's rim, or a disk sector, spreads its share in solid
/// angle where that fits f·cos θ better (file version 9, `rim`): Cook–Torrance m = 1 seen from grazing
/// incidence grows like 1/cos θo toward the horizon on the mirror side, which a proxy flat
/// over its square (or a disk sector's area) follows only in density per unit area, so its
/// weight's relative second moment R reached 10.6 at θi = 89° and 20 at 89.5° on the default
/// grid while rejection mode stayed at 1.00–1.02. On 8 rows, every checked direction now
/// stays under [`quadtree_sampler::COVERAGE_LIMIT`] in warp mode.
#[test]
fn rim_leaves_follow_a_lobe_that_grows_toward_the_horizon() {
    use quadtree_sampler::{COVERAGE_LIMIT, CoverageConfig};
    let baked = BakedSampler::new(
        model("cook-torrance", &["m=1", "kd=0.2"]),
        BakeConfig {
            theta_steps: 8,
            ..BakeConfig::default()
        },
    )
    .unwrap();
    let coverage = baked.coverage::<Pcg64>(CoverageConfig::default()).unwrap();
    for c in &coverage.cells {
        let warp = c.in_mode(BakedMode::Warp).unwrap();
        assert!(
            warp < COVERAGE_LIMIT,
            "θi {:.2}°: warp R {warp}",
            c.theta_deg
        );
    }
}

/// A bake over its memory limit (`BakeConfig::max_bytes`; by default 16 MiB for an
/// anisotropic model, 1 MiB for an isotropic one) holds at most that: some of its
/// trees are pruned (more trials), every other tree is kept bit for bit (same E[T]);
/// serial and parallel bakes are the same bytes; the file keeps the limit; and the pruned
/// sampler is still exact: each sample's pdf is `pdf()`, χ² against its own pdf at off-grid
/// wi in both modes (family-wise α = 0.01), and its mean weight is the albedo within 4
/// standard errors, while a pdf that drops a neighbour is rejected (the negative control on
/// a pruned bake). A limit of 0 or past 2 GiB, and one no tree fits in, are typed errors.
#[test]
fn a_bake_over_its_memory_limit_prunes_where_it_costs_fewest_trials() {
    let b = model("ward", &["alpha_x=0.3", "alpha_y=0.01", "kd=0"]);
    let free = BakedSampler::new(b.clone(), small()).unwrap();
    // The default limit is the model's: 16 MiB anisotropic, 1 MiB isotropic.
    assert_eq!(free.config().max_bytes, Some(16 << 20));
    let iso = BakedSampler::new(model("phong", &["n=200"]), small()).unwrap();
    assert_eq!(iso.config().max_bytes, Some(1 << 20));
    assert_eq!(iso.max_bytes(), 1 << 20);
    let limit = free.bytes() * 8 / 10;
    let config = BakeConfig {
        max_bytes: Some(limit),
        ..small()
    };
    let capped = BakedSampler::new(b.clone(), config).unwrap();
    println!(
        "free {} bytes, E[T] ≤ {:.3}; capped {} of {limit} bytes, E[T] ≤ {:.3}, {} trees pruned",
        free.bytes(),
        free.max_expected_trials(),
        capped.bytes(),
        capped.max_expected_trials(),
        capped.budget_stopped_trees()
    );
    assert!(capped.bytes() <= limit);
    assert_eq!(capped.trees(), free.trees());
    let (before, after) = (free.expected_trials(), capped.expected_trials());
    let kept = before.iter().zip(&after).filter(|(a, b)| a == b).count();
    let pruned = before.iter().zip(&after).filter(|(a, b)| b > a).count();
    assert_eq!(kept + pruned, before.len(), "{before:?} {after:?}");
    assert!(kept > 0 && pruned > 0, "kept {kept}, pruned {pruned}");
    assert_eq!(capped.budget_stopped_trees(), pruned);
    // Serial == parallel, and the file keeps the limit.
    let mut serial = config;
    serial.build.parallel = false;
    let bytes = capped.to_bytes();
    assert!(BakedSampler::new(b.clone(), serial).unwrap().to_bytes() == bytes);
    let back = BakedSampler::from_bytes(&bytes).unwrap();
    assert_eq!(back.config().max_bytes, Some(limit));
    assert_eq!(back.max_bytes(), limit);
    assert!(back.to_bytes() == bytes);
    // Exact still.
    let wis = [dir(52.3, 37.0), dir(80.0, 200.0)];
    let alpha = sidak(0.01, 2 * wis.len());
    let grid = CellGrid::Polar {
        rings: 16,
        sectors: 33,
    };
    let mut capped = capped;
    for (k, &wi) in wis.iter().enumerate() {
        let v = Validation::new(&*b, wi, grid, 1e-7).unwrap();
        let albedo = f64::from(luminance(directional_albedo(&*b, wi, 96, 6).as_vec3()));
        for (m, mode) in [BakedMode::Rejection, BakedMode::Warp]
            .into_iter()
            .enumerate()
        {
            capped.set_mode(mode);
            let at = capped.at(wi).unwrap();
            let seed = 40 + 2 * k as u64 + m as u64;
            let r = v.test_chunked(
                &at,
                500_000,
                |c| Pcg64::seed_from_u64(seed * 100 + c),
                alpha,
            );
            let c = r.chi2_own.as_ref().unwrap();
            println!(
                "{mode:?} wi {wi}: own χ² {:.1} dof {} p {:.4}",
                c.statistic, c.dof, c.p_value
            );
            assert!(
                r.passed_own(),
                "{mode:?} {wi}: {:?}",
                r.rejections(brdf_validate::Against::OwnPdf)
            );
            let (mean, se) = mean_weight(&at, 1_000_000, seed);
            assert!(
                (mean - albedo).abs() <= 4.0 * se,
                "{mode:?} {wi}: {mean} ± {se} vs {albedo}"
            );
            let mut rng = Pcg64::seed_from_u64(seed);
            for _ in 0..2000 {
                let (uc, u) = (
                    uniform_f32(&mut rng),
                    Vec2::new(uniform_f32(&mut rng), uniform_f32(&mut rng)),
                );
                if let Some(s) = capped.sample(wi, uc, u, &mut rng).unwrap() {
                    assert_eq!(s.pdf, capped.pdf(wi, s.wo).unwrap());
                }
            }
        }
    }
    assert_eq!(capped.bound_violations(), 0);
    // The same test can fail on a pruned bake: a pdf that drops a neighbour is rejected.
    capped.set_mode(BakedMode::Warp);
    let broken = Arc::new(capped).broken_pdf_for_testing();
    assert_broken_rejected(&*b, &broken, wis[0], 500_000, 4_400);
    // Limits out of range, and one no tree fits in.
    for bad in [0, quadtree_sampler::MAX_BAKE_BYTES + 1] {
        let c = BakeConfig {
            max_bytes: Some(bad),
            ..small()
        };
        assert!(matches!(BakedSampler::new(b.clone(), c), Err(BakeError::MaxBytes(x)) if x == bad));
    }
    let c = BakeConfig {
        max_bytes: Some(4096),
        ..small()
    };
    let e = BakedSampler::new(b.clone(), c).unwrap_err();
    assert!(matches!(e, BakeError::TooLarge { limit: 4096, .. }), "{e}");
}
