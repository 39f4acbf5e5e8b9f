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
}

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
