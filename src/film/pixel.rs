//! One pixel's exact accumulator: sample count, sums and sums of squares of the radiance, and
//! the sums of the auxiliary layers, all as integers on fixed binary grids (see
//! [`super::fixed`]), so that adding samples in any grouping gives the same bits.

use super::fixed::{Fixed192, MAX_SAMPLE};
use super::PixelSample;
use crate::spectrum::Rgb;

/// Fractional bits of the radiance sums.
pub(super) const SUM_BITS: u32 = 96;
/// Fractional bits of the radiance sums of squares.
pub(super) const SQ_BITS: u32 = 80;
/// Fractional bits of the albedo and normal sums (`i64`; components are clamped to ±4).
pub(super) const AUX_BITS: u32 = 28;
/// Fractional bits of the depth sum (`i128`; depths beyond [`MAX_DEPTH`] count as misses).
pub(super) const DEPTH_BITS: u32 = 48;
/// Largest camera-ray hit distance recorded in the depth layer (scene units).
pub const MAX_DEPTH: f32 = 1.0e12;

/// The accumulator of one pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct Pixel {
    /// Samples accumulated.
    pub n: u32,
    /// Samples with a finite depth.
    pub hits: u32,
    /// Σ radiance, per channel.
    pub sum: [Fixed192; 3],
    /// Σ radiance², per channel.
    pub sum_sq: [Fixed192; 3],
    /// Σ albedo and Σ normal, per component.
    pub albedo: [i64; 3],
    pub normal: [i64; 3],
    /// Σ hit distance over the samples that hit.
    pub depth: i128,
}

/// Whether a sample can be accumulated: its radiance and its first `layers` per-light parts
/// finite and within ±[`MAX_SAMPLE`].
#[inline]
pub(super) fn accepts(s: &PixelSample, layers: usize) -> bool {
    let ok = |v: &f32| v.is_finite() && f64::from(*v).abs() <= MAX_SAMPLE;
    s.radiance.0.iter().all(ok) && s.lights.iter().take(layers).all(|l| l.0.iter().all(ok))
}

#[inline]
fn aux_units(v: f32) -> i64 {
    if v.is_finite() {
        (f64::from(v.clamp(-4.0, 4.0)) * f64::from(1u32 << AUX_BITS)).round() as i64
    } else {
        0
    }
}

impl Pixel {
    /// Adds one sample, which must satisfy [`accepts`].
    #[inline]
    pub fn add(&mut self, s: &PixelSample) {
        self.n += 1;
        for c in 0..3 {
            let x = f64::from(s.radiance.0[c]);
            self.sum[c] = self.sum[c].add(Fixed192::from_f64(x, SUM_BITS));
            self.sum_sq[c] = self.sum_sq[c].add(Fixed192::from_f64(x * x, SQ_BITS));
            self.albedo[c] = self.albedo[c].wrapping_add(aux_units(s.albedo.0[c]));
        }
        for (sum, v) in self.normal.iter_mut().zip(s.normal.to_array()) {
            *sum = sum.wrapping_add(aux_units(v));
        }
        if s.depth.is_finite() && s.depth >= 0.0 && s.depth <= MAX_DEPTH {
            self.hits += 1;
            self.depth += (f64::from(s.depth) * 2f64.powi(DEPTH_BITS as i32)).round() as i128;
        }
    }

    /// Adds another accumulator: exact, so the result does not depend on the grouping.
    #[inline]
    pub fn merge(&mut self, o: &Pixel) {
        self.n = self.n.saturating_add(o.n);
        self.hits = self.hits.saturating_add(o.hits);
        for c in 0..3 {
            self.sum[c] = self.sum[c].add(o.sum[c]);
            self.sum_sq[c] = self.sum_sq[c].add(o.sum_sq[c]);
            self.albedo[c] = self.albedo[c].wrapping_add(o.albedo[c]);
            self.normal[c] = self.normal[c].wrapping_add(o.normal[c]);
        }
        self.depth = self.depth.wrapping_add(o.depth);
    }

    /// Mean radiance per channel, in `f64` (0 when empty).
    pub fn mean_f64(&self) -> [f64; 3] {
        if self.n == 0 {
            return [0.0; 3];
        }
        let n = f64::from(self.n);
        self.sum.map(|s| s.to_f64(SUM_BITS) / n)
    }

    /// Mean radiance.
    pub fn mean(&self) -> Rgb {
        Rgb(self.mean_f64().map(|m| m as f32))
    }

    /// Variance of the mean per channel: the unbiased sample variance over n, 0 when n < 2.
    /// A sum of squared deviations within the rounding error of the sums themselves (the
    /// squares' grid, n · 2^-81, plus a few ulps of Σx²) is reported as exactly 0, so a constant
    /// pixel has zero variance.
    pub fn variance_of_mean(&self) -> Rgb {
        if self.n < 2 {
            return Rgb::ZERO;
        }
        let n = f64::from(self.n);
        Rgb(std::array::from_fn(|c| {
            let s1 = self.sum[c].to_f64(SUM_BITS);
            let s2 = self.sum_sq[c].to_f64(SQ_BITS);
            let m2 = s2 - s1 * (s1 / n);
            let noise = n * 2f64.powi(-(SQ_BITS as i32)) + 8.0 * f64::EPSILON * s2;
            if m2 <= noise {
                0.0
            } else {
                (m2 / ((n - 1.0) * n)) as f32
            }
        }))
    }

    /// Mean of an auxiliary sum over the pixel's samples.
    pub fn aux_mean(&self, sums: [i64; 3]) -> [f32; 3] {
        if self.n == 0 {
            return [0.0; 3];
        }
        let scale = f64::from(self.n) * f64::from(1u32 << AUX_BITS);
        sums.map(|s| (s as f64 / scale) as f32)
    }

    /// Mean hit distance over the samples that hit; +inf when none did.
    pub fn depth(&self) -> f32 {
        if self.hits == 0 {
            f32::INFINITY
        } else {
            (self.depth as f64 * 2f64.powi(-(DEPTH_BITS as i32)) / f64::from(self.hits)) as f32
        }
    }
}
