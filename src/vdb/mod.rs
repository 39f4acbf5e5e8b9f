//! Our own OpenVDB reader and writer, loading straight into [`SparseGrid`]s.
//!
//! Written from the published file format (OpenVDB's documentation and source as facts):
//! file versions 222 to 224 (OpenVDB 3 to 12 write 224), trees `5_4_3` of `float`,
//! half-saved `float`, `double`, `vec3s` and `vec3d`; no, zip and blosc compression, each with
//! or without active-mask compression; active and inactive tiles at every level including the
//! root; every linear map (uniform scale, scale, translation, scale-translate, affine,
//! unitary). VDB leaves become bricks directly. The writer writes `float` (optionally saved as
//! half) and `vec3s` grids with name, class, extra metadata and transform, with no, zip or
//! blosc compression.
//!
//! Every size read from a file is checked against the bytes that remain before anything is
//! allocated: damaged files give a [`VdbError`], never a panic or a huge allocation.

pub mod blosc;
mod codec;
mod read;
mod stats;
mod write;

pub use read::VdbFile;
pub use stats::GridStats;
pub use write::{
    write_vdb, write_vdb_to_vec, write_vdb_to_vec_with_metadata, write_vdb_with_metadata,
    Compression, GridToWrite, WriteOptions,
};

use crate::grid::{GridError, SparseGrid};
use glam::{DAffine3, DMat3, DVec3};
use std::path::{Path, PathBuf};

/// Errors of reading and writing OpenVDB files. Every variant names the file or grid.
#[derive(Debug, thiserror::Error)]
pub enum VdbError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// The file is damaged, truncated or not a VDB file.
    #[error("{path}: at byte {offset}: {msg}")]
    Format {
        /// The file.
        path: PathBuf,
        /// Byte offset where the problem was found.
        offset: u64,
        /// What is wrong.
        msg: String,
    },
    /// A grid whose value type or tree layout velour does not read.
    #[error("{path}: grid '{grid}' has unsupported type '{type_name}' (velour reads Tree_float_5_4_3, Tree_double_5_4_3, Tree_vec3s_5_4_3 and Tree_vec3d_5_4_3 grids)")]
    UnsupportedType {
        /// The file.
        path: PathBuf,
        /// Grid name.
        grid: String,
        /// The grid's type name as stored in the file.
        type_name: String,
    },
    /// A grid with a transform velour does not support (e.g. frustum maps).
    #[error(
        "{path}: grid '{grid}' has unsupported transform '{map}' (velour reads linear maps only)"
    )]
    UnsupportedMap {
        /// The file.
        path: PathBuf,
        /// Grid name.
        grid: String,
        /// Map type name.
        map: String,
    },
    /// A requested grid is not in the file.
    #[error("{path}: no grid named '{name}'; the file has: {}", if available.is_empty() { "no grids".to_string() } else { available.join(", ") })]
    NoSuchGrid {
        /// The file.
        path: PathBuf,
        /// Requested name.
        name: String,
        /// Names of the grids in the file.
        available: Vec<String>,
    },
    /// A grid holds NaN or infinite active values.
    #[error("grid '{grid}' holds {count} non-finite (NaN or infinite) active values")]
    NonFinite {
        /// Grid name.
        grid: String,
        /// Number of non-finite active values (tiles count once).
        count: u64,
    },
    /// A grid-construction error.
    #[error("grid '{grid}': {source}")]
    Grid {
        /// Grid name.
        grid: String,
        /// The error.
        source: GridError,
    },
    /// A grid that cannot be written (e.g. a channel out of range).
    #[error("cannot write grid '{grid}': {msg}")]
    Write {
        /// Grid name.
        grid: String,
        /// What is wrong.
        msg: String,
    },
}

/// Value type of a VDB grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ValueType {
    /// 32-bit float (`Tree_float_5_4_3`).
    Float,
    /// 64-bit float (`Tree_double_5_4_3`), loaded as f32.
    Double,
    /// Vector of three 32-bit floats (`Tree_vec3s_5_4_3`).
    Vec3s,
    /// Vector of three 64-bit floats (`Tree_vec3d_5_4_3`), loaded as f32.
    Vec3d,
}

impl ValueType {
    /// The short name OpenVDB prints (`float`, `double`, `vec3s`, `vec3d`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            ValueType::Float => "float",
            ValueType::Double => "double",
            ValueType::Vec3s => "vec3s",
            ValueType::Vec3d => "vec3d",
        }
    }
    /// The tree type name stored in files, without the `_HalfFloat` suffix.
    #[must_use]
    pub fn tree_type(self) -> String {
        format!("Tree_{}_5_4_3", self.name())
    }
    /// Components per value.
    #[must_use]
    pub fn components(self) -> usize {
        match self {
            ValueType::Float | ValueType::Double => 1,
            ValueType::Vec3s | ValueType::Vec3d => 3,
        }
    }
    /// Bytes per component at full precision.
    #[must_use]
    pub fn component_bytes(self) -> usize {
        match self {
            ValueType::Float | ValueType::Vec3s => 4,
            ValueType::Double | ValueType::Vec3d => 8,
        }
    }
    fn from_tree_type(s: &str) -> Option<Self> {
        match s {
            "Tree_float_5_4_3" => Some(ValueType::Float),
            "Tree_double_5_4_3" => Some(ValueType::Double),
            "Tree_vec3s_5_4_3" => Some(ValueType::Vec3s),
            "Tree_vec3d_5_4_3" => Some(ValueType::Vec3d),
            _ => None,
        }
    }
}

/// An OpenVDB linear map from index space to world space, as stored in the file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VdbMap {
    /// `world = s * index`.
    UniformScale(f64),
    /// `world = s ⊙ index`.
    Scale(DVec3),
    /// `world = index + t`.
    Translation(DVec3),
    /// `world = s * index + t`.
    UniformScaleTranslate {
        /// Scale.
        scale: f64,
        /// Translation.
        translation: DVec3,
    },
    /// `world = s ⊙ index + t`.
    ScaleTranslate {
        /// Per-axis scale.
        scale: DVec3,
        /// Translation.
        translation: DVec3,
    },
    /// A general affine map.
    Affine(DAffine3),
    /// A rotation (stored as an affine matrix).
    Unitary(DAffine3),
}

impl VdbMap {
    /// The map's type name in files (`UniformScaleMap`, `AffineMap`, ...).
    #[must_use]
    pub fn type_name(&self) -> &'static str {
        match self {
            VdbMap::UniformScale(_) => "UniformScaleMap",
            VdbMap::Scale(_) => "ScaleMap",
            VdbMap::Translation(_) => "TranslationMap",
            VdbMap::UniformScaleTranslate { .. } => "UniformScaleTranslateMap",
            VdbMap::ScaleTranslate { .. } => "ScaleTranslateMap",
            VdbMap::Affine(_) => "AffineMap",
            VdbMap::Unitary(_) => "UnitaryMap",
        }
    }
    /// The map as an affine transform (f64).
    #[must_use]
    pub fn to_affine(&self) -> DAffine3 {
        match *self {
            VdbMap::UniformScale(s) => DAffine3::from_scale(DVec3::splat(s)),
            VdbMap::Scale(s) => DAffine3::from_scale(s),
            VdbMap::Translation(t) => DAffine3::from_translation(t),
            VdbMap::UniformScaleTranslate { scale, translation } => {
                DAffine3::from_scale_rotation_translation(
                    DVec3::splat(scale),
                    glam::DQuat::IDENTITY,
                    translation,
                )
            }
            VdbMap::ScaleTranslate { scale, translation } => {
                DAffine3::from_scale_rotation_translation(scale, glam::DQuat::IDENTITY, translation)
            }
            VdbMap::Affine(m) | VdbMap::Unitary(m) => m,
        }
    }
    /// The simplest map type that represents `m` exactly.
    #[must_use]
    pub fn from_affine(m: DAffine3) -> Self {
        let a = m.matrix3;
        let diag = a.x_axis.y == 0.0
            && a.x_axis.z == 0.0
            && a.y_axis.x == 0.0
            && a.y_axis.z == 0.0
            && a.z_axis.x == 0.0
            && a.z_axis.y == 0.0;
        if !diag {
            return VdbMap::Affine(m);
        }
        let s = DVec3::new(a.x_axis.x, a.y_axis.y, a.z_axis.z);
        let uniform = s.x == s.y && s.y == s.z;
        let t = m.translation;
        match (uniform, t == DVec3::ZERO) {
            (true, true) if s.x == 1.0 => VdbMap::Translation(t),
            (true, true) => VdbMap::UniformScale(s.x),
            (false, true) => VdbMap::Scale(s),
            (true, false) if s.x == 1.0 => VdbMap::Translation(t),
            (true, false) => VdbMap::UniformScaleTranslate {
                scale: s.x,
                translation: t,
            },
            (false, false) => VdbMap::ScaleTranslate {
                scale: s,
                translation: t,
            },
        }
    }
}

/// One metadata entry as stored in the file: name, type name and raw value bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct MetaEntry {
    /// Metadata name (e.g. `class`).
    pub name: String,
    /// Type name (`string`, `bool`, `int64`, `vec3i`, `float`, ...).
    pub type_name: String,
    /// The value's bytes (little endian).
    pub data: Vec<u8>,
}

impl MetaEntry {
    /// A string entry.
    #[must_use]
    pub fn string(name: &str, value: &str) -> Self {
        MetaEntry {
            name: name.into(),
            type_name: "string".into(),
            data: value.as_bytes().to_vec(),
        }
    }
    /// An `int64` entry.
    #[must_use]
    pub fn int64(name: &str, value: i64) -> Self {
        MetaEntry {
            name: name.into(),
            type_name: "int64".into(),
            data: value.to_le_bytes().to_vec(),
        }
    }
    /// A `float` entry.
    #[must_use]
    pub fn float(name: &str, value: f32) -> Self {
        MetaEntry {
            name: name.into(),
            type_name: "float".into(),
            data: value.to_le_bytes().to_vec(),
        }
    }
    /// A `double` entry.
    #[must_use]
    pub fn double(name: &str, value: f64) -> Self {
        MetaEntry {
            name: name.into(),
            type_name: "double".into(),
            data: value.to_le_bytes().to_vec(),
        }
    }
    /// A `vec3s` entry.
    #[must_use]
    pub fn vec3s(name: &str, value: [f32; 3]) -> Self {
        MetaEntry {
            name: name.into(),
            type_name: "vec3s".into(),
            data: value.iter().flat_map(|x| x.to_le_bytes()).collect(),
        }
    }
    /// The value of a `string` entry.
    #[must_use]
    pub fn as_str(&self) -> Option<&str> {
        (self.type_name == "string")
            .then(|| std::str::from_utf8(&self.data).ok())
            .flatten()
    }
    /// The value of an `int32` or `int64` entry.
    #[must_use]
    pub fn as_i64(&self) -> Option<i64> {
        match (self.type_name.as_str(), self.data.as_slice()) {
            ("int32", &[a, b, c, d]) => Some(i64::from(i32::from_le_bytes([a, b, c, d]))),
            ("int64", &[a, b, c, d, e, f, g, h]) => {
                Some(i64::from_le_bytes([a, b, c, d, e, f, g, h]))
            }
            _ => None,
        }
    }
    /// The value of a `float` or `double` entry.
    #[must_use]
    pub fn as_f64(&self) -> Option<f64> {
        match (self.type_name.as_str(), self.data.as_slice()) {
            ("float", &[a, b, c, d]) => Some(f64::from(f32::from_le_bytes([a, b, c, d]))),
            ("double", &[a, b, c, d, e, f, g, h]) => {
                Some(f64::from_le_bytes([a, b, c, d, e, f, g, h]))
            }
            _ => None,
        }
    }
    /// The value of a `vec3s` entry.
    #[must_use]
    pub fn as_vec3s(&self) -> Option<[f32; 3]> {
        if self.type_name != "vec3s" || self.data.len() != 12 {
            return None;
        }
        let mut v = [0.0f32; 3];
        for (x, c) in v.iter_mut().zip(self.data.chunks_exact(4)) {
            *x = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
        }
        Some(v)
    }
    /// The value as text, for printing (`None` for types without a text form).
    #[must_use]
    pub fn display(&self) -> Option<String> {
        let d = &self.data;
        let i32s = |n: usize| -> Option<Vec<i32>> {
            (d.len() == 4 * n).then(|| {
                d.chunks_exact(4)
                    .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            })
        };
        let f64s = |n: usize| -> Option<Vec<f64>> {
            (d.len() == 8 * n).then(|| {
                d.chunks_exact(8)
                    .map(|c| f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]))
                    .collect()
            })
        };
        let f32s = |n: usize| -> Option<Vec<f32>> {
            (d.len() == 4 * n).then(|| {
                d.chunks_exact(4)
                    .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                    .collect()
            })
        };
        match self.type_name.as_str() {
            "string" => Some(String::from_utf8_lossy(d).into_owned()),
            "bool" => d.first().map(|&b| (b != 0).to_string()),
            "int32" => i32s(1).map(|v| v[0].to_string()),
            "int64" => (d.len() == 8).then(|| {
                i64::from_le_bytes([d[0], d[1], d[2], d[3], d[4], d[5], d[6], d[7]]).to_string()
            }),
            "float" => f32s(1).map(|v| v[0].to_string()),
            "double" => f64s(1).map(|v| v[0].to_string()),
            "vec3i" => i32s(3).map(|v| format!("[{}, {}, {}]", v[0], v[1], v[2])),
            "vec3s" => f32s(3).map(|v| format!("[{}, {}, {}]", v[0], v[1], v[2])),
            "vec3d" => f64s(3).map(|v| format!("[{}, {}, {}]", v[0], v[1], v[2])),
            _ => None,
        }
    }
}

/// A grid read from a VDB file.
#[derive(Clone, Debug)]
pub struct VdbGrid {
    /// Grid name (the `name` metadata, or the descriptor name).
    pub name: String,
    /// Value type in the file.
    pub value_type: ValueType,
    /// Grid class (`fog volume`, `level set`, `staggered`, `unknown`).
    pub class: String,
    /// Whether the file stores the values as 16-bit halves.
    pub saved_as_half: bool,
    /// Compression flags of the grid in the file (see [`Compression`]).
    pub compression_flags: u32,
    /// The file's index-to-world map.
    pub map: VdbMap,
    /// Every metadata entry of the grid as stored in the file.
    pub metadata: Vec<MetaEntry>,
    /// The values: one channel (scalar or Vec3) named after the grid.
    pub grid: SparseGrid,
}

impl VdbGrid {
    /// Statistics of the active values (OpenVDB's definitions; see [`GridStats`]).
    #[must_use]
    pub fn stats(&self) -> GridStats {
        GridStats::compute(&self.grid, 0)
    }
    /// Refuses grids with NaN or infinite active values, naming the grid.
    ///
    /// # Errors
    /// [`VdbError::NonFinite`].
    pub fn check_finite(&self) -> Result<(), VdbError> {
        let s = self.stats();
        if s.non_finite > 0 {
            return Err(VdbError::NonFinite {
                grid: self.name.clone(),
                count: s.non_finite,
            });
        }
        Ok(())
    }
}

/// Reads every grid of a VDB file.
///
/// # Errors
/// See [`VdbError`].
pub fn read_vdb(path: impl AsRef<Path>) -> Result<Vec<VdbGrid>, VdbError> {
    let f = VdbFile::open(path)?;
    f.read_all()
}

/// Reads only the named grids of a VDB file, in the order asked.
///
/// # Errors
/// [`VdbError::NoSuchGrid`] (listing the grids the file has) for a missing name; see
/// [`VdbError`].
pub fn read_vdb_grids(path: impl AsRef<Path>, names: &[&str]) -> Result<Vec<VdbGrid>, VdbError> {
    let f = VdbFile::open(path)?;
    names.iter().map(|n| f.read_grid(n)).collect()
}

pub(crate) fn dmat3_is_finite(m: &DMat3) -> bool {
    m.x_axis.is_finite() && m.y_axis.is_finite() && m.z_axis.is_finite()
}
