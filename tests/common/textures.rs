//! Small texture files written by tests into their temporary directories (no binary test
//! data is committed): 8- and 16-bit PNGs and float EXRs from a function of the pixel.

use std::path::Path;

use velour::image_io::{write_exr, ExrImage};

/// An 8-bit RGB PNG whose pixel (x, y) (y = 0 is the top row) is `f(x, y)`.
pub fn png_rgb8(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) {
    let mut buf = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h {
        for x in 0..w {
            buf.extend(f(x, y));
        }
    }
    image::save_buffer(path, &buf, w, h, image::ExtendedColorType::Rgb8)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// A 16-bit grey PNG whose pixel (x, y) is `f(x, y)`.
pub fn png_grey16(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> u16) {
    let mut data = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            data.push(f(x, y));
        }
    }
    let img: image::ImageBuffer<image::Luma<u16>, Vec<u16>> =
        image::ImageBuffer::from_raw(w, h, data).expect("buffer size");
    img.save(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// A float EXR with channels R, G, B whose pixel (x, y) is `f(x, y)`.
pub fn exr_rgb(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) {
    let mut img = ExrImage::new(w, h);
    let mut ch = [Vec::new(), Vec::new(), Vec::new()];
    for y in 0..h {
        for x in 0..w {
            let v = f(x, y);
            for c in 0..3 {
                ch[c].push(v[c]);
            }
        }
    }
    for (name, values) in ["R", "G", "B"].iter().zip(ch) {
        img.channels.insert((*name).to_string(), values);
    }
    write_exr(path, &img).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// A float EXR with one channel `Y` whose pixel (x, y) is `f(x, y)`.
pub fn exr_grey(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> f32) {
    let mut img = ExrImage::new(w, h);
    let mut values = Vec::new();
    for y in 0..h {
        for x in 0..w {
            values.push(f(x, y));
        }
    }
    img.channels.insert("Y".to_string(), values);
    write_exr(path, &img).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}
