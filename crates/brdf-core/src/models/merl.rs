//! `merl`: a measured isotropic BRDF in the MERL database's binary format (Matusik, Pfister,
//! Brand & McMillan 2003; SPEC §8). The file is three little-endian i32 dimensions
//! (θh, θd, φd) = (90, 90, 180), then 3 × 90·90·180 little-endian f64 values (all red, then
//! all green, then all blue). f_r is looked up in the Rusinkiewicz half/difference angles of
//! (wi, wo): the database's own nearest-bin lookup, or trilinear interpolation between the
//! bins' centres. A negative stored value means "not measured": f_r = 0 there.
//!
//! The data is held once, as scaled f32, behind an `Arc` (17.5 MB a material; clones share
//! it, and with `std` every open of the same unchanged file shares it too).

use crate::Symmetry;
use crate::brdf::Brdf;
use crate::error::{DataError, DataFault, ParamError};
use crate::geometry::upper_pair;
use crate::math as m;
use crate::param::{ParamSet, ParamSpec, ParamValue};
use alloc::string::String;
use alloc::sync::Arc;
use alloc::vec::Vec;
use core::f64::consts::{FRAC_PI_2, PI};
use core::fmt;
use glam::{DVec3, Vec3};

/// θh bins (the database's `BRDF_SAMPLING_RES_THETA_H`).
pub const MERL_THETA_H: usize = 90;
/// θd bins.
pub const MERL_THETA_D: usize = 90;
/// φd bins over [0, π) (half of the database's `BRDF_SAMPLING_RES_PHI_D` = 360: φd is folded
/// by reciprocity).
pub const MERL_PHI_D: usize = 180;
/// Bins per channel.
pub const MERL_BINS: usize = MERL_THETA_H * MERL_THETA_D * MERL_PHI_D;
/// The exact size of a file: the header and three channels of f64.
pub const MERL_FILE_BYTES: u64 = 12 + 3 * 8 * MERL_BINS as u64;
/// The per-channel scale from stored values to f_r (red 1/1500, green 1.15/1500, blue
/// 1.66/1500), as the database's reader applies it.
pub const MERL_SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];

/// The largest f_r (1/sr, once scaled by [`MERL_SCALE`]) a file may hold: 10²⁰. A table's
/// bins are about a degree wide, so even a perfect mirror tabulated peaks near 10⁴, and the
/// sharpest models of this crate tabulated (Cook–Torrance m = 0.001 at the grazing floor)
/// near 10¹³; a larger value is a broken file, and kept, it would overflow the samplers'
/// f32 arithmetic (weights f·cos/pdf with a defensive share of 10⁻⁶, and f itself near
/// 3.4·10³⁸). A file beyond it is [`DataFault::TooLarge`].
pub const MERL_MAX_F: f64 = 1e20;

/// [`Brdf::integration_tolerance`] of the nearest-bin lookup. Its f_r is a staircase whose
/// steps the quadtree's cells cannot follow (nodes are squares of the disk, steps are curves
/// of constant θh, θd or φd), so integrals converge slowly: on the benches' measured material
/// (Cook–Torrance m = 0.1 tabulated with 3 % noise) at θi = 0°, 45° and 79°, a per-wi tree
/// to 10⁻⁶ stopped at its evaluation budget after 6–8 s with 41–149 nodes and E\[T\] up to
/// 2.35; to 10⁻⁴ it is complete (345–373 nodes, E\[T\] 1.18–1.47) in 0.33–0.49 s, to 10⁻⁵ the
/// same tree in 2.3–3.9 s, and the total volumes of the two differ by 2·10⁻⁵–2·10⁻⁴. The
/// linear lookup is continuous and converges at any tolerance (0.3–0.8 s at 10⁻⁶).
pub const NEAREST_INTEGRATION_TOLERANCE: f64 = 1e-4;

/// [`Brdf::step_width`] of the nearest-bin lookup: 1°, the width of its θd and φd bins (and
/// of its θh bins near θh = 22°; they are narrower toward the mirror direction, where a
/// tree's nodes are small anyway, and wider away from it).
pub const NEAREST_STEP_WIDTH: f64 = core::f64::consts::PI / 180.0;

/// How f_r is read from the bins.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MerlLookup {
    /// The database's reader: the bin that holds the angles.
    Nearest,
    /// Trilinear between the centres of the eight surrounding bins (θh in the database's
    /// square-root coordinate; φd periodic over [0, π)).
    Linear,
}

impl MerlLookup {
    /// The parameter's option names, in order.
    pub const NAMES: &'static [&'static str] = &["nearest", "linear"];

    /// The option's name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Nearest => "nearest",
            Self::Linear => "linear",
        }
    }
}

/// The Rusinkiewicz half/difference angles of a pair (θh, φh, θd, φd) in radians, from two
/// unit f64 directions in the local frame, exactly as the database's reader forms them:
/// h = normalise(wi + wo); d = wi rotated by −φh about the normal, then by −θh about the
/// binormal (y).
#[must_use]
pub fn half_diff(wi: DVec3, wo: DVec3) -> [f64; 4] {
    let h = (wi + wo).normalize_or_zero();
    let [theta_h, theta_d, phi_d] = half_diff_lookup(wi, h);
    [theta_h, m::atan2(h.y, h.x), theta_d, phi_d]
}

/// (θh, θd, φd) of `wi` and the unit half vector `h`: the rotations by −φh and −θh use the
/// half vector's own components as their sines and cosines (sin θh = |h_xy|, cos θh = h_z,
/// (cos φh, sin φh) = h_xy/|h_xy|), so the lookup costs two `acos` and one `atan2`.
#[inline]
fn half_diff_lookup(wi: DVec3, h: DVec3) -> [f64; 3] {
    let rho = m::sqrt(h.x * h.x + h.y * h.y);
    let (cp, sp) = if rho > 0.0 {
        (h.x / rho, h.y / rho)
    } else {
        (1.0, 0.0)
    };
    let t = DVec3::new(wi.x * cp + wi.y * sp, wi.y * cp - wi.x * sp, wi.z);
    let (st, ct) = (rho, h.z);
    let d = DVec3::new(t.x * ct - t.z * st, t.y, t.z * ct + t.x * st);
    // Above the horizon (every evaluation) h_z and d_z = wi·h are at least 0, where the
    // polynomial acos (within 5·10⁻¹³ rad of the backend's) replaces two libm calls: on
    // random pairs an evaluation went from 95.5 to 61 ns in a throughput loop, 95 to 88 ns
    // when each waits on the last; `half_diff` of other pairs keeps the backend's.
    let acos = |c: f64| {
        if c >= 0.0 {
            m::acos_nonnegative(c)
        } else {
            m::acos(c.max(-1.0))
        }
    };
    [acos(h.z), acos(d.z), m::atan2(d.y, d.x)]
}

/// The inverse of [`half_diff`]: the unit pair (wi, wo) of the angles (θh, φh, θd, φd).
#[must_use]
pub fn from_half_diff(theta_h: f64, phi_h: f64, theta_d: f64, phi_d: f64) -> (DVec3, DVec3) {
    let (sd, cd) = (m::sin(theta_d), m::cos(theta_d));
    let d = DVec3::new(sd * m::cos(phi_d), sd * m::sin(phi_d), cd);
    // Undo the rotation by −θh about y, then the one by −φh about z.
    let (st, ct) = (m::sin(theta_h), m::cos(theta_h));
    let t = DVec3::new(d.x * ct + d.z * st, d.y, d.z * ct - d.x * st);
    let (sp, cp) = (m::sin(phi_h), m::cos(phi_h));
    let wi = DVec3::new(t.x * cp - t.y * sp, t.y * cp + t.x * sp, t.z);
    let h = DVec3::new(st * cp, st * sp, ct);
    let wo = 2.0 * wi.dot(h) * h - wi;
    (wi, wo)
}

/// The database's bin indices (θh_i, θd_i, φd_i) of the angles: θh_i = ⌊√(θh/(π/2))·90⌋,
/// θd_i = ⌊θd/(π/2)·90⌋, φd folded into [0, π) (π added when negative), φd_i = ⌊φd/π·180⌋,
/// each clamped to its range.
#[must_use]
pub fn bin_indices(theta_h: f64, theta_d: f64, phi_d: f64) -> [usize; 3] {
    let clamp = |x: f64, n: usize| -> usize { if x > 0.0 { (x as usize).min(n - 1) } else { 0 } };
    let th = if theta_h > 0.0 {
        clamp(
            m::sqrt(theta_h / FRAC_PI_2) * MERL_THETA_H as f64,
            MERL_THETA_H,
        )
    } else {
        0
    };
    let td = clamp(theta_d / FRAC_PI_2 * MERL_THETA_D as f64, MERL_THETA_D);
    let pd = if phi_d < 0.0 { phi_d + PI } else { phi_d };
    let pd = clamp(pd / PI * MERL_PHI_D as f64, MERL_PHI_D);
    [th, td, pd]
}

/// The value index of a bin within one channel: φd_i + 180·θd_i + 180·90·θh_i.
#[inline]
#[must_use]
pub fn bin_index([th, td, pd]: [usize; 3]) -> usize {
    pd + MERL_PHI_D * (td + MERL_THETA_D * th)
}

/// The angles (θh, θd, φd) of a bin's centre (φh = 0): the middle of each index coordinate.
#[must_use]
pub fn bin_centre([th, td, pd]: [usize; 3]) -> [f64; 3] {
    let u = (th as f64 + 0.5) / MERL_THETA_H as f64;
    [
        u * u * FRAC_PI_2,
        (td as f64 + 0.5) / MERL_THETA_D as f64 * FRAC_PI_2,
        (pd as f64 + 0.5) / MERL_PHI_D as f64 * PI,
    ]
}

/// A parsed file: f_r per bin, RGB together (already scaled; "not measured" stored as 0), so
/// that one lookup touches one cache line rather than three 5.8 MB apart as in the file.
pub struct MerlData {
    values: Vec<[f32; 3]>,
    unmeasured: usize,
}

impl fmt::Debug for MerlData {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("MerlData")
            .field("values", &self.values.len())
            .field("unmeasured", &self.unmeasured)
            .finish()
    }
}

impl MerlData {
    /// Parses a whole file's bytes (see the module doc), checking the header, the size and
    /// that every value is finite. `path` names the file in errors.
    pub fn from_bytes(bytes: &[u8], path: &str) -> Result<Self, DataError> {
        let err = |fault| DataError {
            path: String::from(path),
            fault,
        };
        let len = bytes.len() as u64;
        if len < 12 {
            return Err(err(DataFault::Truncated {
                bytes: len,
                expected: MERL_FILE_BYTES,
            }));
        }
        let dim = |k: usize| {
            i32::from_le_bytes([
                bytes[4 * k],
                bytes[4 * k + 1],
                bytes[4 * k + 2],
                bytes[4 * k + 3],
            ])
        };
        let dims = [dim(0), dim(1), dim(2)];
        if dims != [MERL_THETA_H as i32, MERL_THETA_D as i32, MERL_PHI_D as i32] {
            return Err(err(DataFault::Dimensions { found: dims }));
        }
        check_size(len).map_err(err)?;
        let mut values = alloc::vec![[0.0f32; 3]; MERL_BINS];
        let mut unmeasured = 0;
        for (i, chunk) in bytes[12..].chunks_exact(8).enumerate() {
            let mut b = [0u8; 8];
            b.copy_from_slice(chunk);
            let v = f64::from_le_bytes(b);
            if !v.is_finite() {
                return Err(err(DataFault::NotFinite {
                    channel: (i / MERL_BINS) as u8,
                    bin: (i % MERL_BINS) as u32,
                }));
            }
            let (channel, bin) = (i / MERL_BINS, i % MERL_BINS);
            if v < 0.0 {
                unmeasured += 1;
            } else {
                // A finite value whose f_r no measurement gives: past f32's range it was an
                // infinite f_r (every quadtree failed with "NaN expected trials"), and near
                // it the cosine and analytic samplers' weights f·π overflowed to NaN means.
                let f = v * MERL_SCALE[channel];
                if f > MERL_MAX_F {
                    return Err(err(DataFault::TooLarge {
                        channel: channel as u8,
                        bin: bin as u32,
                    }));
                }
                values[bin][channel] = f as f32;
            }
        }
        Ok(Self { values, unmeasured })
    }

    /// How many stored values (over the three channels) were negative: not measured.
    #[must_use]
    pub fn unmeasured(&self) -> usize {
        self.unmeasured
    }

    /// f_r of one bin, RGB.
    #[inline]
    #[must_use]
    pub fn bin(&self, index: usize) -> Vec3 {
        Vec3::from_array(self.values[index])
    }

    /// f_r at the half/difference angles, by `lookup`.
    #[must_use]
    pub fn lookup(&self, theta_h: f64, theta_d: f64, phi_d: f64, lookup: MerlLookup) -> Vec3 {
        match lookup {
            MerlLookup::Nearest => self.bin(bin_index(bin_indices(theta_h, theta_d, phi_d))),
            MerlLookup::Linear => self.linear(theta_h, theta_d, phi_d),
        }
    }

    fn linear(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> Vec3 {
        // Continuous index coordinates with bin centres at integers.
        let axis = |x: f64, n: usize| -> (usize, usize, f64) {
            let t = (x - 0.5).clamp(0.0, (n - 1) as f64);
            let i = (t as usize).min(n - 2);
            (i, i + 1, t - i as f64)
        };
        let th = m::sqrt(theta_h.max(0.0) / FRAC_PI_2) * MERL_THETA_H as f64;
        let (h0, h1, fh) = axis(th, MERL_THETA_H);
        let (d0, d1, fd) = axis(
            theta_d.max(0.0) / FRAC_PI_2 * MERL_THETA_D as f64,
            MERL_THETA_D,
        );
        // φd: periodic over [0, π) (reciprocity), so the bins either side of 0 are 179 and 0.
        let pd = if phi_d < 0.0 { phi_d + PI } else { phi_d };
        let p = pd / PI * MERL_PHI_D as f64 - 0.5;
        let pf = m::floor(p);
        let fp = p - pf;
        let n = MERL_PHI_D as i64;
        let p0 = (pf as i64).rem_euclid(n) as usize;
        let p1 = (p0 + 1) % MERL_PHI_D;
        let mut out = Vec3::ZERO;
        for (h, wh) in [(h0, 1.0 - fh), (h1, fh)] {
            for (d, wd) in [(d0, 1.0 - fd), (d1, fd)] {
                for (q, wq) in [(p0, 1.0 - fp), (p1, fp)] {
                    let w = wh * wd * wq;
                    if w > 0.0 {
                        out += self.bin(bin_index([h, d, q])) * w as f32;
                    }
                }
            }
        }
        out
    }
}

/// The size check shared by the parser and the reader (which checks before reading, so a
/// huge file is refused without allocating for it).
fn check_size(len: u64) -> Result<(), DataFault> {
    if len < MERL_FILE_BYTES {
        Err(DataFault::Truncated {
            bytes: len,
            expected: MERL_FILE_BYTES,
        })
    } else if len > MERL_FILE_BYTES {
        Err(DataFault::WrongSize {
            bytes: len,
            expected: MERL_FILE_BYTES,
        })
    } else {
        Ok(())
    }
}

/// Encodes three channels of f_r (channel-major, [`MERL_BINS`] each, unscaled f_r) as a file
/// in the database's format: the header, then each value divided by its channel's scale.
/// Negative or non-finite inputs are written as −1 ("not measured").
#[must_use]
pub fn encode(f: &[[f64; 3]]) -> Vec<u8> {
    let mut out = Vec::with_capacity(MERL_FILE_BYTES as usize);
    for d in [MERL_THETA_H, MERL_THETA_D, MERL_PHI_D] {
        out.extend_from_slice(&(d as i32).to_le_bytes());
    }
    for (c, scale) in MERL_SCALE.iter().enumerate() {
        for k in 0..MERL_BINS {
            let v = f.get(k).map_or(-1.0, |x| x[c]);
            let stored = if v.is_finite() && v >= 0.0 {
                v / scale
            } else {
                -1.0
            };
            out.extend_from_slice(&stored.to_le_bytes());
        }
    }
    out
}

/// The unit pair (wi, wo), as the f32 vectors a model is evaluated at, of bin `index`'s
/// centre ([`bin_centre`], φh = 0). `brdf tabulate` evaluates a model here, so that `merl`
/// on the file it writes reproduces the model at every bin centre.
#[must_use]
pub fn bin_centre_pair(index: usize) -> (Vec3, Vec3) {
    let th = index / (MERL_PHI_D * MERL_THETA_D);
    let td = (index / MERL_PHI_D) % MERL_THETA_D;
    let pd = index % MERL_PHI_D;
    let [a, b, c] = bin_centre([th, td, pd]);
    let (wi, wo) = from_half_diff(a, 0.0, b, c);
    (wi.as_vec3(), wo.as_vec3())
}

/// A model's f_r at every bin centre ([`bin_centre_pair`]), channel-major input for
/// [`encode`]: what `brdf tabulate` writes (serially here; the CLI runs the same expression
/// in parallel).
#[must_use]
pub fn tabulate<B: Brdf + ?Sized>(brdf: &B) -> Vec<[f64; 3]> {
    (0..MERL_BINS).map(|k| tabulate_bin(brdf, k)).collect()
}

/// One bin of [`tabulate`].
#[inline]
#[must_use]
pub fn tabulate_bin<B: Brdf + ?Sized>(brdf: &B, index: usize) -> [f64; 3] {
    let (wi, wo) = bin_centre_pair(index);
    brdf.eval(wi, wo).as_dvec3().to_array()
}

/// `merl`: f_r from a measured file (see the module doc). Isotropic and reciprocal by the
/// format's construction (the angles do not depend on φh; φd is folded by reciprocity).
#[derive(Clone, Debug)]
pub struct Merl {
    data: Arc<MerlData>,
    path: String,
    lookup: MerlLookup,
}

impl Merl {
    /// The model's parameters.
    pub const PARAMS: &'static [ParamSpec] = &[
        ParamSpec::path(
            "file",
            "the measured BRDF: a file in the MERL database's binary format (required)",
        ),
        ParamSpec::choice(
            "interp",
            MerlLookup::NAMES,
            0,
            "lookup: nearest (the database's reader) or linear (trilinear between bin centres)",
        ),
    ];

    /// The model of already parsed data; `path` is what [`Brdf::params`] reports.
    #[must_use]
    pub fn new(data: Arc<MerlData>, path: String, lookup: MerlLookup) -> Self {
        Self { data, path, lookup }
    }

    /// The data.
    #[must_use]
    pub fn data(&self) -> &Arc<MerlData> {
        &self.data
    }

    /// The lookup.
    #[must_use]
    pub fn lookup(&self) -> MerlLookup {
        self.lookup
    }

    /// Builds from a validated parameter set: reads the file (std only; without std every
    /// file is [`DataFault::NoFileSystem`]).
    pub fn from_params(p: &ParamSet) -> Result<Self, ParamError> {
        let path = p.text("file")?;
        if path.is_empty() {
            return Err(ParamError::Required {
                model: "merl",
                name: "file",
            });
        }
        let lookup = match p.text("interp")? {
            "linear" => MerlLookup::Linear,
            _ => MerlLookup::Nearest,
        };
        let data = open(path).map_err(|error| ParamError::Data {
            name: "file",
            error,
        })?;
        Ok(Self::new(data, String::from(path), lookup))
    }
}

#[cfg(feature = "std")]
fn open(path: &str) -> Result<Arc<MerlData>, DataError> {
    cache::open(path)
}

#[cfg(not(feature = "std"))]
fn open(path: &str) -> Result<Arc<MerlData>, DataError> {
    Err(DataError {
        path: String::from(path),
        fault: DataFault::NoFileSystem,
    })
}

/// Reading files, and sharing the data of one unchanged file between every model made of it.
#[cfg(feature = "std")]
mod cache {
    use super::MerlData;
    use crate::error::{DataError, DataFault};
    use alloc::string::String;
    use alloc::sync::{Arc, Weak};
    use alloc::vec::Vec;
    use std::io::Read;
    use std::path::PathBuf;
    use std::sync::Mutex;
    use std::time::SystemTime;

    type Key = (PathBuf, u64, Option<SystemTime>);

    static OPEN: Mutex<Vec<(Key, Weak<MerlData>)>> = Mutex::new(Vec::new());

    pub(super) fn open(path: &str) -> Result<Arc<MerlData>, DataError> {
        let err = |fault| DataError {
            path: String::from(path),
            fault,
        };
        let meta = std::fs::metadata(path).map_err(|e| err(io_fault(&e)))?;
        if meta.is_dir() {
            return Err(err(DataFault::Directory));
        }
        if !meta.is_file() {
            // A device or a pipe: reading it could block forever or never end.
            return Err(err(DataFault::NotRegular));
        }
        if meta.len() > super::MERL_FILE_BYTES {
            // Refused before reading: a huge file is never loaded.
            return Err(err(DataFault::WrongSize {
                bytes: meta.len(),
                expected: super::MERL_FILE_BYTES,
            }));
        }
        let canonical = std::fs::canonicalize(path).unwrap_or_else(|_| PathBuf::from(path));
        let key: Key = (canonical, meta.len(), meta.modified().ok());
        {
            let mut open = OPEN
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            open.retain(|(_, w)| w.strong_count() > 0);
            if let Some(d) = open
                .iter()
                .find(|(k, _)| *k == key)
                .and_then(|(_, w)| w.upgrade())
            {
                return Ok(d);
            }
        }
        let mut file = std::fs::File::open(path).map_err(|e| err(io_fault(&e)))?;
        let mut bytes = Vec::with_capacity(meta.len() as usize);
        file.by_ref()
            .take(super::MERL_FILE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| err(io_fault(&e)))?;
        let data = Arc::new(MerlData::from_bytes(&bytes, path)?);
        let mut open = OPEN
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        open.push((key, Arc::downgrade(&data)));
        Ok(data)
    }

    fn io_fault(e: &std::io::Error) -> DataFault {
        match e.kind() {
            std::io::ErrorKind::NotFound => DataFault::Missing,
            std::io::ErrorKind::PermissionDenied => DataFault::PermissionDenied,
            std::io::ErrorKind::IsADirectory => DataFault::Directory,
            _ => DataFault::Unreadable,
        }
    }
}

impl Brdf for Merl {
    fn name(&self) -> &'static str {
        "merl"
    }

    fn params(&self) -> ParamSet {
        ParamSet::from_checked(
            self.name(),
            Self::PARAMS,
            &[
                ParamValue::Path(self.path.clone()),
                ParamValue::Choice(self.lookup.name()),
            ],
        )
    }

    fn symmetry(&self) -> Symmetry {
        // Rotation about the normal moves neither θh, θd nor φd; swapping wi and wo moves φd
        // by π, which the format folds. Mirror planes flip φd's sign, which measured data need
        // not honour: not declared.
        Symmetry {
            isotropic: true,
            mirror_x: false,
            mirror_y: false,
            reciprocal: true,
        }
    }

    fn integration_tolerance(&self) -> f64 {
        match self.lookup {
            MerlLookup::Nearest => NEAREST_INTEGRATION_TOLERANCE,
            MerlLookup::Linear => 0.0,
        }
    }

    fn step_width(&self) -> Option<f64> {
        match self.lookup {
            MerlLookup::Nearest => Some(NEAREST_STEP_WIDTH),
            MerlLookup::Linear => None,
        }
    }

    fn eval(&self, wi: Vec3, wo: Vec3) -> Vec3 {
        let Some((wi, wo)) = upper_pair(wi, wo) else {
            return Vec3::ZERO;
        };
        let [theta_h, theta_d, phi_d] = half_diff_lookup(wi, (wi + wo).normalize_or_zero());
        self.data.lookup(theta_h, theta_d, phi_d, self.lookup)
    }
}
