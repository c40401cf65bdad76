//! # plume
//!
//! A production renderer for emissive heterogeneous volumes stored as OpenVDB files,
//! implementing *Line Integration for Rendering Heterogeneous Emissive Volumes* (Simon,
//! Hanika, Zirr, Dachsbacher, EGSR 2017). See `ARCHITECTURE.md` for the pipeline and
//! `../shared/METHOD.md` for the maths.
//!
//! Data flows one way:
//! `scene description → load (vdb shim or brick cache → volume: bricks + pyramid) → medium
//! → integrator → render → film → EXR`.
//!
//! The library has no command-line types: the `plume` binary turns flags and scene files
//! into a [`scene::Shot`], validates it once, and hands it to `farm::job`.

pub mod bench;
pub mod cache;
pub mod camera;
pub mod color;
pub mod cpu;
pub mod denoise;
pub mod error;
pub mod farm;
pub mod film;
pub mod info;
pub mod integrator;
pub mod light;
pub mod load;
pub mod mapfault;
pub mod medium;
pub mod memory;
pub mod output;
pub mod pilot;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod stats;
pub mod synth;
pub mod vdb;
pub mod volume;

pub use error::{Error, Result};
