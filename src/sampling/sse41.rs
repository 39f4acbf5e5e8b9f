//! One 4-dimensional Sobol set with SSE4.1 (`pmulld`) and SSSE3 (`pshufb`): the same integer
//! operations as the baseline path (`sobol_burley`'s `Int4`, which on baseline x86-64 emulates
//! each 32-bit lane multiply with two `pmuludq` and several shuffles and masks, and reverses
//! bits in mask-and-shift rounds), in fewer instructions: one `pmulld` per multiply and a byte
//! shuffle with nibble tables for the bit reversal. Every lane ends with the same `u32` as the
//! baseline's, so the numbers are the same bit for bit.
//!
//! The set is Burley (2020), "Practical Hash-based Owen Scrambling" (JCGT 9(4)): the XOR of the
//! direction vectors selected by the (already shuffled) sample index, Owen-scrambled in
//! reversed bit order by a per-dimension hash of the seed, reversed, and mapped to `[0, 1)`.

use std::arch::x86_64::{
    __m128i, _mm_add_epi32, _mm_and_si128, _mm_castsi128_ps, _mm_loadu_si128, _mm_mullo_epi32,
    _mm_or_si128, _mm_set1_epi32, _mm_set1_epi8, _mm_set1_ps, _mm_setr_epi32, _mm_setr_epi8,
    _mm_shuffle_epi8, _mm_srli_epi16, _mm_srli_epi32, _mm_storeu_ps, _mm_sub_ps, _mm_xor_si128,
};

/// Whether the CPU runs [`sobol_4d`] (SSE4.1, which implies SSSE3). `std` caches the CPUID
/// answer: a load and a bit test per call.
#[inline]
pub(super) fn available() -> bool {
    std::is_x86_feature_detected!("sse4.1")
}

/// `x * c` in every lane, wrapping.
#[inline]
#[target_feature(enable = "sse4.1")]
unsafe fn mul(x: __m128i, c: u32) -> __m128i {
    _mm_mullo_epi32(x, _mm_set1_epi32(c as i32))
}

/// `x ^ (x >> s)` in every lane (logical shift).
#[inline]
#[target_feature(enable = "sse4.1")]
unsafe fn xorshift<const S: i32>(x: __m128i) -> __m128i {
    _mm_xor_si128(x, _mm_srli_epi32::<S>(x))
}

/// The Sobol set of a sample: `table[k][nibbles[k]]` XORed over `k` (the direction vectors'
/// sum for the shuffled index, in reversed bit order), scrambled with the seed words
/// `scramble` (lane `i`: the seed's hash input for dimension `i` of the set), as four numbers
/// in `[0, 1)` (before the clamp below one that the caller applies).
///
/// # Safety
/// The CPU must support SSE4.1 ([`available`]).
#[inline]
#[target_feature(enable = "sse4.1")]
pub(super) unsafe fn sobol_4d(
    table: &[[[u32; 4]; 16]; 4],
    nibbles: [u8; 4],
    scramble: [u32; 4],
) -> [f32; 4] {
    let row = |k: usize| table[k][usize::from(nibbles[k] & 15)];
    let [r0, r1, r2, r3] = [row(0), row(1), row(2), row(3)];
    // SAFETY: each `[u32; 4]` is 16 readable bytes; the load is unaligned.
    let load = |r: &[u32; 4]| unsafe { _mm_loadu_si128(r.as_ptr().cast()) };
    let mut n = _mm_xor_si128(
        _mm_xor_si128(load(&r0), load(&r1)),
        _mm_xor_si128(load(&r2), load(&r3)),
    );

    // The scramble seeds hashed (the same hash as `sobol_burley::parts::hash_int4`).
    let mut s = _mm_setr_epi32(
        scramble[0] as i32,
        scramble[1] as i32,
        scramble[2] as i32,
        scramble[3] as i32,
    );
    s = _mm_xor_si128(s, _mm_set1_epi32(0xe6fe_3bebu32 as i32));
    s = xorshift::<16>(s);
    s = mul(s, 0x7feb_352d);
    s = xorshift::<15>(s);
    s = mul(s, 0x846c_a68b);
    s = xorshift::<16>(s);

    // Owen scrambling in reversed bit order (as `owen_scramble_int4_rev`).
    n = _mm_xor_si128(n, mul(n, 0x3d20_adea));
    n = _mm_add_epi32(n, s);
    let odd = _mm_or_si128(_mm_srli_epi32::<16>(s), _mm_set1_epi32(1));
    n = _mm_mullo_epi32(n, odd);
    n = _mm_xor_si128(n, mul(n, 0x0552_6c56));
    n = _mm_xor_si128(n, mul(n, 0x53a2_2864));

    // Bit reversal of each lane: its bytes in reverse order, each byte's two nibbles swapped
    // and reversed through a 16-entry table.
    let bytes = _mm_shuffle_epi8(
        n,
        _mm_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12),
    );
    let low = _mm_set1_epi8(0x0f);
    // rev4[i] (the four bits of i reversed) in the high nibble, and in the low one.
    let rev_high = _mm_setr_epi8(
        0x00,
        0x80u8 as i8,
        0x40,
        0xc0u8 as i8,
        0x20,
        0xa0u8 as i8,
        0x60,
        0xe0u8 as i8,
        0x10,
        0x90u8 as i8,
        0x50,
        0xd0u8 as i8,
        0x30,
        0xb0u8 as i8,
        0x70,
        0xf0u8 as i8,
    );
    let rev_low = _mm_setr_epi8(
        0x0, 0x8, 0x4, 0xc, 0x2, 0xa, 0x6, 0xe, 0x1, 0x9, 0x5, 0xd, 0x3, 0xb, 0x7, 0xf,
    );
    let lo = _mm_and_si128(bytes, low);
    let hi = _mm_and_si128(_mm_srli_epi16::<4>(bytes), low);
    let rev = _mm_or_si128(
        _mm_shuffle_epi8(rev_high, lo),
        _mm_shuffle_epi8(rev_low, hi),
    );

    // The top 23 bits as the mantissa of a number in [1, 2), minus one.
    let one = _mm_set1_epi32(0x3f80_0000);
    let f = _mm_sub_ps(
        _mm_castsi128_ps(_mm_or_si128(_mm_srli_epi32::<9>(rev), one)),
        _mm_set1_ps(1.0),
    );
    let mut out = [0.0f32; 4];
    // SAFETY: `out` is 16 writable bytes; the store is unaligned.
    unsafe { _mm_storeu_ps(out.as_mut_ptr(), f) };
    out
}
