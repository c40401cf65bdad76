//! The pilot render of `--split-by brightness` (`integrator::split_map`): one pixel per
//! block of the whole frame, a few samples each, measuring the light the camera does not
//! see directly, from which every pixel's split count follows.
//!
//! It draws its own numbers: the render's seed with [`PILOT_STREAM`] mixed in, so no
//! pixel's count depends on the noise of the samples it will split. Each block's samples
//! are summed in order by one worker, so the map is the same for any thread count, and it
//! covers the whole frame whatever crop, tile or sample range the render computes.

use rayon::prelude::*;

use plume_core::color::rec709_luminance;

use crate::integrator::aov::{Aovs, Component};
use crate::integrator::counters::Counters;
use crate::integrator::path::PathState;
use crate::integrator::scene::Scene;
use crate::integrator::split_map::{PilotBlock, SplitMap, PILOT_SPP};
use crate::integrator::trace::NoTrace;
use crate::render::settings::RenderSettings;
use crate::render::tile::{pixel_sample, PixelSample};
use plume_scene::SplitBy;
use plume_volume::field::Field;

/// Mixed into the render's seed for the pilot's numbers.
pub const PILOT_STREAM: u64 = 0x51f1_7a9c_3d2e_8b47;

/// The emission the camera segment adds (`Component::Emission`), summed over a sample.
#[derive(Default)]
struct SeenDirectly {
    emission: [f64; 3],
}

impl Aovs for SeenDirectly {
    const ON: bool = true;
    fn add(&mut self, component: Component, w: [f64; 3], e: [f64; 3]) {
        if component == Component::Emission {
            for ((s, v), w) in self.emission.iter_mut().zip(e).zip(w) {
                *s += w * v;
            }
        }
    }
    fn first_collision(&mut self, _t: f64) {}
    fn begin(&mut self) {
        self.emission = [0.0; 3];
    }
    fn values(&self) -> &[f64] {
        &[]
    }
    fn half(&mut self, _l: [f64; 4]) {}
}

/// The split counts of `settings`' integrator on `scene`, or `None` when it splits
/// uniformly, when no path scatters, or when the pilot finds nothing to weigh (no covered
/// block, no scattered light): every pixel then keeps `split`. Runs on the current rayon
/// pool.
#[must_use]
pub fn split_map<F: Field>(scene: &Scene<F>, settings: &RenderSettings) -> Option<SplitMap> {
    let integrator = settings.integrator;
    if integrator.split_by != SplitBy::Brightness
        || integrator.split <= 1
        || integrator.max_depth == 0
        || scene.medium.albedo.max_component() <= 0.0
    {
        return None;
    }
    let (width, height) = (scene.camera.width, scene.camera.height);
    let (cols, rows) = SplitMap::blocks(width, height);
    let seed = settings.seed ^ PILOT_STREAM;
    let pilot: Vec<PilotBlock> = (0..cols * rows)
        .into_par_iter()
        .map(|b| {
            let (x, y) = SplitMap::pilot_pixel(b % cols, b / cols, width, height);
            let mut seen = SeenDirectly::default();
            let mut counters = Counters::default();
            let mut block = PilotBlock::default();
            for s in 0..u64::from(PILOT_SPP) {
                let PixelSample { ray, mut sampler, time } =
                    pixel_sample(scene, settings.sampler, seed, x, y, s);
                seen.begin();
                let l = integrator.li_aovs(
                    scene,
                    &ray,
                    time,
                    PathState {
                        sampler: &mut sampler,
                        counters: &mut counters,
                        trace: &mut NoTrace,
                        aovs: &mut seen,
                    },
                );
                // A non-finite sample is dropped, as the render drops it
                if l.iter().all(|v| v.is_finite()) && seen.emission.iter().all(|v| v.is_finite()) {
                    block.scattered += (rec709_luminance([l[0], l[1], l[2]])
                        - rec709_luminance(seen.emission))
                    .max(0.0);
                    block.alpha += l[3];
                }
            }
            let n = f64::from(PILOT_SPP);
            PilotBlock { scattered: block.scattered / n, alpha: block.alpha / n }
        })
        .collect();
    SplitMap::from_pilot(cols, &pilot, integrator.split)
}
