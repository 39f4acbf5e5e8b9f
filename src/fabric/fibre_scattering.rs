//! Fibre scattering for fibre volumes (docs/references.md §7).
//!
//! [`FibrePhase`]: the hair/fibre model of Chiang, Bitterli, Tappan and Burley 2016, "A
//! Practical and Controllable Hair and Fur Model for Production Path Tracing" (CGF 35(2))
//! — lobes R, TT, TRT and the residual `p >= 3` lobe, each switchable — mixed with the
//! far field of a Lambertian cylinder (docs/references.md §7.2), used as the phase function of a
//! fibre volume around the local tangent `t` (§7.3; course notes §3.2: "a combination of R,
//! TT and diffuse lobes").
//!
//! Conventions: `wo` and `wi` both point away from the scattering point (docs/references.md §0(b));
//! `wo` is towards the previous path vertex (the viewer). Values are densities per unit
//! solid angle of `wi`: `∫ eval(wo, wi) dwi` is the (RGB) single-scattering albedo of the
//! collision, `<= 1`, and exactly 1 for `σ_a = 0`, all lobes on and a white diffuse lobe.
//!
//! **The offset `h`.** In a fibre volume the hit offset across the fibre is unknown, so the
//! phase function is `½∫₋₁¹ S(wi, wo; h) dh` (§7.3). Here that integral is the midpoint rule
//! over `N = h_nodes` offsets `h_k = −1 + (2k + 1)/N` (default: automatic from `β_n`), *both*
//! in `eval`/`pdf` and in `sample` (which picks one node uniformly): `eval`, `pdf` and
//! `sample` describe exactly the same function, so `weight = eval/pdf` holds to rounding and
//! the sampler passes chi-square tests against `pdf`. The price is a slight azimuthal ripple
//! when the node spacing in `Φ(p, h)` (≥ `4/N` radians) approaches the logistic width
//! (`≈ 1.8 s`, [`azimuthal_scale`]). Measured L1 difference from 256 nodes (R+TT+TRT): at
//! `β_n = 0.3`, 3.4 % with 16 nodes, 1.2 % with 32; at `β_n = 0.15`, 5.9 % with 32, 1.9 % with
//! 64. The automatic default (`⌈10/β_n⌉`) keeps it near 1 %. Cost is linear in the node count.
//!
//! [`SggxFibrePhase`]: the SGGX microflake alternative (Heitz et al. 2015, §7.4) with
//! `S = σ² t tᵀ + (I − t tᵀ)`, specular flakes.

use super::fibre_fast_math::{asin_fast, exp_neg, fresnel_entering, logistic_unscaled, wrap_fast};
use super::{check_range, invalid, FabricError};
use crate::math::{Frame, Mat3, Vec3, PI};
use crate::spectrum::Rgb;

/// Default `h_nodes`: 0 = automatic, `⌈10/β_n⌉` rounded up to even and clamped to
/// `[8, 128]` (≈ 1 % L1 difference from the exact `h` integral; 34 nodes at `β_n = 0.3`).
pub const DEFAULT_H_NODES: u32 = 0;

const INV_2PI: f32 = 0.5 / PI;

/// Which Chiang lobes are active.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FibreLobes {
    /// Reflection (`p = 0`).
    pub r: bool,
    /// Transmission–transmission (`p = 1`).
    pub tt: bool,
    /// Transmission–reflection–transmission (`p = 2`).
    pub trt: bool,
    /// The residual `p >= 3` lobe (isotropic in azimuth).
    pub residual: bool,
}

impl Default for FibreLobes {
    fn default() -> Self {
        FibreLobes {
            r: true,
            tt: true,
            trt: true,
            residual: true,
        }
    }
}

impl FibreLobes {
    fn on(&self, p: usize) -> bool {
        [self.r, self.tt, self.trt, self.residual][p]
    }
}

/// User parameters of [`FibrePhase`].
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FibrePhaseParams {
    /// Index of refraction of the fibre, `[1, 3]` (textile fibres ≈ 1.5–1.6; default 1.55).
    pub eta: f32,
    /// Longitudinal roughness `β_m`, `[0.01, 1]` (default 0.3).
    pub beta_m: f32,
    /// Azimuthal roughness `β_n`, `[0.01, 1]` (default 0.3).
    pub beta_n: f32,
    /// Cuticle tilt `α` (radians, `[−0.2, 0.2]`; 0 for smooth synthetic fibres; default 0).
    pub alpha: f32,
    /// Absorption coefficient inside the fibre per unit *fibre radius* (each channel
    /// `[0, 1000]`); see [`sigma_a_from_colour`]. Default 0.
    pub sigma_a: Rgb,
    /// Weight `d ∈ [0, 1]` of the diffuse lobe: `S = (1 − d)·S_Chiang + d·S_diffuse`
    /// (default 0.3).
    pub diffuse_weight: f32,
    /// Albedo `A_d` of the diffuse lobe (each channel `[0, 1]`; default white).
    pub diffuse_albedo: Rgb,
    /// Active Chiang lobes (default all).
    pub lobes: FibreLobes,
    /// Offsets `h` of the midpoint quadrature over the fibre width, `0..=256`; 0 (the
    /// default, [`DEFAULT_H_NODES`]) picks `⌈10/β_n⌉` rounded up to even, in `[8, 128]`.
    pub h_nodes: u32,
}

impl Default for FibrePhaseParams {
    fn default() -> Self {
        FibrePhaseParams {
            eta: 1.55,
            beta_m: 0.3,
            beta_n: 0.3,
            alpha: 0.0,
            sigma_a: Rgb::ZERO,
            diffuse_weight: 0.3,
            diffuse_albedo: Rgb::ONE,
            lobes: FibreLobes::default(),
            h_nodes: DEFAULT_H_NODES,
        }
    }
}

impl FibrePhaseParams {
    /// Parameters for a fibre of the given colour (each channel in `(0, 1]`): `σ_a` from
    /// the Chiang 2016 inversion ([`sigma_a_from_colour`]) and diffuse albedo = `colour`.
    /// This is how warp and weft get their own albedo.
    #[must_use]
    pub fn with_colour(mut self, colour: Rgb) -> Self {
        let c = FibreColour::new(colour, self.beta_n);
        self.sigma_a = c.sigma_a;
        self.diffuse_albedo = c.diffuse_albedo;
        self
    }
}

/// The colour-dependent parameters of a [`FibrePhase`]: the fibre's absorption `σ_a` (per
/// unit radius) and the diffuse lobe's albedo. A fibre phase function evaluated with another
/// colour ([`FibrePhase::prepare_coloured`]) is the one [`FibrePhaseParams::with_colour`]
/// would build for that colour, without building it (no allocation): how a textured yarn
/// colour, read per walk, reaches the phase function.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FibreColour {
    /// Absorption inside the fibre per unit fibre radius.
    pub sigma_a: Rgb,
    /// Albedo of the diffuse lobe, each channel in `[0, 1]`.
    pub diffuse_albedo: Rgb,
}

impl FibreColour {
    /// The parameters of a fibre of multiple-scattering colour `colour` (each channel in
    /// `[0, 1]`) for azimuthal roughness `beta_n`: `σ_a` by the Chiang et al. 2016 inversion
    /// ([`sigma_a_from_colour`]), the diffuse albedo `colour` clamped to `[0, 1]`.
    #[must_use]
    pub fn new(colour: Rgb, beta_n: f32) -> Self {
        FibreColour {
            sigma_a: sigma_a_from_colour(colour, beta_n),
            diffuse_albedo: colour.map(|c| c.clamp(0.0, 1.0)),
        }
    }
}

/// Chiang et al. 2016 eq. (9): absorption (per unit radius) that gives multiple-scattering
/// colour `c` for azimuthal roughness `β_n`. Channels are clamped to `[1e-4, 1]`.
#[must_use]
pub fn sigma_a_from_colour(c: Rgb, beta_n: f32) -> Rgb {
    let b = beta_n;
    let d = 5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3)
        + 5.574 * b.powi(4)
        + 0.245 * b.powi(5);
    c.map(|x| (x.clamp(1e-4, 1.0).ln() / d).powi(2))
}

/// Longitudinal variance `v` of Chiang 2016 for `β_m`: `(0.726β + 0.812β² + 3.7β²⁰)²`.
#[must_use]
pub fn longitudinal_variance(beta_m: f32) -> f32 {
    (0.726 * beta_m + 0.812 * beta_m * beta_m + 3.7 * beta_m.powi(20)).powi(2)
}

/// Logistic scale `s` of Chiang 2016 for `β_n`: `√(π/8)(0.265β + 1.194β² + 5.372β²²)`.
#[must_use]
pub fn azimuthal_scale(beta_n: f32) -> f32 {
    (PI / 8.0).sqrt() * (0.265 * beta_n + 1.194 * beta_n * beta_n + 5.372 * beta_n.powi(22))
}

/// The per-lobe constants of [`longitudinal_lobe`] for the four variances `v_p`: `1/v`,
/// `ln 2v` (log form, `v <= 0.1`), `sinh(1/v)·2v` (the direct form's normaliser) and
/// `exp(−2/v)` (the sampler's), each computed by the same expression as where it is used.
#[derive(Clone, Debug, PartialEq)]
struct LongitudinalConsts {
    inv_v: [f32; 4],
    ln_2v: [f32; 4],
    sinh_norm: [f32; 4],
    exp_neg_2_over_v: [f32; 4],
}

impl LongitudinalConsts {
    fn new(v: [f32; 4]) -> Self {
        LongitudinalConsts {
            inv_v: v.map(|v| 1.0 / v),
            ln_2v: v.map(|v| (2.0 * v).ln()),
            sinh_norm: v.map(|v| (1.0 / v).sinh() * 2.0 * v),
            exp_neg_2_over_v: v.map(|v| (-2.0 / v).exp()),
        }
    }
}

/// [`i0`] of four arguments at once (the same operations per lane, so the same bits): the
/// four lobes' series share one vector loop, whose divisions are the series' cost.
#[inline]
fn i0_lanes(x: [f32; 4]) -> [f32; 4] {
    let q = x.map(|x| 0.25 * x * x);
    let mut term = [1.0f32; 4];
    let mut val = [1.0f32; 4];
    for k in 1..20 {
        let kk = (k * k) as f32;
        for l in 0..4 {
            term[l] *= q[l] / kk;
            val[l] += term[l];
        }
    }
    val
}

/// `ln I₀(x)` for `x > 12` ([`log_i0`]'s asymptotic branch).
#[inline]
fn log_i0_asymptotic(x: f32) -> f32 {
    let r = 1.0 / x;
    x - 0.5 * (2.0 * PI * x).ln() + (1.0 + r * (0.125 + r * (9.0 / 128.0))).ln()
}

fn i0(x: f32) -> f32 {
    // Σ_k (x²/4)^k / (k!)², by the term recurrence (no overflow). 20 terms: the 10 of pbrt
    // are 2 % low near x = 12, where `log_i0` switches to the asymptotic form.
    let q = 0.25 * x * x;
    let mut term = 1.0f32;
    let mut val = 1.0f32;
    for k in 1..20 {
        term *= q / (k * k) as f32;
        val += term;
    }
    val
}

fn log_i0(x: f32) -> f32 {
    if x > 12.0 {
        // I₀(x) ≈ eˣ/√(2πx)·(1 + 1/(8x) + 9/(128x²)) (pbrt's form has 1/(16x) in the
        // exponent, 0.5 % low at x = 12).
        log_i0_asymptotic(x)
    } else {
        i0(x).ln()
    }
}

/// The longitudinal lobe `M_p` (d'Eon et al. 2011 form, docs/references.md §7.1) for variance `v`:
/// `csch(1/v)/(2v) · exp(−sinθ_i sinθ_o/v) · I₀(cosθ_i cosθ_o/v)`, log-domain for
/// `v <= 0.1`. Normalised: `∫ M_p cosθ_i dθ_i = 1`.
#[must_use]
pub fn longitudinal_lobe(cos_i: f32, sin_i: f32, cos_o: f32, sin_o: f32, v: f32) -> f32 {
    let a = cos_i * cos_o / v;
    let b = sin_i * sin_o / v;
    if v <= 0.1 {
        (log_i0(a) - b - 1.0 / v + std::f32::consts::LN_2 - (2.0 * v).ln()).exp()
    } else {
        (-b).exp() * i0(a) / ((1.0 / v).sinh() * 2.0 * v)
    }
}

fn logistic(x: f32, s: f32) -> f32 {
    let x = x.abs();
    let e = (-x / s).exp();
    e / (s * (1.0 + e) * (1.0 + e))
}

fn logistic_cdf(x: f32, s: f32) -> f32 {
    1.0 / (1.0 + (-x / s).exp())
}

/// The azimuthal lobe: logistic of scale `s` trimmed to `[−π, π]` and renormalised.
#[must_use]
pub fn trimmed_logistic(x: f32, s: f32) -> f32 {
    logistic(x, s) / (logistic_cdf(PI, s) - logistic_cdf(-PI, s))
}

/// [`trimmed_logistic`] with the precomputed normaliser `1 / (F(π) − F(−π))`.
fn trimmed_logistic_norm(x: f32, s: f32, inv_norm: f32) -> f32 {
    logistic(x, s) * inv_norm
}

/// Samples the trimmed logistic of scale `s` given its mass `k = F(π) − F(−π)` and
/// `cdf_neg_pi = F(−π)` (constants of the phase function).
fn sample_trimmed_logistic(u: f32, s: f32, k: f32, cdf_neg_pi: f32) -> f32 {
    let x = -s * (1.0 / (u * k + cdf_neg_pi) - 1.0).ln();
    x.clamp(-PI, PI)
}

/// The weight by which a lobe (or the diffuse term) of attenuation `a` is chosen, here and
/// in the pdf: its largest channel. The sample weight `value/pdf` of a channel is then at
/// most about the node's total lobe weight (≤ 1 without gain), whatever the yarn's colour;
/// with the channels' average, a saturated yarn's own channel gained up to 3× per bounce on
/// the lobes that carry it and lost as much on the others, and deep walks in one colour
/// drew very uneven weights.
#[inline]
fn lobe_weight(a: Rgb) -> f32 {
    a.max_component()
}

/// Wraps an angle into `[−π, π]`.
fn wrap(mut x: f32) -> f32 {
    while x > PI {
        x -= 2.0 * PI;
    }
    while x < -PI {
        x += 2.0 * PI;
    }
    x
}

/// Unpolarised Fresnel reflectance of a dielectric interface (`eta` = transmitted over
/// incident index), for `cos_i` on the incident side.
fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(-1.0, 1.0);
    let (cos_i, eta) = if cos_i < 0.0 {
        (-cos_i, 1.0 / eta)
    } else {
        (cos_i, eta)
    };
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_par * r_par + r_perp * r_perp)
}

/// The Lambertian-cylinder azimuthal lobe `N_d(Δ) = ((π − |Δ|)cos|Δ| + sin|Δ|)/8`
/// (docs/references.md §7.2; `Δ = 0` is back-scattering).
#[must_use]
pub fn diffuse_azimuthal(delta: f32) -> f32 {
    let d = wrap(delta).abs();
    ((PI - d) * d.cos() + d.sin()) / 8.0
}

/// Projected width of a unit fibre seen from `w`: `sin∠(w, t) = √(1 − (w·t)²)`; fibre-volume
/// extinction is `λ D · extinction_scale` (docs/references.md §7.3).
#[must_use]
pub fn extinction_scale(w: Vec3, tangent: Vec3) -> f32 {
    let c = w.dot(tangent);
    (1.0 - c * c).max(0.0).sqrt()
}

/// A direction sampled from a fibre phase function.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FibreSample {
    /// Sampled direction (unit, pointing away from the scattering point).
    pub wi: Vec3,
    /// `eval(wo, wi) / pdf(wo, wi)` (RGB); 1 in a white furnace.
    pub weight: Rgb,
    /// Solid-angle pdf of `wi`.
    pub pdf: f32,
}

/// Directions of a fibre event in the tangent frame.
#[derive(Clone, Copy, Debug)]
struct Angles {
    sin_t: f32,
    cos_t: f32,
    phi: f32,
}

/// Frame around the (re-normalised) tangent; `None` for a zero or non-finite tangent.
/// The model is symmetric under `t → −t`, so a voxeliser may average tangents as `t tᵀ`.
fn tangent_frame(t: Vec3) -> Option<Frame> {
    let t = t.try_normalize()?;
    Some(Frame::from_normal(t))
}

fn angles(frame: &Frame, w: Vec3) -> Angles {
    let l = frame.to_local(w);
    let sin_t = l.z.clamp(-1.0, 1.0);
    Angles {
        sin_t,
        cos_t: (1.0 - sin_t * sin_t).max(0.0).sqrt(),
        phi: l.y.atan2(l.x),
    }
}

/// The Chiang 2016 + diffuse fibre phase function (see the module docs). Build with
/// [`FibrePhase::new`].
#[derive(Clone, Debug, PartialEq)]
pub struct FibrePhase {
    params: FibrePhaseParams,
    v: [f32; 4],
    /// Per-lobe constants of [`longitudinal_lobe`] that depend only on `v` (computed once
    /// with the same operations, so [`FibrePhase::mp`] gives its bits).
    lon: LongitudinalConsts,
    s: f32,
    /// `F(π) − F(−π)` and `F(−π)` of the logistic of scale `s` (the sampler's constants).
    logistic_mass: f32,
    logistic_cdf_neg_pi: f32,
    sin2k_alpha: [f32; 3],
    cos2k_alpha: [f32; 3],
    inv_logistic_norm: f32,
    /// `(h, γ_o = asin h, cos γ_o)` per quadrature node.
    nodes: Vec<(f32, f32, f32)>,
    /// Whether [`FibrePhase::eval_pdf_prepared`] sums the azimuthal lobes with AVX2.
    avx2: bool,
    /// Which of the three azimuthal lobes can be non-zero: off ([`FibreLobes`]) or with a
    /// diffuse weight of 1, a lobe's attenuations and shares are all 0 and its sums exactly
    /// `+0`, so [`azimuthal_sums`] skips it (the same bits).
    azimuthal_active: [bool; 3],
    /// `h_k` and `cos γ_o(h_k)` of the first [`CACHED_NODES`] nodes (0 past the count), for the
    /// batched terms of [`FibrePhase::prepare`].
    node_h: [f32; CACHED_NODES],
    node_cos_go: [f32; CACHED_NODES],
    /// `γ_o(h_k) = asin h_k` of the first [`CACHED_NODES`] nodes, contiguous for the batched
    /// terms.
    node_gamma_o: [f32; CACHED_NODES],
    /// Prepared vertices for one fixed `wo` over a grid of quantised tangents
    /// ([`FibrePhase::quantised_lobe`]), built on first use.
    quantised: QuantisedLobes,
}

/// Cells per side of the tangent grid of [`FibrePhase::quantised_lobe`]: the tangent's
/// hemisphere (`t` and `−t` share a cell) is mapped octahedrally onto a square of
/// `QUANTISED_GRID²` cells. Chosen on `scenes/draped_cloth.toml` (docs/BENCHMARKS.md).
pub const QUANTISED_GRID: usize = 8;

/// The table of [`FibrePhase::quantised_lobe`]: the outgoing direction it was built for and
/// one prepared vertex per tangent cell.
#[derive(Clone, Debug, Default)]
struct QuantisedLobes(std::sync::OnceLock<(Vec3, Vec<PreparedFibre>)>);

impl PartialEq for QuantisedLobes {
    /// A cache: equal whatever it holds (it is a function of the phase function's parameters).
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// The tangent-grid cell of `t` (any length; `t` and `−t` share a cell): `None` for a zero or
/// non-finite tangent. The upper hemisphere is mapped octahedrally onto `[−1, 1]²` (rotated by
/// 45°) and cut into `n × n` cells.
fn tangent_cell(t: Vec3, n: usize) -> Option<usize> {
    let t = if t.z < 0.0 { -t } else { t };
    let s = t.x.abs() + t.y.abs() + t.z;
    if !(s.is_finite() && s > 0.0) {
        return None;
    }
    let (px, py) = (t.x / s, t.y / s);
    let cell = |c: f32| (((c + 1.0) * 0.5 * n as f32) as usize).min(n - 1);
    Some(cell(px + py) * n + cell(px - py))
}

/// The unit tangent at the centre of cell `k` of [`tangent_cell`]'s `n × n` grid.
fn cell_tangent(k: usize, n: usize) -> Vec3 {
    let centre = |i: usize| (i as f32 + 0.5) / n as f32 * 2.0 - 1.0;
    let (u, v) = (centre(k / n), centre(k % n));
    let (px, py) = (0.5 * (u + v), 0.5 * (u - v));
    Vec3::new(px, py, (1.0 - px.abs() - py.abs()).max(0.0)).normalize()
}

/// Per-`h` lobe data for one `wo`.
struct NodeLobes {
    gamma_o: f32,
    gamma_t: f32,
    a: [Rgb; 4],
}

/// Unique (unmirrored) quadrature nodes whose terms a [`PreparedFibre`] keeps: all of them
/// for up to 128 nodes (every automatic count); beyond, every node's terms are computed per
/// evaluation.
const CACHED_NODES: usize = 64;

/// Unique nodes a [`PreparedFibre`] keeps inline, in the vertex's own memory: up to 64 nodes
/// (the automatic count for `β_n ≥ 0.16`; 34 at the default 0.3). A vertex is prepared, moved
/// and dropped several times per path vertex, so its size is part of the cost: a table for
/// 64 unique nodes is 5 KiB to clear and copy, of which the default count uses a quarter.
/// Vertices with more unique nodes (up to [`CACHED_NODES`]) keep their table on the heap.
const INLINE_NODES: usize = 32;

/// What one unique node contributes for a fixed `wo`: the attenuations, their RGB averages,
/// `Φ(p, h)` for the three azimuthal lobes and the total lobe weight.
#[derive(Clone, Copy, Debug)]
struct NodeTerms {
    a: [Rgb; 4],
    w: [f32; 4],
    phi: [f32; 3],
    total: f32,
}

/// The per-vertex terms of the cached unique nodes, laid out by lobe (structure of arrays) for
/// the batched azimuthal sum of [`FibrePhase::eval_pdf_prepared`]. Entries past the unique node
/// count are never read: zero in a new table, an earlier vertex's in a reused slot
/// ([`FibrePhase::prepare_into`]).
#[derive(Clone, Debug)]
struct LobeTable<const N: usize> {
    /// `Φ(p, h_k)` for the azimuthal lobes `p = 0, 1, 2`.
    phi: [[f32; N]; 3],
    /// `A_p(h_k)` by lobe and channel.
    a: [[[f32; N]; 3]; 3],
    /// The lobe's share of the node's sampling weight, `w_p(h_k) / total_k` (0 for a node whose
    /// lobes are all black).
    share: [[f32; N]; 3],
    /// 1 where the node's mirrored twin `−h_k` is a node too, 0 for the unpaired middle node of
    /// an odd count.
    mirror: [f32; N],
    /// `A_3(h_k)` (the residual lobe) by channel.
    a3: [[f32; N]; 3],
    /// `γ_t(h_k)`, the refracted offset angle (the sampler rebuilds `Φ` of a mirrored node
    /// from it).
    gamma_t: [f32; N],
}

impl<const N: usize> LobeTable<N> {
    const ZERO: Self = LobeTable {
        phi: [[0.0; N]; 3],
        a: [[[0.0; N]; 3]; 3],
        share: [[0.0; N]; 3],
        mirror: [0.0; N],
        a3: [[0.0; N]; 3],
        gamma_t: [0.0; N],
    };

    /// The lobes of node `k` (`uk` its unique node, `sign` −1 for the mirrored twin).
    fn node_lobes(&self, uk: usize, sign: f32, gamma_o: f32) -> NodeLobes {
        NodeLobes {
            gamma_o,
            gamma_t: sign * self.gamma_t[uk],
            a: std::array::from_fn(|p| {
                let ch = if p < 3 { &self.a[p] } else { &self.a3 };
                Rgb::new(ch[0][uk], ch[1][uk], ch[2][uk])
            }),
        }
    }
}

/// Where a [`PreparedFibre`] keeps its per-node terms.
// The inline table is large on purpose: the common case needs no heap allocation per vertex.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum NodeTable {
    /// Up to [`INLINE_NODES`] unique nodes, in place.
    Inline(LobeTable<INLINE_NODES>),
    /// Up to [`CACHED_NODES`] unique nodes (narrow azimuthal lobes), on the heap.
    Boxed(Box<LobeTable<CACHED_NODES>>),
    /// No table: no fibre frame, or more unique nodes than [`CACHED_NODES`] (every node's
    /// terms are computed per evaluation).
    Uncached,
}

/// A [`FibrePhase`] with its outgoing direction and tangent fixed (one scattering vertex):
/// the tangent frame, the angles of `wo` and the per-node lobe terms are computed once and
/// shared by every evaluation and the sample at that vertex (next event estimation evaluates
/// the light direction, sampling evaluates the sampled one). The terms that do not depend on
/// `wi` (the residual lobe, isotropic in azimuth, and the diffuse lobe's share of the pdf) are
/// summed over the nodes here, once. No heap allocation up to 64 quadrature nodes
/// ([`INLINE_NODES`]).
#[derive(Clone, Debug)]
pub struct PreparedFibre {
    /// `None` for a zero or non-finite tangent (value and pdf 0, no sample).
    frame: Option<Frame>,
    o: Angles,
    /// Diffuse albedo × diffuse weight, and its RGB average.
    ad: Rgb,
    wd: f32,
    /// The fibre absorption the terms were computed with (offsets beyond the cached ones
    /// are computed per evaluation with it).
    sigma_a: Rgb,
    /// Σ over the nodes (mirrored twins included) of `A_3(h_k) / 2π`: the residual lobe's value
    /// is this × `M_3`.
    residual_value: Rgb,
    /// Σ over the nodes of `w_3(h_k) / total_k / 2π`: the residual lobe's pdf is this × `M_3`.
    residual_pdf: f32,
    /// Σ over the nodes of `w_d / total_k`: the diffuse lobe's pdf is this × its density.
    diffuse_pdf: f32,
    /// Terms of the unique nodes.
    table: NodeTable,
}

impl PreparedFibre {
    /// A slot for [`FibrePhase::prepare_into`] that holds no vertex yet (no frame and no
    /// table: value and pdf 0, no sample, as for a zero tangent). A function, not a
    /// constant: a constant of this 2.6 KiB type is copied whole from read-only data where
    /// it is used, while this writes only the fields and the table's tag.
    #[must_use]
    #[inline]
    pub fn empty() -> PreparedFibre {
        PreparedFibre {
            frame: None,
            o: Angles {
                sin_t: 0.0,
                cos_t: 1.0,
                phi: 0.0,
            },
            ad: Rgb::ZERO,
            wd: 0.0,
            sigma_a: Rgb::ZERO,
            residual_value: Rgb::ZERO,
            residual_pdf: 0.0,
            diffuse_pdf: 0.0,
            table: NodeTable::Uncached,
        }
    }

    /// Sets the `wi`-independent sums ([`FibrePhase::fill_table`]).
    fn set_sums(&mut self, (residual_value, residual_pdf, diffuse_pdf): (Rgb, f32, f32)) {
        self.residual_value = residual_value;
        self.residual_pdf = residual_pdf;
        self.diffuse_pdf = diffuse_pdf;
    }
}

/// Lanes of the batched azimuthal sum (the node arrays are a multiple of it long).
const LANES: usize = 8;

/// Most unpaired-batch nodes: the nodes past the last full batch of [`LANES`].
const TAIL_NODES: usize = LANES - 1;

/// Lanes of the packed tail of [`azimuthal_sums`]: both signs of the three lobes of up to
/// [`TAIL_NODES`] nodes, rounded up to whole batches.
const TAIL_LANES: usize = (6 * TAIL_NODES).div_ceil(LANES) * LANES;

/// For the three azimuthal lobes, the sums over the first `unique` cached nodes (and their
/// mirrored twins) of `A_p(h_k)·L` per channel and of the lobe's sampling share × `L`, where
/// `L` is the unscaled logistic ([`logistic_unscaled`]) at `dphi − Φ(p, ±h_k)`. Nodes in
/// batches of [`LANES`] with one accumulator per lane, summed in a fixed order at the end:
/// the same value whatever instruction set the loop is compiled for. The `r = unique mod 8`
/// nodes past the last full batch are not given a batch of their own per lobe and sign
/// (mostly zero lanes: at the default 17 unique nodes, a third of the work): their `6r`
/// logistics are packed into `⌈6r/8⌉` batches shared by the three lobes, and each adds to
/// its lane's accumulator exactly what its lane of a full batch would have added (lanes past
/// `r` added `0·L = +0`), so the sums are bit for bit those of one batch per lobe and sign
/// (`azimuthal_sums_reference` in the tests).
#[inline(always)]
fn azimuthal_sums<const N: usize>(
    t: &LobeTable<N>,
    unique: usize,
    active: [bool; 3],
    dphi: f32,
    neg_inv_s: f32,
) -> [[f32; 4]; 3] {
    let unique = unique.min(N);
    let full = unique / LANES;
    let rest = unique % LANES;
    let lanes = |x: &[f32; N], batch: usize| -> [f32; LANES] {
        let start = (batch * LANES).min(N - LANES);
        let mut v = [0.0f32; LANES];
        v.copy_from_slice(&x[start..start + LANES]);
        v
    };
    // The tail's arguments: lobe p's `+Φ` of node `8·full + j` at `2pr + j`, its `−Φ` at
    // `2pr + r + j` (dphi − (−Φ) is dphi + Φ exactly); the unused lanes are 0.
    let mut tail_phi = [0.0f32; TAIL_LANES];
    let base = full * LANES;
    for p in 0..3 {
        for j in 0..rest {
            let phi = t.phi[p][base + j];
            tail_phi[2 * p * rest + j] = phi;
            tail_phi[2 * p * rest + rest + j] = -phi;
        }
    }
    let mut tail_l = [0.0f32; TAIL_LANES];
    for batch in 0..(6 * rest).div_ceil(LANES) {
        for j in 0..LANES {
            let i = batch * LANES + j;
            tail_l[i] = logistic_unscaled(wrap_fast(dphi - tail_phi[i]), neg_inv_s);
        }
    }
    let mut out = [[0.0f32; 4]; 3];
    for (p, o) in out.iter_mut().enumerate() {
        if !active[p] {
            // Every attenuation and share of the lobe is 0: its sums are +0, as `out` holds.
            continue;
        }
        let (mut r, mut g, mut b, mut w) =
            ([0.0f32; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES]);
        for batch in 0..full {
            let (phi, mirror) = (lanes(&t.phi[p], batch), lanes(&t.mirror, batch));
            let (ar, ag, ab) = (
                lanes(&t.a[p][0], batch),
                lanes(&t.a[p][1], batch),
                lanes(&t.a[p][2], batch),
            );
            let share = lanes(&t.share[p], batch);
            for j in 0..LANES {
                let l = logistic_unscaled(wrap_fast(dphi - phi[j]), neg_inv_s)
                    + mirror[j] * logistic_unscaled(wrap_fast(dphi + phi[j]), neg_inv_s);
                r[j] += ar[j] * l;
                g[j] += ag[j] * l;
                b[j] += ab[j] * l;
                w[j] += share[j] * l;
            }
        }
        for j in 0..rest {
            let k = base + j;
            let l = tail_l[2 * p * rest + j] + t.mirror[k] * tail_l[2 * p * rest + rest + j];
            r[j] += t.a[p][0][k] * l;
            g[j] += t.a[p][1][k] * l;
            b[j] += t.a[p][2][k] * l;
            w[j] += t.share[p][k] * l;
        }
        let sum = |x: [f32; LANES]| x.iter().sum::<f32>();
        *o = [sum(r), sum(g), sum(b), sum(w)];
    }
    out
}

/// The batched sums before the tail was packed ([`azimuthal_sums`] gives its bits): kept as
/// the tests' reference. For the three azimuthal lobes, the sums over the cached nodes (and their mirrored twins)
/// of `A_p(h_k)·L` per channel and of the lobe's sampling share × `L`, where `L` is the
/// unscaled logistic ([`logistic_unscaled`]) at `dphi − Φ(p, ±h_k)`. Nodes in batches of
/// [`LANES`] with one accumulator per lane, summed in a fixed order at the end: the same
/// value whatever instruction set the loop is compiled for.
#[cfg(test)]
fn azimuthal_sums_reference<const N: usize>(
    t: &LobeTable<N>,
    batches: usize,
    dphi: f32,
    neg_inv_s: f32,
) -> [[f32; 4]; 3] {
    let lanes = |x: &[f32; N], batch: usize| -> [f32; LANES] {
        let start = (batch * LANES).min(N - LANES);
        let mut v = [0.0f32; LANES];
        v.copy_from_slice(&x[start..start + LANES]);
        v
    };
    let mut out = [[0.0f32; 4]; 3];
    for (p, o) in out.iter_mut().enumerate() {
        let (mut r, mut g, mut b, mut w) =
            ([0.0f32; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES]);
        for batch in 0..batches {
            let (phi, mirror) = (lanes(&t.phi[p], batch), lanes(&t.mirror, batch));
            let (ar, ag, ab) = (
                lanes(&t.a[p][0], batch),
                lanes(&t.a[p][1], batch),
                lanes(&t.a[p][2], batch),
            );
            let share = lanes(&t.share[p], batch);
            for j in 0..LANES {
                let l = logistic_unscaled(wrap_fast(dphi - phi[j]), neg_inv_s)
                    + mirror[j] * logistic_unscaled(wrap_fast(dphi + phi[j]), neg_inv_s);
                r[j] += ar[j] * l;
                g[j] += ag[j] * l;
                b[j] += ab[j] * l;
                w[j] += share[j] * l;
            }
        }
        let sum = |x: [f32; LANES]| x.iter().sum::<f32>();
        *o = [sum(r), sum(g), sum(b), sum(w)];
    }
    out
}

/// [`azimuthal_sums`] compiled for AVX2 (eight lanes at once; no FMA contraction, so the
/// same bits as the baseline build).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn azimuthal_sums_avx2<const N: usize>(
    t: &LobeTable<N>,
    unique: usize,
    active: [bool; 3],
    dphi: f32,
    neg_inv_s: f32,
) -> [[f32; 4]; 3] {
    azimuthal_sums(t, unique, active, dphi, neg_inv_s)
}

/// [`FibrePhase::fill_table`] compiled for AVX2 (eight nodes at once; no FMA contraction, so
/// the same bits as the baseline build).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_table_avx2<const N: usize>(
    phase: &FibrePhase,
    table: &mut LobeTable<N>,
    unique: usize,
    o: &Angles,
    sigma_a: Rgb,
    wd: f32,
) -> (Rgb, f32, f32) {
    phase.fill_table(table, unique, o, sigma_a, wd)
}

impl FibrePhase {
    /// Validates `params` (errors name the parameter and its range) and precomputes the
    /// lobe variances and the cuticle tilts.
    pub fn new(params: FibrePhaseParams) -> Result<FibrePhase, FabricError> {
        check_range("eta", params.eta, 1.0, 3.0)?;
        check_range("beta_m", params.beta_m, 0.01, 1.0)?;
        check_range("beta_n", params.beta_n, 0.01, 1.0)?;
        check_range("alpha", params.alpha, -0.2, 0.2)?;
        check_range("diffuse_weight", params.diffuse_weight, 0.0, 1.0)?;
        if params.h_nodes > 256 {
            return Err(invalid(
                "h_nodes",
                params.h_nodes,
                "0..=256 (0 = automatic)",
            ));
        }
        for c in 0..3 {
            let sa = params.sigma_a[c];
            if !(sa.is_finite() && (0.0..=1000.0).contains(&sa)) {
                return Err(invalid(
                    "sigma_a",
                    format!("{:?}", params.sigma_a.0),
                    "each channel in [0, 1000]",
                ));
            }
            let ad = params.diffuse_albedo[c];
            if !(ad.is_finite() && (0.0..=1.0).contains(&ad)) {
                return Err(invalid(
                    "diffuse_albedo",
                    format!("{:?}", params.diffuse_albedo.0),
                    "each channel in [0, 1]",
                ));
            }
        }
        let v0 = longitudinal_variance(params.beta_m);
        let mut sin2k_alpha = [0.0; 3];
        let mut cos2k_alpha = [0.0; 3];
        sin2k_alpha[0] = params.alpha.sin();
        cos2k_alpha[0] = (1.0 - sin2k_alpha[0] * sin2k_alpha[0]).max(0.0).sqrt();
        for i in 1..3 {
            sin2k_alpha[i] = 2.0 * cos2k_alpha[i - 1] * sin2k_alpha[i - 1];
            cos2k_alpha[i] = cos2k_alpha[i - 1].powi(2) - sin2k_alpha[i - 1].powi(2);
        }
        let s = azimuthal_scale(params.beta_n);
        let n = if params.h_nodes == 0 {
            let k = (10.0 / params.beta_n).ceil() as usize;
            (k + k % 2).clamp(8, 128)
        } else {
            params.h_nodes as usize
        };
        // Exactly mirrored nodes (h_{n−1−k} = −h_k), so eval can share A_p between ±h.
        let node = |k: usize| {
            let h = -1.0 + (2 * k + 1) as f32 / n as f32;
            (h, h.asin(), (1.0 - h * h).max(0.0).sqrt())
        };
        let nodes: Vec<(f32, f32, f32)> = (0..n)
            .map(|k| {
                if 2 * k < n {
                    node(k)
                } else {
                    let (h, g, c) = node(n - 1 - k);
                    (-h, -g, c)
                }
            })
            .collect();
        let node_h = std::array::from_fn(|k| nodes.get(k).map_or(0.0, |n| n.0));
        let node_cos_go = std::array::from_fn(|k| nodes.get(k).map_or(0.0, |n| n.2));
        let node_gamma_o = std::array::from_fn(|k| nodes.get(k).map_or(0.0, |n| n.1));
        let v = [v0, 0.25 * v0, 4.0 * v0, 4.0 * v0];
        Ok(FibrePhase {
            inv_logistic_norm: 1.0 / (logistic_cdf(PI, s) - logistic_cdf(-PI, s)),
            logistic_mass: logistic_cdf(PI, s) - logistic_cdf(-PI, s),
            logistic_cdf_neg_pi: logistic_cdf(-PI, s),
            lon: LongitudinalConsts::new(v),
            nodes,
            avx2: crate::math::avx2_enabled(),
            azimuthal_active: std::array::from_fn(|p| {
                params.lobes.on(p) && params.diffuse_weight < 1.0
            }),
            node_h,
            node_cos_go,
            node_gamma_o,
            quantised: QuantisedLobes::default(),
            s,
            v,
            params,
            sin2k_alpha,
            cos2k_alpha,
        })
    }

    /// Number of `h` offsets of the quadrature actually used.
    #[must_use]
    pub fn h_node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The parameters this phase function was built from.
    #[must_use]
    pub fn params(&self) -> &FibrePhaseParams {
        &self.params
    }

    /// `(sin, |cos|)` of `θ_o` tilted by the cuticle scales for lobe `p`.
    fn tilted(&self, p: usize, sin_o: f32, cos_o: f32) -> (f32, f32) {
        let (s, c) = match p {
            0 => (
                sin_o * self.cos2k_alpha[1] - cos_o * self.sin2k_alpha[1],
                cos_o * self.cos2k_alpha[1] + sin_o * self.sin2k_alpha[1],
            ),
            1 => (
                sin_o * self.cos2k_alpha[0] + cos_o * self.sin2k_alpha[0],
                cos_o * self.cos2k_alpha[0] - sin_o * self.sin2k_alpha[0],
            ),
            2 => (
                sin_o * self.cos2k_alpha[2] + cos_o * self.sin2k_alpha[2],
                cos_o * self.cos2k_alpha[2] - sin_o * self.sin2k_alpha[2],
            ),
            _ => (sin_o, cos_o),
        };
        (s, c.abs())
    }

    /// Attenuations `A_p(h)` (with inactive lobes zeroed and the `(1 − d)` mix applied).
    fn node(&self, k: usize, sin_o: f32, cos_o: f32, sigma_a: Rgb) -> NodeLobes {
        let (h, gamma_o, cos_go) = self.nodes[k];
        let eta = self.params.eta;
        let cos_o = cos_o.max(1e-4);
        let sin_t = sin_o / eta;
        let cos_t = (1.0 - sin_t * sin_t).max(1e-8).sqrt();
        let etap = (eta * eta - sin_o * sin_o).max(0.0).sqrt() / cos_o;
        let sin_gt = (h / etap).clamp(-1.0, 1.0);
        let cos_gt = (1.0 - sin_gt * sin_gt).max(0.0).sqrt();
        let gamma_t = sin_gt.asin();
        let trans = if sigma_a.is_black() {
            Rgb::ONE
        } else {
            (sigma_a * (-2.0 * cos_gt / cos_t)).exp()
        };
        let f = fresnel_dielectric(cos_o * cos_go, eta);
        let mut a = [Rgb::ZERO; 4];
        a[0] = Rgb::splat(f);
        a[1] = trans * (1.0 - f) * (1.0 - f);
        a[2] = a[1] * trans * f;
        let denom = Rgb::ONE - trans * f;
        a[3] = (a[2] * trans * f).safe_div(denom);
        let mix = 1.0 - self.params.diffuse_weight;
        for (p, ap) in a.iter_mut().enumerate() {
            *ap = if self.params.lobes.on(p) {
                *ap * mix
            } else {
                Rgb::ZERO
            };
        }
        NodeLobes {
            gamma_o,
            gamma_t,
            a,
        }
    }

    fn phi_p(p: usize, n: &NodeLobes) -> f32 {
        2.0 * p as f32 * n.gamma_t - 2.0 * n.gamma_o + p as f32 * PI
    }

    /// `M_p` for the four lobes: [`longitudinal_lobe`] bit for bit, with its `v`-only terms
    /// precomputed ([`LongitudinalConsts`]), the four `I₀` series in one vector loop
    /// ([`i0_lanes`]), and the residual lobe's `M_3` taken from TRT's where their tilted
    /// angles are the same (no cuticle tilt: `v_2 = v_3`).
    fn mp(&self, o: &Angles, i: &Angles) -> [f32; 4] {
        let tilt: [(f32, f32); 4] = std::array::from_fn(|p| self.tilted(p, o.sin_t, o.cos_t));
        let a: [f32; 4] = std::array::from_fn(|p| i.cos_t * tilt[p].1 / self.v[p]);
        let b: [f32; 4] = std::array::from_fn(|p| i.sin_t * tilt[p].0 / self.v[p]);
        let series = i0_lanes(a);
        let lon = &self.lon;
        let lobe = |p: usize| {
            if self.v[p] <= 0.1 {
                let log_i0 = if a[p] > 12.0 {
                    log_i0_asymptotic(a[p])
                } else {
                    series[p].ln()
                };
                (log_i0 - b[p] - lon.inv_v[p] + std::f32::consts::LN_2 - lon.ln_2v[p]).exp()
            } else {
                (-b[p]).exp() * series[p] / lon.sinh_norm[p]
            }
        };
        let (m0, m1, m2) = (lobe(0), lobe(1), lobe(2));
        let m3 = if tilt[3] == tilt[2] && self.v[3] == self.v[2] {
            m2
        } else {
            lobe(3)
        };
        [m0, m1, m2, m3]
    }

    fn diffuse_density(o: &Angles, i: &Angles) -> f32 {
        (2.0 / PI) * i.cos_t * diffuse_azimuthal(i.phi - o.phi)
    }

    /// The terms of unique node `k` for the outgoing angles `o`.
    fn terms(&self, k: usize, o: &Angles, wd: f32, sigma_a: Rgb) -> NodeTerms {
        let node = self.node(k, o.sin_t, o.cos_t, sigma_a);
        let w: [f32; 4] = std::array::from_fn(|p| lobe_weight(node.a[p]));
        let total: f32 = w.iter().sum::<f32>() + wd;
        NodeTerms {
            a: node.a,
            w,
            phi: std::array::from_fn(|p| Self::phi_p(p, &node)),
            total,
        }
    }

    /// The attenuations `A_p(h_k)` (mixed, inactive lobes zeroed) and `γ_t(h_k)` of the first
    /// `unique` nodes for the outgoing angles `o`: [`FibrePhase::node`]'s arithmetic in one
    /// branch-free loop over the nodes, with [`asin_fast`] and [`exp_neg`] for `asin` and `exp`.
    #[inline(always)]
    fn fill_lobes<const N: usize>(
        &self,
        table: &mut LobeTable<N>,
        unique: usize,
        o: &Angles,
        sigma_a: Rgb,
    ) {
        let eta = self.params.eta;
        let sin_o = o.sin_t;
        let cos_o = o.cos_t.max(1e-4);
        let sin_t = sin_o / eta;
        let cos_t = (1.0 - sin_t * sin_t).max(1e-8).sqrt();
        let etap = (eta * eta - sin_o * sin_o).max(0.0).sqrt() / cos_o;
        let mix = 1.0 - self.params.diffuse_weight;
        let on: [f32; 4] = std::array::from_fn(|p| if self.params.lobes.on(p) { mix } else { 0.0 });
        let unique = unique.min(N);
        for k in 0..unique {
            let sin_gt = (self.node_h[k] / etap).clamp(-1.0, 1.0);
            let cos_gt = (1.0 - sin_gt * sin_gt).max(0.0).sqrt();
            table.gamma_t[k] = asin_fast(sin_gt);
            let f = fresnel_entering(cos_o * self.node_cos_go[k], eta);
            let x = -2.0 * cos_gt / cos_t;
            for c in 0..3 {
                let trans = exp_neg(sigma_a[c] * x);
                let a1 = trans * (1.0 - f) * (1.0 - f);
                let a2 = a1 * trans * f;
                let denom = 1.0 - trans * f;
                let a3 = if denom != 0.0 {
                    a2 * trans * f / denom
                } else {
                    0.0
                };
                table.a[0][c][k] = f * on[0];
                table.a[1][c][k] = a1 * on[1];
                table.a[2][c][k] = a2 * on[2];
                table.a3[c][k] = a3 * on[3];
            }
        }
    }

    /// Fixes `wo` and the tangent of one scattering vertex; see [`PreparedFibre`].
    #[must_use]
    pub fn prepare(&self, wo: Vec3, tangent: Vec3) -> PreparedFibre {
        let mut prepared = PreparedFibre::empty();
        self.prepare_into(&mut prepared, wo, tangent);
        prepared
    }

    /// [`FibrePhase::prepare`] for a fibre of another colour: the vertex then evaluates and
    /// samples exactly as the phase function built with that colour's parameters would
    /// (bit-identical when `colour` is this phase function's own).
    #[must_use]
    pub fn prepare_coloured(&self, wo: Vec3, tangent: Vec3, colour: &FibreColour) -> PreparedFibre {
        let mut prepared = PreparedFibre::empty();
        self.prepare_coloured_into(&mut prepared, wo, tangent, colour);
        prepared
    }

    /// A prepared vertex for `wo` around a tangent near `tangent`: the one of the tangent's
    /// cell in a [`QUANTISED_GRID`]² grid over the tangent's hemisphere (`t` and `−t` share
    /// a cell), prepared at the cell's centre in this phase function's own colour. The
    /// table is built for the first `wo` asked for (every cell at once, thread-safely) and
    /// kept; `None` for another `wo` or a zero or non-finite tangent. For a lobe that only
    /// has to resemble the vertex's own (the sun lean): its samples and pdf are exact for
    /// the cell's tangent.
    #[must_use]
    pub fn quantised_lobe(&self, wo: Vec3, tangent: Vec3) -> Option<&PreparedFibre> {
        let n = QUANTISED_GRID;
        let (built_for, cells) = self.quantised.0.get_or_init(|| {
            let cells = (0..n * n)
                .map(|k| self.prepare(wo, cell_tangent(k, n)))
                .collect();
            (wo, cells)
        });
        if *built_for != wo {
            return None;
        }
        cells.get(tangent_cell(tangent, n)?)
    }

    /// [`FibrePhase::prepare`] into a slot the caller owns: `slot` (any earlier vertex, or
    /// [`PreparedFibre::empty()`]) becomes this phase function's vertex for `wo` around
    /// `tangent`, in place, without the copy that returning a vertex by value can cost (a
    /// [`PreparedFibre`] holds up to 2.6 KiB of node terms). The same bits as
    /// [`FibrePhase::prepare`].
    pub fn prepare_into(&self, slot: &mut PreparedFibre, wo: Vec3, tangent: Vec3) {
        self.prepare_with(
            slot,
            wo,
            tangent,
            self.params.sigma_a,
            self.params.diffuse_albedo,
        );
    }

    /// [`FibrePhase::prepare_coloured`] into a slot the caller owns ([`FibrePhase::prepare_into`]).
    pub fn prepare_coloured_into(
        &self,
        slot: &mut PreparedFibre,
        wo: Vec3,
        tangent: Vec3,
        colour: &FibreColour,
    ) {
        self.prepare_with(slot, wo, tangent, colour.sigma_a, colour.diffuse_albedo);
    }

    /// Makes `slot` the vertex of [`FibrePhase::prepare`] with absorption `sigma_a` and
    /// diffuse albedo `albedo`. A table the slot already holds is refilled where it has the
    /// size this vertex needs (an inline table in place, without clearing it; a boxed one
    /// without a new allocation).
    fn prepare_with(
        &self,
        slot: &mut PreparedFibre,
        wo: Vec3,
        tangent: Vec3,
        sigma_a: Rgb,
        albedo: Rgb,
    ) {
        let ad = albedo * self.params.diffuse_weight;
        let wd = lobe_weight(ad);
        slot.sigma_a = sigma_a;
        slot.frame = tangent_frame(tangent);
        slot.o = Angles {
            sin_t: 0.0,
            cos_t: 1.0,
            phi: 0.0,
        };
        slot.ad = ad;
        slot.wd = wd;
        slot.set_sums((Rgb::ZERO, 0.0, 0.0));
        let Some(frame) = &slot.frame else {
            slot.table = NodeTable::Uncached;
            return;
        };
        let o = angles(frame, wo);
        slot.o = o;
        let unique = self.nodes.len().div_ceil(2);
        // A table the slot holds already is refilled without clearing: only the first
        // `unique` entries are read (`azimuthal_sums` reads whole batches below `unique / 8
        // · 8` and the tail below `unique`, `node_lobes` is called with `uk < unique`), and
        // those the fill writes. A new table is cleared once.
        if unique <= INLINE_NODES {
            if !matches!(slot.table, NodeTable::Inline(_)) {
                slot.table = NodeTable::Inline(LobeTable::ZERO);
            }
            if let NodeTable::Inline(table) = &mut slot.table {
                let sums = self.fill_table_dispatch(table, unique, &o, sigma_a, wd);
                slot.set_sums(sums);
            }
        } else if unique <= CACHED_NODES {
            if !matches!(slot.table, NodeTable::Boxed(_)) {
                slot.table = NodeTable::Boxed(Box::new(LobeTable::ZERO));
            }
            if let NodeTable::Boxed(table) = &mut slot.table {
                let sums = self.fill_table_dispatch(table, unique, &o, sigma_a, wd);
                slot.set_sums(sums);
            }
        } else {
            slot.table = NodeTable::Uncached;
        }
    }

    /// Fills `table` with the terms of the first `unique` nodes (at most `N`) for the
    /// outgoing angles `o` and returns the `wi`-independent sums of [`PreparedFibre`]:
    /// (residual value, residual pdf, diffuse pdf). Every per-node term in loops without
    /// branches over contiguous arrays (so that they vectorise, eight nodes at a time with
    /// AVX2: [`fill_table_avx2`]), then the three sums over the nodes in node order, as one
    /// loop doing both gave them (the same bits: `fill_table_reference` in the tests).
    #[inline(always)]
    fn fill_table<const N: usize>(
        &self,
        table: &mut LobeTable<N>,
        unique: usize,
        o: &Angles,
        sigma_a: Rgb,
        wd: f32,
    ) -> (Rgb, f32, f32) {
        let n_nodes = self.nodes.len();
        let unique = unique.min(N);
        self.fill_lobes(table, unique, o, sigma_a);
        let mut value = [[0.0f32; N]; 3];
        let mut pdf = [0.0f32; N];
        let mut diffuse = [0.0f32; N];
        for k in 0..unique {
            let weight = |ch: &[[f32; N]; 3]| ch[0][k].max(ch[1][k]).max(ch[2][k]);
            let w = [
                weight(&table.a[0]),
                weight(&table.a[1]),
                weight(&table.a[2]),
                weight(&table.a3),
            ];
            let total = w[0] + w[1] + w[2] + w[3] + wd;
            let count = if n_nodes - 1 - k != k { 2.0 } else { 1.0 };
            table.mirror[k] = count - 1.0;
            let inv_total = if total > 0.0 { 1.0 / total } else { 0.0 };
            let gamma_t = table.gamma_t[k];
            let gamma_o = self.node_gamma_o[k];
            // `p` is the lobe's order in the phase (2pγ_t − 2γ_o + pπ) as well as an index.
            #[allow(clippy::needless_range_loop)]
            for p in 0..3 {
                table.phi[p][k] = 2.0 * p as f32 * gamma_t - 2.0 * gamma_o + p as f32 * PI;
                table.share[p][k] = w[p] * inv_total;
            }
            for (c, v) in value.iter_mut().enumerate() {
                v[k] = table.a3[c][k] * (count * INV_2PI);
            }
            pdf[k] = count * w[3] * inv_total * INV_2PI;
            diffuse[k] = count * wd * inv_total;
        }
        let (mut residual_value, mut residual_pdf, mut diffuse_pdf) = (Rgb::ZERO, 0.0, 0.0);
        for k in 0..unique {
            residual_value += Rgb::new(value[0][k], value[1][k], value[2][k]);
            residual_pdf += pdf[k];
            diffuse_pdf += diffuse[k];
        }
        (residual_value, residual_pdf, diffuse_pdf)
    }

    /// [`FibrePhase::fill_table`] with AVX2 where the CPU has it (the same bits).
    fn fill_table_dispatch<const N: usize>(
        &self,
        table: &mut LobeTable<N>,
        unique: usize,
        o: &Angles,
        sigma_a: Rgb,
        wd: f32,
    ) -> (Rgb, f32, f32) {
        if self.avx2 {
            // SAFETY: `avx2` is set only where the CPU has AVX2 (`FibrePhase::new`).
            #[cfg(target_arch = "x86_64")]
            unsafe {
                return fill_table_avx2(self, table, unique, o, sigma_a, wd);
            }
        }
        self.fill_table(table, unique, o, sigma_a, wd)
    }

    /// The node terms as they were filled before [`FibrePhase::fill_table`] was written to
    /// vectorise (the tests' reference for its bits). Fills `table` with the terms of the first `unique` nodes (at most `N`) for the
    /// outgoing angles `o` and returns the `wi`-independent sums of [`PreparedFibre`]:
    /// (residual value, residual pdf, diffuse pdf).
    #[cfg(test)]
    fn fill_table_reference<const N: usize>(
        &self,
        table: &mut LobeTable<N>,
        unique: usize,
        o: &Angles,
        sigma_a: Rgb,
        wd: f32,
    ) -> (Rgb, f32, f32) {
        let n_nodes = self.nodes.len();
        let unique = unique.min(N);
        self.fill_lobes(table, unique, o, sigma_a);
        let (mut residual_value, mut residual_pdf, mut diffuse_pdf) = (Rgb::ZERO, 0.0, 0.0);
        for k in 0..unique {
            let a: [Rgb; 4] = std::array::from_fn(|p| {
                let ch = if p < 3 { &table.a[p] } else { &table.a3 };
                Rgb::new(ch[0][k], ch[1][k], ch[2][k])
            });
            let w: [f32; 4] = std::array::from_fn(|p| lobe_weight(a[p]));
            let total: f32 = w.iter().sum::<f32>() + wd;
            let count = if n_nodes - 1 - k != k { 2.0 } else { 1.0 };
            table.mirror[k] = count - 1.0;
            let inv_total = if total > 0.0 { 1.0 / total } else { 0.0 };
            // `p` is the lobe's order in the phase (2pγ_t − 2γ_o + pπ) as well as an index.
            #[allow(clippy::needless_range_loop)]
            for p in 0..3 {
                table.phi[p][k] =
                    2.0 * p as f32 * table.gamma_t[k] - 2.0 * self.nodes[k].1 + p as f32 * PI;
                table.share[p][k] = w[p] * inv_total;
            }
            residual_value += a[3] * (count * INV_2PI);
            residual_pdf += count * w[3] * inv_total * INV_2PI;
            diffuse_pdf += count * wd * inv_total;
        }
        (residual_value, residual_pdf, diffuse_pdf)
    }

    /// The three azimuthal lobes' sums of [`azimuthal_sums`] over the first `unique` nodes
    /// of `table`, with AVX2 where the CPU has it.
    #[inline]
    fn sums<const N: usize>(
        &self,
        table: &LobeTable<N>,
        unique: usize,
        dphi: f32,
        neg_inv_s: f32,
    ) -> [[f32; 4]; 3] {
        if self.avx2 {
            // SAFETY: `avx2` is set only where the CPU has AVX2 (`FibrePhase::new`).
            #[cfg(target_arch = "x86_64")]
            unsafe {
                azimuthal_sums_avx2(table, unique, self.azimuthal_active, dphi, neg_inv_s)
            }
            #[cfg(not(target_arch = "x86_64"))]
            azimuthal_sums(table, unique, self.azimuthal_active, dphi, neg_inv_s)
        } else {
            azimuthal_sums(table, unique, self.azimuthal_active, dphi, neg_inv_s)
        }
    }

    /// Value (RGB) and pdf of `wi` at a prepared vertex (the same function as
    /// [`FibrePhase::eval`] and [`FibrePhase::pdf`] with the vertex's `wo` and tangent).
    ///
    /// `A_p(h) = A_p(−h)` and `Φ(p, −h) ≡ −Φ(p, h)` (mod 2π): one node's terms serve the
    /// mirrored pair. The azimuthal lobes are summed lobe by lobe over the nodes in batches of
    /// [`LANES`] (branch-free wrap and exponential, [`exp_neg`]), the residual and diffuse
    /// terms come summed from [`FibrePhase::prepare`]. The sum is the quadrature of the
    /// module docs; only the rounding differs from a node-by-node loop.
    #[must_use]
    pub fn eval_pdf_prepared(&self, prepared: &PreparedFibre, wi: Vec3) -> (Rgb, f32) {
        let Some(frame) = &prepared.frame else {
            return (Rgb::ZERO, 0.0);
        };
        let o = &prepared.o;
        let i = angles(frame, wi);
        let m = self.mp(o, &i);
        let dphi = i.phi - o.phi;
        let dd = Self::diffuse_density(o, &i);
        let n_nodes = self.nodes.len();
        let unique = n_nodes.div_ceil(2);
        let neg_inv_s = -1.0 / self.s;
        let sums = match &prepared.table {
            NodeTable::Inline(t) => self.sums(t, unique, dphi, neg_inv_s),
            NodeTable::Boxed(t) => self.sums(&**t, unique, dphi, neg_inv_s),
            NodeTable::Uncached => return self.eval_pdf_uncached(prepared, m, dphi, dd),
        };
        let scale = self.inv_logistic_norm / self.s;
        let mut value = prepared.residual_value * m[3];
        let mut pdf = prepared.residual_pdf * m[3] + prepared.diffuse_pdf * dd;
        for (p, [r, g, b, w]) in sums.into_iter().enumerate() {
            let f = m[p] * scale;
            value += Rgb::new(r, g, b) * f;
            pdf += w * f;
        }
        let inv_n = 1.0 / n_nodes as f32;
        (value * inv_n + prepared.ad * dd, pdf * inv_n)
    }

    /// [`FibrePhase::eval_pdf_prepared`] for more unique nodes than a [`PreparedFibre`]
    /// keeps (`h_nodes` above 128): every node's terms computed here, node by node.
    fn eval_pdf_uncached(
        &self,
        prepared: &PreparedFibre,
        m: [f32; 4],
        dphi: f32,
        dd: f32,
    ) -> (Rgb, f32) {
        let o = &prepared.o;
        let wd = prepared.wd;
        let n_nodes = self.nodes.len();
        let mut value = Rgb::ZERO;
        let mut pdf = 0.0;
        for k in 0..n_nodes.div_ceil(2) {
            let node = self.terms(k, o, wd, prepared.sigma_a);
            let mirrored = n_nodes - 1 - k != k;
            for sign in [1.0f32, -1.0] {
                if sign < 0.0 && !mirrored {
                    break;
                }
                let mut lobe_pdf = wd * dd;
                // `p` picks the lobe (three azimuthal, then the residual) in four tables.
                #[allow(clippy::needless_range_loop)]
                for p in 0..4 {
                    let n = if p < 3 {
                        let phi = sign * node.phi[p];
                        trimmed_logistic_norm(wrap(dphi - phi), self.s, self.inv_logistic_norm)
                    } else {
                        INV_2PI
                    };
                    let lv = m[p] * n;
                    value += node.a[p] * lv;
                    lobe_pdf += node.w[p] * lv;
                }
                if node.total > 0.0 {
                    pdf += lobe_pdf / node.total;
                }
            }
        }
        value = value * (1.0 / n_nodes as f32) + prepared.ad * dd;
        (value, pdf / n_nodes as f32)
    }

    /// Value (RGB) and pdf together (one pass; [`FibrePhase::eval`] and
    /// [`FibrePhase::pdf`] are its two halves).
    #[must_use]
    pub fn eval_pdf(&self, wo: Vec3, wi: Vec3, tangent: Vec3) -> (Rgb, f32) {
        self.eval_pdf_prepared(&self.prepare(wo, tangent), wi)
    }

    /// Phase function value (RGB, per unit solid angle of `wi`), averaged over `h`. The
    /// tangent is re-normalised; a zero or non-finite tangent gives zero (and `pdf` 0,
    /// `sample` `None`). The value is unchanged by `t → −t`.
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3, tangent: Vec3) -> Rgb {
        self.eval_pdf(wo, wi, tangent).0
    }

    /// Solid-angle pdf of [`FibrePhase::sample`].
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, tangent: Vec3) -> f32 {
        self.eval_pdf(wo, wi, tangent).1
    }

    /// Samples `wi` given `wo` and the unit fibre tangent. `u[0]` picks the offset node and
    /// the lobe (∝ the lobe weight's largest channel), `u[1], u[2]` the longitudinal angle (or the
    /// cosine-hemisphere point of the diffuse lobe), `u[3]` the azimuth (or the diffuse
    /// surface normal). `None` when every lobe is black or the direction is degenerate.
    #[must_use]
    pub fn sample(&self, wo: Vec3, tangent: Vec3, u: [f32; 4]) -> Option<FibreSample> {
        self.sample_prepared(&self.prepare(wo, tangent), u)
    }

    /// [`FibrePhase::sample`] at a prepared vertex (bit-identical to it with the vertex's `wo`
    /// and tangent).
    #[must_use]
    pub fn sample_prepared(&self, prepared: &PreparedFibre, u: [f32; 4]) -> Option<FibreSample> {
        let frame = prepared.frame?;
        let o = prepared.o;
        let n_nodes = self.nodes.len();
        let k = ((u[0] * n_nodes as f32) as usize).min(n_nodes - 1);
        let mut u0 = (u[0] * n_nodes as f32 - k as f32).clamp(0.0, 1.0);
        let unique = n_nodes.div_ceil(2);
        // The terms `prepare` computed: node `k` or the mirror of node `n − 1 − k`.
        let (uk, sign) = if k < unique {
            (k, 1.0)
        } else {
            (n_nodes - 1 - k, -1.0)
        };
        let gamma_o = self.nodes[k].1;
        let node = match &prepared.table {
            NodeTable::Inline(t) => t.node_lobes(uk, sign, gamma_o),
            NodeTable::Boxed(t) => t.node_lobes(uk, sign, gamma_o),
            NodeTable::Uncached => self.node(k, o.sin_t, o.cos_t, prepared.sigma_a),
        };
        let wd = prepared.wd;
        let w: [f32; 5] = std::array::from_fn(|p| if p < 4 { lobe_weight(node.a[p]) } else { wd });
        let total: f32 = w.iter().sum();
        if total <= 0.0 {
            return None;
        }
        let mut lobe = 4;
        for (p, &wp) in w.iter().enumerate() {
            let q = wp / total;
            if u0 < q || p == 4 {
                lobe = p;
                break;
            }
            u0 -= q;
        }
        if w[lobe] <= 0.0 {
            lobe = (0..5).rev().find(|&p| w[p] > 0.0)?;
        }
        let local = if lobe < 4 {
            let p = lobe;
            let (sin_op, cos_op) = self.tilted(p, o.sin_t, o.cos_t);
            let v = self.v[p];
            let cos_th =
                1.0 + v * (u[1].max(1e-5) + (1.0 - u[1]) * self.lon.exp_neg_2_over_v[p]).ln();
            let sin_th = (1.0 - cos_th * cos_th).max(0.0).sqrt();
            let sin_i =
                (-cos_th * sin_op + sin_th * (2.0 * PI * u[2]).cos() * cos_op).clamp(-1.0, 1.0);
            let cos_i = (1.0 - sin_i * sin_i).max(0.0).sqrt();
            let dphi = if p < 3 {
                Self::phi_p(p, &node)
                    + sample_trimmed_logistic(
                        u[3],
                        self.s,
                        self.logistic_mass,
                        self.logistic_cdf_neg_pi,
                    )
            } else {
                2.0 * PI * u[3]
            };
            let phi_i = o.phi + dphi;
            Vec3::new(cos_i * phi_i.cos(), cos_i * phi_i.sin(), sin_i)
        } else {
            // Lambertian cylinder: surface normal with projected-width weighting, then a
            // cosine lobe about it (docs/references.md §7.2).
            let gamma = o.phi + (2.0 * u[3] - 1.0).clamp(-1.0, 1.0).asin();
            let n = Vec3::new(gamma.cos(), gamma.sin(), 0.0);
            let c = crate::sampling::sample_cosine_hemisphere(crate::math::Vec2::new(u[1], u[2]));
            Frame::from_normal(n).to_world(c)
        };
        let wi = frame.to_world(local).normalize();
        if !wi.is_finite() {
            return None;
        }
        let (value, pdf) = self.eval_pdf_prepared(prepared, wi);
        if pdf.is_nan() || pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        Some(FibreSample {
            wi,
            weight: value * (1.0 / pdf),
            pdf,
        })
    }
}

/// A direction sampled from [`SggxFibrePhase`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SggxSample {
    /// Sampled direction (pointing away).
    pub wi: Vec3,
    /// Sample weight (= the flake albedo for the specular phase).
    pub weight: Rgb,
    /// Solid-angle pdf.
    pub pdf: f32,
}

/// SGGX specular microflake phase function for fibres (Heitz, Dupuy, Crassin, Dachsbacher
/// 2015; docs/references.md §7.4) with `S = σ² t tᵀ + (I − t tᵀ)`: `σ → 0` gives ideal fibres whose
/// projected area is `sin∠(ω, t)`. The phase function is `D(ω_h) / (4 σ(ω_o))` and sampling
/// is by visible normals; the weight is the flake albedo.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SggxFibrePhase {
    s: Mat3,
    albedo: Rgb,
}

impl SggxFibrePhase {
    /// A fibre flake distribution around unit `tangent` with roughness `sigma ∈ [1e-3, 1]`
    /// and flake albedo (each channel `[0, 1]`).
    pub fn new(tangent: Vec3, sigma: f32, albedo: Rgb) -> Result<Self, FabricError> {
        check_range("sggx.sigma", sigma, 1e-3, 1.0)?;
        if !tangent.is_finite() || (tangent.length() - 1.0).abs() > 1e-3 {
            return Err(invalid(
                "sggx.tangent",
                format!("{tangent:?}"),
                "a unit vector",
            ));
        }
        if !albedo
            .0
            .iter()
            .all(|c| c.is_finite() && (0.0..=1.0).contains(c))
        {
            return Err(invalid(
                "sggx.albedo",
                format!("{:?}", albedo.0),
                "each channel in [0, 1]",
            ));
        }
        let t = tangent;
        let tt = Mat3::from_cols(t * t.x, t * t.y, t * t.z);
        Ok(SggxFibrePhase {
            s: Mat3::IDENTITY + tt * (sigma * sigma - 1.0),
            albedo,
        })
    }

    /// Projected area `σ(ω) = √(ωᵀ S ω)` (extinction is `ρ σ(ω)`).
    #[must_use]
    pub fn projected_area(&self, w: Vec3) -> f32 {
        w.dot(self.s * w).max(0.0).sqrt()
    }

    /// The normal distribution `D(m) = 1 / (π √det S (mᵀ S⁻¹ m)²)`.
    #[must_use]
    pub fn ndf(&self, m: Vec3) -> f32 {
        let det = self.s.determinant().max(1e-30);
        let q = m.dot(self.s.inverse() * m);
        1.0 / (PI * det.sqrt() * q * q)
    }

    /// Phase function value `D(ω_h) / (4 σ(wo))` (both directions pointing away).
    #[must_use]
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.albedo * self.pdf(wo, wi)
    }

    /// Solid-angle pdf of [`SggxFibrePhase::sample`] (= the unit-albedo phase function).
    #[must_use]
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let h = wo + wi;
        if h.length_squared() < 1e-12 {
            return 0.0;
        }
        let so = self.projected_area(wo);
        if so <= 0.0 {
            return 0.0;
        }
        self.ndf(h.normalize()) / (4.0 * so)
    }

    /// Samples a visible normal for `wo` and reflects `wo` about it.
    #[must_use]
    pub fn sample(&self, wo: Vec3, u: [f32; 2]) -> Option<SggxSample> {
        let f = Frame::from_normal(wo);
        let (wk, wj, wi) = (f.s, f.t, f.n);
        let sm = |a: Vec3, b: Vec3| a.dot(self.s * b);
        let (skk, sjj, sii) = (sm(wk, wk), sm(wj, wj), sm(wi, wi));
        let (skj, ski, sji) = (sm(wk, wj), sm(wk, wi), sm(wj, wi));
        let tmp = (sjj * sii - sji * sji).max(0.0).sqrt();
        if tmp <= 0.0 || sii <= 0.0 {
            return None;
        }
        let det = (skk * sjj * sii - skj * skj * sii - ski * ski * sjj - sji * sji * skk
            + 2.0 * skj * ski * sji)
            .abs();
        let inv = 1.0 / sii.sqrt();
        let mk = Vec3::new(det.sqrt() / tmp, 0.0, 0.0);
        let mj = inv * Vec3::new(-(ski * sji - skj * sii) / tmp, tmp, 0.0);
        let mi = inv * Vec3::new(ski, sji, sii);
        let r = u[0].sqrt();
        let phi = 2.0 * PI * u[1];
        let (x, y) = (r * phi.cos(), r * phi.sin());
        let z = (1.0 - x * x - y * y).max(0.0).sqrt();
        let mp = (x * mk + y * mj + z * mi).normalize();
        let m = mp.x * wk + mp.y * wj + mp.z * wi;
        let out = 2.0 * wo.dot(m) * m - wo;
        let pdf = self.pdf(wo, out);
        if pdf.is_nan() || pdf <= 0.0 || !out.is_finite() {
            return None;
        }
        Some(SggxSample {
            wi: out.normalize(),
            weight: self.albedo,
            pdf,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_fast_lands_in_minus_pi_to_pi() {
        for i in -4000..=4000 {
            let x = i as f32 * 0.01;
            let w = wrap_fast(x);
            assert!(w.abs() <= PI + 1e-5, "{x} -> {w}");
            assert!(
                (w - wrap(x)).abs() < 1e-5 || (w.abs() - PI).abs() < 1e-5,
                "{x}"
            );
        }
    }

    fn random_dir(rng: &mut crate::sampling::Rng) -> Vec3 {
        let z = 2.0 * rng.next_f32() - 1.0;
        let a = 2.0 * PI * rng.next_f32();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * a.cos(), r * a.sin(), z)
    }

    /// `mp` (precomputed `v` terms, the four `I₀` series in one loop, `M_3` shared with
    /// `M_2`) gives `longitudinal_lobe`'s bits for every lobe, in both of its forms
    /// (`v <= 0.1` and above, `I₀` series and asymptotic), with and without cuticle tilt.
    #[test]
    fn mp_gives_longitudinal_lobe_bit_for_bit() {
        let mut rng = crate::sampling::Rng::new(5, 3);
        for beta_m in [0.01, 0.05, 0.15, 0.3, 0.45, 0.7, 1.0] {
            for alpha in [0.0, 0.05, -0.2] {
                let phase = FibrePhase::new(FibrePhaseParams {
                    beta_m,
                    alpha,
                    ..FibrePhaseParams::default()
                })
                .unwrap();
                let frame = Frame::from_normal(random_dir(&mut rng));
                for _ in 0..2000 {
                    let o = angles(&frame, random_dir(&mut rng));
                    let i = angles(&frame, random_dir(&mut rng));
                    let m = phase.mp(&o, &i);
                    for (p, &mp) in m.iter().enumerate() {
                        let (s, c) = phase.tilted(p, o.sin_t, o.cos_t);
                        let want = longitudinal_lobe(i.cos_t, i.sin_t, c, s, phase.v[p]);
                        assert_eq!(
                            mp.to_bits(),
                            want.to_bits(),
                            "lobe {p}, β_m {beta_m}, α {alpha}: {mp} vs {want}"
                        );
                    }
                }
            }
        }
    }

    /// The sampler's precomputed constants give the bits of the expressions they replace.
    #[test]
    fn sampler_constants_give_the_per_sample_bits() {
        for beta in [0.01, 0.1, 0.3, 0.6, 1.0] {
            let phase = FibrePhase::new(FibrePhaseParams {
                beta_m: beta,
                beta_n: beta,
                ..FibrePhaseParams::default()
            })
            .unwrap();
            let s = phase.s;
            for i in 0..=1000 {
                let u = i as f32 / 1000.0;
                let k = logistic_cdf(PI, s) - logistic_cdf(-PI, s);
                let old = (-s * (1.0 / (u * k + logistic_cdf(-PI, s)) - 1.0).ln()).clamp(-PI, PI);
                let new =
                    sample_trimmed_logistic(u, s, phase.logistic_mass, phase.logistic_cdf_neg_pi);
                assert_eq!(old.to_bits(), new.to_bits(), "u {u}, β {beta}");
            }
            for p in 0..4 {
                let v = phase.v[p];
                assert_eq!(
                    phase.lon.exp_neg_2_over_v[p].to_bits(),
                    (-2.0 / v).exp().to_bits()
                );
            }
        }
    }

    /// The azimuthal sums with the nodes past the last full batch packed into shared batches,
    /// and lobes that are off (or a diffuse weight of 1) skipped, give the bits of one batch
    /// per lobe and sign over every lobe, for every unique node count from 1 to 64 (both table
    /// sizes), with and without AVX2.
    #[test]
    fn packed_tail_gives_the_batched_sums_bit_for_bit() {
        let mut rng = crate::sampling::Rng::new(9, 4);
        let lobe_sets = [
            (FibreLobes::default(), 0.3),
            (
                FibreLobes {
                    tt: false,
                    ..FibreLobes::default()
                },
                0.3,
            ),
            (
                FibreLobes {
                    r: false,
                    trt: false,
                    ..FibreLobes::default()
                },
                0.0,
            ),
            (FibreLobes::default(), 1.0),
        ];
        for (i, h_nodes) in (1..=128).filter(|n| n % 2 == 0 || *n < 20).enumerate() {
            let (lobes, diffuse_weight) = lobe_sets[i % lobe_sets.len()];
            let params = FibrePhaseParams {
                h_nodes,
                lobes,
                diffuse_weight,
                ..FibrePhaseParams::default()
            }
            .with_colour(Rgb::new(0.7, 0.3, 0.1));
            let phase = FibrePhase::new(params).unwrap();
            let active = phase.azimuthal_active;
            assert_eq!(
                active.iter().filter(|a| **a).count(),
                match i % 4 {
                    0 => 3,
                    1 => 2,
                    2 => 1,
                    _ => 0,
                }
            );
            let unique = phase.h_node_count().div_ceil(2);
            let neg_inv_s = -1.0 / phase.s;
            for _ in 0..40 {
                let prepared = phase.prepare(random_dir(&mut rng), random_dir(&mut rng));
                let dphi = (rng.next_f32() * 4.0 - 2.0) * PI;
                let check = |new: [[f32; 4]; 3], old: [[f32; 4]; 3]| {
                    let bits = |x: [[f32; 4]; 3]| x.map(|l| l.map(f32::to_bits));
                    assert_eq!(bits(new), bits(old), "{h_nodes} nodes, dphi {dphi}");
                };
                let batches = unique.div_ceil(LANES);
                match &prepared.table {
                    NodeTable::Inline(t) => {
                        let old = azimuthal_sums_reference(t, batches, dphi, neg_inv_s);
                        check(azimuthal_sums(t, unique, active, dphi, neg_inv_s), old);
                        check(phase.sums(t, unique, dphi, neg_inv_s), old);
                    }
                    NodeTable::Boxed(t) => {
                        let old = azimuthal_sums_reference(&**t, batches, dphi, neg_inv_s);
                        check(azimuthal_sums(&**t, unique, active, dphi, neg_inv_s), old);
                        check(phase.sums(&**t, unique, dphi, neg_inv_s), old);
                    }
                    NodeTable::Uncached => panic!("{h_nodes} nodes are cached"),
                }
            }
        }
    }

    /// The node terms filled by the vectorised `fill_table` (with and without AVX2) are the
    /// bits of the loop that filled them before, for odd and even node counts, both table
    /// sizes, black and saturated colours and lobes switched off.
    #[test]
    fn vectorised_node_terms_give_the_reference_bits() {
        fn bits<const N: usize>(t: &LobeTable<N>) -> Vec<u32> {
            let mut v: Vec<f32> = Vec::new();
            v.extend(t.phi.iter().flatten());
            v.extend(t.a.iter().flatten().flatten());
            v.extend(t.share.iter().flatten());
            v.extend(&t.mirror);
            v.extend(t.a3.iter().flatten());
            v.extend(&t.gamma_t);
            v.into_iter().map(f32::to_bits).collect()
        }
        fn sums_bits((v, p, d): (Rgb, f32, f32)) -> [u32; 5] {
            [v[0], v[1], v[2], p, d].map(f32::to_bits)
        }
        fn check<const N: usize>(phase: &FibrePhase, o: &Angles, sigma_a: Rgb, wd: f32) {
            let unique = phase.h_node_count().div_ceil(2);
            let mut want = LobeTable::<N>::ZERO;
            let want_sums = phase.fill_table_reference(&mut want, unique, o, sigma_a, wd);
            let mut got = LobeTable::<N>::ZERO;
            let got_sums = phase.fill_table(&mut got, unique, o, sigma_a, wd);
            assert_eq!(bits(&got), bits(&want), "{unique} unique nodes");
            assert_eq!(sums_bits(got_sums), sums_bits(want_sums));
            let mut got = LobeTable::<N>::ZERO;
            let got_sums = phase.fill_table_dispatch(&mut got, unique, o, sigma_a, wd);
            assert_eq!(bits(&got), bits(&want), "{unique} unique nodes (dispatch)");
            assert_eq!(sums_bits(got_sums), sums_bits(want_sums));
        }
        let mut rng = crate::sampling::Rng::new(13, 2);
        let colours = [
            Rgb::new(0.72, 0.1, 0.09),
            Rgb::ONE,
            Rgb::new(1e-4, 0.5, 0.99),
        ];
        for h_nodes in [0, 1, 2, 7, 8, 9, 16, 17, 33, 34, 63, 64, 65, 100, 127, 128] {
            for (ci, colour) in colours.into_iter().enumerate() {
                let lobes = FibreLobes {
                    trt: ci != 1,
                    ..FibreLobes::default()
                };
                let params = FibrePhaseParams {
                    h_nodes,
                    lobes,
                    diffuse_weight: if ci == 2 { 0.0 } else { 0.3 },
                    ..FibrePhaseParams::default()
                }
                .with_colour(colour);
                let phase = FibrePhase::new(params.clone()).unwrap();
                let frame = Frame::from_normal(random_dir(&mut rng));
                for _ in 0..50 {
                    let o = angles(&frame, random_dir(&mut rng));
                    let wd = lobe_weight(params.diffuse_albedo * params.diffuse_weight);
                    if phase.h_node_count().div_ceil(2) <= INLINE_NODES {
                        check::<INLINE_NODES>(&phase, &o, params.sigma_a, wd);
                    } else {
                        check::<CACHED_NODES>(&phase, &o, params.sigma_a, wd);
                    }
                }
            }
        }
    }

    /// The batched evaluation (fast `exp`/`asin`, lobes summed per lobe) against the node by
    /// node quadrature with the library's `exp` and `asin`: the same function to float
    /// precision, for saturated and grey colours, odd and even node counts, and lobes off.
    #[test]
    fn batched_eval_matches_the_node_by_node_quadrature() {
        let mut rng = crate::sampling::Rng::new(7, 1);
        let configs = [
            (Rgb::new(0.72, 0.1, 0.09), 0, FibreLobes::default()),
            (Rgb::new(0.86, 0.82, 0.72), 17, FibreLobes::default()),
            // 50 unique nodes: more than a vertex keeps inline (its table on the heap).
            (Rgb::new(0.3, 0.6, 0.9), 100, FibreLobes::default()),
            (
                Rgb::new(0.5, 0.4, 0.3),
                9,
                FibreLobes {
                    tt: false,
                    ..FibreLobes::default()
                },
            ),
        ];
        let dir = |rng: &mut crate::sampling::Rng| {
            let z = 2.0 * rng.next_f32() - 1.0;
            let a = 2.0 * PI * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(r * a.cos(), r * a.sin(), z)
        };
        for (colour, h_nodes, lobes) in configs {
            let params = FibrePhaseParams {
                h_nodes,
                lobes,
                ..FibrePhaseParams::default()
            }
            .with_colour(colour);
            let phase = FibrePhase::new(params).unwrap();
            for _ in 0..400 {
                let (wo, wi, t) = (dir(&mut rng), dir(&mut rng), dir(&mut rng));
                let prepared = phase.prepare(wo, t);
                let boxed = matches!(prepared.table, NodeTable::Boxed(_));
                assert_eq!(boxed, phase.h_node_count() > 2 * INLINE_NODES);
                let (v, p) = phase.eval_pdf_prepared(&prepared, wi);
                let frame = prepared.frame.unwrap();
                let i = angles(&frame, wi);
                let m = phase.mp(&prepared.o, &i);
                let dphi = i.phi - prepared.o.phi;
                let dd = FibrePhase::diffuse_density(&prepared.o, &i);
                let (rv, rp) = phase.eval_pdf_uncached(&prepared, m, dphi, dd);
                let close = |a: f32, b: f32| (a - b).abs() <= 2e-5 * b.abs() + 1e-30;
                assert!(close(p, rp), "pdf {p} vs {rp} ({colour:?}, {h_nodes})");
                for c in 0..3 {
                    assert!(
                        close(v[c], rv[c]),
                        "value {v:?} vs {rv:?} ({colour:?}, {h_nodes})"
                    );
                }
            }
        }
    }

    /// A slot reused from vertex to vertex ([`FibrePhase::prepare_into`], its table refilled
    /// without clearing) evaluates and samples bit for bit as a vertex prepared afresh: with
    /// phase functions of 64, 34, 18, 9 (odd: an unpaired middle node) and 100 nodes (a boxed
    /// table) taken in turn, so that entries past a vertex's node count hold an earlier
    /// vertex's terms (non-zero), coloured vertices, and zero tangents (no table) between.
    #[test]
    fn reused_slots_give_fresh_vertices_bits() {
        let mut rng = crate::sampling::Rng::new(11, 3);
        let dir = |rng: &mut crate::sampling::Rng| {
            let z = 2.0 * rng.next_f32() - 1.0;
            let a = 2.0 * PI * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            Vec3::new(r * a.cos(), r * a.sin(), z)
        };
        let phases: Vec<FibrePhase> = [64u32, 34, 18, 9, 100]
            .iter()
            .map(|&h_nodes| {
                FibrePhase::new(
                    FibrePhaseParams {
                        h_nodes,
                        ..FibrePhaseParams::default()
                    }
                    .with_colour(Rgb::new(0.72, 0.3, 0.09)),
                )
                .unwrap()
            })
            .collect();
        let colour = FibreColour::new(Rgb::new(0.2, 0.5, 0.8), 0.3);
        let bits =
            |(v, p): (Rgb, f32)| [v[0].to_bits(), v[1].to_bits(), v[2].to_bits(), p.to_bits()];
        let mut slot = PreparedFibre::empty();
        let mut stale = 0;
        for i in 0..600 {
            let phase = &phases[(i * 7 + i / 5) % phases.len()];
            let (wo, wi) = (dir(&mut rng), dir(&mut rng));
            let t = if i % 23 == 0 {
                Vec3::ZERO
            } else {
                dir(&mut rng)
            };
            let u = [
                rng.next_f32(),
                rng.next_f32(),
                rng.next_f32(),
                rng.next_f32(),
            ];
            let (fresh, reused) = if i % 3 == 0 {
                phase.prepare_coloured_into(&mut slot, wo, t, &colour);
                (phase.prepare_coloured(wo, t, &colour), &slot)
            } else {
                phase.prepare_into(&mut slot, wo, t);
                (phase.prepare(wo, t), &slot)
            };
            if let NodeTable::Inline(table) = &reused.table {
                let unique = phase.h_node_count().div_ceil(2);
                stale += usize::from(table.phi[0][unique..].iter().any(|&x| x != 0.0));
            }
            assert_eq!(
                bits(phase.eval_pdf_prepared(reused, wi)),
                bits(phase.eval_pdf_prepared(&fresh, wi)),
                "vertex {i}"
            );
            let sample = |p: &PreparedFibre| {
                phase
                    .sample_prepared(p, u)
                    .map(|s| (s.wi.to_array().map(f32::to_bits), bits((s.weight, s.pdf))))
            };
            assert_eq!(sample(reused), sample(&fresh), "vertex {i}");
        }
        // The check reached tables whose entries past the node count were not zero.
        assert!(stale > 50, "{stale} vertices with stale entries");
    }

    /// Every cell of the tangent grid maps back to itself from its centre, `t` and `−t` share
    /// a cell, and a tangent's cell centre is within the cell size of it.
    #[test]
    fn tangent_cells_round_trip_and_lie_near_their_tangents() {
        for n in [1, 2, 8, QUANTISED_GRID] {
            for k in 0..n * n {
                let c = cell_tangent(k, n);
                assert!((c.length() - 1.0).abs() < 1e-5);
                assert_eq!(tangent_cell(c, n), Some(k), "cell {k} of {n}²");
            }
        }
        let mut rng = crate::sampling::Rng::new(3, 1);
        let n = 8;
        let mut worst = 1.0f32;
        for _ in 0..20_000 {
            let z = 2.0 * rng.next_f32() - 1.0;
            let a = 2.0 * PI * rng.next_f32();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let t = Vec3::new(r * a.cos(), r * a.sin(), z);
            let k = tangent_cell(t, n).unwrap();
            if z != 0.0 {
                assert_eq!(tangent_cell(-t, n), Some(k));
            }
            worst = worst.min(cell_tangent(k, n).dot(t).abs());
        }
        // The octahedral cells of an 8² grid over the hemisphere are at most ~0.3 rad across.
        assert!(
            worst > 0.3f32.cos(),
            "farthest cell centre: {} rad",
            worst.acos()
        );
        assert_eq!(tangent_cell(Vec3::ZERO, n), None);
        assert_eq!(tangent_cell(Vec3::new(f32::NAN, 0.0, 1.0), n), None);
    }

    /// The quantised lobe is the vertex prepared around its cell's centre, kept for the first
    /// `wo` only; its pdf integrates to 1 over the sphere and its samples fall where its pdf
    /// says (coarse bins, 5σ).
    #[test]
    fn quantised_lobe_pdf_integrates_to_one_and_matches_its_samples() {
        let phase =
            FibrePhase::new(FibrePhaseParams::default().with_colour(Rgb::new(0.72, 0.1, 0.09)))
                .unwrap();
        let wo = Vec3::new(0.45, -0.75, -0.5).normalize();
        let mut rng = crate::sampling::Rng::new(11, 2);
        for t in [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.6, -0.1, -0.79),
            Vec3::new(-0.3, 0.95, 0.05),
        ] {
            let lobe = phase.quantised_lobe(wo, t).unwrap();
            let n = QUANTISED_GRID;
            let centre = cell_tangent(tangent_cell(t, n).unwrap(), n);
            let own = phase.prepare(wo, centre);
            let probe = Vec3::new(0.2, 0.3, -0.93).normalize();
            assert_eq!(
                phase.eval_pdf_prepared(lobe, probe),
                phase.eval_pdf_prepared(&own, probe)
            );
            assert!(phase.quantised_lobe(-wo, t).is_none());
            // Bins: 6 bands of sin θ along the cell's tangent × 8 of the azimuth around it.
            let frame = lobe.frame.unwrap();
            let bin = |w: Vec3| {
                let a = angles(&frame, w);
                let band = (((a.sin_t + 1.0) * 3.0) as usize).min(5);
                let sector = (((a.phi + PI) / (2.0 * PI) * 8.0) as usize).min(7);
                band * 8 + sector
            };
            // Midpoint rule in (sin θ, φ): dω = d(sin θ) dφ.
            let (ns, nphi) = (600, 600);
            let mut mass = [0.0f64; 48];
            for i in 0..ns {
                let sin_t = -1.0 + (i as f32 + 0.5) * 2.0 / ns as f32;
                let cos_t = (1.0 - sin_t * sin_t).max(0.0).sqrt();
                for j in 0..nphi {
                    let phi = -PI + (j as f32 + 0.5) * 2.0 * PI / nphi as f32;
                    let w = frame.to_world(Vec3::new(cos_t * phi.cos(), cos_t * phi.sin(), sin_t));
                    let d = (2.0 / ns as f64) * (2.0 * std::f64::consts::PI / nphi as f64);
                    mass[bin(w)] += phase.eval_pdf_prepared(lobe, w).1 as f64 * d;
                }
            }
            let total: f64 = mass.iter().sum();
            assert!((total - 1.0).abs() < 0.01, "∫ pdf = {total} ({t:?})");
            let count = 100_000;
            let mut hits = [0u32; 48];
            for _ in 0..count {
                let u = std::array::from_fn(|_| rng.next_f32());
                let s = phase.sample_prepared(lobe, u).unwrap();
                let (_, pdf) = phase.eval_pdf_prepared(lobe, s.wi);
                assert!((s.pdf - pdf).abs() <= 1e-5 * pdf);
                hits[bin(s.wi)] += 1;
            }
            for (b, (&h, &m)) in hits.iter().zip(&mass).enumerate() {
                let f = h as f64 / count as f64;
                let sigma = (m.max(1e-4) * (1.0 - m) / count as f64).sqrt();
                assert!(
                    (f - m).abs() < 5.0 * sigma + 2e-3 * m,
                    "bin {b}: samples {f} vs pdf mass {m} ({t:?})"
                );
            }
        }
    }
}
