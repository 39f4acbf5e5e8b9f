//! Henyey–Greenstein phase functions: chi-square tests of sampling, normalisation, mean
//! cosine, consistency of pdf/value, extreme inputs and parameter validation.

mod common;

use common::sphere::{assert_chi2, chi2_sphere, integrate_sphere, SphereBins};
use common::stats::{estimate, z_score};
use velour::math::{Vec2, Vec3};
use velour::phase::{henyey_greenstein_mu, PhaseError, PhaseFunction};
use velour::sampling::Rng;

fn wo_dir() -> Vec3 {
    Vec3::new(0.3, -0.5, 0.8).normalize()
}

/// Bins concentrated on the lobe's peak (forward = -wo for g > 0, backward = wo for g < 0).
fn bins_for(g: f32, wo: Vec3) -> SphereBins {
    let axis = if g >= 0.0 { -wo } else { wo };
    let power = if g.abs() > 0.9 { 3.0 } else { 1.0 };
    SphereBins::around(axis, 40, 24, power)
}

#[test]
fn hg_chi_square_all_g() {
    let wo = wo_dir();
    for (k, &g) in [-0.99f32, -0.5, 0.0, 0.5, 0.99].iter().enumerate() {
        let ph = PhaseFunction::henyey_greenstein(g).unwrap();
        let bins = bins_for(g, wo);
        let r = chi2_sphere(
            &bins,
            2,
            400_000,
            100 + k as u64,
            |rng| Some(ph.sample(wo, rng.next_2d()).wi),
            &|wi| ph.pdf(wo, wi) as f64,
        );
        assert_chi2(&format!("HG g={g}"), &r);
        assert!(
            (r.integral - 1.0).abs() < 2e-3,
            "HG g={g}: ∫p = {}",
            r.integral
        );
    }
}

#[test]
fn double_hg_chi_square() {
    let wo = Vec3::new(0.0, 0.0, 1.0);
    for (k, &(g1, g2, w)) in [
        (0.8f32, -0.4f32, 0.7f32),
        (0.99, -0.5, 0.5),
        (0.3, 0.9, 0.2),
    ]
    .iter()
    .enumerate()
    {
        let ph = PhaseFunction::double_henyey_greenstein(g1, g2, w).unwrap();
        let bins = SphereBins::around(
            -wo,
            40,
            16,
            if g1.abs().max(g2.abs()) > 0.9 {
                2.0
            } else {
                1.0
            },
        );
        let r = chi2_sphere(
            &bins,
            2,
            400_000,
            200 + k as u64,
            |rng| Some(ph.sample(wo, rng.next_2d()).wi),
            &|wi| ph.pdf(wo, wi) as f64,
        );
        assert_chi2(&format!("double HG ({g1},{g2},{w})"), &r);
        assert!(
            (r.integral - 1.0).abs() < 2e-3,
            "double HG: ∫p = {}",
            r.integral
        );
    }
}

#[test]
fn chi_square_harness_rejects_a_wrong_pdf() {
    // The harness must be able to fail: samples of HG(0.5) against the pdf of HG(0.45).
    let wo = wo_dir();
    let ph = PhaseFunction::henyey_greenstein(0.5).unwrap();
    let wrong = PhaseFunction::henyey_greenstein(0.45).unwrap();
    let r = chi2_sphere(
        &bins_for(0.5, wo),
        2,
        400_000,
        7,
        |rng| Some(ph.sample(wo, rng.next_2d()).wi),
        &|wi| wrong.pdf(wo, wi) as f64,
    );
    assert!(r.p_value < 1e-6, "wrong pdf not detected: {r:?}");
}

#[test]
fn pdf_integrates_to_one() {
    let wo = wo_dir();
    for &g in &[-0.99f32, -0.9, -0.3, 0.0, 1e-6, 0.5, 0.95, 0.99] {
        let ph = PhaseFunction::henyey_greenstein(g).unwrap();
        let i = integrate_sphere(&bins_for(g, wo), 4, &|wi| ph.pdf(wo, wi) as f64);
        assert!((i - 1.0).abs() < 1e-3, "g={g}: ∫p = {i}");
    }
    let ph = PhaseFunction::double_henyey_greenstein(0.9, -0.6, 0.35).unwrap();
    let i = integrate_sphere(&SphereBins::around(-wo, 60, 16, 2.0), 4, &|wi| {
        ph.pdf(wo, wi) as f64
    });
    assert!((i - 1.0).abs() < 1e-3, "double HG: ∫p = {i}");
}

#[test]
fn mean_cosine_matches_g_z_test() {
    // E[μ] with μ = (-wo)·wi (propagation cosine), z-test with the sample variance.
    let wo = wo_dir();
    let n = 200_000;
    let cases: [(PhaseFunction, f32); 8] = [
        (PhaseFunction::henyey_greenstein(-0.99).unwrap(), -0.99),
        (PhaseFunction::henyey_greenstein(-0.5).unwrap(), -0.5),
        (PhaseFunction::henyey_greenstein(0.0).unwrap(), 0.0),
        (PhaseFunction::henyey_greenstein(1e-6).unwrap(), 1e-6),
        (PhaseFunction::henyey_greenstein(0.5).unwrap(), 0.5),
        (PhaseFunction::henyey_greenstein(0.99).unwrap(), 0.99),
        (
            PhaseFunction::double_henyey_greenstein(0.8, -0.4, 0.7).unwrap(),
            0.7 * 0.8 - 0.3 * 0.4,
        ),
        (
            PhaseFunction::double_henyey_greenstein(0.99, -0.99, 0.5).unwrap(),
            0.0,
        ),
    ];
    for (k, (ph, g)) in cases.iter().enumerate() {
        assert!(
            (ph.mean_cosine() - g).abs() < 1e-6,
            "mean_cosine {} vs {g}",
            ph.mean_cosine()
        );
        let mu = estimate(n, &mut Rng::new(300 + k as u64, 1), |rng| {
            (-wo).dot(ph.sample(wo, rng.next_2d()).wi) as f64
        });
        let mean = mu.mean;
        // (A floor on the variance keeps z finite should every sample coincide.)
        let z = z_score(
            mean,
            *g as f64,
            mu.standard_error.max((1e-12 / n as f64).sqrt()),
        );
        assert!(z.abs() < 4.5, "case {k}: E[mu] = {mean}, g = {g}, z = {z}");
    }
}

#[test]
fn sample_value_and_pdf_agree_with_eval() {
    let mut rng = Rng::new(11, 2);
    for &g in &[-0.99f32, -0.5, 0.0, 0.5, 0.99] {
        let ph = PhaseFunction::henyey_greenstein(g).unwrap();
        for _ in 0..2000 {
            let wo = velour::sampling::sample_uniform_sphere(rng.next_2d());
            let s = ph.sample(wo, rng.next_2d());
            assert!((s.wi.length() - 1.0).abs() < 1e-5);
            let e = ph.eval(wo, s.wi);
            assert_eq!(s.value, s.pdf);
            assert!(
                (s.pdf - e).abs() <= 1e-4 * e.max(1.0),
                "g={g}: pdf {} eval {e}",
                s.pdf
            );
            assert!((ph.pdf(wo, s.wi) - e).abs() == 0.0);
        }
    }
}

#[test]
fn sampled_cosine_is_accurate_near_the_peak() {
    // Compare 1 - μ of the stable sampler with the f64 textbook inversion
    // (docs/references.md §2.3).
    for &g in &[0.99f32, -0.99, 0.5, -0.5, 0.0] {
        let ph = PhaseFunction::henyey_greenstein(g).unwrap();
        let wo = -Vec3::Z; // propagation along +z: μ = wi.z
        for k in 0..200 {
            let xi = (k as f32 + 0.5) / 200.0;
            let wi = ph.sample(wo, Vec2::new(xi, 0.25)).wi;
            let (g64, x) = (g as f64, xi as f64);
            let mu_ref = if g64 == 0.0 {
                2.0 * x - 1.0
            } else {
                let t = (1.0 - g64 * g64) / (1.0 - g64 + 2.0 * g64 * x);
                (1.0 + g64 * g64 - t * t) / (2.0 * g64)
            };
            let mu = wi.z as f64;
            let tol = 2e-6 * (1.0 - mu_ref).min(1.0 + mu_ref).max(1e-3) + 1e-6;
            assert!(
                (mu - mu_ref).abs() < tol.max(3e-6),
                "g={g} xi={xi}: mu {mu} vs {mu_ref}"
            );
        }
    }
}

#[test]
fn hg_oracle_values() {
    // p(μ) = (1 − g²) / (4π (1 + g² − 2gμ)^{3/2}).
    for &(g, mu) in &[
        (0.5f32, 1.0f32),
        (0.5, -1.0),
        (0.5, 0.3),
        (-0.7, 0.2),
        (0.0, 0.9),
    ] {
        let (g64, mu64) = (g as f64, mu as f64);
        let exact = (1.0 - g64 * g64)
            / (4.0 * std::f64::consts::PI * (1.0 + g64 * g64 - 2.0 * g64 * mu64).powf(1.5));
        let v = henyey_greenstein_mu(g, mu) as f64;
        assert!(
            (v - exact).abs() < 1e-5 * exact,
            "g={g} mu={mu}: {v} vs {exact}"
        );
        // Same through vectors: wo = -z (propagation +z), wi at cosine mu from +z.
        let ph = PhaseFunction::henyey_greenstein(g).unwrap();
        let wi = Vec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
        let e = ph.eval(-Vec3::Z, wi) as f64;
        assert!(
            (e - exact).abs() < 1e-4 * exact,
            "vector form g={g} mu={mu}: {e} vs {exact}"
        );
    }
    // Forward scattering means wi ≈ -wo.
    let ph = PhaseFunction::henyey_greenstein(0.9).unwrap();
    let wo = wo_dir();
    assert!(ph.eval(wo, -wo) > 100.0 * ph.eval(wo, wo));
}

#[test]
fn extreme_inputs_are_finite() {
    let eps = 1.0 - f32::EPSILON / 2.0;
    let gs = [
        -1.0f32,
        -0.99,
        -(1.0 - 2f32.powi(-20)),
        0.0,
        1e-7,
        1.0 - 2f32.powi(-20),
        0.99,
        1.0,
    ];
    let wos = [
        Vec3::Z,
        -Vec3::Z,
        Vec3::X,
        Vec3::new(0.0, 1e-20, 1.0).normalize(),
        wo_dir(),
    ];
    let us = [0.0f32, eps, 0.5, 1e-7];
    for &g in &gs {
        let phs = [
            PhaseFunction::henyey_greenstein(g).unwrap(),
            PhaseFunction::double_henyey_greenstein(g, -g, 0.5).unwrap(),
            PhaseFunction::double_henyey_greenstein(g, 0.2, 1.0).unwrap(),
            PhaseFunction::double_henyey_greenstein(g, 0.2, 0.0).unwrap(),
        ];
        for ph in &phs {
            for &wo in &wos {
                for &a in &us {
                    for &b in &us {
                        let s = ph.sample(wo, Vec2::new(a, b));
                        assert!(
                            s.wi.is_finite() && (s.wi.length() - 1.0).abs() < 1e-4,
                            "{ph:?} {wo:?} {a} {b}: {s:?}"
                        );
                        assert!(
                            s.pdf.is_finite() && s.pdf > 0.0,
                            "{ph:?} {wo:?} {a} {b}: {s:?}"
                        );
                        let e = ph.eval(wo, s.wi);
                        assert!(e.is_finite() && e >= 0.0);
                    }
                }
                assert!(ph.eval(wo, wo).is_finite() && ph.eval(wo, -wo).is_finite());
            }
        }
    }
}

#[test]
fn g_is_clamped_to_099() {
    let p = PhaseFunction::henyey_greenstein(1.0).unwrap();
    assert_eq!(p.mean_cosine(), 0.99);
    let p = PhaseFunction::henyey_greenstein(-0.9999).unwrap();
    assert_eq!(p.mean_cosine(), -0.99);
}

#[test]
fn bad_parameters_are_rejected() {
    assert!(matches!(
        PhaseFunction::henyey_greenstein(f32::NAN),
        Err(PhaseError::InvalidParameter { param: "g", .. })
    ));
    assert!(PhaseFunction::henyey_greenstein(1.01).is_err());
    assert!(PhaseFunction::henyey_greenstein(-1.5).is_err());
    assert!(PhaseFunction::henyey_greenstein(f32::INFINITY).is_err());
    assert!(PhaseFunction::double_henyey_greenstein(0.5, -0.3, 1.2).is_err());
    assert!(PhaseFunction::double_henyey_greenstein(0.5, -0.3, -0.1).is_err());
    assert!(PhaseFunction::double_henyey_greenstein(0.5, f32::NAN, 0.5).is_err());
    assert!(PhaseFunction::double_henyey_greenstein(0.5, -0.3, f32::NAN).is_err());
    let msg = PhaseFunction::henyey_greenstein(2.0)
        .unwrap_err()
        .to_string();
    assert!(msg.contains('g') && msg.contains('2'), "{msg}");
}
