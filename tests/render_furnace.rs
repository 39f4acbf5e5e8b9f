//! End-to-end estimator checks on analytic scenes: white furnaces (a non-absorbing interior
//! under a uniform white environment returns exactly the environment), an absorbing sphere
//! against Beer–Lambert, and bit-identical images across thread counts.

mod common;

use std::path::Path;

use common::files::repo_path;
use common::render::{pixel_means, render_finite, scene_from_text};
use common::stats::Estimate;
use velour::film::Film;

/// Renders scene text read as if from `path` on `threads` threads, with no non-finite sample.
fn render_scene_at(text: &str, path: &Path, threads: usize) -> Film {
    render_finite(&scene_from_text(text, path), threads).0
}

fn render_scene(text: &str, threads: usize) -> Film {
    render_scene_at(text, Path::new("test.toml"), threads)
}

fn furnace_scene(surface: &str, nee: &str, g: f32) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 20
[film]
width = 24
height = 24
spp = 24
seed = 3
max_depth = 100000
[[light]]
type = "environment"
radiance = 1.0
[[object]]
name = "ball"
shape = "sphere"
radius = 1.0
{surface}
interior = {{ type = "homogeneous", albedo = 1.0, albedo_mode = "single", attenuation = [0.5, 0.25, 1.0], phase = {{ g = {g} }}, nee = "{nee}" }}
"#
    )
}

fn assert_furnace(text: &str, what: &str) {
    let film = render_scene(text, 0);
    assert_eq!((film.width(), film.height()), (24, 24));
    for c in 0..3 {
        // Mean over all pixels and its standard error (pixels are independent estimates).
        let e = Estimate::of(&pixel_means(&film, c));
        let (m, se) = (e.mean, e.standard_error);
        // The interior albedo is clamped to 1 − 1e-6 (a loss ≪ 1e-3 for these walks).
        assert!(
            (m - 1.0).abs() <= 4.5 * se + 2e-3,
            "{what}: channel {c}: mean {m} ± {se}, expected 1"
        );
    }
}

#[test]
fn white_furnace_index_matched_exit_nee() {
    assert_furnace(&furnace_scene("", "exit", 0.0), "index matched, exit NEE");
}

#[test]
fn white_furnace_index_matched_interior_nee() {
    assert_furnace(
        &furnace_scene("", "interior", 0.5),
        "index matched, interior NEE",
    );
}

#[test]
fn white_furnace_smooth_dielectric_conserves_energy() {
    assert_furnace(
        &furnace_scene(
            r#"surface = { type = "dielectric", ior = 1.5 }"#,
            "exit",
            0.0,
        ),
        "smooth dielectric",
    );
}

#[test]
fn absorbing_sphere_matches_beer_lambert() {
    // A narrow field of view: every camera ray crosses the sphere within 1e-3 of its centre,
    // so the chord is 2R (1 − O(1e-6)).
    let sigma = [0.3f32, 1.0, 2.5];
    let text = format!(
        r#"
[camera]
eye = [0, 0, 10]
look_at = [0, 0, 0]
fov = 0.005
[film]
width = 4
height = 4
spp = 4
[[light]]
type = "environment"
radiance = 1.0
[[object]]
name = "glass"
shape = "sphere"
radius = 1.0
interior = {{ type = "absorption", attenuation = [{}, {}, {}] }}
"#,
        1.0 / sigma[0],
        1.0 / sigma[1],
        1.0 / sigma[2]
    );
    let film = render_scene(&text, 0);
    for (c, &s) in sigma.iter().enumerate() {
        let expected = (-(s as f64) * 2.0).exp();
        for y in 0..4 {
            for x in 0..4 {
                let v = film.mean(x, y)[c] as f64;
                assert!(
                    (v - expected).abs() < 1e-4 * expected.max(1e-3),
                    "channel {c}: {v} vs {expected}"
                );
            }
        }
    }
}

#[test]
fn images_are_bit_identical_across_thread_counts() {
    let path = repo_path("scenes/skin_sphere.toml");
    let text = std::fs::read_to_string(&path).expect("scene");
    let text = text
        .replace("width = 320", "width = 40")
        .replace("height = 240", "height = 30")
        .replace("spp = 32", "spp = 4");
    let a = render_scene_at(&text, &path, 1);
    let b = render_scene_at(&text, &path, 2);
    let c = render_scene_at(&text, &path, 3);
    for y in 0..30 {
        for x in 0..40 {
            let (ma, mb, mc) = (a.mean(x, y), b.mean(x, y), c.mean(x, y));
            for k in 0..3 {
                assert_eq!(ma[k].to_bits(), mb[k].to_bits(), "pixel ({x},{y})");
                assert_eq!(ma[k].to_bits(), mc[k].to_bits(), "pixel ({x},{y})");
            }
        }
    }
}
