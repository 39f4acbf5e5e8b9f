//! Special functions in `f32` needed by the Beckmann distribution: the error function, its
//! complement and its inverse.
//!
//! * [`erfc`] uses the Chebyshev-fitted exponential form of Press et al., *Numerical Recipes*
//!   (2nd ed., §6.2, "erfcc"), whose fractional error is below 1.2e-7 for every argument, so
//!   the tail `erfc(x)` for large `x` keeps full relative precision (no `1 - erf` cancellation).
//! * [`erf`] uses the Maclaurin series near zero (relative precision for tiny arguments) and
//!   `1 - erfc` elsewhere.
//! * [`erf_inv`] starts from the single-precision polynomial fit of M. Giles, "Approximating
//!   the erfinv function" (GPU Computing Gems, 2011) and polishes it with one Newton step
//!   whose residual is formed in the tail-accurate variable `1 - |y|`.

use std::f32::consts::PI;

/// 2/√π.
const TWO_OVER_SQRT_PI: f32 = std::f32::consts::FRAC_2_SQRT_PI;

/// Complementary error function `erfc(x) = 1 - erf(x)`, fractional error < 2e-7 for all `x`
/// (Numerical Recipes "erfcc" fit). Returns 2 for `x = -∞` and 0 for `x = +∞`; NaN in, NaN out.
#[must_use]
pub fn erfc(x: f32) -> f32 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_2
        + t * (1.000_023_7
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_204
                                + t * (1.488_515_9 + t * (-0.822_152_2 + t * 0.170_872_77))))))));
    let ans = if z.is_infinite() { 0.0 } else { t * poly.exp() };
    if x >= 0.0 {
        ans
    } else {
        2.0 - ans
    }
}

/// Error function `erf(x) = 2/√π ∫_0^x e^{-t²} dt`; absolute error < 1.2e-7 and relative
/// error < 1e-6 near 0.
#[must_use]
pub fn erf(x: f32) -> f32 {
    let z = x.abs();
    if z < 0.5 {
        // Maclaurin series: 2/√π Σ (-1)^n x^{2n+1} / (n! (2n+1)); 6 terms give < 1e-9 at 0.5.
        let z2 = x * x;
        let s = 1.0
            + z2 * (-1.0 / 3.0
                + z2 * (1.0 / 10.0
                    + z2 * (-1.0 / 42.0 + z2 * (1.0 / 216.0 + z2 * (-1.0 / 1320.0)))));
        TWO_OVER_SQRT_PI * x * s
    } else if x.is_nan() {
        x
    } else {
        (1.0 - erfc(z)).copysign(x)
    }
}

/// Inverse error function on `(-1, 1)`: returns `x` with `erf(x) = y`. `y = ±1` gives `±∞`,
/// `|y| > 1` and NaN give NaN. Accurate to a few ulp of `x` for `|y| ≤ 1 - 2^-24`.
#[must_use]
pub fn erf_inv(y: f32) -> f32 {
    if y.is_nan() || y.abs() > 1.0 {
        return f32::NAN;
    }
    if y.abs() == 1.0 {
        return f32::INFINITY.copysign(y);
    }
    // Giles (2011), single-precision branch; (1-y)(1+y) is exact enough near |y| = 1.
    let w = -((1.0 - y) * (1.0 + y)).ln();
    let mut p;
    if w < 5.0 {
        let w = w - 2.5;
        p = 2.810_226_4e-8;
        p = 3.432_739_4e-7 + p * w;
        p = -3.523_387_7e-6 + p * w;
        p = -4.391_506_5e-6 + p * w;
        p = 2.185_808_7e-4 + p * w;
        p = -1.253_725e-3 + p * w;
        p = -4.177_681_6e-3 + p * w;
        p = 0.246_640_73 + p * w;
        p = 1.501_409_4 + p * w;
    } else {
        let w = w.sqrt() - 3.0;
        p = -2.002_142_6e-4;
        p = 1.009_505_6e-4 + p * w;
        p = 1.349_343_2e-3 + p * w;
        p = -3.673_428_4e-3 + p * w;
        p = 5.739_507_7e-3 + p * w;
        p = -7.622_461_3e-3 + p * w;
        p = 9.438_870_5e-3 + p * w;
        p = 1.001_674 + p * w;
        p = 2.832_976_8 + p * w;
    }
    let x = p * y;
    // Giles's fit is accurate to a few ulp in the body; in the tail (where x is read through
    // erfc, e.g. by Beckmann slopes) polish it with one Newton step whose residual is formed
    // from erfc: 1 - |y| is exact there (Sterbenz) and erfc keeps relative precision.
    if y.abs() < 0.9 {
        return x;
    }
    let ax = x.abs();
    let ay = y.abs();
    let resid = if ay < 0.5 {
        erf(ax) - ay
    } else {
        (1.0 - ay) - erfc(ax)
    };
    let deriv = TWO_OVER_SQRT_PI * (-ax * ax).exp();
    if deriv > 0.0 && resid.is_finite() {
        let step = resid / deriv;
        // A Newton step on a convex, monotone function: never let it overshoot wildly.
        if step.abs() < 0.1 * ax.max(1e-30) + 1e-30 {
            return (ax - step).copysign(y);
        }
    }
    x
}

/// `1/√π`.
pub(crate) const INV_SQRT_PI: f32 = 0.5 * std::f32::consts::FRAC_2_SQRT_PI;

/// `e^{-a²}/(a√π) - erfc(a)` for `a > 0`, computed without catastrophic cancellation for
/// large `a` (asymptotic series beyond `a = 3`). This is `2 Λ(a)` of the Beckmann distribution.
pub(crate) fn beckmann_two_lambda(a: f32) -> f32 {
    if !(a > 0.0) {
        return f32::INFINITY;
    }
    if a > 3.0 {
        // erfc(a) ~ e^{-a²}/(a√π) (1 - 1/(2a²) + 3/(4a⁴) - 15/(8a⁶) + 105/(16a⁸) ...).
        let r = 1.0 / (a * a);
        let series = r * (0.5 - r * (0.75 - r * (1.875 - r * 6.5625)));
        return (-a * a).exp() / (a * PI.sqrt()) * series;
    }
    ((-a * a).exp() * INV_SQRT_PI / a - erfc(a)).max(0.0)
}
