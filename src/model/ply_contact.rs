//! Contact with Coulomb friction between two deforming plies, for the
//! explicit path (`docs/contact.md`, "Ply–ply contact").
//!
//! Symmetric node-to-surface penalty: every node of each ply is checked
//! against the triangles of the other (two passes, so neither ply is a
//! master the other can pass through). The gap is measured between
//! mid-surfaces: `g = d − (t_A + t_B)/2`, with `d` the node's signed
//! distance from the other ply on the side it started from
//! ([`crate::contact::ply_pair::signed_distance`]). Per node the force is
//! that of the tool-contact penalty kernel
//! ([`crate::contact::kernel::PenaltyContact`]: normal spring, elastic–
//! plastic friction spring at `μ` times the normal force), in the node's
//! position relative to the material point of the other ply under it
//! (barycentric weights of the closest point); the reaction goes to the
//! three nodes of that triangle with the same weights, so momentum is
//! conserved. Candidate triangles come from Verlet lists rebuilt with a
//! refitted bounding-volume tree whenever a node has moved half the skin.
//!
//! The quasi-static path does not take this term: the case layer refuses
//! it there.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::contact::ExplicitPenalty;
use super::term::{
    FrequencyBound, Masses, State, Stencils, Term, TermEnergy, TermFailure, rounded_up,
};
use crate::contact::SurfaceNormal;
use crate::contact::kernel::{
    CompactionLaw, ContactStatus, NodalCompaction, PenaltyContact, PenaltyState, normal_dashpot,
};
use crate::contact::ply_pair::{
    CandidateLists, closest_candidate, side_of, signed_distance, triangle_boxes,
};
use crate::mesh::nodal_areas;

/// Nodes per task of the parallel node loops.
const NODE_CHUNK: usize = 256;

/// Distance beyond the contact offset within which a node is evaluated
/// \[mm\]; farther nodes are open (the penalty is open beyond the offset
/// anyway, so this only bounds the candidate search). Large against any
/// motion within one time increment (below 1e-3 mm in the benches).
const CULL_MARGIN: f64 = 0.25;

/// Round-off allowance of the closing rule \[mm\]: a pair closes when its
/// penetration is at most twice the node's relative motion in the
/// increment plus this (far above the round-off of millimetre
/// coordinates, far below any penetration).
const ENTRY_TOLERANCE: f64 = 1e-9;

/// One ply's side of a ply–ply contact: its nodes (model numbering), their
/// reference positions, its triangles (local node numbering) and its
/// thickness.
#[derive(Debug, Clone)]
pub struct PlySurface {
    /// Name of the ply, for messages.
    pub name: String,
    /// Model node of each local node.
    pub nodes: Vec<usize>,
    /// Reference position of each local node \[mm\].
    pub reference: Vec<Vector3<f64>>,
    /// Triangles, by local node.
    pub triangles: Vec<[usize; 3]>,
    /// Thickness \[mm\].
    pub thickness: f64,
}

/// Settings of one ply–ply contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlyContactOptions {
    /// Coulomb coefficient `μ ≥ 0`.
    pub friction: f64,
    /// Penalty of each node–surface spring, shared by the two passes (so
    /// each takes half): a fraction of the central-difference limit of
    /// the node and the lightest node of the other ply, or a stiffness per
    /// unit area of the node's own ply.
    pub explicit_stiffness: ExplicitPenalty,
    /// Normal damping as a fraction of each spring's critical damping.
    pub explicit_damping: f64,
    /// Skin of the Verlet candidate lists \[mm\].
    pub skin: f64,
    /// The layer between the plies (`docs/theory.md`, "Compaction of the
    /// fabric layer"): Toll's packing law over the contact offset, each
    /// pass carrying half of each node's area; `None`: the linear penalty.
    pub compaction: Option<CompactionLaw>,
}

/// The per-node figures a user sees (VTU fields) of a ply–ply contact.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PlyNodeContact {
    /// 0 open, 1 stick, 2 slip.
    pub status: u8,
    /// Normal force \[N\] of the node's own spring.
    pub normal_force: f64,
    /// Gap of the mid-surfaces at the node \[mm\] (∞ when far).
    pub gap: f64,
}

/// What one node found at the last increment.
#[derive(Debug, Clone, Copy)]
struct Hit {
    /// Triangle of the other ply (`u32::MAX`: none).
    triangle: u32,
    weights: [f64; 3],
    /// The residual `r = −f_c` on the node \[N\].
    residual: Vector3<f64>,
    /// `max(k_N, k_T)` of the node's spring while it acts \[N/mm\].
    stiffness: f64,
}

const NO_HIT: Hit = Hit {
    triangle: u32::MAX,
    weights: [0.0; 3],
    residual: Vector3::new(0.0, 0.0, 0.0),
    stiffness: 0.0,
};

/// The nodes of one ply against the triangles of the other.
struct Pass {
    lists: CandidateLists,
    states: Vec<PenaltyState>,
    /// Per node: the side (±1) of the other ply it started on; 0 until
    /// first seen.
    sides: Vec<f64>,
    springs: Vec<PenaltyContact>,
    dashpots: Vec<f64>,
    /// Per node: dashpot energy and its last force.
    damped: Vec<(f64, Vector3<f64>)>,
    hits: Vec<Hit>,
    outputs: Vec<PlyNodeContact>,
    /// Bounding boxes of the other ply's triangles at the current
    /// positions.
    boxes: Vec<[f64; 6]>,
}

/// Contact with friction between two plies (explicit path).
pub struct PlyContact {
    name: String,
    plies: [PlySurface; 2],
    options: PlyContactOptions,
    /// `(t_A + t_B)/2` \[mm\].
    offset: f64,
    passes: Vec<Pass>,
    /// Current, previous-increment and list-build positions per ply.
    positions: [Vec<Vector3<f64>>; 2],
    previous: [Vec<Vector3<f64>>; 2],
    anchors: [Vec<Vector3<f64>>; 2],
    /// Scatter buffer: ply 0's nodes, then ply 1's.
    node_forces: Vec<Vector3<f64>>,
    /// Tributary (reference) area of each node per ply \[mm²\].
    areas: [Vec<f64>; 2],
    /// An upper bound of how far any node has moved since the lists were
    /// built \[mm\] (the sum of the solver's [`State::motion`]); `+∞`
    /// when not known.
    travelled: f64,
}

/// Why [`PlyContact::new`] refuses its plies or settings. Every message
/// starts with the term's name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlyContactError {
    /// A ply without nodes or triangles.
    #[error("{term}: ply \"{ply}\" has no triangles")]
    NoTriangles {
        /// The term's name.
        term: String,
        /// The ply's name.
        ply: String,
    },
    /// A ply whose reference positions do not match its nodes.
    #[error("{term}: ply \"{ply}\": {positions} reference positions for {nodes} nodes")]
    ReferenceCount {
        /// The term's name.
        term: String,
        /// The ply's name.
        ply: String,
        /// Reference positions given.
        positions: usize,
        /// Nodes of the ply.
        nodes: usize,
    },
    /// A triangle with a node out of range.
    #[error("{term}: ply \"{ply}\": triangle {triangle:?} names a node beyond its {nodes} nodes")]
    NodeBeyond {
        /// The term's name.
        term: String,
        /// The ply's name.
        ply: String,
        /// The triangle (local node numbers).
        triangle: [usize; 3],
        /// Nodes of the ply.
        nodes: usize,
    },
    /// A thickness that is not positive.
    #[error("{term}: ply \"{ply}\": thickness {thickness} mm: expected a positive value")]
    Thickness {
        /// The term's name.
        term: String,
        /// The ply's name.
        ply: String,
        /// The thickness given \[mm\].
        thickness: f64,
    },
    /// A setting out of range.
    #[error("{term}: {key} = {value}: out of range")]
    Setting {
        /// The term's name.
        term: String,
        /// The setting (its case-file key).
        key: &'static str,
        /// The value given.
        value: f64,
    },
}

impl PlyContact {
    /// Contact between the plies `lower` and `upper` (any order; the names
    /// only label messages).
    ///
    /// # Errors
    /// A ply without nodes or triangles, a triangle with a node out of
    /// range, or a setting out of range.
    pub fn new(
        name: impl Into<String>,
        first: PlySurface,
        second: PlySurface,
        options: PlyContactOptions,
    ) -> Result<Self, PlyContactError> {
        let name = name.into();
        for ply in [&first, &second] {
            if ply.nodes.is_empty() || ply.triangles.is_empty() {
                return Err(PlyContactError::NoTriangles {
                    term: name.clone(),
                    ply: ply.name.clone(),
                });
            }
            if ply.reference.len() != ply.nodes.len() {
                return Err(PlyContactError::ReferenceCount {
                    term: name.clone(),
                    ply: ply.name.clone(),
                    positions: ply.reference.len(),
                    nodes: ply.nodes.len(),
                });
            }
            if let Some(t) = ply
                .triangles
                .iter()
                .find(|t| t.iter().any(|&n| n >= ply.nodes.len()))
            {
                return Err(PlyContactError::NodeBeyond {
                    term: name.clone(),
                    ply: ply.name.clone(),
                    triangle: *t,
                    nodes: ply.nodes.len(),
                });
            }
            if !(ply.thickness.is_finite() && ply.thickness > 0.0) {
                return Err(PlyContactError::Thickness {
                    term: name.clone(),
                    ply: ply.name.clone(),
                    thickness: ply.thickness,
                });
            }
        }
        let checks = [
            ("friction", options.friction, options.friction >= 0.0),
            match options.explicit_stiffness {
                ExplicitPenalty::StableFraction(c) => {
                    ("explicit_stiffness", c, c > 0.0 && c <= 1.0)
                }
                ExplicitPenalty::PerArea(k) => ("explicit_pressure_stiffness", k, k > 0.0),
            },
            (
                "explicit_damping",
                options.explicit_damping,
                options.explicit_damping >= 0.0,
            ),
            ("skin", options.skin, options.skin > 0.0),
        ];
        for (key, value, ok) in checks {
            if !(ok && value.is_finite()) {
                return Err(PlyContactError::Setting {
                    term: name,
                    key,
                    value,
                });
            }
        }
        let offset = 0.5 * (first.thickness + second.thickness);
        let positions = [first.reference.clone(), second.reference.clone()];
        let total = first.nodes.len() + second.nodes.len();
        let areas = [
            nodal_areas(&first.reference, &first.triangles),
            nodal_areas(&second.reference, &second.triangles),
        ];
        Ok(Self {
            name,
            areas,
            offset,
            passes: Vec::new(),
            previous: positions.clone(),
            anchors: positions.clone(),
            positions,
            node_forces: vec![Vector3::zeros(); total],
            travelled: f64::INFINITY,
            plies: [first, second],
            options,
        })
    }

    /// The contact offset `(t_A + t_B)/2` \[mm\]: the distance of the
    /// mid-surfaces at which the plies touch.
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// The per-node figures of ply `k` (0 or 1, in the order given to
    /// [`PlyContact::new`]) at the last increment; empty before the
    /// explicit set-up.
    pub fn node_contacts(&self, k: usize) -> &[PlyNodeContact] {
        self.passes.get(k).map_or(&[], |p| &p.outputs)
    }

    /// The model nodes of ply `k`.
    pub fn ply_nodes(&self, k: usize) -> &[usize] {
        &self.plies[k].nodes
    }

    /// The name of ply `k`.
    pub fn ply_name(&self, k: usize) -> &str {
        &self.plies[k].name
    }

    /// The tributary (reference) area of each node of ply `k` \[mm²\]:
    /// a node's contact pressure is its normal force over it.
    pub fn ply_areas(&self, k: usize) -> &[f64] {
        &self.areas[k]
    }

    /// Per node of ply `k`, in the order of [`PlyContact::ply_nodes`]: the
    /// slip accumulated on the other ply since the start \[mm\] (the
    /// friction spring's plastic slip, `docs/contact.md`) and the energy
    /// its friction dissipated \[N·mm\]; empty before the explicit set-up.
    pub fn node_friction(&self, k: usize) -> impl Iterator<Item = (f64, f64)> + '_ {
        self.passes
            .get(k)
            .into_iter()
            .flat_map(|p| p.states.iter().map(|s| (s.slip_length, s.dissipated)))
    }

    /// How many times the candidate lists were built (both passes).
    pub fn list_builds(&self) -> usize {
        self.passes.iter().map(|p| p.lists.builds()).sum()
    }

    /// The sum of the normal forces of ply `k`'s nodes on the other ply at
    /// the last increment \[N\].
    pub fn normal_force(&self, k: usize) -> f64 {
        self.node_contacts(k).iter().map(|c| c.normal_force).sum()
    }

    fn failure(&self, node: usize, reason: String) -> TermFailure {
        failure(&self.name, node, reason)
    }

    /// Current positions of both plies from `u`.
    fn update_positions(&mut self, u: &[f64]) {
        for (ply, positions) in self.plies.iter().zip(self.positions.iter_mut()) {
            positions
                .par_chunks_mut(NODE_CHUNK)
                .zip(ply.reference.par_chunks(NODE_CHUNK))
                .zip(ply.nodes.par_chunks(NODE_CHUNK))
                .for_each(|((positions, reference), nodes)| {
                    for ((x, x0), &n) in positions.iter_mut().zip(reference).zip(nodes) {
                        *x = x0 + Vector3::new(u[3 * n], u[3 * n + 1], u[3 * n + 2]);
                    }
                });
        }
    }

    /// Rebuilds both passes' candidate lists when a node has moved half
    /// the skin since the last build. Nodes are only looked at once
    /// `motion` (the solver's bound of any node's motion since the last
    /// call, [`State::motion`]), summed since the nodes were last looked at
    /// onto the largest motion found then, may exceed half the skin.
    fn refresh_lists(&mut self, motion: f64) {
        let half = 0.5 * self.options.skin;
        self.travelled += rounded_up(motion);
        if self.travelled < half {
            return;
        }
        let largest = self
            .positions
            .iter()
            .zip(&self.anchors)
            .flat_map(|(x, a)| x.iter().zip(a).map(|(x, a)| (x - a).norm_squared()))
            .fold(0.0, f64::max);
        if largest <= half * half {
            // No node has moved half the skin: the bound starts again from
            // the largest motion.
            self.travelled = rounded_up(largest.sqrt());
            return;
        }
        self.rebuild_lists();
    }

    /// Builds both passes' candidate lists at the current positions.
    fn rebuild_lists(&mut self) {
        for (k, pass) in self.passes.iter_mut().enumerate() {
            let other = 1 - k;
            pass.lists.rebuild(
                &self.positions[k],
                &self.positions[other],
                &self.plies[other].triangles,
            );
        }
        self.anchors.clone_from(&self.positions);
        self.travelled = 0.0;
    }
}

impl Term for PlyContact {
    fn name(&self) -> &str {
        &self.name
    }

    /// No quasi-static stencils: the term is explicit only.
    fn stencils(&self) -> Stencils {
        Stencils {
            count: 0,
            nodes: 1,
            extras: 0,
        }
    }

    fn stencil(&self, _s: usize, _nodes: &mut [usize], _extras: &mut [usize]) {}

    fn evaluate(
        &mut self,
        _state: &State,
        _force: &mut [f64],
        _tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        Err(TermFailure {
            term: self.name.clone(),
            what: "term",
            index: 0,
            reason: "ply–ply contact is on the explicit path only (solver = \"explicit\")".into(),
        })
    }

    /// One stencil per node: ply 0's nodes, then ply 1's.
    fn explicit_stencils(&self) -> Stencils {
        Stencils {
            count: self.plies[0].nodes.len() + self.plies[1].nodes.len(),
            nodes: 1,
            extras: 0,
        }
    }

    fn explicit_stencil(&self, s: usize, nodes: &mut [usize], _extras: &mut [usize]) {
        let n0 = self.plies[0].nodes.len();
        nodes[0] = if s < n0 {
            self.plies[0].nodes[s]
        } else {
            self.plies[1].nodes[s - n0]
        };
    }

    fn stiffness_from_time_step(&self) -> bool {
        true
    }

    /// Per node: `k_N = k_T = (c/2) · 4 / (Δt² (1/m + 1/m_other))` with `m`
    /// the node's mass and `m_other` the smallest nodal mass of the other
    /// ply (the two passes share the fraction `c`); the side each node
    /// starts on; the candidate lists.
    ///
    /// # Errors
    /// A node without mass, or a node closer to the other ply's
    /// mid-surface than half the contact offset (the plies overlap).
    fn explicit_setup(
        &mut self,
        state: &State,
        masses: &Masses,
        time_step: f64,
    ) -> Result<(), TermFailure> {
        self.update_positions(state.u);
        self.previous = self.positions.clone();
        let reach = self.offset + CULL_MARGIN;
        let mut passes = Vec::with_capacity(2);
        for k in 0..2 {
            let other = 1 - k;
            let lightest = self.plies[other]
                .nodes
                .iter()
                .map(|&n| masses.node[n])
                .filter(|m| *m > 0.0)
                .fold(f64::INFINITY, f64::min);
            let mut springs = Vec::with_capacity(self.plies[k].nodes.len());
            let mut dashpots = Vec::with_capacity(self.plies[k].nodes.len());
            for (i, &n) in self.plies[k].nodes.iter().enumerate() {
                let m = masses.node[n];
                if !(m > 0.0 && m.is_finite() && lightest.is_finite()) {
                    return Err(self.failure(
                        n,
                        format!("nodal mass {m} t: expected a positive mass (areal_mass)"),
                    ));
                }
                let effective = 1.0 / (1.0 / m + 1.0 / lightest);
                // The two passes share the penalty: each takes half.
                let k_n = 0.5
                    * self
                        .options
                        .explicit_stiffness
                        .stiffness(effective, self.areas[k][i], time_step)
                        .map_err(|e| self.failure(n, e.to_string()))?;
                let mut spring = PenaltyContact::new(k_n, k_n, self.options.friction, self.offset)
                    .map_err(|e| self.failure(n, e.to_string()))?;
                if let Some(law) = &self.options.compaction {
                    // Each pass carries half of the layer's pressure, as it
                    // takes half of the penalty.
                    let layer = NodalCompaction::new(law, 0.5 * self.areas[k][i], self.offset, k_n)
                        .map_err(|e| self.failure(n, e.to_string()))?;
                    spring = spring.with_compaction(layer);
                }
                dashpots.push(self.options.explicit_damping * 2.0 * (k_n * effective).sqrt());
                springs.push(spring);
            }
            let count = self.plies[k].nodes.len();
            passes.push(Pass {
                lists: CandidateLists::new(reach, self.options.skin),
                states: vec![PenaltyState::new(&Vector3::zeros()); count],
                sides: vec![0.0; count],
                springs,
                dashpots,
                damped: vec![(0.0, Vector3::zeros()); count],
                hits: vec![NO_HIT; count],
                boxes: vec![[0.0; 6]; self.plies[other].triangles.len()],
                outputs: vec![
                    PlyNodeContact {
                        gap: f64::INFINITY,
                        ..Default::default()
                    };
                    count
                ],
            });
        }
        self.passes = passes;
        self.rebuild_lists();
        // The side every node starts on; overlapping plies are an error.
        for k in 0..2 {
            let other = 1 - k;
            let (surface, triangles) = (&self.positions[other], &self.plies[other].triangles);
            let pass = &mut self.passes[k];
            triangle_boxes(surface, triangles, &mut pass.boxes);
            for (i, x) in self.positions[k].iter().enumerate() {
                let Some((_, point, normal)) =
                    closest_candidate(x, pass.lists.of(i), surface, triangles, &pass.boxes, None)
                else {
                    continue;
                };
                let distance = (x - point.point).norm();
                if distance < 0.5 * self.offset {
                    return Err(failure(
                        &self.name,
                        self.plies[k].nodes[i],
                        format!(
                            "ply \"{}\" starts {:.4} mm from the mid-surface of ply \"{}\", less than half the contact offset {} mm (the sum of the half thicknesses): the plies overlap; stack them {} mm apart",
                            self.plies[k].name,
                            distance,
                            self.plies[other].name,
                            self.offset,
                            self.offset
                        ),
                    ));
                }
                if let Some(side) = side_of(x, &point, &normal) {
                    pass.sides[i] = side;
                }
            }
        }
        Ok(())
    }

    /// Per node of each ply: its closest point on the other ply, the
    /// penalty kernel in the position relative to that material point, the
    /// normal dashpot; then the reactions scattered to the other ply's
    /// triangle nodes (in a fixed order: the results do not depend on the
    /// thread count).
    fn explicit_forces(&mut self, state: &State, out: &mut [f64]) -> Result<(), TermFailure> {
        if self.passes.is_empty() {
            out.fill(0.0);
            return Ok(());
        }
        self.update_positions(state.u);
        self.refresh_lists(state.motion);
        let dt = state.time_step;
        let offset = self.offset;
        let cull = self.offset + CULL_MARGIN;
        for k in 0..2 {
            let other = 1 - k;
            let (slaves, slaves_prev) = (&self.positions[k], &self.previous[k]);
            let (surface, surface_prev) = (&self.positions[other], &self.previous[other]);
            let triangles = &self.plies[other].triangles;
            let pass = &mut self.passes[k];
            pass.boxes
                .par_chunks_mut(NODE_CHUNK)
                .zip(triangles.par_chunks(NODE_CHUNK))
                .for_each(|(b, t)| triangle_boxes(surface, t, b));
            let lists = &pass.lists;
            let boxes = &pass.boxes;
            let (springs, dashpots) = (&pass.springs, &pass.dashpots);
            let failed = pass
                .hits
                .par_chunks_mut(NODE_CHUNK)
                .zip(pass.states.par_chunks_mut(NODE_CHUNK))
                .zip(pass.sides.par_chunks_mut(NODE_CHUNK))
                .zip(pass.damped.par_chunks_mut(NODE_CHUNK))
                .zip(pass.outputs.par_chunks_mut(NODE_CHUNK))
                .enumerate()
                .map(|(chunk, ((((hits, states), sides), damped), outputs))| {
                    for (j, ((((hit, s), side), damped), o)) in hits
                        .iter_mut()
                        .zip(states.iter_mut())
                        .zip(sides.iter_mut())
                        .zip(damped.iter_mut())
                        .zip(outputs.iter_mut())
                        .enumerate()
                    {
                        let i = chunk * NODE_CHUNK + j;
                        let x = &slaves[i];
                        let hint = (hit.triangle != u32::MAX).then_some(hit.triangle);
                        let found =
                            closest_candidate(x, lists.of(i), surface, triangles, boxes, hint);
                        let mut contact: Option<(usize, [f64; 3], SurfaceNormal)> = None;
                        if let Some((t, point, normal)) = found {
                            if *side == 0.0
                                && let Some(first) = side_of(x, &point, &normal)
                            {
                                *side = first;
                            }
                            if *side != 0.0
                                && let Some(p) = signed_distance(x, &point, &normal, *side)
                                && p.distance <= cull
                            {
                                contact = Some((t, point.weights, p));
                            }
                        }
                        let fresh = s.status == ContactStatus::Open && s.spring == Vector3::zeros();
                        let open = |hit: &mut Hit, o: &mut PlyNodeContact| {
                            *hit = NO_HIT;
                            o.status = 0;
                            o.normal_force = 0.0;
                            o.gap = f64::INFINITY;
                        };
                        if fresh && contact.is_none() {
                            open(hit, o);
                            continue;
                        }
                        // Position relative to the material point under the
                        // node, now and at the last increment (same weights:
                        // this contact's, or the last hit's while a spring is
                        // released).
                        let (weights, point) = match &contact {
                            Some((t, w, p)) => (Some((*t, *w)), Some(*p)),
                            None => (hit_weights(hit), None),
                        };
                        let (relative, relative_prev) = match weights {
                            Some((t, w)) => {
                                let tri = &triangles[t];
                                let under = |xs: &[Vector3<f64>]| {
                                    w[0] * xs[tri[0]] + w[1] * xs[tri[1]] + w[2] * xs[tri[2]]
                                };
                                (x - under(surface), slaves_prev[i] - under(surface_prev))
                            }
                            None => (*x, slaves_prev[i]),
                        };
                        let motion = relative - relative_prev;
                        // A pair closes only where the node reaches the
                        // other ply within this increment (its penetration
                        // at most twice its relative motion): a node found
                        // already deep (beside a free edge that turned to
                        // face it, or across a fold) would start with spring
                        // energy that no work put in.
                        if fresh
                            && let Some(p) = &point
                            && p.distance - offset < -(2.0 * motion.norm() + ENTRY_TOLERANCE)
                        {
                            open(hit, o);
                            continue;
                        }
                        s.previous_position = relative_prev;
                        let r = match springs[i].update_trusted(s, &relative, point.as_ref()) {
                            Ok(r) => r,
                            Err(_) => return Some(i),
                        };
                        let residual =
                            r.residual - normal_dashpot(dashpots[i], &r, &motion, dt, damped);
                        *hit = match weights {
                            Some((t, w)) if r.status != ContactStatus::Open => Hit {
                                triangle: t as u32,
                                weights: w,
                                residual,
                                stiffness: springs[i]
                                    .normal_stiffness()
                                    .max(springs[i].tangential_stiffness()),
                            },
                            Some((t, w)) => Hit {
                                triangle: t as u32,
                                weights: w,
                                ..NO_HIT
                            },
                            None => NO_HIT,
                        };
                        o.status = r.status.code();
                        o.normal_force = r.normal_force;
                        o.gap = r.gap;
                    }
                    None
                })
                .reduce(
                    || None,
                    |a, b| match (a, b) {
                        (Some(x), Some(y)) => Some(x.min(y)),
                        (x, None) => x,
                        (None, y) => y,
                    },
                );
            if let Some(i) = failed {
                let node = self.plies[k].nodes[i];
                return Err(self.failure(node, "the contact kernel rejected the state".into()));
            }
        }
        // Scatter in node order: each node's own residual, the reactions on
        // the triangle under it.
        let n0 = self.plies[0].nodes.len();
        self.node_forces.fill(Vector3::zeros());
        for k in 0..2 {
            let other = 1 - k;
            let (own, theirs) = if k == 0 { (0, n0) } else { (n0, 0) };
            for (i, hit) in self.passes[k].hits.iter().enumerate() {
                if hit.stiffness == 0.0 && hit.residual == Vector3::zeros() {
                    continue;
                }
                self.node_forces[own + i] += hit.residual;
                let tri = &self.plies[other].triangles[hit.triangle as usize];
                for (&n, w) in tri.iter().zip(hit.weights) {
                    self.node_forces[theirs + n] -= w * hit.residual;
                }
            }
        }
        for (f, o) in self.node_forces.iter().zip(out.chunks_exact_mut(3)) {
            o.copy_from_slice(f.as_slice());
        }
        // The current positions become the previous ones (the next pass
        // writes every current position before reading one).
        std::mem::swap(&mut self.previous, &mut self.positions);
        Ok(())
    }

    /// A Gershgorin bound of `λmax(M⁻¹ K)` over the acting springs: a
    /// spring of stiffness `k` between a node (mass `m_s`) and the point
    /// under it (weights `w`, masses `m_j`) is `k b bᵀ` with
    /// `b = (1, −w_1, −w_2, −w_3)`; with `ĉ = (1/√m_s, w_j/√m_j)` each
    /// node's row of `M^{-1/2} K M^{-1/2}` sums to at most
    /// `Σ_springs k ĉ_node Σ ĉ`.
    fn frequency_bound(
        &self,
        _state: &State,
        masses: &Masses,
    ) -> Result<FrequencyBound, TermFailure> {
        if self.passes.is_empty() {
            return Ok(FrequencyBound::default());
        }
        let n0 = self.plies[0].nodes.len();
        let mut rows = vec![0.0; self.node_forces.len()];
        for k in 0..2 {
            let other = 1 - k;
            let (own, theirs) = if k == 0 { (0, n0) } else { (n0, 0) };
            for (i, hit) in self.passes[k].hits.iter().enumerate() {
                if hit.stiffness == 0.0 {
                    continue;
                }
                let tri = &self.plies[other].triangles[hit.triangle as usize];
                let own_c = 1.0 / masses.node[self.plies[k].nodes[i]].sqrt();
                let c: [f64; 3] = std::array::from_fn(|j| {
                    hit.weights[j] / masses.node[self.plies[other].nodes[tri[j]]].sqrt()
                });
                let sum = own_c + c.iter().sum::<f64>();
                rows[own + i] += hit.stiffness * own_c * sum;
                for (&n, cj) in tri.iter().zip(c) {
                    rows[theirs + n] += hit.stiffness * cj * sum;
                }
            }
        }
        let max = rows.iter().fold(0.0_f64, |m, r| m.max(*r));
        if !max.is_finite() {
            return Err(self.failure(0, format!("frequency bound {max}")));
        }
        Ok(FrequencyBound::nodes(max))
    }

    fn energy(&mut self, _state: &State) -> Result<TermEnergy, TermFailure> {
        let mut energy = TermEnergy::default();
        for pass in &self.passes {
            for (s, (damped, _)) in pass.states.iter().zip(&pass.damped) {
                energy.contact += s.stored_energy();
                energy.dissipated += s.dissipated + damped;
            }
        }
        Ok(energy)
    }
}

/// A failure of the term `term` at model node `node`.
fn failure(term: &str, node: usize, reason: String) -> TermFailure {
    TermFailure {
        term: term.to_string(),
        what: "node",
        index: node,
        reason,
    }
}

/// The triangle and weights of a node's last hit, if any.
fn hit_weights(hit: &Hit) -> Option<(usize, [f64; 3])> {
    (hit.triangle != u32::MAX).then_some((hit.triangle as usize, hit.weights))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The messages read as they did when they were Strings.
    #[test]
    fn setup_errors_keep_their_wording() {
        let (term, ply) = (String::from("c"), String::from("lower"));
        let cases = [
            (
                PlyContactError::NoTriangles {
                    term: term.clone(),
                    ply: ply.clone(),
                },
                "c: ply \"lower\" has no triangles",
            ),
            (
                PlyContactError::ReferenceCount {
                    term: term.clone(),
                    ply: ply.clone(),
                    positions: 2,
                    nodes: 3,
                },
                "c: ply \"lower\": 2 reference positions for 3 nodes",
            ),
            (
                PlyContactError::NodeBeyond {
                    term: term.clone(),
                    ply: ply.clone(),
                    triangle: [0, 1, 7],
                    nodes: 3,
                },
                "c: ply \"lower\": triangle [0, 1, 7] names a node beyond its 3 nodes",
            ),
            (
                PlyContactError::Thickness {
                    term: term.clone(),
                    ply,
                    thickness: -0.5,
                },
                "c: ply \"lower\": thickness -0.5 mm: expected a positive value",
            ),
            (
                PlyContactError::Setting {
                    term,
                    key: "skin",
                    value: 0.0,
                },
                "c: skin = 0: out of range",
            ),
        ];
        for (error, text) in cases {
            assert_eq!(error.to_string(), text);
        }
    }
}
