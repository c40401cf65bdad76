//! What a render is asked ([`RenderSettings`], [`RenderControl`], [`SampleBudget`],
//! [`SampleOrder`]) and what it returns ([`RenderResult`], [`StopReason`]).

use std::time::Instant;

use crate::film::{Crop, Film};
use crate::integrator::aov::AovLayout;
use crate::integrator::counters::Counters;
use crate::integrator::volpath::Integrator;
use crate::noise::Adaptive;
use plume_core::sampling::SamplerKind;
use plume_scene::DeferPaths;

/// How many samples to take.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SampleBudget {
    /// Exactly this many samples per pixel.
    Spp(u32),
    /// Whole 1-spp passes until this many seconds are spent (at least one pass).
    Time(f64),
    /// Passes until the process has used this many CPU seconds more (at least one pass):
    /// equal-CPU-time comparisons on a shared machine.
    CpuTime(f64),
}

/// Settings of one render, validated once.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    /// Sample budget.
    pub budget: SampleBudget,
    /// Seed of every sample stream.
    pub seed: u64,
    /// Which numbers the samplers give (`--sampler`).
    pub sampler: SamplerKind,
    /// Worker threads (0 = all cores; in tile-major order from a mapped volume, where
    /// workers wait on page faults, one more, or three per core when paths scatter).
    pub threads: usize,
    /// First sample index (sample ranges; 0 normally).
    pub first_sample: u64,
    /// The integrator.
    pub integrator: Integrator,
    /// Adaptive sampling (`render.noise_threshold`): pixels stop at a checkpoint once
    /// their estimated relative error is below the threshold (`noise`); `None`: every
    /// pixel takes every sample.
    pub adaptive: Option<Adaptive>,
}

/// What a render produced.
#[derive(Debug)]
pub struct RenderResult {
    /// Sums per pixel.
    pub film: Film,
    /// Samples per pixel taken.
    pub spp: u64,
    /// Counters over all tiles.
    pub counters: Counters,
    /// Wall time spent rendering, seconds.
    pub render_seconds: f64,
    /// Wall seconds the workers spent rendering tiles, summed over workers: divided by
    /// `render_seconds`, how many workers had work on average (what pass ends and set-up
    /// between passes cost; wall time, so other load on the machine does not hide it).
    pub busy_seconds: f64,
    /// Why the loop ended.
    pub stopped: StopReason,
}

/// Why a render loop ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// The sample budget was spent.
    Finished,
    /// A stop was requested (a signal); the last pass was completed.
    Interrupted,
    /// The deadline came before the budget was spent.
    TimeLimit,
}

/// The order in which a render visits its samples. The image is the same either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SampleOrder {
    /// Passes over the whole image of a few samples per pixel each (about
    /// [`PASS_SECONDS`]): progress, stop requests and time budgets act between passes.
    #[default]
    Progressive,
    /// For a fixed sample count (with a time budget the render stays progressive): one
    /// pass taking every sample of a tile before the next, tiles in raster order, the
    /// tiles just ahead of the workers prefetched. For volumes larger than memory. A stop
    /// request or the deadline abandons the pass between tiles and keeps nothing of it.
    ///
    /// **Read-ahead window.** A tile's camera rays can cross hundreds of MB of bricks, so a
    /// fixed number of tiles ahead can ask for more than the memory holds: pages read ahead
    /// then push out the pages of the tiles being rendered, and both are read again. The
    /// prefetch thread therefore also waits while the bytes it asked for, for tiles not yet
    /// finished (being rendered or waiting), exceed [`RenderControl::read_ahead_window`]; a
    /// tile already taken by a worker is always asked for. In a memory limit smaller than
    /// the volume this cuts the page faults of emission–absorption and scattering renders
    /// alike (docs/BENCHMARKS.md, "Out of core with scattering: the solar flare").
    TileMajor,
}

/// The [`RenderControl::read_ahead_window`] for a memory budget: half of it, i.e. a
/// quarter of the memory limit when the budget is the default, leaving the rest to the
/// tiles' scattered rays and to the volume's index.
#[must_use]
pub fn read_ahead_window(memory_budget: u64) -> Option<u64> {
    Some(memory_budget / 2)
}

/// Wall seconds a pass aims at: the longest wait between a stop request and the image.
pub const PASS_SECONDS: f64 = 1.0;

/// What `render_with` renders besides the settings: which pixels, from which sums, and
/// when to stop early.
#[derive(Default)]
pub struct RenderControl<'a> {
    /// Pixels to render (default: the whole image).
    pub crop: Option<Crop>,
    /// Sums to continue from (a resumed render), with the same crop; samples are added
    /// from `settings.first_sample` on.
    pub film: Option<Film>,
    /// Checked between passes; `true` ends the render after the current pass.
    pub stop: Option<&'a (dyn Fn() -> bool + Sync)>,
    /// No pass is started that is predicted to end after this instant (at least one pass
    /// is always rendered, except in tile-major order, which abandons it at the deadline).
    pub deadline: Option<Instant>,
    /// Sample order.
    pub order: SampleOrder,
    /// Record AOV layers with this layout (`integrator::aov`); `None`: the beauty only.
    pub aovs: Option<AovLayout>,
    /// In tile-major order, the most bytes asked to be read ahead for tiles that are not
    /// finished yet (see [`SampleOrder::TileMajor`]); `None`: no bound but the number of
    /// tiles ahead. Never changes a result.
    pub read_ahead_window: Option<u64>,
    /// Whether scattered paths are traced in rounds (`integrator::deferred`). Never
    /// changes a result.
    pub defer_paths: DeferPaths,
    /// With half sums in `aovs` (`--denoise`): the half block ([`crate::denoise::half_of`];
    /// `None`: [`crate::denoise::half_block`]`(None)`).
    pub half_block: Option<u64>,
}
