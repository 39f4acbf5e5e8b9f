//! A coarse map of a grid channel's integral towards one distant direction: from points of
//! the grid, ∫ d(x + s·ω) ds over s ≥ 0 (world length) to the grid's edge. Media turn it into
//! a *prediction* of the transmittance towards a distant light (exp(−σ_t · map)), not an
//! estimate: the integrator plays Russian roulette on that light's shadow rays with it before
//! they are traced, and a roulette may depend on anything but the random numbers it decides,
//! so the map's error costs variance, never bias.
//!
//! Built by one sweep against the direction (a semi-Lagrangian march, one map slice at a
//! time): the integral at a node is the integral at the point one slice further along ω
//! (bilinear in that slice) plus the step between them (two trilinear lookups, the midpoint
//! rule on each half). The nodes are `cell` voxels apart, `cell` chosen so that the map has at
//! most 33 nodes along its longest axis whatever the grid's resolution (33³ nodes, 144 kB).

use glam::{DAffine3, IVec3, Vec3};
use rayon::prelude::*;

use super::SparseGrid;

/// Nodes along the map's longest axis (at most): 33 nodes gave the dense peer cloud the same
/// efficiency as 65 and 17 at a seventh of 65's set-up (docs/BENCHMARKS.md, "Shadow rays to
/// the sun rouletted by a predicted transmittance").
const MAP_NODES: i32 = 33;

/// The integral of a grid channel from points of the grid to the grid's edge along one
/// direction, on a regular lattice of the grid's index space.
#[derive(Clone, Debug)]
pub struct SunMap {
    /// Unit world direction the map was made for.
    to_light: Vec3,
    /// World to index space (f32 copy of the grid's map).
    world_to_index: glam::Affine3A,
    /// Index-space position of node (0, 0, 0).
    origin: Vec3,
    /// Node spacing, voxels.
    cell: f32,
    /// The largest node coordinate per axis (`dims − 1`), for the clamp.
    top: Vec3,
    /// The largest cell's lower node per axis (`max(dims − 2, 0)`).
    last_cell: IVec3,
    /// `tau` index steps: one node along y, one along z (x is 1).
    stride_y: usize,
    stride_z: usize,
    /// `tau` index offsets of a cell's upper corner per axis (0 along axes of one node).
    step: [usize; 3],
    /// The integral per node (density × world length), x fastest.
    tau: Vec<f32>,
}

impl SunMap {
    /// The map of channel `channel` of `grid` along `to_light` (unit, world), or `None` when
    /// the grid has nothing active or the direction is not finite.
    #[must_use]
    pub fn build(grid: &SparseGrid, channel: usize, to_light: Vec3) -> Option<SunMap> {
        let (lo, hi) = grid.active_bbox()?;
        let lo = (lo - IVec3::ONE).as_vec3();
        let hi = (hi + IVec3::ONE).as_vec3();
        let extent = (hi - lo).max_element();
        let cell = (extent / (MAP_NODES - 1) as f32).max(1.0);
        let dims = ((hi - lo) / cell).ceil().as_ivec3() + IVec3::ONE;
        let w2i: DAffine3 = grid.world_to_index();
        let world_to_index =
            glam::Affine3A::from_mat3_translation(w2i.matrix3.as_mat3(), w2i.translation.as_vec3());
        let s = world_to_index.transform_vector3(to_light);
        let a = if s.x.abs() >= s.y.abs() && s.x.abs() >= s.z.abs() {
            0
        } else if s.y.abs() >= s.z.abs() {
            1
        } else {
            2
        };
        let sa = s[a];
        if !(sa.abs() > 0.0) || !s.is_finite() {
            return None;
        }
        // One slice towards the light: index step `h` (node units), world length `len`.
        let h = s * (cell / sa.abs()) / cell;
        let len = cell / sa.abs();
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        let (nb, nc) = (dims[b] as usize, dims[c] as usize);
        let slice = nb * nc;
        // Slices ordered from the light's side: slice 0 of `by_slice` is the one farthest
        // towards the light.
        let na = dims[a] as usize;
        let mut by_slice = vec![0.0f32; na * slice];
        let node_index = |k: usize| if sa > 0.0 { na - 1 - k } else { k };
        for k in 1..na {
            let (done, rest) = by_slice.split_at_mut(k * slice);
            let prev = &done[(k - 1) * slice..];
            let cur = &mut rest[..slice];
            let ka = node_index(k) as f32;
            cur.par_chunks_mut(nc).enumerate().for_each_init(
                || grid.padded_accessor(channel),
                |acc, (ib, row)| {
                    for (ic, out) in row.iter_mut().enumerate() {
                        let mut n = Vec3::ZERO;
                        n[a] = ka;
                        n[b] = ib as f32;
                        n[c] = ic as f32;
                        let next = n + h;
                        // Bilinear in the previous slice (zero depth beyond its sides).
                        let (fb, fc) = (next[b], next[c]);
                        let upstream =
                            if fb < 0.0 || fc < 0.0 || fb > (nb - 1) as f32 || fc > (nc - 1) as f32
                            {
                                0.0
                            } else {
                                let (ib0, ic0) = (
                                    (fb as usize).min(nb.saturating_sub(2)),
                                    (fc as usize).min(nc.saturating_sub(2)),
                                );
                                let (tb, tc) = (fb - ib0 as f32, fc - ic0 as f32);
                                let at =
                                    |i: usize, j: usize| prev[(i.min(nb - 1)) * nc + j.min(nc - 1)];
                                let v0 = at(ib0, ic0) * (1.0 - tc) + at(ib0, ic0 + 1) * tc;
                                let v1 = at(ib0 + 1, ic0) * (1.0 - tc) + at(ib0 + 1, ic0 + 1) * tc;
                                v0 * (1.0 - tb) + v1 * tb
                            };
                        let p = lo + n * cell;
                        let step = h * cell;
                        let d = 0.5
                            * (acc.sample_trilinear(p + 0.25 * step)
                                + acc.sample_trilinear(p + 0.75 * step));
                        *out = upstream + d.max(0.0) * len;
                    }
                },
            );
        }
        // Reorder into x-fastest node order.
        let mut tau = vec![0.0f32; by_slice.len()];
        for k in 0..na {
            let ia = node_index(k);
            for ib in 0..nb {
                for ic in 0..nc {
                    let mut n = [0usize; 3];
                    n[a] = ia;
                    n[b] = ib;
                    n[c] = ic;
                    let i = (n[2] * dims.y as usize + n[1]) * dims.x as usize + n[0];
                    tau[i] = by_slice[k * slice + ib * nc + ic];
                }
            }
        }
        let (nx, nxy) = (dims.x as usize, (dims.x * dims.y) as usize);
        Some(SunMap {
            to_light,
            world_to_index,
            origin: lo,
            cell,
            top: (dims - IVec3::ONE).as_vec3(),
            last_cell: (dims - IVec3::splat(2)).max(IVec3::ZERO),
            stride_y: nx,
            stride_z: nxy,
            step: [
                usize::from(dims.x > 1),
                if dims.y > 1 { nx } else { 0 },
                if dims.z > 1 { nxy } else { 0 },
            ],
            tau,
        })
    }

    /// The direction (unit, world) the map was made for.
    #[must_use]
    pub fn to_light(&self) -> Vec3 {
        self.to_light
    }

    /// The integral from world point `p` along the map's direction (density × world
    /// length), trilinear between the nodes (clamped to the map's box).
    #[must_use]
    pub fn integral(&self, p: Vec3) -> f32 {
        let g = (self.world_to_index.transform_point3(p) - self.origin) / self.cell;
        let g = g.clamp(Vec3::ZERO, self.top);
        // `g ≥ 0`, so the cast's truncation is the floor (without a call to `floorf`).
        let i = g.as_ivec3().min(self.last_cell);
        let t = g - i.as_vec3();
        let base = i.z as usize * self.stride_z + i.y as usize * self.stride_y + i.x as usize;
        let [dx, dy, dz] = self.step;
        debug_assert!(base + dz + dy + dx < self.tau.len());
        // SAFETY: `g` is clamped to [0, dims − 1] (a NaN casts to 0), so `0 ≤ i ≤ last_cell`
        // and `i + 1 ≤ dims − 1` along every axis with a step; the farthest corner
        // `base + dx + dy + dz` is then a node of the map, and `tau` holds all of them.
        let v = |o: usize| unsafe { *self.tau.get_unchecked(base + o) };
        let x00 = v(0) + (v(dx) - v(0)) * t.x;
        let x10 = v(dy) + (v(dy + dx) - v(dy)) * t.x;
        let x01 = v(dz) + (v(dz + dx) - v(dz)) * t.x;
        let x11 = v(dz + dy) + (v(dz + dy + dx) - v(dz + dy)) * t.x;
        let y0 = x00 + (x10 - x00) * t.y;
        let y1 = x01 + (x11 - x01) * t.y;
        y0 + (y1 - y0) * t.z
    }
}
