//! `ncform export RUN` and `ncform map RUN --onto STRUCT`: argument
//! handling over [`crate::handoff::export`] (`docs/export.md`). The deck is
//! written to a temporary file beside `--out` and renamed into place, so a
//! failed write leaves no half deck; `map` writes its report beside the
//! deck and counts the elements without a ply on stderr.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::handoff::Handoff;
use crate::handoff::abaqus::AbaqusElement;
use crate::handoff::export::{
    Format, HandoffError, HandoffOptions, PlyMapping, formed_handoff, mapped_handoff,
    write_handoff, write_map_report,
};

/// Why `export` or `map` failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportCommandError {
    /// The hand-off could not be made (bad input).
    #[error(transparent)]
    Handoff(#[from] HandoffError),
    /// The deck could not be written.
    #[error("{path}: cannot write: {source}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

impl ExportCommandError {
    /// `true` for bad input (exit 1), `false` for an output that could not
    /// be written (exit 5).
    pub fn is_input(&self) -> bool {
        matches!(self, Self::Handoff(_))
    }
}

/// Writes `handoff` as `format` to `out` through a temporary file beside
/// it.
fn write_deck(
    handoff: &Handoff,
    format: Format,
    element: AbaqusElement,
    out: &Path,
) -> Result<(), ExportCommandError> {
    let fail = |source: std::io::Error| ExportCommandError::Write {
        path: out.to_path_buf(),
        source,
    };
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(fail)?;
    }
    let mut partial = out.as_os_str().to_owned();
    partial.push(".partial");
    let partial = PathBuf::from(partial);
    let written = (|| {
        let mut file = BufWriter::new(File::create(&partial)?);
        write_handoff(handoff, format, element, &mut file)?;
        file.flush()?;
        file.into_inner().map_err(|e| e.into_error())?.sync_all()?;
        std::fs::rename(&partial, out)
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&partial);
        return Err(fail(e));
    }
    Ok(())
}

/// One line per ply on `say`: what was written.
fn summary_line(handoff: &Handoff, out: &Path) -> String {
    format!(
        "{}: {} nodes, {} elements, {} (written to {})",
        handoff.mesh.source,
        handoff.mesh.nodes.len(),
        handoff.mesh.elements.len(),
        handoff
            .layers
            .iter()
            .map(|l| {
                let covered = l.fibre.iter().filter(|f| f.is_some()).count();
                format!("ply \"{}\" on {covered}", l.name)
            })
            .collect::<Vec<_>>()
            .join(", "),
        out.display()
    )
}

/// `ncform export`: the formed plies of `run` as a deck of `format` at
/// `out`; returns the line to print.
///
/// # Errors
/// [`ExportCommandError`].
pub fn export_command(
    run: &Path,
    format: Format,
    element: AbaqusElement,
    options: &HandoffOptions,
    out: &Path,
) -> Result<String, ExportCommandError> {
    let (handoff, _) = formed_handoff(run, options)?;
    write_deck(&handoff, format, element, out)?;
    Ok(summary_line(&handoff, out))
}

/// `ncform map`: the formed plies of `run` mapped onto the structural mesh
/// `onto`, as a deck of `format` at `out`, with the report
/// `<out>.map.csv`; returns the line to print and, per ply with elements
/// off it, a warning for stderr.
///
/// # Errors
/// [`ExportCommandError`].
pub fn map_command(
    run: &Path,
    onto: &Path,
    format: Format,
    options: &HandoffOptions,
    out: &Path,
) -> Result<(String, Vec<String>), ExportCommandError> {
    let (handoff, mappings) = mapped_handoff(run, onto, options)?;
    write_deck(&handoff, format, AbaqusElement::Shell, out)?;
    let mut report = out.as_os_str().to_owned();
    report.push(".map.csv");
    let report = PathBuf::from(report);
    write_map_report(&report, &handoff, &mappings).map_err(|source| ExportCommandError::Write {
        path: report.clone(),
        source,
    })?;
    let warnings = off_ply_warnings(&handoff, &mappings, options, &report);
    Ok((summary_line(&handoff, out), warnings))
}

/// Per ply that does not cover every element: how many, and where the list
/// is.
fn off_ply_warnings(
    handoff: &Handoff,
    mappings: &[PlyMapping],
    options: &HandoffOptions,
    report: &Path,
) -> Vec<String> {
    mappings
        .iter()
        .filter(|m| !m.result.unmapped.is_empty())
        .map(|m| {
            let labels: Vec<String> = m
                .result
                .unmapped
                .iter()
                .take(10)
                .map(|u| u.label.to_string())
                .collect();
            format!(
                "{} of {} elements of {} have no ply \"{}\" within {} mm and get no direction (labels {}{}); all listed in {}",
                m.result.unmapped.len(),
                handoff.mesh.elements.len(),
                handoff.mesh.source,
                m.ply,
                options.map.tolerance,
                labels.join(", "),
                if m.result.unmapped.len() > 10 { ", …" } else { "" },
                report.display()
            )
        })
        .collect()
}
