//! The one sampler factory ([`AnySampler`]) and the explicit-uniform surface every sampler
//! shares ([`DirectionSampler::sample_with`]): every mode builds from an owned model and is
//! `'static + Send + Sync`, the sample's pdf is the sampler's `pdf`, the caller's uniforms
//! drive the structure (the same numbers give the same sample; samplers without rejection
//! draw nothing else), and `sample(rng)` keeps the historic draw order the CLI's fixed-seed
//! outputs depend on.

use brdf_core::{Brdf, registry};
use glam::{Vec2, Vec3};
use quadtree_sampler::{
    AnySampler, BakeConfig, BakedSampler, BuildConfig, BuildError, DirectionSampler,
    QuadtreeSampler, SamplerMode, descent_uniform, uniform_f32, uniform_f64,
};
use rand_core::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::sync::Arc;

fn model(name: &str, params: &[&str]) -> Arc<dyn Brdf> {
    registry::create(name, params.iter().copied())
        .unwrap()
        .into()
}

fn wi() -> Vec3 {
    Vec3::new(0.5, 0.2, 0.8).normalize()
}

fn owned(mode: SamplerMode) -> AnySampler {
    AnySampler::new(
        model("ward", &["alpha_x=0.1", "alpha_y=0.3"]),
        wi(),
        mode,
        BuildConfig::default(),
    )
    .unwrap()
}

/// A bake of `brdf` with `theta_steps` rows (the other options default).
fn small_bake(brdf: Arc<dyn Brdf>, theta_steps: u16) -> Arc<BakedSampler> {
    Arc::new(
        BakedSampler::new(
            brdf,
            BakeConfig {
                theta_steps,
                ..BakeConfig::default()
            },
        )
        .unwrap(),
    )
}

fn is_static_send_sync<T: 'static + Send + Sync>(_: &T) {}

#[test]
fn every_mode_builds_from_an_owned_model_and_reports_its_own_pdf() {
    for mode in SamplerMode::ALL {
        let s = owned(mode);
        is_static_send_sync(&s);
        assert_eq!(s.name(), mode.name());
        assert_eq!(s.tree_stats().is_some(), mode.builds_tree(), "{mode:?}");
        let mut rng = Pcg64::seed_from_u64(3);
        let mut drawn = 0;
        for _ in 0..2000 {
            let Some(x) = s.sample(&mut rng) else {
                continue;
            };
            drawn += 1;
            let p = s.pdf(x.wo);
            assert!(
                (x.pdf - p).abs() <= 1e-4 * p,
                "{mode:?}: sample pdf {} != pdf {p} at {:?}",
                x.pdf,
                x.wo
            );
            let w = x.f * (x.wo.z / x.pdf);
            assert!((x.weight - w).abs().max_element() <= 1e-5 * w.max_element());
        }
        assert!(drawn > 1900, "{mode:?}: only {drawn} of 2000 samples");
    }
}

#[test]
fn mode_names_round_trip_and_unknown_names_are_none() {
    for mode in SamplerMode::ALL {
        assert_eq!(SamplerMode::from_name(mode.name()), Some(mode));
    }
    assert_eq!(SamplerMode::from_name("Rejection"), None);
    assert_eq!(SamplerMode::from_name(""), None);
}

#[test]
fn a_delta_model_and_a_bad_direction_are_typed_errors_in_every_mode() {
    let mirror = model("mirror", &[]);
    for mode in SamplerMode::ALL {
        let e = AnySampler::new(mirror.clone(), wi(), mode, BuildConfig::default()).unwrap_err();
        assert!(matches!(e, BuildError::DeltaModel { .. }), "{mode:?}: {e}");
        for bad in [Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), Vec3::splat(f32::NAN)] {
            let e = AnySampler::new(model("lambert", &[]), bad, mode, BuildConfig::default())
                .unwrap_err();
            assert!(matches!(e, BuildError::Direction(_)), "{mode:?} {bad}: {e}");
        }
    }
}

/// The caller's uniforms drive the structure: the same (uc, u) and RNG state give the same
/// sample; modes without rejection draw nothing from the RNG; different u reach different
/// parts of the lobe.
#[test]
fn explicit_uniforms_drive_every_sampler() {
    for mode in SamplerMode::ALL {
        let s = owned(mode);
        let mut spread = Vec::new();
        for k in 0..64u32 {
            let uc = (k as f32 + 0.5) / 64.0;
            let u = Vec2::new(
                ((k * 37) % 64) as f32 / 64.0 + 0.007,
                (k as f32 + 0.25) / 64.0,
            );
            let (mut a, mut b) = (
                Pcg64::seed_from_u64(k.into()),
                Pcg64::seed_from_u64(k.into()),
            );
            let x = s.sample_with(uc, u, &mut a);
            let y = s.sample_with(uc, u, &mut b);
            assert_eq!(x, y, "{mode:?}");
            if mode != SamplerMode::Rejection {
                let mut fresh = Pcg64::seed_from_u64(k.into());
                assert_eq!(a.next_u64(), fresh.next_u64(), "{mode:?} drew from the RNG");
            }
            if let Some(x) = x {
                spread.push(x.wo);
            }
        }
        let distinct = spread
            .iter()
            .enumerate()
            .filter(|(i, w)| spread[..*i].iter().all(|v| (*v - **w).length() > 1e-4))
            .count();
        assert!(
            distinct > 48,
            "{mode:?}: only {distinct} distinct directions of 64"
        );
    }
}

/// `sample(rng)` keeps the draw order of before `sample_with` existed: the quadtree descends
/// with one 53-bit uniform, the baselines draw uc, u.x, u.y as 24-bit uniforms.
#[test]
fn sampling_from_an_rng_keeps_the_historic_draw_order() {
    let b = model("phong", &["n=200"]);
    let q = QuadtreeSampler::new(b.clone(), wi(), BuildConfig::default()).unwrap();
    let any = AnySampler::new(
        b.clone(),
        wi(),
        SamplerMode::Rejection,
        BuildConfig::default(),
    )
    .unwrap();
    let (mut r1, mut r2, mut r3) = (
        Pcg64::seed_from_u64(9),
        Pcg64::seed_from_u64(9),
        Pcg64::seed_from_u64(9),
    );
    for _ in 0..500 {
        let a = q.sample(&mut r1);
        let d = uniform_f64(&mut r2);
        let c = q.sample_from(d, &mut r2);
        let e = DirectionSampler::sample(&any, &mut r3);
        assert_eq!(a, c);
        assert_eq!(a, e);
    }
    let base = AnySampler::new(b, wi(), SamplerMode::Analytic, BuildConfig::default()).unwrap();
    let (mut r1, mut r2) = (Pcg64::seed_from_u64(5), Pcg64::seed_from_u64(5));
    for _ in 0..500 {
        let a = base.sample(&mut r1);
        let uc = uniform_f32(&mut r2);
        let u = Vec2::new(uniform_f32(&mut r2), uniform_f32(&mut r2));
        assert_eq!(a, base.sample_with(uc, u, &mut r2));
    }
}

#[test]
fn the_descent_uniform_refines_and_stays_below_one() {
    assert_eq!(descent_uniform(Vec2::ZERO), 0.0);
    let top = descent_uniform(Vec2::splat(1.0 - f32::EPSILON / 2.0));
    assert!(top < 1.0);
    assert!(descent_uniform(Vec2::new(0.5, 0.5)) > 0.5);
    assert!(descent_uniform(Vec2::new(0.5, 0.5)) < 0.5 + 1.0 / 16_777_216.0);
    assert!(descent_uniform(Vec2::splat(f32::NAN)) < 1.0);
    assert!(descent_uniform(Vec2::splat(2.0)) < 1.0);
    assert!(descent_uniform(Vec2::splat(-1.0)) >= 0.0);
}

#[test]
fn a_bake_through_the_factory_is_the_bake_at_that_wi() {
    let bake = small_bake(model("blinn-phong", &["n=50"]), 6);
    let s = AnySampler::<Arc<dyn Brdf>>::baked(bake.clone(), wi()).unwrap();
    is_static_send_sync(&s);
    assert!(s.bake().is_some());
    assert!(s.bound_violations().is_some());
    let mut rng = Pcg64::seed_from_u64(1);
    for _ in 0..300 {
        if let Some(x) = s.sample(&mut rng) {
            assert_eq!(x.pdf, bake.pdf_continuous(wi(), x.wo).unwrap());
            assert_eq!(s.pdf(x.wo), x.pdf);
        }
    }
    assert!(AnySampler::<Arc<dyn Brdf>>::baked(bake, Vec3::new(1.0, 0.0, -0.1)).is_err());
}

/// Uniforms outside [0, 1) (a caller's bug: NaN, ±∞, −1, 2) and degenerate directions never
/// give a sample that is not a unit direction above the horizon with a finite, positive pdf
/// and a finite weight, nor a pdf that is not finite, in any mode, a bake's included. (The
/// uniform sampler returned wo = (0, 0, 2) for u.x = 2, and the table's pdf was ∞ for a
/// direction of length 10⁻³⁰, before both were fixed.)
#[test]
fn out_of_range_uniforms_and_tiny_directions_stay_finite() {
    let odd = [
        0.0f32,
        1.0 - f32::EPSILON / 2.0,
        1.0,
        -1.0,
        2.0,
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
    ];
    let bake = small_bake(model("phong", &["n=50"]), 4);
    let mut samplers: Vec<AnySampler> = SamplerMode::ALL.into_iter().map(owned).collect();
    samplers.push(AnySampler::baked(bake, wi()).unwrap());
    let mut rng = Pcg64::seed_from_u64(3);
    for s in &samplers {
        for &uc in &odd {
            for &x in &odd {
                for &y in &odd {
                    let Some(smp) = s.sample_with(uc, Vec2::new(x, y), &mut rng) else {
                        continue;
                    };
                    let what = format!("{} at ({uc}, {x}, {y}): {smp:?}", s.name());
                    assert!((smp.wo.length() - 1.0).abs() < 1e-5, "{what}");
                    assert!(smp.wo.z >= 0.0, "{what}");
                    assert!(smp.pdf.is_finite() && smp.pdf > 0.0, "{what}");
                    assert!(smp.weight.is_finite(), "{what}");
                }
            }
        }
        let w = Vec3::new(0.3, -0.2, 0.9);
        for scale in [1e-30f32, 1e-20, 1.0, 1e20] {
            let (p, q) = (s.pdf(w * scale), s.pdf(w.normalize()));
            assert!(p.is_finite(), "{} at scale {scale}: {p}", s.name());
            assert!(
                (p - q).abs() <= 1e-5 * q,
                "{} at scale {scale}: {p} vs {q}",
                s.name()
            );
        }
        for bad in [Vec3::ZERO, Vec3::NAN, Vec3::splat(f32::INFINITY), -Vec3::Z] {
            assert_eq!(s.pdf(bad), 0.0, "{} at {bad}", s.name());
        }
    }
}
