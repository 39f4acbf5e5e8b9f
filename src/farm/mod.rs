//! Splitting renders across processes and machines, and putting them back together exactly:
//! tiles (horizontal bands of rows), sample ranges and frame ranges, the metadata every part
//! and image carries, the scene's content hash, and the merge.
//!
//! Exactness rests on two facts of the layers below: every random number is a function of
//! (seed, pixel, sample index, dimension), and the film's sums are exact integers
//! ([`crate::film`]). A part holds the exact film state of its rows and samples; adding the
//! parts' states gives the same bits as one process rendering everything.

pub mod hash;
pub mod merge;
pub mod part;
pub mod split;

pub use merge::{merge_parts, MergeError};
pub use part::PartInfo;
pub use split::{FrameRange, SampleRange, TileSpec};

/// velour's version as written into image metadata: the crate version, plus the git commit
/// when built from a checkout (`0.1.0+3f2a9c1d0b7e`).
#[must_use]
pub fn version() -> String {
    match option_env!("VELOUR_GIT_COMMIT") {
        Some(c) => format!("{}+{c}", env!("CARGO_PKG_VERSION")),
        None => env!("CARGO_PKG_VERSION").to_string(),
    }
}
