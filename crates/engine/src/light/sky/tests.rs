//! Tests of [`super`]: the model against the paper's formulas and values worked by hand
//! from its matrices, physical properties (brightness near the sun, horizon brightening,
//! turbidity, a reddening sun, daylight illuminances), the energy of the environment map,
//! and the lat-long convention.

use glam::{DMat3, DVec3};

use super::*;
use plume_core::color::blackbody::XYZ_TO_REC709;
use plume_core::error::Error;

fn sky(elevation: f64, azimuth: f64, turbidity: f64) -> Sky {
    Sky::new(&SkyParams { elevation, azimuth, turbidity }).expect("valid parameters")
}

/// Unit direction at `elevation`, `azimuth` degrees.
fn dir(elevation: f64, azimuth: f64) -> DVec3 {
    let (e, a) = (elevation.to_radians(), azimuth.to_radians());
    DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin())
}

/// Photometric luminance, cd m⁻², of a radiance in plume units.
fn candela(c: Rgb) -> f64 {
    f64::from(c.luminance()) * LUMENS_PER_WATT
}

/// Illuminance of the sky (sun excluded) on a horizontal plane, lux: the midpoint rule
/// over θ ∈ [0, π/2], φ ∈ [0, 2π) of `L cos θ sin θ dθ dφ`.
fn horizontal_illuminance(s: &Sky) -> f64 {
    let n = 256;
    let (d_theta, d_phi) = (0.5 * PI / f64::from(n), 2.0 * PI / f64::from(2 * n));
    let mut sum = 0.0;
    for j in 0..n {
        let theta = (f64::from(j) + 0.5) * d_theta;
        for i in 0..2 * n {
            let phi = (f64::from(i) + 0.5) * d_phi;
            let d = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            sum += candela(s.radiance(d)) * theta.cos() * theta.sin() * d_theta * d_phi;
        }
    }
    sum
}

/// Σ over a lat-long image of `L dΩ` (W m⁻² per channel).
fn image_integral(pixels: &[Rgb], width: u32, height: u32) -> [f64; 3] {
    let mut sum = [0.0; 3];
    for (k, p) in pixels.iter().enumerate() {
        let omega = latlong_pixel_solid_angle(width, height, k as u32 / width);
        for (s, c) in sum.iter_mut().zip(p.to_f64()) {
            *s += c * omega;
        }
    }
    sum
}

#[test]
fn zenith_luminance_matches_the_published_formula() {
    for t in [1.7, 2.0, 3.0, 6.0, 10.0] {
        for theta_s_degrees in [0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0] {
            let theta_s = f64::to_radians(theta_s_degrees);
            let chi = (4.0 / 9.0 - t / 120.0) * (PI - 2.0 * theta_s);
            let expected = (4.0453 * t - 4.9710) * chi.tan() - 0.2155 * t + 2.4192;
            let got = zenith(t, theta_s).luminance;
            assert!(
                (got - expected).abs() <= 1e-12 * expected.abs(),
                "T {t} θs {theta_s_degrees}: {got} vs {expected}"
            );
        }
    }
    // Worked by hand: T = 2, θs = 30°: χ = 0.44607, tan χ = 0.47885 → 5.88674 kcd/m².
    assert!((zenith(2.0, 30f64.to_radians()).luminance - 5.88674).abs() < 1e-5);
    assert!((zenith(10.0, 60f64.to_radians()).luminance - 14.36030).abs() < 1e-5);
    // Sun on the horizon: χ = 0, Y_z = 2.4192 − 0.2155 T.
    assert!((zenith(3.0, PI / 2.0).luminance - 1.7727).abs() < 1e-9);
}

#[test]
fn zenith_chromaticity_matches_values_worked_from_the_matrices() {
    // [T² T 1] M [θs³ θs² θs 1]ᵀ, evaluated by hand (to 6 decimals) from the paper's M_x, M_y.
    let cases = [
        (2.0, 30.0, 0.251421, 0.255924),
        (3.0, 45.0, 0.245678, 0.251476),
        (10.0, 60.0, 0.292367, 0.314814),
    ];
    for (t, theta_s_degrees, x, y) in cases {
        let z = zenith(t, f64::to_radians(theta_s_degrees));
        assert!(
            (z.x - x).abs() < 1e-6 && (z.y - y).abs() < 1e-6,
            "T {t} θs {theta_s_degrees}: {z:?}"
        );
    }
}

#[test]
fn perez_coefficients_at_t2_and_t10() {
    let close = |got: Perez, want: [f64; 5], what: &str| {
        let got_array = [got.a, got.b, got.c, got.d, got.e];
        for (g, w) in got_array.iter().zip(want) {
            assert!((g - w).abs() < 1e-12, "{what}: {got:?} vs {want:?}");
        }
    };
    let c2 = perez_coefficients(2.0);
    close(c2.luminance, [-1.1056, -0.2833, 5.2797, -2.3359, 0.2363], "Y, T = 2");
    close(c2.x, [-0.2978, -0.1322, 0.2117, -1.0271, 0.0386], "x, T = 2");
    close(c2.y, [-0.2942, -0.1808, 0.1944, -1.7419, 0.0311], "y, T = 2");
    let c10 = perez_coefficients(10.0);
    close(c10.luminance, [0.3240, -3.1265, 5.0981, -1.3711, -0.2997], "Y, T = 10");
    close(c10.x, [-0.4522, -0.6642, 0.2085, -1.5399, 0.0122], "x, T = 10");
    close(c10.y, [-0.4278, -0.9408, 0.1312, -2.0947, -0.0561], "y, T = 10");
}

#[test]
fn radiance_at_the_zenith_is_the_zenith_value() {
    let rec709_to_xyz = DMat3::from_cols_array_2d(&XYZ_TO_REC709).transpose().inverse();
    for (e, t) in [(30.0, 3.0), (60.0, 2.0), (10.0, 8.0), (89.0, 1.7)] {
        let s = sky(e, 20.0, t);
        let z = zenith(t, (90.0 - e).to_radians());
        let c = s.radiance(DVec3::Z);
        let expected_candela = z.luminance * 1000.0;
        assert!(
            (candela(c) / expected_candela - 1.0).abs() < 1e-3,
            "e {e} T {t}: {} vs {expected_candela}",
            candela(c)
        );
        let xyz = rec709_to_xyz * DVec3::from_array(c.to_f64());
        let sum = xyz.x + xyz.y + xyz.z;
        assert!(
            (xyz.x / sum - z.x).abs() < 1e-5 && (xyz.y / sum - z.y).abs() < 1e-5,
            "e {e} T {t}: {xyz:?} vs {z:?}"
        );
        assert!((xyz.y * LUMENS_PER_WATT / expected_candela - 1.0).abs() < 1e-5);
        // A blue sky: B > R at the zenith.
        assert!(c.0[2] > c.0[0], "{c:?}");
    }
}

#[test]
fn sky_is_brighter_near_the_sun_than_opposite_it() {
    for t in [2.0, 3.0, 6.0] {
        let s = sky(30.0, 40.0, t);
        let near = candela(s.radiance(dir(40.0, 40.0)));
        let opposite = candela(s.radiance(dir(40.0, 220.0)));
        assert!(near > 3.0 * opposite, "T {t}: {near} vs {opposite}");
    }
}

#[test]
fn horizon_is_brighter_than_higher_up_at_the_same_angle_from_the_sun() {
    // Sun 30° high at azimuth 0: the horizon at azimuth 90° and the point 60° high at
    // azimuth 180° are both 90° from it, so only the gradation (1 + A e^{B / cos θ}) differs.
    // Brightening needs A_Y < 0, i.e. T < 8.19; above that the fit darkens the horizon.
    for (t, at_least) in [(2.0, 4.0), (3.0, 1.5), (6.0, 1.03)] {
        let s = sky(30.0, 0.0, t);
        let horizon = candela(s.radiance(dir(0.0, 90.0)));
        let higher = candela(s.radiance(dir(60.0, 180.0)));
        assert!(horizon > at_least * higher, "T {t}: horizon {horizon}, 60° {higher}");
    }
    let hazy = sky(30.0, 0.0, 10.0);
    assert!(candela(hazy.radiance(dir(0.0, 90.0))) < candela(hazy.radiance(dir(60.0, 180.0))));
    // Away from the sun, a clear sky's horizon outshines its zenith.
    let s = sky(30.0, 0.0, 3.0);
    assert!(candela(s.radiance(dir(1.0, 90.0))) > candela(s.radiance(DVec3::Z)));
}

#[test]
fn higher_turbidity_is_more_luminous_near_the_sun() {
    let near_sun = dir(35.0, 0.0);
    let values: Vec<f64> = [2.0, 4.0, 6.0, 10.0]
        .iter()
        .map(|&t| candela(sky(30.0, 0.0, t).radiance(near_sun)))
        .collect();
    assert!(values.windows(2).all(|w| w[1] > w[0]), "{values:?}");
}

#[test]
fn sun_reddens_as_it_sets() {
    let elevations = [90.0, 60.0, 30.0, 15.0, 10.0, 5.0, 2.0, 0.0];
    let colours: Vec<Rgb> = elevations.iter().map(|&e| sky(e, 0.0, 3.0).sun_radiance()).collect();
    for (e, c) in elevations.iter().zip(&colours) {
        eprintln!("sun at {e}°: {c:?}, luminance {:.4e}", c.luminance());
    }
    // R/B while blue is in gamut; below ≈ 5° the colour leaves the gamut through its B = 0
    // edge and is mapped onto it, so from there on only R's share can keep growing.
    let ratios: Vec<f64> =
        colours.iter().filter(|c| c.0[2] > 0.0).map(|c| f64::from(c.0[0] / c.0[2])).collect();
    assert!(ratios.len() >= 5 && ratios.windows(2).all(|w| w[1] > w[0]), "R/B {ratios:?}");
    assert!(ratios[0] < 2.0 && ratios[ratios.len() - 1] > 5.0, "R/B {ratios:?}");
    let red_share: Vec<f32> = colours.iter().map(|c| c.0[0] / (c.0[0] + c.0[1] + c.0[2])).collect();
    assert!(red_share.windows(2).all(|w| w[1] > w[0]), "R share {red_share:?}");
    let luminance: Vec<f32> = colours.iter().map(|c| c.luminance()).collect();
    assert!(luminance.windows(2).all(|w| w[1] < w[0]) && luminance[7] > 0.0, "{luminance:?}");
}

#[test]
fn noon_sun_gives_about_100_klux() {
    // Illuminance at normal incidence, L_sun Ω_sun, for a clear sky and a high sun.
    for t in [2.0, 2.5, 3.0] {
        for e in [60.0, 75.0, 90.0] {
            let s = sky(e, 0.0, t);
            let irradiance_luminance =
                f64::from(s.sun_radiance().luminance()) * Sky::sun_solid_angle();
            let lux = irradiance_luminance * LUMENS_PER_WATT;
            assert!((80e3..=110e3).contains(&lux), "T {t} e {e}: {lux} lx");
            assert!(
                (117.0..=161.0).contains(&irradiance_luminance),
                "T {t} e {e}: {irradiance_luminance}"
            );
        }
    }
    // The figure in the report: T = 2.5, sun at the zenith.
    let s = sky(90.0, 0.0, 2.5);
    let lux = f64::from(s.sun_radiance().luminance()) * Sky::sun_solid_angle() * LUMENS_PER_WATT;
    eprintln!("sun, T = 2.5, zenith: {lux:.0} lx");
}

#[test]
fn clear_sky_illuminance_on_a_horizontal_plane_is_tens_of_klux() {
    // Measured clear skies give ≈ 10–25 klux; the fit gives 24–32 klux here, too bright
    // near the horizon (module docs). The band catches unit and normalisation errors
    // (×1000, /683, F(0, θs)), which are factors of π or more.
    for (e, t) in [(30.0, 2.0), (30.0, 3.0), (45.0, 2.5), (60.0, 2.0), (60.0, 3.0)] {
        let lux = horizontal_illuminance(&sky(e, 0.0, t));
        eprintln!("sky, e {e}, T {t}: {lux:.0} lx");
        assert!((15e3..=35e3).contains(&lux), "e {e} T {t}: {lux} lx");
    }
    // A low sun gives less.
    let low = horizontal_illuminance(&sky(5.0, 0.0, 3.0));
    assert!(low < 0.5 * horizontal_illuminance(&sky(30.0, 0.0, 3.0)), "{low}");
}

#[test]
fn sun_image_preserves_energy() {
    for (e, a, width, height) in
        [(30.0, 0.0, 256, 128), (47.3, 123.4, 200, 101), (0.0, -60.0, 64, 32), (88.0, 10.0, 96, 48)]
    {
        let s = sky(e, a, 3.0);
        let with_sun = s.image(width, height, true);
        let without = s.image(width, height, false);
        // Only the sun's pixel differs, and it contains the sun direction.
        let p = s.sun_pixel(width, height);
        let changed: Vec<usize> =
            (0..with_sun.len()).filter(|&k| with_sun[k] != without[k]).collect();
        assert_eq!(changed, vec![p.row as usize * width as usize + p.column as usize]);
        let expected_sun = s.sun_radiance().to_f64().map(|c| c * Sky::sun_solid_angle());
        let (sky_sum, all) =
            (image_integral(&without, width, height), image_integral(&with_sun, width, height));
        let largest = expected_sun.iter().copied().fold(0.0, f64::max);
        assert!(largest > 0.0, "e {e}");
        for c in 0..3 {
            let sun_part = all[c] - sky_sum[c];
            assert!(
                (sun_part - expected_sun[c]).abs() < 1e-5 * largest,
                "e {e} channel {c}: {sun_part} vs {}",
                expected_sun[c]
            );
        }
        if e > 0.0 {
            assert_eq!(latlong_pixel(s.sun_direction(), width, height), p);
        }
        // Nothing below the horizon, the sun on it included.
        let below = (height as usize).div_ceil(2) * width as usize;
        assert!(with_sun[below..].iter().all(|c| c.is_black()), "e {e}");
    }
}

#[test]
fn sky_image_integral_matches_the_sky() {
    let s = sky(30.0, 0.0, 3.0);
    let (width, height) = (512, 256);
    let image_lux: f64 = s
        .image(width, height, false)
        .iter()
        .enumerate()
        .map(|(k, c)| {
            let (i, j) = (k as u32 % width, k as u32 / width);
            let d = latlong_direction(
                (f64::from(i) + 0.5) / f64::from(width),
                (f64::from(j) + 0.5) / f64::from(height),
            );
            candela(*c) * d.z.max(0.0) * latlong_pixel_solid_angle(width, height, j)
        })
        .sum();
    let direct = horizontal_illuminance(&s);
    assert!((image_lux / direct - 1.0).abs() < 2e-3, "{image_lux} vs {direct}");
}

#[test]
fn below_the_horizon_is_black_and_twilight_fades() {
    let s = sky(30.0, 0.0, 3.0);
    assert!(s.radiance(dir(-1.0, 0.0)).is_black() && s.radiance(-DVec3::Z).is_black());
    assert!(!s.radiance(dir(0.0, 0.0)).is_black());
    // +Y on the horizon is 90° from both suns (θ and γ alike): only the fade differs.
    let on_horizon = candela(sky(0.0, 0.0, 3.0).radiance(DVec3::Y));
    let half = candela(sky(-3.0, 0.0, 3.0).radiance(DVec3::Y));
    assert!((half / on_horizon - 0.5).abs() < 1e-6, "{half} vs {on_horizon}");
    assert!(sky(-6.0, 0.0, 3.0).image(32, 16, true).iter().all(|c| c.is_black()));
    assert!(sky(-0.01, 0.0, 3.0).sun_radiance().is_black());
    assert!(!sky(0.0, 0.0, 3.0).sun_radiance().is_black());
}

#[test]
fn out_of_range_parameters_name_their_key() {
    let key_of = |p: SkyParams| match Sky::new(&p) {
        Err(Error::InvalidArgument { flag, .. }) => flag,
        other => panic!("{p:?}: {other:?}"),
    };
    let ok = SkyParams::default();
    for t in [1.69, 10.01, 0.0, -3.0, f64::NAN, f64::INFINITY] {
        assert_eq!(key_of(SkyParams { turbidity: t, ..ok }), "lights.sky.turbidity");
    }
    for e in [90.01, -90.01, f64::NAN, f64::NEG_INFINITY] {
        assert_eq!(key_of(SkyParams { elevation: e, ..ok }), "lights.sky.elevation");
    }
    for a in [f64::NAN, f64::INFINITY] {
        assert_eq!(key_of(SkyParams { azimuth: a, ..ok }), "lights.sky.azimuth");
    }
    for p in [
        SkyParams { turbidity: 1.7, elevation: 90.0, azimuth: -720.0 },
        SkyParams { turbidity: 10.0, elevation: -90.0, azimuth: 0.0 },
    ] {
        assert!(Sky::new(&p).is_ok(), "{p:?}");
    }
}

#[test]
fn sun_direction_follows_the_convention() {
    assert!((sky(0.0, 0.0, 3.0).sun_direction() - DVec3::X).length() < 1e-12);
    assert!((sky(0.0, 90.0, 3.0).sun_direction() - DVec3::Y).length() < 1e-12);
    assert!((sky(90.0, 33.0, 3.0).sun_direction() - DVec3::Z).length() < 1e-12);
    let d = sky(30.0, 45.0, 3.0).sun_direction();
    assert!((d.z - 0.5).abs() < 1e-12 && (d.x - d.y).abs() < 1e-12 && d.x > 0.0);
}

#[test]
fn latlong_convention_and_round_trip() {
    let close = |a: DVec3, b: DVec3| (a - b).length() < 1e-12;
    assert!(close(latlong_direction(0.5, 0.5), DVec3::X));
    assert!(close(latlong_direction(0.25, 0.5), DVec3::Y));
    assert!(close(latlong_direction(0.75, 0.5), -DVec3::Y));
    assert!(close(latlong_direction(0.0, 0.5), -DVec3::X));
    assert!(close(latlong_direction(0.3, 0.0), DVec3::Z));
    assert!(close(latlong_direction(0.3, 1.0), -DVec3::Z));
    assert_eq!(latlong_uv(DVec3::X), (0.5, 0.5));
    assert_eq!(latlong_uv(DVec3::Y), (0.25, 0.5));
    assert_eq!(latlong_uv(DVec3::Z).1, 0.0);
    // −X: φ = ±π, u = 0 (never 1).
    assert_eq!(latlong_uv(-DVec3::X).0, 0.0);
    assert_eq!(latlong_uv(DVec3::new(-1.0, -0.0, 0.0)).0, 0.0);
    for i in 0..37 {
        for j in 1..19 {
            let (u, v) = (f64::from(i) / 37.0, f64::from(j) / 19.0);
            let d = latlong_direction(u, v);
            assert!((d.length() - 1.0).abs() < 1e-12);
            let (u2, v2) = latlong_uv(d);
            assert!((u2 - u).abs() < 1e-12 && (v2 - v).abs() < 1e-12, "({u}, {v}) → ({u2}, {v2})");
            assert!(close(latlong_direction(u2, v2), d));
            // Not normalised: the same (u, v).
            let (u3, v3) = latlong_uv(3.5 * d);
            assert!((u3 - u).abs() < 1e-12 && (v3 - v).abs() < 1e-12);
        }
    }
    // Pixel solid angles cover the sphere.
    let total: f64 = (0..7).map(|j| 11.0 * latlong_pixel_solid_angle(11, 7, j)).sum();
    assert!((total / (4.0 * PI) - 1.0).abs() < 1e-12);
    assert_eq!(latlong_pixel(DVec3::X, 8, 4), LatLongPixel { column: 4, row: 2 });
    assert_eq!(latlong_pixel(dir(45.0, 90.0), 8, 4), LatLongPixel { column: 2, row: 1 });
}
