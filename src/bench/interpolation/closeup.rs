//! The close-up of `plume bench interpolation`: one view rendered with nearest and with
//! linear reconstruction, side by side at one exposure.
//!
//! The scene is a real Blender Mantaflow explosion (Kelvin grid, physical convention:
//! emission ∝ density × blackbody, so the smoke's texture shows in the fire; in the Cycles
//! convention the fire is nearly uniform and only its outline shows the voxels),
//! emission–absorption with the expected-value estimator (ray-march), so the picture shows
//! the reconstruction and not the noise of scattering. The camera looks along the
//! automatic framing's direction for Z-up files, `(0.35, −1, 0.25)`, at the **focus**: on
//! the middle row of the automatic view, the first pixel from the left whose brightness
//! reaches a quarter of the row's brightest (the fire's edge, where blocks show most), and
//! on its ray the point where the emission collected reaches half of the ray's total (on
//! the fire's visible surface). Its distance makes one voxel `pixels_per_voxel` pixels
//! across there:
//! `D = h · W / (2 tan(fov/2) · pixels_per_voxel)` for voxel edge `h`, image width `W`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::DVec3;
use serde::Serialize;

use super::switch::Switch;
use crate::bench::progressive::{accumulate, average};
use crate::bench::spec::{bench_shot, load_file};
use plume_core::error::{Error, Result};
use plume_engine::camera::Camera;
use plume_engine::integrator::{AnyScene, Integrator};
use plume_engine::medium::{Estimator, Medium};
use plume_engine::render::{render, RenderSettings, SampleBudget};
use plume_scene::file::with_keys;
use plume_volume::field::{clip_to_box, Ray};
use plume_volume::trilinear::Trilinear;
use plume_volume::{Field, Interpolation};

/// Horizontal field of view of the close-up, degrees.
const FOV_DEGREES: f64 = 20.0;
/// Viewing direction (towards the camera) of the automatic framing of Z-up files.
const VIEW: DVec3 = DVec3::new(0.35, -1.0, 0.25);

/// Settings of the picture.
#[derive(Clone, Debug)]
pub struct CloseupConfig {
    /// The PNG written.
    pub path: PathBuf,
    /// The file, under the data directory.
    pub file: PathBuf,
    /// Size of each half.
    pub width: u32,
    /// Size of each half.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Voxel edge at the focus, in pixels.
    pub pixels_per_voxel: f64,
    /// Render threads (0 = all cores).
    pub threads: usize,
}

/// How the picture was made.
#[derive(Clone, Debug, Serialize)]
pub struct CloseupReport {
    /// The file, under the data directory.
    pub file: String,
    /// The PNG written.
    pub path: String,
    /// Size of each half.
    pub width: u32,
    /// Size of each half.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Voxel edge at the focus, in pixels.
    pub pixels_per_voxel: f64,
    /// Horizontal field of view, degrees.
    pub fov_degrees: f64,
    /// Camera position, world.
    pub camera_from: [f64; 3],
    /// Focus point, world.
    pub camera_at: [f64; 3],
    /// Wall seconds of each render: nearest, linear.
    pub render_seconds: [f64; 2],
}

impl CloseupReport {
    /// One paragraph saying what the picture shows.
    #[must_use]
    pub fn caption(&self) -> String {
        format!(
            "**Close-up** of `{}` (physical convention, emission–absorption, ray-march estimator, {} spp, {}×{} each, field of view {}°, one voxel ≈ {} pixels across at the focus), nearest (left) and linear (right) at the same exposure. Nearest shows each voxel's box; linear is OpenVDB's `BoxSampler`, Cycles' `Linear`. Renders took {:.1} s and {:.1} s wall.",
            self.file,
            self.spp,
            self.width,
            self.height,
            self.fov_degrees,
            self.pixels_per_voxel,
            self.render_seconds[0],
            self.render_seconds[1]
        )
    }
}

/// Luminance of `∫ τ L_e` along `ray` (a midpoint march of ¼ voxel) and the point where
/// it reaches half its total, when anything along the ray emits.
fn half_emission(field: &Trilinear, medium: &Medium, ray: &Ray) -> Option<(f64, DVec3)> {
    let b = field.world_bounds();
    let (t0, t1) = clip_to_box(ray.origin, ray.direction, b.lo, b.hi, 0.0, f64::INFINITY)?;
    let index_per_world = (field.volume().index_from_world().matrix3 * ray.direction).length();
    let n = ((t1 - t0) * index_per_world * 4.0).ceil().max(1.0) as usize;
    let h = (t1 - t0) / n as f64;
    let le = |d: f32, s: f32| medium.emission.le(d, s);
    let mut optical_depth = 0.0;
    let mut cumulative = Vec::with_capacity(n);
    let mut total = 0.0;
    for i in 0..n {
        let c = field.interpolate_world(ray.at(t0 + (i as f64 + 0.5) * h));
        let mu_t = medium.sigma_t * c.density();
        let e = c.emission(&le);
        total += (-(optical_depth + 0.5 * mu_t * h)).exp()
            * h
            * (0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2]);
        optical_depth += mu_t * h;
        cumulative.push(total);
    }
    let i = cumulative.iter().position(|&c| c >= 0.5 * total).filter(|_| total > 0.0)?;
    Some((total, ray.at(t0 + (i as f64 + 0.5) * h)))
}

/// The focus: on the middle row of the automatic view, the first pixel from the left
/// whose luminance reaches a quarter of the row's brightest, so that the fire's edge
/// against the background crosses the close-up; there, the point of half emission.
fn focus(field: &Trilinear, medium: &Medium, camera: &Camera) -> Option<DVec3> {
    let y = 0.5 * f64::from(camera.height);
    let row: Vec<Option<(f64, DVec3)>> = (0..camera.width)
        .map(|x| half_emission(field, medium, &camera.ray(f64::from(x) + 0.5, y)))
        .collect();
    let brightest = row.iter().flatten().map(|p| p.0).fold(0.0, f64::max);
    row.into_iter().flatten().find(|p| p.0 >= 0.25 * brightest && brightest > 0.0).map(|p| p.1)
}

/// Render the pair and write the PNG.
///
/// # Errors
/// A missing or unreadable file, a ray that misses the fire, an unwritable PNG.
pub fn run(data: &Path, cfg: &CloseupConfig, log: &dyn Fn(&str)) -> Result<CloseupReport> {
    let keys = format!(
        "[emission]\nconvention = \"physical\"\n[camera]\nup_axis = \"z\"\nwidth = {}\nheight = {}",
        cfg.width, cfg.height
    );
    let shot = with_keys(&bench_shot(&data.join(&cfg.file).display().to_string()), &keys)?;
    let mut scene = load_file(shot, vec![])?.loaded.scene;
    let AnyScene::Linear(s) = &scene else { unreachable!("invariant: linear is the default") };
    let at = focus(&s.field, &s.medium, &s.camera).ok_or_else(|| {
        Error::Scene(format!("{}: the middle row meets no emission", cfg.file.display()))
    })?;
    let voxel = s.field.volume().world_from_index().matrix3.x_axis.length();
    let distance = voxel * f64::from(cfg.width)
        / (2.0 * (0.5 * FOV_DEGREES.to_radians()).tan() * cfg.pixels_per_voxel);
    let from = at + VIEW.normalize() * distance;
    let camera = Camera::look_at(from, at, DVec3::Z, FOV_DEGREES, cfg.width, cfg.height)?;
    plume_engine::with_scene!(&mut scene, s => s.camera = camera);
    let mut scene = Switch(Some(scene));
    let settings = RenderSettings {
        budget: SampleBudget::Spp(cfg.spp),
        seed: 0,
        sampler: plume_core::sampling::SamplerKind::default(),
        threads: cfg.threads,
        first_sample: 0,
        adaptive: None,
        integrator: Integrator::emission_only(Estimator::RayMarch),
    };
    let mut images = Vec::new();
    let mut seconds = [0.0; 2];
    for (k, i) in [Interpolation::Nearest, Interpolation::Linear].into_iter().enumerate() {
        let start = Instant::now();
        let r = plume_engine::with_scene!(scene.to(i), s => render(s, &settings, &|_, _| {}));
        seconds[k] = start.elapsed().as_secs_f64();
        let mut sums = vec![[0.0f64; 4]; (cfg.width * cfg.height) as usize];
        accumulate(&mut sums, &r.film);
        images.push(average(&sums, r.spp));
    }
    let exposure = crate::output::auto_exposure(&images[1]);
    if let Some(dir) = cfg.path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|source| Error::Write { path: dir.to_path_buf(), source })?;
    }
    let panels = [
        ("nearest".to_string(), images[0].as_slice()),
        ("linear (trilinear)".to_string(), images[1].as_slice()),
    ];
    crate::bench::plot::side_by_side(&cfg.path, cfg.width, cfg.height, &panels, exposure)?;
    log(&format!(
        "wrote {} (voxel {:.4} world units, camera {:.2} from the focus)",
        cfg.path.display(),
        voxel,
        distance
    ));
    Ok(CloseupReport {
        file: cfg.file.display().to_string(),
        path: cfg.path.display().to_string(),
        width: cfg.width,
        height: cfg.height,
        spp: cfg.spp,
        pixels_per_voxel: cfg.pixels_per_voxel,
        fov_degrees: FOV_DEGREES,
        camera_from: from.to_array(),
        camera_at: at.to_array(),
        render_seconds: seconds,
    })
}
