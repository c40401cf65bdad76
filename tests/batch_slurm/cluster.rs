//! A one-node Slurm cluster for the tests, from Debian's `slurm-wlm` and `munge`
//! (`scripts/test.sh` installs them).
//!
//! [`Cluster::start`] writes a munge key, `slurm.conf` and `cgroup.conf` into a scratch
//! directory and starts `munged`, `slurmctld` and `slurmd` in the foreground as children of
//! the calling thread, each under `setpriv --pdeathsig KILL`: if the test process dies,
//! the kernel kills them. [`Drop`] cancels every job, waits for the queue to empty and
//! stops the daemons, also when a test panics. Commands reach this cluster and no other
//! through `SLURM_CONF`, set on each child (never on the test process).
//!
//! The node is `hostname -s` at 127.0.0.1 on two free loopback ports, with `select/cons_tres`
//! and `CR_CPU_Memory`. It declares 8 CPUs whatever the machine has
//! (`SlurmdParameters=config_overrides`), so that the scenarios' one-CPU tasks run side by
//! side on a two-core machine; the memory is the machine's. Jobs are confined by
//! `task/cgroup` (`ConstrainRAMSpace`), as on a production cluster, where the machine lets
//! Slurm make cgroups; otherwise the cluster starts again without cgroups and
//! [`Cluster::confined`] says why. Finished jobs are written by `jobcomp/filetxt`, which
//! `sacct --completion` reads, since there is no `slurmdbd`.

use std::io::Write as _;
use std::os::unix::fs::PermissionsExt as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The daemons' programs, and the client commands the tests run.
const PROGRAMS: [&str; 9] =
    ["munged", "slurmctld", "slurmd", "sbatch", "squeue", "sacct", "scancel", "sinfo", "setpriv"];

/// A running one-node cluster; stopped on drop.
pub struct Cluster {
    dir: PathBuf,
    conf: PathBuf,
    host: String,
    /// Whether the `slurm_<host>` cgroups are this cluster's to remove (none existed
    /// before it started).
    owns_cgroups: bool,
    daemons: Vec<Daemon>,
    confined: Result<(), String>,
}

/// One daemon process and the name it is reported by.
struct Daemon {
    name: &'static str,
    child: Child,
}

/// How jobs are tracked and confined.
#[derive(Clone, Copy, PartialEq)]
enum Confinement {
    /// `proctrack/cgroup` and `task/cgroup` with `ConstrainRAMSpace=yes`.
    Cgroup,
    /// `proctrack/linuxproc` and `task/none`: `--mem` is scheduled but not enforced.
    None,
}

/// A job's line in `sacct --completion`.
#[derive(Clone, Debug)]
pub struct Finished {
    /// `COMPLETED`, `FAILED`, `CANCELLED`, `TIMEOUT`, …
    pub state: String,
    /// `ExitCode`: the batch script's exit status and the signal that ended it.
    pub exit_code: String,
}

impl Cluster {
    /// Start a cluster in a fresh scratch directory, or say why this machine cannot have
    /// one.
    pub fn start() -> Result<Cluster, String> {
        // SAFETY: geteuid has no preconditions.
        let euid = unsafe { libc::geteuid() };
        if euid != 0 {
            return Err(format!("not root (effective uid {euid}); the daemons run as root"));
        }
        let missing: Vec<&str> = PROGRAMS.into_iter().filter(|p| which(p).is_none()).collect();
        if !missing.is_empty() {
            return Err(format!(
                "{} not found on PATH; scripts/test.sh installs Debian's slurm-wlm and munge",
                missing.join(", ")
            ));
        }
        let dir = crate::common::tmpdir("slurm", "cluster");
        let cgroup = Cluster::start_in(&dir, Confinement::Cgroup);
        match cgroup {
            Ok(cluster) => Ok(cluster),
            Err(why) => {
                let mut cluster = Cluster::start_in(&dir, Confinement::None)
                    .map_err(|e| format!("with cgroups: {why}; without: {e}"))?;
                cluster.confined = Err(why);
                Ok(cluster)
            }
        }
    }

    fn start_in(dir: &Path, confinement: Confinement) -> Result<Cluster, String> {
        for sub in ["state", "spool", "log", "run"] {
            let path = dir.join(sub);
            let _ = std::fs::remove_dir_all(&path);
            std::fs::create_dir_all(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        }
        let key = dir.join("munge.key");
        let mut bytes = vec![0u8; 1024];
        std::fs::File::open("/dev/urandom")
            .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut bytes))
            .map_err(|e| format!("/dev/urandom: {e}"))?;
        std::fs::write(&key, &bytes).map_err(|e| format!("{}: {e}", key.display()))?;
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).unwrap();
        let host = Command::new("hostname")
            .arg("-s")
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_owned())
            .map_err(|e| format!("hostname: {e}"))?;
        let conf = dir.join("slurm.conf");
        std::fs::write(&conf, slurm_conf(dir, &host, confinement)?).unwrap();
        std::fs::write(dir.join("cgroup.conf"), CGROUP_CONF).unwrap();
        let owns_cgroups = slurm_cgroups(&host).is_empty();
        let mut cluster = Cluster {
            dir: dir.to_owned(),
            conf,
            host,
            owns_cgroups,
            daemons: Vec::new(),
            confined: Ok(()),
        };
        let socket = dir.join("run/munge.socket");
        cluster.spawn(
            "munged",
            &[
                "-F",
                "--force",
                &format!("--key-file={}", key.display()),
                &format!("--socket={}", socket.display()),
                &format!("--pid-file={}", dir.join("run/munged.pid").display()),
                &format!("--log-file={}", dir.join("log/munged.log").display()),
                &format!("--seed-file={}", dir.join("run/munged.seed").display()),
            ],
        )?;
        cluster.wait_for("munged's socket", Duration::from_secs(10), |_| socket.exists())?;
        let conf = cluster.conf.display().to_string();
        cluster.spawn("slurmctld", &["-D", "-f", &conf])?;
        cluster.spawn("slurmd", &["-D", "-f", &conf])?;
        cluster.wait_for("the node to be idle", Duration::from_secs(30), |c| {
            c.run("sinfo", &["-h", "-N", "-o", "%T"])
                .is_ok_and(|o| String::from_utf8_lossy(&o.stdout).trim() == "idle")
        })?;
        Ok(cluster)
    }

    /// `Ok` when jobs run in memory cgroups sized by `--mem`, or why they do not.
    pub fn confined(&self) -> Result<(), &str> {
        self.confined.as_ref().map(|_| ()).map_err(String::as_str)
    }

    /// A client command (`sbatch`, `squeue`, …) or script aimed at this cluster.
    pub fn command(&self, program: impl AsRef<std::ffi::OsStr>) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    /// Run a client command; `Err` with its stderr when it fails.
    pub fn run(&self, program: &str, args: &[&str]) -> Result<Output, String> {
        let o = self.command(program).args(args).output().map_err(|e| format!("{program}: {e}"))?;
        if o.status.success() {
            Ok(o)
        } else {
            Err(format!("{program} {args:?}: {}", String::from_utf8_lossy(&o.stderr).trim()))
        }
    }

    /// The jobs in the queue (pending or running) as `id state reason` lines, array tasks
    /// one per line.
    pub fn queue(&self, ids: &[&str]) -> Vec<String> {
        let o = self
            .run("squeue", &["-h", "-r", "-j", &ids.join(","), "-o", "%i %T %r"])
            .unwrap_or_else(|e| panic!("{e}"));
        String::from_utf8_lossy(&o.stdout).lines().map(str::to_owned).collect()
    }

    /// Poll until no task of the jobs `ids` is in the queue, or panic after `timeout`.
    pub fn wait_until_done(&self, ids: &[&str], timeout: Duration) {
        self.poll(&format!("jobs {ids:?} to leave the queue"), timeout, || {
            self.queue(ids).is_empty()
        });
    }

    /// Poll `ready` every 200 ms until it holds, or panic after `timeout` with the
    /// daemons' logs.
    pub fn poll(&self, what: &str, timeout: Duration, mut ready: impl FnMut() -> bool) {
        let start = Instant::now();
        while !ready() {
            assert!(
                start.elapsed() < timeout,
                "timed out after {timeout:?} waiting for {what}: {}",
                self.log_tails()
            );
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// Poll `ready` every 200 ms until it holds; `Err` after `timeout`, with the daemons'
    /// logs, or as soon as a daemon has exited.
    fn wait_for(
        &mut self,
        what: &str,
        timeout: Duration,
        mut ready: impl FnMut(&Cluster) -> bool,
    ) -> Result<(), String> {
        let start = Instant::now();
        loop {
            if ready(self) {
                return Ok(());
            }
            let exited = self.daemons.iter_mut().find_map(|d| match d.child.try_wait() {
                Ok(Some(status)) => Some(format!("{} exited ({status})", d.name)),
                _ => None,
            });
            if let Some(exited) = exited {
                return Err(format!("{exited}: {}", self.log_tails()));
            }
            if start.elapsed() > timeout {
                return Err(format!(
                    "timed out after {timeout:?} waiting for {what}: {}",
                    self.log_tails()
                ));
            }
            std::thread::sleep(Duration::from_millis(200));
        }
    }

    /// Every finished job in `sacct --completion` named `name`.
    pub fn finished(&self, name: &str) -> Vec<Finished> {
        // sacct's filetxt reader does not filter by name, and it warns on stderr about the
        // array fields it cannot parse: filter here, and read stdout only.
        let o = self
            .run("sacct", &["--completion", "-n", "-P", "-o", "JobID,JobName,State,ExitCode"])
            .unwrap_or_else(|e| panic!("{e}"));
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .filter_map(|line| {
                let f: Vec<&str> = line.split('|').collect();
                (f.len() == 4 && f[1] == name)
                    .then(|| Finished { state: f[2].into(), exit_code: f[3].into() })
            })
            .collect()
    }

    fn spawn(&mut self, name: &'static str, args: &[&str]) -> Result<(), String> {
        let log = std::fs::File::create(self.dir.join(format!("log/{name}.out"))).unwrap();
        let child = self
            .command("setpriv")
            .args(["--pdeathsig", "KILL", "--"])
            .arg(which(name).ok_or(format!("{name} not found"))?)
            .args(args)
            .stdin(Stdio::null())
            .stdout(log.try_clone().unwrap())
            .stderr(log)
            .spawn()
            .map_err(|e| format!("{name}: {e}"))?;
        self.daemons.push(Daemon { name, child });
        Ok(())
    }

    /// The last lines of every daemon's log, for a failure message.
    fn log_tails(&self) -> String {
        let mut text = String::new();
        for name in ["munged.out", "slurmctld.out", "slurmctld.log", "slurmd.out", "slurmd.log"] {
            if let Ok(log) = std::fs::read_to_string(self.dir.join("log").join(name)) {
                let lines: Vec<&str> = log.lines().collect();
                let tail = lines[lines.len().saturating_sub(8)..].join("\n    ");
                text.push_str(&format!("\n  {name}:\n    {tail}"));
            }
        }
        text
    }

    /// Cancel every job, wait for the queue to empty, then stop the daemons.
    fn stop(&mut self) {
        if self.daemons.iter().any(|d| d.name == "slurmctld") {
            let _ = self.run("scancel", &["--user=root"]);
            let _ = self.wait_for("the queue to empty", Duration::from_secs(60), |c| {
                c.run("squeue", &["-h"]).is_ok_and(|o| o.stdout.is_empty())
            });
        }
        // A job's slurmstepd outlives its last squeue line by about two seconds
        let _ = self.wait_for("the job steps to exit", Duration::from_secs(30), |c| {
            c.job_steps().is_empty()
        });
        let left_behind = self.job_steps();
        for mut d in self.daemons.drain(..).rev() {
            // SAFETY: kill has no preconditions; the pid is our own unreaped child.
            unsafe { libc::kill(d.child.id() as i32, libc::SIGTERM) };
            let start = Instant::now();
            while matches!(d.child.try_wait(), Ok(None))
                && start.elapsed() < Duration::from_secs(10)
            {
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = d.child.kill();
            let _ = d.child.wait();
        }
        for pid in left_behind {
            // SAFETY: as above; a step left behind by a killed slurmd
            unsafe { libc::kill(pid, libc::SIGKILL) };
        }
        if self.owns_cgroups {
            slurm_cgroups(&self.host).iter().for_each(|d| remove_cgroup(d));
        }
    }

    /// The `slurmstepd` processes of this cluster: those started since its `munged`.
    /// (A step closes every file of the cluster's directory, and `setproctitle` overwrites
    /// its environment, about two seconds before it exits.)
    fn job_steps(&self) -> Vec<i32> {
        let Some(since) = self.daemons.first().and_then(|d| start_time(d.child.id() as i32)) else {
            return Vec::new();
        };
        let Ok(entries) = std::fs::read_dir("/proc") else { return Vec::new() };
        entries
            .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<i32>().ok())
            .filter(|&pid| {
                let comm = std::fs::read_to_string(format!("/proc/{pid}/comm")).unwrap_or_default();
                comm.trim() == "slurmstepd" && start_time(pid).is_some_and(|t| t >= since)
            })
            .collect()
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        self.stop();
        if std::thread::panicking() {
            let _ = writeln!(
                std::io::stderr(),
                "slurm: the cluster's logs are in {}",
                self.dir.display()
            );
        } else {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// `cgroup.conf`: confine memory only, as `--mem` asks; the hierarchy is found
/// automatically (cgroup v1 or v2).
const CGROUP_CONF: &str =
    "ConstrainRAMSpace=yes\nConstrainSwapSpace=no\nConstrainCores=no\nConstrainDevices=no\n";

/// `slurm.conf` for one node on loopback, everything under `dir`.
fn slurm_conf(dir: &Path, host: &str, confinement: Confinement) -> Result<String, String> {
    let meminfo =
        std::fs::read_to_string("/proc/meminfo").map_err(|e| format!("/proc/meminfo: {e}"))?;
    let total_kib: u64 = meminfo
        .lines()
        .find_map(|l| l.strip_prefix("MemTotal:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .ok_or("no MemTotal in /proc/meminfo")?;
    let (proctrack, task) = match confinement {
        Confinement::Cgroup => ("proctrack/cgroup", "task/cgroup"),
        Confinement::None => ("proctrack/linuxproc", "task/none"),
    };
    let d = dir.display();
    Ok(format!(
        "ClusterName=plumetest
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={ctld}
SlurmdPort={slurmd}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket={d}/run/munge.socket
StateSaveLocation={d}/state
SlurmdSpoolDir={d}/spool
SlurmctldPidFile={d}/run/slurmctld.pid
SlurmdPidFile={d}/run/slurmd.pid
SlurmctldLogFile={d}/log/slurmctld.log
SlurmdLogFile={d}/log/slurmd.log
ProctrackType={proctrack}
TaskPlugin={task}
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU_Memory
DefMemPerCPU=512
SchedulerType=sched/builtin
SchedulerParameters=sched_min_interval=100000
SlurmdParameters=config_overrides
JobCompType=jobcomp/filetxt
JobCompLoc={d}/log/jobcomp.txt
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
MpiDefault=none
ReturnToService=2
MinJobAge=3600
NodeName={host} NodeAddr=127.0.0.1 CPUs=8 RealMemory={mem} State=UNKNOWN
PartitionName=test Nodes={host} Default=YES MaxTime=INFINITE State=UP
",
        ctld = free_port()?,
        slurmd = free_port()?,
        mem = total_kib / 1024 - 512,
    ))
}

/// When process `pid` started, in clock ticks since boot (`/proc/<pid>/stat`, field 22).
fn start_time(pid: i32) -> Option<u64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // Fields after the parenthesised command name start at field 3
    stat.rsplit_once(')')?.1.split_whitespace().nth(22 - 3)?.parse().ok()
}

/// The cgroups Slurm makes for this host (`slurm_<host>` in each hierarchy, v1 or v2).
fn slurm_cgroups(host: &str) -> Vec<PathBuf> {
    let root = Path::new("/sys/fs/cgroup");
    let name = format!("slurm_{host}");
    let hierarchies = std::fs::read_dir(root).into_iter().flatten().flatten().map(|e| e.path());
    hierarchies.chain([root.to_owned()]).map(|h| h.join(&name)).filter(|d| d.is_dir()).collect()
}

/// Remove empty cgroups, deepest first (a cgroup with processes stays).
fn remove_cgroup(dir: &Path) {
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        if e.file_type().is_ok_and(|t| t.is_dir()) {
            remove_cgroup(&e.path());
        }
    }
    let _ = std::fs::remove_dir(dir);
}

/// A loopback port nothing listens on now.
fn free_port() -> Result<u16, String> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").map_err(|e| format!("bind: {e}"))?;
    Ok(listener.local_addr().map_err(|e| e.to_string())?.port())
}

/// `program`'s path on `PATH` (the daemons live in /usr/sbin).
fn which(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain([PathBuf::from("/usr/sbin"), PathBuf::from("/sbin")])
        .map(|dir| dir.join(program))
        .find(|p| p.is_file())
}
