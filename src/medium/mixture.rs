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

use glam::Vec3;

use super::artist::Coefficients;
use super::event::{MediumEvent, ScatterVertex, VertexPhase};
use super::grids::{AlbedoGrid, EmissionGrid, GridRay};
use super::heterogeneous::{HeterogeneousMedium, MediumSegments};
use super::lookup::DensityLookup;
use crate::majorant::MajorantSegment;
use crate::math::Ray;
use crate::phase::PhaseFunction;
use crate::spectrum::Rgb;
use crate::tracking::{
    channel_probabilities, mixture_track, MixPoint, RateSegment, TrackingStats, MAX_COMPONENTS,
};

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
    /// The component's constant single-scattering albedo σ_s/σ_t (ignoring an albedo grid).
    fn constant_albedo(&self) -> Rgb {
        match &self.density {
            ComponentDensity::Constant(c) => c.sigma_s.safe_div(c.sigma_t()),
            ComponentDensity::Field(h) => h.coefficients.sigma_s.safe_div(h.coefficients.sigma_t),
        }
    }

    /// The single-scattering albedo at world point `p`.
    fn albedo_at(&self, p: Vec3) -> Rgb {
        match &self.albedo {
            Some(a) => a.single_scattering_at(p),
            None => self.constant_albedo(),
        }
    }

    /// The largest extinction the component can have (RGB, 1/length).
    fn max_sigma_t(&self) -> Rgb {
        match &self.density {
            ComponentDensity::Constant(c) => c.sigma_t(),
            ComponentDensity::Field(h) => h.coefficients.sigma_t_at(h.pyramid.global_bounds().max),
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
    ray: Ray,
    density: [Option<DensityLookup<'a>>; MAX_COMPONENTS],
    emission: [Option<GridRay<'a>>; MAX_COMPONENTS],
}

impl<'a> MixRay<'a> {
    fn new(medium: &'a MixtureMedium, ray: &Ray, emission: bool) -> Self {
        let mut density: [Option<DensityLookup<'a>>; MAX_COMPONENTS] = [None, None, None, None];
        let mut em: [Option<GridRay<'a>>; MAX_COMPONENTS] = [None, None, None, None];
        for (i, c) in medium.components.iter().take(MAX_COMPONENTS).enumerate() {
            if let (ComponentDensity::Field(h), Some(slot)) = (&c.density, density.get_mut(i)) {
                *slot = Some(h.density_along(ray));
            }
            if emission {
                if let (Some(e), Some(slot)) = (&c.emission, em.get_mut(i)) {
                    *slot = Some(GridRay::new(&e.grid, ray));
                }
            }
        }
        MixRay {
            medium,
            ray: *ray,
            density,
            emission: em,
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
        for (((c, slot), lookup), sigma) in comps
            .zip(self.emission.iter_mut())
            .zip(self.density.iter_mut())
            .zip(point.sigma_t.iter_mut())
        {
            *sigma = match (&c.density, lookup) {
                (ComponentDensity::Constant(k), _) => k.sigma_t(),
                (ComponentDensity::Field(h), Some(l)) => h.coefficients.sigma_t_at(l.at(t)),
                (ComponentDensity::Field(_), None) => Rgb::ZERO,
            };
            if emission {
                if let (Some(e), Some(r)) = (&c.emission, slot.as_mut()) {
                    let le = e.at(r, t);
                    if !le.is_black() {
                        let alpha = c.albedo_at(self.ray.at(t));
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
struct MixSegments<'a> {
    streams: [Option<MediumSegments<'a>>; MAX_COMPONENTS],
    current: [Option<MajorantSegment>; MAX_COMPONENTS],
    scale: [Rgb; MAX_COMPONENTS],
    constant: Rgb,
    t: f32,
    end: f32,
}

impl<'a> MixSegments<'a> {
    fn new(medium: &'a MixtureMedium, ray: &Ray, t0: f32, t1: f32) -> Self {
        let mut streams: [Option<MediumSegments<'a>>; MAX_COMPONENTS] = [None, None, None, None];
        let mut scale = [Rgb::ZERO; MAX_COMPONENTS];
        let mut constant = Rgb::ZERO;
        for (i, c) in medium.components.iter().take(MAX_COMPONENTS).enumerate() {
            match &c.density {
                ComponentDensity::Constant(k) => constant += k.sigma_t(),
                ComponentDensity::Field(h) => {
                    if let (Some(s), Some(k)) = (streams.get_mut(i), scale.get_mut(i)) {
                        *s = Some(h.segments_along(ray, t0, t1));
                        *k = h.coefficients.sigma_t;
                    }
                }
            }
        }
        let mut current = [None; MAX_COMPONENTS];
        for (c, s) in current.iter_mut().zip(streams.iter_mut()) {
            *c = s.as_mut().and_then(Iterator::next);
        }
        MixSegments {
            streams,
            current,
            scale,
            constant,
            t: t0,
            end: t1,
        }
    }
}

impl Iterator for MixSegments<'_> {
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

impl MixtureMedium {
    /// The constant components' extinctions (zero for the fields), as a [`MixPoint`].
    fn constant_point(&self) -> MixPoint {
        let mut point = MixPoint {
            sigma_t: [Rgb::ZERO; MAX_COMPONENTS],
            count: self.components.len().min(MAX_COMPONENTS),
            emission: Rgb::ZERO,
        };
        for (c, s) in self.components.iter().zip(point.sigma_t.iter_mut()) {
            if let ComponentDensity::Constant(k) = &c.density {
                *s = k.sigma_t();
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
        self.components
            .iter()
            .fold(Rgb::ZERO, |a, c| a + c.max_sigma_t())
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
        let emits = self.emits();
        let segments = MixSegments::new(self, ray, 0.0, t_max);
        let mut state = MixRay::new(self, ray, emits);
        let probs = channel_probabilities(beta, Rgb::ONE);
        let flight = mixture_track(
            segments,
            &self.constant_point(),
            |t, e| state.at(t, e),
            |i, t, point| match (self.components.get(i), point.sigma_t.get(i)) {
                (Some(c), Some(&sigma_t)) => c.albedo_at(ray.at(t)) * sigma_t,
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
                albedo: c.albedo_at(p),
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
        let mut tr = Rgb::ONE;
        for c in &self.components {
            match &c.density {
                ComponentDensity::Constant(k) => {
                    // Guard 0·∞ (σ_t = 0 over an open interior): docs/references.md §8.
                    tr *= k
                        .sigma_t()
                        .map(|s| if s == 0.0 { 1.0 } else { (-s * t_max).exp() });
                }
                ComponentDensity::Field(h) => tr *= h.transmittance(ray, t_max, u, stats),
            }
            if tr.is_black() {
                break;
            }
        }
        tr
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
        let segs: Vec<RateSegment> = MixSegments::new(&m, &ray, 0.0, 2.0).collect();
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
        let open: Vec<RateSegment> = MixSegments::new(&m, &ray, 0.0, f32::INFINITY).collect();
        assert_eq!(open.len(), 1);
    }
}
