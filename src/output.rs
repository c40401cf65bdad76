//! Image outputs: float EXR with metadata (and, for parts of a split frame, the exact
//! sample sums as `u32` channels) and a tone-mapped PNG preview, all written atomically
//! (temporary file in the same directory, synced, then renamed), so a reader never sees
//! a half-written file, even if plume is killed mid-write.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::film::Crop;

/// A temporary file that is removed when dropped (on every error path, and when a panic
/// unwinds), unless [`TemporaryFile::keep`] was called once it has been renamed into
/// place.
pub(crate) struct TemporaryFile {
    path: Option<PathBuf>,
}

impl TemporaryFile {
    /// Take charge of `path` (created or about to be).
    pub(crate) fn new(path: PathBuf) -> TemporaryFile {
        TemporaryFile { path: Some(path) }
    }

    /// The file has been renamed into place: leave it alone.
    pub(crate) fn keep(mut self) {
        self.path = None;
    }
}

impl Drop for TemporaryFile {
    fn drop(&mut self) {
        if let Some(p) = self.path.take() {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Write a file atomically: `write` fills a temporary file beside `path`, which is
/// synced and renamed over `path` only if everything succeeded.
///
/// # Errors
/// [`Error::Write`] naming `path` if the directory is not writable or writing fails (a
/// full disk included); the temporary file is removed and `path` is left as it was.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>) -> Result<()> {
    if path.file_name().is_none() {
        return Err(Error::Write { path: path.to_path_buf(), source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file name") });
    }
    let tmp = temporary_path(path);
    let result = (|| {
        let file = File::create(&tmp)?;
        let temporary = TemporaryFile::new(tmp.clone());
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        w.flush()?;
        w.get_ref().sync_all()?;
        drop(w);
        std::fs::rename(&tmp, path)?;
        temporary.keep();
        // Make the rename itself durable (a crash of the machine, not only of plume)
        if let Ok(d) = File::open(parent_dir(path)) {
            let _ = d.sync_all();
        }
        Ok(())
    })();
    result.map_err(|source| Error::Write { path: path.to_path_buf(), source })
}

/// Append `line` and a newline to `path` (created if missing) with one `write`, so that
/// lines of processes appending to the same local file do not interleave, and a killed
/// process leaves whole lines. (On NFS, `O_APPEND` is not atomic between hosts: give
/// each task its own file, e.g. with a frame token.)
///
/// A write that fails part-way (a full disk takes what fits, then refuses the rest) is
/// undone: the file is cut back to where this line began, as long as nothing was appended
/// after it, and a file this call created is removed again. The file then holds exactly
/// its earlier lines.
///
/// # Errors
/// [`Error::Write`] naming `path`.
pub fn append_line(path: &Path, line: &str) -> Result<()> {
    use std::io::Seek as _;
    let mut text = String::with_capacity(line.len() + 1);
    text.push_str(line);
    text.push('\n');
    let fail = |source| Error::Write { path: path.to_path_buf(), source };
    let open = |new: bool| std::fs::OpenOptions::new().append(true).create_new(new).open(path);
    let (mut f, created) = match open(true) {
        Ok(f) => (f, true),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => (open(false).map_err(fail)?, false),
        Err(e) => return Err(fail(e)),
    };
    let mut written = 0;
    let result = (|| {
        while written < text.len() {
            match f.write(&text.as_bytes()[written..]) {
                Ok(0) => return Err(std::io::Error::from(std::io::ErrorKind::WriteZero)),
                Ok(n) => written += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        f.sync_data()
    })();
    if let Err(e) = result {
        // With O_APPEND the offset is the end of this process's last write
        let end = f.stream_position().ok();
        let start = end.and_then(|end| end.checked_sub(written as u64));
        let len = f.metadata().map(|m| m.len()).ok();
        if let Some(start) = start.filter(|_| written > 0 && end == len) {
            let _ = f.set_len(start);
        }
        if created && f.metadata().is_ok_and(|m| m.len() == 0) {
            let _ = std::fs::remove_file(path);
        }
        return Err(fail(e));
    }
    Ok(())
}

/// Check, before any expensive work, that `path` can be written: its directory exists and
/// accepts a new file. Creates and removes a probe file named like the temporaries, so a
/// probe left by a killed process is cleaned up by [`remove_stale_temporaries`].
///
/// # Errors
/// [`Error::Write`] naming `path`.
pub fn check_writable(path: &Path) -> Result<()> {
    let probe = temporary_path(path);
    File::create(&probe).and_then(|_| std::fs::remove_file(&probe)).map_err(|source| Error::Write { path: path.to_path_buf(), source })
}

/// Write `pixels` (row-major RGBA, linear) as a 32-bit float EXR with text attributes
/// `metadata` (name, value), atomically.
///
/// # Errors
/// [`Error::Write`] naming `path`.
pub fn write_exr(path: &Path, width: u32, height: u32, pixels: &[[f32; 4]], metadata: &[(String, String)]) -> Result<()> {
    write_exr_image(path, &ExrImage { width, height, crop: Crop::full(width, height), pixels, sums: None, aovs: None, metadata })
}

/// Names of the 16 `u32` channels that hold a pixel's exact `i128` sums: `sum.{R,G,B,A}.w{0..3}`,
/// 32-bit words, least significant first (two's complement).
#[must_use]
pub fn sum_channel_names() -> Vec<String> {
    let mut names = Vec::with_capacity(16);
    for c in ["R", "G", "B", "A"] {
        for w in 0..4 {
            names.push(format!("sum.{c}.w{w}"));
        }
    }
    names
}

/// An image to write: RGBA for the pixels of `crop` of a `width × height` image (the EXR
/// data window is the crop, the display window the image), optionally with exact sums.
pub struct ExrImage<'a> {
    /// Full image width (display window).
    pub width: u32,
    /// Full image height (display window).
    pub height: u32,
    /// The pixels present (data window).
    pub crop: Crop,
    /// Row-major RGBA over `crop`.
    pub pixels: &'a [[f32; 4]],
    /// Exact fixed-point sums over `crop` (`film.rs`), stored as 16 `u32` channels.
    pub sums: Option<&'a [[i128; 4]]>,
    /// AOV layers, if any.
    pub aovs: Option<AovChannels<'a>>,
    /// Text attributes (name, value); non-ASCII characters become `?`.
    pub metadata: &'a [(String, String)],
}

/// AOV layers to write (`integrator::aov`): `f32` channels, and optionally their exact
/// sums (`sum.<channel>.w0..3`), whose channel order is recorded in the attribute
/// `plume:aov_channels`.
pub struct AovChannels<'a> {
    /// `(name, values)`: `emission.R`, …, `alpha.A`, `depth.Z`, each row-major over the crop.
    pub layers: &'a [(String, Vec<f32>)],
    /// The summed channels' names and their sums, `names.len()` per pixel.
    pub sums: Option<(&'a [String], &'a [i128])>,
}

/// The attribute holding the order of the AOV sum channels.
pub const AOV_CHANNELS_ATTRIBUTE: &str = "plume:aov_channels";

/// Write `image` as an EXR, atomically.
///
/// # Errors
/// [`Error::Write`] naming `path`.
///
/// # Panics
/// If the pixel or sum count does not match the crop.
pub fn write_exr_image(path: &Path, image: &ExrImage<'_>) -> Result<()> {
    use exr::prelude::*;
    let n = image.crop.area() as usize;
    assert_eq!(image.pixels.len(), n, "invariant: one pixel per crop pixel");
    let mut list: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for (c, name) in ["R", "G", "B", "A"].iter().enumerate() {
        list.push(AnyChannel::new(*name, FlatSamples::F32(image.pixels.iter().map(|p| p[c]).collect())));
    }
    if let Some(sums) = image.sums {
        assert_eq!(sums.len(), n, "invariant: one sum per crop pixel");
        let names = sum_channel_names();
        for c in 0..4 {
            for w in 0..4 {
                let words = sums.iter().map(|s| ((s[c] as u128) >> (32 * w)) as u32).collect();
                list.push(AnyChannel::new(names[c * 4 + w].as_str(), FlatSamples::U32(words)));
            }
        }
    }
    let mut aov_order = None;
    if let Some(aovs) = &image.aovs {
        for (name, values) in aovs.layers {
            assert_eq!(values.len(), n, "invariant: one AOV value per crop pixel");
            list.push(AnyChannel::new(name.as_str(), FlatSamples::F32(values.clone())));
        }
        if let Some((names, sums)) = aovs.sums {
            let k = names.len();
            assert_eq!(sums.len(), n * k, "invariant: one sum per AOV channel and crop pixel");
            for (c, name) in names.iter().enumerate() {
                for w in 0..4 {
                    let words = (0..n).map(|i| ((sums[i * k + c] as u128) >> (32 * w)) as u32).collect();
                    list.push(AnyChannel::new(format!("sum.{name}.w{w}").as_str(), FlatSamples::U32(words)));
                }
            }
            aov_order = Some(names.join(","));
        }
    }
    let mut attributes = LayerAttributes { layer_position: Vec2(image.crop.x0 as i32, image.crop.y0 as i32), ..LayerAttributes::default() };
    if let Some(order) = aov_order.and_then(|o| Text::new_or_none(&o)) {
        attributes.other.insert(Text::new_or_panic(AOV_CHANNELS_ATTRIBUTE), AttributeValue::Text(order));
    }
    for (k, v) in image.metadata {
        let key = Text::new_or_none(k).unwrap_or_else(|| Text::new_or_panic("plume:invalid"));
        let ascii: String = v.chars().map(|c| if c.is_ascii() { c } else { '?' }).collect();
        if let Some(val) = Text::new_or_none(&ascii) {
            attributes.other.insert(key, AttributeValue::Text(val));
        }
    }
    let size = (image.crop.width() as usize, image.crop.height() as usize);
    let layer = Layer::new(size, attributes, Encoding::FAST_LOSSLESS, AnyChannels::sort(list.into()));
    let display = IntegerBounds::new(Vec2(0, 0), Vec2(image.width as usize, image.height as usize));
    let exr_image = Image::new(ImageAttributes::new(display), layer);
    write_atomic(path, |out| exr_image.write().non_parallel().to_buffered(out).map_err(|e| std::io::Error::other(e.to_string())))
}

/// Everything [`write_exr_image`] stores, read back and decoded.
#[derive(Clone, Debug)]
pub struct ExrContents {
    /// Full image width (display window).
    pub width: u32,
    /// Full image height (display window).
    pub height: u32,
    /// The pixels present (data window).
    pub crop: Crop,
    /// Row-major RGBA over `crop`.
    pub pixels: Vec<[f32; 4]>,
    /// Exact sums, when the file has all 16 sum channels.
    pub sums: Option<Vec<[i128; 4]>>,
    /// Exact AOV sums: the channel names (in sum order) and their sums, names.len() per
    /// pixel, when the file has them all.
    pub aov_sums: Option<(Vec<String>, Vec<i128>)>,
    /// Text attributes.
    pub metadata: std::collections::BTreeMap<String, String>,
}

/// Read and decode a whole single-layer EXR: every channel, so a truncated or corrupt
/// file is an error, not a partial image.
///
/// # Errors
/// [`Error::Scene`] naming the file if it cannot be read or decoded, or lacks RGBA.
pub fn read_exr_contents(path: &Path) -> Result<ExrContents> {
    use crate::error::Error;
    use crate::film::Crop;
    use exr::prelude::*;
    let bad = |m: String| Error::Scene(format!("cannot read EXR {}: {m}", path.display()));
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_file(path)
        .map_err(|e| bad(e.to_string()))?;
    let layer = &image.layer_data;
    let display = image.attributes.display_window;
    let pos = layer.attributes.layer_position;
    let (w, h) = (layer.size.0, layer.size.1);
    let crop = Crop {
        x0: u32::try_from(pos.0 - display.position.0).map_err(|_| bad("data window outside the display window".into()))?,
        y0: u32::try_from(pos.1 - display.position.1).map_err(|_| bad("data window outside the display window".into()))?,
        x1: 0,
        y1: 0,
    };
    let crop = Crop { x1: crop.x0 + w as u32, y1: crop.y0 + h as u32, ..crop };
    let channel = |name: &str| layer.channel_data.list.iter().find(|c| c.name.to_string() == name);
    let mut pixels = vec![[0.0f32, 0.0, 0.0, 1.0]; w * h];
    for (c, name) in ["R", "G", "B", "A"].iter().enumerate() {
        match channel(name) {
            Some(ch) => {
                for (p, v) in pixels.iter_mut().zip(ch.sample_data.values_as_f32()) {
                    p[c] = v;
                }
            }
            None if *name == "A" => {}
            None => return Err(bad(format!("no {name} channel"))),
        }
    }
    let names = sum_channel_names();
    let words: Option<Vec<&Vec<u32>>> = names
        .iter()
        .map(|n| match channel(n).map(|c| &c.sample_data) {
            Some(FlatSamples::U32(v)) if v.len() == w * h => Some(v),
            _ => None,
        })
        .collect();
    let sums = words.map(|words| {
        (0..w * h)
            .map(|i| {
                let mut s = [0i128; 4];
                for (c, v) in s.iter_mut().enumerate() {
                    let u = (0..4).fold(0u128, |acc, k| acc | (u128::from(words[c * 4 + k][i]) << (32 * k)));
                    *v = u as i128;
                }
                s
            })
            .collect()
    });
    // AOV sums, in the order the attribute records, if every one of their words is there
    let aov_sums = match layer.attributes.other.get(&Text::new_or_panic(AOV_CHANNELS_ATTRIBUTE)) {
        Some(AttributeValue::Text(t)) => {
            let names: Vec<String> = t.to_string().split(',').map(str::to_string).collect();
            let words: Option<Vec<&Vec<u32>>> = names
                .iter()
                .flat_map(|n| (0..4).map(move |k| format!("sum.{n}.w{k}")))
                .map(|c| match channel(&c).map(|c| &c.sample_data) {
                    Some(FlatSamples::U32(v)) if v.len() == w * h => Some(v),
                    _ => None,
                })
                .collect();
            words.map(|words| {
                let k = names.len();
                let mut sums = vec![0i128; w * h * k];
                for (i, s) in sums.iter_mut().enumerate() {
                    let (pixel, c) = (i / k, i % k);
                    *s = (0..4).fold(0u128, |acc, q| acc | (u128::from(words[c * 4 + q][pixel]) << (32 * q))) as i128;
                }
                (names, sums)
            })
        }
        _ => None,
    };
    let metadata = layer
        .attributes
        .other
        .iter()
        .chain(image.attributes.other.iter())
        .filter_map(|(k, v)| match v {
            AttributeValue::Text(t) => Some((k.to_string(), t.to_string())),
            _ => None,
        })
        .collect();
    let (width, height) = (display.size.0 as u32, display.size.1 as u32);
    if !crop.fits(width, height) {
        return Err(bad(format!("data window {crop} outside the {width}x{height} display window")));
    }
    Ok(ExrContents { width, height, crop, pixels, sums, aov_sums, metadata })
}

/// Remove temporary files that an earlier, killed plume on this host left beside `path`
/// (`.NAME.HOST.PID.tmp` whose process no longer exists). Best effort: errors are
/// ignored, files of live processes and of other hosts are kept.
pub fn remove_stale_temporaries(path: &Path) {
    let (Some(name), dir) = (path.file_name(), parent_dir(path)) else { return };
    let prefix = format!(".{}.{}.", name.to_string_lossy(), temporary_host());
    let Ok(entries) = std::fs::read_dir(&dir) else { return };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(pid) = file.strip_prefix(&prefix).and_then(|r| r.strip_suffix(".tmp")) else { continue };
        let Ok(pid) = pid.parse::<i32>() else { continue };
        if pid != std::process::id() as i32 && !process_alive(pid) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

fn process_alive(pid: i32) -> bool {
    // SAFETY: kill with signal 0 sends nothing; it only checks that the process exists.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

/// This machine's host name ("unknown" if it cannot be read).
#[must_use]
pub fn host_name() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: gethostname writes at most buf.len() bytes into buf.
    let r = unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) };
    if r != 0 {
        return "unknown".into();
    }
    let end = buf.iter().position(|&b| b == 0).unwrap_or(buf.len());
    let h = String::from_utf8_lossy(&buf[..end]).into_owned();
    if h.is_empty() {
        "unknown".into()
    } else {
        h
    }
}

/// The temporary file beside `path`: `.NAME.HOST.PID.tmp`. Named after host and
/// process, so that a rerun can tell a killed run's leftovers from files being written
/// right now ([`remove_stale_temporaries`]).
pub(crate) fn temporary_path(path: &Path) -> PathBuf {
    let name = path.file_name().map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    parent_dir(path).join(format!(".{name}.{}.{}.tmp", temporary_host(), std::process::id()))
}

/// The host name as used in temporary file names (no dots or slashes).
fn temporary_host() -> String {
    host_name().replace(['/', '.'], "_")
}

pub(crate) fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// The first RGBA layer of an EXR, as [`read_exr`] returns it (for the full record of a
/// plume EXR, with crop, sums and metadata, see [`ExrContents`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RgbaImage {
    /// Width of the layer (its data window), pixels.
    pub width: u32,
    /// Height of the layer (its data window), pixels.
    pub height: u32,
    /// Row-major `[r, g, b, a]`, `width × height` of them.
    pub pixels: Vec<[f32; 4]>,
}

/// Read the first RGBA layer of an EXR as row-major `[r, g, b, a]` (alpha 1 if absent).
///
/// # Errors
/// [`Error::Scene`] naming the file if it is not a readable RGBA EXR.
pub fn read_exr(path: &Path) -> Result<RgbaImage> {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |res: Vec2<usize>, _| (res.0, vec![[0.0f32; 4]; res.0 * res.1]),
        |(w, px): &mut (usize, Vec<[f32; 4]>), Vec2(x, y), (r, g, b, a): (f32, f32, f32, f32)| {
            px[y * *w + x] = [r, g, b, a];
        },
    )
    .map_err(|e| crate::error::Error::Scene(format!("cannot read EXR {}: {e}", path.display())))?;
    let size = image.layer_data.size;
    // `self::`: the exr prelude has an `RgbaImage` of its own
    Ok(self::RgbaImage { width: size.0 as u32, height: size.1 as u32, pixels: image.layer_data.channel_data.pixels.1 })
}

/// sRGB transfer function of a linear value in `[0, 1]`.
fn srgb_encode(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Exposure multiplier that maps the 99.5th percentile of pixel luminance to 0.9.
#[must_use]
pub fn auto_exposure(pixels: &[[f32; 4]]) -> f32 {
    let mut lum: Vec<f32> = pixels.iter().map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]).filter(|l| l.is_finite() && *l > 0.0).collect();
    if lum.is_empty() {
        return 1.0;
    }
    let k = ((lum.len() as f64 * 0.995) as usize).min(lum.len() - 1);
    let (_, v, _) = lum.select_nth_unstable_by(k, f32::total_cmp);
    if *v > 0.0 {
        0.9 / *v
    } else {
        1.0
    }
}

/// Write a tone-mapped 8-bit sRGB PNG preview: `pixel × exposure`, clamped, sRGB encoded,
/// over black. Atomic.
///
/// # Errors
/// [`Error::Write`] naming `path`.
pub fn write_png(path: &Path, width: u32, height: u32, pixels: &[[f32; 4]], exposure: f32) -> Result<()> {
    let mut data = Vec::with_capacity(pixels.len() * 3);
    for p in pixels {
        for c in &p[..3] {
            let v = if c.is_finite() { (c * exposure).clamp(0.0, 1.0) } else { 0.0 };
            data.push((srgb_encode(v) * 255.0 + 0.5) as u8);
        }
    }
    write_atomic(path, |out| {
        let mut enc = png::Encoder::new(out, width, height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(&data).map_err(std::io::Error::other)?;
        w.finish().map_err(std::io::Error::other)
    })
}
