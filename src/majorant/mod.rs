//! The majorant pyramid over a [`SparseGrid`], and the hierarchical DDA that turns a ray into
//! piecewise-constant [`MajorantSegment`]s for the tracking estimators (docs/architecture.md,
//! "The majorant pyramid"; docs/references.md §4.8).
//!
//! Level 0 has one cell per 8^3 brick of index space. Its bounds are the min and max over every
//! value a trilinear lookup anywhere inside the brick can return: the brick's voxels plus a
//! one-voxel apron across neighbouring bricks and constant tiles (trilinear interpolation is a
//! convex combination of the 8 surrounding voxels, so those bounds are exact and conservative).
//! Each coarser level merges 2^3 children (max of maxes, min of mins, mean of means) up to one
//! root cell. Bounds can also come from any other source (procedural media) through
//! [`MajorantPyramid::from_brick_bounds`] (proven bounds) or
//! [`MajorantPyramid::from_estimated_brick_bounds`] (estimates, which the weighted trackers
//! tolerate as long as every segment they bound is looked up: see
//! [`MajorantSegment::is_homogeneous`]).

mod cells;
mod fine;
mod plan;
mod segments;
#[cfg(test)]
mod test_grids;
mod walk;

pub use fine::{LocalBounds, MAX_LOCAL_CELLS};
pub use segments::{FewSegments, MajorantSegment, OpenWalk, Segments, SegmentsStart};

use glam::{DAffine3, DVec3, IVec3};
use rayon::prelude::*;

use crate::grid::{SparseGrid, BRICK_DIM};
use crate::math::Ray;

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

/// What a segment costs its tracker in density lookups per unit length and unit extinction:
/// the model the adaptive walk optimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LookupModel {
    /// Tentative collisions at the majorant's rate each need a lookup (delta and ratio
    /// tracking): a segment costs its majorant.
    Majorant,
    /// Only collisions above the segment's minorant need a lookup (decomposition tracking,
    /// residual ratio tracking with the minorant as control): a segment costs max − min.
    AboveMinorant,
    /// Tentative collisions at the segment's majorant are first tested against the local
    /// bounds of the point ([`LocalBounds`]; `tracking::delta_track_local`): each costs
    /// [`PROBE_COST`] lookups, and the lookups that remain depend only on the local bounds, not
    /// on the segment. A segment costs `PROBE_COST ·` its majorant.
    Probed,
    /// Ratio and residual ratio tracking of shadow rays: lookups at the majorant's rate, as
    /// [`LookupModel::Majorant`], but a segment costs [`RATIO_SEGMENT_COST`] times
    /// [`SEGMENT_COST`] (its walk cells, its control density and the exponentials of its
    /// analytic part), so the walk opens fewer cells.
    Ratio,
}

impl LookupModel {
    /// A distinct index per model.
    #[must_use]
    pub fn index(self) -> usize {
        match self {
            LookupModel::Majorant => 0,
            LookupModel::AboveMinorant => 1,
            LookupModel::Probed => 2,
            LookupModel::Ratio => 3,
        }
    }

    /// Where the adaptive walk finds this model's opening prices (an index into a cell's
    /// stored prices, [`plan::PRICED_MODELS`]) and by what factor they are scaled: a cell is
    /// opened when the ray's segment price is below `factor ·` the stored price.
    pub(crate) fn price_slot(self) -> (usize, f64) {
        match self {
            LookupModel::Majorant => (0, 1.0),
            LookupModel::AboveMinorant => (1, 1.0),
            // Every lookup density is PROBE_COST times the majorant's, so every cost function
            // is f_probed(λ) = PROBE_COST · f_majorant(λ / PROBE_COST).
            LookupModel::Probed => (0, PROBE_COST),
            // The Majorant model's costs with segments RATIO_SEGMENT_COST times dearer: a cell
            // opens where RATIO_SEGMENT_COST times the ray's segment price is below its price.
            LookupModel::Ratio => (0, 1.0 / RATIO_SEGMENT_COST),
        }
    }
}

/// The cost of a tentative collision decided by the local bounds (two uniform numbers, a
/// logarithm, a table read and a comparison), in density lookups. Tuned by instruction counts
/// (docs/BENCHMARKS.md, "Local bounds"): on the dense peer cloud smaller is better (0: 99 M
/// instructions per spp, 0.2: 114 M, 0.3: 126 M; without local bounds 148 M), on the sparse
/// puffs (512³, 20 puffs in empty space) the walk must still skip the empty space (0.1: 70 M,
/// 0.2: 63 M, 0.3: 62 M; without 61 M).
pub const PROBE_COST: f64 = 0.2;

/// What a segment of a shadow ray's ratio tracking costs ([`LookupModel::Ratio`]), in units
/// of [`SEGMENT_COST`]: besides the walk, each segment sets up its control density and the
/// exponentials of its analytic part, and the walk's cells merged back into one segment are
/// paid too. Tuned by instruction counts on the dense peer cloud (docs/BENCHMARKS.md, "Padded
/// bricks and dearer shadow-ray segments"): 1: 1.626 G instructions, 3: 1.541 G, 4: 1.501 G,
/// 6 to 12: 1.499 G, at the same variance.
pub const RATIO_SEGMENT_COST: f64 = 4.0;

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
    /// Per cell and priced lookup model ([`plan::PRICED_MODELS`]), the segment price below
    /// which the adaptive walk opens the cell (see [`plan`]; 0: never, and at level 0).
    open_below: Vec<[f32; 2]>,
    /// Per priced lookup model, the least of `open_below` over the level's non-empty cells
    /// (∞ when every cell is empty): a ray whose price is below it opens every non-empty cell
    /// of the level ([`walk::Descent`]).
    open_floor: [f32; 2],
    /// True when no non-empty cell of the level has constant bounds: the exhaustive walk opens
    /// every non-empty cell of the level.
    all_vary: bool,
}

impl Level {
    /// A level of `dims` cells with `cells` bounds and no opening prices yet.
    fn new(dims: IVec3, cells: Vec<Bounds>) -> Self {
        Level {
            dims,
            cells,
            open_below: Vec::new(),
            open_floor: [f32::INFINITY; 2],
            all_vary: false,
        }
    }

    /// Sets the level's opening prices and the per-level summaries drawn from them.
    fn set_open_below(&mut self, open_below: Vec<[f32; 2]>) {
        let mut floor = [f32::INFINITY; 2];
        for (b, p) in self.cells.iter().zip(&open_below) {
            if b.is_empty() {
                continue;
            }
            for (f, &q) in floor.iter_mut().zip(p) {
                // NaN prices never open a cell: they make the floor NaN (no ray is below it).
                *f = if f.is_nan() || q.is_nan() {
                    f32::NAN
                } else {
                    f.min(q)
                };
            }
        }
        let whole = open_below.len() == self.cells.len();
        self.open_floor = if whole { floor } else { [f32::NAN; 2] };
        self.all_vary = self.cells.iter().all(|b| b.is_empty() || b.min != b.max);
        self.open_below = open_below;
    }

    fn index(&self, c: IVec3) -> usize {
        ((c.z as usize * self.dims.y as usize) + c.y as usize) * self.dims.x as usize + c.x as usize
    }
}

/// A pyramid of (min, max, mean) bounds over brick-sized cells of a grid's index space.
#[derive(Clone, Debug)]
pub struct MajorantPyramid {
    /// Voxel coordinate of level-0 cell (0, 0, 0)'s first voxel.
    origin: IVec3,
    /// Level-0 cells are `2^cell_log2` voxels wide (3: one brick).
    cell_log2: i32,
    levels: Vec<Level>,
    /// Value outside the pyramid's box.
    background: f32,
    world_to_index: DAffine3,
    /// True when every bound is proven (see [`MajorantSegment::exact`]).
    exact: bool,
    /// Per-point bounds over the grid's dual lattice, when attached
    /// ([`Self::with_local_bounds`]).
    local: Option<LocalBounds>,
    /// Per priced lookup model ([`plan::PRICED_MODELS`]), the root's cost as a function of
    /// the segment price: whether opening the root pays for preparing the walk.
    root_cost: [plan::RootCost; 2],
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
    /// Occupied cells whose min equals max in a pyramid of proven bounds (sampled in closed
    /// form; always 0 for estimated bounds).
    pub homogeneous: usize,
}

impl MajorantPyramid {
    /// Builds the pyramid of channel `channel` of `grid` with exact bounds (each cell plus a
    /// one-voxel apron). The finest cells are smaller than a brick where memory allows
    /// ([`finest_cell_log2`]): 2³ voxels for up to 2^16 bricks, 4³ up to 2^21, else the bricks.
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
        let key_lo: IVec3 = (lo - IVec3::ONE) >> 3;
        let key_hi: IVec3 = (hi + IVec3::ONE) >> 3;
        let span: IVec3 = key_hi - key_lo + IVec3::ONE;
        let bricks = span.as_dvec3();
        let cell_log2 = finest_cell_log2(bricks.x * bricks.y * bricks.z);
        let per_brick = BRICK_DIM >> cell_log2;
        let dims = (key_hi - key_lo + IVec3::ONE) * per_brick;
        let count = dims.x as usize * dims.y as usize * dims.z as usize;
        if dims.min_element() <= 0 || count > MAX_LEVEL0_CELLS {
            return Err(MajorantError::TooLarge {
                cells: count,
                max: MAX_LEVEL0_CELLS,
            });
        }
        let mut cells = vec![Bounds::constant(background); count];
        let index = |c: IVec3| {
            ((c.z as usize * dims.y as usize) + c.y as usize) * dims.x as usize + c.x as usize
        };
        // One layer of brick keys (`per_brick` planes of cells, contiguous in `cells`) per
        // task: each key writes only its own cells, so the bounds do not depend on the order.
        let layer = per_brick as usize * dims.y as usize * dims.x as usize;
        cells
            .par_chunks_mut(layer)
            .enumerate()
            .for_each(|(z, slab)| {
                let kz = key_lo.z + z as i32;
                for ky in key_lo.y..=key_hi.y {
                    for kx in key_lo.x..=key_hi.x {
                        let key = IVec3::new(kx, ky, kz);
                        let first = (key - key_lo) * per_brick;
                        let first = IVec3::new(first.x, first.y, 0);
                        cells::brick_cell_bounds(grid, channel, key, cell_log2, |sub, b| {
                            slab[index(first + sub)] = b;
                        });
                    }
                }
            });
        let cell_lo = key_lo * per_brick;
        let cell_hi = (key_hi + IVec3::ONE) * per_brick - IVec3::ONE;
        Self::build(
            cell_lo,
            cell_hi,
            cell_log2,
            background,
            world_to_index,
            true,
            |key| cells[index(key - cell_lo)],
        )
    }

    /// An empty pyramid (the value is `background` everywhere).
    #[must_use]
    pub fn empty(background: f32, world_to_index: DAffine3) -> Self {
        MajorantPyramid {
            origin: IVec3::ZERO,
            cell_log2: 3,
            levels: Vec::new(),
            background,
            world_to_index,
            exact: true,
            local: None,
            root_cost: Default::default(),
        }
    }

    /// Builds a pyramid from proven per-brick bounds (every value a lookup inside the brick
    /// can return lies within them) for brick keys (voxel coordinate >> 3) in
    /// `[key_lo, key_hi]`. Outside that box the value is `background`.
    pub fn from_brick_bounds(
        key_lo: IVec3,
        key_hi: IVec3,
        background: f32,
        world_to_index: DAffine3,
        bounds_of: impl FnMut(IVec3) -> Bounds,
    ) -> Result<Self, MajorantError> {
        Self::build(
            key_lo,
            key_hi,
            3,
            background,
            world_to_index,
            true,
            bounds_of,
        )
    }

    /// [`Self::from_brick_bounds`] for bounds that may be violated (estimated from trial
    /// samples, or given by the artist). Their segments are never taken as homogeneous: a
    /// brick whose estimated min equals its max is still looked up.
    pub fn from_estimated_brick_bounds(
        key_lo: IVec3,
        key_hi: IVec3,
        background: f32,
        world_to_index: DAffine3,
        bounds_of: impl FnMut(IVec3) -> Bounds,
    ) -> Result<Self, MajorantError> {
        Self::build(
            key_lo,
            key_hi,
            3,
            background,
            world_to_index,
            false,
            bounds_of,
        )
    }

    /// The segment price of a ray whose index-space direction per unit of world distance is
    /// `d`, in a medium of extinction `sigma` per unit density: [`SEGMENT_COST`] lookups per
    /// level-0 cell boundary crossed, `|d|₁ / w` per unit length, over σ (density units; see
    /// [`plan`]).
    pub(crate) fn segment_price(&self, d: DVec3, sigma: f64) -> f64 {
        SEGMENT_COST * d.abs().element_sum() / (f64::from(self.finest_cell_voxels()) * sigma)
    }

    /// True when every bound of the pyramid is proven.
    #[must_use]
    pub fn is_exact(&self) -> bool {
        self.exact
    }

    /// The lookup density of a cell emitted whole under `model`: its majorant (or its
    /// majorant above the minorant), 0 when it needs no lookups (empty, or proven constant).
    pub(crate) fn lookup_density(&self, b: &Bounds, model: LookupModel) -> f32 {
        Self::lookup_density_of(b.min, b.max, self.exact, model)
    }

    /// [`Self::lookup_density`] of bounds `[min, max]`, proven or not.
    pub(crate) fn lookup_density_of(min: f32, max: f32, exact: bool, model: LookupModel) -> f32 {
        let empty = max <= 0.0 && min >= 0.0;
        if empty || (exact && min == max) {
            0.0
        } else {
            match model {
                LookupModel::Majorant | LookupModel::Ratio => max,
                LookupModel::AboveMinorant => (max - min).max(0.0),
                LookupModel::Probed => (f64::from(max) * PROBE_COST) as f32,
            }
        }
    }

    /// Builds the pyramid over level-0 cells of `2^cell_log2` voxels with keys (voxel
    /// coordinate >> `cell_log2`) in `[key_lo, key_hi]`.
    #[allow(clippy::too_many_arguments)]
    fn build(
        key_lo: IVec3,
        key_hi: IVec3,
        cell_log2: i32,
        background: f32,
        world_to_index: DAffine3,
        exact: bool,
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
        let mut level0 = Level::new(dims, vec![Bounds::constant(0.0); cells]);
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
        let mut levels = vec![level0];
        while levels.last().is_some_and(|l| l.dims.max_element() > 1) {
            let Some(child) = levels.last() else { break };
            let pd = (child.dims + IVec3::ONE) / 2;
            let mut parent = Level::new(
                pd,
                vec![Bounds::constant(0.0); (pd.x * pd.y * pd.z) as usize],
            );
            for z in 0..pd.z {
                for y in 0..pd.y {
                    for x in 0..pd.x {
                        let mut b = Bounds {
                            min: f32::INFINITY,
                            max: f32::NEG_INFINITY,
                            mean: 0.0,
                        };
                        let mut n = 0.0f32;
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
                    }
                }
            }
            levels.push(parent);
        }
        let mut pyramid = MajorantPyramid {
            origin: key_lo << cell_log2,
            cell_log2,
            levels,
            background,
            world_to_index,
            exact,
            local: None,
            root_cost: Default::default(),
        };
        // The two models' prices are independent: one per worker.
        let [m0, m1] = plan::PRICED_MODELS;
        let ((p0, r0), (p1, r1)) = rayon::join(
            || plan::open_prices(&pyramid, m0),
            || plan::open_prices(&pyramid, m1),
        );
        for (l, level) in pyramid.levels.iter_mut().enumerate() {
            level.set_open_below(
                (0..level.cells.len())
                    .map(|i| [p0[l][i], p1[l][i]])
                    .collect(),
            );
        }
        pyramid.root_cost = [r0, r1];
        Ok(pyramid)
    }

    /// Attaches the local bounds of channel `channel` of `grid` (the grid this pyramid was
    /// built from; [`LocalBounds::from_grid`]).
    pub fn with_local_bounds(
        mut self,
        grid: &SparseGrid,
        channel: usize,
    ) -> Result<Self, MajorantError> {
        self.local = Some(LocalBounds::from_grid(grid, channel)?);
        Ok(self)
    }

    /// The attached local bounds, if any.
    #[must_use]
    pub fn local_bounds(&self) -> Option<&LocalBounds> {
        self.local.as_ref()
    }

    /// Edge of a level-0 cell in voxels (8 = one brick).
    #[must_use]
    pub fn finest_cell_voxels(&self) -> i32 {
        1 << self.cell_log2
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
        let cell = 1 << self.cell_log2;
        let a = (self.origin + lo * cell).as_dvec3() - DVec3::splat(0.5);
        let b = (self.origin + (hi + IVec3::ONE) * cell).as_dvec3() - DVec3::splat(0.5);
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
                cell_voxels: 1 << (self.cell_log2 + i as i32),
                cells: l.cells.len(),
                occupied: l.cells.iter().filter(|b| !b.is_empty()).count(),
                homogeneous: l
                    .cells
                    .iter()
                    .filter(|b| self.exact && !b.is_empty() && b.min == b.max)
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
        let c = (ijk - self.origin) >> (self.cell_log2 + level as i32);
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
}

/// The cost of one more segment, in density lookups (a segment costs a DDA step, an
/// exponential sample and the tracker's per-segment set-up, about what one tentative collision
/// costs; measured with callgrind on the grid scenes, docs/BENCHMARKS.md).
pub const SEGMENT_COST: f64 = 1.0;

/// What preparing the hierarchical walk below an opened root costs a free flight with point
/// bounds ([`LookupModel::Probed`]), in density lookups ([`SEGMENT_COST`] units): the ray's
/// DDA set-up, the root's frame and the descent to the first cells emitted (about 1,100
/// instructions per walk on the dense peer cloud, some five lookups). The plan's prices count
/// segment boundaries per unit length only; a flight stops at its first real collision and
/// covers a short part of the ray in a dense medium, so the root is opened only where the
/// lookups saved over that part pay for the walk ([`walk::root_step`]; docs/BENCHMARKS.md,
/// "The walk's set-up priced per free flight").
pub const WALK_COST: f64 = 8.0;

/// log₂ of the finest cell edge (voxels) for a grid region of `bricks` bricks: 2³-voxel cells
/// (64 per brick) up to 2^16 bricks, 4³ (8 per brick) up to 2^21, else whole bricks, so that
/// level 0 stays within 2^22 cells (16 bytes each).
#[must_use]
pub fn finest_cell_log2(bricks: f64) -> i32 {
    if bricks * 64.0 <= f64::from(1u32 << 22) {
        1
    } else if bricks * 8.0 <= f64::from(1u32 << 24) {
        2
    } else {
        3
    }
}
