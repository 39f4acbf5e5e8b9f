//! A pure-Rust codec for Blosc 1 frames (the container OpenVDB's Blosc compression writes).
//!
//! Frame layout (Blosc 1 format version 2): a 16-byte header
//! `[version, versionlz, flags, typesize, nbytes: u32, blocksize: u32, cbytes: u32]`, then, unless
//! the frame is a plain copy (flag 0x02), one `u32` start offset per block followed by the
//! blocks. A block is split into `typesize` streams when the "don't split" flag (0x10) is clear
//! and the block is a full block with `blocksize / typesize >= 128` and `typesize <= 16`; each
//! stream is `i32 csize` then `csize` bytes, stored raw when `csize` equals the stream's
//! uncompressed size. Flag 0x01 is a byte shuffle of each block, 0x04 a bit shuffle; the
//! compressor code is `flags >> 5` (0 BloscLZ, 1 LZ4, 2 Snappy, 3 zlib, 4 Zstd).
//! Every size is checked against the frame's length and the caller's expected size before
//! anything is allocated.

use std::io::Read;

const HEADER: usize = 16;
const FLAG_SHUFFLE: u8 = 0x01;
const FLAG_MEMCPY: u8 = 0x02;
const FLAG_BITSHUFFLE: u8 = 0x04;
const FLAG_DONT_SPLIT: u8 = 0x10;

fn u32_at(s: &[u8], at: usize) -> Option<u32> {
    s.get(at..at + 4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

fn codec_name(code: u8) -> &'static str {
    match code {
        0 => "blosclz",
        1 => "lz4",
        2 => "snappy",
        3 => "zlib",
        4 => "zstd",
        _ => "unknown",
    }
}

/// Decompresses one Blosc frame that must hold exactly `expected` bytes.
///
/// # Errors
/// A message describing the first inconsistency (truncation, size mismatch, unsupported
/// codec or filter).
pub fn decompress(src: &[u8], expected: usize) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    decompress_into(src, expected, &mut out, &mut Vec::new())?;
    Ok(out)
}

/// As [`decompress`], into `out` (resized to `expected`), with `tmp` as scratch space; both
/// buffers are reused between calls.
///
/// # Errors
/// As [`decompress`].
pub fn decompress_into(
    src: &[u8],
    expected: usize,
    out: &mut Vec<u8>,
    tmp: &mut Vec<u8>,
) -> Result<(), String> {
    if src.len() < HEADER {
        return Err(format!(
            "blosc frame of {} bytes is shorter than its 16-byte header",
            src.len()
        ));
    }
    let flags = src[2];
    let typesize = usize::from(src[3]).max(1);
    let nbytes = u32_at(src, 4).unwrap_or(0) as usize;
    let blocksize = u32_at(src, 8).unwrap_or(0) as usize;
    let cbytes = u32_at(src, 12).unwrap_or(0) as usize;
    if src[0] == 0 || src[0] > 4 {
        return Err(format!("unsupported blosc format version {}", src[0]));
    }
    if nbytes != expected {
        return Err(format!(
            "blosc frame holds {nbytes} bytes, expected {expected}"
        ));
    }
    if cbytes > src.len() || cbytes < HEADER {
        return Err(format!(
            "blosc frame claims {cbytes} bytes but {} are available",
            src.len()
        ));
    }
    let src = &src[..cbytes];
    out.clear();
    if flags & FLAG_MEMCPY != 0 {
        let d = src
            .get(HEADER..HEADER + nbytes)
            .ok_or("truncated uncompressed blosc frame")?;
        out.extend_from_slice(d);
        return Ok(());
    }
    if nbytes == 0 {
        return Ok(());
    }
    if flags & FLAG_BITSHUFFLE != 0 {
        return Err("blosc bit-shuffle filter is not supported".into());
    }
    if blocksize == 0 {
        return Err("blosc frame with zero block size".into());
    }
    let code = flags >> 5;
    let nblocks = nbytes.div_ceil(blocksize);
    if HEADER + 4 * nblocks > cbytes {
        return Err(format!(
            "blosc frame too short for its {nblocks} block offsets"
        ));
    }
    out.resize(nbytes, 0);
    for bi in 0..nblocks {
        let start = u32_at(src, HEADER + 4 * bi).unwrap_or(0) as usize;
        let bsize = blocksize.min(nbytes - bi * blocksize);
        let leftover = bsize < blocksize;
        let nsplits = if flags & FLAG_DONT_SPLIT == 0
            && !leftover
            && typesize <= 16
            && blocksize / typesize >= 128
            && bsize.is_multiple_of(typesize)
        {
            typesize
        } else {
            1
        };
        let neblock = bsize / nsplits;
        tmp.clear();
        tmp.resize(bsize, 0);
        let mut pos = start;
        for sp in 0..nsplits {
            let csize = src
                .get(pos..pos + 4)
                .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .ok_or("truncated blosc block")?;
            pos += 4;
            if csize <= 0 {
                return Err(format!("unsupported blosc stream size {csize}"));
            }
            let csize = csize as usize;
            let data = src.get(pos..pos + csize).ok_or("truncated blosc stream")?;
            pos += csize;
            let dst = &mut tmp[sp * neblock..(sp + 1) * neblock];
            if csize == neblock {
                dst.copy_from_slice(data);
            } else {
                decode_stream(code, data, dst)?;
            }
        }
        let dst = &mut out[bi * blocksize..bi * blocksize + bsize];
        if flags & FLAG_SHUFFLE != 0 && typesize > 1 {
            unshuffle(typesize, tmp, dst);
        } else {
            dst.copy_from_slice(tmp);
        }
    }
    Ok(())
}

fn decode_stream(code: u8, data: &[u8], dst: &mut [u8]) -> Result<(), String> {
    let n = match code {
        1 => lz4_flex::block::decompress_into(data, dst).map_err(|e| format!("lz4: {e}"))?,
        0 => blosclz_decompress(data, dst)?,
        3 => {
            let mut d = flate2::read::ZlibDecoder::new(data);
            let mut filled = 0;
            while filled < dst.len() {
                let k = d
                    .read(&mut dst[filled..])
                    .map_err(|e| format!("zlib: {e}"))?;
                if k == 0 {
                    break;
                }
                filled += k;
            }
            filled
        }
        c => {
            return Err(format!(
                "blosc codec '{}' (code {c}) is not supported",
                codec_name(c)
            ));
        }
    };
    if n != dst.len() {
        return Err(format!(
            "blosc stream decoded to {n} bytes, expected {}",
            dst.len()
        ));
    }
    Ok(())
}

/// BloscLZ decoder (a FastLZ level-2 variant): literal runs `ctrl < 32` copy `ctrl + 1` bytes;
/// otherwise a match of length `(ctrl >> 5) + 2` (7 means extended with 255-bytes) at distance
/// `((ctrl & 31) << 8) + next byte + 1`, with the 16-bit far-distance escape.
fn blosclz_decompress(src: &[u8], dst: &mut [u8]) -> Result<usize, String> {
    let err = || "corrupt blosclz stream".to_string();
    let mut ip = 0usize;
    let mut op = 0usize;
    if src.is_empty() {
        return Ok(0);
    }
    let mut ctrl = usize::from(src[0] & 31);
    ip += 1;
    loop {
        if ctrl >= 32 {
            let mut len = (ctrl >> 5) - 1;
            let mut ofs = (ctrl & 31) << 8;
            if len == 7 - 1 {
                loop {
                    let c = *src.get(ip).ok_or_else(err)?;
                    ip += 1;
                    len += usize::from(c);
                    if c != 255 {
                        break;
                    }
                }
            }
            let code = *src.get(ip).ok_or_else(err)?;
            ip += 1;
            len += 3;
            ofs += usize::from(code);
            if code == 255 && ofs == (31 << 8) + 255 {
                let a = *src.get(ip).ok_or_else(err)?;
                let b = *src.get(ip + 1).ok_or_else(err)?;
                ip += 2;
                ofs = (usize::from(a) << 8) + usize::from(b) + 8191;
            }
            let refp = op.checked_sub(ofs + 1).ok_or_else(err)?;
            if op + len > dst.len() {
                return Err(err());
            }
            for k in 0..len {
                dst[op + k] = dst[refp + k];
            }
            op += len;
        } else {
            let n = ctrl + 1;
            let lit = src.get(ip..ip + n).ok_or_else(err)?;
            dst.get_mut(op..op + n)
                .ok_or_else(err)?
                .copy_from_slice(lit);
            ip += n;
            op += n;
        }
        if ip >= src.len() {
            break;
        }
        ctrl = usize::from(src[ip]);
        ip += 1;
    }
    Ok(op)
}

/// Undoes Blosc's byte shuffle of one block: byte `j` of element `i` was stored at
/// `j * n + i` (`n` elements); trailing bytes past the last whole element are unshuffled.
fn unshuffle(typesize: usize, src: &[u8], dst: &mut [u8]) {
    let n = src.len() / typesize;
    if typesize == 4 {
        let (s0, rest) = src.split_at(n);
        let (s1, rest) = rest.split_at(n);
        let (s2, s3) = rest.split_at(n);
        for (i, d) in dst[..4 * n].chunks_exact_mut(4).enumerate() {
            d[0] = s0[i];
            d[1] = s1[i];
            d[2] = s2[i];
            d[3] = s3[i];
        }
    } else {
        for i in 0..n {
            for j in 0..typesize {
                dst[i * typesize + j] = src[j * n + i];
            }
        }
    }
    let tail = n * typesize;
    dst[tail..].copy_from_slice(&src[tail..]);
}

fn shuffle(typesize: usize, src: &[u8], dst: &mut [u8]) {
    let n = src.len() / typesize;
    for i in 0..n {
        for j in 0..typesize {
            dst[j * n + i] = src[i * typesize + j];
        }
    }
    let tail = n * typesize;
    dst[tail..].copy_from_slice(&src[tail..]);
}

/// Compresses `src` into one Blosc 1 frame: byte shuffle with element size `typesize`, LZ4,
/// a single block, split into `typesize` streams where Blosc itself would split (so that
/// every Blosc 1 version decodes it). Incompressible input is stored as a plain copy.
#[must_use]
pub fn compress(src: &[u8], typesize: usize) -> Vec<u8> {
    let typesize = typesize.clamp(1, 255);
    let nbytes = src.len();
    let header = |flags: u8, blocksize: usize, cbytes: usize| {
        let mut h = vec![2u8, 1, flags, typesize as u8];
        h.extend_from_slice(&(nbytes as u32).to_le_bytes());
        h.extend_from_slice(&(blocksize as u32).to_le_bytes());
        h.extend_from_slice(&(cbytes as u32).to_le_bytes());
        h
    };
    let memcpy = || {
        let mut f = header(
            FLAG_MEMCPY | FLAG_SHUFFLE | (1 << 5),
            nbytes,
            HEADER + nbytes,
        );
        f.extend_from_slice(src);
        f
    };
    if nbytes == 0 {
        return memcpy();
    }
    let split = typesize <= 16 && nbytes / typesize >= 128 && nbytes.is_multiple_of(typesize);
    let nsplits = if split { typesize } else { 1 };
    let mut shuffled = vec![0u8; nbytes];
    shuffle(typesize, src, &mut shuffled);
    let neblock = nbytes / nsplits;
    let mut body = Vec::with_capacity(nbytes);
    for sp in 0..nsplits {
        let part = &shuffled[sp * neblock..(sp + 1) * neblock];
        let c = lz4_flex::block::compress(part);
        if c.len() >= neblock {
            body.extend_from_slice(&(neblock as i32).to_le_bytes());
            body.extend_from_slice(part);
        } else {
            body.extend_from_slice(&(c.len() as i32).to_le_bytes());
            body.extend_from_slice(&c);
        }
    }
    let total = HEADER + 4 + body.len();
    if total >= HEADER + nbytes {
        return memcpy();
    }
    let flags = FLAG_SHUFFLE | (1 << 5) | if split { 0 } else { FLAG_DONT_SPLIT };
    let mut f = header(flags, nbytes, total);
    f.extend_from_slice(&((HEADER + 4) as u32).to_le_bytes());
    f.extend_from_slice(&body);
    f
}
