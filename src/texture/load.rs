//! Texture files → validated linear texels: PNG (8 or 16 bit, grey or colour, with or
//! without alpha) through the `image` crate, OpenEXR through [`crate::image_io::read_exr`].
//! Colour data is decoded before filtering (docs/references.md §14.1); alpha is linear.

use std::path::Path;

use super::{Channel, ColorSpace, MipLevel, MipPyramid, Texture, TextureError, Wrap};
use crate::image_io::read_exr;

/// How a file is turned into a texture. Two parameters naming the same file with equal
/// options share one [`Texture`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureOptions {
    /// How colour (R, G, B) values are decoded.
    pub colorspace: ColorSpace,
    /// One channel (a scalar texture) or `None` for RGB.
    pub channel: Option<Channel>,
    /// Multiplier applied to every value after decoding.
    pub scale: f32,
    /// Wrap mode.
    pub wrap: Wrap,
}

/// The sRGB decoding function (IEC 61966-2-1): c ≤ 0.04045 → c/12.92, else
/// ((c + 0.055)/1.055)^2.4 (docs/references.md §14.1).
#[inline]
#[must_use]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Decoded pixels: RGBA per pixel, row-major, top row first, before any transfer function.
struct Rgba {
    width: u32,
    height: u32,
    pixels: Vec<[f32; 4]>,
}

/// Reads a PNG: 8-bit values / 255, 16-bit values / 65535; grey is replicated into RGB and a
/// missing alpha is 1.
fn read_png(path: &Path, bytes: &[u8]) -> Result<Rgba, TextureError> {
    use image::ColorType;
    let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).map_err(|e| {
        TextureError::Corrupt {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    })?;
    let (width, height) = (img.width(), img.height());
    let pixels: Vec<[f32; 4]> = match img.color() {
        ColorType::L8 | ColorType::La8 | ColorType::Rgb8 | ColorType::Rgba8 => img
            .to_rgba8()
            .pixels()
            .map(|p| p.0.map(|c| f32::from(c) / 255.0))
            .collect(),
        ColorType::L16 | ColorType::La16 | ColorType::Rgb16 | ColorType::Rgba16 => img
            .to_rgba16()
            .pixels()
            .map(|p| p.0.map(|c| f32::from(c) / 65535.0))
            .collect(),
        _ => img.to_rgba32f().pixels().map(|p| p.0).collect(),
    };
    Ok(Rgba {
        width,
        height,
        pixels,
    })
}

/// Reads an EXR: `R`, `G`, `B` (or a single channel, e.g. `Y`, as grey) and `A` (1 when
/// absent).
fn read_exr_rgba(path: &Path) -> Result<Rgba, TextureError> {
    let img = read_exr(path).map_err(|e| TextureError::Corrupt {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let n = img.pixel_count();
    let rgb: Vec<[f32; 3]> = match img.rgb("") {
        Some(rgb) => rgb.into_iter().map(|c| c.0).collect(),
        None => {
            let grey = ["Y", "L", "R"]
                .iter()
                .find_map(|name| img.channel(name))
                .or_else(|| {
                    let mut it = img.channels.values();
                    match (it.next(), it.next()) {
                        (Some(only), None) => Some(only.as_slice()),
                        _ => None,
                    }
                })
                .ok_or_else(|| TextureError::Channels {
                    path: path.to_path_buf(),
                    message: format!(
                        "no R, G, B channels and no single grey channel (channels: {:?})",
                        img.channels.keys().collect::<Vec<_>>()
                    ),
                })?;
            grey.iter().map(|&g| [g; 3]).collect()
        }
    };
    let alpha = img.channel("A");
    if rgb.len() != n || alpha.is_some_and(|a| a.len() != n) {
        return Err(TextureError::Channels {
            path: path.to_path_buf(),
            message: "channels of different sizes".to_string(),
        });
    }
    let pixels = rgb
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let a = alpha.and_then(|a| a.get(i).copied()).unwrap_or(1.0);
            [c[0], c[1], c[2], a]
        })
        .collect();
    Ok(Rgba {
        width: img.width,
        height: img.height,
        pixels,
    })
}

/// "a NaN", "an infinite" or "a negative" for a bad texel value, `None` for a good one.
fn bad_value(v: f32) -> Option<&'static str> {
    if v.is_nan() {
        Some("a NaN")
    } else if v.is_infinite() {
        Some("an infinite")
    } else if v < 0.0 {
        Some("a negative")
    } else {
        None
    }
}

/// Loads `path` (`.png` or `.exr`, by extension) as a texture: decoded, checked (NaN,
/// infinite and negative texels are refused, naming the pixel), reduced to one channel or
/// RGB, scaled, and mip-mapped.
pub fn load_texture(path: &Path, opts: &TextureOptions) -> Result<Texture, TextureError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let image = match ext.as_deref() {
        Some("png") => {
            let bytes = std::fs::read(path).map_err(|source| TextureError::Io {
                path: path.to_path_buf(),
                source,
            })?;
            read_png(path, &bytes)?
        }
        Some("exr") => {
            if let Err(source) = std::fs::metadata(path) {
                return Err(TextureError::Io {
                    path: path.to_path_buf(),
                    source,
                });
            }
            read_exr_rgba(path)?
        }
        _ => {
            return Err(TextureError::Format {
                path: path.to_path_buf(),
            })
        }
    };
    if image.width == 0 || image.height == 0 || image.pixels.is_empty() {
        return Err(TextureError::Empty {
            path: path.to_path_buf(),
        });
    }
    let names = ["R", "G", "B", "A"];
    let w = image.width as usize;
    let channels = if opts.channel.is_some() { 1 } else { 3 };
    let mut texels = Vec::with_capacity(image.pixels.len() * channels);
    for (i, px) in image.pixels.iter().enumerate() {
        for (c, &v) in px.iter().enumerate() {
            if let Some(what) = bad_value(v) {
                return Err(TextureError::BadTexel {
                    path: path.to_path_buf(),
                    x: (i % w) as u32,
                    y: (i / w) as u32,
                    channel: names[c],
                    what,
                    value: v,
                });
            }
        }
        let decode = |c: f32| match opts.colorspace {
            ColorSpace::Srgb => srgb_to_linear(c),
            ColorSpace::Linear => c,
        };
        let rgb = [decode(px[0]), decode(px[1]), decode(px[2])];
        match opts.channel {
            None => texels.extend(rgb.map(|c| c * opts.scale)),
            Some(ch) => texels.push(
                opts.scale
                    * match ch {
                        Channel::R => rgb[0],
                        Channel::G => rgb[1],
                        Channel::B => rgb[2],
                        Channel::A => px[3],
                        Channel::Luminance => 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2],
                    },
            ),
        }
    }
    let base = MipLevel {
        width: image.width,
        height: image.height,
        texels,
    };
    Ok(Texture {
        path: path.to_path_buf(),
        pyramid: MipPyramid::new(base, channels),
        wrap: opts.wrap,
    })
}

/// A texture made in memory (tests, procedural inputs): `texels` holds `width · height ·
/// channels` linear values, top row first; `name` stands for the file in messages.
pub fn texture_from_texels(
    name: &str,
    width: u32,
    height: u32,
    channels: usize,
    texels: Vec<f32>,
    wrap: Wrap,
) -> Result<Texture, TextureError> {
    let path = std::path::PathBuf::from(name);
    if width == 0 || height == 0 || !(channels == 1 || channels == 3) {
        return Err(TextureError::Empty { path });
    }
    if texels.len() != width as usize * height as usize * channels {
        return Err(TextureError::Channels {
            path,
            message: format!(
                "{} values for {width} × {height} texels of {channels} channels",
                texels.len()
            ),
        });
    }
    let w = width as usize;
    for (i, &v) in texels.iter().enumerate() {
        if let Some(what) = bad_value(v) {
            let p = i / channels;
            return Err(TextureError::BadTexel {
                path,
                x: (p % w) as u32,
                y: (p / w) as u32,
                channel: ["R", "G", "B"][(i % channels).min(2)],
                what,
                value: v,
            });
        }
    }
    Ok(Texture {
        path,
        pyramid: MipPyramid::new(
            MipLevel {
                width,
                height,
                texels,
            },
            channels,
        ),
        wrap,
    })
}
