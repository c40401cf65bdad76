//! The binary's logger: the library's `log` records on stderr, one line each, as plume
//! writes its messages: `plume: error: …`, `plume: warning: …`, and `plume: …` for
//! information. Records of other crates (dependencies) are not shown, nor debug and trace
//! records.
//!
//! The library names settings by their scene-file keys (`render.memory_budget`); a user
//! who gave the value as a flag reads the flag (`--memory-budget`). [`set_key_names`]
//! says which keys a command's flags set, and [`name_keys`] rewrites a message so: every
//! log record, and the errors `main.rs` and the render observer print. Until a command
//! sets it, messages are shown as the library wrote them.
//!
//! `-q/--quiet` is a library setting (`render.quiet`, and `quiet` of `plume merge`): the
//! library leaves out what it suppresses, so the logger shows every record it gets.

use std::io::Write as _;
use std::sync::RwLock;

use log::{Level, LevelFilter, Log, Metadata, Record};

use super::keys::{flag_and_rest, flag_name};
use super::request::Origin;

/// Which keys are shown as the flags that set them.
#[derive(Clone, Debug)]
pub enum KeyNames {
    /// Every key a flag sets (a command line without a scene file: every value came from
    /// a flag or its default).
    All,
    /// The keys of these flag ids only (the flags typed beside a scene file; the file's
    /// keys stay keys).
    Typed(Vec<String>),
}

impl KeyNames {
    /// The key names of a render command line: [`KeyNames::All`] without a scene file,
    /// else the typed flags'.
    #[must_use]
    pub fn of(origin: &Origin) -> KeyNames {
        if origin.scene_file.is_some() {
            KeyNames::Typed(origin.given.clone())
        } else {
            KeyNames::All
        }
    }

    fn shows_flag(&self, id: &str) -> bool {
        match self {
            KeyNames::All => true,
            KeyNames::Typed(given) => given.iter().any(|g| g == id),
        }
    }
}

/// The key names of the running command (`None`: messages as the library wrote them).
static KEY_NAMES: RwLock<Option<KeyNames>> = RwLock::new(None);

/// Show the keys `names` says as flags, from now on.
pub fn set_key_names(names: KeyNames) {
    *KEY_NAMES.write().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(names);
}

/// `text` with each scene-file key that a flag gave (see [`set_key_names`]) named as the
/// flag: `render.cache_dir` → `--cache-dir`, `lights.sky.turbidity` → `--sky turbidity`.
#[must_use]
pub fn name_keys(text: &str) -> String {
    let names = KEY_NAMES.read().unwrap_or_else(std::sync::PoisonError::into_inner);
    match names.as_ref() {
        Some(names) => rename_keys(text, names),
        None => text.to_string(),
    }
}

/// Whether `c` may be part of a key (`integrator.nee_table`).
fn in_key(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_' || c == '.'
}

/// [`name_keys`] with `names`: each word made of key characters (trailing full stops
/// left out) that is a key or lies inside one flag's table, and whose flag `names`
/// shows. (Keys are `table.field` of known tables, so file names do not match.)
fn rename_keys(text: &str, names: &KeyNames) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(start) = rest.find(in_key) {
        let (before, from) = rest.split_at(start);
        out.push_str(before);
        let len = from.find(|c: char| !in_key(c)).unwrap_or(from.len());
        let word = from[..len].trim_end_matches('.');
        match flag_and_rest(word).filter(|(id, _)| word.contains('.') && names.shows_flag(id)) {
            Some((id, "")) => out.push_str(&flag_name(id)),
            Some((id, inner)) => out.push_str(&format!("{} {inner}", flag_name(id))),
            None => out.push_str(word),
        }
        // The full stops after the word
        out.push_str(&from[word.len()..len]);
        rest = &from[len..];
    }
    out.push_str(rest);
    out
}

/// The logger (see the module docs).
struct Logger;

static LOGGER: Logger = Logger;

/// Install the logger, once, before anything logs.
pub fn install() {
    if log::set_logger(&LOGGER).is_ok() {
        log::set_max_level(LevelFilter::Info);
    }
}

impl Log for Logger {
    fn enabled(&self, metadata: &Metadata<'_>) -> bool {
        // plume's crates: plume, plume_core, plume_scene, plume_volume, plume_engine, …
        metadata.level() <= Level::Info && metadata.target().starts_with("plume")
    }

    fn log(&self, record: &Record<'_>) {
        if !self.enabled(record.metadata()) {
            return;
        }
        let text = name_keys(&record.args().to_string());
        let prefix = match record.level() {
            Level::Error => "plume: error: ",
            Level::Warn => "plume: warning: ",
            Level::Info | Level::Debug | Level::Trace => "plume: ",
        };
        // A closed stderr must not stop the render
        let _ = writeln!(std::io::stderr().lock(), "{prefix}{text}");
    }

    fn flush(&self) {}
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_become_the_flags_that_set_them() {
        let all = KeyNames::All;
        assert_eq!(
            rename_keys(
                "more than the budget (render.memory_budget); give a writable render.cache_dir.",
                &all
            ),
            "more than the budget (--memory-budget); give a writable --cache-dir."
        );
        assert_eq!(rename_keys("use integrator.nee_table brick", &all), "use --nee-table brick");
        assert_eq!(
            rename_keys("lights.sky.turbidity: 20 is outside [1.7, 10]", &all),
            "--sky turbidity: 20 is outside [1.7, 10]"
        );
        assert_eq!(
            rename_keys("emission.temperature_map/emission.convention: no", &all),
            "--temperature-map/--convention: no"
        );
        // Not keys: file names, words, paths
        for text in [
            "/tmp/x.vdb: 3 voxels",
            "out.exr (64x64, 16 spp)",
            "render.exr",
            "the render. Then",
            "...",
            "v1.2.3",
        ] {
            assert_eq!(rename_keys(text, &all), text);
        }
        let typed = KeyNames::Typed(vec!["overwrite".into()]);
        assert_eq!(
            rename_keys("skipped (farm.overwrite renders it again), render.sample_order", &typed),
            "skipped (--overwrite renders it again), render.sample_order"
        );
    }
}
