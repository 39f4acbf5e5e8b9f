//! Textured yarn colours on `fabric` shells, read at each walk's entry point
//! (docs/textures.md, "Fabric yarn colours"): z-tests on region means with standard errors
//! from the renders' own per-pixel variances, independent seeds per render:
//! - a warp colour texture of one value renders like the constant (fixed mip level and
//!   `mip = "auto"`);
//! - a texture whose left half is red and right half blue gives two halves, each like the
//!   render with that constant, and different from each other;
//! - a walk's medium (`Medium::Dyed`) tracks the mip level the ray's cone picks, exactly as
//!   the untextured fabric does;
//! - bad input: a texture on a free-standing patch (`shape = "bounds"`), a NaN texel, a
//!   missing file, a colour outside [0, 1].

mod common;

use common::files::TempDir;
use common::render::{region_mean, render_finite, scene_from_text};
use common::stats::z_score;
use common::textures::exr_rgb;
use velour::film::Film;
use velour::math::{Ray, Vec3};
use velour::medium::{Medium, RayFootprint, WalkInterior};
use velour::scene::load_scene_str;
use velour::tracking::TrackingStats;

/// Image side (pixels).
const SIDE: u32 = 16;

/// A 4 × 4 plane at z = 0 with u = x / 4, v = y / 4 (two triangles).
fn write_plane(dir: &TempDir) {
    let mut s = String::from("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float u\nproperty float v\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n");
    for (u, v) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
        s += &format!("{} {} 0 {u} {v}\n", u * 4.0, v * 4.0);
    }
    s += "3 0 1 2\n3 0 2 3\n";
    std::fs::write(dir.join("plane.ply"), s).unwrap_or_else(|e| panic!("{e}"));
}

/// A plain-weave shell over the plane seen from `eye_z` above its centre (image x runs
/// along world x, so along u), its warp colour `warp` (a TOML value), other keys `extra`.
fn cloth(warp: &str, extra: &str, eye_z: f32, spp: u32, seed: u32) -> String {
    format!(
        r#"
[camera]
eye = [2.0, 2.0, {eye_z}]
look_at = [2.0, 2.0, 0.0]
up = [0.0, 1.0, 0.0]
fov = 40
[film]
width = {SIDE}
height = {SIDE}
spp = {spp}
seed = {seed}
max_depth = 64
[[light]]
type = "environment"
radiance = 0.5
[[light]]
type = "distant"
direction = [0.3, 0.2, 0.9]
irradiance = 2.0
[[object]]
name = "cloth"
shape = "mesh"
file = "plane.ply"
interior = {{ type = "fabric", pattern = "plain", resolution = 32, tiles = 8, attenuation = 0.01, weft_albedo = [0.7, 0.7, 0.7], warp_albedo = {warp}{extra} }}
"#
    )
}

const RED: [f32; 3] = [0.8, 0.15, 0.1];
const BLUE: [f32; 3] = [0.1, 0.3, 0.85];

fn toml_rgb(c: [f32; 3]) -> String {
    format!("[{:?}, {:?}, {:?}]", c[0], c[1], c[2])
}

fn render(text: &str, dir: &TempDir) -> Film {
    render_finite(&scene_from_text(text, dir.join("scene.toml")), 0).0
}

/// Region means of `a` and `b` over columns `cols`, channel by channel: the z-scores of
/// their differences.
fn region_z(a: &Film, b: &Film, cols: std::ops::Range<u32>) -> [f64; 3] {
    std::array::from_fn(|c| {
        let keep = |x: u32, _: u32| cols.contains(&x);
        let (ma, sa) = region_mean(a, c, keep);
        let (mb, sb) = region_mean(b, c, keep);
        z_score(ma, mb, sa.hypot(sb))
    })
}

fn assert_agree(z: [f64; 3], what: &str) {
    println!("{what}: z = {z:.2?}");
    assert!(z.iter().all(|z| z.abs() < 4.0), "{what}: z = {z:.2?}");
}

#[test]
fn a_one_value_warp_texture_renders_like_the_constant() {
    let dir = TempDir::new("render-texfabric-one");
    write_plane(&dir);
    exr_rgb(&dir.join("red.exr"), 4, 4, |_, _| RED);
    let textured = r#"{ texture = "red.exr" }"#;
    for (extra, eye_z, what) in [
        ("", 3.0, "mip 0"),
        // A pixel's footprint is 8 level-0 voxels here: coarser levels are tracked.
        (", mip = \"auto\"", 3.0, "mip auto"),
    ] {
        let t = render(&cloth(textured, extra, eye_z, 48, 1), &dir);
        let c = render(&cloth(&toml_rgb(RED), extra, eye_z, 48, 2), &dir);
        assert_agree(
            region_z(&t, &c, 0..SIDE),
            &format!("one-value texture vs constant ({what})"),
        );
    }
}

#[test]
fn a_two_colour_warp_texture_gives_two_halves_like_their_constants() {
    let dir = TempDir::new("render-texfabric-halves");
    write_plane(&dir);
    // Left half (u < ½) red, right half blue.
    exr_rgb(&dir.join("halves.exr"), 32, 4, |x, _| {
        if x < 16 {
            RED
        } else {
            BLUE
        }
    });
    let spp = 64;
    let t = render(
        &cloth(
            r#"{ texture = "halves.exr", wrap = "clamp" }"#,
            "",
            3.0,
            spp,
            11,
        ),
        &dir,
    );
    let red = render(&cloth(&toml_rgb(RED), "", 3.0, spp, 12), &dir);
    let blue = render(&cloth(&toml_rgb(BLUE), "", 3.0, spp, 13), &dir);
    // Columns at least 3 pixels (0.4 world units, 3 texels) from the seam at u = ½.
    let (left, right) = (0..SIDE / 2 - 3, SIDE / 2 + 3..SIDE);
    assert_agree(
        region_z(&t, &red, left.clone()),
        "left half vs red constant",
    );
    assert_agree(
        region_z(&t, &blue, right.clone()),
        "right half vs blue constant",
    );
    // Not a vacuous agreement: the halves differ, red on the left, blue on the right.
    let keep_l = |x: u32, _: u32| left.contains(&x);
    let keep_r = |x: u32, _: u32| right.contains(&x);
    let (lr, slr) = region_mean(&t, 0, keep_l);
    let (rr, srr) = region_mean(&t, 0, keep_r);
    let (lb, slb) = region_mean(&t, 2, keep_l);
    let (rb, srb) = region_mean(&t, 2, keep_r);
    let z_red = z_score(lr, rr, slr.hypot(srr));
    let z_blue = z_score(rb, lb, srb.hypot(slb));
    println!("left − right: red z = {z_red:.1}, blue z = {z_blue:.1}");
    assert!(
        z_red > 8.0 && z_blue > 8.0,
        "halves do not differ: red z = {z_red}, blue z = {z_blue}"
    );
}

#[test]
fn a_dyed_fabric_tracks_the_mip_level_of_the_rays_cone() {
    let dir = TempDir::new("render-texfabric-mips");
    write_plane(&dir);
    exr_rgb(&dir.join("halves.exr"), 8, 2, |x, _| {
        if x < 4 {
            RED
        } else {
            BLUE
        }
    });
    let text = cloth(
        r#"{ texture = "halves.exr" }"#,
        ", mip = \"auto\"",
        30.0,
        1,
        1,
    );
    let scene = scene_from_text(&text, dir.join("scene.toml"));
    let obj = &scene.objects[0];
    assert!(matches!(obj.walk.as_deref(), Some(WalkInterior::Fabric(_))));
    let Some(Medium::Dyed(standin)) = obj.medium.map(|m| &scene.media[m as usize]) else {
        panic!("a textured fabric's stand-in is a dyed fabric");
    };
    let chain = standin.medium.mips.as_ref().expect("levels chosen per ray");
    assert!(chain.levels.len() >= 2, "{} levels", chain.levels.len());
    // The same fabric, untextured: the same flights and transmittances, bit for bit, in
    // every level the cone picks (the colours change only the phase functions).
    let plain = Medium::Heterogeneous(Box::new((*standin.medium).clone()));
    let dyed = Medium::Dyed(standin.clone());
    let ray = Ray::new(
        Vec3::new(2.1, 1.9, 1.0),
        Vec3::new(0.05, 0.02, -1.0).normalize(),
    );
    let mut levels = Vec::new();
    for spread in [0.0, 0.04, 0.07, 0.2] {
        let cone = RayFootprint { width: 0.0, spread };
        levels.push(chain.level_for_ray(&ray, cone));
        let mut stats = TrackingStats::default();
        let mut run = |m: &Medium| {
            let mut state = 12345u32;
            let mut u = move || {
                state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (state >> 8) as f32 / (1u32 << 24) as f32
            };
            let mut out = Vec::new();
            for _ in 0..64 {
                let tr = m.transmittance_in_cone(&ray, 2.0, cone, &mut u, &mut stats);
                let e = m.sample_flight_in_cone(
                    &ray,
                    cone,
                    velour::spectrum::Rgb::ONE,
                    &mut u,
                    &mut stats,
                    |_| 2.0,
                );
                out.push((tr, e.weight, e.scatter.map(|s| s.p)));
            }
            out
        };
        let a = run(&plain);
        let b = run(&dyed);
        assert_eq!(format!("{a:?}"), format!("{b:?}"), "spread {spread}");
    }
    // The cones span more than one level, so the comparison covers coarser levels.
    levels.dedup();
    assert!(levels.len() >= 2, "levels {levels:?}");
}

#[test]
fn bad_yarn_colour_textures_are_refused_naming_object_and_key() {
    let dir = TempDir::new("render-texfabric-errors");
    write_plane(&dir);
    exr_rgb(&dir.join("red.exr"), 4, 4, |_, _| RED);
    exr_rgb(&dir.join("nan.exr"), 4, 4, |x, y| {
        if (x, y) == (2, 1) {
            [0.5, f32::NAN, 0.5]
        } else {
            RED
        }
    });
    exr_rgb(&dir.join("bright.exr"), 4, 4, |_, _| [0.5, 1.5, 0.5]);
    let err = |text: &str| {
        load_scene_str(text, &dir.join("scene.toml"))
            .err()
            .unwrap_or_else(|| panic!("accepted:\n{text}"))
            .to_string()
    };
    // A free-standing patch has no texture coordinates.
    let bounds = cloth(r#"{ texture = "red.exr" }"#, "", 3.0, 1, 1)
        .replace(
            "shape = \"mesh\"\nfile = \"plane.ply\"",
            "shape = \"bounds\"",
        )
        .replace(", tiles = 8", "");
    let e = err(&bounds);
    assert!(
        e.contains("cloth: interior.warp_albedo")
            && e.contains("free-standing")
            && e.contains("red.exr"),
        "{e}"
    );
    // A NaN texel, named by pixel.
    let e = err(&cloth(r#"{ texture = "nan.exr" }"#, "", 3.0, 1, 1));
    assert!(
        e.contains("cloth: interior.warp_albedo")
            && e.contains("nan.exr")
            && e.contains("(2, 1)")
            && e.contains("NaN"),
        "{e}"
    );
    // A missing file.
    let e = err(&cloth(r#"{ texture = "missing.exr" }"#, "", 3.0, 1, 1));
    assert!(
        e.contains("cloth: interior.warp_albedo") && e.contains("missing.exr"),
        "{e}"
    );
    // A colour above 1, on another key.
    let text = cloth(&toml_rgb(RED), "", 3.0, 1, 1).replace(
        "weft_albedo = [0.7, 0.7, 0.7]",
        r#"weft_albedo = { texture = "bright.exr" }"#,
    );
    let e = err(&text);
    assert!(
        e.contains("cloth: interior.weft_albedo")
            && e.contains("bright.exr")
            && e.contains("outside [0, 1]"),
        "{e}"
    );
    // A misspelt key inside the texture table.
    let e = err(&cloth(
        r#"{ texture = "red.exr", chanel = "r" }"#,
        "",
        3.0,
        1,
        1,
    ));
    assert!(e.contains("chanel"), "{e}");
}

#[test]
fn a_fibre_prepared_in_another_colour_is_the_fibre_built_in_that_colour() {
    use velour::fabric::{FibreColour, FibrePhase, FibrePhaseParams};
    use velour::spectrum::Rgb;
    // The per-walk colour goes through the same inversion as a constant colour, so a vertex
    // prepared in colour c evaluates and samples bit for bit like the phase function built
    // with c — for the automatic node count and for one beyond the cached nodes.
    for h_nodes in [0, 200] {
        let base = FibrePhaseParams {
            beta_n: 0.4,
            h_nodes,
            ..FibrePhaseParams::default()
        };
        let own = FibrePhase::new(base.clone().with_colour(Rgb([0.9, 0.9, 0.9])))
            .unwrap_or_else(|e| panic!("{e}"));
        for c in [Rgb(RED), Rgb(BLUE), Rgb([0.0, 1.0, 0.5])] {
            let built =
                FibrePhase::new(base.clone().with_colour(c)).unwrap_or_else(|e| panic!("{e}"));
            let colour = FibreColour::new(c, base.beta_n);
            let tangent = Vec3::new(0.3, 0.9, -0.2).normalize();
            let wo = Vec3::new(-0.5, 0.1, 0.8).normalize();
            let a = built.prepare(wo, tangent);
            let b = own.prepare_coloured(wo, tangent, &colour);
            for wi in [Vec3::X, Vec3::new(0.2, -0.7, 0.4).normalize(), -wo] {
                assert_eq!(
                    built.eval_pdf_prepared(&a, wi),
                    own.eval_pdf_prepared(&b, wi),
                    "colour {c:?}, {h_nodes} nodes"
                );
            }
            let u = [0.37, 0.61, 0.13, 0.88];
            assert_eq!(
                built.sample_prepared(&a, u),
                own.sample_prepared(&b, u),
                "colour {c:?}"
            );
            // Not vacuous: the phase function's own colour gives another value.
            assert_ne!(
                own.eval_pdf_prepared(&own.prepare(wo, tangent), Vec3::X).0,
                own.eval_pdf_prepared(&b, Vec3::X).0
            );
        }
    }
}

#[test]
fn a_textured_fabric_can_be_a_look_of_a_blend() {
    let dir = TempDir::new("render-texfabric-blend");
    write_plane(&dir);
    exr_rgb(&dir.join("halves.exr"), 32, 4, |x, _| {
        if x < 16 {
            RED
        } else {
            BLUE
        }
    });
    let fabric = r#"type = "fabric", pattern = "plain", resolution = 32, tiles = 8, attenuation = 0.01, weft_albedo = [0.7, 0.7, 0.7], warp_albedo = { texture = "halves.exr", wrap = "clamp" }"#;
    let plain = cloth(
        r#"{ texture = "halves.exr", wrap = "clamp" }"#,
        "",
        3.0,
        48,
        21,
    );
    // Mask 1: every walk takes look `a`, the textured fabric.
    let blended = plain.replace(
        &format!("interior = {{ {fabric} }}"),
        &format!(
            "interior = {{ type = \"blend\", mask = 1.0, a = {{ {fabric} }}, b = {{ type = \"homogeneous\", albedo = 0.5, attenuation = 0.1 }} }}"
        ),
    );
    assert_ne!(plain, blended, "the blend replaced the interior");
    let a = render(&plain, &dir);
    let b = render(&blended.replace("seed = 21", "seed = 22"), &dir);
    assert_agree(
        region_z(&a, &b, 0..SIDE / 2 - 3),
        "blend look a vs fabric, left",
    );
    assert_agree(
        region_z(&a, &b, SIDE / 2 + 3..SIDE),
        "blend look a vs fabric, right",
    );
    let (l, sl) = region_mean(&b, 0, |x, _| x < SIDE / 2 - 3);
    let (r, sr) = region_mean(&b, 0, |x, _| x >= SIDE / 2 + 3);
    assert!(
        z_score(l, r, sl.hypot(sr)) > 8.0,
        "the blend's halves do not differ"
    );
}
