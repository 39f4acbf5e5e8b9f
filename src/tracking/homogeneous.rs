//! Closed-form free flights through a homogeneous medium with spectrally varying extinction.

use super::{channel_probabilities, pick_channel, Flight};
use crate::spectrum::Rgb;

/// Samples a free-flight distance through a homogeneous medium with spectrally varying σ_t,
/// choosing the channel by throughput with one-sample MIS (balance heuristic) over channels
/// (docs/references.md §4.6). `sigma_t` and `sigma_s` are per unit length; `u_channel` and `u_distance` are uniform in
/// [0, 1).
#[must_use]
pub fn sample_homogeneous(
    sigma_t: Rgb,
    sigma_s: Rgb,
    beta: Rgb,
    t_max: f32,
    u_channel: f32,
    u_distance: f32,
) -> Flight {
    let alpha = sigma_s.safe_div(sigma_t);
    let p = channel_probabilities(beta, alpha);
    let channel = pick_channel(p, u_channel);
    let st = sigma_t[channel];
    let t = if st > 0.0 {
        -(-u_distance).ln_1p() / st
    } else {
        f32::INFINITY
    };
    if t < t_max {
        let tr = sigma_t.map(|s| (-s * t).exp());
        let pdf: f32 = (0..3).map(|k| p[k] * sigma_t[k] * tr[k]).sum();
        if !(pdf > 0.0) {
            return Flight::Escape { weight: Rgb::ZERO };
        }
        Flight::Scatter {
            t,
            weight: sigma_s * tr / pdf,
            density: 1.0,
        }
    } else {
        let tr = sigma_t.map(|s| if s == 0.0 { 1.0 } else { (-s * t_max).exp() });
        let prob: f32 = (0..3).map(|k| p[k] * tr[k]).sum();
        if !(prob > 0.0) {
            return Flight::Escape { weight: Rgb::ZERO };
        }
        Flight::Escape { weight: tr / prob }
    }
}
