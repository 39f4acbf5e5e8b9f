//! Sample statistics for Monte-Carlo tests: mean, variance, standard error and z-scores.
//!
//! A test accepts an estimate when it lies within `k` standard errors of the expected value,
//! plus a small absolute slack for rounding; the standard error comes from the estimator's own
//! sample variance, so the tolerance follows the estimator's noise. Every variance here is the
//! unbiased sample variance (divisor `n − 1`), computed in f64 in two passes (mean first, then
//! squared deviations), which is also an oracle independent of the film's running sums.

use velour::sampling::Rng;
use velour::spectrum::Rgb;

/// Arithmetic mean of `xs` (NaN when empty).
pub fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}

/// Unbiased sample variance of `xs`: `Σ (x − mean)² / (n − 1)`.
///
/// Panics with fewer than two values, for which it is undefined.
pub fn variance(xs: &[f64]) -> f64 {
    assert!(
        xs.len() >= 2,
        "a sample variance needs at least two values, got {}",
        xs.len()
    );
    let m = mean(xs);
    xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (xs.len() as f64 - 1.0)
}

/// The mean of `xs` and its standard error (see [`Estimate::of`]).
pub fn mean_and_standard_error(xs: &[f64]) -> (f64, f64) {
    let e = Estimate::of(xs);
    (e.mean, e.standard_error)
}

/// A sample mean with its standard error `√(variance / n)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The sample mean.
    pub mean: f64,
    /// Standard error of the mean.
    pub standard_error: f64,
    /// Number of values.
    pub count: usize,
}

impl Estimate {
    /// The mean and standard error of `xs` (at least two values).
    pub fn of(xs: &[f64]) -> Estimate {
        Estimate {
            mean: mean(xs),
            standard_error: (variance(xs) / xs.len() as f64).sqrt(),
            count: xs.len(),
        }
    }

    /// `(mean − expected) / standard_error`.
    pub fn z_score(&self, expected: f64) -> f64 {
        z_score(self.mean, expected, self.standard_error)
    }

    /// Whether `|mean − expected| ≤ sigmas · standard_error + slack`.
    pub fn agrees_with(&self, expected: f64, sigmas: f64, slack: f64) -> bool {
        (self.mean - expected).abs() <= sigmas * self.standard_error + slack
    }

    /// Asserts [`Estimate::agrees_with`], naming `what` and the numbers when it fails.
    pub fn assert_agrees(&self, expected: f64, sigmas: f64, slack: f64, what: &str) {
        assert!(
            self.agrees_with(expected, sigmas, slack),
            "{what}: {} ± {} (n = {}) vs expected {expected} (tolerance {sigmas} σ + {slack})",
            self.mean,
            self.standard_error,
            self.count
        );
    }
}

/// Draws `n` values `f(rng)` and returns their mean and standard error.
pub fn estimate(n: usize, rng: &mut Rng, mut f: impl FnMut(&mut Rng) -> f64) -> Estimate {
    let xs: Vec<f64> = (0..n).map(|_| f(rng)).collect();
    Estimate::of(&xs)
}

/// Draws `n` colours `f(rng)` and returns the mean and standard error of each channel.
pub fn estimate_rgb(n: usize, rng: &mut Rng, mut f: impl FnMut(&mut Rng) -> Rgb) -> [Estimate; 3] {
    let mut channels: [Vec<f64>; 3] = Default::default();
    for _ in 0..n {
        let v = f(rng);
        for (c, xs) in channels.iter_mut().enumerate() {
            xs.push(f64::from(v[c]));
        }
    }
    channels.map(|xs| Estimate::of(&xs))
}

/// Asserts [`Estimate::agrees_with`] for each channel of `estimates` against `expected`.
pub fn assert_rgb_agrees(
    estimates: &[Estimate; 3],
    expected: Rgb,
    sigmas: f64,
    slack: f64,
    what: &str,
) {
    for (c, e) in estimates.iter().enumerate() {
        e.assert_agrees(
            f64::from(expected[c]),
            sigmas,
            slack,
            &format!("{what}, channel {c}"),
        );
    }
}

/// `(value − expected) / standard_error`.
pub fn z_score(value: f64, expected: f64, standard_error: f64) -> f64 {
    (value - expected) / standard_error
}

/// z-score of the difference of two independent estimates:
/// `(a − b) / √(se_a² + se_b²)`.
pub fn difference_z_score(a: &Estimate, b: &Estimate) -> f64 {
    (a.mean - b.mean) / a.standard_error.hypot(b.standard_error)
}

/// Standard error of a success fraction over `n` Bernoulli trials of probability `p`:
/// `√(p (1 − p) / n)`.
pub fn binomial_standard_error(p: f64, n: usize) -> f64 {
    (p * (1.0 - p) / n as f64).sqrt()
}

/// z-score of a Poisson count against its mean (the variance of a Poisson count is its mean).
pub fn poisson_z_score(count: f64, mean: f64) -> f64 {
    (count - mean) / mean.sqrt()
}

/// Asserts that two estimates `(mean, standard error)` agree within 4 standard errors of their
/// difference (independent estimates, so the errors add in quadrature).
#[allow(dead_code)]
pub fn assert_means_agree(a: (f64, f64), b: (f64, f64), what: &str) {
    let z = z_score(a.0, b.0, (a.1 * a.1 + b.1 * b.1).sqrt());
    assert!(
        z.abs() < 4.0,
        "{what}: {} ± {} vs {} ± {} (z = {z:.2})",
        a.0,
        a.1,
        b.0,
        b.1
    );
}
