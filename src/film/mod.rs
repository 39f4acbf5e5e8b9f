//! The film: per-pixel accumulation of radiance samples (mean and variance) and of the
//! auxiliary buffers a denoiser or compositor wants (albedo, normal, depth), with EXR and PNG
//! output.
//!
//! Each pixel is a box-filtered estimate: the mean of the radiance samples taken in it. Every
//! sample is rounded once to a fixed binary grid and the pixel keeps integer sums of the
//! radiance, of its square and of the auxiliary layers ([`fixed`], [`pixel`]): 192-bit sums with
//! 96 and 80 fractional bits for the radiance and its square, far below `f32` resolution. The
//! variance of the mean is (Σx² − (Σx)²/n) / (n (n − 1)), evaluated in `f64` from the exact sums.
//!
//! Determinism: integer addition is exact and associative, so a pixel's accumulator depends only
//! on the set of samples added to it, not on how they were grouped. Tiles, passes, threads,
//! sample ranges rendered by different processes ([`Film::merge_film`]) and a checkpoint resumed
//! later ([`Film::to_state_image`], [`Film::from_exr_image`]) all give the same bits as one
//! uninterrupted render.
//!
//! Output ([`Film::write_exr`]): one EXR part with channels
//! - `R`, `G`, `B`: the beauty (mean radiance),
//! - `variance.R/G/B`: the variance of each pixel's mean (sample variance / n; 0 when n < 2),
//! - `albedo.R/G/B`, `normal.X/Y/Z`: means over the pixel's samples,
//! - `depth.Z`: mean camera-ray hit distance over the samples that hit (+inf when none did),
//! - `samples.N`: the number of samples in the pixel,
//!
//! all 32-bit float, written through `<path>.tmp` and renamed so a reader never sees a partial
//! file. Part files and checkpoints add the exact accumulator state as `UINT` channels
//! `state.*` ([`state`]).

mod fixed;
mod layers;
mod pixel;
mod state;

pub use fixed::MAX_SAMPLE;
pub use pixel::MAX_DEPTH;

use crate::image_io::{self, ExrImage, ImageError};
use crate::math::Vec3;
use crate::spectrum::Rgb;
use layers::LayerSums;
use pixel::Pixel;

/// The attribute naming a state image's light layers in slot order (comma-separated).
pub const LIGHT_LAYERS_ATTRIBUTE: &str = "velour:light_layers";

/// Most lights that can have their own beauty layer (`name = "…"` on a light).
pub const MAX_LIGHT_LAYERS: usize = 8;
use std::collections::BTreeMap;
use std::path::Path;

/// Largest accepted film width or height, in pixels.
pub const MAX_SIDE: u32 = image_io::MAX_SIDE;
/// Largest accepted number of film pixels (2^31).
pub const MAX_PIXELS: u64 = image_io::MAX_PIXELS;

/// Errors of the film.
#[derive(Debug, thiserror::Error)]
pub enum FilmError {
    /// A film or tile size of zero or beyond the limits.
    #[error("film size {width}x{height} is not supported (1..={MAX_SIDE} per side, at most 2^31 pixels)")]
    BadSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// The accumulation buffers could not be allocated.
    #[error("cannot allocate the film buffers for {width}x{height} pixels ({bytes} bytes)")]
    OutOfMemory {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
        /// Bytes requested.
        bytes: u64,
    },
    /// A tile does not lie inside the film.
    #[error(
        "tile at ({x0}, {y0}) of {width}x{height} pixels does not fit in the {film_width}x{film_height} film"
    )]
    TileOutside {
        /// Tile left column.
        x0: u32,
        /// Tile top row.
        y0: u32,
        /// Tile width.
        width: u32,
        /// Tile height.
        height: u32,
        /// Film width.
        film_width: u32,
        /// Film height.
        film_height: u32,
    },
    /// An image with which a film is restored lacks something or disagrees with itself.
    #[error("cannot restore a film from that image: {0}")]
    Restore(String),
    /// Writing an output file failed.
    #[error(transparent)]
    Image(#[from] ImageError),
}

/// One camera sample's contribution to a pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelSample {
    /// Radiance carried along the camera ray (linear RGB, W sr^-1 m^-2 in scene units). A
    /// sample whose radiance is not finite is dropped whole and counted.
    pub radiance: Rgb,
    /// Albedo at the first visible surface or medium (linear RGB in [0, 1]; black for a miss).
    pub albedo: Rgb,
    /// Shading normal at the first hit, world space, unit length (zero for a miss).
    pub normal: Vec3,
    /// Distance along the camera ray to the first hit, in scene units; any non-finite or
    /// negative value means the ray hit nothing.
    pub depth: f32,
    /// The radiance of each named light (by layer slot; the film keeps as many as it was made
    /// with, [`Film::with_light_layers`]): parts of `radiance`.
    pub lights: [Rgb; MAX_LIGHT_LAYERS],
}

fn check_size(width: u32, height: u32) -> Result<(), FilmError> {
    if width == 0
        || height == 0
        || width > MAX_SIDE
        || height > MAX_SIDE
        || u64::from(width) * u64::from(height) > MAX_PIXELS
    {
        return Err(FilmError::BadSize { width, height });
    }
    Ok(())
}

fn alloc_pixels(width: u32, height: u32) -> Result<Vec<Pixel>, FilmError> {
    let count = width as usize * height as usize;
    let mut v = Vec::new();
    v.try_reserve_exact(count)
        .map_err(|_| FilmError::OutOfMemory {
            width,
            height,
            bytes: count as u64 * std::mem::size_of::<Pixel>() as u64,
        })?;
    v.resize(count, Pixel::default());
    Ok(v)
}

/// A rectangle of pixel accumulators, filled by one worker and merged into the [`Film`] with
/// [`Film::merge_tile`]. Coordinates are absolute film coordinates.
#[derive(Clone, Debug)]
pub struct FilmTile {
    x0: u32,
    y0: u32,
    width: u32,
    height: u32,
    pixels: Vec<Pixel>,
    layers: LayerSums,
    dropped: u64,
}

impl FilmTile {
    /// Left column of the tile in the film.
    #[must_use]
    pub fn x0(&self) -> u32 {
        self.x0
    }
    /// Top row of the tile in the film.
    #[must_use]
    pub fn y0(&self) -> u32 {
        self.y0
    }
    /// Width of the tile in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height of the tile in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Adds a sample to pixel (`x`, `y`) in film coordinates. Samples with non-finite radiance,
    /// and samples outside the tile, are dropped and counted (see [`FilmTile::dropped_samples`]).
    #[inline]
    pub fn add_sample(&mut self, x: u32, y: u32, s: &PixelSample) {
        let (dx, dy) = (x.wrapping_sub(self.x0), y.wrapping_sub(self.y0));
        if dx >= self.width || dy >= self.height || !pixel::accepts(s, self.layers.count()) {
            self.dropped += 1;
            return;
        }
        let i = dy as usize * self.width as usize + dx as usize;
        self.pixels[i].add(s);
        if self.layers.count() > 0 {
            self.layers.add(i, s);
        }
    }

    /// Samples dropped by this tile since it was made.
    #[must_use]
    pub fn dropped_samples(&self) -> u64 {
        self.dropped
    }

    /// Clears the accumulators (keeps the rectangle), so a worker can reuse the tile.
    pub fn clear(&mut self) {
        self.pixels.fill(Pixel::default());
        self.layers.clear();
        self.dropped = 0;
    }
}

/// A `width x height` film of per-pixel accumulators (see the module documentation).
#[derive(Clone, Debug)]
pub struct Film {
    width: u32,
    height: u32,
    pixels: Vec<Pixel>,
    layer_names: Vec<String>,
    layers: LayerSums,
    dropped: u64,
}

impl Film {
    /// An empty film. Refuses a zero side, a side beyond [`MAX_SIDE`], more than [`MAX_PIXELS`]
    /// pixels, or a size whose buffers cannot be allocated (216 bytes a pixel).
    pub fn new(width: u32, height: u32) -> Result<Film, FilmError> {
        Film::with_light_layers(width, height, &[])
    }

    /// An empty film that also keeps a beauty layer per named light (`names` by slot, at most
    /// [`MAX_LIGHT_LAYERS`]), written as `light.<name>.R/G/B`.
    pub fn with_light_layers(width: u32, height: u32, names: &[String]) -> Result<Film, FilmError> {
        check_size(width, height)?;
        if names.len() > MAX_LIGHT_LAYERS {
            return Err(FilmError::Restore(format!(
                "{} light layers, at most {MAX_LIGHT_LAYERS}",
                names.len()
            )));
        }
        let pixels = alloc_pixels(width, height)?;
        Ok(Film {
            width,
            height,
            layers: LayerSums::new(pixels.len(), names.len())?,
            pixels,
            layer_names: names.to_vec(),
            dropped: 0,
        })
    }

    /// The names of the per-light layers, by slot.
    #[must_use]
    pub fn light_layer_names(&self) -> &[String] {
        &self.layer_names
    }

    /// Width in pixels.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in pixels.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    #[inline]
    fn index(&self, x: u32, y: u32) -> Option<usize> {
        (x < self.width && y < self.height).then(|| y as usize * self.width as usize + x as usize)
    }

    /// Adds a sample to pixel (`x`, `y`) (0, 0 = top left). A sample with non-finite radiance,
    /// or outside the film, is dropped and counted in [`Film::dropped_samples`]; non-finite
    /// albedo or normal components count as 0.
    #[inline]
    pub fn add_sample(&mut self, x: u32, y: u32, s: &PixelSample) {
        match self.index(x, y) {
            Some(i) if pixel::accepts(s, self.layers.count()) => {
                self.pixels[i].add(s);
                if self.layers.count() > 0 {
                    self.layers.add(i, s);
                }
            }
            _ => self.dropped += 1,
        }
    }

    /// An empty tile for the rectangle at (`x0`, `y0`) of `width x height` pixels, clipped to the
    /// film. Errors when the clipped rectangle is empty.
    pub fn tile(&self, x0: u32, y0: u32, width: u32, height: u32) -> Result<FilmTile, FilmError> {
        let w = width.min(self.width.saturating_sub(x0));
        let h = height.min(self.height.saturating_sub(y0));
        if w == 0 || h == 0 {
            return Err(FilmError::TileOutside {
                x0,
                y0,
                width,
                height,
                film_width: self.width,
                film_height: self.height,
            });
        }
        Ok(FilmTile {
            x0,
            y0,
            width: w,
            height: h,
            pixels: alloc_pixels(w, h)?,
            layers: LayerSums::new(w as usize * h as usize, self.layers.count())?,
            dropped: 0,
        })
    }

    /// Empty tiles of `tile_size x tile_size` pixels (smaller at the right and bottom edges)
    /// covering the film, in row-major order of their top-left corners. A `tile_size` of 0 is
    /// taken as 1.
    pub fn tiles(&self, tile_size: u32) -> Result<Vec<FilmTile>, FilmError> {
        let t = tile_size.max(1);
        let mut out = Vec::new();
        for y0 in (0..self.height).step_by(t as usize) {
            for x0 in (0..self.width).step_by(t as usize) {
                out.push(self.tile(x0, y0, t, t)?);
            }
        }
        Ok(out)
    }

    /// Merges a tile's accumulators into the film (pairwise merge per pixel) and adds its
    /// dropped-sample count. Errors when the tile does not lie inside the film.
    pub fn merge_tile(&mut self, tile: &FilmTile) -> Result<(), FilmError> {
        if u64::from(tile.x0) + u64::from(tile.width) > u64::from(self.width)
            || u64::from(tile.y0) + u64::from(tile.height) > u64::from(self.height)
            || tile.pixels.len() != tile.width as usize * tile.height as usize
        {
            return Err(FilmError::TileOutside {
                x0: tile.x0,
                y0: tile.y0,
                width: tile.width,
                height: tile.height,
                film_width: self.width,
                film_height: self.height,
            });
        }
        let (fw, tw) = (self.width as usize, tile.width as usize);
        for (ty, row) in tile.pixels.chunks_exact(tw).enumerate() {
            let start = (tile.y0 as usize + ty) * fw + tile.x0 as usize;
            for (dst, src) in self.pixels[start..start + tw].iter_mut().zip(row) {
                dst.merge(src);
            }
            if self.layers.count() > 0 {
                for x in 0..tw {
                    self.layers
                        .merge_pixel(start + x, &tile.layers, ty * tw + x);
                }
            }
        }
        self.dropped += tile.dropped;
        Ok(())
    }

    /// Merges many tiles in a fixed order (by top row, then left column, then size), whatever
    /// the order they come in, so that even overlapping tiles give a bit-identical film.
    pub fn merge_tiles(
        &mut self,
        tiles: impl IntoIterator<Item = FilmTile>,
    ) -> Result<(), FilmError> {
        let mut tiles: Vec<FilmTile> = tiles.into_iter().collect();
        tiles.sort_by_key(|t| (t.y0, t.x0, t.height, t.width));
        for t in &tiles {
            self.merge_tile(t)?;
        }
        Ok(())
    }

    fn px(&self, x: u32, y: u32) -> Pixel {
        self.index(x, y).map(|i| self.pixels[i]).unwrap_or_default()
    }

    /// Mean radiance of pixel (`x`, `y`) (black when it has no samples or lies outside).
    #[must_use]
    pub fn mean(&self, x: u32, y: u32) -> Rgb {
        self.px(x, y).mean()
    }

    /// Variance of the pixel's mean: the unbiased sample variance divided by the sample count,
    /// per channel; 0 when the pixel has fewer than 2 samples.
    #[must_use]
    pub fn variance_of_mean(&self, x: u32, y: u32) -> Rgb {
        self.px(x, y).variance_of_mean()
    }

    /// Mean albedo of the pixel's samples.
    #[must_use]
    pub fn albedo(&self, x: u32, y: u32) -> Rgb {
        let p = self.px(x, y);
        Rgb(p.aux_mean(p.albedo))
    }

    /// Mean normal of the pixel's samples (not renormalised).
    #[must_use]
    pub fn normal(&self, x: u32, y: u32) -> Vec3 {
        let p = self.px(x, y);
        Vec3::from_array(p.aux_mean(p.normal))
    }

    /// Mean hit distance of the pixel's samples that hit something; +inf when none did.
    #[must_use]
    pub fn depth(&self, x: u32, y: u32) -> f32 {
        self.px(x, y).depth()
    }

    /// Number of samples accumulated in the pixel.
    #[must_use]
    pub fn samples(&self, x: u32, y: u32) -> u32 {
        self.px(x, y).n
    }

    /// Total number of samples accumulated over the film.
    #[must_use]
    pub fn total_samples(&self) -> u64 {
        self.pixels.iter().map(|p| u64::from(p.n)).sum()
    }

    /// Samples dropped (non-finite radiance or outside the film / tile) since the film was made.
    #[must_use]
    pub fn dropped_samples(&self) -> u64 {
        self.dropped
    }

    /// The mean radiance of every pixel, row-major, top row first.
    #[must_use]
    pub fn beauty(&self) -> Vec<Rgb> {
        self.pixels.iter().map(Pixel::mean).collect()
    }

    /// All layers as an [`ExrImage`] (channel names in the module documentation), with the
    /// given text attributes.
    #[must_use]
    pub fn to_exr_image(&self, attributes: &BTreeMap<String, String>) -> ExrImage {
        let mut img = ExrImage::new(self.width, self.height);
        let n = self.pixels.len();
        // The mean and variance need the wide sums converted: once per pixel.
        let means: Vec<Rgb> = self.pixels.iter().map(Pixel::mean).collect();
        let variances: Vec<Rgb> = self.pixels.iter().map(Pixel::variance_of_mean).collect();
        for (c, s) in ["R", "G", "B"].iter().enumerate() {
            img.channels
                .insert((*s).to_string(), means.iter().map(|m| m.0[c]).collect());
            img.channels.insert(
                format!("variance.{s}"),
                variances.iter().map(|v| v.0[c]).collect(),
            );
        }
        let mut put = |name: &str, f: &dyn Fn(&Pixel) -> f32| {
            let mut v = Vec::with_capacity(n);
            v.extend(self.pixels.iter().map(f));
            img.channels.insert(name.to_string(), v);
        };
        for (c, s) in ["R", "G", "B"].iter().enumerate() {
            put(&format!("albedo.{s}"), &|p| p.aux_mean(p.albedo)[c]);
        }
        for (c, s) in ["X", "Y", "Z"].iter().enumerate() {
            put(&format!("normal.{s}"), &|p| p.aux_mean(p.normal)[c]);
        }
        put("depth.Z", &Pixel::depth);
        put(image_io::compare::SAMPLES_CHANNEL, &|p| p.n as f32);
        for (k, name) in self.layer_names.iter().enumerate() {
            for (c, ch) in ["R", "G", "B"].iter().enumerate() {
                let v: Vec<f32> = self
                    .pixels
                    .iter()
                    .enumerate()
                    .map(|(i, p)| {
                        if p.n == 0 {
                            0.0
                        } else {
                            (self.layers.get(i, k)[c].to_f64(pixel::SUM_BITS) / f64::from(p.n))
                                as f32
                        }
                    })
                    .collect();
                img.channels.insert(format!("light.{name}.{ch}"), v);
            }
        }
        img.attributes = attributes.clone();
        img
    }

    /// Writes every layer to an EXR file (see the module documentation), through
    /// `<path>.tmp` and an atomic rename.
    pub fn write_exr(&self, path: &Path) -> Result<(), FilmError> {
        self.write_exr_with_attributes(path, &BTreeMap::new())
    }

    /// [`Film::write_exr`] with extra text attributes in the header (e.g. `velour:spp`,
    /// `velour:seed`); keys and values must be Latin-1.
    pub fn write_exr_with_attributes(
        &self,
        path: &Path,
        attributes: &BTreeMap<String, String>,
    ) -> Result<(), FilmError> {
        image_io::write_exr_owned(path, self.to_exr_image(attributes))?;
        Ok(())
    }

    /// Writes an 8-bit sRGB PNG preview of the beauty (mean radiance times `2^exposure`,
    /// exposure in stops, clamped to [0, 1], sRGB OETF), through `<path>.tmp` and a rename.
    pub fn write_png(&self, path: &Path, exposure: f32) -> Result<(), FilmError> {
        image_io::write_png_rgb(path, self.width, self.height, &self.beauty(), exposure)?;
        Ok(())
    }

    /// All layers plus the exact accumulator state (see [`state`]) as one [`ExrImage`]: what
    /// part files and checkpoints hold.
    #[must_use]
    pub fn to_state_image(&self, attributes: &BTreeMap<String, String>) -> ExrImage {
        let mut img = self.to_exr_image(attributes);
        img.uint_channels = state::encode(&self.pixels);
        if !self.layer_names.is_empty() {
            img.attributes.insert(
                LIGHT_LAYERS_ATTRIBUTE.to_string(),
                self.layer_names.join(","),
            );
            for (k, name) in self.layer_names.iter().enumerate() {
                for (c, ch) in ["R", "G", "B"].iter().enumerate() {
                    for w in 0..6 {
                        let words: Vec<u32> = (0..self.pixels.len())
                            .map(|i| self.layers.get(i, k)[c].to_words()[w])
                            .collect();
                        img.uint_channels.insert(
                            format!("{}light.{name}.{ch}.w{w}", state::STATE_PREFIX),
                            words,
                        );
                    }
                }
            }
        }
        img
    }

    /// Restores a film exactly from an image made by [`Film::to_state_image`] (a part file or a
    /// checkpoint): adding the remaining samples, or merging the other parts, then gives the
    /// same bits as an uninterrupted render. Errors when the state channels are missing,
    /// truncated or inconsistent.
    pub fn from_exr_image(img: &ExrImage) -> Result<Film, FilmError> {
        if !state::present(&img.uint_channels) {
            return Err(FilmError::Restore(
                "the image carries no exact film state (only part files and checkpoints do)"
                    .to_string(),
            ));
        }
        let names: Vec<String> = match img.attributes.get(LIGHT_LAYERS_ATTRIBUTE) {
            Some(list) if !list.is_empty() => list.split(',').map(str::to_string).collect(),
            _ => Vec::new(),
        };
        let mut film = Film::with_light_layers(img.width, img.height, &names)?;
        state::decode(&img.uint_channels, &mut film.pixels)?;
        for (k, name) in names.iter().enumerate() {
            let mut channels = Vec::with_capacity(18);
            for ch in ["R", "G", "B"] {
                for w in 0..6 {
                    let key = format!("{}light.{name}.{ch}.w{w}", state::STATE_PREFIX);
                    let words = img
                        .uint_channels
                        .get(&key)
                        .filter(|v| v.len() == film.pixels.len())
                        .ok_or_else(|| {
                            FilmError::Restore(format!(
                                "state channel {key} is missing or of the wrong length"
                            ))
                        })?;
                    channels.push(words);
                }
            }
            // `i` indexes every one of the 6 × 3 word channels and the film's pixels.
            #[allow(clippy::needless_range_loop)]
            for i in 0..film.pixels.len() {
                let v = std::array::from_fn(|c| {
                    fixed::Fixed192::from_words(std::array::from_fn(|w| channels[c * 6 + w][i]))
                });
                film.layers.set(i, k, v);
            }
        }
        Ok(film)
    }

    /// Adds every pixel of `other`, a band of this film's width whose first row is `row0`
    /// here, to this film: exact, so merging parts in any order gives the same bits.
    pub fn merge_rows(&mut self, other: &Film, row0: u32) -> Result<(), FilmError> {
        if other.width != self.width
            || u64::from(row0) + u64::from(other.height) > u64::from(self.height)
            || other.layer_names != self.layer_names
        {
            return Err(FilmError::Restore(format!(
                "a {}x{} band at row {row0} with light layers {:?} does not fit in a {}x{} film with {:?}",
                other.width, other.height, other.layer_names, self.width, self.height, self.layer_names
            )));
        }
        let start = row0 as usize * self.width as usize;
        for (a, b) in self.pixels[start..].iter_mut().zip(&other.pixels) {
            a.merge(b);
        }
        if self.layers.count() > 0 {
            for i in 0..other.pixels.len() {
                self.layers.merge_pixel(start + i, &other.layers, i);
            }
        }
        self.dropped += other.dropped;
        Ok(())
    }
}
