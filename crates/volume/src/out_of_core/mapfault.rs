//! Mapped files that fail while plume reads them: a fault in a mapping registered here
//! ends plume with one line on stderr naming the file and exit code 4
//! ([`exit::RENDER_OR_OUTPUT`]), never a death by SIGBUS.
//!
//! plume maps brick caches (`cache::Cache::open`, and the cache writer reads back what it
//! wrote), and OpenVDB maps a `.vdb` it streams (in the isolated reader, whose crash is
//! the parent's error, or in plume itself with `--no-isolation`: [`watch_mappings_of`]). When
//! another process truncates a mapped file, or shared storage fails to deliver a page,
//! touching a page that the file no longer backs raises SIGBUS in whichever thread touched
//! it: a render thread, the checksum verifier, the prefetcher. No Rust error can come out
//! of a load instruction, and unwinding out of a signal handler is not possible, so the
//! handler ends the process itself, after one line such as
//!
//! ```text
//! plume: error: brick cache /renders/flare.plume: byte 1834496 of the mapped file could not be read (SIGBUS: …); stopped at once, nothing more was written
//! ```
//!
//! Nothing is left half-written: outputs go to temporary files that are renamed when
//! complete (`plume_core::fs::write_atomic`), and the next run removes temporaries of dead
//! processes; a cache being written is complete or absent in the same way.
//!
//! - **Registry.** A [`Watch`] registers an address range with a message formatted when
//!   it is registered (kind and path); dropping it unregisters. Slots are a fixed static
//!   array of atomics ([`SLOTS`]): the handler allocates nothing and takes no lock. Each
//!   slot is a sequence lock: the writer makes its counter odd while it changes the slot,
//!   and the handler accepts what it read only if the counter was even and unchanged
//!   around the read. A full registry leaves a mapping unwatched (a fault in it is the
//!   default death by SIGBUS), which 64 slots make theoretical: a render maps one cache.
//! - **Handler** ([`install`]: `sigaction`, `SA_SIGINFO`). A fault the kernel raised
//!   (`si_code > 0`) at an address in a registered range: the first thread writes the
//!   line with `write(2)` (and, with `--progress`, the protocol's failure line on
//!   stdout, [`report_on_stdout`]) and calls `_exit(4)`; other threads faulting meanwhile
//!   wait for that exit, so there is one line. Any other fault goes back to the action
//!   installed before (std's, which reports a stack overflow, or the default): it is
//!   restored and the instruction faults again on return. A SIGBUS sent with `kill` gets
//!   the default action and is raised again: plume dies by the signal, as it should
//!   (std's handler alone would have ignored it once).
//! - **[`Mapping`]**: `Mmap` plus its [`Watch`]; the only way plume maps a file. The
//!   watch is dropped before the unmap, so the range is never registered while another
//!   mapping could reuse its addresses.
//!
//! The binary installs the handler at start-up; a library caller that does not call
//! [`install`] keeps the default behaviour (registrations cost nothing then).

use std::fs::File;
use std::io;
use std::ops::{Deref, Range};
use std::path::Path;
use std::sync::atomic::{fence, AtomicBool, AtomicU64, AtomicU8, AtomicUsize, Ordering};
use std::sync::{Mutex, OnceLock};

use memmap2::Mmap;

use plume_core::error::exit;

/// Mappings that can be watched at the same time.
pub const SLOTS: usize = 64;
/// Bytes of a slot's message (kind and path; a longer path is shortened).
const TEXT: usize = 1024;
/// Start of the line on stderr, as `main` starts every error.
const PREFIX: &[u8] = b"plume: error: ";
/// Between the file and the byte offset.
const MIDDLE: &[u8] = b": byte ";
/// After the byte offset.
const MAPPED: &[u8] = b" of the mapped file";
/// Instead of the byte offset and [`MAPPED`], for a [`Watch::any_address`].
const UNKNOWN: &[u8] = b": the mapped file";
/// The end of every message.
const TAIL: &[u8] =
    b" could not be read (SIGBUS: the file was truncated by another process while in use, \
or its storage returned an I/O error); stopped at once, nothing more was written";
/// The stored offset of a [`Watch::any_address`]: no byte offset is known.
const ANY_ADDRESS: u64 = u64::MAX;
/// `--progress openjd`'s last line before a non-zero exit (`farm::progress`).
const OPENJD: &[u8] = b"openjd_fail: exit code 4: ";
/// `--progress json`'s last event, around the message.
const JSON: (&[u8], &[u8]) = (b"{\"event\":\"done\",\"exit_code\":4,\"error\":\"", b"\"}");

/// One registered range and its message. See the module docs (sequence lock).
struct Slot {
    /// Taken by a [`Watch`].
    claimed: AtomicBool,
    /// Odd while the slot changes.
    seq: AtomicUsize,
    start: AtomicUsize,
    end: AtomicUsize,
    /// File offset of `start`.
    offset: AtomicU64,
    len: AtomicUsize,
    text: [AtomicU8; TEXT],
}

impl Slot {
    const fn new() -> Slot {
        Slot {
            claimed: AtomicBool::new(false),
            seq: AtomicUsize::new(0),
            start: AtomicUsize::new(0),
            end: AtomicUsize::new(0),
            offset: AtomicU64::new(0),
            len: AtomicUsize::new(0),
            text: [const { AtomicU8::new(0) }; TEXT],
        }
    }

    /// Change the slot under its sequence lock (only the [`Watch`] that claimed it does).
    fn update(&self, range: Range<usize>, offset: u64, text: &[u8]) {
        self.seq.fetch_add(1, Ordering::AcqRel);
        self.start.store(range.start, Ordering::Relaxed);
        self.end.store(range.end, Ordering::Relaxed);
        self.offset.store(offset, Ordering::Relaxed);
        self.len.store(text.len(), Ordering::Relaxed);
        for (to, &b) in self.text.iter().zip(text) {
            to.store(b, Ordering::Relaxed);
        }
        self.seq.fetch_add(1, Ordering::Release);
    }

    /// If `addr` lies in this slot's range: the file offset of `addr`, with the message
    /// copied into `text` and its length. Lock-free and allocation-free (signal handler).
    fn lookup(&self, addr: usize, text: &mut [u8; TEXT]) -> Option<(u64, usize)> {
        let before = self.seq.load(Ordering::Acquire);
        if before % 2 == 1 {
            return None;
        }
        let (start, end) = (self.start.load(Ordering::Relaxed), self.end.load(Ordering::Relaxed));
        if !(start..end).contains(&addr) {
            return None;
        }
        let offset = match self.offset.load(Ordering::Relaxed) {
            ANY_ADDRESS => ANY_ADDRESS,
            first => first + (addr - start) as u64,
        };
        let len = self.len.load(Ordering::Relaxed).min(TEXT);
        for (to, from) in text.iter_mut().zip(&self.text[..len]) {
            *to = from.load(Ordering::Relaxed);
        }
        fence(Ordering::Acquire);
        (self.seq.load(Ordering::Relaxed) == before).then_some((offset, len))
    }
}

static REGISTRY: [Slot; SLOTS] = [const { Slot::new() }; SLOTS];

/// A registered range: a fault in it ends plume with its message. Dropping it unregisters.
#[derive(Debug)]
pub struct Watch {
    slot: Option<usize>,
}

impl Watch {
    /// Watch `range` (addresses of a mapping whose first byte is byte `offset` of the
    /// file): a fault there is reported as `"{kind} {path}: byte N of the mapped file could
    /// not be read …"`. An empty range, or a full registry, watches nothing.
    #[must_use]
    pub fn new(range: Range<usize>, offset: u64, kind: &str, path: &Path) -> Watch {
        if range.is_empty() {
            return Watch { slot: None };
        }
        let slot = REGISTRY.iter().position(|s| {
            s.claimed.compare_exchange(false, true, Ordering::AcqRel, Ordering::Relaxed).is_ok()
        });
        if let Some(i) = slot {
            REGISTRY[i].update(range, offset, &message_text(kind, path));
        }
        Watch { slot }
    }

    /// Watch every address, for code that maps and reads a file in one call plume cannot
    /// enter (OpenVDB opening a grid maps the file and reads its topology before
    /// [`watch_mappings_of`] can find the mapping). A fault that no other watch claims is
    /// reported as `"{kind} {path}: the mapped file could not be read …"`. Keep it only
    /// around such a call: meanwhile any unclaimed fault is blamed on `path`.
    #[must_use]
    pub fn any_address(kind: &str, path: &Path) -> Watch {
        let slot = REGISTRY.iter().position(|s| {
            s.claimed.compare_exchange(false, true, Ordering::AcqRel, Ordering::Relaxed).is_ok()
        });
        if let Some(i) = slot {
            REGISTRY[i].update(1..usize::MAX, ANY_ADDRESS, &message_text(kind, path));
        }
        Watch { slot }
    }

    /// True when the range is registered (false for an empty range or a full registry).
    #[must_use]
    pub fn is_active(&self) -> bool {
        self.slot.is_some()
    }
}

impl Drop for Watch {
    fn drop(&mut self) {
        if let Some(i) = self.slot {
            REGISTRY[i].update(0..0, 0, &[]);
            REGISTRY[i].claimed.store(false, Ordering::Release);
        }
    }
}

/// `"{kind} {path}"` on one line, at most [`TEXT`] bytes (a longer path keeps its end,
/// the file name, behind `…`). Control characters become `?`, so that the line is one
/// line and the JSON event needs no `\u` escapes.
fn message_text(kind: &str, path: &Path) -> Vec<u8> {
    let path: String =
        path.display().to_string().chars().map(|c| if c.is_control() { '?' } else { c }).collect();
    let mut text = format!("{kind} {path}");
    if text.len() > TEXT {
        let keep = TEXT - kind.len() - " …".len() - 1;
        let mut cut = path.len() - keep;
        while !path.is_char_boundary(cut) {
            cut += 1;
        }
        text = format!("{kind} …{}", &path[cut..]);
    }
    text.into_bytes()
}

/// The registered range holding `addr`: its file offset, message in `text` and length. A
/// range of a known mapping wins over a [`Watch::any_address`].
fn find(addr: usize, text: &mut [u8; TEXT]) -> Option<(u64, usize)> {
    let known = REGISTRY
        .iter()
        .find_map(|s| s.lookup(addr, text).filter(|&(offset, _)| offset != ANY_ADDRESS));
    known.or_else(|| REGISTRY.iter().find_map(|s| s.lookup(addr, text)))
}

/// The message (no prefix, no newline) for a fault at file offset `offset` of the slot
/// text `text`, in `message`; its length. Allocation-free (signal handler).
fn format_message(text: &[u8], offset: u64, message: &mut [u8; MESSAGE]) -> usize {
    if offset == ANY_ADDRESS {
        return concat(message, &[text, UNKNOWN, TAIL]);
    }
    let mut digits = [0u8; 20];
    let mut n = digits.len();
    let mut v = offset;
    loop {
        n -= 1;
        digits[n] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    concat(message, &[text, MIDDLE, &digits[n..], MAPPED, TAIL])
}

/// `parts` one after the other into `to` (which must have room); their length.
fn concat(to: &mut [u8], parts: &[&[u8]]) -> usize {
    let mut at = 0;
    for part in parts {
        to[at..at + part.len()].copy_from_slice(part);
        at += part.len();
    }
    at
}

/// `--progress json`'s event for `message` in `to` (room for twice the message and the
/// frame): quotes and backslashes escaped (control characters never occur, see
/// [`message_text`]). Its length.
fn json_event(message: &[u8], to: &mut [u8; EVENT]) -> usize {
    let mut at = concat(to, &[JSON.0]);
    for &b in message {
        if b == b'"' || b == b'\\' {
            to[at] = b'\\';
            at += 1;
        }
        to[at] = b;
        at += 1;
    }
    at + concat(&mut to[at..], &[JSON.1, b"\n"])
}

/// Longest message: slot text, offset digits, fixed words.
const MESSAGE: usize = TEXT + MIDDLE.len() + 20 + MAPPED.len() + TAIL.len();
/// Longest line on stderr or for `--progress openjd`.
const LINE: usize = PREFIX.len() + OPENJD.len() + MESSAGE + 1;
/// Longest `--progress json` event.
const EVENT: usize = JSON.0.len() + 2 * MESSAGE + JSON.1.len() + 1;

/// What `--progress` prints on stdout (`farm::progress`), which then also reports a fault
/// in its protocol: `openjd_fail: …` or the JSON `done` event, after the line on stderr.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StdoutProtocol {
    /// Nothing on stdout.
    None,
    /// Open Job Description.
    Openjd,
    /// JSON lines.
    Json,
}

/// The [`StdoutProtocol`] as a number, for the handler.
static STDOUT: AtomicU8 = AtomicU8::new(0);

/// Report a fault on stdout too, in `protocol` (set by `farm::progress`).
pub fn report_on_stdout(protocol: StdoutProtocol) {
    STDOUT.store(protocol as u8, Ordering::Relaxed);
}

/// Set by the first thread that reports a fault; the others wait for its `_exit`.
static REPORTING: AtomicBool = AtomicBool::new(false);
/// The SIGBUS action before [`install`], for faults that are not ours.
static PREVIOUS: OnceLock<libc::sigaction> = OnceLock::new();

/// The SIGBUS handler. See the module docs.
extern "C" fn on_sigbus(
    signal: libc::c_int,
    info: *mut libc::siginfo_t,
    _context: *mut libc::c_void,
) {
    // SAFETY: the kernel passes a valid `siginfo_t` to an `SA_SIGINFO` handler.
    let info = unsafe { &*info };
    // Only a fault the kernel raised carries the faulting address (`si_code > 0`); in a
    // signal sent by a process the same bytes hold its pid and uid.
    let addr = if info.si_code > 0 {
        // SAFETY: SIGBUS with si_code > 0 fills the fault fields of the union.
        Some(unsafe { info.si_addr() } as usize)
    } else {
        None
    };
    let mut text = [0u8; TEXT];
    if let Some((offset, len)) = addr.and_then(|a| find(a, &mut text)) {
        if REPORTING.swap(true, Ordering::AcqRel) {
            // Another thread is writing the line and exiting
            loop {
                // SAFETY: pause is async-signal-safe and only waits.
                unsafe { libc::pause() };
            }
        }
        let mut message = [0u8; MESSAGE];
        let m = format_message(&text[..len], offset, &mut message);
        let message = &message[..m];
        let mut line = [0u8; LINE];
        let n = concat(&mut line, &[PREFIX, message, b"\n"]);
        write_all(libc::STDERR_FILENO, &line[..n]);
        if STDOUT.load(Ordering::Relaxed) == StdoutProtocol::Openjd as u8 {
            let n = concat(&mut line, &[OPENJD, message, b"\n"]);
            write_all(libc::STDOUT_FILENO, &line[..n]);
        } else if STDOUT.load(Ordering::Relaxed) == StdoutProtocol::Json as u8 {
            let mut event = [0u8; EVENT];
            let n = json_event(message, &mut event);
            write_all(libc::STDOUT_FILENO, &event[..n]);
        }
        // SAFETY: _exit is async-signal-safe; it ends the process without running
        // destructors or atexit handlers, which is what a handler may do.
        unsafe { libc::_exit(exit::RENDER_OR_OUTPUT) };
    }
    // Not ours. A fault elsewhere goes to the previous action (std's, which reports a
    // stack overflow, or the default): restored, it runs when the instruction faults
    // again on return. A signal sent with kill gets the default action, death by SIGBUS
    // (std's handler would return and so ignore it): raised again, it is delivered
    // when this handler returns, as it stays blocked until then.
    // SAFETY: sigaction and raise are async-signal-safe; `previous` is the action
    // sigaction returned at install, and a zeroed sigaction with SIG_DFL is valid.
    unsafe {
        match PREVIOUS.get() {
            Some(previous) if info.si_code > 0 => {
                libc::sigaction(signal, previous, std::ptr::null_mut());
            }
            _ => {
                let mut default: libc::sigaction = std::mem::zeroed();
                default.sa_sigaction = libc::SIG_DFL;
                libc::sigaction(signal, &default, std::ptr::null_mut());
                if info.si_code <= 0 {
                    libc::raise(signal);
                }
            }
        }
    }
}

/// `write(2)` all of `bytes` to `fd`, retrying short writes and EINTR; gives up on any
/// other error (nothing else could report it).
fn write_all(fd: libc::c_int, mut bytes: &[u8]) {
    while !bytes.is_empty() {
        // SAFETY: write is async-signal-safe; the pointer and length describe `bytes`.
        let n = unsafe { libc::write(fd, bytes.as_ptr().cast(), bytes.len()) };
        if n > 0 {
            bytes = &bytes[n as usize..];
        } else if n < 0 && io::Error::last_os_error().raw_os_error() == Some(libc::EINTR) {
            continue;
        } else {
            return;
        }
    }
}

/// Install the SIGBUS handler (once per process; later calls do nothing). The binary
/// calls this at start-up. See the module docs.
///
/// # Errors
/// The OS error if the handler cannot be installed.
pub fn install() -> io::Result<()> {
    static DONE: Mutex<bool> = Mutex::new(false);
    let mut done = DONE.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    if *done {
        return Ok(());
    }
    // SAFETY: all-zero bytes are a valid sigaction (a plain C struct).
    let mut previous: libc::sigaction = unsafe { std::mem::zeroed() };
    // SAFETY: with a null new action, sigaction only reads the current one into `previous`.
    if unsafe { libc::sigaction(libc::SIGBUS, std::ptr::null(), &mut previous) } != 0 {
        return Err(io::Error::last_os_error());
    }
    let _ = PREVIOUS.set(previous);
    // SAFETY: a zeroed sigaction is valid; `on_sigbus` has the SA_SIGINFO signature,
    // touches only atomics and its own stack, and calls only async-signal-safe functions
    // (write, _exit, pause, sigaction, raise).
    unsafe {
        let mut action: libc::sigaction = std::mem::zeroed();
        let handler: extern "C" fn(libc::c_int, *mut libc::siginfo_t, *mut libc::c_void) =
            on_sigbus;
        action.sa_sigaction = handler as usize;
        // Not SA_ONSTACK: the handler runs on the faulting thread's own stack (its buffers
        // would not fit std's small alternate stack); stack overflows are std's SIGSEGV
        action.sa_flags = libc::SA_SIGINFO;
        libc::sigemptyset(&mut action.sa_mask);
        if libc::sigaction(libc::SIGBUS, &action, std::ptr::null_mut()) != 0 {
            return Err(io::Error::last_os_error());
        }
    }
    *done = true;
    Ok(())
}

/// A read-only mapping of a whole file, watched: a fault in it ends plume with a line
/// naming `kind` and `path` (see the module docs). Dereferences to the [`Mmap`].
#[derive(Debug)]
pub struct Mapping {
    // Declared first so that it is dropped first: unregistered before the unmap
    watch: Watch,
    map: Mmap,
}

impl Mapping {
    /// Map `file` (opened from `path`; `kind` says what it is, e.g. `"brick cache"`).
    ///
    /// # Errors
    /// The OS error of `mmap`.
    pub fn map(file: &File, path: &Path, kind: &str) -> io::Result<Mapping> {
        // SAFETY: the mapping is read-only and plume never writes a file it maps (caches
        // are written to a temporary file and renamed; the writer maps its temporary only
        // after writing what it maps). Another process may still truncate or rewrite the
        // file: a truncation or an I/O error raises SIGBUS, which the watch below turns
        // into a clean exit, and a rewrite changes bytes that every reader of a cache
        // treats as untrusted (indices are bounds-checked, and nothing is written before
        // the checksums and the file's header are checked again).
        let map = unsafe { Mmap::map(file) }?;
        let start = map.as_ptr() as usize;
        let watch = Watch::new(start..start + map.len(), 0, kind, path);
        Ok(Mapping { watch, map })
    }

    /// True when faults in it are reported (see [`Watch::is_active`]).
    #[must_use]
    pub fn is_watched(&self) -> bool {
        self.watch.is_active()
    }
}

impl Deref for Mapping {
    type Target = Mmap;

    fn deref(&self) -> &Mmap {
        &self.map
    }
}

/// Watch every mapping of `path`'s file that this process holds now (found in
/// `/proc/self/maps` by device and inode), for mappings made by code plume does not
/// control: OpenVDB maps a `.vdb` it streams with delayed loading. Best effort: an
/// unreadable `/proc` or file watches nothing.
#[must_use]
pub fn watch_mappings_of(path: &Path, kind: &str) -> Vec<Watch> {
    use std::os::unix::fs::MetadataExt;
    let (Ok(meta), Ok(maps)) =
        (std::fs::metadata(path), std::fs::read_to_string("/proc/self/maps"))
    else {
        return Vec::new();
    };
    let dev = meta.dev();
    // glibc's and the kernel's encoding of a device number
    let (major, minor) =
        (((dev >> 8) & 0xfff) | ((dev >> 32) & !0xfff), (dev & 0xff) | ((dev >> 12) & !0xff));
    maps.lines()
        .filter_map(|line| {
            let mut fields = line.split_whitespace();
            let (range, _perms, offset, device, inode) =
                (fields.next()?, fields.next()?, fields.next()?, fields.next()?, fields.next()?);
            let (lo, hi) = range.split_once('-')?;
            let (maj, min) = device.split_once(':')?;
            let ours = inode.parse::<u64>().ok()? == meta.ino()
                && u64::from_str_radix(maj, 16).ok()? == major
                && u64::from_str_radix(min, 16).ok()? == minor;
            let range = usize::from_str_radix(lo, 16).ok()?..usize::from_str_radix(hi, 16).ok()?;
            ours.then(|| {
                Watch::new(range, u64::from_str_radix(offset, 16).unwrap_or(0), kind, path)
            })
        })
        .collect()
}

#[cfg(test)]
mod tests;
