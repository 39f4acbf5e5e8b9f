//! The finest level's cell bounds of a grid's pyramid ([`super::MajorantPyramid::from_grid`]):
//! per brick, the min and max over every value a trilinear lookup inside each cell can return
//! (the cell's voxels plus a one-voxel apron) and the mean of the cell's own voxels.
//!
//! A brick next to stored voxels is read once into a 10³ block (the brick and its apron, each
//! of the 27 neighbouring nodes copied as a whole), and the cells' min and max come from three
//! separable passes (along x, then y, then z) over that block instead of one pass over every
//! cell's (s + 2)³ window: min and max of a set do not depend on the order they are taken in,
//! so the bounds are the same values.

use glam::IVec3;

use super::Bounds;
use crate::grid::{voxel_offset, BrickData, Node, SparseGrid, BRICK_DIM, BRICK_VOXELS};

/// Voxels along one edge of a brick with its apron.
const SIDE: usize = BRICK_DIM as usize + 2;

/// Cells along one edge of a brick at most (cells of one voxel).
const MAX_CELLS: usize = BRICK_DIM as usize;

/// Calls `emit(sub, bounds)` for each of the `(8 >> cell_log2)³` cells of brick `key`
/// (`cell_log2` in 0..=3): the min and max over every value a trilinear lookup inside the cell
/// can return (its voxels plus a one-voxel apron, across neighbouring bricks and tiles) and the
/// mean of its own voxels (the tile's value where the brick is a tile).
pub(super) fn brick_cell_bounds(
    grid: &SparseGrid,
    channel: usize,
    key: IVec3,
    cell_log2: i32,
    mut emit: impl FnMut(IVec3, Bounds),
) {
    let n = BRICK_DIM >> cell_log2;
    let mut nodes = [Node::Tile {
        tile: 0,
        level: crate::grid::TileLevel::Root,
        active: false,
    }; 27];
    let mut all_tiles = true;
    let mut i = 0;
    for dz in -1..=1 {
        for dy in -1..=1 {
            for dx in -1..=1 {
                let node = grid.node_at_brick(key + IVec3::new(dx, dy, dz));
                all_tiles &= matches!(node, Node::Tile { .. });
                nodes[i] = node;
                i += 1;
            }
        }
    }
    let tile_value = |node: Node| match node {
        Node::Tile { tile, .. } => grid.tile_value(channel, tile),
        Node::Brick(_) => 0.0,
    };
    if all_tiles {
        let own = tile_value(nodes[13]);
        if nodes
            .iter()
            .all(|&node| tile_value(node).to_bits() == own.to_bits())
        {
            // One value everywhere (most often the background): every cell's min, max and
            // mean are that value.
            for z in 0..n {
                for y in 0..n {
                    for x in 0..n {
                        emit(IVec3::new(x, y, z), Bounds::constant(own));
                    }
                }
            }
            return;
        }
        // Each cell sees its own tile and the neighbours its apron reaches.
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let c = IVec3::new(x, y, z);
                    let reach = |k: i32| -> (i32, i32) {
                        (if k == 0 { -1 } else { 0 }, if k == n - 1 { 1 } else { 0 })
                    };
                    let (rx, ry, rz) = (reach(c.x), reach(c.y), reach(c.z));
                    let mut b = Bounds {
                        min: f32::INFINITY,
                        max: f32::NEG_INFINITY,
                        mean: tile_value(nodes[13]),
                    };
                    for dz in rz.0..=rz.1 {
                        for dy in ry.0..=ry.1 {
                            for dx in rx.0..=rx.1 {
                                let v = tile_value(
                                    nodes[((dz + 1) * 9 + (dy + 1) * 3 + dx + 1) as usize],
                                );
                                b.min = b.min.min(v);
                                b.max = b.max.max(v);
                            }
                        }
                    }
                    emit(c, b);
                }
            }
        }
        return;
    }
    let block = apron_block(grid, channel, &nodes);
    let own_tile = match nodes[13] {
        Node::Tile { tile, .. } => Some(grid.tile_value(channel, tile)),
        Node::Brick(_) => None,
    };
    let s = 1usize << cell_log2;
    let n = n as usize;
    let (lo, hi) = window_min_max(&block, s, n);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let (x0, y0, z0) = (x * s, y * s, z * s);
                // The mean in the order the voxels were always summed (z, y, x).
                let mut sum = 0.0f64;
                for bz in z0 + 1..z0 + s + 1 {
                    for by in y0 + 1..y0 + s + 1 {
                        for bx in x0 + 1..x0 + s + 1 {
                            sum += f64::from(block[(bz * SIDE + by) * SIDE + bx]);
                        }
                    }
                }
                let c = (z * n + y) * n + x;
                emit(
                    IVec3::new(x as i32, y as i32, z as i32),
                    Bounds {
                        min: lo[c],
                        max: hi[c],
                        mean: own_tile.unwrap_or((sum / (s * s * s) as f64) as f32),
                    },
                );
            }
        }
    }
}

/// The brick whose 27 neighbouring nodes (brick keys `key + (dx, dy, dz)`, `dx` fastest) are
/// `nodes`, with its one-voxel apron: `block[(z·10 + y)·10 + x]` is channel `channel` of voxel
/// `8·key − 1 + (x, y, z)`, the value an [`crate::grid::Accessor`] returns there.
fn apron_block(grid: &SparseGrid, channel: usize, nodes: &[Node; 27]) -> [f32; SIDE * SIDE * SIDE] {
    // Along one axis, neighbour offset d − 1 covers block indices `first..first + len`, which
    // are the neighbour's local voxels `local..local + len`.
    const SPANS: [(usize, usize, usize); 3] = [(0, 7, 1), (1, 0, 8), (9, 0, 1)];
    let mut block = [0.0f32; SIDE * SIDE * SIDE];
    for (i, node) in nodes.iter().enumerate() {
        let (sx, sy, sz) = (SPANS[i % 3], SPANS[i / 3 % 3], SPANS[i / 9]);
        match *node {
            Node::Tile { tile, .. } => {
                let v = grid.tile_value(channel, tile);
                for z in sz.0..sz.0 + sz.2 {
                    for y in sy.0..sy.0 + sy.2 {
                        let row = (z * SIDE + y) * SIDE;
                        block[row + sx.0..row + sx.0 + sx.2].fill(v);
                    }
                }
            }
            Node::Brick(b) => {
                let data = grid.brick_data(channel, b as usize);
                let read = |v: usize| -> f32 {
                    match data {
                        BrickData::F32(d) => d[v * (d.len() / BRICK_VOXELS)],
                        BrickData::F16(d) => d[v * (d.len() / BRICK_VOXELS)].to_f32(),
                    }
                };
                for k in 0..sz.2 {
                    for j in 0..sy.2 {
                        let row = ((sz.0 + k) * SIDE + sy.0 + j) * SIDE + sx.0;
                        for m in 0..sx.2 {
                            let local =
                                IVec3::new((sx.1 + m) as i32, (sy.1 + j) as i32, (sz.1 + k) as i32);
                            block[row + m] = read(voxel_offset(local));
                        }
                    }
                }
            }
        }
    }
    block
}

/// The min and max of `block` (10³, x fastest) over each cell's window: cell `(x, y, z)` of
/// `n` per axis and `s` voxels wide covers block indices `s·x .. s·x + s + 2` on each axis (its
/// voxels and the apron). Outputs are indexed `(z·n + y)·n + x`.
fn window_min_max(
    block: &[f32; SIDE * SIDE * SIDE],
    s: usize,
    n: usize,
) -> (
    [f32; MAX_CELLS * MAX_CELLS * MAX_CELLS],
    [f32; MAX_CELLS * MAX_CELLS * MAX_CELLS],
) {
    let w = s + 2;
    // Along x: per block row (z, y), per cell x.
    let mut xlo = [0.0f32; SIDE * SIDE * MAX_CELLS];
    let mut xhi = [0.0f32; SIDE * SIDE * MAX_CELLS];
    for r in 0..SIDE * SIDE {
        for x in 0..n {
            let (mut a, mut b) = (f32::INFINITY, f32::NEG_INFINITY);
            for &v in &block[r * SIDE + x * s..r * SIDE + x * s + w] {
                a = a.min(v);
                b = b.max(v);
            }
            xlo[r * n + x] = a;
            xhi[r * n + x] = b;
        }
    }
    // Along y: per block layer z, per cell (y, x).
    let mut ylo = [0.0f32; SIDE * MAX_CELLS * MAX_CELLS];
    let mut yhi = [0.0f32; SIDE * MAX_CELLS * MAX_CELLS];
    for z in 0..SIDE {
        for y in 0..n {
            for x in 0..n {
                let (mut a, mut b) = (f32::INFINITY, f32::NEG_INFINITY);
                for by in y * s..y * s + w {
                    let r = (z * SIDE + by) * n + x;
                    a = a.min(xlo[r]);
                    b = b.max(xhi[r]);
                }
                ylo[(z * n + y) * n + x] = a;
                yhi[(z * n + y) * n + x] = b;
            }
        }
    }
    // Along z: per cell.
    let mut lo = [0.0f32; MAX_CELLS * MAX_CELLS * MAX_CELLS];
    let mut hi = [0.0f32; MAX_CELLS * MAX_CELLS * MAX_CELLS];
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let (mut a, mut b) = (f32::INFINITY, f32::NEG_INFINITY);
                for bz in z * s..z * s + w {
                    let r = (bz * n + y) * n + x;
                    a = a.min(ylo[r]);
                    b = b.max(yhi[r]);
                }
                lo[(z * n + y) * n + x] = a;
                hi[(z * n + y) * n + x] = b;
            }
        }
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::super::test_grids::{mixed_grid, Mix};
    use super::*;
    use crate::grid::{ChannelKind, SparseGridBuilder, Storage};
    use glam::Vec3;

    /// The cell bounds as they were computed before the separable passes: every voxel of the
    /// block read through an accessor, every cell's window scanned whole.
    fn reference(grid: &SparseGrid, channel: usize, key: IVec3, cell_log2: i32) -> Vec<Bounds> {
        let mut acc = grid.accessor(channel);
        let own_tile = match grid.node_at_brick(key) {
            Node::Tile { tile, .. } => Some(grid.tile_value(channel, tile)),
            Node::Brick(_) => None,
        };
        let base = key << 3;
        let mut block = [0.0f32; SIDE * SIDE * SIDE];
        for z in 0..SIDE {
            for y in 0..SIDE {
                for x in 0..SIDE {
                    let ijk = base + IVec3::new(x as i32 - 1, y as i32 - 1, z as i32 - 1);
                    block[(z * SIDE + y) * SIDE + x] = acc.value(ijk);
                }
            }
        }
        let s = 1usize << cell_log2;
        let n = 8 >> cell_log2;
        let mut out = Vec::new();
        for z in 0..n {
            for y in 0..n {
                for x in 0..n {
                    let (x0, y0, z0) = (x * s, y * s, z * s);
                    let mut b = Bounds {
                        min: f32::INFINITY,
                        max: f32::NEG_INFINITY,
                        mean: 0.0,
                    };
                    let mut sum = 0.0f64;
                    for bz in z0..z0 + s + 2 {
                        for by in y0..y0 + s + 2 {
                            for bx in x0..x0 + s + 2 {
                                let v = block[(bz * SIDE + by) * SIDE + bx];
                                b.min = b.min.min(v);
                                b.max = b.max.max(v);
                                let own = (x0 + 1..x0 + s + 1).contains(&bx)
                                    && (y0 + 1..y0 + s + 1).contains(&by)
                                    && (z0 + 1..z0 + s + 1).contains(&bz);
                                if own {
                                    sum += f64::from(v);
                                }
                            }
                        }
                    }
                    b.mean = own_tile.unwrap_or((sum / (s * s * s) as f64) as f32);
                    out.push(b);
                }
            }
        }
        out
    }

    /// Sparse grids (both storages, a scalar and a vector channel before the density so that
    /// the density is not channel 0 of a one-component layout) with scattered voxels, brick
    /// tiles and a block tile: every brick key around them gives the reference's bounds, bit
    /// for bit.
    #[test]
    fn cell_bounds_equal_the_whole_window_scan() {
        let mut checked = 0;
        for (seed, storage) in [(1u64, Storage::F32), (2, Storage::F16), (3, Storage::F32)] {
            let mut rng = Mix(seed);
            let (grid, density) = mixed_grid(storage, &mut rng);
            for kz in -3..6 {
                for ky in -2..5 {
                    for kx in -2..7 {
                        let key = IVec3::new(kx, ky, kz);
                        for cell_log2 in 0..=3 {
                            for channel in [0, density] {
                                let want = reference(&grid, channel, key, cell_log2);
                                let mut got = Vec::new();
                                brick_cell_bounds(&grid, channel, key, cell_log2, |_, b| {
                                    got.push(b);
                                });
                                assert_eq!(want.len(), got.len());
                                for (w, g) in want.iter().zip(&got) {
                                    assert_eq!(
                                        w.min.to_bits(),
                                        g.min.to_bits(),
                                        "{key} {cell_log2}"
                                    );
                                    assert_eq!(
                                        w.max.to_bits(),
                                        g.max.to_bits(),
                                        "{key} {cell_log2}"
                                    );
                                    assert_eq!(
                                        w.mean.to_bits(),
                                        g.mean.to_bits(),
                                        "{key} {cell_log2}"
                                    );
                                }
                                checked += want.len();
                            }
                        }
                    }
                }
            }
        }
        assert!(checked > 100_000, "{checked}");
    }

    /// The pyramid's level 0, filled one layer of brick keys per task in parallel, holds
    /// every key's cell bounds where the key's cells lie (the mean clamped into the range):
    /// no layer is shifted, swapped or left at the background.
    #[test]
    fn parallel_level_zero_places_every_key_layer() {
        let mut rng = Mix(7);
        let mut b = SparseGridBuilder::new(Storage::F32);
        let density = b.add_channel("density", ChannelKind::Scalar, Vec3::splat(0.0));
        for _ in 0..4000 {
            let p = IVec3::new(
                (rng.next() % 48) as i32 - 20,
                (rng.next() % 30) as i32 - 6,
                (rng.next() % 56) as i32 - 24,
            );
            b.set_value(density, p, 0.1 + rng.f32()).expect("voxel");
        }
        let grid = b.build();
        let pyramid = super::super::MajorantPyramid::from_grid(&grid, density).expect("pyramid");
        let cell_log2 = pyramid.finest_cell_voxels().trailing_zeros() as i32;
        let mut checked = 0;
        for kz in -4..5 {
            for ky in -2..5 {
                for kx in -4..5 {
                    let key = IVec3::new(kx, ky, kz);
                    brick_cell_bounds(&grid, density, key, cell_log2, |sub, want| {
                        let got = pyramid.bounds_at_voxel(0, (key << 3i32) + (sub << cell_log2));
                        assert_eq!(want.min.to_bits(), got.min.to_bits(), "{key} {sub}");
                        assert_eq!(want.max.to_bits(), got.max.to_bits(), "{key} {sub}");
                        let mean = want.mean.clamp(want.min, want.max);
                        assert_eq!(mean.to_bits(), got.mean.to_bits(), "{key} {sub}");
                        checked += 1;
                    });
                }
            }
        }
        assert!(checked > 10_000, "{checked}");
    }
}
