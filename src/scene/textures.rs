//! Texturable parameters (docs/textures.md): a constant, or a texture loaded once per file
//! and options and shared ([`Arc`]) by every parameter that names it. The checks name the
//! object, the key and, for bad texels, the pixel.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Arc;

use super::context::Ctx;
use super::desc::{ColorInput, ScalarInput, TextureDesc};
use super::validate::{check_finite_rgb, check_range, color};
use super::SceneError;
use crate::spectrum::Rgb;
use crate::texture::{
    load_texture, Channel, ColorParam, ColorSpace, ScalarParam, Texture, TextureOptions, Wrap,
};

/// What makes two texture parameters share one texture: the file, the colour space, the
/// channel, the scale's bits and the wrap mode.
type TextureKey = (PathBuf, ColorSpace, Option<Channel>, u32, Wrap);

/// The textures loaded so far, by file and options.
#[derive(Default)]
pub(super) struct TextureCache {
    map: HashMap<TextureKey, Arc<Texture>>,
}

/// Where a texturable parameter is read: the scene, the line of its table, `owner.key` for
/// messages, and whether the object has texture coordinates.
pub(super) struct ParamSite<'a> {
    /// The scene.
    pub ctx: &'a Ctx<'a>,
    /// The line of the table holding the key.
    pub line: usize,
    /// `"<object>: surface"` or `"<object>: interior"`.
    pub owner: &'a str,
    /// The object's name.
    pub name: &'a str,
    /// True when the object's shape has texture coordinates (a mesh with UVs, a sphere).
    pub has_uvs: bool,
}

impl ParamSite<'_> {
    /// A colour parameter `key` in `[min, max]` (`default` when absent). Textures must hold
    /// values in that range after decoding and scaling.
    pub fn colour(
        &self,
        key: &str,
        v: Option<&ColorInput>,
        default: Rgb,
        min: f32,
        max: f32,
    ) -> Result<ColorParam, SceneError> {
        let what = format!("{}.{key}", self.owner);
        match v {
            Some(ColorInput::Texture(t)) => {
                let tex = self.load(key, t, true)?;
                self.check(&tex, &what, min, max)?;
                Ok(ColorParam::Texture(tex))
            }
            Some(ColorInput::Value(c)) => Ok(ColorParam::Constant(check_finite_rgb(
                self.ctx,
                self.line,
                &what,
                color(Some(*c), default),
                min,
                max,
            )?)),
            None => Ok(ColorParam::Constant(default)),
        }
    }

    /// A scalar parameter `key` in `[min, max]` (`default` when absent).
    pub fn scalar(
        &self,
        key: &str,
        v: Option<&ScalarInput>,
        default: f32,
        min: f32,
        max: f32,
    ) -> Result<ScalarParam, SceneError> {
        let what = format!("{}.{key}", self.owner);
        match v {
            Some(ScalarInput::Texture(t)) => {
                let tex = self.load(key, t, false)?;
                self.check(&tex, &what, min, max)?;
                Ok(ScalarParam::Texture(tex))
            }
            Some(ScalarInput::Value(x)) => Ok(ScalarParam::Constant(check_range(
                self.ctx, self.line, &what, *x, min, max,
            )?)),
            None => Ok(ScalarParam::Constant(default)),
        }
    }

    /// Every texel of `tex` in `[min, max]`, or an error naming the pixel.
    fn check(&self, tex: &Texture, what: &str, min: f32, max: f32) -> Result<(), SceneError> {
        tex.check_range(min, max, what)
            .map_err(|e| self.ctx.invalid(self.line, format!("{what}: {e}")))
    }

    /// Loads (or finds loaded) the texture of `key`: `colour` parameters read RGB (sRGB by
    /// default for PNG files), scalar ones one channel (linear, `r` by default).
    fn load(&self, key: &str, t: &TextureDesc, colour: bool) -> Result<Arc<Texture>, SceneError> {
        let owner = self.owner;
        let bad = |m: String| self.ctx.invalid(self.line, format!("{owner}.{key}: {m}"));
        if !self.has_uvs {
            return Err(bad(format!(
                "is a texture ({}) but the shape of {} has no texture coordinates (u, v); give the mesh per-vertex u, v (or use a sphere)",
                t.texture, self.name
            )));
        }
        let path = self.ctx.resolve(&t.texture);
        let is_png = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("png"));
        let colorspace = match t.colorspace.as_deref() {
            None if colour && is_png => ColorSpace::Srgb,
            None | Some("linear") => ColorSpace::Linear,
            Some("srgb") => ColorSpace::Srgb,
            Some(other) => {
                return Err(bad(format!(
                    "colorspace = \"{other}\" is unknown (expected \"srgb\" or \"linear\")"
                )))
            }
        };
        let channel = match t.channel.as_deref() {
            None if colour => None,
            None | Some("r") => Some(Channel::R),
            Some("g") => Some(Channel::G),
            Some("b") => Some(Channel::B),
            Some("a") => Some(Channel::A),
            Some("luminance") => Some(Channel::Luminance),
            Some(other) => {
                return Err(bad(format!(
                    "channel = \"{other}\" is unknown (expected \"r\", \"g\", \"b\", \"a\" or \"luminance\")"
                )))
            }
        };
        let scale = t.scale.unwrap_or(1.0);
        if !(scale.is_finite() && (0.0..=1e12).contains(&scale)) {
            return Err(bad(format!("scale = {scale} must be finite and >= 0")));
        }
        let wrap = match t.wrap.as_deref().unwrap_or("repeat") {
            "repeat" => Wrap::Repeat,
            "clamp" => Wrap::Clamp,
            other => {
                return Err(bad(format!(
                    "wrap = \"{other}\" is unknown (expected \"repeat\" or \"clamp\")"
                )))
            }
        };
        let opts = TextureOptions {
            colorspace,
            channel,
            scale,
            wrap,
        };
        let key_of = (path.clone(), colorspace, channel, scale.to_bits(), wrap);
        if let Some(tex) = self.ctx.textures.borrow().map.get(&key_of) {
            return Ok(Arc::clone(tex));
        }
        let tex = Arc::new(load_texture(&path, &opts).map_err(|e| bad(e.to_string()))?);
        self.ctx
            .textures
            .borrow_mut()
            .map
            .insert(key_of, Arc::clone(&tex));
        Ok(tex)
    }
}
