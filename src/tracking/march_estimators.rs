//! Transmittance from ray-marched optical depths, per majorant segment: unbiased ray marching
//! (Kettunen, d'Eon, Pantaleoni, Novák 2021) and the jackknife estimator (Peters 2025,
//! biased, fixed cost). docs/references.md §11.1–11.2.
//!
//! Both march "combs" of `M` equidistant lookups over a segment; `M` follows the segment's
//! coarse optical depth τ_c (its mean density × length × extinction):
//! `N_CMF(τ) = ⌈∛((0.015 + τ)(0.65 + τ)(60.3 + τ))⌉`, `M = max(1, round(N_CMF / 1.31945))`.
//! Optical depths are per RGB channel: one density integral per comb serves every channel.

use crate::majorant::MajorantSegment;
use crate::spectrum::Rgb;

use super::{DensityCoefficients, TrackingStats};

/// The largest order of the URM series (P(N > 16) ≈ 2·10⁻¹¹: the truncation is negligible).
pub const URM_MAX_ORDER: usize = 16;

/// P(N = 0) of the order's roulette ("aggressive" Bhanot–Kennedy).
const URM_P_ZERO: f64 = 0.9;

/// Teeth per comb for coarse optical depth `tau` (the expected lookups of URM stay near
/// `N_CMF(τ)`).
#[must_use]
pub fn comb_teeth(tau: f32) -> u32 {
    let t = f64::from(tau.max(0.0));
    let n_cmf = ((0.015 + t) * (0.65 + t) * (60.3 + t)).cbrt().ceil();
    ((n_cmf / 1.31945).round() as u32).clamp(1, 1 << 16)
}

/// P(N ≥ k) of the order roulette: 1 for k = 0, 0.1 for k = 1, 2, then 0.1 · Π_{i=3..k} 2/i.
#[must_use]
pub fn order_survival(k: usize) -> f64 {
    match k {
        0 => 1.0,
        1 | 2 => 1.0 - URM_P_ZERO,
        _ => (3..=k).fold(1.0 - URM_P_ZERO, |p, i| p * (2.0 / i as f64).min(1.0)),
    }
}

/// Draws the series order N (0 with probability 0.9; else at least 2, each further order k
/// surviving with probability min(1, 2/k)), capped at [`URM_MAX_ORDER`].
fn sample_order(u: &mut impl FnMut() -> f32) -> usize {
    if f64::from(u()) < URM_P_ZERO {
        return 0;
    }
    let mut n = 2;
    while n < URM_MAX_ORDER && f64::from(u()) < (2.0 / (n + 1) as f64).min(1.0) {
        n += 1;
    }
    n
}

/// The integral of the density over the segment by a comb of `teeth` lookups, all shifted by
/// one offset (`jitter = false`) or each jittered in its own stratum.
fn comb_integral(
    seg: &MajorantSegment,
    teeth: u32,
    jitter: bool,
    density: &mut impl FnMut(f32) -> f32,
    u: &mut impl FnMut() -> f32,
    stats: &mut TrackingStats,
) -> f64 {
    let len = seg.length();
    let h = len / teeth as f32;
    let shift = u();
    let mut sum = 0.0f64;
    for m in 0..teeth {
        let offset = if jitter && m > 0 { u() } else { shift };
        sum += f64::from(density(seg.t0 + (m as f32 + offset) * h));
        stats.transmittance_lookups += 1;
    }
    sum * f64::from(h)
}

/// Per-channel optical depth of a density integral `d` over a segment of length `len`.
fn depth(coeff: &DensityCoefficients, d: f64, len: f32) -> [f64; 3] {
    [0, 1, 2].map(|c| f64::from(coeff.sigma_t[c]) * d + f64::from(coeff.base_t[c]) * f64::from(len))
}

/// The coarse optical depth of a segment: its mean density, largest channel.
fn coarse_depth(seg: &MajorantSegment, coeff: &DensityCoefficients) -> f32 {
    coeff.sigma_t_at(seg.mean).max_component() * seg.length()
}

/// Elementary symmetric means of `d`: `m[k]` is the mean over every k-subset of the product
/// of its elements (`m[0] = 1`), by the O(N²) recurrence of Kettunen et al. 2021.
fn elementary_symmetric_means(d: &[f64], m: &mut [f64]) {
    m.iter_mut().for_each(|x| *x = 0.0);
    m[0] = 1.0;
    for (n, &dn) in d.iter().enumerate() {
        let n = n + 1;
        for k in (1..=n).rev() {
            m[k] += (k as f64 / n as f64) * (m[k - 1] * dn - m[k]);
        }
    }
}

/// Unbiased ray marching over one segment: an unbiased estimate of its RGB transmittance
/// (values outside [0, 1] occur and must not be clamped).
pub fn unbiased_ray_march_segment(
    seg: &MajorantSegment,
    coeff: &DensityCoefficients,
    density: &mut impl FnMut(f32) -> f32,
    u: &mut impl FnMut() -> f32,
    stats: &mut TrackingStats,
) -> Rgb {
    let teeth = comb_teeth(coarse_depth(seg, coeff));
    let order = sample_order(u);
    let mut x = [[0.0f64; 3]; URM_MAX_ORDER + 1];
    for xj in x.iter_mut().take(order + 1) {
        *xj = depth(
            coeff,
            comb_integral(seg, teeth, false, density, u, stats),
            seg.length(),
        );
    }
    // 1/(k! P(N ≥ k)) for the orders present.
    let mut weight = [0.0f64; URM_MAX_ORDER + 1];
    let mut factorial = 1.0f64;
    for (k, w) in weight.iter_mut().enumerate().take(order + 1) {
        if k > 0 {
            factorial *= k as f64;
        }
        *w = 1.0 / (factorial * order_survival(k));
    }
    let mut out = [0.0f64; 3];
    let mut diffs = [0.0f64; URM_MAX_ORDER];
    let mut means = [0.0f64; URM_MAX_ORDER + 1];
    for (c, value) in out.iter_mut().enumerate() {
        let mut sum = 0.0;
        for i in 0..=order {
            let mut n = 0;
            for (j, xj) in x.iter().enumerate().take(order + 1) {
                if j != i {
                    diffs[n] = x[i][c] - xj[c];
                    n += 1;
                }
            }
            elementary_symmetric_means(&diffs[..n], &mut means[..=n]);
            let series: f64 = (0..=n).map(|k| means[k] * weight[k]).sum();
            sum += (-x[i][c]).exp() * series;
        }
        *value = sum / (order + 1) as f64;
    }
    Rgb(out.map(|v| v as f32))
}

/// The jackknife transmittance of one segment (Peters 2025): two independent jittered combs
/// give X₁, X₂; with m = (X₁ + X₂)/2 and s = |X₁ − X₂|/2 the estimate is cos(s)·e^(−m). Biased
/// (exact for normally distributed X), at a fixed cost of two combs.
pub fn jackknife_segment(
    seg: &MajorantSegment,
    coeff: &DensityCoefficients,
    density: &mut impl FnMut(f32) -> f32,
    u: &mut impl FnMut() -> f32,
    stats: &mut TrackingStats,
) -> Rgb {
    let teeth = comb_teeth(coarse_depth(seg, coeff));
    let a = depth(
        coeff,
        comb_integral(seg, teeth, true, density, u, stats),
        seg.length(),
    );
    let b = depth(
        coeff,
        comb_integral(seg, teeth, true, density, u, stats),
        seg.length(),
    );
    Rgb([0, 1, 2].map(|c| {
        let m = 0.5 * (a[c] + b[c]);
        let s = 0.5 * (a[c] - b[c]).abs();
        (s.cos() * (-m).exp()) as f32
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symmetric_means_match_brute_force_over_subsets() {
        let d = [0.3, -1.2, 2.5, 0.7, -0.4, 1.1];
        let mut m = [0.0; 7];
        elementary_symmetric_means(&d, &mut m);
        for (k, mk) in m.iter().enumerate() {
            let mut sum = 0.0;
            let mut count = 0.0;
            for mask in 0u32..(1 << d.len()) {
                if mask.count_ones() as usize == k {
                    let p: f64 = (0..d.len())
                        .filter(|i| mask & (1 << i) != 0)
                        .map(|i| d[i])
                        .product();
                    sum += p;
                    count += 1.0;
                }
            }
            assert!(
                (mk - sum / count).abs() < 1e-12,
                "k = {k}: {} vs {}",
                mk,
                sum / count
            );
        }
    }

    #[test]
    fn order_roulette_has_the_stated_survival_and_mean() {
        // E[N] = Σ_{k≥1} P(N ≥ k) = 0.1 (2 + (e² − 5)/2) = 0.31945 (before the cap).
        let mean: f64 = (1..=URM_MAX_ORDER).map(order_survival).sum();
        assert!((mean - 0.319_45).abs() < 1e-4, "{mean}");
        assert!((order_survival(2) - 0.1).abs() < 1e-15);
        assert!((order_survival(4) - 0.1 * (2.0 / 3.0) * 0.5).abs() < 1e-15);
        let mut rng = crate::sampling::Rng::new(4, 4);
        let n = 400_000;
        let mut at_least = [0usize; 6];
        for _ in 0..n {
            let k = sample_order(&mut || rng.next_f32());
            for (j, c) in at_least.iter_mut().enumerate() {
                if k >= j {
                    *c += 1;
                }
            }
        }
        for (j, &c) in at_least.iter().enumerate() {
            let p = order_survival(j);
            let se = (p * (1.0 - p) / n as f64).sqrt().max(1e-9);
            let z = (c as f64 / n as f64 - p) / se;
            assert!(z.abs() < 4.5, "P(N ≥ {j}): z = {z}");
        }
    }

    #[test]
    fn comb_sizes_follow_the_coarse_depth() {
        assert_eq!(comb_teeth(0.5), 3);
        assert_eq!(comb_teeth(1.0), 4);
        assert_eq!(comb_teeth(2.0), 5);
        assert_eq!(comb_teeth(10.0), 15);
    }
}
