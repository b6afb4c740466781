//! The shared part of the fuzz harnesses (`tests/fuzz_readers.rs`,
//! `tests/fuzz_solvers.rs`; `docs/fuzzing.md`): a deterministic mutator
//! over the bytes of real inputs, the mutant counts (raised by
//! `NCFORM_FUZZ_CASES`), and a guard that runs one input in its own thread
//! with a panic catcher and a time bound.

#![allow(dead_code)]

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::mpsc;
use std::time::Duration;

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// Values that replace a numeric token: the extremes of `f64` and of the
/// integer types, signed zeros, non-finite spellings, huge digit strings.
pub const EXTREMES: &[&str] = &[
    "1e308",
    "-1e308",
    "1.8e308",
    "1e-308",
    "5e-324",
    "0",
    "-0",
    "0.0",
    "-0.0",
    "nan",
    "inf",
    "-inf",
    "NaN",
    "4294967296",
    "18446744073709551616",
    "9223372036854775807",
    "-9223372036854775808",
    "-1",
    "1e-9",
    "1e9",
    "1e400",
    "100000000000000000000000000000000000000000000000000000000000000000000000000000000",
];

/// Strings that replace a quoted string's contents.
pub const STRINGS: &[&[u8]] = &[b"", b"a\nb", b"\xff\xfe", b"\"", b"\\", b"x\r\ny", b"\0"];

/// Mutants per reader: `NCFORM_FUZZ_CASES` if set (the long campaign),
/// else `default` (the bounded run of `cargo test`).
pub fn cases(default: usize) -> usize {
    std::env::var("NCFORM_FUZZ_CASES")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(default)
}

/// Mutants per solver seed: `NCFORM_FUZZ_CASES / divisor` if set (a run
/// costs some tens of reads, so one variable sizes both harnesses of a
/// campaign), else `default`.
pub fn cases_scaled(default: usize, divisor: usize) -> usize {
    std::env::var("NCFORM_FUZZ_CASES")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .map_or(default, |n| (n / divisor).max(1))
}

/// The base seed: `NCFORM_FUZZ_SEED` if set, else a fixed one (so the
/// bounded run is the same every time).
pub fn base_seed() -> u64 {
    std::env::var("NCFORM_FUZZ_SEED")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(20_241_231)
}

/// Byte ranges of the numeric tokens of `text`: an optional sign, digits
/// with an optional fraction and exponent, not inside a word.
pub fn numeric_tokens(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    let word = |b: u8| b.is_ascii_alphanumeric() || b == b'_';
    while i < text.len() {
        let start = i;
        let prev_word = start > 0 && (word(text[start - 1]) || text[start - 1] == b'.');
        let mut j = i;
        if j < text.len() && (text[j] == b'-' || text[j] == b'+') {
            j += 1;
        }
        let digits = j;
        while j < text.len() && (text[j].is_ascii_digit() || text[j] == b'.') {
            j += 1;
        }
        if j > digits && text[digits..j].iter().any(u8::is_ascii_digit) && !prev_word {
            if j < text.len() && (text[j] == b'e' || text[j] == b'E') {
                let mut k = j + 1;
                if k < text.len() && (text[k] == b'-' || text[k] == b'+') {
                    k += 1;
                }
                let exp = k;
                while k < text.len() && text[k].is_ascii_digit() {
                    k += 1;
                }
                if k > exp {
                    j = k;
                }
            }
            if j >= text.len() || !word(text[j]) {
                out.push((start, j));
            }
            i = j.max(start + 1);
        } else {
            i = start + 1;
        }
    }
    out
}

/// Byte ranges of the contents of the `"…"` strings of `text` (one line).
pub fn string_tokens(text: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut open: Option<usize> = None;
    for (i, &b) in text.iter().enumerate() {
        match (b, open) {
            (b'"', None) => open = Some(i + 1),
            (b'"', Some(s)) => {
                out.push((s, i));
                open = None;
            }
            (b'\n', Some(_)) => open = None,
            _ => {}
        }
    }
    out
}

/// The mutation operators (`docs/fuzzing.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Operator {
    /// One byte replaced by a random byte.
    ByteFlip,
    /// The input cut at a random byte.
    Truncate,
    /// One line removed.
    DeleteLine,
    /// One line repeated.
    DuplicateLine,
    /// One numeric token replaced by one of [`EXTREMES`].
    ExtremeNumber,
    /// One quoted string's contents replaced by one of [`STRINGS`].
    OddString,
    /// The value of one TOML `key = value` line replaced by a value of
    /// another type ([`wrong_type`]): a number where a string, array or
    /// table is expected and the other way round, an integer where a float
    /// is, a float where an integer is, a bool.
    WrongType,
    /// One TOML `key = value` line moved under another table header (or to
    /// the top level), where the key may not apply.
    MoveKey,
    /// One numeric token multiplied by one of [`SCALES`] (an integer stays
    /// an integer): values the readers accept, far from the seed's, that
    /// reach the solvers more often than [`EXTREMES`] do.
    ScaleNumber,
}

/// Factors of [`Operator::ScaleNumber`].
pub const SCALES: &[f64] = &[1e-6, 1e-3, 0.1, 0.5, 2.0, 10.0, 1e3, 1e6, -1.0, 0.0];

fn lines(input: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = 0;
    for (i, &b) in input.iter().enumerate() {
        if b == b'\n' {
            out.push((start, i + 1));
            start = i + 1;
        }
    }
    if start < input.len() {
        out.push((start, input.len()));
    }
    out
}

fn splice(input: &[u8], (s, e): (usize, usize), with: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(input.len() + with.len());
    out.extend_from_slice(&input[..s]);
    out.extend_from_slice(with);
    out.extend_from_slice(&input[e..]);
    out
}

/// Applies `op` once (or returns the input unchanged if it has nothing
/// to apply it to).
pub fn apply(input: &[u8], op: Operator, rng: &mut StdRng) -> Vec<u8> {
    if input.is_empty() {
        return input.to_vec();
    }
    match op {
        Operator::ByteFlip => {
            let mut out = input.to_vec();
            let i = rng.random_range(0..out.len());
            out[i] = rng.random::<u8>();
            out
        }
        Operator::Truncate => input[..rng.random_range(0..input.len())].to_vec(),
        Operator::DeleteLine | Operator::DuplicateLine => {
            let l = lines(input);
            let (s, e) = l[rng.random_range(0..l.len())];
            if op == Operator::DeleteLine {
                splice(input, (s, e), b"")
            } else {
                let mut with = input[s..e].to_vec();
                if !with.ends_with(b"\n") {
                    with.push(b'\n');
                }
                with.extend_from_slice(&input[s..e]);
                splice(input, (s, e), &with)
            }
        }
        Operator::ExtremeNumber => {
            let t = numeric_tokens(input);
            if t.is_empty() {
                return input.to_vec();
            }
            let span = t[rng.random_range(0..t.len())];
            let with = EXTREMES[rng.random_range(0..EXTREMES.len())];
            splice(input, span, with.as_bytes())
        }
        Operator::OddString => {
            let t = string_tokens(input);
            if t.is_empty() {
                return input.to_vec();
            }
            let span = t[rng.random_range(0..t.len())];
            let with = STRINGS[rng.random_range(0..STRINGS.len())];
            splice(input, span, with)
        }
        Operator::ScaleNumber => {
            let t = numeric_tokens(input);
            if t.is_empty() {
                return input.to_vec();
            }
            let span = t[rng.random_range(0..t.len())];
            let token = String::from_utf8_lossy(&input[span.0..span.1]).into_owned();
            let factor = SCALES[rng.random_range(0..SCALES.len())];
            let with = match (token.parse::<i64>(), token.parse::<f64>()) {
                (Ok(i), _) => format!("{}", ((i as f64) * factor).round() as i64),
                (_, Ok(x)) => format!("{:e}", x * factor),
                _ => token,
            };
            splice(input, span, with.as_bytes())
        }
        Operator::WrongType => {
            let kv = key_values(input);
            if kv.is_empty() {
                return input.to_vec();
            }
            let (_, span) = &kv[rng.random_range(0..kv.len())];
            let value = String::from_utf8_lossy(&input[span.0..span.1]).into_owned();
            let choices = wrong_type(&value);
            let with = &choices[rng.random_range(0..choices.len())];
            splice(input, *span, with.as_bytes())
        }
        Operator::MoveKey => {
            let kv = key_values(input);
            if kv.is_empty() {
                return input.to_vec();
            }
            let (line, _) = kv[rng.random_range(0..kv.len())];
            let mut moved = input[line.0..line.1].to_vec();
            if !moved.ends_with(b"\n") {
                moved.push(b'\n');
            }
            let rest = splice(input, line, b"");
            // After a table header of what is left, or at the top.
            let headers: Vec<usize> = lines(&rest)
                .into_iter()
                .filter(|&(s, _)| {
                    rest[s..].iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'[')
                })
                .map(|(_, e)| e)
                .collect();
            let at = match rng.random_range(0..=headers.len()) {
                0 => 0,
                i => headers[i - 1],
            };
            let mut rest = rest;
            if at == rest.len() && !rest.is_empty() && !rest.ends_with(b"\n") {
                rest.push(b'\n');
            }
            let at = at.min(rest.len());
            splice(&rest, (at, at), &moved)
        }
    }
}

/// The `key = value` lines of TOML text, outside comments and table
/// headers: each line's byte range (with its newline) and its value's
/// (up to an unquoted `#`, trimmed).
pub fn key_values(text: &[u8]) -> Vec<((usize, usize), (usize, usize))> {
    let mut out = Vec::new();
    for (s, e) in lines(text) {
        let line = &text[s..e];
        let Some(first) = line.iter().position(|b| !b.is_ascii_whitespace()) else {
            continue;
        };
        if matches!(line[first], b'#' | b'[') {
            continue;
        }
        let Some(eq) = line.iter().position(|&b| b == b'=') else {
            continue;
        };
        let key = &line[first..eq];
        if key.is_empty() || key.iter().any(|&b| b == b'"' || b == b'\'') {
            continue;
        }
        let mut vs = eq + 1;
        while vs < line.len() && (line[vs] == b' ' || line[vs] == b'\t') {
            vs += 1;
        }
        let mut ve = vs;
        let mut quoted = false;
        while ve < line.len() && line[ve] != b'\n' && line[ve] != b'\r' {
            match line[ve] {
                b'"' => quoted = !quoted,
                b'#' if !quoted => break,
                _ => {}
            }
            ve += 1;
        }
        while ve > vs && line[ve - 1].is_ascii_whitespace() {
            ve -= 1;
        }
        if ve > vs {
            out.push(((s, e), (s + vs, s + ve)));
        }
    }
    out
}

/// Values of another type than the TOML value `value`: for a string a
/// number, a bool, an array, a table; for an integer its float spelling,
/// a fraction, a string, an array; for a float its integer (rounded), a
/// string, a bool, an array; for a bool a number or a string; for an array
/// a scalar, a string, an empty, short, long or nested array, an array of
/// strings, a table; for an inline table a number, a string, an array.
pub fn wrong_type(value: &str) -> Vec<String> {
    let v = value.trim();
    let quoted = format!("\"{}\"", v.replace(['"', '\\'], ""));
    if v.starts_with('"') || v.starts_with('\'') {
        return [
            "3",
            "3.5",
            "true",
            "[\"a\", \"b\"]",
            "[1.0, 2.0]",
            "{ a = 1 }",
        ]
        .map(String::from)
        .to_vec();
    }
    if v.starts_with('[') {
        let inner = v.trim_start_matches('[').trim_end_matches(']');
        let first = inner.split(',').next().unwrap_or("1").trim();
        let first = if first.is_empty() { "1" } else { first };
        return vec![
            first.to_string(),
            quoted,
            "[]".into(),
            format!("[{first}]"),
            format!("[{first}, {first}, {first}, {first}]"),
            format!("[{v}]"),
            "[\"x\", \"y\", \"z\"]".into(),
            format!("{{ x = {first} }}"),
        ];
    }
    if v.starts_with('{') {
        return ["1.0", "\"x\"", "[1.0]"].map(String::from).to_vec();
    }
    if v == "true" || v == "false" {
        return ["1", "0.0", "\"true\"", "[true]"]
            .map(String::from)
            .to_vec();
    }
    if let Ok(i) = v.parse::<i64>() {
        return vec![
            format!("{i}.0"),
            format!("{i}.5"),
            quoted,
            "true".into(),
            format!("[{i}]"),
            "{}".into(),
        ];
    }
    if let Ok(x) = v.parse::<f64>() {
        let int = if x.is_finite() && x.abs() < 9e18 {
            format!("{}", x.round() as i64)
        } else {
            "1".into()
        };
        return vec![
            int,
            quoted,
            "false".into(),
            format!("[{v}, {v}]"),
            format!("{{ x = {v} }}"),
        ];
    }
    ["1.0", "true", "[]", "{}"].map(String::from).to_vec()
}

/// All operators, for drawing.
pub const OPERATORS: [Operator; 9] = [
    Operator::ByteFlip,
    Operator::Truncate,
    Operator::DeleteLine,
    Operator::DuplicateLine,
    Operator::ExtremeNumber,
    Operator::OddString,
    Operator::WrongType,
    Operator::MoveKey,
    Operator::ScaleNumber,
];

/// A mutant of `input`: one to three operators, numeric replacement drawn
/// three times as often as the others (values are what the readers check
/// most). `weights` may restrict the draw (e.g. numbers only).
pub fn mutate(input: &[u8], rng: &mut StdRng, numbers_only: bool) -> (Vec<u8>, Vec<Operator>) {
    let n = rng.random_range(1..=3);
    let mut out = input.to_vec();
    let mut ops = Vec::new();
    for _ in 0..n {
        let op = if numbers_only {
            Operator::ExtremeNumber
        } else {
            match rng.random_range(0..8) {
                0 => Operator::ByteFlip,
                1 => Operator::Truncate,
                2 => Operator::DeleteLine,
                3 => Operator::DuplicateLine,
                4 => Operator::OddString,
                _ => Operator::ExtremeNumber,
            }
        };
        out = apply(&out, op, rng);
        ops.push(op);
    }
    (out, ops)
}

/// A mutant of TOML text: one to three operators drawn as by [`mutate`],
/// with [`Operator::WrongType`] and [`Operator::MoveKey`] among them (a
/// fifth of the draws each; numeric replacement still the most frequent).
pub fn mutate_toml(input: &[u8], rng: &mut StdRng) -> (Vec<u8>, Vec<Operator>) {
    let n = rng.random_range(1..=3);
    let mut out = input.to_vec();
    let mut ops = Vec::new();
    for _ in 0..n {
        let op = match rng.random_range(0..10) {
            0 => Operator::ByteFlip,
            1 => Operator::Truncate,
            2 => Operator::DeleteLine,
            3 => Operator::DuplicateLine,
            4 => Operator::OddString,
            5 | 6 => Operator::WrongType,
            7 => Operator::MoveKey,
            _ => Operator::ExtremeNumber,
        };
        out = apply(&out, op, rng);
        ops.push(op);
    }
    (out, ops)
}

/// A mutant of TOML text with values of the wrong type, keys moved to
/// other tables and scaled numbers only ([`Operator::WrongType`],
/// [`Operator::MoveKey`], [`Operator::ScaleNumber`], one or two of them):
/// text that stays TOML more often than [`mutate_toml`]'s and reaches the
/// readers' type and key checks.
pub fn mutate_types(input: &[u8], rng: &mut StdRng) -> (Vec<u8>, Vec<Operator>) {
    let n = rng.random_range(1..=2);
    let mut out = input.to_vec();
    let mut ops = Vec::new();
    for _ in 0..n {
        let op = match rng.random_range(0..5) {
            0 | 1 => Operator::WrongType,
            2 => Operator::MoveKey,
            _ => Operator::ScaleNumber,
        };
        out = apply(&out, op, rng);
        ops.push(op);
    }
    (out, ops)
}

/// A generator for mutant `k` of reader `reader` (independent streams, so
/// a failure is reproduced from its reader name and number alone).
pub fn rng_for(reader: &str, k: usize) -> StdRng {
    let mut h = base_seed();
    for b in reader.bytes() {
        h = h.wrapping_mul(0x100_0000_01b3).wrapping_add(u64::from(b));
    }
    StdRng::seed_from_u64(h ^ (k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15))
}

/// The name of the threads [`guarded`] runs inputs in.
const FUZZ_THREAD: &str = "fuzz";

/// Runs `f` in its own thread, catching a panic, and waits at most
/// `bound`. `Err` says what went wrong (the panic's message, or that the
/// bound passed; the thread is then left running detached).
pub fn guarded<T: Send + 'static>(
    bound: Duration,
    f: impl FnOnce() -> T + Send + 'static,
) -> Result<T, String> {
    let (tx, rx) = mpsc::channel();
    std::thread::Builder::new()
        .name(FUZZ_THREAD.to_string())
        .stack_size(64 << 20)
        .spawn(move || {
            let result = catch_unwind(AssertUnwindSafe(f)).map_err(|payload| {
                payload
                    .downcast_ref::<&str>()
                    .map(|s| s.to_string())
                    .or_else(|| payload.downcast_ref::<String>().cloned())
                    .unwrap_or_else(|| "(non-string panic payload)".to_string())
            });
            let _ = tx.send(result);
        })
        .expect("spawn a fuzz thread");
    match rx.recv_timeout(bound) {
        Ok(Ok(value)) => Ok(value),
        Ok(Err(panic)) => Err(format!("panicked: {panic}")),
        Err(_) => Err(format!("did not finish within {bound:?}")),
    }
}

/// Quiets the default panic hook's report for the fuzz threads (their
/// panics are caught and reported by the test; `NCFORM_FUZZ_VERBOSE`
/// shows them), once.
pub fn quiet_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let fuzz = std::thread::current().name() == Some(FUZZ_THREAD);
            if !fuzz || std::env::var_os("NCFORM_FUZZ_VERBOSE").is_some() {
                default(info);
            }
        }));
    });
}

/// The text of a mutant for a failure report: lossy UTF-8, at most 4 kB.
pub fn show(bytes: &[u8]) -> String {
    let text = String::from_utf8_lossy(bytes);
    clip(&text, 4000)
}

/// `text` cut to about `max` bytes.
pub fn clip(text: &str, max: usize) -> String {
    if text.len() > max {
        let mut end = max;
        while !text.is_char_boundary(end) {
            end -= 1;
        }
        format!("{}… ({} bytes)", &text[..end], text.len())
    } else {
        text.to_string()
    }
}

/// Whether `text` shows a non-finite number as Rust's `Debug` or JSON
/// writes it (`NaN`, `inf`, or JSON's `null` for either).
pub fn has_non_finite(text: &str) -> bool {
    non_finite_at(text).is_some()
}

/// The first non-finite number of `text` (see [`has_non_finite`]) with up
/// to 80 bytes before it, to name the field.
pub fn non_finite_at(text: &str) -> Option<String> {
    let at = |w: &str| {
        text.match_indices(w).find_map(|(i, _)| {
            let before = text[..i].chars().next_back();
            let after = text[i + w.len()..].chars().next();
            let alone = !before.is_some_and(|c| c.is_alphanumeric() || c == '_')
                && !after.is_some_and(|c| c.is_alphanumeric() || c == '_');
            alone.then_some(i)
        })
    };
    let i = match (at("NaN"), at("inf")) {
        (Some(a), Some(b)) => a.min(b),
        (a, b) => a.or(b)?,
    };
    let mut start = i.saturating_sub(80);
    while !text.is_char_boundary(start) {
        start -= 1;
    }
    Some(format!("…{}", &text[start..(i + 3).min(text.len())]))
}

/// A number in `msg` written out in full rather than short — 30 or more
/// digits (`1e300` as 301 digits, `5e-324` as 326) or 20 or more
/// significant ones (a shortest round-trip `f64` has at most 17) — that
/// `input` does not hold (a number quoted from the input stays as it was
/// written).
pub fn long_number(msg: &str, input: &[u8]) -> Option<String> {
    let bytes = msg.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_digit() {
            let start = i;
            while i < bytes.len() && (bytes[i].is_ascii_digit() || bytes[i] == b'.') {
                i += 1;
            }
            let run = &bytes[start..i];
            let digits: Vec<u8> = run.iter().copied().filter(u8::is_ascii_digit).collect();
            let significant = digits.iter().skip_while(|&&d| d == b'0').count();
            let long = digits.len() >= 30 || significant >= 20;
            if long && !input.windows(run.len()).any(|w| w == run) {
                return Some(String::from_utf8_lossy(run).into_owned());
            }
        } else {
            i += 1;
        }
    }
    None
}

/// `Debug` text split into its strings' contents (one a line) and the
/// rest (its numbers and names, each string left as `""`).
fn split_debug(debug: &str) -> (String, String) {
    let (mut strings, mut rest) = (String::new(), String::with_capacity(debug.len()));
    let (mut in_string, mut escaped) = (false, false);
    for c in debug.chars() {
        match (in_string, escaped, c) {
            (true, true, c) => {
                escaped = false;
                strings.push(c);
            }
            (true, false, '\\') => escaped = true,
            (true, false, '"') => {
                in_string = false;
                strings.push('\n');
                rest.push('"');
            }
            (false, _, '"') => {
                in_string = true;
                rest.push('"');
            }
            (true, false, c) => strings.push(c),
            (false, _, c) => rest.push(c),
        }
    }
    (strings, rest)
}

/// The contents of the `"…"` strings of `Debug` text, one a line: the
/// messages, names and reasons of a value, without its numbers.
pub fn debug_strings(debug: &str) -> String {
    split_debug(debug).0
}

/// The first non-finite number in the `Debug` text of what a reader or a
/// run returned, outside its strings (a title may say "NaN"), other than
/// the laws' derived `x_t` (the onset of a transition, infinite by design
/// for a term without one).
pub fn accepted_non_finite(debug: &str) -> Option<String> {
    non_finite_at(&split_debug(debug).1.replace("x_t: inf", "x_t: (none)"))
}

/// One mutant of a reader that broke a property.
#[derive(Debug)]
pub struct Failure {
    /// The reader.
    pub reader: String,
    /// The mutant's number (reproduce with the same seed).
    pub case: usize,
    /// The operators applied.
    pub operators: Vec<Operator>,
    /// What went wrong.
    pub what: String,
    /// The mutant (lossy text).
    pub input: String,
}

/// Panics with a report of the first failures, if any.
pub fn report(failures: &[Failure], total: usize) {
    if failures.is_empty() {
        return;
    }
    let mut msg = format!(
        "{} of {total} mutants broke a property (seed {}):\n",
        failures.len(),
        base_seed()
    );
    for f in failures.iter().take(8) {
        msg.push_str(&format!(
            "--- {} #{} {:?}: {}\n{}\n",
            f.reader,
            f.case,
            f.operators,
            clip(&f.what, 6000),
            f.input
        ));
    }
    panic!("{msg}");
}

// ------------------------------------------------------------ known defects

/// A defect the harness found that is not fixed yet: a failure of
/// property `class` whose description holds `needle` is reported (with
/// `NCFORM_FUZZ_VERBOSE`, each) but does not fail the test. The integrator
/// removes an entry once its fix is merged (`docs/fuzzing.md`, "Open").
pub struct Known {
    /// The defect's name.
    pub name: &'static str,
    /// The property that fails.
    pub class: &'static str,
    /// Text the failure's description holds.
    pub needle: &'static str,
}

/// The allow-list of known defects (`docs/fuzzing.md`, "Known defects"):
/// empty. An entry lets the bounded run pass on a defect found and named
/// while its fix is under way; the classes found when the forming cases
/// joined the harness (`null` in `summary.json`, numbers written out in
/// full in messages, keys accepted without a word where they do not apply)
/// are fixed at their root.
pub const FUZZ_KNOWN: &[Known] = &[];

/// The [`FUZZ_KNOWN`] entry a failure of property `class` described by
/// `detail` matches, if any.
pub fn known(class: &str, detail: &str) -> Option<&'static str> {
    FUZZ_KNOWN
        .iter()
        .find(|e| e.class == class && detail.contains(e.needle))
        .map(|e| e.name)
}

// ------------------------------------------------------------ tool meshes

/// The corners and outward faces of a unit cube (the seed tool mesh).
pub fn cube() -> (Vec<[f32; 3]>, Vec<[usize; 3]>) {
    let v: Vec<[f32; 3]> = (0..8)
        .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let t = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (v, t)
}

/// The cube of [`cube`], scaled by `scale` and moved by `shift`, as a
/// binary STL.
pub fn binary_stl_of(scale: f32, shift: [f32; 3]) -> Vec<u8> {
    let (v, t) = cube();
    let mut out = vec![0u8; 80];
    out.extend_from_slice(&(t.len() as u32).to_le_bytes());
    for tri in &t {
        out.extend_from_slice(&[0u8; 12]);
        for &i in tri {
            for (c, s) in v[i].iter().zip(shift) {
                out.extend_from_slice(&(c * scale + s).to_le_bytes());
            }
        }
        out.extend_from_slice(&[0u8; 2]);
    }
    out
}

/// The unit cube as a binary STL.
pub fn binary_stl() -> Vec<u8> {
    binary_stl_of(1.0, [0.0; 3])
}

/// The unit cube as an ASCII STL.
pub fn ascii_stl() -> Vec<u8> {
    let (v, t) = cube();
    let mut out = String::from("solid cube\n");
    for tri in &t {
        out.push_str("  facet normal 0 0 0\n    outer loop\n");
        for &i in tri {
            out.push_str(&format!(
                "      vertex {} {} {}\n",
                v[i][0], v[i][1], v[i][2]
            ));
        }
        out.push_str("    endloop\n  endfacet\n");
    }
    out.push_str("endsolid cube\n");
    out.into_bytes()
}

/// The unit cube as an OBJ.
pub fn obj() -> Vec<u8> {
    let (v, t) = cube();
    let mut out = String::from("# unit cube\no cube\n");
    for p in &v {
        out.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
    }
    for tri in &t {
        out.push_str(&format!("f {} {} {}\n", tri[0] + 1, tri[1] + 1, tri[2] + 1));
    }
    out.into_bytes()
}

// ------------------------------------------------------ run-folder checks

/// One property of a run folder that does not hold: its class (what a
/// `FUZZ_KNOWN` entry names) and where and what.
#[derive(Debug, Clone)]
pub struct FolderProblem {
    /// The property: `status-missing`, `status-disagrees`, `stray-partial`,
    /// `empty-file`, `json-unparsable`, `json-null`, `csv-no-header`,
    /// `csv-ragged`, `csv-non-finite`, `xml-unclosed`, `vtu-non-finite`,
    /// `png-truncated`, `manifest`, `summary-missing`,
    /// `summary-disagrees`.
    pub class: &'static str,
    /// The file (relative to the folder) and what is wrong.
    pub detail: String,
}

impl std::fmt::Display for FolderProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "[{}] {}", self.class, self.detail)
    }
}

/// Whether a CSV or VTU cell is a non-finite number or JSON's `null`:
/// `NaN`, `nan`, `inf`, `-inf`, `infinity`, `null` in any case.
pub fn non_finite_cell(cell: &str) -> bool {
    let c = cell.trim().trim_matches('"');
    c.eq_ignore_ascii_case("null") || c.parse::<f64>().is_ok_and(|x| !x.is_finite())
}

/// Every `null` in a JSON value, by its path (`$.forming.states[2].gamma`).
fn json_nulls(v: &serde_json::Value, path: &str, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Null => out.push(path.to_string()),
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                json_nulls(x, &format!("{path}[{i}]"), out);
            }
        }
        serde_json::Value::Object(o) => {
            for (k, x) in o {
                json_nulls(x, &format!("{path}.{k}"), out);
            }
        }
        _ => {}
    }
}

/// Every file under `dir`, relative paths, sorted.
fn files_under(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else if let Ok(rel) = p.strip_prefix(dir) {
                out.push(rel.to_path_buf());
            }
        }
    }
    out.sort();
    out
}

/// The status `status.json` must give for the exit code `code` of a run:
/// 0 complete, 1 failed, 3 incomplete, 4 interrupted, 5 any of the solve's
/// ends with outputs missing, 101 failed.
fn status_fits(status: &str, code: u64) -> bool {
    matches!(
        (status, code),
        ("complete", 0)
            | ("failed", 1 | 101)
            | ("incomplete", 3)
            | ("interrupted", 4)
            | ("complete" | "incomplete" | "interrupted", 5)
    )
}

/// Checks the run folder `out` of a run whose library entry point
/// returned the exit code `exit_code` (`summary.exit_status.code()`, or 1
/// for an `Err`, `docs/cases.md`, "Exit codes"):
///
/// - bad input (`exit_code` 1) may leave no folder; any other end leaves
///   `status.json`, parsable, no longer `running`, with the same
///   `exit_code` and a `status` that fits it (`complete` 0, `failed` 1,
///   `incomplete` 3, `interrupted` 4, any solve end with outputs missing
///   5), `outputs_complete` true exactly when nothing is `missing`;
/// - the manifest (`files`) lists every file of the folder but
///   `status.json`, each with its size, and nothing else;
/// - no `*.partial` or `*.tmp` file is left;
/// - no empty file under an output's name; every `.json` parses and holds
///   no `null` (serde's spelling of NaN and inf); every `.csv` has a header
///   after its `#` preamble, rows of the header's column count, no cell
///   `NaN`/`inf`/`null`, and ends with a newline; every `.vtu`/`.pvd` ends
///   with `</VTKFile>` and (ASCII) holds no non-finite number; every
///   `.png` has the PNG signature and ends with its `IEND` chunk;
/// - a run that solved (0, 3, 4) has a `summary.json` whose `status`
///   agrees with `status.json`.
///
/// Returns every problem found (empty: the folder is sound).
pub fn check_run_folder(out: &std::path::Path, exit_code: u8) -> Vec<FolderProblem> {
    let mut problems = Vec::new();
    let mut bad = |class: &'static str, detail: String| {
        problems.push(FolderProblem { class, detail });
    };
    if !out.exists() {
        if exit_code != 1 {
            bad(
                "status-missing",
                format!("exit code {exit_code} but no run folder"),
            );
        }
        return problems;
    }
    let files = files_under(out);
    // status.json
    let status: Option<serde_json::Value> = match std::fs::read(out.join("status.json")) {
        Err(e) => {
            bad("status-missing", format!("status.json: {e}"));
            None
        }
        Ok(bytes) => match serde_json::from_slice(&bytes) {
            Err(e) => {
                bad("status-missing", format!("status.json does not parse: {e}"));
                None
            }
            Ok(v) => Some(v),
        },
    };
    if let Some(st) = &status {
        let s = st["status"].as_str().unwrap_or("(none)");
        let code = st["exit_code"].as_u64();
        if st["format"] != "ncform-run-folder-1" {
            bad(
                "status-disagrees",
                format!("status.json format {}", st["format"]),
            );
        }
        if code != Some(u64::from(exit_code)) || !status_fits(s, u64::from(exit_code)) {
            bad(
                "status-disagrees",
                format!(
                    "the run returned exit code {exit_code}; status.json says status {s:?}, exit_code {:?}",
                    code
                ),
            );
        }
        let missing = st["missing"].as_array().map_or(0, Vec::len);
        if st["outputs_complete"].as_bool() != Some(missing == 0) {
            bad(
                "status-disagrees",
                format!(
                    "status.json: outputs_complete {} with {missing} missing",
                    st["outputs_complete"]
                ),
            );
        }
        if (missing > 0) != (exit_code == 5) && exit_code != 1 {
            bad(
                "status-disagrees",
                format!("exit code {exit_code} with {missing} outputs missing"),
            );
        }
        // The manifest.
        let listed: Vec<(String, Option<u64>)> = st["files"]
            .as_array()
            .map(|a| {
                a.iter()
                    .map(|f| {
                        (
                            f["path"].as_str().unwrap_or("").to_string(),
                            f["bytes"].as_u64(),
                        )
                    })
                    .collect()
            })
            .unwrap_or_default();
        for (path, bytes) in &listed {
            match std::fs::metadata(out.join(path)) {
                Err(e) => bad("manifest", format!("{path}: listed but {e}")),
                Ok(m) if Some(m.len()) != *bytes => bad(
                    "manifest",
                    format!("{path}: listed with {bytes:?} bytes, has {}", m.len()),
                ),
                Ok(_) => {}
            }
        }
        for f in &files {
            let rel = f.to_string_lossy().replace('\\', "/");
            if rel != "status.json" && !listed.iter().any(|(p, _)| *p == rel) {
                bad(
                    "manifest",
                    format!("{rel}: in the folder, not in status.json"),
                );
            }
        }
        // The summary, once solved.
        if matches!(exit_code, 0 | 3 | 4) {
            match std::fs::read(out.join("summary.json"))
                .ok()
                .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
            {
                None => bad(
                    "summary-missing",
                    format!("exit code {exit_code} without a readable summary.json"),
                ),
                Some(sum) => {
                    if sum["status"]["status"].as_str() != Some(s) {
                        bad(
                            "summary-disagrees",
                            format!(
                                "summary.json status {} but status.json {s:?}",
                                sum["status"]["status"]
                            ),
                        );
                    }
                }
            }
        }
    }
    for f in &files {
        let rel = f.to_string_lossy().into_owned();
        let name = f.file_name().map(|n| n.to_string_lossy().into_owned());
        let name = name.unwrap_or_default();
        if name.ends_with(".partial") || name.ends_with(".tmp") || name.contains(".partial.") {
            bad("stray-partial", rel.clone());
            continue;
        }
        let Ok(bytes) = std::fs::read(out.join(f)) else {
            bad("manifest", format!("{rel}: unreadable"));
            continue;
        };
        if bytes.is_empty() {
            bad("empty-file", rel.clone());
            continue;
        }
        let ext = f
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("json") => match serde_json::from_slice::<serde_json::Value>(&bytes) {
                Err(e) => bad("json-unparsable", format!("{rel}: {e}")),
                Ok(v) => {
                    let mut nulls = Vec::new();
                    json_nulls(&v, "$", &mut nulls);
                    // One problem a path (at most 5 a file), each
                    // ending in `;` so that an allow-list entry can name
                    // exactly one.
                    for path in nulls.iter().take(5) {
                        bad("json-null", format!("{rel}: null at {path};"));
                    }
                }
            },
            Some("csv") => {
                let text = String::from_utf8_lossy(&bytes);
                if !text.ends_with('\n') {
                    bad("csv-ragged", format!("{rel}: does not end with a newline"));
                }
                let mut rows = text.lines().filter(|l| !l.starts_with('#'));
                match rows.next() {
                    None => bad("csv-no-header", rel.clone()),
                    Some(header) => {
                        let columns = header.split(',').count();
                        if header.split(',').any(|c| c.trim().parse::<f64>().is_ok()) {
                            bad(
                                "csv-no-header",
                                format!("{rel}: header is numbers: {header}"),
                            );
                        }
                        for (i, row) in rows.enumerate() {
                            let cells: Vec<&str> = row.split(',').collect();
                            if cells.len() != columns {
                                bad(
                                    "csv-ragged",
                                    format!(
                                        "{rel}: row {} has {} cells, the header {columns}",
                                        i + 1,
                                        cells.len()
                                    ),
                                );
                                break;
                            }
                            if let Some(c) = cells.iter().position(|c| non_finite_cell(c)) {
                                let col = header.split(',').nth(c).unwrap_or("?");
                                bad(
                                    "csv-non-finite",
                                    format!("{rel}: row {}, column {col:?}: {}", i + 1, cells[c]),
                                );
                                break;
                            }
                        }
                    }
                }
            }
            Some("vtu" | "pvd") => {
                let text = String::from_utf8_lossy(&bytes);
                if !text.trim_end().ends_with("</VTKFile>") {
                    bad(
                        "xml-unclosed",
                        format!("{rel}: does not end with </VTKFile>"),
                    );
                }
                let data = text
                    .lines()
                    .filter(|l| !l.trim_start().starts_with('<'))
                    .flat_map(str::split_whitespace)
                    .find(|t| non_finite_cell(t));
                if let Some(t) = data {
                    bad("vtu-non-finite", format!("{rel}: {t}"));
                }
            }
            Some("png") => {
                let iend = [0x49, 0x45, 0x4e, 0x44, 0xae, 0x42, 0x60, 0x82];
                if !bytes.starts_with(&[0x89, b'P', b'N', b'G']) || !bytes.ends_with(&iend) {
                    bad("png-truncated", rel.clone());
                }
            }
            _ => {}
        }
    }
    problems
}
