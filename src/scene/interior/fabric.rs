//! `fabric` interiors: a woven patch (course notes §3) generated and voxelised at load time
//! into density, tangent and yarn-id channels, or read from a patch file `velour weave` wrote
//! (`file`, checked against the file's metadata), shaded with one fibre phase function per
//! yarn family. Free-standing (`shape = "bounds"`, placed by the object transform) or a shell
//! tiled over a mesh's texture coordinates (notes §3.3). The level-of-detail choices (mip
//! level, tiles, extinction normalisation) are the fabric module's ([`crate::fabric::lod`]).
//! The yarn colours (`warp_albedo`, `weft_albedo`, `pile_albedo`) may be textures on a shell,
//! read at each walk's entry point ([`crate::medium::FabricInterior`], docs/textures.md).

use std::sync::Arc;

use glam::DAffine3;

use super::fabric_source::{generate, read_file, PatchSource};
use super::tracking::grey_extinction;
use super::{extinction_and_nee, BuiltInterior, Placement, Site};
use crate::fabric::lod::{self, MAX_MIP_LEVEL};
use crate::fabric::{
    FabricLook, FabricShading, FabricShell, FibreExtinction, FibrePhaseParams, ShellParams,
    VoxelisedPatch, YarnColours,
};
use crate::geometry::TriangleMesh;
use crate::majorant::MajorantPyramid;
use crate::math::Vec2;
use crate::medium::{
    DensityField, DyedFabric, FabricInterior, HeterogeneousMedium, Medium, MipChain, WalkInterior,
};
use crate::phase::PhaseFunction;
use crate::scene::desc::{ColorInput, FabricDesc, FibrePhaseDesc, MipValue, TilesValue};
use crate::scene::SceneError;
use crate::spectrum::Rgb;
use crate::tracking::{DensityCoefficients, TrackingConfig};

/// The medium of a `fabric` interior: fixed, or, when a yarn colour is a texture, resolved
/// per walk (its stand-in the fabric in the textures' mean colours).
pub(super) fn build(
    at: &Site,
    d: &FabricDesc,
    placement: &Placement<'_>,
) -> Result<BuiltInterior, SceneError> {
    let (density, attenuation, nee) =
        extinction_and_nee(at, d.density, d.attenuation, d.nee.as_deref())?;
    if placement.rest_mesh.is_none() && placement.rest_bounds.is_some() {
        return Err(at.invalid(format!("{}: a fabric interior needs shape = \"bounds\" (a free-standing patch) or shape = \"mesh\" (a shell tiled over the mesh's texture coordinates)", at.owner)));
    }
    let (mut medium, colours) = build_fabric(at, d, placement, attenuation, density)?;
    medium.tracking.sun_lean = d.sun_lean.unwrap_or(true);
    if !colours.is_textured() {
        return Ok(BuiltInterior {
            medium: Medium::Heterogeneous(Box::new(medium)),
            nee,
            walk: None,
        });
    }
    let shared = Arc::new(medium);
    Ok(BuiltInterior {
        medium: Medium::Dyed(DyedFabric {
            medium: Arc::clone(&shared),
            colours: colours.at(Vec2::ZERO, f32::INFINITY),
        }),
        nee,
        walk: Some(WalkInterior::Fabric(FabricInterior {
            medium: shared,
            colours,
        })),
    })
}

/// The yarn colour keys: constants, or (on a shell) textures; `defaults` are the patch's
/// own colours (generator defaults or the patch file's).
fn yarn_colours(
    at: &Site,
    d: &FabricDesc,
    placement: &Placement<'_>,
    defaults: [Rgb; 3],
    beta_n: f32,
) -> Result<YarnColours, SceneError> {
    let p = at.params();
    let read = |key: &str, input: Option<&ColorInput>, default: Rgb| {
        if let (Some(ColorInput::Texture(t)), None) = (input, placement.rest_mesh) {
            return Err(at.invalid(format!(
                "{}.{key} is a texture ({}) but a free-standing patch (shape = \"bounds\") has no texture coordinates to read it at; use a constant colour, or a shell over a mesh with u, v (shape = \"mesh\")",
                at.owner, t.texture
            )));
        }
        p.colour(key, input, default, 0.0, 1.0)
    };
    Ok(YarnColours {
        maps: [
            read("warp_albedo", d.warp_albedo.as_ref(), defaults[0])?,
            read("weft_albedo", d.weft_albedo.as_ref(), defaults[1])?,
            read("pile_albedo", d.pile_albedo.as_ref(), defaults[2])?,
        ],
        beta_n,
    })
}

/// How a fabric interior was built, for the render log (`None` for other media and for a
/// full-resolution free-standing patch).
pub(in crate::scene) fn fabric_note(m: &Medium) -> Option<String> {
    let (h, dyed) = match m {
        Medium::Heterogeneous(h) => (&**h, ""),
        Medium::Dyed(f) => (
            &*f.medium,
            "; yarn colours textured, read at each walk's entry point",
        ),
        _ => return None,
    };
    let note = fabric_level_note(h)?;
    Some(format!("{note}{dyed}"))
}

/// [`fabric_note`]'s description of the fabric's levels and shape.
fn fabric_level_note(h: &HeterogeneousMedium) -> Option<String> {
    let look = h.fabric.as_ref()?;
    if let Some(chain) = h.mips.as_ref().filter(|c| !c.levels.is_empty()) {
        return Some(format!(
            "fabric mip level chosen per ray from the ray cone's footprint: levels {}–{} (a level-{} voxel is {:.4} wide)",
            look.mip_level,
            look.mip_level as usize + chain.levels.len(),
            look.mip_level,
            chain.voxel_width
        ));
    }
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

/// The fibre scattering parameters of `fibre_phase = { ... }` (the defaults of
/// [`FibrePhaseParams`] for keys not given).
fn fibre_phase(at: &Site, d: Option<&FibrePhaseDesc>) -> Result<FibrePhaseParams, SceneError> {
    let mut p = FibrePhaseParams::default();
    let Some(d) = d else {
        return Ok(p);
    };
    let key = |k: &str| format!("fibre_phase.{k}");
    if let Some(v) = d.eta {
        p.eta = at.range(&key("eta"), v, 1.0, 3.0)?;
    }
    if let Some(v) = d.beta_m {
        p.beta_m = at.range(&key("beta_m"), v, 0.01, 1.0)?;
    }
    if let Some(v) = d.beta_n {
        p.beta_n = at.range(&key("beta_n"), v, 0.01, 1.0)?;
    }
    if let Some(v) = d.alpha {
        p.alpha = at.range(&key("alpha"), v, -0.2, 0.2)?;
    }
    if let Some(v) = d.diffuse_weight {
        p.diffuse_weight = at.range(&key("diffuse_weight"), v, 0.0, 1.0)?;
    }
    Ok(p)
}

/// What every level of one fabric interior shares.
struct Shared<'a> {
    shell_mesh: Option<&'a TriangleMesh>,
    tiles: Option<[f32; 2]>,
    xf: crate::math::Mat4,
    sigma_t: Rgb,
    extinction: FibreExtinction,
    shading: &'a FabricShading,
}

/// The medium of one mip level `vp` of the patch: a shell over the mesh or the free-standing
/// placed grid, its majorant pyramid, the fibre look and the local bounds.
fn level_medium(
    at: &Site,
    vp: VoxelisedPatch,
    s: &Shared<'_>,
) -> Result<HeterogeneousMedium, SceneError> {
    let bad = |e: &dyn std::fmt::Display| at.failed(e);
    let level = vp.level;
    let patch_voxel_size = vp.voxel_size;
    let (field, pyramid) = match (s.shell_mesh, s.tiles) {
        (Some(mesh), Some(tiles)) => {
            // A shell over the cloth mesh (notes §3.3), in world space.
            let shell = FabricShell::new(&vp, mesh, &ShellParams { tiles }).map_err(|e| bad(&e))?;
            let pyramid = shell.majorant_pyramid().map_err(|e| bad(&e))?;
            (DensityField::Shell(Box::new(shell)), pyramid)
        }
        _ => {
            let mut grid = vp.grid;
            let placed = DAffine3::from_mat4(s.xf.as_dmat4()) * grid.index_to_world();
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
    let mut medium = HeterogeneousMedium {
        field,
        pyramid,
        coefficients: DensityCoefficients::new(s.sigma_t, s.sigma_t),
        phase: PhaseFunction::henyey_greenstein(0.0).map_err(|e| bad(&e))?,
        tracking: TrackingConfig {
            local_bounds: grey_extinction(&DensityCoefficients::new(s.sigma_t, s.sigma_t)),
            ..TrackingConfig::default()
        },
        fabric: Some(Box::new(FabricLook {
            tangent_channel: crate::fabric::voxelise::TANGENT,
            id_channel: crate::fabric::voxelise::ID,
            patch_voxel_size,
            mip_level: level,
            extinction: s.extinction,
            shading: s.shading.clone(),
        })),
        mips: None,
    };
    medium.attach_local_bounds().map_err(|e| bad(&e))?;
    Ok(medium)
}

/// Generates (or reads), voxelises, mips and places the patch (a shell over the placement's
/// mesh, or the free-standing patch), and sets its coefficients: the density is the fibre
/// volume fraction; σ_t⁰ = density / attenuation per unit fraction (× 4/π with
/// fibre-projected extinction, so that its mean over directions is the same); the fibre
/// phase functions carry the yarn colours, so σ_s⁰ = σ_t⁰. With `mip = "auto"` every level
/// that halves the tile exactly is built and the level is chosen per ray
/// ([`crate::medium::MipChain`]).
fn build_fabric(
    at: &Site,
    d: &FabricDesc,
    placement: &Placement<'_>,
    attenuation: Rgb,
    density: f32,
) -> Result<(HeterogeneousMedium, YarnColours), SceneError> {
    let owner = &at.owner;
    let xf = placement.xf;
    let bad = |e: &dyn std::fmt::Display| at.failed(e);
    let mip = requested_mip(at, d.mip.as_ref())?;
    let auto_mip = matches!(&d.mip, Some(MipValue::Named(_)));
    let (source, albedos) = match d.file.as_deref() {
        Some(file) => {
            let pf = read_file(at, d, file)?;
            let albedos = pf.record.albedos;
            (PatchSource::File(Box::new(pf)), albedos)
        }
        // Mip levels are summed from the fine accumulators.
        None => {
            let (vp, albedos) = generate(at, d, auto_mip || mip.is_some_and(|l| l > 0))?;
            (PatchSource::Generated(Box::new(vp)), albedos)
        }
    };
    let fibre = fibre_phase(at, d.fibre_phase.as_ref())?;
    // Textured colours build the fabric in their means (its stand-in); walks use their own.
    let colours = yarn_colours(at, d, placement, albedos, fibre.beta_n)?;
    let albedos = colours.at(Vec2::ZERO, f32::INFINITY);
    let base = source
        .base()
        .ok_or_else(|| at.invalid(format!("{owner}: the patch has no level 0")))?;
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
        Some(mesh) => Some(
            requested_tiles
                .or_else(|| lod::true_size_tiles_of(mesh, base.tile))
                .ok_or_else(|| {
                    at.invalid(format!("{owner}: a fabric shell needs a mesh with texture coordinates (u, v) spanning a non-zero area"))
                })?,
        ),
    };
    // The levels to build: the fixed one, or every level that halves the tile exactly.
    let levels: Vec<u32> = if auto_mip {
        (0..=MAX_MIP_LEVEL)
            .take_while(|&l| lod::halves_exactly(base, l))
            .collect()
    } else {
        let l = mip.unwrap_or(0);
        if !lod::halves_exactly(base, l) {
            return Err(at.invalid(format!("{owner}.mip = {l}: the patch has {} × {} voxels across its tile, which {l} halvings do not divide exactly; use a resolution that is a multiple of {}", base.dims[0], base.dims[1], 1u32 << l)));
        }
        vec![l]
    };
    let voxel_width = lod::voxel_footprint(base, xf, shell_mesh.as_ref(), tiles).0;
    let shading = FabricShading::from_albedos(&fibre, albedos).map_err(|e| bad(&e))?;
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
    let shared = Shared {
        shell_mesh: shell_mesh.as_ref(),
        tiles,
        xf,
        sigma_t: attenuation.map(|d| density * scale / d),
        extinction,
        shading: &shading,
    };
    let mut media = Vec::with_capacity(levels.len());
    for &l in &levels {
        let vp = source.level(l).map_err(|e| bad(&e))?;
        media.push(level_medium(at, vp, &shared)?);
    }
    let mut media = media.into_iter();
    let mut medium = media
        .next()
        .ok_or_else(|| at.invalid(format!("{owner}: no mip level to build")))?;
    let first = levels.first().copied().unwrap_or(0);
    if auto_mip || first > 0 {
        // The fibres' extent: the finest level's occupied box (for a fixed coarser level
        // of a free-standing patch, from the level-0 grid's pyramid; a shell is bounded by
        // its mesh).
        let bounds = if first == 0 {
            medium.pyramid.world_bounds()
        } else if shared.shell_mesh.is_none() {
            let mut grid = base.grid.clone();
            let placed = DAffine3::from_mat4(xf.as_dmat4()) * grid.index_to_world();
            grid.set_index_to_world(placed).map_err(|e| bad(&e))?;
            MajorantPyramid::from_grid(&grid, crate::fabric::voxelise::DENSITY)
                .map_err(|e| bad(&e))?
                .world_bounds()
        } else {
            None
        };
        medium.mips = Some(Box::new(MipChain {
            voxel_width,
            bounds: bounds.unwrap_or(crate::math::Aabb::EMPTY),
            levels: media.collect(),
        }));
    }
    Ok((medium, colours))
}
