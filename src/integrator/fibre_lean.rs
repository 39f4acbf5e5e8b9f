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
#[derive(Clone, Copy)]
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

/// The balance weight of the main path's direction against a lean made at its vertex, as the
/// next vertex's sun NEE takes it: known, or left to be evaluated there
/// ([`FibreLean::main_weight`] costs a fibre phase evaluation, and most of those NEE estimates
/// are 0: rouletted or shadowed, so that the weight would multiply 0).
#[derive(Clone, Copy)]
pub(super) enum LeanWeight<'a> {
    /// The weight.
    Known(f32),
    /// [`FibreLean::main_weight`]`(p, wi, play)` of `lean`, not yet evaluated.
    Deferred {
        /// The lean made at the vertex.
        lean: FibreLean<'a>,
        /// The main direction's pdf under the vertex's own lobe.
        p: f32,
        /// The main direction.
        wi: Vec3,
        /// The lean's play probability at the vertex.
        play: f32,
    },
}

impl LeanWeight<'_> {
    /// The weight (the same bits whether it was known or deferred).
    #[inline]
    pub(super) fn value(&self) -> f32 {
        match *self {
            LeanWeight::Known(w) => w,
            LeanWeight::Deferred { lean, p, wi, play } => lean.main_weight(p, wi, play),
        }
    }
}

/// Whether every fibre lean's weight is evaluated at its own vertex, as when the lean's
/// medium does not outlive the step: the tests' reference for [`LeanWeight::Deferred`].
#[cfg(test)]
pub(super) fn eager_weights() -> bool {
    tests::EAGER.with(std::cell::Cell::get)
}

/// Whether every fibre lean's weight is evaluated at its own vertex: never outside the tests.
#[cfg(not(test))]
#[inline(always)]
pub(super) const fn eager_weights() -> bool {
    false
}

#[cfg(test)]
mod tests {
    use std::cell::Cell;
    use std::path::Path;

    use crate::integrator::{trace_path, TraceStats};
    use crate::math::Vec2;
    use crate::sampling::PixelSampler;
    use crate::scene::load_scene_str;

    thread_local! {
        /// [`super::eager_weights`].
        pub(super) static EAGER: Cell<bool> = const { Cell::new(false) };
    }

    /// A free-standing twill patch under a grazing disc sun (as `tests/fibre_lean.rs`).
    const TWILL: &str = r#"
[camera]
eye = [0.2, 0.2, 1.6]
look_at = [0.2, 0.2, 0.0]
up = [0.0, 1.0, 0.0]
fov = 10
[film]
width = 12
height = 12
spp = 1
max_depth = 64
[[light]]
type = "environment"
radiance = [0.05, 0.05, 0.06]
[[light]]
type = "distant"
direction = [-0.45, -0.3, 0.6]
irradiance = [3.0, 2.9, 2.7]
angular_radius = 3.0
[[object]]
name = "twill"
shape = "bounds"
interior = { type = "fabric", pattern = "twill", yarn = "cotton1", resolution = 32, flyaways = 0, warp_albedo = [0.8, 0.2, 0.1], weft_albedo = [0.85, 0.85, 0.8], attenuation = 0.004, nee = "interior" }
"#;

    /// Every path's radiance bits, the lean weights deferred or not.
    fn radiance_bits(scene: &crate::scene::Scene, eager: bool) -> (Vec<[u32; 3]>, u64) {
        EAGER.with(|e| e.set(eager));
        let mut stats = TraceStats::default();
        let mut out = Vec::new();
        for y in 0..12 {
            for x in 0..12 {
                for s in 0..24 {
                    let mut sampler = PixelSampler::new(7, x, y, s);
                    let film = Vec2::new(x as f32, y as f32) + sampler.next_2d();
                    let lens = sampler.next_2d();
                    let ray = scene.camera.generate_ray(film, lens);
                    let r = trace_path(scene, ray, &mut sampler, &mut stats).radiance;
                    out.push([r[0].to_bits(), r[1].to_bits(), r[2].to_bits()]);
                }
            }
        }
        EAGER.with(|e| e.set(false));
        (out, stats.vertices)
    }

    /// The main direction's lean weight left to the next vertex's sun NEE (evaluated only
    /// where that estimate is not 0) gives every path the radiance, bit for bit, that the
    /// weight evaluated at its own vertex gives.
    #[test]
    fn deferred_lean_weights_give_the_eager_paths_bit_for_bit() {
        let scene = load_scene_str(TWILL, Path::new("inline.toml")).expect("scene");
        let (deferred, vertices) = radiance_bits(&scene, false);
        let (eager, eager_vertices) = radiance_bits(&scene, true);
        assert_eq!(vertices, eager_vertices);
        assert!(vertices > 5_000, "too few vertices: {vertices}");
        let lit = deferred
            .iter()
            .filter(|c| c.iter().any(|&b| b != 0))
            .count();
        assert!(lit > deferred.len() / 2, "too few lit paths: {lit}");
        assert_eq!(deferred, eager);
    }
}
