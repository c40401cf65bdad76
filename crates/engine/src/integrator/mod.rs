//! Integrators: radiance along camera rays.
//!
//! [`Integrator`] (in `volpath.rs`) traces forward paths with line-integrated emission and
//! optional NEE/FNEE; with `max_depth = 0` or albedo 0 it is the emission–absorption
//! integrator `L = ∫₀^d τ(s) L_e(s) ds`. Alpha is `1 − τ(d)` of the camera segment
//! (estimated: the escape indicator, or the exact ray-marched transmittance).

pub mod aov;
mod buffered;
mod build;
pub mod counters;
pub mod deferred;
mod groups;
pub mod lights;
pub mod path;
mod scatter;
pub mod scene;
pub mod split_map;
pub mod trace;
pub mod tracker;
pub mod volpath;

pub use aov::{AovLayout, AovSample, Aovs, Component, NoAovs};
pub use buffered::BufferedPoints;
pub use counters::Counters;
pub use lights::{light_power, LightSampling, Lights, MisHeuristic};
pub use path::PathState;
pub use scene::{AnyScene, Scene};
pub use split_map::{SplitBy, SplitMap};
pub use trace::{LineTrace, NoTrace, Trace};
pub use tracker::{PointLookup, Tracking};
pub use volpath::Integrator;
