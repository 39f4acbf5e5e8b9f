//! Mixture interiors: up to [`MAX_COMPONENTS`] media in one object, each with its own
//! extinction, albedo (constant or a colour grid), emission (a colour, scalar or temperature
//! grid) and phase function (docs/references.md §15). The extinction of the mixture is the sum
//! of its components'; a free flight is tracked against the sum of their majorants (the
//! components' majorant walks merged along the ray), a real collision belongs to a component
//! with probability ∝ its σ_t there, and the event carries that component's albedo and phase
//! function. Emission is gathered along the flight by the collision estimator. Shadow rays
//! multiply the components' transmittances.
//!
//! A one-component "mixture" is how a `voxel` interior with an albedo or emission grid is
//! built: the grids need the per-vertex albedo and the emission of these trackers.
//!
//! Every estimator here reads the components' coefficients from a [`WalkCoefficients`]
//! array: the components' own, or one walk's ([`ScaledMixture`]: textured components read at
//! the entry point, docs/textures.md), so that the majorants scale with each walk's
//! coefficients and stay conservative.

use std::sync::Arc;

use glam::Vec3;

use super::artist::Coefficients;
use super::event::{MediumEvent, ScatterVertex, VertexPhase};
use super::grids::{AlbedoGrid, EmissionGrid, GridRay};
use super::heterogeneous::{HeterogeneousMedium, MediumSegmentsOf};
use super::lookup::DensityLookup;
use super::walk::{EntryInterior, WalkMedium};
use crate::majorant::{MajorantSegment, Segments};
use crate::math::{Ray, Vec2};
use crate::phase::PhaseFunction;
use crate::spectrum::Rgb;
use crate::texture::{ColorParam, ScalarParam};
use crate::tracking::{
    channel_probabilities, mixture_track, DensityCoefficients, MixPoint, RateSegment,
    TrackingStats, MAX_COMPONENTS,
};

/// One component's coefficients: σ_t and σ_s (1/length; per unit density for a field
/// component).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ComponentCoefficients {
    /// Extinction (per unit density for a field).
    pub sigma_t: Rgb,
    /// Scattering (per unit density for a field).
    pub sigma_s: Rgb,
}

impl ComponentCoefficients {
    /// No extinction, no scattering (the unused entries of a [`WalkCoefficients`]).
    pub const ZERO: ComponentCoefficients = ComponentCoefficients {
        sigma_t: Rgb::ZERO,
        sigma_s: Rgb::ZERO,
    };
}

/// The coefficients of a mixture's components (entry `i` for component `i`; entries past
/// the last component unused).
pub type WalkCoefficients = [ComponentCoefficients; MAX_COMPONENTS];

/// The coefficients field `h` is tracked with when its component's coefficients are `k`
/// (its base medium kept: a component's is empty).
fn field_coefficients(h: &HeterogeneousMedium, k: &ComponentCoefficients) -> DensityCoefficients {
    DensityCoefficients {
        sigma_t: k.sigma_t,
        sigma_s: k.sigma_s,
        base_t: h.coefficients.base_t,
        base_s: h.coefficients.base_s,
    }
}

/// Where a component's extinction comes from.
#[derive(Clone, Debug)]
pub enum ComponentDensity {
    /// Constant coefficients (a homogeneous component).
    Constant(Coefficients),
    /// A density field with its majorant pyramid and coefficients per unit density (no
    /// constant part, no fabric look); its `tracking.majorant` is the mixture's.
    Field(Box<HeterogeneousMedium>),
}

/// One component of a mixture.
#[derive(Clone, Debug)]
pub struct MixtureComponent {
    /// Its extinction and scattering (per unit density for a field).
    pub density: ComponentDensity,
    /// Its phase function.
    pub phase: PhaseFunction,
    /// Its per-vertex albedo, if read from a grid.
    pub albedo: Option<Box<AlbedoGrid>>,
    /// Its emission, if any.
    pub emission: Option<Box<EmissionGrid>>,
}

impl MixtureComponent {
    /// The component's own coefficients (σ_t and σ_s; per unit density for a field).
    fn own_coefficients(&self) -> ComponentCoefficients {
        match &self.density {
            ComponentDensity::Constant(c) => ComponentCoefficients {
                sigma_t: c.sigma_t(),
                sigma_s: c.sigma_s,
            },
            ComponentDensity::Field(h) => ComponentCoefficients {
                sigma_t: h.coefficients.sigma_t,
                sigma_s: h.coefficients.sigma_s,
            },
        }
    }

    /// The single-scattering albedo at world point `p` with coefficients `k`: the albedo
    /// grid's, or σ_s/σ_t.
    fn albedo_at(&self, p: Vec3, k: &ComponentCoefficients) -> Rgb {
        match &self.albedo {
            Some(a) => a.single_scattering_at(p),
            None => k.sigma_s.safe_div(k.sigma_t),
        }
    }

    /// The largest extinction the component can have with coefficients `k` (RGB, 1/length).
    fn max_sigma_t(&self, k: &ComponentCoefficients) -> Rgb {
        match &self.density {
            ComponentDensity::Constant(_) => k.sigma_t,
            ComponentDensity::Field(h) => {
                field_coefficients(h, k).sigma_t_at(h.pyramid.global_bounds().max)
            }
        }
    }
}

/// A mixture interior.
#[derive(Clone, Debug)]
pub struct MixtureMedium {
    /// The components (1 to [`MAX_COMPONENTS`]).
    pub components: Vec<MixtureComponent>,
}

/// The per-ray state of a mixture: density lookups and emission lookups per component.
struct MixRay<'a> {
    medium: &'a MixtureMedium,
    k: &'a WalkCoefficients,
    ray: Ray,
    density: [Option<DensityLookup<'a>>; MAX_COMPONENTS],
    emission: [Option<GridRay<'a>>; MAX_COMPONENTS],
}

impl<'a> MixRay<'a> {
    /// The per-ray state without its lookups: [`Self::prepare`] makes them in place (the
    /// lookups are large, and a state built and returned by value is copied).
    #[inline(always)]
    fn idle(medium: &'a MixtureMedium, k: &'a WalkCoefficients, ray: &Ray) -> Self {
        MixRay {
            medium,
            k,
            ray: *ray,
            density: [None, None, None, None],
            emission: [None, None, None, None],
        }
    }

    /// Makes the components' density lookups (and emission lookups when `emission`).
    fn prepare(&mut self, emission: bool) {
        let medium = self.medium;
        let ray = self.ray;
        let slots = self.density.iter_mut().zip(self.emission.iter_mut());
        for (c, (density, em)) in medium.components.iter().take(MAX_COMPONENTS).zip(slots) {
            if let ComponentDensity::Field(h) = &c.density {
                *density = Some(h.density_along(&ray));
            }
            if emission {
                if let Some(e) = &c.emission {
                    *em = Some(GridRay::new(&e.grid, &ray));
                }
            }
        }
    }

    /// The mixture at distance `t` (with its emission when `emission`).
    fn at(&mut self, t: f32, emission: bool) -> MixPoint {
        let mut point = MixPoint {
            sigma_t: [Rgb::ZERO; MAX_COMPONENTS],
            count: self.medium.components.len().min(MAX_COMPONENTS),
            emission: Rgb::ZERO,
        };
        let comps = self.medium.components.iter().take(MAX_COMPONENTS);
        for ((((c, k), slot), lookup), sigma) in comps
            .zip(self.k.iter())
            .zip(self.emission.iter_mut())
            .zip(self.density.iter_mut())
            .zip(point.sigma_t.iter_mut())
        {
            *sigma = match (&c.density, lookup) {
                (ComponentDensity::Constant(_), _) => k.sigma_t,
                (ComponentDensity::Field(h), Some(l)) => {
                    field_coefficients(h, k).sigma_t_at(l.at(t))
                }
                (ComponentDensity::Field(_), None) => Rgb::ZERO,
            };
            if emission {
                if let (Some(e), Some(r)) = (&c.emission, slot.as_mut()) {
                    let le = e.at(r, t);
                    if !le.is_black() {
                        let alpha = c.albedo_at(self.ray.at(t), k);
                        point.emission += *sigma * (Rgb::ONE - alpha) * le;
                    }
                }
            }
        }
        point
    }
}

/// The merged majorant segments of a mixture along a ray: the components' walks joined at
/// every boundary of any of them, each piece's majorant the sum of the components'
/// (constant components everywhere, field components where their walk has a segment).
///
/// The fields' walks are held by the caller ([`FieldWalks`]) and lent: a walk's iterator holds
/// its DDA stack, which every move copies.
struct MixSegments<'a, 'w> {
    streams: [Option<MediumSegmentsOf<&'w mut Segments<'a>>>; MAX_COMPONENTS],
    current: [Option<MajorantSegment>; MAX_COMPONENTS],
    scale: [Rgb; MAX_COMPONENTS],
    constant: Rgb,
    t: f32,
    end: f32,
}

/// The majorant walks of a mixture's field components along one ray (entry `i` for
/// component `i`; `None` for constant components), held where a flight is sampled and lent
/// to [`MixSegments`].
type FieldWalks<'a> = [Option<Segments<'a>>; MAX_COMPONENTS];

impl<'a, 'w> MixSegments<'a, 'w> {
    /// The merged segments of `medium` with coefficients `k` along `ray` over `[t0, t1]`:
    /// each field's density bounds times its σ_t per unit density in `k`. The fields' walks
    /// are prepared in `walks` (which must hold no walk yet).
    fn new(
        medium: &'a MixtureMedium,
        k: &WalkCoefficients,
        ray: &Ray,
        t0: f32,
        t1: f32,
        walks: &'w mut FieldWalks<'a>,
    ) -> Self {
        let mut m = MixSegments {
            streams: [None, None, None, None],
            current: [None; MAX_COMPONENTS],
            scale: [Rgb::ZERO; MAX_COMPONENTS],
            constant: Rgb::ZERO,
            t: t0,
            end: t1,
        };
        let comps = medium.components.iter().take(MAX_COMPONENTS);
        let slots = walks
            .iter_mut()
            .zip(m.streams.iter_mut().zip(m.scale.iter_mut()));
        for ((c, own), (walk, (s, scale))) in comps.zip(k.iter()).zip(slots) {
            match &c.density {
                ComponentDensity::Constant(_) => m.constant += own.sigma_t,
                ComponentDensity::Field(h) => {
                    let w = walk.insert(h.flight_walk(ray, t0, t1));
                    *s = Some(h.flight_segments_of(w, t0, t1));
                    *scale = own.sigma_t;
                }
            }
        }
        for (c, s) in m.current.iter_mut().zip(m.streams.iter_mut()) {
            *c = s.as_mut().and_then(Iterator::next);
        }
        m
    }
}

impl Iterator for MixSegments<'_, '_> {
    type Item = RateSegment;

    fn next(&mut self) -> Option<RateSegment> {
        if !(self.t < self.end) {
            return None;
        }
        let mut next = self.end;
        let mut rate = Rgb::ZERO;
        // Estimated (unproven) bounds may be violated: such pieces are tracked with lookups
        // even where their majorant is zero.
        let mut unproven = false;
        for ((cur, stream), scale) in self
            .current
            .iter_mut()
            .zip(self.streams.iter_mut())
            .zip(self.scale.iter())
        {
            // Drop the segments that end before the current position.
            while let Some(s) = *cur {
                if s.t1 <= self.t {
                    *cur = stream.as_mut().and_then(Iterator::next);
                } else {
                    break;
                }
            }
            if let Some(s) = cur {
                if s.t0 > self.t {
                    next = next.min(s.t0);
                } else {
                    rate += *scale * s.max.max(0.0);
                    unproven |= !s.exact;
                    next = next.min(s.t1);
                }
            }
        }
        if next.is_infinite() && rate.is_black() && self.constant.is_black() {
            // An open interior with nothing left ahead.
            self.t = next;
            return None;
        }
        let seg = RateSegment {
            t0: self.t,
            t1: next,
            majorant: (self.constant + rate).max_component(),
            varying: !rate.is_black() || unproven,
        };
        self.t = next;
        Some(seg)
    }
}

/// A stream of segments cut at `end`: the segments before it, the one that crosses it
/// shortened to end there.
struct ClippedSegments<I> {
    inner: I,
    end: f32,
}

impl<I: Iterator<Item = RateSegment>> Iterator for ClippedSegments<I> {
    type Item = RateSegment;

    #[inline]
    fn next(&mut self) -> Option<RateSegment> {
        let mut seg = self.inner.next()?;
        if !(seg.t0 < self.end) {
            return None;
        }
        seg.t1 = seg.t1.min(self.end);
        Some(seg)
    }
}

impl MixtureMedium {
    /// The components' own coefficients.
    #[must_use]
    pub fn own_coefficients(&self) -> WalkCoefficients {
        let mut k = [ComponentCoefficients::ZERO; MAX_COMPONENTS];
        for (c, slot) in self.components.iter().zip(k.iter_mut()) {
            *slot = c.own_coefficients();
        }
        k
    }

    /// The constant components' extinctions with coefficients `k` (zero for the fields), as
    /// a [`MixPoint`].
    fn constant_point(&self, k: &WalkCoefficients) -> MixPoint {
        let mut point = MixPoint {
            sigma_t: [Rgb::ZERO; MAX_COMPONENTS],
            count: self.components.len().min(MAX_COMPONENTS),
            emission: Rgb::ZERO,
        };
        for ((c, s), own) in self
            .components
            .iter()
            .zip(point.sigma_t.iter_mut())
            .zip(k.iter())
        {
            if let ComponentDensity::Constant(_) = &c.density {
                *s = own.sigma_t;
            }
        }
        point
    }

    /// True when some component emits.
    #[must_use]
    pub fn emits(&self) -> bool {
        self.components.iter().any(|c| c.emission.is_some())
    }

    /// True when some component scatters.
    #[must_use]
    pub fn scatters(&self) -> bool {
        self.components.iter().any(|c| match &c.density {
            ComponentDensity::Constant(k) => !k.sigma_s.is_black(),
            ComponentDensity::Field(h) => !h.coefficients.sigma_s.is_black(),
        })
    }

    /// The sum of the components' largest extinctions (RGB, 1/length).
    #[must_use]
    pub fn max_sigma_t(&self) -> Rgb {
        self.max_sigma_t_with(&self.own_coefficients())
    }

    /// [`Self::max_sigma_t`] with coefficients `k`.
    fn max_sigma_t_with(&self, k: &WalkCoefficients) -> Rgb {
        self.components
            .iter()
            .zip(k.iter())
            .fold(Rgb::ZERO, |a, (c, k)| a + c.max_sigma_t(k))
    }

    /// The union of the world boxes of the field components' majorant pyramids (`None` when
    /// no component is a non-empty field): what `shape = "bounds"` encloses.
    #[must_use]
    pub fn world_bounds(&self) -> Option<crate::math::Aabb> {
        self.components
            .iter()
            .filter_map(|c| match &c.density {
                ComponentDensity::Field(h) => h.pyramid.world_bounds(),
                ComponentDensity::Constant(_) => None,
            })
            .reduce(crate::math::Aabb::union)
    }

    /// Samples a free flight along `ray` over `[0, t_max]` (delta tracking through the mixture;
    /// the hero channel ∝ the throughput `beta`).
    pub(super) fn sample_flight<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'_> {
        self.sample_flight_with(&self.own_coefficients(), ray, t_max, beta, u, stats)
    }

    /// [`Self::sample_flight`] with coefficients `k` in place of the components' own; the
    /// majorants scale with `k`.
    fn sample_flight_with<U: FnMut() -> f32>(
        &self,
        k: &WalkCoefficients,
        ray: &Ray,
        t_max: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'_> {
        let emits = self.emits();
        // The merged walk of the whole ray, cut at `t_max`: a flight over `[0, t_max]` draws
        // the same numbers and makes the same decisions before `t_max` as one over `[0, ∞)`
        // (the walks' cells do not depend on where the ray ends), which is what lets a caller
        // sample the flight first and search the boundary only up to the collision
        // ([`super::Medium::flight_before_boundary`]).
        // The fields' walks are held here and lent to the merged walk, which is lent to the
        // tracker: a walk holds a DDA stack, too large to move around by value.
        let mut walks: FieldWalks<'_> = [None, None, None, None];
        let mut merged = MixSegments::new(self, k, ray, 0.0, f32::INFINITY, &mut walks);
        let segments = ClippedSegments {
            inner: &mut merged,
            end: t_max,
        };
        let mut state = MixRay::idle(self, k, ray);
        state.prepare(emits);
        let probs = channel_probabilities(beta, Rgb::ONE);
        let none = ComponentCoefficients::ZERO;
        let flight = mixture_track(
            segments,
            &self.constant_point(k),
            |t, e| state.at(t, e),
            |i, t, point| match (self.components.get(i), point.sigma_t.get(i)) {
                (Some(c), Some(&sigma_t)) => {
                    c.albedo_at(ray.at(t), k.get(i).unwrap_or(&none)) * sigma_t
                }
                _ => Rgb::ZERO,
            },
            emits,
            probs,
            u,
            stats,
        );
        let scatter = flight.scatter.and_then(|(t, i)| {
            let c = self.components.get(i)?;
            let p = ray.at(t);
            Some(ScatterVertex {
                t,
                p,
                albedo: c.albedo_at(p, k.get(i)?),
                phase: VertexPhase::Hg(&c.phase),
            })
        });
        MediumEvent {
            weight: flight.weight,
            emitted: flight.emitted,
            scatter,
        }
    }

    /// Estimates the transmittance along `ray` over `[0, t_max]`: the product of the
    /// components' transmittances (T = Π_i T_i for a sum of extinctions), the homogeneous ones
    /// in closed form, each field with its own estimator over its own majorant walk
    /// (the mixture's `tracking.transmittance`; independent unbiased estimates multiply into an
    /// unbiased one).
    pub(super) fn transmittance<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        self.transmittance_with(&self.own_coefficients(), ray, t_max, u, stats)
    }

    /// [`Self::transmittance`] with coefficients `k` in place of the components' own.
    fn transmittance_with<U: FnMut() -> f32>(
        &self,
        k: &WalkCoefficients,
        ray: &Ray,
        t_max: f32,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        let mut tr = Rgb::ONE;
        for (c, k) in self.components.iter().zip(k.iter()) {
            match &c.density {
                ComponentDensity::Constant(_) => {
                    // Guard 0·∞ (σ_t = 0 over an open interior): docs/references.md §8.
                    tr *= k
                        .sigma_t
                        .map(|s| if s == 0.0 { 1.0 } else { (-s * t_max).exp() });
                }
                ComponentDensity::Field(h) => {
                    tr *= h.transmittance_with(&field_coefficients(h, k), ray, t_max, u, stats);
                }
            }
            if tr.is_black() {
                break;
            }
        }
        tr
    }
}

/// A shared mixture with one walk's coefficients per component (textured components read at
/// the entry point, docs/textures.md): what a walk through a textured `mixture` interior, or a
/// `voxel`/`fbm` interior with a textured base medium, sees. Building one shares the
/// components (no copy, no allocation); each field's majorants are its density bounds times
/// the walk's σ_t per unit density, so tracking stays conservative.
#[derive(Clone, Debug)]
pub struct ScaledMixture {
    /// The components (their own coefficients are the textures' means).
    pub medium: Arc<MixtureMedium>,
    /// The walk's coefficients, per component.
    pub coefficients: WalkCoefficients,
}

impl ScaledMixture {
    /// The sum of the components' largest extinctions with the walk's coefficients (RGB,
    /// 1/length).
    #[must_use]
    pub fn max_sigma_t(&self) -> Rgb {
        self.medium.max_sigma_t_with(&self.coefficients)
    }

    /// True when some component scatters with the walk's coefficients.
    #[must_use]
    pub fn scatters(&self) -> bool {
        self.coefficients
            .iter()
            .take(self.medium.components.len())
            .any(|k| !k.sigma_s.is_black())
    }

    /// A free flight along `ray` over `[0, t_max]` ([`MixtureMedium`]'s, with the walk's
    /// coefficients).
    pub(super) fn sample_flight<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'_> {
        self.medium
            .sample_flight_with(&self.coefficients, ray, t_max, beta, u, stats)
    }

    /// The transmittance along `ray` over `[0, t_max]` with the walk's coefficients.
    pub(super) fn transmittance<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        self.medium
            .transmittance_with(&self.coefficients, ray, t_max, u, stats)
    }
}

/// A density-field component's textured parameters, read at the entry point: its
/// coefficients per unit density (the field itself does not change).
#[derive(Clone, Debug)]
pub struct FieldTextures {
    /// Artist albedo in [0, 1].
    pub albedo: ColorParam,
    /// Attenuation distance per channel at density 1 (world units), > 0.
    pub attenuation: ColorParam,
    /// Density multiplier ≥ 0.
    pub density: ScalarParam,
    /// How the albedo is read.
    pub mode: super::AlbedoMode,
    /// The component's phase function's mean cosine (for the albedo inversion).
    pub mean_cosine: f32,
}

/// How one component of a textured mixture gets each walk's coefficients.
#[derive(Clone, Debug)]
pub enum ComponentTextures {
    /// Its own, constant coefficients.
    Fixed,
    /// A `homogeneous` or `absorption` component (or a combined interior's base medium) with
    /// textured parameters, read at the entry point.
    Entry(EntryInterior),
    /// A `voxel` or `fbm` component with textured parameters, read at the entry point.
    Field(FieldTextures),
}

impl ComponentTextures {
    /// The coefficients at texture coordinates `uv` (footprint `width_uv` wide), inverted as
    /// for constants (notes eq. 1–3); `own` when fixed.
    fn at(&self, uv: Vec2, width_uv: f32, own: ComponentCoefficients) -> ComponentCoefficients {
        match self {
            ComponentTextures::Fixed => own,
            ComponentTextures::Entry(e) => match e.at(uv, width_uv) {
                WalkMedium::Homogeneous { coefficients, .. } => ComponentCoefficients {
                    sigma_t: coefficients.sigma_t(),
                    sigma_s: coefficients.sigma_s,
                },
                WalkMedium::Absorbing(sigma_a) => ComponentCoefficients {
                    sigma_t: sigma_a,
                    sigma_s: Rgb::ZERO,
                },
                _ => own,
            },
            ComponentTextures::Field(f) => {
                let c = Coefficients::from_artist(
                    f.albedo.eval(uv, width_uv),
                    f.attenuation.eval(uv, width_uv),
                    f.density.eval(uv, width_uv),
                    f.mode,
                    f.mean_cosine,
                );
                ComponentCoefficients {
                    sigma_t: c.sigma_t(),
                    sigma_s: c.sigma_s,
                }
            }
        }
    }
}

/// A mixture with textured components, resolved per walk: at the entry point each textured
/// component's parameters are read and inverted, and the walk tracks the shared components
/// with those coefficients ([`ScaledMixture`]).
#[derive(Clone, Debug)]
pub struct TexturedMixture {
    /// The components, their own coefficients the textures' means.
    pub medium: Arc<MixtureMedium>,
    /// Per component, how a walk's coefficients are read (as many as components).
    pub textures: Vec<ComponentTextures>,
}

impl TexturedMixture {
    /// The medium of a walk entering at texture coordinates `uv` with a footprint `width_uv`
    /// wide.
    #[must_use]
    pub fn at(&self, uv: Vec2, width_uv: f32) -> ScaledMixture {
        let mut coefficients = self.medium.own_coefficients();
        for (k, t) in coefficients.iter_mut().zip(self.textures.iter()) {
            *k = t.at(uv, width_uv, *k);
        }
        ScaledMixture {
            medium: Arc::clone(&self.medium),
            coefficients,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_homogeneous_components_merge_into_one_constant_segment() {
        let a = Coefficients {
            sigma_a: Rgb::new(0.1, 0.2, 0.3),
            sigma_s: Rgb::ONE,
        };
        let b = Coefficients {
            sigma_a: Rgb::ZERO,
            sigma_s: Rgb::splat(2.0),
        };
        let phase = PhaseFunction::HenyeyGreenstein { g: 0.0 };
        let m = MixtureMedium {
            components: vec![
                MixtureComponent {
                    density: ComponentDensity::Constant(a),
                    phase,
                    albedo: None,
                    emission: None,
                },
                MixtureComponent {
                    density: ComponentDensity::Constant(b),
                    phase,
                    albedo: None,
                    emission: None,
                },
            ],
        };
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        let own = m.own_coefficients();
        let segs: Vec<RateSegment> =
            MixSegments::new(&m, &own, &ray, 0.0, 2.0, &mut [None, None, None, None]).collect();
        assert_eq!(
            segs,
            vec![RateSegment {
                t0: 0.0,
                t1: 2.0,
                majorant: 3.3,
                varying: false,
            }]
        );
        // Open interiors: one infinite segment.
        let open: Vec<RateSegment> = MixSegments::new(
            &m,
            &own,
            &ray,
            0.0,
            f32::INFINITY,
            &mut [None, None, None, None],
        )
        .collect();
        assert_eq!(open.len(), 1);
    }

    #[test]
    fn a_walks_coefficients_set_the_majorant_and_the_albedo() {
        let phase = PhaseFunction::HenyeyGreenstein { g: 0.0 };
        let c = Coefficients {
            sigma_a: Rgb::splat(0.5),
            sigma_s: Rgb::splat(0.5),
        };
        let m = Arc::new(MixtureMedium {
            components: vec![
                MixtureComponent {
                    density: ComponentDensity::Constant(c),
                    phase,
                    albedo: None,
                    emission: None,
                },
                MixtureComponent {
                    density: ComponentDensity::Constant(c),
                    phase,
                    albedo: None,
                    emission: None,
                },
            ],
        });
        let mut k = m.own_coefficients();
        k[1] = ComponentCoefficients {
            sigma_t: Rgb::new(4.0, 2.0, 1.0),
            sigma_s: Rgb::new(1.0, 1.0, 1.0),
        };
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        let segs: Vec<RateSegment> =
            MixSegments::new(&m, &k, &ray, 0.0, 1.0, &mut [None, None, None, None]).collect();
        assert_eq!(segs.len(), 1);
        assert!((segs[0].majorant - 5.0).abs() < 1e-6, "{segs:?}");
        let walk = ScaledMixture {
            medium: Arc::clone(&m),
            coefficients: k,
        };
        assert_eq!(walk.max_sigma_t(), Rgb::new(5.0, 3.0, 2.0));
        let tr = walk.transmittance(&ray, 1.0, &mut || 0.5, &mut TrackingStats::default());
        for (t, s) in tr.0.iter().zip([5.0f32, 3.0, 2.0]) {
            assert!((t - (-s).exp()).abs() < 1e-6, "{tr:?}");
        }
        // A fixed-only textured mixture resolves to the components' own coefficients.
        let fixed = TexturedMixture {
            medium: Arc::clone(&m),
            textures: vec![ComponentTextures::Fixed, ComponentTextures::Fixed],
        };
        assert_eq!(fixed.at(Vec2::ZERO, 1.0).coefficients, m.own_coefficients());
    }

    /// Clear water (constant) and a sparse foam field over 6³ bricks: blobs of density in
    /// some bricks, empty bricks between them.
    fn water_and_foam() -> MixtureMedium {
        // The heterogeneous tests' three blobs, a hundred times as dense.
        let mut foam = super::super::heterogeneous::tests::blobs();
        foam.coefficients = DensityCoefficients::new(Rgb::splat(40.0), Rgb::splat(39.0));
        let water = Coefficients {
            sigma_a: Rgb::new(0.28, 0.06, 0.01),
            sigma_s: Rgb::new(0.002, 0.003, 0.006),
        };
        MixtureMedium {
            components: vec![
                MixtureComponent {
                    density: ComponentDensity::Constant(water),
                    phase: PhaseFunction::HenyeyGreenstein { g: 0.0 },
                    albedo: None,
                    emission: None,
                },
                MixtureComponent {
                    density: ComponentDensity::Field(Box::new(foam)),
                    phase: PhaseFunction::HenyeyGreenstein { g: 0.8 },
                    albedo: None,
                    emission: None,
                },
            ],
        }
    }

    #[test]
    fn lent_walks_give_the_fields_segments_and_their_merge() {
        let m = water_and_foam();
        let ComponentDensity::Field(foam) = &m.components[1].density else {
            unreachable!("the second component is the field")
        };
        let own = m.own_coefficients();
        let water = own[0].sigma_t;
        let scale = own[1].sigma_t;
        let mut rng = crate::sampling::Rng::new(25, 1);
        let (mut varying, mut gaps) = (0usize, 0usize);
        for r in 0..3000 {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 56.0 - 4.0;
            let d = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5)
                .normalize_or(Vec3::Z);
            let ray = Ray::new(o, d);
            let t1 = if r % 3 == 0 { 20.0 } else { f32::INFINITY };
            // The walk made in two parts and lent gives the segments of the one-part call.
            let whole: Vec<MajorantSegment> = foam.segments_along(&ray, 0.0, t1).collect();
            let mut walk = foam.flight_walk(&ray, 0.0, t1);
            let lent: Vec<MajorantSegment> = foam.flight_segments_of(&mut walk, 0.0, t1).collect();
            assert_eq!(lent, whole, "ray {r}");
            // The merged segments: the water alone between the foam's segments, water and
            // foam on them.
            let mut expected = Vec::new();
            let mut t = 0.0f32;
            for s in whole.iter().filter(|s| s.t1 > s.t0) {
                if s.t0 > t {
                    expected.push(RateSegment {
                        t0: t,
                        t1: s.t0,
                        majorant: water.max_component(),
                        varying: false,
                    });
                }
                let rate = scale * s.max.max(0.0);
                expected.push(RateSegment {
                    t0: s.t0.max(t),
                    t1: s.t1,
                    majorant: (water + rate).max_component(),
                    varying: !rate.is_black() || !s.exact,
                });
                t = s.t1;
            }
            if t < t1 {
                expected.push(RateSegment {
                    t0: t,
                    t1,
                    majorant: water.max_component(),
                    varying: false,
                });
            }
            let mut walks: FieldWalks<'_> = [None, None, None, None];
            let merged: Vec<RateSegment> =
                MixSegments::new(&m, &own, &ray, 0.0, t1, &mut walks).collect();
            assert_eq!(merged, expected, "ray {r}");
            varying += merged.iter().filter(|s| s.varying).count();
            gaps += merged.iter().filter(|s| !s.varying).count();
        }
        // Both kinds of pieces, in numbers.
        assert!(
            varying > 500 && gaps > 2000,
            "{varying} varying, {gaps} gaps"
        );
    }
}
