//! Several grids per interior and mixture interiors (docs/references.md §15):
//!
//! - an emissive grid of constant density against the closed form
//!   L = L_e·(1 − e^{−σ_t ℓ}) + L_env·e^{−σ_t ℓ} of a purely absorbing emitter (σ_a = σ_t), per
//!   channel, for a Vec3, a scalar × colour and a temperature (blackbody) emission grid;
//! - albedo grids (a Vec3 grid, and a scalar grid through a ramp) of constant value against the
//!   same interior with that constant `albedo` (per-pixel z-tests: the grids take the mixture
//!   tracker, the constant the ordinary one);
//! - a mixture of two homogeneous media with different phase functions against one
//!   homogeneous medium with the σ_s-weighted double Henyey–Greenstein phase function (exact);
//! - the `base_albedo` shorthand against the same interior written as an explicit mixture;
//! - bad input: misaligned grids, level sets used as density, unknown grid names, bad ramps,
//!   negative temperature scales, malformed mixtures.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use common::files::{repo_path, TempDir};
use common::render::{region_mean, render_finite, scene_from_text};
use common::stats::z_score;
use glam::{DAffine3, DVec3, IVec3, Vec3};
use velour::film::Film;
use velour::grid::{ChannelKind, SparseGrid, SparseGridBuilder, Storage};
use velour::image_io::compare::compare;
use velour::scene::load_scene_str;
use velour::spectrum::blackbody::blackbody_rgb;
use velour::vdb::{write_vdb, GridToWrite, WriteOptions};

/// A grid value: scalar or colour.
#[derive(Clone, Copy)]
enum Value {
    Scalar(f32),
    Colour([f32; 3]),
}

/// An n³ grid of constant `value` centred on the origin, spanning [−1.5, 1.5]³ between its
/// first and last voxel centres (so a sphere of radius 1 sees exactly `value` everywhere).
fn constant_grid(n: i32, value: Value, voxel_scale: f64) -> SparseGrid {
    let kind = match value {
        Value::Scalar(_) => ChannelKind::Scalar,
        Value::Colour(_) => ChannelKind::Vec3,
    };
    let mut b = SparseGridBuilder::new(Storage::F32);
    let c = b.add_channel("v", kind, Vec3::ZERO);
    let voxel = 3.0 / f64::from(n - 1) * voxel_scale;
    let half = 0.5 * voxel * f64::from(n - 1);
    b.set_index_to_world(
        DAffine3::from_translation(DVec3::splat(-half)) * DAffine3::from_scale(DVec3::splat(voxel)),
    )
    .unwrap_or_else(|e| panic!("{e}"));
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let ijk = IVec3::new(x, y, z);
                match value {
                    Value::Scalar(v) => b.set_value(c, ijk, v),
                    Value::Colour(v) => b.set_value_vec3(c, ijk, Vec3::from_array(v)),
                }
                .unwrap_or_else(|e| panic!("{e}"));
            }
        }
    }
    b.build()
}

/// Writes the named grids (name, class, grid) to `path`.
fn write(path: &Path, grids: &[(&str, &str, &SparseGrid)]) {
    let list: Vec<GridToWrite<'_>> = grids
        .iter()
        .map(|(name, class, g)| GridToWrite {
            class,
            ..GridToWrite::new(name, g)
        })
        .collect();
    write_vdb(path, &list, &WriteOptions::default()).unwrap_or_else(|e| panic!("{e}"));
}

/// The test volumes: `density` (1), `color` (Vec3), `shade` (scalar 0.25), `glow` (Vec3
/// radiance), `power` (scalar 0.8), `temp` (1) in `grids.vdb`; `coarse.vdb` holds a colour
/// grid with another voxel size; `sdf.vdb` a level set.
fn volumes(dir: &TempDir) {
    let n = 24;
    let density = constant_grid(n, Value::Scalar(1.0), 1.0);
    let color = constant_grid(n, Value::Colour([0.9, 0.5, 0.2]), 1.0);
    let shade = constant_grid(n, Value::Scalar(0.25), 1.0);
    let glow = constant_grid(n, Value::Colour([0.6, 1.2, 0.3]), 1.0);
    let power = constant_grid(n, Value::Scalar(0.8), 1.0);
    let temp = constant_grid(n, Value::Scalar(1.0), 1.0);
    write(
        &dir.join("grids.vdb"),
        &[
            ("density", "fog volume", &density),
            ("color", "unknown", &color),
            ("shade", "unknown", &shade),
            ("glow", "unknown", &glow),
            ("power", "unknown", &power),
            ("temp", "unknown", &temp),
        ],
    );
    let coarse = constant_grid(n, Value::Colour([0.9, 0.5, 0.2]), 2.0);
    write(&dir.join("coarse.vdb"), &[("color", "unknown", &coarse)]);
    let sdf = constant_grid(n, Value::Scalar(-0.1), 1.0);
    write(&dir.join("sdf.vdb"), &[("surface", "level set", &sdf)]);
}

/// A far camera with a tiny field of view looking at a sphere of radius 1 at the origin: every
/// ray crosses it through its centre (chords 2 to within 4·10⁻⁵).
fn emitter_scene(interior: &str) -> String {
    format!(
        r#"
[camera]
eye = [0.0, 0.0, 200.0]
look_at = [0.0, 0.0, 0.0]
fov = 0.005
[film]
width = 4
height = 4
spp = 2048
seed = 5
max_depth = 16
[[light]]
type = "environment"
radiance = 0.5
[[object]]
name = "fire"
shape = "sphere"
radius = 1.0
interior = {{ type = "voxel", file = "grids.vdb", albedo_mode = "single", attenuation = [1.0, 2.0, 0.5], nee = "interior", {interior} }}
"#
    )
}

fn render(dir: &TempDir, text: &str, seed: u64) -> Film {
    let mut scene = scene_from_text(text, dir.join("scene.toml"));
    scene.film.seed = seed;
    render_finite(&scene, 0).0
}

/// Checks every channel of the image mean against `expected` by z-test.
fn assert_image(film: &Film, expected: [f64; 3], what: &str) {
    for (c, &e) in expected.iter().enumerate() {
        let (mean, se) = region_mean(film, c, |_, _| true);
        let z = z_score(mean, e, se);
        assert!(
            z.abs() < 4.5,
            "{what}, channel {c}: {mean:.5} ± {se:.5}, closed form {e:.5} (z = {z:.2})"
        );
    }
}

/// L = L_e (1 − T) + L_env T with T = e^{−σ_t·2} for σ_t = [1, 0.5, 2] (attenuation
/// [1, 2, 0.5]) and albedo 0 (σ_a = σ_t).
fn absorbing_emitter(le: [f64; 3]) -> [f64; 3] {
    let sigma = [1.0, 0.5, 2.0];
    [0, 1, 2].map(|c| {
        let t = (-sigma[c] * 2.0f64).exp();
        le[c] * (1.0 - t) + 0.5 * t
    })
}

#[test]
fn emission_grids_match_the_closed_form_of_an_absorbing_emitter() {
    let dir = TempDir::new("emission");
    volumes(&dir);
    // A Vec3 radiance grid, scaled.
    let film = render(
        &dir,
        &emitter_scene(r#"albedo = 0.0, emission_grid = "glow", emission_scale = 1.5"#),
        1,
    );
    assert_image(
        &film,
        absorbing_emitter([0.9, 1.8, 0.45]),
        "Vec3 emission grid",
    );
    // A scalar grid times a colour.
    let film = render(
        &dir,
        &emitter_scene(
            r#"albedo = 0.0, emission_grid = "power", emission_color = [2.0, 1.0, 0.25]"#,
        ),
        2,
    );
    assert_image(
        &film,
        absorbing_emitter([1.6, 0.8, 0.2]),
        "scalar emission grid × colour",
    );
    // A temperature grid: 1500 K of blackbody radiance, scaled into the scene's range.
    let film = render(
        &dir,
        &emitter_scene(
            r#"albedo = 0.0, temperature_grid = "temp", temperature_scale = 1500.0, emission_scale = 0.05"#,
        ),
        3,
    );
    let bb = blackbody_rgb(1500.0);
    assert!(bb[0] > 1.0, "{bb:?}");
    let le = [0, 1, 2].map(|c| f64::from(bb[c]) * 0.05);
    assert_image(&film, absorbing_emitter(le), "temperature grid");
}

#[test]
fn a_scattering_emitter_in_equilibrium_with_its_environment_is_invisible() {
    // Kirchhoff's law as a furnace test: a medium of any albedo α and phase function that
    // emits σ_a·L_e = (1 − α)σ_t·L_e inside an environment of radiance L_e leaves L = L_e
    // everywhere (L_e solves the transfer equation: absorption and emission cancel, in- and
    // out-scattering cancel). Emitting σ_t·L_e, or missing the scattered light, would not.
    let dir = TempDir::new("emission-furnace");
    volumes(&dir);
    let text = r#"
[camera]
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 34
[film]
width = 8
height = 8
spp = 256
max_depth = 256
[[light]]
type = "environment"
radiance = [1.2, 0.6, 0.3]
[[object]]
name = "ember"
shape = "sphere"
radius = 1.0
interior = { type = "voxel", file = "grids.vdb", albedo = [0.7, 0.4, 0.9], albedo_mode = "single", attenuation = [0.5, 1.0, 0.3], phase = { g = 0.5 }, emission_grid = "power", emission_color = [1.5, 0.75, 0.375], nee = "interior" }
"#;
    let film = render(&dir, text, 9);
    assert_image(&film, [1.2, 0.6, 0.3], "emitter in equilibrium");
}

/// A lit, scattering sphere of constant density.
fn lit_scene(interior: &str) -> String {
    format!(
        r#"
[camera]
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 34
[film]
width = 12
height = 12
spp = 128
max_depth = 64
[[light]]
type = "environment"
radiance = [0.3, 0.35, 0.45]
[[light]]
type = "distant"
direction = [0.5, 0.7, 0.4]
irradiance = 3.0
angular_radius = 3.0
[[object]]
name = "ball"
shape = "sphere"
radius = 1.0
interior = {interior}
"#
    )
}

fn exr(film: &Film) -> velour::image_io::ExrImage {
    film.to_exr_image(&BTreeMap::new())
}

fn assert_consistent(a: &Film, b: &Film, what: &str) {
    let z = compare(&exr(a), &exr(b))
        .unwrap_or_else(|e| panic!("{e}"))
        .z_test
        .unwrap_or_else(|| panic!("{what}: no variance layers"));
    assert!(z.consistent, "{what}: {z:?}");
}

#[test]
fn albedo_grids_of_constant_colour_match_the_constant_albedo() {
    let dir = TempDir::new("albedo");
    volumes(&dir);
    let common = r#"type = "voxel", file = "grids.vdb", attenuation = 0.4, phase = { g = 0.3 }, nee = "interior""#;
    let constant = render(
        &dir,
        &lit_scene(&format!("{{ {common}, albedo = [0.9, 0.5, 0.2] }}")),
        1,
    );
    let vec3 = render(
        &dir,
        &lit_scene(&format!("{{ {common}, albedo_grid = \"color\" }}")),
        2,
    );
    assert_consistent(&constant, &vec3, "Vec3 albedo grid vs constant albedo");
    // `shade` = 0.25 halfway between the ramp's stops at 0 and 0.5.
    let ramp = render(
        &dir,
        &lit_scene(&format!(
            "{{ {common}, albedo_grid = \"shade\", albedo_ramp = [[0.0, [1.0, 0.6, 0.3]], [0.5, [0.8, 0.4, 0.1]], [1.0, 0.0]] }}"
        )),
        3,
    );
    assert_consistent(&constant, &ramp, "ramped albedo grid vs constant albedo");
    // The albedo reaches the image: a grey albedo renders differently.
    let grey = render(
        &dir,
        &lit_scene(&format!("{{ {common}, albedo = 0.3 }}")),
        4,
    );
    let z = compare(&exr(&constant), &exr(&grey))
        .unwrap_or_else(|e| panic!("{e}"))
        .z_test
        .unwrap_or_else(|| panic!("no variance"));
    assert!(!z.consistent, "a different albedo must be detected: {z:?}");
}

#[test]
fn a_mixture_of_two_phase_functions_matches_the_weighted_double_hg_medium() {
    // Components (single-scattering albedos): σ_t = 2, α = 0.95, g = 0.8 and σ_t = 1, α = 0.6,
    // g = −0.5. Their sum is σ_t = 3, σ_s = 1.9 + 0.6 = 2.5, and the phase function at a
    // scattering event is the σ_s-weighted mixture: a double HG with w = 1.9/2.5 = 0.76.
    let dir = TempDir::new("mixture-phase");
    let mixture = lit_scene(
        r#"{ type = "mixture", nee = "interior", media = [
            { type = "homogeneous", albedo = 0.95, albedo_mode = "single", attenuation = 0.5, phase = { g = 0.8 } },
            { type = "homogeneous", albedo = 0.6, albedo_mode = "single", attenuation = 1.0, phase = { g = -0.5 } },
        ] }"#,
    );
    let single = lit_scene(
        r#"{ type = "homogeneous", albedo = 0.8333333, albedo_mode = "single", attenuation = 0.3333333, nee = "interior", phase = { type = "double_hg", g1 = 0.8, g2 = -0.5, w = 0.76 } }"#,
    );
    let a = render(&dir, &mixture, 11);
    let b = render(&dir, &single, 12);
    assert_consistent(&a, &b, "mixture vs weighted double HG");
    // The second medium as a grid of constant density 1: tracked with lookups (null
    // collisions, component chosen ∝ σ_t at each real one) instead of in closed form.
    volumes(&dir);
    let tracked = lit_scene(
        r#"{ type = "mixture", nee = "interior", media = [
            { type = "homogeneous", albedo = 0.95, albedo_mode = "single", attenuation = 0.5, phase = { g = 0.8 } },
            { type = "voxel", file = "grids.vdb", albedo = 0.6, albedo_mode = "single", attenuation = 1.0, phase = { g = -0.5 } },
        ] }"#,
    );
    let t = render(&dir, &tracked, 14);
    assert_consistent(&t, &b, "tracked mixture vs weighted double HG");
    // The phase functions matter here: swapping the lobes' weights is detected.
    let swapped = single.replace("w = 0.76", "w = 0.24");
    let c = render(&dir, &swapped, 13);
    let z = compare(&exr(&a), &exr(&c))
        .unwrap_or_else(|e| panic!("{e}"))
        .z_test
        .unwrap_or_else(|| panic!("no variance"));
    assert!(
        !z.consistent,
        "swapped lobe weights must be detected: {z:?}"
    );
}

#[test]
fn base_albedo_is_the_two_component_mixture() {
    let cloud = repo_path("volumes/cloud.vdb");
    let file = cloud.display();
    let scene = |interior: String| {
        format!(
            r#"
[camera]
eye = [0.0, 0.7, 3.6]
look_at = [0.0, 0.6, 0.0]
fov = 38
[film]
width = 16
height = 12
spp = 96
max_depth = 64
[[light]]
type = "environment"
radiance = [0.25, 0.35, 0.55]
[[light]]
type = "distant"
direction = [0.6, 0.7, 0.4]
irradiance = [4.0, 3.7, 3.3]
angular_radius = 5.0
[[object]]
name = "cloud"
shape = "bounds"
interior = {interior}
"#
        )
    };
    let shorthand = scene(format!(
        r#"{{ type = "voxel", file = "{file}", albedo = 0.9, albedo_mode = "single", attenuation = 0.05, base_albedo = [0.6, 0.7, 0.8], base_attenuation = [1.5, 2.0, 3.0], phase = {{ g = 0.3 }}, nee = "interior" }}"#
    ));
    let mixture = scene(format!(
        r#"{{ type = "mixture", nee = "interior", media = [
            {{ type = "voxel", file = "{file}", albedo = 0.9, albedo_mode = "single", attenuation = 0.05, phase = {{ g = 0.3 }} }},
            {{ type = "homogeneous", albedo = [0.6, 0.7, 0.8], albedo_mode = "single", attenuation = [1.5, 2.0, 3.0], phase = {{ g = 0.3 }} }},
        ] }}"#
    ));
    let dir = TempDir::new("base-mixture");
    let a = render(&dir, &shorthand, 21);
    let b = render(&dir, &mixture, 22);
    assert_consistent(&a, &b, "base_albedo shorthand vs explicit mixture");
}

/// The error of a scene that must not load.
fn error(dir: &TempDir, interior: &str) -> String {
    let text = lit_scene(interior);
    match load_scene_str(&text, &dir.join("scene.toml")) {
        Ok(_) => panic!("accepted: {interior}"),
        Err(e) => e.to_string(),
    }
}

fn assert_mentions(e: &str, needles: &[&str]) {
    for n in needles {
        assert!(e.contains(n), "`{n}` missing from: {e}");
    }
}

#[test]
fn bad_grids_ramps_and_mixtures_are_errors_naming_them() {
    let dir = TempDir::new("grids-bad");
    volumes(&dir);
    let voxel = r#"type = "voxel", file = "grids.vdb""#;
    // Colour and density grids with different transforms: both files and grids named.
    let e = error(
        &dir,
        &format!("{{ {voxel}, albedo_grid = \"color\", albedo_file = \"coarse.vdb\" }}"),
    );
    assert_mentions(
        &e,
        &[
            "scene.toml",
            "albedo_grid",
            "coarse.vdb",
            "grids.vdb",
            "`color`",
            "`density`",
            "different transform",
        ],
    );
    // A level set used as density.
    let e = error(
        &dir,
        r#"{ type = "voxel", file = "sdf.vdb", grid = "surface" }"#,
    );
    assert_mentions(&e, &["sdf.vdb", "`surface`", "level set"]);
    // Unknown grid names list the file's grids.
    let e = error(&dir, &format!("{{ {voxel}, albedo_grid = \"colour\" }}"));
    assert_mentions(&e, &["colour", "density", "color", "shade", "glow"]);
    let e = error(&dir, &format!("{{ {voxel}, temperature_grid = \"heat\" }}"));
    assert_mentions(&e, &["heat", "temp"]);
    // Ramps: unsorted, NaN, on a colour grid, missing for a scalar grid.
    let e = error(
        &dir,
        &format!("{{ {voxel}, albedo_grid = \"shade\", albedo_ramp = [[0.5, 0.2], [0.1, 0.9]] }}"),
    );
    assert_mentions(&e, &["albedo_ramp[1]", "sorted"]);
    let e = error(
        &dir,
        &format!("{{ {voxel}, albedo_grid = \"shade\", albedo_ramp = [[nan, 0.2], [1.0, 0.9]] }}"),
    );
    assert_mentions(&e, &["albedo_ramp[0]", "NaN"]);
    let e = error(
        &dir,
        &format!("{{ {voxel}, albedo_grid = \"shade\", albedo_ramp = [[0.0, 0.2], [1.0, 1.5]] }}"),
    );
    assert_mentions(&e, &["albedo_ramp[1]"]);
    let e = error(&dir, &format!("{{ {voxel}, albedo_grid = \"shade\" }}"));
    assert_mentions(&e, &["shade", "albedo_ramp"]);
    let e = error(
        &dir,
        &format!("{{ {voxel}, albedo_grid = \"color\", albedo_ramp = [[0.0, 0.2], [1.0, 0.9]] }}"),
    );
    assert_mentions(&e, &["albedo_ramp", "Vec3"]);
    let e = error(
        &dir,
        &format!("{{ {voxel}, albedo = 0.5, albedo_grid = \"color\" }}"),
    );
    assert_mentions(&e, &["albedo", "albedo_grid", "keep one"]);
    // Temperature scales: negative, NaN; emission keys without a grid.
    let e = error(
        &dir,
        &format!("{{ {voxel}, temperature_grid = \"temp\", temperature_scale = -100.0 }}"),
    );
    assert_mentions(&e, &["temperature_scale", "-100"]);
    let e = error(
        &dir,
        &format!("{{ {voxel}, temperature_grid = \"temp\", temperature_scale = nan }}"),
    );
    assert_mentions(&e, &["temperature_scale", "NaN"]);
    let e = error(&dir, &format!("{{ {voxel}, emission_color = 2.0 }}"));
    assert_mentions(&e, &["emission_color", "emission_grid"]);
    let e = error(
        &dir,
        &format!("{{ {voxel}, emission_grid = \"glow\", temperature_grid = \"temp\" }}"),
    );
    assert_mentions(&e, &["emission_grid", "temperature_grid", "keep one"]);
    // Mixtures: too few media, nee or tracking on an entry, a blend entry, a misspelt key
    // inside an entry (named with its file line), estimators mixtures do not have.
    let e = error(
        &dir,
        r#"{ type = "mixture", media = [{ type = "homogeneous" }] }"#,
    );
    assert_mentions(&e, &["mixture", "2 to 4", "has 1"]);
    let e = error(
        &dir,
        r#"{ type = "mixture", media = [{ type = "homogeneous", nee = "interior" }, { type = "homogeneous" }] }"#,
    );
    assert_mentions(&e, &["media[0]", "nee", "mixture itself"]);
    let e = error(
        &dir,
        r#"{ type = "mixture", media = [{ type = "homogeneous" }, { type = "absorption" }] }"#,
    );
    assert_mentions(
        &e,
        &["media[1]", "absorption", "cannot be a mixture component"],
    );
    let e = error(
        &dir,
        r#"{ type = "mixture", media = [{ type = "homogeneous" }, { type = "homogeneous", albdo = 0.3 }] }"#,
    );
    assert_mentions(
        &e,
        &["scene.toml:", "media[1]", "albdo", "did you mean `albedo`"],
    );
    let e = error(
        &dir,
        r#"{ type = "mixture", tracking = { free_flight = "ray_march", step = 0.1 }, media = [{ type = "homogeneous" }, { type = "homogeneous" }] }"#,
    );
    assert_mentions(&e, &["tracking.free_flight", "delta"]);
    let e = error(&dir, r#"{ type = "mixture", media = 3 }"#);
    assert_mentions(&e, &["media", "array of tables"]);
    // Every allowed entry type builds: homogeneous, voxel (with its grids) and fbm.
    let text = lit_scene(
        r#"{ type = "mixture", media = [
            { type = "homogeneous", albedo = 0.5 },
            { type = "voxel", file = "grids.vdb", albedo_grid = "color", emission_grid = "glow" },
            { type = "fbm", voxel_size = 0.1, noise = { frequency = 2.0, octaves = 2 } },
        ] }"#,
    );
    let scene = load_scene_str(&text, &dir.join("scene.toml")).unwrap_or_else(|e| panic!("{e}"));
    let (film, _) = render_finite(&scene, 0);
    assert!(film.mean(6, 6).is_finite());
}
