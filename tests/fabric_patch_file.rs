//! The fabric round trip (issue 14 §6): `velour weave` records its generator parameters as
//! file metadata; `interior = { type = "fabric", file = … }` renders the patch it wrote, in
//! agreement with the procedural interior built from the same parameters; scene keys that
//! contradict the file, and files without the tangent or id grid, are errors naming both; and
//! `mip = "auto"` picks the level per ray from the ray cone, at the resolution the render
//! actually uses (`--width`/`--height` included).

mod common;

use common::cli::run_velour;
use common::files::TempDir;
use common::render::{image_mean, render_finite, scene_from_text};
use common::stats::{difference_z_score, Estimate};
use velour::fabric::patch_file::{read_patch_file, WeaveRecord};
use velour::fabric::voxelise::{DENSITY, TANGENT};
use velour::fabric::{generate_patch, voxelise, VoxeliseOptions, WeaveParams, WeavePattern};
use velour::film::Film;
use velour::math::{Ray, Vec3};
use velour::medium::{HeterogeneousMedium, Medium, MipChain, RayFootprint};
use velour::scene::{load_scene_str, Scene};
use velour::spectrum::Rgb;
use velour::vdb::{write_vdb_with_metadata, Compression, GridToWrite, VdbFile, WriteOptions};

/// Runs `velour weave` with `args` plus `-o dir/name`, returning the file's path.
fn weave(dir: &TempDir, name: &str, args: &[&str]) -> std::path::PathBuf {
    let out = dir.join(name);
    let mut all: Vec<String> = vec!["weave".into()];
    all.extend(args.iter().map(|s| s.to_string()));
    all.extend(["-o".into(), out.display().to_string()]);
    run_velour(&all).assert_success();
    out
}

/// A free-standing swatch lit by an environment and a distant light, seen from above by a
/// `size` × `size` camera at `height` over the patch.
fn swatch_scene(interior: &str, size: u32, spp: u32, seed: u64, height: f32) -> String {
    format!(
        r#"
[camera]
eye = [0.2, 0.2, {height}]
look_at = [0.2, 0.2, 0.0]
up = [0.0, 1.0, 0.0]
fov = 30

[film]
width = {size}
height = {size}
spp = {spp}
seed = {seed}
max_depth = 64

[[light]]
type = "environment"
radiance = [0.3, 0.32, 0.36]

[[light]]
type = "distant"
direction = [-0.4, -0.5, 0.8]
irradiance = [3.0, 2.9, 2.7]

[[object]]
name = "swatch"
shape = "bounds"
interior = {{ {interior}, attenuation = 0.002, nee = "interior" }}
"#
    )
}

/// The image mean of each channel as an estimate (standard error from the pixels' variances).
fn channel_means(film: &Film) -> [Estimate; 3] {
    let n = (film.width() * film.height()) as usize;
    [0, 1, 2].map(|c| {
        let (mean, standard_error) = image_mean(film, c);
        Estimate {
            mean,
            standard_error,
            count: n,
        }
    })
}

/// The largest |z| of the per-channel difference of two independent renders' image means.
fn max_z(a: &Film, b: &Film) -> f64 {
    let (ea, eb) = (channel_means(a), channel_means(b));
    (0..3)
        .map(|c| difference_z_score(&ea[c], &eb[c]).abs())
        .fold(0.0, f64::max)
}

fn load_err(text: &str, path: &std::path::Path) -> String {
    match load_scene_str(text, path) {
        Ok(_) => panic!("the scene should not load"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn weave_records_its_generator_parameters_as_file_metadata() {
    let dir = TempDir::new("patch-meta");
    let path = weave(
        &dir,
        "p.vdb",
        &[
            "--pattern",
            "Twill",
            "--warp-yarn",
            "cotton1",
            "--weft-yarn",
            "silk1",
            "--resolution",
            "24",
            "--repeats",
            "2x1",
            "--seed",
            "9",
            "--flyaways",
            "0.5",
        ],
    );
    let file = VdbFile::open(&path).unwrap();
    let r = WeaveRecord::from_metadata(&file.metadata)
        .unwrap()
        .expect("weave metadata");
    assert_eq!(r.pattern, "twill");
    assert_eq!(r.warp_yarn, "cotton1");
    assert_eq!(r.weft_yarn, "silk1");
    assert_eq!(r.resolution, 24);
    assert_eq!(r.repeats, [2, 1]);
    assert_eq!(r.seed, 9);
    assert_eq!(r.flyaways, 0.5);
    assert_eq!(r.albedos[0], Rgb::splat(0.8));
    assert_eq!(r.albedos[1], Rgb::splat(0.6));
    // The tile and its voxels are the generator's.
    let pattern = WeavePattern::from_name("twill").unwrap();
    let [warp, weft] = r.yarns().unwrap();
    let mut params = WeaveParams::with_yarns(pattern, warp, weft);
    params.repeats = [2, 1];
    params.flyaway_fraction = 0.5;
    let patch = generate_patch(&params, 9).unwrap();
    let vp = voxelise(&patch, 24, &VoxeliseOptions::default()).unwrap();
    assert_eq!(r.tile, vp.tile);
    assert_eq!(r.dims, vp.dims);
    // `velour inspect` prints the file metadata.
    let out = run_velour(["inspect".as_ref(), path.as_os_str()]);
    out.assert_success();
    assert!(
        out.stdout
            .contains("velour_weave.weft_yarn (string): silk1"),
        "{}",
        out.stdout
    );
}

#[test]
fn a_patch_file_renders_as_the_procedural_interior_it_records() {
    let dir = TempDir::new("patch-render");
    weave(
        &dir,
        "p.vdb",
        &[
            "--pattern",
            "twill",
            "--resolution",
            "32",
            "--repeats",
            "1",
            "--seed",
            "3",
        ],
    );
    let scene_path = dir.join("s.toml");
    let colours = r#"warp_albedo = [0.75, 0.12, 0.1], weft_albedo = [0.85, 0.8, 0.7]"#;
    let procedural = format!(
        r#"type = "fabric", pattern = "twill", yarn = "cotton1", resolution = 32, repeats = 1, seed = 3, {colours}"#
    );
    let from_file = format!(r#"type = "fabric", file = "p.vdb", {colours}"#);
    let render = |interior: &str, seed: u64| {
        let scene = scene_from_text(&swatch_scene(interior, 16, 48, seed, 1.0), &scene_path);
        render_finite(&scene, 2).0
    };
    // Agreement in expectation: independent seeds, the difference of the image means against
    // its standard error (from the pixels' own variances).
    let a = render(&procedural, 1);
    let b = render(&from_file, 2);
    let z = max_z(&a, &b);
    assert!(z < 4.0, "file vs procedural: |z| = {z:.2}");
    // The grids read back are the generator's bit for bit, so with one seed so is the image.
    let c = render(&from_file, 1);
    for y in 0..a.height() {
        for x in 0..a.width() {
            assert_eq!(a.mean(x, y), c.mean(x, y), "pixel ({x}, {y})");
        }
    }
    // Levels the file lacks are built at load: the same as levels voxelised at load in
    // expectation (densities equal; tangents and ids from the stored level's).
    let proc_mip = render(&format!("{procedural}, mip = 1"), 3);
    let file_mip = render(&format!("{from_file}, mip = 1"), 4);
    let z = max_z(&proc_mip, &file_mip);
    assert!(
        z < 4.0,
        "mip 1 built from the file vs voxelised: |z| = {z:.2}"
    );
}

#[test]
fn keys_that_contradict_the_file_are_errors_naming_both_values() {
    let dir = TempDir::new("patch-contradict");
    weave(
        &dir,
        "p.vdb",
        &["--pattern", "twill", "--resolution", "16", "--repeats", "1"],
    );
    let scene_path = dir.join("s.toml");
    let err = |extra: &str| {
        let text = swatch_scene(
            &format!(r#"type = "fabric", file = "p.vdb", {extra}"#),
            8,
            1,
            1,
            1.0,
        );
        load_err(&text, &scene_path)
    };
    let e = err(r#"pattern = "plain""#);
    assert!(
        e.contains("pattern = \"plain\"")
            && e.contains("pattern = \"twill\"")
            && e.contains("p.vdb"),
        "{e}"
    );
    let e = err("resolution = 64");
    assert!(
        e.contains("resolution = 64") && e.contains("resolution = 16"),
        "{e}"
    );
    let e = err("seed = 2");
    assert!(e.contains("seed = 2") && e.contains("seed = 1"), "{e}");
    let e = err("repeats = 2");
    assert!(
        e.contains("repeats = 2") && e.contains("repeats = 1"),
        "{e}"
    );
    let e = err(r#"weft_yarn = "silk1""#);
    assert!(
        e.contains("weft_yarn = \"silk1\"") && e.contains("weft_yarn = \"cotton1\""),
        "{e}"
    );
    let e = err("flyaways = 0");
    assert!(
        e.contains("flyaways = 0") && e.contains("flyaways = 1"),
        "{e}"
    );
    // Keys that agree (aliases included) and shading keys are fine.
    let ok = swatch_scene(
        r#"type = "fabric", file = "p.vdb", pattern = "twill22", yarn = "cotton", resolution = 16, seed = 1, pile_albedo = [0.2, 0.3, 0.4], fibre_phase = { eta = 1.6, beta_m = 0.2, beta_n = 0.4, alpha = 0.05, diffuse_weight = 0.5 }"#,
        8,
        1,
        1,
        1.0,
    );
    load_scene_str(&ok, &scene_path).unwrap();
    // Out-of-range fibre parameters name the key.
    let e = err("fibre_phase = { beta_n = 2.0 }");
    assert!(e.contains("fibre_phase.beta_n"), "{e}");
    let e = err("fibre_phase = { betta = 0.3 }");
    assert!(e.contains("betta"), "{e}");
}

#[test]
fn a_patch_without_its_tangent_or_id_grid_or_metadata_is_refused() {
    let dir = TempDir::new("patch-missing");
    let full = weave(&dir, "full.vdb", &["--resolution", "16", "--repeats", "1"]);
    let pf = read_patch_file(&full).unwrap();
    let vp = pf.levels[0].as_ref().unwrap();
    let meta = pf.record.to_metadata();
    let opts = WriteOptions {
        compression: Compression::None,
        active_mask: false,
    };
    let density = GridToWrite {
        channel: DENSITY,
        ..GridToWrite::new("density", &vp.grid)
    };
    let tangent = GridToWrite {
        channel: TANGENT,
        ..GridToWrite::new("tangent", &vp.grid)
    };
    let scene_path = dir.join("s.toml");
    let scene_for = |file: &str| {
        swatch_scene(
            &format!(r#"type = "fabric", file = "{file}""#),
            8,
            1,
            1,
            1.0,
        )
    };
    // Density and tangent only: the id grid is missing.
    write_vdb_with_metadata(dir.join("no_id.vdb"), &[density, tangent], &opts, &meta).unwrap();
    let e = load_err(&scene_for("no_id.vdb"), &scene_path);
    assert!(e.contains("no_id.vdb") && e.contains("`id`"), "{e}");
    // Density only: the tangent grid is missing (named first).
    write_vdb_with_metadata(dir.join("no_tan.vdb"), &[density], &opts, &meta).unwrap();
    let e = load_err(&scene_for("no_tan.vdb"), &scene_path);
    assert!(e.contains("no_tan.vdb") && e.contains("`tangent`"), "{e}");
    // All three grids but no weave metadata (e.g. a file from before the round trip).
    velour::fabric::write_patch_vdb(&dir.join("bare.vdb"), &[vp], false).unwrap();
    let e = load_err(&scene_for("bare.vdb"), &scene_path);
    assert!(e.contains("bare.vdb") && e.contains("velour_weave"), "{e}");
    // A missing file is named.
    let e = load_err(&scene_for("nowhere.vdb"), &scene_path);
    assert!(e.contains("nowhere.vdb"), "{e}");
}

#[test]
fn the_level_of_a_footprint_is_floor_log2_of_its_width_in_voxels() {
    let chain = MipChain {
        voxel_width: 0.5,
        bounds: velour::math::Aabb::EMPTY,
        levels: Vec::new(),
    };
    assert_eq!(chain.level_for(100.0), 0, "no coarser level to pick");
    let dir = TempDir::new("patch-levels");
    weave(&dir, "p.vdb", &["--resolution", "32", "--repeats", "1"]);
    let text = swatch_scene(
        r#"type = "fabric", file = "p.vdb", mip = "auto""#,
        8,
        1,
        1,
        1.0,
    );
    let scene = scene_from_text(&text, dir.join("s.toml"));
    let Medium::Heterogeneous(h) = &scene.media[0] else {
        panic!("a heterogeneous medium");
    };
    let chain = h.mips.as_ref().expect("a mip chain");
    // 32 voxels across the tile: levels 1–5 built at load (the file stores level 0 only).
    assert_eq!(chain.levels.len(), 5);
    let v = chain.voxel_width;
    for (w, l) in [
        (0.0, 0),
        (1.99, 0),
        (2.0, 1),
        (3.99, 1),
        (4.0, 2),
        (31.9, 4),
        (32.0, 5),
        (1e9, 5),
        (f32::NAN, 0),
        (f32::INFINITY, 5),
    ] {
        assert_eq!(chain.level_for(w * v), l, "footprint {w} voxels");
        let m: &HeterogeneousMedium = h.level(chain.level_for(w * v));
        assert_eq!(m.fabric.as_ref().unwrap().mip_level, l as u32);
    }
    // The footprint is measured where the ray reaches the fabric's box, not at its origin.
    let b = chain.bounds;
    let centre = (b.min + b.max) * 0.5;
    let above = Vec3::new(centre.x, centre.y, b.max.z + 1.0);
    let down = Ray::new(above, Vec3::new(0.0, 0.0, -1.0));
    let cone = |width: f32, spread: f32| RayFootprint { width, spread };
    assert_eq!(chain.level_for_ray(&down, cone(0.0, 2.5 * v)), 1);
    assert_eq!(chain.level_for_ray(&down, cone(0.0, 5.0 * v)), 2);
    // A ray starting inside is measured at its origin; a ray missing the box too.
    let inside = Ray::new(centre, Vec3::new(0.0, 0.0, 1.0));
    assert_eq!(chain.level_for_ray(&inside, cone(4.5 * v, 10.0)), 2);
    let away = Ray::new(above, Vec3::new(0.0, 0.0, 1.0));
    assert_eq!(chain.level_for_ray(&away, cone(0.5 * v, 10.0)), 0);
    assert!(
        scene.notes.iter().any(|n| n.contains("chosen per ray")),
        "{:?}",
        scene.notes
    );
}

/// `mip = "auto"` renders like the fixed level its camera rays pick, at the film size the
/// render uses: 16² pixels put every camera ray's footprint on the patch between 2 and 4
/// level-0 voxels (level 1), 8² pixels between 4 and 8 (level 2). The loaded scene is resized
/// as `--width`/`--height` do (`Scene::set_resolution`); before the per-ray choice the level
/// came from the scene file's film size.
#[test]
fn auto_mip_follows_the_ray_footprint_at_the_rendered_resolution() {
    let dir = TempDir::new("patch-auto");
    weave(
        &dir,
        "p.vdb",
        &["--pattern", "twill", "--resolution", "32", "--repeats", "1"],
    );
    let path = dir.join("s.toml");
    let colours = r#"warp_albedo = [0.75, 0.12, 0.1], weft_albedo = [0.85, 0.8, 0.7]"#;
    let render = |mip: &str, file_size: u32, size: u32, seed: u64| -> Film {
        let interior = format!(r#"type = "fabric", file = "p.vdb", {colours}, mip = {mip}"#);
        // About 16k samples per image whatever its size.
        let spp = 16_384 / (size * size);
        let mut scene: Scene =
            scene_from_text(&swatch_scene(&interior, file_size, spp, seed, 1.0), &path);
        scene.set_resolution(size, size).unwrap();
        render_finite(&scene, 2).0
    };
    // The scene file says 64² (level 0 for every camera ray); rendered at 16² and 8².
    let auto16 = render("\"auto\"", 64, 16, 1);
    let fixed1 = render("1", 64, 16, 2);
    let z = max_z(&auto16, &fixed1);
    assert!(z < 4.0, "auto at 16² vs mip = 1: |z| = {z:.2}");
    let auto8 = render("\"auto\"", 64, 8, 3);
    let fixed2 = render("2", 64, 8, 4);
    let z = max_z(&auto8, &fixed2);
    assert!(z < 4.0, "auto at 8² vs mip = 2: |z| = {z:.2}");
    // Every ray of these images picks the fixed level (camera rays by their footprint where
    // they reach the fibres, scattered and shadow rays from inside by the same width), and
    // the object's box is the finest level's either way: with one seed, the same image.
    let same_seed = render("2", 64, 8, 3);
    let identical = (0..8).all(|y| (0..8).all(|x| auto8.mean(x, y) == same_seed.mean(x, y)));
    assert!(identical, "auto at 8² and mip = 2 with one seed differ");
    // The levels render differently enough for the test to tell them apart.
    let fixed0 = render("0", 64, 8, 5);
    let z = max_z(&auto8, &fixed0);
    assert!(z > 4.0, "auto at 8² vs mip = 0 should differ: |z| = {z:.2}");
}
