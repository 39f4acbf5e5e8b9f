//! `voxel` interiors: a scalar density grid read from an OpenVDB file, placed by the object
//! transform.

use glam::DAffine3;

use super::heterogeneous::{DensityKeys, DensityLook};
use super::{extinction_and_nee, Placement, Site};
use crate::majorant::MajorantPyramid;
use crate::medium::{DensityField, Medium, NeeStrategy};
use crate::scene::desc::VoxelDesc;
use crate::scene::SceneError;

/// The medium of a `voxel` interior.
pub(super) fn build(
    at: &Site,
    d: &VoxelDesc,
    placement: &Placement<'_>,
) -> Result<(Medium, NeeStrategy), SceneError> {
    let (density, attenuation, nee) =
        extinction_and_nee(at, d.density, d.attenuation, d.nee.as_deref())?;
    let keys = DensityKeys {
        albedo: d.albedo,
        albedo_mode: d.albedo_mode.as_deref(),
        phase: d.phase.as_ref(),
        base_albedo: d.base_albedo,
        base_attenuation: d.base_attenuation,
        tracking: d.tracking.as_ref(),
    };
    let look = DensityLook::read(at, &keys, density, attenuation)?;
    let xf = DAffine3::from_mat4(placement.xf.as_dmat4());
    let (field, pyramid) = voxel_field(at, d, xf)?;
    Ok((look.into_medium(at, field, pyramid)?, nee))
}

/// The grid named by `grid` (default "density") of the file, checked (finite, scalar,
/// non-negative), placed by `xf`, with its majorant pyramid.
fn voxel_field(
    at: &Site,
    d: &VoxelDesc,
    xf: DAffine3,
) -> Result<(DensityField, MajorantPyramid), SceneError> {
    let owner = &at.owner;
    let file = d.file.as_ref().ok_or_else(|| {
        at.invalid(format!(
            "{owner}: a voxel interior needs `file` (an OpenVDB file)"
        ))
    })?;
    let path = at.ctx.resolve(file);
    let name = d.grid.as_deref().unwrap_or("density");
    let mut grids = crate::vdb::read_vdb_grids(&path, &[name]).map_err(|e| at.failed(&e))?;
    let vg = grids
        .pop()
        .ok_or_else(|| at.invalid(format!("{owner}: {}: no grid {name}", path.display())))?;
    if vg.class == "level set" {
        return Err(at.invalid(format!(
            "{owner}: {}: grid `{name}` is a level set (class `level set`: signed distances, negative inside), not a density; use it as the object's boundary (shape = \"levelset\", grid = \"{name}\") and give the interior a fog volume (`velour voxelize --fog`)",
            path.display()
        )));
    }
    vg.check_finite()
        .map_err(|e| at.invalid(format!("{owner}: {}: {e}", path.display())))?;
    if vg.grid.channel_kind(0) != Some(crate::grid::ChannelKind::Scalar) {
        return Err(at.invalid(format!(
            "{owner}: {}: grid `{name}` is not a scalar grid ({})",
            path.display(),
            vg.value_type.name()
        )));
    }
    let stats = vg.stats();
    if stats.min[0] < 0.0 || vg.grid.background(0) < 0.0 {
        return Err(at.invalid(format!(
            "{owner}: {}: grid `{name}` has negative densities (min {})",
            path.display(),
            stats.min[0]
        )));
    }
    let mut grid = vg.grid;
    let placed = xf * grid.index_to_world();
    grid.set_index_to_world(placed)
        .map_err(|e| at.invalid(format!("{owner}: placing grid `{name}`: {e}")))?;
    let pyramid = MajorantPyramid::from_grid(&grid, 0)
        .map_err(|e| at.invalid(format!("{owner}: grid `{name}`: {e}")))?;
    Ok((DensityField::Grid { grid, channel: 0 }, pyramid))
}
