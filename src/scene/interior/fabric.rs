//! `fabric` interiors: a woven patch (course notes §3) generated and voxelised at load time
//! into density, tangent and yarn-id channels, shaded with one fibre phase function per yarn
//! family. Free-standing (`shape = "bounds"`, placed by the object transform) or a shell
//! tiled over a mesh's texture coordinates (notes §3.3). The level-of-detail choices (mip
//! level, tiles, extinction normalisation) are the fabric module's ([`crate::fabric::lod`]).

use glam::DAffine3;

use super::{extinction_and_nee, Placement, Site};
use crate::fabric::lod::{self, MAX_MIP_LEVEL};
use crate::fabric::{
    generate_patch, voxelise, FabricLook, FabricShading, FabricShell, FibreExtinction,
    FibrePhaseParams, ShellParams, VoxeliseOptions, WeaveParams, WeavePattern, YarnParams,
};
use crate::majorant::MajorantPyramid;
use crate::medium::{DensityField, HeterogeneousMedium, Medium, NeeStrategy};
use crate::phase::PhaseFunction;
use crate::scene::desc::{FabricDesc, MipValue, TilesValue};
use crate::scene::SceneError;
use crate::spectrum::Rgb;
use crate::tracking::{DensityCoefficients, TrackingConfig};

/// The medium of a `fabric` interior.
pub(super) fn build(
    at: &Site,
    d: &FabricDesc,
    placement: &Placement<'_>,
) -> Result<(Medium, NeeStrategy), SceneError> {
    let (density, attenuation, nee) =
        extinction_and_nee(at, d.density, d.attenuation, d.nee.as_deref())?;
    if placement.rest_mesh.is_none() && placement.rest_bounds.is_some() {
        return Err(at.invalid(format!("{}: a fabric interior needs shape = \"bounds\" (a free-standing patch) or shape = \"mesh\" (a shell tiled over the mesh's texture coordinates)", at.owner)));
    }
    let medium = build_fabric(at, d, placement, attenuation, density)?;
    Ok((Medium::Heterogeneous(Box::new(medium)), nee))
}

/// How a fabric interior was built, for the render log (`None` for other media and for a
/// full-resolution free-standing patch).
pub(in crate::scene) fn fabric_note(m: &Medium) -> Option<String> {
    let Medium::Heterogeneous(h) = m else {
        return None;
    };
    let look = h.fabric.as_ref()?;
    Some(match &h.field {
        DensityField::Shell(s) => format!(
            "fabric shell of {} tetrahedra, {} × {} tiles, {:.4} thick, patch mip level {}",
            s.tet_count(),
            s.tiles()[0],
            s.tiles()[1],
            s.thickness(),
            look.mip_level
        ),
        _ if look.mip_level > 0 => {
            format!("free-standing fabric patch, mip level {}", look.mip_level)
        }
        _ => return None,
    })
}

/// The requested mip: `Ok(None)` for none or "auto", else the level, checked against
/// [`MAX_MIP_LEVEL`].
fn requested_mip(at: &Site, mip: Option<&MipValue>) -> Result<Option<u32>, SceneError> {
    let owner = &at.owner;
    match mip {
        None => Ok(None),
        Some(MipValue::Level(l)) if (0..=i64::from(MAX_MIP_LEVEL)).contains(l) => {
            Ok(Some(*l as u32))
        }
        Some(MipValue::Level(l)) => Err(at.invalid(format!(
            "{owner}.mip = {l} is outside [0, {MAX_MIP_LEVEL}] (or \"auto\")"
        ))),
        Some(MipValue::Named(n)) if n == "auto" => Ok(None),
        Some(MipValue::Named(n)) => Err(at.invalid(format!(
            "{owner}.mip = \"{n}\" is unknown (expected a level 0–{MAX_MIP_LEVEL} or \"auto\")"
        ))),
    }
}

/// Generates, voxelises, mips and places the patch (a shell over the placement's mesh, or
/// the free-standing patch), and sets its coefficients: the density is the fibre volume
/// fraction; σ_t⁰ = density / attenuation per unit fraction (× 4/π with fibre-projected
/// extinction, so that its mean over directions is the same); the fibre phase functions
/// carry the yarn colours, so σ_s⁰ = σ_t⁰.
fn build_fabric(
    at: &Site,
    d: &FabricDesc,
    placement: &Placement<'_>,
    attenuation: Rgb,
    density: f32,
) -> Result<HeterogeneousMedium, SceneError> {
    let owner = &at.owner;
    let xf = placement.xf;
    let bad = |e: &dyn std::fmt::Display| at.failed(e);
    let pattern =
        WeavePattern::from_name(d.pattern.as_deref().unwrap_or("plain")).map_err(|e| bad(&e))?;
    let yarn = YarnParams::preset(d.yarn.as_deref().unwrap_or("cotton1")).map_err(|e| bad(&e))?;
    let resolution = d.resolution.unwrap_or(128);
    if !(8..=1024).contains(&resolution) {
        return Err(at.invalid(format!(
            "{owner}.resolution = {resolution} is outside [8, 1024]"
        )));
    }
    let repeats = d.repeats.unwrap_or(1);
    if !(1..=16).contains(&repeats) {
        return Err(at.invalid(format!("{owner}.repeats = {repeats} is outside [1, 16]")));
    }
    let flyaways = at.range("flyaways", d.flyaways.unwrap_or(1.0), 0.0, 100.0)?;
    let mut params = WeaveParams::new(pattern, yarn);
    params.repeats = [repeats, repeats];
    params.flyaway_fraction = flyaways;
    params.warp_albedo = at.unit_colour("warp_albedo", d.warp_albedo, params.warp_albedo)?;
    params.weft_albedo = at.unit_colour("weft_albedo", d.weft_albedo, params.weft_albedo)?;
    let patch = generate_patch(&params, d.seed.unwrap_or(1)).map_err(|e| bad(&e))?;
    let mip = requested_mip(at, d.mip.as_ref())?;
    let auto_mip = matches!(&d.mip, Some(MipValue::Named(_)));
    let opts = VoxeliseOptions {
        // Mip levels are summed from the fine accumulators.
        keep_accumulators: auto_mip || mip.is_some_and(|l| l > 0),
        ..VoxeliseOptions::default()
    };
    let vp = voxelise(&patch, resolution, &opts).map_err(|e| bad(&e))?;
    // The shell's world mesh and tiles, or the free-standing placement.
    let shell_mesh = placement.rest_mesh.map(|m| m.transformed(xf));
    let requested_tiles = d.tiles.map(|t| match t {
        TilesValue::Uniform(t) => [t, t],
        TilesValue::PerAxis(t) => t,
    });
    let tiles = match &shell_mesh {
        None => {
            if requested_tiles.is_some() {
                return Err(at.invalid(format!(
                    "{owner}.tiles: only a fabric shell on a mesh is tiled (shape = \"mesh\")"
                )));
            }
            None
        }
        Some(mesh) => Some(lod::shell_tiles(requested_tiles, mesh, &patch).ok_or_else(|| {
            at.invalid(format!("{owner}: a fabric shell needs a mesh with texture coordinates (u, v) spanning a non-zero area"))
        })?),
    };
    let level = if auto_mip {
        let (voxel_world, bounds) = lod::voxel_footprint(&vp, xf, shell_mesh.as_ref(), tiles);
        lod::auto_mip(&vp, placement.view.at(bounds) / voxel_world.max(1e-30))
    } else {
        let l = mip.unwrap_or(0);
        if !lod::halves_exactly(&vp, l) {
            return Err(at.invalid(format!("{owner}.mip = {l}: the patch has {} × {} voxels across its tile, which {l} halvings do not divide exactly; use a resolution that is a multiple of {}", vp.dims[0], vp.dims[1], 1u32 << l)));
        }
        l
    };
    let vp = if level > 0 {
        vp.mip(level).map_err(|e| bad(&e))?
    } else {
        vp
    };
    let patch_voxel_size = vp.voxel_size;
    let (field, pyramid) = match (shell_mesh, tiles) {
        (Some(mesh), Some(tiles)) => {
            // A shell over the cloth mesh (notes §3.3), in world space.
            let shell =
                FabricShell::new(&vp, &mesh, &ShellParams { tiles }).map_err(|e| bad(&e))?;
            let pyramid = shell.majorant_pyramid().map_err(|e| bad(&e))?;
            (DensityField::Shell(Box::new(shell)), pyramid)
        }
        _ => {
            let mut grid = vp.grid;
            let placed = DAffine3::from_mat4(xf.as_dmat4()) * grid.index_to_world();
            grid.set_index_to_world(placed).map_err(|e| bad(&e))?;
            let pyramid = MajorantPyramid::from_grid(&grid, crate::fabric::voxelise::DENSITY)
                .map_err(|e| bad(&e))?;
            let field = DensityField::Grid {
                grid,
                channel: crate::fabric::voxelise::DENSITY,
            };
            (field, pyramid)
        }
    };
    let shading =
        FabricShading::from_patch(&FibrePhaseParams::default(), &patch).map_err(|e| bad(&e))?;
    let extinction = match d.extinction.as_deref().unwrap_or("fibre") {
        "fibre" => FibreExtinction::Projected,
        "isotropic" => FibreExtinction::Isotropic,
        other => {
            return Err(at.invalid(format!(
                "{owner}.extinction = \"{other}\" is unknown (expected \"fibre\" or \"isotropic\")"
            )))
        }
    };
    let scale = extinction.sigma_scale();
    let sigma_t = attenuation.map(|d| density * scale / d);
    let mut medium = HeterogeneousMedium {
        field,
        pyramid,
        coefficients: DensityCoefficients::new(sigma_t, sigma_t),
        phase: PhaseFunction::henyey_greenstein(0.0).map_err(|e| bad(&e))?,
        tracking: TrackingConfig::default(),
        fabric: Some(Box::new(FabricLook {
            tangent_channel: crate::fabric::voxelise::TANGENT,
            id_channel: crate::fabric::voxelise::ID,
            patch_voxel_size,
            mip_level: level,
            extinction,
            shading,
        })),
    };
    medium.attach_local_bounds().map_err(|e| bad(&e))?;
    Ok(medium)
}
