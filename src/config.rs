//! Reading TOML input files (parameter sets, case files) with errors that
//! name the file, the line, the key, the value and what was expected.

use std::fmt;

use serde::de::DeserializeOwned;
use toml::Spanned;

/// Why an input file could not be used. Every variant names its source.
#[derive(Debug, Clone, PartialEq)]
pub enum ConfigError {
    /// The input could not be found or read.
    NotFound {
        /// What the user asked for, e.g. `material parameters 'x.toml'`.
        requested: String,
        /// Why it was not found.
        reason: String,
    },
    /// The TOML could not be parsed, or has unknown or missing keys.
    Syntax {
        /// The file or set name.
        source: String,
        /// The parser's message (it gives line and column).
        message: String,
    },
    /// A key has a value outside its allowed range, or a key that needs
    /// another is given alone.
    Invalid {
        /// The file or set name.
        source: String,
        /// 1-based line of the offending value (0 when not known).
        line: usize,
        /// Dotted key, e.g. `w6.c_mid`.
        key: String,
        /// The value as read.
        value: String,
        /// What was expected.
        expected: String,
    },
    /// A file that a case key points to (a parameter file) cannot be
    /// used: the case's line and key, then the file's own error.
    Referenced {
        /// The case file.
        source: String,
        /// 1-based line of the key in the case file (0 when not known).
        line: usize,
        /// Dotted key, e.g. `ply[0].params`.
        key: String,
        /// The value as written, e.g. `"fabric.toml"`.
        value: String,
        /// The referenced file's error (it names that file).
        cause: Box<ConfigError>,
    },
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::NotFound { requested, reason } => write!(f, "{requested}: {reason}"),
            ConfigError::Syntax { source, message } => {
                write!(f, "{source}: {}", message.trim_end())
            }
            ConfigError::Invalid {
                source,
                line,
                key,
                value,
                expected,
            } => {
                if *line > 0 {
                    write!(f, "{source}:{line}: {key} = {value}: expected {expected}")
                } else {
                    write!(f, "{source}: {key} = {value}: expected {expected}")
                }
            }
            ConfigError::Referenced {
                source,
                line,
                key,
                value,
                cause,
            } => {
                if *line > 0 {
                    write!(f, "{source}:{line}: {key} = {value}: {cause}")
                } else {
                    write!(f, "{source}: {key} = {value}: {cause}")
                }
            }
        }
    }
}

impl std::error::Error for ConfigError {}

/// Deserialises `text` (named `source` in messages); unknown and missing
/// keys are reported by the parser with line and column.
///
/// # Errors
/// [`ConfigError::Syntax`].
pub fn parse_toml<T: DeserializeOwned>(text: &str, source: &str) -> Result<T, ConfigError> {
    toml::from_str(text).map_err(|e| ConfigError::Syntax {
        source: source.to_string(),
        message: shorten_numbers(&e.to_string(), text),
    })
}

/// `message` with every number of 20 or more digits that `text` does not
/// hold written as [`readable_number`]: the parser quotes `1e308` as 309
/// digits when it expected an integer, while a number quoted from the
/// file stays as written.
fn shorten_numbers(message: &str, text: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(first) = rest.find(|c: char| c.is_ascii_digit()) {
        let start = if rest[..first].ends_with('-') {
            first - 1
        } else {
            first
        };
        let end = rest[first..]
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .map_or(rest.len(), |n| first + n);
        let run = &rest[start..end];
        out.push_str(&rest[..start]);
        let digits = run.bytes().filter(u8::is_ascii_digit).count();
        match run.parse::<f64>() {
            Ok(x) if digits >= 20 && !text.contains(run) => out.push_str(&readable_number(x)),
            _ => out.push_str(run),
        }
        rest = &rest[end..];
    }
    out.push_str(rest);
    out
}

/// A value a case file may hold but that is unusual for a fabric or a
/// forming set-up (a friction coefficient of 1.47, an areal mass that looks
/// like g/m²): the run goes ahead and `ncform run` prints the warning to
/// stderr before it starts. The usual ranges are those of
/// [`crate::case::bounds::BOUNDS`] (`docs/cases.md`, "Ranges").
#[derive(Debug, Clone, PartialEq)]
pub struct CaseWarning {
    /// The case (or parameter) file.
    pub source: String,
    /// 1-based line of the value (0 when not known).
    pub line: usize,
    /// Dotted key, e.g. `tool[1].friction`.
    pub key: String,
    /// The value as read.
    pub value: String,
    /// The usual range with its unit, e.g. `[0.05, 1]`; empty for a
    /// warning that is not about a range (a table the solver does not
    /// use).
    pub usual: String,
    /// A short hint at what was probably meant.
    pub hint: String,
}

impl fmt::Display for CaseWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(f, "{}:{}: ", self.source, self.line)?;
        } else {
            write!(f, "{}: ", self.source)?;
        }
        write!(f, "{} = {}: ", self.key, self.value)?;
        if self.usual.is_empty() {
            write!(f, "{}", self.hint)
        } else {
            write!(f, "outside the usual range {}; {}", self.usual, self.hint)
        }
    }
}

/// A key given in a table, as [`TomlChecker::only_keys`] checks it
/// against the keys that apply.
#[derive(Debug, Clone, PartialEq)]
pub struct GivenKey {
    /// The key's name in its table (`width`).
    pub name: &'static str,
    /// 1-based line of its value (0 when not known).
    pub line: usize,
    /// The value as a message shows it.
    pub value: String,
}

/// A value as a message shows it: numbers through [`readable_number`],
/// strings quoted, lists in brackets.
pub trait Shown {
    /// The value as the case file would write it.
    fn shown(&self) -> String;
}

impl Shown for f64 {
    fn shown(&self) -> String {
        readable_number(*self)
    }
}

impl Shown for i64 {
    fn shown(&self) -> String {
        self.to_string()
    }
}

impl Shown for bool {
    fn shown(&self) -> String {
        self.to_string()
    }
}

impl Shown for String {
    fn shown(&self) -> String {
        format!("{self:?}")
    }
}

impl<T: Shown> Shown for Vec<T> {
    fn shown(&self) -> String {
        format!(
            "[{}]",
            self.iter().map(Shown::shown).collect::<Vec<_>>().join(", ")
        )
    }
}

/// Validation helper over one TOML text: turns spans into line numbers,
/// builds [`ConfigError::Invalid`] messages and collects the
/// [`CaseWarning`]s of unusual values.
pub struct TomlChecker<'a> {
    /// The file's text.
    pub text: &'a str,
    /// The file or set name.
    pub source: &'a str,
    /// The warnings collected so far ([`TomlChecker::warn`]).
    pub warnings: std::cell::RefCell<Vec<CaseWarning>>,
}

impl<'a> TomlChecker<'a> {
    /// A checker of `text`, named `source` in messages, without warnings.
    pub fn new(text: &'a str, source: &'a str) -> Self {
        Self {
            text,
            source,
            warnings: std::cell::RefCell::new(Vec::new()),
        }
    }
}

impl TomlChecker<'_> {
    /// Records a warning about `key = value` at `line`: outside the
    /// `usual` range, with a `hint`.
    pub fn warn(&self, line: usize, key: &str, value: String, usual: String, hint: &str) {
        self.warnings.borrow_mut().push(CaseWarning {
            source: self.source.to_string(),
            line,
            key: key.to_string(),
            value,
            usual,
            hint: hint.to_string(),
        });
    }

    /// The warnings collected, emptying the list.
    pub fn take_warnings(&self) -> Vec<CaseWarning> {
        std::mem::take(&mut self.warnings.borrow_mut())
    }

    /// 1-based line of `key = …` in the table `[table]` of the text (0
    /// when not found), for values deserialised without a span (the
    /// `[solver]` knobs, the bending table). `table` is the dotted table
    /// name as its header writes it (`solver`); an inline table
    /// `name = { key = … }` is found by its `name` on a line of that
    /// table.
    pub fn line_of_key(&self, table: &str, key: &str) -> usize {
        self.table_lines(table)
            .find(|(_, t)| {
                t.strip_prefix(key)
                    .is_some_and(|rest| rest.trim_start().starts_with('='))
            })
            .map_or(0, |(n, _)| n + 1)
    }

    /// The keys given in the table `[table]` of the text, in file order
    /// (`table` as its header writes it: `explicit`).
    pub fn keys_of_table(&self, table: &str) -> Vec<String> {
        self.table_lines(table)
            .filter(|(_, t)| !t.starts_with('#'))
            .filter_map(|(_, t)| t.split_once('=').map(|(key, _)| key.trim().to_string()))
            .collect()
    }

    /// The lines of the table `[table]` of the text (`table` as its header
    /// writes it), trimmed, with their 0-based index.
    fn table_lines<'s>(&'s self, table: &'s str) -> impl Iterator<Item = (usize, &'s str)> + 's {
        let mut current = String::new();
        self.text.lines().enumerate().filter_map(move |(n, line)| {
            let t = line.trim();
            if let Some(header) = t.strip_prefix('[') {
                current = header
                    .trim_start_matches('[')
                    .split(']')
                    .next()
                    .unwrap_or("")
                    .trim()
                    .to_string();
                return None;
            }
            (current == table).then_some((n, t))
        })
    }

    /// The key `name` with its line and value when it is given.
    pub fn given<T: Shown>(&self, name: &'static str, v: &Option<Spanned<T>>) -> Option<GivenKey> {
        v.as_ref().map(|v| GivenKey {
            name,
            line: self.line_of(v),
            value: v.get_ref().shown(),
        })
    }

    /// Refuses the first of the `given` keys of `table` (`ply[0].mesh`)
    /// that is not among `takes`, the keys that `what` (`shape
    /// "rectangle"`) takes; the message lists them. `None` entries are keys
    /// not given.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`].
    pub fn only_keys(
        &self,
        table: &str,
        given: &[Option<GivenKey>],
        takes: &[&str],
        what: &str,
    ) -> Result<(), ConfigError> {
        match given.iter().flatten().find(|g| !takes.contains(&g.name)) {
            None => Ok(()),
            Some(g) => Err(self.invalid(
                g.line,
                &format!("{table}.{}", g.name),
                g.value.clone(),
                &if takes.is_empty() {
                    format!("no {} for {what}", g.name)
                } else {
                    format!(
                        "no {} for {what}, which takes only: {}",
                        g.name,
                        takes.join(", ")
                    )
                },
            )),
        }
    }

    /// 1-based line of the header `[table]` (or `[[table]]`) in the text,
    /// 0 when there is none.
    pub fn line_of_header(&self, table: &str) -> usize {
        self.text
            .lines()
            .position(|l| {
                let t = l.trim().trim_start_matches('[');
                t.strip_prefix(table)
                    .is_some_and(|rest| rest.trim_start().starts_with(']'))
            })
            .map_or(0, |n| n + 1)
    }

    /// A [`ConfigError::Referenced`] for an error in a file that `key =
    /// value` at `line` points to.
    pub fn referenced(
        &self,
        line: usize,
        key: &str,
        value: &str,
        cause: ConfigError,
    ) -> ConfigError {
        ConfigError::Referenced {
            source: self.source.to_string(),
            line,
            key: key.to_string(),
            value: value.to_string(),
            cause: Box::new(cause),
        }
    }

    /// 1-based line of a spanned value.
    pub fn line_of<T>(&self, spanned: &Spanned<T>) -> usize {
        let start = spanned.span().start.min(self.text.len());
        self.text[..start].matches('\n').count() + 1
    }

    /// An [`ConfigError::Invalid`] for `key` at `line`.
    pub fn invalid(&self, line: usize, key: &str, value: String, expected: &str) -> ConfigError {
        ConfigError::Invalid {
            source: self.source.to_string(),
            line,
            key: key.to_string(),
            value,
            expected: expected.to_string(),
        }
    }

    /// A one-line text (a title: it heads every CSV, PNG and VTU the run
    /// writes), or an error naming `key` when it holds a line break or
    /// another control character.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`].
    pub fn one_line(&self, v: &Spanned<String>, key: &str) -> Result<String, ConfigError> {
        let text = v.get_ref();
        if text.chars().any(char::is_control) {
            Err(self.invalid(
                self.line_of(v),
                key,
                format!("{text:?}"),
                "one line of text without control characters (it heads every output file)",
            ))
        } else {
            Ok(text.clone())
        }
    }

    /// The value if it is finite and `ok` accepts it, else an error naming
    /// `key` and `expected`.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`].
    pub fn range(
        &self,
        v: &Spanned<f64>,
        key: &str,
        ok: impl Fn(f64) -> bool,
        expected: &str,
    ) -> Result<f64, ConfigError> {
        let x = *v.get_ref();
        if x.is_finite() && ok(x) {
            Ok(x)
        } else {
            Err(self.invalid(self.line_of(v), key, readable_number(x), expected))
        }
    }

    /// An integer key in `range`, as a count, or an error naming the range
    /// (`a count in 1..=100000`).
    ///
    /// # Errors
    /// [`ConfigError::Invalid`].
    pub fn count(
        &self,
        v: &Spanned<i64>,
        key: &str,
        range: std::ops::RangeInclusive<i64>,
    ) -> Result<usize, ConfigError> {
        let n = *v.get_ref();
        if range.contains(&n) {
            Ok(n as usize)
        } else {
            Err(self.invalid(
                self.line_of(v),
                key,
                n.to_string(),
                &format!("a count in {}..={}", range.start(), range.end()),
            ))
        }
    }

    /// The value of a key that names one of `options`, or an error listing
    /// them (`"a", "b" or "c"`).
    ///
    /// # Errors
    /// [`ConfigError::Invalid`].
    pub fn choice<T: Copy>(
        &self,
        v: &Spanned<String>,
        key: &str,
        options: &[(&str, T)],
    ) -> Result<T, ConfigError> {
        if let Some((_, value)) = options.iter().find(|(name, _)| name == v.get_ref()) {
            return Ok(*value);
        }
        let names: Vec<String> = options.iter().map(|(n, _)| format!("\"{n}\"")).collect();
        let expected = match names.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
            _ => names.join(""),
        };
        Err(self.invalid(
            self.line_of(v),
            key,
            format!("\"{}\"", v.get_ref()),
            &expected,
        ))
    }

    /// A missing key or table.
    pub fn missing(&self, key: &str, expected: &str) -> ConfigError {
        self.invalid(0, key, "(missing)".to_string(), expected)
    }
}

/// The text of a TOML file read as `bytes`, or an error naming the file
/// and the line of the first byte that is not UTF-8.
///
/// # Errors
/// [`ConfigError::Syntax`].
pub fn utf8_text(bytes: Vec<u8>, source: &str) -> Result<String, ConfigError> {
    String::from_utf8(bytes).map_err(|e| {
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = valid.iter().filter(|&&b| b == b'\n').count() + 1;
        let column = valid.len() - valid.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1) + 1;
        ConfigError::Syntax {
            source: source.to_string(),
            message: format!(
                "line {line}, byte {column}: not UTF-8 text; expected a TOML file (UTF-8)"
            ),
        }
    })
}

/// Reads a case file: its text, its name for messages and the folder its
/// relative paths are taken from.
///
/// # Errors
/// [`ConfigError::NotFound`] for an unreadable file.
pub fn read_case_file(
    path: &std::path::Path,
) -> Result<(String, String, std::path::PathBuf), ConfigError> {
    let bytes = std::fs::read(path).map_err(|e| ConfigError::NotFound {
        requested: format!("case file '{}'", path.display()),
        reason: e.to_string(),
    })?;
    let text = utf8_text(bytes, &path.display().to_string())?;
    let base = path
        .parent()
        .unwrap_or(std::path::Path::new("."))
        .to_path_buf();
    Ok((text, path.display().to_string(), base))
}

/// `x` rounded to `digits` significant digits, for a computed value in a
/// message (an enclosed volume of `-1000.0000000000001` mm³ reads `-1000`).
pub fn significant(x: f64, digits: usize) -> f64 {
    if !x.is_finite() || x == 0.0 {
        return x;
    }
    format!("{x:.*e}", digits.saturating_sub(1))
        .parse()
        .unwrap_or(x)
}

/// A number as a reader wants it in a message: plain between 1e-4 and 1e15
/// in magnitude (`0.25`, `80`), in exponent form outside (`1e-9`, `1e300`)
/// rather than hundreds of digits; `nan` and `inf` as TOML spells them.
pub fn readable_number(x: f64) -> String {
    if x.is_nan() {
        "nan".into()
    } else if x.is_infinite() {
        if x > 0.0 { "inf".into() } else { "-inf".into() }
    } else if x == 0.0 || (1e-4..1e15).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}
