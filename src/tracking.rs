//! Distance sampling and transmittance estimation through heterogeneous media, all driven
//! by one stream of piecewise-constant majorant segments (REFERENCES §4; course notes
//! §2.2.2–2.2.4).
//!
//! The media handled here have extinction and scattering proportional to a scalar density:
//! σ_t(x) = d(x)·σ_t^0 and σ_s(x) = d(x)·σ_s^0 (RGB per unit density) — the notes' "voxelised"
//! and "heterogeneous scattering" interiors. A segment `[t0, t1]` carries bounds on the
//! *density* (`min ≤ d ≤ max`), so one segment stream serves every channel.
//!
//! Estimators:
//! - [`delta_track`]: free-flight sampling (Woodcock 1965) with the channel chosen by
//!   throughput and one-sample MIS over channels (REFERENCES §4.6, heterogeneous form), written
//!   as weighted null-collision tracking so that it stays unbiased where a bound is violated
//!   (segments with `min == max` are sampled in closed form, without lookups);
//! - [`transmittance`] with [`TransmittanceMode::Ratio`] (Cramer 1978; Novák et al. 2014),
//!   [`TransmittanceMode::ResidualRatio`] (Novák, Selle, Jarosz 2014) with a per-segment
//!   control density, and [`TransmittanceMode::RayMarch`] (the biased fixed-step baseline);
//! - [`ray_march_free_flight`]: the biased fixed-step free-flight baseline.

use crate::medium::pick_channel;
use crate::spectrum::Rgb;

/// A piece of ray `[t0, t1]` (world distances) over which the density is bounded.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MajorantSegment {
    /// Start distance.
    pub t0: f32,
    /// End distance.
    pub t1: f32,
    /// Upper bound of the density on the segment (the majorant, density units).
    pub max: f32,
    /// Lower bound of the density on the segment (the minorant).
    pub min: f32,
    /// Mean density of the region the segment crosses (a control-variate candidate);
    /// any value in `[min, max]` is valid.
    pub mean: f32,
}

impl MajorantSegment {
    /// Length of the segment.
    #[must_use]
    pub fn length(&self) -> f32 {
        (self.t1 - self.t0).max(0.0)
    }
    /// True when the density is known to be constant on the segment.
    #[must_use]
    pub fn is_homogeneous(&self) -> bool {
        self.min == self.max
    }
}

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
    }
}

/// The outcome of a free flight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Flight {
    /// A real collision at `t`; multiply the throughput by `weight` (includes the albedo),
    /// then sample the phase function.
    Scatter {
        /// Distance (world units).
        t: f32,
        /// Throughput factor.
        weight: Rgb,
    },
    /// The flight left the last segment; multiply the throughput by `weight`.
    Escape {
        /// Throughput factor.
        weight: Rgb,
    },
}

/// Channel probabilities ∝ |β_c α_c| (Chiang et al. 2016), with fallbacks (see
/// [`crate::medium::channel_probabilities`]).
fn hero_probabilities(beta: Rgb, coeff: &DensityCoefficients) -> [f32; 3] {
    crate::medium::channel_probabilities(beta, coeff.sigma_s.safe_div(coeff.sigma_t))
}

/// Running numerator (per channel contribution) and per-hero-channel path probabilities of a
/// one-sample-MIS free flight. Common factors (e^{-M Δt}) are omitted from both.
struct MisChain {
    f: Rgb,
    p: Rgb,
}

impl MisChain {
    fn renormalise(&mut self) {
        let m = self.p.max_component();
        if m > 0.0 && !(1e-20..=1e20).contains(&m) {
            self.f /= m;
            self.p /= m;
        }
    }
    fn weight(&self, probs: [f32; 3]) -> Rgb {
        let denom = probs[0] * self.p[0] + probs[1] * self.p[1] + probs[2] * self.p[2];
        if denom > 0.0 && denom.is_finite() {
            self.f / denom
        } else {
            Rgb::ZERO
        }
    }
}

/// Samples a free-flight distance along the segments (delta tracking with one-sample MIS over
/// channels). `density(t)` returns the density at distance `t`; `u()` returns uniform numbers
/// in [0, 1). Unbiased for any segment bounds: where `density > max` (an estimated bound that
/// is violated) the null weight turns negative (weighted tracking) and the violation is counted.
pub fn delta_track<S, D, U>(
    segments: S,
    coeff: &DensityCoefficients,
    mut density: D,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    U: FnMut() -> f32,
{
    let probs = hero_probabilities(beta, coeff);
    let hero = pick_channel(probs, u());
    let mut chain = MisChain {
        f: Rgb::ONE,
        p: Rgb::ONE,
    };
    for seg in segments {
        stats.segments += 1;
        let len = seg.length();
        if len <= 0.0 || coeff.is_void(&seg) {
            continue;
        }
        if seg.is_homogeneous() {
            // Closed form: constant density, no lookups.
            let sigma_t = coeff.sigma_t_at(seg.max);
            let sigma_hero = sigma_t[hero];
            let t_local = if sigma_hero > 0.0 {
                -(-u()).ln_1p() / sigma_hero
            } else {
                f32::INFINITY
            };
            if t_local < len {
                let tr = (sigma_t * t_local).map(|x| (-x).exp());
                chain.f *= coeff.sigma_s_at(seg.max) * tr;
                chain.p *= sigma_t * tr;
                stats.real_collisions += 1;
                return Flight::Scatter {
                    t: seg.t0 + t_local,
                    weight: chain.weight(probs),
                };
            }
            let tr = (sigma_t * len).map(|x| (-x).exp());
            chain.f *= tr;
            chain.p *= tr;
            chain.renormalise();
            continue;
        }
        let majorant = coeff.majorant(&seg);
        if !(majorant > 0.0) || !majorant.is_finite() {
            continue;
        }
        // Distance from the segment start: keeps advancing where a step is below half an ulp
        // of the absolute distance (far from the origin).
        let mut local = 0.0f32;
        loop {
            local += -(-u()).ln_1p() / majorant;
            if local >= len {
                break;
            }
            let t = seg.t0 + local;
            let d = density(t);
            stats.lookups += 1;
            if d > seg.max || d < seg.min {
                stats.violations += 1;
            }
            let sigma_t = coeff.sigma_t_at(d);
            let sigma_n = Rgb::splat(majorant) - sigma_t;
            // Decision probabilities of each channel as hero (weighted tracking: |σ_t| vs |σ_n|).
            let p_real = Rgb([0, 1, 2].map(|k| {
                let a = sigma_t[k].abs();
                let b = sigma_n[k].abs();
                if a + b > 0.0 {
                    a / (a + b)
                } else {
                    0.0
                }
            }));
            if u() < p_real[hero] {
                chain.f *= coeff.sigma_s_at(d);
                chain.p *= p_real * majorant;
                stats.real_collisions += 1;
                return Flight::Scatter {
                    t,
                    weight: chain.weight(probs),
                };
            }
            chain.f *= sigma_n;
            chain.p *= (Rgb::ONE - p_real) * majorant;
            chain.renormalise();
            stats.null_collisions += 1;
            if chain.p.is_black() {
                return Flight::Escape { weight: Rgb::ZERO };
            }
        }
    }
    Flight::Escape {
        weight: chain.weight(probs),
    }
}

/// How the control density of residual ratio tracking is chosen per segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControlVariate {
    /// The segment's minorant: the residual is non-negative.
    Minorant,
    /// The segment's mean density.
    Mean,
    /// Novák's heuristic as used in Tungsten (REFERENCES §4.4):
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
}

/// The control density of a segment. `sigma_scale` converts density to extinction (the largest
/// channel of σ_t⁰): Novák's heuristic is written in optical units.
fn control_density(seg: &MajorantSegment, cv: ControlVariate, sigma_scale: f32) -> f32 {
    match cv {
        ControlVariate::Minorant => seg.min,
        ControlVariate::Mean => seg.mean.clamp(seg.min, seg.max),
        ControlVariate::Novak => {
            let range = seg.max - seg.min;
            let len = seg.length();
            let upper = seg.mean.clamp(seg.min, seg.max);
            if range <= 0.0 {
                return seg.min;
            }
            let exponent = std::f32::consts::LN_2 / (len * range * sigma_scale).max(1e-30);
            if exponent > 80.0 {
                return upper;
            }
            (seg.min + range * exponent.exp_m1()).clamp(seg.min, upper)
        }
    }
}

/// Estimates the RGB transmittance along the segments. Ratio-type estimators are unbiased
/// for any bounds (factors turn negative where a bound is violated); ray marching is biased.
/// Russian roulette (pbrt-v4's rule: below 0.05, stop with probability 0.75) keeps long
/// rays cheap without bias.
pub fn transmittance<S, D, U>(
    segments: S,
    coeff: &DensityCoefficients,
    mut density: D,
    mode: TransmittanceMode,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Rgb
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    U: FnMut() -> f32,
{
    let st = coeff.sigma_t;
    let s_max = coeff.max_sigma_t();
    let mut tr = Rgb::ONE;
    if s_max <= 0.0 && coeff.base_t.is_black() {
        return tr;
    }
    for seg in segments {
        stats.segments += 1;
        let len = seg.length();
        if len <= 0.0 || coeff.is_void(&seg) {
            continue;
        }
        if seg.is_homogeneous() || s_max <= 0.0 {
            tr *= (coeff.sigma_t_at(seg.max) * len).map(|x| (-x).exp());
        } else {
            match mode {
                TransmittanceMode::RayMarch { step } => {
                    let n = (len / step.max(1e-12)).ceil().clamp(1.0, 1e7) as u32;
                    let dt = len / n as f32;
                    let offset = u();
                    let mut depth = 0.0f32;
                    for i in 0..n {
                        depth += density(seg.t0 + (i as f32 + offset) * dt) * dt;
                        stats.transmittance_lookups += 1;
                    }
                    tr *= (st * depth + coeff.base_t * len).map(|x| (-x).exp());
                }
                TransmittanceMode::Ratio | TransmittanceMode::ResidualRatio(_) => {
                    let control = match mode {
                        TransmittanceMode::ResidualRatio(cv) => control_density(&seg, cv, s_max),
                        _ => 0.0,
                    };
                    let residual_bound = (seg.max - control).max(control - seg.min).max(0.0);
                    let analytic = coeff.sigma_t_at(control) * len;
                    if !analytic.is_black() {
                        tr *= analytic.map(|x| (-x).exp());
                    }
                    let majorant = residual_bound * s_max;
                    if majorant > 0.0 && majorant.is_finite() {
                        let mut local = 0.0f32;
                        loop {
                            local += -(-u()).ln_1p() / majorant;
                            if local >= len {
                                break;
                            }
                            let t = seg.t0 + local;
                            let d = density(t);
                            stats.transmittance_lookups += 1;
                            if d > seg.max || d < seg.min {
                                stats.violations += 1;
                            }
                            tr *= Rgb::ONE - st * ((d - control) / majorant);
                            if tr.max_component().abs() < 0.05 {
                                if u() < 0.75 {
                                    return Rgb::ZERO;
                                }
                                tr /= 0.25;
                            }
                        }
                    }
                }
            }
        }
        if tr.is_black() {
            return tr;
        }
    }
    tr
}

/// Fixed-step ray-marching free flight (the biased baseline of the notes §2.2.2): accumulates
/// the hero channel's optical depth in steps of `step` until it exceeds an exponential sample,
/// then weights with one-sample MIS over channels as for homogeneous media.
pub fn ray_march_free_flight<S, D, U>(
    segments: S,
    coeff: &DensityCoefficients,
    mut density: D,
    step: f32,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    U: FnMut() -> f32,
{
    let probs = hero_probabilities(beta, coeff);
    let hero = pick_channel(probs, u());
    let target = -(-u()).ln_1p();
    let mut tau = Rgb::ZERO; // optical depth per channel
    let offset = u();
    for seg in segments {
        stats.segments += 1;
        let len = seg.length();
        if len <= 0.0 || coeff.is_void(&seg) {
            continue;
        }
        let n = (len / step.max(1e-12)).ceil().clamp(1.0, 1e7) as u32;
        let dt = len / n as f32;
        for i in 0..n {
            let d = if seg.is_homogeneous() {
                seg.max
            } else {
                stats.lookups += 1;
                density(seg.t0 + (i as f32 + offset) * dt)
            };
            // Optical depth per channel so far is st·depth + base·length.
            let sigma = coeff.sigma_t_at(d);
            let next = tau + sigma * dt;
            if next[hero] >= target && sigma[hero] > 0.0 {
                // Collide inside this step (constant coefficients within the step).
                let frac = ((target - tau[hero]) / sigma[hero]).clamp(0.0, dt);
                let t = seg.t0 + i as f32 * dt + frac;
                let tr = (tau + sigma * frac).map(|x| (-x).exp());
                let pdf: f32 = (0..3).map(|k| probs[k] * sigma[k] * tr[k]).sum();
                stats.real_collisions += 1;
                return Flight::Scatter {
                    t,
                    weight: if pdf > 0.0 {
                        coeff.sigma_s_at(d) * tr / pdf
                    } else {
                        Rgb::ZERO
                    },
                };
            }
            tau = next;
        }
    }
    let tr = tau.map(|x| (-x).exp());
    let prob: f32 = (0..3).map(|k| probs[k] * tr[k]).sum();
    Flight::Escape {
        weight: if prob > 0.0 { tr / prob } else { Rgb::ZERO },
    }
}
