//! The hero channel: which RGB channel drives a free flight, chosen by throughput, with
//! one-sample MIS (balance heuristic) over channels (docs/references.md §4.6).

use super::DensityCoefficients;
use crate::spectrum::Rgb;

/// Channel-selection probabilities proportional to |β_c · α_c| (Chiang et al. 2016, as in
/// Cycles' random walk), falling back to |β_c| and then to uniform when those are all zero.
#[must_use]
pub fn channel_probabilities(beta: Rgb, alpha: Rgb) -> [f32; 3] {
    let mut w = [0usize, 1, 2].map(|c| (beta[c] * alpha[c]).abs());
    let mut sum: f32 = w.iter().sum();
    if !(sum > 0.0) || !sum.is_finite() {
        w = [0usize, 1, 2].map(|c| beta[c].abs());
        sum = w.iter().sum();
    }
    if !(sum > 0.0) || !sum.is_finite() {
        return [1.0 / 3.0; 3];
    }
    w.map(|x| x / sum)
}

/// The channel whose cumulative probability interval contains uniform `u`.
#[must_use]
pub fn pick_channel(p: [f32; 3], u: f32) -> usize {
    if u < p[0] {
        0
    } else if u < p[0] + p[1] || p[2] == 0.0 {
        1
    } else {
        2
    }
}

/// Channel probabilities ∝ |β_c α_c| (Chiang et al. 2016), with fallbacks (see
/// [`channel_probabilities`]).
pub(super) fn hero_probabilities(beta: Rgb, coeff: &DensityCoefficients) -> [f32; 3] {
    channel_probabilities(beta, coeff.sigma_s.safe_div(coeff.sigma_t))
}
