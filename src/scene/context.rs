//! The scene file being built: its path and text, for line numbers in messages and for
//! resolving the relative paths of the files it names.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use super::SceneError;

/// Where the scene comes from: what every reader and builder step needs to report an error
/// at a line or to find a file next to the scene.
pub(super) struct Ctx<'a> {
    /// The scene file (names it in messages; relative input paths start at its folder).
    pub path: &'a Path,
    /// The whole TOML text.
    pub text: &'a str,
    /// Every input path resolved so far (the files the scene loads), in order.
    pub inputs: RefCell<Vec<PathBuf>>,
    /// Textures loaded so far (shared by every parameter naming the same file and options).
    pub textures: std::cell::RefCell<super::textures::TextureCache>,
}

impl Ctx<'_> {
    /// The 1-based line of byte `offset` of the text.
    pub fn line_of(&self, offset: usize) -> usize {
        self.text[..offset.min(self.text.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count()
            + 1
    }

    /// A value outside its allowed range, a missing key or a loader failure at `line`.
    pub fn invalid(&self, line: usize, message: impl Into<String>) -> SceneError {
        SceneError::Invalid {
            path: self.path.to_path_buf(),
            line,
            message: message.into(),
        }
    }

    /// A syntax error, an unknown key or a value of the wrong type at `line`.
    pub fn parse(&self, line: usize, message: impl Into<String>) -> SceneError {
        SceneError::Parse {
            path: self.path.to_path_buf(),
            line,
            message: message.into(),
        }
    }

    /// An input path named by the scene: absolute as given, relative to the scene's folder.
    /// The path is recorded in [`Ctx::inputs`] (for the scene's content hash).
    pub fn resolve(&self, file: &str) -> PathBuf {
        let p = Path::new(file);
        let resolved = if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.path.parent().unwrap_or(Path::new(".")).join(p)
        };
        self.inputs.borrow_mut().push(resolved.clone());
        resolved
    }
}
