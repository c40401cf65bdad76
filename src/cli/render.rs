//! `plume render`: its flags. Each sets a key of a [`plume_scene::Shot`] (`keys.rs`, the
//! one table of flag → key); `request.rs` is the one conversion of flags (and a scene
//! file) into a validated shot.

use std::path::PathBuf;

use clap::Args;
use glam::DVec3;
use plume_engine::film::Crop;
use plume_engine::integrator::{LightSampling, MisHeuristic};
use plume_engine::medium::Convention;
use plume_scene::{
    Albedo, ByteSize, CameraCollision, CameraSettings, DeferPaths, DistantSettings,
    EmissionSettings, EmissionSource, EnvironmentMapSettings, EstimatorKind, IntegratorSettings,
    Interpolation, MediumSettings, Method, NeeTable, PointLookup, ProgressFormat, Projection,
    ReadSettings, RenderOptions, SampleOrderChoice, SkySettings, SphereSettings, SplitBy,
    TileIndex, TrackingChoice, UpAxis, VolumeEntryKeys, VolumeInput,
};

use super::flags::{
    choice, parse_environment_map, parse_keys, parse_matrix, parse_pair, parse_size, parse_vec3,
    parse_volume_keys,
};

/// `plume render`.
#[derive(Clone, Debug, Args)]
// Negative numbers reach our validation, which names the flag and the allowed range.
#[command(allow_negative_numbers = true)]
pub struct RenderArgs {
    /// The .vdb file or .plume brick cache (`plume prepare`), or with --frames a
    /// pattern with a frame token: `fire.####.vdb`
    /// (one `#` per digit), `fire.%04d.vdb` or `fire.$F4.vdb`. Numbers wider than the
    /// padding are printed in full. Or a scene file (`shot.toml`, docs/scene-file.md):
    /// flags given beside it override its keys.
    pub file: PathBuf,
    /// Output EXR (32-bit float RGBA; alpha = 1 − transmittance); with --frames a
    /// pattern like FILE's. Required unless a scene file gives `[output] image`. Written atomically; an output that is already complete is
    /// skipped unless --overwrite, and one left by an interrupted render is continued.
    #[arg(short, long, help_heading = "Output")]
    pub output: Option<PathBuf>,
    /// Samples per pixel.
    #[arg(long, conflicts_with = "time", help_heading = "Sampling")]
    pub spp: Option<u32>,
    /// Render whole 1-spp passes until this many seconds are spent.
    #[arg(long, help_heading = "Sampling")]
    pub time: Option<f64>,
    /// Adaptive sampling: each pixel stops once its estimated relative standard error is at
    /// most this (e.g. 0.02), relative to its value or, where darker, to --noise-floor.
    /// --spp (default 1024 here) or --time caps it.
    #[arg(long, help_heading = "Sampling")]
    pub noise_threshold: Option<f64>,
    /// With --noise-threshold: samples every pixel takes before it may stop (default 16).
    #[arg(long, help_heading = "Sampling")]
    pub min_spp: Option<u32>,
    /// With --noise-threshold: the radiance below which a pixel's error is taken relative
    /// to it instead of the pixel's value (default 0.1).
    #[arg(long, help_heading = "Sampling", hide_short_help = true)]
    pub noise_floor: Option<f64>,
    /// Seed of the sample streams (default: the frame number with --frames, else 0).
    #[arg(long, help_heading = "Sampling")]
    pub seed: Option<u64>,
    /// Worker threads (0 = all cores; when rendering tile by tile from a brick cache, where
    /// workers wait for the disk, one more, or three per core when paths scatter). The
    /// image does not depend on it.
    #[arg(long, default_value_t = RenderOptions::default().threads, help_heading = "Sampling", hide_short_help = true)]
    pub threads: usize,
    /// Image width in pixels.
    #[arg(long, default_value_t = CameraSettings::default().width, help_heading = "Camera")]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = CameraSettings::default().height, help_heading = "Camera")]
    pub height: u32,
    /// Camera position x,y,z (world). Without it the volume is framed automatically.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, help_heading = "Camera")]
    pub camera_from: Option<DVec3>,
    /// Point looked at x,y,z (default: the volume's centre).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, help_heading = "Camera")]
    pub camera_at: Option<DVec3>,
    /// Up vector x,y,z (default: from --up-axis).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, help_heading = "Camera", hide_short_help = true)]
    pub camera_up: Option<DVec3>,
    /// Horizontal field of view in degrees.
    #[arg(long, default_value_t = CameraSettings::default().fov, help_heading = "Camera")]
    pub fov: f64,
    /// Focal length in mm: with --sensor-width sets the field of view, in place of --fov.
    #[arg(long, help_heading = "Camera")]
    pub focal_length: Option<f64>,
    /// Sensor width in mm, with --focal-length [default: 36].
    #[arg(long, help_heading = "Camera", hide_short_help = true)]
    pub sensor_width: Option<f64>,
    /// Depth of field: the f-number, with --focal-length (the millimetres taken as
    /// thousandths of a world unit).
    #[arg(long, help_heading = "Camera")]
    pub fstop: Option<f64>,
    /// Depth of field: the aperture radius in world units, in place of --fstop.
    #[arg(long, help_heading = "Camera", hide_short_help = true)]
    pub aperture_radius: Option<f64>,
    /// Distance in focus along the view direction, world units [default: to --camera-at].
    #[arg(long, help_heading = "Camera")]
    pub focus_distance: Option<f64>,
    /// Perspective, or orthographic (parallel rays, --ortho-width wide).
    #[arg(long, value_parser = choice::<Projection>(), default_value_t = Projection::Perspective, help_heading = "Camera", hide_short_help = true)]
    pub projection: Projection,
    /// Orthographic: the image's width in world units [default: frames the volume].
    #[arg(long, help_heading = "Camera", hide_short_help = true)]
    pub ortho_width: Option<f64>,
    /// Up axis for automatic framing and the default --camera-up.
    #[arg(long, value_parser = choice::<UpAxis>(), default_value_t = CameraSettings::default().up_axis, help_heading = "Camera")]
    pub up_axis: UpAxis,
    /// The paper's methods as presets: estimator + light sampling. `--estimator` and
    /// `--light-sampling` override the preset's parts.
    #[arg(long, value_parser = choice::<Method>(), default_value_t = IntegratorSettings::default().method, help_heading = "Method")]
    pub method: Method,
    /// How voxel values are reconstructed between voxel centres.
    #[arg(long, value_parser = choice::<Interpolation>(), default_value_t = VolumeInput::new("").interpolation, help_heading = "Volume and grids")]
    pub interpolation: Interpolation,
    /// Emission estimator (default: from --method).
    #[arg(long, value_parser = choice::<EstimatorKind>(), help_heading = "Method", hide_short_help = true)]
    pub estimator: Option<EstimatorKind>,
    /// The camera segment's estimator (default: ray-march where paths scatter, else
    /// --estimator); ray-march makes its emission exact, and --denoise then leaves it
    /// unfiltered.
    #[arg(long, value_parser = choice::<EstimatorKind>(), help_heading = "Method", hide_short_help = true)]
    pub camera_estimator: Option<EstimatorKind>,
    /// How a camera ray's collision is drawn when paths scatter: forced (every ray that
    /// meets the medium may scatter, weighted by its collision probability; where the
    /// camera segment is ray-marched by regular tracking, analog elsewhere) or analog.
    #[arg(long, value_parser = choice::<CameraCollision>(), default_value_t = IntegratorSettings::default().camera_collision, help_heading = "Method", hide_short_help = true)]
    pub camera_collision: CameraCollision,
    /// Next event technique at scattering vertices (default: from --method).
    #[arg(long, value_parser = choice::<LightSampling>(), help_heading = "Method", hide_short_help = true)]
    pub light_sampling: Option<LightSampling>,
    /// MIS heuristic between forward sampling and NEE/FNEE.
    #[arg(long, value_parser = choice::<MisHeuristic>(), default_value_t = IntegratorSettings::default().mis, help_heading = "Method", hide_short_help = true)]
    pub mis: MisHeuristic,
    /// How segments are tracked: exactly cell by cell (regular), or by null collisions
    /// under brick majorants (METHOD.md §13), which look the volume up only at tentative
    /// points. `mixed` tracks camera rays exactly and every segment after a scattering
    /// event by null collisions.
    #[arg(long, value_parser = choice::<TrackingChoice>(), default_value_t = IntegratorSettings::default().tracking, help_heading = "Method", hide_short_help = true)]
    pub tracking: TrackingChoice,
    /// Classic NEE's table: one entry per emitting voxel (16 bytes each), or one per
    /// emitting brick with the voxel drawn from the brick's values (32 bytes per brick),
    /// for volumes whose voxel table does not fit the memory budget. Same law either way.
    #[arg(long, value_parser = choice::<NeeTable>(), default_value_t = IntegratorSettings::default().nee_table, help_heading = "Method", hide_short_help = true)]
    pub nee_table: NeeTable,
    /// How null collisions (--tracking mixed or null) read a trilinear volume at their
    /// tentative points (and, with `stochastic-emission`, at their emission points after
    /// scattering): one voxel picked with its interpolation weight (unbiased: the
    /// free-path law is the interpolated field's exactly; one read instead of eight), or
    /// the interpolated value itself. Camera segments' emission points are always exact.
    /// Nothing changes with --interpolation nearest.
    #[arg(long, value_parser = choice::<PointLookup>(), default_value_t = IntegratorSettings::default().point_lookup, help_heading = "Method", hide_short_help = true)]
    pub point_lookup: PointLookup,
    /// FNEE proxy grid resolution (cells along the longest axis; a power of two, 8 up to
    /// the data resolution). Default 64, or the data resolution if that is smaller.
    #[arg(long, help_heading = "Method", hide_short_help = true)]
    pub proxy_resolution: Option<u32>,
    /// Single-scattering albedo in [0, 1] (0: emission–absorption only), grey or a
    /// scattering colour r,g,b. With --albedo-grid it multiplies the grid (default 1 then).
    #[arg(long, help_heading = "Medium")]
    pub albedo: Option<Albedo>,
    /// Cycles' Absorption Color in [0, 1], grey or r,g,b: channel c's extinction becomes
    /// density scale × (C + (1 − C)(1 − √A)) with C the albedo (then Cycles' Color), so
    /// a colour that differs per channel makes extinction chromatic. Default black (grey).
    #[arg(long, help_heading = "Medium")]
    pub absorption_color: Option<Albedo>,
    /// Henyey–Greenstein asymmetry g in (−1, 1).
    #[arg(long, default_value_t = MediumSettings::default().g, allow_hyphen_values = true, help_heading = "Medium")]
    pub g: f64,
    /// Largest number of scattering events per path.
    #[arg(long, default_value_t = IntegratorSettings::default().max_depth, help_heading = "Method", hide_short_help = true)]
    pub max_depth: u32,
    /// Paths traced from each collision of a camera ray, each carrying 1/N (splitting, 1 to
    /// 256). The camera ray's walk, most of a sample's cost in thin media, is shared by N
    /// scattered paths, which carry most of the noise; 1 traces one path, as the paper does.
    #[arg(long, default_value_t = IntegratorSettings::default().split, help_heading = "Method", hide_short_help = true)]
    pub split: u32,
    /// How many paths leave each camera collision: --split everywhere (uniform), or per
    /// pixel more where the scattered light is brighter and fewer where it is dim, --split
    /// on average over the smoke (brightness; from a low-resolution pilot render of the
    /// whole frame, a small fraction of the render's samples; unbiased either way; it
    /// changes the image from --split 2 on).
    #[arg(long, value_parser = choice::<SplitBy>(), default_value_t = IntegratorSettings::default().split_by, help_heading = "Method", hide_short_help = true)]
    pub split_by: SplitBy,
    /// Constant environment radiance r,g,b seen by escaping paths, W·m⁻²·sr⁻¹ per channel
    /// (default: none).
    #[arg(long, value_parser = parse_vec3, help_heading = "Lights", hide_short_help = true)]
    pub environment: Option<DVec3>,
    /// A lat-long environment map (EXR, Cycles' equirectangular, the up axis its zenith):
    /// a file, or keys `file = "plate.exr", intensity = 1, rotation = 0, visible = true`
    /// (rotation in degrees about the up axis; visible: seen by camera rays).
    #[arg(long, value_parser = parse_environment_map, help_heading = "Lights")]
    pub environment_map: Option<EnvironmentMapSettings>,
    /// The built-in sky (Preetham 1999) with its sun, keys `elevation = 30, azimuth = 0,
    /// turbidity = 3, intensity = 1, sun = true, visible = true` (degrees; azimuth from
    /// +x towards +y with +z up); `--sky ""` for all defaults.
    #[arg(long, value_parser = parse_keys::<SkySettings>, help_heading = "Lights")]
    pub sky: Option<SkySettings>,
    /// A distant light (a sun; repeatable): keys `direction = [x, y, z]` (the way the
    /// light travels), `irradiance = W/m²` (Cycles' Sun Strength; or `illuminance = lux`),
    /// `color = [r, g, b]` or `kelvin = K`, `angle = 0.53` (angular diameter, degrees).
    #[arg(long, value_parser = parse_keys::<DistantSettings>, help_heading = "Lights")]
    pub distant_light: Vec<DistantSettings>,
    /// A sphere light (repeatable; radius 0 is a point light): keys `position = [x, y, z]`,
    /// `radius = 0`, `power = W` (Cycles' Power; or `intensity = W/sr`), `color = [r, g, b]`
    /// or `kelvin = K`.
    #[arg(long, value_parser = parse_keys::<SphereSettings>, help_heading = "Lights")]
    pub sphere_light: Vec<SphereSettings>,
    /// Place the volume in the world: move it by x,y,z (world units), after its scale and
    /// rotation and after the file's own transform.
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, help_heading = "Placement", hide_short_help = true)]
    pub volume_translate: Option<DVec3>,
    /// Rotate the volume by XYZ Euler angles x,y,z in degrees (Blender's default mode:
    /// about the world x axis first, then y, then z).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true, help_heading = "Placement", hide_short_help = true)]
    pub volume_rotate: Option<DVec3>,
    /// Scale the volume: one factor or x,y,z (first of the three, as Blender's object matrix
    /// T·R·S).
    #[arg(long, allow_hyphen_values = true, help_heading = "Placement", hide_short_help = true)]
    pub volume_scale: Option<plume_scene::Scale>,
    /// Place the volume by a 4×4 affine matrix: sixteen numbers row by row, translation in
    /// the last column (in place of the three above).
    #[arg(long, value_parser = parse_matrix, allow_hyphen_values = true, help_heading = "Placement", hide_short_help = true)]
    pub volume_matrix: Option<[[f64; 4]; 4]>,
    /// What the volume's coefficients are per once placed: world units, or Cycles' Object
    /// space (Blender's default), where extinction and emission are divided by the
    /// placement's scale.
    #[arg(long, value_parser = choice::<plume_scene::VolumeSpace>(), default_value_t = VolumeInput::new("").space, help_heading = "Placement", hide_short_help = true)]
    pub volume_space: plume_scene::VolumeSpace,
    /// A name for the volume (letters, digits, `_` and `-`), kept with the scene; it does
    /// not change the render.
    #[arg(long, help_heading = "Placement", hide_short_help = true)]
    pub volume_name: Option<String>,
    /// The light group of the volume's emission: with --aovs its light, seen directly and
    /// scattered, is the EXR layer of that name instead of `emission` and `scattered`.
    #[arg(long, help_heading = "Placement", hide_short_help = true)]
    pub volume_group: Option<String>,
    /// Whether camera rays see the volume (true or false); when false, only the light it
    /// scatters or shadows is seen.
    #[arg(long, action = clap::ArgAction::Set, default_value_t = VolumeInput::new("").visible_to_camera, help_heading = "Placement", hide_short_help = true)]
    pub volume_visible_to_camera: bool,
    /// Whether the volume shadows the light that reaches scattering points (true or
    /// false).
    #[arg(long, action = clap::ArgAction::Set, default_value_t = VolumeInput::new("").casts_shadows, help_heading = "Placement", hide_short_help = true)]
    pub volume_casts_shadows: bool,
    /// Add another volume to the scene (repeatable), with the keys of a scene file's
    /// `[[volumes]]` entry: `file = "smoke.vdb", translate = [1, 0, 0], name = "smoke",
    /// medium = { density_scale = 2, g = 0.3 }`. Besides `file`: the grids, the placement,
    /// `instances = [{ translate = [2, 0, 0] }, …]` (the volume once per placement, its data
    /// shared), `interpolation`, `name`, `group`, `visible_to_camera`, `casts_shadows`, and
    /// `emission = {…}` and `medium = {…}` with the keys of a scene file's [emission] and
    /// [medium]. The emission and medium keys it leaves out take the first volume's values
    /// (from --density-scale, --albedo, --g, --emission-scale and the like, or a scene
    /// file's first volume). Beside a scene file, the volumes are added after the file's.
    #[arg(long, value_name = "KEYS", value_parser = parse_volume_keys, help_heading = "Placement", hide_short_help = true)]
    pub add_volume: Vec<VolumeEntryKeys>,
    /// Motion blur: the velocity grid (world units per second), a vector grid NAME or
    /// three float grids NAME.x, NAME.y, NAME.z. The volume is advected back along it (Eulerian blur:
    /// density at x and time t is the frame's at x − t·v(x); docs/methods.md).
    #[arg(long, help_heading = "Motion")]
    pub velocity_grid: Option<String>,
    /// Multiplies the velocity.
    #[arg(
        long,
        default_value_t = 1.0,
        allow_hyphen_values = true,
        help_heading = "Motion",
        hide_short_help = true
    )]
    pub velocity_scale: f64,
    /// Shutter open,close in frames relative to the frame (default -0.25,0.25 with
    /// --velocity-grid).
    #[arg(long, value_parser = parse_pair, allow_hyphen_values = true, help_heading = "Motion", hide_short_help = true)]
    pub shutter: Option<[f64; 2]>,
    /// Frames per second (converts the shutter to seconds).
    #[arg(long, default_value_t = 24.0, help_heading = "Motion", hide_short_help = true)]
    pub fps: f64,
    /// Render only sample S of pixel (X, Y) and print its path: X,Y,S.
    #[arg(long, help_heading = "Advanced", hide_short_help = true)]
    pub debug_pixel: Option<plume_engine::render::SampleId>,
    /// κ of the blend estimator: α = 1/(1 + κ μ Δ) per voxel.
    #[arg(long, default_value_t = IntegratorSettings::default().kappa, help_heading = "Method", hide_short_help = true)]
    pub kappa: f64,
    /// Which grids make the volume, how the source maps, and how files are read.
    #[command(flatten)]
    pub grids: GridArgs,
    /// σ_t: extinction per world unit per unit density.
    #[arg(long, default_value_t = MediumSettings::default().density_scale, help_heading = "Medium")]
    pub density_scale: f64,
    /// Emission scale s_e.
    #[arg(long, default_value_t = EmissionSettings::default().scale, help_heading = "Medium")]
    pub emission_scale: f32,
    /// Emission colour r,g,b (a tint for blackbody).
    #[arg(long, value_parser = parse_vec3, default_value = "1,1,1", help_heading = "Medium", hide_short_help = true)]
    pub emission_color: DVec3,
    /// Write a tone-mapped sRGB PNG preview here (a pattern with --frames).
    #[arg(long, help_heading = "Output")]
    pub preview: Option<PathBuf>,
    /// Preview exposure in stops (default: automatic).
    #[arg(long, allow_hyphen_values = true, help_heading = "Output", hide_short_help = true)]
    pub exposure: Option<f32>,
    /// Append render statistics here, one JSON object per frame and line (JSON Lines):
    /// wall and CPU seconds, core-hours, spp, samples/s, peak RSS, input SHA-256, host,
    /// command line. May hold a frame token.
    #[arg(long, help_heading = "Output")]
    pub stats: Option<PathBuf>,
    /// Bound on resident anonymous memory, e.g. `4GiB` (default: half of RAM or of this
    /// process's cgroup memory limit, whichever is smaller). A .vdb
    /// larger than a quarter of it on disk renders through a brick cache (mapped; the OS
    /// page cache may hold its pages), and a render whose own tables would exceed it is
    /// refused.
    #[arg(long, value_parser = parse_size, help_heading = "Out of core")]
    pub memory_budget: Option<ByteSize>,
    /// Where automatic brick caches of large .vdb inputs go (default: beside the input,
    /// or `$XDG_CACHE_HOME/plume` when that directory is not writable). A current cache
    /// there is used even if the directory is read-only; one that must be made in a
    /// directory that cannot be written is an error (exit 4).
    #[arg(long, help_heading = "Out of core", hide_short_help = true)]
    pub cache_dir: Option<PathBuf>,
    /// Seconds to wait for another process that is making the same automatic cache (farm
    /// nodes sharing a cache directory) before giving up on it: the .vdb is then read into
    /// memory if that fits --memory-budget, with a warning naming the lock file, and the
    /// frame fails otherwise (exit 4). 0: do not wait. Default: 10 minutes plus 1 s per
    /// 10 MB of the .vdb.
    #[arg(long, help_heading = "Out of core", hide_short_help = true)]
    pub cache_lock_timeout: Option<f64>,
    /// Order of the samples (the image is the same): `progressive` passes over the whole
    /// image, or `tile-major`, every sample of a tile before the next, with the next
    /// tiles' bricks read ahead, so a volume larger than memory is read from disk about
    /// once. `auto`: tile-major for a brick cache larger than the memory available to
    /// the page cache (MemAvailable or what the cgroup memory limit leaves, whichever is
    /// smaller), with --spp and no --time-limit. In tile-major order a stop signal
    /// or time limit abandons the frame (nothing of it is written).
    #[arg(long, value_parser = choice::<SampleOrderChoice>(), default_value_t = RenderOptions::default().sample_order, help_heading = "Out of core", hide_short_help = true)]
    pub sample_order: SampleOrderChoice,
    /// Out of core, scattered paths are traced in rounds: each round reruns every
    /// unfinished path on the values gathered for it, records the lookups of the segment
    /// it could not finish, and reads them all in the order of the cache file, so a page
    /// is read about once per round instead of once per lookup (the image is the same
    /// bit for bit). `auto`: where the volume is paged, in tile-major order, from a cache
    /// file larger than the memory available, with `--split 1`; `always`: in every
    /// tile-major render; `never`. Only paths null-tracked after scattering with FNEE or
    /// no light sampling, no external lights or motion blur, and an estimator other than
    /// point are deferred; others are traced where they scatter.
    #[arg(long, value_parser = choice::<DeferPaths>(), default_value_t = RenderOptions::default().defer_paths, help_heading = "Out of core", hide_short_help = true)]
    pub defer_paths: DeferPaths,
    /// No progress bar or summary.
    #[arg(long, short, help_heading = "Output")]
    pub quiet: bool,
    /// Frames to render: `1-100`, `1-100x2` (or `1-100:2`), `1,5,10-20`. One process
    /// renders them in order, each frame's grids loaded once; a frame that fails is
    /// reported and the others go on (exit code 7); an input that fails while in use
    /// (truncated or replaced by another process) ends the run at once (exit code 4).
    #[arg(long, allow_hyphen_values = true, help_heading = "Farm")]
    pub frames: Option<String>,
    /// Render frames even when their output is already complete (default: skip them).
    #[arg(long, help_heading = "Farm", hide_short_help = true)]
    pub overwrite: bool,
    /// Per-frame wall-clock limit in seconds (loading included): the frame stops between
    /// passes and its image is written with the spp reached (exit code 6); a rerun
    /// continues it.
    #[arg(long, help_heading = "Farm", hide_short_help = true)]
    pub time_limit: Option<f64>,
    /// Render only these pixels: x0,y0,x1,y1 (columns x0..x1−1, rows y0..y1−1). Writes a
    /// part for `plume merge`.
    #[arg(long, conflicts_with = "tile", help_heading = "Farm", hide_short_help = true)]
    pub crop: Option<Crop>,
    /// Render only tile i of n (0-based; a near-square grid, row by row). Writes a part
    /// for `plume merge`.
    #[arg(long, help_heading = "Farm")]
    pub tile: Option<TileIndex>,
    /// Render only samples a..b−1 of every pixel (instead of --spp/--time). Writes a part
    /// for `plume merge`.
    #[arg(long, value_parser = plume_scene::split::parse_sample_range, conflicts_with_all = ["spp", "time"], help_heading = "Farm")]
    pub sample_range: Option<std::ops::Range<u64>>,
    /// Also store the exact sample sums in the EXR (implied by --crop, --tile and
    /// --sample-range), so that it can be merged with more samples later.
    #[arg(long, help_heading = "Farm", hide_short_help = true)]
    pub sums: bool,
    /// Also write AOV layers into the EXR: `emission` (volume emission seen directly),
    /// `scattered` (volume emission after scattering), one layer per light group, `alpha`,
    /// and `depth` (expected distance to the first collision). The colour layers sum to
    /// the beauty.
    #[arg(long, help_heading = "Output")]
    pub aovs: bool,
    /// Denoise the beauty: non-local means on two half buffers of the samples (the
    /// filter Cycles used before OpenImageDenoise). Writes the AOV layers too, and the
    /// noisy beauty as the layer `noisy`; parts rendered with it merge into the same
    /// denoised image.
    #[arg(long, help_heading = "Output")]
    pub denoise: bool,
    /// Write the fully resolved scene (FILE and every flag, defaults included) as a
    /// scene file here, and exit without rendering.
    #[arg(long, help_heading = "Output", hide_short_help = true)]
    pub write_scene: Option<PathBuf>,
    /// Machine-readable progress on stdout (logs stay on stderr).
    #[arg(long, value_parser = choice::<ProgressFormat>(), default_value_t = RenderOptions::default().progress, help_heading = "Farm", hide_short_help = true)]
    pub progress: ProgressFormat,
}

/// Which grids make the volume and how they are read: shared by `render` and `prepare`,
/// because a brick cache stores exactly what these flags select.
#[derive(Clone, Debug, Args)]
pub struct GridArgs {
    /// Density grid name (`name[N]` for the N-th duplicate).
    #[arg(long, default_value_t = VolumeInput::new("").density_grid, help_heading = "Volume and grids")]
    pub density_grid: String,
    /// What drives emission.
    #[arg(long, value_parser = choice::<EmissionSource>(), default_value_t = EmissionSettings::default().source, help_heading = "Volume and grids")]
    pub emission: EmissionSource,
    /// Temperature grid name (blackbody).
    #[arg(long, default_value_t = VolumeInput::new("").temperature_grid, help_heading = "Volume and grids")]
    pub temperature_grid: String,
    /// Temperature grid values to Kelvin: `kelvin` or `linear:OFFSET,SCALE`.
    #[arg(long, default_value_t = EmissionSettings::default().temperature_map, help_heading = "Volume and grids", hide_short_help = true)]
    pub temperature_map: String,
    /// Physical blackbody: temperatures below this (Kelvin) emit nothing.
    #[arg(long, default_value_t = EmissionSettings::default().temperature_cutoff, help_heading = "Volume and grids", hide_short_help = true)]
    pub temperature_cutoff: f32,
    /// Emission grid name (`--emission grid`).
    #[arg(long, help_heading = "Volume and grids")]
    pub emission_grid: Option<String>,
    /// Physical, or Blender Cycles' Principled Volume convention.
    #[arg(long, value_parser = choice::<Convention>(), default_value_t = EmissionSettings::default().convention, help_heading = "Volume and grids")]
    pub convention: Convention,
    /// Per-voxel albedo grid (values clamped to [0, 1]), times --albedo.
    #[arg(long, help_heading = "Volume and grids", hide_short_help = true)]
    pub albedo_grid: Option<String>,
    /// Largest input a grid read may allocate, e.g. `8GiB`, `512MiB` (default: half of RAM
    /// or of the cgroup memory limit, whichever is smaller).
    #[arg(long, value_parser = parse_size, help_heading = "Advanced", hide_short_help = true)]
    pub max_input_memory: Option<ByteSize>,
    /// Seconds the isolated VDB reader may take before it is killed.
    #[arg(long, default_value_t = ReadSettings::default().read_timeout, help_heading = "Advanced", hide_short_help = true)]
    pub read_timeout: f64,
    /// Read the file in this process, not in an isolated child that limits memory and
    /// time and survives crashes (saves a few ms; trusted files only).
    #[arg(long, help_heading = "Advanced", hide_short_help = true)]
    pub no_isolation: bool,
}
