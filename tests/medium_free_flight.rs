//! The homogeneous free-flight sampler with one-sample MIS over RGB channels
//! (docs/references.md §4.6) is unbiased: per channel, E[escape weight] = e^{-σ_t L} and the
//! scattering weights integrate to the single-scattering albedo times the collision probability.

mod common;

use common::stats::{assert_rgb_agrees, estimate_rgb, Estimate};
use velour::medium::{
    multiple_scattering_albedo, single_scattering_albedo_from_multiple, Coefficients,
};
use velour::sampling::Rng;
use velour::spectrum::Rgb;
use velour::tracking::{channel_probabilities, sample_homogeneous, Flight};

/// Mean and standard error of a per-channel estimator, from the same seed each time.
fn estimate(n: usize, f: impl FnMut(&mut Rng) -> Rgb) -> [Estimate; 3] {
    estimate_rgb(n, &mut Rng::new(7, 3), f)
}

/// Every channel within 4.5 standard errors (plus 1e-6) of `expected`.
fn assert_z(estimates: &[Estimate; 3], expected: Rgb, what: &str) {
    assert_rgb_agrees(estimates, expected, 4.5, 1e-6, what);
}

#[test]
fn escape_weight_is_unbiased_transmittance_for_chromatic_media() {
    let coeff = Coefficients {
        sigma_a: Rgb::new(0.2, 1.0, 3.0),
        sigma_s: Rgb::new(2.0, 1.0, 0.5),
    };
    for beta in [Rgb::ONE, Rgb::new(1.0, 0.1, 0.01), Rgb::new(0.0, 0.0, 1.0)] {
        let l = 0.7f32;
        let mean = estimate(400_000, |rng| {
            match sample_homogeneous(
                coeff.sigma_t(),
                coeff.sigma_s,
                beta,
                l,
                rng.next_f32(),
                rng.next_f32(),
            ) {
                Flight::Escape { weight } => weight,
                Flight::Scatter { .. } => Rgb::ZERO,
            }
        });
        let expected = coeff.sigma_t().map(|s| (-s * l).exp());
        assert_z(&mean, expected, "escape");
    }
}

#[test]
fn scatter_weights_integrate_to_albedo_times_collision_probability() {
    // E[weight · 1{scatter}] = ∫_0^L σ_s e^{-σ_t t} dt = α (1 − e^{-σ_t L}).
    let coeff = Coefficients {
        sigma_a: Rgb::new(0.5, 0.1, 2.0),
        sigma_s: Rgb::new(1.5, 0.4, 6.0),
    };
    let l = 0.9f32;
    let beta = Rgb::new(0.3, 1.0, 0.6);
    let mean = estimate(400_000, |rng| {
        match sample_homogeneous(
            coeff.sigma_t(),
            coeff.sigma_s,
            beta,
            l,
            rng.next_f32(),
            rng.next_f32(),
        ) {
            Flight::Scatter { weight, t, .. } => {
                assert!(t >= 0.0 && t < l);
                weight
            }
            Flight::Escape { .. } => Rgb::ZERO,
        }
    });
    let st = coeff.sigma_t();
    let expected = Rgb([0, 1, 2].map(|c| coeff.sigma_s[c] / st[c] * (1.0 - (-st[c] * l).exp())));
    assert_z(&mean, expected, "scatter");
}

#[test]
fn zero_extinction_never_scatters_and_never_produces_nan() {
    let coeff = Coefficients {
        sigma_a: Rgb::ZERO,
        sigma_s: Rgb::ZERO,
    };
    for t_max in [0.0, 1.0, f32::INFINITY] {
        match sample_homogeneous(coeff.sigma_t(), coeff.sigma_s, Rgb::ONE, t_max, 0.5, 0.5) {
            Flight::Escape { weight } => assert_eq!(weight, Rgb::ONE),
            Flight::Scatter { .. } => panic!("scattered in vacuum"),
        }
    }
    let p = channel_probabilities(Rgb::ZERO, Rgb::ZERO);
    assert!(p.iter().all(|x| (*x - 1.0 / 3.0).abs() < 1e-6));
}

#[test]
fn van_de_hulst_inversion_round_trips() {
    for g in [-0.5f32, 0.0, 0.8] {
        for i in 0..=20 {
            let a = i as f32 / 20.0;
            let alpha = single_scattering_albedo_from_multiple(a, g);
            assert!((0.0..1.0).contains(&alpha));
            let back = multiple_scattering_albedo(alpha, g);
            // Exact up to f32 rounding, except at A = 1 where α is clamped to 1 − 1e-6.
            let tol = if a < 0.99 { 2e-4 } else { 1e-2 };
            assert!(
                (back - a).abs() < tol,
                "g {g}: A {a} -> alpha {alpha} -> A {back}"
            );
        }
    }
    // Monotone in A.
    let mut last = -1.0;
    for i in 0..=100 {
        let alpha = single_scattering_albedo_from_multiple(i as f32 / 100.0, 0.0);
        assert!(alpha >= last);
        last = alpha;
    }
    // Published sample values (docs/references.md §1.2: vdH and Chiang agree to ~0.002 for A ≤ 0.9).
    assert!((single_scattering_albedo_from_multiple(0.5, 0.0) - 0.9123).abs() < 5e-3);
    assert!((single_scattering_albedo_from_multiple(0.8, 0.0) - 0.9901).abs() < 3e-3);
}
