//! Benchmarks (`plume bench …`): speed and memory figures are measured here, never in
//! timed tests (STYLE.md §8). Each prints a table and can write JSON.

pub mod core;
pub mod methods;
