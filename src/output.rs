//! Image outputs: float EXR with metadata and a tone-mapped PNG preview, both written
//! atomically (temporary file in the same directory, then rename), so a reader never
//! sees a half-written file, even if plume is killed mid-write.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Write a file atomically: `write` fills a temporary file beside `path`, which is
/// synced and renamed over `path` only if everything succeeded.
///
/// # Errors
/// [`Error::Write`] naming `path` if the directory is not writable or writing fails;
/// the temporary file is removed.
pub fn write_atomic(path: &Path, write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>) -> Result<()> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path.file_name().ok_or_else(|| Error::Write {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file name"),
    })?;
    let tmp = dir.join(format!(".{}.{}.tmp", name.to_string_lossy(), std::process::id()));
    let result = (|| {
        let file = File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        w.flush()?;
        w.get_ref().sync_all()?;
        drop(w);
        std::fs::rename(&tmp, path)
    })();
    result.map_err(|source| {
        let _ = std::fs::remove_file(&tmp);
        Error::Write { path: path.to_path_buf(), source }
    })
}

/// Check, before any expensive work, that `path` can be written: its directory exists and
/// accepts a new file. Creates and removes a probe file.
///
/// # Errors
/// [`Error::Write`] naming `path`.
pub fn check_writable(path: &Path) -> Result<()> {
    let name = path.file_name().map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
    let probe = path.with_file_name(format!(".{name}.probe"));
    write_atomic(&probe, |_| Ok(()))
        .and_then(|()| std::fs::remove_file(&probe).map_err(|source| Error::Write { path: probe.clone(), source }))
        .map_err(|e| match e {
            Error::Write { source, .. } => Error::Write { path: path.to_path_buf(), source },
            other => other,
        })
}

/// Write `pixels` (row-major RGBA, linear) as a 32-bit float EXR with text attributes
/// `metadata` (name, value), atomically.
///
/// # Errors
/// [`Error::Write`] naming `path`.
pub fn write_exr(path: &Path, width: u32, height: u32, pixels: &[[f32; 4]], metadata: &[(String, String)]) -> Result<()> {
    use exr::prelude::*;
    let w = width as usize;
    let channels = SpecificChannels::rgba(|Vec2(x, y): Vec2<usize>| {
        let p = pixels[y * w + x];
        (p[0], p[1], p[2], p[3])
    });
    let mut image = Image::from_channels((width as usize, height as usize), channels);
    for (k, v) in metadata {
        let key = Text::new_or_none(k).unwrap_or_else(|| Text::new_or_panic("plume:invalid"));
        let ascii: String = v.chars().map(|c| if c.is_ascii() { c } else { '?' }).collect();
        if let Some(val) = Text::new_or_none(&ascii) {
            image.attributes.other.insert(key, AttributeValue::Text(val));
        }
    }
    write_atomic(path, |out| {
        image.write().non_parallel().to_buffered(out).map_err(|e| std::io::Error::other(e.to_string()))
    })
}

/// Read the first RGBA layer of an EXR as row-major `[r, g, b, a]` (alpha 1 if absent).
///
/// # Errors
/// [`Error::Scene`] naming the file if it is not a readable RGBA EXR.
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<[f32; 4]>)> {
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
    Ok((size.0 as u32, size.1 as u32, image.layer_data.channel_data.pixels.1))
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
    if *v > 0.0 { 0.9 / *v } else { 1.0 }
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
