//! Fabric interiors with textured yarn colours (docs/textures.md, "Fabric yarn colours"): the
//! warp, weft and pile colours are read at the point where a walk entered the fabric's shell
//! and fixed for that walk. A fabric's colours live only in its fibre phase functions (its
//! extinction and σ_s = σ_t do not depend on them), so a walk's medium is the shared fabric —
//! field, majorants, mip levels — with the walk's three colours, which replace the phase
//! functions' own at every scattering vertex. Building one shares the fabric (no copy, no
//! allocation).

use std::sync::Arc;

use super::event::{MediumEvent, VertexPhase};
use super::walk::WalkMedium;
use super::{HeterogeneousMedium, RayFootprint};
use crate::fabric::YarnColours;
use crate::math::{Ray, Vec2};
use crate::spectrum::Rgb;
use crate::tracking::TrackingStats;

/// A `fabric` interior whose yarn colours are textured, read at the entry point.
#[derive(Clone, Debug)]
pub struct FabricInterior {
    /// The fabric (its own phase functions are those of the textures' means).
    pub medium: Arc<HeterogeneousMedium>,
    /// The warp, weft and pile colours.
    pub colours: YarnColours,
}

impl FabricInterior {
    /// The walk medium of a walk entering at texture coordinates `uv` with a footprint
    /// `width_uv` wide: the entry point itself (three numbers ride on the interior stack; the
    /// colours are read from them, always the same, when the walk's medium is made,
    /// [`Self::medium_at`]). `look` is 0 for the interior itself or a blend's `a`, 1 for `b`.
    #[must_use]
    pub fn at(&self, uv: Vec2, width_uv: f32, look: u8) -> WalkMedium {
        WalkMedium::Fabric { uv, width_uv, look }
    }

    /// The fabric with the colours read at `uv` (footprint `width_uv`).
    #[must_use]
    pub fn medium_at(&self, uv: Vec2, width_uv: f32) -> DyedFabric {
        DyedFabric {
            medium: Arc::clone(&self.medium),
            colours: self.colours.at(uv, width_uv),
        }
    }
}

/// A shared fabric with one walk's warp, weft and pile colours.
#[derive(Clone, Debug)]
pub struct DyedFabric {
    /// The fabric: field, majorants, fibre look and mip levels.
    pub medium: Arc<HeterogeneousMedium>,
    /// Warp, weft and pile colours (multiple-scattering colours of the fibres, in `[0, 1]`).
    pub colours: [Rgb; 3],
}

impl DyedFabric {
    /// A free flight in the mip level `ray`'s cone picks; a scattering vertex's fibre phase
    /// function takes the walk's colour of its yarn family.
    pub(super) fn sample_flight_in_cone<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        cone: RayFootprint,
        t_max: f32,
        beta: Rgb,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> MediumEvent<'_> {
        let mut event = self
            .medium
            .for_ray(ray, cone)
            .sample_flight(ray, t_max, beta, u, stats);
        if let Some(v) = &mut event.scatter {
            if let VertexPhase::Fibre { yarn, dye, .. } = &mut v.phase {
                *dye = self.colours.get(usize::from(*yarn)).copied();
            }
        }
        event
    }

    /// Transmittance in the mip level `ray`'s cone picks (the colours do not change it).
    pub(super) fn transmittance_in_cone<U: FnMut() -> f32>(
        &self,
        ray: &Ray,
        t_max: f32,
        cone: RayFootprint,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Rgb {
        self.medium
            .for_ray(ray, cone)
            .transmittance(ray, t_max, u, stats)
    }
}
