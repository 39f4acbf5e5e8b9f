//! Chi-square goodness-of-fit harness for direction-sampling routines (BSDFs, phase
//! functions, visible normals): [`chi2_sphere`] histograms the samples, [`assert_chi2`] judges
//! the report.
//!
//! The sphere is split into `n_theta × n_phi` cells in `(x, φ)` around an `axis`, where
//! `x ∈ [0, 1]` maps to `cosθ = ±(1 − (1 − |1 − 2x|)^power)` (sign of `1 − 2x`): `power = 1`
//! gives cells uniform in cosθ, `power > 1` concentrates cells near both poles `±axis` (for
//! peaked lobes). Expected counts come from Gauss–Legendre
//! quadrature of the pdf over each cell (in f64), `N ∫_cell pdf` with `N` the number of
//! attempts; cells with expected count < 5 are pooled into one (Cochran's rule). Failed
//! samples (`None`) are checked separately: the success fraction must match `∫ pdf` (binomial
//! z-test plus a quadrature tolerance), since the pdf of a sampler that can fail integrates to
//! its success probability.
//!
//! Significance: each case is rejected at p < [`SIGNIFICANCE`] = 1e-4. A Bonferroni argument
//! bounds the family-wise false-alarm rate of a suite of K cases by K × 1e-4 (≤ 1 % for the
//! ≤ 100 cases of this project's suites); all seeds are fixed, so results are reproducible.

use velour::math::{Frame, Vec3};
use velour::sampling::Rng;

use super::chi2::p_value as chi2_p_value;
use super::stats::binomial_standard_error;

/// Per-case significance level (see the module docs for the multiple-test note).
pub const SIGNIFICANCE: f64 = 1e-4;

/// Accepted quadrature error of `∫ pdf` (kinks at the horizon limit Gauss–Legendre accuracy).
pub const QUADRATURE_TOLERANCE: f64 = 2e-3;

/// Binning of the sphere around an axis.
#[derive(Clone, Copy, Debug)]
pub struct SphereBins {
    /// Polar axis of the binning.
    pub axis: Vec3,
    /// Cells along x (θ).
    pub n_theta: usize,
    /// Cells along φ.
    pub n_phi: usize,
    /// Warp exponent (1 = uniform in cosθ).
    pub power: f64,
}

impl SphereBins {
    /// Uniform-in-cosθ bins around +z.
    pub fn uniform(n_theta: usize, n_phi: usize) -> Self {
        SphereBins {
            axis: Vec3::Z,
            n_theta,
            n_phi,
            power: 1.0,
        }
    }
    /// Bins concentrated around `±axis` with warp `power`.
    pub fn around(axis: Vec3, n_theta: usize, n_phi: usize, power: f64) -> Self {
        SphereBins {
            axis: axis.normalize(),
            n_theta,
            n_phi,
            power,
        }
    }

    fn cell_of(&self, frame: &Frame, w: Vec3) -> Option<usize> {
        let l = frame.to_local(w);
        let cos_t = (l.z as f64).clamp(-1.0, 1.0);
        let x = cos_to_x(cos_t, self.power);
        let phi = (l.y as f64).atan2(l.x as f64); // [-π, π]
        let i = ((x * self.n_theta as f64) as usize).min(self.n_theta - 1);
        let j = (((phi + std::f64::consts::PI) / (2.0 * std::f64::consts::PI) * self.n_phi as f64)
            as usize)
            .min(self.n_phi - 1);
        if !w.is_finite() {
            return None;
        }
        Some(i * self.n_phi + j)
    }
}

/// Outcome of one chi-square case.
#[derive(Clone, Debug)]
pub struct Chi2Report {
    /// Pearson statistic.
    pub chi2: f64,
    /// Degrees of freedom (cells after pooling − 1).
    pub dof: usize,
    /// Upper-tail probability.
    pub p_value: f64,
    /// ∫ pdf over the sphere by quadrature.
    pub integral: f64,
    /// Fraction of successful samples.
    pub success: f64,
    /// Number of attempts.
    pub samples: usize,
    /// Samples that fell in cells with zero expected mass (a hard failure when > 0).
    pub impossible: u64,
}

const GL4_X: [f64; 4] = [
    -0.861_136_311_594_052_6,
    -0.339_981_043_584_856_3,
    0.339_981_043_584_856_3,
    0.861_136_311_594_052_6,
];
const GL4_W: [f64; 4] = [
    0.347_854_845_137_453_9,
    0.652_145_154_862_546_1,
    0.652_145_154_862_546_1,
    0.347_854_845_137_453_9,
];

/// Gauss–Legendre 4×4 integral of `pdf` over the (x, φ) rectangle (with the area Jacobian).
fn gl_rect(
    frame: &Frame,
    p: f64,
    x0: f64,
    x1: f64,
    f0: f64,
    f1: f64,
    pdf: &dyn Fn(Vec3) -> f64,
) -> f64 {
    let (hx, hf) = (0.5 * (x1 - x0), 0.5 * (f1 - f0));
    let mut acc = 0.0;
    for (gx, wx) in GL4_X.iter().zip(GL4_W.iter()) {
        let x = x0 + hx * (1.0 + gx);
        let (cos_t, jac) = x_to_cos(x, p);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        for (gp, wp) in GL4_X.iter().zip(GL4_W.iter()) {
            let phi = f0 + hf * (1.0 + gp);
            let l = Vec3::new(
                (sin_t * phi.cos()) as f32,
                (sin_t * phi.sin()) as f32,
                cos_t as f32,
            );
            let w = frame.to_world(l).normalize();
            let v = pdf(w);
            assert!(v.is_finite() && v >= 0.0, "pdf returned {v} at {w:?}");
            acc += wx * wp * v * jac;
        }
    }
    acc * hx * hf
}

/// Adaptive refinement: split into 2×2 until the refined and coarse estimates agree.
#[allow(clippy::too_many_arguments)]
fn adaptive_rect(
    frame: &Frame,
    p: f64,
    x0: f64,
    x1: f64,
    f0: f64,
    f1: f64,
    coarse: f64,
    depth: u32,
    pdf: &dyn Fn(Vec3) -> f64,
) -> f64 {
    let (xm, fm) = (0.5 * (x0 + x1), 0.5 * (f0 + f1));
    let q = [
        gl_rect(frame, p, x0, xm, f0, fm, pdf),
        gl_rect(frame, p, xm, x1, f0, fm, pdf),
        gl_rect(frame, p, x0, xm, fm, f1, pdf),
        gl_rect(frame, p, xm, x1, fm, f1, pdf),
    ];
    let fine: f64 = q.iter().sum();
    if depth == 0 || (fine - coarse).abs() <= 1e-6 + 1e-4 * fine.abs() {
        return fine;
    }
    adaptive_rect(frame, p, x0, xm, f0, fm, q[0], depth - 1, pdf)
        + adaptive_rect(frame, p, xm, x1, f0, fm, q[1], depth - 1, pdf)
        + adaptive_rect(frame, p, x0, xm, fm, f1, q[2], depth - 1, pdf)
        + adaptive_rect(frame, p, xm, x1, fm, f1, q[3], depth - 1, pdf)
}

/// Maps the bin coordinate x ∈ [0, 1] to cosθ (symmetric power warp, fine at both poles) and
/// returns |dcosθ/dx|.
fn x_to_cos(x: f64, p: f64) -> (f64, f64) {
    let s = 1.0 - 2.0 * x;
    let r = (1.0 - s.abs()).max(0.0);
    let cos_t = (1.0 - r.powf(p)).copysign(s);
    let jac = 2.0 * p * r.powf(p - 1.0);
    (cos_t.clamp(-1.0, 1.0), jac)
}

/// Inverse of [`x_to_cos`].
fn cos_to_x(cos_t: f64, p: f64) -> f64 {
    let c = cos_t.clamp(-1.0, 1.0);
    let s = (1.0 - (1.0 - c.abs()).max(0.0).powf(1.0 / p)).copysign(c);
    0.5 * (1.0 - s)
}

/// Integrates `pdf` over every cell of `bins` (adaptive Gauss–Legendre 4×4, starting from
/// `sub × sub` sub-cells per cell).
pub fn integrate_cells(bins: &SphereBins, sub: usize, pdf: &dyn Fn(Vec3) -> f64) -> Vec<f64> {
    let frame = Frame::from_normal(bins.axis);
    let p = bins.power;
    let mut out = vec![0.0; bins.n_theta * bins.n_phi];
    let dx = 1.0 / (bins.n_theta * sub) as f64;
    let dphi = 2.0 * std::f64::consts::PI / (bins.n_phi * sub) as f64;
    for i in 0..bins.n_theta * sub {
        let x0 = i as f64 * dx;
        for j in 0..bins.n_phi * sub {
            let f0 = -std::f64::consts::PI + j as f64 * dphi;
            let coarse = gl_rect(&frame, p, x0, x0 + dx, f0, f0 + dphi, pdf);
            let v = adaptive_rect(&frame, p, x0, x0 + dx, f0, f0 + dphi, coarse, 4, pdf);
            out[(i / sub) * bins.n_phi + j / sub] += v;
        }
    }
    out
}

/// ∫ pdf dω over the sphere by quadrature.
pub fn integrate_sphere(bins: &SphereBins, sub: usize, pdf: &dyn Fn(Vec3) -> f64) -> f64 {
    integrate_cells(bins, sub, pdf).iter().sum()
}

/// Runs one chi-square case: draws `n` samples (`sample` returns `None` for a failed sample),
/// histograms them in `bins`, and compares with `n × ∫_cell pdf`.
pub fn chi2_sphere(
    bins: &SphereBins,
    sub: usize,
    n: usize,
    seed: u64,
    mut sample: impl FnMut(&mut Rng) -> Option<Vec3>,
    pdf: &dyn Fn(Vec3) -> f64,
) -> Chi2Report {
    let frame = Frame::from_normal(bins.axis);
    let mut rng = Rng::new(seed, 0x5eed);
    let ncell = bins.n_theta * bins.n_phi;
    let mut obs = vec![0u64; ncell];
    let mut failed = 0u64;
    for _ in 0..n {
        match sample(&mut rng).and_then(|w| bins.cell_of(&frame, w)) {
            Some(c) => obs[c] += 1,
            None => failed += 1,
        }
    }
    let mass = integrate_cells(bins, sub, pdf);
    let integral: f64 = mass.iter().sum();
    let nf = n as f64;
    let cells: Vec<(f64, f64)> = mass
        .iter()
        .zip(obs.iter())
        .map(|(m, &o)| (m * nf, o as f64))
        .collect();
    let mut impossible = 0u64;
    let mut pooled = (0.0, 0.0);
    let mut kept = Vec::new();
    for &(e, o) in &cells {
        if e <= 0.0 {
            impossible += o as u64;
        } else if e < 5.0 {
            pooled.0 += e;
            pooled.1 += o;
        } else {
            kept.push((e, o));
        }
    }
    if pooled.0 > 0.0 {
        kept.push(pooled);
    }
    let chi2: f64 = kept.iter().map(|(e, o)| (o - e) * (o - e) / e).sum();
    let dof = kept.len().saturating_sub(1).max(1);
    let p_value = if impossible > 0 {
        0.0
    } else {
        chi2_p_value(chi2, dof)
    };
    Chi2Report {
        chi2,
        dof,
        p_value,
        integral,
        success: 1.0 - failed as f64 / nf,
        samples: n,
        impossible,
    }
}

/// Asserts that a report passes at [`SIGNIFICANCE`], with a readable message.
pub fn assert_chi2(name: &str, r: &Chi2Report) {
    assert!(
        r.impossible == 0,
        "{name}: {} samples landed where the pdf is zero ({r:?})",
        r.impossible
    );
    let sigma = binomial_standard_error(r.success, r.samples);
    assert!(
        (r.success - r.integral).abs() <= 4.0 * sigma + QUADRATURE_TOLERANCE,
        "{name}: success fraction {} but ∫pdf = {} ({r:?})",
        r.success,
        r.integral
    );
    assert!(
        r.p_value > SIGNIFICANCE,
        "{name}: chi-square rejects the sampler: chi2 = {:.1}, dof = {}, p = {:.3e} (integral {:.5}, success {:.5})",
        r.chi2,
        r.dof,
        r.p_value,
        r.integral,
        r.success
    );
}

/// A direction from polar angle `theta_deg` (degrees) in the xz-plane, +z up.
pub fn dir_from_theta_deg(theta_deg: f32) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}
