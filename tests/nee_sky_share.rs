//! The sky's share of next event estimation: a constant environment beside other lights is
//! chosen for NEE at a tenth of its power share (the phase function's and the BSDF's own
//! sampling reach it, MIS-weighted on escape). The image must not change in expectation: a
//! cloud and a diffuse sphere under a constant sky and a sun agree, per pixel (z-test) and in
//! their means, with the same scene whose sky is an environment map of the same constant
//! radiance (chosen at its full power share).

mod common;

use common::files::TempDir;
use common::render::{assert_images_agree, render_finite, scene_from_text};
use velour::film::Film;
use velour::image_io::{write_exr, ExrImage};

const SKY: [f32; 3] = [0.25, 0.35, 0.55];

/// An fBm cloud (albedo 0.9, σ_t ≤ 6 per unit density) in an index-matched sphere with NEE at
/// every interior vertex, and a diffuse sphere beside it, under `sky` and a sun.
fn scene(sky: &str, spp: u32, seed: u64) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0.2, 0, 0]
fov = 30
[film]
width = 16
height = 16
spp = {spp}
seed = {seed}
max_depth = 64
{sky}
[[light]]
type = "distant"
direction = [0.5, 0.8, 0.3]
irradiance = [3.0, 2.8, 2.5]
[[object]]
name = "cloud"
shape = "sphere"
radius = 0.8
interior = {{ type = "fbm", voxel_size = 0.05, noise = {{ frequency = 1.5, octaves = 3, seed = 4 }}, albedo = 0.9, albedo_mode = "single", attenuation = {att}, phase = {{ g = 0.5 }}, nee = "interior" }}
[[object]]
name = "ball"
shape = "sphere"
center = [1.1, -0.4, 0.3]
radius = 0.35
surface = {{ type = "lambertian", reflectance = 0.6 }}
"#,
        att = 1.0 / 6.0,
    )
}

fn constant_sky() -> String {
    format!(
        "[[light]]\ntype = \"environment\"\nradiance = [{}, {}, {}]",
        SKY[0], SKY[1], SKY[2]
    )
}

fn map_sky() -> &'static str {
    "[[light]]\ntype = \"envmap\"\nfile = \"sky.exr\""
}

fn render(dir: &TempDir, text: &str) -> Film {
    let scene = scene_from_text(text, dir.join("scene.toml"));
    render_finite(&scene, 0).0
}

/// A lat-long map of the constant sky radiance.
fn write_sky(dir: &TempDir) {
    let mut img = ExrImage::new(16, 8);
    for (c, v) in ["R", "G", "B"].iter().zip(SKY) {
        img.channels.insert((*c).to_string(), vec![v; 128]);
    }
    write_exr(&dir.join("sky.exr"), &img).expect("write sky.exr");
}

#[test]
fn a_constant_sky_with_a_smaller_nee_share_renders_the_same_image() {
    let dir = TempDir::new("nee_sky_share");
    write_sky(&dir);
    let constant = render(&dir, &scene(&constant_sky(), 512, 1));
    let map = render(&dir, &scene(map_sky(), 512, 2));
    assert_images_agree(&constant, &map);
}
