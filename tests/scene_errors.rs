//! Bad scene input gives a clear error naming the file, line and key — never a panic.

use std::path::Path;

use velour::scene::{load_scene, load_scene_str, SceneError};

const BASE: &str = r#"
[camera]
eye = [0, 0, 4]
look_at = [0, 0, 0]

[film]
width = 8
height = 8

[[light]]
type = "environment"

[[object]]
name = "skin"
shape = "sphere"
surface = { type = "dielectric", ior = 1.4, roughness = 0.3 }
interior = { type = "homogeneous", albedo = 0.8, attenuation = 0.5 }
"#;

fn err(text: &str) -> String {
    match load_scene_str(text, Path::new("bad.toml")) {
        Ok(_) => panic!("scene was accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn base_scene_loads() {
    load_scene_str(BASE, Path::new("ok.toml")).expect("base scene");
}

#[test]
fn misspelt_key_names_file_line_and_key() {
    let text = BASE.replace("width = 8", "widht = 8");
    let e = err(&text);
    assert!(e.contains("bad.toml:7"), "{e}");
    assert!(e.contains("widht"), "{e}");
}

#[test]
fn misspelt_key_in_inline_table_is_reported() {
    let text = BASE.replace("roughness = 0.3", "rougness = 0.3");
    let e = err(&text);
    assert!(e.contains("rougness") && e.contains("bad.toml:16"), "{e}");
}

#[test]
fn out_of_range_parameters_are_refused() {
    for (from, to, key) in [
        ("albedo = 0.8", "albedo = 1.2", "albedo"),
        ("albedo = 0.8", "albedo = -0.1", "albedo"),
        ("attenuation = 0.5", "attenuation = -1.0", "attenuation"),
        ("attenuation = 0.5", "attenuation = 0.0", "attenuation"),
        (
            "attenuation = 0.5",
            "attenuation = 0.5, density = -2.0",
            "density",
        ),
        ("attenuation = 0.5", "attenuation = nan", "attenuation"),
        ("ior = 1.4", "ior = 0.8", "ior"),
        ("roughness = 0.3", "roughness = 1.5", "roughness"),
        ("width = 8", "width = 0", "width"),
    ] {
        let text = BASE.replace(from, to);
        let e = err(&text);
        assert!(e.contains(key), "{to}: {e}");
        assert!(e.contains("bad.toml:"), "{to}: {e}");
    }
}

#[test]
fn keys_unused_by_the_chosen_type_are_errors() {
    let text = BASE.replace(
        "roughness = 0.3 }",
        "roughness = 0.3, transmittance = 0.5 }",
    );
    let e = err(&text);
    assert!(e.contains("transmittance"), "{e}");
    let text = BASE.replace(
        "attenuation = 0.5 }",
        "attenuation = 0.5, phase = { g = 0.3, w = 0.5 } }",
    );
    let e = err(&text);
    assert!(e.contains("`w`"), "{e}");
}

#[test]
fn unknown_types_list_the_allowed_ones() {
    let e = err(&BASE.replace("type = \"dielectric\"", "type = \"glass\""));
    assert!(e.contains("glass") && e.contains("dielectric"), "{e}");
    let e = err(&BASE.replace("shape = \"sphere\"", "shape = \"cube\""));
    assert!(e.contains("cube") && e.contains("mesh"), "{e}");
}

#[test]
fn missing_files_are_named() {
    let text = BASE.replace(
        "shape = \"sphere\"",
        "shape = \"mesh\"\nfile = \"does/not/exist.ply\"",
    );
    let e = err(&text);
    assert!(e.contains("does/not/exist.ply"), "{e}");
    match load_scene(Path::new("no/such/scene.toml")) {
        Err(SceneError::Io { path, .. }) => assert!(path.ends_with("scene.toml")),
        other => panic!("{other:?}"),
    }
}

#[test]
fn toml_syntax_errors_name_the_line() {
    let text = BASE.replace("eye = [0, 0, 4]", "eye = [0, 0, 4");
    let e = err(&text);
    assert!(e.contains("bad.toml:"), "{e}");
}

#[test]
fn keys_of_another_type_name_the_types_that_use_them() {
    let text = BASE.replace(
        "attenuation = 0.5 }",
        "attenuation = 0.5, resolution = 64 }",
    );
    let e = err(&text);
    assert!(e.starts_with("bad.toml:17: skin: interior: "), "{e}");
    assert!(
        e.contains("key `resolution` is not used by type \"homogeneous\" (only by \"fabric\")"),
        "{e}"
    );
}

#[test]
fn unknown_interior_types_name_the_line_and_the_choices() {
    let e = err(&BASE.replace("type = \"homogeneous\"", "type = \"nebula\""));
    assert!(
        e.starts_with("bad.toml:17: skin: interior.type = \"nebula\""),
        "{e}"
    );
    assert!(
        e.contains("\"voxel\", \"fbm\", \"fabric\", \"blend\" or \"mixture\""),
        "{e}"
    );
}

#[test]
fn a_value_of_the_wrong_type_names_its_key() {
    let text =
        "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\nfov = 30\n[film]\nwidth = \"wide\"\n";
    let e = velour::scene::load_scene_str(text, std::path::Path::new("typed.toml"))
        .expect_err("a string width is refused")
        .to_string();
    assert!(e.contains("typed.toml:6") && e.contains("`width`"), "{e}");
}
