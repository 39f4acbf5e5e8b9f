//! Optional external programs: real OpenVDB (Debian's `python3-openvdb` bindings and the
//! `libopenvdb-tools` command-line tools), used to cross-check our VDB reader and writer.
//!
//! A test that needs one starts with
//!
//! ```ignore
//! if !external::require_python_openvdb() {
//!     return;
//! }
//! ```
//!
//! When the program is missing the check prints `skipping <test>: <program> not found
//! (apt-get install <package>); ...` and returns `false`, so the test passes without running
//! on a machine that has only Rust. With the environment variable
//! [`REQUIRE_EXTERNAL`]` = 1` (as CI sets it) a missing program fails the test instead, so
//! that a broken installation cannot pass silently.

use std::ffi::OsStr;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use super::cli::Capture;

/// Environment variable that turns a missing external program into a test failure when set
/// to `1`.
pub const REQUIRE_EXTERNAL: &str = "VELOUR_REQUIRE_EXTERNAL";

/// The interpreter Debian's `python3-openvdb` installs its module for.
pub const PYTHON: &str = "/usr/bin/python3";

/// The module name of OpenVDB's Python bindings (OpenVDB 10, as Debian ships it).
pub const PYTHON_OPENVDB_MODULE: &str = "pyopenvdb";

/// Debian package of OpenVDB's Python bindings.
pub const PYTHON_OPENVDB_PACKAGE: &str = "python3-openvdb";

/// Debian package of OpenVDB's command-line tools (`vdb_tool`, `vdb_print`).
pub const OPENVDB_TOOLS_PACKAGE: &str = "libopenvdb-tools";

/// Whether [`REQUIRE_EXTERNAL`] is set to `1`.
pub fn external_required() -> bool {
    std::env::var_os(REQUIRE_EXTERNAL).is_some_and(|v| v == "1")
}

/// Whether [`PYTHON`] can import OpenVDB's bindings; when it cannot, reports the skip (or
/// fails, see the module docs). Checked once per test binary.
pub fn require_python_openvdb() -> bool {
    static AVAILABLE: OnceLock<bool> = OnceLock::new();
    let available = *AVAILABLE.get_or_init(|| {
        Command::new(PYTHON)
            .args(["-c", &format!("import {PYTHON_OPENVDB_MODULE}")])
            .output()
            .is_ok_and(|o| o.status.success())
    });
    available
        || missing(
            &format!("{PYTHON} with module {PYTHON_OPENVDB_MODULE}"),
            PYTHON_OPENVDB_PACKAGE,
        )
}

/// Whether [`PYTHON`] can import numpy (Debian package python3-numpy), for the tool scripts'
/// own checks; when it cannot, reports the skip (or fails, see the module docs).
pub fn require_python_numpy() -> bool {
    static AVAILABLE: OnceLock<bool> = OnceLock::new();
    let available = *AVAILABLE.get_or_init(|| {
        Command::new(PYTHON)
            .args(["-c", "import numpy"])
            .output()
            .is_ok_and(|o| o.status.success())
    });
    available || missing(&format!("{PYTHON} with module numpy"), "python3-numpy")
}

/// Whether `program` is an executable on `PATH`; when it is not, reports the skip (or fails,
/// see the module docs), suggesting Debian's `package`.
pub fn require_tool(program: &str, package: &str) -> bool {
    find_on_path(program).is_some() || missing(program, package)
}

/// The first executable file named `program` in the directories of `PATH`.
pub fn find_on_path(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(program))
        .find(|p| is_executable(p))
}

fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

/// Reports a missing program: a failure when [`external_required`], else a notice on the
/// terminal. Returns `false` (the test should return early).
fn missing(what: &str, package: &str) -> bool {
    let test = std::thread::current()
        .name()
        .unwrap_or("this test")
        .to_string();
    if external_required() {
        panic!("{test}: {what} not found (apt-get install {package}), and {REQUIRE_EXTERNAL}=1 requires it");
    }
    // Straight to the stderr stream, past the test harness's output capture, so that the
    // skip shows in a normal `cargo test` run.
    let _ = writeln!(
        std::io::stderr(),
        "skipping {test}: {what} not found (apt-get install {package}); \
         set {REQUIRE_EXTERNAL}=1 to make this a failure"
    );
    false
}

/// Runs [`PYTHON`] with `args` and returns its standard output; panics with its standard
/// error when it fails. Call [`require_python_openvdb`] first when the script needs OpenVDB.
pub fn run_python<I, S>(args: I) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let out = Command::new(PYTHON).args(args).capture();
    assert!(
        out.success(),
        "{PYTHON} failed ({}): {}",
        out.status,
        out.stderr
    );
    out.stdout
}
