//! # plume-core
//!
//! What every layer of plume shares: the library's one error type ([`Error`], with the
//! process exit codes in [`error::exit`]), colour ([`color`]: RGB, CIE 1931, blackbody),
//! sampling ([`sampling`]: the sampler keyed by sample and dimension, warps, alias tables,
//! piecewise-constant distributions, phase functions) and atomic file writes ([`fs`]).
//!
//! **Architecture invariant:** pure building blocks. Nothing here prints, exits, reads an
//! environment variable or knows about scenes, volumes or rendering; randomness enters
//! as arguments (`u`), never from a global generator.

pub mod choice;
pub mod color;
pub mod error;
pub mod fs;
pub mod sampling;
pub mod stop;

pub use error::{Error, Result};
