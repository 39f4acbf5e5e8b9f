//! A parameter that is either a constant or a texture read at a point's texture coordinates.
//! Textures are shared ([`Arc`]) between every parameter naming the same file and options.

use std::sync::Arc;

use super::Texture;
use crate::math::Vec2;
use crate::spectrum::Rgb;

/// A colour parameter (albedo, attenuation, tint, reflectance).
#[derive(Clone, Debug)]
pub enum ColorParam {
    /// The same value everywhere.
    Constant(Rgb),
    /// Read from a texture (RGB, or one channel as grey).
    Texture(Arc<Texture>),
}

/// A scalar parameter (density, roughness, coat weight, a mask).
#[derive(Clone, Debug)]
pub enum ScalarParam {
    /// The same value everywhere.
    Constant(f32),
    /// Read from one channel of a texture.
    Texture(Arc<Texture>),
}

impl ColorParam {
    /// The value at `uv` for a footprint `width_uv` wide (texture units).
    #[inline]
    #[must_use]
    pub fn eval(&self, uv: Vec2, width_uv: f32) -> Rgb {
        match self {
            ColorParam::Constant(c) => *c,
            ColorParam::Texture(t) => t.eval(uv, width_uv),
        }
    }

    /// True for a texture.
    #[must_use]
    pub fn is_textured(&self) -> bool {
        matches!(self, ColorParam::Texture(_))
    }

    /// The largest value per channel anywhere.
    #[must_use]
    pub fn max(&self) -> Rgb {
        match self {
            ColorParam::Constant(c) => *c,
            ColorParam::Texture(t) => t.max(),
        }
    }

    /// The smallest value per channel anywhere.
    #[must_use]
    pub fn min(&self) -> Rgb {
        match self {
            ColorParam::Constant(c) => *c,
            ColorParam::Texture(t) => t.min(),
        }
    }
}

impl ScalarParam {
    /// The value at `uv` for a footprint `width_uv` wide (texture units).
    #[inline]
    #[must_use]
    pub fn eval(&self, uv: Vec2, width_uv: f32) -> f32 {
        match self {
            ScalarParam::Constant(c) => *c,
            ScalarParam::Texture(t) => t.eval_scalar(uv, width_uv),
        }
    }

    /// True for a texture.
    #[must_use]
    pub fn is_textured(&self) -> bool {
        matches!(self, ScalarParam::Texture(_))
    }

    /// The largest value anywhere.
    #[must_use]
    pub fn max(&self) -> f32 {
        match self {
            ScalarParam::Constant(c) => *c,
            ScalarParam::Texture(t) => t.max().0[0],
        }
    }
}
