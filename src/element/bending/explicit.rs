//! The bending force pass of the explicit solver: three phases, each a
//! plain loop over element batches, in which every element writes forces
//! only to its own three nodes, *adding* them to its force slot
//! (docs/bending.md, "Explicit three-phase scheme").
//!
//! 1. [`BendingPass::geometry`]: per element, the current edges `e_0, e_1`,
//!    `|N|`, `1/|N|` and the unit normal `n` from the own nodes (and
//!    [`BendingPass::ghost_normals`], the normals of the ghost triangles of
//!    clamped edges).
//! 2. [`BendingPass::moments`]: per element, the hinge measures from the
//!    partners' normals, the fibre stretches `I4`, `I8` (from the squared
//!    edge lengths), `Δκ`, `μ_i = ∂W/∂φ_i`, the per-edge moments
//!    `P_{e,i} = l_i ∂W_e/∂θ_i = μ_i J m'(θ_i)` (`m' = cos(θ_i/2)`, or
//!    `2 cos θ_i` on a clamped edge), and the forces of everything the
//!    element's own energy gives its own nodes: the area-ratio, edge-length
//!    and fibre-stretch terms and its own moments' hinge terms.
//! 3. [`BendingPass::hinge_forces`]: per element, the partners' moments on
//!    the shared edges, `P_{p,j}`, and their hinge terms on the own nodes
//!    (and the ghost-triangle terms of clamped edges).
//!
//! With `θ` depending on the positions only through the two unit normals,
//! `∂θ_i/∂x_k = (e_i·e_k)/(l_i |N|) n` on the own nodes (Eq. (9)), so the
//! hinge force of edge `i` on own node `k` is
//! `(P_{e,i} + P_{p,j}) (e_i·e_k)/(l_i² |N|) n`.
//! The squared fibre stretches are linear in the squared edge lengths,
//! `I4 = Σ_i w4_i l_i²` (the triangle's metric; likewise `I8`), so their
//! force on own node `k`, `Σ_α (∂W/∂I_α) ∂I_α/∂x_k`, is
//! `2 Σ_i ω_i s(i, k) e_i` with `ω_i = Σ_α (∂W/∂I_α) w_αi` and
//! `s(i, k) = ±1` at the end nodes of edge `i` (`∂(l_i²)/∂x_k = 2 s(i, k) e_i`):
//! an edge-length term on the own nodes only, added to those of phase 2.
//!
//! Elements are stored in batches of [`LANES`] (structure of arrays), so that
//! on x86-64 with AVX2 each batch runs in SIMD registers (the
//! [`crate::material::lanes::Real`] arithmetic); elsewhere lane by lane with
//! the same expressions. The phases write only to their own batches; the
//! caller may run each phase in parallel over chunks of batches with a
//! barrier in between ([`BendingPass::add_forces`] does so with rayon).

// Index loops mirror the indices of the formulas (nodes, edges, components).
#![allow(clippy::needless_range_loop)]

use nalgebra::Vector3;
use rayon::prelude::*;

use super::element::BendingElement;
use super::topology::BendingTopology;
use super::{BendingStiffness, CLAMP_LIMIT, FOLD_LIMIT, HingeKind, TopologyError};
use crate::material::lanes::Real;

/// Elements per batch (one AVX2 register of `f64`).
pub const LANES: usize = 4;
/// Batches per parallel chunk in [`BendingPass::add_forces`].
const CHUNK_BATCHES: usize = 64;
/// Partner index of a free edge (no normal, no moment).
const NONE: u32 = u32::MAX;
/// Partner normals at or above this index are ghosts (`index − GHOST`).
const GHOST: u32 = 1 << 31;

type Lanes = [f64; LANES];

/// Reference data of [`LANES`] elements (structure of arrays).
#[derive(Debug, Clone, Copy)]
struct ElementBatch {
    /// Node indices of the own three nodes.
    nodes: [[u32; LANES]; 3],
    /// Reference edges `E_0, E_1` (x, y, z each) [mm].
    edges: [Lanes; 6],
    /// Element of the partner normal of each edge, `GHOST + g` for the ghost
    /// `g` of a clamped edge, the element itself for a free edge.
    partner_normal: [[u32; LANES]; 3],
    /// `4 p + j` of the partner's moment on the shared edge (in the flat
    /// moments array); `NONE` for free and clamped edges.
    partner_moment: [[u32; LANES]; 3],
    /// Per edge, bit `l` set where lane `l`'s edge has a hinge (0 for a
    /// free edge); [`lane_mask`] turns the bits into 1/0 lanes.
    active: [u8; 3],
    /// Per edge, bit `l` set where lane `l`'s edge is clamped (measure
    /// `2 sin θ`).
    clamped: [u8; 3],
    /// `c_i` (Voigt, 3 per edge).
    coefficients: [Lanes; 9],
    /// The weights of the squared fibre stretches in the squared edge
    /// lengths, `I4 = Σ_k w4_k l_k²`, `I8 = Σ_k w8_k l_k²`:
    /// `w4_k = −p_{k+1} p_{k+2}` (`p_a = ∂N_a/∂a0`), `w8_k` likewise with
    /// `∂N_a/∂b0` (docs/bending.md, "Explicit three-phase scheme").
    stretch_weights: [Lanes; 6],
    /// `κ0` (not read when every element of the pass is flat:
    /// `PassConstants::flat`).
    reference_curvature: [Lanes; 3],
    /// `A0` [mm²] (the moduli `A0 · (B11, B22, B66)` are formed from it).
    area: Lanes,
    /// `1/(2 A0)` [1/mm²].
    inv_double_area: Lanes,
}

/// Phase-1 output of a batch: the current own geometry (the unit normals
/// go to [`BendingScratch::normals`], one slot per element, which the
/// phases read for the element itself and for its partners).
#[derive(Debug, Clone, Copy, Default)]
pub struct GeometryBatch {
    /// Current edges `e_0, e_1`.
    edges: [Lanes; 6],
    /// `|N| = 2A`.
    norm: Lanes,
    /// `1/|N|`.
    inv_norm: Lanes,
}

/// Phase-2 output of a batch (the moments `P_{e,i}` go to
/// [`BendingScratch::moments`], one slot per element).
#[derive(Debug, Clone, Copy, Default)]
pub struct HingeBatch {
    /// `1/l_i²`.
    inv_length2: [Lanes; 3],
    /// `e_0·e_1, e_1·e_2, e_2·e_0`.
    gram: [Lanes; 3],
}

/// The ghost triangle `(x_a, x_b, G)` of a clamped edge.
#[derive(Debug, Clone, Copy)]
struct Ghost {
    /// The element and its clamped edge `i`.
    element: usize,
    edge: usize,
    /// `a = node i+2`, `b = node i+1`.
    nodes: [usize; 2],
    /// `G − X_b` [mm].
    ghost_from_b: [f64; 3],
    /// `X_a − G` [mm].
    a_from_ghost: [f64; 3],
}

/// Phase-1 output for one ghost triangle.
#[derive(Debug, Clone, Copy, Default)]
pub struct GhostState {
    /// Unit normal of the ghost triangle.
    normal: [f64; 3],
    /// `1/|N'|`.
    inv_norm: f64,
    /// Current `e'_0 = G − x_b`, `e'_1 = x_a − G`.
    edges: [[f64; 3]; 2],
}

/// Scratch arrays of the three phases, sized by [`BendingPass::scratch`].
#[derive(Debug, Clone, Default)]
pub struct BendingScratch {
    /// Phase 1, one per batch.
    pub geometry: Vec<GeometryBatch>,
    /// Phase 1, one per clamped edge.
    pub ghosts: Vec<GhostState>,
    /// Phase 2, one per batch.
    pub hinges: Vec<HingeBatch>,
    /// Phase 1, one per element slot (`LANES` per batch): the unit normal,
    /// compact for the partners' gathers (one cache line each).
    pub normals: Vec<[f64; 4]>,
    /// Phase 2, one per element slot: the moments
    /// `P_{e,i} = μ_i J m'(θ_i)` [N·mm²] (`m' = cos(θ_i/2)`, `2 cos θ_i` on
    /// clamped edges; zero on free edges), compact for the partners'
    /// gathers.
    pub moments: Vec<[f64; 4]>,
}

/// The first element whose bending force could not be computed: a hinge
/// completely folded (`1 + cos θ ≤ FOLD_LIMIT`), a clamped hinge turned to
/// or past 90° about its clamp line (`cos θ ≤ CLAMP_LIMIT`) or a
/// non-finite result (collapsed triangle). [`BendingPass::positions`] and
/// the reference kernels name the cause.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error(
    "bending element {element}: a hinge is folded onto itself, a clamped hinge is turned past 90° or the triangle has collapsed"
)]
pub struct BendingFailure {
    /// The element (triangle) index.
    pub element: usize,
}

/// The explicit bending force pass over a mesh (docs/bending.md, "Explicit
/// three-phase scheme").
#[derive(Debug, Clone)]
pub struct BendingPass {
    batches: Vec<ElementBatch>,
    ghosts: Vec<Ghost>,
    /// Per element: its own nodes and the partner slot nodes (for
    /// [`BendingPass::positions`]).
    topology: BendingTopology,
    elements: Vec<BendingElement>,
    nodes: Vec<Vector3<f64>>,
    element_count: usize,
    /// What every element shares in phase 2.
    constants: PassConstants,
    /// Use the AVX2 path where the CPU has it.
    simd: bool,
}

/// What every element of a pass shares in phase 2.
#[derive(Debug, Clone, Copy)]
struct PassConstants {
    /// `(B11, B22, B66)` [N·mm]: an element's moduli are `A0` times these.
    moduli: [f64; 3],
    /// Every element's reference curvature `κ0` is zero (a flat blank):
    /// `κ − κ0` is `κ` and `κ0` is not read.
    flat: bool,
}

/// Lane masks: row `b`, lane `l` is 1 where bit `l` of `b` is set, else 0.
const LANE_MASKS: [[f64; LANES]; 1 << LANES] = {
    let mut table = [[0.0; LANES]; 1 << LANES];
    let mut b = 0;
    while b < 1 << LANES {
        let mut l = 0;
        while l < LANES {
            if b & (1 << l) != 0 {
                table[b][l] = 1.0;
            }
            l += 1;
        }
        b += 1;
    }
    table
};

/// The unit normals of lanes `off..off + W` from their compact slots
/// (`normals`, the batch's `LANES` slots), as three lane vectors.
#[inline(always)]
fn own_normal<V: Real<Array = [f64; W]>, const W: usize>(
    ctx: V,
    normals: &[[f64; 4]],
    off: usize,
) -> [V; 3] {
    let mut lanes = [[0.0; W]; 3];
    for w in 0..W {
        for c in 0..3 {
            lanes[c][w] = normals[off + w][c];
        }
    }
    [ctx.load(lanes[0]), ctx.load(lanes[1]), ctx.load(lanes[2])]
}

/// Lanes `off..off + W` of the 1/0 mask of the lane bits `bits`.
#[inline(always)]
fn lane_mask<V: Real<Array = [f64; W]>, const W: usize>(ctx: V, bits: u8, off: usize) -> V {
    ld(ctx, &LANE_MASKS[bits as usize], off)
}

impl BendingPass {
    /// Lays out the pass for the elements `elements` (one per triangle of
    /// `topology`, built from the reference positions `nodes` \[mm\]) with the
    /// stiffness `stiffness`.
    ///
    /// # Errors
    /// [`TopologyError::ElementCount`] or [`TopologyError::KindMismatch`]
    /// when the elements do not match the topology,
    /// [`TopologyError::TooLarge`] past `2³¹` nodes or elements.
    pub fn new(
        nodes: &[Vector3<f64>],
        topology: &BendingTopology,
        elements: &[BendingElement],
        stiffness: &BendingStiffness,
    ) -> Result<Self, TopologyError> {
        let count = topology.triangles.len();
        if elements.len() != count || nodes.len() != topology.node_count {
            return Err(TopologyError::ElementCount {
                elements: elements.len(),
                triangles: count,
                nodes: nodes.len(),
                node_count: topology.node_count,
            });
        }
        if count >= GHOST as usize || nodes.len() >= GHOST as usize {
            return Err(TopologyError::TooLarge {
                elements: count,
                nodes: nodes.len(),
            });
        }
        let mut ghosts = Vec::new();
        for (e, element) in elements.iter().enumerate() {
            for i in 0..3 {
                let has_partner = topology.partners[e][i].is_some();
                let ok = match element.kinds[i] {
                    HingeKind::Neighbour => has_partner,
                    HingeKind::Free | HingeKind::Clamped => !has_partner,
                };
                if !ok {
                    return Err(TopologyError::KindMismatch {
                        triangle: e,
                        edge: i,
                    });
                }
                if element.kinds[i] == HingeKind::Clamped {
                    let tri = topology.triangles[e];
                    let (a, b) = (tri[(i + 2) % 3], tri[(i + 1) % 3]);
                    let g = Vector3::from(element.ghosts[i]);
                    ghosts.push(Ghost {
                        element: e,
                        edge: i,
                        nodes: [a, b],
                        ghost_from_b: (g - nodes[b]).into(),
                        a_from_ghost: (nodes[a] - g).into(),
                    });
                }
            }
        }
        let d = stiffness.diagonal();
        let batch_count = count.div_ceil(LANES);
        let mut batches = Vec::with_capacity(batch_count);
        let mut ghost_of = vec![[NONE; 3]; count];
        for (index, g) in ghosts.iter().enumerate() {
            ghost_of[g.element][g.edge] = index as u32;
        }
        for b in 0..batch_count {
            let mut batch = ElementBatch {
                nodes: [[0; LANES]; 3],
                edges: [[0.0; LANES]; 6],
                partner_normal: [[0; LANES]; 3],
                partner_moment: [[NONE; LANES]; 3],
                active: [0; 3],
                clamped: [0; 3],
                coefficients: [[0.0; LANES]; 9],
                stretch_weights: [[0.0; LANES]; 6],
                reference_curvature: [[0.0; LANES]; 3],
                area: [0.0; LANES],
                inv_double_area: [0.0; LANES],
            };
            for l in 0..LANES {
                // Padding lanes repeat the last element; their results are
                // never written out.
                let e = (b * LANES + l).min(count - 1);
                let tri = topology.triangles[e];
                let element = &elements[e];
                for k in 0..3 {
                    batch.nodes[k][l] = tri[k] as u32;
                }
                let e0 = nodes[tri[2]] - nodes[tri[1]];
                let e1 = nodes[tri[0]] - nodes[tri[2]];
                for c in 0..3 {
                    batch.edges[c][l] = e0[c];
                    batch.edges[3 + c][l] = e1[c];
                }
                for i in 0..3 {
                    match (element.kinds[i], topology.partners[e][i]) {
                        (HingeKind::Neighbour, Some(p)) => {
                            batch.partner_normal[i][l] = p.triangle as u32;
                            batch.partner_moment[i][l] = (4 * p.triangle + p.local) as u32;
                            batch.active[i] |= 1 << l;
                        }
                        (HingeKind::Clamped, _) => {
                            batch.partner_normal[i][l] = GHOST + ghost_of[e][i];
                            batch.active[i] |= 1 << l;
                            batch.clamped[i] |= 1 << l;
                        }
                        _ => batch.partner_normal[i][l] = e as u32,
                    }
                    for v in 0..3 {
                        batch.coefficients[3 * i + v][l] = element.coefficients[i][v];
                    }
                    for (alpha, p) in element.fibre_gradients.iter().enumerate() {
                        batch.stretch_weights[3 * alpha + i][l] = -p[(i + 1) % 3] * p[(i + 2) % 3];
                    }
                }
                for v in 0..3 {
                    batch.reference_curvature[v][l] = element.reference_curvature[v];
                }
                batch.area[l] = element.area;
                batch.inv_double_area[l] = 1.0 / (2.0 * element.area);
            }
            batches.push(batch);
        }
        Ok(Self {
            batches,
            ghosts,
            topology: topology.clone(),
            elements: elements.to_vec(),
            nodes: nodes.to_vec(),
            element_count: count,
            constants: PassConstants {
                moduli: d,
                flat: elements.iter().all(|e| e.reference_curvature == [0.0; 3]),
            },
            simd: true,
        })
    }

    /// With `enabled = false` the phases run lane by lane without SIMD (the
    /// same expressions; for comparisons and tests). On by default.
    pub fn with_simd(mut self, enabled: bool) -> Self {
        self.simd = enabled;
        self
    }

    #[cfg(target_arch = "x86_64")]
    fn simd_token(&self) -> Option<pulp::x86::V3> {
        if self.simd {
            pulp::x86::V3::try_new()
        } else {
            None
        }
    }

    /// Number of elements.
    pub fn element_count(&self) -> usize {
        self.element_count
    }

    /// Number of batches (`⌈elements / LANES⌉`).
    pub fn batch_count(&self) -> usize {
        self.batches.len()
    }

    /// The elements, in the order of the force slots.
    pub fn elements(&self) -> &[BendingElement] {
        &self.elements
    }

    /// Scratch arrays of the right sizes.
    pub fn scratch(&self) -> BendingScratch {
        BendingScratch {
            geometry: vec![GeometryBatch::default(); self.batches.len()],
            ghosts: vec![GhostState::default(); self.ghosts.len()],
            hinges: vec![HingeBatch::default(); self.batches.len()],
            normals: vec![[0.0; 4]; self.batches.len() * LANES],
            moments: vec![[0.0; 4]; self.batches.len() * LANES],
        }
    }

    /// The current positions `X + u` \[mm\] of the six stencil slots of
    /// element `e` for the reference kernels (ignored slots: the element's
    /// first node).
    pub fn positions(&self, e: usize, u: &[f64]) -> [Vector3<f64>; 6] {
        let stencil = self.topology.stencil(e);
        let first = stencil[0].unwrap_or(0);
        std::array::from_fn(|s| {
            let n = stencil[s].unwrap_or(first);
            self.nodes[n] + Vector3::new(u[3 * n], u[3 * n + 1], u[3 * n + 2])
        })
    }

    /// Phase 1 for the batches `first..first + geometry.len()`: own edges,
    /// `|N|`, `1/|N|` and the unit normal from the displacements `u` \[mm\]
    /// (3 per node); the normals also into `normals` (`LANES` slots per
    /// batch).
    pub fn geometry(
        &self,
        first: usize,
        u: &[f64],
        geometry: &mut [GeometryBatch],
        normals: &mut [[f64; 4]],
    ) {
        let batches = &self.batches[first..first + geometry.len()];
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = self.simd_token() {
            let pass = Avx2Geometry {
                simd,
                batches,
                u,
                geometry: &mut *geometry,
                normals: &mut *normals,
            };
            <pulp::x86::V3 as pulp::Simd>::vectorize(simd, pass);
            return;
        }
        for ((batch, out), normals) in batches
            .iter()
            .zip(geometry.iter_mut())
            .zip(normals.chunks_exact_mut(LANES))
        {
            for l in 0..LANES {
                geometry_lanes::<f64, 1>(0.0, batch, u, out, normals, l);
            }
        }
    }

    /// Phase 1 for the ghost triangles of clamped edges (all of them; there
    /// are few).
    pub fn ghost_normals(&self, u: &[f64], ghosts: &mut [GhostState]) {
        for (ghost, out) in self.ghosts.iter().zip(ghosts.iter_mut()) {
            let [a, b] = ghost.nodes;
            let mut e0 = [0.0; 3];
            let mut e1 = [0.0; 3];
            for c in 0..3 {
                e0[c] = ghost.ghost_from_b[c] - u[3 * b + c];
                e1[c] = ghost.a_from_ghost[c] + u[3 * a + c];
            }
            let big_n = cross(&e0, &e1);
            let norm = dot(&big_n, &big_n).sqrt();
            let inv_norm = 1.0 / norm;
            *out = GhostState {
                normal: big_n.map(|c| c * inv_norm),
                inv_norm,
                edges: [e0, e1],
            };
        }
    }

    /// Phase 2 for the batches `first..first + hinges.len()`: hinge measures
    /// from the partners' normals (`geometry`, `normals` and `ghosts` of all
    /// elements, from phase 1), curvature, moments into `hinges` and
    /// `moments` (`LANES` slots per batch), and the forces of the own energy
    /// on the own nodes added to `forces` (the slots of the elements of
    /// these batches, `forces.len() = min(LANES·len, count − LANES·first)`).
    ///
    /// # Errors
    /// The first element of these batches with a folded hinge, a clamped
    /// hinge turned to or past 90° or a non-finite result.
    #[allow(clippy::too_many_arguments)]
    pub fn moments<const ADD: bool>(
        &self,
        first: usize,
        geometry: &[GeometryBatch],
        normals: &[[f64; 4]],
        ghosts: &[GhostState],
        hinges: &mut [HingeBatch],
        moments: &mut [[f64; 4]],
        forces: &mut [[f64; 9]],
    ) -> Result<(), BendingFailure> {
        let batches = &self.batches[first..first + hinges.len()];
        let own = &geometry[first..first + hinges.len()];
        let own_normals = &normals[first * LANES..(first + hinges.len()) * LANES];
        let failed = 'pass: {
            #[cfg(target_arch = "x86_64")]
            if let Some(simd) = self.simd_token() {
                let pass = Avx2Moments::<ADD> {
                    simd,
                    constants: &self.constants,
                    batches,
                    own,
                    own_normals,
                    normals,
                    ghosts,
                    hinges: &mut *hinges,
                    moments: &mut *moments,
                    forces: &mut *forces,
                };
                break 'pass <pulp::x86::V3 as pulp::Simd>::vectorize(simd, pass);
            }
            moments_scalar::<ADD>(
                &self.constants,
                batches,
                own,
                own_normals,
                normals,
                ghosts,
                hinges,
                moments,
                forces,
            )
        };
        match failed {
            Some(offset) => Err(BendingFailure {
                element: first * LANES + offset,
            }),
            None => Ok(()),
        }
    }

    /// Phase 3 for the batches `first..first + forces.len().div_ceil(LANES)`:
    /// the partners' moments (`hinges` and `moments` of all elements, from
    /// phase 2) on the shared edges and the ghost-triangle terms of clamped
    /// edges, added to `forces`.
    #[allow(clippy::too_many_arguments)]
    pub fn hinge_forces(
        &self,
        first: usize,
        geometry: &[GeometryBatch],
        normals: &[[f64; 4]],
        ghosts: &[GhostState],
        hinges: &[HingeBatch],
        moments: &[[f64; 4]],
        forces: &mut [[f64; 9]],
    ) {
        let count = forces.len().div_ceil(LANES);
        let batches = &self.batches[first..first + count];
        let own = &geometry[first..first + count];
        let own_hinges = &hinges[first..first + count];
        let own_normals = &normals[first * LANES..(first + count) * LANES];
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = self.simd_token() {
            let pass = Avx2HingeForces {
                simd,
                batches,
                own,
                own_normals,
                own_hinges,
                moments,
                forces: &mut *forces,
            };
            <pulp::x86::V3 as pulp::Simd>::vectorize(simd, pass);
            self.ghost_forces(first, ghosts, hinges, moments, geometry, forces);
            return;
        }
        for (b, (batch, (geo, hinge))) in batches.iter().zip(own.iter().zip(own_hinges)).enumerate()
        {
            let end = ((b + 1) * LANES).min(forces.len());
            let slots = &mut forces[b * LANES..end];
            let own_normals = &own_normals[b * LANES..(b + 1) * LANES];
            for l in 0..slots.len() {
                hinge_force_lanes::<f64, 1>(0.0, batch, geo, own_normals, hinge, moments, slots, l);
            }
        }
        self.ghost_forces(first, ghosts, hinges, moments, geometry, forces);
    }

    /// The ghost-triangle hinge terms of the clamped edges of the elements
    /// `first·LANES..` (those of `forces`): `(P_{e,i}/l_i²)(e'_2·e'_k)/|N'| n'`
    /// on the edge nodes.
    fn ghost_forces(
        &self,
        first: usize,
        ghosts: &[GhostState],
        hinges: &[HingeBatch],
        moments: &[[f64; 4]],
        geometry: &[GeometryBatch],
        forces: &mut [[f64; 9]],
    ) {
        let start = first * LANES;
        let end = start + forces.len();
        let from = self.ghosts.partition_point(|g| g.element < start);
        let to = self.ghosts.partition_point(|g| g.element < end);
        for (ghost, state) in self.ghosts[from..to].iter().zip(&ghosts[from..to]) {
            let e = ghost.element;
            let i = ghost.edge;
            let (b, l) = (e / LANES, e % LANES);
            let hinge = &hinges[b];
            let geo = &geometry[b];
            let moment = moments[e][i] * hinge.inv_length2[i][l];
            // e'_2 = x_b − x_a = −e_i.
            let own_edge = own_edge(geo, l, i);
            let edge2 = own_edge.map(|c| -c);
            let scale = moment * state.inv_norm;
            let [e0, e1] = &state.edges;
            let coefficient = [dot(&edge2, e0) * scale, dot(&edge2, e1) * scale];
            let slot_a = (i + 2) % 3;
            let slot_b = (i + 1) % 3;
            let out = &mut forces[e - start];
            for c in 0..3 {
                out[3 * slot_a + c] += coefficient[0] * state.normal[c];
                out[3 * slot_b + c] += coefficient[1] * state.normal[c];
            }
        }
    }

    /// All three phases for the displacements `u` \[mm\], the bending forces
    /// `∂W/∂x` \[N\] of each element's own nodes *added* to `forces` (one slot
    /// per element, node-major). Runs in parallel on rayon's current pool
    /// over chunks of batches, a barrier between the phases.
    ///
    /// # Errors
    /// The first element with a folded hinge, a clamped hinge turned to or
    /// past 90° or a non-finite result.
    pub fn add_forces(
        &self,
        u: &[f64],
        scratch: &mut BendingScratch,
        forces: &mut [[f64; 9]],
    ) -> Result<(), BendingFailure> {
        self.forces_with::<true>(u, scratch, forces)
    }

    /// [`BendingPass::add_forces`] writing the forces over `forces` (one
    /// slot per element) instead of adding them: the slots need no zeroing
    /// pass, and phase 2 writes them without reading them first (less
    /// memory traffic; the same values as adding to zeroed slots).
    ///
    /// # Errors
    /// As [`BendingPass::add_forces`].
    pub fn write_forces(
        &self,
        u: &[f64],
        scratch: &mut BendingScratch,
        forces: &mut [[f64; 9]],
    ) -> Result<(), BendingFailure> {
        self.forces_with::<false>(u, scratch, forces)
    }

    fn forces_with<const ADD: bool>(
        &self,
        u: &[f64],
        scratch: &mut BendingScratch,
        forces: &mut [[f64; 9]],
    ) -> Result<(), BendingFailure> {
        let chunk = CHUNK_BATCHES;
        scratch
            .geometry
            .par_chunks_mut(chunk)
            .zip(scratch.normals.par_chunks_mut(chunk * LANES))
            .enumerate()
            .for_each(|(c, (out, normals))| self.geometry(c * chunk, u, out, normals));
        self.ghost_normals(u, &mut scratch.ghosts);
        let geometry = &scratch.geometry;
        let normals = &scratch.normals;
        let ghosts = &scratch.ghosts;
        let failure = scratch
            .hinges
            .par_chunks_mut(chunk)
            .zip(scratch.moments.par_chunks_mut(chunk * LANES))
            .zip(forces.par_chunks_mut(chunk * LANES))
            .enumerate()
            .map(|(c, ((hinges, moments), forces))| {
                self.moments::<ADD>(
                    c * chunk,
                    geometry,
                    normals,
                    ghosts,
                    hinges,
                    moments,
                    forces,
                )
                .err()
                .map_or(usize::MAX, |f| f.element)
            })
            .min()
            .unwrap_or(usize::MAX);
        if failure != usize::MAX {
            return Err(BendingFailure { element: failure });
        }
        let hinges = &scratch.hinges;
        let moments = &scratch.moments;
        forces
            .par_chunks_mut(chunk * LANES)
            .enumerate()
            .for_each(|(c, slots)| {
                let first = c * chunk;
                self.hinge_forces(first, geometry, normals, ghosts, hinges, moments, slots)
            });
        Ok(())
    }
}

/// `e_i` of lane `l` from the phase-1 edges (`e_2 = −e_0 − e_1`).
#[inline]
fn own_edge(geo: &GeometryBatch, l: usize, i: usize) -> [f64; 3] {
    std::array::from_fn(|c| match i {
        0 => geo.edges[c][l],
        1 => geo.edges[3 + c][l],
        _ => -geo.edges[c][l] - geo.edges[3 + c][l],
    })
}

#[inline(always)]
fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Lanes `off..off + W` of `a`.
#[inline(always)]
fn ld<V: Real<Array = [f64; W]>, const W: usize>(ctx: V, a: &Lanes, off: usize) -> V {
    let mut t = [0.0; W];
    t.copy_from_slice(&a[off..off + W]);
    ctx.load(t)
}

/// Stores `v` into lanes `off..off + W` of `a`.
#[inline(always)]
fn st<V: Real<Array = [f64; W]>, const W: usize>(v: V, a: &mut Lanes, off: usize) {
    a[off..off + W].copy_from_slice(&v.store());
}

#[inline(always)]
fn vdot<V: Real>(a: &[V; 3], b: &[V; 3]) -> V {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn vcross<V: Real>(a: &[V; 3], b: &[V; 3]) -> [V; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Phase 1 for lanes `off..off + W` of one batch.
#[inline(always)]
fn geometry_lanes<V: Real<Array = [f64; W]>, const W: usize>(
    ctx: V,
    batch: &ElementBatch,
    u: &[f64],
    out: &mut GeometryBatch,
    normals: &mut [[f64; 4]],
    off: usize,
) {
    // Gather the own nodes' displacements: du[k][c] lane by lane.
    let mut du = [[[0.0; W]; 3]; 3];
    for w in 0..W {
        for k in 0..3 {
            let n = 3 * batch.nodes[k][off + w] as usize;
            let node = &u[n..n + 3];
            for c in 0..3 {
                du[k][c][w] = node[c];
            }
        }
    }
    let load = |k: usize, c: usize| ctx.load(du[k][c]);
    let mut e0 = [ctx; 3];
    let mut e1 = [ctx; 3];
    for c in 0..3 {
        e0[c] = ld(ctx, &batch.edges[c], off) + (load(2, c) - load(1, c));
        e1[c] = ld(ctx, &batch.edges[3 + c], off) + (load(0, c) - load(2, c));
    }
    let big_n = vcross(&e0, &e1);
    let norm = vdot(&big_n, &big_n).sqrt();
    let inv_norm = ctx.splat(1.0) / norm;
    let normal = [
        (big_n[0] * inv_norm).store(),
        (big_n[1] * inv_norm).store(),
        (big_n[2] * inv_norm).store(),
    ];
    for w in 0..W {
        normals[off + w] = [normal[0][w], normal[1][w], normal[2][w], 0.0];
    }
    for c in 0..3 {
        st(e0[c], &mut out.edges[c], off);
        st(e1[c], &mut out.edges[3 + c], off);
    }
    st(norm, &mut out.norm, off);
    st(inv_norm, &mut out.inv_norm, off);
}

/// Phase 2 for lanes `off..off + W` of one batch; returns the lanes (bits)
/// that failed.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn moment_lanes<V: Real<Array = [f64; W]>, const W: usize, const ADD: bool>(
    ctx: V,
    constants: &PassConstants,
    batch: &ElementBatch,
    own: &GeometryBatch,
    own_normals: &[[f64; 4]],
    normals: &[[f64; 4]],
    ghosts: &[GhostState],
    hinge: &mut HingeBatch,
    own_moments: &mut [[f64; 4]],
    forces: &mut [[f64; 9]],
    off: usize,
) -> u32 {
    let one = ctx.splat(1.0);
    let mut e = [[ctx; 3]; 3];
    let n = own_normal(ctx, own_normals, off);
    for c in 0..3 {
        e[0][c] = ld(ctx, &own.edges[c], off);
        e[1][c] = ld(ctx, &own.edges[3 + c], off);
        e[2][c] = -(e[0][c] + e[1][c]);
    }
    let norm = ld(ctx, &own.norm, off);
    let inv_norm = ld(ctx, &own.inv_norm, off);
    let length2 = [vdot(&e[0], &e[0]), vdot(&e[1], &e[1]), vdot(&e[2], &e[2])];
    let inv_length2 = [one / length2[0], one / length2[1], one / length2[2]];
    // e_i × n = l_i ν_i (outward in-plane normal times length).
    let outward = [vcross(&e[0], &n), vcross(&e[1], &n), vcross(&e[2], &n)];
    let area_ratio = norm * ld(ctx, &batch.inv_double_area, off);
    let mut phi = [ctx; 3];
    let mut active = [ctx; 3];
    let mut slope = [ctx; 3];
    let mut failed = 0u32;
    for i in 0..3 {
        // Gather the partner normals.
        let mut partner = [[0.0; W]; 3];
        for w in 0..W {
            let p = batch.partner_normal[i][off + w];
            if p < GHOST {
                let normal = &normals[p as usize];
                for c in 0..3 {
                    partner[c][w] = normal[c];
                }
            } else {
                let g = &ghosts[(p - GHOST) as usize];
                for c in 0..3 {
                    partner[c][w] = g.normal[c];
                }
            }
        }
        let partner = [
            ctx.load(partner[0]),
            ctx.load(partner[1]),
            ctx.load(partner[2]),
        ];
        active[i] = lane_mask(ctx, batch.active[i], off);
        let clamped = lane_mask(ctx, batch.clamped[i], off);
        let not_clamped = one - clamped;
        let cos = vdot(&n, &partner);
        let one_plus_cos = one + cos;
        // l_i sin θ = −n'·(e_i × n).
        let length_sin = -vdot(&partner, &outward[i]);
        let zero = ctx.splat(0.0);
        let fold = one_plus_cos.le(ctx.splat(FOLD_LIMIT)) & active[i].gt(zero) & clamped.le(zero);
        let overturned = cos.le(ctx.splat(CLAMP_LIMIT)) & clamped.gt(zero);
        failed |= V::bits(fold | overturned);
        // Interior hinge: y = 2 cos(θ/2) = √(2(1 + cos θ)),
        // φ = θ̂ J / l = 2 (l sin θ) J / (l² y), m' = y/2.
        // Clamped hinge: y = 1, φ = 2 sin θ J / l = 2 (l sin θ) J / l²,
        // m' = 2 cos θ (docs/bending.md, Eq. (2c)).
        let y = (one_plus_cos * 2.0 * not_clamped + clamped).sqrt();
        slope[i] = y * 0.5 * not_clamped + cos * 2.0 * clamped;
        phi[i] = length_sin * 2.0 * area_ratio * inv_length2[i] / y * active[i];
    }
    // Fibre stretches from the squared edge lengths (the metric of the
    // triangle): I4 = Σ_k w4_k l_k², I8 = Σ_k w8_k l_k²; the factors
    // s = [1/I4, 1/I8, 1/√(I4 I8)] with one division and one square root.
    let weight = |a: usize, k: usize| ld(ctx, &batch.stretch_weights[3 * a + k], off);
    let i4 = weight(0, 0) * length2[0] + weight(0, 1) * length2[1] + weight(0, 2) * length2[2];
    let i8 = weight(1, 0) * length2[0] + weight(1, 1) * length2[1] + weight(1, 2) * length2[2];
    let inv_product = one / (i4 * i8);
    let scales = [i8 * inv_product, i4 * inv_product, inv_product.sqrt()];
    // κ = s K, moment M = A0 D Δκ, μ_i = Σ_v c_iv s_v M_v.
    let mut kappa = [ctx; 3];
    let mut moment = [ctx; 3];
    let mut scaled_moment = [ctx; 3];
    for v in 0..3 {
        let mut k = phi[0] * ld(ctx, &batch.coefficients[v], off);
        for i in 1..3 {
            k = k + phi[i] * ld(ctx, &batch.coefficients[3 * i + v], off);
        }
        kappa[v] = k * scales[v];
        let change = if constants.flat {
            kappa[v]
        } else {
            kappa[v] - ld(ctx, &batch.reference_curvature[v], off)
        };
        moment[v] = change * (ld(ctx, &batch.area, off) * constants.moduli[v]);
        scaled_moment[v] = moment[v] * scales[v];
    }
    let mut mu = [ctx; 3];
    for (i, mu) in mu.iter_mut().enumerate() {
        *mu = ld(ctx, &batch.coefficients[3 * i], off) * scaled_moment[0]
            + ld(ctx, &batch.coefficients[3 * i + 1], off) * scaled_moment[1]
            + ld(ctx, &batch.coefficients[3 * i + 2], off) * scaled_moment[2];
    }
    // −2 ∂W/∂I4 = 2 s1 (M1 κ1 + ½ M3 κ3), likewise for I8 (Eq. (8)); the
    // stretch force on own node k, Σ_α (∂W/∂I_α) Σ_i w_αi ∂(l_i²)/∂x_k,
    // has the form of the edge-length terms below: it joins τ_i as
    // −2 ω_i = −2 Σ_α (∂W/∂I_α) w_αi.
    let half_twist = moment[2] * kappa[2] * 0.5;
    let stretch_force4 = (moment[0] * kappa[0] + half_twist) * scales[0] * 2.0;
    let stretch_force8 = (moment[1] * kappa[1] + half_twist) * scales[1] * 2.0;
    // Per-edge moments P_i = μ_i J m'(θ_i) and π_i = P_i / l_i².
    let mut pi = [ctx; 3];
    let mut sigma = ctx.splat(0.0);
    let mut tau = [ctx; 3];
    for i in 0..3 {
        let p = mu[i] * area_ratio * slope[i] * active[i];
        let lanes = p.store();
        for w in 0..W {
            own_moments[off + w][i] = lanes[w];
        }
        st(inv_length2[i], &mut hinge.inv_length2[i], off);
        pi[i] = p * inv_length2[i];
        let mu_phi = mu[i] * phi[i];
        sigma = sigma + mu_phi;
        tau[i] =
            mu_phi * inv_length2[i] + stretch_force4 * weight(0, i) + stretch_force8 * weight(1, i);
    }
    sigma = sigma * inv_norm;
    // Gram matrix off-diagonals from the squared lengths.
    let gram = [
        (length2[2] - length2[0] - length2[1]) * 0.5, // e_0·e_1
        (length2[0] - length2[1] - length2[2]) * 0.5, // e_1·e_2
        (length2[1] - length2[2] - length2[0]) * 0.5, // e_2·e_0
    ];
    for (g, out) in gram.iter().zip(hinge.gram.iter_mut()) {
        st(*g, out, off);
    }
    // t_k = (1/|N|) Σ_i π_i (e_i·e_k).
    let t = [
        (pi[0] * length2[0] + pi[1] * gram[0] + pi[2] * gram[2]) * inv_norm,
        (pi[0] * gram[0] + pi[1] * length2[1] + pi[2] * gram[1]) * inv_norm,
        (pi[0] * gram[2] + pi[1] * gram[1] + pi[2] * length2[2]) * inv_norm,
    ];
    let mut f = [[ctx; 3]; 3];
    let mut total = ctx.splat(0.0);
    for k in 0..3 {
        let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
        for c in 0..3 {
            f[k][c] = t[k] * n[c] - sigma * outward[k][c] + tau[k2] * e[k2][c] - tau[k1] * e[k1][c];
            total = total + f[k][c].abs();
        }
    }
    let not_finite = !total.is_finite();
    failed |= V::bits(not_finite);
    let lanes = W.min(forces.len().saturating_sub(off));
    let stored: [[[f64; W]; 3]; 3] = [
        [f[0][0].store(), f[0][1].store(), f[0][2].store()],
        [f[1][0].store(), f[1][1].store(), f[1][2].store()],
        [f[2][0].store(), f[2][1].store(), f[2][2].store()],
    ];
    scatter::<W, ADD>(forces, off, &stored);
    // Padding lanes never fail.
    if lanes < W {
        failed &= (1u32 << lanes) - 1;
    }
    failed
}

/// Phase 2 lane by lane (no SIMD); the first failing offset.
#[allow(clippy::too_many_arguments)]
fn moments_scalar<const ADD: bool>(
    constants: &PassConstants,
    batches: &[ElementBatch],
    own: &[GeometryBatch],
    own_normals: &[[f64; 4]],
    normals: &[[f64; 4]],
    ghosts: &[GhostState],
    hinges: &mut [HingeBatch],
    moments: &mut [[f64; 4]],
    forces: &mut [[f64; 9]],
) -> Option<usize> {
    for (b, ((batch, (geo, hinge)), own_moments)) in batches
        .iter()
        .zip(own.iter().zip(hinges.iter_mut()))
        .zip(moments.chunks_exact_mut(LANES))
        .enumerate()
    {
        let end = ((b + 1) * LANES).min(forces.len());
        let slots = &mut forces[b * LANES..end];
        let own_normals = &own_normals[b * LANES..(b + 1) * LANES];
        for l in 0..LANES {
            if moment_lanes::<f64, 1, ADD>(
                0.0,
                constants,
                batch,
                geo,
                own_normals,
                normals,
                ghosts,
                hinge,
                own_moments,
                slots,
                l,
            ) != 0
            {
                return Some(b * LANES + l);
            }
        }
    }
    None
}

/// Phase 3 for lanes `off..off + W` of one batch.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn hinge_force_lanes<V: Real<Array = [f64; W]>, const W: usize>(
    ctx: V,
    batch: &ElementBatch,
    own: &GeometryBatch,
    own_normals: &[[f64; 4]],
    hinge: &HingeBatch,
    moments: &[[f64; 4]],
    forces: &mut [[f64; 9]],
    off: usize,
) {
    let mut pi = [ctx; 3];
    let mut partner_moment = [ctx; 3];
    for i in 0..3 {
        let mut moment = [0.0; W];
        for (w, m) in moment.iter_mut().enumerate() {
            let p = batch.partner_moment[i][off + w];
            if p != NONE {
                *m = moments[p as usize / 4][p as usize % 4];
            }
        }
        partner_moment[i] = ctx.load(moment);
        pi[i] = partner_moment[i] * ld(ctx, &hinge.inv_length2[i], off);
    }
    let gram = [
        ld(ctx, &hinge.gram[0], off),
        ld(ctx, &hinge.gram[1], off),
        ld(ctx, &hinge.gram[2], off),
    ];
    let inv_norm = ld(ctx, &own.inv_norm, off);
    // t_k = (1/|N|) (P'_k + Σ_{i≠k} π'_i e_i·e_k), using π'_k l_k² = P'_k.
    let t = [
        (partner_moment[0] + pi[1] * gram[0] + pi[2] * gram[2]) * inv_norm,
        (pi[0] * gram[0] + partner_moment[1] + pi[2] * gram[1]) * inv_norm,
        (pi[0] * gram[2] + pi[1] * gram[1] + partner_moment[2]) * inv_norm,
    ];
    let n = own_normal(ctx, own_normals, off);
    let stored: [[[f64; W]; 3]; 3] = [
        [
            (t[0] * n[0]).store(),
            (t[0] * n[1]).store(),
            (t[0] * n[2]).store(),
        ],
        [
            (t[1] * n[0]).store(),
            (t[1] * n[1]).store(),
            (t[1] * n[2]).store(),
        ],
        [
            (t[2] * n[0]).store(),
            (t[2] * n[1]).store(),
            (t[2] * n[2]).store(),
        ],
    ];
    scatter::<W, true>(forces, off, &stored);
}

/// Adds (`ADD`) or writes node-major lane forces `f[k][c][w]` to the
/// slots `off..off + W` that exist (the last batch may be partial).
#[inline(always)]
fn scatter<const W: usize, const ADD: bool>(
    forces: &mut [[f64; 9]],
    off: usize,
    f: &[[[f64; W]; 3]; 3],
) {
    let put = |slot: &mut [f64; 9], w: usize| {
        for k in 0..3 {
            for c in 0..3 {
                if ADD {
                    slot[3 * k + c] += f[k][c][w];
                } else {
                    slot[3 * k + c] = f[k][c][w];
                }
            }
        }
    };
    let start = off.min(forces.len());
    let slots = &mut forces[start..];
    if slots.len() >= W {
        // A whole batch (the common case) as a fixed-length loop.
        for (w, slot) in slots[..W].iter_mut().enumerate() {
            put(slot, w);
        }
    } else {
        for (w, slot) in slots.iter_mut().enumerate() {
            put(slot, w);
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    //! The phases entered through `pulp`'s x86-64-v3 token, four lanes in
    //! one AVX2 register (eight lanes in two registers spilled more to the
    //! stack and measured slower).
    use super::*;
    use crate::material::lanes::x86::F64x4;

    pub(super) struct Avx2Geometry<'a> {
        pub simd: pulp::x86::V3,
        pub batches: &'a [ElementBatch],
        pub u: &'a [f64],
        pub geometry: &'a mut [GeometryBatch],
        pub normals: &'a mut [[f64; 4]],
    }

    impl pulp::WithSimd for Avx2Geometry<'_> {
        type Output = ();
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) {
            let ctx = F64x4::new(self.simd, [0.0; LANES]);
            for ((batch, out), normals) in self
                .batches
                .iter()
                .zip(self.geometry.iter_mut())
                .zip(self.normals.chunks_exact_mut(LANES))
            {
                geometry_lanes::<F64x4, LANES>(ctx, batch, self.u, out, normals, 0);
            }
        }
    }

    pub(super) struct Avx2Moments<'a, const ADD: bool> {
        pub simd: pulp::x86::V3,
        pub constants: &'a PassConstants,
        pub batches: &'a [ElementBatch],
        pub own: &'a [GeometryBatch],
        pub own_normals: &'a [[f64; 4]],
        pub normals: &'a [[f64; 4]],
        pub ghosts: &'a [GhostState],
        pub hinges: &'a mut [HingeBatch],
        pub moments: &'a mut [[f64; 4]],
        pub forces: &'a mut [[f64; 9]],
    }

    impl<const ADD: bool> pulp::WithSimd for Avx2Moments<'_, ADD> {
        type Output = Option<usize>;
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) -> Option<usize> {
            let ctx = F64x4::new(self.simd, [0.0; LANES]);
            let mut first_failure = None;
            for (b, ((batch, (geo, hinge)), own_moments)) in self
                .batches
                .iter()
                .zip(self.own.iter().zip(self.hinges.iter_mut()))
                .zip(self.moments.chunks_exact_mut(LANES))
                .enumerate()
            {
                let end = ((b + 1) * LANES).min(self.forces.len());
                let slots = &mut self.forces[b * LANES..end];
                let failed = moment_lanes::<F64x4, LANES, ADD>(
                    ctx,
                    self.constants,
                    batch,
                    geo,
                    &self.own_normals[b * LANES..(b + 1) * LANES],
                    self.normals,
                    self.ghosts,
                    hinge,
                    own_moments,
                    slots,
                    0,
                );
                if failed != 0 && first_failure.is_none() {
                    first_failure = Some(b * LANES + failed.trailing_zeros() as usize);
                }
            }
            first_failure
        }
    }

    pub(super) struct Avx2HingeForces<'a> {
        pub simd: pulp::x86::V3,
        pub batches: &'a [ElementBatch],
        pub own: &'a [GeometryBatch],
        pub own_normals: &'a [[f64; 4]],
        pub own_hinges: &'a [HingeBatch],
        pub moments: &'a [[f64; 4]],
        pub forces: &'a mut [[f64; 9]],
    }

    impl pulp::WithSimd for Avx2HingeForces<'_> {
        type Output = ();
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) {
            let ctx = F64x4::new(self.simd, [0.0; LANES]);
            for (b, (batch, (geo, hinge))) in self
                .batches
                .iter()
                .zip(self.own.iter().zip(self.own_hinges))
                .enumerate()
            {
                let end = ((b + 1) * LANES).min(self.forces.len());
                let slots = &mut self.forces[b * LANES..end];
                hinge_force_lanes::<F64x4, LANES>(
                    ctx,
                    batch,
                    geo,
                    &self.own_normals[b * LANES..(b + 1) * LANES],
                    hinge,
                    self.moments,
                    slots,
                    0,
                );
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
use avx2::{Avx2Geometry, Avx2HingeForces, Avx2Moments};
