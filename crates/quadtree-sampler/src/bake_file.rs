//! Bake files (SPEC §7): a [`BakedSampler`] written once and read back in milliseconds.
//!
//! Layout (all integers little-endian):
//!
//! | bytes | what |
//! | --- | --- |
//! | 8 | magic `BRDFBAKE` |
//! | 4 | format version ([`BAKE_FORMAT_VERSION`]) |
//! | 8 | payload length n |
//! | n | payload: the model name, its parameters as `name=value`, the bake configuration, the grid's φ domain, per tree its wi, volume, both layouts' nodes and the warp's shaped leaves, and per transport direction the grid cells a rejection-mode query answers with its nearest tree, encoded with `postcard` (LEB128 integers, little-endian floats) |
//! | 4 | CRC-32 (IEEE) of everything before it |
//!
//! Reading checks, in order: the magic, the version, the length against the file's size
//! (truncated or trailing bytes), the checksum (a flipped bit anywhere), the payload's
//! decoding, the model (registered, parameters valid), the configuration (in range, and the
//! grid it implies is the one recorded: the model's declared symmetries have not changed),
//! every tree's structure, and that the nearest-tree cells fit the grid. Each failure is its
//! own [`BakeFileError`]; nothing panics, and no length in the file is trusted before the
//! checksum has passed.

use crate::bake_grid::{BakeGrid, Nearest, PhiDomain};
use crate::baked::{BakeConfig, BakedSampler, Slice, Tables};
use crate::config::{BuildConfig, IntegrationRule};
use crate::packed::PackedTree;
use crate::warp_table::{RIM_FLAG, WarpTable};
use alloc::string::{String, ToString};
use alloc::sync::Arc;
use alloc::vec::Vec;
use brdf_core::{Brdf, DiskMap, ParamError, registry};
use core::fmt;
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// The first eight bytes of every bake file.
pub const BAKE_MAGIC: [u8; 8] = *b"BRDFBAKE";

/// The format version this library writes and reads. Version 2: leaves may use the
/// transposed angle chart, and the models evaluate with the grazing floor
/// (`brdf_core::geometry::GRAZING_COS`). Version 3: the root and its children may use the
/// polar chart (orthographic trees). Version 4: leaves may carry a height shape
/// ([`crate::proposal::Shape`], in bits 3–26 of a leaf's link word). Version 5: the root
/// and its children may use the polar chart on concentric trees too, and a square or polar
/// leaf may carry a fine height shape (its five further levels in the leaf's third data
/// word). Version 6: per transport direction, the grid cells a rejection-mode query answers
/// with its nearest tree (measured at the bake). Version 7: per tree, the warp's leaves that
/// spread their shares by a fitted shape (node index and the shape's two words, as a packed
/// leaf keeps them). Version 8: version 7's record, whose anisotropic grids are sampled
/// by the half-vector transport (their nearest-tree cells measured under it). Files of
/// versions 5 to 7 are still read ([`OLDEST_READ_VERSION`]): version 5 holds no
/// nearest-tree cells, and its samplers blend every cell; neither 5 nor 6 holds shapes, and
/// their warps spread every leaf uniformly; up to 7 an anisotropic grid rotates its trees
/// onto a query's mirror direction — each as it did when it was written. Version 9:
/// version 8's record, whose warps (orthographic trees) spread the share of a leaf on the
/// disk's rim uniformly in solid angle over its part of the hemisphere,
/// its shape fitted in that chart; up to 8 such a leaf spreads over its square. Version 10:
/// version 9's record, whose nearest-tree cells were measured with the band along the
/// horizon that a tilted tree cannot reach (`baked_nearest::unreached_excess`); files of
/// versions 6 to 9 read with their nearest-tree cells dropped, so that every cell blends
/// (exact, and no band is left to the defensive share alone: a snapped Schlick r = 0.01
/// cell's samples there weighed 10⁶ times their due; rejection mode costs one evaluation
/// more per query where they snapped). Version 11: version 10's record followed by the
/// bake's [`BakeConfig::max_bytes`]; older files read as baked with
/// [`crate::MAX_BAKE_BYTES`] (no limit but the hard one, as they were). A file of any other
/// version is a typed error (SPEC §7): bake it again.
pub const BAKE_FORMAT_VERSION: u32 = 11;

/// The oldest format version read: version 5, whose records are version 6's without the
/// nearest-tree cells (and version 6's are version 7's without the warp's shapes).
pub const OLDEST_READ_VERSION: u32 = 5;

const HEADER: usize = 8 + 4 + 8;
const TRAILER: usize = 4;

/// The longest bake file read: [`crate::MAX_BAKE_BYTES`] with its header and trailer. A
/// file stores less than its bake holds in memory (0.1–0.5× of `bytes`, measured on
/// `brdf bake` of lambert, phong n = 1000, strauss and anisotropic ward), so every bake a
/// build can make is read back; a longer one (or a device that never ends) is refused
/// before it is read.
pub const MAX_BAKE_FILE_BYTES: u64 = crate::MAX_BAKE_BYTES as u64 + (HEADER + TRAILER) as u64;

/// Why bytes could not be read as a bake file.
#[derive(Clone, Debug, PartialEq)]
pub enum BakeFileError {
    /// The bytes do not start with [`BAKE_MAGIC`]: not a bake file.
    NotABakeFile,
    /// A bake file of another format version.
    Version {
        /// The version in the file.
        found: u32,
        /// The version this library reads.
        supported: u32,
    },
    /// Fewer bytes than the header says (a truncated file).
    Truncated {
        /// Bytes the header promises.
        expected: u64,
        /// Bytes present.
        found: u64,
    },
    /// The header declares a file longer than [`MAX_BAKE_FILE_BYTES`].
    TooLarge {
        /// Bytes the header declares.
        declared: u64,
        /// The limit.
        limit: u64,
    },
    /// More bytes than the header says.
    TrailingBytes {
        /// Bytes the header promises.
        expected: u64,
        /// Bytes present.
        found: u64,
    },
    /// The checksum does not match: the file was corrupted.
    Checksum {
        /// The CRC-32 stored in the file.
        stored: u32,
        /// The CRC-32 of the bytes read.
        computed: u32,
    },
    /// The payload does not decode (a file written by something else under this name).
    Decode,
    /// The model recorded is unknown, or its parameters are invalid.
    Model(ParamError),
    /// A recorded option is out of range or names an unknown variant.
    Config(&'static str),
    /// The recorded grid is not the grid the model and configuration give (its symmetry
    /// declaration or the grid rules changed since the file was written), or the recorded
    /// nearest-tree cells do not fit it.
    GridMismatch,
    /// A tree's nodes are not a valid tree.
    Tree {
        /// Which tree (row-major in the grid; adjoint trees after the forward ones).
        index: usize,
        /// What is wrong.
        fault: &'static str,
    },
}

impl fmt::Display for BakeFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotABakeFile => write!(f, "not a bake file (no BRDFBAKE header)"),
            Self::Version { found, supported } => write!(
                f,
                "bake file format version {found}; this build reads version {supported} (bake it again)"
            ),
            Self::Truncated { expected, found } => {
                write!(f, "truncated bake file: {found} bytes of {expected}")
            }
            Self::TooLarge { declared, limit } => write!(
                f,
                "bake file declares {declared} bytes, more than the {limit} a bake may hold"
            ),
            Self::TrailingBytes { expected, found } => {
                write!(f, "bake file has {found} bytes, its header says {expected}")
            }
            Self::Checksum { stored, computed } => write!(
                f,
                "bake file is corrupted (CRC-32 {computed:08x}, recorded {stored:08x})"
            ),
            Self::Decode => write!(f, "bake file payload does not decode"),
            Self::Model(e) => write!(f, "bake file's model: {e}"),
            Self::Config(what) => write!(f, "bake file's configuration: {what}"),
            Self::GridMismatch => write!(
                f,
                "bake file's grid is not the one its model and configuration give (bake it again)"
            ),
            Self::Tree { index, fault } => write!(f, "bake file's tree {index}: {fault}"),
        }
    }
}

impl core::error::Error for BakeFileError {}

#[derive(Serialize, Deserialize)]
struct ConfigRecord {
    map: u8,
    split_threshold: f64,
    rule: u8,
    rule_n: u8,
    integration_tolerance: f64,
    integration_depth: u8,
    max_depth: u8,
    node_budget: u32,
    evaluation_budget: u64,
    target_trials: Option<f64>,
    bound_safety: f64,
    bound_grid: u8,
    min_relative_waste: f64,
    theta_steps: u16,
    phi_steps: u16,
    defensive: f64,
}

/// One tree as versions 5 and 6 store it.
#[derive(Serialize, Deserialize)]
struct SliceRecordV6 {
    wi: [f32; 3],
    volume: f64,
    budget_exhausted: bool,
    packed: Vec<[u32; 4]>,
    warp: Vec<(u32, f32)>,
}

/// One tree: version 6's record, then the warp's shaped leaves (node index, the shape's
/// corner word and fine word). postcard writes a struct as its fields in order, so this is
/// version 6's fields followed by the shapes.
#[derive(Serialize, Deserialize)]
struct SliceRecord {
    tree: SliceRecordV6,
    warp_shapes: Vec<(u32, u32, u32)>,
}

impl SliceRecordV6 {
    /// The version 7 record it stands for: every warp leaf flat.
    fn upgrade(self) -> SliceRecord {
        SliceRecord {
            tree: self,
            warp_shapes: Vec::new(),
        }
    }
}

/// The [`Nearest`] cells of one transport direction.
#[derive(Serialize, Deserialize)]
struct NearestRecord {
    theta: Vec<bool>,
    phi: Vec<bool>,
}

/// The trees of one transport direction and their (rejection mode's) nearest-tree cells.
#[derive(Serialize, Deserialize)]
struct TablesRecord<S = SliceRecord> {
    slices: Vec<S>,
    nearest: NearestRecord,
}

/// A file's record; `T` is one transport direction's trees as the version stores them:
/// [`TablesRecord`] (version 7), `TablesRecord<SliceRecordV6>` (version 6) or a plain
/// `Vec<SliceRecordV6>` (version 5, [`RecordV5`]).
#[derive(Serialize, Deserialize)]
struct Record<T = TablesRecord> {
    model: String,
    params: Vec<String>,
    config: ConfigRecord,
    domain: u8,
    forward: T,
    adjoint: Option<T>,
}

impl<T> Record<T> {
    /// The same record with each direction's trees mapped by `f`.
    fn map<U>(self, f: impl Fn(T) -> U) -> Record<U> {
        Record {
            model: self.model,
            params: self.params,
            config: self.config,
            domain: self.domain,
            forward: f(self.forward),
            adjoint: self.adjoint.map(f),
        }
    }
}

/// A version 11 file's record: version 10's ([`Record`]), then the most bytes the bake
/// was allowed ([`BakeConfig::max_bytes`]). postcard writes a struct as its fields in order,
/// so this is version 10's payload followed by one integer.
#[derive(Serialize, Deserialize)]
struct RecordV11 {
    record: Record,
    max_bytes: u64,
}

/// A version 6 file's record: version 7's without the warp's shapes.
type RecordV6 = Record<TablesRecord<SliceRecordV6>>;

impl RecordV6 {
    /// The version 7 record it stands for: every warp leaf flat.
    fn upgrade(self) -> Record {
        self.map(|t| TablesRecord {
            slices: t.slices.into_iter().map(SliceRecordV6::upgrade).collect(),
            nearest: t.nearest,
        })
    }
}

/// A version 5 file's record: the trees alone.
type RecordV5 = Record<Vec<SliceRecordV6>>;

impl RecordV5 {
    /// The version 6 record it stands for: every cell blends (no nearest-tree cells, which
    /// [`Nearest::fits`] accepts as none measured).
    fn upgrade(self) -> RecordV6 {
        self.map(|slices| TablesRecord {
            slices,
            nearest: NearestRecord {
                theta: Vec::new(),
                phi: Vec::new(),
            },
        })
    }
}

fn map_code(m: DiskMap) -> u8 {
    match m {
        DiskMap::Orthographic => 0,
        DiskMap::Concentric => 1,
    }
}

fn domain_code(d: PhiDomain) -> u8 {
    match d {
        PhiDomain::Rotation => 0,
        PhiDomain::Quadrant => 1,
        PhiDomain::UpperHalf => 2,
        PhiDomain::RightHalf => 3,
        PhiDomain::Circle => 4,
    }
}

impl ConfigRecord {
    fn of(c: &BakeConfig) -> Self {
        let b = &c.build;
        let (rule, rule_n) = match b.rule {
            IntegrationRule::Midpoint { n } => (0, n),
            IntegrationRule::GaussLegendre { n } => (1, n),
        };
        Self {
            map: map_code(b.map),
            split_threshold: b.split_threshold,
            rule,
            rule_n,
            integration_tolerance: b.integration_tolerance,
            integration_depth: b.integration_depth,
            max_depth: b.max_depth,
            node_budget: b.node_budget,
            evaluation_budget: b.evaluation_budget,
            target_trials: b.target_trials,
            bound_safety: b.bound_safety,
            bound_grid: b.bound_grid,
            min_relative_waste: b.min_relative_waste,
            theta_steps: c.theta_steps,
            phi_steps: c.phi_steps,
            defensive: c.defensive,
        }
    }

    /// The configuration, with the bake's `max_bytes` (recorded beside it from version 11).
    fn to_config(&self, max_bytes: u64) -> Result<BakeConfig, BakeFileError> {
        let map = match self.map {
            0 => DiskMap::Orthographic,
            1 => DiskMap::Concentric,
            _ => return Err(BakeFileError::Config("unknown disk map")),
        };
        let rule = match self.rule {
            0 => IntegrationRule::Midpoint { n: self.rule_n },
            1 => IntegrationRule::GaussLegendre { n: self.rule_n },
            _ => return Err(BakeFileError::Config("unknown integration rule")),
        };
        let build = BuildConfig {
            map,
            split_threshold: self.split_threshold,
            rule,
            integration_tolerance: self.integration_tolerance,
            integration_depth: self.integration_depth,
            max_depth: self.max_depth,
            node_budget: self.node_budget,
            evaluation_budget: self.evaluation_budget,
            target_trials: self.target_trials,
            bound_safety: self.bound_safety,
            bound_grid: self.bound_grid,
            min_relative_waste: self.min_relative_waste,
            // Not recorded: serial and parallel builds are bit-identical.
            parallel: true,
        };
        build
            .validate()
            .map_err(|_| BakeFileError::Config("a build option is out of range"))?;
        if !(self.defensive > 0.0 && self.defensive < 1.0) {
            return Err(BakeFileError::Config("defensive share out of (0, 1)"));
        }
        let max_bytes = usize::try_from(max_bytes)
            .ok()
            .filter(|b| (1..=crate::MAX_BAKE_BYTES).contains(b))
            .ok_or(BakeFileError::Config("max_bytes out of range"))?;
        Ok(BakeConfig {
            build,
            theta_steps: self.theta_steps,
            phi_steps: self.phi_steps,
            defensive: self.defensive,
            max_bytes: Some(max_bytes),
        })
    }
}

fn slice_record(s: &Slice) -> SliceRecord {
    SliceRecord {
        tree: SliceRecordV6 {
            wi: s.wi.to_array(),
            volume: s.tree.volume(),
            budget_exhausted: s.tree.stats().budget_exhausted,
            packed: s.tree.raw_nodes(),
            warp: s.warp.shares().collect(),
        },
        warp_shapes: s
            .warp
            .shaped()
            .map(|(i, shape, chart)| {
                let flag = if chart { RIM_FLAG } else { 0 };
                (i, shape.to_bits() | flag, shape.fine_bits())
            })
            .collect(),
    }
}

fn tables_record(t: &Tables) -> TablesRecord {
    TablesRecord {
        slices: t.slices.iter().map(slice_record).collect(),
        nearest: NearestRecord {
            theta: t.nearest.theta.clone(),
            phi: t.nearest.phi.clone(),
        },
    }
}

/// One transport direction's tables from its record; `rim_charts`: whether the warps' rim
/// leaves spread their shares in solid angle (version 9 on, [`crate::rim`]).
fn tables_from(
    record: TablesRecord,
    grid: &BakeGrid,
    map: DiskMap,
    first_index: usize,
    rim_charts: bool,
) -> Result<Tables, BakeFileError> {
    let TablesRecord { slices, nearest } = record;
    let nearest = Nearest {
        theta: nearest.theta,
        phi: nearest.phi,
    };
    if !nearest.fits(grid) {
        return Err(BakeFileError::GridMismatch);
    }
    Ok(Tables {
        slices: slices_from(slices, grid, map, first_index, rim_charts)?,
        nearest,
    })
}

fn slices_from(
    records: Vec<SliceRecord>,
    grid: &BakeGrid,
    map: DiskMap,
    first_index: usize,
    rim_charts: bool,
) -> Result<Vec<Slice>, BakeFileError> {
    if records.len() != grid.len() {
        return Err(BakeFileError::GridMismatch);
    }
    let mut slices = Vec::with_capacity(records.len());
    for (k, record) in records.into_iter().enumerate() {
        let index = first_index + k;
        let SliceRecord {
            tree: r,
            warp_shapes,
        } = record;
        let wi = Vec3::from_array(r.wi);
        if wi.to_array().map(f32::to_bits) != grid.direction(k).to_array().map(f32::to_bits) {
            return Err(BakeFileError::GridMismatch);
        }
        let tree = PackedTree::from_raw(&r.packed, map, r.volume, r.budget_exhausted)
            .map_err(|fault| BakeFileError::Tree { index, fault })?;
        let shapes = warp_shapes
            .iter()
            .map(|&(i, bits, fine)| {
                // From version 9 a shape's first word may mark a leaf's solid-angle chart.
                let chart = rim_charts && bits & RIM_FLAG != 0;
                let bits = if rim_charts { bits & !RIM_FLAG } else { bits };
                crate::proposal::Shape::from_bits(bits, fine)
                    .map(|s| (i, s, chart))
                    .ok_or("a warp shape whose words no shape writes")
            })
            .collect::<Result<Vec<_>, _>>()
            .map_err(|fault| BakeFileError::Tree { index, fault })?;
        let warp = WarpTable::from_raw(r.warp, map)
            .and_then(|w| w.with_shapes(&shapes))
            .map_err(|fault| BakeFileError::Tree { index, fault })?;
        if warp.len() != tree.nodes().len()
            || tree
                .nodes()
                .iter()
                .enumerate()
                .any(|(i, p)| warp.is_leaf(i) != p.is_leaf())
        {
            return Err(BakeFileError::Tree {
                index,
                fault: "its warp table and its tree differ in shape",
            });
        }
        slices.push(Slice::new(wi, tree, warp));
    }
    Ok(slices)
}

/// A model's parameters as the file records them, `name=value`.
fn param_strings(brdf: &dyn Brdf) -> Vec<String> {
    brdf.params()
        .iter()
        .map(|(spec, v)| alloc::format!("{}={v}", spec.name))
        .collect()
}

/// The payload this library writes ([`BAKE_FORMAT_VERSION`]): `record`, then `max_bytes`.
fn current_payload(record: Record, max_bytes: usize) -> Vec<u8> {
    let record = RecordV11 {
        record,
        max_bytes: max_bytes as u64,
    };
    // Encoding into a Vec cannot fail for these plain types.
    postcard::to_allocvec(&record).unwrap_or_default()
}

/// A file's bytes around an encoded `payload`: magic, `version`, length, and the CRC-32.
fn frame(version: u32, payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER + payload.len() + TRAILER);
    out.extend_from_slice(&BAKE_MAGIC);
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(payload);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Little-endian word of `n` bytes at `at` (a truncation error where `bytes` ends first).
fn word(bytes: &[u8], at: usize, n: usize) -> Result<u64, BakeFileError> {
    let b = bytes.get(at..at + n).ok_or(BakeFileError::Truncated {
        expected: (at + n) as u64,
        found: bytes.len() as u64,
    })?;
    Ok(b.iter()
        .rev()
        .fold(0u64, |acc, &x| (acc << 8) | u64::from(x)))
}

/// The whole file's length as its header (the first [`HEADER`] bytes of `bytes`) declares
/// it, after checking the magic and the version, and that it is within
/// [`MAX_BAKE_FILE_BYTES`].
fn declared_length(bytes: &[u8]) -> Result<u64, BakeFileError> {
    if bytes.len() < 8 || bytes[..8] != BAKE_MAGIC {
        return Err(BakeFileError::NotABakeFile);
    }
    let version = word(bytes, 8, 4)? as u32;
    if !(OLDEST_READ_VERSION..=BAKE_FORMAT_VERSION).contains(&version) {
        return Err(BakeFileError::Version {
            found: version,
            supported: BAKE_FORMAT_VERSION,
        });
    }
    let n = word(bytes, 12, 8)?;
    let declared = n.saturating_add((HEADER + TRAILER) as u64);
    if declared > MAX_BAKE_FILE_BYTES {
        return Err(BakeFileError::TooLarge {
            declared,
            limit: MAX_BAKE_FILE_BYTES,
        });
    }
    Ok(declared)
}

impl BakedSampler {
    /// What a bake file of this sampler encodes.
    fn record(&self) -> Record {
        let (forward, adjoint) = self.tables();
        Record {
            model: self.brdf().name().to_string(),
            params: param_strings(&**self.brdf()),
            config: ConfigRecord::of(self.config()),
            domain: domain_code(self.grid().domain()),
            forward: tables_record(forward),
            adjoint: adjoint.map(tables_record),
        }
    }

    /// The bake file's bytes (see the module doc of `bake_file`): everything needed to
    /// sample again without building a tree.
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        frame(
            BAKE_FORMAT_VERSION,
            &current_payload(self.record(), self.max_bytes()),
        )
    }

    /// Reads a bake file's bytes, rebuilding the model from the registry (see the module
    /// doc of `bake_file` for every check made).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, BakeFileError> {
        let expected = declared_length(bytes)?;
        let n = expected - (HEADER + TRAILER) as u64;
        let found = bytes.len() as u64;
        if found < expected {
            return Err(BakeFileError::Truncated { expected, found });
        }
        if found > expected {
            return Err(BakeFileError::TrailingBytes { expected, found });
        }
        let body = HEADER + n as usize;
        let stored = word(bytes, body, 4)? as u32;
        let computed = crc32fast::hash(&bytes[..body]);
        if stored != computed {
            return Err(BakeFileError::Checksum { stored, computed });
        }
        let payload = &bytes[HEADER..body];
        let version = word(bytes, 8, 4)? as u32;
        // Files before version 11 were baked with no limit but the hard one.
        let (record, max_bytes): (Record, u64) = match version {
            5 => (
                postcard::from_bytes::<RecordV5>(payload)
                    .map_err(|_| BakeFileError::Decode)?
                    .upgrade()
                    .upgrade(),
                crate::MAX_BAKE_BYTES as u64,
            ),
            6 => (
                postcard::from_bytes::<RecordV6>(payload)
                    .map_err(|_| BakeFileError::Decode)?
                    .upgrade(),
                crate::MAX_BAKE_BYTES as u64,
            ),
            7..=10 => (
                postcard::from_bytes(payload).map_err(|_| BakeFileError::Decode)?,
                crate::MAX_BAKE_BYTES as u64,
            ),
            _ => {
                let RecordV11 { record, max_bytes } =
                    postcard::from_bytes(payload).map_err(|_| BakeFileError::Decode)?;
                (record, max_bytes)
            }
        };
        let info = registry::find(&record.model).map_err(BakeFileError::Model)?;
        let params = info
            .parse_params(record.params.iter().map(String::as_str))
            .map_err(BakeFileError::Model)?;
        let brdf: Arc<dyn Brdf> = info.build(&params).map_err(BakeFileError::Model)?.into();
        let config = record.config.to_config(max_bytes)?;
        let grid = BakeGrid::new(brdf.symmetry(), config.theta_steps, config.phi_steps)
            .map_err(|_| BakeFileError::Config("theta or phi steps out of range"))?;
        if domain_code(grid.domain()) != record.domain {
            return Err(BakeFileError::GridMismatch);
        }
        if record.adjoint.is_some() == brdf.symmetry().reciprocal {
            return Err(BakeFileError::GridMismatch);
        }
        let map = config.build.map;
        // Version 9 is version 8's record, whose warps spread their rim leaves in solid
        // angle; older files' rim leaves spread over their squares, as they did.
        let rim_charts = version >= 9;
        let mut forward = tables_from(record.forward, &grid, map, 0, rim_charts)?;
        let mut adjoint = record
            .adjoint
            .map(|a| tables_from(a, &grid, map, grid.len(), rim_charts))
            .transpose()?;
        // Nearest-tree cells measured before version 10 did not see the horizon band: they
        // are dropped, and every cell blends (exact; only slower where they snapped).
        if version < 10 {
            for t in core::iter::once(&mut forward).chain(adjoint.as_mut()) {
                t.nearest = Default::default();
            }
        }
        // Version 8 is version 7's record, sampled by the half-vector transport where the
        // grid is anisotropic; older files sample as they did (rotations).
        let half_vector = version >= 8 && !brdf.symmetry().isotropic;
        Ok(Self::from_parts(
            brdf,
            config,
            grid,
            forward,
            adjoint,
            half_vector,
        ))
    }
}

#[cfg(feature = "std")]
mod files {
    use super::{BakeFileError, BakedSampler, HEADER, declared_length};
    use std::fmt;
    use std::io::{Read, Write};
    use std::path::{Path, PathBuf};

    /// Why a bake file could not be read or written.
    #[derive(Debug)]
    pub enum BakeIoError {
        /// The file system refused (missing file, a directory, no permission, disk full).
        Io {
            /// The path.
            path: PathBuf,
            /// The error.
            source: std::io::Error,
        },
        /// The file was read but is not a valid bake file.
        Format {
            /// The path.
            path: PathBuf,
            /// What is wrong.
            source: BakeFileError,
        },
    }

    impl fmt::Display for BakeIoError {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            match self {
                Self::Io { path, source } => write!(f, "{}: {source}", path.display()),
                Self::Format { path, source } => write!(f, "{}: {source}", path.display()),
            }
        }
    }

    impl std::error::Error for BakeIoError {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            match self {
                Self::Io { source, .. } => Some(source),
                Self::Format { source, .. } => Some(source),
            }
        }
    }

    /// A temporary path in the directory of `path` (hidden, named after it and this process),
    /// so that renaming it over `path` is atomic.
    pub fn temporary_beside(path: &Path) -> std::io::Result<PathBuf> {
        let name = path
            .file_name()
            .ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidInput, "no file name"))?;
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let mut tmp = std::ffi::OsString::from(".");
        tmp.push(name);
        tmp.push(std::format!(".{}.tmp", std::process::id()));
        Ok(dir.join(tmp))
    }

    /// Writes `bytes` to `path` complete or not at all: into a temporary file beside it,
    /// flushed and synced, then renamed over `path`. A failure (or a kill) leaves the
    /// previous file, or none, never a truncated one.
    pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
        let tmp = temporary_beside(path)?;
        let result = (|| {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()?;
            std::fs::rename(&tmp, path)
        })();
        if result.is_err() {
            let _ = std::fs::remove_file(&tmp);
        }
        result
    }

    impl BakedSampler {
        /// Writes the bake file (complete or absent: see [`write_atomically`]).
        pub fn save(&self, path: impl AsRef<Path>) -> Result<(), BakeIoError> {
            let path = path.as_ref();
            write_atomically(path, &self.to_bytes()).map_err(|source| BakeIoError::Io {
                path: path.to_path_buf(),
                source,
            })
        }

        /// Reads a bake file (see [`BakedSampler::from_bytes`]). Its header is read first:
        /// no more than the length it declares (and at most [`super::MAX_BAKE_FILE_BYTES`]) is read
        /// after it, so a huge file, or a device such as `/dev/zero`, is an error, not an
        /// unbounded read.
        pub fn load(path: impl AsRef<Path>) -> Result<Self, BakeIoError> {
            let path = path.as_ref();
            let io = |source| BakeIoError::Io {
                path: path.to_path_buf(),
                source,
            };
            let format = |source| BakeIoError::Format {
                path: path.to_path_buf(),
                source,
            };
            let mut file = std::fs::File::open(path).map_err(io)?;
            let mut bytes = std::vec::Vec::new();
            (&mut file)
                .take(HEADER as u64)
                .read_to_end(&mut bytes)
                .map_err(io)?;
            if bytes.len() == HEADER {
                let declared = declared_length(&bytes).map_err(format)?;
                // One byte past the declared length tells a longer file from an exact one.
                let rest = declared + 1 - HEADER as u64;
                let len = file.metadata().map_or(0, |m| m.len());
                bytes.reserve(usize::try_from(len.min(declared)).unwrap_or(0));
                file.take(rest).read_to_end(&mut bytes).map_err(io)?;
                if bytes.len() as u64 > declared {
                    // Only one byte past the declared length was read: the file's own length
                    // (where it has one) says how many more there are.
                    return Err(format(BakeFileError::TrailingBytes {
                        expected: declared,
                        found: len.max(bytes.len() as u64),
                    }));
                }
            }
            Self::from_bytes(&bytes).map_err(format)
        }
    }
}

#[cfg(feature = "std")]
pub use files::{BakeIoError, temporary_beside, write_atomically};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{BakeConfig, BakedMode};

    /// A phong bake of `params` on `theta_steps` rows.
    fn phong_bake(params: &[&str], theta_steps: u16) -> BakedSampler {
        let phong = registry::create("phong", params.iter().copied()).unwrap();
        let config = BakeConfig {
            theta_steps,
            ..BakeConfig::default()
        };
        BakedSampler::new(phong.into(), config).unwrap()
    }

    /// A tree's stored warp shapes: (node, corner word, fine word).
    type StoredShapes = Vec<(u32, u32, u32)>;

    /// A tree as versions 5 and 6 wrote it (its warp's shapes dropped).
    fn slice_record_v6(s: &Slice) -> SliceRecordV6 {
        slice_record(s).tree
    }

    /// `baked` with every warp leaf flat, as a file without shapes reads.
    fn flat_warps(baked: &BakedSampler) -> BakedSampler {
        let mut flat = BakedSampler::from_bytes(&baked.to_bytes()).unwrap();
        for s in flat.forward.slices.iter_mut() {
            s.warp = WarpTable::from_raw(s.warp.shares().collect(), s.map).unwrap();
        }
        flat
    }

    /// A version 9 payload as version 8 would have written it: the warp leaves that spread
    /// in their solid-angle charts dropped from the stored shapes (flat over their squares).
    fn chartless(payload: &[u8]) -> Vec<u8> {
        let mut record: Record = postcard::from_bytes(payload).unwrap();
        for t in core::iter::once(&mut record.forward).chain(record.adjoint.as_mut()) {
            for s in &mut t.slices {
                s.warp_shapes.retain(|&(_, bits, _)| bits & RIM_FLAG == 0);
            }
        }
        postcard::to_allocvec(&record).unwrap()
    }

    /// A version 8 file reads its warps' rim leaves flat over their squares (as written),
    /// a version 9 file in their solid-angle charts: the same rejection sampler, and warp
    /// pdfs that differ near the rim.
    #[test]
    fn a_version_8_file_spreads_its_rim_leaves_over_their_squares() {
        let ct = brdf_core::registry::create("cook-torrance", ["m=1", "kd=0.2"]).unwrap();
        let config = BakeConfig {
            theta_steps: 4,
            ..BakeConfig::default()
        };
        let baked = BakedSampler::new(ct.into(), config).unwrap();
        let bytes = baked.to_bytes();
        let payload = &bytes[HEADER..bytes.len() - TRAILER];
        let charted = baked
            .tables()
            .0
            .slices
            .iter()
            .map(|s| s.warp.shaped().filter(|p| p.2).count());
        assert!(charted.sum::<usize>() >= 4);
        // Lambert's sectors are exact spread over their area: none takes its chart.
        let lambert = registry::create("lambert", [""; 0]).unwrap();
        let flat = BakedSampler::new(lambert.into(), config).unwrap();
        assert!(
            flat.tables()
                .0
                .slices
                .iter()
                .all(|s| s.warp.shaped().all(|p| !p.2))
        );
        // A version 8 reader refuses a chart's mark.
        assert!(BakedSampler::from_bytes(&frame(8, payload)).is_err());
        let mut old = BakedSampler::from_bytes(&frame(8, &chartless(payload))).unwrap();
        let mut new = BakedSampler::from_bytes(&bytes).unwrap();
        let wi = glam::Vec3::new(0.999, 0.0, 0.03).normalize();
        let mut differ = 0;
        for k in 0..50 {
            let a = k as f32 * 0.123;
            let wo = glam::Vec3::new(0.99 * a.cos(), 0.99 * a.sin(), 0.141);
            assert_eq!(old.pdf(wi, wo).unwrap(), new.pdf(wi, wo).unwrap());
            old.set_mode(BakedMode::Warp);
            new.set_mode(BakedMode::Warp);
            differ += usize::from(old.pdf(wi, wo).unwrap() != new.pdf(wi, wo).unwrap());
            old.set_mode(BakedMode::Rejection);
            new.set_mode(BakedMode::Rejection);
        }
        assert!(differ > 25, "{differ}");
    }

    /// A version 7 file of an anisotropic bake (its record is version 8's) still samples
    /// as it did, by rotations onto the query's mirror direction; a version 8 file by the
    /// half-vector transport. The two pdfs differ off the grid.
    #[test]
    fn a_version_7_anisotropic_file_rotates_its_neighbours() {
        let ward = brdf_core::registry::create("ward", ["alpha_x=0.05", "alpha_y=0.3"]).unwrap();
        let config = BakeConfig {
            theta_steps: 4,
            phi_steps: 3,
            ..BakeConfig::default()
        };
        let baked = BakedSampler::new(ward.into(), config).unwrap();
        let bytes = baked.to_bytes();
        assert_eq!(word(&bytes, 8, 4).unwrap(), u64::from(BAKE_FORMAT_VERSION));
        let payload = &bytes[HEADER..bytes.len() - TRAILER];
        let old = BakedSampler::from_bytes(&frame(7, &chartless(payload))).unwrap();
        let new = BakedSampler::from_bytes(&bytes).unwrap();
        assert!(!old.half_vector && new.half_vector && baked.half_vector);
        let mut rotated = BakedSampler::from_bytes(&bytes).unwrap();
        rotated.rotate_neighbours_for_testing();
        let wi = glam::Vec3::new(0.5, 0.3, 0.7).normalize();
        let mut differ = 0;
        for k in 0..50 {
            let a = k as f32 * 0.123;
            let wo = glam::Vec3::new(0.6 * a.cos(), 0.6 * a.sin(), 0.8);
            let p_old = old.pdf(wi, wo).unwrap();
            assert_eq!(p_old.to_bits(), rotated.pdf(wi, wo).unwrap().to_bits());
            assert_eq!(
                new.pdf(wi, wo).unwrap().to_bits(),
                baked.pdf(wi, wo).unwrap().to_bits()
            );
            differ += usize::from(new.pdf(wi, wo).unwrap() != p_old);
        }
        assert!(differ > 40, "{differ}");
    }

    /// A version 6 file (no warp shapes, as this library wrote them before) still reads:
    /// the same trees, every warp leaf flat, its nearest-tree cells dropped (measured
    /// before version 10's horizon band, see [`BAKE_FORMAT_VERSION`]); and
    /// the shapes this bake fitted change the warp's pdf (else they were not stored).
    #[test]
    fn a_version_6_file_reads_with_flat_warps() {
        let baked = phong_bake(&["n=1000", "kd=0"], 8);
        let (forward, _) = baked.tables();
        assert!(forward.slices.iter().any(|s| s.warp.shaped().count() > 0));
        let record = Record {
            model: baked.brdf().name().to_string(),
            params: param_strings(&**baked.brdf()),
            config: ConfigRecord::of(baked.config()),
            domain: domain_code(baked.grid().domain()),
            forward: TablesRecord {
                slices: forward.slices.iter().map(slice_record_v6).collect(),
                nearest: NearestRecord {
                    theta: forward.nearest.theta.clone(),
                    phi: forward.nearest.phi.clone(),
                },
            },
            adjoint: None,
        };
        let v6 = frame(6, &postcard::to_allocvec(&record).unwrap());
        let old = BakedSampler::from_bytes(&v6).unwrap();
        assert_eq!(old.forward.slices, flat_warps(&baked).forward.slices);
        assert!(old.forward.nearest.theta.is_empty());
        let back = BakedSampler::from_bytes(&baked.to_bytes()).unwrap();
        assert_eq!(back.forward, baked.forward);
        let wi = glam::Vec3::new(0.45, 0.1, 0.8).normalize();
        let (old, new) = (
            old.with_mode(crate::BakedMode::Warp),
            back.with_mode(crate::BakedMode::Warp),
        );
        let differ = (0..200)
            .filter(|&k| {
                let a = f32::from(k as u8) * 0.031;
                let wo =
                    glam::Vec3::new(-0.4 + 0.1 * a.cos(), -0.1 + 0.1 * a.sin(), 0.9).normalize();
                old.pdf(wi, wo).unwrap() != new.pdf(wi, wo).unwrap()
            })
            .count();
        assert!(differ > 100, "{differ} of 200 pdfs differ");
    }

    /// Stored shapes that no fit writes are typed errors: on a branch, twice, out of order,
    /// flat, or with words no shape has.
    #[test]
    fn malformed_warp_shapes_are_refused() {
        let baked = phong_bake(&["n=1000", "kd=0"], 4);
        let edit = |f: &dyn Fn(&mut StoredShapes, &Slice)| {
            let (forward, _) = baked.tables();
            let mut record = baked.record();
            let k = forward
                .slices
                .iter()
                .position(|s| s.warp.shaped().count() > 1)
                .unwrap();
            f(
                &mut record.forward.slices[k].warp_shapes,
                &forward.slices[k],
            );
            BakedSampler::from_bytes(&frame(
                BAKE_FORMAT_VERSION,
                &current_payload(record, baked.max_bytes()),
            ))
        };
        assert!(edit(&|_, _| {}).is_ok());
        let refused = |r: Result<BakedSampler, BakeFileError>| {
            assert!(matches!(r, Err(BakeFileError::Tree { .. })), "{r:?}");
        };
        refused(edit(&|v, _| v[0].0 = 0));
        refused(edit(&|v, _| v.swap(0, 1)));
        refused(edit(&|v, _| {
            let first = v[0];
            v.insert(0, first);
        }));
        refused(edit(&|v, _| {
            v[0].1 = 0;
            v[0].2 = 0;
        }));
        refused(edit(&|v, _| v[0].2 = 7));
        refused(edit(&|v, s| v.push((s.warp.len() as u32, v[0].1, v[0].2))));
    }

    /// A tree volume that is not its leaves' sum, in a file whose checksum is right (a
    /// writer's bug, not a corrupted byte), is a typed error: every rejection-mode pdf of
    /// that tree would be off by the ratio (a volume flushed to 10⁻³⁰⁰ by one zeroed byte
    /// made it infinite, found by mutating payloads under a recomputed checksum). Rounding
    /// the volume to f32 and back, as a writer might, still reads.
    #[test]
    fn a_volume_that_is_not_its_leaves_sum_is_refused() {
        let baked = phong_bake(&["n=1000"], 4);
        let edit = |f: &dyn Fn(&mut f64)| {
            let mut record = baked.record();
            f(&mut record.forward.slices[1].tree.volume);
            BakedSampler::from_bytes(&frame(
                BAKE_FORMAT_VERSION,
                &current_payload(record, baked.max_bytes()),
            ))
        };
        assert!(edit(&|_| {}).is_ok());
        assert!(edit(&|v| *v = f64::from(*v as f32)).is_ok());
        for change in [
            (|v: &mut f64| *v *= 1.0 + 1e-5) as fn(&mut f64),
            |v| *v *= 0.5,
            |v| *v = 1e-300,
            |v| *v = 0.0,
            |v| *v = f64::from_bits(v.to_bits() ^ (1 << 40)),
        ] {
            assert!(
                matches!(
                    edit(&change),
                    Err(BakeFileError::Tree {
                        index: 1,
                        fault: "a tree volume that is not the sum of its leaves' v1"
                    })
                ),
                "{:?}",
                edit(&change).err()
            );
        }
    }

    /// Split cuts that are not the leaves' shares of the volume, under a valid checksum, are
    /// a typed error: selection would draw leaves away from the volumes the pdf divides by.
    /// A cut moved by 100 units (2⁻³¹ each: less than the f32 rounding of the shares can
    /// move one) still reads; by 2²⁰, or so that a live leaf gets no width, it does not.
    #[test]
    fn cuts_that_are_not_the_volumes_shares_are_refused() {
        let baked = phong_bake(&["n=1000"], 4);
        let edit = |f: &dyn Fn(&mut Vec<[u32; 4]>)| {
            let mut record = baked.record();
            f(&mut record.forward.slices[2].tree.packed);
            BakedSampler::from_bytes(&frame(
                BAKE_FORMAT_VERSION,
                &current_payload(record, baked.max_bytes()),
            ))
        };
        let root = baked.tables().0.slices[2].tree.raw_nodes()[0];
        assert!(root[1] < root[2] && root[2] - root[1] > 1 << 21, "{root:?}");
        assert!(edit(&|_| {}).is_ok());
        assert!(edit(&|t| t[0][1] += 100).is_ok());
        let refused = |r: Result<BakedSampler, BakeFileError>| {
            assert!(
                matches!(
                    r,
                    Err(BakeFileError::Tree {
                        index: 2,
                        fault: "a leaf whose selection interval is not its share of the volume"
                            | "a leaf with volume that selection cannot reach"
                    })
                ),
                "{:?}",
                r.as_ref().err()
            );
        };
        refused(edit(&|t| t[0][1] += 1 << 20));
        refused(edit(&|t| t[0][2] = t[0][1]));
    }

    /// A version 5 file (the trees without nearest-tree cells, as this library wrote them
    /// before) still reads: the same trees, and a sampler that blends every cell as it did,
    /// bit for bit the pdf of this bake with its cells cleared.
    #[test]
    fn a_version_5_file_reads_and_blends_everywhere() {
        let baked = phong_bake(&["n=1000", "kd=0"], 8);
        let (forward, _) = baked.tables();
        let record = RecordV5 {
            model: baked.brdf().name().to_string(),
            params: param_strings(&**baked.brdf()),
            config: ConfigRecord::of(baked.config()),
            domain: domain_code(baked.grid().domain()),
            forward: forward.slices.iter().map(slice_record_v6).collect(),
            adjoint: None,
        };
        let v5 = frame(5, &postcard::to_allocvec(&record).unwrap());
        let old = BakedSampler::from_bytes(&v5).unwrap();
        let flat = flat_warps(&baked);
        assert_eq!(old.forward.slices, flat.forward.slices);
        assert!(old.forward.nearest.theta.is_empty());
        assert!(baked.nearest_cells(crate::BakedMode::Rejection).0 > 0);
        let mut blended = BakedSampler::from_bytes(&flat.to_bytes()).unwrap();
        blended.blend_everywhere_for_testing();
        let wi = glam::Vec3::new(0.45, 0.1, 0.8).normalize();
        let role = crate::Role::Importance;
        assert_eq!(old.mixture_at(role, wi), blended.mixture_at(role, wi));
        assert_eq!(baked.mixture_at(role, wi).unwrap().len(), 1);
        assert_same_pdfs(&old, &blended, wi, 200);
    }

    /// A version 9 file's nearest-tree cells, measured without the horizon band, are
    /// dropped: it reads as this bake with every cell blending, bit for bit in its pdf; the
    /// same record as version 10 keeps them.
    #[test]
    fn a_version_9_file_drops_its_nearest_tree_cells() {
        let baked = phong_bake(&["n=1000", "kd=0"], 8);
        assert!(baked.nearest_cells(crate::BakedMode::Rejection).0 > 0);
        let bytes = baked.to_bytes();
        let payload = &bytes[HEADER..bytes.len() - TRAILER];
        let old = BakedSampler::from_bytes(&frame(9, payload)).unwrap();
        assert!(old.forward.nearest.theta.is_empty());
        let kept = BakedSampler::from_bytes(&frame(10, payload)).unwrap();
        assert_eq!(kept.forward, baked.forward);
        let mut blended = BakedSampler::from_bytes(&bytes).unwrap();
        blended.blend_everywhere_for_testing();
        assert_eq!(old.forward, blended.forward);
        let wi = glam::Vec3::new(0.45, 0.1, 0.8).normalize();
        assert_same_pdfs(&old, &blended, wi, 100);
    }

    /// `a` and `b` report the same pdf at `wi`, bit for bit, at `n` directions on a small
    /// circle around (−0.4, −0.1, 0.9).
    fn assert_same_pdfs(a: &BakedSampler, b: &BakedSampler, wi: glam::Vec3, n: u8) {
        for k in 0..n {
            let t = f32::from(k) * 0.031;
            let wo = glam::Vec3::new(-0.4 + 0.1 * t.cos(), -0.1 + 0.1 * t.sin(), 0.9).normalize();
            assert_eq!(
                a.pdf(wi, wo).unwrap().to_bits(),
                b.pdf(wi, wo).unwrap().to_bits(),
                "wo {wo}"
            );
        }
    }

    /// A file whose nearest-tree cells do not fit its grid (one flag short, or φ flags on an
    /// isotropic grid) is a typed error, not an index out of range at the first query; the
    /// file as written reads back equal, cells included.
    #[test]
    fn nearest_cells_that_do_not_fit_the_grid_are_refused() {
        let baked = phong_bake(&["n=100"], 4);
        let back = BakedSampler::from_bytes(&baked.to_bytes()).unwrap();
        assert_eq!(back.forward, baked.forward);
        let mut short = BakedSampler::from_bytes(&baked.to_bytes()).unwrap();
        short.forward.nearest.theta.pop();
        assert_eq!(
            BakedSampler::from_bytes(&short.to_bytes()).unwrap_err(),
            BakeFileError::GridMismatch
        );
        let mut phi = BakedSampler::from_bytes(&baked.to_bytes()).unwrap();
        phi.forward.nearest.phi = alloc::vec![true; phi.grid.cells()];
        assert_eq!(
            BakedSampler::from_bytes(&phi.to_bytes()).unwrap_err(),
            BakeFileError::GridMismatch
        );
    }
}
