//! Heterogeneous interiors: σ_t(x) = base_t + d(x)·σ_t⁰ and σ_s(x) = base_s + d(x)·σ_s⁰ with the
//! density d(x) from a [`DensityField`] (the notes' "voxelised", "heterogeneous scattering"
//! and combined interiors). The medium turns a ray into majorant segments and density lookups
//! and hands both to the tracking estimators.

use glam::Vec3;

use super::event::{MediumEvent, ScatterVertex, VertexPhase};
use super::lookup::{
    index_ray, DensityLookup, GridLookup, GridProbe, LocalProbe, SharedShellProbe, ShellProbe,
};
use crate::fabric::{FabricLook, FabricShell, FibreGridLookup, FibreVoxel, ShellLookup};
use crate::grid::SparseGrid;
use crate::majorant::{LookupModel, MajorantPyramid, MajorantSegment, Segments, SegmentsStart};
use crate::math::{Aabb, Ray};
use crate::phase::PhaseFunction;
use crate::procedural::{FbmField, LazyFbmGrid};
use crate::spectrum::Rgb;
use crate::tracking::{
    decomposition_track, decomposition_track_local, delta_track, delta_track_local,
    ray_march_free_flight, split_flight, transmittance, DensityCoefficients, Flight,
    FreeFlightMethod, TrackingConfig, TrackingStats, TransmittanceMode,
};

/// Where a heterogeneous interior's density comes from.
// The grid, the common case, stays inline (its lookups start without a pointer to follow); the
// larger rare fields are boxed.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum DensityField {
    /// A grid channel (an OpenVDB grid, a baked procedural, a voxelised weave).
    Grid {
        /// The grid (its index-to-world map places it in the scene).
        grid: SparseGrid,
        /// The density channel.
        channel: usize,
    },
    /// Procedural fBm evaluated directly (exact, slow).
    Procedural(Box<FbmField>),
    /// Procedural fBm baked lazily into bricks where lookups go.
    LazyBaked(Box<LazyFbmGrid>),
    /// A voxelised weave patch tiled over a mesh shell (notes §3.3).
    Shell(Box<FabricShell>),
}

/// A heterogeneous interior: a density field, its majorant bounds, optical coefficients per
/// unit density, a phase function and the estimator choices.
#[derive(Clone, Debug)]
pub struct HeterogeneousMedium {
    /// The density.
    pub field: DensityField,
    /// Majorant bounds of the density.
    pub pyramid: MajorantPyramid,
    /// Coefficients per unit density.
    pub coefficients: DensityCoefficients,
    /// Phase function.
    pub phase: PhaseFunction,
    /// Estimator choices.
    pub tracking: TrackingConfig,
    /// Fibre shading of a voxelised fabric (tangent and yarn-id channels of the grid), if any.
    pub fabric: Option<Box<FabricLook>>,
    /// Coarser mip levels of a fabric whose level is chosen per ray from the ray's footprint
    /// (`mip = "auto"`), or, for a fixed coarser level, only the finest level's box (no
    /// levels); `None` for other interiors.
    pub mips: Option<Box<MipChain>>,
}

/// The coarser levels of a fabric interior whose mip level is chosen per ray (course notes
/// §5.3, with the footprint of a ray cone, docs/textures.md): a ray whose footprint where it
/// reaches the fabric (the box of the base level's non-empty cells) spans `w` voxels of the
/// base level (the medium holding the chain) is tracked, and shadowed, in level
/// `floor(log2 w)` (the base below 2 voxels), capped at the coarsest level built.
#[derive(Clone, Debug)]
pub struct MipChain {
    /// World width of one voxel of the base level (world units; the cube root of a placed
    /// voxel's volume, or the geometric mean of a shell voxel's widths along the cloth).
    pub voxel_width: f32,
    /// World box of the finest level's non-empty majorant cells (the fibres' extent): where
    /// the footprint is measured (a ray that starts outside is measured where it enters the
    /// box), and the box of a `shape = "bounds"` object, whatever its level (a coarser
    /// level's trilinear fringe beyond the fibres is not rendered).
    pub bounds: Aabb,
    /// Levels 1, 2, … above the base, each a complete medium with its own grid or shell,
    /// majorant pyramid and fibre look.
    pub levels: Vec<HeterogeneousMedium>,
}

impl MipChain {
    /// The level (0 = the base) for a footprint `width` (world units): `floor(log2(width /
    /// voxel_width))`, 0 below two voxels (and for NaN), at most the coarsest level held.
    #[inline]
    #[must_use]
    pub fn level_for(&self, width: f32) -> usize {
        let r = width / self.voxel_width;
        if !(r >= 2.0) {
            return 0;
        }
        // floor(log2 r) from the exponent bits (r ≥ 2 is normal or infinite).
        let l = ((r.to_bits() >> 23) & 0xff) as usize - 127;
        l.min(self.levels.len())
    }

    /// The level for a ray whose cone is `cone` at its origin: [`Self::level_for`] of the
    /// cone's width where the ray enters [`Self::bounds`] (at its origin when it starts
    /// inside, or misses the box).
    #[inline]
    #[must_use]
    pub fn level_for_ray(&self, ray: &Ray, cone: RayFootprint) -> usize {
        let t = self
            .bounds
            .intersect(ray, 0.0, f32::INFINITY)
            .map_or(0.0, |(t0, _)| t0.max(0.0));
        self.level_for(cone.width_at(t))
    }
}

/// A ray's cone (Akenine-Möller et al. 2019/2021, docs/references.md §14.2), as the
/// integrator tracks it for texture and fabric mip footprints.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayFootprint {
    /// Width at the ray's origin, world units.
    pub width: f32,
    /// Spread angle, radians: the width grows by `spread · t`.
    pub spread: f32,
}

impl RayFootprint {
    /// No footprint: every per-ray choice takes the finest level.
    pub const POINT: RayFootprint = RayFootprint {
        width: 0.0,
        spread: 0.0,
    };

    /// The width at distance `t` along the ray (world units).
    #[inline]
    #[must_use]
    pub fn width_at(self, t: f32) -> f32 {
        self.width + self.spread * t
    }
}

impl HeterogeneousMedium {
    /// The medium of the mip level `ray`, whose cone is `cone` at its origin, is tracked in:
    /// `self` unless the interior chooses its level per ray ([`MipChain::level_for_ray`]).
    #[inline]
    #[must_use]
    pub fn for_ray(&self, ray: &Ray, cone: RayFootprint) -> &HeterogeneousMedium {
        match &self.mips {
            None => self,
            Some(chain) => self.level(chain.level_for_ray(ray, cone)),
        }
    }

    /// Level `l` of a fabric with a per-ray mip choice (0, or a level past the coarsest
    /// built, is `self`).
    #[must_use]
    pub fn level(&self, l: usize) -> &HeterogeneousMedium {
        match &self.mips {
            None => self,
            Some(chain) => match l {
                0 => self,
                l => chain.levels.get(l - 1).unwrap_or(self),
            },
        }
    }

    /// The world box of the density's non-empty majorant cells (`None` when it is empty);
    /// for a fabric with a [`MipChain`], the box of its finest level, whichever level the
    /// medium itself is.
    #[must_use]
    pub fn world_bounds(&self) -> Option<Aabb> {
        match &self.mips {
            Some(chain) if chain.bounds.is_valid() => Some(chain.bounds),
            _ => self.pyramid.world_bounds(),
        }
    }

    /// The fibre frame of a fabric interior at world point `p`: the world-space tangent and
    /// the yarn id of the nearest patch voxel (`None` for other interiors or outside the
    /// patch's shell).
    #[must_use]
    pub fn fibre_at(&self, p: Vec3) -> Option<FibreVoxel> {
        let look = self.fabric.as_ref()?;
        match &self.field {
            DensityField::Grid { grid, .. } => Some(look.fibre_in_grid(grid, p)),
            DensityField::Shell(shell) => shell.fibre_at(p),
            _ => None,
        }
    }

    /// The phase function at world point `p`: the fibre phase function of the yarn there for
    /// fabric, the interior's own phase function otherwise.
    #[must_use]
    pub fn phase_at(&self, p: Vec3) -> VertexPhase<'_> {
        if let Some(look) = self.fabric.as_deref() {
            if let Some(fibre) = self.fibre_at(p) {
                return VertexPhase::Fibre {
                    phase: look.phase_for_id(fibre.id),
                    tangent: fibre.tangent,
                    yarn: FabricLook::family_of_id(fibre.id),
                    dye: None,
                };
            }
        }
        VertexPhase::Hg(&self.phase)
    }

    /// The fabric look when its extinction is fibre-projected.
    fn projected_fibres(&self) -> Option<&FabricLook> {
        self.fabric.as_deref().filter(|l| l.projects())
    }

    /// Builds the pyramid's local bounds ([`crate::majorant::LocalBounds`]) when the tracking
    /// configuration uses them (`local_bounds` with delta or decomposition tracking) and the
    /// field is a grid (other fields track without them, and build no table).
    pub fn attach_local_bounds(&mut self) -> Result<(), crate::majorant::MajorantError> {
        let used = self.tracking.local_bounds
            && matches!(
                self.tracking.free_flight,
                FreeFlightMethod::DeltaTracking | FreeFlightMethod::Decomposition
            );
        if !used || self.pyramid.local_bounds().is_some() {
            return Ok(());
        }
        if let DensityField::Grid { grid, channel } = &self.field {
            let pyramid = std::mem::replace(
                &mut self.pyramid,
                MajorantPyramid::empty(0.0, grid.world_to_index()),
            );
            self.pyramid = pyramid.with_local_bounds(grid, *channel)?;
        }
        Ok(())
    }

    /// Point bounds along `ray` when the interior uses them (`tracking.local_bounds` with delta
    /// or decomposition tracking): a grid field whose pyramid carries local bounds, or a
    /// fabric shell (its per-voxel maxima).
    fn local_probe(&self, ray: &Ray) -> Option<LocalProbe<'_>> {
        if !self.uses_local_bounds() {
            return None;
        }
        match &self.field {
            DensityField::Grid { grid, .. } => Some(LocalProbe::new(
                self.pyramid.local_bounds()?,
                grid,
                ray,
                self.projected_fibres().is_some(),
            )),
            DensityField::Shell(shell) => Some(LocalProbe::Shell(ShellProbe::new(shell, ray))),
            _ => None,
        }
    }

    /// True when [`Self::local_probe`] gives point bounds.
    fn uses_local_bounds(&self) -> bool {
        self.tracking.local_bounds
            && matches!(
                self.tracking.free_flight,
                FreeFlightMethod::DeltaTracking | FreeFlightMethod::Decomposition
            )
            && match self.field {
                DensityField::Grid { .. } => self.pyramid.local_bounds().is_some(),
                DensityField::Shell(_) => true,
                _ => false,
            }
    }

    /// The majorant segments of `[t0, t1]` along `ray` for free flights, lazily: the pyramid's
    /// adaptive walk at this medium's extinction, with the fibre-projected and combined-interior
    /// adjustments.
    #[must_use]
    pub fn segments_along(&self, ray: &Ray, t0: f32, t1: f32) -> MediumSegments<'_> {
        self.segments_with(&self.coefficients, ray, t0, t1, self.flight_model())
    }

    /// The walk's lookup model of free flights.
    fn flight_model(&self) -> LookupModel {
        // With point bounds a tentative collision costs a probe, and the lookups left depend on
        // the local bounds only.
        if self.uses_local_bounds() {
            LookupModel::Probed
        } else {
            self.unprobed_flight_model()
        }
    }

    /// [`Self::segments_along`] in two parts, for callers that hold the pyramid's walk in
    /// place and lend it ([`Self::flight_segments_of`]): moving the walk's iterator copies its
    /// DDA stack. The pyramid's segments of `[t0, t1]` along `ray` for free flights.
    #[inline]
    pub(super) fn flight_walk(&self, ray: &Ray, t0: f32, t1: f32) -> Segments<'_> {
        self.pyramid_segments(&self.coefficients, ray, t0, t1, self.flight_model())
    }

    /// The second part of [`Self::segments_along`]: the free flights' segments from `walk`
    /// (made by [`Self::flight_walk`] over the same `[t0, t1]`), borrowed.
    #[inline]
    pub(super) fn flight_segments_of<'w, 'a>(
        &self,
        walk: &'w mut Segments<'a>,
        t0: f32,
        t1: f32,
    ) -> MediumSegmentsOf<&'w mut Segments<'a>> {
        self.medium_segments(&self.coefficients, walk, t0, t1)
    }

    /// The walk's lookup model of shadow rays.
    /// Shadow rays keep the segments of the walk without point bounds: ratio tracking's
    /// variance grows as its majorant tightens (docs/references.md §4.10).
    fn shadow_model(&self) -> LookupModel {
        match (self.tracking.free_flight, self.tracking.transmittance) {
            (FreeFlightMethod::Decomposition, _) => LookupModel::AboveMinorant,
            // Ratio tracking's segments cost more than a free flight's (docs/BENCHMARKS.md,
            // "Padded bricks and dearer shadow-ray segments").
            (_, TransmittanceMode::Ratio | TransmittanceMode::ResidualRatio(_)) => {
                LookupModel::Ratio
            }
            _ => LookupModel::Majorant,
        }
    }

    /// The walk's lookup model of free flights without point bounds (and of projected
    /// fields' trackers, [`Self::segments_for`]).
    fn unprobed_flight_model(&self) -> LookupModel {
        // Decomposition tracking pays lookups only above each segment's minorant: the walk
        // then prefers cells with tight minorants too.
        match self.tracking.free_flight {
            FreeFlightMethod::Decomposition => LookupModel::AboveMinorant,
            _ => LookupModel::Majorant,
        }
    }

    /// The majorant segments of `[t0, t1]` along `ray` walked at coefficients `c`'s extinction
    /// under the lookup model of free flights without point bounds: for trackers of this field with coefficients of
    /// their own (surface-projected textures, [`super::ProjectedMedium`]).
    pub(super) fn segments_for(
        &self,
        c: &DensityCoefficients,
        ray: &Ray,
        t0: f32,
        t1: f32,
    ) -> MediumSegments<'_> {
        self.segments_with(c, ray, t0, t1, self.unprobed_flight_model())
    }

    /// [`Self::segments_along`] under lookup model `model`, for coefficients `c`.
    fn segments_with(
        &self,
        c: &DensityCoefficients,
        ray: &Ray,
        t0: f32,
        t1: f32,
        model: LookupModel,
    ) -> MediumSegments<'_> {
        let inner = self.pyramid_segments(c, ray, t0, t1, model);
        self.medium_segments(c, inner, t0, t1)
    }

    /// The pyramid's majorant segments of `[t0, t1]` along `ray` for coefficients `c`, before
    /// the adjustments of [`Self::medium_segments`].
    #[inline]
    fn pyramid_segments(
        &self,
        c: &DensityCoefficients,
        ray: &Ray,
        t0: f32,
        t1: f32,
        model: LookupModel,
    ) -> Segments<'_> {
        self.pyramid.segments_along(
            ray,
            t0,
            t1,
            self.tracking.majorant,
            Some(c.max_sigma_t()),
            model,
        )
    }

    /// The pyramid's segments `inner` of `[t0, t1]` with the fibre-projected and
    /// combined-interior adjustments for coefficients `c`.
    #[inline]
    fn medium_segments<I>(
        &self,
        c: &DensityCoefficients,
        inner: I,
        t0: f32,
        t1: f32,
    ) -> MediumSegmentsOf<I> {
        let fill = (!c.base_t.is_black() && t1.is_finite()).then_some(GapFill {
            t: t0,
            end: t1,
            held: None,
        });
        MediumSegmentsOf {
            inner,
            zero_min: self.projected_fibres().is_some(),
            fill,
        }
    }

    /// The density lookup along `ray` and, when the interior uses them, its point bounds
    /// ([`Self::density_along`] and [`Self::local_probe`], the grid's index-space ray
    /// computed once for both). Inlined into the flight, so that the lookup (with its
    /// accessor's cache) is built in place rather than returned and copied.
    #[inline(always)]
    fn lookups_along(&self, ray: &Ray) -> (DensityLookup<'_>, Option<LocalProbe<'_>>) {
        if let (DensityField::Grid { grid, channel }, true, None) = (
            &self.field,
            self.uses_local_bounds(),
            self.projected_fibres(),
        ) {
            if let Some(table) = self.pyramid.local_bounds() {
                let (o, d) = index_ray(grid, ray);
                return (
                    DensityLookup::Grid(GridLookup::from_index_ray(grid, *channel, o, d)),
                    Some(LocalProbe::from_index_ray(table, o, d, false)),
                );
            }
        }
        (self.density_along(ray), self.local_probe(ray))
    }

    /// A density lookup along `ray`, by distance.
    #[must_use]
    pub fn density_along<'a>(&'a self, ray: &Ray) -> DensityLookup<'a> {
        match &self.field {
            DensityField::Grid { grid, channel } => match self.projected_fibres() {
                Some(look) => {
                    DensityLookup::FibreGrid(FibreGridLookup::new(grid, *channel, look, ray))
                }
                None => DensityLookup::Grid(GridLookup::new(grid, *channel, ray)),
            },
            DensityField::Procedural(f) => DensityLookup::Procedural {
                field: f,
                ray: *ray,
            },
            DensityField::Shell(shell) => DensityLookup::Shell(ShellLookup::new(
                shell,
                ray,
                self.projected_fibres().is_some(),
            )),
            DensityField::LazyBaked(g) => {
                let w2i = g.world_to_index();
                let o = w2i.transform_point3(ray.o.as_dvec3()).as_vec3();
                let d = w2i.transform_vector3(ray.d.as_dvec3()).as_vec3();
                DensityLookup::Lazy { grid: g, o, d }
            }
        }
    }

    /// Samples a free flight along `ray` over `[0, t_max]` with the interior's free-flight
    /// estimator.
    pub(super) fn sample_flight<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'_> {
        self.sample_flight_with(&self.coefficients, ray, t_max, beta, u, stats)
    }

    /// [`Self::sample_flight`] with coefficients `c` in place of the medium's own (a walk's
    /// entry-projected coefficients, docs/textures.md); the majorants scale with `c`.
    pub(super) fn sample_flight_with<U: FnMut() -> f32>(
        &self,
        c: &DensityCoefficients,
        ray: &Ray,
        t_max: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'_> {
        let model = if self.uses_local_bounds() {
            LookupModel::Probed
        } else {
            self.unprobed_flight_model()
        };
        let flight = match self.tracking.free_flight {
            FreeFlightMethod::Split if t_max.is_finite() => {
                let mut lookup = self.density_along(ray);
                split_flight(
                    |a, b| self.segments_with(c, ray, a, b, model),
                    c,
                    |t| lookup.at(t),
                    self.tracking.transmittance,
                    t_max,
                    u,
                    stats,
                )
            }
            // The segments are made where they are consumed, and passed by reference: the
            // walk's iterator holds its DDA stack, which a move would copy. Where the walk is
            // not needed (the root emitted whole, as in thin media) it is not prepared at all.
            _ => match self.pyramid.segments_start(
                ray,
                0.0,
                t_max,
                self.tracking.majorant,
                Some(c.max_sigma_t()),
                model,
            ) {
                SegmentsStart::Few(few) => {
                    let mut segments = self.medium_segments(c, few, 0.0, t_max);
                    self.track_flight(&mut segments, c, ray, beta, u, stats)
                }
                SegmentsStart::Open(walk) => {
                    // The adjustments borrow the walk's iterator rather than take it: moving
                    // it into them copied its DDA stack (twice, 920 bytes each).
                    let mut inner = walk.segments();
                    let mut segments = self.medium_segments(c, &mut inner, 0.0, t_max);
                    self.track_flight(&mut segments, c, ray, beta, u, stats)
                }
            },
        };
        match flight {
            Flight::Escape { weight } => MediumEvent::pass(weight),
            Flight::Scatter { t, weight, density } => {
                let p = ray.at(t);
                MediumEvent {
                    weight,
                    emitted: Rgb::ZERO,
                    scatter: Some(ScatterVertex {
                        t,
                        p,
                        albedo: c.sigma_s_at(density).safe_div(c.sigma_t_at(density)),
                        phase: self.phase_at(p),
                    }),
                }
            }
        }
    }

    /// A free flight over `segments` along `ray` with the interior's free-flight estimator
    /// (split flights excepted, which make their own segments).
    fn track_flight<S, U>(
        &self,
        segments: &mut S,
        c: &DensityCoefficients,
        ray: &Ray,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Flight
    where
        S: Iterator<Item = MajorantSegment>,
        U: FnMut() -> f32,
    {
        if let (DensityField::Shell(shell), true) = (&self.field, self.uses_local_bounds()) {
            // The shell's point bounds and lookups share point location (a lookup takes the
            // bound's tetrahedron at the same distance).
            let lookup = ShellLookup::new(shell, ray, self.projected_fibres().is_some());
            let probe = SharedShellProbe::new(&lookup);
            let density = |t| lookup.at_out_of_line(t);
            return match self.tracking.free_flight {
                FreeFlightMethod::Decomposition => {
                    decomposition_track_local(segments, c, density, probe, beta, u, stats)
                }
                _ => delta_track_local(segments, c, density, probe, beta, u, stats),
            };
        }
        // A grid with its local-bounds table (the common case): the grid's lookup and probe
        // are built as they are used, from one index-space ray, without the enums around
        // them. Returned together from `lookups_along`, they were copied through memory (a
        // `memcpy` call per flight); the trackers see the same lookups and bounds.
        if let (DensityField::Grid { grid, channel }, true, None, Some(table)) = (
            &self.field,
            self.uses_local_bounds(),
            self.projected_fibres(),
            self.pyramid.local_bounds(),
        ) {
            let (o, d) = index_ray(grid, ray);
            let mut lookup = GridLookup::from_index_ray(grid, *channel, o, d);
            let mut probe = GridProbe::from_index_ray(table, o, d, false);
            return match self.tracking.free_flight {
                FreeFlightMethod::Decomposition => decomposition_track_local(
                    segments,
                    c,
                    |t| lookup.at(t),
                    &mut probe,
                    beta,
                    u,
                    stats,
                ),
                _ => delta_track_local(segments, c, |t| lookup.at(t), &mut probe, beta, u, stats),
            };
        }
        self.track_flight_general(segments, c, ray, beta, u, stats)
    }

    /// [`Self::track_flight`] without its grid case: the lookup and the point bounds (if any)
    /// as [`Self::lookups_along`] makes them (also the reference its grid case is tested
    /// against).
    fn track_flight_general<S, U>(
        &self,
        segments: &mut S,
        c: &DensityCoefficients,
        ray: &Ray,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Flight
    where
        S: Iterator<Item = MajorantSegment>,
        U: FnMut() -> f32,
    {
        // The probe is lent to the tracker, not moved into it (a move copied it through
        // memory, with loads wider than the stores that had just built it).
        let (mut lookup, mut probe) = self.lookups_along(ray);
        match (self.tracking.free_flight, probe.as_mut()) {
            (FreeFlightMethod::DeltaTracking, Some(probe)) => {
                delta_track_local(segments, c, |t| lookup.at(t), probe, beta, u, stats)
            }
            (FreeFlightMethod::Decomposition, Some(probe)) => {
                decomposition_track_local(segments, c, |t| lookup.at(t), probe, beta, u, stats)
            }
            // An open interior (no boundary ahead) under `Split`: delta tracking.
            (FreeFlightMethod::DeltaTracking | FreeFlightMethod::Split, _) => {
                delta_track(segments, c, |t| lookup.at(t), beta, u, stats)
            }
            (FreeFlightMethod::Decomposition, _) => {
                decomposition_track(segments, c, |t| lookup.at(t), beta, u, stats)
            }
            (FreeFlightMethod::RayMarch { step }, _) => {
                ray_march_free_flight(segments, c, |t| lookup.at(t), step, beta, u, stats)
            }
        }
    }

    /// Estimates the transmittance along `ray` over `[0, t_max]` with the interior's
    /// transmittance estimator.
    pub(super) fn transmittance<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        self.transmittance_with(&self.coefficients, ray, t_max, u, stats)
    }

    /// [`Self::transmittance`] with coefficients `c` in place of the medium's own.
    pub(super) fn transmittance_with<U: FnMut() -> f32>(
        &self,
        c: &DensityCoefficients,
        ray: &Ray,
        t_max: f32,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        // Shadow rays do not thin by the point bounds (`tracking::transmittance_local`): that
        // saves lookups but ratio tracking's variance grows as its majorant tightens (on the
        // dense peer cloud 35 % of the lookups at 1.5× the image's relative MSE).
        // [`Self::segments_with`], with the walk's iterator borrowed (not moved, which
        // copies its DDA stack).
        let mut inner = self.pyramid_segments(c, ray, 0.0, t_max, self.shadow_model());
        let mut segments = self.medium_segments(c, &mut inner, 0.0, t_max);
        // A ray that meets no segment (it misses the field's box, or the walk finds only
        // empty cells): every estimator returns one over no segments, without drawing; skip
        // the density lookup's set-up (about a third of the ocean's shadow rays).
        let Some(first) = segments.next() else {
            return Rgb::ONE;
        };
        let mut lookup = self.density_along(ray);
        transmittance(
            std::iter::once(first).chain(&mut segments),
            c,
            |t| lookup.at(t),
            self.tracking.transmittance,
            u,
            stats,
        )
    }
}

/// The state of the combined-interior gap filling of [`MediumSegments`].
#[derive(Clone, Copy, Debug)]
struct GapFill {
    /// Where the last segment returned ended.
    t: f32,
    /// The end of the ray interval.
    end: f32,
    /// A pyramid segment held back while the gap before it is returned.
    held: Option<MajorantSegment>,
}

/// The majorant segments of a heterogeneous medium along a ray: the pyramid's segments with
/// the minima set to 0 for fibre-projected extinction (sin∠(ω, t) ∈ [0, 1] scales the density:
/// the maxima still bound it, the minima do not, and no segment is homogeneous), and, in a
/// combined interior, zero-density segments over the empty space the pyramid skipped (the
/// homogeneous part fills it).
pub struct MediumSegmentsOf<I> {
    inner: I,
    zero_min: bool,
    fill: Option<GapFill>,
}

/// The majorant segments of a heterogeneous medium along a ray, from the pyramid's iterator.
pub type MediumSegments<'a> = MediumSegmentsOf<Segments<'a>>;

impl<I: Iterator<Item = MajorantSegment>> MediumSegmentsOf<I> {
    #[inline]
    fn next_inner(&mut self) -> Option<MajorantSegment> {
        let mut s = self.inner.next()?;
        if self.zero_min {
            s.min = 0.0;
        }
        Some(s)
    }
}

impl<I: Iterator<Item = MajorantSegment>> Iterator for MediumSegmentsOf<I> {
    type Item = MajorantSegment;

    #[inline]
    fn next(&mut self) -> Option<MajorantSegment> {
        let Some(mut fill) = self.fill else {
            return self.next_inner();
        };
        let out = if let Some(s) = fill.held.take() {
            fill.t = fill.t.max(s.t1);
            Some(s)
        } else {
            match self.next_inner() {
                Some(s) if s.t0 > fill.t => {
                    let gap = MajorantSegment::constant(fill.t, s.t0, 0.0);
                    fill.held = Some(s);
                    Some(gap)
                }
                Some(s) => {
                    fill.t = fill.t.max(s.t1);
                    Some(s)
                }
                None if fill.t < fill.end => {
                    let gap = MajorantSegment::constant(fill.t, fill.end, 0.0);
                    fill.t = fill.end;
                    Some(gap)
                }
                None => None,
            }
        };
        self.fill = Some(fill);
        out
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::grid::{ChannelKind, SparseGridBuilder, Storage};
    use crate::majorant::MajorantPyramid;
    use crate::sampling::Rng;

    /// Three dense blobs in a 48³ index box with empty bricks between them (the ocean's foam
    /// in miniature; the mixture's tests use it too), σ_t 0.4 and σ_s 0.39 per unit density.
    pub(in crate::medium) fn blobs() -> HeterogeneousMedium {
        let mut b = SparseGridBuilder::new(Storage::F32);
        let density = b.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
        let blobs = [
            (glam::IVec3::new(6, 30, 9), 5),
            (glam::IVec3::new(30, 8, 36), 7),
            (glam::IVec3::new(40, 40, 12), 4),
        ];
        for (c, r) in blobs {
            for x in -r..=r {
                for y in -r..=r {
                    for z in -r..=r {
                        let d = glam::IVec3::new(x, y, z);
                        if d.length_squared() <= r * r {
                            let v = 1.0 - (d.length_squared() as f32) / (r * r) as f32;
                            b.set_value(density, c + d, 0.25 + v).expect("voxel");
                        }
                    }
                }
            }
        }
        let grid = b.build();
        let pyramid = MajorantPyramid::from_grid(&grid, density).expect("pyramid");
        HeterogeneousMedium {
            field: DensityField::Grid {
                grid,
                channel: density,
            },
            pyramid,
            coefficients: DensityCoefficients::new(Rgb::splat(0.4), Rgb::splat(0.39)),
            phase: PhaseFunction::HenyeyGreenstein { g: 0.8 },
            tracking: TrackingConfig::default(),
            fabric: None,
            mips: None,
        }
    }

    #[test]
    fn shadow_rays_without_segments_skip_the_estimator_and_the_others_are_unchanged() {
        let foam = &blobs();
        let c = foam.coefficients;
        let mut rng = Rng::new(26, 1);
        let (mut none, mut some, mut below_one) = (0usize, 0usize, 0usize);
        for r in 0..3000 {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 56.0 - 4.0;
            let d = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                .normalize_or(Vec3::Z);
            let ray = Ray::new(o, d);
            let t_max = if r % 3 == 0 { 20.0 } else { 80.0 };
            // The reference: the estimator over all the segments (none or some), with a
            // lookup built up front.
            let segments: Vec<MajorantSegment> = foam
                .medium_segments(
                    &c,
                    foam.pyramid_segments(&c, &ray, 0.0, t_max, foam.shadow_model()),
                    0.0,
                    t_max,
                )
                .collect();
            let mut lookup = foam.density_along(&ray);
            let (mut u1, mut u2) = (Rng::new(r, 7), Rng::new(r, 7));
            let (mut s1, mut s2) = (TrackingStats::default(), TrackingStats::default());
            let expected = transmittance(
                segments.iter().copied(),
                &c,
                |t| lookup.at(t),
                foam.tracking.transmittance,
                &mut || u1.next_f32(),
                &mut s1,
            );
            let got = foam.transmittance_with(&c, &ray, t_max, &mut || u2.next_f32(), &mut s2);
            assert_eq!(got, expected, "ray {r}");
            // The same numbers drawn and counted.
            assert_eq!(u1.next_f32().to_bits(), u2.next_f32().to_bits(), "ray {r}");
            assert_eq!(s1, s2, "ray {r}");
            if segments.is_empty() {
                assert_eq!(got, Rgb::ONE, "ray {r}");
                none += 1;
            } else {
                some += 1;
                below_one += usize::from(got != Rgb::ONE);
            }
        }
        // Both kinds of rays, and estimates that do depend on the field.
        assert!(
            none > 300 && some > 300 && below_one > 100,
            "{none} without, {some} with segments, {below_one} below one"
        );
    }
    #[test]
    fn a_grid_flight_tracks_as_the_general_lookup_and_probe() {
        for method in [
            FreeFlightMethod::DeltaTracking,
            FreeFlightMethod::Decomposition,
        ] {
            let mut foam = blobs();
            foam.tracking.free_flight = method;
            foam.attach_local_bounds().expect("local bounds");
            assert!(foam.uses_local_bounds() && foam.pyramid.local_bounds().is_some());
            // Chromatic and denser than the blobs' own coefficients: more collisions.
            let c = DensityCoefficients::new(Rgb::new(3.0, 2.0, 1.0), Rgb::new(2.9, 1.8, 0.9));
            let mut rng = Rng::new(26, 2);
            let (mut scattered, mut escaped, mut lookups) = (0usize, 0usize, 0u64);
            for r in 0..3000 {
                let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 56.0 - 4.0;
                // Most rays aimed near a blob (the others anywhere).
                let aim = [
                    Vec3::new(6.0, 30.0, 9.0),
                    Vec3::new(30.0, 8.0, 36.0),
                    Vec3::new(40.0, 40.0, 12.0),
                ][r as usize % 3]
                    + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 8.0;
                let d = if r % 4 == 0 {
                    (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                        .normalize_or(Vec3::Z)
                } else {
                    (aim - o).normalize_or(Vec3::Z)
                };
                let ray = Ray::new(o, d);
                let t_max = if r % 3 == 0 { 20.0 } else { 80.0 };
                let segments: Vec<MajorantSegment> = foam
                    .medium_segments(
                        &c,
                        foam.pyramid_segments(&c, &ray, 0.0, t_max, LookupModel::Probed),
                        0.0,
                        t_max,
                    )
                    .collect();
                let beta = Rgb::new(1.0, 0.7, 0.4);
                let (mut u1, mut u2) = (Rng::new(r, 9), Rng::new(r, 9));
                let (mut s1, mut s2) = (TrackingStats::default(), TrackingStats::default());
                let expected = foam.track_flight_general(
                    &mut segments.iter().copied(),
                    &c,
                    &ray,
                    beta,
                    &mut || u1.next_f32(),
                    &mut s1,
                );
                let got = foam.track_flight(
                    &mut segments.iter().copied(),
                    &c,
                    &ray,
                    beta,
                    &mut || u2.next_f32(),
                    &mut s2,
                );
                assert_eq!(got, expected, "{method:?}, ray {r}");
                // The same numbers drawn, the same lookups and bound probes counted.
                assert_eq!(u1.next_f32().to_bits(), u2.next_f32().to_bits(), "ray {r}");
                assert_eq!(s1, s2, "{method:?}, ray {r}");
                match got {
                    Flight::Scatter { .. } => scattered += 1,
                    Flight::Escape { .. } => escaped += 1,
                }
                lookups += s1.lookups;
            }
            assert!(
                scattered > 500 && escaped > 300 && lookups > 3000,
                "{method:?}: {scattered} scattered, {escaped} escaped, {lookups} lookups"
            );
        }
    }
}
