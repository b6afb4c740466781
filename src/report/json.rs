//! The JSON text of the run folder's files (`summary.json`,
//! `status.json`), with no `null` standing for a number.
//!
//! The files' schema (`docs/cases.md`, "summary.json"): a figure that does
//! not apply to the run, or that the run never reached (the explicit
//! figures of a quasi-static run, the step range of a run that took no
//! increment), is left out of the file; every number written is finite.
//! The structures written mark their optional figures
//! `skip_serializing_if = "Option::is_none"`, so a `null` could only come
//! from a number that is not finite — `serde_json` writes NaN and ±∞ as
//! `null`. The formatter here writes such a value as the string
//! [`NOT_FINITE`] instead, so the file says what happened, and counts it
//! so the caller can say it on the error stream.

use std::io;

use serde::Serialize;
use serde_json::ser::{Formatter, PrettyFormatter};

/// What stands in the file for a number that was computed as NaN or ±∞.
pub const NOT_FINITE: &str = "not finite: could not be computed";

/// Pretty-printed JSON text of `value`, with every NaN or ±∞ written as
/// the string [`NOT_FINITE`]; with the number of such values.
///
/// # Errors
/// What `serde_json` refuses (a map with non-string keys).
pub fn json_text<T: Serialize + ?Sized>(value: &T) -> Result<(String, usize), serde_json::Error> {
    let mut buffer = Vec::new();
    let mut formatter = FiniteFormatter {
        pretty: PrettyFormatter::new(),
        not_finite: 0,
    };
    let mut serializer = serde_json::Serializer::with_formatter(&mut buffer, &mut formatter);
    value.serialize(&mut serializer)?;
    let not_finite = formatter.not_finite;
    let mut text = String::from_utf8(buffer).map_err(|e| {
        serde_json::Error::io(io::Error::new(io::ErrorKind::InvalidData, e.to_string()))
    })?;
    text.push('\n');
    Ok((text, not_finite))
}

/// `value` without the `null` members of its objects, at every depth: for
/// documents built as [`serde_json::Value`] from structures whose unset
/// options serialise as `null` (the resolved case: an unset key is left
/// out, and the automatic value that `docs/cases.md` gives applies).
pub fn without_nulls(value: serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match value {
        Value::Object(map) => Value::Object(
            map.into_iter()
                .filter(|(_, v)| !v.is_null())
                .map(|(k, v)| (k, without_nulls(v)))
                .collect(),
        ),
        Value::Array(items) => Value::Array(items.into_iter().map(without_nulls).collect()),
        other => other,
    }
}

/// serde_json's pretty formatter, writing `null` as [`NOT_FINITE`].
struct FiniteFormatter {
    pretty: PrettyFormatter<'static>,
    not_finite: usize,
}

impl Formatter for &mut FiniteFormatter {
    fn write_null<W: ?Sized + io::Write>(&mut self, writer: &mut W) -> io::Result<()> {
        self.not_finite += 1;
        write!(writer, "\"{NOT_FINITE}\"")
    }

    fn begin_array<W: ?Sized + io::Write>(&mut self, writer: &mut W) -> io::Result<()> {
        self.pretty.begin_array(writer)
    }

    fn end_array<W: ?Sized + io::Write>(&mut self, writer: &mut W) -> io::Result<()> {
        self.pretty.end_array(writer)
    }

    fn begin_array_value<W: ?Sized + io::Write>(
        &mut self,
        writer: &mut W,
        first: bool,
    ) -> io::Result<()> {
        self.pretty.begin_array_value(writer, first)
    }

    fn end_array_value<W: ?Sized + io::Write>(&mut self, writer: &mut W) -> io::Result<()> {
        self.pretty.end_array_value(writer)
    }

    fn begin_object<W: ?Sized + io::Write>(&mut self, writer: &mut W) -> io::Result<()> {
        self.pretty.begin_object(writer)
    }

    fn end_object<W: ?Sized + io::Write>(&mut self, writer: &mut W) -> io::Result<()> {
        self.pretty.end_object(writer)
    }

    fn begin_object_key<W: ?Sized + io::Write>(
        &mut self,
        writer: &mut W,
        first: bool,
    ) -> io::Result<()> {
        self.pretty.begin_object_key(writer, first)
    }

    fn begin_object_value<W: ?Sized + io::Write>(&mut self, writer: &mut W) -> io::Result<()> {
        self.pretty.begin_object_value(writer)
    }

    fn end_object_value<W: ?Sized + io::Write>(&mut self, writer: &mut W) -> io::Result<()> {
        self.pretty.end_object_value(writer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Figures {
        finite: f64,
        nan: f64,
        infinite: [f64; 2],
        #[serde(skip_serializing_if = "Option::is_none")]
        absent: Option<f64>,
    }

    /// NaN and ±∞ become the documented string, each counted; an absent
    /// figure is left out; the text is the pretty printer's otherwise.
    #[test]
    fn non_finite_numbers_are_named_not_null() {
        let figures = Figures {
            finite: 1.5,
            nan: f64::NAN,
            infinite: [f64::INFINITY, f64::NEG_INFINITY],
            absent: None,
        };
        let (text, count) = json_text(&figures).unwrap();
        assert_eq!(count, 3);
        assert!(!text.contains("null"), "{text}");
        assert!(!text.contains("absent"), "{text}");
        let parsed: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(parsed["finite"], 1.5);
        assert_eq!(parsed["nan"], NOT_FINITE);
        assert_eq!(parsed["infinite"][1], NOT_FINITE);
        let finite_only = Figures {
            finite: 1.5,
            nan: 2.0,
            infinite: [3.0, 4.0],
            absent: Some(5.0),
        };
        let (text, count) = json_text(&finite_only).unwrap();
        assert_eq!(count, 0);
        assert_eq!(
            text,
            serde_json::to_string_pretty(&finite_only).unwrap() + "\n"
        );
    }
}
