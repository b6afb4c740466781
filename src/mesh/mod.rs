//! Triangle meshes of the fabric: the [`Mesh`] container, the OAT specimen
//! generator ([`generate`]) and the readers for Abaqus `.inp` ([`inp`]) and
//! Gmsh `.msh` 4.1 ([`msh`]) files; and the reader of a structural shell
//! mesh (triangles and quads) a formed ply is mapped onto ([`structural`]).
//!
//! A mesh is a list of reference node coordinates (mm), 3-node triangles
//! (node indices, counter-clockwise gives the normal by the right-hand
//! rule), one unit roving direction per triangle (in its plane), named node
//! and element sets, and the external labels used in messages. Indices are
//! 0-based; labels are the ids of the file (1-based indices for generated
//! meshes). See `docs/meshes.md`.

pub mod generate;
pub mod inp;
pub mod msh;
pub mod shapes;
pub mod structural;

use std::collections::BTreeMap;

use nalgebra::Vector3;

/// Relative area below which a triangle is degenerate:
/// `area <= DEGENERATE_AREA * (longest edge)²`.
pub const DEGENERATE_AREA: f64 = 1e-10;

/// Tolerance on `|‖a‖ − 1|` and on `|a·n|` for fibre directions.
pub const FIBRE_TOLERANCE: f64 = 1e-9;

/// Shortest admissible in-plane projection of a unit global fibre direction
/// in [`Mesh::set_fibres_from_global`].
pub const MIN_FIBRE_PROJECTION: f64 = 1e-6;

/// A triangle mesh of the fabric in its reference configuration.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Mesh {
    /// Reference coordinates of the nodes (mm).
    pub nodes: Vec<Vector3<f64>>,
    /// Node indices of each triangle.
    pub triangles: Vec<[usize; 3]>,
    /// Unit roving direction per triangle, in its plane; empty until set.
    pub fibres: Vec<Vector3<f64>>,
    /// Named node sets: sorted, unique node indices.
    pub node_sets: BTreeMap<String, Vec<usize>>,
    /// Named element sets: sorted, unique triangle indices.
    pub element_sets: BTreeMap<String, Vec<usize>>,
    /// External node ids (file ids; 1-based index for generated meshes).
    pub node_labels: Vec<i64>,
    /// External element ids (file ids; 1-based index for generated meshes).
    pub element_labels: Vec<i64>,
    /// File path, or `generated ...`, for messages.
    pub source: String,
}

/// Why a mesh could not be read, generated or used. Every message names the
/// source (file), the line where there is one, the offending id or value and
/// what was expected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The file could not be read.
    #[error("cannot read mesh file {file}: {reason}")]
    Io {
        /// The path as given.
        file: String,
        /// The operating system's reason.
        reason: String,
    },
    /// A token that is not what the format allows at this place.
    #[error("{file}:{line}: found `{found}`, expected {expected}")]
    Syntax {
        /// The file (source) name.
        file: String,
        /// 1-based line number.
        line: usize,
        /// The offending token or line.
        found: String,
        /// What the format allows here.
        expected: String,
    },
    /// A well-formed construct that ncform does not support (binary or
    /// version 2 Gmsh files, `*INCLUDE`, mesh generation keywords, ...).
    #[error("{file}:{line}: {found} is not supported; {remedy}")]
    Unsupported {
        /// The file (source) name.
        file: String,
        /// 1-based line number.
        line: usize,
        /// The unsupported construct as written.
        found: String,
        /// What to do instead.
        remedy: String,
    },
    /// Elements other than 3-node triangles.
    #[error(
        "non-triangle element type {element_type} at {file}:{line}; ncform needs 3-node triangles"
    )]
    NonTriangle {
        /// The file (source) name.
        file: String,
        /// 1-based line number.
        line: usize,
        /// The type as written (e.g. `S4R`, or `3 (Gmsh 4-node quadrangle)`).
        element_type: String,
    },
    /// An element line with the wrong number of nodes.
    #[error("{file}:{line}: element {element} has {found} nodes, expected {expected}")]
    WrongNodeCount {
        /// The file (source) name.
        file: String,
        /// 1-based line number.
        line: usize,
        /// The element id.
        element: i64,
        /// Number of node ids found.
        found: usize,
        /// Number of node ids the type needs.
        expected: usize,
    },
    /// An element references a node id that is not defined.
    #[error("{file}:{line}: element {element} references node {node}, which is not defined")]
    UnknownNode {
        /// The file (source) name.
        file: String,
        /// 1-based line number of the element.
        line: usize,
        /// The element id.
        element: i64,
        /// The undefined node id.
        node: i64,
    },
    /// A node or element id defined twice.
    #[error(
        "{file}:{line}: {kind} {id} is defined twice (first at line {first_line}); ids must be unique"
    )]
    DuplicateId {
        /// The file (source) name.
        file: String,
        /// 1-based line number of the second definition.
        line: usize,
        /// `node` or `element`.
        kind: &'static str,
        /// The repeated id.
        id: i64,
        /// 1-based line number of the first definition.
        first_line: usize,
    },
    /// A set member that is neither a defined id nor a defined set.
    #[error(
        "{file}:{line}: set `{set}` references {kind} `{member}`, which is not defined (expected a {kind} id or a {kind} set name defined earlier)"
    )]
    UnknownSetMember {
        /// The file (source) name.
        file: String,
        /// 1-based line number of the member.
        line: usize,
        /// The set being defined.
        set: String,
        /// `node` or `element`.
        kind: &'static str,
        /// The member as written.
        member: String,
    },
    /// A file without any 3-node triangle.
    #[error("{file}: no 3-node triangles found; {hint}")]
    NoTriangles {
        /// The file (source) name.
        file: String,
        /// What is probably missing.
        hint: String,
    },
    /// A set name that the mesh does not have.
    #[error("{file}: no {kind} set named `{name}`; available {kind} sets: {}", if .available.is_empty() { "(none)".to_string() } else { .available.join(", ") })]
    UnknownSet {
        /// The mesh source.
        file: String,
        /// `node` or `element`.
        kind: &'static str,
        /// The requested name.
        name: String,
        /// The names the mesh has.
        available: Vec<String>,
    },
    /// A triangle whose area is (nearly) zero.
    #[error(
        "{file}: element {element} is degenerate: area {area:e} mm² <= 1e-10 × (longest edge {longest_edge:e} mm)²"
    )]
    Degenerate {
        /// The mesh source.
        file: String,
        /// The element label.
        element: i64,
        /// Its area (mm²).
        area: f64,
        /// Its longest edge (mm).
        longest_edge: f64,
    },
    /// A global fibre direction (nearly) normal to an element.
    #[error("{file}: element {element}: the fibre direction ({}, {}, {}) is (nearly) normal to the element; its in-plane projection has length {} < 1e-6", crate::config::readable_number(.direction[0]), crate::config::readable_number(.direction[1]), crate::config::readable_number(.direction[2]), crate::config::readable_number(*.length))]
    FibreNormalToElement {
        /// The mesh source.
        file: String,
        /// The element label.
        element: i64,
        /// The global direction as given.
        direction: [f64; 3],
        /// Length of the projection of the unit direction on the plane.
        length: f64,
    },
    /// Any other inconsistency found by [`Mesh::check`].
    #[error("{file}: {what}")]
    Invalid {
        /// The mesh source.
        file: String,
        /// What is wrong, naming the node or element label and the value.
        what: String,
    },
    /// An OAT specimen specification that cannot be meshed.
    #[error("{parameter} = {value}: expected {expected} (specimen generator)")]
    InvalidSpec {
        /// The parameter, spelled as its case-file key (`width`, `length`,
        /// `bias_angle_deg`, `element_size`, `nx, ny`, `pattern`).
        parameter: &'static str,
        /// The value as given.
        value: String,
        /// What is allowed.
        expected: String,
    },
}

impl Mesh {
    /// The external label of element `e` (its 1-based index if labels are
    /// missing).
    pub fn element_label(&self, e: usize) -> i64 {
        self.element_labels.get(e).copied().unwrap_or(e as i64 + 1)
    }

    /// The external label of node `n` (its 1-based index if labels are
    /// missing).
    pub fn node_label(&self, n: usize) -> i64 {
        self.node_labels.get(n).copied().unwrap_or(n as i64 + 1)
    }

    /// Checks the mesh: label counts match; coordinates finite; node indices
    /// in range; no node repeated in a triangle; no degenerate triangle
    /// (`area <= 1e-10 · (longest edge)²`, the error names the element label
    /// and its area); fibres empty or one per triangle, unit and in plane
    /// (`|‖a‖ − 1| <= 1e-9`, `|a·n| <= 1e-9`); set members in range, sorted
    /// and unique.
    pub fn check(&self) -> Result<(), MeshError> {
        let invalid = |what: String| MeshError::Invalid {
            file: self.source.clone(),
            what,
        };
        if self.node_labels.len() != self.nodes.len() {
            return Err(invalid(format!(
                "{} node labels for {} nodes; expected one label per node",
                self.node_labels.len(),
                self.nodes.len()
            )));
        }
        if self.element_labels.len() != self.triangles.len() {
            return Err(invalid(format!(
                "{} element labels for {} triangles; expected one label per triangle",
                self.element_labels.len(),
                self.triangles.len()
            )));
        }
        for (n, x) in self.nodes.iter().enumerate() {
            if !x.iter().all(|c| c.is_finite()) {
                return Err(invalid(format!(
                    "node {} has non-finite coordinates ({}, {}, {}); expected finite numbers",
                    self.node_label(n),
                    crate::config::readable_number(x.x),
                    crate::config::readable_number(x.y),
                    crate::config::readable_number(x.z)
                )));
            }
        }
        for (e, tri) in self.triangles.iter().enumerate() {
            let label = self.element_label(e);
            for &n in tri {
                if n >= self.nodes.len() {
                    return Err(invalid(format!(
                        "element {label} has node index {n}; expected an index below the node count {}",
                        self.nodes.len()
                    )));
                }
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                let rep = if tri[0] == tri[1] || tri[0] == tri[2] {
                    tri[0]
                } else {
                    tri[1]
                };
                return Err(invalid(format!(
                    "element {label} uses node {} twice; expected three distinct nodes",
                    self.node_label(rep)
                )));
            }
            let area = self.triangle_area(e);
            let longest = self.longest_edge(e);
            if area.is_nan() || area <= DEGENERATE_AREA * longest * longest {
                return Err(MeshError::Degenerate {
                    file: self.source.clone(),
                    element: label,
                    area,
                    longest_edge: longest,
                });
            }
        }
        if !self.fibres.is_empty() {
            if self.fibres.len() != self.triangles.len() {
                return Err(invalid(format!(
                    "{} fibre directions for {} triangles; expected none or one per triangle",
                    self.fibres.len(),
                    self.triangles.len()
                )));
            }
            for (e, a) in self.fibres.iter().enumerate() {
                let label = self.element_label(e);
                let norm = a.norm();
                if norm.is_nan() || (norm - 1.0).abs() > FIBRE_TOLERANCE {
                    return Err(invalid(format!(
                        "element {label}: fibre direction ({}, {}, {}) has length {}; expected a unit vector (±1e-9)",
                        crate::config::readable_number(a.x),
                        crate::config::readable_number(a.y),
                        crate::config::readable_number(a.z),
                        crate::config::readable_number(norm)
                    )));
                }
                let an = a.dot(&self.triangle_normal(e));
                if an.is_nan() || an.abs() > FIBRE_TOLERANCE {
                    return Err(invalid(format!(
                        "element {label}: fibre direction ({}, {}, {}) leaves the element plane (a·n = {}); expected |a·n| <= 1e-9",
                        crate::config::readable_number(a.x),
                        crate::config::readable_number(a.y),
                        crate::config::readable_number(a.z),
                        crate::config::readable_number(an)
                    )));
                }
            }
        }
        for (kind, sets, count) in [
            ("node", &self.node_sets, self.nodes.len()),
            ("element", &self.element_sets, self.triangles.len()),
        ] {
            for (name, members) in sets {
                if let Some(&m) = members.iter().find(|&&m| m >= count) {
                    return Err(invalid(format!(
                        "{kind} set `{name}` has index {m}; expected indices below {count}"
                    )));
                }
                if members.windows(2).any(|w| w[0] >= w[1]) {
                    return Err(invalid(format!(
                        "{kind} set `{name}` is not sorted and unique; expected strictly increasing indices"
                    )));
                }
            }
        }
        Ok(())
    }

    /// Sets the fibre direction of every triangle to the projection of the
    /// global `direction` onto the triangle's plane, normalised:
    /// `a = (d − (d·n) n) / ‖d − (d·n) n‖` with `d` the unit direction.
    ///
    /// Fails without changing the mesh when `direction` is zero or not
    /// finite, or when the projection of the unit direction on some triangle
    /// is shorter than 1e-6 (the direction is along the normal); the error
    /// names the first such element.
    pub fn set_fibres_from_global(&mut self, direction: Vector3<f64>) -> Result<(), MeshError> {
        let norm = direction.norm();
        if !(norm.is_finite() && norm > 0.0) {
            return Err(MeshError::Invalid {
                file: self.source.clone(),
                what: format!(
                    "global fibre direction ({}, {}, {}) is invalid; expected a finite non-zero vector",
                    crate::config::readable_number(direction.x),
                    crate::config::readable_number(direction.y),
                    crate::config::readable_number(direction.z)
                ),
            });
        }
        let d = direction / norm;
        let mut fibres = Vec::with_capacity(self.triangles.len());
        for e in 0..self.triangles.len() {
            let n = self.triangle_normal(e);
            let p = d - n * d.dot(&n);
            let length = p.norm();
            if length.is_nan() || length < MIN_FIBRE_PROJECTION {
                return Err(MeshError::FibreNormalToElement {
                    file: self.source.clone(),
                    element: self.element_label(e),
                    direction: [direction.x, direction.y, direction.z],
                    length,
                });
            }
            let a = p / length;
            // One more projection removes the rounding left by the first.
            let a = (a - n * a.dot(&n)).normalize();
            fibres.push(a);
        }
        self.fibres = fibres;
        Ok(())
    }

    /// The node set `name` (exact name, or the unique case-insensitive
    /// match). The error lists the available node sets.
    pub fn node_set(&self, name: &str) -> Result<&[usize], MeshError> {
        lookup_set(&self.node_sets, name).ok_or_else(|| MeshError::UnknownSet {
            file: self.source.clone(),
            kind: "node",
            name: name.to_string(),
            available: self.node_sets.keys().cloned().collect(),
        })
    }

    /// The element set `name` (exact name, or the unique case-insensitive
    /// match). The error lists the available element sets.
    pub fn element_set(&self, name: &str) -> Result<&[usize], MeshError> {
        lookup_set(&self.element_sets, name).ok_or_else(|| MeshError::UnknownSet {
            file: self.source.clone(),
            kind: "element",
            name: name.to_string(),
            available: self.element_sets.keys().cloned().collect(),
        })
    }

    /// Unit normal of triangle `e` by the right-hand rule on its node order:
    /// `n = (x1 − x0) × (x2 − x0) / ‖…‖`. NaN for a degenerate triangle.
    ///
    /// # Panics
    /// If `e` or one of its node indices is out of range.
    pub fn triangle_normal(&self, e: usize) -> Vector3<f64> {
        self.cross(e).normalize()
    }

    /// Area of triangle `e`, `‖(x1 − x0) × (x2 − x0)‖ / 2` (mm²).
    ///
    /// # Panics
    /// If `e` or one of its node indices is out of range.
    pub fn triangle_area(&self, e: usize) -> f64 {
        0.5 * self.cross(e).norm()
    }

    /// The tributary area of each node, `Σ A0/3` over its triangles
    /// \[mm²\] ([`nodal_areas`]).
    pub fn nodal_areas(&self) -> Vec<f64> {
        nodal_areas(&self.nodes, &self.triangles)
    }

    /// Centroid of triangle `e`, `(x0 + x1 + x2) / 3` (mm).
    ///
    /// # Panics
    /// If `e` or one of its node indices is out of range.
    pub fn centroid(&self, e: usize) -> Vector3<f64> {
        let [a, b, c] = self.triangles[e];
        (self.nodes[a] + self.nodes[b] + self.nodes[c]) / 3.0
    }

    /// Indices of the nodes that belong to no triangle (sorted). Readers
    /// keep such nodes (e.g. reference points); a solver must fix or
    /// ignore them.
    pub fn unconnected_nodes(&self) -> Vec<usize> {
        let mut used = vec![false; self.nodes.len()];
        for tri in &self.triangles {
            for &n in tri {
                if let Some(u) = used.get_mut(n) {
                    *u = true;
                }
            }
        }
        (0..self.nodes.len()).filter(|&n| !used[n]).collect()
    }

    fn cross(&self, e: usize) -> Vector3<f64> {
        let [a, b, c] = self.triangles[e];
        let x0 = self.nodes[a];
        (self.nodes[b] - x0).cross(&(self.nodes[c] - x0))
    }

    fn longest_edge(&self, e: usize) -> f64 {
        let [a, b, c] = self.triangles[e];
        let (xa, xb, xc) = (self.nodes[a], self.nodes[b], self.nodes[c]);
        (xb - xa).norm().max((xc - xb).norm()).max((xa - xc).norm())
    }
}

fn lookup_set<'a>(sets: &'a BTreeMap<String, Vec<usize>>, name: &str) -> Option<&'a [usize]> {
    if let Some(s) = sets.get(name) {
        return Some(s);
    }
    let mut matches = sets.iter().filter(|(k, _)| k.eq_ignore_ascii_case(name));
    match (matches.next(), matches.next()) {
        (Some((_, s)), None) => Some(s),
        _ => None,
    }
}

/// Reads a mesh file as text (lossy: a binary file keeps its ASCII header,
/// so a reader can reject it by name rather than as invalid UTF-8).
pub(crate) fn read_text(path: &std::path::Path) -> Result<(String, String), MeshError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| MeshError::Io {
        file: file.clone(),
        reason: e.to_string(),
    })?;
    Ok((String::from_utf8_lossy(&bytes).into_owned(), file))
}

/// Sorts and deduplicates every set of a map (readers' final step).
pub(crate) fn normalise_sets(sets: &mut BTreeMap<String, Vec<usize>>) {
    for members in sets.values_mut() {
        members.sort_unstable();
        members.dedup();
    }
}

/// The tributary area of each node of the triangles `triangles` on the
/// positions `nodes`: a third of every triangle's area
/// `½ |(x1 − x0) × (x2 − x0)|` at each of its nodes \[mm²\].
///
/// # Panics
/// If a triangle names a node beyond `nodes`.
pub fn nodal_areas(nodes: &[Vector3<f64>], triangles: &[[usize; 3]]) -> Vec<f64> {
    let mut area = vec![0.0; nodes.len()];
    for &[a, b, c] in triangles {
        let x0 = nodes[a];
        let third = 0.5 * (nodes[b] - x0).cross(&(nodes[c] - x0)).norm() / 3.0;
        for n in [a, b, c] {
            area[n] += third;
        }
    }
    area
}
