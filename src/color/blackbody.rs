//! Temporary stand-in (replaced by the colour work on branch `color`).
use super::Rgb;
/// Default cutoff.
pub const DEFAULT_CUTOFF_KELVIN: f32 = 500.0;
/// Table.
pub struct BlackbodyTable;
static T: BlackbodyTable = BlackbodyTable;
/// Table access.
pub fn blackbody_table() -> &'static BlackbodyTable { &T }
impl BlackbodyTable {
    /// C(T).
    pub fn rgb(&self, t: f32) -> Rgb { Rgb::splat(t * 1e-3) }
    /// C/Y.
    pub fn chromaticity(&self, _t: f32) -> Rgb { Rgb::ONE }
}
/// Cycles.
pub fn cycles_blackbody(t: f32) -> Rgb { Rgb::splat(5.670373e-8 / std::f32::consts::PI * 1e-6 * t.powi(4)) }
