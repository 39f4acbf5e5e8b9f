//! The hierarchical DDA over a [`MajorantPyramid`]: an iterator over the cells a ray crosses,
//! skipping empty cells at the coarsest level that is empty, emitting homogeneous cells whole,
//! and descending elsewhere (towards a finest level, and in the adaptive walk only where the
//! descent pays in optical depth: where the ray's segment price is below the cell's opening
//! price, [`super::plan`]).
//!
//! The walk is iterative with one DDA state per level on a fixed stack inside the iterator (no
//! heap allocation per ray); a child's state comes from its parent's exit distances and the
//! parent cell's mid-planes, so the ray is never re-located per level.

use glam::{DVec3, IVec3};

use super::{Bounds, Level, LookupModel, MajorantPyramid};

/// Levels the iterative walk keeps a DDA state for. A cubic grid within
/// [`super::MAX_LEVEL0_CELLS`] has at most 9 levels; only grids more than 2^11 bricks (16,384
/// voxels) long on one axis have more, and their deepest levels are then emitted whole
/// (coarser, still conservative). Kept small: the walk is moved by value.
pub(super) const MAX_LEVELS: usize = 12;

/// One cell the walk emits: a ray interval (index-space ray parameter, which equals the world
/// distance) with the cell's level, bounds and lookup density (see
/// [`MajorantPyramid::lookup_density`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct WalkCell {
    pub t0: f64,
    pub t1: f64,
    pub level: u8,
    pub bounds: Bounds,
    pub lookup: f32,
}

/// How the walk decides to open a cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Descent {
    /// Open every cell that is neither empty nor of constant bounds (the exhaustive walk).
    Always,
    /// Open a cell where `price` is below its stored opening price in `slot` (the adaptive
    /// walk; `price` is the ray's segment price divided by the model's price factor, see
    /// [`LookupModel::price_slot`]).
    BelowPrice {
        /// The ray's segment price, in the units of the stored prices.
        price: f32,
        /// Index of the stored prices.
        slot: usize,
        /// The medium's extinction per unit density.
        sigma: f32,
        /// True when the root is opened only where it pays for preparing the walk
        /// ([`Descent::root_pays`]): free flights with point bounds
        /// ([`LookupModel::Probed`]).
        weigh_set_up: bool,
    },
}

impl Descent {
    /// The adaptive descent of a ray of index-space direction `d` per unit of world distance
    /// in a medium of extinction `sigma` per unit density under `model`; the exhaustive one
    /// without `sigma`.
    pub(super) fn new(
        pyramid: &MajorantPyramid,
        d: DVec3,
        sigma: Option<f64>,
        model: LookupModel,
    ) -> Self {
        match sigma {
            None => Descent::Always,
            Some(s) => {
                let (slot, factor) = model.price_slot();
                Descent::BelowPrice {
                    price: (pyramid.segment_price(d, s) / factor) as f32,
                    slot,
                    sigma: s as f32,
                    weigh_set_up: model == LookupModel::Probed,
                }
            }
        }
    }

    /// True when opening the root `rb` of `pyramid` over a ray interval `length` long saves
    /// more lookups than preparing the walk costs ([`super::WALK_COST`]). A probed free flight
    /// stops at its first real collision: it is expected to cover `(1 − e^{−τ})/(σ·mean)` of
    /// the interval (`τ = σ·mean·length`, the root's mean density as if homogeneous), and
    /// opening saves the root's lookup density less its best cost at the ray's price
    /// ([`super::plan::RootCost`]) per unit of that length. Other walks keep the plan's
    /// decision alone: shadow rays' ratio tracking walks the whole ray, and charging its walks
    /// too raised the dense cloud's image variance (its control is the segment's mean); free
    /// flights without point bounds pay a lookup per tentative collision, for which the plan's
    /// prices were measured (docs/BENCHMARKS.md, "The walk's set-up priced per free flight").
    #[inline]
    fn root_pays(self, pyramid: &MajorantPyramid, rb: &Bounds, length: f64) -> bool {
        let Descent::BelowPrice {
            price,
            slot,
            sigma,
            weigh_set_up: true,
        } = self
        else {
            return true;
        };
        let Some(cost) = pyramid.root_cost.get(slot) else {
            return true;
        };
        let sigma = f64::from(sigma);
        let rate = sigma * f64::from(rb.mean.max(0.0));
        let tau = rate * length;
        let thin = !(tau > 1e-6);
        // Bounds first (the saving at price 0, a covered length of at most 1/rate): most
        // flights in a dense medium are decided without the cost function or the exponential.
        let most = sigma * super::PROBE_COST;
        let upper = most * if thin { length } else { length.min(1.0 / rate) };
        if !(upper * f64::from(cost.max_saving()) > super::WALK_COST) {
            return false;
        }
        let covered = if thin {
            length
        } else {
            -(-tau).exp_m1() / rate
        };
        most * covered * f64::from(cost.saving(price)) > super::WALK_COST
    }

    /// True when every non-empty cell of `level` is opened (as [`Self::opens`] decides),
    /// from the level's summaries: the walk starts below such levels.
    #[inline]
    fn opens_all(self, level: &Level) -> bool {
        match self {
            Descent::Always => level.all_vary,
            Descent::BelowPrice { price, slot, .. } => {
                level.open_floor.get(slot).is_some_and(|&p| price < p)
            }
        }
    }

    /// True when cell `i` of `level` (bounds `b`, not empty) is opened.
    #[inline(always)]
    fn opens(self, level: &Level, i: usize, b: &Bounds) -> bool {
        match self {
            Descent::Always => b.min != b.max,
            Descent::BelowPrice { price, slot, .. } => level
                .open_below
                .get(i)
                .and_then(|p| p.get(slot))
                .is_some_and(|&p| price < p),
        }
    }
}

/// One level's DDA state (48 bytes: the walk is moved by value, so the stack is kept small).
/// The frame at stack depth `i` walks level `top − i` (each descent goes one level down), and
/// the cells of its level inside the parent cell are `[lo, min(lo + 2, dims))` with
/// `lo = cell & !1` (the parent's cell doubled), so neither is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Frame {
    /// Distance at which the ray leaves the current cell across each axis (arrays rather
    /// than glam vectors: the walk indexes them by a run-time axis, which a glam vector's
    /// `Index` turns into a branch per access).
    pub t_next: [f64; 3],
    /// Where the parent cell ends.
    pub t_end: f64,
    pub cell: [i32; 3],
    pub done: bool,
}

/// The ray's fixed DDA quantities in the pyramid's index space.
#[derive(Clone, Copy, Debug)]
pub(super) struct RaySetup {
    pub o: DVec3,
    pub step: IVec3,
    pub inv_d: DVec3,
    /// |Δt| across one level-0 cell per axis (∞ along axes the ray does not move on).
    pub delta0: DVec3,
    /// Index-space position of the pyramid box's corner (voxel extents start at −½).
    pub base: DVec3,
    /// Edge of a level-0 cell, voxels.
    pub cell0: f64,
}

impl RaySetup {
    pub(super) fn new(o: DVec3, d: DVec3, base: DVec3, cell0: f64) -> Self {
        let mut step = IVec3::ZERO;
        let mut inv_d = DVec3::ZERO;
        for k in 0..3 {
            if d[k] > 0.0 {
                step[k] = 1;
                inv_d[k] = 1.0 / d[k];
            } else if d[k] < 0.0 {
                step[k] = -1;
                inv_d[k] = 1.0 / d[k];
            }
        }
        let across = |k: usize| {
            if step[k] != 0 {
                (cell0 * inv_d[k]).abs()
            } else {
                f64::INFINITY
            }
        };
        RaySetup {
            o,
            step,
            inv_d,
            delta0: DVec3::new(across(0), across(1), across(2)),
            base,
            cell0,
        }
    }

    /// The DDA state of the child a ray enters at distance `t` when it descends into `cell`
    /// of `level` (whose exits are `exits`): per axis, the half of the cell the ray is in at
    /// `t` and the distance to its exit (the mid-plane, or the parent's own exit plane).
    /// Returns the child cell and its exit distances.
    pub(super) fn child_state(
        &self,
        level: usize,
        cell: IVec3,
        exits: DVec3,
        t: f64,
    ) -> (IVec3, DVec3) {
        let half = self.cell0 * pow2(level - 1);
        let mut c = cell * 2;
        let mut c_next = exits;
        for k in 0..3 {
            let mid = self.base[k] + (2 * cell[k] + 1) as f64 * half;
            if self.step[k] == 0 {
                if self.o[k] >= mid {
                    c[k] += 1;
                }
                continue;
            }
            let tm = (mid - self.o[k]) * self.inv_d[k];
            let upper = if self.step[k] > 0 { tm <= t } else { tm > t };
            if upper {
                c[k] += 1;
            }
            if tm > t {
                c_next[k] = tm;
            }
        }
        (c, c_next)
    }
}

/// 2^`n` as an `f64` (exact; a signed conversion, one instruction where the unsigned one
/// takes several).
#[inline(always)]
fn pow2(n: usize) -> f64 {
    (1i64 << n) as f64
}

/// The hierarchical DDA over `t ∈ [t0, t1]` (inside the pyramid's box) as an iterator of
/// [`WalkCell`]s in ray order.
pub(super) struct Walk<'a> {
    pyramid: &'a MajorantPyramid,
    ray: RaySetup,
    finest: usize,
    /// Which cells to open.
    descent: Descent,
    /// The lookup cost of emitted cells.
    model: LookupModel,
    stack: [Frame; MAX_LEVELS],
    depth: usize,
    /// The pyramid's coarsest level (that of `stack[0]`).
    top: usize,
    t: f64,
    t1: f64,
}

/// What the walk does at the pyramid's root for one ray.
pub(super) enum RootStep {
    /// The root is empty: no cells.
    Empty,
    /// The root is emitted whole (no DDA needed).
    Whole(WalkCell),
    /// The root is opened: the walk descends.
    Open,
}

/// Decides the root of `pyramid` over `[t0, t1]`, as [`Walk::new`] does, without preparing
/// the walk: callers emit a whole root directly. Inlined into its callers (out of line, its
/// `RootStep` result, a whole cell, was returned through memory on every free flight).
#[inline(always)]
pub(super) fn root_step(
    pyramid: &MajorantPyramid,
    t0: f64,
    t1: f64,
    finest: usize,
    descent: Descent,
    model: LookupModel,
) -> RootStep {
    let Some(top) = pyramid.levels.len().checked_sub(1) else {
        return RootStep::Empty;
    };
    let root = &pyramid.levels[top];
    let rb = root.cells[0];
    if rb.is_empty() {
        return RootStep::Empty;
    }
    if top <= finest || !descent.opens(root, 0, &rb) || !descent.root_pays(pyramid, &rb, t1 - t0) {
        return RootStep::Whole(WalkCell {
            t0,
            t1,
            level: top.min(u8::MAX as usize) as u8,
            bounds: rb,
            lookup: pyramid.lookup_density(&rb, model),
        });
    }
    RootStep::Open
}

/// The level a walk below an opened root of `pyramid` starts at: the first level below the
/// root that may not open every non-empty cell ([`Descent::opens_all`]; not above `finest`),
/// or the root itself where that is the root's children (nothing to skip: the walk keeps its
/// bits).
fn start_level(pyramid: &MajorantPyramid, finest: usize, descent: Descent) -> usize {
    let top = pyramid.levels.len().saturating_sub(1);
    let mut start = top.saturating_sub(1);
    while start > finest
        && pyramid
            .levels
            .get(start)
            .is_some_and(|l| descent.opens_all(l))
    {
        start -= 1;
    }
    if start + 1 < top {
        start
    } else {
        top
    }
}

impl<'a> Walk<'a> {
    /// Prepares the walk of the index-space ray `o + t d` over `[t0, t1]` below an opened root
    /// (the caller asked [`root_step`] first, and emits a whole or empty root itself), opening
    /// cells as `descent` decides.
    ///
    /// Where the levels below the root open every non-empty cell for this ray
    /// ([`Descent::opens_all`]), the walk starts at the first level that may not (a DDA over
    /// that whole level) instead of descending to it from the root at every walk: the same
    /// cells with the same bounds, their ends computed along another path (equal up to the
    /// last bits). Empty cells of the skipped levels hold only empty cells, which the walk
    /// crosses without emitting them.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(super) fn new(
        pyramid: &'a MajorantPyramid,
        t0: f64,
        t1: f64,
        o: DVec3,
        d: DVec3,
        finest: usize,
        descent: Descent,
        model: LookupModel,
    ) -> Self {
        let start = start_level(pyramid, finest, descent);
        Self::starting_at(pyramid, t0, t1, o, d, finest, descent, model, start)
    }

    /// [`Self::new`] with the walk's first DDA over level `start` (the root's level, or one
    /// whose coarser levels below the root all open every non-empty cell for this ray).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn starting_at(
        pyramid: &'a MajorantPyramid,
        t0: f64,
        t1: f64,
        o: DVec3,
        d: DVec3,
        finest: usize,
        descent: Descent,
        model: LookupModel,
        start: usize,
    ) -> Self {
        let base = pyramid.origin.as_dvec3() - DVec3::splat(0.5);
        let cell0 = f64::from(pyramid.finest_cell_voxels());
        let mut walk = Walk {
            pyramid,
            ray: RaySetup::new(o, d, base, cell0),
            finest,
            descent,
            model,
            stack: [Frame::default(); MAX_LEVELS],
            depth: 0,
            top: 0,
            t: t0,
            t1,
        };
        let Some(root) = pyramid.levels.get(start) else {
            return walk;
        };
        let top = start;
        let r = &walk.ray;
        let size = cell0 * pow2(top);
        let p = o + d * (t0 + (t1 - t0) * 1e-6);
        // The cast truncates towards zero where the floor would round down, which differs
        // only in (−∞, 0) (and not for the integer values there), where both clamp to 0:
        // the same cell without three calls to `floor`.
        let cell = ((p - r.base) / size)
            .as_ivec3()
            .clamp(IVec3::ZERO, root.dims - IVec3::ONE);
        let mut t_next = DVec3::splat(f64::INFINITY);
        for k in 0..3 {
            if r.step[k] > 0 {
                t_next[k] = (r.base[k] + (cell[k] + 1) as f64 * size - o[k]) * r.inv_d[k];
            } else if r.step[k] < 0 {
                t_next[k] = (r.base[k] + cell[k] as f64 * size - o[k]) * r.inv_d[k];
            }
        }
        walk.stack[0] = Frame {
            t_next: t_next.to_array(),
            t_end: t1,
            cell: cell.to_array(),
            done: false,
        };
        walk.depth = 1;
        walk.top = top;
        walk
    }
}

impl Iterator for Walk<'_> {
    type Item = WalkCell;

    fn next(&mut self) -> Option<WalkCell> {
        let step = self.ray.step.to_array();
        let delta0 = self.ray.delta0.to_array();
        while self.depth > 0 {
            let f = &mut self.stack[self.depth - 1];
            if f.done || self.t >= f.t_end {
                self.t = self.t.max(f.t_end.min(self.t1));
                self.depth -= 1;
                continue;
            }
            let level = self.top - (self.depth - 1);
            let cell_a = f.cell;
            let exits_a = f.t_next;
            let axis = if exits_a[0] <= exits_a[1] && exits_a[0] <= exits_a[2] {
                0
            } else if exits_a[1] <= exits_a[2] {
                1
            } else {
                2
            };
            let t = self.t;
            let t_exit = exits_a[axis].min(f.t_end).max(t);
            f.cell[axis] += step[axis];
            f.t_next[axis] += delta0[axis] * pow2(level);
            let lv = &self.pyramid.levels[level];
            let dim = lv.dims.to_array()[axis];
            // The first frame walks its whole level (one cell at the root), the others the
            // cells inside their parent cell.
            let (lo, hi) = if self.depth == 1 {
                (0, dim)
            } else {
                let lo = cell_a[axis] & !1;
                (lo, (lo + 2).min(dim))
            };
            if f.cell[axis] < lo || f.cell[axis] >= hi || t_exit >= f.t_end {
                f.done = true;
            }
            if !(t_exit > t) {
                continue;
            }
            let cell = IVec3::from_array(cell_a);
            let exits = DVec3::from_array(exits_a);
            let i = lv.index(cell);
            let b = lv.cells[i];
            if b.is_empty() {
                self.t = t_exit;
                continue;
            }
            if level > self.finest && self.descent.opens(lv, i, &b) {
                let child = &self.pyramid.levels[level - 1];
                let (c, c_next) = self.ray.child_state(level, cell, exits, t);
                let lo = cell * 2;
                let hi = (lo + IVec3::splat(2)).min(child.dims);
                if c.cmpge(lo).all() && c.cmplt(hi).all() && self.depth < MAX_LEVELS {
                    self.stack[self.depth] = Frame {
                        t_next: c_next.to_array(),
                        t_end: t_exit,
                        cell: c.to_array(),
                        done: false,
                    };
                    self.depth += 1;
                    continue;
                }
            }
            let out = WalkCell {
                t0: t,
                t1: t_exit,
                level: level.min(u8::MAX as usize) as u8,
                bounds: b,
                lookup: self.pyramid.lookup_density(&b, self.model),
            };
            self.t = t_exit;
            // Leave finished levels at once (saves a loop turn per level).
            while self.depth > 0 && self.stack[self.depth - 1].done {
                self.t = self.t.max(self.stack[self.depth - 1].t_end.min(self.t1));
                self.depth -= 1;
            }
            return Some(out);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pyramid over 16³ bricks (the unit cube) with bounds `field(brick centre)`.
    fn pyramid(field: impl Fn(DVec3) -> f32) -> MajorantPyramid {
        let scale = glam::DAffine3::from_scale(DVec3::splat(128.0));
        MajorantPyramid::from_brick_bounds(IVec3::ZERO, IVec3::splat(15), 0.0, scale, |k| {
            let v = field((k.as_dvec3() + 0.5) / 16.0);
            Bounds {
                min: 0.0,
                max: v,
                mean: 0.5 * v,
            }
        })
        .unwrap_or_else(|e| unreachable!("{e}"))
    }

    /// The descent of a ray along x through the middle of `p` under `model`, and whether it
    /// opens the root.
    fn opens_root(p: &MajorantPyramid, sigma: f64, model: LookupModel) -> (Descent, bool) {
        let descent = Descent::new(p, DVec3::new(128.0, 0.0, 0.0), Some(sigma), model);
        let open = matches!(root_step(p, 0.0, 1.0, 0, descent, model), RootStep::Open);
        (descent, open)
    }

    #[test]
    fn a_free_flight_opens_the_root_only_where_the_walk_pays() {
        // A dense blob in sparse space: flights cross the empty part at no cost once the root
        // is opened.
        let blob = pyramid(|c| {
            if (c - 0.5).length() < 0.15 {
                10.0
            } else {
                0.01
            }
        });
        // A dense field whose maxima vary little: a flight ends after a short way, and the
        // few probes a finer walk would save there do not pay for preparing it.
        let dense = pyramid(|c| 0.1 + 0.9 * (c.x * 7.0).sin().abs() as f32);
        let root = |p: &MajorantPyramid| p.levels.last().map(|l| l.cells[0]);
        for sigma in [40.0, 400.0, 4000.0] {
            let (_, open) = opens_root(&blob, sigma, LookupModel::Probed);
            assert!(open, "blob at {sigma}");
            let (descent, open) = opens_root(&dense, sigma, LookupModel::Probed);
            assert!(!open, "dense at {sigma}");
            // At high extinction the plan alone would open it.
            let top = dense.levels.len() - 1;
            let rb = root(&dense).unwrap_or(Bounds::constant(0.0));
            if sigma > 1000.0 {
                assert!(descent.opens(&dense.levels[top], 0, &rb), "plan at {sigma}");
            }
            assert!(!descent.root_pays(&dense, &rb, 1.0));
            // Other walks keep the plan's decision.
            for model in [LookupModel::Ratio, LookupModel::Majorant] {
                let (other, _) = opens_root(&dense, sigma, model);
                assert!(matches!(
                    other,
                    Descent::BelowPrice {
                        weigh_set_up: false,
                        ..
                    }
                ));
                assert!(other.root_pays(&dense, &rb, 1.0));
            }
        }
    }

    /// Bounds over a box of `hi + 1` bricks (not cubic) from four blobs, some homogeneous
    /// (min = max), some sparse (small blobs), some nearly filling the box.
    fn blob_pyramid(seed: u64, background: f32) -> MajorantPyramid {
        let mut rng = crate::sampling::Rng::new(seed, 3);
        let hi = IVec3::new(
            4 + (rng.next_u32() % 40) as i32,
            1 + (rng.next_u32() % 24) as i32,
            2 + (rng.next_u32() % 30) as i32,
        );
        let big = seed % 2 == 1;
        let blobs: Vec<(DVec3, f64, f32)> = (0..4)
            .map(|_| {
                let c = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64())
                    * (hi + IVec3::ONE).as_dvec3();
                let r = if big { 20.0 } else { 1.0 } + 3.0 * rng.next_f64();
                (c, r, 0.1 + 5.0 * rng.next_f32())
            })
            .collect();
        let scale = glam::DAffine3::from_scale(DVec3::splat(1.0 / 64.0));
        MajorantPyramid::from_brick_bounds(IVec3::ZERO, hi, background, scale, |k| {
            let p = k.as_dvec3() + 0.5;
            let mut b = Bounds::constant(0.0);
            for (i, &(c, r, v)) in blobs.iter().enumerate() {
                if (p - c).length() < r {
                    let lo = if i % 3 == 0 && !big { v } else { 0.0 };
                    b = Bounds {
                        min: if b.max > 0.0 { b.min.min(lo) } else { lo },
                        max: b.max.max(v),
                        mean: 0.5 * (lo + v),
                    };
                }
            }
            b
        })
        .unwrap_or_else(|e| unreachable!("{e}"))
    }

    /// The cells of a walk with a length above `eps` (a walk may emit or skip a cell that
    /// the ray only grazes, depending on the last bits of its ends).
    fn long_cells(walk: Walk<'_>, eps: f64) -> Vec<WalkCell> {
        walk.filter(|c| c.t1 - c.t0 > eps).collect()
    }

    #[test]
    fn a_walk_started_below_opened_levels_emits_the_descents_cells() {
        let mut rng = crate::sampling::Rng::new(11, 5);
        let (mut cells, mut skipped, mut walks, mut fallbacks) = (0usize, 0usize, 0usize, 0usize);
        for seed in 0..32 {
            let p = blob_pyramid(seed, if seed % 5 == 4 { 0.05 } else { 0.0 });
            let top = p.levels.len() - 1;
            let size = (p.levels[0].dims * 8).as_dvec3();
            let base = DVec3::splat(-0.5);
            for r in 0..600 {
                // Origins around the box, some directions along an axis or a diagonal plane.
                let o = base
                    + DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * size * 1.4
                    - size * 0.2;
                let mut d = DVec3::new(
                    rng.next_f64() - 0.5,
                    rng.next_f64() - 0.5,
                    rng.next_f64() - 0.5,
                );
                if r % 7 == 0 {
                    d[(r / 7) % 3] = 0.0;
                }
                if r % 11 == 0 {
                    d = DVec3::ZERO;
                    d[r % 3] = if r % 2 == 0 { 1.0 } else { -1.0 };
                }
                let d = d.normalize_or(DVec3::X) * 64.0;
                // Clip to the box (slabs), sometimes a part of the chord only.
                let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
                for k in 0..3 {
                    let (a, b) = ((base[k] - o[k]) / d[k], (base[k] + size[k] - o[k]) / d[k]);
                    if d[k] == 0.0 {
                        if o[k] < base[k] || o[k] >= base[k] + size[k] {
                            t1 = -1.0;
                        }
                        continue;
                    }
                    t0 = t0.max(a.min(b));
                    t1 = t1.min(a.max(b));
                }
                if !(t1 > t0) {
                    continue;
                }
                if r % 5 == 1 {
                    let (u, v) = (rng.next_f64(), rng.next_f64());
                    (t0, t1) = (t0 + (t1 - t0) * u.min(v), t0 + (t1 - t0) * u.max(v));
                }
                let sigma = [None, Some(0.3), Some(40.0), Some(3000.0), Some(1e6)][r % 5];
                let model = [
                    LookupModel::Majorant,
                    LookupModel::AboveMinorant,
                    LookupModel::Probed,
                    LookupModel::Ratio,
                ][(r / 5) % 4];
                let finest = r % 3;
                let descent = Descent::new(&p, d, sigma, model);
                if !matches!(
                    root_step(&p, t0, t1, finest, descent, model),
                    RootStep::Open
                ) {
                    continue;
                }
                walks += 1;
                let start = start_level(&p, finest, descent);
                if start < top {
                    skipped += 1;
                }
                let eps = 1e-9 * t1.abs().max(1.0);
                let new = long_cells(Walk::new(&p, t0, t1, o, d, finest, descent, model), eps);
                let old = long_cells(
                    Walk::starting_at(&p, t0, t1, o, d, finest, descent, model, top),
                    eps,
                );
                let above: Vec<&WalkCell> = old
                    .iter()
                    .filter(|c| start < top && usize::from(c.level) > start)
                    .collect();
                if !above.is_empty() {
                    // The descent's fallback where a child's state falls outside the level (a
                    // ray entering the box on a mid-plane of a coarser cell, by the last bits):
                    // it emits the coarser cell whole, which the started walk does not reach.
                    // Such a cell must be one its descent opens (else skipping was wrong).
                    for c in above {
                        let level = usize::from(c.level);
                        let lv = &p.levels[level];
                        let size = 8.0 * pow2(level);
                        let at = o + d * (0.5 * (c.t0 + c.t1));
                        let cell = ((at - base) / size)
                            .floor()
                            .as_ivec3()
                            .clamp(IVec3::ZERO, lv.dims - IVec3::ONE);
                        let i = lv.index(cell);
                        assert_eq!(lv.cells[i], c.bounds, "pyramid {seed}, ray {r}");
                        assert!(
                            level == top || descent.opens(lv, i, &c.bounds),
                            "pyramid {seed}, ray {r}: level {level} skipped but not opened"
                        );
                    }
                    fallbacks += 1;
                    continue;
                }
                assert_eq!(
                    new.len(),
                    old.len(),
                    "pyramid {seed}, ray {r}, start {start}, finest {finest}: {new:?} against {old:?}"
                );
                for (a, b) in new.iter().zip(&old) {
                    assert_eq!(
                        (a.level, a.bounds, a.lookup),
                        (b.level, b.bounds, b.lookup),
                        "pyramid {seed}, ray {r}"
                    );
                    assert!(
                        (a.t0 - b.t0).abs() <= eps && (a.t1 - b.t1).abs() <= eps,
                        "pyramid {seed}, ray {r}: {a:?} against {b:?}"
                    );
                }
                if start == top {
                    // Nothing skipped: the same bits.
                    let all = |w: Walk<'_>| w.collect::<Vec<_>>();
                    assert_eq!(
                        all(Walk::new(&p, t0, t1, o, d, finest, descent, model)),
                        all(Walk::starting_at(
                            &p, t0, t1, o, d, finest, descent, model, top
                        ))
                    );
                }
                cells += new.len();
            }
        }
        assert!(
            cells > 20_000,
            "{cells} cells, {skipped} of {walks} skip, {fallbacks} fallbacks"
        );
        assert!(
            skipped * 5 > walks,
            "{skipped} of {walks} walks skip levels"
        );
        assert!(
            fallbacks * 100 < skipped,
            "{fallbacks} fallbacks in {skipped} walks"
        );
    }

    fn setup(o: [f64; 3], d: [f64; 3]) -> RaySetup {
        RaySetup::new(DVec3::from(o), DVec3::from(d), DVec3::splat(-0.5), 8.0)
    }

    #[test]
    fn child_state_enters_the_half_the_ray_is_in() {
        // A level-1 cell spans 16 voxels: [−0.5, 15.5) per axis, mid-planes at 7.5.
        let r = setup([-0.5, 3.0, 12.0], [1.0, 0.0, 0.0]);
        let exits = DVec3::new(16.0, f64::INFINITY, f64::INFINITY);
        let (c, next) = r.child_state(1, IVec3::ZERO, exits, 0.0);
        // x: enters the lower half, leaves it at the mid-plane t = 8; y (3 < 7.5) lower half;
        // z (12 > 7.5) upper half; axes the ray does not move on keep the parent's exits.
        assert_eq!(c, IVec3::new(0, 0, 1));
        assert_eq!(next, DVec3::new(8.0, f64::INFINITY, f64::INFINITY));
    }

    #[test]
    fn child_state_past_the_mid_plane_takes_the_upper_half() {
        let r = setup([-0.5, -0.5, -0.5], [1.0, 0.5, -1.0]);
        let exits = DVec3::new(16.0, 32.0, 0.0);
        // At t = 10 the ray is at x = 9.5 (upper half in x, the mid-plane is behind it: the
        // parent's exit stays), y = 4.5 (lower half, exits at its mid-plane t = 16), and z has
        // a negative direction: the mid-plane 7.5 lies at t = −8, behind the ray.
        let (c, next) = r.child_state(1, IVec3::ZERO, exits, 10.0);
        assert_eq!(c, IVec3::new(1, 0, 0));
        assert_eq!(next, DVec3::new(16.0, 16.0, 0.0));
    }

    #[test]
    fn child_state_on_the_mid_plane_is_the_half_ahead() {
        // Exactly on the mid-plane (t = 8 for x), the ray is in the half it moves into: the
        // upper one moving +x, the lower one moving −x (whose exit is the parent's).
        let up = setup([-0.5, 0.0, 0.0], [1.0, 0.0, 0.0]);
        let (c, _) = up.child_state(1, IVec3::ZERO, DVec3::splat(f64::INFINITY), 8.0);
        assert_eq!(c.x, 1);
        let down = setup([15.5, 0.0, 0.0], [-1.0, 0.0, 0.0]);
        let (c, next) = down.child_state(1, IVec3::ZERO, DVec3::splat(f64::INFINITY), 8.0);
        assert_eq!(c.x, 0);
        assert_eq!(next.x, f64::INFINITY);
    }
}
