//! The memory this process may use: physical RAM, the kernel's `MemAvailable`, and the
//! memory limits of the control group (cgroup) it runs in. The tightest figure wins.
//!
//! Why: on a render farm (Slurm, Kubernetes, Docker) a job runs in a cgroup whose memory
//! limit is far below the machine's RAM, and the page cache of a mapped brick cache is
//! charged to that cgroup. `/proc/meminfo` describes the whole machine, so a 4.8 GB cache
//! in a 1.5 GiB cgroup looked as if it fitted, was rendered in progressive passes, and was
//! read from disk again on every pass (100× slower). Two decisions use these figures:
//! the default memory budget (half of [`MemoryLimits::limit`]: physical RAM or the cgroup
//! limit) and `--sample-order auto` ([`MemoryLimits::available`]: `MemAvailable` or what
//! the cgroup still has).
//!
//! What is read, under a file-system root (`/`; a temporary tree in tests):
//! - `/proc/meminfo`: `MemTotal` (physical memory; `sysconf` where it is missing) and
//!   `MemAvailable`, both in KiB.
//! - `/proc/self/cgroup`: the process's cgroup paths, one `id:controllers:path` line per
//!   hierarchy. `0::/path` is cgroup v2; a line whose controllers include `memory` is
//!   cgroup v1. Hybrid systems have both lines, and both are read.
//! - cgroup v2, in `/sys/fs/cgroup/<path>` and each parent up to `/sys/fs/cgroup`:
//!   `memory.max` and `memory.high` (`max` = no limit; past `memory.high` the kernel
//!   reclaims and throttles, so for page cache it is a limit too), `memory.current` and
//!   `memory.stat`.
//! - cgroup v1, in `/sys/fs/cgroup/memory/<path>` and each parent:
//!   `memory.limit_in_bytes` (the kernel writes "no limit" as 2^63 − 4096; anything from
//!   2^62 up is taken as none), `memory.usage_in_bytes` and `memory.stat`.
//!
//! Every level up to the mount root is read: a parent's limit binds its children, and in a
//! container without a cgroup namespace `/proc/self/cgroup` names the host's path while
//! the container's own cgroup is mounted at the root. A path leading outside the namespace
//! (`/..`) is not followed. A missing, unreadable or garbled file sets no limit; nothing
//! here fails or panics.
//!
//! What a cgroup still has available is its limit minus its usage plus its file pages
//! (`active_file + inactive_file` in `memory.stat`; v1 `total_…`, which include children):
//! page cache counts against the limit, but the kernel reclaims it first, as `MemAvailable`
//! counts it, and the usage of any long-running cgroup sits at its limit with cache. The
//! smallest over the limited levels wins.

use std::fmt;
use std::path::{Path, PathBuf};

/// The default budget where the OS says nothing about memory.
const FALLBACK_BUDGET_BYTES: u64 = 4 << 30;

/// cgroup v1 writes "no limit" as the largest page-aligned `i64`; values from here up are
/// taken as no limit.
const UNLIMITED_FROM: u64 = 1 << 62;

/// Which cgroup interface a limit was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CgroupVersion {
    /// cgroup v1, the `memory` controller's own hierarchy (`/sys/fs/cgroup/memory`).
    V1,
    /// cgroup v2, the unified hierarchy (`/sys/fs/cgroup`).
    V2,
}

impl fmt::Display for CgroupVersion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            CgroupVersion::V1 => "cgroup v1",
            CgroupVersion::V2 => "cgroup v2",
        })
    }
}

/// One level of this process's cgroup (itself or a parent) that has a memory limit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CgroupLevel {
    /// The interface it was read from.
    pub version: CgroupVersion,
    /// The cgroup's directory.
    pub dir: PathBuf,
    /// Its limit, bytes: v2 the smaller of `memory.max` and `memory.high`, v1
    /// `memory.limit_in_bytes`.
    pub limit: u64,
    /// Memory charged to it now, page cache included (`memory.current`,
    /// `memory.usage_in_bytes`), bytes; `None` where unreadable.
    pub usage: Option<u64>,
    /// File pages in that usage, which the kernel can reclaim (`active_file +
    /// inactive_file` of `memory.stat`), bytes; `None` where unreadable.
    pub file_pages: Option<u64>,
}

impl CgroupLevel {
    /// Bytes still available under this limit: `limit − (usage − file_pages)`, between 0
    /// and the limit; the limit itself where the usage is unknown.
    #[must_use]
    pub fn available(&self) -> u64 {
        let Some(usage) = self.usage else { return self.limit };
        self.limit.saturating_sub(usage.saturating_sub(self.file_pages.unwrap_or(0)))
    }
}

/// Where a memory figure came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemorySource {
    /// Physical memory (`MemTotal`).
    Physical,
    /// The kernel's estimate of memory available without swapping (`MemAvailable`).
    MemAvailable,
    /// A memory limit of this process's cgroup (the figure is the limit, or what is
    /// still available under it).
    Cgroup(CgroupVersion),
}

/// A number of bytes and where it came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryBound {
    /// Bytes.
    pub bytes: u64,
    /// Which figure it is.
    pub source: MemorySource,
}

impl fmt::Display for MemoryBound {
    /// `1.23 GB under this process's cgroup v2 memory limit`, `1.23 GB, MemAvailable`, …
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let gb = self.bytes as f64 / 1e9;
        match self.source {
            MemorySource::Physical => write!(f, "{gb:.2} GB of physical memory"),
            MemorySource::MemAvailable => write!(f, "{gb:.2} GB, MemAvailable"),
            MemorySource::Cgroup(version) => {
                write!(f, "{gb:.2} GB under this process's {version} memory limit")
            }
        }
    }
}

/// The memory figures of this process (see the module docs for what is read).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct MemoryLimits {
    /// Physical memory, bytes; `None` where the OS does not say.
    pub physical: Option<u64>,
    /// `MemAvailable`, bytes: memory the OS could give without swapping, reclaimable page
    /// cache included; `None` where `/proc/meminfo` is unavailable.
    pub mem_available: Option<u64>,
    /// The levels of this process's cgroups that have a memory limit, innermost first (v2
    /// levels before v1 ones); empty where there are none.
    pub cgroup_levels: Vec<CgroupLevel>,
}

impl MemoryLimits {
    /// This process's figures, read now (a few small files; no caching, as limits and
    /// usage change).
    #[must_use]
    pub fn read() -> MemoryLimits {
        let mut limits = MemoryLimits::read_from(Path::new("/"));
        if limits.physical.is_none() {
            limits.physical = sysconf_physical_bytes();
        }
        limits
    }

    /// The figures from the files under `root` (`/` for this process; a fake tree in
    /// tests). Physical memory is `MemTotal` only.
    #[must_use]
    pub fn read_from(root: &Path) -> MemoryLimits {
        let meminfo = read_text(&root.join("proc/meminfo"))
            .map_or_else(Meminfo::default, |t| parse_meminfo(&t));
        let paths = read_text(&root.join("proc/self/cgroup"))
            .map_or_else(CgroupPaths::default, |t| parse_proc_cgroup(&t));
        let mut cgroup_levels = Vec::new();
        if let Some(path) = &paths.v2 {
            cgroup_levels.extend(limited_levels(
                &root.join("sys/fs/cgroup"),
                path,
                CgroupVersion::V2,
            ));
        }
        if let Some(path) = &paths.v1_memory {
            cgroup_levels.extend(limited_levels(
                &root.join("sys/fs/cgroup/memory"),
                path,
                CgroupVersion::V1,
            ));
        }
        MemoryLimits { physical: meminfo.total, mem_available: meminfo.available, cgroup_levels }
    }

    /// The level with the smallest limit (the innermost of equals).
    #[must_use]
    pub fn cgroup_limit(&self) -> Option<&CgroupLevel> {
        self.cgroup_levels.iter().min_by_key(|l| l.limit)
    }

    /// The level with the least still available (the innermost of equals).
    #[must_use]
    pub fn cgroup_available(&self) -> Option<&CgroupLevel> {
        self.cgroup_levels.iter().min_by_key(|l| l.available())
    }

    /// The most this process may ever hold: physical memory or the tightest cgroup limit,
    /// whichever is smaller (physical memory on a tie).
    #[must_use]
    pub fn limit(&self) -> Option<MemoryBound> {
        let physical =
            self.physical.map(|bytes| MemoryBound { bytes, source: MemorySource::Physical });
        let cgroup = self
            .cgroup_limit()
            .map(|l| MemoryBound { bytes: l.limit, source: MemorySource::Cgroup(l.version) });
        tighter(physical, cgroup)
    }

    /// What this process could still get now: `MemAvailable` or the least still available
    /// under a cgroup limit, whichever is smaller (`MemAvailable` on a tie).
    #[must_use]
    pub fn available(&self) -> Option<MemoryBound> {
        let machine = self
            .mem_available
            .map(|bytes| MemoryBound { bytes, source: MemorySource::MemAvailable });
        let cgroup = self
            .cgroup_available()
            .map(|l| MemoryBound { bytes: l.available(), source: MemorySource::Cgroup(l.version) });
        tighter(machine, cgroup)
    }

    /// The default memory budget (`render.memory_budget`, `reading.max_input_memory`): half
    /// of [`MemoryLimits::limit`], or 4 GiB where nothing is known.
    #[must_use]
    pub fn default_budget(&self) -> u64 {
        self.limit().map_or(FALLBACK_BUDGET_BYTES, |l| l.bytes / 2)
    }
}

/// `a` unless `b` is strictly smaller; whichever exists.
fn tighter(a: Option<MemoryBound>, b: Option<MemoryBound>) -> Option<MemoryBound> {
    match (a, b) {
        (Some(a), Some(b)) => Some(if b.bytes < a.bytes { b } else { a }),
        (a, b) => a.or(b),
    }
}

/// The levels with a memory limit of the cgroup at `path` under the hierarchy mounted at
/// `mount`, innermost first, up to and including the mount root.
fn limited_levels(mount: &Path, path: &str, version: CgroupVersion) -> Vec<CgroupLevel> {
    let Some(components) = cgroup_components(path) else { return Vec::new() };
    (0..=components.len())
        .rev()
        .filter_map(|depth| {
            read_level(
                &components[..depth].iter().fold(mount.to_path_buf(), |d, c| d.join(c)),
                version,
            )
        })
        .collect()
}

/// The level at `dir`, if it has a memory limit.
fn read_level(dir: &Path, version: CgroupVersion) -> Option<CgroupLevel> {
    let file = |name: &str| read_text(&dir.join(name));
    let (limit, usage, stat_keys): (Option<u64>, _, &[[&str; 2]]) = match version {
        CgroupVersion::V2 => (
            ["memory.max", "memory.high"]
                .into_iter()
                .filter_map(|n| file(n).and_then(|t| parse_limit(&t)))
                .min(),
            "memory.current",
            &[["active_file", "inactive_file"]],
        ),
        CgroupVersion::V1 => (
            file("memory.limit_in_bytes").and_then(|t| parse_limit(&t)),
            "memory.usage_in_bytes",
            &[["total_active_file", "total_inactive_file"], ["active_file", "inactive_file"]],
        ),
    };
    let stat = file("memory.stat");
    let file_pages = stat.and_then(|s| stat_keys.iter().find_map(|keys| parse_stat_sum(&s, keys)));
    Some(CgroupLevel {
        version,
        dir: dir.to_path_buf(),
        limit: limit?,
        usage: file(usage).and_then(|t| parse_bytes(&t)),
        file_pages,
    })
}

/// A small text file, or `None`.
fn read_text(path: &Path) -> Option<String> {
    std::fs::read_to_string(path).ok()
}

/// Physical memory from `sysconf`, bytes.
fn sysconf_physical_bytes() -> Option<u64> {
    // SAFETY: sysconf only reads system configuration; it has no preconditions and
    // returns -1 for an unknown name.
    let (pages, page_size) =
        unsafe { (libc::sysconf(libc::_SC_PHYS_PAGES), libc::sysconf(libc::_SC_PAGESIZE)) };
    if pages <= 0 || page_size <= 0 {
        return None;
    }
    (pages as u64).checked_mul(page_size as u64)
}

/// The two `/proc/meminfo` figures used here, bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Meminfo {
    /// `MemTotal`.
    total: Option<u64>,
    /// `MemAvailable`.
    available: Option<u64>,
}

/// `MemTotal` and `MemAvailable` of a `/proc/meminfo` text (`Key:   123 kB` lines).
fn parse_meminfo(text: &str) -> Meminfo {
    let field = |key: &str| {
        text.lines().find_map(|l| {
            let value = l.strip_prefix(key)?.strip_prefix(':')?.trim();
            value.strip_suffix("kB").unwrap_or(value).trim().parse::<u64>().ok()?.checked_mul(1024)
        })
    };
    Meminfo { total: field("MemTotal"), available: field("MemAvailable") }
}

/// The memory cgroup paths of a `/proc/self/cgroup` text.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct CgroupPaths {
    /// The cgroup v2 path (`0::/path`).
    v2: Option<String>,
    /// The cgroup v1 path of the hierarchy with the `memory` controller.
    v1_memory: Option<String>,
}

/// Parse `/proc/self/cgroup`: `hierarchy-id:controller,list:/path` lines; others ignored.
fn parse_proc_cgroup(text: &str) -> CgroupPaths {
    let mut paths = CgroupPaths::default();
    for line in text.lines() {
        let mut fields = line.splitn(3, ':');
        let (Some(id), Some(controllers), Some(path)) =
            (fields.next(), fields.next(), fields.next())
        else {
            continue;
        };
        if !path.starts_with('/') {
            continue;
        }
        if id == "0" && controllers.is_empty() {
            paths.v2.get_or_insert_with(|| path.to_string());
        } else if controllers.split(',').any(|c| c == "memory") {
            paths.v1_memory.get_or_insert_with(|| path.to_string());
        }
    }
    paths
}

/// The components of a cgroup path; `None` for one leading out of the cgroup namespace
/// (`/../..`) or otherwise not a plain path below the mount root.
fn cgroup_components(path: &str) -> Option<Vec<&str>> {
    let components: Vec<&str> = path.split('/').filter(|c| !c.is_empty()).collect();
    components.iter().all(|c| *c != ".." && *c != ".").then_some(components)
}

/// A limit file's value in bytes; `None` for no limit (`max`, 2^62 and up, 0) and for
/// anything that is not a number.
fn parse_limit(text: &str) -> Option<u64> {
    parse_bytes(text).filter(|&b| b > 0 && b < UNLIMITED_FROM)
}

/// A file holding one number of bytes.
fn parse_bytes(text: &str) -> Option<u64> {
    text.trim().parse().ok()
}

/// The sum of the values of `keys` in a `memory.stat` text (`key value` lines); `None`
/// unless every key is there with a number.
fn parse_stat_sum(text: &str, keys: &[&str]) -> Option<u64> {
    keys.iter().try_fold(0u64, |sum, key| {
        let value = text
            .lines()
            .find_map(|l| l.strip_prefix(key)?.strip_prefix(' ')?.trim().parse::<u64>().ok())?;
        sum.checked_add(value)
    })
}

#[cfg(test)]
mod tests;
