//! Checks shared by every part of the scene: finite numbers in range, colours and vectors.
//! Each failure names the key (`what`) and the line of the table holding it.

use super::context::Ctx;
use super::desc::ColorValue;
use super::SceneError;
use crate::math::Vec3;
use crate::spectrum::Rgb;

/// A colour key's value, or `default` when the key is absent.
pub(super) fn color(v: Option<ColorValue>, default: Rgb) -> Rgb {
    match v {
        None => default,
        Some(ColorValue::Scalar(s)) => Rgb::splat(s),
        Some(ColorValue::Rgb(c)) => Rgb(c),
    }
}

/// `c` when every channel is finite and in `[min, max]`.
pub(super) fn check_finite_rgb(
    ctx: &Ctx,
    line: usize,
    what: &str,
    c: Rgb,
    min: f32,
    max: f32,
) -> Result<Rgb, SceneError> {
    for v in c.0 {
        if !v.is_finite() || v < min || v > max {
            return Err(ctx.invalid(
                line,
                format!(
                    "{what} = {:?} is outside [{min}, {max}] (or not finite)",
                    c.0
                ),
            ));
        }
    }
    Ok(c)
}

/// `v` when it is finite and in `[min, max]`.
pub(super) fn check_range(
    ctx: &Ctx,
    line: usize,
    what: &str,
    v: f32,
    min: f32,
    max: f32,
) -> Result<f32, SceneError> {
    if !v.is_finite() || v < min || v > max {
        return Err(ctx.invalid(
            line,
            format!("{what} = {v} is outside [{min}, {max}] (or not finite)"),
        ));
    }
    Ok(v)
}

/// `v` as a vector when every component is finite.
pub(super) fn vec3(ctx: &Ctx, line: usize, what: &str, v: [f32; 3]) -> Result<Vec3, SceneError> {
    if v.iter().any(|x| !x.is_finite()) {
        return Err(ctx.invalid(line, format!("{what} = {v:?} is not finite")));
    }
    Ok(Vec3::from_array(v))
}

/// Rejects the keys of a small table that its chosen `kind` does not use (`present` pairs
/// each such key with whether it is set): a camera's lens keys on a pinhole, a sphere's keys
/// on a mesh, a second lobe on a single-lobe phase function. (Lights, surfaces and
/// interiors have one description per type instead, so their reader rejects such keys.)
pub(super) fn reject_unused(
    ctx: &Ctx,
    line: usize,
    owner: &str,
    kind: &str,
    present: &[(&str, bool)],
) -> Result<(), SceneError> {
    for (key, is_set) in present {
        if *is_set {
            return Err(ctx.invalid(
                line,
                format!("{owner}: key `{key}` is not used by type \"{kind}\""),
            ));
        }
    }
    Ok(())
}
