//! Tests of [`super`]: the parsers on their own, then whole fake `/proc` + `/sys/fs/cgroup`
//! trees in temporary directories (v1, v2, hybrid, nested, missing and garbled files).

use super::*;

const MIB: u64 = 1 << 20;
const GIB: u64 = 1 << 30;

/// A fake file-system root in a temporary directory, removed on drop.
struct FakeRoot {
    dir: PathBuf,
}

impl FakeRoot {
    fn new(name: &str) -> FakeRoot {
        let dir = std::env::temp_dir().join(format!("plume-memory-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create fake root");
        FakeRoot { dir }
    }

    /// Write `contents` to `relative` (parents created).
    fn file(&self, relative: &str, contents: impl AsRef<[u8]>) -> &FakeRoot {
        let path = self.dir.join(relative);
        std::fs::create_dir_all(path.parent().expect("a parent")).expect("create dirs");
        std::fs::write(&path, contents).expect("write fake file");
        self
    }

    /// `/proc/meminfo` with `MemTotal` and `MemAvailable` in GiB.
    fn meminfo(&self, total_gib: u64, available_gib: u64) -> &FakeRoot {
        let text = format!(
            "MemTotal:       {} kB\nMemFree:          1000 kB\nMemAvailable:   {} kB\n",
            total_gib << 20,
            available_gib << 20
        );
        self.file("proc/meminfo", text)
    }

    fn read(&self) -> MemoryLimits {
        MemoryLimits::read_from(&self.dir)
    }
}

impl Drop for FakeRoot {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

fn level(
    version: CgroupVersion,
    limit: u64,
    usage: Option<u64>,
    file_pages: Option<u64>,
) -> CgroupLevel {
    CgroupLevel { version, dir: PathBuf::from("/x"), limit, usage, file_pages }
}

/// The `memory.stat` lines this module reads, among others.
fn v2_stat(active_file: u64, inactive_file: u64) -> String {
    format!(
        "anon 1000\nfile {}\nactive_anon 10\ninactive_anon 990\nactive_file {active_file}\ninactive_file {inactive_file}\nshmem 0\n",
        active_file + inactive_file
    )
}

// ---------------------------------------------------------------------------------------
// Parsers

#[test]
fn meminfo_reads_total_and_available_in_kib() {
    let m =
        parse_meminfo("MemTotal:       24684084 kB\nMemFree:  3 kB\nMemAvailable:   23499992 kB\n");
    assert_eq!(m, Meminfo { total: Some(24_684_084 * 1024), available: Some(23_499_992 * 1024) });
    // Old kernels have no MemAvailable; garbage and overflow are ignored
    assert_eq!(
        parse_meminfo("MemTotal: 1024 kB\n"),
        Meminfo { total: Some(1 << 20), available: None }
    );
    assert_eq!(
        parse_meminfo("MemTotal: lots kB\nMemAvailable: 18446744073709551615 kB\n"),
        Meminfo::default()
    );
    assert_eq!(parse_meminfo(""), Meminfo::default());
    // A key that only starts like ours is not ours
    assert_eq!(parse_meminfo("MemTotalX: 5 kB\n").total, None);
}

#[test]
fn proc_cgroup_finds_the_v2_and_v1_memory_paths() {
    assert_eq!(
        parse_proc_cgroup("0::/user.slice/session-1.scope\n"),
        CgroupPaths { v2: Some("/user.slice/session-1.scope".into()), v1_memory: None }
    );
    // A hybrid system (this one's layout): v1 controllers and an empty v2 line
    let hybrid = "9:name=systemd:/\n5:devices:/\n4:memory:/process_api/ee46\n3:cpuset:/\n0::/\n";
    assert_eq!(
        parse_proc_cgroup(hybrid),
        CgroupPaths { v2: Some("/".into()), v1_memory: Some("/process_api/ee46".into()) }
    );
    // Co-mounted controllers; a path with colons keeps them
    assert_eq!(parse_proc_cgroup("3:cpu,memory:/job:7\n").v1_memory.as_deref(), Some("/job:7"));
    // `memory` must be a whole controller name
    assert_eq!(parse_proc_cgroup("3:memory_x:/a\n4:name=memory:/b\n").v1_memory, None);
}

#[test]
fn proc_cgroup_ignores_garbage() {
    for text in ["", "garbage\n", "0:/no-third-field\n", "0::relative\n", "\u{0}\u{1}:::\n", "::\n"]
    {
        assert_eq!(parse_proc_cgroup(text), CgroupPaths::default(), "{text:?}");
    }
}

#[test]
fn limits_parse_with_max_huge_zero_and_garbage_meaning_none() {
    assert_eq!(parse_limit("536870912\n"), Some(512 * MIB));
    assert_eq!(parse_limit("max\n"), None);
    assert_eq!(parse_limit("9223372036854771712\n"), None, "cgroup v1's 'no limit'");
    assert_eq!(parse_limit(&(1u64 << 62).to_string()), None);
    assert_eq!(parse_limit(&((1u64 << 62) - 1).to_string()), Some((1 << 62) - 1));
    for garbage in ["0", "", "-1", "1.5G", "max max", "18446744073709551616", "\u{fffd}"] {
        assert_eq!(parse_limit(garbage), None, "{garbage:?}");
    }
}

#[test]
fn cgroup_paths_outside_the_namespace_are_not_followed() {
    assert_eq!(cgroup_components("/"), Some(vec![]));
    assert_eq!(cgroup_components("/a/b//c/"), Some(vec!["a", "b", "c"]));
    assert_eq!(cgroup_components("/../../host.slice"), None);
    assert_eq!(cgroup_components("/a/./b"), None);
}

#[test]
fn stat_sums_need_every_key() {
    let stat = v2_stat(3, 4);
    assert_eq!(parse_stat_sum(&stat, &["active_file", "inactive_file"]), Some(7));
    assert_eq!(parse_stat_sum(&stat, &["total_active_file", "total_inactive_file"]), None);
    assert_eq!(
        parse_stat_sum("active_file x\ninactive_file 4\n", &["active_file", "inactive_file"]),
        None
    );
    assert_eq!(
        parse_stat_sum(
            "active_file 18446744073709551615\ninactive_file 4\n",
            &["active_file", "inactive_file"]
        ),
        None,
        "overflow"
    );
}

#[test]
fn available_under_a_limit_counts_file_pages_as_reclaimable() {
    let v = CgroupVersion::V2;
    assert_eq!(level(v, GIB, Some(600 * MIB), Some(100 * MIB)).available(), 524 * MIB);
    assert_eq!(level(v, GIB, None, None).available(), GIB, "usage unknown: the limit");
    assert_eq!(
        level(v, GIB, Some(600 * MIB), None).available(),
        424 * MIB,
        "no memory.stat: usage counts in full"
    );
    assert_eq!(level(v, GIB, Some(2 * GIB), Some(0)).available(), 0, "over the limit");
    assert_eq!(level(v, GIB, Some(GIB), Some(2 * GIB)).available(), GIB, "never above the limit");
}

#[test]
fn the_tightest_figure_wins_and_ties_keep_the_machine_figure() {
    let cgroup = |limit, usage| MemoryLimits {
        physical: Some(8 * GIB),
        mem_available: Some(6 * GIB),
        cgroup_levels: vec![level(CgroupVersion::V1, limit, usage, None)],
    };
    let tight = cgroup(2 * GIB, Some(GIB));
    assert_eq!(
        tight.limit(),
        Some(MemoryBound { bytes: 2 * GIB, source: MemorySource::Cgroup(CgroupVersion::V1) })
    );
    assert_eq!(
        tight.available(),
        Some(MemoryBound { bytes: GIB, source: MemorySource::Cgroup(CgroupVersion::V1) })
    );
    assert_eq!(tight.default_budget(), GIB);
    let loose = cgroup(8 * GIB, Some(GIB));
    assert_eq!(loose.limit(), Some(MemoryBound { bytes: 8 * GIB, source: MemorySource::Physical }));
    assert_eq!(
        loose.available(),
        Some(MemoryBound { bytes: 6 * GIB, source: MemorySource::MemAvailable })
    );
    assert_eq!(MemoryLimits::default().limit(), None);
    assert_eq!(MemoryLimits::default().default_budget(), 4 * GIB);
    let cgroup_only = MemoryLimits {
        cgroup_levels: vec![level(CgroupVersion::V2, GIB, None, None)],
        ..MemoryLimits::default()
    };
    assert_eq!(cgroup_only.limit().map(|l| l.bytes), Some(GIB));
}

#[test]
fn bounds_say_where_they_came_from() {
    let b = |bytes, source| MemoryBound { bytes, source }.to_string();
    assert_eq!(
        b(1_500_000_000, MemorySource::Cgroup(CgroupVersion::V2)),
        "1.50 GB under this process's cgroup v2 memory limit"
    );
    assert_eq!(b(2_000_000_000, MemorySource::MemAvailable), "2.00 GB, MemAvailable");
    assert_eq!(b(8_000_000_000, MemorySource::Physical), "8.00 GB of physical memory");
}

// ---------------------------------------------------------------------------------------
// Fake trees

#[test]
fn no_cgroup_gives_the_machine_figures() {
    let root = FakeRoot::new("none");
    root.meminfo(24, 20).file("proc/self/cgroup", "0::/\n");
    let m = root.read();
    assert_eq!(
        m,
        MemoryLimits {
            physical: Some(24 * GIB),
            mem_available: Some(20 * GIB),
            cgroup_levels: vec![]
        }
    );
    assert_eq!(m.limit(), Some(MemoryBound { bytes: 24 * GIB, source: MemorySource::Physical }));
    assert_eq!(
        m.available(),
        Some(MemoryBound { bytes: 20 * GIB, source: MemorySource::MemAvailable })
    );
    assert_eq!(m.default_budget(), 12 * GIB);
}

#[test]
fn an_empty_root_gives_nothing_and_the_fallback_budget() {
    let root = FakeRoot::new("empty");
    let m = root.read();
    assert_eq!(m, MemoryLimits::default());
    assert_eq!(m.default_budget(), 4 * GIB);
}

#[test]
fn v2_nested_levels_take_the_smallest_limit() {
    let root = FakeRoot::new("v2-nested");
    let job = "sys/fs/cgroup/system.slice/slurmstepd.scope/job_7";
    root.meminfo(24, 20)
        .file("proc/self/cgroup", "0::/system.slice/slurmstepd.scope/job_7/step_0\n")
        .file("sys/fs/cgroup/system.slice/memory.max", "max\n")
        .file("sys/fs/cgroup/system.slice/memory.current", "9000000000\n")
        .file("sys/fs/cgroup/system.slice/slurmstepd.scope/memory.max", (4 * GIB).to_string())
        .file(&format!("{job}/memory.max"), format!("{}\n", 1536 * MIB))
        .file(&format!("{job}/memory.high"), "max\n")
        .file(&format!("{job}/memory.current"), format!("{}\n", 1400 * MIB))
        .file(&format!("{job}/memory.stat"), v2_stat(100 * MIB, 900 * MIB))
        .file(&format!("{job}/step_0/memory.max"), "max\n")
        .file(&format!("{job}/step_0/memory.current"), format!("{}\n", 1300 * MIB));
    let m = root.read();
    assert_eq!(m.cgroup_levels.len(), 2, "{m:?}");
    let tight = m.cgroup_limit().expect("a limit");
    assert_eq!(
        (tight.version, tight.limit, tight.usage, tight.file_pages),
        (CgroupVersion::V2, 1536 * MIB, Some(1400 * MIB), Some(1000 * MIB))
    );
    assert_eq!(tight.dir, root.dir.join(job));
    assert_eq!(
        m.limit(),
        Some(MemoryBound { bytes: 1536 * MIB, source: MemorySource::Cgroup(CgroupVersion::V2) })
    );
    // 1.5 GiB − (1400 − 1000) MiB: the page cache is reclaimable
    assert_eq!(
        m.available(),
        Some(MemoryBound { bytes: 1136 * MIB, source: MemorySource::Cgroup(CgroupVersion::V2) })
    );
    assert_eq!(m.default_budget(), 768 * MIB);
}

#[test]
fn v2_memory_high_counts_as_a_limit() {
    let root = FakeRoot::new("v2-high");
    root.meminfo(24, 20)
        .file("proc/self/cgroup", "0::/a\n")
        .file("sys/fs/cgroup/a/memory.max", "max\n")
        .file("sys/fs/cgroup/a/memory.high", "1073741824\n");
    assert_eq!(
        root.read().limit(),
        Some(MemoryBound { bytes: GIB, source: MemorySource::Cgroup(CgroupVersion::V2) })
    );
}

#[test]
fn a_parent_with_less_left_decides_what_is_available() {
    // The job's own limit is the tightest, but its parent is nearly full with siblings
    let root = FakeRoot::new("v2-parent-full");
    root.meminfo(24, 20)
        .file("proc/self/cgroup", "0::/farm/job\n")
        .file("sys/fs/cgroup/farm/memory.max", (4 * GIB).to_string())
        .file("sys/fs/cgroup/farm/memory.current", (4 * GIB - 100 * MIB).to_string())
        .file("sys/fs/cgroup/farm/memory.stat", v2_stat(0, 0))
        .file("sys/fs/cgroup/farm/job/memory.max", (2 * GIB).to_string())
        .file("sys/fs/cgroup/farm/job/memory.current", (100 * MIB).to_string());
    let m = root.read();
    assert_eq!(m.limit().map(|l| l.bytes), Some(2 * GIB));
    assert_eq!(m.available().map(|l| l.bytes), Some(100 * MIB));
    assert_eq!(
        m.cgroup_available().map(|l| l.dir.clone()),
        Some(root.dir.join("sys/fs/cgroup/farm"))
    );
}

#[test]
fn v1_limit_usage_and_hierarchical_stat() {
    let root = FakeRoot::new("v1");
    let dir = "sys/fs/cgroup/memory/docker/abc";
    root.meminfo(24, 20)
        .file("proc/self/cgroup", "5:devices:/docker/abc\n4:memory:/docker/abc\n0::/\n")
        .file("sys/fs/cgroup/memory/memory.limit_in_bytes", "9223372036854771712\n")
        .file(&format!("{dir}/memory.limit_in_bytes"), format!("{}\n", 512 * MIB))
        .file(&format!("{dir}/memory.usage_in_bytes"), format!("{}\n", 500 * MIB))
        .file(
            &format!("{dir}/memory.stat"),
            format!(
                "active_file 1\ninactive_file 2\ntotal_active_file {}\ntotal_inactive_file {}\n",
                50 * MIB,
                50 * MIB
            ),
        );
    let m = root.read();
    assert_eq!(m.cgroup_levels.len(), 1, "the root's 'no limit' is none: {m:?}");
    assert_eq!(
        m.limit(),
        Some(MemoryBound { bytes: 512 * MIB, source: MemorySource::Cgroup(CgroupVersion::V1) })
    );
    assert_eq!(
        m.available(),
        Some(MemoryBound { bytes: 112 * MIB, source: MemorySource::Cgroup(CgroupVersion::V1) })
    );
    assert_eq!(m.default_budget(), 256 * MIB);
}

#[test]
fn v1_without_total_stat_keys_uses_the_plain_ones() {
    let root = FakeRoot::new("v1-plain-stat");
    let dir = "sys/fs/cgroup/memory/job";
    root.file("proc/self/cgroup", "4:memory:/job\n")
        .file(&format!("{dir}/memory.limit_in_bytes"), (GIB).to_string())
        .file(&format!("{dir}/memory.usage_in_bytes"), (GIB).to_string())
        .file(
            &format!("{dir}/memory.stat"),
            format!("active_file {}\ninactive_file {}\n", 100 * MIB, 200 * MIB),
        );
    let m = root.read();
    assert_eq!(
        m.available(),
        Some(MemoryBound { bytes: 300 * MIB, source: MemorySource::Cgroup(CgroupVersion::V1) })
    );
    assert_eq!(m.physical, None);
}

#[test]
fn a_container_without_a_cgroup_namespace_finds_its_limit_at_the_mount_root() {
    // /proc/self/cgroup names the host's path, which does not exist inside the container
    let root = FakeRoot::new("v1-container");
    root.meminfo(24, 20)
        .file("proc/self/cgroup", "4:memory:/kubepods/burstable/pod1/ctr\n")
        .file("sys/fs/cgroup/memory/memory.limit_in_bytes", format!("{}\n", 3 * GIB))
        .file("sys/fs/cgroup/memory/memory.usage_in_bytes", format!("{}\n", GIB));
    let m = root.read();
    assert_eq!(
        m.limit(),
        Some(MemoryBound { bytes: 3 * GIB, source: MemorySource::Cgroup(CgroupVersion::V1) })
    );
    assert_eq!(m.available().map(|a| a.bytes), Some(2 * GIB));
}

#[test]
fn hybrid_systems_read_both_hierarchies() {
    let root = FakeRoot::new("hybrid");
    root.meminfo(24, 20)
        .file("proc/self/cgroup", "4:memory:/slurm/job\n0::/slurm/job\n")
        .file("sys/fs/cgroup/slurm/job/memory.max", (3 * GIB).to_string())
        .file("sys/fs/cgroup/memory/slurm/job/memory.limit_in_bytes", (2 * GIB).to_string());
    let m = root.read();
    assert_eq!(
        m.cgroup_levels.iter().map(|l| (l.version, l.limit)).collect::<Vec<_>>(),
        [(CgroupVersion::V2, 3 * GIB), (CgroupVersion::V1, 2 * GIB)]
    );
    assert_eq!(m.limit().map(|l| l.source), Some(MemorySource::Cgroup(CgroupVersion::V1)));
}

#[test]
fn a_cgroup_limit_above_physical_memory_does_not_decide() {
    let root = FakeRoot::new("loose");
    root.meminfo(8, 6)
        .file("proc/self/cgroup", "0::/big\n")
        .file("sys/fs/cgroup/big/memory.max", (64 * GIB).to_string());
    let m = root.read();
    assert_eq!(m.limit(), Some(MemoryBound { bytes: 8 * GIB, source: MemorySource::Physical }));
    assert_eq!(
        m.available(),
        Some(MemoryBound { bytes: 6 * GIB, source: MemorySource::MemAvailable })
    );
}

#[test]
fn garbage_and_missing_files_set_no_limit() {
    let root = FakeRoot::new("garbage");
    root.file("proc/meminfo", [0xff, 0xfe, 0x00, 0x80])
        .file("proc/self/cgroup", "0::/a/b\n4:memory:/a\n")
        .file("sys/fs/cgroup/a/b/memory.max", "lots\n")
        .file("sys/fs/cgroup/a/b/memory.high", [0xff, 0xff])
        .file("sys/fs/cgroup/a/memory.max", "")
        .file("sys/fs/cgroup/memory/a/memory.limit_in_bytes", "-5\n")
        .file("sys/fs/cgroup/memory/memory.limit_in_bytes", "0\n");
    assert_eq!(root.read(), MemoryLimits::default());
    // A limit with garbled usage and stat still limits; available is then the limit
    root.file("sys/fs/cgroup/a/memory.max", "1073741824\n")
        .file("sys/fs/cgroup/a/memory.current", "x\n")
        .file("sys/fs/cgroup/a/memory.stat", "active_file\n");
    let m = root.read();
    assert_eq!(
        m.cgroup_levels,
        [CgroupLevel {
            version: CgroupVersion::V2,
            dir: root.dir.join("sys/fs/cgroup/a"),
            limit: GIB,
            usage: None,
            file_pages: None
        }]
    );
    assert_eq!(m.available().map(|a| a.bytes), Some(GIB));
}

#[test]
fn a_directory_where_a_file_should_be_is_ignored() {
    let root = FakeRoot::new("dirs");
    std::fs::create_dir_all(root.dir.join("proc/self/cgroup")).unwrap();
    std::fs::create_dir_all(root.dir.join("proc/meminfo")).unwrap();
    assert_eq!(root.read(), MemoryLimits::default());
}

#[test]
fn a_path_outside_the_cgroup_namespace_reads_no_cgroup() {
    let root = FakeRoot::new("outside");
    root.meminfo(24, 20)
        .file("proc/self/cgroup", "0::/../../other\n")
        .file("sys/fs/cgroup/memory.max", (GIB).to_string());
    assert_eq!(root.read().cgroup_levels, []);
}

#[test]
fn this_machine_reads_without_panicking() {
    let m = MemoryLimits::read();
    assert!(m.physical.is_some_and(|p| p > 0), "{m:?}");
    assert!(m.default_budget() > 0);
    if let Some(available) = m.available() {
        assert!(available.bytes <= m.mem_available.unwrap_or(u64::MAX), "{m:?}");
    }
}
