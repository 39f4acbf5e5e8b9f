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

/// The segments of one ray interval, in ray order: see [`MajorantPyramid::segments_along`].
pub struct Segments<'a> {
    before: Option<MajorantSegment>,
    /// The pyramid's root emitted whole: the walk is not prepared at all.
    whole: Option<MajorantSegment>,
    walk: Option<Merged<Walk<'a>>>,
    after: Option<MajorantSegment>,
}

impl Iterator for Segments<'_> {
    type Item = MajorantSegment;

    fn next(&mut self) -> Option<MajorantSegment> {
        if let Some(s) = self.before.take() {
            return Some(s);
        }
        if let Some(s) = self.whole.take() {
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
        let mut out = Segments {
            before: None,
            whole: None,
            walk: None,
            after: None,
        };
        if !(t_max > t_min) {
            return out;
        }
        match mode {
            MajorantMode::Global => {
                let b = self.global_bounds();
                if !b.is_empty() {
                    if t_max.is_finite() || self.background != 0.0 {
                        out.before = Some(MajorantSegment::new(t_min, t_max, b, self.exact));
                    } else if let Some((a, c)) = self.clip(ray, t_min, t_max) {
                        out.before = Some(MajorantSegment::new(a, c, b, self.exact));
                    }
                }
            }
            MajorantMode::Hierarchical { finest } => {
                let (o, d) = self.ray_to_index(ray);
                let Some((a, c)) = self.clip_index(o, d, t_min, t_max) else {
                    out.before = self.background_segment(t_min, t_max);
                    return out;
                };
                out.before = self.background_segment(t_min, a);
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
                        out.whole = Some(MajorantSegment::new(
                            cell.t0 as f32,
                            cell.t1 as f32,
                            cell.bounds,
                            self.exact,
                        ));
                    }
                    RootStep::Open => {
                        let walk = Walk::new(self, t0, t1, o, d, finest, descent, model);
                        out.walk = Some(Merged::new(walk, sigma, self.exact, model));
                    }
                }
                out.after = self.background_segment(c, t_max);
            }
        }
        out
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

    /// [`Self::clip`] for a ray already in index space.
    #[inline]
    fn clip_index(&self, o: DVec3, d: DVec3, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let l0 = self.levels.first()?;
        let lo = self.origin.as_dvec3() - DVec3::splat(0.5);
        let hi = lo + (l0.dims * self.finest_cell_voxels()).as_dvec3();
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
}
