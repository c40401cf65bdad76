//! Light sampling building blocks for the path integrator (METHOD.md §6–8).
//!
//! Two kinds of light: the volume's own emission, and [`external`] lights (suns, sphere
//! and point lights, environment maps, the built-in [`sky`]), sampled as a separate
//! strategy. Two techniques sample the volume's own emission:
//!
//! - [`nee`]: volume-measure next-event estimation (Villemin & Hery 2013): a *point* `y`
//!   drawn from the full-resolution emissive voxels ∝ power, density per unit world volume.
//! - [`fnee`]: a *direction* drawn through the coarse proxy grid
//!   ([`plume_volume::proxy`]), density per unit solid angle.
//!
//! All are pure: randomness enters as `u` arguments, so each sample/pdf pair is
//! chi²-tested (`tests/light_sampling.rs` for the volume's). Emission enters as a closure
//! `power(density, source) = Y(L_e)`, keeping the data side free of optics.
//!
//! Light from outside the volume:
//!
//! - [`external`]: the lights and their sampling for the integrator;
//! - [`envmap`]: lat-long environment maps looked up per pixel, directions drawn ∝
//!   luminance · sin θ, density per unit solid angle (chi²-tested in
//!   `tests/environment_map.rs`);
//! - [`sky`]: Preetham et al.'s (1999) analytic daylight sky and sun disc, as radiance per
//!   direction or as a lat-long environment map, and plume's lat-long convention.

mod by_power;
pub mod envmap;
pub mod external;
pub mod fnee;
pub mod mixture;
pub mod nee;
mod nee_bricks;
pub mod nee_mixture;
pub mod power;
pub mod sky;
pub mod weigh;

pub use fnee::{DirectionSample, ProxyPoint};
pub use nee::{EmitterDistribution, VoxelSample};
pub use power::LightPower;
