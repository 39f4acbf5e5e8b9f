//! The sparse brick grid: every spatially varying quantity in velour (VDB densities, baked
//! procedural noise, voxelised fabric) lives in a [`SparseGrid`] of 8^3 bricks.
//!
//! # Layout
//! The topology mirrors OpenVDB's default `5_4_3` tree so that a VDB leaf becomes a brick with
//! no re-layout:
//! - a **brick** holds 8^3 voxels (values plus a 512-bit active mask), voxel `(x, y, z)` of a
//!   brick at offset `(x << 6) | (y << 3) | z` (x slowest, as in OpenVDB);
//! - a **block** covers 128^3 voxels (16^3 bricks): a flat table of 4096 entries, each a brick
//!   index or a constant tile (an 8^3 tile);
//! - a hash map from block coordinate (voxel coordinate `>> 7`) to a block or a constant
//!   128^3 tile;
//! - a hash map of constant **root tiles** of 4096^3 voxels (voxel coordinate `>> 12`).
//!
//! Constant regions stay constant nodes: they are never expanded into voxels. Tiles carry a
//! value per channel and an active flag; tile index 0 is the background (inactive).
//!
//! # Channels
//! A grid holds one or more channels (scalar or [`Vec3`]) sharing the topology, each stored as
//! `f32` or `f16` ([`Storage`]).
//!
//! # Coordinates
//! Index `(i, j, k)` is the centre of voxel `(i, j, k)` (OpenVDB's convention): trilinear
//! lookups at integer index coordinates return the voxel value exactly, as OpenVDB's
//! `BoxSampler` does. World space is any affine image of index space ([`SparseGrid::index_to_world`]).
//! Values are unitless: the grid knows nothing of optics.

mod access;
mod builder;
mod sun_map;

pub use access::{floor_frac, trilerp, Accessor};
pub use builder::SparseGridBuilder;
pub use sun_map::SunMap;

use glam::{DAffine3, DVec3, IVec3, Vec3};
use half::f16;
use rayon::prelude::*;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// log2 of the brick edge (8 voxels).
pub const BRICK_LOG2: i32 = 3;
/// Brick edge in voxels.
pub const BRICK_DIM: i32 = 8;
/// Voxels per brick.
pub const BRICK_VOXELS: usize = 512;
/// log2 of the block edge in voxels (128).
pub const BLOCK_LOG2: i32 = 7;
/// log2 of the root-tile edge in voxels (4096).
pub const ROOT_LOG2: i32 = 12;
/// Entries (bricks or 8^3 tiles) in one block: 16^3.
pub const BLOCK_ENTRIES: usize = 4096;

/// Marks a topology entry that refers to a tile (low 31 bits: tile index) rather than a brick
/// or block.
pub(crate) const TILE_BIT: u32 = 1 << 31;
/// The background tile entry.
pub(crate) const BG_ENTRY: u32 = TILE_BIT;

/// Errors of grid construction.
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    /// A channel index beyond the grid's channels.
    #[error("grid channel {index} does not exist (the grid has {count} channels)")]
    NoSuchChannel {
        /// Requested channel.
        index: usize,
        /// Number of channels.
        count: usize,
    },
    /// A slice of values with the wrong length.
    #[error("{what}: expected {expected} values, got {got}")]
    WrongLength {
        /// What was being set.
        what: &'static str,
        /// Expected count.
        expected: usize,
        /// Received count.
        got: usize,
    },
    /// A tile that would overlap existing finer nodes.
    #[error("cannot set a {level:?} tile at {key}: finer nodes already exist there")]
    Occupied {
        /// Tile level.
        level: TileLevel,
        /// Tile key (voxel coordinate shifted right by the level's log2 size).
        key: IVec3,
    },
    /// A non-invertible or non-finite index-to-world map.
    #[error("index-to-world map is not invertible or not finite: {0}")]
    BadTransform(String),
    /// Too many bricks or tiles for 31-bit indices.
    #[error("grid too large: more than 2^31 bricks or tiles")]
    TooLarge,
}

/// How a channel stores brick values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    /// 32-bit floats.
    F32,
    /// 16-bit half floats (IEEE binary16); tiles and backgrounds stay 32-bit.
    F16,
}

impl Storage {
    /// Bytes per stored component.
    #[must_use]
    pub fn bytes(self) -> usize {
        match self {
            Storage::F32 => 4,
            Storage::F16 => 2,
        }
    }
}

/// The kind of value a channel holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ChannelKind {
    /// One float per voxel.
    Scalar,
    /// Three floats per voxel.
    Vec3,
}

impl ChannelKind {
    /// Components per voxel (1 or 3).
    #[must_use]
    pub fn components(self) -> usize {
        match self {
            ChannelKind::Scalar => 1,
            ChannelKind::Vec3 => 3,
        }
    }
}

/// Levels at which constant tiles live.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TileLevel {
    /// An 8^3 tile in place of a brick.
    Brick,
    /// A 128^3 tile in place of a block.
    Block,
    /// A 4096^3 root tile.
    Root,
}

impl TileLevel {
    /// log2 of the tile edge in voxels.
    #[must_use]
    pub fn log2(self) -> i32 {
        match self {
            TileLevel::Brick => BRICK_LOG2,
            TileLevel::Block => BLOCK_LOG2,
            TileLevel::Root => ROOT_LOG2,
        }
    }
    /// Tile edge in voxels.
    #[must_use]
    pub fn dim(self) -> i64 {
        1i64 << self.log2()
    }
    /// Voxels covered by one tile.
    #[must_use]
    pub fn voxels(self) -> u64 {
        1u64 << (3 * self.log2())
    }
}

/// Brick values of one channel, in the channel's storage.
#[derive(Clone, Debug)]
pub(crate) enum Values {
    F32(Vec<f32>),
    F16(Vec<f16>),
}

/// One channel of a grid: per-brick values, per-tile values and a background.
#[derive(Clone, Debug)]
pub(crate) struct Channel {
    pub(crate) name: String,
    pub(crate) kind: ChannelKind,
    pub(crate) values: Values,
    /// `components` floats per tile, tile 0 is the background.
    pub(crate) tile_values: Vec<f32>,
    /// The bricks with their apron ([`SparseGrid::padded_accessor`]), made on first use.
    pub(crate) padded: std::sync::OnceLock<Option<Vec<f32>>>,
    /// For a vector channel: its padded bricks interleaved with one scalar channel's
    /// ([`SparseGrid::padded_pairs`]), with that channel's index; made on first use.
    pub(crate) padded_pairs: std::sync::OnceLock<Option<(usize, Vec<[f32; 4]>)>>,
    /// The channel's integral towards one distant direction ([`SparseGrid::sun_map`]), made
    /// on first use for the first direction asked.
    pub(crate) sun_map: std::sync::OnceLock<Option<Box<SunMap>>>,
}

/// Edge of a brick with its apron: the brick's 8 voxels and the first voxel of the next brick
/// along each axis, so that the 8 corners of every trilinear cell whose first corner lies in
/// the brick are read from one padded brick.
pub(crate) const PADDED_EDGE: usize = 9;
/// Values of one padded brick (9³).
pub(crate) const PADDED_VOXELS: usize = PADDED_EDGE * PADDED_EDGE * PADDED_EDGE;
/// The padded copy of a channel is made only while it stays below this size (bytes).
const PADDED_BUDGET: usize = 1 << 30;

/// The stored values of one brick of one channel: 512 × components values in voxel order.
#[derive(Clone, Copy, Debug)]
pub enum BrickData<'a> {
    /// 32-bit storage.
    F32(&'a [f32]),
    /// 16-bit storage.
    F16(&'a [f16]),
}

impl BrickData<'_> {
    /// Component `c` of voxel `v` (`v = (x << 6) | (y << 3) | z`).
    #[must_use]
    pub fn get(&self, v: usize, comps: usize, c: usize) -> f32 {
        match self {
            BrickData::F32(s) => s[v * comps + c],
            BrickData::F16(s) => s[v * comps + c].to_f32(),
        }
    }
}

/// Mutable brick values of one channel, in the channel's storage (see
/// [`SparseGridBuilder::values_mut`]).
#[derive(Debug)]
pub enum ValuesMut<'a> {
    /// 32-bit storage.
    F32(&'a mut [f32]),
    /// 16-bit storage.
    F16(&'a mut [f16]),
}

/// What covers a brick-sized cell of index space.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Node {
    /// A brick of voxels (index into the grid's bricks).
    Brick(u32),
    /// A constant tile: its index (read values with [`SparseGrid::tile_value`]), the level of
    /// the node that holds it and whether it is active. Tile 0 is the background.
    Tile {
        /// Tile index.
        tile: u32,
        /// Level of the tile.
        level: TileLevel,
        /// Active flag.
        active: bool,
    },
}

/// A constant tile node of the topology, as listed by [`SparseGrid::tiles`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileNode {
    /// Tile level.
    pub level: TileLevel,
    /// Index-space voxel coordinate of the tile's minimum corner.
    pub origin: IVec3,
    /// Tile index (values via [`SparseGrid::tile_value`]).
    pub tile: u32,
    /// Active flag.
    pub active: bool,
}

/// Memory used by a grid, in bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryReport {
    /// Brick values of all channels.
    pub brick_value_bytes: usize,
    /// Brick active masks and origins.
    pub brick_meta_bytes: usize,
    /// Blocks, hash maps and tiles.
    pub topology_bytes: usize,
    /// Sum of the above.
    pub total_bytes: usize,
    /// Active voxels stored in bricks.
    pub active_brick_voxels: u64,
    /// Active voxels including those covered by active tiles.
    pub active_voxels: u64,
    /// `total_bytes / active_brick_voxels` (infinite when there are none).
    pub bytes_per_active_brick_voxel: f64,
    /// Bytes of one raw voxel value over all channels (e.g. 4 for one f32 channel).
    pub raw_value_bytes: usize,
}

/// A cheap hasher for integer coordinate keys (multiply-rotate, as in FxHash).
#[derive(Default, Clone, Copy)]
pub struct CoordHasher(u64);

impl Hasher for CoordHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_i32(&mut self, i: i32) {
        self.write_u64(i as u32 as u64);
    }
    fn write_u32(&mut self, i: u32) {
        self.write_u64(u64::from(i));
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

/// Hash map keyed by integer coordinates.
pub type CoordMap<V> = HashMap<IVec3, V, BuildHasherDefault<CoordHasher>>;

/// A sparse grid of 8^3 bricks with constant tiles, one or more channels and an affine
/// index-to-world map. Build one with [`SparseGridBuilder`]; query it with the methods below or
/// with an [`Accessor`] for coherent lookups.
#[derive(Clone, Debug)]
pub struct SparseGrid {
    pub(crate) brick_origin: Vec<IVec3>,
    pub(crate) brick_mask: Vec<[u64; 8]>,
    pub(crate) blocks: Vec<Box<[u32; BLOCK_ENTRIES]>>,
    /// Block key (voxel >> 7) -> block index or `TILE_BIT | tile`.
    pub(crate) block_map: CoordMap<u32>,
    /// Root key (voxel >> 12) -> tile index.
    pub(crate) root_tiles: CoordMap<u32>,
    /// Active flag per tile (tile 0: background, inactive).
    pub(crate) tile_active: Vec<bool>,
    pub(crate) channels: Vec<Channel>,
    pub(crate) storage: Storage,
    pub(crate) index_to_world: DAffine3,
    pub(crate) world_to_index: DAffine3,
}

/// Offset of voxel `(x, y, z)` (local to its brick, 0..8) in the brick.
#[inline]
#[must_use]
pub fn voxel_offset(local: IVec3) -> usize {
    ((local.x << 6) | (local.y << 3) | local.z) as usize
}

/// Offset of brick `(x, y, z)` (local to its block, 0..16) in the block.
#[inline]
pub(crate) fn block_slot(brick_key: IVec3) -> usize {
    let l = brick_key & 15;
    ((l.x << 8) | (l.y << 4) | l.z) as usize
}

impl SparseGrid {
    /// Storage of the brick values.
    #[must_use]
    pub fn storage(&self) -> Storage {
        self.storage
    }
    /// Number of channels.
    #[must_use]
    pub fn channel_count(&self) -> usize {
        self.channels.len()
    }
    /// Name of channel `c` (empty when out of range).
    #[must_use]
    pub fn channel_name(&self, c: usize) -> &str {
        self.channels.get(c).map_or("", |ch| ch.name.as_str())
    }
    /// Kind of channel `c`, `None` when out of range.
    #[must_use]
    pub fn channel_kind(&self, c: usize) -> Option<ChannelKind> {
        self.channels.get(c).map(|ch| ch.kind)
    }
    /// Index of the channel called `name`.
    #[must_use]
    pub fn channel_index(&self, name: &str) -> Option<usize> {
        self.channels.iter().position(|c| c.name == name)
    }
    /// Background of channel `c` (first component for Vec3 channels; 0 when out of range).
    #[must_use]
    pub fn background(&self, c: usize) -> f32 {
        self.tile_value(c, 0)
    }
    /// Background of a Vec3 channel (a scalar background is splatted).
    #[must_use]
    pub fn background_vec3(&self, c: usize) -> Vec3 {
        self.tile_value_vec3(c, 0)
    }
    /// The affine map from index space to world space (f64).
    #[must_use]
    pub fn index_to_world(&self) -> DAffine3 {
        self.index_to_world
    }
    /// The affine map from world space to index space (f64).
    #[must_use]
    pub fn world_to_index(&self) -> DAffine3 {
        self.world_to_index
    }
    /// Maps an index-space point to world space.
    #[must_use]
    pub fn index_to_world_point(&self, p: Vec3) -> Vec3 {
        self.index_to_world.transform_point3(p.as_dvec3()).as_vec3()
    }
    /// Maps a world-space point to index space.
    #[must_use]
    pub fn world_to_index_point(&self, p: Vec3) -> Vec3 {
        self.world_to_index.transform_point3(p.as_dvec3()).as_vec3()
    }
    /// Replaces the index-to-world map.
    ///
    /// # Errors
    /// [`GridError::BadTransform`] if the map is not finite or not invertible.
    pub fn set_index_to_world(&mut self, m: DAffine3) -> Result<(), GridError> {
        let det = m.matrix3.determinant();
        if !det.is_finite() || det.abs() < 1e-300 || !m.translation.is_finite() {
            return Err(GridError::BadTransform(format!("{m:?}")));
        }
        self.index_to_world = m;
        self.world_to_index = m.inverse();
        for ch in &mut self.channels {
            ch.sun_map = std::sync::OnceLock::new();
        }
        Ok(())
    }

    /// Number of bricks.
    #[must_use]
    pub fn brick_count(&self) -> usize {
        self.brick_origin.len()
    }
    /// Index-space voxel coordinate of the minimum corner of brick `b`.
    #[must_use]
    pub fn brick_origin(&self, b: usize) -> IVec3 {
        self.brick_origin[b]
    }
    /// Active mask of brick `b`: bit `v` of word `v >> 6` for voxel offset `v`.
    #[must_use]
    pub fn brick_active_mask(&self, b: usize) -> &[u64; 8] {
        &self.brick_mask[b]
    }
    /// Values of brick `b` in channel `c` (512 × components values).
    ///
    /// # Panics
    /// If `c` or `b` is out of range (programming error).
    #[must_use]
    pub fn brick_data(&self, c: usize, b: usize) -> BrickData<'_> {
        let ch = &self.channels[c];
        let n = BRICK_VOXELS * ch.kind.components();
        match &ch.values {
            Values::F32(v) => BrickData::F32(&v[b * n..(b + 1) * n]),
            Values::F16(v) => BrickData::F16(&v[b * n..(b + 1) * n]),
        }
    }
    /// Number of tiles (including the background tile 0).
    #[must_use]
    pub fn tile_count(&self) -> usize {
        self.tile_active.len()
    }
    /// Value of tile `t` in scalar channel `c` (first component of a Vec3 channel; 0 when out
    /// of range).
    #[must_use]
    pub fn tile_value(&self, c: usize, t: u32) -> f32 {
        self.channels.get(c).map_or(0.0, |ch| {
            let n = ch.kind.components();
            ch.tile_values.get(t as usize * n).copied().unwrap_or(0.0)
        })
    }
    /// Value of tile `t` in channel `c` as a vector (scalars are splatted).
    #[must_use]
    pub fn tile_value_vec3(&self, c: usize, t: u32) -> Vec3 {
        self.channels.get(c).map_or(Vec3::ZERO, |ch| {
            let n = ch.kind.components();
            let s = &ch.tile_values[t as usize * n..t as usize * n + n];
            if n == 3 {
                Vec3::new(s[0], s[1], s[2])
            } else {
                Vec3::splat(s[0])
            }
        })
    }
    /// Whether tile `t` is active.
    #[must_use]
    pub fn tile_active(&self, t: u32) -> bool {
        self.tile_active.get(t as usize).copied().unwrap_or(false)
    }

    /// The node covering the brick-sized cell with key `brick_key` (voxel coordinate `>> 3`).
    #[must_use]
    pub fn node_at_brick(&self, brick_key: IVec3) -> Node {
        let block_key = brick_key >> (BLOCK_LOG2 - BRICK_LOG2);
        if let Some(&e) = self.block_map.get(&block_key) {
            if e & TILE_BIT != 0 {
                let t = e & !TILE_BIT;
                return Node::Tile {
                    tile: t,
                    level: TileLevel::Block,
                    active: self.tile_active(t),
                };
            }
            let entry = self.blocks[e as usize][block_slot(brick_key)];
            if entry & TILE_BIT != 0 {
                let t = entry & !TILE_BIT;
                return Node::Tile {
                    tile: t,
                    level: TileLevel::Brick,
                    active: self.tile_active(t),
                };
            }
            return Node::Brick(entry);
        }
        if !self.root_tiles.is_empty() {
            if let Some(&t) = self
                .root_tiles
                .get(&(brick_key >> (ROOT_LOG2 - BRICK_LOG2)))
            {
                return Node::Tile {
                    tile: t,
                    level: TileLevel::Root,
                    active: self.tile_active(t),
                };
            }
        }
        Node::Tile {
            tile: 0,
            level: TileLevel::Root,
            active: false,
        }
    }

    /// The brick holding voxel `ijk`, if any.
    #[must_use]
    pub fn brick_at_voxel(&self, ijk: IVec3) -> Option<usize> {
        match self.node_at_brick(ijk >> BRICK_LOG2) {
            Node::Brick(b) => Some(b as usize),
            Node::Tile { .. } => None,
        }
    }

    /// Every non-background tile node (active tiles, and inactive tiles whose value differs
    /// from the background), at every level.
    #[must_use]
    pub fn tiles(&self) -> Vec<TileNode> {
        let mut out = Vec::new();
        for (&key, &t) in &self.root_tiles {
            out.push(TileNode {
                level: TileLevel::Root,
                origin: key << ROOT_LOG2,
                tile: t,
                active: self.tile_active(t),
            });
        }
        for (&key, &e) in &self.block_map {
            if e & TILE_BIT != 0 {
                let t = e & !TILE_BIT;
                if t != 0 {
                    out.push(TileNode {
                        level: TileLevel::Block,
                        origin: key << BLOCK_LOG2,
                        tile: t,
                        active: self.tile_active(t),
                    });
                }
                continue;
            }
            for (slot, &entry) in self.blocks[e as usize].iter().enumerate() {
                if entry & TILE_BIT != 0 && entry != BG_ENTRY {
                    let t = entry & !TILE_BIT;
                    let s = slot as i32;
                    let local = IVec3::new(s >> 8, (s >> 4) & 15, s & 15);
                    out.push(TileNode {
                        level: TileLevel::Brick,
                        origin: (key << BLOCK_LOG2) + (local << BRICK_LOG2),
                        tile: t,
                        active: self.tile_active(t),
                    });
                }
            }
        }
        out.sort_by_key(|n| (n.origin.x, n.origin.y, n.origin.z, n.level as u8));
        out
    }

    /// Number of active voxels in bricks.
    #[must_use]
    pub fn active_brick_voxels(&self) -> u64 {
        self.brick_mask
            .iter()
            .map(|m| m.iter().map(|w| u64::from(w.count_ones())).sum::<u64>())
            .sum()
    }

    /// Number of active voxels, counting each active tile as the voxels it covers.
    #[must_use]
    pub fn active_voxels(&self) -> u64 {
        let tiles: u64 = self
            .tiles()
            .iter()
            .filter(|t| t.active)
            .map(|t| t.level.voxels())
            .sum();
        self.active_brick_voxels() + tiles
    }

    /// Inclusive index-space bounding box `(min, max)` of active voxels and active tiles, or
    /// `None` if nothing is active.
    #[must_use]
    pub fn active_bbox(&self) -> Option<(IVec3, IVec3)> {
        let mut lo = IVec3::MAX;
        let mut hi = IVec3::MIN;
        for (b, m) in self.brick_mask.iter().enumerate() {
            // Word x of the mask holds the voxels of slab x; bit (y << 3) | z within it.
            let Some(x0) = m.iter().position(|&w| w != 0) else {
                continue;
            };
            let x1 = 7 - m.iter().rev().position(|&w| w != 0).unwrap_or(0);
            let yz = m.iter().fold(0u64, |a, &w| a | w);
            let ys: Vec<i32> = (0..8).filter(|y| (yz >> (8 * y)) & 0xff != 0).collect();
            let zbits = (0..8).fold(0u64, |a, y| a | ((yz >> (8 * y)) & 0xff));
            let (y0, y1) = (ys[0], ys[ys.len() - 1]);
            let (z0, z1) = (
                zbits.trailing_zeros() as i32,
                63 - zbits.leading_zeros() as i32,
            );
            let o = self.brick_origin[b];
            lo = lo.min(o + IVec3::new(x0 as i32, y0, z0));
            hi = hi.max(o + IVec3::new(x1 as i32, y1, z1));
        }
        for t in self.tiles() {
            if t.active {
                let d = (t.level.dim() - 1) as i32;
                lo = lo.min(t.origin);
                hi = hi.max(t.origin + IVec3::splat(d));
            }
        }
        (lo.x <= hi.x).then_some((lo, hi))
    }

    /// Memory used by the grid.
    #[must_use]
    pub fn memory_report(&self) -> MemoryReport {
        let comps: usize = self.channels.iter().map(|c| c.kind.components()).sum();
        let brick_value_bytes = self.brick_count() * BRICK_VOXELS * comps * self.storage.bytes();
        let brick_meta_bytes = self.brick_count() * (64 + 12);
        let map_entry = 12 + 4 + 8; // key, value, hash-table control and slack (approximate)
        let topology_bytes = self.blocks.len() * BLOCK_ENTRIES * 4
            + (self.block_map.capacity() + self.root_tiles.capacity()) * map_entry
            + self.tile_active.len() * (1 + 4 * comps);
        let total_bytes = brick_value_bytes + brick_meta_bytes + topology_bytes;
        let active_brick_voxels = self.active_brick_voxels();
        MemoryReport {
            brick_value_bytes,
            brick_meta_bytes,
            topology_bytes,
            total_bytes,
            active_brick_voxels,
            active_voxels: self.active_voxels(),
            bytes_per_active_brick_voxel: total_bytes as f64 / active_brick_voxels as f64,
            raw_value_bytes: comps * self.storage.bytes(),
        }
    }

    /// A new accessor on channel `c` (see [`Accessor`]).
    ///
    /// # Panics
    /// If `c` is not a channel of the grid (programming error).
    #[must_use]
    pub fn accessor(&self, c: usize) -> Accessor<'_> {
        Accessor::new(self, c)
    }

    /// An accessor on channel `c` whose trilinear lookups read padded bricks: a copy of the
    /// channel's bricks with an apron of one voxel on their upper faces (9³ values each,
    /// [`PADDED_EDGE`]), made on the first call, so that the 8 corners of a lookup whose
    /// first corner lies in a brick never straddle bricks. The same values as
    /// [`Self::accessor`] (bit for bit: 16-bit voxels are copied as the f32 values the plain
    /// accessor converts them to), at 729/512 of a 32-bit channel's memory (729/256 of a
    /// 16-bit one's); made only for scalar channels below a size budget (1 GiB), the plain
    /// accessor otherwise.
    ///
    /// # Panics
    /// If `c` is not a channel of the grid (programming error).
    #[must_use]
    pub fn padded_accessor(&self, c: usize) -> Accessor<'_> {
        let ch = &self.channels[c];
        let padded = ch.padded.get_or_init(|| self.make_padded(c)).as_deref();
        Accessor::with_padded(self, c, padded)
    }

    /// The map of channel `c`'s integral from each point to the grid's edge along `to_light`
    /// (unit, world; [`SunMap`]), made on the first call (in parallel, 2 lookups per node) for
    /// the direction then asked; `None` for any other direction (beyond 1e-6 in each
    /// component), a grid with nothing active, or a channel with more than one component.
    ///
    /// # Panics
    /// If `c` is not a channel of the grid (programming error).
    #[must_use]
    pub fn sun_map(&self, c: usize, to_light: Vec3) -> Option<&SunMap> {
        let ch = &self.channels[c];
        let map = ch
            .sun_map
            .get_or_init(|| {
                (ch.kind.components() == 1)
                    .then(|| SunMap::build(self, c, to_light).map(Box::new))
                    .flatten()
            })
            .as_deref()?;
        ((map.to_light() - to_light).abs().max_element() <= 1e-6).then_some(map)
    }

    /// Makes the padded bricks of channel `c` now ([`Self::padded_accessor`]), in parallel,
    /// instead of on the first lookup (where the first render thread would make them alone
    /// while the others wait). Scene loading calls this for voxel and baked fBm interiors.
    ///
    /// # Panics
    /// If `c` is not a channel of the grid (programming error).
    pub fn prepare_padded(&self, c: usize) {
        let _ = self.padded_accessor(c);
    }

    /// The padded bricks ([`Self::padded_accessor`]'s layout, [`PADDED_EDGE`]³ voxels per
    /// brick, `x` slowest) of the scalar channel `scalar` and the vector channel `vector`
    /// interleaved: `[s, v.x, v.y, v.z]` per voxel, the values [`Accessor::value`] and
    /// [`Accessor::value_vec3`] read there (bit for bit, tiles and 16-bit storage included),
    /// so that a trilinear lookup of the one and nearest-voxel reads of the other at the
    /// same cell touch one table ([`Accessor::padded_pair_cell`]; a fabric's density and
    /// tangents). Made on the first call for the vector channel (in parallel) and kept
    /// there; `None` for another `scalar` asked later, for channels of other kinds, or
    /// beyond the padded copies' size budget (1 GiB).
    ///
    /// # Panics
    /// If `scalar` or `vector` is not a channel of the grid (programming error).
    #[must_use]
    pub fn padded_pairs(&self, scalar: usize, vector: usize) -> Option<&[[f32; 4]]> {
        let (s, table) = self.channels[vector]
            .padded_pairs
            .get_or_init(|| self.make_padded_pairs(scalar, vector).map(|t| (scalar, t)))
            .as_ref()?;
        (*s == scalar).then_some(table.as_slice())
    }

    /// [`Self::padded_pairs`] made now (bricks in parallel, two accessors per worker).
    fn make_padded_pairs(&self, scalar: usize, vector: usize) -> Option<Vec<[f32; 4]>> {
        let kinds = (
            self.channels[scalar].kind.components(),
            self.channels[vector].kind.components(),
        );
        if kinds != (1, 3) {
            return None;
        }
        let n = self.brick_count().checked_mul(PADDED_VOXELS)?;
        if n.checked_mul(16)? > PADDED_BUDGET {
            return None;
        }
        let mut out = vec![[0.0f32; 4]; n];
        out.par_chunks_mut(PADDED_VOXELS)
            .zip(self.brick_origin.par_iter())
            .for_each_init(
                || (Accessor::new(self, scalar), Accessor::new(self, vector)),
                |(s, v), (brick, &origin)| {
                    s.write_padded_pair_brick(v, origin >> BRICK_LOG2, brick);
                },
            );
        Some(out)
    }

    /// The padded bricks of channel `c` ([`Self::padded_accessor`]), or `None` where they are
    /// not made (bricks in parallel, one accessor per worker).
    fn make_padded(&self, c: usize) -> Option<Vec<f32>> {
        let ch = &self.channels[c];
        if ch.kind.components() != 1 {
            return None;
        }
        let n = self.brick_count().checked_mul(PADDED_VOXELS)?;
        if n.checked_mul(4)? > PADDED_BUDGET {
            return None;
        }
        let mut out = vec![0.0f32; n];
        out.par_chunks_mut(PADDED_VOXELS)
            .zip(self.brick_origin.par_iter())
            .for_each_init(
                || Accessor::new(self, c),
                |acc, (brick, &origin)| acc.write_padded_brick(origin >> BRICK_LOG2, brick),
            );
        Some(out)
    }

    /// Value of voxel `ijk` in channel 0 (active or not; tiles and background outside bricks).
    /// This and the other channel-0 conveniences below panic if the grid has no channel
    /// (a programming error); use an [`Accessor`] for repeated lookups.
    #[must_use]
    pub fn value_at(&self, ijk: IVec3) -> f32 {
        self.accessor(0).value(ijk)
    }
    /// Value of voxel `ijk` in Vec3 channel `c`.
    #[must_use]
    pub fn value_at_vec3(&self, c: usize, ijk: IVec3) -> Vec3 {
        self.accessor(c).value_vec3(ijk)
    }
    /// Whether voxel `ijk` is active (in an active brick voxel or an active tile).
    #[must_use]
    pub fn is_active(&self, ijk: IVec3) -> bool {
        match self.node_at_brick(ijk >> BRICK_LOG2) {
            Node::Brick(b) => {
                let v = voxel_offset(ijk & 7);
                self.brick_mask[b as usize][v >> 6] >> (v & 63) & 1 != 0
            }
            Node::Tile { active, .. } => active,
        }
    }
    /// Nearest-voxel lookup of channel 0 at index-space point `p`.
    #[must_use]
    pub fn sample_nearest_index(&self, p: Vec3) -> f32 {
        self.accessor(0).sample_nearest(p)
    }
    /// Nearest-voxel lookup of channel 0 at world-space point `p`.
    #[must_use]
    pub fn sample_nearest_world(&self, p: Vec3) -> f32 {
        self.accessor(0)
            .sample_nearest(self.world_to_index_point(p))
    }
    /// Trilinear lookup of channel 0 at index-space point `p` (voxel centres at integers).
    #[must_use]
    pub fn sample_trilinear_index(&self, p: Vec3) -> f32 {
        self.accessor(0).sample_trilinear(p)
    }
    /// Trilinear lookup of channel 0 at world-space point `p`.
    #[must_use]
    pub fn sample_trilinear_world(&self, p: Vec3) -> f32 {
        self.accessor(0)
            .sample_trilinear(self.world_to_index_point(p))
    }
    /// Trilinear lookup of Vec3 channel `c` at index-space point `p`.
    #[must_use]
    pub fn sample_trilinear_index_vec3(&self, c: usize, p: Vec3) -> Vec3 {
        self.accessor(c).sample_trilinear_vec3(p)
    }
    /// Trilinear lookup of Vec3 channel `c` at world-space point `p`.
    #[must_use]
    pub fn sample_trilinear_world_vec3(&self, c: usize, p: Vec3) -> Vec3 {
        self.accessor(c)
            .sample_trilinear_vec3(self.world_to_index_point(p))
    }

    /// Voxel size along each index axis in world units (lengths of the map's columns).
    #[must_use]
    pub fn voxel_size(&self) -> DVec3 {
        let m = self.index_to_world.matrix3;
        DVec3::new(m.x_axis.length(), m.y_axis.length(), m.z_axis.length())
    }
}
