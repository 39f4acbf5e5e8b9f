//! `projection = "surface"` in renders (z-tests on image and region means with standard
//! errors from the renders' own per-pixel variances, fixed and independent seeds):
//! - with textures of one value, surface projection renders like entry projection and like
//!   the untextured constant interior, behind a rough and behind an index-matched boundary
//!   (the spectral trackers against the textures' majorant are unbiased; per-channel
//!   attenuations exercise null collisions in the other channels; behind the index-matched
//!   boundary shadow rays from interior vertices are ratio-tracked);
//! - with an albedo texture white on one side of a plane and black on the other, paths that
//!   enter on the white side near the edge and wander under the black side are absorbed with
//!   surface projection but not with entry projection: the white side near the edge is darker
//!   (and the black side near it not darker);
//! - surface projection filters the textures with the ray's footprint: a one-texel checker of
//!   albedos 0.05 and 0.95, far finer than a pixel, renders like the constant albedo 0.5 (its
//!   mip mean); reading the finest level instead, every vertex would see 0.05 or 0.95, whose
//!   inverted single-scattering albedos average far below that of 0.5 (a darker image).

mod common;

use std::path::Path;

use common::files::TempDir;
use common::render::{image_mean, region_mean, render_text, unit_sphere_hit_x};
use common::stats::{assert_means_agree, z_score};
use common::textures::{exr_grey, png_rgb8};
use velour::geometry::{icosphere, write_ply};
use velour::math::Vec2;

/// A unit icosphere (1280 triangles) with planar texture coordinates u = (x + 1)/2,
/// v = (y + 1)/2: no seam, and u = ½ on the plane x = 0.
fn write_ball(path: &Path) {
    let mut mesh = icosphere(3);
    mesh.uvs = Some(
        mesh.positions
            .iter()
            .map(|p| Vec2::new((p.x + 1.0) / 2.0, (p.y + 1.0) / 2.0))
            .collect(),
    );
    write_ply(path, &mesh, false).unwrap();
}

/// `interior` (an inline table) with `nee = "exit"` spelled out: the comparisons here are about
/// the interior, not about next event estimation, and keep the exit-point NEE they were
/// written with (the default behind this rough boundary under a sun is "exit_guided").
fn with_exit_nee(interior: &str) -> String {
    let body = interior.trim_end();
    let body = body.strip_suffix('}').unwrap_or(body);
    format!("{body}, nee = \"exit\" }}")
}

fn scene(interior: &str, spp: u32, seed: u32) -> String {
    lit_scene(
        &with_exit_nee(interior),
        spp,
        seed,
        r#"{ type = "dielectric", ior = 1.33, roughness = 0.3 }"#,
        "[[light]]\ntype = \"distant\"\ndirection = [0.3, 0.5, 0.8]\nirradiance = 2.0\n",
    )
}

/// The ball under an environment light and `lights`, with boundary `surface`.
fn lit_scene(interior: &str, spp: u32, seed: u32, surface: &str, lights: &str) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 32
[film]
width = 16
height = 16
spp = {spp}
seed = {seed}
max_depth = 100000
[[light]]
type = "environment"
radiance = 1.0
{lights}
[[object]]
name = "ball"
shape = "mesh"
file = "ball.ply"
surface = {surface}
interior = {interior}
"#
    )
}

#[test]
fn surface_projection_of_constant_textures_matches_entry_and_the_constant() {
    let dir = TempDir::new("render-proj-const");
    write_ball(&dir.join("ball.ply"));
    // Linear albedo 0.8, 0.6, 0.3 (EXR: no sRGB decoding); density 1.5 from a texture.
    common::textures::exr_rgb(&dir.join("albedo.exr"), 5, 3, |_, _| [0.8, 0.6, 0.3]);
    exr_grey(&dir.join("density.exr"), 4, 4, |_, _| 1.5);
    let textured = |projection: &str| {
        format!(
            r#"{{ type = "homogeneous", albedo = {{ texture = "albedo.exr" }}, density = {{ texture = "density.exr" }}, attenuation = [0.3, 0.45, 0.9], projection = "{projection}" }}"#
        )
    };
    let constant = r#"{ type = "homogeneous", albedo = [0.8, 0.6, 0.3], density = 1.5, attenuation = [0.3, 0.45, 0.9] }"#;
    let s = render_text(&scene(&textured("surface"), 192, 1), dir.path());
    let e = render_text(&scene(&textured("entry"), 192, 2), dir.path());
    let c = render_text(&scene(constant, 192, 3), dir.path());
    for ch in 0..3 {
        let (ms, me, mc) = (image_mean(&s, ch), image_mean(&e, ch), image_mean(&c, ch));
        assert_means_agree(ms, me, &format!("surface vs entry, channel {ch}"));
        assert_means_agree(ms, mc, &format!("surface vs constant, channel {ch}"));
        // Standard errors small enough for the comparison to mean something (a scalar
        // majorant over three channels is noisier than the closed-form flights of the other
        // two: the MIS weights of the channels follow the count of null collisions).
        assert!(ms.1 < 0.06 * ms.0, "channel {ch}: {ms:?}");
    }
    // Behind an index-matched boundary NEE happens at interior vertices: shadow rays are
    // ratio-tracked through the projected medium.
    let clear = r#"{ type = "dielectric", ior = 1.0 }"#;
    let s = render_text(
        &lit_scene(&textured("surface"), 128, 4, clear, ""),
        dir.path(),
    );
    let c = render_text(&lit_scene(constant, 128, 5, clear, ""), dir.path());
    for ch in 0..3 {
        assert_means_agree(
            image_mean(&s, ch),
            image_mean(&c, ch),
            &format!("index-matched: surface vs constant, channel {ch}"),
        );
    }
}

#[test]
fn surface_projection_darkens_white_skin_near_black_skin() {
    let dir = TempDir::new("render-proj-stripe");
    write_ball(&dir.join("ball.ply"));
    // White for u > ½ (x > 0), black for u < ½: 8 texels across, so that the camera rays'
    // footprint (about half a texel) reads level 0 at the entry point as surface projection
    // does; bilinear filtering blends the two colours only for |x| < 1/8 (between the centres
    // of the two texels at the edge), which the regions below leave out.
    png_rgb8(&dir.join("stripe.png"), 8, 2, |x, _| {
        if x >= 4 {
            [250, 250, 250]
        } else {
            [10, 10, 10]
        }
    });
    let interior = |projection: &str| {
        format!(
            r#"{{ type = "homogeneous", albedo = {{ texture = "stripe.png" }}, attenuation = 0.15, projection = "{projection}" }}"#
        )
    };
    // An index-matched boundary under the environment alone: NEE at the interior vertices,
    // its shadow rays ratio-tracked through the projected medium; no caustic fireflies.
    let clear = r#"{ type = "dielectric", ior = 1.0 }"#;
    let s = render_text(
        &lit_scene(&interior("surface"), 256, 11, clear, ""),
        dir.path(),
    );
    let e = render_text(
        &lit_scene(&interior("entry"), 256, 12, clear, ""),
        dir.path(),
    );
    let near_white = |i, j| {
        unit_sphere_hit_x(32.0, i, j).is_some_and(|(x, cos)| x > 0.13 && x < 0.4 && cos > 0.4)
    };
    let near_black = |i, j| {
        unit_sphere_hit_x(32.0, i, j).is_some_and(|(x, cos)| x < -0.13 && x > -0.4 && cos > 0.4)
    };
    for ch in 0..3 {
        let (sw, ew) = (
            region_mean(&s, ch, near_white),
            region_mean(&e, ch, near_white),
        );
        let z = z_score(sw.0, ew.0, (sw.1 * sw.1 + ew.1 * ew.1).sqrt());
        assert!(
            z < -4.0,
            "white side near the edge, channel {ch}: surface {sw:?} not darker than entry {ew:?} (z = {z:.2})"
        );
        let (sb, eb) = (
            region_mean(&s, ch, near_black),
            region_mean(&e, ch, near_black),
        );
        let z = z_score(sb.0, eb.0, (sb.1 * sb.1 + eb.1 * eb.1).sqrt());
        // Under black skin the first collision absorbs almost every walk, wherever it
        // projects, so the few walks whose first collision lies under white skin brighten
        // it only slightly: it must not get darker.
        assert!(
            z > -4.0,
            "black side near the edge, channel {ch}: surface {sb:?} darker than entry {eb:?} (z = {z:.2})"
        );
    }
}

#[test]
fn surface_projection_filters_a_fine_checker_to_its_mean() {
    let dir = TempDir::new("render-proj-checker");
    write_ball(&dir.join("ball.ply"));
    // 512 texels across the ball's two units: a camera pixel covers about 25 texels, so every
    // lookup reads a level where the checker has averaged to 0.5 exactly.
    exr_grey(&dir.join("checker.exr"), 512, 512, |x, y| {
        if (x + y) % 2 == 0 {
            0.05
        } else {
            0.95
        }
    });
    let clear = r#"{ type = "dielectric", ior = 1.0 }"#;
    let checker = render_text(
        &lit_scene(
            r#"{ type = "homogeneous", albedo = { texture = "checker.exr" }, attenuation = 0.15, projection = "surface" }"#,
            256,
            21,
            clear,
            "",
        ),
        dir.path(),
    );
    let constant = render_text(
        &lit_scene(
            r#"{ type = "homogeneous", albedo = 0.5, attenuation = 0.15 }"#,
            256,
            22,
            clear,
            "",
        ),
        dir.path(),
    );
    for ch in 0..3 {
        assert_means_agree(
            image_mean(&checker, ch),
            image_mean(&constant, ch),
            &format!("fine checker under surface projection against its mean, channel {ch}"),
        );
    }
}
