//! One tile's samples: the camera ray and sampler of each pixel sample
//! ([`pixel_sample`]), traced by the pixel's integrator and added to the tile's exact
//! sums, AOVs and half sums; scattered paths may be deferred (`integrator::deferred`).

use crate::film::Tile;
use crate::integrator::aov::{AovSample, Aovs, NoAovs};
use crate::integrator::counters::Counters;
use crate::integrator::deferred::PendingSample;
use crate::integrator::path::PathState;
use crate::integrator::scene::Scene;
use crate::integrator::split_map::{pixel_integrator, SplitMap};
use crate::integrator::trace::NoTrace;
use plume_core::sampling::{Dim, Sampler, SamplerKind};
use plume_scene::SampleId;
use plume_volume::field::Field;

use super::settings::RenderSettings;

/// One pixel sample as the render loop starts it: what [`pixel_sample`] returns.
#[derive(Clone, Debug)]
#[must_use]
pub struct PixelSample {
    /// The camera ray through the jittered point of the pixel (world space).
    pub ray: plume_volume::field::Ray,
    /// The sample's sampler, at the camera segment after the pixel jitter was drawn.
    pub sampler: Sampler,
    /// The sample's shutter time (seconds), when the scene moves.
    pub time: Option<f64>,
}

/// The camera ray and sampler state of one pixel sample, as the render loop makes them
/// (used by `--debug-pixel` to replay a sample exactly).
pub fn pixel_sample<F: Field>(
    scene: &Scene<F>,
    kind: SamplerKind,
    seed: u64,
    x: u32,
    y: u32,
    s: u64,
) -> PixelSample {
    let pixel = u64::from(y) * u64::from(scene.camera.width) + u64::from(x);
    let mut sampler = Sampler::with_kind(kind, seed, pixel, s);
    sampler.start_vertex(0);
    let [jx, jy] = sampler.get_2d(Dim::Direction);
    // With motion, the sample's shutter time places the camera (and the volume, in `li`)
    let shutter =
        scene.motion.as_ref().map(|m| m.shutter).or(scene.camera.motion.map(|m| m.shutter()));
    let time = shutter.map(|[open, close]| open + sampler.get_1d(Dim::Time) * (close - open));
    let camera = time.map_or(scene.camera, |t| scene.camera.at_time(t));
    let (px, py) = (f64::from(x) + jx, f64::from(y) + jy);
    let ray = if camera.needs_lens_sample() {
        camera.ray_through_lens(px, py, sampler.get_2d(Dim::Lens))
    } else {
        camera.ray(px, py)
    };
    PixelSample { ray, sampler, time }
}

/// Where a tile's samples whose scattered paths are deferred go (`integrator::deferred`):
/// the tile's number in the film, and the list.
/// What every tile of a pass renders with: the settings, and the per-pixel path counts
/// when splitting by brightness (`integrator::split_map`).
#[derive(Clone, Copy, Debug)]
pub(super) struct TileJob<'a> {
    /// The render's settings.
    pub(super) settings: &'a RenderSettings,
    /// Paths per camera collision per pixel, from the pilot render.
    pub(super) split_map: Option<&'a SplitMap>,
}

pub(super) type Deferring<'p> = Option<(usize, &'p mut Vec<PendingSample>)>;

pub(super) fn render_tile<F: Field>(
    scene: &Scene<F>,
    job: TileJob<'_>,
    samples: std::ops::Range<u64>,
    tile: &mut Tile,
    defer: Deferring<'_>,
) -> Counters {
    if tile.aov_channels == 0 {
        render_tile_with(scene, job, samples, tile, &mut NoAovs, defer)
    } else {
        let mut aovs = AovSample::new(tile.aov_channels, tile.half.map(|h| (h.at, h.filtered)));
        render_tile_with(scene, job, samples, tile, &mut aovs, None)
    }
}

fn render_tile_with<F: Field, A: Aovs>(
    scene: &Scene<F>,
    job: TileJob<'_>,
    samples: std::ops::Range<u64>,
    tile: &mut Tile,
    aovs: &mut A,
    mut defer: Deferring<'_>,
) -> Counters {
    let mut counters = Counters::default();
    let pixels = (tile.width * tile.height) as usize;
    let Some(adaptive) = job.settings.adaptive else {
        for index in 0..pixels {
            let run = PixelRun { samples: samples.clone(), index };
            render_pixel(scene, job, run, tile, aovs, &mut defer, &mut counters);
        }
        return counters;
    };
    // Adaptive sampling (`noise`): the pixels still sampling hold every sample before
    // this pass; at each checkpoint the tile decides for all of them together, from its
    // sums at that count, then renders them to the next checkpoint
    let mut active: Vec<bool> = (0..pixels).map(|i| tile.count(i) == samples.start).collect();
    let mut s0 = samples.start;
    while s0 < samples.end {
        if adaptive.is_checkpoint(s0) {
            stop_converged(&adaptive, tile, &mut active);
        }
        let s1 = adaptive.checkpoint_from(s0 + 1).min(samples.end);
        for index in (0..pixels).filter(|&i| active[i]) {
            let run = PixelRun { samples: s0..s1, index };
            render_pixel(scene, job, run, tile, aovs, &mut defer, &mut counters);
        }
        s0 = s1;
    }
    counters
}

/// At a checkpoint: the active pixels of `tile` whose pooled error is below the
/// threshold stop (`active` becomes `false`). Every decision reads the tile as it is
/// before any is applied.
fn stop_converged(adaptive: &crate::noise::Adaptive, tile: &Tile, active: &mut [bool]) {
    let noise = crate::noise::pixel_noise(&tile.sums, &tile.moments);
    let rect = crate::film::Crop {
        x0: tile.x0,
        y0: tile.y0,
        x1: tile.x0 + tile.width,
        y1: tile.y0 + tile.height,
    };
    let grid = crate::noise::NoiseGrid::new(rect, &noise, adaptive.floor);
    for (i, a) in active.iter_mut().enumerate() {
        let (x, y) = (tile.x0 + i as u32 % tile.width, tile.y0 + i as u32 / tile.width);
        if *a && adaptive.converged(&grid, x, y) {
            *a = false;
        }
    }
}

/// Which samples of which pixel (row-major within the tile) [`render_pixel`] renders.
struct PixelRun {
    samples: std::ops::Range<u64>,
    index: usize,
}

/// Render samples `run.samples` of pixel `run.index` of `tile`, adding each to its sums
/// (or, deferring, to the pending list).
fn render_pixel<F: Field, A: Aovs>(
    scene: &Scene<F>,
    TileJob { settings, split_map }: TileJob<'_>,
    PixelRun { samples, index }: PixelRun,
    tile: &mut Tile,
    aovs: &mut A,
    defer: &mut Deferring<'_>,
    counters: &mut Counters,
) {
    let (tx, ty) = (index as u32 % tile.width, index as u32 / tile.width);
    let (x, y) = (tile.x0 + tx, tile.y0 + ty);
    let integrator = pixel_integrator(&settings.integrator, split_map, x, y);
    for s in samples {
        let PixelSample { ray, mut sampler, time } =
            pixel_sample(scene, settings.sampler, settings.seed, x, y, s);
        aovs.begin();
        let l = if let Some((tile_index, pending)) = defer.as_mut() {
            let mut paths = Vec::new();
            let state = PathState {
                sampler: &mut sampler,
                counters,
                trace: &mut NoTrace,
                aovs: &mut NoAovs,
            };
            let l = integrator.li_deferring(scene, &ray, time, state, &mut paths);
            if !paths.is_empty() {
                // Added to the film when its paths are done
                counters.samples += 1;
                pending.push(PendingSample::new(
                    *tile_index,
                    index,
                    SampleId { x, y, sample: s },
                    integrator,
                    l,
                    paths,
                ));
                continue;
            }
            l
        } else {
            integrator.li_aovs(
                scene,
                &ray,
                time,
                PathState { sampler: &mut sampler, counters, trace: &mut NoTrace, aovs },
            )
        };
        if tile.half.is_some_and(|h| A::ON && crate::denoise::half_of(s, h.block)) {
            aovs.half(l);
        }
        counters.samples += 1;
        if l.iter().all(|v| v.is_finite())
            && (!A::ON || aovs.values().iter().all(|v| v.is_finite()))
        {
            tile.add_sample(index, s, l);
            if A::ON {
                tile.add_aov(index, aovs.values());
            }
        } else {
            // Drop and count non-finite samples; report the first for replay
            tile.add_dropped(index, s);
            counters.nonfinite_samples += 1;
            counters.first_nonfinite.get_or_insert(SampleId { x, y, sample: s });
        }
    }
}
