//! Optics: the medium's coefficients, emission models and free-path tracking with the
//! emission estimators of METHOD.md §3–4. This module consumes only
//! [`plume_volume::Segment`]s; it never indexes a voxel.
//!
//! Units: `sigma_t` is per world unit (metre) per unit density, so `μ_t = σ_t ρ`;
//! `μ_s = a μ_t`, `μ_a = (1 − a) μ_t`; a chromatic medium's channel `c` has `k_c μ_t`
//! (`extinction`, walked by `chromatic`). Emission density `L_e` is radiance added per
//! unit length (W m⁻³ sr⁻¹ per RGB channel) and already contains its coefficient.

pub mod chromatic;
pub mod coefficients;
pub mod emission;
pub mod extinction;
pub mod forced;
pub mod free_path;
pub mod null_tracking;
pub mod tracking;

pub use coefficients::Medium;
pub use emission::{Convention, Emission, EmissionKind, TemperatureMap};
pub use extinction::{Chromatic, Extinction};
pub use forced::Collision;
pub use tracking::{track, DistanceSample, Estimator, ShadowResult, TrackResult};
