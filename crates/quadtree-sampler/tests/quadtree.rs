//! The quadtree's acceptance tests (issue "quadtree-sampler", Done when): for every non-delta
//! model, default and sharp parameters, wi at 0°, 45°, 80°, 89°: the build terminates, E[T]
//! ≤ 2 (seed rule) and ≤ 1.25 (target mode), no bound violations, the albedo matches an
//! independent quadrature, serial == parallel bit for bit, and 10⁶ samples follow f·cos.

use brdf_core::quadrature::{GaussLegendre, directional_albedo};
use brdf_core::{Brdf, DiskMap, geometry::luminance, registry};
use glam::Vec3;
use quadtree_sampler::{
    BuildConfig, BuildError, LAST_RETRY_TOLERANCE, PackedTree, Quadtree, QuadtreeSampler,
    RETRY_TOLERANCE, refleja,
};
use rand_core::SeedableRng;
use rand_pcg::Pcg64;
use std::f64::consts::PI;

fn dir(theta: f64, phi: f64) -> Vec3 {
    let (t, p) = (theta.to_radians(), phi.to_radians());
    Vec3::new(
        (t.sin() * p.cos()) as f32,
        (t.sin() * p.sin()) as f32,
        t.cos() as f32,
    )
}

/// Every non-delta model: defaults, and a sharp setting of the glossy ones.
const SETS: &[(&str, &[&str])] = &[
    ("lambert", &[]),
    ("phong", &[]),
    ("phong", &["n=1000"]),
    ("blinn-phong", &[]),
    ("blinn-phong", &["n=1000"]),
    ("lewis-phong", &[]),
    ("lewis-phong", &["n=1000", "kd=0.1", "ks=0.9"]),
    ("cook-torrance", &[]),
    ("cook-torrance", &["m=0.1"]),
    ("oren-nayar", &[]),
    ("oren-nayar", &["sigma=1.5"]),
    ("ward", &[]),
    ("ward", &["alpha_x=0.05", "alpha_y=0.2"]),
    ("schlick", &[]),
    ("schlick", &["r=0.02", "p=0.3"]),
    ("htsg", &[]),
    ("poulin-fournier", &[]),
    ("strauss", &[]),
    ("strauss", &["smoothness=0.9", "metalness=1"]),
];

const ANGLES: [f64; 4] = [0.0, 45.0, 80.0, 89.0];

/// Models whose eval costs microseconds (HTSG sums a series, Poulin-Fournier integrates over
/// the cylinder): the albedo oracle uses a coarser hemisphere rule for them.
const COSTLY: &[&str] = &["htsg", "poulin-fournier"];

fn model(name: &str, params: &[&str]) -> Box<dyn Brdf> {
    registry::create(name, params.iter().copied()).unwrap()
}

/// ρ(wi) = ∫ Y(f) cos dω by the hemisphere rule (independent of the tree).
/// (160 × 640 panels of 8 × 8 points; 80 × 320 for the costly models, whose lobes here are
/// broad.)
fn quadrature_albedo(b: &dyn Brdf, wi: Vec3) -> f64 {
    let panels = if COSTLY.contains(&b.name()) { 80 } else { 160 };
    f64::from(luminance(directional_albedo(b, wi, panels, 8).as_vec3()))
}

/// The seed's orthographic map in CI; the concentric map (as many builds again, and its
/// target mode the slowest of all) behind `--ignored`:
/// `cargo test --release -p quadtree-sampler --features rayon --test quadtree -- --ignored`
/// (about 3 minutes on 2 cores). Same assertions, same seeds.
#[test]
fn builds_terminate_with_bounded_trials_and_the_right_albedo() {
    check_builds(DiskMap::Orthographic);
}

/// [`builds_terminate_with_bounded_trials_and_the_right_albedo`] on the concentric map.
#[test]
fn builds_terminate_with_bounded_trials_and_the_right_albedo_concentric() {
    check_builds(DiskMap::Concentric);
}

fn check_builds(map: DiskMap) {
    for &(name, params) in SETS {
        let b = model(name, params);
        for theta in ANGLES {
            let wi = dir(theta, 30.0);
            let want = quadrature_albedo(&*b, wi);
            {
                let seed = QuadtreeSampler::new(
                    &*b,
                    wi,
                    BuildConfig {
                        map,
                        ..BuildConfig::default()
                    },
                )
                .unwrap();
                let s = seed.stats();
                assert!(
                    !s.budget_exhausted,
                    "{name} {params:?} {theta}° {map:?}: budget"
                );
                assert!(
                    s.expected_trials <= 2.0,
                    "{name} {params:?} {theta}° {map:?}: E[T] = {}",
                    s.expected_trials
                );
                let got = seed.albedo();
                assert!(
                    (got - want).abs() <= 1e-3 * want,
                    "{name} {params:?} {theta}° {map:?}: tree albedo {got} vs quadrature {want}"
                );
                let target = QuadtreeSampler::new(
                    &*b,
                    wi,
                    BuildConfig {
                        map,
                        target_trials: Some(1.25),
                        ..BuildConfig::default()
                    },
                )
                .unwrap();
                let t = target.stats();
                assert!(
                    t.expected_trials <= 1.25,
                    "{name} {params:?} {theta}° {map:?}: target E[T] = {} ({} nodes)",
                    t.expected_trials,
                    t.nodes
                );
                // Target mode costs a bounded multiple of the seed rule. Issue 16's goal is 4×
                // its nodes; a sharp smooth lobe misses it: its seed-rule leaves have P ≈ 0.6,
                // the target needs 0.8 (× safety), and one split of a smooth lobe's leaf takes
                // it from one to the other, so the whole lobe splits once more (measured, these
                // sets: up to 4.8×, Schlick p = 0.3 at 80°; Cook–Torrance 89° 4.3×). Hence 5×
                // here, counted from a full tree of depth 3 (85 nodes): where the seed rule stops
                // at one node above 1.25 (Lambert, orthographic: 4/π × safety), the target must
                // resolve the rim that far. (It was 94 421 nodes for Lambert before rim leaves
                // chose their proposal.)
                assert!(
                    t.nodes <= 5 * s.nodes.max(85),
                    "{name} {params:?} {theta}° {map:?}: target {} nodes, seed rule {}",
                    t.nodes,
                    s.nodes
                );
                assert!((target.albedo() - want).abs() <= 1e-3 * want);
            }
        }
    }
}

/// The concentric map has a constant Jacobian, so a constant f is one node whose only waste is
/// the safety factor (1.02): Lambert at any wi, Oren–Nayar at normal incidence (its B term
/// vanishes with tan β = 0), by the seed rule and by target mode alike. (Rim leaves once sampled
/// in the sine chart whatever f did, whose vanishing Jacobian kept their acceptance near ½:
/// 4 129 nodes, E[T] 1.998, and 270 049 nodes for target 1.25.)
#[test]
fn a_constant_brdf_is_one_node_on_either_map() {
    let cases: [(&str, &[f64]); 2] = [
        ("lambert", &[0.0, 30.0, 60.0, 80.0, 89.0, 89.99]),
        ("oren-nayar", &[0.0]),
    ];
    // Concentric: the square is the disk. Orthographic: the root's polar box is the disk
    // (with the square, E[T] was 4/π times the safety factor, 1.30, and target mode split
    // the rim into 85 nodes).
    for map in [DiskMap::Concentric, DiskMap::Orthographic] {
        for (name, thetas) in cases {
            let b = model(name, &[]);
            for &theta in thetas {
                for target in [None, Some(1.25), Some(1.05)] {
                    let config = BuildConfig {
                        map,
                        target_trials: target,
                        ..BuildConfig::default()
                    };
                    let t = Quadtree::new(&*b, dir(theta, 20.0), config).unwrap();
                    let st = t.stats();
                    assert_eq!(st.nodes, 1, "{map:?} {name} {theta}° {target:?}");
                    assert!(
                        st.expected_trials <= 1.03,
                        "{map:?} {name} {theta}° {target:?}: E[T] {}",
                        st.expected_trials
                    );
                }
            }
        }
    }
}

/// The least target a build accepts, the bounds' safety factor, is reached where every bound
/// is tight: Lambert is one node on both maps, at the normal and at grazing, its E[T] at most
/// `target_limit` of the target (compared exactly with the target, the rounding of the
/// stored volumes left it 8·10⁻⁸ over, and the build split a million nodes for nothing). A
/// lobe cannot reach it: its build stops at the budget and says so.
#[test]
fn a_target_at_the_safety_factor_is_reached_where_the_bounds_are_tight() {
    let lambert = model("lambert", &[]);
    let safety = BuildConfig::default().bound_safety;
    for map in [DiskMap::Orthographic, DiskMap::Concentric] {
        for theta in [0.0, 45.0, 89.0] {
            let config = BuildConfig {
                map,
                ..BuildConfig::with_target_trials(safety)
            };
            let st = QuadtreeSampler::new(&*lambert, dir(theta, 20.0), config)
                .unwrap()
                .stats();
            assert_eq!(st.nodes, 1, "{map:?} {theta}°: {st:?}");
            assert!(!st.budget_exhausted, "{map:?} {theta}°: {st:?}");
            assert!(
                st.expected_trials <= quadtree_sampler::target_limit(safety),
                "{map:?} {theta}°: {st:?}"
            );
        }
    }
    let phong = model("phong", &["n=100"]);
    let config = BuildConfig {
        node_budget: 1 << 12,
        ..BuildConfig::with_target_trials(safety)
    };
    let st = QuadtreeSampler::new(&*phong, dir(30.0, 0.0), config)
        .unwrap()
        .stats();
    assert!(st.budget_exhausted && st.expected_trials > safety, "{st:?}");
}

/// Where the seed's E[T] ≤ 2 is out of reach (a needle lobe at grazing incidence, its
/// leaves at the depth limit), the build stops within `FLOOR_SLACK` of the least E[T] any
/// splitting could reach instead of splitting until the node budget: Cook–Torrance
/// m = 0.001 at cos θi = 10⁻⁴ took 10⁶ nodes and 50 s with kd = 1 (E[T] 3.059 → 3.033) and
/// 19 365 nodes with kd = 0 (6.438 → 6.437). Its samples still violate no bound.
#[test]
fn an_unreachable_target_stops_near_its_floor() {
    let wi = Vec3::new(1.0, 0.0, 1e-4).normalize();
    let config = BuildConfig::default();
    for kd in ["kd=0", "kd=1"] {
        let b = model("cook-torrance", &["m=0.001", "f0=0.999", kd]);
        let tree = Quadtree::new(&*b, wi, config).unwrap();
        let st = tree.stats().clone();
        let (mut floor, mut v1s) = (0.0, 0.0);
        for (_, n) in tree.leaves().filter(|(_, n)| n.v1 > 0.0) {
            v1s += n.v1;
            floor += if n.depth < config.max_depth && n.reducible_waste(config.bound_safety) > 0.0 {
                config.bound_safety * n.v1
            } else {
                n.box_volume()
            };
        }
        assert!(floor / v1s > 2.0, "{kd}: the target was reachable: {st:?}");
        assert!(
            st.expected_trials <= quadtree_sampler::FLOOR_SLACK * floor / v1s * (1.0 + 1e-9),
            "{kd}: E[T] {} over floor {}: {st:?}",
            st.expected_trials,
            floor / v1s
        );
        assert!(st.nodes < 5_000 && !st.budget_exhausted, "{kd}: {st:?}");
        let s = QuadtreeSampler::new(&*b, wi, config).unwrap();
        let mut rng = Pcg64::seed_from_u64(3);
        for _ in 0..20_000 {
            s.sample(&mut rng);
        }
        assert_eq!(s.bound_violations(), 0, "{kd}");
    }
}

#[test]
fn builds_terminate_at_grazing_incidence() {
    for &(name, params) in SETS {
        let b = model(name, params);
        let config = BuildConfig::with_target_trials(1.25);
        let s = QuadtreeSampler::new(&*b, dir(89.9, 0.0), config).unwrap();
        assert!(s.stats().nodes <= 1 << 20);
        assert!(s.albedo().is_finite());
    }
}

/// A lobe narrower than the spacing of the root's integration points (sharp lobes at grazing
/// incidence, squeezed against the rim) must still be found: the root's rule sees f = 0 at
/// every point, but its bound search does not. These builds used to stop at an empty root
/// (albedo 0, every sample failing). Oracle: the validation's adaptive cell integration.
#[test]
fn a_lobe_between_the_roots_integration_points_is_found() {
    use brdf_validate::{CellGrid, Validation};
    for (name, params, theta, map) in [
        (
            "ward",
            &["alpha_x=0.01", "alpha_y=0.01", "kd=0"][..],
            89.0,
            DiskMap::Orthographic,
        ),
        (
            "ward",
            &["alpha_x=0.01", "alpha_y=0.01", "kd=0"][..],
            80.0,
            DiskMap::Concentric,
        ),
        (
            "cook-torrance",
            &["m=0.02", "kd=0"][..],
            89.0,
            DiskMap::Concentric,
        ),
        (
            "blinn-phong",
            &["n=10000", "kd=0"][..],
            89.0,
            DiskMap::Concentric,
        ),
    ] {
        let b = model(name, params);
        let wi = dir(theta, 30.0);
        let v = Validation::new(&*b, wi, CellGrid::Square { res: 25 }, 1e-7).unwrap();
        let want: f64 = v.mass().iter().sum();
        let s = QuadtreeSampler::new(
            &*b,
            wi,
            BuildConfig {
                map,
                ..BuildConfig::default()
            },
        )
        .unwrap();
        let got = s.albedo();
        assert!(
            (got - want).abs() <= 1e-5 * want,
            "{name} {theta}° {map:?}: tree albedo {got} vs cells {want}"
        );
        let st = s.stats();
        assert!(
            !st.budget_exhausted && st.expected_trials <= 2.0,
            "{name}: {st:?}"
        );
        let mut rng = Pcg64::seed_from_u64(7);
        let drawn = (0..20_000).filter(|_| s.sample(&mut rng).is_some()).count();
        assert_eq!(
            drawn, 20_000,
            "{name} {theta}° {map:?}: every sample succeeds"
        );
        assert_eq!(s.bound_violations(), 0, "{name} {theta}° {map:?}");
    }
}

/// An evaluation budget that stops Cook–Torrance m = 0.1's target-1.1 tree at 45° part-way
/// (13 nodes; 32 000 completes its 349) even at [`LAST_RETRY_TOLERANCE`], where no retry
/// follows.
#[cfg(feature = "rayon")]
const PART_WAY_BUDGET: u64 = 30_000;

// Only with the `rayon` feature: without it a "parallel" build is the serial one and this
// would pass whatever the parallel code did. `cargo test --workspace` turns it on (the
// viewer and brdf-validate's tests ask for it); alone: `cargo test -p quadtree-sampler
// --features rayon`.
#[cfg(feature = "rayon")]
#[test]
fn serial_and_parallel_builds_are_bit_identical() {
    for &(name, params) in &[
        ("phong", &["n=1000"][..]),
        ("ward", &[][..]),
        ("cook-torrance", &["m=0.1"][..]),
    ] {
        let b = model(name, params);
        let wi = dir(45.0, 10.0);
        // The seed's rule, target mode, and builds that the node budget or the evaluation
        // budget stops part-way (a parallel build evaluates ahead of the breadth-first pass,
        // which must still stop where the serial one does), on both maps. An evaluation
        // budget that stops a build to 10⁻⁶ has it built again to a looser tolerance; one
        // that stops a build already at the last (LAST_RETRY_TOLERANCE) leaves it part-way.
        let budgets = [
            (None, u32::MAX, u64::MAX, DiskMap::Orthographic, 1e-6),
            (Some(1.3), u32::MAX, u64::MAX, DiskMap::Orthographic, 1e-6),
            (None, 61, u64::MAX, DiskMap::Orthographic, 1e-6),
            (Some(1.1), u32::MAX, 100_000, DiskMap::Orthographic, 1e-6),
            (
                Some(1.1),
                u32::MAX,
                PART_WAY_BUDGET,
                DiskMap::Orthographic,
                LAST_RETRY_TOLERANCE,
            ),
            (None, u32::MAX, u64::MAX, DiskMap::Concentric, 1e-6),
            (Some(1.2), 17, u64::MAX, DiskMap::Concentric, 1e-6),
        ];
        for (target, node_budget, evaluation_budget, map, tolerance) in budgets {
            let config = BuildConfig {
                target_trials: target,
                node_budget: node_budget.min(BuildConfig::default().node_budget),
                evaluation_budget: evaluation_budget.min(BuildConfig::default().evaluation_budget),
                map,
                integration_tolerance: tolerance,
                ..BuildConfig::default()
            };
            let serial = Quadtree::new(
                &*b,
                wi,
                BuildConfig {
                    parallel: false,
                    ..config
                },
            )
            .unwrap();
            // (The evaluation budget's allowance per node lets the smaller trees finish.)
            if node_budget != u32::MAX || (evaluation_budget != u64::MAX && name == "cook-torrance")
            {
                let retried = serial.integration_tolerance() > tolerance;
                assert!(serial.budget_exhausted() != retried, "{name} {config:?}");
                let by_evaluations = evaluation_budget != u64::MAX;
                assert_eq!(
                    retried,
                    by_evaluations && tolerance < LAST_RETRY_TOLERANCE,
                    "{name} {config:?}"
                );
            }
            for threads in [1, 2, 3, 4] {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let par = pool.install(|| {
                    Quadtree::new(
                        &*b,
                        wi,
                        BuildConfig {
                            parallel: true,
                            ..config
                        },
                    )
                    .unwrap()
                });
                assert_eq!(serial.nodes().len(), par.nodes().len(), "{name} {config:?}");
                assert_eq!(serial.budget_exhausted(), par.budget_exhausted());
                for (a, c) in serial.nodes().iter().zip(par.nodes()) {
                    assert_eq!(a.v1.to_bits(), c.v1.to_bits(), "{name}: {threads} threads");
                    assert_eq!(a.bound.to_bits(), c.bound.to_bits());
                    assert_eq!(a, c);
                }
                // So is the sampling layout packed from them.
                assert_eq!(PackedTree::new(&serial), PackedTree::new(&par));
            }
        }
    }
}

#[test]
fn packed_selection_matches_v1_and_reaches_every_live_leaf() {
    for (name, params, theta) in [
        ("phong", &["n=1000"][..], 45.0),
        ("ward", &[][..], 80.0),
        ("cook-torrance", &["m=0.1"][..], 30.0),
        ("lambert", &[][..], 10.0),
        // Grazing: leaves whose v1 is positive in f64 but under f32's smallest subnormal.
        ("phong", &["n=1000", "kd=0"][..], 89.0),
    ] {
        let b = model(name, params);
        let tree =
            Quadtree::new(&*b, dir(theta, 10.0), BuildConfig::with_target_trials(1.3)).unwrap();
        let packed = PackedTree::new(&tree);
        // 16 bytes a node, 32 a leaf sampled in an angle or sine chart (its box, found once;
        // a polar box is constants), and 16 a selection-guide entry: the largest power of two
        // up to half the node count (at least 1, at most 256).
        let rim_leaves = tree
            .leaves()
            .filter(|(_, n)| n.proposal.chart.needs_stored_box())
            .count();
        let n = tree.nodes().len();
        let guide = (0..=8)
            .map(|b| 1usize << b)
            .filter(|&g| g == 1 || 2 * g <= n)
            .max()
            .unwrap();
        assert_eq!(
            packed.stats().bytes,
            16 * n + 32 * rim_leaves + 16 * guide,
            "{name}: 16 bytes a node, 32 a rim leaf, 16 a guide entry"
        );
        let p = packed.selection_probabilities();
        let volume = tree.volume();
        let inspected = packed.leaves();
        assert_eq!(inspected.len(), tree.leaves().count());
        let unit = 1.0 / f64::from(1u32 << 31);
        // One unit of 2^-31 per leaf, plus one for every leaf under a unit that the minimum
        // width may have pushed along (module doc of `packed`).
        let tiny = tree
            .leaves()
            .filter(|(_, n)| n.v1 > 0.0 && n.v1 / volume < unit)
            .count();
        let mut distance = 0.0;
        for ((i, n), u) in tree.leaves().zip(&inspected) {
            let want = n.v1 / volume;
            distance += 0.5 * (p[i] - want).abs();
            assert!(
                (p[i] - want).abs() <= (1.0 + tiny as f64) * unit,
                "{name}: leaf {i}: {} vs {want} ({tiny} tiny leaves)",
                p[i]
            );
            assert_eq!(
                p[i] > 0.0,
                n.v1 > 0.0,
                "{name}: leaf {i} reachable iff live"
            );
            // Inspection of the packed leaf: the same square, depth and proposal, a bound at
            // least as large, v1 to f32, and the selection probability itself.
            assert_eq!((u.index, u.rect, u.depth), (i, n.rect(), n.depth));
            assert!(u.bound >= n.bound && u.bound <= n.bound * (1.0 + 1e-6));
            assert_eq!(u.proposal, n.proposal);
            assert_eq!(
                (u.v1, u.live, u.probability),
                (f64::from(n.v1 as f32), n.v1 > 0.0, p[i])
            );
        }
        let leaves = tree.leaves().count() as f64;
        assert!(
            distance <= leaves * unit,
            "{name}: total variation {distance}"
        );
        // The descent lands in the leaf holding the uniform, with that leaf's square: walk
        // the leaves in interval order and select at both ends of each interval.
        let mut start = 0.0;
        let mut order: Vec<usize> = tree.leaves().map(|(i, _)| i).collect();
        order.sort_by_key(|&i| leaf_path(&tree, i));
        for i in order {
            if p[i] > 0.0 {
                for u in [start, start + p[i] - 1.0 / f64::from(1u32 << 31)] {
                    let s = packed.select(u);
                    assert_eq!(s.index, i, "{name}: u = {u}");
                    assert_eq!(s.rect, tree.nodes()[i].rect());
                    // A reachable leaf is sampled: its bound is the build's, never 0.
                    assert!(
                        packed.proposal(&s).1 >= tree.nodes()[i].bound,
                        "{name}: leaf {i}"
                    );
                }
            }
            start += p[i];
        }
        assert!((start - 1.0).abs() < 1e-12);
    }
}

/// The child indices from the root down to node `i` (sorts leaves in selection order).
fn leaf_path(tree: &Quadtree, i: usize) -> Vec<usize> {
    let nodes = tree.nodes();
    let mut path = Vec::new();
    let mut j = 0;
    while j != i {
        let c = nodes[j].first_child as usize;
        let p = tree.nodes()[i].rect().min;
        let r = nodes[j].rect();
        let half = 0.5 * (r.max.x - r.min.x);
        let k = usize::from(p.x >= r.min.x + half) + 2 * usize::from(p.y >= r.min.y + half);
        path.push(k);
        j = c + k;
    }
    path
}

#[test]
fn delta_models_are_a_typed_error_and_refleja_samples_them_analytically() {
    let mirror = model("mirror", &["reflectance=0.8"]);
    let e = QuadtreeSampler::new(&*mirror, dir(30.0, 0.0), BuildConfig::default()).unwrap_err();
    assert_eq!(e, BuildError::DeltaModel { model: "mirror" });
    // World frame with a tilted normal: the sample is the world mirror direction.
    let n = Vec3::new(0.2, -0.1, 1.0).normalize();
    let wi = (n + Vec3::new(0.5, 0.3, 0.0)).normalize();
    let mut rng = Pcg64::seed_from_u64(3);
    let s = refleja(&*mirror, wi, n, &mut rng).unwrap().unwrap();
    let want = 2.0 * wi.dot(n) * n - wi;
    assert!(s.delta && (s.wo - want).length() < 1e-5);
    assert_eq!(s.weight, Vec3::splat(0.8));
    // refleja on a continuous model gives a world direction above the surface.
    let phong = model("phong", &["n=200"]);
    let s = refleja(&*phong, wi, n, &mut rng).unwrap().unwrap();
    assert!(s.wo.dot(n) > 0.0 && !s.delta);
}

#[test]
fn bad_inputs_are_typed_errors() {
    use brdf_core::DirectionError;
    let b = model("lambert", &[]);
    for (wi, e) in [
        (Vec3::new(0.0, 0.0, -1.0), DirectionError::BelowHorizon),
        (Vec3::new(1.0, 0.0, 0.0), DirectionError::BelowHorizon),
        (Vec3::ZERO, DirectionError::ZeroLength),
        (Vec3::new(f32::NAN, 0.0, 1.0), DirectionError::NotFinite),
    ] {
        assert_eq!(
            QuadtreeSampler::new(&*b, wi, BuildConfig::default()).unwrap_err(),
            BuildError::Direction(e)
        );
    }
    for cfg in [
        BuildConfig {
            split_threshold: 0.0,
            ..BuildConfig::default()
        },
        BuildConfig {
            split_threshold: f64::NAN,
            ..BuildConfig::default()
        },
        BuildConfig {
            target_trials: Some(0.5),
            ..BuildConfig::default()
        },
        // Below the safety factor, E[T]'s floor: unreachable, refused before any split.
        BuildConfig {
            target_trials: Some(1.0),
            ..BuildConfig::default()
        },
        BuildConfig {
            target_trials: Some(1.1),
            bound_safety: 1.2,
            ..BuildConfig::default()
        },
        // P never exceeds 1/bound_safety: a higher threshold splits every node.
        BuildConfig {
            split_threshold: 0.99,
            ..BuildConfig::default()
        },
        BuildConfig {
            split_threshold: 0.7,
            bound_safety: 1.5,
            ..BuildConfig::default()
        },
        BuildConfig {
            bound_safety: 0.9,
            ..BuildConfig::default()
        },
        BuildConfig {
            max_depth: 64,
            ..BuildConfig::default()
        },
    ] {
        assert!(matches!(
            QuadtreeSampler::new(&*b, Vec3::Z, cfg),
            Err(BuildError::OutOfRange { .. })
        ));
    }
    let n = Vec3::Z;
    assert!(refleja(&*b, -Vec3::Z, n, &mut Pcg64::seed_from_u64(1)).is_err());
}

/// Probability of each cell of an equal-area polar grid (r², φ) on the disk under the density
/// f·cos/ρ, by Gauss–Legendre in (z, φ) per cell (dA_disk = z dz dφ), never using the tree.
fn cell_probabilities(b: &dyn Brdf, wi: Vec3, rings: usize, sectors: usize) -> Vec<f64> {
    let gl = GaussLegendre::new(6);
    let sub = 6;
    let mut p = vec![0.0; rings * sectors];
    for i in 0..rings {
        // Ring i: r² ∈ [i/R, (i+1)/R] ⇔ z ∈ [√(1 − (i+1)/R), √(1 − i/R)].
        let (z0, z1) = (
            (1.0 - (i + 1) as f64 / rings as f64).max(0.0).sqrt(),
            (1.0 - i as f64 / rings as f64).sqrt(),
        );
        for j in 0..sectors {
            let (p0, p1) = (
                2.0 * PI * j as f64 / sectors as f64,
                2.0 * PI * (j + 1) as f64 / sectors as f64,
            );
            let mut acc = 0.0;
            for a in 0..sub {
                let (za, zb) = (
                    z0 + (z1 - z0) * a as f64 / sub as f64,
                    z0 + (z1 - z0) * (a + 1) as f64 / sub as f64,
                );
                for (z, wz) in gl.on(za, zb) {
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    for c in 0..sub {
                        let (pa, pb) = (
                            p0 + (p1 - p0) * c as f64 / sub as f64,
                            p0 + (p1 - p0) * (c + 1) as f64 / sub as f64,
                        );
                        for (phi, wp) in gl.on(pa, pb) {
                            let w =
                                Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                            acc += wz * wp * z * f64::from(b.eval_luminance(wi, w));
                        }
                    }
                }
            }
            p[i * sectors + j] = acc;
        }
    }
    let total: f64 = p.iter().sum();
    p.iter().map(|x| x / total).collect()
}

fn cell_of(wo: Vec3, rings: usize, sectors: usize) -> usize {
    let r2 = f64::from(wo.x * wo.x + wo.y * wo.y).min(1.0 - 1e-12);
    let phi = f64::from(wo.y).atan2(f64::from(wo.x)).rem_euclid(2.0 * PI);
    let i = ((r2 * rings as f64) as usize).min(rings - 1);
    let j = ((phi / (2.0 * PI) * sectors as f64) as usize).min(sectors - 1);
    i * sectors + j
}

/// Pearson χ² of counts against probabilities, pooling cells expected below 5; returns
/// (χ², dof, Wilson–Hilferty z). The full harness with exact p-values is the validation crate's.
fn chi2(counts: &[u64], probs: &[f64], m: u64) -> (f64, usize, f64) {
    let mut order: Vec<usize> = (0..probs.len()).collect();
    order.sort_by(|&a, &b| probs[a].total_cmp(&probs[b]));
    let (mut chi, mut cells) = (0.0, 0usize);
    let (mut pool_e, mut pool_o) = (0.0, 0.0);
    for k in order {
        let (e, o) = (probs[k] * m as f64, counts[k] as f64);
        if e < 5.0 || pool_e > 0.0 && pool_e < 5.0 {
            pool_e += e;
            pool_o += o;
            if pool_e >= 5.0 {
                chi += (pool_o - pool_e).powi(2) / pool_e;
                cells += 1;
                (pool_e, pool_o) = (0.0, 0.0);
            }
            continue;
        }
        chi += (o - e).powi(2) / e;
        cells += 1;
    }
    if pool_e > 0.0 {
        chi += (pool_o - pool_e).powi(2) / pool_e.max(1e-300);
        cells += 1;
    }
    let k = (cells - 1) as f64;
    let z = ((chi / k).cbrt() - (1.0 - 2.0 / (9.0 * k))) / (2.0 / (9.0 * k)).sqrt();
    (chi, cells - 1, z)
}

/// 10⁶ samples per (model, wi): Pearson χ² on a 24 × 48 equal-area polar grid against the
/// independent cell integrals. Reject at z > 3.72 (one-sided α = 1e-4 per test, Šidák over the
/// 152 tests of this run ≈ 1.5 %; the seeds are fixed, so the outcome is deterministic).
/// The χ² of every set and angle on the seed's orthographic map in CI; the concentric map
/// behind `--ignored` (see [`builds_terminate_with_bounded_trials_and_the_right_albedo`]).
#[test]
fn samples_follow_f_cos() {
    check_samples(DiskMap::Orthographic);
}

/// [`samples_follow_f_cos`] on the concentric map.
#[test]
#[ignore = "the concentric half: about 80 s on 2 cores; run with --ignored"]
fn samples_follow_f_cos_concentric() {
    check_samples(DiskMap::Concentric);
}

fn check_samples(map: DiskMap) {
    let (rings, sectors, m) = (24, 48, 1_000_000u64);
    let mut worst = (0.0f64, String::new());
    for (k, &(name, params)) in SETS.iter().enumerate() {
        let b = model(name, params);
        for (j, theta) in ANGLES.into_iter().enumerate() {
            let wi = dir(theta, 30.0);
            let probs = cell_probabilities(&*b, wi, rings, sectors);
            {
                let sampler = QuadtreeSampler::new(
                    &*b,
                    wi,
                    BuildConfig {
                        map,
                        ..BuildConfig::default()
                    },
                )
                .unwrap();
                let mut rng = Pcg64::seed_from_u64(100 * k as u64 + 10 * j as u64 + map as u64);
                let mut counts = vec![0u64; rings * sectors];
                let mut trials = 0u64;
                for _ in 0..m {
                    let s = sampler
                        .sample(&mut rng)
                        .expect("the rejection loop never gives up here");
                    counts[cell_of(s.wo, rings, sectors)] += 1;
                    trials += u64::from(s.trials);
                }
                assert_eq!(
                    sampler.bound_violations(),
                    0,
                    "{name} {params:?} {theta}° {map:?}: bound violations"
                );
                let (c, dof, z) = chi2(&counts, &probs, m);
                let mean_trials = trials as f64 / m as f64;
                let e_t = sampler.stats().expected_trials;
                assert!(
                    (mean_trials - e_t).abs() < 0.02 * e_t + 0.01,
                    "{name} {theta}°: mean trials {mean_trials} vs E[T] {e_t}"
                );
                if z > worst.0 {
                    worst = (
                        z,
                        format!("{name} {params:?} {theta}° {map:?}: chi2 {c:.1} dof {dof}"),
                    );
                }
                assert!(
                    z < 3.72,
                    "{name} {params:?} θi={theta}° {map:?}: χ² = {c:.1}, dof {dof}, z = {z:.2}"
                );
            }
        }
    }
    println!("worst z = {:.2} ({})", worst.0, worst.1);
}

/// The χ² above can fail: the same sampler with every bound halved is rejected.
#[test]
fn an_underestimated_bound_is_caught() {
    let b = model("phong", &["n=200", "kd=0.1"]);
    let wi = dir(45.0, 30.0);
    let (rings, sectors, m) = (24, 48, 1_000_000u64);
    let probs = cell_probabilities(&*b, wi, rings, sectors);
    let mut sampler = QuadtreeSampler::new(&*b, wi, BuildConfig::default()).unwrap();
    sampler.scale_bounds_for_testing(0.5);
    let mut rng = Pcg64::seed_from_u64(9);
    let mut counts = vec![0u64; rings * sectors];
    for _ in 0..m {
        let s = sampler.sample(&mut rng).unwrap();
        counts[cell_of(s.wo, rings, sectors)] += 1;
    }
    let (c, dof, z) = chi2(&counts, &probs, m);
    assert!(sampler.bound_violations() > 0);
    assert!(
        z > 3.72,
        "a halved bound went unnoticed by χ²: {c} dof {dof}, z {z}"
    );
    println!(
        "halved bounds: χ² = {c:.0}, dof {dof}, z = {z:.1}, violations {}",
        sampler.bound_violations()
    );
}

mod warp {
    use super::*;
    use quadtree_sampler::{DEFAULT_MIX, WarpSampler};

    /// The warp is invertible, its pdf integrates to 1 and is > 0 wherever f·cos is, and its
    /// weights average to the albedo (unbiased), for sharp and grazing cases.
    #[test]
    fn warp_is_invertible_normalised_and_unbiased() {
        for &(name, params, theta) in &[
            ("phong", &["n=1000"][..], 45.0),
            ("ward", &["alpha_x=0.05", "alpha_y=0.2"][..], 80.0),
            ("cook-torrance", &[][..], 0.0),
            ("lambert", &[][..], 30.0),
        ] {
            let b = model(name, params);
            let wi = dir(theta, 30.0);
            let w = WarpSampler::new(&*b, wi, BuildConfig::default(), DEFAULT_MIX).unwrap();
            let n = 256;
            let mut sum = 0.0;
            let mut sum2 = 0.0;
            for i in 0..n {
                for j in 0..n {
                    // Stratified: one point per cell of an n × n grid.
                    let u =
                        glam::Vec2::new((i as f32 + 0.37) / n as f32, (j as f32 + 0.61) / n as f32);
                    let s = w.sample_warp(u).expect("inside the hemisphere");
                    assert!(
                        (s.pdf - w.pdf(s.wo)).abs() <= 1e-4 * s.pdf,
                        "{name}: sampled pdf {} vs pdf() {}",
                        s.pdf,
                        w.pdf(s.wo)
                    );
                    let back = w.invert(s.wo);
                    assert!(
                        (back - u).abs().max_element() < 2e-3,
                        "{name}: {u} -> {} -> {back}",
                        s.wo
                    );
                    let y = f64::from(luminance(s.weight));
                    sum += y;
                    sum2 += y * y;
                }
            }
            let m = f64::from(n * n);
            let mean = sum / m;
            let want = quadrature_albedo(&*b, wi);
            // Stratification makes the error far smaller than iid; allow 4 iid standard errors.
            let se = ((sum2 / m - mean * mean).max(0.0) / m).sqrt();
            assert!(
                (mean - want).abs() <= 4.0 * se + 1e-3 * want,
                "{name}: warp mean weight {mean} vs albedo {want} (se {se})"
            );
            let mass =
                brdf_core::quadrature::hemisphere_integral(128, 6, |wo| f64::from(w.pdf(wo)));
            assert!((mass - 1.0).abs() < 2e-3, "{name}: pdf mass {mass}");
        }
    }

    /// `pdf()` at the f32 directions of nine points of every leaf, its centre and eight an
    /// eighth of its side from its edges, is that leaf's density (its mean times its shape
    /// where the direction maps back to): the direction is mapped
    /// back to the square in f64, which moves a point by 6.7·10⁻⁸ at most (the f32 map moved
    /// them by up to 2.4·10⁻⁷ near the rim, where these leaves are 1.9·10⁻⁶ wide). Cook–Torrance m = 0.001 at 89.9° puts
    /// 95 % of its mass within 10⁻⁵ of the square's edge, where the f32 map (r = √(x² + y²)
    /// in f32) placed directions in the wrong leaves: its pdf integrated to 0.922 over the
    /// mirror's cell of a 25 × 25 grid, where the samples put 0.950, and a χ² of the samples
    /// against their own pdf was 28 231 on 525 dof.
    #[test]
    fn the_warp_pdf_finds_every_leaf_from_its_points() {
        const AT: [f64; 3] = [0.125, 0.5, 0.875];
        for &(name, params, theta, phi) in &[
            ("cook-torrance", &["m=0.001"][..], 89.9, 0.0),
            ("ward", &["alpha_x=0.001"][..], 88.0, 200.0),
            ("phong", &["n=1000"][..], 45.0, 30.0),
        ] {
            let b = model(name, params);
            let w = WarpSampler::new(&*b, dir(theta, phi), BuildConfig::default(), DEFAULT_MIX)
                .unwrap();
            let (volume, mix) = (w.tree().volume(), w.mix());
            let j = f64::from(DiskMap::Concentric.square_area_per_projected_solid_angle());
            let mut wrong = 0;
            let mut points = 0;
            let mut shaped = 0;
            for (i, n) in w.tree().leaves() {
                let r = n.rect();
                let q = (1.0 - mix) * n.v1 / volume + mix * r.area() / 4.0;
                let shape = w.leaf_shape(i);
                shaped += usize::from(!shape.is_flat());
                for k in 0..9 {
                    let t = glam::DVec2::new(AT[k % 3], AT[k / 3]);
                    let Some(d) = DiskMap::Concentric.square_to_direction_f64(r.min + t * r.side())
                    else {
                        continue;
                    };
                    let wo = d.as_vec3();
                    if wo.z <= 0.0 {
                        continue;
                    }
                    points += 1;
                    let back = DiskMap::Concentric
                        .direction_to_square_f64(brdf_core::geometry::normalize_f64(wo.as_dvec3()));
                    let at = (back - r.min) / r.side();
                    let want = q / r.area() * shape.value(at) / shape.mean() * j * f64::from(wo.z);
                    let got = f64::from(w.pdf(wo));
                    if (got - want).abs() > 1e-5 * want {
                        wrong += 1;
                    }
                }
            }
            assert_eq!(wrong, 0, "{name}: {wrong} of {points} points found wrongly");
            assert!(shaped > 0, "{name}: no leaf shaped");
        }
    }

    /// A warp sample's pdf is `pdf()` of the f32 direction it returns, bit for bit, even
    /// where rounding that direction carries it out of the leaf it was drawn in: a
    /// Cook–Torrance lobe of m = 0.001 at 89.9° lies at the rim in leaves 1.9·10⁻⁶ wide, and
    /// 1 142 of these 2·10⁵ samples cross an edge (with the f32 map back, 4 % did, and the
    /// sampled pdf then differed from `pdf(wo)` by up to 3×). The uniform-area share of the
    /// mix reaches every leaf, so the regular cases are checked too.
    #[test]
    fn sampled_pdf_is_the_pdf_of_the_returned_direction() {
        for &(name, params, theta, phi) in &[
            ("cook-torrance", &["m=0.001"][..], 89.9, 303.6),
            ("ward", &["alpha_x=0.001"][..], 60.0, 10.0),
            ("phong", &["n=1000"][..], 45.0, 30.0),
        ] {
            let b = model(name, params);
            let wi = dir(theta, phi);
            let w = WarpSampler::new(&*b, wi, BuildConfig::default(), DEFAULT_MIX).unwrap();
            let mut rng = Pcg64::seed_from_u64(5);
            let mut moved = 0;
            for _ in 0..200_000 {
                let u = glam::Vec2::new(
                    quadtree_sampler::uniform_f32(&mut rng),
                    quadtree_sampler::uniform_f32(&mut rng),
                );
                let Some(s) = w.sample_warp(u) else { continue };
                let (p, leaf) = w.warp_to_square(u.as_dvec2());
                let q = DiskMap::Concentric
                    .direction_to_square_f64(brdf_core::geometry::normalize_f64(s.wo.as_dvec3()));
                if w.tree().leaf_at(q) != leaf {
                    moved += 1;
                }
                assert_eq!(
                    s.pdf.to_bits(),
                    w.pdf(s.wo).to_bits(),
                    "{name} at u = {u}: point {p} in leaf {leaf}, direction {} in leaf {}",
                    s.wo,
                    w.tree().leaf_at(q)
                );
            }
            // The case the test is for still occurs (else it checks nothing new).
            if name == "cook-torrance" {
                assert!(moved > 500, "only {moved} samples left their leaf");
            }
        }
    }
}

mod random {
    use super::*;
    use brdf_core::{ParamKind, ParamValue};
    use proptest::prelude::*;

    /// A random non-delta model with random valid parameters (log-uniform exponents).
    fn model_strategy() -> impl Strategy<Value = Box<dyn Brdf>> {
        let n = registry::models().len();
        (
            0..n,
            proptest::collection::vec((0.0f32..=1.0, 0.0f32..=1.0, 0.0f32..=1.0), 8),
        )
            .prop_filter_map("delta or constraint", |(i, draws)| {
                let info = &registry::models()[i];
                // A measured model needs a file: its own suite gives it one.
                if info.delta || info.measured {
                    return None;
                }
                let mut p = info.defaults();
                for (spec, (a, b, c)) in info.params.iter().zip(draws) {
                    let lerp = |t: f32| {
                        if spec.max / spec.min.max(1e-3) > 1e3 {
                            ((spec.max.min(1e4) + 1.0).ln() * t).exp() - 1.0
                        } else {
                            spec.min + (spec.max - spec.min) * t
                        }
                        .clamp(spec.min, spec.max)
                    };
                    let v = match spec.kind {
                        ParamKind::Scalar => ParamValue::Scalar(lerp(a)),
                        ParamKind::Rgb => ParamValue::Rgb(Vec3::new(lerp(a), lerp(b), lerp(c))),
                        ParamKind::Path | ParamKind::Choice(_) => continue,
                    };
                    p.set(spec.name, v).ok()?;
                }
                info.build(&p).ok()
            })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, rng_seed: proptest::test_runner::RngSeed::Fixed(16), ..ProptestConfig::default() })]

        /// Any model, any valid parameters, any wi above the horizon (grazing included), either
        /// map: the build terminates within budget with E[T] ≤ 2, and 20 000 samples meet no
        /// bound violation and carry the pdf that `pdf` reports.
        #[test]
        fn any_build_terminates_and_samples_exactly(
            b in model_strategy(),
            cos_t in prop_oneof![0.0f32..1.0, 1e-4f32..1e-2],
            phi in 0.0f32..std::f32::consts::TAU,
            concentric in any::<bool>(),
            seed in any::<u64>(),
        ) {
            let s = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let wi = Vec3::new(s * phi.cos(), s * phi.sin(), cos_t.max(1e-4));
            let map = if concentric { DiskMap::Concentric } else { DiskMap::Orthographic };
            let q = QuadtreeSampler::new(&*b, wi, BuildConfig { map, ..BuildConfig::default() }).unwrap();
            let st = q.stats();
            prop_assert!(!st.budget_exhausted && st.expected_trials <= 2.0, "{} {:?}: {st:?}", b.name(), b.params());
            let mut rng = Pcg64::seed_from_u64(seed);
            for _ in 0..20_000 {
                if let Some(x) = q.sample(&mut rng) {
                    prop_assert!((x.pdf - q.pdf(x.wo)).abs() <= 1e-6 * x.pdf);
                }
            }
            prop_assert_eq!(q.bound_violations(), 0, "{} {:?} wi {}", b.name(), b.params(), wi);
        }
    }
}

/// The Codificador (a `Frame` and a `DiskMap`): world → square → world round-trips through
/// a tilted frame, and `refleja` refuses a `wi` on the wrong side of the normal.
#[test]
fn codificador_round_trips_world_directions() {
    use brdf_core::Frame;
    let n = Vec3::new(0.3, -0.5, 0.8).normalize();
    let wi = (n + Vec3::new(0.2, 0.4, 0.1)).normalize();
    let frame = Frame::from_normal(n).unwrap();
    assert!((frame.to_world(frame.to_local(wi)) - wi).length() < 1e-6);
    for map in [DiskMap::Orthographic, DiskMap::Concentric] {
        for k in 0..50 {
            let local = dir(80.0 * k as f64 / 50.0, 7.3 * k as f64);
            let w = frame.to_world(local);
            let square = map.direction_to_square(frame.to_local(w));
            let back = frame.to_world(map.square_to_direction(square).unwrap());
            assert!((back - w).length() < 1e-4, "{map:?}: {w} -> {back}");
        }
    }
    let lambert = registry::create("lambert", [] as [&str; 0]).unwrap();
    let mut rng = Pcg64::seed_from_u64(3);
    assert!(refleja(&*lambert, -n, n, &mut rng).is_err());
    let s = quadtree_sampler::refleja(&*lambert, wi, n, &mut rng)
        .unwrap()
        .unwrap();
    assert!(s.wo.dot(n) > 0.0 && (s.wo.length() - 1.0).abs() < 1e-5);
}

/// Target mode splits no more than the target needs: asked for an E\[T\] just below the seed
/// tree's, it adds a split or a few, not a whole batch of 16 (64 nodes), as batching by a
/// fixed count did.
#[test]
fn a_target_just_below_the_seed_trees_adds_a_few_splits() {
    for (name, params) in [
        ("phong", &["n=1000", "kd=0"][..]),
        ("ward", &["alpha_x=0.05", "alpha_y=0.05", "kd=0"][..]),
        ("cook-torrance", &["m=0.1"][..]),
    ] {
        let b = model(name, params);
        let wi = dir(45.0, 30.0);
        let seed = Quadtree::new(&*b, wi, BuildConfig::default()).unwrap();
        let before = seed.stats();
        let target = before.expected_trials - 0.005;
        let refined = Quadtree::new(&*b, wi, BuildConfig::with_target_trials(target)).unwrap();
        let after = refined.stats();
        assert!(after.expected_trials <= target, "{name}: {after:?}");
        assert!(
            before.leaves >= 64,
            "{name}: a tree too small to tell: {before:?}"
        );
        let added = after.nodes - before.nodes;
        assert!(
            added > 0 && added <= 16,
            "{name}: {added} nodes added for E[T] {} → {target}",
            before.expected_trials
        );
    }
}

/// Height shapes (`proposal::Shape`) cut the trials the seed's flat boxes waste on a lobe
/// that leans across a leaf, without changing which nodes the seed's rule splits.
/// Schlick at normal incidence is one polar leaf on either map (the concentric map's rings
/// are squares, which no bilinear shape over the square follows): its f falls with r² and
/// climbs again in the last sliver before the rim. Flat, E[T] was 1.395; shaped, it stays
/// one leaf and E[T] ≤ 1.25 (target mode's goal) with no bound violation in 200 000
/// samples. Oren–Nayar at θ = 45° leans toward wi: one shaped leaf on either map, E[T]
/// ≤ 1.25 (flat: 1.274). Cook–Torrance at normal incidence on the concentric map (277
/// nodes) keeps its node count, and its E[T] (1.89 flat) falls under 1.5.
#[test]
fn shaped_leaves_cut_trials_on_the_seed_trees() {
    let one_shaped_leaf = |name: &str, wi: Vec3, map: DiskMap| {
        let brdf = model(name, &[]);
        let config = BuildConfig {
            map,
            ..BuildConfig::default()
        };
        let s = QuadtreeSampler::new(&*brdf, wi, config).unwrap();
        let stats = s.tree().stats();
        assert_eq!(stats.nodes, 1, "{name} {map:?}");
        assert!(
            stats.expected_trials <= 1.25,
            "{name} {map:?}: E[T] {}",
            stats.expected_trials
        );
        let leaf = &s.tree().leaves()[0];
        assert!(!leaf.proposal.shape.is_flat(), "{name} {map:?}");
        let mut rng = Pcg64::seed_from_u64(8);
        for _ in 0..200_000 {
            s.sample(&mut rng).unwrap();
        }
        assert_eq!(s.bound_violations(), 0, "{name} {map:?}");
    };
    let oblique = Vec3::new(0.5f32.sqrt(), 0.0, 0.5f32.sqrt());
    for map in [DiskMap::Orthographic, DiskMap::Concentric] {
        one_shaped_leaf("schlick", Vec3::Z, map);
        one_shaped_leaf("oren-nayar", oblique, map);
    }

    let ct = model("cook-torrance", &[]);
    let config = BuildConfig {
        map: DiskMap::Concentric,
        ..BuildConfig::default()
    };
    let s = QuadtreeSampler::new(&*ct, Vec3::Z, config).unwrap();
    let stats = s.tree().stats();
    assert_eq!(stats.nodes, 277);
    assert!(
        stats.expected_trials < 1.5,
        "E[T] {}",
        stats.expected_trials
    );
    assert!(
        s.tree()
            .leaves()
            .iter()
            .any(|l| !l.proposal.shape.is_flat())
    );
}

/// Every node's v1 and bound, as bits: two trees compared node for node.
fn node_bits(t: &Quadtree) -> Vec<(u64, u64)> {
    t.nodes()
        .iter()
        .map(|n| (n.v1.to_bits(), n.bound.to_bits()))
        .collect()
}

/// A model's own integration tolerance (`Brdf::integration_tolerance`) loosens the build's
/// where it is larger, up to 10⁻³; a NaN, negative or smaller one changes nothing. The trees
/// are compared node for node (v1 and bound bits).
#[test]
fn a_models_integration_tolerance_is_used_within_its_limit() {
    #[derive(Debug)]
    struct Loose(Box<dyn Brdf>, f64);
    impl Brdf for Loose {
        fn name(&self) -> &'static str {
            self.0.name()
        }
        fn params(&self) -> brdf_core::ParamSet {
            self.0.params()
        }
        fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
            self.0.eval(wi, wo)
        }
        fn peak_hints(&self, wi: Vec3) -> brdf_core::PeakHints {
            self.0.peak_hints(wi)
        }
        fn symmetry(&self) -> brdf_core::Symmetry {
            self.0.symmetry()
        }
        fn integration_tolerance(&self) -> f64 {
            self.1
        }
    }
    let wi = dir(40.0, 20.0);
    let build = |tolerance: f64, config: f64| {
        let b = Loose(model("phong", &["n=200"]), tolerance);
        let cfg = BuildConfig {
            integration_tolerance: config,
            ..BuildConfig::default()
        };
        node_bits(&Quadtree::new(&b, wi, cfg).unwrap())
    };
    let plain = build(0.0, 1e-6);
    for t in [f64::NAN, -1.0, 1e-9, 1e-6] {
        assert!(build(t, 1e-6) == plain, "tolerance {t} changed the tree");
    }
    let loose = build(0.0, 1e-4);
    assert!(
        loose != plain,
        "1e-4 integrates as 1e-6 does: the test has no power"
    );
    assert!(build(1e-4, 1e-6) == loose);
    let loosest = build(0.0, 1e-3);
    for t in [1e-3, 0.5, f64::INFINITY] {
        assert!(
            build(t, 1e-6) == loosest,
            "tolerance {t} is not capped at 1e-3"
        );
    }
    // The cap limits the model, not the configuration.
    assert!(build(0.5, 1e-2) == build(0.0, 1e-2));
}

/// A build its evaluation budget stops is built again to `RETRY_TOLERANCE`, then
/// `LAST_RETRY_TOLERANCE`, and the first complete tree is kept: over a range of budgets,
/// every build is an error, the tree at its own tolerance, or (where the budget stopped 10⁻⁶
/// but not 10⁻⁴) the complete 10⁻⁴ tree, or (where it stopped 10⁻⁴ too) the complete 10⁻³
/// tree, node for node; serial and parallel agree, and both retries happen in the range.
#[test]
fn a_build_the_evaluation_budget_stops_is_retried_looser() {
    let b = model("phong", &["n=1000", "kd=0"]);
    let wi = dir(45.0, 30.0);
    let cfg = |budget: u64, tolerance: f64, parallel: bool| BuildConfig {
        evaluation_budget: budget,
        integration_tolerance: tolerance,
        parallel,
        ..BuildConfig::default()
    };
    // Each retry's tolerance, its complete tree, and how many budgets ended there.
    let mut retries = [RETRY_TOLERANCE, LAST_RETRY_TOLERANCE].map(|tolerance| {
        let tree = Quadtree::new(&*b, wi, cfg(1 << 28, tolerance, false)).unwrap();
        assert!(!tree.budget_exhausted());
        (tolerance, tree, 0)
    });
    for k in 56..80u32 {
        // Budgets 2^(k/4): 2^14 to 2^19.75.
        let budget = (2f64.powf(f64::from(k) / 4.0)) as u64;
        let serial = Quadtree::new(&*b, wi, cfg(budget, 1e-6, false));
        let parallel = Quadtree::new(&*b, wi, cfg(budget, 1e-6, true));
        match (&serial, &parallel) {
            (Ok(s), Ok(p)) => {
                assert!(
                    node_bits(s) == node_bits(p),
                    "budget {budget}: serial != parallel"
                );
                assert_eq!(s.integration_tolerance(), p.integration_tolerance());
                let tolerance = s.integration_tolerance();
                match retries.iter_mut().find(|r| r.0 == tolerance) {
                    Some((_, tree, count)) => {
                        assert!(
                            !s.budget_exhausted(),
                            "budget {budget}: kept an exhausted retry to {tolerance:e}"
                        );
                        assert!(
                            node_bits(s) == node_bits(tree),
                            "budget {budget}: not the complete {tolerance:e} tree"
                        );
                        *count += 1;
                    }
                    None => assert_eq!(tolerance, 1e-6),
                }
            }
            (Err(_), Err(_)) => {}
            _ => panic!("budget {budget}: serial and parallel differ in success"),
        }
    }
    let [retried, last_retried] = retries.map(|r| r.2);
    println!("{retried} budgets retried to 1e-4, {last_retried} to 1e-3");
    assert!(
        retried > 0 && last_retried > 0,
        "no budget stopped 1e-6 and not 1e-4, or 1e-4 and not 1e-3: the test has no power"
    );
    // A complete build is the first attempt's.
    let plain = Quadtree::new(&*b, wi, BuildConfig::default()).unwrap();
    assert_eq!(plain.integration_tolerance(), 1e-6);
    assert!(!plain.budget_exhausted());
}
