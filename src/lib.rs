//! # plume
//!
//! A production renderer for emissive heterogeneous volumes stored as OpenVDB files,
//! implementing *Line Integration for Rendering Heterogeneous Emissive Volumes* (Simon,
//! Hanika, Zirr, Dachsbacher, EGSR 2017). See `ARCHITECTURE.md` for the pipeline and
//! `../shared/METHOD.md` for the maths.
//!
//! Data flows one way:
//! `.vdb → vdb (shim) → volume (bricks + pyramid) → medium → integrator → film → EXR`.

pub mod app;
pub mod bench;
pub mod cache;
pub mod camera;
pub mod cli;
pub mod color;
pub mod error;
pub mod farm;
pub mod film;
pub mod info;
pub mod integrator;
pub mod light;
pub mod medium;
pub mod output;
pub mod render;
pub mod sampling;
pub mod stats;
pub mod synth;
pub mod vdb;
pub mod volume;

pub use error::{Error, Result};
