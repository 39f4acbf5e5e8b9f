//! Textured components of `mixture` interiors, and textured `base_albedo`/`base_attenuation`
//! of `voxel` and `fbm` interiors, read at the entry point (docs/textures.md, "Mixtures read
//! at the entry point"): z-tests on image means with standard errors from the renders' own
//! per-pixel variances, fixed and independent seeds per side:
//! - textures of one value render like the constants (a mixture with a textured homogeneous
//!   and a textured voxel component; a voxel and an fbm interior with a textured base);
//! - a density texture of two values on a mixture's voxel component, and a base attenuation
//!   of two values, render in each half of the sphere like the constant of that half, with no
//!   majorant violation (each walk's majorants scale with its coefficients), and the halves
//!   differ;
//! - a textured mixture can be a blend's look, and a textured base sits next to an albedo grid;
//! - bad input: textures without texture coordinates, NaN and out-of-range texels, estimators
//!   a textured base does not have, each naming the object and key.

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

/// `halves.exr`: `right` where x > 0 on the unit sphere (cos 2πu > 0 for u = φ/2π), `left`
/// elsewhere.
fn write_halves(dir: &TempDir, name: &str, right: f32, left: f32) {
    exr_grey(&dir.join(name), 64, 4, |x, _| {
        let u = (x as f32 + 0.5) / 64.0;
        if (2.0 * std::f32::consts::PI * u).cos() > 0.0 {
            right
        } else {
            left
        }
    });
}

#[test]
fn one_value_textures_on_mixture_components_render_like_the_constants() {
    let dir = TempDir::new("render-texmix-one");
    write_voxels(&dir);
    png_rgb8(&dir.join("albedo.png"), 5, 3, |_, _| [230, 180, 120]);
    exr_grey(&dir.join("density.exr"), 4, 4, |_, _| 1.5);
    exr_rgb(&dir.join("attenuation.exr"), 3, 2, |_, _| [0.8, 1.2, 2.0]);
    let textured = r#"{ type = "mixture", media = [
        { type = "homogeneous", albedo = { texture = "albedo.png" }, attenuation = { texture = "attenuation.exr" }, phase = { g = 0.4 } },
        { type = "voxel", file = "density.vdb", albedo = 0.9, density = { texture = "density.exr" }, attenuation = 0.4 } ] }"#;
    let constant = format!(
        r#"{{ type = "mixture", media = [
        {{ type = "homogeneous", albedo = [{:.9}, {:.9}, {:.9}], attenuation = [0.8, 1.2, 2.0], phase = {{ g = 0.4 }} }},
        {{ type = "voxel", file = "density.vdb", albedo = 0.9, density = 1.5, attenuation = 0.4 }} ] }}"#,
        lin(230),
        lin(180),
        lin(120)
    );
    let t = render_text(&ball(textured, 256, 1), dir.path());
    let c = render_text(&ball(&constant, 256, 2), dir.path());
    assert_images_agree(&t, &c, "mixture");
}

#[test]
fn one_value_base_textures_render_like_the_constant_base() {
    let dir = TempDir::new("render-texmix-base");
    write_voxels(&dir);
    png_rgb8(&dir.join("base.png"), 3, 3, |_, _| [200, 120, 220]);
    exr_rgb(&dir.join("base_att.exr"), 2, 3, |_, _| [0.6, 0.9, 1.4]);
    // The textured base makes a two-component mixture; the constant one is the combined
    // heterogeneous medium: two estimators of one image.
    let textured = r#"{ type = "voxel", file = "density.vdb", albedo = 0.8, attenuation = 0.5, base_albedo = { texture = "base.png" }, base_attenuation = { texture = "base_att.exr" } }"#;
    let constant = format!(
        r#"{{ type = "voxel", file = "density.vdb", albedo = 0.8, attenuation = 0.5, base_albedo = [{:.9}, {:.9}, {:.9}], base_attenuation = [0.6, 0.9, 1.4] }}"#,
        lin(200),
        lin(120),
        lin(220)
    );
    let t = render_text(&ball(textured, 256, 3), dir.path());
    let c = render_text(&ball(&constant, 256, 4), dir.path());
    assert_images_agree(&t, &c, "voxel base");
    // fbm, with its own albedo textured too (both components per walk).
    png_rgb8(&dir.join("albedo.png"), 2, 2, |_, _| [90, 200, 160]);
    let textured = format!(
        r#"{{ {FBM}, albedo = {{ texture = "albedo.png" }}, attenuation = 0.3, base_albedo = 0.5, base_attenuation = {{ texture = "base_att.exr" }} }}"#
    );
    let constant = format!(
        r#"{{ {FBM}, albedo = [{:.9}, {:.9}, {:.9}], attenuation = 0.3, base_albedo = 0.5, base_attenuation = [0.6, 0.9, 1.4] }}"#,
        lin(90),
        lin(200),
        lin(160)
    );
    let t = render_text(&ball(&textured, 128, 5), dir.path());
    let c = render_text(&ball(&constant, 128, 6), dir.path());
    assert_images_agree(&t, &c, "fbm base");
}

/// A textured base next to an albedo grid (the grid stays on the field component): a
/// one-value base texture renders like the constant base.
#[test]
fn a_textured_base_with_an_albedo_grid_renders_like_the_constant_base() {
    let dir = TempDir::new("render-texmix-base-grid");
    write_voxels(&dir);
    exr_rgb(&dir.join("base.exr"), 2, 2, |_, _| [0.7, 0.5, 0.9]);
    let voxel = |base: &str| {
        format!(
            r#"{{ type = "voxel", file = "density.vdb", albedo_grid = "density", albedo_ramp = [[0.3, [0.9, 0.5, 0.2]], [1.0, [0.3, 0.8, 0.95]]], attenuation = 0.5, base_albedo = {base}, base_attenuation = 1.5 }}"#
        )
    };
    let s = scene_from_text(
        &ball(&voxel(r#"{ texture = "base.exr" }"#), 256, 41),
        dir.join("scene.toml"),
    );
    assert!(matches!(
        s.objects[0].walk.as_deref(),
        Some(WalkInterior::Mixture(_))
    ));
    let t = render_finite(&s, 0).0;
    let c = render_text(&ball(&voxel("[0.7, 0.5, 0.9]"), 256, 42), dir.path());
    assert_images_agree(&t, &c, "voxel base with an albedo grid");
}

/// Renders `textured` and the two constant interiors of its halves, and checks each half of
/// the textured render against its constant, no majorant violation, and the halves apart.
fn assert_halves(dir: &TempDir, textured: &str, right: &str, left: &str, seed: u32) {
    let (t, summary) = render_finite(
        &scene_from_text(&ball(textured, 256, seed), dir.join("scene.toml")),
        0,
    );
    // Each walk's majorants scale with its coefficients: none is exceeded (the trackers
    // stay unbiased through a violation, so the z-tests could not see one; this count can).
    assert_eq!(summary.tracking.violations, 0, "majorant violations");
    assert!(summary.tracking.real_collisions > 0);
    let r = render_text(&ball(right, 256, seed + 1), dir.path());
    let l = render_text(&ball(left, 256, seed + 2), dir.path());
    let in_right = |i, j| unit_sphere_hit_x(FOV, i, j).is_some_and(|(x, cos)| x > 0.5 && cos > 0.5);
    let in_left = |i, j| unit_sphere_hit_x(FOV, i, j).is_some_and(|(x, cos)| x < -0.5 && cos > 0.5);
    for c in 0..3 {
        for (name, film, region) in [
            ("right", &r, &in_right as &dyn Fn(u32, u32) -> bool),
            ("left", &l, &in_left),
        ] {
            let (a, b) = (region_mean(&t, c, region), region_mean(film, c, region));
            eprintln!(
                "{name} half, channel {c}: {:.5} ± {:.5} vs {:.5} ± {:.5}, z = {:.2}",
                a.0,
                a.1,
                b.0,
                b.1,
                z_score(a.0, b.0, (a.1 * a.1 + b.1 * b.1).sqrt())
            );
            assert_means_agree(a, b, &format!("{name} half, channel {c}"));
        }
    }
    // The halves differ: the right half of the textured render is not the left constant's.
    let (d, o) = (region_mean(&t, 0, in_right), region_mean(&l, 0, in_right));
    let z = z_score(d.0, o.0, (d.1 * d.1 + o.1 * o.1).sqrt());
    eprintln!("right half against the left constant: z = {z:.1}");
    assert!(
        z.abs() > 6.0,
        "right half {d:?} indistinguishable from {o:?}"
    );
}

/// The voxel component's density texture is 4 on the right and ¼ on the left: its stand-in
/// (the mean, ≈ 2.1) is below one half and above the other, so each walk must scale the
/// field's majorants by its own coefficients.
#[test]
fn a_two_valued_density_on_a_mixture_component_gives_each_half_its_own() {
    let dir = TempDir::new("render-texmix-halves");
    write_voxels(&dir);
    write_halves(&dir, "halves.exr", 4.0, 0.25);
    let mixture = |density: &str| {
        format!(
            r#"{{ type = "mixture", media = [
            {{ type = "homogeneous", albedo = [0.5, 0.7, 0.9], attenuation = 2.0 }},
            {{ type = "voxel", file = "density.vdb", albedo = [0.9, 0.6, 0.3], attenuation = 0.5, density = {density} }} ] }}"#
        )
    };
    assert_halves(
        &dir,
        &mixture(r#"{ texture = "halves.exr" }"#),
        &mixture("4.0"),
        &mixture("0.25"),
        7,
    );
}

/// A base attenuation of 0.1 on the right and 3 on the left (a dense and a thin base).
#[test]
fn a_two_valued_base_attenuation_gives_each_half_its_own() {
    let dir = TempDir::new("render-texmix-base-halves");
    write_voxels(&dir);
    write_halves(&dir, "base.exr", 0.1, 3.0);
    let voxel = |att: &str| {
        format!(
            r#"{{ type = "voxel", file = "density.vdb", albedo = 0.9, attenuation = 0.5, base_albedo = [0.95, 0.5, 0.2], base_attenuation = {att} }}"#
        )
    };
    assert_halves(
        &dir,
        &voxel(r#"{ texture = "base.exr" }"#),
        &voxel("0.1"),
        &voxel("3.0"),
        17,
    );
}

/// A textured mixture as a blend's look `b`: with a constant mask m the image is
/// m · A + (1 − m) · B.
#[test]
fn a_textured_mixture_look_in_a_blend_is_weighted_by_the_mask() {
    let dir = TempDir::new("render-texmix-blend");
    write_voxels(&dir);
    exr_rgb(&dir.join("albedo.exr"), 2, 2, |_, _| [0.95, 0.7, 0.4]);
    let a = r#"{ type = "homogeneous", albedo = [0.3, 0.6, 0.9], attenuation = [0.5, 0.3, 0.2] }"#;
    let mix = |albedo: &str| {
        format!(
            r#"{{ type = "mixture", media = [{{ type = "homogeneous", albedo = {albedo}, attenuation = 0.7 }}, {{ type = "voxel", file = "density.vdb", attenuation = 0.3 }}] }}"#
        )
    };
    let m = 0.3;
    let blend = format!(
        r#"{{ type = "blend", mask = {m}, a = {a}, b = {} }}"#,
        mix(r#"{ texture = "albedo.exr" }"#)
    );
    let fm = render_text(&ball(&blend, 256, 31), dir.path());
    let fa = render_text(&ball(a, 128, 32), dir.path());
    let fb = render_text(&ball(&mix("[0.95, 0.7, 0.4]"), 128, 33), dir.path());
    for c in 0..3 {
        let (ma, sa) = image_mean(&fa, c);
        let (mb, sb) = image_mean(&fb, c);
        let expected = m * ma + (1.0 - m) * mb;
        let se = (m * m * sa * sa + (1.0 - m) * (1.0 - m) * sb * sb).sqrt();
        let got = image_mean(&fm, c);
        eprintln!(
            "blend, channel {c}: z = {:.2}",
            z_score(got.0, expected, (got.1 * got.1 + se * se).sqrt())
        );
        assert_means_agree(
            got,
            (expected, se),
            &format!("blend with a textured mixture look, channel {c}"),
        );
    }
}

fn bounds_with(interior: &str) -> String {
    format!("[[object]]\nname = \"cloud\"\nshape = \"bounds\"\ninterior = {interior}\n")
}

#[test]
fn textured_mixtures_load_per_walk_with_the_means_as_stand_in() {
    let dir = TempDir::new("texmix-load");
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
            r#"{ type = "mixture", media = [{ type = "homogeneous", attenuation = 0.5 }, { type = "voxel", file = "density.vdb", density = { texture = "d.exr" } }] }"#,
        ),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let obj = &s.objects[0];
    assert!(matches!(
        obj.walk.as_deref(),
        Some(WalkInterior::Mixture(_))
    ));
    let m = obj.medium.map(|m| &s.media[m as usize]);
    let Some(Medium::ScaledMixture(f)) = m else {
        panic!("stand-in is not a scaled mixture: {m:?}");
    };
    // The stand-in: the homogeneous component's σ_t = 2, the field's at the mean density 2.
    assert!((f.coefficients[0].sigma_t.0[0] - 2.0).abs() < 1e-5);
    assert!(
        (f.coefficients[1].sigma_t.0[0] - 2.0).abs() < 1e-4,
        "{:?}",
        f.coefficients
    );
    // Constant mixtures stay fixed.
    let s = load(
        &dir,
        &sphere_with(
            r#"{ type = "mixture", media = [{ type = "homogeneous" }, { type = "voxel", file = "density.vdb" }] }"#,
        ),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(s.objects[0].walk.is_none());
    let m = s.objects[0].medium.map(|m| &s.media[m as usize]);
    assert!(matches!(m, Some(Medium::Mixture(_))), "{m:?}");
}

#[test]
fn bad_textured_components_and_bases_name_object_key_and_pixel() {
    let dir = TempDir::new("texmix-bad");
    write_voxels(&dir);
    png_rgb8(&dir.join("a.png"), 2, 2, |_, _| [100, 100, 100]);
    exr_grey(&dir.join("nan.exr"), 3, 2, |x, y| {
        if (x, y) == (1, 1) {
            f32::NAN
        } else {
            1.0
        }
    });
    exr_grey(
        &dir.join("big.exr"),
        2,
        2,
        |x, _| if x == 1 { 1.5 } else { 0.5 },
    );
    // No texture coordinates: `shape = "bounds"`.
    let e = err(
        &dir,
        &bounds_with(
            r#"{ type = "mixture", media = [{ type = "voxel", file = "density.vdb", albedo = { texture = "a.png" } }, { type = "homogeneous" }] }"#,
        ),
    );
    assert_mentions(
        &e,
        &[
            "scene.toml:",
            "cloud: interior.media[0].albedo",
            "texture coordinates",
        ],
    );
    let e = err(
        &dir,
        &bounds_with(
            r#"{ type = "voxel", file = "density.vdb", base_albedo = { texture = "a.png" } }"#,
        ),
    );
    assert_mentions(&e, &["cloud: interior.base_albedo", "texture coordinates"]);
    // A NaN texel, in a component and in a base.
    let e = err(
        &dir,
        &sphere_with(
            r#"{ type = "mixture", media = [{ type = "homogeneous", density = { texture = "nan.exr" } }, { type = "homogeneous" }] }"#,
        ),
    );
    assert_mentions(
        &e,
        &["ball: interior.media[0].density", "nan.exr", "(1, 1)"],
    );
    let e = err(
        &dir,
        &sphere_with(&format!(
            r#"{{ {FBM}, base_attenuation = {{ texture = "nan.exr" }} }}"#
        )),
    );
    assert_mentions(
        &e,
        &["ball: interior.base_attenuation", "nan.exr", "(1, 1)"],
    );
    // A base albedo texel above 1.
    let e = err(
        &dir,
        &sphere_with(
            r#"{ type = "voxel", file = "density.vdb", base_albedo = { texture = "big.exr" } }"#,
        ),
    );
    assert_mentions(&e, &["ball: interior.base_albedo", "big.exr", "(1, 0)"]);
    // A textured base is tracked as a mixture: delta tracking only.
    let e = err(
        &dir,
        &sphere_with(
            r#"{ type = "voxel", file = "density.vdb", base_albedo = { texture = "a.png" }, tracking = { free_flight = "decomposition" } }"#,
        ),
    );
    assert_mentions(&e, &["ball: interior.tracking.free_flight", "delta"]);
    // Surface projection stays refused inside a mixture.
    let e = err(
        &dir,
        &sphere_with(
            r#"{ type = "mixture", media = [{ type = "homogeneous", albedo = { texture = "a.png" }, projection = "surface" }, { type = "homogeneous" }] }"#,
        ),
    );
    assert_mentions(&e, &["ball: interior.media[0]", "projection"]);
    // A textured base inside a mixture: bases are refused there.
    let e = err(
        &dir,
        &sphere_with(
            r#"{ type = "mixture", media = [{ type = "voxel", file = "density.vdb", base_albedo = { texture = "a.png" } }, { type = "homogeneous" }] }"#,
        ),
    );
    assert_mentions(&e, &["ball: interior.media[0]", "base_albedo"]);
}
