//! Decomposition tracking (Kutz et al. 2017): its distances follow the analytic collision
//! density, its escape and scattering weights are unbiased (chromatic, combined media with a
//! differently coloured constant part, violated minorants), and its control collisions save
//! lookups in proportion to the minorant's share of the majorant.

mod common;

use common::stats::{assert_rgb_agrees, estimate_rgb, Estimate};
use velour::majorant::{Bounds, MajorantSegment};
use velour::sampling::Rng;
use velour::spectrum::Rgb;
use velour::tracking::{
    decomposition_track, delta_track, DensityCoefficients, Flight, TrackingStats,
};

const L: f32 = 2.0;

/// A ramp density a + b t on [0, L] (a dense medium whose minorants are large).
fn ramp(t: f32) -> f32 {
    1.0 + 0.5 * t
}
fn ramp_depth(t: f32) -> f64 {
    t as f64 + 0.25 * (t as f64) * (t as f64)
}

/// The ramp in `n` segments with proven bounds, or (`violated`) with a minorant the density
/// stays below over the first 80 % of each segment, so that the residual turns negative there.
fn segments(n: usize, violated: bool) -> Vec<MajorantSegment> {
    (0..n)
        .map(|i| {
            let t0 = L * i as f32 / n as f32;
            let t1 = L * (i + 1) as f32 / n as f32;
            let min = if violated {
                ramp(t0 + 0.8 * (t1 - t0))
            } else {
                ramp(t0)
            };
            let b = Bounds {
                min,
                max: ramp(t1),
                mean: 0.5 * (ramp(t0) + ramp(t1)),
            };
            MajorantSegment::new(t0, t1, b, !violated)
        })
        .collect()
}

fn mean_se(n: usize, f: impl FnMut(&mut Rng) -> Rgb) -> [Estimate; 3] {
    estimate_rgb(n, &mut Rng::new(17, 3), f)
}

fn flight(
    segs: &[MajorantSegment],
    coeff: &DensityCoefficients,
    beta: Rgb,
    rng: &mut Rng,
) -> Flight {
    let mut st = TrackingStats::default();
    let mut u = || rng.next_f32();
    decomposition_track(segs.iter().copied(), coeff, ramp, beta, &mut u, &mut st)
}

/// ∫₀^L σ_s(t) T(t) dt per channel, and T(L), by the midpoint rule.
fn scatter_integral(coeff: &DensityCoefficients) -> (Rgb, Rgb) {
    let n = 20_000;
    let dt = f64::from(L) / n as f64;
    let mut sum = [0.0f64; 3];
    for i in 0..n {
        let t = (i as f64 + 0.5) * dt;
        let d = ramp(t as f32) as f64;
        for (k, sum_k) in sum.iter_mut().enumerate() {
            let tau =
                f64::from(coeff.base_t[k]) * t + f64::from(coeff.sigma_t[k]) * ramp_depth(t as f32);
            let ss = f64::from(coeff.base_s[k]) + f64::from(coeff.sigma_s[k]) * d;
            *sum_k += ss * (-tau).exp() * dt;
        }
    }
    let tr = Rgb([0, 1, 2].map(|k| {
        let tau =
            f64::from(coeff.base_t[k]) * f64::from(L) + f64::from(coeff.sigma_t[k]) * ramp_depth(L);
        (-tau).exp() as f32
    }));
    (Rgb(sum.map(|v| v as f32)), tr)
}

#[test]
fn distances_follow_the_analytic_collision_density() {
    let s = 0.8f32;
    let coeff = DensityCoefficients::new(Rgb::splat(s), Rgb::splat(s));
    let segs = segments(4, false);
    let bins = 20usize;
    let n = 200_000usize;
    let mut counts = vec![0usize; bins + 1];
    let mut rng = Rng::new(5, 9);
    for _ in 0..n {
        match flight(&segs, &coeff, Rgb::ONE, &mut rng) {
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
fn weights_are_unbiased_for_chromatic_and_combined_media_and_violated_minorants() {
    let chromatic = DensityCoefficients::new(Rgb::new(0.3, 1.0, 2.0), Rgb::new(0.3, 0.6, 1.9));
    // A constant part of another colour: control collisions carry the control's albedo.
    let combined = DensityCoefficients {
        base_t: Rgb::new(0.4, 0.2, 0.1),
        base_s: Rgb::new(0.1, 0.2, 0.05),
        ..chromatic
    };
    for (coeff, violated, what) in [
        (chromatic, false, "chromatic"),
        (combined, false, "combined"),
        (chromatic, true, "violated minorant"),
    ] {
        let segs = segments(5, violated);
        let (scatter, tr) = scatter_integral(&coeff);
        for beta in [Rgb::ONE, Rgb::new(0.05, 1.0, 0.4)] {
            let m = mean_se(200_000, |rng| match flight(&segs, &coeff, beta, rng) {
                Flight::Escape { weight } => weight,
                Flight::Scatter { .. } => Rgb::ZERO,
            });
            assert_rgb_agrees(&m, tr, 4.5, 1e-5, &format!("{what}: escape weight"));
            let m = mean_se(200_000, |rng| match flight(&segs, &coeff, beta, rng) {
                Flight::Scatter { weight, .. } => weight,
                Flight::Escape { .. } => Rgb::ZERO,
            });
            assert_rgb_agrees(&m, scatter, 4.5, 1e-5, &format!("{what}: scatter weight"));
        }
    }
}

#[test]
fn control_collisions_save_lookups_in_proportion_to_the_minorant() {
    let coeff = DensityCoefficients::new(Rgb::splat(1.0), Rgb::splat(0.8));
    let segs = segments(8, false);
    let n = 100_000;
    let (mut delta, mut decomposition) = (TrackingStats::default(), TrackingStats::default());
    let mut rng = Rng::new(2, 2);
    for _ in 0..n {
        let mut u = || rng.next_f32();
        let _ = delta_track(
            segs.iter().copied(),
            &coeff,
            ramp,
            Rgb::ONE,
            &mut u,
            &mut delta,
        );
        let mut u = || rng.next_f32();
        let _ = decomposition_track(
            segs.iter().copied(),
            &coeff,
            ramp,
            Rgb::ONE,
            &mut u,
            &mut decomposition,
        );
    }
    // Per segment the residual majorant is max − min = 0.5·L/8 against a majorant of about
    // 1.5: about 6 % of the tentative collisions need a lookup.
    let ratio = decomposition.lookups as f64 / delta.lookups as f64;
    assert!(ratio < 0.15, "decomposition/delta lookups = {ratio}");
    assert!(decomposition.lookups > 0, "the residual is looked up");
}
