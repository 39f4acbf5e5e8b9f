//! Image files: OpenEXR read/write (any channel layout, layers as `layer.channel` names in one
//! part), 8-bit sRGB PNG previews, latitude-longitude environment maps, and image comparison
//! ([`compare`]).
//!
//! Conventions:
//! - Pixels are stored row-major, top row first (the EXR data window's order).
//! - The default layer of an EXR is the channels `R`, `G`, `B` (what compositors show); other
//!   layers are channels named `layer.C`, e.g. `variance.R`, `albedo.G`, `normal.X`, `depth.Z`
//!   (the single-part "legacy layer" convention that every compositor reads).
//! - Files are written to `<path>.tmp` and renamed over `<path>` once complete and synced, so a
//!   reader (or a crash) never sees a half-written image.

pub mod compare;

pub use compare::{compare, compare_layer, ChannelStats, CompareError, ImageComparison, ZTest};

use crate::spectrum::Rgb;
use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, Layer, LayerAttributes,
    ReadChannels, ReadLayers, SmallVec, Text, WritableImage,
};
use std::collections::BTreeMap;
use std::io::{BufWriter, Cursor, Write};
use std::path::{Path, PathBuf};

/// Largest accepted width or height of an image, in pixels.
pub const MAX_SIDE: u32 = 65_536;
/// Largest accepted number of pixels in an image (2^31).
pub const MAX_PIXELS: u64 = 1 << 31;
/// Largest accepted number of channels in one EXR file (all parts together).
pub const MAX_CHANNELS: usize = 1024;
/// Largest accepted number of samples (pixels x channels) read from one EXR file: 2^32, i.e.
/// 16 GiB of `f32`. Files whose header declares more are refused before any pixel is decoded.
pub const MAX_SAMPLES: u64 = 1 << 32;

/// Errors of image reading, writing and validation. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file could not be read, created, written or renamed.
    #[error("{}: {what}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done.
        what: &'static str,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not a readable OpenEXR image (corrupt, truncated, unsupported feature).
    #[error("{}: not a readable OpenEXR image: {message}", path.display())]
    Exr {
        /// The file.
        path: PathBuf,
        /// What the decoder reported.
        message: String,
    },
    /// The image's content does not satisfy what the caller requires (missing channels, bad
    /// size, channel length mismatch, unsupported layout).
    #[error("{}: {message}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A texel of an environment map is negative or not finite.
    #[error(
        "{}: texel (x {x}, y {y}) channel {channel} is {value}; environment maps must be finite \
         and non-negative",
        path.display()
    )]
    BadTexel {
        /// The file.
        path: PathBuf,
        /// Column of the first bad texel (0 = left).
        x: u32,
        /// Row of the first bad texel (0 = top).
        y: u32,
        /// Channel name (`R`, `G` or `B`).
        channel: &'static str,
        /// The offending value.
        value: f32,
    },
    /// The PNG encoder failed.
    #[error("{}: cannot encode PNG: {message}", path.display())]
    Png {
        /// The file.
        path: PathBuf,
        /// What the encoder reported.
        message: String,
    },
}

/// A decoded EXR image: every float channel as `f32` and every integer channel as `u32`,
/// row-major, top row first.
///
/// Channel names are the full EXR names (`R`, `variance.G`, `normal.X`, ...). For a multi-part
/// file, channels of parts other than the first are prefixed with the part's name
/// (`partname.R`) when it has one.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExrImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Channel name -> `width * height` samples, row-major, top row first.
    pub channels: BTreeMap<String, Vec<f32>>,
    /// 32-bit unsigned integer channels (EXR `UINT`), kept exact: name -> samples. Integer
    /// channels read from a file land here, not in [`ExrImage::channels`].
    pub uint_channels: BTreeMap<String, Vec<u32>>,
    /// Text attributes of the (first) header that are not standard EXR attributes, e.g.
    /// `velour:spp`. Written back as EXR `string` attributes.
    pub attributes: BTreeMap<String, String>,
}

/// Channel suffixes tried, in order, when a three-channel layer is looked up by [`ExrImage::rgb`].
const TRIPLE_SUFFIXES: [[&str; 3]; 3] = [["R", "G", "B"], ["X", "Y", "Z"], ["r", "g", "b"]];

impl ExrImage {
    /// An image of the given size with no channels.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        ExrImage {
            width,
            height,
            channels: BTreeMap::new(),
            uint_channels: BTreeMap::new(),
            attributes: BTreeMap::new(),
        }
    }

    /// Number of pixels (`width * height`).
    #[must_use]
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The samples of one channel by full name, if present.
    #[must_use]
    pub fn channel(&self, name: &str) -> Option<&[f32]> {
        self.channels.get(name).map(Vec::as_slice)
    }

    /// The full channel names of a three-channel layer: `""` is the default layer (`R`, `G`,
    /// `B`), any other name `layer.R/G/B`, falling back to `layer.X/Y/Z` (normals, positions)
    /// and lowercase `layer.r/g/b`. `None` when no complete triple exists.
    #[must_use]
    pub fn rgb_channel_names(&self, layer: &str) -> Option<[String; 3]> {
        TRIPLE_SUFFIXES.iter().find_map(|suffixes| {
            let names = suffixes.map(|s| layer_channel_name(layer, s));
            names
                .iter()
                .all(|n| self.channels.contains_key(n))
                .then_some(names)
        })
    }

    /// The pixels of a three-channel layer as [`Rgb`] (see [`ExrImage::rgb_channel_names`] for
    /// how the layer's channels are found). `None` when the layer is missing or a channel has
    /// the wrong length.
    #[must_use]
    pub fn rgb(&self, layer: &str) -> Option<Vec<Rgb>> {
        let names = self.rgb_channel_names(layer)?;
        let [r, g, b] = names.map(|n| self.channels.get(&n));
        let (r, g, b) = (r?, g?, b?);
        let n = self.pixel_count();
        if r.len() != n || g.len() != n || b.len() != n {
            return None;
        }
        Some(
            r.iter()
                .zip(g)
                .zip(b)
                .map(|((&r, &g), &b)| Rgb::new(r, g, b))
                .collect(),
        )
    }

    /// Inserts (or replaces) a three-channel layer from [`Rgb`] pixels: `""` writes `R`, `G`,
    /// `B`; any other name `layer.R/G/B`. `pixels` must hold `width * height` values (checked by
    /// [`write_exr`]).
    pub fn insert_rgb(&mut self, layer: &str, pixels: &[Rgb]) {
        for (i, s) in ["R", "G", "B"].iter().enumerate() {
            self.channels.insert(
                layer_channel_name(layer, s),
                pixels.iter().map(|p| p.0[i]).collect(),
            );
        }
    }

    /// The layer names present: `""` for channels without a dot, otherwise the part of the name
    /// before the last dot.
    #[must_use]
    pub fn layers(&self) -> Vec<String> {
        let mut v: Vec<String> = self
            .channels
            .keys()
            .map(|n| layer_of(n).to_string())
            .collect();
        v.dedup();
        v.sort();
        v.dedup();
        v
    }

    /// The channel names of one layer, in name order (`""` = channels without a dot).
    #[must_use]
    pub fn layer_channels(&self, layer: &str) -> Vec<String> {
        self.channels
            .keys()
            .filter(|n| layer_of(n) == layer)
            .cloned()
            .collect()
    }
}

/// `layer.suffix`, or just `suffix` for the default layer `""`.
#[must_use]
pub fn layer_channel_name(layer: &str, suffix: &str) -> String {
    if layer.is_empty() {
        suffix.to_string()
    } else {
        format!("{layer}.{suffix}")
    }
}

/// The layer part of a full channel name (everything before the last dot; `""` if none).
#[must_use]
pub fn layer_of(channel: &str) -> &str {
    channel.rfind('.').map_or("", |i| &channel[..i])
}

fn exr_err(path: &Path, e: impl std::fmt::Display) -> ImageError {
    ImageError::Exr {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

fn invalid(path: &Path, message: impl Into<String>) -> ImageError {
    ImageError::Invalid {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

/// Reads an OpenEXR file: every channel of every part (layer) whose size equals the first
/// part's, `f16` and `f32` channels converted to `f32`, `u32` channels kept exact in
/// [`ExrImage::uint_channels`]; for tiled or
/// mip-mapped files the largest level. Deep images, sub-sampled channels and headers declaring
/// absurd sizes (beyond [`MAX_SIDE`], [`MAX_PIXELS`], [`MAX_CHANNELS`], [`MAX_SAMPLES`]) are
/// refused. A corrupt or truncated file is an error naming the file, never a panic.
pub fn read_exr(path: &Path) -> Result<ExrImage, ImageError> {
    let bytes = std::fs::read(path).map_err(|source| ImageError::Io {
        path: path.to_path_buf(),
        what: "cannot read",
        source,
    })?;
    read_exr_bytes(path, &bytes)
}

/// Like [`read_exr`] for an EXR file already in memory; `path` is used only in error messages.
pub fn read_exr_bytes(path: &Path, bytes: &[u8]) -> Result<ExrImage, ImageError> {
    // Validate the header before decoding, so that a corrupt size never turns into a huge
    // allocation inside the decoder.
    let meta = exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| exr_err(path, e))?;
    if meta.headers.is_empty() {
        return Err(invalid(path, "the file has no image part"));
    }
    let mut total_channels = 0usize;
    let mut total_samples = 0u64;
    for header in &meta.headers {
        if header.deep {
            return Err(invalid(path, "deep images are not supported"));
        }
        let (w, h) = (header.layer_size.0 as u64, header.layer_size.1 as u64);
        if w == 0 || h == 0 || w > MAX_SIDE as u64 || h > MAX_SIDE as u64 || w * h > MAX_PIXELS {
            return Err(invalid(
                path,
                format!(
                    "unsupported image size {w}x{h} (at most {MAX_SIDE} per side and 2^31 pixels)"
                ),
            ));
        }
        total_channels += header.channels.list.len();
        total_samples = total_samples.saturating_add(w * h * header.channels.list.len() as u64);
        for c in &header.channels.list {
            if c.sampling.0 != 1 || c.sampling.1 != 1 {
                return Err(invalid(
                    path,
                    format!("channel {} is sub-sampled, which is not supported", c.name),
                ));
            }
        }
    }
    if total_channels > MAX_CHANNELS || total_samples > MAX_SAMPLES {
        return Err(invalid(
            path,
            format!("{total_channels} channels of {total_samples} samples in all: too large"),
        ));
    }

    // The decoder is not ours: a panic inside it on a malformed file is turned into an error.
    let decoded = std::panic::catch_unwind(|| {
        exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_buffered(Cursor::new(bytes))
    });
    let image = match decoded {
        Ok(Ok(image)) => image,
        Ok(Err(e)) => return Err(exr_err(path, e)),
        Err(_) => return Err(exr_err(path, "the decoder failed on malformed data")),
    };

    let first = image
        .layer_data
        .first()
        .ok_or_else(|| invalid(path, "the file has no image part"))?;
    let (w, h) = (first.size.0, first.size.1);
    let mut out = ExrImage::new(w as u32, h as u32);
    for (name, value) in &first.attributes.other {
        if let AttributeValue::Text(t) = value {
            out.attributes.insert(name.to_string(), t.to_string());
        }
    }
    for (index, layer) in image.layer_data.iter().enumerate() {
        if layer.size != first.size {
            continue;
        }
        let prefix = match (&layer.attributes.layer_name, index) {
            (_, 0) | (None, _) => String::new(),
            (Some(n), _) => n.to_string(),
        };
        for channel in &layer.channel_data.list {
            if let FlatSamples::U32(words) = &channel.sample_data {
                if words.len() != w * h {
                    return Err(invalid(
                        path,
                        format!(
                            "channel {} holds {} samples, expected {}",
                            channel.name,
                            words.len(),
                            w * h
                        ),
                    ));
                }
                let name = layer_channel_name(&prefix, &channel.name.to_string());
                out.uint_channels.insert(name, words.clone());
                continue;
            }
            let samples: Vec<f32> = channel.sample_data.values_as_f32().collect();
            if samples.len() != w * h {
                return Err(invalid(
                    path,
                    format!(
                        "channel {} holds {} samples, expected {}",
                        channel.name,
                        samples.len(),
                        w * h
                    ),
                ));
            }
            let name = layer_channel_name(&prefix, &channel.name.to_string());
            out.channels.insert(name, samples);
        }
    }
    Ok(out)
}

/// The temporary file an atomic write goes through: `<path>.tmp`.
#[must_use]
pub fn temp_path(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_os_string();
    s.push(".tmp");
    PathBuf::from(s)
}

/// Writes a file atomically: `write` fills a buffered writer on `<path>.tmp`, which is then
/// flushed, synced to disk and renamed over `path`. On failure the temporary file is removed.
pub(crate) fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<std::fs::File>) -> Result<(), ImageError>,
) -> Result<(), ImageError> {
    let tmp = temp_path(path);
    let io = |what: &'static str| {
        let path = path.to_path_buf();
        move |source| ImageError::Io { path, what, source }
    };
    let result = (|| {
        let file = std::fs::File::create(&tmp).map_err(io("cannot create temporary file"))?;
        let mut writer = BufWriter::new(file);
        write(&mut writer)?;
        writer.flush().map_err(io("cannot write"))?;
        let file = writer.into_inner().map_err(|e| ImageError::Io {
            path: path.to_path_buf(),
            what: "cannot write",
            source: e.into_error(),
        })?;
        file.sync_all().map_err(io("cannot sync"))?;
        drop(file);
        std::fs::rename(&tmp, path).map_err(io("cannot rename temporary file over"))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Writes an EXR file: one scan-line part, ZIP (16 lines) lossless compression, float channels
/// as 32-bit float and [`ExrImage::uint_channels`] as 32-bit unsigned integers, plus the image's text [`ExrImage::attributes`]. Written to `<path>.tmp` and
/// renamed. Channels must hold `width * height` samples and the size must be within
/// [`MAX_SIDE`] / [`MAX_PIXELS`].
pub fn write_exr(path: &Path, image: &ExrImage) -> Result<(), ImageError> {
    write_exr_owned(path, image.clone())
}

/// [`write_exr`] taking the image by value, which saves a copy of every channel.
pub fn write_exr_owned(path: &Path, image: ExrImage) -> Result<(), ImageError> {
    validate_size(path, image.width, image.height)?;
    if image.channels.is_empty() {
        return Err(invalid(path, "an EXR image needs at least one channel"));
    }
    let channel_count = image.channels.len() + image.uint_channels.len();
    if channel_count > MAX_CHANNELS {
        return Err(invalid(
            path,
            format!("too many channels ({channel_count})"),
        ));
    }
    let n = image.pixel_count();
    let mut list = Vec::with_capacity(channel_count);
    let typed = image
        .channels
        .into_iter()
        .map(|(name, v)| (name, FlatSamples::F32(v)))
        .chain(
            image
                .uint_channels
                .into_iter()
                .map(|(name, v)| (name, FlatSamples::U32(v))),
        );
    for (name, samples) in typed {
        if samples.len() != n {
            return Err(invalid(
                path,
                format!(
                    "channel {name} holds {} samples, expected {n}",
                    samples.len()
                ),
            ));
        }
        let text = Text::new_or_none(&name)
            .filter(|_| !name.is_empty())
            .ok_or_else(|| {
                invalid(
                    path,
                    format!("channel name {name:?} is empty or not Latin-1"),
                )
            })?;
        list.push(AnyChannel::new(text, samples));
    }
    let mut attributes = LayerAttributes::default();
    for (k, v) in &image.attributes {
        let (Some(key), Some(value)) = (Text::new_or_none(k), Text::new_or_none(v)) else {
            return Err(invalid(
                path,
                format!("attribute {k:?} is not Latin-1 text"),
            ));
        };
        attributes.other.insert(key, AttributeValue::Text(value));
    }
    let layer = Layer::new(
        (image.width as usize, image.height as usize),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    let exr_image = Image::from_layer(layer);
    write_atomically(path, |w| {
        exr_image
            .write()
            .to_buffered(w)
            .map_err(|e| exr_err(path, e))
    })
}

fn validate_size(path: &Path, width: u32, height: u32) -> Result<(), ImageError> {
    if width == 0
        || height == 0
        || width > MAX_SIDE
        || height > MAX_SIDE
        || width as u64 * height as u64 > MAX_PIXELS
    {
        return Err(invalid(
            path,
            format!("unsupported image size {width}x{height} (1..={MAX_SIDE} per side, at most 2^31 pixels)"),
        ));
    }
    Ok(())
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1): linear `[0, 1]` -> encoded
/// `[0, 1]`. Inputs are clamped to `[0, 1]`; NaN maps to 0.
#[must_use]
pub fn srgb_oetf(linear: f32) -> f32 {
    let v = if linear.is_nan() {
        0.0
    } else {
        linear.clamp(0.0, 1.0)
    };
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Quantises an encoded `[0, 1]` value to 8 bits, rounding to nearest.
fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Writes an 8-bit sRGB PNG of linear RGB pixels (row-major, top row first): each channel is
/// multiplied by `2^exposure` (exposure in stops), clamped to `[0, 1]` and encoded with the sRGB
/// OETF ([`srgb_oetf`]). Written to `<path>.tmp` and renamed.
pub fn write_png_rgb(
    path: &Path,
    width: u32,
    height: u32,
    linear_rgb: &[Rgb],
    exposure: f32,
) -> Result<(), ImageError> {
    validate_size(path, width, height)?;
    if linear_rgb.len() != width as usize * height as usize {
        return Err(invalid(
            path,
            format!(
                "{} pixels given for a {width}x{height} PNG",
                linear_rgb.len()
            ),
        ));
    }
    let scale = if exposure.is_finite() {
        exposure.exp2()
    } else {
        1.0
    };
    let bytes: Vec<u8> = linear_rgb
        .iter()
        .flat_map(|p| p.0.map(|c| to_u8(srgb_oetf(c * scale))))
        .collect();
    write_png_rgb8(path, width, height, &bytes)
}

/// Writes already-encoded 8-bit RGB bytes (`3 * width * height`, row-major, top row first) as a
/// PNG, atomically through `<path>.tmp`.
pub fn write_png_rgb8(path: &Path, width: u32, height: u32, rgb8: &[u8]) -> Result<(), ImageError> {
    use image::ImageEncoder;
    validate_size(path, width, height)?;
    if rgb8.len() != 3 * width as usize * height as usize {
        return Err(invalid(
            path,
            format!("{} bytes given for a {width}x{height} RGB PNG", rgb8.len()),
        ));
    }
    write_atomically(path, |w| {
        image::codecs::png::PngEncoder::new(w)
            .write_image(rgb8, width, height, image::ExtendedColorType::Rgb8)
            .map_err(|e| ImageError::Png {
                path: path.to_path_buf(),
                message: e.to_string(),
            })
    })
}

/// An equirectangular (latitude-longitude) environment map: `width x height` linear RGB texels,
/// row-major, top row first (row 0 = the top pole). How directions map to texels is the light's
/// business.
#[derive(Clone, Debug, PartialEq)]
pub struct LatLongMap {
    /// Width in texels (longitude).
    pub width: u32,
    /// Height in texels (latitude).
    pub height: u32,
    /// `width * height` texels, row-major, top row first; every channel finite and >= 0.
    pub texels: Vec<Rgb>,
}

/// Reads an environment map from the default layer (`R`, `G`, `B`) of an EXR file. Errors name
/// the file when a channel is missing and name the first texel (in row-major order) that is
/// negative or not finite.
pub fn read_latlong_exr(path: &Path) -> Result<LatLongMap, ImageError> {
    let image = read_exr(path)?;
    let texels = image.rgb("").ok_or_else(|| {
        let present: Vec<&str> = image.channels.keys().map(String::as_str).collect();
        invalid(
            path,
            format!(
                "an environment map needs channels R, G and B; the file has {}",
                if present.is_empty() {
                    "none".to_string()
                } else {
                    present.join(", ")
                }
            ),
        )
    })?;
    for (i, t) in texels.iter().enumerate() {
        for (c, &v) in t.0.iter().enumerate() {
            if !v.is_finite() || v < 0.0 {
                return Err(ImageError::BadTexel {
                    path: path.to_path_buf(),
                    x: (i % image.width as usize) as u32,
                    y: (i / image.width as usize) as u32,
                    channel: ["R", "G", "B"][c],
                    value: v,
                });
            }
        }
    }
    Ok(LatLongMap {
        width: image.width,
        height: image.height,
        texels,
    })
}
