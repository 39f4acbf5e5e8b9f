//! The majorant pyramid over a [`SparseGrid`], and the hierarchical DDA that turns a ray into
//! piecewise-constant [`MajorantSegment`]s for the tracking estimators (DESIGN.md; REFERENCES
//! §4.8).
//!
//! Level 0 has one cell per 8^3 brick of index space. Its bounds are the min and max over every
//! value a trilinear lookup anywhere inside the brick can return: the brick's voxels plus a
//! one-voxel apron across neighbouring bricks and constant tiles (trilinear interpolation is a
//! convex combination of the 8 surrounding voxels, so those bounds are exact and conservative).
//! Each coarser level merges 2^3 children (max of maxes, min of mins, mean of means) up to one
//! root cell. Bounds can also come from any other source (procedural media) through
//! [`MajorantPyramid::from_brick_bounds`]; those may be estimates, which the weighted trackers
//! tolerate.

use glam::{DAffine3, DVec3, IVec3, Vec3};

use crate::grid::{Node, SparseGrid, BRICK_DIM};
use crate::math::Ray;
use crate::tracking::MajorantSegment;

/// Refuses pyramids whose finest level would exceed this many cells.
pub const MAX_LEVEL0_CELLS: usize = 1 << 24;

/// Errors while building a pyramid.
#[derive(Debug, thiserror::Error)]
pub enum MajorantError {
    /// The grid spans too much index space for a dense level 0.
    #[error(
        "the grid spans {cells} bricks of index space; the majorant pyramid supports at most {max}"
    )]
    TooLarge {
        /// Level-0 cells needed.
        cells: usize,
        /// The limit.
        max: usize,
    },
    /// A bound is NaN, infinite or negative.
    #[error("invalid majorant bound at brick {brick:?}: min {min}, max {max}")]
    InvalidBound {
        /// Brick coordinate.
        brick: [i32; 3],
        /// Minimum.
        min: f32,
        /// Maximum.
        max: f32,
    },
}

/// Bounds of the values in a region.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    /// Smallest value.
    pub min: f32,
    /// Largest value.
    pub max: f32,
    /// Mean value (any value in `[min, max]` is acceptable as a control variate).
    pub mean: f32,
}

impl Bounds {
    /// The bounds of a constant value.
    #[must_use]
    pub fn constant(v: f32) -> Self {
        Bounds {
            min: v,
            max: v,
            mean: v,
        }
    }
    /// True when the value is known to be zero everywhere in the region.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.max <= 0.0 && self.min >= 0.0
    }
}

/// How segments are produced along a ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MajorantMode {
    /// Hierarchical DDA: skip empty space at the coarsest empty level, emit homogeneous cells
    /// whole, and descend towards level `finest` elsewhere (0 = brick level): everywhere with
    /// [`MajorantPyramid::segments`] (the exhaustive walk), only where it pays in optical
    /// depth with [`MajorantPyramid::segments_adaptive`] (the walk renders use; see there).
    Hierarchical {
        /// Finest level used.
        finest: u8,
    },
    /// One segment with the grid's global bounds over the whole ray interval (Mitsuba 3's
    /// approach; the baseline of the benchmarks).
    Global,
}

#[derive(Clone, Debug)]
struct Level {
    dims: IVec3,
    cells: Vec<Bounds>,
    /// Per cell, the volume average over its brick cells of their *lookup density*: the
    /// majorant of a brick that needs lookups, 0 for empty and homogeneous bricks. A walk that
    /// descends to the bricks makes delta tracking look up σ⁰·(this) per unit length, against
    /// σ⁰·max when it stops at the cell: the gain the adaptive descent weighs.
    fine: Vec<f32>,
}

/// The lookup density of a cell emitted whole: its majorant, or 0 when it needs no lookups.
fn lookup_density(b: &Bounds) -> f32 {
    if b.is_empty() || b.min == b.max {
        0.0
    } else {
        b.max
    }
}

impl Level {
    fn index(&self, c: IVec3) -> usize {
        ((c.z as usize * self.dims.y as usize) + c.y as usize) * self.dims.x as usize + c.x as usize
    }
}

/// A pyramid of (min, max, mean) bounds over brick-sized cells of a grid's index space.
#[derive(Clone, Debug)]
pub struct MajorantPyramid {
    /// Voxel coordinate of level-0 cell (0, 0, 0)'s first voxel.
    origin: IVec3,
    levels: Vec<Level>,
    /// Value outside the pyramid's box.
    background: f32,
    world_to_index: DAffine3,
}

/// Statistics of one pyramid level (for `velour majorants`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelReport {
    /// Level (0 = bricks).
    pub level: usize,
    /// Edge of a cell, voxels.
    pub cell_voxels: i32,
    /// Cells in the level's box.
    pub cells: usize,
    /// Cells whose bounds are not empty.
    pub occupied: usize,
    /// Occupied cells whose min equals max (sampled in closed form).
    pub homogeneous: usize,
}

impl MajorantPyramid {
    /// Builds the pyramid of channel `channel` of `grid` with exact bounds (brick + one-voxel
    /// apron).
    pub fn from_grid(grid: &SparseGrid, channel: usize) -> Result<Self, MajorantError> {
        let background = grid.background(channel);
        // Region: every brick and every non-background tile.
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
        let world_to_index = grid.world_to_index();
        if lo.x > hi.x {
            return Ok(Self::empty(background, world_to_index));
        }
        let key_lo = (lo - IVec3::ONE) >> 3;
        let key_hi = (hi + IVec3::ONE) >> 3;
        let mut acc = grid.accessor(channel);
        Self::from_brick_bounds(key_lo, key_hi, background, world_to_index, |key| {
            let mut nodes = [Node::Tile {
                tile: 0,
                level: crate::grid::TileLevel::Root,
                active: false,
            }; 27];
            let mut all_tiles = true;
            let mut i = 0;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let n = grid.node_at_brick(key + IVec3::new(dx, dy, dz));
                        all_tiles &= matches!(n, Node::Tile { .. });
                        nodes[i] = n;
                        i += 1;
                    }
                }
            }
            let own = nodes[13];
            if all_tiles {
                let mut b = Bounds {
                    min: f32::INFINITY,
                    max: f32::NEG_INFINITY,
                    mean: 0.0,
                };
                for n in nodes {
                    if let Node::Tile { tile, .. } = n {
                        let v = grid.tile_value(channel, tile);
                        b.min = b.min.min(v);
                        b.max = b.max.max(v);
                    }
                }
                if let Node::Tile { tile, .. } = own {
                    b.mean = grid.tile_value(channel, tile);
                }
                return b;
            }
            let base = key << 3;
            let mut b = Bounds {
                min: f32::INFINITY,
                max: f32::NEG_INFINITY,
                mean: 0.0,
            };
            for z in -1..=BRICK_DIM {
                for y in -1..=BRICK_DIM {
                    for x in -1..=BRICK_DIM {
                        let v = acc.value(base + IVec3::new(x, y, z));
                        b.min = b.min.min(v);
                        b.max = b.max.max(v);
                    }
                }
            }
            b.mean = match own {
                Node::Tile { tile, .. } => grid.tile_value(channel, tile),
                Node::Brick(_) => {
                    let mut s = 0.0f64;
                    for z in 0..BRICK_DIM {
                        for y in 0..BRICK_DIM {
                            for x in 0..BRICK_DIM {
                                s += acc.value(base + IVec3::new(x, y, z)) as f64;
                            }
                        }
                    }
                    (s / 512.0) as f32
                }
            };
            b
        })
    }

    /// An empty pyramid (the value is `background` everywhere).
    #[must_use]
    pub fn empty(background: f32, world_to_index: DAffine3) -> Self {
        MajorantPyramid {
            origin: IVec3::ZERO,
            levels: Vec::new(),
            background,
            world_to_index,
        }
    }

    /// Builds a pyramid from per-brick bounds for brick keys (voxel coordinate >> 3) in
    /// `[key_lo, key_hi]`. Outside that box the value is `background`.
    pub fn from_brick_bounds(
        key_lo: IVec3,
        key_hi: IVec3,
        background: f32,
        world_to_index: DAffine3,
        mut bounds_of: impl FnMut(IVec3) -> Bounds,
    ) -> Result<Self, MajorantError> {
        let dims = key_hi - key_lo + IVec3::ONE;
        let cells = dims.x as usize * dims.y as usize * dims.z as usize;
        if dims.min_element() <= 0 || cells > MAX_LEVEL0_CELLS {
            return Err(MajorantError::TooLarge {
                cells,
                max: MAX_LEVEL0_CELLS,
            });
        }
        let mut level0 = Level {
            dims,
            cells: vec![Bounds::constant(0.0); cells],
            fine: Vec::new(),
        };
        for z in 0..dims.z {
            for y in 0..dims.y {
                for x in 0..dims.x {
                    let c = IVec3::new(x, y, z);
                    let key = key_lo + c;
                    let b = bounds_of(key);
                    if !(b.min.is_finite() && b.max.is_finite() && b.mean.is_finite())
                        || b.min > b.max
                    {
                        return Err(MajorantError::InvalidBound {
                            brick: key.to_array(),
                            min: b.min,
                            max: b.max,
                        });
                    }
                    let i = level0.index(c);
                    level0.cells[i] = Bounds {
                        mean: b.mean.clamp(b.min, b.max),
                        ..b
                    };
                }
            }
        }
        level0.fine = level0.cells.iter().map(lookup_density).collect();
        let mut levels = vec![level0];
        while levels.last().is_some_and(|l| l.dims.max_element() > 1) {
            let Some(child) = levels.last() else { break };
            let pd = (child.dims + IVec3::ONE) / 2;
            let mut parent = Level {
                dims: pd,
                cells: vec![Bounds::constant(0.0); (pd.x * pd.y * pd.z) as usize],
                fine: vec![0.0; (pd.x * pd.y * pd.z) as usize],
            };
            for z in 0..pd.z {
                for y in 0..pd.y {
                    for x in 0..pd.x {
                        let mut b = Bounds {
                            min: f32::INFINITY,
                            max: f32::NEG_INFINITY,
                            mean: 0.0,
                        };
                        let mut n = 0.0f32;
                        let mut fine = 0.0f32;
                        for dz in 0..2 {
                            for dy in 0..2 {
                                for dx in 0..2 {
                                    let c = IVec3::new(2 * x + dx, 2 * y + dy, 2 * z + dz);
                                    // Cells beyond the child box hold the background.
                                    let inside = c.cmplt(child.dims).all();
                                    let cb = if inside {
                                        child.cells[child.index(c)]
                                    } else {
                                        Bounds::constant(background)
                                    };
                                    if inside {
                                        fine += child.fine[child.index(c)];
                                    }
                                    b.min = b.min.min(cb.min);
                                    b.max = b.max.max(cb.max);
                                    b.mean += cb.mean;
                                    n += 1.0;
                                }
                            }
                        }
                        b.mean = (b.mean / n).clamp(b.min, b.max);
                        let i = parent.index(IVec3::new(x, y, z));
                        parent.cells[i] = b;
                        parent.fine[i] = (fine / n).min(lookup_density(&b));
                    }
                }
            }
            levels.push(parent);
        }
        Ok(MajorantPyramid {
            origin: key_lo << 3,
            levels,
            background,
            world_to_index,
        })
    }

    /// Number of levels (0 when empty).
    #[must_use]
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// Bounds over the whole grid (including the background outside the pyramid's box).
    #[must_use]
    pub fn global_bounds(&self) -> Bounds {
        match self.levels.last() {
            Some(top) => {
                let b = top.cells[0];
                Bounds {
                    min: b.min.min(self.background),
                    max: b.max.max(self.background),
                    mean: b.mean,
                }
            }
            None => Bounds::constant(self.background),
        }
    }

    /// World-space box around every non-empty level-0 cell (including the one-voxel apron),
    /// or `None` when the grid is empty.
    #[must_use]
    pub fn world_bounds(&self) -> Option<crate::math::Aabb> {
        let l0 = self.levels.first()?;
        let mut lo = IVec3::MAX;
        let mut hi = IVec3::MIN;
        for z in 0..l0.dims.z {
            for y in 0..l0.dims.y {
                for x in 0..l0.dims.x {
                    let c = IVec3::new(x, y, z);
                    if !l0.cells[l0.index(c)].is_empty() {
                        lo = lo.min(c);
                        hi = hi.max(c);
                    }
                }
            }
        }
        if lo.x > hi.x {
            return None;
        }
        let index_to_world = self.world_to_index.inverse();
        let a = (self.origin + lo * BRICK_DIM).as_dvec3() - DVec3::splat(0.5);
        let b = (self.origin + (hi + IVec3::ONE) * BRICK_DIM).as_dvec3() - DVec3::splat(0.5);
        Some(crate::math::Aabb::around_transformed(a, b, &index_to_world))
    }

    /// Per-level cell counts.
    #[must_use]
    pub fn level_reports(&self) -> Vec<LevelReport> {
        self.levels
            .iter()
            .enumerate()
            .map(|(i, l)| LevelReport {
                level: i,
                cell_voxels: BRICK_DIM << i,
                cells: l.cells.len(),
                occupied: l.cells.iter().filter(|b| !b.is_empty()).count(),
                homogeneous: l
                    .cells
                    .iter()
                    .filter(|b| !b.is_empty() && b.min == b.max)
                    .count(),
            })
            .collect()
    }

    /// Bounds of the level-`level` cell containing voxel `ijk` (background outside).
    #[must_use]
    pub fn bounds_at_voxel(&self, level: usize, ijk: IVec3) -> Bounds {
        let Some(l) = self.levels.get(level) else {
            return Bounds::constant(self.background);
        };
        let c = (ijk - self.origin) >> (3 + level as i32);
        if c.cmplt(IVec3::ZERO).any() || c.cmpge(l.dims).any() {
            return Bounds::constant(self.background);
        }
        l.cells[l.index(c)]
    }

    /// The ray in index space: origin and direction (not unit) with the same parameter `t`.
    #[must_use]
    pub fn ray_to_index(&self, ray: &Ray) -> (DVec3, DVec3) {
        let o = self.world_to_index.transform_point3(ray.o.as_dvec3());
        let d = self.world_to_index.transform_vector3(ray.d.as_dvec3());
        (o, d)
    }

    /// Appends to `out` the segments covering `[t_min, t_max]` of `ray` (world space), with the
    /// exhaustive walk: [`MajorantMode::Hierarchical`] descends to its finest level wherever a
    /// cell is neither empty nor homogeneous, whatever the medium's extinction (what
    /// `velour majorants` reports per level). Segments of zero density are skipped; the others
    /// tile their part of the interval. Renders use [`MajorantPyramid::segments_adaptive`].
    pub fn segments(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        mode: MajorantMode,
        out: &mut Vec<MajorantSegment>,
    ) {
        self.segments_with(ray, t_min, t_max, mode, None, out);
    }

    /// Appends to `out` the segments covering `[t_min, t_max]` of `ray` for a medium whose
    /// extinction is at most `sigma_scale` per unit density (the largest channel of σ_t⁰).
    ///
    /// With [`MajorantMode::Hierarchical`] the walk weighs each descent in optical depth: a
    /// tentative collision (a density lookup) and a segment cost about the same, so a cell
    /// crossed over `Δt` is split only where the lookups it saves, σ·Δt·(max − the brick-level
    /// lookup density below it), exceed [`SEGMENT_COST`] per extra segment, and adjacent
    /// segments are merged where the merge costs fewer than [`SEGMENT_COST`] extra lookups.
    /// Optically thin cells (σ·max·Δt ≪ 1) are therefore emitted whole. Merged and undivided
    /// segments take the max of the maxima and the min of the minima they cover (0 across
    /// skipped empty cells), so the bounds stay conservative. A non-finite or non-positive
    /// `sigma_scale` gives the exhaustive walk of [`MajorantPyramid::segments`].
    pub fn segments_adaptive(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        mode: MajorantMode,
        sigma_scale: f32,
        out: &mut Vec<MajorantSegment>,
    ) {
        let sigma = (sigma_scale.is_finite() && sigma_scale > 0.0).then_some(sigma_scale as f64);
        self.segments_with(ray, t_min, t_max, mode, sigma, out);
    }

    fn segments_with(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        mode: MajorantMode,
        sigma: Option<f64>,
        out: &mut Vec<MajorantSegment>,
    ) {
        if !(t_max > t_min) {
            return;
        }
        match mode {
            MajorantMode::Global => {
                let b = self.global_bounds();
                if !b.is_empty() {
                    if t_max.is_finite() || self.background != 0.0 {
                        out.push(MajorantSegment {
                            t0: t_min,
                            t1: t_max,
                            min: b.min,
                            max: b.max,
                            mean: b.mean,
                        });
                    } else if let Some((a, c)) = self.clip(ray, t_min, t_max) {
                        out.push(MajorantSegment {
                            t0: a,
                            t1: c,
                            min: b.min,
                            max: b.max,
                            mean: b.mean,
                        });
                    }
                }
            }
            MajorantMode::Hierarchical { finest } => {
                let (o, d) = self.ray_to_index(ray);
                let Some((a, c)) = self.clip_index(o, d, t_min, t_max) else {
                    self.push_background(t_min, t_max, out);
                    return;
                };
                self.push_background(t_min, a, out);
                let top = self.levels.len() - 1;
                let finest = (finest as usize).min(top);
                self.walk(a as f64, c as f64, o, d, finest, sigma, out);
                self.push_background(c, t_max, out);
            }
        }
    }

    fn push_background(&self, t0: f32, t1: f32, out: &mut Vec<MajorantSegment>) {
        if self.background != 0.0 && t1 > t0 {
            out.push(MajorantSegment {
                t0,
                t1,
                min: self.background,
                max: self.background,
                mean: self.background,
            });
        }
    }

    /// Clips the ray to the pyramid's box in index space (voxel extents: voxel i covers
    /// [i − 0.5, i + 0.5)).
    fn clip(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let (o, d) = self.ray_to_index(ray);
        self.clip_index(o, d, t_min, t_max)
    }

    /// [`Self::clip`] for a ray already in index space.
    fn clip_index(&self, o: DVec3, d: DVec3, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let l0 = self.levels.first()?;
        let lo = self.origin.as_dvec3() - DVec3::splat(0.5);
        let hi = lo + (l0.dims * BRICK_DIM).as_dvec3();
        let mut t0 = t_min as f64;
        let mut t1 = t_max as f64;
        for k in 0..3 {
            if d[k] == 0.0 {
                if o[k] < lo[k] || o[k] >= hi[k] {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / d[k];
            let (mut a, mut b) = ((lo[k] - o[k]) * inv, (hi[k] - o[k]) * inv);
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            t0 = t0.max(a);
            t1 = t1.min(b);
        }
        (t0 < t1).then_some((t0 as f32, t1 as f32))
    }

    /// Hierarchical DDA over `t ∈ [t0, t1]` (inside the pyramid's box), iterative: a stack of
    /// one DDA state per level, each child state derived from its parent's exit distances and
    /// the parent cell's mid-planes (no per-level re-location of the ray).
    #[allow(clippy::too_many_arguments)]
    fn walk(
        &self,
        t0: f64,
        t1: f64,
        o: DVec3,
        d: DVec3,
        finest: usize,
        sigma: Option<f64>,
        out: &mut Vec<MajorantSegment>,
    ) {
        let top = self.levels.len() - 1;
        // Descending to the bricks saves σ·Δt·(max − fine) lookups and costs one more segment
        // per brick boundary crossed, Δt·|d|₁/8: both scale with Δt, so the test is
        // `max − fine > threshold` with one threshold per ray.
        let threshold = match sigma {
            None => f32::NEG_INFINITY,
            Some(s) => (SEGMENT_COST * d.abs().element_sum() / (BRICK_DIM as f64 * s)) as f32,
        };
        // The root is one cell over the whole box: emitted whole, no DDA is needed.
        let root = &self.levels[top];
        let (rb, rf) = (root.cells[0], root.fine[0]);
        if rb.is_empty() {
            return;
        }
        if top <= finest || rb.min == rb.max || !(rb.max - rf > threshold) {
            out.push(MajorantSegment {
                t0: t0 as f32,
                t1: t1 as f32,
                min: rb.min,
                max: rb.max,
                mean: rb.mean,
            });
            return;
        }
        let base = self.origin.as_dvec3() - DVec3::splat(0.5);
        let mut step = IVec3::ZERO;
        let mut inv_d = DVec3::ZERO;
        for k in 0..3 {
            if d[k] > 0.0 {
                step[k] = 1;
                inv_d[k] = 1.0 / d[k];
            } else if d[k] < 0.0 {
                step[k] = -1;
                inv_d[k] = 1.0 / d[k];
            }
        }
        // |Δt| across one level-0 cell per axis (∞ along axes the ray does not move on).
        let delta0 = DVec3::new(
            if step.x != 0 {
                (BRICK_DIM as f64 * inv_d.x).abs()
            } else {
                f64::INFINITY
            },
            if step.y != 0 {
                (BRICK_DIM as f64 * inv_d.y).abs()
            } else {
                f64::INFINITY
            },
            if step.z != 0 {
                (BRICK_DIM as f64 * inv_d.z).abs()
            } else {
                f64::INFINITY
            },
        );
        // The root state.
        let size = (BRICK_DIM << top) as f64;
        let p = o + d * (t0 + (t1 - t0) * 1e-6);
        let cell = ((p - base) / size)
            .floor()
            .as_ivec3()
            .clamp(IVec3::ZERO, root.dims - IVec3::ONE);
        let mut t_next = DVec3::splat(f64::INFINITY);
        for k in 0..3 {
            if step[k] > 0 {
                t_next[k] = (base[k] + (cell[k] + 1) as f64 * size - o[k]) * inv_d[k];
            } else if step[k] < 0 {
                t_next[k] = (base[k] + cell[k] as f64 * size - o[k]) * inv_d[k];
            }
        }
        let mut stack = [Frame::default(); MAX_LEVELS];
        stack[0] = Frame {
            level: top as u32,
            cell,
            lo: IVec3::ZERO,
            hi: root.dims,
            t_next,
            t_end: t1,
            done: false,
        };
        let mut depth = 1usize;
        let mut emit = Emitter {
            sigma,
            start: out.len(),
            last_lookup: 0.0,
        };
        let mut t = t0;
        while depth > 0 {
            let f = &mut stack[depth - 1];
            if f.done || t >= f.t_end {
                t = t.max(f.t_end.min(t1));
                depth -= 1;
                continue;
            }
            let level = f.level as usize;
            let cell = f.cell;
            let exits = f.t_next;
            let axis = if exits.x <= exits.y && exits.x <= exits.z {
                0
            } else if exits.y <= exits.z {
                1
            } else {
                2
            };
            let t_exit = exits[axis].min(f.t_end).max(t);
            f.cell[axis] += step[axis];
            f.t_next[axis] += delta0[axis] * (1u64 << level) as f64;
            if f.cell[axis] < f.lo[axis] || f.cell[axis] >= f.hi[axis] || t_exit >= f.t_end {
                f.done = true;
            }
            if !(t_exit > t) {
                continue;
            }
            let lv = &self.levels[level];
            let i = lv.index(cell);
            let b = lv.cells[i];
            if b.is_empty() {
                t = t_exit;
                continue;
            }
            if level > finest && b.min != b.max && b.max - lv.fine[i] > threshold {
                // The child state: per axis, the half of the cell the ray enters and the
                // distance to its exit (the mid-plane, or the parent's own exit plane).
                let child = &self.levels[level - 1];
                let half = (BRICK_DIM << (level - 1)) as f64;
                let mut c = cell * 2;
                let mut c_next = exits;
                for k in 0..3 {
                    let mid = base[k] + (2 * cell[k] + 1) as f64 * half;
                    if step[k] == 0 {
                        if o[k] >= mid {
                            c[k] += 1;
                        }
                        continue;
                    }
                    let tm = (mid - o[k]) * inv_d[k];
                    let upper = if step[k] > 0 { tm <= t } else { tm > t };
                    if upper {
                        c[k] += 1;
                    }
                    if tm > t {
                        c_next[k] = tm;
                    }
                }
                let lo = cell * 2;
                let hi = (lo + IVec3::splat(2)).min(child.dims);
                if c.cmpge(lo).all() && c.cmplt(hi).all() && depth < MAX_LEVELS {
                    stack[depth] = Frame {
                        level: (level - 1) as u32,
                        cell: c,
                        lo,
                        hi,
                        t_next: c_next,
                        t_end: t_exit,
                        done: false,
                    };
                    depth += 1;
                    continue;
                }
            }
            emit.push(out, t, t_exit, b, lookup_density(&b));
            t = t_exit;
            // Leave finished levels at once (saves a loop turn per level).
            while depth > 0 && stack[depth - 1].done {
                t = t.max(stack[depth - 1].t_end.min(t1));
                depth -= 1;
            }
        }
    }
}

/// The cost of one more segment, in density lookups (a segment costs a DDA step, an
/// exponential sample and the tracker's per-segment set-up, about what one tentative collision
/// costs; measured with callgrind on the grid scenes, docs/BENCHMARKS.md).
pub const SEGMENT_COST: f64 = 1.0;

/// Levels below the root the iterative walk descends at most. A cubic grid within
/// [`MAX_LEVEL0_CELLS`] has at most 9 levels; only grids more than 2^15 bricks long on one axis
/// have more, and their deepest levels are then emitted whole (coarser, still conservative).
const MAX_LEVELS: usize = 16;

/// One level's DDA state in [`MajorantPyramid::walk`].
#[derive(Clone, Copy, Debug, Default)]
struct Frame {
    level: u32,
    done: bool,
    cell: IVec3,
    /// Cells `[lo, hi)` of this level inside the parent cell.
    lo: IVec3,
    hi: IVec3,
    /// Distance at which the ray leaves the current cell across each axis.
    t_next: DVec3,
    /// Where the parent cell ends.
    t_end: f64,
}

/// Appends walk output to the segment list, merging adjacent segments with equal bounds, and,
/// in the adaptive walk, segments whose merge costs fewer than [`SEGMENT_COST`] lookups.
struct Emitter {
    sigma: Option<f64>,
    /// First segment of this walk (earlier ones are never merged into).
    start: usize,
    /// Lookup density of the last segment.
    last_lookup: f32,
}

impl Emitter {
    fn push(&mut self, out: &mut Vec<MajorantSegment>, t0: f64, t1: f64, b: Bounds, lookup: f32) {
        let seg = MajorantSegment {
            t0: t0 as f32,
            t1: t1 as f32,
            min: b.min,
            max: b.max,
            mean: b.mean,
        };
        if out.len() > self.start {
            if let Some(last) = out.last_mut() {
                if last.t1 == seg.t0
                    && last.min == seg.min
                    && last.max == seg.max
                    && last.mean == seg.mean
                {
                    last.t1 = seg.t1;
                    return;
                }
                if let Some(s) = self.sigma {
                    // Lookups added by one segment over both (and the empty gap between):
                    // σ·(L·max − the lookup integrals of the two as they are).
                    let max = last.max.max(seg.max);
                    let (la, gap, lb) = (
                        f64::from(last.length()),
                        f64::from((seg.t0 - last.t1).max(0.0)),
                        f64::from(seg.length()),
                    );
                    let extra = s
                        * ((la + gap + lb) * f64::from(max)
                            - la * f64::from(self.last_lookup)
                            - lb * f64::from(lookup));
                    if extra < SEGMENT_COST {
                        let total = la + gap + lb;
                        let mut min = last.min.min(seg.min);
                        if gap > 0.0 {
                            min = min.min(0.0);
                        }
                        let mean = if total > 0.0 {
                            ((la * f64::from(last.mean) + lb * f64::from(seg.mean)) / total) as f32
                        } else {
                            last.mean
                        };
                        *last = MajorantSegment {
                            t0: last.t0,
                            t1: seg.t1,
                            min,
                            max,
                            mean: mean.clamp(min, max),
                        };
                        self.last_lookup = if min == max { 0.0 } else { max };
                        return;
                    }
                }
            }
        }
        self.last_lookup = lookup;
        out.push(seg);
    }
}

/// A density lookup along a ray in a grid's index space (trilinear, coherent accessor).
pub struct RayDensity<'a> {
    accessor: crate::grid::Accessor<'a>,
    o: Vec3,
    d: Vec3,
}

impl<'a> RayDensity<'a> {
    /// Prepares lookups along `ray` (world space) in channel `channel` of `grid`.
    #[must_use]
    pub fn new(grid: &'a SparseGrid, channel: usize, ray: &Ray) -> Self {
        let w2i = grid.world_to_index();
        let o = w2i.transform_point3(ray.o.as_dvec3()).as_vec3();
        let d = w2i.transform_vector3(ray.d.as_dvec3()).as_vec3();
        RayDensity {
            accessor: grid.accessor(channel),
            o,
            d,
        }
    }
    /// Trilinear density at distance `t`.
    pub fn at(&mut self, t: f32) -> f32 {
        self.accessor.sample_trilinear(self.o + self.d * t)
    }
}
