//! EXR and PNG files: round trip of every film layer, foreign layouts (f16 / u32 channels,
//! multiple parts), corrupt and truncated files, PNG previews and environment maps.

mod common;

use std::path::Path;

use common::files::TempDir;
use velour::film::{Film, PixelSample};
use velour::image_io::{
    read_exr, read_exr_bytes, read_latlong_exr, srgb_oetf, temp_path, write_exr, write_png_rgb,
    ExrImage, ImageError,
};
use velour::math::Vec3;
use velour::sampling::Rng;
use velour::spectrum::Rgb;

fn noisy_film(w: u32, h: u32, spp: u32) -> Film {
    let mut film = Film::new(w, h).unwrap();
    let mut rng = Rng::new(7, 0);
    for y in 0..h {
        for x in 0..w {
            for _ in 0..spp {
                film.add_sample(
                    x,
                    y,
                    &PixelSample {
                        radiance: Rgb::new(rng.next_f32(), rng.next_f32() * 4.0, x as f32),
                        albedo: Rgb::new(rng.next_f32(), 0.5, y as f32 / h as f32),
                        normal: Vec3::new(rng.next_f32(), -1.0, 0.25),
                        depth: if x == 0 {
                            f32::INFINITY
                        } else {
                            2.0 + rng.next_f32()
                        },
                        lights: [Rgb::ZERO; velour::film::MAX_LIGHT_LAYERS],
                    },
                );
            }
        }
    }
    film
}

#[test]
fn every_film_layer_round_trips_through_exr() {
    let dir = TempDir::new("exr-layers");
    let (w, h) = (13, 6);
    let film = noisy_film(w, h, 5);
    let path = dir.join("layers.exr");
    film.write_exr(&path).unwrap();
    assert!(
        !temp_path(&path).exists(),
        "the temporary file is renamed away"
    );
    let img = read_exr(&path).unwrap();
    assert_eq!((img.width, img.height), (w, h));
    let names: Vec<&str> = img.channels.keys().map(String::as_str).collect();
    assert_eq!(
        names,
        [
            "B",
            "G",
            "R",
            "albedo.B",
            "albedo.G",
            "albedo.R",
            "depth.Z",
            "normal.X",
            "normal.Y",
            "normal.Z",
            "samples.N",
            "variance.B",
            "variance.G",
            "variance.R"
        ]
    );
    let beauty = img.rgb("").unwrap();
    let variance = img.rgb("variance").unwrap();
    let albedo = img.rgb("albedo").unwrap();
    let normal = img.rgb("normal").unwrap(); // falls back to X/Y/Z
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            assert_eq!(beauty[i], film.mean(x, y));
            assert_eq!(variance[i], film.variance_of_mean(x, y));
            assert_eq!(albedo[i], film.albedo(x, y));
            assert_eq!(normal[i].0, film.normal(x, y).to_array());
            assert_eq!(
                img.channel("depth.Z").unwrap()[i].to_bits(),
                film.depth(x, y).to_bits()
            );
            assert_eq!(img.channel("samples.N").unwrap()[i], 5.0);
        }
    }
    assert_eq!(img.channel("depth.Z").unwrap()[0], f32::INFINITY);
    assert_eq!(
        img.layers(),
        ["", "albedo", "depth", "normal", "samples", "variance"]
    );

    // And the generic writer reproduces the same image.
    let path2 = dir.join("layers2.exr");
    write_exr(&path2, &img).unwrap();
    let again = read_exr(&path2).unwrap();
    assert_eq!(again, img);
}

#[test]
fn foreign_layouts_f16_u32_and_multiple_parts_are_read() {
    let dir = TempDir::new("exr-foreign");
    use exr::prelude::*;
    let (w, h) = (7usize, 3usize);
    let r: Vec<f16> = (0..w * h).map(|i| f16::from_f32(i as f32 * 0.5)).collect();
    let g: Vec<f16> = (0..w * h).map(|i| f16::from_f32(-(i as f32))).collect();
    let b: Vec<f16> = (0..w * h).map(|_| f16::from_f32(0.333)).collect();
    let id: Vec<u32> = (0..w * h).map(|i| i as u32 * 1000).collect();
    let z: Vec<f32> = (0..w * h).map(|i| i as f32 + 0.125).collect();
    let main = Layer::new(
        (w, h),
        LayerAttributes::named("main"),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(vec![
            AnyChannel::new("R", FlatSamples::F16(r.clone())),
            AnyChannel::new("G", FlatSamples::F16(g)),
            AnyChannel::new("B", FlatSamples::F16(b)),
            AnyChannel::new("id", FlatSamples::U32(id)),
        ])),
    );
    let second = Layer::new(
        (w, h),
        LayerAttributes::named("extra"),
        Encoding::UNCOMPRESSED,
        AnyChannels::sort(SmallVec::from_vec(vec![AnyChannel::new(
            "Z",
            FlatSamples::F32(z),
        )])),
    );
    let path = dir.join("foreign.exr");
    Image::from_layers(
        ImageAttributes::new(IntegerBounds::from_dimensions((w, h))),
        vec![main, second],
    )
    .write()
    .to_file(&path)
    .unwrap();
    let img = read_exr(&path).unwrap();
    assert_eq!((img.width, img.height), (w as u32, h as u32));
    let rgb = img.rgb("").unwrap();
    assert_eq!(rgb[5], Rgb::new(2.5, -5.0, f16::from_f32(0.333).to_f32()));
    // Integer channels are kept exact, apart from the float ones.
    assert_eq!(img.uint_channels["id"][20], 20_000);
    assert!(img.channel("id").is_none());
    assert_eq!(img.channel("extra.Z").unwrap()[3], 3.125);
    assert_eq!(r[6].to_f32(), img.channel("R").unwrap()[6]);
}

fn good_exr_bytes() -> Vec<u8> {
    let dir = TempDir::new("exr-good");
    let path = dir.join("good.exr");
    noisy_film(9, 5, 3).write_exr(&path).unwrap();
    std::fs::read(&path).unwrap()
}

#[test]
fn truncated_exr_is_an_error_naming_the_file_at_every_length() {
    let bytes = good_exr_bytes();
    let name = Path::new("cut.exr");
    assert!(read_exr_bytes(name, &bytes).is_ok());
    for len in 0..bytes.len() {
        match read_exr_bytes(name, &bytes[..len]) {
            Ok(_) => panic!(
                "a file truncated to {len} of {} bytes was accepted",
                bytes.len()
            ),
            Err(e) => assert!(e.to_string().contains("cut.exr"), "{e}"),
        }
    }
}

#[test]
fn corrupt_exr_never_panics() {
    let bytes = good_exr_bytes();
    let name = Path::new("flipped.exr");
    let mut rng = Rng::new(3, 3);
    let (mut ok, mut err) = (0, 0);
    for pos in 0..bytes.len() {
        for pattern in [0xffu8, 0x80, 0x01, (rng.next_u32() as u8) | 1] {
            let mut b = bytes.clone();
            b[pos] ^= pattern;
            match read_exr_bytes(name, &b) {
                Ok(img) => {
                    ok += 1;
                    for v in img.channels.values() {
                        assert_eq!(v.len(), img.width as usize * img.height as usize);
                    }
                }
                Err(e) => {
                    err += 1;
                    assert!(e.to_string().contains("flipped.exr"), "{e}");
                }
            }
        }
    }
    // Random garbage, and garbage behind a valid magic number.
    for k in 0..200 {
        let len = 4 + (rng.next_u32() % 600) as usize;
        let mut b: Vec<u8> = (0..len).map(|_| rng.next_u32() as u8).collect();
        if k % 2 == 0 {
            b[..4].copy_from_slice(&[0x76, 0x2f, 0x31, 0x01]);
        }
        assert!(read_exr_bytes(name, &b).is_err());
    }
    assert!(err > 0 && ok + err == 4 * bytes.len());
}

#[test]
fn missing_file_is_an_io_error_naming_it() {
    let e = read_exr(Path::new("/nonexistent/dir/none.exr")).unwrap_err();
    assert!(matches!(e, ImageError::Io { .. }));
    assert!(e.to_string().contains("none.exr"));
}

#[test]
fn writer_rejects_inconsistent_images() {
    let dir = TempDir::new("exr-rejects");
    let mut img = ExrImage::new(4, 4);
    assert!(
        write_exr(&dir.join("empty.exr"), &img).is_err(),
        "no channels"
    );
    img.channels.insert("R".into(), vec![0.0; 15]);
    assert!(
        write_exr(&dir.join("short.exr"), &img).is_err(),
        "wrong length"
    );
    let img = ExrImage::new(0, 4);
    assert!(write_exr(&dir.join("zero.exr"), &img).is_err());
    assert!(!dir.join("short.exr").exists() && !temp_path(&dir.join("short.exr")).exists());
}

#[test]
fn png_preview_has_the_right_size_and_srgb_values() {
    let dir = TempDir::new("png-preview");
    let (w, h) = (11, 4);
    let mut film = Film::new(w, h).unwrap();
    for y in 0..h {
        for x in 0..w {
            let v = x as f32 / (w - 1) as f32;
            film.add_sample(
                x,
                y,
                &PixelSample {
                    radiance: Rgb::new(v, 0.25 * v, 2.0),
                    albedo: Rgb::ZERO,
                    normal: Vec3::ZERO,
                    depth: 1.0,
                    lights: [Rgb::ZERO; velour::film::MAX_LIGHT_LAYERS],
                },
            );
        }
    }
    let path = dir.join("preview.png");
    film.write_png(&path, 1.0).unwrap(); // one stop up: x2
    let png = image::open(&path).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (w, h));
    for x in 0..w {
        let v = x as f32 / (w - 1) as f32;
        let expect = |l: f32| (srgb_oetf(2.0 * l) * 255.0).round() as u8;
        let p = png.get_pixel(x, 2).0;
        assert_eq!(p, [expect(v), expect(0.25 * v), 255], "pixel {x}");
    }
    assert_eq!(srgb_oetf(0.0), 0.0);
    assert!((srgb_oetf(1.0) - 1.0).abs() < 1e-6);
    assert!((srgb_oetf(0.002) - 0.02584).abs() < 1e-6, "linear segment");
    assert!((srgb_oetf(0.5) - 0.735_356_7).abs() < 1e-5);
    assert!(write_png_rgb(&dir.join("bad.png"), 3, 3, &[Rgb::ZERO; 8], 0.0).is_err());
}

#[test]
fn latlong_maps_are_read_and_bad_texels_named() {
    let dir = TempDir::new("exr-latlong");
    let (w, h) = (8u32, 4u32);
    let mut img = ExrImage::new(w, h);
    let texels: Vec<Rgb> = (0..w * h).map(|i| Rgb::new(i as f32, 1.0, 0.5)).collect();
    img.insert_rgb("", &texels);
    let path = dir.join("env.exr");
    write_exr(&path, &img).unwrap();
    let map = read_latlong_exr(&path).unwrap();
    assert_eq!((map.width, map.height), (w, h));
    assert_eq!(map.texels, texels);

    let mut bad = img.clone();
    bad.channels.get_mut("G").unwrap()[2 * w as usize + 5] = -0.5;
    bad.channels.get_mut("B").unwrap()[3 * w as usize] = f32::NAN;
    write_exr(&path, &bad).unwrap();
    let e = read_latlong_exr(&path).unwrap_err();
    match &e {
        ImageError::BadTexel { x, y, channel, .. } => assert_eq!((*x, *y, *channel), (5, 2, "G")),
        other => panic!("unexpected error {other}"),
    }
    assert!(
        e.to_string().contains("env.exr") && e.to_string().contains("x 5, y 2"),
        "{e}"
    );

    let mut missing = img.clone();
    missing.channels.remove("B");
    write_exr(&path, &missing).unwrap();
    let e = read_latlong_exr(&path).unwrap_err();
    assert!(
        e.to_string().contains("env.exr") && e.to_string().contains("R, G and B"),
        "{e}"
    );
}

#[test]
fn a_failed_write_keeps_the_previous_file_whole() {
    // The write goes to `<path>.tmp` and is renamed only when complete; when the temporary
    // file cannot be written (here a directory is in its way, as a full disk would stop it),
    // the previous file is untouched and no temporary file is left behind.
    let dir = TempDir::new("exr-atomic");
    let path = dir.join("frame.partial.exr");
    let old = noisy_film(4, 3, 2);
    old.write_exr(&path).unwrap();
    let before = std::fs::read(&path).unwrap();
    let tmp = velour::image_io::temp_path(&path);
    std::fs::create_dir(&tmp).unwrap();
    let new = noisy_film(4, 3, 5);
    assert!(new.write_exr(&path).is_err());
    assert_eq!(
        std::fs::read(&path).unwrap(),
        before,
        "the previous file changed"
    );
    std::fs::remove_dir(&tmp).unwrap();
    new.write_exr(&path).unwrap();
    assert!(!tmp.exists());
    assert_ne!(std::fs::read(&path).unwrap(), before);
}
