//! The `vdb` module against the real files described in `../shared/data/PROVENANCE.md`, and
//! against plume's own fixtures in `data/fixtures` (written by `make_fixtures.cc`).
//!
//! Expected values were read with OpenVDB 10.0.1 itself (a small C++ program calling
//! `io::File::readGrid`, `activeVoxelCount`, `transform().indexToWorld`, and summing
//! `cbeginValueOn()` with tile voxel counts), not copied from file metadata. Where they
//! differ from PROVENANCE.md the test says so.
//!
//! Malformed, truncated, foreign and missing files are in `vdb_hostile.rs`; writing grids
//! in `vdb_write.rs`.

use crate::common;

use std::collections::HashSet;

use common::{data, fixture, leaves_by_origin, read};
use glam::{DAffine3, DVec3, IVec3};
use plume::vdb::{
    leaf_offset, list_grids, read_float_grid, FloatGrid, GridInfo, GridSelector, ReadLimits,
    LEAF_VOXELS,
};
use plume::Error;

fn grid<'a>(infos: &'a [GridInfo], selector: &str) -> &'a GridInfo {
    infos.iter().find(|g| g.selector == selector).unwrap_or_else(|| panic!("no {selector}"))
}

#[track_caller]
fn assert_close(actual: f64, expected: f64, relative: f64) {
    let tolerance = relative * expected.abs().max(1e-30);
    assert!(
        (actual - expected).abs() <= tolerance,
        "{actual} differs from {expected} by more than {relative} relative"
    );
}

#[track_caller]
fn assert_stats(info: &GridInfo, min: f64, max: f64, mean: f64) {
    assert_close(info.min.expect("min"), min, 1e-6);
    assert_close(info.max.expect("max"), max, 1e-6);
    assert_close(info.mean.expect("mean"), mean, 1e-6);
}

/// Sum of every value in the grid's leaves, in f64.
fn value_sum(grid: &FloatGrid) -> f64 {
    grid.values.iter().map(|&v| f64::from(v)).sum()
}

/// Common FloatGrid invariants: sizes agree, origins are leaf-aligned and unique.
#[track_caller]
fn assert_well_formed(grid: &FloatGrid) {
    assert_eq!(grid.values.len(), grid.origins.len() * LEAF_VOXELS);
    let unique: HashSet<IVec3> = grid.origins.iter().copied().collect();
    assert_eq!(unique.len(), grid.origins.len(), "duplicate leaf origins");
    for origin in &grid.origins {
        assert_eq!(*origin % 8, IVec3::ZERO, "origin {origin} not leaf-aligned");
    }
}

#[test]
fn smoke1_half_float_grid() {
    let infos = list_grids(&data("smoke/openvdb_org_smoke1.vdb")).unwrap();
    assert_eq!(infos.len(), 1);
    let info = &infos[0];
    assert_eq!((info.name.as_str(), info.selector.as_str()), ("density", "density"));
    assert_eq!((info.value_type.as_str(), info.class.as_str()), ("float", "fog volume"));
    assert_eq!(info.active_voxels, 1_049_275);
    assert_eq!((info.leaf_count, info.active_tiles), (3117, 0));
    assert_eq!(info.index_bbox, Some([[1, 2, 1], [111, 223, 112]]));
    assert_eq!(info.transform, "uniform-scale-translate");
    for size in info.voxel_size {
        assert_close(size, 10.0 / 21.0, 1e-6);
    }
    // Half-float storage: 5.71484375 is exactly representable in binary16.
    assert_stats(info, 1.001358032e-05, 5.71484375, 0.1634458989);
    assert!(info.memory_bytes > 3117 * 2048);

    let grid = read("smoke/openvdb_org_smoke1.vdb", "density").unwrap();
    assert_well_formed(&grid);
    assert_eq!(grid.name, "density");
    assert_eq!(grid.leaf_count(), 3117);
    assert_eq!(grid.background, 0.0);
    // Inactive voxels of this file hold 0, so all values sum to the active sum.
    assert_close(value_sum(&grid), 0.1634458989 * 1_049_275.0, 1e-6);
    let p_world = grid.world_from_index.transform_point3(DVec3::new(1.0, 2.0, 3.0));
    assert!(p_world.abs_diff_eq(DVec3::new(-33.5714, -12.1429, -25.0), 1e-3), "{p_world}");
}

#[test]
fn cloud_tiles_are_voxelized_and_coordinates_negative() {
    let path = "cloud/wdas_cloud_sixteenth.vdb";
    let infos = list_grids(&data(path)).unwrap();
    assert_eq!(infos.len(), 1);
    let info = &infos[0];
    // 349,082 voxels in leaves plus 130 tiles of 8³ = 66,560 voxels.
    assert_eq!(info.active_voxels, 349_082 + 66_560);
    assert_eq!((info.leaf_count, info.active_tiles), (1241, 130));
    assert_eq!(info.index_bbox, Some([[-66, -21, -90], [59, 64, 63]]));
    assert_eq!(info.transform, "uniform-scale");
    for size in info.voxel_size {
        assert_close(size, 10.0 / 3.0, 1e-6);
    }
    // Active voxels that hold 0 exist, hence min 0.
    assert_stats(info, 0.0, 1.0, 0.4536165833);

    let grid = read(path, "density").unwrap();
    assert_well_formed(&grid);
    assert_eq!(grid.leaf_count(), 1241 + 130, "every tile becomes one leaf-sized block");
    assert!(grid.origins.iter().any(|o| o.x < 0 && o.y < 0 && o.z < 0));
    // The tile blocks come last, each filled with the tile value 0.5.
    for i in 1241..grid.leaf_count() {
        assert!(grid.leaf_values(i).iter().all(|&v| v == 0.5), "tile block {i}");
    }
    // A tile OpenVDB reports at (-32, 8, -8)..(-25, 15, -1).
    let tile = grid.origins.iter().position(|&o| o == IVec3::new(-32, 8, -8)).unwrap();
    assert!(tile >= 1241);
    // Every active voxel is present: the sum of all values (inactive ones hold 0 in this
    // file) equals mean × count of the active values.
    assert_close(value_sum(&grid), 0.4536165833 * 415_642.0, 1e-6);
    assert_close(value_sum(&grid), 155262.1039 + 0.5 * 66_560.0, 1e-6);
}

#[test]
fn fire_has_non_uniform_voxels() {
    let path = "fire/openusd_densityAndHeat.vdb";
    let infos = list_grids(&data(path)).unwrap();
    let names: Vec<&str> = infos.iter().map(|g| g.selector.as_str()).collect();
    assert_eq!(names, ["density", "heat"]);
    let density = grid(&infos, "density");
    let heat = grid(&infos, "heat");
    assert_eq!((density.active_voxels, density.leaf_count), (6124, 46));
    assert_eq!((heat.active_voxels, heat.leaf_count), (5224, 37));
    assert_eq!(density.class, "unknown");
    assert_eq!(density.transform, "scale-translate");
    for (info, expected) in density.voxel_size.iter().zip([0.703377, 0.703377, 0.716455]) {
        assert_close(*info, expected, 1e-5);
    }
    assert_stats(density, 0.001001121942, 0.9975093603, 0.06527173149);
    assert_stats(heat, 0.001000175136, 0.7595377564, 0.05293267328);

    let grid = read(path, "heat").unwrap();
    assert_well_formed(&grid);
    assert_eq!(grid.leaf_count(), 37);
    assert_close(value_sum(&grid), 276.5202852, 1e-6);
    let scale = DVec3::new(
        grid.world_from_index.matrix3.x_axis.length(),
        grid.world_from_index.matrix3.y_axis.length(),
        grid.world_from_index.matrix3.z_axis.length(),
    );
    assert!(scale.abs_diff_eq(DVec3::new(0.703377, 0.703377, 0.716455), 1e-5), "{scale}");
    // OpenVDB: indexToWorld(1, 2, 3) = (-7.73714, -7.03377, -21.9855).
    let p_world = grid.world_from_index.transform_point3(DVec3::new(1.0, 2.0, 3.0));
    assert!(p_world.abs_diff_eq(DVec3::new(-7.73714, -7.03377, -21.9855), 1e-4), "{p_world}");
}

#[test]
fn sequence_frames_in_file_order() {
    let infos = list_grids(&data("sequence/openusd_smoke_000001.vdb")).unwrap();
    // File order, not io::File's alphabetical density/obstacles/shadow/velocity.
    let listed: Vec<(&str, &str)> =
        infos.iter().map(|g| (g.name.as_str(), g.value_type.as_str())).collect();
    assert_eq!(
        listed,
        [("density", "float"), ("shadow", "float"), ("velocity", "vec3s"), ("obstacles", "int32")]
    );
    assert_eq!(infos.iter().map(|g| g.file_index).collect::<Vec<_>>(), [0, 1, 2, 3]);
    for info in &infos {
        assert_eq!(info.active_voxels, 0);
        assert_eq!(info.index_bbox, None);
        assert_eq!((info.min, info.max, info.mean), (None, None, None));
    }
    assert_eq!(grid(&infos, "velocity").class, "staggered");
    for size in infos[0].voxel_size {
        assert_close(size, 0.1323, 5e-3);
    }

    let empty = read("sequence/openusd_smoke_000001.vdb", "density").unwrap();
    assert_eq!(empty.leaf_count(), 0);
    assert!(empty.values.is_empty());
    for selector in ["velocity", "obstacles"] {
        match read("sequence/openusd_smoke_000001.vdb", selector) {
            Err(Error::UnsupportedGrid { grid, message, .. }) => {
                assert_eq!(grid, selector);
                assert!(message.contains(if selector == "velocity" { "vec3s" } else { "int32" }));
            }
            other => panic!("{selector}: expected UnsupportedGrid, got {other:?}"),
        }
    }

    for (file, voxels, sum) in [
        ("sequence/openusd_smoke_000002.vdb", 71_983, 26291.57048),
        ("sequence/openusd_smoke_000003.vdb", 90_197, 29401.88654),
    ] {
        let infos = list_grids(&data(file)).unwrap();
        assert_eq!(infos.len(), 1);
        assert_eq!(infos[0].active_voxels, voxels);
        let grid = read(file, "density").unwrap();
        assert_well_formed(&grid);
        assert_close(value_sum(&grid), sum, 1e-6);
    }
}

/// PROVENANCE.md lists these grids as 803 / 2,222 / 491 voxels. OpenVDB reads them in the
/// opposite order: the descriptors in the file are `density[0]` (491 voxels), `density[1]`
/// (2,222) and `density[2]` (803), and `io::File::readGrid("density[1]")` agrees. Houdini
/// stored its primitive numbers as `index` metadata 2, 1, 0, which is the order
/// PROVENANCE.md follows. plume uses file order, like OpenVDB.
#[test]
fn duplicate_names_are_addressed_in_file_order() {
    let path = "edge_cases/arnold_usd_grids_3x_density.vdb";
    let infos = list_grids(&data(path)).unwrap();
    let listed: Vec<(&str, &str, u64)> =
        infos.iter().map(|g| (g.name.as_str(), g.selector.as_str(), g.active_voxels)).collect();
    assert_eq!(
        listed,
        [
            ("density", "density", 491),
            ("density", "density[1]", 2222),
            ("density", "density[2]", 803)
        ]
    );
    for info in &infos {
        assert_close(info.max.unwrap(), 10.0, 1e-6);
    }

    // The three grids differ in translation: OpenVDB's indexToWorld(1, 2, 3).
    for (selector, sum, x_world) in [
        ("density", 2057.87622, 4.1),
        ("density[1]", 9430.390897, 2.1),
        ("density[2]", 2959.641949, 0.1),
    ] {
        let grid = read(path, selector).unwrap();
        assert_well_formed(&grid);
        assert_eq!(grid.name, "density");
        assert_close(value_sum(&grid), sum, 1e-6);
        let p_world = grid.world_from_index.transform_point3(DVec3::new(1.0, 2.0, 3.0));
        // The file stores the map in single precision.
        assert!(p_world.abs_diff_eq(DVec3::new(x_world, 0.2, 0.3), 1e-6), "{selector}: {p_world}");
    }
    assert!(matches!(read(path, "density[0]"), Ok(g) if g.leaf_count() == 8));
    match read(path, "density[3]") {
        Err(Error::GridNotFound { name, available, .. }) => {
            assert_eq!(name, "density[3]");
            assert_eq!(available, ["density", "density[1]", "density[2]"]);
        }
        other => panic!("expected GridNotFound, got {other:?}"),
    }
}

/// A vector grid is listed, and refused by the scalar reader (`read_vec3_grid` reads it as
/// three components: `tests/vec3_grids.rs`).
#[test]
fn vec3_grid_is_listed_but_not_read_as_a_float_grid() {
    let path = "edge_cases/oiio_sphereCd.vdb";
    let infos = list_grids(&data(path)).unwrap();
    assert_eq!(infos.len(), 1);
    assert_eq!((infos[0].name.as_str(), infos[0].value_type.as_str()), ("Cd", "vec3s"));
    assert_eq!(infos[0].active_voxels, 9047);
    // Vector statistics are of the magnitude.
    let (min, max) = (infos[0].min.unwrap(), infos[0].max.unwrap());
    assert!(0.0 <= min && min <= max, "{min} {max}");

    let error = read(path, "Cd").unwrap_err();
    assert!(matches!(error, Error::UnsupportedGrid { .. }), "{error:?}");
    let message = error.to_string();
    assert!(message.contains("\"Cd\"") && message.contains("vec3s"), "{message}");
    assert!(message.contains("oiio_sphereCd.vdb"), "{message}");
}

/// `nanovdb_convert` wrote one grid with an empty name; OpenVDB calls it `[0]`.
#[test]
fn converted_nanovdb_file_has_an_unnamed_grid() {
    let path = "nanovdb/smoke-blosc_converted_by_nanovdb_convert.vdb";
    let infos = list_grids(&data(path)).unwrap();
    assert_eq!(infos.len(), 1);
    assert_eq!((infos[0].name.as_str(), infos[0].selector.as_str()), ("", "[0]"));
    assert_eq!(infos[0].active_voxels, 1_049_275);
    assert_eq!(infos[0].voxel_size, [1.0, 1.0, 1.0]);
    let grid = read(path, "[0]").unwrap();
    assert_eq!(grid.leaf_count(), 3117);
    assert_close(value_sum(&grid), 0.1634458989 * 1_049_275.0, 1e-6);
    assert_eq!(grid.world_from_index, DAffine3::IDENTITY);
}

#[test]
fn explosions_list_in_file_order() {
    let infos = list_grids(&data("explosion/blender_fluid_noise_0040.vdb")).unwrap();
    let listed: Vec<(&str, u64)> =
        infos.iter().map(|g| (g.name.as_str(), g.active_voxels)).collect();
    assert_eq!(
        listed,
        [
            ("density_noise", 932_846),
            ("flame_noise", 637_305),
            ("color_r_noise", 897_835),
            ("color_g_noise", 897_835),
            ("color_b_noise", 897_835),
        ]
    );
    assert_stats(&infos[0], 1.000032626e-06, 0.901350379, 0.1888253611);

    for (file, density, temperature, t_min, t_max) in [
        ("mantaflow_explosion_kelvin_0020.vdb", 417_098, 306_341, 1515.000977, 2961.415283),
        ("mantaflow_explosion_kelvin_0040.vdb", 932_846, 599_176, 1515.000244, 2461.865723),
        (
            "mantaflow_explosion_r192n2_kelvin_0040.vdb",
            2_503_234,
            1_777_897,
            1515.000122,
            2507.559326,
        ),
    ] {
        let infos = list_grids(&data(&format!("explosion/{file}"))).unwrap();
        assert_eq!(grid(&infos, "density").active_voxels, density, "{file}");
        let t = grid(&infos, "temperature");
        assert_eq!(t.active_voxels, temperature, "{file}");
        assert_close(t.min.unwrap(), t_min, 1e-6);
        assert_close(t.max.unwrap(), t_max, 1e-6);
    }

    let grid = read("explosion/mantaflow_explosion_kelvin_0020.vdb", "temperature").unwrap();
    assert_well_formed(&grid);
    assert_close(value_sum(&grid), 665_325_557.5, 1e-6);
}

/// `affine_tiles.vdb`, grid `heat_double`: a double grid with a rotated, non-uniform affine
/// map, one active voxel, one inactive voxel holding 3.0, an active 8³ tile of 2.0, an
/// active 128³ tile of 3.0 and an inactive 8³ tile of 7.0 (background 0.5).
#[test]
fn double_grid_with_affine_map_and_tiles_of_two_levels() {
    let path = fixture("affine_tiles.vdb");
    let infos = list_grids(&path).unwrap();
    let heat = grid(&infos, "heat_double");
    assert_eq!(heat.value_type, "double");
    assert_eq!(heat.transform, "affine");
    assert_eq!(heat.active_voxels, 1 + 8 * 8 * 8 + 128 * 128 * 128);
    assert_eq!((heat.leaf_count, heat.active_tiles), (1, 2));
    assert_eq!(heat.index_bbox, Some([[-3, 0, 0], [255, 127, 127]]));
    let mean = (1.25 + 2.0 * 512.0 + 3.0 * 2_097_152.0) / 2_097_665.0;
    assert_stats(heat, 1.25, 3.0, mean);
    assert_close(heat.voxel_size[0], 0.2, 1e-12);
    assert_close(heat.voxel_size[1], 0.3, 1e-12);
    assert_close(heat.voxel_size[2], 0.4, 1e-12);

    let grid = read_float_grid(&path, &GridSelector::first("heat_double"), &ReadLimits::default())
        .unwrap();
    assert_well_formed(&grid);
    assert_eq!(grid.background, 0.5);
    // 1 leaf + 1 block for the 8³ tile + 16³ blocks for the 128³ tile.
    assert_eq!(grid.leaf_count(), 1 + 1 + 4096);
    let leaves = leaves_by_origin(&grid);
    let leaf = &leaves[&IVec3::new(-8, 0, 0)];
    assert_eq!(leaf[leaf_offset(-3, 5, 7)], 1.25);
    assert_eq!(leaf[leaf_offset(-2, 5, 7)], 3.0, "inactive voxels keep their value");
    assert_eq!(leaf.iter().filter(|&&v| v == 0.5).count(), 510);
    assert!(leaves[&IVec3::new(64, 0, 0)].iter().all(|&v| v == 2.0));
    assert!(leaves[&IVec3::new(248, 120, 120)].iter().all(|&v| v == 3.0));
    assert!(!leaves.contains_key(&IVec3::new(-64, 0, 0)), "inactive tiles are not voxelized");
    assert_close(
        value_sum(&grid),
        1.25 + 3.0 + 510.0 * 0.5 + 512.0 * 2.0 + 2_097_152.0 * 3.0,
        1e-12,
    );

    // The map as OpenVDB's indexToWorld reports it (make_fixtures output), and exactly
    // as the fixture built it: x axis 0.2·(cos ½, sin ½, 0), y axis 0.3·(−sin ½, cos ½, 0),
    // z axis (0, 0, 0.4), translation (1, −2, 3).
    for (p_index, expected) in [
        (DVec3::new(0.0, 0.0, 0.0), DVec3::new(1.0, -2.0, 3.0)),
        (DVec3::new(1.0, 2.0, 3.0), DVec3::new(0.887861, -1.37757, 4.2)),
        (DVec3::new(-3.0, 5.0, 7.0), DVec3::new(-0.245688, -0.971281, 5.8)),
    ] {
        let p_world = grid.world_from_index.transform_point3(p_index);
        assert!(p_world.abs_diff_eq(expected, 1e-5), "{p_index} -> {p_world}");
    }
    let (s, c) = 0.5f64.sin_cos();
    let expected = DAffine3::from_cols(
        DVec3::new(0.2 * c, 0.2 * s, 0.0),
        DVec3::new(-0.3 * s, 0.3 * c, 0.0),
        DVec3::new(0.0, 0.0, 0.4),
        DVec3::new(1.0, -2.0, 3.0),
    );
    assert!(grid.world_from_index.abs_diff_eq(expected, 1e-12), "{:?}", grid.world_from_index);
}

/// `affine_tiles.vdb`, grid `root_tile`: one active root tile, 4096³ voxels in a 20 KB
/// file. Voxelizing it would take 2^27 leaf blocks (276 GB); the limit stops it first.
#[test]
fn a_root_tile_is_refused_not_allocated() {
    let path = fixture("affine_tiles.vdb");
    let infos = list_grids(&path).unwrap();
    let root = grid(&infos, "root_tile");
    assert_eq!(root.active_voxels, 1 << 36);
    assert_eq!((root.leaf_count, root.active_tiles), (0, 1));
    assert_eq!(root.index_bbox, Some([[0, 0, 0], [4095, 4095, 4095]]));
    assert_stats(root, 1.0, 1.0, 1.0);

    let limits = ReadLimits { max_bytes: 1 << 30 };
    match read_float_grid(&path, &GridSelector::first("root_tile"), &limits) {
        Err(Error::TooLarge { needed, limit, .. }) => {
            assert_eq!(needed, (1u64 << 27) * (512 * 4 + 12));
            assert_eq!(limit, 1 << 30);
        }
        other => panic!("expected TooLarge, got {other:?}"),
    }
}

#[test]
fn frustum_transform_is_unsupported() {
    let path = fixture("frustum.vdb");
    let infos = list_grids(&path).unwrap();
    assert_eq!(infos[0].transform, "frustum");
    assert_eq!(infos[0].active_voxels, 1);
    let error =
        read_float_grid(&path, &GridSelector::first("fog"), &ReadLimits::default()).unwrap_err();
    assert!(matches!(error, Error::UnsupportedGrid { .. }), "{error:?}");
    assert!(error.to_string().contains("frustum"), "{error}");
}
