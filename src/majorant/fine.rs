//! Local bounds: the range of the density over small cells of the grid's *dual* lattice (cells
//! between voxel centres), read in O(1) at any point of a ray without a walk
//! (docs/references.md §4.10).
//!
//! A trilinear lookup at index-space point `p` blends the 8 voxels around `floor(p)`: the
//! voxels `floor(p)` and `floor(p) + 1` on each axis. A dual cell of edge `s` voxels holds the
//! points whose `floor(p)` lies in `[c·s, c·s + s − 1]` per axis, so every lookup inside it
//! reads voxels of `[c·s, c·s + s]` only: `s + 1` voxels per axis, where a cell of the
//! majorant pyramid (aligned with the voxels' own extents) needs its `s` voxels and a
//! one-voxel apron on both sides, `s + 2`. With `s = 1` the bounds are the exact range of the
//! trilinear field over the cell (its extrema are at the corners).
//!
//! The trackers use these bounds to decide most tentative collisions of a coarse segment
//! without a density lookup (`tracking::delta_track_local`): a tentative collision above the
//! local majorant is null for sure, one below the local minorant belongs to the control part.
//! Bounds are stored as 16-bit codes on a linear scale over the grid's range, the maximum
//! rounded up and the minimum rounded down, so they stay conservative.

use glam::{IVec3, Vec3};
use rayon::prelude::*;

use super::MajorantError;
use crate::grid::{voxel_offset, BrickData, Node, SparseGrid, BRICK_DIM, BRICK_VOXELS};

/// The largest number of cells of a local-bounds table (4 bytes each, 2 MiB in all): the cell
/// edge doubles until the grid's region fits. Larger tables are tighter but leave the caches:
/// on the 128³ peer cloud, 2^22 cells (edge 1 voxel, 1.15 lookups per real collision) rendered
/// slower than 2^19 (edge 2, 1.31) and 2^16 (edge 4, 1.63), which were on a par
/// (docs/BENCHMARKS.md, "Local bounds").
pub const MAX_LOCAL_CELLS: usize = 1 << 19;

/// Edge of a block of cells in the table's layout.
const BLOCK: i32 = 4;
/// Cells in a block.
const BLOCK_CELLS: usize = (BLOCK * BLOCK * BLOCK) as usize;

/// Per-cell bounds of a grid channel over its dual lattice (see the module documentation).
#[derive(Clone, Debug)]
pub struct LocalBounds {
    /// The first voxel (sample point) of cell (0, 0, 0).
    origin: IVec3,
    /// log₂ of the cell edge, voxels.
    log2: i32,
    dims: IVec3,
    /// Decoded value = `lo + code · scale`.
    lo: f32,
    scale: f32,
    /// Per cell: (minimum code, maximum code), in blocks of 4³ cells (x fastest within a
    /// block, blocks x fastest), so that the cells a ray probes in a row share cache lines.
    cells: Vec<[u16; 2]>,
    /// Blocks per axis.
    blocks: IVec3,
    /// Per block: the largest maximum code of its cells. A few kilobytes that stay in the
    /// first-level cache: most tentative collisions of a coarse segment lie above their
    /// block's maximum already and need no read of `cells` ([`Self::probe`]).
    block_max: Vec<u16>,
    /// The value outside the table's box (every voxel there is background).
    background: f32,
}

/// Widens `columns[vx·ny + vy]` (`(nx, ny) = size`) by the values of channel `channel` at
/// voxels `corner + (vx, vy, vz)`, `vz` in `0..=depth`: the values an
/// [`crate::grid::Accessor`] reads there, gathered node by node (a tile's value once per
/// column it covers, a brick's voxels from its storage), not voxel by voxel through the
/// accessor's look-up. Min and max of a set do not depend on the order they are taken in, so
/// the ranges are the per-voxel scan's.
fn column_ranges(
    grid: &SparseGrid,
    channel: usize,
    corner: IVec3,
    size: (usize, usize),
    depth: i32,
    columns: &mut [[f32; 2]],
) {
    let (nx, ny) = size;
    let hi = corner + IVec3::new(nx as i32 - 1, ny as i32 - 1, depth);
    let (klo, khi) = (corner >> 3i32, hi >> 3i32);
    for kz in klo.z..=khi.z {
        let z_lo = corner.z.max(kz * BRICK_DIM) - kz * BRICK_DIM;
        let z_hi = hi.z.min(kz * BRICK_DIM + BRICK_DIM - 1) - kz * BRICK_DIM;
        for kx in klo.x..=khi.x {
            let x_lo = corner.x.max(kx * BRICK_DIM);
            let x_hi = hi.x.min(kx * BRICK_DIM + BRICK_DIM - 1);
            for ky in klo.y..=khi.y {
                let y_lo = corner.y.max(ky * BRICK_DIM);
                let y_hi = hi.y.min(ky * BRICK_DIM + BRICK_DIM - 1);
                let node = grid.node_at_brick(IVec3::new(kx, ky, kz));
                for vx in x_lo..=x_hi {
                    let row = (vx - corner.x) as usize * ny;
                    let cols = &mut columns
                        [row + (y_lo - corner.y) as usize..=row + (y_hi - corner.y) as usize];
                    match node {
                        Node::Tile { tile, .. } => {
                            let v = grid.tile_value(channel, tile);
                            for col in cols {
                                col[0] = col[0].min(v);
                                col[1] = col[1].max(v);
                            }
                        }
                        Node::Brick(b) => {
                            let data = grid.brick_data(channel, b as usize);
                            for (col, vy) in cols.iter_mut().zip(y_lo..=y_hi) {
                                for lz in z_lo..=z_hi {
                                    let local = IVec3::new(vx & 7, vy & 7, lz);
                                    let v = match data {
                                        BrickData::F32(d) => {
                                            d[voxel_offset(local) * (d.len() / BRICK_VOXELS)]
                                        }
                                        BrickData::F16(d) => d
                                            [voxel_offset(local) * (d.len() / BRICK_VOXELS)]
                                            .to_f32(),
                                    };
                                    col[0] = col[0].min(v);
                                    col[1] = col[1].max(v);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

impl LocalBounds {
    /// Builds the table of channel `channel` of `grid`: the smallest power-of-two cell edge
    /// whose table over the grid's non-background region has at most [`MAX_LOCAL_CELLS`] cells.
    pub fn from_grid(grid: &SparseGrid, channel: usize) -> Result<Self, MajorantError> {
        let background = grid.background(channel);
        let mut lo = IVec3::MAX;
        let mut hi = IVec3::MIN;
        for b in 0..grid.brick_count() {
            let o = grid.brick_origin(b);
            lo = lo.min(o);
            hi = hi.max(o + IVec3::splat(BRICK_DIM - 1));
        }
        for t in grid.tiles() {
            if grid.tile_value(channel, t.tile) != background {
                lo = lo.min(t.origin);
                hi = hi.max(t.origin + IVec3::splat((t.level.dim() - 1) as i32));
            }
        }
        if lo.x > hi.x {
            return Ok(Self::constant(background));
        }
        // Points whose floor is lo − 1 already read voxel lo.
        let first = lo - IVec3::ONE;
        let span = (hi - first + IVec3::ONE).as_i64vec3();
        let mut log2 = 0;
        let dims = loop {
            let s = 1i64 << log2;
            let d = (span + glam::I64Vec3::splat(s - 1)) / s;
            if (d.x * d.y * d.z) as usize <= MAX_LOCAL_CELLS || log2 >= 20 {
                break d.as_ivec3();
            }
            log2 += 1;
        };
        let count = dims.x as usize * dims.y as usize * dims.z as usize;
        if dims.min_element() <= 0 || count > MAX_LOCAL_CELLS {
            return Err(MajorantError::TooLarge {
                cells: count,
                max: MAX_LOCAL_CELLS,
            });
        }
        let s = 1i32 << log2;
        let plane = dims.x as usize * dims.y as usize;
        // Exact f32 bounds first, one z-layer of cells per task: each voxel column's range over
        // the layer's s + 1 voxel planes, then each cell's over its (s + 1)² columns (each voxel
        // read once per layer instead of once per cell that holds it).
        let mut exact = vec![[0.0f32; 2]; count];
        let (nx, ny) = ((dims.x * s + 1) as usize, (dims.y * s + 1) as usize);
        let su = s as usize;
        exact
            .par_chunks_mut(plane)
            .enumerate()
            .for_each(|(z, layer)| {
                let mut columns = vec![[f32::INFINITY, f32::NEG_INFINITY]; nx * ny];
                let z0 = first.z + z as i32 * s;
                let corner = IVec3::new(first.x, first.y, z0);
                column_ranges(grid, channel, corner, (nx, ny), s, &mut columns);
                for (j, cell) in layer.iter_mut().enumerate() {
                    let (x, y) = (j % dims.x as usize, j / dims.x as usize);
                    let (mut mn, mut mx) = (f32::INFINITY, f32::NEG_INFINITY);
                    for vx in x * su..=x * su + su {
                        for &[a, b] in columns
                            .get(vx * ny + y * su..=vx * ny + y * su + su)
                            .unwrap_or(&[])
                        {
                            mn = mn.min(a);
                            mx = mx.max(b);
                        }
                    }
                    *cell = [mn, mx];
                }
            });
        let (mut gmin, mut gmax) = (background, background);
        for (i, &[mn, mx]) in exact.iter().enumerate() {
            if !(mn.is_finite() && mx.is_finite()) {
                let c = IVec3::new(
                    (i % dims.x as usize) as i32,
                    ((i / dims.x as usize) % dims.y as usize) as i32,
                    (i / plane) as i32,
                );
                return Err(MajorantError::InvalidBound {
                    brick: ((first + c * s) >> 3i32).to_array(),
                    min: mn,
                    max: mx,
                });
            }
            gmin = gmin.min(mn);
            gmax = gmax.max(mx);
        }
        let mut scale = (gmax - gmin) / f32::from(u16::MAX);
        // The top code must decode to at least the grid's maximum.
        while scale > 0.0 && gmin + f32::from(u16::MAX) * scale < gmax {
            scale = f32::from_bits(scale.to_bits() + 1);
        }
        let blocks = (dims + IVec3::splat(BLOCK - 1)) / BLOCK;
        let padded = (blocks.x * blocks.y * blocks.z) as usize * (BLOCK * BLOCK * BLOCK) as usize;
        let mut table = LocalBounds {
            origin: first,
            log2,
            dims,
            lo: gmin,
            scale,
            cells: Vec::new(),
            blocks,
            block_max: Vec::new(),
            background,
        };
        let fill = [table.encode_down(background), table.encode_up(background)];
        let mut cells = vec![fill; padded];
        for (i, &[mn, mx]) in exact.iter().enumerate() {
            let c = IVec3::new(
                (i % dims.x as usize) as i32,
                ((i / dims.x as usize) % dims.y as usize) as i32,
                (i / plane) as i32,
            );
            if let Some(slot) = cells.get_mut(table.slot(c)) {
                *slot = [table.encode_down(mn), table.encode_up(mx)];
            }
        }
        table.block_max = cells
            .chunks(BLOCK_CELLS)
            .map(|block| block.iter().map(|&[_, mx]| mx).max().unwrap_or(0))
            .collect();
        table.cells = cells;
        Ok(table)
    }

    /// A table without cells: the value is `background` everywhere.
    #[must_use]
    pub fn constant(background: f32) -> Self {
        LocalBounds {
            origin: IVec3::ZERO,
            log2: 0,
            dims: IVec3::ZERO,
            lo: background,
            scale: 0.0,
            cells: Vec::new(),
            blocks: IVec3::ZERO,
            block_max: Vec::new(),
            background,
        }
    }

    /// Index of cell `c` (inside `dims`) in the blocked layout.
    #[inline(always)]
    fn slot(&self, c: IVec3) -> usize {
        let (block, within) = self.block_slot(c);
        block * BLOCK_CELLS + within
    }

    /// The block of cell `c` (inside `dims`) and the cell's index within the block.
    #[inline(always)]
    fn block_slot(&self, c: IVec3) -> (usize, usize) {
        let b = c >> 2i32;
        let w = c & IVec3::splat(BLOCK - 1);
        let block = (b.z as usize * self.blocks.y as usize + b.y as usize) * self.blocks.x as usize
            + b.x as usize;
        (
            block,
            (w.z as usize * BLOCK as usize + w.y as usize) * BLOCK as usize + w.x as usize,
        )
    }

    fn decode(&self, code: u16) -> f32 {
        self.lo + f32::from(code) * self.scale
    }

    /// The largest code whose value is at most `v` (the minimum rounded down).
    fn encode_down(&self, v: f32) -> u16 {
        if !(self.scale > 0.0) {
            return 0;
        }
        let mut q = ((v - self.lo) / self.scale).floor().clamp(0.0, 65535.0) as u16;
        while q > 0 && self.decode(q) > v {
            q -= 1;
        }
        q
    }

    /// The smallest code whose value is at least `v` (the maximum rounded up; the top code
    /// decodes to at least the grid's maximum by construction of `scale`).
    fn encode_up(&self, v: f32) -> u16 {
        if !(self.scale > 0.0) {
            return 0;
        }
        let mut q = ((v - self.lo) / self.scale).ceil().clamp(0.0, 65535.0) as u16;
        while q < u16::MAX && self.decode(q) < v {
            q += 1;
        }
        q
    }

    /// Edge of a cell, voxels.
    #[must_use]
    pub fn cell_voxels(&self) -> i32 {
        1 << self.log2
    }

    /// Cells in the table.
    #[must_use]
    pub fn cell_count(&self) -> usize {
        self.dims.x.max(0) as usize * self.dims.y.max(0) as usize * self.dims.z.max(0) as usize
    }

    /// Bounds `(min, max)` of every value a trilinear lookup at index-space point `p` can
    /// return (`p` computed exactly as the lookup computes it).
    #[inline]
    #[must_use]
    pub fn at(&self, p: Vec3) -> (f32, f32) {
        self.probe(p, |_| false)
            .unwrap_or((self.background, self.background))
    }

    /// [`Self::at`], unless the largest maximum of the block of cells around `p` (a proven
    /// upper bound of every lookup at `p`, read from a table small enough to stay cached)
    /// satisfies `skip`: then `None`, without reading the cell.
    #[inline(always)]
    pub fn probe(&self, p: Vec3, skip: impl FnOnce(f32) -> bool) -> Option<(f32, f32)> {
        // floor(p) without a libm call, as the grid's trilinear lookup computes it.
        let t = p.as_ivec3();
        let tf = t.as_vec3();
        let i = t - IVec3::new(
            i32::from(tf.x > p.x),
            i32::from(tf.y > p.y),
            i32::from(tf.z > p.z),
        );
        // A point below the origin has a negative cell (the shift is arithmetic), which is
        // beyond `dims` unsigned: one comparison for both sides.
        let c = i.wrapping_sub(self.origin) >> self.log2;
        if c.as_uvec3().cmpge(self.dims.as_uvec3()).any() {
            return Some((self.background, self.background));
        }
        let (block, within) = self.block_slot(c);
        if let Some(&code) = self.block_max.get(block) {
            if skip(self.decode(code)) {
                return None;
            }
        }
        match self.cells.get(block * BLOCK_CELLS + within) {
            Some(&[a, b]) => Some((self.decode(a), self.decode(b))),
            None => Some((self.background, self.background)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_outwards() {
        let t = LocalBounds {
            origin: IVec3::ZERO,
            log2: 0,
            dims: IVec3::ZERO,
            lo: 0.0,
            scale: 1.0 / 65535.0,
            cells: Vec::new(),
            blocks: IVec3::ZERO,
            block_max: Vec::new(),
            background: 0.0,
        };
        for v in [0.0f32, 1e-7, 0.3, 0.5, 0.7777, 0.999_999, 1.0] {
            let (d, u) = (t.decode(t.encode_down(v)), t.decode(t.encode_up(v)));
            assert!(d <= v && u >= v, "{v}: [{d}, {u}]");
            assert!(u - d <= 2.0 / 65535.0, "{v}: [{d}, {u}]");
        }
        assert_eq!(t.decode(t.encode_up(0.0)), 0.0);
    }

    /// Column ranges gathered node by node equal the per-voxel accessor scan they replace, bit
    /// for bit: both storages, a vector channel before the density, brick and block tiles,
    /// windows crossing brick boundaries on every axis and depths from 0 to 17 voxels.
    #[test]
    fn column_ranges_equal_the_accessor_scan() {
        use super::super::test_grids::{mixed_grid, Mix};
        use crate::grid::Storage;
        let mut rng = Mix(11);
        let mut checked = 0usize;
        for storage in [Storage::F32, Storage::F16] {
            let (grid, density) = mixed_grid(storage, &mut rng);
            for _ in 0..300 {
                let corner = IVec3::new(
                    (rng.next() % 60) as i32 - 20,
                    (rng.next() % 40) as i32 - 12,
                    (rng.next() % 50) as i32 - 16,
                );
                let (nx, ny) = (
                    1 + (rng.next() % 30) as usize,
                    1 + (rng.next() % 30) as usize,
                );
                let depth = (rng.next() % 18) as i32;
                for channel in [0, density] {
                    let mut got = vec![[f32::INFINITY, f32::NEG_INFINITY]; nx * ny];
                    column_ranges(&grid, channel, corner, (nx, ny), depth, &mut got);
                    let mut acc = grid.accessor(channel);
                    for (i, g) in got.iter().enumerate() {
                        let v0 = corner + IVec3::new((i / ny) as i32, (i % ny) as i32, 0);
                        let mut want = [f32::INFINITY, f32::NEG_INFINITY];
                        for vz in 0..=depth {
                            let v = acc.value(v0 + IVec3::new(0, 0, vz));
                            want[0] = want[0].min(v);
                            want[1] = want[1].max(v);
                        }
                        assert_eq!(want.map(f32::to_bits), g.map(f32::to_bits), "{v0} {depth}");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 100_000, "{checked}");
    }
}
