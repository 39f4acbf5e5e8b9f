//! velour — a Monte-Carlo volumetric path tracer for translucent creatures, fabric and
//! OpenVDB volumes, after N. Walster, "Volumetric Skin and Fabric Shading at Framestore"
//! (SIGGRAPH course notes).
//!
//! Layers (a module imports only from layers above it):
//! 1. [`math`], [`sampling`], [`spectrum`]
//! 2. [`grid`], [`vdb`], [`geometry`], [`phase`], [`bsdf`], [`camera`], [`film`], [`image_io`]
//! 3. [`fabric`], [`medium`]
//! 4. [`light`]
//! 5. [`scene`]
//! 6. [`integrator`], [`render`]
//! 7. [`cli`] and the `velour` binary.

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
pub mod vdb;

pub mod fabric;
pub mod majorant;
pub mod medium;
pub mod tracking;
pub mod volume;

pub mod light;

pub mod scene;

pub mod integrator;
pub mod render;

pub mod cli;
