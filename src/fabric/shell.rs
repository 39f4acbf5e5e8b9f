//! A voxelised weave patch tiled over a mesh shell (course notes §3.3: "at each sampling
//! position, project back to the surface and query a voxel position").
//!
//! # The shell map
//! The cloth mesh (with texture coordinates) is the cloth's mid-surface. Each vertex `p` is
//! offset along its normal `n` (area-weighted over the triangles around the welded position)
//! to `p − n·T/2` (the bottom) and `p + n·T/2` (the top), so every triangle sweeps a prism of
//! thickness `T`. Each prism is cut into three tetrahedra with the diagonal of every side quad
//! chosen by the global vertex order, so neighbouring prisms share their side faces exactly
//! (the "shell map" of Porumbescu et al. 2005). Inside one tetrahedron the map from world
//! space to the patch's index space is affine, so "projecting a sample back to the surface"
//! is exact and costs one 3×3 product once the tetrahedron is found:
//!
//! * `u, v` (the mesh's texture coordinates) times `tiles` give the position in patch tiles;
//!   `x = u·tiles_u·n_x − ½`, `y = v·tiles_v·n_y − ½` in voxel units (voxel centres at
//!   integers, wrapping modulo `n_x`, `n_y`);
//! * the height `h ∈ [0, 1]` across the shell gives `z = k_min − 1 + h·(k_max − k_min + 2)`,
//!   so the shell spans the patch's occupied voxel layers plus one layer on each side (the
//!   trilinear tails of the outer layers stay inside and the fibre volume is conserved).
//!
//! `T` follows from the scale of the tiling: one patch voxel is `L/(tiles·n)` world units
//! wide, where `L = sqrt(world area / UV area)` is the mesh's mean world length per unit of
//! UV, and the shell is as many of those (in `z`) as the patch is thick, so the weave keeps its
//! proportions. Fibre tangents map to the world through the tetrahedron's linear part.
//!
//! # Lookups
//! A uniform grid over the shell's box lists the tetrahedra overlapping each cell; a lookup
//! tests the last tetrahedron first (tracking steps are short), then walks a few tetrahedra
//! across the faces the point lies beyond, then searches the cell's list. Along one ray a
//! [`ShellCursor`] follows the affine maps of the last tetrahedron, shares its locations between
//! point bounds and lookups, and starts from the tetrahedron remembered at the ray's origin.
//! Points in no tetrahedron have zero density. Majorants come from a world-space pyramid of
//! bricks that overlap the shell, bounded by the patch's maximum density.

use std::cell::Cell;

use glam::{DMat3, DVec3, IVec3, Mat3, Vec3};

use super::voxelise::{VoxelisedPatch, DENSITY, ID, TANGENT};
use super::FabricError;
use crate::geometry::TriangleMesh;
use crate::grid::{Accessor, SparseGrid};
use crate::majorant::{Bounds, MajorantPyramid};
use crate::math::{Aabb, Ray};

/// Largest number of tetrahedra a shell may have (three per triangle).
pub const MAX_SHELL_TETS: usize = 30_000_000;
/// Largest extent of one tetrahedron in patch voxels (f32 precision of the shell map).
pub const MAX_TET_SPAN_VOXELS: f32 = 262_144.0;
/// Largest number of point-location cells.
const MAX_CELLS: usize = 1 << 22;
/// Point-location cells per tetrahedron (before the cap). On the draped cloth, eight instead
/// of one half saved 1–2 % of the render's CPU time (lookups that miss the last
/// tetrahedron and its neighbours scan shorter lists).
const CELLS_PER_TET: usize = 8;
/// Largest number of level-0 majorant bricks.
const MAX_MAJORANT_BRICKS: f64 = 4.0e6;

/// One tetrahedron of the shell, with its affine maps.
#[derive(Clone, Copy, Debug)]
struct ShellTet {
    /// World position of vertex 0.
    w0: Vec3,
    /// World → barycentric (λ1, λ2, λ3) of `x − w0`.
    world_to_bary: Mat3,
    /// Patch index coordinates of vertex 0 (`x`, `y` reduced modulo the tile).
    q0: Vec3,
    /// Barycentric → patch index offsets (columns `q_k − q0`).
    bary_to_q: Mat3,
    /// Patch-unit tangent → world direction: the inverse linear part of the map after the
    /// patch's voxel size (tangents are stored in patch units).
    tangent_to_world: Mat3,
}

impl ShellTet {
    /// The patch `z` range of the tetrahedron (over its four vertices).
    fn z_range(&self) -> (f32, f32) {
        let z = [
            self.q0.z,
            self.q0.z + self.bary_to_q.x_axis.z,
            self.q0.z + self.bary_to_q.y_axis.z,
            self.q0.z + self.bary_to_q.z_axis.z,
        ];
        (
            z.iter().copied().fold(f32::INFINITY, f32::min),
            z.iter().copied().fold(f32::NEG_INFINITY, f32::max),
        )
    }
}

/// What point location reads of a tetrahedron (its world → barycentric map and its face
/// neighbours), one cache line per tetrahedron: a lookup tests the last tetrahedron, walks to
/// its neighbours and only then searches a cell's list, and most of its time is waiting for
/// these.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct TetLocator {
    w0: Vec3,
    world_to_bary: Mat3,
    /// The tetrahedron across the face opposite vertex `k` (vertex 0 is `w0`, vertex `k ≥ 1`
    /// the one of barycentric `λ_k`), or [`NO_NEIGHBOUR`] on the shell's boundary.
    neighbours: [u32; 4],
}

/// [`TetLocator::neighbours`] of a boundary face.
const NO_NEIGHBOUR: u32 = u32::MAX;

/// Tetrahedra a lookup walks across faces from the last one found before it searches the
/// point-location grid.
const MAX_WALK_STEPS: usize = 3;

/// Barycentric tolerance of the inside test.
const BARY_EPS: f32 = -1e-5;

impl TetLocator {
    fn of(t: &ShellTet) -> TetLocator {
        TetLocator {
            w0: t.w0,
            world_to_bary: t.world_to_bary,
            neighbours: [NO_NEIGHBOUR; 4],
        }
    }

    /// Barycentrics `(λ1, λ2, λ3)` of `p`, whether or not `p` lies inside.
    #[inline(always)]
    fn bary(&self, p: Vec3) -> Vec3 {
        self.world_to_bary * (p - self.w0)
    }

    /// Whether barycentrics `l` lie inside (with tolerance).
    #[inline(always)]
    fn inside(l: Vec3) -> bool {
        l.min_element() >= BARY_EPS && 1.0 - l.x - l.y - l.z >= BARY_EPS
    }

    /// Barycentrics `(λ1, λ2, λ3)` of `p`, and whether `p` lies inside (with tolerance).
    #[inline(always)]
    fn locate(&self, p: Vec3) -> Option<Vec3> {
        let l = self.bary(p);
        Self::inside(l).then_some(l)
    }

    /// The neighbour across the face `p` lies furthest beyond (the most negative
    /// barycentric), or [`NO_NEIGHBOUR`].
    #[inline(always)]
    fn towards(&self, l: Vec3) -> u32 {
        let l0 = 1.0 - l.x - l.y - l.z;
        let (mut k, mut m) = (0usize, l0);
        if l.x < m {
            (k, m) = (1, l.x);
        }
        if l.y < m {
            (k, m) = (2, l.y);
        }
        if l.z < m {
            k = 3;
        }
        self.neighbours[k]
    }
}

/// Parameters of [`FabricShell::new`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellParams {
    /// Patch tiles across the unit UV square, per axis (`u`, `v`), each ≥ 1.
    pub tiles: [f32; 2],
}

/// A weave patch tiled over a mesh shell; see the module docs.
#[derive(Clone, Debug)]
pub struct FabricShell {
    patch: SparseGrid,
    dims: IVec3,
    tets: Vec<ShellTet>,
    /// `tets[i]`'s point-location map, packed.
    locators: Vec<TetLocator>,
    cell_origin: Vec3,
    inv_cell: f32,
    cell_dims: IVec3,
    /// `cell_start[c]..cell_start[c + 1]` indexes `cell_tets`.
    cell_start: Vec<u32>,
    cell_tets: Vec<u32>,
    boundary: TriangleMesh,
    thickness: f32,
    voxel_world: f32,
    bounds: Aabb,
    density_bounds: Bounds,
    /// First patch layer (`z` index) of the shell.
    layer_lo: i32,
    /// Per patch layer from `layer_lo`: (max, mean) of the density over the layer.
    layers: Vec<(f32, f32)>,
    tiles: [f32; 2],
    /// Point bounds of trilinear lookups ([`FabricShell::point_bound`]): per patch voxel `v`
    /// of layers `layer_lo − 1 ..= layer_lo + dims.z` (x fastest), the largest density of
    /// the eight voxels `v .. v + 1` (wrapped in x, y) a lookup in the cell above `v` reads,
    /// rounded up to a multiple `code · support_step` of 1/255 of the largest
    /// ([`quantise_up`]): one byte an entry (150 KiB for the draped cloth's patch where 32-bit
    /// floats took 600 KiB and missed the second-level cache), still a bound.
    support_codes: Vec<u8>,
    /// The value of one step of `support_codes`.
    support_step: f32,
    /// One bit per entry of `support_codes`, set where the largest density is above 0: the test "are all eight
    /// voxels of this lookup empty" from a table of 1/32 the size (19 KiB for the draped
    /// cloth's patch against 600 KiB), which stays in the first-level cache. Shadow rays,
    /// which make most of the lookups, need only that test before reading the bricks.
    support_bits: Vec<u64>,
    /// Flat copy of the patch's density (first component, as the accessor reads it) and
    /// tangent, interleaved ([`FlatVoxel`], 16 bytes a voxel), over layers
    /// `layer_lo − 1 ..= layer_lo + dims.z + 1`, x and y padded by one voxel (column
    /// `dims.x` repeats column 0, row `dims.y` row 0), in tiles of 2 × 2 voxels of a layer,
    /// one 64-byte cache line each ([`flat_index`]): the eight corners of every lookup that
    /// passes the occupancy bit lie at offsets from one index that depend only on the
    /// corner's parity, with no brick resolution and no wrapping ([`FabricShell::cell_at`]).
    /// The nearest voxel's tangent (and the other corners' where it is zero) lies on the
    /// cache lines the density corners were read from, and the corners span 2 to 8 lines
    /// (4.5 on average; rows of voxels took 5 and a separate tangent table one to four more).
    flat_tiles: Vec<FlatTile>,
    /// Tiles per row of `flat_tiles` (`⌈(dims.x + 1) / 2⌉`).
    flat_row_tiles: usize,
    /// Voxels per layer of `flat_tiles` (4 × tiles per layer).
    flat_layer: usize,
    /// The patch's yarn ids on the layout of `flat_tiles` (read once per scattering
    /// vertex, [`FabricShell::fibre_at`]).
    flat_id: Vec<f32>,
}

/// The fibre frame of a voxel: world tangent and yarn-family id (0 warp, 1 weft, 2 pile).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FibreVoxel {
    /// Unit fibre tangent in world space.
    pub tangent: Vec3,
    /// Yarn family id as stored in the patch's `id` channel.
    pub id: f32,
}

/// One voxel of [`FabricShell`]'s flat tables: the density (the channel's first component)
/// and the tangent, side by side so that a lookup's corners and its nearest tangent share
/// cache lines (16-byte aligned: four voxels a 64-byte line, none straddling two).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(16))]
struct FlatVoxel {
    density: f32,
    tangent: [f32; 3],
}

/// Four [`FlatVoxel`]s, 2 × 2 of a layer (`x` fastest), on one 64-byte cache line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(64))]
struct FlatTile([FlatVoxel; 4]);

/// Where a lookup's cell lies in [`FabricShell`]'s flat tables: the index of its lower
/// corner and the steps to the next voxel in `x`, `y` and `z` from there (in 2 × 2 tiles
/// they depend on the corner's parity: [`flat_index`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct FlatCell {
    f: usize,
    dx: usize,
    dy: usize,
    dz: usize,
}

impl FlatCell {
    /// The cell whose lower corner is voxel `(x, y, z)` (table coordinates) of flat tables of
    /// `row_tiles` tiles a row and `layer` voxels a layer.
    #[inline(always)]
    fn new(x: usize, y: usize, z: usize, row_tiles: usize, layer: usize) -> FlatCell {
        FlatCell {
            f: flat_index(x, y, z, row_tiles, layer),
            dx: 1 + ((x & 1) << 1),
            dy: if y & 1 == 0 { 2 } else { 4 * row_tiles - 2 },
            dz: layer,
        }
    }

    /// The index of corner `d ∈ {0, 1}³` of the cell.
    #[inline(always)]
    fn corner(&self, d: IVec3) -> usize {
        self.f + d.x as usize * self.dx + d.y as usize * self.dy + d.z as usize * self.dz
    }
}

/// The index of voxel `(x, y, z)` (non-negative, table coordinates) in flat tables of
/// `row_tiles` tiles a row and `layer` voxels a layer, tiled 2 × 2 in `x`, `y`: tile
/// `(x / 2, y / 2)` of layer `z`, voxel `2 (y mod 2) + x mod 2` in it.
#[inline(always)]
fn flat_index(x: usize, y: usize, z: usize, row_tiles: usize, layer: usize) -> usize {
    z * layer + ((y >> 1) * row_tiles + (x >> 1)) * 4 + ((y & 1) << 1) + (x & 1)
}

/// A world point located in the shell: its tetrahedron and its patch index coordinates
/// (`x`, `y` not yet wrapped), as [`FabricShell::locate`] finds them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShellPoint {
    tet: u32,
    q: Vec3,
}

impl ShellPoint {
    /// The tetrahedron the point was found in.
    #[must_use]
    pub fn tet(&self) -> usize {
        self.tet as usize
    }

    /// Patch index coordinates (`x`, `y` not wrapped).
    #[must_use]
    pub fn q(&self) -> Vec3 {
        self.q
    }
}

/// Point location along one ray through a shell, shared by the ray's density lookups and
/// point bounds (both take `&self`).
///
/// * The first point is searched from the tetrahedron remembered at the ray's origin
///   ([`FabricShell::vertex_hint`]: a ray leaving a scattering vertex starts in the
///   tetrahedron the flight that ended there found), later ones from the last tetrahedron
///   found, as in [`FabricShell::locate`].
/// * The last point located is kept: a free flight's density lookup follows the point bound
///   of its tentative collision at the same distance, and takes the bound's tetrahedron and
///   patch coordinates instead of locating the point again (the same values: a search from
///   that tetrahedron finds it first, with the same arithmetic).
/// * When the cursor is dropped, the last point and its tetrahedron are remembered
///   ([`FabricShell::remember_vertex`]) for the rays that leave it.
#[derive(Debug)]
pub struct ShellCursor<'a> {
    shell: &'a FabricShell,
    ray: Ray,
    hint: Cell<u32>,
    /// The affine maps along the ray in the last tetrahedron found.
    span: Cell<TetSpan>,
    /// The distance of the last point located (NaN before the first) and where it was.
    last: Cell<(f32, Option<ShellPoint>)>,
}

impl<'a> ShellCursor<'a> {
    /// Point location along `ray` (world space) through `shell`.
    #[must_use]
    pub fn new(shell: &'a FabricShell, ray: &Ray) -> Self {
        ShellCursor {
            shell,
            ray: *ray,
            hint: Cell::new(shell.vertex_hint(ray.o)),
            span: Cell::new(TetSpan::NONE),
            last: Cell::new((f32::NAN, None)),
        }
    }

    /// The shell.
    #[inline(always)]
    #[must_use]
    pub fn shell(&self) -> &'a FabricShell {
        self.shell
    }

    /// The ray.
    #[inline(always)]
    #[must_use]
    pub fn ray(&self) -> &Ray {
        &self.ray
    }

    /// The point at distance `t` located ([`FabricShell::locate`]); `None` outside the shell.
    #[inline(always)]
    pub fn locate(&self, t: f32) -> Option<ShellPoint> {
        let (last_t, last) = self.last.get();
        if last_t == t {
            return last;
        }
        let span = self.span.get();
        if span.tet != u32::MAX {
            // Inside the last tetrahedron both maps are affine in `t`.
            let s = t - span.t_ref;
            if TetLocator::inside(span.l + span.dl * s) {
                let found = Some(ShellPoint {
                    tet: span.tet,
                    q: span.q + span.dq * s,
                });
                self.last.set((t, found));
                return found;
            }
        }
        let mut hint = self.hint.get();
        let found = self.shell.locate_with_bary(self.ray.at(t), &mut hint);
        self.hint.set(hint);
        if let Some((s, l)) = found {
            self.span.set(self.shell.span(s, l, t, self.ray.d));
        }
        let found = found.map(|(s, _)| s);
        self.last.set((t, found));
        found
    }

    /// The point bound at distance `t` ([`FabricShell::point_bound_at`]); 0 outside the
    /// shell. A lookup at the same distance next reuses this point location.
    #[inline(always)]
    #[must_use]
    pub fn point_bound(&self, t: f32) -> f32 {
        // A `match`, not `Option::map_or`: the compiler kept `map_or` (only `#[inline]`) out
        // of line, a call per tentative collision (`core::option::Option::map_or` in
        // profiles).
        match self.locate(t) {
            Some(s) => self.shell.point_bound_at(s),
            None => 0.0,
        }
    }
}

/// A ray's barycentrics and patch coordinates inside one tetrahedron, affine in the
/// distance: `l + dl·(t − t_ref)` and `q + dq·(t − t_ref)`, from the point at `t_ref`
/// where the tetrahedron was found.
#[derive(Clone, Copy, Debug)]
struct TetSpan {
    /// The tetrahedron (`u32::MAX`: none yet).
    tet: u32,
    t_ref: f32,
    l: Vec3,
    dl: Vec3,
    q: Vec3,
    dq: Vec3,
}

impl TetSpan {
    const NONE: TetSpan = TetSpan {
        tet: u32::MAX,
        t_ref: 0.0,
        l: Vec3::ZERO,
        dl: Vec3::ZERO,
        q: Vec3::ZERO,
        dq: Vec3::ZERO,
    };
}

impl Drop for ShellCursor<'_> {
    fn drop(&mut self) {
        if let (t, Some(s)) = self.last.get() {
            self.shell.remember_vertex(self.ray.at(t), s.tet);
        }
    }
}

/// One entry of the per-thread cache of [`FabricShell::remember_vertex`].
#[derive(Clone, Copy, Debug)]
struct VertexTet {
    /// The shell's address (0: empty).
    shell: usize,
    /// The point's bits.
    p: [u32; 3],
    tet: u32,
}

/// Entries of the per-thread vertex cache (direct-mapped by the point's bits).
const VERTEX_SLOTS: usize = 8;

thread_local! {
    /// Tetrahedra found at the last points of this thread's rays through shells (where a
    /// path's next rays start), by point: see [`FabricShell::remember_vertex`].
    static VERTEX_TETS: [Cell<VertexTet>; VERTEX_SLOTS] = const {
        [const {
            Cell::new(VertexTet {
                shell: 0,
                p: [0; 3],
                tet: u32::MAX,
            })
        }; VERTEX_SLOTS]
    };
}

/// The slot of point bits `p` in [`VERTEX_TETS`].
#[inline(always)]
fn vertex_slot(p: [u32; 3]) -> usize {
    let h = (p[0] ^ p[1].rotate_left(11) ^ p[2].rotate_left(22)).wrapping_mul(0x9E37_79B1);
    (h >> 29) as usize % VERTEX_SLOTS
}

impl FabricShell {
    /// Builds the shell of `patch` over `mesh` (world space; needs texture coordinates).
    ///
    /// # Errors
    /// [`FabricError::InvalidParameter`] when the mesh has no texture coordinates or no
    /// triangle with non-zero UV area, when `tiles` is outside `[1, 1e6]`, when the patch is
    /// empty or not wrapped, or when the shell would be degenerate;
    /// [`FabricError::TooLarge`] beyond [`MAX_SHELL_TETS`].
    pub fn new(
        patch: &VoxelisedPatch,
        mesh: &TriangleMesh,
        params: &ShellParams,
    ) -> Result<FabricShell, FabricError> {
        for (k, t) in params.tiles.iter().enumerate() {
            if !(t.is_finite() && (1.0..=1e6).contains(t)) {
                return Err(super::invalid(
                    &format!("tiles[{k}]"),
                    t,
                    "[1, 1e6] patch tiles per unit of UV",
                ));
            }
        }
        if !patch.wrapped {
            return Err(super::invalid(
                "patch.wrap",
                false,
                "a tiled shell needs a periodic (wrapped) patch",
            ));
        }
        let uvs = mesh.uvs.as_ref().ok_or_else(|| {
            super::invalid(
                "mesh.uvs",
                "none",
                "a fabric shell needs texture coordinates (u, v) on the mesh",
            )
        })?;
        let tets_needed = mesh.indices.len() * 3;
        if tets_needed > MAX_SHELL_TETS {
            return Err(FabricError::TooLarge {
                name: "mesh triangles".into(),
                what: "shell tetrahedra".into(),
                count: tets_needed as u64,
                limit: MAX_SHELL_TETS as u64,
            });
        }
        let (lo, hi) = patch
            .grid
            .active_bbox()
            .ok_or_else(|| super::invalid("patch", "empty", "a patch with fibres"))?;
        let dims = IVec3::new(patch.dims[0] as i32, patch.dims[1] as i32, hi.z - lo.z + 2);
        let z_lo = (lo.z - 1) as f32;

        // Scale: world length per unit UV, then the world size of one patch voxel.
        let (vx, vy) = tiled_voxel_widths(mesh, params.tiles, patch.dims).ok_or_else(|| {
            super::invalid(
                "mesh.uvs",
                "zero area",
                "triangles with non-zero world and UV area",
            )
        })?;
        // Patch voxels may be slightly anisotropic (h_x, h_y, h_z); keep the proportions.
        let h = patch.voxel_size;
        let scale = (vx / h.x * vy / h.y).sqrt();
        let voxel_z = h.z * scale;
        let thickness = voxel_z * f64::from(dims.z);

        let canon = welded_ids(mesh);
        let normals = welded_normals(mesh, &canon);
        let mut tets = Vec::with_capacity(tets_needed);
        // Per tetrahedron, its corners' welded vertex keys (2 · welded id + top), for the
        // face neighbours.
        let mut tet_keys: Vec<[u32; 4]> = Vec::with_capacity(tets_needed);
        let period = Vec3::new(dims.x as f32, dims.y as f32, 0.0);
        let tile_scale = DVec3::new(
            f64::from(params.tiles[0]) * f64::from(dims.x),
            f64::from(params.tiles[1]) * f64::from(dims.y),
            f64::from(dims.z),
        );
        for tri in &mesh.indices {
            // Sort the corners by welded id: the side-quad diagonals then agree between
            // neighbouring prisms.
            let mut c = *tri;
            c.sort_by_key(|&i| canon[i as usize]);
            let vert = |i: u32, top: bool| {
                let p = mesh.positions[i as usize].as_dvec3();
                let n = normals[canon[i as usize] as usize];
                let s = if top { 0.5 } else { -0.5 };
                let uv = uvs[i as usize].as_dvec2();
                let q = DVec3::new(uv.x, uv.y, if top { 1.0 } else { 0.0 }) * tile_scale
                    + DVec3::new(-0.5, -0.5, f64::from(z_lo));
                (p + n * (s * thickness), q)
            };
            let [a, b, d] = c;
            let key = |i: u32, top: bool| 2 * canon[i as usize] + u32::from(top);
            let keys = [
                [key(a, false), key(b, false), key(d, false), key(d, true)],
                [key(a, false), key(b, false), key(b, true), key(d, true)],
                [key(a, false), key(a, true), key(b, true), key(d, true)],
            ];
            let corners = [
                [
                    vert(a, false),
                    vert(b, false),
                    vert(d, false),
                    vert(d, true),
                ],
                [vert(a, false), vert(b, false), vert(b, true), vert(d, true)],
                [vert(a, false), vert(a, true), vert(b, true), vert(d, true)],
            ];
            for (t, k) in corners.into_iter().zip(keys) {
                if let Some(tet) = make_tet(t, period, h) {
                    tets.push(tet);
                    tet_keys.push(k);
                }
            }
        }
        // f32 patch coordinates inside one tetrahedron stay exact to ~1/64 voxel only while a
        // triangle spans fewer than 2^18 voxels of the tiled patch.
        let span = tets
            .iter()
            .map(|t| {
                let m = t.bary_to_q;
                m.x_axis
                    .abs()
                    .max(m.y_axis.abs())
                    .max(m.z_axis.abs())
                    .max_element()
            })
            .fold(0.0f32, f32::max);
        if span > MAX_TET_SPAN_VOXELS {
            return Err(super::invalid(
                "tiles",
                format!("{:?} (a triangle spans {span:.0} patch voxels)", params.tiles),
                &format!("at most {MAX_TET_SPAN_VOXELS} voxels per triangle: use fewer tiles or subdivide the mesh"),
            ));
        }
        if tets.is_empty() {
            return Err(super::invalid(
                "mesh",
                "degenerate",
                "a mesh whose triangles have non-zero world and UV area",
            ));
        }
        let boundary = shell_boundary(mesh, &canon, &normals, thickness);
        let bounds = boundary.bounds();
        let layer_lo = lo.z - 1;
        let layers = layer_stats(&patch.grid, layer_lo, dims);
        let density_bounds = bounds_over_layers(&layers, 0, layers.len() - 1);
        let mut shell = FabricShell {
            patch: patch.grid.clone(),
            dims,
            locators: tets.iter().map(TetLocator::of).collect(),
            tets,
            cell_origin: Vec3::ZERO,
            inv_cell: 1.0,
            cell_dims: IVec3::ONE,
            cell_start: Vec::new(),
            cell_tets: Vec::new(),
            boundary,
            thickness: thickness as f32,
            voxel_world: voxel_z as f32,
            bounds,
            density_bounds,
            layer_lo,
            layers,
            tiles: params.tiles,
            support_codes: Vec::new(),
            support_step: 0.0,
            support_bits: Vec::new(),
            flat_tiles: Vec::new(),
            flat_row_tiles: 0,
            flat_layer: 0,
            flat_id: Vec::new(),
        };
        shell.link_neighbours(&tet_keys);
        shell.build_cells();
        let support = support_max(&shell.patch, dims, layer_lo);
        shell.support_bits = occupancy_bits(&support);
        (shell.support_codes, shell.support_step) = quantise_up(&support);
        let flat = flat_channels(&shell.patch, dims, layer_lo);
        (shell.flat_tiles, shell.flat_id) = (flat.tiles, flat.id);
        (shell.flat_row_tiles, shell.flat_layer) = (flat.row_tiles, flat.layer);
        Ok(shell)
    }

    /// Fills [`TetLocator::neighbours`]: two tetrahedra are neighbours across a face whose
    /// three corners have the same welded vertex keys (`keys[i]`, corner by corner as in
    /// the tetrahedron). A face shared by more than two (a degenerate mesh) links none.
    fn link_neighbours(&mut self, keys: &[[u32; 4]]) {
        let mut faces: std::collections::HashMap<[u32; 3], (u32, u8, u32)> =
            std::collections::HashMap::with_capacity(keys.len() * 2);
        for (i, k) in keys.iter().enumerate() {
            for opp in 0..4u8 {
                let f = face_key(k, opp);
                faces
                    .entry(f)
                    .and_modify(|e| e.2 += 1)
                    .or_insert((i as u32, opp, 1));
            }
        }
        for (i, k) in keys.iter().enumerate() {
            for opp in 0..4u8 {
                let f = face_key(k, opp);
                let Some(&(first, _, count)) = faces.get(&f) else {
                    continue;
                };
                if count != 2 {
                    continue;
                }
                if first != i as u32 {
                    // The later of the pair links both ways.
                    let (j, jopp, _) = faces[&f];
                    self.locators[i].neighbours[usize::from(opp)] = j;
                    self.locators[j as usize].neighbours[usize::from(jopp)] = i as u32;
                }
            }
        }
    }

    fn tet_bounds(&self, i: usize) -> Aabb {
        let t = &self.tets[i];
        // Vertices: w0 + columns of the inverse of world_to_bary.
        let m = t.world_to_bary.inverse();
        let mut b = Aabb::EMPTY.union_point(t.w0);
        for c in [m.x_axis, m.y_axis, m.z_axis] {
            b = b.union_point(t.w0 + c);
        }
        b
    }

    fn build_cells(&mut self) {
        let ext = self.bounds.extent().max(Vec3::splat(1e-6));
        // Cells per tetrahedron (capped): the shell is a thin sheet in its box, so most
        // cells are empty, and the lists of the occupied ones stay short.
        let target = (self.tets.len() * CELLS_PER_TET).clamp(1, MAX_CELLS) as f32;
        let mut cell = (ext.x * ext.y * ext.z / target).cbrt();
        // Thin shells: no cell finer than a tenth of the thickness.
        cell = cell
            .max(self.thickness * 0.1)
            .max(ext.max_element() / 4096.0);
        let dims = |c: f32| (ext / c).ceil().as_ivec3().max(IVec3::ONE);
        while {
            let d = dims(cell);
            d.x as usize * d.y as usize * d.z as usize > MAX_CELLS
        } {
            cell *= 1.25;
        }
        self.cell_origin = self.bounds.min;
        self.inv_cell = 1.0 / cell;
        self.cell_dims = dims(cell);
        let n = self.cell_dims.x as usize * self.cell_dims.y as usize * self.cell_dims.z as usize;
        let ranges: Vec<(IVec3, IVec3)> = (0..self.tets.len())
            .map(|i| {
                let b = self.tet_bounds(i);
                (self.cell_of(b.min), self.cell_of(b.max))
            })
            .collect();
        let mut count = vec![0u32; n + 1];
        for (lo, hi) in &ranges {
            self.for_cells(*lo, *hi, |c| count[c] += 1);
        }
        let mut start = Vec::with_capacity(n + 1);
        let mut acc = 0u32;
        for c in &count[..n] {
            start.push(acc);
            acc += c;
        }
        start.push(acc);
        let mut fill = start.clone();
        let mut list = vec![0u32; acc as usize];
        for (i, (lo, hi)) in ranges.iter().enumerate() {
            self.for_cells(*lo, *hi, |c| {
                list[fill[c] as usize] = i as u32;
                fill[c] += 1;
            });
        }
        self.cell_start = start;
        self.cell_tets = list;
    }

    fn cell_of(&self, p: Vec3) -> IVec3 {
        ((p - self.cell_origin) * self.inv_cell)
            .floor()
            .as_ivec3()
            .clamp(IVec3::ZERO, self.cell_dims - IVec3::ONE)
    }

    fn for_cells(&self, lo: IVec3, hi: IVec3, mut f: impl FnMut(usize)) {
        let d = self.cell_dims;
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    f(((z * d.y + y) * d.x + x) as usize);
                }
            }
        }
    }

    /// The tetrahedron containing world point `p` and its barycentrics; `hint` (the last
    /// tetrahedron found) is tried first and updated.
    #[inline(always)]
    fn find(&self, p: Vec3, hint: &mut u32) -> Option<(usize, Vec3)> {
        if let Some(t) = self.locators.get(*hint as usize) {
            let mut l = t.bary(p);
            if TetLocator::inside(l) {
                return Some((*hint as usize, l));
            }
            // Lookups along a ray move a little at a time: walk across the face the point
            // lies beyond, a few steps, before searching the grid.
            let mut next = t.towards(l);
            for _ in 0..MAX_WALK_STEPS {
                let Some(n) = self.locators.get(next as usize) else {
                    break;
                };
                l = n.bary(p);
                if TetLocator::inside(l) {
                    *hint = next;
                    return Some((next as usize, l));
                }
                next = n.towards(l);
            }
        }
        self.find_in_cells(p, hint)
    }

    /// The search of [`FabricShell::find`] in the point-location grid's cell of `p`, after
    /// the last tetrahedron and its neighbours missed. Out of line: [`FabricShell::find`]'s
    /// common path, inlined into the lookups, returns its result in registers.
    #[inline(never)]
    fn find_in_cells(&self, p: Vec3, hint: &mut u32) -> Option<(usize, Vec3)> {
        let rel = (p - self.cell_origin) * self.inv_cell;
        if rel.min_element() < 0.0 || !rel.is_finite() {
            return None;
        }
        let c = rel.as_ivec3();
        if c.cmpge(self.cell_dims).any() {
            return None;
        }
        let d = self.cell_dims;
        let cell = ((c.z * d.y + c.y) * d.x + c.x) as usize;
        let (s, e) = (self.cell_start[cell], self.cell_start[cell + 1]);
        for &i in &self.cell_tets[s as usize..e as usize] {
            let Some(t) = self.locators.get(i as usize) else {
                continue;
            };
            if let Some(l) = t.locate(p) {
                *hint = i;
                return Some((i as usize, l));
            }
        }
        None
    }

    /// Patch index coordinates of world point `p` (x, y not yet wrapped), or `None` outside
    /// the shell. `hint` caches the last tetrahedron.
    #[inline]
    pub fn patch_coordinates(&self, p: Vec3, hint: &mut u32) -> Option<Vec3> {
        self.locate(p, hint).map(|s| s.q)
    }

    /// World point `p` located: its tetrahedron and patch index coordinates, or `None`
    /// outside the shell. `hint` (the last tetrahedron found) is tried first and updated.
    #[inline(always)]
    pub fn locate(&self, p: Vec3, hint: &mut u32) -> Option<ShellPoint> {
        self.locate_with_bary(p, hint).map(|(s, _)| s)
    }

    /// [`FabricShell::locate`] with the point's barycentrics.
    #[inline(always)]
    fn locate_with_bary(&self, p: Vec3, hint: &mut u32) -> Option<(ShellPoint, Vec3)> {
        let (i, l) = self.find(p, hint)?;
        let t = &self.tets[i];
        Some((
            ShellPoint {
                tet: i as u32,
                q: t.q0 + t.bary_to_q * l,
            },
            l,
        ))
    }

    /// The affine maps along direction `d` in the tetrahedron of `s` (barycentrics `l`),
    /// found at distance `t`.
    #[inline]
    fn span(&self, s: ShellPoint, l: Vec3, t: f32, d: Vec3) -> TetSpan {
        let (Some(loc), Some(tet)) = (
            self.locators.get(s.tet as usize),
            self.tets.get(s.tet as usize),
        ) else {
            return TetSpan::NONE;
        };
        let dl = loc.world_to_bary * d;
        TetSpan {
            tet: s.tet,
            t_ref: t,
            l,
            dl,
            q: s.q,
            dq: tet.bary_to_q * dl,
        }
    }

    /// The tetrahedron remembered at world point `p` on this thread
    /// ([`FabricShell::remember_vertex`]), or `u32::MAX` (no hint).
    #[inline]
    #[must_use]
    pub fn vertex_hint(&self, p: Vec3) -> u32 {
        let bits = p.to_array().map(f32::to_bits);
        let id = std::ptr::from_ref(self) as usize;
        VERTEX_TETS.with(|slots| {
            let e = slots[vertex_slot(bits)].get();
            if e.shell == id && e.p == bits {
                e.tet
            } else {
                u32::MAX
            }
        })
    }

    /// Remembers, on this thread, that world point `p` was found in tetrahedron `tet`: the
    /// last point of a ray ([`ShellCursor`] when dropped), where a free flight ends in a
    /// scattering vertex and the path's next rays (shadow rays, the next flight) and its
    /// fibre frame ([`FabricShell::fibre_at`]) start. They take it as their first hint
    /// ([`FabricShell::vertex_hint`]) instead of searching the point-location grid.
    ///
    /// A hint only changes which tetrahedron is tried first, so a point within the inside
    /// test's tolerance of two tetrahedra (on a shared face) can land in the other one. What
    /// a ray reads depends only on its own path: the cache is keyed by the shell and the
    /// point's exact bits, and a path's rays read only what earlier rays of the same path
    /// wrote (another path would have to reach the very same point).
    #[inline]
    pub fn remember_vertex(&self, p: Vec3, tet: u32) {
        let bits = p.to_array().map(f32::to_bits);
        let id = std::ptr::from_ref(self) as usize;
        VERTEX_TETS.with(|slots| {
            slots[vertex_slot(bits)].set(VertexTet {
                shell: id,
                p: bits,
                tet,
            });
        });
    }

    /// Trilinear density of the patch at index point `q`, periodic in `x` and `y`, read
    /// through the accessor (the reference the flat tables are tested against).
    #[cfg(test)]
    fn density_at_q(&self, acc: &mut Accessor<'_>, q: Vec3) -> f32 {
        let i = super::floor_ivec3(q);
        let base = self.wrap(i);
        if base.x + 1 < self.dims.x && base.y + 1 < self.dims.y {
            // No corner wraps: the accessor's trilinear lookup (one brick resolve, coherent
            // reads) at the point shifted into the tile. The shift is a whole number of tiles,
            // so `q + shift` and its fractional part are exact: the same value as below.
            return acc.sample_trilinear(q + (base - i).as_vec3());
        }
        let t = q - i.as_vec3();
        let mut v = [0.0f32; 8];
        for (k, vk) in v.iter_mut().enumerate() {
            let d = IVec3::new((k >> 2) as i32, ((k >> 1) & 1) as i32, (k & 1) as i32);
            *vk = acc.value(self.wrap(base + d));
        }
        let lerp = |a: f32, b: f32, s: f32| a + (b - a) * s;
        let y0 = lerp(lerp(v[0], v[4], t.x), lerp(v[2], v[6], t.x), t.y);
        let y1 = lerp(lerp(v[1], v[5], t.x), lerp(v[3], v[7], t.x), t.y);
        lerp(y0, y1, t.z)
    }

    #[inline]
    fn wrap(&self, i: IVec3) -> IVec3 {
        IVec3::new(
            wrap_axis(i.x, self.dims.x),
            wrap_axis(i.y, self.dims.y),
            i.z,
        )
    }

    /// An accessor on the patch's density channel (one per thread or ray).
    #[must_use]
    pub fn density_accessor(&self) -> Accessor<'_> {
        self.patch.accessor(DENSITY)
    }

    /// Fibre volume fraction at world point `p` (0 outside the shell).
    ///
    /// The values are read from the shell's flat copy of the patch (the same values, bit for
    /// bit, as a trilinear lookup through [`Self::density_accessor`]).
    #[inline]
    pub fn density(&self, p: Vec3, hint: &mut u32) -> f32 {
        match self.locate(p, hint) {
            Some(s) => self.density_at(s),
            None => 0.0,
        }
    }

    /// [`FabricShell::density`] at a located point.
    #[inline(always)]
    #[must_use]
    pub fn density_at(&self, s: ShellPoint) -> f32 {
        let q = s.q;
        let i = super::floor_ivec3(q);
        match self.cell_at(i) {
            // Between the yarns the eight voxels are all empty: no table reads.
            Some((k, c)) if self.bit(k) => self.flat_trilinear(c, q - i.as_vec3()),
            _ => 0.0,
        }
    }

    /// An accessor on the patch's tangent channel.
    #[must_use]
    pub fn tangent_accessor(&self) -> Accessor<'_> {
        self.patch.accessor(TANGENT)
    }

    /// Fibre volume fraction at `p` times `sin∠(dir, tangent)` (unit `dir`; docs/references.md §7.3):
    /// the density seen by light travelling along `dir`, with the tangent of the nearest voxel.
    #[inline]
    pub fn projected_density(
        &self,
        tangents: &mut Accessor<'_>,
        p: Vec3,
        dir: Vec3,
        hint: &mut u32,
    ) -> f32 {
        match self.locate(p, hint) {
            Some(s) => self.projected_density_at(Some(tangents), s, dir),
            None => 0.0,
        }
    }

    /// [`FabricShell::projected_density`] at a located point. `tangents` is read only where
    /// the nearest voxel is not a corner of the lookup's cell (coordinates beyond 2²²
    /// voxels); without it, an accessor is made there.
    #[inline(always)]
    pub fn projected_density_at(
        &self,
        tangents: Option<&mut Accessor<'_>>,
        s: ShellPoint,
        dir: Vec3,
    ) -> f32 {
        let q = s.q;
        let v = super::floor_ivec3(q);
        // Between the yarns the eight voxels the filter reads are all empty (densities are
        // never negative): the trilinear value would be 0, so neither it nor the tangent is
        // read. The same value.
        let Some((k, c)) = self.cell_at(v) else {
            return 0.0;
        };
        if !self.bit(k) {
            return 0.0;
        }
        let frac = q - v.as_vec3();
        let density = self.flat_trilinear(c, frac);
        if density.is_nan() || density <= 0.0 {
            return density;
        }
        let local = self.flat_tangent_near(q, v, c, frac, tangents);
        let Some(t) = self.tets.get(s.tet as usize) else {
            return density;
        };
        density * super::look::projected_width(dir, t.tangent_to_world * local)
    }

    /// An upper bound on the density (plain or fibre-projected) a lookup at world point `p`
    /// returns: the largest of the eight voxels its trilinear filter reads, one table read
    /// after point location (0 outside the shell). `hint` as in [`FabricShell::density`].
    /// Where `p` lies on a face shared by two tetrahedra, the lookup may find the other one
    /// and round into the neighbouring cell; the trackers stay unbiased where a bound is
    /// exceeded (weighted tracking) and count it as a violation.
    #[inline]
    pub fn point_bound(&self, p: Vec3, hint: &mut u32) -> f32 {
        match self.locate(p, hint) {
            Some(s) => self.point_bound_at(s),
            None => 0.0,
        }
    }

    /// [`FabricShell::point_bound`] at a located point.
    #[inline(always)]
    #[must_use]
    pub fn point_bound_at(&self, s: ShellPoint) -> f32 {
        self.support_at_q(s.q)
    }

    /// The largest density of the eight voxels a trilinear lookup at patch index point `q`
    /// reads, rounded up (one byte of the [`support_max`] table; 0 outside the shell's layers, where the
    /// patch holds no fibre).
    /// About half the entries are 0 (between the yarns); their bit is read first, from the
    /// small table, and only the others read the large one.
    #[inline(always)]
    fn support_at_q(&self, q: Vec3) -> f32 {
        let Some(k) = self.support_index(q) else {
            return 0.0;
        };
        if !self.bit(k) {
            return 0.0;
        }
        self.support_codes
            .get(k)
            .map_or(0.0, |&c| f32::from(c) * self.support_step)
    }

    /// Bit `k` of `support_bits`.
    #[inline(always)]
    fn bit(&self, k: usize) -> bool {
        self.support_bits
            .get(k >> 6)
            .is_some_and(|w| (w >> (k & 63)) & 1 != 0)
    }

    /// For a lookup whose lower corner is voxel `i` (unwrapped): its entry `k` in the
    /// support table and bits, and where its cell lies in `flat_tiles` / `flat_id`; `None`
    /// outside the shell's layers (as [`FabricShell::support_index`]).
    #[inline(always)]
    fn cell_at(&self, i: IVec3) -> Option<(usize, FlatCell)> {
        let v = self.wrap(i);
        let z = v.z - (self.layer_lo - 1);
        if z < 0 || z > self.dims.z + 1 {
            return None;
        }
        let k = ((z * self.dims.y + v.y) * self.dims.x + v.x) as usize;
        let (x, y) = (v.x as usize, v.y as usize);
        let c = FlatCell::new(x, y, z as usize, self.flat_row_tiles, self.flat_layer);
        Some((k, c))
    }

    /// The flat voxels of `flat_tiles`, in [`flat_index`] order.
    #[inline(always)]
    fn flat_voxels(&self) -> &[FlatVoxel] {
        // SAFETY: `FlatTile` is `repr(C)` around four `FlatVoxel`s of 16 bytes (64 bytes, its
        // alignment, no padding), so `n` tiles are `4 n` contiguous, aligned voxels.
        unsafe {
            std::slice::from_raw_parts(
                self.flat_tiles.as_ptr().cast::<FlatVoxel>(),
                self.flat_tiles.len() * 4,
            )
        }
    }

    /// Trilinear density at fractional position `t` in the cell `c` (from
    /// [`FabricShell::cell_at`]): the accessor's order of operations.
    #[inline(always)]
    fn flat_trilinear(&self, c: FlatCell, t: Vec3) -> f32 {
        let (dx, dy, dz) = (c.dx, c.dy, c.dz);
        let off = [0, dz, dy, dy + dz, dx, dx + dz, dx + dy, dx + dy + dz];
        let voxels = self.flat_voxels();
        debug_assert!(c.f + off[7] < voxels.len());
        let mut v = [0.0f32; 8];
        for (vk, o) in v.iter_mut().zip(off) {
            // SAFETY: `cell_at` gives `c` for a wrapped voxel (x < dims.x, y < dims.y) of a
            // layer `z ≤ dims.z + 1` from `layer_lo − 1`; the table holds `dims.z + 3`
            // layers of tiles covering `(dims.x + 1) × (dims.y + 1)` voxels, so the voxel one
            // step on in each of x, y, z (`off[7]`) is inside it.
            *vk = unsafe { voxels.get_unchecked(c.f + o).density };
        }
        let lerp = |a: f32, b: f32, s: f32| a + (b - a) * s;
        let y0 = lerp(lerp(v[0], v[4], t.x), lerp(v[2], v[6], t.x), t.y);
        let y1 = lerp(lerp(v[1], v[5], t.x), lerp(v[3], v[7], t.x), t.y);
        lerp(y0, y1, t.z)
    }

    /// [`super::tangent_near`] at patch index point `q` (lower corner `v = floor(q)`, flat
    /// cell `c`, fraction `t = q − v`) from `flat_tiles`: the same voxels in the same order.
    /// Where the nearest voxel is not one of the cell's corners (`q` so large that `q + 0.5`
    /// rounds past `v + 1`), the accessor `tangents` is read as before.
    #[inline(always)]
    fn flat_tangent_near(
        &self,
        q: Vec3,
        v: IVec3,
        c: FlatCell,
        t: Vec3,
        tangents: Option<&mut Accessor<'_>>,
    ) -> Vec3 {
        let n = super::floor_ivec3(q + Vec3::splat(0.5)) - v;
        if !(n.cmpge(IVec3::ZERO) & n.cmple(IVec3::ONE)).all() {
            return match tangents {
                Some(a) => super::tangent_near(q, |ijk| a.value_vec3(self.wrap(ijk))),
                None => {
                    let mut a = self.patch.accessor(TANGENT);
                    super::tangent_near(q, |ijk| a.value_vec3(self.wrap(ijk)))
                }
            };
        }
        let voxels = self.flat_voxels();
        let at = |d: IVec3| {
            let i = c.corner(d);
            debug_assert!(i < voxels.len());
            // SAFETY: `d` is in {0, 1}³ and `c` comes from `cell_at`: inside the table, as
            // in `flat_trilinear`.
            Vec3::from_array(unsafe { voxels.get_unchecked(i).tangent })
        };
        let nearest = at(n);
        if nearest != Vec3::ZERO {
            return nearest;
        }
        let mut best = (0.0f32, Vec3::ZERO);
        for k in 0..8 {
            let d = IVec3::new(k >> 2, (k >> 1) & 1, k & 1);
            let w = (if d.x == 1 { t.x } else { 1.0 - t.x })
                * (if d.y == 1 { t.y } else { 1.0 - t.y })
                * (if d.z == 1 { t.z } else { 1.0 - t.z });
            if w > best.0 {
                let tv = at(d);
                if tv != Vec3::ZERO {
                    best = (w, tv);
                }
            }
        }
        best.1
    }

    /// Whether [`FabricShell::support_at_q`] is above 0 (one bit of `support_bits`): false
    /// exactly where the trilinear lookup at `q` reads eight empty voxels.
    #[cfg(test)]
    fn occupied_at_q(&self, q: Vec3) -> bool {
        self.support_index(q).is_some_and(|k| self.bit(k))
    }

    /// The entry of the support table for a lookup at patch index point `q`; `None` outside
    /// the shell's layers.
    #[inline(always)]
    fn support_index(&self, q: Vec3) -> Option<usize> {
        let v = self.wrap(super::floor_ivec3(q));
        let z = v.z - (self.layer_lo - 1);
        if z < 0 || z > self.dims.z + 1 {
            return None;
        }
        Some(((z * self.dims.y + v.y) * self.dims.x + v.x) as usize)
    }

    /// Fibre tangent (world space) and yarn id of the voxel nearest to world point `p`.
    ///
    /// Tangent and id are read from the shell's flat tables where the nearest voxel is a
    /// corner of the lookup's cell inside the tables' layers (the same values, bit for bit,
    /// as through the patch's accessors, which read the others).
    /// The search starts from the tetrahedron remembered at `p` ([`FabricShell::vertex_hint`]:
    /// at a scattering vertex, the one the free flight found there).
    #[must_use]
    pub fn fibre_at(&self, p: Vec3) -> Option<FibreVoxel> {
        let mut hint = self.vertex_hint(p);
        let (i, l) = self.find(p, &mut hint)?;
        let t = &self.tets[i];
        let q = t.q0 + t.bary_to_q * l;
        let (tangent_patch, id) = self.fibre_voxel_at_q(q);
        let world = t.tangent_to_world * tangent_patch;
        Some(FibreVoxel {
            tangent: world.try_normalize().unwrap_or(Vec3::X),
            id,
        })
    }

    /// The patch-unit tangent ([`super::tangent_near`]) and the yarn id of the voxel nearest
    /// to patch index point `q`: from the flat tables where that voxel is a corner of the
    /// cell of `floor(q)` within their layers, else through the patch's accessors.
    #[inline]
    fn fibre_voxel_at_q(&self, q: Vec3) -> (Vec3, f32) {
        let v = super::floor_ivec3(q);
        let n = super::floor_ivec3(q + Vec3::splat(0.5)) - v;
        if let Some((_, c)) = self.cell_at(v) {
            if (n.cmpge(IVec3::ZERO) & n.cmple(IVec3::ONE)).all() {
                let mut tangents = self.patch.accessor(TANGENT);
                let tangent = self.flat_tangent_near(q, v, c, q - v.as_vec3(), Some(&mut tangents));
                if let Some(&id) = self.flat_id.get(c.corner(n)) {
                    return (tangent, id);
                }
            }
        }
        let mut tangents = self.patch.accessor(TANGENT);
        let tangent = super::tangent_near(q, |c| tangents.value_vec3(self.wrap(c)));
        let ijk = self.wrap((q + Vec3::splat(0.5)).floor().as_ivec3());
        let id = self.patch.accessor(ID).value(ijk);
        (tangent, id)
    }

    /// The closed boundary of the shell (bottom, top and side walls), outward-wound.
    #[must_use]
    pub fn boundary_mesh(&self) -> &TriangleMesh {
        &self.boundary
    }

    /// Shell thickness, world units.
    #[must_use]
    pub fn thickness(&self) -> f32 {
        self.thickness
    }

    /// World size of one patch voxel (along the thickness).
    #[must_use]
    pub fn voxel_world_size(&self) -> f32 {
        self.voxel_world
    }

    /// Tiles across the unit UV square.
    #[must_use]
    pub fn tiles(&self) -> [f32; 2] {
        self.tiles
    }

    /// Tetrahedra of the shell map.
    #[must_use]
    pub fn tet_count(&self) -> usize {
        self.tets.len()
    }

    /// World positions of tetrahedron `tet`'s four corners (vertex 0 first; from its
    /// world → barycentric map, so to f32 rounding), or `None` past the last one.
    #[must_use]
    pub fn tet_corners(&self, tet: usize) -> Option<[Vec3; 4]> {
        let t = self.tets.get(tet)?;
        let m = t.world_to_bary.inverse();
        Some([t.w0, t.w0 + m.x_axis, t.w0 + m.y_axis, t.w0 + m.z_axis])
    }

    /// The tetrahedra across tetrahedron `tet`'s four faces (entry `k`: the face opposite
    /// vertex `k` of [`FabricShell::tet_corners`]), `None` on the shell's boundary. Point
    /// location walks across them from the last tetrahedron a ray found. `None` past the
    /// last tetrahedron.
    #[must_use]
    pub fn face_neighbours(&self, tet: usize) -> Option<[Option<usize>; 4]> {
        let n = self.locators.get(tet)?.neighbours;
        Some(n.map(|j| (j != NO_NEIGHBOUR).then_some(j as usize)))
    }

    /// The patch grid (density, tangent, id).
    #[must_use]
    pub fn patch(&self) -> &SparseGrid {
        &self.patch
    }

    /// Density bounds of the patch (min 0, max, mean over the shell's layers).
    #[must_use]
    pub fn density_bounds(&self) -> Bounds {
        self.density_bounds
    }

    /// World volume of the shell (sum of its tetrahedra).
    #[must_use]
    pub fn volume(&self) -> f64 {
        self.tets
            .iter()
            .map(|t| 1.0 / (6.0 * f64::from(t.world_to_bary.determinant().abs())))
            .sum()
    }

    /// A world-space majorant pyramid: bricks overlapping a tetrahedron are bounded by the
    /// patch's density range, all others are empty.
    pub fn majorant_pyramid(&self) -> Result<MajorantPyramid, crate::majorant::MajorantError> {
        let ext = self.bounds.extent().as_dvec3().max(DVec3::splat(1e-9));
        // Bricks of a third of the thickness (so their height ranges are narrow), coarser
        // when the box would need too many.
        let mut brick = (f64::from(self.thickness) / 3.0).max(1e-9);
        let count = |b: f64| (ext / b).ceil().x * (ext / b).ceil().y * (ext / b).ceil().z;
        while count(brick) > MAX_MAJORANT_BRICKS {
            brick *= 1.25;
        }
        let voxel = brick / 8.0;
        // Lattice: voxel (0,0,0)'s centre a brick's apron below the box.
        let origin = self.bounds.min.as_dvec3() - DVec3::splat(brick);
        let index_to_world = glam::DAffine3::from_translation(origin)
            * glam::DAffine3::from_scale(DVec3::splat(voxel));
        let world_to_index = index_to_world.inverse();
        let key_hi = ((ext + DVec3::splat(2.0 * brick)) / brick)
            .ceil()
            .as_ivec3();
        let dims = key_hi + IVec3::ONE;
        // Per brick, the range of patch z (height) that the tetrahedra reach inside it: z is
        // affine in each tetrahedron, so its extremes over the brick box are at box corners.
        let mut z_range =
            vec![(f32::INFINITY, f32::NEG_INFINITY); (dims.x * dims.y * dims.z) as usize];
        let apron = voxel; // trilinear lookups in the pyramid's lattice reach a voxel out
        for (i, t) in self.tets.iter().enumerate() {
            let b = self.tet_bounds(i);
            let lo = (world_to_index.transform_point3(b.min.as_dvec3()) - DVec3::ONE) / 8.0;
            let hi = (world_to_index.transform_point3(b.max.as_dvec3()) + DVec3::ONE) / 8.0;
            let lo = lo.floor().as_ivec3().max(IVec3::ZERO);
            let hi = hi.floor().as_ivec3().min(key_hi);
            let m = t.bary_to_q * t.world_to_bary;
            let row = Vec3::new(m.x_axis.z, m.y_axis.z, m.z_axis.z).as_dvec3();
            let (tz0, tz1) = t.z_range();
            for z in lo.z..=hi.z {
                for y in lo.y..=hi.y {
                    for x in lo.x..=hi.x {
                        let key = IVec3::new(x, y, z);
                        let bmin = index_to_world.transform_point3((key * 8).as_dvec3())
                            - DVec3::splat(apron);
                        let bmax = bmin + DVec3::splat(brick + 2.0 * apron);
                        let (mut z0, mut z1) = (f64::INFINITY, f64::NEG_INFINITY);
                        for c in 0..8 {
                            let p = DVec3::new(
                                if c & 1 != 0 { bmax.x } else { bmin.x },
                                if c & 2 != 0 { bmax.y } else { bmin.y },
                                if c & 4 != 0 { bmax.z } else { bmin.z },
                            );
                            let zc = f64::from(t.q0.z) + row.dot(p - t.w0.as_dvec3());
                            z0 = z0.min(zc);
                            z1 = z1.max(zc);
                        }
                        let (z0, z1) = (z0.max(f64::from(tz0)), z1.min(f64::from(tz1)));
                        if z0 <= z1 {
                            let r = &mut z_range[((z * dims.y + y) * dims.x + x) as usize];
                            r.0 = r.0.min(z0 as f32);
                            r.1 = r.1.max(z1 as f32);
                        }
                    }
                }
            }
        }
        let top = self.layers.len() - 1;
        let layer = |z: f32| ((z.floor() as i32 - self.layer_lo).max(0) as usize).min(top);
        MajorantPyramid::from_brick_bounds(IVec3::ZERO, key_hi, 0.0, world_to_index, |k| {
            let (z0, z1) = z_range[((k.z * dims.y + k.y) * dims.x + k.x) as usize];
            if z0 <= z1 {
                bounds_over_layers(&self.layers, layer(z0), layer(z1))
            } else {
                Bounds::constant(0.0)
            }
        })
    }
}

/// `x` modulo `n` (`n > 0`), without a division when `x` lies within one period of
/// `[0, n)` (a tetrahedron's patch coordinates start in the tile and span a few voxels).
#[inline(always)]
fn wrap_axis(x: i32, n: i32) -> i32 {
    if (0..n).contains(&x) {
        x
    } else if x >= n && x - n < n {
        x - n
    } else if x < 0 && x >= -n {
        x + n
    } else {
        x.rem_euclid(n)
    }
}

/// The mesh's mean world length per unit of texture coordinate, `sqrt(world area / UV
/// area)`, or `None` without texture coordinates or with zero UV area.
#[must_use]
pub fn world_length_per_uv(mesh: &TriangleMesh) -> Option<f64> {
    let uvs = mesh.uvs.as_ref()?;
    let (mut area_w, mut area_uv) = (0.0f64, 0.0f64);
    for tri in &mesh.indices {
        let p = tri.map(|i| mesh.positions[i as usize].as_dvec3());
        let t = tri.map(|i| uvs[i as usize].as_dvec2());
        area_w += (p[1] - p[0]).cross(p[2] - p[0]).length() * 0.5;
        area_uv += (t[1] - t[0]).perp_dot(t[2] - t[0]).abs() * 0.5;
    }
    (area_uv > 0.0 && area_w > 0.0 && area_w.is_finite()).then(|| (area_w / area_uv).sqrt())
}

/// World widths `(x, y)` of one patch voxel when a patch of `dims` voxels across its tile is
/// tiled `tiles` times over the unit UV square of `mesh`: `L / (tiles · n)` with `L` from
/// [`world_length_per_uv`]; `None` without texture coordinates or with zero UV area.
#[must_use]
pub fn tiled_voxel_widths(
    mesh: &TriangleMesh,
    tiles: [f32; 2],
    dims: [u32; 2],
) -> Option<(f64, f64)> {
    let per_uv = world_length_per_uv(mesh)?;
    Some((
        per_uv / (f64::from(tiles[0]) * f64::from(dims[0])),
        per_uv / (f64::from(tiles[1]) * f64::from(dims[1])),
    ))
}

/// A tetrahedron from four (world, patch index) corners, or `None` when degenerate.
/// `patch_voxel` is the patch's voxel size in its own units.
fn make_tet(c: [(DVec3, DVec3); 4], period: Vec3, patch_voxel: DVec3) -> Option<ShellTet> {
    let w = DMat3::from_cols(c[1].0 - c[0].0, c[2].0 - c[0].0, c[3].0 - c[0].0);
    let q = DMat3::from_cols(c[1].1 - c[0].1, c[2].1 - c[0].1, c[3].1 - c[0].1);
    let scale_w = (c[1].0 - c[0].0)
        .length()
        .max((c[2].0 - c[0].0).length())
        .max((c[3].0 - c[0].0).length());
    let dw = w.determinant();
    let dq = q.determinant();
    if !dw.is_finite() || dw.abs() <= 1e-12 * scale_w.powi(3) || dq.is_nan() || dq.abs() <= 1e-12 {
        return None;
    }
    let tangent_to_world = w * q.inverse() * DMat3::from_diagonal(patch_voxel.recip());
    // Reduce x, y of the first corner modulo the tile (lookups wrap): keeps f32 precision.
    let mut q0 = c[0].1.as_vec3();
    q0.x -= (q0.x / period.x).floor() * period.x;
    q0.y -= (q0.y / period.y).floor() * period.y;
    Some(ShellTet {
        w0: c[0].0.as_vec3(),
        world_to_bary: w.inverse().as_mat3(),
        q0,
        bary_to_q: q.as_mat3(),
        tangent_to_world: tangent_to_world.as_mat3(),
    })
}

/// For each vertex, the id of the first vertex at the same position (welds UV seams).
fn welded_ids(mesh: &TriangleMesh) -> Vec<u32> {
    let mut first = std::collections::HashMap::with_capacity(mesh.positions.len());
    mesh.positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let key = [p.x, p.y, p.z].map(|x| if x == 0.0 { 0 } else { x.to_bits() });
            *first.entry(key).or_insert(i as u32)
        })
        .collect()
}

/// Area-weighted vertex normals over welded positions (indexed by welded id `canon`).
fn welded_normals(mesh: &TriangleMesh, canon: &[u32]) -> Vec<DVec3> {
    let mut n = vec![DVec3::ZERO; mesh.positions.len()];
    for tri in &mesh.indices {
        let p = tri.map(|i| mesh.positions[i as usize].as_dvec3());
        let face = (p[1] - p[0]).cross(p[2] - p[0]);
        for &i in tri {
            n[canon[i as usize] as usize] += face;
        }
    }
    n.iter().map(|v| v.normalize_or_zero()).collect()
}

/// Bottom, top and side walls of the shell, with side quads split like the tetrahedra. Each
/// layer's vertex `i` carries the cloth mesh's texture coordinates of vertex `i`, and the
/// bottom and top faces keep the mesh's own vertex indices, so that a path entering the shell
/// reads the cloth's UV there (across a UV seam each side keeps its own; the welded
/// positions are the same, so the surface is the same). Side walls take their vertices' UVs.
fn shell_boundary(
    mesh: &TriangleMesh,
    canon: &[u32],
    normals: &[DVec3],
    thickness: f64,
) -> TriangleMesh {
    let nv = mesh.positions.len() as u32;
    let mut positions = Vec::with_capacity(2 * mesh.positions.len());
    for s in [-0.5, 0.5] {
        for (i, p) in mesh.positions.iter().enumerate() {
            let n = normals[canon[i] as usize];
            positions.push((p.as_dvec3() + n * (s * thickness)).as_vec3());
        }
    }
    let uvs = mesh
        .uvs
        .as_ref()
        .map(|uv| uv.iter().chain(uv.iter()).copied().collect::<Vec<_>>());
    let mut indices = Vec::with_capacity(mesh.indices.len() * 4);
    // Edges by welded ids; a boundary edge is used by one triangle, in its winding x → y.
    let mut edges: std::collections::HashMap<(u32, u32), (u32, u32, u32)> =
        std::collections::HashMap::new();
    for tri in &mesh.indices {
        let [a, b, c] = tri.map(|i| canon[i as usize]);
        if a == b || b == c || a == c {
            continue;
        }
        let [ia, ib, ic] = *tri;
        indices.push([ia, ic, ib]); // bottom, facing −n
        indices.push([ia + nv, ib + nv, ic + nv]); // top, facing +n
        for (x, y) in [(a, b), (b, c), (c, a)] {
            edges.entry((x.min(y), x.max(y))).or_insert((0, x, y)).0 += 1;
        }
    }
    let mut walls: Vec<(u32, u32)> = edges
        .into_values()
        .filter(|(n, _, _)| *n == 1)
        .map(|(_, x, y)| (x, y))
        .collect();
    walls.sort_unstable();
    for (x, y) in walls {
        // The quad (x_b, y_b, y_t, x_t) faces outward (edge × normal); its diagonal joins the
        // lower id's bottom to the higher id's top, as in the prisms' tetrahedra.
        let (xb, yb, xt, yt) = (x, y, x + nv, y + nv);
        if x < y {
            indices.push([xb, yb, yt]);
            indices.push([xb, yt, xt]);
        } else {
            indices.push([xb, yb, xt]);
            indices.push([yb, yt, xt]);
        }
    }
    let mut m = TriangleMesh {
        positions,
        normals: None,
        uvs,
        indices,
    };
    m.make_outward();
    m
}

/// The table of [`FabricShell::point_bound`]: per voxel of layers `layer_lo − 1 ..=
/// layer_lo + dims.z` (x fastest, then y, then z; `dims.x × dims.y` voxels per layer), the
/// largest density of the voxel and its seven upper neighbours (x and y wrapped).
fn support_max(grid: &SparseGrid, dims: IVec3, layer_lo: i32) -> Vec<f32> {
    let (nx, ny, nz) = (dims.x, dims.y, dims.z + 3);
    let idx = |x: i32, y: i32, z: i32| ((z * ny + y) * nx + x) as usize;
    let mut value = vec![0.0f32; (nx * ny * (nz + 1)) as usize];
    for b in 0..grid.brick_count() {
        let data = grid.brick_data(DENSITY, b);
        let o = grid.brick_origin(b);
        for v in 0..crate::grid::BRICK_VOXELS {
            let p = o + IVec3::new((v >> 6) as i32, ((v >> 3) & 7) as i32, (v & 7) as i32);
            let z = p.z - (layer_lo - 1);
            if (0..=nz).contains(&z) {
                let k = idx(p.x.rem_euclid(nx), p.y.rem_euclid(ny), z);
                value[k] = value[k].max(data.get(v, 1, 0));
            }
        }
    }
    let mut out = vec![0.0f32; (nx * ny * nz) as usize];
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                let mut m = 0.0f32;
                for d in 0..8 {
                    let (dx, dy, dz) = (d & 1, (d >> 1) & 1, d >> 2);
                    m = m.max(value[idx((x + dx) % nx, (y + dy) % ny, z + dz)]);
                }
                out[idx(x, y, z)] = m;
            }
        }
    }
    out
}

/// `values` (non-negative) as byte codes `c` with `c · step ≥ v` (the smallest such code,
/// 0 exactly for 0), `step` about 1/255 of the largest value; returns the codes and `step`.
fn quantise_up(values: &[f32]) -> (Vec<u8>, f32) {
    let top = values.iter().copied().fold(0.0f32, f32::max);
    if !(top > 0.0) || !top.is_finite() {
        return (vec![0; values.len()], 1.0);
    }
    let mut step = top / 255.0;
    while 255.0 * step < top {
        step = f32::from_bits(step.to_bits() + 1);
    }
    let codes = values
        .iter()
        .map(|&v| {
            if !(v > 0.0) {
                return 0;
            }
            let mut c = (v / step).ceil().clamp(1.0, 255.0) as u8;
            while c > 1 && f32::from(c - 1) * step >= v {
                c -= 1;
            }
            while c < 255 && f32::from(c) * step < v {
                c += 1;
            }
            c
        })
        .collect();
    (codes, step)
}

/// The shell's flat tables ([`flat_channels`]).
struct FlatTables {
    tiles: Vec<FlatTile>,
    id: Vec<f32>,
    row_tiles: usize,
    layer: usize,
}

/// The shell's flat copies of the patch's density (first component) and tangent channels,
/// interleaved, and of its id channel: layers `layer_lo − 1 ..= layer_lo + dims.z + 1`,
/// `(dims.x + 1) × (dims.y + 1)` voxels a layer in 2 × 2 tiles ([`flat_index`]; a row or
/// column of tiles past the last voxel when that count is odd holds zeros), voxel `(x, y)`
/// holding the patch's `(x mod dims.x, y mod dims.y)`, read through accessors (the values
/// lookups read, bit for bit).
fn flat_channels(grid: &SparseGrid, dims: IVec3, layer_lo: i32) -> FlatTables {
    let (rx, ry, nz) = (dims.x + 1, dims.y + 1, dims.z + 3);
    let row_tiles = (rx as usize).div_ceil(2);
    let layer = 4 * row_tiles * (ry as usize).div_ceil(2);
    let n = layer * nz as usize;
    let mut tiles = vec![FlatTile::default(); n / 4];
    let mut id = vec![0.0f32; n];
    let mut dacc = grid.accessor(DENSITY);
    let mut tacc = grid.accessor(TANGENT);
    let mut iacc = grid.accessor(ID);
    for z in 0..nz {
        for y in 0..ry {
            for x in 0..rx {
                let ijk = IVec3::new(x % dims.x, y % dims.y, z + layer_lo - 1);
                let i = flat_index(x as usize, y as usize, z as usize, row_tiles, layer);
                tiles[i / 4].0[i % 4] = FlatVoxel {
                    density: dacc.value(ijk),
                    tangent: tacc.value_vec3(ijk).to_array(),
                };
                id[i] = iacc.value(ijk);
            }
        }
    }
    FlatTables {
        tiles,
        id,
        row_tiles,
        layer,
    }
}

/// One bit per entry of `support`, set where the entry is above 0 (bit `k & 63` of word
/// `k >> 6`).
fn occupancy_bits(support: &[f32]) -> Vec<u64> {
    let mut bits = vec![0u64; support.len().div_ceil(64)];
    for (k, &v) in support.iter().enumerate() {
        if v > 0.0 {
            bits[k >> 6] |= 1 << (k & 63);
        }
    }
    bits
}

/// Per layer `z = layer_lo + k` (`k < dims.z + 1`, the last one past the shell's top for
/// trilinear lookups there): the largest and the mean density of the layer.
fn layer_stats(grid: &SparseGrid, layer_lo: i32, dims: IVec3) -> Vec<(f32, f32)> {
    let n = dims.z as usize + 1;
    let mut max = vec![0.0f32; n];
    let mut sum = vec![0.0f64; n];
    for b in 0..grid.brick_count() {
        let data = grid.brick_data(DENSITY, b);
        let oz = grid.brick_origin(b).z;
        for v in 0..crate::grid::BRICK_VOXELS {
            let k = (oz + (v & 7) as i32 - layer_lo) as usize;
            if k < n {
                let x = data.get(v, 1, 0);
                max[k] = max[k].max(x);
                sum[k] += f64::from(x);
            }
        }
    }
    let per_layer = f64::from(dims.x) * f64::from(dims.y);
    max.into_iter()
        .zip(sum)
        .map(|(m, s)| (m, ((s / per_layer) as f32).clamp(0.0, m)))
        .collect()
}

/// Bounds of trilinear lookups whose `z` lies between layers `k0` and `k1` (inclusive;
/// a lookup also reads the layer above its floor).
fn bounds_over_layers(layers: &[(f32, f32)], k0: usize, k1: usize) -> Bounds {
    let k1 = (k1 + 1).min(layers.len() - 1);
    let k0 = k0.min(k1);
    let slice = &layers[k0..=k1];
    let max = slice.iter().fold(0.0f32, |m, l| m.max(l.0));
    let mean = slice.iter().map(|l| l.1).sum::<f32>() / slice.len() as f32;
    Bounds {
        min: 0.0,
        max,
        mean: mean.clamp(0.0, max),
    }
}

/// The sorted corner keys of the face of tetrahedron `k` opposite its corner `opp` (shared
/// faces of neighbouring tetrahedra get the same key).
fn face_key(k: &[u32; 4], opp: u8) -> [u32; 3] {
    let mut f = [0u32; 3];
    let mut n = 0;
    for (c, &v) in k.iter().enumerate() {
        if c != usize::from(opp) {
            f[n] = v;
            n += 1;
        }
    }
    f.sort_unstable();
    f
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fabric::{
        generate_patch, voxelise, VoxeliseOptions, WeaveParams, WeavePattern, YarnParams,
    };
    use crate::math::Vec2;
    use crate::sampling::Rng;

    /// The division-free branches of `wrap_axis` agree with `rem_euclid` within a period
    /// of the tile and beyond it.
    #[test]
    fn wrap_axis_matches_rem_euclid() {
        for n in [1, 2, 3, 64, 65] {
            for x in (-3 * n - 2)..(3 * n + 2) {
                assert_eq!(wrap_axis(x, n), x.rem_euclid(n), "x {x} n {n}");
            }
            for x in [i32::MIN, i32::MIN + 1, i32::MAX - 1, i32::MAX] {
                assert_eq!(wrap_axis(x, n), x.rem_euclid(n), "x {x} n {n}");
            }
        }
    }

    /// The flat tables give the accessor's trilinear densities and nearest tangents bit for
    /// bit, at random patch points over several tiles (negative ones too), below, inside and
    /// above the shell's layers, a quarter of them on the voxel lattice and half-lattice
    /// (corners that wrap, nearest voxels on ties).
    #[test]
    fn flat_tables_read_the_accessor_values_bit_for_bit() {
        let yarn = YarnParams::preset("cotton1").expect("preset");
        let mut wp = WeaveParams::new(WeavePattern::from_name("twill").expect("twill"), yarn);
        wp.repeats = [1, 1];
        let fp = generate_patch(&wp, 3).expect("patch");
        let vp = voxelise(&fp, 32, &VoxeliseOptions::default()).expect("voxelise");
        let mesh = TriangleMesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            normals: None,
            uvs: Some(vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(0.0, 1.0),
                Vec2::new(1.0, 1.0),
            ]),
            indices: vec![[0, 1, 2], [1, 3, 2]],
        };
        let shell =
            FabricShell::new(&vp, &mesh, &ShellParams { tiles: [2.0, 2.0] }).expect("shell");
        let d = shell.dims.as_vec3();
        let mut acc = shell.density_accessor();
        let mut tan = shell.tangent_accessor();
        let mut tan2 = shell.tangent_accessor();
        let mut rng = Rng::new(23, 0);
        let (mut occupied, mut tangents) = (0u32, 0u32);
        for n in 0..300_000 {
            let r = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let mut q = Vec3::new(
                (r.x * 6.0 - 3.0) * d.x,
                (r.y * 6.0 - 3.0) * d.y,
                (shell.layer_lo - 3) as f32 + r.z * (d.z + 6.0),
            );
            if n % 4 == 0 {
                q = (q * 2.0).floor() * 0.5;
            }
            let i = super::super::floor_ivec3(q);
            let flat = shell.cell_at(i).filter(|&(k, _)| shell.bit(k));
            assert_eq!(shell.occupied_at_q(q), flat.is_some(), "at {q}");
            let Some((_, c)) = flat else {
                continue;
            };
            occupied += 1;
            let t = q - i.as_vec3();
            let old = shell.density_at_q(&mut acc, q);
            let new = shell.flat_trilinear(c, t);
            assert_eq!(
                old.to_bits(),
                new.to_bits(),
                "density at {q}: {old} against {new}"
            );
            let old = super::super::tangent_near(q, |c| tan.value_vec3(shell.wrap(c)));
            let new = shell.flat_tangent_near(q, i, c, t, Some(&mut tan2));
            assert_eq!(
                old.to_array().map(f32::to_bits),
                new.to_array().map(f32::to_bits),
                "tangent at {q}: {old} against {new}"
            );
            tangents += u32::from(old != Vec3::ZERO);
        }
        assert!(
            occupied > 50_000 && tangents > 20_000,
            "{occupied} {tangents}"
        );
    }

    /// A cell's corner steps ([`FlatCell`]) reach the [`flat_index`] of each neighbour, for
    /// every parity and at the tables' edges, and the tiled tables hold each voxel's density
    /// and tangent once, on its own 64-byte line.
    #[test]
    fn tiled_flat_cells_step_to_their_neighbours() {
        for (rx, ry) in [(5usize, 4usize), (33, 33), (65, 64)] {
            let row_tiles = rx.div_ceil(2);
            let layer = 4 * row_tiles * ry.div_ceil(2);
            let mut seen = vec![false; layer * 3];
            for z in 0..3 {
                for y in 0..ry {
                    for x in 0..rx {
                        let i = flat_index(x, y, z, row_tiles, layer);
                        assert!(!seen[i], "({x}, {y}, {z}) shares {i}");
                        seen[i] = true;
                        assert_eq!(i / 4, flat_index(x & !1, y & !1, z, row_tiles, layer) / 4);
                        if x + 1 >= rx || y + 1 >= ry || z + 1 >= 3 {
                            continue;
                        }
                        let c = FlatCell::new(x, y, z, row_tiles, layer);
                        assert_eq!(c.f, i);
                        for k in 0..8 {
                            let d = IVec3::new(k >> 2, (k >> 1) & 1, k & 1);
                            let (a, b, e) = (d.x as usize, d.y as usize, d.z as usize);
                            assert_eq!(
                                c.corner(d),
                                flat_index(x + a, y + b, z + e, row_tiles, layer),
                                "corner {d} of ({x}, {y}, {z})"
                            );
                        }
                    }
                }
            }
        }
        assert_eq!(std::mem::size_of::<FlatTile>(), 64);
        assert_eq!(std::mem::align_of::<FlatTile>(), 64);
    }

    /// The nearest voxel's tangent and yarn id of `fibre_voxel_at_q` (flat tables where they
    /// hold the voxel) are the accessors' bit for bit, at random patch points over several
    /// tiles, below, inside and above the shell's layers, a quarter of them on the
    /// half-lattice (nearest voxels on ties).
    #[test]
    fn fibre_voxel_reads_the_accessor_values_bit_for_bit() {
        let yarn = YarnParams::preset("cotton1").expect("preset");
        let mut wp = WeaveParams::new(WeavePattern::from_name("twill").expect("twill"), yarn);
        wp.repeats = [1, 1];
        let fp = generate_patch(&wp, 3).expect("patch");
        let vp = voxelise(&fp, 32, &VoxeliseOptions::default()).expect("voxelise");
        let mesh = TriangleMesh {
            positions: vec![
                Vec3::ZERO,
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            normals: None,
            uvs: Some(vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(0.0, 1.0),
                Vec2::new(1.0, 1.0),
            ]),
            indices: vec![[0, 1, 2], [1, 3, 2]],
        };
        let shell =
            FabricShell::new(&vp, &mesh, &ShellParams { tiles: [2.0, 2.0] }).expect("shell");
        let d = shell.dims.as_vec3();
        let mut tan = shell.tangent_accessor();
        let mut ids = shell.patch.accessor(ID);
        let mut rng = Rng::new(29, 0);
        let mut seen = [0u32; 3];
        for n in 0..200_000 {
            let r = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            let mut q = Vec3::new(
                (r.x * 6.0 - 3.0) * d.x,
                (r.y * 6.0 - 3.0) * d.y,
                (shell.layer_lo - 3) as f32 + r.z * (d.z + 6.0),
            );
            if n % 4 == 0 {
                q = (q * 2.0).floor() * 0.5;
            }
            let tangent = super::super::tangent_near(q, |c| tan.value_vec3(shell.wrap(c)));
            let id = ids.value(shell.wrap((q + Vec3::splat(0.5)).floor().as_ivec3()));
            let (t2, id2) = shell.fibre_voxel_at_q(q);
            assert_eq!(
                tangent.to_array().map(f32::to_bits),
                t2.to_array().map(f32::to_bits),
                "tangent at {q}: {tangent} against {t2}"
            );
            assert_eq!(id.to_bits(), id2.to_bits(), "id at {q}: {id} against {id2}");
            if tangent != Vec3::ZERO {
                seen[(id as usize).min(2)] += 1;
            }
        }
        assert!(seen[0] > 5_000 && seen[1] > 5_000, "{seen:?}");
    }

    /// A twill shell over a bumpy 12 × 12 grid of the unit square (no creases: its prisms
    /// do not overlap), 2 × 2 tiles of a 32-voxel patch.
    fn bumpy_shell() -> FabricShell {
        let yarn = YarnParams::preset("cotton1").expect("preset");
        let mut wp = WeaveParams::new(WeavePattern::from_name("twill").expect("twill"), yarn);
        wp.repeats = [1, 1];
        let fp = generate_patch(&wp, 3).expect("patch");
        let vp = voxelise(&fp, 32, &VoxeliseOptions::default()).expect("voxelise");
        let n = 12u32;
        let (mut positions, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::new());
        for j in 0..=n {
            for i in 0..=n {
                let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
                let z = 0.04
                    * (std::f32::consts::TAU * x).sin()
                    * (std::f32::consts::TAU * y * 0.5).cos();
                positions.push(Vec3::new(x, y, z));
                uvs.push(Vec2::new(x, y));
            }
        }
        for j in 0..n {
            for i in 0..n {
                let a = j * (n + 1) + i;
                indices.push([a, a + 1, a + n + 1]);
                indices.push([a + 1, a + n + 2, a + n + 1]);
            }
        }
        let mesh = TriangleMesh {
            positions,
            normals: None,
            uvs: Some(uvs),
            indices,
        };
        FabricShell::new(&vp, &mesh, &ShellParams { tiles: [2.0, 2.0] }).expect("shell")
    }

    /// A random point of the bumpy shell's box, a little beyond it.
    fn point_in_box(shell: &FabricShell, rng: &mut Rng) -> Vec3 {
        let r = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let e = shell.bounds.extent();
        shell.bounds.min - e * 0.05 + r * e * 1.1
    }

    /// Point location from any hint (the tetrahedron of a nearby point, a random one, one
    /// remembered at the point) finds what the search of the point-location grid finds: the
    /// same tetrahedron and patch coordinates bit for bit where the point is inside one
    /// tetrahedron by more than the tolerance, and patch coordinates within 1e-3 voxels where
    /// it lies on a shared face (where either tetrahedron may take it).
    #[test]
    fn hinted_point_location_finds_what_the_grid_search_finds() {
        let shell = bumpy_shell();
        let mut rng = Rng::new(5, 1);
        let (mut inside, mut on_faces) = (0u32, 0u32);
        for n in 0..200_000 {
            let p = point_in_box(&shell, &mut rng);
            let mut none = u32::MAX;
            let cells = shell.locate(p, &mut none);
            let mut hint = match n % 3 {
                0 => {
                    let near = p
                        + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                            * shell.thickness;
                    let mut h = u32::MAX;
                    shell.locate(near, &mut h);
                    h
                }
                1 => (rng.next_f32() * shell.tet_count() as f32) as u32,
                _ => {
                    if let Some(c) = cells {
                        shell.remember_vertex(p, c.tet);
                    }
                    shell.vertex_hint(p)
                }
            };
            let hinted = shell.locate(p, &mut hint);
            let (Some(a), Some(b)) = (cells, hinted) else {
                assert_eq!(cells, hinted, "at {p}");
                continue;
            };
            let l = shell.locators[a.tet()].bary(p);
            let margin = l.min_element().min(1.0 - l.x - l.y - l.z);
            if margin > 1e-4 {
                inside += 1;
                assert_eq!(a, b, "at {p}");
            } else {
                on_faces += 1;
                assert!(
                    (a.q() - b.q()).abs().max_element() < 1e-3,
                    "at {p}: {a:?} {b:?}"
                );
            }
            assert_eq!(hint, b.tet, "the hint is the tetrahedron found");
        }
        assert!(inside > 20_000, "{inside} {on_faces}");
    }

    /// A cursor's locations along a ray are those of `locate` from the running hint (the
    /// origin's remembered tetrahedron first, then the last one found): the same tetrahedron
    /// where the point is inside one by more than the tolerance, and patch coordinates within
    /// 1e-3 voxels (the cursor follows the ray's affine maps inside a tetrahedron, which round
    /// differently). The same distance asked twice in a row (a point bound, then the lookup)
    /// gives the same answer bit for bit; dropping the cursor remembers its last point.
    #[test]
    fn a_cursor_locates_as_the_running_hint_does_and_remembers_its_last_point() {
        let shell = bumpy_shell();
        let mut rng = Rng::new(9, 2);
        let (mut found, mut spans) = (0u32, 0u32);
        for _ in 0..2_000 {
            let o = point_in_box(&shell, &mut rng);
            let d = (point_in_box(&shell, &mut rng) - o).normalize_or_zero();
            let ray = Ray::new(o, d);
            if rng.next_f32() < 0.5 {
                let mut h = u32::MAX;
                if let Some(s) = shell.locate(o, &mut h) {
                    shell.remember_vertex(o, s.tet);
                }
            }
            let mut hint = shell.vertex_hint(o);
            let cursor = ShellCursor::new(&shell, &ray);
            let step = shell.thickness * 0.05;
            let mut t = 0.0f32;
            let mut last = None;
            for _ in 0..100 {
                t += step * rng.next_f32();
                let p = ray.at(t);
                let want = shell.locate(p, &mut hint);
                let got = cursor.locate(t);
                spans += u32::from(cursor.span.get().t_ref != t);
                if rng.next_f32() < 0.5 {
                    let again = cursor.locate(t);
                    assert_eq!(
                        again.map(|s| (s.tet, s.q.to_array().map(f32::to_bits))),
                        got.map(|s| (s.tet, s.q.to_array().map(f32::to_bits))),
                        "asked again at t = {t}"
                    );
                }
                match (want, got) {
                    (None, None) => {}
                    (Some(a), Some(b)) => {
                        found += 1;
                        let l = shell.locators[a.tet()].bary(p);
                        if l.min_element().min(1.0 - l.x - l.y - l.z) > 1e-4 {
                            assert_eq!(a.tet, b.tet, "at t = {t}");
                        }
                        assert!(
                            (a.q - b.q).abs().max_element() < 1e-3,
                            "at t = {t}: {a:?} {b:?}"
                        );
                        hint = b.tet;
                    }
                    _ => {
                        // Only within the tolerance of the shell's boundary.
                        let s = want.or(got).map_or(0, |s| s.tet as usize);
                        let l = shell.locators[s].bary(p);
                        assert!(
                            l.min_element().min(1.0 - l.x - l.y - l.z) < 1e-4,
                            "at t = {t}: {want:?} {got:?}"
                        );
                    }
                }
                last = got.map(|s| (t, s.tet));
            }
            drop(cursor);
            if let Some((t, tet)) = last {
                assert_eq!(shell.vertex_hint(ray.at(t)), tet);
            }
        }
        assert!(found > 20_000 && spans > 10_000, "{found} {spans}");
    }

    /// A cursor's point bound is [`FabricShell::point_bound_at`] of the point the cursor
    /// locates at that distance, and 0 where it locates none (outside the shell); the point
    /// is kept for the lookup that follows at the same distance.
    #[test]
    fn a_cursor_point_bound_is_the_bound_at_its_located_point() {
        let shell = bumpy_shell();
        let mut rng = Rng::new(19, 4);
        let (mut inside, mut outside, mut positive) = (0u32, 0u32, 0u32);
        for _ in 0..1_000 {
            let o = point_in_box(&shell, &mut rng);
            let d = (point_in_box(&shell, &mut rng) - o).normalize_or_zero();
            let ray = Ray::new(o, d);
            let cursor = ShellCursor::new(&shell, &ray);
            let reference = ShellCursor::new(&shell, &ray);
            let mut t = 0.0f32;
            for _ in 0..60 {
                t += shell.thickness * 0.1 * rng.next_f32();
                let bound = cursor.point_bound(t);
                let located = reference.locate(t);
                let want = located.map_or(0.0, |s| shell.point_bound_at(s));
                assert_eq!(bound.to_bits(), want.to_bits(), "at t = {t}");
                assert_eq!(
                    cursor
                        .last
                        .get()
                        .1
                        .map(|s| (s.tet, s.q.to_array().map(f32::to_bits))),
                    located.map(|s| (s.tet, s.q.to_array().map(f32::to_bits))),
                    "kept point at t = {t}"
                );
                match located {
                    Some(_) => inside += 1,
                    None => outside += 1,
                }
                positive += u32::from(bound > 0.0);
            }
        }
        assert!(
            inside > 5_000 && outside > 1_000 && positive > 1_000,
            "{inside} {outside} {positive}"
        );
    }

    /// The per-thread vertex cache answers only for the same shell and the same point bits.
    #[test]
    fn the_vertex_cache_answers_only_for_its_shell_and_point() {
        let a = bumpy_shell();
        let b = bumpy_shell();
        let p = Vec3::new(0.3, 0.4, 0.01);
        a.remember_vertex(p, 17);
        assert_eq!(a.vertex_hint(p), 17);
        assert_eq!(b.vertex_hint(p), u32::MAX);
        let next = Vec3::new(f32::from_bits(p.x.to_bits() + 1), p.y, p.z);
        assert_eq!(a.vertex_hint(next), u32::MAX);
        a.remember_vertex(p, 18);
        assert_eq!(a.vertex_hint(p), 18);
    }

    /// The byte codes of the point bounds are the smallest whose value bounds the float:
    /// 0 exactly for 0, at most one step above, never below.
    #[test]
    fn quantised_support_bounds_from_above_within_a_step() {
        let mut rng = Rng::new(3, 3);
        let mut values: Vec<f32> = (0..100_000)
            .map(|n| match n % 5 {
                0 => 0.0,
                1 => rng.next_f32() * 1e-6,
                _ => rng.next_f32() * 0.73,
            })
            .collect();
        values.push(0.73);
        let (codes, step) = quantise_up(&values);
        for (&v, &c) in values.iter().zip(&codes) {
            let b = f32::from(c) * step;
            assert!(b >= v, "{v} coded {c} decodes to {b}");
            assert_eq!(c == 0, v == 0.0, "{v} coded {c}");
            assert!(
                c <= 1 || f32::from(c - 1) * step < v,
                "{v} coded {c}: not the smallest"
            );
        }
        let shell = bumpy_shell();
        let support = support_max(&shell.patch, shell.dims, shell.layer_lo);
        for (k, &v) in support.iter().enumerate() {
            let c = shell.support_codes[k];
            assert!(f32::from(c) * shell.support_step >= v && shell.bit(k) == (c > 0));
        }
    }
}
