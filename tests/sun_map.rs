//! The grid's map of its integral towards a distant direction (`SparseGrid::sun_map`), which
//! predicts the sun's transmittance for the shadow rays' Russian roulette, against a fine
//! march of the same trilinear field.

use glam::{DAffine3, DMat3, DVec3, IVec3, Vec3};
use velour::grid::{ChannelKind, SparseGrid, SparseGridBuilder, Storage};
use velour::sampling::Rng;

/// A 40³-voxel smooth blob (density up to 1, zero outside a ball) placed in the unit cube.
fn blob() -> SparseGrid {
    let mut b = SparseGridBuilder::new(Storage::F32);
    b.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
    let n = 40;
    let c = Vec3::splat((n - 1) as f32 / 2.0);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let p = Vec3::new(x as f32, y as f32, z as f32);
                let r = (p - c).length() / (n as f32 / 2.0);
                if r < 1.0 {
                    let wave = 0.5 + 0.5 * (0.35 * p.x).sin() * (0.27 * p.y + 0.4 * p.z).cos();
                    b.set_value(0, IVec3::new(x, y, z), (1.0 - r * r) * wave)
                        .expect("voxel");
                }
            }
        }
    }
    let m = DAffine3::from_mat3_translation(
        DMat3::from_diagonal(DVec3::new(1.0, 1.2, 0.9) / f64::from(n)),
        DVec3::splat(-0.5),
    );
    b.set_index_to_world(m).expect("transform");
    b.build()
}

/// ∫ d(p + s·ω) ds (world length) by the midpoint rule with steps of 0.02 voxels.
fn marched(grid: &SparseGrid, p: Vec3, dir: Vec3) -> f32 {
    let ds = 0.02 / 40.0;
    let mut sum = 0.0f64;
    let mut s = 0.5 * ds;
    while s < 3.0 {
        sum += f64::from(grid.sample_trilinear_world(p + dir * s)) * f64::from(ds);
        s += ds;
    }
    sum as f32
}

#[test]
fn the_map_agrees_with_a_fine_march_along_the_direction() {
    let grid = blob();
    let dir = Vec3::new(-0.5, 0.8, 0.4).normalize();
    let map = grid.sun_map(0, dir).expect("a map");
    let mut rng = Rng::new(5, 0);
    let (mut worst, mut largest, mut worst_reversed) = (0.0f32, 0.0f32, 0.0f32);
    for _ in 0..300 {
        let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3::splat(0.5);
        let truth = marched(&grid, p, dir);
        let got = map.integral(p);
        largest = largest.max(truth);
        worst = worst.max((got - truth).abs() - 0.12 * truth);
        // The same comparison against the march the other way (a map swept from the wrong
        // side): the test must be able to tell.
        let reversed = marched(&grid, p, -dir);
        worst_reversed = worst_reversed.max((got - reversed).abs() - 0.12 * reversed);
    }
    eprintln!("largest {largest}; beyond 12 %: {worst} (reversed: {worst_reversed})");
    // The blob's integrals reach about 0.37 (density × world length). The sweep interpolates
    // each slice from the last, which diffuses the field across the direction a little (the
    // peaks about 8 % low, the fringes a little high): a prediction, within 12 % + 0.015.
    assert!(largest > 0.3, "the blob is too thin to test: {largest}");
    assert!(worst < 0.015, "map off by {worst} beyond 12 %");
    assert!(
        worst_reversed > 0.1,
        "the test cannot tell the direction: {worst_reversed}"
    );
}

#[test]
fn the_map_is_made_for_one_direction_only() {
    let grid = blob();
    let dir = Vec3::new(0.3, -0.2, 0.9).normalize();
    assert!(grid.sun_map(0, dir).is_some());
    assert!(grid.sun_map(0, -dir).is_none());
    assert!(grid.sun_map(0, dir).is_some());
}
