//! `plume synth flare` as users run it: a small .vdb, and the refusals that point large
//! flares elsewhere.

use crate::common;

use common::{plume, tmpdir};

#[test]
fn synth_flare_writes_a_vdb_with_density_and_temperature() {
    let d = tmpdir("flare", "vdb");
    let p = d.join("flare.vdb");
    let o =
        plume(&["synth", "flare", "--resolution", "45", "--seed", "2", "-o", p.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let info = plume(&["info", p.to_str().unwrap(), "--json"]);
    assert!(info.status.success(), "{}", String::from_utf8_lossy(&info.stderr));
    let grids: serde_json::Value = serde_json::from_slice(&info.stdout).expect("json");
    let names: Vec<&str> =
        grids.as_array().expect("array").iter().filter_map(|g| g["name"].as_str()).collect();
    assert!(names.contains(&"density") && names.contains(&"temperature"), "{names:?}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn synth_flare_refuses_a_vdb_too_large_for_memory() {
    let d = tmpdir("flare", "large");
    let p = d.join("big.vdb");
    let o = plume(&["synth", "flare", "--resolution", "4096", "-o", p.to_str().unwrap()]);
    assert!(!o.status.success());
    let message = String::from_utf8_lossy(&o.stderr);
    assert!(
        message.contains("--resolution") && message.contains("GiB") && message.contains(".plume"),
        "{message}"
    );
    assert!(!p.exists());
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn synth_flare_refuses_other_outputs() {
    let o = plume(&["synth", "flare", "--resolution", "16", "-o", "/nonexistent/flare.raw"]);
    assert_eq!(o.status.code(), Some(2));
    let message = String::from_utf8_lossy(&o.stderr);
    assert!(message.contains("--output") && message.contains(".plume"), "{message}");
}
