//! The biased fixed-step ray-marching free flight.

use super::channels::hero_probabilities;
use super::{pick_channel, DensityCoefficients, Flight, TrackingStats};
use crate::majorant::MajorantSegment;
use crate::spectrum::Rgb;

/// Fixed-step ray-marching free flight (the biased baseline of the notes §2.2.2): accumulates
/// the hero channel's optical depth in steps of `step` until it exceeds an exponential sample,
/// then weights with one-sample MIS over channels as for homogeneous media.
pub fn ray_march_free_flight<S, D, U>(
    segments: S,
    coeff: &DensityCoefficients,
    mut density: D,
    step: f32,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    U: FnMut() -> f32,
{
    let probs = hero_probabilities(beta, coeff);
    let hero = pick_channel(probs, u());
    let target = -(1.0 - u()).ln();
    let mut tau = Rgb::ZERO; // optical depth per channel
    let offset = u();
    for seg in segments {
        stats.segments += 1;
        let len = seg.length();
        if len <= 0.0 || coeff.is_void(&seg) {
            continue;
        }
        let n = (len / step.max(1e-12)).ceil().clamp(1.0, 1e7) as u32;
        let dt = len / n as f32;
        for i in 0..n {
            let d = if seg.is_homogeneous() {
                seg.max
            } else {
                stats.lookups += 1;
                density(seg.t0 + (i as f32 + offset) * dt)
            };
            // Optical depth per channel so far is st·depth + base·length.
            let sigma = coeff.sigma_t_at(d);
            let next = tau + sigma * dt;
            if next[hero] >= target && sigma[hero] > 0.0 {
                // Collide inside this step (constant coefficients within the step).
                let frac = ((target - tau[hero]) / sigma[hero]).clamp(0.0, dt);
                let t = seg.t0 + i as f32 * dt + frac;
                let tr = (tau + sigma * frac).map(|x| (-x).exp());
                let pdf: f32 = (0..3).map(|k| probs[k] * sigma[k] * tr[k]).sum();
                stats.real_collisions += 1;
                return Flight::Scatter {
                    t,
                    weight: if pdf > 0.0 {
                        coeff.sigma_s_at(d) * tr / pdf
                    } else {
                        Rgb::ZERO
                    },
                    density: d,
                };
            }
            tau = next;
        }
    }
    let tr = tau.map(|x| (-x).exp());
    let prob: f32 = (0..3).map(|k| probs[k] * tr[k]).sum();
    Flight::Escape {
        weight: if prob > 0.0 { tr / prob } else { Rgb::ZERO },
    }
}
