//! The split free flight for thin media (docs/references.md §11.4): its pass weights estimate
//! the transmittance and its scattering weights the in-scattering integral without bias (on a
//! chromatic ramp, with ratio and residual ratio transmittance), and in a thin medium it
//! estimates the in-scattered term with far less variance than delta tracking, which reaches
//! it only through the few flights that happen to collide.

mod common;

use common::stats::{assert_rgb_agrees, estimate_rgb, Estimate};
use velour::majorant::{Bounds, MajorantSegment};
use velour::sampling::Rng;
use velour::spectrum::Rgb;
use velour::tracking::{
    delta_track, split_flight, ControlVariate, DensityCoefficients, Flight, TrackingStats,
    TransmittanceMode,
};

const L: f32 = 2.0;

fn ramp(t: f32) -> f32 {
    0.2 + 0.3 * t
}
fn ramp_depth(t: f64) -> f64 {
    0.2 * t + 0.15 * t * t
}

/// The ramp over [a, b] in segments of length L/4 with proven bounds.
fn segments(a: f32, b: f32) -> Vec<MajorantSegment> {
    let n = 4;
    (0..n)
        .filter_map(|i| {
            let t0 = (L * i as f32 / n as f32).max(a);
            let t1 = (L * (i + 1) as f32 / n as f32).min(b);
            (t1 > t0).then(|| {
                MajorantSegment::new(
                    t0,
                    t1,
                    Bounds {
                        min: ramp(t0),
                        max: ramp(t1),
                        mean: 0.5 * (ramp(t0) + ramp(t1)),
                    },
                    true,
                )
            })
        })
        .collect()
}

fn flight(coeff: &DensityCoefficients, mode: TransmittanceMode, rng: &mut Rng) -> Flight {
    let mut st = TrackingStats::default();
    let mut u = || rng.next_f32();
    split_flight(segments, coeff, ramp, mode, L, &mut u, &mut st)
}

fn mean_se(n: usize, f: impl FnMut(&mut Rng) -> Rgb) -> [Estimate; 3] {
    estimate_rgb(n, &mut Rng::new(23, 1), f)
}

/// (∫₀^L σ_s T dt, ∫₀^L t σ_s T dt, T(L)) per channel, by the midpoint rule.
fn integrals(coeff: &DensityCoefficients) -> (Rgb, Rgb, Rgb) {
    let n = 20_000;
    let dt = f64::from(L) / n as f64;
    let (mut a, mut b) = ([0.0f64; 3], [0.0f64; 3]);
    for i in 0..n {
        let t = (i as f64 + 0.5) * dt;
        for k in 0..3 {
            let tr = (-f64::from(coeff.sigma_t[k]) * ramp_depth(t)).exp();
            let ss = f64::from(coeff.sigma_s[k]) * f64::from(ramp(t as f32));
            a[k] += ss * tr * dt;
            b[k] += t * ss * tr * dt;
        }
    }
    let tr =
        Rgb([0, 1, 2]
            .map(|k| (-f64::from(coeff.sigma_t[k]) * ramp_depth(f64::from(L))).exp() as f32));
    (Rgb(a.map(|v| v as f32)), Rgb(b.map(|v| v as f32)), tr)
}

#[test]
fn pass_and_scatter_weights_are_unbiased() {
    let coeff = DensityCoefficients::new(Rgb::new(0.3, 1.0, 2.0), Rgb::new(0.25, 0.6, 1.9));
    let (scatter, moment, tr) = integrals(&coeff);
    for mode in [
        TransmittanceMode::Ratio,
        TransmittanceMode::ResidualRatio(ControlVariate::Novak),
    ] {
        let what = format!("{mode:?}");
        let m = mean_se(300_000, |rng| match flight(&coeff, mode, rng) {
            Flight::Escape { weight } => weight,
            Flight::Scatter { .. } => Rgb::ZERO,
        });
        assert_rgb_agrees(&m, tr, 4.5, 1e-5, &format!("{what}: pass weight"));
        let m = mean_se(300_000, |rng| match flight(&coeff, mode, rng) {
            Flight::Scatter { weight, .. } => weight,
            Flight::Escape { .. } => Rgb::ZERO,
        });
        assert_rgb_agrees(&m, scatter, 4.5, 1e-5, &format!("{what}: scatter weight"));
        // The distances: E[t · weight] over scattering flights.
        let m = mean_se(300_000, |rng| match flight(&coeff, mode, rng) {
            Flight::Scatter { weight, t, .. } => weight * t,
            Flight::Escape { .. } => Rgb::ZERO,
        });
        assert_rgb_agrees(&m, moment, 4.5, 1e-5, &format!("{what}: first moment"));
    }
}

#[test]
fn a_thin_medium_scatters_with_far_less_variance_than_delta_tracking() {
    // T ≈ 0.98 on the grey ramp scaled down: delta tracking collides in 2 % of the flights,
    // the split flight scatters in SPLIT_MIN_SCATTER = 10 % of them (its transmitted term pays
    // for it: T²P/(1 − P) against delta tracking's T(1 − T)).
    let coeff = DensityCoefficients::new(Rgb::splat(0.02), Rgb::splat(0.02));
    let mode = TransmittanceMode::ResidualRatio(ControlVariate::Novak);
    let split = mean_se(100_000, |rng| match flight(&coeff, mode, rng) {
        Flight::Scatter { weight, .. } => weight,
        Flight::Escape { .. } => Rgb::ZERO,
    });
    let delta = mean_se(100_000, |rng| {
        let mut st = TrackingStats::default();
        let mut u = || rng.next_f32();
        match delta_track(segments(0.0, L), &coeff, ramp, Rgb::ONE, &mut u, &mut st) {
            Flight::Scatter { weight, .. } => weight,
            Flight::Escape { .. } => Rgb::ZERO,
        }
    });
    let (_, _, tr) = integrals(&coeff);
    assert!(
        tr[0] > 0.975,
        "the test medium should be thin: T = {}",
        tr[0]
    );
    assert!(
        split[0].standard_error * 2.0 < delta[0].standard_error,
        "split {} vs delta {}",
        split[0].standard_error,
        delta[0].standard_error
    );
}
