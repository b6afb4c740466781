//! Case values by key: the indexed key paths the error messages use
//! (`loading.displacement`, `tool[1].mass`, `ply[0].fibre_angle_deg`) and,
//! through a table that names a parameter set, that set's values
//! (`material.w6.s_ini`, `ply[0].w6.s_ini`) — read, changed and written
//! back as a case file that `ncform run` runs alone (`docs/studies.md`,
//! "Keys").
//!
//! A [`CaseDocument`] keeps the case file's text (its comments and layout
//! kept by `toml_edit`) and the parameter sets edited through it. Every
//! [`CaseDocument::set`] is checked at once: the value's type against the
//! value the case has, then the edited parameter set by the law's own
//! parser, then the whole case by the case parser, so an unknown key, a
//! wrong type or a value outside its documented range is refused with the
//! key named before anything runs.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use toml_edit::{DocumentMut, Item, Value};

use crate::case::Case;
use crate::material::MaterialSpec;

/// Why a key could not be read or set, or the edited case not written.
#[derive(Debug, Clone, thiserror::Error)]
pub enum KeyError {
    /// The case file (or a parameter file it names) could not be read or
    /// is not TOML.
    #[error("{file}: {reason}")]
    Read {
        /// The file.
        file: String,
        /// Why.
        reason: String,
    },
    /// A key that is not of the form `name`, `name[i]`, separated by dots.
    #[error(
        "key '{key}': {reason}; expected a path such as loading.displacement, tool[1].mass or ply[0].w6.s_ini (docs/studies.md, \"Keys\")"
    )]
    Malformed {
        /// The key.
        key: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A key whose path does not exist in the case (an index past the
    /// tables, a value where a table was expected).
    #[error("{file}: key '{key}': {reason}")]
    NoSuchKey {
        /// The case file.
        file: String,
        /// The key.
        key: String,
        /// What the case has there.
        reason: String,
    },
    /// A value whose type differs from the value the case has.
    #[error("{file}: key '{key}' = {value}: the case has {existing} there; expected {expected}")]
    Type {
        /// The case file.
        file: String,
        /// The key.
        key: String,
        /// The value given.
        value: String,
        /// The value the case has.
        existing: String,
        /// The type expected.
        expected: &'static str,
    },
    /// The case (or its parameter set) refuses the edited value: the
    /// parser's message, with the key and value that were set.
    #[error("key '{key}' = {value}: {message}")]
    Invalid {
        /// The key.
        key: String,
        /// The value.
        value: String,
        /// The parser's message (file, line, key, value, expected).
        message: String,
    },
    /// The edited case could not be written.
    #[error("{path}: cannot write: {reason}")]
    Write {
        /// The file.
        path: String,
        /// Why.
        reason: String,
    },
}

/// One segment of a key path: a name and, for `name[i]`, an index.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Segment {
    /// The table or value name.
    pub name: String,
    /// The index into an array of tables (`tool[1]`) or an array value.
    pub index: Option<usize>,
}

/// Splits `key` into its segments (`tool[1].mass` → `tool`\[1\], `mass`).
///
/// # Errors
/// [`KeyError::Malformed`] for an empty segment, a name with characters
/// other than letters, digits, `_` and `-`, or an index that is not a
/// number.
pub fn parse_key(key: &str) -> Result<Vec<Segment>, KeyError> {
    let bad = |reason: String| KeyError::Malformed {
        key: key.to_string(),
        reason,
    };
    if key.trim().is_empty() {
        return Err(bad("empty".into()));
    }
    key.split('.')
        .map(|part| {
            let (name, index) = match part.split_once('[') {
                None => (part, None),
                Some((name, rest)) => {
                    let digits = rest
                        .strip_suffix(']')
                        .ok_or_else(|| bad(format!("'{part}' has '[' without a closing ']'")))?;
                    let i = digits.parse::<usize>().map_err(|_| {
                        bad(format!(
                            "'{part}': the index '{digits}' is not a whole number"
                        ))
                    })?;
                    (name, Some(i))
                }
            };
            if name.is_empty() {
                return Err(bad(format!("an empty name in '{part}'")));
            }
            if !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            {
                return Err(bad(format!(
                    "'{name}' has characters other than letters, digits, '_' and '-'"
                )));
            }
            Ok(Segment {
                name: name.to_string(),
                index,
            })
        })
        .collect()
}

/// A parameter set that a case table names (`[material] params`, a ply's
/// `params`), as edited through that table.
#[derive(Debug, Clone)]
struct ParamSet {
    /// The set's text, edited.
    doc: DocumentMut,
    /// Where it came from: a named set or the file, for the header.
    origin: String,
}

/// A case file open for reading and changing values by key.
#[derive(Debug, Clone)]
pub struct CaseDocument {
    /// The case file as given.
    path: PathBuf,
    /// The folder its relative paths are taken from.
    base_dir: PathBuf,
    /// The case's text, edited.
    doc: DocumentMut,
    /// The parameter sets edited through a table, by that table's key
    /// (`material`, `ply[0]`).
    params: BTreeMap<String, ParamSet>,
    /// Every key set, in order, with its value (for the header).
    edits: Vec<(String, String)>,
}

/// The tables through which a parameter set's values are reached.
fn names_a_parameter_set(table_key: &str) -> bool {
    table_key == "material" || (table_key.starts_with("ply[") && !table_key.contains('.'))
}

impl CaseDocument {
    /// Opens the case file `path`.
    ///
    /// # Errors
    /// [`KeyError::Read`] for an unreadable file or text that is not TOML.
    pub fn load(path: &Path) -> Result<Self, KeyError> {
        let (text, _source, base_dir) =
            crate::config::read_case_file(path).map_err(|e| KeyError::Read {
                file: path.display().to_string(),
                reason: e.to_string(),
            })?;
        Self::from_text(&text, path, &base_dir)
    }

    /// A case of text `text`, named `path` in messages, whose relative
    /// paths are taken from `base_dir`.
    ///
    /// # Errors
    /// [`KeyError::Read`] for text that is not TOML.
    pub fn from_text(text: &str, path: &Path, base_dir: &Path) -> Result<Self, KeyError> {
        let doc = text.parse::<DocumentMut>().map_err(|e| KeyError::Read {
            file: path.display().to_string(),
            reason: e.to_string().trim().to_string(),
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            base_dir: base_dir.to_path_buf(),
            doc,
            params: BTreeMap::new(),
            edits: Vec::new(),
        })
    }

    /// The case file as given.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The keys set so far, in order, with their values as TOML.
    pub fn edits(&self) -> &[(String, String)] {
        &self.edits
    }

    /// The case file's text as edited (parameter sets still named as in
    /// the original; [`CaseDocument::write`] writes the edited sets).
    pub fn text(&self) -> String {
        self.doc.to_string()
    }

    /// The value at `key`.
    ///
    /// # Errors
    /// [`KeyError::Malformed`], or [`KeyError::NoSuchKey`] when the case
    /// (or the parameter set the key goes through) has no value there.
    pub fn get(&self, key: &str) -> Result<toml::Value, KeyError> {
        let segments = parse_key(key)?;
        let mut this = self.clone();
        let (target, rest) = this.route(key, &segments)?;
        let item = match target {
            Target::Case => lookup(this.doc.as_item_mut(), &segments, key, &self.path, false)?,
            Target::Params(table) => {
                let file = self.path.display().to_string();
                let set = this
                    .params
                    .get_mut(&table)
                    .ok_or_else(|| KeyError::NoSuchKey {
                        file,
                        key: key.to_string(),
                        reason: "no parameter set".into(),
                    })?;
                lookup(
                    set.doc.as_item_mut(),
                    &segments[rest..],
                    key,
                    &self.path,
                    false,
                )?
            }
        };
        let value = item.as_value().ok_or_else(|| KeyError::NoSuchKey {
            file: self.path.display().to_string(),
            key: key.to_string(),
            reason: format!("a {} there, not a value", item.type_name()),
        })?;
        to_toml_value(value).ok_or_else(|| KeyError::NoSuchKey {
            file: self.path.display().to_string(),
            key: key.to_string(),
            reason: "a value that is not plain TOML".into(),
        })
    }

    /// Sets `key` to `value` and checks the case as edited: the type
    /// against the value the case has (a whole number is taken where the
    /// case has a float), the parameter set by the law's parser when the
    /// key goes through one, then the whole case by the case parser. On
    /// an error the document is left as it was.
    ///
    /// # Errors
    /// [`KeyError::Malformed`], [`KeyError::NoSuchKey`], [`KeyError::Type`]
    /// or [`KeyError::Invalid`], each naming the key.
    pub fn set(&mut self, key: &str, value: toml::Value) -> Result<(), KeyError> {
        let mut edited = self.clone();
        edited.set_unchecked(key, &value)?;
        edited.case().map_err(|e| match e {
            KeyError::Invalid { message, .. } => KeyError::Invalid {
                key: key.to_string(),
                value: value.to_string(),
                message,
            },
            other => other,
        })?;
        *self = edited;
        Ok(())
    }

    /// [`CaseDocument::set`] without the check of the whole case (the
    /// type and the parameter set are still checked): for a sweep that
    /// sets several keys of one point before checking it once.
    ///
    /// # Errors
    /// As [`CaseDocument::set`], but for the case parser's.
    pub fn set_unchecked(&mut self, key: &str, value: &toml::Value) -> Result<(), KeyError> {
        let segments = parse_key(key)?;
        let given = value.to_string();
        let new: Value = given
            .parse()
            .map_err(|e: toml_edit::TomlError| KeyError::Malformed {
                key: key.to_string(),
                reason: format!("the value {given} is not a TOML value: {e}"),
            })?;
        let (target, rest) = self.route(key, &segments)?;
        let file = self.path.display().to_string();
        match target {
            Target::Case => {
                let item = lookup(self.doc.as_item_mut(), &segments, key, &self.path, true)?;
                assign(item, new, key, &file)?;
            }
            Target::Params(table) => {
                let set = self
                    .params
                    .get_mut(&table)
                    .ok_or_else(|| KeyError::NoSuchKey {
                        file: file.clone(),
                        key: key.to_string(),
                        reason: "no parameter set".into(),
                    })?;
                let item = lookup(
                    set.doc.as_item_mut(),
                    &segments[rest..],
                    key,
                    &self.path,
                    false,
                )?;
                assign(item, new, key, &file)?;
                let text = set.doc.to_string();
                MaterialSpec::from_toml_str(&text, &format!("{} ({table}.params)", set.origin))
                    .map_err(|e| KeyError::Invalid {
                        key: key.to_string(),
                        value: given.clone(),
                        message: e.to_string(),
                    })?;
            }
        }
        self.edits.push((key.to_string(), given));
        Ok(())
    }

    /// Where `segments` lead: into the case itself, or, when a segment
    /// after a table that names a parameter set (`material`, `ply[i]`) is
    /// not one of that table's keys, into that set from the segment on
    /// (loaded on first use).
    fn route(&mut self, key: &str, segments: &[Segment]) -> Result<(Target, usize), KeyError> {
        let mut table_key = String::new();
        let mut item: &Item = self.doc.as_item();
        for (k, seg) in segments.iter().enumerate() {
            if k > 0 && names_a_parameter_set(&table_key) {
                let has = item
                    .as_table_like()
                    .is_some_and(|t| t.contains_key(&seg.name));
                if !has && seg.name != "params" {
                    let origin = item
                        .as_table_like()
                        .and_then(|t| t.get("params"))
                        .and_then(Item::as_str)
                        .map(str::to_string);
                    self.load_params(&table_key, origin.as_deref(), key)?;
                    return Ok((Target::Params(table_key), k));
                }
            }
            if !table_key.is_empty() {
                table_key.push('.');
            }
            table_key.push_str(&seg.name);
            if let Some(i) = seg.index {
                table_key.push_str(&format!("[{i}]"));
            }
            let next = item
                .as_table_like()
                .and_then(|t| t.get(&seg.name))
                .and_then(|it| match seg.index {
                    None => Some(it),
                    Some(i) => it.get(i),
                });
            match next {
                Some(n) => item = n,
                None => break,
            }
        }
        Ok((Target::Case, 0))
    }

    /// Loads the parameter set that the table `table_key` names
    /// (`origin`: a named set or a file; none: the default set), unless
    /// it is loaded already.
    fn load_params(
        &mut self,
        table_key: &str,
        origin: Option<&str>,
        key: &str,
    ) -> Result<(), KeyError> {
        if self.params.contains_key(table_key) {
            return Ok(());
        }
        let name = origin.unwrap_or(crate::material::params::DEFAULT_SET);
        let (text, origin) = match MaterialSpec::named_text(name) {
            Some(text) => (text.to_string(), format!("named set {name}")),
            None => {
                let path = self.base_dir.join(name);
                let text = std::fs::read_to_string(&path).map_err(|e| KeyError::NoSuchKey {
                    file: self.path.display().to_string(),
                    key: key.to_string(),
                    reason: format!(
                        "{table_key}.params = \"{name}\": not a named set and not a readable file ({}: {e})",
                        path.display()
                    ),
                })?;
                (text, path.display().to_string())
            }
        };
        let doc = text.parse::<DocumentMut>().map_err(|e| KeyError::Read {
            file: origin.clone(),
            reason: e.to_string().trim().to_string(),
        })?;
        self.params
            .insert(table_key.to_string(), ParamSet { doc, origin });
        Ok(())
    }

    /// The case as edited, validated by the case parser (the edited
    /// parameter sets written to a private temporary folder for the
    /// parse, then removed).
    ///
    /// # Errors
    /// [`KeyError::Invalid`] with the parser's message (the key is the
    /// last one set), [`KeyError::Write`] when the temporary files cannot
    /// be written.
    pub fn case(&self) -> Result<Case, KeyError> {
        let scratch = scratch_dir();
        let result = (|| {
            let text = self.text_with_params(&scratch, true)?;
            Case::from_toml_str(&text, &self.path.display().to_string(), &self.base_dir).map_err(
                |e| {
                    let (key, value) = self.edits.last().cloned().unwrap_or_default();
                    KeyError::Invalid {
                        key,
                        value,
                        message: e.to_string(),
                    }
                },
            )
        })();
        let _ = std::fs::remove_dir_all(&scratch);
        result
    }

    /// Writes the case as edited into `folder` as `case.toml`, with every
    /// edited parameter set beside it (`params-material.toml`,
    /// `params-ply0.toml`) and every other relative file path made
    /// absolute, so that `ncform run folder/case.toml` runs it alone.
    /// Returns the case file's path and every file it reads (for hashes).
    ///
    /// # Errors
    /// [`KeyError::Write`].
    pub fn write(&self, folder: &Path) -> Result<(PathBuf, Vec<PathBuf>), KeyError> {
        std::fs::create_dir_all(folder).map_err(|e| KeyError::Write {
            path: folder.display().to_string(),
            reason: e.to_string(),
        })?;
        let text = self.text_with_params(folder, false)?;
        let path = folder.join("case.toml");
        write_file(&path, &text)?;
        let mut inputs = vec![path.clone()];
        inputs.extend(self.referenced_files());
        for table in self.params.keys() {
            inputs.push(folder.join(param_file_name(table)));
        }
        Ok((path, inputs))
    }

    /// The files the case names by a relative or absolute path that exist
    /// (meshes, tool drawings, parameter files not edited here).
    pub fn referenced_files(&self) -> Vec<PathBuf> {
        let mut files = Vec::new();
        let mut doc = self.doc.clone();
        visit_strings(doc.as_item_mut(), &mut |s| {
            let p = self.base_dir.join(s.value());
            if p.is_file() {
                files.push(std::fs::canonicalize(&p).unwrap_or(p));
            }
        });
        files.sort();
        files.dedup();
        files
    }

    /// The case text with every edited parameter set written into
    /// `folder` and named there (absolutely when `absolute`, else by its
    /// file name beside the case), and, unless `absolute` (the parse keeps
    /// the original base folder), every relative file path made absolute.
    fn text_with_params(&self, folder: &Path, absolute: bool) -> Result<String, KeyError> {
        let mut doc = self.doc.clone();
        if !absolute {
            visit_strings(doc.as_item_mut(), &mut |s| {
                let rel = Path::new(s.value());
                if rel.is_absolute() {
                    return;
                }
                let p = self.base_dir.join(rel);
                if p.is_file() {
                    let abs = std::fs::canonicalize(&p).unwrap_or(p);
                    let decor = s.decor().clone();
                    let mut v = toml_edit::Formatted::new(abs.display().to_string());
                    *v.decor_mut() = decor;
                    *s = v;
                }
            });
        }
        if !self.params.is_empty() {
            std::fs::create_dir_all(folder).map_err(|e| KeyError::Write {
                path: folder.display().to_string(),
                reason: e.to_string(),
            })?;
        }
        for (table, set) in &self.params {
            let name = param_file_name(table);
            let path = folder.join(&name);
            let header = format!(
                "# ncform parameter set: {} with {}\n",
                set.origin,
                self.edits
                    .iter()
                    .filter(|(k, _)| k.starts_with(&format!("{table}.")))
                    .map(|(k, v)| format!("{k} = {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            write_file(&path, &format!("{header}{}", set.doc))?;
            let named = if absolute {
                path.display().to_string()
            } else {
                name
            };
            let segments = parse_key(table)?;
            let item = lookup(doc.as_item_mut(), &segments, table, &self.path, true)?;
            let t = item
                .as_table_like_mut()
                .ok_or_else(|| KeyError::NoSuchKey {
                    file: self.path.display().to_string(),
                    key: table.clone(),
                    reason: "not a table".into(),
                })?;
            t.insert("params", toml_edit::value(named));
        }
        if !self.edits.is_empty() {
            let note = format!(
                "# ncform: {} with {}\n",
                self.path.display(),
                self.edits
                    .iter()
                    .map(|(k, v)| format!("{k} = {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            let prefix = doc.decor().prefix().and_then(|p| p.as_str()).unwrap_or("");
            let prefix = format!("{note}{prefix}");
            doc.decor_mut().set_prefix(prefix);
        }
        Ok(doc.to_string())
    }
}

/// Where a key leads.
enum Target {
    /// Into the case file.
    Case,
    /// Into the parameter set that the table with this key names.
    Params(String),
}

/// The file an edited parameter set is written to: `params-material.toml`,
/// `params-ply0.toml`.
fn param_file_name(table: &str) -> String {
    let stem: String = table
        .chars()
        .filter(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    format!("params-{stem}.toml")
}

/// A folder for the files of one validation parse.
fn scratch_dir() -> PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static COUNT: AtomicUsize = AtomicUsize::new(0);
    std::env::temp_dir().join(format!(
        "ncform-keys-{}-{}",
        std::process::id(),
        COUNT.fetch_add(1, Ordering::Relaxed)
    ))
}

/// Writes `text` to `path`.
fn write_file(path: &Path, text: &str) -> Result<(), KeyError> {
    std::fs::write(path, text).map_err(|e| KeyError::Write {
        path: path.display().to_string(),
        reason: e.to_string(),
    })
}

/// Calls `f` on every string value in `item`, tables and arrays included.
fn visit_strings(item: &mut Item, f: &mut dyn FnMut(&mut toml_edit::Formatted<String>)) {
    match item {
        Item::Value(v) => visit_value(v, f),
        Item::Table(t) => {
            for (_, it) in t.iter_mut() {
                visit_strings(it, f);
            }
        }
        Item::ArrayOfTables(a) => {
            for t in a.iter_mut() {
                for (_, it) in t.iter_mut() {
                    visit_strings(it, f);
                }
            }
        }
        Item::None => {}
    }
}

/// [`visit_strings`] of a value.
fn visit_value(v: &mut Value, f: &mut dyn FnMut(&mut toml_edit::Formatted<String>)) {
    match v {
        Value::String(s) => f(s),
        Value::Array(a) => {
            for x in a.iter_mut() {
                visit_value(x, f);
            }
        }
        Value::InlineTable(t) => {
            for (_, x) in t.iter_mut() {
                visit_value(x, f);
            }
        }
        _ => {}
    }
}

/// The item at `segments` below `root`; with `create`, the missing tables
/// and the last key are made (as an empty value slot to assign).
fn lookup<'a>(
    root: &'a mut Item,
    segments: &[Segment],
    key: &str,
    file: &Path,
    create: bool,
) -> Result<&'a mut Item, KeyError> {
    let no = |reason: String| KeyError::NoSuchKey {
        file: file.display().to_string(),
        key: key.to_string(),
        reason,
    };
    let mut item = root;
    let mut path = String::new();
    for (k, seg) in segments.iter().enumerate() {
        let last = k + 1 == segments.len();
        let here = if path.is_empty() {
            "the top level".to_string()
        } else {
            path.clone()
        };
        let table = item
            .as_table_like_mut()
            .ok_or_else(|| no(format!("{here} is a value, not a table")))?;
        if !table.contains_key(&seg.name) {
            if !create || seg.index.is_some() {
                return Err(no(format!("{here} has no '{}'", seg.name)));
            }
            let new = if last {
                Item::None
            } else {
                let mut t = toml_edit::Table::new();
                t.set_implicit(true);
                Item::Table(t)
            };
            table.insert(&seg.name, new);
        }
        let mut next = table
            .get_mut(&seg.name)
            .ok_or_else(|| no(format!("{here} has no '{}'", seg.name)))?;
        if let Some(i) = seg.index {
            let count = match &*next {
                Item::ArrayOfTables(a) => a.len(),
                Item::Value(Value::Array(a)) => a.len(),
                other => {
                    return Err(no(format!(
                        "'{}' is a {}, not an array to index",
                        seg.name,
                        other.type_name()
                    )));
                }
            };
            if i >= count {
                return Err(no(format!(
                    "index {i} past the {count} '{}' entries (indices start at 0)",
                    seg.name
                )));
            }
            next = next
                .get_mut(i)
                .ok_or_else(|| no(format!("no '{}[{i}]'", seg.name)))?;
        }
        item = next;
        if !path.is_empty() {
            path.push('.');
        }
        path.push_str(&seg.name);
        if let Some(i) = seg.index {
            path.push_str(&format!("[{i}]"));
        }
    }
    Ok(item)
}

/// Puts `new` into the slot `item`, keeping its comments; a whole number
/// where the case has a float becomes a float, and any other change of
/// type is refused.
fn assign(item: &mut Item, new: Value, key: &str, file: &str) -> Result<(), KeyError> {
    let type_error = |existing: &Value, expected: &'static str, new: &Value| KeyError::Type {
        file: file.to_string(),
        key: key.to_string(),
        value: new.to_string().trim().to_string(),
        existing: existing.to_string().trim().to_string(),
        expected,
    };
    let slot = match item {
        Item::None => {
            *item = Item::Value(new);
            return Ok(());
        }
        Item::Value(v) => v,
        other => {
            return Err(KeyError::NoSuchKey {
                file: file.to_string(),
                key: key.to_string(),
                reason: format!("a {} there, not a value", other.type_name()),
            });
        }
    };
    let new = match (&*slot, new) {
        (Value::Float(_), Value::Integer(i)) => Value::from(*i.value() as f64),
        (Value::Float(_), n @ Value::Float(_)) => n,
        (Value::Integer(_), Value::Float(f))
            if f.value().fract() == 0.0 && f.value().abs() < 9e15 =>
        {
            Value::from(*f.value() as i64)
        }
        (Value::Integer(_), n @ Value::Integer(_)) => n,
        (Value::String(_), n @ Value::String(_)) => n,
        (Value::Boolean(_), n @ Value::Boolean(_)) => n,
        (Value::Array(_), n @ Value::Array(_)) => n,
        (Value::InlineTable(_), n @ Value::InlineTable(_)) => n,
        (existing, n) => {
            let expected = match existing {
                Value::Float(_) => "a number",
                Value::Integer(_) => "a whole number",
                Value::String(_) => "a string",
                Value::Boolean(_) => "true or false",
                Value::Array(_) => "an array",
                Value::InlineTable(_) => "an inline table",
                Value::Datetime(_) => "a date",
            };
            return Err(type_error(existing, expected, &n));
        }
    };
    let decor = slot.decor().clone();
    *slot = new;
    *slot.decor_mut() = decor;
    Ok(())
}

/// A `toml_edit` value as a `toml` value.
fn to_toml_value(v: &Value) -> Option<toml::Value> {
    let text = format!("x = {}", v.to_string().trim());
    let table: toml::Table = text.parse().ok()?;
    table.get("x").cloned()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn oat45() -> CaseDocument {
        CaseDocument::load(Path::new("cases/oat45.toml")).unwrap()
    }

    #[test]
    fn keys_parse_into_names_and_indices() {
        let s = parse_key("tool[1].mass").unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].index, Some(1));
        assert!(parse_key("tool[x].mass").is_err());
        assert!(parse_key("a..b").is_err());
        assert!(parse_key("").is_err());
    }

    #[test]
    fn a_case_value_is_read_set_and_checked() {
        let mut doc = oat45();
        assert_eq!(
            doc.get("loading.displacement").unwrap(),
            toml::Value::Float(80.0)
        );
        // An output displacement beyond the end is refused by the case.
        let e = doc
            .set("loading.displacement", toml::Value::Integer(40))
            .unwrap_err()
            .to_string();
        assert!(e.contains("output_displacements"), "{e}");
        doc.set("loading.displacement", toml::Value::Integer(70))
            .unwrap();
        assert_eq!(
            doc.get("loading.displacement").unwrap(),
            toml::Value::Float(70.0)
        );
        // The comment on the line stays.
        assert!(doc.text().contains("displacement = 70.0"));
        assert!(doc.text().contains("# final clamp displacement"));
        let Case::Oat(case) = doc.case().unwrap() else {
            panic!("an OAT")
        };
        assert_eq!(case.displacement, 70.0);
    }

    #[test]
    fn unknown_keys_wrong_types_and_bad_values_are_refused_naming_the_key() {
        let mut doc = oat45();
        let e = doc
            .set("loading.displacment", toml::Value::Float(40.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("displacment"), "{e}");
        let e = doc
            .set("loading.displacement", toml::Value::String("far".into()))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("loading.displacement") && e.contains("a number"),
            "{e}"
        );
        let e = doc
            .set("material.thickness", toml::Value::Float(-1.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("material.thickness"), "{e}");
        let e = doc
            .set("material.w6.s_ini", toml::Value::Float(-0.5))
            .unwrap_err()
            .to_string();
        assert!(e.contains("w6") && e.contains("s_ini"), "{e}");
        let e = doc
            .set("tool[0].mass", toml::Value::Float(1.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("tool"), "{e}");
        // Nothing of the refused sets stayed.
        assert_eq!(doc.edits().len(), 0);
    }

    #[test]
    fn a_parameter_set_value_is_set_through_its_table_and_written_beside_the_case() {
        let mut doc = oat45();
        assert_eq!(
            doc.get("material.w6.s_ini").unwrap(),
            toml::Value::Float(0.018)
        );
        doc.set("material.w6.s_ini", toml::Value::Float(0.02))
            .unwrap();
        let Case::Oat(case) = doc.case().unwrap() else {
            panic!("an OAT")
        };
        let dir = std::env::temp_dir().join(format!("ncform-keys-test-{}", std::process::id()));
        let (path, inputs) = doc.write(&dir).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains("params = \"params-material.toml\""), "{text}");
        assert!(inputs.iter().any(|p| p.ends_with("params-material.toml")));
        let Case::Oat(again) = Case::load(&path).unwrap() else {
            panic!("an OAT")
        };
        assert_eq!(
            format!("{:?}", again.material.material),
            format!("{:?}", case.material.material)
        );
        assert!(format!("{:?}", case.material.material).contains("s_ini: 0.02,"));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn forming_keys_reach_tools_plies_and_the_ply_parameter_set() {
        let mut doc = CaseDocument::load(Path::new("cases/hemisphere-0.toml")).unwrap();
        let mass = doc.get("tool[1].mass");
        assert!(mass.is_ok() || doc.get("tool[2].mass").is_ok(), "{mass:?}");
        doc.set("ply[0].fibre_angle_deg", toml::Value::Float(30.0))
            .unwrap();
        doc.set("ply[0].w6.s_ini", toml::Value::Float(0.02))
            .unwrap();
        let dir = std::env::temp_dir().join(format!("ncform-keys-form-{}", std::process::id()));
        let (path, _) = doc.write(&dir).unwrap();
        let Case::Forming(case) = Case::load(&path).unwrap() else {
            panic!("a forming case")
        };
        assert_eq!(case.plies[0].fibre_angle_deg, 30.0);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
