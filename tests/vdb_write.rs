//! The `vdb` module's writer: grids written with `write_float_grids` read back equal
//! (transform, background, leaves in OpenVDB offset order, all-background leaves pruned,
//! duplicate names addressed by index), writes are atomic (no temp file left, an existing
//! file replaced) and failed writes leave no file.

use crate::common;

use std::fs;

use common::{leaves_by_origin, scratch_dir};
use glam::{DAffine3, DMat3, DVec3, IVec3};
use plume::vdb::{
    leaf_offset, list_grids, read_float_grid, write_float_grids, FloatGrid, GridSelector,
    ReadLimits, LEAF_VOXELS,
};
use plume::Error;

/// A grid with a rotated, non-uniformly scaled, translated transform, a non-zero
/// background, negative origins, inactive (background) voxels and one all-background leaf.
fn synthetic_grid(name: &str, background: f32) -> FloatGrid {
    let rotation = DMat3::from_rotation_z(0.3) * DMat3::from_rotation_x(-0.2);
    let world_from_index = DAffine3::from_mat3_translation(
        rotation * DMat3::from_diagonal(DVec3::new(0.5, 0.25, 0.75)),
        DVec3::new(-1.5, 2.0, 10.0),
    );
    let origins = vec![IVec3::new(-16, 0, 8), IVec3::new(0, -8, -8), IVec3::new(24, 24, 24)];
    let mut values = vec![background; origins.len() * LEAF_VOXELS];
    for (i, v) in values[..2 * LEAF_VOXELS].iter_mut().enumerate() {
        if i % 3 != 0 {
            *v = (i % 97) as f32 * 0.125 - 2.0;
        }
    }
    // The third leaf stays entirely background and is pruned on write.
    FloatGrid { name: name.to_string(), world_from_index, background, origins, values }
}

#[test]
fn write_then_read_round_trips() {
    let dir = scratch_dir("vdb_write", "round_trip");
    let path = dir.join("two.vdb");
    let first = synthetic_grid("density", 0.25);
    let second = synthetic_grid("density", 0.0);
    write_float_grids(&path, &[&first, &second]).unwrap();

    let infos = list_grids(&path).unwrap();
    let selectors: Vec<&str> = infos.iter().map(|g| g.selector.as_str()).collect();
    assert_eq!(selectors, ["density", "density[1]"]);
    assert_eq!(infos[0].class, "fog volume");
    assert_eq!(infos[0].leaf_count, 2, "the all-background leaf is pruned");
    let active = first.values.iter().filter(|&&v| v != first.background).count() as u64;
    assert_eq!(infos[0].active_voxels, active);

    for (selector, expected) in [("density", &first), ("density[1]", &second)] {
        let grid =
            read_float_grid(&path, &selector.parse().unwrap(), &ReadLimits::default()).unwrap();
        assert_eq!(grid.name, "density");
        assert_eq!(grid.background, expected.background);
        assert!(
            grid.world_from_index.abs_diff_eq(expected.world_from_index, 1e-12),
            "{:?} vs {:?}",
            grid.world_from_index,
            expected.world_from_index
        );
        let mut written = leaves_by_origin(expected);
        written.remove(&IVec3::new(24, 24, 24));
        assert_eq!(leaves_by_origin(&grid), written, "{selector}");
    }
    // Leaf values are in OpenVDB offset order: check one voxel through leaf_offset.
    let grid =
        read_float_grid(&path, &GridSelector::first("density"), &ReadLimits::default()).unwrap();
    let leaf = grid.origins.iter().position(|&o| o == IVec3::new(0, -8, -8)).unwrap();
    let offset = leaf_offset(1, 2, 4);
    assert_eq!(grid.leaf_values(leaf)[offset], first.leaf_values(1)[offset]);
    // No temp files are left beside the output.
    let entries: Vec<_> = fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(entries, ["two.vdb"]);
}

#[test]
fn failed_writes_leave_no_file() {
    let dir = scratch_dir("vdb_write", "failed_writes");
    let grid = synthetic_grid("density", 0.0);

    // The directory does not exist.
    let missing_dir = dir.join("missing").join("out.vdb");
    let error = write_float_grids(&missing_dir, &[&grid]).unwrap_err();
    assert!(matches!(error, Error::Write { .. }), "{error:?}");
    assert!(!dir.join("missing").exists());

    // The target is a directory: the temp file is written, the rename fails, and the temp
    // file is removed.
    let target = dir.join("taken.vdb");
    fs::create_dir(&target).unwrap();
    let error = write_float_grids(&target, &[&grid]).unwrap_err();
    assert!(matches!(error, Error::Write { .. }), "{error:?}");

    // Malformed grids are refused before any file is created.
    let mut bad = synthetic_grid("bad", 0.0);
    bad.values.pop();
    let error = write_float_grids(&dir.join("bad.vdb"), &[&bad]).unwrap_err();
    assert!(error.to_string().contains("\"bad\""), "{error}");
    let mut misaligned = synthetic_grid("misaligned", 0.0);
    misaligned.origins[0] = IVec3::new(3, 0, 0);
    assert!(write_float_grids(&dir.join("bad.vdb"), &[&misaligned]).is_err());

    let entries: Vec<_> = fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(entries, ["taken.vdb"], "only the pre-existing directory remains");
}

#[test]
fn write_replaces_an_existing_file() {
    let dir = scratch_dir("vdb_write", "replace");
    let path = dir.join("out.vdb");
    fs::write(&path, b"old contents").unwrap();
    write_float_grids(&path, &[&synthetic_grid("a", 0.0)]).unwrap();
    let infos = list_grids(&path).unwrap();
    assert_eq!(infos.len(), 1);
    assert_eq!(infos[0].name, "a");
}
