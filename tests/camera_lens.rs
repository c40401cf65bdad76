//! The plate's camera through `plume render`: a focal length is a field of view, a thin
//! lens keeps the plane in focus sharp and blurs what lies off it, an orthographic camera
//! maps world widths to pixels linearly, and the lens keys that do not go together are
//! refused in one line. Fixed seeds; tolerances far from the values measured.

use crate::common;

use std::path::{Path, PathBuf};

use common::{exr_pixels, grid, plume, refused_in_one_line, s, stderr, tmpdir};
use glam::{DAffine3, DVec3, IVec3};

const SIZE: u32 = 64;

/// An emitting cube 0.08 units wide (one 8³ leaf of 0.01-unit voxels) at the origin, of
/// density `density`.
fn cube(dir: &Path, density: f32) -> PathBuf {
    let xf =
        DAffine3::from_translation(DVec3::splat(-0.035)) * DAffine3::from_scale(DVec3::splat(0.01));
    let d = grid("density", xf, &[IVec3::ZERO], |_| density);
    let e = grid("emission", xf, &[IVec3::ZERO], |_| 1.0);
    let path = dir.join("cube.vdb");
    plume::vdb::write_float_grids(&path, &[&d, &e]).unwrap();
    path
}

/// Render `input` seen from 2 units along −z with `extra` flags; the RGBA pixels.
fn render(input: &Path, name: &str, extra: &[&str]) -> Vec<[f32; 4]> {
    let out = input.with_file_name(format!("{name}.exr"));
    let size = SIZE.to_string();
    let mut args = vec![
        "render",
        s(input),
        "-o",
        s(&out),
        "--camera-from",
        "0,0,-2",
        "--camera-at",
        "0,0,0",
        "--width",
        &size,
        "--height",
        &size,
        "--spp",
        "64",
        "--seed",
        "5",
        "-q",
    ];
    args.extend(extra);
    let o = plume(&args);
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    exr_pixels(&out)
}

fn peak(img: &[[f32; 4]]) -> f32 {
    img.iter().map(|p| p[0]).fold(0.0, f32::max)
}

fn flux(img: &[[f32; 4]]) -> f64 {
    img.iter().map(|p| f64::from(p[0])).sum()
}

#[test]
fn a_focal_length_is_the_field_of_view_it_implies() {
    let dir = tmpdir("lens", "focal");
    let input = cube(&dir, 1.0);
    // 50 mm on the default 36 mm sensor, and on a 24 mm one
    for (focal, sensor) in [(50.0f64, None), (35.0, Some(24.0))] {
        let fov = 2.0 * (sensor.unwrap_or(36.0) / (2.0 * focal)).atan().to_degrees();
        let focal_text = focal.to_string();
        let mut flags = vec!["--focal-length", focal_text.as_str()];
        let sensor_text = sensor.map(|v: f64| v.to_string());
        if let Some(t) = &sensor_text {
            flags.extend(["--sensor-width", t.as_str()]);
        }
        let by_lens = render(&input, "lens", &flags);
        let by_fov = render(&input, "fov", &["--fov", &fov.to_string()]);
        let bits = |img: &[[f32; 4]]| img.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&by_lens), bits(&by_fov), "{focal} mm on {sensor:?}");
    }
}

#[test]
fn a_thin_lens_keeps_the_plane_in_focus_sharp_and_blurs_the_rest() {
    let dir = tmpdir("lens", "focus");
    let input = cube(&dir, 1.0);
    // The image is 0.7 units wide at the cube, the cube 0.08
    let narrow = ["--fov", "20"];
    let pinhole = render(&input, "pinhole", &narrow);
    let sharp = render(
        &input,
        "sharp",
        &[&narrow[..], &["--aperture-radius", "0.2", "--focus-distance", "2"]].concat(),
    );
    // Focused at half the distance: a circle of confusion 2 r (D − F)/F = 0.4 units across
    // at the cube, five times the cube's width (and inside the image)
    let blurred = render(
        &input,
        "blurred",
        &[&narrow[..], &["--aperture-radius", "0.2", "--focus-distance", "1"]].concat(),
    );
    let (p0, p1, p2) = (peak(&pinhole), peak(&sharp), peak(&blurred));
    assert!(p0 > 0.0);
    assert!(p1 > 0.85 * p0, "in focus: peak {p1} against the pinhole's {p0}");
    assert!(p2 < 0.2 * p0, "out of focus: peak {p2} against the pinhole's {p0}");
    // The blur moves light, it does not make or lose it (a small cube near the axis)
    for (name, img) in [("sharp", &sharp), ("blurred", &blurred)] {
        let ratio = flux(img) / flux(&pinhole);
        assert!((ratio - 1.0).abs() < 0.05, "{name}: flux {ratio} of the pinhole's");
    }
    // The same through an f-number: 50 mm at f/0.5 is an aperture radius of 0.05 units
    let by_fstop = render(
        &input,
        "fstop",
        &["--focal-length", "50", "--fstop", "0.5", "--focus-distance", "1"],
    );
    let by_radius = render(
        &input,
        "radius",
        &[
            "--fov",
            &(2.0 * (36.0f64 / 100.0).atan().to_degrees()).to_string(),
            "--aperture-radius",
            "0.05",
            "--focus-distance",
            "1",
        ],
    );
    assert_eq!(by_fstop, by_radius);
}

#[test]
fn an_orthographic_camera_maps_widths_linearly() {
    let dir = tmpdir("lens", "ortho");
    // Optical depth 4 across: alpha 0.98 where the cube is
    let input = cube(&dir, 50.0);
    // The cube (0.08 units, voxels kept constant) on images 0.32 and 0.64 units wide: a
    // quarter and an eighth
    for (width, expected) in [("0.32", 16.0), ("0.64", 8.0)] {
        let img = render(
            &input,
            &format!("ortho{width}"),
            &[
                "--projection",
                "orthographic",
                "--ortho-width",
                width,
                "--interpolation",
                "nearest",
                "--method",
                "ray-march",
            ],
        );
        let row = (SIZE / 2) as usize;
        let covered = (0..SIZE as usize).filter(|&x| img[row * SIZE as usize + x][3] > 0.5).count();
        assert!(
            (covered as f64 - expected).abs() <= 1.0,
            "{width}: {covered} pixels, expected {expected}"
        );
        // Parallel rays all cross the same depth of the cube: with ray-march's exact
        // transmittance every covered pixel has the same alpha
        let alphas: Vec<f32> = (0..SIZE as usize)
            .map(|x| img[row * SIZE as usize + x][3])
            .filter(|&a| a > 0.5)
            .collect();
        let spread = alphas.iter().fold(0.0f32, |m, a| m.max((a - alphas[alphas.len() / 2]).abs()));
        assert!(spread < 1e-3, "{width}: alpha spread {spread}");
    }
    // Framed automatically without a width: the whole cube in view
    let auto = render(&input, "ortho-auto", &["--projection", "orthographic"]);
    assert!(auto.iter().any(|p| p[3] > 0.5));
    let edge = |p: &[f32; 4]| p[3];
    let border: f32 = (0..SIZE as usize)
        .map(|x| edge(&auto[x]) + edge(&auto[(SIZE as usize - 1) * SIZE as usize + x]))
        .sum();
    assert_eq!(border, 0.0, "nothing touches the top or bottom edge");
}

#[test]
fn lens_keys_that_do_not_go_together_are_refused() {
    let dir = tmpdir("lens", "refused");
    let input = cube(&dir, 1.0);
    let out = dir.join("x.exr");
    let base = ["render", s(&input), "-o", s(&out)];
    for (flags, needle) in [
        (&["--fstop", "2"][..], "--fstop: needs --focal-length"),
        (&["--focal-length", "50", "--fstop", "2", "--aperture-radius", "0.1"][..], "not both"),
        (&["--sensor-width", "24"][..], "--sensor-width: needs --focal-length"),
        (&["--ortho-width", "2"][..], "--ortho-width: applies to"),
        (&["--projection", "orthographic", "--aperture-radius", "0.1"][..], "no lens"),
        (&["--focal-length", "-5"][..], "--focal-length"),
        (&["--focus-distance", "0"][..], "--focus-distance"),
    ] {
        let args: Vec<&str> = base.iter().copied().chain(flags.iter().copied()).collect();
        refused_in_one_line(&args, 2, &[needle], &out);
    }
}
