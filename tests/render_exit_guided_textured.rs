//! `nee = "exit_guided"` behind textured and blended boundaries, and blended boundaries under
//! every NEE mode. z-tests of image and region means at fixed, independent seeds, with the
//! standard errors from the renders' own per-pixel variances (4σ):
//! - a roughness and tint texture of one value renders like those constants;
//! - with two-valued roughness and tint textures, and with blends (two rough looks, or a rough
//!   and a smooth one, under a two-valued mask), `exit_guided` agrees with `exit` on each half
//!   of the sphere and over the image: the guided connection reads the surface at the exit
//!   point as the unidirectional walk does, so it stays unbiased;
//! - a blend of two dielectrics that differ only in tint is, in expectation, the dielectric
//!   with the mask-weighted tint: checked under `exit`, `exit_guided`, `interior` (rough
//!   looks) and `manifold` (smooth looks).

mod common;

use common::files::TempDir;
use common::render::{image_mean, region_mean, render_text, scene_from_text, unit_sphere_hit_x};
use common::stats::{assert_means_agree, z_score};
use common::textures::{exr_grey, exr_rgb};
use velour::film::Film;
use velour::medium::NeeStrategy;

/// The camera's vertical field of view, degrees: the unit sphere fills most of the frame.
const FOV: f32 = 36.0;

/// A unit sphere of dense skin behind `surface`, lit by a sphere light (MIS and the area
/// Jacobian of the connection), a delta sun and a small disc sun.
fn lit_sphere(surface: &str, nee: &str, spp: u32, seed: u32) -> String {
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
type = "sphere"
center = [-1.5, 2.0, 1.5]
radius = 0.6
radiance = 10.0
[[light]]
type = "distant"
direction = [0.7, 0.2, 0.6]
irradiance = 1.5
[[light]]
type = "distant"
direction = [-0.2, -0.7, 0.5]
irradiance = 2.0
angular_radius = 6.0
[[object]]
name = "skin"
shape = "sphere"
radius = 1.0
surface = {surface}
interior = {{ type = "homogeneous", albedo = [0.97, 0.9, 0.7], albedo_mode = "single", density = 8.0, attenuation = [1.0, 0.8, 0.6], phase = {{ g = 0.3 }}, nee = "{nee}" }}
"#
    )
}

/// The sphere's texture coordinate u = φ/2π with φ = atan2(z, x): the camera on +z sees
/// u ∈ (0, ½), x > 0 (the image's right) near u = 0. `right` where cos 2πu > 0 (x > 0),
/// `left` elsewhere, as a 64 × 4 image.
fn halves<T: Copy>(right: T, left: T) -> impl Fn(u32, u32) -> T {
    move |x, _| {
        let u = (x as f32 + 0.5) / 64.0;
        if (2.0 * std::f32::consts::PI * u).cos() > 0.0 {
            right
        } else {
            left
        }
    }
}

/// Pixels well inside the right (x > 0.5) or left (x < −0.5) half of the sphere, not
/// grazing (the texture filter's footprint stays inside the half).
fn right(i: u32, j: u32) -> bool {
    unit_sphere_hit_x(FOV, i, j).is_some_and(|(x, cos)| x > 0.5 && cos > 0.5)
}

fn left(i: u32, j: u32) -> bool {
    unit_sphere_hit_x(FOV, i, j).is_some_and(|(x, cos)| x < -0.5 && cos > 0.5)
}

/// [`assert_means_agree`] (4σ), printing the z value (`--nocapture`).
fn agree(a: (f64, f64), b: (f64, f64), what: &str) {
    let z = z_score(a.0, b.0, (a.1 * a.1 + b.1 * b.1).sqrt());
    eprintln!(
        "{what}: {:.5} ± {:.5} vs {:.5} ± {:.5}, z = {z:.2}",
        a.0, a.1, b.0, b.1
    );
    assert_means_agree(a, b, what);
}

/// `exit` and `exit_guided` agree on each half of the sphere and over the whole image.
fn assert_halves_agree(exit: &Film, guided: &Film, what: &str) {
    for c in 0..3 {
        agree(
            region_mean(guided, c, right),
            region_mean(exit, c, right),
            &format!("{what}: right half, channel {c} (exit_guided vs exit)"),
        );
        agree(
            region_mean(guided, c, left),
            region_mean(exit, c, left),
            &format!("{what}: left half, channel {c} (exit_guided vs exit)"),
        );
        agree(
            image_mean(guided, c),
            image_mean(exit, c),
            &format!("{what}: image, channel {c} (exit_guided vs exit)"),
        );
    }
}

#[test]
fn exit_guided_with_one_value_textures_renders_like_the_constants() {
    let dir = TempDir::new("exit-guided-tex-const");
    exr_grey(&dir.join("rough.exr"), 4, 4, |_, _| 0.45);
    exr_rgb(&dir.join("tint.exr"), 3, 5, |_, _| [0.9, 0.8, 0.7]);
    let textured = r#"{ type = "dielectric", ior = 1.4, roughness = { texture = "rough.exr" }, tint = { texture = "tint.exr" } }"#;
    let constant =
        r#"{ type = "dielectric", ior = 1.4, roughness = 0.45, tint = [0.9, 0.8, 0.7] }"#;
    let t = render_text(&lit_sphere(textured, "exit_guided", 128, 1), dir.path());
    let c = render_text(&lit_sphere(constant, "exit_guided", 128, 2), dir.path());
    for ch in 0..3 {
        agree(
            image_mean(&t, ch),
            image_mean(&c, ch),
            &format!("channel {ch} (one-value textures vs constants)"),
        );
    }
}

/// Roughness 0.3 and a warm tint on the right half, roughness 0.8 and a cool tint on the left.
#[test]
fn exit_guided_agrees_with_exit_behind_two_valued_roughness_and_tint() {
    let dir = TempDir::new("exit-guided-tex-halves");
    exr_grey(&dir.join("rough.exr"), 64, 4, halves(0.3, 0.8));
    exr_rgb(
        &dir.join("tint.exr"),
        64,
        4,
        halves([1.0, 0.75, 0.5], [0.5, 0.8, 1.0]),
    );
    let surface = r#"{ type = "dielectric", ior = 1.4, roughness = { texture = "rough.exr" }, tint = { texture = "tint.exr" } }"#;
    let exit = render_text(&lit_sphere(surface, "exit", 1024, 3), dir.path());
    let guided = render_text(&lit_sphere(surface, "exit_guided", 256, 4), dir.path());
    assert_halves_agree(&exit, &guided, "two-valued roughness and tint");
    // The halves differ: the textures are read (warm right, cool left).
    let ratio = |f: &Film, keep: fn(u32, u32) -> bool| {
        region_mean(f, 0, keep).0 / region_mean(f, 2, keep).0
    };
    assert!(
        ratio(&guided, right) > 1.2 * ratio(&guided, left),
        "right half not warmer than the left: R/B {} vs {}",
        ratio(&guided, right),
        ratio(&guided, left)
    );
}

/// Blends under a two-valued mask (0.85 on the right half, 0.2 on the left): two rough looks
/// of different roughness and tint; and a rough look with a smooth one (where the guided
/// connection can only use the rough look's lobe, and gives nothing through the smooth look,
/// which the walk alone accounts for).
#[test]
fn exit_guided_agrees_with_exit_behind_a_blended_boundary() {
    let dir = TempDir::new("exit-guided-blend");
    exr_grey(&dir.join("mask.exr"), 64, 4, halves(0.85, 0.2));
    let a = r#"{ type = "dielectric", ior = 1.4, roughness = 0.35, tint = [1.0, 0.7, 0.5] }"#;
    for (b, seed) in [
        (
            r#"{ type = "dielectric", ior = 1.4, roughness = 0.8, tint = [0.5, 0.8, 1.0] }"#,
            5,
        ),
        (
            r#"{ type = "dielectric", ior = 1.4, roughness = 0.0, tint = [0.5, 0.8, 1.0] }"#,
            7,
        ),
    ] {
        let surface =
            format!(r#"{{ type = "blend", mask = {{ texture = "mask.exr" }}, a = {a}, b = {b} }}"#);
        let exit = render_text(&lit_sphere(&surface, "exit", 1024, seed), dir.path());
        let guided = render_text(
            &lit_sphere(&surface, "exit_guided", 256, seed + 1),
            dir.path(),
        );
        assert_halves_agree(&exit, &guided, &format!("blend with b = {b}"));
    }
}

/// A blend of two dielectrics of one roughness that differ only in their tint, with a
/// one-value mask m, has in expectation the BSDF of the dielectric with tint
/// m · tint_a + (1 − m) · tint_b (the tint multiplies transmission only, and each hit, shadow
/// ray crossing or manifold connection picks or weights the looks by the mask): the two
/// render alike under every NEE mode. `manifold` needs smooth looks.
#[test]
fn a_tint_blend_renders_like_the_mixed_tint_under_every_nee_mode() {
    let dir = TempDir::new("blend-every-nee");
    let m = 0.35f32;
    exr_grey(&dir.join("mask.exr"), 3, 3, |_, _| m);
    let (ta, tb) = ([1.0f32, 0.6, 0.3], [0.3f32, 0.7, 1.0]);
    let mixed: Vec<f32> = (0..3).map(|c| m * ta[c] + (1.0 - m) * tb[c]).collect();
    let colour = |t: &[f32]| format!("[{:.9}, {:.9}, {:.9}]", t[0], t[1], t[2]);
    for (nee, roughness, spp, seed) in [
        ("exit", 0.5, 256, 11),
        ("exit_guided", 0.5, 128, 13),
        ("interior", 0.5, 128, 15),
        ("manifold", 0.0, 128, 17),
    ] {
        let look = |t: &[f32]| {
            format!(
                r#"{{ type = "dielectric", ior = 1.4, roughness = {roughness:.2}, tint = {} }}"#,
                colour(t)
            )
        };
        let blend = format!(
            r#"{{ type = "blend", mask = {{ texture = "mask.exr" }}, a = {}, b = {} }}"#,
            look(&ta),
            look(&tb)
        );
        let text = lit_sphere(&blend, nee, spp, seed);
        let scene = scene_from_text(&text, dir.join("scene.toml"));
        assert_eq!(
            scene.objects[0].nee,
            match nee {
                "exit" => NeeStrategy::ExitPoint,
                "exit_guided" => NeeStrategy::ExitGuided,
                "interior" => NeeStrategy::Interior,
                _ => NeeStrategy::Manifold,
            },
            "{nee}: the blend keeps the NEE mode asked for"
        );
        let fb = render_text(&text, dir.path());
        let fm = render_text(&lit_sphere(&look(&mixed), nee, spp, seed + 1), dir.path());
        for c in 0..3 {
            agree(
                image_mean(&fb, c),
                image_mean(&fm, c),
                &format!("nee = {nee}, channel {c} (tint blend vs mixed tint)"),
            );
        }
    }
}

/// A blend of index-matched dielectrics (IOR 1) is an index-matched boundary: NEE moves to
/// the interior vertices, as behind a plain dielectric of IOR 1. A blend with a rough look
/// under `nee = "manifold"` is an error naming the look's key.
#[test]
fn blends_choose_their_nee_like_plain_dielectrics() {
    let dir = TempDir::new("blend-nee-choice");
    let matched = r#"{ type = "blend", mask = 0.5, a = { type = "dielectric", ior = 1.0, tint = 0.9 }, b = { type = "dielectric", ior = 1.0, tint = 0.5 } }"#;
    let text = lit_sphere(matched, "exit", 1, 1);
    let scene = scene_from_text(&text, dir.join("scene.toml"));
    assert_eq!(scene.objects[0].nee, NeeStrategy::Interior);
    let rough = r#"{ type = "blend", mask = 0.5, a = { type = "dielectric", ior = 1.4 }, b = { type = "dielectric", ior = 1.4, roughness = 0.3 } }"#;
    let text = lit_sphere(rough, "manifold", 1, 1);
    let e = velour::scene::load_scene_str(&text, &dir.join("scene.toml"))
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        e.contains("skin: interior.nee = \"manifold\"")
            && e.contains("surface.b.roughness = 0.3 is rough"),
        "{e}"
    );
}
