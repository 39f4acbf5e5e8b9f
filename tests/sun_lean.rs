//! The sun-leaned estimate of the next vertex's sun light (`tracking.sun_lean`, on by
//! default): at each medium vertex one extra direction from a Henyey–Greenstein lobe centred
//! on the sun, a free flight along it and the sun's NEE where it collides, balance-weighted
//! against the path's own sun NEE at its next vertex. The image must not change in
//! expectation: a thin forward-scattering cloud under a dim sky and a sun renders the same
//! image, per pixel (z-test) and in its means, with `sun_lean = false`; and with less
//! variance (the noise of such a cloud is the second vertex's sun light).

mod common;

use common::files::TempDir;
use common::render::{assert_images_agree, render_text, total_variance};

/// An optically thin fBm cloud (σ_t ≤ 2 per unit, albedo 0.9, HG g = 0.6) in an index-matched
/// sphere with NEE at every vertex, under a dim constant sky and a bright sun.
fn scene(sun_lean: bool, spp: u32, seed: u64) -> String {
    cloud(sun_lean, 0.5, spp, seed)
}

/// The same cloud with `attenuation` (1 / σ_t at density 1): 0.5 is the thin cloud, 0.025 a
/// dense one (σ_t ≤ 40 per unit, as the dense peer cloud).
fn cloud(sun_lean: bool, attenuation: f32, spp: u32, seed: u64) -> String {
    format!(
        r#"
[camera]
eye = [0, 0.3, 3.2]
look_at = [0, 0, 0]
fov = 32
[film]
width = 16
height = 16
spp = {spp}
seed = {seed}
max_depth = 64
[[light]]
type = "environment"
radiance = [0.05, 0.06, 0.08]
[[light]]
type = "distant"
direction = [-0.5, 0.8, 0.4]
irradiance = [5.0, 4.6, 4.1]
[[object]]
name = "cloud"
shape = "sphere"
radius = 0.9
interior = {{ type = "fbm", voxel_size = 0.05, noise = {{ frequency = 1.5, octaves = 3, seed = 4 }}, albedo = 0.9, albedo_mode = "single", attenuation = {attenuation}, phase = {{ g = 0.6 }}, nee = "interior", tracking = {{ sun_lean = {sun_lean} }} }}
"#
    )
}

#[test]
fn the_sun_leaned_estimate_renders_the_same_image_with_less_variance() {
    let dir = TempDir::new("sun_lean");
    let lean = render_text(&scene(true, 384, 1), dir.path());
    let plain = render_text(&scene(false, 384, 2), dir.path());
    assert_images_agree(&lean, &plain);
    let (vl, vp) = (total_variance(&lean), total_variance(&plain));
    eprintln!("variance of the pixel means: lean {vl:.4e}, plain {vp:.4e}");
    assert!(vl < 0.8 * vp, "no less variance: {vl:.4e} against {vp:.4e}");
}

/// In a dense cloud most vertices lie where the sun is hidden: there the lean is played only
/// with a probability below 1 (from the vertex's own sun shadow-ray estimate) and its estimate
/// is divided by it, and the balance weights use that probability times the lobe's pdf. Same
/// image as without the lean (per pixel and in the means).
#[test]
fn the_lean_played_by_chance_in_a_dense_cloud_renders_the_same_image() {
    let dir = TempDir::new("sun_lean_dense");
    let lean = render_text(&cloud(true, 0.025, 256, 3), dir.path());
    let plain = render_text(&cloud(false, 0.025, 256, 4), dir.path());
    assert_images_agree(&lean, &plain);
    let (vl, vp) = (total_variance(&lean), total_variance(&plain));
    eprintln!("dense: variance of the pixel means: lean {vl:.4e}, plain {vp:.4e}");
}
