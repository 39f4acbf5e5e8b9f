//! Level-set spheres written as OpenVDB files: exact signed distances in a narrow band,
//! inactive ±background beyond it (inside as 8³ tiles where a whole brick is deep inside),
//! class `level set`, as OpenVDB's `createLevelSetSphere` lays them out.

use std::path::Path;

use glam::{DAffine3, DVec3, IVec3, Vec3};
use velour::grid::{ChannelKind, SparseGrid, SparseGridBuilder, Storage, TileLevel};
use velour::vdb::{write_vdb, GridToWrite, WriteOptions};

/// A level-set sphere of radius `radius` (world units) at `center`, voxel size `voxel`,
/// half-width `half_width` voxels: background = half_width × voxel, negative inside.
pub fn sphere_grid(center: DVec3, radius: f64, voxel: f64, half_width: f64) -> SparseGrid {
    let bg = half_width * voxel;
    let mut b = SparseGridBuilder::new(Storage::F32);
    let c = b.add_channel("surface", ChannelKind::Scalar, Vec3::splat(bg as f32));
    b.set_index_to_world(DAffine3::from_scale(DVec3::splat(voxel)))
        .expect("transform");
    let lo = ((center - DVec3::splat(radius + bg + voxel)) / voxel)
        .floor()
        .as_ivec3();
    let hi = ((center + DVec3::splat(radius + bg + voxel)) / voxel)
        .ceil()
        .as_ivec3();
    let dist = |ijk: IVec3| (ijk.as_dvec3() * voxel - center).length() - radius;
    for bx in (lo.x >> 3)..=(hi.x >> 3) {
        for by in (lo.y >> 3)..=(hi.y >> 3) {
            for bz in (lo.z >> 3)..=(hi.z >> 3) {
                let key = IVec3::new(bx, by, bz);
                let voxels: Vec<(IVec3, f64)> = (0..512)
                    .map(|v| {
                        let ijk = (key << 3) + IVec3::new(v >> 6, (v >> 3) & 7, v & 7);
                        (ijk, dist(ijk))
                    })
                    .collect();
                if voxels.iter().all(|&(_, d)| d >= bg) {
                    continue;
                }
                if voxels.iter().all(|&(_, d)| d <= -bg) {
                    b.set_tile(TileLevel::Brick, key, &[-bg as f32], false)
                        .expect("tile");
                    continue;
                }
                for (ijk, d) in voxels {
                    if d.abs() < bg {
                        b.set_value(c, ijk, d as f32).expect("value");
                    } else if d < 0.0 {
                        b.set_value(c, ijk, -bg as f32).expect("value");
                        b.set_active(ijk, false).expect("inactive");
                    }
                }
            }
        }
    }
    b.build()
}

/// Writes `grid` as grid `name` of class `class` to `path`.
pub fn write_grid(path: &Path, name: &str, class: &str, grid: &SparseGrid) {
    let mut g = GridToWrite::new(name, grid);
    g.class = class;
    write_vdb(path, &[g], &WriteOptions::default()).expect("write vdb");
}
