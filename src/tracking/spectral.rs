//! Tracking through media whose RGB extinction and scattering vary independently per channel
//! (not a scalar density times fixed coefficients), against scalar majorants: interiors whose
//! textured parameters are projected back to their boundary (`projection = "surface"`,
//! docs/textures.md). The majorant is constant per [`RateSegment`] of the ray: one segment
//! over the whole ray for a homogeneous interior (the textures' bound), the density field's
//! majorant segments for a `voxel` or `fbm` interior (the field's bound times the textures').
//!
//! - [`spectral_delta_track`], [`spectral_delta_track_segments`]: delta tracking with the
//!   hero channel and one-sample MIS over channels (docs/references.md §4.6), written as
//!   weighted null-collision tracking (docs/references.md §4) so that a majorant exceeded
//!   somewhere stays unbiased (the violation is counted). Where σ_t,c ≤ M the per-channel
//!   probabilities of real and null collisions are σ_t,c/M and 1 − σ_t,c/M; where σ_t,c > M
//!   they are |σ_t,c| / (|σ_t,c| + |M − σ_t,c|) and its complement. The throughput of a
//!   real collision is σ_s(x), of a null one M − σ_t(x) (negative where violated), each
//!   divided by M, over the MIS mixture of the channels' path probabilities.
//! - [`spectral_ratio_transmittance`], [`spectral_ratio_transmittance_segments`]: ratio
//!   tracking (Cramer 1978; Novák et al. 2014), Π (1 − σ_t(x_i)/M) per channel.

use super::delta::MisChain;
use super::{channel_probabilities, pick_channel, Flight, RateSegment, TrackingStats};
use crate::spectrum::Rgb;

/// Tentative collisions after which a flight gives up (weight 0): only reached by an open
/// interior (`t_max = ∞`) with no extinction, which a closed boundary does not have.
pub const SPECTRAL_MAX_STEPS: u32 = 1 << 20;

/// Relative excess of σ_t over the majorant that counts as a violation (below it, rounding).
const ROUNDING: f32 = 1e-5;

/// True (and counted) when `sigma_t` exceeds the majorant `m` in some channel (beyond
/// rounding).
#[inline]
fn violated(sigma_t: Rgb, m: f32, stats: &mut TrackingStats) {
    if sigma_t.max_component() > m * (1.0 + ROUNDING) {
        stats.violations += 1;
    }
}

/// The probability per channel that a tentative collision at rate `m` is real where the
/// extinction is `s`: s/m within the majorant (and up to rounding above it, clamped to 1),
/// |s| / (|s| + |m − s|) where the majorant is violated (weighted tracking).
#[inline]
fn real_probability(s: f32, m: f32) -> f32 {
    if s > m * (1.0 + ROUNDING) {
        s / (s + (s - m))
    } else {
        (s / m).clamp(0.0, 1.0)
    }
}

/// The whole ray `[0, t_max]` as one segment of majorant `majorant`.
fn one_segment(majorant: f32, t_max: f32) -> std::iter::Once<RateSegment> {
    std::iter::once(RateSegment {
        t0: 0.0,
        t1: t_max,
        majorant,
        varying: true,
    })
}

/// True when a segment's majorant drives tracking (finite and > 0); other segments do not
/// attenuate.
#[inline]
fn usable(majorant: f32) -> bool {
    majorant > 0.0 && majorant.is_finite()
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
    sigma_t: T,
    sigma_s: S,
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
    if !usable(majorant) {
        // The hero channel's number is drawn all the same (the stream stays aligned).
        let _ = u();
        stats.segments += 1;
        return Flight::Escape { weight: Rgb::ONE };
    }
    spectral_delta_track_segments(
        one_segment(majorant, t_max),
        sigma_t,
        sigma_s,
        alpha,
        beta,
        u,
        stats,
    )
}

/// [`spectral_delta_track`] over a stream of segments, each with its own scalar majorant
/// (segments whose majorant is 0 or not finite do not attenuate; their `varying` flag is
/// ignored: every tentative collision is looked up). The segments must be in order along the
/// ray and not overlap.
pub fn spectral_delta_track_segments<I, T, S, U>(
    segments: I,
    mut sigma_t: T,
    mut sigma_s: S,
    alpha: Rgb,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    I: IntoIterator<Item = RateSegment>,
    T: FnMut(f32) -> Rgb,
    S: FnMut(f32) -> Rgb,
    U: FnMut() -> f32,
{
    let probs = channel_probabilities(beta, alpha);
    let hero = pick_channel(probs, u());
    let mut chain = MisChain {
        f: Rgb::ONE,
        p: Rgb::ONE,
    };
    let mut steps = 0u32;
    for seg in segments {
        stats.segments += 1;
        let majorant = seg.majorant;
        if !usable(majorant) {
            continue;
        }
        let mut t = seg.t0;
        loop {
            t += -(1.0 - u()).ln() / majorant;
            if !(t < seg.t1) {
                break;
            }
            steps += 1;
            if steps > SPECTRAL_MAX_STEPS {
                return Flight::Escape { weight: Rgb::ZERO };
            }
            let st = sigma_t(t);
            stats.lookups += 1;
            violated(st, majorant, stats);
            let q = st.map(|s| real_probability(s, majorant));
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
    }
    Flight::Escape {
        weight: chain.weight(probs),
    }
}

/// Ratio tracking over `[0, t_max]` against the scalar majorant `majorant`: the product of
/// 1 − σ_t(x_i)/M over tentative collisions at rate M, per channel. Unbiased for any
/// majorant (values below 0 where it is exceeded, which is counted); stops early once every
/// channel is 0.
pub fn spectral_ratio_transmittance<T, U>(
    majorant: f32,
    t_max: f32,
    sigma_t: T,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Rgb
where
    T: FnMut(f32) -> Rgb,
    U: FnMut() -> f32,
{
    spectral_ratio_transmittance_segments(one_segment(majorant, t_max), sigma_t, u, stats)
}

/// [`spectral_ratio_transmittance`] over a stream of segments, each with its own scalar
/// majorant (segments whose majorant is 0 or not finite do not attenuate).
pub fn spectral_ratio_transmittance_segments<I, T, U>(
    segments: I,
    mut sigma_t: T,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Rgb
where
    I: IntoIterator<Item = RateSegment>,
    T: FnMut(f32) -> Rgb,
    U: FnMut() -> f32,
{
    let mut tr = Rgb::ONE;
    let mut steps = 0u32;
    for seg in segments {
        stats.segments += 1;
        let majorant = seg.majorant;
        if !usable(majorant) {
            continue;
        }
        let mut t = seg.t0;
        loop {
            t += -(1.0 - u()).ln() / majorant;
            if !(t < seg.t1) {
                break;
            }
            steps += 1;
            if steps > SPECTRAL_MAX_STEPS {
                return Rgb::ZERO;
            }
            let st = sigma_t(t);
            stats.transmittance_lookups += 1;
            violated(st, majorant, stats);
            tr *= Rgb::ONE - st / majorant;
            if tr.is_black() {
                return Rgb::ZERO;
            }
        }
    }
    tr
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

    /// A free flight whose majorant is exceeded (σ_t = 1.5 against M = 1 in two channels) is
    /// counted and stays unbiased: the escape weight's mean is the transmittance and the
    /// scattered weight's mean α (1 − T), per channel (weighted tracking).
    #[test]
    fn delta_tracking_stays_unbiased_where_the_majorant_is_violated() {
        let sig_t = |_: f32| Rgb([1.5, 0.6, 1.5]);
        let alpha = Rgb([0.9, 0.5, 0.2]);
        let mut u = stream(13);
        let mut stats = TrackingStats::default();
        let n = 200_000;
        let (mut esc, mut esc2, mut sc, mut sc2) = (Rgb::ZERO, Rgb::ZERO, Rgb::ZERO, Rgb::ZERO);
        for _ in 0..n {
            match spectral_delta_track(
                1.0,
                1.0,
                sig_t,
                |t| sig_t(t) * alpha,
                alpha,
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
        for c in 0..3 {
            let t = (-sig_t(0.0)[c]).exp();
            for (sum, sum2, want, what) in [
                (esc[c], esc2[c], t, "escape"),
                (sc[c], sc2[c], alpha[c] * (1.0 - t), "scatter"),
            ] {
                let mean = sum / n as f32;
                let var = sum2 / n as f32 - mean * mean;
                let z = (mean - want) / (var / n as f32).sqrt().max(1e-9);
                assert!(z.abs() < 4.0, "{what} channel {c}: {mean} vs {want}, z {z}");
            }
        }
        assert!(stats.violations > 0);
    }

    /// Segments with majorants of their own (a tight one, an empty gap of majorant 0, a loose
    /// one) give the transmittance exp(−∫σ_t) and the scattering budget ∫ T σ_s of the medium,
    /// with no violation: both trackers walk the majorants piecewise.
    #[test]
    fn segments_with_their_own_majorants_track_the_piecewise_medium() {
        // σ_t: 0.5, 1, 2 on [0, 0.4); 0 on [0.4, 0.7); 2, 0.2, 1 on [0.7, 1.2).
        let sig_t = |t: f32| {
            if t < 0.4 {
                Rgb([0.5, 1.0, 2.0])
            } else if t < 0.7 {
                Rgb::ZERO
            } else {
                Rgb([2.0, 0.2, 1.0])
            }
        };
        let albedo = Rgb([0.9, 0.5, 0.1]);
        let segments = || {
            [(0.0, 0.4, 2.0), (0.4, 0.7, 0.0), (0.7, 1.2, 3.0)].map(|(t0, t1, majorant)| {
                RateSegment {
                    t0,
                    t1,
                    majorant,
                    varying: true,
                }
            })
        };
        let first = Rgb([0.2, 0.4, 0.8]);
        let tau = first + Rgb([1.0, 0.1, 0.5]);
        let mut u = stream(21);
        let mut stats = TrackingStats::default();
        let n = 200_000;
        let (mut tr, mut tr2) = (Rgb::ZERO, Rgb::ZERO);
        let (mut esc, mut esc2, mut sc, mut sc2) = (Rgb::ZERO, Rgb::ZERO, Rgb::ZERO, Rgb::ZERO);
        for _ in 0..n {
            let v = spectral_ratio_transmittance_segments(segments(), sig_t, &mut u, &mut stats);
            tr += v;
            tr2 += v * v;
            match spectral_delta_track_segments(
                segments(),
                sig_t,
                |t| sig_t(t) * albedo,
                Rgb::splat(0.5),
                Rgb::ONE,
                &mut u,
                &mut stats,
            ) {
                Flight::Escape { weight } => {
                    esc += weight;
                    esc2 += weight * weight;
                }
                Flight::Scatter { weight, t, .. } => {
                    assert!(!(0.4..0.7).contains(&t), "a collision in the gap at {t}");
                    sc += weight;
                    sc2 += weight * weight;
                }
            }
        }
        for c in 0..3 {
            let t_mid = (-first[c]).exp();
            let t_end = (-tau[c]).exp();
            let scatter = albedo[c] * (1.0 - t_end);
            for (sum, sum2, want, what) in [
                (tr[c], tr2[c], t_end, "ratio"),
                (esc[c], esc2[c], t_end, "escape"),
                (sc[c], sc2[c], scatter, "scatter"),
            ] {
                let mean = sum / n as f32;
                let var = sum2 / n as f32 - mean * mean;
                let z = (mean - want) / (var / n as f32).sqrt().max(1e-9);
                assert!(
                    z.abs() < 4.0,
                    "{what} channel {c}: {mean} vs {want} (T mid {t_mid}), z {z}"
                );
            }
        }
        assert_eq!(stats.violations, 0);
    }
}
