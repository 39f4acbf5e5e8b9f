//! `voxel` interiors: a scalar density grid read from an OpenVDB file, placed by the object
//! transform.

use glam::DAffine3;

use super::grids::{self, DensityGridRef};
use super::heterogeneous::{field_keys, FieldLook};
use super::{BuiltInterior, Placement, Site};
use crate::majorant::MajorantPyramid;
use crate::medium::DensityField;
use crate::scene::desc::VoxelDesc;
use crate::scene::SceneError;

/// The medium of a `voxel` interior.
pub(super) fn build(
    at: &Site,
    d: &VoxelDesc,
    placement: &Placement<'_>,
) -> Result<BuiltInterior, SceneError> {
    let look = FieldLook::read(at, &field_keys!(d))?;
    let xf = DAffine3::from_mat4(placement.xf.as_dmat4());
    let (field, pyramid, density_ref) = voxel_field(at, d, xf)?;
    let grids = if grids::wanted(d) {
        if look.params.is_textured() {
            return Err(at.invalid(format!(
                "{}: textured albedo/attenuation/density cannot be combined with albedo or emission grids (use constant values, or the albedo grid alone)",
                at.owner
            )));
        }
        let (mode, mean_cosine) = (look.look.mode, look.look.mean_cosine());
        let albedo = grids::albedo_grid(at, d, &density_ref, xf, mode, mean_cosine)?;
        Some((albedo, grids::emission_grid(at, d, &density_ref, xf)?))
    } else {
        None
    };
    look.build(at, field, pyramid, grids, d.tracking.as_ref())
}

/// The grid named by `grid` (default "density") of the file, checked (finite, scalar,
/// non-negative, not a level set), placed by `xf`, with its majorant pyramid and what the
/// extra grids are checked against.
fn voxel_field(
    at: &Site,
    d: &VoxelDesc,
    xf: DAffine3,
) -> Result<(DensityField, MajorantPyramid, DensityGridRef), SceneError> {
    let owner = &at.owner;
    let file = d.file.as_ref().ok_or_else(|| {
        at.invalid(format!(
            "{owner}: a voxel interior needs `file` (an OpenVDB file)"
        ))
    })?;
    let path = at.ctx.resolve(file);
    let name = d.grid.as_deref().unwrap_or("density");
    let vg = grids::read_grid(at, &path, name)?;
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
    let density_ref = DensityGridRef {
        path: path.clone(),
        name: name.to_string(),
        map: vg.grid.index_to_world(),
    };
    let mut grid = vg.grid;
    let placed = xf * grid.index_to_world();
    grid.set_index_to_world(placed)
        .map_err(|e| at.invalid(format!("{owner}: placing grid `{name}`: {e}")))?;
    let pyramid = MajorantPyramid::from_grid(&grid, 0)
        .map_err(|e| at.invalid(format!("{owner}: grid `{name}`: {e}")))?;
    grid.prepare_padded(0);
    Ok((
        DensityField::Grid { grid, channel: 0 },
        pyramid,
        density_ref,
    ))
}
