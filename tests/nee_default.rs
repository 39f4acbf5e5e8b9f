//! The default `nee` of an interior (absent, or `nee = "auto"`), resolved per object from its
//! surface and the scene's lights (docs/scene-format.md, docs/choosing-estimators.md):
//! `"exit_guided"` behind a rough dielectric boundary, coated or not (constant or textured
//! roughness, or a blend of two such looks) when the scene has a distant or sphere light;
//! `"exit"` behind smooth or diffuse-transmission boundaries, blends with a smooth look, and
//! under environments alone; `"interior"` behind an index-matched boundary. Explicit values are kept. The render
//! uses the resolved value: the default renders bit for bit as the explicit strategy does.

mod common;

use std::path::Path;

use common::files::TempDir;
use common::render::{render_finite, scene_from_text};
use common::textures::exr_grey;
use velour::film::Film;
use velour::medium::NeeStrategy;
use velour::scene::{load_scene_str, Scene};

const SUN: &str = r#"
[[light]]
type = "distant"
direction = [-0.6, 0.8, 0.5]
irradiance = 4.0
"#;

const DISC_SUN: &str = r#"
[[light]]
type = "distant"
direction = [-0.6, 0.8, 0.5]
irradiance = 4.0
angular_radius = 2.0
"#;

const SPHERE_LIGHT: &str = r#"
[[light]]
type = "sphere"
center = [-1.5, 2.0, 1.5]
radius = 0.5
radiance = 10.0
"#;

const SKY: &str = r#"
[[light]]
type = "environment"
radiance = [0.35, 0.4, 0.5]
"#;

/// A unit sphere of dense skin behind `surface`, with the interior's extra keys `nee`
/// (e.g. `, nee = "exit"`, or empty for the default) under `lights`.
fn skin(surface: &str, nee: &str, lights: &str) -> String {
    format!(
        r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]
fov = 30
[film]
width = 8
height = 8
spp = 4
max_depth = 1000
{lights}
[[object]]
name = "skin"
shape = "sphere"
radius = 1.0
surface = {surface}
interior = {{ type = "homogeneous", albedo = 0.95, albedo_mode = "single", density = 20.0{nee} }}
"#
    )
}

const ROUGH: &str = r#"{ type = "dielectric", ior = 1.4, roughness = 0.3 }"#;

fn load(text: &str) -> Scene {
    scene_from_text(text, Path::new("nee_default.toml"))
}

fn nee_of(text: &str) -> NeeStrategy {
    load(text).objects[0].nee
}

#[test]
fn rough_dielectric_under_a_small_light_defaults_to_exit_guided() {
    for (lights, what) in [
        (SUN, "delta sun"),
        (DISC_SUN, "disc sun"),
        (SPHERE_LIGHT, "sphere light"),
        (&format!("{SKY}{SUN}") as &str, "sky and sun"),
    ] {
        assert_eq!(
            nee_of(&skin(ROUGH, "", lights)),
            NeeStrategy::ExitGuided,
            "{what}, nee absent"
        );
        assert_eq!(
            nee_of(&skin(ROUGH, r#", nee = "auto""#, lights)),
            NeeStrategy::ExitGuided,
            "{what}, nee = \"auto\""
        );
    }
}

#[test]
fn environment_only_smooth_and_diffuse_boundaries_default_to_exit() {
    let cases = [
        (ROUGH, SKY, "rough dielectric under an environment alone"),
        (
            r#"{ type = "dielectric", ior = 1.4 }"#,
            SUN,
            "smooth dielectric",
        ),
        (
            r#"{ type = "dielectric", ior = 1.4, roughness = 0.03 }"#,
            SUN,
            "dielectric below the smooth threshold",
        ),
        (
            r#"{ type = "diffuse_transmission", transmittance = 0.8 }"#,
            SUN,
            "diffuse transmission",
        ),
    ];
    for (surface, lights, what) in cases {
        for nee in ["", r#", nee = "auto""#] {
            assert_eq!(
                nee_of(&skin(surface, nee, lights)),
                NeeStrategy::ExitPoint,
                "{what} ({nee:?})"
            );
        }
    }
}

#[test]
fn explicit_values_are_kept() {
    for (key, want) in [
        ("exit", NeeStrategy::ExitPoint),
        ("exit_guided", NeeStrategy::ExitGuided),
        ("interior", NeeStrategy::Interior),
    ] {
        for lights in [SUN, SKY] {
            assert_eq!(
                nee_of(&skin(ROUGH, &format!(r#", nee = "{key}""#), lights)),
                want,
                "nee = {key:?}"
            );
        }
    }
}

#[test]
fn index_matched_default_is_interior_without_a_warning() {
    for nee in ["", r#", nee = "auto""#] {
        let scene = load(&skin(r#"{ type = "dielectric", ior = 1.0 }"#, nee, SUN));
        assert_eq!(scene.objects[0].nee, NeeStrategy::Interior, "{nee:?}");
        assert!(scene.warnings.is_empty(), "{nee:?}: {:?}", scene.warnings);
    }
    // An explicit "exit" there is still overridden, with a warning.
    let scene = load(&skin(
        r#"{ type = "dielectric", ior = 1.0 }"#,
        r#", nee = "exit""#,
        SUN,
    ));
    assert_eq!(scene.objects[0].nee, NeeStrategy::Interior);
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
}

#[test]
fn textured_and_blended_rough_boundaries_default_to_exit_guided() {
    let dir = TempDir::new("nee-default-textured");
    exr_grey(
        &dir.join("rough.exr"),
        4,
        4,
        |x, _| if x < 2 { 0.2 } else { 0.5 },
    );
    exr_grey(
        &dir.join("mask.exr"),
        4,
        4,
        |x, _| if x < 2 { 0.0 } else { 1.0 },
    );
    let path = dir.join("scene.toml");
    let nee = |surface: &str, lights: &str| {
        load_scene_str(&skin(surface, "", lights), &path)
            .unwrap_or_else(|e| panic!("{e}"))
            .objects[0]
            .nee
    };
    let textured = r#"{ type = "dielectric", ior = 1.4, roughness = { texture = "rough.exr" } }"#;
    assert_eq!(nee(textured, SUN), NeeStrategy::ExitGuided, "textured");
    assert_eq!(nee(textured, SKY), NeeStrategy::ExitPoint, "textured, sky");
    let blend = |a: &str, b: &str| {
        format!(r#"{{ type = "blend", mask = {{ texture = "mask.exr" }}, a = {a}, b = {b} }}"#)
    };
    let rough_b = r#"{ type = "dielectric", ior = 1.4, roughness = 0.6, tint = 0.8 }"#;
    let smooth = r#"{ type = "dielectric", ior = 1.4 }"#;
    let coated = r#"{ type = "dielectric", ior = 1.4, roughness = 0.3, coat = { ior = 1.5, roughness = 0.1 } }"#;
    assert_eq!(
        nee(&blend(ROUGH, rough_b), SUN),
        NeeStrategy::ExitGuided,
        "blend of rough looks"
    );
    assert_eq!(
        nee(&blend(smooth, ROUGH), SUN),
        NeeStrategy::ExitPoint,
        "blend of a smooth and a rough look"
    );
    assert_eq!(
        nee(&blend(smooth, smooth), SUN),
        NeeStrategy::ExitPoint,
        "blend of smooth looks"
    );
    assert_eq!(
        nee(&blend(ROUGH, coated), SUN),
        NeeStrategy::ExitGuided,
        "blend with a coated look"
    );
    assert_eq!(
        nee(coated, SUN),
        NeeStrategy::ExitGuided,
        "coated rough dielectric"
    );
    assert_eq!(nee(coated, SKY), NeeStrategy::ExitPoint, "coated, sky");
    let smooth_coated =
        r#"{ type = "dielectric", ior = 1.4, coat = { ior = 1.5, roughness = 0.1 } }"#;
    assert_eq!(
        nee(smooth_coated, SUN),
        NeeStrategy::ExitPoint,
        "coated smooth dielectric"
    );
}

#[test]
fn unknown_value_names_auto_among_the_choices() {
    let text = skin(ROUGH, r#", nee = "guided""#, SUN);
    let e = load_scene_str(&text, Path::new("nee_default.toml"))
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(
        e.contains("nee = \"guided\" is unknown") && e.contains("\"auto\""),
        "{e}"
    );
}

fn pixels(film: &Film) -> Vec<[f32; 3]> {
    let mut v = Vec::new();
    for y in 0..film.height() {
        for x in 0..film.width() {
            v.push(film.mean(x, y).0);
        }
    }
    v
}

/// The integrator follows the resolved value: the default renders the same image, at the
/// same seed, as the strategy it resolves to, and not the one it does not.
#[test]
fn default_renders_as_the_resolved_strategy() {
    let render = |text: &str| pixels(&render_finite(&load(text), 1).0);
    let default = render(&skin(ROUGH, "", SUN));
    let guided = render(&skin(ROUGH, r#", nee = "exit_guided""#, SUN));
    let exit = render(&skin(ROUGH, r#", nee = "exit""#, SUN));
    assert_eq!(default, guided, "default vs exit_guided under a sun");
    assert_ne!(default, exit, "default vs exit under a sun");
    let default_sky = render(&skin(ROUGH, "", SKY));
    let exit_sky = render(&skin(ROUGH, r#", nee = "exit""#, SKY));
    assert_eq!(default_sky, exit_sky, "default vs exit under a sky");
}
