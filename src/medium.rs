//! Interiors: the participating media inside objects, and the conversion of the artist's
//! parameters into optical coefficients.
//!
//! Artist parameters follow the course notes §2.4.2 (eq. 1–3): `attenuation` is a distance per
//! RGB channel (σ_t = density / attenuation), `albedo` is the colour the artist wants the
//! medium to be. By default the albedo is read as the *multiple-scattering* albedo and inverted
//! to the single-scattering albedo with the van de Hulst relation as used by Chiang, Kutz and
//! Burley 2016 / Wrenninge et al. 2017 (REFERENCES §1.3–1.4), which contains the similarity
//! relation for anisotropic phase functions. `albedo_mode = "single"` uses the albedo as σ_s/σ_t.

use crate::grid::SparseGrid;
use crate::majorant::{MajorantMode, MajorantPyramid, RayDensity};
use crate::math::Ray;
use crate::phase::PhaseFunction;
use crate::spectrum::Rgb;
use crate::tracking::{DensityCoefficients, MajorantSegment, TransmittanceMode};
use crate::volume::{FbmField, LazyFbmGrid};

/// How the artist's albedo maps to the single-scattering albedo σ_s/σ_t.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AlbedoMode {
    /// The albedo is the multiple-scattering (diffuse-illumination) albedo of a semi-infinite
    /// medium: inverted with van de Hulst's relation (REFERENCES §1.3).
    MultipleScattering,
    /// The albedo is the single-scattering albedo σ_s/σ_t itself.
    SingleScattering,
}

/// Where next event estimation happens for paths inside an interior (notes §2.3.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NeeStrategy {
    /// Only at boundary vertices, through the (rough) boundary BSDF: for dense media (skin).
    ExitPoint,
    /// At every interior scattering vertex, with transparent shadows through the boundaries:
    /// for less dense media (liquids). Biased where the boundary refracts (notes §2.3.3).
    Interior,
}

/// The largest single-scattering albedo velour uses (REFERENCES §8: albedo → 1 makes walks of
/// ~1/(1−α) events; the clamp keeps them finite).
pub const MAX_SINGLE_SCATTERING_ALBEDO: f32 = 0.999_999;

/// van de Hulst's inversion: the single-scattering albedo of a semi-infinite index-matched
/// medium whose diffuse-illumination albedo is `a`, for mean cosine `g`
/// (REFERENCES §1.3: s(A) = 4.09712 + 4.20863 A − sqrt(9.59217 + 41.6808 A + 17.7126 A²),
/// α = (1 − s²)/(1 − g s²)).
#[must_use]
pub fn single_scattering_albedo_from_multiple(a: f32, g: f32) -> f32 {
    let a = a.clamp(0.0, 1.0) as f64;
    let g = g.clamp(-0.999, 0.999) as f64;
    let s = 4.09712 + 4.20863 * a - (9.59217 + 41.6808 * a + 17.7126 * a * a).sqrt();
    let s2 = s * s;
    let alpha = (1.0 - s2) / (1.0 - g * s2);
    (alpha as f32).clamp(0.0, MAX_SINGLE_SCATTERING_ALBEDO)
}

/// van de Hulst's forward relation A(α, g) = (1 − s)(1 − 0.139 s)/(1 + 1.17 s),
/// s = sqrt((1 − α)/(1 − g α)): the multiple-scattering albedo of a medium.
#[must_use]
pub fn multiple_scattering_albedo(alpha: f32, g: f32) -> f32 {
    let alpha = alpha.clamp(0.0, 1.0) as f64;
    let g = g.clamp(-0.999, 0.999) as f64;
    let s = ((1.0 - alpha) / (1.0 - g * alpha)).max(0.0).sqrt();
    ((1.0 - s) * (1.0 - 0.139 * s) / (1.0 + 1.17 * s)) as f32
}

/// Optical coefficients of a homogeneous region, per unit world length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coefficients {
    /// Absorption coefficient σ_a (1/length).
    pub sigma_a: Rgb,
    /// Scattering coefficient σ_s (1/length).
    pub sigma_s: Rgb,
}

impl Coefficients {
    /// Extinction σ_t = σ_a + σ_s.
    #[must_use]
    pub fn sigma_t(&self) -> Rgb {
        self.sigma_a + self.sigma_s
    }

    /// Coefficients from the artist's parameters (notes eq. 1–3 with a density multiplier):
    /// σ_t = density / attenuation, σ_s = α σ_t, σ_a = σ_t − σ_s, where α is `albedo` itself or
    /// its van de Hulst inversion (see [`AlbedoMode`]).
    #[must_use]
    pub fn from_artist(
        albedo: Rgb,
        attenuation: Rgb,
        density: f32,
        mode: AlbedoMode,
        g: f32,
    ) -> Self {
        let sigma_t = attenuation.map(|d| if d.is_infinite() { 0.0 } else { density / d });
        let alpha = match mode {
            AlbedoMode::MultipleScattering => {
                albedo.map(|a| single_scattering_albedo_from_multiple(a, g))
            }
            AlbedoMode::SingleScattering => {
                albedo.map(|a| a.clamp(0.0, MAX_SINGLE_SCATTERING_ALBEDO))
            }
        };
        let sigma_s = sigma_t * alpha;
        Coefficients {
            sigma_a: (sigma_t - sigma_s).clamp_zero(),
            sigma_s,
        }
    }
}

/// A homogeneous scattering medium.
#[derive(Clone, Debug)]
pub struct HomogeneousMedium {
    /// Optical coefficients.
    pub coefficients: Coefficients,
    /// Phase function.
    pub phase: PhaseFunction,
}

/// How free-flight distances are sampled in a heterogeneous interior.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FreeFlightMethod {
    /// Delta (Woodcock) tracking over the majorant segments: unbiased.
    DeltaTracking,
    /// Fixed-step ray marching: biased, the notes' §2.2.2 baseline.
    RayMarching {
        /// Step length, world units.
        step: f32,
    },
}

/// The estimator choices of a heterogeneous interior (speed/accuracy trade; REFERENCES §4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackingConfig {
    /// Free-flight sampling.
    pub free_flight: FreeFlightMethod,
    /// Transmittance estimation for shadow rays.
    pub transmittance: TransmittanceMode,
    /// Which majorants drive both.
    pub majorant: MajorantMode,
}

impl Default for TrackingConfig {
    /// Delta tracking, residual ratio tracking with Novák's control, hierarchical majorants
    /// down to the brick level.
    fn default() -> Self {
        TrackingConfig {
            free_flight: FreeFlightMethod::DeltaTracking,
            transmittance: TransmittanceMode::ResidualRatio(crate::tracking::ControlVariate::Novak),
            majorant: MajorantMode::Hierarchical { finest: 0 },
        }
    }
}

/// Where a heterogeneous interior's density comes from.
#[derive(Clone, Debug)]
pub enum DensityField {
    /// A grid channel (an OpenVDB grid, a baked procedural, a voxelised weave).
    Grid {
        /// The grid (its index-to-world map places it in the scene).
        grid: SparseGrid,
        /// The density channel.
        channel: usize,
    },
    /// Procedural fBm evaluated directly (exact, slow).
    Procedural(Box<FbmField>),
    /// Procedural fBm baked lazily into bricks where lookups go.
    LazyBaked(Box<LazyFbmGrid>),
    /// A voxelised weave patch tiled over a mesh shell (notes §3.3).
    Shell(Box<crate::fabric::FabricShell>),
}

/// A heterogeneous interior: σ_t(x) = d(x)·σ_t⁰ and σ_s(x) = d(x)·σ_s⁰ with the density d(x)
/// from a [`DensityField`] (the notes' "voxelised" and "heterogeneous scattering" interiors).
#[derive(Clone, Debug)]
pub struct HeterogeneousMedium {
    /// The density.
    pub field: DensityField,
    /// Majorant bounds of the density.
    pub pyramid: MajorantPyramid,
    /// Coefficients per unit density.
    pub coefficients: DensityCoefficients,
    /// Phase function.
    pub phase: PhaseFunction,
    /// Estimator choices.
    pub tracking: TrackingConfig,
    /// Fibre shading of a voxelised fabric (tangent and yarn-id channels of the grid), if any.
    pub fabric: Option<Box<FabricLook>>,
}

/// How the extinction of a fibre medium depends on the direction of travel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FibreExtinction {
    /// The same in every direction: σ_t = d·σ_t⁰ with the fibre volume fraction d.
    Isotropic,
    /// The projected width of aligned cylinders (REFERENCES §7.3): σ_t(ω) = d·σ_t⁰·sin∠(ω, t),
    /// so light travelling along the fibres passes. The scene scales σ_t⁰ by 4/π so that the
    /// extinction averaged over directions equals the isotropic one at the same attenuation.
    Projected,
}

/// How a voxelised weave patch scatters (course notes §3.2): the fibre phase function of the
/// yarn family stored in the `id` channel, around the averaged fibre tangent of the `tangent`
/// channel, with isotropic or fibre-projected extinction ([`FibreExtinction`]). The channels
/// are those of the grid (a free-standing patch) or of the shell's patch.
#[derive(Clone, Debug)]
pub struct FabricLook {
    /// Grid channel of the averaged tangent (Vec3).
    pub tangent_channel: usize,
    /// Grid channel of the yarn id (0 warp, 1 weft, 2 pile).
    pub id_channel: usize,
    /// Voxel size of the patch in its own units (the unit the tangents are stored in).
    pub patch_voxel_size: glam::DVec3,
    /// The patch's mip level (0 = full resolution; notes §5.3).
    pub mip_level: u32,
    /// Whether extinction depends on the angle to the fibres.
    pub extinction: FibreExtinction,
    /// One fibre phase function per yarn family.
    pub shading: crate::fabric::FabricShading,
}

impl FabricLook {
    /// Patch-unit tangent → world direction for a free-standing patch `grid`: the placement's
    /// linear part after the patch's voxel size.
    fn tangent_to_world(&self, grid: &SparseGrid) -> glam::DMat3 {
        grid.index_to_world().matrix3 * glam::DMat3::from_diagonal(self.patch_voxel_size.recip())
    }
}

impl HeterogeneousMedium {
    /// The fibre frame of a fabric interior at world point `p`: the world-space tangent and
    /// the yarn id of the nearest patch voxel (`None` for other interiors or outside the
    /// patch's shell). Tangents are stored in patch units and mapped through the placement,
    /// so rotated and sheared patches keep their fibre directions.
    #[must_use]
    pub fn fibre_at(&self, p: glam::Vec3) -> Option<crate::fabric::FibreVoxel> {
        let look = self.fabric.as_ref()?;
        match &self.field {
            DensityField::Grid { grid, .. } => {
                let q = grid.world_to_index_point(p);
                let mut tangents = grid.accessor(look.tangent_channel);
                let t = crate::fabric::tangent_near(q, |ijk| tangents.value_vec3(ijk));
                let ijk = (q + glam::Vec3::splat(0.5)).floor().as_ivec3();
                let id = grid.accessor(look.id_channel).value(ijk);
                let world = (look.tangent_to_world(grid) * t.as_dvec3()).as_vec3();
                Some(crate::fabric::FibreVoxel {
                    tangent: world.try_normalize().unwrap_or(glam::Vec3::X),
                    id,
                })
            }
            DensityField::Shell(shell) => shell.fibre_at(p),
            _ => None,
        }
    }

    /// The fabric look when its extinction is fibre-projected.
    fn projected_fibres(&self) -> Option<&FabricLook> {
        self.fabric
            .as_deref()
            .filter(|l| l.extinction == FibreExtinction::Projected)
    }

    /// Appends the majorant segments of `[t0, t1]` along `ray` to `out`.
    pub fn segments(&self, ray: &Ray, t0: f32, t1: f32, out: &mut Vec<MajorantSegment>) {
        let start = out.len();
        self.pyramid.segments_adaptive(
            ray,
            t0,
            t1,
            self.tracking.majorant,
            self.coefficients.max_sigma_t(),
            out,
        );
        if self.projected_fibres().is_some() {
            // sin∠(ω, t) ∈ [0, 1] scales the density: the maxima still bound it, the minima
            // do not, and no segment is homogeneous in the closed-form sense.
            for s in &mut out[start..] {
                s.min = 0.0;
            }
        }
        if !self.coefficients.base_t.is_black() && t1.is_finite() {
            // A combined interior: the homogeneous part also fills the empty space the
            // pyramid skipped.
            let zero = |a: f32, b: f32| MajorantSegment {
                t0: a,
                t1: b,
                min: 0.0,
                max: 0.0,
                mean: 0.0,
            };
            let mut filled = Vec::with_capacity(out.len() - start + 4);
            let mut t = t0;
            for s in &out[start..] {
                if s.t0 > t {
                    filled.push(zero(t, s.t0));
                }
                filled.push(*s);
                t = t.max(s.t1);
            }
            if t < t1 {
                filled.push(zero(t, t1));
            }
            out.truncate(start);
            out.extend(filled);
        }
    }

    /// A density lookup along `ray`, by distance.
    #[must_use]
    pub fn density_along<'a>(&'a self, ray: &Ray) -> RayLookup<'a> {
        match &self.field {
            DensityField::Grid { grid, channel } => match self.projected_fibres() {
                Some(look) => RayLookup::FibreGrid(FibreGridLookup::new(grid, *channel, look, ray)),
                None => RayLookup::Grid(RayDensity::new(grid, *channel, ray)),
            },
            DensityField::Procedural(f) => RayLookup::Procedural {
                field: f,
                ray: *ray,
            },
            DensityField::Shell(shell) => RayLookup::Shell {
                accessor: shell.density_accessor(),
                tangents: self
                    .projected_fibres()
                    .map(|_| (shell.tangent_accessor(), ray.d.normalize_or_zero())),
                shell,
                ray: *ray,
                hint: u32::MAX,
            },
            DensityField::LazyBaked(g) => {
                let w2i = g.world_to_index();
                let o = w2i.transform_point3(ray.o.as_dvec3()).as_vec3();
                let d = w2i.transform_vector3(ray.d.as_dvec3()).as_vec3();
                RayLookup::Lazy { grid: g, o, d }
            }
        }
    }
}

/// Density lookups along one ray.
pub enum RayLookup<'a> {
    /// Trilinear grid lookups with a coherent accessor.
    Grid(RayDensity<'a>),
    /// Lazily baked bricks (index-space ray).
    Lazy {
        /// The bricks.
        grid: &'a LazyFbmGrid,
        /// Ray origin, index space.
        o: glam::Vec3,
        /// Ray direction, index space.
        d: glam::Vec3,
    },
    /// Direct procedural evaluation.
    Procedural {
        /// The field.
        field: &'a FbmField,
        /// The ray.
        ray: Ray,
    },
    /// A patch tiled over a mesh shell: each point is mapped to the patch (notes §3.3).
    Shell {
        /// The shell.
        shell: &'a crate::fabric::FabricShell,
        /// Accessor on the patch's density.
        accessor: crate::grid::Accessor<'a>,
        /// The ray (world space).
        ray: Ray,
        /// The last tetrahedron found.
        hint: u32,
        /// For fibre-projected extinction: an accessor on the patch's tangents and the unit
        /// direction of the ray.
        tangents: Option<(crate::grid::Accessor<'a>, glam::Vec3)>,
    },
    /// A fabric grid with fibre-projected extinction.
    FibreGrid(FibreGridLookup<'a>),
}

/// Density × sin∠(ray, fibre) along a ray through a free-standing fabric grid
/// ([`FibreExtinction::Projected`]).
pub struct FibreGridLookup<'a> {
    density: crate::grid::Accessor<'a>,
    tangent: crate::grid::Accessor<'a>,
    o: glam::Vec3,
    d: glam::Vec3,
    /// Patch-unit tangent → world direction (the placement's linear part over the voxel size).
    tangent_to_world: glam::Mat3,
    dir: glam::Vec3,
}

impl<'a> FibreGridLookup<'a> {
    fn new(grid: &'a SparseGrid, channel: usize, look: &FabricLook, ray: &Ray) -> Self {
        let w2i = grid.world_to_index();
        let m = look.tangent_to_world(grid);
        FibreGridLookup {
            density: grid.accessor(channel),
            tangent: grid.accessor(look.tangent_channel),
            o: w2i.transform_point3(ray.o.as_dvec3()).as_vec3(),
            d: w2i.transform_vector3(ray.d.as_dvec3()).as_vec3(),
            tangent_to_world: m.as_mat3(),
            dir: ray.d.normalize_or_zero(),
        }
    }

    fn at(&mut self, t: f32) -> f32 {
        let p = self.o + self.d * t;
        let density = self.density.sample_trilinear(p);
        if density.is_nan() || density <= 0.0 {
            return density;
        }
        let local = crate::fabric::tangent_near(p, |ijk| self.tangent.value_vec3(ijk));
        density * projected_width(self.dir, self.tangent_to_world * local)
    }
}

/// `sin∠(dir, tangent)` for a unit `dir`; 1 when the tangent is zero (no fibre direction).
#[inline]
#[must_use]
pub fn projected_width(dir: glam::Vec3, tangent: glam::Vec3) -> f32 {
    match tangent.try_normalize() {
        Some(t) => crate::fabric::fibre_scattering::extinction_scale(dir, t),
        None => 1.0,
    }
}

impl RayLookup<'_> {
    /// Density at distance `t`.
    pub fn at(&mut self, t: f32) -> f32 {
        match self {
            RayLookup::Grid(g) => g.at(t),
            RayLookup::Procedural { field, ray } => field.density_world(ray.at(t)),
            RayLookup::Lazy { grid, o, d } => grid.sample_trilinear_index(*o + *d * t),
            RayLookup::Shell {
                shell,
                accessor,
                ray,
                hint,
                tangents,
            } => match tangents {
                None => shell.density(accessor, ray.at(t), hint),
                Some((tan, dir)) => shell.projected_density(accessor, tan, ray.at(t), *dir, hint),
            },
            RayLookup::FibreGrid(g) => g.at(t),
        }
    }
}

/// An interior: what fills an object (notes §2.4.1).
#[derive(Clone, Debug)]
pub enum Medium {
    /// Absorption only (coloured glass): Beer–Lambert attenuation, no scattering.
    Absorbing {
        /// Absorption coefficient (1/length).
        sigma_a: Rgb,
    },
    /// Homogeneous scattering (most skin, water).
    Homogeneous(HomogeneousMedium),
    /// Spatially varying density (voxel data or procedural noise).
    Heterogeneous(Box<HeterogeneousMedium>),
}

impl Medium {
    /// Extinction coefficient of homogeneous media (the largest one, over the majorant, for
    /// heterogeneous media).
    #[must_use]
    pub fn sigma_t(&self) -> Rgb {
        match self {
            Medium::Absorbing { sigma_a } => *sigma_a,
            Medium::Homogeneous(h) => h.coefficients.sigma_t(),
            Medium::Heterogeneous(h) => h.coefficients.sigma_t_at(h.pyramid.global_bounds().max),
        }
    }

    /// Transmittance `exp(−σ_t d)` along a straight segment of length `d` (world units) of a
    /// homogeneous medium.
    #[must_use]
    pub fn transmittance(&self, d: f32) -> Rgb {
        if d <= 0.0 {
            return Rgb::ONE;
        }
        // Guard 0·∞ (σ_t = 0 with an infinite segment): REFERENCES §8.
        self.sigma_t()
            .map(|s| if s == 0.0 { 1.0 } else { (-s * d).exp() })
    }

    /// True when the medium can scatter light.
    #[must_use]
    pub fn scatters(&self) -> bool {
        match self {
            Medium::Absorbing { .. } => false,
            Medium::Homogeneous(h) => !h.coefficients.sigma_s.is_black(),
            Medium::Heterogeneous(h) => !h.coefficients.sigma_s.is_black(),
        }
    }
}

/// The outcome of sampling a free-flight distance in a homogeneous medium with one-sample MIS
/// over the RGB channels (REFERENCES §4.6; the course notes' Algorithm 1, line 3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FreeFlight {
    /// A real scattering event at distance `t`; `weight` multiplies the path throughput.
    Scatter {
        /// Distance along the ray (world units).
        t: f32,
        /// Throughput factor σ_s e^{−σ_t t} / Σ_k P(k) σ_t,k e^{−σ_t,k t}.
        weight: Rgb,
    },
    /// The flight passed `t_max` (the boundary); `weight` multiplies the throughput.
    Escape {
        /// Throughput factor e^{−σ_t t_max} / Σ_k P(k) e^{−σ_t,k t_max}.
        weight: Rgb,
    },
}

/// Channel-selection probabilities proportional to |β_c · α_c| (Chiang et al. 2016, as in
/// Cycles' random walk), falling back to |β_c| and then to uniform when those are all zero.
#[must_use]
pub fn channel_probabilities(beta: Rgb, alpha: Rgb) -> [f32; 3] {
    let mut w = [0usize, 1, 2].map(|c| (beta[c] * alpha[c]).abs());
    let mut sum: f32 = w.iter().sum();
    if !(sum > 0.0) || !sum.is_finite() {
        w = [0usize, 1, 2].map(|c| beta[c].abs());
        sum = w.iter().sum();
    }
    if !(sum > 0.0) || !sum.is_finite() {
        return [1.0 / 3.0; 3];
    }
    w.map(|x| x / sum)
}

/// The channel whose cumulative probability interval contains uniform `u`.
#[must_use]
pub fn pick_channel(p: [f32; 3], u: f32) -> usize {
    if u < p[0] {
        0
    } else if u < p[0] + p[1] || p[2] == 0.0 {
        1
    } else {
        2
    }
}

/// Samples a free-flight distance through a homogeneous medium with spectrally varying σ_t,
/// choosing the channel by throughput with one-sample MIS (balance heuristic) over channels
/// (REFERENCES §4.6). `u_channel` and `u_distance` are uniform in [0, 1).
#[must_use]
pub fn sample_free_flight(
    coeff: &Coefficients,
    beta: Rgb,
    t_max: f32,
    u_channel: f32,
    u_distance: f32,
) -> FreeFlight {
    let sigma_t = coeff.sigma_t();
    let alpha = coeff.sigma_s.safe_div(sigma_t);
    let p = channel_probabilities(beta, alpha);
    let channel = pick_channel(p, u_channel);
    let st = sigma_t[channel];
    let t = if st > 0.0 {
        -(-u_distance).ln_1p() / st
    } else {
        f32::INFINITY
    };
    if t < t_max {
        let tr = sigma_t.map(|s| (-s * t).exp());
        let pdf: f32 = (0..3).map(|k| p[k] * sigma_t[k] * tr[k]).sum();
        if !(pdf > 0.0) {
            return FreeFlight::Escape { weight: Rgb::ZERO };
        }
        FreeFlight::Scatter {
            t,
            weight: coeff.sigma_s * tr / pdf,
        }
    } else {
        let tr = sigma_t.map(|s| if s == 0.0 { 1.0 } else { (-s * t_max).exp() });
        let prob: f32 = (0..3).map(|k| p[k] * tr[k]).sum();
        if !(prob > 0.0) {
            return FreeFlight::Escape { weight: Rgb::ZERO };
        }
        FreeFlight::Escape { weight: tr / prob }
    }
}
