//! Exact fixed-point accumulators for the film.
//!
//! Floating-point addition is not associative, so a pixel whose samples are summed in two
//! processes and then added differs in the last bits from the same pixel summed in one. The film
//! therefore rounds every sample once, to a fixed binary grid, and adds integers: integer
//! addition is associative and exact, so any split of a pixel's samples (tiles, sample ranges,
//! a resumed checkpoint) merges to the same bits as one uninterrupted render.
//!
//! [`Fixed192`] is a signed 192-bit two's-complement integer counting units of `2^-frac_bits`.
//! The film uses 96 fractional bits for radiance sums (exact for every `f32` sample of magnitude
//! at least 2^-73) and 80 for sums of squares (exact for squares of at least 2^-33, within
//! 2^-81 of the square below that). With samples limited to [`MAX_SAMPLE`] and at most 2^32
//! samples per pixel, no sum can overflow.

/// Largest sample magnitude the film accumulates (2^32 ≈ 4.3 × 10⁹); larger samples are
/// dropped and counted like non-finite ones.
pub const MAX_SAMPLE: f64 = (1u64 << 32) as f64;

/// A signed 192-bit fixed-point number: three little-endian 64-bit limbs, two's complement.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Fixed192(pub [u64; 3]);

impl Fixed192 {
    /// Zero.
    pub const ZERO: Fixed192 = Fixed192([0; 3]);

    /// `v · 2^frac_bits`, rounded to the nearest integer (ties away from zero). `v` must be
    /// finite with `|v| · 2^frac_bits < 2^190`; larger values saturate to that bound. (The
    /// film adds values in place, [`Fixed192::add_f64`]; this is that sum from zero.)
    #[cfg(test)]
    #[must_use]
    pub fn from_f64(v: f64, frac_bits: u32) -> Fixed192 {
        Fixed192::ZERO.add_f64(v, frac_bits)
    }

    /// `self` plus `v · 2^frac_bits` rounded to the nearest integer (ties away from zero),
    /// wrapping; `v` must be finite with `|v| · 2^frac_bits < 2^190` (larger values saturate
    /// to that bound, non-finite ones add nothing). The film's usual case: a normal number
    /// (not zero, subnormal, infinite or NaN: those have exponent field 0, or 0x7ff and a
    /// shift of at least 972) whose value in units, mantissa · 2^shift with 0 ≤ shift ≤ 75,
    /// is below 2^128. That magnitude is added to (for a negative `v`, subtracted from) the
    /// two low limbs with one carry (borrow) into the top limb, without building and
    /// negating a 192-bit number.
    #[must_use]
    #[inline]
    pub fn add_f64(self, v: f64, frac_bits: u32) -> Fixed192 {
        let bits = v.abs().to_bits();
        let exp = (bits >> 52) as i64;
        let shift = exp - 1075 + i64::from(frac_bits);
        if exp != 0 && (shift as u64) <= 75 {
            let m = (bits & ((1u64 << 52) - 1)) | (1u64 << 52);
            let w = u128::from(m) << shift;
            let low = u128::from(self.0[0]) | (u128::from(self.0[1]) << 64);
            let (low, top) = if v < 0.0 {
                let (d, borrow) = low.overflowing_sub(w);
                (d, self.0[2].wrapping_sub(u64::from(borrow)))
            } else {
                let (d, carry) = low.overflowing_add(w);
                (d, self.0[2].wrapping_add(u64::from(carry)))
            };
            return Fixed192([low as u64, (low >> 64) as u64, top]);
        }
        self.add(Fixed192::from_f64_general(v, frac_bits))
    }

    /// `v · 2^frac_bits` rounded as [`Fixed192::add_f64`] rounds it, for every value (the
    /// fast path's cases included).
    fn from_f64_general(v: f64, frac_bits: u32) -> Fixed192 {
        let bits = v.abs().to_bits();
        let exp = (bits >> 52) as i64;
        if exp == 0x7ff || v == 0.0 {
            return Fixed192::ZERO;
        }
        // v = mantissa · 2^shift exactly (subnormals have no hidden bit and exponent 1).
        let (mantissa, e) = if exp == 0 {
            (bits & ((1u64 << 52) - 1), 1)
        } else {
            ((bits & ((1u64 << 52) - 1)) | (1u64 << 52), exp)
        };
        let shift = e - 1075 + i64::from(frac_bits);
        let magnitude: [u64; 3] = if shift >= 0 {
            if shift > 190 - 53 {
                [u64::MAX, u64::MAX, (1u64 << 62) - 1]
            } else {
                shl(mantissa, shift as u32)
            }
        } else {
            let s = (-shift) as u32;
            if s > 54 {
                [0; 3]
            } else {
                // Round half away from zero.
                let q = (mantissa >> s) + ((mantissa >> (s - 1)) & 1);
                [q, 0, 0]
            }
        };
        let out = Fixed192(magnitude);
        if v < 0.0 {
            out.neg()
        } else {
            out
        }
    }

    /// The two's-complement negation.
    #[must_use]
    pub fn neg(self) -> Fixed192 {
        let inv = Fixed192(self.0.map(|l| !l));
        inv.add(Fixed192([1, 0, 0]))
    }

    /// Wrapping 192-bit addition (the film's bounds keep it from wrapping).
    #[must_use]
    #[inline]
    pub fn add(self, o: Fixed192) -> Fixed192 {
        let (l0, c0) = self.0[0].overflowing_add(o.0[0]);
        let (l1a, c1a) = self.0[1].overflowing_add(o.0[1]);
        let (l1, c1b) = l1a.overflowing_add(u64::from(c0));
        let l2 = self.0[2]
            .wrapping_add(o.0[2])
            .wrapping_add(u64::from(c1a) + u64::from(c1b));
        Fixed192([l0, l1, l2])
    }

    /// Whether the number is negative.
    #[must_use]
    pub fn is_negative(self) -> bool {
        self.0[2] >> 63 == 1
    }

    /// The value divided by `2^frac_bits`, correctly rounded to the nearest `f64` (ties to
    /// even).
    #[must_use]
    pub fn to_f64(self, frac_bits: u32) -> f64 {
        let (neg, m) = if self.is_negative() {
            (true, self.neg())
        } else {
            (false, self)
        };
        let Some(top_limb) = (0..3).rev().find(|&i| m.0[i] != 0) else {
            return 0.0;
        };
        // The highest 64 significant bits, with a sticky bit for everything below them, round
        // exactly as the whole number would (64 > 53 + 2).
        let lead = m.0[top_limb].leading_zeros();
        let high_bit = 64 * top_limb as u32 + 63 - lead; // index of the top set bit
        let v = if high_bit < 64 {
            m.0[0] as f64
        } else {
            let low = high_bit - 63; // bit index of the window's lowest bit
            let window = |i: u32| -> u64 {
                let (limb, off) = ((i / 64) as usize, i % 64);
                let a = m.0[limb] >> off;
                let b = if off == 0 || limb + 1 > 2 {
                    0
                } else {
                    m.0[limb + 1] << (64 - off)
                };
                a | b
            };
            let mut top = window(low);
            let sticky = (0..(low / 64) as usize).any(|i| m.0[i] != 0)
                || (m.0[(low / 64) as usize] & ((1u64 << (low % 64)) - 1)) != 0;
            if sticky {
                top |= 1;
            }
            top as f64 * 2f64.powi(low as i32)
        };
        let v = v * 2f64.powi(-(frac_bits as i32));
        if neg {
            -v
        } else {
            v
        }
    }

    /// The six little-endian 32-bit words of the number (for storing in an EXR `u32` channel).
    #[must_use]
    pub fn to_words(self) -> [u32; 6] {
        let mut w = [0u32; 6];
        for (i, l) in self.0.iter().enumerate() {
            w[2 * i] = *l as u32;
            w[2 * i + 1] = (*l >> 32) as u32;
        }
        w
    }

    /// The inverse of [`Fixed192::to_words`].
    #[must_use]
    pub fn from_words(w: [u32; 6]) -> Fixed192 {
        Fixed192(std::array::from_fn(|i| {
            u64::from(w[2 * i]) | (u64::from(w[2 * i + 1]) << 32)
        }))
    }
}

/// `m << s` as three limbs, for `m < 2^53`, `s ≤ 137`.
fn shl(m: u64, s: u32) -> [u64; 3] {
    let wide = u128::from(m);
    if s < 64 {
        let v = wide << s;
        [v as u64, (v >> 64) as u64, 0]
    } else if s < 128 {
        let v = wide << (s - 64);
        [0, v as u64, (v >> 64) as u64]
    } else {
        [0, 0, m << (s - 128)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_representable_values() {
        for v in [
            0.0,
            1.0,
            -1.0,
            0.5,
            3.25,
            -1e-9,
            1e12,
            -7.0e11,
            2f64.powi(-90),
            1.0 + 2f64.powi(-52),
        ] {
            let f = Fixed192::from_f64(v, 96);
            assert_eq!(f.to_f64(96), v, "{v}");
            assert_eq!(Fixed192::from_words(f.to_words()), f);
        }
    }

    #[test]
    fn addition_is_exact_and_order_free() {
        let xs: Vec<f64> = (0..1000)
            .map(|i| ((i * 7919) % 1013) as f64 * 1e-3 - 0.3 + 1e-20 * i as f64)
            .collect();
        let fwd = xs
            .iter()
            .fold(Fixed192::ZERO, |a, &x| a.add(Fixed192::from_f64(x, 96)));
        let mut rev = Fixed192::ZERO;
        for &x in xs.iter().rev() {
            rev = rev.add(Fixed192::from_f64(x, 96));
        }
        let halves = xs[..400]
            .iter()
            .fold(Fixed192::ZERO, |a, &x| a.add(Fixed192::from_f64(x, 96)))
            .add(
                xs[400..]
                    .iter()
                    .fold(Fixed192::ZERO, |a, &x| a.add(Fixed192::from_f64(x, 96))),
            );
        assert_eq!(fwd, rev);
        assert_eq!(fwd, halves);
        let exact: f64 = xs.iter().sum();
        assert!((fwd.to_f64(96) - exact).abs() < 1e-9);
        // Correct rounding: 1 + 2^-60 is 1 in f64; 2^70 + 1 + 2^-90 rounds like the real sum.
        let one = Fixed192::from_f64(1.0, 96);
        let tiny = Fixed192::from_f64(2f64.powi(-60), 96);
        assert_eq!(one.add(tiny).to_f64(96), 1.0);
        let half_ulp = Fixed192::from_f64(2f64.powi(-53), 96);
        assert_eq!(one.add(half_ulp).to_f64(96), 1.0, "ties to even");
        assert_eq!(
            one.add(half_ulp).add(tiny).to_f64(96),
            1.0 + 2f64.powi(-52),
            "just above the tie rounds up"
        );
    }

    #[test]
    fn adding_a_value_in_place_is_adding_its_conversion() {
        let mut rng = crate::sampling::Rng::new(9, 4);
        // Accumulators on both sides of zero and of the limb boundaries (carries and
        // borrows across both low limbs and into the top one).
        let mut accs = vec![
            Fixed192::ZERO,
            Fixed192([u64::MAX, u64::MAX, 0]),
            Fixed192([u64::MAX, 0, 0]),
            Fixed192([0, 0, 1]),
            Fixed192([0, 1, 0]),
            Fixed192::from_f64(-1.0, 96),
            Fixed192([u64::MAX; 3]),
        ];
        let mut limb = || u64::from(rng.next_u32()) << 32 | u64::from(rng.next_u32());
        for _ in 0..64 {
            accs.push(Fixed192([limb(), limb(), limb() >> 3]));
        }
        for bits in [0, 28, 80, 96, 120] {
            let mut values = vec![0.0, -0.0, f64::MIN_POSITIVE, -5.0e-324, f64::NAN, 1.0e300];
            for e in -140..40 {
                for m in [1.0, 1.5, 2.0 - f64::EPSILON] {
                    values.push(m * 2f64.powi(e));
                }
            }
            for _ in 0..2_000 {
                let x = f64::from(rng.next_f32()) * 2f64.powi((rng.next_u32() % 160) as i32 - 120);
                values.push(x);
                values.push(x * x);
            }
            let negated: Vec<f64> = values.iter().map(|v| -v).collect();
            values.extend(negated);
            for a in &accs {
                for &v in &values {
                    assert_eq!(
                        a.add_f64(v, bits),
                        a.add(Fixed192::from_f64_general(v, bits)),
                        "{a:?} + {v:e} at {bits} bits"
                    );
                }
            }
        }
    }

    #[test]
    fn the_two_limb_case_matches_the_general_conversion_bit_for_bit() {
        let mut rng = crate::sampling::Rng::new(5, 2);
        let mut fast = 0usize;
        let mut check = |v: f64, bits: u32| {
            assert_eq!(
                Fixed192::from_f64(v, bits),
                Fixed192::from_f64_general(v, bits),
                "{v:e} at {bits} bits"
            );
            let e = ((v.abs().to_bits() >> 52) as i64) - 1075 + i64::from(bits);
            fast += usize::from(v != 0.0 && (0..=75).contains(&e) && v.is_normal());
        };
        for bits in [0, 28, 48, 80, 96, 120] {
            // Every exponent around the fast path's bounds, both signs, edge mantissas.
            for e in -1100..1030 {
                for m in [1.0, 1.5, 2.0 - f64::EPSILON] {
                    let v = m * 2f64.powi(e);
                    check(v, bits);
                    check(-v, bits);
                }
            }
            for _ in 0..100_000 {
                let x = f64::from(rng.next_f32()) * 2f64.powi((rng.next_u32() % 160) as i32 - 100);
                check(x, bits);
                check(-x * x, bits);
                check(f64::from(x as f32), bits);
            }
            for v in [
                0.0,
                -0.0,
                f64::MIN_POSITIVE,
                5e-324,
                f64::INFINITY,
                f64::NAN,
                f64::MAX,
            ] {
                check(v, bits);
                check(-v, bits);
            }
        }
        assert!(fast > 500_000, "{fast} values on the fast path");
    }

    #[test]
    fn rounds_below_the_grid() {
        // 2^-97 is half a unit at 96 fractional bits: rounds away from zero to one unit.
        assert_eq!(Fixed192::from_f64(2f64.powi(-97), 96), Fixed192([1, 0, 0]));
        assert_eq!(Fixed192::from_f64(2f64.powi(-99), 96), Fixed192::ZERO);
        assert_eq!(
            Fixed192::from_f64(-(2f64.powi(-97)), 96),
            Fixed192([1, 0, 0]).neg()
        );
    }

    #[test]
    fn large_sums_do_not_overflow() {
        // 2^32 samples of MAX_SAMPLE² at 80 fractional bits: 2^176 units, within 2^191.
        let big = Fixed192::from_f64(MAX_SAMPLE * MAX_SAMPLE * 2f64.powi(31), 80);
        let acc = big.add(big);
        assert!(!acc.is_negative());
        assert_eq!(acc.to_f64(80), MAX_SAMPLE * MAX_SAMPLE * 2f64.powi(32));
        let s = Fixed192::from_f64(MAX_SAMPLE * 2f64.powi(31), 96);
        assert_eq!(s.add(s).to_f64(96), MAX_SAMPLE * 2f64.powi(32));
    }
}
