//! Split renders put back together: tiles and sample ranges merged by `velour merge`, and a
//! render stopped by SIGTERM and resumed, give the same bits as one uninterrupted render; parts
//! that do not belong together are refused and nothing is written.

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::cli::{run_velour, velour};
use common::files::{repo_path, TempDir};
use common::render::pixel_bits;
use velour::image_io::read_exr;

const SIZE: [&str; 4] = ["--width", "40", "--height", "30"];

fn scene() -> PathBuf {
    repo_path("scenes/skin_sphere.toml")
}

/// Renders with the common size and `extra` arguments, asserting success.
fn render(extra: &[&str]) {
    let mut args: Vec<String> = vec!["render".into(), scene().display().to_string()];
    args.extend(SIZE.iter().map(|s| s.to_string()));
    args.extend(["-q", "--threads", "2"].iter().map(|s| s.to_string()));
    args.extend(extra.iter().map(|s| s.to_string()));
    run_velour(&args).assert_success();
}

fn merge(out: &Path, parts: &[PathBuf]) -> common::cli::Captured {
    let mut args = vec!["merge".to_string(), "-o".into(), out.display().to_string()];
    args.extend(parts.iter().map(|p| p.display().to_string()));
    run_velour(&args)
}

#[test]
fn tiles_and_sample_ranges_merge_to_the_same_bits() {
    let dir = TempDir::new("farm-merge");
    let one = dir.join("one.exr");
    render(&["--spp", "8", "-o", one.to_str().unwrap()]);
    let reference = pixel_bits(&one);
    assert!(reference.contains_key("variance.R") && reference.contains_key("albedo.G"));

    // 4 tiles (bands of 7 or 8 rows), each in two sample ranges.
    let mut parts = Vec::new();
    for t in 0..4 {
        for (a, b) in [(0, 3), (3, 8)] {
            let p = dir.join(format!("t{t}.s{a}.exr"));
            render(&[
                "--spp",
                "8",
                "--tile",
                &format!("{t}/4"),
                "--samples",
                &format!("{a}..{b}"),
                "-o",
                p.to_str().unwrap(),
            ]);
            parts.push(p);
        }
    }
    let merged = dir.join("merged.exr");
    merge(&merged, &parts).assert_success();
    assert!(
        pixel_bits(&merged) == reference,
        "tiles x ranges merge differs from one render"
    );

    // 4 sample passes, given to merge in a shuffled order.
    let mut passes = Vec::new();
    for (a, b) in [(0, 1), (1, 2), (2, 5), (5, 8)] {
        let p = dir.join(format!("pass{a}.exr"));
        render(&[
            "--spp",
            "8",
            "--samples",
            &format!("{a}..{b}"),
            "-o",
            p.to_str().unwrap(),
        ]);
        passes.push(p);
    }
    passes.swap(0, 3);
    let merged_passes = dir.join("merged_passes.exr");
    merge(&merged_passes, &passes).assert_success();
    assert!(
        pixel_bits(&merged_passes) == reference,
        "sample passes merge differs"
    );
    let attrs = read_exr(&merged_passes).unwrap().attributes;
    for key in [
        "velour:version",
        "velour:scene_hash",
        "velour:seed",
        "velour:spp",
    ] {
        assert!(attrs.contains_key(key), "{key} missing from {attrs:?}");
    }

    // Refusals: a missing range, an overlap, another seed, a corrupt part, a final image.
    let bad = dir.join("bad.exr");
    // passes[..3] holds 5..8, 1..2 and 2..5 (after the swap): 0..1 is missing.
    merge(&bad, &passes[..3]).assert_failure_mentioning(&["samples 0..1", "missing"]);
    let overlap = dir.join("overlap.exr");
    render(&[
        "--spp",
        "8",
        "--samples",
        "4..8",
        "-o",
        overlap.to_str().unwrap(),
    ]);
    let mut with_overlap = passes.clone();
    with_overlap.push(overlap);
    merge(&bad, &with_overlap).assert_failure_mentioning(&["both hold samples"]);
    let seeded = dir.join("seeded.exr");
    render(&[
        "--spp",
        "8",
        "--samples",
        "5..8",
        "--seed",
        "99",
        "-o",
        seeded.to_str().unwrap(),
    ]);
    let mut mixed: Vec<PathBuf> = passes
        .iter()
        .filter(|p| !p.ends_with("pass5.exr"))
        .cloned()
        .collect();
    mixed.push(seeded.clone());
    merge(&bad, &mixed).assert_failure_mentioning(&["seeded.exr", "seed"]);
    let corrupt = dir.join("corrupt.exr");
    let bytes = std::fs::read(&passes[0]).unwrap();
    std::fs::write(&corrupt, &bytes[..bytes.len() / 2]).unwrap();
    let mut with_corrupt = passes[1..].to_vec();
    with_corrupt.push(corrupt);
    merge(&bad, &with_corrupt).assert_failure_mentioning(&["corrupt.exr"]);
    merge(&bad, std::slice::from_ref(&one))
        .assert_failure_mentioning(&["one.exr", "not a velour part"]);
    assert!(!bad.exists(), "a refused merge wrote its output");

    // Bad splits are refused by render itself.
    let mut args: Vec<String> = vec!["render".into(), scene().display().to_string()];
    args.extend(SIZE.iter().map(|s| s.to_string()));
    for (flag, value, needle) in [
        ("--tile", "4/4", "0 <= I < N"),
        ("--tile", "0/31", "at most 30 tiles"),
        ("--samples", "6..9", "beyond the render's 8 spp"),
        ("--samples", "5..5", "A < B"),
    ] {
        let mut a = args.clone();
        a.extend(
            ["--spp", "8", flag, value, "-o"]
                .iter()
                .map(|s| s.to_string()),
        );
        a.push(dir.join("x.exr").display().to_string());
        run_velour(&a).assert_failure_mentioning(&[needle]);
    }
}

#[test]
fn a_render_stopped_by_sigterm_resumes_to_the_same_bits() {
    let dir = TempDir::new("farm-resume");
    // Adaptive sampling is on, so the resumed mask of converged pixels is checked too.
    let spp = "600";
    let adaptive = ["--noise-threshold", "0.02", "--min-spp", "8"];
    let full = dir.join("full.exr");
    let mut a = vec!["--spp", spp, "-o", full.to_str().unwrap()];
    a.extend(adaptive);
    render(&a);

    let out = dir.join("frame.exr");
    let partial = dir.join("frame.partial.exr");
    let mut child = velour()
        .args(["render", scene().to_str().unwrap()])
        .args(SIZE)
        .args([
            "-q",
            "--threads",
            "1",
            "--spp",
            spp,
            "-o",
            out.to_str().unwrap(),
        ])
        .args(["--checkpoint-every", "0.2"])
        .args(adaptive)
        .spawn()
        .unwrap();
    // Wait for the first checkpoint, then stop the render.
    let start = Instant::now();
    while !partial.exists() && start.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(100));
    // SAFETY: kill sends a signal to the child we spawned; no memory is touched.
    unsafe {
        libc::kill(child.id() as i32, libc::SIGTERM);
    }
    let status = child.wait().unwrap();
    if status.success() {
        // The render finished before the signal arrived: nothing to resume (a fast machine).
        assert!(pixel_bits(&out) == pixel_bits(&full));
        eprintln!("note: the render finished before SIGTERM; resume not exercised");
        return;
    }
    assert!(partial.exists(), "no checkpoint after SIGTERM");
    assert!(
        !out.exists(),
        "the final name appeared before the render was complete"
    );
    let done: u32 = read_exr(&partial).unwrap().attributes["velour:done"]
        .parse()
        .unwrap();
    assert!(done < 600);

    // Another seed may not resume this checkpoint.
    let mut args: Vec<String> = vec!["render".into(), scene().display().to_string()];
    args.extend(SIZE.iter().map(|s| s.to_string()));
    args.extend(
        ["-q", "--spp", spp, "--resume", "--seed", "7", "-o"]
            .iter()
            .map(|s| s.to_string()),
    );
    args.push(out.display().to_string());
    run_velour(&args).assert_failure_mentioning(&["frame.partial.exr", "seed"]);

    let mut a = vec!["--spp", spp, "--resume", "-o", out.to_str().unwrap()];
    a.extend(adaptive);
    render(&a);
    assert!(
        pixel_bits(&out) == pixel_bits(&full),
        "resumed render differs from the uninterrupted one"
    );
    assert!(
        !partial.exists(),
        "the checkpoint is removed once the image is complete"
    );
}

#[test]
fn frame_ranges_substitute_the_frame_number() {
    let dir = TempDir::new("farm-frames");
    // Frame N reads backdropN.ply: the scene's input paths are substituted too.
    for f in [3, 4] {
        std::fs::copy(
            repo_path("scenes/meshes/backdrop.ply"),
            dir.join(format!("backdrop{f}.ply")),
        )
        .unwrap();
    }
    let text = std::fs::read_to_string(scene())
        .unwrap()
        .replace("meshes/backdrop.ply", "backdrop{frame}.ply");
    let framed = dir.join("framed.toml");
    std::fs::write(&framed, text).unwrap();
    let pattern = dir.join("f{frame:03}.exr");
    let mut args: Vec<String> = vec!["render".into(), framed.display().to_string()];
    args.extend(SIZE.iter().map(|s| s.to_string()));
    args.extend(
        ["-q", "--spp", "1", "--frames", "3..=4", "-o"]
            .iter()
            .map(|s| s.to_string()),
    );
    args.push(pattern.display().to_string());
    run_velour(&args).assert_success();
    let hashes: Vec<String> = ["f003.exr", "f004.exr"]
        .iter()
        .map(|f| {
            let img = read_exr(&dir.join(f)).unwrap();
            assert!(img.attributes.contains_key("velour:frame"), "{f}");
            img.attributes["velour:scene_hash"].clone()
        })
        .collect();
    assert_ne!(hashes[0], hashes[1], "the frames' scene texts differ");
    // A changed input of one frame changes that frame's hash.
    std::fs::write(dir.join("backdrop4.ply"), b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n").unwrap();
    run_velour(&args).assert_success();
    let h4 = read_exr(&dir.join("f004.exr")).unwrap().attributes["velour:scene_hash"].clone();
    assert_ne!(h4, hashes[1], "a changed input file changes the hash");
    let mut no_placeholder: Vec<String> = vec!["render".into(), framed.display().to_string()];
    no_placeholder.extend(["--frames", "1..3", "-o"].iter().map(|s| s.to_string()));
    no_placeholder.push(dir.join("same.exr").display().to_string());
    run_velour(&no_placeholder).assert_failure_mentioning(&["{frame}"]);
}

/// The per-pixel sample counts of an image.
fn sample_counts(path: &Path) -> Vec<f32> {
    read_exr(path).unwrap().channels["samples.N"].clone()
}

#[test]
fn adaptive_sampling_stops_flat_pixels_and_spends_on_noisy_ones() {
    let dir = TempDir::new("farm-adaptive");
    // A flat scene: a constant environment and nothing else; every sample is the same.
    let flat = dir.join("flat.toml");
    std::fs::write(
        &flat,
        "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nfov = 30\n\n[film]\nwidth = 16\nheight = 12\nspp = 256\n\n[[light]]\ntype = \"environment\"\nradiance = [0.3, 0.4, 0.5]\n",
    )
    .unwrap();
    let out = dir.join("flat.exr");
    run_velour([
        "render",
        flat.to_str().unwrap(),
        "-q",
        "--noise-threshold",
        "0.01",
        "--min-spp",
        "8",
        "-o",
        out.to_str().unwrap(),
    ])
    .assert_success();
    assert!(
        sample_counts(&out).iter().all(|&n| n == 8.0),
        "a flat image stops at --min-spp"
    );

    // The skin sphere: smooth background pixels stop early, noisy ones take more samples.
    let out = dir.join("skin.exr");
    render(&[
        "--spp",
        "256",
        "--noise-threshold",
        "0.08",
        "-o",
        out.to_str().unwrap(),
    ]);
    let n = sample_counts(&out);
    let (min, max) = n
        .iter()
        .fold((f32::MAX, 0f32), |(a, b), &v| (a.min(v), b.max(v)));
    assert!(
        min >= 16.0 && min < max,
        "counts {min}..{max}: the default minimum is 16"
    );
    assert!(
        n.iter()
            .all(|&v| v == 16.0 || v == 256.0 || v % 16.0 == 0.0),
        "tests run every 16 samples"
    );
    let mean = n.iter().sum::<f32>() / n.len() as f32;
    assert!(
        mean < 200.0,
        "adaptive sampling saved nothing (mean spp {mean})"
    );

    // A time limit ends the render early with whole passes.
    let out = dir.join("timed.exr");
    let start = std::time::Instant::now();
    render(&[
        "--spp",
        "1000000",
        "--time-limit",
        "0.5",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(start.elapsed() < Duration::from_secs(20));
    let n = sample_counts(&out);
    assert!(n[0] >= 1.0 && n[0] < 1_000_000.0 && n.iter().all(|&v| v == n[0]));

    // Refused combinations.
    let mut args: Vec<String> = vec!["render".into(), scene().display().to_string()];
    args.extend(SIZE.iter().map(|s| s.to_string()));
    for (extra, needle) in [
        (
            vec![
                "--samples",
                "0..4",
                "--spp",
                "8",
                "--noise-threshold",
                "0.1",
            ],
            "cannot be combined",
        ),
        (vec!["--noise-threshold=-1"], "positive"),
        (vec!["--min-spp", "4"], "needs --noise-threshold"),
        (vec!["--time-limit", "nan"], "positive number of seconds"),
    ] {
        let mut a = args.clone();
        a.extend(extra.iter().map(|s| s.to_string()));
        run_velour(&a).assert_failure_mentioning(&[needle]);
    }
}

#[test]
fn volume_aovs_come_from_the_first_medium_event() {
    let dir = TempDir::new("farm-aov");
    let out = dir.join("skin.exr");
    render(&["--spp", "16", "-o", out.to_str().unwrap()]);
    let img = read_exr(&out).unwrap();
    let (w, h) = (img.width as usize, img.height as usize);
    let ch = |name: &str| &img.channels[name];
    // The centre pixel sees the skin sphere (radius 0.9 at 4.2 units): its albedo AOV is the
    // skin interior's artist albedo, not the dielectric boundary's white, its normal faces the
    // camera and its depth is that of the sphere's front.
    let c = (h / 2) * w + w / 2;
    let albedo = [ch("albedo.R")[c], ch("albedo.G")[c], ch("albedo.B")[c]];
    for (got, want) in albedo.iter().zip([0.9f32, 0.6, 0.45]) {
        assert!(
            (got - want).abs() < 1e-5,
            "albedo AOV {albedo:?}, want the skin's"
        );
    }
    assert!(
        ch("normal.Z")[c] > 0.8,
        "normal AOV at the entry faces the camera"
    );
    let depth = ch("depth.Z")[c];
    assert!(
        depth > 3.1 && depth < 3.6,
        "depth {depth}: the skin's front, about 3.3 away"
    );
    for i in 0..w * h {
        let n = [ch("normal.X")[i], ch("normal.Y")[i], ch("normal.Z")[i]];
        let len = n.iter().map(|v| v * v).sum::<f32>().sqrt();
        assert!(len <= 1.0 + 1e-5, "|N| = {len}");
        for c in ["albedo.R", "albedo.G", "albedo.B"] {
            assert!((0.0..=1.0).contains(&ch(c)[i]), "{c} out of [0, 1]");
        }
        assert!(!ch("depth.Z")[i].is_nan());
    }
    // Metadata: version, scene hash, command, seed, spp, time and the estimators per interior.
    for key in [
        "velour:version",
        "velour:scene_hash",
        "velour:command",
        "velour:seed",
        "velour:spp",
        "velour:render_seconds",
        "velour:interior.skin",
    ] {
        assert!(
            img.attributes.contains_key(key),
            "{key} missing: {:?}",
            img.attributes
        );
    }
    assert!(img.attributes["velour:interior.skin"].contains("homogeneous"));
}

#[test]
fn a_clouds_albedo_aov_is_its_albedo() {
    let dir = TempDir::new("farm-aov-cloud");
    let out = dir.join("cloud.exr");
    run_velour([
        "render",
        repo_path("scenes/cloud.toml").to_str().unwrap(),
        "--width",
        "32",
        "--height",
        "24",
        "--spp",
        "8",
        "-q",
        "-o",
        out.to_str().unwrap(),
    ])
    .assert_success();
    let img = read_exr(&out).unwrap();
    // Pixels whose every sample scattered in the cloud show its albedo (0.99); pixels where some
    // samples passed through show a fraction of it; none shows anything else.
    let r = &img.channels["albedo.R"];
    let max = r.iter().copied().fold(0f32, f32::max);
    assert!(
        (max - 0.99).abs() < 1e-5,
        "albedo AOV max {max}, want the cloud's 0.99"
    );
    assert!(r.iter().all(|&a| a <= 0.99 + 1e-5));
}

#[test]
fn the_render_summary_says_what_was_built() {
    let dir = TempDir::new("farm-summary");
    let run = |scene: &str| {
        let out = dir.join("s.exr");
        let r = run_velour([
            "render",
            repo_path(scene).to_str().unwrap(),
            "--width",
            "16",
            "--height",
            "12",
            "--spp",
            "1",
            "-q",
            "-o",
            out.to_str().unwrap(),
        ]);
        r.assert_success();
        r.stdout
    };
    let skin = run("scenes/skin_sphere.toml");
    assert!(
        skin.contains("interior skin: homogeneous, no grid"),
        "{skin}"
    );
    let cloud = run("scenes/cloud.toml");
    assert!(cloud.contains("interior cloud: voxel, grid of"), "{cloud}");
    assert!(cloud.contains("free flights DeltaTracking"), "{cloud}");
    let fbm = run("scenes/fbm_creature.toml");
    assert!(fbm.contains(": fbm (baked), grid of"), "{fbm}");
}
