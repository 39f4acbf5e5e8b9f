//! Damaged files: every fixture truncated at many offsets and with flipped bytes must give an
//! error (truncation) or a result (some flips are harmless), never a panic, and never a huge
//! allocation (a counting global allocator records the largest single request).

mod common;

use common::files::vdb_fixture;
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use velour::sampling::Rng;
use velour::vdb::{blosc, VdbFile};

struct Counting;
static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only records sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

const FIXTURES: [&str; 6] = [
    "noise_fbm.vdb",
    "noise_fbm_half.vdb",
    "sphere_fog.vdb",
    "tiles_internal.vdb",
    "velocity_vec3s.vdb",
    "xform_scaletranslate.vdb",
];

/// Reads every grid; `Ok(())` or the error text. Panics propagate (and fail the test).
fn try_read(name: &str, bytes: Vec<u8>) -> Result<(), String> {
    let f = VdbFile::from_bytes(name, bytes).map_err(|e| e.to_string())?;
    f.read_all().map_err(|e| e.to_string())?;
    Ok(())
}

/// Truncation offsets: every few bytes through the header, metadata and transform, then
/// spread over the rest of the file.
fn cut_points(len: usize, rng: &mut Rng) -> Vec<usize> {
    let mut v: Vec<usize> = (0..len.min(700)).step_by(7).collect();
    for _ in 0..40 {
        v.push((rng.next_f64() * len as f64) as usize);
    }
    v.push(len - 1);
    v
}

#[test]
fn truncated_and_flipped_files_give_errors_not_panics() {
    let mut rng = Rng::new(99, 0);
    let mut truncations = 0;
    let mut flips = 0;
    let mut flip_errors = 0;
    for name in FIXTURES {
        let path = vdb_fixture(name);
        let bytes = std::fs::read(&path).unwrap();
        assert!(try_read(name, bytes.clone()).is_ok());
        for cut in cut_points(bytes.len(), &mut rng) {
            let r = try_read(name, bytes[..cut].to_vec());
            let e = r.expect_err(&format!("{name} truncated to {cut} bytes was accepted"));
            assert!(e.contains(name), "error does not name the file: {e}");
            truncations += 1;
        }
        for _ in 0..30 {
            let mut b = bytes.clone();
            let at = (rng.next_f64() * b.len() as f64) as usize;
            let x = (rng.next_u32() % 255 + 1) as u8;
            b[at] ^= x;
            flips += 1;
            if try_read(name, b).is_err() {
                flip_errors += 1;
            }
        }
        // Flips concentrated in the header and descriptor, where sizes live.
        for at in (0..bytes.len().min(400)).step_by(8) {
            let mut b = bytes.clone();
            b[at] ^= 0x80;
            flips += 1;
            if try_read(name, b).is_err() {
                flip_errors += 1;
            }
        }
    }
    assert!(truncations > 500);
    assert!(
        flip_errors > flips / 4,
        "{flip_errors} of {flips} flips detected"
    );
    let largest = LARGEST.load(Ordering::Relaxed);
    assert!(
        largest < 64 << 20,
        "largest single allocation {largest} bytes"
    );
}

#[test]
fn blosc_frames_with_lying_headers_are_refused() {
    let data: Vec<u8> = (0..4096u32)
        .flat_map(|i| ((i as f32).sin()).to_le_bytes())
        .collect();
    let frame = blosc::compress(&data, 4);
    assert_eq!(blosc::decompress(&frame, data.len()).unwrap(), data);
    // Wrong expected size, claimed sizes beyond the frame, truncations, flips.
    assert!(blosc::decompress(&frame, data.len() + 4).is_err());
    let mut big = frame.clone();
    big[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(blosc::decompress(&big, data.len()).is_err());
    let mut lying = frame.clone();
    lying[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
    assert!(blosc::decompress(&lying, data.len()).is_err());
    for cut in 0..frame.len() {
        assert!(
            blosc::decompress(&frame[..cut], data.len()).is_err(),
            "cut {cut}"
        );
    }
    let mut rng = Rng::new(5, 0);
    for _ in 0..2000 {
        let mut f = frame.clone();
        let at = (rng.next_f64() * f.len() as f64) as usize;
        f[at] ^= (rng.next_u32() % 255 + 1) as u8;
        if let Ok(out) = blosc::decompress(&f, data.len()) {
            assert_eq!(out.len(), data.len());
        }
    }
    // Incompressible data is stored as a plain copy; empty input round-trips.
    let noise: Vec<u8> = (0..1000u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    assert_eq!(
        blosc::decompress(&blosc::compress(&noise, 4), 1000).unwrap(),
        noise
    );
    assert_eq!(
        blosc::decompress(&blosc::compress(&[], 4), 0).unwrap(),
        Vec::<u8>::new()
    );
}

/// Frames made by the real C-Blosc 1.21 (`tools/vdb/make_blosc_frames.py`): blosclz, lz4,
/// lz4hc and zlib, with and without shuffle, several type sizes, one or several blocks.
#[test]
fn real_blosc_frames_decode() {
    let path = vdb_fixture("blosc_frames.bin");
    let bytes = std::fs::read(path).unwrap();
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
    let mut pos = 4;
    let mut sets = Vec::new();
    for _ in 0..u32_at(0) {
        let n = u32_at(pos);
        sets.push(&bytes[pos + 4..pos + 4 + n]);
        pos += 4 + n;
    }
    let mut by_codec = std::collections::BTreeMap::new();
    let mut multi_block = 0;
    while pos < bytes.len() {
        let set = bytes[pos] as usize;
        let n = u32_at(pos + 1);
        let len = u32_at(pos + 5);
        let frame = &bytes[pos + 9..pos + 9 + len];
        pos += 9 + len;
        let raw = &sets[set][..n];
        let flags = frame[2];
        let got = blosc::decompress(frame, n)
            .unwrap_or_else(|e| panic!("codec {} flags {flags:#x}: {e}", flags >> 5));
        assert_eq!(got, raw, "codec {} flags {flags:#x}", flags >> 5);
        *by_codec
            .entry(if flags & 2 != 0 { 99 } else { flags >> 5 })
            .or_insert(0) += 1;
        let blocksize = u32::from_le_bytes(frame[8..12].try_into().unwrap()) as usize;
        multi_block += usize::from(blocksize < n);
    }
    // blosclz (0), lz4 and lz4hc (1), zlib (3), and plain copies (99) all seen.
    for c in [0u8, 1, 3, 99] {
        assert!(by_codec.get(&c).copied().unwrap_or(0) > 0, "{by_codec:?}");
    }
    assert!(multi_block > 10);
}
