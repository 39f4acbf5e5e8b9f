//! `compare()`: error metrics, the per-pixel z-test verdict on synthetic images with known
//! statistics and on films rendered from known distributions, the error map, and the
//! distribution tails it relies on.

use velour::film::{Film, PixelSample};
use velour::image_io::compare::{
    binomial_upper_tail, error_map, normal_two_sided_tail, student_t_two_sided_tail, ErrorMapMode,
    P_ABOVE_2, P_ABOVE_3,
};
use velour::image_io::{compare, compare_layer, CompareError, ExrImage};
use velour::math::Vec3;
use velour::sampling::Rng;
use velour::spectrum::Rgb;

fn normal(rng: &mut Rng) -> f64 {
    // Box-Muller.
    let u1 = 1.0 - rng.next_f64();
    let u2 = rng.next_f64();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// A smooth "true" image.
fn truth(w: u32, h: u32) -> Vec<Rgb> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            Rgb::new(0.5 + 0.4 * (x * 0.2).sin(), 1.0 + y * 0.01, 0.05)
        })
        .collect()
}

/// `truth + offset_sigmas * sd + N(0, sd^2)` with variance channels holding `sd^2`.
fn noisy(truth: &[Rgb], w: u32, h: u32, seed: u64, rel_sd: f32, offset_sigmas: f32) -> ExrImage {
    let mut rng = Rng::new(seed, 1);
    let mut mean = Vec::new();
    let mut var = Vec::new();
    for t in truth {
        let sd = t.map(|v| rel_sd * v.abs() + 1e-3);
        let mut m = Rgb::ZERO;
        for c in 0..3 {
            m.0[c] = t.0[c] + sd.0[c] * (offset_sigmas + normal(&mut rng) as f32);
        }
        mean.push(m);
        var.push(sd * sd);
    }
    let mut img = ExrImage::new(w, h);
    img.insert_rgb("", &mean);
    img.insert_rgb("variance", &var);
    img
}

#[test]
fn identical_images_have_zero_error_and_are_consistent() {
    let (w, h) = (32, 16);
    let a = noisy(&truth(w, h), w, h, 1, 0.1, 0.0);
    let c = compare(&a, &a).unwrap();
    assert_eq!(
        (c.rmse, c.rel_mse, c.mean_bias, c.max_abs_error),
        (0.0, 0.0, 0.0, 0.0)
    );
    assert_eq!(c.compared, u64::from(3 * w * h));
    let z = c.z_test.unwrap();
    assert!(z.consistent);
    assert_eq!(
        (z.frac_above_2, z.frac_above_3, z.mean_z, z.mean_z2),
        (0.0, 0.0, 0.0, 0.0)
    );
    assert_eq!(z.tested, u64::from(3 * w * h));
}

#[test]
fn metrics_follow_their_definitions() {
    let (w, h) = (3, 2);
    let mut a = ExrImage::new(w, h);
    let mut b = ExrImage::new(w, h);
    let av = [1.0f32, 2.0, 3.0, 4.0, 5.0, f32::NAN];
    let bv = [1.5f32, 2.0, 2.0, 0.0, 5.0, 1.0];
    a.channels.insert("Y".into(), av.to_vec());
    b.channels.insert("Y".into(), bv.to_vec());
    let c = compare(&a, &b).unwrap();
    assert_eq!(c.per_channel.len(), 1);
    assert_eq!(c.compared, 5);
    assert_eq!(c.skipped_non_finite, 1);
    let d: Vec<f64> = (0..5)
        .map(|i| f64::from(av[i]) - f64::from(bv[i]))
        .collect();
    let rmse = (d.iter().map(|d| d * d).sum::<f64>() / 5.0).sqrt();
    let rel = (0..5)
        .map(|i| d[i] * d[i] / (f64::from(bv[i]).powi(2) + 0.01))
        .sum::<f64>()
        / 5.0;
    assert!((c.rmse - rmse).abs() < 1e-12);
    assert!((c.rel_mse - rel).abs() < 1e-12);
    assert!((c.mean_bias - d.iter().sum::<f64>() / 5.0).abs() < 1e-12);
    assert_eq!(c.max_abs_error, 4.0);
    assert!(c.z_test.is_none(), "no variance channels, no z-test");
}

#[test]
fn unbiased_noisy_images_with_correct_variance_are_consistent() {
    let (w, h) = (64, 64);
    let t = truth(w, h);
    let a = noisy(&t, w, h, 11, 0.05, 0.0);
    let b = noisy(&t, w, h, 12, 0.02, 0.0);
    let c = compare(&a, &b).unwrap();
    let z = c.z_test.unwrap();
    let n = z.tested as f64;
    assert_eq!(n, 3.0 * 64.0 * 64.0);
    assert!(z.consistent, "{z:?}");
    // z ~ N(0, 1): mean z within 4 standard errors, mean z^2 within 4 (sd of z^2 is sqrt 2).
    assert!(z.mean_z.abs() < 4.0 / n.sqrt(), "{}", z.mean_z);
    assert!(
        (z.mean_z2 - 1.0).abs() < 4.0 * (2.0 / n).sqrt(),
        "{}",
        z.mean_z2
    );
    let sd3 = (P_ABOVE_3 * (1.0 - P_ABOVE_3) / n).sqrt();
    assert!(
        (z.frac_above_3 - P_ABOVE_3).abs() < 4.0 * sd3,
        "{}",
        z.frac_above_3
    );
    let sd2 = (P_ABOVE_2 * (1.0 - P_ABOVE_2) / n).sqrt();
    assert!(
        (z.frac_above_2 - P_ABOVE_2).abs() < 4.0 * sd2,
        "{}",
        z.frac_above_2
    );
}

#[test]
fn image_offset_by_five_sigma_is_inconsistent() {
    let (w, h) = (32, 32);
    let t = truth(w, h);
    let a = noisy(&t, w, h, 21, 0.05, 5.0); // sd of a is the whole sd of a - b below
    let mut b = ExrImage::new(w, h);
    b.insert_rgb("", &t);
    b.insert_rgb("variance", &vec![Rgb::ZERO; (w * h) as usize]);
    let z = compare(&a, &b).unwrap().z_test.unwrap();
    assert!(!z.consistent);
    assert!(z.frac_above_3 > 0.9, "{}", z.frac_above_3);
    assert!(z.tail_p_value < 1e-100);
    assert!(z.bias_z.iter().all(|&b| b > 100.0), "{:?}", z.bias_z);
}

#[test]
fn a_small_global_bias_is_caught_by_the_aggregate_test() {
    // 0.2 sigma everywhere: almost invisible in the tail count, obvious in aggregate.
    let (w, h) = (64, 64);
    let t = truth(w, h);
    let a = noisy(&t, w, h, 31, 0.05, 0.2);
    let mut b = ExrImage::new(w, h);
    b.insert_rgb("", &t);
    b.insert_rgb("variance", &vec![Rgb::ZERO; (w * h) as usize]);
    let z = compare(&a, &b).unwrap().z_test.unwrap();
    assert!(!z.consistent, "{z:?}");
    assert!(z.bias_p_value < 1e-6);
}

/// A film of `spp` exponential samples per pixel with mean `truth * scale`.
fn exponential_film(truth: &[Rgb], w: u32, h: u32, spp: u32, seed: u64, scale: f32) -> ExrImage {
    let mut film = Film::new(w, h).unwrap();
    for y in 0..h {
        for x in 0..w {
            let mut rng = Rng::new(seed, u64::from(y * w + x));
            let t = truth[(y * w + x) as usize];
            for _ in 0..spp {
                let e = -(1.0 - rng.next_f32()).ln();
                film.add_sample(
                    x,
                    y,
                    &PixelSample {
                        radiance: t * (e * scale),
                        albedo: Rgb::ONE,
                        normal: Vec3::Z,
                        depth: 1.0,
                        lights: [Rgb::ZERO; velour::film::MAX_LIGHT_LAYERS],
                    },
                );
            }
        }
    }
    film.to_exr_image(&Default::default())
}

#[test]
fn rendered_films_of_skewed_samples_are_consistent_and_a_ten_percent_bias_is_not() {
    // Exponential samples (skewness 2) at 16 spp: the z-scores follow Student's t, which the
    // test takes from the per-pixel sample counts.
    let (w, h) = (48, 48);
    let t = truth(w, h);
    let a = exponential_film(&t, w, h, 16, 1, 1.0);
    let b = exponential_film(&t, w, h, 16, 2, 1.0);
    let c = compare(&a, &b).unwrap();
    let z = c.z_test.unwrap();
    assert!(z.uses_sample_counts);
    assert!(z.consistent, "{z:?}");
    let biased = exponential_film(&t, w, h, 16, 3, 1.1);
    let z = compare(&biased, &b).unwrap().z_test.unwrap();
    assert!(!z.consistent, "{z:?}");
}

#[test]
fn size_mismatch_and_missing_layers_are_clear_errors() {
    let a = noisy(&truth(8, 4), 8, 4, 1, 0.1, 0.0);
    let b = noisy(&truth(4, 8), 4, 8, 1, 0.1, 0.0);
    let e = compare(&a, &b).unwrap_err();
    assert!(matches!(
        e,
        CompareError::SizeMismatch {
            wa: 8,
            ha: 4,
            wb: 4,
            hb: 8
        }
    ));
    assert!(
        e.to_string().contains("8x4") && e.to_string().contains("4x8"),
        "{e}"
    );
    let e = compare_layer(&a, &a, "albedo").unwrap_err();
    assert!(e.to_string().contains("albedo"), "{e}");
    let mut c = a.clone();
    c.channels.remove("G");
    let e = compare(&a, &c).unwrap_err();
    assert!(e.to_string().contains("channel G"), "{e}");
    // Layers other than the default are compared by their own channels.
    let cmp = compare_layer(&a, &a, "variance").unwrap();
    assert_eq!(cmp.per_channel[0].name, "variance.R");
}

#[test]
fn error_maps_use_z_scores_when_variances_exist_else_absolute_error() {
    let (w, h) = (16, 8);
    let t = truth(w, h);
    let a = noisy(&t, w, h, 5, 0.05, 0.0);
    let mut biased = a.clone();
    biased.channels.get_mut("R").unwrap()[3] += 1000.0;
    biased.channels.get_mut("G").unwrap()[4] -= 1000.0;
    let m = error_map(&biased, &a, "", None).unwrap();
    assert_eq!(m.mode, ErrorMapMode::ZScore);
    assert_eq!(
        (m.width, m.height, m.rgb8.len()),
        (w, h, (3 * w * h) as usize)
    );
    assert_eq!(&m.rgb8[0..3], &[0, 0, 0], "agreement is black");
    assert_eq!(&m.rgb8[9..12], &[255, 255, 0], "a >> b saturates to yellow");
    assert_eq!(&m.rgb8[12..15], &[0, 255, 255], "a << b saturates to cyan");

    let mut plain_a = ExrImage::new(w, h);
    let mut plain_b = ExrImage::new(w, h);
    plain_a.insert_rgb("", &t);
    let mut tb = t.clone();
    tb[7] += 0.5;
    plain_b.insert_rgb("", &tb);
    let m = error_map(&plain_a, &plain_b, "", Some(0.25)).unwrap();
    assert_eq!(m.mode, ErrorMapMode::AbsoluteError);
    assert_eq!(m.scale, 0.25);
    assert_eq!(
        &m.rgb8[21..24],
        &[255, 255, 255],
        "error beyond the scale is white"
    );
    assert_eq!(&m.rgb8[0..3], &[0, 0, 0]);
}

#[test]
fn distribution_tails_match_closed_forms() {
    assert!((normal_two_sided_tail(3.0) - P_ABOVE_3).abs() < 1e-12);
    assert!((normal_two_sided_tail(2.0) - P_ABOVE_2).abs() < 1e-12);
    assert!((normal_two_sided_tail(0.0) - 1.0).abs() < 1e-12);
    assert!((normal_two_sided_tail(6.0) - 1.973_175_290_075_2e-9).abs() < 1e-17);
    // Student's t with 1 degree of freedom is Cauchy; with 2, P(|T| > t) = 1 - t / sqrt(2 + t^2).
    for t in [0.5f64, 1.0, 3.0, 10.0] {
        let cauchy = 1.0 - 2.0 / std::f64::consts::PI * t.atan();
        assert!(
            (student_t_two_sided_tail(t, 1.0) - cauchy).abs() < 1e-10,
            "t {t}"
        );
        let t2 = 1.0 - t / (2.0 + t * t).sqrt();
        assert!(
            (student_t_two_sided_tail(t, 2.0) - t2).abs() < 1e-10,
            "t {t}"
        );
    }
    assert!((student_t_two_sided_tail(3.0, 1e6) - P_ABOVE_3).abs() < 1e-7);
    // Binomial upper tail against direct summation.
    let (n, p) = (40u64, 0.1f64);
    let mut pmf = vec![0.0f64; n as usize + 1];
    pmf[0] = (1.0 - p).powi(n as i32);
    for k in 1..=n as usize {
        pmf[k] = pmf[k - 1] * ((n as usize - k + 1) as f64 / k as f64) * (p / (1.0 - p));
    }
    for k in [0u64, 1, 4, 10, 20, 40] {
        let direct: f64 = pmf[k as usize..].iter().sum();
        let got = binomial_upper_tail(n, k, p);
        assert!(
            (got - direct).abs() < 1e-12 * direct.max(1e-300) + 1e-15,
            "k {k}: {got} vs {direct}"
        );
    }
    assert_eq!(binomial_upper_tail(5, 6, 0.5), 0.0);
}
