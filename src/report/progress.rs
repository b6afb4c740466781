//! Progress of a run on the terminal: a bar when stderr is a terminal,
//! a line every tenth of the load otherwise (CI, pipes), or nothing.

use std::io::IsTerminal;

use indicatif::{ProgressBar, ProgressStyle};

/// How progress is shown.
pub enum Progress {
    /// A bar on a terminal; `true` for a forming programme (fraction λ).
    Bar(ProgressBar, bool),
    /// A line every tenth of the stroke (CI, pipes).
    Lines {
        /// Next load to report at.
        next: f64,
        /// `true` for a forming programme (fraction λ).
        programme: bool,
    },
    /// Nothing.
    Quiet,
}

impl Progress {
    /// A bar when stderr is a terminal, quiet lines otherwise, for an OAT
    /// of stroke `total` \[mm\].
    pub fn auto(total: f64) -> Self {
        Self::with_kind(total, false)
    }

    /// As [`Progress::auto`] for a forming programme (`λ` from 0 to 1).
    pub fn auto_programme() -> Self {
        Self::with_kind(1.0, true)
    }

    fn with_kind(total: f64, programme: bool) -> Self {
        if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new((total * 1000.0).round() as u64);
            let template = if programme {
                "{spinner} [{elapsed_precise}] {bar:40} λ = {msg}"
            } else {
                "{spinner} [{elapsed_precise}] {bar:40} d = {msg}"
            };
            if let Ok(style) = ProgressStyle::with_template(template) {
                bar.set_style(style);
            }
            Progress::Bar(bar, programme)
        } else {
            Progress::Lines {
                next: 0.0,
                programme,
            }
        }
    }

    /// Shows the state at load `load` (a clamp displacement [mm], or the
    /// programme fraction) with force `reaction` and a solver-specific
    /// `detail`.
    pub fn update(&mut self, load: f64, reaction: f64, detail: &str, total: f64) {
        match self {
            Progress::Bar(bar, programme) => {
                bar.set_position((load * 1000.0).round() as u64);
                if *programme {
                    bar.set_message(format!("{load:.3}, F = {reaction:.3} N, {detail}"));
                } else {
                    bar.set_message(format!("{load:.2} mm, F = {reaction:.3} N, {detail}"));
                }
            }
            Progress::Lines { next, programme } => {
                if load + 1e-9 >= *next {
                    if *programme {
                        eprintln!("λ = {load:5.3}, F = {reaction:10.4} N, {detail}");
                    } else {
                        eprintln!("d = {load:7.3} mm, F = {reaction:10.4} N, {detail}");
                    }
                    *next = load + 0.1 * total;
                }
            }
            Progress::Quiet => {}
        }
    }

    /// Ends the bar (a no-op for lines and quiet).
    pub fn finish(&self) {
        if let Progress::Bar(bar, _) = self {
            bar.finish();
        }
    }
}
