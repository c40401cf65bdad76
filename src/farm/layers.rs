//! What is written of a frame's image: the AOV layout asked for (`--aovs`, `--denoise`),
//! and the beauty (denoised when the layout holds half sums), the `error` layer and the AOV
//! layers computed from exact sums. Shared by `plume render` (`farm::outputs`) and `plume merge`
//! (`farm::merge`), so that a merged frame is the single render's.

use crate::farm::plan::Job;
use crate::load::LoadedScene;
use plume_engine::film::{Crop, Moments};
use plume_engine::integrator::AovLayout;

/// The AOV layout that `output` asks for (`--aovs`, `--denoise`): one layer per light
/// group of the job's lights and volumes, and the half sums with `--denoise`.
pub(crate) fn layout_for(output: &plume_scene::OutputSettings, job: &Job<'_>) -> Option<AovLayout> {
    let scene = &job.shot.scene;
    let filtered = plume_engine::denoise::Filtered::for_camera(
        plume_engine::integrator::Integrator::for_scene(scene).camera_estimator(),
    );
    // Volume light groups move direct emission out of the `emission` layer, which the
    // denoiser would otherwise leave out of its filter: it filters the whole beauty
    let filtered = match scene.entries().iter().any(|e| e.volume.group.is_some()) {
        true => plume_engine::denoise::Filtered::Beauty,
        false => filtered,
    };
    (output.aovs || output.denoise).then(|| AovLayout {
        groups: scene.aov_groups(),
        halves: output.denoise.then_some(filtered),
    })
}

/// The AOV layout of this frame ([`layout_for`]).
pub(crate) fn aov_layout(job: &Job<'_>, loaded: &LoadedScene) -> Option<AovLayout> {
    let layout = layout_for(&job.shot.settings.output, job);
    if let (Some(l), Some(e)) = (&layout, &loaded.scene.lights().external) {
        debug_assert!(
            l.groups.starts_with(e.groups()),
            "the description's groups begin with the built lights'"
        );
    }
    layout
}

/// Named `f32` channels (`emission.R`, …), each row-major over the image.
pub type Layers = Vec<(String, Vec<f32>)>;

/// What is written of an image: its beauty and its AOV layers.
#[derive(Debug)]
pub struct Written {
    /// The beauty, row-major over the image.
    pub pixels: Vec<[f32; 4]>,
    /// The AOV layers (with `noisy` when denoised).
    pub layers: Layers,
    /// Whether the beauty was denoised.
    pub denoised: bool,
}

/// An image's exact record, row-major over its pixels: what its beauty and layers are
/// computed from.
#[derive(Clone, Copy, Debug)]
pub struct FrameSums<'a> {
    /// RGBA sums.
    pub rgba: &'a [[i128; 4]],
    /// Squared colour sums and sample counts.
    pub moments: &'a [Moments],
    /// AOV channel sums (`layout.channels()` per pixel; empty without AOVs).
    pub aov: &'a [i128],
}

/// The beauty and the layers of an image (`crop`) from its exact sums, its noisy beauty
/// and its pooled standard errors (`FrameNoise::errors`): the `error` layer
/// ([`error_layer`]) always, the AOV layers of `layout` if any;
/// with half sums in the layout (and samples in both halves) the beauty is denoised
/// ([`plume_engine::denoise::from_sums`]) and the noisy one becomes the layer `noisy`.
/// Used by `plume render` and `plume merge`, so that a merged frame is the single render's.
#[must_use]
pub fn beauty_and_layers(
    layout: Option<&AovLayout>,
    sums: FrameSums<'_>,
    noisy: Vec<[f32; 4]>,
    errors: &[[f64; 3]],
    crop: Crop,
) -> Written {
    let Some(layout) = layout else {
        return Written { pixels: noisy, layers: error_layer(errors), denoised: false };
    };
    let counts: Vec<u64> = sums.moments.iter().map(|m| m.count).collect();
    let mut layers = aov_layers(layout, sums.aov, &noisy, &counts);
    layers.extend(error_layer(errors));
    match plume_engine::denoise::from_sums(
        layout,
        sums.rgba,
        sums.aov,
        &counts,
        (crop.width() as usize, crop.height() as usize),
    ) {
        Some(denoised) => {
            for (c, name) in ["R", "G", "B", "A"].iter().enumerate() {
                layers.push((format!("noisy.{name}"), noisy.iter().map(|p| p[c]).collect()));
            }
            Written { pixels: denoised, layers, denoised: true }
        }
        None => Written { pixels: noisy, layers, denoised: false },
    }
}

/// The `error` layer: per pixel and colour channel, the estimated standard error of the
/// pixel's (noisy) mean, pooled over its neighbours (`errors`, from
/// [`plume_engine::noise::FrameNoise`]; infinite for a pixel with fewer than two
/// samples).
#[must_use]
pub fn error_layer(errors: &[[f64; 3]]) -> Layers {
    ["R", "G", "B"]
        .iter()
        .enumerate()
        .map(|(c, name)| (format!("error.{name}"), errors.iter().map(|e| e[c] as f32).collect()))
        .collect()
}

/// The AOV layers' pixel values from their exact sums (`aov_sums`, `layout.channels()`
/// per pixel) over `counts` samples per pixel, with `alpha` from the beauty: `(name,
/// values)` per channel.
#[must_use]
pub fn aov_layers(
    layout: &AovLayout,
    aov_sums: &[i128],
    beauty: &[[f32; 4]],
    counts: &[u64],
) -> Layers {
    let (n, n_layers) = (layout.channels(), layout.layer_channels());
    let names = layout.channel_names();
    // Every layer channel but depth's hit count, which `depth.Z` divides by
    let mut layers: Layers = names[..n_layers - 1]
        .iter()
        .map(|c| (c.clone(), Vec::with_capacity(beauty.len())))
        .collect();
    for (sums, &spp) in aov_sums.chunks_exact(n).zip(counts) {
        for (layer, v) in
            layers.iter_mut().zip(layout.pixel(sums, spp, plume_engine::film::pixel_value))
        {
            layer.1.push(v);
        }
    }
    layers.push(("alpha.A".into(), beauty.iter().map(|p| p[3]).collect()));
    layers
}
