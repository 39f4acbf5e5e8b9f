//! A coarse grid of the cells that no triangle touches, so that a short ray segment lying in
//! such cells is known to hit no triangle without traversing the BVH.
//!
//! Inside a dense homogeneous medium most rays are traced only up to their sampled free-flight
//! distance (docs/architecture.md, "Ray casting"), and nearly all of them end before the
//! boundary: 99 % of the short rays of the skin icosphere miss. Each still paid a traversal from
//! the root. Here the triangles' bounding boxes, padded, mark the cells they overlap; a segment
//! whose (padded) bounding box lies in at most [`MAX_CELLS_TESTED`] unmarked cells cannot reach
//! a triangle, so the BVH would report no hit either. The answer is the same as the traversal's
//! (the paddings exceed the rounding of the segment's end point and of the triangle test), so
//! images are bit-identical.

use glam::Vec3A;

use crate::math::Vec3;

/// Segments whose bounding box overlaps more cells than this are traversed.
const MAX_CELLS_TESTED: i64 = 8;

/// Cells per axis at most (the grid costs one bit per cell).
const MAX_CELLS_PER_AXIS: f32 = 128.0;

/// The cells no triangle touches, over the triangles' bounds.
#[derive(Clone, Debug)]
pub(super) struct EmptyCells {
    /// The grid's lower corner.
    lo: Vec3,
    /// Cells per unit length.
    inv_cell: f32,
    dims: [i64; 3],
    /// Margin added around every tested segment's bounding box (world units).
    margin: f32,
    /// One bit per cell, x fastest: set where a padded triangle box overlaps the cell.
    occupied: Vec<u64>,
    /// The triangles of each occupied cell ([`EmptyCells::fill_lists`]), for rays that start
    /// inside the grid.
    lists: Option<CellLists>,
}

/// Per occupied cell, the BVH positions of the triangles whose padded box (with the grid's
/// margin) overlaps it, in increasing order. Occupied cells are numbered by their rank among
/// the set bits of [`EmptyCells::occupied`].
#[derive(Clone, Debug)]
struct CellLists {
    /// Set bits in the words before each word of `occupied`.
    rank: Vec<u32>,
    /// Start of each occupied cell's list in `slots` (one more entry than occupied cells).
    starts: Vec<u32>,
    slots: Vec<u32>,
    /// Per cell (x fastest): 0 for an occupied cell, else the Chebyshev distance in cells to
    /// the nearest occupied one (at most 255), so that the cells within one less of it hold
    /// no triangle and a ray crosses them in one step.
    clearance: Vec<u8>,
}

/// Cells a ray from inside the grid walks through before it falls back to the hierarchy.
const MAX_CELLS_WALKED: usize = 256;

impl EmptyCells {
    /// The grid over `boxes` (the triangles' padded bounding boxes), with about two cells per
    /// triangle along each axis of a closed surface (`2·∛n` cells along the longest axis).
    /// `pad` is the padding the boxes already carry; the cells are marked with 4× more and
    /// segments are widened by it. `None` without triangles or for a degenerate extent.
    pub(super) fn build(boxes: &[(Vec3, Vec3)], pad: f32) -> Option<EmptyCells> {
        let (first, rest) = boxes.split_first()?;
        let (mut lo, mut hi) = *first;
        for (a, b) in rest {
            lo = lo.min(*a);
            hi = hi.max(*b);
        }
        let margin = 4.0 * pad.max(f32::MIN_POSITIVE);
        lo -= Vec3::splat(2.0 * margin);
        hi += Vec3::splat(2.0 * margin);
        let extent = hi - lo;
        let longest = extent.max_element();
        if !(longest.is_finite() && longest > 0.0) {
            return None;
        }
        let per_axis = (2.0 * (boxes.len() as f32).cbrt())
            .round()
            .clamp(4.0, MAX_CELLS_PER_AXIS);
        let cell = longest / per_axis;
        let inv_cell = 1.0 / cell;
        let dims = [0, 1, 2].map(|k| ((extent[k] * inv_cell).ceil() as i64).clamp(1, 128));
        let n = (dims[0] * dims[1] * dims[2]) as usize;
        let mut grid = EmptyCells {
            lo,
            inv_cell,
            dims,
            margin,
            occupied: vec![0; n.div_ceil(64)],
            lists: None,
        };
        for (a, b) in boxes {
            let Some((c0, c1)) =
                grid.cell_range(*a - Vec3::splat(margin), *b + Vec3::splat(margin))
            else {
                continue;
            };
            for z in c0[2]..=c1[2] {
                for y in c0[1]..=c1[1] {
                    for x in c0[0]..=c1[0] {
                        let i = grid.index(x, y, z);
                        if let Some(w) = grid.occupied.get_mut(i / 64) {
                            *w |= 1 << (i % 64);
                        }
                    }
                }
            }
        }
        Some(grid)
    }

    /// Fills the per-cell triangle lists: `boxes` are the triangles' padded boxes in BVH
    /// position order (the boxes `build` marked the cells with, in another order).
    pub(super) fn fill_lists(&mut self, boxes: &[(Vec3, Vec3)]) {
        let mut rank = Vec::with_capacity(self.occupied.len());
        let mut total = 0u32;
        for w in &self.occupied {
            rank.push(total);
            total += w.count_ones();
        }
        let mut counts = vec![0u32; total as usize + 1];
        let ranges: Vec<_> = boxes
            .iter()
            .map(|(a, b)| {
                self.cell_range(*a - Vec3::splat(self.margin), *b + Vec3::splat(self.margin))
            })
            .collect();
        let cell_rank = |i: usize| -> Option<usize> {
            let w = *self.occupied.get(i / 64)?;
            let bit = 1u64 << (i % 64);
            (w & bit != 0).then(|| (rank[i / 64] + (w & (bit - 1)).count_ones()) as usize)
        };
        for pass in 0..2 {
            if pass == 1 {
                // Counts to starts (exclusive prefix sums), then fill.
                let mut sum = 0;
                for c in counts.iter_mut() {
                    let n = *c;
                    *c = sum;
                    sum += n;
                }
            }
            let mut fill = counts.clone();
            let mut slots = vec![
                0u32;
                if pass == 1 {
                    *counts.last().unwrap_or(&0) as usize
                } else {
                    0
                }
            ];
            for (slot, r) in ranges.iter().enumerate() {
                let Some((c0, c1)) = *r else { continue };
                for z in c0[2]..=c1[2] {
                    for y in c0[1]..=c1[1] {
                        for x in c0[0]..=c1[0] {
                            let Some(k) = cell_rank(self.index(x, y, z)) else {
                                continue;
                            };
                            if pass == 0 {
                                counts[k] += 1;
                            } else if let Some(s) = slots.get_mut(fill[k] as usize) {
                                *s = slot as u32;
                                fill[k] += 1;
                            }
                        }
                    }
                }
            }
            if pass == 1 {
                self.lists = Some(CellLists {
                    clearance: self.clearance(),
                    rank: rank.clone(),
                    starts: counts.clone(),
                    slots,
                });
            }
        }
    }

    /// The Chebyshev distance transform of the occupied cells (two chamfer passes over the
    /// 26 neighbours with unit weights, exact for the maximum norm), capped at 255.
    fn clearance(&self) -> Vec<u8> {
        let [dx, dy, dz] = self.dims;
        let n = (dx * dy * dz) as usize;
        let mut dist = vec![255u8; n];
        for z in 0..dz {
            for y in 0..dy {
                for x in 0..dx {
                    let i = self.index(x, y, z);
                    if self
                        .occupied
                        .get(i / 64)
                        .is_some_and(|w| w & (1 << (i % 64)) != 0)
                    {
                        dist[i] = 0;
                    }
                }
            }
        }
        for forward in [true, false] {
            let order = |a: i64, n: i64| if forward { a } else { n - 1 - a };
            let s = if forward { -1 } else { 1 };
            for zz in 0..dz {
                let z = order(zz, dz);
                for yy in 0..dy {
                    let y = order(yy, dy);
                    for xx in 0..dx {
                        let x = order(xx, dx);
                        let i = self.index(x, y, z);
                        let mut best = dist[i];
                        // The neighbours already visited in this pass.
                        for (ox, oy, oz) in [
                            (s, 0, 0),
                            (-1, s, 0),
                            (0, s, 0),
                            (1, s, 0),
                            (-1, -1, s),
                            (0, -1, s),
                            (1, -1, s),
                            (-1, 0, s),
                            (0, 0, s),
                            (1, 0, s),
                            (-1, 1, s),
                            (0, 1, s),
                            (1, 1, s),
                        ] {
                            let (nx, ny, nz) = (x + ox, y + oy, z + oz);
                            if nx < 0 || ny < 0 || nz < 0 || nx >= dx || ny >= dy || nz >= dz {
                                continue;
                            }
                            best = best.min(dist[self.index(nx, ny, nz)].saturating_add(1));
                        }
                        dist[i] = best;
                    }
                }
            }
        }
        dist
    }

    /// Walks the cells along `ray` from its origin's cell, calling `test(position, t_max)` for
    /// the triangles of each occupied cell (a triangle in several cells is tested in each; the
    /// test's strict `t < t_max` keeps the first hit at a distance). `test` returns the new
    /// `t_max`, ≤ 0 to stop (an any-hit query that found something). Returns `Ok` when the
    /// answer is final: `t_max` lies before the exit of the cell just walked (every point of
    /// the ray before it lies in a walked cell, and every triangle through such a point is in
    /// that cell's list), or the ray left the grid, outside which there are no triangles.
    /// Returns `Err(t_max)` when the origin is outside the grid, or after
    /// [`MAX_CELLS_WALKED`] cells: the hierarchy finishes the query from `t_max`.
    ///
    /// The cell boundaries and exit distances carry rounding errors of a few ulps of the
    /// coordinates; the triangles are listed with the grid's margin (about 64 ε of the scene's
    /// magnitude), so a point within that distance of a walked cell is covered.
    #[inline]
    pub(super) fn march(
        &self,
        o: Vec3,
        d: Vec3,
        mut t_max: f32,
        mut test: impl FnMut(u32, f32) -> f32,
    ) -> Result<(), f32> {
        let Some(lists) = &self.lists else {
            return Err(t_max);
        };
        let [dx, dy, dz] = self.dims;
        let dims = [dx as i32, dy as i32, dz as i32];
        let f = (o - self.lo) * self.inv_cell;
        let fa = f.to_array();
        if !(0..3).all(|k| fa[k] >= 0.0 && fa[k] < dims[k] as f32) {
            return Err(t_max);
        }
        let cell = 1.0 / self.inv_cell;
        let lo = self.lo.to_array();
        let oa = o.to_array();
        let da = d.to_array();
        let mut c = [0i32; 3];
        for k in 0..3 {
            c[k] = (fa[k] as i32).min(dims[k] - 1);
        }
        let up = [da[0] > 0.0, da[1] > 0.0, da[2] > 0.0];
        let moving = [da[0] != 0.0, da[1] != 0.0, da[2] != 0.0];
        for _ in 0..MAX_CELLS_WALKED {
            let i = self.index(c[0] as i64, c[1] as i64, c[2] as i64);
            let w = self.occupied.get(i / 64).copied().unwrap_or(0);
            let bit = 1u64 << (i % 64);
            // The cube of cells `c ± r` holds no triangle.
            let r = if w & bit != 0 {
                let rank =
                    lists.rank.get(i / 64).copied().unwrap_or(0) + (w & (bit - 1)).count_ones();
                let (s, e) = (
                    lists.starts.get(rank as usize).copied().unwrap_or(0),
                    lists.starts.get(rank as usize + 1).copied().unwrap_or(0),
                );
                for &slot in lists.slots.get(s as usize..e as usize).unwrap_or(&[]) {
                    t_max = test(slot, t_max);
                    if t_max <= 0.0 {
                        return Ok(());
                    }
                }
                0
            } else {
                i32::from(lists.clearance.get(i).copied().unwrap_or(1)) - 1
            };
            // Where the ray leaves the cube, through which face.
            let mut face = [0i32; 3];
            let mut t = [f32::INFINITY; 3];
            for k in 0..3 {
                face[k] = if up[k] { c[k] + r + 1 } else { c[k] - r };
                if moving[k] {
                    t[k] = (lo[k] + face[k] as f32 * cell - oa[k]) / da[k];
                }
            }
            let k = if t[0] < t[1] {
                if t[0] < t[2] {
                    0
                } else {
                    2
                }
            } else if t[1] < t[2] {
                1
            } else {
                2
            };
            let t_exit = t[k];
            if t_max <= t_exit - self.margin {
                return Ok(());
            }
            if r > 0 {
                // The other axes' cells at the exit point.
                for j in 0..3 {
                    if j != k {
                        let f = (oa[j] + t_exit * da[j] - lo[j]) * self.inv_cell;
                        if !(f >= 0.0 && f < dims[j] as f32) {
                            return Ok(());
                        }
                        c[j] = f as i32;
                    }
                }
            }
            c[k] = if up[k] { face[k] } else { face[k] - 1 };
            if c[k] < 0 || c[k] >= dims[k] {
                return Ok(());
            }
        }
        Err(t_max)
    }

    /// The range of cells the box `[a, b]` overlaps, clamped to the grid.
    fn cell_range(&self, a: Vec3, b: Vec3) -> Option<([i64; 3], [i64; 3])> {
        let fa = (a - self.lo) * self.inv_cell;
        let fb = (b - self.lo) * self.inv_cell;
        if !(fa.is_finite() && fb.is_finite()) {
            return None;
        }
        let c0 = [0, 1, 2].map(|k| (fa[k].floor() as i64).clamp(0, self.dims[k] - 1));
        let c1 = [0, 1, 2].map(|k| (fb[k].floor() as i64).clamp(0, self.dims[k] - 1));
        Some((c0, c1))
    }

    #[inline]
    fn index(&self, x: i64, y: i64, z: i64) -> usize {
        ((z * self.dims[1] + y) * self.dims[0] + x) as usize
    }

    /// True when the segment from `a` to `b` lies in cells no triangle touches: no triangle
    /// can be hit along it. False when unsure (long segments, segments leaving the grid).
    #[inline]
    pub(super) fn clear(&self, a: Vec3, b: Vec3) -> bool {
        // In SIMD lanes: the same per-coordinate IEEE operations (`a` and `b` are finite or
        // infinite, never NaN, so `min`/`max` agree with the scalar ones where it matters).
        let (a, b) = (Vec3A::from(a), Vec3A::from(b));
        let m = Vec3A::splat(self.margin);
        let lo = Vec3A::from(self.lo);
        let fa = (a.min(b) - m - lo) * self.inv_cell;
        let fb = (a.max(b) + m - lo) * self.inv_cell;
        let [dx, dy, dz] = self.dims;
        // Inside the grid (this also rejects NaN). The dimensions (at most 128) are exact in f32.
        let dims = Vec3A::new(dx as f32, dy as f32, dz as f32);
        if !(fa.cmpge(Vec3A::ZERO) & fb.cmplt(dims)).all() {
            return false;
        }
        // Written out per axis (indexing by a variable and array `map`s cost about 290
        // instructions per call; the same comparisons and conversions).
        let ([ax, ay, az], [bx, by, bz]) = (fa.to_array(), fb.to_array());
        let (x0, y0, z0) = (ax as i64, ay as i64, az as i64);
        let x1 = (bx as i64).min(dx - 1);
        let y1 = (by as i64).min(dy - 1);
        let z1 = (bz as i64).min(dz - 1);
        let count = (x1 - x0 + 1) * (y1 - y0 + 1) * (z1 - z0 + 1);
        if count > MAX_CELLS_TESTED {
            return false;
        }
        for z in z0..=z1 {
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let i = self.index(x, y, z);
                    match self.occupied.get(i / 64) {
                        Some(w) if w & (1 << (i % 64)) == 0 => {}
                        _ => return false,
                    }
                }
            }
        }
        true
    }
}
