//! Density lookups along one ray, dispatched over the density sources (an enum, no trait
//! objects in the tracking loops).

use glam::Vec3;

use crate::fabric::{FabricShell, FibreGridLookup, ShellCursor, ShellLookup};
use crate::grid::{Accessor, SparseGrid};
use crate::majorant::LocalBounds;
use crate::math::Ray;
use crate::procedural::{FbmField, LazyFbmGrid};
use crate::tracking::{PointBounds, Probe};

/// Density lookups along one ray, by distance.
pub enum DensityLookup<'a> {
    /// Trilinear grid lookups with a coherent accessor.
    Grid(GridLookup<'a>),
    /// Lazily baked procedural bricks (index-space ray).
    Lazy {
        /// The bricks.
        grid: &'a LazyFbmGrid,
        /// Ray origin, index space.
        o: Vec3,
        /// Ray direction, index space.
        d: Vec3,
    },
    /// Direct procedural evaluation.
    Procedural {
        /// The field.
        field: &'a FbmField,
        /// The ray.
        ray: Ray,
    },
    /// A free-standing fabric grid with fibre-projected extinction.
    FibreGrid(FibreGridLookup<'a>),
    /// A weave patch tiled over a mesh shell.
    Shell(ShellLookup<'a>),
}

impl DensityLookup<'_> {
    /// Density at distance `t`. Grid lookups, the trackers' common case, are inlined into
    /// them; the other sources are dispatched out of line.
    #[inline(always)]
    pub fn at(&mut self, t: f32) -> f32 {
        match self {
            DensityLookup::Grid(g) => g.at(t),
            _ => self.at_other(t),
        }
    }

    /// [`Self::at`] for the sources other than grids.
    #[inline(never)]
    fn at_other(&mut self, t: f32) -> f32 {
        match self {
            DensityLookup::Grid(g) => g.at(t),
            DensityLookup::Procedural { field, ray } => field.density_world(ray.at(t)),
            DensityLookup::Lazy { grid, o, d } => grid.sample_trilinear_index(*o + *d * t),
            DensityLookup::Shell(s) => s.at(t),
            DensityLookup::FibreGrid(g) => g.at(t),
        }
    }
}

/// `ray` (world space) in `grid`'s index space: origin and direction, transformed in double
/// precision and rounded to single (what [`GridLookup`] and [`LocalProbe`] step along, so
/// that both see the same points).
#[inline]
#[must_use]
pub fn index_ray(grid: &SparseGrid, ray: &Ray) -> (Vec3, Vec3) {
    let w2i = grid.world_to_index();
    (
        w2i.transform_point3(ray.o.as_dvec3()).as_vec3(),
        w2i.transform_vector3(ray.d.as_dvec3()).as_vec3(),
    )
}

/// A trilinear density lookup along a ray in a grid's index space (coherent accessor).
pub struct GridLookup<'a> {
    accessor: Accessor<'a>,
    o: Vec3,
    d: Vec3,
}

impl<'a> GridLookup<'a> {
    /// Prepares lookups along `ray` (world space) in channel `channel` of `grid`.
    #[must_use]
    pub fn new(grid: &'a SparseGrid, channel: usize, ray: &Ray) -> Self {
        let (o, d) = index_ray(grid, ray);
        Self::from_index_ray(grid, channel, o, d)
    }

    /// Prepares lookups along the index-space ray `o + t d` ([`index_ray`]) in channel
    /// `channel` of `grid`.
    #[inline]
    #[must_use]
    pub fn from_index_ray(grid: &'a SparseGrid, channel: usize, o: Vec3, d: Vec3) -> Self {
        GridLookup {
            accessor: grid.padded_accessor(channel),
            o,
            d,
        }
    }

    /// Trilinear density at distance `t`.
    #[inline(always)]
    pub fn at(&mut self, t: f32) -> f32 {
        self.accessor.sample_trilinear(self.o + self.d * t)
    }
}

/// Point bounds along a ray: from a grid's local-bounds table, or from a fabric shell's
/// per-voxel maxima.
pub enum LocalProbe<'a> {
    /// A grid's local-bounds table ([`GridProbe`]).
    Grid(GridProbe<'a>),
    /// A fabric shell's point bounds ([`FabricShell::point_bound`]).
    Shell(ShellProbe<'a>),
}

impl<'a> LocalProbe<'a> {
    /// Point bounds along `ray` (world space) from `table`, built over `grid`.
    #[must_use]
    pub fn new(table: &'a LocalBounds, grid: &SparseGrid, ray: &Ray, zero_min: bool) -> Self {
        LocalProbe::Grid(GridProbe::new(table, grid, ray, zero_min))
    }

    /// Point bounds along the index-space ray `o + t d` ([`index_ray`] of the grid `table`
    /// was built over).
    #[inline]
    #[must_use]
    pub fn from_index_ray(table: &'a LocalBounds, o: Vec3, d: Vec3, zero_min: bool) -> Self {
        LocalProbe::Grid(GridProbe::from_index_ray(table, o, d, zero_min))
    }
}

impl PointBounds for LocalProbe<'_> {
    /// Grid tables, the common case, are read inline; fabric shells out of line.
    #[inline(always)]
    fn at(&mut self, t: f32) -> Option<(f32, f32)> {
        match self {
            LocalProbe::Grid(g) => g.at(t),
            LocalProbe::Shell(s) => s.at_out_of_line(t),
        }
    }

    #[inline(always)]
    fn probe(&mut self, t: f32, skip: impl FnOnce(f32) -> bool) -> Probe {
        match self {
            LocalProbe::Grid(g) => g.probe(t, skip),
            LocalProbe::Shell(s) => Probe::from_bounds(s.at_out_of_line(t)),
        }
    }

    #[inline]
    fn proven_minorant(&self) -> bool {
        match self {
            LocalProbe::Grid(g) => g.proven_minorant(),
            LocalProbe::Shell(_) => false,
        }
    }
}

/// Point bounds along a ray from a grid's local-bounds table ([`LocalBounds`]), at the
/// index-space points the grid's lookups along the same ray compute.
pub struct GridProbe<'a> {
    table: &'a LocalBounds,
    o: Vec3,
    d: Vec3,
    /// The density is the grid's scaled by a factor in [0, 1] (fibre-projected extinction):
    /// the minimum is 0.
    zero_min: bool,
}

impl<'a> GridProbe<'a> {
    /// Point bounds along `ray` (world space) from `table`, built over `grid`.
    #[must_use]
    pub fn new(table: &'a LocalBounds, grid: &SparseGrid, ray: &Ray, zero_min: bool) -> Self {
        let (o, d) = index_ray(grid, ray);
        Self::from_index_ray(table, o, d, zero_min)
    }

    /// Point bounds along the index-space ray `o + t d` ([`index_ray`] of the grid `table`
    /// was built over).
    #[inline]
    #[must_use]
    pub fn from_index_ray(table: &'a LocalBounds, o: Vec3, d: Vec3, zero_min: bool) -> Self {
        GridProbe {
            table,
            o,
            d,
            zero_min,
        }
    }
}

impl GridProbe<'_> {
    /// The table's bounds `(a, b)` as the probe returns them (0 inside for a scaled field).
    #[inline(always)]
    fn widen(&self, a: f32, b: f32) -> (f32, f32) {
        if self.zero_min {
            (a.min(0.0), b.max(0.0))
        } else {
            (a, b)
        }
    }
}

impl PointBounds for GridProbe<'_> {
    #[inline(always)]
    fn at(&mut self, t: f32) -> Option<(f32, f32)> {
        let (a, b) = self.table.at(self.o + self.d * t);
        Some(self.widen(a, b))
    }

    /// The table's block maxima first (`LocalBounds::probe`).
    #[inline(always)]
    fn probe(&mut self, t: f32, skip: impl FnOnce(f32) -> bool) -> Probe {
        let zero_min = self.zero_min;
        match self.table.probe(self.o + self.d * t, |ub| {
            skip(if zero_min { ub.max(0.0) } else { ub })
        }) {
            Some((a, b)) => {
                let (a, b) = self.widen(a, b);
                Probe::Bounds(a, b)
            }
            None => Probe::Skipped,
        }
    }

    /// The table's minima are the voxels' minima over each cell rounded down: no trilinear
    /// lookup in the cell is lower (`majorant::LocalBounds`).
    #[inline]
    fn proven_minorant(&self) -> bool {
        true
    }
}

/// Point bounds along a ray through a fabric shell: `(0, the largest voxel the lookup's
/// trilinear filter reads)`, which bounds the fibre-projected density too.
pub struct ShellProbe<'a> {
    cursor: ShellCursor<'a>,
}

impl<'a> ShellProbe<'a> {
    /// Point bounds along `ray` (world space) through `shell`.
    #[must_use]
    pub fn new(shell: &'a FabricShell, ray: &Ray) -> Self {
        ShellProbe {
            cursor: ShellCursor::new(shell, ray),
        }
    }
}

impl PointBounds for ShellProbe<'_> {
    #[inline]
    fn at(&mut self, t: f32) -> Option<(f32, f32)> {
        Some((0.0, self.cursor.point_bound(t)))
    }
}

impl ShellProbe<'_> {
    /// [`PointBounds::at`], not inlined into [`LocalProbe`]'s dispatch.
    #[inline(never)]
    fn at_out_of_line(&mut self, t: f32) -> Option<(f32, f32)> {
        self.at(t)
    }
}

/// The point bounds of a free flight through a fabric shell that share point location with
/// the flight's density lookups ([`ShellLookup::bound`]): the lookup that follows a bound
/// at the same distance takes its tetrahedron and patch coordinates.
pub struct SharedShellProbe<'l, 'a> {
    lookup: &'l ShellLookup<'a>,
}

impl<'l, 'a> SharedShellProbe<'l, 'a> {
    /// Point bounds through the shell of `lookup`, along its ray.
    #[must_use]
    pub fn new(lookup: &'l ShellLookup<'a>) -> Self {
        SharedShellProbe { lookup }
    }

    /// The bound at `t`, out of line (called at every tentative collision).
    #[inline(never)]
    fn bound(&self, t: f32) -> f32 {
        self.lookup.bound(t)
    }
}

impl PointBounds for SharedShellProbe<'_, '_> {
    #[inline(always)]
    fn at(&mut self, t: f32) -> Option<(f32, f32)> {
        Some((0.0, self.bound(t)))
    }
}
