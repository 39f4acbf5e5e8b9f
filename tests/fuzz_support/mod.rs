//! Byte-level mutation fuzzing on stable Rust, shared by `fuzz_ply.rs` and `fuzz_scene.rs`.
//!
//! - [`Mutation`]: bit flips, byte replacements, insertions, deletions, truncation, chunk
//!   duplication, splices from another seed, and numbers (ASCII or 4-byte binary words)
//!   replaced by extreme values; [`mutations`] is their proptest strategy.
//! - [`fuzz`]: runs a check on mutated inputs with proptest's runner (fixed seed, shrinking of
//!   failures), bounded by a number of cases and a time budget ([`Budget`]); a failing input is
//!   shrunk, written to the regressions folder and reported.
//! - [`CountingAlloc`]: the test binary's global allocator; it records, per thread, the largest
//!   single allocation and the total allocated, so a check can bound both
//!   ([`measure_allocations`]), and serves huge requests with uncommitted address space so that
//!   a reader reserving memory from a count in its input fails its check instead of aborting.
//! - [`catch_panic`]: runs a closure and turns a panic into an error carrying its message.
//!
//! Use from a test file with `#[path = "fuzz_support/mod.rs"] mod fuzz_support;`.
#![allow(dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::fmt::Debug;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use proptest::prelude::*;
use proptest::test_runner::{
    Config, RngAlgorithm, RngSeed, TestCaseError, TestError, TestRng, TestRunner,
};

// ---------------------------------------------------------------------------------------------
// Allocation accounting

/// Requests above this size are served by reserving address space without committing memory
/// (`mmap` with `MAP_NORESERVE`): a reader that reserves a huge buffer from a count read from
/// a file is reported by the size check of its test instead of exhausting the machine's
/// memory or aborting the test binary. Pages are only committed when written.
pub const LAZY_ABOVE_BYTES: usize = 256 << 20;

/// The global allocator of the fuzz test binaries: the system allocator plus per-thread
/// accounting (see [`measure_allocations`]) and lazily committed huge blocks (see
/// [`LAZY_ABOVE_BYTES`]).
pub struct CountingAlloc;

/// Live bytes from `System` (all threads) above which requests are refused: the test binary
/// then aborts with Rust's "memory allocation failed" message instead of driving a shared
/// machine out of memory.
pub const LIVE_CAP_BYTES: usize = 6 << 30;

static LIVE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
    static TOTAL: Cell<usize> = const { Cell::new(0) };
}

/// Counts `size` more live bytes, or refuses (false) when that would pass [`LIVE_CAP_BYTES`].
fn reserve_live(size: usize) -> bool {
    let before = LIVE.fetch_add(size, Ordering::Relaxed);
    if before.saturating_add(size) > LIVE_CAP_BYTES {
        LIVE.fetch_sub(size, Ordering::Relaxed);
        let msg = b"fuzz_support: live allocations would pass LIVE_CAP_BYTES; refusing (the input under test may be in the target tmp folder's fuzz-current-input file)\n";
        // SAFETY: writes a static buffer to standard error; no allocation.
        unsafe {
            libc::write(2, msg.as_ptr().cast(), msg.len());
        }
        return false;
    }
    true
}

fn note(size: usize) {
    // `try_with`: never panic inside the allocator (thread-local storage being torn down).
    let _ = LARGEST.try_with(|c| c.set(c.get().max(size)));
    let _ = TOTAL.try_with(|c| c.set(c.get().saturating_add(size)));
}

fn is_lazy(size: usize) -> bool {
    size > LAZY_ABOVE_BYTES
}

/// Reserves `size` bytes of zeroed, lazily committed memory (null on failure or when the
/// alignment exceeds a page).
unsafe fn lazy_alloc(layout: Layout) -> *mut u8 {
    if layout.align() > 4096 {
        return std::ptr::null_mut();
    }
    let p = libc::mmap(
        std::ptr::null_mut(),
        layout.size(),
        libc::PROT_READ | libc::PROT_WRITE,
        libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_NORESERVE,
        -1,
        0,
    );
    if p == libc::MAP_FAILED {
        std::ptr::null_mut()
    } else {
        p.cast()
    }
}

// SAFETY: blocks of at most LAZY_ABOVE_BYTES come from `System`, larger ones from `mmap`
// (page aligned, zeroed) and go back to `munmap`; which is which follows from the size in the
// layout, which the caller passes unchanged to `dealloc`/`realloc`. Accounting only touches an
// atomic counter and `Cell`s of constant-initialised thread-locals (no allocation, no
// unwinding).
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        if is_lazy(layout.size()) {
            return lazy_alloc(layout);
        }
        if !reserve_live(layout.size()) {
            return std::ptr::null_mut();
        }
        let p = System.alloc(layout);
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        if is_lazy(layout.size()) {
            return lazy_alloc(layout);
        }
        if !reserve_live(layout.size()) {
            return std::ptr::null_mut();
        }
        let p = System.alloc_zeroed(layout);
        if p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        if is_lazy(layout.size()) {
            libc::munmap(ptr.cast(), layout.size());
        } else {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            System.dealloc(ptr, layout)
        }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        let Ok(new_layout) = Layout::from_size_align(new_size, layout.align()) else {
            return std::ptr::null_mut();
        };
        if !is_lazy(layout.size()) && !is_lazy(new_size) {
            if new_size > layout.size() && !reserve_live(new_size - layout.size()) {
                return std::ptr::null_mut();
            }
            let p = System.realloc(ptr, layout, new_size);
            if p.is_null() {
                if new_size > layout.size() {
                    LIVE.fetch_sub(new_size - layout.size(), Ordering::Relaxed);
                }
            } else if new_size < layout.size() {
                LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
            return p;
        }
        let new = self.alloc(new_layout);
        if !new.is_null() {
            std::ptr::copy_nonoverlapping(ptr, new, layout.size().min(new_size));
            self.dealloc(ptr, layout);
        }
        new
    }
}

/// Allocations made by the current thread during [`measure_allocations`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AllocStats {
    /// Largest single allocation or reallocation (bytes).
    pub largest: usize,
    /// Sum of all allocation and reallocation sizes (bytes).
    pub total: usize,
}

/// Runs `f` and reports the allocations the current thread made meanwhile (allocations of
/// other threads, e.g. a thread pool, are not counted).
pub fn measure_allocations<R>(f: impl FnOnce() -> R) -> (R, AllocStats) {
    let saved = (LARGEST.with(Cell::get), TOTAL.with(Cell::get));
    LARGEST.with(|c| c.set(0));
    TOTAL.with(|c| c.set(0));
    let r = f();
    let stats = AllocStats {
        largest: LARGEST.with(Cell::get),
        total: TOTAL.with(Cell::get),
    };
    LARGEST.with(|c| c.set(saved.0.max(stats.largest)));
    TOTAL.with(|c| c.set(saved.1.saturating_add(stats.total)));
    (r, stats)
}

thread_local! {
    /// Set while [`catch_panic`] runs on this thread.
    static QUIET: Cell<bool> = const { Cell::new(false) };
}

/// Number of [`catch_panic`] calls running on any thread.
static ACTIVE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
/// Where the last silenced panic happened.
static LAST_LOCATION: std::sync::Mutex<String> = std::sync::Mutex::new(String::new());

/// Installs (once) a panic hook that stays silent, only recording where the panic happened,
/// for panics on a thread inside [`catch_panic`] and, while one runs, on unnamed threads (the
/// thread pool the code under test may use, whose panics come back to the caller); it defers
/// to the previous hook for everything else (test threads are named).
fn install_quiet_hook() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let pool_thread =
                ACTIVE.load(Ordering::SeqCst) > 0 && std::thread::current().name().is_none();
            if QUIET.with(Cell::get) || pool_thread {
                let location = info
                    .location()
                    .map(|l| format!("{}:{}:{}", l.file(), l.line(), l.column()))
                    .unwrap_or_default();
                if let Ok(mut last) = LAST_LOCATION.lock() {
                    *last = location;
                }
            } else {
                previous(info);
            }
        }));
    });
}

/// Runs `f`, turning a panic into `Err` with the panic's message and location (the panic is
/// not printed: the caller reports it).
pub fn catch_panic<R>(f: impl FnOnce() -> R) -> Result<R, String> {
    install_quiet_hook();
    let was_quiet = QUIET.with(|q| q.replace(true));
    ACTIVE.fetch_add(1, Ordering::SeqCst);
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    ACTIVE.fetch_sub(1, Ordering::SeqCst);
    QUIET.with(|q| q.set(was_quiet));
    result.map_err(|payload| {
        let message = payload
            .downcast_ref::<&str>()
            .map(|s| (*s).to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "(non-string panic payload)".to_string());
        let location = LAST_LOCATION.lock().map(|l| l.clone()).unwrap_or_default();
        format!("{message} (at {location})")
    })
}

// ---------------------------------------------------------------------------------------------
// Mutations

/// Replacement numbers for [`Mutation::Number`]: boundaries of every integer type, huge
/// counts, float extremes, non-finite spellings, signs and zeros.
pub const NUMBERS: &[&str] = &[
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "3",
    "7",
    "127",
    "-128",
    "255",
    "256",
    "65535",
    "65536",
    "2147483647",
    "2147483648",
    "-2147483649",
    "4294967295",
    "4294967296",
    "100000000000",
    "9223372036854775807",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999999",
    "0.5",
    "1.5",
    "0.0",
    "1e-45",
    "1e-400",
    "3.4028235e38",
    "1e39",
    "-1e30",
    "1e400",
    "nan",
    "inf",
    "-inf",
    "+inf",
];

/// 32-bit patterns for [`Mutation::Word`]: integer extremes and special floats.
pub const WORDS: &[u32] = &[
    0,
    1,
    3,
    0xff,
    0xffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    0x7fc0_0000, // f32 NaN
    0x7f80_0000, // f32 +inf
    0xff80_0000, // f32 -inf
    0x7f7f_ffff, // f32 max
    0x3f80_0000, // f32 1.0
    0x0000_0001, // f32 smallest subnormal / integer 1
];

/// One edit of an input. Positions are taken modulo the input's length (plus one where the
/// end is a valid position), so any value applies to any input.
#[derive(Clone, Debug)]
pub enum Mutation {
    /// Flips bit `bit` of byte `at`.
    FlipBit { at: u32, bit: u8 },
    /// Replaces byte `at`.
    SetByte { at: u32, byte: u8 },
    /// Inserts bytes before `at`.
    Insert { at: u32, bytes: Vec<u8> },
    /// Deletes `len` bytes from `at`.
    Delete { at: u32, len: u16 },
    /// Keeps only the first `keep` bytes.
    Truncate { keep: u32 },
    /// Copies `len` bytes from `from` and inserts them before `to`.
    Duplicate { from: u32, len: u16, to: u32 },
    /// Inserts `len` bytes of seed `seed` (from `from`) before `to`.
    Splice {
        seed: u32,
        from: u32,
        len: u16,
        to: u32,
    },
    /// Replaces the `nth` ASCII number (a run of digits, signs, dots and exponents holding a
    /// digit) by `NUMBERS[value]`.
    Number { nth: u32, value: u8 },
    /// Overwrites 4 bytes at `at` with `WORDS[value]`, big or little endian.
    Word {
        at: u32,
        value: u8,
        big_endian: bool,
    },
}

fn interesting_byte() -> impl Strategy<Value = u8> {
    prop_oneof![
        3 => any::<u8>(),
        1 => prop::sample::select(&b"\0\xff\x7f\x80\n\r\t -+.e0129[]{}\"=#,"[..]),
    ]
}

/// A strategy for one [`Mutation`].
pub fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        1 => (any::<u32>(), 0u8..8).prop_map(|(at, bit)| Mutation::FlipBit { at, bit }),
        1 => (any::<u32>(), interesting_byte()).prop_map(|(at, byte)| Mutation::SetByte { at, byte }),
        1 => (any::<u32>(), prop::collection::vec(interesting_byte(), 1..12))
            .prop_map(|(at, bytes)| Mutation::Insert { at, bytes }),
        1 => (any::<u32>(), 1u16..48).prop_map(|(at, len)| Mutation::Delete { at, len }),
        1 => any::<u32>().prop_map(|keep| Mutation::Truncate { keep }),
        1 => (any::<u32>(), 1u16..200, any::<u32>())
            .prop_map(|(from, len, to)| Mutation::Duplicate { from, len, to }),
        1 => (any::<u32>(), any::<u32>(), 1u16..200, any::<u32>()).prop_map(|(seed, from, len, to)| {
            Mutation::Splice {
                seed,
                from,
                len,
                to,
            }
        }),
        3 => (any::<u32>(), 0..NUMBERS.len() as u8)
            .prop_map(|(nth, value)| Mutation::Number { nth, value }),
        2 => (any::<u32>(), 0..WORDS.len() as u8, any::<bool>())
            .prop_map(|(at, value, big_endian)| Mutation::Word { at, value, big_endian }),
    ]
}

/// A strategy for a seed index below `seeds` and 1 to `max` mutations.
pub fn mutations(seeds: usize, max: usize) -> impl Strategy<Value = (usize, Vec<Mutation>)> {
    (0..seeds, prop::collection::vec(mutation(), 1..=max))
}

fn pos(at: u32, len: usize) -> usize {
    at as usize % (len + 1)
}

/// Byte ranges of the ASCII numbers of `data` (see [`Mutation::Number`]).
pub fn number_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let is_num = |b: u8| b.is_ascii_digit() || matches!(b, b'-' | b'+' | b'.' | b'e' | b'E');
    let mut spans = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if is_num(data[i]) && (i == 0 || !data[i - 1].is_ascii_alphabetic()) {
            let start = i;
            while i < data.len() && is_num(data[i]) {
                i += 1;
            }
            if data[start..i].iter().any(u8::is_ascii_digit) {
                spans.push((start, i));
            }
        } else {
            i += 1;
        }
    }
    spans
}

/// Applies `m` to `data`; `seeds` feeds [`Mutation::Splice`].
pub fn apply(data: &mut Vec<u8>, m: &Mutation, seeds: &[Vec<u8>]) {
    let len = data.len();
    match m {
        Mutation::FlipBit { at, bit } => {
            if len > 0 {
                data[*at as usize % len] ^= 1 << (bit % 8);
            }
        }
        Mutation::SetByte { at, byte } => {
            if len > 0 {
                data[*at as usize % len] = *byte;
            }
        }
        Mutation::Insert { at, bytes } => {
            let p = pos(*at, len);
            data.splice(p..p, bytes.iter().copied());
        }
        Mutation::Delete { at, len: n } => {
            let p = pos(*at, len);
            let end = (p + *n as usize).min(len);
            data.drain(p..end);
        }
        Mutation::Truncate { keep } => data.truncate(pos(*keep, len)),
        Mutation::Duplicate { from, len: n, to } => {
            let p = pos(*from, len);
            let chunk = data[p..(p + *n as usize).min(len)].to_vec();
            let q = pos(*to, len);
            data.splice(q..q, chunk);
        }
        Mutation::Splice {
            seed,
            from,
            len: n,
            to,
        } => {
            if let Some(other) = seeds.get(*seed as usize % seeds.len().max(1)) {
                let p = pos(*from, other.len());
                let chunk = &other[p..(p + *n as usize).min(other.len())];
                let q = pos(*to, len);
                data.splice(q..q, chunk.iter().copied());
            }
        }
        Mutation::Number { nth, value } => {
            let spans = number_spans(data);
            if !spans.is_empty() {
                let (a, b) = spans[*nth as usize % spans.len()];
                let text = NUMBERS[*value as usize % NUMBERS.len()].as_bytes();
                data.splice(a..b, text.iter().copied());
            }
        }
        Mutation::Word {
            at,
            value,
            big_endian,
        } => {
            if len >= 4 {
                let p = *at as usize % (len - 3);
                let w = WORDS[*value as usize % WORDS.len()];
                let bytes = if *big_endian {
                    w.to_be_bytes()
                } else {
                    w.to_le_bytes()
                };
                data[p..p + 4].copy_from_slice(&bytes);
            }
        }
    }
}

/// Seed `seed` with `mutations` applied in order.
pub fn mutate(seeds: &[Vec<u8>], seed: usize, mutations: &[Mutation]) -> Vec<u8> {
    let mut data = seeds[seed % seeds.len()].clone();
    for m in mutations {
        apply(&mut data, m, seeds);
    }
    data
}

// ---------------------------------------------------------------------------------------------
// Running

/// How long a fuzz test runs: `cases` mutated inputs or `time`, whichever ends first, from RNG
/// seed `seed`. Environment overrides: `VELOUR_FUZZ_CASES`, `VELOUR_FUZZ_SECONDS`,
/// `VELOUR_FUZZ_SEED`.
#[derive(Clone, Copy, Debug)]
pub struct Budget {
    /// Number of cases.
    pub cases: u32,
    /// Wall-clock limit of the generation phase (shrinking a failure may take longer).
    pub time: Duration,
    /// RNG seed.
    pub seed: u64,
}

impl Budget {
    /// The defaults given, overridden by the environment variables.
    pub fn from_env(cases: u32, seconds: f64, seed: u64) -> Budget {
        fn var<T: std::str::FromStr>(name: &str) -> Option<T> {
            let v = std::env::var(name).ok()?;
            match v.trim().parse() {
                Ok(x) => Some(x),
                Err(_) => panic!("{name} = {v:?} is not a valid value"),
            }
        }
        let seconds: f64 = var("VELOUR_FUZZ_SECONDS").unwrap_or(seconds);
        Budget {
            cases: var("VELOUR_FUZZ_CASES").unwrap_or(cases),
            time: Duration::from_secs_f64(seconds.max(0.0)),
            seed: var("VELOUR_FUZZ_SEED").unwrap_or(seed),
        }
    }
}

/// A short, stable name for an input: FNV-1a 64 of its bytes in hex.
pub fn content_name(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// Writes `bytes` to `dir/<content name>.<ext>` (kept if already there) and returns the path.
pub fn save_input(dir: &Path, ext: &str, bytes: &[u8]) -> PathBuf {
    std::fs::create_dir_all(dir).expect("create the regressions folder");
    let path = dir.join(format!("{}.{ext}", content_name(bytes)));
    if !path.exists() {
        std::fs::write(&path, bytes).expect("write the failing input");
    }
    path
}

/// The files of `dir` with extension `ext`, sorted (none if `dir` does not exist).
pub fn files_with_extension(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|e| e == ext))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

/// A printable excerpt of an input for failure messages.
pub fn preview(bytes: &[u8]) -> String {
    let shown = &bytes[..bytes.len().min(600)];
    let mut s: String = shown.escape_ascii().to_string();
    if bytes.len() > shown.len() {
        s.push_str(&format!("… ({} bytes in all)", bytes.len()));
    }
    s
}

/// Where the input under test is written before each case when `save_current` is set, so
/// that a crash of the test binary (an abort, a kill for lack of memory) leaves it behind.
pub fn current_input_path(ext: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("fuzz-current-input.{ext}"))
}

/// What [`fuzz`] runs: a strategy of cases, how a case becomes bytes, and the check.
pub struct FuzzTarget<'a, S: Strategy> {
    /// Name in messages.
    pub name: &'a str,
    /// Generates cases.
    pub strategy: S,
    /// Turns a case into the input bytes.
    pub input: &'a dyn Fn(&S::Value) -> Vec<u8>,
    /// `Ok` when the code under test behaved (returned `Ok` or a proper error).
    pub check: &'a dyn Fn(&[u8]) -> Result<(), String>,
    /// Folder where a failing input is saved.
    pub regressions: &'a Path,
    /// Extension of saved inputs.
    pub ext: &'a str,
    /// Write every input to [`current_input_path`] before checking it.
    pub save_current: bool,
}

/// Runs `target.check` on generated inputs within `budget`. A failure is shrunk by proptest,
/// saved in `target.regressions` and reported with a panic naming the file.
pub fn fuzz<S: Strategy>(budget: Budget, target: FuzzTarget<'_, S>)
where
    S::Value: Debug,
{
    let config = Config {
        cases: budget.cases,
        failure_persistence: None,
        max_shrink_iters: 4096,
        max_shrink_time: 120_000,
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(budget.seed),
        ..Config::default()
    };
    let mut seed_bytes = [0u8; 32];
    seed_bytes[..8].copy_from_slice(&budget.seed.to_le_bytes());
    let mut runner = TestRunner::new_with_rng(
        config,
        TestRng::from_seed(RngAlgorithm::ChaCha, &seed_bytes),
    );
    let start = Instant::now();
    let failing = AtomicBool::new(false);
    let ran = AtomicU64::new(0);
    let result = runner.run(&target.strategy, |case| {
        if !failing.load(Ordering::Relaxed) && start.elapsed() > budget.time {
            return Ok(());
        }
        ran.fetch_add(1, Ordering::Relaxed);
        let bytes = (target.input)(&case);
        if target.save_current {
            let _ = std::fs::write(current_input_path(target.ext), &bytes);
        }
        (target.check)(&bytes).map_err(|m| {
            failing.store(true, Ordering::Relaxed);
            TestCaseError::fail(m)
        })
    });
    println!(
        "{}: {} inputs checked in {:.1} s (seed {}, budget {} cases / {:.0} s)",
        target.name,
        ran.load(Ordering::Relaxed),
        start.elapsed().as_secs_f64(),
        budget.seed,
        budget.cases,
        budget.time.as_secs_f64()
    );
    match result {
        Ok(()) => {}
        Err(TestError::Fail(reason, case)) => {
            let bytes = (target.input)(&case);
            let saved = save_input(target.regressions, target.ext, &bytes);
            panic!(
                "{}: {reason}\nminimal failing case {case:?}\nsaved as {} (keep it there: the regression test replays it):\n{}",
                target.name,
                saved.display(),
                preview(&bytes)
            );
        }
        Err(TestError::Abort(reason)) => panic!("{}: aborted: {reason}", target.name),
    }
}
