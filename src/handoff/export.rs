//! The hand-off's library entry points (`docs/export.md`): a run's formed
//! plies as a [`Handoff`] on their own mesh ([`formed_handoff`], what
//! `ncform export` writes) or mapped onto a structural mesh of the user's
//! ([`mapped_handoff`], what `ncform map` writes), and the deck of either
//! in a target's format ([`write_handoff`]).
//!
//! A stack is handed on as one mesh with one layer per ply: the first ply
//! asked for is the reference, its formed mesh the mesh and its own
//! directions its layer; every other ply is mapped onto that mesh as onto a
//! structural mesh ([`super::map`]). Where a ply drew in differently and
//! does not reach an element within the tolerance, the element has no such
//! layer: its section lists the plies present (a partial layup), and the
//! file's header counts such elements per ply.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::abaqus::{AbaqusElement, AbaqusOptions, write_abaqus};
use super::calculix::{CalculixOptions, write_calculix};
use super::lsdyna::{LsDynaOptions, write_lsdyna};
use super::map::{FormedSurface, MapError, MapOptions, MapResult, map_onto};
use super::run::{FormedPly, RunFolderError, ply_index, read_formed_state, run_plies};
use super::{Handoff, Layer, OrthotropicMaterial};
use crate::mesh::structural::{StructuralMeshError, read_structural_inp};

/// A target format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// An Abaqus input deck (`.inp`).
    Abaqus,
    /// An LS-DYNA keyword deck (`.k`).
    LsDyna,
    /// A CalculiX input deck (`.inp`) of layered oriented solids.
    Calculix,
}

/// Why a hand-off cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum HandoffError {
    /// The run folder.
    #[error(transparent)]
    Run(#[from] RunFolderError),
    /// The structural mesh.
    #[error(transparent)]
    Mesh(#[from] StructuralMeshError),
    /// A ply could not be mapped.
    #[error("mapping ply \"{ply}\" onto {target}: {source}")]
    Map {
        /// The ply.
        ply: String,
        /// The mesh mapped onto.
        target: String,
        /// The cause.
        source: MapError,
    },
}

/// What to hand on and how.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct HandoffOptions {
    /// The plies, by name or number from 1, bottom to top (empty: all of
    /// the run's, in the case's order).
    pub plies: Vec<String>,
    /// The state (the `NNNN` of the run's VTU files; `None`: the last).
    pub state: Option<usize>,
    /// Hand on the last converged state of a run that did not finish.
    pub incomplete: bool,
    /// How plies are mapped (a stack's plies beyond the first, or every
    /// ply onto a structural mesh).
    pub map: MapOptions,
}

/// One ply mapped onto the hand-off's mesh.
#[derive(Debug, Clone)]
pub struct PlyMapping {
    /// The ply.
    pub ply: String,
    /// The mapping, per element of the mesh.
    pub result: MapResult,
}

/// The run's plies asked for, as indices.
fn selected_plies(run: &Path, given: &[String]) -> Result<Vec<usize>, HandoffError> {
    let names: Vec<String> = run_plies(run)?.into_iter().map(|p| p.0).collect();
    if given.is_empty() {
        return Ok((0..names.len()).collect());
    }
    Ok(given
        .iter()
        .map(|g| ply_index(run, &names, g))
        .collect::<Result<_, _>>()?)
}

/// Maps `ply` onto `target`.
fn map_ply(
    ply: &FormedPly,
    target: &super::ShellMesh,
    options: &MapOptions,
) -> Result<MapResult, HandoffError> {
    // Elements whose directions are not defined (collapsed) are left out
    // of the surface: nothing is sampled from them.
    let keep: Vec<usize> = (0..ply.triangles.len()).filter(|&e| ply.valid[e]).collect();
    let triangles: Vec<[usize; 3]> = keep.iter().map(|&e| ply.triangles[e]).collect();
    let fibre: Vec<[f64; 3]> = keep.iter().map(|&e| ply.fibre[e]).collect();
    map_onto(
        &FormedSurface {
            nodes: &ply.nodes,
            triangles: &triangles,
            fibre: &fibre,
        },
        target,
        options,
    )
    .map_err(|source| HandoffError::Map {
        ply: ply.name.clone(),
        target: target.source.clone(),
        source,
    })
}

/// Each of `plies` mapped onto `mesh`: its layer and its mapping.
fn map_plies(
    plies: &[FormedPly],
    mesh: &super::ShellMesh,
    options: &MapOptions,
) -> Result<(Vec<Layer>, Vec<PlyMapping>), HandoffError> {
    let mut layers = Vec::new();
    let mut mappings = Vec::new();
    for ply in plies {
        let result = map_ply(ply, mesh, options)?;
        layers.push(result.to_layer(&ply.name, ply.thickness));
        mappings.push(PlyMapping {
            ply: ply.name.clone(),
            result,
        });
    }
    Ok((layers, mappings))
}

/// The convention lines every deck's header repeats after the provenance.
fn mapping_lines(mappings: &[PlyMapping], elements: usize, options: &MapOptions) -> Vec<String> {
    mappings
        .iter()
        .map(|m| {
            format!(
                "ply \"{}\" mapped (orientation tensor a(x)a averaged over each element, projected into its plane; tolerance {} mm): {} of {elements} elements covered, {} without it",
                m.ply,
                options.tolerance,
                elements - m.result.unmapped.len(),
                m.result.unmapped.len()
            )
        })
        .collect()
}

/// The formed plies of the run in `run` as a hand-off on the first ply's
/// formed mesh (its node numbering from 1 and its element labels), the
/// other plies mapped onto it; and the mappings made.
///
/// # Errors
/// As [`read_formed_state`]; a ply that cannot be mapped.
pub fn formed_handoff(
    run: &Path,
    options: &HandoffOptions,
) -> Result<(Handoff, Vec<PlyMapping>), HandoffError> {
    let plies = selected_plies(run, &options.plies)?;
    let state = read_formed_state(run, &plies, options.state, options.incomplete)?;
    let mut header = state.header();
    let reference = &state.plies[0];
    let (mesh, layer) = reference.shell_mesh(&run.display().to_string());
    let (mapped, mappings) = map_plies(&state.plies[1..], &mesh, &options.map)?;
    let layers: Vec<Layer> = std::iter::once(layer).chain(mapped).collect();
    if state.plies.len() > 1 {
        header.push(format!(
            "stack: the mesh is ply \"{}\"'s, formed; the other plies are mapped onto it, and an element a ply does not reach has no such layer (a partial layup)",
            reference.name
        ));
        header.extend(mapping_lines(&mappings, mesh.elements.len(), &options.map));
    }
    Ok((
        Handoff {
            mesh,
            layers,
            header,
            material: OrthotropicMaterial::default(),
        },
        mappings,
    ))
}

/// The formed plies of the run in `run` mapped onto the structural mesh
/// `onto` (an Abaqus `.inp`, its labels kept); and the mappings made.
///
/// # Errors
/// As [`read_formed_state`] and the structural reader; a ply that cannot
/// be mapped.
pub fn mapped_handoff(
    run: &Path,
    onto: &Path,
    options: &HandoffOptions,
) -> Result<(Handoff, Vec<PlyMapping>), HandoffError> {
    let plies = selected_plies(run, &options.plies)?;
    let state = read_formed_state(run, &plies, options.state, options.incomplete)?;
    let mesh = read_structural_inp(onto)?;
    let mut header = state.header();
    header.push(format!(
        "structural mesh: {} ({} nodes, {} elements, labels as read)",
        onto.display(),
        mesh.nodes.len(),
        mesh.elements.len()
    ));
    let (layers, mappings) = map_plies(&state.plies, &mesh, &options.map)?;
    header.extend(mapping_lines(&mappings, mesh.elements.len(), &options.map));
    Ok((
        Handoff {
            mesh,
            layers,
            header,
            material: OrthotropicMaterial::default(),
        },
        mappings,
    ))
}

/// Writes `handoff` as a deck of `format` to `out` (`element`: the Abaqus
/// element family where the mesh does not name one).
///
/// # Errors
/// The writers' errors (an inconsistent hand-off) and those of `out`.
pub fn write_handoff(
    handoff: &Handoff,
    format: Format,
    element: AbaqusElement,
    out: &mut impl Write,
) -> io::Result<()> {
    match format {
        Format::Abaqus => write_abaqus(handoff, &AbaqusOptions { element }, out).map(|_| ()),
        Format::LsDyna => write_lsdyna(handoff, &LsDynaOptions::default(), out).map(|_| ()),
        Format::Calculix => write_calculix(handoff, &CalculixOptions::default(), out).map(|_| ()),
    }
}

/// The map report's CSV next to a deck: per element of the mesh and ply,
/// its label, whether it got a direction, the covered fraction of its
/// area, the nearest distance to the ply \[mm\] and the anisotropy of the
/// averaged orientation tensor.
pub fn write_map_report(
    path: &Path,
    handoff: &Handoff,
    mappings: &[PlyMapping],
) -> io::Result<PathBuf> {
    let mut rows = Vec::new();
    for m in mappings {
        for (e, el) in handoff.mesh.elements.iter().enumerate() {
            rows.push(format!(
                "{},\"{}\",{},{},{},{}",
                el.label,
                m.ply,
                i32::from(m.result.fibre[e].is_some()),
                m.result.coverage[e],
                if m.result.distance[e].is_finite() {
                    m.result.distance[e]
                } else {
                    -1.0
                },
                m.result.anisotropy[e]
            ));
        }
    }
    let mut text = String::from(
        "# ncform map report: per structural element and ply; mapped 0 = no ply within the tolerance (no direction written); coverage = covered fraction of the element's area; distance = nearest distance to the ply [mm] (-1: none); anisotropy = (l1-l2)/(l1+l2) of the averaged orientation tensor (1: every sample agrees)\n# units: mm\nelement,ply,mapped,coverage,distance [mm],anisotropy\n",
    );
    for r in rows {
        text.push_str(&r);
        text.push('\n');
    }
    std::fs::write(path, text)?;
    Ok(path.to_path_buf())
}
