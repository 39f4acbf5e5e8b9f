//! Russian roulette's `[film]` settings (`roulette_depth`, `roulette_threshold`): roulette only
//! trades variance against cost, so a dense, bright medium renders the same image in
//! expectation at any threshold (per-pixel z-test and image means), while a lower threshold
//! lets paths run longer. Out-of-range settings are errors naming the key.

mod common;

use common::files::TempDir;
use common::render::{assert_images_agree, render_finite, scene_from_text};
use velour::film::Film;
use velour::render::RenderSummary;
use velour::scene::load_scene_str;

/// A dense fBm medium (albedo 0.95, σ_t ≤ 20 per unit density) in an index-matched sphere
/// under a sky and a sun: most of its light comes from high scattering orders, where roulette
/// plays.
fn scene(roulette: &str, spp: u32, seed: u64) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 28
[film]
width = 12
height = 12
spp = {spp}
seed = {seed}
max_depth = 512
{roulette}
[[light]]
type = "environment"
radiance = [0.3, 0.4, 0.5]
[[light]]
type = "distant"
direction = [0.5, 0.8, 0.3]
irradiance = [3.0, 2.8, 2.5]
[[object]]
name = "cloud"
shape = "sphere"
radius = 0.8
interior = {{ type = "fbm", voxel_size = 0.05, noise = {{ frequency = 1.5, octaves = 3, seed = 4 }}, albedo = 0.95, albedo_mode = "single", attenuation = 0.05, phase = {{ g = 0.5 }}, nee = "interior" }}
"#
    )
}

fn render(dir: &TempDir, text: &str) -> (Film, RenderSummary) {
    let scene = scene_from_text(text, dir.join("scene.toml"));
    render_finite(&scene, 0)
}

#[test]
fn any_roulette_threshold_renders_the_same_image_and_lower_ones_trace_longer_paths() {
    let dir = TempDir::new("roulette");
    let (strict, s_strict) = render(&dir, &scene("roulette_threshold = 1.0", 256, 1));
    let (lenient, s_lenient) = render(&dir, &scene("roulette_threshold = 0.2", 256, 2));
    let (late, s_late) = render(
        &dir,
        &scene("roulette_depth = 40\nroulette_threshold = 1.0", 256, 3),
    );
    eprintln!(
        "mean path length: threshold 1 {:.3}, threshold 0.2 {:.3}, depth 40 {:.3}",
        s_strict.mean_path_length, s_lenient.mean_path_length, s_late.mean_path_length
    );
    assert_images_agree(&strict, &lenient);
    assert_images_agree(&strict, &late);
    // Roulette at threshold 1 ends paths from depth 5 on; the others let them run on.
    assert!(s_lenient.mean_path_length > 1.05 * s_strict.mean_path_length);
    assert!(s_late.mean_path_length > 1.05 * s_strict.mean_path_length);
}

#[test]
fn out_of_range_roulette_settings_are_errors_naming_the_key() {
    for (line, key) in [
        ("roulette_threshold = 0.0", "film.roulette_threshold"),
        ("roulette_threshold = 1.5", "film.roulette_threshold"),
        ("roulette_threshold = nan", "film.roulette_threshold"),
        ("roulette_threshold = -0.5", "film.roulette_threshold"),
        ("roulette_depth = 2000000", "film.roulette_depth"),
    ] {
        let err = load_scene_str(&scene(line, 1, 1), std::path::Path::new("roulette.toml"))
            .err()
            .unwrap_or_else(|| panic!("{line} was accepted"))
            .to_string();
        assert!(err.contains(key), "{line}: {err}");
    }
}
