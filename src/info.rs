//! `plume info`: a human-readable table and a JSON dump of [`GridInfo`]s.
//!
//! The JSON is an array with one object per grid, in file order, with the keys `name`,
//! `file_index`, `selector`, `type`, `class`, `active_voxels`, `leaf_count`,
//! `active_tiles`, `index_bbox` (`[[x,y,z],[x,y,z]]`, inclusive, or `null` when empty),
//! `voxel_size` (`[x,y,z]`, world units), `transform`, `min`, `max`, `mean` (`null` when
//! the type has no statistics; vector grids report the magnitude) and `memory_bytes`.

use std::fmt::Write as _;
use std::path::Path;

use crate::vdb::GridInfo;

/// Bytes per MiB, for the table's memory column.
const MIB: f64 = 1024.0 * 1024.0;

/// One block of `key  value` lines per grid, headed by the file name and grid count.
#[must_use]
pub fn format_table(path: &Path, grids: &[GridInfo]) -> String {
    let mut out = String::new();
    let plural = if grids.len() == 1 { "" } else { "s" };
    // Writing into a String cannot fail, so the fmt::Results below are ignored.
    let _ = writeln!(out, "{}: {} grid{plural}", path.display(), grids.len());
    for grid in grids {
        let _ = writeln!(out);
        let _ = writeln!(out, "[{}] {}", grid.file_index, grid.selector);
        let mut line = |key: &str, value: String| {
            let _ = writeln!(out, "    {key:<14}{value}");
        };
        line("name", format!("{:?}", grid.name));
        line("type", grid.value_type.clone());
        line("class", grid.class.clone());
        line("active voxels", group_digits(grid.active_voxels));
        line("leaves", group_digits(grid.leaf_count));
        line("active tiles", group_digits(grid.active_tiles));
        line(
            "index bbox",
            match grid.index_bbox {
                Some([lo, hi]) => format!(
                    "({}, {}, {}) .. ({}, {}, {}), {} x {} x {} voxels",
                    lo[0],
                    lo[1],
                    lo[2],
                    hi[0],
                    hi[1],
                    hi[2],
                    i64::from(hi[0]) - i64::from(lo[0]) + 1,
                    i64::from(hi[1]) - i64::from(lo[1]) + 1,
                    i64::from(hi[2]) - i64::from(lo[2]) + 1
                ),
                None => "empty".to_string(),
            },
        );
        let [sx, sy, sz] = grid.voxel_size;
        line("voxel size", format!("{sx:.6} x {sy:.6} x {sz:.6}"));
        line("transform", grid.transform.clone());
        let magnitude = if grid.value_type.starts_with("vec") { " (magnitude)" } else { "" };
        line(
            "values",
            match (grid.min, grid.max, grid.mean) {
                (Some(min), Some(max), Some(mean)) => {
                    format!("min {min:.6}  max {max:.6}  mean {mean:.6}{magnitude}")
                }
                _ => "-".to_string(),
            },
        );
        line("memory", format!("{:.2} MiB", grid.memory_bytes as f64 / MIB));
    }
    out
}

/// The grids as a pretty-printed JSON array (keys in the module docs).
#[must_use]
pub fn to_json(grids: &[GridInfo]) -> String {
    // Non-finite f64s serialize as null, so serialization of these plain types cannot fail.
    serde_json::to_string_pretty(grids).expect("invariant: GridInfo serializes to JSON")
}

/// A brick cache whose checksums were verified, as `plume info --json` prints it: the
/// file, its size, brick counts and the cache's metadata.
#[must_use]
pub fn cache_json(path: &Path, cache: &crate::cache::Cache) -> serde_json::Value {
    serde_json::json!({
        "file": path,
        "bytes": cache.file_bytes,
        "checksums": "ok",
        "bricks": cache.volume.brick_count(),
        "dense_bricks": cache.volume.dense_brick_count(),
        "meta": cache.meta,
    })
}

/// `1049275` -> `1,049,275`.
fn group_digits(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> GridInfo {
        GridInfo {
            name: "density".into(),
            file_index: 0,
            selector: "density".into(),
            value_type: "float".into(),
            class: "fog volume".into(),
            active_voxels: 1_049_275,
            leaf_count: 3117,
            active_tiles: 0,
            index_bbox: Some([[1, 2, 1], [111, 223, 112]]),
            voxel_size: [0.5, 0.5, 0.25],
            transform: "scale-translate".into(),
            min: Some(0.0),
            max: Some(5.5),
            mean: Some(1.0),
            memory_bytes: 7 * 1024 * 1024,
        }
    }

    #[test]
    fn groups_digits() {
        assert_eq!(group_digits(0), "0");
        assert_eq!(group_digits(999), "999");
        assert_eq!(group_digits(1000), "1,000");
        assert_eq!(group_digits(1_049_275), "1,049,275");
    }

    #[test]
    fn table_shows_every_field() {
        let table = format_table(Path::new("smoke.vdb"), &[sample()]);
        for needle in [
            "smoke.vdb: 1 grid",
            "[0] density",
            "float",
            "fog volume",
            "1,049,275",
            "3,117",
            "(1, 2, 1) .. (111, 223, 112), 111 x 222 x 112 voxels",
            "0.500000 x 0.500000 x 0.250000",
            "scale-translate",
            "max 5.500000",
            "7.00 MiB",
        ] {
            assert!(table.contains(needle), "{needle:?} missing from\n{table}");
        }
    }

    #[test]
    fn json_has_the_documented_keys() {
        let mut empty = sample();
        empty.index_bbox = None;
        empty.min = None;
        let json: serde_json::Value = serde_json::from_str(&to_json(&[sample(), empty])).unwrap();
        let first = &json[0];
        for key in [
            "name",
            "type",
            "class",
            "active_voxels",
            "voxel_size",
            "index_bbox",
            "min",
            "max",
            "mean",
            "transform",
            "memory_bytes",
            "selector",
            "leaf_count",
            "active_tiles",
        ] {
            assert!(first.get(key).is_some(), "key {key} missing");
        }
        assert_eq!(first["index_bbox"], serde_json::json!([[1, 2, 1], [111, 223, 112]]));
        assert_eq!(first["voxel_size"], serde_json::json!([0.5, 0.5, 0.25]));
        assert!(json[1]["index_bbox"].is_null());
        assert!(json[1]["min"].is_null());
    }
}
