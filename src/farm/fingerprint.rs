//! What identifies a frame's pixels: the SHA-256 of the input file and a hash of the
//! settings. Parts of a frame merge only if both agree; an existing output is skipped or
//! continued only if its settings hash matches.

use std::io::Read;
use std::path::Path;

use sha2::{Digest, Sha256};

use plume_core::error::{Error, Result};
use plume_scene::{
    CameraSettings, EmissionSettings, EnvironmentMapSettings, FarmOptions, IntegratorSettings,
    JobSettings, LightSettings, MediumSettings, OutputSettings, ReadSettings, RenderOptions,
    SceneDescription, Shot, VolumeEntry, VolumeInput,
};

/// Hex SHA-256 of a file's bytes and its size.
///
/// # Errors
/// [`Error::Open`] naming the file.
///
/// A brick cache file (`.plume`) is identified by its header page instead: the header
/// holds the hash of the chunk checksums, which cover every other byte, so hashing 4 KiB
/// identifies a file of tens of GB (its size is still the file's).
pub fn file_sha256(path: &Path) -> Result<(String, u64)> {
    let open = |source| Error::Open { path: path.to_path_buf(), source };
    let mut file = std::fs::File::open(path).map_err(open)?;
    let mut hasher = Sha256::new();
    if crate::cache::is_cache_path(path) {
        let size = file.metadata().map_err(open)?.len();
        let mut page = vec![0u8; plume_volume::out_of_core::format::PAGE as usize];
        let n = file.read(&mut page).map_err(open)?;
        hasher.update(&page[..n]);
        return Ok((hex(&hasher.finalize()), size));
    }
    let mut buf = vec![0u8; 1 << 20];
    let mut bytes = 0u64;
    loop {
        let n = file.read(&mut buf).map_err(open)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        bytes += n as u64;
    }
    Ok((hex(&hasher.finalize()), bytes))
}

/// The identity of a frame's inputs from each one's SHA-256 (`each`, the first volume's
/// first): the first input's own for a scene of one volume, else the hex SHA-256 of all of
/// them, one per line, in order, so that a change to any input changes it.
#[must_use]
pub fn inputs_sha256(each: &[String]) -> String {
    match each {
        [one] => one.clone(),
        all => hex(&Sha256::digest(all.join("\n").as_bytes())),
    }
}

/// Hash (32 hex digits) of the plume version, the seed and every value of the shot that
/// can change pixels.
///
/// Fail-safe by construction: each part of the shot is taken apart field by field with
/// exhaustive patterns (no `..`), one function per part, so a field added to the
/// description does not compile until it is either hashed there or listed as one that
/// cannot change pixels (paths, threads, sample budget and range, crop, progress,
/// logging, limits). A field hashed with another part's line is listed as `_` with a
/// comment naming where it is hashed.
#[must_use]
pub fn settings_hash(shot: &Shot, seed: u64) -> String {
    let Shot { scene, settings } = shot;
    let SceneDescription {
        volume,
        emission,
        medium,
        more_volumes,
        // A list of one volume renders as the same volume given alone
        listed: _,
        camera,
        lights,
        integrator,
    } = scene;
    let (sampler, output) = job_text(settings);
    // The split count is always hashed: its default (8) changed every scattering render's
    // pixels, so parts rendered before it existed must not merge with parts rendered after.
    // So is the camera collision, whose default (forced, with a ray-marched camera segment)
    // did the same
    let text = format!(
        "plume {}\nseed {seed}\nsampler {sampler}\nfixed point {}\n{}\n{}\n{}\n{}\nlights {}\n{}{output}{}{}",
        env!("CARGO_PKG_VERSION"),
        plume_engine::film::FIXED_POINT_BITS,
        volume_text(volume),
        emission_text(emission),
        medium_text(medium),
        camera_text(camera),
        lights_text(lights),
        integrator_text(integrator, &volume.interpolation),
        motion_text(volume, camera),
        more_volumes_text(more_volumes),
    );
    hex(&Sha256::digest(text.as_bytes())[..16])
}

/// The volume's line: its grids and interpolation (not the file, whose path differs
/// between farm nodes: the input is identified by its SHA-256).
fn volume_text(volume: &VolumeInput) -> String {
    let VolumeInput {
        file: _,
        density_grid,
        temperature_grid,
        emission_grid,
        albedo_grid,
        interpolation,
        // In `motion_text`
        velocity_grid: _,
        velocity_scale: _,
        translate,
        rotate,
        scale,
        matrix,
        space,
        name,
        group,
        visible_to_camera,
        casts_shadows,
        instances,
    } = volume;
    let mut line = format!(
        "volume {density_grid:?} {temperature_grid:?} {emission_grid:?} {albedo_grid:?} {interpolation}"
    );
    // Without a placement the line is what it was before placements existed
    if translate.is_some() || rotate.is_some() || scale.is_some() || matrix.is_some() {
        line += &format!(" placed {translate:?} {rotate:?} {scale:?} {matrix:?} {space}");
    }
    // Likewise a volume without a name that the camera sees and that casts shadows
    if name.is_some() || !visible_to_camera || !casts_shadows {
        line += &format!(" object {name:?} {visible_to_camera} {casts_shadows}");
    }
    // Likewise a volume without a light group
    if let Some(group) = group {
        line += &format!(" group {group:?}");
    }
    // Likewise a volume without instances
    if let Some(instances) = instances {
        line += &format!(" instances {instances:?}");
    }
    line
}

/// The further volumes' lines, one each: grids, placement, emission, medium and motion (not
/// the files, which are identified by their SHA-256); nothing for a scene of one volume.
fn more_volumes_text(more_volumes: &[VolumeEntry]) -> String {
    let mut text = String::new();
    for (i, entry) in more_volumes.iter().enumerate() {
        let VolumeEntry { volume, emission, medium } = entry;
        let motion = format!("{:?} {:?}", volume.velocity_grid, volume.velocity_scale);
        text += &format!(
            "\nvolumes[{}] {} {} {} motion {motion}",
            i + 1,
            volume_text(volume),
            emission_text(emission),
            medium_text(medium)
        );
    }
    text
}

/// The emission's line.
fn emission_text(emission: &EmissionSettings) -> String {
    let EmissionSettings { source, convention, temperature_map, temperature_cutoff, scale, color } =
        emission;
    format!(
        "emission {source} {convention} {temperature_map:?} {temperature_cutoff:?} {scale:?} {color:?}"
    )
}

/// The medium's line.
fn medium_text(medium: &MediumSettings) -> String {
    let MediumSettings { density_scale, albedo, absorption_color, g } = medium;
    // A grey albedo hashes as the number it was before colours existed
    let colour = |c: &Option<plume_scene::Albedo>| match c {
        None => "None".to_string(),
        Some(plume_scene::Albedo::Grey(a)) => format!("Some({a:?})"),
        Some(plume_scene::Albedo::Color(c)) => format!("Some({c:?})"),
    };
    let albedo = colour(albedo);
    // Without an absorption colour the line is what it was before it existed
    match absorption_color {
        None => format!("medium {density_scale:?} {albedo} {g:?}"),
        a => format!("medium {density_scale:?} {albedo} {g:?} absorption {}", colour(a)),
    }
}

/// The camera's line (its motion keys are in [`motion_text`]).
fn camera_text(camera: &CameraSettings) -> String {
    let CameraSettings {
        from,
        at,
        up,
        fov,
        width,
        height,
        up_axis,
        focal_length,
        sensor_width,
        fstop,
        aperture_radius,
        focus_distance,
        projection,
        ortho_width,
        // In `motion_text`
        shutter: _,
        fps: _,
        keys: _,
    } = camera;
    let line = format!("camera {from:?} {at:?} {up:?} {fov:?} {width} {height} {up_axis}");
    // A pinhole camera given by its field of view hashes as before these keys existed
    let optics = [focal_length, sensor_width, fstop, aperture_radius, focus_distance, ortho_width];
    if optics.iter().all(|v| v.is_none()) && *projection == plume_scene::Projection::Perspective {
        line
    } else {
        format!("{line} {projection} {optics:?}")
    }
}

/// Motion blur's keys, only when there is motion: still scenes hash as without them.
fn motion_text(volume: &VolumeInput, camera: &CameraSettings) -> String {
    let (velocity_grid, velocity_scale) = (&volume.velocity_grid, &volume.velocity_scale);
    let (shutter, fps, keys) = (&camera.shutter, &camera.fps, &camera.keys);
    if velocity_grid.is_some() || !keys.is_empty() {
        format!("\nmotion {velocity_grid:?} {velocity_scale:?} {shutter:?} {fps:?} {keys:?}")
    } else {
        String::new()
    }
}

/// The lights' line, after `lights `.
fn lights_text(lights: &LightSettings) -> String {
    let LightSettings { environment, environment_map, sky, distant, sphere } = lights;
    // The map's file by name only (paths differ between farm nodes); scenes without an
    // environment map, sky, distant or sphere light keep the hash they had without these
    // keys
    let map = environment_map.as_ref().map(|m| {
        let EnvironmentMapSettings { file, intensity, rotation, visible, group } = m;
        format!("{:?} {intensity:?} {rotation:?} {visible} {group:?}", file.file_name())
    });
    if map.is_none() && sky.is_none() && distant.is_empty() && sphere.is_empty() {
        format!("{environment:?}")
    } else {
        format!("{environment:?} {map:?} {sky:?} {distant:?} {sphere:?}")
    }
}

/// The integrator's line, with the volume's `interpolation` (which decides whether point
/// lookups change pixels).
fn integrator_text(
    integrator: &IntegratorSettings,
    interpolation: &plume_volume::Interpolation,
) -> String {
    let IntegratorSettings {
        method,
        estimator,
        camera_estimator,
        camera_collision,
        light_sampling,
        mis,
        proxy_resolution,
        max_depth,
        kappa,
        tracking,
        nee_table,
        split,
        split_by,
        point_lookup,
    } = integrator;
    // Splitting by brightness changes every scattering pixel's count; uniform (the
    // default) adds nothing, so hashes made without the key stay valid
    let split_by = if split_by.is_uniform() { String::new() } else { format!(" by {split_by}") };
    // A brick table draws other voxels than a voxel table from the same numbers; the
    // default adds nothing, so hashes made without the key stay valid
    let nee_table =
        if nee_table.is_voxel() { String::new() } else { format!(" nee-table {nee_table}") };
    // Picked point lookups draw other numbers than exact ones on a trilinear volume:
    // hashed there, so parts of different kinds do not merge; elsewhere (nearest, or exact
    // lookups) they add nothing, so hashes made without the key stay valid (the same
    // pixels)
    let point_lookup = match (point_lookup, interpolation) {
        (_, plume_volume::Interpolation::Nearest)
        | (plume_engine::integrator::PointLookup::Exact, _) => "",
        (plume_engine::integrator::PointLookup::Stochastic, _) => " point-lookup stochastic",
        (plume_engine::integrator::PointLookup::StochasticEmission, _) => {
            " point-lookup stochastic emission"
        }
    };
    // Likewise the camera segment's own estimator
    let camera_estimator = camera_estimator.map_or(String::new(), |e| format!(" camera {e}"));
    format!(
        "integrator {method} {estimator:?} {light_sampling:?} {mis} {proxy_resolution:?} {max_depth} {kappa:?} {tracking}{nee_table}{point_lookup}{camera_estimator} split {split}{split_by} camera-collision {camera_collision}"
    )
}

/// Of the job's settings only the seed (an argument of [`settings_hash`]) and the sampler
/// change pixels; AOV layers and half sums change what the file holds, so parts and
/// resumes must agree on them: `(sampler, the lines of the AOVs and denoising)`.
fn job_text(settings: &JobSettings) -> (String, String) {
    let JobSettings { render, farm, output, reading } = settings;
    let RenderOptions {
        spp: _,
        time: _,
        noise_threshold,
        min_spp: _,
        noise_floor: _,
        seed: _,
        sampler,
        threads: _,
        sample_order: _,
        defer_paths: _,
        memory_budget: _,
        cache_dir: _,
        user_cache_dir: _,
        cache_lock_timeout: _,
        debug_pixel: _,
        quiet: _,
        progress: _,
    } = render;
    let FarmOptions { frames: _, overwrite: _, time_limit: _, crop: _, tile: _, sample_range: _ } =
        farm;
    let OutputSettings { image: _, preview: _, exposure: _, stats: _, sums: _, aovs, denoise } =
        output;
    let ReadSettings { max_input_memory: _, read_timeout: _, no_isolation: _ } = reading;
    let aovs = if *aovs { "\naovs" } else { "" };
    let denoise =
        if *denoise { format!("\ndenoise {}", half_block(settings)) } else { String::new() };
    // Adaptive sampling decides which samples each pixel takes; without it nothing is added
    let adaptive = match (noise_threshold, adaptive_settings(settings)) {
        (Some(_), Some(a)) => format!("\nadaptive {:?} {} {:?}", a.threshold, a.min_spp, a.floor),
        _ => String::new(),
    };
    (sampler.to_string(), format!("{aovs}{denoise}{adaptive}"))
}

/// Adaptive sampling's settings as the render takes them (`render.noise_threshold`, with
/// `min_spp` and `noise_floor` or their defaults), or `None` without a threshold.
#[must_use]
pub fn adaptive_settings(settings: &JobSettings) -> Option<plume_engine::noise::Adaptive> {
    let render = &settings.render;
    let threshold = render.noise_threshold?;
    Some(plume_engine::noise::Adaptive {
        threshold,
        min_spp: u64::from(render.min_spp_or_default(planned_spp(settings))).max(2),
        floor: render.noise_floor.unwrap_or(plume_engine::noise::DEFAULT_FLOOR),
    })
}

/// The half block of a frame rendered with `--denoise` ([`plume_engine::denoise::half_block`] of
/// its [`planned_spp`]). Hashed, so parts and resumes agree on the halves.
#[must_use]
pub fn half_block(settings: &JobSettings) -> u64 {
    plume_engine::denoise::half_block(planned_spp(settings))
}

/// The spp a frame plans: `render.spp` or its default (`RenderOptions::default_spp`), or
/// none with a time budget or sample ranges (which exclude `render.spp`).
fn planned_spp(settings: &JobSettings) -> Option<u32> {
    let (farm, render) = (&settings.farm, &settings.render);
    match (&farm.sample_range, render.spp, render.time) {
        (Some(_), spp, _) => spp,
        (None, _, Some(_)) => None,
        (None, spp, None) => Some(spp.unwrap_or_else(|| render.default_spp())),
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use plume_scene::TileIndex;

    #[test]
    fn settings_hash_ignores_what_does_not_change_pixels() {
        let shot = Shot::new("in.vdb", "out.exr");
        let base = settings_hash(&shot, 1);
        assert_eq!(base.len(), 32);
        let mut same = Shot::new("other.vdb", "other.exr");
        same.settings.render.threads = 3;
        same.settings.render.spp = Some(9);
        same.settings.render.quiet = true;
        same.settings.farm.tile = Some(TileIndex { index: 1, count: 4 });
        same.settings.farm.sample_range = Some(0..4);
        same.settings.output.stats = Some("s.json".into());
        same.settings.render.progress = plume_scene::ProgressFormat::Openjd;
        assert_eq!(settings_hash(&same, 1), base);
        let mut denser = shot.clone();
        denser.scene.medium.density_scale = 2.0;
        assert_ne!(settings_hash(&denser, 1), base);
        let mut narrower = shot.clone();
        narrower.scene.camera.width = 20;
        assert_ne!(settings_hash(&narrower, 1), base);
        let mut tinted = shot.clone();
        tinted.scene.emission.color = [1.0, 0.5, 0.5];
        assert_ne!(settings_hash(&tinted, 1), base);
        assert_ne!(settings_hash(&shot, 2), base);
        let mut random = shot.clone();
        random.settings.render.sampler = plume_scene::SamplerKind::Random;
        assert_ne!(settings_hash(&random, 1), base);
    }

    #[test]
    fn further_volumes_are_hashed_and_a_list_of_one_is_one_volume() {
        let shot = Shot::new("in.vdb", "out.exr");
        let base = settings_hash(&shot, 1);
        let mut listed = shot.clone();
        listed.scene.listed = true;
        assert_eq!(settings_hash(&listed, 1), base);
        let mut two = shot.clone();
        two.scene.more_volumes.push(VolumeEntry::new("b.vdb"));
        let with_two = settings_hash(&two, 1);
        assert_ne!(with_two, base);
        // Not the file (identified by its SHA-256), but what it is made into
        two.scene.more_volumes[0].volume.file = "elsewhere/c.vdb".into();
        assert_eq!(settings_hash(&two, 1), with_two);
        two.scene.more_volumes[0].medium.g = 0.5;
        assert_ne!(settings_hash(&two, 1), with_two);
        let mut named = shot.clone();
        named.scene.volume.name = Some("fire".into());
        assert_ne!(settings_hash(&named, 1), base);
    }

    #[test]
    fn one_input_is_identified_by_its_own_sha256_several_by_all_of_theirs() {
        let (a, b) = ("a".repeat(64), "b".repeat(64));
        assert_eq!(inputs_sha256(std::slice::from_ref(&a)), a);
        let both = inputs_sha256(&[a.clone(), b.clone()]);
        assert_eq!(both.len(), 64);
        assert_ne!(both, inputs_sha256(&[b, a]));
    }
}
