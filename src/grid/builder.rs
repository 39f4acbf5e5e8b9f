//! Building grids in memory: voxel by voxel, brick by brick, or tile by tile.

use super::{
    block_slot, voxel_offset, Channel, ChannelKind, CoordMap, GridError, SparseGrid, Storage,
    TileLevel, Values, BG_ENTRY, BLOCK_ENTRIES, BLOCK_LOG2, BRICK_LOG2, BRICK_VOXELS, ROOT_LOG2,
    TILE_BIT,
};
use glam::{DAffine3, IVec3, Vec3};
use half::f16;

/// Builds a [`SparseGrid`]: add channels first, then set voxels, fill bricks or set tiles, and
/// call [`SparseGridBuilder::build`]. Setting a voxel inside a constant tile splits the tile
/// down to one brick (the rest of the tile stays constant).
#[derive(Debug)]
pub struct SparseGridBuilder {
    grid: SparseGrid,
}

impl SparseGridBuilder {
    /// An empty grid with no channels, brick storage `storage` and the identity map.
    #[must_use]
    pub fn new(storage: Storage) -> Self {
        SparseGridBuilder {
            grid: SparseGrid {
                brick_origin: Vec::new(),
                brick_mask: Vec::new(),
                blocks: Vec::new(),
                block_map: CoordMap::default(),
                root_tiles: CoordMap::default(),
                tile_active: vec![false],
                channels: Vec::new(),
                storage,
                index_to_world: DAffine3::IDENTITY,
                world_to_index: DAffine3::IDENTITY,
            },
        }
    }

    /// Adds a channel with background `background` (first component used for scalars) and
    /// returns its index. Existing bricks and tiles of the new channel hold the background.
    pub fn add_channel(&mut self, name: &str, kind: ChannelKind, background: Vec3) -> usize {
        let n = kind.components();
        let bg = [background.x, background.y, background.z];
        let mut tile_values = Vec::with_capacity(self.grid.tile_active.len() * n);
        for _ in 0..self.grid.tile_active.len() {
            tile_values.extend_from_slice(&bg[..n]);
        }
        let count = self.grid.brick_count() * BRICK_VOXELS * n;
        let values = match self.grid.storage {
            Storage::F32 => Values::F32(bg[..n].iter().copied().cycle().take(count).collect()),
            Storage::F16 => Values::F16(
                bg[..n]
                    .iter()
                    .map(|&v| f16::from_f32(v))
                    .cycle()
                    .take(count)
                    .collect(),
            ),
        };
        self.grid.channels.push(Channel {
            name: name.to_string(),
            kind,
            values,
            tile_values,
            padded: std::sync::OnceLock::new(),
            padded_pairs: std::sync::OnceLock::new(),
            sun_map: std::sync::OnceLock::new(),
        });
        self.grid.channels.len() - 1
    }

    /// Sets the index-to-world map.
    ///
    /// # Errors
    /// [`GridError::BadTransform`] if it is not finite or not invertible.
    pub fn set_index_to_world(&mut self, m: DAffine3) -> Result<(), GridError> {
        self.grid.set_index_to_world(m)
    }

    /// The grid built so far (for lookups during construction).
    #[must_use]
    pub fn grid(&self) -> &SparseGrid {
        &self.grid
    }

    fn check_channel(&self, c: usize) -> Result<usize, GridError> {
        self.grid
            .channels
            .get(c)
            .map(|ch| ch.kind.components())
            .ok_or(GridError::NoSuchChannel {
                index: c,
                count: self.grid.channels.len(),
            })
    }

    /// Adds a tile record holding `values` (concatenated components of every channel).
    fn new_tile(&mut self, values: &[f32], active: bool) -> Result<u32, GridError> {
        let total: usize = self.grid.channels.iter().map(|c| c.kind.components()).sum();
        if values.len() != total {
            return Err(GridError::WrongLength {
                what: "tile values",
                expected: total,
                got: values.len(),
            });
        }
        let t = self.grid.tile_active.len();
        if t >= TILE_BIT as usize {
            return Err(GridError::TooLarge);
        }
        self.grid.tile_active.push(active);
        let mut k = 0;
        for ch in &mut self.grid.channels {
            let n = ch.kind.components();
            ch.tile_values.extend_from_slice(&values[k..k + n]);
            k += n;
        }
        Ok(t as u32)
    }

    /// Sets a constant tile at `level` covering voxels `key << level.log2()` onwards, with
    /// `values` the concatenated components of every channel (one float per scalar channel,
    /// three per Vec3 channel). Returns the tile index.
    ///
    /// # Errors
    /// [`GridError::WrongLength`] for a wrong number of values, [`GridError::Occupied`] if finer
    /// nodes (bricks, blocks) already exist inside the tile.
    pub fn set_tile(
        &mut self,
        level: TileLevel,
        key: IVec3,
        values: &[f32],
        active: bool,
    ) -> Result<u32, GridError> {
        let occupied = GridError::Occupied { level, key };
        match level {
            TileLevel::Brick => {
                let b = self.block_for(key >> (BLOCK_LOG2 - BRICK_LOG2))?;
                let slot = block_slot(key);
                if self.grid.blocks[b][slot] & TILE_BIT == 0 {
                    return Err(occupied);
                }
                let t = self.new_tile(values, active)?;
                self.grid.blocks[b][slot] = TILE_BIT | t;
                Ok(t)
            }
            TileLevel::Block => {
                if let Some(&e) = self.grid.block_map.get(&key) {
                    if e & TILE_BIT == 0 {
                        return Err(occupied);
                    }
                }
                let t = self.new_tile(values, active)?;
                self.grid.block_map.insert(key, TILE_BIT | t);
                Ok(t)
            }
            TileLevel::Root => {
                let shift = ROOT_LOG2 - BLOCK_LOG2;
                if self.grid.block_map.keys().any(|k| (*k >> shift) == key) {
                    return Err(occupied);
                }
                let t = self.new_tile(values, active)?;
                self.grid.root_tiles.insert(key, t);
                Ok(t)
            }
        }
    }

    /// The block for `block_key`, created (from a covering root tile or the background) if
    /// missing; a constant 128^3 tile there is split into a block of 8^3 tiles.
    fn block_for(&mut self, block_key: IVec3) -> Result<usize, GridError> {
        let g = &mut self.grid;
        let fill = match g.block_map.get(&block_key) {
            Some(&e) if e & TILE_BIT == 0 => return Ok(e as usize),
            Some(&e) => e,
            None => {
                let root_key = block_key >> (ROOT_LOG2 - BLOCK_LOG2);
                match g.root_tiles.remove(&root_key) {
                    Some(t) => {
                        // Split the root tile into 32^3 block tiles.
                        let o = root_key << (ROOT_LOG2 - BLOCK_LOG2);
                        for x in 0..32 {
                            for y in 0..32 {
                                for z in 0..32 {
                                    g.block_map.insert(o + IVec3::new(x, y, z), TILE_BIT | t);
                                }
                            }
                        }
                        TILE_BIT | t
                    }
                    None => BG_ENTRY,
                }
            }
        };
        if g.blocks.len() >= TILE_BIT as usize {
            return Err(GridError::TooLarge);
        }
        g.blocks.push(Box::new([fill; BLOCK_ENTRIES]));
        let b = g.blocks.len() - 1;
        g.block_map.insert(block_key, b as u32);
        Ok(b)
    }

    /// The brick for `brick_key` (voxel coordinate `>> 3`), created if missing: a new brick
    /// takes the value and active state of the tile it replaces. Returns the brick index.
    ///
    /// # Errors
    /// [`GridError::TooLarge`] beyond 2^31 bricks.
    pub fn brick(&mut self, brick_key: IVec3) -> Result<usize, GridError> {
        let b = self.block_for(brick_key >> (BLOCK_LOG2 - BRICK_LOG2))?;
        let slot = block_slot(brick_key);
        let e = self.grid.blocks[b][slot];
        if e & TILE_BIT == 0 {
            return Ok(e as usize);
        }
        let t = (e & !TILE_BIT) as usize;
        let g = &mut self.grid;
        let idx = g.brick_origin.len();
        if idx >= TILE_BIT as usize {
            return Err(GridError::TooLarge);
        }
        g.brick_origin.push(brick_key << BRICK_LOG2);
        g.brick_mask.push(if g.tile_active[t] {
            [u64::MAX; 8]
        } else {
            [0; 8]
        });
        for ch in &mut g.channels {
            let n = ch.kind.components();
            let tv = &ch.tile_values[t * n..t * n + n];
            match &mut ch.values {
                Values::F32(v) if n == 1 => v.resize(v.len() + BRICK_VOXELS, tv[0]),
                Values::F16(v) if n == 1 => v.resize(v.len() + BRICK_VOXELS, f16::from_f32(tv[0])),
                Values::F32(v) => {
                    for _ in 0..BRICK_VOXELS {
                        v.extend_from_slice(tv);
                    }
                }
                Values::F16(v) => {
                    for _ in 0..BRICK_VOXELS {
                        v.extend(tv.iter().map(|&x| f16::from_f32(x)));
                    }
                }
            }
        }
        g.blocks[b][slot] = idx as u32;
        Ok(idx)
    }

    /// Sets component values of voxel `ijk` in channel `c` (1 or 3 values) and activates it.
    ///
    /// # Errors
    /// Unknown channel or wrong number of components.
    pub fn set_value_components(
        &mut self,
        c: usize,
        ijk: IVec3,
        v: &[f32],
    ) -> Result<(), GridError> {
        let n = self.check_channel(c)?;
        if v.len() != n {
            return Err(GridError::WrongLength {
                what: "voxel value",
                expected: n,
                got: v.len(),
            });
        }
        let b = self.brick(ijk >> BRICK_LOG2)?;
        let o = voxel_offset(ijk & 7);
        self.grid.brick_mask[b][o >> 6] |= 1 << (o & 63);
        let i = (b * BRICK_VOXELS + o) * n;
        match &mut self.grid.channels[c].values {
            Values::F32(s) => s[i..i + n].copy_from_slice(v),
            Values::F16(s) => {
                for (d, &x) in s[i..i + n].iter_mut().zip(v) {
                    *d = f16::from_f32(x);
                }
            }
        }
        Ok(())
    }

    /// Sets scalar channel `c` at voxel `ijk` to `v` and activates the voxel.
    ///
    /// # Errors
    /// Unknown channel, or a Vec3 channel.
    pub fn set_value(&mut self, c: usize, ijk: IVec3, v: f32) -> Result<(), GridError> {
        self.set_value_components(c, ijk, &[v])
    }

    /// Sets Vec3 channel `c` at voxel `ijk` to `v` and activates the voxel.
    ///
    /// # Errors
    /// Unknown channel, or a scalar channel.
    pub fn set_value_vec3(&mut self, c: usize, ijk: IVec3, v: Vec3) -> Result<(), GridError> {
        self.set_value_components(c, ijk, &v.to_array())
    }

    /// Sets the active state of voxel `ijk` (creating its brick if needed).
    ///
    /// # Errors
    /// [`GridError::TooLarge`] beyond 2^31 bricks.
    pub fn set_active(&mut self, ijk: IVec3, active: bool) -> Result<(), GridError> {
        let b = self.brick(ijk >> BRICK_LOG2)?;
        let o = voxel_offset(ijk & 7);
        if active {
            self.grid.brick_mask[b][o >> 6] |= 1 << (o & 63);
        } else {
            self.grid.brick_mask[b][o >> 6] &= !(1 << (o & 63));
        }
        Ok(())
    }

    /// Fills channel `c` of the brick at `brick_key` with `values` (512 × components, voxel
    /// order `(x << 6) | (y << 3) | z`) and sets its active mask. Returns the brick index.
    ///
    /// # Errors
    /// Unknown channel or wrong number of values.
    pub fn fill_brick(
        &mut self,
        c: usize,
        brick_key: IVec3,
        values: &[f32],
        active_mask: [u64; 8],
    ) -> Result<usize, GridError> {
        let n = self.check_channel(c)?;
        if values.len() != BRICK_VOXELS * n {
            return Err(GridError::WrongLength {
                what: "brick values",
                expected: BRICK_VOXELS * n,
                got: values.len(),
            });
        }
        let b = self.brick(brick_key)?;
        self.grid.brick_mask[b] = active_mask;
        let i = b * BRICK_VOXELS * n;
        match &mut self.grid.channels[c].values {
            Values::F32(s) => s[i..i + values.len()].copy_from_slice(values),
            Values::F16(s) => {
                for (d, &x) in s[i..i + values.len()].iter_mut().zip(values) {
                    *d = f16::from_f32(x);
                }
            }
        }
        Ok(b)
    }

    /// Reserves room for `additional` more bricks (avoids regrowing storage when the brick
    /// count is known, e.g. when loading a VDB file).
    pub fn reserve_bricks(&mut self, additional: usize) {
        let g = &mut self.grid;
        g.brick_origin.reserve(additional);
        g.brick_mask.reserve(additional);
        for ch in &mut g.channels {
            let n = additional * BRICK_VOXELS * ch.kind.components();
            match &mut ch.values {
                Values::F32(v) => v.reserve(n),
                Values::F16(v) => v.reserve(n),
            }
        }
    }

    /// Sets the active mask of brick `b` (an index returned by [`SparseGridBuilder::brick`]).
    ///
    /// # Panics
    /// If `b` is not a brick index (programming error).
    pub fn set_brick_mask(&mut self, b: usize, mask: [u64; 8]) {
        self.grid.brick_mask[b] = mask;
    }

    /// Mutable access to all brick values of channel `c` (brick `b`, voxel `v`, component
    /// `k` at `(b * 512 + v) * components + k`), for filling many bricks at once (e.g. in
    /// parallel).
    ///
    /// # Panics
    /// If `c` is not a channel (programming error).
    pub fn values_mut(&mut self, c: usize) -> super::ValuesMut<'_> {
        match &mut self.grid.channels[c].values {
            Values::F32(v) => super::ValuesMut::F32(v),
            Values::F16(v) => super::ValuesMut::F16(v),
        }
    }

    /// Finishes the grid.
    #[must_use]
    pub fn build(mut self) -> SparseGrid {
        // Padded copies made while building (through `grid()`) may be out of date.
        for ch in &mut self.grid.channels {
            ch.padded = std::sync::OnceLock::new();
            ch.padded_pairs = std::sync::OnceLock::new();
            ch.sun_map = std::sync::OnceLock::new();
        }
        self.grid
    }
}
