//! Level-of-detail policy for rendering a voxelised fabric: which mip level a view needs, how
//! many patch tiles cover a shell mesh, and how fibre-projected extinction is normalised.
//!
//! These are the decisions a scene makes once, at load time, from plain numbers: the camera's
//! eye and pixel angle, the patch's voxel counts and the world size of the cloth. The mip
//! levels themselves are built by [`VoxelisedPatch::mip`] (course notes §5.3: voxels `2^l`
//! times wider, fibre volume conserved); the shell by [`super::FabricShell`].

use glam::{DAffine3, Vec3};

use super::{FabricPatch, VoxelisedPatch};
use crate::geometry::TriangleMesh;
use crate::math::{Aabb, Mat4};

/// The coarsest patch mip level a scene may ask for, explicitly or through the automatic
/// choice ([`auto_mip`]).
pub const MAX_MIP_LEVEL: u32 = 6;

/// The factor on the isotropic extinction σ_t⁰ = density / attenuation that fibre-projected
/// extinction uses, `4/π`.
///
/// Projected extinction is σ_t(ω) = d · σ_t⁰ · sin∠(ω, t) for fibres along `t` (the projected
/// width of aligned cylinders; see `docs/references.md` §7.3). The mean of `sin θ` over the
/// sphere of directions is `π/4`, so scaling σ_t⁰ by `4/π` makes the direction-averaged
/// extinction equal the isotropic one at the same attenuation.
pub const PROJECTED_EXTINCTION_SCALE: f32 = 4.0 / std::f32::consts::PI;

/// What one pixel of the camera covers: the eye and the angle a pixel subtends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewFootprint {
    /// Eye position, world units.
    pub eye: Vec3,
    /// Angle subtended by one pixel, radians.
    pub pixel_angle: f32,
}

impl ViewFootprint {
    /// The footprint of a camera at `eye` with a vertical field of view of `fov_degrees`
    /// spread over `height` pixels (a height of 0 counts as 1).
    #[must_use]
    pub fn new(eye: Vec3, fov_degrees: f32, height: u32) -> ViewFootprint {
        ViewFootprint {
            eye,
            pixel_angle: fov_degrees.to_radians() / height.max(1) as f32,
        }
    }

    /// Width of a pixel's footprint (world units) at the point of `bounds` nearest to the eye
    /// (zero when the eye is inside `bounds`).
    #[must_use]
    pub fn at(&self, bounds: Aabb) -> f32 {
        let nearest = self.eye.clamp(bounds.min, bounds.max);
        self.eye.distance(nearest) * self.pixel_angle
    }
}

/// Patch tiles across the unit UV square of a shell `mesh` (world space) that give the weave
/// of `patch` its true size, reading scene units as the yarn preset's (centimetres): the
/// mesh's world length per unit of texture coordinate over the patch's tile, rounded, at
/// least 1 per axis. `None` when the mesh has no texture coordinates spanning a non-zero
/// area.
#[must_use]
pub fn true_size_tiles(mesh: &TriangleMesh, patch: &FabricPatch) -> Option<[f32; 2]> {
    true_size_tiles_of(mesh, [f64::from(patch.tile.x), f64::from(patch.tile.y)])
}

/// [`true_size_tiles`] for a patch whose tile is `tile` (patch units; e.g. read from a patch
/// file's metadata).
#[must_use]
pub fn true_size_tiles_of(mesh: &TriangleMesh, tile: [f64; 2]) -> Option<[f32; 2]> {
    let per_uv = super::shell::world_length_per_uv(mesh)?;
    Some([
        ((per_uv / tile[0]).round() as f32).max(1.0),
        ((per_uv / tile[1]).round() as f32).max(1.0),
    ])
}

/// The tiles of a shell: the scene's `requested` tiles when given, else
/// [`true_size_tiles`]. `None` only when nothing was requested and the mesh has no usable
/// texture coordinates.
#[must_use]
pub fn shell_tiles(
    requested: Option<[f32; 2]>,
    mesh: &TriangleMesh,
    patch: &FabricPatch,
) -> Option<[f32; 2]> {
    match requested {
        Some(t) => Some(t),
        None => true_size_tiles(mesh, patch),
    }
}

/// The world width of one level-0 voxel of `vp` and the world box of the fabric.
///
/// For a shell (`shell_mesh` in world space with `tiles`), the width is the geometric mean of
/// the tiled voxel's two widths along the cloth ([`super::shell::tiled_voxel_widths`]; 1 when
/// the mesh has no usable texture coordinates) and the box is the mesh's. For a free-standing
/// patch placed by `xf`, the width is the cube root of the placed voxel's volume and the box
/// surrounds the patch's active voxels.
#[must_use]
pub fn voxel_footprint(
    vp: &VoxelisedPatch,
    xf: Mat4,
    shell_mesh: Option<&TriangleMesh>,
    tiles: Option<[f32; 2]>,
) -> (f32, Aabb) {
    if let (Some(mesh), Some(t)) = (shell_mesh, tiles) {
        let (vx, vy) = super::shell::tiled_voxel_widths(mesh, t, vp.dims).unwrap_or((1.0, 1.0));
        return ((vx * vy).sqrt() as f32, mesh.bounds());
    }
    let placed = DAffine3::from_mat4(xf.as_dmat4()) * vp.grid.index_to_world();
    let voxel = placed.matrix3.determinant().abs().cbrt() as f32;
    let b = vp.grid.active_bbox().map_or(Aabb::EMPTY, |(lo, hi)| {
        Aabb::around_transformed(lo.as_dvec3(), hi.as_dvec3(), &placed)
    });
    (voxel, b)
}

/// Whether mip level `level` halves the voxels across the tile of `vp` exactly `level` times,
/// so that the tile still wraps exactly at that level.
#[must_use]
pub fn halves_exactly(vp: &VoxelisedPatch, level: u32) -> bool {
    vp.dims[0].is_multiple_of(1 << level) && vp.dims[1].is_multiple_of(1 << level)
}

/// The coarsest mip level whose voxels are no wider than a pixel's footprint at the fabric's
/// nearest point, when that footprint spans `footprint_in_voxels` level-0 voxels (course
/// notes §5.3): `floor(log2(footprint))`, 0 below two voxels, capped at [`MAX_MIP_LEVEL`] and
/// lowered until the level [`halves_exactly`].
#[must_use]
pub fn auto_mip(vp: &VoxelisedPatch, footprint_in_voxels: f32) -> u32 {
    let wanted = if footprint_in_voxels >= 2.0 {
        footprint_in_voxels.log2().floor() as u32
    } else {
        0
    };
    let mut l = wanted.min(MAX_MIP_LEVEL);
    while l > 0 && !halves_exactly(vp, l) {
        l -= 1;
    }
    l
}
