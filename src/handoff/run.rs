//! A forming run's folder read back for the hand-off (`docs/export.md`):
//! its plies at one written state, from `summary.json`,
//! `case.resolved.json` and the plies' VTU files (`vtu/<ply>_NNNN.vtu`,
//! with the orientation fields every forming run writes). Only what the
//! folder holds is used: the hand-off needs no case file and no solve.

use std::fs;
use std::path::{Path, PathBuf};

use super::{Layer, ShellElement, ShellMesh};

/// Why a run folder cannot be handed on.
#[derive(Debug, thiserror::Error)]
pub enum RunFolderError {
    /// A file of the folder cannot be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// A file's content is not what a forming run writes.
    #[error("{path}: {what}")]
    Content {
        /// The file.
        path: PathBuf,
        /// What is wrong, with the value found.
        what: String,
    },
    /// The folder holds no written state of a ply.
    #[error(
        "{run}: no finished state of ply \"{ply}\" (no vtu/{stem}_NNNN.vtu): the run wrote none, or this is not a forming run's folder"
    )]
    NoState {
        /// The run folder.
        run: PathBuf,
        /// The ply.
        ply: String,
        /// Its file stem.
        stem: String,
    },
    /// A state asked for that the folder does not hold.
    #[error("{run}: --state {state}: ply \"{ply}\" has states {available}")]
    StateOutOfRange {
        /// The run folder.
        run: PathBuf,
        /// The state asked for.
        state: usize,
        /// The ply.
        ply: String,
        /// The states written.
        available: String,
    },
    /// A ply asked for that the run does not have.
    #[error("{run}: --ply {given}: the run's plies are {plies} (a name or a number from 1)")]
    PlyOutOfRange {
        /// The run folder.
        run: PathBuf,
        /// The value given.
        given: String,
        /// The plies of the run, quoted.
        plies: String,
    },
    /// The state is the last converged state of a run that did not finish.
    #[error(
        "{run}: state {state} is the last converged state of a run that did not finish ({status}); pass --incomplete to export it anyway (the file's header will say so)"
    )]
    Incomplete {
        /// The run folder.
        run: PathBuf,
        /// The state.
        state: usize,
        /// The run's status.
        status: String,
    },
}

/// One ply of a run at one written state.
#[derive(Debug, Clone, PartialEq)]
pub struct FormedPly {
    /// Its name.
    pub name: String,
    /// Its thickness in the case \[mm\].
    pub thickness: f64,
    /// Its design fibre angle \[deg\].
    pub design_angle_deg: f64,
    /// Current node positions \[mm\].
    pub nodes: Vec<[f64; 3]>,
    /// Reference node positions (current less the displacement) \[mm\].
    pub reference: Vec<[f64; 3]>,
    /// Triangles (node indices).
    pub triangles: Vec<[usize; 3]>,
    /// Element labels of the ply's mesh.
    pub labels: Vec<u64>,
    /// Current unit fibre direction per element (`fibre_direction`).
    pub fibre: Vec<[f64; 3]>,
    /// Whether the element's directions are defined (`orientation_valid`).
    pub valid: Vec<bool>,
}

impl FormedPly {
    /// The ply as a shell mesh of its own (node labels from 1, its element
    /// labels) and as the one layer on it (its fibre directions where
    /// defined).
    pub fn shell_mesh(&self, source: &str) -> (ShellMesh, Layer) {
        let mesh = ShellMesh {
            source: source.to_string(),
            node_labels: (1..=self.nodes.len() as u64).collect(),
            nodes: self.nodes.clone(),
            elements: self
                .triangles
                .iter()
                .zip(&self.labels)
                .map(|(t, &label)| ShellElement {
                    label,
                    nodes: t.to_vec(),
                    abaqus_type: String::new(),
                })
                .collect(),
        };
        let layer = Layer {
            name: self.name.clone(),
            thickness: self.thickness,
            fibre: self
                .fibre
                .iter()
                .zip(&self.valid)
                .map(|(a, &ok)| ok.then_some(*a))
                .collect(),
        };
        (mesh, layer)
    }
}

/// The plies of a run at one written state.
#[derive(Debug, Clone, PartialEq)]
pub struct FormedState {
    /// The run folder.
    pub run: PathBuf,
    /// The case's title.
    pub title: String,
    /// The state's number (the `NNNN` of its files).
    pub state: usize,
    /// Its programme fraction line, as the VTU says it.
    pub load_line: String,
    /// Whether the run finished.
    pub complete: bool,
    /// The run's status, as `summary.json` says it.
    pub status: String,
    /// Whether the state is the last converged state of an unfinished run.
    pub last_converged: bool,
    /// The plies read, in the order asked for.
    pub plies: Vec<FormedPly>,
}

impl FormedState {
    /// The provenance lines of a hand-off file.
    pub fn header(&self) -> Vec<String> {
        let mut lines = vec![
            format!("formed by ncform {}", env!("CARGO_PKG_VERSION")),
            format!("run folder: {}", self.run.display()),
            format!("case: {}", self.title),
            format!("state {}: {}", self.state, self.load_line),
            format!(
                "plies: {}",
                self.plies
                    .iter()
                    .map(|p| format!("\"{}\"", p.name))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ];
        if self.last_converged {
            lines.push(format!(
                "WARNING: the run did not finish ({}); this is its last converged state, exported on request (--incomplete)",
                self.status
            ));
        }
        lines
    }
}

fn read_text(path: &Path) -> Result<String, RunFolderError> {
    fs::read_to_string(path).map_err(|source| RunFolderError::Read {
        path: path.to_path_buf(),
        source,
    })
}

fn read_json(path: &Path) -> Result<serde_json::Value, RunFolderError> {
    serde_json::from_str(&read_text(path)?).map_err(|e| RunFolderError::Content {
        path: path.to_path_buf(),
        what: format!("not JSON: {e}"),
    })
}

/// The plies of the run in `run` (name, thickness, design angle), from
/// `case.resolved.json`.
pub fn run_plies(run: &Path) -> Result<Vec<(String, f64, f64)>, RunFolderError> {
    let path = run.join("case.resolved.json");
    let doc = read_json(&path)?;
    let content = |what: &str| RunFolderError::Content {
        path: path.clone(),
        what: what.to_string(),
    };
    let plies = doc
        .pointer("/case/plies")
        .and_then(|p| p.as_array())
        .ok_or_else(|| {
            content("no case.plies: not a forming run (the hand-off takes formed plies)")
        })?;
    plies
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let name = p.get("name").and_then(|v| v.as_str());
            let thickness = p.get("thickness").and_then(|v| v.as_f64());
            let angle = p.get("fibre_angle_deg").and_then(|v| v.as_f64());
            match (name, thickness, angle) {
                (Some(n), Some(t), Some(a)) => Ok((n.to_string(), t, a)),
                _ => Err(content(&format!(
                    "case.plies[{i}]: expected name, thickness and fibre_angle_deg"
                ))),
            }
        })
        .collect()
}

/// The index of the ply `given` (a name, or a number from 1) among the
/// `plies`' names.
pub fn ply_index(run: &Path, plies: &[String], given: &str) -> Result<usize, RunFolderError> {
    plies
        .iter()
        .position(|p| p == given)
        .or_else(|| {
            given
                .parse::<usize>()
                .ok()
                .filter(|&k| k >= 1 && k <= plies.len())
                .map(|k| k - 1)
        })
        .ok_or_else(|| RunFolderError::PlyOutOfRange {
            run: run.to_path_buf(),
            given: given.to_string(),
            plies: plies
                .iter()
                .map(|p| format!("\"{p}\""))
                .collect::<Vec<_>>()
                .join(", "),
        })
}

/// The states written for the ply of file stem `stem`, ascending.
fn written_states(run: &Path, stem: &str) -> Result<Vec<usize>, RunFolderError> {
    let dir = run.join("vtu");
    let entries = match fs::read_dir(&dir) {
        Ok(entries) => entries,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(source) => return Err(RunFolderError::Read { path: dir, source }),
    };
    let prefix = format!("{stem}_");
    let mut states: Vec<usize> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().to_string();
            name.strip_prefix(&prefix)?
                .strip_suffix(".vtu")?
                .parse()
                .ok()
        })
        .collect();
    states.sort_unstable();
    Ok(states)
}

/// Reads the plies `plies` (indices into the run's plies) of the run in
/// `run` at state `state` (`None`: the last written). The last converged
/// state of a run that did not finish is read only when `incomplete` is
/// set.
///
/// # Errors
/// A missing or unreadable file, a ply or state the run does not have,
/// or an unfinished run's last state without `incomplete`.
pub fn read_formed_state(
    run: &Path,
    plies: &[usize],
    state: Option<usize>,
    incomplete: bool,
) -> Result<FormedState, RunFolderError> {
    let summary_path = run.join("summary.json");
    let summary = read_json(&summary_path)?;
    let complete = summary
        .get("complete")
        .and_then(|v| v.as_bool())
        .ok_or_else(|| RunFolderError::Content {
            path: summary_path.clone(),
            what: "no \"complete\": not a run's summary".into(),
        })?;
    let status = summary
        .get("status")
        .map_or_else(|| "unknown".to_string(), |s| s.to_string());
    let title = summary
        .get("title")
        .and_then(|v| v.as_str())
        .unwrap_or("")
        .to_string();
    let specs = run_plies(run)?;
    let mut out = FormedState {
        run: run.to_path_buf(),
        title,
        state: 0,
        load_line: String::new(),
        complete,
        status,
        last_converged: false,
        plies: Vec::new(),
    };
    for &p in plies {
        let Some((name, thickness, angle)) = specs.get(p) else {
            return Err(RunFolderError::PlyOutOfRange {
                run: run.to_path_buf(),
                given: (p + 1).to_string(),
                plies: specs
                    .iter()
                    .map(|s| format!("\"{}\"", s.0))
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        };
        let stem = crate::report::forming::file_stem(name);
        let states = written_states(run, &stem)?;
        let Some(&last) = states.last() else {
            return Err(RunFolderError::NoState {
                run: run.to_path_buf(),
                ply: name.clone(),
                stem,
            });
        };
        let chosen = state.unwrap_or(last);
        if !states.contains(&chosen) {
            return Err(RunFolderError::StateOutOfRange {
                run: run.to_path_buf(),
                state: chosen,
                ply: name.clone(),
                available: format!("{}..={} ({} written)", states[0], last, states.len()),
            });
        }
        let path = run.join("vtu").join(format!("{stem}_{chosen:04}.vtu"));
        let vtu = read_ply_vtu(&path)?;
        let last_converged = vtu
            .load_line
            .contains(crate::report::LAST_STATE_NOTE.trim())
            || (!complete && chosen == last);
        if last_converged && !incomplete {
            return Err(RunFolderError::Incomplete {
                run: run.to_path_buf(),
                state: chosen,
                status: out.status.clone(),
            });
        }
        out.state = chosen;
        out.load_line = vtu.load_line.clone();
        out.last_converged |= last_converged;
        out.plies.push(FormedPly {
            name: name.clone(),
            thickness: *thickness,
            design_angle_deg: *angle,
            nodes: vtu.points,
            reference: vtu.reference,
            triangles: vtu.triangles,
            labels: vtu.labels,
            fibre: vtu.fibre,
            valid: vtu.valid,
        });
    }
    Ok(out)
}

/// What the hand-off reads of a ply's VTU.
struct PlyVtu {
    load_line: String,
    points: Vec<[f64; 3]>,
    reference: Vec<[f64; 3]>,
    triangles: Vec<[usize; 3]>,
    labels: Vec<u64>,
    fibre: Vec<[f64; 3]>,
    valid: Vec<bool>,
}

/// Reads a ply's VTU as a forming run writes it (ASCII arrays).
fn read_ply_vtu(path: &Path) -> Result<PlyVtu, RunFolderError> {
    let text = read_text(path)?;
    let bad = |what: String| RunFolderError::Content {
        path: path.to_path_buf(),
        what,
    };
    let doc = roxmltree::Document::parse(&text).map_err(|e| bad(format!("not XML: {e}")))?;
    let load_line = doc
        .root()
        .children()
        .filter(|n| n.is_comment())
        .filter_map(|n| n.text())
        .find(|t| t.contains("programme fraction"))
        .unwrap_or("")
        .trim()
        .to_string();
    let piece = doc
        .descendants()
        .find(|n| n.has_tag_name("Piece"))
        .ok_or_else(|| bad("no <Piece>".into()))?;
    let count = |attr: &str| -> Result<usize, RunFolderError> {
        piece
            .attribute(attr)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| bad(format!("<Piece>: no valid {attr}")))
    };
    let (points_n, cells_n) = (count("NumberOfPoints")?, count("NumberOfCells")?);
    let array = |parent: &str, name: Option<&str>| -> Result<Vec<f64>, RunFolderError> {
        let node = piece
            .descendants()
            .filter(|n| n.has_tag_name(parent))
            .flat_map(|n| n.descendants())
            .find(|n| {
                n.has_tag_name("DataArray")
                    && name.is_none_or(|want| n.attribute("Name") == Some(want))
            })
            .ok_or_else(|| {
                bad(format!(
                    "no <{parent}> array{} (written by ncform before orientation fields? rerun the case)",
                    name.map(|n| format!(" \"{n}\"")).unwrap_or_default()
                ))
            })?;
        node.text()
            .unwrap_or("")
            .split_ascii_whitespace()
            .map(|v| {
                v.parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| bad(format!("array {name:?}: not a finite number: {v:?}")))
            })
            .collect()
    };
    let triples =
        |values: Vec<f64>, what: &str, n: usize| -> Result<Vec<[f64; 3]>, RunFolderError> {
            if values.len() != 3 * n {
                return Err(bad(format!(
                    "{what}: {} values, expected {}",
                    values.len(),
                    3 * n
                )));
            }
            Ok(values.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
        };
    let points = triples(array("Points", None)?, "Points", points_n)?;
    let displacement = triples(
        array("PointData", Some("displacement"))?,
        "displacement",
        points_n,
    )?;
    let connectivity = array("Cells", Some("connectivity"))?;
    if connectivity.len() != 3 * cells_n
        || connectivity
            .iter()
            .any(|&k| k < 0.0 || k.fract() != 0.0 || k as usize >= points_n)
    {
        return Err(bad(format!(
            "connectivity: expected {cells_n} triangles of nodes 0..{points_n}"
        )));
    }
    let triangles = connectivity
        .chunks_exact(3)
        .map(|c| [c[0] as usize, c[1] as usize, c[2] as usize])
        .collect();
    let fibre = triples(
        array("CellData", Some("fibre_direction"))?,
        "fibre_direction",
        cells_n,
    )?;
    let scalars = |name: &str| -> Result<Vec<f64>, RunFolderError> {
        let v = array("CellData", Some(name))?;
        if v.len() == cells_n {
            Ok(v)
        } else {
            Err(bad(format!(
                "{name}: {} values, expected {cells_n}",
                v.len()
            )))
        }
    };
    let labels = scalars("element_label")?
        .iter()
        .enumerate()
        .map(|(e, &l)| if l >= 1.0 { l as u64 } else { e as u64 + 1 })
        .collect();
    let valid = scalars("orientation_valid")?
        .iter()
        .map(|&v| v > 0.0)
        .collect();
    let reference = points
        .iter()
        .zip(&displacement)
        .map(|(x, u)| [x[0] - u[0], x[1] - u[1], x[2] - u[2]])
        .collect();
    Ok(PlyVtu {
        load_line,
        points,
        reference,
        triangles,
        labels,
        fibre,
        valid,
    })
}
