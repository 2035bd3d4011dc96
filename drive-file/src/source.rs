//! A parsed TOML file that remembers where every key is, so that an error can say
//! `file:line:column: key: reason` — for syntax and type errors (from `toml`) and for the
//! range checks done after deserialising alike.

use serde::de::DeserializeOwned;
use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::de::{DeTable, DeValue};

/// An input error: the file, the position of the offending value, its dotted key and why.
#[derive(Debug, Clone, PartialEq)]
pub struct FileError {
    /// The file (or `<builtin NAME>` for data compiled into the program).
    pub file: PathBuf,
    /// 1-based line and column of the offending value (or key), when known.
    pub at: Option<(usize, usize)>,
    /// Dotted key path (`controller.speed.kp`, `events[2].value`), when known.
    pub key: Option<String>,
    /// What is wrong.
    pub reason: String,
}

impl FileError {
    /// An error about the file as a whole (cannot read it, …).
    pub fn file(file: &Path, reason: impl Into<String>) -> Self {
        Self { file: file.to_path_buf(), at: None, key: None, reason: reason.into() }
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some((line, col)) = self.at {
            write!(f, ":{line}:{col}")?;
        }
        if let Some(k) = &self.key {
            write!(f, ": {k}")?;
        }
        write!(f, ": {}", self.reason)
    }
}

impl std::error::Error for FileError {}

/// A TOML document with the spans of its keys and values.
#[derive(Debug)]
pub struct Source<'a> {
    path: &'a Path,
    text: &'a str,
    doc: DeTable<'a>,
}

/// One step of a key path.
enum Step<'k> {
    Key(&'k str),
    Index(usize),
}

/// `a.b[3].c` → `a`, `b`, `[3]`, `c`.
fn steps(path: &str) -> Vec<Step<'_>> {
    let mut out = Vec::new();
    for part in path.split('.') {
        let (name, mut rest) = part.split_once('[').map_or((part, ""), |(n, r)| (n, r));
        if !name.is_empty() {
            out.push(Step::Key(name));
        }
        while let Some((idx, tail)) = rest.split_once(']') {
            if let Ok(i) = idx.parse() {
                out.push(Step::Index(i));
            }
            rest = tail.strip_prefix('[').unwrap_or(tail);
        }
    }
    out
}

impl<'a> Source<'a> {
    /// Parse `text` (read from `path`); a syntax error is reported with its position.
    pub fn parse(path: &'a Path, text: &'a str) -> Result<Self, FileError> {
        match DeTable::parse(text) {
            Ok(doc) => Ok(Self { path, text, doc: doc.into_inner() }),
            Err(e) => {
                let mut reason = first_line(e.message());
                // toml's "duplicate key" points at the key but does not name it.
                if reason.starts_with("duplicate key")
                    && let Some(k) = e.span().and_then(|s| text.get(s)).map(str::trim)
                    && !k.is_empty()
                    && !reason.contains(k)
                {
                    reason = format!(
                        "duplicate key `{k}`: written twice (TOML takes each key, and each [table], once)"
                    );
                }
                Err(FileError {
                    file: path.to_path_buf(),
                    at: e.span().map(|s| line_col(text, s.start)),
                    key: None,
                    reason,
                })
            }
        }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        self.path
    }

    /// Does the document have a top-level key `key`?
    pub fn has(&self, key: &str) -> bool {
        self.doc.iter().any(|(k, _)| k.get_ref().as_ref() == key)
    }

    /// The string value of a top-level key, if it is a string.
    pub fn string(&self, key: &str) -> Option<String> {
        self.doc.iter().find(|(k, _)| k.get_ref().as_ref() == key).and_then(|(_, v)| match v.get_ref() {
            DeValue::String(s) => Some(s.to_string()),
            _ => None,
        })
    }

    /// Deserialize the whole document; unknown keys, missing keys and type errors become a
    /// [`FileError`] at the offending position with its key path.
    pub fn deserialize<T: DeserializeOwned>(&self) -> Result<T, FileError> {
        toml::from_str(self.text).map_err(|e| {
            let span = e.span();
            // A missing key's span is its table's, which starts where the table's first key
            // does: naming that key would point at the wrong one.
            let missing = e.message().starts_with("missing field");
            FileError {
                file: self.path.to_path_buf(),
                at: span.clone().map(|s| line_col(self.text, s.start)),
                key: if missing { None } else { span.and_then(|s| self.key_at(&s)) },
                reason: first_line(e.message()),
            }
        })
    }

    /// An error about the value at the dotted `key` (its position looked up in the file; the
    /// table's position if the key is absent — a default that failed a check).
    pub fn error(&self, key: &str, reason: impl Into<String>) -> FileError {
        FileError {
            file: self.path.to_path_buf(),
            at: self.span_of(key).map(|s| line_col(self.text, s.start)),
            key: Some(key.to_string()),
            reason: reason.into(),
        }
    }

    /// Does the file set the dotted `key` (not a default)?
    pub fn contains(&self, key: &str) -> bool {
        let mut table = &self.doc;
        let mut keys = key.split('.').peekable();
        while let Some(k) = keys.next() {
            let Some((_, v)) = table.iter().find(|(n, _)| n.get_ref().as_ref() == k) else { return false };
            match v.get_ref() {
                DeValue::Table(t) => table = t,
                _ => return keys.peek().is_none(),
            }
        }
        true
    }

    /// `Ok(())` if `ok`, else [`Source::error`].
    pub fn check(&self, ok: bool, key: &str, reason: &str) -> Result<(), FileError> {
        if ok { Ok(()) } else { Err(self.error(key, reason)) }
    }

    /// Span of the value at `key`, or of the deepest existing table on its path.
    fn span_of(&self, key: &str) -> Option<Range<usize>> {
        let mut table = &self.doc;
        let mut found = None;
        let mut array: Option<&toml::de::DeArray<'a>> = None;
        for step in steps(key) {
            let value = match (step, array) {
                (Step::Key(k), None) => table.iter().find(|(n, _)| n.get_ref().as_ref() == k).map(|(_, v)| v),
                (Step::Index(i), Some(a)) => a.get(i),
                _ => None,
            };
            let Some(v) = value else { break };
            found = Some(v.span());
            array = None;
            match v.get_ref() {
                DeValue::Table(t) => table = t,
                DeValue::Array(a) => array = Some(a),
                _ => {}
            }
        }
        found
    }

    /// The dotted key path whose value (or key) holds byte `span`: the deepest entry whose
    /// key or scalar value contains it (a `[table]` header's span does not cover its body,
    /// so every table is searched).
    fn key_at(&self, span: &Range<usize>) -> Option<String> {
        fn inside(r: &Range<usize>, at: usize) -> bool {
            r.start <= at && at < r.end.max(r.start + 1)
        }
        fn search(v: &DeValue<'_>, at: usize) -> Option<String> {
            match v {
                DeValue::Table(t) => t.iter().find_map(|(k, v)| {
                    let name = k.get_ref().to_string();
                    match search(v.get_ref(), at) {
                        Some(rest) if rest.starts_with('[') => Some(format!("{name}{rest}")),
                        Some(rest) => Some(format!("{name}.{rest}")),
                        None if inside(&k.span(), at) || inside(&v.span(), at) => Some(name),
                        None => None,
                    }
                }),
                DeValue::Array(a) => a.iter().enumerate().find_map(|(i, e)| match search(e.get_ref(), at) {
                    Some(rest) => Some(format!("[{i}].{rest}")),
                    None if inside(&e.span(), at) => Some(format!("[{i}]")),
                    None => None,
                }),
                _ => None,
            }
        }
        search(&DeValue::Table(self.doc.clone()), span.start)
    }
}

/// A file's fingerprint: FNV-1a (64 bits) of its text, in hex — what ties a result (a
/// campaign's summary) to the exact file it was computed on.
pub fn fingerprint(text: &str) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// A number for a message: plain in the usual range, in exponent form beyond it (so that
/// `1e300` does not print as 301 digits).
pub fn num(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-3..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

fn first_line(msg: &str) -> String {
    msg.lines().next().unwrap_or(msg).trim().to_string()
}

/// 1-based line and column (in characters) of byte `offset`.
fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let before = text.get(..offset.min(text.len())).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// Read `path` as text; the error names the file.
pub fn read(path: &Path) -> Result<String, FileError> {
    std::fs::read_to_string(path).map_err(|e| FileError::file(path, format!("cannot read: {e}")))
}

#[cfg(test)]
mod tests {
    #[test]
    fn fingerprint_is_fnv1a_64() {
        // FNV-1a 64 test vectors (the empty string and "a").
        assert_eq!(super::fingerprint(""), "cbf29ce484222325");
        assert_eq!(super::fingerprint("a"), "af63dc4c8601ec8c");
    }

    use super::*;
    use serde::Deserialize;

    /// `contains`: a key the file sets, not one it leaves to its default.
    #[test]
    fn contains_names_only_what_the_file_sets() {
        let src = Source::parse(Path::new("d.toml"), "[board]\ndead_time_s = 1e-6\n[pwm]\n").unwrap();
        assert!(src.contains("board.dead_time_s") && src.contains("board") && src.contains("pwm"));
        assert!(!src.contains("board.sample_window_s") && !src.contains("board.dead_time_s.x"));
        assert!(!src.contains("controller.current_trim_bandwidth_rad_s"));
    }

    /// A key set twice is named, at its second line (toml's own message, "duplicate key",
    /// named none: issue 49).
    #[test]
    fn a_duplicate_key_names_itself() {
        let text = "[motor]\nrs_ohm = 16.2\nrr_ohm = 1.0\nrs_ohm = 17.0\n";
        let e = Source::parse(Path::new("d.toml"), text).unwrap_err();
        assert!(e.reason.contains("`rs_ohm`"), "{e}");
        assert_eq!(e.at.map(|(line, _)| line), Some(4), "{e}");
    }

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct T {
        a: f64,
        inner: Inner,
        list: Vec<Item>,
    }
    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Inner {
        x: f64,
    }
    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    #[allow(dead_code)]
    struct Item {
        v: f64,
    }

    const TEXT: &str = "a = 1.0\n[inner]\nx = 2.0\n[[list]]\nv = 1.0\n[[list]]\nv = 3.0\n";

    #[test]
    fn positions_of_keys_and_errors() {
        let p = Path::new("f.toml");
        let s = Source::parse(p, TEXT).unwrap();
        assert!(s.deserialize::<T>().is_ok());
        assert_eq!(s.error("inner.x", "bad").to_string(), "f.toml:3:5: inner.x: bad");
        assert_eq!(s.error("list[1].v", "bad").to_string(), "f.toml:7:5: list[1].v: bad");
        // A missing key points at its table.
        assert_eq!(s.error("inner.y", "bad").at, Some((2, 1)));
        // Type error: position and key from toml's span.
        let bad = TEXT.replace("x = 2.0", "x = \"two\"");
        let e = Source::parse(p, &bad).unwrap().deserialize::<T>().unwrap_err();
        assert_eq!((e.at, e.key.as_deref()), (Some((3, 5)), Some("inner.x")), "{e}");
        // Unknown key.
        let bad = TEXT.replace("v = 3.0", "v = 3.0\nw = 1");
        let e = Source::parse(p, &bad).unwrap().deserialize::<T>().unwrap_err();
        assert_eq!(e.at, Some((8, 1)), "{e}");
        assert!(e.to_string().contains("list[1].w") && e.reason.contains("unknown field"), "{e}");
        // A missing key names no other key (its span is the table's, where `a` starts).
        let e = Source::parse(p, "a = 1.0\n").unwrap().deserialize::<T>().unwrap_err();
        assert_eq!(e.key, None, "{e}");
        assert!(e.reason.contains("missing field `inner`"), "{e}");
        // Syntax error.
        let e = Source::parse(p, "a = = 1").unwrap_err();
        assert_eq!(e.at, Some((1, 5)), "{e}");
    }
}
