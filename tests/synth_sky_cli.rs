//! `plume synth sky` as users run it: a lat-long EXR with a blue sky over a black ground
//! that carries the sun's energy, and refusals of bad values that name the flag.

use crate::common;

use common::{plume, plume_exits, tmpdir};
use plume::output::read_exr;
use plume_engine::light::sky::{latlong_pixel_solid_angle, Sky, SkyParams};

#[test]
fn synth_sky_writes_a_latlong_exr() {
    let d = tmpdir("sky", "exr");
    let p = d.join("sky.exr");
    let args = [
        "synth",
        "sky",
        "-o",
        p.to_str().unwrap(),
        "--width",
        "128",
        "--height",
        "64",
        "--elevation",
        "40",
        "--azimuth",
        "-30",
    ];
    let o = plume(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let image = read_exr(&p).expect("read the sky back");
    assert_eq!((image.width, image.height), (128, 64));
    let (w, h) = (image.width as usize, image.height as usize);
    // Top row: sky blue (B > R), finite, alpha 1.
    for px in &image.pixels[..w] {
        assert!(px[2] > px[0] && px[0] > 0.0 && px[3] == 1.0, "{px:?}");
    }
    // Bottom half: black ground, alpha 1.
    assert!(image.pixels[w * h / 2..].iter().all(|px| px[..3] == [0.0; 3] && px[3] == 1.0));
    // The file carries the sun: its energy, Σ L dΩ beyond the sky, is L_sun Ω_sun.
    let sky = Sky::new(&SkyParams { elevation: 40.0, azimuth: -30.0, turbidity: 3.0 }).unwrap();
    let without_sun = sky.image(128, 64, false);
    let mut extra = 0.0;
    for (k, (px, s)) in image.pixels.iter().zip(&without_sun).enumerate() {
        extra += f64::from(px[1] - s.0[1]) * latlong_pixel_solid_angle(128, 64, (k / w) as u32);
    }
    let expected = f64::from(sky.sun_radiance().0[1]) * Sky::sun_solid_angle();
    assert!((extra / expected - 1.0).abs() < 1e-5, "{extra} vs {expected}");
    // The sun's pixel: azimuth −30° is u = (1 + 30/180)/2, elevation 40° is v = 50/180.
    let (i, j) = (((1.0 + 30.0 / 180.0) / 2.0 * 128.0) as usize, (50.0 / 180.0 * 64.0) as usize);
    let brightest = image
        .pixels
        .iter()
        .enumerate()
        .max_by(|a, b| a.1[1].total_cmp(&b.1[1]))
        .map(|(k, _)| k)
        .unwrap();
    assert_eq!((brightest % w, brightest / w), (i, j));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn synth_sky_without_sun_defaults() {
    let d = tmpdir("sky", "nosun");
    let p = d.join("sky.exr");
    let o = plume(&[
        "synth",
        "sky",
        "-o",
        p.to_str().unwrap(),
        "--no-sun",
        "--width",
        "64",
        "--height",
        "32",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let image = read_exr(&p).unwrap();
    let sky = Sky::new(&SkyParams::default()).unwrap().image(64, 32, false);
    assert!(image.pixels.iter().zip(&sky).all(|(px, s)| px[..3] == s.0));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn synth_sky_refuses_bad_values_and_writes_nothing() {
    let d = tmpdir("sky", "bad");
    let p = d.join("sky.exr");
    let out = p.to_str().unwrap();
    for (flag, value) in [
        ("--turbidity", "0"),
        ("--turbidity", "nan"),
        ("--elevation", "91"),
        ("--azimuth", "inf"),
        ("--width", "0"),
        ("--height", "99999"),
    ] {
        let message = plume_exits(&["synth", "sky", "-o", out, flag, value], 2, &[flag]);
        assert_eq!(message.trim_end().lines().count(), 1, "{message}");
        assert!(!p.exists(), "{flag} {value}");
    }
    plume_exits(
        &["synth", "sky", "-o", d.join("sky.png").to_str().unwrap()],
        2,
        &["--output", ".exr"],
    );
    assert!(std::fs::read_dir(&d).unwrap().next().is_none(), "nothing written");
    let _ = std::fs::remove_dir_all(&d);
}
