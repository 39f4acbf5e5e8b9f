//! Statistics of active values, with OpenVDB's definitions.

use crate::grid::{BrickData, SparseGrid, BRICK_VOXELS};
use glam::IVec3;

/// Statistics of the active values of one channel of a grid, with the definitions of
/// OpenVDB's tools (as in `truth.jsonl` of the fixtures): tiles count as the voxels they
/// cover, sums are over value × voxels covered in f64, the moment is the sum of value × count ×
/// index-space centre of each active item. Vector channels give per-component figures.
/// Non-finite values are counted in `non_finite` and left out of min, max, sum and moment.
#[derive(Clone, Debug, PartialEq)]
pub struct GridStats {
    /// Active voxels, counting tiles as the voxels they cover.
    pub active_voxels: u64,
    /// Active voxels by level: `[root tiles, 128^3 tiles, 8^3 tiles, brick voxels]`.
    pub active_voxels_by_level: [u64; 4],
    /// Number of bricks (VDB leaves), active or not.
    pub leaf_count: u64,
    /// Components per value (1 or 3).
    pub components: usize,
    /// Per-component minimum of active values (`+inf` when none).
    pub min: [f64; 3],
    /// Per-component maximum of active values (`-inf` when none).
    pub max: [f64; 3],
    /// Per-component sum of value × voxels covered.
    pub sum: [f64; 3],
    /// Sum of |value| × voxels covered (vector channels).
    pub sum_len: f64,
    /// Scalar channels: sum of value × count × index-space centre per axis.
    pub moment: [f64; 3],
    /// Number of active items (voxels or tiles) holding NaN or infinite values.
    pub non_finite: u64,
    /// Inclusive active index-space bounding box.
    pub active_bbox: Option<(IVec3, IVec3)>,
}

impl GridStats {
    /// Computes the statistics of channel `c` of `grid`.
    ///
    /// # Panics
    /// If `c` is not a channel of `grid` (programming error).
    #[must_use]
    pub fn compute(grid: &SparseGrid, c: usize) -> GridStats {
        let comps = grid.channel_kind(c).map_or(1, |k| k.components());
        let mut s = GridStats {
            active_voxels: 0,
            active_voxels_by_level: [0; 4],
            leaf_count: grid.brick_count() as u64,
            components: comps,
            min: [f64::INFINITY; 3],
            max: [f64::NEG_INFINITY; 3],
            sum: [0.0; 3],
            sum_len: 0.0,
            moment: [0.0; 3],
            non_finite: 0,
            active_bbox: grid.active_bbox(),
        };
        let add = |v: [f32; 3], count: f64, centre: [f64; 3], s: &mut GridStats| {
            if v[..comps].iter().any(|x| !x.is_finite()) {
                s.non_finite += 1;
                return;
            }
            let mut len2 = 0.0;
            for (k, &vk) in v[..comps].iter().enumerate() {
                let x = f64::from(vk);
                s.min[k] = s.min[k].min(x);
                s.max[k] = s.max[k].max(x);
                s.sum[k] += x * count;
                len2 += x * x;
            }
            s.sum_len += len2.sqrt() * count;
            if comps == 1 {
                let x = f64::from(v[0]);
                for (m, c) in s.moment.iter_mut().zip(centre) {
                    *m += x * count * c;
                }
            }
        };
        let mut buf = vec![0f32; BRICK_VOXELS * comps];
        for b in 0..grid.brick_count() {
            let m = grid.brick_active_mask(b);
            let o = grid.brick_origin(b);
            match grid.brick_data(c, b) {
                BrickData::F32(d) => buf.copy_from_slice(d),
                BrickData::F16(d) => {
                    for (x, h) in buf.iter_mut().zip(d) {
                        *x = h.to_f32();
                    }
                }
            }
            if comps == 1 {
                // Scalar fast path: per-brick accumulators, moments relative to the origin.
                let (mut mn, mut mx) = (s.min[0], s.max[0]);
                let (mut sum, mut sabs, mut mom) = (0.0f64, 0.0f64, [0.0f64; 3]);
                let mut count = 0u64;
                for (wi, &word) in m.iter().enumerate() {
                    let mut w = word;
                    while w != 0 {
                        let v = wi * 64 + w.trailing_zeros() as usize;
                        w &= w - 1;
                        let x = f64::from(buf[v]);
                        if !x.is_finite() {
                            s.non_finite += 1;
                            count += 1;
                            continue;
                        }
                        count += 1;
                        if x < mn {
                            mn = x;
                        }
                        if x > mx {
                            mx = x;
                        }
                        sum += x;
                        sabs += x.abs();
                        mom[0] += x * (v >> 6) as f64;
                        mom[1] += x * ((v >> 3) & 7) as f64;
                        mom[2] += x * (v & 7) as f64;
                    }
                }
                s.min[0] = mn;
                s.max[0] = mx;
                s.sum[0] += sum;
                s.sum_len += sabs;
                let of = [f64::from(o.x), f64::from(o.y), f64::from(o.z)];
                for a in 0..3 {
                    s.moment[a] += mom[a] + of[a] * sum;
                }
                s.active_voxels_by_level[3] += count;
                continue;
            }
            for (wi, &word) in m.iter().enumerate() {
                let mut w = word;
                while w != 0 {
                    let v = wi * 64 + w.trailing_zeros() as usize;
                    w &= w - 1;
                    let mut val = [0f32; 3];
                    val[..comps].copy_from_slice(&buf[v * comps..v * comps + comps]);
                    let v = v as i32;
                    let p = o + IVec3::new(v >> 6, (v >> 3) & 7, v & 7);
                    s.active_voxels_by_level[3] += 1;
                    add(
                        val,
                        1.0,
                        [f64::from(p.x), f64::from(p.y), f64::from(p.z)],
                        &mut s,
                    );
                }
            }
        }
        for t in grid.tiles() {
            if !t.active {
                continue;
            }
            let n = t.level.voxels();
            let level = match t.level {
                crate::grid::TileLevel::Root => 0,
                crate::grid::TileLevel::Block => 1,
                crate::grid::TileLevel::Brick => 2,
            };
            s.active_voxels_by_level[level] += n;
            let half = (t.level.dim() - 1) as f64 / 2.0;
            let centre = [
                f64::from(t.origin.x) + half,
                f64::from(t.origin.y) + half,
                f64::from(t.origin.z) + half,
            ];
            let v = grid.tile_value_vec3(c, t.tile).to_array();
            add(v, n as f64, centre, &mut s);
        }
        s.active_voxels = s.active_voxels_by_level.iter().sum();
        s
    }
}
