//! The plan of a `plume render` run ([`Job`]): frame patterns, frames, crop and
//! samples, worked out once from the validated shot. A leaf of `farm`: the run
//! (`farm::job`) and each frame (`farm::frame`) read it.

use std::ops::Range;

use crate::farm::pattern::FramePattern;
use crate::farm::{frames, split};
use plume_core::error::{Error, Result};
use plume_engine::film::Crop;
use plume_scene::{SceneDescription, ValidShot};

/// The plan of a `plume render` run.
pub struct Job<'a> {
    /// The shot as given.
    pub shot: &'a ValidShot,
    /// The (first) volume's file, maybe with a frame token.
    pub input: FramePattern,
    /// The further volumes' files (`volumes[1].file`, …), in order, each maybe with a
    /// frame token.
    pub more_inputs: Vec<FramePattern>,
    /// The EXR, maybe with a frame token.
    pub output: FramePattern,
    /// The preview.
    pub preview: Option<FramePattern>,
    /// The statistics file.
    pub stats: Option<FramePattern>,
    /// Frames in order; `[None]` without frames.
    pub frames: Vec<Option<i64>>,
    /// Pixels to render (crop or tile), `None` for the whole image.
    pub crop: Option<Crop>,
    /// Samples to render: the sample range, or `0..spp`; `None` for a time budget.
    pub samples: Option<Range<u64>>,
    /// Store exact sums in the EXR (parts and `output.sums`).
    pub write_sums: bool,
}

impl<'a> Job<'a> {
    /// Plan the run: frame patterns, frames, crop and samples.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the key: a frame token without frames, several
    /// frames written to one file.
    pub fn new(shot: &'a ValidShot) -> Result<Job<'a>> {
        let (scene, settings) = (&shot.scene, &shot.settings);
        let input = FramePattern::parse(&scene.volume.file);
        let more_inputs: Vec<FramePattern> =
            scene.more_volumes.iter().map(|e| FramePattern::parse(&e.volume.file)).collect();
        let output = FramePattern::parse(&settings.output.image);
        let preview = settings.output.preview.as_deref().map(FramePattern::parse);
        let stats = settings.output.stats.as_deref().map(FramePattern::parse);
        let frames: Vec<Option<i64>> = match &settings.farm.frames {
            Some(list) => frames::parse_frames(list)
                .map_err(|m| Error::invalid("farm.frames", m))?
                .into_iter()
                .map(Some)
                .collect(),
            None => {
                let inputs = std::iter::once(&input).chain(&more_inputs);
                let keys = scene.entries().iter().map(|e| e.key("file")).collect::<Vec<_>>();
                let files = keys.iter().map(String::as_str).zip(inputs);
                for (key, p) in files.chain([("output.image", &output)]) {
                    if p.has_frame() && !p.as_path().exists() {
                        return Err(Error::invalid(
                            key,
                            format!(
                                "{} has a frame token; say which frames to render with farm.frames",
                                p.as_path().display()
                            ),
                        ));
                    }
                }
                vec![None]
            }
        };
        if frames.len() > 1 {
            for (key, p) in [("output.image", Some(&output)), ("output.preview", preview.as_ref())]
            {
                if let Some(p) = p.filter(|p| !p.has_frame()) {
                    return Err(Error::invalid(
                        key,
                        format!("{} frames would all be written to {}; put a frame token in it (####, %04d or $F4)", frames.len(), p.as_path().display()),
                    ));
                }
            }
        }
        let (width, height) = (scene.camera.width, scene.camera.height);
        let farm = &settings.farm;
        let crop = match (farm.crop, farm.tile) {
            (Some(c), _) => Some(c),
            (None, Some(t)) => Some(
                split::tile_crop(t.index, t.count, width, height, settings.render.adaptive_block())
                    .map_err(|m| Error::invalid("farm.tile", m))?,
            ),
            (None, None) => None,
        };
        let samples = match (&farm.sample_range, settings.render.spp, settings.render.time) {
            (Some(r), _, _) => Some(r.clone()),
            (None, _, Some(_)) => None,
            (None, Some(n), None) => Some(0..u64::from(n)),
            (None, None, None) => Some(0..u64::from(settings.render.default_spp())),
        };
        let write_sums = settings.output.sums || crop.is_some() || farm.sample_range.is_some();
        Ok(Job {
            shot,
            input,
            more_inputs,
            output,
            preview,
            stats,
            frames,
            crop,
            samples,
            write_sums,
        })
    }

    /// The scene.
    #[must_use]
    pub fn scene(&self) -> &SceneDescription {
        &self.shot.scene
    }

    /// The pixels each frame renders: the crop or tile, else the whole image.
    #[must_use]
    pub fn pixels(&self) -> Crop {
        self.crop.unwrap_or(Crop::full(self.shot.scene.camera.width, self.shot.scene.camera.height))
    }
}
