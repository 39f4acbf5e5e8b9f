//! The channel types the delta and ratio trackers are written over once: [`Rgb`] for media
//! whose coefficients differ per channel, and one `f32` for grey media (σ_t and σ_s equal in
//! every channel), chosen once per flight or shadow ray ([`DensityCoefficients::grey`]).
//!
//! A grey medium's channels take the same decisions and weights, so tracking it in RGB computes
//! everything three times and picks the hero's copy. The scalar instantiation does each
//! operation once, in the same order: its decisions and weights are those of the RGB tracker
//! bit for bit (every RGB operation is per channel), with the same random numbers drawn.

use std::ops::{Add, Div, DivAssign, Mul, MulAssign, Sub};

use super::DensityCoefficients;
use crate::majorant::MajorantSegment;
use crate::spectrum::Rgb;

/// A value per colour channel, as the trackers compute with it: RGB, or one scalar standing for
/// three equal channels.
pub(super) trait Channels:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Mul<f32, Output = Self>
    + Div<f32, Output = Self>
    + MulAssign
    + DivAssign<f32>
{
    /// One in every channel.
    const ONE: Self;
    /// `v` in every channel.
    fn splat(v: f32) -> Self;
    /// Channel `k` (0, 1, 2).
    fn channel(self, k: usize) -> f32;
    /// The largest channel.
    fn max_channel(self) -> f32;
    /// True when every channel is zero.
    fn is_zero(self) -> bool;
    /// `f` per channel.
    fn map(self, f: impl Fn(f32) -> f32) -> Self;
    /// `f` per channel of `self` and `o`.
    fn zip(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self;
    /// As RGB.
    fn to_rgb(self) -> Rgb;
    /// From an RGB value computed from this channel type's coefficients (for a scalar: equal
    /// channels, the first stands for all).
    fn from_rgb(v: Rgb) -> Self;
    /// `Σ_k probs_k · self_k`, summed in channel order.
    fn mix(self, probs: [f32; 3]) -> f32;
}

impl Channels for Rgb {
    const ONE: Self = Rgb::ONE;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Rgb::splat(v)
    }
    #[inline(always)]
    fn channel(self, k: usize) -> f32 {
        self[k]
    }
    #[inline(always)]
    fn max_channel(self) -> f32 {
        self.max_component()
    }
    #[inline(always)]
    fn is_zero(self) -> bool {
        self.is_black()
    }
    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> Self {
        Rgb::map(self, f)
    }
    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        Rgb([f(self[0], o[0]), f(self[1], o[1]), f(self[2], o[2])])
    }
    #[inline(always)]
    fn to_rgb(self) -> Rgb {
        self
    }
    #[inline(always)]
    fn from_rgb(v: Rgb) -> Self {
        v
    }
    #[inline(always)]
    fn mix(self, probs: [f32; 3]) -> f32 {
        probs[0] * self[0] + probs[1] * self[1] + probs[2] * self[2]
    }
}

impl Channels for f32 {
    const ONE: Self = 1.0;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn channel(self, _k: usize) -> f32 {
        self
    }
    #[inline(always)]
    fn max_channel(self) -> f32 {
        self
    }
    #[inline(always)]
    fn is_zero(self) -> bool {
        self == 0.0
    }
    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> Self {
        f(self)
    }
    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        f(self, o)
    }
    #[inline(always)]
    fn to_rgb(self) -> Rgb {
        Rgb::splat(self)
    }
    #[inline(always)]
    fn from_rgb(v: Rgb) -> Self {
        v[0]
    }
    #[inline(always)]
    fn mix(self, probs: [f32; 3]) -> f32 {
        probs[0] * self + probs[1] * self + probs[2] * self
    }
}

/// [`DensityCoefficients`] in a channel type: σ_t(d) = base_t + d·σ_t⁰, σ_s(d) = base_s + d·σ_s⁰.
#[derive(Clone, Copy, Debug)]
pub(super) struct Coefficients<V> {
    pub(super) sigma_t: V,
    pub(super) sigma_s: V,
    pub(super) base_t: V,
    pub(super) base_s: V,
}

impl<V: Channels> Coefficients<V> {
    /// σ_t at density `d`.
    #[inline(always)]
    pub(super) fn sigma_t_at(&self, d: f32) -> V {
        self.base_t + self.sigma_t * d
    }
    /// σ_s at density `d`.
    #[inline(always)]
    pub(super) fn sigma_s_at(&self, d: f32) -> V {
        self.base_s + self.sigma_s * d
    }
    /// The scalar majorant of a segment: the largest channel of σ_t at its max density
    /// ([`DensityCoefficients::majorant`]).
    #[inline(always)]
    pub(super) fn majorant(&self, seg: &MajorantSegment) -> f32 {
        self.sigma_t_at(seg.max).max_channel()
    }
    /// True when nothing attenuates on the segment ([`DensityCoefficients::is_void`]).
    #[inline(always)]
    pub(super) fn is_void(&self, seg: &MajorantSegment) -> bool {
        seg.max <= 0.0 && seg.min >= 0.0 && self.base_t.is_zero()
    }
}

impl DensityCoefficients {
    /// The coefficients as RGB values.
    #[inline]
    pub(super) fn rgb(&self) -> Coefficients<Rgb> {
        Coefficients {
            sigma_t: self.sigma_t,
            sigma_s: self.sigma_s,
            base_t: self.base_t,
            base_s: self.base_s,
        }
    }

    /// The coefficients as one scalar when the medium is grey (each coefficient equal in all
    /// three channels, bit for bit), else `None`.
    #[inline]
    pub(super) fn grey(&self) -> Option<Coefficients<f32>> {
        fn one(v: Rgb) -> Option<f32> {
            (v[0].to_bits() == v[1].to_bits() && v[1].to_bits() == v[2].to_bits()).then_some(v[0])
        }
        Some(Coefficients {
            sigma_t: one(self.sigma_t)?,
            sigma_s: one(self.sigma_s)?,
            base_t: one(self.base_t)?,
            base_s: one(self.base_s)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_only_when_every_coefficient_is_equal_in_all_channels() {
        let grey = DensityCoefficients::new(Rgb::splat(40.0), Rgb::splat(36.0));
        let c = grey.grey();
        assert!(matches!(c, Some(c) if c.sigma_t == 40.0 && c.sigma_s == 36.0 && c.base_t == 0.0));
        let chroma = DensityCoefficients::new(Rgb::new(40.0, 40.0, 39.0), Rgb::splat(36.0));
        assert!(chroma.grey().is_none());
        let based = DensityCoefficients {
            base_s: Rgb::new(0.1, 0.2, 0.1),
            ..grey
        };
        assert!(based.grey().is_none());
        // −0 and +0 differ in their bits: not grey (the scalar could not stand for both).
        let signed = DensityCoefficients {
            base_t: Rgb::new(0.0, -0.0, 0.0),
            ..grey
        };
        assert!(signed.grey().is_none());
    }

    #[test]
    fn scalar_operations_match_the_rgb_ones_bit_for_bit() {
        let a = 0.3f32;
        let b = 1.7f32;
        let probs = [0.2f32, 0.5, 0.3];
        assert_eq!(Rgb::splat(a).mix(probs), a.mix(probs));
        assert_eq!(
            Rgb::splat(a).zip(Rgb::splat(b), |x, y| x / (x + y)),
            Rgb::splat(a.zip(b, |x, y| x / (x + y)))
        );
        assert_eq!(Rgb::splat(b).max_channel(), b.max_channel());
        assert_eq!(f32::from_rgb(Rgb::splat(a)), a);
    }
}
