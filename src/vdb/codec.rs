//! Byte-level reading and the compressed value arrays of OpenVDB nodes
//! (`io::readCompressedValues` / `writeCompressedValues` in OpenVDB's terms).

use super::{blosc, ValueType, VdbError};
use half::f16;
use std::io::Read;
use std::path::Path;

/// Compression flag: zlib.
pub const COMPRESS_ZIP: u32 = 0x1;
/// Compression flag: only active values are stored (plus up to two inactive values and a
/// selection mask).
pub const COMPRESS_ACTIVE_MASK: u32 = 0x2;
/// Compression flag: blosc.
pub const COMPRESS_BLOSC: u32 = 0x4;

/// Per-node metadata byte of mask compression.
pub const NO_MASK_OR_INACTIVE_VALS: u8 = 0;
pub const NO_MASK_AND_MINUS_BG: u8 = 1;
pub const NO_MASK_AND_ONE_INACTIVE_VAL: u8 = 2;
pub const MASK_AND_NO_INACTIVE_VALS: u8 = 3;
pub const MASK_AND_ONE_INACTIVE_VAL: u8 = 4;
pub const MASK_AND_TWO_INACTIVE_VALS: u8 = 5;
pub const NO_MASK_AND_ALL_VALS: u8 = 6;

/// A bounds-checked little-endian reader over a byte slice that starts at file offset `base`.
pub struct Reader<'a> {
    pub data: &'a [u8],
    pub pos: usize,
    pub base: u64,
    pub path: &'a Path,
}

impl<'a> Reader<'a> {
    pub fn new(data: &'a [u8], base: u64, path: &'a Path) -> Self {
        Reader {
            data,
            pos: 0,
            base,
            path,
        }
    }
    pub fn offset(&self) -> u64 {
        self.base + self.pos as u64
    }
    pub fn err(&self, msg: impl Into<String>) -> VdbError {
        VdbError::Format {
            path: self.path.to_path_buf(),
            offset: self.offset(),
            msg: msg.into(),
        }
    }
    pub fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
    pub fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], VdbError> {
        if n > self.remaining() {
            return Err(self.err(format!(
                "unexpected end of data reading {what} ({n} bytes needed, {} left)",
                self.remaining()
            )));
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    pub fn u8(&mut self, what: &str) -> Result<u8, VdbError> {
        Ok(self.take(1, what)?[0])
    }
    pub fn u32(&mut self, what: &str) -> Result<u32, VdbError> {
        let b = self.take(4, what)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    pub fn i32(&mut self, what: &str) -> Result<i32, VdbError> {
        Ok(self.u32(what)? as i32)
    }
    pub fn i64(&mut self, what: &str) -> Result<i64, VdbError> {
        let b = self.take(8, what)?;
        Ok(i64::from_le_bytes([
            b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7],
        ]))
    }
    pub fn f64(&mut self, what: &str) -> Result<f64, VdbError> {
        Ok(f64::from_bits(self.i64(what)? as u64))
    }
    pub fn dvec3(&mut self, what: &str) -> Result<glam::DVec3, VdbError> {
        Ok(glam::DVec3::new(
            self.f64(what)?,
            self.f64(what)?,
            self.f64(what)?,
        ))
    }
    pub fn string(&mut self, what: &str) -> Result<String, VdbError> {
        let n = self.u32(what)? as usize;
        let b = self.take(n, what)?;
        Ok(String::from_utf8_lossy(b).into_owned())
    }
    pub fn bytes_string(&mut self, what: &str) -> Result<Vec<u8>, VdbError> {
        let n = self.u32(what)? as usize;
        Ok(self.take(n, what)?.to_vec())
    }
    pub fn mask(&mut self, words: usize, out: &mut [u64], what: &str) -> Result<(), VdbError> {
        let b = self.take(words * 8, what)?;
        for (o, c) in out[..words].iter_mut().zip(b.chunks_exact(8)) {
            *o = u64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]);
        }
        Ok(())
    }
    /// Reads one value of `vt` at full precision into `out` (components as f32).
    pub fn value(&mut self, vt: ValueType, out: &mut [f32; 3], what: &str) -> Result<(), VdbError> {
        let n = vt.components();
        let b = self.take(n * vt.component_bytes(), what)?;
        decode(vt, false, b, &mut out[..n]);
        Ok(())
    }
}

/// Decodes raw little-endian values (f32, f64 or f16 components) into f32 components.
pub fn decode(vt: ValueType, half: bool, bytes: &[u8], out: &mut [f32]) {
    if half {
        for (o, c) in out.iter_mut().zip(bytes.chunks_exact(2)) {
            *o = f16::from_bits(u16::from_le_bytes([c[0], c[1]])).to_f32();
        }
    } else if vt.component_bytes() == 8 {
        for (o, c) in out.iter_mut().zip(bytes.chunks_exact(8)) {
            *o = f64::from_le_bytes([c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]]) as f32;
        }
    } else {
        for (o, c) in out.iter_mut().zip(bytes.chunks_exact(4)) {
            *o = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
        }
    }
}

/// Reads one data buffer of exactly `nbytes` uncompressed bytes (OpenVDB's `readData`):
/// blosc and zip buffers start with an `i64` size, negative for a stored (uncompressed) buffer.
/// Returns the bytes when stored raw in the file, `None` when they were decompressed into
/// `scratch`.
pub fn read_data<'a>(
    r: &mut Reader<'a>,
    nbytes: usize,
    compression: u32,
    scratch: &mut Vec<u8>,
    tmp: &mut Vec<u8>,
) -> Result<Option<&'a [u8]>, VdbError> {
    if compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
        return r.take(nbytes, "node values").map(Some);
    }
    let at = r.offset();
    let size = r.i64("compressed buffer size")?;
    if size <= 0 {
        let n = size.unsigned_abs();
        if n != nbytes as u64 {
            return Err(VdbError::Format {
                path: r.path.to_path_buf(),
                offset: at,
                msg: format!("stored buffer of {n} bytes where {nbytes} were expected"),
            });
        }
        return r.take(nbytes, "stored node values").map(Some);
    }
    let size = usize::try_from(size).unwrap_or(usize::MAX);
    let src = r.take(size, "compressed node values")?;
    let fail = |msg: String| VdbError::Format {
        path: r.path.to_path_buf(),
        offset: at,
        msg,
    };
    if compression & COMPRESS_BLOSC != 0 {
        blosc::decompress_into(src, nbytes, scratch, tmp).map_err(fail)?;
    } else {
        scratch.clear();
        scratch.resize(nbytes, 0);
        let mut d = flate2::read::ZlibDecoder::new(src);
        let mut filled = 0;
        while filled < nbytes {
            match d.read(&mut scratch[filled..]) {
                Ok(0) => break,
                Ok(k) => filled += k,
                Err(e) => return Err(fail(format!("zlib: {e}"))),
            }
        }
        let mut extra = [0u8; 1];
        let more = d.read(&mut extra).unwrap_or(0);
        if filled != nbytes || more != 0 {
            return Err(fail(format!(
                "zip buffer does not hold the expected {nbytes} bytes"
            )));
        }
    }
    Ok(None)
}

/// Context for reading the value arrays of one grid.
#[derive(Clone)]
pub struct ValueCodec {
    pub vt: ValueType,
    pub half: bool,
    pub compression: u32,
    pub background: [f32; 3],
    pub scratch: Vec<u8>,
    pub tmp: Vec<u8>,
    pub temp: Vec<f32>,
}

impl ValueCodec {
    /// Skips the value array of a node (as [`ValueCodec::read_values`] would read it)
    /// without decompressing it.
    pub fn skip_values(
        &self,
        r: &mut Reader<'_>,
        count: usize,
        mask: &[u64],
    ) -> Result<(), VdbError> {
        let n = self.vt.components();
        let cb = self.vt.component_bytes();
        let meta = r.u8("mask-compression flag")?;
        if meta > NO_MASK_AND_ALL_VALS {
            return Err(r.err(format!("invalid mask-compression flag {meta}")));
        }
        if matches!(
            meta,
            NO_MASK_AND_ONE_INACTIVE_VAL | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS
        ) {
            r.take(n * cb, "inactive value")?;
            if meta == MASK_AND_TWO_INACTIVE_VALS {
                r.take(n * cb, "inactive value")?;
            }
        }
        let words = count / 64;
        if matches!(
            meta,
            MASK_AND_NO_INACTIVE_VALS | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS
        ) {
            r.take(words * 8, "selection mask")?;
        }
        let temp_count =
            if self.compression & COMPRESS_ACTIVE_MASK != 0 && meta != NO_MASK_AND_ALL_VALS {
                mask[..words].iter().map(|w| w.count_ones() as usize).sum()
            } else {
                count
            };
        let elem = if self.half { 2 * n } else { cb * n };
        if self.half && temp_count == 0 {
            return Ok(());
        }
        let nbytes = temp_count * elem;
        if self.compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
            r.take(nbytes, "node values")?;
            return Ok(());
        }
        let size = r.i64("compressed buffer size")?;
        if size <= 0 {
            if size.unsigned_abs() != nbytes as u64 {
                return Err(r.err(format!(
                    "stored buffer of {} bytes where {nbytes} were expected",
                    size.unsigned_abs()
                )));
            }
            r.take(nbytes, "stored node values")?;
        } else {
            r.take(
                usize::try_from(size).unwrap_or(usize::MAX),
                "compressed node values",
            )?;
        }
        Ok(())
    }

    /// Reads the value array of a node with `count` values and active mask `mask`
    /// (`count / 64` words) into `out` (`count × components` floats).
    pub fn read_values(
        &mut self,
        r: &mut Reader<'_>,
        count: usize,
        mask: &[u64],
        out: &mut [f32],
    ) -> Result<(), VdbError> {
        let n = self.vt.components();
        let cb = self.vt.component_bytes();
        let mask_compressed = self.compression & COMPRESS_ACTIVE_MASK != 0;
        let meta = r.u8("mask-compression flag")?;
        if meta > NO_MASK_AND_ALL_VALS {
            return Err(r.err(format!("invalid mask-compression flag {meta}")));
        }
        let bg = self.background;
        let mut inactive1 = bg;
        let mut inactive0 = if meta == NO_MASK_OR_INACTIVE_VALS {
            bg
        } else {
            [-bg[0], -bg[1], -bg[2]]
        };
        if matches!(
            meta,
            NO_MASK_AND_ONE_INACTIVE_VAL | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS
        ) {
            r.value(self.vt, &mut inactive0, "inactive value")?;
            if meta == MASK_AND_TWO_INACTIVE_VALS {
                r.value(self.vt, &mut inactive1, "inactive value")?;
            }
        }
        let words = count / 64;
        let mut selection: Option<&[u8]> = None;
        if matches!(
            meta,
            MASK_AND_NO_INACTIVE_VALS | MASK_AND_ONE_INACTIVE_VAL | MASK_AND_TWO_INACTIVE_VALS
        ) {
            selection = Some(r.take(words * 8, "selection mask")?);
        }
        let temp_count = if mask_compressed && meta != NO_MASK_AND_ALL_VALS {
            mask[..words].iter().map(|w| w.count_ones() as usize).sum()
        } else {
            count
        };
        let elem = if self.half { 2 * n } else { cb * n };
        let scatter = mask_compressed && temp_count != count;
        {
            let bytes: &[u8] = if self.half && temp_count == 0 {
                &[]
            } else {
                match read_data(
                    r,
                    temp_count * elem,
                    self.compression,
                    &mut self.scratch,
                    &mut self.tmp,
                )? {
                    Some(b) => b,
                    None => &self.scratch,
                }
            };
            if scatter {
                self.temp.clear();
                self.temp.resize(temp_count * n, 0.0);
                decode(self.vt, self.half, bytes, &mut self.temp);
            } else {
                decode(self.vt, self.half, bytes, &mut out[..count * n]);
            }
        }
        if scatter {
            let mut t = 0;
            for i in 0..count {
                let dst = &mut out[i * n..i * n + n];
                if mask[i >> 6] >> (i & 63) & 1 != 0 {
                    dst.copy_from_slice(&self.temp[t * n..t * n + n]);
                    t += 1;
                } else {
                    let sel = selection.is_some_and(|s| s[i >> 3] >> (i & 7) & 1 != 0);
                    dst.copy_from_slice(if sel {
                        &inactive1[..n]
                    } else {
                        &inactive0[..n]
                    });
                }
            }
        }
        Ok(())
    }
}

/// Writes one data buffer with the given compression (OpenVDB's `writeData`).
pub fn write_data(out: &mut Vec<u8>, bytes: &[u8], typesize: usize, compression: u32) {
    if compression & COMPRESS_BLOSC != 0 {
        let f = blosc::compress(bytes, typesize);
        if f.len() < bytes.len() {
            out.extend_from_slice(&(f.len() as i64).to_le_bytes());
            out.extend_from_slice(&f);
        } else {
            out.extend_from_slice(&(-(bytes.len() as i64)).to_le_bytes());
            out.extend_from_slice(bytes);
        }
    } else if compression & COMPRESS_ZIP != 0 {
        use std::io::Write;
        let mut e = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        let z = e
            .write_all(bytes)
            .and_then(|()| e.finish())
            .unwrap_or_default();
        if !z.is_empty() && z.len() < bytes.len() {
            out.extend_from_slice(&(z.len() as i64).to_le_bytes());
            out.extend_from_slice(&z);
        } else {
            out.extend_from_slice(&(-(bytes.len() as i64)).to_le_bytes());
            out.extend_from_slice(bytes);
        }
    } else {
        out.extend_from_slice(bytes);
    }
}

/// Writes the value array of a node: `values` (`count × components` floats, all slots), the
/// node's active mask, and which slots are children (their values are ignored).
/// Uses OpenVDB's mask-compression flags 0, 1, 2 or 6.
#[allow(clippy::too_many_arguments)]
pub fn write_values(
    out: &mut Vec<u8>,
    values: &[f32],
    comps: usize,
    mask: &[u64],
    child: Option<&[u64]>,
    background: &[f32],
    half: bool,
    compression: u32,
) {
    let count = values.len() / comps;
    let bit = |m: &[u64], i: usize| m[i >> 6] >> (i & 63) & 1 != 0;
    let mask_compress = compression & COMPRESS_ACTIVE_MASK != 0;
    let mut meta = NO_MASK_AND_ALL_VALS;
    let mut inactive: Option<&[f32]> = None;
    if mask_compress {
        let mut unique = 0;
        for i in 0..count {
            if bit(mask, i) || child.is_some_and(|c| bit(c, i)) {
                continue;
            }
            let v = &values[i * comps..i * comps + comps];
            match inactive {
                None => {
                    inactive = Some(v);
                    unique = 1;
                }
                Some(u) if same(u, v) => {}
                Some(_) => {
                    unique = 2;
                    break;
                }
            }
        }
        meta = match (unique, inactive) {
            (0, _) => NO_MASK_OR_INACTIVE_VALS,
            (1, Some(u)) if same(u, background) => NO_MASK_OR_INACTIVE_VALS,
            (1, Some(u))
                if u.iter()
                    .zip(background)
                    .all(|(a, b)| a.to_bits() == (-b).to_bits()) =>
            {
                NO_MASK_AND_MINUS_BG
            }
            (1, Some(_)) => NO_MASK_AND_ONE_INACTIVE_VAL,
            _ => NO_MASK_AND_ALL_VALS,
        };
    }
    out.push(meta);
    if meta == NO_MASK_AND_ONE_INACTIVE_VAL {
        for &x in inactive.unwrap_or(background) {
            let x = if half { f16::from_f32(x).to_f32() } else { x };
            out.extend_from_slice(&x.to_le_bytes());
        }
    }
    let selected: Vec<f32> = if meta == NO_MASK_AND_ALL_VALS {
        values.to_vec()
    } else {
        let mut s = Vec::with_capacity(values.len());
        for i in 0..count {
            if bit(mask, i) {
                s.extend_from_slice(&values[i * comps..i * comps + comps]);
            }
        }
        s
    };
    if half {
        if selected.is_empty() {
            return;
        }
        let b: Vec<u8> = selected
            .iter()
            .flat_map(|&x| f16::from_f32(x).to_bits().to_le_bytes())
            .collect();
        write_data(out, &b, 2, compression);
    } else {
        let b: Vec<u8> = selected.iter().flat_map(|&x| x.to_le_bytes()).collect();
        write_data(out, &b, 4, compression);
    }
}

fn same(a: &[f32], b: &[f32]) -> bool {
    a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}
