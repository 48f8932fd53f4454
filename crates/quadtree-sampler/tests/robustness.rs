//! Robustness over the whole input space: grazing incident directions converge to the
//! grazing floor's tree or fail typed, every build is bounded by its budgets (nodes,
//! evaluations) with a typed outcome, and an f_r that is 0 is one typed error in every mode.
//!
//! The CI part sweeps z = 10⁻ᵏ at a few k; the full sweep (k = 1…45, every model, both maps,
//! every mode) is behind `#[ignore]`:
//! `cargo test --release -p quadtree-sampler --features rayon --test robustness -- --ignored`
//! (about 4 minutes on 2 cores, with the random sweep below).
//! `cargo run --release -p quadtree-sampler --features rayon --example grazing_sweep` prints
//! the table (time, nodes, E[T], albedo, outcome). A random sweep of 400 trees for bound
//! violations is behind `#[ignore]` too (`random_builds_meet_no_bound_violation`).

use brdf_core::geometry::GRAZING_COS;
use brdf_core::{Brdf, DiskMap, registry};
use glam::Vec3;
use quadtree_sampler::{
    BuildConfig, BuildError, DirectionSampler, MAX_USABLE_EXPECTED_TRIALS, Quadtree,
    QuadtreeSampler, TableSampler, WarpSampler,
};
use rand_core::SeedableRng;
use rand_pcg::Pcg64;

/// Every continuous model: defaults, and a sharp or anisotropic set where it has one.
const SETS: &[(&str, &[&str])] = &[
    ("lambert", &[]),
    ("phong", &["n=1000"]),
    ("blinn-phong", &["n=1000"]),
    ("lewis-phong", &[]),
    ("cook-torrance", &[]),
    ("cook-torrance", &["m=0.05"]),
    ("oren-nayar", &[]),
    ("ward", &["alpha_x=0.05", "alpha_y=0.2"]),
    ("schlick", &[]),
    ("htsg", &[]),
    ("poulin-fournier", &[]),
    ("strauss", &[]),
];

fn model(name: &str, params: &[&str]) -> Box<dyn Brdf> {
    registry::create(name, params.iter().copied()).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The incident direction (0.8, 0.6, 10⁻ᵏ) (k = 45: the smallest positive f32).
fn grazing(k: i32) -> Vec3 {
    let z = 10f64.powi(-k) as f32;
    Vec3::new(0.8, 0.6, if z > 0.0 { z } else { f32::from_bits(1) })
}

/// Builds every mode at every k; checks that each ends usable (or typed), that samples are
/// finite with pdf > 0, and that below the floor the tree's albedo is the floor's.
fn sweep(ks: &[i32], sets: &[(&str, &[&str])], every_mode: bool) {
    for &(name, params) in sets {
        let b = model(name, params);
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            let cfg = BuildConfig {
                map,
                ..BuildConfig::default()
            };
            let mut at_floor: Option<f64> = None;
            for &k in ks {
                let wi = grazing(k);
                let q = QuadtreeSampler::new(&*b, wi, cfg)
                    .unwrap_or_else(|e| panic!("{name} {params:?} {map:?} k = {k}: {e}"));
                let st = q.stats();
                let albedo = q.albedo();
                assert!(
                    st.expected_trials <= MAX_USABLE_EXPECTED_TRIALS
                        && albedo.is_finite()
                        && albedo > 0.0,
                    "{name} {map:?} k = {k}: {st:?}, albedo {albedo}"
                );
                let mut rng = Pcg64::seed_from_u64(k as u64);
                let mut lost = 0;
                for _ in 0..256 {
                    match q.sample(&mut rng) {
                        Some(s) => assert!(
                            s.pdf.is_finite()
                                && s.pdf > 0.0
                                && s.weight.is_finite()
                                && s.wo.z > 0.0,
                            "{name} {map:?} k = {k}: {s:?}"
                        ),
                        None => lost += 1,
                    }
                }
                assert_eq!(lost, 0, "{name} {map:?} k = {k}: samples lost");
                assert_eq!(q.bound_violations(), 0, "{name} {map:?} k = {k}");
                // Below the floor the model is its floor value, so the tree is the floor's.
                if f64::from(wi.z) < GRAZING_COS {
                    match at_floor {
                        None => at_floor = Some(albedo),
                        Some(a) => assert!(
                            (albedo - a).abs() <= 1e-6 * a,
                            "{name} {map:?} k = {k}: albedo {albedo} but {a} at the floor"
                        ),
                    }
                }
                if every_mode || k == *ks.last().unwrap() {
                    let w = WarpSampler::new(&*b, wi, cfg, 0.1)
                        .unwrap_or_else(|e| panic!("{name} warp k = {k}: {e}"));
                    let t = TableSampler::new(&*b, wi, 64)
                        .unwrap_or_else(|e| panic!("{name} table k = {k}: {e}"));
                    for s in [&w as &dyn DirectionSampler, &t] {
                        for _ in 0..64 {
                            if let Some(x) = s.sample(&mut rng) {
                                let p = s.pdf(x.wo);
                                assert!(
                                    x.pdf.is_finite() && x.pdf > 0.0 && p.is_finite(),
                                    "{name} {} k = {k}: {x:?}, pdf {p}",
                                    s.name()
                                );
                            }
                        }
                    }
                }
            }
        }
    }
}

/// CI: the sweep at k = 1 (84°), 3, 4 (the floor), 6 and 45 (the smallest f32), rejection
/// everywhere, warp and table at k = 45.
#[test]
fn grazing_incidence_converges_to_the_floor() {
    sweep(&[1, 3, 4, 6, 45], SETS, false);
}

/// The full sweep: k = 1…45, every model, both maps, every mode.
#[test]
#[ignore = "about 7 minutes on 2 cores; run with --ignored"]
fn grazing_sweep_full() {
    let ks: Vec<i32> = (1..=45).collect();
    sweep(&ks, SETS, true);
}

/// f_r ≡ 0 for this wi (a dielectric with no interface and no diffuse term, a black
/// Lambertian): one typed error in every quadtree mode, at every wi.
#[test]
fn a_zero_brdf_is_one_typed_error_everywhere() {
    for (name, params) in [
        ("cook-torrance", &["f0=0", "kd=0"][..]),
        ("htsg", &["eta=1", "kappa=0", "a=0"]),
        ("lambert", &["albedo=0"]),
    ] {
        let b = model(name, params);
        for wi in [Vec3::Z, grazing(2), grazing(45)] {
            for map in [DiskMap::Orthographic, DiskMap::Concentric] {
                let cfg = BuildConfig {
                    map,
                    ..BuildConfig::default()
                };
                let zero = BuildError::ZeroBrdf { model: b.name() };
                assert_eq!(
                    QuadtreeSampler::new(&*b, wi, cfg).err(),
                    Some(zero.clone()),
                    "{name}"
                );
                assert_eq!(
                    WarpSampler::new(&*b, wi, cfg, 0.1).err(),
                    Some(zero.clone())
                );
                assert_eq!(TableSampler::new(&*b, wi, 32).err(), Some(zero.clone()));
                assert!(zero.to_string().contains("is 0 everywhere"));
            }
        }
    }
}

/// A lobe sharper than a small budget can bound ends in the typed `Exhausted` error (not a
/// sampler that needs thousands of trials), by nodes or by evaluations; and the stop is
/// deterministic: serial and parallel builds agree bit for bit.
#[test]
fn budgets_stop_the_build_typed_and_deterministically() {
    let b = model("blinn-phong", &["n=100000", "kd=0"]);
    let wi = Vec3::new(0.5, 0.0, 0.75f32.sqrt());
    for cfg in [
        BuildConfig {
            node_budget: 9,
            ..BuildConfig::default()
        },
        BuildConfig {
            evaluation_budget: 1,
            ..BuildConfig::default()
        },
    ] {
        match Quadtree::new(&*b, wi, cfg) {
            Err(BuildError::Exhausted {
                model,
                nodes,
                expected_trials,
            }) => {
                assert_eq!(model, "blinn-phong");
                assert!(nodes <= 9 && expected_trials > MAX_USABLE_EXPECTED_TRIALS);
            }
            other => panic!("{cfg:?}: {other:?}"),
        }
    }
    // Budgets that stop the build part-way, usable or not: the same outcome (tree or error)
    // on one thread and on several, and at least one of them leaves a usable tree.
    let b = model("cook-torrance", &["m=0.05"]);
    let wi = Vec3::new(0.9, 0.0, 0.19f32.sqrt());
    let mut usable_and_stopped = 0;
    let by_evaluations = (12..28).map(|e| BuildConfig {
        evaluation_budget: 1u64 << e,
        ..BuildConfig::default()
    });
    let by_nodes = [13, 41, 101, 201, 401].map(|n| BuildConfig {
        node_budget: n,
        ..BuildConfig::default()
    });
    for cfg in by_evaluations.chain(by_nodes) {
        let par = Quadtree::new(&*b, wi, cfg);
        let ser = Quadtree::new(
            &*b,
            wi,
            BuildConfig {
                parallel: false,
                ..cfg
            },
        );
        assert_eq!(par, ser, "{cfg:?}");
        if let Ok(t) = &par
            && t.stats().budget_exhausted
        {
            usable_and_stopped += 1;
        }
    }
    assert!(usable_and_stopped > 0, "no budget stopped a usable build");
}

/// Every direction above the horizon, however close to it, gives a finite pdf from every
/// quadtree mode, and its samples' pdf is the sampler's pdf.
#[test]
fn pdfs_are_finite_at_grazing_outgoing_directions() {
    let b = model("ward", &["alpha_x=0.05", "alpha_y=0.2"]);
    let wi = Vec3::new(0.6, 0.0, 0.8);
    let q = QuadtreeSampler::new(&*b, wi, BuildConfig::default()).unwrap();
    let w = WarpSampler::new(&*b, wi, BuildConfig::default(), 0.1).unwrap();
    let t = TableSampler::new(&*b, wi, 64).unwrap();
    for s in [&q as &dyn DirectionSampler, &w, &t] {
        for k in 1..=45 {
            let wo = {
                let z = 10f64.powi(-k) as f32;
                Vec3::new(-0.6, 0.8, if z > 0.0 { z } else { f32::from_bits(1) })
            };
            let p = s.pdf(wo);
            assert!(p.is_finite() && p >= 0.0, "{} at {wo}: {p}", s.name());
        }
    }
}

/// Ward's albedo (luminance) at `wi` with ks = 1, kd = 0.1, by an independent midpoint rule
/// in the half vector's slopes (s_x, s_y) = (h.x, h.y)/h.z, where the lobe is the separable
/// Gaussian exp(−s_x²/α_x² − s_y²/α_y²): wo = 2(wi·h)h − wi, dω_o = 4(wi·h) dω_h,
/// dω_h = ds_x ds_y/(1 + s²)^{3/2}; wi and wo lifted to the grazing floor as the model lifts
/// them. Nine standard deviations each way, `n` points per axis.
fn ward_albedo(wi: Vec3, ax: f64, ay: f64, n: usize) -> f64 {
    use glam::DVec3;
    let lift = |w: DVec3| {
        if w.z >= GRAZING_COS {
            return w;
        }
        let s = ((1.0 - GRAZING_COS) * (1.0 + GRAZING_COS)).sqrt() / w.truncate().length();
        DVec3::new(w.x * s, w.y * s, GRAZING_COS)
    };
    let wi = lift(wi.as_dvec3().normalize());
    let (hx, hy) = (18.0 * ax / n as f64, 18.0 * ay / n as f64);
    let mut sum = 0.0;
    for i in 0..n {
        let sx = -9.0 * ax + (i as f64 + 0.5) * hx;
        for j in 0..n {
            let sy = -9.0 * ay + (j as f64 + 0.5) * hy;
            let len = (1.0 + sx * sx + sy * sy).sqrt();
            let h = DVec3::new(sx, sy, 1.0) / len;
            let d = h.dot(wi);
            let wo = 2.0 * d * h - wi;
            if d <= 0.0 || wo.z <= 0.0 {
                continue;
            }
            let hv = wi + lift(wo);
            let e = ((hv.x / ax).powi(2) + (hv.y / ay).powi(2)) / (hv.z * hv.z);
            let f =
                (-e).exp() / (4.0 * core::f64::consts::PI * ax * ay * (wi.z * lift(wo).z).sqrt());
            sum += f * wo.z * 4.0 * d / (len * len * len);
        }
    }
    0.1 + sum * hx * hy
}

/// A lobe narrow along one tangent axis is a ridge along a line of the disk (Ward with
/// α = 0.001 across, 0.5 along: wo.x = −wi.x wherever h.x = 0). On the concentric map that
/// line is bent, and a node wider than the ridge saw nothing of it at its grid, its clamped
/// peak hint or its integration: such nodes never split, and at θ = 89° the tree missed 15 %
/// of the volume (17 % at 89.99°) with no bound violation to show it. Both maps' trees now
/// hold the volume of an independent quadrature to 10⁻⁴.
#[test]
fn a_ridge_along_a_tangent_axis_is_found_on_both_maps() {
    let dir = |theta: f64, phi: f64| {
        let (t, p) = (theta.to_radians(), phi.to_radians());
        Vec3::new(
            (t.sin() * p.cos()) as f32,
            (t.sin() * p.sin()) as f32,
            t.cos() as f32,
        )
        .normalize()
    };
    for (ax, ay, wi) in [
        (0.001, 0.5, dir(89.0, 127.99)),
        (0.5, 0.001, dir(89.0, 33.0)),
    ] {
        let b = model(
            "ward",
            &["ks=1", &format!("alpha_x={ax}"), &format!("alpha_y={ay}")],
        );
        let want = ward_albedo(wi, ax, ay, 1200);
        for map in [DiskMap::Orthographic, DiskMap::Concentric] {
            let cfg = BuildConfig {
                map,
                ..BuildConfig::default()
            };
            let q = QuadtreeSampler::new(&*b, wi, cfg).unwrap();
            let got = q.albedo();
            assert!(
                (got / want - 1.0).abs() < 1e-4,
                "α ({ax}, {ay}) wi {wi} {map:?}: tree {got} vs quadrature {want}"
            );
        }
    }
}

/// Bounds that a random sweep (random model, parameters, wi and map; 200 000 samples each)
/// found short, now held: 0 bound violations in 400 000 samples each, where the build before
/// the fixes met 3–129 in 200 000–400 000 (all but the Blinn–Phong case below).
/// - Polar boxes (the root's children) whose heights move as √s near their centre edge, so
///   that h/S peaked between the bound grid's first two rows: Cook–Torrance m = 0.67 near
///   grazing (3.5 % short), Strauss with smoothness 0 on both maps, Ward at θ = 55°.
/// - A ridge along a tangent axis on the concentric map (Ward α_x = 0.001), and along it
///   the low corner of a shaped box (Schlick p = 0.001).
/// - A sharp lobe at the rim of a sine-chart node, whose hint's own height is ~0 there:
///   Blinn–Phong n = 3 129 at cos θi = 10⁻⁴, about 12 times short once the hint was placed
///   in f64 (before, f32 rounding put it on the horizon and another node's grid happened
///   to find the lobe).
/// - A lobe whose peak lies just beyond a node's edge, zeroed there by masking: Cook–Torrance
///   m = 0.037 at cos θi = 0.02 (a quadrant of the root bounded at its diffuse level, half
///   of f on its edge; 7 violations in 200 000 samples at 41a4cdf).
#[test]
fn bounds_a_random_sweep_found_short_now_hold() {
    let cases: &[(&str, &[&str], [f32; 3], DiskMap)] = &[
        (
            "cook-torrance",
            &[
                "m=0.6720417",
                "f0=0.999,0.230451,0.999",
                "kd=0.9747243,1.0,0.9747243",
            ],
            [0.508938, -0.86075133, 0.009444398],
            DiskMap::Concentric,
        ),
        (
            "strauss",
            &[
                "color=1.0,0.2463566,1.0",
                "smoothness=0",
                "metalness=0.051256973",
                "transparency=0.33966598",
            ],
            [-0.94511646, -0.32655838, 0.010699943],
            DiskMap::Concentric,
        ),
        (
            "strauss",
            &[
                "color=0.021163523,0.62657803,0.021163523",
                "smoothness=0",
                "metalness=0",
                "transparency=0.9255156",
            ],
            [0.54629946, -0.78668344, 0.28755176],
            DiskMap::Orthographic,
        ),
        (
            "ward",
            &[
                "kd=0,0.080691196,0",
                "ks=0,0.8946189,0",
                "alpha_x=0.1238242",
                "alpha_y=0.8589544",
            ],
            [0.44332936, 0.68906015, 0.57328457],
            DiskMap::Concentric,
        ),
        (
            "ward",
            &[
                "kd=0.6679321,1.0,0.6679321",
                "ks=0.9116466,0.8537064,0.9116466",
                "alpha_x=0.001",
                "alpha_y=0.3926516",
            ],
            [0.9502759, 0.31135762, 0.0056635924],
            DiskMap::Concentric,
        ),
        (
            "schlick",
            &["c=1.0,0.26741356,1.0", "r=0.7426997", "p=0.001"],
            [-0.29182482, -0.34674048, 0.8914086],
            DiskMap::Concentric,
        ),
        (
            "blinn-phong",
            &["kd=0,0.22320211,0", "ks=0,0.29599807,0", "n=3128.7935"],
            [-0.29649946, 0.955033, 0.0001],
            DiskMap::Concentric,
        ),
        (
            "cook-torrance",
            &[
                "m=0.03740554",
                "f0=0.0,0.8492909,0.0",
                "kd=1.0,0.72211456,1.0",
            ],
            [-0.015714027, 0.9996784, 0.019903857],
            DiskMap::Orthographic,
        ),
    ];
    for &(name, params, w, map) in cases {
        let b = model(name, params);
        let wi = Vec3::from(w);
        let cfg = BuildConfig {
            map,
            ..BuildConfig::default()
        };
        let q = QuadtreeSampler::new(&*b, wi, cfg).unwrap();
        let mut rng = Pcg64::seed_from_u64(7);
        for _ in 0..400_000 {
            let _ = q.sample(&mut rng);
        }
        assert_eq!(
            q.bound_violations(),
            0,
            "{name} {params:?} wi {wi} {map:?}: {:?}",
            q.stats()
        );
    }
}

/// Checks every leaf of `b`'s tree at `wi` on `map` whose proposal `pick` selects, directly:
/// its bound times its shape against f·Jacobian on an (n + 1)² grid over its box, the unit
/// coordinates kept `inset` inside [0, 1] (sampling draws a hair inside the lower edges and
/// never on the upper ones, which are open). Returns how many leaves it checked.
fn assert_leaves_bounded(
    b: &dyn Brdf,
    wi: Vec3,
    map: DiskMap,
    n: u32,
    inset: f64,
    pick: impl Fn(&quadtree_sampler::proposal::Proposal) -> bool,
) -> usize {
    let cfg = BuildConfig {
        map,
        ..BuildConfig::default()
    };
    let tree = Quadtree::new(b, wi, cfg).unwrap();
    let mut checked = 0;
    for (i, node) in tree.leaves() {
        let prop = &node.proposal;
        if !pick(prop) {
            continue;
        }
        checked += 1;
        let rect = node.rect();
        for ix in 0..=n {
            for iy in 0..=n {
                let t = (glam::DVec2::new(f64::from(ix), f64::from(iy)) / f64::from(n))
                    .clamp(glam::DVec2::splat(inset), glam::DVec2::splat(1.0 - inset));
                let q = prop.lo + (prop.hi - prop.lo) * t;
                let Some(c) = prop.point(map, &rect, q) else {
                    continue;
                };
                let f = f64::from(brdf_core::geometry::luminance(b.eval(wi, c.w.as_vec3())));
                let s = if prop.shape.is_flat() {
                    1.0
                } else {
                    prop.shape.value(prop.unit(q))
                };
                assert!(
                    f * c.jacobian <= node.bound * s,
                    "{} wi {wi} {map:?}: leaf {i} ({:?}, rect {rect:?}): f·J {} at {q} over its \
                     bound {} × shape {s}",
                    b.name(),
                    prop.chart,
                    f * c.jacobian,
                    node.bound
                );
            }
        }
    }
    checked
}

/// A leaf whose largest f·Jacobian lies on one of its edges that the angle chart bends into
/// a curve: Strauss with smoothness 0.99 at cos θi = 0.006 on the orthographic map, whose
/// lobe a rim leaf (sampled in the transposed angle chart) cuts at its edge x = −0.71875.
/// The bound search's climbs took axis steps in the chart, where that edge is a corner for
/// every step (one leaves the node, the other goes down), and stopped 6 % below the edge's
/// maximum: 1 bound violation in 200 000 samples. Checked here directly: every angle-chart
/// leaf's bound against f·Jacobian on a 301 × 301 grid over its box. (At 41a4cdf this finds
/// that leaf's f·J over its bound; on a 401 × 401 grid it reaches 1.048 times it.)
#[test]
fn a_maximum_on_a_curved_leaf_edge_is_bounded() {
    use quadtree_sampler::chart::Chart;
    let b = model(
        "strauss",
        &[
            "color=0.0977,0.8623,0.0977",
            "smoothness=0.99",
            "metalness=0.4554",
            "transparency=0.9166",
        ],
    );
    let wi = Vec3::new(0.5554, -0.8316, 0.00569).normalize();
    let checked = assert_leaves_bounded(&*b, wi, DiskMap::Orthographic, 300, 0.0, |p| {
        matches!(p.chart, Chart::Angle | Chart::AngleY)
    });
    assert!(checked > 0, "the tree has rim leaves in an angle chart");
}

/// Shaped leaves whose h/S peaks on an edge of their box, where the bound search's grid and
/// climbs did not look, found by the random build sweep (seeds 9, 10 and 12; 1–25 bound
/// violations in 200 000 samples each):
/// - Schlick near grazing, orthographic: the polar box of the root's child x < 0, y ≥ 0
///   starts at φ = π/2, where cos φ rounds to +6·10⁻¹⁷ and the point leaves the node, so
///   the search read 0 along that edge; the shape is lowest at its centre corner, where h/S
///   peaks on that edge (5.8 % over the bound);
/// - Phong n = 5.75, concentric: a polar box whose shape falls to 9/63 at (rim, φ edge)
///   peaks at s = 0.9907 on that edge, between the grid's rows at 0.9375 and 1 and away
///   from every climb (0.5 % over the bound);
/// - Oren–Nayar σ = 0.24 at cos θi = 0.05, orthographic: a square leaf's left edge peaks
///   between two grid points (0.6 % over the bound).
/// - Poulin–Fournier n = 8.5, gap 1.3, concentric (seed 21 of the sweep over the two
///   expensive models): a shaped leaf of side ¼ on the rim peaks at z = 0.07 on its edge,
///   between the grid's last column (z = 0.18) and the rim band's last height (z = 0.03):
///   1.6 % over the bound.
///
/// Checked directly: every shaped leaf's bound times its shape against f·Jacobian on a
/// 201 × 201 grid over its box, 101 × 101 for Poulin–Fournier (the lower edges a hair
/// inside, where sampling draws).
#[test]
fn shaped_leaves_bound_their_edges() {
    // (Model, parameters, wi, map, grid steps of the check.)
    type Case = (
        &'static str,
        &'static [&'static str],
        [f32; 3],
        DiskMap,
        u32,
    );
    let cases: &[Case] = &[
        (
            "schlick",
            &["c=0.5810296,1.0,0.5810296", "r=0.6671167", "p=0.2013464"],
            [0.49749616, 0.86741334, 0.009571404],
            DiskMap::Orthographic,
            200,
        ),
        (
            "phong",
            &[
                "kd=0,0.45512393,0",
                "ks=0.5721115,0.7477144,0.5721115",
                "n=5.7500534",
            ],
            [-0.404434, 0.58912426, 0.69954675],
            DiskMap::Concentric,
            200,
        ),
        (
            "oren-nayar",
            &["albedo=0.13341576,0.9883535,0.13341576", "sigma=0.23993957"],
            [-0.77254313, -0.6330125, 0.049722016],
            DiskMap::Orthographic,
            200,
        ),
        (
            "poulin-fournier",
            &[
                "height=1.0",
                "gap=1.3243163",
                "kd=0,0.17667715,0",
                "ks=1.0,0.048097074,1.0",
                "n=8.545831",
            ],
            [-0.29641256, 0.8353494, 0.462959],
            DiskMap::Concentric,
            // (Coarser, for time: the slowest model to evaluate; 101² finds the fault.)
            100,
        ),
    ];
    for &(name, params, w, map, n) in cases {
        let b = model(name, params);
        let wi = Vec3::from(w).normalize();
        let shaped = assert_leaves_bounded(&*b, wi, map, n, 1e-9, |p| !p.shape.is_flat());
        assert!(shaped > 0, "{name}: the tree has shaped leaves");
    }
}

/// A lobe far narrower than the node holding it, at the f32 resolution of directions:
/// Cook–Torrance m = 0.001 at cos θi = 0.006. Its deepest nodes (side 7.6·10⁻⁶ on the
/// concentric map) used to refine their integration to all 8 levels everywhere, into cells
/// a few f32 steps wide where f is a staircase the error estimate never sees converge:
/// 3–9 million evaluations a node, and the concentric build ended on its evaluation budget
/// after 17 s with 217 nodes (the orthographic one took 1.3 s). Integration now stops at
/// cells of side 2⁻²²: both builds finish within their budgets, and their volumes, found
/// in different charts, agree.
#[test]
fn integration_stops_at_the_resolution_of_f32_directions() {
    let b = model(
        "cook-torrance",
        &[
            "m=0.001",
            "f0=0.999,0.9175976,0.999",
            "kd=0.40108106,0.53716046,0.40108106",
        ],
    );
    let wi = Vec3::new(-0.8565785, -0.5159781, 0.0063116667);
    let albedo = [DiskMap::Orthographic, DiskMap::Concentric].map(|map| {
        let cfg = BuildConfig {
            map,
            ..BuildConfig::default()
        };
        let q = QuadtreeSampler::new(&*b, wi, cfg).unwrap();
        let stats = q.stats();
        assert!(!stats.budget_exhausted, "{map:?}: {stats:?}");
        assert!(stats.expected_trials < 1.2, "{map:?}: {stats:?}");
        q.albedo()
    });
    assert!(
        (albedo[0] / albedo[1] - 1.0).abs() < 1e-6,
        "orthographic {} vs concentric {}",
        albedo[0],
        albedo[1]
    );
}

/// A random sweep like the one behind `bounds_a_random_sweep_found_short_now_hold`, kept so
/// that it can be rerun: 400 random trees (a random continuous model but HTSG and
/// Poulin–Fournier, for time; parameters with 15 % of the draws on each end of their ranges;
/// a random wi, a quarter of them with cos θi in [10⁻⁴, 10⁻²]; a random map), 200 000
/// samples each, and no bound violation allowed. About 1.5 minutes on one core:
/// `cargo test --release -p quadtree-sampler --test robustness random_builds -- --ignored`.
/// At f37796b (before the fixes the other test names) it fails: 10 of the 400 trees (Ward
/// and Schlick ridges on both maps, Strauss), 1 to 437 violations each.
#[test]
#[ignore = "about 1.5 minutes: run with --ignored"]
fn random_builds_meet_no_bound_violation() {
    use brdf_core::{ParamKind, ParamValue};
    use rand_core::Rng;
    let mut r = Pcg64::seed_from_u64(5);
    let mut u = || (r.next_u32() >> 8) as f32 / (1u32 << 24) as f32;
    let models: Vec<_> = registry::models()
        .iter()
        .filter(|m| !m.delta && !m.measured && m.name != "htsg" && m.name != "poulin-fournier")
        .collect();
    let mut failures = Vec::new();
    for case in 0..400 {
        let info = models[((u() * models.len() as f32) as usize).min(models.len() - 1)];
        let mut p = info.defaults();
        for spec in info.params {
            let mut lerp = || {
                let t = u();
                let t = if t < 0.15 {
                    0.0
                } else if t > 0.85 {
                    1.0
                } else {
                    (t - 0.15) / 0.7
                };
                if spec.max / spec.min.max(1e-3) > 1e3 {
                    ((spec.max.min(1e5) + 1.0).ln() * t).exp() - 1.0
                } else {
                    spec.min + (spec.max - spec.min) * t
                }
                .clamp(spec.min, spec.max)
            };
            let v = match spec.kind {
                ParamKind::Scalar => ParamValue::Scalar(lerp()),
                ParamKind::Rgb => {
                    let (a, b) = (lerp(), lerp());
                    ParamValue::Rgb(Vec3::new(a, b, a))
                }
                ParamKind::Path | ParamKind::Choice(_) => continue,
            };
            // A constraint between parameters (kd + ks ≤ 1) refuses some draws: the
            // default stays.
            let _ = p.set(spec.name, v);
        }
        let Ok(b) = info.build(&p) else { continue };
        let ct = match (u() * 4.0) as u32 {
            0 => 1e-4 * (1.0 + 99.0 * u()),
            1 => 0.02 * u(),
            _ => u(),
        };
        let phi = u() * std::f32::consts::TAU;
        let s = (1.0 - ct * ct).max(0.0).sqrt();
        let wi = Vec3::new(s * phi.cos(), s * phi.sin(), ct.max(1e-6));
        let map = if u() < 0.5 {
            DiskMap::Concentric
        } else {
            DiskMap::Orthographic
        };
        let cfg = BuildConfig {
            map,
            ..BuildConfig::default()
        };
        // A zero f_r is a typed error, as it should be; nothing to sample.
        let Ok(q) = QuadtreeSampler::new(&*b, wi, cfg) else {
            continue;
        };
        let mut rng = Pcg64::seed_from_u64(case);
        for _ in 0..200_000 {
            let _ = q.sample(&mut rng);
        }
        if q.bound_violations() > 0 {
            failures.push(format!(
                "case {case}: {} {:?} wi {wi} {map:?}: {} violations",
                info.name,
                p.iter()
                    .map(|(s, v)| format!("{}={v:?}", s.name))
                    .collect::<Vec<_>>(),
                q.bound_violations()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// An RNG that returns all ones: every proposal point lands on the far corner of its box.
struct AllOnes;

impl rand_core::TryRng for AllOnes {
    type Error = rand_core::Infallible;
    fn try_next_u32(&mut self) -> Result<u32, Self::Error> {
        Ok(u32::MAX)
    }
    fn try_next_u64(&mut self) -> Result<u64, Self::Error> {
        Ok(u64::MAX)
    }
    fn try_fill_bytes(&mut self, dst: &mut [u8]) -> Result<(), Self::Error> {
        dst.fill(0xff);
        Ok(())
    }
}

/// A caller's broken RNG ends a sample (`None`, counted as given up), never hangs it: here
/// in a flat polar leaf (Lambert's tree is one, on the orthographic map), whose proposal
/// draws its point again while it misses the disk (all ones puts it at the square's corner,
/// outside), and in a square leaf (Phong's glossy tree), whose trials never accept.
#[test]
fn a_broken_rng_gives_up_instead_of_hanging() {
    use quadtree_sampler::chart::Chart;
    for (name, params) in [("lambert", &[][..]), ("phong", &["n=1000"][..])] {
        let b = model(name, params);
        let q = QuadtreeSampler::new(
            &*b,
            Vec3::new(0.3, 0.2, 0.9).normalize(),
            BuildConfig::default(),
        )
        .unwrap();
        if name == "lambert" {
            let leaves = q.tree().leaves();
            assert_eq!(leaves.len(), 1);
            assert_eq!(leaves[0].proposal.chart, Chart::Polar);
            assert!(leaves[0].proposal.shape.is_flat());
        }
        assert!(q.sample(&mut AllOnes).is_none(), "{name}");
        assert_eq!(q.gave_up(), 1, "{name}");
    }
}
