//! `velour diff` end to end: the binary on EXR files written by the film.

mod common;

use common::cli::{run_velour, Captured};
use common::files::TempDir;
use velour::film::{Film, PixelSample};
use velour::math::Vec3;
use velour::sampling::Rng;
use velour::spectrum::Rgb;

fn render(path: &std::path::Path, w: u32, h: u32, seed: u64, scale: f32) {
    let mut film = Film::new(w, h).unwrap();
    for y in 0..h {
        for x in 0..w {
            let mut rng = Rng::new(seed, u64::from(y * w + x));
            for _ in 0..32 {
                let v = rng.next_f32() * scale * (1.0 + x as f32 / w as f32);
                film.add_sample(
                    x,
                    y,
                    &PixelSample {
                        radiance: Rgb::new(v, 0.5 * v, 0.25),
                        albedo: Rgb::splat(0.5),
                        normal: Vec3::Y,
                        depth: 3.0,
                        lights: [Rgb::ZERO; velour::film::MAX_LIGHT_LAYERS],
                    },
                );
            }
        }
    }
    film.write_exr(path).unwrap();
}

/// `velour diff ARGS`.
fn velour(args: &[&std::ffi::OsStr]) -> Captured {
    run_velour(std::iter::once("diff".as_ref()).chain(args.iter().copied()))
}

#[test]
fn diff_json_report_and_error_png() {
    let dir = TempDir::new("diff-cli");
    let (a, b, c, png) = (
        dir.join("a.exr"),
        dir.join("b.exr"),
        dir.join("c.exr"),
        dir.join("err.png"),
    );
    render(&a, 24, 16, 1, 1.0);
    render(&b, 24, 16, 2, 1.0);
    render(&c, 24, 16, 3, 1.3);

    let out = velour(&[
        a.as_os_str(),
        b.as_os_str(),
        "--json".as_ref(),
        "--error-png".as_ref(),
        png.as_os_str(),
    ]);
    out.assert_success();
    let json: serde_json::Value = serde_json::from_str(&out.stdout).unwrap();
    assert_eq!(json["width"], 24);
    assert_eq!(json["height"], 16);
    assert_eq!(json["verdict"], "consistent");
    assert_eq!(json["per_channel"].as_array().unwrap().len(), 3);
    assert!(json["rmse"].as_f64().unwrap() > 0.0);
    assert_eq!(json["z_test"]["uses_sample_counts"], true);
    assert_eq!(json["error_png"]["mode"], "ZScore");
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (24, 16));

    // A biased image: inconsistent, and --check turns that into a failure.
    let out = velour(&[c.as_os_str(), b.as_os_str(), "--json".as_ref()]);
    assert!(out.success());
    let json: serde_json::Value = serde_json::from_str(&out.stdout).unwrap();
    assert_eq!(json["verdict"], "inconsistent");
    let out = velour(&[c.as_os_str(), b.as_os_str(), "--check".as_ref()]);
    assert!(!out.success());
    let text = &out.stdout;
    assert!(
        text.contains("INCONSISTENT") && text.contains("RMSE"),
        "{text}"
    );

    // Another layer, human-readable.
    let out = velour(&[
        a.as_os_str(),
        b.as_os_str(),
        "--layer".as_ref(),
        "albedo".as_ref(),
    ]);
    assert!(out.success());
    let text = &out.stdout;
    assert!(
        text.contains("albedo.R") && text.contains("not run"),
        "{text}"
    );
}

#[test]
fn diff_errors_are_reported_not_panicked() {
    let dir = TempDir::new("diff-cli-errors");
    let (a, small, junk) = (
        dir.join("ea.exr"),
        dir.join("esmall.exr"),
        dir.join("junk.exr"),
    );
    render(&a, 8, 8, 1, 1.0);
    render(&small, 4, 8, 1, 1.0);
    std::fs::write(&junk, b"v/1\x01 this is not an exr").unwrap();
    for (x, y, expect) in [
        (&a, &small, "differ in size"),
        (&a, &junk, "junk.exr"),
        (&a, &dir.join("missing.exr"), "missing.exr"),
    ] {
        let out = velour(&[x.as_os_str(), y.as_os_str()]);
        assert_eq!(out.status.code(), Some(1));
        out.assert_failure_mentioning(&[expect]);
    }
    let out = velour(&[
        a.as_os_str(),
        a.as_os_str(),
        "--layer".as_ref(),
        "nope".as_ref(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(out.stderr.contains("nope"));
}
