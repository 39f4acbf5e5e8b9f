//! The fabric level-of-detail policy (`velour::fabric::lod`): the automatic mip level, the
//! exact-halving rule, the pixel footprint, shell tiles and the 4/π normalisation of
//! fibre-projected extinction.

use glam::{Vec2, Vec3};
use velour::fabric::lod::{
    auto_mip, halves_exactly, shell_tiles, true_size_tiles, voxel_footprint, ViewFootprint,
    MAX_MIP_LEVEL, PROJECTED_EXTINCTION_SCALE,
};
use velour::fabric::{
    generate_patch, voxelise, FabricPatch, VoxeliseOptions, VoxelisedPatch, WeaveParams,
    WeavePattern, YarnParams,
};
use velour::geometry::TriangleMesh;
use velour::math::{Aabb, Mat4};

fn plain_patch(resolution: u32) -> (FabricPatch, VoxelisedPatch) {
    let yarn = YarnParams::preset("cotton1").unwrap();
    let mut p = WeaveParams::new(WeavePattern::Plain, yarn);
    p.repeats = [1, 1];
    let fp = generate_patch(&p, 1).unwrap();
    let vp = voxelise(&fp, resolution, &VoxeliseOptions::default()).unwrap();
    (fp, vp)
}

/// Two triangles over `[0, size.x] × [0, size.y]` at z = 0 with UV = position / size.
fn quad(size: Vec2) -> TriangleMesh {
    let corners = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
    TriangleMesh {
        positions: corners
            .iter()
            .map(|&(u, v)| Vec3::new(u * size.x, v * size.y, 0.0))
            .collect(),
        normals: None,
        uvs: Some(corners.iter().map(|&(u, v)| Vec2::new(u, v)).collect()),
        indices: vec![[0, 1, 2], [0, 2, 3]],
    }
}

#[test]
fn projected_extinction_averages_to_the_isotropic_one() {
    // Mean of sin θ over uniformly distributed directions: ∫₀^π sin θ · (sin θ / 2) dθ = π/4
    // (midpoint rule; the error is far below the tolerance).
    let n = 100_000;
    let h = std::f64::consts::PI / f64::from(n);
    let mean: f64 = (0..n)
        .map(|i| {
            let s = ((f64::from(i) + 0.5) * h).sin();
            s * s / 2.0 * h
        })
        .sum();
    let averaged = f64::from(PROJECTED_EXTINCTION_SCALE) * mean;
    assert!((averaged - 1.0).abs() < 1e-6, "{averaged}");
}

#[test]
fn the_footprint_grows_with_distance_from_the_nearest_point() {
    let view = ViewFootprint::new(Vec3::new(0.0, 0.0, 10.0), 40.0, 64);
    let angle = 40f32.to_radians() / 64.0;
    assert_eq!(view.pixel_angle, angle);
    let unit = Aabb {
        min: Vec3::splat(-1.0),
        max: Vec3::splat(1.0),
    };
    assert!((view.at(unit) - 9.0 * angle).abs() < 1e-6);
    let inside = ViewFootprint::new(Vec3::ZERO, 40.0, 64);
    assert_eq!(inside.at(unit), 0.0);
    // A zero height counts as one pixel.
    assert_eq!(
        ViewFootprint::new(Vec3::ZERO, 40.0, 0).pixel_angle,
        40f32.to_radians()
    );
}

#[test]
fn auto_mip_is_the_coarsest_level_within_the_footprint_that_halves_exactly() {
    let (_, vp) = plain_patch(36);
    assert_eq!(vp.dims, [36, 36]);
    // 36 = 4 · 9: one and two halvings are exact, three are not.
    assert!(halves_exactly(&vp, 0) && halves_exactly(&vp, 1) && halves_exactly(&vp, 2));
    assert!(!halves_exactly(&vp, 3));
    assert_eq!(auto_mip(&vp, 0.5), 0);
    assert_eq!(auto_mip(&vp, 1.99), 0);
    assert_eq!(auto_mip(&vp, 2.0), 1);
    assert_eq!(auto_mip(&vp, 3.9), 1);
    assert_eq!(auto_mip(&vp, 4.0), 2);
    assert_eq!(auto_mip(&vp, 1000.0), 2);
    let (_, vp) = plain_patch(256);
    assert_eq!(auto_mip(&vp, 16.0), 4);
    assert_eq!(auto_mip(&vp, 1e6), MAX_MIP_LEVEL);
}

#[test]
fn shell_tiles_give_the_weave_its_true_size() {
    let (fp, vp) = plain_patch(32);
    // A cloth 10 tiles wide and 4 tall (scene units = the preset's centimetres).
    let mesh = quad(Vec2::new(10.0 * fp.tile.x, 4.0 * fp.tile.y));
    // The UV square covers the whole cloth, so one UV unit is sqrt(10 · 4) tile widths on
    // average (the plain weave's tile is square).
    let expected = (40f32).sqrt().round();
    assert_eq!(true_size_tiles(&mesh, &fp), Some([expected, expected]));
    assert_eq!(shell_tiles(None, &mesh, &fp), Some([expected, expected]));
    assert_eq!(shell_tiles(Some([3.0, 5.0]), &mesh, &fp), Some([3.0, 5.0]));
    let mut no_uv = mesh.clone();
    no_uv.uvs = None;
    assert_eq!(true_size_tiles(&no_uv, &fp), None);
    assert_eq!(shell_tiles(Some([2.0, 2.0]), &no_uv, &fp), Some([2.0, 2.0]));

    // The voxel footprint of that shell: the tiled voxel width along the cloth and its box.
    let (width, bounds) = voxel_footprint(&vp, Mat4::IDENTITY, Some(&mesh), Some([10.0, 4.0]));
    let per_uv = (10.0 * fp.tile.x * 4.0 * fp.tile.y).sqrt();
    let wx = per_uv / (10.0 * vp.dims[0] as f32);
    let wy = per_uv / (4.0 * vp.dims[1] as f32);
    assert!((width / (wx * wy).sqrt() - 1.0).abs() < 1e-4, "{width}");
    assert_eq!(bounds, mesh.bounds());
    // A free-standing patch scaled by 2: voxels twice as wide as the patch's own.
    let (width, bounds) = voxel_footprint(&vp, Mat4::from_scale(Vec3::splat(2.0)), None, None);
    let own = vp.voxel_size.element_product().cbrt() as f32;
    assert!((width / (2.0 * own) - 1.0).abs() < 1e-4, "{width} vs {own}");
    assert!(bounds.extent().x > 1.9 * fp.tile.x, "{bounds:?}");
}
