//! The extra grids of a `voxel` interior, read only when the scene asks for them: a per-voxel
//! albedo (`albedo_grid`, a Vec3 grid or a scalar grid through `albedo_ramp`) and emission
//! (`emission_grid`, Vec3 or scalar × `emission_color`, or `temperature_grid` through
//! blackbody radiance). Every grid must share the density grid's index-to-world map.

use std::path::{Path, PathBuf};

use glam::DAffine3;

use super::Site;
use crate::grid::{ChannelKind, SparseGrid};
use crate::medium::{AlbedoGrid, AlbedoMode, AlbedoSource, EmissionGrid, EmissionKind};
use crate::scene::desc::VoxelDesc;
use crate::scene::validate::color;
use crate::scene::SceneError;
use crate::spectrum::blackbody::BlackbodyTable;
use crate::spectrum::Rgb;
use crate::vdb::VdbGrid;

/// The density grid the extra grids are checked against.
pub(super) struct DensityGridRef {
    /// Its file.
    pub path: PathBuf,
    /// Its name.
    pub name: String,
    /// Its index-to-world map as stored in the file (before the object transform).
    pub map: DAffine3,
}

/// True when the interior asks for any extra grid (or one of their keys).
pub(super) fn wanted(d: &VoxelDesc) -> bool {
    d.albedo_grid.is_some()
        || d.albedo_ramp.is_some()
        || d.albedo_file.is_some()
        || d.emission_grid.is_some()
        || d.emission_color.is_some()
        || d.emission_file.is_some()
        || d.temperature_grid.is_some()
        || d.temperature_scale.is_some()
        || d.emission_scale.is_some()
}

/// Reads grid `name` of `path` (listing the file's grids when it has no such grid), refusing
/// non-finite values and level sets (signed distances are not densities, colours or
/// temperatures).
pub(super) fn read_grid(at: &Site, path: &Path, name: &str) -> Result<VdbGrid, SceneError> {
    let owner = &at.owner;
    let mut grids = crate::vdb::read_vdb_grids(path, &[name]).map_err(|e| at.failed(&e))?;
    let vg = grids
        .pop()
        .ok_or_else(|| at.invalid(format!("{owner}: {}: no grid {name}", path.display())))?;
    vg.check_finite()
        .map_err(|e| at.invalid(format!("{owner}: {}: {e}", path.display())))?;
    if vg.class == "level set" {
        return Err(at.invalid(format!(
            "{owner}: {}: grid `{name}` is a level set (class `level set`: signed distances, negative inside), not a fog volume; use it as a boundary (shape = \"levelset\") or convert it to a fog volume",
            path.display()
        )));
    }
    Ok(vg)
}

/// Refuses a grid whose map differs from the density grid's (beyond 10⁻⁶ of a voxel).
fn check_transform(
    at: &Site,
    key: &str,
    path: &Path,
    vg: &VdbGrid,
    density: &DensityGridRef,
) -> Result<(), SceneError> {
    let a = vg.grid.index_to_world();
    let b = density.map;
    let voxel = b
        .matrix3
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(1e-30);
    if a.abs_diff_eq(b, 1e-6 * voxel) {
        return Ok(());
    }
    let show = |m: DAffine3| {
        let c = m.to_cols_array();
        format!(
            "[{:.6}, {:.6}, {:.6} | {:.6}, {:.6}, {:.6} | {:.6}, {:.6}, {:.6} | translation {:.6}, {:.6}, {:.6}]",
            c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10], c[11]
        )
    };
    Err(at.invalid(format!(
        "{}.{key}: grid `{}` of {} has a different transform from the density grid `{}` of {}: index-to-world {} vs {} (the grids must be aligned voxel for voxel)",
        at.owner,
        vg.name,
        path.display(),
        density.name,
        density.path.display(),
        show(a),
        show(b)
    )))
}

/// Places `vg`'s grid in the scene by the object transform `xf`.
fn place(at: &Site, mut grid: SparseGrid, xf: DAffine3) -> Result<SparseGrid, SceneError> {
    let placed = xf * grid.index_to_world();
    grid.set_index_to_world(placed)
        .map_err(|e| at.invalid(format!("{}: placing a grid: {e}", at.owner)))?;
    Ok(grid)
}

/// The file of an extra grid: `file_key`'s value resolved against the scene, or the density's.
fn grid_file(at: &Site, file: Option<&String>, density: &DensityGridRef) -> PathBuf {
    file.map_or_else(|| density.path.clone(), |f| at.ctx.resolve(f))
}

/// The albedo grid of `d`, if it asks for one. `mode` and `g` are the interior's albedo mode
/// and phase mean cosine (the inversion applied per vertex).
pub(super) fn albedo_grid(
    at: &Site,
    d: &VoxelDesc,
    density: &DensityGridRef,
    xf: DAffine3,
    mode: AlbedoMode,
    g: f32,
) -> Result<Option<AlbedoGrid>, SceneError> {
    let owner = &at.owner;
    let Some(name) = d.albedo_grid.as_deref() else {
        refuse_unused(
            at,
            &[
                ("albedo_ramp", d.albedo_ramp.is_some()),
                ("albedo_file", d.albedo_file.is_some()),
            ],
            "`albedo_grid` (the name of the albedo grid)",
        )?;
        return Ok(None);
    };
    if d.albedo.is_some() {
        return Err(at.invalid(format!(
            "{owner}: `albedo` and `albedo_grid` both give the albedo; keep one"
        )));
    }
    let path = grid_file(at, d.albedo_file.as_ref(), density);
    let vg = read_grid(at, &path, name)?;
    check_transform(at, "albedo_grid", &path, &vg, density)?;
    let source = match (vg.grid.channel_kind(0), &d.albedo_ramp) {
        (Some(ChannelKind::Vec3), None) => AlbedoSource::Colour,
        (Some(ChannelKind::Vec3), Some(_)) => {
            return Err(at.invalid(format!(
                "{owner}.albedo_ramp: grid `{name}` of {} is a colour (Vec3) grid; a ramp maps scalar grids only",
                path.display()
            )))
        }
        (_, Some(stops)) => AlbedoSource::Ramp(ramp(at, stops)?),
        (_, None) => {
            return Err(at.invalid(format!(
                "{owner}: grid `{name}` of {} is scalar: give `albedo_ramp = [[0.0, [r, g, b]], [1.0, [r, g, b]]]` to map it to colours",
                path.display()
            )))
        }
    };
    Ok(Some(AlbedoGrid {
        grid: place(at, vg.grid, xf)?,
        source,
        mode,
        g,
    }))
}

/// The stops of `albedo_ramp`: at least one, values finite and strictly increasing, colours
/// in [0, 1].
fn ramp(
    at: &Site,
    stops: &[(f32, crate::scene::desc::ColorValue)],
) -> Result<Vec<(f32, Rgb)>, SceneError> {
    let owner = &at.owner;
    if stops.is_empty() {
        return Err(at.invalid(format!(
            "{owner}.albedo_ramp is empty (give [[value, [r, g, b]], ...])"
        )));
    }
    let mut out = Vec::with_capacity(stops.len());
    let mut last = f32::NEG_INFINITY;
    for (i, (v, c)) in stops.iter().enumerate() {
        if !v.is_finite() {
            return Err(at.invalid(format!(
                "{owner}.albedo_ramp[{i}]: value {v} is not a finite number"
            )));
        }
        if *v <= last {
            return Err(at.invalid(format!(
                "{owner}.albedo_ramp[{i}]: value {v} does not follow {last}: the stops must be sorted by increasing value"
            )));
        }
        last = *v;
        let rgb = at.unit_colour(&format!("albedo_ramp[{i}]"), Some(*c), Rgb::ZERO)?;
        out.push((*v, rgb));
    }
    Ok(out)
}

/// The emission of `d`, if it asks for one.
pub(super) fn emission_grid(
    at: &Site,
    d: &VoxelDesc,
    density: &DensityGridRef,
    xf: DAffine3,
) -> Result<Option<EmissionGrid>, SceneError> {
    let owner = &at.owner;
    let scale = at.range("emission_scale", d.emission_scale.unwrap_or(1.0), 0.0, 1e30)?;
    let tint = super::super::validate::check_finite_rgb(
        at.ctx,
        at.line,
        &format!("{owner}.emission_color"),
        color(d.emission_color, Rgb::ONE),
        0.0,
        f32::MAX,
    )?;
    let (name, temperature) = match (d.emission_grid.as_deref(), d.temperature_grid.as_deref()) {
        (Some(_), Some(_)) => {
            return Err(at.invalid(format!(
                "{owner}: `emission_grid` and `temperature_grid` both give the emission; keep one"
            )))
        }
        (Some(n), None) => (n, false),
        (None, Some(n)) => (n, true),
        (None, None) => {
            refuse_unused(
                at,
                &[
                    ("emission_color", d.emission_color.is_some()),
                    ("emission_file", d.emission_file.is_some()),
                    ("emission_scale", d.emission_scale.is_some()),
                    ("temperature_scale", d.temperature_scale.is_some()),
                ],
                "`emission_grid` or `temperature_grid`",
            )?;
            return Ok(None);
        }
    };
    if !temperature && d.temperature_scale.is_some() {
        return Err(at.invalid(format!(
            "{owner}.temperature_scale applies to `temperature_grid` only"
        )));
    }
    let temperature_scale = match d.temperature_scale {
        Some(s) if !s.is_finite() || s < 0.0 => {
            return Err(at.invalid(format!(
            "{owner}.temperature_scale = {s}: must be a finite number ≥ 0 (kelvin per grid unit)"
        )))
        }
        Some(s) => s,
        None => 1.0,
    };
    let path = grid_file(at, d.emission_file.as_ref(), density);
    let vg = read_grid(at, &path, name)?;
    let key = if temperature {
        "temperature_grid"
    } else {
        "emission_grid"
    };
    check_transform(at, key, &path, &vg, density)?;
    let stats = vg.stats();
    let kind = vg.grid.channel_kind(0);
    let background = vg.grid.background(0);
    let kind = match (kind, temperature) {
        (Some(ChannelKind::Vec3), true) => {
            return Err(at.invalid(format!(
            "{owner}.temperature_grid: grid `{name}` of {} is a Vec3 grid; temperatures are scalar",
            path.display()
        )))
        }
        (Some(ChannelKind::Vec3), false) => EmissionKind::Colour,
        (_, false) => EmissionKind::Scalar,
        (_, true) => EmissionKind::Temperature {
            scale: temperature_scale,
            table: BlackbodyTable::new((stats.max[0] as f32).max(background) * temperature_scale),
        },
    };
    let min = stats
        .min
        .iter()
        .take(stats.components.max(1))
        .fold(f64::INFINITY, |a, &b| a.min(b)) as f32;
    if min < 0.0 || background < 0.0 {
        let what = if temperature {
            "temperatures"
        } else {
            "radiance"
        };
        return Err(at.invalid(format!(
            "{owner}.{key}: grid `{name}` of {} has negative {what} (min {})",
            path.display(),
            min.min(background)
        )));
    }
    Ok(Some(EmissionGrid {
        grid: place(at, vg.grid, xf)?,
        kind,
        scale: tint * scale,
    }))
}

/// An error for the first key of `keys` that is set although the key it depends on
/// (`needs`, as the message names it) is absent.
fn refuse_unused(at: &Site, keys: &[(&str, bool)], needs: &str) -> Result<(), SceneError> {
    match keys.iter().find(|(_, set)| *set) {
        Some((key, _)) => {
            Err(at.invalid(format!("{}.{key} has no effect without {needs}", at.owner)))
        }
        None => Ok(()),
    }
}
