//! PNG figures of `plume bench`: error against CPU time on log–log axes (one line per
//! method, error bars = ±1 std over runs), a crop montage of the equal-time images, and a
//! plain two-column line plot for sweeps.
//!
//! Drawn with `plotters`' bitmap backend into a memory buffer and encoded with the `png`
//! crate; text uses the DejaVu Sans subset shipped in `assets/fonts` (registered with
//! `plotters`' `ab_glyph` backend), so no system font or fontconfig is needed.

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;

use super::compare::CompareReport;
use plume_core::error::{Error, Result};

/// DejaVu Sans, subset to ASCII and a few symbols (license: `assets/fonts/LICENSE-DejaVu.txt`).
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans-subset.ttf");

/// Okabe–Ito colours (distinguishable with colour-vision deficiencies), then greys.
const COLORS: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
    RGBColor(120, 120, 120),
];

fn font_ready() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The font is compiled in; failure would be a corrupt asset, caught by the tests
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

fn plot_err<E: std::fmt::Debug>(e: E) -> Error {
    Error::Scene(format!("cannot draw plot: {e:?}"))
}

/// Encode an 8-bit RGB buffer as PNG, atomically: indexed (a palette, lossless) when it
/// holds at most 256 colours, which plots usually do, else RGB.
///
/// # Errors
/// The file cannot be written.
pub fn write_rgb_png(path: &Path, width: u32, height: u32, rgb: &[u8]) -> Result<()> {
    let mut palette: Vec<[u8; 3]> = Vec::new();
    let mut index = std::collections::HashMap::new();
    let mut indices = Vec::with_capacity(rgb.len() / 3);
    for c in rgb.chunks_exact(3) {
        let key = [c[0], c[1], c[2]];
        let i = *index.entry(key).or_insert_with(|| {
            palette.push(key);
            palette.len() - 1
        });
        if palette.len() > 256 {
            break;
        }
        indices.push(i as u8);
    }
    let indexed = palette.len() <= 256;
    plume_core::fs::write_atomic(path, |out| {
        let mut enc = png::Encoder::new(out, width, height);
        if indexed {
            enc.set_color(png::ColorType::Indexed);
            enc.set_palette(palette.concat());
        } else {
            enc.set_color(png::ColorType::Rgb);
        }
        enc.set_depth(png::BitDepth::Eight);
        enc.set_compression(png::Compression::High);
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(if indexed { &indices } else { rgb }).map_err(std::io::Error::other)?;
        w.finish().map_err(std::io::Error::other)
    })
}

/// Axis labels for a log axis over `[lo, hi]`: 1-2-5 per decade, or 1-1.5-2-3-5-7 when
/// the range spans less than a decade and a half.
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if !(lo > 0.0 && hi > lo && hi.is_finite()) {
        return vec![1.0];
    }
    let mantissas: &[f64] =
        if hi / lo < 30.0 { &[1.0, 1.5, 2.0, 3.0, 5.0, 7.0] } else { &[1.0, 2.0, 5.0] };
    let mut out = Vec::new();
    for e in lo.log10().floor() as i32..=hi.log10().ceil() as i32 {
        for m in mantissas {
            let v = m * 10f64.powi(e);
            if v >= lo && v <= hi {
                out.push(v);
            }
        }
    }
    out
}

/// One line of a log–log plot: `(x, y, y_std)` points.
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points `(x, mean y, std y)`.
    pub points: Vec<(f64, f64, f64)>,
}

/// Draw panels of log–log series side by side: `(title, x label, y label, series)`.
///
/// # Errors
/// Drawing or writing fails.
pub fn loglog_panels(
    path: &Path,
    panels: &[(&str, &str, &str, Vec<Series>)],
    panel_width: u32,
    height: u32,
) -> Result<()> {
    font_ready();
    let width = panel_width * panels.len() as u32;
    let mut buf = vec![255u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        let areas = root.split_evenly((1, panels.len()));
        for (area, (title, xl, yl, series)) in areas.iter().zip(panels) {
            let pts = series.iter().flat_map(|s| s.points.iter());
            let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
            for &(x, y, sd) in pts.filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.1.is_finite()) {
                x0 = x0.min(x);
                x1 = x1.max(x);
                y0 = y0.min((y - sd).max(y * 0.5));
                y1 = y1.max(y + sd);
            }
            if x0 >= x1 {
                (x0, x1) = (x0.min(1.0) * 0.5, x1.max(1.0) * 2.0);
            }
            if y0 >= y1 {
                (y0, y1) = (y0.min(1.0) * 0.5, y1.max(1.0) * 2.0);
            }
            let mut chart = ChartBuilder::on(area)
                .caption(*title, ("sans-serif", 17))
                .margin(8)
                .x_label_area_size(38)
                .y_label_area_size(70)
                .build_cartesian_2d(
                    (x0 / 1.15..x1 * 1.15)
                        .log_scale()
                        .with_key_points(log_ticks(x0 / 1.15, x1 * 1.15)),
                    (y0 / 1.15..y1 * 1.15)
                        .log_scale()
                        .with_key_points(log_ticks(y0 / 1.15, y1 * 1.15)),
                )
                .map_err(plot_err)?;
            chart
                .configure_mesh()
                .x_desc(*xl)
                .y_desc(*yl)
                .label_style(("sans-serif", 12))
                .axis_desc_style(("sans-serif", 14))
                .x_label_formatter(&|v| super::numbers::label(*v))
                .y_label_formatter(&|v| super::numbers::label(*v))
                .light_line_style(RGBColor(235, 235, 235))
                .draw()
                .map_err(plot_err)?;
            for (i, s) in series.iter().enumerate() {
                let c = COLORS[i % COLORS.len()];
                let good: Vec<(f64, f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|p| p.0 > 0.0 && p.1 > 0.0 && p.1.is_finite())
                    .collect();
                chart
                    .draw_series(LineSeries::new(
                        good.iter().map(|p| (p.0, p.1)),
                        c.stroke_width(2),
                    ))
                    .map_err(plot_err)?
                    .label(s.label.clone())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                    });
                chart
                    .draw_series(good.iter().map(|p| Circle::new((p.0, p.1), 3, c.filled())))
                    .map_err(plot_err)?;
                chart
                    .draw_series(good.iter().filter(|p| p.2 > 0.0).map(|p| {
                        ErrorBar::new_vertical(
                            p.0,
                            (p.1 - p.2).max(p.1 * 0.5),
                            p.1,
                            p.1 + p.2,
                            c.stroke_width(1),
                            6,
                        )
                    }))
                    .map_err(plot_err)?;
            }
            chart
                .configure_series_labels()
                .label_font(("sans-serif", 12))
                .background_style(WHITE.mix(0.85))
                .border_style(RGBColor(180, 180, 180))
                .position(SeriesLabelPosition::LowerLeft)
                .draw()
                .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    write_rgb_png(path, width, height, &buf)
}

/// RMSE and relMSE against CPU seconds, log–log, one line per method.
///
/// # Errors
/// Drawing or writing fails.
pub fn error_vs_time(report: &CompareReport, path: &Path) -> Result<()> {
    let series = |f: &dyn Fn(&super::compare::Point) -> (f64, f64)| -> Vec<Series> {
        report
            .methods
            .iter()
            .map(|m| Series {
                label: m.method.clone(),
                points: m
                    .curve
                    .iter()
                    .map(|p| {
                        let (y, sd) = f(p);
                        (p.cpu_seconds.mean, y, sd)
                    })
                    .collect(),
            })
            .collect()
    };
    let rmse = series(&|p| (p.rmse.mean, p.rmse.std));
    let rel = series(&|p| (p.relmse.mean, p.relmse.std));
    loglog_panels(
        path,
        &[
            ("RMSE vs CPU time", "CPU seconds", "RMSE", rmse),
            ("relMSE vs CPU time", "CPU seconds", "relMSE (trimmed)", rel),
        ],
        440,
        330,
    )
}

fn srgb8(v: f32) -> u8 {
    let v = if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
    let s = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

/// Crops of the equal-time images (first run) beside the reference, all at the
/// reference's automatic exposure, each labelled with method and RMSE.
///
/// # Errors
/// Drawing or writing fails.
pub fn crop_montage(report: &CompareReport, path: &Path) -> Result<()> {
    font_ready();
    let (w, h) = (report.width as usize, report.height as usize);
    let reference = &report.reference.pixels;
    let exposure = crate::output::auto_exposure(reference);
    // Crop centred on the reference's luminance centroid
    let (mut sx, mut sy, mut sw) = (0.0f64, 0.0f64, 0.0f64);
    for (i, p) in reference.iter().enumerate() {
        let l = f64::from(0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]).max(0.0);
        if l.is_finite() {
            sx += l * (i % w) as f64;
            sy += l * (i / w) as f64;
            sw += l;
        }
    }
    let crop = (w.min(h) / 2).clamp(1, 64);
    let (cx, cy) = if sw > 0.0 { (sx / sw, sy / sw) } else { (w as f64 / 2.0, h as f64 / 2.0) };
    let x0 = (cx as usize).saturating_sub(crop / 2).min(w - crop);
    let y0 = (cy as usize).saturating_sub(crop / 2).min(h - crop);
    let scale = if crop <= 48 { 3 } else { 2 };
    let tile = crop * scale;
    let label_h = 34;
    let mut tiles: Vec<(String, String, &[[f32; 4]])> =
        vec![("reference".into(), format!("{} spp", report.reference.spp), reference.as_slice())];
    for m in &report.methods {
        tiles.push((
            m.method.clone(),
            format!("RMSE {}", super::numbers::num(super::metrics::rmse(&m.image, reference))),
            m.image.as_slice(),
        ));
    }
    let cols = tiles.len().min(4);
    let rows = tiles.len().div_ceil(cols);
    let gap = 4;
    let (mw, mh) = (cols * (tile + gap) + gap, rows * (tile + label_h + gap) + gap);
    let mut buf = vec![255u8; mw * mh * 3];
    for (k, (_, _, img)) in tiles.iter().enumerate() {
        let (ox, oy) = (gap + (k % cols) * (tile + gap), gap + (k / cols) * (tile + label_h + gap));
        for ty in 0..tile {
            for tx in 0..tile {
                let p = img[(y0 + ty / scale) * w + x0 + tx / scale];
                let o = ((oy + ty) * mw + ox + tx) * 3;
                for c in 0..3 {
                    // 6 bits per channel: invisible on noisy crops, a third smaller files
                    buf[o + c] = srgb8(p[c] * exposure) & 0xFC;
                }
            }
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (mw as u32, mh as u32)).into_drawing_area();
        for (k, (name, sub, _)) in tiles.iter().enumerate() {
            let (ox, oy) =
                (gap + (k % cols) * (tile + gap), gap + (k / cols) * (tile + label_h + gap) + tile);
            root.draw(&Text::new(
                name.clone(),
                (ox as i32 + 2, oy as i32 + 2),
                ("sans-serif", 14).into_font().color(&BLACK),
            ))
            .map_err(plot_err)?;
            root.draw(&Text::new(
                sub.clone(),
                (ox as i32 + 2, oy as i32 + 18),
                ("sans-serif", 12).into_font().color(&RGBColor(70, 70, 70)),
            ))
            .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    write_rgb_png(path, mw as u32, mh as u32, &buf)
}

/// Images of one size side by side at one exposure (8-bit sRGB, full precision), each
/// labelled below: `(label, row-major RGBA)`.
///
/// # Errors
/// Drawing or writing fails.
///
/// # Panics
/// If an image is not `width × height`.
pub fn side_by_side(
    path: &Path,
    width: u32,
    height: u32,
    panels: &[(String, &[[f32; 4]])],
    exposure: f32,
) -> Result<()> {
    font_ready();
    let (w, h) = (width as usize, height as usize);
    let (gap, label_h) = (4, 24);
    let (mw, mh) = (panels.len() * (w + gap) + gap, h + label_h + 2 * gap);
    let mut buf = vec![255u8; mw * mh * 3];
    for (k, (_, img)) in panels.iter().enumerate() {
        assert_eq!(img.len(), w * h, "panel {k} is not {width}x{height}");
        let ox = gap + k * (w + gap);
        for y in 0..h {
            for x in 0..w {
                let o = ((gap + y) * mw + ox + x) * 3;
                for c in 0..3 {
                    buf[o + c] = srgb8(img[y * w + x][c] * exposure);
                }
            }
        }
    }
    {
        let root = BitMapBackend::with_buffer(&mut buf, (mw as u32, mh as u32)).into_drawing_area();
        for (k, (label, _)) in panels.iter().enumerate() {
            let (x, y) = ((gap + k * (w + gap)) as i32 + 2, (gap + h) as i32 + 4);
            root.draw(&Text::new(
                label.clone(),
                (x, y),
                ("sans-serif", 15).into_font().color(&BLACK),
            ))
            .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    write_rgb_png(path, mw as u32, mh as u32, &buf)
}
