//! Why a validated case cannot be turned into a model: the errors of
//! [`FormingCase::build`](super::forming::FormingCase::build) and
//! [`OatCase::build`](super::OatCase::build). Each names the case file (or,
//! for a bad triangle of an OAT's mesh, the mesh), the item — ply, tool,
//! boundary line, element, node set, mesh file — and the cause. A case file
//! that cannot be read or validated is a
//! [`ConfigError`](crate::config::ConfigError) instead. The keys the
//! messages name are documented in `docs/cases.md`.

use std::path::PathBuf;

use crate::config::readable_number;
use crate::contact::{MeshToolError, ShapeError};
use crate::element::BendingError;
use crate::element::membrane::ReferenceError;
use crate::mesh::MeshError;
use crate::model::BendingSetupError;

/// Why a tool's surface cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ToolSurfaceError {
    /// The shape or its placement is invalid.
    #[error(transparent)]
    Shape(#[from] ShapeError),
    /// The mesh file of a `mesh` tool cannot be read or used.
    #[error(transparent)]
    Mesh(#[from] MeshToolError),
    /// A `pyramid` tool whose shape is not a pyramid.
    #[error("not a pyramid")]
    NotAPyramid,
}

/// Why a case cannot be built into a model. The messages are those the
/// command line prints.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BuildError {
    /// A ply's mesh cannot be generated, given its fibres or checked.
    #[error("{}: ply \"{ply}\": [ply.mesh] {cause}", at(.file, *.line))]
    PlyMesh {
        /// The case file.
        file: String,
        /// The line of the `[ply.mesh]` key the mesh comes from (`shape`
        /// or `file`; 0 when not known).
        line: usize,
        /// The ply's name.
        ply: String,
        /// What is wrong with the mesh.
        #[source]
        cause: Box<MeshError>,
    },
    /// A ply's mesh file cannot be read.
    #[error("{}: ply \"{ply}\": [ply.mesh] file = \"{}\": {cause}", at(.file, *.line), .path.display())]
    PlyMeshFile {
        /// The case file.
        file: String,
        /// The line of `file` in the case file.
        line: usize,
        /// The ply's name.
        ply: String,
        /// The mesh file.
        path: PathBuf,
        /// Why it cannot be read.
        #[source]
        cause: Box<MeshError>,
    },
    /// A ply's mesh file is neither an Abaqus `.inp` nor a Gmsh `.msh`.
    #[error(
        "{}: ply \"{ply}\": mesh.file = \"{}\": expected an Abaqus .inp or a Gmsh .msh file",
        at(.file, *.line),
        .path.display()
    )]
    PlyMeshFormat {
        /// The case file.
        file: String,
        /// The line of `file` in the case file.
        line: usize,
        /// The ply's name.
        ply: String,
        /// The mesh file.
        path: PathBuf,
    },
    /// A triangle of a ply cannot carry a membrane.
    #[error("{file}: ply \"{ply}\": element {element}: {cause}")]
    PlyElement {
        /// The case file.
        file: String,
        /// The ply's name.
        ply: String,
        /// The element's label in the ply's mesh.
        element: i64,
        /// What is wrong with the triangle.
        #[source]
        cause: ReferenceError,
    },
    /// The node set of a `[[boundary]]` is not in its ply's mesh.
    #[error("{file}:{line}: boundary on ply \"{ply}\": {cause}")]
    Boundary {
        /// The case file.
        file: String,
        /// The line of the boundary's `nodes`.
        line: usize,
        /// The ply's name.
        ply: String,
        /// Why the node set cannot be used.
        #[source]
        cause: Box<MeshError>,
    },
    /// A ply's bending stiffnesses are invalid.
    #[error("{file}: ply \"{ply}\": bending: {cause}")]
    BendingStiffness {
        /// The case file.
        file: String,
        /// The ply's name.
        ply: String,
        /// What is wrong with the stiffnesses.
        #[source]
        cause: BendingError,
    },
    /// A ply's mesh cannot carry a bending term.
    #[error("{file}: ply \"{ply}\": bending: {cause}")]
    Bending {
        /// The case file.
        file: String,
        /// The ply's name.
        ply: String,
        /// What is wrong with the mesh (its topology or a hinge).
        #[source]
        cause: Box<BendingSetupError>,
    },
    /// The node set of a `[[probe]]` is not in its ply's mesh.
    #[error("{file}:{line}: probe on ply \"{ply}\": {cause}")]
    Probe {
        /// The case file.
        file: String,
        /// The line of the probe's `nodes`.
        line: usize,
        /// The ply's name.
        ply: String,
        /// Why the node set cannot be used.
        #[source]
        cause: Box<MeshError>,
    },
    /// The node set of a `[[load]]` is not in its ply's mesh.
    #[error("{file}:{line}: load on ply \"{ply}\": {cause}")]
    Load {
        /// The case file.
        file: String,
        /// The line of the load's `nodes`.
        line: usize,
        /// The ply's name.
        ply: String,
        /// Why the node set cannot be used.
        #[source]
        cause: Box<MeshError>,
    },
    /// A tool's surface cannot be built.
    #[error("{}: tool \"{tool}\": {cause}", at(.file, *.line))]
    Tool {
        /// The case file.
        file: String,
        /// The line of the tool's `file` (a mesh tool) or `shape`.
        line: usize,
        /// The tool's name.
        tool: String,
        /// What is wrong with the surface.
        #[source]
        cause: Box<ToolSurfaceError>,
    },
    /// The contact penalty of a node of a ply against a tool is not a
    /// positive number.
    #[error(
        "{file}: contact of ply \"{ply}\" with tool \"{tool}\": node {node}: penalty {} N/mm: expected a positive stiffness (set contact.penalty)", readable_number(*.penalty)
    )]
    ContactPenalty {
        /// The case file.
        file: String,
        /// The ply's name.
        ply: String,
        /// The tool's name.
        tool: String,
        /// The node's label in the ply's mesh.
        node: i64,
        /// Its penalty \[N/mm\].
        penalty: f64,
    },
    /// A ply's mid-surface starts inside a tool, more than the contact
    /// offset into the contact layer.
    #[error(
        "{file}: tool \"{tool}\" starts inside ply \"{ply}\": node {node} at ({}, {}, {}) mm is {} mm inside the tool; the mid-surface may sit at most the contact offset ({} mm) from touching: move the tool or the ply",
        readable_number(.position[0]),
        readable_number(.position[1]),
        readable_number(.position[2]),
        depth_text(*.depth),
        readable_number(*.offset)
    )]
    ToolInsidePly {
        /// The case file.
        file: String,
        /// The tool's name.
        tool: String,
        /// The ply's name.
        ply: String,
        /// The node's label in the ply's mesh.
        node: i64,
        /// Its reference position \[mm\].
        position: [f64; 3],
        /// How far it is inside the tool \[mm\].
        depth: f64,
        /// The contact offset \[mm\].
        offset: f64,
    },
    /// Two plies' contact cannot be set up.
    #[error("{file}: {cause}")]
    PlyContact {
        /// The case file.
        file: String,
        /// Why (naming the contact and the ply).
        cause: crate::model::ply_contact::PlyContactError,
    },
    /// An OAT's specimen mesh cannot be generated; `table` is the case
    /// file's table holding the parameter (`specimen` or `mesh`).
    #[error("{file}: [{table}] {cause}")]
    Generator {
        /// The case file.
        file: String,
        /// The table of the offending parameter.
        table: &'static str,
        /// What is wrong with the parameters.
        #[source]
        cause: Box<MeshError>,
    },
    /// An OAT's mesh file is neither an Abaqus `.inp` nor a Gmsh `.msh`.
    #[error(
        "{file}: mesh.file = \"{}\"{}: expected an Abaqus .inp or a Gmsh .msh file",
        .path.display(),
        line_note(*.line)
    )]
    MeshFormat {
        /// The case file.
        file: String,
        /// The line of `mesh.file` in the case file.
        line: usize,
        /// The mesh file.
        path: PathBuf,
    },
    /// An OAT's mesh file cannot be read.
    #[error("{file}: mesh.file = \"{}\"{}: {cause}", .path.display(), line_note(*.line))]
    MeshFile {
        /// The case file.
        file: String,
        /// The line of `mesh.file` in the case file.
        line: usize,
        /// The mesh file.
        path: PathBuf,
        /// Why it cannot be read.
        #[source]
        cause: Box<MeshError>,
    },
    /// An OAT's mesh cannot take fibres along the rovings.
    #[error(
        "{file}: specimen.bias_angle_deg = {}: {cause}",
        readable_number(*.bias_angle_deg)
    )]
    Fibres {
        /// The case file.
        file: String,
        /// The bias angle \[deg\].
        bias_angle_deg: f64,
        /// Why the fibres cannot be set.
        #[source]
        cause: Box<MeshError>,
    },
    /// An OAT's mesh fails its checks.
    #[error("{file}: {cause}")]
    Mesh {
        /// The case file.
        file: String,
        /// What is wrong with the mesh.
        #[source]
        cause: Box<MeshError>,
    },
    /// A clamp's node set of an OAT is not in its mesh; `key` is
    /// `fixed_clamp_set` or `moving_clamp_set`.
    #[error("{file}: mesh.{key} = \"{set}\": {cause}")]
    ClampSet {
        /// The case file.
        file: String,
        /// The `[mesh]` key naming the set.
        key: &'static str,
        /// The set's name.
        set: String,
        /// Why the set cannot be used.
        #[source]
        cause: Box<MeshError>,
    },
    /// A clamp's node set of an OAT is empty; `key` is
    /// `mesh.fixed_clamp_set` or `mesh.moving_clamp_set`.
    #[error(
        "{file}: {key} = \"{set}\": the node set of {mesh} is empty; expected the nodes of a clamped edge"
    )]
    EmptyClamp {
        /// The case file.
        file: String,
        /// The key naming the set.
        key: &'static str,
        /// The set's name.
        set: String,
        /// The mesh's source.
        mesh: String,
    },
    /// A node of an OAT's mesh is in both clamps.
    #[error(
        "{file}: mesh.fixed_clamp_set = \"{fixed}\" and mesh.moving_clamp_set = \"{moving}\": node {node} of {mesh} is in both sets; expected two clamps without a common node (one is fixed, the other moves)"
    )]
    SharedClampNode {
        /// The case file.
        file: String,
        /// The fixed clamp's set.
        fixed: String,
        /// The moving clamp's set.
        moving: String,
        /// The node's label.
        node: i64,
        /// The mesh's source.
        mesh: String,
    },
    /// A triangle of an OAT's mesh cannot carry a membrane.
    #[error("{mesh}: element {element}: {cause}")]
    Element {
        /// The mesh's source.
        mesh: String,
        /// The element's label.
        element: i64,
        /// What is wrong with the triangle.
        #[source]
        cause: ReferenceError,
    },
}

/// A depth inside a tool as the message writes it: four decimals, or the
/// readable number for a depth of a kilometre and more \[mm\].
fn depth_text(depth: f64) -> String {
    if depth < 1e6 {
        format!("{depth:.4}")
    } else {
        readable_number(depth)
    }
}

/// A place in the case file as messages write it: `case.toml:12`, or the
/// file alone when the line is not known (0).
fn at(file: &str, line: usize) -> String {
    if line > 0 {
        format!("{file}:{line}")
    } else {
        file.to_string()
    }
}

/// The case line of a key placed after it, ` (line 12)` (empty when not
/// known), for messages whose beginning `file: key = value` is fixed.
fn line_note(line: usize) -> String {
    if line > 0 {
        format!(" (line {line})")
    } else {
        String::new()
    }
}
