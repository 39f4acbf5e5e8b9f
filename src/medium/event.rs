//! What a free flight through an interior returns to the integrator: the throughput weight
//! of the flight, any radiance the medium emitted along it, and, where the flight ended in a
//! real collision, the scattering vertex with its albedo and the phase function chosen there.

use crate::fabric::{FibreColour, FibrePhase, PreparedFibre};
use crate::math::Vec3;
use crate::phase::PhaseFunction;
use crate::sampling::PixelSampler;
use crate::spectrum::Rgb;

/// The outcome of [`super::Medium::sample_flight`].
#[derive(Clone, Copy)]
pub struct MediumEvent<'a> {
    /// Throughput factor of the flight: transmittance over the sampling probability up to
    /// the vertex, and σ_s over the collision probability at it (or up to `t_max` when the
    /// flight passed). Multiply the path throughput by it.
    pub weight: Rgb,
    /// Radiance the medium emitted towards the ray origin along the flight, already divided
    /// by the flight's sampling probabilities: add `throughput before the flight × emitted`.
    /// Zero for media that do not emit (all but those with emission or temperature grids).
    pub emitted: Rgb,
    /// The real collision the flight ended at, or `None` when it passed `t_max`.
    pub scatter: Option<ScatterVertex<'a>>,
}

impl MediumEvent<'_> {
    /// A flight that passed `t_max` with throughput factor `weight`.
    #[must_use]
    pub fn pass(weight: Rgb) -> Self {
        MediumEvent {
            weight,
            emitted: Rgb::ZERO,
            scatter: None,
        }
    }
}

/// A real scattering vertex inside a medium.
#[derive(Clone, Copy)]
pub struct ScatterVertex<'a> {
    /// Distance along the ray (world units).
    pub t: f32,
    /// The vertex (world space).
    pub p: Vec3,
    /// Single-scattering albedo σ_s/σ_t at the vertex (for AOVs and albedo-driven choices).
    pub albedo: Rgb,
    /// The phase function at the vertex.
    pub phase: VertexPhase<'a>,
}

/// The phase function chosen at one scattering vertex.
#[derive(Clone, Copy)]
pub enum VertexPhase<'a> {
    /// Henyey–Greenstein (single or double).
    Hg(&'a PhaseFunction),
    /// A fibre phase function around a world-space fibre tangent (voxelised fabric).
    Fibre {
        /// The yarn family's phase function.
        phase: &'a FibrePhase,
        /// Unit fibre tangent (world space).
        tangent: Vec3,
        /// The yarn family: 0 warp, 1 weft, 2 pile.
        yarn: u8,
        /// The walk's colour of this yarn when the fabric's colours are textured (read at
        /// the entry point, docs/textures.md): the phase function is evaluated for that
        /// colour ([`FibrePhase::prepare_coloured`]); `None` for its own.
        dye: Option<Rgb>,
    },
}

/// Makes `slot` the prepared fibre vertex of `phase` for `wo` around `tangent`, in the walk's
/// colour `dye` when there is one.
fn prepare_fibre(
    slot: &mut PreparedFibre,
    phase: &FibrePhase,
    wo: Vec3,
    tangent: Vec3,
    dye: Option<Rgb>,
) {
    match dye {
        None => phase.prepare_into(slot, wo, tangent),
        Some(c) => phase.prepare_coloured_into(
            slot,
            wo,
            tangent,
            &FibreColour::new(c, phase.params().beta_n),
        ),
    }
}

/// Storage for the prepared fibre vertices of one path ([`VertexPhase::prepare`]): the path's
/// own scattering vertex and the next vertex a sun lean's flight finds. Kept across the path's
/// vertices, each slot's node table is made (and cleared) at its first fibre vertex and then
/// refilled in place ([`FibrePhase::prepare_into`]).
#[derive(Debug)]
pub struct VertexSlots {
    /// For the path's scattering vertex.
    pub vertex: PreparedFibre,
    /// For the vertex a lean's flight scatters at.
    pub lean: PreparedFibre,
}

impl VertexSlots {
    /// Two empty slots ([`PreparedFibre::empty`]).
    #[must_use]
    pub fn new() -> Self {
        VertexSlots {
            vertex: PreparedFibre::empty(),
            lean: PreparedFibre::empty(),
        }
    }
}

impl Default for VertexSlots {
    fn default() -> Self {
        Self::new()
    }
}

/// A direction sampled from a [`VertexPhase`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseDirection {
    /// Unit direction, pointing away from the vertex (the new propagation direction).
    pub wi: Vec3,
    /// Phase value over pdf (RGB).
    pub weight: Rgb,
    /// Solid-angle pdf of `wi`.
    pub pdf: f32,
}

impl<'a> VertexPhase<'a> {
    /// Value (RGB, 1/sr) and solid-angle pdf of scattering `wo → wi` (both pointing away).
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> (Rgb, f32) {
        match self {
            VertexPhase::Hg(p) => (Rgb::splat(p.eval(wo, wi)), p.pdf(wo, wi)),
            VertexPhase::Fibre {
                phase,
                tangent,
                dye,
                ..
            } => {
                let mut slot = PreparedFibre::empty();
                prepare_fibre(&mut slot, phase, wo, *tangent, *dye);
                phase.eval_pdf_prepared(&slot, wi)
            }
        }
    }

    /// Fixes the outgoing direction `wo` of this vertex: what every evaluation and the sample
    /// there share is computed once (the fibre phase function's per-offset lobe terms).
    /// Results are bit-identical to [`VertexPhase::eval`] and [`VertexPhase::sample`]. A fibre
    /// vertex's terms are made in `slot`, storage the caller owns (a fresh
    /// [`PreparedFibre::empty()`] or an earlier vertex's), which the result borrows: the
    /// vertex (up to 2.6 KiB) is then never copied, whatever the compiler inlines. An
    /// Henyey–Greenstein vertex leaves `slot` as it is.
    #[must_use]
    pub fn prepare<'s>(&self, wo: Vec3, slot: &'s mut PreparedFibre) -> PreparedPhase<'s>
    where
        'a: 's,
    {
        match *self {
            VertexPhase::Hg(p) => PreparedPhase::Hg { phase: p, wo },
            VertexPhase::Fibre {
                phase,
                tangent,
                dye,
                ..
            } => {
                prepare_fibre(slot, phase, wo, tangent, dye);
                PreparedPhase::Fibre {
                    phase,
                    prepared: slot,
                }
            }
        }
    }

    /// Samples a direction (`None` when the sample failed or has zero pdf).
    pub fn sample(&self, wo: Vec3, sampler: &mut PixelSampler) -> Option<PhaseDirection> {
        match self {
            VertexPhase::Hg(p) => {
                let s = p.sample(wo, sampler.next_2d());
                // The value is the pdf, finite (HG's value is 0 where not finite): a positive
                // pdf divided by itself is exactly 1.
                (s.pdf > 0.0).then_some(PhaseDirection {
                    wi: s.wi,
                    weight: Rgb::ONE,
                    pdf: s.pdf,
                })
            }
            VertexPhase::Fibre {
                phase,
                tangent,
                dye,
                ..
            } => {
                let u = [
                    sampler.next_1d(),
                    sampler.next_1d(),
                    sampler.next_1d(),
                    sampler.next_1d(),
                ];
                let mut slot = PreparedFibre::empty();
                prepare_fibre(&mut slot, phase, wo, *tangent, *dye);
                let s = phase.sample_prepared(&slot, u)?;
                (s.pdf > 0.0).then_some(PhaseDirection {
                    wi: s.wi,
                    weight: s.weight,
                    pdf: s.pdf,
                })
            }
        }
    }
}

/// A [`VertexPhase`] with its outgoing direction fixed ([`VertexPhase::prepare`]); a fibre
/// vertex's terms are borrowed from the caller's slot.
#[derive(Clone, Copy, Debug)]
pub enum PreparedPhase<'a> {
    /// Henyey–Greenstein (nothing to precompute).
    Hg {
        /// The phase function.
        phase: &'a PhaseFunction,
        /// Outgoing direction (pointing away).
        wo: Vec3,
    },
    /// A fibre phase function with its per-vertex terms.
    Fibre {
        /// The yarn family's phase function.
        phase: &'a FibrePhase,
        /// Frame, outgoing angles and per-offset terms of this vertex (in the caller's slot).
        prepared: &'a PreparedFibre,
    },
}

impl PreparedPhase<'_> {
    /// Value (RGB, 1/sr) and solid-angle pdf of scattering towards `wi` (pointing away).
    #[must_use]
    pub fn eval(&self, wi: Vec3) -> (Rgb, f32) {
        match self {
            PreparedPhase::Hg { phase, wo } => {
                (Rgb::splat(phase.eval(*wo, wi)), phase.pdf(*wo, wi))
            }
            PreparedPhase::Fibre { phase, prepared } => phase.eval_pdf_prepared(prepared, wi),
        }
    }

    /// Samples a direction (`None` when the sample failed or has zero pdf); the same random
    /// numbers and results as [`VertexPhase::sample`].
    pub fn sample(&self, sampler: &mut PixelSampler) -> Option<PhaseDirection> {
        match self {
            PreparedPhase::Hg { phase, wo } => VertexPhase::Hg(phase).sample(*wo, sampler),
            PreparedPhase::Fibre { phase, prepared } => {
                let u = [
                    sampler.next_1d(),
                    sampler.next_1d(),
                    sampler.next_1d(),
                    sampler.next_1d(),
                ];
                let s = phase.sample_prepared(prepared, u)?;
                (s.pdf > 0.0).then_some(PhaseDirection {
                    wi: s.wi,
                    weight: s.weight,
                    pdf: s.pdf,
                })
            }
        }
    }
}
