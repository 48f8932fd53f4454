//! The measured model `merl` (SPEC §8): the half/difference conversion round-trips, the bin
//! indices equal the database reader's (transcribed here on its own, with its general
//! rotation formula), a file tabulated from a model reproduces it at every bin centre, the
//! linear lookup agrees with the nearest one there, "not measured" bins are 0, the data is
//! shared, and every kind of malformed file is its own typed error.

use brdf_core::models::merl::{
    self, MERL_BINS, MERL_FILE_BYTES, bin_centre_pair, bin_index, bin_indices, encode,
    from_half_diff, half_diff,
};
use brdf_core::{Brdf, DataFault, ParamError, registry};
use glam::{DVec3, Vec3};
use rand::{RngExt, SeedableRng};
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::{Path, PathBuf};

/// A path named `name` in a directory of its own, removed with everything in it when this
/// is dropped (a tabulated MERL file is 35 MB; a run writes a dozen).
struct TempFile {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

impl std::ops::Deref for TempFile {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for TempFile {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

fn temp(name: &str) -> TempFile {
    let dir = tempfile::Builder::new()
        .prefix("brdf-merl-")
        .tempdir()
        .unwrap();
    let path = dir.path().join(name);
    TempFile { _dir: dir, path }
}

fn open(path: &Path, interp: &str) -> Result<Box<dyn Brdf>, ParamError> {
    let file = format!("file={}", path.display());
    let interp = format!("interp={interp}");
    registry::create("merl", [file.as_str(), interp.as_str()])
}

fn fault(path: &Path) -> DataFault {
    match open(path, "nearest") {
        Err(ParamError::Data {
            name: "file",
            error,
        }) => {
            assert_eq!(error.path, path.display().to_string());
            error.fault
        }
        other => panic!("{}: {other:?}", path.display()),
    }
}

/// The database reader's own arithmetic (BRDFRead.cpp), transcribed independently: spherical
/// angles in, Rodrigues rotations, the three index formulas.
mod reader {
    use std::f64::consts::PI;

    fn rotate(v: [f64; 3], axis: [f64; 3], angle: f64) -> [f64; 3] {
        let (c, s) = (angle.cos(), angle.sin());
        let dot = v[0] * axis[0] + v[1] * axis[1] + v[2] * axis[2];
        let cross = [
            axis[1] * v[2] - axis[2] * v[1],
            axis[2] * v[0] - axis[0] * v[2],
            axis[0] * v[1] - axis[1] * v[0],
        ];
        [0, 1, 2].map(|k| v[k] * c + axis[k] * dot * (1.0 - c) + cross[k] * s)
    }

    /// std_coords_to_half_diff_coords.
    pub fn half_diff(ti: f64, pi: f64, to: f64, po: f64) -> (f64, f64, f64) {
        let i = [ti.sin() * pi.cos(), ti.sin() * pi.sin(), ti.cos()];
        let o = [to.sin() * po.cos(), to.sin() * po.sin(), to.cos()];
        let mut h = [i[0] + o[0], i[1] + o[1], i[2] + o[2]];
        let n = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
        h = h.map(|x| x / n);
        let theta_half = h[2].acos();
        let phi_half = h[1].atan2(h[0]);
        let temp = rotate(i, [0.0, 0.0, 1.0], -phi_half);
        let diff = rotate(temp, [0.0, 1.0, 0.0], -theta_half);
        (theta_half, diff[2].acos(), diff[1].atan2(diff[0]))
    }

    pub fn index(theta_half: f64, theta_diff: f64, phi_diff: f64) -> usize {
        let th = if theta_half <= 0.0 {
            0
        } else {
            let t = theta_half / (PI / 2.0) * 90.0;
            ((t * 90.0).sqrt() as i64).clamp(0, 89) as usize
        };
        let td = ((theta_diff / (PI * 0.5) * 90.0) as i64).clamp(0, 89) as usize;
        let pd = {
            let p = if phi_diff < 0.0 {
                phi_diff + PI
            } else {
                phi_diff
            };
            ((p / PI * 180.0) as i64).clamp(0, 179) as usize
        };
        pd + td * 180 + th * 180 * 90
    }
}

#[test]
fn half_diff_round_trips() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
    for _ in 0..10_000 {
        let th = rng.random_range(0.0..FRAC_PI_2);
        let ph = rng.random_range(-PI..PI);
        let td = rng.random_range(0.0..FRAC_PI_2);
        let pd = rng.random_range(-PI..PI);
        let (wi, wo) = from_half_diff(th, ph, td, pd);
        assert!((wi.length() - 1.0).abs() < 1e-12 && (wo.length() - 1.0).abs() < 1e-12);
        let [a, b, c, d] = half_diff(wi, wo);
        assert!((a - th).abs() < 1e-7, "θh {a} vs {th}");
        assert!((c - td).abs() < 1e-7, "θd {c} vs {td}");
        if th > 1e-6 {
            let dphi = (b - ph + 3.0 * PI).rem_euclid(2.0 * PI) - PI;
            assert!(dphi.abs() < 1e-6, "φh {b} vs {ph}");
        }
        if td > 1e-6 {
            let dphi = (d - pd + 3.0 * PI).rem_euclid(2.0 * PI) - PI;
            assert!(dphi.abs() < 1e-6, "φd {d} vs {pd}");
        }
    }
}

#[test]
fn bin_indices_equal_the_database_readers() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(2);
    let mut differ = 0;
    let n = 200_000;
    for _ in 0..n {
        let (ti, pi) = (
            rng.random_range(0.0..FRAC_PI_2),
            rng.random_range(0.0..2.0 * PI),
        );
        let (to, po) = (
            rng.random_range(0.0..FRAC_PI_2),
            rng.random_range(0.0..2.0 * PI),
        );
        let (a, b, c) = reader::half_diff(ti, pi, to, po);
        let want = reader::index(a, b, c);
        let dir = |t: f64, p: f64| DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
        let [th, _, td, pd] = half_diff(dir(ti, pi), dir(to, po));
        let got = bin_index(bin_indices(th, td, pd));
        // Both are f64 arithmetic by different formulas: a pair within ~1e-15 rad of a bin
        // edge may fall either side. Anything more is a wrong formula.
        if got != want {
            differ += 1;
        }
    }
    assert!(
        differ <= 2,
        "{differ} of {n} directions in another bin than the reader's"
    );
}

/// A model with a sharp lobe and distinct channels, tabulated; the file read back by `merl`.
fn tabulated(name: &str, model: &dyn Brdf) -> TempFile {
    let path = temp(name);
    std::fs::write(&path, encode(&merl::tabulate(model))).unwrap();
    path
}

fn merl_idx(k: usize) -> [usize; 3] {
    [k / (180 * 90), (k / 180) % 90, k % 180]
}

#[test]
fn a_tabulated_model_is_reproduced_at_every_bin_centre() {
    let model = registry::create("blinn-phong", ["n=200", "kd=0.3,0.2,0.1", "ks=0.5"]).unwrap();
    let path = tabulated("blinn.binary", &*model);
    assert_eq!(std::fs::metadata(&path).unwrap().len(), MERL_FILE_BYTES);
    let nearest = open(&path, "nearest").unwrap();
    let linear = open(&path, "linear").unwrap();
    // Nearest: the stored value of the very bin (relative 1e-6: the f32 of f / scale × scale).
    // Linear: at a centre the weights are 1 and 0 up to the f32 rounding of the directions
    // (~10⁻⁵ of a bin), so a steep lobe moves it by that share of the step to its neighbour.
    let mut worst = [0.0f32; 2];
    for k in 0..MERL_BINS {
        let (wi, wo) = bin_centre_pair(k);
        let want = model.eval(wi, wo);
        for (slot, m) in [&nearest, &linear].into_iter().enumerate() {
            let got = m.eval(wi, wo);
            if want.max_element() > 0.0 {
                let err = (got - want).abs().max_element() / want.max_element();
                worst[slot] = worst[slot].max(err);
            } else {
                assert_eq!(
                    got,
                    Vec3::ZERO,
                    "bin {k} {:?}: {got} where the model is 0",
                    merl_idx(k)
                );
            }
        }
    }
    println!(
        "worst relative error at bin centres: nearest {:e}, linear {:e}",
        worst[0], worst[1]
    );
    assert!(
        worst[0] <= 1e-6,
        "nearest: relative error {:e} at a bin centre",
        worst[0]
    );
    assert!(
        worst[1] <= 1e-2,
        "linear: relative error {:e} at a bin centre",
        worst[1]
    );
    // Away from the centres the nearest lookup is piecewise constant, the linear one not.
    let wi = Vec3::new(0.3, 0.1, 0.9).normalize();
    let wo = Vec3::new(-0.28, -0.12, 0.9).normalize();
    assert_ne!(nearest.eval(wi, wo), linear.eval(wi, wo));
    assert_eq!(
        nearest.params().text("file").unwrap(),
        path.display().to_string()
    );
    assert_eq!(linear.params().text("interp").unwrap(), "linear");
}

#[test]
fn unmeasured_bins_are_zero_and_the_data_is_shared() {
    let model = registry::create("lambert", ["albedo=0.5"]).unwrap();
    let mut f = merl::tabulate(&*model);
    // "Not measured" at every bin with θd beyond 80°.
    for (k, v) in f.iter_mut().enumerate() {
        if (k / 180) % 90 >= 80 {
            *v = [-1.0; 3];
        }
    }
    let path = temp("holes.binary");
    std::fs::write(&path, encode(&f)).unwrap();
    let a = open(&path, "nearest").unwrap();
    let b = open(&path, "linear").unwrap();
    let (wi, wo) = (Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.6, 0.0, 0.8));
    assert!(
        (a.eval(wi, wo) - Vec3::splat(0.5 / std::f32::consts::PI))
            .abs()
            .max_element()
            < 1e-6
    );
    let grazing = (Vec3::new(0.999, 0.0, 0.04), Vec3::new(-0.999, 0.0, 0.04));
    assert_eq!(a.eval(grazing.0, grazing.1), Vec3::ZERO);
    for v in a.eval(grazing.0, grazing.1).to_array() {
        assert!(v.is_finite());
    }
    // Opening the same unchanged file twice holds its data once.
    let data = |b: &dyn Brdf| {
        let m = registry::create("merl", [format!("file={}", path.display()).as_str()]).unwrap();
        let _ = b;
        m.eval(wi, wo)
    };
    assert_eq!(data(&*a), data(&*b));
    let m1 = brdf_core::models::Merl::from_params(&a.params()).unwrap();
    let m2 = brdf_core::models::Merl::from_params(&b.params()).unwrap();
    assert!(std::sync::Arc::ptr_eq(m1.data(), m2.data()));
    assert_eq!(m1.data().unmeasured(), 3 * 90 * 10 * 180);
}

#[test]
fn every_malformed_file_is_its_own_typed_error() {
    let good = encode(&vec![[0.1, 0.2, 0.3]; MERL_BINS]);
    let write = |name: &str, bytes: &[u8]| {
        let p = temp(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    // Missing, a directory, empty, a short header.
    assert_eq!(fault(&temp("does-not-exist.binary")), DataFault::Missing);
    assert_eq!(fault(&std::env::temp_dir()), DataFault::Directory);
    // A device is refused before any read (/dev/zero would read 35 MB, a pipe could block).
    #[cfg(unix)]
    for device in ["/dev/null", "/dev/zero"] {
        assert_eq!(fault(Path::new(device)), DataFault::NotRegular, "{device}");
    }
    // A file far larger than the format (sparse: nothing on disk) is refused from its
    // size, without reading or allocating for it.
    let huge = temp("huge.binary");
    std::fs::File::create(&huge)
        .unwrap()
        .set_len(1 << 36)
        .unwrap();
    assert!(matches!(
        fault(&huge),
        DataFault::WrongSize { bytes, .. } if bytes == 1 << 36
    ));
    std::fs::remove_file(&huge).unwrap();
    assert!(matches!(
        fault(&write("empty.binary", &[])),
        DataFault::Truncated { bytes: 0, .. }
    ));
    assert!(matches!(
        fault(&write("header.binary", &good[..7])),
        DataFault::Truncated { bytes: 7, .. }
    ));
    // Truncated after the header, and one byte short.
    for cut in [12, 1000, good.len() - 1] {
        match fault(&write("cut.binary", &good[..cut])) {
            DataFault::Truncated { bytes, expected } => {
                assert_eq!((bytes, expected), (cut as u64, MERL_FILE_BYTES));
            }
            f => panic!("cut at {cut}: {f:?}"),
        }
    }
    // Trailing bytes.
    let mut long = good.clone();
    long.extend_from_slice(&[0; 8]);
    assert!(matches!(
        fault(&write("long.binary", &long)),
        DataFault::WrongSize { .. }
    ));
    // Wrong dimensions (also a file of another resolution, whatever its size).
    let mut dims = good.clone();
    dims[8..12].copy_from_slice(&360i32.to_le_bytes());
    assert_eq!(
        fault(&write("dims.binary", &dims)),
        DataFault::Dimensions {
            found: [90, 90, 360]
        }
    );
    let small = [[90i32, 90, 90]]
        .concat()
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect::<Vec<_>>();
    assert!(matches!(
        fault(&write("small.binary", &small)),
        DataFault::Dimensions { .. }
    ));
    // NaN and infinity, in each channel.
    for (channel, bad) in [(0u8, f64::NAN), (1, f64::INFINITY), (2, f64::NEG_INFINITY)] {
        let mut b = good.clone();
        let bin = 12_345u32;
        let at = 12 + 8 * (usize::from(channel) * MERL_BINS + bin as usize);
        b[at..at + 8].copy_from_slice(&bad.to_le_bytes());
        assert_eq!(
            fault(&write("nan.binary", &b)),
            DataFault::NotFinite { channel, bin }
        );
    }
    // No file at all, and a bad choice.
    assert!(matches!(
        registry::create("merl", []),
        Err(ParamError::Required {
            model: "merl",
            name: "file"
        })
    ));
    let p = write("ok.binary", &good);
    assert!(matches!(
        open(&p, "cubic"),
        Err(ParamError::BadValue { name: "interp", .. })
    ));
    let m = open(&p, "nearest").unwrap();
    let f = m.eval(Vec3::Z, Vec3::new(0.6, 0.0, 0.8));
    assert!(
        (f.x - 0.1_f32).abs() < 1e-7 && (f.z - 0.3_f32).abs() < 1e-7,
        "{f}"
    );
    // Every error message names the file.
    let e = open(&temp("does-not-exist.binary"), "nearest")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("does-not-exist.binary") && e.contains("no such file"),
        "{e}"
    );
}

/// Isotropy and reciprocity, as declared, hold by evaluation (linear lookup: continuous, so
/// a rotation's rounding cannot move a value across a bin edge).
#[test]
fn declared_symmetries_hold_by_evaluation() {
    let model = registry::create("ward", ["alpha_x=0.2", "alpha_y=0.2"]).unwrap();
    let path = tabulated("ward.binary", &*model);
    let m = open(&path, "linear").unwrap();
    let s = m.symmetry();
    assert!(s.isotropic && s.reciprocal);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
    let dir = |rng: &mut rand_pcg::Pcg64| {
        let (t, p) = (
            rng.random_range(0.05..1.4f32),
            rng.random_range(0.0..std::f32::consts::TAU),
        );
        Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    };
    for _ in 0..2000 {
        let (wi, wo) = (dir(&mut rng), dir(&mut rng));
        let f = m.eval(wi, wo);
        let g = m.eval(wo, wi);
        let rot = glam::Quat::from_rotation_z(rng.random_range(0.0..std::f32::consts::TAU));
        let h = m.eval(rot * wi, rot * wo);
        let tol = 1e-3 * f.max_element() + 1e-6;
        assert!((f - g).abs().max_element() <= tol, "reciprocity {f} {g}");
        assert!((f - h).abs().max_element() <= tol, "isotropy {f} {h}");
    }
}
