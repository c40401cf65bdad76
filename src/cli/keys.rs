//! The one table of `plume render` flag → scene key ([`render_flags`]), how each flag
//! sets its key, and the way back: the flag a user typed for a key that a library error
//! names (`lights.sky.turbidity` → `--sky turbidity`).

use std::ops::Range;

use super::render::{GridArgs, RenderArgs};
use plume_scene::Shot;

/// Flag id (clap's, the field name) → scene key, and how the flag sets the key. The
/// positional FILE sets `volume.file` (unless it is a scene file); `-o` sets
/// `output.image`.
macro_rules! flags_to_keys {
    ($table:ident, $apply:ident, $args:ty, $s:ident, $a:ident; $($id:literal => $key:literal: $target:expr => $value:expr;)*) => {
        /// Flag ids and the keys they set.
        pub const $table: &[(&str, &str)] = &[$(($id, $key)),*];

        /// Set the key of every flag that `given` says counts.
        pub fn $apply($s: &mut Shot, $a: &$args, given: &dyn Fn(&str) -> bool) {
            $(if given($id) {
                $target = $value;
            })*
        }
    };
}

flags_to_keys! { RENDER_ONLY_FLAGS, apply_render_only, RenderArgs, s, a;
    "output" => "output.image": s.settings.output.image => a.output.clone().unwrap_or_default();
    "spp" => "render.spp": s.settings.render.spp => a.spp;
    "time" => "render.time": s.settings.render.time => a.time;
    "noise_threshold" => "render.noise_threshold": s.settings.render.noise_threshold => a.noise_threshold;
    "min_spp" => "render.min_spp": s.settings.render.min_spp => a.min_spp;
    "noise_floor" => "render.noise_floor": s.settings.render.noise_floor => a.noise_floor;
    "seed" => "render.seed": s.settings.render.seed => a.seed;
    "threads" => "render.threads": s.settings.render.threads => a.threads;
    "width" => "camera.width": s.scene.camera.width => a.width;
    "height" => "camera.height": s.scene.camera.height => a.height;
    "camera_from" => "camera.from": s.scene.camera.from => a.camera_from;
    "camera_at" => "camera.at": s.scene.camera.at => a.camera_at;
    "camera_up" => "camera.up": s.scene.camera.up => a.camera_up;
    "fov" => "camera.fov": s.scene.camera.fov => a.fov;
    "focal_length" => "camera.focal_length": s.scene.camera.focal_length => a.focal_length;
    "sensor_width" => "camera.sensor_width": s.scene.camera.sensor_width => a.sensor_width;
    "fstop" => "camera.fstop": s.scene.camera.fstop => a.fstop;
    "aperture_radius" => "camera.aperture_radius": s.scene.camera.aperture_radius => a.aperture_radius;
    "focus_distance" => "camera.focus_distance": s.scene.camera.focus_distance => a.focus_distance;
    "projection" => "camera.projection": s.scene.camera.projection => a.projection;
    "ortho_width" => "camera.ortho_width": s.scene.camera.ortho_width => a.ortho_width;
    "up_axis" => "camera.up_axis": s.scene.camera.up_axis => a.up_axis;
    "method" => "integrator.method": s.scene.integrator.method => a.method;
    "estimator" => "integrator.estimator": s.scene.integrator.estimator => a.estimator;
    "camera_estimator" => "integrator.camera_estimator": s.scene.integrator.camera_estimator => a.camera_estimator;
    "camera_collision" => "integrator.camera_collision": s.scene.integrator.camera_collision => a.camera_collision;
    "light_sampling" => "integrator.light_sampling": s.scene.integrator.light_sampling => a.light_sampling;
    "mis" => "integrator.mis": s.scene.integrator.mis => a.mis;
    "tracking" => "integrator.tracking": s.scene.integrator.tracking => a.tracking;
    "nee_table" => "integrator.nee_table": s.scene.integrator.nee_table => a.nee_table;
    "point_lookup" => "integrator.point_lookup": s.scene.integrator.point_lookup => a.point_lookup;
    "proxy_resolution" => "integrator.proxy_resolution": s.scene.integrator.proxy_resolution => a.proxy_resolution;
    "albedo" => "medium.albedo": s.scene.medium.albedo => a.albedo;
    "absorption_color" => "medium.absorption_color": s.scene.medium.absorption_color => a.absorption_color;
    "g" => "medium.g": s.scene.medium.g => a.g;
    "max_depth" => "integrator.max_depth": s.scene.integrator.max_depth => a.max_depth;
    "split" => "integrator.split": s.scene.integrator.split => a.split;
    "split_by" => "integrator.split_by": s.scene.integrator.split_by => a.split_by;
    "environment" => "lights.environment": s.scene.lights.environment => a.environment;
    "environment_map" => "lights.environment_map": s.scene.lights.environment_map => a.environment_map.clone();
    "sky" => "lights.sky": s.scene.lights.sky => a.sky.clone();
    "distant_light" => "lights.distant": s.scene.lights.distant => a.distant_light.clone();
    "sphere_light" => "lights.sphere": s.scene.lights.sphere => a.sphere_light.clone();
    "debug_pixel" => "render.debug_pixel": s.settings.render.debug_pixel => a.debug_pixel;
    "velocity_grid" => "volume.velocity_grid": s.scene.volume.velocity_grid => a.velocity_grid.clone();
    "velocity_scale" => "volume.velocity_scale": s.scene.volume.velocity_scale => a.velocity_scale;
    "volume_translate" => "volume.translate": s.scene.volume.translate => a.volume_translate.map(|v| v.to_array());
    "volume_rotate" => "volume.rotate": s.scene.volume.rotate => a.volume_rotate.map(|v| v.to_array());
    "volume_scale" => "volume.scale": s.scene.volume.scale => a.volume_scale;
    "volume_matrix" => "volume.matrix": s.scene.volume.matrix => a.volume_matrix;
    "volume_space" => "volume.space": s.scene.volume.space => a.volume_space;
    "volume_name" => "volume.name": s.scene.volume.name => a.volume_name.clone();
    "volume_group" => "volume.group": s.scene.volume.group => a.volume_group.clone();
    "volume_visible_to_camera" => "volume.visible_to_camera": s.scene.volume.visible_to_camera => a.volume_visible_to_camera;
    "volume_casts_shadows" => "volume.casts_shadows": s.scene.volume.casts_shadows => a.volume_casts_shadows;
    "shutter" => "camera.shutter": s.scene.camera.shutter => a.shutter;
    "fps" => "camera.fps": s.scene.camera.fps => a.fps;
    "kappa" => "integrator.kappa": s.scene.integrator.kappa => a.kappa;
    "density_scale" => "medium.density_scale": s.scene.medium.density_scale => a.density_scale;
    "emission_scale" => "emission.scale": s.scene.emission.scale => a.emission_scale;
    "emission_color" => "emission.color": s.scene.emission.color => a.emission_color.as_vec3().to_array();
    "preview" => "output.preview": s.settings.output.preview => a.preview.clone();
    "exposure" => "output.exposure": s.settings.output.exposure => a.exposure;
    "stats" => "output.stats": s.settings.output.stats => a.stats.clone();
    "memory_budget" => "render.memory_budget": s.settings.render.memory_budget => a.memory_budget;
    "cache_dir" => "render.cache_dir": s.settings.render.cache_dir => a.cache_dir.clone();
    "cache_lock_timeout" => "render.cache_lock_timeout": s.settings.render.cache_lock_timeout => a.cache_lock_timeout;
    "sample_order" => "render.sample_order": s.settings.render.sample_order => a.sample_order;
    "defer_paths" => "render.defer_paths": s.settings.render.defer_paths => a.defer_paths;
    "quiet" => "render.quiet": s.settings.render.quiet => a.quiet;
    "frames" => "farm.frames": s.settings.farm.frames => a.frames.clone();
    "overwrite" => "farm.overwrite": s.settings.farm.overwrite => a.overwrite;
    "time_limit" => "farm.time_limit": s.settings.farm.time_limit => a.time_limit;
    "crop" => "farm.crop": s.settings.farm.crop => a.crop;
    "tile" => "farm.tile": s.settings.farm.tile => a.tile;
    "sample_range" => "farm.sample_range": s.settings.farm.sample_range => a.sample_range.clone();
    "sums" => "output.sums": s.settings.output.sums => a.sums;
    "aovs" => "output.aovs": s.settings.output.aovs => a.aovs;
    "denoise" => "output.denoise": s.settings.output.denoise => a.denoise;
    "interpolation" => "volume.interpolation": s.scene.volume.interpolation => a.interpolation;
    "progress" => "render.progress": s.settings.render.progress => a.progress;
}

flags_to_keys! { GRID_FLAGS, apply_grids, GridArgs, s, a;
    "density_grid" => "volume.density_grid": s.scene.volume.density_grid => a.density_grid.clone();
    "emission" => "emission.source": s.scene.emission.source => a.emission;
    "temperature_grid" => "volume.temperature_grid": s.scene.volume.temperature_grid => a.temperature_grid.clone();
    "temperature_map" => "emission.temperature_map": s.scene.emission.temperature_map => a.temperature_map.clone();
    "temperature_cutoff" => "emission.temperature_cutoff": s.scene.emission.temperature_cutoff => a.temperature_cutoff;
    "emission_grid" => "volume.emission_grid": s.scene.volume.emission_grid => a.emission_grid.clone();
    "convention" => "emission.convention": s.scene.emission.convention => a.convention;
    "albedo_grid" => "volume.albedo_grid": s.scene.volume.albedo_grid => a.albedo_grid.clone();
    "max_input_memory" => "reading.max_input_memory": s.settings.reading.max_input_memory => a.max_input_memory;
    "read_timeout" => "reading.read_timeout": s.settings.reading.read_timeout => a.read_timeout;
    "no_isolation" => "reading.no_isolation": s.settings.reading.no_isolation => a.no_isolation;
}

/// `--add-volume` appends to the list of volumes (`volumes`) instead of setting a key; it is
/// applied after every other flag, so that its entries take the first volume's emission
/// and medium as the flags left them.
pub const LIST_FLAGS: &[(&str, &str)] = &[("add_volume", "volumes")];

/// Every render flag's id and key.
pub fn render_flags() -> impl Iterator<Item = &'static (&'static str, &'static str)> {
    RENDER_ONLY_FLAGS.iter().chain(GRID_FLAGS).chain(LIST_FLAGS)
}

/// Set the key of every render flag that `given` says counts, and append the volumes of
/// `--add-volume`.
pub(super) fn apply(shot: &mut Shot, args: &RenderArgs, given: &dyn Fn(&str) -> bool) {
    apply_render_only(shot, args, given);
    apply_grids(shot, &args.grids, given);
    if given("add_volume") {
        let scene = &mut shot.scene;
        let added: Vec<_> =
            args.add_volume.iter().map(|k| k.resolve(&scene.emission, &scene.medium)).collect();
        scene.more_volumes.extend(added);
    }
}

/// `--flag-name` of a flag id (`FILE` for the positional).
pub(super) fn flag_name(id: &str) -> String {
    if id == "file" {
        "FILE".into()
    } else {
        format!("--{}", id.replace('_', "-"))
    }
}

/// The flag that set `key` and how a user reads it (`--albedo`, `--sky turbidity`), where
/// the volumes of indices `added` came from `--add-volume`: a key of one of them is inside
/// that flag (`volumes[1].medium.g` → `--add-volume medium.g`, `--add-volume #2 …` when
/// there are several), and a key of the first volume in a list is the first volume's
/// (`volumes[0].medium.g` → `--g`).
pub(super) fn flag_for_key(key: &str, added: &Range<usize>) -> Option<(&'static str, String)> {
    if let Some((index, rest)) = volume_entry_key(key) {
        if added.contains(&index) {
            let which = if added.len() > 1 {
                format!(" #{}", index - added.start + 1)
            } else {
                String::new()
            };
            let rest = if rest.is_empty() { String::new() } else { format!(" {rest}") };
            return Some(("add_volume", format!("--add-volume{which}{rest}")));
        }
        if index > 0 || rest.is_empty() {
            return None;
        }
        return flag_for_key(&plume_scene::volumes::key("volume", rest), &(0..0));
    }
    let (id, rest) = flag_and_rest(key)?;
    let name = if rest.is_empty() { flag_name(id) } else { format!("{} {rest}", flag_name(id)) };
    Some((id, name))
}

/// `volumes[INDEX].REST` as `(INDEX, REST)`.
fn volume_entry_key(key: &str) -> Option<(usize, &str)> {
    let (index, rest) = key.strip_prefix("volumes[")?.split_once(']')?;
    Some((index.parse().ok()?, rest.strip_prefix('.').unwrap_or(rest)))
}

/// The flag that sets `key`, and the rest of the key inside the flag's table
/// (`lights.sky.turbidity` → `("sky", "turbidity")`; empty for the flag's own key).
pub(super) fn flag_and_rest(key: &str) -> Option<(&'static str, &str)> {
    if key == "volume.file" {
        return Some(("file", ""));
    }
    let mut k = key;
    loop {
        if let Some((id, _)) = render_flags().find(|(_, f)| *f == k) {
            return Some((id, key[k.len()..].trim_start_matches('.')));
        }
        k = k.rsplit_once('.')?.0;
    }
}
