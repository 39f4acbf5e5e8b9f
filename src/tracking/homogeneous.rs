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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flights_have_the_bits_of_the_c_librarys_exp_and_log() {
        // The former arithmetic, with the C library's `logf` and `expf`.
        let reference = |f: &HomogeneousFlight, u_distance: f32, t_max: f32| {
            let st = f.sigma_t[pick_channel(f.p, 0.3)];
            let t = -(1.0 - u_distance).ln() / st;
            let (sigma_t, p) = (f.sigma_t, f.p);
            if t < t_max {
                let tr = sigma_t.map(|s| (-s * t).exp());
                let pdf: f32 = (0..3).map(|k| p[k] * sigma_t[k] * tr[k]).sum();
                (
                    t,
                    if pdf > 0.0 {
                        f.sigma_s * tr / pdf
                    } else {
                        Rgb::ZERO
                    },
                )
            } else {
                let tr = sigma_t.map(|s| if s == 0.0 { 1.0 } else { (-s * t_max).exp() });
                let prob: f32 = (0..3).map(|k| p[k] * tr[k]).sum();
                (t, if prob > 0.0 { tr / prob } else { Rgb::ZERO })
            }
        };
        let media = [
            (Rgb::new(16.0, 24.0, 36.0), Rgb::new(15.84, 22.8, 30.6)),
            (Rgb::new(0.5, 0.0, 3.0), Rgb::new(0.4, 0.0, 2.0)),
            (Rgb::new(1e-3, 80.0, 2.0), Rgb::new(1e-3, 40.0, 1.0)),
        ];
        let mut n = 0;
        for (sigma_t, sigma_s) in media {
            for i in 0..20_000u32 {
                let u = (i as f32 + 0.5) / 20_000.0;
                let beta = Rgb::new(1.0, 0.5 + u, 0.25);
                let f = HomogeneousFlight::sample(sigma_t, sigma_s, beta, 0.3, u);
                for t_max in [0.01f32, 0.2, 1.5, 40.0, f32::INFINITY] {
                    let (t, weight) = reference(&f, u, t_max);
                    assert_eq!(f.t.to_bits(), t.to_bits());
                    let got = match f.resolve(t_max) {
                        Flight::Scatter { weight, .. } | Flight::Escape { weight } => weight,
                    };
                    assert_eq!(got.0.map(f32::to_bits), weight.0.map(f32::to_bits));
                    n += 1;
                }
            }
        }
        assert_eq!(n, 300_000);
    }
}
