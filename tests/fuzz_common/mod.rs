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
}

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
    }
}

/// All operators, for drawing.
pub const OPERATORS: [Operator; 6] = [
    Operator::ByteFlip,
    Operator::Truncate,
    Operator::DeleteLine,
    Operator::DuplicateLine,
    Operator::ExtremeNumber,
    Operator::OddString,
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
