//! `plume bench core`: the core renderer's figures on a generated explosion.
//!
//! - **voxel steps per second per core**: single-threaded hierarchical DDA, counting every
//!   piece the DDA produces (voxel steps plus skipped nodes), for camera rays in tile order
//!   (what a render traces) and for random incoherent chords (the cache's worst case:
//!   every brick entered is a cold miss);
//! - **parallel speed-up**: the same emission render on 1 and on N threads (wall time);
//! - **time to first sample**: `load_scene` (read grids, build bricks + pyramid, camera)
//!   for a given file, best of several runs;
//! - **brick memory**: heap bytes of the [`Volume`] against the raw f32 leaf data read.

use std::path::Path;
use std::time::Instant;

use glam::DVec3;
use serde::Serialize;

use crate::load::load_scene;
use plume_core::color::Rgb;
use plume_core::error::Result;
use plume_core::sampling::Sampler;
use plume_engine::camera::Camera;
use plume_engine::integrator::{Integrator, Scene};
use plume_engine::medium::{Convention, Emission, EmissionKind, Estimator, Medium, TemperatureMap};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_scene::Shot;
use plume_synth::{explosion, ExplosionParams};
use plume_volume::field::Ray;
use plume_volume::grid::LEAF_VOXELS;
use plume_volume::{Field, Volume};

/// Results of `plume bench core`.
#[derive(Debug, Serialize)]
pub struct CoreReport {
    /// Explosion resolution.
    pub resolution: u32,
    /// Raw DDA pieces per second on one thread (millions), random incoherent chords.
    pub voxel_steps_per_second_millions: f64,
    /// Raw DDA pieces per second on one thread (millions), camera rays in tile order.
    pub coherent_voxel_steps_per_second_millions: f64,
    /// Rays traced in the DDA benchmark.
    pub dda_rays: u64,
    /// Render wall seconds on 1 thread.
    pub render_seconds_1_thread: f64,
    /// Render wall seconds on `threads` threads.
    pub render_seconds_n_threads: f64,
    /// Threads of the parallel run.
    pub threads: usize,
    /// `render_seconds_1_thread / render_seconds_n_threads`.
    pub speedup: f64,
    /// File used for time to first sample.
    pub ttfs_file: String,
    /// Best time to first sample over 5 runs, seconds.
    pub time_to_first_sample_seconds: f64,
    /// Heap bytes of the brick volume.
    pub volume_bytes: u64,
    /// Bytes of the raw f32 leaves read (density + temperature).
    pub raw_bytes: u64,
    /// `volume_bytes / raw_bytes`.
    pub memory_ratio: f64,
}

fn emission() -> Emission {
    Emission {
        kind: EmissionKind::Blackbody,
        convention: Convention::Physical,
        scale: 1.0,
        color: Rgb::ONE,
        temperature_map: TemperatureMap::Kelvin,
        cutoff_kelvin: plume_core::color::blackbody::DEFAULT_CUTOFF_KELVIN,
    }
}

/// Rays of the random-chord DDA benchmark.
const DDA_RAYS: u64 = 20_000;

/// Run the core benchmark.
///
/// # Errors
/// If the time-to-first-sample file cannot be loaded.
pub fn run(resolution: u32, threads: usize, ttfs_file: &Path) -> Result<CoreReport> {
    let ex = explosion(&ExplosionParams { resolution, ..Default::default() });
    let raw_bytes =
        ((ex.density.leaf_count() + ex.temperature.leaf_count()) * LEAF_VOXELS * 4) as u64;
    let em = emission();
    let volume = Volume::build(&ex.density, Some(&ex.temperature), |v| em.map_source(v))?;
    let volume_bytes = volume.memory_bytes() as u64;
    let (steps, dda_seconds) = random_chord_steps(&volume);
    let (coherent_steps, coherent_seconds) = coherent_steps(&volume)?;
    let threads = if threads == 0 {
        std::thread::available_parallelism().map_or(2, |n| n.get())
    } else {
        threads
    };
    let (one, many) = render_seconds(volume, em, threads)?;
    let ttfs = time_to_first_sample(ttfs_file)?;
    Ok(CoreReport {
        resolution,
        voxel_steps_per_second_millions: steps as f64 / dda_seconds / 1e6,
        coherent_voxel_steps_per_second_millions: coherent_steps as f64 / coherent_seconds / 1e6,
        dda_rays: DDA_RAYS,
        render_seconds_1_thread: one,
        render_seconds_n_threads: many,
        threads,
        speedup: one / many,
        ttfs_file: ttfs_file.display().to_string(),
        time_to_first_sample_seconds: ttfs,
        volume_bytes,
        raw_bytes,
        memory_ratio: volume_bytes as f64 / raw_bytes as f64,
    })
}

/// DDA on random chords between points on a sphere around the volume and points inside:
/// (raw DDA pieces, seconds).
fn random_chord_steps(volume: &Volume) -> (u64, f64) {
    let plume_volume::Bounds3 { lo, hi } = volume.world_bounds();
    let centre = 0.5 * (lo + hi);
    let radius = 0.5 * (hi - lo).length();
    let mut sampler = Sampler::new(1, 0, 0);
    let mut steps = 0u64;
    let t = Instant::now();
    for _ in 0..DDA_RAYS {
        let z = 2.0 * sampler.next_f64() - 1.0;
        let phi = std::f64::consts::TAU * sampler.next_f64();
        let r = (1.0 - z * z).sqrt();
        let origin = centre + DVec3::new(r * phi.cos(), r * phi.sin(), z) * radius * 1.5;
        let target =
            lo + (hi - lo) * DVec3::new(sampler.next_f64(), sampler.next_f64(), sampler.next_f64());
        let ray = Ray { origin, direction: (target - origin).normalize() };
        let mut it = volume.segments(&ray, 0.0, f64::INFINITY);
        for s in it.by_ref() {
            std::hint::black_box(s);
        }
        steps += it.raw_steps();
    }
    (steps, t.elapsed().as_secs_f64())
}

/// DDA on coherent rays: a 640×480 camera's rays in 16×16 tiles, as the renderer traces
/// them: (raw DDA pieces, seconds).
fn coherent_steps(volume: &Volume) -> Result<(u64, f64)> {
    let plume_volume::Bounds3 { lo, hi } = volume.world_bounds();
    let camera =
        Camera::frame_bounds(lo, hi, DVec3::new(0.35, 0.25, 1.0), DVec3::Y, 40.0, 640, 480)?;
    let mut coherent_steps = 0u64;
    let t = Instant::now();
    for ty in (0..480).step_by(16) {
        for tx in (0..640).step_by(16) {
            for y in ty..ty + 16 {
                for x in tx..tx + 16 {
                    let ray = camera.ray(f64::from(x) + 0.5, f64::from(y) + 0.5);
                    let mut it = volume.segments(&ray, 0.0, f64::INFINITY);
                    for s in it.by_ref() {
                        std::hint::black_box(s);
                    }
                    coherent_steps += it.raw_steps();
                }
            }
        }
    }
    Ok((coherent_steps, t.elapsed().as_secs_f64()))
}

/// Parallel speed-up of a whole render: wall seconds of the same emission render on 1 and
/// on `threads` threads (after a warm-up on `threads`).
fn render_seconds(volume: Volume, em: Emission, threads: usize) -> Result<(f64, f64)> {
    let plume_volume::Bounds3 { lo, hi } = volume.world_bounds();
    let camera =
        Camera::frame_bounds(lo, hi, DVec3::new(0.35, 0.25, 1.0), DVec3::Y, 40.0, 320, 240)?;
    let scene = Scene {
        field: volume,
        medium: Medium {
            sigma_t: 4.0,
            albedo: plume_core::color::Rgb::splat(0.0),
            g: 0.0,
            emission: em,
            extinction: Default::default(),
        },
        camera,
        lights: Default::default(),
        motion: None,
        majorants: None,
    };
    let time_render = |threads: usize| {
        let settings = RenderSettings {
            budget: SampleBudget::Spp(8),
            seed: 0,
            sampler: plume_core::sampling::SamplerKind::default(),
            threads,
            first_sample: 0,
            adaptive: None,
            integrator: Integrator::emission_only(Estimator::Line),
        };
        let t = Instant::now();
        let r = render(&scene, &settings, &|_, _| {});
        std::hint::black_box(r.spp);
        t.elapsed().as_secs_f64()
    };
    time_render(threads); // warm-up
    let one = time_render(1);
    let many = time_render(threads);
    Ok((one, many))
}

/// Time to first sample on a real file: best of 5 loads, seconds.
fn time_to_first_sample(ttfs_file: &Path) -> Result<f64> {
    let mut shot = Shot::new(ttfs_file, super::spec::UNUSED_OUTPUT);
    shot.settings.render.quiet = true;
    let shot = shot.validate()?;
    let mut ttfs = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        let loaded = load_scene(&shot.scene, ttfs_file, &shot.settings, None)?;
        std::hint::black_box(loaded.scene.camera());
        ttfs = ttfs.min(t.elapsed().as_secs_f64());
    }
    Ok(ttfs)
}

impl std::fmt::Display for CoreReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "| figure ({}³ generated explosion) | value | target |", self.resolution)?;
        writeln!(f, "|---|---|---|")?;
        writeln!(
            f,
            "| voxel steps per second, 1 core, camera rays in tile order | {:.1} M | ≥ 20 M |",
            self.coherent_voxel_steps_per_second_millions
        )?;
        writeln!(
            f,
            "| voxel steps per second, 1 core, random incoherent chords | {:.1} M | (worst case) |",
            self.voxel_steps_per_second_millions
        )?;
        writeln!(
            f,
            "| render speed-up, {} threads vs 1 | {:.2}× ({:.2} s → {:.2} s) | ≥ 1.8× |",
            self.threads, self.speedup, self.render_seconds_1_thread, self.render_seconds_n_threads
        )?;
        writeln!(
            f,
            "| time to first sample, {} | {:.3} s | < 0.5 s |",
            self.ttfs_file, self.time_to_first_sample_seconds
        )?;
        writeln!(
            f,
            "| brick memory / raw f32 voxel data | {:.2} ({:.1} MiB / {:.1} MiB) | ≤ 1.5 |",
            self.memory_ratio,
            self.volume_bytes as f64 / 1048576.0,
            self.raw_bytes as f64 / 1048576.0
        )
    }
}
