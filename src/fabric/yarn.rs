//! The procedural yarn model of Zhao, Luan and Bala 2016, "Fitting Procedural Yarn Models
//! for Realistic Cloth Rendering" (ACM TOG 35(4)), building on Schröder et al. 2015.
//!
//! A yarn is `K` plies twisted around the yarn axis; a ply is `m` fibres twisted around the
//! ply axis, spread over an elliptical cross-section with the radial density of the paper's
//! eq. (1) and migrating in and out (eq. (3)); loop-type and hair-type flyaway fibres are
//! added per ply. Yarns are generated along the `z` axis from `z = 0` to `z = length` and can
//! be bent onto any centreline ([`Centreline`]), mapping `z` to arc length with a
//! rotation-minimising frame (double reflection, Wang et al. 2008).
//!
//! **Units.** Every length is in the same unit; the presets ([`YarnParams::preset`]) are in
//! **centimetres** and densities in **per centimetre**, as in the released fits. Call
//! [`YarnParams::scaled`] to change units (e.g. `scaled(10.0)` for millimetres). Angles are in
//! radians.

use super::{check_positive, check_range, invalid, FabricError};
use crate::math::{Vec2, Vec3, PI};
use crate::sampling::Rng;

/// Largest number of polyline vertices one generation call may produce (about 0.6 GB of
/// `Vec3`); beyond it generation fails with [`FabricError::TooLarge`].
pub const MAX_VERTICES: u64 = 50_000_000;
/// Largest `ply_count · fibres_per_ply` accepted by [`YarnParams::validate`].
pub const MAX_FIBRES_PER_YARN: u64 = 1_000_000;

const TAU: f32 = 2.0 * PI;

/// A normal distribution `N(mean, std_dev²)` of a flyaway parameter.
///
/// The released configuration files store a value `σ_cfg` that their generator uses as
/// `μ + 0.5·σ_cfg·N(0,1)` ("twice the sigma"); the presets here store the actual standard
/// deviation, `std_dev = 0.5·σ_cfg`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NormalDist {
    /// Mean (units of the parameter it describes).
    pub mean: f32,
    /// Standard deviation (same units), `>= 0`.
    pub std_dev: f32,
}

impl NormalDist {
    /// A distribution from the released files' `(μ, σ_cfg)` pair (`std_dev = σ_cfg / 2`).
    #[must_use]
    pub const fn from_config(mean: f32, sigma_cfg: f32) -> Self {
        NormalDist {
            mean,
            std_dev: 0.5 * sigma_cfg,
        }
    }
    /// Draws one value (Box–Muller).
    pub fn sample(&self, rng: &mut Rng) -> f32 {
        self.mean + self.std_dev * standard_normal(rng)
    }
}

/// Draws a standard normal number (Box–Muller, one of the pair).
pub(crate) fn standard_normal(rng: &mut Rng) -> f32 {
    let u1 = 1.0 - rng.next_f32(); // (0, 1]
    let u2 = rng.next_f32();
    (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
}

/// Handedness of a twist. `Z`: right-handed helix (the angle grows counter-clockwise with
/// `z`); `S`: left-handed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Twist {
    /// Left-handed (angle decreases with `z`).
    S,
    /// Right-handed (angle increases with `z`).
    Z,
}

impl Twist {
    /// `+1` for `Z`, `-1` for `S`.
    #[must_use]
    pub fn sign(self) -> f32 {
        match self {
            Twist::Z => 1.0,
            Twist::S => -1.0,
        }
    }
}

/// All parameters of the procedural yarn (docs/references.md §6.1–6.8; Zhao et al. 2016 Table 2).
///
/// Lengths in the scene unit (presets: cm), densities per unit length, angles in radians;
/// "normalised" quantities are relative to the ply's unit cross-section before the
/// elliptical scaling.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct YarnParams {
    /// `K`, the number of plies, in `1..=64`.
    pub ply_count: u32,
    /// `m`, regular fibres per ply, `>= 1`; `ply_count · fibres_per_ply <= 10^6`.
    pub fibres_per_ply: u32,
    /// Radius of the yarn as fitted (length, `> 0`); used for documentation and clearance
    /// estimates only ([`YarnParams::envelope_radius`] is what the weave uses).
    pub yarn_radius: f32,
    /// `R_ply`, distance of ply centres from the yarn axis (length, `>= 0`). The released
    /// tool uses `yarn_radius / 2`, as do the presets; use 0 for a single ply.
    pub ply_offset: f32,
    /// `α_ply`, length of one full turn of the plies around the yarn axis (`> 0`).
    pub ply_pitch: f32,
    /// Handedness of the ply twist.
    pub ply_twist: Twist,
    /// `e_X`, semi-axis of the ply cross-section along the radial axis (towards the yarn
    /// centre; length, `> 0`).
    pub ellipse_x: f32,
    /// `e_Y`, semi-axis of the ply cross-section perpendicular to it (length, `> 0`).
    pub ellipse_y: f32,
    /// `α`, length of one full turn of a fibre around its ply centre (`> 0`).
    pub fibre_pitch: f32,
    /// Handedness of the fibre twist (opposite to `ply_twist` in every published fit; the
    /// presets take both from the configs' `yarn_clock_wise`/`fiber_clock_wise` flags,
    /// `clock_wise = 1` ⇔ `S`).
    pub fibre_twist: Twist,
    /// `ε` of the cross-sectional density `p(R)` (eq. 1), in `[0, 1)`.
    pub epsilon: f32,
    /// `β` of the cross-sectional density `p(R)`, in `[0, 20]`.
    pub beta: f32,
    /// `R_min`, smallest migration radius ratio, in `[0, r_max]`.
    pub r_min: f32,
    /// `R_max`, largest migration radius ratio, in `(0, 2]` (1 in every fit).
    pub r_max: f32,
    /// `s`, migration cycles per fibre turn (`>= 0`; 0 disables migration).
    pub migration_freq: f32,
    /// Physical radius of one fibre (length, `> 0`). Not part of the fits: the presets use
    /// typical textile values (cotton 8 µm, polyester/rayon/silk 6 µm) (our assumption).
    pub fibre_radius: f32,
    /// `ρ_hair`, hair-type flyaways per ply per unit length (`>= 0`).
    pub hair_density: f32,
    /// `z_span^hair`, axial extent of a hair (length; any sign).
    pub hair_z_span: NormalDist,
    /// `R_min^hair`, radius (from the ply centre) where a hair starts (length; resampled
    /// until `>= 0`).
    pub hair_r_min: NormalDist,
    /// `R_span^hair`, radial extent of a hair (length; resampled until `> 0`).
    pub hair_r_span: NormalDist,
    /// `θ_span^hair`, angular extent of a hair around the ply centre (radians; any sign).
    pub hair_theta_span: NormalDist,
    /// Polyline segments per hair, in `1..=256` (the released tool uses 24).
    pub hair_segments: u32,
    /// `ρ_loop`, loop-type flyaways per ply per unit length (`>= 0`).
    pub loop_density: f32,
    /// `R_max^loop`, radius reached at the top of a loop (length; normalised by
    /// `sqrt(e_X e_Y)` internally and resampled until it exceeds the fibre's own maximum).
    pub loop_r_max: NormalDist,
    /// Axial distance between consecutive polyline vertices of regular fibres (length,
    /// `> 0`). Presets: `min(α, α_ply) / 32`.
    pub segment_length: f32,
}

/// Names accepted by [`YarnParams::preset`] (aliases `cotton`, `polyester`, `rayon`, `silk`
/// map to the first fit of each material).
pub const PRESET_NAMES: &[&str] = &[
    "cotton1",
    "cotton2",
    "polyester1",
    "rayon1",
    "rayon2",
    "rayon3",
    "rayon4",
    "silk1",
    "silk2",
    "cotton",
    "polyester",
    "rayon",
    "silk",
];

/// One row of the fitted-parameter table (docs/references.md §6.8), in cm.
struct PresetRow {
    k: u32,
    m: u32,
    yarn_radius: f32,
    ply_pitch: f32,
    ex: f32,
    ey: f32,
    alpha: f32,
    eps: f32,
    beta: f32,
    r_min: f32,
    s: f32,
    rho_hair: f32,
    z_span: (f32, f32),
    r_min_hair: (f32, f32),
    r_span_hair: (f32, f32),
    theta_span: (f32, f32),
    rho_loop: f32,
    r_loop: (f32, f32),
    fibre_radius: f32,
    /// `yarn_clock_wise: 1` in the config file (ply twist S, fibre twist Z); otherwise ply Z,
    /// fibre S.
    ply_s: bool,
}

#[rustfmt::skip]
fn preset_row(name: &str) -> Option<PresetRow> {
    let r = |k, m, yarn_radius, ply_pitch, ex, ey, alpha, eps, beta, r_min, s, rho_hair, z_span, r_min_hair, r_span_hair, theta_span, rho_loop, r_loop, fibre_radius, ply_s| PresetRow {
        k, m, yarn_radius, ply_pitch, ex, ey, alpha, eps, beta, r_min, s, rho_hair, z_span, r_min_hair, r_span_hair, theta_span, rho_loop, r_loop, fibre_radius, ply_s,
    };
    Some(match name {
        "cotton1" | "cotton" => r(3, 75, 0.03782, 0.4527, 0.02004, 0.02572, 0.3661, 0.0, 0.2010, 0.85, 1.0, 30.36, (0.0024, 0.0632), (0.0204, 0.0056), (0.0167, 0.0095), (0.390, 0.342), 19.10, (0.0246, 0.0052), 0.0008, false),
        "cotton2" => r(3, 36, 0.03304, 0.3363, 0.01799, 0.02475, 0.4347, 0.0109, 0.4170, 0.95, 1.9, 20.53, (0.0152, 0.0466), (0.0208, 0.0052), (0.0127, 0.0069), (0.396, 0.379), 15.39, (0.0248, 0.0064), 0.0008, false),
        "polyester1" | "polyester" => r(2, 60, 0.02871, 0.3704, 0.02110, 0.02854, 0.3796, 0.3385, 0.4229, 0.70, 1.1, 31.49, (-0.0054, 0.0510), (0.0208, 0.0049), (0.0119, 0.0086), (0.408, 0.451), 34.11, (0.0270, 0.0040), 0.0006, false),
        "rayon1" | "rayon" => r(2, 150, 0.05071, 0.6393, 0.03559, 0.05311, 0.7115, 0.1408, 0.6909, 0.85, 1.9, 53.04, (0.0135, 0.0631), (0.0416, 0.0070), (0.0200, 0.0186), (0.376, 0.415), 64.48, (0.0507, 0.0107), 0.0006, true),
        "rayon2" => r(2, 79, 0.02867, 0.3723, 0.02088, 0.02830, 0.3777, 0.2417, 0.3895, 0.80, 1.5, 47.31, (0.0016, 0.0269), (0.0185, 0.0051), (0.0125, 0.0069), (0.461, 0.528), 36.51, (0.0262, 0.0059), 0.0006, false),
        "rayon3" => r(2, 143, 0.04185, 0.6384, 0.03351, 0.04411, 0.6129, 0.0, 0.6326, 0.95, 1.9, 53.72, (-0.0118, 0.1220), (0.0305, 0.0054), (0.0291, 0.0187), (0.799, 0.718), 46.05, (0.0398, 0.0112), 0.0006, true),
        "rayon4" => r(2, 122, 0.04522, 0.4978, 0.03432, 0.04830, 0.5577, 0.1637, 0.4000, 0.80, 1.6, 66.82, (0.0145, 0.0490), (0.0387, 0.0072), (0.0212, 0.0157), (0.333, 0.274), 63.64, (0.0441, 0.0107), 0.0006, true),
        "silk1" | "silk" => r(3, 33, 0.03762, 0.5255, 0.02160, 0.02527, 0.4603, 0.0, 0.4851, 0.95, 0.1, 24.87, (0.0184, 0.0505), (0.0218, 0.0052), (0.0132, 0.0102), (0.405, 0.402), 20.67, (0.0256, 0.0049), 0.0006, false),
        "silk2" => r(3, 47, 0.04505, 0.7017, 0.02523, 0.03059, 0.5602, 0.4017, 0.5941, 0.70, 1.2, 25.54, (0.0060, 0.0414), (0.0236, 0.0046), (0.0110, 0.0087), (0.448, 0.443), 20.64, (0.0281, 0.0045), 0.0006, false),
        _ => return None,
    })
}

impl YarnParams {
    /// A named preset from the published fits (docs/references.md §6.8), in **centimetres**. Names:
    /// [`PRESET_NAMES`] (case-insensitive). The fibre radius is not part of the fits (see
    /// [`YarnParams::fibre_radius`]).
    pub fn preset(name: &str) -> Result<YarnParams, FabricError> {
        let lower = name.trim().to_ascii_lowercase();
        let Some(p) = preset_row(&lower) else {
            return Err(FabricError::UnknownPreset {
                name: name.to_string(),
                allowed: PRESET_NAMES.join(", "),
            });
        };
        let nd = |(m, s): (f32, f32)| NormalDist::from_config(m, s);
        Ok(YarnParams {
            ply_count: p.k,
            fibres_per_ply: p.m,
            yarn_radius: p.yarn_radius,
            ply_offset: 0.5 * p.yarn_radius,
            ply_pitch: p.ply_pitch,
            ply_twist: if p.ply_s { Twist::S } else { Twist::Z },
            ellipse_x: p.ex,
            ellipse_y: p.ey,
            fibre_pitch: p.alpha,
            fibre_twist: if p.ply_s { Twist::Z } else { Twist::S },
            epsilon: p.eps,
            beta: p.beta,
            r_min: p.r_min,
            r_max: 1.0,
            migration_freq: p.s,
            fibre_radius: p.fibre_radius,
            hair_density: p.rho_hair,
            hair_z_span: nd(p.z_span),
            hair_r_min: nd(p.r_min_hair),
            hair_r_span: nd(p.r_span_hair),
            hair_theta_span: nd(p.theta_span),
            hair_segments: 24,
            loop_density: p.rho_loop,
            loop_r_max: nd(p.r_loop),
            segment_length: p.alpha.min(p.ply_pitch) / 32.0,
        })
    }

    /// Checks every parameter; the error names the first bad one and its allowed range.
    pub fn validate(&self) -> Result<(), FabricError> {
        if !(1..=64).contains(&self.ply_count) {
            return Err(invalid("ply_count", self.ply_count, "1..=64"));
        }
        if self.fibres_per_ply == 0 {
            return Err(invalid("fibres_per_ply", 0, "1..=1000000 (with ply_count)"));
        }
        let total = self.ply_count as u64 * self.fibres_per_ply as u64;
        if total > MAX_FIBRES_PER_YARN {
            return Err(FabricError::TooLarge {
                name: "fibres_per_ply".into(),
                what: "fibres per yarn (ply_count · fibres_per_ply)".into(),
                count: total,
                limit: MAX_FIBRES_PER_YARN,
            });
        }
        const BIG: f32 = 1.0e6;
        check_positive("yarn_radius", self.yarn_radius, BIG)?;
        check_range("ply_offset", self.ply_offset, 0.0, BIG)?;
        check_positive("ply_pitch", self.ply_pitch, BIG)?;
        check_positive("ellipse_x", self.ellipse_x, BIG)?;
        check_positive("ellipse_y", self.ellipse_y, BIG)?;
        check_positive("fibre_pitch", self.fibre_pitch, BIG)?;
        if !(self.epsilon.is_finite() && (0.0..1.0).contains(&self.epsilon)) {
            return Err(invalid("epsilon", self.epsilon, "[0, 1)"));
        }
        check_range("beta", self.beta, 0.0, 20.0)?;
        check_positive("r_max", self.r_max, 2.0)?;
        check_range("r_min", self.r_min, 0.0, self.r_max)?;
        check_range("migration_freq", self.migration_freq, 0.0, 1000.0)?;
        check_positive("fibre_radius", self.fibre_radius, BIG)?;
        check_range("hair_density", self.hair_density, 0.0, BIG)?;
        check_range("loop_density", self.loop_density, 0.0, BIG)?;
        for (name, d) in [
            ("hair_z_span", self.hair_z_span),
            ("hair_r_min", self.hair_r_min),
            ("hair_r_span", self.hair_r_span),
            ("hair_theta_span", self.hair_theta_span),
            ("loop_r_max", self.loop_r_max),
        ] {
            if !d.mean.is_finite() || d.mean.abs() > BIG {
                return Err(invalid(&format!("{name}.mean"), d.mean, "a finite value"));
            }
            check_range(&format!("{name}.std_dev"), d.std_dev, 0.0, BIG)?;
        }
        if self.hair_density > 0.0
            && self.hair_r_span.mean <= 0.0
            && self.hair_r_span.std_dev == 0.0
        {
            return Err(invalid(
                "hair_r_span.mean",
                self.hair_r_span.mean,
                "> 0 when std_dev = 0",
            ));
        }
        if !(1..=256).contains(&self.hair_segments) {
            return Err(invalid("hair_segments", self.hair_segments, "1..=256"));
        }
        check_positive("segment_length", self.segment_length, BIG)?;
        Ok(())
    }

    /// The same yarn in other length units: every length is multiplied by `factor` and every
    /// per-length density divided by it (e.g. `factor = 10` converts the cm presets to mm).
    pub fn scaled(&self, factor: f32) -> Result<YarnParams, FabricError> {
        check_positive("scale factor", factor, 1.0e6)?;
        let sd = |d: NormalDist| NormalDist {
            mean: d.mean * factor,
            std_dev: d.std_dev * factor,
        };
        Ok(YarnParams {
            yarn_radius: self.yarn_radius * factor,
            ply_offset: self.ply_offset * factor,
            ply_pitch: self.ply_pitch * factor,
            ellipse_x: self.ellipse_x * factor,
            ellipse_y: self.ellipse_y * factor,
            fibre_pitch: self.fibre_pitch * factor,
            fibre_radius: self.fibre_radius * factor,
            hair_density: self.hair_density / factor,
            hair_z_span: sd(self.hair_z_span),
            hair_r_min: sd(self.hair_r_min),
            hair_r_span: sd(self.hair_r_span),
            loop_density: self.loop_density / factor,
            loop_r_max: sd(self.loop_r_max),
            segment_length: self.segment_length * factor,
            ..self.clone()
        })
    }

    /// The same yarn with both flyaway densities (`hair_density`, `loop_density`) multiplied
    /// by `scale` (`>= 0`; 1 keeps the fitted amount, 0 removes flyaways).
    pub fn with_flyaway_scale(&self, scale: f32) -> Result<YarnParams, FabricError> {
        check_range("flyaway_fraction", scale, 0.0, 100.0)?;
        Ok(YarnParams {
            hair_density: self.hair_density * scale,
            loop_density: self.loop_density * scale,
            ..self.clone()
        })
    }

    /// Radius of the cylinder around the yarn axis that contains every regular fibre:
    /// `ply_offset + r_max · max(e_X, e_Y)` (flyaways may leave it).
    #[must_use]
    pub fn envelope_radius(&self) -> f32 {
        self.ply_offset + self.r_max * self.ellipse_x.max(self.ellipse_y)
    }

    /// Angle of ply `ply`'s centre around the yarn axis at height `z` (eq. 6):
    /// `θ_ply + sign · 2π z / α_ply`, `θ_ply = 2π ply / K`.
    #[must_use]
    pub fn ply_angle(&self, ply: u32, z: f32) -> f32 {
        TAU * ply as f32 / self.ply_count.max(1) as f32
            + self.ply_twist.sign() * TAU * z / self.ply_pitch
    }

    /// Centre of ply `ply` in the yarn cross-section at height `z`.
    #[must_use]
    pub fn ply_centre(&self, ply: u32, z: f32) -> Vec2 {
        let a = self.ply_angle(ply, z);
        self.ply_offset * Vec2::new(a.cos(), a.sin())
    }

    /// The co-rotating axes of ply `ply` at height `z`: `(radial, tangential)` unit vectors
    /// of the yarn cross-section. The ply ellipse has semi-axis `e_X` along `radial`
    /// (pointing away from the yarn centre) and `e_Y` along `tangential`.
    #[must_use]
    pub fn ply_axes(&self, ply: u32, z: f32) -> (Vec2, Vec2) {
        let a = self.ply_angle(ply, z);
        (Vec2::new(a.cos(), a.sin()), Vec2::new(-a.sin(), a.cos()))
    }

    /// The acceptance function `p(R) = (1 − 2ε)((e − e^R)/(e − 1))^β + ε` of the paper's
    /// eq. (1) for a normalised radius `r ∈ [0, 1)`. The radial density of fibre centres is
    /// `2R p(R) / q` with `q = ∫₀¹ 2R p(R) dR`.
    #[must_use]
    pub fn cross_section_acceptance(&self, r: f32) -> f32 {
        let e = std::f32::consts::E;
        let base = ((e - r.exp()) / (e - 1.0)).max(0.0);
        (1.0 - 2.0 * self.epsilon) * base.powf(self.beta) + self.epsilon
    }

    /// Draws a fibre centre in the unit ply cross-section by rejection (the paper's
    /// Algorithm 2): uniform in the disc, accepted with probability `p(R)`.
    pub fn sample_cross_section(&self, rng: &mut Rng) -> Vec2 {
        let mut last = Vec2::ZERO;
        for _ in 0..100_000 {
            let r = rng.next_f32().sqrt();
            let phi = TAU * rng.next_f32();
            last = r * Vec2::new(phi.cos(), phi.sin());
            if rng.next_f32() < self.cross_section_acceptance(r) {
                return last;
            }
        }
        last
    }
}

/// The kind of a generated fibre.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FibreKind {
    /// A regular ply fibre (helix with migration).
    Regular,
    /// A regular fibre carrying at least one loop-type flyaway.
    Loop,
    /// A hair-type flyaway (one end outside the ply).
    Hair,
    /// A velvet pile fibre (see [`super::weave::PileParams`]).
    Pile,
}

/// One fibre: a polyline with a constant radius.
#[derive(Clone, Debug, PartialEq)]
pub struct Fibre {
    /// Vertices (world/scene units).
    pub points: Vec<Vec3>,
    /// Physical fibre radius (length).
    pub radius: f32,
    /// What kind of fibre this is.
    pub kind: FibreKind,
    /// Index of the ply it belongs to (0 for pile fibres).
    pub ply: u32,
    /// `R_i`, the fibre's normalised cross-section radius before migration (regular and loop
    /// fibres); 0 for hair and pile fibres.
    pub section_radius: f32,
    /// `θ_i`, the fibre's initial angle in the ply cross-section (regular and loop fibres;
    /// 0 otherwise).
    pub section_angle: f32,
}

impl Fibre {
    /// Length of the polyline.
    #[must_use]
    pub fn length(&self) -> f64 {
        self.points
            .windows(2)
            .map(|w| (w[1] - w[0]).length() as f64)
            .sum()
    }
    /// Volume of the fibre as a chain of cylinders: `Σ π r² |p_{k+1} − p_k|`.
    #[must_use]
    pub fn volume(&self) -> f64 {
        std::f64::consts::PI * (self.radius as f64).powi(2) * self.length()
    }
}

/// A generated yarn.
#[derive(Clone, Debug)]
pub struct Yarn {
    /// Regular and loop fibres first (ply by ply, `fibres_per_ply` each), then hairs.
    pub fibres: Vec<Fibre>,
    /// Axial length (arc length of the centreline when bent).
    pub length: f32,
    /// Number of loop-type flyaways (a fibre may carry several).
    pub loop_count: usize,
    /// Number of hair-type flyaways (= fibres of kind [`FibreKind::Hair`]).
    pub hair_count: usize,
}

impl Yarn {
    /// Sum of the fibre volumes.
    #[must_use]
    pub fn fibre_volume(&self) -> f64 {
        self.fibres.iter().map(Fibre::volume).sum()
    }
}

/// A loop applied to a fibre: radii inside `[centre − width/2, centre + width/2]` are
/// multiplied by `1 + (k − 1)·½(1 + cos(2π(z − centre)/width))`.
struct LoopBump {
    centre: f32,
    width: f32,
    k: f32,
}

/// Poisson process of the given rate on `[0, length)`: the event positions.
fn poisson_positions(rng: &mut Rng, rate: f32, length: f32) -> Vec<f32> {
    let mut out = Vec::new();
    if rate <= 0.0 || length <= 0.0 {
        return out;
    }
    let mut z = 0.0f64;
    loop {
        let u = rng.next_f64();
        z += -(1.0 - u).ln() / rate as f64;
        if z >= length as f64 {
            return out;
        }
        out.push(z as f32);
    }
}

fn redraw(d: NormalDist, rng: &mut Rng, ok: impl Fn(f32) -> bool, fallback: f32) -> f32 {
    for _ in 0..64 {
        let v = d.sample(rng);
        if ok(v) {
            return v;
        }
    }
    fallback
}

/// Generates a straight yarn along `+z` from `z = 0` to `z = length`, deterministic in
/// `seed`. Hair and loop events per ply come from Poisson processes of rates `ρ_hair` and
/// `ρ_loop` (so their counts are Poisson with mean `ρ·length`). Hairs are cropped to
/// `[0, length]` and dropped if fewer than two vertices remain. A loop event raises the
/// migration period of a random fibre around it to `R_max^loop`; loops never overlap (an
/// event landing on a period that already has a loop re-picks the fibre, up to 16 times,
/// then is dropped), so loop counts saturate at one per fibre per migration period.
pub fn generate_yarn(params: &YarnParams, length: f32, seed: u64) -> Result<Yarn, FabricError> {
    params.validate()?;
    check_positive("length", length, 1.0e6)?;
    let p = params;
    let n_seg = (length / p.segment_length).ceil().max(1.0) as u64;
    let regular = p.ply_count as u64 * p.fibres_per_ply as u64;
    let hair_expect = (p.hair_density as f64 * length as f64 * p.ply_count as f64) as u64;
    let verts = regular * (n_seg + 1) + hair_expect * (p.hair_segments as u64 + 1);
    if verts > MAX_VERTICES {
        return Err(FabricError::TooLarge {
            name: "segment_length / length / fibres_per_ply".into(),
            what: "polyline vertices".into(),
            count: verts,
            limit: MAX_VERTICES,
        });
    }
    let mut rng = Rng::new(seed, 0x7961_726e);
    let norm_loop = (p.ellipse_x * p.ellipse_y).sqrt();
    let sf = p.fibre_twist.sign();
    let mut fibres = Vec::with_capacity(regular as usize);
    let mut loop_count = 0usize;
    let mut hair_count = 0usize;
    let mut hairs = Vec::new();
    for ply in 0..p.ply_count {
        // Regular fibres' parameters.
        struct Reg {
            r_i: f32,
            theta_i: f32,
            theta_m: f32,
            loops: Vec<LoopBump>,
        }
        let mut regs: Vec<Reg> = (0..p.fibres_per_ply)
            .map(|_| {
                let c = p.sample_cross_section(&mut rng);
                Reg {
                    r_i: c.length(),
                    theta_i: c.y.atan2(c.x),
                    theta_m: TAU * rng.next_f32(),
                    loops: Vec::new(),
                }
            })
            .collect();
        let migr = |r: &Reg, z: f32| {
            let th = TAU * z / p.fibre_pitch;
            r.r_i
                * (p.r_min
                    + (p.r_max - p.r_min) * 0.5 * ((p.migration_freq * th + r.theta_m).cos() + 1.0))
        };
        // Loop-type flyaways: Poisson process along the ply; each picks a fibre and the
        // migration period around the event, whose peak is raised to R_max^loop.
        for z_e in poisson_positions(&mut rng, p.loop_density, length) {
            // Pick a fibre whose migration period around z_e carries no loop yet (loops
            // never overlap; after 16 failed picks the event is dropped).
            for _ in 0..16 {
                let idx = ((rng.next_f32() * regs.len() as f32) as usize).min(regs.len() - 1);
                let r = &regs[idx];
                let (centre, width) = if p.migration_freq > 0.0 {
                    let s = p.migration_freq;
                    let psi = s * TAU * z_e / p.fibre_pitch + r.theta_m;
                    let k = (psi / TAU).round();
                    (
                        (TAU * k - r.theta_m) * p.fibre_pitch / (TAU * s),
                        p.fibre_pitch / s,
                    )
                } else {
                    (z_e, p.fibre_pitch)
                };
                if r.loops
                    .iter()
                    .any(|l| (l.centre - centre).abs() < 0.999 * l.width)
                {
                    continue;
                }
                let peak = migr(r, centre).max(1e-6);
                let r_loop = redraw(
                    p.loop_r_max,
                    &mut rng,
                    |v| v / norm_loop > peak,
                    1.05 * peak * norm_loop,
                );
                let k = (r_loop / norm_loop) / peak;
                regs[idx].loops.push(LoopBump { centre, width, k });
                loop_count += 1;
                break;
            }
        }
        for r in &regs {
            let mut points = Vec::with_capacity(n_seg as usize + 1);
            for s in 0..=n_seg {
                let z = length * s as f32 / n_seg as f32;
                let mut rad = migr(r, z);
                for lb in &r.loops {
                    let d = z - lb.centre;
                    if d.abs() < 0.5 * lb.width {
                        rad *= 1.0 + (lb.k - 1.0) * 0.5 * (1.0 + (TAU * d / lb.width).cos());
                    }
                }
                let ang = r.theta_i + sf * TAU * z / p.fibre_pitch;
                let local = Vec2::new(rad * ang.cos() * p.ellipse_x, rad * ang.sin() * p.ellipse_y);
                let (ax, ay) = p.ply_axes(ply, z);
                let xy = p.ply_centre(ply, z) + local.x * ax + local.y * ay;
                points.push(Vec3::new(xy.x, xy.y, z));
            }
            fibres.push(Fibre {
                points,
                radius: p.fibre_radius,
                kind: if r.loops.is_empty() {
                    FibreKind::Regular
                } else {
                    FibreKind::Loop
                },
                ply,
                section_radius: r.r_i,
                section_angle: r.theta_i,
            });
        }
        // Hair-type flyaways (world units around the ply centre, co-rotating frame).
        for z0 in poisson_positions(&mut rng, p.hair_density, length) {
            let theta0 = TAU * rng.next_f32();
            let r0 = redraw(
                p.hair_r_min,
                &mut rng,
                |v| v >= 0.0,
                p.hair_r_min.mean.abs(),
            );
            let r_span = redraw(
                p.hair_r_span,
                &mut rng,
                |v| v > 0.0,
                p.hair_r_span.mean.abs(),
            );
            let th_span = p.hair_theta_span.sample(&mut rng);
            let z_span = p.hair_z_span.sample(&mut rng);
            let mut points = Vec::with_capacity(p.hair_segments as usize + 1);
            for k in 0..=p.hair_segments {
                let t = k as f32 / p.hair_segments as f32;
                let z = z0 + z_span * t;
                if !(0.0..=length).contains(&z) {
                    continue;
                }
                let rad = r0 + r_span * t;
                let th = theta0 + th_span * t;
                let (ax, ay) = p.ply_axes(ply, z);
                let xy = p.ply_centre(ply, z) + rad * th.cos() * ax + rad * th.sin() * ay;
                points.push(Vec3::new(xy.x, xy.y, z));
            }
            if points.len() >= 2 {
                hair_count += 1;
                hairs.push(Fibre {
                    points,
                    radius: p.fibre_radius,
                    kind: FibreKind::Hair,
                    ply,
                    section_radius: 0.0,
                    section_angle: 0.0,
                });
            }
        }
    }
    fibres.extend(hairs);
    Ok(Yarn {
        fibres,
        length,
        loop_count,
        hair_count,
    })
}

/// A frame of a [`Centreline`] at some arc length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CentrelineFrame {
    /// Point on the curve.
    pub position: Vec3,
    /// Unit tangent.
    pub tangent: Vec3,
    /// Unit normal of the rotation-minimising frame (the yarn's cross-section `x` axis).
    pub normal: Vec3,
    /// `tangent × normal` (the yarn's cross-section `y` axis).
    pub binormal: Vec3,
}

/// A polyline centreline with arc-length parameterisation and a rotation-minimising frame
/// computed by double reflection (Wang, Jüttler, Zheng, Liu 2008). Frenet frames are never
/// used: they flip at inflection points, which every weave crossing has.
#[derive(Clone, Debug)]
pub struct Centreline {
    points: Vec<Vec3>,
    arc: Vec<f32>,
    tangents: Vec<Vec3>,
    normals: Vec<Vec3>,
}

impl Centreline {
    /// Builds the centreline through `points` (at least two, consecutive points distinct).
    /// The initial normal is `up` projected perpendicular to the first tangent (any vector
    /// not parallel to it; for cloth, the cloth normal).
    pub fn new(points: Vec<Vec3>, up: Vec3) -> Result<Centreline, FabricError> {
        if points.len() < 2 {
            return Err(FabricError::InvalidCentreline {
                reason: format!("needs at least 2 points, got {}", points.len()),
            });
        }
        if !up.is_finite() {
            return Err(FabricError::InvalidCentreline {
                reason: format!("`up` = {up:?} is not finite"),
            });
        }
        if points.iter().any(|p| !p.is_finite()) {
            return Err(FabricError::InvalidCentreline {
                reason: "non-finite point".into(),
            });
        }
        let n = points.len();
        let mut arc = vec![0.0f32; n];
        for i in 1..n {
            let d = (points[i] - points[i - 1]).length();
            if d <= 0.0 {
                return Err(FabricError::InvalidCentreline {
                    reason: format!("points {} and {} coincide", i - 1, i),
                });
            }
            arc[i] = arc[i - 1] + d;
        }
        let tangents: Vec<Vec3> = (0..n)
            .map(|i| {
                let a = points[i.saturating_sub(1)];
                let b = points[(i + 1).min(n - 1)];
                (b - a).normalize()
            })
            .collect();
        let t0 = tangents[0];
        let mut r0 = up - up.dot(t0) * t0;
        if r0.length_squared() < 1e-12 {
            r0 = crate::math::Frame::from_normal(t0).s;
        }
        let mut normals = Vec::with_capacity(n);
        normals.push(r0.normalize());
        for i in 0..n - 1 {
            let v1 = points[i + 1] - points[i];
            let c1 = v1.dot(v1);
            let r = normals[i];
            let rl = r - (2.0 / c1) * v1.dot(r) * v1;
            let tl = tangents[i] - (2.0 / c1) * v1.dot(tangents[i]) * v1;
            let v2 = tangents[i + 1] - tl;
            let c2 = v2.dot(v2);
            let mut rn = if c2 > 1e-20 {
                rl - (2.0 / c2) * v2.dot(rl) * v2
            } else {
                rl
            };
            // Remove rounding drift: keep the normal exactly perpendicular and unit.
            rn -= rn.dot(tangents[i + 1]) * tangents[i + 1];
            normals.push(rn.normalize_or(normals[i]));
        }
        Ok(Centreline {
            points,
            arc,
            tangents,
            normals,
        })
    }

    /// Total arc length.
    #[must_use]
    pub fn length(&self) -> f32 {
        self.arc[self.arc.len() - 1]
    }

    /// The polyline's vertices.
    #[must_use]
    pub fn points(&self) -> &[Vec3] {
        &self.points
    }

    /// The frame at arc length `s` (clamped to `[0, length]`); position, tangent and normal
    /// are interpolated linearly between vertices and re-orthonormalised.
    #[must_use]
    pub fn frame_at(&self, s: f32) -> CentrelineFrame {
        let s = s.clamp(0.0, self.length());
        let i = self
            .arc
            .partition_point(|&a| a <= s)
            .clamp(1, self.arc.len() - 1)
            - 1;
        let seg = self.arc[i + 1] - self.arc[i];
        let u = ((s - self.arc[i]) / seg).clamp(0.0, 1.0);
        let position = self.points[i].lerp(self.points[i + 1], u);
        let tangent = self.tangents[i]
            .lerp(self.tangents[i + 1], u)
            .normalize_or(self.tangents[i]);
        let n = self.normals[i].lerp(self.normals[i + 1], u);
        let normal = (n - n.dot(tangent) * tangent).normalize_or(self.normals[i]);
        CentrelineFrame {
            position,
            tangent,
            normal,
            binormal: tangent.cross(normal),
        }
    }

    /// Maps a point of a straight yarn (`x, y` cross-section, `z` = arc length) onto the
    /// curve: `C(z) + x·N(z) + y·B(z)`.
    #[must_use]
    pub fn map_point(&self, p: Vec3) -> Vec3 {
        let f = self.frame_at(p.z);
        f.position + p.x * f.normal + p.y * f.binormal
    }
}

/// Generates a yarn of length `centreline.length()` and bends it onto `centreline`
/// (yarn `z` = arc length, so the twist is uniform in arc length; yarn `x, y` = the
/// rotation-minimising normal and binormal).
pub fn generate_yarn_on_centreline(
    params: &YarnParams,
    centreline: &Centreline,
    seed: u64,
) -> Result<Yarn, FabricError> {
    let mut yarn = generate_yarn(params, centreline.length(), seed)?;
    for f in &mut yarn.fibres {
        for p in &mut f.points {
            *p = centreline.map_point(*p);
        }
    }
    Ok(yarn)
}
