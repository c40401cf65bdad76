//! `plume bench volumes`: what a sample costs and what memory a scene holds as the number
//! of instances of one volume grows (`plume_engine::overlap`).
//!
//! **The scene.** A generated explosion (albedo 0.8, `g` 0.3, blackbody emission) placed
//! `N` times as a cloud layer: one shared [`Volume`] and one shared [`ProxyGrid`], each
//! instance on a square grid in the ground plane (x–z; plume's explosions are y up) with
//! spacing 1.2× the volume's horizontal extent, so that neighbours barely overlap, turned
//! about the up axis by `i` golden angles and scaled by `0.8 + 0.4 frac(i φ⁻¹)`. Cells are
//! filled ring by ring from the centre, so every `N ≥ 9` holds the same 3×3 instances
//! around the origin, and a camera looking straight down from a fixed height sees that
//! 3×3 patch whatever `N`: what a pixel holds is the same, and what changes is how many
//! volumes a ray must look through to find the few it crosses. Rendered with line-fnee
//! (line estimator, FNEE over the mixture of placed proxies, max depth 8) on rayon's pool.
//!
//! **Cost.** Samples per process CPU second (user + system, all threads), and CPU µs per
//! sample relative to the smallest `N`. Beside them the work per sample (voxel steps and
//! tentative points, the renderer's counters) and walks per sample: a change in these is a
//! change of what the rays cross, not of finding volumes; and ns per unit of work. Camera
//! rays alone (the same scene emission-only: straight down through one or two instances)
//! are timed too: their cost is what finding the volumes costs a ray that crosses few.
//! With `N = 1` only the centre
//! instance is in view (the other eight cells of the patch are empty), so its samples are
//! cheaper for that reason too.
//!
//! **Memory.** The shared volume's and proxy's bytes, once; and the overhead per instance:
//! its [`Member`] and scattering-class slot in [`Volumes`], its share of the mixture's
//! tables ([`ProxyMixture::memory_bytes`] less the shared proxy), and its entry in the
//! R*-tree of the volumes' boxes (`plume_volume::instance::BoundsIndex`). The tree's leaf
//! (a 3-D rectangle of `f64` and an index) is counted twice, for the inner nodes and the
//! slack of its nodes: an estimate, not a measurement (`rstar` reports no size).
//!
//! **Verdict.** The camera rays' cost per sample (finding the volumes a ray meets and
//! walking them) at the largest `N` at most [`MAX_COST_RATIO`] times that at the smallest
//! `N` whose view is full (`N ≥ 9`: the same 3×3 instances in view; log growth, not linear),
//! and overhead per instance under [`MAX_OVERHEAD_BYTES`]. The whole path's cost is reported
//! beside it: it also grows with the light FNEE gathers from farther instances, which is
//! more work, not a slower search. Timings are figures of a command, never of a test
//! (STYLE.md §8).

use std::fmt::Write as _;
use std::sync::Arc;
use std::time::Instant;

use glam::{DAffine3, DMat3, DVec3};
use plume_core::color::Rgb;
use plume_core::error::{Error, Result};
use plume_engine::camera::Camera;
use plume_engine::integrator::lights::proxy_weight;
use plume_engine::integrator::{
    light_power, Counters, Integrator, LightSampling, Lights, MisHeuristic, Scene, Tracking,
};
use plume_engine::light::mixture::{PlacedProxy, ProxyMixture};
use plume_engine::medium::{Collision, Emission, Estimator, Medium};
use plume_engine::overlap::member::Member;
use plume_engine::overlap::volumes::Volumes;
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_engine::stats::cpu_seconds;
use plume_volume::instance::Instance;
use plume_volume::proxy::ProxyGrid;
use plume_volume::{Field, Volume};

use super::numbers::num;

/// The largest cost per sample at the largest `N` allowed, relative to the smallest `N`.
pub const MAX_COST_RATIO: f64 = 3.0;

/// The largest overhead per instance allowed, bytes.
pub const MAX_OVERHEAD_BYTES: f64 = 1024.0;

/// Instance spacing over the volume's horizontal extent.
const SPACING: f64 = 1.2;

/// Camera height over the layer, in spacings; the view spans 3 spacings at the layer.
const HEIGHT: f64 = 4.0;

/// Proxy cells along the volume's longest edge.
const PROXY_RESOLUTION: u32 = 16;

/// What `plume bench volumes` measures.
#[derive(Clone, Debug)]
pub struct VolumesConfig {
    /// Resolution of the generated explosion.
    pub resolution: u32,
    /// Numbers of instances, one render each.
    pub instances: Vec<usize>,
    /// Image width and height.
    pub size: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Renders per `N`; the one of least CPU time is kept.
    pub repeats: u32,
}

/// One number of instances: its render's figures and its scene's memory.
#[derive(Clone, Debug, serde::Serialize)]
pub struct InstancesPoint {
    /// Instances in the scene.
    pub instances: usize,
    /// Samples rendered.
    pub samples: u64,
    /// Process CPU seconds (user + system) of the render kept.
    pub cpu_seconds: f64,
    /// Wall seconds of that render.
    pub wall_seconds: f64,
    /// Rays tracked (camera, scattered and shadow segments).
    pub walks: u64,
    /// Voxel steps plus null collisions' tentative points.
    pub work: u64,
    /// Process CPU seconds of the emission-only render (camera rays alone).
    pub camera_cpu_seconds: f64,
    /// Samples of that render.
    pub camera_samples: u64,
    /// Seconds to build the volumes and the mixture of proxies.
    pub build_seconds: f64,
    /// Bytes of the shared volume.
    pub volume_bytes: usize,
    /// Bytes of the shared proxy.
    pub proxy_bytes: usize,
    /// Bytes per instance: its member and scattering-class slot.
    pub member_bytes: f64,
    /// Bytes per instance: its share of the mixture's tables (less the shared proxy).
    pub mixture_bytes: f64,
    /// Bytes per instance: its R*-tree entry (estimated, see the module docs).
    pub tree_bytes: f64,
}

impl InstancesPoint {
    /// Samples per process CPU second.
    #[must_use]
    pub fn samples_per_cpu_second(&self) -> f64 {
        self.samples as f64 / self.cpu_seconds
    }

    /// CPU µs per sample.
    #[must_use]
    pub fn micros_per_sample(&self) -> f64 {
        1e6 * self.cpu_seconds / self.samples as f64
    }

    /// Work (voxel steps and tentative points) per sample.
    #[must_use]
    pub fn work_per_sample(&self) -> f64 {
        self.work as f64 / self.samples as f64
    }

    /// CPU ns per unit of work.
    #[must_use]
    pub fn nanos_per_work(&self) -> f64 {
        1e9 * self.cpu_seconds / self.work as f64
    }

    /// CPU µs per sample of camera rays alone (emission only).
    #[must_use]
    pub fn camera_micros_per_sample(&self) -> f64 {
        1e6 * self.camera_cpu_seconds / self.camera_samples as f64
    }

    /// Walks per sample.
    #[must_use]
    pub fn walks_per_sample(&self) -> f64 {
        self.walks as f64 / self.samples as f64
    }

    /// Overhead per instance in bytes.
    #[must_use]
    pub fn overhead_bytes(&self) -> f64 {
        self.member_bytes + self.mixture_bytes + self.tree_bytes
    }
}

/// The benchmark's figures (see the module docs).
#[derive(Clone, Debug, serde::Serialize)]
pub struct VolumesReport {
    /// Resolution of the generated explosion.
    pub resolution: u32,
    /// Image width and height.
    pub size: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Render threads (rayon's pool).
    pub threads: usize,
    /// Logical CPUs of the machine.
    pub cpus: usize,
    /// CPU model.
    pub cpu_model: String,
    /// One point per number of instances, in the order asked.
    pub points: Vec<InstancesPoint>,
}

/// The explosion's scene parts: the volume, its medium and its proxy, all shared.
struct Shared {
    volume: Arc<Volume>,
    medium: Medium,
    proxy: Arc<ProxyGrid>,
    /// Centre of the volume's world box.
    centre: DVec3,
    /// Distance between neighbouring instances' centres.
    spacing: f64,
}

/// Build the shared parts.
fn shared(resolution: u32) -> Result<Shared> {
    let ex = plume_synth::explosion(&plume_synth::ExplosionParams {
        resolution,
        seed: 3,
        ..Default::default()
    });
    let emission = Emission::blackbody(1.0);
    let volume = Volume::build(&ex.density, Some(&ex.temperature), |v| emission.map_source(v))?;
    let proxy = ProxyGrid::build(&volume, PROXY_RESOLUTION, light_power(&emission))?
        .ok_or_else(|| Error::Scene("bench volumes: the explosion emits nothing".into()))?;
    let plume_volume::Bounds3 { lo, hi } = volume.world_bounds();
    let extent = (hi.x - lo.x).max(hi.z - lo.z);
    Ok(Shared {
        volume: Arc::new(volume),
        medium: Medium {
            sigma_t: 1.0,
            albedo: Rgb::splat(0.8),
            g: 0.3,
            emission,
            extinction: Default::default(),
        },
        proxy: Arc::new(proxy),
        centre: 0.5 * (lo + hi),
        spacing: SPACING * extent,
    })
}

/// The first `n` cells of the grid, ring by ring from the centre (ring `r`: the cells with
/// `max(|x|, |z|) = r`, row by row).
fn cells(n: usize) -> Vec<(i64, i64)> {
    let mut out = Vec::with_capacity(n);
    let mut r = 0i64;
    while out.len() < n {
        for z in -r..=r {
            for x in -r..=r {
                if x.abs().max(z.abs()) == r && out.len() < n {
                    out.push((x, z));
                }
            }
        }
        r += 1;
    }
    out
}

/// Instance `i` at `cell`: the volume's centre moved there, turned about the up axis by
/// `i` golden angles and scaled by `0.8 + 0.4 frac(i φ⁻¹)`.
fn placement(s: &Shared, i: usize, (x, z): (i64, i64)) -> Result<Instance> {
    let golden_angle = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let scale = 0.8 + 0.4 * (i as f64 * 0.618_033_988_749_895).fract();
    let at = DVec3::new(x as f64 * s.spacing, 0.0, z as f64 * s.spacing);
    let world_from_base = DAffine3::from_translation(at)
        * DAffine3::from_mat3(DMat3::from_rotation_y(i as f64 * golden_angle) * scale)
        * DAffine3::from_translation(-s.centre);
    Instance::new(world_from_base)
        .ok_or_else(|| Error::Scene(format!("bench volumes: instance {i} is singular")))
}

/// The line-fnee integrator of the benchmark.
fn integrator() -> Integrator {
    Integrator {
        estimator: Estimator::Line,
        camera_estimator: None,
        light_sampling: LightSampling::Fnee,
        mis: MisHeuristic::Power,
        max_depth: 8,
        tracking: Tracking::Regular,
        split: 1,
        camera_collision: Collision::Analog,
        point_lookup: plume_engine::integrator::PointLookup::Exact,
        split_by: plume_engine::integrator::SplitBy::Uniform,
    }
}

/// Render `scene` `repeats` times (at least once): the process CPU seconds, wall seconds
/// and counters of the render of least CPU time.
fn timed<F: Field + Send + Sync>(
    scene: &Scene<F>,
    settings: &RenderSettings,
    repeats: u32,
) -> (f64, f64, Counters) {
    let mut best: Option<(f64, f64, Counters)> = None;
    for _ in 0..repeats.max(1) {
        let (cpu0, wall0) = (cpu_seconds(), Instant::now());
        let r = render(scene, settings, &|_, _| {});
        let (cpu, wall) = (cpu_seconds() - cpu0, wall0.elapsed().as_secs_f64());
        if best.as_ref().is_none_or(|b| cpu < b.0) {
            best = Some((cpu, wall, r.counters));
        }
    }
    best.expect("invariant: at least one render")
}

/// The layer of `n` instances and its camera, rendered `cfg.repeats` times.
fn measure(s: &Shared, n: usize, cfg: &VolumesConfig) -> Result<InstancesPoint> {
    let build = Instant::now();
    let mut members = Vec::with_capacity(n);
    let mut proxies = Vec::with_capacity(n);
    for (i, cell) in cells(n).into_iter().enumerate() {
        let instance = placement(s, i, cell)?;
        members.push(Member {
            field: Arc::clone(&s.volume),
            instance: Some(instance),
            medium: s.medium,
            visible_to_camera: true,
            casts_shadows: true,
        });
        let weight = proxy_weight(&s.proxy, &s.medium.emission) / instance.base_per_world_volume();
        proxies
            .push((PlacedProxy { proxy: Arc::clone(&s.proxy), instance: Some(instance) }, weight));
    }
    let volumes = Volumes::new(members)?;
    let mixture = ProxyMixture::new(proxies)
        .ok_or_else(|| Error::Scene("bench volumes: no proxy of positive power".into()))?;
    let build_seconds = build.elapsed().as_secs_f64();
    let mixture_bytes = mixture.memory_bytes() - s.proxy.memory_bytes();
    // Straight down at the centre instance; the view spans 3 spacings at the layer
    let height = HEIGHT * s.spacing;
    let fov = 2.0 * (1.5 / HEIGHT).atan().to_degrees();
    let camera = Camera::look_at(
        DVec3::new(0.0, height, 0.0),
        DVec3::ZERO,
        DVec3::Z,
        fov,
        cfg.size,
        cfg.size,
    )?;
    let medium = volumes.medium();
    let scene = Scene {
        field: volumes,
        medium,
        camera,
        lights: Lights { proxies: Some(mixture), ..Lights::default() },
        motion: None,
        majorants: None,
    };
    let settings = RenderSettings {
        budget: SampleBudget::Spp(cfg.spp),
        seed: 5,
        sampler: plume_core::sampling::SamplerKind::default(),
        threads: rayon::current_num_threads(),
        first_sample: 0,
        adaptive: None,
        integrator: integrator(),
    };
    let (cpu, wall, c) = timed(&scene, &settings, cfg.repeats);
    // Camera rays alone: emission and absorption, no scattering, no light samples
    let emission_only =
        RenderSettings { integrator: Integrator::emission_only(Estimator::Line), ..settings };
    let (camera_cpu, _, camera_counters) = timed(&scene, &emission_only, cfg.repeats);
    // The R*-tree's leaf: a 3-D box of f64 and the member's index
    let leaf = std::mem::size_of::<([[f64; 3]; 2], usize)>();
    let member = std::mem::size_of::<Member<Volume>>() + std::mem::size_of::<Option<usize>>();
    Ok(InstancesPoint {
        instances: n,
        samples: c.samples,
        cpu_seconds: cpu,
        wall_seconds: wall,
        walks: c.walks,
        work: c.voxel_steps + c.tentative_points,
        camera_cpu_seconds: camera_cpu,
        camera_samples: camera_counters.samples,
        build_seconds,
        volume_bytes: s.volume.memory_bytes(),
        proxy_bytes: s.proxy.memory_bytes(),
        member_bytes: member as f64,
        mixture_bytes: mixture_bytes as f64 / n as f64,
        tree_bytes: (2 * leaf) as f64,
    })
}

/// Run the benchmark.
///
/// # Errors
/// No numbers of instances, a zero among them, or a scene that cannot be built (not
/// expected).
pub fn run(cfg: &VolumesConfig) -> Result<VolumesReport> {
    if cfg.instances.is_empty() || cfg.instances.contains(&0) {
        return Err(Error::Scene("bench volumes: --instances must be positive numbers".into()));
    }
    let s = shared(cfg.resolution)?;
    let mut points = Vec::new();
    for &n in &cfg.instances {
        let p = measure(&s, n, cfg)?;
        log::info!(
            "bench volumes: {n} instances, {} samples per CPU second",
            num(p.samples_per_cpu_second())
        );
        points.push(p);
    }
    let machine = super::machine();
    Ok(VolumesReport {
        resolution: cfg.resolution,
        size: cfg.size,
        spp: cfg.spp,
        threads: rayon::current_num_threads(),
        cpus: machine.cpus,
        cpu_model: machine.model,
        points,
    })
}

impl VolumesReport {
    /// The points of least instances with a full view (else least) and of most.
    fn ends(&self) -> Option<(&InstancesPoint, &InstancesPoint)> {
        let full = self.points.iter().filter(|p| p.instances >= 9).min_by_key(|p| p.instances);
        let least = full.or_else(|| self.points.iter().min_by_key(|p| p.instances))?;
        let most = self.points.iter().max_by_key(|p| p.instances)?;
        Some((least, most))
    }

    /// The camera rays' cost per sample at the most instances over that at the least
    /// with a full view.
    #[must_use]
    pub fn cost_ratio(&self) -> f64 {
        self.ends()
            .map_or(f64::NAN, |(a, b)| b.camera_micros_per_sample() / a.camera_micros_per_sample())
    }

    /// The largest overhead per instance, bytes.
    #[must_use]
    pub fn largest_overhead(&self) -> f64 {
        self.points.iter().map(InstancesPoint::overhead_bytes).fold(0.0, f64::max)
    }

    /// The figures as Markdown: the table and the verdict's line.
    #[must_use]
    pub fn table(&self) -> String {
        let mut s = String::new();
        let base = self.ends().map_or(f64::NAN, |(a, _)| a.micros_per_sample());
        let _ = writeln!(
            s,
            "| instances | samples / CPU s | CPU µs / sample | ÷ fewest | work / sample | walks / sample | ns / work | camera rays alone µs / sample | build ms | overhead B / instance (member + mixture + tree) |"
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|");
        for p in &self.points {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {}× | {} | {} | {} | {} | {} | {} ({} + {} + {}) |",
                p.instances,
                num(p.samples_per_cpu_second()),
                num(p.micros_per_sample()),
                num(p.micros_per_sample() / base),
                num(p.work_per_sample()),
                num(p.walks_per_sample()),
                num(p.nanos_per_work()),
                num(p.camera_micros_per_sample()),
                num(1e3 * p.build_seconds),
                num(p.overhead_bytes()),
                num(p.member_bytes),
                num(p.mixture_bytes),
                num(p.tree_bytes),
            );
        }
        if let Some(p) = self.points.first() {
            let _ = writeln!(
                s,
                "\nShared, once: volume {} KiB, proxy {} KiB. Explosion {}³, {}² px, {} spp, line-fnee, {} threads on {} CPUs ({}).",
                num(p.volume_bytes as f64 / 1024.0),
                num(p.proxy_bytes as f64 / 1024.0),
                self.resolution,
                self.size,
                self.spp,
                self.threads,
                self.cpus,
                self.cpu_model,
            );
        }
        let _ = writeln!(
            s,
            "\nCamera rays' cost per sample, most ÷ fewest instances with a full view: {}× (limit {}×); largest overhead per instance {} B (limit {} B): {}.",
            num(self.cost_ratio()),
            num(MAX_COST_RATIO),
            num(self.largest_overhead()),
            num(MAX_OVERHEAD_BYTES),
            if self.verdict().is_ok() { "pass" } else { "FAIL" }
        );
        s
    }

    /// `Err` when a check fails (see the module docs).
    ///
    /// # Errors
    /// The cost ratio above [`MAX_COST_RATIO`] or an overhead at or above
    /// [`MAX_OVERHEAD_BYTES`].
    pub fn verdict(&self) -> Result<()> {
        let ratio = self.cost_ratio();
        let mut failed = Vec::new();
        if ratio.is_nan() || ratio > MAX_COST_RATIO {
            failed.push(format!(
                "camera rays' cost per sample grew {}× (limit {MAX_COST_RATIO}×)",
                num(ratio)
            ));
        }
        let overhead = self.largest_overhead();
        if overhead.is_nan() || overhead >= MAX_OVERHEAD_BYTES {
            failed.push(format!(
                "overhead per instance {} B (limit {MAX_OVERHEAD_BYTES} B)",
                num(overhead)
            ));
        }
        if failed.is_empty() {
            Ok(())
        } else {
            Err(Error::Scene(format!("bench volumes: {}", failed.join("; "))))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::cells;

    #[test]
    fn cells_fill_rings_from_the_centre() {
        assert_eq!(cells(1), vec![(0, 0)]);
        let nine = cells(9);
        assert!(nine.iter().all(|&(x, z)| x.abs() <= 1 && z.abs() <= 1));
        let mut all = cells(1000);
        assert_eq!(all.len(), 1000);
        all.sort_unstable();
        all.dedup();
        assert_eq!(all.len(), 1000, "no cell twice");
    }
}
