//! What lies behind a thin medium, estimated by transmittance (`tracking.behind`,
//! docs/choosing-estimators.md): the image agrees with plain delta tracking's (the path
//! survives the free flight or dies) by per-pixel z-test and in its mean, with the environment,
//! a sphere light and a surface behind the cloud; it has far less variance per sample where the
//! sky is seen through the cloud; `auto` picks it for thin media only; bad values are refused.

mod common;

use std::collections::BTreeMap;

use common::render::{region_mean, render_finite, scene_from_text};
use velour::film::Film;
use velour::image_io::compare::compare;
use velour::scene::load_scene_str;

/// A thin fBm cloud (σ_t ≤ `sigma` per unit density, single-scattering albedo 0.9) in an
/// index-matched sphere under a sky and a sun, with `extra` appended (more lights or objects).
fn cloud(behind: &str, sigma: f32, spp: u32, extra: &str) -> String {
    medium(behind, sigma, 0.9, "[0.25, 0.35, 0.55]", spp, extra)
}

/// Dark smoke (albedo 0.2, σ_t ≤ 2) in front of a bright sky.
fn smoke(behind: &str, spp: u32) -> String {
    medium(behind, 2.0, 0.2, "[1.0, 1.1, 1.3]", spp, "")
}

fn medium(behind: &str, sigma: f32, albedo: f32, sky: &str, spp: u32, extra: &str) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 24
[film]
width = 16
height = 16
spp = {spp}
max_depth = 64
[[light]]
type = "environment"
radiance = {sky}
[[light]]
type = "distant"
direction = [0.5, 0.8, 0.3]
irradiance = [3.0, 2.8, 2.5]
[[object]]
name = "cloud"
shape = "sphere"
radius = 0.8
interior = {{ type = "fbm", voxel_size = 0.05, noise = {{ frequency = 1.5, octaves = 3, seed = 4 }}, albedo = {albedo}, albedo_mode = "single", attenuation = {att}, phase = {{ g = 0.5 }}, nee = "interior"{tracking} }}
{extra}
"#,
        att = 1.0 / sigma,
        tracking = if behind.is_empty() {
            String::new()
        } else {
            format!(", tracking = {{ behind = \"{behind}\" }}")
        },
    )
}

fn render(text: &str, seed: u64) -> (Film, velour::render::RenderSummary) {
    let mut scene = scene_from_text(text, "behind.toml");
    scene.film.seed = seed;
    render_finite(&scene, 0)
}

/// The mean over pixels of each pixel's variance of one sample (channel `c`).
fn variance_per_sample(film: &Film, spp: u32, c: usize) -> f64 {
    let (mut sum, mut n) = (0.0, 0.0);
    for y in 0..film.height() {
        for x in 0..film.width() {
            sum += f64::from(film.variance_of_mean(x, y)[c]) * f64::from(spp);
            n += 1.0;
        }
    }
    sum / n
}

/// Both renders agree per pixel (z-test) and in their image means per channel (|z| < 4).
fn assert_agree(a: &Film, b: &Film, what: &str) {
    let cmp = compare(
        &a.to_exr_image(&BTreeMap::new()),
        &b.to_exr_image(&BTreeMap::new()),
    )
    .expect("compare");
    let z = cmp.z_test.expect("variance layers");
    assert!(z.consistent, "{what}: per-pixel z-test fails: {z:?}");
    for c in 0..3 {
        let (ma, sa) = region_mean(a, c, |_, _| true);
        let (mb, sb) = region_mean(b, c, |_, _| true);
        let zc = (ma - mb) / (sa * sa + sb * sb).sqrt();
        eprintln!("{what}: channel {c}: {ma:.5} ± {sa:.5} against {mb:.5} ± {sb:.5} (z = {zc:.2})");
        assert!(
            zc.abs() < 4.0,
            "{what}: channel {c} means differ: z = {zc:.2}"
        );
    }
}

#[test]
fn transmittance_behind_agrees_with_survival_on_a_bright_cloud() {
    let (survive, _) = render(&cloud("survive", 2.0, 256, ""), 1);
    let (estimate, _) = render(&cloud("transmittance", 2.0, 256, ""), 2);
    assert_agree(&survive, &estimate, "environment behind");
}

#[test]
fn transmittance_behind_cuts_the_variance_of_dark_smoke_against_the_sky() {
    let spp = 256;
    let (survive, s_sum) = render(&smoke("survive", spp), 1);
    let (estimate, e_sum) = render(&smoke("transmittance", spp), 2);
    assert_agree(&survive, &estimate, "smoke");
    // The sky seen through the smoke is what the survival estimate spends its variance on.
    for c in 0..3 {
        let vs = variance_per_sample(&survive, spp, c);
        let ve = variance_per_sample(&estimate, spp, c);
        eprintln!(
            "channel {c}: variance per sample {vs:.3e} (survive) against {ve:.3e} (transmittance)"
        );
        assert!(
            ve * 2.0 < vs,
            "channel {c}: transmittance behind should cut the variance per sample at least 2×: {ve:.3e} against {vs:.3e}"
        );
    }
    // It costs lookups: the transmittance estimate to the boundary.
    assert!(e_sum.tracking.lookups > s_sum.tracking.lookups);
}

#[test]
fn a_sphere_light_behind_the_cloud_is_seen_through_it() {
    // No sky: only the sun and a sphere light behind the cloud, seen through it.
    let extra = r#"
[[light]]
type = "sphere"
center = [0.2, 0.1, -2.0]
radius = 0.5
radiance = [6.0, 5.0, 4.0]
"#;
    let no_sky = |behind| medium(behind, 2.0, 0.9, "[0.0, 0.0, 0.0]", 128, extra);
    let (survive, _) = render(&no_sky("survive"), 3);
    let (estimate, _) = render(&no_sky("transmittance"), 4);
    assert_agree(&survive, &estimate, "sphere light behind");
    // The light is in the picture, through the cloud.
    let (m, _) = region_mean(&estimate, 0, |x, y| {
        (7..=10).contains(&x) && (6..=9).contains(&y)
    });
    assert!(
        m > 0.5,
        "the sphere light should be seen through the cloud: {m}"
    );
}

#[test]
fn a_surface_behind_the_cloud_falls_back_to_survival() {
    let extra = r#"
[[object]]
name = "wall"
shape = "sphere"
center = [0, 0, -6]
radius = 4.5
surface = { type = "lambertian", reflectance = 0.6 }
"#;
    let (survive, _) = render(&cloud("survive", 2.0, 128, extra), 5);
    let (estimate, _) = render(&cloud("transmittance", 2.0, 128, extra), 6);
    assert_agree(&survive, &estimate, "wall behind");
}

#[test]
fn the_default_is_to_survive() {
    // The same seed: the default renders exactly like `behind = "survive"`.
    let bits = |text: &str| {
        let (film, _) = render(text, 7);
        let img = film.to_exr_image(&BTreeMap::new());
        img.channels
            .into_iter()
            .map(|(k, v)| (k, v.into_iter().map(f32::to_bits).collect::<Vec<_>>()))
            .collect::<BTreeMap<_, _>>()
    };
    assert_eq!(bits(&smoke("", 4)), bits(&smoke("survive", 4)));
    assert_ne!(bits(&smoke("", 4)), bits(&smoke("transmittance", 4)));
}

#[test]
fn unknown_behind_values_are_refused() {
    let err = load_scene_str(
        &cloud("through", 2.0, 4, ""),
        std::path::Path::new("behind.toml"),
    )
    .expect_err("a misspelt value must be refused");
    let msg = err.to_string();
    assert!(msg.contains("behind") && msg.contains("through"), "{msg}");
}
