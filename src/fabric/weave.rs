//! Weave patterns, warp/weft centrelines and periodic fabric patches (docs/references.md §6.10–6.12;
//! course notes §3.4: plain, twill, basket and satin weaves, velvet, a flyaway control and
//! separate warp/weft albedo).
//!
//! Layout: warps (ends) run along `+y` at `x_j = (j + ½)·warp_spacing`; wefts (picks) run
//! along `+x` at `y_i = (i + ½)·weft_spacing`; the cloth normal is `+z` and the base weave is
//! centred on `z = 0`. A patch covers `[0, tile.x) × [0, tile.y)` and tiles periodically;
//! fibre vertices are *not* wrapped (fibres near the tile edges, hairs and pile tufts may
//! stick out by up to a yarn radius or pile height), so a voxeliser should wrap `x, y`
//! modulo the tile.

use super::yarn::{generate_yarn_on_centreline, Centreline, Fibre, FibreKind, YarnParams};
use super::{check_positive, check_range, invalid, FabricError};
use crate::math::{Aabb, Vec2, Vec3, PI};
use crate::sampling::{hash_words, Rng};
use crate::spectrum::Rgb;

/// Largest number of warp or weft yarns in a patch.
pub const MAX_YARNS_PER_DIRECTION: u32 = 4096;

/// Direction of a twill's diagonal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum TwillDirection {
    /// The float block shifts by +1 warp per weft (the matrices of docs/references.md §6.10).
    Z,
    /// The float block shifts by −1 warp per weft.
    S,
}

/// A weave pattern (docs/references.md §6.10). `W[i][j] = 1` ⇔ warp `j` is over weft `i`.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum WeavePattern {
    /// Plain (1/1) weave: `[1 0; 0 1]`.
    Plain,
    /// An `over/under` twill: warp `j` is over weft `i` iff `(j ∓ i) mod (over + under) <
    /// over`. `over, under >= 1`, `over + under >= 3` (2/1, 2/2, 3/1, ...).
    Twill {
        /// Wefts each warp floats over.
        over: u32,
        /// Wefts each warp passes under.
        under: u32,
        /// Diagonal direction.
        direction: TwillDirection,
    },
    /// Basket weave (hopsack) of `size × size` blocks (`size >= 2`; 2 gives the 4×4 matrix
    /// of docs/references.md §6.10).
    Basket {
        /// Block size in yarns, `>= 2`.
        size: u32,
    },
    /// An `harness`-end satin: warp-faced `W[i][j] = 0 ⇔ j ≡ step·i (mod harness)`;
    /// `weft_faced` takes the complement (sateen). `harness >= 5`; `step` coprime with
    /// `harness` and not 1 or `harness − 1`.
    Satin {
        /// Number of harnesses (pattern size), `>= 5`.
        harness: u32,
        /// The move number ("counter").
        step: u32,
        /// Sateen (weft-faced) instead of satin (warp-faced).
        weft_faced: bool,
    },
    /// Velvet: a plain base weave plus a cut pile (see [`PileParams`]; the default pile is
    /// used when [`WeaveParams::pile`] is `None`).
    Velvet,
    /// An explicit matrix: `rows[i][j]` = warp `j` over weft `i`.
    Custom {
        /// Rows (wefts) of equal length (warps).
        rows: Vec<Vec<bool>>,
    },
}

/// Names accepted by [`WeavePattern::from_name`].
pub const PATTERN_NAMES: &[&str] = &[
    "plain", "twill", "twill21", "twill22", "twill31", "basket", "satin", "sateen", "velvet",
];

fn gcd(a: u32, b: u32) -> u32 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

impl WeavePattern {
    /// A pattern by name: `plain`, `twill` (= `twill22`), `twill21`, `twill22`, `twill31`,
    /// `basket` (2×2), `satin` (5-harness, move 2), `sateen` (its complement), `velvet`.
    pub fn from_name(name: &str) -> Result<WeavePattern, FabricError> {
        let tw = |over, under| WeavePattern::Twill {
            over,
            under,
            direction: TwillDirection::Z,
        };
        Ok(match name.trim().to_ascii_lowercase().as_str() {
            "plain" => WeavePattern::Plain,
            "twill" | "twill22" => tw(2, 2),
            "twill21" => tw(2, 1),
            "twill31" => tw(3, 1),
            "basket" => WeavePattern::Basket { size: 2 },
            "satin" => WeavePattern::Satin {
                harness: 5,
                step: 2,
                weft_faced: false,
            },
            "sateen" => WeavePattern::Satin {
                harness: 5,
                step: 2,
                weft_faced: true,
            },
            "velvet" => WeavePattern::Velvet,
            _ => {
                return Err(FabricError::UnknownPattern {
                    name: name.to_string(),
                    allowed: PATTERN_NAMES.join(", "),
                })
            }
        })
    }

    /// A short name for messages.
    #[must_use]
    pub fn name(&self) -> String {
        match self {
            WeavePattern::Plain => "plain".into(),
            WeavePattern::Twill {
                over,
                under,
                direction,
            } => {
                format!("twill {over}/{under} {direction:?}")
            }
            WeavePattern::Basket { size } => format!("basket {size}x{size}"),
            WeavePattern::Satin {
                harness,
                step,
                weft_faced,
            } => {
                format!(
                    "{} {harness}/{step}",
                    if *weft_faced { "sateen" } else { "satin" }
                )
            }
            WeavePattern::Velvet => "velvet".into(),
            WeavePattern::Custom { .. } => "custom".into(),
        }
    }

    /// The pattern's matrix, checked: every row and column contains both 0 and 1.
    pub fn matrix(&self) -> Result<WeaveMatrix, FabricError> {
        let bad = |reason: String| FabricError::InvalidPattern {
            pattern: self.name(),
            reason,
        };
        let m = match self {
            WeavePattern::Plain | WeavePattern::Velvet => {
                WeaveMatrix::from_fn(2, 2, |i, j| (i + j) % 2 == 0)
            }
            WeavePattern::Twill {
                over,
                under,
                direction,
            } => {
                if *over == 0 || *under == 0 || over + under < 3 || over + under > 64 {
                    return Err(bad(format!(
                        "over = {over}, under = {under}: allowed over, under >= 1 and 3 <= over + under <= 64"
                    )));
                }
                let n = (over + under) as usize;
                WeaveMatrix::from_fn(n, n, |i, j| {
                    let d = match direction {
                        TwillDirection::Z => (j + n - i % n) % n,
                        TwillDirection::S => (j + i) % n,
                    };
                    d < *over as usize
                })
            }
            WeavePattern::Basket { size } => {
                if !(2..=32).contains(size) {
                    return Err(bad(format!("size = {size}: allowed 2..=32")));
                }
                let s = *size as usize;
                WeaveMatrix::from_fn(2 * s, 2 * s, |i, j| (i / s + j / s).is_multiple_of(2))
            }
            WeavePattern::Satin {
                harness,
                step,
                weft_faced,
            } => {
                let n = *harness;
                if !(5..=64).contains(&n) {
                    return Err(bad(format!("harness = {n}: allowed 5..=64")));
                }
                let ok = |s: u32| s > 1 && s < n - 1 && gcd(s, n) == 1;
                if !ok(*step) {
                    let allowed: Vec<String> = (2..n - 1)
                        .filter(|&s| ok(s))
                        .map(|s| s.to_string())
                        .collect();
                    return Err(bad(format!(
                        "step (move number) = {step} must be coprime with harness {n} and not 1 or {}: allowed {}",
                        n - 1,
                        allowed.join(", ")
                    )));
                }
                let nn = n as usize;
                WeaveMatrix::from_fn(nn, nn, |i, j| {
                    let down = j % nn == (*step as usize * i) % nn;
                    down == *weft_faced
                })
            }
            WeavePattern::Custom { rows } => {
                let r = rows.len();
                let c = rows.first().map_or(0, Vec::len);
                if !(2..=256).contains(&r) || !(2..=256).contains(&c) {
                    return Err(bad(format!(
                        "{r}×{c} matrix: allowed 2..=256 rows and columns"
                    )));
                }
                if let Some(i) = rows.iter().position(|row| row.len() != c) {
                    return Err(bad(format!(
                        "row {i} has {} entries, row 0 has {c}",
                        rows[i].len()
                    )));
                }
                WeaveMatrix::from_fn(r, c, |i, j| rows[i][j])
            }
        };
        m.check().map_err(bad)?;
        Ok(m)
    }
}

/// A periodic binary weave matrix: `get(i, j)` = warp `j` over weft `i`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WeaveMatrix {
    rows: usize,
    cols: usize,
    data: Vec<bool>,
}

impl WeaveMatrix {
    fn from_fn(rows: usize, cols: usize, f: impl Fn(usize, usize) -> bool) -> Self {
        let mut data = Vec::with_capacity(rows * cols);
        for i in 0..rows {
            for j in 0..cols {
                data.push(f(i, j));
            }
        }
        WeaveMatrix { rows, cols, data }
    }
    fn check(&self) -> Result<(), String> {
        for i in 0..self.rows {
            let ones = (0..self.cols)
                .filter(|&j| self.get(i as i64, j as i64))
                .count();
            if ones == 0 || ones == self.cols {
                return Err(format!(
                    "weft (row) {i} never interlaces: every row needs both 0 and 1"
                ));
            }
        }
        for j in 0..self.cols {
            let ones = (0..self.rows)
                .filter(|&i| self.get(i as i64, j as i64))
                .count();
            if ones == 0 || ones == self.rows {
                return Err(format!(
                    "warp (column) {j} never interlaces: every column needs both 0 and 1"
                ));
            }
        }
        Ok(())
    }
    /// Number of rows (wefts per repeat).
    #[must_use]
    pub fn rows(&self) -> usize {
        self.rows
    }
    /// Number of columns (warps per repeat).
    #[must_use]
    pub fn cols(&self) -> usize {
        self.cols
    }
    /// Warp `j` over weft `i` (indices taken modulo the pattern size; negative allowed).
    #[must_use]
    pub fn get(&self, i: i64, j: i64) -> bool {
        let r = i.rem_euclid(self.rows as i64) as usize;
        let c = j.rem_euclid(self.cols as i64) as usize;
        self.data[r * self.cols + c]
    }
    /// The matrix as rows of 0/1.
    #[must_use]
    pub fn to_rows(&self) -> Vec<Vec<u8>> {
        (0..self.rows)
            .map(|i| {
                (0..self.cols)
                    .map(|j| self.get(i as i64, j as i64) as u8)
                    .collect()
            })
            .collect()
    }
}

/// Velvet pile parameters (docs/references.md §6.12, an engineering model with no fitted values).
/// Lengths in the yarn's unit (cm for the presets), angles in radians.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PileParams {
    /// Mean pile height `H` above the weave mid-plane (length, `> 0`; default 0.2 cm).
    pub height: f32,
    /// Relative height variation: each fibre's length is `H·(1 + v·(2u − 1))`, `v ∈ [0, 0.9]`
    /// (default 0.15).
    pub height_variation: f32,
    /// Nap angle: common tilt of the pile from the cloth normal, `[0, π/2)` (default 0.26 ≈ 15°).
    pub nap_angle: f32,
    /// Azimuth of the nap direction in the cloth plane (radians from `+x`; default π/2, along
    /// the warp).
    pub nap_azimuth: f32,
    /// Standard deviation of the per-fibre random tilt around the nap direction, `[0, 1]`
    /// radians (default 0.12 ≈ 7°).
    pub jitter: f32,
    /// Quadratic sag towards the nap, as a fraction of the height, `[0, 1]` (default 0.1).
    pub bend: f32,
    /// Fibres per tuft leg, `1..=10000` (a V-tuft has two legs; default 40).
    pub fibres_per_leg: u32,
    /// Radius of a tuft leg's footprint (length, `> 0`; default 0.01 cm).
    pub tuft_radius: f32,
    /// Physical radius of a pile fibre (length, `> 0`; default 0.0006 cm).
    pub fibre_radius: f32,
    /// One tuft column every `every` warps, `1..=64` (default 1).
    pub every: u32,
    /// Polyline segments per pile fibre, `1..=64` (default 8).
    pub segments: u32,
    /// Albedo of the pile fibres (default: a mid grey).
    pub albedo: Rgb,
}

impl Default for PileParams {
    fn default() -> Self {
        PileParams {
            height: 0.2,
            height_variation: 0.15,
            nap_angle: 0.26,
            nap_azimuth: 0.5 * PI,
            jitter: 0.12,
            bend: 0.1,
            fibres_per_leg: 40,
            tuft_radius: 0.01,
            fibre_radius: 0.0006,
            every: 1,
            segments: 8,
            albedo: Rgb::splat(0.5),
        }
    }
}

impl PileParams {
    /// Checks every parameter (names in errors are prefixed with `pile.`).
    pub fn validate(&self) -> Result<(), FabricError> {
        check_positive("pile.height", self.height, 1.0e6)?;
        check_range("pile.height_variation", self.height_variation, 0.0, 0.9)?;
        check_range("pile.nap_angle", self.nap_angle, 0.0, 0.5 * PI - 1e-3)?;
        check_range("pile.nap_azimuth", self.nap_azimuth, -4.0 * PI, 4.0 * PI)?;
        check_range("pile.jitter", self.jitter, 0.0, 1.0)?;
        check_range("pile.bend", self.bend, 0.0, 1.0)?;
        if !(1..=10_000).contains(&self.fibres_per_leg) {
            return Err(invalid(
                "pile.fibres_per_leg",
                self.fibres_per_leg,
                "1..=10000",
            ));
        }
        check_positive("pile.tuft_radius", self.tuft_radius, 1.0e6)?;
        check_positive("pile.fibre_radius", self.fibre_radius, 1.0e6)?;
        if !(1..=64).contains(&self.every) {
            return Err(invalid("pile.every", self.every, "1..=64"));
        }
        if !(1..=64).contains(&self.segments) {
            return Err(invalid("pile.segments", self.segments, "1..=64"));
        }
        check_albedo("pile.albedo", self.albedo)
    }
}

fn check_albedo(name: &str, a: Rgb) -> Result<(), FabricError> {
    if a.0.iter().all(|c| c.is_finite() && (0.0..=1.0).contains(c)) {
        Ok(())
    } else {
        Err(invalid(
            name,
            format!("{:?}", a.0),
            "each channel in [0, 1]",
        ))
    }
}

/// Parameters of a woven patch.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WeaveParams {
    /// The weave pattern.
    pub pattern: WeavePattern,
    /// Yarn of the warps (running along `y`).
    pub warp_yarn: YarnParams,
    /// Yarn of the wefts (running along `x`).
    pub weft_yarn: YarnParams,
    /// `p_x`, distance between neighbouring warps (length, `> 0`).
    pub warp_spacing: f32,
    /// `p_y`, distance between neighbouring wefts (length, `> 0`).
    pub weft_spacing: f32,
    /// `h_w`, height of a warp centreline above (or below) the mid-plane at a crossing
    /// (length, `>= 0`).
    pub warp_height: f32,
    /// `h_f`, height of a weft centreline at a crossing (length, `>= 0`). Validation
    /// requires `h_w + h_f >= r_w + r_f` (the envelope radii of the two yarns), i.e.
    /// `(t_w + t_f)/2` with thicknesses `t = 2r` (docs/references.md §6.11).
    pub weft_height: f32,
    /// Flyaway control (course notes §3.4), in `[0, 100]`: multiplies both flyaway densities
    /// (`hair_density`, `loop_density`) of both yarns. 1 = as fitted (100 %), 0 = none.
    pub flyaway_fraction: f32,
    /// Albedo of warp fibres (each channel in `[0, 1]`).
    pub warp_albedo: Rgb,
    /// Albedo of weft fibres (each channel in `[0, 1]`).
    pub weft_albedo: Rgb,
    /// Pattern repeats along `x` (warps) and `y` (wefts), each `>= 1`.
    pub repeats: [u32; 2],
    /// Centreline vertices per crossing interval, `4..=256` (default 16).
    pub samples_per_crossing: u32,
    /// Adjust each yarn's fibre pitch, ply pitch and migration frequency so that a whole
    /// number of turns/cycles fits its centreline (then regular fibres join up across the
    /// tile; flyaways still do not). Default true.
    pub snap_pitches: bool,
    /// Velvet pile; `None` = no pile, except for [`WeavePattern::Velvet`], which uses
    /// [`PileParams::default`].
    pub pile: Option<PileParams>,
}

impl WeaveParams {
    /// Defaults around one yarn used for warp and weft: spacing `2r/0.9` (yarn width 90 % of
    /// the spacing), crossing heights `h_w = h_f = r` (yarns just touch), `r` =
    /// [`YarnParams::envelope_radius`]; flyaway fraction 1, warp albedo 0.8 grey, weft albedo
    /// 0.6 grey, 2×2 repeats, 16 samples per crossing, pitches snapped.
    #[must_use]
    pub fn new(pattern: WeavePattern, yarn: YarnParams) -> Self {
        let r = yarn.envelope_radius();
        WeaveParams {
            pattern,
            warp_yarn: yarn.clone(),
            weft_yarn: yarn,
            warp_spacing: 2.0 * r / 0.9,
            weft_spacing: 2.0 * r / 0.9,
            warp_height: r,
            weft_height: r,
            flyaway_fraction: 1.0,
            warp_albedo: Rgb::splat(0.8),
            weft_albedo: Rgb::splat(0.6),
            repeats: [2, 2],
            samples_per_crossing: 16,
            snap_pitches: true,
            pile: None,
        }
    }

    /// [`WeaveParams::new`] with separate warp and weft yarns (what `velour weave` and
    /// `fabric` interiors use): spacings `2r_w/0.9` and `2r_f/0.9`, crossing heights
    /// `h_w = h_f = (r_w + r_f)/2` with the envelope radii `r_w`, `r_f` of the two yarns. The
    /// same as [`WeaveParams::new`] when the yarns are equal.
    #[must_use]
    pub fn with_yarns(pattern: WeavePattern, warp: YarnParams, weft: YarnParams) -> Self {
        let (rw, rf) = (warp.envelope_radius(), weft.envelope_radius());
        let mut p = WeaveParams::new(pattern, warp);
        p.weft_yarn = weft;
        p.warp_spacing = 2.0 * rw / 0.9;
        p.weft_spacing = 2.0 * rf / 0.9;
        p.warp_height = 0.5 * (rw + rf);
        p.weft_height = 0.5 * (rw + rf);
        p
    }

    /// Minimum `h_w + h_f` for warp and weft not to interpenetrate at crossings: the sum of
    /// the two yarns' envelope radii.
    #[must_use]
    pub fn required_clearance(&self) -> f32 {
        self.warp_yarn.envelope_radius() + self.weft_yarn.envelope_radius()
    }

    /// The active pile, if any.
    #[must_use]
    pub fn active_pile(&self) -> Option<PileParams> {
        match (&self.pile, &self.pattern) {
            (Some(p), _) => Some(p.clone()),
            (None, WeavePattern::Velvet) => Some(PileParams::default()),
            _ => None,
        }
    }

    /// Checks every parameter, the pattern and both yarns (yarn errors are prefixed with
    /// `warp_yarn.` / `weft_yarn.`).
    pub fn validate(&self) -> Result<(), FabricError> {
        let prefix = |p: &str, e: FabricError| match e {
            FabricError::InvalidParameter {
                name,
                value,
                allowed,
            } => FabricError::InvalidParameter {
                name: format!("{p}.{name}"),
                value,
                allowed,
            },
            FabricError::TooLarge {
                name,
                what,
                count,
                limit,
            } => FabricError::TooLarge {
                name: format!("{p}.{name}"),
                what,
                count,
                limit,
            },
            other => other,
        };
        self.warp_yarn
            .validate()
            .map_err(|e| prefix("warp_yarn", e))?;
        self.weft_yarn
            .validate()
            .map_err(|e| prefix("weft_yarn", e))?;
        self.pattern.matrix()?;
        check_positive("warp_spacing", self.warp_spacing, 1.0e6)?;
        check_positive("weft_spacing", self.weft_spacing, 1.0e6)?;
        check_range("warp_height", self.warp_height, 0.0, 1.0e6)?;
        check_range("weft_height", self.weft_height, 0.0, 1.0e6)?;
        let need = self.required_clearance();
        if self.warp_height + self.weft_height < need * (1.0 - 1e-5) {
            return Err(invalid(
                "warp_height + weft_height",
                self.warp_height + self.weft_height,
                &format!(">= {need} (sum of the yarns' envelope radii, so warp and weft do not interpenetrate)"),
            ));
        }
        check_range("flyaway_fraction", self.flyaway_fraction, 0.0, 100.0)?;
        check_albedo("warp_albedo", self.warp_albedo)?;
        check_albedo("weft_albedo", self.weft_albedo)?;
        for (k, &r) in self.repeats.iter().enumerate() {
            if r == 0 || r > 1024 {
                return Err(invalid(&format!("repeats[{k}]"), r, "1..=1024"));
            }
        }
        let m = self.pattern.matrix()?;
        let warps = m.cols() as u64 * self.repeats[0] as u64;
        let wefts = m.rows() as u64 * self.repeats[1] as u64;
        for (name, n) in [("repeats[0]", warps), ("repeats[1]", wefts)] {
            if n > MAX_YARNS_PER_DIRECTION as u64 {
                return Err(FabricError::TooLarge {
                    name: name.into(),
                    what: "yarns in one direction".into(),
                    count: n,
                    limit: MAX_YARNS_PER_DIRECTION as u64,
                });
            }
        }
        if !(4..=256).contains(&self.samples_per_crossing) {
            return Err(invalid(
                "samples_per_crossing",
                self.samples_per_crossing,
                "4..=256",
            ));
        }
        if let Some(p) = self.active_pile() {
            p.validate()?;
        }
        Ok(())
    }

    /// The weave matrix (velvet: its plain base).
    pub fn matrix(&self) -> Result<WeaveMatrix, FabricError> {
        self.pattern.matrix()
    }

    /// Periodic tile size `(cols·repeats[0]·p_x, rows·repeats[1]·p_y)`.
    pub fn tile_size(&self) -> Result<Vec2, FabricError> {
        let m = self.matrix()?;
        Ok(Vec2::new(
            (m.cols() as u32 * self.repeats[0]) as f32 * self.warp_spacing,
            (m.rows() as u32 * self.repeats[1]) as f32 * self.weft_spacing,
        ))
    }

    /// Height of warp `j`'s centreline at `y` (docs/references.md §6.11): `±h_w` at the crossings
    /// `y_i = (i + ½)p_y` (`+` where the warp is over), cosine ease in between. Periodic.
    #[must_use]
    pub fn warp_height_at(&self, m: &WeaveMatrix, j: i64, y: f32) -> f32 {
        let zk = |i: i64| {
            if m.get(i, j) {
                self.warp_height
            } else {
                -self.warp_height
            }
        };
        ease(y / self.weft_spacing - 0.5, zk)
    }

    /// Height of weft `i`'s centreline at `x`: `∓h_f` at the crossings `x_j = (j + ½)p_x`
    /// (`−` where the warp is over), cosine ease in between. Periodic.
    #[must_use]
    pub fn weft_height_at(&self, m: &WeaveMatrix, i: i64, x: f32) -> f32 {
        let zk = |j: i64| {
            if m.get(i, j) {
                -self.weft_height
            } else {
                self.weft_height
            }
        };
        ease(x / self.warp_spacing - 0.5, zk)
    }

    /// The centreline of warp `j` over the tile: from `(x_j, 0)` to `(x_j, tile.y)`.
    pub fn warp_centreline(&self, m: &WeaveMatrix, j: u32) -> Result<Centreline, FabricError> {
        let wefts = m.rows() as u32 * self.repeats[1];
        let n = wefts * self.samples_per_crossing;
        let x = (j as f32 + 0.5) * self.warp_spacing;
        let len = wefts as f32 * self.weft_spacing;
        let pts = (0..=n)
            .map(|k| {
                let y = len * k as f32 / n as f32;
                Vec3::new(x, y, self.warp_height_at(m, j as i64, y))
            })
            .collect();
        Centreline::new(pts, Vec3::Z)
    }

    /// The centreline of weft `i` over the tile: from `(0, y_i)` to `(tile.x, y_i)`.
    pub fn weft_centreline(&self, m: &WeaveMatrix, i: u32) -> Result<Centreline, FabricError> {
        let warps = m.cols() as u32 * self.repeats[0];
        let n = warps * self.samples_per_crossing;
        let y = (i as f32 + 0.5) * self.weft_spacing;
        let len = warps as f32 * self.warp_spacing;
        let pts = (0..=n)
            .map(|k| {
                let x = len * k as f32 / n as f32;
                Vec3::new(x, y, self.weft_height_at(m, i as i64, x))
            })
            .collect();
        Centreline::new(pts, Vec3::Z)
    }
}

/// Cosine ease through values `zk(k)` at integer `t = k`.
fn ease(t: f32, zk: impl Fn(i64) -> f32) -> f32 {
    let k = t.floor();
    let u = t - k;
    let (a, b) = (zk(k as i64), zk(k as i64 + 1));
    a + (b - a) * 0.5 * (1.0 - (PI * u).cos())
}

/// Which yarn a fibre belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum YarnId {
    /// Warp number `j` (along `y`, at `x = (j + ½)p_x`).
    Warp(u32),
    /// Weft number `i` (along `x`, at `y = (i + ½)p_y`).
    Weft(u32),
    /// A velvet pile fibre.
    Pile,
}

/// A fibre and the yarn it belongs to.
#[derive(Clone, Debug, PartialEq)]
pub struct PatchFibre {
    /// Which yarn.
    pub yarn: YarnId,
    /// The fibre.
    pub fibre: Fibre,
}

/// A generated periodic fabric patch.
#[derive(Clone, Debug)]
pub struct FabricPatch {
    /// Every fibre, tagged with its yarn.
    pub fibres: Vec<PatchFibre>,
    /// Periodic tile size in `x, y` (length); the patch repeats with this period.
    pub tile: Vec2,
    /// Bounding box of every fibre vertex (the `z` extent of the cloth; `x, y` may exceed the
    /// tile slightly, see the module docs).
    pub bounds: Aabb,
    /// Analytic fibre volume `Σ π r² · |segment|` over every polyline segment (length³), the
    /// number a voxelisation must reproduce.
    pub fibre_volume: f64,
    /// The weave matrix used.
    pub matrix: WeaveMatrix,
    /// Number of warps in the tile.
    pub warp_count: u32,
    /// Number of wefts in the tile.
    pub weft_count: u32,
    /// Albedo of warp fibres.
    pub warp_albedo: Rgb,
    /// Albedo of weft fibres.
    pub weft_albedo: Rgb,
    /// Albedo of pile fibres (black when there is no pile).
    pub pile_albedo: Rgb,
    /// Loop-type flyaways over all yarns.
    pub loop_count: usize,
    /// Hair-type flyaways over all yarns.
    pub hair_count: usize,
}

impl FabricPatch {
    /// Writes the fibres as Wavefront OBJ polylines (`v` and `l` records), one group per
    /// yarn (`g warp_3`, `g weft_0`, `g pile`), for inspection in any 3D viewer. Units are the
    /// patch's (cm for the presets).
    pub fn write_obj(&self, out: &mut impl std::io::Write) -> Result<(), FabricError> {
        let io = |e: std::io::Error| FabricError::Io {
            what: "OBJ fibre export".into(),
            reason: e.to_string(),
        };
        writeln!(
            out,
            "# velour fabric patch: {} fibres, tile {} x {}, fibre volume {:e}",
            self.fibres.len(),
            self.tile.x,
            self.tile.y,
            self.fibre_volume
        )
        .map_err(io)?;
        let mut base = 1usize;
        let mut group: Option<YarnId> = None;
        for f in &self.fibres {
            if group != Some(f.yarn) {
                let name = match f.yarn {
                    YarnId::Warp(j) => format!("warp_{j}"),
                    YarnId::Weft(i) => format!("weft_{i}"),
                    YarnId::Pile => "pile".to_string(),
                };
                writeln!(out, "g {name}").map_err(io)?;
                group = Some(f.yarn);
            }
            for q in &f.fibre.points {
                writeln!(out, "v {} {} {}", q.x, q.y, q.z).map_err(io)?;
            }
            let n = f.fibre.points.len();
            let idx: Vec<String> = (base..base + n).map(|k| k.to_string()).collect();
            writeln!(out, "l {}", idx.join(" ")).map_err(io)?;
            base += n;
        }
        Ok(())
    }

    /// Albedo of the fibres of a yarn (warp and weft take their own, course notes §3.4).
    #[must_use]
    pub fn albedo(&self, id: YarnId) -> Rgb {
        match id {
            YarnId::Warp(_) => self.warp_albedo,
            YarnId::Weft(_) => self.weft_albedo,
            YarnId::Pile => self.pile_albedo,
        }
    }
}

/// Snaps a yarn's pitches so a whole number of turns fits `len`.
fn snap(y: &YarnParams, len: f32) -> YarnParams {
    let whole = |pitch: f32| len / (len / pitch).round().max(1.0);
    let alpha = whole(y.fibre_pitch);
    let s = if y.migration_freq > 0.0 {
        let cycles = (len * y.migration_freq / alpha).round().max(1.0);
        cycles * alpha / len
    } else {
        0.0
    };
    YarnParams {
        fibre_pitch: alpha,
        ply_pitch: whole(y.ply_pitch),
        migration_freq: s,
        ..y.clone()
    }
}

/// Generates a periodic woven patch: warp and weft yarns on their centrelines (each yarn
/// seeded from `seed` and its id), plus velvet pile tufts when a pile is active.
///
/// Velvet (docs/references.md §6.12): one V-tuft per weft and per `pile.every`-th warp gap, anchored
/// at `((j + 1)p_x, y_i)` with its two legs at `y_i ± r_f` (either side of the binding weft).
/// Each leg has `fibres_per_leg` fibres starting at `z = 0` inside a disc of radius
/// `tuft_radius`; a fibre of length `H(1 + v(2u − 1))` leaves along the cloth normal tilted by
/// the nap angle towards the nap azimuth plus a Gaussian tilt of standard deviation `jitter`,
/// and sags quadratically by `bend·H` towards the nap.
pub fn generate_patch(params: &WeaveParams, seed: u64) -> Result<FabricPatch, FabricError> {
    params.validate()?;
    let m = params.matrix()?;
    let warps = m.cols() as u32 * params.repeats[0];
    let wefts = m.rows() as u32 * params.repeats[1];
    let warp_yarn = params
        .warp_yarn
        .with_flyaway_scale(params.flyaway_fraction)?;
    let weft_yarn = params
        .weft_yarn
        .with_flyaway_scale(params.flyaway_fraction)?;
    // Memory estimate before generating anything.
    let tile = params.tile_size()?;
    let est = |y: &YarnParams, count: u32, len: f32| {
        let segs = (1.2 * len / y.segment_length).ceil() as u64 + 1;
        count as u64 * y.ply_count as u64 * y.fibres_per_ply as u64 * segs
    };
    let total = est(&warp_yarn, warps, tile.y) + est(&weft_yarn, wefts, tile.x);
    if total > super::yarn::MAX_VERTICES {
        return Err(FabricError::TooLarge {
            name: "repeats / fibres_per_ply / segment_length".into(),
            what: "polyline vertices".into(),
            count: total,
            limit: super::yarn::MAX_VERTICES,
        });
    }
    let mut fibres = Vec::new();
    let (mut loop_count, mut hair_count) = (0, 0);
    for j in 0..warps {
        let c = params.warp_centreline(&m, j)?;
        let y = if params.snap_pitches {
            snap(&warp_yarn, c.length())
        } else {
            warp_yarn.clone()
        };
        let yarn = generate_yarn_on_centreline(&y, &c, hash_words(&[seed, 1, j as u64]))?;
        loop_count += yarn.loop_count;
        hair_count += yarn.hair_count;
        fibres.extend(yarn.fibres.into_iter().map(|f| PatchFibre {
            yarn: YarnId::Warp(j),
            fibre: f,
        }));
    }
    for i in 0..wefts {
        let c = params.weft_centreline(&m, i)?;
        let y = if params.snap_pitches {
            snap(&weft_yarn, c.length())
        } else {
            weft_yarn.clone()
        };
        let yarn = generate_yarn_on_centreline(&y, &c, hash_words(&[seed, 2, i as u64]))?;
        loop_count += yarn.loop_count;
        hair_count += yarn.hair_count;
        fibres.extend(yarn.fibres.into_iter().map(|f| PatchFibre {
            yarn: YarnId::Weft(i),
            fibre: f,
        }));
    }
    let pile = params.active_pile();
    if let Some(p) = &pile {
        let mut rng = Rng::new(hash_words(&[seed, 3]), 0x70696c65);
        let leg_offset = params.weft_yarn.envelope_radius();
        let nap = Vec3::new(p.nap_azimuth.cos(), p.nap_azimuth.sin(), 0.0);
        let columns: Vec<u32> = (0..warps).filter(|j| j % p.every == 0).collect();
        let legs = wefts as u64 * columns.len() as u64 * 2 * p.fibres_per_leg as u64;
        if legs * (p.segments as u64 + 1) > super::yarn::MAX_VERTICES {
            return Err(FabricError::TooLarge {
                name: "pile.fibres_per_leg".into(),
                what: "pile vertices".into(),
                count: legs * (p.segments as u64 + 1),
                limit: super::yarn::MAX_VERTICES,
            });
        }
        for i in 0..wefts {
            for &j in &columns {
                let anchor = Vec2::new(
                    (j + 1) as f32 * params.warp_spacing,
                    (i as f32 + 0.5) * params.weft_spacing,
                );
                for side in [-1.0f32, 1.0] {
                    let leg = anchor + Vec2::new(0.0, side * leg_offset);
                    for _ in 0..p.fibres_per_leg {
                        fibres.push(PatchFibre {
                            yarn: YarnId::Pile,
                            fibre: pile_fibre(p, leg, nap, &mut rng),
                        });
                    }
                }
            }
        }
    }
    let mut bounds = Aabb::EMPTY;
    let mut fibre_volume = 0.0f64;
    for f in &fibres {
        fibre_volume += f.fibre.volume();
        for &q in &f.fibre.points {
            bounds = bounds.union_point(q);
        }
    }
    Ok(FabricPatch {
        fibres,
        tile,
        bounds,
        fibre_volume,
        matrix: m,
        warp_count: warps,
        weft_count: wefts,
        warp_albedo: params.warp_albedo,
        weft_albedo: params.weft_albedo,
        pile_albedo: pile.as_ref().map_or(Rgb::ZERO, |p| p.albedo),
        loop_count,
        hair_count,
    })
}

fn pile_fibre(p: &PileParams, leg: Vec2, nap: Vec3, rng: &mut Rng) -> Fibre {
    let d = crate::sampling::sample_uniform_disk_concentric(rng.next_2d()) * p.tuft_radius;
    let base = Vec3::new(leg.x + d.x, leg.y + d.y, 0.0);
    let len = p.height * (1.0 + p.height_variation * (2.0 * rng.next_f32() - 1.0));
    // Common nap tilt, then a Gaussian tilt in a random azimuth.
    let tilted = (Vec3::Z * p.nap_angle.cos() + nap * p.nap_angle.sin()).normalize();
    let jitter = (p.jitter * super::yarn::standard_normal(rng))
        .abs()
        .min(0.5 * PI);
    let frame = crate::math::Frame::from_normal(tilted);
    let az = 2.0 * PI * rng.next_f32();
    let dir = frame.to_world(Vec3::new(
        jitter.sin() * az.cos(),
        jitter.sin() * az.sin(),
        jitter.cos(),
    ));
    let points = (0..=p.segments)
        .map(|k| {
            let t = k as f32 / p.segments as f32;
            base + dir * (len * t) + nap * (p.bend * len * t * t)
        })
        .collect();
    Fibre {
        points,
        radius: p.fibre_radius,
        kind: FibreKind::Pile,
        ply: 0,
        section_radius: 0.0,
        section_angle: 0.0,
    }
}

/// One fibre phase function per yarn family, so warp, weft and pile fibres scatter with their
/// own albedo (course notes §3.4, "separate warp and weft scattering properties").
#[derive(Clone, Debug, PartialEq)]
pub struct FabricShading {
    /// Phase function of warp fibres.
    pub warp: super::FibrePhase,
    /// Phase function of weft fibres.
    pub weft: super::FibrePhase,
    /// Phase function of pile fibres.
    pub pile: super::FibrePhase,
}

impl FabricShading {
    /// Builds the three phase functions from shared fibre parameters and the patch's albedos
    /// (each through [`super::FibrePhaseParams::with_colour`]; a black albedo, e.g. the pile
    /// of a patch without pile, becomes the darkest allowed colour).
    pub fn from_patch(
        base: &super::FibrePhaseParams,
        patch: &FabricPatch,
    ) -> Result<FabricShading, FabricError> {
        Self::from_albedos(
            base,
            [patch.warp_albedo, patch.weft_albedo, patch.pile_albedo],
        )
    }

    /// [`FabricShading::from_patch`] from the warp, weft and pile albedos.
    pub fn from_albedos(
        base: &super::FibrePhaseParams,
        albedos: [Rgb; 3],
    ) -> Result<FabricShading, FabricError> {
        let make = |c: Rgb| super::FibrePhase::new(base.clone().with_colour(c));
        Ok(FabricShading {
            warp: make(albedos[0])?,
            weft: make(albedos[1])?,
            pile: make(albedos[2])?,
        })
    }

    /// The phase function of a yarn.
    #[must_use]
    pub fn for_yarn(&self, id: YarnId) -> &super::FibrePhase {
        match id {
            YarnId::Warp(_) => &self.warp,
            YarnId::Weft(_) => &self.weft,
            YarnId::Pile => &self.pile,
        }
    }
}
