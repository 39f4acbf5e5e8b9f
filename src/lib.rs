//! velour — a Monte-Carlo volumetric path tracer for translucent creatures, fabric and
//! OpenVDB volumes, after N. Walster, "Volumetric Skin and Fabric Shading at Framestore"
//! (SIGGRAPH course notes).
//!
//! Modules are layered: each imports only from the layers below it (docs/architecture.md
//! names the layers; `tests/architecture_layers.rs` enforces them).

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
