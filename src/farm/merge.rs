//! `plume merge`: assemble the parts of one frame, rendered as pixel crops and sample
//! ranges in separate processes, into the image a single process would have rendered,
//! bit for bit.
//!
//! Parts carry exact integer sums (`film.rs`), so merging is integer addition, which
//! does not depend on order or grouping; the pixel value comes from the same
//! [`pixel_value`] as in the render. Before adding, the parts are checked to be one
//! frame: same plume version, frame, image size, seed, input (SHA-256) and settings
//! hash, all complete; and to cover it exactly once: every pixel must receive
//! non-overlapping sample ranges that join into one contiguous range, the same for every
//! pixel. The check runs on the cells cut by all part edges, so it costs
//! O(parts³) at most, never O(pixels × parts).

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;
use std::time::Instant;

use crate::farm::layers::{beauty_and_layers, FrameSums, Written};
use crate::farm::part::{read_part, Completion, PartInfo};
use crate::output::{write_exr_image, AovChannels, ExactSums, ExrImage};
use plume_core::error::{Error, Result};
use plume_engine::film::{pixel_value, Crop, Moments, FIXED_POINT_BITS};
use plume_engine::integrator::AovLayout;
use plume_engine::noise::FrameNoise;
use plume_scene::split::format_range;

/// A merged frame.
#[derive(Debug)]
pub struct Merged {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples every pixel holds.
    pub samples: Range<u64>,
    /// Exact sums, row-major over the whole image.
    pub sums: Vec<[i128; 4]>,
    /// The pixels' moments (squared sums and sample counts), row-major.
    pub moments: Vec<Moments>,
    /// Sums clamped while adding parts (0 unless the image is beyond the fixed-point range).
    pub saturated: u64,
    /// AOV channel names and their exact sums (`names.len()` per pixel, row-major), when
    /// the parts have AOVs.
    pub aovs: Option<(Vec<String>, Vec<i128>)>,
}

impl Merged {
    /// The pixels: [`pixel_value`] of every sum over the pixel's sample count.
    #[must_use]
    pub fn pixels(&self) -> Vec<[f32; 4]> {
        self.sums
            .iter()
            .zip(&self.moments)
            .map(|(s, m)| s.map(|v| pixel_value(v, m.count)))
            .collect()
    }
}

/// Check that `parts` are one frame and cover it exactly once (see the module docs).
///
/// # Errors
/// [`Error::InvalidPart`] naming the part (and the other part) at fault, or
/// [`Error::Scene`] naming pixels that no part covers.
pub fn check_parts(parts: &[PartInfo]) -> Result<Range<u64>> {
    let first = parts.first().ok_or_else(|| Error::invalid("PARTS", "no parts given"))?;
    for p in parts {
        check_same_frame(p, first)?;
    }
    let (w, h) = (first.width, first.height);
    let xs = cell_edges(parts, &|c| [c.x0, c.x1], w);
    let ys = cell_edges(parts, &|c| [c.y0, c.y1], h);
    let mut union: Option<(Range<u64>, Crop)> = None;
    for yj in ys.windows(2) {
        for xi in xs.windows(2) {
            let cell = Crop { x0: xi[0], y0: yj[0], x1: xi[1], y1: yj[1] };
            let here = cell_samples(parts, cell, (w, h))?;
            match &union {
                None => union = Some((here, cell)),
                Some((u, at)) if *u != here => {
                    return Err(Error::Scene(format!(
                        "pixels {cell} have samples {}, but pixels {at} have {}",
                        format_range(&here),
                        format_range(u)
                    )));
                }
                Some(_) => {}
            }
        }
    }
    Ok(union.expect("invariant: the image has at least one cell").0)
}

/// Check that part `p` is complete, in this plume's fixed point, and of the same frame as
/// `first`: plume version, frame, image size, seed, input and settings hash.
///
/// # Errors
/// [`Error::InvalidPart`] naming `p` (and `first`, for a difference).
fn check_same_frame(p: &PartInfo, first: &PartInfo) -> Result<()> {
    let bad = |message: String| Error::InvalidPart { path: p.path.clone(), message };
    if p.fixed_point_bits != FIXED_POINT_BITS {
        return Err(bad(format!(
            "holds sums in units of 2^-{}; this plume uses 2^-{FIXED_POINT_BITS}",
            p.fixed_point_bits
        )));
    }
    if p.status != Completion::Complete {
        return Err(bad(format!(
            "is {} with samples {}; run its command again to finish it",
            p.status.as_str(),
            format_range(&p.samples)
        )));
    }
    let differs = |what: &str, mine: String, theirs: String| {
        bad(format!("{what} is {mine}, but {} has {theirs}", first.path.display()))
    };
    if p.version != first.version {
        return Err(differs("the plume version", p.version.clone(), first.version.clone()));
    }
    if p.frame != first.frame {
        return Err(differs("the frame", format!("{:?}", p.frame), format!("{:?}", first.frame)));
    }
    if (p.width, p.height) != (first.width, first.height) {
        return Err(differs(
            "the image size",
            format!("{}x{}", p.width, p.height),
            format!("{}x{}", first.width, first.height),
        ));
    }
    if p.seed != first.seed {
        return Err(differs("the seed", p.seed.to_string(), first.seed.to_string()));
    }
    if p.input_sha256 != first.input_sha256 {
        return Err(differs(
            "the input (SHA-256)",
            format!("{} ({})", p.input, p.input_sha256),
            format!("{} ({})", first.input, first.input_sha256),
        ));
    }
    if p.settings_hash != first.settings_hash {
        return Err(differs(
            "the settings hash",
            p.settings_hash.clone(),
            format!("{} (rendered with other flags)", first.settings_hash),
        ));
    }
    Ok(())
}

/// The sorted, distinct edges along one axis (`axis` picks a crop's two) of all parts'
/// crops and of the image (`0` and `size`): the cells between them are covered by whole
/// parts.
fn cell_edges(parts: &[PartInfo], axis: &dyn Fn(&Crop) -> [u32; 2], size: u32) -> Vec<u32> {
    let mut v: Vec<u32> = parts.iter().flat_map(|p| axis(&p.crop)).chain([0, size]).collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// The samples the pixels of `cell` (of an image of `size`) receive: the parts covering
/// it must hold non-overlapping sample ranges that join into one contiguous range.
///
/// # Errors
/// [`Error::Scene`] when no part covers the cell or a sample range is missing,
/// [`Error::InvalidPart`] naming a part whose samples overlap another's.
fn cell_samples(parts: &[PartInfo], cell: Crop, size: (u32, u32)) -> Result<Range<u64>> {
    let (w, h) = size;
    let mut covering: Vec<&PartInfo> = parts.iter().filter(|p| p.crop.contains(&cell)).collect();
    if covering.is_empty() {
        return Err(Error::Scene(format!("no part covers pixels {cell} of the {w}x{h} image")));
    }
    covering.sort_by_key(|p| (p.samples.start, p.samples.end));
    for pair in covering.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        if a.samples.end > b.samples.start {
            return Err(Error::InvalidPart {
                path: b.path.clone(),
                message: format!(
                    "samples {} of pixels {cell} overlap samples {} of {}",
                    format_range(&b.samples),
                    format_range(&a.samples),
                    a.path.display()
                ),
            });
        }
        if a.samples.end < b.samples.start {
            return Err(Error::Scene(format!(
                "no part holds samples {}..{} of pixels {cell}",
                a.samples.end, b.samples.start
            )));
        }
    }
    Ok(covering[0].samples.start..covering[covering.len() - 1].samples.end)
}

/// Add the parts' sums into one image after [`check_parts`].
///
/// # Errors
/// As [`check_parts`]; [`Error::InvalidPart`] for a part without exact sums.
pub fn merge_parts(parts: &[(PartInfo, crate::output::ExrContents)]) -> Result<Merged> {
    for (p, c) in parts {
        if c.sums.is_none() {
            return Err(Error::InvalidPart {
                path: p.path.clone(),
                message: "has no exact sums; render parts with farm.crop, farm.tile, farm.sample_range or output.sums".into(),
            });
        }
    }
    let infos: Vec<PartInfo> = parts.iter().map(|(p, _)| p.clone()).collect();
    let samples = check_parts(&infos)?;
    let (w, h) = (infos[0].width, infos[0].height);
    // AOVs: every part has the same channels (the settings hash says whether there are
    // AOVs and which light groups), or none has
    let aov_names = parts[0].1.aov_sums.as_ref().map(|(n, _)| n.clone());
    for (p, c) in parts {
        if c.aov_sums.as_ref().map(|(n, _)| n) != aov_names.as_ref() {
            return Err(Error::InvalidPart {
                path: p.path.clone(),
                message: format!("has other AOV sums than {}", parts[0].0.path.display()),
            });
        }
    }
    let mut sums = vec![[0i128; 4]; w as usize * h as usize];
    let mut moments = vec![Moments::default(); w as usize * h as usize];
    let k = aov_names.as_ref().map_or(0, Vec::len);
    let mut aov = vec![0i128; w as usize * h as usize * k];
    let mut saturated = 0u64;
    let mut add = |d: &mut i128, s: i128| {
        *d = d.checked_add(s).unwrap_or_else(|| {
            saturated += 1;
            if s < 0 {
                i128::MIN
            } else {
                i128::MAX
            }
        });
    };
    for (p, c) in parts {
        let part = c.sums.as_ref().expect("invariant: checked above");
        let cw = p.crop.width() as usize;
        for y in p.crop.y0..p.crop.y1 {
            for x in p.crop.x0..p.crop.x1 {
                let src = (y - p.crop.y0) as usize * cw + (x - p.crop.x0) as usize;
                let dst = y as usize * w as usize + x as usize;
                for (d, s) in sums[dst].iter_mut().zip(part.rgba[src]) {
                    add(d, s);
                }
                moments[dst] = moments[dst].plus(part.moments[src]);
                if let Some((_, part_aov)) = &c.aov_sums {
                    for (d, s) in aov[dst * k..(dst + 1) * k]
                        .iter_mut()
                        .zip(&part_aov[src * k..(src + 1) * k])
                    {
                        add(d, *s);
                    }
                }
            }
        }
    }
    Ok(Merged {
        width: w,
        height: h,
        samples,
        sums,
        moments,
        saturated,
        aovs: aov_names.map(|n| (n, aov)),
    })
}

/// Header keys of a part that describe only that part's process, not the merged image.
const PER_PROCESS_KEYS: [&str; 9] = [
    "plume:counters",
    "plume:samplesPerSecond",
    "plume:samplesPerCpuSecond",
    "plume:peakRssBytes",
    "plume:renderSeconds",
    "plume:timeToFirstSampleSeconds",
    "plume:threads",
    "plume:resumedFromSpp",
    "plume:volumeBytes",
];

/// What `plume merge` is asked to do.
#[derive(Clone, Debug)]
pub struct MergeOptions {
    /// Parts of one frame (EXRs with exact sums).
    pub parts: Vec<std::path::PathBuf>,
    /// The merged EXR.
    pub output: std::path::PathBuf,
    /// Keep the exact sums in the output.
    pub sums: bool,
    /// A tone-mapped sRGB PNG preview.
    pub preview: Option<std::path::PathBuf>,
    /// Preview exposure in stops (default: automatic).
    pub exposure: Option<f32>,
    /// No summary.
    pub quiet: bool,
    /// The directory relative paths are relative to: the merged frame's scene description
    /// has its paths made absolute against it.
    pub working_dir: std::path::PathBuf,
}

/// Run `plume merge`.
///
/// # Errors
/// A missing part ([`Error::Open`]), an invalid or inconsistent one, or the output.
pub fn merge_command(args: &MergeOptions, command_line: &str) -> Result<()> {
    let start = Instant::now();
    if !args.output.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
        return Err(Error::invalid(
            "--output",
            format!("{} must end in .exr", args.output.display()),
        ));
    }
    for path in std::iter::once(&args.output).chain(args.preview.iter()) {
        plume_core::fs::check_writable(path)?;
    }
    let parts = args.parts.iter().map(|p| read_part(p)).collect::<Result<Vec<_>>>()?;
    let merged = merge_parts(&parts)?;
    let full = Crop::full(merged.width, merged.height);
    let noise = FrameNoise::of(&merged.sums, &merged.moments, full, noise_floor(&parts));
    let metadata =
        merged_metadata(&parts, &merged, &noise, &args.output, command_line, &args.working_dir);
    let layout = merged.aovs.as_ref().and_then(|(names, _)| AovLayout::from_channel_names(names));
    // Parts rendered with --denoise carry the half sums: the merged frame is denoised as
    // the single render would be
    let aov_sums = merged.aovs.as_ref().map_or(&[][..], |(_, sums)| sums.as_slice());
    let frame_sums = FrameSums { rgba: &merged.sums, moments: &merged.moments, aov: aov_sums };
    let Written { pixels, layers, .. } =
        beauty_and_layers(layout.as_ref(), frame_sums, merged.pixels(), &noise.errors, full);
    let aovs = Some(AovChannels {
        layers: &layers,
        sums: merged
            .aovs
            .as_ref()
            .filter(|_| layout.is_some() && args.sums)
            .map(|(names, sums)| (names.as_slice(), sums.as_slice())),
    });
    let image = ExrImage {
        width: merged.width,
        height: merged.height,
        crop: full,
        pixels: &pixels,
        sums: args.sums.then_some(ExactSums { rgba: &merged.sums, moments: &merged.moments }),
        aovs,
        metadata: &metadata,
    };
    write_exr_image(&args.output, &image)?;
    if let Some(p) = &args.preview {
        let exposure =
            args.exposure.map_or_else(|| crate::output::auto_exposure(&pixels), |ev| 2f32.powf(ev));
        crate::output::write_png(p, merged.width, merged.height, &pixels, exposure)?;
    }
    if merged.saturated > 0 {
        log::warn!("{} sums exceeded the fixed-point range and were clamped; this image may differ from a single render", merged.saturated);
    }
    if !args.quiet {
        log::info!(
            "merged {} parts into {} ({}x{}, samples {}) in {:.2} s",
            parts.len(),
            args.output.display(),
            merged.width,
            merged.height,
            format_range(&merged.samples),
            start.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// The noise floor the parts were rendered with (their error estimate's), for the merged
/// image's estimate.
fn noise_floor(parts: &[(PartInfo, crate::output::ExrContents)]) -> f64 {
    parts[0]
        .1
        .metadata
        .get("plume:errorEstimate")
        .and_then(|t| serde_json::from_str::<serde_json::Value>(t).ok())
        .and_then(|v| v.get("floor")?.as_f64())
        .filter(|f| f.is_finite() && *f > 0.0)
        .unwrap_or(plume_engine::noise::DEFAULT_FLOOR)
}

/// The merged image's header: the first part's record without per-process figures, with
/// the merged sample range and crop, costs summed over the parts, and this command.
fn merged_metadata(
    parts: &[(PartInfo, crate::output::ExrContents)],
    merged: &Merged,
    noise: &FrameNoise,
    output: &Path,
    command_line: &str,
    working_dir: &Path,
) -> Vec<(String, String)> {
    let mut m: BTreeMap<String, String> = parts[0].1.metadata.clone();
    // (The AOV sums' channel order is written with the sums, if they are kept)
    m.retain(|k, _| {
        k.starts_with("plume:")
            && !PER_PROCESS_KEYS.contains(&k.as_str())
            && k != crate::output::AOV_CHANNELS_ATTRIBUTE
    });
    let sum_f = |key: &str| {
        parts
            .iter()
            .filter_map(|(_, c)| c.metadata.get(key).and_then(|v| v.parse::<f64>().ok()))
            .sum::<f64>()
    };
    let sum_u = |key: &str| {
        parts
            .iter()
            .filter_map(|(_, c)| c.metadata.get(key).and_then(|v| v.parse::<u64>().ok()))
            .sum::<u64>()
    };
    let spp = merged.samples.end - merged.samples.start;
    let cpu = sum_f("plume:cpuSeconds");
    let set: [(&str, String); 16] = [
        (
            "plume:errorEstimate",
            serde_json::to_string(&noise.estimate).expect("invariant: serializes"),
        ),
        (
            "plume:sppHistogram",
            serde_json::to_string(&noise.histogram).expect("invariant: serializes"),
        ),
        ("plume:commandLine", command_line.to_string()),
        ("plume:host", plume_core::fs::host_name()),
        ("plume:output", output.display().to_string()),
        ("plume:status", Completion::Complete.as_str().into()),
        ("plume:spp", spp.to_string()),
        ("plume:sampleRange", format_range(&merged.samples)),
        ("plume:crop", Crop::full(merged.width, merged.height).to_string()),
        ("plume:mergedParts", parts.len().to_string()),
        ("plume:wallSeconds", format!("{}", sum_f("plume:wallSeconds"))),
        ("plume:cpuSeconds", format!("{cpu}")),
        ("plume:coreHours", format!("{}", cpu / 3600.0)),
        ("plume:allocatedCoreHours", format!("{}", sum_f("plume:allocatedCoreHours"))),
        (
            "plume:saturatedSamples",
            (sum_u("plume:saturatedSamples") + merged.saturated).to_string(),
        ),
        ("plume:underflowedSamples", sum_u("plume:underflowedSamples").to_string()),
    ];
    for (k, v) in set {
        m.insert(k.to_string(), v);
    }
    // The scene that made the parts, as the merged frame: the whole image, all samples
    if let Some(scene) =
        m.get("plume:scene").and_then(|t| merged_scene(t, merged, output, working_dir))
    {
        m.insert("plume:scene".into(), scene);
    }
    m.into_iter().collect()
}

/// The first part's scene file (`plume:scene`) rewritten for the merged frame: no crop,
/// tile or sample range, the merged sample count and output. `None` when it does not
/// parse (an older plume's part); the part's text is kept then.
fn merged_scene(
    part_scene: &str,
    merged: &Merged,
    output: &Path,
    working_dir: &Path,
) -> Option<String> {
    let mut shot: plume_scene::Shot = toml::from_str(part_scene).ok()?;
    let farm = &mut shot.settings.farm;
    (farm.crop, farm.tile) = (None, None);
    let first = merged.samples.start;
    farm.sample_range = (first != 0).then(|| merged.samples.clone());
    shot.settings.render.spp =
        (first == 0).then(|| u32::try_from(merged.samples.end).ok()).flatten();
    shot.settings.render.time = None;
    shot.settings.output.image = output.to_path_buf();
    plume_scene::file::to_toml(&shot, working_dir).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn part(name: &str, crop: Crop, samples: Range<u64>) -> PartInfo {
        PartInfo {
            path: PathBuf::from(name),
            version: "v".into(),
            frame: Some(1),
            width: 10,
            height: 8,
            crop,
            samples,
            seed: 1,
            settings_hash: "h".into(),
            input_sha256: "s".into(),
            input: "in.vdb".into(),
            status: Completion::Complete,
            fixed_point_bits: FIXED_POINT_BITS,
            estimator: "Line".into(),
            cpu_seconds: 0.0,
            wall_seconds: 0.0,
            allocated_core_hours: 0.0,
        }
    }

    fn c(x0: u32, y0: u32, x1: u32, y1: u32) -> Crop {
        Crop { x0, y0, x1, y1 }
    }

    #[test]
    fn accepts_tiles_times_sample_ranges_and_mixed_splits() {
        let left = c(0, 0, 4, 8);
        let right = c(4, 0, 10, 8);
        let ok = [part("a", left, 0..5), part("b", left, 5..9), part("c", right, 0..9)];
        assert_eq!(check_parts(&ok).unwrap(), 0..9);
        // A full-image first range, then tiles for the rest
        let mixed =
            [part("a", c(0, 0, 10, 8), 0..4), part("b", left, 4..9), part("c", right, 4..9)];
        assert_eq!(check_parts(&mixed).unwrap(), 0..9);
    }

    #[test]
    fn rejects_overlaps_gaps_holes_and_disagreements() {
        let left = c(0, 0, 4, 8);
        let right = c(4, 0, 10, 8);
        let msg = |parts: &[PartInfo]| check_parts(parts).unwrap_err().to_string();
        assert!(msg(&[part("a", left, 0..5), part("b", left, 4..9), part("c", right, 0..9)])
            .contains("overlap"));
        assert!(
            msg(&[part("a", c(0, 0, 5, 8), 0..9), part("b", right, 0..9)]).contains("overlap"),
            "overlapping tiles"
        );
        assert!(msg(&[part("a", left, 0..4), part("b", left, 5..9), part("c", right, 0..9)])
            .contains("samples 4..5"));
        assert!(msg(&[part("a", left, 0..9), part("c", c(4, 0, 10, 7), 0..9)])
            .contains("no part covers pixels 4,7,10,8"));
        assert!(msg(&[part("a", left, 0..9), part("c", right, 0..8)]).contains("have samples"));
        let mut other = part("b", right, 0..9);
        other.settings_hash = "x".into();
        assert!(msg(&[part("a", left, 0..9), other]).contains("settings hash"));
        let mut other = part("b", right, 0..9);
        other.seed = 2;
        assert!(msg(&[part("a", left, 0..9), other]).contains("seed"));
        let mut other = part("b", right, 0..9);
        other.status = Completion::Interrupted;
        assert!(msg(&[part("a", left, 0..9), other]).contains("interrupted"));
    }
}
