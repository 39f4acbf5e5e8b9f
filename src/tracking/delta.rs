//! Delta tracking over majorant segments with one-sample MIS over channels, written as
//! weighted null-collision tracking, and its decomposition-tracking variant.

use super::channels::hero_probabilities;
use super::grey::{Channels, Coefficients};
use super::{
    pick_channel, DensityCoefficients, Flight, NoPointBounds, PointBounds, Probe, TrackingStats,
};
use crate::majorant::MajorantSegment;
use crate::sampling::ONE_MINUS_EPSILON;
use crate::spectrum::Rgb;

/// Running numerator (per channel contribution) and per-hero-channel path probabilities of a
/// one-sample-MIS free flight. Common factors (e^{-M Δt}) are omitted from both. In RGB, or
/// one scalar for a grey medium (its three channels equal).
pub(super) struct MisChain<V = Rgb> {
    pub(super) f: V,
    pub(super) p: V,
}

impl<V: Channels> MisChain<V> {
    #[inline]
    pub(super) fn renormalise(&mut self) {
        let m = self.p.max_channel();
        if m > 0.0 && !(1e-20..=1e20).contains(&m) {
            self.f /= m;
            self.p /= m;
        }
    }
    #[inline]
    pub(super) fn weight(&self, probs: [f32; 3]) -> Rgb {
        let denom = self.p.mix(probs);
        if denom > 0.0 && denom.is_finite() {
            (self.f / denom).to_rgb()
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
    density: D,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    U: FnMut() -> f32,
{
    track(
        segments,
        coeff,
        density,
        NoPointBounds,
        beta,
        u,
        stats,
        false,
    )
}

/// [`delta_track`] with point bounds (docs/references.md §4.10): a tentative collision of a
/// segment (rate M, the segment's majorant) is first tested against the local majorant m(x)
/// of its point. With the same uniform number that decides real against null, `u·M ≥ m(x)`
/// means a null collision whatever the density (thinning: the accepted points are a Poisson
/// process of rate m(x)), and needs no lookup; otherwise the density is looked up and the
/// collision is decided against m(x) with `u·M/m(x)`. The events are those of delta tracking
/// with the segment's majorant; the weights are those of delta tracking with the local
/// majorant (identical for grey media). Unbiased for any bounds (weighted tracking where the
/// local bounds are violated), as long as the local bounds are proven wherever they are zero.
///
/// In a grey medium without a constant part (one albedo everywhere), where the point bounds'
/// minima are proven ([`PointBounds::proven_minorant`]) and lie strictly below the point's
/// majorant, the collision takes a control part at the local minorant as in
/// [`decomposition_track_local`]: a tentative collision below it is real without a lookup.
/// The events are still those of delta tracking, and the weights too up to rounding.
pub fn delta_track_local<S, D, P, U>(
    segments: S,
    coeff: &DensityCoefficients,
    density: D,
    local: P,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    P: PointBounds,
    U: FnMut() -> f32,
{
    track(segments, coeff, density, local, beta, u, stats, false)
}

/// Decomposition tracking (Kutz, Habel, Li, Novák 2017; docs/references.md §11.3): delta
/// tracking with each segment's extinction split into a constant control, σ_t at the
/// segment's minorant, and the residual above it. A tentative collision belongs to the control
/// with probability σ_c/M and is then a real collision at the control's albedo that needs **no
/// density lookup**; otherwise the density is looked up and the residual decides between a
/// real collision (at the residual's albedo) and a null one. Lookups fall roughly in the ratio
/// (M − σ_c)/M. Unbiased for any bounds (weighted tracking where the minorant is violated).
pub fn decomposition_track<S, D, U>(
    segments: S,
    coeff: &DensityCoefficients,
    density: D,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    U: FnMut() -> f32,
{
    track(
        segments,
        coeff,
        density,
        NoPointBounds,
        beta,
        u,
        stats,
        true,
    )
}

/// [`decomposition_track`] with point bounds: the thinning of [`delta_track_local`], and the
/// control part of each tentative collision is σ_t at the *local* minorant of its point (the
/// exact minorant of a small cell, not the segment's, which is 0 wherever the segment touches
/// empty voxels). Control collisions need no lookup. Unbiased for any bounds.
pub fn decomposition_track_local<S, D, P, U>(
    segments: S,
    coeff: &DensityCoefficients,
    density: D,
    local: P,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Flight
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    P: PointBounds,
    U: FnMut() -> f32,
{
    track(segments, coeff, density, local, beta, u, stats, true)
}

/// The delta tracker, with (`decompose`) or without a control part, and with or without point
/// bounds: picks the hero channel, then tracks in one scalar when the medium is grey (the same
/// decisions and weights, bit for bit) and in RGB otherwise.
#[allow(clippy::too_many_arguments)]
fn track<S, D, P, U>(
    segments: S,
    coeff: &DensityCoefficients,
    density: D,
    local_bounds: P,
    beta: Rgb,
    u: &mut U,
    stats: &mut TrackingStats,
    decompose: bool,
) -> Flight
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    P: PointBounds,
    U: FnMut() -> f32,
{
    match coeff.grey() {
        Some(grey) => {
            // Every channel takes the same decisions and weights: the hero's number is drawn
            // (the stream stays aligned) but not needed, and the mixture of the channels' path
            // probabilities is the path probability itself.
            let _ = u();
            let flight = HeroChoice {
                probs: [1.0, 0.0, 0.0],
                hero: 0,
                decompose,
                local_control: grey.base_t == 0.0
                    && grey.base_s == 0.0
                    && local_bounds.proven_minorant(),
            };
            flight.track(segments, &grey, density, local_bounds, u, stats)
        }
        None => {
            let probs = hero_probabilities(beta, coeff);
            let hero = pick_channel(probs, u());
            let flight = HeroChoice {
                probs,
                hero,
                decompose,
                local_control: false,
            };
            flight.track(segments, &coeff.rgb(), density, local_bounds, u, stats)
        }
    }
}

/// Decomposition tracking's control part (σ_t, σ_s) at density `lo`, for bounds `[lo, hi]`
/// under majorant `major`: only where it lies strictly below the majorant, which leaves the
/// residual a rate to be sampled at. Estimated bounds may cross (`lo > hi`) or coincide while
/// the density varies; there the flight takes no control (delta tracking's events).
fn control_below<V: Channels>(coeff: &Coefficients<V>, lo: f32, hi: f32, major: f32) -> (V, V) {
    if lo < hi && coeff.sigma_t_at(lo).max_channel() < major {
        (coeff.sigma_t_at(lo), coeff.sigma_s_at(lo))
    } else {
        (V::splat(0.0), V::splat(0.0))
    }
}

/// A free flight's channel choice: the hero channel, drawn with probabilities `probs`.
struct HeroChoice {
    probs: [f32; 3],
    hero: usize,
    decompose: bool,
    /// Without decomposition: take a control part at the proven local minorant of each
    /// point where it lies strictly below the local majorant (a grey medium of one albedo:
    /// the events of delta tracking, and its weights up to rounding, at fewer lookups).
    local_control: bool,
}

impl HeroChoice {
    /// Tracks the flight over `segments` with coefficients in channel type `V`.
    fn track<V, S, D, P, U>(
        &self,
        segments: S,
        coeff: &Coefficients<V>,
        mut density: D,
        mut local_bounds: P,
        u: &mut U,
        stats: &mut TrackingStats,
    ) -> Flight
    where
        V: Channels,
        S: IntoIterator<Item = MajorantSegment>,
        D: FnMut(f32) -> f32,
        P: PointBounds,
        U: FnMut() -> f32,
    {
        let (probs, hero) = (self.probs, self.hero);
        let (decompose, local_control) = (self.decompose, self.local_control && !self.decompose);
        let mut chain = MisChain {
            f: V::ONE,
            p: V::ONE,
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
                let sigma_hero = sigma_t.channel(hero);
                let t_local = if sigma_hero > 0.0 {
                    -(1.0 - u()).ln() / sigma_hero
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
                        density: seg.max,
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
            // The control part (decomposition tracking) and each channel's probability, as
            // hero, that a tentative collision belongs to it; zero for plain delta tracking.
            let (seg_control_t, seg_control_s) = if decompose {
                control_below(coeff, seg.min, seg.max, majorant)
            } else {
                (V::splat(0.0), V::splat(0.0))
            };
            // Distance from the segment start: keeps advancing where a step is below half an
            // ulp of the absolute distance (far from the origin).
            let mut local = 0.0f32;
            loop {
                local += -(1.0 - u()).ln() / majorant;
                if local >= len {
                    break;
                }
                let t = seg.t0 + local;
                let mut u_event = u();
                // The bounds at this point: the segment's, or tighter local ones (thinning).
                let mut lo = seg.min;
                let mut hi = seg.max;
                let mut major = majorant;
                let (mut control_t, mut control_s) = (seg_control_t, seg_control_s);
                let mut controlled = decompose;
                // A coarser upper bound `ub` that already puts the point's local majorant at
                // or below `u_event · majorant` decides the null collision as the point's own
                // bounds would (σ_t is non-decreasing in the density, and b ≤ ub).
                let skip = |ub: f32| {
                    let m = coeff.sigma_t_at(ub.min(seg.max)).max_channel().max(0.0);
                    m < majorant && u_event * majorant >= m
                };
                let probe = local_bounds.probe(t, skip);
                if probe == Probe::Skipped {
                    stats.probed += 1;
                    continue;
                }
                if let Probe::Bounds(a_local, b) = probe {
                    let (a, b) = (a_local.max(seg.min), b.min(seg.max));
                    if a <= b {
                        let m = coeff.sigma_t_at(b).max_channel().max(0.0);
                        if m < majorant {
                            if u_event * majorant >= m {
                                // Above the local majorant: null whatever the density.
                                stats.probed += 1;
                                continue;
                            }
                            u_event = (u_event * majorant / m).min(ONE_MINUS_EPSILON);
                            major = m;
                        }
                        lo = a;
                        hi = b;
                        if decompose {
                            (control_t, control_s) = control_below(coeff, a, b, major);
                        } else if local_control && a_local > 0.0 && a_local < b {
                            // The proven minorant, not the segment's (an estimate may be
                            // violated); below the majorant, so that the residual is sampled.
                            control_t = coeff.sigma_t_at(a_local);
                            control_s = coeff.sigma_s_at(a_local);
                            controlled = true;
                        }
                    }
                }
                let p_control = control_t / major;
                let p_rest = V::ONE - p_control;
                if controlled {
                    if u_event < p_control.channel(hero) {
                        // A control collision: real, no lookup.
                        chain.f *= control_s;
                        chain.p *= control_t;
                        stats.real_collisions += 1;
                        return Flight::Scatter {
                            t,
                            weight: chain.weight(probs),
                            density: lo,
                        };
                    }
                    // The same number decides the residual's event.
                    u_event = ((u_event - p_control.channel(hero)) / p_rest.channel(hero))
                        .min(ONE_MINUS_EPSILON);
                }
                let d = density(t);
                stats.lookups += 1;
                if d > hi || d < lo {
                    stats.violations += 1;
                }
                let sigma_t = coeff.sigma_t_at(d);
                let sigma_n = V::splat(major) - sigma_t;
                let sigma_r = sigma_t - control_t;
                // Decision probabilities of each channel as hero (weighted tracking: the
                // residual's |σ_r| against |σ_n|).
                let p_real = sigma_r.zip(sigma_n, |r, n| {
                    let a = r.abs();
                    let b = n.abs();
                    if a + b > 0.0 {
                        a / (a + b)
                    } else {
                        0.0
                    }
                });
                if u_event < p_real.channel(hero) {
                    chain.f *= coeff.sigma_s_at(d) - control_s;
                    chain.p *= p_rest * p_real * major;
                    stats.real_collisions += 1;
                    return Flight::Scatter {
                        t,
                        weight: chain.weight(probs),
                        density: d,
                    };
                }
                chain.f *= sigma_n;
                chain.p *= p_rest * (V::ONE - p_real) * major;
                chain.renormalise();
                stats.null_collisions += 1;
                if chain.p.is_zero() {
                    return Flight::Escape { weight: Rgb::ZERO };
                }
            }
        }
        Flight::Escape {
            weight: chain.weight(probs),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::majorant::Bounds;
    use crate::tracking::test_support::{test_density, test_segments, Stream, TestBounds};
    use std::cell::Cell;

    /// `choice`'s flight over the test segments tracked in RGB (stream `u`, statistics `s1`) and
    /// in one scalar (`v`, `s2`), each with point bounds made by `bounds`.
    #[allow(clippy::too_many_arguments)]
    fn rgb_and_grey<P: PointBounds>(
        choice: &HeroChoice,
        coeff: &DensityCoefficients,
        grey: &Coefficients<f32>,
        bounds: impl Fn() -> P,
        u: &mut Stream,
        v: &mut Stream,
        s1: &mut TrackingStats,
        s2: &mut TrackingStats,
    ) -> (Flight, Flight) {
        let rgb = coeff.rgb();
        (
            choice.track(
                test_segments(),
                &rgb,
                test_density,
                bounds(),
                &mut || u.next(),
                s1,
            ),
            choice.track(
                test_segments(),
                grey,
                test_density,
                bounds(),
                &mut || v.next(),
                s2,
            ),
        )
    }

    #[test]
    fn grey_flights_are_the_rgb_flights_bit_for_bit() {
        let coeffs = [
            DensityCoefficients::new(Rgb::splat(0.8), Rgb::splat(0.7)),
            DensityCoefficients {
                base_t: Rgb::splat(0.2),
                base_s: Rgb::splat(0.1),
                ..DensityCoefficients::new(Rgb::splat(1.0), Rgb::splat(0.5))
            },
        ];
        let betas = [Rgb::ONE, Rgb::new(0.2, 0.5, 0.9), Rgb::new(1e-30, 0.0, 3.0)];
        let (mut scatters, mut violations) = (0, 0);
        for (ci, coeff) in coeffs.iter().enumerate() {
            let Some(grey) = coeff.grey() else {
                panic!("coefficients {ci} are grey");
            };
            for decompose in [false, true] {
                for (bi, &beta) in betas.iter().enumerate() {
                    for seed in 0..400u64 {
                        let probs = hero_probabilities(beta, coeff);
                        let mut u = Stream::new(seed);
                        let hero = pick_channel(probs, u.next());
                        let choice = HeroChoice {
                            probs,
                            hero,
                            decompose,
                            local_control: false,
                        };
                        let mut v = Stream::new(seed);
                        let _ = v.next();
                        let (mut s1, mut s2) = (TrackingStats::default(), TrackingStats::default());
                        let local = seed % 2 == 0;
                        let (u, v, s1, s2) = (&mut u, &mut v, &mut s1, &mut s2);
                        let (rgb, scalar) = if local {
                            rgb_and_grey(&choice, coeff, &grey, || TestBounds, u, v, s1, s2)
                        } else {
                            rgb_and_grey(&choice, coeff, &grey, || NoPointBounds, u, v, s1, s2)
                        };
                        let case =
                            format!("coeff {ci}, decompose {decompose}, beta {bi}, seed {seed}");
                        assert_eq!(rgb, scalar, "{case}");
                        assert_eq!(s1, s2, "{case}");
                        assert_eq!(u.draws, v.draws, "{case}");
                        violations += s1.violations;
                        if matches!(rgb, Flight::Scatter { .. }) {
                            scatters += 1;
                        }
                    }
                }
            }
        }
        // Both outcomes were exercised, and violations (negative weights) too.
        assert!(
            scatters > 500 && scatters < 4000 && violations > 100,
            "{scatters} {violations}"
        );
    }

    fn close(a: Rgb, b: Rgb, rel: f32) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() <= rel * b[k].abs().max(1e-30))
    }

    /// Proven point bounds with a coarser bound of their own (`probe`), counting the calls
    /// of each method in cells outside it: what a lent probe must forward.
    struct CountingBounds<'c> {
        at: &'c Cell<u32>,
        probes: &'c Cell<u32>,
    }

    impl PointBounds for CountingBounds<'_> {
        fn at(&mut self, t: f32) -> Option<(f32, f32)> {
            self.at.set(self.at.get() + 1);
            let d = test_density(t);
            Some(((d - 0.05).max(0.0), (d + 0.05).min(1.0)))
        }
        fn probe(&mut self, t: f32, skip: impl FnOnce(f32) -> bool) -> Probe {
            self.probes.set(self.probes.get() + 1);
            if skip((test_density(t) + 0.1).min(1.0)) {
                return Probe::Skipped;
            }
            Probe::from_bounds(self.at(t))
        }
        fn proven_minorant(&self) -> bool {
            true
        }
    }

    /// One flight with [`CountingBounds`] moved into the tracker or lent to it: the flight,
    /// the counters, the numbers drawn and the bounds' calls.
    fn counted_flight(
        coeff: &DensityCoefficients,
        seed: u64,
        decompose: bool,
        lend: bool,
    ) -> (Flight, TrackingStats, u32, u32, u32) {
        let (at, probes) = (Cell::new(0), Cell::new(0));
        let mut u = Stream::new(seed);
        let mut stats = TrackingStats::default();
        let mut bounds = CountingBounds {
            at: &at,
            probes: &probes,
        };
        let beta = Rgb::new(0.3, 0.6, 0.9);
        let (segs, d) = (test_segments(), test_density);
        let flight = match (decompose, lend) {
            (false, false) => {
                delta_track_local(segs, coeff, d, bounds, beta, &mut || u.next(), &mut stats)
            }
            (false, true) => delta_track_local(
                segs,
                coeff,
                d,
                &mut bounds,
                beta,
                &mut || u.next(),
                &mut stats,
            ),
            (true, false) => decomposition_track_local(
                segs,
                coeff,
                d,
                bounds,
                beta,
                &mut || u.next(),
                &mut stats,
            ),
            (true, true) => decomposition_track_local(
                segs,
                coeff,
                d,
                &mut bounds,
                beta,
                &mut || u.next(),
                &mut stats,
            ),
        };
        (flight, stats, u.draws, at.get(), probes.get())
    }

    #[test]
    fn lent_point_bounds_track_as_the_bounds_themselves() {
        let coeffs = [
            // Grey without a constant part: the proven minorant's control part applies.
            DensityCoefficients::new(Rgb::splat(0.8), Rgb::splat(0.7)),
            DensityCoefficients::new(Rgb::new(0.5, 0.8, 1.1), Rgb::new(0.4, 0.7, 0.6)),
        ];
        let (mut skipped, mut unlooked) = (0u64, 0u64);
        for coeff in &coeffs {
            for seed in 0..1500u64 {
                let decompose = seed % 3 == 0;
                let own = counted_flight(coeff, seed, decompose, false);
                let lent = counted_flight(coeff, seed, decompose, true);
                assert_eq!(own.0, lent.0, "seed {seed}");
                assert_eq!(own.1, lent.1, "seed {seed}");
                assert_eq!(
                    (own.2, own.3, own.4),
                    (lent.2, lent.3, lent.4),
                    "seed {seed}"
                );
                skipped += lent.1.probed;
                // Real collisions decided without a lookup (a control part).
                unlooked +=
                    u64::from(matches!(lent.0, Flight::Scatter { .. }) && lent.1.lookups == 0);
            }
        }
        // The coarser bound skipped lookups, and control parts decided collisions.
        assert!(skipped > 1000 && unlooked > 20, "{skipped} {unlooked}");
    }

    /// Point bounds that hold: a band around the density, the whole range, or none.
    struct ProvenBounds;

    impl PointBounds for ProvenBounds {
        fn at(&mut self, t: f32) -> Option<(f32, f32)> {
            let d = test_density(t);
            match ((t * 13.0) as i32).rem_euclid(3) {
                0 => None,
                1 => Some(((d - 0.05).max(0.0), (d + 0.05).min(1.0))),
                _ => Some((0.0, 1.0)),
            }
        }
        fn proven_minorant(&self) -> bool {
            true
        }
    }

    #[test]
    fn grey_flights_without_a_constant_part_are_delta_tracking_up_to_rounding() {
        // Proven bounds: the density (in [0.05, 0.95] beyond t = 0.6) never leaves them.
        let b = |min, max| Bounds {
            min,
            max,
            mean: 0.5,
        };
        let segments = || {
            vec![
                MajorantSegment::new(0.0, 0.4, b(0.0, 1.0), true),
                MajorantSegment::constant(0.4, 0.6, 0.5),
                MajorantSegment::new(0.6, 1.3, b(0.04, 0.96), true),
                MajorantSegment::new(1.3, 3.0, b(0.04, 0.96), true),
            ]
        };
        let coeff = DensityCoefficients::new(Rgb::splat(0.8), Rgb::splat(0.7));
        let (mut lookups, mut delta_lookups, mut scatters) = (0, 0, 0);
        for (bi, beta) in [Rgb::ONE, Rgb::new(0.2, 0.5, 0.9)].into_iter().enumerate() {
            for seed in 0..2000u64 {
                // The public tracker (grey, decomposed) against the RGB delta tracker.
                let mut u = Stream::new(seed);
                let (mut s1, mut s2) = (TrackingStats::default(), TrackingStats::default());
                let grey = if seed % 2 == 0 {
                    delta_track_local(
                        segments(),
                        &coeff,
                        test_density,
                        ProvenBounds,
                        beta,
                        &mut || u.next(),
                        &mut s1,
                    )
                } else {
                    delta_track(
                        segments(),
                        &coeff,
                        test_density,
                        beta,
                        &mut || u.next(),
                        &mut s1,
                    )
                };
                let probs = hero_probabilities(beta, &coeff);
                let mut v = Stream::new(seed);
                let hero = pick_channel(probs, v.next());
                let choice = HeroChoice {
                    probs,
                    hero,
                    decompose: false,
                    local_control: false,
                };
                let rgb = if seed % 2 == 0 {
                    choice.track(
                        segments(),
                        &coeff.rgb(),
                        test_density,
                        ProvenBounds,
                        &mut || v.next(),
                        &mut s2,
                    )
                } else {
                    choice.track(
                        segments(),
                        &coeff.rgb(),
                        test_density,
                        NoPointBounds,
                        &mut || v.next(),
                        &mut s2,
                    )
                };
                let case = format!("beta {bi}, seed {seed}");
                assert_eq!(u.draws, v.draws, "{case}");
                let (w1, w2) = match (grey, rgb) {
                    (
                        Flight::Scatter {
                            t: t1, weight: w1, ..
                        },
                        Flight::Scatter {
                            t: t2, weight: w2, ..
                        },
                    ) => {
                        assert_eq!(t1, t2, "{case}");
                        scatters += 1;
                        (w1, w2)
                    }
                    (Flight::Escape { weight: w1 }, Flight::Escape { weight: w2 }) => (w1, w2),
                    _ => panic!("{case}: {grey:?} against {rgb:?}"),
                };
                assert!(close(w1, w2, 1e-5), "{case}: {w1:?} against {w2:?}");
                assert_eq!(s1.real_collisions, s2.real_collisions, "{case}");
                lookups += s1.lookups;
                delta_lookups += s2.lookups;
            }
        }
        assert!(scatters > 1000 && scatters < 3000, "{scatters}");
        // Real collisions below the proven local minorants need no lookup.
        assert!(
            lookups * 20 < delta_lookups * 19,
            "{lookups} {delta_lookups}"
        );
    }

    #[test]
    fn weight_is_the_contribution_over_the_mixture_of_hero_probabilities() {
        let chain = MisChain {
            f: Rgb::new(1.0, 2.0, 3.0),
            p: Rgb::new(0.5, 1.0, 2.0),
        };
        let probs = [0.2, 0.3, 0.5];
        let mix = 0.2 * 0.5 + 0.3 * 1.0 + 0.5 * 2.0;
        assert!(close(
            chain.weight(probs),
            Rgb::new(1.0, 2.0, 3.0) / mix,
            1e-6
        ));
    }

    #[test]
    fn renormalising_keeps_the_weight() {
        for scale in [1e-30f32, 1e-25, 1e25, 1e30] {
            let mut chain = MisChain {
                f: Rgb::new(1.0, 2.0, 0.0) * scale,
                p: Rgb::new(1.0, 3.0, 1.0) * scale,
            };
            let probs = [0.25, 0.25, 0.5];
            let before = chain.weight(probs);
            chain.renormalise();
            assert!(
                (chain.p.max_component() - 1.0).abs() < 1e-6,
                "scale {scale}"
            );
            assert!(close(chain.weight(probs), before, 1e-5), "scale {scale}");
        }
        // Within the safe range nothing changes.
        let mut chain = MisChain {
            f: Rgb::new(4.0, 5.0, 6.0),
            p: Rgb::new(7.0, 8.0, 9.0),
        };
        chain.renormalise();
        assert_eq!(chain.f, Rgb::new(4.0, 5.0, 6.0));
        assert_eq!(chain.p, Rgb::new(7.0, 8.0, 9.0));
    }

    #[test]
    fn a_path_no_channel_could_take_weighs_nothing() {
        let zero = MisChain {
            f: Rgb::ONE,
            p: Rgb::ZERO,
        };
        assert_eq!(zero.weight([1.0 / 3.0; 3]), Rgb::ZERO);
        let overflow = MisChain {
            f: Rgb::ONE,
            p: Rgb::splat(f32::INFINITY),
        };
        assert_eq!(overflow.weight([1.0 / 3.0; 3]), Rgb::ZERO);
    }
}
