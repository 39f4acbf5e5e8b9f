//! The majorant pyramid is conservative (every trilinear lookup inside a cell lies within the
//! cell's bounds, including brick faces, corners and constant tiles), its segments tile the
//! ray interval exactly, and renders with the pyramid and with one global majorant agree.

use glam::{DAffine3, DVec3, IVec3, Vec3};
use proptest::prelude::*;
use velour::grid::{ChannelKind, SparseGrid, SparseGridBuilder, Storage, TileLevel};
use velour::majorant::{MajorantMode, MajorantPyramid};
use velour::math::Ray;
use velour::sampling::Rng;

/// A grid with random bricks, a few 8^3 tiles and a 128^3 tile, under a rotated affine map.
fn test_grid(seed: u64) -> SparseGrid {
    let mut rng = Rng::new(seed, 1);
    let mut b = SparseGridBuilder::new(Storage::F32);
    let c = b.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
    let rot = DAffine3::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
    b.set_index_to_world(
        DAffine3::from_translation(DVec3::new(0.3, -0.2, 0.1))
            * rot
            * DAffine3::from_scale(DVec3::new(0.05, 0.04, 0.06)),
    )
    .expect("map");
    for _ in 0..40 {
        let key = IVec3::new(
            (rng.next_u32() % 6) as i32 - 2,
            (rng.next_u32() % 6) as i32 - 2,
            (rng.next_u32() % 6) as i32 - 2,
        );
        let base = rng.next_f32() * 3.0;
        let values: Vec<f32> = (0..512).map(|_| base * rng.next_f32()).collect();
        b.fill_brick(c, key, &values, [u64::MAX; 8]).expect("brick");
    }
    // Constant 8^3 tiles next to bricks, and a 128^3 tile away from them.
    for (k, v) in [
        (IVec3::new(4, 0, 0), 2.5f32),
        (IVec3::new(-3, 1, 1), 0.7),
        (IVec3::new(0, 4, 0), 4.0),
    ] {
        b.set_tile(TileLevel::Brick, k, &[v], true).expect("tile");
    }
    b.set_tile(TileLevel::Block, IVec3::new(1, 0, 0), &[1.25], true)
        .expect("block tile");
    b.build()
}

fn check_conservative(grid: &SparseGrid, pyramid: &MajorantPyramid, points: &[Vec3]) {
    for &p in points {
        let v = grid.sample_trilinear_index(p);
        let ijk = (p + Vec3::splat(0.5)).floor().as_ivec3();
        for level in 0..pyramid.level_count() {
            let b = pyramid.bounds_at_voxel(level, ijk);
            assert!(
                v <= b.max * (1.0 + 1e-6) + 1e-7 && v >= b.min * (1.0 - 1e-6) - 1e-7,
                "value {v} at {p:?} outside level-{level} bounds {b:?}"
            );
        }
    }
}

#[test]
fn bounds_contain_every_trilinear_value() {
    for seed in 0..3 {
        let grid = test_grid(seed);
        let pyramid = MajorantPyramid::from_grid(&grid, 0).expect("pyramid");
        let mut rng = Rng::new(seed, 9);
        let mut pts = Vec::new();
        // Random points over the whole region (bricks, tiles, the 128^3 tile, empty space).
        for _ in 0..300_000 {
            pts.push(Vec3::new(
                rng.next_f32() * 200.0 - 30.0,
                rng.next_f32() * 60.0 - 25.0,
                rng.next_f32() * 60.0 - 25.0,
            ));
        }
        // Points on brick faces, edges and corners (cell boundaries at 8k − 0.5).
        for _ in 0..200_000 {
            let k = IVec3::new(
                (rng.next_u32() % 50) as i32 - 20,
                (rng.next_u32() % 12) as i32 - 4,
                (rng.next_u32() % 12) as i32 - 4,
            );
            let mut p = (k * 8).as_vec3() - Vec3::splat(0.5);
            let axis = (rng.next_u32() % 4) as usize;
            for a in 0..3 {
                if a != axis {
                    p[a] += rng.next_f32() * 8.0;
                }
            }
            pts.push(p);
            pts.push(p + Vec3::splat(1e-4));
            pts.push(p - Vec3::splat(1e-4));
        }
        check_conservative(&grid, &pyramid, &pts);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn bounds_hold_at_arbitrary_points(x in -40.0f32..200.0, y in -30.0f32..60.0, z in -30.0f32..60.0, seed in 0u64..4) {
        let grid = test_grid(seed);
        let pyramid = MajorantPyramid::from_grid(&grid, 0).expect("pyramid");
        check_conservative(&grid, &pyramid, &[Vec3::new(x, y, z)]);
    }
}

#[test]
fn segments_tile_the_ray_interval() {
    let grid = test_grid(5);
    let pyramid = MajorantPyramid::from_grid(&grid, 0).expect("pyramid");
    let i2w = grid.index_to_world();
    let centre = i2w.transform_point3(DVec3::new(20.0, 8.0, 8.0)).as_vec3();
    let mut rng = Rng::new(3, 3);
    let mut out = Vec::new();
    let dirs = [
        Vec3::X,
        Vec3::Y,
        Vec3::Z,
        -Vec3::X,
        Vec3::new(0.0, -0.0, 1.0),
    ];
    for i in 0..4000 {
        let d = if i < dirs.len() {
            dirs[i]
        } else {
            velour::sampling::sample_uniform_sphere(rng.next_2d())
        };
        let o = centre - d * (rng.next_f32() * 6.0 + 1.0)
            + velour::sampling::sample_uniform_sphere(rng.next_2d()) * rng.next_f32();
        let ray = Ray::new(o, d.normalize());
        for mode in [
            MajorantMode::Hierarchical { finest: 0 },
            MajorantMode::Hierarchical { finest: 2 },
        ] {
            out.clear();
            pyramid.segments(&ray, 0.0, 20.0, mode, &mut out);
            for w in out.windows(2) {
                assert!(w[0].t1 <= w[1].t0 + 1e-6, "overlap {:?}", w);
            }
            for s in &out {
                assert!(s.t0 < s.t1 && s.max >= s.min && s.max > 0.0);
            }
            // Every point of the interval that is not covered has zero density.
            for k in 0..400 {
                let t = 20.0 * (k as f32 + 0.5) / 400.0;
                let covered = out.iter().any(|s| t >= s.t0 && t <= s.t1);
                if !covered {
                    let v = grid.sample_trilinear_world(ray.at(t));
                    assert!(v == 0.0, "uncovered t = {t} has density {v}");
                } else if let Some(s) = out.iter().find(|s| t > s.t0 && t < s.t1) {
                    let v = grid.sample_trilinear_world(ray.at(t));
                    assert!(
                        v <= s.max * (1.0 + 1e-5) + 1e-6 && v >= s.min * (1.0 - 1e-5) - 1e-6,
                        "t {t}: {v} not in {s:?}"
                    );
                }
            }
            // Consecutive segments touch exactly (no gaps) inside the grid's box.
            for w in out.windows(2) {
                if (w[1].t0 - w[0].t1).abs() > 1e-5 {
                    let mid = 0.5 * (w[0].t1 + w[1].t0);
                    assert_eq!(
                        grid.sample_trilinear_world(ray.at(mid)),
                        0.0,
                        "gap with density at t {mid}"
                    );
                }
            }
        }
    }
}

/// Checks that `out` covers `[0, t_max]` of `ray` where the density is non-zero, with bounds
/// that contain the density, and that its segments neither overlap nor leave dense gaps.
fn check_tiling(
    grid: &SparseGrid,
    ray: &Ray,
    t_max: f32,
    out: &[velour::majorant::MajorantSegment],
) {
    for w in out.windows(2) {
        assert!(w[0].t1 <= w[1].t0 + 1e-6, "overlap {:?}", w);
    }
    for s in out {
        assert!(s.t0 < s.t1 && s.max >= s.min && s.max > 0.0, "{s:?}");
        assert!(s.mean >= s.min && s.mean <= s.max, "{s:?}");
    }
    for k in 0..400 {
        let t = t_max * (k as f32 + 0.5) / 400.0;
        let v = grid.sample_trilinear_world(ray.at(t));
        match out.iter().find(|s| t >= s.t0 && t <= s.t1) {
            None => assert!(v == 0.0, "uncovered t = {t} has density {v}"),
            Some(s) => assert!(
                v <= s.max * (1.0 + 1e-5) + 1e-6 && v >= s.min * (1.0 - 1e-5) - 1e-6,
                "t {t}: {v} not in {s:?}"
            ),
        }
    }
}

/// ∫ max dt over the segments that need density lookups (non-homogeneous ones).
fn lookup_integral(out: &[velour::majorant::MajorantSegment]) -> f64 {
    out.iter()
        .filter(|s| s.min != s.max)
        .map(|s| f64::from(s.max) * f64::from(s.t1 - s.t0))
        .sum()
}

#[test]
fn adaptive_segments_are_conservative_at_every_optical_scale() {
    let grid = test_grid(5);
    let pyramid = MajorantPyramid::from_grid(&grid, 0).expect("pyramid");
    let i2w = grid.index_to_world();
    let centre = i2w.transform_point3(DVec3::new(20.0, 8.0, 8.0)).as_vec3();
    let mut rng = Rng::new(4, 3);
    let mut out = Vec::new();
    let mut exhaustive = Vec::new();
    let (mut fine_lookups, mut exhaustive_lookups) = (0.0f64, 0.0f64);
    let (mut coarse_segments, mut exhaustive_segments) = (0usize, 0usize);
    for i in 0..2000 {
        let d = if i < 3 {
            [Vec3::X, -Vec3::Y, Vec3::Z][i]
        } else {
            velour::sampling::sample_uniform_sphere(rng.next_2d())
        };
        let o = centre - d * (rng.next_f32() * 6.0 + 1.0)
            + velour::sampling::sample_uniform_sphere(rng.next_2d()) * rng.next_f32();
        let ray = Ray::new(o, d.normalize());
        for finest in [0u8, 2] {
            let mode = MajorantMode::Hierarchical { finest };
            exhaustive.clear();
            pyramid.segments(&ray, 0.0, 20.0, mode, &mut exhaustive);
            for sigma in [
                1e-6f32,
                0.1,
                3.0,
                100.0,
                1e4,
                1e9,
                0.0,
                f32::INFINITY,
                f32::NAN,
            ] {
                out.clear();
                pyramid.segments_adaptive(&ray, 0.0, 20.0, mode, sigma, &mut out);
                check_tiling(&grid, &ray, 20.0, &out);
                if sigma == 1e9 && finest == 0 {
                    fine_lookups += lookup_integral(&out);
                    exhaustive_lookups += lookup_integral(&exhaustive);
                }
                if sigma == 1e-6 && finest == 0 {
                    coarse_segments += out.len();
                    exhaustive_segments += exhaustive.len();
                }
                if !(sigma.is_finite() && sigma > 0.0) {
                    assert_eq!(out, exhaustive, "σ = {sigma} must give the exhaustive walk");
                }
            }
        }
    }
    // Optically thick: the adaptive walk descends as far as the exhaustive one.
    assert!(
        fine_lookups <= exhaustive_lookups * (1.0 + 1e-4),
        "σ = 1e9: lookup integral {fine_lookups} above the exhaustive walk's {exhaustive_lookups}"
    );
    // Optically thin: cells are emitted whole and merged (one segment per ray or close).
    assert!(
        coarse_segments * 4 < exhaustive_segments,
        "σ = 1e-6: {coarse_segments} segments against {exhaustive_segments} exhaustive"
    );
}

#[test]
fn homogeneous_tiles_become_closed_form_segments() {
    // A grid that is one constant 128^3 tile: deep inside it, segments are homogeneous.
    let mut b = SparseGridBuilder::new(Storage::F32);
    b.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
    b.set_tile(TileLevel::Block, IVec3::ZERO, &[2.0], true)
        .expect("tile");
    let grid = b.build();
    let pyramid = MajorantPyramid::from_grid(&grid, 0).expect("pyramid");
    let ray = Ray::new(Vec3::new(-10.0, 64.0, 64.0), Vec3::X);
    let mut out = Vec::new();
    pyramid.segments(
        &ray,
        0.0,
        200.0,
        MajorantMode::Hierarchical { finest: 0 },
        &mut out,
    );
    let inner: f32 = out
        .iter()
        .filter(|s| s.min == s.max && s.max == 2.0)
        .map(|s| s.t1 - s.t0)
        .sum();
    assert!(inner > 100.0, "homogeneous length {inner}: {out:?}");
}
