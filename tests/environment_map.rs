//! Environment-map tier: the lat-long convention, lookup, loading, and importance sampling.
//!
//! - Sampling: chi² of `EnvironmentMap::sample` on bins of `(cos θ, φ)` (not the map's
//!   pixel grid, so the `(u, v) → d` mapping is tested too) against `pdf` integrated per
//!   bin; chi² of `Distribution2D` on a grid that is not its own; `∫ pdf dω = 1`; each
//!   pixel's probability is its share of `∫ Y dω`; `sample` agrees with `pdf` and `eval`
//!   bit for bit; black pixels are never sampled; `Σ L/pdf` is unbiased.
//! - Convention and lookup: a single bright pixel, the axes, every pixel by an independent
//!   formula.
//! - Loading: `f32` RGB and `f16` RGBA files read back; a missing file, a non-EXR, a file
//!   without RGB, a 3×3 file and a NaN pixel are errors (exit code 3) naming the file.
//!
//! Fixed seeds; each chi² test rejects at p < 0.01.
//! `cargo test --test environment_map -- --nocapture` prints the statistics.

use crate::common;

use std::f64::consts::PI;
use std::path::Path;

use common::{chi2_test, direction_bin, mean_stderr_from_sums, rng, tmpdir};
use glam::DVec3;
use plume::Error;
use plume_core::color::Rgb;
use plume_core::sampling::distribution2d::Distribution2D;
use plume_engine::light::envmap::EnvironmentMap;

const W: u32 = 16;
const H: u32 = 8;
/// Rejection level of each chi² test.
const ALPHA: f64 = 0.01;

/// The direction of polar angle `theta` (from +Z) and azimuth `phi` (from +X towards +Y),
/// written out here independently of the library.
fn dir(theta: f64, phi: f64) -> DVec3 {
    DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos())
}

/// The centre direction of pixel `(i, j)` of a `w × h` map, by the documented convention.
fn pixel_centre(i: u32, j: u32, w: u32, h: u32) -> DVec3 {
    let (u, v) = ((f64::from(i) + 0.5) / f64::from(w), (f64::from(j) + 0.5) / f64::from(h));
    dir(PI * v, PI * (1.0 - 2.0 * u))
}

fn luminance(p: Rgb) -> f64 {
    let [r, g, b] = p.to_f64();
    0.2126 * r + 0.7152 * g + 0.0722 * b
}

/// Black pixels of the random map: scattered ones, one in each polar row, and all of row 5.
fn is_black(i: u32, j: u32) -> bool {
    matches!((i, j), (3, 1) | (10, 4) | (11, 4) | (0, 3) | (7, 0) | (12, 7)) || j == 5
}

/// A 16 × 8 map of random colours in [0.05, 2) with the black pixels of [`is_black`].
fn random_pixels() -> Vec<Rgb> {
    let mut s = rng(0xe4f1);
    (0..W * H)
        .map(|k| {
            let c = Rgb(std::array::from_fn(|_| (0.05 + 1.95 * s.next_f64()) as f32));
            if is_black(k % W, k / W) {
                Rgb::ZERO
            } else {
                c
            }
        })
        .collect()
}

fn random_map() -> EnvironmentMap {
    EnvironmentMap::from_pixels(W, H, random_pixels(), "random map").unwrap()
}

/// `∫ f(d(θ, φ)) sin θ dθ dφ` over `θ ∈ [t0, t1]`, `φ ∈ [p0, p1]` by the midpoint rule on
/// `n × n` points.
fn integrate(
    f: &impl Fn(DVec3) -> f64,
    (t0, t1): (f64, f64),
    (p0, p1): (f64, f64),
    n: usize,
) -> f64 {
    let (dt, dp) = ((t1 - t0) / n as f64, (p1 - p0) / n as f64);
    let mut sum = 0.0;
    for a in 0..n {
        let theta = t0 + (a as f64 + 0.5) * dt;
        for b in 0..n {
            sum += f(dir(theta, p0 + (b as f64 + 0.5) * dp)) * theta.sin();
        }
    }
    sum * dt * dp
}

/// `[a, b]` cut at the multiples of `step` inside it.
fn split(a: f64, b: f64, step: f64) -> Vec<(f64, f64)> {
    let mut cuts = vec![a];
    let mut k = (a / step).floor() + 1.0;
    while k * step < b {
        cuts.push(k * step);
        k += 1.0;
    }
    cuts.push(b);
    cuts.windows(2).map(|w| (w[0], w[1])).collect()
}

/// [`integrate`] over pieces cut where the documented convention puts a `W × H` map's
/// pixel edges (`θ = jπ/H`, `φ = 2πk/W`): the integrand is smooth on each piece, so the
/// midpoint rule does not straddle a jump.
fn integrate_by_pixels(
    f: &impl Fn(DVec3) -> f64,
    (t0, t1): (f64, f64),
    (p0, p1): (f64, f64),
    n: usize,
) -> f64 {
    let mut sum = 0.0;
    for thetas in split(t0, t1, PI / f64::from(H)) {
        for phis in split(p0, p1, 2.0 * PI / f64::from(W)) {
            sum += integrate(f, thetas, phis, n);
        }
    }
    sum
}

#[test]
fn sample_chi_square_on_cos_theta_phi_bins() {
    let map = random_map();
    let (nz, nphi, samples) = (20usize, 40usize, 200_000usize);
    let bin = |d: DVec3| {
        direction_bin(d, DVec3::Z, (DVec3::X, DVec3::Y), -1.0, nz, nphi)
            .expect("every direction has a bin")
    };
    let mut observed = vec![0.0; nz * nphi];
    let mut s = rng(7);
    for _ in 0..samples {
        let u = [s.next_f64(), s.next_f64()];
        let sample = map.sample(u).unwrap_or_else(|| panic!("no sample for {u:?}"));
        let d = sample.direction;
        assert!((d.length() - 1.0).abs() < 1e-12, "{u:?}: |d| = {}", d.length());
        assert_eq!(
            sample.pdf.to_bits(),
            map.pdf(d).to_bits(),
            "{u:?}: sample pdf {} vs pdf(d) {}",
            sample.pdf,
            map.pdf(d)
        );
        assert_eq!(sample.radiance, map.eval(d), "{u:?}");
        assert!(!sample.radiance.is_black(), "{u:?}: sampled a black pixel towards {d}");
        observed[bin(d)] += 1.0;
    }
    // expected: pdf integrated over each bin (θ from the bin's cos θ range), piece by piece
    let pdf = |d: DVec3| map.pdf(d);
    let mut expected = vec![0.0; nz * nphi];
    for iz in 0..nz {
        let (z0, z1) =
            (-1.0 + 2.0 * iz as f64 / nz as f64, -1.0 + 2.0 * (iz + 1) as f64 / nz as f64);
        for ip in 0..nphi {
            let phis =
                (2.0 * PI * ip as f64 / nphi as f64, 2.0 * PI * (ip + 1) as f64 / nphi as f64);
            expected[iz * nphi + ip] =
                samples as f64 * integrate_by_pixels(&pdf, (z1.acos(), z0.acos()), phis, 8);
        }
    }
    let total: f64 = expected.iter().sum::<f64>() / samples as f64;
    assert!((total - 1.0).abs() < 1e-9, "expected counts sum to {total} of the samples");
    let empty = expected.iter().filter(|&&e| e == 0.0).count();
    assert!(empty > 0, "no bin lies wholly in black pixels: the test would not see them sampled");
    let outcome = chi2_test("envmap_directions", &observed, &expected, ALPHA, 1);
    assert!(outcome.dof > 500, "{outcome:?}");
}

#[test]
fn distribution2d_chi_square_on_a_foreign_grid() {
    // 7 × 5 cells with zeros, binned on 17 × 13: bins straddle cell edges
    let (w, h) = (7usize, 5usize);
    let mut s = rng(11);
    let weights: Vec<f64> =
        (0..w * h).map(|k| if k % 6 == 2 || k / w == 3 { 0.0 } else { s.next_f64() }).collect();
    let d = Distribution2D::new(&weights, w, h).unwrap();
    let (bu, bv, samples) = (17usize, 13usize, 100_000usize);
    let mut observed = vec![0.0; bu * bv];
    for _ in 0..samples {
        let sample = d.sample([s.next_f64(), s.next_f64()]);
        let [u, v] = sample.uv;
        assert_eq!(sample.pdf.to_bits(), d.pdf(sample.uv).to_bits());
        observed[((v * bv as f64) as usize) * bu + (u * bu as f64) as usize] += 1.0;
    }
    // expected: exact overlap of each bin with each cell, times the cell's density
    let total: f64 = weights.iter().sum();
    let overlap = |a0: f64, a1: f64, b0: f64, b1: f64| (a1.min(b1) - a0.max(b0)).max(0.0);
    let mut expected = vec![0.0; bu * bv];
    for (k, e) in expected.iter_mut().enumerate() {
        let (x, y) = ((k % bu) as f64, (k / bu) as f64);
        for (c, &wc) in weights.iter().enumerate() {
            let (i, j) = ((c % w) as f64, (c / w) as f64);
            let area =
                overlap(x / bu as f64, (x + 1.0) / bu as f64, i / w as f64, (i + 1.0) / w as f64)
                    * overlap(
                        y / bv as f64,
                        (y + 1.0) / bv as f64,
                        j / h as f64,
                        (j + 1.0) / h as f64,
                    );
            *e += samples as f64 * area * wc / total * (w * h) as f64;
        }
    }
    chi2_test("distribution2d_cells", &observed, &expected, ALPHA, 1);
}

#[test]
fn pdf_integrates_to_one_over_the_sphere() {
    let map = random_map();
    // a grid unaligned with the pixels: the error comes from pixel edges only
    let (nt, np) = (999usize, 1999usize);
    let (dt, dp) = (PI / nt as f64, 2.0 * PI / np as f64);
    let mut total = 0.0;
    for a in 0..nt {
        let theta = (a as f64 + 0.5) * dt;
        for b in 0..np {
            total += map.pdf(dir(theta, (b as f64 + 0.5) * dp)) * theta.sin();
        }
    }
    let total = total * dt * dp;
    assert!((total - 1.0).abs() < 1e-3, "∫ pdf dω = {total}");
}

#[test]
fn each_pixel_is_chosen_in_proportion_to_its_luminous_power() {
    let map = random_map();
    let pixels = random_pixels();
    let pdf = |d: DVec3| map.pdf(d);
    let mut luminance_integral = 0.0;
    for j in 0..H {
        let thetas = (PI * f64::from(j) / f64::from(H), PI * f64::from(j + 1) / f64::from(H));
        // exact solid angle of the pixel
        let omega = 2.0 * PI / f64::from(W) * (thetas.0.cos() - thetas.1.cos());
        for i in 0..W {
            // u = (1 − φ/π)/2: column i spans φ ∈ [π(1 − 2(i+1)/W), π(1 − 2i/W)]
            let phis = (
                PI * (1.0 - 2.0 * f64::from(i + 1) / f64::from(W)),
                PI * (1.0 - 2.0 * f64::from(i) / f64::from(W)),
            );
            let mass = integrate(&pdf, thetas, phis, 8);
            let y = luminance(pixels[(j * W + i) as usize]);
            let share = y * omega / map.luminance_integral();
            assert!(
                (mass - share).abs() <= 1e-9 * share.max(1e-3),
                "pixel ({i}, {j}): mass {mass} vs power share {share}"
            );
            luminance_integral += y * omega;
        }
    }
    assert!((map.luminance_integral() / luminance_integral - 1.0).abs() < 1e-12);
}

#[test]
fn luminance_integral_matches_quadrature_of_eval() {
    let map = random_map();
    let y = |d: DVec3| luminance(map.eval(d));
    let quadrature = integrate(&y, (0.0, PI), (-PI, PI), 1499);
    assert!(
        (quadrature / map.luminance_integral() - 1.0).abs() < 2e-3,
        "{quadrature} vs {}",
        map.luminance_integral()
    );
}

/// `Σ L/pdf` over samples, per channel and for luminance: mean and standard error.
fn estimate(map: &EnvironmentMap, samples: u64, seed: u64) -> [(f64, f64); 4] {
    let mut sums = [(0.0f64, 0.0f64); 4];
    let mut s = rng(seed);
    for _ in 0..samples {
        let sample = map.sample([s.next_f64(), s.next_f64()]).expect("a sample");
        let [r, g, b] = sample.radiance.to_f64();
        for (k, l) in [r, g, b, luminance(sample.radiance)].into_iter().enumerate() {
            let x = l / sample.pdf;
            sums[k].0 += x;
            sums[k].1 += x * x;
        }
    }
    sums.map(|(sum, sum_sq)| mean_stderr_from_sums(sum, sum_sq, samples))
}

#[test]
fn constant_map_estimator_averages_to_four_pi_l() {
    let l = Rgb([0.5, 1.0, 2.0]);
    let map = EnvironmentMap::from_pixels(W, H, vec![l; (W * H) as usize], "constant").unwrap();
    let [r, g, b, y] = estimate(&map, 100_000, 3);
    for ((mean, stderr), c) in [r, g, b, y].into_iter().zip([0.5, 1.0, 2.0, luminance(l)]) {
        let truth = 4.0 * PI * c;
        assert!(stderr > 0.0 && stderr < 0.01 * truth, "stderr {stderr}");
        assert!((mean - truth).abs() < 4.0 * stderr, "mean {mean} vs 4πL = {truth} (σ {stderr})");
    }
}

#[test]
fn random_map_estimator_averages_to_the_luminance_integral() {
    let map = random_map();
    let [.., (mean, stderr)] = estimate(&map, 100_000, 5);
    let truth = map.luminance_integral();
    assert!((mean - truth).abs() < 4.0 * stderr, "mean {mean} vs ∫Y dω = {truth} (σ {stderr})");
}

#[test]
fn one_bright_pixel_is_seen_towards_its_centre() {
    let (i, j) = (5, 2);
    let bright = Rgb([3.0, 4.0, 5.0]);
    let mut pixels = vec![Rgb::ZERO; (W * H) as usize];
    pixels[(j * W + i) as usize] = bright;
    let map = EnvironmentMap::from_pixels(W, H, pixels, "one pixel").unwrap();
    assert_eq!(map.eval(pixel_centre(i, j, W, H)), bright);
    for (a, b) in [(i - 1, j), (i + 1, j), (i, j - 1), (i, j + 1)] {
        assert_eq!(map.eval(pixel_centre(a, b, W, H)), Rgb::ZERO, "neighbour ({a}, {b})");
    }
    // every sample lands in that pixel
    let mut s = rng(1);
    for _ in 0..1000 {
        let sample = map.sample([s.next_f64(), s.next_f64()]).unwrap();
        assert_eq!(sample.radiance, bright);
        assert!(sample.direction.dot(pixel_centre(i, j, W, H)) > (PI / 8.0).cos() - 1e-12);
    }
}

#[test]
fn convention_axes() {
    // pixel value = (column, row, 1)
    let pixels = (0..W * H).map(|k| Rgb([(k % W) as f32, (k / W) as f32, 1.0])).collect();
    let map = EnvironmentMap::from_pixels(W, H, pixels, "axes").unwrap();
    let at = |d: DVec3| {
        let p = map.eval(d.normalize());
        (p.0[0] as u32, p.0[1] as u32)
    };
    let eps = 1e-6;
    // +X is u = 1/2: a little towards −Y (φ < 0) is column W/2, towards +Y column W/2 − 1
    assert_eq!(at(dir(PI / 2.0 - eps, -eps)), (W / 2, H / 2 - 1));
    assert_eq!(at(dir(PI / 2.0 + eps, eps)), (W / 2 - 1, H / 2));
    // +Y is u = 1/4, −Y u = 3/4, −X the seam u = 0 / 1
    assert_eq!(at(dir(PI / 2.0 - eps, PI / 2.0 - eps)), (W / 4, H / 2 - 1));
    assert_eq!(at(dir(PI / 2.0 - eps, -PI / 2.0 - eps)), (3 * W / 4, H / 2 - 1));
    assert_eq!(at(dir(PI / 2.0 - eps, PI - eps)), (0, H / 2 - 1));
    assert_eq!(at(dir(PI / 2.0 - eps, -PI + eps)), (W - 1, H / 2 - 1));
    // v = 0 (row 0, the top of the image) is +Z; the bottom row −Z
    assert_eq!(at(DVec3::Z).1, 0);
    assert_eq!(at(dir(0.1, 2.0)).1, 0);
    assert_eq!(at(-DVec3::Z).1, H - 1);
    assert_eq!(at(dir(PI - 0.1, 2.0)).1, H - 1);
    // every pixel, from directions all over the sphere, by the documented formula
    let mut s = rng(2);
    for _ in 0..10_000 {
        let d = dir((2.0 * s.next_f64() - 1.0).acos(), 2.0 * PI * s.next_f64());
        let u = 0.5 * (1.0 - d.y.atan2(d.x) / PI);
        let v = d.z.acos() / PI;
        let expected =
            (((u * f64::from(W)) as u32).min(W - 1), ((v * f64::from(H)) as u32).min(H - 1));
        assert_eq!(at(d), expected, "{d}");
    }
}

// ---------------------------------------------------------------------------------------
// Loading

fn write_rgb(path: &Path, w: usize, h: usize, f: impl Sync + Fn(usize, usize) -> (f32, f32, f32)) {
    exr::prelude::write_rgb_file(path, w, h, f).expect("write test EXR");
}

/// Pixel `(x, y)` of the loading tests: distinct, exact in `f16`.
fn value(x: usize, y: usize) -> (f32, f32, f32) {
    (x as f32 * 0.25, y as f32 + 0.5, (x + 8 * y) as f32 * 0.125)
}

fn check_loaded(map: &EnvironmentMap, w: u32, h: u32) {
    assert_eq!((map.width(), map.height()), (w, h));
    for j in 0..h {
        for i in 0..w {
            let (r, g, b) = value(i as usize, j as usize);
            assert_eq!(map.eval(pixel_centre(i, j, w, h)), Rgb([r, g, b]), "pixel ({i}, {j})");
        }
    }
}

#[test]
fn loads_f32_rgb_and_f16_rgba() {
    let dir = tmpdir("envmap", "load");
    let path = dir.join("rgb.exr");
    write_rgb(&path, 8, 4, value);
    check_loaded(&EnvironmentMap::load(&path).unwrap(), 8, 4);

    use exr::prelude::f16;
    let path = dir.join("rgba_half.exr");
    exr::prelude::write_rgba_file(&path, 8, 4, |x, y| {
        let (r, g, b) = value(x, y);
        (f16::from_f32(r), f16::from_f32(g), f16::from_f32(b), f16::ONE)
    })
    .unwrap();
    check_loaded(&EnvironmentMap::load(&path).unwrap(), 8, 4);
    let _ = std::fs::remove_dir_all(&dir);
}

/// An 8 × 4 EXR with a single `Y` channel.
fn write_luminance_only(path: &Path) {
    use exr::prelude::*;
    let channels =
        AnyChannels::sort(vec![AnyChannel::new("Y", FlatSamples::F32(vec![1.0; 32]))].into());
    Image::from_channels((8, 4), channels).write().to_file(path).unwrap();
}

/// The error of loading `path`, which must have exit code 3 and name the file.
fn load_error(path: &Path) -> (Error, String) {
    let e = EnvironmentMap::load(path).expect_err("loading should fail");
    let message = e.to_string();
    assert_eq!(e.exit_code(), 3, "{message}");
    assert!(
        message.contains(path.to_str().unwrap()),
        "{message:?} does not name {}",
        path.display()
    );
    assert!(!message.contains('\n'), "{message:?} is not one line");
    (e, message)
}

#[test]
fn bad_files_are_errors_naming_the_file() {
    let dir = tmpdir("envmap", "bad");

    let (e, _) = load_error(&dir.join("missing.exr"));
    assert!(matches!(e, Error::Open { .. }), "{e:?}");

    let text = dir.join("text.exr");
    std::fs::write(&text, "not an image\n").unwrap();
    let (_, m) = load_error(&text);
    assert!(m.contains("not a readable EXR"), "{m}");

    let square = dir.join("square.exr");
    write_rgb(&square, 3, 3, |_, _| (1.0, 1.0, 1.0));
    let (_, m) = load_error(&square);
    assert!(m.contains("3x3") && m.contains("not a lat-long map"), "{m}");

    let nan = dir.join("nan.exr");
    write_rgb(
        &nan,
        8,
        4,
        |x, y| if (x, y) == (3, 1) { (0.5, f32::NAN, 0.5) } else { (1.0, 1.0, 1.0) },
    );
    let (_, m) = load_error(&nan);
    assert!(m.contains("pixel (3, 1)") && m.contains("NaN"), "{m}");

    let negative = dir.join("negative.exr");
    write_rgb(
        &negative,
        8,
        4,
        |x, y| if (x, y) == (7, 3) { (-1.0, 0.0, 0.0) } else { (1.0, 1.0, 1.0) },
    );
    let (_, m) = load_error(&negative);
    assert!(m.contains("pixel (7, 3)") && m.contains("negative"), "{m}");

    let grey = dir.join("grey.exr");
    write_luminance_only(&grey);
    let (_, m) = load_error(&grey);
    assert!(m.contains("no R channel") && m.contains("has Y"), "{m}");

    let _ = std::fs::remove_dir_all(&dir);
}
