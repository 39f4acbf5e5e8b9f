//! Closed-form free flights through a homogeneous medium with spectrally varying extinction.
//!
//! The distance is sampled before the boundary is known ([`HomogeneousFlight::sample`]) and
//! resolved against it afterwards ([`HomogeneousFlight::resolve`]): the integrator can then look
//! for the boundary only up to the sampled distance, which in a dense medium is a short, cheap
//! ray. [`sample_homogeneous`] does both at once.

use super::{channel_probabilities, pick_channel, Flight};
use crate::math::{exp3, ln_f32};
use crate::spectrum::Rgb;

/// A free-flight distance sampled in a homogeneous medium, not yet compared with the
/// boundary.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HomogeneousFlight {
    /// Extinction (1/length).
    sigma_t: Rgb,
    /// Scattering (1/length).
    sigma_s: Rgb,
    /// Channel-selection probabilities.
    p: [f32; 3],
    /// The sampled distance (∞ when the chosen channel does not attenuate).
    pub t: f32,
}

impl HomogeneousFlight {
    /// Samples a distance with the channel chosen by throughput and one-sample MIS (balance
    /// heuristic) over channels (docs/references.md §4.6). `sigma_t` and `sigma_s` are per
    /// unit length; `u_channel` and `u_distance` are uniform in [0, 1).
    #[must_use]
    #[inline(always)]
    pub fn sample(sigma_t: Rgb, sigma_s: Rgb, beta: Rgb, u_channel: f32, u_distance: f32) -> Self {
        let alpha = sigma_s.safe_div(sigma_t);
        let p = channel_probabilities(beta, alpha);
        let channel = pick_channel(p, u_channel);
        let st = sigma_t[channel];
        let t = if st > 0.0 {
            -ln_f32(1.0 - u_distance) / st
        } else {
            f32::INFINITY
        };
        HomogeneousFlight {
            sigma_t,
            sigma_s,
            p,
            t,
        }
    }

    /// The flight's outcome when the medium ends at `t_max`: a scattering event at the sampled
    /// distance if it lies before `t_max`, else an escape with the MIS-weighted transmittance.
    #[must_use]
    pub fn resolve(&self, t_max: f32) -> Flight {
        let (sigma_t, p, t) = (self.sigma_t, self.p, self.t);
        if t < t_max {
            let tr = Rgb(exp3(sigma_t.0.map(|s| -s * t)));
            let pdf: f32 = (0..3).map(|k| p[k] * sigma_t[k] * tr[k]).sum();
            if !(pdf > 0.0) {
                return Flight::Escape { weight: Rgb::ZERO };
            }
            Flight::Scatter {
                t,
                weight: self.sigma_s * tr / pdf,
                density: 1.0,
            }
        } else {
            let e = exp3(sigma_t.0.map(|s| -s * t_max));
            let tr = Rgb([0, 1, 2].map(|k| if sigma_t[k] == 0.0 { 1.0 } else { e[k] }));
            let prob: f32 = (0..3).map(|k| p[k] * tr[k]).sum();
            if !(prob > 0.0) {
                return Flight::Escape { weight: Rgb::ZERO };
            }
            Flight::Escape { weight: tr / prob }
        }
    }
}

/// Samples a free flight through a homogeneous medium that ends at `t_max`
/// ([`HomogeneousFlight::sample`] then [`HomogeneousFlight::resolve`]).
#[must_use]
pub fn sample_homogeneous(
    sigma_t: Rgb,
    sigma_s: Rgb,
    beta: Rgb,
    t_max: f32,
    u_channel: f32,
    u_distance: f32,
) -> Flight {
    HomogeneousFlight::sample(sigma_t, sigma_s, beta, u_channel, u_distance).resolve(t_max)
}
