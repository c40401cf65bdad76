//! The `vdb` module against hostile input: OpenImageIO's damaged files (hostile bounds
//! metadata, truncated descriptors), real files cut off inside their leaf data, NanoVDB
//! files, grids larger than the memory limit, missing paths, directories, non-VDB files
//! and missing grids. Each is read as OpenVDB reads it or refused with a clear error,
//! never allocated blindly.

use crate::common;

use std::fs;
use std::path::Path;

use common::{data, read, scratch_dir};
use plume::vdb::{list_grids, read_float_grid, read_vec3_grid, GridSelector, ReadLimits};
use plume::Error;

/// OpenImageIO's damaged files: the bbox files hold valid, empty trees whose grid metadata
/// claims hostile bounds (0..200000³, 0..1e9³, inverted, the whole int32 range, …).
/// OpenVDB reads them as empty grids, and so do we: the metadata is never used.
#[test]
fn malformed_bbox_files_are_empty_grids() {
    for (file, name) in [
        ("oiio_bad-bbox-bomb.vdb", "bomb"),
        ("oiio_bad-bbox-empty.vdb", "empty"),
        ("oiio_bad-bbox-huge.vdb", "huge"),
        ("oiio_bad-bbox-inverted.vdb", "inverted"),
        ("oiio_bad-bbox-overflow.vdb", "overflow"),
        ("oiio_bad-bbox-roundup.vdb", "roundup"),
    ] {
        let relative = format!("edge_cases/malformed/{file}");
        let infos = list_grids(&data(&relative)).unwrap();
        assert_eq!(infos.len(), 1, "{file}");
        assert_eq!(infos[0].name, name);
        assert_eq!((infos[0].active_voxels, infos[0].leaf_count), (0, 0), "{file}");
        assert_eq!(infos[0].index_bbox, None, "{file}");
        let grid = read(&relative, name).unwrap();
        assert_eq!(grid.leaf_count(), 0, "{file}");
    }
}

/// Cut off inside the first grid descriptor (its type string claims 16 bytes; 3 remain).
/// OpenVDB alone reports "Grid type Tre<garbage> is not registered".
#[test]
fn truncated_file_is_an_error() {
    let path = data("edge_cases/malformed/oiio_truncated.vdb");
    for result in [
        list_grids(&path).map(|_| ()),
        read_float_grid(&path, &"huge".parse().unwrap(), &ReadLimits::default()).map(|_| ()),
        read_vec3_grid(&path, &"huge".parse().unwrap(), &ReadLimits::default()).map(|_| ()),
    ] {
        match result {
            Err(Error::Vdb { message, .. }) => {
                assert!(message.contains("truncated"), "{message}");
                assert!(message.chars().all(|c| !c.is_control()), "{message:?}");
            }
            other => panic!("expected Vdb error, got {other:?}"),
        }
    }
}

/// OpenVDB 10 reads a file truncated inside its leaf data without any error, leaving the
/// missing leaves as garbage (the cloud cut at 60% sums to about -2.7e24). The shim
/// checks each grid's end offset against the file size first.
#[test]
fn file_truncated_in_leaf_data_is_an_error() {
    let dir = scratch_dir("vdb_hostile", "truncated");
    for source in ["smoke/openvdb_org_smoke1.vdb", "cloud/wdas_cloud_sixteenth.vdb"] {
        let bytes = fs::read(data(source)).unwrap();
        for percent in [30, 60, 99] {
            let path = dir.join(format!("{percent}.vdb"));
            fs::write(&path, &bytes[..bytes.len() * percent / 100]).unwrap();
            let result =
                read_float_grid(&path, &GridSelector::first("density"), &ReadLimits::default());
            match result {
                Err(Error::Vdb { message, .. }) => {
                    assert!(message.contains("truncated"), "{message}")
                }
                other => panic!("{source} at {percent}%: expected Vdb error, got {other:?}"),
            }
            assert!(list_grids(&path).is_err());
        }
    }
}

#[test]
fn nanovdb_file_gets_a_clear_error() {
    let path = data("nanovdb/openvdb_fvdb_smoke-blosc.nvdb");
    for error in [
        list_grids(&path).unwrap_err(),
        read_float_grid(&path, &GridSelector::first("density"), &ReadLimits::default())
            .unwrap_err(),
        read_vec3_grid(&path, &GridSelector::first("velocity"), &ReadLimits::default())
            .unwrap_err(),
    ] {
        assert!(matches!(error, Error::Vdb { .. }), "{error:?}");
        let message = error.to_string();
        assert!(message.contains("NanoVDB") && message.contains("nanovdb_convert"), "{message}");
    }
}

#[test]
fn memory_limit_is_checked_before_allocating() {
    let path = data("cloud/wdas_cloud_sixteenth.vdb");
    let selector = GridSelector::first("density");
    // 1241 leaves + 130 tile blocks, 512 f32 values and 3 i32 per block.
    let needed = (1241 + 130) * (512 * 4 + 12);
    match read_float_grid(&path, &selector, &ReadLimits { max_bytes: needed - 1 }) {
        Err(Error::TooLarge { needed: reported, limit, grid, .. }) => {
            assert_eq!((reported, limit), (needed, needed - 1));
            assert_eq!(grid, "density");
        }
        other => panic!("expected TooLarge, got {other:?}"),
    }
    assert!(read_float_grid(&path, &selector, &ReadLimits { max_bytes: needed }).is_ok());
    assert!(ReadLimits::default().max_bytes > 0);
}

#[test]
fn missing_paths_and_grids() {
    let missing = data("no/such/file.vdb");
    assert!(matches!(list_grids(&missing), Err(Error::Open { .. })));
    let error = read_float_grid(&missing, &GridSelector::first("density"), &ReadLimits::default())
        .unwrap_err();
    assert!(matches!(error, Error::Open { .. }), "{error:?}");
    assert!(error.to_string().contains("file.vdb"));

    // A directory is not a regular file.
    assert!(matches!(list_grids(&data("smoke")), Err(Error::Open { .. })));
    // Not a VDB file at all.
    let not_vdb = Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml");
    match list_grids(&not_vdb) {
        Err(Error::Vdb { message, .. }) => assert!(message.contains("not an OpenVDB file")),
        other => panic!("expected Vdb error, got {other:?}"),
    }

    let error = read("fire/openusd_densityAndHeat.vdb", "temperature").unwrap_err();
    let message = error.to_string();
    assert!(matches!(error, Error::GridNotFound { .. }), "{error:?}");
    assert!(message.contains("\"temperature\"") && message.contains("density, heat"), "{message}");
}
