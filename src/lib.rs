//! # plume
//!
//! A production renderer for emissive heterogeneous volumes stored as OpenVDB files,
//! implementing *Line Integration for Rendering Heterogeneous Emissive Volumes* (Simon,
//! Hanika, Zirr, Dachsbacher, EGSR 2017). See `ARCHITECTURE.md` for the crate graph and
//! `../shared/METHOD.md` for the maths.
//!
//! This is the application layer, over the library crates (lowest first):
//! `plume-core` (errors, colour, sampling), `plume-scene` (the description),
//! `plume-volume` (bricks, pyramid, out of core), `plume-synth` (procedural volumes) and
//! `plume-engine` (medium, lights, integrator, film, render loop). Here live the OpenVDB
//! bridge ([`vdb`]), loading a description into a scene ([`load`]), brick cache conversion
//! ([`cache`]), image outputs ([`output`]), the farm's frame loop ([`farm`]), benchmarks
//! ([`bench`]) and `plume info` ([`info`]). Only the binary's `cli` writes to the terminal.
//!
//! Data flows one way:
//! `scene description → load (vdb shim or brick cache → volume: bricks + pyramid) → medium
//! → integrator → render → film → EXR`.

pub mod bench;
pub mod cache;
pub mod cpu;
pub mod farm;
pub mod info;
pub mod load;
pub mod output;
pub mod vdb;

pub use plume_core::error::{Error, Result};
