//! The film's exact accumulator state as EXR `UINT` channels, for part files and checkpoints:
//! a film restored from them continues (or merges) to the same bits as an uninterrupted render.
//!
//! Channels (all 32-bit unsigned, little-endian words of the integers in [`super::pixel`]):
//! `state.n`, `state.hits`; `state.sum.{R,G,B}.w0..w5` and `state.sq.{R,G,B}.w0..w5` (the
//! 192-bit radiance sums and sums of squares); `state.albedo.{R,G,B}.w0..w1` and
//! `state.normal.{X,Y,Z}.w0..w1` (64-bit); `state.depth.w0..w3` (128-bit).

use std::collections::BTreeMap;

use super::fixed::Fixed192;
use super::pixel::Pixel;
use super::FilmError;

/// Prefix of every state channel.
pub const STATE_PREFIX: &str = "state.";

const RGB: [&str; 3] = ["R", "G", "B"];
const XYZ: [&str; 3] = ["X", "Y", "Z"];

fn names(base: &str, words: usize) -> Vec<String> {
    (0..words).map(|w| format!("{base}.w{w}")).collect()
}

/// Every state channel of `pixels`, by name.
pub(super) fn encode(pixels: &[Pixel]) -> BTreeMap<String, Vec<u32>> {
    let mut out = BTreeMap::new();
    let mut put = |name: String, f: &dyn Fn(&Pixel) -> u32| {
        out.insert(name, pixels.iter().map(f).collect::<Vec<u32>>());
    };
    put(format!("{STATE_PREFIX}n"), &|p| p.n);
    put(format!("{STATE_PREFIX}hits"), &|p| p.hits);
    for c in 0..3 {
        for (w, name) in names(&format!("{STATE_PREFIX}sum.{}", RGB[c]), 6)
            .into_iter()
            .enumerate()
        {
            put(name, &|p| p.sum[c].to_words()[w]);
        }
        for (w, name) in names(&format!("{STATE_PREFIX}sq.{}", RGB[c]), 6)
            .into_iter()
            .enumerate()
        {
            put(name, &|p| p.sum_sq[c].to_words()[w]);
        }
        for (w, name) in names(&format!("{STATE_PREFIX}albedo.{}", RGB[c]), 2)
            .into_iter()
            .enumerate()
        {
            put(name, &|p| (p.albedo[c] as u64 >> (32 * w)) as u32);
        }
        for (w, name) in names(&format!("{STATE_PREFIX}normal.{}", XYZ[c]), 2)
            .into_iter()
            .enumerate()
        {
            put(name, &|p| (p.normal[c] as u64 >> (32 * w)) as u32);
        }
    }
    for (w, name) in names(&format!("{STATE_PREFIX}depth"), 4)
        .into_iter()
        .enumerate()
    {
        put(name, &|p| (p.depth as u128 >> (32 * w)) as u32);
    }
    out
}

/// Whether an image carries film state channels at all.
pub(super) fn present(channels: &BTreeMap<String, Vec<u32>>) -> bool {
    channels.contains_key(&format!("{STATE_PREFIX}n"))
}

/// Restores `pixels` (already sized) from the state channels; errors name a missing channel.
pub(super) fn decode(
    channels: &BTreeMap<String, Vec<u32>>,
    pixels: &mut [Pixel],
) -> Result<(), FilmError> {
    let len = pixels.len();
    let get = |name: &str| -> Result<&[u32], FilmError> {
        channels
            .get(name)
            .map(Vec::as_slice)
            .filter(|v| v.len() == len)
            .ok_or_else(|| {
                FilmError::Restore(format!(
                    "state channel {name} is missing or of the wrong length"
                ))
            })
    };
    let words = |base: String, k: usize| -> Result<Vec<&[u32]>, FilmError> {
        names(&base, k).iter().map(|n| get(n)).collect()
    };
    let n = get(&format!("{STATE_PREFIX}n"))?;
    let hits = get(&format!("{STATE_PREFIX}hits"))?;
    let mut sum = Vec::new();
    let mut sq = Vec::new();
    let mut albedo = Vec::new();
    let mut normal = Vec::new();
    for c in 0..3 {
        sum.push(words(format!("{STATE_PREFIX}sum.{}", RGB[c]), 6)?);
        sq.push(words(format!("{STATE_PREFIX}sq.{}", RGB[c]), 6)?);
        albedo.push(words(format!("{STATE_PREFIX}albedo.{}", RGB[c]), 2)?);
        normal.push(words(format!("{STATE_PREFIX}normal.{}", XYZ[c]), 2)?);
    }
    let depth = words(format!("{STATE_PREFIX}depth"), 4)?;
    for (i, p) in pixels.iter_mut().enumerate() {
        p.n = n[i];
        p.hits = hits[i];
        if p.hits > p.n {
            return Err(FilmError::Restore(format!(
                "pixel {i} has {} hits among {} samples",
                p.hits, p.n
            )));
        }
        for c in 0..3 {
            p.sum[c] = Fixed192::from_words(std::array::from_fn(|w| sum[c][w][i]));
            p.sum_sq[c] = Fixed192::from_words(std::array::from_fn(|w| sq[c][w][i]));
            if p.sum_sq[c].is_negative() {
                return Err(FilmError::Restore(format!(
                    "pixel {i} has a negative sum of squares"
                )));
            }
            p.albedo[c] = (u64::from(albedo[c][0][i]) | u64::from(albedo[c][1][i]) << 32) as i64;
            p.normal[c] = (u64::from(normal[c][0][i]) | u64::from(normal[c][1][i]) << 32) as i64;
        }
        p.depth = (0..4).fold(0u128, |acc, w| acc | u128::from(depth[w][i]) << (32 * w)) as i128;
    }
    Ok(())
}
