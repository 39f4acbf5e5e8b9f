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

/// Smallest nonzero radiance magnitude a [`RunSums`] takes (2^-17): every `f32` at least this
/// large is a multiple of 2^-40, so it lies on the sums' grid (2^-[`SUM_BITS`]) and its square,
/// a multiple of 2^-80, on the squares' grid (2^-[`SQ_BITS`]); neither is rounded by the film.
const RUN_MIN: f64 = 1.0 / 131_072.0;

/// Four `f64` lanes (the three colour channels and an unused zero lane) with the operations
/// [`RunSums`] needs: one AVX register where the build has AVX (x86-64-v3), else an array.
#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
mod lanes {
    use std::arch::x86_64::{
        __m256d, _mm256_add_pd, _mm256_andnot_pd, _mm256_cmp_pd, _mm256_cvtps_pd,
        _mm256_movemask_pd, _mm256_mul_pd, _mm256_or_pd, _mm256_set1_pd, _mm256_setzero_pd,
        _mm256_storeu_pd, _mm256_sub_pd, _mm_set_ps, _CMP_EQ_OQ, _CMP_GE_OQ, _CMP_NEQ_UQ,
    };

    /// Four `f64` lanes.
    #[derive(Clone, Copy, Debug)]
    pub struct Lanes(__m256d);

    impl Default for Lanes {
        fn default() -> Self {
            // SAFETY (every intrinsic of this module): the build enables AVX (this module is
            // compiled only then), and none touches memory but `to_array`'s store.
            Lanes(unsafe { _mm256_setzero_pd() })
        }
    }

    impl Lanes {
        /// The channels of `rgb` (exact) and a zero lane.
        #[inline]
        pub fn from_rgb(rgb: [f32; 3]) -> Lanes {
            Lanes(unsafe { _mm256_cvtps_pd(_mm_set_ps(0.0, rgb[2], rgb[1], rgb[0])) })
        }
        #[inline]
        pub fn add(self, o: Lanes) -> Lanes {
            Lanes(unsafe { _mm256_add_pd(self.0, o.0) })
        }
        #[inline]
        pub fn sub(self, o: Lanes) -> Lanes {
            Lanes(unsafe { _mm256_sub_pd(self.0, o.0) })
        }
        #[inline]
        pub fn mul(self, o: Lanes) -> Lanes {
            Lanes(unsafe { _mm256_mul_pd(self.0, o.0) })
        }
        /// Whether every lane is zero or at least `min` in magnitude.
        #[inline]
        pub fn zero_or_at_least(self, min: f64) -> bool {
            unsafe {
                let abs = _mm256_andnot_pd(_mm256_set1_pd(-0.0), self.0);
                let big = _mm256_cmp_pd::<_CMP_GE_OQ>(abs, _mm256_set1_pd(min));
                let zero = _mm256_cmp_pd::<_CMP_EQ_OQ>(self.0, _mm256_setzero_pd());
                _mm256_movemask_pd(_mm256_or_pd(big, zero)) == 0b1111
            }
        }
        /// Whether any lane is nonzero.
        #[inline]
        pub fn any_nonzero(self) -> bool {
            unsafe {
                _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_NEQ_UQ>(self.0, _mm256_setzero_pd())) != 0
            }
        }
        /// The lanes.
        #[inline]
        pub fn to_array(self) -> [f64; 4] {
            let mut out = [0.0; 4];
            // SAFETY: `out` holds four `f64`s; the store is unaligned.
            unsafe { _mm256_storeu_pd(out.as_mut_ptr(), self.0) };
            out
        }
    }
}

/// Four `f64` lanes (the three colour channels and an unused zero lane) with the operations
/// [`RunSums`] needs: one AVX register where the build has AVX (x86-64-v3), else an array.
#[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
mod lanes {
    /// Four `f64` lanes.
    #[derive(Clone, Copy, Debug, Default)]
    pub struct Lanes([f64; 4]);

    impl Lanes {
        /// The channels of `rgb` (exact) and a zero lane.
        #[inline]
        pub fn from_rgb(rgb: [f32; 3]) -> Lanes {
            Lanes([f64::from(rgb[0]), f64::from(rgb[1]), f64::from(rgb[2]), 0.0])
        }
        #[inline]
        pub fn add(self, o: Lanes) -> Lanes {
            Lanes(std::array::from_fn(|i| self.0[i] + o.0[i]))
        }
        #[inline]
        pub fn sub(self, o: Lanes) -> Lanes {
            Lanes(std::array::from_fn(|i| self.0[i] - o.0[i]))
        }
        #[inline]
        pub fn mul(self, o: Lanes) -> Lanes {
            Lanes(std::array::from_fn(|i| self.0[i] * o.0[i]))
        }
        /// Whether every lane is zero or at least `min` in magnitude.
        #[inline]
        pub fn zero_or_at_least(self, min: f64) -> bool {
            self.0.iter().all(|&v| v == 0.0 || v.abs() >= min)
        }
        /// Whether any lane is nonzero.
        #[inline]
        pub fn any_nonzero(self) -> bool {
            self.0.iter().any(|&v| v != 0.0)
        }
        /// The lanes.
        #[inline]
        pub fn to_array(self) -> [f64; 4] {
            self.0
        }
    }
}

use lanes::Lanes;

/// Knuth's TwoSum, lane by lane: `(s, e)` with `s = fl(a + b)` and `a + b = s + e` exactly
/// (round to nearest, no overflow). When `a` and `b` are multiples of a power of two `g`, so are
/// `s` and `e`: a rounded `s` is a multiple of its own ulp, which exceeds the lowest set bit of
/// `a + b`.
#[inline]
fn two_sum(a: Lanes, b: Lanes) -> (Lanes, Lanes) {
    let s = a.add(b);
    let bb = s.sub(a);
    (s, a.sub(s.sub(bb)).add(b.sub(bb)))
}

/// The radiance sums of a run of one pixel's samples, kept in `f64` pairs instead of
/// [`Fixed192`] (six 192-bit conversions and adds a sample): per channel a sum `hi`, the sum
/// `lo` of `hi`'s rounding errors, and the same pair for the squares. Only samples whose
/// channels are zero or at least [`RUN_MIN`] enter, so every value added is on its fixed-point
/// grid, and by [`two_sum`] so is every partial sum and error; an error of `lo` itself (rare)
/// goes straight to the pixel. The pixel's integers after [`Pixel::fold_run`] are then exactly
/// the sum of the samples' units: the same bits as adding each sample with [`Pixel::add`],
/// whatever the run's length.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct RunSums {
    hi: Lanes,
    lo: Lanes,
    sq_hi: Lanes,
    sq_lo: Lanes,
}

impl Pixel {
    /// Adds one sample, which must satisfy [`accepts`].
    #[inline]
    pub fn add(&mut self, s: &PixelSample) {
        self.add_radiance(s.radiance.0);
        self.add_rest(s);
    }

    /// Adds a sample's radiance to the fixed-point sums, one conversion per value.
    #[inline]
    fn add_radiance(&mut self, radiance: [f32; 3]) {
        for (c, &r) in radiance.iter().enumerate() {
            let x = f64::from(r);
            self.sum[c] = self.sum[c].add_f64(x, SUM_BITS);
            self.sum_sq[c] = self.sum_sq[c].add_f64(x * x, SQ_BITS);
        }
    }

    /// Adds one sample, which must satisfy [`accepts`], with its radiance summed in `run`
    /// when it can be (see [`RunSums`]); [`Pixel::fold_run`] must follow the run's last sample.
    #[inline]
    pub fn add_in_run(&mut self, run: &mut RunSums, s: &PixelSample) {
        let x = Lanes::from_rgb(s.radiance.0);
        if x.zero_or_at_least(RUN_MIN) {
            let (h, e) = two_sum(run.hi, x);
            let (l, spill) = two_sum(run.lo, e);
            let (sq_h, sq_e) = two_sum(run.sq_hi, x.mul(x));
            let (sq_l, sq_spill) = two_sum(run.sq_lo, sq_e);
            *run = RunSums {
                hi: h,
                lo: l,
                sq_hi: sq_h,
                sq_lo: sq_l,
            };
            if spill.any_nonzero() || sq_spill.any_nonzero() {
                self.add_spill(spill, sq_spill);
            }
        } else {
            self.add_radiance(s.radiance.0);
        }
        self.add_rest(s);
    }

    /// Adds the rounding errors of a run's `lo` sums (on the grids, so exact).
    #[cold]
    #[inline(never)]
    fn add_spill(&mut self, spill: Lanes, sq_spill: Lanes) {
        let (e, sq_e) = (spill.to_array(), sq_spill.to_array());
        for c in 0..3 {
            self.sum[c] = self.sum[c].add_f64(e[c], SUM_BITS);
            self.sum_sq[c] = self.sum_sq[c].add_f64(sq_e[c], SQ_BITS);
        }
    }

    /// Adds a run's sums to the fixed-point sums (exact: they are on the grids) and empties it.
    #[inline]
    pub fn fold_run(&mut self, run: &mut RunSums) {
        // Zeros (a black channel, an error-free `lo`) add nothing and would take the
        // conversion's general path.
        for (sums, bits, lanes) in [
            (&mut self.sum, SUM_BITS, [run.hi, run.lo]),
            (&mut self.sum_sq, SQ_BITS, [run.sq_hi, run.sq_lo]),
        ] {
            for v in lanes.into_iter().filter(|v| v.any_nonzero()) {
                let v = v.to_array();
                for c in 0..3 {
                    if v[c] != 0.0 {
                        sums[c] = sums[c].add_f64(v[c], bits);
                    }
                }
            }
        }
        *run = RunSums::default();
    }

    /// The count, albedo, normal and depth part of [`Pixel::add`].
    #[inline]
    fn add_rest(&mut self, s: &PixelSample) {
        self.n += 1;
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

    fn radiance_sample(radiance: [f32; 3]) -> PixelSample {
        PixelSample {
            radiance: Rgb(radiance),
            albedo: Rgb::ZERO,
            normal: Vec3::ZERO,
            depth: f32::INFINITY,
            lights: [Rgb::ZERO; crate::film::MAX_LIGHT_LAYERS],
        }
    }

    #[test]
    fn a_run_of_samples_adds_the_same_bits_as_one_sample_at_a_time() {
        let mut rng = Rng::new(11, 6);
        let value = |rng: &mut Rng| -> f32 {
            let sign = if rng.next_u32() & 1 == 0 { 1.0 } else { -1.0 };
            let m = 1.0 + rng.next_f32();
            match rng.next_u32() % 8 {
                0 => 0.0,
                // Around the run's bound 2^-17: the smaller ones are rounded per sample.
                1 => sign * m * 2f32.powi((rng.next_u32() % 8) as i32 - 21),
                // Tiny values, rounded on the sums' and squares' grids.
                2 => sign * m * 2f32.powi(-((rng.next_u32() % 60) as i32) - 20),
                // Up to the film's largest sample, 2^32.
                3 => sign * m * 2f32.powi((rng.next_u32() % 32) as i32),
                _ => sign * m * 2f32.powi((rng.next_u32() % 40) as i32 - 20),
            }
        };
        let mut spilled = 0;
        for run in 0..3_000 {
            let len = 1 + rng.next_u32() % if run % 10 == 0 { 300 } else { 70 };
            let (mut one, mut runs) = (Pixel::default(), Pixel::default());
            let mut sums = RunSums::default();
            let samples: Vec<PixelSample> = (0..len)
                .map(|_| radiance_sample([value(&mut rng), value(&mut rng), value(&mut rng)]))
                .collect();
            for s in &samples {
                one.add(s);
                runs.add_in_run(&mut sums, s);
            }
            // Before the fold the fixed-point sums hold only rounded samples and spilled
            // errors of the runs' `lo` sums.
            spilled += usize::from(runs.sum_sq != [Fixed192::ZERO; 3]);
            runs.fold_run(&mut sums);
            assert_eq!(one, runs, "run {run} of {len} samples");
            // A second run on the same pixel (the run sums were emptied by the fold).
            let extra = radiance_sample([value(&mut rng), 1.0, -3.5]);
            one.add(&extra);
            runs.add_in_run(&mut sums, &extra);
            runs.fold_run(&mut sums);
            assert_eq!(one, runs, "run {run}, then one more sample");
        }
        assert!(spilled > 100, "{spilled} runs spilled or rounded");
    }

    #[test]
    fn a_run_whose_error_sum_is_inexact_spills_it_exactly() {
        // 2^32, then squares with bits 2^64 down to 2^-80: the squares' `lo` sum (errors up to
        // 2^11 with bits down to 2^-80) cannot hold them all, so its own errors spill.
        let big = 4_294_967_296.0f32;
        let odd = [
            1.0 + f32::EPSILON,
            1.5 + f32::EPSILON,
            1.25 + 3.0 * f32::EPSILON,
        ];
        let mut samples = vec![radiance_sample([big, big, big])];
        for k in 0..40 {
            let v = odd[k % 3] * 2f32.powi(-(k as i32 % 17));
            samples.push(radiance_sample([v, -v, big - 256.0 * v]));
        }
        let (mut one, mut runs, mut sums) =
            (Pixel::default(), Pixel::default(), RunSums::default());
        for s in &samples {
            one.add(s);
            runs.add_in_run(&mut sums, s);
        }
        assert_ne!(runs.sum_sq, [Fixed192::ZERO; 3], "nothing spilled");
        runs.fold_run(&mut sums);
        assert_eq!(one, runs);
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
