//! Vector grids (`vec3s`/`vec3d`) read as three float components for velocity motion blur:
//! `read_vec3_grid` in-process and in the isolated reader, against OpenVDB's
//! own view of the same grids.
//!
//! OpenVDB's view comes from `tests/scripts/pyopenvdb_vec3.py`, run with `/usr/bin/python3`
//! (Debian's `python3-openvdb` installs `pyopenvdb` there only). Without it the comparisons
//! are skipped with a loud message; the C++-written fixture `data/fixtures/vec3.vdb` (see
//! `make_fixtures.cc`) still covers tiles, vec3d, half floats and NaN.
//!
//! Real data: the only non-empty vector grid in `../shared/data` is OpenImageIO's `Cd`
//! (`edge_cases/oiio_sphereCd.vdb`, 9,047 voxels in 56 leaves). Blender's `velocity` in
//! `sequence/openusd_smoke_000001.vdb` is empty (0 voxels, 0 leaves, class staggered), and
//! Blender's cache `explosion/blender_fluid_noise_0040.vdb` holds no velocity at all (only
//! the noise grids); both are checked as what they are.

use crate::common;

use std::collections::HashMap;
use std::fs;
use std::path::Path;
use std::process::Command;
use std::time::Duration;

use common::{data, fixture, leaves_by_origin, plume, s, scratch_dir, stderr, PLUME};
use glam::{DAffine3, DVec3, IVec3};
use plume::vdb::{
    leaf_offset, list_grids, read_float_grid, read_vec3_grid, read_vec3_grid_isolated, FloatGrid,
    GridSelector, IsolationLimits, ReadIsolation, ReadLimits, LEAF_VOXELS,
};
use plume::Error;
use serde_json::Value;

const SPHERE_CD: &str = "edge_cases/oiio_sphereCd.vdb";
const FRAME_1: &str = "sequence/openusd_smoke_000001.vdb";
const HELPER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/scripts/pyopenvdb_vec3.py");

fn selector(text: &str) -> GridSelector {
    text.parse().unwrap()
}

fn isolation() -> ReadIsolation {
    ReadIsolation::Child {
        reader_exe: PLUME.into(),
        limits: IsolationLimits::new(&ReadLimits::default(), Duration::from_secs(60)),
    }
}

fn read_local(path: &Path, grid: &str) -> plume::Result<[FloatGrid; 3]> {
    read_vec3_grid(path, &selector(grid), &ReadLimits::default())
}

fn read_isolated(path: &Path, grid: &str) -> plume::Result<[FloatGrid; 3]> {
    isolation().read_vec3_grid(path, &selector(grid), &ReadLimits::default())
}

/// Reads `grid` in-process and isolated, asserts both give the same bits, and returns it.
#[track_caller]
fn read_both(path: &Path, grid: &str) -> [FloatGrid; 3] {
    let local = read_local(path, grid).unwrap();
    let isolated = read_isolated(path, grid).unwrap();
    for (a, b) in local.iter().zip(&isolated) {
        assert_same_bits(a, b);
    }
    local
}

#[track_caller]
fn assert_same_bits(a: &FloatGrid, b: &FloatGrid) {
    assert_eq!(a.name, b.name);
    assert_eq!(a.world_from_index, b.world_from_index, "{}", a.name);
    assert_eq!(a.background.to_bits(), b.background.to_bits(), "{}", a.name);
    assert_eq!(a.origins, b.origins, "{}", a.name);
    assert_eq!(a.values.len(), b.values.len(), "{}", a.name);
    assert!(
        a.values.iter().zip(&b.values).all(|(x, y)| x.to_bits() == y.to_bits()),
        "{}: values differ",
        a.name
    );
}

/// The component invariants: names `NAME.x/y/z`, shared origins and transform, sizes that
/// agree, leaf-aligned unique origins, finite values.
#[track_caller]
fn assert_components(grids: &[FloatGrid; 3], name: &str) {
    for (grid, axis) in grids.iter().zip(["x", "y", "z"]) {
        assert_eq!(grid.name, format!("{name}.{axis}"));
        assert_eq!(grid.origins, grids[0].origins, "{axis}: origins differ from x");
        assert_eq!(grid.world_from_index, grids[0].world_from_index);
        assert_eq!(grid.values.len(), grid.leaf_count() * LEAF_VOXELS);
        assert!(grid.values.iter().all(|v| v.is_finite()), "{axis}: non-finite value");
        assert!(grid.background.is_finite());
    }
    let mut seen = std::collections::HashSet::new();
    for origin in &grids[0].origins {
        assert_eq!(*origin % 8, IVec3::ZERO, "origin {origin} not leaf-aligned");
        assert!(seen.insert(*origin), "duplicate origin {origin}");
    }
}

/// The vector at voxel `p` (which must lie in a leaf), from the three components.
fn vector_at(leaves: &[HashMap<IVec3, Vec<f32>>; 3], p: IVec3) -> [f32; 3] {
    let origin = p & !7;
    let offset = leaf_offset(p.x, p.y, p.z);
    [0, 1, 2].map(|c| {
        leaves[c].get(&origin).unwrap_or_else(|| panic!("no leaf at {origin} for voxel {p}"))
            [offset]
    })
}

fn leaves_of(grids: &[FloatGrid; 3]) -> [HashMap<IVec3, Vec<f32>>; 3] {
    [0, 1, 2].map(|c| leaves_by_origin(&grids[c]))
}

/// Runs the pyopenvdb helper with `args`; `None` (after a loud message) when pyopenvdb
/// is unavailable.
fn pyopenvdb(args: &[&str]) -> Option<Vec<u8>> {
    let output = match Command::new("/usr/bin/python3").arg(HELPER).args(args).output() {
        Ok(output) => output,
        Err(e) => {
            eprintln!("\n!!!!!!!!!! SKIPPED pyopenvdb comparison: cannot run /usr/bin/python3: {e} !!!!!!!!!!\n");
            return None;
        }
    };
    if output.status.code() == Some(3) {
        eprintln!(
            "\n!!!!!!!!!! SKIPPED pyopenvdb comparison: {} (apt-get install python3-openvdb) !!!!!!!!!!\n",
            String::from_utf8_lossy(&output.stderr).trim()
        );
        return None;
    }
    assert!(
        output.status.success(),
        "pyopenvdb helper {args:?} failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    Some(output.stdout)
}

/// OpenVDB's view of one grid (see `dump()` in the helper), or `None` without pyopenvdb.
fn openvdb_dump(path: &Path, grid: &str) -> Option<Value> {
    pyopenvdb(&["dump", s(path), grid])
        .map(|out| serde_json::from_slice(&out).expect("helper prints JSON"))
}

fn vec3_of(value: &Value) -> [f32; 3] {
    // pyopenvdb widens each f32 to a Python float exactly, so the cast back is exact.
    [0, 1, 2].map(|c| value[c].as_f64().unwrap() as f32)
}

fn ivec3_of(value: &Value) -> IVec3 {
    IVec3::new(
        value[0].as_i64().unwrap() as i32,
        value[1].as_i64().unwrap() as i32,
        value[2].as_i64().unwrap() as i32,
    )
}

/// Asserts that the components hold exactly what OpenVDB holds: the file leaves (every
/// voxel inside them, active or not, bit for bit) first, then one block per 8³ cell of
/// every active tile, filled with the tile's vector; and the background. Returns the
/// number of active voxels checked.
#[track_caller]
fn assert_matches_openvdb(grids: &[FloatGrid; 3], dump: &Value) -> usize {
    let leaves = leaves_of(grids);
    let background = vec3_of(&dump["background"]);
    for c in 0..3 {
        assert_eq!(
            grids[c].background.to_bits(),
            background[c].to_bits(),
            "background component {c}"
        );
    }
    let voxels = dump["voxels"].as_array().unwrap();
    let file_leaves = dump["leaf_count"].as_u64().unwrap() as usize;
    assert_eq!(
        voxels.len(),
        file_leaves * LEAF_VOXELS,
        "pyopenvdb lists every voxel of every leaf"
    );
    let mut active = 0;
    for voxel in voxels {
        let v = voxel.as_array().unwrap();
        let p = IVec3::new(
            v[0].as_i64().unwrap() as i32,
            v[1].as_i64().unwrap() as i32,
            v[2].as_i64().unwrap() as i32,
        );
        let expected = vec3_of(&Value::from(v[3..6].to_vec()));
        let got = vector_at(&leaves, p);
        assert_eq!(
            got.map(f32::to_bits),
            expected.map(f32::to_bits),
            "voxel {p}: {got:?} vs OpenVDB {expected:?}"
        );
        active += usize::from(v[6].as_bool().unwrap());
    }
    // The file's leaves come first, tile blocks after them
    let leaf_origins: std::collections::HashSet<IVec3> =
        voxels.iter().map(|v| ivec3_of(v) & !7).collect();
    assert_eq!(leaf_origins.len(), file_leaves);
    assert!(
        grids[0].origins[..file_leaves].iter().all(|o| leaf_origins.contains(o)),
        "file leaves are not first"
    );
    let mut tile_blocks = 0;
    for tile in dump["tiles"].as_array().unwrap() {
        let (lo, hi, value) = (ivec3_of(&tile[0]), ivec3_of(&tile[1]), vec3_of(&tile[2]));
        for x in (lo.x..=hi.x).step_by(8) {
            for y in (lo.y..=hi.y).step_by(8) {
                for z in (lo.z..=hi.z).step_by(8) {
                    let origin = IVec3::new(x, y, z);
                    for c in 0..3 {
                        let block = leaves[c]
                            .get(&origin)
                            .unwrap_or_else(|| panic!("tile block {origin} missing"));
                        assert!(
                            block.iter().all(|v| v.to_bits() == value[c].to_bits()),
                            "tile block {origin} component {c} is not {}",
                            value[c]
                        );
                    }
                    tile_blocks += 1;
                }
            }
        }
    }
    assert_eq!(grids[0].leaf_count(), file_leaves + tile_blocks, "leaves + voxelized tile blocks");
    active
}

/// Blender's `velocity` (frame 1 of the OpenUSD sequence) is a staggered vec3s grid with no
/// voxels yet: three empty components, the frame's transform, a zero background, the same
/// bits isolated. Blender's fluid cache holds no velocity grid.
#[test]
fn blender_velocity_grid_reads_as_three_empty_components() {
    let path = data(FRAME_1);
    let infos = list_grids(&path).unwrap();
    let info = infos.iter().find(|g| g.name == "velocity").unwrap();
    assert_eq!((info.value_type.as_str(), info.class.as_str()), ("vec3s", "staggered"));
    assert_eq!((info.active_voxels, info.leaf_count, info.active_tiles), (0, 0, 0));

    let velocity = read_both(&path, "velocity");
    assert_components(&velocity, "velocity");
    assert_eq!(velocity[0].leaf_count(), 0);
    assert!(velocity.iter().all(|g| g.values.is_empty() && g.background == 0.0));
    let density = read_float_grid(&path, &selector("density"), &ReadLimits::default()).unwrap();
    assert_eq!(velocity[0].world_from_index, density.world_from_index);
    let scale = velocity[0].world_from_index.matrix3.x_axis.length();
    assert!((scale - 0.132601).abs() < 1e-6, "{scale}");
    if let Some(dump) = openvdb_dump(&path, "velocity") {
        assert_eq!(
            (dump["active_voxels"].as_u64(), dump["leaf_count"].as_u64()),
            (Some(0), Some(0))
        );
        assert_matches_openvdb(&velocity, &dump);
    }

    let noise = data("explosion/blender_fluid_noise_0040.vdb");
    match read_local(&noise, "velocity") {
        Err(Error::GridNotFound { available, .. }) => {
            assert!(available.contains(&"density_noise".to_string()), "{available:?}")
        }
        other => panic!("expected GridNotFound, got {other:?}"),
    }
}

/// OpenImageIO's `Cd`: 56 leaves, 9,047 active voxels, background (1, 1, 1). Every value of
/// every leaf equals OpenVDB's, bit for bit, in-process and isolated; `plume info` shows
/// the magnitude range OpenVDB's values give.
#[test]
fn real_vec3_grid_matches_openvdb_voxel_for_voxel() {
    let path = data(SPHERE_CD);
    let cd = read_both(&path, "Cd");
    assert_components(&cd, "Cd");
    let info = &list_grids(&path).unwrap()[0];
    assert_eq!((info.leaf_count, info.active_tiles, info.active_voxels), (56, 0, 9047));
    assert_eq!(cd[0].leaf_count(), 56, "the grid's leaves, no tiles");
    assert_eq!(cd.each_ref().map(|g| g.background), [1.0, 1.0, 1.0]);
    assert_eq!(cd[0].world_from_index, DAffine3::from_scale(DVec3::splat(f64::from(0.1f32))));
    // Colours, not all equal: the components are distinct grids
    assert_ne!(cd[0].values, cd[1].values);
    assert_ne!(cd[1].values, cd[2].values);

    let Some(dump) = openvdb_dump(&path, "Cd") else { return };
    assert_eq!(dump["type"], "vec3s");
    assert_eq!(dump["active_voxels"].as_u64(), Some(9047));
    let active = assert_matches_openvdb(&cd, &dump);
    assert_eq!(active, 9047);
    println!("Cd: 56 leaves, 28,672 voxel vectors equal to OpenVDB's ({active} active)");

    // plume info: vec3s, magnitude statistics as OpenVDB's values give them
    let json: Value = serde_json::from_slice(&plume(&["info", "--json", s(&path)]).stdout).unwrap();
    assert_eq!(json[0]["type"], "vec3s");
    for key in ["min", "max"] {
        let (shown, expected) =
            (json[0][key].as_f64().unwrap(), dump[format!("magnitude_{key}")].as_f64().unwrap());
        assert!(
            (shown - expected).abs() <= 1e-6 * expected.max(1.0),
            "{key}: plume info {shown}, OpenVDB {expected}"
        );
    }
    let table = plume(&["info", s(&path)]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(text.contains("vec3s") && text.contains("(magnitude)"), "{text}");
    assert!(
        text.contains(&format!("max {:.6}", dump["magnitude_max"].as_f64().unwrap())),
        "{text}"
    );
}

/// A vec3s grid written by pyopenvdb with voxels, a partial fill, eight level-1 tiles and
/// one level-2 tile (128³): every tile becomes blocks of its vector in every component, in
/// the order `read_float_grid` gives a float grid of the same topology (`vel_x`).
#[test]
fn synthetic_tiles_are_voxelized_in_every_component() {
    let dir = scratch_dir("vec3_grids", "synthetic");
    let path = dir.join("vel.vdb");
    if pyopenvdb(&["write", s(&path)]).is_none() {
        return;
    }
    let infos = list_grids(&path).unwrap();
    assert_eq!((infos[0].name.as_str(), infos[0].value_type.as_str()), ("vel", "vec3s"));
    assert_eq!((infos[0].leaf_count, infos[0].active_tiles), (4, 9));

    let vel = read_both(&path, "vel");
    assert_components(&vel, "vel");
    // 4 leaves + 8 level-1 tile blocks + 16³ blocks of the level-2 tile
    assert_eq!(vel[0].leaf_count(), 4 + 8 + 4096);
    assert_eq!(vel.each_ref().map(|g| g.background), [0.5, 0.0, -0.5]);
    assert_eq!(vel[0].world_from_index, DAffine3::from_scale(DVec3::splat(0.25)));
    let leaves = leaves_of(&vel);
    assert_eq!(vector_at(&leaves, IVec3::new(1, 2, 3)), [1.0, -2.0, 3.5]);
    assert_eq!(
        vector_at(&leaves, IVec3::new(2, 2, 3)),
        [4.0, 4.0, 4.0],
        "inactive voxels keep their value"
    );
    assert_eq!(vector_at(&leaves, IVec3::new(-9, 0, 4)), [0.25, 0.5, -0.75]);
    assert_eq!(vector_at(&leaves, IVec3::new(3, 19, 3)), [9.0, -9.0, 0.125]);
    assert_eq!(
        vector_at(&leaves, IVec3::new(4, 19, 3)),
        [0.5, 0.0, -0.5],
        "background beside the fill"
    );
    assert_eq!(vector_at(&leaves, IVec3::new(47, 15, 15)), [1.5, -2.5, 3.5]);
    assert_eq!(vector_at(&leaves, IVec3::new(200, 127, 64)), [-0.5, 0.75, 2.0]);
    assert!(!leaves[0].contains_key(&IVec3::new(48, 0, 0)));

    // Same blocks, same order as the float reader on the same topology
    let vel_x = read_float_grid(&path, &selector("vel_x"), &ReadLimits::default()).unwrap();
    assert_eq!(vel_x.origins, vel[0].origins);
    assert!(vel_x.values.iter().zip(&vel[0].values).all(|(a, b)| a.to_bits() == b.to_bits()));

    let dump = openvdb_dump(&path, "vel").expect("pyopenvdb wrote the file, so it can read it");
    let active = assert_matches_openvdb(&vel, &dump);
    let tile_voxels: u64 = dump["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| (ivec3_of(&t[1]) - ivec3_of(&t[0]) + 1).as_i64vec3().element_product() as u64)
        .sum();
    assert_eq!(active as u64 + tile_voxels, dump["active_voxels"].as_u64().unwrap());
    assert_eq!(tile_voxels, 8 * 512 + 128 * 128 * 128);
}

/// `data/fixtures/vec3.vdb` (written by OpenVDB in C++, `make_fixtures.cc`): a vec3d grid
/// under a rotated affine map with a tile, a vec3s grid stored as half floats, and a grid
/// with a NaN component.
#[test]
fn vec3d_half_float_and_nan_fixtures() {
    let path = fixture("vec3.vdb");
    let vel = read_both(&path, "vel_double");
    assert_components(&vel, "vel_double");
    assert_eq!(vel.each_ref().map(|g| g.background), [0.5, -0.5, 0.25]);
    // One leaf + one block for the active 8³ tile; the inactive tile is not voxelized.
    assert_eq!(vel[0].origins, [IVec3::new(-8, 0, 0), IVec3::new(64, 0, 0)]);
    let leaves = leaves_of(&vel);
    assert_eq!(vector_at(&leaves, IVec3::new(-3, 5, 7)), [1.25, -2.5, 3.75]);
    assert_eq!(
        vector_at(&leaves, IVec3::new(-2, 5, 7)),
        [3.0, 3.0, 3.0],
        "inactive voxels keep their value"
    );
    for (c, background) in [0.5, -0.5, 0.25].into_iter().enumerate() {
        assert_eq!(
            leaves[c][&IVec3::new(-8, 0, 0)].iter().filter(|&&v| v == background).count(),
            510
        );
    }
    for (c, tile) in [2.0, -4.0, 6.0].into_iter().enumerate() {
        assert!(vel[c].leaf_values(1).iter().all(|&v| v == tile), "tile component {c}");
    }
    // The same map as affine_tiles.vdb's heat_double (make_fixtures.cc builds both from m)
    let heat = read_float_grid(
        &fixture("affine_tiles.vdb"),
        &selector("heat_double"),
        &ReadLimits::default(),
    )
    .unwrap();
    assert_eq!(vel[0].world_from_index, heat.world_from_index);

    // Half floats read as the halves they are: 0.1 is stored as 0.0999755859375
    let half = read_both(&path, "vel_half");
    let leaves = leaves_of(&half);
    let expected = [0.099_975_586_f32, 0.199_951_17, -0.300_048_83];
    assert_eq!(vector_at(&leaves, IVec3::new(0, 0, 0)), expected);
    assert_eq!(vector_at(&leaves, IVec3::new(9, 0, 0)), expected);
    assert_ne!(expected[0], 0.1);

    for result in [read_local(&path, "vel_nan"), read_isolated(&path, "vel_nan")] {
        match result {
            Err(Error::Vdb { message, path: p }) => {
                assert_eq!(p, path);
                assert!(
                    message.contains("vel_nan") && message.contains("1 of 1536 vector components"),
                    "{message}"
                );
                assert!(message.contains("NaN or infinite"), "{message}");
            }
            other => panic!(
                "expected Vdb error for NaN, got {:?}",
                other.map(|grids| grids[1].values.iter().filter(|v| v.is_nan()).count())
            ),
        }
    }
}

/// A scalar grid asked for as a vector is UnsupportedGrid naming the file, the grid and its
/// type; a missing grid is GridNotFound; the isolated reader gives the same errors.
#[test]
fn wrong_types_and_missing_grids_are_refused() {
    for (path, grid, value_type) in [
        (fixture("vec3.vdb"), "density", "float"),
        (data("fire/openusd_densityAndHeat.vdb"), "heat", "float"),
        (data(FRAME_1), "obstacles", "int32"),
        (data("edge_cases/arnold_usd_grids_3x_density.vdb"), "density[2]", "float"),
    ] {
        let local = read_local(&path, grid).unwrap_err();
        let isolated = read_isolated(&path, grid).unwrap_err();
        assert_eq!(local.to_string(), isolated.to_string());
        match local {
            Error::UnsupportedGrid { path: p, grid: g, message } => {
                assert_eq!((p, g.as_str()), (path.clone(), grid));
                assert!(
                    message.contains(&format!("value type {value_type} is not a vector grid")),
                    "{message}"
                );
            }
            other => panic!("{grid}: expected UnsupportedGrid, got {other:?}"),
        }
        assert!(isolated.to_string().contains(s(&path)), "{isolated}");
    }
    for (path, grid) in
        [(data(SPHERE_CD), "velocity"), (data(SPHERE_CD), "Cd[1]"), (fixture("vec3.vdb"), "vel")]
    {
        let local = read_local(&path, grid).unwrap_err();
        let isolated = read_isolated(&path, grid).unwrap_err();
        assert_eq!(local.to_string(), isolated.to_string());
        match local {
            Error::GridNotFound { name, available, .. } => {
                assert_eq!(name, grid);
                assert!(!available.is_empty());
            }
            other => panic!("{grid}: expected GridNotFound, got {other:?}"),
        }
    }
    // The float reader still refuses vectors
    assert!(matches!(
        read_float_grid(&data(SPHERE_CD), &selector("Cd"), &ReadLimits::default()),
        Err(Error::UnsupportedGrid { .. })
    ));
}

/// The limit covers three float grids' worth of output (values and origins per
/// component), checked before allocating, in-process and isolated.
#[test]
fn memory_limit_counts_three_components() {
    let path = data(SPHERE_CD);
    let needed: u64 = 56 * 3 * (512 * 4 + 12);
    for limit in [needed - 1, needed] {
        let limits = ReadLimits { max_bytes: limit };
        let local = read_vec3_grid(&path, &selector("Cd"), &limits);
        let isolated = read_vec3_grid_isolated(
            &PLUME.into(),
            &path,
            &selector("Cd"),
            &limits,
            &IsolationLimits::new(&ReadLimits::default(), Duration::from_secs(60)),
        );
        for result in [local, isolated] {
            match result {
                Err(Error::TooLarge { needed: n, limit: l, grid, .. }) if limit < needed => {
                    assert_eq!((n, l, grid.as_str()), (needed, limit, "Cd"));
                }
                Ok(grids) if limit == needed => assert_eq!(grids[0].leaf_count(), 56),
                other => panic!("limit {limit}: {other:?}"),
            }
        }
    }
}

/// Damaged vector files are errors, never crashes: `Cd` cut inside its leaf data (OpenVDB
/// alone would fill the missing leaves with garbage), in-process and isolated, and the
/// crash and hang inputs of `data/regressions/` asked for as vectors in the isolated reader.
#[test]
fn damaged_files_are_clean_errors_for_vec3_reads() {
    let bytes = fs::read(data(SPHERE_CD)).unwrap();
    let dir = scratch_dir("vec3_grids", "truncated");
    for percent in [30, 60, 99] {
        let path = dir.join(format!("{percent}.vdb"));
        fs::write(&path, &bytes[..bytes.len() * percent / 100]).unwrap();
        for result in [read_local(&path, "Cd"), read_isolated(&path, "Cd")] {
            match result {
                Err(Error::Vdb { message, .. }) => {
                    assert!(message.contains("truncated"), "{percent}%: {message}")
                }
                other => panic!("{percent}%: expected a Vdb error, got {other:?}"),
            }
        }
    }
    let regressions = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/regressions");
    let mut files: Vec<_> = fs::read_dir(&regressions)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "vdb"))
        .collect();
    files.sort();
    assert!(files.len() >= 6);
    for file in files {
        for grid in ["density", "heat", "Cd"] {
            let error = read_isolated(&file, grid).expect_err("a damaged file");
            let message = error.to_string();
            assert!(message.contains(s(&file)) && !message.contains('\n'), "{message}");
        }
    }
}

/// `plume info` lists vector grids with their magnitude range, and an empty one without.
#[test]
fn plume_info_lists_vector_grids() {
    let out = plume(&["info", s(&data(FRAME_1))]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    let velocity =
        text.split("\n\n").find(|block| block.contains("] velocity")).expect("velocity listed");
    assert!(velocity.contains("vec3s") && velocity.contains("staggered"), "{velocity}");
    assert!(velocity.contains("values        -"), "{velocity}");

    let out = plume(&["info", s(&fixture("vec3.vdb"))]);
    let text = String::from_utf8_lossy(&out.stdout);
    // vel_double: the voxel (1.25, -2.5, 3.75) and the tile (2, -4, 6)
    let (low, high) =
        (f64::sqrt(1.25 * 1.25 + 2.5 * 2.5 + 3.75 * 3.75), f64::sqrt(4.0 + 16.0 + 36.0));
    assert!(text.contains(&format!("min {low:.6}  max {high:.6}")), "{text}");
    assert!(text.contains("vec3d"), "{text}");
}
