//! `[film]` and `[camera]`: image size, sampling and output, and the camera model.

use std::path::PathBuf;

use super::context::Ctx;
use super::desc::{CameraDesc, FilmDesc};
use super::validate::{check_range, reject_unused, vec3};
use super::{CameraParams, FilmSettings, Roulette, SceneError};
use crate::camera::Camera;

/// Largest accepted image side, pixels.
const MAX_IMAGE_SIDE: u32 = 32_768;

/// The 1-based line of the table header `header` (e.g. `[film]`), or 1 without one.
fn header_line(ctx: &Ctx, header: &str) -> usize {
    ctx.text
        .lines()
        .position(|l| l.trim() == header)
        .map_or(1, |i| i + 1)
}

/// The film settings, with defaults for missing keys (and for a missing `[film]`).
pub(super) fn build_film(ctx: &Ctx, film: Option<&FilmDesc>) -> Result<FilmSettings, SceneError> {
    let f = film.cloned().unwrap_or_default();
    let line = header_line(ctx, "[film]");
    let width = f.width.unwrap_or(480);
    let height = f.height.unwrap_or(360);
    for (k, v) in [("film.width", width), ("film.height", height)] {
        if v == 0 || v > MAX_IMAGE_SIDE {
            return Err(ctx.invalid(line, format!("{k} = {v} is outside [1, {MAX_IMAGE_SIDE}]")));
        }
    }
    let spp = f.spp.unwrap_or(16);
    if spp == 0 || spp > 1 << 24 {
        return Err(ctx.invalid(line, format!("film.spp = {spp} is outside [1, 16777216]")));
    }
    let max_depth = f.max_depth.unwrap_or(256);
    if max_depth == 0 || max_depth > 1_000_000 {
        return Err(ctx.invalid(
            line,
            format!("film.max_depth = {max_depth} is outside [1, 1000000]"),
        ));
    }
    let roulette_depth = f.roulette_depth.unwrap_or(Roulette::DEFAULT.start_depth);
    if roulette_depth > 1_000_000 {
        return Err(ctx.invalid(
            line,
            format!("film.roulette_depth = {roulette_depth} is outside [0, 1000000]"),
        ));
    }
    let roulette_threshold = f.roulette_threshold.unwrap_or(Roulette::DEFAULT.threshold);
    if !(roulette_threshold > 0.0 && roulette_threshold <= 1.0) {
        return Err(ctx.invalid(
            line,
            format!("film.roulette_threshold = {roulette_threshold} is outside (0, 1]"),
        ));
    }
    let exposure = check_range(
        ctx,
        line,
        "film.exposure",
        f.exposure.unwrap_or(0.0),
        -30.0,
        30.0,
    )?;
    let output = match &f.output {
        // Outputs are relative to the working directory (inputs to the scene file).
        Some(o) => PathBuf::from(o),
        None => {
            let stem = ctx
                .path
                .file_stem()
                .and_then(|s| s.to_str())
                .filter(|s| !s.starts_with('<'))
                .unwrap_or("default");
            PathBuf::from("out").join(format!("{stem}.exr"))
        }
    };
    Ok(FilmSettings {
        width,
        height,
        spp,
        seed: f.seed.unwrap_or(0),
        max_depth,
        roulette: Roulette {
            start_depth: roulette_depth,
            threshold: roulette_threshold,
        },
        output,
        exposure,
    })
}

/// The camera for the film's resolution, and what it was built from.
pub(super) fn build_camera(
    ctx: &Ctx,
    camera: Option<&CameraDesc>,
    film: &FilmSettings,
) -> Result<(Camera, CameraParams), SceneError> {
    let line = header_line(ctx, "[camera]");
    let c = camera.ok_or_else(|| ctx.invalid(1, "missing [camera] table"))?;
    let eye = vec3(
        ctx,
        line,
        "camera.eye",
        c.eye
            .ok_or_else(|| ctx.invalid(line, "camera.eye is required"))?,
    )?;
    let look_at = vec3(
        ctx,
        line,
        "camera.look_at",
        c.look_at
            .ok_or_else(|| ctx.invalid(line, "camera.look_at is required"))?,
    )?;
    let up = vec3(ctx, line, "camera.up", c.up.unwrap_or([0.0, 1.0, 0.0]))?;
    let fov = check_range(ctx, line, "camera.fov", c.fov.unwrap_or(40.0), 1e-3, 179.0)?;
    let kind = c.kind.as_deref().unwrap_or("pinhole");
    let lens = match kind {
        "pinhole" => {
            reject_unused(
                ctx,
                line,
                "camera",
                kind,
                &[
                    ("aperture_radius", c.aperture_radius.is_some()),
                    ("focus_distance", c.focus_distance.is_some()),
                ],
            )?;
            None
        }
        "thin_lens" => {
            let aperture = check_range(
                ctx,
                line,
                "camera.aperture_radius",
                c.aperture_radius.unwrap_or(0.0),
                0.0,
                1e6,
            )?;
            let focus = check_range(
                ctx,
                line,
                "camera.focus_distance",
                c.focus_distance.unwrap_or((look_at - eye).length()),
                1e-6,
                1e9,
            )?;
            Some((aperture, focus))
        }
        other => {
            return Err(ctx.invalid(
                line,
                format!(
                    "camera.type = \"{other}\" is unknown (expected \"pinhole\" or \"thin_lens\")"
                ),
            ))
        }
    };
    let params = CameraParams {
        eye,
        look_at,
        up,
        fov,
        lens,
    };
    let cam = params
        .build(film.width, film.height)
        .map_err(|e| ctx.invalid(line, format!("camera: {e}")))?;
    Ok((cam, params))
}
