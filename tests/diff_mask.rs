//! `velour diff --mask`: metrics restricted to the white pixels of a PNG, and the relative RMSE
//! (per-pixel form and RMSE over the mean) that the first-image measurement uses.

mod common;

use common::cli::{run_velour, Captured};
use common::files::TempDir;
use std::ffi::OsStr;
use velour::image_io::compare::{compare_layer_masked, PixelMask};
use velour::image_io::{write_exr, write_png_rgb8, CompareError, ExrImage};
use velour::spectrum::Rgb;

const W: u32 = 8;
const H: u32 = 4;

/// Reference: a ramp. Test image: 10 % brighter on the left half, wildly wrong on the right.
fn images() -> (ExrImage, ExrImage) {
    let mut refp = Vec::new();
    let mut test = Vec::new();
    for y in 0..H {
        for x in 0..W {
            let b = Rgb::new(0.5 + 0.1 * x as f32, 0.25 + 0.05 * y as f32, 1.0 + x as f32);
            refp.push(b);
            test.push(if x < W / 2 { b * 1.1 } else { b * 3.0 });
        }
    }
    let mut a = ExrImage::new(W, H);
    a.insert_rgb("", &test);
    let mut b = ExrImage::new(W, H);
    b.insert_rgb("", &refp);
    (a, b)
}

/// White on the left half, black on the right, one light-grey (counted) and one magenta (not
/// counted) pixel.
fn left_half_rgb8() -> Vec<u8> {
    let mut px = Vec::new();
    for _y in 0..H {
        for x in 0..W {
            px.extend_from_slice(if x < W / 2 {
                &[255, 255, 255]
            } else {
                &[0, 0, 0]
            });
        }
    }
    px[0..3].copy_from_slice(&[200, 200, 200]);
    let last = 3 * (W * H) as usize - 3;
    px[last..].copy_from_slice(&[255, 0, 255]);
    px
}

#[test]
fn mask_restricts_metrics_to_white_pixels() {
    let (a, b) = images();
    let mask = PixelMask::from_rgb8(W, H, &left_half_rgb8()).unwrap();
    assert_eq!(mask.counted_pixels(), u64::from(W * H / 2));
    let c = compare_layer_masked(&a, &b, "", Some(&mask)).unwrap();
    assert_eq!(c.masked_out, u64::from(W * H / 2));
    assert_eq!(c.compared, 3 * u64::from(W * H / 2));
    // Every counted pixel-channel is exactly 10 % off: both relative forms are 0.1.
    assert!((c.rel_rmse - 0.1).abs() < 1e-6, "{}", c.rel_rmse);
    for ch in &c.per_channel {
        assert!((ch.rel_rmse - 0.1).abs() < 1e-6, "{ch:?}");
    }
    // The looser form weighs bright pixels more: for R (0.5, 0.6, 0.7, 0.8 in each row),
    // RMSE = 0.1 sqrt(mean(b^2)) and RMSE / mean(b) = 0.1 sqrt(0.435) / 0.65.
    let r = &c.per_channel[0];
    let expect_r = 0.1 * 0.435f64.sqrt() / 0.65;
    assert!((r.rmse / r.mean_reference - expect_r).abs() < 1e-6, "{r:?}");
    // Mean of the reference over the left half, all channels: R 0.65, G 0.325, B 2.5.
    let expect = (0.65 + 0.325 + 2.5) / 3.0;
    assert!(
        (c.mean_reference - expect).abs() < 1e-6,
        "{}",
        c.mean_reference
    );

    // Without the mask the right half's error (relative 2.0) dominates.
    let all = compare_layer_masked(&a, &b, "", None).unwrap();
    assert_eq!(all.masked_out, 0);
    let strict = ((0.1f64 * 0.1 + 2.0 * 2.0) / 2.0).sqrt();
    assert!((all.rel_rmse - strict).abs() < 1e-5, "{}", all.rel_rmse);
}

#[test]
fn mask_of_another_size_is_an_error() {
    let (a, b) = images();
    let mask = PixelMask::from_flags(W, H + 1, vec![true; (W * (H + 1)) as usize]).unwrap();
    let e = compare_layer_masked(&a, &b, "", Some(&mask)).unwrap_err();
    assert!(matches!(e, CompareError::MaskSize { .. }), "{e}");
    assert!(e.to_string().contains("8x5"), "{e}");
    assert!(PixelMask::from_flags(W, H, vec![true; 3]).is_none());
    assert!(PixelMask::from_rgb8(W, H, &[0; 5]).is_none());
}

/// `velour diff ARGS`.
fn diff(args: &[&OsStr]) -> Captured {
    run_velour(std::iter::once(OsStr::new("diff")).chain(args.iter().copied()))
}

#[test]
fn diff_cli_mask_option() {
    let dir = TempDir::new("diff-mask");
    let (a_path, b_path, mask_path) = (dir.join("a.exr"), dir.join("b.exr"), dir.join("m.png"));
    let (a, b) = images();
    write_exr(&a_path, &a).unwrap();
    write_exr(&b_path, &b).unwrap();
    write_png_rgb8(&mask_path, W, H, &left_half_rgb8()).unwrap();

    let out = diff(&[
        a_path.as_os_str(),
        b_path.as_os_str(),
        "--mask".as_ref(),
        mask_path.as_os_str(),
        "--json".as_ref(),
    ]);
    out.assert_success();
    let json: serde_json::Value = serde_json::from_str(&out.stdout).unwrap();
    assert_eq!(json["masked_out"], W * H / 2);
    assert!((json["rel_rmse"].as_f64().unwrap() - 0.1).abs() < 1e-6);
    assert!(json["mask"].as_str().unwrap().ends_with("m.png"));

    let out = diff(&[
        a_path.as_os_str(),
        b_path.as_os_str(),
        "--mask".as_ref(),
        mask_path.as_os_str(),
    ]);
    out.assert_success();
    assert!(
        out.stdout.contains("16 of 32 pixels compared") && out.stdout.contains("relative RMSE"),
        "{}",
        out.stdout
    );

    // A missing mask and a mask of the wrong size are errors naming the problem.
    let out = diff(&[
        a_path.as_os_str(),
        b_path.as_os_str(),
        "--mask".as_ref(),
        dir.join("nope.png").as_os_str(),
    ]);
    out.assert_failure_mentioning(&["nope.png"]);
    let small = dir.join("small.png");
    write_png_rgb8(&small, 2, 2, &[255; 12]).unwrap();
    let out = diff(&[
        a_path.as_os_str(),
        b_path.as_os_str(),
        "--mask".as_ref(),
        small.as_os_str(),
    ]);
    out.assert_failure_mentioning(&["mask is 2x2"]);

    let help = run_velour(["diff", "--help"]);
    help.assert_success();
    assert!(help.stdout.contains("--mask"), "{}", help.stdout);
}
