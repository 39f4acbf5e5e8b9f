//! The `velour render` command end to end: writes an EXR and a PNG, honours the film
//! overrides, and fails with a clear message and a non-zero exit on bad input.

mod common;

use common::cli::{run_velour, velour, Capture};
use common::files::TempDir;

const SPHERE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/skin_sphere.toml");

#[test]
fn renders_the_sphere_scene_to_exr_and_png() {
    let dir = TempDir::new("cli-render");
    let out = dir.join("skin.exr");
    let o = velour()
        .args([
            "render",
            SPHERE,
            "--spp",
            "2",
            "--width",
            "32",
            "--height",
            "24",
            "--seed",
            "5",
            "--threads",
            "2",
            "-q",
            "-o",
        ])
        .arg(&out)
        .capture();
    o.assert_success();
    assert!(
        o.stdout.contains("samples/s") && o.stdout.contains("rays"),
        "{}",
        o.stdout
    );
    let img = velour::image_io::read_exr(&out).expect("read back");
    assert_eq!((img.width, img.height), (32, 24));
    for ch in [
        "R",
        "G",
        "B",
        "variance.R",
        "albedo.R",
        "normal.X",
        "depth.Z",
    ] {
        assert!(
            img.channels.keys().any(|k| k == ch || k.ends_with(ch)),
            "missing channel {ch}: {:?}",
            img.channels.keys()
        );
    }
    assert!(out.with_extension("png").exists());
}

#[test]
fn bad_scene_fails_with_file_line_and_key() {
    let dir = TempDir::new("cli-render-bad");
    let scene = dir.join("bad.toml");
    std::fs::write(
        &scene,
        "[camera]\neye = [0, 0, 4]\nlook_at = [0, 0, 0]\nfvo = 30\n",
    )
    .expect("write");
    velour()
        .args(["render", "-q"])
        .arg(&scene)
        .capture()
        .assert_failure_mentioning(&["bad.toml:4", "fvo"]);
}

#[test]
fn absurd_overrides_are_refused() {
    run_velour(["render", SPHERE, "--spp", "0", "-q"]).assert_failure_mentioning(&["--spp"]);
}
