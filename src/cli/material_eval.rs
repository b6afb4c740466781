//! `ncform material eval`: JSON lines in, energy, stress, tangent and
//! invariants out, one line per input line.
//!
//! Input line: `{"C": [[c11, c12], [c12, c22]], "fiber_angle_deg": θ}`, the
//! fibre `a0 = (cos θ, sin θ)` in the frame of `C`, `b0` turned by +90°.
//! Output line: `{"W": …, "S": [[…], […]], "tangent": [[[[…]]]],
//! "invariants": {"I4", "I6", "I8", "I10", "I11"}}` with
//! `tangent[i][j][k][l] = ℂ_ijkl`. A bad line yields
//! `{"line": n, "error": "…"}` on the output and a message on the error
//! stream; blank lines are skipped.

use std::io::{BufRead, Write};

use serde::Deserialize;
use serde_json::{Value, json};

use crate::config::readable_number;
use crate::material::{FibreFrame, Invariants, Material, MembraneMaterial, Sym2, Tangent};

/// Relative asymmetry `|C12 − C21| / max|C_ij|` above which an input `C` is
/// rejected rather than symmetrised: a few ulps of round-off pass.
pub const SYMMETRY_TOLERANCE: f64 = 1e-12;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EvalInput {
    #[serde(rename = "C")]
    c: [[f64; 2]; 2],
    fiber_angle_deg: f64,
}

/// Counts of a finished `eval` run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EvalSummary {
    /// Lines answered with a result.
    pub answered: usize,
    /// Lines answered with an error.
    pub failed: usize,
}

/// Maps Voigt index `a ∈ {0, 1, 2}` ↔ tensor index pair.
const VOIGT: [[usize; 2]; 2] = [[0, 2], [2, 1]];

/// `ℂ_ijkl` as a nested 2×2×2×2 array from Voigt storage.
pub fn tangent_tensor(tangent: &Tangent) -> [[[[f64; 2]; 2]; 2]; 2] {
    let mut t = [[[[0.0; 2]; 2]; 2]; 2];
    for (i, ti) in t.iter_mut().enumerate() {
        for (j, tij) in ti.iter_mut().enumerate() {
            for (k, tijk) in tij.iter_mut().enumerate() {
                for (l, v) in tijk.iter_mut().enumerate() {
                    *v = tangent[(VOIGT[i][j], VOIGT[k][l])];
                }
            }
        }
    }
    t
}

/// Evaluates one input line; `Err` carries the message for that line.
// A String error: it is the text of the line's `{"error": …}` answer, not
// an error the program acts on (the command answers every line).
pub fn eval_line(material: &Material, line: &str) -> Result<Value, String> {
    let input: EvalInput = serde_json::from_str(line).map_err(|e| {
        let message = e.to_string();
        // serde_json appends " at line 1 column N"; the column is what helps.
        let message = message.split(" at line ").next().unwrap_or(&message);
        // A key may hold an escaped newline or other control character:
        // keep the answer one line.
        let message: String = message
            .chars()
            .flat_map(|c| {
                let escaped: Vec<char> = if c.is_control() {
                    c.escape_default().collect()
                } else {
                    vec![c]
                };
                escaped
            })
            .collect();
        format!(
            "invalid input at column {}: {message} (expected {{\"C\": [[c11, c12], [c12, c22]], \"fiber_angle_deg\": θ}})",
            e.column()
        )
    })?;
    let [[c11, c12], [c21, c22]] = input.c;
    let scale = c11.abs().max(c22.abs()).max(c12.abs()).max(c21.abs());
    if (c12 - c21).abs() > SYMMETRY_TOLERANCE * scale {
        return Err(format!(
            "C is not symmetric: C12 = {}, C21 = {} (expected equal to a relative {SYMMETRY_TOLERANCE:e})",
            readable_number(c12),
            readable_number(c21)
        ));
    }
    if !input.fiber_angle_deg.is_finite() {
        return Err("fiber_angle_deg must be a finite number of degrees".to_string());
    }
    let c = Sym2::new(c11, c22, 0.5 * (c12 + c21));
    let frame = FibreFrame::from_angle(input.fiber_angle_deg.to_radians());
    let invariants = Invariants::new(&c, &frame).map_err(|e| e.to_string())?;
    let (state, tangent) = material
        .stress_tangent(&c, &frame)
        .map_err(|e| e.to_string())?;
    let s = state.stress;
    let tensor = tangent_tensor(&tangent);
    let outputs = [
        state.energy,
        s[0],
        s[1],
        s[2],
        invariants.i4,
        invariants.i6,
        invariants.i8,
        invariants.i10(),
        invariants.i11,
    ];
    if outputs
        .iter()
        .chain(tensor.as_flattened().as_flattened().as_flattened())
        .any(|v| !v.is_finite())
    {
        return Err(format!(
            "the law's energy, stress or tangent overflows at C = [[{}, {}], [{}, {}]] \
             (expected a C whose result is finite)",
            readable_number(c11),
            readable_number(c12),
            readable_number(c21),
            readable_number(c22)
        ));
    }
    Ok(json!({
        "W": state.energy,
        "S": [[s[0], s[2]], [s[2], s[1]]],
        "tangent": tensor,
        "invariants": {
            "I4": invariants.i4,
            "I6": invariants.i6,
            "I8": invariants.i8,
            "I10": invariants.i10(),
            "I11": invariants.i11,
        },
    }))
}

/// Runs `eval` over every line of `input`, writing results to `output` and
/// one message per bad line to `errors` (`<source>:<line>: <message>`).
/// Lines are read as bytes: a line that is not UTF-8 is answered with an
/// error and the later lines are still evaluated.
///
/// # Errors
/// Only I/O errors of the streams themselves.
pub fn run(
    material: &Material,
    input: impl BufRead,
    mut output: impl Write,
    mut errors: impl Write,
    source: &str,
) -> std::io::Result<EvalSummary> {
    let mut summary = EvalSummary::default();
    let mut input = input;
    let mut bytes = Vec::new();
    let mut number = 0;
    loop {
        bytes.clear();
        if input.read_until(b'\n', &mut bytes)? == 0 {
            break;
        }
        number += 1;
        let result = match std::str::from_utf8(&bytes) {
            Ok(line) if line.trim().is_empty() => continue,
            Ok(line) => eval_line(material, line),
            Err(e) => Err(format!(
                "not UTF-8 text at byte {} of the line (expected a JSON line)",
                e.valid_up_to() + 1
            )),
        };
        match result {
            Ok(value) => {
                summary.answered += 1;
                writeln!(output, "{value}")?;
            }
            Err(message) => {
                summary.failed += 1;
                writeln!(errors, "{source}:{number}: {message}")?;
                writeln!(output, "{}", json!({"line": number, "error": message}))?;
            }
        }
    }
    output.flush()?;
    Ok(summary)
}
