//! Scene files: a [`Shot`] as TOML (`plume render shot.toml`, `--write-scene`).
//!
//! One table per part of the shot (see [`Shot`]); keys are the field names of the
//! description (`[camera] width = 640`), values the command line's (`method =
//! "line-fnee"`, `crop = "0,0,64,64"`, `memory_budget = "4GiB"`). Unknown keys are
//! errors. Relative paths in a file are relative to the file's directory, so a shot
//! directory can be moved as a whole; [`fn@write`] writes absolute paths.
//!
//! Every error names the file, the line and the key: syntax errors, unknown keys and
//! wrong types from the parser's span, values out of range from [`Shot::validate`]'s
//! key, looked up in the document ([`SceneFile::line_of`]).

use std::ops::Range;
use std::path::{Path, PathBuf};

use toml_edit::{ImDocument, Item, TableLike};

use super::Shot;
use plume_core::error::{Error, Result};

/// A scene file as read: its text, for finding the line of a key.
pub struct SceneFile {
    /// The file.
    pub path: PathBuf,
    text: String,
    doc: Option<ImDocument<String>>,
}

impl SceneFile {
    /// Read and parse `path`.
    ///
    /// # Errors
    /// [`Error::Open`] when it cannot be read; [`Error::SceneFile`] naming the line and
    /// key of a syntax error, unknown key or wrong type.
    pub fn read(path: &Path) -> Result<(Shot, SceneFile)> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| Error::Open { path: path.to_path_buf(), source })?;
        SceneFile::parse(path, text, &plume_core::fs::parent_dir(path))
    }

    /// Parse `text`, a scene file that errors call `path`, its relative paths made
    /// relative to `base` (a file's directory; an embedding application's working
    /// directory for a scene built in code).
    ///
    /// # Errors
    /// [`Error::SceneFile`] naming the line and key of a syntax error, unknown key or
    /// wrong type.
    pub fn parse(path: &Path, text: String, base: &Path) -> Result<(Shot, SceneFile)> {
        let doc = ImDocument::parse(text.clone()).ok();
        let file = SceneFile { path: path.to_path_buf(), text, doc };
        // `[volume]` beside `[[volumes]]`, an empty list: named at their line
        if let Some(doc) = &file.doc {
            let volumes = doc.get("volumes").map(|v| match v {
                Item::ArrayOfTables(a) => a.len(),
                other => other.as_array().map_or(1, toml_edit::Array::len),
            });
            if let Some((key, message)) =
                crate::volume_tables_error(doc.contains_key("volume"), volumes)
            {
                return Err(file.error_at_key(key, message));
            }
        }
        let mut shot: Shot = toml::from_str(&file.text).map_err(|e| {
            let span = e.span();
            let key = span
                .as_ref()
                .and_then(|s| file.key_at(s.start).or_else(|| file.key_in_text(s.start)));
            // One line: the parser's message may continue with what it expected
            let message = e.message().trim().lines().map(str::trim).collect::<Vec<_>>().join("; ");
            file.error(span.map(|s| s.start), key, &message)
        })?;
        resolve_paths(&mut shot, |p| {
            if p.is_relative() && !base.as_os_str().is_empty() && base != Path::new(".") {
                base.join(p)
            } else {
                p.to_path_buf()
            }
        });
        Ok((shot, file))
    }

    /// The error for `key` (at its line when the file has it).
    #[must_use]
    pub fn error_at_key(&self, key: &str, message: &str) -> Error {
        self.error(self.line_offset(key), Some(key.to_string()), message)
    }

    fn error(&self, offset: Option<usize>, key: Option<String>, message: &str) -> Error {
        let line = offset.map(|o| self.line_at(o));
        Error::SceneFile { path: self.path.clone(), line, key, message: message.to_string() }
    }

    /// Whether the file sets `key` (`camera.width`).
    #[must_use]
    pub fn has_key(&self, key: &str) -> bool {
        self.line_offset(key).is_some()
    }

    /// The 1-based line of `key` in the file, if it is there.
    #[must_use]
    pub fn line_of(&self, key: &str) -> Option<usize> {
        self.line_offset(key).map(|o| self.line_at(o))
    }

    /// The 1-based line of byte `offset`.
    fn line_at(&self, offset: usize) -> usize {
        self.text.as_bytes()[..offset.min(self.text.len())].iter().filter(|&&b| b == b'\n').count()
            + 1
    }

    /// Byte offset of `key`'s definition. A part of the key may index a list of tables
    /// (`volumes[1].medium.g`; inline tables count as tables): a key inside an entry that
    /// the entry leaves out (it inherits the value) is at the entry's start.
    fn line_offset(&self, key: &str) -> Option<usize> {
        let doc = self.doc.as_ref()?;
        let mut table: &dyn TableLike = doc.as_table();
        let mut entry = None;
        let parts: Vec<&str> = key.split('/').next().unwrap_or(key).split('.').collect();
        for (i, part) in parts.iter().enumerate() {
            let (name, index) = match part.strip_suffix(']').and_then(|p| p.split_once('[')) {
                Some((name, index)) => (name, Some(index.parse::<usize>().ok()?)),
                None => (*part, None),
            };
            let Some((k, mut item)) = table.get_key_value(name) else { return entry };
            let mut span = k.span();
            if let Some(index) = index {
                item = item.get(index)?;
                span = item.span().or(span);
                entry = span.as_ref().map(|s| s.start);
            }
            if i + 1 == parts.len() {
                return span.or_else(|| item.span()).map(|s| s.start);
            }
            let Some(inner) = item.as_table_like() else { return entry };
            table = inner;
        }
        None
    }

    /// The key on the line of byte `offset`, read from the text (for a file that does not
    /// parse): the last `[table]` header above it, and the name before `=` on that line.
    fn key_in_text(&self, offset: usize) -> Option<String> {
        let line = self.line_at(offset);
        let mut table = String::new();
        // Entries of each list of tables (`[[volumes]]`) so far
        let mut lists: Vec<(String, usize)> = Vec::new();
        for (i, text) in self.text.lines().enumerate() {
            let t = text.trim();
            if i + 1 == line {
                let name = t.split_once('=').map(|(k, _)| k.trim().trim_matches('"').to_string());
                return match (table.is_empty(), name) {
                    (_, Some(n)) if n.is_empty() => None,
                    (true, n) => n,
                    (false, Some(n)) => Some(format!("{table}.{n}")),
                    (false, None) => Some(table),
                };
            }
            if t.starts_with('[') {
                table = header_key(t, &mut lists);
            }
        }
        None
    }

    /// The dotted key whose definition (key or value) holds byte `offset`; an entry of a
    /// list of tables is named by its index (`volumes[1].medium.g`).
    fn key_at(&self, offset: usize) -> Option<String> {
        fn walk(table: &dyn TableLike, offset: usize, prefix: &str) -> Option<String> {
            let inside =
                |s: Option<Range<usize>>| s.is_some_and(|s| s.contains(&offset) || s.end == offset);
            for (name, item) in table.iter() {
                let path =
                    if prefix.is_empty() { name.to_string() } else { format!("{prefix}.{name}") };
                if let Some(sub) = item.as_table_like() {
                    if let Some(found) = walk(sub, offset, &path) {
                        return Some(found);
                    }
                }
                let entries = match item {
                    Item::ArrayOfTables(a) => a.iter().map(|t| t as &dyn TableLike).collect(),
                    _ => item.as_array().map_or(Vec::new(), |a| {
                        a.iter()
                            .filter_map(|v| v.as_inline_table().map(|t| t as &dyn TableLike))
                            .collect()
                    }),
                };
                for (i, entry) in entries.into_iter().enumerate() {
                    if let Some(found) = walk(entry, offset, &format!("{path}[{i}]")) {
                        return Some(found);
                    }
                }
                let key_span = table.key(name).and_then(toml_edit::Key::span);
                let whole_table = matches!(item, Item::Table(_) | Item::ArrayOfTables(_));
                if inside(key_span) || (!whole_table && inside(item.span())) {
                    return Some(path);
                }
            }
            None
        }
        walk(self.doc.as_ref()?.as_table(), offset, "")
    }
}

/// The key of a table header line (`[camera]`, `[[volumes]]`, `[volumes.medium]`,
/// `[[volumes.instances]]`), each list it is in or is named by its current entry
/// (`volumes[1].instances[0]`); `lists` counts the entries of each list so far, those of a
/// list inside another counted afresh in each of the other's entries.
fn header_key(line: &str, lists: &mut Vec<(String, usize)>) -> String {
    let name: Vec<&str> =
        line.trim_matches(|c| c == '[' || c == ']').trim().split('.').map(str::trim).collect();
    let name = name.join(".");
    if line.starts_with("[[") {
        let inner = format!("{name}.");
        lists.retain(|(n, _)| !n.starts_with(&inner));
        match lists.iter_mut().find(|(n, _)| *n == name) {
            Some((_, count)) => *count += 1,
            None => lists.push((name.clone(), 1)),
        }
    }
    let mut key = String::new();
    let mut end = 0;
    for part in name.split('.') {
        if end > 0 {
            key.push('.');
            end += 1;
        }
        end += part.len();
        key.push_str(part);
        if let Some((_, count)) = lists.iter().find(|(n, _)| *n == name[..end]) {
            key += &format!("[{}]", count - 1);
        }
    }
    key
}

/// Apply `f` to every path of `shot` (inputs, outputs, cache directory) that is given:
/// an empty path means "not given" and stays empty, so validation can say it is required.
pub fn resolve_paths(shot: &mut Shot, f: impl Fn(&Path) -> PathBuf) {
    let f = |p: &Path| if p.as_os_str().is_empty() { PathBuf::new() } else { f(p) };
    let s = &mut shot.settings;
    shot.scene.volume.file = f(&shot.scene.volume.file);
    for entry in &mut shot.scene.more_volumes {
        entry.volume.file = f(&entry.volume.file);
    }
    s.output.image = f(&s.output.image);
    for p in
        [&mut s.output.preview, &mut s.output.stats, &mut s.render.cache_dir].into_iter().flatten()
    {
        *p = f(p);
    }
    if let Some(m) = &mut shot.scene.lights.environment_map {
        m.file = f(&m.file);
    }
}

/// `shot` as TOML, every path absolute (made so against `working_dir`, the directory
/// relative paths are relative to, which the application gives), so the file renders the
/// same from anywhere.
///
/// # Errors
/// A value TOML cannot hold (a seed above 2^63 − 1).
pub fn to_toml(shot: &Shot, working_dir: &Path) -> Result<String> {
    let mut shot = shot.clone();
    resolve_paths(
        &mut shot,
        |p| if p.is_relative() { working_dir.join(p) } else { p.to_path_buf() },
    );
    to_toml_as_is(&shot)
}

/// `shot` as TOML with its paths as they are.
///
/// # Errors
/// A value TOML cannot hold (a seed above 2^63 − 1).
pub fn to_toml_as_is(shot: &Shot) -> Result<String> {
    let body = toml::to_string_pretty(shot)
        .map_err(|e| Error::Scene(format!("cannot write the scene as TOML: {e}")))?;
    Ok(format!(
        "# plume {} scene file (plume render FILE.toml; docs/scene-file.md)\n{body}",
        env!("CARGO_PKG_VERSION")
    ))
}

/// `shot` with the keys of a scene-file fragment set (`"[medium]\nalbedo = 0.8"`), for
/// shots built in code (benchmarks).
///
/// # Errors
/// [`Error::Scene`] when the fragment does not parse or sets a key the shot has not.
pub fn with_keys(shot: &Shot, fragment: &str) -> Result<Shot> {
    fn merge(into: &mut toml::Table, from: toml::Table) {
        for (k, v) in from {
            match (into.get_mut(&k), v) {
                (Some(toml::Value::Table(a)), toml::Value::Table(b)) => merge(a, b),
                (_, v) => {
                    into.insert(k, v);
                }
            }
        }
    }
    let bad = |e: &dyn std::fmt::Display| Error::Scene(format!("scene keys {fragment:?}: {e}"));
    let mut table = toml::Table::try_from(shot).map_err(|e| bad(&e))?;
    merge(&mut table, fragment.parse::<toml::Table>().map_err(|e| bad(&e))?);
    table.try_into().map_err(|e| bad(&e))
}

/// Write `shot` to `path` as TOML ([`to_toml`], paths made absolute against
/// `working_dir`), atomically.
///
/// # Errors
/// As [`to_toml`]; [`Error::Write`].
pub fn write(path: &Path, shot: &Shot, working_dir: &Path) -> Result<()> {
    let text = to_toml(shot, working_dir)?;
    plume_core::fs::write_atomic(path, |w| std::io::Write::write_all(w, text.as_bytes()))
}

/// Whether `path` names a scene file (`.toml`).
#[must_use]
pub fn is_scene_file(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}
