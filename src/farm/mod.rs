//! Render-farm behaviour of `plume render` and `plume merge`: frame sequences and
//! patterns, skip/continue/overwrite of outputs, splitting a frame into tiles and sample
//! ranges and merging them exactly, signals, time limits, exit codes, progress lines and
//! per-frame cost records. See docs/farm.md and `ARCHITECTURE.md`.
//!
//! Nothing here prints: messages go through the `log` facade, progress and replays to
//! the application's [`observer::JobObserver`], progress lines to its sink
//! ([`progress::Progress`]).

pub mod fingerprint;
pub mod frame;
pub mod job;
pub mod layers;
pub mod merge;
pub mod observer;
pub mod outputs;
pub mod part;
pub mod pattern;
pub mod plan;
pub mod progress;
mod resume;
pub mod signals;

pub use plume_scene::{frames, split};
