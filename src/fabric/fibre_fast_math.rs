//! Branch-free scalar maths for the fibre phase function's batched loops
//! ([`super::fibre_scattering`]): written without branches or float-to-integer conversions so
//! that a loop over quadrature nodes vectorises, and accurate to a few ulp of the library's
//! functions (unit tests below). The polynomials are Cephes' (Moshier 1992).

use crate::math::PI;

/// 1/(2π).
const INV_2PI: f32 = 0.5 / PI;

/// `x` wrapped into `[−π, π]` (to rounding) without a loop: `x − 2π·round(x / 2π)`, the
/// rounding by the float magic number (exact for `|x / 2π| < 2²²`).
#[inline(always)]
pub(super) fn wrap_fast(x: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0; // 1.5 · 2²³
    let n = (x * INV_2PI + MAGIC) - MAGIC;
    x - n * (2.0 * PI)
}

/// `eˣ` for `x ≤ 0` (inputs below −87 are clamped there), branch-free so that a loop of it
/// vectorises: Cody and Waite's range reduction by `ln 2` and Cephes' degree-6 polynomial
/// (`expf`, Moshier 1992), within 2 ulp of the library's `expf` (unit test).
#[inline(always)]
pub(super) fn exp_neg(x: f32) -> f32 {
    const MAGIC: f32 = 12_582_912.0;
    let x = x.max(-87.0);
    // n = round(x / ln 2), as a float and (from the rounded sum's low mantissa bits) as an
    // integer: no float-to-integer conversion, which would not vectorise.
    let t = x * std::f32::consts::LOG2_E + MAGIC;
    let n = t - MAGIC;
    let ni = (t.to_bits() as i32).wrapping_sub(MAGIC.to_bits() as i32);
    let r = x - n * 0.693_359_4 - n * -2.121_944_4e-4;
    let p = ((((1.987_569_1e-4 * r + 1.398_199_9e-3) * r + 8.333_452e-3) * r + 4.166_579_6e-2) * r
        + 0.166_666_65)
        * r
        + 0.5;
    let y = p * r * r + r + 1.0;
    y * f32::from_bits((ni.wrapping_add(127) << 23) as u32)
}

/// The logistic density at `x` without its `1/s` factor: `e/(1 + e)²` with `e = exp(−|x|/s)`,
/// given `neg_inv_s = −1/s`.
#[inline(always)]
pub(super) fn logistic_unscaled(x: f32, neg_inv_s: f32) -> f32 {
    let e = exp_neg(x.abs() * neg_inv_s);
    let d = 1.0 + e;
    e / (d * d)
}

/// `asin x` for `x ∈ [−1, 1]`, branch-free so that a loop of it vectorises: Cephes' `asinf`
/// (Moshier 1992; the half-angle identity above |x| = ½), within 3 ulp of the library's
/// `asinf` (unit test). Odd exactly.
#[inline(always)]
pub(super) fn asin_fast(x: f32) -> f32 {
    let a = x.abs();
    let big = a > 0.5;
    let zb = 0.5 * (1.0 - a);
    let z = if big { zb } else { a * a };
    let r = if big { zb.sqrt() } else { a };
    let p = ((((4.216_32e-2 * z + 2.418_131e-2) * z + 4.547_002_6e-2) * z + 7.495_300_3e-2) * z
        + 0.166_667_52)
        * z
        * r
        + r;
    let y = if big {
        std::f32::consts::FRAC_PI_2 - (p + p)
    } else {
        p
    };
    y.copysign(x)
}

/// Unpolarised Fresnel reflectance for `cos_i ∈ [0, 1]` and `eta ≥ 1` (no total internal
/// reflection): the fibre model's dielectric Fresnel arithmetic on that branch, branch-free.
#[inline(always)]
pub(super) fn fresnel_entering(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(-1.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Units in the last place between `a` and `b` (same sign, finite).
    fn ulps(a: f32, b: f32) -> u32 {
        (a.to_bits() as i64 - b.to_bits() as i64).unsigned_abs() as u32
    }

    #[test]
    fn fast_exp_and_asin_are_within_a_few_ulp() {
        let mut worst = (0, 0);
        for i in 0..=200_000 {
            let x = -87.0 * i as f32 / 200_000.0;
            worst.0 = worst.0.max(ulps(exp_neg(x), x.exp()));
            let y = -1.0 + 2.0 * i as f32 / 200_000.0;
            worst.1 = worst.1.max(ulps(asin_fast(y), y.asin()));
            assert_eq!(asin_fast(-y).to_bits(), (-asin_fast(y)).to_bits());
        }
        assert!(
            worst.0 <= 2 && worst.1 <= 3,
            "ulp errors (exp, asin): {worst:?}"
        );
        assert_eq!(exp_neg(0.0), 1.0);
        assert_eq!(exp_neg(-0.0), 1.0);
        assert!(exp_neg(-1e4) > 0.0 && exp_neg(-1e4) < 1e-37);
        assert_eq!(asin_fast(1.0), std::f32::consts::FRAC_PI_2);
    }
}
