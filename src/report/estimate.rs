//! What a prepared run is expected to take before it starts: the solver's
//! work (explicit increments from the first stable step, or quasi-static
//! load steps from the load stepping), a rough run time from the rates
//! measured on this project's 2-core machine (`docs/benchmarks.md`) and
//! the size of the outputs (VTU states, PNG maps, history rows). Printed
//! by `ncform check` and at the start of `ncform run` (`docs/cases.md`,
//! "Checking a case").
//!
//! The figures are rough by design: a run time within a factor of a few
//! on a machine like the project's, an output size within some tens of
//! per cent. Nothing here is a promise or a test bound.

use serde::Serialize;

use crate::case::Case;
use crate::solver::ExplicitEstimate;

/// What a prepared run is expected to take, as its solver sees it before
/// the first step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "solver", rename_all = "kebab-case")]
pub enum SolverEstimate {
    /// Newton load steps: at least `min_steps` (the programme over the
    /// largest increment, with the output stops); cut-backs add more.
    QuasiStatic {
        /// Fewest load steps the settings allow.
        min_steps: usize,
        /// Steps if the first increment is kept throughout.
        initial_steps: usize,
        /// Free unknowns.
        unknowns: usize,
    },
    /// The explicit run's increments from its first stable step.
    Explicit(ExplicitEstimate),
}

/// Explicit element-cycles per second of a membrane-only model (an OAT)
/// on the project's machine: the membrane bench's 33.8 M/s on one thread
/// and 51.3 M/s on two, less the outputs and step estimates of a whole
/// run (`docs/benchmarks.md`).
pub const MEMBRANE_CYCLES_PER_SECOND: f64 = 20e6;

/// Explicit element-cycles per second of a forming model (membrane,
/// bending, tool contact): the paper-size [0°] hemisphere's 15.4–16.8 M/s
/// (`docs/benchmarks.md`).
pub const FORMING_CYCLES_PER_SECOND: f64 = 15e6;

/// Seconds per node and increment of each ply–ply contact, on top of the
/// element-cycles: the term's 103 ns (`docs/benchmarks.md`).
pub const PLY_CONTACT_SECONDS_PER_NODE: f64 = 103e-9;

/// Quasi-static seconds per Newton iteration and free unknown of an OAT:
/// the 45° OAT's 2.9 s for 119 iterations of about 13,000 unknowns.
pub const OAT_SECONDS_PER_ITERATION_UNKNOWN: f64 = 2e-6;

/// Quasi-static seconds per Newton iteration and free unknown of a forming
/// case: the verification cases' 2–5 µs (the indentation's 2.9 s for 241
/// iterations of 5,403 unknowns). A hard contact case takes far longer:
/// the quasi-static hemisphere 42 × 42, 30 µs at 51 iterations a step.
pub const FORMING_SECONDS_PER_ITERATION_UNKNOWN: f64 = 5e-6;

/// Newton iterations per load step assumed: an OAT's about 6, a forming
/// case's about 8 (augmentations included; the verification cases take
/// 1–9).
pub const ITERATIONS_PER_STEP: (f64, f64) = (6.0, 8.0);

/// Bytes of a ply's (or an OAT's) VTU per triangle and state (ASCII, with
/// the cell and point fields), and of its blank-plane projection.
pub const VTU_BYTES_PER_TRIANGLE: (f64, f64) = (230.0, 90.0);

/// Bytes of one PNG map (three per ply and state: the maps, the
/// image-correlation maps and the deformation modes).
pub const MAP_BYTES: f64 = 140e3;

/// Seconds to draw and write one PNG map, and per triangle drawn.
pub const MAP_SECONDS: (f64, f64) = (0.02, 1e-6);

/// Bytes per history row, summed over the CSV files that get one.
pub const HISTORY_ROW_BYTES: (f64, f64) = (250.0, 1500.0);

/// Rate of writing text outputs (VTU, CSV) \[bytes/s\].
pub const TEXT_BYTES_PER_SECOND: f64 = 50e6;

/// The size of a built model, as the estimate needs it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ModelSize {
    /// Nodes of the plies (or of the OAT's mesh).
    pub nodes: usize,
    /// Triangles of the plies (or of the OAT's mesh).
    pub elements: usize,
    /// Plies (0 for an OAT).
    pub plies: usize,
    /// Tools.
    pub tools: usize,
    /// Ply–ply contacts.
    pub ply_contacts: usize,
    /// Terms of the model the solver drives.
    pub terms: usize,
}

/// What a run is expected to take.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// The solver's figures.
    pub solver: SolverEstimate,
    /// The model's size.
    pub model: ModelSize,
    /// Rough wall time of the solve \[s\] on a machine like the project's.
    pub solve_seconds: f64,
    /// VTU states written (besides the reference for a forming case).
    pub states: usize,
    /// History rows written.
    pub history_rows: usize,
    /// PNG maps written.
    pub maps: usize,
    /// Estimated size of the outputs \[bytes\].
    pub output_bytes: f64,
    /// Rough wall time of writing the outputs \[s\].
    pub output_seconds: f64,
}

impl Estimate {
    /// The estimate of `case`, built into a model of size `model`, whose
    /// solver expects `solver`.
    pub fn new(case: &Case, solver: SolverEstimate, model: ModelSize) -> Self {
        let forming = matches!(case, Case::Forming(_));
        let solve_seconds = match solver {
            SolverEstimate::Explicit(e) => {
                let rate = if forming {
                    FORMING_CYCLES_PER_SECOND
                } else {
                    MEMBRANE_CYCLES_PER_SECOND
                };
                let ply_contacts = e.increments
                    * model.nodes as f64
                    * model.ply_contacts as f64
                    * PLY_CONTACT_SECONDS_PER_NODE;
                e.element_cycles() / rate + ply_contacts
            }
            SolverEstimate::QuasiStatic {
                min_steps,
                unknowns,
                ..
            } => {
                let (per_unknown, iterations) = if forming {
                    (FORMING_SECONDS_PER_ITERATION_UNKNOWN, ITERATIONS_PER_STEP.1)
                } else {
                    (OAT_SECONDS_PER_ITERATION_UNKNOWN, ITERATIONS_PER_STEP.0)
                };
                min_steps as f64 * iterations * per_unknown * unknowns as f64
            }
        };
        let (states, history_rows, maps_on) = match case {
            Case::Oat(c) => {
                let rows = match solver {
                    SolverEstimate::Explicit(_) => {
                        (c.displacement / c.explicit.history_interval).round() as usize
                    }
                    SolverEstimate::QuasiStatic { min_steps, .. } => min_steps,
                };
                (c.output_displacements.len().max(1), rows, false)
            }
            Case::Forming(c) => {
                let rows = match solver {
                    SolverEstimate::Explicit(_) => c.history_rows,
                    SolverEstimate::QuasiStatic { min_steps, .. } => min_steps,
                };
                (c.states.len(), rows, c.maps)
            }
        };
        let maps = if maps_on { 3 * model.plies * states } else { 0 };
        let triangles = model.elements as f64;
        let per_state_vtu = if forming {
            (VTU_BYTES_PER_TRIANGLE.0 + VTU_BYTES_PER_TRIANGLE.1) * triangles
        } else {
            VTU_BYTES_PER_TRIANGLE.0 * triangles
        };
        let row_bytes = if forming {
            HISTORY_ROW_BYTES.1
        } else {
            HISTORY_ROW_BYTES.0
        };
        let text_bytes = states as f64 * per_state_vtu + history_rows as f64 * row_bytes;
        let output_bytes = text_bytes + maps as f64 * MAP_BYTES;
        let per_map = MAP_SECONDS.0 + MAP_SECONDS.1 * triangles / model.plies.max(1) as f64;
        let output_seconds = text_bytes / TEXT_BYTES_PER_SECOND + maps as f64 * per_map;
        Self {
            solver,
            model,
            solve_seconds,
            states,
            history_rows,
            maps,
            output_bytes,
            output_seconds,
        }
    }

    /// The estimate in two lines: the solver's work with the run time, and
    /// the outputs.
    pub fn lines(&self) -> [String; 2] {
        let work = match self.solver {
            SolverEstimate::Explicit(e) => format!(
                "about {} increments (first stable step {:.3e} s over {} s, {} outputs), {} element-cycles",
                count(e.increments),
                e.time_step,
                short(e.duration),
                e.outputs,
                count(e.element_cycles())
            ),
            SolverEstimate::QuasiStatic {
                min_steps,
                initial_steps,
                unknowns,
            } => format!(
                "at least {min_steps} load steps ({initial_steps} at the first increment; cut-backs add more), {unknowns} unknowns"
            ),
        };
        [
            format!(
                "estimate: {work}; roughly {} on a 2-core machine like the project's (a rough estimate: docs/benchmarks.md)",
                duration(self.solve_seconds)
            ),
            format!(
                "estimate: outputs about {} ({} states of {} triangles, {} maps, {} history rows); writing them takes {}",
                bytes(self.output_bytes),
                self.states,
                self.model.elements,
                self.maps,
                self.history_rows,
                duration(self.output_seconds)
            ),
        ]
    }

    /// A warning when writing the outputs would take longer than the solve
    /// (and more than a minute) or fill more than 5 GB, naming the keys
    /// that set them.
    pub fn output_warning(&self) -> Option<String> {
        let slow = self.output_seconds > 60.0 && self.output_seconds > self.solve_seconds;
        let big = self.output_bytes > 5e9;
        if !(slow || big) {
            return None;
        }
        let keys = if self.maps > 0 {
            "lower [output] states, or set [output] maps = false to write the fields without the PNG maps"
        } else {
            "lower [output] states (or the history rows)"
        };
        Some(format!(
            "the outputs would dwarf the solve: about {} taking {} to write ({} states, {} maps), against a solve of {}; {keys}",
            bytes(self.output_bytes),
            duration(self.output_seconds),
            self.states,
            self.maps,
            duration(self.solve_seconds)
        ))
    }
}

/// A count, rounded, with thousands separators.
fn count(x: f64) -> String {
    if !x.is_finite() || x >= 1e15 {
        return format!("{x:.3e}");
    }
    let digits = format!("{:.0}", x.max(0.0));
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// A number in at most six decimals without trailing zeros (`0.44`), or
/// in exponent form outside `[1e-4, 1e6)`.
fn short(x: f64) -> String {
    if x == 0.0 || (1e-4..1e6).contains(&x.abs()) {
        let text = format!("{x:.6}");
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{x:.3e}")
    }
}

/// Seconds as `12 s`, `3.4 min`, `5.6 h` or `7.8 days`.
fn duration(seconds: f64) -> String {
    if seconds < 1.0 {
        "under a second".to_string()
    } else if seconds < 120.0 {
        format!("{seconds:.0} s")
    } else if seconds < 7200.0 {
        format!("{:.1} min", seconds / 60.0)
    } else if seconds < 172_800.0 {
        format!("{:.1} h", seconds / 3600.0)
    } else {
        format!("{:.1} days", seconds / 86400.0)
    }
}

/// Bytes as `kB`, `MB` or `GB` (decimal).
fn bytes(b: f64) -> String {
    if b < 1e6 {
        format!("{:.0} kB", b / 1e3)
    } else if b < 1e9 {
        format!("{:.0} MB", b / 1e6)
    } else {
        format!("{:.1} GB", b / 1e9)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_durations_and_sizes_read_as_written() {
        assert_eq!(count(1_234_567.2), "1,234,567");
        assert_eq!(count(999.0), "999");
        assert_eq!(short(0.439_999_999_999_999_95), "0.44");
        assert_eq!(short(1e-7), "1.000e-7");
        assert_eq!(duration(90.0), "90 s");
        assert_eq!(duration(600.0), "10.0 min");
        assert_eq!(bytes(2.5e10), "25.0 GB");
    }
}
