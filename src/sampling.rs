//! Random numbers and sample warps.
//!
//! Every random number in a render is a pure function of
//! `(seed, pixel, sample index, dimension)` ([`PixelSampler`]), so an image is bit-identical
//! whatever the thread count, tile order or split of the samples. Dimensions are grouped by
//! path vertex: the camera's first [`CAMERA_SOBOL_DIMENSIONS`] numbers and the first
//! [`VERTEX_SOBOL_DIMENSIONS`] numbers of each of the first [`SOBOL_VERTICES`] vertices come from
//! Owen-scrambled Sobol points (`sobol_burley`, Burley 2020, "Practical Hash-based Owen
//! Scrambling"), four dimensions at a time; the rest of a vertex (long tracking walks, shadow
//! rays) and deeper vertices come from a cheap counter-based hash. Each vertex's Sobol block
//! starts at the same place whatever the previous vertices consumed, so the first decisions of
//! every vertex (free-flight channel and distance, light choice and position, scattering
//! direction) stay stratified across the pixel's samples.

use std::sync::OnceLock;

use sobol_burley::parts::{hash, hash_int4, owen_scramble_rev, Int4};

use crate::math::{Vec2, Vec3, INV_PI, PI};

/// Sobol dimensions of the camera vertex (pixel position, lens).
pub const CAMERA_SOBOL_DIMENSIONS: u32 = 4;

/// Sobol dimensions at the start of each path vertex.
pub const VERTEX_SOBOL_DIMENSIONS: u32 = 8;

/// Vertices (after the camera) whose first numbers come from the Sobol sequence.
pub const SOBOL_VERTICES: u32 =
    (sobol_burley::NUM_DIMENSION_SETS_4D - 1) / (VERTEX_SOBOL_DIMENSIONS / 4);

/// Sample indices served by the Sobol sequence (`sobol_burley` supports 2^16); later
/// samples of a pixel are hashed.
pub const SOBOL_SAMPLES: u32 = 1 << 16;

/// The largest `f32` strictly below 1.
pub const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// A 64-bit finaliser (splitmix64 / Stafford variant 13): a good avalanche hash.
#[must_use]
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Hashes any number of words into 64 bits.
#[must_use]
pub fn hash_words(words: &[u64]) -> u64 {
    let mut h = 0x9e37_79b9_7f4a_7c15u64;
    for &w in words {
        h = mix64(h ^ w.wrapping_add(0x9e37_79b9_7f4a_7c15).wrapping_add(h << 6));
    }
    h
}

/// Converts 32 random bits to a float in `[0, 1)` (24 bits; never rounds to 1).
#[must_use]
#[inline]
pub fn bits_to_unit_f32(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Direction-vector sums of one 4-dimensional Sobol set, four index bits at a time:
/// `[nibble][value]` is the XOR of the set's reversed direction vectors for the bits of `value`
/// in the `nibble`-th group of four bits (from the top) of the reversed 16-bit index.
type NibbleTable = [[[u32; 4]; 16]; 4];

/// The [`NibbleTable`]s once made ([`nibble_tables`]).
static NIBBLE_TABLES: OnceLock<Vec<NibbleTable>> = OnceLock::new();

/// The nibble tables of every dimension set (`sobol_burley`'s direction vectors, regrouped):
/// `sobol_burley::parts::sobol_int4_rev` is linear over GF(2) in the index bits, so the XOR of
/// the vectors of the set bits, one bit at a time, equals the XOR of four table entries.
fn nibble_tables() -> &'static [NibbleTable] {
    NIBBLE_TABLES.get_or_init(|| {
        (0..sobol_burley::NUM_DIMENSION_SETS_4D)
            .map(|set| {
                let mut t = [[[0u32; 4]; 16]; 4];
                for (nibble, row) in t.iter_mut().enumerate() {
                    for (value, entry) in row.iter_mut().enumerate() {
                        // Bit k of `value` is bit 28 − 4·nibble + k of the reversed index.
                        let bits = (value as u32) << (28 - 4 * nibble);
                        *entry = sobol_burley::parts::sobol_int4_rev(bits, set).into();
                    }
                }
                t
            })
            .collect()
    })
}

/// The reversed, seed-shuffled Sobol index of `sample_index` (what `sobol_burley::sample_4d`
/// computes first), split into the four nibbles that index the [`NibbleTable`]s.
#[cfg(test)]
fn shuffled_nibbles(sample_index: u32, seed: u32) -> [u8; 4] {
    shuffled_nibbles_keyed(sample_index, shuffle_key(seed))
}

/// The key of the index shuffle of [`shuffled_nibbles`] for a pixel's Sobol `seed`.
#[inline]
fn shuffle_key(seed: u32) -> u32 {
    hash(seed ^ 0x79c6_8e4a)
}

/// [`shuffled_nibbles`] with the shuffle's key ([`shuffle_key`]) given.
#[inline]
fn shuffled_nibbles_keyed(sample_index: u32, key: u32) -> [u8; 4] {
    let rev = owen_scramble_rev(sample_index.reverse_bits(), key);
    [28, 24, 20, 16].map(|shift| ((rev >> shift) & 15) as u8)
}

/// Sobol sets whose scramble keys ([`scramble_key`]) a [`PixelSeed`] holds: the camera's set and
/// the two sets of each of the first two vertices (what most paths of a thin medium draw).
const KEYED_SETS: usize = 5;

/// The key of the Owen scrambling of Sobol set `set` for a pixel's Sobol `seed`: what
/// `sobol_burley::sample_4d` hashes from (seed, set) before scrambling the set's four numbers.
#[inline]
fn scramble_key(seed: u32, set: u32) -> Int4 {
    let seed: Int4 = [seed.wrapping_mul(0x9c8f_2d3b); 4].into();
    let ds: Int4 = [set; 4].into();
    hash_int4(seed ^ ds ^ [0x912f_69ba, 0x174f_18ab, 0x691e_72ca, 0xb40c_c1b8].into())
}

/// The part of a [`PixelSampler`] that depends on the pixel only (not on the sample): made
/// once per pixel by a render loop that takes many samples there.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelSeed {
    /// Hash of (render seed, pixel).
    seed: u64,
    /// [`shuffle_key`] of the pixel's Sobol seed.
    shuffle: u32,
    /// [`scramble_key`]s of the pixel's first [`KEYED_SETS`] Sobol sets.
    keys: [[u32; 4]; KEYED_SETS],
}

impl PixelSeed {
    /// The pixel part of pixel `(px, py)`'s samples for the render seed `seed`.
    #[must_use]
    pub fn new(seed: u64, px: u32, py: u32) -> Self {
        let seed = hash_words(&[seed, ((px as u64) << 32) | py as u64]);
        let mut keys = [[0u32; 4]; KEYED_SETS];
        for (set, key) in (0u32..).zip(keys.iter_mut()) {
            *key = scramble_key(seed as u32, set).into();
        }
        PixelSeed {
            seed,
            shuffle: shuffle_key(seed as u32),
            keys,
        }
    }
}

/// `sobol_burley::sample_4d(sample_index, set, seed)` bit for bit, with the index shuffled
/// once per sample (`nibbles`, [`shuffled_nibbles`]), the direction vectors summed by four
/// table reads instead of one XOR per set index bit, and the scramble's key given (`key`,
/// [`scramble_key`] of the seed and set; Burley 2020's scrambling unchanged).
#[inline]
fn sobol_4d_keyed(table: &NibbleTable, nibbles: [u8; 4], key: [u32; 4]) -> [f32; 4] {
    let a = table[0][usize::from(nibbles[0] & 15)];
    let b = table[1][usize::from(nibbles[1] & 15)];
    let c = table[2][usize::from(nibbles[2] & 15)];
    let d = table[3][usize::from(nibbles[3] & 15)];
    let mut out = [0.0f32; 4];
    for i in 0..4 {
        // `sobol_burley::parts::owen_scramble_int4_rev`, lane by lane (the compiler makes SSE2
        // lanes of it with a shorter 32-bit multiply than the crate's), then the reversal
        // and `to_f32_norm`.
        let s = key[i];
        let mut n = a[i] ^ b[i] ^ c[i] ^ d[i];
        n ^= n.wrapping_mul(0x3d20_adea);
        n = n.wrapping_add(s);
        n = n.wrapping_mul((s >> 16) | 1);
        n ^= n.wrapping_mul(0x0552_6c56);
        n ^= n.wrapping_mul(0x53a2_2864);
        out[i] = f32::from_bits((n.reverse_bits() >> 9) | 0x3f80_0000) - 1.0;
    }
    out
}

/// [`sobol_4d_keyed`] with the key computed from the pixel's Sobol `seed` and the `set`.
#[cfg(test)]
fn sobol_4d(tables: &[NibbleTable], nibbles: [u8; 4], set: u32, seed: u32) -> [f32; 4] {
    sobol_4d_keyed(
        &tables[set as usize],
        nibbles,
        scramble_key(seed, set).into(),
    )
}

/// Deterministic per-pixel sample stream, grouped by path vertex (see the module docs).
#[derive(Clone, Debug)]
pub struct PixelSampler {
    /// Seed of the pixel's scrambled Sobol sequence.
    sobol_seed: u32,
    sample_index: u32,
    /// Hash of (pixel, sample) for the hashed dimensions.
    hash_base: u64,
    /// Current vertex (0 = camera).
    vertex: u32,
    /// Numbers drawn in the current vertex.
    used: u32,
    /// How many of the current vertex's first numbers come from the Sobol sequence (0 past
    /// [`SOBOL_VERTICES`] or [`SOBOL_SAMPLES`]); set when the vertex starts, so that a hashed
    /// draw tests one bound only.
    sobol_dims: u32,
    /// The current vertex's first 4-dimensional Sobol set.
    first_set: u32,
    /// The current 4-dimensional Sobol set.
    sobol: [f32; 4],
    /// The sample's shuffled Sobol index, by nibble ([`shuffled_nibbles`]).
    nibbles: [u8; 4],
    /// The pixel's [`PixelSeed::keys`].
    keys: [[u32; 4]; KEYED_SETS],
}

impl PixelSampler {
    /// Starts sample `sample_index` of pixel `(px, py)` for the render seed `seed`, at the
    /// camera vertex.
    #[must_use]
    pub fn new(seed: u64, px: u32, py: u32, sample_index: u32) -> Self {
        PixelSampler::in_pixel(&PixelSeed::new(seed, px, py), sample_index)
    }

    /// [`PixelSampler::new`] with the pixel's part computed once ([`PixelSeed`]): the same
    /// numbers.
    #[must_use]
    #[inline]
    pub fn in_pixel(pixel: &PixelSeed, sample_index: u32) -> Self {
        PixelSampler {
            sobol_seed: pixel.seed as u32,
            sample_index,
            hash_base: hash_words(&[pixel.seed, sample_index as u64]),
            vertex: 0,
            used: 0,
            sobol_dims: if sample_index < SOBOL_SAMPLES {
                CAMERA_SOBOL_DIMENSIONS
            } else {
                0
            },
            first_set: 0,
            sobol: [0.0; 4],
            nibbles: shuffled_nibbles_keyed(sample_index, pixel.shuffle),
            keys: pixel.keys,
        }
    }

    /// Moves to the next path vertex: its first numbers come from a fresh Sobol block.
    pub fn start_vertex(&mut self) {
        self.vertex = self.vertex.saturating_add(1);
        self.used = 0;
        if self.vertex <= SOBOL_VERTICES && self.sample_index < SOBOL_SAMPLES {
            self.sobol_dims = VERTEX_SOBOL_DIMENSIONS;
            self.first_set = 1 + (self.vertex - 1) * (VERTEX_SOBOL_DIMENSIONS / 4);
        } else {
            self.sobol_dims = 0;
        }
    }

    /// The next uniform number in `[0, 1)`. The hashed draws (most of them: tracking walks,
    /// shadow rays) are a few instructions and inline; the Sobol ones are out of line.
    #[inline]
    pub fn next_1d(&mut self) -> f32 {
        let j = self.used;
        if j < self.sobol_dims {
            return self.next_sobol(j);
        }
        self.used = j.saturating_add(1);
        let key = (u64::from(self.vertex) << 32) | u64::from(j);
        let bits = mix64(self.hash_base ^ key.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        bits_to_unit_f32((bits >> 32) as u32)
    }

    /// Number `j` (< `sobol_dims`) of the current vertex, from its Sobol sets. The first
    /// number of a set is returned by [`Self::fill_sobol`] itself (a tail call), so the other
    /// three keep nothing across a call and cost a few instructions.
    #[inline(never)]
    fn next_sobol(&mut self, j: u32) -> f32 {
        self.used = j + 1;
        if j.is_multiple_of(4) {
            return self.fill_sobol(self.first_set + j / 4);
        }
        self.sobol[(j % 4) as usize]
    }

    /// Computes Sobol set `set` of the sample into `self.sobol` and returns its first number.
    /// Its numbers are below [`ONE_MINUS_EPSILON`] already: the largest is 1 − 2^−23.
    #[inline(never)]
    fn fill_sobol(&mut self, set: u32) -> f32 {
        // Before the tables exist (once per process), a tail call makes them: the common path
        // then keeps no registers across a call.
        let Some(tables) = NIBBLE_TABLES.get() else {
            return self.fill_sobol_first(set);
        };
        let key = match self.keys.get(set as usize) {
            Some(&key) => key,
            None => scramble_key(self.sobol_seed, set).into(),
        };
        self.sobol = sobol_4d_keyed(&tables[set as usize], self.nibbles, key);
        self.sobol[0]
    }

    /// [`Self::fill_sobol`] when the nibble tables are not made yet.
    #[cold]
    #[inline(never)]
    fn fill_sobol_first(&mut self, set: u32) -> f32 {
        nibble_tables();
        self.fill_sobol(set)
    }

    /// The next two uniform numbers.
    #[inline]
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_1d(), self.next_1d())
    }

    /// The current vertex (0 = camera) and the numbers drawn in it so far.
    #[must_use]
    pub fn position(&self) -> (u32, u32) {
        (self.vertex, self.used)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pixel_seed_reused_over_samples_gives_each_sample_its_numbers() {
        let mut rng = Rng::new(9, 4);
        for _ in 0..200 {
            let (seed, px, py) = (
                u64::from(rng.next_u32()),
                rng.next_u32() >> 20,
                rng.next_u32() >> 20,
            );
            let pixel = PixelSeed::new(seed, px, py);
            // Sobol samples, the last ones, and hashed samples past 2^16.
            for s in (0..40).chain(SOBOL_SAMPLES - 3..SOBOL_SAMPLES + 3) {
                // The reference: the pixel's part computed per sample by the formulas written
                // out (`PixelSampler::new` itself goes through `PixelSeed` now).
                let pixel_seed = hash_words(&[seed, (u64::from(px) << 32) | u64::from(py)]);
                let rev =
                    owen_scramble_rev(s.reverse_bits(), hash(pixel_seed as u32 ^ 0x79c6_8e4a));
                let mut a = PixelSampler {
                    sobol_seed: pixel_seed as u32,
                    hash_base: hash_words(&[pixel_seed, u64::from(s)]),
                    nibbles: [28, 24, 20, 16].map(|shift| ((rev >> shift) & 15) as u8),
                    ..PixelSampler::new(seed, px, py, s)
                };
                let mut b = PixelSampler::in_pixel(&pixel, s);
                let (mut x, mut y) = (Vec::new(), Vec::new());
                for v in 0..4 {
                    for _ in 0..10 {
                        x.push(a.next_1d().to_bits());
                        y.push(b.next_1d().to_bits());
                    }
                    if v < 3 {
                        a.start_vertex();
                        b.start_vertex();
                    }
                }
                assert_eq!(x, y, "seed {seed} pixel ({px}, {py}) sample {s}");
                // And the numbers of another pixel differ.
                let mut c = PixelSampler::in_pixel(&PixelSeed::new(seed, px + 1, py), s);
                let z: Vec<u32> = (0..10).map(|_| c.next_1d().to_bits()).collect();
                assert_ne!(
                    &x[..10],
                    &z[..],
                    "seed {seed} pixel ({px}, {py}) sample {s}"
                );
            }
        }
    }

    #[test]
    fn every_vertex_sobol_draw_matches_sobol_burley_with_keys_kept_or_not() {
        // The sets whose scramble keys the pixel keeps (the first `KEYED_SETS`) and the later
        // ones (keys computed per set), every Sobol number of every Sobol vertex, against
        // `sobol_burley::sample_4d` itself; interleaved samples of one pixel share its keys.
        let mut rng = Rng::new(21, 5);
        for _ in 0..60 {
            let (seed, px, py) = (
                u64::from(rng.next_u32()),
                rng.next_u32() >> 20,
                rng.next_u32() >> 20,
            );
            let pixel = PixelSeed::new(seed, px, py);
            let sobol_seed = pixel.seed as u32;
            for s in (0..12).chain([rng.next_u32() % SOBOL_SAMPLES, SOBOL_SAMPLES - 1]) {
                let mut sampler = PixelSampler::in_pixel(&pixel, s);
                for vertex in 0..=SOBOL_VERTICES {
                    let (dims, first_set) = if vertex == 0 {
                        (CAMERA_SOBOL_DIMENSIONS, 0)
                    } else {
                        sampler.start_vertex();
                        (VERTEX_SOBOL_DIMENSIONS, 1 + (vertex - 1) * 2)
                    };
                    for j in 0..dims {
                        let want = sobol_burley::sample_4d(s, first_set + j / 4, sobol_seed)
                            [(j % 4) as usize];
                        let got = sampler.next_1d();
                        assert!(got < ONE_MINUS_EPSILON);
                        assert_eq!(
                            got.to_bits(),
                            want.to_bits(),
                            "seed {seed} pixel ({px}, {py}) sample {s} vertex {vertex} draw {j}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn table_sobol_matches_sobol_burley_bit_for_bit() {
        let mut rng = Rng::new(7, 3);
        let tables = nibble_tables();
        for n in 0..20_000u32 {
            // Every index below 2^10, then random ones up to 2^16; every set; random seeds.
            let index = if n < 1024 { n } else { rng.next_u32() >> 16 };
            let seed = rng.next_u32();
            let set = n % sobol_burley::NUM_DIMENSION_SETS_4D;
            let want = sobol_burley::sample_4d(index, set, seed);
            let got = sobol_4d(tables, shuffled_nibbles(index, seed), set, seed);
            assert_eq!(
                want.map(f32::to_bits),
                got.map(f32::to_bits),
                "index {index} set {set} seed {seed}"
            );
        }
    }
}

/// A small, fast PCG32 generator (O'Neill 2014) for tests, tools and baking.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

impl Rng {
    /// A generator seeded from `seed` and stream `stream`.
    #[must_use]
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut r = Rng {
            state: 0,
            inc: (stream << 1) | 1,
        };
        r.next_u32();
        r.state = r.state.wrapping_add(mix64(seed));
        r.next_u32();
        r
    }
    /// 32 random bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }
    /// Uniform `f32` in `[0, 1)`.
    pub fn next_f32(&mut self) -> f32 {
        bits_to_unit_f32(self.next_u32())
    }
    /// Uniform `f64` in `[0, 1)`.
    pub fn next_f64(&mut self) -> f64 {
        let hi = (self.next_u32() as u64) << 21;
        let lo = (self.next_u32() >> 11) as u64;
        (hi | lo) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }
    /// Two uniform numbers.
    pub fn next_2d(&mut self) -> Vec2 {
        Vec2::new(self.next_f32(), self.next_f32())
    }
}

/// Uniform point on the unit disc (concentric map, Shirley & Chiu 1997).
#[must_use]
pub fn sample_uniform_disk_concentric(u: Vec2) -> Vec2 {
    let o = u * 2.0 - Vec2::ONE;
    if o.x == 0.0 && o.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, theta) = if o.x.abs() > o.y.abs() {
        (o.x, PI / 4.0 * (o.y / o.x))
    } else {
        (o.y, PI / 2.0 - PI / 4.0 * (o.x / o.y))
    };
    Vec2::new(r * theta.cos(), r * theta.sin())
}

/// Cosine-weighted direction on the +z hemisphere; pdf = cosθ/π.
#[must_use]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = sample_uniform_disk_concentric(u);
    let z = (1.0 - d.x * d.x - d.y * d.y).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// Pdf of [`sample_cosine_hemisphere`] (solid angle).
#[must_use]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * INV_PI
}

/// Uniform direction on the unit sphere; pdf = 1/(4π).
#[must_use]
pub fn sample_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Uniform direction in the cone of half-angle `acos(cos_max)` around +z; pdf = 1/(2π(1−cos_max)).
#[must_use]
pub fn sample_uniform_cone(u: Vec2, cos_max: f32) -> Vec3 {
    let cos_t = (1.0 - u.x) + u.x * cos_max;
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Pdf of [`sample_uniform_cone`] (solid angle).
#[must_use]
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Balance heuristic weight of strategy `f` against `g` (one sample each).
#[must_use]
pub fn balance_heuristic(pdf_f: f32, pdf_g: f32) -> f32 {
    if pdf_f + pdf_g > 0.0 {
        pdf_f / (pdf_f + pdf_g)
    } else {
        0.0
    }
}

/// Power heuristic (β = 2) weight of strategy `f` against `g` (Veach 1997).
#[must_use]
pub fn power_heuristic(pdf_f: f32, pdf_g: f32) -> f32 {
    if pdf_f.is_infinite() {
        return 1.0;
    }
    let f = pdf_f * pdf_f;
    let g = pdf_g * pdf_g;
    if f + g > 0.0 && (f + g).is_finite() {
        f / (f + g)
    } else if pdf_f > pdf_g {
        1.0
    } else {
        0.0
    }
}

/// A piecewise-constant 2D distribution over `[0,1)^2` (for environment-map importance
/// sampling): a marginal over rows and a conditional per row.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    width: usize,
    height: usize,
    conditional_cdf: Vec<f32>,
    conditional_integral: Vec<f32>,
    marginal_cdf: Vec<f32>,
    marginal_integral: f32,
}

impl Distribution2D {
    /// Builds from non-negative row-major weights (`width × height`). Returns `None` if every
    /// weight is zero or the sizes do not match.
    #[must_use]
    pub fn new(weights: &[f32], width: usize, height: usize) -> Option<Self> {
        if width == 0 || height == 0 || weights.len() != width * height {
            return None;
        }
        let mut conditional_cdf = vec![0.0f32; (width + 1) * height];
        let mut conditional_integral = vec![0.0f32; height];
        for y in 0..height {
            let row = &weights[y * width..(y + 1) * width];
            let cdf = &mut conditional_cdf[y * (width + 1)..(y + 1) * (width + 1)];
            let mut acc = 0.0f64;
            cdf[0] = 0.0;
            for x in 0..width {
                acc += row[x].max(0.0) as f64 / width as f64;
                cdf[x + 1] = acc as f32;
            }
            conditional_integral[y] = acc as f32;
            if acc > 0.0 {
                for c in cdf.iter_mut() {
                    *c = (*c as f64 / acc) as f32;
                }
            } else {
                for (x, c) in cdf.iter_mut().enumerate() {
                    *c = x as f32 / width as f32;
                }
            }
        }
        let mut marginal_cdf = vec![0.0f32; height + 1];
        let mut acc = 0.0f64;
        for y in 0..height {
            acc += conditional_integral[y] as f64 / height as f64;
            marginal_cdf[y + 1] = acc as f32;
        }
        if acc <= 0.0 || !acc.is_finite() {
            return None;
        }
        for c in marginal_cdf.iter_mut() {
            *c = (*c as f64 / acc) as f32;
        }
        Some(Distribution2D {
            width,
            height,
            conditional_cdf,
            conditional_integral,
            marginal_cdf,
            marginal_integral: acc as f32,
        })
    }

    fn sample_cdf(cdf: &[f32], u: f32) -> (usize, f32) {
        let n = cdf.len() - 1;
        let mut lo = 0usize;
        let mut hi = n;
        while lo + 1 < hi {
            let mid = (lo + hi) / 2;
            if cdf[mid] <= u {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        // skip zero-width cells
        let mut i = lo;
        while i + 1 < n && cdf[i + 1] <= u {
            i += 1;
        }
        let width = cdf[i + 1] - cdf[i];
        let du = if width > 0.0 {
            ((u - cdf[i]) / width).clamp(0.0, ONE_MINUS_EPSILON)
        } else {
            0.5
        };
        (i, du)
    }

    /// Samples a point in `[0,1)^2`; returns the point and its pdf (w.r.t. area in `[0,1)^2`).
    #[must_use]
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (y, dy) = Self::sample_cdf(&self.marginal_cdf, u.y);
        let row = &self.conditional_cdf[y * (self.width + 1)..(y + 1) * (self.width + 1)];
        let (x, dx) = Self::sample_cdf(row, u.x);
        let p = Vec2::new(
            (x as f32 + dx) / self.width as f32,
            (y as f32 + dy) / self.height as f32,
        );
        (p, self.pdf(p))
    }

    /// Pdf of a point in `[0,1)^2`.
    #[must_use]
    pub fn pdf(&self, p: Vec2) -> f32 {
        let x = ((p.x * self.width as f32) as usize).min(self.width - 1);
        let y = ((p.y * self.height as f32) as usize).min(self.height - 1);
        let row = &self.conditional_cdf[y * (self.width + 1)..(y + 1) * (self.width + 1)];
        let cell = row[x + 1] - row[x];
        let row_p = self.marginal_cdf[y + 1] - self.marginal_cdf[y];
        cell * row_p * (self.width * self.height) as f32
    }

    /// Integral of the weights over `[0,1)^2`.
    #[must_use]
    pub fn integral(&self) -> f32 {
        self.marginal_integral
    }

    /// Integral of row `y`.
    #[must_use]
    pub fn row_integral(&self, y: usize) -> f32 {
        self.conditional_integral[y]
    }
}
