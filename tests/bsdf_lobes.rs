//! Diffuse transmission, Lambertian, conductor and coated surfaces: chi-square of sampling,
//! normalisation, weight consistency, energy, reciprocity, Fresnel of conductors, validation.

mod common;

use common::sphere::{assert_chi2, chi2_sphere, dir_from_theta_deg, integrate_sphere, SphereBins};
use common::stats::{binomial_standard_error, estimate, z_score};
use velour::bsdf::fresnel::{fresnel_conductor, fresnel_dielectric};
use velour::bsdf::{BaseLobe, MicrofacetDistribution, Surface};
use velour::math::{Vec2, Vec3};
use velour::sampling::Rng;
use velour::spectrum::Rgb;

const GGX: MicrofacetDistribution = MicrofacetDistribution::Ggx;
const BECKMANN: MicrofacetDistribution = MicrofacetDistribution::Beckmann;

fn gold() -> (Rgb, Rgb) {
    // Approximate RGB complex IOR of gold.
    (Rgb::new(0.143, 0.374, 1.442), Rgb::new(3.983, 2.386, 1.603))
}

fn chi2_surface(name: &str, s: &Surface, wo: Vec3, bins: SphereBins, seed: u64) {
    let r = chi2_sphere(
        &bins,
        2,
        150_000,
        seed,
        |rng| {
            let uc = rng.next_f32();
            s.sample(wo, uc, rng.next_2d())
                .and_then(|x| if x.is_delta { None } else { Some(x.wi) })
        },
        &|wi| s.pdf(wo, wi) as f64,
    );
    assert_chi2(name, &r);
    assert!(r.integral <= 1.0 + 3e-3, "{name}: ∫pdf = {}", r.integral);
}

#[test]
fn diffuse_lobes_chi_square() {
    let dt =
        Surface::diffuse_transmission(Rgb::new(0.2, 0.3, 0.1), Rgb::new(0.7, 0.5, 0.6)).unwrap();
    let dt_only = Surface::diffuse_transmission(Rgb::ZERO, Rgb::splat(0.8)).unwrap();
    let lam = Surface::lambertian(Rgb::new(0.9, 0.5, 0.1)).unwrap();
    let mut seed = 0;
    for &theta in &[0.0f32, 45.0, 85.0] {
        for inside in [false, true] {
            let mut wo = dir_from_theta_deg(theta);
            if inside {
                wo.z = -wo.z;
            }
            for (name, s) in [
                ("diffuse transmission", &dt),
                ("pure diffuse transmission", &dt_only),
                ("lambertian", &lam),
            ] {
                seed += 1;
                chi2_surface(
                    &format!("{name} theta={theta} inside={inside}"),
                    s,
                    wo,
                    SphereBins::uniform(20, 16),
                    500 + seed,
                );
            }
        }
    }
}

#[test]
fn conductor_chi_square() {
    let (eta, k) = gold();
    let mut seed = 0;
    for dist in [GGX, BECKMANN] {
        for &rough in &[0.3f32, 0.7, 1.0] {
            let s = Surface::conductor(eta, k, rough, dist).unwrap();
            for &theta in &[0.0f32, 45.0, 85.0] {
                let wo = dir_from_theta_deg(theta);
                seed += 1;
                let bins = if rough < 0.5 {
                    SphereBins::around(Vec3::new(-wo.x, -wo.y, wo.z), 30, 24, 2.0)
                } else {
                    SphereBins::uniform(30, 24)
                };
                chi2_surface(
                    &format!("{dist:?} conductor r={rough} theta={theta}"),
                    &s,
                    wo,
                    bins,
                    700 + seed,
                );
            }
        }
    }
}

#[test]
fn coated_surfaces_chi_square() {
    let bases = [
        Surface::lambertian(Rgb::new(0.8, 0.4, 0.2)).unwrap(),
        Surface::dielectric(1.4, 0.5, GGX, Rgb::ONE).unwrap(),
        Surface::conductor_from_reflectance(Rgb::new(0.9, 0.6, 0.3), 0.8).unwrap(),
    ];
    let mut seed = 0;
    for base in &bases {
        let s = base.clone().with_coat(1.5, 0.4, 0.8).unwrap();
        for &theta in &[0.0f32, 60.0] {
            for inside in [false, true] {
                let mut wo = dir_from_theta_deg(theta);
                if inside {
                    wo.z = -wo.z;
                }
                seed += 1;
                chi2_surface(
                    &format!("coat over {:?} theta={theta} inside={inside}", base.base()),
                    &s,
                    wo,
                    SphereBins::uniform(30, 24),
                    900 + seed,
                );
            }
        }
    }
}

#[test]
fn sample_weight_matches_eval_over_pdf() {
    let (eta, k) = gold();
    let surfaces = [
        Surface::diffuse_transmission(Rgb::new(0.2, 0.3, 0.1), Rgb::new(0.7, 0.5, 0.6)).unwrap(),
        Surface::lambertian(Rgb::new(0.9, 0.5, 0.1)).unwrap(),
        Surface::conductor(eta, k, 0.5, GGX).unwrap(),
        Surface::conductor(eta, k, 0.2, BECKMANN).unwrap(),
        Surface::lambertian(Rgb::splat(0.5))
            .unwrap()
            .with_coat(1.5, 0.3, 1.0)
            .unwrap(),
        Surface::dielectric(1.33, 0.4, BECKMANN, Rgb::ONE)
            .unwrap()
            .with_coat(1.6, 0.2, 0.5)
            .unwrap(),
        Surface::conductor(eta, k, 0.6, GGX)
            .unwrap()
            .with_coat(1.5, 0.0, 1.0)
            .unwrap(),
    ];
    let mut rng = Rng::new(3, 3);
    for s in &surfaces {
        let mut n_ok = 0;
        for _ in 0..5000 {
            let wo = velour::sampling::sample_uniform_sphere(rng.next_2d());
            let Some(x) = s.sample(wo, rng.next_f32(), rng.next_2d()) else {
                continue;
            };
            assert!(x.weight.is_finite() && x.weight.min_component() >= 0.0);
            if x.is_delta {
                continue;
            }
            n_ok += 1;
            let f = s.eval(wo, x.wi);
            let pdf = s.pdf(wo, x.wi);
            assert!(
                (pdf - x.pdf).abs() <= 1e-3 * pdf,
                "{s:?}: pdf {} vs {pdf}",
                x.pdf
            );
            let expect = f * (x.wi.z.abs() / pdf);
            for c in 0..3 {
                assert!(
                    (x.weight[c] - expect[c]).abs() <= 2e-3 * expect[c].max(1e-3),
                    "{s:?}: {:?} vs {expect:?}",
                    x.weight
                );
            }
        }
        assert!(n_ok > 1000, "{s:?}: only {n_ok} continuous samples");
    }
}

/// Mean and standard error of the sampled weight average (the albedo for one `wo`).
/// A failed sample counts as zero; the standard error is that of the largest channel.
fn albedo(s: &Surface, wo: Vec3, n: usize, seed: u64) -> (Rgb, f64) {
    let mut sum = Rgb::ZERO;
    let largest = estimate(n, &mut Rng::new(seed, 1), |rng| {
        let Some(x) = s.sample(wo, rng.next_f32(), rng.next_2d()) else {
            return 0.0;
        };
        let w = x.weight * (x.eta * x.eta);
        sum += w;
        w.max_component() as f64
    });
    (sum / n as f32, largest.standard_error)
}

#[test]
fn energy_conservation() {
    let white_dt = Surface::diffuse_transmission(Rgb::splat(0.3), Rgb::splat(0.7)).unwrap();
    let white_lam = Surface::lambertian(Rgb::ONE).unwrap();
    let coated_lam = Surface::lambertian(Rgb::ONE)
        .unwrap()
        .with_coat(1.5, 0.5, 1.0)
        .unwrap();
    let coated_lam_smooth = Surface::lambertian(Rgb::ONE)
        .unwrap()
        .with_coat(1.5, 0.0, 1.0)
        .unwrap();
    let coated_glass = Surface::dielectric(1.5, 0.0, GGX, Rgb::ONE)
        .unwrap()
        .with_coat(1.8, 0.7, 1.0)
        .unwrap();
    let mirror_like = Surface::conductor_from_reflectance(Rgb::splat(0.999), 0.3).unwrap();
    let mut seed = 0;
    for &theta in &[0.0f32, 30.0, 60.0, 80.0, 89.0] {
        for inside in [false, true] {
            let mut wo = dir_from_theta_deg(theta);
            if inside {
                wo.z = -wo.z;
            }
            seed += 1;
            // Diffuse transmission and Lambertian: every sample weighs exactly R + T (resp. albedo).
            let (a, _) = albedo(&white_dt, wo, 2000, seed);
            assert!(
                (a.average() - 1.0).abs() < 1e-5,
                "diffuse transmission albedo {a:?}"
            );
            let (a, _) = albedo(&white_lam, wo, 2000, seed);
            assert!((a.average() - 1.0).abs() < 1e-5, "lambertian albedo {a:?}");
            for (name, s) in [
                ("coated lambertian", &coated_lam),
                ("smooth-coated lambertian", &coated_lam_smooth),
                ("coated glass", &coated_glass),
                ("conductor r=0.999", &mirror_like),
            ] {
                let (a, se) = albedo(s, wo, 40_000, 100 + seed);
                assert!(
                    (a.max_component() as f64) <= 1.0 + 4.0 * se + 2e-3,
                    "{name} theta={theta} inside={inside}: albedo {a:?} ± {se}"
                );
                assert!(
                    a.min_component() > 0.2,
                    "{name} theta={theta} inside={inside}: albedo {a:?}"
                );
            }
        }
    }
}

#[test]
fn diffuse_transmission_sides_and_reciprocity() {
    let s =
        Surface::diffuse_transmission(Rgb::new(0.2, 0.3, 0.1), Rgb::new(0.7, 0.5, 0.6)).unwrap();
    assert!(s.has_transmission() && !s.is_delta());
    let a = dir_from_theta_deg(30.0);
    let b = Vec3::new(0.2, -0.3, -0.9).normalize();
    let c = Vec3::new(-0.5, 0.1, 0.7).normalize();
    let pi = std::f32::consts::PI;
    assert!((s.eval(a, b).g() - 0.5 / pi).abs() < 1e-6);
    assert!((s.eval(a, c).g() - 0.3 / pi).abs() < 1e-6);
    assert_eq!(s.eval(a, b), s.eval(b, a));
    // Transmission probability T̄/(R̄+T̄).
    let mut rng = Rng::new(8, 8);
    let n = 100_000;
    let t = (0..n)
        .filter(|_| {
            s.sample(a, rng.next_f32(), rng.next_2d())
                .is_some_and(|x| x.is_transmission)
        })
        .count();
    let p = 0.6 / (0.2 + 0.6);
    let z = z_score(t as f64 / n as f64, p, binomial_standard_error(p, n));
    assert!(z.abs() < 4.5, "transmission fraction z = {z}");
    assert!(!Surface::diffuse_transmission(Rgb::splat(0.5), Rgb::ZERO)
        .unwrap()
        .has_transmission());
}

#[test]
fn conductor_fresnel_and_reciprocity() {
    // k = 0 reduces to the dielectric Fresnel.
    for &c in &[0.05f32, 0.3, 0.7, 1.0] {
        let f = fresnel_conductor(c, Rgb::splat(1.5), Rgb::ZERO);
        assert!((f.r() - fresnel_dielectric(c, 1.5)).abs() < 1e-5, "c={c}");
    }
    // Normal incidence: ((n−1)² + k²)/((n+1)² + k²).
    let (eta, k) = gold();
    let f0 = fresnel_conductor(1.0, eta, k);
    for i in 0..3 {
        let e = ((eta[i] - 1.0).powi(2) + k[i] * k[i]) / ((eta[i] + 1.0).powi(2) + k[i] * k[i]);
        assert!((f0[i] - e).abs() < 1e-5);
    }
    // Grazing: F → 1.
    assert!(fresnel_conductor(0.0, eta, k).min_component() > 0.999);
    // Reflectance mapping reproduces F(0°) = r.
    let r = Rgb::new(0.95, 0.64, 0.54);
    let s = Surface::conductor_from_reflectance(r, 0.0).unwrap();
    assert!(s.is_delta());
    let x = s.sample(Vec3::Z, 0.5, Vec2::splat(0.5)).unwrap();
    assert!(
        (x.weight - r).map(f32::abs).max_component() < 1e-4,
        "{:?} vs {r:?}",
        x.weight
    );
    assert!((s.albedo_hint() - r).map(f32::abs).max_component() < 1e-4);
    // Reciprocity of rough reflection (two-sided).
    let mut rng = Rng::new(9, 9);
    for dist in [GGX, BECKMANN] {
        let s = Surface::conductor(eta, k, 0.5, dist)
            .unwrap()
            .with_coat(1.5, 0.3, 0.7)
            .unwrap();
        for _ in 0..20_000 {
            let wo = velour::sampling::sample_uniform_sphere(rng.next_2d());
            let wi = velour::sampling::sample_uniform_sphere(rng.next_2d());
            let (a, b) = (s.eval(wo, wi), s.eval(wi, wo));
            for ch in 0..3 {
                assert!(
                    (a[ch] - b[ch]).abs() <= 1e-3 * a[ch].max(b[ch]) + 1e-7,
                    "{a:?} vs {b:?}"
                );
            }
            if wo.z * wi.z < 0.0 {
                assert_eq!(a, Rgb::ZERO);
            }
        }
    }
}

#[test]
fn pdfs_integrate_to_one() {
    let (eta, k) = gold();
    let surfaces = [
        Surface::diffuse_transmission(Rgb::new(0.2, 0.3, 0.1), Rgb::new(0.7, 0.5, 0.6)).unwrap(),
        Surface::lambertian(Rgb::new(0.9, 0.5, 0.1)).unwrap(),
        Surface::lambertian(Rgb::splat(0.5))
            .unwrap()
            .with_coat(1.5, 0.3, 1.0)
            .unwrap(),
    ];
    for s in &surfaces {
        for &theta in &[0.0f32, 70.0] {
            let wo = dir_from_theta_deg(theta);
            let i = integrate_sphere(&SphereBins::uniform(40, 24), 2, &|wi| s.pdf(wo, wi) as f64);
            // The coat's reflected samples can fall below the horizon: ∫pdf = success rate.
            let mut rng = Rng::new(12, 12);
            let n = 100_000;
            let ok = (0..n)
                .filter(|_| s.sample(wo, rng.next_f32(), rng.next_2d()).is_some())
                .count() as f64
                / n as f64;
            let tol = 4.0 * (ok * (1.0 - ok) / n as f64).sqrt() + 2e-3;
            assert!(
                (i - ok).abs() < tol,
                "{s:?} theta={theta}: ∫pdf = {i}, success {ok}"
            );
            if s.coat().is_none() {
                assert!((i - 1.0).abs() < 2e-3, "{s:?} theta={theta}: ∫pdf = {i}");
            }
        }
    }
    // Rough conductor: ∫pdf = probability that the reflected direction is above the surface.
    let s = Surface::conductor(eta, k, 0.8, GGX).unwrap();
    let wo = dir_from_theta_deg(75.0);
    let i = integrate_sphere(&SphereBins::uniform(40, 24), 2, &|wi| s.pdf(wo, wi) as f64);
    let mut rng = Rng::new(2, 2);
    let n = 100_000;
    let ok = (0..n)
        .filter(|_| s.sample(wo, rng.next_f32(), rng.next_2d()).is_some())
        .count() as f64
        / n as f64;
    assert!(
        i < 1.0 && (i - ok).abs() < 4.0 * (ok * (1.0 - ok) / n as f64).sqrt() + 2e-3,
        "∫pdf {i} vs success {ok}"
    );
}

#[test]
fn extreme_inputs_are_finite() {
    let (eta, k) = gold();
    let eps = 1.0 - f32::EPSILON / 2.0;
    let surfaces = [
        Surface::diffuse_transmission(Rgb::ZERO, Rgb::ZERO).unwrap(),
        Surface::diffuse_transmission(Rgb::splat(0.5), Rgb::splat(0.5)).unwrap(),
        Surface::lambertian(Rgb::ZERO).unwrap(),
        Surface::conductor(eta, k, 0.0, GGX).unwrap(),
        Surface::conductor(eta, k, 1.0, BECKMANN).unwrap(),
        Surface::conductor(Rgb::splat(1e-3), Rgb::splat(1e3), 0.04, BECKMANN).unwrap(),
        Surface::conductor_from_reflectance(Rgb::ONE, 0.5).unwrap(),
        Surface::conductor_from_reflectance(Rgb::ZERO, 0.5).unwrap(),
        Surface::lambertian(Rgb::ZERO)
            .unwrap()
            .with_coat(1.0, 0.0, 1.0)
            .unwrap(),
        Surface::lambertian(Rgb::ONE)
            .unwrap()
            .with_coat(3.0, 1.0, 1.0)
            .unwrap(),
        Surface::dielectric(1.0, 0.0, GGX, Rgb::ONE)
            .unwrap()
            .with_coat(1.5, 0.02, 0.5)
            .unwrap(),
    ];
    let wos = [
        Vec3::Z,
        -Vec3::Z,
        Vec3::X,
        Vec3::new(1.0, 0.0, 1e-9).normalize(),
        -dir_from_theta_deg(89.99),
    ];
    let us = [0.0f32, 1e-7, 0.5, eps, 1.0];
    for s in &surfaces {
        for &wo in &wos {
            for &uc in &us {
                for &a in &us {
                    for &b in &us {
                        if let Some(x) = s.sample(wo, uc, Vec2::new(a, b)) {
                            assert!(
                                x.wi.is_finite()
                                    && x.weight.is_finite()
                                    && x.pdf.is_finite()
                                    && x.pdf > 0.0,
                                "{s:?} {wo:?}: {x:?}"
                            );
                            assert!(x.weight.min_component() >= 0.0);
                        }
                    }
                }
            }
            for &wi in &wos {
                assert!(s.eval(wo, wi).is_finite() && s.pdf(wo, wi).is_finite());
            }
            assert!(
                s.eval(wo, Vec3::splat(f32::NAN)).is_finite()
                    && s.pdf(wo, Vec3::splat(f32::NAN)) == 0.0
            );
        }
        assert!(s.albedo_hint().is_finite());
    }
}

#[test]
fn flags_and_hints() {
    let (eta, k) = gold();
    assert!(Surface::dielectric(1.5, 0.0, GGX, Rgb::ONE)
        .unwrap()
        .is_delta());
    assert!(!Surface::dielectric(1.5, 0.2, GGX, Rgb::ONE)
        .unwrap()
        .is_delta());
    assert!(Surface::dielectric(1.5, 0.0, GGX, Rgb::ONE)
        .unwrap()
        .with_coat(1.5, 0.0, 0.5)
        .unwrap()
        .is_delta());
    assert!(!Surface::dielectric(1.5, 0.0, GGX, Rgb::ONE)
        .unwrap()
        .with_coat(1.5, 0.5, 0.5)
        .unwrap()
        .is_delta());
    assert!(!Surface::lambertian(Rgb::ONE).unwrap().is_delta());
    assert!(!Surface::conductor(eta, k, 0.5, GGX)
        .unwrap()
        .has_transmission());
    assert_eq!(
        Surface::lambertian(Rgb::new(0.1, 0.2, 0.3))
            .unwrap()
            .albedo_hint(),
        Rgb::new(0.1, 0.2, 0.3)
    );
    assert!(matches!(
        Surface::lambertian(Rgb::ONE).unwrap().base(),
        BaseLobe::Lambertian { .. }
    ));
    assert_eq!(
        Surface::diffuse_transmission(Rgb::splat(0.25), Rgb::splat(0.5))
            .unwrap()
            .albedo_hint(),
        Rgb::splat(0.75)
    );
}

#[test]
fn bad_parameters_are_rejected() {
    let (eta, k) = gold();
    assert!(Surface::lambertian(Rgb::new(1.1, 0.5, 0.5)).is_err());
    assert!(Surface::lambertian(Rgb::new(-0.1, 0.5, 0.5)).is_err());
    assert!(Surface::lambertian(Rgb::new(f32::NAN, 0.5, 0.5)).is_err());
    assert!(Surface::diffuse_transmission(Rgb::splat(0.6), Rgb::splat(0.6)).is_err());
    assert!(Surface::diffuse_transmission(Rgb::splat(-0.1), Rgb::splat(0.6)).is_err());
    assert!(Surface::conductor(Rgb::new(0.0, 1.0, 1.0), k, 0.5, GGX).is_err());
    assert!(Surface::conductor(eta, Rgb::new(-1.0, 1.0, 1.0), 0.5, GGX).is_err());
    assert!(Surface::conductor(eta, Rgb::new(f32::NAN, 1.0, 1.0), 0.5, GGX).is_err());
    assert!(Surface::conductor(eta, k, 1.5, GGX).is_err());
    assert!(Surface::conductor_from_reflectance(Rgb::splat(1.5), 0.5).is_err());
    let base = Surface::lambertian(Rgb::ONE).unwrap();
    assert!(base.clone().with_coat(0.9, 0.5, 0.5).is_err());
    assert!(base.clone().with_coat(f32::NAN, 0.5, 0.5).is_err());
    assert!(base.clone().with_coat(1.5, -0.5, 0.5).is_err());
    assert!(base.clone().with_coat(1.5, 0.5, 1.5).is_err());
    let msg = Surface::diffuse_transmission(Rgb::splat(0.6), Rgb::splat(0.6))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("reflectance + transmittance"), "{msg}");
    let msg = Surface::lambertian(Rgb::new(0.5, 2.0, 0.5))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("albedo.g"), "{msg}");
}

#[test]
fn random_stress_never_returns_nan() {
    // Random parameters (including the edges of their ranges) and random, also grazing and
    // axis-aligned, directions: every output must be finite and non-negative.
    let mut rng = Rng::new(2024, 7);
    let pick = |rng: &mut Rng, edges: &[f32]| -> f32 {
        if rng.next_f32() < 0.3 {
            edges[(rng.next_u32() as usize) % edges.len()]
        } else {
            rng.next_f32()
        }
    };
    for i in 0..3000 {
        let rough = pick(&mut rng, &[0.0, 1e-3, 0.0316, 0.0317, 1.0]);
        let dist = if i % 2 == 0 { GGX } else { BECKMANN };
        let eta = [1.0001f32, 1.5, 3.0, 1.0 / 1.5, 1.0, 0.3][i % 6];
        let c = Rgb::new(
            pick(&mut rng, &[0.0, 1.0]),
            pick(&mut rng, &[0.0, 1.0]),
            pick(&mut rng, &[0.0, 1.0]),
        );
        let mut s = match i % 4 {
            0 => Surface::dielectric(eta, rough, dist, c).unwrap(),
            1 => Surface::diffuse_transmission(c * 0.5, c * 0.5).unwrap(),
            2 => Surface::lambertian(c).unwrap(),
            _ => Surface::conductor(Rgb::splat(eta), c * 5.0, rough, dist).unwrap(),
        };
        if i % 3 == 0 {
            s = s
                .with_coat(
                    1.0 + 2.0 * rng.next_f32(),
                    pick(&mut rng, &[0.0, 1.0]),
                    pick(&mut rng, &[0.0, 1.0]),
                )
                .unwrap();
        }
        for _ in 0..50 {
            let wo = match rng.next_u32() % 5 {
                0 => [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.6, 0.8, 0.0)]
                    [(rng.next_u32() % 4) as usize],
                1 => Vec3::new(
                    rng.next_f32() - 0.5,
                    rng.next_f32() - 0.5,
                    (rng.next_f32() - 0.5) * 1e-6,
                )
                .normalize(),
                _ => velour::sampling::sample_uniform_sphere(rng.next_2d()),
            };
            let u = Vec2::new(
                pick(&mut rng, &[0.0, 1.0 - f32::EPSILON / 2.0]),
                pick(&mut rng, &[0.0, 1.0 - f32::EPSILON / 2.0]),
            );
            if let Some(x) = s.sample(wo, rng.next_f32(), u) {
                assert!(
                    x.wi.is_finite() && x.weight.is_finite() && x.pdf.is_finite() && x.pdf > 0.0,
                    "{s:?} {wo:?}: {x:?}"
                );
                assert!(
                    x.weight.min_component() >= 0.0 && x.eta.is_finite() && x.eta > 0.0,
                    "{s:?} {wo:?}: {x:?}"
                );
                let f = s.eval(wo, x.wi);
                let p = s.pdf(wo, x.wi);
                assert!(f.is_finite() && f.min_component() >= 0.0 && p.is_finite() && p >= 0.0);
            }
            let wi = velour::sampling::sample_uniform_sphere(rng.next_2d());
            let f = s.eval(wo, wi);
            assert!(
                f.is_finite() && f.min_component() >= 0.0 && s.pdf(wo, wi).is_finite(),
                "{s:?} {wo:?} {wi:?}"
            );
        }
    }
}

/// Surfaces built at every hit take a coat prepared once ([`velour::bsdf::Coat::new`]): it must
/// give the very surface that [`Surface::with_coat`] builds in place (same albedo table, so the
/// same values, pdfs and samples), for rough and smooth coats, and validate the weight.
#[test]
fn a_prepared_coat_gives_the_surface_built_in_place() {
    use velour::bsdf::Coat;
    let bases = [
        Surface::dielectric(1.4, 0.3, GGX, Rgb::ONE).unwrap(),
        Surface::diffuse_transmission(Rgb::splat(0.15), Rgb::new(0.85, 0.55, 0.4)).unwrap(),
        Surface::lambertian(Rgb::splat(0.6)).unwrap(),
    ];
    for base in &bases {
        for &(ior, roughness) in &[(1.5f32, 0.1f32), (1.4, 0.35), (1.8, 0.0), (1.0, 1.0)] {
            let coat = Coat::new(ior, roughness).unwrap();
            for &weight in &[0.0f32, 0.37, 1.0] {
                let in_place = base.clone().with_coat(ior, roughness, weight).unwrap();
                let prepared = base.clone().with_prepared_coat(&coat, weight).unwrap();
                assert_eq!(
                    in_place, prepared,
                    "ior {ior} roughness {roughness} weight {weight}"
                );
            }
        }
    }
    let coat = Coat::new(1.5, 0.2).unwrap();
    for bad in [-0.1f32, 1.5, f32::NAN] {
        assert!(
            bases[0].clone().with_prepared_coat(&coat, bad).is_err(),
            "weight {bad}"
        );
    }
    assert!(Coat::new(0.9, 0.2).is_err());
    assert!(Coat::new(f32::NAN, 0.2).is_err());
    assert!(Coat::new(1.5, 1.2).is_err());
}
