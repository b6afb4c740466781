//! CSV files with a commented header that states what the file holds and its
//! units (`# ` lines, read by `pandas.read_csv(..., comment="#")` and
//! `numpy.loadtxt`).

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// Writes `rows` under a `# `-commented `preamble` and a header line of
/// `columns` (each naming its unit, e.g. `f6 [MPa]`). Values are written with
/// full `f64` round-trip precision.
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
        let line: Vec<String> = row.iter().map(|v| format!("{v:?}")).collect();
        writeln!(out, "{}", line.join(","))?;
    }
    out.flush()
}
