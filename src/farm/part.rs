//! What an output EXR says about itself: the frame record as `plume:*` header attributes,
//! read back as a [`PartInfo`] to merge parts, skip complete outputs and continue
//! interrupted ones.

use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::output::{read_exr_contents, ExrContents};
use plume_core::error::{Error, Result};
use plume_engine::film::Crop;
use plume_engine::stats::RenderStats;

/// How far a frame (or part) got.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Completion {
    /// The whole sample budget was rendered.
    Complete,
    /// Stopped by SIGTERM/SIGINT; holds the samples rendered so far.
    Interrupted,
    /// Stopped by `--time-limit`; holds the samples rendered so far.
    TimeLimit,
}

impl Completion {
    /// `complete`, `interrupted` or `time-limit`, as written in headers and stats.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Completion::Complete => "complete",
            Completion::Interrupted => "interrupted",
            Completion::TimeLimit => "time-limit",
        }
    }

    fn parse(s: &str) -> Option<Completion> {
        [Completion::Complete, Completion::Interrupted, Completion::TimeLimit]
            .into_iter()
            .find(|c| c.as_str() == s)
    }
}

/// The header attributes of a frame record: every field of `stats` as
/// `plume:<camelCaseName>` (`plume:version` for the version), text values as is, others
/// as JSON.
#[must_use]
pub fn stats_metadata(stats: &RenderStats) -> Vec<(String, String)> {
    let value = serde_json::to_value(stats).expect("invariant: stats serialize");
    let serde_json::Value::Object(map) = value else {
        unreachable!("invariant: stats is a struct")
    };
    let mut out = Vec::with_capacity(map.len());
    for (k, v) in map {
        let key = if k == "plume_version" {
            "plume:version".to_string()
        } else {
            format!("plume:{}", camel_case(&k))
        };
        match v {
            serde_json::Value::Null => {}
            serde_json::Value::String(s) => out.push((key, s)),
            other => out.push((key, other.to_string())),
        }
    }
    out
}

fn camel_case(snake: &str) -> String {
    let mut out = String::with_capacity(snake.len());
    let mut upper = false;
    for c in snake.chars() {
        if c == '_' {
            upper = true;
        } else if upper {
            out.push(c.to_ascii_uppercase());
            upper = false;
        } else {
            out.push(c);
        }
    }
    out
}

/// What a plume EXR says about the pixels it holds.
#[derive(Clone, Debug)]
pub struct PartInfo {
    /// The file.
    pub path: PathBuf,
    /// plume version that rendered it.
    pub version: String,
    /// Frame number, if rendered with `--frames`.
    pub frame: Option<i64>,
    /// Full image width.
    pub width: u32,
    /// Full image height.
    pub height: u32,
    /// Pixels present.
    pub crop: Crop,
    /// Sample indices summed.
    pub samples: Range<u64>,
    /// Seed.
    pub seed: u64,
    /// `farm::fingerprint::settings_hash`.
    pub settings_hash: String,
    /// SHA-256 of the input.
    pub input_sha256: String,
    /// Input path as given to the render.
    pub input: String,
    /// How far it got.
    pub status: Completion,
    /// F of the sums.
    pub fixed_point_bits: u32,
    /// Estimator name.
    pub estimator: String,
    /// Cost of rendering it: CPU seconds.
    pub cpu_seconds: f64,
    /// Cost of rendering it: wall seconds.
    pub wall_seconds: f64,
    /// Cost of rendering it: allocated core-hours.
    pub allocated_core_hours: f64,
}

impl PartInfo {
    /// Read the record from decoded EXR contents.
    ///
    /// # Errors
    /// [`Error::InvalidPart`] naming the missing or malformed attribute.
    pub fn from_contents(path: &Path, c: &ExrContents) -> Result<PartInfo> {
        let m = &c.metadata;
        let bad = |message: String| Error::InvalidPart { path: path.to_path_buf(), message };
        let get = |k: &str| {
            m.get(&format!("plume:{k}"))
                .map(String::as_str)
                .ok_or_else(|| bad(format!("no plume:{k} attribute (not rendered by this plume?)")))
        };
        let num = |k: &str| {
            get(k).and_then(|v| {
                v.parse::<u64>().map_err(|_| bad(format!("plume:{k} = {v:?} is not a number")))
            })
        };
        let real = |k: &str| {
            m.get(&format!("plume:{k}")).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0)
        };
        let spp = num("spp")?;
        let samples = match m.get("plume:sampleRange") {
            Some(r) => plume_scene::split::parse_sample_range(r)
                .map_err(|e| bad(format!("plume:sampleRange: {e}")))?,
            None => 0..spp,
        };
        if samples.end - samples.start != spp {
            return Err(bad(format!(
                "plume:spp {spp} disagrees with plume:sampleRange {}",
                plume_scene::split::format_range(&samples)
            )));
        }
        let status = Completion::parse(get("status")?)
            .ok_or_else(|| bad("plume:status is not complete, interrupted or time-limit".into()))?;
        Ok(PartInfo {
            path: path.to_path_buf(),
            version: get("version")?.to_string(),
            frame: m.get("plume:frame").and_then(|f| f.parse().ok()),
            width: c.width,
            height: c.height,
            crop: c.crop,
            samples,
            seed: num("seed")?,
            settings_hash: get("settingsHash")?.to_string(),
            input_sha256: get("inputSha256")?.to_string(),
            input: m.get("plume:input").cloned().unwrap_or_default(),
            status,
            fixed_point_bits: u32::try_from(num("fixedPointBits")?)
                .map_err(|_| bad("plume:fixedPointBits out of range".into()))?,
            estimator: m.get("plume:estimator").cloned().unwrap_or_default(),
            cpu_seconds: real("cpuSeconds"),
            wall_seconds: real("wallSeconds"),
            allocated_core_hours: real("allocatedCoreHours"),
        })
    }
}

/// Read and fully decode a part: its record and its pixels and sums.
///
/// # Errors
/// [`Error::InvalidPart`] if the file is unreadable, truncated or lacks plume's record;
/// [`Error::Open`] if it does not exist.
pub fn read_part(path: &Path) -> Result<(PartInfo, ExrContents)> {
    if let Err(source) = std::fs::metadata(path) {
        return Err(Error::Open { path: path.to_path_buf(), source });
    }
    let contents = read_exr_contents(path)
        .map_err(|e| Error::InvalidPart { path: path.to_path_buf(), message: e.to_string() })?;
    let info = PartInfo::from_contents(path, &contents)?;
    Ok((info, contents))
}

/// What the render of a frame expects its output to hold.
#[derive(Clone, Debug)]
pub struct Expected {
    /// `settings_hash` of this run.
    pub settings_hash: String,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Pixels rendered.
    pub crop: Crop,
    /// Samples asked for; `None` for a `--time` budget (any count is complete).
    pub samples: Option<Range<u64>>,
    /// AOV channels per pixel, with `--aovs`.
    pub aov_channels: Option<usize>,
}

/// An output that exists already, judged against what this run would write.
#[derive(Debug)]
pub enum Existing {
    /// No file.
    Missing,
    /// Complete, with the same settings and samples: skip the frame.
    Complete(PartInfo),
    /// The same settings with exact sums and fewer samples than asked (an interrupted or
    /// time-limited render, or a smaller budget rendered with `--sums`): continue it (if
    /// the input is unchanged).
    Resumable(PartInfo, crate::output::OwnedSums, Option<Vec<i128>>),
    /// Anything else (unreadable, truncated, other settings): render anew; the reason.
    Stale(String),
}

/// Judge the file at `path` (which must be fully readable to count).
#[must_use]
pub fn assess(path: &Path, expected: &Expected) -> Existing {
    if !path.exists() {
        return Existing::Missing;
    }
    let (info, contents) = match read_part(path) {
        Ok(p) => p,
        Err(e) => return Existing::Stale(format!("not a valid plume image ({e})")),
    };
    if info.settings_hash != expected.settings_hash {
        return Existing::Stale("rendered with other settings or seed".into());
    }
    if (info.width, info.height, info.crop) != (expected.width, expected.height, expected.crop) {
        return Existing::Stale(format!(
            "holds pixels {} of {}x{}, not {} of {}x{}",
            info.crop, info.width, info.height, expected.crop, expected.width, expected.height
        ));
    }
    let range = plume_scene::split::format_range;
    let Some(r) = &expected.samples else {
        // A --time budget: any complete image will do; a partial one cannot be continued
        return match info.status {
            Completion::Complete => Existing::Complete(info),
            status => Existing::Stale(format!(
                "{} and a render.time budget cannot be continued",
                status.as_str()
            )),
        };
    };
    if info.status == Completion::Complete && info.samples == *r {
        Existing::Complete(info)
    } else if info.samples.start == r.start && info.samples.end < r.end {
        // Fewer samples than asked (interrupted, time-limited, or a smaller budget
        // rendered with --sums): continue from the exact sums
        // (With AOVs, their sums too: the settings hash says whether there are AOVs)
        match (contents.sums, contents.aov_sums, expected.aov_channels) {
            (Some(sums), _, None) => Existing::Resumable(info, sums, None),
            (Some(sums), Some((names, aov)), Some(n)) if names.len() == n => {
                Existing::Resumable(info, sums, Some(aov))
            }
            (Some(_), _, Some(_)) => Existing::Stale(format!(
                "holds samples {} without exact AOV sums",
                range(&info.samples)
            )),
            (None, ..) => Existing::Stale(format!(
                "holds samples {} without exact sums (output.sums), not {}",
                range(&info.samples),
                range(r)
            )),
        }
    } else {
        Existing::Stale(format!(
            "{} with samples {}, not {}",
            info.status.as_str(),
            range(&info.samples),
            range(r)
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camel_case_keys() {
        assert_eq!(camel_case("input_sha256"), "inputSha256");
        assert_eq!(camel_case("spp"), "spp");
        assert_eq!(camel_case("time_to_first_sample_seconds"), "timeToFirstSampleSeconds");
        assert_eq!(Completion::parse("time-limit"), Some(Completion::TimeLimit));
    }
}
