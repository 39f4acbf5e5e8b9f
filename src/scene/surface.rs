//! `surface = { ... }`: an object's boundary, one builder per surface type.

use super::context::Ctx;
use super::desc::{CoatDesc, SurfaceDesc};
use super::validate::{check_finite_rgb, check_range, color};
use super::{DielectricParams, ObjectSurface, SceneError};
use crate::bsdf::{MicrofacetDistribution, Surface};
use crate::spectrum::Rgb;

/// The microfacet distribution named by `distribution` ("ggx" when absent).
fn distribution(
    ctx: &Ctx,
    line: usize,
    name: &str,
    d: Option<&str>,
) -> Result<MicrofacetDistribution, SceneError> {
    match d.unwrap_or("ggx") {
        "ggx" => Ok(MicrofacetDistribution::Ggx),
        "beckmann" => Ok(MicrofacetDistribution::Beckmann),
        other => Err(ctx.invalid(
            line,
            format!(
                "{name}: surface.distribution = \"{other}\" is unknown (expected \"ggx\" or \"beckmann\")"
            ),
        )),
    }
}

/// The coat as (IOR, roughness, weight), with defaults 1.5, 0.1 and 1.
fn coat(ctx: &Ctx, line: usize, owner: &str, c: &CoatDesc) -> Result<(f32, f32, f32), SceneError> {
    let ior = check_range(
        ctx,
        line,
        &format!("{owner}.coat.ior"),
        c.ior.unwrap_or(1.5),
        1.0,
        4.0,
    )?;
    let r = check_range(
        ctx,
        line,
        &format!("{owner}.coat.roughness"),
        c.roughness.unwrap_or(0.1),
        0.0,
        1.0,
    )?;
    let w = check_range(
        ctx,
        line,
        &format!("{owner}.coat.weight"),
        c.weight.unwrap_or(1.0),
        0.0,
        1.0,
    )?;
    Ok((ior, r, w))
}

/// The boundary of object `name` and the IOR of its interior (1 unless it refracts); no
/// surface is an index-matched ([`ObjectSurface::Null`]) boundary. `line` is the line of the
/// surface table.
pub(super) fn build_surface(
    ctx: &Ctx,
    line: usize,
    name: &str,
    s: Option<&SurfaceDesc>,
) -> Result<(ObjectSurface, f32), SceneError> {
    let Some(s) = s else {
        return Ok((ObjectSurface::Null, 1.0));
    };
    let owner = format!("{name}: surface");
    let bad = |e: &dyn std::fmt::Display| ctx.invalid(line, format!("{owner}: {e}"));
    let roughness = check_range(
        ctx,
        line,
        &format!("{owner}.roughness"),
        s.roughness().unwrap_or(0.0),
        0.0,
        1.0,
    )?;
    let coat = s.coat().map(|c| coat(ctx, line, &owner, c)).transpose()?;
    let with_coat = |surf: Surface| -> Result<Surface, SceneError> {
        match coat {
            Some((ior, r, w)) => surf.with_coat(ior, r, w).map_err(|e| bad(&e)),
            None => Ok(surf),
        }
    };
    let colour = |what: &str, v, default| {
        check_finite_rgb(
            ctx,
            line,
            &format!("{owner}.{what}"),
            color(v, default),
            0.0,
            1.0,
        )
    };
    match s {
        SurfaceDesc::Dielectric(d) => {
            let ior = check_range(
                ctx,
                line,
                &format!("{owner}.ior"),
                d.ior.unwrap_or(1.4),
                1.0,
                4.0,
            )?;
            let tint = colour("tint", d.tint, Rgb::ONE)?;
            let dist = distribution(ctx, line, name, d.distribution.as_deref())?;
            // Check once that the parameters build (the per-hit construction then cannot fail).
            let test = Surface::dielectric(ior, roughness, dist, tint).map_err(|e| bad(&e))?;
            with_coat(test)?;
            Ok((
                ObjectSurface::Dielectric(DielectricParams {
                    ior,
                    roughness,
                    distribution: dist,
                    tint,
                    coat,
                }),
                ior,
            ))
        }
        SurfaceDesc::DiffuseTransmission(d) => {
            let r = colour("reflectance", d.reflectance, Rgb::splat(0.0))?;
            let t = colour("transmittance", d.transmittance, Rgb::ONE)?;
            let surf = Surface::diffuse_transmission(r, t).map_err(|e| bad(&e))?;
            Ok((ObjectSurface::Fixed(with_coat(surf)?), 1.0))
        }
        SurfaceDesc::Lambertian(d) => {
            let r = colour("reflectance", d.reflectance, Rgb::splat(0.8))?;
            let surf = Surface::lambertian(r).map_err(|e| bad(&e))?;
            Ok((ObjectSurface::Fixed(with_coat(surf)?), 1.0))
        }
        SurfaceDesc::Conductor(d) => {
            let r = colour("reflectance", d.reflectance, Rgb::splat(0.9))?;
            let dist = distribution(ctx, line, name, d.distribution.as_deref())?;
            let surf = Surface::conductor_from_reflectance_with(r, roughness, dist)
                .map_err(|e| bad(&e))?;
            Ok((ObjectSurface::Fixed(with_coat(surf)?), 1.0))
        }
    }
}
