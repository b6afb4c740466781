//! A report that keeps a run's results in memory and writes nothing: the
//! history rows (with the MDZ means of an OAT, the tool forces, draw-in
//! and zone means of a forming run), the last recorded state's
//! displacement and element fields, and the solve's figures. What a
//! caller running cases from code (a fit, a sweep, a script) reads.

use super::rows::{FormingRow, HistoryRow};
use super::runner::{Built, Recorded, Report, RunError, Solved};
use crate::post::fields::{ElementFields, element_fields};

/// A recorded state's values.
#[derive(Debug, Clone)]
pub struct StateValues {
    /// Its load: the clamp displacement \[mm\] of an OAT, the programme
    /// fraction of a forming run.
    pub load: f64,
    /// Displacement of every dof \[mm\].
    pub u: Vec<f64>,
    /// Per ply (one for an OAT), the fields of every element; empty for a
    /// ply whose fields cannot be evaluated.
    pub fields: Vec<Vec<ElementFields>>,
}

/// The results of a run, in memory.
#[derive(Debug, Clone, Default)]
pub struct MemoryReport {
    /// An OAT's history: one row per recorded state.
    pub oat_rows: Vec<HistoryRow>,
    /// A forming run's history: one row per recorded state.
    pub forming_rows: Vec<FormingRow>,
    /// The last recorded state, its fields evaluated at the end of the run.
    pub last_state: Option<StateValues>,
    /// States whose fields could not be evaluated: load and why.
    pub unreadable: Vec<(f64, String)>,
    /// The solve's figures, once it ended.
    pub solved: Option<Solved>,
    /// The set-up error, if the run failed.
    pub error: Option<String>,
}

impl MemoryReport {
    /// An empty report.
    pub fn new() -> Self {
        Self::default()
    }

    /// The force curve: `(load, force)` per recorded state — the clamp
    /// displacement \[mm\] and force \[N\] of an OAT, the stroke \[mm\] and
    /// the stroke tool's force \[N\] of a forming run (the first tool's
    /// without a stroke tool).
    pub fn force_curve(&self, stroke_tool: Option<usize>) -> Vec<(f64, f64)> {
        if !self.oat_rows.is_empty() {
            return self
                .oat_rows
                .iter()
                .map(|r| (r.displacement, r.force))
                .collect();
        }
        self.forming_rows
            .iter()
            .map(|r| {
                let force = stroke_tool
                    .or((!r.tools.is_empty()).then_some(0))
                    .map_or(0.0, |t| r.tools[t].force);
                (r.stroke, force)
            })
            .collect()
    }
}

impl Report for MemoryReport {
    fn begin(&mut self, _built: &Built) -> Result<(), RunError> {
        Ok(())
    }

    fn record(&mut self, _built: &Built, state: &Recorded) {
        match state {
            Recorded::Oat { row, u, fields } => {
                self.oat_rows.push((*row).clone());
                self.last_state = Some(StateValues {
                    load: row.displacement,
                    u: u.to_vec(),
                    fields: vec![fields.to_vec()],
                });
            }
            Recorded::OatUnreadable {
                load,
                element,
                error,
            } => self
                .unreadable
                .push((*load, format!("element {element}: {error}"))),
            Recorded::Forming { row, snapshot } => {
                self.forming_rows.push((*row).clone());
                match &mut self.last_state {
                    Some(last) if last.u.len() == snapshot.u.len() => {
                        last.load = row.load;
                        last.u.copy_from_slice(snapshot.u);
                    }
                    last => {
                        *last = Some(StateValues {
                            load: row.load,
                            u: snapshot.u.to_vec(),
                            fields: Vec::new(),
                        });
                    }
                }
            }
        }
    }

    fn end(&mut self, built: &Built, solved: &Solved) {
        if let (Built::Forming { model, .. }, Some(last)) = (built, &mut self.last_state) {
            last.fields = model
                .plies
                .iter()
                .map(|ply| element_fields(&ply.membrane, &last.u).unwrap_or_default())
                .collect();
        }
        self.solved = Some(solved.clone());
    }

    fn fail(&mut self, error: &RunError) {
        self.error = Some(error.to_string());
    }
}
