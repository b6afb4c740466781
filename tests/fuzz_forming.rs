//! Fuzz harness of forming runs (`docs/fuzzing.md`): coarse, short-stroke
//! copies of the shipped paper-size forming cases — the hemisphere [0°],
//! [45°] and [0°/90°] with ply contact, the tetrahedron [0°] — generated
//! from the shipped files' text, each run through the explicit and the
//! quasi-static solver, mutated and run to the end through the library's
//! entry points (`FormingCase::load` + `run_forming`) into a scratch run
//! folder.
//!
//! The mutants: the byte and number operators of the other harnesses,
//! wrong value types and keys moved between tables
//! ([`fuzz_common::mutate_toml`]), keys added to tables where they do not
//! apply (a tool-motion key on a fixed tool, a key of one shape on
//! another, an explicit-only key under the quasi-static solver and the
//! other way round), and foreign, truncated or empty mesh, tool and
//! parameter files.
//!
//! Asserted for every mutant: no panic; an answer within [`BOUND`]; no
//! non-finite number in the returned summary; either a result or an error
//! naming the case file or the file at fault; numbers in messages written
//! short; an inapplicable key refused or reported; and the run folder
//! sound ([`fuzz_common::check_run_folder`]): `status.json` agreeing with
//! the returned exit status, the manifest, no partial file, every JSON,
//! CSV, VTU/PVD and PNG whole, no `null`/`NaN`/`inf` in them.
//!
//! Work is capped: the seeds' `explicit.max_increments` and
//! `solver.max_wall_seconds` are put back into every mutant after it is
//! made (never mutated, never removed), and a mutant may not raise the
//! cells, the output states, the history rows or the Newton iterations of
//! a step above small limits ([`LIMITS`]). The bounded run draws
//! [`DEFAULT_CASES`] mutants per seed and solver; `NCFORM_FUZZ_CASES=N`
//! gives `N / RUN_COST`, `NCFORM_FUZZ_SEED` changes the seed,
//! `NCFORM_FUZZ_ONLY=k,…` runs only those mutants (a reproduction) and
//! `NCFORM_FUZZ_TRACE=1` prints each mutant's outcome.
//!
//! Defects found and not yet fixed are allowed by name in
//! [`fuzz_common::FUZZ_KNOWN`] (counted, not failed); an entry goes once
//! its fix is merged.

mod fuzz_common;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use fuzz_common::{
    FolderProblem, Operator, accepted_non_finite, cases_scaled, check_run_folder, guarded, known,
    mutate, mutate_toml, quiet_panics, show,
};
use ncform::case::forming::FormingCase;
use ncform::material::MaterialSpec;
use ncform::report::Progress;
use ncform::report::files::run_forming;
use rand::RngExt;
use rand::rngs::StdRng;

/// Mutants per seed and solver in `cargo test` (8 campaigns).
const DEFAULT_CASES: usize = 150;

/// A campaign's `NCFORM_FUZZ_CASES` (mutants per reader) divided by this
/// gives the mutants per seed and solver: a forming run with its outputs
/// costs about as much as a hundred reads.
const RUN_COST: usize = 100;

/// Longest one run may take. The seeds run in a fraction of a second and
/// their work is capped; the bound only turns a hang into a failure.
const BOUND: Duration = Duration::from_secs(120);

/// The explicit seeds' increment cap, put back into every mutant.
const MAX_INCREMENTS: &str = "max_increments = 20000";

/// The quasi-static seeds' wall-time cap, put back into every mutant.
const MAX_WALL_SECONDS: &str = "max_wall_seconds = 5.0";

/// The shipped paper-size forming cases the seeds are made from.
const SHIPPED: [(&str, &str); 4] = [
    ("hemisphere-0", include_str!("../cases/hemisphere-0.toml")),
    ("hemisphere-45", include_str!("../cases/hemisphere-45.toml")),
    (
        "hemisphere-0-90",
        include_str!("../cases/hemisphere-0-90.toml"),
    ),
    ("tetrahedron-0", include_str!("../cases/tetrahedron-0.toml")),
];

/// The solver a seed is run with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Solver {
    Explicit,
    QuasiStatic,
}

/// The sample meshes of the repository (a plate of another size, and the
/// sources of foreign and truncated mesh files).
const SQUARE_INP: &str = include_str!("../cases/meshes/square.inp");
const SQUARE_MSH: &str = include_str!("../cases/meshes/square.msh");

/// A coarse, short copy of the shipped case `text` for `solver`, its
/// comments and blank lines dropped: 4 × 4
/// cells (32 triangles a ply), a stroke of 3 mm (12 mm for the tetrahedron,
/// whose die opening is the punch's section 10 mm or more above its tip),
/// zones of 150 mm (so that each holds an element of the coarse mesh), 2
/// output states. Explicit: 10 history rows and the programme in 10 ms.
/// Quasi-static: the `solver` line, `[explicit]`, `output.history` and
/// `[[ply_contact]]` (explicit only) dropped, a `[solver]` table of Newton
/// knobs added. The work caps are added by [`with_caps`].
fn coarse(text: &str, solver: Solver) -> String {
    let stroke = if text.contains("shape = \"pyramid\"") {
        "12.0"
    } else {
        "3.0"
    };
    let qs = solver == Solver::QuasiStatic;
    let mut out = String::new();
    let mut table = String::new();
    for line in text.lines().map(uncommented) {
        if line.trim().is_empty() {
            continue;
        }
        let t = line.trim_start();
        if t.starts_with('[') {
            table = t.split('#').next().unwrap_or("").trim().to_string();
        }
        let key = t.split('=').next().unwrap_or("").trim();
        let l = match (table.as_str(), key) {
            ("", "solver") if qs => continue,
            ("[explicit]" | "[[ply_contact]]", _) if qs => continue,
            ("[output]", "history") if qs => continue,
            ("[ply.mesh]", "cells") => "cells = [4, 4]".to_string(),
            ("[[tool]]", "displacement") => format!("displacement = {stroke}"),
            ("[[zone]]", "size") => "size = [150.0, 150.0]".to_string(),
            ("[output]", "states") => "states = 2".to_string(),
            ("[output]", "history") => "history = 10".to_string(),
            ("[explicit]", "duration") => "duration = 0.01".to_string(),
            _ => line.to_string(),
        };
        out.push_str(&l);
        out.push('\n');
    }
    if qs {
        out.push_str(
            "\n[solver]\ninitial_increment = 0.25\nmax_increment = 0.5\n\
             min_increment = 0.01\nmax_iterations = 25\n",
        );
    }
    out
}

/// `line` without its comment (from an unquoted `#`), trailing blanks
/// removed: the shipped cases' comments hold many numbers, whose mutation
/// would change nothing.
fn uncommented(line: &str) -> &str {
    let mut quoted = false;
    for (i, c) in line.char_indices() {
        match c {
            '"' => quoted = !quoted,
            '#' if !quoted => return line[..i].trim_end(),
            _ => {}
        }
    }
    line.trim_end()
}

/// Whether a line sets a work cap (such lines are taken out of every
/// mutant and the seed's caps put back).
fn is_cap(line: &[u8]) -> bool {
    let t = String::from_utf8_lossy(line);
    let t = t.trim_start();
    t.starts_with("max_increments") || t.starts_with("max_wall_seconds")
}

/// Keys whose value sets the work of a run — the mesh, the outputs, the
/// Newton iterations of one step — with the largest value a mutant may
/// give and the seed's line that replaces a larger one: a mutant may make
/// them small or invalid, not ask for minutes of work (`output.states =
/// 2000` writes 2,000 VTU states and their PNG maps).
const LIMITS: &[(&str, f64, &str)] = &[
    ("cells", 16.0, "cells = [4, 4]\n"),
    ("states", 5.0, "states = 2\n"),
    ("history", 50.0, "history = 10\n"),
    ("max_iterations", 100.0, "max_iterations = 25\n"),
];

/// `line`, or the seed's line of its key when it gives a limited key
/// ([`LIMITS`]) a number above the limit.
fn within_limits(line: &[u8]) -> &[u8] {
    let text = String::from_utf8_lossy(line);
    let Some((key, value)) = text.split_once('=') else {
        return line;
    };
    let Some(&(_, limit, seed)) = LIMITS.iter().find(|(k, _, _)| *k == key.trim()) else {
        return line;
    };
    let too_large = fuzz_common::numeric_tokens(value.as_bytes())
        .into_iter()
        .any(|(s, e)| {
            value[s..e]
                .parse::<f64>()
                .map_or(true, |x| x.is_nan() || x > limit)
        });
    if too_large { seed.as_bytes() } else { line }
}

/// `text` with its caps and limits ([`LIMITS`]): every cap line removed, then `max_increments`
/// put under `[explicit]` when a top-level `solver = …` chooses a method
/// (else `max_wall_seconds` under `[solver]`), the table added at the end
/// if the text has none. So no mutant asks for more work than the seed.
fn with_caps(text: &[u8]) -> Vec<u8> {
    let lines: Vec<&[u8]> = text.split_inclusive(|&b| b == b'\n').collect();
    let kept: Vec<&[u8]> = lines
        .into_iter()
        .filter(|l| !is_cap(l))
        .map(within_limits)
        .collect();
    let starts = |l: &[u8], p: &str| String::from_utf8_lossy(l).trim_start().starts_with(p);
    let method = top_level_method(&kept);
    let (header, cap) = if method {
        ("[explicit]", MAX_INCREMENTS)
    } else {
        ("[solver]", MAX_WALL_SECONDS)
    };
    let mut out = Vec::with_capacity(text.len() + 40);
    let mut placed = false;
    for l in &kept {
        out.extend_from_slice(l);
        if !placed && starts(l, header) {
            if !out.ends_with(b"\n") {
                out.push(b'\n');
            }
            out.extend_from_slice(cap.as_bytes());
            out.push(b'\n');
            placed = true;
        }
    }
    if !placed {
        if !out.is_empty() && !out.ends_with(b"\n") {
            out.push(b'\n');
        }
        out.extend_from_slice(format!("\n{header}\n{cap}\n").as_bytes());
    }
    out
}

/// Whether a top-level `solver = …` line (before the first table header)
/// chooses a method.
fn top_level_method(lines: &[&[u8]]) -> bool {
    lines
        .iter()
        .map(|l| String::from_utf8_lossy(l))
        .take_while(|l| !l.trim_start().starts_with('['))
        .any(|l| {
            l.trim_start()
                .strip_prefix("solver")
                .is_some_and(|r| r.trim_start().starts_with('='))
        })
}

/// The seed of `shipped` for `solver`, without its caps (they are put
/// back by [`with_caps`] after mutation).
fn seed(shipped: &str, solver: Solver) -> String {
    coarse(shipped, solver)
}

/// One mutant: the case file's bytes, the other files written beside it,
/// what was done, and the key added where it does not apply (if that was
/// the mutation).
struct Mutant {
    case: Vec<u8>,
    files: Vec<(String, Vec<u8>)>,
    what: String,
    inapplicable: Option<&'static str>,
}

/// A key added where it does not apply: after the first line holding
/// `anchor` (`None`: appended at the end, a table with it), the line, the
/// key (which a refusal or a warning must name).
type Misplaced = (Option<&'static str>, &'static str, &'static str);

/// Keys that do not apply where they are put, for either solver.
const MISPLACED: &[Misplaced] = &[
    // A motion key on a fixed tool.
    (Some("name = \"die\""), "displacement = 5.0", "displacement"),
    (
        Some("name = \"die\""),
        "direction = [0.0, 0.0, -1.0]",
        "direction",
    ),
    (Some("name = \"die\""), "mass = 1.0", "mass"),
    (Some("name = \"die\""), "weight = 10.0", "weight"),
    // A floating tool's key on a prescribed one, the other way round.
    (Some("name = \"punch\""), "mass = 2.0", "mass"),
    (Some("name = \"punch\""), "weight = 20.0", "weight"),
    (
        Some("name = \"blankholder\""),
        "displacement = 5.0",
        "displacement",
    ),
    // A key of one shape on another.
    (Some("name = \"die\""), "radius = 10.0", "radius"),
    (Some("name = \"die\""), "sides = 4", "sides"),
    (
        Some("name = \"punch\""),
        "opening_radius = 50.0",
        "opening_radius",
    ),
    (
        Some("name = \"punch\""),
        "major_radius = 50.0",
        "major_radius",
    ),
    (Some("name = \"punch\""), "clearance = 3.0", "clearance"),
    (Some("name = \"punch\""), "scale = 2.0", "scale"),
    (Some("name = \"punch\""), "closed = false", "closed"),
    (
        Some("name = \"blankholder\""),
        "edge_direction = [1.0, 0.0, 0.0]",
        "edge_direction",
    ),
    // A [ply.mesh] key of the disk or the wrapped strip on a rectangle.
    (Some("[ply.mesh]"), "radius = 50.0", "radius"),
    (Some("[ply.mesh]"), "width = 20.0", "width"),
    (
        Some("[ply.mesh]"),
        "wrap_angle_deg = 90.0",
        "wrap_angle_deg",
    ),
    (Some("[ply.mesh]"), "tail_length = 10.0", "tail_length"),
];

/// Explicit-only keys, put into a quasi-static case.
const MISPLACED_QUASI_STATIC: &[Misplaced] = &[
    (None, "[explicit]\nduration = 0.01", "duration"),
    (
        None,
        "[explicit]\nroving_mass_length = 9.0",
        "roving_mass_length",
    ),
    (
        None,
        "[contact]\nexplicit_damping = 0.5",
        "explicit_damping",
    ),
    (
        None,
        "[contact]\nexplicit_stiffness = 0.5",
        "explicit_stiffness",
    ),
    (Some("[output]"), "history = 10", "history"),
];

/// Quasi-static-only keys, put into an explicit case.
const MISPLACED_EXPLICIT: &[Misplaced] = &[
    (None, "[contact]\npenalty_scale = 2.0", "penalty_scale"),
    (
        None,
        "[contact]\ntangential_penalty_scale = 0.1",
        "tangential_penalty_scale",
    ),
    (None, "[contact]\ngap_tolerance = 0.01", "gap_tolerance"),
    (
        None,
        "[contact]\nmultiplier_tolerance = 1e-4",
        "multiplier_tolerance",
    ),
    (None, "[contact]\npenalty = 100.0", "penalty"),
];

/// `text` with `line` after the first line holding `anchor` (or appended).
fn insert_after(text: &str, anchor: Option<&str>, line: &str) -> Option<String> {
    match anchor {
        None => Some(format!("{text}\n{line}\n")),
        Some(a) => {
            let at = text.find(a)?;
            let end = text[at..].find('\n').map_or(text.len(), |i| at + i + 1);
            Some(format!("{}{line}\n{}", &text[..end], &text[end..]))
        }
    }
}

/// Keys of the table starting at the first line holding `anchor` (up to
/// the next header), removed when their key is in `keys`; `with` put after
/// the anchor line.
fn replace_in_table(text: &str, anchor: &str, keys: &[&str], with: &str) -> Option<String> {
    let at = text.find(anchor)?;
    let head_end = text[at..].find('\n').map_or(text.len(), |i| at + i + 1);
    let rest = &text[head_end..];
    let table_end = rest
        .match_indices('\n')
        .map(|(i, _)| i + 1)
        .find(|&i| rest[i..].trim_start().starts_with('['))
        .unwrap_or(rest.len());
    let table: String = rest[..table_end]
        .split_inclusive('\n')
        .filter(|l| {
            let k = l.split('=').next().unwrap_or("").trim();
            !(l.contains('=') && keys.contains(&k))
        })
        .collect();
    Some(format!(
        "{}{with}\n{table}{}",
        &text[..head_end],
        &rest[table_end..]
    ))
}

/// The keys of a generated blank (taken out when a mesh file is given).
const GENERATED_BLANK: &[&str] = &["shape", "size", "cells", "pattern", "element_size"];

/// The keys of the analytic punches (taken out when it becomes a mesh).
const ANALYTIC_PUNCH: &[&str] = &[
    "shape",
    "radius",
    "sides",
    "face_angle_deg",
    "rounding_radius",
    "height",
    "edge_direction",
];

/// `bytes` cut at a random byte.
fn truncated(bytes: &[u8], rng: &mut StdRng) -> Vec<u8> {
    if bytes.is_empty() {
        return Vec::new();
    }
    bytes[..rng.random_range(0..bytes.len())].to_vec()
}

/// A mutant whose blank, punch or parameter set comes from a foreign,
/// truncated, empty or missing file (or, as a control, a sound one).
fn file_mutant(seed: &str, rng: &mut StdRng) -> Mutant {
    let params = MaterialSpec::named_text("schaefer2024").unwrap();
    match rng.random_range(0..3) {
        0 => {
            // The first ply's mesh from a file.
            let (name, bytes, what): (&str, Vec<u8>, &str) = match rng.random_range(0..10) {
                0 => ("blank.inp", SQUARE_INP.into(), "a sound .inp"),
                1 => ("blank.inp", SQUARE_MSH.into(), "a .msh named .inp"),
                2 => ("blank.msh", SQUARE_INP.into(), "an .inp named .msh"),
                3 => (
                    "blank.inp",
                    fuzz_common::binary_stl(),
                    "a binary STL named .inp",
                ),
                4 => (
                    "blank.stl",
                    fuzz_common::ascii_stl(),
                    "an STL as a ply mesh",
                ),
                5 => (
                    "blank.inp",
                    truncated(SQUARE_INP.as_bytes(), rng),
                    "a truncated .inp",
                ),
                6 => (
                    "blank.msh",
                    truncated(SQUARE_MSH.as_bytes(), rng),
                    "a truncated .msh",
                ),
                7 => ("blank.inp", Vec::new(), "an empty .inp"),
                8 => ("blank.obj", fuzz_common::obj(), "an OBJ as a ply mesh"),
                _ => ("missing.inp", Vec::new(), "a missing mesh file"),
            };
            let case = replace_in_table(
                seed,
                "[ply.mesh]",
                GENERATED_BLANK,
                &format!("file = \"{name}\""),
            )
            .unwrap_or_else(|| seed.to_string());
            let files = if name == "missing.inp" {
                Vec::new()
            } else {
                vec![(name.to_string(), bytes)]
            };
            Mutant {
                case: case.into_bytes(),
                files,
                what: format!("ply mesh: {what} ({name})"),
                inapplicable: None,
            }
        }
        1 => {
            // The punch as a mesh tool.
            let stl = fuzz_common::binary_stl_of(40.0, [-20.0, -20.0, 1.0]);
            let (name, bytes, what): (&str, Vec<u8>, &str) = match rng.random_range(0..8) {
                0 => ("punch.stl", stl, "a sound binary STL"),
                1 => ("punch.stl", truncated(&stl, rng), "a truncated binary STL"),
                2 => ("punch.stl", Vec::new(), "an empty STL"),
                3 => ("punch.stl", SQUARE_INP.into(), "an .inp named .stl"),
                4 => ("punch.stl", fuzz_common::obj(), "an OBJ named .stl"),
                5 => ("punch.obj", fuzz_common::ascii_stl(), "an STL named .obj"),
                6 => (
                    "punch.stl",
                    truncated(&fuzz_common::ascii_stl(), rng),
                    "a truncated ASCII STL",
                ),
                _ => ("punch.stl", SQUARE_MSH.into(), "a .msh named .stl"),
            };
            let case = replace_in_table(
                seed,
                "name = \"punch\"",
                ANALYTIC_PUNCH,
                &format!("shape = \"mesh\"\nfile = \"{name}\""),
            )
            .unwrap_or_else(|| seed.to_string());
            Mutant {
                case: case.into_bytes(),
                files: vec![(name.to_string(), bytes)],
                what: format!("punch mesh: {what} ({name})"),
                inapplicable: None,
            }
        }
        _ => {
            // Every ply's parameter set from a file.
            let (bytes, what): (Vec<u8>, String) = match rng.random_range(0..8) {
                0 => (params.into(), "the named set as a file".into()),
                1 => {
                    let (m, ops) = mutate(params.as_bytes(), rng, true);
                    (m, format!("numbers {ops:?}"))
                }
                2 => {
                    let (m, ops) = mutate_toml(params.as_bytes(), rng);
                    (m, format!("{ops:?}"))
                }
                3 => (truncated(params.as_bytes(), rng), "truncated".into()),
                4 => (Vec::new(), "empty".into()),
                5 => (fuzz_common::binary_stl(), "a binary STL".into()),
                6 => (SQUARE_INP.into(), "an .inp".into()),
                _ => (seed.as_bytes().to_vec(), "the case file itself".into()),
            };
            let case = seed.replace("params = \"schaefer2024\"", "params = \"fabric.toml\"");
            Mutant {
                case: case.into_bytes(),
                files: vec![("fabric.toml".to_string(), bytes)],
                what: format!("parameter file: {what}"),
                inapplicable: None,
            }
        }
    }
}

/// Mutant `k` of `seed` run with `solver`: a fifth general byte and TOML
/// mutations ([`mutate_toml`]: byte flips, truncations, lines deleted or
/// doubled, odd strings, wrong types, moved keys, extreme numbers), 15 %
/// one or two numbers scaled (by 10⁻⁶ … 10⁶, −1 or 0: values the readers
/// accept, which reach the solver), 15 % one to three extreme numbers, 10 %
/// wrong types only, 5 % a moved key, 10 % a key where it does not apply,
/// 20 % foreign, truncated or empty mesh, tool and parameter files.
fn mutant(seed: &str, solver: Solver, rng: &mut StdRng) -> Mutant {
    let bytes = seed.as_bytes();
    let ops = |ops: Vec<Operator>| format!("{ops:?}");
    match rng.random_range(0..20) {
        0..=4 => {
            let (m, o) = mutate_toml(bytes, rng);
            Mutant {
                case: m,
                files: Vec::new(),
                what: ops(o),
                inapplicable: None,
            }
        }
        5..=7 => {
            let n = rng.random_range(1..=2);
            let mut m = bytes.to_vec();
            for _ in 0..n {
                m = fuzz_common::apply(&m, Operator::ScaleNumber, rng);
            }
            Mutant {
                case: m,
                files: Vec::new(),
                what: ops(vec![Operator::ScaleNumber; n]),
                inapplicable: None,
            }
        }
        8..=10 => {
            let (m, o) = mutate(bytes, rng, true);
            Mutant {
                case: m,
                files: Vec::new(),
                what: ops(o),
                inapplicable: None,
            }
        }
        11 | 12 => {
            let n = rng.random_range(1..=2);
            let mut m = bytes.to_vec();
            for _ in 0..n {
                m = fuzz_common::apply(&m, Operator::WrongType, rng);
            }
            Mutant {
                case: m,
                files: Vec::new(),
                what: ops(vec![Operator::WrongType; n]),
                inapplicable: None,
            }
        }
        13 => Mutant {
            case: fuzz_common::apply(bytes, Operator::MoveKey, rng),
            files: Vec::new(),
            what: ops(vec![Operator::MoveKey]),
            inapplicable: None,
        },
        14 | 15 => {
            let extra = match solver {
                Solver::QuasiStatic => MISPLACED_QUASI_STATIC,
                Solver::Explicit => MISPLACED_EXPLICIT,
            };
            let all: Vec<&Misplaced> = MISPLACED.iter().chain(extra).collect();
            // Only those whose anchor the seed has.
            let fit: Vec<&&Misplaced> = all
                .iter()
                .filter(|(a, _, _)| a.is_none_or(|a| seed.contains(a)))
                .collect();
            let (anchor, line, key) = **fit[rng.random_range(0..fit.len())];
            let case = insert_after(seed, anchor, line).unwrap_or_else(|| seed.to_string());
            Mutant {
                case: case.into_bytes(),
                files: Vec::new(),
                what: format!("inapplicable key: {line:?} after {anchor:?}"),
                inapplicable: Some(key),
            }
        }
        _ => file_mutant(seed, rng),
    }
}

/// What one run broke: each property's class and what was seen.
type Broken = Vec<(&'static str, String)>;

/// Runs one mutant in a scratch folder; returns the properties it broke
/// and whether the solver ran (the case was accepted and solved).
fn check_run(m: Mutant, k: usize) -> (Broken, bool) {
    let dir = tempfile::tempdir().expect("a scratch folder");
    let case_path = dir.path().join(format!("case-{k}.toml"));
    std::fs::write(&case_path, with_caps(&m.case)).unwrap();
    let mut named = vec![case_path.display().to_string()];
    for (name, bytes) in &m.files {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        named.push(p.display().to_string());
    }
    let out = dir.path().join("out");
    let mut broken: Broken = Vec::new();
    let loaded = FormingCase::load(&case_path);
    let case_debug = loaded.as_ref().map(|c| format!("{c:?}")).ok();
    let result = match &loaded {
        Err(e) => Err(e.to_string()),
        Ok(case) => run_forming(case, &out, Progress::Quiet).map_err(|e| e.to_string()),
    };
    let ran = result.is_ok();
    if std::env::var_os("NCFORM_FUZZ_TRACE").is_some() {
        eprintln!(
            "trace #{k} {}: {}",
            m.what,
            match &result {
                Ok(s) => format!("ok {:?}", s.exit_status),
                Err(e) => fuzz_common::clip(e, 600),
            }
        );
    }
    let exit = match &result {
        Ok(s) => s.exit_status.code(),
        Err(_) => 1,
    };
    // Messages only: the summary's numbers are data.
    let text = match &result {
        Ok(summary) => fuzz_common::debug_strings(&format!("{summary:?}")),
        Err(msg) => msg.clone(),
    };
    let mut input = with_caps(&m.case);
    for (_, b) in &m.files {
        input.extend_from_slice(b);
    }
    if let Some(n) = fuzz_common::long_number(&text, &input) {
        broken.push((
            "long-number",
            format!(
                "a message writes a {}-digit number: {}",
                n.len(),
                fuzz_common::clip(&text.replace(&n, "<HERE>"), 1500)
            ),
        ));
    }
    match &result {
        Ok(summary) => {
            if let Some(at) = accepted_non_finite(&format!("{summary:?}")) {
                broken.push((
                    "summary-non-finite",
                    format!("a non-finite number in the returned summary: {at}"),
                ));
            }
        }
        Err(msg) if named.iter().any(|n| msg.contains(n.as_str())) => {}
        Err(msg) => broken.push((
            "error-unnamed",
            format!("the error names neither the case nor the file at fault: {msg}"),
        )),
    }
    if let Some(key) = m.inapplicable {
        let warnings = std::fs::read_to_string(out.join("summary.json")).unwrap_or_default();
        let reported = text.contains(key)
            || case_debug
                .as_deref()
                .is_some_and(|d| fuzz_common::debug_strings(d).contains(key))
            || warnings
                .split("\"warnings\"")
                .skip(1)
                .any(|w| w.split(']').next().is_some_and(|w| w.contains(key)));
        if !reported {
            broken.push((
                "inapplicable-key-silent",
                format!(
                    "`{key}` where it does not apply was accepted without a word ({})",
                    match &result {
                        Ok(_) => "the run went on",
                        Err(_) => "the run failed on something else",
                    }
                ),
            ));
        }
    }
    for FolderProblem { class, detail } in check_run_folder(&out, exit) {
        broken.push((class, detail));
    }
    (broken, ran)
}

/// The lines of `mutant` that differ from `seed`, by a longest common
/// subsequence of lines: `-N: line` for a seed line `N` the mutant lost,
/// `+N: line` for a mutant line `N` the seed does not have.
fn diff(seed: &[u8], mutant: &[u8]) -> String {
    let a: Vec<&[u8]> = seed.split_inclusive(|&b| b == b'\n').collect();
    let b: Vec<&[u8]> = mutant.split_inclusive(|&b| b == b'\n').collect();
    let (n, m) = (a.len(), b.len());
    // lcs[i][j]: the longest common subsequence of a[i..] and b[j..].
    let mut lcs = vec![vec![0u32; m + 1]; n + 1];
    for i in (0..n).rev() {
        for j in (0..m).rev() {
            lcs[i][j] = if a[i] == b[j] {
                lcs[i + 1][j + 1] + 1
            } else {
                lcs[i + 1][j].max(lcs[i][j + 1])
            };
        }
    }
    let line = |l: &[u8]| {
        String::from_utf8_lossy(l)
            .trim_end_matches('\n')
            .to_string()
    };
    let (mut i, mut j, mut out) = (0, 0, String::new());
    while i < n || j < m {
        if i < n && j < m && a[i] == b[j] {
            i += 1;
            j += 1;
        } else if j < m && (i == n || lcs[i][j + 1] >= lcs[i + 1][j]) {
            out.push_str(&format!("+{}: {}\n", j + 1, line(b[j])));
            j += 1;
        } else {
            out.push_str(&format!("-{}: {}\n", i + 1, line(a[i])));
            i += 1;
        }
    }
    out
}

/// One broken property of one mutant.
struct Found {
    k: usize,
    what: String,
    class: &'static str,
    detail: String,
    input: String,
    known: Option<&'static str>,
}

/// Mutants of one seed with one solver; fails on any failure outside
/// [`fuzz_common::FUZZ_KNOWN`] and when fewer than a twentieth of the mutants reached the
/// solver (the harness would then test only the input checks).
fn campaign(shipped: &str, text: &str, solver: Solver) {
    quiet_panics();
    let name = format!("forming-{shipped}-{solver:?}");
    let test = format!(
        "fuzz_{}_{}",
        shipped.replace('-', "_"),
        match solver {
            Solver::Explicit => "explicit",
            Solver::QuasiStatic => "quasi_static",
        }
    );
    let seed = seed(text, solver);
    let count = match std::env::var("NCFORM_FUZZ_ONLY") {
        Ok(v) => v
            .split(',')
            .filter_map(|n| n.trim().parse::<usize>().ok())
            .max()
            .map_or(0, |m| m + 1),
        Err(_) => cases_scaled(DEFAULT_CASES, RUN_COST),
    };
    let started = Instant::now();
    let mut found: Vec<Found> = Vec::new();
    let mut solved = 0;
    let only: Option<Vec<usize>> = std::env::var("NCFORM_FUZZ_ONLY")
        .ok()
        .map(|v| v.split(',').filter_map(|n| n.trim().parse().ok()).collect());
    for k in 0..count {
        if only.as_ref().is_some_and(|o| !o.contains(&k)) {
            continue;
        }
        let mut rng = fuzz_common::rng_for(&name, k);
        let m = mutant(&seed, solver, &mut rng);
        let what = m.what.clone();
        let mut input = diff(&with_caps(seed.as_bytes()), &with_caps(&m.case)).into_bytes();
        for (n, b) in &m.files {
            input.extend_from_slice(format!("\n--- {n} ({} bytes):\n", b.len()).as_bytes());
            input.extend_from_slice(&b[..b.len().min(600)]);
        }
        let broken = match guarded(BOUND, move || check_run(m, k)) {
            Ok((broken, ran)) => {
                solved += usize::from(ran);
                broken
            }
            Err(e) if e.starts_with("panicked") => vec![("panic", e)],
            Err(e) => vec![("hang", e)],
        };
        for (class, detail) in broken {
            found.push(Found {
                k,
                what: what.clone(),
                class,
                known: known(class, &detail),
                detail,
                input: show(&input),
            });
        }
    }
    let new: Vec<&Found> = found.iter().filter(|f| f.known.is_none()).collect();
    let mut by_known: Vec<(&str, usize)> = Vec::new();
    for f in found.iter().filter_map(|f| f.known) {
        match by_known.iter_mut().find(|(n, _)| *n == f) {
            Some((_, c)) => *c += 1,
            None => by_known.push((f, 1)),
        }
    }
    eprintln!(
        "{name}: {count} mutants, {solved} solved, {} failures ({} new; known: {by_known:?}) in {:.1} s (seed {})",
        found.len(),
        new.len(),
        started.elapsed().as_secs_f64(),
        fuzz_common::base_seed()
    );
    if std::env::var_os("NCFORM_FUZZ_VERBOSE").is_some() {
        for f in found.iter().filter(|f| f.known.is_some()) {
            eprintln!(
                "  known {} #{} {}: [{}] {}",
                f.known.unwrap_or(""),
                f.k,
                f.what,
                f.class,
                fuzz_common::clip(&f.detail, 300)
            );
        }
    }
    for f in &new {
        eprintln!(
            "FAIL {name} #{} {}: [{}] {}",
            f.k,
            f.what,
            f.class,
            fuzz_common::clip(&f.detail, 400).replace('\n', " ")
        );
    }
    if !new.is_empty() {
        let mut msg = format!(
            "{name}: {} failures in {count} mutants (seed {}):\n",
            new.len(),
            fuzz_common::base_seed()
        );
        for f in new.iter().take(8) {
            msg.push_str(&format!(
                "--- {name} #{} {}: [{}] {}\n(again: NCFORM_FUZZ_SEED={} NCFORM_FUZZ_ONLY={} cargo test --release --test fuzz_forming {test}; the mutant against the seed:)\n{}\n",
                f.k,
                f.what,
                f.class,
                fuzz_common::clip(&f.detail, 3000),
                fuzz_common::base_seed(),
                f.k,
                f.input
            ));
        }
        panic!("{msg}");
    }
    assert!(
        20 * solved >= count,
        "{name}: only {solved} of {count} mutants reached the solver"
    );
}

/// The seeds as they are run to the end, complete, with sound run
/// folders (outside [`fuzz_common::FUZZ_KNOWN`]): a check that the harness exercises
/// the solvers and not only their input checks, and that the coarse
/// copies still follow the shipped cases.
#[test]
fn seeds_run_to_the_end() {
    for (shipped, text) in SHIPPED {
        for solver in [Solver::Explicit, Solver::QuasiStatic] {
            let dir = tempfile::tempdir().unwrap();
            let case: PathBuf = dir.path().join("case.toml");
            std::fs::write(&case, with_caps(seed(text, solver).as_bytes())).unwrap();
            let out = dir.path().join("out");
            let loaded = FormingCase::load(&case)
                .unwrap_or_else(|e| panic!("{shipped} {solver:?}: the seed is refused: {e}"));
            let summary = run_forming(&loaded, &out, Progress::Quiet)
                .unwrap_or_else(|e| panic!("{shipped} {solver:?}: the seed fails: {e}"));
            assert!(
                summary.complete,
                "{shipped} {solver:?}: the seed did not run to the end: {:?}",
                summary.status
            );
            let problems: Vec<String> = check_run_folder(&out, summary.exit_status.code())
                .into_iter()
                .filter(|p| known(p.class, &p.detail).is_none())
                .map(|p| p.to_string())
                .collect();
            assert!(
                problems.is_empty(),
                "{shipped} {solver:?}: the seed's run folder: {problems:#?}"
            );
        }
    }
}

/// The caps are in every mutant, once, in their table.
#[test]
fn caps_survive_mutation() {
    for (shipped, text) in SHIPPED {
        for solver in [Solver::Explicit, Solver::QuasiStatic] {
            let s = seed(text, solver);
            for k in 0..200 {
                let mut rng = fuzz_common::rng_for("caps", k);
                let m = with_caps(&mutant(&s, solver, &mut rng).case);
                let t = String::from_utf8_lossy(&m);
                let cap = match solver {
                    Solver::Explicit => MAX_INCREMENTS,
                    Solver::QuasiStatic => MAX_WALL_SECONDS,
                };
                let other = match solver {
                    Solver::Explicit => MAX_WALL_SECONDS,
                    Solver::QuasiStatic => MAX_INCREMENTS,
                };
                let lines: Vec<&[u8]> = m.split_inclusive(|&b| b == b'\n').collect();
                let method = top_level_method(&lines);
                // A mutant may lose or gain the `solver` line; the cap
                // follows the method the mutant asks for.
                let cap = if method == (solver == Solver::Explicit) {
                    cap
                } else {
                    other
                };
                assert_eq!(
                    t.matches(cap).count(),
                    1,
                    "{shipped} {solver:?} #{k}: the cap is not in the mutant once:\n{t}"
                );
            }
        }
    }
}

/// Property: mutants of the coarse [0°] hemisphere, explicit.
#[test]
fn fuzz_hemisphere_0_explicit() {
    campaign(SHIPPED[0].0, SHIPPED[0].1, Solver::Explicit);
}

/// Property: mutants of the coarse [0°] hemisphere, quasi-static.
#[test]
fn fuzz_hemisphere_0_quasi_static() {
    campaign(SHIPPED[0].0, SHIPPED[0].1, Solver::QuasiStatic);
}

/// Property: mutants of the coarse [45°] hemisphere, explicit.
#[test]
fn fuzz_hemisphere_45_explicit() {
    campaign(SHIPPED[1].0, SHIPPED[1].1, Solver::Explicit);
}

/// Property: mutants of the coarse [45°] hemisphere, quasi-static.
#[test]
fn fuzz_hemisphere_45_quasi_static() {
    campaign(SHIPPED[1].0, SHIPPED[1].1, Solver::QuasiStatic);
}

/// Property: mutants of the coarse [0°/90°] hemisphere with ply contact,
/// explicit.
#[test]
fn fuzz_hemisphere_0_90_explicit() {
    campaign(SHIPPED[2].0, SHIPPED[2].1, Solver::Explicit);
}

/// Property: mutants of the coarse [0°/90°] hemisphere, quasi-static
/// (without the ply contact, which the quasi-static path does not take).
#[test]
fn fuzz_hemisphere_0_90_quasi_static() {
    campaign(SHIPPED[2].0, SHIPPED[2].1, Solver::QuasiStatic);
}

/// Property: mutants of the coarse [0°] tetrahedron, explicit.
#[test]
fn fuzz_tetrahedron_0_explicit() {
    campaign(SHIPPED[3].0, SHIPPED[3].1, Solver::Explicit);
}

/// Property: mutants of the coarse [0°] tetrahedron, quasi-static.
#[test]
fn fuzz_tetrahedron_0_quasi_static() {
    campaign(SHIPPED[3].0, SHIPPED[3].1, Solver::QuasiStatic);
}
