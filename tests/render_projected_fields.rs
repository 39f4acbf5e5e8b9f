//! `projection = "surface"` on `voxel` and `fbm` interiors (docs/textures.md, "Density fields
//! projected to the surface"): the density field stays, and the coefficients per unit density
//! come from the textures at the boundary point closest to every lookup. z-tests on image and
//! region means with standard errors from the renders' own per-pixel variances, fixed and
//! independent seeds per side:
//! - with textures of one value, surface projection renders like entry projection and like
//!   the untextured constant interior, on a voxel grid (albedo and density textures) and on
//!   baked fBm (albedo and per-channel attenuation textures), with no majorant violation
//!   (the majorants are the field's exact bounds times the textures' maximum);
//! - with an albedo texture white on one side of a plane and black on the other, over a voxel
//!   grid, the white side near the edge is darker with surface projection than with entry
//!   projection (walks wander under the black side and are absorbed there);
//! - the medium built: its majorant bound and its field;
//! - bad input: a mesh without texture coordinates, a sphere, an unknown projection.

mod common;

use std::path::Path;

use common::files::TempDir;
use common::render::{image_mean, region_mean, render_finite, scene_from_text, unit_sphere_hit_x};
use common::stats::{assert_means_agree, z_score};
use common::textures::{exr_grey, exr_rgb, png_rgb8};
use glam::{DAffine3, DVec3, IVec3, Vec3};
use velour::film::Film;
use velour::geometry::{icosphere, write_ply};
use velour::grid::{ChannelKind, SparseGridBuilder, Storage};
use velour::math::Vec2;
use velour::medium::Medium;
use velour::scene::load_scene_str;
use velour::texture::srgb_to_linear;
use velour::vdb::{write_vdb, GridToWrite, WriteOptions};

/// A unit icosphere (1280 triangles) with planar texture coordinates u = (x + 1)/2,
/// v = (y + 1)/2 (u = ½ on the plane x = 0), or without texture coordinates.
fn write_ball(path: &Path, uvs: bool) {
    let mut mesh = icosphere(3);
    mesh.uvs = uvs.then(|| {
        mesh.positions
            .iter()
            .map(|p| Vec2::new((p.x + 1.0) / 2.0, (p.y + 1.0) / 2.0))
            .collect()
    });
    write_ply(path, &mesh, false).unwrap();
}

/// `density.vdb`: a 16³ grid over [−1.5, 1.5]³ whose density steps between 0.3, 0.65 and 1
/// (so tracking meets real heterogeneity).
fn write_voxels(dir: &TempDir) {
    let n = 16;
    let mut b = SparseGridBuilder::new(Storage::F32);
    let c = b.add_channel("v", ChannelKind::Scalar, Vec3::ZERO);
    let voxel = 3.0 / f64::from(n - 1);
    b.set_index_to_world(
        DAffine3::from_translation(DVec3::splat(-1.5)) * DAffine3::from_scale(DVec3::splat(voxel)),
    )
    .unwrap();
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let v = 0.3 + 0.35 * ((x + 2 * y + z) % 3) as f32;
                b.set_value(c, IVec3::new(x, y, z), v).unwrap();
            }
        }
    }
    let grid = b.build();
    let list = [GridToWrite {
        class: "fog volume",
        ..GridToWrite::new("density", &grid)
    }];
    write_vdb(dir.join("density.vdb"), &list, &WriteOptions::default()).unwrap();
}

const FBM: &str = r#"type = "fbm", noise = { frequency = 3.0, offset = 0.4, amplitude = 1.0 }, voxel_size = 0.05"#;

/// The mesh ball (`ball.ply`) with an index-matched boundary, filled with `interior`, under
/// an environment light and a distant light (NEE at interior vertices, shadow rays tracked
/// through the projected field).
fn scene(interior: &str, spp: u32, seed: u32) -> String {
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
[[light]]
type = "distant"
direction = [0.3, 0.5, 0.8]
irradiance = 2.0
[[object]]
name = "ball"
shape = "mesh"
file = "ball.ply"
surface = {{ type = "dielectric", ior = 1.0 }}
interior = {interior}
"#
    )
}

/// Renders `text` in `dir`, asserting no majorant violation (and no non-finite sample).
fn render_unviolated(text: &str, dir: &Path) -> Film {
    let (film, summary) = render_finite(&scene_from_text(text, dir.join("scene.toml")), 0);
    assert_eq!(summary.tracking.violations, 0, "{:?}", summary.tracking);
    film
}

fn lin(v: u8) -> f32 {
    srgb_to_linear(f32::from(v) / 255.0)
}

fn assert_images_agree(a: &Film, b: &Film, what: &str) {
    for ch in 0..3 {
        let (ma, mb) = (image_mean(a, ch), image_mean(b, ch));
        let z = z_score(ma.0, mb.0, (ma.1 * ma.1 + mb.1 * mb.1).sqrt());
        eprintln!("{what}, channel {ch}: {ma:?} vs {mb:?}, z = {z:.2}");
        assert_means_agree(ma, mb, &format!("{what}, channel {ch}"));
        // Standard errors small enough for the comparison to mean something.
        assert!(ma.1 < 0.06 * ma.0, "{what}, channel {ch}: {ma:?}");
    }
}

#[test]
fn one_value_textures_on_a_voxel_interior_render_alike_projected_at_entry_or_surface() {
    let dir = TempDir::new("render-projfield-voxel");
    write_ball(&dir.join("ball.ply"), true);
    write_voxels(&dir);
    png_rgb8(&dir.join("albedo.png"), 5, 3, |_, _| [230, 180, 120]);
    exr_grey(&dir.join("density.exr"), 4, 4, |_, _| 1.5);
    let textured = |projection: &str| {
        format!(
            r#"{{ type = "voxel", file = "density.vdb", albedo = {{ texture = "albedo.png" }}, density = {{ texture = "density.exr" }}, attenuation = [0.3, 0.45, 0.9], projection = "{projection}" }}"#
        )
    };
    let constant = format!(
        "{{ type = \"voxel\", file = \"density.vdb\", albedo = [{:.9}, {:.9}, {:.9}], density = 1.5, attenuation = [0.3, 0.45, 0.9] }}",
        lin(230),
        lin(180),
        lin(120)
    );
    let s = render_unviolated(&scene(&textured("surface"), 192, 1), dir.path());
    let e = render_unviolated(&scene(&textured("entry"), 192, 2), dir.path());
    let c = render_unviolated(&scene(&constant, 192, 3), dir.path());
    assert_images_agree(&s, &e, "voxel: surface vs entry");
    assert_images_agree(&s, &c, "voxel: surface vs constant");
}

#[test]
fn one_value_textures_on_an_fbm_interior_render_alike_projected_at_entry_or_surface() {
    let dir = TempDir::new("render-projfield-fbm");
    write_ball(&dir.join("ball.ply"), true);
    png_rgb8(&dir.join("albedo.png"), 3, 3, |_, _| [200, 120, 220]);
    exr_rgb(&dir.join("attenuation.exr"), 2, 3, |_, _| [0.15, 0.3, 0.2]);
    let textured = |projection: &str| {
        format!(
            r#"{{ {FBM}, albedo = {{ texture = "albedo.png" }}, attenuation = {{ texture = "attenuation.exr" }}, density = 1.2, projection = "{projection}" }}"#
        )
    };
    let constant = format!(
        "{{ {FBM}, albedo = [{:.9}, {:.9}, {:.9}], attenuation = [0.15, 0.3, 0.2], density = 1.2 }}",
        lin(200),
        lin(120),
        lin(220)
    );
    let s = render_unviolated(&scene(&textured("surface"), 128, 4), dir.path());
    let e = render_unviolated(&scene(&textured("entry"), 128, 5), dir.path());
    let c = render_unviolated(&scene(&constant, 128, 6), dir.path());
    assert_images_agree(&s, &e, "fbm: surface vs entry");
    assert_images_agree(&s, &c, "fbm: surface vs constant");
}

#[test]
fn surface_projection_darkens_white_skin_near_black_skin_over_a_voxel_grid() {
    let dir = TempDir::new("render-projfield-stripe");
    write_ball(&dir.join("ball.ply"), true);
    write_voxels(&dir);
    // White for u > ½ (x > 0), black for u < ½: 8 texels across, so that the camera rays'
    // footprint reads level 0 at the entry point as surface projection does; bilinear
    // filtering blends the two colours only for |x| < 1/8, which the regions leave out.
    png_rgb8(&dir.join("stripe.png"), 8, 2, |x, _| {
        if x >= 4 {
            [250, 250, 250]
        } else {
            [10, 10, 10]
        }
    });
    let interior = |projection: &str| {
        format!(
            r#"{{ type = "voxel", file = "density.vdb", albedo = {{ texture = "stripe.png" }}, attenuation = 0.1, projection = "{projection}" }}"#
        )
    };
    let s = render_unviolated(&scene(&interior("surface"), 256, 11), dir.path());
    let e = render_unviolated(&scene(&interior("entry"), 256, 12), dir.path());
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
        eprintln!("white side, channel {ch}: surface {sw:?}, entry {ew:?}, z = {z:.2}");
        assert!(
            z < -4.0,
            "white side near the edge, channel {ch}: surface {sw:?} not darker than entry {ew:?} (z = {z:.2})"
        );
        let (sb, eb) = (
            region_mean(&s, ch, near_black),
            region_mean(&e, ch, near_black),
        );
        let z = z_score(sb.0, eb.0, (sb.1 * sb.1 + eb.1 * eb.1).sqrt());
        eprintln!("black side, channel {ch}: surface {sb:?}, entry {eb:?}, z = {z:.2}");
        assert!(
            z > -4.0,
            "black side near the edge, channel {ch}: surface {sb:?} darker than entry {eb:?} (z = {z:.2})"
        );
    }
}

/// The text of a scene with one object `ball` of shape `shape` (its extra keys included)
/// filled with `interior`.
fn object(shape: &str, interior: &str) -> String {
    format!(
        "[camera]\neye = [0, 0, 4]\nlook_at = [0, 0, 0]\n[[object]]\nname = \"ball\"\n{shape}\ninterior = {interior}\n"
    )
}

const MESH: &str = "shape = \"mesh\"\nfile = \"ball.ply\"";

#[test]
fn the_projected_field_is_bounded_by_the_field_times_the_textures() {
    let dir = TempDir::new("projfield-built");
    write_ball(&dir.join("ball.ply"), true);
    write_voxels(&dir);
    exr_grey(&dir.join("density.exr"), 4, 2, |x, _| {
        if x < 2 {
            1.0
        } else {
            3.0
        }
    });
    let text = object(
        MESH,
        r#"{ type = "voxel", file = "density.vdb", density = { texture = "density.exr" }, attenuation = [0.5, 1.0, 2.0], projection = "surface" }"#,
    );
    let scene = load_scene_str(&text, &dir.join("scene.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.objects[0].walk.is_none());
    let m = scene.objects[0].medium.unwrap() as usize;
    let Medium::Projected(p) = &scene.media[m] else {
        panic!("not a projected medium: {:?}", scene.media[m]);
    };
    let field = p.field.as_ref().expect("a projected field");
    // σ_t⁰ bound: max density 3 over attenuations 0.5, 1, 2; the grid's largest density is 1.
    let want = [6.0, 3.0, 1.5];
    for (c, &want) in want.iter().enumerate() {
        assert!(
            (field.bound.sigma_t.0[c] - want).abs() < 1e-4,
            "{:?}",
            field.bound
        );
        assert!(
            (p.sigma_t_max.0[c] - want).abs() < 1e-3,
            "{:?}",
            p.sigma_t_max
        );
    }
    // Nothing textured: projection changes nothing (the plain field).
    let text = object(
        MESH,
        r#"{ type = "voxel", file = "density.vdb", density = 2.0, projection = "surface" }"#,
    );
    let scene = load_scene_str(&text, &dir.join("scene.toml")).unwrap_or_else(|e| panic!("{e}"));
    let m = scene.objects[0].medium.unwrap() as usize;
    assert!(
        matches!(scene.media[m], Medium::Heterogeneous(_)),
        "{:?}",
        scene.media[m]
    );
}

fn assert_mentions(e: &str, parts: &[&str]) {
    for p in parts {
        assert!(e.contains(p), "`{p}` missing from: {e}");
    }
}

#[test]
fn surface_projection_of_fields_needs_a_mesh_with_texture_coordinates() {
    let dir = TempDir::new("projfield-bad");
    write_ball(&dir.join("bare.ply"), false);
    write_ball(&dir.join("ball.ply"), true);
    write_voxels(&dir);
    png_rgb8(&dir.join("a.png"), 2, 2, |_, _| [100, 100, 100]);
    let voxel = r#"{ type = "voxel", file = "density.vdb", albedo = { texture = "a.png" }, projection = "surface" }"#.to_string();
    let fbm = format!(r#"{{ {FBM}, albedo = {{ texture = "a.png" }}, projection = "surface" }}"#);
    let err = |text: &str| match load_scene_str(text, &dir.join("scene.toml")) {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e.to_string(),
    };
    for interior in [&voxel, &fbm] {
        let e = err(&object("shape = \"mesh\"\nfile = \"bare.ply\"", interior));
        assert_mentions(
            &e,
            &[
                "scene.toml:",
                "ball: interior.projection = \"surface\"",
                "texture coordinates",
            ],
        );
        let e = err(&object("shape = \"sphere\"", interior));
        assert_mentions(
            &e,
            &[
                "scene.toml:",
                "ball: interior.projection = \"surface\"",
                "mesh boundary",
            ],
        );
    }
    let e = err(&object(
        MESH,
        &format!(r#"{{ {FBM}, albedo = {{ texture = "a.png" }}, projection = "closest" }}"#),
    ));
    assert_mentions(&e, &["ball: interior.projection = \"closest\"", "unknown"]);
    // Tracking keys a projected field does not use are refused, not ignored.
    for (key, value) in [
        ("free_flight", "\"decomposition\""),
        ("transmittance", "\"ratio\""),
        ("local_bounds", "true"),
    ] {
        let e = err(&object(
            MESH,
            &format!(
                r#"{{ {FBM}, albedo = {{ texture = "a.png" }}, projection = "surface", tracking = {{ {key} = {value} }} }}"#
            ),
        ));
        assert_mentions(
            &e,
            &[
                "scene.toml:",
                &format!("ball: interior.tracking.{key}"),
                "projection = \"surface\"",
            ],
        );
    }
    // `majorant` still applies.
    load_scene_str(
        &object(
            MESH,
            &format!(
                r#"{{ {FBM}, albedo = {{ texture = "a.png" }}, projection = "surface", tracking = {{ majorant = "global" }} }}"#
            ),
        ),
        &dir.join("scene.toml"),
    )
    .unwrap_or_else(|e| panic!("{e}"));
}
