//! Image outputs: float EXR with metadata (and, for parts of a split frame, the exact
//! sample sums as `u32` channels) and a tone-mapped PNG preview, all written atomically
//! (temporary file in the same directory, synced, then renamed), so a reader never sees
//! a half-written file, even if plume is killed mid-write.

use std::path::Path;

use plume_core::error::Result;
use plume_core::fs::write_atomic;
use plume_engine::film::{Crop, Moments};

/// Write `pixels` (row-major RGBA, linear) as a 32-bit float EXR with text attributes
/// `metadata` (name, value), atomically.
///
/// # Errors
/// [`Error::Write`] naming `path`.
pub fn write_exr(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[[f32; 4]],
    metadata: &[(String, String)],
) -> Result<()> {
    write_exr_image(
        path,
        &ExrImage {
            width,
            height,
            crop: Crop::full(width, height),
            pixels,
            sums: None,
            aovs: None,
            metadata,
        },
    )
}

/// Names of the `i128` channels (each stored as four `u32` words like the sums) that
/// hold a pixel's [`Moments`]: its squared colour sums, its sample count, and the colour
/// sums and index of its two highest sample levels.
pub const MOMENT_CHANNELS: [&str; 11] = plume_engine::moments::CHANNELS;

/// A film's exact record over a crop, row-major: what `plume merge` adds and a continued
/// render resumes from.
#[derive(Clone, Copy, Debug)]
pub struct ExactSums<'a> {
    /// The RGBA sums (`film.rs`), stored as `sum.R.w0` … `sum.A.w3`.
    pub rgba: &'a [[i128; 4]],
    /// The pixels' moments, stored as `sum.R2.w0` … `sum.top.w3` ([`MOMENT_CHANNELS`]).
    pub moments: &'a [Moments],
}

/// [`ExactSums`], owned (as read back).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OwnedSums {
    /// The RGBA sums.
    pub rgba: Vec<[i128; 4]>,
    /// The pixels' moments.
    pub moments: Vec<Moments>,
}

impl OwnedSums {
    /// Borrowed, to write.
    #[must_use]
    pub fn as_ref(&self) -> ExactSums<'_> {
        ExactSums { rgba: &self.rgba, moments: &self.moments }
    }
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
    /// Exact fixed-point sums and moments over `crop` (`film.rs`), as `u32` words.
    pub sums: Option<ExactSums<'a>>,
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
        list.push(AnyChannel::new(
            *name,
            FlatSamples::F32(image.pixels.iter().map(|p| p[c]).collect()),
        ));
    }
    if let Some(ExactSums { rgba: sums, moments }) = image.sums {
        assert_eq!(sums.len(), n, "invariant: one sum per crop pixel");
        assert_eq!(moments.len(), n, "invariant: one moment per crop pixel");
        for (c, name) in ["R", "G", "B", "A"].iter().enumerate() {
            push_words(&mut list, name, sums.iter().map(|s| s[c]));
        }
        let values: Vec<[i128; 11]> = moments.iter().map(Moments::to_values).collect();
        for (c, name) in MOMENT_CHANNELS.iter().enumerate() {
            push_words(&mut list, name, values.iter().map(|v| v[c]));
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
                push_words(&mut list, name, (0..n).map(|i| sums[i * k + c]));
            }
            aov_order = Some(names.join(","));
        }
    }
    let mut attributes = LayerAttributes {
        layer_position: Vec2(image.crop.x0 as i32, image.crop.y0 as i32),
        ..LayerAttributes::default()
    };
    if let Some(order) = aov_order.and_then(|o| Text::new_or_none(&o)) {
        attributes
            .other
            .insert(Text::new_or_panic(AOV_CHANNELS_ATTRIBUTE), AttributeValue::Text(order));
    }
    for (k, v) in image.metadata {
        let key = Text::new_or_none(k).unwrap_or_else(|| Text::new_or_panic("plume:invalid"));
        let ascii: String = v.chars().map(|c| if c.is_ascii() { c } else { '?' }).collect();
        if let Some(val) = Text::new_or_none(&ascii) {
            attributes.other.insert(key, AttributeValue::Text(val));
        }
    }
    let size = (image.crop.width() as usize, image.crop.height() as usize);
    let layer =
        Layer::new(size, attributes, Encoding::FAST_LOSSLESS, AnyChannels::sort(list.into()));
    let display = IntegerBounds::new(Vec2(0, 0), Vec2(image.width as usize, image.height as usize));
    let exr_image = Image::new(ImageAttributes::new(display), layer);
    write_atomic(path, |out| {
        exr_image
            .write()
            .non_parallel()
            .to_buffered(out)
            .map_err(|e| std::io::Error::other(e.to_string()))
    })
}

/// Push the exact `i128` values of channel `name` as four `u32` channels
/// `sum.<name>.w0..3`, 32-bit words, least significant first (two's complement).
fn push_words(
    list: &mut Vec<exr::prelude::AnyChannel<exr::prelude::FlatSamples>>,
    name: &str,
    values: impl Iterator<Item = i128> + Clone,
) {
    use exr::prelude::*;
    for w in 0..4 {
        let words = values.clone().map(|v| ((v as u128) >> (32 * w)) as u32).collect();
        list.push(AnyChannel::new(format!("sum.{name}.w{w}").as_str(), FlatSamples::U32(words)));
    }
}

/// The float channels of an EXR's first layer, over its data window.
#[derive(Clone, Debug)]
pub struct ExrChannels {
    /// Data window width.
    pub width: usize,
    /// Data window height.
    pub height: usize,
    /// Every `f32` or `f16` channel (as `f32`), row-major, in the file's order (sorted by
    /// name); the exact-sum `u32` channels are left out.
    pub channels: Vec<(String, Vec<f32>)>,
}

/// Read every float channel of the EXR at `path` ([`ExrChannels`]).
///
/// # Errors
/// [`Error::Scene`] naming the file if it cannot be read or decoded.
pub fn read_exr_channels(path: &Path) -> Result<ExrChannels> {
    use exr::prelude::*;
    let image = read_whole_exr(path)?;
    let layer = &image.layer_data;
    let channels = layer
        .channel_data
        .list
        .iter()
        .filter(|c| !matches!(c.sample_data, FlatSamples::U32(_)))
        .map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect()))
        .collect();
    Ok(ExrChannels { width: layer.size.0, height: layer.size.1, channels })
}

/// Every channel and attribute of the first layer of the EXR at `path`, decoded whole.
///
/// # Errors
/// [`Error::Scene`] naming the file if it cannot be read or decoded.
fn read_whole_exr(
    path: &Path,
) -> Result<exr::image::Image<exr::image::Layer<exr::image::AnyChannels<exr::prelude::FlatSamples>>>>
{
    use exr::prelude::*;
    read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_file(path)
        .map_err(|e| {
            plume_core::error::Error::Scene(format!("cannot read EXR {}: {e}", path.display()))
        })
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
    /// Exact sums and the pixels' moments, when the file has all their channels.
    pub sums: Option<OwnedSums>,
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
    use exr::prelude::*;
    use plume_core::error::Error;
    use plume_engine::film::Crop;
    let bad = |m: String| Error::Scene(format!("cannot read EXR {}: {m}", path.display()));
    let image = read_whole_exr(path)?;
    let layer = &image.layer_data;
    let display = image.attributes.display_window;
    let pos = layer.attributes.layer_position;
    let (w, h) = (layer.size.0, layer.size.1);
    let crop = Crop {
        x0: u32::try_from(pos.0 - display.position.0)
            .map_err(|_| bad("data window outside the display window".into()))?,
        y0: u32::try_from(pos.1 - display.position.1)
            .map_err(|_| bad("data window outside the display window".into()))?,
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
    // One exact `i128` channel from its four words, if they are all there
    let exact = |name: &str| -> Option<Vec<i128>> {
        let words: Option<Vec<&Vec<u32>>> = (0..4)
            .map(|k| match channel(&format!("sum.{name}.w{k}")).map(|c| &c.sample_data) {
                Some(FlatSamples::U32(v)) if v.len() == w * h => Some(v),
                _ => None,
            })
            .collect();
        let words = words?;
        Some(
            (0..w * h)
                .map(|i| {
                    (0..4).fold(0u128, |acc, k| acc | (u128::from(words[k][i]) << (32 * k))) as i128
                })
                .collect(),
        )
    };
    let rgba: Option<Vec<Vec<i128>>> = ["R", "G", "B", "A"].iter().map(|c| exact(c)).collect();
    let moments: Option<Vec<Vec<i128>>> = MOMENT_CHANNELS.iter().map(|c| exact(c)).collect();
    let sums = rgba.zip(moments).map(|(rgba, m)| {
        let sums = (0..w * h).map(|i| std::array::from_fn(|c| rgba[c][i])).collect();
        let moments: Option<Vec<Moments>> =
            (0..w * h).map(|i| Moments::from_values(std::array::from_fn(|c| m[c][i]))).collect();
        moments.map(|moments| OwnedSums { rgba: sums, moments })
    });
    let sums = sums.flatten();
    // AOV sums, in the order the attribute records, if every one of their words is there
    let aov_sums = match layer.attributes.other.get(&Text::new_or_panic(AOV_CHANNELS_ATTRIBUTE)) {
        Some(AttributeValue::Text(t)) => {
            let names: Vec<String> = t.to_string().split(',').map(str::to_string).collect();
            let channels: Option<Vec<Vec<i128>>> = names.iter().map(|n| exact(n)).collect();
            channels.map(|channels| {
                let k = names.len();
                let sums = (0..w * h * k).map(|i| channels[i % k][i / k]).collect();
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
    .map_err(|e| {
        plume_core::error::Error::Scene(format!("cannot read EXR {}: {e}", path.display()))
    })?;
    let size = image.layer_data.size;
    // `self::`: the exr prelude has an `RgbaImage` of its own
    Ok(self::RgbaImage {
        width: size.0 as u32,
        height: size.1 as u32,
        pixels: image.layer_data.channel_data.pixels.1,
    })
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
    let mut lum: Vec<f32> = pixels
        .iter()
        .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
        .filter(|l| l.is_finite() && *l > 0.0)
        .collect();
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
pub fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[[f32; 4]],
    exposure: f32,
) -> Result<()> {
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
