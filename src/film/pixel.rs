//! One pixel's exact accumulator: sample count, sums and sums of squares of the radiance, and
//! the sums of the auxiliary layers, all as integers on fixed binary grids (see
//! [`super::fixed`]), so that adding samples in any grouping gives the same bits.

use super::fixed::{Fixed192, MAX_SAMPLE};
use super::PixelSample;
use crate::math::Vec3;
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

/// Fixed-point units of an albedo or normal component: `v` clamped to ±4, times
/// 2^[`AUX_BITS`], rounded to the nearest integer with ties away from zero; 0 for a non-finite
/// `v`. In `f32` throughout: the scaled value is exact (a power-of-two scale of an `f32` of
/// magnitude at most 4, so at most 2^30, and no subnormal result), its truncation is an `f32`
/// too, and so is the fraction `x − trunc(x)`; the answer is [`round_small`]'s on the same
/// value in `f64`, without the saturating `f64 → i64` conversion.
#[inline]
fn aux_units(v: f32) -> i64 {
    if !v.is_finite() {
        return 0;
    }
    let x = v.clamp(-4.0, 4.0) * (1u32 << AUX_BITS) as f32;
    // SAFETY: `x` is finite and |x| ≤ 2^30 < 2^31, so its truncation is an `i32`.
    let t = unsafe { x.to_int_unchecked::<i32>() };
    let frac = x - t as f32;
    i64::from(t) + i64::from(frac >= 0.5) - i64::from(frac <= -0.5)
}

/// `x.round() as i64` (nearest integer, ties away from zero) for `|x| < 2^52`, without the
/// library call `f64::round` compiles to on baseline x86-64 (six of them per sample were
/// about 3 % of the thin peer cloud's instructions): the truncation is exact, and so is the
/// fraction `x − trunc(x)` (the low bits of `x`), whose comparison with ±0.5 decides the tie
/// the same way.
#[inline]
fn round_small(x: f64) -> i64 {
    let t = x as i64;
    let frac = x - t as f64;
    t + i64::from(frac >= 0.5) - i64::from(frac <= -0.5)
}

/// Fixed-point units of a finite hit distance `depth ≥ 0`: `(depth · 2^DEPTH_BITS).round()`,
/// by [`round_small`] below 2^52 units (depths below 16), by the library above.
#[inline]
fn depth_units(depth: f32) -> i128 {
    let x = f64::from(depth) * 2f64.powi(DEPTH_BITS as i32);
    if x < SMALL_LIMIT {
        i128::from(round_small(x))
    } else {
        x.round() as i128
    }
}

/// Bound below which [`round_small`] applies (2^52: every larger `f64` is an integer).
const SMALL_LIMIT: f64 = 4_503_599_627_370_496.0;

impl Pixel {
    /// Adds one sample, which must satisfy [`accepts`].
    #[inline]
    pub fn add(&mut self, s: &PixelSample) {
        self.n += 1;
        for c in 0..3 {
            let x = f64::from(s.radiance.0[c]);
            self.sum[c] = self.sum[c].add_f64(x, SUM_BITS);
            self.sum_sq[c] = self.sum_sq[c].add_f64(x * x, SQ_BITS);
        }
        // A sample that saw nothing has zero albedo and normal (most of a thin medium's
        // samples): adding their zero units changes nothing.
        if s.albedo.0 != [0.0; 3] || s.normal != Vec3::ZERO {
            for c in 0..3 {
                self.albedo[c] = self.albedo[c].wrapping_add(aux_units(s.albedo.0[c]));
            }
            for (sum, v) in self.normal.iter_mut().zip(s.normal.to_array()) {
                *sum = sum.wrapping_add(aux_units(v));
            }
        }
        if s.depth.is_finite() && s.depth >= 0.0 && s.depth <= MAX_DEPTH {
            self.hits += 1;
            self.depth += depth_units(s.depth);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    #[test]
    fn small_rounding_matches_the_library_bit_for_bit() {
        let mut edges = vec![0.0, -0.0, 0.5, -0.5, 1.5, -1.5, 2.5, -2.5, 4.0, -4.0];
        // The largest double below one half (x + 0.5 rounds up to 1 there), and ties at the
        // clamp bound and at 2^51.
        edges.extend([0.499_999_999_999_999_94, -0.499_999_999_999_999_94]);
        edges.extend([
            1073741824.5,
            -1073741824.5,
            2f64.powi(51) + 0.5,
            -(2f64.powi(51) + 0.5),
        ]);
        for x in edges {
            assert_eq!(round_small(x), x.round() as i64, "{x}");
        }
        let mut rng = Rng::new(5, 1);
        for n in 0..1_000_000u32 {
            // The albedo and normal range, on and off the half grid, and depths below 16.
            let x = match n % 3 {
                0 => (rng.next_f64() * 8.0 - 4.0) * f64::from(1u32 << AUX_BITS),
                1 => f64::from(rng.next_u32() as i32 >> 1) + 0.5,
                _ => f64::from(rng.next_f32() * 16.0) * 2f64.powi(DEPTH_BITS as i32),
            };
            assert_eq!(round_small(x), x.round() as i64, "{x}");
        }
    }

    /// The `f64` rounding `aux_units` replaced: the clamped, scaled value rounded by the
    /// library (ties away from zero).
    fn aux_units_by_library(v: f32) -> i64 {
        if v.is_finite() {
            (f64::from(v.clamp(-4.0, 4.0)) * f64::from(1u32 << AUX_BITS)).round() as i64
        } else {
            0
        }
    }

    #[test]
    fn aux_units_match_the_library_rounding_of_the_scaled_value() {
        let half_unit = 2f32.powi(-(AUX_BITS as i32) - 1);
        let mut edges = vec![
            0.0,
            -0.0,
            4.0,
            -4.0,
            4.5,
            -1.0e30,
            f32::MIN_POSITIVE,
            -f32::from_bits(1),
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        // Ties and their neighbours on the unit grid, near zero and near the clamp.
        for k in [0.0f32, 1.0, 2.0, 1000.0] {
            let tie = (2.0 * k + 1.0) * half_unit;
            for t in [tie, -tie] {
                edges.extend([
                    t,
                    f32::from_bits(t.to_bits() - 1),
                    f32::from_bits(t.to_bits() + 1),
                ]);
            }
        }
        let near_four = 4.0 - half_unit;
        edges.extend([near_four, -near_four]);
        for v in edges {
            assert_eq!(aux_units(v), aux_units_by_library(v), "{v:e}");
        }
        let mut rng = Rng::new(7, 3);
        for n in 0..1_000_000u32 {
            let v = match n % 3 {
                0 => rng.next_f32() * 10.0 - 5.0,
                // Tiny components (normals near an axis): a few bits below the unit.
                1 => (rng.next_f32() - 0.5) * 2f32.powi(-(AUX_BITS as i32) + 4),
                _ => f32::from_bits(rng.next_u32()),
            };
            assert_eq!(aux_units(v), aux_units_by_library(v), "{v:e}");
        }
    }

    #[test]
    fn a_sample_with_only_an_albedo_or_only_a_normal_adds_that_layer() {
        let unit = 1i64 << AUX_BITS;
        let mut p = Pixel::default();
        let mut s = PixelSample {
            radiance: Rgb([1.0, 2.0, 3.0]),
            albedo: Rgb::ZERO,
            normal: Vec3::new(0.0, 0.0, -1.0),
            depth: f32::INFINITY,
            lights: [Rgb::ZERO; crate::film::MAX_LIGHT_LAYERS],
        };
        p.add(&s);
        assert_eq!((p.albedo, p.normal), ([0; 3], [0, 0, -unit]));
        s.albedo = Rgb([0.5, 0.0, 0.25]);
        s.normal = Vec3::ZERO;
        p.add(&s);
        assert_eq!(
            (p.albedo, p.normal),
            ([unit / 2, 0, unit / 4], [0, 0, -unit])
        );
        // Neither: the sums stay, the count and the radiance grow.
        s.albedo = Rgb::ZERO;
        p.add(&s);
        assert_eq!(
            (p.n, p.albedo, p.normal),
            (3, [unit / 2, 0, unit / 4], [0, 0, -unit])
        );
        assert_eq!(p.mean_f64(), [1.0, 2.0, 3.0]);
    }

    #[test]
    fn depth_units_match_the_library_above_and_below_sixteen() {
        let mut rng = Rng::new(6, 2);
        for n in 0..200_000u32 {
            let d = if n % 2 == 0 {
                rng.next_f32() * 32.0
            } else {
                rng.next_f32() * MAX_DEPTH
            };
            let want = (f64::from(d) * 2f64.powi(DEPTH_BITS as i32)).round() as i128;
            assert_eq!(depth_units(d), want, "{d}");
        }
        for d in [0.0, 16.0, f32::from_bits(16f32.to_bits() - 1), MAX_DEPTH] {
            let want = (f64::from(d) * 2f64.powi(DEPTH_BITS as i32)).round() as i128;
            assert_eq!(depth_units(d), want, "{d}");
        }
    }
}
