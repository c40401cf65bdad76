//! One scene moved between reconstructions, shared by the cost renders and the close-up.

use plume_engine::integrator::AnyScene;
use plume_volume::Interpolation;

/// Moves one scene between reconstructions (the volume is never copied).
pub(super) struct Switch(pub(super) Option<AnyScene>);

impl Switch {
    /// The scene with `interpolation`.
    pub(super) fn to(&mut self, interpolation: Interpolation) -> &AnyScene {
        let s = self.0.take().expect("invariant: the scene is put back after every switch");
        self.0.insert(s.into_interpolation(interpolation))
    }
}
