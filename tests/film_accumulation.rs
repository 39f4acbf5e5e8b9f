//! Film accumulation: mean and variance against a direct two-pass computation, dropped
//! samples, size limits, tiles and the bit-identical result of any tile merge order.

mod common;

use std::collections::BTreeMap;

use common::files::TempDir;
use common::stats;
use velour::film::{Film, FilmError, FilmTile, PixelSample};
use velour::image_io::read_exr;
use velour::math::Vec3;
use velour::sampling::Rng;
use velour::spectrum::Rgb;

/// A deterministic, skewed sample for (pixel, sample index): radiance from an exponential-like
/// distribution with a pixel-dependent scale, plus AOVs.
fn sample(x: u32, y: u32, s: u32) -> PixelSample {
    let mut rng = Rng::new(0x5eed ^ u64::from(s), u64::from(y) << 32 | u64::from(x));
    let scale = 0.1 + (x as f32 * 0.37 + y as f32 * 0.11).sin().abs();
    let e = |u: f32| -(1.0 - u).ln() * scale;
    PixelSample {
        radiance: Rgb::new(
            e(rng.next_f32()),
            2.0 * e(rng.next_f32()),
            e(rng.next_f32()) + 0.5,
        ),
        albedo: Rgb::new(rng.next_f32(), 0.5, 0.25),
        normal: Vec3::new(0.0, 1.0, rng.next_f32() - 0.5),
        depth: if rng.next_f32() < 0.3 {
            f32::INFINITY
        } else {
            1.0 + rng.next_f32()
        },
        lights: [Rgb::ZERO; velour::film::MAX_LIGHT_LAYERS],
    }
}

#[test]
fn mean_and_variance_match_direct_computation() {
    let (w, h, spp) = (5, 4, 37);
    let mut film = Film::new(w, h).unwrap();
    for s in 0..spp {
        for y in 0..h {
            for x in 0..w {
                film.add_sample(x, y, &sample(x, y, s));
            }
        }
    }
    for y in 0..h {
        for x in 0..w {
            let xs: Vec<PixelSample> = (0..spp).map(|s| sample(x, y, s)).collect();
            let n = spp as f64;
            assert_eq!(film.samples(x, y), spp);
            for c in 0..3 {
                let radiance: Vec<f64> = xs.iter().map(|p| f64::from(p.radiance.0[c])).collect();
                let (mean, var) = (stats::mean(&radiance), stats::variance(&radiance));
                let got_mean = f64::from(film.mean(x, y).0[c]);
                let got_var = f64::from(film.variance_of_mean(x, y).0[c]);
                assert!(
                    (got_mean - mean).abs() <= 1e-6 * mean.abs(),
                    "mean {got_mean} vs {mean}"
                );
                assert!(
                    (got_var - var / n).abs() <= 1e-6 * var / n,
                    "variance of mean {got_var} vs {}",
                    var / n
                );
                let albedo = xs.iter().map(|p| f64::from(p.albedo.0[c])).sum::<f64>() / n;
                assert!((f64::from(film.albedo(x, y).0[c]) - albedo).abs() < 1e-6);
            }
            let hits: Vec<f64> = xs
                .iter()
                .filter(|p| p.depth.is_finite())
                .map(|p| f64::from(p.depth))
                .collect();
            let depth = stats::mean(&hits);
            assert!((f64::from(film.depth(x, y)) - depth).abs() < 1e-6);
            let nz = xs.iter().map(|p| f64::from(p.normal.z)).sum::<f64>() / n;
            assert!((f64::from(film.normal(x, y).z) - nz).abs() < 1e-6);
        }
    }
}

#[test]
fn constant_pixel_has_exactly_zero_variance_and_few_samples_give_zero() {
    let mut film = Film::new(2, 1).unwrap();
    let s = PixelSample {
        radiance: Rgb::new(0.1, 1e4, 3.3e-7),
        albedo: Rgb::ZERO,
        normal: Vec3::ZERO,
        depth: f32::INFINITY,
        lights: [Rgb::ZERO; velour::film::MAX_LIGHT_LAYERS],
    };
    for _ in 0..10_000 {
        film.add_sample(0, 0, &s);
    }
    film.add_sample(1, 0, &s);
    assert_eq!(film.mean(0, 0), s.radiance);
    assert_eq!(film.variance_of_mean(0, 0), Rgb::ZERO);
    assert_eq!(
        film.variance_of_mean(1, 0),
        Rgb::ZERO,
        "n = 1 has no variance estimate"
    );
    assert_eq!(film.depth(0, 0), f32::INFINITY, "no hit gives +inf depth");
    assert_eq!(film.samples(1, 0), 1);
}

#[test]
fn non_finite_and_outside_samples_are_dropped_and_counted() {
    let mut film = Film::new(3, 3).unwrap();
    let good = sample(1, 1, 0);
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut s = good;
        s.radiance.0[1] = bad;
        film.add_sample(1, 1, &s);
    }
    film.add_sample(3, 0, &good);
    film.add_sample(0, 7, &good);
    assert_eq!(film.dropped_samples(), 5);
    assert_eq!(film.samples(1, 1), 0);
    film.add_sample(1, 1, &good);
    assert_eq!(film.mean(1, 1), good.radiance);

    let mut tile = film.tile(0, 0, 2, 2).unwrap();
    let mut s = good;
    s.radiance.0[0] = f32::NAN;
    tile.add_sample(0, 0, &s);
    tile.add_sample(2, 0, &good); // outside the tile
    tile.add_sample(1, 1, &good);
    assert_eq!(tile.dropped_samples(), 2);
    film.merge_tile(&tile).unwrap();
    assert_eq!(film.dropped_samples(), 7);
    assert_eq!(film.samples(1, 1), 2);
    assert_eq!(film.total_samples(), 2);
}

#[test]
fn absurd_sizes_are_refused() {
    for (w, h) in [(0, 10), (10, 0), (65_537, 1), (1, 70_000), (65_536, 65_536)] {
        assert!(
            matches!(Film::new(w, h), Err(FilmError::BadSize { .. })),
            "{w}x{h} should be refused"
        );
    }
    assert!(Film::new(65_536, 1).is_ok());
    let film = Film::new(8, 8).unwrap();
    assert!(film.tile(8, 0, 4, 4).is_err());
    let t = film.tile(6, 6, 4, 4).unwrap();
    assert_eq!(
        (t.width(), t.height()),
        (2, 2),
        "tiles are clipped to the film"
    );
    let big = Film::new(16, 16).unwrap().tile(8, 8, 8, 8).unwrap();
    let mut small = Film::new(8, 8).unwrap();
    assert!(matches!(
        small.merge_tile(&big),
        Err(FilmError::TileOutside { .. })
    ));
}

/// Renders `passes` passes of `spp` samples each into tiles of `tile_size`, merging the tiles
/// of each pass in the order given by `order` (a permutation seed; 0 = row-major).
fn render_tiled(w: u32, h: u32, tile_size: u32, passes: u32, spp: u32, order: u64) -> Film {
    let mut film = Film::new(w, h).unwrap();
    for pass in 0..passes {
        let mut tiles: Vec<FilmTile> = film.tiles(tile_size).unwrap();
        for t in &mut tiles {
            for y in t.y0()..t.y0() + t.height() {
                for x in t.x0()..t.x0() + t.width() {
                    for s in pass * spp..(pass + 1) * spp {
                        t.add_sample(x, y, &sample(x, y, s));
                    }
                }
            }
        }
        if order != 0 {
            // Fisher-Yates with a fixed seed: a different merge order.
            let mut rng = Rng::new(order, u64::from(pass));
            for i in (1..tiles.len()).rev() {
                let j = (rng.next_u32() as usize) % (i + 1);
                tiles.swap(i, j);
            }
        }
        for t in &tiles {
            film.merge_tile(t).unwrap();
        }
    }
    film
}

fn exr_bits(film: &Film, name: &str) -> BTreeMap<String, Vec<u32>> {
    let dir = TempDir::new("film-bits");
    let path = dir.join(name);
    film.write_exr(&path).unwrap();
    let img = read_exr(&path).unwrap();
    img.channels
        .into_iter()
        .map(|(k, v)| (k, v.into_iter().map(f32::to_bits).collect()))
        .collect()
}

#[test]
fn tile_merge_order_and_tile_size_do_not_change_a_bit() {
    let (w, h) = (37, 23);
    let reference = exr_bits(&render_tiled(w, h, 8, 3, 4, 0), "ref.exr");
    assert_eq!(reference.len(), 14, "channels: {:?}", reference.keys());
    for (tile, order, name) in [
        (8, 1, "shuffled"),
        (8, 99, "shuffled2"),
        (5, 7, "tile5"),
        (64, 0, "one_tile"),
    ] {
        let other = exr_bits(&render_tiled(w, h, tile, 3, 4, order), name);
        assert!(
            other == reference,
            "tile size {tile}, order {order}: pixel data differ"
        );
    }
    // The film's sums are exact: a different pass split gives the same bits too.
    let film1 = exr_bits(&render_tiled(w, h, 8, 1, 12, 0), "one_pass.exr");
    assert!(film1 == reference, "1 pass of 12 vs 3 passes of 4");
}

#[test]
fn overlapping_tiles_merge_identically_in_any_order() {
    let make = |order: &[usize]| {
        let mut film = Film::new(10, 10).unwrap();
        let mut tiles = Vec::new();
        for (k, &(x0, y0)) in [(0u32, 0u32), (3, 2), (5, 5), (2, 6)].iter().enumerate() {
            let mut t = film.tile(x0, y0, 6, 4).unwrap();
            for y in y0..y0 + t.height() {
                for x in x0..x0 + t.width() {
                    for s in 0..3 {
                        t.add_sample(x, y, &sample(x, y, s + 10 * k as u32));
                    }
                }
            }
            tiles.push(t);
        }
        let ordered: Vec<FilmTile> = order.iter().map(|&i| tiles[i].clone()).collect();
        film.merge_tiles(ordered).unwrap();
        film
    };
    let a = make(&[0, 1, 2, 3]);
    let b = make(&[3, 1, 0, 2]);
    for y in 0..10 {
        for x in 0..10 {
            assert_eq!(
                a.mean(x, y).0.map(f32::to_bits),
                b.mean(x, y).0.map(f32::to_bits)
            );
            assert_eq!(
                a.variance_of_mean(x, y).0.map(f32::to_bits),
                b.variance_of_mean(x, y).0.map(f32::to_bits)
            );
        }
    }
    assert_eq!(a.samples(4, 3), 6, "pixel covered by two tiles");
}

#[test]
fn one_pass_of_tiles_equals_direct_accumulation() {
    let (w, h) = (9, 7);
    let mut direct = Film::new(w, h).unwrap();
    for y in 0..h {
        for x in 0..w {
            for s in 0..5 {
                direct.add_sample(x, y, &sample(x, y, s));
            }
        }
    }
    let tiled = render_tiled(w, h, 4, 1, 5, 3);
    assert!(exr_bits(&direct, "direct.exr") == exr_bits(&tiled, "tiled.exr"));
}

#[test]
fn film_restored_from_its_state_continues_to_the_same_bits() {
    let (w, h) = (6, 5);
    let film = render_tiled(w, h, 4, 2, 8, 0);
    let dir = TempDir::new("film-resume");
    let path = dir.join("resume.exr");
    let mut attrs = BTreeMap::new();
    attrs.insert("velour:spp".to_string(), "16".to_string());
    velour::image_io::write_exr(&path, &film.to_state_image(&attrs)).unwrap();
    let img = read_exr(&path).unwrap();
    assert_eq!(
        img.attributes.get("velour:spp").map(String::as_str),
        Some("16")
    );
    let mut resumed = Film::from_exr_image(&img).unwrap();
    let mut full = render_tiled(w, h, 4, 2, 8, 0);
    for y in 0..h {
        for x in 0..w {
            for s in 16..24 {
                resumed.add_sample(x, y, &sample(x, y, s));
                full.add_sample(x, y, &sample(x, y, s));
            }
        }
    }
    assert_eq!(resumed.samples(2, 3), 24);
    assert!(exr_bits(&resumed, "resumed.exr") == exr_bits(&full, "full.exr"));

    // Samples 0..8 and 8..24 rendered apart and merged: the same bits again.
    let mut early = Film::new(w, h).unwrap();
    let mut late = Film::new(w, h).unwrap();
    for y in 0..h {
        for x in 0..w {
            for s in 0..24 {
                let f = if s < 8 { &mut early } else { &mut late };
                f.add_sample(x, y, &sample(x, y, s));
            }
        }
    }
    late.merge_rows(&early, 0).unwrap();
    assert!(exr_bits(&late, "merged.exr") == exr_bits(&full, "full2.exr"));

    let mut incomplete = img.clone();
    incomplete.uint_channels.remove("state.sum.G.w3");
    assert!(matches!(
        Film::from_exr_image(&incomplete),
        Err(FilmError::Restore(m)) if m.contains("state.sum.G.w3")
    ));
    let mut beauty_only = img.clone();
    beauty_only.uint_channels.clear();
    assert!(matches!(
        Film::from_exr_image(&beauty_only),
        Err(FilmError::Restore(_))
    ));
}

/// Fills the tiles of each pass in parallel on a pool of `threads` threads and merges them in
/// completion order (whatever order the workers finish in).
fn render_parallel(w: u32, h: u32, threads: usize) -> Film {
    use rayon::prelude::*;
    use std::sync::Mutex;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let film = Mutex::new(Film::new(w, h).unwrap());
    for pass in 0..2u32 {
        let tiles = film.lock().unwrap().tiles(6).unwrap();
        pool.install(|| {
            tiles.into_par_iter().for_each(|mut t| {
                for y in t.y0()..t.y0() + t.height() {
                    for x in t.x0()..t.x0() + t.width() {
                        for s in pass * 3..(pass + 1) * 3 {
                            t.add_sample(x, y, &sample(x, y, s));
                        }
                    }
                }
                film.lock().unwrap().merge_tile(&t).unwrap();
            });
        });
    }
    film.into_inner().unwrap()
}

#[test]
fn thread_count_does_not_change_a_bit() {
    let (w, h) = (31, 17);
    let one = exr_bits(&render_parallel(w, h, 1), "par1.exr");
    let four = exr_bits(&render_parallel(w, h, 4), "par4.exr");
    let sequential = exr_bits(&render_tiled(w, h, 6, 2, 3, 0), "seq.exr");
    assert!(one == four && one == sequential);
}
