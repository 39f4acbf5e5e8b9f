//! The peer benchmarks' generated inputs (`tools/peers`): the icosphere generator feeds the skin
//! scene velour renders, and the fBm cloud's resampling onto a finer lattice leaves the
//! world-space field velour looks up unchanged (the premise of the 256³ and 512³ scenes). The
//! race itself (Mitsuba, Cycles) is not run here; see docs/peers.md.

mod common;

use std::path::Path;
use std::process::Command;

use common::cli::{run_velour, Capture};
use common::external::{require_python_openvdb, require_tool, run_python};
use common::files::{repo_path, TempDir};
use glam::Vec3;

fn peers_script(name: &str) -> String {
    repo_path("tools/peers").join(name).display().to_string()
}

/// A bench scene's text with its generated input redirected to `file`.
fn bench_scene_with(scene: &str, generated: &str, file: &Path) -> String {
    let text =
        std::fs::read_to_string(repo_path("tools/peers/bench").join(scene)).expect("bench scene");
    let from = format!("\"../generated/{generated}\"");
    assert!(text.contains(&from), "{scene} does not name {from}");
    text.replace(&from, &format!("{:?}", file.display().to_string()))
}

#[test]
fn icosphere_generator_writes_the_skin_mesh_velour_renders() {
    if !require_tool("python3", "python3") {
        return;
    }
    let dir = TempDir::new("peers-icosphere");
    let ply = dir.join("icosphere.ply");
    let out = Command::new("python3")
        .args([peers_script("make_icosphere.py"), ply.display().to_string()])
        .capture();
    assert!(out.success(), "make_icosphere.py failed: {}", out.stderr);
    let bytes = std::fs::read(&ply).expect("ply written");
    let header_end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .expect("PLY header");
    let header = String::from_utf8_lossy(&bytes[..header_end]);
    assert!(header.contains("element vertex 10242"), "{header}");
    assert!(header.contains("element face 20480"), "{header}");
    assert!(
        !header.contains("nx"),
        "the benchmark mesh must have no normals (flat facets)"
    );
    // 12-byte vertices, 13-byte triangles: nothing missing, nothing extra.
    assert_eq!(bytes.len() - header_end - 11, 10242 * 12 + 20480 * 13);

    let scene = dir.join("skin.toml");
    std::fs::write(
        &scene,
        bench_scene_with("skin_icosphere.toml", "icosphere_20k.ply", &ply),
    )
    .unwrap();
    let exr = dir.join("skin.exr");
    let r = run_velour([
        "render",
        scene.to_str().unwrap(),
        "--width",
        "16",
        "--height",
        "16",
        "--spp",
        "2",
        "--max-depth",
        "16",
        "--threads",
        "1",
        "-q",
        "-o",
        exr.to_str().unwrap(),
    ]);
    r.assert_success();
    // velour warns about an open mesh used as an interior boundary; the icosphere is closed.
    assert!(
        !r.stderr.contains("open"),
        "unexpected warning: {}",
        r.stderr
    );
}

#[test]
fn fbm_cloud_resampled_finer_keeps_the_world_field() {
    if !require_python_openvdb() {
        return;
    }
    let dir = TempDir::new("peers-fbm");
    let coarse = dir.join("cloud16.vdb");
    let fine = dir.join("cloud32.vdb");
    run_python([
        peers_script("make_fbm_cloud.py"),
        coarse.display().to_string(),
        "--res".into(),
        "16".into(),
    ]);
    run_python([
        peers_script("resample_grid.py"),
        coarse.display().to_string(),
        fine.display().to_string(),
        "--factor".into(),
        "2".into(),
    ]);
    let read = |p: &Path| {
        velour::vdb::read_vdb(p)
            .expect("velour reads the generated grid")
            .into_iter()
            .find(|g| g.name == "density")
            .expect("grid density")
            .grid
    };
    let (a, b) = (read(&coarse), read(&fine));
    assert!((a.voxel_size().x - 1.0 / 16.0).abs() < 1e-12);
    assert!((b.voxel_size().x - 1.0 / 32.0).abs() < 1e-12);
    // Random world points over the unit box and a little beyond (where both fields are 0).
    let mut state = 0x9E37_79B9_7F4A_7C15_u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f32 / (1u64 << 53) as f32
    };
    let (mut worst, mut largest) = (0.0f32, 0.0f32);
    for _ in 0..20_000 {
        let p = Vec3::new(next(), next(), next()) * 1.2 - Vec3::splat(0.6);
        let (va, vb) = (a.sample_trilinear_world(p), b.sample_trilinear_world(p));
        worst = worst.max((va - vb).abs());
        largest = largest.max(va);
    }
    // float32 rounding of the interpolation weights and values, ~1e-7 of the maximum 1.
    assert!(worst < 1e-5, "the resampled field differs by {worst}");
    assert!(
        largest > 0.5,
        "the points missed the cloud (largest value {largest})"
    );
}
