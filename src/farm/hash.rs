//! The scene's content hash: SHA-256 over the scene text, the contents of every file it loads
//! and the command-line settings that change pixels. Parts and checkpoints carry it, and
//! `velour merge` and `--resume` refuse files whose hash differs.

use std::io::Read;
use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

/// Errors of hashing.
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot read for the scene hash: {source}")]
pub struct HashError {
    /// The file.
    pub path: PathBuf,
    /// Cause.
    pub source: std::io::Error,
}

/// SHA-256 (lower-case hex) of `scene_text`, then each file of `inputs` (its contents, in
/// order; paths are not hashed, so the same files on another mount point hash the same), then
/// `settings` (the pixel-affecting command-line overrides, as text). Each piece is preceded by
/// its length, so no two different inputs concatenate to the same stream.
pub fn scene_hash(
    scene_text: &str,
    inputs: &[PathBuf],
    settings: &str,
) -> Result<String, HashError> {
    let mut h = Sha256::new();
    h.update(b"velour scene hash 1\n");
    piece(scene_text.as_bytes(), &mut h);
    for path in inputs {
        hash_file(path, &mut h)?;
    }
    piece(settings.as_bytes(), &mut h);
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

fn piece(bytes: &[u8], h: &mut Sha256) {
    h.update((bytes.len() as u64).to_le_bytes());
    h.update(bytes);
}

fn hash_file(path: &Path, h: &mut Sha256) -> Result<(), HashError> {
    let err = |source| HashError {
        path: path.to_path_buf(),
        source,
    };
    let mut file = std::fs::File::open(path).map_err(err)?;
    let len = file.metadata().map_err(err)?.len();
    h.update(len.to_le_bytes());
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = file.read(&mut buf).map_err(err)?;
        if n == 0 {
            return Ok(());
        }
        h.update(&buf[..n]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hash_depends_on_text_files_and_settings() {
        let dir = std::env::temp_dir().join(format!("velour-hash-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("a.bin");
        std::fs::write(&f, b"one").unwrap();
        let a = scene_hash("x = 1", std::slice::from_ref(&f), "spp=4").unwrap();
        assert_eq!(a.len(), 64);
        assert_eq!(
            a,
            scene_hash("x = 1", std::slice::from_ref(&f), "spp=4").unwrap()
        );
        assert_ne!(
            a,
            scene_hash("x = 2", std::slice::from_ref(&f), "spp=4").unwrap()
        );
        assert_ne!(
            a,
            scene_hash("x = 1", std::slice::from_ref(&f), "spp=8").unwrap()
        );
        std::fs::write(&f, b"two").unwrap();
        assert_ne!(
            a,
            scene_hash("x = 1", std::slice::from_ref(&f), "spp=4").unwrap()
        );
        assert!(scene_hash("x", &[dir.join("missing")], "").is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
