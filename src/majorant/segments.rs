//! Majorant segments: the pieces of a ray over which the density is bounded, as the tracking
//! estimators consume them. [`MajorantPyramid::segments_along`] turns a ray into a stream of
//! segments without heap allocation: the background before and after the pyramid's box, and
//! in between the hierarchical walk ([`super::walk`]) with the merge adapter [`Merged`].

use glam::DVec3;

use super::walk::{root_step, Descent, RootStep, Walk, WalkCell};
use super::{Bounds, LookupModel, MajorantMode, MajorantPyramid, SEGMENT_COST};
use crate::math::Ray;

/// A piece of ray `[t0, t1]` (world distances) over which the density is bounded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MajorantSegment {
    /// Start distance.
    pub t0: f32,
    /// End distance.
    pub t1: f32,
    /// Upper bound of the density on the segment (the majorant, density units).
    pub max: f32,
    /// Lower bound of the density on the segment (the minorant).
    pub min: f32,
    /// Mean density of the region the segment crosses (a control-variate candidate);
    /// any value in `[min, max]` is valid.
    pub mean: f32,
    /// True when the bounds are proven (every density on the segment lies in `[min, max]`):
    /// bounds computed from baked voxels or constant tiles, analytic bounds, and the constant
    /// density of a homogeneous region. False for estimated or artist-given bounds, which a
    /// density may violate.
    pub exact: bool,
}

impl MajorantSegment {
    /// A segment over `[t0, t1]` with `bounds`, proven (`exact`) or not.
    #[must_use]
    pub fn new(t0: f32, t1: f32, bounds: Bounds, exact: bool) -> Self {
        MajorantSegment {
            t0,
            t1,
            max: bounds.max,
            min: bounds.min,
            mean: bounds.mean,
            exact,
        }
    }

    /// A segment of constant, known density `value` (exact).
    #[must_use]
    pub fn constant(t0: f32, t1: f32, value: f32) -> Self {
        Self::new(t0, t1, Bounds::constant(value), true)
    }

    /// Length of the segment.
    #[must_use]
    pub fn length(&self) -> f32 {
        (self.t1 - self.t0).max(0.0)
    }

    /// True when the density is known to be constant on the segment: proven bounds with
    /// `min == max`. Only such segments may be sampled in closed form, without lookups;
    /// estimated bounds that happen to coincide must still be looked up (weighted tracking
    /// is unbiased only if every segment whose bound may be violated is looked up).
    #[must_use]
    pub fn is_homogeneous(&self) -> bool {
        self.exact && self.min == self.max
    }
}

/// Merges adjacent walk cells into segments: always where their bounds are equal, and in the
/// adaptive walk (`sigma` given) where one segment over both costs fewer than
/// [`SEGMENT_COST`] extra lookups than two.
pub(super) struct Merged<I> {
    inner: I,
    sigma: Option<f64>,
    exact: bool,
    model: LookupModel,
    /// The segment being grown, with the lookup density it stands for.
    pending: Option<(MajorantSegment, f32)>,
}

impl<I: Iterator<Item = WalkCell>> Merged<I> {
    pub(super) fn new(inner: I, sigma: Option<f64>, exact: bool, model: LookupModel) -> Self {
        Merged {
            inner,
            sigma,
            exact,
            model,
            pending: None,
        }
    }

    /// Tries to extend `last` (with lookup density `last_lookup`) by `seg`.
    fn try_merge(
        sigma: Option<f64>,
        exact: bool,
        model: LookupModel,
        last: &mut (MajorantSegment, f32),
        seg: &MajorantSegment,
        lookup: f32,
    ) -> bool {
        let (prev, last_lookup) = last;
        if prev.t1 == seg.t0 && prev.min == seg.min && prev.max == seg.max && prev.mean == seg.mean
        {
            prev.t1 = seg.t1;
            return true;
        }
        let Some(s) = sigma else {
            return false;
        };
        // Lookups added by one segment over both (and the empty gap between):
        // σ·(L·(its lookup density) − the lookup integrals of the two as they are).
        let max = prev.max.max(seg.max);
        let mut min = prev.min.min(seg.min);
        if seg.t0 > prev.t1 {
            min = min.min(0.0);
        }
        let merged = MajorantPyramid::lookup_density_of(min, max, false, model);
        let (la, gap, lb) = (
            f64::from(prev.length()),
            f64::from((seg.t0 - prev.t1).max(0.0)),
            f64::from(seg.length()),
        );
        let extra = s
            * ((la + gap + lb) * f64::from(merged)
                - la * f64::from(*last_lookup)
                - lb * f64::from(lookup));
        if !(extra < SEGMENT_COST) {
            return false;
        }
        let total = la + gap + lb;
        let mean = if total > 0.0 {
            ((la * f64::from(prev.mean) + lb * f64::from(seg.mean)) / total) as f32
        } else {
            prev.mean
        };
        *prev = MajorantSegment {
            t0: prev.t0,
            t1: seg.t1,
            min,
            max,
            mean: mean.clamp(min, max),
            exact,
        };
        *last_lookup = MajorantPyramid::lookup_density_of(min, max, exact, model);
        true
    }
}

impl<I: Iterator<Item = WalkCell>> Iterator for Merged<I> {
    type Item = MajorantSegment;

    fn next(&mut self) -> Option<MajorantSegment> {
        for cell in self.inner.by_ref() {
            let seg = MajorantSegment::new(cell.t0 as f32, cell.t1 as f32, cell.bounds, self.exact);
            match self.pending.as_mut() {
                None => self.pending = Some((seg, cell.lookup)),
                Some(last) => {
                    let mut grown = *last;
                    if Self::try_merge(
                        self.sigma,
                        self.exact,
                        self.model,
                        &mut grown,
                        &seg,
                        cell.lookup,
                    ) {
                        self.pending = Some(grown);
                    } else {
                        let done = last.0;
                        self.pending = Some((seg, cell.lookup));
                        return Some(done);
                    }
                }
            }
        }
        self.pending.take().map(|(s, _)| s)
    }
}

/// At most three segments known without the walk (the background before and after the
/// pyramid's box and the root emitted whole, or the global bounds), in ray order: a small
/// iterator, cheap to build and to move.
#[derive(Clone, Copy, Debug)]
pub struct FewSegments {
    segs: [MajorantSegment; 3],
    next: u8,
    len: u8,
}

impl FewSegments {
    const NONE: MajorantSegment = MajorantSegment {
        t0: 0.0,
        t1: 0.0,
        max: 0.0,
        min: 0.0,
        mean: 0.0,
        exact: true,
    };

    fn empty() -> Self {
        FewSegments {
            segs: [Self::NONE; 3],
            next: 0,
            len: 0,
        }
    }

    #[inline]
    fn push(&mut self, s: Option<MajorantSegment>) {
        if let Some(s) = s {
            if let Some(slot) = self.segs.get_mut(usize::from(self.len)) {
                *slot = s;
                self.len += 1;
            }
        }
    }
}

impl Iterator for FewSegments {
    type Item = MajorantSegment;

    #[inline]
    fn next(&mut self) -> Option<MajorantSegment> {
        if self.next < self.len {
            let s = self.segs.get(usize::from(self.next)).copied();
            self.next += 1;
            s
        } else {
            None
        }
    }
}

/// A walk below an opened root, not yet prepared: what [`OpenWalk::segments`] needs to build
/// the walk's iterator (whose DDA stack is large) where it is consumed.
#[derive(Clone, Copy, Debug)]
pub struct OpenWalk<'a> {
    pyramid: &'a MajorantPyramid,
    before: Option<MajorantSegment>,
    after: Option<MajorantSegment>,
    o: DVec3,
    d: DVec3,
    t0: f64,
    t1: f64,
    finest: usize,
    descent: Descent,
    sigma: Option<f64>,
    model: LookupModel,
}

impl<'a> OpenWalk<'a> {
    /// The segments: the background before the box, the walk's merged cells, the background
    /// after it.
    #[inline]
    #[must_use]
    pub fn segments(self) -> Segments<'a> {
        let mut before = FewSegments::empty();
        before.push(self.before);
        let walk = Walk::new(
            self.pyramid,
            self.t0,
            self.t1,
            self.o,
            self.d,
            self.finest,
            self.descent,
            self.model,
        );
        Segments {
            before,
            walk: Some(Merged::new(
                walk,
                self.sigma,
                self.pyramid.exact,
                self.model,
            )),
            after: self.after,
        }
    }
}

/// How a ray's segments start ([`MajorantPyramid::segments_start`]).
#[derive(Clone, Copy, Debug)]
pub enum SegmentsStart<'a> {
    /// All of them, known without the walk.
    Few(FewSegments),
    /// The root is opened: the walk is needed.
    Open(OpenWalk<'a>),
}

/// The segments of one ray interval, in ray order: see [`MajorantPyramid::segments_along`].
pub struct Segments<'a> {
    /// The segments before the walk's (all of them when the walk is not needed).
    before: FewSegments,
    walk: Option<Merged<Walk<'a>>>,
    after: Option<MajorantSegment>,
}

impl Iterator for Segments<'_> {
    type Item = MajorantSegment;

    fn next(&mut self) -> Option<MajorantSegment> {
        if let Some(s) = self.before.next() {
            return Some(s);
        }
        if let Some(walk) = self.walk.as_mut() {
            if let Some(s) = walk.next() {
                return Some(s);
            }
            self.walk = None;
        }
        self.after.take()
    }
}

impl From<FewSegments> for Segments<'_> {
    fn from(before: FewSegments) -> Self {
        Segments {
            before,
            walk: None,
            after: None,
        }
    }
}

impl MajorantPyramid {
    /// The segments covering `[t_min, t_max]` of `ray` (world space), lazily and without heap
    /// allocation.
    ///
    /// `sigma_scale` is the medium's largest extinction per unit density (the largest channel
    /// of σ_t⁰). Given (finite and positive), [`MajorantMode::Hierarchical`] walks adaptively:
    /// a tentative collision (a density lookup) and a segment cost about the same, so a cell is
    /// opened only where the lookups its descendants save at this extinction exceed
    /// [`SEGMENT_COST`] per extra segment along this ray's direction (decided at every level
    /// from prices stored per cell, [`super::plan`]), and adjacent segments are merged where
    /// the merge costs fewer than [`SEGMENT_COST`] extra lookups. Optically thin cells
    /// (σ·max·Δt ≪ 1) are therefore emitted whole. Merged and undivided
    /// segments take the max of the maxima and the min of the minima they cover (0 across
    /// skipped empty cells), so the bounds stay conservative. `None` gives the exhaustive walk:
    /// it descends to its finest level wherever a cell is neither empty nor homogeneous,
    /// whatever the medium's extinction (what `velour majorants` reports per level).
    ///
    /// `model` is what a segment costs the medium's tracker (the adaptive walk minimises it).
    ///
    /// Segments of zero density are skipped; the others tile their part of the interval.
    #[must_use]
    #[inline]
    pub fn segments_along(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        mode: MajorantMode,
        sigma_scale: Option<f32>,
        model: LookupModel,
    ) -> Segments<'_> {
        match self.segments_start(ray, t_min, t_max, mode, sigma_scale, model) {
            SegmentsStart::Few(few) => few.into(),
            SegmentsStart::Open(walk) => walk.segments(),
        }
    }

    /// The segments of [`Self::segments_along`], split by whether the walk is needed: where
    /// it is not (the root emitted whole or empty, the global bounds, a ray that misses the
    /// box) they are all known at once and come as a small iterator; otherwise the walk is
    /// described, to be prepared by [`OpenWalk::segments`] where it is consumed.
    #[must_use]
    #[inline]
    pub fn segments_start(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        mode: MajorantMode,
        sigma_scale: Option<f32>,
        model: LookupModel,
    ) -> SegmentsStart<'_> {
        let mut few = FewSegments::empty();
        if !(t_max > t_min) {
            return SegmentsStart::Few(few);
        }
        match mode {
            MajorantMode::Global => {
                let b = self.global_bounds();
                if !b.is_empty() {
                    if t_max.is_finite() || self.background != 0.0 {
                        few.push(Some(MajorantSegment::new(t_min, t_max, b, self.exact)));
                    } else if let Some((a, c)) = self.clip(ray, t_min, t_max) {
                        few.push(Some(MajorantSegment::new(a, c, b, self.exact)));
                    }
                }
                SegmentsStart::Few(few)
            }
            MajorantMode::Hierarchical { finest } => {
                let (o, d) = self.ray_to_index(ray);
                let Some((a, c)) = self.clip_index(o, d, t_min, t_max) else {
                    few.push(self.background_segment(t_min, t_max));
                    return SegmentsStart::Few(few);
                };
                let before = self.background_segment(t_min, a);
                let after = self.background_segment(c, t_max);
                let top = self.levels.len() - 1;
                let finest = (finest as usize).min(top);
                let sigma = sigma_scale
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .map(f64::from);
                let descent = Descent::new(self, d, sigma, model);
                let (t0, t1) = (f64::from(a), f64::from(c));
                match root_step(self, t0, t1, finest, descent, model) {
                    RootStep::Empty => {}
                    // What the merge adapter makes of a walk that emits only its root.
                    RootStep::Whole(cell) => {
                        few.push(before);
                        few.push(Some(MajorantSegment::new(
                            cell.t0 as f32,
                            cell.t1 as f32,
                            cell.bounds,
                            self.exact,
                        )));
                        few.push(after);
                        return SegmentsStart::Few(few);
                    }
                    RootStep::Open => {
                        return SegmentsStart::Open(OpenWalk {
                            pyramid: self,
                            before,
                            after,
                            o,
                            d,
                            t0,
                            t1,
                            finest,
                            descent,
                            sigma,
                            model,
                        });
                    }
                }
                few.push(before);
                few.push(after);
                SegmentsStart::Few(few)
            }
        }
    }

    /// Appends to `out` the segments of the exhaustive walk over `[t_min, t_max]` of `ray`
    /// ([`Self::segments_along`] without `sigma_scale`).
    pub fn segments(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        mode: MajorantMode,
        out: &mut Vec<MajorantSegment>,
    ) {
        out.extend(self.segments_along(ray, t_min, t_max, mode, None, LookupModel::Majorant));
    }

    /// Appends to `out` the segments of the adaptive walk for a medium whose extinction is at
    /// most `sigma_scale` per unit density ([`Self::segments_along`]).
    pub fn segments_adaptive(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        mode: MajorantMode,
        sigma_scale: f32,
        out: &mut Vec<MajorantSegment>,
    ) {
        out.extend(self.segments_along(
            ray,
            t_min,
            t_max,
            mode,
            Some(sigma_scale),
            LookupModel::Majorant,
        ));
    }

    /// Adds to `length[ℓ]` the length of `[t_min, t_max]` along `ray` that the adaptive walk
    /// (extinction `sigma_scale` per unit density, lookup model `model`) covers with whole
    /// cells of level ℓ, before adjacent segments are merged: which levels the walk picks (for
    /// `velour majorants`). Empty cells are not counted, nor levels beyond `length`.
    pub fn adaptive_level_lengths(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        sigma_scale: f32,
        model: LookupModel,
        length: &mut [f64],
    ) {
        let (o, d) = self.ray_to_index(ray);
        let Some((a, c)) = self.clip_index(o, d, t_min, t_max) else {
            return;
        };
        let sigma = Some(f64::from(sigma_scale)).filter(|s| s.is_finite() && *s > 0.0);
        let descent = Descent::new(self, d, sigma, model);
        let (t0, t1) = (f64::from(a), f64::from(c));
        let mut add = |cell: WalkCell| {
            if let Some(l) = length.get_mut(usize::from(cell.level)) {
                *l += cell.t1 - cell.t0;
            }
        };
        match root_step(self, t0, t1, 0, descent, model) {
            RootStep::Empty => {}
            RootStep::Whole(cell) => add(cell),
            RootStep::Open => Walk::new(self, t0, t1, o, d, 0, descent, model).for_each(add),
        }
    }

    fn background_segment(&self, t0: f32, t1: f32) -> Option<MajorantSegment> {
        (self.background != 0.0 && t1 > t0)
            .then(|| MajorantSegment::constant(t0, t1, self.background))
    }

    /// Clips the ray to the pyramid's box in index space (voxel extents: voxel i covers
    /// [i − 0.5, i + 0.5)).
    fn clip(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let (o, d) = self.ray_to_index(ray);
        self.clip_index(o, d, t_min, t_max)
    }

    /// [`Self::clip`] for a ray already in index space. Inlined into its callers: called out
    /// of line, its vector arguments and its result went through memory on every free flight.
    #[inline(always)]
    fn clip_index(&self, o: DVec3, d: DVec3, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let l0 = self.levels.first()?;
        let lo = self.origin.as_dvec3() - DVec3::splat(0.5);
        let hi = lo + (l0.dims * self.finest_cell_voxels()).as_dvec3();
        clip_box(o, d, lo, hi, t_min, t_max)
    }
}

/// `[t_min, t_max]` of the ray `o + t d` clipped to the box `[lo, hi)` (index space).
#[inline(always)]
fn clip_box(
    o: DVec3,
    d: DVec3,
    lo: DVec3,
    hi: DVec3,
    t_min: f32,
    t_max: f32,
) -> Option<(f32, f32)> {
    let mut t0 = t_min as f64;
    let mut t1 = t_max as f64;
    // The three slabs written out by axis (indexing a `DVec3` by a loop variable compiles to
    // a branch per access); the same operations in the same order as a loop over the axes.
    if !(clip_slab(o.x, d.x, lo.x, hi.x, &mut t0, &mut t1)
        && clip_slab(o.y, d.y, lo.y, hi.y, &mut t0, &mut t1)
        && clip_slab(o.z, d.z, lo.z, hi.z, &mut t0, &mut t1))
    {
        return None;
    }
    (t0 < t1).then_some((t0 as f32, t1 as f32))
}

/// One slab of [`clip_box`]: narrows `[t0, t1]` to where the ray
/// `o + t d` lies within `[lo, hi)` on one axis. False when the ray runs parallel to the slab
/// outside it.
#[inline(always)]
fn clip_slab(o: f64, d: f64, lo: f64, hi: f64, t0: &mut f64, t1: &mut f64) -> bool {
    if d == 0.0 {
        return !(o < lo || o >= hi);
    }
    let inv = 1.0 / d;
    let (mut a, mut b) = ((lo - o) * inv, (hi - o) * inv);
    if a > b {
        std::mem::swap(&mut a, &mut b);
    }
    *t0 = t0.max(a);
    *t1 = t1.min(b);
    true
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The clip as a loop over the axes (the form before the axes were written out).
    fn by_loop(
        o: DVec3,
        d: DVec3,
        lo: DVec3,
        hi: DVec3,
        t_min: f32,
        t_max: f32,
    ) -> Option<(f32, f32)> {
        let mut t0 = t_min as f64;
        let mut t1 = t_max as f64;
        for k in 0..3 {
            if d[k] == 0.0 {
                if o[k] < lo[k] || o[k] >= hi[k] {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / d[k];
            let (mut a, mut b) = ((lo[k] - o[k]) * inv, (hi[k] - o[k]) * inv);
            if a > b {
                std::mem::swap(&mut a, &mut b);
            }
            t0 = t0.max(a);
            t1 = t1.min(b);
        }
        (t0 < t1).then_some((t0 as f32, t1 as f32))
    }

    #[test]
    fn written_out_clip_matches_the_loop_bit_for_bit() {
        let mut rng = Rng::new(17, 0);
        let lo = DVec3::new(-0.5, 3.5, -8.5);
        let hi = DVec3::new(127.5, 67.5, 23.5);
        let mut hits = 0;
        for i in 0..200_000 {
            let mut u = || f64::from(rng.next_f32());
            // Origins inside, outside and on faces; directions with zero components.
            let mut o = DVec3::new(
                -40.0 + 210.0 * u(),
                -40.0 + 150.0 * u(),
                -40.0 + 100.0 * u(),
            );
            match i % 5 {
                1 => o.x = lo.x,
                2 => o.y = hi.y,
                _ => {}
            }
            let mut d = DVec3::new(u() - 0.5, u() - 0.5, u() - 0.5);
            match i % 7 {
                1 => d.x = 0.0,
                2 => (d.y, d.z) = (0.0, 0.0),
                3 => d = DVec3::ZERO,
                _ => {}
            }
            let t_min = if i % 3 == 0 { 0.0 } else { (20.0 * u()) as f32 };
            let t_max = if i % 4 == 0 {
                f32::INFINITY
            } else {
                t_min + (400.0 * u()) as f32
            };
            let a = clip_box(o, d, lo, hi, t_min, t_max);
            let b = by_loop(o, d, lo, hi, t_min, t_max);
            let bits = |c: Option<(f32, f32)>| c.map(|(x, y)| (x.to_bits(), y.to_bits()));
            assert_eq!(
                bits(a),
                bits(b),
                "ray {i}: o {o:?} d {d:?} [{t_min}, {t_max}]"
            );
            hits += usize::from(a.is_some());
        }
        assert!(hits > 20_000, "{hits} of the rays hit the box");
    }
}
