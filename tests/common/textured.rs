//! Scene text and files shared by the textured-interior render tests
//! (`render_textured_fields`, `render_textured_mixture`): a unit sphere under an environment and
//! a distant light, a stepped 16³ density grid, fBm keys, and scene-loading helpers for the
//! bad-input checks.

use glam::{DAffine3, DVec3, IVec3, Vec3};
use velour::film::Film;
use velour::grid::{ChannelKind, SparseGridBuilder, Storage};
use velour::scene::load_scene_str;
use velour::texture::srgb_to_linear;
use velour::vdb::{write_vdb, GridToWrite, WriteOptions};

use super::files::TempDir;
use super::render::image_mean;
use super::stats::{assert_means_agree, z_score};

pub const FOV: f32 = 36.0;

pub fn head(spp: u32, seed: u32) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = {FOV}
[film]
width = 16
height = 16
spp = {spp}
seed = {seed}
max_depth = 100000
[[light]]
type = "environment"
radiance = 1.0
[[light]]
type = "distant"
direction = [0.5, 0.6, 0.6]
irradiance = 2.0
"#
    )
}

/// A unit sphere (no boundary surface: index-matched) filled with `interior`.
pub fn ball(interior: &str, spp: u32, seed: u32) -> String {
    format!(
        "{}[[object]]\nname = \"ball\"\nshape = \"sphere\"\ninterior = {interior}\n",
        head(spp, seed)
    )
}

/// `density.vdb`: a 16³ grid over [−1.5, 1.5]³ whose density steps between 0.3, 0.65 and 1.
pub fn write_voxels(dir: &TempDir) {
    let n = 16;
    let mut b = SparseGridBuilder::new(Storage::F32);
    let c = b.add_channel("v", ChannelKind::Scalar, Vec3::ZERO);
    let voxel = 3.0 / f64::from(n - 1);
    b.set_index_to_world(
        DAffine3::from_translation(DVec3::splat(-1.5)) * DAffine3::from_scale(DVec3::splat(voxel)),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let v = 0.3 + 0.35 * ((x + 2 * y + z) % 3) as f32;
                b.set_value(c, IVec3::new(x, y, z), v)
                    .unwrap_or_else(|e| panic!("{e}"));
            }
        }
    }
    let grid = b.build();
    let list = [GridToWrite {
        class: "fog volume",
        ..GridToWrite::new("density", &grid)
    }];
    write_vdb(dir.join("density.vdb"), &list, &WriteOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
}

pub const FBM: &str = r#"type = "fbm", noise = { frequency = 3.0, offset = 0.4, amplitude = 1.0 }, voxel_size = 0.05"#;

pub fn lin(v: u8) -> f32 {
    srgb_to_linear(f32::from(v) / 255.0)
}

/// Asserts the image means agree per channel, printing the z values.
pub fn assert_images_agree(t: &Film, c: &Film, what: &str) {
    for ch in 0..3 {
        let (a, b) = (image_mean(t, ch), image_mean(c, ch));
        eprintln!(
            "{what}, channel {ch}: {:.5} ± {:.5} vs {:.5} ± {:.5}, z = {:.2}",
            a.0,
            a.1,
            b.0,
            b.1,
            z_score(a.0, b.0, (a.1 * a.1 + b.1 * b.1).sqrt())
        );
        assert_means_agree(a, b, &format!("{what}, channel {ch}"));
    }
}

pub const HEAD: &str =
    "[camera]\neye = [0, 0, 4]\nlook_at = [0, 0, 0]\n\n[film]\nwidth = 8\nheight = 8\n";

pub fn load(dir: &TempDir, body: &str) -> Result<velour::scene::Scene, String> {
    load_scene_str(&format!("{HEAD}{body}"), &dir.join("scene.toml")).map_err(|e| e.to_string())
}

pub fn err(dir: &TempDir, body: &str) -> String {
    match load(dir, body) {
        Ok(_) => panic!("scene loaded but should fail:\n{body}"),
        Err(e) => e,
    }
}

pub fn assert_mentions(e: &str, needles: &[&str]) {
    for n in needles {
        assert!(e.contains(n), "error does not mention {n:?}: {e}");
    }
}

pub fn sphere_with(interior: &str) -> String {
    format!("[[object]]\nname = \"ball\"\nshape = \"sphere\"\ninterior = {interior}\n")
}
