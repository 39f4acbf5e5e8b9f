//! Every scene shipped in `scenes/` loads and renders (tiny, one sample per pixel) to a finite
//! image without warnings, so a scene file cannot rot unnoticed.

mod common;

use common::cli::run_velour;
use common::files::{repo_path, TempDir};
use velour::image_io::read_exr;

#[test]
fn every_shipped_scene_renders() {
    let dir = TempDir::new("shipped");
    let mut scenes: Vec<_> = std::fs::read_dir(repo_path("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 9, "{scenes:?}");
    for scene in &scenes {
        let name = scene.file_stem().unwrap().to_string_lossy().to_string();
        let out = dir.join(format!("{name}.exr"));
        let r = run_velour([
            "render",
            scene.to_str().unwrap(),
            "--width",
            "24",
            "--height",
            "18",
            "--spp",
            "1",
            "-q",
            "-o",
            out.to_str().unwrap(),
        ]);
        r.assert_success();
        assert!(!r.stderr.contains("warning:"), "{name}: {}", r.stderr);
        let img = read_exr(&out).unwrap();
        for c in ["R", "G", "B"] {
            assert!(
                img.channels[c].iter().all(|v| v.is_finite() && *v >= 0.0),
                "{name}: {c}"
            );
        }
    }
}
