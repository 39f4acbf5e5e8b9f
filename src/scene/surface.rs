//! `surface = { ... }`: an object's boundary, one builder per surface type.

use super::context::Ctx;
use super::desc::{CoatDesc, ColorInput, SurfaceBlendDesc, SurfaceDesc};
use super::textures::ParamSite;
use super::validate::check_range;
use super::{
    CoatParams, DielectricParams, ObjectSurface, SceneError, SurfaceBlend, TexturedKind,
    TexturedSurface,
};
use crate::bsdf::{Coat, MicrofacetDistribution, Surface};
use crate::spectrum::Rgb;
use crate::texture::{ColorParam, ScalarParam};

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

/// The coat (IOR, roughness, weight, with defaults 1.5, 0.1 and 1), its albedo table built
/// here once; the weight may be a texture.
fn coat(p: &ParamSite, c: &CoatDesc) -> Result<CoatParams, SceneError> {
    let (ctx, line, owner) = (p.ctx, p.line, p.owner);
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
    let weight = p.scalar("coat.weight", c.weight.as_ref(), 1.0, 0.0, 1.0)?;
    let coat = Coat::new(ior, r).map_err(|e| ctx.invalid(line, format!("{owner}.coat: {e}")))?;
    Ok(CoatParams { coat, weight })
}

/// The constant of a parameter known to be untextured.
fn constant(c: &ColorParam) -> Rgb {
    match c {
        ColorParam::Constant(c) => *c,
        ColorParam::Texture(t) => t.mean(),
    }
}

/// The constant of a scalar parameter known to be untextured.
fn constant_scalar(c: &ScalarParam) -> f32 {
    match c {
        ScalarParam::Constant(c) => *c,
        ScalarParam::Texture(t) => t.mean().0[0],
    }
}

/// The boundary of object `name` and the IOR of its interior (1 unless it refracts); no
/// surface is an index-matched ([`ObjectSurface::Null`]) boundary. `line` is the line of the
/// surface table; `has_uvs` says whether the shape has texture coordinates (textured
/// parameters need them).
pub(super) fn build_surface(
    ctx: &Ctx,
    line: usize,
    name: &str,
    s: Option<&SurfaceDesc>,
    has_uvs: bool,
) -> Result<(ObjectSurface, f32), SceneError> {
    let Some(s) = s else {
        return Ok((ObjectSurface::Null, 1.0));
    };
    build_named(ctx, line, name, format!("{name}: surface"), s, has_uvs)
}

/// [`build_surface`] of a surface table named `owner` in messages (`"<name>: surface"`, or a
/// blend's `"<name>: surface.a"`).
fn build_named(
    ctx: &Ctx,
    line: usize,
    name: &str,
    owner: String,
    s: &SurfaceDesc,
    has_uvs: bool,
) -> Result<(ObjectSurface, f32), SceneError> {
    if let SurfaceDesc::Blend(d) = s {
        return blend(ctx, line, name, &owner, d, has_uvs);
    }
    let p = ParamSite {
        ctx,
        line,
        owner: &owner,
        name,
        has_uvs,
    };
    let bad = |e: &dyn std::fmt::Display| ctx.invalid(line, format!("{owner}: {e}"));
    let roughness = p.scalar("roughness", s.roughness(), 0.0, 0.0, 1.0)?;
    let coat = s.coat().map(|c| coat(&p, c)).transpose()?;
    let with_coat = |surf: Surface| -> Result<Surface, SceneError> {
        match &coat {
            Some(c) => surf
                .with_prepared_coat(&c.coat, constant_scalar(&c.weight))
                .map_err(|e| bad(&e)),
            None => Ok(surf),
        }
    };
    let colour = |what: &str, v: Option<&ColorInput>, default| p.colour(what, v, default, 0.0, 1.0);
    // A surface with a textured parameter is built at each hit; the constant one once.
    let textured = |kind: TexturedKind, coat: Option<CoatParams>| {
        ObjectSurface::Textured(Box::new(TexturedSurface { kind, coat }))
    };
    let coat_textured = coat.as_ref().is_some_and(|c| c.weight.is_textured());
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
            let tint = colour("tint", d.tint.as_ref(), Rgb::ONE)?;
            let dist = distribution(ctx, line, name, d.distribution.as_deref())?;
            let min_reflect_probability = check_range(
                ctx,
                line,
                &format!("{owner}.min_reflect_probability"),
                d.min_reflect_probability.unwrap_or(0.0),
                0.0,
                crate::bsdf::MAX_REFLECT_FLOOR,
            )?;
            // Check once that the parameters build (the per-hit construction then cannot fail:
            // textured values are checked against the same ranges).
            let test = Surface::dielectric(ior, constant_scalar(&roughness), dist, constant(&tint))
                .and_then(|s| s.with_reflect_floor(min_reflect_probability))
                .map_err(|e| bad(&e))?;
            let in_air = with_coat(test)?;
            let mut params = DielectricParams {
                ior,
                roughness,
                distribution: dist,
                tint,
                min_reflect_probability,
                coat,
                in_air: None,
            };
            // Untextured: the surface a hit from air builds is this one (the relative IOR
            // `ior / 1` is `ior`; the constants are the values read).
            if !params.is_textured() {
                params.in_air = Some(in_air);
            }
            Ok((ObjectSurface::Dielectric(params), ior))
        }
        SurfaceDesc::DiffuseTransmission(d) => {
            let r = colour("reflectance", d.reflectance.as_ref(), Rgb::splat(0.0))?;
            let t = colour("transmittance", d.transmittance.as_ref(), Rgb::ONE)?;
            let surf =
                Surface::diffuse_transmission(constant(&r), constant(&t)).map_err(|e| bad(&e))?;
            let surf = with_coat(surf)?;
            if r.is_textured() || t.is_textured() || coat_textured {
                let kind = TexturedKind::DiffuseTransmission {
                    reflectance: r,
                    transmittance: t,
                };
                return Ok((textured(kind, coat), 1.0));
            }
            Ok((ObjectSurface::Fixed(surf), 1.0))
        }
        SurfaceDesc::Lambertian(d) => {
            let r = colour("reflectance", d.reflectance.as_ref(), Rgb::splat(0.8))?;
            let surf = with_coat(Surface::lambertian(constant(&r)).map_err(|e| bad(&e))?)?;
            if r.is_textured() || coat_textured {
                return Ok((
                    textured(TexturedKind::Lambertian { reflectance: r }, coat),
                    1.0,
                ));
            }
            Ok((ObjectSurface::Fixed(surf), 1.0))
        }
        SurfaceDesc::Blend(_) => Err(bad(&"a blend is built by `blend`")),
        SurfaceDesc::Conductor(d) => {
            let r = colour("reflectance", d.reflectance.as_ref(), Rgb::splat(0.9))?;
            let dist = distribution(ctx, line, name, d.distribution.as_deref())?;
            let surf = Surface::conductor_from_reflectance_with(
                constant(&r),
                constant_scalar(&roughness),
                dist,
            )
            .map_err(|e| bad(&e))?;
            let surf = with_coat(surf)?;
            if r.is_textured() || roughness.is_textured() || coat_textured {
                let kind = TexturedKind::Conductor {
                    reflectance: r,
                    roughness,
                    distribution: dist,
                };
                return Ok((textured(kind, coat), 1.0));
            }
            Ok((ObjectSurface::Fixed(surf), 1.0))
        }
    }
}

/// `type = "blend"`: `a` with probability mask(uv) at each hit, else `b`. Both must refract
/// alike (dielectrics of one IOR, or neither) and both transmit or neither, so that the
/// object's interior, its IOR and its two-sidedness do not depend on the choice.
fn blend(
    ctx: &Ctx,
    line: usize,
    name: &str,
    owner: &str,
    d: &SurfaceBlendDesc,
    has_uvs: bool,
) -> Result<(ObjectSurface, f32), SceneError> {
    let p = ParamSite {
        ctx,
        line,
        owner,
        name,
        has_uvs,
    };
    let mask_input = d.mask.as_ref().ok_or_else(|| {
        ctx.invalid(
            line,
            format!("{owner}: a blend needs `mask` (a number in [0, 1] or {{ texture = \"file\", channel = ... }})"),
        )
    })?;
    let mask = p.scalar("mask", Some(mask_input), 0.5, 0.0, 1.0)?;
    let look = |key: &str, desc: Option<&toml::Spanned<SurfaceDesc>>| {
        let desc = desc.ok_or_else(|| {
            ctx.invalid(
                line,
                format!("{owner}: a blend needs `{key}` (a surface table with a `type`)"),
            )
        })?;
        let inner_line = ctx.line_of(desc.span().start);
        if matches!(desc.get_ref(), SurfaceDesc::Blend(_)) {
            return Err(ctx.invalid(
                inner_line,
                format!("{owner}.{key}: a blend's surfaces cannot be blends"),
            ));
        }
        build_named(
            ctx,
            inner_line,
            name,
            format!("{owner}.{key}"),
            desc.get_ref(),
            has_uvs,
        )
    };
    let (a, ior_a) = look("a", d.a.as_deref())?;
    let (b, ior_b) = look("b", d.b.as_deref())?;
    let dielectric = |s: &ObjectSurface| matches!(s, ObjectSurface::Dielectric(_));
    if dielectric(&a) != dielectric(&b) || ior_a != ior_b {
        return Err(ctx.invalid(
            line,
            format!("{owner}: a blend's `a` and `b` must both be dielectrics of the same `ior` (here {ior_a} and {ior_b}), or both other types"),
        ));
    }
    if a.transmits() != b.transmits() {
        return Err(ctx.invalid(
            line,
            format!("{owner}: a blend's `a` and `b` must both transmit light or both be opaque"),
        ));
    }
    Ok((
        ObjectSurface::Blend(Box::new(SurfaceBlend { mask, a, b })),
        ior_a,
    ))
}
