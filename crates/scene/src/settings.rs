//! How a render job runs: samples, seed and threads (`[render]`), frames and splits
//! (`[farm]`), outputs (`[output]`) and how input files are read (`[reading]`). None of
//! these change what the scene is; the settings hash (`farm::fingerprint`) says which of
//! them change pixels.

use std::ops::Range;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::choice::{DeferPaths, ProgressFormat, SampleOrderChoice, SamplerKind};
use super::values::{sample_range_text, ByteSize, TileIndex};
use crate::pixels::Crop;
use crate::pixels::SampleId;

/// How the job runs.
#[derive(Clone, Debug, PartialEq)]
pub struct JobSettings {
    /// Samples, seed, threads, memory, progress.
    pub render: RenderOptions,
    /// Frames, crops, sample ranges, limits.
    pub farm: FarmOptions,
    /// Where the images and records go.
    pub output: OutputSettings,
    /// How input files are read.
    pub reading: ReadSettings,
}

impl JobSettings {
    /// Defaults, writing the image to `image`.
    #[must_use]
    pub fn new(image: impl Into<PathBuf>) -> JobSettings {
        JobSettings {
            render: RenderOptions::default(),
            farm: FarmOptions::default(),
            output: OutputSettings::new(image),
            reading: ReadSettings::default(),
        }
    }
}

/// Samples, seed, threads, memory and progress (`[render]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderOptions {
    /// Samples per pixel (default 64 when neither this nor `time` is given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spp: Option<u32>,
    /// Render whole 1-spp passes until this many seconds are spent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
    /// Adaptive sampling: a pixel stops once its estimated relative standard error is at
    /// most this (`plume_engine::noise`); `spp` (default 1024 here) or `time` caps it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_threshold: Option<f64>,
    /// With `noise_threshold`: samples every pixel takes before it may stop (default 16,
    /// or the cap if smaller).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub min_spp: Option<u32>,
    /// With `noise_threshold`: the radiance below which errors are taken relative to it
    /// rather than to the pixel's value (default 0.1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_floor: Option<f64>,
    /// Seed of the sample streams (default: the frame number with frames, else 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Which numbers drive the samples (default: Owen-scrambled Sobol).
    pub sampler: SamplerKind,
    /// Worker threads (0 = all cores). The image does not depend on it.
    pub threads: usize,
    /// Order of the samples (the image does not depend on it).
    pub sample_order: SampleOrderChoice,
    /// When scattered paths are traced in rounds that read the cache file in order (the
    /// image does not depend on it).
    pub defer_paths: DeferPaths,
    /// Bound on resident anonymous memory (default: half of RAM or of the process's
    /// cgroup memory limit, whichever is smaller; `memory::MemoryLimits`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub memory_budget: Option<ByteSize>,
    /// Where automatic brick caches go (default: beside the input).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cache_dir: Option<PathBuf>,
    /// Where automatic brick caches go when `cache_dir` is not given and the input's
    /// directory cannot be written: the user's cache directory, which the application
    /// finds (the library reads no environment). Not a scene-file key: it describes the
    /// machine, not the shot. `None`: beside the input only.
    #[serde(skip)]
    pub user_cache_dir: Option<PathBuf>,
    /// Seconds to wait for another process making the same automatic cache before
    /// rendering without it (default: 10 minutes plus 1 s per 10 MB of the input;
    /// `cache::convert::lock_timeout`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cache_lock_timeout: Option<f64>,
    /// Render only this pixel sample and print its path.
    #[serde(skip_serializing_if = "Option::is_none", with = "super::values::opt_text")]
    pub debug_pixel: Option<SampleId>,
    /// No progress bar or summary.
    pub quiet: bool,
    /// Machine-readable progress on stdout.
    pub progress: ProgressFormat,
}

/// The edge, in pixels, of the image-aligned blocks within which adaptive sampling pools
/// a pixel's neighbours (the film's tile size).
pub const ADAPTIVE_BLOCK: u32 = 16;

impl RenderOptions {
    /// The samples per pixel when neither `spp`, `time` nor a sample range is given: 64,
    /// or 1024 as the cap of adaptive sampling.
    #[must_use]
    pub fn default_spp(&self) -> u32 {
        if self.noise_threshold.is_some() {
            1024
        } else {
            64
        }
    }

    /// The edge of the pixel blocks whose decisions a render takes together: 16 with
    /// adaptive sampling (`plume_engine::noise`: crops and tiles must not cut them), else
    /// 1 (every pixel alone).
    #[must_use]
    pub fn adaptive_block(&self) -> u32 {
        if self.noise_threshold.is_some() {
            ADAPTIVE_BLOCK
        } else {
            1
        }
    }

    /// Adaptive sampling's minimum samples per pixel: `min_spp`, else 16 or the `cap`
    /// if smaller.
    #[must_use]
    pub fn min_spp_or_default(&self, cap: Option<u32>) -> u32 {
        self.min_spp.unwrap_or_else(|| cap.map_or(16, |c| c.min(16)))
    }
}

/// Frames, splits and limits (`[farm]`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FarmOptions {
    /// Frames to render: `1-100`, `1-100x2`, `1,5,10-20`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frames: Option<String>,
    /// Render frames even when their output is already complete.
    pub overwrite: bool,
    /// Per-frame wall-clock limit in seconds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_limit: Option<f64>,
    /// Render only these pixels (`x0,y0,x1,y1`).
    #[serde(skip_serializing_if = "Option::is_none", with = "super::values::opt_text")]
    pub crop: Option<Crop>,
    /// Render only tile i of n (`i/n`).
    #[serde(skip_serializing_if = "Option::is_none", with = "super::values::opt_text")]
    pub tile: Option<TileIndex>,
    /// Render only samples a..b−1 of every pixel (`a..b`).
    #[serde(skip_serializing_if = "Option::is_none", with = "sample_range_text")]
    pub sample_range: Option<Range<u64>>,
}

/// Where the images and records go (`[output]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSettings {
    /// The EXR (a pattern with frames).
    #[serde(default)]
    pub image: PathBuf,
    /// A tone-mapped sRGB PNG preview (a pattern with frames).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preview: Option<PathBuf>,
    /// Preview exposure in stops (default: automatic).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure: Option<f32>,
    /// Render statistics, one JSON object per frame and line.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stats: Option<PathBuf>,
    /// Also store the exact sample sums in the EXR.
    #[serde(default)]
    pub sums: bool,
    /// Also write AOV layers (`integrator::aov`): `emission`, `scattered`, one per light
    /// group, `alpha`, `depth`.
    #[serde(default)]
    pub aovs: bool,
    /// Denoise the beauty (`plume_engine::denoise`): records the AOV layers and half sums it
    /// needs, writes the AOV layers and the noisy beauty as the layer `noisy`.
    #[serde(default)]
    pub denoise: bool,
}

impl OutputSettings {
    /// No image yet (a scene file without one, completed by `-o`).
    pub(super) fn unset() -> OutputSettings {
        OutputSettings::new(PathBuf::new())
    }

    /// Only the EXR `image`.
    #[must_use]
    pub fn new(image: impl Into<PathBuf>) -> OutputSettings {
        OutputSettings {
            image: image.into(),
            preview: None,
            exposure: None,
            stats: None,
            sums: false,
            aovs: false,
            denoise: false,
        }
    }
}

/// How input files are read (`[reading]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReadSettings {
    /// Largest input a grid read may allocate (default: half of RAM or of the cgroup
    /// memory limit, whichever is smaller).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_input_memory: Option<ByteSize>,
    /// Seconds the isolated VDB reader may take before it is killed.
    pub read_timeout: f64,
    /// Read files in this process, not in an isolated child (trusted files only).
    pub no_isolation: bool,
}

impl Default for ReadSettings {
    fn default() -> Self {
        ReadSettings { max_input_memory: None, read_timeout: 120.0, no_isolation: false }
    }
}
