//! The one validation of a [`Shot`]: every check that needs no file, each failure an
//! [`Error::InvalidArgument`] naming the field by its key (`camera.width`). The binary
//! turns a key into the flag a user typed or the scene file's line.
//!
//! Every volume of a scene gets the same checks, each naming the volume's own key
//! ([`EntryRef::key`]: `volume.matrix`, `medium.g` for one volume given as `[volume]`;
//! `volumes[1].matrix`, `volumes[1].medium.g` in a list). What several volumes cannot
//! do yet is refused in `several_volumes.rs`, also for a volume with `instances`, whose
//! placements are checked as a volume's own (`volume.instances[1].matrix`).
//!
//! What needs the file system (frame tokens of paths that exist, writable outputs) or
//! the data (proxy resolution against the volume, grids present) is checked when the
//! job runs.

use std::ops::Deref;

use super::{CameraSettings, JobSettings, Projection, RenderOptions, SceneDescription, Shot};
use crate::selector::GridSelector;
use crate::sets::TemperatureMap;
use crate::volumes::EntryRef;
use plume_core::error::{Error, Result};

/// A [`Shot`] that passed [`Shot::validate`]; what renders take.
#[derive(Clone, Debug, PartialEq)]
pub struct ValidShot(Shot);

impl Deref for ValidShot {
    type Target = Shot;
    fn deref(&self) -> &Shot {
        &self.0
    }
}

impl ValidShot {
    /// The shot.
    #[must_use]
    pub fn into_inner(self) -> Shot {
        self.0
    }
}

fn finite_nonneg(key: &str, v: f64) -> Result<()> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(key, format!("{v} must be a finite number ≥ 0")))
    }
}

fn positive_seconds(key: &str, v: f64) -> Result<()> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(key, format!("{v} must be a positive number of seconds")))
    }
}

fn nonneg_components(key: &str, v: [f64; 3]) -> Result<()> {
    if v.iter().all(|c| c.is_finite() && *c >= 0.0) {
        Ok(())
    } else {
        Err(Error::invalid(key, "components must be finite and ≥ 0"))
    }
}

/// The grid selector `name` (`name` or `name[N]`).
///
/// # Errors
/// [`Error::InvalidArgument`] for `key` when it does not parse.
pub fn selector(key: &str, name: &str) -> Result<GridSelector> {
    name.parse::<GridSelector>()
        .map_err(|_| Error::invalid(key, format!("{name:?} is not a grid name or name[N]")))
}

impl Shot {
    /// Check every value that can be checked without reading files.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the field's key, e.g. `medium.albedo`.
    pub fn validate(self) -> Result<ValidShot> {
        let (scene, job) = (&self.scene, &self.settings);
        let entries = scene.entries();
        sample_budget(&job.render)?;
        camera_frame(&scene.camera)?;
        for entry in &entries {
            instances(entry)?;
        }
        crate::several_volumes::check(scene, &entries)?;
        medium_and_method(scene, &entries)?;
        motion(scene, &entries[0])?;
        camera_motion(&scene.camera)?;
        for entry in &entries {
            grids(entry)?;
            entry.volume.placement().transform(&entry.prefix)?;
        }
        job_settings(job, &scene.camera)?;
        Ok(ValidShot(self))
    }
}

/// `render.spp` and `render.time`.
fn sample_budget(r: &RenderOptions) -> Result<()> {
    if r.spp == Some(0) {
        return Err(Error::invalid("render.spp", "must be at least 1"));
    }
    adaptive(r)?;
    if let Some(t) = r.time {
        positive_seconds("render.time", t)?;
        if r.spp.is_some() {
            return Err(Error::invalid("render.spp", "give render.spp or render.time, not both"));
        }
    }
    Ok(())
}

/// `render.noise_threshold`, `render.min_spp` and `render.noise_floor`.
fn adaptive(r: &RenderOptions) -> Result<()> {
    let Some(t) = r.noise_threshold else {
        for (key, given) in [
            ("render.min_spp", r.min_spp.is_some()),
            ("render.noise_floor", r.noise_floor.is_some()),
        ] {
            if given {
                return Err(Error::invalid(
                    key,
                    "is for adaptive sampling: give render.noise_threshold too",
                ));
            }
        }
        return Ok(());
    };
    if !(t.is_finite() && t > 0.0) {
        return Err(Error::invalid(
            "render.noise_threshold",
            format!("{t} must be positive and finite"),
        ));
    }
    if let Some(f) = r.noise_floor {
        if !(f.is_finite() && f > 0.0) {
            return Err(Error::invalid(
                "render.noise_floor",
                format!("{f} must be positive and finite"),
            ));
        }
    }
    if let Some(m) = r.min_spp {
        if m < 2 {
            return Err(Error::invalid(
                "render.min_spp",
                format!("{m} is below 2: a pixel's error needs two samples"),
            ));
        }
        if r.time.is_none() {
            let cap = r.spp.unwrap_or_else(|| r.default_spp());
            if m > cap {
                let what = if r.spp.is_some() {
                    "render.spp"
                } else {
                    "the default cap of adaptive sampling"
                };
                return Err(Error::invalid(
                    "render.min_spp",
                    format!("{m} is more than {what} ({cap})"),
                ));
            }
        }
    }
    Ok(())
}

/// The image size and field of view.
fn camera_frame(cam: &CameraSettings) -> Result<()> {
    if cam.width == 0 || cam.height == 0 || cam.width > 32768 || cam.height > 32768 {
        return Err(Error::invalid(
            "camera.width/camera.height",
            format!("{}x{} must be between 1x1 and 32768x32768", cam.width, cam.height),
        ));
    }
    if !(cam.fov.is_finite() && cam.fov > 0.0 && cam.fov < 180.0) {
        return Err(Error::invalid(
            "camera.fov",
            format!("{} is not in (0, 180) degrees", cam.fov),
        ));
    }
    camera_optics(cam)
}

/// Focal length, sensor, aperture, focus and orthographic width: positive where given,
/// and only the combinations that mean something.
fn camera_optics(cam: &CameraSettings) -> Result<()> {
    let positive = |key: &str, v: Option<f64>| match v {
        Some(x) if !(x.is_finite() && x > 0.0) => {
            Err(Error::invalid(key, format!("{x} must be positive and finite")))
        }
        _ => Ok(()),
    };
    positive("camera.focal_length", cam.focal_length)?;
    positive("camera.sensor_width", cam.sensor_width)?;
    positive("camera.fstop", cam.fstop)?;
    positive("camera.focus_distance", cam.focus_distance)?;
    positive("camera.ortho_width", cam.ortho_width)?;
    if let Some(r) = cam.aperture_radius.filter(|r| !(r.is_finite() && *r >= 0.0)) {
        return Err(Error::invalid("camera.aperture_radius", format!("{r} must be 0 or more")));
    }
    if cam.fstop.is_some() && cam.aperture_radius.is_some() {
        return Err(Error::invalid(
            "camera.fstop",
            "give camera.fstop (with camera.focal_length) or camera.aperture_radius, not both",
        ));
    }
    if cam.fstop.is_some() && cam.focal_length.is_none() {
        return Err(Error::invalid(
            "camera.fstop",
            "needs camera.focal_length (the aperture is focal_length / fstop wide)",
        ));
    }
    if cam.sensor_width.is_some() && cam.focal_length.is_none() {
        return Err(Error::invalid(
            "camera.sensor_width",
            "needs camera.focal_length (together they set the field of view)",
        ));
    }
    let orthographic = cam.projection == Projection::Orthographic;
    if orthographic && cam.lens_radius() > 0.0 {
        return Err(Error::invalid(
            "camera.projection",
            "an orthographic camera has no lens: leave out camera.fstop and camera.aperture_radius",
        ));
    }
    if !orthographic && cam.ortho_width.is_some() {
        return Err(Error::invalid(
            "camera.ortho_width",
            "applies to camera.projection = \"orthographic\" only",
        ));
    }
    if orthographic && cam.focal_length.is_some() {
        return Err(Error::invalid(
            "camera.focal_length",
            "an orthographic camera has no focal length: give camera.ortho_width",
        ));
    }
    Ok(())
}

/// The media, emission, lights and the integrator's choices, and which of them go
/// together.
fn medium_and_method(scene: &SceneDescription, entries: &[EntryRef<'_>]) -> Result<()> {
    for e in entries {
        finite_nonneg(&e.key("medium.density_scale"), e.medium.density_scale)?;
        finite_nonneg(&e.key("emission.scale"), f64::from(e.emission.scale))?;
    }
    finite_nonneg("integrator.kappa", scene.integrator.kappa)?;
    if !(1..=256).contains(&scene.integrator.split) {
        return Err(Error::invalid(
            "integrator.split",
            format!(
                "{} is not between 1 and 256 paths per camera collision",
                scene.integrator.split
            ),
        ));
    }
    for e in entries {
        emission_and_medium(scene, e)?;
    }
    scene.lights.validate()?;
    let (estimator, light_sampling) = scene.integrator.parts();
    if matches!(
        scene.integrator.tracking,
        super::TrackingChoice::Mixed | super::TrackingChoice::Null
    ) && scene.scatters()
        && !crate::sets::Tracking::applies(estimator, light_sampling)
    {
        return Err(Error::invalid(
            "integrator.tracking",
            format!(
                "{} tracks by null collisions after scattering, which {} cannot use (blend mixes per voxel; the point estimator's MIS with classic NEE needs exact optical depths): use regular or auto",
                super::Choice::name(scene.integrator.tracking),
                if light_sampling == crate::sets::LightSampling::Nee { "the point estimator with classic NEE" } else { "the blend estimator" }
            ),
        ));
    }
    // The camera segment tracks by null collisions under `null` and with motion blur,
    // which blend (a per-voxel mix) cannot use
    let camera_null = scene.integrator.tracking == super::TrackingChoice::Null
        || scene.volume.velocity_grid.is_some();
    if camera_null && scene.integrator.camera_estimator == Some(super::EstimatorKind::Blend) {
        return Err(Error::invalid(
            "integrator.camera_estimator",
            "blend mixes per voxel, which null-collision tracking of camera rays (tracking = null, motion blur) has not: use line, point or ray-march",
        ));
    }
    Ok(())
}

/// One volume's emission mapping, albedo, g and absorption colour.
fn emission_and_medium(scene: &SceneDescription, e: &EntryRef<'_>) -> Result<()> {
    finite_nonneg(&e.key("emission.temperature_cutoff"), f64::from(e.emission.temperature_cutoff))?;
    nonneg_components(&e.key("emission.color"), e.emission.color.map(f64::from))?;
    e.emission.temperature_map.parse::<TemperatureMap>().map_err(|err| match err {
        Error::InvalidArgument { message, .. } => {
            Error::invalid(&e.key("emission.temperature_map"), message)
        }
        other => other,
    })?;
    for albedo in e.albedo_rgb() {
        if !(0.0..=1.0).contains(&albedo) {
            return Err(Error::invalid(
                &e.key("medium.albedo"),
                format!("{albedo} is not in [0, 1]"),
            ));
        }
    }
    if !(e.medium.g > -1.0 && e.medium.g < 1.0) {
        return Err(Error::invalid(
            &e.key("medium.g"),
            format!("{} is not in (-1, 1)", e.medium.g),
        ));
    }
    absorption_color(scene, e)
}

/// A volume's absorption colour, and what chromatic extinction may be used with: it is
/// tracked regularly (its hero-channel pdfs need exact optical depths), and its channels'
/// extinction ratios must be the same everywhere (an albedo grid would change them per
/// voxel).
fn absorption_color(scene: &SceneDescription, e: &EntryRef<'_>) -> Result<()> {
    let Some(color) = e.medium.absorption_color else { return Ok(()) };
    let key = e.key("medium.absorption_color");
    for a in color.rgb() {
        if !(0.0..=1.0).contains(&a) {
            return Err(Error::invalid(&key, format!("{a} is not in [0, 1]")));
        }
    }
    if color.rgb() == [0.0; 3] {
        return Ok(());
    }
    let refuse = |with: String| {
        Err(Error::invalid(&key, format!("an absorption colour cannot be used with {with}")))
    };
    if e.volume.albedo_grid.is_some() {
        return refuse(format!(
            "an albedo grid ({}): it would change the extinction per voxel",
            e.key("albedo_grid")
        ));
    }
    if e.volume.velocity_grid.is_some() {
        return refuse(format!(
            "motion blur ({}), which tracks by null collisions",
            e.key("velocity_grid")
        ));
    }
    if scene.integrator.tracking == super::TrackingChoice::Null {
        return refuse("integrator.tracking = \"null\": coloured media track regularly".into());
    }
    Ok(())
}

/// Motion blur: the first volume's velocity grid (several volumes have none) and what may
/// be used with it.
fn motion(scene: &SceneDescription, first: &EntryRef<'_>) -> Result<()> {
    if let Some(name) = &first.volume.velocity_grid {
        selector(&first.key("velocity_grid"), name)?;
        if !first.volume.velocity_scale.is_finite() {
            return Err(Error::invalid(
                &first.key("velocity_scale"),
                format!("{} must be finite", first.volume.velocity_scale),
            ));
        }
        let (_, light_sampling) = scene.integrator.parts();
        if light_sampling == crate::sets::LightSampling::Nee && scene.scatters() {
            return Err(Error::invalid(
                "integrator.light_sampling",
                "classic NEE draws points from the frame's emitters, which move under motion blur: use fnee (the default) or none",
            ));
        }
        if matches!(scene.integrator.parts().0, crate::sets::Estimator::Blend { .. }) {
            return Err(Error::invalid(
                "integrator.estimator",
                "blend mixes per voxel, which null-collision tracking (motion blur) has not: use line, point or ray-march",
            ));
        }
    }
    Ok(())
}

/// The shutter, camera keys and frame rate.
fn camera_motion(cam: &CameraSettings) -> Result<()> {
    if let Some([open, close]) = cam.shutter {
        if !(open.is_finite() && close.is_finite() && open <= close) {
            return Err(Error::invalid(
                "camera.shutter",
                format!("{open},{close}: open must be at most close, both finite (frames)"),
            ));
        }
    }
    if !cam.keys.is_empty() {
        if cam.from.is_some() || cam.at.is_some() {
            return Err(Error::invalid(
                "camera.keys",
                "give camera.keys or camera.from/camera.at, not both",
            ));
        }
        for (i, k) in cam.keys.iter().enumerate() {
            if !(k.frame.is_finite()
                && k.from.is_finite()
                && k.at.is_finite()
                && k.up.is_none_or(|u| u.is_finite()))
            {
                return Err(Error::invalid(
                    "camera.keys",
                    format!("key {}: frame, from, at and up must be finite", i + 1),
                ));
            }
            if let Some(f) = k.fov {
                if !(f > 0.0 && f < 180.0) {
                    return Err(Error::invalid(
                        "camera.keys",
                        format!("key {}: fov {f} is not in (0, 180) degrees", i + 1),
                    ));
                }
            }
            if i > 0 && cam.keys[i - 1].frame >= k.frame {
                return Err(Error::invalid(
                    "camera.keys",
                    format!(
                        "key {}: frames must increase ({} after {})",
                        i + 1,
                        k.frame,
                        cam.keys[i - 1].frame
                    ),
                ));
            }
        }
    }
    if !(cam.fps.is_finite() && cam.fps > 0.0) {
        return Err(Error::invalid(
            "camera.fps",
            format!("{} must be a positive number of frames per second", cam.fps),
        ));
    }
    Ok(())
}

/// A volume's instances: where given, at least one, each a valid placement (named
/// `volumes[1].instances[0].matrix`).
fn instances(e: &EntryRef<'_>) -> Result<()> {
    let Some(list) = &e.volume.instances else { return Ok(()) };
    if list.is_empty() {
        return Err(Error::invalid(
            &e.key("instances"),
            "is empty: give at least one placement ({ translate = [x, y, z] }, rotate, scale or matrix), or leave instances out",
        ));
    }
    for (k, placement) in list.iter().enumerate() {
        placement.transform(&e.key(&format!("instances[{k}]")))?;
    }
    Ok(())
}

/// Every grid name of a volume parses as `name` or `name[N]`; its name and group are
/// layer names.
fn grids(e: &EntryRef<'_>) -> Result<()> {
    let v = e.volume;
    selector(&e.key("density_grid"), &v.density_grid)?;
    selector(&e.key("temperature_grid"), &v.temperature_grid)?;
    for (field, name) in [("emission_grid", &v.emission_grid), ("albedo_grid", &v.albedo_grid)] {
        if let Some(n) = name {
            selector(&e.key(field), n)?;
        }
    }
    crate::lights::group_name(&e.key("name"), v.name.as_ref())?;
    crate::lights::group_name(&e.key("group"), v.group.as_ref())
}

/// Outputs, reading, and the farm's frames, crops, tiles and sample ranges.
fn job_settings(job: &JobSettings, cam: &CameraSettings) -> Result<()> {
    let r = &job.render;
    if let Some(dp) = r.debug_pixel {
        if dp.x >= cam.width || dp.y >= cam.height {
            return Err(Error::invalid(
                "render.debug_pixel",
                format!(
                    "pixel {},{} is outside the {}x{} image",
                    dp.x, dp.y, cam.width, cam.height
                ),
            ));
        }
    }
    let out = &job.output;
    if let Some(e) = out.exposure {
        if !e.is_finite() {
            return Err(Error::invalid("output.exposure", "must be finite"));
        }
    }
    if out.image.as_os_str().is_empty() {
        return Err(Error::invalid(
            "output.image",
            "required: the EXR to write (`-o OUT.exr`, or `image` in `[output]`)",
        ));
    }
    if !out.image.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        return Err(Error::invalid(
            "output.image",
            format!("{} must end in .exr", out.image.display()),
        ));
    }
    positive_seconds("reading.read_timeout", job.reading.read_timeout)?;
    if let Some(t) = r.cache_lock_timeout {
        if !(t.is_finite() && t >= 0.0) {
            return Err(Error::invalid(
                "render.cache_lock_timeout",
                format!("{t} must be a number of seconds, 0 or more"),
            ));
        }
    }
    let farm = &job.farm;
    if let Some(list) = &farm.frames {
        crate::frames::parse_frames(list).map_err(|m| Error::invalid("farm.frames", m))?;
    }
    if let Some(t) = farm.time_limit {
        positive_seconds("farm.time_limit", t)?;
    }
    if farm.crop.is_some() && farm.tile.is_some() {
        return Err(Error::invalid("farm.crop", "give farm.crop or farm.tile, not both"));
    }
    if let Some(c) = farm.crop {
        if !c.fits(cam.width, cam.height) {
            return Err(Error::invalid(
                "farm.crop",
                format!("{c} is not inside the {}x{} image", cam.width, cam.height),
            ));
        }
    }
    if let Some(t) = farm.tile {
        crate::split::tile_crop(t.index, t.count, cam.width, cam.height, r.adaptive_block())
            .map_err(|m| Error::invalid("farm.tile", m))?;
    }
    if let (Some(c), true) = (farm.crop, r.noise_threshold.is_some()) {
        // Adaptive decisions pool blocks of pixels: a crop must not cut one
        let b = r.adaptive_block();
        let on_edge = |v: u32, size: u32| v % b == 0 || v == size;
        if !(on_edge(c.x0, cam.width)
            && on_edge(c.y0, cam.height)
            && on_edge(c.x1, cam.width)
            && on_edge(c.y1, cam.height))
        {
            return Err(Error::invalid(
                "farm.crop",
                format!("{c} cuts adaptive sampling's blocks of {b}x{b} pixels: with render.noise_threshold its edges must be multiples of {b} or the image's"),
            ));
        }
    }
    if let Some(range) = &farm.sample_range {
        if r.spp.is_some() || r.time.is_some() {
            return Err(Error::invalid(
                "farm.sample_range",
                "give farm.sample_range or render.spp/render.time, not both",
            ));
        }
        if r.noise_threshold.is_some() {
            // Checkpoints need each pixel's samples from 0: a range starting later cannot
            // decide, and ranges rendered apart would decide differently from one render
            return Err(Error::invalid(
                "farm.sample_range",
                "cannot be merged deterministically with adaptive sampling (render.noise_threshold), which decides from each pixel's samples from 0 on; split the frame with farm.tile or farm.crop instead",
            ));
        }
        if range.end - range.start > u64::from(u32::MAX) {
            return Err(Error::invalid(
                "farm.sample_range",
                "at most 4294967295 samples per pixel in one run",
            ));
        }
    }
    Ok(())
}
