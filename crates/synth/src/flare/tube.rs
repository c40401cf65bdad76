//! One loop in index space: its distance function, bounds and voxel evaluation.
//!
//! A [`Tube`] is a [`LoopSpec`] scaled to a resolution. Its centreline is the *full*
//! circle of the loop; the part below the photosphere lies outside the domain, so only
//! the arc between the footpoints (and the tube's cut ends at `y = 0`) is ever seen.
//!
//! For a point `p`, with `q = p − centre` split into in-plane components `(q·e1, q·e2)`
//! and out-of-plane `h = q·n`, the distance to the circle is
//! `√((|(q·e1, q·e2)| − R)² + h²)` (a torus' distance function), exact and 1-Lipschitz,
//! which is what makes the brick tests in `flare.rs` conservative. The angle from the
//! top, `φ = atan2(q·e1, q·e2)`, divided by the footpoints' angle gives the arc
//! coordinate `s ∈ [−1, 1]` (0 at the top) that drives the along-loop profiles.

use glam::{DVec3, IVec3, Vec3};

use super::layout::{LoopSpec, FOOT_TEMPERATURE, PEAK_TEMPERATURE};
use plume_volume::grid::{leaf_offset, LEAF_DIM, LEAF_VOXELS};

/// The tube widens by this fraction from the footpoints to the top.
const EXPANSION: f32 = 0.3;
/// Smallest tube radius, voxels: thinner loops are widened and their density reduced in
/// proportion to the cross-section, so they neither alias into dots at low resolution
/// nor change their emission per unit length.
pub const MIN_TUBE_RADIUS: f64 = 0.8;
/// Fraction of the arc (from each footpoint) over which the legs cool to the footpoint
/// temperature.
const LEG: f32 = 0.35;

/// Per-voxel accumulators of one brick: `Σ ρᵢ` and `Σ ρᵢ·Tᵢ` over loops `i`.
pub struct Accumulator {
    pub density: [f32; LEAF_VOXELS],
    pub weighted_temperature: [f32; LEAF_VOXELS],
}

/// A loop scaled to index space (voxel units).
#[derive(Clone, Debug)]
pub struct Tube {
    /// Circle centre, index space.
    centre: DVec3,
    e1: Vec3,
    e2: Vec3,
    normal: Vec3,
    /// Circle radius, voxels.
    radius: f32,
    inverse_half_angle: f32,
    /// Bound on the tube radius anywhere along the loop, voxels: no voxel farther than
    /// this from the circle has density.
    pub reach: f32,
    /// The along-arc profiles (tube radius in voxels, density, temperature) tabulated at
    /// `s = −1 + 2i/n`, `i = 0 … n`, interpolated linearly: the libm sines and the knot
    /// are evaluated once per node instead of once per voxel.
    profile: Vec<Profile>,
    /// `n / 2`, maps `s + 1` to a table position.
    table_scale: f32,
    /// Index-space bounds of the tube (the whole torus, not clipped to the domain).
    pub lo: DVec3,
    pub hi: DVec3,
}

/// Along-arc profile values at one table node.
#[derive(Clone, Copy, Debug)]
struct Profile {
    radius: f32,
    density: f32,
    temperature: f32,
}

impl Tube {
    /// `spec` at `resolution` voxels per unit length (index = normalised·resolution − ½).
    pub fn new(spec: &LoopSpec, resolution: f64) -> Tube {
        let circle = spec.circle();
        let centre = circle.centre * resolution - 0.5;
        let radius = circle.radius * resolution;
        let natural = spec.radius * resolution;
        let tube_radius = natural.max(MIN_TUBE_RADIUS);
        let widening = (natural / tube_radius).powi(2) as f32;
        // About one node per 4 voxels of arc, 64 to 4096 nodes
        let arc = 2.0 * circle.half_angle * radius;
        let nodes = ((arc / 4.0).ceil() as usize).clamp(64, 4096);
        let profile: Vec<Profile> = (0..=nodes)
            .map(|i| {
                let s = (-1.0 + 2.0 * i as f64 / nodes as f64) as f32;
                profile_at(spec, tube_radius as f32, spec.density * widening, s)
            })
            .collect();
        let reach = profile.iter().map(|p| p.radius).fold(0.0, f32::max);
        // Extent of a circle along axis k: R·√(1 − n_k²)
        let extent = (DVec3::ONE - circle.normal * circle.normal).max(DVec3::ZERO).map(f64::sqrt)
            * radius
            + f64::from(reach);
        Tube {
            centre,
            e1: circle.e1.as_vec3(),
            e2: circle.e2.as_vec3(),
            normal: circle.normal.as_vec3(),
            radius: radius as f32,
            inverse_half_angle: (1.0 / circle.half_angle) as f32,
            reach,
            profile,
            table_scale: 0.5 * nodes as f32,
            lo: centre - extent,
            hi: centre + extent,
        }
    }

    /// Distance from `p` (index space) to the circle, voxels.
    pub fn distance(&self, p: DVec3) -> f64 {
        let q = p - self.centre;
        let (e1, e2, n) = (self.e1.as_dvec3(), self.e2.as_dvec3(), self.normal.as_dvec3());
        let in_plane = (q.dot(e1).powi(2) + q.dot(e2).powi(2)).sqrt() - f64::from(self.radius);
        (in_plane * in_plane + q.dot(n).powi(2)).sqrt()
    }

    /// The circle point at angle `phi` from the top, index space.
    pub fn point(&self, phi: f64) -> DVec3 {
        let (sin, cos) = phi.sin_cos();
        self.centre + f64::from(self.radius) * (sin * self.e1.as_dvec3() + cos * self.e2.as_dvec3())
    }

    /// Circle radius, voxels.
    pub fn circle_radius(&self) -> f64 {
        f64::from(self.radius)
    }

    /// Adds this loop's density and density-weighted temperature to the voxels of the
    /// brick at voxel `origin`, local indices below `end` (each ≤ 8).
    pub fn accumulate(&self, origin: IVec3, end: IVec3, acc: &mut Accumulator) {
        debug_assert!(end.cmple(IVec3::splat(LEAF_DIM)).all());
        let o = (origin.as_dvec3() - self.centre).as_vec3();
        let (e1, e2, n) = (self.e1, self.e2, self.normal);
        let q0 = Vec3::new(o.dot(e1), o.dot(e2), o.dot(n));
        let reach = self.local_reach(q0 + 3.5 * (e1 + e2 + n));
        let reach2 = reach * reach;
        let steps: [f32; 8] = std::array::from_fn(|z| z as f32);
        for x in 0..end.x {
            for y in 0..end.y {
                let (fx, fy) = (x as f32, y as f32);
                let row = q0
                    + Vec3::new(fx * e1.x + fy * e1.y, fx * e2.x + fy * e2.y, fx * n.x + fy * n.y);
                // In-plane (a, b) and out-of-plane h components of p − centre along the
                // row, and squared distances to the circle (8 lanes, vectorisable)
                let a: [f32; 8] = std::array::from_fn(|z| row.x + steps[z] * e1.z);
                let b: [f32; 8] = std::array::from_fn(|z| row.y + steps[z] * e2.z);
                let d2: [f32; 8] = std::array::from_fn(|z| {
                    let h = row.z + steps[z] * n.z;
                    let radial = (a[z] * a[z] + b[z] * b[z]).sqrt() - self.radius;
                    radial * radial + h * h
                });
                for z in 0..end.z as usize {
                    if d2[z] < reach2 {
                        self.add_voxel(a[z], b[z], d2[z], leaf_offset(x, y, z as i32), acc);
                    }
                }
            }
        }
    }

    /// Whether the brick whose voxel centres span `centre ± 3.5` (index space) may get
    /// density from this tube: its bounding sphere comes within the local reach (plus
    /// `margin` voxels) of the circle. Exact arithmetic aside, never false for a brick
    /// that [`Tube::accumulate`] adds density to.
    pub fn may_reach_brick(&self, centre: DVec3, margin: f64) -> bool {
        let brick_radius = 3.5 * 3f64.sqrt();
        let distance = self.distance(centre);
        if distance >= f64::from(self.reach) + brick_radius + margin {
            return false;
        }
        let q = centre - self.centre;
        let (e1, e2, n) = (self.e1.as_dvec3(), self.e2.as_dvec3(), self.normal.as_dvec3());
        let reach = self.local_reach(DVec3::new(q.dot(e1), q.dot(e2), q.dot(n)).as_vec3());
        distance < f64::from(reach) + brick_radius + margin
    }

    /// A bound on the tube radius over a brick whose centre is at `q` (components along
    /// e1, e2, n relative to the circle's centre): the largest table node the brick's
    /// voxels can interpolate from, else [`Tube::reach`]. Same values with either bound;
    /// the local one only skips more voxels.
    fn local_reach(&self, q: Vec3) -> f32 {
        use std::f32::consts::PI;
        // Angle seen from the circle's centre, plus the brick's bounding sphere and
        // fast_atan2's error
        let in_plane = (q.x * q.x + q.y * q.y).sqrt();
        let brick_radius = 3.5 * 3f32.sqrt();
        if in_plane <= 2.0 * brick_radius {
            return self.reach;
        }
        let phi = fast_atan2(q.x, q.y);
        let spread = (brick_radius / in_plane).asin() + 1e-4;
        if phi.abs() + spread >= PI {
            return self.reach;
        }
        let to_position =
            |phi: f32| ((phi * self.inverse_half_angle).clamp(-1.0, 1.0) + 1.0) * self.table_scale;
        let last = self.profile.len() - 1;
        let lo = (to_position(phi - spread).floor().max(0.0) as usize).min(last);
        let hi = (to_position(phi + spread).ceil() as usize + 1).min(last);
        self.profile[lo..=hi].iter().map(|p| p.radius).fold(0.0, f32::max)
    }

    /// One voxel within reach: arc coordinate, interpolated profiles, cross-section.
    #[inline]
    fn add_voxel(&self, a: f32, b: f32, d2: f32, offset: usize, acc: &mut Accumulator) {
        let s = (fast_atan2(a, b) * self.inverse_half_angle).clamp(-1.0, 1.0);
        let position = (s + 1.0) * self.table_scale;
        let i = (position as usize).min(self.profile.len() - 2);
        let f = position - i as f32;
        let (p0, p1) = (self.profile[i], self.profile[i + 1]);
        let r = p0.radius + f * (p1.radius - p0.radius);
        let r2 = r * r;
        if d2 >= r2 {
            return;
        }
        // Tube cross-section (1 − d²/r²)², smooth with compact support
        let t = 1.0 - d2 / r2;
        let density = (p0.density + f * (p1.density - p0.density)) * (t * t);
        let temperature = p0.temperature + f * (p1.temperature - p0.temperature);
        acc.density[offset] += density;
        acc.weighted_temperature[offset] += density * temperature;
    }
}

/// Tube radius (voxels), density and temperature (Kelvin) at arc coordinate `s` of
/// `spec`, for a tube of `tube_radius` voxels at the footpoints and density scale
/// `density`.
fn profile_at(spec: &LoopSpec, tube_radius: f32, density: f32, s: f32) -> Profile {
    let [wa, wk, wp] = spec.wobble;
    let radius = tube_radius * (1.0 + EXPANSION * (1.0 - s * s)) * (1.0 + wa * (wk * s + wp).sin());
    // Beading along the loop
    let [ba, k1, p1, k2, p2] = spec.beading;
    let mut density = density * (1.0 + ba * (k1 * s + p1).sin() * (k2 * s + p2).sin());
    // Legs cool towards the footpoints
    let mut temperature = FOOT_TEMPERATURE
        + (spec.top_temperature - FOOT_TEMPERATURE) * smoothstep((1.0 - s.abs()) / LEG);
    if let Some(knot) = spec.knot {
        let u = (s - knot.centre) / knot.half_width;
        if u.abs() < 1.0 {
            let bump = (1.0 - u * u) * (1.0 - u * u);
            density *= 1.0 + knot.gain * bump;
            temperature += (knot.temperature - temperature) * bump;
        }
    }
    Profile { radius, density, temperature: temperature.clamp(FOOT_TEMPERATURE, PEAK_TEMPERATURE) }
}

/// Cubic smoothstep of `t` clamped to `[0, 1]`.
fn smoothstep(t: f32) -> f32 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// `atan2(y, x)` to within 2·10⁻⁵ rad (about a tenth of a voxel along a 4096-voxel loop),
/// several times faster than the libm call: an odd minimax polynomial for `atan` on
/// `[0, 1]` (Abramowitz & Stegun 4.4.49 style), then octant fix-ups. 0 for `(0, 0)`.
#[inline]
pub fn fast_atan2(y: f32, x: f32) -> f32 {
    use std::f32::consts::{FRAC_PI_2, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = if ax > ay { (ay, ax) } else { (ax, ay) };
    if large == 0.0 {
        return 0.0;
    }
    let z = small / large;
    let z2 = z * z;
    let mut r = z
        * (0.999_977_26
            + z2 * (-0.332_623_47
                + z2 * (0.193_543_46
                    + z2 * (-0.116_432_87 + z2 * (0.052_653_32 - 0.011_721_2 * z2)))));
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        -r
    } else {
        r
    }
}
