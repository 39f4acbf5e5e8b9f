//! The per-pixel sampler: every number is a function of (seed, pixel, sample, vertex, draw);
//! the Sobol block of each vertex is stratified across a pixel's samples whatever the earlier
//! vertices consumed; hashed numbers are uniform; vertices are not correlated.

mod common;

use common::chi2::p_value;
use velour::sampling::{PixelSampler, SOBOL_VERTICES, VERTEX_SOBOL_DIMENSIONS};

/// The numbers of sample `s` of pixel (3, 5): `per_vertex[k]` draws at vertex k (0 = camera).
fn draws(seed: u64, s: u32, per_vertex: &[u32]) -> Vec<Vec<f32>> {
    let mut sampler = PixelSampler::new(seed, 3, 5, s);
    let mut out = Vec::new();
    for (k, &n) in per_vertex.iter().enumerate() {
        if k > 0 {
            sampler.start_vertex();
        }
        out.push((0..n).map(|_| sampler.next_1d()).collect());
    }
    out
}

#[test]
fn numbers_are_a_function_of_seed_pixel_sample_and_position() {
    let a = draws(7, 11, &[4, 20, 3, 40]);
    let b = draws(7, 11, &[4, 20, 3, 40]);
    assert_eq!(a, b);
    // What a vertex draws does not depend on how much the previous vertex drew.
    let c = draws(7, 11, &[4, 2, 3, 40]);
    assert_eq!(a[2], c[2]);
    assert_eq!(a[3], c[3]);
    assert_ne!(
        draws(8, 11, &[4, 20])[1],
        a[1],
        "the seed changes the numbers"
    );
    assert_ne!(
        draws(7, 12, &[4, 20])[1],
        a[1],
        "the sample changes the numbers"
    );
    for v in a.iter().flatten() {
        assert!((0.0..1.0).contains(v), "{v}");
    }
}

#[test]
fn each_vertex_sobol_block_is_stratified_across_samples() {
    // Owen-scrambled Sobol: over 2^m samples every dimension puts exactly one point in each
    // interval [i/2^m, (i+1)/2^m).
    let n = 256u32;
    for vertex in [1usize, 2, 7, SOBOL_VERTICES as usize] {
        // Earlier vertices draw a varying number of values (a tracking walk).
        let samples: Vec<Vec<f32>> = (0..n)
            .map(|s| {
                let mut per_vertex = vec![3 + (s % 5) * 7; vertex + 1];
                per_vertex[vertex] = VERTEX_SOBOL_DIMENSIONS;
                draws(1, s, &per_vertex).swap_remove(vertex)
            })
            .collect();
        for d in 0..VERTEX_SOBOL_DIMENSIONS as usize {
            let mut cells = vec![0u32; n as usize];
            for s in &samples {
                cells[(s[d] * n as f32) as usize] += 1;
            }
            assert!(
                cells.iter().all(|&c| c == 1),
                "vertex {vertex}, dimension {d} is not stratified"
            );
        }
    }
}

/// Chi-square p-value of `values` against the uniform distribution on 64 cells.
fn uniformity_p(values: &[f32]) -> f64 {
    let mut cells = [0u32; 64];
    for v in values {
        cells[(v * 64.0) as usize] += 1;
    }
    let expected = values.len() as f64 / 64.0;
    let stat: f64 = cells
        .iter()
        .map(|&c| (c as f64 - expected).powi(2) / expected)
        .sum();
    p_value(stat, 63)
}

#[test]
fn hashed_numbers_are_uniform_and_vertices_uncorrelated() {
    // Draws beyond the Sobol block, and vertices beyond the Sobol vertices, are hashed.
    let deep = SOBOL_VERTICES as usize + 3;
    let n = 40_000u32;
    let mut tail = Vec::new();
    let mut deep_values = Vec::new();
    let (mut sxy, mut sx, mut sy, mut sxx, mut syy) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    for s in 0..n {
        let mut per_vertex = vec![2u32; deep + 1];
        per_vertex[1] = VERTEX_SOBOL_DIMENSIONS + 4;
        let d = draws(5, s, &per_vertex);
        tail.extend_from_slice(&d[1][VERTEX_SOBOL_DIMENSIONS as usize..]);
        deep_values.push(d[deep][0]);
        let (x, y) = (f64::from(d[1][0]), f64::from(d[2][0]));
        sxy += x * y;
        sx += x;
        sy += y;
        sxx += x * x;
        syy += y * y;
    }
    let p_tail = uniformity_p(&tail);
    let p_deep = uniformity_p(&deep_values);
    assert!(p_tail > 1e-4, "hashed draws of a vertex: p = {p_tail}");
    assert!(p_deep > 1e-4, "a deep vertex: p = {p_deep}");
    // Correlation of the first numbers of two consecutive vertices: |r|·√n is standard normal.
    let nf = f64::from(n);
    let cov = sxy / nf - (sx / nf) * (sy / nf);
    let r = cov / ((sxx / nf - (sx / nf).powi(2)) * (syy / nf - (sy / nf).powi(2))).sqrt();
    assert!(
        r.abs() * nf.sqrt() < 4.5,
        "vertex 1 and 2 correlate: r = {r}"
    );
}

#[test]
fn samples_past_the_sobol_range_stay_uniform_and_distinct() {
    let first = 1u32 << 16;
    let values: Vec<f32> = (first..first + 20_000)
        .map(|s| draws(2, s, &[1, 1])[1][0])
        .collect();
    let p = uniformity_p(&values);
    assert!(p > 1e-4, "p = {p}");
    let mut sorted = values.clone();
    sorted.sort_by(f32::total_cmp);
    sorted.dedup();
    assert!(
        sorted.len() > 19_900,
        "too many repeated values: {}",
        sorted.len()
    );
}
