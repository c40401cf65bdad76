//! What a description means for reading: the grid requests its bindings make, the
//! emission kind and model they resolve to, the reader's limits and isolation, the
//! memory budget. Shared by [`crate::load`] and the brick-cache conversion
//! (`cache::convert`), which both depend on it and not on each other's callers.

use std::time::Duration;

use crate::vdb::{GridRequest, GridSelector, ReadIsolation, ReadLimits};
use plume_core::color::Rgb;
use plume_core::error::{Error, Result};
use plume_engine::medium::{Emission, EmissionKind};
use plume_scene::validate::selector;
use plume_scene::{EmissionSettings, EmissionSource, JobSettings, ReadSettings, VolumeInput};
use plume_volume::out_of_core::memory::MemoryLimits;

/// Emission grid names tried, in order, by `emission.source = "auto"` and by `"grid"`
/// without `volume.emission_grid`.
pub const EMISSION_GRID_CANDIDATES: [&str; 4] = ["emission", "flame", "heat", "flame_noise"];

/// The grids a volume is built from, as read requests: density, then the source
/// (temperature or emission grid, per `emission.source`; none for `none`), then the
/// albedo grid if any. See [`split_found`].
///
/// # Errors
/// A selector that does not parse.
pub(crate) fn grid_requests(
    volume: &VolumeInput,
    source: EmissionSource,
) -> Result<Vec<GridRequest>> {
    let candidates = || -> Result<Vec<GridSelector>> {
        EMISSION_GRID_CANDIDATES.iter().map(|n| selector("volume.emission_grid", n)).collect()
    };
    let temperature = selector("volume.temperature_grid", &volume.temperature_grid)?;
    let mut requests =
        vec![GridRequest::required(selector("volume.density_grid", &volume.density_grid)?)];
    match source {
        EmissionSource::None => {}
        EmissionSource::Blackbody => requests.push(GridRequest::required(temperature)),
        EmissionSource::Grid => {
            let alternatives = match &volume.emission_grid {
                Some(n) => vec![selector("volume.emission_grid", n)?],
                None => candidates()?,
            };
            requests.push(GridRequest { alternatives, required: true });
        }
        EmissionSource::Auto => {
            let alternatives = std::iter::once(temperature).chain(candidates()?).collect();
            requests.push(GridRequest { alternatives, required: false });
        }
    }
    if let Some(name) = &volume.albedo_grid {
        requests.push(GridRequest::required(selector("volume.albedo_grid", name)?));
    }
    Ok(requests)
}

/// The grids [`grid_requests`] read, by role.
pub(crate) struct FoundGrids<G> {
    /// The density grid.
    pub density: G,
    /// The source grid, if emission has one.
    pub source: Option<G>,
    /// The albedo grid, if asked for.
    pub albedo: Option<G>,
}

/// Sort what [`grid_requests`] found into roles.
pub(crate) fn split_found<G>(source: EmissionSource, found: Vec<Option<G>>) -> FoundGrids<G> {
    let mut found = found.into_iter();
    let density = found.next().flatten().expect("invariant: the density request is required");
    let source = if source == EmissionSource::None { None } else { found.next().flatten() };
    let albedo = found.next().flatten();
    FoundGrids { density, source, albedo }
}

/// The emission kind `source` resolves to, given which source alternative was found.
#[must_use]
pub fn emission_kind(source: EmissionSource, found_alternative: Option<usize>) -> EmissionKind {
    match (source, found_alternative) {
        (EmissionSource::None, _) | (EmissionSource::Auto, None) => EmissionKind::None,
        (EmissionSource::Blackbody, _) => EmissionKind::Blackbody,
        (EmissionSource::Grid, _) => EmissionKind::Grid,
        (EmissionSource::Auto, Some(0)) => EmissionKind::Blackbody,
        (EmissionSource::Auto, Some(_)) => EmissionKind::Grid,
    }
}

/// The emission model of `settings` for `kind`.
///
/// # Errors
/// An unparsable `emission.temperature_map`.
pub fn emission_model(settings: &EmissionSettings, kind: EmissionKind) -> Result<Emission> {
    Ok(Emission {
        kind,
        convention: settings.convention,
        scale: settings.scale,
        color: Rgb(settings.color),
        temperature_map: settings.temperature_map.parse()?,
        cutoff_kelvin: settings.temperature_cutoff,
    })
}

/// The emission model at unit scale and white colour: what brick caches and light power
/// are built with (both are independent of scale and tint).
///
/// # Errors
/// As [`emission_model`].
pub fn unit_emission_model(settings: &EmissionSettings, kind: EmissionKind) -> Result<Emission> {
    emission_model(&EmissionSettings { scale: 1.0, color: [1.0; 3], ..settings.clone() }, kind)
}

/// How input files are read: the limits of one read and where it runs.
pub struct FileReader {
    /// Largest input one grid read may allocate.
    pub limits: ReadLimits,
    /// In an isolated child or in this process.
    pub isolation: ReadIsolation,
}

/// The reader `reading` asks for.
///
/// # Errors
/// A read timeout that is not a positive number of seconds.
pub fn reader(reading: &ReadSettings) -> Result<FileReader> {
    // The default reads the memory limits (cgroup files): only when no limit is given
    let limits = ReadLimits {
        max_bytes: reading
            .max_input_memory
            .map_or_else(|| ReadLimits::default().max_bytes, |b| b.0),
    };
    let timeout = Duration::try_from_secs_f64(reading.read_timeout)
        .ok()
        .filter(|t| !t.is_zero())
        .ok_or_else(|| {
        Error::invalid(
            "reading.read_timeout",
            format!("{} is not a positive number of seconds", reading.read_timeout),
        )
    })?;
    Ok(FileReader {
        limits,
        isolation: ReadIsolation::from_flags(reading.no_isolation, &limits, timeout),
    })
}

/// The memory budget: `render.memory_budget`, or half of physical memory or of this
/// process's cgroup memory limit, whichever is smaller ([`MemoryLimits::default_budget`]).
#[must_use]
pub fn memory_budget(settings: &JobSettings) -> u64 {
    settings.render.memory_budget.map_or_else(|| MemoryLimits::read().default_budget(), |b| b.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use plume_scene::ByteSize;

    #[test]
    fn an_explicit_memory_budget_overrides_every_limit() {
        let mut settings = JobSettings::new("x.exr");
        assert_eq!(memory_budget(&settings), MemoryLimits::read().default_budget());
        settings.render.memory_budget = Some(ByteSize(3 << 40));
        assert_eq!(memory_budget(&settings), 3 << 40, "even above RAM and any cgroup limit");
    }

    #[test]
    fn the_default_input_limit_is_the_default_budget() {
        let FileReader { limits, .. } =
            reader(&ReadSettings::default()).expect("default reading settings");
        assert_eq!(limits.max_bytes, MemoryLimits::read().default_budget());
        let FileReader { limits, .. } = reader(&ReadSettings {
            max_input_memory: Some(ByteSize(1 << 20)),
            ..ReadSettings::default()
        })
        .expect("valid");
        assert_eq!(limits.max_bytes, 1 << 20);
    }
}
