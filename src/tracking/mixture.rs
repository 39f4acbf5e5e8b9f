//! Free flights through a *mixture*: up to [`MAX_COMPONENTS`] media sharing
//! one region of space, each with its own extinction, albedo and phase function
//! (docs/references.md §15.1). The extinction of the mixture is the sum of the components'
//! (σ_t = Σ_i σ_t,i), so one scalar majorant per segment bounds the sum, tentative collisions
//! are decided against the total, and a real collision is given to component i with
//! probability σ_t,i(x)/σ_t(x) in the hero channel. The estimators also accumulate emission
//! with the collision estimator (docs/references.md §15.2): σ_a·L_e/M̄ at every tentative
//! collision. (Shadow rays need no mixture estimator: the transmittance of a sum of extinctions is
//! the product of the components' transmittances.)
//!
//! Nothing here knows where the coefficients come from: the caller gives a stream of
//! [`RateSegment`]s and a lookup of the components' extinction (and emission) at a distance.

use super::{pick_channel, TrackingStats};
use crate::spectrum::Rgb;

/// The largest number of components of a mixture.
pub const MAX_COMPONENTS: usize = 4;

/// A piece `[t0, t1]` of a ray with a scalar majorant (1/length): at every point of it, every
/// channel of the mixture's total extinction is at most `majorant` (where it is not, weighted
/// tracking keeps the estimators unbiased and the violation is counted).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RateSegment {
    /// Start distance.
    pub t0: f32,
    /// End distance (may be infinite for an open interior).
    pub t1: f32,
    /// Majorant of σ_t over the channels (1/length).
    pub majorant: f32,
    /// False when only the constant components (the `constant` argument of [`mixture_track`])
    /// attenuate on the segment: it is then sampled in closed form, without lookups.
    pub varying: bool,
}

/// The mixture at one point of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MixPoint {
    /// Extinction of each component (1/length); only the first `count` entries are used.
    pub sigma_t: [Rgb; MAX_COMPONENTS],
    /// Number of components.
    pub count: usize,
    /// Emitted radiance per unit length, Σ_i σ_a,i·L_e,i (zero for non-emitting mixtures, and
    /// when the lookup was asked without emission).
    pub emission: Rgb,
}

impl MixPoint {
    /// The total extinction Σ_i σ_t,i.
    #[must_use]
    pub fn total(&self) -> Rgb {
        self.sigma_t
            .iter()
            .take(self.count)
            .fold(Rgb::ZERO, |a, &s| a + s)
    }
}

/// The outcome of [`mixture_track`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MixFlight {
    /// Throughput factor of the flight (as [`super::Flight`]'s weights).
    pub weight: Rgb,
    /// The real collision, `(t, component)`, or `None` when the flight left the last segment.
    pub scatter: Option<(f32, usize)>,
    /// Emitted radiance gathered along the flight, already divided by its sampling
    /// probabilities: the caller adds (throughput before the flight) × `emitted`.
    pub emitted: Rgb,
}

/// Running contribution and per-hero-channel path probabilities (common exponential factors
/// omitted from both), as in delta tracking.
struct Chain {
    f: Rgb,
    p: Rgb,
}

impl Chain {
    fn weight(&self, probs: [f32; 3]) -> Rgb {
        let denom = probs[0] * self.p[0] + probs[1] * self.p[1] + probs[2] * self.p[2];
        if denom > 0.0 && denom.is_finite() {
            self.f / denom
        } else {
            Rgb::ZERO
        }
    }
    fn renormalise(&mut self) {
        let m = self.p.max_component();
        if m > 0.0 && !(1e-20..=1e20).contains(&m) {
            self.f /= m;
            self.p /= m;
        }
    }
}

/// Delta tracking through a mixture, written as weighted null-collision tracking with one-sample
/// MIS over the RGB channels (docs/references.md §4.6, §15.1). `probs` are the channel
/// probabilities of the hero channel (e.g. [`super::channel_probabilities`] of the
/// throughput). `lookup(t, emission)` returns the mixture at distance `t` (with its emission
/// when `emission` is true); `scattering(i, t, point)` returns σ_s of component `i` at the
/// real collision `t` (where a per-vertex albedo is read). When `emits` is true the emission
/// is gathered at every tentative collision with the collision estimator (§15.2).
///
/// At a tentative collision with total extinction σ_t and majorant M̄, the hero channel h
/// decides real against null with probability |σ_t,h|/(|σ_t,h| + |M̄ − σ_t,h|); a real
/// collision picks component i with probability σ_t,i,h/σ_t,h by the same uniform number, and
/// the path probabilities of every channel carry both factors so that the MIS weight stays
/// exact. Segments that are not `varying` hold only the constant extinctions `constant` (which
/// do not emit): their distance is sampled in closed form from σ_t,h, without lookups.
#[allow(clippy::too_many_arguments)]
pub fn mixture_track<S, L, A, U>(
    segments: S,
    constant: &MixPoint,
    mut lookup: L,
    mut scattering: A,
    emits: bool,
    probs: [f32; 3],
    u: &mut U,
    stats: &mut TrackingStats,
) -> MixFlight
where
    S: IntoIterator<Item = RateSegment>,
    L: FnMut(f32, bool) -> MixPoint,
    A: FnMut(usize, f32, &MixPoint) -> Rgb,
    U: FnMut() -> f32,
{
    let hero = pick_channel(probs, u());
    let mut chain = Chain {
        f: Rgb::ONE,
        p: Rgb::ONE,
    };
    let mut emitted = Rgb::ZERO;
    let constant_t = constant.total();
    for seg in segments {
        stats.segments += 1;
        let len = seg.t1 - seg.t0;
        let major = seg.majorant;
        if !(len > 0.0) || !(major > 0.0) || !major.is_finite() {
            continue;
        }
        if !seg.varying {
            // Closed form through the constant components (as in a homogeneous medium).
            let sigma_hero = constant_t[hero];
            let t_local = if sigma_hero > 0.0 {
                -(-u()).ln_1p() / sigma_hero
            } else {
                f32::INFINITY
            };
            if t_local < len {
                let tr = (constant_t * (-t_local)).exp();
                let t = seg.t0 + t_local;
                let chosen = pick_component(constant, constant_t, hero, u());
                chain.f *= scattering(chosen, t, constant) * tr;
                chain.p *= constant.sigma_t[chosen] * tr;
                stats.real_collisions += 1;
                return MixFlight {
                    weight: chain.weight(probs),
                    scatter: Some((t, chosen)),
                    emitted,
                };
            }
            let tr = (constant_t * (-len)).exp();
            chain.f *= tr;
            chain.p *= tr;
            chain.renormalise();
            continue;
        }
        let mut local = 0.0f32;
        loop {
            local += -(-u()).ln_1p() / major;
            if !(local < len) {
                break;
            }
            let t = seg.t0 + local;
            let point = lookup(t, emits);
            stats.lookups += 1;
            let sigma_t = point.total();
            if sigma_t.max_component() > major {
                stats.violations += 1;
            }
            if emits {
                // The collision estimator: every tentative collision scores σ_a·L_e/M̄ with
                // the weight of the path prefix that reached it.
                emitted += chain.weight(probs) * point.emission / major;
            }
            let sigma_n = Rgb::splat(major) - sigma_t;
            let p_real = Rgb([0, 1, 2].map(|k| {
                let a = sigma_t[k].abs();
                let b = sigma_n[k].abs();
                if a + b > 0.0 {
                    a / (a + b)
                } else {
                    0.0
                }
            }));
            let u_event = u();
            if u_event < p_real[hero] {
                // Which component: ∝ its extinction in the hero channel, by the same number.
                let chosen = pick_component(&point, sigma_t, hero, u_event / p_real[hero]);
                let share = point.sigma_t[chosen].safe_div(sigma_t);
                let sigma_s = scattering(chosen, t, &point);
                chain.f *= sigma_s;
                chain.p *= p_real * share * major;
                stats.real_collisions += 1;
                return MixFlight {
                    weight: chain.weight(probs),
                    scatter: Some((t, chosen)),
                    emitted,
                };
            }
            chain.f *= sigma_n;
            chain.p *= (Rgb::ONE - p_real) * major;
            chain.renormalise();
            stats.null_collisions += 1;
            if chain.p.is_black() {
                return MixFlight {
                    weight: Rgb::ZERO,
                    scatter: None,
                    emitted,
                };
            }
        }
    }
    MixFlight {
        weight: chain.weight(probs),
        scatter: None,
        emitted,
    }
}

/// The component of `point` whose share of `total` in channel `hero` contains uniform `u`
/// (components with zero extinction there are never picked unless all are zero).
fn pick_component(point: &MixPoint, total: Rgb, hero: usize, u: f32) -> usize {
    let mut x = u * total[hero];
    let mut chosen = 0;
    for (i, s) in point.sigma_t.iter().take(point.count).enumerate() {
        chosen = i;
        if x < s[hero] {
            break;
        }
        x -= s[hero];
    }
    while chosen > 0 && point.sigma_t.get(chosen).is_some_and(|s| !(s[hero] > 0.0)) {
        chosen -= 1;
    }
    chosen
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rng(seed: u64) -> impl FnMut() -> f32 {
        let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 40) as f32) / (1u64 << 24) as f32
        }
    }

    fn two(a: Rgb, b: Rgb) -> MixPoint {
        MixPoint {
            sigma_t: [a, b, Rgb::ZERO, Rgb::ZERO],
            count: 2,
            emission: Rgb::ZERO,
        }
    }

    #[test]
    fn collisions_go_to_components_in_proportion_to_their_extinction() {
        // Grey components σ1 = 1, σ2 = 3 over a long segment with majorant 5: a quarter of
        // the real collisions belong to the first.
        let seg = RateSegment {
            t0: 0.0,
            t1: 1e6,
            majorant: 5.0,
            varying: true,
        };
        let mut u = rng(7);
        let mut stats = TrackingStats::default();
        let n = 40_000;
        let mut first = 0;
        for _ in 0..n {
            let f = mixture_track(
                [seg],
                &two(Rgb::ZERO, Rgb::ZERO),
                |_, _| two(Rgb::ONE, Rgb::splat(3.0)),
                |i, _, p| p.sigma_t[i] * 0.5,
                false,
                [1.0 / 3.0; 3],
                &mut u,
                &mut stats,
            );
            let (_, i) = f.scatter.expect("collides");
            // Grey: the weight is the chosen component's albedo.
            assert!((f.weight[0] - 0.5).abs() < 1e-5);
            if i == 0 {
                first += 1;
            }
        }
        let p = first as f64 / n as f64;
        let se = (0.25 * 0.75 / n as f64).sqrt();
        assert!((p - 0.25).abs() < 4.0 * se, "share {p}");
    }
}
