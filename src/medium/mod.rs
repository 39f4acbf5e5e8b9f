//! Interiors: the participating media inside objects (course notes §2.4.1), and what the
//! integrator asks of them. A medium answers two questions about a ray segment inside it: where
//! does a free flight end ([`Medium::sample_flight`], returning a [`MediumEvent`] with the
//! weight, any emission and the scattering vertex with its phase function), and how much light
//! passes ([`Medium::transmittance`]). How it answers (closed forms, delta tracking over
//! majorant segments, fibre-projected lookups through a fabric shell) stays inside.
//!
//! - [`artist`]: the artist's parameters → optical coefficients (van de Hulst inversion);
//! - [`heterogeneous`]: density fields, their segments and lookups, tracked;
//! - [`lookup`]: density lookups along a ray, one enum over the density sources;
//! - [`event`]: the event and the per-vertex phase function;
//! - [`mixture`]: several media in one object;
//! - [`grids`]: per-vertex albedo and emission grids;
//! - [`walk`]: interiors resolved once per walk (entry-projected textures, blends);
//! - [`projected`]: textured interiors read at the closest boundary point of every lookup;
//! - [`dyed`]: fabrics whose yarn colours are textured, read per walk.

pub mod artist;
pub mod dyed;
pub mod event;
pub mod grids;
pub mod heterogeneous;
pub mod lookup;
pub mod mixture;
pub mod projected;
pub mod walk;

pub use artist::{
    multiple_scattering_albedo, single_scattering_albedo_from_multiple, AlbedoMode, Coefficients,
    MAX_SINGLE_SCATTERING_ALBEDO,
};
pub use dyed::{DyedFabric, FabricInterior};
pub use event::{
    MediumEvent, PhaseDirection, PreparedPhase, ScatterVertex, VertexPhase, VertexSlots,
};
pub use grids::{AlbedoGrid, AlbedoSource, EmissionGrid, EmissionKind};
pub use heterogeneous::{
    DensityField, HeterogeneousMedium, MediumSegments, MediumSegmentsOf, MipChain, RayFootprint,
};
pub use lookup::{DensityLookup, GridLookup, LocalProbe};
pub use mixture::{
    ComponentCoefficients, ComponentDensity, ComponentTextures, FieldTextures, MixtureComponent,
    MixtureMedium, ScaledMixture, TexturedMixture, WalkCoefficients,
};
pub use projected::ProjectedMedium;
pub use walk::{EntryInterior, FieldInterior, WalkInterior, WalkLook, WalkMedium};

use crate::math::{Ray, Vec3};
use crate::phase::PhaseFunction;
use crate::spectrum::Rgb;
use crate::tracking::{BehindMode, Flight, HomogeneousFlight, TrackingStats};

/// Where next event estimation happens for paths inside an interior (notes §2.3.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NeeStrategy {
    /// Only at boundary vertices, through the (rough) boundary BSDF: for dense media (skin).
    ExitPoint,
    /// At every interior scattering vertex, with transparent shadows through the boundaries:
    /// for less dense media (liquids). Biased where the boundary refracts (notes §2.3.3).
    Interior,
    /// Exit-point NEE, plus a guided connection from every interior scattering vertex through
    /// the rough boundary to a light (docs/choosing-estimators.md, `src/integrator/connect.rs`):
    /// for dense media behind a rough dielectric lit by small lights, where the BTDF lobe
    /// makes exit-point NEE noisy. Unbiased; MIS-combined with BTDF sampling at the exit.
    ExitGuided,
    /// Manifold next event estimation (Hanika, Droske and Fascione 2015) from every interior
    /// scattering vertex through the object's smooth dielectric boundary to sphere and
    /// distant lights (`src/integrator/manifold`): for media behind a smooth refractive
    /// interface lit by small lights. Biased only by missed extra solutions and failed walks.
    Manifold,
}

/// A homogeneous scattering medium.
#[derive(Clone, Copy, Debug)]
pub struct HomogeneousMedium {
    /// Optical coefficients.
    pub coefficients: Coefficients,
    /// Phase function.
    pub phase: PhaseFunction,
}

/// An interior: what fills an object (notes §2.4.1).
#[derive(Clone, Debug)]
pub enum Medium {
    /// Absorption only (coloured glass): Beer–Lambert attenuation, no scattering.
    Absorbing {
        /// Absorption coefficient (1/length).
        sigma_a: Rgb,
    },
    /// Homogeneous scattering (most skin, water).
    Homogeneous(HomogeneousMedium),
    /// Spatially varying density (voxel data, procedural noise, fabric).
    Heterogeneous(Box<HeterogeneousMedium>),
    /// Several media in one object, or a medium with albedo or emission grids.
    Mixture(Box<MixtureMedium>),
    /// Textured parameters read at the boundary point closest to every lookup
    /// (`projection = "surface"`): RGB coefficients varying per channel, tracked.
    Projected(Box<ProjectedMedium>),
    /// A heterogeneous medium's field with one walk's coefficients (a textured `voxel` or
    /// `fbm` interior read at the entry point, docs/textures.md).
    Scaled(ScaledField),
    /// A mixture's components with one walk's coefficients (textured components read at the
    /// entry point, docs/textures.md).
    ScaledMixture(ScaledMixture),
    /// A fabric with one walk's yarn colours (a `fabric` interior with textured colours,
    /// read at the entry point, docs/textures.md).
    Dyed(DyedFabric),
}

/// A shared heterogeneous medium with other coefficients per unit density (its combined base
/// medium kept): what a walk through a textured `voxel` or `fbm` interior sees. Building one
/// shares the field (no copy, no allocation).
#[derive(Clone, Debug)]
pub struct ScaledField {
    /// The field, majorants, phase function, estimator choices and base medium.
    pub medium: std::sync::Arc<HeterogeneousMedium>,
    /// Extinction per unit density (1/length).
    pub sigma_t: Rgb,
    /// Scattering per unit density (1/length).
    pub sigma_s: Rgb,
}

impl ScaledField {
    /// The coefficients in use: these per unit density, the medium's base medium.
    #[must_use]
    pub fn coefficients(&self) -> crate::tracking::DensityCoefficients {
        let own = self.medium.coefficients;
        crate::tracking::DensityCoefficients {
            sigma_t: self.sigma_t,
            sigma_s: self.sigma_s,
            base_t: own.base_t,
            base_s: own.base_s,
        }
    }
}

impl Medium {
    /// Extinction coefficient of homogeneous media (the largest one, over the majorant, for
    /// heterogeneous media).
    #[must_use]
    pub fn sigma_t(&self) -> Rgb {
        match self {
            Medium::Absorbing { sigma_a } => *sigma_a,
            Medium::Homogeneous(h) => h.coefficients.sigma_t(),
            Medium::Heterogeneous(h) => h.coefficients.sigma_t_at(h.pyramid.global_bounds().max),
            Medium::Mixture(m) => m.max_sigma_t(),
            Medium::Projected(p) => p.sigma_t_max,
            Medium::Scaled(f) => f
                .coefficients()
                .sigma_t_at(f.medium.pyramid.global_bounds().max),
            Medium::ScaledMixture(m) => m.max_sigma_t(),
            Medium::Dyed(f) => {
                let h = &f.medium;
                h.coefficients.sigma_t_at(h.pyramid.global_bounds().max)
            }
        }
    }

    /// True when the medium can scatter light.
    #[must_use]
    pub fn scatters(&self) -> bool {
        match self {
            Medium::Absorbing { .. } => false,
            Medium::Homogeneous(h) => !h.coefficients.sigma_s.is_black(),
            Medium::Heterogeneous(h) => !h.coefficients.sigma_s.is_black(),
            Medium::Mixture(m) => m.scatters(),
            Medium::Projected(p) => p.scatters(),
            Medium::Scaled(f) => !f.sigma_s.is_black() || !f.medium.coefficients.base_s.is_black(),
            Medium::ScaledMixture(m) => m.scatters(),
            Medium::Dyed(f) => !f.medium.coefficients.sigma_s.is_black(),
        }
    }

    /// Whether a ray crossing this medium estimates the light behind it by transmittance
    /// instead of letting its path survive the free flight ([`crate::tracking::BehindMode`]):
    /// for `voxel` and `fbm` interiors (also textured ones read at the entry point) by their
    /// `tracking.behind`; never for other media.
    #[must_use]
    pub fn estimates_behind(&self) -> bool {
        match self {
            Medium::Heterogeneous(h) => h.tracking.behind == BehindMode::Transmittance,
            Medium::Scaled(f) => f.medium.tracking.behind == BehindMode::Transmittance,
            _ => false,
        }
    }

    /// Whether medium vertices with NEE also make the sun-leaned estimate of the next vertex's
    /// sun light ([`crate::tracking::TrackingConfig::sun_lean`]): for `voxel` and `fbm`
    /// interiors (also textured ones read at the entry point) by their `tracking.sun_lean`;
    /// never for other media.
    #[must_use]
    pub fn sun_lean(&self) -> bool {
        match self {
            Medium::Heterogeneous(h) => h.tracking.sun_lean,
            Medium::Scaled(f) => f.medium.tracking.sun_lean,
            _ => false,
        }
    }

    /// True when a free flight through this medium draws the same numbers and makes the same
    /// decisions before any distance `t` whether the ray ends at `t_max ≥ t` or runs on:
    /// mixtures, whose merged walk is cut at `t_max` rather than built for it (homogeneous
    /// media clip their boundary search by themselves, [`Self::sample_flight_in_cone`]).
    #[must_use]
    pub fn flight_before_boundary(&self) -> bool {
        matches!(self, Medium::Mixture(_) | Medium::ScaledMixture(_))
    }

    /// [`Self::sample_flight_in_cone`] with the random numbers drawn from a state that can be
    /// rewound (`draw(state)` returns the next uniform number in [0, 1)); the same event, and
    /// `state` left where it would be, but the boundary is searched only as far as needed also
    /// for media whose flight does not depend on where the ray ends
    /// ([`Self::flight_before_boundary`]): the flight over `[0, ∞)` is sampled first and
    /// `boundary` asked up to its collision; where the boundary comes first, `state` is
    /// rewound and the flight sampled again to the boundary from the same numbers. Costs a
    /// second flight to the boundary where the ray leaves the interior, saves searching the
    /// boundary beyond the collision where it does not (a closed mesh around a large
    /// interior: the ocean's 91,840-triangle water body).
    #[allow(clippy::too_many_arguments)]
    pub fn sample_flight_rewinding<S, D, B>(
        &self,
        ray: &Ray,
        cone: RayFootprint,
        beta: Rgb,
        state: &mut S,
        mut draw: D,
        stats: &mut TrackingStats,
        mut boundary: B,
    ) -> MediumEvent<'_>
    where
        S: Clone,
        D: FnMut(&mut S) -> f32,
        B: FnMut(f32) -> f32,
    {
        if !self.flight_before_boundary() {
            return self.sample_flight_in_cone(
                ray,
                cone,
                beta,
                &mut || draw(state),
                stats,
                boundary,
            );
        }
        let start = state.clone();
        let flight =
            self.sample_flight_in_cone(ray, cone, beta, &mut || draw(state), stats, |_| {
                f32::INFINITY
            });
        let t_collision = flight.scatter.as_ref().map_or(f32::INFINITY, |v| v.t);
        let t_boundary = boundary(t_collision);
        if !(t_boundary < t_collision) {
            return flight;
        }
        *state = start;
        self.sample_flight_in_cone(ray, cone, beta, &mut || draw(state), stats, |_| t_boundary)
    }

    /// Samples a free flight along `ray` over `[0, t_max]` (`t_max` is where the ray leaves
    /// the interior; the course notes' Algorithm 1, lines 3–11): the channel is chosen by the
    /// path throughput `beta` with one-sample MIS over channels (docs/references.md §4.6).
    /// `u()` returns uniform numbers in [0, 1); tracking counters go to `stats`.
    pub fn sample_flight<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'_> {
        self.sample_flight_to_boundary(ray, beta, u, stats, |_| t_max)
    }

    /// [`Self::sample_flight_in_cone`] with a zero footprint (the finest level of a fabric
    /// whose mip level is chosen per ray).
    pub fn sample_flight_to_boundary<U, B>(
        &self,
        ray: &Ray,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
        boundary: B,
    ) -> MediumEvent<'_>
    where
        U: FnMut() -> f32,
        B: FnMut(f32) -> f32,
    {
        self.sample_flight_in_cone(ray, RayFootprint::POINT, beta, u, stats, boundary)
    }

    /// [`Self::sample_flight`] for a ray whose boundary is not known yet: `boundary(limit)`
    /// returns the distance to where the ray leaves the interior if that is below `limit`,
    /// and ∞ otherwise. A homogeneous medium samples its distance first and asks for the
    /// boundary only up to it (in a dense medium a short ray, cheap to trace); other media ask
    /// with `limit = ∞`. `boundary` is called exactly once. `cone` is the ray's cone at
    /// its origin: it picks the mip level of a fabric that chooses its level per ray
    /// ([`MipChain`]); other media ignore it.
    pub fn sample_flight_in_cone<U, B>(
        &self,
        ray: &Ray,
        cone: RayFootprint,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
        mut boundary: B,
    ) -> MediumEvent<'_>
    where
        U: FnMut() -> f32,
        B: FnMut(f32) -> f32,
    {
        match self {
            Medium::Absorbing { .. } => {
                MediumEvent::pass(self.closed_form_transmittance(boundary(f32::INFINITY)))
            }
            Medium::Homogeneous(h) => {
                let u_channel = u();
                let u_distance = u();
                let c = &h.coefficients;
                let sigma_t = c.sigma_t();
                let flight =
                    HomogeneousFlight::sample(sigma_t, c.sigma_s, beta, u_channel, u_distance);
                match flight.resolve(boundary(flight.t)) {
                    Flight::Escape { weight } => MediumEvent::pass(weight),
                    Flight::Scatter { t, weight, .. } => MediumEvent {
                        weight,
                        emitted: Rgb::ZERO,
                        scatter: Some(ScatterVertex {
                            t,
                            p: ray.at(t),
                            albedo: c.sigma_s.safe_div(sigma_t),
                            phase: VertexPhase::Hg(&h.phase),
                        }),
                    },
                }
            }
            Medium::Heterogeneous(h) => {
                h.for_ray(ray, cone)
                    .sample_flight(ray, boundary(f32::INFINITY), beta, u, stats)
            }
            Medium::Mixture(m) => m.sample_flight(ray, boundary(f32::INFINITY), beta, u, stats),
            Medium::Projected(p) => p.sample_flight(
                ray,
                boundary(f32::INFINITY),
                p.footprint_uv(cone),
                beta,
                u,
                stats,
            ),
            Medium::Scaled(f) => {
                let c = f.coefficients();
                f.medium
                    .sample_flight_with(&c, ray, boundary(f32::INFINITY), beta, u, stats)
            }
            Medium::ScaledMixture(m) => {
                m.sample_flight(ray, boundary(f32::INFINITY), beta, u, stats)
            }
            Medium::Dyed(f) => {
                f.sample_flight_in_cone(ray, cone, boundary(f32::INFINITY), beta, u, stats)
            }
        }
    }

    /// Transmittance along `ray` over `[0, t_max]`: closed form for homogeneous interiors,
    /// the interior's transmittance estimator for heterogeneous ones.
    pub fn transmittance<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        self.transmittance_in_cone(ray, t_max, RayFootprint::POINT, u, stats)
    }

    /// [`Self::transmittance`] for a ray whose cone is `cone` at its origin (picks a per-ray
    /// fabric mip level as in [`Self::sample_flight_in_cone`]).
    pub fn transmittance_in_cone<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        cone: RayFootprint,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        match self {
            Medium::Absorbing { .. } | Medium::Homogeneous(_) => {
                self.closed_form_transmittance(t_max)
            }
            Medium::Heterogeneous(h) => h.for_ray(ray, cone).transmittance(ray, t_max, u, stats),
            Medium::Mixture(m) => m.transmittance(ray, t_max, u, stats),
            Medium::Projected(p) => p.transmittance(ray, t_max, p.footprint_uv(cone), u, stats),
            Medium::Scaled(f) => {
                f.medium
                    .transmittance_with(&f.coefficients(), ray, t_max, u, stats)
            }
            Medium::ScaledMixture(m) => m.transmittance(ray, t_max, u, stats),
            Medium::Dyed(f) => f.transmittance_in_cone(ray, t_max, cone, u, stats),
        }
    }

    /// A prediction of the transmittance (largest channel) from world point `p` inside the
    /// medium to its grid's edge along `to_light` (unit, world): exp(−σ_t⁰ · ∫d) from the
    /// grid's [`crate::grid::SunMap`] (made on the first call for the first direction asked),
    /// for `voxel` and baked `fbm` interiors on a grid without fibres or per-ray mip levels;
    /// `None` for other media and other directions. Not an estimate: used to choose
    /// probabilities (Russian roulette, the sun lean's play), where errors cost variance only.
    #[must_use]
    pub fn sun_transmittance_hint(&self, p: Vec3, to_light: Vec3) -> Option<f32> {
        let Medium::Heterogeneous(h) = self else {
            return None;
        };
        if h.fabric.is_some() || h.mips.is_some() {
            return None;
        }
        let heterogeneous::DensityField::Grid { grid, channel } = &h.field else {
            return None;
        };
        let map = grid.sun_map(*channel, to_light)?;
        Some((-h.coefficients.max_sigma_t() * map.integral(p)).exp())
    }

    /// Makes the grid's sun map ([`Self::sun_transmittance_hint`]) for direction `to_light`
    /// now, in parallel, instead of on the first shadow ray (where one render thread would make
    /// it while the others wait). Does nothing for media without one. Scene loading calls this
    /// for the interiors whose sun lean will ask for it.
    pub fn prepare_sun_map(&self, to_light: Vec3) {
        let Medium::Heterogeneous(h) = self else {
            return;
        };
        if h.fabric.is_some() || h.mips.is_some() {
            return;
        }
        if let heterogeneous::DensityField::Grid { grid, channel } = &h.field {
            let _ = grid.sun_map(*channel, to_light);
        }
    }

    /// Transmittance `exp(−σ_t d)` along a straight segment of length `d` (world units) of a
    /// homogeneous medium.
    #[must_use]
    pub fn closed_form_transmittance(&self, d: f32) -> Rgb {
        if d <= 0.0 {
            return Rgb::ONE;
        }
        // Guard 0·∞ (σ_t = 0 with an infinite segment): docs/references.md §8.
        let sigma_t = match self {
            Medium::Absorbing { sigma_a } => *sigma_a,
            Medium::Homogeneous(h) => h.coefficients.sigma_t(),
            _ => self.sigma_t(),
        };
        let e = crate::math::exp3(sigma_t.0.map(|s| -s * d));
        Rgb([0, 1, 2].map(|k| if sigma_t[k] == 0.0 { 1.0 } else { e[k] }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_transmittance_has_the_bits_of_the_c_librarys_exp() {
        let media = [
            Medium::Homogeneous(HomogeneousMedium {
                coefficients: Coefficients {
                    sigma_a: Rgb::new(0.16, 1.2, 5.4),
                    sigma_s: Rgb::new(15.84, 22.8, 30.6),
                },
                phase: PhaseFunction::HenyeyGreenstein { g: 0.0 },
            }),
            Medium::Absorbing {
                sigma_a: Rgb::new(0.0, 2.5, 90.0),
            },
        ];
        let mut n = 0;
        for m in &media {
            let sigma_t = m.sigma_t();
            for i in 0..50_000u32 {
                let d = (i as f32) * 1e-4 * (1.0 + i as f32 * 1e-3);
                let want = sigma_t.map(|s| if s == 0.0 { 1.0 } else { (-s * d).exp() });
                let got = m.closed_form_transmittance(d);
                assert_eq!(got.0.map(f32::to_bits), want.0.map(f32::to_bits), "d = {d}");
                n += 1;
            }
            // An infinite segment: 0 where σ_t > 0, 1 where σ_t = 0 (no 0·∞).
            let far = sigma_t.map(|s| if s == 0.0 { 1.0 } else { 0.0 });
            assert_eq!(m.closed_form_transmittance(f32::INFINITY), far);
        }
        assert_eq!(n, 100_000);
    }
}
