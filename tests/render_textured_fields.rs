//! Textured `albedo`, `attenuation` and `density` on `voxel` and `fbm` interiors, read at the
//! entry point (docs/textures.md): z-tests on image means with standard errors from the
//! renders' own per-pixel variances, fixed and independent seeds per side:
//! - a texture of one value renders like the constant (voxel and fbm);
//! - a density texture of two values (¼ and 4 around a stand-in mean near 2) renders, in
//!   each half of the sphere, like the constant of that half: the majorant follows each
//!   walk's density up and down;
//! - bad input: `projection = "surface"` on a sphere (tests/render_projected_fields.rs renders
//!   it on meshes), textures with albedo grids, textures
//!   without texture coordinates, bad texels, unknown keys.

mod common;

use common::files::TempDir;
use common::render::{
    image_mean, region_mean, render_finite, render_text, scene_from_text, unit_sphere_hit_x,
};
use common::stats::{assert_means_agree, z_score};
use common::textured::{
    assert_images_agree, assert_mentions, ball, err, lin, load, sphere_with, write_voxels, FBM, FOV,
};
use common::textures::{exr_grey, exr_rgb, png_rgb8};
use velour::medium::{Medium, WalkInterior};

#[test]
fn a_one_value_texture_on_a_voxel_interior_renders_like_the_constant() {
    let dir = TempDir::new("render-texfield-voxel");
    write_voxels(&dir);
    png_rgb8(&dir.join("albedo.png"), 5, 3, |_, _| [230, 180, 120]);
    exr_grey(&dir.join("density.exr"), 4, 4, |_, _| 1.5);
    let textured = r#"{ type = "voxel", file = "density.vdb", albedo = { texture = "albedo.png" }, density = { texture = "density.exr" }, attenuation = 0.4, projection = "entry" }"#;
    let constant = format!(
        "{{ type = \"voxel\", file = \"density.vdb\", albedo = [{:.9}, {:.9}, {:.9}], density = 1.5, attenuation = 0.4 }}",
        lin(230),
        lin(180),
        lin(120)
    );
    let t = render_text(&ball(textured, 256, 1), dir.path());
    let c = render_text(&ball(&constant, 256, 2), dir.path());
    assert_images_agree(&t, &c, "voxel");
}

#[test]
fn a_one_value_texture_on_an_fbm_interior_renders_like_the_constant() {
    let dir = TempDir::new("render-texfield-fbm");
    png_rgb8(&dir.join("albedo.png"), 3, 3, |_, _| [200, 120, 220]);
    exr_rgb(&dir.join("attenuation.exr"), 2, 3, |_, _| [0.15, 0.3, 0.2]);
    let textured = format!(
        r#"{{ {FBM}, albedo = {{ texture = "albedo.png" }}, attenuation = {{ texture = "attenuation.exr" }}, density = 1.2 }}"#
    );
    let constant = format!(
        "{{ {FBM}, albedo = [{:.9}, {:.9}, {:.9}], attenuation = [0.15, 0.3, 0.2], density = 1.2 }}",
        lin(200),
        lin(120),
        lin(220)
    );
    let t = render_text(&ball(&textured, 128, 3), dir.path());
    let c = render_text(&ball(&constant, 128, 4), dir.path());
    assert_images_agree(&t, &c, "fbm");
}

/// A voxel sphere whose density texture is 4 where x > 0 (cos 2πu > 0 for the sphere's
/// u = φ/2π) and ¼ elsewhere: each half renders like the constant of that half (a path
/// entering at a pixel's hit point keeps that value for its walk; the sphere is convex and
/// has no boundary, so a camera path enters once). The stand-in medium (the mean, ≈ 2.1) is
/// below the dense half and above the thin one: each walk must track its own density.
#[test]
fn a_two_valued_density_texture_gives_each_half_its_own_density() {
    let dir = TempDir::new("render-texfield-halves");
    write_voxels(&dir);
    exr_grey(&dir.join("halves.exr"), 64, 4, |x, _| {
        let u = (x as f32 + 0.5) / 64.0;
        if (2.0 * std::f32::consts::PI * u).cos() > 0.0 {
            4.0
        } else {
            0.25
        }
    });
    let voxel = |density: &str| {
        format!(
            r#"{{ type = "voxel", file = "density.vdb", albedo = [0.9, 0.6, 0.3], attenuation = 0.5, density = {density} }}"#
        )
    };
    let (textured, summary) = render_finite(
        &scene_from_text(
            &ball(&voxel(r#"{ texture = "halves.exr" }"#), 256, 7),
            dir.join("scene.toml"),
        ),
        0,
    );
    // Each walk's majorants are the field's density bounds times that walk's σ_t⁰: none is
    // ever exceeded (the trackers would stay unbiased through a violation, so the z-tests
    // below cannot see one; this count can).
    assert_eq!(summary.tracking.violations, 0, "majorant violations");
    assert!(summary.tracking.real_collisions > 0);
    let dense = render_text(&ball(&voxel("4.0"), 256, 8), dir.path());
    let thin = render_text(&ball(&voxel("0.25"), 256, 9), dir.path());
    let right = |i, j| unit_sphere_hit_x(FOV, i, j).is_some_and(|(x, cos)| x > 0.5 && cos > 0.5);
    let left = |i, j| unit_sphere_hit_x(FOV, i, j).is_some_and(|(x, cos)| x < -0.5 && cos > 0.5);
    for c in 0..3 {
        assert_means_agree(
            region_mean(&textured, c, right),
            region_mean(&dense, c, right),
            &format!("right (dense) half, channel {c}"),
        );
        assert_means_agree(
            region_mean(&textured, c, left),
            region_mean(&thin, c, left),
            &format!("left (thin) half, channel {c}"),
        );
    }
    // The halves differ (the test could not pass with a texture read nowhere): the dense half
    // differs from the thin half's constant render.
    let (d, t) = (
        region_mean(&textured, 0, right),
        region_mean(&thin, 0, right),
    );
    let z = z_score(d.0, t.0, (d.1 * d.1 + t.1 * t.1).sqrt());
    assert!(
        z.abs() > 6.0,
        "dense half {d:?} indistinguishable from thin {t:?}"
    );
}

/// A textured voxel interior can be a blend's look (here `b`, the second slot of the walk
/// medium): with a constant mask m the image is m · A + (1 − m) · B.
#[test]
fn a_textured_voxel_look_in_a_blend_is_weighted_by_the_mask() {
    let dir = TempDir::new("render-texfield-blend");
    write_voxels(&dir);
    exr_rgb(&dir.join("albedo.exr"), 2, 2, |_, _| [0.95, 0.7, 0.4]);
    let a = r#"{ type = "homogeneous", albedo = [0.3, 0.6, 0.9], attenuation = [0.5, 0.3, 0.2] }"#;
    let b = r#"{ type = "voxel", file = "density.vdb", albedo = { texture = "albedo.exr" }, attenuation = 0.3 }"#;
    let b_constant =
        r#"{ type = "voxel", file = "density.vdb", albedo = [0.95, 0.7, 0.4], attenuation = 0.3 }"#;
    let m = 0.3;
    let blend = format!(r#"{{ type = "blend", mask = {m}, a = {a}, b = {b} }}"#);
    let fm = render_text(&ball(&blend, 256, 11), dir.path());
    let fa = render_text(&ball(a, 128, 12), dir.path());
    let fb = render_text(&ball(b_constant, 128, 13), dir.path());
    for c in 0..3 {
        let (ma, sa) = image_mean(&fa, c);
        let (mb, sb) = image_mean(&fb, c);
        let expected = m * ma + (1.0 - m) * mb;
        let se = (m * m * sa * sa + (1.0 - m) * (1.0 - m) * sb * sb).sqrt();
        assert_means_agree(
            image_mean(&fm, c),
            (expected, se),
            &format!("blend with a textured voxel look, channel {c}"),
        );
    }
}

#[test]
fn textured_fields_load_as_per_walk_interiors_and_constants_stay_fixed() {
    let dir = TempDir::new("texfield-load");
    write_voxels(&dir);
    exr_grey(
        &dir.join("d.exr"),
        2,
        2,
        |x, _| if x == 0 { 1.0 } else { 3.0 },
    );
    let s = load(
        &dir,
        &sphere_with(
            r#"{ type = "voxel", file = "density.vdb", density = { texture = "d.exr" } }"#,
        ),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let obj = &s.objects[0];
    assert!(matches!(obj.walk.as_deref(), Some(WalkInterior::Field(_))));
    let m = obj.medium.map(|m| &s.media[m as usize]);
    // The stand-in: the field at the texture's mean density (2).
    let Some(Medium::Scaled(f)) = m else {
        panic!("stand-in is not a scaled field: {m:?}");
    };
    let ratio = f.sigma_t.0[0] / f.medium.coefficients.sigma_t.0[0];
    assert!((ratio - 1.0).abs() < 1e-6, "stand-in ratio {ratio}");
    assert!(
        (f.sigma_t.0[0] - 2.0).abs() < 1e-4,
        "stand-in σ_t {:?}",
        f.sigma_t
    );
    let s = load(
        &dir,
        &sphere_with(&format!(
            "{{ {FBM}, density = 2.0, projection = \"entry\" }}"
        )),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(s.objects[0].walk.is_none());
    let m = s.objects[0].medium.map(|m| &s.media[m as usize]);
    assert!(matches!(m, Some(Medium::Heterogeneous(_))), "{m:?}");
}

#[test]
fn surface_projection_of_density_fields_on_a_sphere_is_refused() {
    let dir = TempDir::new("texfield-surface");
    write_voxels(&dir);
    png_rgb8(&dir.join("a.png"), 2, 2, |_, _| [100, 100, 100]);
    for interior in [
        r#"{ type = "voxel", file = "density.vdb", albedo = { texture = "a.png" }, projection = "surface" }"#.to_string(),
        format!(r#"{{ {FBM}, albedo = {{ texture = "a.png" }}, projection = "surface" }}"#),
    ] {
        let e = err(&dir, &sphere_with(&interior));
        assert_mentions(
            &e,
            &["scene.toml:", "ball: interior.projection", "\"surface\"", "mesh boundary"],
        );
    }
    let e = err(
        &dir,
        &sphere_with(&format!(r#"{{ {FBM}, projection = "walk" }}"#)),
    );
    assert_mentions(&e, &["ball: interior.projection", "\"walk\"", "unknown"]);
}

#[test]
fn textured_fields_with_albedo_grids_are_refused() {
    let dir = TempDir::new("texfield-mixture");
    write_voxels(&dir);
    png_rgb8(&dir.join("a.png"), 2, 2, |_, _| [100, 100, 100]);
    // (Textured mixture components are accepted: tests/render_textured_mixture.rs.)
    let e = err(
        &dir,
        &sphere_with(
            r#"{ type = "voxel", file = "density.vdb", density = { texture = "a.png" }, albedo_grid = "density", albedo_ramp = [[0.0, 0.2], [1.0, 0.9]] }"#,
        ),
    );
    assert_mentions(&e, &["ball: interior", "albedo or emission grids"]);
}

#[test]
fn bad_textures_on_density_fields_name_object_key_and_pixel() {
    let dir = TempDir::new("texfield-bad");
    write_voxels(&dir);
    exr_grey(&dir.join("neg.exr"), 3, 2, |x, y| {
        if (x, y) == (2, 1) {
            -1.0
        } else {
            1.0
        }
    });
    png_rgb8(&dir.join("a.png"), 2, 2, |_, _| [100, 100, 100]);
    // A negative density texel.
    let e = err(
        &dir,
        &sphere_with(
            r#"{ type = "voxel", file = "density.vdb", density = { texture = "neg.exr" } }"#,
        ),
    );
    assert_mentions(&e, &["ball: interior.density", "neg.exr", "(2, 1)"]);
    // A missing file.
    let e = err(
        &dir,
        &sphere_with(&format!(
            r#"{{ {FBM}, attenuation = {{ texture = "gone.exr" }} }}"#
        )),
    );
    assert_mentions(&e, &["ball: interior.attenuation", "gone.exr"]);
    // A misspelt key inside the texture table.
    let e = err(
        &dir,
        &sphere_with(&format!(
            r#"{{ {FBM}, albedo = {{ texture = "a.png", chanel = "r" }} }}"#
        )),
    );
    assert_mentions(&e, &["scene.toml:", "chanel"]);
    // No texture coordinates: a voxel interior on `shape = "bounds"`.
    let e = err(
        &dir,
        "[[object]]\nname = \"cloud\"\nshape = \"bounds\"\ninterior = { type = \"voxel\", file = \"density.vdb\", albedo = { texture = \"a.png\" } }\n",
    );
    assert_mentions(&e, &["cloud: interior.albedo", "texture coordinates"]);
}
