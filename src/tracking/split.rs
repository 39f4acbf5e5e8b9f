//! The split free flight for optically thin media (docs/references.md §11.4, "separating the
//! two terms"): the light a ray brings back through a medium is
//! `T(0, d) L_b + ∫₀^d T(0, t) σ_s(t) L_s(t) dt`. Delta tracking estimates the first term by
//! letting the path survive or die, which in a thin medium is noisy on both terms. Instead,
//! with probability `P` the path scatters at a distance drawn from the majorant's exponential
//! truncated to `[0, d]` (it never escapes) and is weighted by `T̂(0, t) σ_s(t) / (p(t) P)`; with
//! probability `1 − P` it passes with weight `T̂(0, d) / (1 − P)`. `T̂` is any unbiased
//! transmittance estimator (the interior's), so each term is estimated without bias and each
//! sample contributes to exactly one of them. `P = max(P_MIN, 1 − T̃)` from the coarse
//! transmittance `T̃` of the segments' mean densities.

use crate::majorant::MajorantSegment;
use crate::spectrum::Rgb;

use super::{transmittance, DensityCoefficients, Flight, TrackingStats, TransmittanceMode};

/// The smallest probability of the scattering branch.
pub const SPLIT_MIN_SCATTER: f32 = 0.1;

/// Samples a split free flight over `[0, t_max]` (`t_max` finite). `segments(a, b)` returns the
/// majorant segments of `[a, b]` (called up to three times); `density(t)` the density at `t`;
/// `mode` estimates the transmittances. Unbiased whenever `mode` is.
pub fn split_flight<F, S, D, U>(
    segments: F,
    coeff: &DensityCoefficients,
    mut density: D,
    mode: TransmittanceMode,
    t_max: f32,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    F: Fn(f32, f32) -> S,
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    U: FnMut() -> f32,
{
    // Majorant optical depth (scalar: the largest channel) and the coarse optical depth.
    let mut tau_majorant = 0.0f64;
    let mut tau_coarse = 0.0f64;
    for seg in segments(0.0, t_max) {
        if coeff.is_void(&seg) {
            continue;
        }
        let len = f64::from(seg.length());
        tau_majorant += f64::from(coeff.majorant(&seg)) * len;
        tau_coarse += f64::from(coeff.sigma_t_at(seg.mean).max_component()) * len;
    }
    if !(tau_majorant > 0.0) {
        // Nothing attenuates: the path passes.
        let tr = transmittance(segments(0.0, t_max), coeff, &mut density, mode, u, stats);
        return Flight::Escape { weight: tr };
    }
    let p_scatter = ((1.0 - (-tau_coarse).exp()) as f32).clamp(SPLIT_MIN_SCATTER, 1.0);
    if p_scatter < 1.0 && u() >= p_scatter {
        let tr = transmittance(segments(0.0, t_max), coeff, &mut density, mode, u, stats);
        return Flight::Escape {
            weight: tr / (1.0 - p_scatter),
        };
    }
    // A distance from the majorant's exponential truncated to [0, t_max]:
    // τ* = −ln(1 − ξ (1 − e^{−τ_M})), then t where the majorant's depth reaches τ*.
    let escape = (-tau_majorant).exp();
    let target = -(1.0 - f64::from(u()) * (1.0 - escape)).ln();
    let mut acc = 0.0f64;
    let mut hit: Option<(f32, f64)> = None;
    for seg in segments(0.0, t_max) {
        if coeff.is_void(&seg) {
            continue;
        }
        let m = f64::from(coeff.majorant(&seg));
        let len = f64::from(seg.length());
        if m > 0.0 && acc + m * len >= target {
            let local = ((target - acc) / m).clamp(0.0, len);
            hit = Some((seg.t0 + local as f32, m));
            break;
        }
        acc += m * len;
    }
    let Some((t, m)) = hit else {
        // Rounding put the target past the last segment: no collision to report.
        return Flight::Escape { weight: Rgb::ZERO };
    };
    let t = t.min(t_max);
    let pdf = m * (-target).exp() / (1.0 - escape);
    let d = density(t);
    stats.lookups += 1;
    stats.real_collisions += 1;
    let tr = transmittance(segments(0.0, t), coeff, &mut density, mode, u, stats);
    let weight = tr * coeff.sigma_s_at(d) / (pdf as f32 * p_scatter);
    Flight::Scatter {
        t,
        weight: if weight.is_finite() {
            weight
        } else {
            Rgb::ZERO
        },
        density: d,
    }
}
