//! Smooth and rough dielectric BSDF: chi-square of sampling (reflection + transmission, TIR),
//! pdf normalisation, sample/eval/pdf consistency, white furnace, Fresnel, reciprocity,
//! index-matched pass-through and extreme inputs.

mod common;

use common::sphere::{assert_chi2, chi2_sphere, dir_from_theta_deg, integrate_sphere, SphereBins};
use common::stats::{binomial_standard_error, estimate, Estimate};
use velour::bsdf::fresnel::fresnel_dielectric;
use velour::bsdf::{MicrofacetDistribution, Surface};
use velour::math::{refract, Vec2, Vec3};
use velour::sampling::Rng;
use velour::spectrum::Rgb;

const GGX: MicrofacetDistribution = MicrofacetDistribution::Ggx;
const BECKMANN: MicrofacetDistribution = MicrofacetDistribution::Beckmann;

fn mirror(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Axis of the transmitted lobe (refraction through the macro normal), or the mirror on TIR.
fn refracted_axis(wo: Vec3, eta: f32) -> Vec3 {
    let (n, e) = if wo.z > 0.0 {
        (Vec3::Z, eta)
    } else {
        (-Vec3::Z, 1.0 / eta)
    };
    refract(wo, n, e).unwrap_or(mirror(wo))
}

fn rough_chi2(dist: MicrofacetDistribution, eta: f32, inside: bool, seed_base: u64) {
    let mut k = 0;
    for &alpha in &[0.1f32, 0.5, 1.0] {
        for &theta in &[0.0f32, 45.0, 85.0] {
            let mut wo = dir_from_theta_deg(theta);
            if inside {
                wo.z = -wo.z;
            }
            let s = Surface::dielectric(eta, alpha.sqrt(), dist, Rgb::ONE).unwrap();
            // Narrow lobes: two binnings, one concentrated on the reflected lobe and one on the
            // transmitted lobe. Broad lobes: cells uniform in cosθ.
            let binnings = if alpha <= 0.1 {
                vec![
                    SphereBins::around(mirror(wo), 36, 24, 2.0),
                    SphereBins::around(refracted_axis(wo, eta), 36, 24, 2.0),
                ]
            } else {
                vec![SphereBins::uniform(36, 24)]
            };
            for bins in binnings {
                k += 1;
                let r = chi2_sphere(
                    &bins,
                    2,
                    if dist == GGX { 150_000 } else { 100_000 },
                    seed_base + k,
                    |rng| {
                        let uc = rng.next_f32();
                        s.sample(wo, uc, rng.next_2d()).map(|x| {
                            assert!(!x.is_delta);
                            x.wi
                        })
                    },
                    &|wi| s.pdf(wo, wi) as f64,
                );
                let name = format!("{dist:?} dielectric eta={eta} alpha={alpha} theta={theta} inside={inside} axis={:?}", bins.axis);
                assert_chi2(&name, &r);
                assert!(r.integral <= 1.0 + 3e-3, "{name}: ∫pdf = {}", r.integral);
            }
        }
    }
}

#[test]
fn ggx_rough_dielectric_chi_square_entering() {
    rough_chi2(GGX, 1.5, false, 10_000);
}

#[test]
fn ggx_rough_dielectric_chi_square_exiting_with_tir() {
    // η = 1/1.5 seen from outside: total internal reflection beyond 41.8° (85° case).
    rough_chi2(GGX, 1.0 / 1.5, false, 11_000);
}

#[test]
fn ggx_rough_dielectric_chi_square_from_inside() {
    rough_chi2(GGX, 1.5, true, 12_000);
}

#[test]
fn beckmann_rough_dielectric_chi_square_entering() {
    rough_chi2(BECKMANN, 1.5, false, 20_000);
}

#[test]
fn beckmann_rough_dielectric_chi_square_exiting_with_tir() {
    rough_chi2(BECKMANN, 1.0 / 1.5, false, 21_000);
}

#[test]
fn beckmann_rough_dielectric_chi_square_from_inside() {
    rough_chi2(BECKMANN, 1.5, true, 22_000);
}

#[test]
fn pdf_integrates_to_sampling_success_rate() {
    // ∫ pdf dω equals the probability that `sample` returns a (non-delta) direction.
    for dist in [GGX, BECKMANN] {
        for &eta in &[1.5f32, 1.0 / 1.5] {
            for &theta in &[0.0f32, 60.0, 85.0] {
                let wo = dir_from_theta_deg(theta);
                let s = Surface::dielectric(eta, 0.5, dist, Rgb::ONE).unwrap();
                let i =
                    integrate_sphere(&SphereBins::uniform(60, 32), 3, &|wi| s.pdf(wo, wi) as f64);
                let mut rng = Rng::new(5, 5);
                let n = 100_000;
                let ok = (0..n)
                    .filter(|_| s.sample(wo, rng.next_f32(), rng.next_2d()).is_some())
                    .count();
                let p = ok as f64 / n as f64;
                let sigma = binomial_standard_error(p, n).max(1e-4);
                assert!(
                    i <= 1.0 + 2e-3,
                    "{dist:?} eta={eta} theta={theta}: ∫pdf = {i}"
                );
                assert!(
                    (i - p).abs() < 4.0 * sigma + 2e-3,
                    "{dist:?} eta={eta} theta={theta}: ∫pdf = {i}, success = {p}"
                );
            }
        }
    }
}

#[test]
fn sample_weight_matches_eval_over_pdf() {
    let mut rng = Rng::new(77, 3);
    for dist in [GGX, BECKMANN] {
        for &eta in &[1.5f32, 1.0 / 1.5, 1.0001, 3.0] {
            for &rough in &[0.1f32, 0.5, 1.0] {
                let s = Surface::dielectric(eta, rough, dist, Rgb::new(1.0, 0.5, 0.25)).unwrap();
                for _ in 0..3000 {
                    let wo = velour::sampling::sample_uniform_sphere(rng.next_2d());
                    let Some(x) = s.sample(wo, rng.next_f32(), rng.next_2d()) else {
                        continue;
                    };
                    assert!(!x.is_delta);
                    let f = s.eval(wo, x.wi);
                    let pdf = s.pdf(wo, x.wi);
                    assert!((pdf - x.pdf).abs() <= 1e-3 * pdf, "pdf {} vs {pdf}", x.pdf);
                    let expect = f * (x.wi.z.abs() / pdf);
                    for c in 0..3 {
                        assert!(
                            (x.weight[c] - expect[c]).abs() <= 1e-3 * expect[c].max(1e-3),
                            "{:?} vs {expect:?}",
                            x.weight
                        );
                    }
                    assert_eq!(x.is_transmission, wo.z * x.wi.z < 0.0);
                    let etap = if !x.is_transmission {
                        1.0
                    } else if wo.z > 0.0 {
                        eta
                    } else {
                        1.0 / eta
                    };
                    assert!((x.eta - etap).abs() < 1e-6 * etap);
                    // Weight of a rough sample is G2/G1 ≤ 1 (times tint/η'² for transmission).
                    let bound = if x.is_transmission {
                        1.0 / (etap * etap)
                    } else {
                        1.0
                    };
                    assert!(x.weight.max_component() <= bound * (1.0 + 1e-4));
                }
            }
        }
    }
}

/// Energy albedo from outside/inside: E[weight · η'²] (undoes the radiance η'² scaling).
/// A failed sample counts as zero energy.
fn furnace(s: &Surface, wo: Vec3, n: usize, seed: u64) -> Estimate {
    estimate(n, &mut Rng::new(seed, 9), |rng| {
        s.sample(wo, rng.next_f32(), rng.next_2d())
            .map_or(0.0, |x| (x.weight.average() * x.eta * x.eta) as f64)
    })
}

#[test]
fn smooth_dielectric_conserves_energy_exactly() {
    for &eta in &[1.5f32, 1.0 / 1.5, 1.33, 3.0] {
        let s = Surface::dielectric(eta, 0.0, GGX, Rgb::ONE).unwrap();
        assert!(s.is_delta());
        for k in 0..=30 {
            let theta = 89.9 * k as f32 / 30.0;
            for inside in [false, true] {
                let mut wo = dir_from_theta_deg(theta);
                if inside {
                    wo.z = -wo.z;
                }
                let f = fresnel_dielectric(wo.z, eta);
                for &uc in &[0.0f32, f * 0.5, f, (f + 1.0) * 0.5, 0.999_999] {
                    let Some(x) = s.sample(wo, uc, Vec2::new(0.3, 0.7)) else {
                        panic!("no sample")
                    };
                    assert!(x.is_delta);
                    assert!(s.eval(wo, x.wi) == Rgb::ZERO && s.pdf(wo, x.wi) == 0.0);
                    // f/pdf = 1 (R = F, T = 1 − F, chosen by F); × 1/η'² in radiance mode.
                    let energy = x.weight.average() * x.eta * x.eta;
                    assert!(
                        (energy - 1.0).abs() < 1e-5,
                        "eta={eta} theta={theta}: {x:?}"
                    );
                    if x.is_transmission {
                        assert!((x.pdf - (1.0 - f)).abs() < 1e-6 && uc >= f);
                        // Snell's law.
                        let sin_o = wo.x.hypot(wo.y);
                        let sin_i = x.wi.x.hypot(x.wi.y);
                        assert!((sin_o - x.eta * sin_i).abs() < 1e-5);
                    } else {
                        assert!((x.pdf - f).abs() < 1e-6 || f == 1.0);
                        assert!((x.wi - mirror(wo)).length() < 1e-6);
                    }
                }
            }
        }
    }
}

#[test]
fn rough_dielectric_white_furnace() {
    // Albedo ≤ 1 at every incidence; ≥ 0.95 for small roughness up to 70° (single-scattering
    // Smith microfacets lose energy only at high roughness / grazing angles).
    let n = 12_000;
    let mut seed = 1;
    for dist in [GGX, BECKMANN] {
        for &eta in &[1.5f32, 1.0 / 1.5] {
            for &rough in &[0.1f32, 0.3, 0.7, 1.0] {
                let s = Surface::dielectric(eta, rough, dist, Rgb::ONE).unwrap();
                for &theta in &[0.0f32, 20.0, 45.0, 70.0, 85.0, 89.0] {
                    for inside in [false, true] {
                        let mut wo = dir_from_theta_deg(theta);
                        if inside {
                            wo.z = -wo.z;
                        }
                        seed += 1;
                        let e = furnace(&s, wo, n, seed);
                        let (m, se) = (e.mean, e.standard_error);
                        assert!(m <= 1.0 + 4.0 * se + 1e-4, "{dist:?} eta={eta} r={rough} theta={theta} inside={inside}: albedo {m} ± {se}");
                        if rough <= 0.1 && theta <= 70.0 {
                            assert!(m >= 0.95, "{dist:?} eta={eta} r={rough} theta={theta} inside={inside}: albedo {m}");
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn fresnel_values_and_critical_angle() {
    // F(0°, 1.4) = ((1.4 − 1)/(1.4 + 1))² = 0.02778.
    assert!((fresnel_dielectric(1.0, 1.4) - 0.027_777_78).abs() < 1e-6);
    assert!((fresnel_dielectric(-1.0, 1.0 / 1.4) - 0.027_777_78).abs() < 1e-6);
    assert_eq!(fresnel_dielectric(0.7, 1.0), 0.0);
    assert_eq!(fresnel_dielectric(0.0, 1.5), 1.0);
    // Agreement with Walter 2007 eq. 22 (f64 oracle) everywhere.
    for &eta in &[1.0 / 1.5, 1.0 / 1.4, 1.33, 1.4, 1.5, 2.4] {
        for k in 1..=200 {
            let c = (k as f32 / 200.0) as f64;
            let g2 = (eta as f64).powi(2) - 1.0 + c * c;
            let oracle = if g2 < 0.0 {
                1.0
            } else {
                let g = g2.sqrt();
                let a = (g - c) / (g + c);
                let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
                0.5 * a * a * (1.0 + b * b)
            };
            let f = fresnel_dielectric(c as f32, eta) as f64;
            assert!(
                (f - oracle).abs() < 2e-6,
                "eta={eta} c={c}: {f} vs {oracle}"
            );
        }
    }
    // From inside skin (1.4 → 1): cos θc = 0.69985; F = 1 below, continuous at θc.
    let eta_exit = 1.0 / 1.4f32;
    let cos_c = (1.0 - eta_exit * eta_exit).sqrt();
    assert!((cos_c - 0.699_854_3).abs() < 1e-5);
    assert_eq!(fresnel_dielectric(cos_c * 0.999, eta_exit), 1.0);
    let just_above = fresnel_dielectric(cos_c * (1.0 + 1e-6), eta_exit);
    assert!(just_above > 0.99 && just_above <= 1.0, "{just_above}");
    // Continuity: 1 − F vanishes like sqrt(c − c_c) as the critical angle is approached.
    for &d in &[1e-6f32, 1e-5, 1e-4, 1e-3, 1e-2] {
        let f = fresnel_dielectric(cos_c + d, eta_exit);
        assert!(1.0 - f <= 12.0 * d.sqrt() + 1e-6, "d={d}: F = {f}");
    }
    let mut prev = 1.0;
    for k in 0..=1000 {
        let c = cos_c + (1.0 - cos_c) * k as f32 / 1000.0;
        let f = fresnel_dielectric(c, eta_exit);
        assert!(f <= prev + 1e-6, "F not monotone at c={c}");
        prev = f;
    }
}

#[test]
fn reciprocity() {
    let mut rng = Rng::new(4, 4);
    for dist in [GGX, BECKMANN] {
        for &eta in &[1.5f32, 1.0 / 1.33] {
            let s = Surface::dielectric(eta, 0.6, dist, Rgb::ONE).unwrap();
            let mut checked = 0;
            let mut loose = 0;
            for _ in 0..20_000 {
                let wo = velour::sampling::sample_uniform_sphere(rng.next_2d());
                let wi = velour::sampling::sample_uniform_sphere(rng.next_2d());
                let a = s.eval(wo, wi).r();
                let b = s.eval(wi, wo).r();
                if wo.z * wi.z > 0.0 {
                    // f_r(wo, wi) = f_r(wi, wo).
                    assert!(
                        (a - b).abs() <= 1e-4 * a.max(b) + 1e-5,
                        "reflection {a} vs {b}"
                    );
                } else {
                    // Radiance-mode BTDF: f(wo, wi)/η_wo² = f(wi, wo)/η_wi².
                    let (n_o, n_i) = if wo.z > 0.0 { (1.0, eta) } else { (eta, 1.0) };
                    let (x, y) = (a / (n_o * n_o), b / (n_i * n_i));
                    // f32 conditioning: when the transmitted side is grazing to the microfacet,
                    // the other side sits at the critical angle where 1 − F ∝ sqrt(c − c_c)
                    // amplifies rounding; such pairs carry negligible energy and are skipped.
                    let etap = if wo.z > 0.0 { eta } else { 1.0 / eta };
                    let m = (wi * etap + wo).normalize();
                    if wo.dot(m).abs().min(wi.dot(m).abs()) < 0.01 {
                        continue;
                    }
                    assert!(
                        (x - y).abs() <= 2e-2 * x.max(y) + 1e-5,
                        "transmission {x} vs {y}, wo {wo:?} wi {wi:?}"
                    );
                    if (x - y).abs() > 1e-3 * x.max(y) + 1e-5 {
                        loose += 1;
                    }
                }
                if a > 0.0 {
                    checked += 1;
                }
            }
            assert!(checked > 1000);
            assert!(
                loose * 100 < checked,
                "{loose} of {checked} pairs off by > 1e-3"
            );
        }
    }
}

#[test]
fn index_matched_is_pass_through() {
    for rough in [0.0f32, 0.5, 1.0] {
        let s = Surface::dielectric(1.0, rough, GGX, Rgb::ONE).unwrap();
        assert!(s.is_delta() && s.has_transmission());
        for wo in [dir_from_theta_deg(30.0), -dir_from_theta_deg(70.0), Vec3::Z] {
            let x = s.sample(wo, 0.3, Vec2::new(0.2, 0.9)).unwrap();
            assert_eq!(x.wi, -wo);
            assert_eq!(x.weight, Rgb::ONE);
            assert!(x.is_delta && x.is_transmission && x.eta == 1.0);
            assert_eq!(s.eval(wo, -wo), Rgb::ZERO);
            assert_eq!(s.pdf(wo, -wo), 0.0);
        }
    }
    // Slightly off index matching: the rough lobe is valid and finite.
    let s = Surface::dielectric(1.0001, 0.5, GGX, Rgb::ONE).unwrap();
    assert!(!s.is_delta());
}

#[test]
fn extreme_inputs_are_finite() {
    let eps = 1.0 - f32::EPSILON / 2.0;
    let wos = [
        Vec3::Z,
        -Vec3::Z,
        Vec3::X,
        Vec3::new(1.0, 0.0, 1e-9).normalize(),
        Vec3::new(1.0, 0.0, -1e-9).normalize(),
        dir_from_theta_deg(89.99),
        -dir_from_theta_deg(41.8),
    ];
    let us = [0.0f32, 1e-7, 0.5, eps];
    for dist in [GGX, BECKMANN] {
        for &eta in &[1.0001f32, 1.5, 3.0, 1.0 / 3.0, 0.9999, 1.0] {
            for &rough in &[0.0f32, 0.01, 0.0316, 0.05, 0.5, 1.0] {
                let s = Surface::dielectric(eta, rough, dist, Rgb::ONE).unwrap();
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
                                        "{x:?}"
                                    );
                                    assert!(
                                        x.weight.min_component() >= 0.0
                                            && x.eta.is_finite()
                                            && x.eta > 0.0
                                    );
                                    assert!((x.wi.length() - 1.0).abs() < 1e-3);
                                }
                            }
                        }
                    }
                    for &wi in &wos {
                        let f = s.eval(wo, wi);
                        let p = s.pdf(wo, wi);
                        assert!(
                            f.is_finite() && f.min_component() >= 0.0 && p.is_finite() && p >= 0.0,
                            "{eta} {rough} {wo:?} {wi:?}: {f:?} {p}"
                        );
                        let f = s.eval(wo, -wi);
                        assert!(f.is_finite());
                    }
                }
            }
        }
    }
}

#[test]
fn bad_parameters_are_rejected() {
    assert!(Surface::dielectric(f32::NAN, 0.5, GGX, Rgb::ONE).is_err());
    assert!(Surface::dielectric(0.0, 0.5, GGX, Rgb::ONE).is_err());
    assert!(Surface::dielectric(-1.5, 0.5, GGX, Rgb::ONE).is_err());
    assert!(Surface::dielectric(f32::INFINITY, 0.5, GGX, Rgb::ONE).is_err());
    assert!(Surface::dielectric(1.5, -0.1, GGX, Rgb::ONE).is_err());
    assert!(Surface::dielectric(1.5, 1.1, GGX, Rgb::ONE).is_err());
    assert!(Surface::dielectric(1.5, f32::NAN, GGX, Rgb::ONE).is_err());
    assert!(Surface::dielectric(1.5, 0.5, GGX, Rgb::new(1.0, 1.2, 0.0)).is_err());
    assert!(Surface::dielectric(1.5, 0.5, GGX, Rgb::new(1.0, f32::NAN, 0.0)).is_err());
    let e = Surface::dielectric(1.5, 2.0, GGX, Rgb::ONE)
        .unwrap_err()
        .to_string();
    assert!(e.contains("roughness") && e.contains('2'), "{e}");
    // eta < 1 is allowed at this level (nested media).
    assert!(Surface::dielectric(0.75, 0.5, GGX, Rgb::ONE).is_ok());
}
