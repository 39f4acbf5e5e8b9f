//! Transmittance estimators over majorant segments: ratio tracking, residual ratio tracking
//! with a per-segment control density, and fixed-step ray marching.

use super::grey::{Channels, Coefficients};
use super::{
    ControlVariate, DensityCoefficients, NoPointBounds, PointBounds, TrackingStats,
    TransmittanceMode,
};
use crate::majorant::MajorantSegment;
use crate::spectrum::Rgb;

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
    density: D,
    mode: TransmittanceMode,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Rgb
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    U: FnMut() -> f32,
{
    transmittance_local(segments, coeff, density, NoPointBounds, mode, u, stats)
}

/// [`transmittance`] with point bounds (docs/references.md §4.10): ratio and residual ratio
/// tracking accept each tentative collision of a segment (rate M, its residual majorant) with
/// probability m(x)/M, m(x) the residual majorant of the point's local bounds, without a
/// lookup, and weigh the accepted ones against m(x): ratio tracking with the local majorant,
/// sampled by thinning. Unbiased; the other modes ignore the point bounds. Fewer lookups, but a
/// ratio estimate's variance grows as its majorant tightens (relative second moment
/// exp(∫σ²/m) for constant σ), so the media do not use it: on the dense peer cloud it took 35 %
/// of the shadow rays' lookups at 1.5× the image's relative MSE (docs/references.md §4.10).
pub fn transmittance_local<S, D, P, U>(
    segments: S,
    coeff: &DensityCoefficients,
    density: D,
    local_bounds: P,
    mode: TransmittanceMode,
    u: &mut U,
    stats: &mut TrackingStats,
) -> Rgb
where
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    P: PointBounds,
    U: FnMut() -> f32,
{
    match coeff.grey() {
        Some(grey) => estimate(
            segments,
            coeff,
            &grey,
            density,
            local_bounds,
            mode,
            u,
            stats,
        )
        .to_rgb(),
        None => estimate(
            segments,
            coeff,
            &coeff.rgb(),
            density,
            local_bounds,
            mode,
            u,
            stats,
        ),
    }
}

/// [`transmittance_local`] with the coefficients in channel type `V` (one scalar for a grey
/// medium: the same estimate as in RGB, bit for bit). `rgb` is the same coefficients for the
/// estimators that work in RGB only (unbiased ray marching, the jackknife).
#[allow(clippy::too_many_arguments)]
fn estimate<V, S, D, P, U>(
    segments: S,
    rgb: &DensityCoefficients,
    coeff: &Coefficients<V>,
    mut density: D,
    mut local_bounds: P,
    mode: TransmittanceMode,
    u: &mut U,
    stats: &mut TrackingStats,
) -> V
where
    V: Channels,
    S: IntoIterator<Item = MajorantSegment>,
    D: FnMut(f32) -> f32,
    P: PointBounds,
    U: FnMut() -> f32,
{
    let st = coeff.sigma_t;
    let s_max = st.max_channel();
    let mut tr = V::ONE;
    if s_max <= 0.0 && coeff.base_t.is_zero() {
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
                TransmittanceMode::UnbiasedRayMarch => {
                    tr *= V::from_rgb(super::unbiased_ray_march_segment(
                        &seg,
                        rgb,
                        &mut density,
                        u,
                        stats,
                    ));
                }
                TransmittanceMode::Jackknife => {
                    tr *= V::from_rgb(super::jackknife_segment(&seg, rgb, &mut density, u, stats));
                }
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
                    if !analytic.is_zero() {
                        tr *= analytic.map(|x| (-x).exp());
                    }
                    let majorant = residual_bound * s_max;
                    if majorant > 0.0 && majorant.is_finite() {
                        let mut local = 0.0f32;
                        loop {
                            local += -(1.0 - u()).ln() / majorant;
                            if local >= len {
                                break;
                            }
                            let t = seg.t0 + local;
                            let (mut lo, mut hi, mut major) = (seg.min, seg.max, majorant);
                            if let Some((a, b)) = local_bounds.at(t) {
                                let (a, b) = (a.max(seg.min), b.min(seg.max));
                                if a <= b {
                                    let m = (b - control).max(control - a).max(0.0) * s_max;
                                    if m < majorant {
                                        if u() * majorant >= m {
                                            stats.probed += 1;
                                            continue;
                                        }
                                        major = m;
                                    }
                                    lo = a;
                                    hi = b;
                                }
                            }
                            let d = density(t);
                            stats.transmittance_lookups += 1;
                            if d > hi || d < lo {
                                stats.violations += 1;
                            }
                            tr *= V::ONE - st * ((d - control) / major);
                            if tr.max_channel().abs() < 0.05 {
                                if u() < 0.75 {
                                    return V::splat(0.0);
                                }
                                tr /= 0.25;
                            }
                        }
                    }
                }
            }
        }
        if tr.is_zero() {
            return tr;
        }
    }
    tr
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::test_support::{test_density, test_segments, Stream, TestBounds};

    /// The transmittance over the test segments estimated in RGB (stream `u`, statistics `s1`)
    /// and in one scalar (`v`, `s2`) with `mode`, each with point bounds made by `bounds`.
    #[allow(clippy::too_many_arguments)]
    fn rgb_and_grey<P: PointBounds>(
        coeff: &DensityCoefficients,
        grey: &Coefficients<f32>,
        mode: TransmittanceMode,
        bounds: impl Fn() -> P,
        u: &mut Stream,
        v: &mut Stream,
        s1: &mut TrackingStats,
        s2: &mut TrackingStats,
    ) -> (Rgb, f32) {
        let rgb = coeff.rgb();
        (
            estimate(
                test_segments(),
                coeff,
                &rgb,
                test_density,
                bounds(),
                mode,
                &mut || u.next(),
                s1,
            ),
            estimate(
                test_segments(),
                coeff,
                grey,
                test_density,
                bounds(),
                mode,
                &mut || v.next(),
                s2,
            ),
        )
    }

    #[test]
    fn grey_transmittance_is_the_rgb_estimate_bit_for_bit() {
        let coeffs = [
            DensityCoefficients::new(Rgb::splat(4.0), Rgb::splat(3.6)),
            DensityCoefficients {
                base_t: Rgb::splat(0.7),
                base_s: Rgb::splat(0.2),
                ..DensityCoefficients::new(Rgb::splat(6.0), Rgb::splat(1.5))
            },
        ];
        let modes = [
            TransmittanceMode::Ratio,
            TransmittanceMode::ResidualRatio(ControlVariate::Minorant),
            TransmittanceMode::ResidualRatio(ControlVariate::Mean),
            TransmittanceMode::ResidualRatio(ControlVariate::Novak),
            TransmittanceMode::RayMarch { step: 0.1 },
            TransmittanceMode::UnbiasedRayMarch,
            TransmittanceMode::Jackknife,
        ];
        let (mut zero, mut negative) = (0, 0);
        for (ci, coeff) in coeffs.iter().enumerate() {
            let Some(grey) = coeff.grey() else {
                panic!("coefficients {ci} are grey");
            };
            for mode in modes {
                for seed in 0..300u64 {
                    let (mut u, mut v) = (Stream::new(seed), Stream::new(seed));
                    let (mut s1, mut s2) = (TrackingStats::default(), TrackingStats::default());
                    let (u, v, s1, s2) = (&mut u, &mut v, &mut s1, &mut s2);
                    let (rgb, scalar) = if seed % 2 == 0 {
                        rgb_and_grey(coeff, &grey, mode, || TestBounds, u, v, s1, s2)
                    } else {
                        rgb_and_grey(coeff, &grey, mode, || NoPointBounds, u, v, s1, s2)
                    };
                    let case = format!("coeff {ci}, {mode:?}, seed {seed}");
                    assert_eq!(rgb, Rgb::splat(scalar), "{case}");
                    assert_eq!(s1, s2, "{case}");
                    assert_eq!(u.draws, v.draws, "{case}");
                    zero += usize::from(scalar == 0.0);
                    negative += usize::from(scalar < 0.0);
                }
            }
        }
        // Roulette ended some estimates, violated bounds made some negative.
        assert!(zero > 100 && negative > 10, "{zero} {negative}");
    }

    use crate::majorant::Bounds;

    fn seg(len: f32, min: f32, max: f32, mean: f32) -> MajorantSegment {
        MajorantSegment::new(0.0, len, Bounds { min, max, mean }, true)
    }

    #[test]
    fn minorant_and_mean_controls() {
        let s = seg(1.0, 0.2, 1.0, 0.5);
        assert_eq!(control_density(&s, ControlVariate::Minorant, 3.0), 0.2);
        assert_eq!(control_density(&s, ControlVariate::Mean, 3.0), 0.5);
        // A mean outside the bounds is clamped into them.
        let odd = MajorantSegment { mean: 7.0, ..s };
        assert_eq!(control_density(&odd, ControlVariate::Mean, 3.0), 1.0);
    }

    #[test]
    fn novak_control_moves_from_the_mean_to_the_minorant_with_optical_depth() {
        // σ·L·(max − min) is the optical thickness of the bound's range: thin segments take
        // the mean (the exponent overflows), thick ones approach the minorant.
        let s = seg(1.0, 0.2, 1.0, 0.5);
        let thin = control_density(&s, ControlVariate::Novak, 1e-3);
        let medium = control_density(&s, ControlVariate::Novak, 2.0);
        let thick = control_density(&s, ControlVariate::Novak, 1e4);
        assert_eq!(thin, 0.5);
        assert!(thick > 0.2 && thick < 0.2 + 1e-3, "{thick}");
        // Written in optical units: min + R·(2^{1/(σ L R)} − 1), here R = 0.8.
        let expected = 0.2 + 0.8 * (std::f32::consts::LN_2 / (1.0 * 0.8 * 2.0)).exp_m1();
        assert!(
            (medium - expected.clamp(0.2, 0.5)).abs() < 1e-6,
            "{medium} vs {expected}"
        );
        for sigma in [1e-3f32, 0.1, 1.0, 10.0, 1e3, 1e6] {
            let c = control_density(&s, ControlVariate::Novak, sigma);
            assert!((0.2..=0.5).contains(&c), "σ {sigma}: {c}");
        }
    }

    #[test]
    fn novak_control_of_a_constant_segment_is_its_value() {
        let s = seg(2.0, 0.7, 0.7, 0.7);
        assert_eq!(control_density(&s, ControlVariate::Novak, 5.0), 0.7);
    }
}
