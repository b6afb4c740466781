//! Edge partners of a triangle mesh: for every triangle and each of its
//! edges, the triangle across the edge and that triangle's vertex opposite
//! it; and the hinge kind of each edge (docs/bending.md, "Stencil and
//! topology").

// Index loops mirror the indices of the formulas (nodes, edges, components).
#![allow(clippy::needless_range_loop)]

use std::collections::HashMap;

use super::HingeKind;

/// The partner of one edge: the triangle across it and its local vertex
/// opposite the shared edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct EdgePartner {
    /// Index of the neighbouring triangle.
    pub triangle: usize,
    /// The neighbour's local vertex `j` opposite the shared edge (so the
    /// shared edge is the neighbour's edge `j`).
    pub local: usize,
    /// The node index of that vertex (stencil slot `3 + i`).
    pub node: usize,
}

/// Why the edge partners of a mesh cannot be found.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TopologyError {
    /// A triangle references a node index past the node count.
    #[error("triangle {triangle} references node {node}, but the mesh has {node_count} nodes")]
    UnknownNode {
        /// The triangle.
        triangle: usize,
        /// The node index.
        node: usize,
        /// Number of nodes.
        node_count: usize,
    },
    /// A triangle uses the same node twice.
    #[error("triangle {triangle} uses node {node} twice")]
    RepeatedNode {
        /// The triangle.
        triangle: usize,
        /// The repeated node.
        node: usize,
    },
    /// More than two triangles share an edge.
    #[error(
        "non-manifold edge ({a}, {b}): shared by triangles {triangles:?}; expected at most two"
    )]
    NonManifold {
        /// First node of the edge (smaller index).
        a: usize,
        /// Second node of the edge.
        b: usize,
        /// All triangles using the edge.
        triangles: Vec<usize>,
    },
    /// Two neighbours traverse their shared edge in the same direction:
    /// their normals (counter-clockwise rule) point to opposite sides.
    #[error(
        "triangles {first} and {second} share edge ({a}, {b}) with inconsistent orientation (both run {a} → {b}); reorder the nodes of one of them"
    )]
    InconsistentOrientation {
        /// One triangle.
        first: usize,
        /// The other triangle.
        second: usize,
        /// Start node of the edge in both.
        a: usize,
        /// End node of the edge in both.
        b: usize,
    },
    /// The bending elements do not match the triangles or nodes.
    #[error(
        "{elements} bending elements over {nodes} nodes for {triangles} triangles over {node_count} nodes; expected one element per triangle and the same nodes"
    )]
    ElementCount {
        /// Elements given.
        elements: usize,
        /// Triangles of the topology.
        triangles: usize,
        /// Node positions given.
        nodes: usize,
        /// Nodes of the topology.
        node_count: usize,
    },
    /// An element's hinge kind does not match the topology (`Neighbour`
    /// without a partner, or `Free`/`Clamped` where there is one).
    #[error("triangle {triangle}, edge {edge}: hinge kind does not match the mesh topology")]
    KindMismatch {
        /// The triangle.
        triangle: usize,
        /// Its local edge.
        edge: usize,
    },
    /// Too many nodes or elements for 31-bit indices.
    #[error(
        "{elements} elements over {nodes} nodes: the explicit bending pass takes fewer than 2³¹ of each"
    )]
    TooLarge {
        /// Elements.
        elements: usize,
        /// Nodes.
        nodes: usize,
    },
    /// The clamp mask does not have one entry per node.
    #[error("clamped-node mask has {found} entries, expected one per node ({expected})")]
    MaskLength {
        /// Entries given.
        found: usize,
        /// Number of nodes.
        expected: usize,
    },
}

/// The triangles of a mesh with the partner of each edge.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BendingTopology {
    /// Node indices of each triangle (counter-clockwise).
    pub triangles: Vec<[usize; 3]>,
    /// `partners[e][i]`: the partner across edge `i` of triangle `e` (the
    /// edge joining its nodes `i + 1` and `i + 2`), `None` on the boundary.
    pub partners: Vec<[Option<EdgePartner>; 3]>,
    /// Number of nodes of the mesh.
    pub node_count: usize,
}

impl BendingTopology {
    /// Finds the edge partners of `triangles` over `node_count` nodes.
    ///
    /// # Errors
    /// Unknown or repeated nodes, non-manifold edges (more than two
    /// triangles), neighbours with inconsistent orientation.
    pub fn new(triangles: &[[usize; 3]], node_count: usize) -> Result<Self, TopologyError> {
        // Directed edge (start, end) → (triangle, local edge).
        let mut by_edge: HashMap<(usize, usize), Vec<(usize, usize)>> =
            HashMap::with_capacity(3 * triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            for &node in tri {
                if node >= node_count {
                    return Err(TopologyError::UnknownNode {
                        triangle: t,
                        node,
                        node_count,
                    });
                }
            }
            for k in 0..3 {
                if tri[k] == tri[(k + 1) % 3] {
                    return Err(TopologyError::RepeatedNode {
                        triangle: t,
                        node: tri[k],
                    });
                }
            }
            for i in 0..3 {
                let (a, b) = (tri[(i + 1) % 3], tri[(i + 2) % 3]);
                by_edge
                    .entry((a.min(b), a.max(b)))
                    .or_default()
                    .push((t, i));
            }
        }
        let mut partners = vec![[None; 3]; triangles.len()];
        // Deterministic error reporting: visit edges in sorted order.
        let mut edges: Vec<_> = by_edge.into_iter().collect();
        edges.sort_unstable_by_key(|(key, _)| *key);
        for ((a, b), users) in edges {
            match users.as_slice() {
                [_] => {}
                [(t1, i1), (t2, i2)] => {
                    let start = |t: usize, i: usize| triangles[t][(i + 1) % 3];
                    if start(*t1, *i1) == start(*t2, *i2) {
                        let s = start(*t1, *i1);
                        return Err(TopologyError::InconsistentOrientation {
                            first: *t1,
                            second: *t2,
                            a: s,
                            b: if s == a { b } else { a },
                        });
                    }
                    partners[*t1][*i1] = Some(EdgePartner {
                        triangle: *t2,
                        local: *i2,
                        node: triangles[*t2][*i2],
                    });
                    partners[*t2][*i2] = Some(EdgePartner {
                        triangle: *t1,
                        local: *i1,
                        node: triangles[*t1][*i1],
                    });
                }
                _ => {
                    return Err(TopologyError::NonManifold {
                        a,
                        b,
                        triangles: users.iter().map(|(t, _)| *t).collect(),
                    });
                }
            }
        }
        Ok(Self {
            triangles: triangles.to_vec(),
            partners,
            node_count,
        })
    }

    /// Hinge kinds: `Neighbour` where an edge has a partner; on the
    /// boundary `Clamped` when both nodes of the edge are clamped
    /// (`clamped[node]`), `Free` otherwise. An interior edge stays a
    /// `Neighbour` whatever its nodes.
    ///
    /// # Errors
    /// [`TopologyError::MaskLength`] when `clamped` has not one entry per
    /// node.
    pub fn hinge_kinds(&self, clamped: &[bool]) -> Result<Vec<[HingeKind; 3]>, TopologyError> {
        if clamped.len() != self.node_count {
            return Err(TopologyError::MaskLength {
                found: clamped.len(),
                expected: self.node_count,
            });
        }
        Ok(self
            .triangles
            .iter()
            .zip(&self.partners)
            .map(|(tri, partners)| {
                std::array::from_fn(|i| match partners[i] {
                    Some(_) => HingeKind::Neighbour,
                    None if clamped[tri[(i + 1) % 3]] && clamped[tri[(i + 2) % 3]] => {
                        HingeKind::Clamped
                    }
                    None => HingeKind::Free,
                })
            })
            .collect())
    }

    /// Hinge kinds with every boundary edge free.
    pub fn free_hinge_kinds(&self) -> Vec<[HingeKind; 3]> {
        self.partners
            .iter()
            .map(|p| p.map(|p| p.map_or(HingeKind::Free, |_| HingeKind::Neighbour)))
            .collect()
    }

    /// The node of each stencil slot of triangle `e`: its own three nodes,
    /// then the partner vertex across each edge (`None` on the boundary).
    pub fn stencil(&self, e: usize) -> [Option<usize>; 6] {
        let t = self.triangles[e];
        let p = self.partners[e];
        [
            Some(t[0]),
            Some(t[1]),
            Some(t[2]),
            p[0].map(|p| p.node),
            p[1].map(|p| p.node),
            p[2].map(|p| p.node),
        ]
    }

    /// How many stencils use each node in an active slot (own nodes, and
    /// partner vertices of `Neighbour` edges): dividing a node's lumped mass
    /// by this count gives each stencil its share for
    /// [`super::BendingElement::max_frequency_squared`] (docs/bending.md,
    /// "Frequency bound").
    pub fn stencil_counts(&self) -> Vec<usize> {
        let mut counts = vec![0; self.node_count];
        for e in 0..self.triangles.len() {
            for node in self.stencil(e).into_iter().flatten() {
                counts[node] += 1;
            }
        }
        counts
    }
}
