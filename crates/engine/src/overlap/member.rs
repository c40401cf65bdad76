//! One volume of several ([`Member`]): its field, shared so that views and instances cost
//! no copy, its placement as an instance, its medium and how rays see it.

use std::sync::Arc;

use crate::medium::Medium;
use plume_volume::field::{Bounds3, Field};
use plume_volume::instance::Instance;

/// One volume among several: its field (shared, so views and instances cost no copy), its
/// grey medium and its visibility.
#[derive(Debug)]
pub struct Member<F: Field> {
    /// The volume, placed in the world.
    pub field: Arc<F>,
    /// Where an instance puts the volume, relative to the field's own world frame.
    pub instance: Option<Instance>,
    /// Its coefficients and emission (grey extinction).
    pub medium: Medium,
    /// Seen by camera rays.
    pub visible_to_camera: bool,
    /// Blocks shadow rays.
    pub casts_shadows: bool,
}

impl<F: Field> Member<F> {
    /// The world box of the volume where it is placed.
    pub fn world_bounds(&self) -> Bounds3 {
        let b = self.field.world_bounds();
        self.instance.map_or(b, |i| i.bounds(b))
    }
}
