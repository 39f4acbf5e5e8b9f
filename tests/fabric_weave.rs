//! Weave patterns (docs/references.md §6.10), centrelines (§6.11), patches and velvet
//! (§6.12).

mod common;

use common::stats::poisson_z_score;
use velour::fabric::{
    generate_patch, FabricError, FibreKind, PileParams, TwillDirection, WeaveParams, WeavePattern,
    YarnId, YarnParams,
};
use velour::spectrum::Rgb;

fn rows(p: &WeavePattern) -> Vec<Vec<u8>> {
    p.matrix().unwrap_or_else(|e| panic!("{e}")).to_rows()
}

#[test]
fn matrices_equal_reference() {
    let n = |s: &str| WeavePattern::from_name(s).unwrap();
    assert_eq!(rows(&n("plain")), vec![vec![1, 0], vec![0, 1]]);
    assert_eq!(
        rows(&n("twill21")),
        vec![vec![1, 1, 0], vec![0, 1, 1], vec![1, 0, 1]]
    );
    assert_eq!(
        rows(&n("twill22")),
        vec![
            vec![1, 1, 0, 0],
            vec![0, 1, 1, 0],
            vec![0, 0, 1, 1],
            vec![1, 0, 0, 1]
        ]
    );
    assert_eq!(rows(&n("twill")), rows(&n("twill22")));
    assert_eq!(
        rows(&n("twill31")),
        vec![
            vec![1, 1, 1, 0],
            vec![0, 1, 1, 1],
            vec![1, 0, 1, 1],
            vec![1, 1, 0, 1]
        ]
    );
    assert_eq!(
        rows(&n("basket")),
        vec![
            vec![1, 1, 0, 0],
            vec![1, 1, 0, 0],
            vec![0, 0, 1, 1],
            vec![0, 0, 1, 1]
        ]
    );
    assert_eq!(
        rows(&n("satin")),
        vec![
            vec![0, 1, 1, 1, 1],
            vec![1, 1, 0, 1, 1],
            vec![1, 1, 1, 1, 0],
            vec![1, 0, 1, 1, 1],
            vec![1, 1, 1, 0, 1]
        ]
    );
    let satin = rows(&n("satin"));
    let sateen = rows(&n("sateen"));
    for (a, b) in satin.iter().flatten().zip(sateen.iter().flatten()) {
        assert_eq!(a + b, 1, "sateen is the complement of satin");
    }
    assert_eq!(rows(&n("velvet")), rows(&n("plain")));
    // S twill = Z twill mirrored (shift −1 per row): S[i][j] = Z[i][(over − 1 − j) mod n].
    let s = rows(&WeavePattern::Twill {
        over: 2,
        under: 1,
        direction: TwillDirection::S,
    });
    assert_eq!(s, vec![vec![1, 1, 0], vec![1, 0, 1], vec![0, 1, 1]]);
    let z = rows(&n("twill21"));
    for i in 0..3 {
        for j in 0..3 {
            assert_eq!(s[i][j], z[i][(4 - j) % 3]);
        }
    }
}

#[test]
fn every_pattern_is_valid_and_periodic() {
    let mut pats: Vec<WeavePattern> = velour::fabric::weave::PATTERN_NAMES
        .iter()
        .map(|n| WeavePattern::from_name(n).unwrap())
        .collect();
    for over in 1..5 {
        for under in 1..5 {
            if over + under >= 3 {
                pats.push(WeavePattern::Twill {
                    over,
                    under,
                    direction: TwillDirection::Z,
                });
            }
        }
    }
    for h in 5..13 {
        for step in 2..h - 1 {
            let p = WeavePattern::Satin {
                harness: h,
                step,
                weft_faced: false,
            };
            if let Ok(m) = p.matrix() {
                // Satin: exactly one interlacing per row and column.
                for i in 0..h as i64 {
                    assert_eq!((0..h as i64).filter(|&j| !m.get(i, j)).count(), 1);
                    assert_eq!((0..h as i64).filter(|&j| !m.get(j, i)).count(), 1);
                }
                pats.push(p);
            }
        }
    }
    for p in &pats {
        let m = p.matrix().unwrap();
        for i in 0..m.rows() as i64 {
            let ones = (0..m.cols() as i64).filter(|&j| m.get(i, j)).count();
            assert!(ones > 0 && ones < m.cols(), "{}: row {i}", p.name());
        }
        for j in 0..m.cols() as i64 {
            let ones = (0..m.rows() as i64).filter(|&i| m.get(i, j)).count();
            assert!(ones > 0 && ones < m.rows(), "{}: col {j}", p.name());
        }
        for i in -3..10 {
            for j in -3..10 {
                assert_eq!(
                    m.get(i, j),
                    m.get(i + m.rows() as i64, j - 2 * m.cols() as i64)
                );
            }
        }
    }
}

#[test]
fn satin_moves_must_be_coprime() {
    for (h, step) in [
        (5, 1),
        (5, 4),
        (6, 2),
        (6, 3),
        (8, 4),
        (8, 6),
        (10, 5),
        (5, 0),
        (5, 7),
    ] {
        let e = WeavePattern::Satin {
            harness: h,
            step,
            weft_faced: false,
        }
        .matrix()
        .unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("step") && msg.contains("allowed"), "{msg}");
    }
    // No valid move exists below 5 harnesses.
    for h in [0, 3, 4] {
        let e = WeavePattern::Satin {
            harness: h,
            step: 2,
            weft_faced: false,
        }
        .matrix()
        .unwrap_err();
        assert!(e.to_string().contains("harness"), "{e}");
    }
    for (h, step) in [(5, 2), (5, 3), (7, 2), (7, 3), (8, 3), (8, 5), (12, 5)] {
        WeavePattern::Satin {
            harness: h,
            step,
            weft_faced: false,
        }
        .matrix()
        .unwrap();
    }
    let e = WeavePattern::Satin {
        harness: 8,
        step: 2,
        weft_faced: false,
    }
    .matrix()
    .unwrap_err();
    assert!(e.to_string().contains("3, 5"), "allowed moves listed: {e}");
}

#[test]
fn invalid_patterns_rejected() {
    let e = WeavePattern::from_name("jacquard").unwrap_err();
    assert!(matches!(e, FabricError::UnknownPattern { .. }));
    assert!(e.to_string().contains("jacquard") && e.to_string().contains("satin"));
    let float = WeavePattern::Custom {
        rows: vec![vec![true, true], vec![false, true]],
    };
    assert!(float
        .matrix()
        .unwrap_err()
        .to_string()
        .contains("never interlaces"));
    let ragged = WeavePattern::Custom {
        rows: vec![vec![true, false], vec![false]],
    };
    assert!(ragged.matrix().is_err());
    assert!(WeavePattern::Custom { rows: vec![] }.matrix().is_err());
    assert!(WeavePattern::Twill {
        over: 1,
        under: 1,
        direction: TwillDirection::Z
    }
    .matrix()
    .is_err());
    assert!(WeavePattern::Twill {
        over: 0,
        under: 3,
        direction: TwillDirection::Z
    }
    .matrix()
    .is_err());
    assert!(WeavePattern::Basket { size: 1 }.matrix().is_err());
    let ok = WeavePattern::Custom {
        rows: vec![vec![true, false, false], vec![false, true, true]],
    };
    assert_eq!(ok.matrix().unwrap().cols(), 3);
}

fn small_yarn() -> YarnParams {
    let mut y = YarnParams::preset("cotton2").unwrap();
    y.fibres_per_ply = 6;
    y.segment_length *= 2.0;
    y
}

#[test]
fn plain_weave_centreline_is_the_sinusoid() {
    let p = WeaveParams::new(WeavePattern::Plain, small_yarn());
    let m = p.matrix().unwrap();
    let (hw, hf) = (p.warp_height, p.weft_height);
    let (py, px) = (p.weft_spacing, p.warp_spacing);
    for j in 0..4i64 {
        for k in 0..=400 {
            let y = 4.0 * py * k as f32 / 400.0;
            let want = hw
                * (std::f32::consts::PI * (y - 0.5 * py) / py + std::f32::consts::PI * j as f32)
                    .cos();
            assert!((p.warp_height_at(&m, j, y) - want).abs() < 1e-5 * hw.max(1e-3) + 1e-6);
        }
    }
    for i in 0..4i64 {
        for k in 0..=400 {
            let x = 4.0 * px * k as f32 / 400.0;
            let want = -hf
                * (std::f32::consts::PI * (x - 0.5 * px) / px + std::f32::consts::PI * i as f32)
                    .cos();
            assert!((p.weft_height_at(&m, i, x) - want).abs() < 1e-5 * hf.max(1e-3) + 1e-6);
        }
    }
    // The generated centreline polyline samples the same curve.
    let c = p.warp_centreline(&m, 1).unwrap();
    for q in c.points() {
        let want = hw * (std::f32::consts::PI * (q.y - 0.5 * py) / py + std::f32::consts::PI).cos();
        assert!((q.z - want).abs() < 1e-5);
        assert!((q.x - 1.5 * px).abs() < 1e-6);
    }
}

#[test]
fn crossings_keep_clearance_for_every_pattern() {
    for name in velour::fabric::weave::PATTERN_NAMES {
        let p = WeaveParams::new(WeavePattern::from_name(name).unwrap(), small_yarn());
        p.validate().unwrap();
        let m = p.matrix().unwrap();
        let need = p.required_clearance();
        for i in 0..m.rows() as u32 * p.repeats[1] {
            for j in 0..m.cols() as u32 * p.repeats[0] {
                let x = (j as f32 + 0.5) * p.warp_spacing;
                let y = (i as f32 + 0.5) * p.weft_spacing;
                let zw = p.warp_height_at(&m, j as i64, y);
                let zf = p.weft_height_at(&m, i as i64, x);
                assert!((zw - zf).abs() >= need * (1.0 - 1e-5), "{name} ({i},{j})");
                assert_eq!(zw > zf, m.get(i as i64, j as i64), "warp on top iff W = 1");
            }
        }
        // Periodicity of the centrelines over the tile.
        let tile = p.tile_size().unwrap();
        for k in 0..50 {
            let t = k as f32 / 50.0;
            assert!(
                (p.warp_height_at(&m, 0, t * tile.y)
                    - p.warp_height_at(&m, 0, t * tile.y + tile.y))
                .abs()
                    < 1e-5
            );
        }
    }
    let mut p = WeaveParams::new(WeavePattern::Plain, small_yarn());
    p.warp_height *= 0.5;
    let e = p.validate().unwrap_err().to_string();
    assert!(
        e.contains("warp_height + weft_height") && e.contains("allowed"),
        "{e}"
    );
}

#[test]
fn weave_parameter_errors_name_the_parameter() {
    let base = WeaveParams::new(WeavePattern::Plain, small_yarn());
    type Edit = Box<dyn Fn(&mut WeaveParams)>;
    let cases: Vec<(&str, Edit)> = vec![
        ("warp_spacing", Box::new(|p| p.warp_spacing = 0.0)),
        ("weft_spacing", Box::new(|p| p.weft_spacing = -1.0)),
        ("flyaway_fraction", Box::new(|p| p.flyaway_fraction = -0.5)),
        (
            "warp_albedo",
            Box::new(|p| p.warp_albedo = Rgb::new(1.5, 0.0, 0.0)),
        ),
        ("repeats[0]", Box::new(|p| p.repeats = [0, 1])),
        (
            "warp_yarn.ply_count",
            Box::new(|p| p.warp_yarn.ply_count = 0),
        ),
        (
            "weft_yarn.ellipse_x",
            Box::new(|p| p.weft_yarn.ellipse_x = 0.0),
        ),
        (
            "pile.height",
            Box::new(|p| {
                p.pile = Some(PileParams {
                    height: 0.0,
                    ..PileParams::default()
                })
            }),
        ),
        (
            "samples_per_crossing",
            Box::new(|p| p.samples_per_crossing = 1),
        ),
    ];
    for (name, f) in cases {
        let mut p = base.clone();
        f(&mut p);
        let msg = generate_patch(&p, 1).unwrap_err().to_string();
        assert!(msg.contains(name), "expected {name} in: {msg}");
    }
    let mut p = base.clone();
    p.repeats = [1000, 1000];
    assert!(matches!(
        generate_patch(&p, 1).unwrap_err(),
        FabricError::TooLarge { .. }
    ));
}

#[test]
fn patch_counts_tags_volume_and_albedo() {
    let mut p = WeaveParams::new(WeavePattern::from_name("twill21").unwrap(), small_yarn());
    p.warp_albedo = Rgb::new(0.9, 0.1, 0.1);
    p.weft_albedo = Rgb::new(0.1, 0.1, 0.9);
    let patch = generate_patch(&p, 42).unwrap();
    let y = &p.warp_yarn;
    assert_eq!((patch.warp_count, patch.weft_count), (6, 6));
    let regular = patch
        .fibres
        .iter()
        .filter(|f| f.fibre.kind != FibreKind::Hair)
        .count();
    assert_eq!(regular, 12 * (y.ply_count * y.fibres_per_ply) as usize);
    assert_eq!(patch.fibres.len(), regular + patch.hair_count);
    for j in 0..6 {
        assert!(patch.fibres.iter().any(|f| f.yarn == YarnId::Warp(j)));
        assert!(patch.fibres.iter().any(|f| f.yarn == YarnId::Weft(j)));
    }
    assert!(!patch.fibres.iter().any(|f| f.yarn == YarnId::Pile));
    assert_eq!(patch.albedo(YarnId::Warp(3)), p.warp_albedo);
    assert_eq!(patch.albedo(YarnId::Weft(0)), p.weft_albedo);
    let vol: f64 = patch
        .fibres
        .iter()
        .map(|f| {
            let r = f.fibre.radius as f64;
            f.fibre
                .points
                .windows(2)
                .map(|w| std::f64::consts::PI * r * r * (w[1] - w[0]).length() as f64)
                .sum::<f64>()
        })
        .sum();
    assert!((vol / patch.fibre_volume - 1.0).abs() < 1e-9);
    let tile = p.tile_size().unwrap();
    assert_eq!(patch.tile, tile);
    assert!((tile.x - 6.0 * p.warp_spacing).abs() < 1e-6);
    // Warp fibres run along y over the whole tile; wefts along x.
    for f in patch
        .fibres
        .iter()
        .filter(|f| f.fibre.kind == FibreKind::Regular)
    {
        let a = f.fibre.points[0];
        let b = *f.fibre.points.last().unwrap();
        match f.yarn {
            YarnId::Warp(_) => assert!((b.y - a.y - tile.y).abs() < 0.1 * tile.y),
            YarnId::Weft(_) => assert!((b.x - a.x - tile.x).abs() < 0.1 * tile.x),
            YarnId::Pile => unreachable!(),
        }
    }
    // Regular fibres stay within the yarn envelope around their centreline height range.
    let env = y.envelope_radius();
    let zmax = p.warp_height.max(p.weft_height) + env;
    for f in patch
        .fibres
        .iter()
        .filter(|f| f.fibre.kind == FibreKind::Regular)
    {
        assert!(f.fibre.points.iter().all(|q| q.z.abs() <= zmax * 1.01));
    }
    assert!(patch.bounds.max.z > 0.5 * zmax && patch.bounds.min.z < -0.5 * zmax);
    // Same seed: same patch.
    let again = generate_patch(&p, 42).unwrap();
    assert_eq!(again.fibres, patch.fibres);
}

#[test]
fn flyaway_fraction_scales_flyaway_counts() {
    let mut p = WeaveParams::new(WeavePattern::Plain, small_yarn());
    p.repeats = [3, 3];
    let mut hairs = [0usize; 3];
    let mut loops = [0usize; 3];
    for (k, frac) in [0.0f32, 1.0, 3.0].iter().enumerate() {
        p.flyaway_fraction = *frac;
        let patch = generate_patch(&p, 9).unwrap();
        hairs[k] = patch.hair_count;
        loops[k] = patch.loop_count;
    }
    assert_eq!((hairs[0], loops[0]), (0, 0));
    // Hairs: Poisson with mean ρ_hair·K·(total yarn length)·fraction.
    let y = &p.warp_yarn;
    let m = p.matrix().unwrap();
    let len: f32 = (0..6)
        .map(|j| p.warp_centreline(&m, j).unwrap().length())
        .sum::<f32>()
        * 2.0;
    for (k, frac) in [(1, 1.0f64), (2, 3.0)] {
        let mean = y.hair_density as f64 * y.ply_count as f64 * len as f64 * frac;
        let z = poisson_z_score(hairs[k] as f64, mean);
        assert!(z.abs() < 4.5, "fraction {frac}: {} vs {mean}", hairs[k]);
        // Loops grow with the fraction but saturate at one per fibre per migration period.
        let loop_mean = y.loop_density as f64 * y.ply_count as f64 * len as f64 * frac;
        assert!((loops[k] as f64) < loop_mean + 4.5 * loop_mean.sqrt());
    }
    assert!(loops[2] > loops[1]);
    let periods = len as f64 * y.migration_freq as f64 / y.fibre_pitch as f64 + 12.0;
    let cap = periods * (y.ply_count * y.fibres_per_ply) as f64;
    assert!(
        (loops[2] as f64) < cap * 1.2,
        "{} loops, cap {cap}",
        loops[2]
    );
}

#[test]
fn velvet_pile_tufts() {
    let mut p = WeaveParams::new(WeavePattern::Velvet, small_yarn());
    p.flyaway_fraction = 0.0;
    let pile = PileParams {
        fibres_per_leg: 30,
        ..PileParams::default()
    };
    p.pile = Some(pile.clone());
    let patch = generate_patch(&p, 5).unwrap();
    let pf: Vec<_> = patch
        .fibres
        .iter()
        .filter(|f| f.yarn == YarnId::Pile)
        .collect();
    assert_eq!(
        pf.len(),
        (patch.warp_count * patch.weft_count * 2 * 30) as usize
    );
    assert_eq!(patch.albedo(YarnId::Pile), pile.albedo);
    let nap = velour::math::Vec3::new(pile.nap_azimuth.cos(), pile.nap_azimuth.sin(), 0.0);
    let mut mean_dir = velour::math::Vec3::ZERO;
    for f in &pf {
        assert_eq!(f.fibre.kind, FibreKind::Pile);
        let a = f.fibre.points[0];
        let b = *f.fibre.points.last().unwrap();
        assert!(a.z.abs() < 1e-6);
        let len = f.fibre.length() as f32;
        // Length H(1 ± v), stretched by the sag only slightly.
        assert!(len >= pile.height * (1.0 - pile.height_variation) * 0.999);
        assert!(len <= pile.height * (1.0 + pile.height_variation) * (1.0 + pile.bend));
        assert!(b.z > 0.5 * pile.height);
        mean_dir += (b - a).normalize();
    }
    let mean_dir = mean_dir.normalize();
    // The mean pile direction leans towards the nap by about nap angle (+ the sag).
    let tilt = mean_dir.dot(nap).atan2(mean_dir.z);
    assert!(
        tilt > pile.nap_angle * 0.8 && tilt < pile.nap_angle + 0.15,
        "tilt {tilt}"
    );
    assert!(patch.bounds.max.z > 0.8 * pile.height);
    // Default pile when none is given.
    p.pile = None;
    let patch = generate_patch(&p, 5).unwrap();
    assert!(patch.fibres.iter().any(|f| f.yarn == YarnId::Pile));
    // A pile can be put on any base weave.
    let mut q = WeaveParams::new(WeavePattern::from_name("satin").unwrap(), small_yarn());
    q.pile = Some(PileParams {
        fibres_per_leg: 2,
        every: 5,
        ..PileParams::default()
    });
    let patch = generate_patch(&q, 5).unwrap();
    let n = patch
        .fibres
        .iter()
        .filter(|f| f.yarn == YarnId::Pile)
        .count();
    assert_eq!(n, (patch.weft_count * 2 * 2 * 2) as usize);
}

/// With `snap_pitches`, regular fibres join up across the tile seam (period = tile).
#[test]
fn snapped_regular_fibres_are_periodic() {
    for name in ["plain", "twill31", "satin"] {
        let mut p = WeaveParams::new(WeavePattern::from_name(name).unwrap(), small_yarn());
        p.flyaway_fraction = 0.0;
        let patch = generate_patch(&p, 3).unwrap();
        let mut worst = 0.0f32;
        for f in &patch.fibres {
            let a = f.fibre.points[0];
            let b = *f.fibre.points.last().unwrap();
            let shift = match f.yarn {
                YarnId::Warp(_) => velour::math::Vec3::new(0.0, patch.tile.y, 0.0),
                YarnId::Weft(_) => velour::math::Vec3::new(patch.tile.x, 0.0, 0.0),
                YarnId::Pile => unreachable!(),
            };
            worst = worst.max((b - a - shift).length());
        }
        // Float rounding only (the fibre radius is 8e-4).
        assert!(worst < 2e-4, "{name}: seam gap {worst}");
        // Without snapping the seam is open.
        let mut q = p.clone();
        q.snap_pitches = false;
        let patch = generate_patch(&q, 3).unwrap();
        // Off-axis gap between a fibre's two ends (warps run along y, wefts along x).
        let open = patch
            .fibres
            .iter()
            .map(|f| {
                let d = *f.fibre.points.last().unwrap() - f.fibre.points[0];
                match f.yarn {
                    YarnId::Warp(_) => d.x.abs().max(d.z.abs()),
                    _ => d.y.abs().max(d.z.abs()),
                }
            })
            .fold(0.0f32, f32::max);
        assert!(open > 1e-3, "{name}: unsnapped seam unexpectedly closed");
    }
}

#[test]
fn obj_export_lists_every_vertex() {
    let mut p = WeaveParams::new(WeavePattern::Plain, small_yarn());
    p.repeats = [1, 1];
    let patch = generate_patch(&p, 2).unwrap();
    let mut buf = Vec::new();
    patch.write_obj(&mut buf).unwrap();
    let text = String::from_utf8(buf).unwrap();
    let verts: usize = patch.fibres.iter().map(|f| f.fibre.points.len()).sum();
    assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), verts);
    assert_eq!(
        text.lines().filter(|l| l.starts_with("l ")).count(),
        patch.fibres.len()
    );
    assert!(text.contains("g warp_0") && text.contains("g weft_1"));
    let last = text.lines().rev().find(|l| l.starts_with("l ")).unwrap();
    assert_eq!(last.split(' ').next_back().unwrap(), verts.to_string());
    // I/O failures become errors that say what was being written.
    struct Fail;
    impl std::io::Write for Fail {
        fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
            Err(std::io::Error::other("disk full"))
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let e = patch.write_obj(&mut Fail).unwrap_err().to_string();
    assert!(e.contains("OBJ") && e.contains("disk full"), "{e}");
}
