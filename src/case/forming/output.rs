//! The `[output]` table of a forming case: how many VTU states over the
//! programme, how many history rows of an explicit run, which side the
//! PNG maps look at the plies from and whether they are drawn at all. Key-by-key documentation:
//! `docs/cases.md`, "Forming cases".

use super::raw::OutputRaw;
use super::{DEFAULT_HISTORY_ROWS, DEFAULT_STATES, MapView};
use crate::case::SolverKind;
use crate::config::{ConfigError, TomlChecker};

/// The validated `[output]` table.
pub(super) struct Outputs {
    /// How the PNG maps look at the plies (`camera`).
    pub(super) camera: MapView,
    /// Whether the PNG maps are written at every output state (`maps`).
    pub(super) maps: bool,
    /// Number of VTU states besides `λ = 0` (`states`).
    pub(super) states: usize,
    /// History rows of an explicit run (`history`).
    pub(super) history_rows: usize,
}

/// The `[output]` table's camera, maps switch, states and history rows,
/// each with its default when left out; `history` under the quasi-static
/// solver (one row per converged step) is a warning: read and checked, so
/// that switching solvers is a one-line change, but not used.
pub(super) fn output(
    check: &TomlChecker,
    raw: Option<&OutputRaw>,
    solver: SolverKind,
) -> Result<Outputs, ConfigError> {
    if solver == SolverKind::QuasiStatic
        && let Some(history) = raw.and_then(|o| o.history.as_ref())
    {
        check.warn(
            check.line_of(history),
            "output.history",
            history.get_ref().to_string(),
            String::new(),
            "the quasi-static solver writes one history row per converged step and does not use \
             output.history (it is checked, so that solver = \"explicit\" is a one-line change)",
        );
    }
    let camera = match raw.and_then(|o| o.camera.as_ref()) {
        None => MapView::Below,
        Some(c) => check.choice(
            c,
            "output.camera",
            &[("below", MapView::Below), ("above", MapView::Above)],
        )?,
    };
    let (states, history_rows) = match raw {
        None => (DEFAULT_STATES, DEFAULT_HISTORY_ROWS),
        Some(o) => (
            match &o.states {
                None => DEFAULT_STATES,
                Some(n) => check.count(n, "output.states", 1..=10_000)?,
            },
            match &o.history {
                None => DEFAULT_HISTORY_ROWS,
                Some(n) => check.count(n, "output.history", 1..=1_000_000)?,
            },
        ),
    };
    Ok(Outputs {
        camera,
        maps: raw.and_then(|o| o.maps).unwrap_or(true),
        states,
        history_rows,
    })
}
