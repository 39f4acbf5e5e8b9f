//! Procedural yarn (Zhao, Luan, Bala 2016): presets, validation, fibre statistics against
//! their parameters, twist/ply pitch, migration, flyaway counts, centreline frames.

mod common;

use common::chi2::critical_value_999;
use common::stats::poisson_z_score;
use velour::fabric::yarn::{MAX_FIBRES_PER_YARN, PRESET_NAMES};
use velour::fabric::{
    generate_yarn, generate_yarn_on_centreline, Centreline, FabricError, FibreKind, Twist,
    YarnParams,
};
use velour::math::{Vec2, Vec3};

const TAU: f32 = std::f32::consts::TAU;

fn no_flyaways(mut p: YarnParams) -> YarnParams {
    p.hair_density = 0.0;
    p.loop_density = 0.0;
    p
}

fn wrap(mut x: f32) -> f32 {
    while x > std::f32::consts::PI {
        x -= TAU;
    }
    while x < -std::f32::consts::PI {
        x += TAU;
    }
    x
}

#[test]
fn presets_load_validate_and_aliases_match() {
    for name in PRESET_NAMES {
        let p = YarnParams::preset(name).unwrap_or_else(|e| panic!("{name}: {e}"));
        p.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(p.r_max, 1.0);
        assert_ne!(
            p.ply_twist, p.fibre_twist,
            "{name}: fits have opposite twists"
        );
    }
    assert_eq!(
        YarnParams::preset("cotton").unwrap(),
        YarnParams::preset("cotton1").unwrap()
    );
    assert_eq!(
        YarnParams::preset("SILK").unwrap(),
        YarnParams::preset("silk1").unwrap()
    );
    assert_eq!(
        YarnParams::preset("rayon").unwrap(),
        YarnParams::preset("rayon1").unwrap()
    );
    assert_eq!(
        YarnParams::preset("polyester").unwrap(),
        YarnParams::preset("polyester1").unwrap()
    );
    let c2 = YarnParams::preset("cotton2").unwrap();
    assert_eq!((c2.ply_count, c2.fibres_per_ply), (3, 36));
    assert!((c2.fibre_pitch - 0.4347).abs() < 1e-6);
    assert!((c2.ply_offset - 0.03304 / 2.0).abs() < 1e-7);
    // (μ, σ_cfg) = (0.0248, 0.0064) -> std_dev = 0.0032.
    assert!((c2.loop_r_max.std_dev - 0.0032).abs() < 1e-7);
}

#[test]
fn unknown_preset_lists_names() {
    let e = YarnParams::preset("wool").unwrap_err();
    assert!(matches!(e, FabricError::UnknownPreset { .. }));
    let msg = e.to_string();
    assert!(
        msg.contains("wool") && msg.contains("cotton1") && msg.contains("silk2"),
        "{msg}"
    );
}

#[test]
fn bad_parameters_name_the_parameter() {
    let base = YarnParams::preset("cotton1").unwrap();
    type Edit = Box<dyn Fn(&mut YarnParams)>;
    let cases: Vec<(&str, Edit)> = vec![
        ("ply_count", Box::new(|p| p.ply_count = 0)),
        ("fibres_per_ply", Box::new(|p| p.fibres_per_ply = 0)),
        ("yarn_radius", Box::new(|p| p.yarn_radius = 0.0)),
        ("yarn_radius", Box::new(|p| p.yarn_radius = -1.0)),
        ("ellipse_x", Box::new(|p| p.ellipse_x = -0.01)),
        ("ellipse_y", Box::new(|p| p.ellipse_y = f32::NAN)),
        ("fibre_pitch", Box::new(|p| p.fibre_pitch = 0.0)),
        ("ply_pitch", Box::new(|p| p.ply_pitch = -0.3)),
        ("epsilon", Box::new(|p| p.epsilon = 1.0)),
        ("beta", Box::new(|p| p.beta = -0.1)),
        ("r_min", Box::new(|p| p.r_min = 1.5)),
        ("fibre_radius", Box::new(|p| p.fibre_radius = 0.0)),
        ("hair_density", Box::new(|p| p.hair_density = -1.0)),
        (
            "loop_r_max.std_dev",
            Box::new(|p| p.loop_r_max.std_dev = -1.0),
        ),
        ("segment_length", Box::new(|p| p.segment_length = 0.0)),
    ];
    for (name, f) in cases {
        let mut p = base.clone();
        f(&mut p);
        let e = p.validate().expect_err(name);
        let msg = e.to_string();
        assert!(
            msg.contains(&format!("`{name}`")),
            "expected `{name}` in: {msg}"
        );
        assert!(msg.contains("allowed"), "{msg}");
        assert!(generate_yarn(&p, 1.0, 1).is_err());
    }
    // Fibre count beyond memory.
    let mut p = base.clone();
    p.fibres_per_ply = 2_000_000;
    let e = p.validate().unwrap_err();
    assert!(matches!(e, FabricError::TooLarge { .. }), "{e}");
    assert!(
        e.to_string().contains("fibres_per_ply")
            && e.to_string().contains(&MAX_FIBRES_PER_YARN.to_string())
    );
    // Vertex count beyond memory (many tiny segments).
    let mut p = base.clone();
    p.segment_length = 1e-6;
    let e = generate_yarn(&p, 10.0, 1).unwrap_err();
    assert!(matches!(e, FabricError::TooLarge { .. }), "{e}");
    // Bad length.
    let e = generate_yarn(&base, -1.0, 1).unwrap_err();
    assert!(e.to_string().contains("`length`"), "{e}");
}

#[test]
fn fibre_counts_match_k_times_m_plus_flyaways() {
    let p = YarnParams::preset("cotton2").unwrap();
    let y = generate_yarn(&no_flyaways(p.clone()), 1.0, 7).unwrap();
    assert_eq!(y.fibres.len(), (p.ply_count * p.fibres_per_ply) as usize);
    assert!(y.fibres.iter().all(|f| f.kind == FibreKind::Regular));
    let y = generate_yarn(&p, 1.0, 7).unwrap();
    let hairs = y
        .fibres
        .iter()
        .filter(|f| f.kind == FibreKind::Hair)
        .count();
    assert_eq!(hairs, y.hair_count);
    assert_eq!(
        y.fibres.len(),
        (p.ply_count * p.fibres_per_ply) as usize + y.hair_count
    );
    assert!(y.loop_count > 0 && y.hair_count > 0);
    assert!(y.fibres.iter().any(|f| f.kind == FibreKind::Loop));
    for f in &y.fibres {
        assert!(f.points.len() >= 2);
        assert!(f.points.iter().all(|q| q.is_finite()));
        assert!(f.ply < p.ply_count);
        assert_eq!(f.radius, p.fibre_radius);
    }
    // Deterministic in the seed.
    let y2 = generate_yarn(&p, 1.0, 7).unwrap();
    assert_eq!(y.fibres, y2.fibres);
    let y3 = generate_yarn(&p, 1.0, 8).unwrap();
    assert_ne!(y.fibres, y3.fibres);
}

/// Histogram of `R_i` against `2R p(R)/q` (p from the paper's eq. 1, integrated here).
#[test]
fn radial_distribution_matches_density_chi_square() {
    for name in ["cotton2", "polyester1", "rayon1", "silk2"] {
        let mut p = no_flyaways(YarnParams::preset(name).unwrap());
        p.ply_count = 1;
        p.fibres_per_ply = 40_000;
        p.segment_length = 1.0; // 2 vertices per fibre
        let y = generate_yarn(&p, 0.01, 11).unwrap();
        let e = std::f64::consts::E;
        let dens = |r: f64| {
            let base = (e - r.exp()) / (e - 1.0);
            2.0 * r * ((1.0 - 2.0 * p.epsilon as f64) * base.powf(p.beta as f64) + p.epsilon as f64)
        };
        let bins = 25;
        let sub = 200;
        let mut mass = vec![0.0f64; bins];
        for (b, m) in mass.iter_mut().enumerate() {
            for k in 0..sub {
                let r = (b as f64 + (k as f64 + 0.5) / sub as f64) / bins as f64;
                *m += dens(r) / (bins * sub) as f64;
            }
        }
        let q: f64 = mass.iter().sum();
        let mut counts = vec![0u64; bins];
        for f in &y.fibres {
            assert!((0.0..1.0).contains(&f.section_radius));
            counts[((f.section_radius * bins as f32) as usize).min(bins - 1)] += 1;
        }
        let n = y.fibres.len() as f64;
        let chi2: f64 = counts
            .iter()
            .zip(&mass)
            .map(|(&c, &m)| {
                let ex = n * m / q;
                (c as f64 - ex).powi(2) / ex
            })
            .sum();
        let crit = critical_value_999((bins - 1) as f64);
        assert!(chi2 < crit, "{name}: chi2 {chi2} >= {crit}");
    }
}

/// Normalised position of a fibre vertex in its ply's co-rotating cross-section frame.
fn ply_local(p: &YarnParams, ply: u32, q: Vec3) -> Vec2 {
    let d = Vec2::new(q.x, q.y) - p.ply_centre(ply, q.z);
    let (ax, ay) = p.ply_axes(ply, q.z);
    Vec2::new(d.dot(ax) / p.ellipse_x, d.dot(ay) / p.ellipse_y)
}

#[test]
fn fibre_twist_returns_after_one_pitch() {
    let mut p = no_flyaways(YarnParams::preset("cotton1").unwrap());
    p.fibres_per_ply = 20;
    p.segment_length = p.fibre_pitch / 64.0;
    let len = 2.0 * p.fibre_pitch;
    let y = generate_yarn(&p, len, 3).unwrap();
    for f in &y.fibres {
        let n = f.points.len() - 1;
        assert_eq!(n, 128);
        let ang = |k: usize| {
            let l = ply_local(&p, f.ply, f.points[k]);
            l.y.atan2(l.x)
        };
        assert!(wrap(ang(0) - f.section_angle).abs() < 1e-3);
        assert!(wrap(ang(64) - ang(0)).abs() < 2e-3, "not periodic in α");
        assert!(wrap(ang(128) - ang(0)).abs() < 2e-3);
        // Half a pitch: opposite side; a quarter: +π/2 for a Z fibre twist.
        assert!((wrap(ang(32) - ang(0)).abs() - std::f32::consts::PI).abs() < 2e-3);
        let quarter = wrap(ang(16) - ang(0));
        assert!(
            (quarter - p.fibre_twist.sign() * std::f32::consts::FRAC_PI_2).abs() < 2e-3,
            "{quarter}"
        );
    }
    assert_eq!(p.fibre_twist, Twist::S);
    // Twist flags of the released configs: rayon1/3/4 have S plies, the others Z plies.
    for (name, ply) in [
        ("cotton1", Twist::Z),
        ("polyester1", Twist::Z),
        ("rayon1", Twist::S),
        ("rayon3", Twist::S),
        ("rayon4", Twist::S),
        ("silk2", Twist::Z),
    ] {
        assert_eq!(YarnParams::preset(name).unwrap().ply_twist, ply, "{name}");
    }
}

#[test]
fn ply_centroids_follow_ply_helix() {
    let mut p = no_flyaways(YarnParams::preset("cotton2").unwrap());
    p.fibres_per_ply = 3000;
    p.migration_freq = 0.0;
    p.segment_length = p.ply_pitch / 8.0;
    let y = generate_yarn(&p, p.ply_pitch, 5).unwrap();
    // Fibre positions relative to the ply centre are symmetric in the (normalised) disc:
    // the ply's fibre centroid at every vertex is the ply centre.
    let n_vert = y.fibres[0].points.len();
    for ply in 0..p.ply_count {
        let fibres: Vec<_> = y.fibres.iter().filter(|f| f.ply == ply).collect();
        for k in 0..n_vert {
            let z = fibres[0].points[k].z;
            let mean = fibres
                .iter()
                .map(|f| Vec2::new(f.points[k].x, f.points[k].y))
                .sum::<Vec2>()
                / fibres.len() as f32;
            let c = p.ply_centre(ply, z);
            // Standard error: e·R_rms/sqrt(n), R_rms < 0.75.
            let tol = 5.0 * p.ellipse_y * 0.75 / (fibres.len() as f32).sqrt();
            assert!((mean - c).length() < tol, "ply {ply} z {z}: {mean} vs {c}");
        }
        // The helix itself: one turn per α_ply, radius ply_offset.
        let c0 = p.ply_centre(ply, 0.0);
        assert!((p.ply_centre(ply, p.ply_pitch) - c0).length() < 1e-5);
        assert!((p.ply_centre(ply, 0.5 * p.ply_pitch) + c0).length() < 1e-5);
        assert!((c0.length() - p.ply_offset).abs() < 1e-6);
    }
}

#[test]
fn migration_radius_between_rmin_and_rmax() {
    let mut p = no_flyaways(YarnParams::preset("rayon4").unwrap());
    p.fibres_per_ply = 30;
    let period = p.fibre_pitch / p.migration_freq;
    p.segment_length = period / 128.0;
    let y = generate_yarn(&p, 3.0 * period, 9).unwrap();
    for f in &y.fibres {
        let r: Vec<f32> = f
            .points
            .iter()
            .map(|&q| ply_local(&p, f.ply, q).length())
            .collect();
        let (mn, mx) = r
            .iter()
            .fold((f32::MAX, 0.0f32), |(a, b), &x| (a.min(x), b.max(x)));
        let ri = f.section_radius;
        let tol = 2e-3 + 1e-4 / ri.max(1e-3);
        assert!((mx / ri - p.r_max).abs() < tol, "max {mx} R_i {ri}");
        assert!((mn / ri - p.r_min).abs() < tol, "min {mn} R_i {ri}");
        // Period α/s: radius repeats after 128 vertices.
        for k in 0..r.len() - 128 {
            assert!((r[k] - r[k + 128]).abs() < 1e-3 * ri.max(0.05), "k {k}");
        }
    }
}

#[test]
fn flyaway_counts_match_densities() {
    let mut p = YarnParams::preset("cotton1").unwrap();
    p.fibres_per_ply = 40;
    p.segment_length = 0.05;
    // A loop peaks at R_max^loop (normalised by sqrt(e_X e_Y)); loops never compound.
    let loop_cap =
        (p.loop_r_max.mean + 6.0 * p.loop_r_max.std_dev) / (p.ellipse_x * p.ellipse_y).sqrt();
    let len = 20.0;
    let mut hairs = 0usize;
    let mut loops = 0usize;
    let runs = 3;
    for seed in 0..runs {
        let y = generate_yarn(&p, len, 100 + seed).unwrap();
        hairs += y.hair_count;
        loops += y.loop_count;
        for f in y.fibres.iter().filter(|f| f.kind == FibreKind::Loop) {
            // A looped fibre leaves its normal migration envelope somewhere.
            let mx = f
                .points
                .iter()
                .map(|&q| ply_local(&p, f.ply, q).length())
                .fold(0.0f32, f32::max);
            assert!(mx > p.r_max * f.section_radius * 1.001);
            assert!(mx < loop_cap * 1.001, "loop reaches {mx} > {loop_cap}");
        }
        for f in y.fibres.iter().filter(|f| f.kind == FibreKind::Hair) {
            assert!(f.points.iter().all(|q| (0.0..=len).contains(&q.z)));
        }
    }
    let k = (p.ply_count as f64) * len as f64 * runs as f64;
    for (name, n, rho) in [
        ("hair", hairs, p.hair_density),
        ("loop", loops, p.loop_density),
    ] {
        let mean = rho as f64 * k;
        let z = poisson_z_score(n as f64, mean);
        assert!(z.abs() < 4.0, "{name}: {n} vs {mean} (z = {z})");
    }
    let none = generate_yarn(&p.with_flyaway_scale(0.0).unwrap(), len, 1).unwrap();
    assert_eq!((none.hair_count, none.loop_count), (0, 0));
    assert!(p.with_flyaway_scale(-1.0).is_err());
}

#[test]
fn scaling_to_other_units_scales_geometry() {
    let mut p = YarnParams::preset("silk2").unwrap();
    p.fibres_per_ply = 10;
    let mm = p.scaled(10.0).unwrap();
    assert!((mm.fibre_pitch - 10.0 * p.fibre_pitch).abs() < 1e-5);
    assert!((mm.hair_density - p.hair_density / 10.0).abs() < 1e-5);
    let a = generate_yarn(&p, 1.0, 21).unwrap();
    let b = generate_yarn(&mm, 10.0, 21).unwrap();
    assert_eq!(a.fibres.len(), b.fibres.len());
    assert_eq!(a.hair_count, b.hair_count);
    for (fa, fb) in a.fibres.iter().zip(&b.fibres) {
        assert_eq!(fa.points.len(), fb.points.len());
        for (qa, qb) in fa.points.iter().zip(&fb.points) {
            assert!((*qa * 10.0 - *qb).length() < 1e-3, "{qa} {qb}");
        }
    }
    assert!((b.fibre_volume() / a.fibre_volume() - 1000.0).abs() < 1.0);
    assert!(p.scaled(0.0).is_err());
}

fn sine_centreline(n: usize, len: f32, amp: f32) -> Centreline {
    let pts = (0..=n)
        .map(|k| {
            let y = len * k as f32 / n as f32;
            Vec3::new(0.3, y, amp * (TAU * y / (len / 2.0)).cos())
        })
        .collect();
    Centreline::new(pts, Vec3::Z).unwrap()
}

#[test]
fn rotation_minimising_frame_is_continuous() {
    let c = sine_centreline(400, 1.0, 0.05);
    let mut prev: Option<velour::fabric::CentrelineFrame> = None;
    for k in 0..=1000 {
        let s = c.length() * k as f32 / 1000.0;
        let f = c.frame_at(s);
        assert!((f.tangent.length() - 1.0).abs() < 1e-4);
        assert!((f.normal.length() - 1.0).abs() < 1e-4);
        assert!(f.normal.dot(f.tangent).abs() < 1e-4);
        // Planar curve (x = const): the RMF binormal stays the plane normal, never flips.
        assert!((f.binormal.x.abs() - 1.0).abs() < 1e-4, "{:?}", f.binormal);
        if let Some(pf) = prev {
            assert!(pf.normal.dot(f.normal) > 0.99);
            assert!(pf.binormal.dot(f.binormal) > 0.9999);
        }
        prev = Some(f);
    }
    // A non-planar curve (helix): still continuous and orthonormal.
    let pts: Vec<Vec3> = (0..=600)
        .map(|k| {
            let t = k as f32 / 600.0 * 3.0 * TAU;
            Vec3::new(t.cos(), t.sin(), 0.2 * t)
        })
        .collect();
    let c = Centreline::new(pts, Vec3::X).unwrap();
    let mut prev = c.frame_at(0.0);
    for k in 1..=2000 {
        let f = c.frame_at(c.length() * k as f32 / 2000.0);
        assert!(f.normal.dot(f.tangent).abs() < 1e-4);
        assert!(prev.normal.dot(f.normal) > 0.99);
        prev = f;
    }
    // Bad centrelines.
    assert!(Centreline::new(vec![Vec3::ZERO], Vec3::Z).is_err());
    assert!(Centreline::new(vec![Vec3::ZERO, Vec3::ZERO], Vec3::Z).is_err());
    assert!(Centreline::new(vec![Vec3::ZERO, Vec3::NAN], Vec3::Z).is_err());
}

/// On a bent centreline the twist is uniform in arc length: a fibre of a single centred
/// ply (no migration) sits at angle θ_i + 2π s (±1/α ± 1/α_ply) in the (N, B) frame.
#[test]
fn twist_is_mapped_to_arc_length() {
    let mut p = no_flyaways(YarnParams::preset("cotton1").unwrap());
    p.ply_count = 1;
    p.ply_offset = 0.0;
    p.fibres_per_ply = 5;
    p.ellipse_y = p.ellipse_x;
    p.r_min = 1.0;
    let c = sine_centreline(800, 1.0, 0.08);
    p.segment_length = c.length() / 300.0;
    let y = generate_yarn_on_centreline(&p, &c, 4).unwrap();
    let rate = TAU * (p.fibre_twist.sign() / p.fibre_pitch + p.ply_twist.sign() / p.ply_pitch);
    for f in &y.fibres {
        let n = f.points.len() - 1;
        for (k, q) in f.points.iter().enumerate() {
            let s = c.length() * k as f32 / n as f32;
            let fr = c.frame_at(s);
            let d = *q - fr.position;
            assert!(d.dot(fr.tangent).abs() < 1e-4);
            let ang = d.dot(fr.binormal).atan2(d.dot(fr.normal));
            let want = f.section_angle + rate * s;
            assert!(wrap(ang - want).abs() < 5e-3, "k {k}: {ang} vs {want}");
            assert!((d.length() - f.section_radius * p.ellipse_x).abs() < 1e-4);
        }
    }
    // Twist phase after the whole centreline = length/α·2π (fibre frame only).
    assert!(y.length == c.length());
}

mod never_panics {
    use proptest::prelude::*;
    use velour::fabric::{generate_patch, generate_yarn, WeaveParams, WeavePattern, YarnParams};

    fn weird() -> impl Strategy<Value = f32> {
        prop_oneof![
            Just(f32::NAN),
            Just(f32::INFINITY),
            Just(-1.0f32),
            Just(0.0f32),
            Just(1e-30f32),
            Just(1e30f32),
            0.0f32..2.0,
        ]
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]
        #[test]
        fn bad_yarn_values_error_not_panic(
            a in weird(), b in weird(), c in weird(), d in weird(), e in weird(),
            f in weird(), g in weird(), k in 0u32..5, m in 0u32..6, len in weird(),
        ) {
            let mut p = YarnParams::preset("cotton2").unwrap();
            p.ply_count = k;
            p.fibres_per_ply = m;
            p.ellipse_x = a;
            p.fibre_pitch = b.max(0.05);
            p.epsilon = c;
            p.beta = d;
            p.r_min = e;
            p.hair_r_span.mean = f;
            p.loop_r_max.std_dev = g;
            let r = generate_yarn(&p, len.min(2.0), 1);
            if let Ok(y) = r {
                prop_assert!(y.fibres.iter().all(|f| f.points.iter().all(|q| q.is_finite())));
            }
            let mut w = WeaveParams::new(WeavePattern::Plain, YarnParams::preset("cotton2").unwrap());
            w.warp_yarn.fibres_per_ply = 2;
            w.weft_yarn.fibres_per_ply = 2;
            w.warp_spacing = a;
            w.warp_height = b;
            w.flyaway_fraction = c;
            let _ = generate_patch(&w, 2);
        }
    }
}
