//! Procedural explosions: a seeded, sparse, mushroom-shaped fireball at any resolution, for
//! tests and benchmarks. No file I/O; writing goes through the VDB shim.
//!
//! # World placement
//! The volume fills a cube of edge [`WORLD_SIZE`] = 4 m centred at the origin, y up, at
//! every resolution `n`: voxel size `4 m / n`, and voxel `(i, j, k)`, `0 ≤ i, j, k < n`, is
//! centred at index `(i, j, k)` (OpenVDB), i.e. at world `−2 m + (i + ½)·4 m / n`. The
//! model below is a function of world position only, with fixed world-space detail, so
//! every resolution samples *the same* volume: a given `--density-scale` gives the same
//! optical thickness at 32³ and 1024³, and higher resolutions only resolve more detail.
//!
//! # Model
//! 1. **Envelope.** A signed-distance-like function `e(p)` (metres, negative inside) of a
//!    mushroom cloud: a squashed sphere (cap), a torus under its rim (the rolling ring),
//!    a capsule (stem) and a round-rimmed disc at the ground (dust skirt), joined by a
//!    polynomial smooth minimum. Every part is 1-Lipschitz (the squashed cap sphere is
//!    divided by its squash factor; the rest are exact distances), and so is the smooth
//!    minimum, whose gradient is a convex combination of its arguments' gradients.
//! 2. **Pyroclastic displacement** (Wrenninge 2012, ch. 7). The surface is pushed out by
//!    `A·b(q)`, `b ∈ [0, 1]` a clamped turbulence (sum of `|noise|`) looked up at the
//!    *domain-warped* point `q = p + W·fbm₃(p)`. Inside depth `δ = A·b(q) − e(p)`; density
//!    ramps smoothly from 0 at `δ = 0` over 0.2 m, so there are no hard edges.
//!    It is also faded to 0 towards the ground plane and the cube's faces.
//! 3. **Smoke density** inside is `0.2 … 1.5` (unitless; μ_t = σ_t·ρ), modulated by a
//!    finer fBm, and thinned by up to half in the fire so the flames show through.
//! 4. **Heat** `h ∈ [0, 1]` falls off linearly from a squashed core sphere inside the cap,
//!    perturbed by warped fBm. Where `h > 0` and density > 0 the temperature is
//!    `T = T_edge + (T_core − T_edge)·√h` Kelvin (T_edge = [`FIRE_EDGE_TEMPERATURE`]);
//!    elsewhere it is 0, the background: cold smoke is absent from the temperature grid
//!    rather than stored below the 500 K blackbody cutoff (METHOD.md §2).
//!
//! # Sparsity and speed
//! Because `b ≤ 1`, density can be non-zero only where `e(p) < A`. A leaf (8³ voxels) is
//! skipped without evaluating noise when `e(c) − r ≥ A` for its bounding sphere (centre
//! `c`, radius `r`; valid because `e` is 1-Lipschitz), and inside a leaf each voxel is
//! tested the same way before any noise is evaluated. Leaves left all zero are dropped,
//! so no stored leaf is empty and the temperature grid (fire only) is sparser than the
//! density grid.
//!
//! # Determinism
//! Same [`ExplosionParams`] ⇒ bit-identical grids, at any rayon thread count: every voxel
//! is a pure function of its world position and the seed (`synth/noise.rs`), leaves are
//! evaluated in parallel one x-slab at a time and collected in order, and leaves appear in
//! lexicographic `(x, y, z)` order of their origins (x slowest, like voxels inside a leaf).

mod flare;
mod noise;
pub mod velocity;

use glam::{DAffine3, DVec3, IVec3, Vec3};
use rayon::prelude::*;

use noise::{stream_seed, Fractal, FractalCache};
use plume_volume::grid::{leaf_offset, FloatGrid, LEAF_DIM, LEAF_VOXELS};

pub use flare::{
    Flare, FlareParams, BYTES_PER_BRICK, FLARE_SIZE, FOOT_TEMPERATURE, MAX_FLARE_RESOLUTION,
    MIN_TUBE_RADIUS, PEAK_TEMPERATURE,
};

/// Edge length of the world cube holding the explosion, in metres, at every resolution.
pub const WORLD_SIZE: f64 = 4.0;
/// Largest accepted [`ExplosionParams::resolution`] (index coordinates stay far from `i32`
/// overflow; memory runs out long before).
pub const MAX_RESOLUTION: u32 = 1 << 16;
/// Temperature at the outer edge of the fire, Kelvin. Above the 500 K cutoff, but
/// emission there is ~10⁻¹² of the core's at 550 nm, so the step from 0 is invisible.
pub const FIRE_EDGE_TEMPERATURE: f32 = 600.0;
/// Depth over which density ramps from 0 at the displaced surface to its full value, metres.
const SURFACE_WIDTH: f32 = 0.2;

/// Inputs of [`explosion`]. Build with struct-update syntax from [`Default`].
#[derive(Clone, Debug, PartialEq)]
pub struct ExplosionParams {
    /// Voxels per edge of the 4 m cube (need not be a multiple of 8). Default 128.
    pub resolution: u32,
    /// Seed of every noise stream; a different seed gives a different volume. Default 1.
    pub seed: u64,
    /// Scale of the pyroclastic displacement (bumpiness of the surface); 0 gives the smooth
    /// envelope, 1 the default (displacement up to 0.35 m), above ~1.8 the billows may
    /// reach the fade zone at the cube's faces.
    pub turbulence: f32,
    /// Hottest temperature, at the centre of the fire, Kelvin. Default 3200 K.
    pub core_temperature: f32,
}

impl Default for ExplosionParams {
    fn default() -> Self {
        ExplosionParams { resolution: 128, seed: 1, turbulence: 1.0, core_temperature: 3200.0 }
    }
}

/// A generated explosion: two sparse grids on the same index space and transform.
#[derive(Clone, Debug)]
pub struct Explosion {
    /// Grid `density`: unitless smoke density ρ ≥ 0 (μ_t = σ_t·ρ per metre), background 0.
    pub density: FloatGrid,
    /// Grid `temperature`: Kelvin where there is fire, else 0 (the background). Its leaves
    /// are a subset of the density grid's leaves, and `T > 0` only where density > 0.
    pub temperature: FloatGrid,
}

/// The transform shared by both grids at `resolution`: uniform scale `4 m / resolution`
/// and a translation placing voxel centres `0 … resolution−1` symmetrically in
/// `[−2 m, 2 m]` (index `−½` maps to −2 m, index `resolution − ½` to +2 m).
///
/// # Panics
/// If `resolution` is 0.
#[must_use]
pub fn world_from_index(resolution: u32) -> DAffine3 {
    assert!(resolution > 0, "explosion resolution must be positive");
    let voxel_size = WORLD_SIZE / f64::from(resolution);
    DAffine3::from_scale(DVec3::splat(voxel_size))
        * DAffine3::from_translation(DVec3::splat(0.5 - 0.5 * f64::from(resolution)))
}

/// Generates the explosion described by `params` (see the module docs for the model).
///
/// Cost grows with the number of voxels near the cloud (about 20 % of the cube); leaves
/// are evaluated in parallel on the current rayon pool.
///
/// # Panics
/// If `resolution` is 0 or above [`MAX_RESOLUTION`], `turbulence` is negative or not
/// finite, or `core_temperature` is not finite or below [`FIRE_EDGE_TEMPERATURE`].
#[must_use]
pub fn explosion(params: &ExplosionParams) -> Explosion {
    generate(params, true)
}

/// [`explosion`], with leaf culling optional so tests can check that it is conservative.
fn generate(params: &ExplosionParams, cull_leaves: bool) -> Explosion {
    assert!(
        (1..=MAX_RESOLUTION).contains(&params.resolution),
        "explosion resolution {} outside 1..={MAX_RESOLUTION}",
        params.resolution
    );
    assert!(
        params.turbulence.is_finite() && params.turbulence >= 0.0,
        "turbulence {} must be finite and non-negative",
        params.turbulence
    );
    assert!(
        params.core_temperature.is_finite() && params.core_temperature >= FIRE_EDGE_TEMPERATURE,
        "core temperature {} K must be finite and at least {FIRE_EDGE_TEMPERATURE} K",
        params.core_temperature
    );
    let model = Model::new(params);
    let resolution = params.resolution as i32;
    let world_from_index = world_from_index(params.resolution);
    let leaves_per_axis = (resolution + LEAF_DIM - 1) / LEAF_DIM;
    // Bounding sphere of a leaf's voxel centres; 0.1 % slack covers f32 rounding of `e`.
    let voxel_size = WORLD_SIZE / f64::from(params.resolution);
    let leaf_radius = (3f64.sqrt() * 3.5 * voxel_size * 1.001) as f32;

    let mut density = empty_grid("density", world_from_index);
    let mut temperature = empty_grid("temperature", world_from_index);
    for leaf_x in 0..leaves_per_axis {
        // Origins of this slab's leaves that may hold smoke, in (y, z) order.
        let candidates: Vec<IVec3> = (0..leaves_per_axis)
            .flat_map(|leaf_y| {
                (0..leaves_per_axis)
                    .map(move |leaf_z| IVec3::new(leaf_x, leaf_y, leaf_z) * LEAF_DIM)
            })
            .filter(|origin| {
                let centre = world_from_index.transform_point3(origin.as_dvec3() + 3.5);
                !cull_leaves || model.may_have_smoke(centre.as_vec3(), leaf_radius)
            })
            .collect();
        // Evaluate in parallel; `collect` keeps candidate order.
        let leaves: Vec<Option<Leaf>> = candidates
            .par_iter()
            .map(|&origin| evaluate_leaf(&model, &world_from_index, resolution, origin))
            .collect();
        for leaf in leaves.into_iter().flatten() {
            density.origins.push(leaf.origin);
            density.values.extend_from_slice(&leaf.density[..]);
            if let Some(values) = leaf.temperature {
                temperature.origins.push(leaf.origin);
                temperature.values.extend_from_slice(&values[..]);
            }
        }
    }
    Explosion { density, temperature }
}

fn empty_grid(name: &str, world_from_index: DAffine3) -> FloatGrid {
    FloatGrid {
        name: name.to_owned(),
        world_from_index,
        background: 0.0,
        origins: Vec::new(),
        values: Vec::new(),
    }
}

/// One evaluated leaf; `temperature` is `None` when it has no fire.
struct Leaf {
    origin: IVec3,
    density: Box<[f32; LEAF_VOXELS]>,
    temperature: Option<Box<[f32; LEAF_VOXELS]>>,
}

/// Evaluates the leaf at `origin`, zeroing voxels with an index component ≥ `resolution`.
/// `None` when every density value is zero.
fn evaluate_leaf(
    model: &Model,
    world_from_index: &DAffine3,
    resolution: i32,
    origin: IVec3,
) -> Option<Leaf> {
    let mut density = Box::new([0.0f32; LEAF_VOXELS]);
    let mut temperature = Box::new([0.0f32; LEAF_VOXELS]);
    let mut cache = SampleCache::default();
    let end = (IVec3::splat(resolution) - origin).min(IVec3::splat(LEAF_DIM));
    for x in 0..end.x {
        for y in 0..end.y {
            for z in 0..end.z {
                let p_index = (origin + IVec3::new(x, y, z)).as_dvec3();
                let p_world = world_from_index.transform_point3(p_index).as_vec3();
                let sample = model.sample(p_world, &mut cache);
                let offset = leaf_offset(x, y, z);
                density[offset] = sample.density;
                temperature[offset] = sample.temperature;
            }
        }
    }
    if density.iter().all(|&d| d == 0.0) {
        return None;
    }
    let hot = temperature.iter().any(|&t| t > 0.0);
    Some(Leaf { origin, density, temperature: hot.then_some(temperature) })
}

// Envelope primitives, metres, y up (see the module docs).
/// Cap: centre, horizontal radius, vertical squash (vertical semi-axis = radius / squash).
const CAP_CENTRE: Vec3 = Vec3::new(0.0, 0.55, 0.0);
const CAP_RADIUS: f32 = 0.9;
const CAP_SQUASH: f32 = 1.3;
/// Rolling ring under the cap's rim: height, major and minor radius.
const RING_Y: f32 = 0.2;
const RING_MAJOR: f32 = 0.72;
const RING_MINOR: f32 = 0.3;
/// Stem capsule: bottom and top of its axis, radius.
const STEM_BOTTOM_Y: f32 = -1.5;
const STEM_TOP_Y: f32 = 0.3;
const STEM_RADIUS: f32 = 0.25;
/// Dust skirt on the ground, a disc with a round rim: centre height, radius, half height.
/// (A squashed sphere would let the displacement reach `squash·A` sideways.)
const SKIRT_Y: f32 = -1.5;
const SKIRT_RADIUS: f32 = 1.05;
const SKIRT_HALF_HEIGHT: f32 = 0.18;
/// Smooth-minimum blend radius between the parts.
const BLEND: f32 = 0.3;
/// Ground plane; density fades to 0 over `GROUND_FADE` above it.
const GROUND_Y: f32 = -1.8;
const GROUND_FADE: f32 = 0.12;
/// Density fades to 0 over this distance from the cube's faces.
const BORDER_FADE: f32 = 0.12;
/// Pyroclastic displacement bound `A` at turbulence 1, metres.
const DISPLACEMENT: f32 = 0.35;
/// Turbulence is scaled by this before clamping to 1 (its mean is only ~0.2).
const DISPLACEMENT_GAIN: f32 = 2.2;
/// Domain-warp amplitude `W`, metres.
const WARP: f32 = 0.5;
/// Smoke density range (unitless) before the edge ramp and fire thinning.
const SMOKE_MIN: f32 = 0.2;
const SMOKE_MAX: f32 = 1.5;
/// Contrast of the smoke-density fBm, and the fraction of density removed at `h = 1`.
const SMOKE_CONTRAST: f32 = 1.2;
const FIRE_THINNING: f32 = 0.5;
/// Fire core: centre, horizontal radius, squash; amplitude and contrast of its noise.
const CORE_CENTRE: Vec3 = Vec3::new(0.0, 0.45, 0.0);
const CORE_RADIUS: f32 = 0.72;
const CORE_SQUASH: f32 = 1.3;
const HEAT_NOISE: f32 = 0.5;
const HEAT_CONTRAST: f32 = 2.5;

/// Noise caches for [`Model::sample`], one per fractal; reused from voxel to voxel.
#[derive(Default)]
struct SampleCache {
    warp: FractalCache,
    displacement: FractalCache,
    smoke: FractalCache,
    heat: FractalCache,
}

/// Density and temperature at one point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Sample {
    density: f32,
    temperature: f32,
}

/// The explosion as a function of world position (precomputed per [`ExplosionParams`]).
struct Model {
    /// Displacement bound `A`, metres.
    amplitude: f32,
    core_temperature: f32,
    /// Domain warp, one fBm per axis.
    warp: Fractal,
    /// Pyroclastic displacement turbulence.
    displacement: Fractal,
    /// Smoke density variation.
    smoke: Fractal,
    /// Fire boundary perturbation.
    heat: Fractal,
}

impl Model {
    fn new(params: &ExplosionParams) -> Model {
        let seed = |stream| stream_seed(params.seed, stream);
        Model {
            amplitude: DISPLACEMENT * params.turbulence,
            core_temperature: params.core_temperature,
            warp: Fractal { frequency: 0.5, octaves: 2, seed: seed(0) },
            displacement: Fractal { frequency: 1.2, octaves: 5, seed: seed(3) },
            smoke: Fractal { frequency: 2.5, octaves: 2, seed: seed(4) },
            heat: Fractal { frequency: 1.6, octaves: 3, seed: seed(5) },
        }
    }

    /// Conservative test: false only if no point within `radius` of `centre` has smoke.
    fn may_have_smoke(&self, centre: Vec3, radius: f32) -> bool {
        envelope(centre) - radius < self.amplitude
    }

    /// Density and temperature at `p` (world, metres).
    fn sample(&self, p: Vec3, cache: &mut SampleCache) -> Sample {
        // Cheap rejection before any noise: displaced surface lies within e(p) < A.
        let e = envelope(p);
        if e >= self.amplitude {
            return Sample::default();
        }
        let border = WORLD_SIZE as f32 * 0.5 - p.abs().max_element();
        let fade = smoothstep(border / BORDER_FADE) * smoothstep((p.y - GROUND_Y) / GROUND_FADE);
        if fade <= 0.0 {
            return Sample::default();
        }
        // Domain-warped lookup point
        // FIXME: the warp is about a third of generation time; a warp interpolated from a cached world-space lattice would
        // remove most of that, at the price of C0 kinks in the warped noise.
        let q = p + WARP * self.warp.fbm_vec3(p, &mut cache.warp);
        // Pyroclastic displacement of the envelope
        let bumps =
            (DISPLACEMENT_GAIN * self.displacement.turbulence(q, &mut cache.displacement)).min(1.0);
        let depth = self.amplitude * bumps - e;
        if depth <= 0.0 {
            return Sample::default();
        }
        let heat = self.heat(p, q, &mut cache.heat);
        let variation =
            (0.5 + SMOKE_CONTRAST * self.smoke.fbm(q, &mut cache.smoke)).clamp(0.0, 1.0);
        let density = fade
            * smoothstep(depth / SURFACE_WIDTH)
            * lerp(variation, SMOKE_MIN, SMOKE_MAX)
            * (1.0 - FIRE_THINNING * heat);
        let temperature = if heat > 0.0 && density > 0.0 {
            lerp(heat.sqrt(), FIRE_EDGE_TEMPERATURE, self.core_temperature)
        } else {
            0.0
        };
        Sample { density, temperature }
    }

    /// Heat `h ∈ [0, 1]`: 1 − (scaled distance from the core) plus noise at `q`.
    fn heat(&self, p: Vec3, q: Vec3, cache: &mut FractalCache) -> f32 {
        let c = p - CORE_CENTRE;
        let r = Vec3::new(c.x, c.y * CORE_SQUASH, c.z).length() / CORE_RADIUS;
        if r >= 1.0 + HEAT_NOISE {
            return 0.0;
        }
        let noise = (HEAT_CONTRAST * self.heat.fbm(q, cache)).clamp(-1.0, 1.0);
        (1.0 - r + HEAT_NOISE * noise).clamp(0.0, 1.0)
    }
}

/// The undisplaced mushroom envelope `e(p)`, metres, negative inside, 1-Lipschitz.
fn envelope(p: Vec3) -> f32 {
    let cap = squashed_sphere(p - CAP_CENTRE, CAP_RADIUS, CAP_SQUASH);
    let ring = {
        let radial = Vec3::new(p.x, 0.0, p.z).length() - RING_MAJOR;
        (radial * radial + (p.y - RING_Y) * (p.y - RING_Y)).sqrt() - RING_MINOR
    };
    let stem = {
        let axis_y = p.y.clamp(STEM_BOTTOM_Y, STEM_TOP_Y);
        Vec3::new(p.x, p.y - axis_y, p.z).length() - STEM_RADIUS
    };
    let skirt = {
        // Exact distance to a disc (radius R − h, thickness 0) inflated by h: a
        // flat cylinder of radius R and half height h with a round rim.
        let radial =
            (Vec3::new(p.x, 0.0, p.z).length() - (SKIRT_RADIUS - SKIRT_HALF_HEIGHT)).max(0.0);
        (radial * radial + (p.y - SKIRT_Y) * (p.y - SKIRT_Y)).sqrt() - SKIRT_HALF_HEIGHT
    };
    smooth_min(smooth_min(smooth_min(cap, ring), stem), skirt)
}

/// Ellipsoid with horizontal radius `radius` and vertical semi-axis `radius / squash`
/// (`squash ≥ 1`) as `(|(x, squash·y, z)| − radius) / squash`: exact zero set, 1-Lipschitz.
fn squashed_sphere(p: Vec3, radius: f32, squash: f32) -> f32 {
    (Vec3::new(p.x, p.y * squash, p.z).length() - radius) / squash
}

/// Polynomial smooth minimum with blend radius [`BLEND`] (Quílez): ≤ `min(a, b)`, and
/// 1-Lipschitz when `a` and `b` are.
fn smooth_min(a: f32, b: f32) -> f32 {
    let h = (BLEND - (a - b).abs()).max(0.0) / BLEND;
    a.min(b) - h * h * BLEND * 0.25
}

/// Cubic smoothstep of `t` clamped to `[0, 1]`.
fn smoothstep(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn lerp(t: f32, a: f32, b: f32) -> f32 {
    a + t * (b - a)
}

#[cfg(test)]
mod tests;
