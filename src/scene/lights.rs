//! `[[light]]`: one builder per light type.

use super::context::Ctx;
use super::desc::LightDesc;
use super::validate::{check_finite_rgb, check_range, color, vec3};
use super::SceneError;
use crate::light::{EnvironmentMap, Light};
use crate::spectrum::Rgb;

/// The scene's lights and their beauty layers.
pub(super) struct SceneLights {
    /// The lights, in file order.
    pub lights: Vec<Light>,
    /// Per light: its beauty layer's slot, for named lights ([`layer_slot`]).
    pub layers: Vec<Option<u8>>,
    /// The names of the light layers, by slot.
    pub layer_names: Vec<String>,
}

/// Builds every `[[light]]` of `descs` in file order ([`build_light`], then the layer of a
/// named light); the first error met is returned.
pub(super) fn build_lights(
    ctx: &Ctx,
    descs: &[toml::Spanned<LightDesc>],
) -> Result<SceneLights, SceneError> {
    let mut built = SceneLights {
        lights: Vec::with_capacity(descs.len()),
        layers: Vec::with_capacity(descs.len()),
        layer_names: Vec::new(),
    };
    for spanned in descs {
        let line = ctx.line_of(spanned.span().start);
        built
            .lights
            .push(build_light(ctx, line, spanned.get_ref())?);
        built.layers.push(match spanned.get_ref().name() {
            None => None,
            Some(name) => Some(layer_slot(ctx, line, name, &mut built.layer_names)?),
        });
    }
    Ok(built)
}

/// The light of a `[[light]]` table starting at `line`.
pub(super) fn build_light(ctx: &Ctx, line: usize, l: &LightDesc) -> Result<Light, SceneError> {
    match l {
        LightDesc::Environment(d) => {
            let radiance = check_finite_rgb(
                ctx,
                line,
                "light.radiance",
                color(d.radiance, Rgb::ONE),
                0.0,
                1e12,
            )?;
            Ok(Light::ConstantEnvironment { radiance })
        }
        LightDesc::Envmap(d) => {
            let file = d
                .file
                .as_ref()
                .ok_or_else(|| ctx.invalid(line, "light \"envmap\" needs `file`"))?;
            let scale = check_range(ctx, line, "light.scale", d.scale.unwrap_or(1.0), 0.0, 1e12)?;
            let rotation = check_range(
                ctx,
                line,
                "light.rotation",
                d.rotation.unwrap_or(0.0),
                -36000.0,
                36000.0,
            )?;
            let map = crate::image_io::read_latlong_exr(&ctx.resolve(file))
                .map_err(|e| ctx.invalid(line, format!("light \"envmap\": {e}")))?;
            Ok(Light::EnvironmentMap(Box::new(EnvironmentMap::new(
                map, scale, rotation,
            ))))
        }
        LightDesc::Distant(d) => {
            let direction = d.direction.ok_or_else(|| {
                ctx.invalid(
                    line,
                    "light \"distant\" needs `direction` (towards the light)",
                )
            })?;
            let dir = vec3(ctx, line, "light.direction", direction)?;
            if dir.length() < 1e-12 {
                return Err(ctx.invalid(line, "light.direction must not be zero"));
            }
            let e = check_finite_rgb(
                ctx,
                line,
                "light.irradiance",
                color(d.irradiance, Rgb::splat(3.0)),
                0.0,
                1e12,
            )?;
            let r = check_range(
                ctx,
                line,
                "light.angular_radius",
                d.angular_radius.unwrap_or(0.0),
                0.0,
                90.0,
            )?;
            Ok(Light::distant(dir, e, r))
        }
        LightDesc::Sphere(d) => {
            let center = vec3(ctx, line, "light.center", d.center.unwrap_or([0.0; 3]))?;
            let radius = check_range(
                ctx,
                line,
                "light.radius",
                d.radius.unwrap_or(0.1),
                1e-9,
                1e9,
            )?;
            let radiance = check_finite_rgb(
                ctx,
                line,
                "light.radiance",
                color(d.radiance, Rgb::splat(10.0)),
                0.0,
                1e12,
            )?;
            Ok(Light::Sphere {
                center,
                radius,
                radiance,
            })
        }
    }
}

/// The beauty-layer slot of a light named `name` (appended to `names`). A name must be
/// non-empty, made of ASCII letters, digits, `_` and `-` (it becomes an EXR channel name), unique,
/// and at most [`crate::film::MAX_LIGHT_LAYERS`] lights may be named.
pub(super) fn layer_slot(
    ctx: &Ctx,
    line: usize,
    name: &str,
    names: &mut Vec<String>,
) -> Result<u8, SceneError> {
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
    {
        return Err(ctx.invalid(
            line,
            format!("light.name = {name:?}: use ASCII letters, digits, '_' and '-' only"),
        ));
    }
    if names.iter().any(|n| n == name) {
        return Err(ctx.invalid(
            line,
            format!("light.name = {name:?} is used by another light"),
        ));
    }
    if names.len() >= crate::film::MAX_LIGHT_LAYERS {
        return Err(ctx.invalid(
            line,
            format!(
                "light.name = {name:?}: at most {} lights can have their own layer",
                crate::film::MAX_LIGHT_LAYERS
            ),
        ));
    }
    names.push(name.to_string());
    Ok((names.len() - 1) as u8)
}
