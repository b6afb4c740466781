//! A case file of either scenario: an off-axis tension test or a forming
//! set-up. A file with `[[ply]]` tables is a forming case, any other an
//! OAT (`docs/cases.md`).

use std::path::Path;

use super::explicit::SolverKind;
use super::forming::{FormingCase, is_forming};
use super::oat::OatCase;
use crate::config::ConfigError;

/// A validated case of either scenario, as [`crate::report::run`] runs it.
#[derive(Debug, Clone)]
// One case per run: the size of the larger variant costs nothing, and
// unboxed variants keep `Case::Oat(case)` patterns plain.
#[allow(clippy::large_enum_variant)]
pub enum Case {
    /// An off-axis tension test (`[specimen]`, `[loading]`).
    Oat(OatCase),
    /// A forming set-up (`[[ply]]`, `[[tool]]`, …).
    Forming(FormingCase),
}

impl Case {
    /// Reads and validates a case file, of the scenario its tables say.
    ///
    /// # Errors
    /// An unreadable file, or the scenario's parse and validation errors,
    /// naming the file, line, key and value.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let (text, source, base) = crate::config::read_case_file(path)?;
        Self::from_toml_str(&text, &source, &base)
    }

    /// Parses and validates a case text; `source` names it in messages and
    /// relative paths are resolved against `base_dir`.
    ///
    /// # Errors
    /// As [`OatCase::from_toml_str`] or [`FormingCase::from_toml_str`].
    pub fn from_toml_str(text: &str, source: &str, base_dir: &Path) -> Result<Self, ConfigError> {
        if is_forming(text) {
            FormingCase::from_toml_str(text, source, base_dir).map(Case::Forming)
        } else {
            OatCase::from_toml_str(text, source, base_dir).map(Case::Oat)
        }
    }

    /// The title.
    pub fn title(&self) -> &str {
        match self {
            Case::Oat(c) => &c.title,
            Case::Forming(c) => &c.title,
        }
    }

    /// The case file (or the name given).
    pub fn source(&self) -> &str {
        match self {
            Case::Oat(c) => &c.source,
            Case::Forming(c) => &c.source,
        }
    }

    /// The case's warnings: unusual values (`docs/cases.md`, "Ranges")
    /// and what it reads but does not use, in file order of the checks.
    pub fn warnings(&self) -> &[crate::config::CaseWarning] {
        match self {
            Case::Oat(c) => &c.warnings,
            Case::Forming(c) => &c.warnings,
        }
    }

    /// The solver that runs the case.
    pub fn solver_kind(&self) -> SolverKind {
        match self {
            Case::Oat(c) => c.solver_kind,
            Case::Forming(c) => c.solver_kind,
        }
    }
}
