//! Image textures for surface and interior parameters (docs/textures.md,
//! docs/references.md §14): OpenEXR and PNG (8 and 16 bit) files decoded to linear `f32`
//! (sRGB decoding for colour data), one channel or RGB, a `scale`, repeat or clamp wrapping,
//! and a box-filtered mip pyramid read with trilinear filtering at the level a footprint
//! width picks.
//!
//! - [`load`]: files → validated linear texels ([`TextureOptions`] say how);
//! - [`mip`]: the pyramid and its filtered lookups;
//! - [`param`]: a parameter that is a constant or a texture ([`ColorParam`], [`ScalarParam`]).
//!
//! Texture coordinates: `u` runs left to right, `v` bottom to top (the OBJ/Blender/PLY
//! convention): `v = 0` is the image's bottom row.

pub mod load;
pub mod mip;
pub mod param;

use std::path::PathBuf;

pub use load::{load_texture, srgb_to_linear, texture_from_texels, TextureOptions};
pub use mip::{MipLevel, MipPyramid};
pub use param::{ColorParam, ScalarParam};

use crate::math::Vec2;
use crate::spectrum::Rgb;

/// Errors while loading a texture. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// The file is missing or unreadable.
    #[error("texture {}: cannot read: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The file is not a decodable PNG or EXR.
    #[error("texture {}: corrupt or unsupported image: {message}", path.display())]
    Corrupt {
        /// The file.
        path: PathBuf,
        /// What the decoder said.
        message: String,
    },
    /// The extension is neither `.png` nor `.exr`.
    #[error("texture {}: unknown image format (expected a .png or .exr file)", path.display())]
    Format {
        /// The file.
        path: PathBuf,
    },
    /// A texel is NaN, infinite or negative.
    #[error("texture {}: pixel ({x}, {y}) (column, row from the top) has {what} value {value} in channel {channel}; texels must be finite and >= 0", path.display())]
    BadTexel {
        /// The file.
        path: PathBuf,
        /// Column.
        x: u32,
        /// Row from the top.
        y: u32,
        /// Channel name.
        channel: &'static str,
        /// "a NaN", "an infinite" or "a negative".
        what: &'static str,
        /// The value.
        value: f32,
    },
    /// A texel is above an upper bound the parameter needs (a mask above 1).
    #[error("texture {}: pixel ({x}, {y}) (column, row from the top) is {value} after scaling, outside [{min}, {max}] ({what})", path.display())]
    OutOfRange {
        /// The file.
        path: PathBuf,
        /// Column.
        x: u32,
        /// Row from the top.
        y: u32,
        /// The value.
        value: f32,
        /// Lowest allowed value.
        min: f32,
        /// Highest allowed value.
        max: f32,
        /// Which parameter needs the range.
        what: String,
    },
    /// The EXR has no channel that can be read as asked.
    #[error("texture {}: {message}", path.display())]
    Channels {
        /// The file.
        path: PathBuf,
        /// What is missing.
        message: String,
    },
    /// The image is empty.
    #[error("texture {}: the image has no pixels", path.display())]
    Empty {
        /// The file.
        path: PathBuf,
    },
}

/// How a texture is read where `u` or `v` leaves [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wrap {
    /// Periodic: `T(u + 1) = T(u)`.
    Repeat,
    /// The edge texel continues.
    Clamp,
}

/// How 8/16-bit colour values are decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ColorSpace {
    /// The sRGB transfer function is undone (IEC 61966-2-1; docs/references.md §14.1).
    Srgb,
    /// Values are used as stored.
    Linear,
}

/// Which channel of the image a single-channel parameter (or a grey colour) reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Channel {
    /// Red.
    R,
    /// Green.
    G,
    /// Blue.
    B,
    /// Alpha (always linear).
    A,
    /// Rec. 709 luminance of the (decoded) RGB.
    Luminance,
}

impl Channel {
    /// The scene-file name.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Channel::R => "r",
            Channel::G => "g",
            Channel::B => "b",
            Channel::A => "a",
            Channel::Luminance => "luminance",
        }
    }
}

/// A loaded texture: linear texels (one or three channels, `scale` applied) in a mip pyramid.
#[derive(Debug)]
pub struct Texture {
    /// The file (messages).
    pub path: PathBuf,
    /// The pyramid.
    pub pyramid: MipPyramid,
    /// Wrap mode.
    pub wrap: Wrap,
}

impl Texture {
    /// The filtered value at `uv` for a footprint `width_uv` wide in texture coordinates (one
    /// unit = the whole image): trilinear between the two mip levels around
    /// λ = log2(width_uv · max(W, H)) (docs/references.md §14.1). A width of 0 reads level 0
    /// bilinearly. Single-channel textures return grey.
    #[inline]
    #[must_use]
    pub fn eval(&self, uv: Vec2, width_uv: f32) -> Rgb {
        let texels = width_uv * self.pyramid.side() as f32;
        self.pyramid.trilinear(uv, texels, self.wrap)
    }

    /// The filtered scalar (first channel) at `uv`: see [`Texture::eval`].
    #[inline]
    #[must_use]
    pub fn eval_scalar(&self, uv: Vec2, width_uv: f32) -> f32 {
        self.eval(uv, width_uv).0[0]
    }

    /// The largest texel of level 0 per channel: no filtered lookup exceeds it.
    #[must_use]
    pub fn max(&self) -> Rgb {
        self.pyramid.max()
    }

    /// The smallest texel of level 0 per channel (grey textures: the same in every channel):
    /// no filtered lookup falls below it. Computed on each call (a pass over level 0).
    #[must_use]
    pub fn min(&self) -> Rgb {
        let level = self.pyramid.level(0);
        let c = self.pyramid.channels().max(1);
        let mut m = [f32::INFINITY; 3];
        for texel in level.texels.chunks_exact(c) {
            for (k, v) in m.iter_mut().enumerate() {
                let x = texel.get(k).or(texel.first()).copied().unwrap_or(0.0);
                *v = v.min(x);
            }
        }
        Rgb(m)
    }

    /// The mean over level 0 per channel (= the value of the coarsest level).
    #[must_use]
    pub fn mean(&self) -> Rgb {
        self.pyramid.mean()
    }

    /// Checks that every level-0 texel is within `[min, max]` in every channel; the error
    /// names the first texel outside and `what` needs the range.
    pub fn check_range(&self, min: f32, max: f32, what: &str) -> Result<(), TextureError> {
        let level = self.pyramid.level(0);
        let c = self.pyramid.channels();
        for (i, texel) in level.texels.chunks_exact(c).enumerate() {
            if let Some(&value) = texel.iter().find(|v| !(**v >= min && **v <= max)) {
                let w = level.width as usize;
                return Err(TextureError::OutOfRange {
                    path: self.path.clone(),
                    x: (i % w) as u32,
                    y: (i / w) as u32,
                    value,
                    min,
                    max,
                    what: what.to_string(),
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
