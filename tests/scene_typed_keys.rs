//! Lights, surfaces and interiors have one description per `type`: for every type, a misspelt
//! key and a key that only another type uses are errors naming the file, the key and the
//! key's own line, whether the table is written on its own lines or inline.

use std::path::Path;

use velour::scene::load_scene_str;

const HEAD: &str =
    "[camera]\neye = [0, 0, 4]\nlook_at = [0, 0, 0]\n\n[film]\nwidth = 8\nheight = 8\n";

/// One bad-key case: the table's `type`, a key of that type misspelt, and a key that only
/// other types use (with one of them).
struct Case {
    kind: &'static str,
    good: &'static str,
    misspelt: &'static str,
    foreign: &'static str,
    foreign_owner: &'static str,
}

const LIGHTS: [Case; 4] = [
    Case {
        kind: "environment",
        good: "radiance",
        misspelt: "radance",
        foreign: "file",
        foreign_owner: "envmap",
    },
    Case {
        kind: "envmap",
        good: "rotation",
        misspelt: "rotaton",
        foreign: "direction",
        foreign_owner: "distant",
    },
    Case {
        kind: "distant",
        good: "irradiance",
        misspelt: "iradiance",
        foreign: "center",
        foreign_owner: "sphere",
    },
    Case {
        kind: "sphere",
        good: "radius",
        misspelt: "radis",
        foreign: "scale",
        foreign_owner: "envmap",
    },
];

const SURFACES: [Case; 5] = [
    Case {
        kind: "dielectric",
        good: "roughness",
        misspelt: "rougness",
        foreign: "transmittance",
        foreign_owner: "diffuse_transmission",
    },
    Case {
        kind: "diffuse_transmission",
        good: "transmittance",
        misspelt: "transmitance",
        foreign: "ior",
        foreign_owner: "dielectric",
    },
    Case {
        kind: "lambertian",
        good: "reflectance",
        misspelt: "reflectanse",
        foreign: "roughness",
        foreign_owner: "conductor",
    },
    Case {
        kind: "conductor",
        good: "distribution",
        misspelt: "distribtion",
        foreign: "tint",
        foreign_owner: "dielectric",
    },
    Case {
        kind: "blend",
        good: "mask",
        misspelt: "msk",
        foreign: "ior",
        foreign_owner: "dielectric",
    },
];

const INTERIORS: [Case; 8] = [
    Case {
        kind: "absorption",
        good: "attenuation",
        misspelt: "atenuation",
        foreign: "albedo",
        foreign_owner: "homogeneous",
    },
    Case {
        kind: "homogeneous",
        good: "albedo",
        misspelt: "albdo",
        foreign: "pattern",
        foreign_owner: "fabric",
    },
    Case {
        kind: "voxel",
        good: "base_albedo",
        misspelt: "base_albdo",
        foreign: "noise",
        foreign_owner: "fbm",
    },
    Case {
        kind: "fbm",
        good: "voxel_size",
        misspelt: "voxel_sise",
        foreign: "file",
        foreign_owner: "voxel",
    },
    Case {
        kind: "fabric",
        good: "pattern",
        misspelt: "patern",
        foreign: "albedo",
        foreign_owner: "homogeneous",
    },
    Case {
        kind: "blend",
        good: "mask",
        misspelt: "msk",
        foreign: "albedo",
        foreign_owner: "homogeneous",
    },
    Case {
        kind: "mixture",
        good: "tracking",
        misspelt: "trackng",
        foreign: "albedo",
        foreign_owner: "homogeneous",
    },
    Case {
        kind: "voxel",
        good: "albedo_grid",
        misspelt: "albedo_gird",
        foreign: "noise",
        foreign_owner: "fbm",
    },
];

/// The error of a scene that must not load.
fn err(text: &str) -> String {
    match load_scene_str(text, Path::new("bad.toml")) {
        Ok(_) => panic!("scene was accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

/// The text so far plus `line`, and the 1-based number of that line.
fn push(text: &mut String, line: &str) -> usize {
    text.push_str(line);
    text.push('\n');
    text.lines().count()
}

/// A scene whose `[[light]]` of type `kind` has `key` on a line of its own; the line number.
fn light_scene(kind: &str, key: &str) -> (String, usize) {
    let mut text = HEAD.to_string();
    push(&mut text, "[[light]]");
    push(&mut text, &format!("type = \"{kind}\""));
    let line = push(&mut text, &format!("{key} = 0.5"));
    push(&mut text, "");
    (text, line)
}

/// A scene with an object whose `table` ("surface" or "interior") of type `kind` has `key`:
/// as a sub-table on lines of its own, or inline on the object's line `table = { ... }`.
fn object_scene(table: &str, kind: &str, key: &str, inline: bool) -> (String, usize) {
    let mut text = HEAD.to_string();
    push(&mut text, "[[light]]\ntype = \"environment\"\n");
    push(
        &mut text,
        "[[object]]\nname = \"thing\"\nshape = \"sphere\"",
    );
    let line = if inline {
        push(
            &mut text,
            &format!("{table} = {{ type = \"{kind}\", {key} = 0.5 }}"),
        )
    } else {
        push(&mut text, &format!("\n[object.{table}]"));
        push(&mut text, &format!("type = \"{kind}\""));
        push(&mut text, &format!("{key} = 0.5"))
    };
    push(&mut text, "");
    (text, line)
}

/// Checks the two errors of one case; `scene(key)` writes the key, returning the text and
/// the line the error must name.
fn check(case: &Case, owner: &str, scene: impl Fn(&str) -> (String, usize)) {
    let (text, line) = scene(case.misspelt);
    let e = err(&text);
    let at = format!("bad.toml:{line}: ");
    assert!(e.starts_with(&at), "{}: wanted {at}: {e}", case.kind);
    assert!(e.contains(owner), "{}: {e}", case.kind);
    assert!(
        e.contains(&format!("unknown key `{}`", case.misspelt)),
        "{e}"
    );
    assert!(e.contains(&format!("type \"{}\"", case.kind)), "{e}");
    // The right spelling: suggested, or the only key the type takes.
    let suggested = format!("did you mean `{}`", case.good);
    let only = format!("(expected `{}`)", case.good);
    assert!(e.contains(&suggested) || e.contains(&only), "{e}");

    let (text, line) = scene(case.foreign);
    let e = err(&text);
    let at = format!("bad.toml:{line}: ");
    assert!(e.starts_with(&at), "{}: wanted {at}: {e}", case.kind);
    assert!(e.contains(owner), "{}: {e}", case.kind);
    let not_used = format!(
        "key `{}` is not used by type \"{}\"",
        case.foreign, case.kind
    );
    assert!(e.contains(&not_used), "{e}");
    assert!(e.contains(&format!("\"{}\"", case.foreign_owner)), "{e}");
}

#[test]
fn every_light_type_names_a_misspelt_or_foreign_key_and_its_line() {
    for case in &LIGHTS {
        check(case, "light: ", |key| light_scene(case.kind, key));
    }
}

#[test]
fn every_surface_type_names_a_misspelt_or_foreign_key_and_its_line() {
    for case in &SURFACES {
        for inline in [false, true] {
            check(case, "thing: surface: ", |key| {
                object_scene("surface", case.kind, key, inline)
            });
        }
    }
}

#[test]
fn every_interior_type_names_a_misspelt_or_foreign_key_and_its_line() {
    for case in &INTERIORS {
        for inline in [false, true] {
            check(case, "thing: interior: ", |key| {
                object_scene("interior", case.kind, key, inline)
            });
        }
    }
}

#[test]
fn the_cases_use_real_keys() {
    // A misspelt key becomes the good one again and the scene reads past it: the error is
    // then about something else (a missing file, nothing at all), never an unknown key.
    for (table, cases) in [("surface", &SURFACES[..]), ("interior", &INTERIORS[..])] {
        for case in cases {
            let (text, _) = object_scene(table, case.kind, case.good, false);
            if let Err(e) = load_scene_str(&text, Path::new("ok.toml")) {
                let e = e.to_string();
                assert!(!e.contains("unknown key") && !e.contains("not used"), "{e}");
            }
        }
    }
    for case in &LIGHTS {
        let (text, _) = light_scene(case.kind, case.good);
        if let Err(e) = load_scene_str(&text, Path::new("ok.toml")) {
            let e = e.to_string();
            assert!(!e.contains("unknown key") && !e.contains("not used"), "{e}");
        }
    }
}

#[test]
fn a_missing_or_unknown_type_is_named_with_the_choices() {
    let (text, _) = object_scene("interior", "homogeneous", "albedo", false);
    let no_type = text.replace("type = \"homogeneous\"\n", "");
    let e = err(&no_type);
    assert!(e.contains("thing: interior: missing key `type`"), "{e}");
    assert!(e.contains("\"fabric\""), "{e}");

    let (text, line) = light_scene("environment", "radiance");
    let e = err(&text.replace("\"environment\"", "\"spot\""));
    assert!(e.starts_with(&format!("bad.toml:{}: ", line - 1)), "{e}");
    assert!(e.contains("light.type = \"spot\" is unknown"), "{e}");
    assert!(e.contains("\"sphere\""), "{e}");

    let e = err(&text.replace("\"environment\"", "3"));
    assert!(e.contains("light.type must be a string"), "{e}");
}

#[test]
fn keys_of_tables_nested_in_a_typed_table_keep_their_own_line() {
    // `coat` belongs to every surface type; a misspelt key inside it is the coat's.
    let mut text = HEAD.to_string();
    push(&mut text, "[[light]]\ntype = \"environment\"\n");
    push(
        &mut text,
        "[[object]]\nname = \"thing\"\nshape = \"sphere\"\n",
    );
    push(&mut text, "[object.surface]\ntype = \"lambertian\"");
    push(&mut text, "[object.surface.coat]\nior = 1.5");
    let line = push(&mut text, "wieght = 0.5");
    let e = err(&text);
    assert!(e.starts_with(&format!("bad.toml:{line}: ")), "{e}");
    assert!(e.contains("unknown key `wieght`"), "{e}");
    assert!(e.contains("did you mean `weight`"), "{e}");
    assert!(!e.contains("type \"lambertian\""), "{e}");
}

#[test]
fn object_and_top_level_keys_suggest_the_right_spelling() {
    let (text, _) = object_scene("interior", "homogeneous", "albedo", true);
    let e = err(&text.replace("interior = {", "interor = {"));
    assert!(e.contains("thing: unknown key `interor`"), "{e}");
    assert!(e.contains("did you mean `interior`"), "{e}");
    let e = err(&text.replace("shape = ", "shpae = "));
    assert!(e.contains("did you mean `shape`"), "{e}");
    let e = err(&text.replace("width = 8", "widht = 8"));
    assert!(e.starts_with("bad.toml:6: unknown key `widht`"), "{e}");
    assert!(e.contains("did you mean `width`"), "{e}");
    let e = err(&text.replace("[camera]", "[camra]"));
    assert!(
        e.starts_with("bad.toml:1: ") && e.contains("did you mean `camera`"),
        "{e}"
    );
    let e = err(&text.replace("[[light]]", "[light]"));
    assert!(e.contains("[[light]]"), "{e}");
}

#[test]
fn fabric_interiors_refuse_the_combined_base_medium() {
    // The base medium of a combined interior belongs to voxel and fbm interiors only.
    let (text, line) = object_scene("interior", "fabric", "base_albedo", false);
    let e = err(&text);
    assert!(e.starts_with(&format!("bad.toml:{line}: ")), "{e}");
    assert!(e.contains("\"voxel\" or \"fbm\""), "{e}");
}
