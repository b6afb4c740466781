//! CSV files with a commented header that states what the file holds and its
//! units (`# ` lines, read by `pandas.read_csv(..., comment="#")` and
//! `numpy.loadtxt`).

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// One value's field: its shortest round-trip text, or empty when it is
/// not finite.
fn csv_field(v: f64) -> String {
    if v.is_finite() {
        format!("{v:?}")
    } else {
        String::new()
    }
}

/// Writes `rows` under a `# `-commented `preamble` and a header line of
/// `columns` (each naming its unit, e.g. `f6 [MPa]`). Values are written with
/// full `f64` round-trip precision; a value that is not finite (a figure
/// that could not be computed at that state) is an empty field, which
/// `pandas.read_csv` reads as NaN (`docs/cases.md`, "Outputs").
///
/// # Errors
/// I/O errors, or a row whose length differs from `columns`.
pub fn write_csv(
    path: &Path,
    preamble: &[String],
    columns: &[&str],
    rows: &[Vec<f64>],
) -> io::Result<()> {
    let mut out = BufWriter::new(File::create(path)?);
    for line in preamble {
        writeln!(out, "# {line}")?;
    }
    writeln!(out, "{}", columns.join(","))?;
    for row in rows {
        if row.len() != columns.len() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!(
                    "{}: a row has {} values for {} columns",
                    path.display(),
                    row.len(),
                    columns.len()
                ),
            ));
        }
        let line: Vec<String> = row.iter().map(|v| csv_field(*v)).collect();
        writeln!(out, "{}", line.join(","))?;
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A value that is not finite is an empty field: never `NaN` or
    /// `inf`, and the row keeps its column count.
    #[test]
    fn non_finite_values_are_empty_fields() {
        let dir = std::env::temp_dir().join(format!("ncform-csv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("rows.csv");
        let rows = vec![
            vec![1.0, f64::NAN, 0.1],
            vec![f64::INFINITY, -2.5, f64::NEG_INFINITY],
        ];
        write_csv(
            &path,
            &["a test".into()],
            &["a [mm]", "b [N]", "c [-]"],
            &rows,
        )
        .unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines,
            ["# a test", "a [mm],b [N],c [-]", "1.0,,0.1", ",-2.5,"]
        );
    }
}
