//! Motion blur's data (METHOD.md §13): the velocity, the shutter, and the
//! majorants dilated by the largest displacement.
//!
//! **Eulerian blur.** A sample at time `t` (seconds from the frame, in the shutter) sees
//! the volume advected back along its velocity: `μ(x, t) = μ(x − t·s·v(x))`, and the same
//! for emission and albedo (`s` the velocity scale). A uniform `v` blurs exactly like the
//! average of the volume translated by `t·s·v` over the shutter (tested).
//!
//! The field is then no longer piecewise polynomial along a ray, so paths are tracked by
//! null collisions (`medium::null_tracking`) under majorants whose cells are dilated by
//! `D = max|v| · s · max(|open|, |close|)` (in voxels per index axis: `D_world` times the
//! largest row 1-norm of the world-to-index map).

use glam::DVec3;

use super::brick::Volume;
use super::majorant::MajorantGrid;
use super::velocity::Velocity;

/// What a motion-blurred render needs besides the frame's volume.
#[derive(Clone, Debug)]
pub struct Motion {
    /// Velocity, world units per second.
    pub velocity: Velocity,
    /// Multiplies the velocity (`--velocity-scale`).
    pub scale: f64,
    /// Shutter open and close, seconds relative to the frame.
    pub shutter: [f64; 2],
    /// Majorants dilated by the largest displacement.
    pub majorants: MajorantGrid,
}

impl Motion {
    /// Motion of `volume` by `velocity × scale` over `shutter` (seconds).
    #[must_use]
    pub fn new(volume: &Volume, velocity: Velocity, scale: f64, shutter: [f64; 2]) -> Motion {
        let world = velocity.max_speed() * scale.abs() * shutter[0].abs().max(shutter[1].abs());
        let m = volume.index_from_world().matrix3;
        let row_norm =
            (0..3).map(|r| (0..3).map(|c| m.col(c)[r].abs()).sum::<f64>()).fold(0.0, f64::max);
        let majorants = MajorantGrid::new(volume, world * row_norm);
        Motion { velocity, scale, shutter, majorants }
    }

    /// The shutter time of a sample from a uniform `u` (seconds).
    #[inline]
    #[must_use]
    pub fn time(&self, u: f64) -> f64 {
        self.shutter[0] + u * (self.shutter[1] - self.shutter[0])
    }

    /// Where the volume at time `t` reads world point `p`: `p − t·s·v(p)`.
    #[inline]
    #[must_use]
    pub fn source_point(&self, p: DVec3, t: f64) -> DVec3 {
        p - self.velocity.at(p) * (t * self.scale)
    }
}
