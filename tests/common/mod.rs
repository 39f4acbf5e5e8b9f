//! Helpers shared by the integration tests. A test file includes them with `mod common;` and
//! uses the submodules by name, e.g. `common::files::TempDir` or `common::stats::Estimate`.
//!
//! - [`chi2`]: chi-square p-values and critical values.
//! - [`sphere`]: the chi-square harness for direction samplers on the sphere.
//! - [`stats`]: mean, variance, standard error, z-scores.
//! - [`files`]: repository paths and self-removing temporary directories.
//! - [`cli`]: running the `velour` binary (or any command) and capturing its output.
//! - [`external`]: optional external programs (real OpenVDB) that skip, or fail under
//!   `VELOUR_REQUIRE_EXTERNAL=1`, when missing.
//! - [`levelset`]: level-set spheres written as OpenVDB files.
//! - [`render`]: rendering inline scene text, image and region means with standard errors.
//! - [`textured`]: the scene text, density grid and loading helpers of the textured-interior
//!   render tests.
//! - [`textures`]: small PNG/EXR texture files written into temporary directories.
//! - [`vdb_figures`]: OpenVDB's figures of a grid (JSON) against ours.

// Each test binary compiles every helper but uses only some of them.
#![allow(dead_code)]

pub mod chi2;
pub mod cli;
pub mod external;
pub mod files;
pub mod levelset;
pub mod render;
pub mod sphere;
pub mod stats;
pub mod textured;
pub mod textures;
pub mod vdb_figures;
