//! Unbiased ray marching and the jackknife transmittance (docs/references.md §11.1–11.2):
//! both are exact for a constant density; unbiased ray marching agrees with e^(−τ) on a ramp and
//! a step; the jackknife is biased but less so than plain ray marching at equal lookups, and
//! costs exactly two combs per segment.

mod common;

use common::stats::{estimate, Estimate};
use velour::majorant::{Bounds, MajorantSegment};
use velour::sampling::Rng;
use velour::spectrum::Rgb;
use velour::tracking::{
    comb_teeth, transmittance, DensityCoefficients, TrackingStats, TransmittanceMode,
};

fn grey(s: f32) -> DensityCoefficients {
    DensityCoefficients::new(Rgb::splat(s), Rgb::splat(s))
}

/// One proven segment over [0, l] with bounds `[min, max]` and coarse mean `mean`.
fn segment(l: f32, min: f32, max: f32, mean: f32) -> MajorantSegment {
    MajorantSegment::new(0.0, l, Bounds { min, max, mean }, true)
}

/// Mean and standard error of `n` transmittance estimates (channel 0).
fn run(
    n: usize,
    seg: MajorantSegment,
    coeff: &DensityCoefficients,
    density: impl Fn(f32) -> f32 + Copy,
    mode: TransmittanceMode,
    stats: &mut TrackingStats,
) -> Estimate {
    estimate(n, &mut Rng::new(9, 1), |rng| {
        let mut u = || rng.next_f32();
        f64::from(transmittance([seg], coeff, density, mode, &mut u, stats)[0])
    })
}

#[test]
fn both_are_exact_for_a_constant_density() {
    let coeff = grey(1.5);
    // min < max so that the segment is not taken in closed form.
    let seg = segment(1.2, 0.5, 2.0, 1.0);
    let exact = (-1.5f64 * 1.2).exp();
    for mode in [
        TransmittanceMode::UnbiasedRayMarch,
        TransmittanceMode::Jackknife,
    ] {
        let mut rng = Rng::new(1, 1);
        for _ in 0..2000 {
            let mut u = || rng.next_f32();
            let mut st = TrackingStats::default();
            let t = transmittance([seg], &coeff, |_| 1.0, mode, &mut u, &mut st)[0];
            assert!(
                (f64::from(t) - exact).abs() < 1e-5,
                "{mode:?}: {t} vs {exact}"
            );
        }
    }
}

/// A named case: the segment, the exact transmittance over it and the density along it.
type MarchCase<'a> = (&'a str, MajorantSegment, f64, &'a dyn Fn(f32) -> f32);

#[test]
fn unbiased_ray_marching_agrees_with_the_exact_transmittance() {
    let coeff = grey(1.0);
    // A ramp σ = 0.5 + 4t on [0, 1] (τ = 2.5) and a step (σ = 8 on the first tenth, 0.2 after).
    let ramp = |t: f32| 0.5 + 4.0 * t;
    let step = |t: f32| if t < 0.1 { 8.0 } else { 0.2 };
    let cases: [MarchCase; 2] = [
        ("ramp", segment(1.0, 0.5, 4.5, 2.5), (-2.5f64).exp(), &ramp),
        (
            "step",
            segment(1.0, 0.2, 8.0, 0.98),
            (-(0.8 + 0.18f64)).exp(),
            &step,
        ),
    ];
    for (what, seg, exact, density) in cases {
        let mut stats = TrackingStats::default();
        let e = run(
            400_000,
            seg,
            &coeff,
            density,
            TransmittanceMode::UnbiasedRayMarch,
            &mut stats,
        );
        e.assert_agrees(exact, 4.0, 0.0, &format!("URM on the {what}"));
        // Expected lookups per call: about M (1 + E[N]), E[N] = 0.31945.
        let m = f64::from(comb_teeth(seg.mean * seg.length()));
        let per_call = stats.transmittance_lookups as f64 / 400_000.0;
        assert!(
            (per_call - m * 1.31945).abs() < 0.05 * m,
            "{what}: {per_call} lookups per call, expected about {}",
            m * 1.31945
        );
    }
}

#[test]
fn the_jackknife_is_less_biased_than_plain_ray_marching_and_costs_two_combs() {
    let coeff = grey(1.0);
    let step = |t: f32| if t < 0.1 { 8.0 } else { 0.2 };
    let seg = segment(1.0, 0.2, 8.0, 0.98);
    let exact = (-(0.8 + 0.18f64)).exp();
    let mut st = TrackingStats::default();
    let jack = run(
        200_000,
        seg,
        &coeff,
        step,
        TransmittanceMode::Jackknife,
        &mut st,
    );
    let teeth = u64::from(comb_teeth(seg.mean * seg.length()));
    assert_eq!(
        st.transmittance_lookups,
        200_000 * 2 * teeth,
        "two combs per call"
    );
    // Plain ray marching with the same number of lookups: step = length / (2 M).
    let mut st = TrackingStats::default();
    let plain = run(
        200_000,
        seg,
        &coeff,
        step,
        TransmittanceMode::RayMarch {
            step: 1.0 / (2 * teeth) as f32,
        },
        &mut st,
    );
    let (bias_jack, bias_plain) = (jack.mean - exact, plain.mean - exact);
    assert!(
        bias_plain > 5.0 * plain.standard_error,
        "plain ray marching should be visibly biased: {bias_plain}"
    );
    assert!(
        bias_jack.abs() < bias_plain.abs(),
        "jackknife bias {bias_jack} vs plain ray marching {bias_plain}"
    );
}
