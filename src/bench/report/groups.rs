//! Renderer options at equal CPU time, each against the default on one scene ([`GROUPS`]):
//! tracking, splitting, splitting by brightness, forced camera collisions, stochastic
//! point lookups, and motion blur against the still image. What each group measures is
//! here; `group_section` runs one and writes its section.

use std::path::{Path, PathBuf};

/// One renderer option's values, compared at equal CPU time on one scene.
pub(super) struct Group {
    /// Section title.
    pub(super) title: &'static str,
    /// File name stem of its scene files and JSON.
    pub(super) name: &'static str,
    /// What it measures.
    pub(super) intro: &'static str,
    /// The scene all variants share.
    pub(super) base: Base,
    /// The method of every run.
    pub(super) method: &'static str,
    /// Each value: a label, the flag it is on the command line, its scene-file keys.
    pub(super) variants: &'static [(&'static str, &'static str, &'static str)],
    /// One reference, of the base scene, for every variant (the variants render the same
    /// image in expectation); otherwise each variant computes its own.
    pub(super) shared_reference: bool,
}

/// A scene of the option groups.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Base {
    /// The Blender Mantaflow explosion, frame 40, as the Cycles comparison renders it.
    Kelvin40,
    /// The README demo's scene (the generated explosion 128³) at 160×120.
    Demo,
}

impl Base {
    /// File name stem of its scene file and saved reference.
    pub(super) fn name(self) -> &'static str {
        match self {
            Base::Kelvin40 => "kelvin40",
            Base::Demo => "demo-scene",
        }
    }

    /// The scene spec (under `data`) and its scene-file keys.
    pub(super) fn spec(self, data: &Path) -> (PathBuf, &'static str) {
        match self {
            Base::Kelvin40 => (
                data.join("explosion/mantaflow_explosion_kelvin_0040.vdb"),
                "[emission]\nconvention = \"cycles\"\n[medium]\nalbedo = 0.8\n[camera]\nup_axis = \"z\"\nwidth = 128\nheight = 128",
            ),
            Base::Demo => (
                PathBuf::from("explosion:128"),
                "[medium]\ndensity_scale = 4.0\nalbedo = 0.8\ng = 0.3\n[camera]\nwidth = 160\nheight = 120\n[integrator]\ncamera_estimator = \"ray-march\"\nsplit = 6\nproxy_resolution = 32",
            ),
        }
    }

    /// The scene in words, for the section.
    pub(super) fn about(self) -> &'static str {
        match self {
            Base::Kelvin40 => "`explosion/mantaflow_explosion_kelvin_0040.vdb` (Blender's explosion, frame 40, blackbody from the Kelvin grid) as the Cycles comparison renders it: `--convention cycles --albedo 0.8 --up-axis z`, 128×128, line-fnee",
            Base::Demo => "the README demo's scene (the generated explosion 128³, σ_t = 4, albedo 0.8, g 0.3, ray-marched camera segment, 6 paths per camera collision, 32³ proxy) at 160×120, line-fnee",
        }
    }
}

/// The option groups, in document order.
pub(super) const GROUPS: [Group; 6] = [
    Group {
        title: "Tracking: null collisions after scattering",
        name: "tracking",
        intro: "`--tracking`: how segments are tracked. `regular` walks every segment exactly (the paper's); `mixed` (what the default `auto` picks for line-fnee) keeps the exact walk on camera rays and tracks the segments after a scattering event by null collisions under brick majorants, looking the volume up only at tentative collisions; `null` tracks camera rays that way too.",
        base: Base::Kelvin40,
        method: "line-fnee",
        variants: &[
            ("regular", "--tracking regular", "[integrator]\ntracking = \"regular\""),
            ("mixed (default)", "--tracking mixed", "[integrator]\ntracking = \"mixed\""),
            ("null", "--tracking null", "[integrator]\ntracking = \"null\""),
        ],
        shared_reference: true,
    },
    Group {
        title: "Splitting at the camera collision",
        name: "split",
        intro: "`--split N`: N paths traced from each collision of a camera ray, each carrying 1/N, on one walk of the camera ray. In thin smoke most camera rays cross without colliding and their walk is most of a sample's cost, while the scattered light carries most of the noise; splitting spends more where the noise is.",
        base: Base::Kelvin40,
        method: "line-fnee",
        variants: &[
            ("1", "--split 1", "[integrator]\nsplit = 1"),
            ("4", "--split 4", "[integrator]\nsplit = 4"),
            ("8 (default)", "--split 8", "[integrator]\nsplit = 8"),
            ("16", "--split 16", "[integrator]\nsplit = 16"),
        ],
        shared_reference: true,
    },
    Group {
        title: "Splitting by brightness",
        name: "split-by",
        intro: "`--split-by brightness`: the paths per camera collision set per pixel from a low-resolution pilot render, more where the scattered light is brighter, `--split` on average over the smoke; against the same number everywhere (`uniform`, the default). Measured on the dense demo scene, where the scattered light varies most across the image.",
        base: Base::Demo,
        method: "line-fnee",
        variants: &[
            ("uniform (default)", "--split-by uniform", "[integrator]\nsplit_by = \"uniform\""),
            ("brightness", "--split-by brightness", "[integrator]\nsplit_by = \"brightness\""),
        ],
        shared_reference: true,
    },
    Group {
        title: "Forced camera collisions",
        name: "camera-collision",
        intro: "`--camera-collision`: `analog` lets a camera ray scatter only where its free path ends (the paper's); `forced` (the default) lets every camera ray that meets the smoke scatter, weighted by its collision probability, on the ray-marched camera segment's own walk.",
        base: Base::Kelvin40,
        method: "line-fnee",
        variants: &[
            ("analog", "--camera-collision analog", "[integrator]\ncamera_collision = \"analog\""),
            ("forced (default)", "--camera-collision forced", "[integrator]\ncamera_collision = \"forced\""),
        ],
        shared_reference: true,
    },
    Group {
        title: "Stochastic point lookups",
        name: "point-lookup",
        intro: "`--point-lookup`: what a null-collision walk reads at a point. `exact` interpolates eight voxels at every tentative and emission point; `stochastic` (the default) reads one voxel at a tentative point, picked with its trilinear weight (unbiased: the acceptance test needs only an unbiased density); `stochastic-emission` also picks one voxel's emission at emission points after scattering, which is cheaper but has a heavier tail of single samples.",
        base: Base::Kelvin40,
        method: "line-fnee",
        variants: &[
            ("exact", "--point-lookup exact", "[integrator]\npoint_lookup = \"exact\""),
            ("stochastic (default)", "--point-lookup stochastic", "[integrator]\npoint_lookup = \"stochastic\""),
            ("stochastic-emission", "--point-lookup stochastic-emission", "[integrator]\npoint_lookup = \"stochastic-emission\""),
        ],
        shared_reference: true,
    },
    Group {
        title: "Motion blur",
        name: "motion-blur",
        intro: "The cost of motion blur: the demo scene still, and blurred by its own velocity grid (`--velocity-grid velocity --velocity-scale 8` over the default shutter; the generated explosion carries radial expansion plus curl noise). Blurred segments are tracked by null collisions under majorants dilated by the motion, with a lookup of the advected field at each tentative point. The two images differ, so each has its own reference; efficiency is relative to the still image's.",
        base: Base::Demo,
        method: "line-fnee",
        variants: &[
            ("still", "", ""),
            ("blurred", "--velocity-grid velocity --velocity-scale 8", "[volume]\nvelocity_grid = \"velocity\"\nvelocity_scale = 8.0"),
        ],
        shared_reference: false,
    },
];
