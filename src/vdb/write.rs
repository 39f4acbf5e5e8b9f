//! The writer: file format version 224, as OpenVDB 10 writes it.

use super::codec::{write_data, write_values, COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC, COMPRESS_ZIP};
use super::{GridStats, MetaEntry, VdbError, VdbMap};
use crate::grid::{
    ChannelKind, SparseGrid, BG_ENTRY, BLOCK_LOG2, BRICK_VOXELS, ROOT_LOG2, TILE_BIT,
};
use glam::{DVec3, IVec3};
use std::collections::BTreeMap;
use std::path::Path;

/// Buffer compression of written grids.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Compression {
    /// Values stored raw.
    None,
    /// zlib per buffer with an `i64` size prefix.
    Zip,
    /// Blosc (LZ4 with byte shuffle) per buffer with an `i64` size prefix (OpenVDB's default).
    #[default]
    Blosc,
}

impl Compression {
    /// Parses `none`, `zip` or `blosc`.
    #[must_use]
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "none" => Some(Compression::None),
            "zip" => Some(Compression::Zip),
            "blosc" => Some(Compression::Blosc),
            _ => None,
        }
    }
}

/// Options of the writer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WriteOptions {
    /// Buffer compression.
    pub compression: Compression,
    /// Store only active values (plus at most one inactive value) per node (OpenVDB's default).
    pub active_mask: bool,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            compression: Compression::Blosc,
            active_mask: true,
        }
    }
}

impl WriteOptions {
    fn flags(&self) -> u32 {
        let c = match self.compression {
            Compression::None => 0,
            Compression::Zip => COMPRESS_ZIP,
            Compression::Blosc => COMPRESS_BLOSC,
        };
        c | if self.active_mask {
            COMPRESS_ACTIVE_MASK
        } else {
            0
        }
    }
}

/// One grid to write: a channel of a [`SparseGrid`] with its VDB name and class. Scalar
/// channels are written as `float` grids (as `half` when `half` is set), Vec3 channels as
/// `vec3s` grids.
#[derive(Clone, Copy, Debug)]
pub struct GridToWrite<'a> {
    /// Grid name.
    pub name: &'a str,
    /// Grid class (`fog volume`, `level set`, `unknown`, ...).
    pub class: &'a str,
    /// The grid.
    pub grid: &'a SparseGrid,
    /// The channel to write.
    pub channel: usize,
    /// Save values as 16-bit halves.
    pub half: bool,
    /// The map to store; `None` derives the simplest map from the grid's index-to-world map.
    pub map: Option<VdbMap>,
    /// Extra grid metadata (entries named like the ones the writer sets are skipped).
    pub metadata: &'a [MetaEntry],
}

impl<'a> GridToWrite<'a> {
    /// Channel 0 of `grid` under `name`, class `unknown`, full precision, no extra metadata.
    #[must_use]
    pub fn new(name: &'a str, grid: &'a SparseGrid) -> Self {
        GridToWrite {
            name,
            class: "unknown",
            grid,
            channel: 0,
            half: false,
            map: None,
            metadata: &[],
        }
    }
}

fn put_u32(o: &mut Vec<u8>, v: u32) {
    o.extend_from_slice(&v.to_le_bytes());
}
fn put_str(o: &mut Vec<u8>, s: &[u8]) {
    put_u32(o, s.len() as u32);
    o.extend_from_slice(s);
}
fn put_dvec3(o: &mut Vec<u8>, v: DVec3) {
    for x in v.to_array() {
        o.extend_from_slice(&x.to_le_bytes());
    }
}
fn put_meta(o: &mut Vec<u8>, m: &[MetaEntry]) {
    put_u32(o, m.len() as u32);
    for e in m {
        put_str(o, e.name.as_bytes());
        put_str(o, e.type_name.as_bytes());
        put_str(o, &e.data);
    }
}

fn put_map(o: &mut Vec<u8>, map: &VdbMap) {
    let scales = |o: &mut Vec<u8>, s: DVec3| {
        let inv = DVec3::ONE / s;
        put_dvec3(o, s);
        put_dvec3(o, s.abs());
        put_dvec3(o, inv);
        put_dvec3(o, inv * inv);
        put_dvec3(o, inv * 0.5);
    };
    let map = match map {
        VdbMap::Unitary(m) => VdbMap::Affine(*m),
        m => *m,
    };
    put_str(o, map.type_name().as_bytes());
    match map {
        VdbMap::UniformScale(s) => scales(o, DVec3::splat(s)),
        VdbMap::Scale(s) => scales(o, s),
        VdbMap::Translation(t) => put_dvec3(o, t),
        VdbMap::UniformScaleTranslate { scale, translation } => {
            put_dvec3(o, translation);
            scales(o, DVec3::splat(scale));
        }
        VdbMap::ScaleTranslate { scale, translation } => {
            put_dvec3(o, translation);
            scales(o, scale);
        }
        VdbMap::Affine(m) | VdbMap::Unitary(m) => {
            let rows = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
            for r in rows {
                put_dvec3(o, r);
                o.extend_from_slice(&0f64.to_le_bytes());
            }
            put_dvec3(o, m.translation);
            o.extend_from_slice(&1f64.to_le_bytes());
        }
    }
}

fn uuid() -> String {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let mut x = t ^ 0x9e37_79b9_7f4a_7c15 ^ u64::from(std::process::id()).rotate_left(32);
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let (a, b) = (next(), next());
    format!(
        "{:08x}-{:04x}-4{:03x}-{:04x}-{:012x}",
        a >> 32,
        (a >> 16) & 0xffff,
        a & 0xfff,
        0x8000 | (b >> 48) & 0x3fff,
        b & 0xffff_ffff_ffff
    )
}

/// Writes grids to a VDB file.
///
/// # Errors
/// [`VdbError::Write`] for a grid that cannot be written, [`VdbError::Io`] for I/O errors.
pub fn write_vdb(
    path: impl AsRef<Path>,
    grids: &[GridToWrite<'_>],
    opts: &WriteOptions,
) -> Result<(), VdbError> {
    write_vdb_with_metadata(path, grids, opts, &[])
}

/// [`write_vdb`] with extra file-level metadata (after `creator`; entries named `creator` are
/// skipped), as OpenVDB's `io::File::write(grids, metadata)` stores it.
///
/// # Errors
/// As [`write_vdb`].
pub fn write_vdb_with_metadata(
    path: impl AsRef<Path>,
    grids: &[GridToWrite<'_>],
    opts: &WriteOptions,
    file_metadata: &[MetaEntry],
) -> Result<(), VdbError> {
    let bytes = write_vdb_to_vec_with_metadata(grids, opts, file_metadata)?;
    std::fs::write(path.as_ref(), bytes).map_err(|source| VdbError::Io {
        path: path.as_ref().to_path_buf(),
        source,
    })
}

/// Writes grids to an in-memory VDB file.
///
/// # Errors
/// [`VdbError::Write`] for a grid that cannot be written (missing channel, non-invertible map).
pub fn write_vdb_to_vec(
    grids: &[GridToWrite<'_>],
    opts: &WriteOptions,
) -> Result<Vec<u8>, VdbError> {
    write_vdb_to_vec_with_metadata(grids, opts, &[])
}

/// [`write_vdb_to_vec`] with extra file-level metadata (see [`write_vdb_with_metadata`]).
///
/// # Errors
/// As [`write_vdb_to_vec`].
pub fn write_vdb_to_vec_with_metadata(
    grids: &[GridToWrite<'_>],
    opts: &WriteOptions,
    file_metadata: &[MetaEntry],
) -> Result<Vec<u8>, VdbError> {
    let mut o = Vec::new();
    o.extend_from_slice(&[0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0]);
    put_u32(&mut o, 224);
    put_u32(&mut o, 10);
    put_u32(&mut o, 0);
    o.push(1);
    o.extend_from_slice(uuid().as_bytes());
    let mut file_meta = vec![MetaEntry::string("creator", "velour")];
    file_meta.extend(
        file_metadata
            .iter()
            .filter(|e| e.name != "creator")
            .cloned(),
    );
    put_meta(&mut o, &file_meta);
    put_u32(&mut o, grids.len() as u32);
    let mut used: Vec<String> = Vec::new();
    for g in grids {
        let kind = g
            .grid
            .channel_kind(g.channel)
            .ok_or_else(|| VdbError::Write {
                grid: g.name.into(),
                msg: format!("channel {} does not exist", g.channel),
            })?;
        let mut unique = g.name.to_string();
        let mut k = 0;
        while used.contains(&unique) {
            unique = format!("{}\u{1e}{k}", g.name);
            k += 1;
        }
        used.push(unique.clone());
        let tree_type = match kind {
            ChannelKind::Scalar => "Tree_float_5_4_3",
            ChannelKind::Vec3 => "Tree_vec3s_5_4_3",
        };
        put_str(&mut o, unique.as_bytes());
        let ty = if g.half {
            format!("{tree_type}_HalfFloat")
        } else {
            tree_type.to_string()
        };
        put_str(&mut o, ty.as_bytes());
        put_str(&mut o, b"");
        let offsets_at = o.len();
        o.extend_from_slice(&[0u8; 24]);
        let grid_pos = o.len() as i64;
        let flags = opts.flags();
        put_u32(&mut o, flags);
        // Metadata, sorted by name as OpenVDB's MetaMap stores it.
        let stats = GridStats::compute(g.grid, g.channel);
        let (lo, hi) = stats.active_bbox.unwrap_or((IVec3::ZERO, IVec3::ZERO));
        let vec3i = |v: IVec3| {
            v.to_array()
                .iter()
                .flat_map(|x| x.to_le_bytes())
                .collect::<Vec<u8>>()
        };
        let compression_name = match (opts.compression, opts.active_mask) {
            (Compression::None, false) => "none",
            (Compression::None, true) => "active values",
            (Compression::Zip, false) => "zip",
            (Compression::Zip, true) => "zip + active values",
            (Compression::Blosc, false) => "blosc",
            (Compression::Blosc, true) => "blosc + active values",
        };
        let mut meta: BTreeMap<String, MetaEntry> = BTreeMap::new();
        for e in g.metadata {
            meta.insert(e.name.clone(), e.clone());
        }
        for e in [
            MetaEntry::string("class", g.class),
            MetaEntry::string("name", g.name),
            MetaEntry::string("file_compression", compression_name),
            MetaEntry {
                name: "is_saved_as_half_float".into(),
                type_name: "bool".into(),
                data: vec![u8::from(g.half)],
            },
            MetaEntry {
                name: "file_bbox_min".into(),
                type_name: "vec3i".into(),
                data: vec3i(lo),
            },
            MetaEntry {
                name: "file_bbox_max".into(),
                type_name: "vec3i".into(),
                data: vec3i(hi),
            },
            MetaEntry {
                name: "file_voxel_count".into(),
                type_name: "int64".into(),
                data: (stats.active_voxels as i64).to_le_bytes().to_vec(),
            },
            MetaEntry {
                name: "file_mem_bytes".into(),
                type_name: "int64".into(),
                data: (g.grid.memory_report().total_bytes as i64)
                    .to_le_bytes()
                    .to_vec(),
            },
        ] {
            meta.insert(e.name.clone(), e);
        }
        meta.remove("file_delayed_load");
        let meta: Vec<MetaEntry> = meta.into_values().collect();
        put_meta(&mut o, &meta);
        put_map(
            &mut o,
            &g.map
                .unwrap_or_else(|| VdbMap::from_affine(g.grid.index_to_world())),
        );
        let block_pos = write_tree(&mut o, g.grid, g.channel, g.half, flags) as i64;
        let end_pos = o.len() as i64;
        o[offsets_at..offsets_at + 8].copy_from_slice(&grid_pos.to_le_bytes());
        o[offsets_at + 8..offsets_at + 16].copy_from_slice(&block_pos.to_le_bytes());
        o[offsets_at + 16..offsets_at + 24].copy_from_slice(&end_pos.to_le_bytes());
    }
    Ok(o)
}

enum RootItem {
    Tile(u32),
    Node(Vec<(usize, u32)>),
}

fn set_bit(m: &mut [u64], i: usize) {
    m[i >> 6] |= 1 << (i & 63);
}

/// Writes topology and leaf buffers; returns the offset where the buffers start.
fn write_tree(o: &mut Vec<u8>, g: &SparseGrid, c: usize, half: bool, flags: u32) -> usize {
    let n = g.channel_kind(c).map_or(1, |k| k.components());
    let tile_vals = |t: u32| -> Vec<f32> {
        let v = g.tile_value_vec3(c, t).to_array();
        v[..n].to_vec()
    };
    let bg = tile_vals(0);
    let mut root: BTreeMap<(i32, i32, i32), RootItem> = BTreeMap::new();
    for (&k, &t) in &g.root_tiles {
        root.insert((k.x, k.y, k.z), RootItem::Tile(t));
    }
    let shift = ROOT_LOG2 - BLOCK_LOG2;
    for (&k, &e) in &g.block_map {
        if e == BG_ENTRY {
            continue;
        }
        let rk = k >> shift;
        let l = k & 31;
        let slot = ((l.x << 10) | (l.y << 5) | l.z) as usize;
        match root
            .entry((rk.x, rk.y, rk.z))
            .or_insert_with(|| RootItem::Node(Vec::new()))
        {
            RootItem::Node(v) => v.push((slot, e)),
            RootItem::Tile(_) => {}
        }
    }
    o.extend_from_slice(&1i32.to_le_bytes());
    for &x in &bg {
        o.extend_from_slice(&x.to_le_bytes());
    }
    let tiles: Vec<_> = root
        .iter()
        .filter_map(|(k, v)| {
            if let RootItem::Tile(t) = v {
                Some((*k, *t))
            } else {
                None
            }
        })
        .collect();
    put_u32(o, tiles.len() as u32);
    put_u32(o, (root.len() - tiles.len()) as u32);
    for ((x, y, z), t) in tiles {
        for v in [x, y, z] {
            o.extend_from_slice(&(v << ROOT_LOG2).to_le_bytes());
        }
        for x in tile_vals(t) {
            o.extend_from_slice(&x.to_le_bytes());
        }
        o.push(u8::from(g.tile_active(t)));
    }
    let mut leaves: Vec<usize> = Vec::new();
    for (&(x, y, z), item) in &root {
        let RootItem::Node(entries) = item else {
            continue;
        };
        let mut entries = entries.clone();
        entries.sort_unstable();
        for v in [x, y, z] {
            o.extend_from_slice(&(v << ROOT_LOG2).to_le_bytes());
        }
        let mut child5 = vec![0u64; 512];
        let mut value5 = vec![0u64; 512];
        let mut vals5: Vec<f32> = bg.iter().copied().cycle().take(32768 * n).collect();
        for &(slot, e) in &entries {
            if e & TILE_BIT != 0 {
                let t = e & !TILE_BIT;
                vals5[slot * n..slot * n + n].copy_from_slice(&tile_vals(t));
                if g.tile_active(t) {
                    set_bit(&mut value5, slot);
                }
            } else {
                set_bit(&mut child5, slot);
            }
        }
        put_words(o, &child5);
        put_words(o, &value5);
        write_values(o, &vals5, n, &value5, Some(&child5), &bg, half, flags);
        for &(_, e) in &entries {
            if e & TILE_BIT != 0 {
                continue;
            }
            let block = &g.blocks[e as usize];
            let mut child4 = [0u64; 64];
            let mut value4 = [0u64; 64];
            let mut vals4: Vec<f32> = bg.iter().copied().cycle().take(4096 * n).collect();
            let mut bricks = Vec::new();
            for (slot, &be) in block.iter().enumerate() {
                if be & TILE_BIT != 0 {
                    let t = be & !TILE_BIT;
                    if t != 0 {
                        vals4[slot * n..slot * n + n].copy_from_slice(&tile_vals(t));
                        if g.tile_active(t) {
                            set_bit(&mut value4, slot);
                        }
                    }
                } else {
                    set_bit(&mut child4, slot);
                    bricks.push(be as usize);
                }
            }
            put_words(o, &child4);
            put_words(o, &value4);
            write_values(o, &vals4, n, &value4, Some(&child4), &bg, half, flags);
            for &b in &bricks {
                put_words(o, g.brick_active_mask(b));
            }
            leaves.extend(bricks);
        }
    }
    let block_pos = o.len();
    let mut vals = vec![0f32; BRICK_VOXELS * n];
    for b in leaves {
        let m = g.brick_active_mask(b);
        put_words(o, m);
        let d = g.brick_data(c, b);
        for v in 0..BRICK_VOXELS {
            for k in 0..n {
                vals[v * n + k] = d.get(v, n, k);
            }
        }
        write_values(o, &vals, n, m, None, &bg, half, flags);
    }
    let _ = write_data;
    block_pos
}

fn put_words(o: &mut Vec<u8>, w: &[u64]) {
    for x in w {
        o.extend_from_slice(&x.to_le_bytes());
    }
}
