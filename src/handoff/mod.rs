//! The formed part handed on to structural analysis (`docs/export.md`): a
//! shell mesh with its own node and element labels, and per element the
//! fibre direction of each ply that covers it, written as decks that
//! Abaqus, LS-DYNA and CalculiX read ([`abaqus`], [`lsdyna`], [`calculix`]),
//! and the mapping of a formed ply onto a structural mesh of the user's
//! ([`map`]).
//!
//! A fibre direction is a unit vector tangent to its element, defined up to
//! its sign (`a` and `−a` are the same fibre). The element normal is the one
//! of its node order, `n = (x₂ − x₁) × (x₃ − x₁)` normalised (for a quad, the
//! cross product of its diagonals, `(x₃ − x₁) × (x₄ − x₂)`), and the
//! transverse in-plane direction of a layer is `n × a`.

pub mod abaqus;
pub mod calculix;
mod common;
pub mod export;
pub mod lsdyna;
pub mod map;
pub mod run;

/// One shell element of a [`ShellMesh`].
#[derive(Debug, Clone, PartialEq)]
pub struct ShellElement {
    /// Its label in the target's numbering (positive).
    pub label: u64,
    /// Its three or four nodes, as indices into [`ShellMesh::nodes`], in
    /// the element's own order (which sets its normal).
    pub nodes: Vec<usize>,
    /// The Abaqus element type it was read as (`S3`, `S4R`, `M3D3`, …), or
    /// empty when the writer chooses (a formed ply's triangles).
    pub abaqus_type: String,
}

impl ShellElement {
    /// `true` for a three-node element.
    pub fn is_triangle(&self) -> bool {
        self.nodes.len() == 3
    }
}

/// A shell mesh in a structural code's terms: labelled nodes \[mm\] and
/// labelled triangles and quads.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ShellMesh {
    /// Where it comes from (a file or a run folder), for messages.
    pub source: String,
    /// Node labels (positive, distinct), one per node.
    pub node_labels: Vec<u64>,
    /// Node positions \[mm\].
    pub nodes: Vec<[f64; 3]>,
    /// The elements.
    pub elements: Vec<ShellElement>,
}

impl ShellMesh {
    /// The unit normal of element `e` from its node order (see the module
    /// documentation); `None` for a degenerate element.
    pub fn normal(&self, e: usize) -> Option<[f64; 3]> {
        let el = &self.elements[e];
        let x = |k: usize| self.nodes[el.nodes[k]];
        let (u, v) = if el.nodes.len() == 4 {
            (sub(x(2), x(0)), sub(x(3), x(1)))
        } else {
            (sub(x(1), x(0)), sub(x(2), x(0)))
        };
        normalized(cross(u, v))
    }

    /// The centroid of element `e` (the mean of its nodes) \[mm\].
    pub fn centroid(&self, e: usize) -> [f64; 3] {
        let el = &self.elements[e];
        let mut c = [0.0; 3];
        for &n in &el.nodes {
            for (ck, xk) in c.iter_mut().zip(self.nodes[n]) {
                *ck += xk;
            }
        }
        c.map(|v| v / el.nodes.len() as f64)
    }
}

/// One ply of a hand-off: its thickness and, per element of the mesh, its
/// fibre direction where it covers the element.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// The ply's name.
    pub name: String,
    /// Its thickness in the structural model \[mm\].
    pub thickness: f64,
    /// Per element of the mesh: the unit fibre direction, tangent to the
    /// element, or `None` where the ply does not cover the element (the
    /// element then has no such layer; nothing is made up).
    pub fibre: Vec<Option<[f64; 3]>>,
}

/// The elastic constants written for the plies, in the target's
/// engineering-constant form \[MPa, tonne/mm³\]: a placeholder for the cured
/// laminate, which the structural analyst replaces (the forming law says
/// nothing about the cured part's stiffness). Axis 1 is the fibre, 2 the
/// transverse in-plane direction, 3 the normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrthotropicMaterial {
    /// `E1` \[MPa\].
    pub e1: f64,
    /// `E2 = E3` \[MPa\].
    pub e2: f64,
    /// `ν12 = ν13`.
    pub nu12: f64,
    /// `ν23`.
    pub nu23: f64,
    /// `G12 = G13` \[MPa\].
    pub g12: f64,
    /// `G23` \[MPa\].
    pub g23: f64,
    /// Density \[tonne/mm³\].
    pub density: f64,
}

impl Default for OrthotropicMaterial {
    /// A cured unidirectional carbon/epoxy at about 55 % fibre volume
    /// (typical handbook values: `E1` 135 GPa, `E2` 10 GPa, `G12` 5 GPa,
    /// `ν12` 0.3, `ν23` 0.45, 1.55 g/cm³).
    fn default() -> Self {
        Self {
            e1: 135_000.0,
            e2: 10_000.0,
            nu12: 0.3,
            nu23: 0.45,
            g12: 5_000.0,
            g23: 10_000.0 / (2.0 * 1.45),
            density: 1.55e-9,
        }
    }
}

/// A formed part ready to be written: the mesh, its plies bottom to top,
/// and the lines of provenance every file's header repeats (run folder,
/// state, whether the run was complete).
#[derive(Debug, Clone, PartialEq)]
pub struct Handoff {
    /// The mesh.
    pub mesh: ShellMesh,
    /// The plies, bottom (first) to top.
    pub layers: Vec<Layer>,
    /// Provenance lines, written as comments in the target's syntax.
    pub header: Vec<String>,
    /// The elastic constants written for every ply.
    pub material: OrthotropicMaterial,
}

impl Handoff {
    /// Per element, the bit set of the layers that cover it (bit `k` for
    /// layer `k`): elements of one layup share one section.
    pub fn layups(&self) -> Vec<u64> {
        (0..self.mesh.elements.len())
            .map(|e| {
                self.layers
                    .iter()
                    .enumerate()
                    .filter(|(_, l)| l.fibre[e].is_some())
                    .fold(0u64, |bits, (k, _)| bits | (1 << k))
            })
            .collect()
    }
}

/// `a − b`.
pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a × b`.
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a · b`.
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a / |a|`, `None` for a zero or non-finite vector.
pub(crate) fn normalized(a: [f64; 3]) -> Option<[f64; 3]> {
    let len = dot(a, a).sqrt();
    (len > 0.0 && len.is_finite()).then(|| a.map(|v| v / len))
}
