//! Closed sets of named values that a scene description, a scene file and the command
//! line all spell the same way (kebab-case names, one help line each).
//!
//! Each set is a plain `enum` with a [`Choice`] table. The table gives `FromStr` and
//! `Display` (the names), serde (a scene file holds the names), and the command line's
//! list of possible values with their help (the binary builds its value parsers from
//! [`Choice::CHOICES`]), so a name is written once.

use plume_core::choice;
pub use plume_core::choice::Choice;
pub use plume_core::sampling::SamplerKind;

pub use crate::sets::Interpolation;
use crate::sets::{
    Collision, Convention, Estimator, LightSampling, MisHeuristic, PointLookup, SplitBy, Tracking,
};

/// The paper's methods (its conclusion table) as presets of estimator + light sampling.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Collision estimator + classic NEE with MIS in volume measure.
    PointNee,
    /// Line integration + classic NEE (no MIS partner).
    LineNee,
    /// Line integration + forward NEE with MIS (the paper's method).
    LineFnee,
    /// Expected-value (ray-marching) estimator, forward paths only.
    RayMarch,
}

choice!(Method {
    "point-nee" => Method::PointNee, "Collision estimator + classic NEE with MIS in volume measure";
    "line-nee" => Method::LineNee, "Line integration + classic NEE (no MIS partner)";
    "line-fnee" => Method::LineFnee, "Line integration + forward NEE with MIS (the paper's method)";
    "ray-march" => Method::RayMarch, "Expected-value (ray-marching) estimator, forward paths only";
});

impl Method {
    /// The preset's estimator and light sampling.
    #[must_use]
    pub fn parts(self) -> (EstimatorKind, LightSampling) {
        match self {
            Method::PointNee => (EstimatorKind::Point, LightSampling::Nee),
            Method::LineNee => (EstimatorKind::Line, LightSampling::Nee),
            Method::LineFnee => (EstimatorKind::Line, LightSampling::Fnee),
            Method::RayMarch => (EstimatorKind::RayMarch, LightSampling::None),
        }
    }
}

/// An emission estimator by name; [`EstimatorKind::with_kappa`] makes the
/// [`Estimator`] (the blend estimator carries its κ).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EstimatorKind {
    /// Collision estimator `L_e/μ_t` at sampled collisions.
    Point,
    /// Track-length estimator (line integration, the paper's).
    Line,
    /// Expected-value estimator (exact per-voxel closed form, deterministic).
    RayMarch,
    /// Per-voxel blend of line and point (κ).
    Blend,
}

choice!(EstimatorKind {
    "point" => EstimatorKind::Point, "Collision estimator L_e/μ_t at sampled collisions";
    "line" => EstimatorKind::Line, "Track-length estimator (line integration, the paper's)";
    "ray-march" => EstimatorKind::RayMarch, "Expected-value estimator (exact per-voxel closed form, deterministic)";
    "blend" => EstimatorKind::Blend, "Per-voxel blend of line and point (kappa)";
});

impl EstimatorKind {
    /// The estimator, with `kappa` for [`EstimatorKind::Blend`].
    #[must_use]
    pub fn with_kappa(self, kappa: f64) -> Estimator {
        match self {
            EstimatorKind::Point => Estimator::Point,
            EstimatorKind::Line => Estimator::Line,
            EstimatorKind::RayMarch => Estimator::RayMarch,
            EstimatorKind::Blend => Estimator::Blend { kappa },
        }
    }
}

choice!(LightSampling {
    "none" => LightSampling::None, "Forward (phase-sampled) paths only";
    "nee" => LightSampling::Nee, "Classic NEE to emissive voxels (volume measure)";
    "fnee" => LightSampling::Fnee, "Forward NEE: proxy direction + free path, MIS in solid angle";
});

/// How a camera ray's collision is drawn when paths scatter (`medium::forced`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraCollision {
    /// Forced collisions, where the camera segment is ray-marched by regular tracking.
    Forced,
    /// The analog free path.
    Analog,
}

choice!(CameraCollision {
    "forced" => CameraCollision::Forced, "Every camera ray that meets the medium may scatter, weighted by its collision probability (needs a ray-marched camera segment)";
    "analog" => CameraCollision::Analog, "A camera ray scatters only where its free path ends (the paper's)";
});

impl CameraCollision {
    /// What the walk is asked for.
    #[must_use]
    pub fn collision(self) -> Collision {
        match self {
            CameraCollision::Forced => Collision::Forced,
            CameraCollision::Analog => Collision::Analog,
        }
    }
}

/// Resolution of classic NEE's table (`light::nee`, `light::nee_bricks`): a voxel is
/// drawn from one table entry per emitting voxel, or from its brick's entry and then the
/// brick's values. The same law either way; the brick table needs no memory per voxel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NeeTable {
    /// 16 bytes per emitting voxel.
    #[default]
    Voxel,
    /// 32 bytes per emitting brick; a sample weighs its brick's voxels.
    Brick,
}

choice!(NeeTable {
    "voxel" => NeeTable::Voxel, "One entry per emitting voxel (16 bytes each): the fastest samples";
    "brick" => NeeTable::Brick, "One entry per emitting brick, the voxel drawn from the brick's values: for volumes whose voxel table does not fit in memory";
});

impl NeeTable {
    /// Whether this is the default (`voxel`): scene files and the settings hash leave it out.
    #[must_use]
    pub fn is_voxel(&self) -> bool {
        *self == NeeTable::Voxel
    }
}

/// How segments are tracked, before the estimator is known (`auto` is resolved by
/// [`TrackingChoice::resolve`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrackingChoice {
    /// `mixed` where the estimator and light sampling allow it ([`Tracking::applies`]),
    /// else `regular`.
    Auto,
    /// [`Tracking::Regular`].
    Regular,
    /// [`Tracking::Mixed`].
    Mixed,
    /// [`Tracking::Null`].
    Null,
}

choice!(TrackingChoice {
    "auto" => TrackingChoice::Auto, "mixed, or regular where null collisions do not apply (blend, point estimator with classic NEE)";
    "regular" => TrackingChoice::Regular, "Exact regular tracking of every segment (the paper's)";
    "mixed" => TrackingChoice::Mixed, "Regular tracking of camera segments, null collisions after scattering";
    "null" => TrackingChoice::Null, "Null-collision tracking of every segment (METHOD.md §13)";
});

impl TrackingChoice {
    /// The tracking for `estimator` and `light_sampling`.
    #[must_use]
    pub fn resolve(self, estimator: Estimator, light_sampling: LightSampling) -> Tracking {
        match self {
            TrackingChoice::Auto if Tracking::applies(estimator, light_sampling) => Tracking::Mixed,
            TrackingChoice::Auto | TrackingChoice::Regular => Tracking::Regular,
            TrackingChoice::Mixed => Tracking::Mixed,
            TrackingChoice::Null => Tracking::Null,
        }
    }
}

choice!(PointLookup {
    "stochastic" => PointLookup::Stochastic, "One voxel per tentative point, picked with its trilinear weight (unbiased, one read instead of eight); emission points read the trilinear value";
    "stochastic-emission" => PointLookup::StochasticEmission, "Also one picked voxel per emission point after scattering: faster, but single samples in a fire reach larger values (fireflies)";
    "exact" => PointLookup::Exact, "The trilinear value (eight voxels) at every tentative and emission point";
});

choice!(SplitBy {
    "uniform" => SplitBy::Uniform, "--split paths at every camera collision";
    "brightness" => SplitBy::Brightness, "Per pixel, more paths where the scattered light is brighter (from a low-resolution pilot render), --split on average over the smoke";
});

choice!(MisHeuristic {
    "balance" => MisHeuristic::Balance, "Balance heuristic";
    "power" => MisHeuristic::Power, "Power heuristic (exponent 2)";
});

choice!(Convention {
    "physical" => Convention::Physical, "Emission density ∝ density × source";
    "cycles" => Convention::Cycles, "Blender Cycles' Principled Volume: emission not multiplied by density";
});

/// What drives emission, before the grids are read (`auto` is resolved against the file).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmissionSource {
    /// Blackbody if the temperature grid exists, else the first emission grid found.
    Auto,
    /// Blackbody from the temperature grid.
    Blackbody,
    /// Scalar emission grid × colour × scale.
    Grid,
    /// No emission (absorption only).
    None,
}

choice!(EmissionSource {
    "auto" => EmissionSource::Auto, "Blackbody if the temperature grid exists, else an emission grid if one of `emission`, `flame`, `heat`, `flame_noise` exists, else none";
    "blackbody" => EmissionSource::Blackbody, "Blackbody from the temperature grid";
    "grid" => EmissionSource::Grid, "Scalar emission grid × colour × scale";
    "none" => EmissionSource::None, "No emission (absorption only)";
});

/// The order in which samples are taken (the image is the same either way).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SampleOrderChoice {
    /// Tile-major for a mapped cache larger than the memory available (MemAvailable or
    /// what the cgroup memory limit leaves), with a fixed spp and no time limit;
    /// progressive otherwise.
    #[default]
    Auto,
    /// Passes over the whole image.
    Progressive,
    /// Each tile's samples together, tiles in order, bricks read ahead.
    TileMajor,
}

choice!(SampleOrderChoice {
    "auto" => SampleOrderChoice::Auto, "Tile-major when the volume is a mapped cache larger than available memory and the render has a fixed spp and no time limit; progressive otherwise";
    "progressive" => SampleOrderChoice::Progressive, "Passes over the whole image";
    "tile-major" => SampleOrderChoice::TileMajor, "Each tile's samples together, tiles in order, bricks read ahead";
});

/// When the scattered paths of a tile-major render are traced in rounds that read the
/// cache file in order (`integrator::deferred`) instead of each where it scatters. Only
/// paths that `Integrator::defers` can be (null-tracked after scattering, FNEE or no
/// light sampling, no external lights, no motion blur, not the point estimator); the
/// image is the same bit for bit either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeferPaths {
    /// Where the volume is paged, in tile-major order, from a cache file larger than the
    /// memory available (as `--sample-order auto` judges), with one path per camera
    /// collision (`render::render_with` and `farm::frame`).
    #[default]
    Auto,
    /// In every tile-major render (for tests and measurements in core).
    Always,
    /// Never.
    Never,
}

choice!(DeferPaths {
    "auto" => DeferPaths::Auto, "In rounds where the volume is paged from a cache file in tile-major order";
    "always" => DeferPaths::Always, "In rounds in every tile-major render";
    "never" => DeferPaths::Never, "Each path where it scatters";
});

/// How the camera projects the world onto the image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Projection {
    /// Rays from the camera's position (a pinhole, or a thin lens with an aperture).
    #[default]
    Perspective,
    /// Parallel rays along the view direction from the image plane through the position.
    Orthographic,
}

choice!(Projection {
    "perspective" => Projection::Perspective, "Rays from the camera position (pinhole, or thin lens with an aperture)";
    "orthographic" => Projection::Orthographic, "Parallel rays along the view direction, camera.ortho_width wide";
});

/// Up axis of automatic framing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UpAxis {
    /// +y up (Houdini, OpenVDB samples).
    Y,
    /// +z up (Blender).
    Z,
}

choice!(UpAxis {
    "y" => UpAxis::Y, "+y up (Houdini, OpenVDB samples)";
    "z" => UpAxis::Z, "+z up (Blender)";
});

choice!(Interpolation {
    "linear" => Interpolation::Linear, "Trilinear between voxel centres (OpenVDB BoxSampler, Cycles' Linear): smooth close-ups, exact tracking";
    "nearest" => Interpolation::Nearest, "Each voxel constant over its box: the paper's volume, exact and faster; blocks in close-ups";
});

/// Machine-readable progress on stdout.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ProgressFormat {
    /// None (logs on stderr only).
    #[default]
    None,
    /// Open Job Description: `openjd_progress: PERCENT` and `openjd_status: TEXT` lines.
    Openjd,
    /// One JSON object per line.
    Json,
}

choice!(ProgressFormat {
    "none" => ProgressFormat::None, "None (logs on stderr only)";
    "openjd" => ProgressFormat::Openjd, "Open Job Description: `openjd_progress: PERCENT` and `openjd_status: TEXT` lines";
    "json" => ProgressFormat::Json, "One JSON object per line (`event`: frame_start, progress, frame_done, frame_skipped, frame_failed, done)";
});

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trips<
        T: Choice + std::fmt::Debug + std::str::FromStr<Err = String> + std::fmt::Display,
    >() {
        for &(name, v, help) in T::CHOICES {
            assert_eq!(v.name(), name);
            assert_eq!(name.parse::<T>().unwrap(), v);
            assert_eq!(v.to_string(), name);
            assert!(!help.is_empty());
        }
        let e = "no-such-value".parse::<T>().unwrap_err();
        assert!(e.contains(T::CHOICES[0].0), "{e}");
    }

    #[test]
    fn names_round_trip() {
        round_trips::<Method>();
        round_trips::<EstimatorKind>();
        round_trips::<LightSampling>();
        round_trips::<MisHeuristic>();
        round_trips::<TrackingChoice>();
        round_trips::<NeeTable>();
        round_trips::<PointLookup>();
        round_trips::<SplitBy>();
        round_trips::<Convention>();
        round_trips::<EmissionSource>();
        round_trips::<SampleOrderChoice>();
        round_trips::<DeferPaths>();
        round_trips::<UpAxis>();
        round_trips::<ProgressFormat>();
        round_trips::<Interpolation>();
        round_trips::<SamplerKind>();
    }
}
