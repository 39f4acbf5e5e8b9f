//! `velour tradeoff`: the configurations offered for heterogeneous and homogeneous scenes,
//! edited scenes that load, and the CLI end to end (CSV, SVG, most efficient configuration).

mod common;

use std::path::Path;

use common::cli::{velour, Capture};
use common::files::TempDir;
use velour::cli::tradeoff::{
    apply, configurations, csv, most_efficient, svg_plot, Measurement, Target,
};
use velour::scene::{load_scene, load_scene_str};

const CLOUD: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cloud.toml");
const FBM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/fbm_creature.toml");
const SKIN: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/skin_sphere.toml");
const EYE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/eye.toml");

/// A small eye-like scene: a scattering ball behind a dielectric boundary of the given
/// roughness (0 = smooth), lit by a small sphere light and a dim environment.
fn ball_scene(roughness: f64) -> String {
    format!(
        r#"
[camera]
eye = [0.0, 0.0, 4.0]
look_at = [0.0, 0.0, 0.0]
fov = 30

[film]
width = 8
height = 6
spp = 2
seed = 3
max_depth = 32

[[light]]
type = "sphere"
center = [-3.0, 2.0, 2.0]
radius = 0.1
radiance = [400.0, 400.0, 400.0]

[[light]]
type = "environment"
radiance = [0.05, 0.05, 0.05]

[[object]]
name = "ball"
shape = "sphere"
radius = 1.0
surface = {{ type = "dielectric", ior = 1.4, roughness = {roughness} }}
interior = {{ type = "homogeneous", albedo = 0.9, attenuation = 0.3, nee = "exit" }}
"#
    )
}

fn names(configs: &[velour::cli::tradeoff::Configuration]) -> Vec<&str> {
    configs.iter().map(|c| c.name.as_str()).collect()
}

fn configs_of(path: &str) -> (toml::Table, Vec<velour::cli::tradeoff::Configuration>) {
    let text = std::fs::read_to_string(path).expect("scene");
    let doc: toml::Table = toml::from_str(&text).expect("toml");
    let scene = load_scene(Path::new(path)).expect("load");
    let c = configurations(&doc, &scene, &[]);
    (doc, c)
}

#[test]
fn heterogeneous_scenes_get_every_estimator_and_all_edits_load() {
    for path in [CLOUD, FBM] {
        let (doc, configs) = configs_of(path);
        let names: Vec<&str> = configs.iter().map(|c| c.name.as_str()).collect();
        for want in [
            "scene file",
            "delta + ratio",
            "local bounds",
            "transmittance behind",
            "no sun lean",
            "global majorant",
            "pyramid L1",
            "ray marching",
            "NEE exit",
            "NEE interior",
        ] {
            assert!(
                names.iter().any(|n| n.contains(want)),
                "{path}: no configuration {want:?} in {names:?}"
            );
        }
        assert_eq!(
            names.iter().any(|n| n.contains("exact procedural")),
            path == FBM,
            "{names:?}"
        );
        // Every edit of the cloud; for the (slow to bake) fbm creature, the procedural ones.
        for c in configs
            .iter()
            .filter(|c| path == CLOUD || c.name.contains("procedural") || c.name.contains("step"))
        {
            let text = apply(&doc, c).expect("apply");
            let scene = load_scene_str(&text, Path::new(path))
                .unwrap_or_else(|e| panic!("{path}: {}: {e}", c.name));
            assert!(!scene.media.is_empty());
        }
    }
}

#[test]
fn homogeneous_scenes_only_vary_nee() {
    let (_, configs) = configs_of(SKIN);
    let names: Vec<&str> = configs.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(
        names,
        ["scene file", "NEE exit", "NEE exit_guided", "NEE interior"]
    );
}

#[test]
fn csv_svg_and_the_most_efficient_configuration() {
    let row = |config: &str, budget: f64, seconds: f64, rmse: f64| Measurement {
        config: config.into(),
        budget,
        unit: "seconds",
        seconds,
        spp: 4,
        rmse,
        rel_mse: rmse * rmse,
        bias: 0.0,
        efficiency: 1.0 / (rmse * rmse * seconds),
        lookups_per_path: 3.0,
        non_finite: 0,
    };
    let rows = vec![
        row("a", 1.0, 1.0, 0.2),
        row("a", 2.0, 2.0, 0.15),
        row("b", 1.0, 1.0, 0.1),
        row("b", 2.0, 2.0, 0.09),
    ];
    assert_eq!(most_efficient(&rows).map(|m| m.config.as_str()), Some("b"));
    let c = csv(&rows);
    assert_eq!(c.lines().count(), 5);
    assert!(c.starts_with(
        "config,budget,unit,seconds,spp,rmse,rel_mse,bias,efficiency,lookups_per_path,non_finite"
    ));
    let svg = svg_plot(&rows, "t <&>");
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    assert_eq!(svg.matches("<polyline").count(), 2);
    assert!(svg.contains("t &lt;&amp;&gt;"));
}

#[test]
fn tradeoff_cli_end_to_end() {
    let dir = TempDir::new("tradeoff-cli");
    let reference = dir.join("ref.exr");
    velour()
        .args([
            "reference",
            CLOUD,
            "--spp",
            "8",
            "--width",
            "12",
            "--height",
            "9",
            "--threads",
            "2",
            "-q",
            "-o",
        ])
        .arg(&reference)
        .capture()
        .assert_success();
    let out = dir.join("t");
    let o = velour()
        .args([
            "tradeoff",
            CLOUD,
            "--budgets",
            "1,2",
            "--unit",
            "spp",
            "--only",
            "scene file,delta + ratio,step",
            "--steps",
            "0.05",
            "--adaptive",
            "0.2",
            "--min-spp",
            "2",
            "--threads",
            "2",
            "--reference",
        ])
        .arg(&reference)
        .arg("-o")
        .arg(&out)
        .capture();
    o.assert_success();
    let stdout = &o.stdout;
    assert!(stdout.contains("most efficient at 2 spp:"), "{stdout}");
    let table = std::fs::read_to_string(out.join("tradeoff.csv")).expect("csv");
    // 3 configurations (scene file, delta + ratio, one ray-marching step) and the scene file
    // with adaptive sampling, × 2 budgets.
    assert_eq!(table.lines().count(), 1 + 4 * 2, "{table}");
    assert!(table.contains("scene file, adaptive 0.2"), "{table}");
    for line in table.lines().skip(1) {
        let f: Vec<&str> = line.rsplitn(11, ',').collect();
        let rmse: f64 = f[5].parse().expect("rmse");
        assert!(rmse.is_finite() && rmse > 0.0, "{line}");
    }
    assert!(std::fs::read_to_string(out.join("tradeoff.svg"))
        .expect("svg")
        .contains("<polyline"));

    let o = velour()
        .args(["tradeoff", CLOUD, "--unit", "hours", "--reference"])
        .arg(&reference)
        .capture();
    assert!(!o.success() && o.stderr.contains("--unit"));
    let o = velour()
        .args(["tradeoff", CLOUD, "--budgets", "0", "--reference"])
        .arg(&reference)
        .capture();
    assert!(!o.success() && o.stderr.contains("--budgets"));
}

#[test]
fn manifold_nee_is_offered_exactly_where_the_scene_accepts_it() {
    // The eye: both scattering interiors (sclera = object 1, iris = object 4) sit behind the
    // smooth cornea; the absorbing ones are left alone.
    let (doc, configs) = configs_of(EYE);
    let manifold = configs
        .iter()
        .find(|c| c.name == "NEE manifold")
        .unwrap_or_else(|| panic!("{:?}", names(&configs)));
    let objects: Vec<_> = manifold.edits.iter().map(|e| e.target).collect();
    assert_eq!(objects, [Target::Object(1), Target::Object(4)]);
    let text = apply(&doc, manifold).expect("apply");
    load_scene_str(&text, Path::new(EYE)).expect("the edited eye loads");

    // A smooth ball gets it beside exit and interior NEE; a rough one (roughness 0.3, and the
    // shipped skin sphere's 0.6, see homogeneous_scenes_only_vary_nee) does not, and gets the
    // guided connections instead, which behind the smooth ball would be exit-point NEE.
    let dir = TempDir::new("tradeoff-manifold");
    for (roughness, offered) in [(0.0, true), (0.3, false)] {
        let path = dir.join(format!("ball_{roughness}.toml"));
        std::fs::write(&path, ball_scene(roughness)).expect("write");
        let text = ball_scene(roughness);
        let doc: toml::Table = toml::from_str(&text).expect("toml");
        let scene = load_scene(&path).expect("load");
        let configs = configurations(&doc, &scene, &[]);
        let want: &[&str] = if offered {
            &["scene file", "NEE exit", "NEE interior", "NEE manifold"]
        } else {
            &["scene file", "NEE exit", "NEE exit_guided", "NEE interior"]
        };
        assert_eq!(names(&configs), want, "roughness {roughness}");
    }
    // No sphere or distant light: nothing to connect to.
    let path = dir.join("ball_env.toml");
    let text = ball_scene(0.0).replace("type = \"sphere\"\ncenter = [-3.0, 2.0, 2.0]\nradius = 0.1\nradiance = [400.0, 400.0, 400.0]\n\n[[light]]\n", "");
    std::fs::write(&path, &text).expect("write");
    let doc: toml::Table = toml::from_str(&text).expect("toml");
    let scene = load_scene(&path).expect("load");
    assert_eq!(scene.lights.len(), 1);
    assert!(!names(&configurations(&doc, &scene, &[])).contains(&"NEE manifold"));
}

#[test]
fn tradeoff_cli_measures_manifold_nee() {
    let dir = TempDir::new("tradeoff-manifold-cli");
    let scene = dir.join("ball.toml");
    std::fs::write(&scene, ball_scene(0.0)).expect("write");
    let reference = dir.join("ref.exr");
    velour()
        .arg("reference")
        .arg(&scene)
        .args(["--spp", "16", "--threads", "2", "-q", "-o"])
        .arg(&reference)
        .capture()
        .assert_success();
    let out = dir.join("t");
    let o = velour()
        .arg("tradeoff")
        .arg(&scene)
        .args([
            "--budgets",
            "2",
            "--unit",
            "spp",
            "--only",
            "NEE",
            "--threads",
            "2",
        ])
        .arg("--reference")
        .arg(&reference)
        .arg("-o")
        .arg(&out)
        .capture();
    o.assert_success();
    assert!(
        o.stdout.contains("most efficient at 2 spp: NEE "),
        "{}",
        o.stdout
    );
    let table = std::fs::read_to_string(out.join("tradeoff.csv")).expect("csv");
    assert_eq!(table.lines().count(), 1 + 3, "{table}");
    let row = table
        .lines()
        .find(|l| l.starts_with("\"NEE manifold\""))
        .unwrap_or_else(|| panic!("{table}"));
    let f: Vec<&str> = row.rsplitn(11, ',').collect();
    let (rmse, efficiency): (f64, f64) = (
        f[5].parse().expect("rmse"),
        f[2].parse().expect("efficiency"),
    );
    assert!(rmse.is_finite() && rmse > 0.0 && efficiency > 0.0, "{row}");
}
