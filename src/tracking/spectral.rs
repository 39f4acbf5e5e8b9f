//! Tracking through media whose RGB extinction and scattering vary independently per channel
//! (not a scalar density times fixed coefficients), against one constant scalar majorant:
//! interiors whose textured parameters are projected back to their boundary
//! (`projection = "surface"`, docs/textures.md).
//!
//! - [`spectral_delta_track`]: delta tracking with the hero channel and one-sample MIS over
//!   channels (docs/references.md §4.6), written as weighted null-collision tracking
//!   (docs/references.md §4) so that a majorant exceeded somewhere stays unbiased (the
//!   violation is counted). The per-channel probabilities of real and null collisions are
//!   σ_t,c/M and 1 − σ_t,c/M; the throughput of a real collision is σ_s(x), of a null one
//!   M − σ_t(x), divided by the MIS mixture of the channels' path densities.
//! - [`spectral_ratio_transmittance`]: ratio tracking (Cramer 1978; Novák et al. 2014),
//!   Π (1 − σ_t(x_i)/M) per channel.

use super::delta::MisChain;
use super::{channel_probabilities, pick_channel, Flight, TrackingStats};
use crate::spectrum::Rgb;

/// Tentative collisions after which a flight gives up (weight 0): only reached by an open
/// interior (`t_max = ∞`) with no extinction, which a closed boundary does not have.
pub const SPECTRAL_MAX_STEPS: u32 = 1 << 20;

/// True (and counted) when `sigma_t` exceeds the majorant `m` in some channel (beyond
/// rounding).
#[inline]
fn violated(sigma_t: Rgb, m: f32, stats: &mut TrackingStats) {
    if sigma_t.max_component() > m * (1.0 + 1e-5) {
        stats.violations += 1;
    }
}

/// Samples a free flight over `[0, t_max]` through a medium with extinction `sigma_t(t)` and
/// scattering `sigma_s(t)` (RGB, 1/length) bounded by the scalar majorant `majorant` (the
/// largest σ_t of any channel anywhere on the ray). `sigma_s` is called only at a real
/// collision, at the distance of the `sigma_t` call just before. The hero channel is picked
/// with probabilities ∝ |β_c α_c| for `alpha`, a representative single-scattering albedo of
/// the medium. Unbiased for any majorant; where σ_t > M the violation is counted.
#[allow(clippy::too_many_arguments)]
pub fn spectral_delta_track<T, S, U>(
    majorant: f32,
    t_max: f32,
    mut sigma_t: T,
    mut sigma_s: S,
    alpha: Rgb,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    T: FnMut(f32) -> Rgb,
    S: FnMut(f32) -> Rgb,
    U: FnMut() -> f32,
{
    let probs = channel_probabilities(beta, alpha);
    let hero = pick_channel(probs, u());
    stats.segments += 1;
    if !(majorant > 0.0) || !majorant.is_finite() {
        return Flight::Escape { weight: Rgb::ONE };
    }
    let mut chain = MisChain {
        f: Rgb::ONE,
        p: Rgb::ONE,
    };
    let mut t = 0.0f32;
    for _ in 0..SPECTRAL_MAX_STEPS {
        t += -(-u()).ln_1p() / majorant;
        if !(t < t_max) {
            return Flight::Escape {
                weight: chain.weight(probs),
            };
        }
        let st = sigma_t(t);
        stats.lookups += 1;
        violated(st, majorant, stats);
        let q = st.map(|s| (s / majorant).clamp(0.0, 1.0));
        if u() < q[hero] {
            stats.real_collisions += 1;
            chain.f *= sigma_s(t);
            chain.p *= q;
            return Flight::Scatter {
                t,
                weight: chain.weight(probs) / majorant,
                density: 1.0,
            };
        }
        stats.null_collisions += 1;
        chain.f *= Rgb::splat(majorant) - st;
        chain.p *= Rgb::ONE - q;
        // f carries the factor M per null collision and p does not: divide it out.
        chain.f /= majorant;
        chain.renormalise();
    }
    Flight::Escape { weight: Rgb::ZERO }
}

/// Ratio tracking over `[0, t_max]` against the scalar majorant `majorant`: the product of
/// 1 − σ_t(x_i)/M over tentative collisions at rate M, per channel. Unbiased for any
/// majorant (values below 0 where it is exceeded, which is counted); stops early once every
/// channel is 0.
pub fn spectral_ratio_transmittance<T, U>(
    majorant: f32,
    t_max: f32,
    mut sigma_t: T,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Rgb
where
    T: FnMut(f32) -> Rgb,
    U: FnMut() -> f32,
{
    stats.segments += 1;
    if !(majorant > 0.0) || !majorant.is_finite() {
        return Rgb::ONE;
    }
    let mut tr = Rgb::ONE;
    let mut t = 0.0f32;
    for _ in 0..SPECTRAL_MAX_STEPS {
        t += -(-u()).ln_1p() / majorant;
        if !(t < t_max) {
            return tr;
        }
        let st = sigma_t(t);
        stats.transmittance_lookups += 1;
        violated(st, majorant, stats);
        tr *= Rgb::ONE - st / majorant;
        if tr.is_black() {
            return Rgb::ZERO;
        }
    }
    Rgb::ZERO
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic uniform stream.
    fn stream(seed: u64) -> impl FnMut() -> f32 {
        let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// Transmittance through a piecewise medium (σ_t differs per channel and per half) is
    /// exp(−∫σ_t): a z-test of the ratio tracker's mean.
    #[test]
    fn ratio_tracking_matches_the_optical_depth() {
        let sig = |t: f32| {
            if t < 0.5 {
                Rgb([0.5, 1.0, 2.0])
            } else {
                Rgb([2.0, 0.2, 1.0])
            }
        };
        let tau = Rgb([0.25 + 1.0, 0.5 + 0.1, 1.0 + 0.5]);
        let mut u = stream(3);
        let mut stats = TrackingStats::default();
        let n = 200_000;
        let (mut s, mut s2) = (Rgb::ZERO, Rgb::ZERO);
        for _ in 0..n {
            let v = spectral_ratio_transmittance(2.5, 1.0, sig, &mut u, &mut stats);
            s += v;
            s2 += v * v;
        }
        for c in 0..3 {
            let mean = s[c] / n as f32;
            let var = s2[c] / n as f32 - mean * mean;
            let z = (mean - (-tau[c]).exp()) / (var / n as f32).sqrt();
            assert!(z.abs() < 4.0, "channel {c}: mean {mean}, z {z}");
        }
        assert_eq!(stats.violations, 0);
    }

    /// The expected escape weight of a free flight is the transmittance, and the expected
    /// scattered weight is ∫ T(t) σ_s(t) dt, per channel (single-scattering budget).
    #[test]
    fn delta_tracking_balances_escape_and_scattering() {
        let sig_t = |t: f32| {
            if t < 0.5 {
                Rgb([0.5, 1.0, 2.0])
            } else {
                Rgb([2.0, 0.2, 1.0])
            }
        };
        let sig_s = |t: f32| sig_t(t) * Rgb([0.9, 0.5, 0.1]);
        let tau = Rgb([1.25, 0.6, 1.5]);
        let mut u = stream(5);
        let mut stats = TrackingStats::default();
        let n = 200_000;
        let (mut esc, mut esc2, mut sc, mut sc2) = (Rgb::ZERO, Rgb::ZERO, Rgb::ZERO, Rgb::ZERO);
        for _ in 0..n {
            match spectral_delta_track(
                2.5,
                1.0,
                sig_t,
                sig_s,
                Rgb::splat(0.5),
                Rgb::ONE,
                &mut u,
                &mut stats,
            ) {
                Flight::Escape { weight } => {
                    esc += weight;
                    esc2 += weight * weight;
                }
                Flight::Scatter { weight, .. } => {
                    sc += weight;
                    sc2 += weight * weight;
                }
            }
        }
        // ∫ T σ_s = α (1 − T) on each half: first half up to T(0.5), second from there.
        let half = Rgb([0.25, 0.5, 1.0]);
        for c in 0..3 {
            let t_mid = (-half[c]).exp();
            let t_end = (-tau[c]).exp();
            let alpha = [0.9, 0.5, 0.1][c];
            let scatter = alpha * (1.0 - t_mid) + alpha * (t_mid - t_end);
            for (sum, sum2, want, what) in [
                (esc[c], esc2[c], t_end, "escape"),
                (sc[c], sc2[c], scatter, "scatter"),
            ] {
                let mean = sum / n as f32;
                let var = sum2 / n as f32 - mean * mean;
                let z = (mean - want) / (var / n as f32).sqrt().max(1e-9);
                assert!(z.abs() < 4.0, "{what} channel {c}: {mean} vs {want}, z {z}");
            }
        }
        assert_eq!(stats.violations, 0);
    }

    /// A majorant below σ_t is counted and stays unbiased in expectation (weighted tracking).
    #[test]
    fn violations_are_counted_and_stay_unbiased() {
        let mut u = stream(9);
        let mut stats = TrackingStats::default();
        let n = 200_000;
        let mut s = Rgb::ZERO;
        let mut s2 = Rgb::ZERO;
        for _ in 0..n {
            let v = spectral_ratio_transmittance(1.0, 1.0, |_| Rgb::splat(1.5), &mut u, &mut stats);
            s += v;
            s2 += v * v;
        }
        let mean = s[0] / n as f32;
        let var = s2[0] / n as f32 - mean * mean;
        let z = (mean - (-1.5f32).exp()) / (var / n as f32).sqrt();
        assert!(z.abs() < 4.0, "{mean}, z {z}");
        assert!(stats.violations > 0);
    }
}
