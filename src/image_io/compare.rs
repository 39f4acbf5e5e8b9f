//! Comparison of two images of the same scene: error metrics, a per-pixel z-test when both
//! images carry the variance of their pixel estimates, and a false-colour error map.
//!
//! `a` is the image under test and `b` the reference. For every compared pixel-channel
//! (pixels where either value is not finite are skipped and counted) with `d = a - b`:
//! - RMSE = sqrt(mean(d^2)),
//! - relative MSE = mean(d^2 / (b^2 + 0.01)) (the 0.01 keeps black reference pixels from
//!   dominating),
//! - mean bias = mean(d),
//! - max |d|,
//! - relative RMSE = sqrt(mean((d / b)^2)) over the pixel-channels whose reference value is not
//!   zero (the strict per-pixel form: every pixel counts by its own relative error),
//! - mean reference = mean(b) (so that `RMSE / mean reference` gives the looser relative form),
//!
//! each over all channels of the layer together and per channel. A [`PixelMask`] restricts the
//! metrics and the z-test to the pixels it marks (e.g. the pixels of one object).
//!
//! The z-test (after the per-pixel render tests of Mitsuba 3) runs when both images hold a
//! variance channel for every compared channel (`variance.R` for `R`; `L.variance.X` for `L.X`),
//! the variance of each pixel *estimate* (sample variance / sample count, what
//! [`crate::film::Film`] writes). Then `z = d / sqrt(var_a + var_b)`. With per-pixel sample
//! counts (`samples.N`, written by the film) in either image, the two-sided tail probabilities
//! of `z` are taken from Student's t with the Welch-Satterthwaite degrees of freedom, since the
//! variances are themselves estimated (an image without counts, e.g. a converged reference, is
//! taken to know its variance exactly); otherwise from the normal distribution. The verdict is
//! "consistent" unless one of two tests rejects at an overall false-alarm rate of
//! [`VERDICT_ALPHA`] (split evenly between the tests and, by Bonferroni, between channels):
//! - tail test: per channel, the number of pixels beyond the `|z| > 3` tail (probability
//!   0.0027 under the null) is compared with its Binomial(N, 0.0027) distribution;
//! - aggregate bias test: per channel, `sum(d) / sqrt(sum(var_a + var_b))` is a standard normal
//!   under the null, and is far more sensitive to a small global bias than the tail count.
//!
//! Limits: Monte-Carlo estimates with heavy tails (rare bright paths) at few samples per pixel
//! have z-scores with heavier tails than assumed; a biased verdict there may be a false alarm.

use super::{layer_channel_name, layer_of, ExrImage};

/// Overall false-alarm probability of the z-test verdict for two unbiased images.
pub const VERDICT_ALPHA: f64 = 1e-3;
/// Two-sided tail probability of a standard normal beyond 2: P(|Z| > 2).
pub const P_ABOVE_2: f64 = 0.045_500_263_896_358_42;
/// Two-sided tail probability of a standard normal beyond 3: P(|Z| > 3).
pub const P_ABOVE_3: f64 = 0.002_699_796_063_260_19;
/// Name of the per-pixel sample-count channel used for the degrees of freedom of the t-test.
pub const SAMPLES_CHANNEL: &str = "samples.N";
/// The constant added to `b^2` in the relative MSE denominator.
pub const REL_MSE_EPSILON: f64 = 1e-2;
/// The `|z|` at which the z-score colour map saturates, unless told otherwise.
pub const DEFAULT_Z_SCALE: f64 = 5.0;

/// Errors of image comparison.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// The images differ in size.
    #[error("the images differ in size: A is {wa}x{ha}, B is {wb}x{hb}")]
    SizeMismatch {
        /// Width of A.
        wa: u32,
        /// Height of A.
        ha: u32,
        /// Width of B.
        wb: u32,
        /// Height of B.
        hb: u32,
    },
    /// A channel of the compared layer is missing from one image.
    #[error("image {image} has no layer {layer:?} ({detail})")]
    MissingLayer {
        /// `"A"` or `"B"`.
        image: &'static str,
        /// The layer asked for (`""` = default R, G, B).
        layer: String,
        /// The channels looked for or present.
        detail: String,
    },
    /// The mask image could not be read or decoded.
    #[error("{}: not a readable PNG mask: {message}", path.display())]
    MaskRead {
        /// The mask file.
        path: std::path::PathBuf,
        /// What the decoder reported.
        message: String,
    },
    /// The mask differs in size from the compared images.
    #[error("the mask is {wm}x{hm} but the images are {w}x{h}")]
    MaskSize {
        /// Width of the mask.
        wm: u32,
        /// Height of the mask.
        hm: u32,
        /// Width of the images.
        w: u32,
        /// Height of the images.
        h: u32,
    },
    /// A channel does not hold `width * height` samples.
    #[error("image {image}: channel {channel} holds {len} samples, expected {expected}")]
    BadChannel {
        /// `"A"` or `"B"`.
        image: &'static str,
        /// The channel.
        channel: String,
        /// Its length.
        len: usize,
        /// `width * height`.
        expected: usize,
    },
}

/// Error metrics of one channel (definitions in the module documentation).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ChannelStats {
    /// Full channel name in A (and B).
    pub name: String,
    /// Number of pixels compared (both values finite).
    pub compared: u64,
    /// Root mean square of `a - b`.
    pub rmse: f64,
    /// Mean of `(a - b)^2 / (b^2 + 0.01)`.
    pub rel_mse: f64,
    /// `sqrt(mean(((a - b) / b)^2))` over the compared pixels where `b != 0`.
    pub rel_rmse: f64,
    /// Mean of `b` (the reference) over the compared pixels.
    pub mean_reference: f64,
    /// Mean of `a - b`.
    pub mean_bias: f64,
    /// Largest `|a - b|`.
    pub max_abs_error: f64,
}

/// The per-pixel z-test summary (definitions in the module documentation).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ZTest {
    /// Variance channel names used (same names in A and B).
    pub variance_channels: Vec<String>,
    /// True when either image carries [`SAMPLES_CHANNEL`], so tails come from Student's t (an
    /// image without it is taken to know its variance exactly).
    pub uses_sample_counts: bool,
    /// Pixel-channels tested.
    pub tested: u64,
    /// Pixel-channels not tested: a variance negative or not finite, or fewer than 2 samples.
    pub untestable: u64,
    /// Tested pixel-channels with `var_a + var_b == 0` (z = 0 if `a == b`, else infinite).
    pub zero_variance: u64,
    /// Fraction of tested pixel-channels beyond the two-sided 2-sigma tail (probability
    /// [`P_ABOVE_2`] under the null).
    pub frac_above_2: f64,
    /// Fraction of tested pixel-channels beyond the two-sided 3-sigma tail (probability
    /// [`P_ABOVE_3`] under the null).
    pub frac_above_3: f64,
    /// Expected value of `frac_above_2` for consistent images.
    pub expected_above_2: f64,
    /// Expected value of `frac_above_3` for consistent images.
    pub expected_above_3: f64,
    /// Mean of the finite z-scores.
    pub mean_z: f64,
    /// Mean of the finite z^2 (a chi-square per degree of freedom: about 1, or a little more
    /// with few samples per pixel, for consistent images).
    pub mean_z2: f64,
    /// Per channel, `sum(a - b) / sqrt(sum(var_a + var_b))`: standard normal when unbiased.
    pub bias_z: Vec<f64>,
    /// Bonferroni-corrected p-value of the tail test (binomial upper tail of the `|z| > 3`
    /// count, smallest over channels, times the channel count, at most 1).
    pub tail_p_value: f64,
    /// Bonferroni-corrected two-sided p-value of the aggregate bias test.
    pub bias_p_value: f64,
    /// True unless the tail test or the bias test rejects (each at `VERDICT_ALPHA / 2`).
    pub consistent: bool,
}

/// The result of [`compare_layer`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ImageComparison {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// The layer compared (`""` = the default R, G, B).
    pub layer: String,
    /// Pixel-channels compared (both values finite), all channels together.
    pub compared: u64,
    /// Pixel-channels skipped because a value is NaN or infinite.
    pub skipped_non_finite: u64,
    /// Pixels left out because the mask does not mark them (0 without a mask).
    pub masked_out: u64,
    /// RMSE over all channels.
    pub rmse: f64,
    /// Relative MSE over all channels.
    pub rel_mse: f64,
    /// Relative RMSE `sqrt(mean(((a - b) / b)^2))` over all channels (pixel-channels with
    /// `b != 0`).
    pub rel_rmse: f64,
    /// Mean of the reference over all compared pixel-channels.
    pub mean_reference: f64,
    /// Mean bias over all channels.
    pub mean_bias: f64,
    /// Largest `|a - b|` over all channels.
    pub max_abs_error: f64,
    /// The same metrics per channel.
    pub per_channel: Vec<ChannelStats>,
    /// The z-test, when both images carry variance channels.
    pub z_test: Option<ZTest>,
}

/// Which pixels a comparison counts: e.g. the pixels covered by one object, so that its error
/// is not diluted by (or hidden in) the rest of the frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PixelMask {
    width: u32,
    height: u32,
    counted: Vec<bool>,
}

/// The 8-bit level from which a mask pixel's channel counts as white.
pub const MASK_WHITE_LEVEL: u8 = 128;

impl PixelMask {
    /// A mask from `width * height` flags, row-major, top row first (`true` = counted).
    /// `None` when the length does not match the size.
    #[must_use]
    pub fn from_flags(width: u32, height: u32, counted: Vec<bool>) -> Option<Self> {
        (counted.len() == width as usize * height as usize).then_some(PixelMask {
            width,
            height,
            counted,
        })
    }

    /// A mask from 8-bit RGB bytes (`3 * width * height`, row-major, top row first): a pixel is
    /// counted when its three channels are all at least [`MASK_WHITE_LEVEL`] (white or light
    /// grey); black, dark and coloured pixels (e.g. an error map's magenta) are not. `None`
    /// when the length does not match the size.
    #[must_use]
    pub fn from_rgb8(width: u32, height: u32, rgb8: &[u8]) -> Option<Self> {
        if rgb8.len() != 3 * width as usize * height as usize {
            return None;
        }
        let counted = rgb8
            .chunks_exact(3)
            .map(|p| p.iter().all(|&c| c >= MASK_WHITE_LEVEL))
            .collect();
        PixelMask::from_flags(width, height, counted)
    }

    /// Reads a mask from a PNG file (any bit depth or colour type; converted to 8-bit RGB, so a
    /// grey-scale mask works too). See [`PixelMask::from_rgb8`] for which pixels count.
    pub fn read_png(path: &std::path::Path) -> Result<Self, CompareError> {
        let read_error = |message: String| CompareError::MaskRead {
            path: path.to_path_buf(),
            message,
        };
        let img = image::ImageReader::open(path)
            .map_err(|e| read_error(e.to_string()))?
            .with_guessed_format()
            .map_err(|e| read_error(e.to_string()))?
            .decode()
            .map_err(|e| read_error(e.to_string()))?
            .to_rgb8();
        let (w, h) = img.dimensions();
        PixelMask::from_rgb8(w, h, img.as_raw())
            .ok_or_else(|| read_error("decoded pixel data does not match its size".to_string()))
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

    /// Number of counted pixels.
    #[must_use]
    pub fn counted_pixels(&self) -> u64 {
        self.counted.iter().filter(|&&c| c).count() as u64
    }

    /// True when pixel `i` (row-major index) is counted.
    #[must_use]
    pub fn counts(&self, i: usize) -> bool {
        self.counted.get(i).copied().unwrap_or(false)
    }
}

/// The channels of one side, resolved and checked.
struct Side<'a> {
    values: Vec<&'a [f32]>,
    variances: Option<Vec<&'a [f32]>>,
    samples: Option<&'a [f32]>,
}

/// Everything needed to compare a layer of A against B.
struct Prepared<'a> {
    names: Vec<String>,
    variance_names: Vec<String>,
    a: Side<'a>,
    b: Side<'a>,
    pixels: usize,
    mask: Option<&'a PixelMask>,
}

/// The channel names compared for a layer: its R/G/B (or X/Y/Z) triple when present, else all
/// of its channels.
fn layer_channel_names(img: &ExrImage, layer: &str) -> Vec<String> {
    match img.rgb_channel_names(layer) {
        Some(t) => t.to_vec(),
        None => img.layer_channels(layer),
    }
}

/// The variance channel of a compared channel: `variance.R` for `R`, `L.variance.X` for `L.X`.
#[must_use]
pub fn variance_channel_name(channel: &str) -> String {
    let layer = layer_of(channel);
    let suffix = if layer.is_empty() {
        channel
    } else {
        &channel[layer.len() + 1..]
    };
    let var_layer = if layer.is_empty() {
        "variance".to_string()
    } else {
        format!("{layer}.variance")
    };
    layer_channel_name(&var_layer, suffix)
}

fn prepare<'a>(
    a: &'a ExrImage,
    b: &'a ExrImage,
    layer: &str,
    mask: Option<&'a PixelMask>,
) -> Result<Prepared<'a>, CompareError> {
    if a.width != b.width || a.height != b.height {
        return Err(CompareError::SizeMismatch {
            wa: a.width,
            ha: a.height,
            wb: b.width,
            hb: b.height,
        });
    }
    if let Some(m) = mask {
        if m.width != a.width || m.height != a.height {
            return Err(CompareError::MaskSize {
                wm: m.width,
                hm: m.height,
                w: a.width,
                h: a.height,
            });
        }
    }
    let names = layer_channel_names(a, layer);
    if names.is_empty() {
        return Err(CompareError::MissingLayer {
            image: "A",
            layer: layer.to_string(),
            detail: format!("its layers are {:?}", a.layers()),
        });
    }
    let pixels = a.pixel_count();
    let get = |img: &'a ExrImage,
               which: &'static str,
               name: &str|
     -> Result<Option<&'a [f32]>, CompareError> {
        match img.channel(name) {
            None => Ok(None),
            Some(v) if v.len() == pixels => Ok(Some(v)),
            Some(v) => Err(CompareError::BadChannel {
                image: which,
                channel: name.to_string(),
                len: v.len(),
                expected: pixels,
            }),
        }
    };
    let side = |img: &'a ExrImage, which: &'static str| -> Result<Side<'a>, CompareError> {
        let mut values = Vec::new();
        for n in &names {
            values.push(
                get(img, which, n)?.ok_or_else(|| CompareError::MissingLayer {
                    image: which,
                    layer: layer.to_string(),
                    detail: format!("channel {n} is missing"),
                })?,
            );
        }
        let mut variances = Some(Vec::new());
        for n in &names {
            match (
                get(img, which, &variance_channel_name(n))?,
                variances.as_mut(),
            ) {
                (Some(v), Some(list)) => list.push(v),
                _ => variances = None,
            }
        }
        Ok(Side {
            values,
            variances,
            samples: get(img, which, SAMPLES_CHANNEL)?,
        })
    };
    let sa = side(a, "A")?;
    let sb = side(b, "B")?;
    Ok(Prepared {
        variance_names: names.iter().map(|n| variance_channel_name(n)).collect(),
        names,
        a: sa,
        b: sb,
        pixels,
        mask,
    })
}

/// Compares the default layer (`R`, `G`, `B`) of `a` against the reference `b`.
pub fn compare(a: &ExrImage, b: &ExrImage) -> Result<ImageComparison, CompareError> {
    compare_layer(a, b, "")
}

/// Where a pixel-channel's z-score falls, for the tail counts.
struct ZOutcome {
    z: f64,
    zero_variance: bool,
    above_2: bool,
    above_3: bool,
}

impl Prepared<'_> {
    /// True when pixel `i` is compared (no mask, or the mask counts it).
    fn counts(&self, i: usize) -> bool {
        self.mask.is_none_or(|m| m.counts(i))
    }

    fn z_enabled(&self) -> bool {
        self.a.variances.is_some() && self.b.variances.is_some()
    }

    /// The z-score of channel `c` at pixel `i`, or `None` when untestable.
    fn z_at(&self, c: usize, i: usize) -> Option<ZOutcome> {
        /// Relative difference treated as float rounding (a few f32 ulps).
        const ROUNDING_FLOOR: f64 = 1e-6;
        let (va, vb) = (self.a.variances.as_ref()?, self.b.variances.as_ref()?);
        let (a, b) = (
            f64::from(self.a.values[c][i]),
            f64::from(self.b.values[c][i]),
        );
        let (va, vb) = (f64::from(va[c][i]), f64::from(vb[c][i]));
        if !(a.is_finite() && b.is_finite() && va.is_finite() && vb.is_finite())
            || va < 0.0
            || vb < 0.0
        {
            return None;
        }
        let na = self.a.samples.map(|s| f64::from(s[i]));
        let nb = self.b.samples.map(|s| f64::from(s[i]));
        // (NaN counts are caught too: they are not >= 2.)
        let too_few = |n: Option<f64>| n.is_some_and(|n| n.is_nan() || n < 2.0);
        if too_few(na) || too_few(nb) {
            return None;
        }
        let d = a - b;
        // Values stored as f32 carry rounding of about 1e-7 relative: a difference below that
        // floor is not evidence of bias, however small the estimated variances are (e.g.
        // pixels that every sample estimates to within rounding).
        let floor = (ROUNDING_FLOOR * a.abs().max(b.abs())).powi(2);
        let var = if d.abs() <= ROUNDING_FLOOR * a.abs().max(b.abs()) && va + vb < floor {
            0.0
        } else {
            va + vb
        };
        let d = if var == 0.0 && d.abs() <= ROUNDING_FLOOR * a.abs().max(b.abs()) {
            0.0
        } else {
            d
        };
        if var == 0.0 {
            let z = if d == 0.0 {
                0.0
            } else {
                f64::INFINITY.copysign(d)
            };
            let beyond = d != 0.0;
            return Some(ZOutcome {
                z,
                zero_variance: true,
                above_2: beyond,
                above_3: beyond,
            });
        }
        let z = d / var.sqrt();
        let az = z.abs();
        let (above_2, above_3) = if (na.is_some() || nb.is_some()) && az > 2.0 {
            // Welch-Satterthwaite degrees of freedom of var_a + var_b; an image without sample
            // counts is taken to know its variance exactly.
            let term = |v: f64, n: Option<f64>| n.map_or(0.0, |n| v * v / (n - 1.0));
            let denom = term(va, na) + term(vb, nb);
            let dof = if denom > 0.0 {
                var * var / denom
            } else {
                f64::INFINITY
            };
            let p = student_t_two_sided_tail(az, dof);
            (p < P_ABOVE_2, p < P_ABOVE_3)
        } else {
            (az > 2.0, az > 3.0)
        };
        Some(ZOutcome {
            z,
            zero_variance: false,
            above_2,
            above_3,
        })
    }
}

/// Running sums of the error metrics over pixel-channels.
#[derive(Default)]
struct Sums {
    /// Pixel-channels added.
    n: u64,
    /// Sum of `d^2`.
    sq: f64,
    /// Sum of `d^2 / (b^2 + REL_MSE_EPSILON)`.
    rel: f64,
    /// Sum of `(d / b)^2` over pixel-channels with `b != 0`, and their count.
    rel_strict: f64,
    rel_strict_n: u64,
    /// Sum of `b`.
    b: f64,
    /// Sum of `d`.
    d: f64,
    /// Largest `|d|`.
    max: f64,
}

impl Sums {
    fn add(&mut self, a: f64, b: f64) {
        let d = a - b;
        self.n += 1;
        self.sq += d * d;
        self.rel += d * d / (b * b + REL_MSE_EPSILON);
        if b != 0.0 {
            self.rel_strict += (d / b) * (d / b);
            self.rel_strict_n += 1;
        }
        self.b += b;
        self.d += d;
        self.max = self.max.max(d.abs());
    }

    fn merge(&mut self, o: &Sums) {
        self.n += o.n;
        self.sq += o.sq;
        self.rel += o.rel;
        self.rel_strict += o.rel_strict;
        self.rel_strict_n += o.rel_strict_n;
        self.b += o.b;
        self.d += o.d;
        self.max = self.max.max(o.max);
    }

    /// `x / n`, or 0 when nothing was added.
    fn mean(&self, x: f64) -> f64 {
        if self.n > 0 {
            x / self.n as f64
        } else {
            0.0
        }
    }

    fn rel_rmse(&self) -> f64 {
        if self.rel_strict_n > 0 {
            (self.rel_strict / self.rel_strict_n as f64).sqrt()
        } else {
            0.0
        }
    }
}

/// Compares one layer of `a` against the reference `b` (`""` = the default `R`, `G`, `B`;
/// otherwise the layer's R/G/B or X/Y/Z triple, or all of its channels, e.g. `depth` ->
/// `depth.Z`). Metrics and the z-test are defined in the module documentation.
pub fn compare_layer(
    a: &ExrImage,
    b: &ExrImage,
    layer: &str,
) -> Result<ImageComparison, CompareError> {
    compare_layer_masked(a, b, layer, None)
}

/// [`compare_layer`] restricted to the pixels `mask` counts (all pixels without one): the
/// metrics and the z-test see only those pixels; `masked_out` reports how many were left out.
/// A mask of another size than the images is an error.
pub fn compare_layer_masked(
    a: &ExrImage,
    b: &ExrImage,
    layer: &str,
    mask: Option<&PixelMask>,
) -> Result<ImageComparison, CompareError> {
    let p = prepare(a, b, layer, mask)?;
    let nc = p.names.len();
    let masked_out = (0..p.pixels).filter(|&i| !p.counts(i)).count() as u64;

    let mut per_channel = Vec::with_capacity(nc);
    let mut all = Sums::default();
    let mut skipped = 0u64;
    for c in 0..nc {
        let mut ch = Sums::default();
        for i in (0..p.pixels).filter(|&i| p.counts(i)) {
            let (av, bv) = (f64::from(p.a.values[c][i]), f64::from(p.b.values[c][i]));
            if !(av.is_finite() && bv.is_finite()) {
                skipped += 1;
                continue;
            }
            ch.add(av, bv);
        }
        per_channel.push(ChannelStats {
            name: p.names[c].clone(),
            compared: ch.n,
            rmse: ch.mean(ch.sq).sqrt(),
            rel_mse: ch.mean(ch.rel),
            rel_rmse: ch.rel_rmse(),
            mean_reference: ch.mean(ch.b),
            mean_bias: ch.mean(ch.d),
            max_abs_error: ch.max,
        });
        all.merge(&ch);
    }

    let z_test = p.z_enabled().then(|| z_test(&p));
    Ok(ImageComparison {
        width: a.width,
        height: a.height,
        layer: layer.to_string(),
        compared: all.n,
        skipped_non_finite: skipped,
        masked_out,
        rmse: all.mean(all.sq).sqrt(),
        rel_mse: all.mean(all.rel),
        rel_rmse: all.rel_rmse(),
        mean_reference: all.mean(all.b),
        mean_bias: all.mean(all.d),
        max_abs_error: all.max,
        per_channel,
        z_test,
    })
}

fn z_test(p: &Prepared<'_>) -> ZTest {
    let nc = p.names.len();
    let (mut tested, mut untestable, mut zero_var) = (0u64, 0u64, 0u64);
    let (mut above2, mut above3) = (0u64, 0u64);
    let (mut zsum, mut z2sum, mut zn) = (0.0f64, 0.0f64, 0u64);
    let mut tail_p = 1.0f64;
    let mut bias_z = Vec::with_capacity(nc);
    let mut bias_p = 1.0f64;
    for c in 0..nc {
        let (mut n_c, mut k3_c) = (0u64, 0u64);
        let (mut dsum, mut vsum) = (0.0f64, 0.0f64);
        for i in (0..p.pixels).filter(|&i| p.counts(i)) {
            let Some(o) = p.z_at(c, i) else {
                untestable += 1;
                continue;
            };
            n_c += 1;
            above2 += u64::from(o.above_2);
            k3_c += u64::from(o.above_3);
            zero_var += u64::from(o.zero_variance);
            if o.z.is_finite() {
                zsum += o.z;
                z2sum += o.z * o.z;
                zn += 1;
            }
            let (a, b) = (f64::from(p.a.values[c][i]), f64::from(p.b.values[c][i]));
            dsum += a - b;
            if let (Some(va), Some(vb)) = (&p.a.variances, &p.b.variances) {
                vsum += f64::from(va[c][i]) + f64::from(vb[c][i]);
            }
        }
        tested += n_c;
        above3 += k3_c;
        tail_p = tail_p.min(binomial_upper_tail(n_c, k3_c, P_ABOVE_3));
        let bz = if vsum > 0.0 {
            dsum / vsum.sqrt()
        } else if dsum == 0.0 {
            0.0
        } else {
            f64::INFINITY.copysign(dsum)
        };
        bias_p = bias_p.min(normal_two_sided_tail(bz.abs()));
        bias_z.push(bz);
    }
    let tail_p_value = (tail_p * nc as f64).min(1.0);
    let bias_p_value = (bias_p * nc as f64).min(1.0);
    let frac = |k: u64| {
        if tested > 0 {
            k as f64 / tested as f64
        } else {
            0.0
        }
    };
    ZTest {
        variance_channels: p.variance_names.clone(),
        uses_sample_counts: p.a.samples.is_some() || p.b.samples.is_some(),
        tested,
        untestable,
        zero_variance: zero_var,
        frac_above_2: frac(above2),
        frac_above_3: frac(above3),
        expected_above_2: P_ABOVE_2,
        expected_above_3: P_ABOVE_3,
        mean_z: if zn > 0 { zsum / zn as f64 } else { 0.0 },
        mean_z2: if zn > 0 { z2sum / zn as f64 } else { 0.0 },
        bias_z,
        tail_p_value,
        bias_p_value,
        consistent: tail_p_value >= VERDICT_ALPHA / 2.0 && bias_p_value >= VERDICT_ALPHA / 2.0,
    }
}

/// What an error map shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum ErrorMapMode {
    /// Signed z-score of the channel with the largest `|z|`: black at 0, through red to yellow
    /// for `a > b`, through blue to cyan for `a < b`, saturating at `|z| = scale`.
    ZScore,
    /// Mean over channels of `|a - b|`: black -> red -> yellow -> white, saturating at `scale`.
    AbsoluteError,
}

/// A false-colour error image, 8-bit RGB.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorMap {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` bytes, row-major, top row first.
    pub rgb8: Vec<u8>,
    /// What is shown.
    pub mode: ErrorMapMode,
    /// The value at which the colour scale saturates (|z| or |a - b|).
    pub scale: f64,
}

/// Builds the false-colour error map of a layer of `a` against `b`: z-scores when both images
/// carry variance channels (colour scale saturating at `scale`, default
/// [`DEFAULT_Z_SCALE`]), else the mean absolute error over the layer's channels (saturating at
/// `scale`, default the 99th percentile of the per-pixel error, or 1 if that is 0). Untestable
/// or non-finite pixels are drawn magenta. See [`ErrorMapMode`] for the colours.
pub fn error_map(
    a: &ExrImage,
    b: &ExrImage,
    layer: &str,
    scale: Option<f64>,
) -> Result<ErrorMap, CompareError> {
    let p = prepare(a, b, layer, None)?;
    let nc = p.names.len();
    const MAGENTA: [u8; 3] = [255, 0, 255];
    let mut rgb8 = Vec::with_capacity(3 * p.pixels);
    let to8 = |v: f64| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    let valid_scale = scale.filter(|s| s.is_finite() && *s > 0.0);
    let (mode, used_scale) = if p.z_enabled() {
        let s = valid_scale.unwrap_or(DEFAULT_Z_SCALE);
        for i in 0..p.pixels {
            let mut best: Option<f64> = None;
            for c in 0..nc {
                if let Some(o) = p.z_at(c, i) {
                    if best.is_none_or(|b| o.z.abs() > b.abs()) {
                        best = Some(o.z);
                    }
                }
            }
            match best {
                None => rgb8.extend_from_slice(&MAGENTA),
                Some(z) => {
                    let t = (z.abs() / s).min(1.0);
                    let c = if z >= 0.0 {
                        [t, t * t, 0.0]
                    } else {
                        [0.0, t * t, t]
                    };
                    rgb8.extend(c.map(to8));
                }
            }
        }
        (ErrorMapMode::ZScore, s)
    } else {
        let errors: Vec<Option<f64>> = (0..p.pixels)
            .map(|i| {
                let mut sum = 0.0;
                for c in 0..nc {
                    let d = f64::from(p.a.values[c][i]) - f64::from(p.b.values[c][i]);
                    if !d.is_finite() {
                        return None;
                    }
                    sum += d.abs();
                }
                Some(sum / nc as f64)
            })
            .collect();
        let s = valid_scale.unwrap_or_else(|| {
            let mut finite: Vec<f64> = errors.iter().flatten().copied().collect();
            finite.sort_by(f64::total_cmp);
            let q = finite
                .get(((finite.len() as f64 * 0.99) as usize).min(finite.len().saturating_sub(1)))
                .copied()
                .unwrap_or(0.0);
            if q > 0.0 {
                q
            } else {
                1.0
            }
        });
        for e in errors {
            match e {
                None => rgb8.extend_from_slice(&MAGENTA),
                Some(e) => {
                    let t = (e / s).min(1.0);
                    rgb8.extend([3.0 * t, 3.0 * t - 1.0, 3.0 * t - 2.0].map(to8));
                }
            }
        }
        (ErrorMapMode::AbsoluteError, s)
    };
    Ok(ErrorMap {
        width: a.width,
        height: a.height,
        rgb8,
        mode,
        scale: used_scale,
    })
}

// ---------------------------------------------------------------------------------------------
// Distribution tails (standard special-function identities: Abramowitz & Stegun 6.5, 26.5).

/// ln Γ(x) for x > 0 (Lanczos approximation, g = 7, 9 terms; ~1e-15 relative).
pub fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x) Γ(1 - x) = π / sin(πx).
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut s = C[0];
    for (k, &c) in C.iter().enumerate().skip(1) {
        s += c / (x + k as f64);
    }
    let t = x + G + 0.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + s.ln()
}

/// Continued fraction of the regularized incomplete beta function (modified Lentz).
fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    const EPS: f64 = 1e-15;
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 - qab * x / qap;
    if d.abs() < TINY {
        d = TINY;
    }
    d = 1.0 / d;
    let mut h = d;
    for m in 1..100_000 {
        let m = f64::from(m);
        let m2 = 2.0 * m;
        for aa in [
            m * (b - m) * x / ((qam + m2) * (a + m2)),
            -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2)),
        ] {
            d = 1.0 + aa * d;
            if d.abs() < TINY {
                d = TINY;
            }
            c = 1.0 + aa / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            h *= d * c;
        }
        if (d * c - 1.0).abs() < EPS {
            break;
        }
    }
    h
}

/// Regularized incomplete beta function I_x(a, b), a, b > 0, x in [0, 1].
#[must_use]
pub fn regularized_incomplete_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = ln_gamma(a + b) - ln_gamma(a) - ln_gamma(b) + a * x.ln() + b * (1.0 - x).ln();
    if x < (a + 1.0) / (a + b + 2.0) {
        (ln_front.exp() * beta_cf(a, b, x) / a).clamp(0.0, 1.0)
    } else {
        (1.0 - ln_front.exp() * beta_cf(b, a, 1.0 - x) / b).clamp(0.0, 1.0)
    }
}

/// Regularized upper incomplete gamma function Q(a, x), a > 0, x >= 0 (the chi-square upper
/// tail is `Q(dof / 2, statistic / 2)`).
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let ln_front = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        // Series for P(a, x).
        let (mut ap, mut del) = (a, 1.0 / a);
        let mut sum = del;
        for _ in 0..100_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (1.0 - sum * ln_front.exp()).clamp(0.0, 1.0)
    } else {
        // Continued fraction for Q(a, x) (modified Lentz).
        const TINY: f64 = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..100_000 {
            let i = f64::from(i);
            let an = -i * (i - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (ln_front.exp() * h).clamp(0.0, 1.0)
    }
}

/// P(|Z| > z) for a standard normal Z (z >= 0; infinite z gives 0).
#[must_use]
pub fn normal_two_sided_tail(z: f64) -> f64 {
    if z.is_nan() {
        return 1.0;
    }
    if z.is_infinite() {
        return 0.0;
    }
    // erfc(z / sqrt 2) = Q(1/2, z^2 / 2).
    gamma_q(0.5, 0.5 * z * z)
}

/// P(|T| > t) for Student's t with `dof` degrees of freedom (t >= 0; infinite `dof` gives the
/// normal tail).
#[must_use]
pub fn student_t_two_sided_tail(t: f64, dof: f64) -> f64 {
    if t.is_nan() || dof.is_nan() || dof <= 0.0 {
        return 1.0;
    }
    if t.is_infinite() {
        return 0.0;
    }
    if !dof.is_finite() || dof > 1e7 {
        return normal_two_sided_tail(t);
    }
    regularized_incomplete_beta(0.5 * dof, 0.5, dof / (dof + t * t))
}

/// P(K >= k) for K ~ Binomial(n, p).
#[must_use]
pub fn binomial_upper_tail(n: u64, k: u64, p: f64) -> f64 {
    if k == 0 {
        return 1.0;
    }
    if k > n {
        return 0.0;
    }
    // P(K >= k) = I_p(k, n - k + 1).
    regularized_incomplete_beta(k as f64, (n - k + 1) as f64, p)
}
