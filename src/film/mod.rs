//! The film: per-pixel accumulation of radiance samples (mean and variance) and of the
//! auxiliary buffers a denoiser or compositor wants (albedo, normal, depth), with EXR and PNG
//! output.
//!
//! Each pixel is a box-filtered estimate: the mean of the radiance samples taken in it. The
//! mean and the sum of squared deviations are accumulated in `f64` with Welford's update and
//! merged with Chan et al.'s pairwise formula ("Updating formulae and a pairwise algorithm for
//! computing sample variances", 1979), so a constant pixel has exactly zero variance and no
//! cancellation occurs at high sample counts.
//!
//! Determinism: a pixel's accumulator depends only on the sequence of samples added to it and on
//! how they are grouped into [`FilmTile`]s before merging. Tiles cover disjoint pixels in the
//! usual use, so the order in which tiles are merged cannot change a bit; [`Film::merge_tiles`]
//! also sorts tiles by position first, so even overlapping tiles merge in one fixed order. A
//! renderer that adds samples to each pixel in sample-index order, in passes of a fixed sample
//! count, gets a bit-identical film whatever the thread count, tile shape or tile order.
//!
//! Output ([`Film::write_exr`]): one EXR part with channels
//! - `R`, `G`, `B`: the beauty (mean radiance),
//! - `variance.R/G/B`: the variance of each pixel's mean (sample variance / n; 0 when n < 2),
//! - `albedo.R/G/B`, `normal.X/Y/Z`: means over the pixel's samples,
//! - `depth.Z`: mean camera-ray hit distance over the samples that hit (+inf when none did),
//! - `samples.N`: the number of samples in the pixel,
//!
//! all 32-bit float, written through `<path>.tmp` and renamed so a reader never sees a partial
//! file.

use crate::image_io::{self, ExrImage, ImageError};
use crate::math::Vec3;
use crate::spectrum::Rgb;
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
}

/// The accumulator of one pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Pixel {
    /// Samples accumulated.
    n: u32,
    /// Samples with a finite depth.
    hits: u32,
    /// Running mean of the radiance.
    mean: [f64; 3],
    /// Sum of squared deviations from the mean (Welford's M2).
    m2: [f64; 3],
    /// Sums of albedo, normal and hit depth.
    albedo: [f64; 3],
    normal: [f64; 3],
    depth: f64,
}

impl Pixel {
    /// Welford's single-sample update. The sample must have finite radiance.
    #[inline]
    fn add(&mut self, s: &PixelSample) {
        self.n += 1;
        let inv_n = 1.0 / f64::from(self.n);
        for c in 0..3 {
            let x = f64::from(s.radiance.0[c]);
            let d = x - self.mean[c];
            self.mean[c] += d * inv_n;
            self.m2[c] += d * (x - self.mean[c]);
            self.albedo[c] += finite_or_zero(s.albedo.0[c]);
        }
        for (sum, v) in self.normal.iter_mut().zip(s.normal.to_array()) {
            *sum += finite_or_zero(v);
        }
        if s.depth.is_finite() && s.depth >= 0.0 {
            self.hits += 1;
            self.depth += f64::from(s.depth);
        }
    }

    /// Chan et al.'s pairwise merge of another accumulator into this one. When `self` is empty
    /// the result is `o` exactly.
    #[inline]
    fn merge(&mut self, o: &Pixel) {
        if o.n == 0 {
            return;
        }
        if self.n == 0 {
            *self = *o;
            return;
        }
        let (na, nb) = (f64::from(self.n), f64::from(o.n));
        let n = na + nb;
        for c in 0..3 {
            let d = o.mean[c] - self.mean[c];
            self.mean[c] += d * (nb / n);
            self.m2[c] += o.m2[c] + d * d * (na * nb / n);
            self.albedo[c] += o.albedo[c];
            self.normal[c] += o.normal[c];
        }
        self.n = self.n.saturating_add(o.n);
        self.hits = self.hits.saturating_add(o.hits);
        self.depth += o.depth;
    }

    fn mean(&self) -> Rgb {
        Rgb(self.mean.map(|m| m as f32))
    }

    fn variance_of_mean(&self) -> Rgb {
        if self.n < 2 {
            return Rgb::ZERO;
        }
        let n = f64::from(self.n);
        Rgb(self.m2.map(|m2| (m2.max(0.0) / ((n - 1.0) * n)) as f32))
    }

    fn avg(&self, sums: [f64; 3]) -> [f32; 3] {
        if self.n == 0 {
            return [0.0; 3];
        }
        sums.map(|s| (s / f64::from(self.n)) as f32)
    }

    fn depth(&self) -> f32 {
        if self.hits == 0 {
            f32::INFINITY
        } else {
            (self.depth / f64::from(self.hits)) as f32
        }
    }
}

#[inline]
fn finite_or_zero(v: f32) -> f64 {
    if v.is_finite() {
        f64::from(v)
    } else {
        0.0
    }
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
        if dx >= self.width || dy >= self.height || !s.radiance.is_finite() {
            self.dropped += 1;
            return;
        }
        self.pixels[dy as usize * self.width as usize + dx as usize].add(s);
    }

    /// Samples dropped by this tile since it was made.
    #[must_use]
    pub fn dropped_samples(&self) -> u64 {
        self.dropped
    }

    /// Clears the accumulators (keeps the rectangle), so a worker can reuse the tile.
    pub fn clear(&mut self) {
        self.pixels.fill(Pixel::default());
        self.dropped = 0;
    }
}

/// A `width x height` film of per-pixel accumulators (see the module documentation).
#[derive(Clone, Debug)]
pub struct Film {
    width: u32,
    height: u32,
    pixels: Vec<Pixel>,
    dropped: u64,
}

impl Film {
    /// An empty film. Refuses a zero side, a side beyond [`MAX_SIDE`], more than [`MAX_PIXELS`]
    /// pixels, or a size whose buffers cannot be allocated (about 112 bytes a pixel).
    pub fn new(width: u32, height: u32) -> Result<Film, FilmError> {
        check_size(width, height)?;
        Ok(Film {
            width,
            height,
            pixels: alloc_pixels(width, height)?,
            dropped: 0,
        })
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
            Some(i) if s.radiance.is_finite() => self.pixels[i].add(s),
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
        Rgb(p.avg(p.albedo))
    }

    /// Mean normal of the pixel's samples (not renormalised).
    #[must_use]
    pub fn normal(&self, x: u32, y: u32) -> Vec3 {
        let p = self.px(x, y);
        Vec3::from_array(p.avg(p.normal))
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
        let mut put = |name: &str, f: &dyn Fn(&Pixel) -> f32| {
            let mut v = Vec::with_capacity(n);
            v.extend(self.pixels.iter().map(f));
            img.channels.insert(name.to_string(), v);
        };
        for (c, s) in ["R", "G", "B"].iter().enumerate() {
            put(s, &|p| p.mean[c] as f32);
            put(&format!("variance.{s}"), &|p| p.variance_of_mean().0[c]);
            put(&format!("albedo.{s}"), &|p| p.avg(p.albedo)[c]);
        }
        for (c, s) in ["X", "Y", "Z"].iter().enumerate() {
            put(&format!("normal.{s}"), &|p| p.avg(p.normal)[c]);
        }
        put("depth.Z", &Pixel::depth);
        put(image_io::compare::SAMPLES_CHANNEL, &|p| p.n as f32);
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

    /// Restores a film from an image written by [`Film::write_exr`] (e.g. to resume a render):
    /// the mean, variance, sample count and auxiliary layers are turned back into accumulators.
    /// The EXR holds 32-bit values, so a resumed render matches an uninterrupted one only to
    /// `f32` precision. Errors when `R/G/B`, `variance.R/G/B` or `samples.N` are missing.
    pub fn from_exr_image(img: &ExrImage) -> Result<Film, FilmError> {
        let mut film = Film::new(img.width, img.height)?;
        let len = img.pixel_count();
        let need = |name: &str| {
            img.channel(name).filter(|v| v.len() == len).ok_or_else(|| {
                FilmError::Restore(format!("channel {name} is missing or of the wrong length"))
            })
        };
        let rgb = [need("R")?, need("G")?, need("B")?];
        let var = [
            need("variance.R")?,
            need("variance.G")?,
            need("variance.B")?,
        ];
        let count = need(image_io::compare::SAMPLES_CHANNEL)?;
        let opt = |name: &str| img.channel(name).filter(|v| v.len() == len);
        let albedo = ["albedo.R", "albedo.G", "albedo.B"].map(opt);
        let normal = ["normal.X", "normal.Y", "normal.Z"].map(opt);
        let depth = opt("depth.Z");
        for (i, p) in film.pixels.iter_mut().enumerate() {
            let n = count[i];
            if !(n >= 0.0 && n <= u32::MAX as f32 && n.fract() == 0.0) {
                return Err(FilmError::Restore(format!(
                    "pixel {i} has a sample count of {n}"
                )));
            }
            p.n = n as u32;
            if p.n == 0 {
                continue;
            }
            let nf = f64::from(p.n);
            for c in 0..3 {
                p.mean[c] = f64::from(rgb[c][i]);
                p.m2[c] = f64::from(var[c][i]).max(0.0) * nf * (nf - 1.0);
                p.albedo[c] = albedo[c].map_or(0.0, |v| f64::from(v[i]) * nf);
                p.normal[c] = normal[c].map_or(0.0, |v| f64::from(v[i]) * nf);
            }
            if let Some(d) = depth.map(|d| d[i]).filter(|d| d.is_finite()) {
                p.hits = p.n;
                p.depth = f64::from(d) * nf;
            }
            if !p.mean.iter().chain(&p.m2).all(|v| v.is_finite()) {
                return Err(FilmError::Restore(format!(
                    "pixel {i} has a non-finite mean or variance"
                )));
            }
        }
        Ok(film)
    }
}
