//! `voxel` interiors: a scalar density grid read from an OpenVDB file, placed by the object
//! transform.

use glam::DAffine3;

use super::field_params::FieldParams;
use super::grids::{self, DensityGridRef};
use super::heterogeneous::{field_textures, BaseParams, DensityKeys, DensityLook};
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
    let params = FieldParams::read(
        at,
        d.albedo.as_ref(),
        d.attenuation.as_ref(),
        d.density.as_ref(),
        d.nee.as_deref(),
        d.projection.as_deref(),
    )?;
    params.refuse_unused_tracking(at, d.tracking.as_ref())?;
    let base = BaseParams::read(at, d.base_albedo.as_ref(), d.base_attenuation.as_ref())?;
    let (density, attenuation) = params.look_extinction();
    let keys = DensityKeys {
        albedo: params.look_albedo(d.albedo.as_ref()),
        albedo_mode: d.albedo_mode.as_deref(),
        phase: d.phase.as_ref(),
        base_albedo: base.albedo(),
        base_attenuation: base.attenuation(),
        tracking: d.tracking.as_ref(),
    };
    let mut look = DensityLook::read(at, &keys, density, attenuation)?;
    if params.surface.is_some() {
        look = look.without_local_bounds();
    }
    let xf = DAffine3::from_mat4(placement.xf.as_dmat4());
    let (field, pyramid, density_ref) = voxel_field(at, d, xf)?;
    let mode = look.mode;
    if !grids::wanted(d) && !base.is_textured() {
        return Ok(params.finish(look.into_medium(at, field, pyramid)?, mode));
    }
    if params.is_textured() && grids::wanted(d) {
        return Err(at.invalid(format!(
            "{}: textured albedo/attenuation/density cannot be combined with albedo or emission grids (use constant values, or the albedo grid alone)",
            at.owner
        )));
    }
    let albedo = grids::albedo_grid(at, d, &density_ref, xf, look.mode, look.mean_cosine())?;
    let emission = grids::emission_grid(at, d, &density_ref, xf)?;
    if base.is_textured() {
        // The field and the base medium as a two-component mixture, the base (and the
        // field's own textured parameters) read per walk.
        let textures = vec![field_textures(&params, &look), base.textures(&look)];
        let medium =
            look.into_mixture(at, field, pyramid, albedo, emission, d.tracking.as_ref())?;
        return super::mixture::with_base_textures(at, medium, textures, params.nee);
    }
    let medium = look.into_mixture(at, field, pyramid, albedo, emission, d.tracking.as_ref())?;
    Ok(params.finish(medium, mode))
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
