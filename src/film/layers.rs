//! Per-light beauty layers: for each pixel and each named light, the exact sum of the light's
//! share of the radiance samples (the same fixed-point grid as the beauty, [`super::pixel`]),
//! so that the layers merge, resume and split exactly like the beauty.

use super::fixed::Fixed192;
use super::pixel::SUM_BITS;
use super::{FilmError, PixelSample};

/// Exact per-light radiance sums of a rectangle of pixels, `count` lights per pixel.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(super) struct LayerSums {
    count: usize,
    sums: Vec<[Fixed192; 3]>,
}

impl LayerSums {
    /// Zero sums for `pixels` pixels and `count` lights.
    pub fn new(pixels: usize, count: usize) -> Result<LayerSums, FilmError> {
        let len = pixels.saturating_mul(count);
        let mut sums = Vec::new();
        sums.try_reserve_exact(len)
            .map_err(|_| FilmError::Restore(format!("cannot allocate {count} light layers")))?;
        sums.resize(len, [Fixed192::ZERO; 3]);
        Ok(LayerSums { count, sums })
    }

    /// Lights per pixel.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Adds a sample's per-light radiance to pixel `i`.
    #[inline]
    pub fn add(&mut self, i: usize, s: &PixelSample) {
        let start = i * self.count;
        for (sum, light) in self.sums[start..start + self.count]
            .iter_mut()
            .zip(&s.lights)
        {
            for (acc, v) in sum.iter_mut().zip(light.0) {
                *acc = acc.add_f64(f64::from(v), SUM_BITS);
            }
        }
    }

    /// Adds pixel `src` of `other` to pixel `dst` of this one.
    #[inline]
    pub fn merge_pixel(&mut self, dst: usize, other: &LayerSums, src: usize) {
        let n = self.count.min(other.count);
        for k in 0..n {
            let (a, b) = (dst * self.count + k, src * other.count + k);
            if let (Some(a), Some(b)) = (self.sums.get(a).copied(), other.sums.get(b)) {
                self.sums[dst * self.count + k] = std::array::from_fn(|c| a[c].add(b[c]));
            }
        }
    }

    /// Light `k`'s sum at pixel `i`.
    pub fn get(&self, i: usize, k: usize) -> [Fixed192; 3] {
        self.sums
            .get(i * self.count + k)
            .copied()
            .unwrap_or([Fixed192::ZERO; 3])
    }

    /// Sets light `k`'s sum at pixel `i`.
    pub fn set(&mut self, i: usize, k: usize, v: [Fixed192; 3]) {
        if let Some(s) = self.sums.get_mut(i * self.count + k) {
            *s = v;
        }
    }

    /// Clears every sum.
    pub fn clear(&mut self) {
        self.sums.fill([Fixed192::ZERO; 3]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::film::MAX_LIGHT_LAYERS;
    use crate::math::Vec3;
    use crate::spectrum::Rgb;

    /// A sample whose light slots hold `lights` (the other fields are unused by the layers).
    fn sample(lights: &[Rgb]) -> PixelSample {
        let mut s = PixelSample {
            radiance: Rgb::ZERO,
            albedo: Rgb::ZERO,
            normal: Vec3::ZERO,
            depth: f32::INFINITY,
            lights: [Rgb::ZERO; MAX_LIGHT_LAYERS],
        };
        s.lights[..lights.len()].copy_from_slice(lights);
        s
    }

    #[test]
    fn add_sums_each_lights_channels_into_its_own_pixel_and_slot() {
        let mut sums = LayerSums::new(3, 2).expect("a small layer table");
        let a = Rgb([1.0, 2.0, 3.0]);
        let b = Rgb([0.5, 0.25, -4.0]);
        sums.add(1, &sample(&[a, b]));
        sums.add(1, &sample(&[a, b]));
        sums.add(2, &sample(&[b, a]));
        let read = |i, k| sums.get(i, k).map(|f| f.to_f64(SUM_BITS));
        assert_eq!(read(1, 0), [2.0, 4.0, 6.0]);
        assert_eq!(read(1, 1), [1.0, 0.5, -8.0]);
        assert_eq!(read(2, 0), [0.5, 0.25, -4.0]);
        assert_eq!(read(2, 1), [1.0, 2.0, 3.0]);
        assert_eq!(read(0, 0), [0.0; 3]);
        assert_eq!(read(0, 1), [0.0; 3]);
    }
}
