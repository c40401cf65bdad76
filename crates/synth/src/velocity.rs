//! The generated explosion's velocity: radial expansion from the fire's core
//! plus curl noise, on the density grid's leaves, world units (metres) per second.
//!
//! `v(p) = k (p − c) + A ∇×ψ(p)` with `c` the core centre, `k` = [`EXPANSION_RATE`] per
//! second (a fireball still growing), and `ψ` a vector fBm whose curl (central
//! differences, step `h` = [`CURL_STEP`] m) is divergence-free turbulence of amplitude
//! `A` = [`CURL_AMPLITUDE`] m/s. A pure function of the world position and the seed, so
//! every resolution samples the same field.

use glam::Vec3;

use super::noise::{stream_seed, Fractal, FractalCache};
use super::{ExplosionParams, CORE_CENTRE};
use plume_volume::grid::{leaf_offset, FloatGrid, LEAF_DIM};

/// Radial expansion rate, per second.
pub const EXPANSION_RATE: f32 = 1.2;
/// Curl-noise amplitude, metres per second.
pub const CURL_AMPLITUDE: f32 = 0.8;
/// Central-difference step of the curl, metres.
pub const CURL_STEP: f32 = 0.02;

/// The velocity of the explosion `params` on the leaves of `density` (its grid layout and
/// transform), as three float components `velocity.x`, `velocity.y`, `velocity.z`
/// (`plume synth explosion` writes them as one vec3 grid `velocity`).
#[must_use]
pub fn explosion_velocity(params: &ExplosionParams, density: &FloatGrid) -> [FloatGrid; 3] {
    let potential = Fractal { frequency: 0.9, octaves: 3, seed: stream_seed(params.seed, 7) };
    let mut cache: FractalCache = Default::default();
    let mut psi = |p: Vec3| potential.fbm_vec3(p, &mut cache);
    let xf = density.world_from_index;
    let mut out: [Vec<f32>; 3] = [Vec::new(), Vec::new(), Vec::new()];
    for c in &mut out {
        c.resize(density.values.len(), 0.0);
    }
    for (leaf, &origin) in density.origins.iter().enumerate() {
        for x in 0..LEAF_DIM {
            for y in 0..LEAF_DIM {
                for z in 0..LEAF_DIM {
                    let ijk = origin + glam::IVec3::new(x, y, z);
                    let p = xf.transform_point3(ijk.as_dvec3()).as_vec3();
                    let h = CURL_STEP;
                    let d = |axis: Vec3, psi: &mut dyn FnMut(Vec3) -> Vec3| {
                        (psi(p + axis * h) - psi(p - axis * h)) / (2.0 * h)
                    };
                    let (dx, dy, dz) =
                        (d(Vec3::X, &mut psi), d(Vec3::Y, &mut psi), d(Vec3::Z, &mut psi));
                    // ∇×ψ = (∂yψz − ∂zψy, ∂zψx − ∂xψz, ∂xψy − ∂yψx)
                    let curl = Vec3::new(dy.z - dz.y, dz.x - dx.z, dx.y - dy.x);
                    // The curl of fBm of frequency f has magnitude ≈ f: scale to the amplitude
                    let v = (p - CORE_CENTRE) * EXPANSION_RATE
                        + curl * (CURL_AMPLITUDE / potential.frequency);
                    let i = leaf * plume_volume::grid::LEAF_VOXELS + leaf_offset(x, y, z);
                    for (axis, c) in out.iter_mut().enumerate() {
                        c[i] = v[axis];
                    }
                }
            }
        }
    }
    let grid = |name: &str, values: Vec<f32>| FloatGrid {
        name: name.into(),
        world_from_index: xf,
        background: 0.0,
        origins: density.origins.clone(),
        values,
    };
    let [x, y, z] = out;
    [grid("velocity.x", x), grid("velocity.y", y), grid("velocity.z", z)]
}
