//! velour — a Monte-Carlo volumetric path tracer for translucent creatures, fabric and
//! OpenVDB volumes, after N. Walster, "Volumetric Skin and Fabric Shading at Framestore"
//! (SIGGRAPH course notes).
//!
//! Modules are layered: each imports only from the layers below it (docs/architecture.md
//! names the layers; `tests/architecture_layers.rs` enforces them).

// Negated comparisons are the crate's NaN-rejecting idiom: `!(x > 0.0)` reads "not positive"
// and is true for NaN, where `x <= 0.0` would be false, so a NaN density, distance or pdf takes
// the rejecting branch. They are written this way on purpose wherever they appear (one policy
// for the whole crate, in place of the former per-module allows).
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod math;
pub mod sampling;
pub mod spectrum;

pub mod bsdf;
pub mod camera;
pub mod film;
pub mod geometry;
pub mod grid;
pub mod image_io;
pub mod phase;
pub mod texture;
pub mod vdb;

pub mod majorant;
pub mod tracking;

pub mod fabric;
pub mod procedural;

pub mod medium;
pub mod voxelize;

pub mod light;

pub mod scene;

pub mod integrator;
pub mod render;

pub mod farm;

pub mod cli;
