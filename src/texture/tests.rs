//! Unit tests of decoding, the pyramid and filtered lookups (docs/references.md §14.4).

use super::*;

/// The sRGB encoding (the inverse of [`srgb_to_linear`]).
fn linear_to_srgb(l: f32) -> f32 {
    if l <= 0.003_130_8 {
        l * 12.92
    } else {
        1.055 * l.powf(1.0 / 2.4) - 0.055
    }
}

fn tex(w: u32, h: u32, c: usize, texels: Vec<f32>, wrap: Wrap) -> Texture {
    texture_from_texels("test", w, h, c, texels, wrap).unwrap()
}

#[test]
fn srgb_decoding_matches_the_standard_and_round_trips() {
    assert_eq!(srgb_to_linear(0.0), 0.0);
    assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
    assert!((srgb_to_linear(128.0 / 255.0) - 0.2158).abs() < 1e-4);
    for i in 0..=255 {
        let c = i as f32 / 255.0;
        let back = linear_to_srgb(srgb_to_linear(c));
        assert!((back - c).abs() < 1e-5, "{i}: {back}");
    }
}

#[test]
fn a_constant_texture_gives_its_value_at_every_level_and_odd_sizes() {
    for (w, h) in [(1, 1), (7, 5), (13, 1), (16, 16), (33, 17)] {
        let t = tex(
            w,
            h,
            3,
            [0.25, 0.5, 0.75].repeat((w * h) as usize),
            Wrap::Repeat,
        );
        for level in 0..t.pyramid.level_count() {
            let l = t.pyramid.level(level);
            for v in &l.texels {
                assert!(v.is_finite() && *v >= 0.0);
            }
            for &(u, v) in &[(0.0, 0.0), (0.37, 0.91), (-2.3, 5.1), (0.999, 0.001)] {
                let c = t.pyramid.bilinear(level, Vec2::new(u, v), Wrap::Repeat);
                assert!((c - Rgb([0.25, 0.5, 0.75])).max_component().abs() < 1e-5);
                assert!((Rgb([0.25, 0.5, 0.75]) - c).max_component().abs() < 1e-5);
            }
        }
        for width in [0.0, 0.01, 0.3, 1.0, 10.0, f32::NAN, f32::INFINITY] {
            let c = t.eval(Vec2::new(0.4, 0.6), width);
            assert!((c.0[1] - 0.5).abs() < 1e-5, "{w}x{h} width {width}: {c:?}");
        }
        assert_eq!(
            t.pyramid.level_count(),
            1 + (w.max(h) as f32).log2().floor() as usize
        );
    }
}

#[test]
fn every_level_keeps_the_mean() {
    // Deterministic pseudo-random texels on odd and even sizes.
    for (w, h) in [(9u32, 7u32), (16, 16), (31, 4), (5, 40)] {
        let mut s = 12345u32;
        let texels: Vec<f32> = (0..w * h)
            .map(|_| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (s >> 8) as f32 / (1u32 << 24) as f32
            })
            .collect();
        let t = tex(w, h, 1, texels, Wrap::Clamp);
        let mean0 = t.mean().0[0];
        for level in 0..t.pyramid.level_count() {
            let l = t.pyramid.level(level);
            let m: f64 =
                l.texels.iter().map(|&v| f64::from(v)).sum::<f64>() / l.texels.len() as f64;
            assert!(
                (m as f32 - mean0).abs() < 1e-5,
                "{w}x{h} level {level}: {m} vs {mean0}"
            );
        }
        let top = t.pyramid.level(t.pyramid.level_count() - 1);
        assert_eq!((top.width, top.height), (1, 1));
        assert!(t.max().0[0] >= mean0);
    }
}

#[test]
fn wrap_modes() {
    // A 4 × 1 ramp 0, 1, 2, 3.
    let t = tex(4, 1, 1, vec![0.0, 1.0, 2.0, 3.0], Wrap::Repeat);
    for &u in &[0.1f32, 0.3, 0.62, 0.875] {
        let a = t.eval_scalar(Vec2::new(u, 0.5), 0.0);
        let b = t.eval_scalar(Vec2::new(u + 1.0, 0.5), 0.0);
        let c = t.eval_scalar(Vec2::new(u - 3.0, 0.5), 0.0);
        assert!(
            (a - b).abs() < 1e-5 && (a - c).abs() < 1e-4,
            "{u}: {a} {b} {c}"
        );
    }
    // Texel centres read exactly.
    assert!((t.eval_scalar(Vec2::new(0.375, 0.5), 0.0) - 1.0).abs() < 1e-6);
    // Repeat blends the last texel into the first across u = 0.
    assert!((t.eval_scalar(Vec2::new(0.0, 0.5), 0.0) - 1.5).abs() < 1e-6);
    let c = tex(4, 1, 1, vec![0.0, 1.0, 2.0, 3.0], Wrap::Clamp);
    assert!((c.eval_scalar(Vec2::new(0.0, 0.5), 0.0)).abs() < 1e-6);
    assert!((c.eval_scalar(Vec2::new(-5.0, 0.5), 0.0)).abs() < 1e-6);
    assert!((c.eval_scalar(Vec2::new(7.0, 0.5), 0.0) - 3.0).abs() < 1e-6);
}

#[test]
fn v_runs_bottom_to_top() {
    // Top row 1, bottom row 0.
    let t = tex(1, 2, 1, vec![1.0, 0.0], Wrap::Clamp);
    assert!((t.eval_scalar(Vec2::new(0.5, 0.9), 0.0) - 1.0).abs() < 1e-6);
    assert!(t.eval_scalar(Vec2::new(0.5, 0.1), 0.0).abs() < 1e-6);
}

#[test]
fn a_checker_at_a_coarse_level_gives_the_mean() {
    let n = 64u32;
    let texels: Vec<f32> = (0..n * n)
        .map(|i| {
            if ((i % n) / 4 + (i / n) / 4).is_multiple_of(2) {
                1.0
            } else {
                0.0
            }
        })
        .collect();
    let t = tex(n, n, 1, texels, Wrap::Repeat);
    // At full resolution the checker shows.
    let fine = t.eval_scalar(Vec2::new(2.0 / 64.0, 1.0 - 2.0 / 64.0), 0.0);
    assert!((fine - 1.0).abs() < 1e-6);
    // A footprint of 8 texels (one period) or more reads 0.5 everywhere.
    for &(u, v) in &[(0.1f32, 0.2f32), (0.33, 0.77), (0.5, 0.5), (0.9, 0.01)] {
        for width in [8.0 / 64.0, 16.0 / 64.0, 1.0, 4.0] {
            let c = t.eval_scalar(Vec2::new(u, v), width);
            assert!((c - 0.5).abs() < 1e-5, "({u}, {v}) width {width}: {c}");
        }
    }
    // Trilinear between levels is monotone in the level weight at one point.
    assert!((t.pyramid.level_for_width(8.0) - 3.0).abs() < 1e-6);
    assert_eq!(t.pyramid.level_for_width(0.5), 0.0);
    assert_eq!(t.pyramid.level_for_width(1e9), 6.0);
}

#[test]
fn bad_texels_name_the_pixel() {
    let e = texture_from_texels(
        "t.exr",
        3,
        2,
        1,
        vec![0.0, 0.0, 0.0, 0.0, f32::NAN, 0.0],
        Wrap::Repeat,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("t.exr") && e.contains("(1, 1)") && e.contains("NaN"),
        "{e}"
    );
    let e = texture_from_texels(
        "t.exr",
        2,
        1,
        3,
        vec![0.0, 0.0, 0.0, 0.0, -1.0, 0.0],
        Wrap::Repeat,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("(1, 0)") && e.contains("negative") && e.contains("channel G"),
        "{e}"
    );
}

#[test]
fn range_checks_name_the_pixel() {
    let t = tex(2, 2, 1, vec![0.0, 0.5, 1.0, 1.5], Wrap::Repeat);
    let e = t.check_range(0.0, 1.0, "mask").unwrap_err().to_string();
    assert!(
        e.contains("(1, 1)") && e.contains("1.5") && e.contains("mask"),
        "{e}"
    );
    assert!(tex(1, 1, 1, vec![1.0], Wrap::Repeat)
        .check_range(0.0, 1.0, "m")
        .is_ok());
}
