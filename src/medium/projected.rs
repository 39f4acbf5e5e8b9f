//! Interiors whose textured parameters are projected back to their boundary
//! (`projection = "surface"`, docs/textures.md): at every point the walk looks at (tentative
//! collisions of free flights, shadow-ray lookups, scattering vertices) the texture
//! coordinates are those of the closest point of the object's mesh, found through a BVH over
//! that mesh ([`ClosestPointMesh`]). The parameters read there are inverted like constants
//! (notes eq. 1–3), so the medium is heterogeneous with RGB coefficients that vary per
//! channel; it is tracked against one scalar majorant, the largest extinction the textures
//! allow anywhere (max density / min attenuation over all texels: conservative, never
//! violated but by rounding), with [`spectral_delta_track`] and
//! [`spectral_ratio_transmittance`].

use std::cell::Cell;

use super::artist::Coefficients;
use super::event::{MediumEvent, ScatterVertex, VertexPhase};
use super::walk::{EntryInterior, WalkMedium};
use crate::geometry::ClosestPointMesh;
use crate::math::{Ray, Vec2, Vec3};
use crate::spectrum::Rgb;
use crate::tracking::{spectral_delta_track, spectral_ratio_transmittance, Flight, TrackingStats};

/// A homogeneous or absorbing interior whose textures are read at the boundary point closest
/// to each lookup.
#[derive(Clone, Debug)]
pub struct ProjectedMedium {
    /// The textured parameters (as for `projection = "entry"`).
    pub params: EntryInterior,
    /// The object's boundary mesh in world space, with its texture coordinates.
    pub boundary: ClosestPointMesh,
    /// The largest σ_t per channel anywhere (1/length): density max / attenuation min.
    pub sigma_t_max: Rgb,
    /// The single-scattering albedo of the textures' means: picks the hero channel.
    pub mean_albedo: Rgb,
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
        ProjectedMedium {
            params,
            boundary,
            sigma_t_max,
            mean_albedo,
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
        !self.params.absorbing && !self.mean_albedo.is_black()
    }

    /// The texture coordinates of the boundary point closest to `p` (level 0 is read: the
    /// projected point has no footprint of its own).
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
    fn sigma_t_at(&self, uv: Vec2) -> Rgb {
        let density = self.params.density.eval(uv, 0.0);
        self.params.attenuation.eval(uv, 0.0).map(
            |d| {
                if d.is_infinite() {
                    0.0
                } else {
                    density / d
                }
            },
        )
    }

    /// The coefficients at texture coordinates `uv` (the artist albedo inverted there).
    #[must_use]
    pub fn coefficients_at(&self, uv: Vec2) -> Coefficients {
        match self.params.at(uv, 0.0) {
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

    /// A free flight along `ray` over `[0, t_max]`: delta tracking with the hero channel
    /// against the medium's majorant; an absorbing interior passes with the ratio-tracked
    /// transmittance.
    pub fn sample_flight<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'_> {
        if !self.scatters() {
            return MediumEvent::pass(self.transmittance(ray, t_max, u, stats));
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
                self.sigma_t_at(uv)
            },
            |_| {
                let c = self.coefficients_at(last_uv.get());
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

    /// Transmittance along `ray` over `[0, t_max]`: ratio tracking against the majorant.
    pub fn transmittance<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        let hint = Cell::new(u32::MAX);
        spectral_ratio_transmittance(
            self.majorant(),
            t_max,
            |t| self.sigma_t_at(self.uv_near(ray.at(t), &hint)),
            u,
            stats,
        )
    }
}
