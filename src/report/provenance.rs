//! The resolved case and its provenance, written to every run folder as
//! `case.resolved.json` (`docs/cases.md`, "The run folder"): the case as
//! the run used it, every default filled in, and where it came from — the
//! ncform version, the git commit the binary was built from, and the
//! SHA-256 of every file the case read (the case file, parameter files,
//! mesh and tool files).
//!
//! The resolved case is built from the case structs' public fields: plain
//! numbers, names and switches as JSON values; the solver settings as
//! their serialised structs; the few nested choices that have no JSON form
//! of their own (a mesh's source, a tool's shape and motion, a load's
//! amplitude, the law's parameters) as their Rust notation in a string.

use std::path::{Path, PathBuf};

use serde::Serialize;
use serde_json::{Value, json};
use sha2::{Digest, Sha256};

use super::runner::Built;
use crate::case::forming::{FormingCase, PlyMesh, ToolShape};
use crate::case::oat::MeshSource;
use crate::case::{Case, OatCase};
use crate::material::MaterialSpec;

/// The run-folder file of the resolved case and its provenance.
pub const RESOLVED_CASE_FILE: &str = "case.resolved.json";

/// The `format` of [`RESOLVED_CASE_FILE`] this version writes.
pub const RESOLVED_FORMAT: &str = "ncform-resolved-case-1";

/// The git commit the binary was built from (`build.rs`), or "unknown"
/// when it was built outside a git checkout.
pub const GIT_COMMIT: &str = match option_env!("NCFORM_GIT_COMMIT") {
    Some(commit) => commit,
    None => "unknown",
};

/// A file the case read, with its hash.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct InputFile {
    /// What it is: `case file`, `parameter file of ply "…"`, `mesh`, …
    pub role: String,
    /// The path as the case gives it (resolved against the case file's
    /// folder).
    pub path: String,
    /// Its size \[bytes\] (`None` when it could not be read).
    pub bytes: Option<u64>,
    /// SHA-256 of its content, lower-case hex, or why it could not be read
    /// (`unreadable: …`).
    pub sha256: String,
}

/// A case of either scenario, borrowed.
#[derive(Clone, Copy)]
enum Scenario<'a> {
    Oat(&'a OatCase),
    Forming(&'a FormingCase),
}

impl<'a> From<&'a Case> for Scenario<'a> {
    fn from(case: &'a Case) -> Self {
        match case {
            Case::Oat(c) => Scenario::Oat(c),
            Case::Forming(c) => Scenario::Forming(c),
        }
    }
}

/// Where a run came from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Provenance {
    /// The ncform version (`Cargo.toml`).
    pub ncform_version: String,
    /// The git commit of the build, or "unknown".
    pub git_commit: String,
    /// Every file the case read, the case file first.
    pub inputs: Vec<InputFile>,
}

/// The lower-case hex SHA-256 of `bytes`.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The input `path` of role `role`, hashed now.
fn input(role: String, path: &Path) -> InputFile {
    let (bytes, sha256) = match std::fs::read(path) {
        Ok(content) => (Some(content.len() as u64), sha256_hex(&content)),
        Err(e) => (None, format!("unreadable: {e}")),
    };
    InputFile {
        role,
        path: path.display().to_string(),
        bytes,
        sha256,
    }
}

/// `path` as the case read it: taken from the case file's folder when
/// relative and not found from the working folder.
fn resolved(case_source: &str, path: &Path) -> PathBuf {
    if path.is_absolute() || path.exists() {
        return path.to_path_buf();
    }
    Path::new(case_source)
        .parent()
        .map_or_else(|| path.to_path_buf(), |dir| dir.join(path))
}

/// The parameter file of a law, if it came from one (not a named set).
fn parameter_file(case_source: &str, material: &MaterialSpec) -> Option<PathBuf> {
    let path = resolved(case_source, Path::new(&material.source));
    path.is_file().then_some(path)
}

impl Provenance {
    /// The provenance of a run of `case`: this build, and the files the
    /// case read hashed now.
    pub fn of(case: &Case) -> Self {
        Self::of_scenario(case.into())
    }

    fn of_scenario(case: Scenario) -> Self {
        let source = match case {
            Scenario::Oat(c) => c.source.as_str(),
            Scenario::Forming(c) => c.source.as_str(),
        };
        let mut inputs = vec![input("case file".into(), Path::new(source))];
        match case {
            Scenario::Oat(c) => {
                if let Some(p) = parameter_file(source, &c.material) {
                    inputs.push(input("parameter file".into(), &p));
                }
                if let MeshSource::File { path, .. } = &c.mesh {
                    inputs.push(input("mesh".into(), &resolved(source, path)));
                }
            }
            Scenario::Forming(c) => {
                for ply in &c.plies {
                    if let Some(p) = parameter_file(source, &ply.material) {
                        inputs.push(input(format!("parameter file of ply \"{}\"", ply.name), &p));
                    }
                    if let PlyMesh::File { path } = &ply.mesh {
                        inputs.push(input(
                            format!("mesh of ply \"{}\"", ply.name),
                            &resolved(source, path),
                        ));
                    }
                }
                for tool in &c.tools {
                    if let ToolShape::Mesh { path, .. } = &tool.shape {
                        inputs.push(input(
                            format!("surface of tool \"{}\"", tool.name),
                            &resolved(source, path),
                        ));
                    }
                }
            }
        }
        Self {
            ncform_version: env!("CARGO_PKG_VERSION").to_string(),
            git_commit: GIT_COMMIT.to_string(),
            inputs,
        }
    }
}

/// A 3-vector as a JSON array.
fn v3(v: &nalgebra::Vector3<f64>) -> Value {
    json!([v.x, v.y, v.z])
}

/// A law as JSON: where it came from, the law and its parameters under
/// the parameter file's keys ([`MaterialSpec::parameter_values`]).
fn material(m: &MaterialSpec) -> Value {
    let parameters: serde_json::Map<String, Value> = m
        .parameter_values()
        .into_iter()
        .map(|(key, value)| (key, json!(value)))
        .collect();
    json!({
        "name": m.name,
        "source": m.source,
        "law": m.law_name(),
        "parameters": parameters,
    })
}

/// The resolved OAT.
fn oat(c: &OatCase) -> Value {
    json!({
        "scenario": "oat",
        "title": c.title,
        "source": c.source,
        "specimen": {
            "width": c.width,
            "length": c.length,
            "bias_angle_deg": c.bias_angle_deg,
        },
        "mesh": format!("{:?}", c.mesh),
        "material": material(&c.material),
        "thickness": c.thickness,
        "density": c.density,
        "displacement": c.displacement,
        "output_displacements": c.output_displacements,
        "mdz_size": c.mdz_size,
        "contour_displacement": c.contour_displacement,
        "solver_kind": c.solver_kind,
        "solver": c.solver,
        "explicit": c.explicit,
    })
}

/// The resolved forming case.
fn forming(c: &FormingCase) -> Value {
    let ply_name = |p: usize| c.plies.get(p).map_or("?", |ply| ply.name.as_str());
    json!({
        "scenario": "forming",
        "title": c.title,
        "source": c.source,
        "plies": c.plies.iter().map(|p| json!({
            "name": p.name,
            "mesh": format!("{:?}", p.mesh),
            "material": material(&p.material),
            "thickness": p.thickness,
            "density": p.density,
            "fibre_angle_deg": p.fibre_angle_deg,
            "bending": p.bending,
        })).collect::<Vec<_>>(),
        "rosette": c.rosette,
        "defects": c.defects,
        "tools": c.tools.iter().map(|t| json!({
            "name": t.name,
            "shape": format!("{:?}", t.shape),
            "origin": v3(&t.origin),
            "axis": v3(&t.axis),
            "inside": t.inside,
            "friction": t.friction,
            "motion": format!("{:?}", t.motion),
            "plies": t.plies.iter().map(|&p| ply_name(p)).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "boundaries": c.boundaries.iter().map(|b| json!({
            "ply": ply_name(b.ply),
            "nodes": b.nodes,
            "fixed": b.fixed,
            "displacement": b.displacement,
            "clamp_rotation": b.clamp_rotation,
        })).collect::<Vec<_>>(),
        "loads": c.loads.iter().map(|l| json!({
            "ply": ply_name(l.ply),
            "nodes": l.nodes,
            "force": v3(&l.force),
            "amplitude": format!("{:?}", l.amplitude),
        })).collect::<Vec<_>>(),
        "probes": c.probes.iter().map(|p| json!({
            "ply": ply_name(p.ply),
            "nodes": p.nodes,
        })).collect::<Vec<_>>(),
        "zones": c.zones.iter().map(|z| json!({
            "ply": ply_name(z.ply),
            "zone": format!("{:?}", z.zone),
        })).collect::<Vec<_>>(),
        "ply_contacts": c.ply_contacts.iter().map(|pc| json!({
            "plies": [ply_name(pc.plies[0]), ply_name(pc.plies[1])],
            "friction": pc.friction,
            "skin": pc.skin,
        })).collect::<Vec<_>>(),
        "gravity": c.gravity.map(|g| json!({
            "acceleration": v3(&g.acceleration),
            "amplitude": format!("{:?}", g.amplitude),
        })),
        "contact": c.contact,
        "solver_kind": c.solver_kind,
        "solver": c.solver,
        "explicit": c.explicit,
        "output": {
            "states": c.states.len(),
            "history": c.history_rows,
            "camera": format!("{:?}", c.camera).to_lowercase(),
            "maps": c.maps,
        },
        "prescribed_travel": c.prescribed_travel,
    })
}

/// The resolved case as JSON (see the module's summary).
pub fn resolved_case(case: &Case) -> Value {
    match case {
        Case::Oat(c) => oat(c),
        Case::Forming(c) => forming(c),
    }
}

/// The content of [`RESOLVED_CASE_FILE`] for a run of `case`: its format,
/// the provenance, the case's warnings and the resolved case, without
/// `null` members (an unset setting is left out).
pub fn resolved_case_document(case: &Case) -> Value {
    document(case.into())
}

/// [`resolved_case_document`] of the case a run's reports see.
pub fn resolved_case_document_of(built: &Built) -> Value {
    document(match built {
        Built::Oat { case, .. } => Scenario::Oat(case),
        Built::Forming { case, .. } => Scenario::Forming(case),
    })
}

/// [`resolved_case_document`] of a borrowed case of either scenario.
fn document(case: Scenario) -> Value {
    let (resolved, warnings) = match case {
        Scenario::Oat(c) => (oat(c), &c.warnings),
        Scenario::Forming(c) => (forming(c), &c.warnings),
    };
    super::json::without_nulls(json!({
        "format": RESOLVED_FORMAT,
        "provenance": Provenance::of_scenario(case),
        "warnings": warning_lines(warnings),
        "case": resolved,
    }))
}

/// The case's warnings as the lines `ncform run` prints (without
/// `warning: `).
fn warning_lines(warnings: &[crate::config::CaseWarning]) -> Vec<String> {
    warnings.iter().map(ToString::to_string).collect()
}
