//! Classic NEE's brick table (`--nee-table brick`, `light::nee_bricks`): renders give the
//! voxel table's image means for the point and line estimators, nearest and trilinear;
//! the choice is a flag, a scene key and part of the settings hash (the default leaves the
//! hash as it was); a voxel table over the memory budget is refused with the brick table
//! named as the way out, which then renders. The sampling law itself is chi²-tested in
//! `tests/light_sampling.rs`. Fixed seeds; k·σ tolerances from independent runs.

use crate::common;

use common::{explosion, plume, plume_exits, region_means_with, s, tmpdir};
use plume_core::sampling::SamplerKind;
use plume_engine::integrator::{
    AnyScene, Integrator, LightSampling, Lights, MisHeuristic, Tracking,
};
use plume_engine::medium::{Collision, Estimator};
use plume_scene::NeeTable;
use plume_volume::Interpolation;

/// The generated explosion with classic NEE from `table`.
fn scene(table: NeeTable, interpolation: Interpolation) -> AnyScene {
    common::explosion_scene(1.5, interpolation, false, |vol, e| {
        Lights::build_with(vol, e, LightSampling::Nee, 8, table).unwrap()
    })
}

#[test]
fn brick_table_gives_the_image_means_of_the_voxel_table() {
    // 2 estimators × 2 reconstructions × 5 regions = 20 comparisons; Šidák at α = 0.01
    // gives |z| < 3.5 per test
    for interpolation in [Interpolation::Nearest, Interpolation::Linear] {
        let (voxels, bricks) =
            (scene(NeeTable::Voxel, interpolation), scene(NeeTable::Brick, interpolation));
        for estimator in [Estimator::Point, Estimator::Line] {
            let integrator = Integrator {
                estimator,
                camera_estimator: None,
                light_sampling: LightSampling::Nee,
                mis: MisHeuristic::Power,
                max_depth: 64,
                tracking: Tracking::Regular,
                split: 1,
                camera_collision: Collision::Analog,
                point_lookup: plume_engine::integrator::PointLookup::Exact,
                split_by: plume_engine::integrator::SplitBy::Uniform,
            };
            let a = region_means_with(SamplerKind::Sobol, &voxels, integrator, 16, 16, 11);
            let b = region_means_with(SamplerKind::Sobol, &bricks, integrator, 16, 16, 500);
            assert!(a[0].0 > 0.0);
            common::assert_same_means(
                &format!("{interpolation} {estimator:?}, brick table vs voxel table"),
                &b,
                &a,
                3.5,
            );
        }
    }
}

#[test]
fn nee_table_is_a_flag_a_scene_key_and_part_of_the_settings_hash() {
    let dir = tmpdir("nee_table", "cli");
    let vdb = explosion(&dir, 32, Some(3));
    let base = [
        "render",
        s(&vdb),
        "--width",
        "24",
        "--height",
        "16",
        "--spp",
        "4",
        "--albedo",
        "0.8",
        "--method",
        "line-nee",
        "--stats",
    ];
    let hashes = common::settings_hashes(
        &dir,
        &base,
        "--nee-table",
        &[("default", None), ("voxel", Some("voxel")), ("brick", Some("brick"))],
    );
    let pixels = |name: &str| common::exr_pixels(&dir.join(format!("{name}.exr")));
    assert_eq!(pixels("default"), pixels("voxel"));
    assert_ne!(pixels("voxel"), pixels("brick"));
    assert_eq!(hashes[0], hashes[1], "the default changed the settings hash");
    assert_ne!(hashes[1], hashes[2], "the tables share a settings hash");
    let scene_file = dir.join("scene.toml");
    std::fs::write(
        &scene_file,
        format!(
            "[volume]\nfile = {:?}\n[integrator]\nmethod = \"line-nee\"\nnee_table = \"brick\"\n[medium]\nalbedo = 0.8\n[camera]\nwidth = 24\nheight = 16\n",
            s(&vdb)
        ),
    )
    .unwrap();
    let out = dir.join("scene.exr");
    let o = plume(&["render", s(&scene_file), "--spp", "4", "-o", s(&out)]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(common::exr_pixels(&out), pixels("brick"));
    plume_exits(
        &["render", s(&vdb), "--nee-table", "octree", "-o", s(&out)],
        2,
        &["--nee-table", "voxel", "brick"],
    );
}

#[test]
fn a_voxel_table_over_the_budget_names_the_brick_table_which_fits() {
    let dir = tmpdir("nee_table", "budget");
    let vdb = explosion(&dir, 32, Some(3));
    let out = dir.join("x.exr");
    let args = [
        "render",
        s(&vdb),
        "--width",
        "16",
        "--height",
        "12",
        "--spp",
        "2",
        "--albedo",
        "0.8",
        "--method",
        "line-nee",
        "--memory-budget",
        "64KiB",
    ];
    let mut refused = args.to_vec();
    refused.extend(["-o", s(&out)]);
    plume_exits(&refused, 2, &["--memory-budget", "voxel table", "--nee-table brick"]);
    assert!(!out.exists());
    let mut bricks = refused.clone();
    bricks.extend(["--nee-table", "brick"]);
    let o = plume(&bricks);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.exists());
}
