//! Distance sampling and transmittance estimation through participating media, all driven
//! by one stream of piecewise-constant majorant segments (docs/references.md §4; course notes
//! §2.2.2–2.2.4).
//!
//! The heterogeneous media handled here have extinction and scattering proportional to a
//! scalar density: σ_t(x) = d(x)·σ_t^0 and σ_s(x) = d(x)·σ_s^0 (RGB per unit density), plus an
//! optional constant part — the notes' "voxelised" and "heterogeneous scattering" interiors.
//! A [`MajorantSegment`] `[t0, t1]` carries bounds on the *density* (`min ≤ d ≤ max`), so one
//! segment stream serves every channel. The estimators know nothing of where densities come
//! from: they take the segments and a `density(t)` lookup.
//!
//! Estimators:
//! - [`sample_homogeneous`]: closed-form free flights through a homogeneous medium, the
//!   channel chosen by throughput with one-sample MIS over channels (docs/references.md §4.6;
//!   [`channel_probabilities`], [`pick_channel`]);
//! - [`delta_track`]: free-flight sampling (Woodcock 1965) with the same channel choice,
//!   written as weighted null-collision tracking so that it stays unbiased where a bound is
//!   violated (segments of proven constant density are sampled in closed form, without
//!   lookups);
//! - [`transmittance`] with [`TransmittanceMode::Ratio`] (Cramer 1978; Novák et al. 2014),
//!   [`TransmittanceMode::ResidualRatio`] (Novák, Selle, Jarosz 2014) with a per-segment
//!   control density, and [`TransmittanceMode::RayMarch`] (the biased fixed-step baseline);
//! - [`ray_march_free_flight`]: the biased fixed-step free-flight baseline;
//! - [`spectral_delta_track`], [`spectral_ratio_transmittance`]: the same two questions for
//!   media whose RGB coefficients vary per channel independently (surface-projected textures),
//!   against one scalar majorant per segment.

mod channels;
mod delta;
mod grey;
mod homogeneous;
mod march;
mod march_estimators;
mod mixture;
mod ratio;
mod spectral;
mod split;
#[cfg(test)]
mod test_support;

pub use channels::{channel_probabilities, pick_channel};
pub use delta::{decomposition_track, decomposition_track_local, delta_track, delta_track_local};
pub use homogeneous::{sample_homogeneous, HomogeneousFlight};
pub use march::ray_march_free_flight;
pub use march_estimators::{
    comb_teeth, jackknife_segment, order_survival, unbiased_ray_march_segment, URM_MAX_ORDER,
};
pub use mixture::{mixture_track, MixFlight, MixPoint, RateSegment, MAX_COMPONENTS};
pub use ratio::{transmittance, transmittance_local};
pub use spectral::{
    spectral_delta_track, spectral_delta_track_segments, spectral_ratio_transmittance,
    spectral_ratio_transmittance_segments, SPECTRAL_MAX_STEPS,
};
pub use split::{split_flight, SPLIT_MIN_SCATTER};

use crate::majorant::{MajorantMode, MajorantSegment};
use crate::spectrum::Rgb;

/// Optical coefficients: σ_t(x) = base_t + d(x)·σ_t⁰ and σ_s(x) = base_s + d(x)·σ_s⁰. The
/// constant part is a homogeneous medium the density field is added to (the notes' combined
/// interiors, §2.4.1: a homogeneous ocean with voxel foam); it is zero for plain voxel media.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DensityCoefficients {
    /// Extinction per unit density (1/length).
    pub sigma_t: Rgb,
    /// Scattering per unit density (1/length).
    pub sigma_s: Rgb,
    /// Constant extinction added everywhere on the ray (1/length).
    pub base_t: Rgb,
    /// Constant scattering added everywhere on the ray (1/length).
    pub base_s: Rgb,
}

impl DensityCoefficients {
    /// Coefficients proportional to the density, without a constant part.
    #[must_use]
    pub fn new(sigma_t: Rgb, sigma_s: Rgb) -> Self {
        DensityCoefficients {
            sigma_t,
            sigma_s,
            base_t: Rgb::ZERO,
            base_s: Rgb::ZERO,
        }
    }
    /// The largest channel of σ_t⁰.
    #[must_use]
    pub fn max_sigma_t(&self) -> f32 {
        self.sigma_t.max_component()
    }
    /// σ_t at density `d`.
    #[must_use]
    pub fn sigma_t_at(&self, d: f32) -> Rgb {
        self.base_t + self.sigma_t * d
    }
    /// σ_s at density `d`.
    #[must_use]
    pub fn sigma_s_at(&self, d: f32) -> Rgb {
        self.base_s + self.sigma_s * d
    }
    /// The scalar majorant of a segment: max over channels of σ_t at the segment's max density.
    #[must_use]
    pub fn majorant(&self, seg: &MajorantSegment) -> f32 {
        self.sigma_t_at(seg.max).max_component()
    }
    /// True when nothing attenuates on the segment.
    #[must_use]
    pub fn is_void(&self, seg: &MajorantSegment) -> bool {
        seg.max <= 0.0 && seg.min >= 0.0 && self.base_t.is_black()
    }
}

/// Bounds on the density at a point of the ray that are cheaper than a lookup and usually
/// tighter than the segment's (a table read: `majorant::LocalBounds`). The trackers decide
/// most tentative collisions from them without a lookup (docs/references.md §4.10).
pub trait PointBounds {
    /// `(min, max)` of every density a lookup at distance `t` can return, or `None` when
    /// unknown (the segment's bounds then apply).
    fn at(&mut self, t: f32) -> Option<(f32, f32)>;

    /// [`Self::at`], unless a coarser proven upper bound `ub` on every density a lookup at `t`
    /// can return, cheaper to read than the bounds themselves, already satisfies `skip(ub)`:
    /// then [`Probe::Skipped`] without reading the finer bounds. The default has no coarser
    /// bound and reads [`Self::at`].
    #[inline(always)]
    fn probe(&mut self, t: f32, skip: impl FnOnce(f32) -> bool) -> Probe {
        let _ = skip;
        Probe::from_bounds(self.at(t))
    }

    /// True when the minima [`Self::at`] returns are proven: no lookup at that distance
    /// returns less. The trackers then decide tentative collisions below them without a
    /// lookup where that leaves the estimator unchanged (grey media of one albedo).
    fn proven_minorant(&self) -> bool {
        false
    }
}

/// What [`PointBounds::probe`] found at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Probe {
    /// No bounds at the point (the segment's apply).
    Unknown,
    /// A coarser upper bound satisfied the caller's test; the finer bounds were not read.
    Skipped,
    /// The point's `(min, max)`, as [`PointBounds::at`] returns them.
    Bounds(f32, f32),
}

impl Probe {
    /// [`Probe::Bounds`] or [`Probe::Unknown`].
    #[inline(always)]
    #[must_use]
    pub fn from_bounds(b: Option<(f32, f32)>) -> Self {
        match b {
            Some((lo, hi)) => Probe::Bounds(lo, hi),
            None => Probe::Unknown,
        }
    }
}

/// Point bounds lent to a tracker: the same answers as the bounds themselves, without
/// moving them into the tracker (a move copies the probe through memory).
impl<P: PointBounds + ?Sized> PointBounds for &mut P {
    #[inline(always)]
    fn at(&mut self, t: f32) -> Option<(f32, f32)> {
        (**self).at(t)
    }

    #[inline(always)]
    fn probe(&mut self, t: f32, skip: impl FnOnce(f32) -> bool) -> Probe {
        (**self).probe(t, skip)
    }

    #[inline(always)]
    fn proven_minorant(&self) -> bool {
        (**self).proven_minorant()
    }
}

/// No point bounds: the trackers use the segments' bounds alone.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoPointBounds;

impl PointBounds for NoPointBounds {
    #[inline(always)]
    fn at(&mut self, _t: f32) -> Option<(f32, f32)> {
        None
    }
}

/// Counters for the speed/accuracy measurements.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TrackingStats {
    /// Density lookups while sampling free-flight distances.
    pub lookups: u64,
    /// Density lookups while estimating transmittance (shadow rays).
    pub transmittance_lookups: u64,
    /// Real (scattering) collisions.
    pub real_collisions: u64,
    /// Null collisions.
    pub null_collisions: u64,
    /// Lookups whose density exceeded the segment's majorant or fell below its minorant.
    pub violations: u64,
    /// Segments visited.
    pub segments: u64,
    /// Tentative collisions (free flights and transmittance) rejected without a density
    /// lookup because they lie above the local majorant of their point (point bounds).
    pub probed: u64,
}

impl TrackingStats {
    /// Adds `o` into `self`.
    pub fn merge(&mut self, o: &TrackingStats) {
        self.lookups += o.lookups;
        self.transmittance_lookups += o.transmittance_lookups;
        self.real_collisions += o.real_collisions;
        self.null_collisions += o.null_collisions;
        self.violations += o.violations;
        self.segments += o.segments;
        self.probed += o.probed;
    }
}

/// The outcome of a free flight, homogeneous or tracked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Flight {
    /// A real collision at `t`; multiply the throughput by `weight` (includes the albedo),
    /// then sample the phase function.
    Scatter {
        /// Distance (world units).
        t: f32,
        /// Throughput factor.
        weight: Rgb,
        /// Density at the collision (1 in a homogeneous medium).
        density: f32,
    },
    /// The flight left the last segment; multiply the throughput by `weight`.
    Escape {
        /// Throughput factor.
        weight: Rgb,
    },
}

/// How free-flight distances are sampled in a heterogeneous interior.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FreeFlightMethod {
    /// Delta (Woodcock) tracking over the majorant segments: unbiased.
    DeltaTracking,
    /// Decomposition tracking (Kutz et al. 2017): delta tracking whose segments' minorant part
    /// is sampled without lookups: unbiased.
    Decomposition,
    /// The split flight for optically thin media ([`split_flight`]): scatter with a
    /// probability from the coarse optical depth at a distance that cannot escape, or pass
    /// with the estimated transmittance; unbiased with an unbiased transmittance estimator.
    Split,
    /// Fixed-step ray marching: biased, the notes' §2.2.2 baseline.
    RayMarch {
        /// Step length, world units.
        step: f32,
    },
}

/// The estimator choices of a heterogeneous interior (speed/accuracy trade;
/// docs/references.md §4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingConfig {
    /// Free-flight sampling.
    pub free_flight: FreeFlightMethod,
    /// Transmittance estimation for shadow rays.
    pub transmittance: TransmittanceMode,
    /// Which majorants drive both.
    pub majorant: MajorantMode,
    /// Test tentative collisions against per-point local bounds before looking the density
    /// up (where the density field has them: grids and baked procedurals), and let the walk
    /// stay at coarser segments accordingly (docs/references.md §4.10). On by default: for
    /// grey media the free flights' events are those without, at fewer lookups; only delta
    /// and decomposition tracking use them.
    pub local_bounds: bool,
    /// How a ray's light from behind the medium (the environment or an emitter seen through
    /// it) is estimated: by the path surviving the free flight, or by a transmittance estimate.
    pub behind: BehindMode,
    /// At each medium vertex with NEE at the vertex (`nee = "interior"`) and a
    /// Henyey–Greenstein phase function, also estimate the brightest delta distant light's
    /// light scattered at the *next* vertex along one extra direction drawn from a lobe centred
    /// on that light, balance-weighted against the path's own next vertex (unbiased; the
    /// integrator's `SunLean`, docs/choosing-estimators.md). On by default.
    pub sun_lean: bool,
}

/// How the light behind a medium reaches a ray that crosses it (docs/choosing-estimators.md,
/// "What lies behind a medium"). The radiance along a ray through a medium is
/// `T(0, d) L_b + ∫₀^d T(0, t) σ_s(t) L_s(t) dt`. Delta tracking estimates the first term by
/// letting the path survive the free flight or not; [`BehindMode::Transmittance`] estimates it
/// with the interior's transmittance estimator instead and keeps delta tracking for the second
/// term only (an escaped flight then adds nothing). Both are unbiased. Which has less variance
/// depends on the scene: surviving is better where the in-scattered light `L_s` is about as
/// bright as `L_b` (a bright, high-albedo cloud against the sky: the two outcomes then give
/// similar values), the transmittance estimate where `L_s` is much darker than `L_b` (dark
/// smoke against a bright sky).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BehindMode {
    /// The path survives the free flight or dies (plain delta tracking).
    Survive,
    /// The light behind is weighted by a transmittance estimate where the ray, once out of
    /// the medium, reaches the environment or a sphere light with nothing in between;
    /// elsewhere as [`BehindMode::Survive`].
    Transmittance,
}

impl Default for TrackingConfig {
    /// Delta tracking with local bounds (where the field has them), residual ratio tracking
    /// with Novák's control, hierarchical majorants down to the brick level.
    fn default() -> Self {
        TrackingConfig {
            free_flight: FreeFlightMethod::DeltaTracking,
            transmittance: TransmittanceMode::ResidualRatio(ControlVariate::Novak),
            majorant: MajorantMode::Hierarchical { finest: 0 },
            local_bounds: true,
            behind: BehindMode::Survive,
            sun_lean: true,
        }
    }
}

/// How the control density of residual ratio tracking is chosen per segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlVariate {
    /// The segment's minorant: the residual is non-negative.
    Minorant,
    /// The segment's mean density.
    Mean,
    /// Novák's heuristic as used in Tungsten (docs/references.md §4.4):
    /// σ_c = clamp(min + R(γ^{1/(L R)} − 1), min, mean) with γ = 2.
    Novak,
}

/// Transmittance estimators.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TransmittanceMode {
    /// Ratio tracking: Π (1 − σ_t(x_i)/M).
    Ratio,
    /// Residual ratio tracking with a per-segment control density.
    ResidualRatio(ControlVariate),
    /// Fixed-step ray marching with step `step` (world units): biased.
    RayMarch {
        /// Step length.
        step: f32,
    },
    /// Unbiased ray marching (Kettunen et al. 2021): combs sized by each segment's coarse
    /// optical depth, debiased by a randomly truncated power series. Unbiased; values outside
    /// [0, 1] occur.
    UnbiasedRayMarch,
    /// The jackknife estimator (Peters 2025): two jittered combs per segment, cos(s)·e^(−m).
    /// **Biased** (the bias shrinks with the comb size, not with samples per pixel), at a fixed
    /// cost.
    Jackknife,
}
