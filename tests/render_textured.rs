//! Textured, entry-projected and blended interiors in renders (z-tests on image means with
//! standard errors from the renders' own per-pixel variances, fixed seeds, independent seeds
//! for the two sides of each comparison):
//! - a texture that holds one value everywhere renders like that constant;
//! - a blend with a constant mask m renders m · A + (1 − m) · B;
//! - entry projection on a sphere textured half red, half blue is red on one side and blue
//!   on the other: each side matches the render of its constant colour.

mod common;

use std::path::Path;

use common::files::TempDir;
use common::render::{image_mean, region_mean, render_text, unit_sphere_hit_x};
use common::stats::{assert_means_agree, z_score};
use common::textures::{exr_grey, png_rgb8};
use velour::film::Film;
use velour::math::{Vec2, Vec3};
use velour::texture::srgb_to_linear;

fn head(spp: u32, seed: u32, fov: f32) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = {fov}
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

#[test]
fn a_texture_of_one_value_renders_like_the_constant() {
    let dir = TempDir::new("render-tex-const");
    png_rgb8(&dir.join("albedo.png"), 7, 5, |_, _| [230, 180, 120]);
    png_rgb8(&dir.join("tint.png"), 3, 3, |_, _| [240, 240, 200]);
    exr_grey(&dir.join("rough.exr"), 4, 4, |_, _| 0.4);
    let lin = |v: u8| srgb_to_linear(f32::from(v) / 255.0);
    let object = |surface: &str, interior: &str| {
        format!(
            "[[object]]\nname = \"ball\"\nshape = \"sphere\"\nsurface = {surface}\ninterior = {}\n",
            with_exit_nee(interior)
        )
    };
    let textured = object(
        r#"{ type = "dielectric", ior = 1.4, roughness = { texture = "rough.exr" }, tint = { texture = "tint.png" } }"#,
        r#"{ type = "homogeneous", albedo = { texture = "albedo.png" }, attenuation = 0.3 }"#,
    );
    let constant = object(
        &format!(
            "{{ type = \"dielectric\", ior = 1.4, roughness = 0.4, tint = [{:.9}, {:.9}, {:.9}] }}",
            lin(240),
            lin(240),
            lin(200)
        ),
        &format!(
            "{{ type = \"homogeneous\", albedo = [{:.9}, {:.9}, {:.9}], attenuation = 0.3 }}",
            lin(230),
            lin(180),
            lin(120)
        ),
    );
    let t = render_text(&format!("{}{textured}", head(64, 1, 24.0)), dir.path());
    let c = render_text(&format!("{}{constant}", head(64, 2, 24.0)), dir.path());
    for ch in 0..3 {
        assert_means_agree(
            image_mean(&t, ch),
            image_mean(&c, ch),
            &format!("channel {ch}"),
        );
    }
}

/// `interior` (an inline table) with `nee = "exit"` spelled out: the comparisons here are about
/// the interior, not about next event estimation, and keep the exit-point NEE they were
/// written with (the default behind this rough boundary under a sun is "exit_guided").
fn with_exit_nee(interior: &str) -> String {
    let body = interior.trim_end();
    let body = body.strip_suffix('}').unwrap_or(body);
    format!("{body}, nee = \"exit\" }}")
}

fn blend_scene(interior: &str, spp: u32, seed: u32) -> String {
    format!(
        "{}[[object]]\nname = \"ball\"\nshape = \"sphere\"\nsurface = {{ type = \"dielectric\", ior = 1.33, roughness = 0.3 }}\ninterior = {}\n",
        head(spp, seed, 24.0),
        with_exit_nee(interior)
    )
}

#[test]
fn a_blend_with_a_constant_mask_is_the_weighted_sum_of_its_looks() {
    let dir = TempDir::new("render-tex-blend");
    let m = 0.3;
    exr_grey(&dir.join("mask.exr"), 5, 3, |_, _| m);
    let a = r#"{ type = "homogeneous", albedo = [0.95, 0.4, 0.2], attenuation = 0.2 }"#;
    let b = r#"{ type = "homogeneous", albedo = [0.1, 0.5, 0.95], attenuation = [0.1, 0.3, 0.2], phase = { g = 0.5 } }"#;
    let blend =
        format!(r#"{{ type = "blend", mask = {{ texture = "mask.exr" }}, a = {a}, b = {b} }}"#);
    let fb = render_text(&blend_scene(&blend, 128, 3), dir.path());
    let fa = render_text(&blend_scene(a, 64, 4), dir.path());
    let fbb = render_text(&blend_scene(b, 64, 5), dir.path());
    let m = f64::from(m);
    for c in 0..3 {
        let (mb, sb) = image_mean(&fb, c);
        let (ma, sa) = image_mean(&fa, c);
        let (m2, s2) = image_mean(&fbb, c);
        let expected = m * ma + (1.0 - m) * m2;
        let se = (m * m * sa * sa + (1.0 - m) * (1.0 - m) * s2 * s2).sqrt();
        assert_means_agree((mb, sb), (expected, se), &format!("blend channel {c}"));
        // The two looks differ enough that a wrong weight would show.
        let z_looks = z_score(ma, m2, (sa * sa + s2 * s2).sqrt());
        if c != 1 {
            assert!(
                z_looks.abs() > 8.0,
                "looks too close in channel {c}: z = {z_looks}"
            );
        }
    }
}

/// The sphere's texture coordinate u = φ/2π with φ = atan2(z, x): the camera on +z sees
/// u ∈ (0, ½), x > 0 (the image's right) near u = 0. The texture is red where cos 2πu > 0
/// (x > 0) and blue elsewhere.
fn half_red_half_blue(dir: &TempDir) {
    png_rgb8(&dir.join("halves.png"), 64, 4, |x, _| {
        let u = (x as f32 + 0.5) / 64.0;
        if (2.0 * std::f32::consts::PI * u).cos() > 0.0 {
            [240, 20, 20]
        } else {
            [20, 20, 240]
        }
    });
}

fn halves_scene(albedo: &str, spp: u32, seed: u32) -> String {
    format!(
        "{}[[object]]\nname = \"ball\"\nshape = \"sphere\"\ninterior = {{ type = \"homogeneous\", albedo = {albedo}, attenuation = 0.3, projection = \"entry\" }}\n",
        head(spp, seed, 36.0)
    )
}

#[test]
fn entry_projection_is_red_on_one_side_and_blue_on_the_other() {
    let dir = TempDir::new("render-tex-halves");
    half_red_half_blue(&dir);
    let lin = |v: u8| srgb_to_linear(f32::from(v) / 255.0);
    let (hi, lo) = (lin(240), lin(20));
    let textured = render_text(
        &halves_scene(r#"{ texture = "halves.png" }"#, 64, 7),
        dir.path(),
    );
    let red = render_text(
        &halves_scene(&format!("[{hi:.9}, {lo:.9}, {lo:.9}]"), 64, 8),
        dir.path(),
    );
    let blue = render_text(
        &halves_scene(&format!("[{lo:.9}, {lo:.9}, {hi:.9}]"), 64, 9),
        dir.path(),
    );
    // Pixels well inside each half (the filter footprint is a few texels) and not grazing.
    let right = |i, j| unit_sphere_hit_x(36.0, i, j).is_some_and(|(x, cos)| x > 0.5 && cos > 0.5);
    let left = |i, j| unit_sphere_hit_x(36.0, i, j).is_some_and(|(x, cos)| x < -0.5 && cos > 0.5);
    for c in 0..3 {
        assert_means_agree(
            region_mean(&textured, c, right),
            region_mean(&red, c, right),
            &format!("right (red) half, channel {c}"),
        );
        assert_means_agree(
            region_mean(&textured, c, left),
            region_mean(&blue, c, left),
            &format!("left (blue) half, channel {c}"),
        );
    }
    let (r_right, b_right) = (
        region_mean(&textured, 0, right).0,
        region_mean(&textured, 2, right).0,
    );
    let (r_left, b_left) = (
        region_mean(&textured, 0, left).0,
        region_mean(&textured, 2, left).0,
    );
    assert!(
        r_right > 2.0 * b_right,
        "right half not red: R {r_right}, B {b_right}"
    );
    assert!(
        b_left > 2.0 * r_left,
        "left half not blue: R {r_left}, B {b_left}"
    );
}

/// A quad facing the camera, 4 × 4 world units, texture coordinates spanning [0, 1]².
fn write_quad(path: &Path) {
    let mesh = velour::geometry::TriangleMesh {
        positions: vec![
            Vec3::new(-2.0, -2.0, 0.0),
            Vec3::new(2.0, -2.0, 0.0),
            Vec3::new(2.0, 2.0, 0.0),
            Vec3::new(-2.0, 2.0, 0.0),
        ],
        normals: None,
        uvs: Some(vec![
            Vec2::new(0.0, 0.0),
            Vec2::new(1.0, 0.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(0.0, 1.0),
        ]),
        indices: vec![[0, 1, 2], [0, 2, 3]],
    };
    velour::geometry::write_ply(path, &mesh, false).unwrap();
}

fn quad_scene(reflectance: &str, spp: u32, seed: u32) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 30
[film]
width = 16
height = 16
spp = {spp}
seed = {seed}
[[light]]
type = "environment"
radiance = 1.0
[[object]]
name = "quad"
shape = "mesh"
file = "quad.ply"
surface = {{ type = "lambertian", reflectance = {reflectance} }}
"#
    )
}

/// Mean over pixels of channel 0's variance of the pixel mean.
fn mean_variance(film: &Film) -> f64 {
    let mut v = 0.0;
    for y in 0..film.height() {
        for x in 0..film.width() {
            v += f64::from(film.variance_of_mean(x, y)[0]);
        }
    }
    v / f64::from(film.width() * film.height())
}

/// A checker of one-texel cells seen at about 8 texels per pixel: the camera ray's cone picks
/// a mip level where the checker is its mean, so the pixels are as quiet as a constant grey
/// plane (point sampling would give every sample 0 or 1: a variance of the pixel mean of
/// about 0.25 / spp), and the image matches that grey plane.
#[test]
fn ray_cones_pick_the_mip_level_of_the_pixel_footprint() {
    let dir = TempDir::new("render-tex-cone");
    write_quad(&dir.join("quad.ply"));
    exr_grey(&dir.join("checker.exr"), 256, 256, |x, y| {
        ((x + y) % 2) as f32
    });
    let spp = 16;
    let checker = render_text(
        &quad_scene(r#"{ texture = "checker.exr" }"#, spp, 11),
        dir.path(),
    );
    let grey = render_text(&quad_scene("0.5", spp, 12), dir.path());
    let (vc, vg) = (mean_variance(&checker), mean_variance(&grey));
    let point_sampled = 0.25 / f64::from(spp);
    assert!(
        vc < 2.0 * vg + 0.02 * point_sampled,
        "checker pixels are noisy: variance {vc} vs grey {vg} (point sampling ≈ {point_sampled})"
    );
    assert_means_agree(
        image_mean(&checker, 0),
        image_mean(&grey, 0),
        "checker vs grey",
    );
}

fn opaque_ball(surface: &str, spp: u32, seed: u32) -> String {
    format!(
        "{}[[object]]\nname = \"ball\"\nshape = \"sphere\"\nsurface = {surface}\n",
        head(spp, seed, 24.0)
    )
}

/// A convex opaque ball is seen through one surface interaction per camera path, so a
/// surface blend with a constant mask m renders m · A + (1 − m) · B exactly in expectation.
#[test]
fn a_surface_blend_with_a_constant_mask_is_the_weighted_sum_of_its_surfaces() {
    let dir = TempDir::new("render-tex-surface-blend");
    let m = 0.7;
    exr_grey(&dir.join("mask.exr"), 3, 3, |_, _| m);
    let a = r#"{ type = "lambertian", reflectance = [0.9, 0.2, 0.1] }"#;
    let b = r#"{ type = "conductor", reflectance = [0.2, 0.5, 0.95], roughness = 0.4 }"#;
    let blend =
        format!(r#"{{ type = "blend", mask = {{ texture = "mask.exr" }}, a = {a}, b = {b} }}"#);
    let fb = render_text(&opaque_ball(&blend, 128, 21), dir.path());
    let fa = render_text(&opaque_ball(a, 64, 22), dir.path());
    let fbb = render_text(&opaque_ball(b, 64, 23), dir.path());
    let m = f64::from(m);
    for c in 0..3 {
        let (ma, sa) = image_mean(&fa, c);
        let (m2, s2) = image_mean(&fbb, c);
        let expected = m * ma + (1.0 - m) * m2;
        let se = (m * m * sa * sa + (1.0 - m) * (1.0 - m) * s2 * s2).sqrt();
        assert_means_agree(
            image_mean(&fb, c),
            (expected, se),
            &format!("surface blend channel {c}"),
        );
    }
}

/// A blend's looks can be any interior: a procedural (fBm) look and a homogeneous one, behind
/// an index-matched boundary (so NEE happens at interior vertices, its shadow rays tracked
/// through the walk's look). A convex object is entered once per camera path, so the image
/// is m · A + (1 − m) · B in expectation.
#[test]
fn a_blend_of_a_heterogeneous_and_a_homogeneous_look() {
    let dir = TempDir::new("render-tex-blend-fbm");
    let a = r#"{ type = "fbm", noise = { frequency = 3.0, offset = 0.4, amplitude = 1.0 }, voxel_size = 0.05, albedo = [0.9, 0.5, 0.3], attenuation = 0.15 }"#;
    let b = r#"{ type = "homogeneous", albedo = [0.3, 0.6, 0.9], attenuation = [0.5, 0.3, 0.2] }"#;
    let scene = |interior: &str, spp: u32, seed: u32| {
        format!(
            "{}[[object]]\nname = \"ball\"\nshape = \"sphere\"\ninterior = {interior}\n",
            head(spp, seed, 24.0)
        )
    };
    let m = 0.4;
    let blend = format!(r#"{{ type = "blend", mask = {m}, a = {a}, b = {b} }}"#);
    let fb = render_text(&scene(&blend, 96, 31), dir.path());
    let fa = render_text(&scene(a, 48, 32), dir.path());
    let fbb = render_text(&scene(b, 48, 33), dir.path());
    for c in 0..3 {
        let (ma, sa) = image_mean(&fa, c);
        let (m2, s2) = image_mean(&fbb, c);
        let expected = m * ma + (1.0 - m) * m2;
        let se = (m * m * sa * sa + (1.0 - m) * (1.0 - m) * s2 * s2).sqrt();
        assert_means_agree(
            image_mean(&fb, c),
            (expected, se),
            &format!("fbm/homogeneous blend channel {c}"),
        );
    }
}
