//! The sun lean for fibre vertices: the fabric counterpart of [`super::direct::SunLean`].
//!
//! At a fibre vertex inside a fabric the sun's next event estimate at the path's *next* vertex
//! is large only where the direction between the two vertices lies on that vertex's narrow
//! fibre cone around the sun; the path's own lobe, centred on where the path came from,
//! rarely picks such a direction. So at each fibre vertex one more direction is drawn from
//! the vertex's yarn family's fibre phase function prepared for the outgoing direction −sun
//! (the sun's light arriving along its own direction), around the vertex's tangent quantised
//! to a grid cell ([`FibrePhase::quantised_lobe`], prepared once per cell, not per vertex). The fibre phase function is reciprocal and,
//! across the fibre's two ends, nearly symmetric under reversing both directions, so that
//! lobe follows the sun term of a next vertex whose fibre runs alike. The drawn direction is
//! followed by a free flight and, where it collides, the sun's NEE there is added. That
//! estimate and the path's own sun NEE at its next vertex (reached without a boundary) are
//! combined with the balance heuristic over the direction between the two vertices
//! (Veach 1997, §9.2), with the lean's pdf weighed by its play probability P as in
//! [`super::direct::SunLean`]. Unbiased for any lobe whose pdf is evaluated exactly; unlike
//! the Henyey–Greenstein lean it also serves disc suns (the NEE at either vertex samples the
//! disc; the lobe is centred on the disc's centre).

use crate::fabric::{FibrePhase, PreparedFibre};
use crate::light::Light;
use crate::math::Vec3;
use crate::medium::{PreparedPhase, VertexPhase};
use crate::sampling::PixelSampler;
use crate::scene::Scene;
use crate::spectrum::Rgb;

/// The fibre lean at one vertex: the light it leans towards and the vertex's phase function
/// prepared for the outgoing direction −sun around the vertex's quantised tangent.
pub(super) struct FibreLean<'a> {
    /// The sun's index in the scene.
    pub light: usize,
    /// The vertex's yarn family's fibre phase function.
    phase: &'a FibrePhase,
    /// Its lobe with outgoing direction −sun ([`FibrePhase::quantised_lobe`]: the tangent's
    /// cell, the family's own colour), shared by every vertex of that cell.
    lobe: &'a PreparedFibre,
}

/// The lean's play probability per unit of the vertex's sun transmittance estimate
/// ([`FibreLean::play_probability`]): chosen on `scenes/draped_cloth.toml` (docs/BENCHMARKS.md,
/// "draped_cloth: the sun lean at fibre vertices").
const FIBRE_LEAN_PLAY_PER_TRANSMITTANCE: f32 = 2.0;

/// The lean's smallest play probability ([`FibreLean::play_probability`]).
const FIBRE_LEAN_PLAY_FLOOR: f32 = 0.1;

impl<'a> FibreLean<'a> {
    /// The lean at a vertex whose phase function is `phase`: `None` unless it is a fibre
    /// phase function and the scene has a distant light.
    pub(super) fn at_vertex(scene: &Scene, phase: &VertexPhase<'a>) -> Option<FibreLean<'a>> {
        let VertexPhase::Fibre { phase, tangent, .. } = *phase else {
            return None;
        };
        let light = scene.brightest_sun?;
        let Some(Light::Distant { to_light, .. }) = scene.lights.get(light) else {
            return None;
        };
        Some(FibreLean {
            light,
            phase,
            lobe: phase.quantised_lobe(-*to_light, tangent)?,
        })
    }

    /// The probability with which the lean is played at a vertex whose own sun NEE estimated
    /// the transmittance to the sun as `seen` (its largest channel; `None` when that NEE
    /// picked another light): `FIBRE_LEAN_PLAY_PER_TRANSMITTANCE · seen` clamped to
    /// [`FIBRE_LEAN_PLAY_FLOOR`, 1], and 1 for `None`; as [`super::direct::SunLean`]'s, with
    /// the constants chosen on the draped cloth.
    #[inline]
    pub(super) fn play_probability(&self, seen: Option<f32>) -> f32 {
        match seen {
            Some(t) => (t * FIBRE_LEAN_PLAY_PER_TRANSMITTANCE).clamp(FIBRE_LEAN_PLAY_FLOOR, 1.0),
            None => 1.0,
        }
    }

    /// Balance weight p/(p + P·q) of the main path's direction `wi`, drawn with pdf `p` by the
    /// vertex's own lobe, where the lean was played with probability `play` = P.
    #[inline]
    pub(super) fn main_weight(&self, p: f32, wi: Vec3, play: f32) -> f32 {
        let q = play * self.phase.eval_pdf_prepared(self.lobe, wi).1;
        if p + q > 0.0 && q.is_finite() {
            p / (p + q)
        } else {
            1.0
        }
    }

    /// Draws the leaned direction, `main` being the vertex's own prepared phase function
    /// (outgoing direction towards where the path came from) and `play` = P the lean's play
    /// probability: returns (direction, main phase value / q, balance weight P·q/(p + P·q)),
    /// or `None` for a failed sample or a zero pdf (the caller divides by P).
    pub(super) fn sample(
        &self,
        main: &PreparedPhase<'_>,
        play: f32,
        sampler: &mut PixelSampler,
    ) -> Option<(Vec3, Rgb, f32)> {
        let u = [
            sampler.next_1d(),
            sampler.next_1d(),
            sampler.next_1d(),
            sampler.next_1d(),
        ];
        let s = self.phase.sample_prepared(self.lobe, u)?;
        let q = s.pdf;
        let (value, p) = main.eval(s.wi);
        (q > 0.0 && q.is_finite()).then(|| (s.wi, value * (1.0 / q), play * q / (p + play * q)))
    }
}
