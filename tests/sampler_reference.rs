//! Bit-for-bit references for two hot paths written for speed: the per-pixel sampler (Sobol
//! bounds set once per vertex, hashed draws inline) against its rule written out per draw,
//! and the single-lobe Henyey–Greenstein value and sampled direction against their plain forms.

use velour::math::{Vec2, Vec3};
use velour::phase::PhaseFunction;
use velour::sampling::{
    bits_to_unit_f32, hash_words, mix64, PixelSampler, Rng, CAMERA_SOBOL_DIMENSIONS,
    ONE_MINUS_EPSILON, SOBOL_SAMPLES, SOBOL_VERTICES, VERTEX_SOBOL_DIMENSIONS,
};

/// Draw `j` of vertex `vertex` (0 = camera) of sample `s` of pixel (`px`, `py`), by the
/// sampler's documented rule: the first Sobol dimensions of a vertex from `sobol_burley`'s
/// 4-dimensional sets (the camera's from set 0, vertex v's from set 1 + 2(v − 1)), every other
/// number from the hash of (pixel, sample, vertex, draw).
fn reference(seed: u64, px: u32, py: u32, s: u32, vertex: u32, j: u32) -> f32 {
    let pixel_seed = hash_words(&[seed, (u64::from(px) << 32) | u64::from(py)]);
    let (dims, first_set) = if vertex == 0 {
        (CAMERA_SOBOL_DIMENSIONS, 0)
    } else {
        (
            VERTEX_SOBOL_DIMENSIONS,
            1 + (vertex - 1) * (VERTEX_SOBOL_DIMENSIONS / 4),
        )
    };
    if j < dims && vertex <= SOBOL_VERTICES && s < SOBOL_SAMPLES {
        let v = sobol_burley::sample_4d(s, first_set + j / 4, pixel_seed as u32);
        return v[(j % 4) as usize].min(ONE_MINUS_EPSILON);
    }
    let hash_base = hash_words(&[pixel_seed, u64::from(s)]);
    let key = (u64::from(vertex) << 32) | u64::from(j);
    bits_to_unit_f32((mix64(hash_base ^ key.wrapping_mul(0x9e37_79b9_7f4a_7c15)) >> 32) as u32)
}

#[test]
fn sampler_draws_match_the_rule_written_out_per_draw() {
    let mut rng = Rng::new(11, 2);
    let samples = [
        0,
        1,
        7,
        1000,
        SOBOL_SAMPLES - 1,
        SOBOL_SAMPLES,
        SOBOL_SAMPLES + 5,
    ];
    for &s in &samples {
        for (seed, px, py) in [(1u64, 0u32, 0u32), (7, 3, 5), (12345, 250, 17)] {
            let mut sampler = PixelSampler::new(seed, px, py, s);
            // Every vertex up to past the Sobol range, each drawing 0–13 numbers.
            for vertex in 0..SOBOL_VERTICES + 4 {
                if vertex > 0 {
                    sampler.start_vertex();
                }
                let n = rng.next_u32() % 14;
                for j in 0..n {
                    let got = sampler.next_1d();
                    let want = reference(seed, px, py, s, vertex, j);
                    assert_eq!(
                        got.to_bits(),
                        want.to_bits(),
                        "seed {seed} pixel ({px}, {py}) sample {s} vertex {vertex} draw {j}"
                    );
                }
                assert_eq!(sampler.position(), (vertex, n));
            }
        }
    }
}

/// HG by the plain form: 1 − μ and 1 + μ both computed and clamped, then the
/// cancellation-free denominator for the sign of g.
fn hg_reference(g: f32, wo: Vec3, wi: Vec3) -> f32 {
    let a = (0.5 * (wo + wi).length_squared()).clamp(0.0, 2.0);
    let b = (0.5 * (wo - wi).length_squared()).clamp(0.0, 2.0);
    let delta = if g >= 0.0 {
        (1.0 - g) * (1.0 - g) + 2.0 * g * a
    } else {
        (1.0 + g) * (1.0 + g) - 2.0 * g * b
    };
    let v = (1.0 - g) * (1.0 + g) * velour::math::INV_4PI / (delta * delta.sqrt());
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

#[test]
fn hg_value_and_direction_match_their_plain_forms() {
    let mut rng = Rng::new(5, 9);
    for &g in &[-0.99f32, -0.6, -0.1, 0.0, 0.3, 0.6, 0.99] {
        let phase = PhaseFunction::henyey_greenstein(g).unwrap();
        for _ in 0..2_000 {
            let wo = velour::sampling::sample_uniform_sphere(rng.next_2d());
            let u = Vec2::new(rng.next_f32(), rng.next_f32());
            let s = phase.sample(wo, u);
            assert_eq!(phase.sample_direction(wo, u), s.wi, "g {g}");
            for wi in [s.wi, velour::sampling::sample_uniform_sphere(rng.next_2d())] {
                assert_eq!(
                    phase.eval(wo, wi).to_bits(),
                    hg_reference(g, wo, wi).to_bits(),
                    "g {g} wo {wo:?} wi {wi:?}"
                );
            }
        }
    }
}
