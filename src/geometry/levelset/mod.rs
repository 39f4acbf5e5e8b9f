//! Level-set boundaries: the zero crossing of a signed-distance grid (OpenVDB's level sets:
//! negative inside, a narrow band of distances, ±background beyond it) as the boundary of an
//! object, intersected directly rather than meshed (docs/references.md §12.5).
//!
//! The surface is the zero set of the trilinear interpolant of the grid's values (voxel
//! centres at integer index coordinates). A ray is carried into index space (any invertible
//! affine map: a line stays a line and `t` stays the world distance) and walked by a
//! four-level DDA: cells of 64³ voxels, bricks of 8³ voxels, quarters of 4³ voxels (kept
//! only for bricks the surface may cross), then single trilinear cells. Each 64³ cell, brick
//! and quarter has the minimum and maximum of every voxel value any trilinear cell in it
//! interpolates (its voxels plus a one-voxel apron), so cells whose range excludes 0 are
//! skipped whole with no lookups: the bounds are conservative, no crossing is missed. In a trilinear cell the interpolant along the ray is a cubic in `t`; the cubic is
//! split at its extrema and the first sign change is refined (Marmitt et al. 2004), so two
//! crossings inside one cell (thin features, grazing rays) are found too.
//!
//! The geometric normal is the gradient of the trilinear interpolant at the hit (outward,
//! consistent with the crossing's direction); the shading normal interpolates central
//! differences at the cell's corners, which removes the trilinear gradient's jumps across
//! cell faces.

mod cell;
mod dda;

use glam::{DAffine3, IVec3};

use crate::grid::{ChannelKind, Node, SparseGrid, BRICK_DIM, BRICK_LOG2};
use crate::math::{Aabb, Mat3, Ray, Vec3};

use self::cell::{corner_signs, corner_values, first_root, smooth_gradient, trilinear_gradient};
use self::dda::DdaRay;

/// Bricks per edge of a coarse cell (8 bricks = 64 voxels).
const COARSE_LOG2: i32 = 3;
/// At most this many bricks in the level set's brick box (4 bytes × 2 each).
const MAX_TABLE_BRICKS: i64 = 1 << 26;

/// Why a grid cannot be a level-set boundary.
#[derive(Debug, thiserror::Error)]
pub enum LevelSetError {
    /// Not a scalar grid.
    #[error("a level set must be a scalar (float) grid, this one holds vectors")]
    NotScalar,
    /// The background is not positive (the outside must be positive).
    #[error("background {0} is not positive: a level set's background (outside) is +half-width × voxel size")]
    Background(f32),
    /// No voxel is negative: there is no inside.
    #[error("no value is negative (min {0}): a level set is negative inside; this looks like a fog volume or density grid")]
    NoInside(f32),
    /// The grid has no voxels (bricks) at all.
    #[error("the grid has no voxels (a level set needs a narrow band)")]
    Empty,
    /// NaN or infinite values.
    #[error("voxel {0} holds a non-finite value")]
    NonFinite(IVec3),
    /// Too large a box of bricks.
    #[error(
        "the grid spans {0} bricks, more than the {MAX_TABLE_BRICKS} a level-set boundary supports"
    )]
    TooLarge(i64),
    /// An unusable transform.
    #[error("{0}")]
    Transform(String),
}

/// Min and max of the values a trilinear lookup can blend in one cell of a level.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Range {
    min: f32,
    max: f32,
}

impl Range {
    const EMPTY: Range = Range {
        min: f32::INFINITY,
        max: f32::NEG_INFINITY,
    };
    /// Whether the zero crossing can lie in the cell.
    #[inline]
    fn straddles_zero(self) -> bool {
        self.min <= 0.0 && self.max >= 0.0
    }
    fn add(self, o: Range) -> Range {
        Range {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }
}

/// A dense box of per-cell ranges: key `k` in `[lo, lo + dims)`.
#[derive(Clone, Debug)]
struct RangeTable {
    lo: IVec3,
    dims: IVec3,
    ranges: Vec<Range>,
}

impl RangeTable {
    /// The flat index of key `k`, if inside the table.
    #[inline]
    fn index(&self, k: IVec3) -> Option<usize> {
        let r = k - self.lo;
        if r.cmplt(IVec3::ZERO).any() || r.cmpge(self.dims).any() {
            return None;
        }
        Some(
            ((r.x as usize * self.dims.y as usize) + r.y as usize) * self.dims.z as usize
                + r.z as usize,
        )
    }
    #[inline]
    fn get(&self, k: IVec3) -> Range {
        self.index(k)
            .and_then(|i| self.ranges.get(i).copied())
            .unwrap_or(Range::EMPTY)
    }
    fn hi(&self) -> IVec3 {
        self.lo + self.dims - IVec3::ONE
    }
}

/// A hit on a level set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelSetHit {
    /// Distance along the ray (> 0).
    pub t: f32,
    /// Hit point (world).
    pub p: Vec3,
    /// Unit outward geometric normal: the trilinear interpolant's gradient, with
    /// `dot(d, n) > 0` exactly when the ray leaves the inside.
    pub n: Vec3,
    /// Unit shading normal (interpolated central differences), in `n`'s hemisphere.
    pub ns: Vec3,
    /// Bound on the distance of `p` from the interpolant's zero set (world units).
    pub p_error: f32,
}

/// A level-set boundary: a scalar grid (negative inside) placed in the world, with its brick
/// and coarse-cell ranges for the ray walk. Build with [`LevelSet::new`].
#[derive(Clone, Debug)]
pub struct LevelSet {
    grid: SparseGrid,
    bricks: RangeTable,
    coarse: RangeTable,
    /// Per brick of `bricks` (same order): index into `subs`, or `u32::MAX` when the brick's
    /// range excludes zero.
    sub_of: Vec<u32>,
    /// Ranges of the eight 4³-cell quarters of each brick whose range straddles zero,
    /// `[(x << 2) | (y << 1) | z]`.
    subs: Vec<[Range; 8]>,
    /// World to index (f32, for rays).
    to_index_m: Mat3,
    to_index_t: Vec3,
    /// Transpose of the world-to-index linear part (index gradients to world normals).
    normal_m: Mat3,
    /// Largest world length of an index unit step (the voxel size).
    voxel: f32,
    bounds: Aabb,
}

impl LevelSet {
    /// A level set from channel 0 of `grid` (its index-to-world map places it). Checks: a
    /// scalar channel, at least one negative value, a positive background, finite values in
    /// every brick; computes the ranges of the walk (O(bricks)).
    ///
    /// # Errors
    /// [`LevelSetError`] naming the problem.
    pub fn new(grid: SparseGrid) -> Result<LevelSet, LevelSetError> {
        if grid.channel_kind(0) != Some(ChannelKind::Scalar) {
            return Err(LevelSetError::NotScalar);
        }
        if grid.brick_count() == 0 {
            return Err(LevelSetError::Empty);
        }
        let (mut vlo, mut vhi) = (IVec3::MAX, IVec3::MIN);
        for b in 0..grid.brick_count() {
            let o = grid.brick_origin(b);
            vlo = vlo.min(o);
            vhi = vhi.max(o + IVec3::splat(BRICK_DIM - 1));
        }
        // Cells whose lower corner is one voxel below the bricks still blend brick values.
        let klo = (vlo - IVec3::ONE) >> BRICK_LOG2;
        let khi = vhi >> BRICK_LOG2;
        let dims = khi - klo + IVec3::ONE;
        let count = i64::from(dims.x) * i64::from(dims.y) * i64::from(dims.z);
        if count > MAX_TABLE_BRICKS {
            return Err(LevelSetError::TooLarge(count));
        }
        let (bricks, sub_of, subs) = brick_ranges(&grid, klo, dims)?;
        let min = bricks
            .ranges
            .iter()
            .fold(f32::INFINITY, |m, r| m.min(r.min));
        if !(min < 0.0) {
            return Err(LevelSetError::NoInside(min));
        }
        let bg = grid.background(0);
        if !(bg > 0.0) || !bg.is_finite() {
            return Err(LevelSetError::Background(bg));
        }
        let coarse = coarse_ranges(&bricks);
        let mut ls = LevelSet {
            grid,
            bricks,
            coarse,
            sub_of,
            subs,
            to_index_m: Mat3::IDENTITY,
            to_index_t: Vec3::ZERO,
            normal_m: Mat3::IDENTITY,
            voxel: 1.0,
            bounds: Aabb::EMPTY,
        };
        ls.place(ls.grid.index_to_world())?;
        // The crossings' cells and gradients read 2³ corner blocks: through the padded bricks
        // (the same values), made now rather than by the first render thread.
        ls.grid.prepare_padded(0);
        Ok(ls)
    }

    /// Sets the index-to-world map to `m` and derives the ray and normal maps.
    fn place(&mut self, m: DAffine3) -> Result<(), LevelSetError> {
        self.grid
            .set_index_to_world(m)
            .map_err(|e| LevelSetError::Transform(e.to_string()))?;
        let inv = m.inverse();
        let l = inv.matrix3.as_mat3();
        self.to_index_m = l;
        self.to_index_t = inv.translation.as_vec3();
        self.normal_m = l.transpose();
        let a = m.matrix3;
        self.voxel = a
            .x_axis
            .length()
            .max(a.y_axis.length())
            .max(a.z_axis.length()) as f32;
        let lo = (self.bricks.lo << BRICK_LOG2).as_dvec3();
        let hi = ((self.bricks.hi() + IVec3::ONE) << BRICK_LOG2).as_dvec3();
        self.bounds = Aabb::around_transformed(lo, hi, &m);
        if !self.bounds.min.is_finite() || !self.bounds.max.is_finite() || !self.voxel.is_finite() {
            return Err(LevelSetError::Transform(
                "the placed level set is not finite".to_string(),
            ));
        }
        Ok(())
    }

    /// Applies the affine object-to-world transform `m` after the current placement.
    ///
    /// # Errors
    /// [`LevelSetError::Transform`] for a singular or non-finite result.
    pub fn transform(&mut self, m: glam::Mat4) -> Result<(), LevelSetError> {
        let d = DAffine3::from_mat4(m.as_dmat4());
        self.place(d * self.grid.index_to_world())
    }

    /// The grid (values in the file's units; index-to-world map includes the placement).
    #[must_use]
    pub fn grid(&self) -> &SparseGrid {
        &self.grid
    }

    /// World bounding box of every cell that can hold the zero crossing.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// World length of the largest index-space unit step (the voxel size of uniform grids).
    #[must_use]
    pub fn voxel_size(&self) -> f32 {
        self.voxel
    }

    /// The level-set value (trilinear) at world point `p`: negative inside.
    #[must_use]
    pub fn value_at(&self, p: Vec3) -> f32 {
        let pi = self.to_index_m * p + self.to_index_t;
        self.grid.padded_accessor(0).sample_trilinear(pi)
    }

    /// The nearest zero crossing with `0 < t < t_max` along `ray` (unit direction), from
    /// outside (entering) or inside (leaving). Allocation-free.
    #[must_use]
    pub fn intersect(&self, ray: &Ray, t_max: f32) -> Option<LevelSetHit> {
        let o = self.to_index_m * ray.o + self.to_index_t;
        let d = self.to_index_m * ray.d;
        if !o.is_finite() || !d.is_finite() || d == Vec3::ZERO {
            return None;
        }
        let iray = Ray { o, d };
        let lo = (self.bricks.lo << BRICK_LOG2).as_vec3();
        let hi = ((self.bricks.hi() + IVec3::ONE) << BRICK_LOG2).as_vec3();
        // The walk is not cut at t_max (cells past it are not visited): a crossing's refined
        // position does not depend on t_max, so closest-hit searches agree bit for bit.
        let (t0, t1) = Aabb { min: lo, max: hi }.intersect(&iray, 0.0, f32::INFINITY)?;
        if t0 >= t_max {
            return None;
        }
        let mut acc = self.grid.padded_accessor(0);
        // Whether the ray is inside where the last cell visited ended (skipped cells have
        // one sign throughout).
        let mut inside: Option<bool> = None;
        let side = |r: Range| Some(r.max < 0.0);
        let walks = DdaRay::new(o, d);
        let mut coarse = walks.walk(
            t0,
            t1,
            BRICK_LOG2 + COARSE_LOG2,
            self.coarse.lo,
            self.coarse.hi(),
        );
        while let Some((ck, ca, cb)) = coarse.next() {
            if ca >= t_max {
                return None;
            }
            let cr = self.coarse.get(ck);
            if !cr.straddles_zero() {
                inside = side(cr);
                continue;
            }
            let blo = (ck << COARSE_LOG2).max(self.bricks.lo);
            let bhi =
                ((ck << COARSE_LOG2) + IVec3::splat((1 << COARSE_LOG2) - 1)).min(self.bricks.hi());
            let mut bdda = walks.walk(ca, cb, BRICK_LOG2, blo, bhi);
            while let Some((bk, ba, bb)) = bdda.next() {
                if ba >= t_max {
                    return None;
                }
                let br = self.bricks.get(bk);
                if !br.straddles_zero() {
                    inside = side(br);
                    continue;
                }
                let quarters = self
                    .bricks
                    .index(bk)
                    .and_then(|i| self.sub_of.get(i))
                    .and_then(|&q| self.subs.get(q as usize));
                let Some(quarters) = quarters else {
                    // A constant brick of value 0: no crossing inside it.
                    inside = side(br);
                    continue;
                };
                let qlo = bk << 1;
                let mut qdda = walks.walk(ba, bb, 2, qlo, qlo + IVec3::ONE);
                while let Some((qk, qa, qb)) = qdda.next() {
                    if qa >= t_max {
                        return None;
                    }
                    let q = qk - qlo;
                    let qr = quarters
                        .get(((q.x << 2) | (q.y << 1) | q.z) as usize)
                        .copied()
                        .unwrap_or(Range::EMPTY);
                    if !qr.straddles_zero() {
                        inside = side(qr);
                        continue;
                    }
                    let vlo = qk << 2;
                    let mut vdda = walks.walk(qa, qb, 0, vlo, vlo + IVec3::splat(3));
                    while let Some((ijk, ta, tb)) = vdda.next() {
                        if ta >= t_max {
                            return None;
                        }
                        let c = corner_values(&mut acc, ijk);
                        // The corners' range straddles zero exactly when some corner is
                        // `<= 0` and some `>= 0`; else the cell is inside when none is `>= 0`.
                        let (any_le, any_ge) = corner_signs(&c);
                        if !(any_le && any_ge) {
                            inside = Some(!any_ge);
                            continue;
                        }
                        let local = o - ijk.as_vec3();
                        if let Some(t) = first_root(&c, local, d, ta, tb, &mut inside) {
                            if t > 0.0 && t < t_max {
                                let leaving = inside == Some(false);
                                return Some(
                                    self.make_hit(ray, &mut acc, o, d, ijk, &c, t, leaving),
                                );
                            }
                        }
                    }
                }
            }
        }
        None
    }

    /// Whether anything is hit with `0 < t < t_max` (shadow rays).
    #[must_use]
    pub fn occluded(&self, ray: &Ray, t_max: f32) -> bool {
        self.intersect(ray, t_max).is_some()
    }

    #[allow(clippy::too_many_arguments)]
    fn make_hit(
        &self,
        ray: &Ray,
        acc: &mut crate::grid::Accessor<'_>,
        o: Vec3,
        d: Vec3,
        ijk: IVec3,
        c: &[f32; 8],
        t: f32,
        leaving: bool,
    ) -> LevelSetHit {
        let local = (o + d * t - ijk.as_vec3()).clamp(Vec3::ZERO, Vec3::ONE);
        let g = self.normal_m * trilinear_gradient(c, local);
        let mut n = g.normalize_or(-ray.d);
        // The sign of dφ/dt at the crossing says entering (< 0) or leaving (> 0); the
        // gradient at the refined root agrees except for rays grazing the surface, where
        // it is nudged so that the integrator's entering/leaving test follows the crossing.
        let dn = n.dot(ray.d);
        let want = if leaving { 1e-3 } else { -1e-3 };
        if (leaving && dn < want) || (!leaving && dn > want) {
            n = (n + (want - dn) * ray.d).normalize_or(n);
        }
        let s = self.normal_m * smooth_gradient(acc, ijk, local);
        let s = s.normalize_or(n);
        let ns = if s.dot(n) < 0.0 { -s } else { s };
        let p = ray.at(t);
        // Root refined to ~1e-5 voxel; f32 index coordinates round at ε|p_index|; the world
        // point at γ(3)(|o| + |t d|).
        let index_err = 1e-3 + 4.0 * f32::EPSILON * (o.abs() + (d * t).abs()).max_element();
        let p_error = index_err * self.voxel
            + crate::math::gamma(4) * (ray.o.abs() + (ray.d * t).abs()).max_element();
        LevelSetHit {
            t,
            p,
            n,
            ns,
            p_error,
        }
    }
}

/// Brick ranges and quarter ranges.
type BrickTables = (RangeTable, Vec<u32>, Vec<[Range; 8]>);

/// Per-brick ranges over the brick box `[klo, klo + dims)`: the values at voxels
/// `[8k, 8k + 8]` (the brick and its apron on the + sides); for bricks straddling zero also the
/// ranges of their eight quarters (voxels `[8k + 4q, 8k + 4q + 4]`).
fn brick_ranges(grid: &SparseGrid, klo: IVec3, dims: IVec3) -> Result<BrickTables, LevelSetError> {
    let n = (dims.x as usize) * (dims.y as usize) * (dims.z as usize);
    let mut ranges = Vec::with_capacity(n);
    let mut sub_of = Vec::with_capacity(n);
    let mut subs = Vec::new();
    let mut acc = grid.accessor(0);
    for x in 0..dims.x {
        for y in 0..dims.y {
            for z in 0..dims.z {
                let k = klo + IVec3::new(x, y, z);
                let (r, quarters) = brick_range(grid, &mut acc, k)?;
                ranges.push(r);
                match quarters {
                    Some(q) if r.straddles_zero() => {
                        sub_of.push(subs.len() as u32);
                        subs.push(q);
                    }
                    _ => sub_of.push(u32::MAX),
                }
            }
        }
    }
    let table = RangeTable {
        lo: klo,
        dims,
        ranges,
    };
    Ok((table, sub_of, subs))
}

/// One brick's range and, unless it is constant, its quarters' ranges.
fn brick_range(
    grid: &SparseGrid,
    acc: &mut crate::grid::Accessor<'_>,
    k: IVec3,
) -> Result<(Range, Option<[Range; 8]>), LevelSetError> {
    // A brick cell under one constant tile whose + neighbours are the same tile: constant.
    if let Node::Tile { tile, .. } = grid.node_at_brick(k) {
        let v = grid.tile_value(0, tile);
        let same = (1..8).all(|n: i32| {
            let dk = IVec3::new(n >> 2, (n >> 1) & 1, n & 1);
            matches!(grid.node_at_brick(k + dk), Node::Tile { tile: t, .. } if grid.tile_value(0, t) == v)
        });
        if same {
            if !v.is_finite() {
                return Err(LevelSetError::NonFinite(k << BRICK_LOG2));
            }
            return Ok((Range { min: v, max: v }, None));
        }
    }
    let base = k << BRICK_LOG2;
    let mut r = Range::EMPTY;
    let mut quarters = [Range::EMPTY; 8];
    for x in 0..=BRICK_DIM {
        for y in 0..=BRICK_DIM {
            for z in 0..=BRICK_DIM {
                let ijk = base + IVec3::new(x, y, z);
                let v = acc.value(ijk);
                if !v.is_finite() {
                    return Err(LevelSetError::NonFinite(ijk));
                }
                let one = Range { min: v, max: v };
                r = r.add(one);
                // Voxel 4 of an axis is in both quarters' aprons.
                for (q, slot) in quarters.iter_mut().enumerate() {
                    let (qx, qy, qz) = ((q >> 2) as i32, ((q >> 1) & 1) as i32, (q & 1) as i32);
                    let within = |c: i32, h: i32| (4 * h..=4 * h + 4).contains(&c);
                    if within(x, qx) && within(y, qy) && within(z, qz) {
                        *slot = slot.add(one);
                    }
                }
            }
        }
    }
    Ok((r, Some(quarters)))
}

/// Ranges of 8³-brick cells, merged from the brick table.
fn coarse_ranges(bricks: &RangeTable) -> RangeTable {
    let lo = bricks.lo >> COARSE_LOG2;
    let hi = bricks.hi() >> COARSE_LOG2;
    let dims = hi - lo + IVec3::ONE;
    let mut ranges = vec![Range::EMPTY; (dims.x * dims.y * dims.z) as usize];
    for x in 0..bricks.dims.x {
        for y in 0..bricks.dims.y {
            for z in 0..bricks.dims.z {
                let k = bricks.lo + IVec3::new(x, y, z);
                let c = (k >> COARSE_LOG2) - lo;
                let i = ((c.x * dims.y + c.y) * dims.z + c.z) as usize;
                if let Some(slot) = ranges.get_mut(i) {
                    *slot = slot.add(bricks.get(k));
                }
            }
        }
    }
    RangeTable { lo, dims, ranges }
}
