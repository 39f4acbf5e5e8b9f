//! RGB radiometric quantities.
//!
//! velour renders in linear RGB (Rec.709 primaries). Every optical coefficient
//! (σ_a, σ_s, σ_t, albedo, throughput, radiance) is an [`Rgb`].

pub mod blackbody;

use std::ops::{Add, AddAssign, Div, DivAssign, Index, IndexMut, Mul, MulAssign, Neg, Sub};

/// A linear RGB triple of `f32`.
#[derive(Clone, Copy, Debug, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct Rgb(pub [f32; 3]);

impl Rgb {
    /// All zero.
    pub const ZERO: Rgb = Rgb([0.0; 3]);
    /// All one.
    pub const ONE: Rgb = Rgb([1.0; 3]);

    /// Builds a triple from its channels.
    #[must_use]
    pub const fn new(r: f32, g: f32, b: f32) -> Self {
        Rgb([r, g, b])
    }
    /// The same value in every channel.
    #[must_use]
    pub const fn splat(v: f32) -> Self {
        Rgb([v, v, v])
    }
    /// Red channel.
    #[must_use]
    pub fn r(self) -> f32 {
        self.0[0]
    }
    /// Green channel.
    #[must_use]
    pub fn g(self) -> f32 {
        self.0[1]
    }
    /// Blue channel.
    #[must_use]
    pub fn b(self) -> f32 {
        self.0[2]
    }
    /// Largest channel.
    #[must_use]
    pub fn max_component(self) -> f32 {
        self.0[0].max(self.0[1]).max(self.0[2])
    }
    /// Smallest channel.
    #[must_use]
    pub fn min_component(self) -> f32 {
        self.0[0].min(self.0[1]).min(self.0[2])
    }
    /// Mean of the three channels.
    #[must_use]
    pub fn average(self) -> f32 {
        (self.0[0] + self.0[1] + self.0[2]) / 3.0
    }
    /// Rec.709 luminance.
    #[must_use]
    pub fn luminance(self) -> f32 {
        0.2126 * self.0[0] + 0.7152 * self.0[1] + 0.0722 * self.0[2]
    }
    /// True when every channel is exactly zero.
    #[must_use]
    pub fn is_black(self) -> bool {
        self.0 == [0.0; 3]
    }
    /// True when every channel is finite (no NaN, no infinity).
    #[must_use]
    pub fn is_finite(self) -> bool {
        self.0.iter().all(|v| v.is_finite())
    }
    /// Applies `f` to each channel.
    #[must_use]
    pub fn map(self, f: impl Fn(f32) -> f32) -> Self {
        Rgb([f(self.0[0]), f(self.0[1]), f(self.0[2])])
    }
    /// Channel-wise `exp`.
    #[must_use]
    pub fn exp(self) -> Self {
        self.map(f32::exp)
    }
    /// Channel-wise square root (negative inputs clamp to 0).
    #[must_use]
    pub fn sqrt(self) -> Self {
        self.map(|v| v.max(0.0).sqrt())
    }
    /// Channel-wise `max(self, 0)`.
    #[must_use]
    pub fn clamp_zero(self) -> Self {
        self.map(|v| v.max(0.0))
    }
    /// Channel-wise division that yields 0 where the divisor is 0.
    #[must_use]
    pub fn safe_div(self, d: Rgb) -> Self {
        Rgb([0, 1, 2].map(|i| {
            if d.0[i] != 0.0 {
                self.0[i] / d.0[i]
            } else {
                0.0
            }
        }))
    }
}

impl Index<usize> for Rgb {
    type Output = f32;
    fn index(&self, i: usize) -> &f32 {
        &self.0[i]
    }
}
impl IndexMut<usize> for Rgb {
    fn index_mut(&mut self, i: usize) -> &mut f32 {
        &mut self.0[i]
    }
}

macro_rules! rgb_binop {
    ($tr:ident, $f:ident, $tra:ident, $fa:ident, $op:tt) => {
        impl $tr for Rgb {
            type Output = Rgb;
            fn $f(self, o: Rgb) -> Rgb {
                Rgb([self.0[0] $op o.0[0], self.0[1] $op o.0[1], self.0[2] $op o.0[2]])
            }
        }
        impl $tr<f32> for Rgb {
            type Output = Rgb;
            fn $f(self, o: f32) -> Rgb {
                Rgb([self.0[0] $op o, self.0[1] $op o, self.0[2] $op o])
            }
        }
        impl $tra for Rgb {
            fn $fa(&mut self, o: Rgb) {
                *self = *self $op o;
            }
        }
        impl $tra<f32> for Rgb {
            fn $fa(&mut self, o: f32) {
                *self = *self $op o;
            }
        }
    };
}
rgb_binop!(Add, add, AddAssign, add_assign, +);
rgb_binop!(Mul, mul, MulAssign, mul_assign, *);
rgb_binop!(Div, div, DivAssign, div_assign, /);

impl Sub for Rgb {
    type Output = Rgb;
    fn sub(self, o: Rgb) -> Rgb {
        Rgb([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}
impl Sub<f32> for Rgb {
    type Output = Rgb;
    fn sub(self, o: f32) -> Rgb {
        Rgb([self.0[0] - o, self.0[1] - o, self.0[2] - o])
    }
}
impl Neg for Rgb {
    type Output = Rgb;
    fn neg(self) -> Rgb {
        Rgb([-self.0[0], -self.0[1], -self.0[2]])
    }
}
impl Mul<Rgb> for f32 {
    type Output = Rgb;
    fn mul(self, o: Rgb) -> Rgb {
        o * self
    }
}
