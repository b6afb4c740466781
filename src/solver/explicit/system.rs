//! The explicit solver's view of a model: one force buffer with a region
//! per term (each term's explicit stencils, one value per stencil dof),
//! the node-to-entry adjacency that makes the force gather race-free,
//! lumped masses (with optional mass scaling) and the per-dof
//! constraints. Built once; the passes here allocate nothing.

use rayon::prelude::*;
use serde::Serialize;

use super::super::dofs::DofMap;
use super::chains::{MassChains, StretchEntry};
use super::setup_error::SetupError;
use crate::model::{FrequencyBound, Masses, Model, NO_SLOT, State, TermFailure, rounded_up};

/// Nodes per block of the node pass. Partial sums are taken per block and
/// added in block order, so sums do not depend on the thread count.
pub const NODE_BLOCK: usize = 256;

/// Mass figures of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MassSummary {
    /// Physical mass \[t\].
    pub physical: f64,
    /// Mass added by mass scaling \[t\].
    pub added: f64,
    /// `added / physical`.
    pub added_fraction: f64,
    /// Elements whose density was raised.
    pub scaled_elements: usize,
    /// Nodes on chains of coupling masses (roving mass scaling).
    pub coupled_nodes: usize,
    /// Chains of coupling masses.
    pub chains: usize,
    /// `Σ μ` of the coupling masses \[t\] (they add no translational mass).
    pub coupling_mass: f64,
    /// The coupling masses' form: `"stretch"` (on the stretch rate
    /// along each edge), `"full"` (on all components) or `"none"`.
    pub coupling_form: &'static str,
}

/// Coefficients of one node-pass update (central difference, leapfrog form).
#[derive(Debug, Clone, Copy)]
pub struct Update {
    /// Velocity step `h = (Δt_{n−½} + Δt_{n+½}) / 2` \[s\].
    pub velocity_step: f64,
    /// Position step `Δt_{n+½}` \[s\].
    pub time_step: f64,
    /// Mass-proportional damping `α` [1/s].
    pub damping: f64,
    /// `λ(t_{n+1})` for the prescribed dofs.
    pub load_next: f64,
}

/// [`Update`] with its per-pass factors, for one dof at a time.
struct Leapfrog {
    step: Update,
    /// `1 − αh/2`.
    keep: f64,
    /// `1 / (1 + αh/2)`.
    inv_scale: f64,
}

impl Leapfrog {
    fn new(step: Update) -> Self {
        let half = 0.5 * step.damping * step.velocity_step;
        Self {
            step,
            keep: 1.0 - half,
            inv_scale: 1.0 / (1.0 + half),
        }
    }

    /// One dof of the node pass: a free dof (`p` NaN) takes
    /// `v_{n+½} = ((1 − αh/2) v_{n−½} + increment) / (1 + αh/2)` (the
    /// increment `h a` of its acceleration) and `u += Δt v_{n+½}`, and
    /// returns the damping's energy `α m v̄² h`; a prescribed one takes
    /// `u = p λ(t_{n+1})`, `v = Δu/Δt` and returns 0.
    #[inline(always)]
    fn advance(&self, u: &mut f64, v: &mut f64, p: f64, increment: f64, m: f64) -> f64 {
        let Update {
            velocity_step: h,
            time_step: dt,
            damping: alpha,
            load_next,
        } = self.step;
        if p.is_nan() {
            let v_old = *v;
            let v_new = (self.keep * v_old + increment) * self.inv_scale;
            *v = v_new;
            *u += dt * v_new;
            let v_mean = 0.5 * (v_old + v_new);
            alpha * m * v_mean * v_mean * h
        } else {
            let u_new = p * load_next;
            *v = (u_new - *u) / dt;
            *u = u_new;
            0.0
        }
    }
}

/// The model as the time loop sees it: built once by
/// [`ExplicitSystem::new`], then driven pass by pass (by
/// [`super::solve_explicit`], or by a benchmark).
pub struct ExplicitSystem {
    nodes: usize,
    /// Per term: its region `[start, end)` of the force buffer.
    regions: Vec<(usize, usize)>,
    /// CSR: for node `n`, `node_entries[node_offsets[n]..node_offsets[n + 1]]`
    /// are the buffer positions of the x-values of every stencil slot on
    /// `n`, in term and stencil order.
    node_offsets: Vec<u32>,
    node_entries: Vec<u32>,
    /// The same for every extra dof (one value per slot).
    extra_offsets: Vec<u32>,
    extra_entries: Vec<u32>,
    /// Lumped masses \[t\].
    pub masses: Masses,
    /// `1 / mass` per node (0 for a massless node, which has no free dof).
    inverse_mass: Vec<f64>,
    /// Per dof: the displacement per unit load, or NaN for a free dof.
    per_unit_load: Vec<f64>,
    /// Prescribed dofs with a non-zero `per_unit_load`.
    pub driven: Vec<(usize, f64)>,
    /// Mass figures.
    pub mass: MassSummary,
    /// Per term: the group of connected nodes all its node slots lie in
    /// (the components of the terms whose stiffness is their own), `None`
    /// for a term without stiffness or node slots or one whose nodes span
    /// several groups; the number of groups.
    groups: Vec<Option<usize>>,
    group_count: usize,
    /// The coupling masses along chains (empty without roving mass
    /// scaling: then the node pass is the fused lumped one).
    chains: MassChains,
    /// With coupling masses: the accelerations of one pass (3 per node)
    /// and the chains' scratch.
    accelerations: std::sync::Mutex<CoupledBuffers>,
}

/// The coupled node pass's buffers.
#[derive(Debug, Default)]
struct CoupledBuffers {
    /// The accelerations of one pass (3 per node).
    accelerations: Vec<f64>,
    /// The chains' scratch ([`MassChains::scratch`]).
    chains: Vec<StretchEntry>,
}

/// Union–find root of `n` with path halving.
fn root(parent: &mut [usize], mut n: usize) -> usize {
    while parent[n] != n {
        parent[n] = parent[parent[n]];
        n = parent[n];
    }
    n
}

/// `2/√ω²` \[s\], `∞` for `ω² = 0`: the central-difference limit.
pub fn critical_step(frequency_squared: f64) -> f64 {
    if frequency_squared > 0.0 {
        2.0 / frequency_squared.sqrt()
    } else {
        f64::INFINITY
    }
}

impl ExplicitSystem {
    /// Builds the system for `model` at the state `state`; with
    /// `mass_scaling = Some((target, safety))` every term first raises its
    /// mass where its stable step is below `target`.
    ///
    /// # Errors
    /// A node or extra dof that is free and has no mass; a term that fails
    /// at the state (with mass scaling).
    pub fn new(
        model: &mut Model,
        dofs: &DofMap,
        mass_scaling: Option<(f64, f64)>,
        state: &State,
    ) -> Result<Self, SetupError> {
        let nodes = model.nodes;
        let extras = model.extras.len();
        let mut regions = Vec::with_capacity(model.terms.len());
        let mut node_slots: Vec<(usize, u32)> = Vec::new();
        let mut extra_slots: Vec<(usize, u32)> = Vec::new();
        let mut offset = 0usize;
        // Node groups: the connected components of the terms whose
        // stiffness is their own (membrane, bending); terms on disjoint node
        // sets are decoupled blocks.
        let mut parent: Vec<usize> = (0..nodes).collect();
        let mut term_node_slots = Vec::with_capacity(model.terms.len());
        for term in &model.terms {
            let first_slot = node_slots.len();
            let layout = term.explicit_stencils();
            let grouped = term.has_stiffness() && !term.stiffness_from_time_step();
            let mut first: Option<usize> = None;
            let size = layout.size();
            let mut slot_nodes = vec![NO_SLOT; layout.nodes];
            let mut slot_extras = vec![NO_SLOT; layout.extras];
            let start = offset;
            for s in 0..layout.count {
                slot_nodes.fill(NO_SLOT);
                slot_extras.fill(NO_SLOT);
                term.explicit_stencil(s, &mut slot_nodes, &mut slot_extras);
                for (a, &n) in slot_nodes.iter().enumerate() {
                    if n != NO_SLOT {
                        node_slots.push((n, (offset + 3 * a) as u32));
                        if grouped && n < nodes {
                            match first {
                                None => first = Some(n),
                                Some(f) => {
                                    let (a, b) = (root(&mut parent, f), root(&mut parent, n));
                                    if a != b {
                                        parent[a.max(b)] = a.min(b);
                                    }
                                }
                            }
                        }
                    }
                }
                for (a, &x) in slot_extras.iter().enumerate() {
                    if x != NO_SLOT {
                        extra_slots.push((x, (offset + 3 * layout.nodes + a) as u32));
                    }
                }
                offset += size;
            }
            regions.push((start, offset));
            term_node_slots.push(first_slot..node_slots.len());
        }
        // Every term with stiffness whose nodes all lie in one component
        // joins its group (a tool's contact with one ply: the ply's group);
        // a term spanning components (contact between two plies) does not.
        let mut group_of_root = vec![usize::MAX; nodes];
        let mut group_count = 0;
        let groups = model
            .terms
            .iter()
            .zip(&term_node_slots)
            .map(|(term, slots)| {
                if !term.has_stiffness() {
                    return None;
                }
                let mut term_nodes = node_slots[slots.clone()]
                    .iter()
                    .map(|&(n, _)| n)
                    .filter(|&n| n < nodes);
                let first = root(&mut parent, term_nodes.next()?);
                if term_nodes.any(|n| root(&mut parent, n) != first) {
                    return None;
                }
                if group_of_root[first] == usize::MAX {
                    group_of_root[first] = group_count;
                    group_count += 1;
                }
                Some(group_of_root[first])
            })
            .collect();
        let csr = |count: usize, slots: &[(usize, u32)]| {
            let mut offsets = vec![0u32; count + 1];
            for &(n, _) in slots {
                offsets[n + 1] += 1;
            }
            for n in 0..count {
                offsets[n + 1] += offsets[n];
            }
            let mut fill = offsets.clone();
            let mut entries = vec![0u32; slots.len()];
            // Slots are pushed in term and stencil order: a stable fill keeps it.
            for &(n, entry) in slots {
                entries[fill[n] as usize] = entry;
                fill[n] += 1;
            }
            (offsets, entries)
        };
        let (node_offsets, node_entries) = csr(nodes, &node_slots);
        let (extra_offsets, extra_entries) = csr(extras, &extra_slots);
        let mut per_unit_load = vec![f64::NAN; dofs.total];
        let mut driven = Vec::new();
        for c in &dofs.constrained {
            per_unit_load[c.dof] = c.per_unit_load;
            if c.per_unit_load != 0.0 {
                driven.push((c.dof, c.per_unit_load));
            }
        }
        let mut scaled_elements = 0;
        if let Some((target, safety)) = mass_scaling {
            for term in &mut model.terms {
                scaled_elements += term
                    .scale_masses(state, target, safety)
                    .map_err(SetupError::Term)?
                    .scaled_elements;
            }
        }
        let mut masses = Masses {
            node: vec![0.0; nodes],
            extra: vec![0.0; extras],
        };
        let mut physical = 0.0;
        for term in &model.terms {
            physical += term.lumped_masses(&mut masses);
        }
        let total: f64 = masses.node.iter().chain(&masses.extra).sum();
        let inverse_mass = masses
            .node
            .iter()
            .map(|&m| if m > 0.0 { 1.0 / m } else { 0.0 })
            .collect();
        for (node, &m) in masses.node.iter().enumerate() {
            let free = (0..3).any(|k| per_unit_load[3 * node + k].is_nan());
            if free && m <= 0.0 {
                return Err(SetupError::MasslessNode { node });
            }
        }
        for (k, &m) in masses.extra.iter().enumerate() {
            if per_unit_load[3 * nodes + k].is_nan() && m <= 0.0 {
                return Err(SetupError::MasslessExtra {
                    name: model.extras[k].name.clone(),
                });
            }
        }
        let mut couplings = Vec::new();
        for term in &model.terms {
            term.mass_couplings(&mut couplings);
        }
        let chains = MassChains::new(&masses.node, &couplings, |n| {
            std::array::from_fn(|k| per_unit_load[3 * n + k].is_nan())
        })?;
        let added = total - physical;
        Ok(Self {
            nodes,
            regions,
            node_offsets,
            node_entries,
            extra_offsets,
            extra_entries,
            masses,
            inverse_mass,
            per_unit_load,
            driven,
            mass: MassSummary {
                physical,
                added,
                added_fraction: if physical > 0.0 {
                    added / physical
                } else {
                    0.0
                },
                scaled_elements,
                coupled_nodes: chains.nodes(),
                chains: chains.count(),
                coupling_mass: chains.coupling_mass(),
                coupling_form: chains.form(),
            },
            groups,
            group_count,
            accelerations: std::sync::Mutex::new(if chains.is_empty() {
                CoupledBuffers::default()
            } else {
                CoupledBuffers {
                    accelerations: vec![0.0; 3 * nodes],
                    chains: chains.scratch(),
                }
            }),
            chains,
        })
    }

    /// Whether the mass matrix has coupling masses (roving mass scaling).
    pub fn has_mass_couplings(&self) -> bool {
        !self.chains.is_empty()
    }

    /// Length of the force buffer.
    pub fn force_len(&self) -> usize {
        self.regions.last().map_or(0, |r| r.1)
    }

    /// Force pass: every term's explicit stencil forces at `state` into its
    /// region of `forces` (each term runs its own parallel loop), adding
    /// each term's wall time \[s\] to its entry of `seconds` (one per
    /// term, in term order).
    ///
    /// # Errors
    /// The first term (in order) that fails, at its lowest-index stencil.
    pub fn element_forces(
        &self,
        model: &mut Model,
        state: &State,
        forces: &mut [f64],
        seconds: &mut [f64],
    ) -> Result<(), TermFailure> {
        for ((term, &(start, end)), spent) in model
            .terms
            .iter_mut()
            .zip(&self.regions)
            .zip(seconds.iter_mut())
        {
            let clock = std::time::Instant::now();
            let pass = term.explicit_forces(state, &mut forces[start..end]);
            *spent += clock.elapsed().as_secs_f64();
            pass?;
        }
        Ok(())
    }

    /// `2 / √ω²`: the estimated critical step at `state` \[s\] (a lower
    /// bound of the true one), with `ω²` a bound of `λmax(M⁻¹K)` from the
    /// terms' bounds ([`ExplicitSystem::combined_frequency`]). Terms whose
    /// stiffness follows from the step are left out when `with_penalties`
    /// is false.
    ///
    /// # Errors
    /// The first term that fails.
    pub fn critical_time_step_of(
        &self,
        model: &Model,
        state: &State,
        with_penalties: bool,
    ) -> Result<f64, TermFailure> {
        let bounds = self.term_bounds(model, state, with_penalties)?;
        Ok(critical_step(self.combined_frequency(&bounds)))
    }

    /// Each term's bound ([`FrequencyBound`]) at `state`, in term order;
    /// zero for the terms whose stiffness follows from the step when
    /// `with_penalties` is false.
    ///
    /// # Errors
    /// The first term that fails.
    pub fn term_bounds(
        &self,
        model: &Model,
        state: &State,
        with_penalties: bool,
    ) -> Result<Vec<FrequencyBound>, TermFailure> {
        let mut bounds = vec![FrequencyBound::default(); model.terms.len()];
        for (term, bound) in model.terms.iter().zip(&mut bounds) {
            if with_penalties || !term.stiffness_from_time_step() {
                *bound = term.frequency_bound(state, &self.masses)?;
            }
        }
        Ok(bounds)
    }

    /// `ω²` \[1/s²\] from the terms' bounds `bounds` (one per term, in term
    /// order; `docs/explicit.md`, "The stable time step"). On the node
    /// dofs, the terms within one group of connected nodes add up (Weyl),
    /// the groups are decoupled blocks of `K` and combine by the largest
    /// sum, and the terms spanning groups add on top:
    /// `n = max_g Σ_{t∈g} n_t + Σ_{t spanning} n_t`. The extra dofs' block
    /// is bounded by `b = Σ_t b_t` and the coupling block's norm by
    /// `c = Σ_t √(n_t b_t)` (triangle inequality), so
    /// `ω² ≤ λmax [[n, c], [c, b]] = (n + b)/2 + √(((n − b)/2)² + c²)`,
    /// or the plain sum `Σ_t (n_t + b_t)` where that is lower.
    pub fn combined_frequency(&self, bounds: &[FrequencyBound]) -> f64 {
        let mut spanning = 0.0;
        let mut extras = 0.0;
        let mut coupling = 0.0;
        let mut groups = vec![0.0; self.group_count];
        for (group, bound) in self.groups.iter().zip(bounds) {
            match group {
                Some(g) => groups[*g] += bound.nodes,
                None => spanning += bound.nodes,
            }
            extras += bound.extras;
            coupling += (bound.nodes * bound.extras).sqrt();
        }
        let nodes = spanning + groups.iter().fold(0.0_f64, |m, g| m.max(*g));
        if extras == 0.0 {
            return nodes;
        }
        let half_gap = 0.5 * (nodes - extras);
        let blocks = 0.5 * (nodes + extras) + (half_gap * half_gap + coupling * coupling).sqrt();
        // Weyl's plain sum is a bound too; with extras it can be the lower.
        blocks.min(bounds.iter().fold(0.0, |s, b| s + b.total()))
    }

    /// [`ExplicitSystem::critical_time_step_of`] with every term.
    ///
    /// # Errors
    /// The first term that fails.
    pub fn critical_time_step(&self, model: &Model, state: &State) -> Result<f64, TermFailure> {
        self.critical_time_step_of(model, state, true)
    }

    /// `Σ` of the buffer entries at node `node`, in adjacency order.
    #[inline(always)]
    fn gather(&self, forces: &[f64], node: usize, out: &mut [f64; 3]) {
        *out = [0.0; 3];
        let range = self.node_offsets[node] as usize..self.node_offsets[node + 1] as usize;
        for &entry in &self.node_entries[range] {
            let i = entry as usize;
            out[0] += forces[i];
            out[1] += forces[i + 1];
            out[2] += forces[i + 2];
        }
    }

    /// `Σ` of the buffer entries at extra dof `k`, in adjacency order.
    fn gather_extra(&self, forces: &[f64], k: usize) -> f64 {
        let range = self.extra_offsets[k] as usize..self.extra_offsets[k + 1] as usize;
        self.extra_entries[range]
            .iter()
            .map(|&i| forces[i as usize])
            .fold(0.0, |s, f| s + f)
    }

    /// The residual `f_int − f_ext` of dof `dof` \[N\].
    pub fn dof_force(&self, forces: &[f64], dof: usize) -> f64 {
        if dof < 3 * self.nodes {
            let mut f = [0.0; 3];
            self.gather(forces, dof / 3, &mut f);
            f[dof % 3]
        } else {
            self.gather_extra(forces, dof - 3 * self.nodes)
        }
    }

    /// The generalised reaction `R = Σ_driven p_d f_d` [N per unit λ].
    pub fn reaction(&self, forces: &[f64]) -> f64 {
        self.driven
            .iter()
            .map(|&(dof, p)| p * self.dof_force(forces, dof))
            .fold(0.0, |s, r| s + r)
    }

    /// Gather pass without update, for outputs, at the displacements `u`
    /// (which set the stretch-form coupling masses' directions): the
    /// residual per dof into `internal` and, per node block, the kinetic
    /// energy of the free dofs
    /// with the velocity `v_n = v_{n−½} + (Δt/2)(a_n − α v_{n−½})` into
    /// `kinetic_partial`, and the energy the damping takes over that half
    /// step, `α m ((v_{n−½} + v_n)/2)² Δt/2`, into `damping_partial` (so
    /// that the reported damping energy reaches `t_n` like the kinetic
    /// energy does). The extra dofs come last, in one more partial entry.
    /// The kinetic energy of the nodes' prescribed dofs (clamps), with their
    /// velocity `v_{n−½} = Δu/Δt`, goes per node block into `driven_partial`.
    #[allow(clippy::too_many_arguments)]
    pub fn gather_with_kinetic(
        &self,
        forces: &[f64],
        u: &[f64],
        v_half: &[f64],
        half_step: f64,
        damping: f64,
        internal: &mut [f64],
        kinetic_partial: &mut [f64],
        damping_partial: &mut [f64],
        driven_partial: &mut [f64],
    ) {
        if !self.chains.is_empty() {
            self.gather_with_kinetic_coupled(
                forces,
                u,
                v_half,
                half_step,
                internal,
                kinetic_partial,
                damping_partial,
                driven_partial,
            );
            self.extras_kinetic(
                forces,
                v_half,
                half_step,
                damping,
                &mut internal[3 * self.nodes..],
                kinetic_partial,
                damping_partial,
            );
            return;
        }
        let (node_internal, extra_internal) = internal.split_at_mut(3 * self.nodes);
        let blocks = self.node_blocks();
        node_internal
            .par_chunks_mut(3 * NODE_BLOCK)
            .zip(kinetic_partial[..blocks].par_iter_mut())
            .zip(damping_partial[..blocks].par_iter_mut())
            .zip(driven_partial.par_iter_mut())
            .enumerate()
            .for_each(
                |(block, (((f_block, kinetic_sum), damping_sum), driven_sum))| {
                    let mut kinetic = 0.0;
                    let mut dissipated = 0.0;
                    let mut driven = 0.0;
                    let mut f = [0.0; 3];
                    for (i, f_node) in f_block.chunks_exact_mut(3).enumerate() {
                        let node = block * NODE_BLOCK + i;
                        self.gather(forces, node, &mut f);
                        f_node.copy_from_slice(&f);
                        let m = self.masses.node[node];
                        for (k, fk) in f.iter().enumerate() {
                            let dof = 3 * node + k;
                            if self.per_unit_load[dof].is_nan() {
                                let v = v_half[dof];
                                let vn = v + half_step * (-fk / m - damping * v);
                                kinetic += 0.5 * m * vn * vn;
                                let v_mean = 0.5 * (v + vn);
                                dissipated += damping * m * v_mean * v_mean * half_step;
                            } else {
                                let v = v_half[dof];
                                driven += 0.5 * m * v * v;
                            }
                        }
                    }
                    *kinetic_sum = kinetic;
                    *damping_sum = dissipated;
                    *driven_sum = driven;
                },
            );
        self.extras_kinetic(
            forces,
            v_half,
            half_step,
            damping,
            extra_internal,
            kinetic_partial,
            damping_partial,
        );
    }

    /// The extra dofs' part of [`ExplicitSystem::gather_with_kinetic`], in
    /// the last partial entries.
    #[allow(clippy::too_many_arguments)]
    fn extras_kinetic(
        &self,
        forces: &[f64],
        v_half: &[f64],
        half_step: f64,
        damping: f64,
        extra_internal: &mut [f64],
        kinetic_partial: &mut [f64],
        damping_partial: &mut [f64],
    ) {
        let blocks = self.node_blocks();
        let mut kinetic = 0.0;
        let mut dissipated = 0.0;
        for (k, f_extra) in extra_internal.iter_mut().enumerate() {
            let f = self.gather_extra(forces, k);
            *f_extra = f;
            let dof = 3 * self.nodes + k;
            if self.per_unit_load[dof].is_nan() {
                let m = self.masses.extra[k];
                let v = v_half[dof];
                let vn = v + half_step * (-f / m - damping * v);
                kinetic += 0.5 * m * vn * vn;
                let v_mean = 0.5 * (v + vn);
                dissipated += damping * m * v_mean * v_mean * half_step;
            }
        }
        kinetic_partial[blocks] = kinetic;
        damping_partial[blocks] = dissipated;
    }

    /// Pass A of the coupled node pass: per free dof `−f` on the chains'
    /// nodes and `−f/m` elsewhere into `accelerations` (prescribed dofs get
    /// 0), the residual into `internal` if given. The chains' solve follows
    /// (by the caller), so that `accelerations = M⁻¹(−f)` on every free dof.
    fn coupled_accelerations(
        &self,
        forces: &[f64],
        buffers: &mut CoupledBuffers,
        internal: Option<&mut [f64]>,
    ) {
        let accelerations = buffers.accelerations.as_mut_slice();
        let body = |block: usize, a_block: &mut [f64], f_out: Option<&mut [f64]>| {
            let mut f = [0.0; 3];
            let mut f_out = f_out;
            for (i, a_node) in a_block.chunks_exact_mut(3).enumerate() {
                let node = block * NODE_BLOCK + i;
                self.gather(forces, node, &mut f);
                if let Some(out) = f_out.as_deref_mut() {
                    out[3 * i..3 * i + 3].copy_from_slice(&f);
                }
                let scale = if self.chains.takes_force(node) {
                    1.0
                } else {
                    self.inverse_mass[node]
                };
                for k in 0..3 {
                    a_node[k] = if self.per_unit_load[3 * node + k].is_nan() {
                        -f[k] * scale
                    } else {
                        0.0
                    };
                }
            }
        };
        match internal {
            Some(internal) => accelerations
                .par_chunks_mut(3 * NODE_BLOCK)
                .zip(internal[..3 * self.nodes].par_chunks_mut(3 * NODE_BLOCK))
                .enumerate()
                .for_each(|(block, (a, f))| body(block, a, Some(f))),
            None => accelerations
                .par_chunks_mut(3 * NODE_BLOCK)
                .enumerate()
                .for_each(|(block, a)| body(block, a, None)),
        }
    }

    /// [`ExplicitSystem::gather_with_kinetic`] with coupling masses (no
    /// damping: the case refuses it with them): `v_n = v_{n−½} + (Δt/2)
    /// M⁻¹(−f)` and `½ v_nᵀ M v_n` with the couplings' part, which goes
    /// into the first block's entry.
    #[allow(clippy::too_many_arguments)]
    fn gather_with_kinetic_coupled(
        &self,
        forces: &[f64],
        u: &[f64],
        v_half: &[f64],
        half_step: f64,
        internal: &mut [f64],
        kinetic_partial: &mut [f64],
        damping_partial: &mut [f64],
        driven_partial: &mut [f64],
    ) {
        let mut guard = self
            .accelerations
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let buffers = &mut *guard;
        self.coupled_accelerations(forces, buffers, Some(internal));
        self.chains
            .solve(&mut buffers.accelerations, u, buffers.chains.as_mut_slice());
        let velocities = buffers.accelerations.as_mut_slice();
        let blocks = self.node_blocks();
        velocities
            .par_chunks_mut(3 * NODE_BLOCK)
            .zip(kinetic_partial[..blocks].par_iter_mut())
            .zip(driven_partial.par_iter_mut())
            .enumerate()
            .for_each(|(block, ((a_block, kinetic_sum), driven_sum))| {
                let mut kinetic = 0.0;
                let mut driven = 0.0;
                for (i, a_node) in a_block.chunks_exact_mut(3).enumerate() {
                    let node = block * NODE_BLOCK + i;
                    let m = self.masses.node[node];
                    for (k, a) in a_node.iter_mut().enumerate() {
                        let dof = 3 * node + k;
                        let v = v_half[dof];
                        if self.per_unit_load[dof].is_nan() {
                            let vn = v + half_step * *a;
                            kinetic += 0.5 * m * vn * vn;
                            *a = vn;
                        } else {
                            driven += 0.5 * m * v * v;
                            *a = v;
                        }
                    }
                }
                *kinetic_sum = kinetic;
                *driven_sum = driven;
            });
        kinetic_partial[0] += self
            .chains
            .coupling_kinetic_energy(velocities, &buffers.chains);
        damping_partial[..blocks].fill(0.0);
    }

    /// Node pass, fused: gathers `f_n`, then per free dof
    /// `v_{n+½} = ((1 − αh/2) v_{n−½} − h f/m) / (1 + αh/2)` and
    /// `u_{n+1} = u_n + Δt v_{n+½}`; prescribed dofs take
    /// `u = p λ(t_{n+1})` and `v = Δu/Δt`. Per node block (and for the
    /// extra dofs, in the last entry), the energy the damping dissipates
    /// over the step goes into `partial`.
    ///
    /// Returns a bound of the largest distance a node moved \[mm\] (the
    /// extra dofs left out; per node block, the largest change of one
    /// component goes through `motion_partial`, one entry per node block):
    /// the bound [`State::motion`] of the next force pass.
    pub fn update(
        &self,
        forces: &[f64],
        u: &mut [f64],
        v: &mut [f64],
        partial: &mut [f64],
        motion_partial: &mut [f64],
        step: Update,
    ) -> f64 {
        if !self.chains.is_empty() {
            self.update_coupled(forces, u, v, partial, motion_partial, step);
            return largest_motion(motion_partial);
        }
        let leapfrog = Leapfrog::new(step);
        let h = step.velocity_step;
        let (u_nodes, u_extra) = u.split_at_mut(3 * self.nodes);
        let (v_nodes, v_extra) = v.split_at_mut(3 * self.nodes);
        let blocks = self.node_blocks();
        let (partial_nodes, partial_extra) = partial.split_at_mut(blocks);
        u_nodes
            .par_chunks_mut(3 * NODE_BLOCK)
            .zip(v_nodes.par_chunks_mut(3 * NODE_BLOCK))
            .zip(partial_nodes.par_iter_mut())
            .zip(motion_partial[..blocks].par_iter_mut())
            .enumerate()
            .for_each(|(block, (((u_block, v_block), sum), motion))| {
                let mut dissipated = 0.0;
                let mut largest = 0.0_f64;
                let mut f = [0.0; 3];
                let first = block * NODE_BLOCK;
                for (i, (u_node, v_node)) in u_block
                    .chunks_exact_mut(3)
                    .zip(v_block.chunks_exact_mut(3))
                    .enumerate()
                {
                    let node = first + i;
                    self.gather(forces, node, &mut f);
                    let m = self.masses.node[node];
                    let h_over_m = h * self.inverse_mass[node];
                    for k in 0..3 {
                        let before = u_node[k];
                        dissipated += leapfrog.advance(
                            &mut u_node[k],
                            &mut v_node[k],
                            self.per_unit_load[3 * node + k],
                            -(h_over_m * f[k]),
                            m,
                        );
                        largest = at_least(largest, (u_node[k] - before).abs());
                    }
                }
                *sum = dissipated;
                *motion = largest;
            });
        partial_extra[0] = self.update_extras(forces, u_extra, v_extra, step);
        largest_motion(&motion_partial[..blocks])
    }

    /// The node pass with coupling masses: pass A and the chains' solve
    /// ([`ExplicitSystem::coupled_accelerations`]; the stretch form's
    /// per-node correction fused into the update's pass), then per free dof
    /// `v_{n+½} = ((1 − αh/2) v_{n−½} + h a) / (1 + αh/2)` (α = 0 with
    /// couplings: the case refuses damping with them), the prescribed dofs
    /// and the extra dofs as in [`ExplicitSystem::update`].
    fn update_coupled(
        &self,
        forces: &[f64],
        u: &mut [f64],
        v: &mut [f64],
        partial: &mut [f64],
        motion_partial: &mut [f64],
        step: Update,
    ) {
        let leapfrog = Leapfrog::new(step);
        let h = step.velocity_step;
        let damping = step.damping != 0.0;
        let mut guard = self
            .accelerations
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let buffers = &mut *guard;
        self.coupled_accelerations(forces, buffers, None);
        // The chains' correction, if any, is done node by node below.
        let correct = self.chains.solve_without_correction(
            &mut buffers.accelerations,
            u,
            buffers.chains.as_mut_slice(),
        );
        let scratch = buffers.chains.as_slice();
        let accelerations = buffers.accelerations.as_slice();
        let (u_nodes, u_extra) = u.split_at_mut(3 * self.nodes);
        let (v_nodes, v_extra) = v.split_at_mut(3 * self.nodes);
        let blocks = self.node_blocks();
        let (partial_nodes, partial_extra) = partial.split_at_mut(blocks);
        u_nodes
            .par_chunks_mut(3 * NODE_BLOCK)
            .zip(v_nodes.par_chunks_mut(3 * NODE_BLOCK))
            .zip(accelerations.par_chunks(3 * NODE_BLOCK))
            .zip(partial_nodes.par_iter_mut())
            .zip(motion_partial[..blocks].par_iter_mut())
            .enumerate()
            .for_each(|(block, ((((u_block, v_block), a_block), sum), motion))| {
                let mut dissipated = 0.0;
                let mut largest = 0.0_f64;
                let first = block * NODE_BLOCK;
                for (i, ((u_node, v_node), a_node)) in u_block
                    .chunks_exact_mut(3)
                    .zip(v_block.chunks_exact_mut(3))
                    .zip(a_block.chunks_exact(3))
                    .enumerate()
                {
                    let node = first + i;
                    let m = self.masses.node[node];
                    let mut a = [a_node[0], a_node[1], a_node[2]];
                    if correct {
                        self.chains.correct(node, &mut a, scratch);
                    }
                    for k in 0..3 {
                        let before = u_node[k];
                        let damped = leapfrog.advance(
                            &mut u_node[k],
                            &mut v_node[k],
                            self.per_unit_load[3 * node + k],
                            h * a[k],
                            m,
                        );
                        // Without damping (always, with couplings: the case
                        // refuses both) the damping's energy is not formed.
                        if damping {
                            dissipated += damped;
                        }
                        largest = at_least(largest, (u_node[k] - before).abs());
                    }
                }
                *sum = dissipated;
                *motion = largest;
            });
        partial_extra[0] = self.update_extras(forces, u_extra, v_extra, step);
    }

    /// The extra dofs' update of the node pass; returns the energy the
    /// damping took from them.
    fn update_extras(
        &self,
        forces: &[f64],
        u_extra: &mut [f64],
        v_extra: &mut [f64],
        step: Update,
    ) -> f64 {
        let leapfrog = Leapfrog::new(step);
        let h = step.velocity_step;
        let mut dissipated = 0.0;
        for (k, (uk, vk)) in u_extra.iter_mut().zip(v_extra.iter_mut()).enumerate() {
            let f = self.gather_extra(forces, k);
            let m = self.masses.extra[k];
            dissipated += leapfrog.advance(
                uk,
                vk,
                self.per_unit_load[3 * self.nodes + k],
                -(h / m * f),
                m,
            );
        }
        dissipated
    }

    /// Number of node blocks.
    pub fn node_blocks(&self) -> usize {
        self.nodes.div_ceil(NODE_BLOCK)
    }

    /// Length of the per-block partial sums: the node blocks and one entry
    /// for the extra dofs.
    pub fn partials(&self) -> usize {
        self.node_blocks() + 1
    }
}

/// `max(m, s)`, NaN if `s` is NaN (where `f64::max` would drop it).
#[inline(always)]
fn at_least(m: f64, s: f64) -> f64 {
    if s <= m { m } else { s }
}

/// The largest node motion \[mm\] from the per-block largest changes of
/// one displacement component: `√3` times the largest (a node's motion is
/// at most that), rounded up ([`rounded_up`]); `+∞` if not finite.
fn largest_motion(components: &[f64]) -> f64 {
    let largest = components.iter().fold(0.0_f64, |m, s| at_least(m, *s));
    let motion = largest * 3.0_f64.sqrt();
    if motion.is_finite() {
        rounded_up(motion)
    } else {
        f64::INFINITY
    }
}
