//! `velour weave` end to end: writes density, tangent and id grids (and mips, OBJ, preview),
//! prints statistics, and fails with a message naming the flag and its range on bad input.

mod common;

use common::cli::{run_velour, velour, Capture};
use common::files::TempDir;

#[test]
fn writes_vdb_with_mips_obj_and_stats() {
    let dir = TempDir::new("cli-weave");
    let vdb = dir.join("patch.vdb");
    let obj = dir.join("patch.obj");
    let o = velour()
        .args([
            "weave",
            "--pattern",
            "twill",
            "--yarn",
            "cotton2",
            "--repeats",
            "1",
            "--resolution",
            "48",
            "--mip",
            "2",
            "--seed",
            "3",
            "--stats",
            "-o",
        ])
        .arg(&vdb)
        .arg("--obj")
        .arg(&obj)
        .capture();
    o.assert_success();
    let stdout = &o.stdout;
    for key in [
        "fibres",
        "fibre volume",
        "conservation error",
        "active voxels",
        "bytes per active voxel",
        "voxelise",
    ] {
        assert!(stdout.contains(key), "missing `{key}` in {stdout}");
    }
    let grids = velour::vdb::read_vdb(&vdb).expect("read back");
    let names: Vec<&str> = grids.iter().map(|g| g.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "density",
            "tangent",
            "id",
            "density_mip1",
            "tangent_mip1",
            "id_mip1",
            "density_mip2",
            "tangent_mip2",
            "id_mip2"
        ]
    );
    assert_eq!(grids[0].class, "fog volume");
    assert_eq!(grids[1].value_type, velour::vdb::ValueType::Vec3s);
    let s = grids[0].stats();
    assert!(s.active_voxels > 1000 && s.max[0] <= 1.0 && s.min[0] > 0.0);
    // The same grid from the library: same statistics.
    let yarn = velour::fabric::YarnParams::preset("cotton2").unwrap();
    let r = yarn.envelope_radius();
    let mut p = velour::fabric::WeaveParams::new(
        velour::fabric::WeavePattern::from_name("twill").unwrap(),
        yarn,
    );
    p.repeats = [1, 1];
    p.warp_height = r;
    p.weft_height = r;
    let patch = velour::fabric::generate_patch(&p, 3).unwrap();
    let vp = velour::fabric::voxelise(&patch, 48, &Default::default()).unwrap();
    assert_eq!(
        s,
        velour::vdb::GridStats::compute(&vp.grid, velour::fabric::voxelise::DENSITY)
    );
    let text = std::fs::read_to_string(&obj).expect("obj");
    assert!(text.contains("g warp_0") && text.contains("\nl "));
}

#[test]
fn half_density_and_preview() {
    let dir = TempDir::new("cli-weave-half");
    let vdb = dir.join("half.vdb");
    let png = dir.join("swatch.png");
    let o = velour()
        .args([
            "weave",
            "--pattern",
            "velvet",
            "--warp-yarn",
            "silk1",
            "--weft-yarn",
            "polyester1",
            "--flyaways",
            "0",
            "--repeats",
            "1x2",
            "--resolution",
            "32",
            "--half",
            "--preview-size",
            "48",
            "-o",
        ])
        .arg(&vdb)
        .arg("--preview")
        .arg(&png)
        .capture();
    o.assert_success();
    let grids = velour::vdb::read_vdb(&vdb).expect("read back");
    assert!(grids[0].saved_as_half && !grids[2].saved_as_half);
    // Velvet: the id grid holds pile voxels.
    assert_eq!(grids[2].stats().max[0], 2.0);
    let img = image::open(&png).expect("png").to_rgb8();
    assert_eq!(img.dimensions(), (48, 48));
    // Lit fibres: not a flat background.
    let lum: Vec<u32> = img
        .pixels()
        .map(|p| u32::from(p[0]) + u32::from(p[1]))
        .collect();
    assert!(lum.iter().max().unwrap() > &(lum.iter().min().unwrap() + 60));
}

/// `velour weave ARGS` fails, naming every one of `needles` and without a panic.
fn fails_with(args: &[&str], needles: &[&str]) {
    let mut all = vec!["weave"];
    all.extend_from_slice(args);
    run_velour(&all).assert_failure_mentioning(needles);
}

#[test]
fn bad_flags_are_named_with_their_range() {
    let dir = TempDir::new("cli-weave-bad");
    let out = dir.join("x.vdb");
    let out = out.to_str().unwrap();
    fails_with(
        &["--pattern", "herringbone", "-o", out],
        &[
            "--pattern",
            "herringbone",
            "plain",
            "twill",
            "satin",
            "velvet",
        ],
    );
    fails_with(
        &["--resolution", "0", "-o", out],
        &["--resolution", "1..=8192"],
    );
    fails_with(
        &["--resolution", "-5", "-o", out],
        &["--resolution", "1..=8192"],
    );
    fails_with(
        &["--flyaways", "-1", "-o", out],
        &["--flyaways", "[0, 100]"],
    );
    fails_with(
        &["--flyaways", "nan", "-o", out],
        &["--flyaways", "[0, 100]"],
    );
    fails_with(
        &["--yarn", "nylon", "-o", out],
        &["--yarn", "nylon", "cotton1"],
    );
    fails_with(
        &["--weft-yarn", "wool", "-o", out],
        &["--weft-yarn", "silk2"],
    );
    fails_with(&["--repeats", "0", "-o", out], &["--repeats", "1..=1024"]);
    fails_with(&["--repeats", "2x", "-o", out], &["--repeats", "NxM"]);
    fails_with(&["--mip", "9", "-o", out], &["--mip", "0..=8"]);
    fails_with(
        &["--preview-size", "8", "--stats"],
        &["--preview-size", "16..=4096"],
    );
    fails_with(&[], &["nothing to do", "-o"]);
    // Too fine for memory: a named, bounded error rather than an allocation failure.
    fails_with(
        &["--pattern", "plain", "--resolution", "8192", "-o", out],
        &["--resolution", "limit"],
    );
    assert!(!std::path::Path::new(out).exists());
}
