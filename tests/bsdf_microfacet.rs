//! Microfacet distributions: visible-normal sampling (chi-square), normalisation of D and of
//! the visible-normal density (which checks Smith Λ), and the special functions behind Beckmann.

mod common;

use common::sphere::{assert_chi2, chi2_sphere, dir_from_theta_deg, integrate_sphere, SphereBins};
use velour::bsdf::microfacet::Microfacet;
use velour::bsdf::special::{erf, erf_inv, erfc};
use velour::bsdf::MicrofacetDistribution;
use velour::math::{Vec2, Vec3};

const DISTS: [MicrofacetDistribution; 2] = [
    MicrofacetDistribution::Ggx,
    MicrofacetDistribution::Beckmann,
];

fn bins_for_alpha(alpha: f32) -> SphereBins {
    let power = if alpha <= 0.1 {
        3.5
    } else if alpha < 0.6 {
        2.0
    } else {
        1.0
    };
    SphereBins::around(Vec3::Z, 40, 24, power)
}

fn vndf_chi2(dist: MicrofacetDistribution, seed_base: u64) {
    let mut k = 0;
    for &alpha in &[0.05f32, 0.1, 0.5, 1.0] {
        for &theta in &[0.0f32, 45.0, 85.0] {
            for &below in &[false, true] {
                if below && theta != 45.0 {
                    continue;
                }
                let mut w = dir_from_theta_deg(theta);
                // Non-zero azimuth to exercise the rotation of the sampled slopes.
                w = Vec3::new(w.x * 0.6, w.x * 0.8, w.z);
                if below {
                    w.z = -w.z;
                }
                let mf = Microfacet::new(dist, alpha);
                k += 1;
                let r = chi2_sphere(
                    &bins_for_alpha(alpha),
                    2,
                    200_000,
                    seed_base + k,
                    |rng| Some(mf.sample_visible(w, rng.next_2d())),
                    &|m| mf.visible_pdf(w, m) as f64,
                );
                let name = format!("{dist:?} VNDF alpha={alpha} theta={theta} below={below}");
                assert_chi2(&name, &r);
                assert!(
                    (r.integral - 1.0).abs() < 3e-3,
                    "{name}: ∫D_v = {}",
                    r.integral
                );
            }
        }
    }
}

#[test]
fn ggx_visible_normals_chi_square() {
    vndf_chi2(MicrofacetDistribution::Ggx, 1000);
}

#[test]
fn beckmann_visible_normals_chi_square() {
    vndf_chi2(MicrofacetDistribution::Beckmann, 2000);
}

#[test]
fn chi_square_detects_a_wrong_distribution() {
    // GGX and Beckmann visible normals of equal α differ mostly in their tails: the test
    // must tell them apart, and must notice a 5 % error in α.
    let w = dir_from_theta_deg(45.0);
    let ggx = Microfacet::new(MicrofacetDistribution::Ggx, 0.5);
    let beck = Microfacet::new(MicrofacetDistribution::Beckmann, 0.5);
    let beck_wide = Microfacet::new(MicrofacetDistribution::Beckmann, 0.525);
    for (name, wrong) in [
        ("beckmann vs ggx", &ggx),
        ("alpha 0.5 vs 0.525", &beck_wide),
    ] {
        let r = chi2_sphere(
            &bins_for_alpha(0.5),
            2,
            200_000,
            77,
            |rng| Some(beck.sample_visible(w, rng.next_2d())),
            &|m| wrong.visible_pdf(w, m) as f64,
        );
        assert!(r.p_value < 1e-6, "{name}: not detected ({r:?})");
    }
}

#[test]
fn projected_ndf_and_visible_density_integrate_to_one() {
    // ∫ D(m) m.z dm = 1 and ∫ D_w(m) dm = 1; the latter holds only if Smith Λ is exact
    // (∫ max(0, w·m) D(m) dm = w.z (1 + Λ(w))), so it tests Λ too.
    for dist in DISTS {
        for &alpha in &[0.01f32, 0.05, 0.2, 0.5, 1.0] {
            let mf = Microfacet::new(dist, alpha);
            let bins = bins_for_alpha(alpha.max(0.01));
            let bins = SphereBins {
                power: if alpha < 0.05 { 5.0 } else { bins.power },
                n_theta: 80,
                ..bins
            };
            let i = integrate_sphere(&bins, 2, &|m| (mf.d(m) * m.z.max(0.0)) as f64);
            assert!(
                (i - 1.0).abs() < 2e-3,
                "{dist:?} alpha={alpha}: ∫D cos = {i}"
            );
            for &theta in &[0.0f32, 30.0, 60.0, 80.0, 89.0] {
                let w = dir_from_theta_deg(theta);
                let i = integrate_sphere(&bins, 2, &|m| mf.visible_pdf(w, m) as f64);
                assert!(
                    (i - 1.0).abs() < 3e-3,
                    "{dist:?} alpha={alpha} theta={theta}: ∫D_v = {i}"
                );
            }
        }
    }
}

#[test]
fn smith_lambda_limits() {
    for dist in DISTS {
        let mf = Microfacet::new(dist, 0.5);
        assert_eq!(mf.lambda(Vec3::Z), 0.0);
        assert_eq!(mf.g1(Vec3::Z), 1.0);
        assert_eq!(mf.g1(Vec3::X), 0.0);
        let g = mf.g1(dir_from_theta_deg(89.999));
        assert!(g.is_finite() && (0.0..=1.0).contains(&g));
        // G2 ≤ min(G1(wo), G1(wi)) and symmetric.
        let a = dir_from_theta_deg(60.0);
        let b = Vec3::new(0.0, 0.5, 0.8).normalize();
        assert!(mf.g2(a, b) <= mf.g1(a).min(mf.g1(b)) + 1e-6);
        assert_eq!(mf.g2(a, b), mf.g2(b, a));
    }
    // GGX Λ closed form at tanθ = 1, α = 1: (sqrt(2) - 1)/2.
    let ggx = Microfacet::new(MicrofacetDistribution::Ggx, 1.0);
    let l = ggx.lambda(dir_from_theta_deg(45.0));
    assert!((l - (2f32.sqrt() - 1.0) / 2.0).abs() < 1e-5, "{l}");
    // Beckmann Λ(a = 1) = (erf(1) − 1)/2 + e^{-1}/(2√π) = 0.0250... (a = 1/(α tanθ) = 1).
    let beck = Microfacet::new(MicrofacetDistribution::Beckmann, 1.0);
    let l = beck.lambda(dir_from_theta_deg(45.0)) as f64;
    let exact = (0.842_700_792_949_714_9 - 1.0) / 2.0
        + (-1.0f64).exp() / (2.0 * std::f64::consts::PI.sqrt());
    assert!((l - exact).abs() < 2e-6, "{l} vs {exact}");
}

#[test]
fn erf_family_accuracy() {
    let known: [(f32, f64); 8] = [
        (0.0, 0.0),
        (1e-3, 1.128_378_416_355_7e-3),
        (0.1, 0.112_462_916_018_284_9),
        (0.5, 0.520_499_877_813_046_5),
        (1.0, 0.842_700_792_949_714_9),
        (2.0, 0.995_322_265_018_952_7),
        (-1.5, -0.966_105_146_475_310_7),
        (3.0, 0.999_977_909_503_001_4),
    ];
    for (x, e) in known {
        let v = erf(x) as f64;
        assert!(
            (v - e).abs() <= 2e-7 + 2e-6 * e.abs(),
            "erf({x}) = {v}, expected {e}"
        );
    }
    let tails: [(f32, f64); 4] = [
        (2.0, 4.677_734_981_047_266e-3),
        (3.0, 2.209_049_699_858_544e-5),
        (5.0, 1.537_459_794_428_035e-12),
        (-1.0, 1.842_700_792_949_715),
    ];
    for (x, e) in tails {
        let v = erfc(x) as f64;
        assert!(
            (v - e).abs() <= 3e-6 * e.abs(),
            "erfc({x}) = {v}, expected {e}"
        );
    }
    // Round trip and tails of the inverse.
    for k in -999..=999 {
        let y = k as f32 / 1000.0;
        let x = erf_inv(y);
        assert!(
            (erf(x) - y).abs() <= 3e-7 + 2e-6 * y.abs(),
            "erf(erf_inv({y})) = {}",
            erf(x)
        );
    }
    for &x in &[2.5f32, 3.0, 3.5, 3.8] {
        let y = 1.0 - erfc(x);
        let back = erf_inv(y);
        // y is rounded to f32 near 1; compare through erfc, which is what matters.
        assert!(
            ((1.0 - y) - erfc(back)).abs() <= 1e-6 * (1.0 - y),
            "x={x}: erf_inv(erf(x)) = {back}"
        );
    }
    assert_eq!(erf_inv(1.0), f32::INFINITY);
    assert_eq!(erf_inv(-1.0), f32::NEG_INFINITY);
    assert!(erf_inv(1.5).is_nan() && erf_inv(f32::NAN).is_nan());
    assert!(erf_inv(0.0) == 0.0 && erf(0.0) == 0.0);
    assert!(erf(f32::INFINITY) == 1.0 && erf(f32::NEG_INFINITY) == -1.0);
}

#[test]
fn extreme_directions_sample_finite_normals() {
    let eps = 1.0 - f32::EPSILON / 2.0;
    let ws = [
        Vec3::Z,
        -Vec3::Z,
        Vec3::X,
        -Vec3::Y,
        Vec3::new(1.0, 0.0, 1e-8).normalize(),
        dir_from_theta_deg(89.9),
    ];
    for dist in DISTS {
        for &alpha in &[1e-3f32, 0.01, 0.5, 1.0] {
            let mf = Microfacet::new(dist, alpha);
            for &w in &ws {
                for &a in &[0.0f32, 1e-7, 0.5, eps] {
                    for &b in &[0.0f32, 1e-7, 0.5, eps] {
                        let m = mf.sample_visible(w, Vec2::new(a, b));
                        assert!(
                            m.is_finite() && m.z > 0.0 && (m.length() - 1.0).abs() < 1e-4,
                            "{dist:?} {alpha} {w:?} {a} {b}: {m:?}"
                        );
                        let p = mf.visible_pdf(w, m);
                        assert!(p.is_finite() && p >= 0.0);
                        assert!(mf.d(m).is_finite());
                    }
                }
            }
        }
    }
}
