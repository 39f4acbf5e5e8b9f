//! Per-light beauty layers: lights with a `name` get their own `light.<name>.R/G/B` layer;
//! with every light named the layers sum to the beauty; the layers split and merge exactly
//! like the beauty; bad names are refused.

mod common;

use std::path::Path;

use common::cli::run_velour;
use common::files::{repo_path, TempDir};
use common::render::pixel_bits;
use velour::image_io::read_exr;

/// The skin sphere with its two lights named `sky` and `key` (the key only when `both`).
fn named_scene(dir: &TempDir, both: bool) -> std::path::PathBuf {
    let text = std::fs::read_to_string(repo_path("scenes/skin_sphere.toml"))
        .unwrap()
        .replace("type = \"distant\"", "type = \"distant\"\nname = \"key\"")
        .replace(
            "type = \"environment\"",
            if both {
                "type = \"environment\"\nname = \"sky\""
            } else {
                "type = \"environment\""
            },
        )
        .replace(
            "meshes/backdrop.ply",
            &repo_path("scenes/meshes/backdrop.ply")
                .display()
                .to_string(),
        );
    let path = dir.join(if both { "both.toml" } else { "key.toml" });
    std::fs::write(&path, text).unwrap();
    path
}

fn render(scene: &Path, out: &Path, extra: &[&str]) {
    let mut args = vec![
        "render".to_string(),
        scene.display().to_string(),
        "--width".into(),
        "40".into(),
        "--height".into(),
        "30".into(),
        "--spp".into(),
        "8".into(),
        "-q".into(),
        "-o".into(),
        out.display().to_string(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    run_velour(&args).assert_success();
}

#[test]
fn named_lights_have_layers_that_sum_to_the_beauty() {
    let dir = TempDir::new("light-layers");
    let scene = named_scene(&dir, true);
    let out = dir.join("both.exr");
    render(&scene, &out, &[]);
    let img = read_exr(&out).unwrap();
    let ch = |n: &str| &img.channels[n];
    let mut key_total = 0.0f64;
    for c in ["R", "G", "B"] {
        let (beauty, sky, key) = (
            ch(c),
            ch(&format!("light.sky.{c}")),
            ch(&format!("light.key.{c}")),
        );
        for i in 0..beauty.len() {
            let sum = sky[i] + key[i];
            assert!(
                (sum - beauty[i]).abs() <= 1e-5 * beauty[i].abs() + 1e-7,
                "pixel {i} {c}: sky {} + key {} != beauty {}",
                sky[i],
                key[i],
                beauty[i]
            );
            assert!(sky[i] >= 0.0 && key[i] >= 0.0);
            key_total += f64::from(key[i]);
        }
    }
    assert!(key_total > 0.0, "the key light contributes");

    // Only the key named: one layer, no larger than the beauty.
    let scene = named_scene(&dir, false);
    let out = dir.join("key.exr");
    render(&scene, &out, &[]);
    let img = read_exr(&out).unwrap();
    assert!(img.channels.contains_key("light.key.R"));
    assert!(!img.channels.keys().any(|k| k.starts_with("light.sky")));
    for (b, k) in img.channels["R"].iter().zip(&img.channels["light.key.R"]) {
        assert!(*k <= *b * (1.0 + 1e-5) + 1e-7);
    }
}

#[test]
fn light_layers_merge_exactly() {
    let dir = TempDir::new("light-layers-merge");
    let scene = named_scene(&dir, true);
    let one = dir.join("one.exr");
    render(&scene, &one, &[]);
    let (a, b) = (dir.join("a.exr"), dir.join("b.exr"));
    render(&scene, &a, &["--samples", "0..3"]);
    render(&scene, &b, &["--samples", "3..8"]);
    let merged = dir.join("merged.exr");
    run_velour([
        "merge",
        "-o",
        merged.to_str().unwrap(),
        a.to_str().unwrap(),
        b.to_str().unwrap(),
    ])
    .assert_success();
    let (x, y) = (pixel_bits(&one), pixel_bits(&merged));
    assert!(x.contains_key("light.key.G"));
    assert!(x == y, "merged light layers differ from one render");
}

#[test]
fn bad_light_names_are_refused() {
    let dir = TempDir::new("light-names");
    let base = "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 30\n\n[film]\nwidth = 8\nheight = 6\nspp = 1\n";
    let light = |name: &str| {
        format!("\n[[light]]\ntype = \"environment\"\nradiance = 0.1\nname = \"{name}\"\n")
    };
    let cases = [
        (
            format!("{base}{}{}", light("sky"), light("sky")),
            "used by another light",
        ),
        (format!("{base}{}", light("my sky")), "letters, digits"),
        (format!("{base}{}", light("")), "letters, digits"),
        (
            format!(
                "{base}{}",
                (0..9).map(|i| light(&format!("l{i}"))).collect::<String>()
            ),
            "at most 8 lights",
        ),
    ];
    for (i, (text, needle)) in cases.iter().enumerate() {
        let path = dir.join(format!("bad{i}.toml"));
        std::fs::write(&path, text).unwrap();
        run_velour([
            "render",
            path.to_str().unwrap(),
            "-q",
            "-o",
            dir.join("x.exr").to_str().unwrap(),
        ])
        .assert_failure_mentioning(&[needle, &format!("bad{i}.toml")]);
    }
}
