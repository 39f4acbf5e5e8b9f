//! Files for tests: paths into the repository and temporary directories that clean up.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// `relative` resolved against the repository root (the crate's manifest directory).
pub fn repo_path(relative: impl AsRef<Path>) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(relative)
}

/// A committed mesh: `scenes/meshes/<name>`.
pub fn mesh_path(name: &str) -> PathBuf {
    repo_path("scenes/meshes").join(name)
}

/// A committed OpenVDB fixture: `tests/data/vdb/<name>`.
pub fn vdb_fixture(name: &str) -> PathBuf {
    repo_path("tests/data/vdb").join(name)
}

/// A fresh, empty directory under Cargo's scratch directory for integration tests
/// (`target/tmp`), removed with everything in it when dropped.
///
/// Its name holds a label, the process id and a per-process counter, so tests running in
/// parallel (threads of one process, or several test binaries) never share one. When the
/// owning test panics the directory is kept, and its path printed, for inspection.
#[derive(Debug)]
pub struct TempDir {
    path: PathBuf,
}

impl TempDir {
    /// Creates `target/tmp/velour-<label>-<pid>-<n>`. Panics when it cannot be created.
    pub fn new(label: &str) -> TempDir {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let n = NEXT.fetch_add(1, Ordering::Relaxed);
        let path = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("velour-{label}-{}-{n}", std::process::id()));
        // A directory of the same name can only be left over from an earlier, crashed run
        // whose process id has been reused.
        let _ = std::fs::remove_dir_all(&path);
        std::fs::create_dir_all(&path)
            .unwrap_or_else(|e| panic!("cannot create {}: {e}", path.display()));
        TempDir { path }
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// `name` inside the directory.
    pub fn join(&self, name: impl AsRef<Path>) -> PathBuf {
        self.path.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("test files kept in {}", self.path.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.path);
        }
    }
}
