//! The reader: header, grid descriptors, metadata, transforms and trees.

use super::codec::{Reader, ValueCodec};
use super::{dmat3_is_finite, MetaEntry, ValueType, VdbError, VdbGrid, VdbMap};
use crate::grid::{ChannelKind, SparseGridBuilder, Storage, TileLevel};
use glam::{DAffine3, DMat3, DVec3, IVec3, Vec3};
use rayon::prelude::*;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

const MAGIC: [u8; 8] = [0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0];
const MIN_VERSION: u32 = 222;
const HALF_SUFFIX: &str = "_HalfFloat";

/// Where a grid lives in the file (OpenVDB's `GridDescriptor`).
#[derive(Clone, Debug)]
struct Descriptor {
    unique_name: String,
    name: String,
    type_name: String,
    half: bool,
    parent: String,
    grid_pos: u64,
    end_pos: u64,
}

/// An opened VDB file: its header and the list of its grids. Grids are decoded on demand, so
/// a scene that needs one grid of a large file decodes only that grid.
#[derive(Clone, Debug)]
pub struct VdbFile {
    path: PathBuf,
    bytes: Option<std::sync::Arc<Vec<u8>>>,
    len: u64,
    /// File format version (e.g. 224).
    pub version: u32,
    /// Version `(major, minor)` of the library that wrote the file.
    pub library_version: (u32, u32),
    /// The file's UUID string.
    pub uuid: String,
    /// File-level metadata.
    pub metadata: Vec<MetaEntry>,
    grids: Vec<Descriptor>,
}

fn io_err(path: &Path, source: std::io::Error) -> VdbError {
    VdbError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Where the bytes of a VDB file come from.
enum Source<'a> {
    File(File),
    Bytes(&'a [u8]),
}

fn read_range(
    f: &mut Source<'_>,
    path: &Path,
    start: u64,
    len: usize,
) -> Result<Vec<u8>, VdbError> {
    match f {
        Source::File(f) => {
            f.seek(SeekFrom::Start(start))
                .map_err(|e| io_err(path, e))?;
            let mut v = vec![0u8; len];
            f.read_exact(&mut v).map_err(|e| io_err(path, e))?;
            Ok(v)
        }
        Source::Bytes(b) => usize::try_from(start)
            .ok()
            .and_then(|s| b.get(s..s.checked_add(len)?))
            .map(<[u8]>::to_vec)
            .ok_or_else(|| VdbError::Format {
                path: path.to_path_buf(),
                offset: start,
                msg: "range beyond the data".into(),
            }),
    }
}

/// Parses with `parse` from a chunk of the file at `start`, growing the chunk while the
/// parser runs out of bytes and the file has more.
fn parse_growing<T>(
    f: &mut Source<'_>,
    path: &Path,
    file_len: u64,
    start: u64,
    mut parse: impl FnMut(&mut Reader<'_>) -> Result<T, VdbError>,
) -> Result<T, VdbError> {
    let mut chunk: u64 = 1 << 16;
    loop {
        let len = chunk.min(file_len.saturating_sub(start));
        let bytes = read_range(f, path, start, len as usize)?;
        let mut r = Reader::new(&bytes, start, path);
        match parse(&mut r) {
            Err(VdbError::Format { msg, .. })
                if msg.starts_with("unexpected end") && start + len < file_len =>
            {
                chunk *= 4;
            }
            other => return other,
        }
    }
}

fn read_metadata(r: &mut Reader<'_>) -> Result<Vec<MetaEntry>, VdbError> {
    let count = r.u32("metadata count")? as usize;
    // Every entry takes at least 12 bytes.
    if count > r.remaining() / 12 {
        return Err(r.err(format!("metadata count {count} exceeds the data left")));
    }
    let mut out = Vec::with_capacity(count);
    for _ in 0..count {
        let name = r.string("metadata name")?;
        let type_name = r.string("metadata type")?;
        let data = r.bytes_string("metadata value")?;
        out.push(MetaEntry {
            name,
            type_name,
            data,
        });
    }
    Ok(out)
}

fn meta_string(m: &[MetaEntry], name: &str) -> Option<String> {
    m.iter()
        .find(|e| e.name == name && e.type_name == "string")
        .map(|e| String::from_utf8_lossy(&e.data).into_owned())
}

fn read_map(r: &mut Reader<'_>, path: &Path, grid: &str) -> Result<VdbMap, VdbError> {
    let at = r.offset();
    let type_name = r.string("transform type")?;
    let map = match type_name.as_str() {
        "UniformScaleMap" | "ScaleMap" => {
            let s = r.dvec3("map scale")?;
            r.take(4 * 24, "map data")?;
            if type_name == "UniformScaleMap" {
                VdbMap::UniformScale(s.x)
            } else {
                VdbMap::Scale(s)
            }
        }
        "TranslationMap" => VdbMap::Translation(r.dvec3("map translation")?),
        "UniformScaleTranslateMap" | "ScaleTranslateMap" => {
            let t = r.dvec3("map translation")?;
            let s = r.dvec3("map scale")?;
            r.take(4 * 24, "map data")?;
            if type_name == "UniformScaleTranslateMap" {
                VdbMap::UniformScaleTranslate {
                    scale: s.x,
                    translation: t,
                }
            } else {
                VdbMap::ScaleTranslate {
                    scale: s,
                    translation: t,
                }
            }
        }
        "AffineMap" | "UnitaryMap" => {
            let mut m = [0f64; 16];
            for v in &mut m {
                *v = r.f64("map matrix")?;
            }
            // OpenVDB multiplies row vectors: rows 0..2 are the images of the index axes,
            // row 3 the translation.
            let a = DAffine3 {
                matrix3: DMat3::from_cols(
                    DVec3::new(m[0], m[1], m[2]),
                    DVec3::new(m[4], m[5], m[6]),
                    DVec3::new(m[8], m[9], m[10]),
                ),
                translation: DVec3::new(m[12], m[13], m[14]),
            };
            if type_name == "AffineMap" {
                VdbMap::Affine(a)
            } else {
                VdbMap::Unitary(a)
            }
        }
        _ => {
            return Err(VdbError::UnsupportedMap {
                path: path.to_path_buf(),
                grid: grid.into(),
                map: type_name,
            });
        }
    };
    let a = map.to_affine();
    let det = a.matrix3.determinant();
    if !dmat3_is_finite(&a.matrix3)
        || !a.translation.is_finite()
        || !det.is_finite()
        || det.abs() < 1e-300
    {
        return Err(VdbError::Format {
            path: path.to_path_buf(),
            offset: at,
            msg: format!("grid '{grid}': {type_name} is not invertible or not finite"),
        });
    }
    Ok(map)
}

impl VdbFile {
    /// Opens a VDB file and reads its header and grid list (no grid data).
    ///
    /// # Errors
    /// I/O errors, a file that is not a VDB file, a format version below 222, or a damaged
    /// header.
    pub fn open(path: impl AsRef<Path>) -> Result<VdbFile, VdbError> {
        let path = path.as_ref();
        let f = File::open(path).map_err(|e| io_err(path, e))?;
        let len = f.metadata().map_err(|e| io_err(path, e))?.len();
        Self::parse_header(path, Source::File(f), len, None)
    }

    /// Reads a VDB file held in memory; `name` stands for the file's path in messages.
    ///
    /// # Errors
    /// As [`VdbFile::open`].
    pub fn from_bytes(name: impl AsRef<Path>, bytes: Vec<u8>) -> Result<VdbFile, VdbError> {
        let bytes = std::sync::Arc::new(bytes);
        let len = bytes.len() as u64;
        Self::parse_header(
            name.as_ref(),
            Source::Bytes(&bytes.clone()),
            len,
            Some(bytes),
        )
    }

    fn source(&self) -> Result<Source<'_>, VdbError> {
        match &self.bytes {
            Some(b) => Ok(Source::Bytes(b)),
            None => File::open(&self.path)
                .map(Source::File)
                .map_err(|e| io_err(&self.path, e)),
        }
    }

    fn parse_header(
        path: &Path,
        mut f: Source<'_>,
        len: u64,
        bytes: Option<std::sync::Arc<Vec<u8>>>,
    ) -> Result<VdbFile, VdbError> {
        let (version, library_version, uuid, metadata, count, first) = parse_growing(
            &mut f,
            path,
            len,
            0,
            |r| {
                let magic = r.take(8, "magic number")?;
                if magic != MAGIC {
                    return Err(r.err("not an OpenVDB file (bad magic number)"));
                }
                let version = r.u32("file version")?;
                if version < MIN_VERSION {
                    return Err(r.err(format!(
                        "file format version {version} is older than 222 (OpenVDB 3), which velour does not read"
                    )));
                }
                let lib = (r.u32("library version")?, r.u32("library version")?);
                let has_offsets = r.u8("grid-offsets flag")?;
                if has_offsets == 0 {
                    return Err(
                        r.err("files without grid offsets (streamed VDBs) are not supported")
                    );
                }
                let uuid = String::from_utf8_lossy(r.take(36, "uuid")?).into_owned();
                let metadata = read_metadata(r)?;
                let count = r.i32("grid count")?;
                if count < 0 || count as u64 > len / 40 {
                    return Err(r.err(format!("invalid grid count {count}")));
                }
                Ok((version, lib, uuid, metadata, count as usize, r.offset()))
            },
        )?;
        let mut grids: Vec<Descriptor> = Vec::with_capacity(count);
        let mut pos = first;
        for _ in 0..count {
            let d = parse_growing(&mut f, path, len, pos, |r| {
                let unique_name = r.string("grid name")?;
                let mut type_name = r.string("grid type")?;
                let half = type_name.ends_with(HALF_SUFFIX);
                if half {
                    type_name.truncate(type_name.len() - HALF_SUFFIX.len());
                }
                let parent = r.string("instance parent")?;
                let at = r.offset();
                let gp = r.i64("grid position")?;
                let bp = r.i64("block position")?;
                let ep = r.i64("end position")?;
                let here = r.offset() as i64;
                // Instances have no blocks of their own: their block position is 0.
                if gp < here || ep < gp || (bp != 0 && (bp < gp || bp > ep)) || ep as u64 > len {
                    return Err(VdbError::Format {
                        path: path.to_path_buf(),
                        offset: at,
                        msg: format!("grid '{unique_name}': invalid positions {gp}, {bp}, {ep} (file is {len} bytes)"),
                    });
                }
                let name = unique_name.split('\u{1e}').next().unwrap_or("").to_string();
                Ok(Descriptor {
                    unique_name,
                    name,
                    type_name,
                    half,
                    parent,
                    grid_pos: gp as u64,
                    end_pos: ep as u64,
                })
            })?;
            pos = d.end_pos;
            grids.push(d);
        }
        Ok(VdbFile {
            path: path.to_path_buf(),
            bytes,
            len,
            version,
            library_version,
            uuid,
            metadata,
            grids,
        })
    }

    /// The file's path.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Names of the grids in file order.
    #[must_use]
    pub fn grid_names(&self) -> Vec<String> {
        self.grids.iter().map(|d| d.name.clone()).collect()
    }

    /// Stored tree type names of the grids in file order (without `_HalfFloat`).
    #[must_use]
    pub fn grid_types(&self) -> Vec<String> {
        self.grids.iter().map(|d| d.type_name.clone()).collect()
    }

    /// Reads every grid.
    ///
    /// # Errors
    /// See [`VdbError`].
    pub fn read_all(&self) -> Result<Vec<VdbGrid>, VdbError> {
        (0..self.grids.len()).map(|i| self.read_index(i)).collect()
    }

    /// Reads the first grid called `name`.
    ///
    /// # Errors
    /// [`VdbError::NoSuchGrid`] listing the file's grids; see [`VdbError`].
    pub fn read_grid(&self, name: &str) -> Result<VdbGrid, VdbError> {
        let i = self
            .grids
            .iter()
            .position(|d| d.name == name || d.unique_name == name)
            .ok_or_else(|| VdbError::NoSuchGrid {
                path: self.path.clone(),
                name: name.to_string(),
                available: self.grid_names(),
            })?;
        self.read_index(i)
    }

    /// Reads grid number `i` in file order.
    ///
    /// # Errors
    /// See [`VdbError`].
    pub fn read_index(&self, i: usize) -> Result<VdbGrid, VdbError> {
        let d = self.grids.get(i).ok_or_else(|| VdbError::NoSuchGrid {
            path: self.path.clone(),
            name: format!("#{i}"),
            available: self.grid_names(),
        })?;
        let vt =
            ValueType::from_tree_type(&d.type_name).ok_or_else(|| VdbError::UnsupportedType {
                path: self.path.clone(),
                grid: d.name.clone(),
                type_name: d.type_name.clone(),
            })?;
        let mut f = self.source()?;
        let bytes = read_range(
            &mut f,
            &self.path,
            d.grid_pos,
            (d.end_pos - d.grid_pos) as usize,
        )?;
        let mut r = Reader::new(&bytes, d.grid_pos, &self.path);
        let compression = r.u32("grid compression")?;
        if compression & !7 != 0 {
            return Err(r.err(format!("unknown compression flags {compression:#x}")));
        }
        let metadata = read_metadata(&mut r)?;
        let map = read_map(&mut r, &self.path, &d.name)?;
        let name = meta_string(&metadata, "name").unwrap_or_else(|| d.name.clone());
        let class = meta_string(&metadata, "class").unwrap_or_else(|| "unknown".into());
        let half = d.half
            || metadata.iter().any(|e| {
                e.name == "is_saved_as_half_float" && e.data.first().is_some_and(|&b| b != 0)
            });
        let grid = if d.parent.is_empty() {
            read_tree(
                &mut r,
                &self.path,
                &name,
                vt,
                half,
                compression,
                map.to_affine(),
                self.len,
            )?
        } else {
            // An instance shares the tree of its parent: read the parent's tree.
            let p = self
                .grids
                .iter()
                .position(|g| g.unique_name == d.parent && g.parent.is_empty());
            let p = p.ok_or_else(|| r.err(format!("instance parent '{}' not found", d.parent)))?;
            let mut g = self.read_index(p)?.grid;
            g.set_index_to_world(map.to_affine())
                .map_err(|source| VdbError::Grid {
                    grid: name.clone(),
                    source,
                })?;
            g
        };
        Ok(VdbGrid {
            name,
            value_type: vt,
            class,
            saved_as_half: half,
            compression_flags: compression,
            map,
            metadata,
            grid,
        })
    }
}

fn bit(m: &[u64], i: usize) -> bool {
    m[i >> 6] >> (i & 63) & 1 != 0
}

/// Local coordinate of slot `n` in a node with `2^log2` children per axis (x slowest).
fn slot_coord(n: usize, log2: i32) -> IVec3 {
    let n = n as i32;
    let m = (1 << log2) - 1;
    IVec3::new(n >> (2 * log2), (n >> log2) & m, n & m)
}

fn same(a: &[f32], b: &[f32]) -> bool {
    a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// Reads the tree (topology then leaf buffers) into a new grid.
#[allow(clippy::too_many_arguments)]
fn read_tree(
    r: &mut Reader<'_>,
    path: &Path,
    name: &str,
    vt: ValueType,
    half: bool,
    compression: u32,
    xform: DAffine3,
    file_len: u64,
) -> Result<crate::grid::SparseGrid, VdbError> {
    let n = vt.components();
    let gerr = |source| VdbError::Grid {
        grid: name.to_string(),
        source,
    };
    let _buffer_count = r.i32("buffer count")?;
    let mut bg = [0f32; 3];
    r.value(vt, &mut bg, "background")?;
    let storage = if half { Storage::F16 } else { Storage::F32 };
    let mut b = SparseGridBuilder::new(storage);
    let kind = if n == 3 {
        ChannelKind::Vec3
    } else {
        ChannelKind::Scalar
    };
    let bgv = if n == 3 {
        Vec3::from_array(bg)
    } else {
        Vec3::splat(bg[0])
    };
    b.add_channel(name, kind, bgv);
    b.set_index_to_world(xform).map_err(gerr)?;
    let _ = file_len;
    let num_tiles = r.u32("root tile count")? as usize;
    let num_children = r.u32("root child count")? as usize;
    let tile_bytes = 12 + n * vt.component_bytes() + 1;
    if num_tiles > r.remaining() / tile_bytes || num_children > r.remaining() / (12 + 8192) {
        return Err(r.err(format!(
            "root claims {num_tiles} tiles and {num_children} children, more than the data holds"
        )));
    }
    let mut codec = ValueCodec {
        vt,
        half,
        compression,
        background: bg,
        scratch: Vec::new(),
        tmp: Vec::new(),
        temp: Vec::new(),
    };
    let bgs = &bg[..n];
    for _ in 0..num_tiles {
        let at = r.offset();
        let o = IVec3::new(
            r.i32("tile origin")?,
            r.i32("tile origin")?,
            r.i32("tile origin")?,
        );
        let mut v = [0f32; 3];
        r.value(vt, &mut v, "tile value")?;
        let active = r.u8("tile state")? != 0;
        if o & 4095 != IVec3::ZERO {
            return Err(VdbError::Format {
                path: path.to_path_buf(),
                offset: at,
                msg: format!("root tile origin {o} is not a multiple of 4096"),
            });
        }
        if active || !same(&v[..n], bgs) {
            b.set_tile(TileLevel::Root, o >> 12, &v[..n], active)
                .map_err(gerr)?;
        }
    }
    // Leaves in file order: origin and active mask; their values follow the topology.
    let mut leaves: Vec<(IVec3, [u64; 8])> = Vec::new();
    let mut vals5 = vec![0f32; 32768 * n];
    let mut vals4 = vec![0f32; 4096 * n];
    let mut child5 = vec![0u64; 512];
    let mut value5 = vec![0u64; 512];
    let mut child4 = [0u64; 64];
    let mut value4 = [0u64; 64];
    for _ in 0..num_children {
        let at = r.offset();
        let o5 = IVec3::new(
            r.i32("node origin")?,
            r.i32("node origin")?,
            r.i32("node origin")?,
        );
        if o5 & 4095 != IVec3::ZERO {
            return Err(VdbError::Format {
                path: path.to_path_buf(),
                offset: at,
                msg: format!("root child origin {o5} is not a multiple of 4096"),
            });
        }
        r.mask(512, &mut child5, "internal child mask")?;
        r.mask(512, &mut value5, "internal value mask")?;
        codec.read_values(r, 32768, &value5, &mut vals5)?;
        for s in 0..32768 {
            if bit(&child5, s) {
                continue;
            }
            let v = &vals5[s * n..s * n + n];
            let active = bit(&value5, s);
            if active || !same(v, bgs) {
                let key = (o5 >> 7) + slot_coord(s, 5);
                b.set_tile(TileLevel::Block, key, v, active).map_err(gerr)?;
            }
        }
        for s5 in 0..32768 {
            if !bit(&child5, s5) {
                continue;
            }
            let o4 = o5 + (slot_coord(s5, 5) << 7);
            r.mask(64, &mut child4, "internal child mask")?;
            r.mask(64, &mut value4, "internal value mask")?;
            codec.read_values(r, 4096, &value4, &mut vals4)?;
            for s in 0..4096 {
                if bit(&child4, s) {
                    continue;
                }
                let v = &vals4[s * n..s * n + n];
                let active = bit(&value4, s);
                if active || !same(v, bgs) {
                    let key = (o4 >> 3) + slot_coord(s, 4);
                    b.set_tile(TileLevel::Brick, key, v, active).map_err(gerr)?;
                }
            }
            for s4 in 0..4096 {
                if !bit(&child4, s4) {
                    continue;
                }
                let o3 = o4 + (slot_coord(s4, 4) << 3);
                let mut m = [0u64; 8];
                r.mask(8, &mut m, "leaf value mask")?;
                leaves.push((o3, m));
            }
        }
    }
    // Leaf buffers, in the same order. Split the stream into per-leaf byte ranges (cheap:
    // no decompression), create the bricks, then decode the leaves in parallel straight into
    // their bricks.
    let mut ranges = Vec::with_capacity(leaves.len());
    for (_, m) in &leaves {
        let start = r.pos;
        r.take(64, "leaf value mask")?;
        codec.skip_values(r, 512, m)?;
        ranges.push((start, r.pos));
    }
    let first = b.grid().brick_count();
    b.reserve_bricks(leaves.len());
    let mut in_order = true;
    for (i, (o3, m)) in leaves.iter().enumerate() {
        let idx = b.brick(*o3 >> 3).map_err(gerr)?;
        in_order &= idx == first + i;
        b.set_brick_mask(idx, *m);
    }
    if !in_order {
        // Duplicate leaves (a damaged file): decode sequentially, the last one wins.
        let mut vals = vec![0f32; 512 * n];
        for ((o3, m), &(s0, s1)) in leaves.iter().zip(&ranges) {
            let mut rr = Reader::new(&r.data[s0..s1], r.base + s0 as u64, path);
            rr.take(64, "leaf value mask")?;
            codec.read_values(&mut rr, 512, m, &mut vals)?;
            b.fill_brick(0, *o3 >> 3, &vals, *m).map_err(gerr)?;
        }
        return Ok(b.build());
    }
    let data = r.data;
    let base = r.base;
    let template = ValueCodec {
        scratch: Vec::new(),
        tmp: Vec::new(),
        temp: Vec::new(),
        ..codec
    };
    let decode =
        |c: &mut (ValueCodec, Vec<f32>), i: usize, out: &mut [f32]| -> Result<(), VdbError> {
            let (s0, s1) = ranges[i];
            let mut rr = Reader::new(&data[s0..s1], base + s0 as u64, path);
            rr.take(64, "leaf value mask")?;
            c.0.read_values(&mut rr, 512, &leaves[i].1, out)
        };
    let init = || (template.clone(), vec![0f32; 512 * n]);
    match b.values_mut(0) {
        crate::grid::ValuesMut::F32(v) => v[first * 512 * n..]
            .par_chunks_mut(512 * n)
            .enumerate()
            .try_for_each_init(init, |c, (i, out)| decode(c, i, out))?,
        crate::grid::ValuesMut::F16(v) => v[first * 512 * n..]
            .par_chunks_mut(512 * n)
            .enumerate()
            .try_for_each_init(init, |c, (i, out)| {
                let mut tmp = std::mem::take(&mut c.1);
                let res = decode(c, i, &mut tmp);
                for (d, &x) in out.iter_mut().zip(&tmp) {
                    *d = half::f16::from_f32(x);
                }
                c.1 = tmp;
                res
            })?,
    }
    Ok(b.build())
}
