//! The error of the fit's input: the fit file, the cases and parameter
//! files it names, and the measured files. Its own module, so that the
//! readers of the fit file (`input`) and of the measured files
//! (`measured`) both use it without importing each other.

use crate::config::ConfigError;

/// Why a fit's input cannot be used. The messages are those the command
/// line prints.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FitInputError {
    /// The fit file (or a case or parameter file it names): syntax,
    /// unknown or missing keys, a value out of range.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A measured file cannot be read.
    #[error("{file}: {reason}")]
    Unreadable {
        /// The measured file.
        file: String,
        /// Why it cannot be read.
        reason: String,
    },
    /// A cell, row, column or header of a measured file.
    #[error("{}: {column} = {value}: {expected}", at(.file, *.line))]
    Cell {
        /// The measured file.
        file: String,
        /// 1-based line in that file (0 when not known).
        line: usize,
        /// The column's header (`displacement [mm]`), or `(row)`,
        /// `(header)`.
        column: String,
        /// The value as read.
        value: String,
        /// What is wrong and what was expected.
        expected: String,
    },
    /// An error of a measured file, with the fit file's line and key that
    /// name it.
    #[error("{}: {key} = {value}: {cause}", at(.fit, *.line))]
    Referenced {
        /// The fit file.
        fit: String,
        /// 1-based line of the key in the fit file (0 when not known).
        line: usize,
        /// The key, e.g. `test[0].measured`.
        key: String,
        /// The value as written, e.g. `"oat30-a.csv"`.
        value: String,
        /// The measured file's error (it names that file).
        cause: Box<FitInputError>,
    },
}

/// `file:line`, or the file alone when the line is not known (0).
fn at(file: &str, line: usize) -> String {
    if line > 0 {
        format!("{file}:{line}")
    } else {
        file.to_string()
    }
}
