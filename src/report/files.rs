//! The run-folder report: a [`Report`] that writes a run's files into a
//! folder (`docs/cases.md`, "The run folder"), with the OAT's files
//! written by [`super::oat`] and a forming run's by [`super::forming`].

use std::path::{Path, PathBuf};

use super::folder::RunFolder;
use super::forming::{FormingFiles, FormingSummary};
use super::oat::{OatFiles, RunSummary};
use super::progress::Progress;
use super::runner::{Built, Recorded, Report, RunError, Solved, run};
use crate::case::forming::FormingCase;
use crate::case::{Case, OatCase};
use crate::solver::CancelToken;

/// The summary a run folder gets, of either scenario.
#[derive(Debug, Clone)]
pub enum FolderSummary {
    /// An OAT's `summary.json`.
    Oat(Box<RunSummary>),
    /// A forming run's `summary.json`.
    Forming(Box<FormingSummary>),
}

/// Where the folder comes from.
enum Slot<'f> {
    /// To be prepared at [`Report::begin`], once the case is built (a case
    /// that cannot be built leaves no folder).
    Pending(PathBuf),
    /// Prepared by this report.
    Owned(Box<RunFolder>),
    /// Prepared by the caller (a test can then put things in the way of
    /// the outputs).
    Borrowed(&'f mut RunFolder),
}

/// The writer of the scenario's files.
enum Writer {
    Oat(OatFiles),
    Forming(Box<FormingFiles>),
}

/// Writes a run into a run folder: prepared once the case is built and
/// its solver set up (an earlier run moved aside, a foreign folder
/// refused: [`RunFolder::prepare`]), the resolved case with its
/// provenance (`case.resolved.json`) first, the outputs as the states
/// come, the summary and `status.json` at the end; a set-up error is
/// written to `status.json` as `failed` when the folder was prepared.
pub struct FolderReport<'f> {
    slot: Slot<'f>,
    writer: Option<Writer>,
    summary: Option<FolderSummary>,
}

impl FolderReport<'static> {
    /// A report into the folder `out`, prepared when the run begins.
    pub fn new(out: &Path) -> Self {
        Self {
            slot: Slot::Pending(out.to_path_buf()),
            writer: None,
            summary: None,
        }
    }
}

impl<'f> FolderReport<'f> {
    /// A report into a folder the caller prepared (with `vtu/`, and
    /// `maps/` for a forming run).
    pub fn in_folder(folder: &'f mut RunFolder) -> Self {
        Self {
            slot: Slot::Borrowed(folder),
            writer: None,
            summary: None,
        }
    }

    /// The summary written at the end of the run, if it ended.
    pub fn into_summary(self) -> Option<FolderSummary> {
        self.summary
    }

    fn folder(&mut self) -> Option<&mut RunFolder> {
        self.slot.folder()
    }
}

impl Slot<'_> {
    /// The folder, once prepared.
    fn folder(&mut self) -> Option<&mut RunFolder> {
        match self {
            Slot::Pending(_) => None,
            Slot::Owned(folder) => Some(folder),
            Slot::Borrowed(folder) => Some(folder),
        }
    }
}

impl Report for FolderReport<'_> {
    fn begin(&mut self, built: &Built) -> Result<(), RunError> {
        let (source, title, subdirs): (&str, &str, &[&str]) = match built {
            Built::Oat { case, .. } => (&case.source, &case.title, &["vtu"]),
            Built::Forming { case, .. } if case.maps => {
                (&case.source, &case.title, &["vtu", "maps"])
            }
            Built::Forming { case, .. } => (&case.source, &case.title, &["vtu"]),
        };
        if let Slot::Pending(out) = &self.slot {
            let folder =
                RunFolder::prepare(out, source, title, subdirs).map_err(RunError::Folder)?;
            self.slot = Slot::Owned(Box::new(folder));
        }
        if let Some(folder) = self.folder() {
            write_resolved_case(built, folder);
        }
        let out = self.folder().map(|f| f.path().to_path_buf());
        let out = out.unwrap_or_default();
        self.writer = Some(match built {
            Built::Oat { case, .. } => Writer::Oat(OatFiles::new(case, &out)),
            Built::Forming { .. } => Writer::Forming(Box::new(FormingFiles::new(&out))),
        });
        Ok(())
    }

    fn record(&mut self, built: &Built, state: &Recorded) {
        let Some(writer) = &mut self.writer else {
            return;
        };
        let Some(folder) = self.slot.folder() else {
            return;
        };
        match (writer, built) {
            (Writer::Oat(w), Built::Oat { case, model }) => {
                w.record(case, model, state, folder.outputs_mut());
            }
            (
                Writer::Forming(w),
                Built::Forming {
                    case,
                    model,
                    readout,
                },
            ) => w.record(case, model, readout, state, folder.outputs_mut()),
            _ => {}
        }
    }

    fn end(&mut self, built: &Built, solved: &Solved) {
        let Some(writer) = &mut self.writer else {
            return;
        };
        let Some(folder) = self.slot.folder() else {
            return;
        };
        self.summary = match (writer, built) {
            (Writer::Oat(w), Built::Oat { case, model }) => Some(FolderSummary::Oat(Box::new(
                w.finish(case, model, solved, folder),
            ))),
            (
                Writer::Forming(w),
                Built::Forming {
                    case,
                    model,
                    readout,
                },
            ) => Some(FolderSummary::Forming(Box::new(
                w.finish(case, model, readout, solved, folder),
            ))),
            _ => None,
        };
    }

    fn fail(&mut self, error: &RunError) {
        if let Some(folder) = self.folder() {
            folder.fail(&error.to_string());
        }
    }
}

/// Writes the resolved case and its provenance
/// ([`super::provenance::RESOLVED_CASE_FILE`]) into `folder`, recorded in
/// its manifest like every output.
fn write_resolved_case(built: &Built, folder: &mut RunFolder) {
    let path = folder.path().join(super::provenance::RESOLVED_CASE_FILE);
    let document = super::provenance::resolved_case_document_of(built);
    folder.outputs_mut().write_json(&path, &document);
}

/// Runs `case` into `report` and returns the summary it wrote.
fn run_to_folder(
    case: &Case,
    mut report: FolderReport,
    mut progress: Progress,
    cancel: &CancelToken,
) -> Result<FolderSummary, RunError> {
    run(case, &mut report, &mut progress, cancel)?;
    report.into_summary().ok_or(RunError::NoSummary("none"))
}

/// Runs an OAT into the folder `out` (prepared after the set-up: an
/// earlier run moved aside, a foreign folder refused) and returns its
/// summary; a solve that stopped early is `complete = false` with its
/// reason; `cancel` stops it at the solver's next safe point (the results
/// up to there are written and marked interrupted).
///
/// # Errors
/// Set-up failures (case, mesh, output folder), naming the file; nothing
/// is written then, or `status.json` says `failed` when the folder was
/// prepared.
pub fn run_case_with(
    case: &OatCase,
    out: &Path,
    progress: Progress,
    cancel: &CancelToken,
) -> Result<RunSummary, RunError> {
    oat_summary(run_to_folder(
        &Case::Oat(case.clone()),
        FolderReport::new(out),
        progress,
        cancel,
    )?)
}

/// As [`run_case_with`], never cancelled.
///
/// # Errors
/// As [`run_case_with`].
pub fn run_case(case: &OatCase, out: &Path, progress: Progress) -> Result<RunSummary, RunError> {
    run_case_with(case, out, progress, &CancelToken::default())
}

/// As [`run_case_with`] into a folder already prepared.
///
/// # Errors
/// As [`run_case_with`]; `status.json` then says `failed`.
pub fn run_case_in(
    case: &OatCase,
    folder: &mut RunFolder,
    progress: Progress,
    cancel: &CancelToken,
) -> Result<RunSummary, RunError> {
    oat_summary(run_to_folder(
        &Case::Oat(case.clone()),
        FolderReport::in_folder(folder),
        progress,
        cancel,
    )?)
}

/// Runs a forming case into the folder `out`, as [`run_case_with`].
///
/// # Errors
/// As [`run_case_with`] (plies, tools and meshes too).
pub fn run_forming_with(
    case: &FormingCase,
    out: &Path,
    progress: Progress,
    cancel: &CancelToken,
) -> Result<FormingSummary, RunError> {
    forming_summary(run_to_folder(
        &Case::Forming(case.clone()),
        FolderReport::new(out),
        progress,
        cancel,
    )?)
}

/// As [`run_forming_with`], never cancelled.
///
/// # Errors
/// As [`run_forming_with`].
pub fn run_forming(
    case: &FormingCase,
    out: &Path,
    progress: Progress,
) -> Result<FormingSummary, RunError> {
    run_forming_with(case, out, progress, &CancelToken::default())
}

/// As [`run_forming_with`] into a folder already prepared (with `vtu/` and
/// `maps/`).
///
/// # Errors
/// As [`run_forming_with`]; `status.json` then says `failed`.
pub fn run_forming_in(
    case: &FormingCase,
    folder: &mut RunFolder,
    progress: Progress,
    cancel: &CancelToken,
) -> Result<FormingSummary, RunError> {
    forming_summary(run_to_folder(
        &Case::Forming(case.clone()),
        FolderReport::in_folder(folder),
        progress,
        cancel,
    )?)
}

fn oat_summary(summary: FolderSummary) -> Result<RunSummary, RunError> {
    match summary {
        FolderSummary::Oat(s) => Ok(*s),
        FolderSummary::Forming(_) => Err(RunError::NoSummary("a forming summary, not an OAT's")),
    }
}

fn forming_summary(summary: FolderSummary) -> Result<FormingSummary, RunError> {
    match summary {
        FolderSummary::Forming(s) => Ok(*s),
        FolderSummary::Oat(_) => Err(RunError::NoSummary("an OAT summary, not a forming run's")),
    }
}
