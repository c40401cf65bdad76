//! What a scene of several volumes cannot do yet, refused by [`crate::Shot::validate`]
//! with one message each naming the key of the volume at fault. A scene is several when it
//! has more than one volume or any volume has `instances`
//! ([`SceneDescription::is_several`]); a scene of one volume without instances passes
//! untouched.
//!
//! - All volumes share one reconstruction (`interpolation`).
//! - Motion blur (`velocity_grid`), albedo grids and absorption colours are for one
//!   volume only.
//! - Several volumes are tracked regularly (no `integrator.tracking = "null"`).
//! - At most [`MAX_SCATTERING_MEDIA`] distinct scattering media, each an albedo colour
//!   and a `g`.

use super::SceneDescription;
use crate::choice::{Choice, TrackingChoice};
use crate::volumes::EntryRef;
use plume_core::error::{Error, Result};

/// The most distinct scattering media (albedo colour and `g`) among the volumes that
/// scatter.
pub const MAX_SCATTERING_MEDIA: usize = 8;

/// Refuse what several volumes cannot do yet; `entries` are `scene`'s.
///
/// # Errors
/// [`Error::InvalidArgument`] naming the key of the first volume at fault.
pub(crate) fn check(scene: &SceneDescription, entries: &[EntryRef<'_>]) -> Result<()> {
    let [first, ..] = entries else { return Ok(()) };
    if !scene.is_several() {
        return Ok(());
    }
    for e in entries {
        one_volume_only(e)?;
        if e.volume.interpolation != first.volume.interpolation {
            return Err(Error::invalid(
                &e.key("interpolation"),
                format!(
                    "{} differs from the first volume's {}: all volumes share one reconstruction",
                    e.volume.interpolation.name(),
                    first.volume.interpolation.name()
                ),
            ));
        }
    }
    if scene.integrator.tracking == TrackingChoice::Null {
        return Err(Error::invalid(
            "integrator.tracking",
            "null tracks one volume: several volumes and instances are tracked regularly (use auto or regular)",
        ));
    }
    scattering_media(scene, entries)
}

/// A volume's keys that only a scene of one volume may give.
fn one_volume_only(e: &EntryRef<'_>) -> Result<()> {
    let refuse = |field: &str, what: &str| {
        Err(Error::invalid(
            &e.key(field),
            format!("{what} is for a scene of one volume only, for now: leave it out with several volumes or instances"),
        ))
    };
    if e.volume.velocity_grid.is_some() {
        return refuse("velocity_grid", "motion blur");
    }
    if e.volume.albedo_grid.is_some() {
        return refuse("albedo_grid", "an albedo grid");
    }
    if e.medium.absorption_color.is_some() {
        return refuse("medium.absorption_color", "an absorption colour (coloured extinction)");
    }
    Ok(())
}

/// At most [`MAX_SCATTERING_MEDIA`] distinct pairs (albedo colour, `g`) among the volumes
/// that scatter.
fn scattering_media(scene: &SceneDescription, entries: &[EntryRef<'_>]) -> Result<()> {
    if scene.integrator.max_depth == 0 {
        return Ok(());
    }
    let mut media: Vec<([f32; 3], f64)> = Vec::new();
    for e in entries.iter().filter(|e| e.albedo() > 0.0) {
        let medium = (e.albedo_rgb(), e.medium.g);
        if media.contains(&medium) {
            continue;
        }
        if media.len() == MAX_SCATTERING_MEDIA {
            return Err(Error::invalid(
                &e.key("medium"),
                format!(
                    "a {}th distinct scattering medium (albedo {:?}, g {}): at most {MAX_SCATTERING_MEDIA} pairs of albedo colour and g may scatter",
                    MAX_SCATTERING_MEDIA + 1,
                    medium.0,
                    medium.1
                ),
            ));
        }
        media.push(medium);
    }
    Ok(())
}
