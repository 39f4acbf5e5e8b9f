//! The mip pyramid of a texture: level 0 is the image; each next level halves each side
//! (rounded down, at least 1) with an area-weighted box filter, so odd and other
//! non-power-of-two sizes are filtered exactly: every destination texel averages the source
//! area it covers (fractional texels weighted by their covered part), and each level has the
//! same mean as level 0. Lookups are bilinear within a level and trilinear across levels
//! (docs/references.md §14.1).

use super::Wrap;
use crate::math::Vec2;
use crate::spectrum::Rgb;

/// One level: `width × height` texels of `channels` linear values each, row-major, top row
/// first.
#[derive(Clone, Debug)]
pub struct MipLevel {
    /// Texels across.
    pub width: u32,
    /// Texels down.
    pub height: u32,
    /// `width · height · channels` values.
    pub texels: Vec<f32>,
}

/// Levels from full resolution down to 1 × 1.
#[derive(Clone, Debug)]
pub struct MipPyramid {
    channels: usize,
    levels: Vec<MipLevel>,
    max: Rgb,
    mean: Rgb,
}

/// For each destination texel of an axis shrunk from `src` to `dst` texels, the source
/// texels it covers and their weights (covered length / destination texel length).
fn box_weights(src: usize, dst: usize) -> Vec<Vec<(usize, f32)>> {
    let ratio = src as f64 / dst as f64;
    (0..dst)
        .map(|i| {
            let (a, b) = (i as f64 * ratio, (i + 1) as f64 * ratio);
            let first = a.floor() as usize;
            let last = (b.ceil() as usize).min(src);
            (first..last)
                .filter_map(|j| {
                    let overlap = (b.min(j as f64 + 1.0) - a.max(j as f64)).max(0.0);
                    (overlap > 0.0).then_some((j, (overlap / ratio) as f32))
                })
                .collect()
        })
        .collect()
}

/// `x.floor()` without a call: the x86-64 baseline has no rounding instruction, so `floor`
/// is a library call per coordinate. Bit for bit the same for every `f32` (`−0.0` stays
/// `−0.0`; values of magnitude 2²³ or more, infinities and NaN are returned as they are,
/// as `floor` returns them: they have no fraction).
///
/// A float, not an integer as the grid's, fabric's and level set's floors return: the
/// bilinear weights are `x − ⌊x⌋` and the texel index an `i64`, right at every magnitude of a
/// repeated texture coordinate, where an `i32` floor would saturate.
#[inline(always)]
fn floor_exact(x: f32) -> f32 {
    const INTEGRAL: f32 = 8_388_608.0; // 2^23: every f32 at least this large is an integer
    if x.is_nan() || x.abs() >= INTEGRAL {
        return x;
    }
    // Exact: |x| < 2^23 fits an i32, and every integer below 2^23 is an f32.
    let t = x as i32 as f32;
    if t > x {
        t - 1.0
    } else {
        // `t ≤ x`: `x ≥ 0` (truncation is the floor) or `x` a negative integer (`t = x`).
        // The sign restores a negative zero, which truncation makes positive.
        t.copysign(x)
    }
}

/// `i.rem_euclid(n)` for `n > 0` as an index, without the division where `i` is already in
/// `[0, n)` (the common case: a bilinear lookup's texels away from the image's edge).
#[inline(always)]
fn wrap_index(i: i64, n: i64) -> usize {
    if (0..n).contains(&i) {
        i as usize
    } else {
        i.rem_euclid(n) as usize
    }
}

impl MipLevel {
    /// The next coarser level (each side halved, rounded down, at least 1), box-filtered.
    fn downsample(&self, channels: usize) -> MipLevel {
        let (w, h) = (self.width as usize, self.height as usize);
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let wx = box_weights(w, nw);
        let wy = box_weights(h, nh);
        // Along x, then along y.
        let mut rows = vec![0.0f32; nw * h * channels];
        for y in 0..h {
            for (x, taps) in wx.iter().enumerate() {
                for &(j, wgt) in taps {
                    for c in 0..channels {
                        rows[(y * nw + x) * channels + c] +=
                            wgt * self.texels[(y * w + j) * channels + c];
                    }
                }
            }
        }
        let mut texels = vec![0.0f32; nw * nh * channels];
        for (y, taps) in wy.iter().enumerate() {
            for &(j, wgt) in taps {
                for x in 0..nw {
                    for c in 0..channels {
                        texels[(y * nw + x) * channels + c] +=
                            wgt * rows[(j * nw + x) * channels + c];
                    }
                }
            }
        }
        MipLevel {
            width: nw as u32,
            height: nh as u32,
            texels,
        }
    }
}

impl MipPyramid {
    /// The pyramid over `base` (`channels` = 1 or 3 values per texel; the caller has checked
    /// that `base.texels` holds `width · height · channels` finite values ≥ 0 and that both
    /// sides are ≥ 1).
    #[must_use]
    pub fn new(base: MipLevel, channels: usize) -> MipPyramid {
        let mut max = [0.0f32; 3];
        let mut sum = [0.0f64; 3];
        for texel in base.texels.chunks_exact(channels) {
            for c in 0..3 {
                let v = texel[c.min(channels - 1)];
                max[c] = max[c].max(v);
                sum[c] += f64::from(v);
            }
        }
        let n = (base.width as f64 * base.height as f64).max(1.0);
        let mean = Rgb(sum.map(|s| (s / n) as f32));
        let mut levels = vec![base];
        while let Some(last) = levels.last() {
            if last.width == 1 && last.height == 1 {
                break;
            }
            let next = last.downsample(channels);
            levels.push(next);
        }
        MipPyramid {
            channels,
            levels,
            max: Rgb(max),
            mean,
        }
    }

    /// Values per texel (1 or 3).
    #[must_use]
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Number of levels, 1 + ⌊log2 max(W, H)⌋.
    #[must_use]
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// Level `i` (clamped to the coarsest).
    #[must_use]
    pub fn level(&self, i: usize) -> &MipLevel {
        let last = self.levels.len() - 1;
        &self.levels[i.min(last)]
    }

    /// max(W, H) of level 0, texels.
    #[must_use]
    pub fn side(&self) -> u32 {
        let l = self.level(0);
        l.width.max(l.height)
    }

    /// The largest level-0 texel per channel (a bound on every filtered lookup).
    #[must_use]
    pub fn max(&self) -> Rgb {
        self.max
    }

    /// The mean of level 0 per channel.
    #[must_use]
    pub fn mean(&self) -> Rgb {
        self.mean
    }

    /// The mip level (fractional) for a footprint `texels` wide at level 0: log2(texels),
    /// clamped to [0, levels − 1]; 0 for footprints of a texel or less (and NaN).
    #[inline]
    #[must_use]
    pub fn level_for_width(&self, texels: f32) -> f32 {
        if texels.is_nan() || texels <= 1.0 {
            return 0.0;
        }
        texels.log2().min((self.levels.len() - 1) as f32)
    }

    /// Trilinear lookup: bilinear in the two levels around [`Self::level_for_width`],
    /// blended linearly.
    #[inline]
    #[must_use]
    pub fn trilinear(&self, uv: Vec2, texels: f32, wrap: Wrap) -> Rgb {
        let lambda = self.level_for_width(texels);
        let l0 = lambda.floor();
        let f = lambda - l0;
        let l0 = l0 as usize;
        let a = self.bilinear(l0, uv, wrap);
        if f <= 0.0 || l0 + 1 >= self.levels.len() {
            return a;
        }
        let b = self.bilinear(l0 + 1, uv, wrap);
        a * (1.0 - f) + b * f
    }

    /// Bilinear lookup in level `level` (clamped to the coarsest): texel centres at
    /// (i + ½)/W; `v` runs bottom to top.
    #[inline]
    #[must_use]
    pub fn bilinear(&self, level: usize, uv: Vec2, wrap: Wrap) -> Rgb {
        let l = self.level(level);
        let (w, h) = (l.width as i64, l.height as i64);
        let u = if uv.x.is_finite() { uv.x } else { 0.0 };
        let v = if uv.y.is_finite() { uv.y } else { 0.0 };
        let x = u * l.width as f32 - 0.5;
        let y = (1.0 - v) * l.height as f32 - 0.5;
        let (xf, yf) = (floor_exact(x), floor_exact(y));
        let (fx, fy) = (x - xf, y - yf);
        let (x0, y0) = (xf as i64, yf as i64);
        let index = |i: i64, n: i64| -> usize {
            match wrap {
                Wrap::Repeat => wrap_index(i, n),
                Wrap::Clamp => i.clamp(0, n - 1) as usize,
            }
        };
        let (xa, xb) = (index(x0, w), index(x0 + 1, w));
        let (ya, yb) = (index(y0, h), index(y0 + 1, h));
        let c = self.channels;
        let width = l.width as usize;
        let texel = |x: usize, y: usize| -> Rgb {
            let i = (y * width + x) * c;
            match l.texels.get(i..i + c) {
                Some([g]) => Rgb::splat(*g),
                Some([r, g, b]) => Rgb([*r, *g, *b]),
                _ => Rgb::ZERO,
            }
        };
        let top = texel(xa, ya) * (1.0 - fx) + texel(xb, ya) * fx;
        let bottom = texel(xa, yb) * (1.0 - fx) + texel(xb, yb) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`floor_exact`] is `f32::floor` bit for bit: signed zeros, values just around
    /// integers and halves, the 2²³ boundary, huge values, infinities, NaN and random bit
    /// patterns of every exponent.
    #[test]
    fn floor_exact_is_floor_bit_for_bit() {
        let mut values = vec![
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_608.0,
            16_777_217.0,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for k in -2000..2000 {
            let x = k as f32 * 0.25;
            values.extend([
                x,
                f32::from_bits(x.to_bits() + 1),
                f32::from_bits(x.to_bits().wrapping_sub(1)),
            ]);
        }
        // Random bit patterns (xorshift32).
        let mut bits = 0x9e37_79b9u32;
        for _ in 0..500_000 {
            bits ^= bits << 13;
            bits ^= bits >> 17;
            bits ^= bits << 5;
            values.push(f32::from_bits(bits));
        }
        for x in values {
            let (got, want) = (floor_exact(x), x.floor());
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "{x:e} ({:#x}): {got:e} vs {want:e}",
                x.to_bits()
            );
        }
    }

    /// [`wrap_index`] is `rem_euclid` for indices inside, below and above `[0, n)`.
    #[test]
    fn wrap_index_is_rem_euclid() {
        for n in [1i64, 2, 3, 7, 64, 1000] {
            for i in -3 * n - 2..3 * n + 2 {
                assert_eq!(wrap_index(i, n), i.rem_euclid(n) as usize, "{i} mod {n}");
            }
            for i in [i64::MIN, i64::MIN + 1, i64::MAX] {
                assert_eq!(wrap_index(i, n), i.rem_euclid(n) as usize, "{i} mod {n}");
            }
        }
    }
}
