//! The chi-square distribution: upper-tail probabilities (p-values) and critical values.
//!
//! [`p_value`] is exact to about 1e-14 (regularised incomplete gamma function); use it when a
//! test reports the significance of a Pearson statistic. [`critical_value_999`] is the
//! Wilson–Hilferty approximation of the 0.1 % upper point (3 % above the exact point for one
//! degree of freedom, under 1 % from ten on, so slightly lenient); use it for a plain
//! `statistic < critical` acceptance test.

use velour::image_io::compare::gamma_q;

/// Upper-tail probability `P(X ≥ statistic)` of a chi-square variable with `dof` degrees of
/// freedom: `Q(dof / 2, statistic / 2)`.
pub fn p_value(statistic: f64, dof: usize) -> f64 {
    gamma_q(dof as f64 * 0.5, statistic * 0.5)
}

/// Upper 0.1 % point of the chi-square distribution with `dof` degrees of freedom, by the
/// Wilson–Hilferty cube-root normal approximation (Wilson and Hilferty 1931):
/// `dof · (1 − a + z √a)³` with `a = 2 / (9 dof)` and `z = 3.09`, the one-sided 0.999 normal
/// quantile.
pub fn critical_value_999(dof: f64) -> f64 {
    let z = 3.09;
    let a = 2.0 / (9.0 * dof);
    dof * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Pearson's statistic of free-flight distances binned over `[0, length)`: `counts[..bins]`
/// are the scatters per equal-width bin and the last entry the escapes, against the
/// distance CDF `cdf` (so `1 − cdf(length)` is the escape probability). The statistic has
/// `counts.len() − 1` degrees of freedom.
pub fn pearson_free_flight(counts: &[usize], length: f32, cdf: impl Fn(f32) -> f64) -> f64 {
    let bins = counts.len() - 1;
    let n: usize = counts.iter().sum();
    let mut chi2 = 0.0;
    for (i, &c) in counts.iter().enumerate() {
        let p = if i < bins {
            cdf(length * (i + 1) as f32 / bins as f32) - cdf(length * i as f32 / bins as f32)
        } else {
            1.0 - cdf(length)
        };
        let e = p * n as f64;
        chi2 += (c as f64 - e).powi(2) / e;
    }
    chi2
}
