//! Every tracking estimator driven by majorant segments is unbiased against closed forms
//! (constant, piecewise-constant and linear-ramp densities), delta-tracking distances follow
//! the analytic CDF, and weighted tracking stays unbiased with a deliberately violated bound.

mod common;

use common::stats::{assert_rgb_agrees, estimate_rgb, Estimate};
use velour::majorant::MajorantSegment;
use velour::sampling::Rng;
use velour::spectrum::Rgb;
use velour::tracking::{
    decomposition_track, delta_track, transmittance, ControlVariate, DensityCoefficients, Flight,
    TrackingStats, TransmittanceMode,
};

const L: f32 = 2.0;

/// Linear ramp density a + b t on [0, L].
fn ramp(t: f32) -> f32 {
    0.2 + 0.9 * t
}
fn ramp_depth(t: f32) -> f64 {
    (0.2 * t as f64) + 0.45 * (t as f64) * (t as f64)
}

/// The ramp split into `n` segments with exact per-segment bounds (optionally scaled).
fn ramp_segments(n: usize, bound_scale: f32) -> Vec<MajorantSegment> {
    (0..n)
        .map(|i| {
            let t0 = L * i as f32 / n as f32;
            let t1 = L * (i + 1) as f32 / n as f32;
            MajorantSegment {
                t0,
                t1,
                min: ramp(t0),
                max: ramp(t1) * bound_scale,
                mean: 0.5 * (ramp(t0) + ramp(t1)),
                // Bounds scaled below the ramp's maximum are violated estimates.
                exact: bound_scale >= 1.0,
            }
        })
        .collect()
}

fn grey(s: f32) -> DensityCoefficients {
    DensityCoefficients::new(Rgb::splat(s), Rgb::splat(s * 0.7))
}

/// Per-channel mean and standard error of `n` estimates `f(rng)`, from the same seed each time.
fn mean_se(n: usize, f: impl FnMut(&mut Rng) -> Rgb) -> [Estimate; 3] {
    estimate_rgb(n, &mut Rng::new(11, 5), f)
}

/// Every channel within 4.5 standard errors (plus 1e-5) of `expect`.
fn check(estimates: &[Estimate; 3], expect: Rgb, what: &str) {
    assert_rgb_agrees(estimates, expect, 4.5, 1e-5, what);
}

fn expected_ramp_tr(coeff: &DensityCoefficients) -> Rgb {
    coeff
        .sigma_t
        .map(|s| (-(s as f64) * ramp_depth(L)).exp() as f32)
}

#[test]
fn transmittance_estimators_are_unbiased_on_a_linear_ramp() {
    let coeff = DensityCoefficients::new(Rgb::new(0.5, 1.0, 1.7), Rgb::new(0.4, 0.5, 1.0));
    let expect = expected_ramp_tr(&coeff);
    for segs in [1usize, 4, 16] {
        for mode in [
            TransmittanceMode::Ratio,
            TransmittanceMode::ResidualRatio(ControlVariate::Minorant),
            TransmittanceMode::ResidualRatio(ControlVariate::Mean),
            TransmittanceMode::ResidualRatio(ControlVariate::Novak),
        ] {
            let segments = ramp_segments(segs, 1.0);
            let m = mean_se(100_000, |rng| {
                let mut st = TrackingStats::default();
                let mut u = || rng.next_f32();
                transmittance(
                    segments.iter().copied(),
                    &coeff,
                    ramp,
                    mode,
                    &mut u,
                    &mut st,
                )
            });
            check(&m, expect, &format!("{mode:?} with {segs} segments"));
        }
    }
}

#[test]
fn residual_tracking_is_exact_and_lookup_free_on_constant_segments() {
    let coeff = grey(1.3);
    // Piecewise constant: 0.5 on [0,1), 2.0 on [1,2).
    let segments = [
        MajorantSegment {
            t0: 0.0,
            t1: 1.0,
            min: 0.5,
            max: 0.5,
            mean: 0.5,
            exact: true,
        },
        MajorantSegment {
            t0: 1.0,
            t1: 2.0,
            min: 2.0,
            max: 2.0,
            mean: 2.0,
            exact: true,
        },
    ];
    let mut rng = Rng::new(1, 1);
    let mut u = || rng.next_f32();
    let mut st = TrackingStats::default();
    let tr = transmittance(
        segments,
        &coeff,
        |_| panic!("no lookup expected"),
        TransmittanceMode::Ratio,
        &mut u,
        &mut st,
    );
    let expect = (-1.3f64 * 2.5).exp() as f32;
    assert!((tr[0] - expect).abs() < 1e-6, "{tr:?} vs {expect}");
    assert_eq!(st.lookups, 0);
}

#[test]
fn ratio_tracking_has_zero_variance_when_the_majorant_is_tight() {
    // A constant density inside loose bounds: residual tracking with the control equal to the
    // density has a zero residual, so every estimate is exactly e^{-σL}.
    let coeff = grey(0.8);
    let seg = [MajorantSegment {
        t0: 0.0,
        t1: 3.0,
        min: 0.6,
        max: 1.4,
        mean: 1.0,
        exact: true,
    }];
    let mut rng = Rng::new(2, 2);
    for _ in 0..100 {
        let mut u = || rng.next_f32();
        let mut st = TrackingStats::default();
        let tr = transmittance(
            seg,
            &coeff,
            |_| 1.0,
            TransmittanceMode::ResidualRatio(ControlVariate::Mean),
            &mut u,
            &mut st,
        );
        let expect = (-0.8f32 * 3.0).exp();
        assert!(
            (tr[0] - expect).abs() < 1e-5 * expect.max(1.0),
            "{} vs {expect}",
            tr[0]
        );
    }
}

#[test]
fn delta_tracking_escape_and_scatter_weights_are_unbiased() {
    let coeff = DensityCoefficients::new(Rgb::new(0.3, 1.0, 2.0), Rgb::new(0.3, 0.6, 1.9));
    let segments = ramp_segments(5, 1.0);
    let expect_tr = expected_ramp_tr(&coeff);
    for beta in [Rgb::ONE, Rgb::new(0.05, 1.0, 0.4)] {
        let m = mean_se(200_000, |rng| {
            let mut st = TrackingStats::default();
            let mut u = || rng.next_f32();
            match delta_track(
                segments.iter().copied(),
                &coeff,
                ramp,
                beta,
                &mut u,
                &mut st,
            ) {
                Flight::Escape { weight } => weight,
                Flight::Scatter { .. } => Rgb::ZERO,
            }
        });
        check(&m, expect_tr, "escape weight");
        // E[weight · 1{scatter}] = ∫ σ_s(t) T(t) dt = α (1 − T(L)) for constant albedo.
        let m = mean_se(200_000, |rng| {
            let mut st = TrackingStats::default();
            let mut u = || rng.next_f32();
            match delta_track(
                segments.iter().copied(),
                &coeff,
                ramp,
                beta,
                &mut u,
                &mut st,
            ) {
                Flight::Scatter { weight, .. } => weight,
                Flight::Escape { .. } => Rgb::ZERO,
            }
        });
        let alpha = coeff.sigma_s.safe_div(coeff.sigma_t);
        check(&m, alpha * (Rgb::ONE - expect_tr), "scatter weight");
    }
}

#[test]
fn weighted_tracking_stays_unbiased_with_a_violated_bound() {
    let coeff = grey(1.0);
    // Bounds at 60 % of the true maximum: violated over most of every segment.
    let segments = ramp_segments(3, 0.6);
    let expect = expected_ramp_tr(&coeff);
    // Delta tracking, and decomposition tracking: the last segments' estimated minimum lies
    // above their maximum, so a control at the minimum would leave the residual nothing to
    // sample.
    for (decompose, name) in [
        (false, "violated delta tracking"),
        (true, "violated decomposition tracking"),
    ] {
        let mut violations = 0;
        let m = mean_se(300_000, |rng| {
            let mut st = TrackingStats::default();
            let mut u = || rng.next_f32();
            let track = if decompose {
                decomposition_track
            } else {
                delta_track
            };
            let f = track(
                segments.iter().copied(),
                &coeff,
                ramp,
                Rgb::ONE,
                &mut u,
                &mut st,
            );
            violations += st.violations;
            match f {
                Flight::Escape { weight } => weight,
                Flight::Scatter { .. } => Rgb::ZERO,
            }
        });
        assert!(violations > 0, "the test must violate the bound");
        check(&m, expect, name);
    }
    let m = mean_se(300_000, |rng| {
        let mut st = TrackingStats::default();
        let mut u = || rng.next_f32();
        transmittance(
            segments.iter().copied(),
            &coeff,
            ramp,
            TransmittanceMode::Ratio,
            &mut u,
            &mut st,
        )
    });
    check(&m, expect, "violated ratio tracking");
}

#[test]
fn delta_tracking_distances_follow_the_analytic_cdf() {
    // Grey medium: the collision density is σ(t) e^{-τ(t)}; bin t and the escape event.
    let s = 0.9f32;
    let coeff = DensityCoefficients::new(Rgb::splat(s), Rgb::splat(s));
    let segments = ramp_segments(4, 1.0);
    let bins = 20usize;
    let n = 200_000usize;
    let mut counts = vec![0usize; bins + 1];
    let mut rng = Rng::new(5, 9);
    for _ in 0..n {
        let mut st = TrackingStats::default();
        let mut u = || rng.next_f32();
        match delta_track(
            segments.iter().copied(),
            &coeff,
            ramp,
            Rgb::ONE,
            &mut u,
            &mut st,
        ) {
            Flight::Scatter { t, .. } => {
                counts[((t / L * bins as f32) as usize).min(bins - 1)] += 1
            }
            Flight::Escape { .. } => counts[bins] += 1,
        }
    }
    let cdf = |t: f32| 1.0 - (-(s as f64) * ramp_depth(t)).exp();
    let chi2 = common::chi2::pearson_free_flight(&counts, L, cdf);
    // 20 degrees of freedom: P(χ² > 52.4) ≈ 1e-4.
    assert!(chi2 < 52.4, "chi2 = {chi2}, counts {counts:?}");
}

#[test]
fn combined_media_add_a_homogeneous_part_everywhere() {
    // σ_t(x) = base + d(x)·σ⁰ with zero-density gaps between segments filled by the caller.
    let mut coeff = DensityCoefficients::new(Rgb::new(0.5, 1.0, 1.5), Rgb::new(0.4, 0.8, 1.0));
    coeff.base_t = Rgb::new(0.7, 0.2, 0.4);
    coeff.base_s = Rgb::new(0.5, 0.1, 0.3);
    let mut segments = ramp_segments(3, 1.0);
    // A density-free stretch after the ramp: only the homogeneous part attenuates there.
    segments.push(MajorantSegment {
        t0: L,
        t1: L + 1.0,
        min: 0.0,
        max: 0.0,
        mean: 0.0,
        exact: true,
    });
    let expect = Rgb([0, 1, 2].map(|c| {
        (-(coeff.sigma_t[c] as f64) * ramp_depth(L) - coeff.base_t[c] as f64 * (L as f64 + 1.0))
            .exp() as f32
    }));
    let density = |t: f32| if t < L { ramp(t) } else { 0.0 };
    for mode in [
        TransmittanceMode::Ratio,
        TransmittanceMode::ResidualRatio(ControlVariate::Novak),
    ] {
        let m = mean_se(100_000, |rng| {
            let mut st = TrackingStats::default();
            let mut u = || rng.next_f32();
            transmittance(
                segments.iter().copied(),
                &coeff,
                density,
                mode,
                &mut u,
                &mut st,
            )
        });
        check(&m, expect, &format!("combined {mode:?}"));
    }
    let m = mean_se(200_000, |rng| {
        let mut st = TrackingStats::default();
        let mut u = || rng.next_f32();
        match delta_track(
            segments.iter().copied(),
            &coeff,
            density,
            Rgb::ONE,
            &mut u,
            &mut st,
        ) {
            Flight::Escape { weight } => weight,
            Flight::Scatter { .. } => Rgb::ZERO,
        }
    });
    check(&m, expect, "combined delta tracking escape");
}
