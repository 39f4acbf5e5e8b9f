//! Assembling the grid from the band's distances and the parity vote: level-set values and
//! inactive ±background interiors, or fog ramps with active interior tiles (and noise), with the
//! figures of [`VoxelizeReport`] (docs/voxelize.md, "What is written").

use glam::{DAffine3, DVec3, IVec3, Vec3};
use rayon::prelude::*;

use crate::grid::{
    ChannelKind, GridError, SparseGrid, SparseGridBuilder, Storage, TileLevel, BRICK_DIM,
    BRICK_VOXELS,
};
use crate::procedural::FbmField;

use super::distance::BrickDistances;
use super::sign::ParityTables;
use super::{VoxelizeError, VoxelizeReport, FOG_GRID, LEVEL_SET_GRID};

/// Per band brick: values, active mask, split votes.
struct BrickValues {
    key: IVec3,
    values: Vec<f32>,
    mask: [u64; 8],
    split: u64,
}

impl BrickValues {
    /// Adds this brick's active voxels and split sign votes to `report`.
    fn count_into(&self, report: &mut VoxelizeReport) {
        report.split_votes += self.split;
        report.active_voxels += self
            .mask
            .iter()
            .map(|m| u64::from(m.count_ones()))
            .sum::<u64>();
    }
}

fn local(v: usize) -> IVec3 {
    IVec3::new((v >> 6) as i32, ((v >> 3) & 7) as i32, (v & 7) as i32)
}

/// Computes band bricks' values in parallel: `f(inside, distance in voxels, voxel)` returns
/// `(value, active)`.
fn band_values<F>(bands: &[BrickDistances], parity: &ParityTables, f: F) -> Vec<BrickValues>
where
    F: Fn(bool, f32, IVec3) -> (f32, bool) + Sync,
{
    bands
        .par_iter()
        .map(|b| {
            let origin = b.key * BRICK_DIM;
            let mut values = vec![0.0f32; BRICK_VOXELS];
            let mut mask = [0u64; 8];
            let mut split = 0;
            for (i, (out, &d)) in values.iter_mut().zip(b.d.iter()).enumerate() {
                let ijk = origin + local(i);
                let votes = parity.votes(ijk);
                if d.is_finite() && (1..=5).contains(&votes) {
                    split += 1;
                }
                let (value, active) = f(votes >= 4, d, ijk);
                *out = value;
                if active {
                    mask[i >> 6] |= 1 << (i & 63);
                }
            }
            BrickValues {
                key: b.key,
                values,
                mask,
                split,
            }
        })
        .collect()
}

/// Brick keys of the domain that no band reaches and that lie inside the mesh.
fn inside_bricks(
    bands: &[BrickDistances],
    parity: &ParityTables,
    (lo, hi): (IVec3, IVec3),
) -> Vec<IVec3> {
    let band: std::collections::HashSet<[i32; 3]> =
        bands.iter().map(|b| b.key.to_array()).collect();
    let k0 = lo.div_euclid(IVec3::splat(BRICK_DIM));
    let k1 = hi.div_euclid(IVec3::splat(BRICK_DIM));
    let xs: Vec<i32> = (k0.x..=k1.x).collect();
    xs.par_iter()
        .flat_map_iter(|&x| {
            let mut out = Vec::new();
            for y in k0.y..=k1.y {
                for z in k0.z..=k1.z {
                    let key = IVec3::new(x, y, z);
                    // No voxel of a brick without band lies within the reach (≥ 1 voxel) of
                    // the surface, so one voxel decides the whole brick.
                    if !band.contains(&key.to_array()) && parity.inside(key * BRICK_DIM) {
                        out.push(key);
                    }
                }
            }
            out
        })
        .collect()
}

fn builder(voxel_size: f64, name: &str, background: f32) -> Result<SparseGridBuilder, GridError> {
    let mut b = SparseGridBuilder::new(Storage::F32);
    b.add_channel(name, ChannelKind::Scalar, Vec3::splat(background));
    b.set_index_to_world(DAffine3::from_scale(DVec3::splat(voxel_size)))?;
    Ok(b)
}

pub(super) type Assembled = (SparseGrid, &'static str, &'static str);

pub(super) fn level_set(
    bands: &[BrickDistances],
    parity: &ParityTables,
    domain: (IVec3, IVec3),
    half_width: f64,
    v: f64,
    report: &mut VoxelizeReport,
) -> Result<Assembled, VoxelizeError> {
    let bg = (half_width * v) as f32;
    let w = half_width as f32;
    let vf = v as f32;
    let bricks = band_values(bands, parity, |inside, d, _| {
        let s = if inside { -1.0 } else { 1.0 };
        if d < w {
            (s * d * vf, true)
        } else {
            (s * bg, false)
        }
    });
    let inside = inside_bricks(bands, parity, domain);
    let mut b = builder(v, LEVEL_SET_GRID, bg)?;
    b.reserve_bricks(bricks.len());
    for br in &bricks {
        b.fill_brick(0, br.key, &br.values, br.mask)?;
        br.count_into(report);
        report.integral += br
            .values
            .iter()
            .enumerate()
            .filter(|(i, _)| br.mask[i >> 6] >> (i & 63) & 1 != 0)
            .map(|(_, &x)| f64::from(x))
            .sum::<f64>()
            * v.powi(3);
    }
    for key in &inside {
        b.set_tile(TileLevel::Brick, *key, &[-bg], false)?;
    }
    report.inside_bricks = inside.len();
    Ok((b.build(), LEVEL_SET_GRID, "level set"))
}

pub(super) fn fog(
    bands: &[BrickDistances],
    parity: &ParityTables,
    domain: (IVec3, IVec3),
    band: f64,
    v: f64,
    noise: Option<&FbmField>,
    report: &mut VoxelizeReport,
) -> Result<Assembled, VoxelizeError> {
    let bf = band as f32;
    let factor = |ijk: IVec3| -> f32 { noise.map_or(1.0, |n| n.density_rest(ijk.as_dvec3() * v)) };
    let bricks = band_values(bands, parity, |inside, d, ijk| {
        if inside {
            ((d / bf).min(1.0) * factor(ijk), true)
        } else {
            (0.0, false)
        }
    });
    let inside = inside_bricks(bands, parity, domain);
    let mut b = builder(v, FOG_GRID, 0.0)?;
    b.reserve_bricks(bricks.len() + if noise.is_some() { inside.len() } else { 0 });
    let voxel_volume = v.powi(3);
    for br in &bricks {
        b.fill_brick(0, br.key, &br.values, br.mask)?;
        br.count_into(report);
        report.integral += br.values.iter().map(|&x| f64::from(x)).sum::<f64>() * voxel_volume;
    }
    match noise {
        None => {
            for key in &inside {
                b.set_tile(TileLevel::Brick, *key, &[1.0], true)?;
            }
            report.integral += (inside.len() * BRICK_VOXELS) as f64 * voxel_volume;
        }
        Some(_) => {
            let dense: Vec<(IVec3, Vec<f32>)> = inside
                .par_iter()
                .map(|&key| {
                    let origin = key * BRICK_DIM;
                    let vals = (0..BRICK_VOXELS)
                        .map(|i| factor(origin + local(i)))
                        .collect();
                    (key, vals)
                })
                .collect();
            for (key, vals) in &dense {
                b.fill_brick(0, *key, vals, [u64::MAX; 8])?;
                report.integral += vals.iter().map(|&x| f64::from(x)).sum::<f64>() * voxel_volume;
            }
        }
    }
    report.active_voxels += (inside.len() * BRICK_VOXELS) as u64;
    report.inside_bricks = inside.len();
    Ok((b.build(), FOG_GRID, "fog volume"))
}
