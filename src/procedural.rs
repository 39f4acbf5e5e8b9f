//! Sources of spatially varying density: procedural fBm (the notes' "heterogeneous
//! scattering", §2.3.1) evaluated in an object's rest space, baked into a [`SparseGrid`] or
//! evaluated directly, with majorant bounds from the fBm's analytic range, from the artist, or
//! estimated per brick from trial samples with a safety factor (notes §5.1).

use glam::{DAffine3, DVec3, IVec3, Vec3};
use noise::{Fbm, MultiFractal, NoiseFn, Perlin};
use rayon::prelude::*;

use crate::grid::{ChannelKind, SparseGrid, SparseGridBuilder, Storage, BRICK_DIM};
use crate::majorant::{Bounds, MajorantError, MajorantPyramid};
use crate::math::Aabb;
use crate::sampling::Rng;

/// Errors of procedural density sources.
#[derive(Debug, thiserror::Error)]
pub enum ProceduralError {
    /// A parameter outside its allowed range.
    #[error("{name} = {value} is invalid: {allowed}")]
    Parameter {
        /// Parameter name.
        name: &'static str,
        /// Given value.
        value: f64,
        /// Allowed range.
        allowed: &'static str,
    },
    /// Building the majorant pyramid failed.
    #[error(transparent)]
    Majorant(#[from] MajorantError),
    /// Building the grid failed.
    #[error("baking the procedural density: {0}")]
    Grid(String),
}

/// The largest noise-space coordinate (rest coordinate × the finest octave's frequency) an fBm
/// is evaluated at: see [`FbmParams::check_extent`].
pub const MAX_NOISE_COORDINATE: f64 = 1e12;

/// Parameters of a procedural fBm density: d(p) = clamp(offset + amplitude · fbm(frequency · p),
/// min, max), with `fbm` the sum of `octaves` Perlin octaves (lacunarity, gain), normalised to
/// [−1, 1] (the `noise` crate's convention). `p` is in the object's rest space.
#[derive(Clone, Debug, PartialEq)]
pub struct FbmParams {
    /// Base frequency, 1/length (rest space).
    pub frequency: f32,
    /// Octaves, 1–16.
    pub octaves: u32,
    /// Frequency multiplier per octave.
    pub lacunarity: f32,
    /// Amplitude multiplier per octave (persistence).
    pub gain: f32,
    /// Scale of the noise.
    pub amplitude: f32,
    /// Added to the scaled noise.
    pub offset: f32,
    /// Lower clamp (≥ 0).
    pub min: f32,
    /// Upper clamp.
    pub max: f32,
    /// Noise seed.
    pub seed: u32,
}

impl Default for FbmParams {
    fn default() -> Self {
        FbmParams {
            frequency: 4.0,
            octaves: 5,
            lacunarity: 2.0,
            gain: 0.5,
            amplitude: 1.0,
            offset: 0.5,
            min: 0.0,
            max: 1.0,
            seed: 1,
        }
    }
}

impl FbmParams {
    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<(), ProceduralError> {
        let bad = |name, value: f32, allowed| {
            Err(ProceduralError::Parameter {
                name,
                value: value as f64,
                allowed,
            })
        };
        if !(self.frequency > 0.0 && self.frequency.is_finite()) {
            return bad("noise.frequency", self.frequency, "must be finite and > 0");
        }
        if self.octaves == 0 || self.octaves > 16 {
            return bad("noise.octaves", self.octaves as f32, "must be in 1..=16");
        }
        if !(self.lacunarity >= 1.0 && self.lacunarity <= 8.0) {
            return bad("noise.lacunarity", self.lacunarity, "must be in [1, 8]");
        }
        if !(self.gain > 0.0 && self.gain <= 1.0) {
            return bad("noise.gain", self.gain, "must be in (0, 1]");
        }
        if !self.amplitude.is_finite() || !self.offset.is_finite() {
            return bad("noise.amplitude/offset", self.amplitude, "must be finite");
        }
        if !(self.min >= 0.0 && self.min.is_finite()) {
            return bad(
                "noise.min",
                self.min,
                "must be finite and ≥ 0 (densities are never negative)",
            );
        }
        if !(self.max >= self.min && self.max.is_finite()) {
            return bad("noise.max", self.max, "must be finite and ≥ noise.min");
        }
        Ok(())
    }

    /// The frequency of the finest octave, frequency × lacunarity^(octaves − 1) (1/length).
    #[must_use]
    pub fn highest_frequency(&self) -> f64 {
        f64::from(self.frequency) * f64::from(self.lacunarity).powi(self.octaves as i32 - 1)
    }

    /// Checks that the finest octave over rest-space coordinates up to `max_abs_coordinate`
    /// stays within [`MAX_NOISE_COORDINATE`] noise periods (beyond, the noise's lattice
    /// arithmetic overflows and its f64 coordinates lose their fraction).
    pub fn check_extent(&self, max_abs_coordinate: f64) -> Result<(), ProceduralError> {
        let reach = self.highest_frequency() * max_abs_coordinate;
        if reach.is_finite() && reach <= MAX_NOISE_COORDINATE {
            return Ok(());
        }
        Err(ProceduralError::Parameter {
            name: "noise.frequency",
            value: f64::from(self.frequency),
            allowed: "too high for the object: frequency × lacunarity^(octaves − 1) × the largest rest-space coordinate must stay below 1e12",
        })
    }

    /// The analytic range of the density: |fbm| ≤ 1, so d ∈ clamp(offset ± |amplitude|).
    #[must_use]
    pub fn analytic_bounds(&self) -> Bounds {
        let lo = (self.offset - self.amplitude.abs()).clamp(self.min, self.max);
        let hi = (self.offset + self.amplitude.abs()).clamp(self.min, self.max);
        Bounds {
            min: lo,
            max: hi,
            mean: self.offset.clamp(lo, hi),
        }
    }
}

/// A procedural fBm density placed in the world by an object transform.
#[derive(Clone, Debug)]
pub struct FbmField {
    params: FbmParams,
    noise: Fbm<Perlin>,
    /// World → rest space.
    world_to_rest: DAffine3,
    /// Rest → world.
    rest_to_world: DAffine3,
}

impl FbmField {
    /// Builds the field; `rest_to_world` is the object's transform.
    pub fn new(params: FbmParams, rest_to_world: DAffine3) -> Result<Self, ProceduralError> {
        params.validate()?;
        let noise = Fbm::<Perlin>::new(params.seed)
            .set_octaves(params.octaves as usize)
            .set_frequency(params.frequency as f64)
            .set_lacunarity(params.lacunarity as f64)
            .set_persistence(params.gain as f64);
        Ok(FbmField {
            params,
            noise,
            world_to_rest: rest_to_world.inverse(),
            rest_to_world,
        })
    }

    /// Parameters.
    #[must_use]
    pub fn params(&self) -> &FbmParams {
        &self.params
    }

    /// Rest → world transform.
    #[must_use]
    pub fn rest_to_world(&self) -> DAffine3 {
        self.rest_to_world
    }

    /// Density at a rest-space point.
    #[must_use]
    pub fn density_rest(&self, p: DVec3) -> f32 {
        // Points beyond the checked extent (never reached inside a checked object) are clamped
        // so that the noise's lattice arithmetic cannot overflow.
        let limit = MAX_NOISE_COORDINATE / self.params.highest_frequency().max(1e-300);
        let p = p.clamp(DVec3::splat(-limit), DVec3::splat(limit));
        if !p.is_finite() {
            return self.params.min;
        }
        let n = self.noise.get([p.x, p.y, p.z]) as f32;
        (self.params.offset + self.params.amplitude * n).clamp(self.params.min, self.params.max)
    }

    /// Density at a world-space point (the exact, slow evaluation: ~1 µs per sample).
    #[must_use]
    pub fn density_world(&self, p: Vec3) -> f32 {
        self.density_rest(self.world_to_rest.transform_point3(p.as_dvec3()))
    }
}

/// How the bounds of a directly evaluated procedural density are obtained.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ProceduralBound {
    /// The fBm's analytic range (conservative, loose).
    Analytic,
    /// The artist's global min and max (may be violated; tracking stays unbiased).
    Artist {
        /// Minimum density.
        min: f32,
        /// Maximum density.
        max: f32,
    },
    /// Estimated per brick from `samples` trial samples, widened by `safety` (notes §5.1); may
    /// be violated (tracking stays unbiased and counts violations).
    Estimated {
        /// Trial samples per brick.
        samples: u32,
        /// Multiplier on the estimated range (≥ 1).
        safety: f32,
    },
}

/// The index space used for a procedural field: voxels of `voxel_size` (rest units) covering
/// `rest_bounds`, mapped to the world by the object's transform.
#[derive(Clone, Copy, Debug)]
pub struct ProceduralLattice {
    /// First voxel (index space) of the covered box.
    pub lo: IVec3,
    /// Last voxel (inclusive).
    pub hi: IVec3,
    /// Index → world.
    pub index_to_world: DAffine3,
}

impl ProceduralLattice {
    /// Voxels of size `voxel_size` over `rest_bounds` (rest space), placed by `rest_to_world`.
    pub fn new(
        rest_bounds: Aabb,
        voxel_size: f32,
        rest_to_world: DAffine3,
    ) -> Result<Self, ProceduralError> {
        if !(voxel_size > 0.0 && voxel_size.is_finite()) {
            return Err(ProceduralError::Parameter {
                name: "voxel_size",
                value: voxel_size as f64,
                allowed: "must be finite and > 0",
            });
        }
        let lo = (rest_bounds.min / voxel_size).floor().as_ivec3() - IVec3::ONE;
        let hi = (rest_bounds.max / voxel_size).ceil().as_ivec3() + IVec3::ONE;
        let n = (hi - lo + IVec3::ONE).as_dvec3();
        if n.x * n.y * n.z > 2.0e9 {
            return Err(ProceduralError::Parameter {
                name: "voxel_size",
                value: voxel_size as f64,
                allowed: "too small for the object: more than 2e9 voxels",
            });
        }
        let index_to_world = rest_to_world * DAffine3::from_scale(DVec3::splat(voxel_size as f64));
        Ok(ProceduralLattice {
            lo,
            hi,
            index_to_world,
        })
    }

    fn brick_keys(&self) -> (IVec3, IVec3) {
        (self.lo >> 3, self.hi >> 3)
    }
}

/// Bakes the field into a [`SparseGrid`] over the lattice (f32 storage, one channel
/// `density`), in parallel over bricks. Bricks that are entirely zero are left out.
pub fn bake_fbm(
    field: &FbmField,
    lattice: &ProceduralLattice,
) -> Result<SparseGrid, ProceduralError> {
    let (klo, khi) = lattice.brick_keys();
    let mut keys = Vec::new();
    for z in klo.z..=khi.z {
        for y in klo.y..=khi.y {
            for x in klo.x..=khi.x {
                keys.push(IVec3::new(x, y, z));
            }
        }
    }
    let index_to_rest = field.world_to_rest * lattice.index_to_world;
    let bricks: Vec<(IVec3, Vec<f32>)> = keys
        .par_iter()
        .filter_map(|&key| {
            let mut v = vec![0.0f32; 512];
            let mut any = false;
            for x in 0..BRICK_DIM {
                for y in 0..BRICK_DIM {
                    for z in 0..BRICK_DIM {
                        let ijk = key * BRICK_DIM + IVec3::new(x, y, z);
                        let d = field.density_rest(index_to_rest.transform_point3(ijk.as_dvec3()));
                        any |= d != 0.0;
                        v[((x << 6) | (y << 3) | z) as usize] = d;
                    }
                }
            }
            any.then_some((key, v))
        })
        .collect();
    let mut b = SparseGridBuilder::new(Storage::F32);
    let c = b.add_channel("density", ChannelKind::Scalar, Vec3::ZERO);
    b.set_index_to_world(lattice.index_to_world)
        .map_err(|e| ProceduralError::Grid(e.to_string()))?;
    for (key, values) in bricks {
        b.fill_brick(c, key, &values, [u64::MAX; 8])
            .map_err(|e| ProceduralError::Grid(e.to_string()))?;
    }
    Ok(b.build())
}

/// The majorant pyramid of a directly evaluated field, with per-brick bounds from `bound`.
/// Returns the pyramid and, for estimated bounds, nothing else: violations are counted while
/// tracking.
pub fn procedural_pyramid(
    field: &FbmField,
    lattice: &ProceduralLattice,
    bound: ProceduralBound,
    seed: u64,
) -> Result<MajorantPyramid, ProceduralError> {
    let (klo, khi) = lattice.brick_keys();
    let world_to_index = lattice.index_to_world.inverse();
    let analytic = field.params.analytic_bounds();
    let index_to_rest = field.world_to_rest * lattice.index_to_world;
    let pyramid = match bound {
        ProceduralBound::Analytic => {
            MajorantPyramid::from_brick_bounds(klo, khi, 0.0, world_to_index, |_| analytic)?
        }
        ProceduralBound::Artist { min, max } => {
            if !(min >= 0.0 && max >= min && max.is_finite()) {
                return Err(ProceduralError::Parameter {
                    name: "bound_min/bound_max",
                    value: max as f64,
                    allowed: "need 0 ≤ bound_min ≤ bound_max < ∞",
                });
            }
            let b = Bounds {
                min,
                max,
                mean: 0.5 * (min + max),
            };
            // The artist's bounds are a claim, not a proof: never taken as exact.
            MajorantPyramid::from_estimated_brick_bounds(klo, khi, 0.0, world_to_index, |_| b)?
        }
        ProceduralBound::Estimated { samples, safety } => {
            if samples == 0 || samples > 1_000_000 || !(safety >= 1.0 && safety.is_finite()) {
                return Err(ProceduralError::Parameter {
                    name: "trial_samples/safety",
                    value: safety as f64,
                    allowed: "trial_samples in 1..=1000000, safety ≥ 1",
                });
            }
            let mut rng = Rng::new(seed, 77);
            // Estimated bounds may be violated: never taken as exact, so a brick whose trial
            // samples all agree is still looked up.
            MajorantPyramid::from_estimated_brick_bounds(klo, khi, 0.0, world_to_index, |key| {
                let mut lo = f32::INFINITY;
                let mut hi = f32::NEG_INFINITY;
                let mut sum = 0.0f32;
                // The brick's lookup region spans voxels [8k − 1, 8k + 8].
                let base = (key * BRICK_DIM).as_dvec3() - DVec3::splat(1.0);
                for _ in 0..samples {
                    let u = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 9.0;
                    let d = field.density_rest(index_to_rest.transform_point3(base + u));
                    lo = lo.min(d);
                    hi = hi.max(d);
                    sum += d;
                }
                let mean = sum / samples as f32;
                let range = (hi - lo).max(1e-3 * hi.abs()).max(1e-6);
                let widen = 0.5 * (safety - 1.0) * range + (safety - 1.0) * hi;
                let min = (lo - widen).clamp(analytic.min, analytic.max);
                let max = (hi + widen).clamp(analytic.min, analytic.max).max(1e-6);
                Bounds {
                    min: min.min(max),
                    max,
                    mean: mean.clamp(min.min(max), max),
                }
            })?
        }
    };
    Ok(pyramid)
}

/// A procedural field baked lazily: each 8³ brick of the lattice is evaluated the first time a
/// lookup touches it ("only where rays go"), then reused. Lookups are trilinear in index space,
/// like a baked [`SparseGrid`]. Thread-safe (bricks are `OnceLock`s).
#[derive(Debug)]
pub struct LazyFbmGrid {
    field: FbmField,
    key_lo: IVec3,
    dims: IVec3,
    bricks: Vec<std::sync::OnceLock<Box<[f32]>>>,
    index_to_rest: DAffine3,
    world_to_index: DAffine3,
}

impl Clone for LazyFbmGrid {
    fn clone(&self) -> Self {
        LazyFbmGrid {
            field: self.field.clone(),
            key_lo: self.key_lo,
            dims: self.dims,
            bricks: (0..self.bricks.len())
                .map(|_| std::sync::OnceLock::new())
                .collect(),
            index_to_rest: self.index_to_rest,
            world_to_index: self.world_to_index,
        }
    }
}

impl LazyFbmGrid {
    /// Prepares lazy baking of `field` over `lattice` (nothing is evaluated yet).
    pub fn new(field: FbmField, lattice: &ProceduralLattice) -> Result<Self, ProceduralError> {
        let (key_lo, key_hi) = lattice.brick_keys();
        let dims = key_hi - key_lo + IVec3::ONE;
        let n = dims.x as usize * dims.y as usize * dims.z as usize;
        if n > 1 << 26 {
            return Err(ProceduralError::Parameter {
                name: "voxel_size",
                value: n as f64,
                allowed: "too small for lazy baking: more than 2^26 bricks",
            });
        }
        let index_to_rest = field.world_to_rest * lattice.index_to_world;
        Ok(LazyFbmGrid {
            field,
            key_lo,
            dims,
            bricks: (0..n).map(|_| std::sync::OnceLock::new()).collect(),
            index_to_rest,
            world_to_index: lattice.index_to_world.inverse(),
        })
    }

    /// World → index map.
    #[must_use]
    pub fn world_to_index(&self) -> DAffine3 {
        self.world_to_index
    }

    /// Bricks evaluated so far.
    #[must_use]
    pub fn baked_bricks(&self) -> usize {
        self.bricks.iter().filter(|b| b.get().is_some()).count()
    }

    /// Bricks of the lattice.
    #[must_use]
    pub fn total_bricks(&self) -> usize {
        self.bricks.len()
    }

    fn brick(&self, key: IVec3) -> Option<&[f32]> {
        let c = key - self.key_lo;
        if c.cmplt(IVec3::ZERO).any() || c.cmpge(self.dims).any() {
            return None;
        }
        let i = (c.z as usize * self.dims.y as usize + c.y as usize) * self.dims.x as usize
            + c.x as usize;
        Some(self.bricks[i].get_or_init(|| {
            let mut v = vec![0.0f32; 512];
            for x in 0..BRICK_DIM {
                for y in 0..BRICK_DIM {
                    for z in 0..BRICK_DIM {
                        let ijk = key * BRICK_DIM + IVec3::new(x, y, z);
                        v[((x << 6) | (y << 3) | z) as usize] = self
                            .field
                            .density_rest(self.index_to_rest.transform_point3(ijk.as_dvec3()));
                    }
                }
            }
            v.into_boxed_slice()
        }))
    }

    /// Voxel value (0 outside the lattice).
    #[must_use]
    pub fn value(&self, ijk: IVec3) -> f32 {
        match self.brick(ijk >> 3) {
            Some(b) => {
                let l = ijk & 7;
                b[((l.x << 6) | (l.y << 3) | l.z) as usize]
            }
            None => 0.0,
        }
    }

    /// Trilinear lookup at index-space `p` (voxel centres at integers).
    #[must_use]
    pub fn sample_trilinear_index(&self, p: Vec3) -> f32 {
        let f = p.floor();
        let i = f.as_ivec3();
        let t = p - f;
        let mut acc = 0.0f32;
        for dz in 0..2 {
            for dy in 0..2 {
                for dx in 0..2 {
                    let w = (if dx == 1 { t.x } else { 1.0 - t.x })
                        * (if dy == 1 { t.y } else { 1.0 - t.y })
                        * (if dz == 1 { t.z } else { 1.0 - t.z });
                    if w > 0.0 {
                        acc += w * self.value(i + IVec3::new(dx, dy, dz));
                    }
                }
            }
        }
        acc
    }
}
