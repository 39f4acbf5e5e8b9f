//! `scenes/fire.toml` reads as a fire: its flames (the `temperature` grid of `volumes/fire.vdb`
//! emitting blackbody light) are bright and warm (R > G > B), they light the ground beside them,
//! and the smoke above them is darker than the sky beside it. Each comparison is a z-test of
//! region means with standard errors from the pixels' own variances (fixed seed). And the
//! committed VDB is what `tools/make_fire.py` writes, voxel for voxel (when Debian's Python with
//! OpenVDB and numpy is present).

mod common;

use common::external::{require_python_numpy, require_python_openvdb, run_python};
use common::files::{repo_path, TempDir};
use common::render::{region_mean, render_finite, scene_from_text};
use glam::IVec3;
use velour::vdb::{read_vdb_grids, VdbGrid};

/// Standard errors a difference must exceed to count.
const Z: f64 = 5.0;

/// Region of the image as fractions of its width and height: [x0, x1) × [y0, y1), y down.
type Region = [f64; 4];

#[test]
fn fire_scene_has_warm_bright_flames_lit_ground_and_dark_smoke() {
    let path = repo_path("scenes/fire.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    // The shipped framing and samples per pixel at a quarter of the width and height.
    let small = text
        .replace("width = 320", "width = 80")
        .replace("height = 360", "height = 90");
    assert_ne!(
        small, text,
        "the film keys of scenes/fire.toml changed; update this test"
    );
    let scene = scene_from_text(&small, &path);
    let (film, _) = render_finite(&scene, 2);
    let (w, h) = (f64::from(film.width()), f64::from(film.height()));
    let mean = |c: usize, r: Region| {
        region_mean(&film, c, |x, y| {
            let (u, v) = ((f64::from(x) + 0.5) / w, (f64::from(y) + 0.5) / h);
            u >= r[0] && u < r[1] && v >= r[2] && v < r[3]
        })
    };
    // `a` exceeds `b` by more than Z combined standard errors (the sum of both, which bounds the
    // standard error of the difference whatever their correlation).
    let exceeds = |what: &str, a: (f64, f64), b: (f64, f64)| {
        eprintln!(
            "{what}: {:.4} ± {:.4} vs {:.4} ± {:.4}, z = {:.1}",
            a.0,
            a.1,
            b.0,
            b.1,
            (a.0 - b.0) / (a.1 + b.1)
        );
        assert!(
            a.0 - b.0 > Z * (a.1 + b.1),
            "{what}: {:.4} ± {:.4} is not above {:.4} ± {:.4}",
            a.0,
            a.1,
            b.0,
            b.1
        );
    };

    let flames: Region = [0.45, 0.55, 0.68, 0.8];
    let [r, g, b] = [0, 1, 2].map(|c| mean(c, flames));
    exceeds("flames bright (R above 1)", r, (1.0, 0.0));
    exceeds("flames warm (R above G)", r, g);
    exceeds("flames warm (G above B)", g, b);

    // The ground left of the flames against the ground at the image's edge.
    let ground_by_fire: Region = [0.25, 0.42, 0.8, 0.9];
    let ground_far: Region = [0.0, 0.1, 0.8, 0.9];
    exceeds(
        "ground lit by the flames (R)",
        mean(0, ground_by_fire),
        mean(0, ground_far),
    );

    let smoke: Region = [0.45, 0.55, 0.12, 0.25];
    let sky: Region = [0.05, 0.2, 0.12, 0.25];
    exceeds(
        "smoke darker than the sky (B)",
        mean(2, sky),
        mean(2, smoke),
    );
}

fn fire_grids(path: &std::path::Path) -> Vec<VdbGrid> {
    read_vdb_grids(path, &["density", "temperature"])
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn committed_fire_vdb_is_what_make_fire_writes() {
    let committed = fire_grids(&repo_path("volumes/fire.vdb"));
    // Aligned grids (the scene loader refuses others), temperatures only where there is density
    // and at most about 2200 K (grid units of 1000 K).
    let (density, temperature) = (&committed[0], &committed[1]);
    assert_eq!(density.map, temperature.map);
    let (lo, hi) = temperature
        .grid
        .active_bbox()
        .expect("temperature grid is empty");
    let mut t_max = 0.0f32;
    let mut t_acc = temperature.grid.accessor(0);
    for i in lo.x..=hi.x {
        for j in lo.y..=hi.y {
            for k in lo.z..=hi.z {
                let ijk = IVec3::new(i, j, k);
                if temperature.grid.is_active(ijk) {
                    assert!(
                        density.grid.is_active(ijk),
                        "temperature without density at {ijk}"
                    );
                    t_max = t_max.max(t_acc.value(ijk));
                }
            }
        }
    }
    assert!(
        (2.0..2.3).contains(&t_max),
        "hottest voxel {t_max} (x 1000 K)"
    );

    if !require_python_openvdb() || !require_python_numpy() {
        return;
    }
    let dir = TempDir::new("make_fire");
    run_python([
        repo_path("tools/make_fire.py").to_str().unwrap(),
        "--out",
        dir.path().to_str().unwrap(),
    ]);
    let made = fire_grids(&dir.join("fire.vdb"));
    for (a, b) in committed.iter().zip(&made) {
        assert_eq!(a.map, b.map, "{}", a.name);
        let bbox = a.grid.active_bbox();
        assert_eq!(bbox, b.grid.active_bbox(), "{}", a.name);
        let (lo, hi) = bbox.expect("empty grid");
        let (mut acc_a, mut acc_b) = (a.grid.accessor(0), b.grid.accessor(0));
        for i in lo.x..=hi.x {
            for j in lo.y..=hi.y {
                for k in lo.z..=hi.z {
                    let ijk = IVec3::new(i, j, k);
                    assert_eq!(
                        a.grid.is_active(ijk),
                        b.grid.is_active(ijk),
                        "{} {ijk}",
                        a.name
                    );
                    let (va, vb) = (acc_a.value(ijk), acc_b.value(ijk));
                    assert_eq!(va.to_bits(), vb.to_bits(), "{} {ijk}: {va} vs {vb}", a.name);
                }
            }
        }
    }
}
