//! The start-up check that this CPU runs the instruction sets the binary was compiled for.
//!
//! velour builds for `x86-64-v3` on x86-64 (`.cargo/config.toml`: AVX, AVX2, BMI1, BMI2, F16C,
//! FMA, LZCNT, MOVBE, the OS saving the AVX registers; every x86-64 server CPU since about 2015).
//! The compiler may then use those instructions anywhere, and a CPU without them stops the
//! process with SIGILL at the first one. So `main` asks the CPU first, by `cpuid` (not by
//! `is_x86_feature_detected!`, which answers "yes" at compile time for a feature the build
//! enables), and exits with a message instead. A build for another CPU level
//! (`RUSTFLAGS="-C target-cpu=x86-64"`) checks only what it was compiled for.
//!
//! The failure path is kept to integer code and calls into the standard library, which is
//! compiled for the baseline, so that it runs on the CPUs it reports.

/// The `cpuid` and `xgetbv` words the check reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CpuWords {
    /// Leaf 1, ECX: FMA (bit 12), MOVBE (22), OSXSAVE (27), AVX (28), F16C (29).
    pub leaf1_ecx: u32,
    /// Leaf 7 sub-leaf 0, EBX: BMI1 (bit 3), AVX2 (5), BMI2 (8).
    pub leaf7_ebx: u32,
    /// Leaf 0x8000_0001, ECX: LZCNT (bit 5).
    pub ext1_ecx: u32,
    /// XCR0 (`xgetbv(0)`), when OSXSAVE is set: the OS saves SSE (bit 1) and AVX (bit 2) state.
    pub xcr0: u64,
}

/// One feature the check knows: its name, and whether the build was compiled for it.
struct Feature {
    name: &'static str,
    compiled: bool,
    present: fn(&CpuWords) -> bool,
}

const fn bit32(word: u32, bit: u32) -> bool {
    (word >> bit) & 1 == 1
}

/// The features in the order they are checked (the first one missing is reported).
const FEATURES: [Feature; 8] = [
    Feature {
        name: "AVX (with the operating system saving its registers)",
        compiled: cfg!(target_feature = "avx"),
        present: |w| bit32(w.leaf1_ecx, 28) && bit32(w.leaf1_ecx, 27) && w.xcr0 & 0b110 == 0b110,
    },
    Feature {
        name: "AVX2",
        compiled: cfg!(target_feature = "avx2"),
        present: |w| bit32(w.leaf7_ebx, 5),
    },
    Feature {
        name: "FMA",
        compiled: cfg!(target_feature = "fma"),
        present: |w| bit32(w.leaf1_ecx, 12),
    },
    Feature {
        name: "BMI1",
        compiled: cfg!(target_feature = "bmi1"),
        present: |w| bit32(w.leaf7_ebx, 3),
    },
    Feature {
        name: "BMI2",
        compiled: cfg!(target_feature = "bmi2"),
        present: |w| bit32(w.leaf7_ebx, 8),
    },
    Feature {
        name: "LZCNT",
        compiled: cfg!(target_feature = "lzcnt"),
        present: |w| bit32(w.ext1_ecx, 5),
    },
    Feature {
        name: "F16C",
        compiled: cfg!(target_feature = "f16c"),
        present: |w| bit32(w.leaf1_ecx, 29),
    },
    Feature {
        name: "MOVBE",
        compiled: cfg!(target_feature = "movbe"),
        present: |w| bit32(w.leaf1_ecx, 22),
    },
];

/// The first instruction set the build was compiled for that `words` do not report, or `None`.
#[must_use]
pub fn first_missing(words: &CpuWords) -> Option<&'static str> {
    FEATURES
        .iter()
        .find(|f| f.compiled && !(f.present)(words))
        .map(|f| f.name)
}

/// This CPU's words (all zero off x86-64, where the build enables none of these features).
#[must_use]
pub fn read_words() -> CpuWords {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{__cpuid, __cpuid_count};
        // A leaf above the highest the CPU reports (asked first) is not asked.
        let max = __cpuid(0).eax;
        let leaf1_ecx = if max >= 1 { __cpuid(1).ecx } else { 0 };
        let leaf7_ebx = if max >= 7 { __cpuid_count(7, 0).ebx } else { 0 };
        let max_ext = __cpuid(0x8000_0000).eax;
        let ext1_ecx = if max_ext >= 0x8000_0001 {
            __cpuid(0x8000_0001).ecx
        } else {
            0
        };
        let xcr0 = if bit32(leaf1_ecx, 27) { xgetbv0() } else { 0 };
        CpuWords {
            leaf1_ecx,
            leaf7_ebx,
            ext1_ecx,
            xcr0,
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    CpuWords::default()
}

/// XCR0, read with `xgetbv` (only called when `cpuid` reports OSXSAVE).
#[cfg(target_arch = "x86_64")]
fn xgetbv0() -> u64 {
    let (lo, hi): (u32, u32);
    // SAFETY: `xgetbv` with ECX = 0 is defined whenever CPUID.1:ECX.OSXSAVE is set, which
    // the caller checked; it reads a register and touches no memory.
    unsafe {
        std::arch::asm!("xgetbv", in("ecx") 0u32, out("eax") lo, out("edx") hi,
            options(nomem, nostack, preserves_flags));
    }
    u64::from(lo) | (u64::from(hi) << 32)
}

/// Exits with status 1 and a message naming the missing instruction set when this CPU lacks
/// one the build was compiled for. Called first thing in `main`.
pub fn exit_unless_supported() {
    if let Some(name) = first_missing(&read_words()) {
        refuse(name);
    }
}

/// The failure path: static bytes through the standard library only (see the module docs).
#[cold]
#[inline(never)]
fn refuse(name: &'static str) -> ! {
    use std::io::Write;
    let mut err = std::io::stderr().lock();
    // Nothing useful can be done if stderr is closed: the exit status still says it failed.
    let _ = err.write_all(b"error: this CPU lacks ");
    let _ = err.write_all(name.as_bytes());
    let _ = err.write_all(
        b", which this build of velour was compiled for (x86-64-v3: AVX2, FMA, BMI1/2, \
LZCNT, F16C, MOVBE). Rebuild it for this CPU with RUSTFLAGS=\"-C target-cpu=native\" \
cargo build --release (or target-cpu=x86-64 for any x86-64 CPU).\n",
    );
    std::process::exit(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Words with every checked feature present.
    fn full() -> CpuWords {
        CpuWords {
            leaf1_ecx: (1 << 12) | (1 << 22) | (1 << 27) | (1 << 28) | (1 << 29),
            leaf7_ebx: (1 << 3) | (1 << 5) | (1 << 8),
            ext1_ecx: 1 << 5,
            xcr0: 0b111,
        }
    }

    #[test]
    fn this_machine_runs_what_the_build_was_compiled_for() {
        // The test binary is compiled with the same flags as velour: it would not have got
        // here on a CPU without them, so the check must agree.
        assert_eq!(first_missing(&read_words()), None);
    }

    #[test]
    fn each_missing_feature_the_build_uses_is_named() {
        assert_eq!(first_missing(&full()), None);
        type Clear = fn(&mut CpuWords);
        let cases: [(&str, Clear); 9] = [
            (
                "AVX (with the operating system saving its registers)",
                |w| w.leaf1_ecx &= !(1 << 28),
            ),
            (
                "AVX (with the operating system saving its registers)",
                |w| w.xcr0 = 0b011,
            ),
            (
                "AVX (with the operating system saving its registers)",
                |w| w.leaf1_ecx &= !(1 << 27),
            ),
            ("AVX2", |w| w.leaf7_ebx &= !(1 << 5)),
            ("FMA", |w| w.leaf1_ecx &= !(1 << 12)),
            ("BMI1", |w| w.leaf7_ebx &= !(1 << 3)),
            ("BMI2", |w| w.leaf7_ebx &= !(1 << 8)),
            ("LZCNT", |w| w.ext1_ecx = 0),
            ("F16C", |w| w.leaf1_ecx &= !(1 << 29)),
        ];
        for (name, clear) in cases {
            let mut w = full();
            clear(&mut w);
            let compiled = FEATURES.iter().any(|f| f.name == name && f.compiled);
            let want = compiled.then_some(name);
            assert_eq!(first_missing(&w), want, "{name}");
        }
        let mut w = full();
        w.leaf1_ecx &= !(1 << 22);
        assert_eq!(
            first_missing(&w),
            cfg!(target_feature = "movbe").then_some("MOVBE")
        );
        // A CPU with none of them: the first the build uses.
        let first = FEATURES.iter().find(|f| f.compiled).map(|f| f.name);
        assert_eq!(first_missing(&CpuWords::default()), first);
    }

    #[test]
    fn the_repository_builds_for_x86_64_v3() {
        // `.cargo/config.toml` asks for x86-64-v3 on x86-64; a build that lost the setting
        // would run but miss the measured speed (docs/BENCHMARKS.md). An explicit RUSTFLAGS
        // replaces the file's flags: such a build is the user's choice and skips this test.
        if option_env!("RUSTFLAGS").is_some() || !cfg!(target_arch = "x86_64") {
            eprintln!("skipped: RUSTFLAGS set or not x86-64");
            return;
        }
        let compiled = [cfg!(target_feature = "avx2"), cfg!(target_feature = "fma")];
        assert_eq!(compiled, [true, true], "AVX2 and FMA compiled in");
    }
}
