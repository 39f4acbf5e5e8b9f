//! The `velour render` command end to end: writes an EXR and a PNG, honours the film
//! overrides, and fails with a clear message and a non-zero exit on bad input.

use std::path::PathBuf;
use std::process::Command;

fn velour() -> Command {
    Command::new(env!("CARGO_BIN_EXE_velour"))
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("velour-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

#[test]
fn renders_the_sphere_scene_to_exr_and_png() {
    let dir = temp_dir("render");
    let out = dir.join("skin.exr");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/skin_sphere.toml");
    let o = velour()
        .args([
            "render",
            scene,
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
        .output()
        .expect("run velour");
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("samples/s") && stdout.contains("rays"),
        "{stdout}"
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
    let dir = temp_dir("bad");
    let scene = dir.join("bad.toml");
    std::fs::write(
        &scene,
        "[camera]\neye = [0, 0, 4]\nlook_at = [0, 0, 0]\nfvo = 30\n",
    )
    .expect("write");
    let o = velour()
        .args(["render", "-q"])
        .arg(&scene)
        .output()
        .expect("run velour");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.toml:4") && err.contains("fvo"), "{err}");
}

#[test]
fn absurd_overrides_are_refused() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/skin_sphere.toml");
    let o = velour()
        .args(["render", scene, "--spp", "0", "-q"])
        .output()
        .expect("run velour");
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--spp"));
}
