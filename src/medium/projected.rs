//! Interiors whose textured parameters are projected back to their boundary
//! (`projection = "surface"`, docs/textures.md): at every point the walk looks at (tentative
//! collisions of free flights, shadow-ray lookups, scattering vertices) the texture
//! coordinates are those of the closest point of the object's mesh, found through a BVH over
//! that mesh ([`ClosestPointMesh`]). The parameters read there are inverted like constants
//! (notes eq. 1–3), so the medium is heterogeneous with RGB coefficients that vary per
//! channel. It is tracked with [`spectral_delta_track_segments`] and
//! [`spectral_ratio_transmittance_segments`] against scalar majorants that the textures bound:
//!
//! - a homogeneous or absorbing interior: one majorant over the whole ray, the largest
//!   extinction the textures allow anywhere (max density / min attenuation over all texels);
//! - a `voxel` or `fbm` interior ([`ProjectedDensity`]): σ_t(x) = base_t + d(x)·σ_t⁰(uv(x)),
//!   with the field's density d(x) and the textures' extinction per unit density σ_t⁰ at the
//!   projected point; the majorant of each of the field's majorant segments is
//!   base_t + d_max·max σ_t⁰ (its density bound times the textures' bound).
//!
//! Both are conservative (never violated but by rounding, or where a field's estimated
//! density bounds are); violations are counted and stay unbiased (weighted tracking).

use std::cell::Cell;
use std::sync::Arc;

use super::artist::Coefficients;
use super::event::{MediumEvent, ScatterVertex, VertexPhase};
use super::heterogeneous::{HeterogeneousMedium, RayFootprint};
use super::walk::{EntryInterior, WalkMedium};
use crate::geometry::ClosestPointMesh;
use crate::math::{Ray, Vec2, Vec3};
use crate::spectrum::Rgb;
use crate::tracking::{
    spectral_delta_track, spectral_delta_track_segments, spectral_ratio_transmittance,
    spectral_ratio_transmittance_segments, DensityCoefficients, Flight, RateSegment, TrackingStats,
};

/// The density field under a surface-projected `voxel` or `fbm` interior: the textures give
/// the coefficients per unit density at the projected point, the field the density.
#[derive(Clone, Debug)]
pub struct ProjectedDensity {
    /// The field, its majorant pyramid, phase function and combined base medium
    /// (`coefficients.base_t`, `base_s`; its own per-unit-density coefficients, those of the
    /// textures' means, are not used by the projected medium).
    pub medium: Arc<HeterogeneousMedium>,
    /// The bound the majorants are made of: σ_t⁰ = the largest extinction per unit density
    /// per channel over the textures (max density / min attenuation, 1/length), and the
    /// field's base medium.
    pub bound: DensityCoefficients,
}

impl ProjectedDensity {
    /// The majorant segments of `[0, t_max]` along `ray`: the field's segments (walked at
    /// the bound's extinction), each with majorant max_c(base_t + d_max·σ_t⁰max).
    fn rate_segments<'a>(
        &'a self,
        ray: &Ray,
        t_max: f32,
    ) -> impl Iterator<Item = RateSegment> + 'a {
        let bound = self.bound;
        self.medium
            .segments_for(&bound, ray, 0.0, t_max)
            .map(move |s| RateSegment {
                t0: s.t0,
                t1: s.t1,
                majorant: bound.majorant(&s),
                varying: true,
            })
    }
}

/// What the last extinction lookup of a projected field saw: the density, the texture
/// coordinates (unset where the density is 0) and σ_t.
#[derive(Clone, Copy, Debug)]
struct FieldPoint {
    density: f32,
    uv: Vec2,
    sigma_t: Rgb,
}

/// An interior whose textures are read at the boundary point closest to each lookup: a
/// homogeneous or absorbing one, or a density field's coefficients per unit density
/// ([`ProjectedDensity`]).
#[derive(Clone, Debug)]
pub struct ProjectedMedium {
    /// The textured parameters (as for `projection = "entry"`; over a density field they are
    /// per unit density).
    pub params: EntryInterior,
    /// The object's boundary mesh in world space, with its texture coordinates.
    pub boundary: ClosestPointMesh,
    /// The largest σ_t per channel anywhere (1/length): density max / attenuation min (over
    /// a density field: times the field's largest density, plus its base medium).
    pub sigma_t_max: Rgb,
    /// The single-scattering albedo of the textures' means: picks the hero channel.
    pub mean_albedo: Rgb,
    /// The density field of a `voxel` or `fbm` interior (`None`: homogeneous or absorbing).
    pub field: Option<ProjectedDensity>,
    /// The boundary's mean texture scale (texture units per world unit): turns a ray cone's
    /// width into the footprint the textures are filtered with (0 reads level 0).
    pub uv_scale: f32,
}

impl ProjectedMedium {
    /// The medium of `params` projected onto `boundary`: its bound on σ_t from the textures'
    /// extremes, and its mean albedo.
    #[must_use]
    pub fn new(params: EntryInterior, boundary: ClosestPointMesh) -> Self {
        let density_max = params.density.max();
        let sigma_t_max = params.attenuation.min().map(|d| {
            if d.is_infinite() {
                0.0
            } else {
                density_max / d
            }
        });
        let mean_albedo = match params.at(Vec2::ZERO, f32::INFINITY) {
            WalkMedium::Homogeneous { coefficients, .. } => {
                coefficients.sigma_s.safe_div(coefficients.sigma_t())
            }
            _ => Rgb::ZERO,
        };
        let uv_scale = boundary.mean_uv_scale();
        ProjectedMedium {
            params,
            boundary,
            sigma_t_max,
            mean_albedo,
            field: None,
            uv_scale,
        }
    }

    /// The medium of a `voxel` or `fbm` interior `medium` whose coefficients per unit density
    /// are `params` (not absorbing; its phase function is the field's) read at the closest
    /// point of `boundary`: the bound of its majorants is the textures' largest extinction
    /// per unit density with the field's base medium.
    #[must_use]
    pub fn over_field(
        params: EntryInterior,
        boundary: ClosestPointMesh,
        medium: Arc<HeterogeneousMedium>,
    ) -> Self {
        let unit = ProjectedMedium::new(params, boundary);
        let own = medium.coefficients;
        let bound = DensityCoefficients {
            sigma_t: unit.sigma_t_max,
            sigma_s: Rgb::ZERO,
            base_t: own.base_t,
            base_s: own.base_s,
        };
        ProjectedMedium {
            sigma_t_max: bound.sigma_t_at(medium.pyramid.global_bounds().max),
            field: Some(ProjectedDensity { medium, bound }),
            ..unit
        }
    }

    /// The scalar majorant: the largest σ_t of any channel anywhere.
    #[must_use]
    pub fn majorant(&self) -> f32 {
        self.sigma_t_max.max_component()
    }

    /// True when the medium scatters (not an `absorption` interior).
    #[must_use]
    pub fn scatters(&self) -> bool {
        let base = self
            .field
            .as_ref()
            .is_some_and(|f| !f.bound.base_s.is_black());
        !self.params.absorbing && (!self.mean_albedo.is_black() || base)
    }

    /// The footprint (texture units) the textures are read with along a ray whose cone is
    /// `cone` at its origin: the cone's width there times the boundary's mean texture scale.
    /// Inside the object a ray starts at the entry point or at a scattering vertex, so this
    /// is the entry point's footprint for the first flight and the widened cone's after
    /// scattering (docs/textures.md). Mip levels average texels, so the majorant (the
    /// finest level's extremes) stays conservative at every level.
    #[inline]
    #[must_use]
    pub fn footprint_uv(&self, cone: RayFootprint) -> f32 {
        (cone.width * self.uv_scale).max(0.0)
    }

    /// The texture coordinates of the boundary point closest to `p`.
    #[inline]
    #[must_use]
    pub fn uv_at(&self, p: Vec3) -> Vec2 {
        self.boundary.nearest(p).map_or(Vec2::ZERO, |n| n.uv)
    }

    /// [`Self::uv_at`] for successive points of one ray: `hint` carries the last answer's
    /// triangle ([`ClosestPointMesh::nearest_from`]).
    #[inline]
    fn uv_near(&self, p: Vec3, hint: &Cell<u32>) -> Vec2 {
        let mut h = hint.get();
        let uv = self
            .boundary
            .nearest_from(p, &mut h)
            .map_or(Vec2::ZERO, |n| n.uv);
        hint.set(h);
        uv
    }

    /// σ_t at texture coordinates `uv` (density / attenuation per channel).
    #[inline]
    fn sigma_t_at(&self, uv: Vec2, width_uv: f32) -> Rgb {
        let density = self.params.density.eval(uv, width_uv);
        self.params.attenuation.eval(uv, width_uv).map(|d| {
            if d.is_infinite() {
                0.0
            } else {
                density / d
            }
        })
    }

    /// The coefficients at texture coordinates `uv`, read with a footprint `width_uv` wide
    /// (texture units; the artist albedo inverted there).
    #[must_use]
    pub fn coefficients_at(&self, uv: Vec2, width_uv: f32) -> Coefficients {
        match self.params.at(uv, width_uv) {
            WalkMedium::Homogeneous { coefficients, .. } => coefficients,
            WalkMedium::Absorbing(sigma_a) => Coefficients {
                sigma_a,
                sigma_s: Rgb::ZERO,
            },
            WalkMedium::Scene(_)
            | WalkMedium::Field { .. }
            | WalkMedium::EntryPoint { .. }
            | WalkMedium::Fabric { .. } => Coefficients {
                sigma_a: Rgb::ZERO,
                sigma_s: Rgb::ZERO,
            },
        }
    }

    /// A free flight along `ray` over `[0, t_max]`, the textures read with a footprint
    /// `width_uv` wide ([`Self::footprint_uv`]): delta tracking with the hero channel
    /// against the medium's majorant; an absorbing interior passes with the ratio-tracked
    /// transmittance.
    pub fn sample_flight<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        width_uv: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'_> {
        if !self.scatters() {
            return MediumEvent::pass(self.transmittance(ray, t_max, width_uv, u, stats));
        }
        if let Some(field) = &self.field {
            return self.field_flight(field, ray, t_max, width_uv, beta, u, stats);
        }
        // The uv of the last σ_t lookup: σ_s is asked for at the same point.
        let last_uv = Cell::new(Vec2::ZERO);
        let scattered = Cell::new(Rgb::ZERO);
        let hint = Cell::new(u32::MAX);
        let flight = spectral_delta_track(
            self.majorant(),
            t_max,
            |t| {
                let uv = self.uv_near(ray.at(t), &hint);
                last_uv.set(uv);
                self.sigma_t_at(uv, width_uv)
            },
            |_| {
                let c = self.coefficients_at(last_uv.get(), width_uv);
                scattered.set(c.sigma_s.safe_div(c.sigma_t()));
                c.sigma_s
            },
            self.mean_albedo,
            beta,
            u,
            stats,
        );
        match flight {
            Flight::Escape { weight } => MediumEvent::pass(weight),
            Flight::Scatter { t, weight, .. } => MediumEvent {
                weight,
                emitted: Rgb::ZERO,
                scatter: Some(ScatterVertex {
                    t,
                    p: ray.at(t),
                    albedo: scattered.get(),
                    phase: VertexPhase::Hg(&self.params.phase),
                }),
            },
        }
    }

    /// Transmittance along `ray` over `[0, t_max]`, the textures read with a footprint
    /// `width_uv` wide: ratio tracking against the majorant.
    pub fn transmittance<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        width_uv: f32,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        let hint = Cell::new(u32::MAX);
        if let Some(field) = &self.field {
            let mut lookup = field.medium.density_along(ray);
            let last = Cell::new(FieldPoint::EMPTY);
            return spectral_ratio_transmittance_segments(
                field.rate_segments(ray, t_max),
                |t| self.field_sigma_t(field, lookup.at(t), ray.at(t), width_uv, &hint, &last),
                u,
                stats,
            );
        }
        spectral_ratio_transmittance(
            self.majorant(),
            t_max,
            |t| self.sigma_t_at(self.uv_near(ray.at(t), &hint), width_uv),
            u,
            stats,
        )
    }

    /// σ_t of a projected field at point `p` where the field's density is `density`: the
    /// base medium plus the density times σ_t⁰ at the projected point (no projection where
    /// the density is 0). What it saw goes to `last`.
    #[inline]
    fn field_sigma_t(
        &self,
        field: &ProjectedDensity,
        density: f32,
        p: Vec3,
        width_uv: f32,
        hint: &Cell<u32>,
        last: &Cell<FieldPoint>,
    ) -> Rgb {
        let base = field.bound.base_t;
        if density == 0.0 {
            last.set(FieldPoint {
                density,
                uv: Vec2::ZERO,
                sigma_t: base,
            });
            return base;
        }
        let uv = self.uv_near(p, hint);
        let sigma_t = base + self.sigma_t_at(uv, width_uv) * density;
        last.set(FieldPoint {
            density,
            uv,
            sigma_t,
        });
        sigma_t
    }

    /// σ_s of a projected field at the point `last` describes: the base medium plus the
    /// density times σ_s⁰ at the projected point.
    fn field_sigma_s(&self, field: &ProjectedDensity, last: FieldPoint, width_uv: f32) -> Rgb {
        let base = field.bound.base_s;
        if last.density == 0.0 {
            return base;
        }
        base + self.coefficients_at(last.uv, width_uv).sigma_s * last.density
    }

    /// A free flight through a projected field: spectral delta tracking over the field's
    /// majorant segments.
    // The field, the ray and its clip, the footprint, the throughput, the numbers and the
    // counters: the flight's inputs, each used once.
    #[allow(clippy::too_many_arguments)]
    fn field_flight<'a, U: FnMut() -> f32>(
        &'a self,
        field: &'a ProjectedDensity,
        ray: &Ray,
        t_max: f32,
        width_uv: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'a> {
        let hint = Cell::new(u32::MAX);
        let last = Cell::new(FieldPoint::EMPTY);
        let scattered = Cell::new(Rgb::ZERO);
        let mut lookup = field.medium.density_along(ray);
        let flight = spectral_delta_track_segments(
            field.rate_segments(ray, t_max),
            |t| self.field_sigma_t(field, lookup.at(t), ray.at(t), width_uv, &hint, &last),
            |_| {
                let at = last.get();
                let sigma_s = self.field_sigma_s(field, at, width_uv);
                scattered.set(sigma_s.safe_div(at.sigma_t));
                sigma_s
            },
            self.mean_albedo,
            beta,
            u,
            stats,
        );
        match flight {
            Flight::Escape { weight } => MediumEvent::pass(weight),
            Flight::Scatter { t, weight, .. } => {
                let p = ray.at(t);
                MediumEvent {
                    weight,
                    emitted: Rgb::ZERO,
                    scatter: Some(ScatterVertex {
                        t,
                        p,
                        albedo: scattered.get(),
                        phase: field.medium.phase_at(p),
                    }),
                }
            }
        }
    }
}

impl FieldPoint {
    /// Nothing seen yet.
    const EMPTY: FieldPoint = FieldPoint {
        density: 0.0,
        uv: Vec2::ZERO,
        sigma_t: Rgb::ZERO,
    };
}
