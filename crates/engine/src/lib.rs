//! # plume-engine
//!
//! The optics and the render: the medium and its free-path tracking with the emission
//! estimators ([`medium`]), light sampling ([`light`]: NEE, FNEE, lights besides the
//! volume), the path integrator ([`integrator`]), the camera ([`camera`]), the render loop
//! over passes and tiles ([`render`], with [`pilot`] for splitting by brightness), the film
//! of exact fixed-point sums ([`film`]), error estimates and adaptive sampling ([`noise`]),
//! the denoiser ([`denoise`]) and per-frame statistics ([`stats`]).
//!
//! Data flows one way: a loaded [`integrator::Scene`] (volume, medium, camera, lights) is
//! rendered by [`render::render`] into a [`film::Film`], whose sums become pixels.
//!
//! **Architecture invariants:** the render phase is infallible (loading returns `Result`,
//! rendering does not); estimators see the volume only through `Field::segments` and never
//! index a voxel; the same inputs and seed give the same bits at any thread count and any
//! tiling. Nothing here prints, exits or reads the environment: progress goes to a
//! [`render::RenderObserver`], messages through the `log` facade.

pub mod camera;
pub mod denoise;
pub mod film;
pub mod integrator;
pub mod light;
pub mod medium;
pub mod moments;
pub mod noise;
pub mod overlap;
pub mod pilot;
pub mod render;
pub mod stats;
