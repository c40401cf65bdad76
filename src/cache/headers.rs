//! Grid headers read without their values (topology only): the grid a request binds
//! ([`probe`]), and the memory of reading a file in core estimated from them
//! ([`in_core_bytes`]).

use std::path::Path;

use crate::load::bind::{grid_requests, reader, FileReader};
use crate::vdb::{GridSelector, ReadIsolation, ReadLimits, StreamedGrid};
use plume_core::error::{Error, Result};
use plume_scene::{JobSettings, SceneDescription};

/// Message of the error a header visitor returns to stop a stream after its header.
const HEADER_ONLY: &str = "plume: header probe";

/// The header of grid `selector` in `file` (its topology is read, no values), or `None`
/// when the file has no such grid.
pub(super) fn probe(
    isolation: &ReadIsolation,
    file: &Path,
    selector: &GridSelector,
    limits: &ReadLimits,
) -> Result<Option<StreamedGrid>> {
    let mut header = None;
    let result = isolation.stream_float_grid(
        file,
        selector,
        limits,
        &mut |h| {
            header = Some(h.clone());
            Err(Error::Scene(HEADER_ONLY.into()))
        },
        &mut |_, _| Ok(()),
    );
    match result {
        Ok(h) => Ok(Some(h)),
        Err(Error::Scene(m)) if m == HEADER_ONLY => Ok(header),
        Err(Error::GridNotFound { .. }) => Ok(None),
        Err(e) => Err(e),
    }
}

/// Peak memory of reading `input` in core, estimated from its grids' headers (topology
/// only): the values of every leaf of the grids the description selects, twice (the
/// grids as read, and the volume built from them while they are still held).
///
/// # Errors
/// As reading the headers.
pub(super) fn in_core_bytes(
    scene: &SceneDescription,
    input: &Path,
    settings: &JobSettings,
) -> Result<u64> {
    let FileReader { limits, isolation } = reader(&settings.reading)?;
    let mut leaves = 0u64;
    for request in grid_requests(&scene.volume, scene.emission.source)? {
        for sel in &request.alternatives {
            if let Some(h) = probe(&isolation, input, sel, &limits)? {
                leaves += h.leaf_count;
                break;
            }
        }
    }
    Ok(leaves.saturating_mul(2 * plume_volume::grid::LEAF_VOXELS as u64 * 4))
}
