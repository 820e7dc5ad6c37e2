//! Scene errors as users read them: the file, the dotted key path, the line
//! and column, what was expected and what was found.
//!
//! Three sources feed them:
//! - serde, reading the TOML into the types of `file.rs`: unknown and
//!   missing keys, wrong types and array lengths, unknown enum values. Its
//!   message says which of these it is; the rest comes from elsewhere: the
//!   key path from `serde_path_to_error`, the allowed keys and values and
//!   what a key means from the JSON Schema (the doc comments of
//!   `file.rs`), and what was found from the parsed TOML document;
//! - [`check_numbers`]: every number against the bounds in the schema,
//!   finite, and representable where it is single precision;
//! - `parse.rs`, for what involves more than one value.

use super::SceneError;
use serde_json::Value as Json;
use std::fmt;
use std::ops::Range;
use std::sync::OnceLock;
use toml::de::{DeTable, DeValue};
use toml::Spanned;

/// One step of a key path.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Seg {
    Key(String),
    Index(usize),
}

/// A dotted key path such as `fluid[1].box.min[2]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct KeyPath(pub Vec<Seg>);

impl KeyPath {
    pub fn key(&self, k: &str) -> KeyPath {
        let mut p = self.clone();
        p.0.push(Seg::Key(k.to_string()));
        p
    }

    pub fn index(&self, i: usize) -> KeyPath {
        let mut p = self.clone();
        p.0.push(Seg::Index(i));
        p
    }

    fn parent(&self) -> KeyPath {
        KeyPath(self.0[..self.0.len().saturating_sub(1)].to_vec())
    }

    fn last_key(&self) -> Option<&str> {
        match self.0.last() {
            Some(Seg::Key(k)) => Some(k),
            _ => None,
        }
    }
}

impl fmt::Display for KeyPath {
    /// Keys joined by dots, indices in brackets; a key that is not a bare
    /// TOML key is quoted.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, seg) in self.0.iter().enumerate() {
            match seg {
                Seg::Index(n) => write!(f, "[{n}]")?,
                Seg::Key(k) => {
                    if i > 0 {
                        f.write_str(".")?;
                    }
                    let bare = !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
                    if bare {
                        f.write_str(k)?;
                    } else {
                        write!(f, "{k:?}")?;
                    }
                }
            }
        }
        Ok(())
    }
}

/// The parsed scene text, for positions and for what was found.
pub(super) struct Doc<'t> {
    pub file: &'t str,
    pub text: &'t str,
    pub root: &'t Spanned<DeTable<'t>>,
}

impl Doc<'_> {
    /// An error at `path`, positioned at its value (or, if it has none, the
    /// nearest enclosing one).
    pub fn err(&self, path: &KeyPath, reason: impl Into<String>) -> SceneError {
        let span = (0..=path.0.len()).rev().find_map(|n| self.span(&path.0[..n]));
        self.err_at(path, span, reason)
    }

    fn err_at(&self, path: &KeyPath, span: Option<Range<usize>>, reason: impl Into<String>) -> SceneError {
        SceneError {
            file: self.file.to_string(),
            key: path.to_string(),
            position: span.map(|s| {
                let (line, column, _) = line_column(self.text, s.start);
                (line, column)
            }),
            reason: reason.into(),
        }
    }

    /// The value at `path`.
    pub fn value(&self, path: &[Seg]) -> Option<&DeValue<'_>> {
        self.spanned(path).map(|v| v.get_ref())
    }

    fn span(&self, path: &[Seg]) -> Option<Range<usize>> {
        if path.is_empty() {
            return None;
        }
        self.spanned(path).map(|v| v.span())
    }

    fn spanned(&self, path: &[Seg]) -> Option<&Spanned<DeValue<'_>>> {
        let (first, rest) = path.split_first()?;
        let Seg::Key(k) = first else { return None };
        let mut v = self.root.get_ref().get(k.as_str())?;
        for seg in rest {
            v = match (seg, v.get_ref()) {
                (Seg::Key(k), DeValue::Table(t)) => t.get(k.as_str())?,
                (Seg::Index(i), DeValue::Array(a)) => a.get(*i)?,
                _ => return None,
            };
        }
        Some(v)
    }

    /// The span of the key (not the value) at the end of `path`.
    fn key_span(&self, path: &KeyPath) -> Option<Range<usize>> {
        let name = path.last_key()?;
        let parent = path.parent();
        let table = if parent.0.is_empty() {
            self.root.get_ref()
        } else {
            match self.value(&parent.0)? {
                DeValue::Table(t) => t,
                _ => return None,
            }
        };
        table.keys().find(|k| k.get_ref() == name).map(|k| k.span())
    }

    /// What was found at `path`, for "found ...".
    fn found(&self, path: &KeyPath) -> Option<String> {
        self.value(&path.0).map(describe)
    }

    /// A serde error from reading the document into the scene types.
    pub fn serde_error(&self, e: serde_path_to_error::Error<toml::de::Error>) -> SceneError {
        use serde_path_to_error::Segment;
        let path = KeyPath(
            e.path()
                .iter()
                .map(|seg| match seg {
                    Segment::Seq { index } => Seg::Index(*index),
                    Segment::Map { key } | Segment::Enum { variant: key } => Seg::Key(key.clone()),
                    Segment::Unknown => Seg::Key("?".to_string()),
                })
                .collect(),
        );
        let inner = e.into_inner();
        let message = inner.message().trim();
        let quoted = message.split('`').nth(1).unwrap_or("");
        let schema = Schema::get();
        if message.starts_with("unknown field") {
            // The path ends at the unknown key.
            let (key, parent) = match path.last_key() {
                Some(k) if k == quoted => (path.clone(), path.parent()),
                _ => (path.key(quoted), path.clone()),
            };
            let allowed = schema.keys(&parent.0);
            let mut reason = format!("unknown key `{quoted}`");
            if let Some(near) = closest(quoted, &allowed) {
                reason.push_str(&format!(" (did you mean `{near}`?)"));
            }
            reason.push_str(&format!("; allowed here: {}", allowed.join(", ")));
            let span = self.key_span(&key).or_else(|| inner.span());
            return self.err_at(&key, span, reason);
        }
        if message.starts_with("missing field") {
            let key = path.key(quoted);
            let reason = format!("missing required key `{quoted}` (expected {})", schema.what(&key.0));
            return self.err(&key, reason);
        }
        if message.starts_with("unknown variant") {
            let values = schema.values(&path.0);
            let mut reason = format!("expected {}, found the string {quoted:?}", expected(&schema, &path));
            if let Some(near) = closest(quoted, &values) {
                reason.push_str(&format!(" (did you mean \"{near}\"?)"));
            }
            return self.err(&path, reason);
        }
        // Anything else is a value of the wrong type or length ("invalid
        // type: ...", "invalid length ...", "invalid value: ...", or the
        // TOML reader's "wanted string or table" for an enum).
        match (self.found(&path), schema.kind(&path.0)) {
            (Some(found), kind) if !matches!(kind, Kind::Other) => {
                self.err(&path, self.type_reason(&schema, &path, &found))
            }
            _ => self.err_at(&path, inner.span(), message),
        }
    }

    /// "expected ..., found ..." for a value of the wrong type at `path`.
    fn type_reason(&self, schema: &Schema, path: &KeyPath, found: &str) -> String {
        let name = path.last_key().unwrap_or("");
        match schema.kind(&path.0) {
            Kind::Bool => format!("expected true or false, found {found}"),
            Kind::TopTables if found == "a table" => {
                format!("expected an array of tables (write [[{name}]]), found a single table ([{name}])")
            }
            Kind::TopTables => format!("expected an array of tables ([[{name}]]), found {found}"),
            _ => format!("expected {}, found {found}", expected(schema, path)),
        }
    }
}

/// What the value at `path` should be: its meaning and its kind.
fn expected(schema: &Schema, path: &KeyPath) -> String {
    let what = schema.what(&path.0);
    match schema.kind(&path.0) {
        Kind::Bool => "true or false".to_string(),
        Kind::Number => format!("{what} (a number)"),
        Kind::Integer(min) => format!("{what} (an integer >= {min})"),
        Kind::String { non_empty: true } => format!("{what} (a non-empty string)"),
        Kind::String { non_empty: false } => format!("{what} (a string)"),
        Kind::Enum(values) => {
            let names: Vec<String> = values.iter().map(|v| format!("\"{v}\"")).collect();
            format!("{what} as one of {} (a string)", names.join(", "))
        }
        Kind::Vec3 => format!("{what} as an array of 3 numbers [x, y, z]"),
        Kind::TopTables | Kind::Array => format!("{what} (an array of tables)"),
        Kind::Table => format!("{what} (a table)"),
        Kind::Other => what,
    }
}

/// Checks every number of the document against the schema: finite, within
/// the bounds the schema gives, and within single precision where the
/// field is `f32`.
pub(super) fn check_numbers(doc: &Doc<'_>) -> Result<(), SceneError> {
    let schema = Schema::get();
    for (k, v) in doc.root.get_ref() {
        check_value(doc, &schema, &KeyPath(vec![Seg::Key(k.get_ref().to_string())]), v.get_ref())?;
    }
    Ok(())
}

fn check_value(doc: &Doc<'_>, schema: &Schema, path: &KeyPath, v: &DeValue<'_>) -> Result<(), SceneError> {
    match v {
        DeValue::Table(t) => {
            for (k, x) in t {
                check_value(doc, schema, &path.key(k.get_ref()), x.get_ref())?;
            }
        }
        DeValue::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                check_value(doc, schema, &path.index(i), x.get_ref())?;
            }
        }
        DeValue::Integer(_) | DeValue::Float(_) => {
            let Some(s) = schema.at(&path.0) else { return Ok(()) };
            let x = number(v).unwrap_or(f64::NAN);
            if !x.is_finite() {
                return Err(doc.err(path, format!("expected a finite number, found {}", fmt_f64(x))));
            }
            let bounds = Bounds::of(s);
            if s.get("type").and_then(Json::as_str) == Some("integer") {
                // Deserialized already, so it fits the integer type; serde
                // gives 0 for the bounds below.
                if !bounds.contains(x) {
                    let min = bounds.min.map_or(0.0, |m| m.0);
                    return Err(doc.err(
                        path,
                        format!("expected {} (an integer >= {min}), found {}", schema.what(&path.0), fmt_f64(x)),
                    ));
                }
                return Ok(());
            }
            let range = bounds.text();
            let what = schema.what(&path.0);
            let y = if s.get("format").and_then(Json::as_str) == Some("float") { f64::from(x as f32) } else { x };
            if !y.is_finite() {
                return Err(doc.err(
                    path,
                    format!("expected {what}{range}, found {}, which is out of single-precision range", fmt_f64(x)),
                ));
            }
            if !bounds.contains(y) {
                return Err(doc.err(path, format!("expected {what}{range}, found {}", fmt_f64(x))));
            }
        }
        _ => {}
    }
    Ok(())
}

/// The numeric value of an integer or float.
pub(super) fn number(v: &DeValue<'_>) -> Option<f64> {
    match v {
        DeValue::Integer(i) => i64::from_str_radix(i.as_str(), i.radix()).ok().map(|i| i as f64),
        DeValue::Float(x) => x.as_str().parse().ok(),
        _ => None,
    }
}

/// The bounds a schema puts on a number; `(value, inclusive)`.
struct Bounds {
    min: Option<(f64, bool)>,
    max: Option<(f64, bool)>,
}

impl Bounds {
    fn of(s: &Json) -> Bounds {
        let get = |k: &str| s.get(k).and_then(Json::as_f64);
        Bounds {
            min: get("exclusiveMinimum").map(|m| (m, false)).or_else(|| get("minimum").map(|m| (m, true))),
            max: get("exclusiveMaximum").map(|m| (m, false)).or_else(|| get("maximum").map(|m| (m, true))),
        }
    }

    fn contains(&self, x: f64) -> bool {
        let above = self.min.is_none_or(|(m, inc)| if inc { x >= m } else { x > m });
        let below = self.max.is_none_or(|(m, inc)| if inc { x <= m } else { x < m });
        above && below
    }

    /// ` > 0`, ` >= 0`, ` in (0, 1]`, or nothing.
    fn text(&self) -> String {
        match (self.min, self.max) {
            (Some((lo, li)), Some((hi, hi_inc))) => {
                format!(" in {}{lo}, {hi}{}", if li { "[" } else { "(" }, if hi_inc { "]" } else { ")" })
            }
            (Some((lo, true)), None) => format!(" >= {lo}"),
            (Some((lo, false)), None) => format!(" > {lo}"),
            (None, Some((hi, true))) => format!(" <= {hi}"),
            (None, Some((hi, false))) => format!(" < {hi}"),
            (None, None) => String::new(),
        }
    }
}

/// The kinds of value the scene schema has.
enum Kind {
    Bool,
    Number,
    /// With its least value.
    Integer(f64),
    String {
        non_empty: bool,
    },
    Enum(Vec<String>),
    Vec3,
    /// A top-level `[[name]]` list.
    TopTables,
    Array,
    Table,
    Other,
}

/// The scene schema, for the meaning, kind and allowed keys of a path.
pub(super) struct Schema {
    root: &'static Json,
}

impl Schema {
    pub fn get() -> Schema {
        static ROOT: OnceLock<Json> = OnceLock::new();
        Schema { root: ROOT.get_or_init(super::schema) }
    }

    /// Follows `$ref`s and one-element `allOf`s.
    fn resolve(&self, mut s: &'static Json) -> &'static Json {
        for _ in 0..16 {
            if let Some(r) = s.get("$ref").and_then(Json::as_str) {
                match r.strip_prefix('#').and_then(|p| self.root.pointer(p)) {
                    Some(t) => s = t,
                    None => return s,
                }
            } else if let Some([one]) = s.get("allOf").and_then(Json::as_array).map(Vec::as_slice) {
                s = one;
            } else {
                return s;
            }
        }
        s
    }

    /// The schema at `path`, as the parent states it (with the field's
    /// description), not resolved.
    fn at(&self, path: &[Seg]) -> Option<&'static Json> {
        let mut s = self.root;
        for seg in path {
            let r = self.resolve(s);
            s = match seg {
                Seg::Key(k) => match r.get("properties").and_then(|p| p.get(k)) {
                    Some(p) => p,
                    None => r.get("additionalProperties").filter(|a| a.is_object())?,
                },
                Seg::Index(_) => r.get("items")?,
            };
        }
        Some(s)
    }

    /// What the value at `path` is: the first paragraph of its description
    /// ("the rest density in kg/m^3"), or the component of a 3-vector.
    pub fn what(&self, path: &[Seg]) -> String {
        let described = self.at(path).and_then(|s| {
            let text = s.get("description").or_else(|| self.resolve(s).get("description"))?;
            text.as_str()
        });
        if let Some(text) = described {
            let first = text.split("\n\n").next().unwrap_or("");
            let mut what = first.split_whitespace().collect::<Vec<_>>().join(" ");
            if what.ends_with('.') {
                what.pop();
            }
            for article in ["The ", "A ", "An "] {
                if let Some(rest) = what.strip_prefix(article) {
                    what = format!("{}{rest}", article.to_lowercase());
                }
            }
            return what;
        }
        match path.last() {
            Some(Seg::Index(i)) if *i < 3 => format!("the {} component", ["x", "y", "z"][*i]),
            _ => "a value".to_string(),
        }
    }

    fn kind(&self, path: &[Seg]) -> Kind {
        let Some(s) = self.at(path).map(|s| self.resolve(s)) else { return Kind::Other };
        if let Some(values) = enum_values(s) {
            return Kind::Enum(values);
        }
        match s.get("type").and_then(Json::as_str) {
            Some("boolean") => Kind::Bool,
            Some("number") => Kind::Number,
            Some("integer") => Kind::Integer(Bounds::of(s).min.map_or(0.0, |m| m.0)),
            Some("string") => Kind::String { non_empty: s.get("minLength").and_then(Json::as_u64).unwrap_or(0) > 0 },
            Some("array") if s.get("maxItems").and_then(Json::as_u64) == Some(3) => Kind::Vec3,
            Some("array") if path.len() == 1 => Kind::TopTables,
            Some("array") => Kind::Array,
            Some("object") => Kind::Table,
            _ => Kind::Other,
        }
    }

    /// The keys allowed in the table at `path`, in the order of the types.
    pub fn keys(&self, path: &[Seg]) -> Vec<String> {
        let s = self.at(path).map(|s| self.resolve(s));
        s.and_then(|s| s.get("properties"))
            .and_then(Json::as_object)
            .map_or_else(Vec::new, |p| p.keys().cloned().collect())
    }

    /// The strings an enum at `path` takes.
    fn values(&self, path: &[Seg]) -> Vec<String> {
        self.at(path).and_then(|s| enum_values(self.resolve(s))).unwrap_or_default()
    }
}

/// The values of an enum schema (`enum`, or `oneOf` of `const`s).
fn enum_values(s: &Json) -> Option<Vec<String>> {
    if let Some(e) = s.get("enum").and_then(Json::as_array) {
        return Some(e.iter().filter_map(|v| v.as_str().map(str::to_string)).collect());
    }
    let one_of = s.get("oneOf")?.as_array()?;
    one_of.iter().map(|v| v.get("const").and_then(Json::as_str).map(str::to_string)).collect()
}

/// What a value is, for "found ..." in messages.
pub(super) fn describe(v: &DeValue<'_>) -> String {
    match v {
        DeValue::String(s) => {
            let short: String = s.chars().take(40).collect();
            if short.len() < s.len() {
                format!("the string {short:?}...")
            } else {
                format!("the string {:?}", s.as_ref())
            }
        }
        DeValue::Integer(i) => match i64::from_str_radix(i.as_str(), i.radix()) {
            Ok(n) => format!("the integer {n}"),
            Err(_) => format!("the integer {i}"),
        },
        DeValue::Float(_) => format!("the number {}", fmt_f64(number(v).unwrap_or(f64::NAN))),
        DeValue::Boolean(b) => format!("the boolean {b}"),
        DeValue::Datetime(t) => format!("the date-time {t}"),
        DeValue::Array(a) if a.len() == 1 => "an array of 1 element".to_string(),
        DeValue::Array(a) => format!("an array of {} elements", a.len()),
        DeValue::Table(_) => "a table".to_string(),
    }
}

/// Formats a float the way TOML spells it (`nan`, `inf`).
pub(super) fn fmt_f64(x: f64) -> String {
    if x.is_nan() {
        "nan".to_string()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.to_string()
    } else {
        format!("{x}")
    }
}

/// 1-based line and column (in characters) of byte `offset`, and that line's text.
pub(super) fn line_column(text: &str, offset: usize) -> (usize, usize, String) {
    let mut line_start = 0;
    let mut line = 1;
    let mut column = 1;
    for (i, c) in text.char_indices() {
        if i >= offset {
            break;
        }
        if c == '\n' {
            line += 1;
            column = 1;
            line_start = i + 1;
        } else {
            column += 1;
        }
    }
    let rest = text.get(line_start..).unwrap_or("");
    let content = rest.lines().next().unwrap_or("").trim_end();
    let mut shown: String = content.chars().take(80).collect();
    if shown.len() < content.len() {
        shown.push_str("...");
    }
    (line, column, shown)
}

/// The candidate closest to `word` by edit distance, if it is plausibly a typo.
pub(super) fn closest<'a>(word: &str, candidates: &'a [String]) -> Option<&'a str> {
    candidates
        .iter()
        .map(|a| (edit_distance(word, a), a.as_str()))
        .filter(|(dist, a)| *dist <= 2.max(a.len() / 3))
        .min_by_key(|(dist, _)| *dist)
        .map(|(_, a)| a)
}

/// Levenshtein distance between two short strings.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for (i, ca) in a.chars().enumerate() {
        cur[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let subst = prev[j] + usize::from(ca != *cb);
            cur[j + 1] = subst.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}
