//! What sampling a light besides the volume returns ([`LightSample`]), and the
//! orthonormal frame the lights sample cones and discs in ([`frame`]).

use glam::DVec3;

/// A sampled direction towards a light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point towards the light.
    pub direction: DVec3,
    /// Distance to the light along `direction` (∞ for distant lights and environments).
    pub distance: f64,
    /// `L(ω)/p(ω)` for an area light; the irradiance at the point for a delta light.
    pub value: [f64; 3],
    /// Solid-angle pdf `p(ω)` of the light's own sampling; 0 for a delta light.
    pub pdf: f64,
}

/// An orthonormal pair perpendicular to unit `n` (Duff et al. 2017).
#[must_use]
pub fn frame(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}
