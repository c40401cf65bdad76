//! Where the loops of a flare go: a seeded list of [`LoopSpec`]s in the unit cube.
//!
//! Coordinates here are *normalised*: the domain is `[0, 1]³`, y up, the photosphere is
//! the plane `y = 0`. Nothing depends on the resolution, so every resolution samples the
//! same loops (`flare.rs` scales them to index space).
//!
//! Two populations (Aschwanden, *Physics of the Solar Corona*, 2005, ch. 3 and 10):
//! - **The flare arcade**: short, low, hot loops straddling a curved polarity inversion
//!   line (PIL) that runs diagonally across the box, sheared along it, taller towards the
//!   middle of the PIL, with hot knots (flare kernels) near some loop tops.
//! - **Active-region loops**: longer, taller, fatter, fainter and cooler loops in fans
//!   between sunspot-like footpoint patches of opposite polarity on either side of the
//!   PIL (nearer pairs of patches preferred), arching over the arcade.
//!
//! Each loop draws its random numbers from its own SplitMix64 stream keyed by (seed,
//! population, index), so changing the loop counts leaves the other loops unchanged.

use std::f64::consts::{PI, TAU};

use glam::{DVec2, DVec3};

/// Coolest temperature anywhere in a loop (its footpoints), Kelvin.
pub const FOOT_TEMPERATURE: f32 = 1.0e6;
/// Hottest temperature anywhere (knots of the hottest arcade loops), Kelvin.
pub const PEAK_TEMPERATURE: f32 = 2.0e7;

/// One coronal loop in normalised coordinates: a circular arc in a (possibly tilted)
/// plane through two footpoints on `y = 0`, wrapped in a tube.
#[derive(Clone, Debug, PartialEq)]
pub struct LoopSpec {
    /// Footpoints, on `y = 0`, distinct.
    pub feet: [DVec2; 2],
    /// Height of the arc's top above the photosphere, measured in the loop's plane.
    pub height: f64,
    /// Rotation of the loop's plane about the footpoint axis, radians (0: vertical).
    pub tilt: f64,
    /// Tube radius at the footpoints (the tube widens towards the top), normalised units.
    pub radius: f64,
    /// Density scale (unitless, before the tube profile and modulations).
    pub density: f32,
    /// Temperature on the upper part of the loop, Kelvin (the legs cool to
    /// [`FOOT_TEMPERATURE`]).
    pub top_temperature: f32,
    /// A hot, dense knot near the top, if any.
    pub knot: Option<Knot>,
    /// Along-arc beading: density × (1 + a·sin(k₁s + p₁)·sin(k₂s + p₂)), `[a, k₁, p₁, k₂, p₂]`.
    pub beading: [f32; 5],
    /// Along-arc radius wobble: radius × (1 + a·sin(ks + p)), `[a, k, p]`.
    pub wobble: [f32; 3],
}

/// A flare kernel on a loop: density gain and heating in a window of the arc coordinate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Knot {
    /// Centre in the arc coordinate `s` (−1, +1 at the footpoints, 0 at the top).
    pub centre: f32,
    /// Half width in `s`.
    pub half_width: f32,
    /// Peak density gain: density × (1 + gain·bump).
    pub gain: f32,
    /// Temperature at the knot's centre, Kelvin.
    pub temperature: f32,
}

/// Loop counts and knot probability; see `FlareParams`.
#[derive(Clone, Copy, Debug)]
pub struct LayoutCounts {
    pub arcade: u32,
    pub active_region: u32,
    pub knot_fraction: f32,
}

/// Footpoints are kept this far inside the box's side faces.
const SIDE_MARGIN: f64 = 0.03;
/// Tallest loop, leaving the top of the box empty.
const MAX_HEIGHT: f64 = 0.8;

/// SplitMix64 (Steele et al. 2014): a tiny, seedable, splittable generator.
struct SplitMix64(u64);

impl SplitMix64 {
    fn new(seed: u64, population: u64, index: u64) -> SplitMix64 {
        let mut rng = SplitMix64(seed ^ population.wrapping_mul(0xd1b5_4a32_d192_ed03));
        rng.0 ^= rng.next_u64() ^ index.wrapping_mul(0x9e37_79b9_7f4a_7c15);
        rng
    }

    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        plume_core::sampling::mix64(self.0)
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Log-uniform in `[lo, hi]`, both positive.
    fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.unit()).exp()
    }

    /// Uniform in the disc of `radius` around `centre`.
    fn in_disc(&mut self, centre: DVec2, radius: f64) -> DVec2 {
        let (r, a) = (radius * self.unit().sqrt(), TAU * self.unit());
        centre + r * DVec2::new(a.cos(), a.sin())
    }

    fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }
}

/// All loops for `seed`: the arcade first, then the active-region loops.
pub fn loops(seed: u64, counts: LayoutCounts) -> Vec<LoopSpec> {
    let pil = Pil::new(&mut SplitMix64::new(seed, 0, 0));
    let arcade = (0..counts.arcade).map(|i| {
        arcade_loop(&pil, &mut SplitMix64::new(seed, 1, u64::from(i)), counts.knot_fraction)
    });
    let spots = Spots::new(&pil, &mut SplitMix64::new(seed, 0, 1));
    let mut active: Vec<LoopSpec> = (0..counts.active_region)
        .map(|i| active_region_loop(&spots, &mut SplitMix64::new(seed, 2, u64::from(i))))
        .collect();
    // Normalise Σ arc·(radius + D)², the active-region loops' volume dilated by about
    // the reach of a brick at 4096³ (D = 5/4096), which sets the data size: seeds would
    // otherwise differ by ±25 % with the patches' spacing. Solve for one common radius
    // scale k: A·k² + 2B·k + C = target.
    const D: f64 = 5.0 / 4096.0;
    let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
    for spec in &active {
        let circle = spec.circle();
        let arc = 2.0 * circle.half_angle * circle.radius;
        (a, b, c) =
            (a + arc * spec.radius * spec.radius, b + arc * spec.radius * D, c + arc * D * D);
    }
    let target = ACTIVE_REGION_VOLUME_PER_LOOP * active.len() as f64;
    if a > 0.0 && target > c {
        let scale = (-b + (b * b + a * (target - c)).sqrt()) / a;
        for spec in &mut active {
            spec.radius *= scale;
        }
    }
    arcade.chain(active).collect()
}

/// Target of Σ arc·(radius + D)² per active-region loop, normalised units (see [`loops`]).
const ACTIVE_REGION_VOLUME_PER_LOOP: f64 = 4.4e-5;

/// The polarity inversion line: a gentle S curve in the (x, z) plane,
/// `c(t) = start + t·(end − start) + bend·sin(2πt + phase)·normal`, `t ∈ [0, 1]`.
struct Pil {
    start: DVec2,
    end: DVec2,
    bend: f64,
    phase: f64,
}

impl Pil {
    fn new(rng: &mut SplitMix64) -> Pil {
        // Diagonal across the box, so that the default three-quarter view sees the
        // arcade obliquely (a row of arcs), not end-on or as a picket fence.
        let angle = rng.uniform(0.3, 0.5);
        let half = 0.33 * DVec2::new(angle.cos(), angle.sin());
        let centre =
            DVec2::new(0.5, 0.5) + DVec2::new(rng.uniform(-0.04, 0.04), rng.uniform(-0.04, 0.04));
        Pil {
            start: centre - half,
            end: centre + half,
            bend: rng.uniform(0.03, 0.06),
            phase: rng.uniform(0.0, TAU),
        }
    }

    fn axis_normal(&self) -> DVec2 {
        let d = (self.end - self.start).normalize();
        DVec2::new(-d.y, d.x)
    }

    fn point(&self, t: f64) -> DVec2 {
        self.start
            + t * (self.end - self.start)
            + self.bend * (TAU * t + self.phase).sin() * self.axis_normal()
    }

    /// Unit tangent at `t`.
    fn tangent(&self, t: f64) -> DVec2 {
        let derivative = (self.end - self.start)
            + self.bend * TAU * (TAU * t + self.phase).cos() * self.axis_normal();
        derivative.normalize()
    }
}

fn arcade_loop(pil: &Pil, rng: &mut SplitMix64, knot_fraction: f32) -> LoopSpec {
    let t = rng.unit();
    let (centre, tangent) = (pil.point(t), pil.tangent(t));
    let normal = DVec2::new(-tangent.y, tangent.x);
    // Nested arcade: taller in the middle of the PIL; each loop a fraction of the
    // envelope, most close to it (the outer, newest loops)
    let envelope = 0.05 + 0.13 * (PI * t).sin().powf(0.6);
    let relative = 1.0 - 0.6 * rng.unit().powi(2);
    let height = envelope * relative;
    // Footpoint half-separation: a little flatter or taller than a semicircle
    let half_separation = height * rng.uniform(0.8, 1.15);
    // Sheared arcade: feet displaced along the PIL in opposite directions
    let shear = half_separation * rng.uniform(0.15, 0.35);
    let feet = [
        centre - half_separation * normal - shear * tangent,
        centre + half_separation * normal + shear * tangent,
    ];
    // Higher (later, in the standard flare model) loops are hotter
    let hotness = (0.6 * relative + 0.4 * rng.unit()).clamp(0.0, 1.0);
    let top_temperature = 10f64.powf(6.5 + 0.75 * hotness) as f32;
    let knot = rng.chance(f64::from(knot_fraction)).then(|| Knot {
        centre: rng.uniform(-0.3, 0.3) as f32,
        half_width: rng.uniform(0.08, 0.2) as f32,
        gain: rng.uniform(1.5, 4.0) as f32,
        temperature: rng.uniform(1.2e7, f64::from(PEAK_TEMPERATURE)) as f32,
    });
    LoopSpec {
        feet: feet.map(clamp_inside),
        height,
        tilt: rng.uniform(-0.12, 0.12),
        radius: rng.log_uniform(0.0008, 0.0025),
        density: rng.uniform(0.4, 1.0) as f32,
        top_temperature,
        knot,
        beading: modulation(rng, 0.5, 6.0, 20.0),
        wobble: {
            let [a, k, p, _, _] = modulation(rng, 0.2, 3.0, 10.0);
            [a, k, p]
        },
    }
}

/// Sunspot-like footpoint patches of the active-region loops: [`SPOTS`] of each
/// polarity, the positive ones on one side of the PIL, the negative on the other.
struct Spots {
    /// Centre and radius of each patch, positive then negative.
    patches: [[(DVec2, f64); SPOTS]; 2],
}

/// Footpoint patches per polarity.
const SPOTS: usize = 5;

impl Spots {
    fn new(pil: &Pil, rng: &mut SplitMix64) -> Spots {
        let (normal, along) = (pil.axis_normal(), (pil.end - pil.start).normalize());
        let middle = pil.point(0.5);
        let mut patch = |side: f64, i: usize| {
            let offset =
                along * (0.45 * ((i as f64 + rng.uniform(0.2, 0.8)) / SPOTS as f64 - 0.5) * 2.0);
            let centre = middle + offset + side * rng.uniform(0.16, 0.3) * normal;
            (clamp_inside(centre), rng.uniform(0.05, 0.1))
        };
        let positive = std::array::from_fn(|i| patch(-1.0, i));
        let negative = std::array::from_fn(|i| patch(1.0, i));
        Spots { patches: [positive, negative] }
    }
}

fn active_region_loop(spots: &Spots, rng: &mut SplitMix64) -> LoopSpec {
    // A positive and a negative patch, nearer pairs more likely (weights 1/distance)
    let pick = |rng: &mut SplitMix64| (rng.unit() * SPOTS as f64) as usize % SPOTS;
    let (mut i, mut j) = (pick(rng), pick(rng));
    for _ in 0..2 {
        let (a, b) = (pick(rng), pick(rng));
        let distance =
            |i: usize, j: usize| (spots.patches[0][i].0 - spots.patches[1][j].0).length();
        if distance(a, b) < distance(i, j) {
            (i, j) = (a, b);
        }
    }
    let ((pc, pr), (nc, nr)) = (spots.patches[0][i], spots.patches[1][j]);
    let positive = rng.in_disc(pc, pr);
    let negative = rng.in_disc(nc, nr);
    let half_separation = 0.5 * (negative - positive).length().max(0.05);
    let height = (half_separation * rng.uniform(0.5, 1.3)).min(MAX_HEIGHT);
    LoopSpec {
        feet: [clamp_inside(positive), clamp_inside(negative)],
        height,
        tilt: rng.uniform(-0.5, 0.5),
        radius: rng.log_uniform(0.0035, 0.012),
        density: rng.uniform(0.015, 0.045) as f32,
        top_temperature: rng.log_uniform(1.3e6, 3.5e6) as f32,
        knot: None,
        beading: modulation(rng, 0.4, 3.0, 12.0),
        wobble: {
            let [a, k, p, _, _] = modulation(rng, 0.25, 2.0, 8.0);
            [a, k, p]
        },
    }
}

/// `[a, k₁, p₁, k₂, p₂]` with `a ∈ [0, max_amplitude]` and wave numbers in `[k_lo, k_hi]`.
fn modulation(rng: &mut SplitMix64, max_amplitude: f64, k_lo: f64, k_hi: f64) -> [f32; 5] {
    [
        rng.uniform(0.0, max_amplitude) as f32,
        rng.uniform(k_lo, k_hi) as f32,
        rng.uniform(0.0, TAU) as f32,
        rng.uniform(k_lo, k_hi) as f32,
        rng.uniform(0.0, TAU) as f32,
    ]
}

fn clamp_inside(p: DVec2) -> DVec2 {
    p.clamp(DVec2::splat(SIDE_MARGIN), DVec2::splat(1.0 - SIDE_MARGIN))
}

/// A loop's plane and circle in normalised coordinates.
#[derive(Clone, Copy, Debug)]
pub struct Circle {
    /// Centre (may lie below the photosphere: the loop is then less than a semicircle).
    pub centre: DVec3,
    /// Unit vector from foot 0 to foot 1 (horizontal).
    pub e1: DVec3,
    /// Unit vector in the loop's plane, perpendicular to `e1`, pointing to the top.
    pub e2: DVec3,
    /// Unit normal of the plane, `e1 × e2`.
    pub normal: DVec3,
    /// Radius.
    pub radius: f64,
    /// Angle from the top to either footpoint, radians, in `(0, π)`.
    pub half_angle: f64,
}

impl LoopSpec {
    /// The circle through both footpoints whose top is `height` above their midpoint,
    /// along `e2`.
    pub fn circle(&self) -> Circle {
        let [a, b] = self.feet.map(|f| DVec3::new(f.x, 0.0, f.y));
        let (middle, half_separation) = (0.5 * (a + b), 0.5 * (b - a).length().max(1e-6));
        let e1 = (b - a).normalize_or(DVec3::X);
        let side = e1.cross(DVec3::Y).normalize();
        let e2 = self.tilt.cos() * DVec3::Y + self.tilt.sin() * side;
        // Centre offset c along e2 with c + R = height, R² = d² + c²
        let h = self.height.max(1e-6);
        let c = (h * h - half_separation * half_separation) / (2.0 * h);
        let radius = (h * h + half_separation * half_separation) / (2.0 * h);
        Circle {
            centre: middle + c * e2,
            e1,
            e2,
            normal: e1.cross(e2),
            radius,
            half_angle: 0.5 * PI + (c / radius).clamp(-1.0, 1.0).asin(),
        }
    }
}
