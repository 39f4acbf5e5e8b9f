//! Fibre scattering (docs/references.md §7): Chiang 2016 lobes, the diffuse fibre lobe, the
//! fibre-volume phase function (normalisation, furnace, sampling) and SGGX fibre flakes.

mod common;

use common::chi2::critical_value_999;
use velour::fabric::fibre_scattering::{
    diffuse_azimuthal, extinction_scale, longitudinal_lobe, longitudinal_variance,
    sigma_a_from_colour, trimmed_logistic,
};
use velour::fabric::{FibreLobes, FibrePhase, FibrePhaseParams, SggxFibrePhase};
use velour::math::Vec3;
use velour::sampling::Rng;
use velour::spectrum::Rgb;

const PI: f64 = std::f64::consts::PI;

/// An orthonormal frame around `t` of the test's own (independent of the library's).
fn basis(t: Vec3) -> (Vec3, Vec3) {
    let a = if t.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let u = (a - a.dot(t) * t).normalize();
    (u, t.cross(u))
}

/// Direction for `(z = w·t, φ)` in the test frame.
fn dir(t: Vec3, z: f64, phi: f64) -> Vec3 {
    let (u, v) = basis(t);
    let r = (1.0 - z * z).max(0.0).sqrt();
    (u * (r * phi.cos()) as f32 + v * (r * phi.sin()) as f32 + t * z as f32).normalize()
}

/// `∫ f(w) dw` over the sphere by the midpoint rule in `(z, φ)` (dω = dz dφ).
fn integrate_sphere(t: Vec3, n: usize, mut f: impl FnMut(Vec3) -> [f64; 3]) -> [f64; 3] {
    let mut acc = [0.0; 3];
    let dz = 2.0 / n as f64;
    let dphi = 2.0 * PI / n as f64;
    for a in 0..n {
        let z = -1.0 + (a as f64 + 0.5) * dz;
        for b in 0..n {
            let phi = -PI + (b as f64 + 0.5) * dphi;
            let v = f(dir(t, z, phi));
            for c in 0..3 {
                acc[c] += v[c] * dz * dphi;
            }
        }
    }
    acc
}

fn rgb3(c: Rgb) -> [f64; 3] {
    [c.0[0] as f64, c.0[1] as f64, c.0[2] as f64]
}

#[test]
fn longitudinal_lobe_is_normalised() {
    for v in [1e-3f32, 1e-2, 0.1, 1.0, 10.0] {
        for theta_o in [-1.3f64, -0.4, 0.0, 0.7, 1.45] {
            let n = 40_000;
            let mut sum = 0.0f64;
            for k in 0..n {
                let th = -PI / 2.0 + PI * (k as f64 + 0.5) / n as f64;
                let m = longitudinal_lobe(
                    th.cos() as f32,
                    th.sin() as f32,
                    theta_o.cos() as f32,
                    theta_o.sin() as f32,
                    v,
                );
                sum += m as f64 * th.cos() * PI / n as f64;
            }
            assert!((sum - 1.0).abs() < 2e-3, "v {v} θo {theta_o}: {sum}");
        }
    }
    // The azimuthal logistic and the diffuse azimuthal lobe integrate to 1 over [−π, π].
    for s in [0.05f32, 0.3, 1.0, 3.0] {
        let n = 20_000;
        let sum: f64 = (0..n)
            .map(|k| {
                trimmed_logistic((-PI + 2.0 * PI * (k as f64 + 0.5) / n as f64) as f32, s) as f64
            })
            .sum::<f64>()
            * 2.0
            * PI
            / n as f64;
        assert!((sum - 1.0).abs() < 1e-3, "s {s}: {sum}");
    }
    let n = 20_000;
    let sum: f64 = (0..n)
        .map(|k| diffuse_azimuthal((-PI + 2.0 * PI * (k as f64 + 0.5) / n as f64) as f32) as f64)
        .sum::<f64>()
        * 2.0
        * PI
        / n as f64;
    assert!((sum - 1.0).abs() < 1e-4, "{sum}");
    assert!(longitudinal_variance(0.3) > 0.0);
}

/// A random sampling query: a fibre tangent and an outgoing direction, uniform on the sphere,
/// and the four uniform numbers a phase sample takes.
fn sampling_query(rng: &mut Rng) -> (Vec3, Vec3, [f32; 4]) {
    let t = velour::sampling::sample_uniform_sphere(rng.next_2d());
    let wo = velour::sampling::sample_uniform_sphere(rng.next_2d());
    let u = [
        rng.next_f32(),
        rng.next_f32(),
        rng.next_f32(),
        rng.next_f32(),
    ];
    (t, wo, u)
}

fn phase(p: FibrePhaseParams) -> FibrePhase {
    FibrePhase::new(p).unwrap()
}

fn some_dirs() -> Vec<Vec3> {
    vec![
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.3, -0.5, 0.8).normalize(),
        Vec3::new(-0.2, 0.9, -0.4).normalize(),
        Vec3::new(0.05, 0.1, -0.99).normalize(),
    ]
}

/// White furnace: σ_a = 0, white diffuse lobe ⇒ ∫ S dω_i = 1 for every ω_o and mix.
#[test]
fn white_furnace_integrates_to_one() {
    let t = Vec3::new(0.2, 0.3, 0.93).normalize();
    for (d, alpha, beta) in [(0.0f32, 0.0f32, 0.3f32), (0.3, 0.05, 0.4), (0.5, 0.0, 0.8)] {
        let ph = phase(FibrePhaseParams {
            diffuse_weight: d,
            alpha,
            beta_m: beta,
            beta_n: beta,
            h_nodes: if d == 0.0 { 32 } else { 8 },
            ..Default::default()
        });
        for wo in some_dirs().into_iter().skip(1) {
            let v = integrate_sphere(t, 200, |wi| rgb3(ph.eval(wo, wi, t)));
            let p = integrate_sphere(t, 200, |wi| [ph.pdf(wo, wi, t) as f64; 3]);
            for c in 0..3 {
                assert!((v[c] - 1.0).abs() < 1e-2, "d {d} wo {wo}: ∫S = {v:?}");
            }
            assert!((p[0] - 1.0).abs() < 1e-2, "∫pdf = {}", p[0]);
        }
    }
}

#[test]
fn absorbing_and_partial_lobes_conserve_energy() {
    let t = Vec3::Z;
    let diffuse_only = phase(FibrePhaseParams {
        diffuse_weight: 1.0,
        diffuse_albedo: Rgb::new(0.2, 0.5, 0.9),
        ..Default::default()
    });
    let wo = Vec3::new(0.6, 0.0, 0.8);
    let v = integrate_sphere(t, 200, |wi| rgb3(diffuse_only.eval(wo, wi, t)));
    for (c, want) in [0.2, 0.5, 0.9].iter().enumerate() {
        assert!(
            (v[c] - want).abs() < 5e-3,
            "diffuse lobe integrates to A_d: {v:?}"
        );
    }
    let coloured = phase(FibrePhaseParams::default().with_colour(Rgb::new(0.8, 0.4, 0.1)));
    for wo in some_dirs().into_iter().take(2) {
        let v = integrate_sphere(t, 160, |wi| rgb3(coloured.eval(wo, wi, t)));
        assert!(
            v[0] < 1.0 && v[0] > v[1] && v[1] > v[2] && v[2] > 0.0,
            "{v:?}"
        );
    }
    // R + TT only (the course notes' choice without TRT): strictly less than 1.
    let rtt = phase(FibrePhaseParams {
        diffuse_weight: 0.0,
        lobes: FibreLobes {
            r: true,
            tt: true,
            trt: false,
            residual: false,
        },
        ..Default::default()
    });
    let v = integrate_sphere(t, 160, |wi| rgb3(rtt.eval(Vec3::X, wi, t)));
    assert!(v[0] < 0.999 && v[0] > 0.8, "{v:?}");
    // Colour inversion: white is transparent, darker colours absorb more.
    assert_eq!(sigma_a_from_colour(Rgb::ONE, 0.3), Rgb::ZERO);
    let s = sigma_a_from_colour(Rgb::new(0.8, 0.4, 0.1), 0.3);
    assert!(s.0[0] < s.0[1] && s.0[1] < s.0[2]);
}

#[test]
fn sample_weight_is_eval_over_pdf() {
    let mut rng = Rng::new(3, 0);
    for params in [
        FibrePhaseParams::default(),
        FibrePhaseParams {
            alpha: 0.04,
            beta_m: 0.15,
            beta_n: 0.5,
            ..Default::default()
        }
        .with_colour(Rgb::new(0.9, 0.3, 0.2)),
        FibrePhaseParams {
            diffuse_weight: 1.0,
            diffuse_albedo: Rgb::new(0.3, 0.6, 0.9),
            ..Default::default()
        },
    ] {
        let white = params.sigma_a == Rgb::ZERO && params.diffuse_albedo == Rgb::ONE;
        let ph = phase(params);
        for _ in 0..4000 {
            let (t, wo, u) = sampling_query(&mut rng);
            let Some(s) = ph.sample(wo, t, u) else {
                continue;
            };
            assert!((s.wi.length() - 1.0).abs() < 1e-4);
            let f = ph.eval(wo, s.wi, t);
            let pdf = ph.pdf(wo, s.wi, t);
            assert!((pdf / s.pdf - 1.0).abs() < 1e-4, "{pdf} vs {}", s.pdf);
            for c in 0..3 {
                let w = f.0[c] / pdf;
                assert!(
                    (s.weight.0[c] - w).abs() < 1e-4 * w.max(1.0),
                    "{:?} vs {w}",
                    s.weight
                );
                if white {
                    assert!(
                        (s.weight.0[c] - 1.0).abs() < 1e-4,
                        "white furnace weight {:?}",
                        s.weight
                    );
                }
            }
        }
    }
}

/// Histogram of sampled ω_i in (z = ω_i·t, φ) bins against the pdf integrated per bin.
fn chi_square_directions(
    name: &str,
    t: Vec3,
    n_samples: usize,
    mut sample: impl FnMut([f32; 4]) -> Option<Vec3>,
    pdf: impl Fn(Vec3) -> f64,
) {
    let (nz, nphi, sub) = (24usize, 48usize, 6usize);
    let (u, v) = basis(t);
    let mut counts = vec![0f64; nz * nphi];
    let mut rng = Rng::new(17, 5);
    let mut got = 0usize;
    for _ in 0..n_samples {
        let uu = [
            rng.next_f32(),
            rng.next_f32(),
            rng.next_f32(),
            rng.next_f32(),
        ];
        let Some(wi) = sample(uu) else { continue };
        got += 1;
        let z = wi.dot(t).clamp(-1.0, 1.0) as f64;
        let phi = (wi.dot(v) as f64).atan2(wi.dot(u) as f64);
        let a = (((z + 1.0) / 2.0 * nz as f64) as usize).min(nz - 1);
        let b = (((phi + PI) / (2.0 * PI) * nphi as f64) as usize).min(nphi - 1);
        counts[a * nphi + b] += 1.0;
    }
    assert!(
        got as f64 > 0.99 * n_samples as f64,
        "{name}: too many failed samples"
    );
    let mut expected = vec![0f64; nz * nphi];
    let (dz, dphi) = (2.0 / (nz * sub) as f64, 2.0 * PI / (nphi * sub) as f64);
    for a in 0..nz * sub {
        let z = -1.0 + (a as f64 + 0.5) * dz;
        for b in 0..nphi * sub {
            let phi = -PI + (b as f64 + 0.5) * dphi;
            expected[(a / sub) * nphi + b / sub] +=
                pdf(dir(t, z, phi)) * dz * dphi * n_samples as f64;
        }
    }
    // Pool cells with expected < 5.
    let (mut chi2, mut df) = (0.0, 0usize);
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (o, e) in counts.iter().zip(&expected) {
        if *e < 5.0 {
            pool_o += o;
            pool_e += e;
        } else {
            chi2 += (o - e).powi(2) / e;
            df += 1;
        }
    }
    if pool_e > 5.0 {
        chi2 += (pool_o - pool_e).powi(2) / pool_e;
        df += 1;
    }
    let crit = critical_value_999((df - 1) as f64);
    assert!(chi2 < crit, "{name}: chi2 {chi2} >= {crit} (df {df})");
}

#[test]
fn sampled_directions_match_pdf_chi_square() {
    let t = Vec3::new(0.3, -0.2, 0.93).normalize();
    let cases = [
        ("default", FibrePhaseParams::default()),
        (
            "coloured tilted",
            FibrePhaseParams {
                alpha: 0.05,
                beta_m: 0.25,
                beta_n: 0.4,
                h_nodes: 8,
                ..Default::default()
            }
            .with_colour(Rgb::new(0.7, 0.3, 0.1)),
        ),
        (
            "diffuse",
            FibrePhaseParams {
                diffuse_weight: 1.0,
                h_nodes: 1,
                ..Default::default()
            },
        ),
        (
            "R+TT",
            FibrePhaseParams {
                lobes: FibreLobes {
                    r: true,
                    tt: true,
                    trt: false,
                    residual: false,
                },
                h_nodes: 8,
                ..Default::default()
            },
        ),
    ];
    for (k, (name, params)) in cases.into_iter().enumerate() {
        let ph = phase(params);
        let wos = [
            Vec3::new(0.8, 0.1, 0.3).normalize(),
            Vec3::new(-0.1, 0.4, -0.9).normalize(),
        ];
        // The default (32 nodes) is the costliest: one direction suffices.
        for &wo in &wos[..if k == 0 { 1 } else { 2 }] {
            chi_square_directions(
                name,
                t,
                100_000,
                |u| ph.sample(wo, t, u).map(|s| s.wi),
                |wi| ph.pdf(wo, wi, t) as f64,
            );
        }
    }
}

#[test]
fn extinction_scale_is_projected_width() {
    let t = Vec3::new(0.0, 0.6, 0.8);
    assert!(extinction_scale(t, t).abs() < 1e-3);
    assert!((extinction_scale(Vec3::X, t) - 1.0).abs() < 1e-6);
    let w = Vec3::new(0.0, 0.8, -0.6);
    assert!(
        (extinction_scale((w + t).normalize(), t) - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-5
    );
}

#[test]
fn bad_phase_parameters_name_the_parameter() {
    let cases: Vec<(&str, FibrePhaseParams)> = vec![
        (
            "eta",
            FibrePhaseParams {
                eta: 0.5,
                ..Default::default()
            },
        ),
        (
            "beta_m",
            FibrePhaseParams {
                beta_m: 0.0,
                ..Default::default()
            },
        ),
        (
            "beta_n",
            FibrePhaseParams {
                beta_n: 2.0,
                ..Default::default()
            },
        ),
        (
            "diffuse_weight",
            FibrePhaseParams {
                diffuse_weight: -0.1,
                ..Default::default()
            },
        ),
        (
            "sigma_a",
            FibrePhaseParams {
                sigma_a: Rgb::new(-1.0, 0.0, 0.0),
                ..Default::default()
            },
        ),
        (
            "diffuse_albedo",
            FibrePhaseParams {
                diffuse_albedo: Rgb::new(0.0, f32::NAN, 0.0),
                ..Default::default()
            },
        ),
        (
            "alpha",
            FibrePhaseParams {
                alpha: 1.0,
                ..Default::default()
            },
        ),
    ];
    for (name, p) in cases {
        let msg = FibrePhase::new(p).unwrap_err().to_string();
        assert!(
            msg.contains(&format!("`{name}`")) && msg.contains("allowed"),
            "{msg}"
        );
    }
    assert!(FibrePhase::new(FibrePhaseParams {
        h_nodes: 300,
        ..Default::default()
    })
    .unwrap_err()
    .to_string()
    .contains("`h_nodes`"));
    // Automatic node count: ⌈10/β_n⌉, even, in [8, 128].
    let auto = |b: f32| {
        phase(FibrePhaseParams {
            beta_n: b,
            ..Default::default()
        })
        .h_node_count()
    };
    assert_eq!(
        (auto(0.3), auto(0.15), auto(1.0), auto(0.01)),
        (34, 68, 10, 128)
    );
    assert_eq!(
        phase(FibrePhaseParams {
            h_nodes: 5,
            ..Default::default()
        })
        .h_node_count(),
        5
    );
    assert!(SggxFibrePhase::new(Vec3::Z, 0.0, Rgb::ONE).is_err());
    assert!(SggxFibrePhase::new(Vec3::new(0.0, 0.0, 2.0), 0.5, Rgb::ONE).is_err());
}

#[test]
fn sggx_fibre_flakes() {
    let t = Vec3::new(0.4, 0.1, 0.9).normalize();
    // σ → 0: projected area is the cylinder's sin∠(ω, t).
    let thin = SggxFibrePhase::new(t, 1e-3, Rgb::ONE).unwrap();
    for w in some_dirs() {
        assert!((thin.projected_area(w) - extinction_scale(w, t)).abs() < 2e-3);
    }
    for sigma in [0.4f32, 0.8] {
        let ph = SggxFibrePhase::new(t, sigma, Rgb::new(0.5, 0.7, 0.9)).unwrap();
        for w in some_dirs() {
            // σ(ω) = ∫ max(0, ω·m) D(m) dm.
            let proj = integrate_sphere(t, 400, |m| [(w.dot(m).max(0.0) * ph.ndf(m)) as f64; 3])[0];
            assert!(
                (proj / ph.projected_area(w) as f64 - 1.0).abs() < 1e-2,
                "σ {sigma}: {proj}"
            );
            // The specular phase integrates to one; eval = albedo·pdf.
            let p = integrate_sphere(t, 400, |wi| [ph.pdf(w, wi) as f64; 3])[0];
            assert!((p - 1.0).abs() < 1e-2, "σ {sigma}: ∫ pdf = {p}");
            let e = ph.eval(w, Vec3::X);
            assert!((e.0[1] - 0.7 * ph.pdf(w, Vec3::X)).abs() < 1e-5);
        }
        let wo = Vec3::new(-0.5, 0.7, 0.2).normalize();
        chi_square_directions(
            "sggx",
            t,
            100_000,
            |u| ph.sample(wo, [u[0], u[1]]).map(|s| s.wi),
            |wi| ph.pdf(wo, wi) as f64,
        );
        let mut rng = Rng::new(1, 1);
        for _ in 0..1000 {
            if let Some(s) = ph.sample(wo, [rng.next_f32(), rng.next_f32()]) {
                assert!((s.pdf / ph.pdf(wo, s.wi) - 1.0).abs() < 1e-3);
                assert_eq!(s.weight, Rgb::new(0.5, 0.7, 0.9));
            }
        }
    }
}

/// Warp and weft take their own phase function (albedo by yarn id).
#[test]
fn fabric_shading_by_yarn_id() {
    use velour::fabric::{
        generate_patch, FabricShading, WeaveParams, WeavePattern, YarnId, YarnParams,
    };
    let mut y = YarnParams::preset("polyester1").unwrap();
    y.fibres_per_ply = 2;
    let mut p = WeaveParams::new(WeavePattern::Plain, y);
    p.warp_albedo = Rgb::new(0.9, 0.2, 0.1);
    p.weft_albedo = Rgb::new(0.1, 0.3, 0.9);
    let patch = generate_patch(&p, 1).unwrap();
    let base = FibrePhaseParams {
        h_nodes: 8,
        ..Default::default()
    };
    let sh = FabricShading::from_patch(&base, &patch).unwrap();
    let t = Vec3::Z;
    let wo = Vec3::new(0.6, 0.0, 0.8);
    let warp = integrate_sphere(t, 120, |wi| {
        rgb3(sh.for_yarn(YarnId::Warp(0)).eval(wo, wi, t))
    });
    let weft = integrate_sphere(t, 120, |wi| {
        rgb3(sh.for_yarn(YarnId::Weft(1)).eval(wo, wi, t))
    });
    assert!(warp[0] > warp[2] && weft[2] > weft[0], "{warp:?} {weft:?}");
    assert_eq!(sh.for_yarn(YarnId::Warp(5)), &sh.warp);
    assert_eq!(sh.for_yarn(YarnId::Pile), &sh.pile);
}

/// Degenerate tangents give zero, and the model does not depend on the tangent's sign or length.
#[test]
fn tangent_sign_and_degenerate_tangents() {
    let ph = phase(
        FibrePhaseParams {
            alpha: 0.0,
            ..Default::default()
        }
        .with_colour(Rgb::new(0.7, 0.5, 0.3)),
    );
    let mut rng = Rng::new(8, 8);
    for _ in 0..200 {
        let t = velour::sampling::sample_uniform_sphere(rng.next_2d());
        let wo = velour::sampling::sample_uniform_sphere(rng.next_2d());
        let wi = velour::sampling::sample_uniform_sphere(rng.next_2d());
        let a = ph.eval(wo, wi, t);
        let b = ph.eval(wo, wi, -t);
        let c = ph.eval(wo, wi, 3.0 * t);
        for k in 0..3 {
            assert!(
                (a.0[k] - b.0[k]).abs() <= 1e-3 * a.0[k].max(1e-3),
                "{a:?} {b:?}"
            );
            assert!((a.0[k] - c.0[k]).abs() <= 1e-4 * a.0[k].max(1e-3));
        }
    }
    assert_eq!(ph.eval(Vec3::X, Vec3::Y, Vec3::ZERO), Rgb::ZERO);
    assert_eq!(ph.pdf(Vec3::X, Vec3::Y, Vec3::NAN), 0.0);
    assert!(ph.sample(Vec3::X, Vec3::ZERO, [0.5; 4]).is_none());
}

/// Lobes are chosen by their largest channel, so a sample's weight (value over pdf) stays at
/// most 1 in every channel of a saturated yarn colour: paths that scatter many times in a
/// red yarn keep even weights instead of gaining up to 3× on the lobes that carry red (as
/// choosing by the channels' average did) and losing as much on the others.
#[test]
fn saturated_colours_sample_with_weights_at_most_one() {
    let mut rng = Rng::new(11, 0);
    for colour in [
        Rgb::new(0.72, 0.1, 0.09),
        Rgb::new(0.1, 0.8, 0.2),
        Rgb::new(0.86, 0.82, 0.72),
    ] {
        let ph = phase(FibrePhaseParams::default().with_colour(colour));
        let mut largest = 0.0f32;
        for _ in 0..20_000 {
            let (t, wo, u) = sampling_query(&mut rng);
            if let Some(s) = ph.sample(wo, t, u) {
                largest = largest.max(s.weight.max_component());
            }
        }
        assert!(
            largest <= 1.0 + 1e-4,
            "colour {colour:?}: largest sample weight {largest}"
        );
        assert!(
            largest > 0.5,
            "colour {colour:?}: largest sample weight {largest}"
        );
    }
}
