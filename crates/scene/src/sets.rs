//! The closed sets the engine switches on, as the description names them: how emission
//! is estimated ([`Estimator`]) and converted ([`EmissionKind`], [`Convention`],
//! [`TemperatureMap`]), how free paths are tracked ([`Tracking`], [`PointLookup`],
//! [`Collision`]), how lights are sampled and weighted ([`LightSampling`],
//! [`MisHeuristic`]), how paths are split ([`SplitBy`]), how voxels are reconstructed
//! ([`Interpolation`]) and what the denoiser filters ([`Filtered`]).
//!
//! They live here, below the engine, so that the description and its validation can name
//! them without depending on the code that runs them; their names, for scene files and
//! the command line, are in [`crate::choice`]. Methods here are only rules about the sets
//! themselves (which combinations apply, what a choice implies), never rendering.

use plume_core::error::Error;

/// Which next event technique runs at scattering vertices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightSampling {
    /// Forward paths only.
    None,
    /// Classic NEE to emissive voxels in volume measure.
    Nee,
    /// Forward NEE: proxy direction + free path.
    Fnee,
}

/// MIS heuristic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MisHeuristic {
    /// `k = 1`.
    Balance,
    /// `k = 2`.
    Power,
}

impl MisHeuristic {
    /// Weight of technique `a` against `b`: `aᵏ/(aᵏ + bᵏ)`, 1 when `b = 0`, 0 when `a = 0`.
    #[inline]
    #[must_use]
    pub fn weight(self, a: f64, b: f64) -> f64 {
        // NaN or non-positive pdfs count as "cannot sample this".
        if b.is_nan() || b <= 0.0 || a == f64::INFINITY {
            return 1.0;
        }
        if a.is_nan() || a <= 0.0 || b == f64::INFINITY {
            return 0.0;
        }
        let r = b / a;
        match self {
            MisHeuristic::Balance => 1.0 / (1.0 + r),
            MisHeuristic::Power => 1.0 / (1.0 + r * r),
        }
    }
}

/// How the segments of a still volume's paths are tracked.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tracking {
    /// Regular tracking of every segment (the paper's; exact).
    Regular,
    /// Regular tracking of camera segments, null collisions after scattering (FNEE light
    /// segments and forward segments; shadow rays stay exact).
    Mixed,
    /// Null collisions on every segment (shadow rays stay exact).
    Null,
}

impl Tracking {
    /// Whether null collisions can serve `estimator` with `light_sampling`: not blend (a
    /// per-voxel mix, and null collisions have no voxels), and not the point estimator
    /// with classic NEE (its MIS at forward collisions needs the exact optical depth,
    /// which null collisions do not know). Where they cannot, every segment tracks
    /// regularly whatever the [`Tracking`].
    #[must_use]
    pub fn applies(estimator: Estimator, light_sampling: LightSampling) -> bool {
        let blend = matches!(estimator, Estimator::Blend { .. });
        let point_nee = estimator == Estimator::Point && light_sampling == LightSampling::Nee;
        !(blend || point_nee)
    }

    /// Whether segments after a scattering event use null collisions.
    #[must_use]
    pub fn null_after_scattering(self) -> bool {
        self != Tracking::Regular
    }

    /// Whether camera segments use null collisions.
    #[must_use]
    pub fn null_on_camera(self) -> bool {
        self == Tracking::Null
    }
}

/// How null collisions read a field whose point values combine several voxels (the
/// trilinear one) at their tentative points and emission points (`--point-lookup`).
///
/// **Stochastic filtering.** A trilinear density is `Σ_c w_c ρ_c` over the 8 voxels
/// around the point. Picking one corner with probability `w_c` and reading `ρ_c` alone is
/// an unbiased estimate of it, and what null collisions do with a tentative point's
/// density is linear in it: delta tracking accepts with probability `E[μ_c]/μ̄ = μ(x)/μ̄`,
/// so the free-path law is *exactly* the interpolated field's and its noise unchanged;
/// ratio tracking multiplies independent factors `1 − μ_c/μ̄` whose means are
/// `1 − μ(x)/μ̄`. The majorants bound every corner of a dual cell (`volume::majorant`),
/// so `μ_c ≤ μ̄` holds as `μ(x) ≤ μ̄` does.
///
/// **Emission points.** An emission point scores `ℓ W L_e(x)`, linear in the corners'
/// per-voxel emission `L_e(x) = Σ_c w_c le(ρ_c, s_c)`, so one picked corner's `le` is
/// unbiased there too: the expected value of Cycles' one-tap stochastic lookup, which is
/// how Cycles reads a volume's emission. It is bounded by the cell's brightest corner (no
/// weight divides it), but a fire's corners differ by orders of magnitude (a blackbody's
/// `T⁴` and more), so its tail is heavy. On a camera ray, whose emission reaches the pixel
/// directly, emission-only motion blur shows fireflies; after scattering it saves
/// instructions at the same denoised error, but single samples in the fire reach about
/// twice the largest values of exact emission points, and a denoised render can keep such
/// a sample as a visible speck (measured in docs/BENCHMARKS.md, "Stochastic point
/// lookups"). So the default, [`PointLookup::Stochastic`], reads emission
/// points exactly; [`PointLookup::StochasticEmission`] picks them on scattered segments only
/// ([`PointLookup::on_camera`]), for renders that trade that tail for speed.
///
/// Real collisions (albedo, the point estimator's score: all they read) and every
/// regularly tracked segment read the exact value.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointLookup {
    /// The interpolated value (8 voxels) everywhere.
    Exact,
    /// One voxel picked with its interpolation weight at tentative points; emission points
    /// exact (the default).
    Stochastic,
    /// One voxel picked at tentative points, and at emission points after scattering
    /// (faster, with a heavier tail: see above).
    StochasticEmission,
}

impl PointLookup {
    /// Whether tentative points read one picked voxel.
    #[must_use]
    pub fn picks_density(self) -> bool {
        self != PointLookup::Exact
    }

    /// Whether emission points read one picked voxel.
    #[must_use]
    pub fn picks_emission(self) -> bool {
        self == PointLookup::StochasticEmission
    }

    /// The lookup of a camera segment: emission points stay exact there (the type's docs).
    #[must_use]
    pub fn on_camera(self) -> PointLookup {
        match self {
            PointLookup::StochasticEmission => PointLookup::Stochastic,
            other => other,
        }
    }
}

/// How many paths leave each camera collision (`--split-by`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SplitBy {
    /// `--split` paths at every collision.
    #[default]
    Uniform,
    /// Per pixel, in proportion to the square root of its scattered light (module docs),
    /// `--split` on average over the smoke.
    Brightness,
}

impl SplitBy {
    /// Whether this is the default (`uniform`): scene files and the settings hash leave it
    /// out.
    #[must_use]
    pub fn is_uniform(&self) -> bool {
        *self == SplitBy::Uniform
    }
}

/// How a walk draws its collision.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Collision {
    /// None is needed (no scattering, no depth layer): ray-march does not locate one.
    Skip,
    /// The analog free path: `E = −ln(1 − u)`, a collision where the optical depth
    /// reaches `E`, weight 1.
    Analog,
    /// Forced (module docs). Only the expected-value walk (ray-march, regular tracking)
    /// forces; estimators whose emission depends on the free path (point, line, blend),
    /// and null collisions, draw it as [`Collision::Analog`].
    Forced,
}

impl Collision {
    /// Whether the walk must locate a collision.
    #[inline]
    #[must_use]
    pub fn needed(self) -> bool {
        self != Collision::Skip
    }
}

/// What drives emission.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmissionKind {
    /// No emission.
    None,
    /// Blackbody radiation from a temperature grid.
    Blackbody,
    /// A scalar emission grid times a colour.
    Grid,
}

/// Which renderer's meaning of emission to follow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Convention {
    /// Emission density proportional to density × source.
    Physical,
    /// Blender Cycles' Principled Volume: emission not multiplied by density; blackbody
    /// scaled by σ_SB/π·10⁻⁶·T⁴.
    Cycles,
}

/// Mapping from temperature-grid values to Kelvin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TemperatureMap {
    /// Values are Kelvin.
    Kelvin,
    /// `T′ = offset + scale · v`.
    Linear {
        /// Kelvin at v = 0.
        offset: f32,
        /// Kelvin per unit v.
        scale: f32,
    },
}

impl std::str::FromStr for TemperatureMap {
    type Err = Error;

    fn from_str(s: &str) -> Result<TemperatureMap, Error> {
        if s == "kelvin" {
            return Ok(TemperatureMap::Kelvin);
        }
        let bad = || {
            Error::invalid(
                "emission.temperature_map",
                format!("{s:?}: expected `kelvin` or `linear:OFFSET,SCALE`"),
            )
        };
        let rest = s.strip_prefix("linear:").ok_or_else(bad)?;
        let (a, b) = rest.split_once(',').ok_or_else(bad)?;
        let offset: f32 = a.trim().parse().map_err(|_| bad())?;
        let scale: f32 = b.trim().parse().map_err(|_| bad())?;
        if !offset.is_finite() || !scale.is_finite() {
            return Err(bad());
        }
        Ok(TemperatureMap::Linear { offset, scale })
    }
}

impl TemperatureMap {
    /// Kelvin for a grid value.
    #[inline]
    #[must_use]
    pub fn kelvin(&self, v: f32) -> f32 {
        match *self {
            TemperatureMap::Kelvin => v,
            TemperatureMap::Linear { offset, scale } => offset + scale * v,
        }
    }
}

/// Emission estimator along a free-path segment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Estimator {
    /// Collision estimator `L_e/μ_t` at the sampled collision.
    Point,
    /// Track-length estimator: emission integrated up to the collision or exit.
    Line,
    /// Expected-value estimator: the deterministic per-segment closed form.
    RayMarch,
    /// Per-segment blend of line and point with parameter κ ≥ 0.
    Blend {
        /// κ in `α = 1/(1 + κ μ Δ)`; 0 gives the line estimator.
        kappa: f64,
    },
}

/// How voxel values are reconstructed between voxel centres.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Interpolation {
    /// Each voxel constant over its box `[k − ½, k + ½]³`: the paper's piecewise-constant
    /// volume, exact and fastest; shows voxel blocks in close-ups.
    Nearest,
    /// Trilinear between voxel centres, OpenVDB's `BoxSampler` convention (`trilinear`,
    /// METHOD.md §12); exact tracking on dual cells.
    #[default]
    Linear,
}

/// What [`from_sums`] filters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filtered {
    /// The whole beauty.
    Beauty,
    /// The beauty less the camera segment's emission, which is added back unfiltered
    /// (a ray-march camera segment: `--camera-estimator ray-march`).
    LessEmission,
}

impl Filtered {
    /// What to filter for a camera segment tracked with `estimator`: only the
    /// expected-value estimator's emission is exact along each ray.
    #[must_use]
    pub fn for_camera(estimator: Estimator) -> Filtered {
        if estimator == Estimator::RayMarch {
            Filtered::LessEmission
        } else {
            Filtered::Beauty
        }
    }
}
