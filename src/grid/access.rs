//! Cached lookups: nearest and trilinear interpolation.

use super::{
    block_slot, voxel_offset, SparseGrid, Values, BLOCK_LOG2, BRICK_LOG2, BRICK_VOXELS,
    PADDED_EDGE, PADDED_VOXELS, ROOT_LOG2, TILE_BIT,
};
use glam::{IVec3, Vec3};

/// Brick values of the accessor's channel.
#[derive(Clone, Copy, Debug)]
enum Vals<'a> {
    F32(&'a [f32]),
    F16(&'a [half::f16]),
}

/// A lookup handle on one channel of a [`SparseGrid`] that remembers the last brick and the
/// last block it visited: coherent lookups (along a ray, within a brick or block) skip the
/// hash-map walk. Cheap to create; not shared between threads (make one per thread).
#[derive(Clone, Debug)]
pub struct Accessor<'a> {
    grid: &'a SparseGrid,
    vals: Vals<'a>,
    tiles: &'a [f32],
    /// The channel's padded bricks ([`SparseGrid::padded_accessor`]), if any.
    padded: Option<&'a [f32]>,
    comps: usize,
    key: IVec3,
    /// Brick index, or `TILE_BIT | tile` for a constant cell.
    entry: u32,
    block_key: IVec3,
    /// Block index, or `TILE_BIT | tile` for a constant block (or root tile / background).
    block_entry: u32,
}

const NO_KEY: IVec3 = IVec3::new(i32::MIN, i32::MIN, i32::MIN);

impl<'a> Accessor<'a> {
    /// An accessor on channel `channel` of `grid`.
    ///
    /// # Panics
    /// If `channel` is out of range (programming error).
    #[must_use]
    pub fn new(grid: &'a SparseGrid, channel: usize) -> Self {
        Self::with_padded(grid, channel, None)
    }

    /// An accessor on channel `channel` of `grid` that reads the 8 corners of a trilinear
    /// lookup from `padded` (the channel's padded bricks, [`SparseGrid::padded_accessor`])
    /// where the first corner lies in a brick.
    ///
    /// # Panics
    /// If `channel` is out of range (programming error).
    #[must_use]
    pub(super) fn with_padded(
        grid: &'a SparseGrid,
        channel: usize,
        padded: Option<&'a [f32]>,
    ) -> Self {
        let ch = &grid.channels[channel];
        let vals = match &ch.values {
            Values::F32(v) => Vals::F32(v),
            Values::F16(v) => Vals::F16(v),
        };
        Accessor {
            grid,
            vals,
            tiles: &ch.tile_values,
            padded,
            comps: ch.kind.components(),
            key: NO_KEY,
            entry: TILE_BIT,
            block_key: NO_KEY,
            block_entry: TILE_BIT,
        }
    }

    /// The grid.
    #[must_use]
    pub fn grid(&self) -> &'a SparseGrid {
        self.grid
    }

    #[inline(always)]
    fn resolve(&mut self, key: IVec3) -> u32 {
        if key == self.key {
            return self.entry;
        }
        let block_key = key >> (BLOCK_LOG2 - BRICK_LOG2);
        if block_key != self.block_key {
            self.block_entry = self.resolve_block(block_key);
            self.block_key = block_key;
        }
        let be = self.block_entry;
        let e = if be & TILE_BIT != 0 {
            be
        } else {
            self.grid.blocks[be as usize][block_slot(key)]
        };
        self.key = key;
        self.entry = e;
        e
    }

    /// Like `resolve`, but leaves the brick cache alone (the block cache is updated).
    #[inline(always)]
    fn peek(&mut self, key: IVec3) -> u32 {
        let block_key = key >> (BLOCK_LOG2 - BRICK_LOG2);
        if block_key != self.block_key {
            self.block_entry = self.resolve_block(block_key);
            self.block_key = block_key;
        }
        let be = self.block_entry;
        if be & TILE_BIT != 0 {
            be
        } else {
            self.grid.blocks[be as usize][block_slot(key)]
        }
    }

    #[cold]
    fn resolve_block(&self, block_key: IVec3) -> u32 {
        let g = self.grid;
        match g.block_map.get(&block_key) {
            Some(&e) => e,
            None if g.root_tiles.is_empty() => TILE_BIT,
            None => g
                .root_tiles
                .get(&(block_key >> (ROOT_LOG2 - BLOCK_LOG2)))
                .map_or(TILE_BIT, |&t| TILE_BIT | t),
        }
    }

    /// Component `c` at brick entry `e`, voxel offset `v`.
    #[inline(always)]
    fn fetch(&self, e: u32, v: usize, c: usize) -> f32 {
        if e & TILE_BIT != 0 {
            return self.tiles[(e & !TILE_BIT) as usize * self.comps + c];
        }
        let i = (e as usize * BRICK_VOXELS + v) * self.comps + c;
        match self.vals {
            Vals::F32(s) => s[i],
            Vals::F16(s) => s[i].to_f32(),
        }
    }

    /// Writes the padded copy of brick `key` (brick coordinates) into `out` (9³ values): the
    /// first component of the voxels `8 key + (x, y, z)`, `x, y, z ∈ 0..9` ([`PADDED_EDGE`]),
    /// `z` fastest; the 8 bricks (or tiles) they lie in are resolved once.
    pub(super) fn write_padded_brick(&mut self, key: IVec3, out: &mut [f32]) {
        let e = self.padded_entries(key);
        for (slot, (n, v)) in out.iter_mut().zip(padded_voxels()) {
            *slot = self.fetch(e[n], v, 0);
        }
    }

    /// The entries of the 8 bricks (or tiles) `key + (0|1, 0|1, 0|1)` that a padded copy of
    /// brick `key` reads, in [`padded_voxels`]' numbering (`x` slowest).
    fn padded_entries(&mut self, key: IVec3) -> [u32; 8] {
        let mut e = [0u32; 8];
        for (n, en) in e.iter_mut().enumerate() {
            let d = IVec3::new((n >> 2) as i32, ((n >> 1) & 1) as i32, (n & 1) as i32);
            *en = self.peek(key + d);
        }
        e
    }

    /// [`Self::write_padded_brick`] for the interleaved pairs of [`SparseGrid::padded_pairs`]:
    /// this accessor's first component and `vector`'s three (an accessor on a vector channel
    /// of the same grid) at each of the 9³ voxels, into `out`.
    pub(super) fn write_padded_pair_brick(
        &mut self,
        vector: &Accessor<'_>,
        key: IVec3,
        out: &mut [[f32; 4]],
    ) {
        let e = self.padded_entries(key);
        for (slot, (n, v)) in out.iter_mut().zip(padded_voxels()) {
            let t = vector.fetch_vec3(e[n], v);
            *slot = [self.fetch(e[n], v, 0), t.x, t.y, t.z];
        }
    }

    /// The entries of `table` ([`SparseGrid::padded_pairs`] of this accessor's grid) at the 8
    /// corners of the trilinear cell whose first corner is voxel `i`, as
    /// `c[(dx << 2) | (dy << 1) | dz]` (the order of [`trilerp`]), read with one brick
    /// resolution through this accessor's cache; `None` where `i` lies in a tile (or the
    /// background), or `table` is too short.
    #[inline(always)]
    pub fn padded_pair_cell(&mut self, table: &[[f32; 4]], i: IVec3) -> Option<[[f32; 4]; 8]> {
        const E: usize = PADDED_EDGE;
        const OFF: [usize; 8] = [0, 1, E, E + 1, E * E, E * E + 1, E * E + E, E * E + E + 1];
        let e = self.resolve(i >> BRICK_LOG2);
        if e & TILE_BIT != 0 {
            return None;
        }
        let l = i & 7;
        let base =
            e as usize * PADDED_VOXELS + (l.x as usize * E + l.y as usize) * E + l.z as usize;
        let s = table.get(base..base + OFF[7] + 1)?;
        Some(std::array::from_fn(|k| s[OFF[k]]))
    }

    /// Value (first component) of voxel `ijk`, active or not.
    #[inline]
    pub fn value(&mut self, ijk: IVec3) -> f32 {
        let e = self.resolve(ijk >> BRICK_LOG2);
        self.fetch(e, voxel_offset(ijk & 7), 0)
    }

    /// Vector value of voxel `ijk` (a scalar channel is splatted).
    #[inline]
    pub fn value_vec3(&mut self, ijk: IVec3) -> Vec3 {
        let e = self.resolve(ijk >> BRICK_LOG2);
        let v = voxel_offset(ijk & 7);
        self.fetch_vec3(e, v)
    }

    /// [`Self::value_vec3`] inlined into the caller where the voxel lies in a 32-bit vector
    /// brick, the common case of a fabric's tangent channel (the same value: the brick's
    /// three components at the voxel, as [`Self::fetch`] reads them); tiles, half-precision
    /// and scalar channels go through [`Self::value_vec3`]'s body out of line.
    #[inline(always)]
    pub fn value_vec3_hot(&mut self, ijk: IVec3) -> Vec3 {
        let e = self.resolve(ijk >> BRICK_LOG2);
        let v = voxel_offset(ijk & 7);
        if e & TILE_BIT == 0 && self.comps == 3 {
            if let Vals::F32(s) = self.vals {
                let i = (e as usize * BRICK_VOXELS + v) * 3;
                if let Some(c) = s.get(i..i + 3) {
                    return Vec3::new(c[0], c[1], c[2]);
                }
            }
        }
        self.fetch_vec3_cold(e, v)
    }

    /// [`Self::fetch_vec3`] out of line (the rare cases of [`Self::value_vec3_hot`]).
    #[inline(never)]
    #[cold]
    fn fetch_vec3_cold(&self, e: u32, v: usize) -> Vec3 {
        self.fetch_vec3(e, v)
    }

    /// The vector value at brick entry `e`, voxel offset `v` (a scalar channel splatted).
    #[inline(always)]
    fn fetch_vec3(&self, e: u32, v: usize) -> Vec3 {
        if self.comps == 3 {
            Vec3::new(
                self.fetch(e, v, 0),
                self.fetch(e, v, 1),
                self.fetch(e, v, 2),
            )
        } else {
            Vec3::splat(self.fetch(e, v, 0))
        }
    }

    /// Value of the voxel nearest to index-space point `p`.
    #[inline]
    pub fn sample_nearest(&mut self, p: Vec3) -> f32 {
        self.value((p + Vec3::splat(0.5)).floor().as_ivec3())
    }

    /// Trilinear interpolation of the first component at index-space point `p` (voxel
    /// centres at integer coordinates, as OpenVDB's `BoxSampler`).
    ///
    /// The common cases of a padded accessor, a cell whose first corner lies in a brick or
    /// whose 8 corners lie in one constant tile, are a short inlined path; every other case
    /// (a cell across a tile's edge, plain accessors) goes
    /// through [`Self::gather`] out of line (the same values: the padded copy holds what
    /// `gather` reads there).
    #[inline]
    pub fn sample_trilinear(&mut self, p: Vec3) -> f32 {
        let (i, t) = floor_frac(p);
        if let Some(pad) = self.padded {
            let e = self.resolve(i >> BRICK_LOG2);
            if e & TILE_BIT == 0 {
                if let Some(c) = padded_corners(pad, e, i & 7) {
                    return trilerp(&c, t);
                }
            } else if (i & 7).cmplt(IVec3::splat(7)).all() {
                // All 8 corners under one constant tile (or the background): its value, as
                // `gather` finds it.
                if let Some(&v) = self.tiles.get((e & !TILE_BIT) as usize * self.comps) {
                    return v;
                }
            }
        }
        self.sample_trilinear_cold(i, t)
    }

    /// [`Self::sample_trilinear`] at the cell of first corner `i` with weights `t`, by
    /// [`Self::gather`].
    #[inline(never)]
    fn sample_trilinear_cold(&mut self, i: IVec3, t: Vec3) -> f32 {
        match self.gather(i) {
            Ok(c) => trilerp(&c, t),
            Err(v) => v,
        }
    }

    /// The first component at the 8 voxels `i + (dx, dy, dz)`, `dx, dy, dz ∈ {0, 1}`, as
    /// `c[(dx << 2) | (dy << 1) | dz]` (the corners of one trilinear cell), read with one
    /// brick resolution when they share a brick.
    #[inline]
    pub fn corners(&mut self, i: IVec3) -> [f32; 8] {
        match self.gather(i) {
            Ok(c) => c,
            Err(v) => [v; 8],
        }
    }

    /// The 8 corner values from voxel `i`, or `Err(value)` when one constant tile (or the
    /// background) lies under all of them.
    #[inline(always)]
    fn gather(&mut self, i: IVec3) -> Result<[f32; 8], f32> {
        let l = i & 7;
        let mut c = [0.0f32; 8];
        if let Some(p) = self.padded {
            let e = self.resolve(i >> BRICK_LOG2);
            if e & TILE_BIT == 0 {
                // All 8 corners in the brick's padded copy (the same values as below).
                if let Some(c) = padded_corners(p, e, l) {
                    return Ok(c);
                }
            }
        }
        if l.x < 7 && l.y < 7 && l.z < 7 {
            let e = self.resolve(i >> BRICK_LOG2);
            if e & TILE_BIT != 0 {
                return Err(self.fetch(e, 0, 0));
            }
            let base = e as usize * BRICK_VOXELS + voxel_offset(l);
            const OFF: [usize; 8] = [0, 1, 8, 9, 64, 65, 72, 73];
            if self.comps == 1 {
                match self.vals {
                    Vals::F32(s) => {
                        let s = &s[base..base + 74];
                        for k in 0..8 {
                            c[k] = s[OFF[k]];
                        }
                    }
                    Vals::F16(s) => {
                        let s = &s[base..base + 74];
                        for k in 0..8 {
                            c[k] = s[OFF[k]].to_f32();
                        }
                    }
                }
            } else {
                for k in 0..8 {
                    c[k] = self.fetch(e, voxel_offset(l) + OFF[k], 0);
                }
            }
        } else {
            // The 8 corners straddle 2 to 8 bricks: resolve the first through the cache and
            // each neighbour once, without evicting the first (the next lookup is most
            // likely in it).
            let k0 = i >> BRICK_LOG2;
            let e0 = self.resolve(k0);
            let i1 = i.wrapping_add(IVec3::ONE);
            let l1 = i1 & 7;
            let cx = usize::from(l.x == 7);
            let cy = usize::from(l.y == 7);
            let cz = usize::from(l.z == 7);
            // e[(dx & cx) << 2 | (dy & cy) << 1 | (dz & cz)]
            let mut e = [e0; 8];
            for (n, en) in e.iter_mut().enumerate().skip(1) {
                let (nx, ny, nz) = (n >> 2, (n >> 1) & 1, n & 1);
                if nx <= cx && ny <= cy && nz <= cz {
                    let d = IVec3::new(nx as i32, ny as i32, nz as i32);
                    *en = self.peek(k0 + d);
                }
            }
            if e0 & TILE_BIT != 0 && e.iter().all(|&x| x == e0) {
                // One constant tile (or the background) under all 8 corners.
                return Err(self.fetch(e0, 0, 0));
            }
            for (k, ck) in c.iter_mut().enumerate() {
                let (dx, dy, dz) = (k >> 2, (k >> 1) & 1, k & 1);
                let ent = e[((dx & cx) << 2) | ((dy & cy) << 1) | (dz & cz)];
                let off = ((if dx == 1 { l1.x } else { l.x }) << 6)
                    | ((if dy == 1 { l1.y } else { l.y }) << 3)
                    | (if dz == 1 { l1.z } else { l.z });
                *ck = self.fetch(ent, off as usize, 0);
            }
        }
        Ok(c)
    }

    /// Trilinear interpolation of a vector channel at index-space point `p`.
    pub fn sample_trilinear_vec3(&mut self, p: Vec3) -> Vec3 {
        let (i, t) = floor_frac(p);
        let c: [Vec3; 8] = std::array::from_fn(|k| {
            let d = IVec3::new((k >> 2) as i32, ((k >> 1) & 1) as i32, (k & 1) as i32);
            self.value_vec3(i.wrapping_add(d))
        });
        Vec3::new(
            trilerp(&c.map(|v| v.x), t),
            trilerp(&c.map(|v| v.y), t),
            trilerp(&c.map(|v| v.z), t),
        )
    }
}

/// The 8 trilinear corners of the cell whose first corner is local voxel `l` (each of x, y,
/// z in 0..8) of brick entry `e`, read from the brick's padded copy `pad`
/// ([`PADDED_EDGE`]³ values per brick, x slowest); `None` if the copy is too short.
#[inline]
fn padded_corners(pad: &[f32], e: u32, l: IVec3) -> Option<[f32; 8]> {
    const E: usize = PADDED_EDGE;
    const OFF: [usize; 8] = [0, 1, E, E + 1, E * E, E * E + 1, E * E + E, E * E + E + 1];
    let base = e as usize * PADDED_VOXELS + (l.x as usize * E + l.y as usize) * E + l.z as usize;
    let s = pad.get(base..base + OFF[7] + 1)?;
    Some(std::array::from_fn(|k| s[OFF[k]]))
}

/// Integer floor and fractional part of each coordinate, without a libm call (the x86-64
/// baseline has no rounding instruction): `p.floor().as_ivec3()` and `p - ⌊p⌋` for every `p`
/// within the `i32` range; saturating above it, NaN gives 0, and below −2³¹ the correction
/// step wraps (to `i32::MAX`). [`Accessor::sample_trilinear`]'s cell and weights.
///
/// The integers are those of `fabric::floor_ivec3` for every input (the level above computes
/// them three lanes at once in SSE2; this layer cannot import it). It is not the level set
/// DDA's floor, which saturates below −2³¹ too (its cell key is clamped next), nor the
/// texture lookups' `floor_exact`, a float floor exact at every magnitude.
#[inline(always)]
#[must_use]
pub fn floor_frac(p: Vec3) -> (IVec3, Vec3) {
    let t = p.as_ivec3(); // truncation toward zero, saturating
    let tf = t.as_vec3();
    let i = t.wrapping_sub(IVec3::new(
        i32::from(tf.x > p.x),
        i32::from(tf.y > p.y),
        i32::from(tf.z > p.z),
    ));
    (i, p - i.as_vec3())
}

/// Trilinear blend of corner values `c[(dx << 2) | (dy << 1) | dz]` with weights `t`
/// ([`Accessor::sample_trilinear`]'s order of operations).
#[inline]
#[must_use]
pub fn trilerp(c: &[f32; 8], t: Vec3) -> f32 {
    let lerp = |a: f32, b: f32, s: f32| a + (b - a) * s;
    let x00 = lerp(c[0], c[4], t.x);
    let x01 = lerp(c[1], c[5], t.x);
    let x10 = lerp(c[2], c[6], t.x);
    let x11 = lerp(c[3], c[7], t.x);
    let y0 = lerp(x00, x10, t.y);
    let y1 = lerp(x01, x11, t.y);
    lerp(y0, y1, t.z)
}

/// The voxels of a padded brick ([`PADDED_EDGE`]³, `z` fastest) as (which of the 8 bricks
/// `key + (0|1, 0|1, 0|1)` holds it, its index within that brick).
fn padded_voxels() -> impl Iterator<Item = (usize, usize)> {
    (0..PADDED_EDGE)
        .flat_map(|x| (0..PADDED_EDGE).flat_map(move |y| (0..PADDED_EDGE).map(move |z| (x, y, z))))
        .map(|(x, y, z)| {
            let n = ((x >> 3) << 2) | ((y >> 3) << 1) | (z >> 3);
            let v = ((x & 7) << 6) | ((y & 7) << 3) | (z & 7);
            (n, v)
        })
}

#[cfg(test)]
mod tests {
    use super::floor_frac;
    use crate::grid::{ChannelKind, SparseGridBuilder, Storage};
    use glam::{IVec3, Vec3};

    /// [`floor_frac`] is the plain floor bit for bit within the `i32` range (its integers the
    /// floor cast, its fractions `p - p.floor()`): signed zeros, values just around integers
    /// and halves, the 2²³ and 2³¹ boundaries, and random bit patterns of every exponent;
    /// and saturating above 2³¹, wrapping below −2³¹, NaN to 0 as documented.
    #[test]
    fn floor_frac_is_the_plain_floor() {
        let mut values = vec![
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_608.0,
            2_147_483_520.0,
            -2_147_483_520.0,
            -2_147_483_648.0,
        ];
        for k in -2000..2000 {
            let x = k as f32 * 0.25;
            values.extend([x, x.next_up(), x.next_down()]);
        }
        let mut bits = 0x9e37_79b9u32;
        for _ in 0..300_000 {
            bits ^= bits << 13;
            bits ^= bits >> 17;
            bits ^= bits << 5;
            let x = f32::from_bits(bits);
            if x.is_finite() && x.abs() < 2_147_483_648.0 {
                values.push(x);
            }
        }
        for &x in &values {
            let p = Vec3::new(x, -x, 0.25);
            let (i, f) = floor_frac(p);
            let want = p.floor();
            assert_eq!(i, want.as_ivec3(), "{p:?}");
            // Bit for bit but for the sign of a zero fraction (−0 − (−0) is +0).
            assert_eq!(f, p - want, "{p:?}");
            assert!(
                f.cmpge(Vec3::ZERO).all() && f.cmple(Vec3::ONE).all(),
                "{p:?}"
            );
        }
        let (i, _) = floor_frac(Vec3::new(3.0e9, -3.0e9, f32::NAN));
        assert_eq!(i, IVec3::new(i32::MAX, i32::MAX, 0));
        let (i, _) = floor_frac(Vec3::new(
            f32::INFINITY,
            f32::NEG_INFINITY,
            -2_147_483_904.0,
        ));
        assert_eq!(i, IVec3::new(i32::MAX, i32::MAX, i32::MAX));
    }

    /// A 16-bit scalar channel gets its padded copy too (the media's fast lookups), holding
    /// the f32 values the plain accessor converts its voxels to: the same lookups bit for bit.
    #[test]
    fn sixteen_bit_channels_are_padded_with_the_plain_values() {
        for storage in [Storage::F32, Storage::F16] {
            let mut b = SparseGridBuilder::new(storage);
            b.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
            for i in 0..400 {
                let p = IVec3::new(i % 11, (i / 11) % 9, i / 99);
                b.set_value(0, p, 0.1 + (i as f32) * 0.0173).expect("voxel");
            }
            let g = b.build();
            let mut padded = g.padded_accessor(0);
            assert!(padded.padded.is_some(), "{storage:?}");
            let mut plain = g.accessor(0);
            for k in 0..2000 {
                let f = k as f32;
                let p = Vec3::new(
                    (f * 0.37) % 12.0 - 0.5,
                    (f * 0.53) % 10.0 - 0.5,
                    (f * 0.71) % 6.0 - 0.5,
                );
                assert_eq!(
                    padded.sample_trilinear(p).to_bits(),
                    plain.sample_trilinear(p).to_bits(),
                    "{storage:?} {p}"
                );
            }
        }
    }
}
