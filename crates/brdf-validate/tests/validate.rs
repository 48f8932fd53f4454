//! The validation harness (SPEC §5) on real samplers: it accepts the quadtree and the exact
//! baselines, and it rejects the negative controls — a harness that cannot fail is worthless.

use brdf_core::{Brdf, DiskMap, registry};
use brdf_validate::{Against, CellGrid, Reason, Report, Validation, Verdict, sidak};
use glam::{Vec2, Vec3};
use quadtree_sampler::{
    Baseline, BaselineSampler, BuildConfig, DEFAULT_TABLE_RES, DirectionSampler, QuadtreeSampler,
    Sample, TableSampler,
};
use rand_core::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// Tests in this file; the family-wise rate is α = 0.01 (SPEC §5) with Šidák's correction.
const TESTS: usize = 24;
const SAMPLES: u64 = 1_000_000;

fn dir(theta: f64, phi: f64) -> Vec3 {
    let (t, p) = (theta.to_radians(), phi.to_radians());
    Vec3::new(
        (t.sin() * p.cos()) as f32,
        (t.sin() * p.sin()) as f32,
        t.cos() as f32,
    )
}

fn model(name: &str, params: &[&str]) -> Box<dyn Brdf> {
    registry::create(name, params.iter().copied()).unwrap()
}

fn grids() -> [CellGrid; 2] {
    [
        CellGrid::Square { res: 25 },
        CellGrid::Polar {
            rings: 25,
            sectors: 51,
        },
    ]
}

fn run<S: DirectionSampler + ?Sized>(v: &Validation, s: &S, seed: u64) -> Report {
    let mut rng = Pcg64::seed_from_u64(seed);
    v.test(s, SAMPLES, &mut rng, sidak(0.01, TESTS))
}

/// The quadtree (both maps) passes on a sharp lobe and a grazing Ward, on both grids; so does
/// cosine sampling of a Lambertian surface (exactly ∝ f·cos).
#[test]
fn exact_samplers_pass() {
    let mut seed = 0;
    for (name, params, theta) in [
        ("phong", &["n=200", "kd=0.1"][..], 45.0),
        ("ward", &["alpha_x=0.05", "alpha_y=0.2"][..], 80.0),
    ] {
        let b = model(name, params);
        let wi = dir(theta, 30.0);
        for grid in grids() {
            let v = Validation::new(&*b, wi, grid, 1e-7).unwrap();
            for map in [DiskMap::Orthographic, DiskMap::Concentric] {
                let q = QuadtreeSampler::new(
                    &*b,
                    wi,
                    BuildConfig {
                        map,
                        ..BuildConfig::default()
                    },
                )
                .unwrap();
                seed += 1;
                let r = run(&v, &q, seed);
                let c = r.chi2.as_ref().unwrap();
                println!(
                    "{name} {theta}° {grid:?} {map:?}: χ² {:.1} dof {} p {:.3} spread {:?}",
                    c.statistic, c.dof, c.p_value, r.spread
                );
                assert!(r.passed(), "{name} {grid:?} {map:?}: {:?}", r.reasons);
                // The seed's statistic: a_i/a scatters around 1 by counting noise alone
                // (the RMS of 500–1300 roughly normal ratios lands within 10 % of it).
                let s = r.spread.unwrap();
                assert!(s.rms < 1.15 * s.noise, "{s:?}");
            }
        }
    }
    let b = model("lambert", &[]);
    let wi = dir(20.0, 0.0);
    let v = Validation::new(&*b, wi, grids()[1], 1e-7).unwrap();
    let cos = BaselineSampler::new(&*b, wi, Baseline::Cosine).unwrap();
    let r = run(&v, &cos, 99);
    assert!(r.passed(), "{:?}", r.reasons);
}

/// Negative control 1: cosine samples judged against Phong n = 200 (they follow cos, not
/// f·cos): rejected against f·cos, while the test against their own pdf passes.
#[test]
fn cosine_samples_are_not_phong() {
    let b = model("phong", &["n=200", "kd=0.1"]);
    let wi = dir(45.0, 30.0);
    let v = Validation::new(&*b, wi, grids()[1], 1e-7).unwrap();
    let cos = BaselineSampler::new(&*b, wi, Baseline::Cosine).unwrap();
    let r = run(&v, &cos, 1);
    assert!(!r.passed());
    let c = r.chi2.unwrap();
    assert!(c.p_value < 1e-100, "{c:?}");
    let own = r.chi2_own.unwrap();
    assert!(own.p_value > sidak(0.01, TESTS), "{own:?}");
}

/// Negative control 2: the quadtree with every bound halved (rejection then clips the peaks).
#[test]
fn an_underestimated_bound_is_rejected() {
    let b = model("phong", &["n=200", "kd=0.1"]);
    let wi = dir(45.0, 30.0);
    for grid in grids() {
        let v = Validation::new(&*b, wi, grid, 1e-7).unwrap();
        let mut q = QuadtreeSampler::new(&*b, wi, BuildConfig::default()).unwrap();
        q.scale_bounds_for_testing(0.5);
        let r = run(&v, &q, 2);
        assert!(!r.passed(), "{grid:?}: halved bounds passed");
        assert!(r.chi2.unwrap().p_value < 1e-10);
    }
}

/// A sampler whose density is 5 % low in one quadrant (x > 0, y > 0) while it reports the
/// quadtree's pdf: samples landing there are re-drawn with probability 5 %.
struct Skewed<'a>(QuadtreeSampler<&'a dyn Brdf>);

impl DirectionSampler for Skewed<'_> {
    fn name(&self) -> &'static str {
        "skewed"
    }

    fn sample_with(&self, uc: f32, u: Vec2, rng: &mut dyn Rng) -> Option<Sample> {
        let mut s = self.0.sample_with(uc, u, rng)?;
        loop {
            let u = (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
            if !(s.wo.x > 0.0 && s.wo.y > 0.0 && u < 0.05) {
                return Some(s);
            }
            s = self.0.sample(rng)?;
        }
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        self.0.pdf(wo)
    }
}

/// Negative control 3: a pdf off by 5 % in one quadrant is rejected on both grids.
#[test]
fn a_five_percent_error_in_one_quadrant_is_rejected() {
    let b = model("ward", &[]);
    let wi = dir(30.0, 200.0);
    for grid in grids() {
        let v = Validation::new(&*b, wi, grid, 1e-7).unwrap();
        let q = QuadtreeSampler::new(&*b, wi, BuildConfig::default()).unwrap();
        let r = run(&v, &Skewed(q), 3);
        assert!(!r.passed(), "{grid:?}: a 5 % skew passed");
        let c = r.chi2.unwrap();
        println!(
            "skewed {grid:?}: χ² {:.0} dof {} p {:.2e}",
            c.statistic, c.dof, c.p_value
        );
        assert!(c.p_value < sidak(0.01, TESTS));
    }
}

/// A sampler that never draws anything, whatever pdf it claims.
struct Nothing<'a>(QuadtreeSampler<&'a dyn Brdf>);

impl DirectionSampler for Nothing<'_> {
    fn name(&self) -> &'static str {
        "nothing"
    }

    fn sample_with(&self, _uc: f32, _u: Vec2, _rng: &mut dyn Rng) -> Option<Sample> {
        None
    }

    fn pdf(&self, wo: Vec3) -> f32 {
        self.0.pdf(wo)
    }
}

/// The three verdicts: a correct sampler passes; too few samples for any χ² is
/// inconclusive (not a rejection); a sampler that loses every sample is rejected, against
/// its own pdf too, however few samples were drawn (a rejection outranks inconclusive).
#[test]
fn verdicts_tell_rejected_from_inconclusive() {
    let b = model("lambert", &[]);
    let wi = dir(20.0, 0.0);
    let v = Validation::new(&*b, wi, grids()[0], 1e-7).unwrap();
    let q = || QuadtreeSampler::new(&*b, wi, BuildConfig::default()).unwrap();
    let r = run(&v, &q(), 4);
    assert_eq!(
        (r.verdict(), r.verdict_own()),
        (Verdict::Passed, Verdict::Passed)
    );
    let mut rng = Pcg64::seed_from_u64(5);
    let few = v.test(&q(), 1, &mut rng, 0.01);
    assert_eq!(few.verdict(), Verdict::Inconclusive, "{:?}", few.reasons);
    assert_eq!(few.verdict_own(), Verdict::Inconclusive);
    assert!(
        !few.passed()
            && few.rejections(Against::FCos).is_empty()
            && !few.unjudged(Against::FCos).is_empty()
    );
    for samples in [1, SAMPLES] {
        let mut rng = Pcg64::seed_from_u64(6);
        let lost = v.test(&Nothing(q()), samples, &mut rng, 0.01);
        assert_eq!(lost.verdict(), Verdict::Rejected, "{samples}");
        assert_eq!(lost.verdict_own(), Verdict::Rejected, "{samples}");
        assert!(
            lost.rejections(Against::OwnPdf)
                .iter()
                .any(|r| matches!(r, Reason::AllLost { .. }))
        );
    }
}

/// Bad set-ups are typed errors.
#[test]
fn bad_inputs_are_errors() {
    let b = model("phong", &[]);
    assert!(Validation::new(&*b, Vec3::new(0.0, 0.0, -1.0), grids()[0], 1e-7).is_err());
    assert!(Validation::new(&*b, Vec3::Z, CellGrid::Square { res: 0 }, 1e-7).is_err());
    assert!(Validation::new(&*b, Vec3::Z, grids()[0], 0.0).is_err());
    let mirror = model("mirror", &[]);
    assert!(Validation::new(&*mirror, Vec3::Z, grids()[0], 1e-7).is_err());
}

/// The chunked test is bit-identical on 1 and 4 threads, and with a single chunk it is the
/// serial test.
#[test]
fn chunked_test_does_not_depend_on_the_thread_count() {
    let b = model("ward", &["alpha_x=0.1", "alpha_y=0.3"]);
    let wi = dir(60.0, 20.0);
    let v = Validation::new(&*b, wi, grids()[1], 1e-7).unwrap();
    let q = QuadtreeSampler::new(&*b, wi, BuildConfig::default()).unwrap();
    let seeded = |k: u64| Pcg64::seed_from_u64(1000 + k);
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| v.test_chunked(&q, 300_000, seeded, 0.01))
    };
    let (one, four) = (on(1), on(4));
    assert_eq!(one.histogram.observed, four.histogram.observed);
    assert_eq!(one.histogram.observed.iter().sum::<u64>(), 300_000);
    let bits = |r: &Report| {
        let c = r.chi2.as_ref().unwrap();
        (
            c.statistic.to_bits(),
            c.p_value.to_bits(),
            r.reasons.clone(),
        )
    };
    assert_eq!(bits(&one), bits(&four));
    let chunked = v.test_chunked(&q, 50_000, seeded, 0.01);
    let serial = v.test(&q, 50_000, &mut seeded(0), 0.01);
    assert_eq!(chunked.histogram.observed, serial.histogram.observed);
    assert_eq!(bits(&chunked), bits(&serial));
}

/// The 256² table baseline is exact for its own pdf (it is only roughly ∝ f·cos), on a sharp
/// Phong lobe and a grazing anisotropic Ward. The seed's square grid at 11² keeps the
/// own-pdf integration cheap: the table's pdf jumps at every one of its cell edges.
#[test]
fn table_baseline_is_exact_for_its_own_pdf() {
    let mut seed = 100;
    for (name, params, theta) in [
        ("phong", &["n=1000", "kd=0.05", "ks=0.9"][..], 45.0),
        ("ward", &["alpha_x=0.05", "alpha_y=0.2"][..], 80.0),
    ] {
        let b = model(name, params);
        let wi = dir(theta, 30.0);
        let v = Validation::new(&*b, wi, CellGrid::Square { res: 11 }, 1e-7).unwrap();
        let t = TableSampler::new(&*b, wi, DEFAULT_TABLE_RES).unwrap();
        seed += 1;
        let r = run(&v, &t, seed);
        println!("{name} table: {:?} own {:?}", r.chi2, r.chi2_own);
        assert!(
            r.passed_own(),
            "{name}: {:?}",
            r.rejections(Against::OwnPdf)
        );
        assert_eq!((r.lost, r.outside, r.inconsistent), (0, 0, 0));
    }
    // Bad input is an error, not a panic.
    let b = model("phong", &[]);
    assert!(TableSampler::new(&*b, Vec3::new(0.0, 0.0, 1.0), 0).is_err());
    assert!(TableSampler::new(&*b, Vec3::new(0.0, 0.0, -1.0), 16).is_err());
    assert!(TableSampler::new(&*b, Vec3::new(f32::NAN, 0.0, 1.0), 16).is_err());
    let mirror = model("mirror", &[]);
    assert!(TableSampler::new(&*mirror, Vec3::new(0.0, 0.0, 1.0), 16).is_err());
}

/// The expected masses find a lobe narrower than a cell's node spacing: sharp lobes at
/// grazing incidence, squeezed against the rim into a sliver of one sector. Three grids with
/// different cells and coordinates must agree on the total. Before each cell's ranges were
/// cut at the model's peak hints, the polar 25 × 51 grid lost most of such a lobe (Ward
/// α = 0.01 at 89°: 0.00314 of 0.00953), and a correct sampler would have been rejected.
#[test]
fn cell_masses_find_a_lobe_between_the_nodes() {
    for (name, params, theta, phi) in [
        (
            "ward",
            &["alpha_x=0.01", "alpha_y=0.01", "kd=0"][..],
            89.0,
            30.0,
        ),
        (
            "ward",
            &["alpha_x=0.01", "alpha_y=0.01", "kd=0"][..],
            80.0,
            30.0,
        ),
        ("cook-torrance", &["m=0.02", "kd=0"][..], 89.0, 30.0),
        ("blinn-phong", &["n=10000", "kd=0"][..], 89.0, 30.0),
        // Needles along a tangent axis, which no hint's φ or height finds (see
        // `needle_lobes_pass_on_both_grids`).
        ("ward", NEEDLE_AT_THE_POLE, 0.0, 0.0),
        ("ward", NEEDLE_ACROSS_THE_RINGS, 89.0, 107.9),
        ("ward", NEEDLE_ACROSS_A_SECTOR, 45.0, 300.6),
    ] {
        let b = model(name, params);
        let wi = dir(theta, phi);
        let totals: Vec<f64> = [
            CellGrid::Polar {
                rings: 25,
                sectors: 51,
            },
            CellGrid::Polar {
                rings: 100,
                sectors: 201,
            },
            CellGrid::Square { res: 25 },
        ]
        .into_iter()
        .map(|g| {
            Validation::new(&*b, wi, g, 1e-7)
                .unwrap()
                .mass()
                .iter()
                .sum()
        })
        .collect();
        for t in &totals[1..] {
            assert!(
                (t - totals[0]).abs() <= 1e-5 * totals[0],
                "{name} {theta}°: totals {totals:?}"
            );
        }
    }
}

/// Ward, αy = 0.001 (a needle along x) at normal incidence: its lobe is a disk of radius
/// about 0.001 at the pole, which the polar cells' old coordinate v = √z squeezed to 10⁻⁶.
const NEEDLE_AT_THE_POLE: &[&str] = &["alpha_x=1", "alpha_y=0.001", "ks=0.3,1,0.8", "kd=0"];
/// Ward, αx = 0.0011: the lobe runs along the line wo.x = −wi.x, crossing every ring.
const NEEDLE_ACROSS_THE_RINGS: &[&str] = &["alpha_x=0.0011", "alpha_y=1", "kd=0"];
/// Ward, αy = 0.001 at 45°: the line wo.y = −wi.y, again inside sectors, with a diffuse part.
const NEEDLE_ACROSS_A_SECTOR: &[&str] = &["alpha_x=0.86", "alpha_y=0.001", "kd=0.5"];

/// Lobes narrow along one tangent axis pass on both grids. Each is far narrower than the
/// nodes of a polar cell's integration, and none peaks where a hint's φ or height cuts the
/// ranges: Ward's lobe lies along the line where the half vector's x (or y) slope is 0,
/// wo.x = −wi.x. Before polar cells cut their φ range where each circle crosses the hints'
/// lines x = h.x and y = h.y, and integrated away from the rim in w = √(1 − z), the polar
/// grid missed up to half of such a lobe's mass in a cell (χ² 26 725 on 88 dof, 6 478 on
/// 72 and 2 013 on 1 274 for these three), and the exact quadtree was rejected; the square
/// grid, whose charts are cut at the hints' x and y, passed. (At 89° the second needle is
/// 10⁻⁵ wide at the rim, which only the pieces graded toward a break resolve; its quadtree
/// takes 6 s to build, so `cell_masses_find_a_lobe_between_the_nodes` checks it there.)
#[test]
fn needle_lobes_pass_on_both_grids() {
    for (params, theta, phi, seed) in [
        (NEEDLE_AT_THE_POLE, 0.0, 0.0, 40),
        (NEEDLE_ACROSS_THE_RINGS, 60.0, 107.9, 41),
        (NEEDLE_ACROSS_A_SECTOR, 45.0, 300.6, 42),
    ] {
        let b = model("ward", params);
        let wi = dir(theta, phi);
        let q = QuadtreeSampler::new(&*b, wi, BuildConfig::default()).unwrap();
        for grid in grids() {
            let v = Validation::new(&*b, wi, grid, 1e-7).unwrap();
            let r = run(&v, &q, seed);
            let c = r.chi2.as_ref().unwrap();
            println!(
                "{params:?} {theta}° {grid:?}: χ² {:.1} dof {} p {:.3}",
                c.statistic, c.dof, c.p_value
            );
            assert!(r.passed(), "{params:?} {theta}° {grid:?}: {:?}", r.reasons);
        }
    }
}

/// The mean weight is judged against the albedo the cell masses give (adaptive, cut at the
/// model's peaks). A fixed 96-panel quadrature gave it before: 6.43·10⁻⁴ for the specular
/// part of this Blinn–Phong (n = 39 794 at 89°: a needle at the rim), where three grids and
/// the quadtree's volume give 1.319·10⁻⁴, and the exact quadtree was rejected (p = 2·10⁻²⁴).
#[test]
fn the_mean_weight_of_a_needle_at_the_rim_is_its_albedo() {
    let b = model("blinn-phong", &["ks=0.04618,0.5049,0", "n=39794"]);
    let wi = Vec3::new(-0.789_315, -0.613_74, 0.017_452).normalize();
    let settings = brdf_validate::Settings {
        grids: vec![CellGrid::Square { res: 25 }],
        samples: 200_000,
        mean_weight: true,
        seed: 5,
        ..brdf_validate::Settings::default()
    };
    let r = brdf_validate::suite(
        &*b,
        &[wi],
        &settings,
        |_, wi| {
            QuadtreeSampler::new(&*b, wi, BuildConfig::default())
                .map_err(Box::<dyn std::error::Error>::from)
        },
        |_| Ok(()),
    )
    .unwrap();
    let w = &r.weight_tests[0];
    println!("{w:?}");
    assert!((w.albedo - 0.500_132).abs() < 2e-6, "{w:?}");
    assert!(w.passed, "{w:?}");
}

/// A baked sampler's pdf carries each neighbour tree's lobe rotated onto wi, and a needle
/// narrow along its tree's x axis then lies along a rotated plane that the model's hints at
/// wi do not name: the sampler names it ([`DirectionSampler::density_hints`]) and its own
/// cell probabilities are cut there. Ward αx = 0.001 baked on 2 × 2 trees (θ 0° and 89°,
/// φ 0° and 90°), off the grid at 47° and 67°: without those planes the polar grid's own
/// probabilities missed a quarter of the needle's cell (χ² 37 228 and 66 863 on 1 275 dof,
/// each test taking a minute), and the sampler was rejected; a brute-force Monte Carlo of
/// its pdf over that cell (4·10⁶ points) agreed with its samples.
#[test]
fn a_baked_needle_rotated_off_its_axes_passes() {
    let b: std::sync::Arc<dyn Brdf> = std::sync::Arc::from(model("ward", &["alpha_x=0.001"]));
    let config = quadtree_sampler::BakeConfig {
        theta_steps: 2,
        phi_steps: 2,
        ..quadtree_sampler::BakeConfig::default()
    };
    let baked =
        std::sync::Arc::new(quadtree_sampler::BakedSampler::new(b.clone(), config).unwrap());
    for (wi, seed) in [
        (Vec3::new(0.393_217, -0.619_28, 0.68), 50),
        (Vec3::new(0.7, -0.6, 0.387), 51),
    ] {
        let wi = wi.normalize();
        let s = quadtree_sampler::AnySampler::<std::sync::Arc<dyn Brdf>>::baked(baked.clone(), wi)
            .unwrap();
        assert!(!s.density_hints().ridges.is_empty());
        let grid = CellGrid::Polar {
            rings: 25,
            sectors: 51,
        };
        let v = Validation::new(&*b, wi, grid, 1e-7).unwrap();
        let mut rng = Pcg64::seed_from_u64(seed);
        let r = v.test(&s, 200_000, &mut rng, sidak(0.01, 2));
        let c = r.chi2_own.as_ref().unwrap();
        println!(
            "{wi}: own χ² {:.1} dof {} p {:.3}",
            c.statistic, c.dof, c.p_value
        );
        assert!(
            !r.reasons.iter().any(|x| matches!(
                x,
                Reason::ChiSquare {
                    against: Against::OwnPdf,
                    ..
                } | Reason::PdfAboveOne { .. }
            )),
            "{wi}: {:?}",
            r.reasons
        );
    }
}

/// A model that is 0 everywhere at wi (Lambert with albedo 0) leaves nothing to compare the
/// samples with against f·cos: that test is unjudged (inconclusive), and the sampler is
/// judged on its own pdf alone. The all-zero masses used to reject both, as if they were
/// broken (NaN or negative).
#[test]
fn a_model_that_is_zero_at_wi_is_unjudged_against_f_cos() {
    let b = model("lambert", &["albedo=0"]);
    let wi = dir(60.0, 271.3);
    let s = BaselineSampler::new(&*b, wi, Baseline::Cosine).unwrap();
    let v = Validation::new(&*b, wi, CellGrid::Square { res: 25 }, 1e-7).unwrap();
    let r = run(&v, &s, 60);
    assert_eq!(r.verdict_own(), Verdict::Passed, "{:?}", r.reasons);
    assert_eq!(r.verdict(), Verdict::Inconclusive, "{:?}", r.reasons);
}

/// `check_with` takes ridge planes for a BSDF outside the workspace whose needle runs along
/// an axis that is not the frame's: Ward αx = 0.001 with its tangent turned 30° about the
/// normal, sampled exactly by Ward's own sampler in the turned frame. Given the mirror
/// direction alone, the masses and the sampler's own cell probabilities miss part of the
/// needle, and the sampler is rejected; given the needle's plane as well, it passes.
#[test]
fn a_needle_along_a_turned_axis_passes_when_its_plane_is_named() {
    use brdf_validate::{DensityHints, FnSampler, Ridge, Settings, check, check_with};
    let b = model("ward", &["alpha_x=0.001", "kd=0"]);
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    // Model frame → local frame: a turn by 30° about the normal.
    let turn = glam::DMat3::from_cols(
        glam::DVec3::new(c, s, 0.0),
        glam::DVec3::new(-s, c, 0.0),
        glam::DVec3::Z,
    );
    let to_local = |w: Vec3| (turn * w.as_dvec3()).as_vec3();
    let to_model = |w: Vec3| (turn.transpose() * w.as_dvec3()).as_vec3();
    let wi = dir(60.0, 20.0);
    let wi_m = to_model(wi);
    let sampler = FnSampler::new(
        "turned ward",
        |uc, u| {
            let x = b.sample_continuous(wi_m, uc, u)?;
            Some((to_local(x.wo), x.pdf))
        },
        |wo| b.pdf_continuous(wi_m, to_model(wo)),
    );
    let fcos = |wo: Vec3| {
        f64::from(brdf_core::geometry::luminance(b.eval(wi_m, to_model(wo)))) * f64::from(wo.z)
    };
    let settings = Settings {
        samples: 200_000,
        against: Against::OwnPdf,
        mean_weight: true,
        seed: 7,
        ..Settings::default()
    };
    let mirror = Vec3::new(-wi.x, -wi.y, wi.z);
    let without = check(&sampler, fcos, &[mirror], &settings).unwrap();
    println!("{without}");
    let hints = DensityHints {
        peaks: vec![mirror.as_dvec3()],
        // The needle: wo.x = −wi.x in the model frame.
        ridges: vec![Ridge {
            normal: turn * glam::DVec3::X,
            offset: -f64::from(wi_m.x),
        }],
        step: None,
    };
    let with = check_with(&sampler, fcos, &hints, &settings).unwrap();
    println!("{with}");
    assert!(!without.passed(), "{without}");
    assert!(with.passed(), "{with}");
}

/// The cell masses' tolerance is relative to the f·cos's own scale: the same function times
/// 10¹⁰ or 10¹⁰⁰ costs about the same number of evaluations and gives the same masses times
/// that.
/// (The coarse total that sets the scale was integrated to 10⁻³ absolute: at 10¹⁰⁰ every
/// piece refined to its limit, 24 s for a constant; an f·cos of 10³⁰⁰ made `check` take
/// 352 s, 149 s of them in the sampler's own cell probabilities, held to a tolerance of 0
/// once the masses' total overflowed.) A constant, which jumps to 0 at the rim, is the
/// hardest case.
#[test]
fn the_masses_tolerance_follows_the_scale_of_f() {
    use std::sync::atomic::{AtomicU64, Ordering};
    let run = |scale: f64| {
        let calls = AtomicU64::new(0);
        let f = |_: Vec3| {
            calls.fetch_add(1, Ordering::Relaxed);
            scale
        };
        let v = Validation::of_fcos(f, &[], CellGrid::Square { res: 25 }, 1e-7).unwrap();
        (calls.into_inner(), v.mass().to_vec())
    };
    // An oracle whose masses overflow (an infinite total) still bounds the work of the
    // sampler's own cell probabilities: a cosine pdf over them costs what it does under a
    // finite oracle.
    let own = |scale: f64| {
        let v = Validation::of_fcos(|_| scale, &[], CellGrid::Square { res: 25 }, 1e-7).unwrap();
        let calls = AtomicU64::new(0);
        let p = v.own_probability(&|w: Vec3| {
            calls.fetch_add(1, Ordering::Relaxed);
            f64::from(w.z.max(0.0)) / std::f64::consts::PI
        });
        (calls.into_inner(), p.iter().sum::<f64>())
    };
    let (base, sum) = own(1.0);
    let (huge, huge_sum) = own(1e300);
    assert!(huge <= 2 * base, "{huge} evaluations against {base}");
    assert!(
        (sum - 1.0).abs() < 1e-5 && (huge_sum - 1.0).abs() < 1e-5,
        "{sum} {huge_sum}"
    );
    let (calls, mass) = run(1.0);
    for scale in [1e10, 1e100] {
        let (c, m) = run(scale);
        assert!(
            c <= 2 * calls,
            "scale {scale:e}: {c} evaluations against {calls}"
        );
        for (a, b) in mass.iter().zip(&m) {
            assert!(
                (b / scale - a).abs() <= 1e-6 * a.abs().max(1e-12),
                "{scale:e}: {a} {b}"
            );
        }
    }
}

/// A lobe narrower than the coarse grid's nodes, with no peak to cut at, still sets the
/// masses' tolerance: a needle of 10¹² within 0.08° of the normal costs about what a broad
/// cap does and is found whole. (The coarse total that scales the tolerance missed it: 0,
/// so every cell that saw the needle was refined to every piece's limit, about 10⁹
/// evaluations on the polar grid, and `check` had not finished after 380 s.)
#[test]
fn a_needle_the_coarse_total_misses_keeps_a_usable_tolerance() {
    use std::sync::atomic::{AtomicU64, Ordering};
    let run = |r2: f32, grid: CellGrid| {
        let calls = AtomicU64::new(0);
        let cap = |w: Vec3| {
            calls.fetch_add(1, Ordering::Relaxed);
            if w.x * w.x + w.y * w.y < r2 {
                1e12
            } else {
                0.0
            }
        };
        let v = Validation::of_fcos(cap, &[], grid, 1e-7).unwrap();
        // ∫ fcos dω = ∫ fcos/z dA over the cap: 2π(1 − √(1 − r²)) × 10¹².
        let exact = 2.0 * std::f64::consts::PI * (1.0 - (1.0 - f64::from(r2)).sqrt()) * 1e12;
        (calls.into_inner(), v.mass().iter().sum::<f64>() / exact)
    };
    for grid in [
        CellGrid::Square { res: 25 },
        CellGrid::Polar {
            rings: 25,
            sectors: 51,
        },
    ] {
        let (broad, _) = run(1e-2, grid);
        let (calls, ratio) = run(2e-6, grid);
        assert!(
            calls <= 5 * broad,
            "{grid:?}: {calls} evaluations against {broad} for a broad cap"
        );
        assert!((ratio - 1.0).abs() < 2e-3, "{grid:?}: {ratio}");
    }
}

/// A sampler whose reported density is many times too large (3·10³⁸ everywhere: its cells'
/// probabilities sum to 10³⁸) costs what a cosine density does to integrate, and is
/// rejected. (Its cells were refined to every piece's limit against a tolerance meant for a
/// total of 1: `check` took 424 s.)
#[test]
fn an_absurd_reported_density_is_integrated_at_its_own_scale() {
    use std::sync::atomic::{AtomicU64, Ordering};
    let v = Validation::of_fcos(
        |w: Vec3| f64::from(w.z.max(0.0)) / std::f64::consts::PI,
        &[],
        CellGrid::Square { res: 25 },
        1e-7,
    )
    .unwrap();
    let own = |scale: f64| {
        let calls = AtomicU64::new(0);
        let p = v.own_probability(&|w: Vec3| {
            calls.fetch_add(1, Ordering::Relaxed);
            scale * f64::from(w.z.max(0.0)) / std::f64::consts::PI
        });
        (calls.into_inner(), p.iter().sum::<f64>())
    };
    let (base, sum) = own(1.0);
    let (huge, huge_sum) = own(3e38);
    assert!(huge <= 2 * base, "{huge} evaluations against {base}");
    // (Each cell to its own tolerance: 625 of them sum to within 10⁻⁵.)
    assert!((sum - 1.0).abs() < 1e-5, "{sum}");
    assert!((huge_sum / 3e38 - 1.0).abs() < 1e-5, "{huge_sum}");
}

/// An oracle that is NaN over part of the disk (a broken BSDF) costs what a finite one
/// does to integrate: its finite cells set the tolerance. The cells it touches are NaN, the
/// others are integrated as from the finite oracle, and `check` rejects it for masses that
/// are not a distribution. (Its NaN coarse total made the tolerance 10⁻³⁰⁷ absolute and
/// refined every finite cell to every piece's limit: 5.6–13 s a `check`.)
#[test]
fn an_oracle_nan_on_part_of_the_disk_is_integrated_at_its_finite_scale() {
    use std::sync::atomic::{AtomicU64, Ordering};
    let cosine = |w: Vec3| 0.8 * f64::from(w.z.max(0.0)) / std::f64::consts::PI;
    let run = |spot: bool| {
        let calls = AtomicU64::new(0);
        let f = |w: Vec3| {
            calls.fetch_add(1, Ordering::Relaxed);
            if spot && w.x > 0.5 {
                f64::NAN
            } else {
                cosine(w)
            }
        };
        let v = Validation::of_fcos(f, &[], CellGrid::Square { res: 25 }, 1e-7).unwrap();
        (calls.into_inner(), v.mass().to_vec())
    };
    let (base, good) = run(false);
    let (calls, spotted) = run(true);
    assert!(calls <= 2 * base, "{calls} evaluations against {base}");
    let nan = spotted.iter().filter(|m| m.is_nan()).count();
    assert!(nan > 0 && nan < spotted.len(), "{nan} NaN cells");
    // A finite cell of the spotted oracle lies wholly at x ≤ 0.5, where the two agree,
    // each to its tolerance (10⁻⁷ of a total of 0.8, or of the finite cells' 0.6).
    for (i, (a, b)) in good.iter().zip(&spotted).enumerate() {
        if b.is_finite() {
            assert!((a - b).abs() <= 2e-7, "cell {i}: {a} against {b}");
        }
    }
    let sampler = brdf_validate::FnSampler::new(
        "cosine",
        |_, u| {
            let w = brdf_core::warp::sample_cosine_hemisphere(u);
            Some((w, brdf_core::warp::cosine_hemisphere_pdf(w.z)))
        },
        |w: Vec3| brdf_core::warp::cosine_hemisphere_pdf(w.z),
    );
    let settings = brdf_validate::Settings {
        samples: 20_000,
        ..brdf_validate::Settings::default()
    };
    let report = brdf_validate::check(
        &sampler,
        |w: Vec3| if w.x > 0.5 { f64::NAN } else { cosine(w) },
        &[],
        &settings,
    )
    .unwrap();
    assert_eq!(report.verdict(), Verdict::Rejected, "{report}");
}

/// The area of the unit disk within [x0, x1] × [y0, y1], in closed form: the height of the
/// column at x, min(y1, h) − max(y0, −h) with h = √(1 − x²) (0 where negative), is one
/// expression between the x where h meets |y0| or |y1|, each integrated exactly
/// (∫ h dx = (x·h + asin x)/2).
fn disk_area_in(x0: f64, x1: f64, y0: f64, y1: f64) -> f64 {
    let h = |x: f64| (1.0 - x * x).max(0.0).sqrt();
    let hint = |x: f64| 0.5 * (x * h(x) + x.clamp(-1.0, 1.0).asin());
    let mut cuts = vec![x0.max(-1.0), x1.min(1.0)];
    for y in [y0, y1] {
        if y.abs() < 1.0 {
            let x = (1.0 - y * y).sqrt();
            cuts.extend([x, -x]);
        }
    }
    let (lo, hi) = (cuts[0], cuts[1]);
    let mut cuts: Vec<f64> = cuts.into_iter().filter(|&x| x >= lo && x <= hi).collect();
    cuts.sort_by(f64::total_cmp);
    cuts.windows(2)
        .map(|w| {
            let (p, q) = (w[0], w[1]);
            let mid = 0.5 * (p + q);
            let hm = h(mid);
            if y1.min(hm) - y0.max(-hm) <= 0.0 {
                return 0.0;
            }
            // Each bound is a row (a constant) or the rim (±h) over the whole piece.
            let top = if y1 < hm {
                y1 * (q - p)
            } else {
                hint(q) - hint(p)
            };
            let bottom = if y0 > -hm {
                y0 * (q - p)
            } else {
                -(hint(q) - hint(p))
            };
            top - bottom
        })
        .sum()
}

/// Every cell of the square grid, rim cells included, holds a constant per-area density's
/// mass to its tolerance: the exact area of the cell within the disk, in closed form. Where
/// a cell's row meets the rim the column's height has a kink, which the rule's error
/// estimate missed: a rim cell came out 0.65 % high, 4.4 times its tolerance, and the 625
/// cells summed to 1.7·10⁻⁶ over the total at a tolerance of 10⁻⁷.
#[test]
fn square_rim_cells_hold_their_exact_area() {
    let k = 1.0 / std::f64::consts::PI;
    for res in [25usize, 7] {
        let v = Validation::of_fcos(
            |w: Vec3| k * f64::from(w.z.max(0.0)),
            &[],
            CellGrid::Square { res },
            1e-7,
        )
        .unwrap();
        let side = 2.0 / res as f64;
        let mut worst = 0.0f64;
        for (i, &mass) in v.mass().iter().enumerate() {
            let (ix, iy) = ((i % res) as f64, (i / res) as f64);
            let (x0, y0) = (-1.0 + side * ix, -1.0 + side * iy);
            let exact = k * disk_area_in(x0, x0 + side, y0, y0 + side);
            worst = worst.max((mass - exact).abs());
        }
        // The total is 1: each cell within 10⁻⁷ of it.
        assert!(worst <= 1e-7, "{res}×{res}: a cell {worst:e} off");
        let sum: f64 = v.mass().iter().sum();
        assert!((sum - 1.0).abs() <= 1e-7, "{res}×{res}: total {sum}");
    }
}

/// The polar grid's cells are of equal area (π over their number): a constant per-area
/// density gives every one, at the pole and at the rim, the same mass to its tolerance.
#[test]
fn polar_cells_of_a_constant_hold_equal_masses() {
    let k = 1.0 / std::f64::consts::PI;
    for (rings, sectors) in [(25usize, 51usize), (7, 15)] {
        let v = Validation::of_fcos(
            |w: Vec3| k * f64::from(w.z.max(0.0)),
            &[],
            CellGrid::Polar { rings, sectors },
            1e-7,
        )
        .unwrap();
        let exact = 1.0 / (rings * sectors) as f64;
        let worst = v
            .mass()
            .iter()
            .map(|m| (m - exact).abs())
            .fold(0.0f64, f64::max);
        assert!(worst <= 1e-7, "{rings}×{sectors}: a cell {worst:e} off");
    }
}

/// A tolerance below the rounding of an f32 f·cos costs about what the default does and
/// changes the masses by no more than that rounding: pieces whose error estimate is within
/// it are not halved. (Each cell's nested integration halved them to every piece's limit,
/// chasing rounding: `brdf test --tol 1e-10` on htsg had not finished after 600 s, `--tol
/// 1e-9 --cells 2` took 144 s against 1.6 s at the default.) The oracle is a glossy lobe
/// on a diffuse base, computed in f32 as a model's `eval` is.
#[test]
fn a_tolerance_below_f32_rounding_costs_what_the_default_does() {
    use std::sync::atomic::{AtomicU64, Ordering};
    let mirror = Vec3::new(-0.6, 0.0, 0.8);
    let run = |tol: f64, grid: CellGrid| {
        let calls = AtomicU64::new(0);
        let f = |w: Vec3| {
            calls.fetch_add(1, Ordering::Relaxed);
            let lobe = w.dot(mirror).max(0.0).powf(40.0);
            f64::from((0.3 / std::f32::consts::PI + 2.0 * lobe) * w.z.max(0.0))
        };
        let v = Validation::of_fcos(f, &[mirror], grid, tol).unwrap();
        (calls.into_inner(), v.mass().to_vec())
    };
    for grid in [
        CellGrid::Square { res: 2 },
        CellGrid::Polar {
            rings: 2,
            sectors: 5,
        },
        CellGrid::Square { res: 7 },
    ] {
        let (base, mass) = run(1e-7, grid);
        let (calls, fine) = run(1e-13, grid);
        assert!(
            calls <= 3 * base,
            "{grid:?}: {calls} evaluations at 1e-13 against {base} at 1e-7"
        );
        let total: f64 = mass.iter().sum();
        for (a, b) in mass.iter().zip(&fine) {
            assert!((a - b).abs() <= 1e-7 * total, "{grid:?}: {a} {b}");
        }
    }
}
