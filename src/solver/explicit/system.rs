//! The explicit solver's view of a membrane model: fibre-basis triangles,
//! the node-to-element adjacency that makes the force gather race-free,
//! lumped masses (with optional mass scaling) and the per-dof constraints.
//! Built once; the passes here allocate nothing.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;
use serde::Serialize;

use super::super::assembly::{ElementFailure, ElementFailureKind};
use super::super::dofs::DofMap;
use super::super::model::MembraneModel;
use crate::element::FibreTriangle;
use crate::element::fibre_triangle::{FibreTriangles, LaneStress};
use crate::material::lanes::Real;
#[cfg(target_arch = "x86_64")]
use crate::material::lanes::x86::F64x8;
use crate::material::{Material, MaterialError, UdNcf};

/// Nodes per block of the node pass. Partial sums are taken per block and
/// added in block order, so sums do not depend on the thread count.
pub const NODE_BLOCK: usize = 256;
/// Smallest run of elements one rayon task takes.
const ELEMENT_MIN_LEN: usize = 512;
/// Triangles per batch of the force pass: the lanes of the law (two AVX2
/// registers).
const LANES: usize = 8;
/// Triangles per task of the batched force pass (a multiple of [`LANES`]).
const ELEMENT_CHUNK: usize = 256;

/// [`LANES`] triangles of the force pass, lane by lane, with their nodes.
/// The last batch repeats its last triangle in the lanes past the end.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
struct ElementBatch {
    triangles: FibreTriangles<LANES>,
    /// `nodes[a][l]`: node `a` of lane `l`.
    nodes: [[u32; LANES]; 3],
}

/// Mass figures of a run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MassSummary {
    /// Physical mass `Σ ρ t A0` [t].
    pub physical: f64,
    /// Mass added by mass scaling [t].
    pub added: f64,
    /// `added / physical`.
    pub added_fraction: f64,
    /// Elements whose density was raised.
    pub scaled_elements: usize,
}

/// Why a model cannot be integrated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SetupError {
    /// A node with a free dof carries no mass (no element touches it).
    #[error(
        "node {node} has a free dof but no mass: no triangle uses it (constrain it or remove it)"
    )]
    MasslessNode {
        /// Node index.
        node: usize,
    },
    /// An element fails at the initial state.
    #[error("initial state: {0}")]
    Element(ElementFailure),
}

/// Coefficients of one node-pass update (central difference, leapfrog form).
#[derive(Debug, Clone, Copy)]
pub struct Update {
    /// Velocity step `h = (Δt_{n−½} + Δt_{n+½}) / 2` [s].
    pub velocity_step: f64,
    /// Position step `Δt_{n+½}` [s].
    pub time_step: f64,
    /// Mass-proportional damping `α` [1/s].
    pub damping: f64,
    /// `λ(t_{n+1})` for the prescribed dofs.
    pub load_next: f64,
}

/// The model as the time loop sees it: built once by
/// [`ExplicitSystem::new`], then driven pass by pass (by
/// [`super::solve_explicit`], or by a benchmark).
pub struct ExplicitSystem<'a> {
    /// The membrane model.
    pub model: &'a MembraneModel,
    /// Its triangles in fibre-basis form.
    pub elements: Vec<FibreTriangle>,
    nodes_of: Vec<[u32; 3]>,
    /// The same triangles in batches of [`LANES`] for the force pass.
    batches: Vec<ElementBatch>,
    /// CSR: for node `n`, `entries[offsets[n]..offsets[n + 1]]` are
    /// `9 e + 3 a` for every triangle `e` using it as its node `a`.
    offsets: Vec<u32>,
    entries: Vec<u32>,
    /// Density of each element after mass scaling [t/mm³].
    pub element_density: Vec<f64>,
    /// Lumped mass of each node [t].
    pub node_mass: Vec<f64>,
    /// `1 / node_mass` (0 for a massless node, which has no free dof).
    inverse_mass: Vec<f64>,
    /// Per dof: the displacement per unit load, or NaN for a free dof.
    per_unit_load: Vec<f64>,
    /// Prescribed dofs with a non-zero `per_unit_load`.
    pub driven: Vec<(usize, f64)>,
    /// Mass figures.
    pub mass: MassSummary,
    /// Reject triangles that turn over in their plane.
    pub check_inversion: bool,
}

/// The UD-NCF law on lanes for the batched kernel.
impl<V: Real> LaneStress<V> for UdNcf {
    #[inline(always)]
    fn stress_lanes(&self, c: &[V; 3]) -> ([V; 3], V::Mask) {
        self.fibre_stress_lanes(c)
    }
}

/// [`ExplicitSystem::batch_forces`] on AVX2 lanes, as a `pulp` operation:
/// `with_simd` is inlined into pulp's function compiled for x86-64-v3, and
/// everything below it (all `#[inline(always)]`) with it.
#[cfg(target_arch = "x86_64")]
struct Avx2Batches<'s, 'a> {
    system: &'s ExplicitSystem<'a>,
    simd: pulp::x86::V3,
    law: &'s UdNcf,
    u: &'s [[f64; 3]],
    batches: &'s [ElementBatch],
    out: &'s mut [[f64; 9]],
}

#[cfg(target_arch = "x86_64")]
impl pulp::WithSimd for Avx2Batches<'_, '_> {
    type Output = Option<usize>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> Option<usize> {
        let context = F64x8::new(self.simd, [0.0; LANES]);
        self.system
            .batch_forces(context, self.law, self.u, self.batches, self.out)
    }
}

impl<'a> ExplicitSystem<'a> {
    /// Builds the system for density `density` [t/mm³] at the
    /// displacement `u`; with `mass_scaling = Some((target, safety))`,
    /// elements whose `safety × 2/ω_e` at the initial state is below
    /// `target` get `ρ_e (target / (safety × 2/ω_e))²`.
    ///
    /// # Errors
    /// A node with a free dof and no mass; an element that fails at `u`
    /// (with mass scaling).
    pub fn new(
        model: &'a MembraneModel,
        dofs: &DofMap,
        density: f64,
        mass_scaling: Option<(f64, f64)>,
        check_inversion: bool,
        u: &[f64],
    ) -> Result<Self, SetupError> {
        let elements: Vec<FibreTriangle> = model
            .references
            .iter()
            .map(|r| FibreTriangle::new(r, model.thickness))
            .collect();
        let nodes_of: Vec<[u32; 3]> = model
            .triangles
            .iter()
            .map(|t| t.map(|n| n as u32))
            .collect();
        let batches = (0..elements.len().div_ceil(LANES))
            .map(|b| {
                let element = |l: usize| (b * LANES + l).min(elements.len() - 1);
                ElementBatch {
                    triangles: FibreTriangles::from_fn(|l| elements[element(l)]),
                    nodes: std::array::from_fn(|a| {
                        std::array::from_fn(|l| nodes_of[element(l)][a])
                    }),
                }
            })
            .collect();
        let n_nodes = model.nodes.len();
        let mut counts = vec![0u32; n_nodes + 1];
        for t in &model.triangles {
            for &n in t {
                counts[n + 1] += 1;
            }
        }
        for n in 0..n_nodes {
            counts[n + 1] += counts[n];
        }
        let offsets = counts;
        let mut fill = offsets.clone();
        let mut entries = vec![0u32; *offsets.last().unwrap_or(&0) as usize];
        for (e, t) in model.triangles.iter().enumerate() {
            for (a, &n) in t.iter().enumerate() {
                entries[fill[n] as usize] = (9 * e + 3 * a) as u32;
                fill[n] += 1;
            }
        }
        let mut per_unit_load = vec![f64::NAN; dofs.total];
        let mut driven = Vec::new();
        for c in &dofs.constrained {
            per_unit_load[c.dof] = c.per_unit_load;
            if c.per_unit_load != 0.0 {
                driven.push((c.dof, c.per_unit_load));
            }
        }
        let mut system = Self {
            model,
            elements,
            nodes_of,
            batches,
            offsets,
            entries,
            element_density: vec![density; model.triangles.len()],
            node_mass: vec![0.0; n_nodes],
            inverse_mass: vec![0.0; n_nodes],
            per_unit_load,
            driven,
            mass: MassSummary {
                physical: 0.0,
                added: 0.0,
                added_fraction: 0.0,
                scaled_elements: 0,
            },
            check_inversion,
        };
        if let Some((target, safety)) = mass_scaling {
            system.scale_masses(u, target, safety)?;
        }
        system.lump_masses(density);
        for (node, &m) in system.node_mass.iter().enumerate() {
            let free = (0..3).any(|k| system.per_unit_load[3 * node + k].is_nan());
            if free && m <= 0.0 {
                return Err(SetupError::MasslessNode { node });
            }
        }
        Ok(system)
    }

    fn scale_masses(&mut self, u: &[f64], target: f64, safety: f64) -> Result<(), SetupError> {
        let omega2 = self.element_frequencies(u).map_err(SetupError::Element)?;
        for (rho, w2) in self.element_density.iter_mut().zip(omega2) {
            // ω² ∝ 1/ρ: scaling ρ by s² scales the stable step by s.
            let stable = safety * 2.0 / w2.sqrt();
            if w2 > 0.0 && stable < target {
                *rho *= (target / stable).powi(2);
                self.mass.scaled_elements += 1;
            }
        }
        Ok(())
    }

    fn lump_masses(&mut self, density: f64) {
        self.node_mass.fill(0.0);
        let mut physical = 0.0;
        let mut total = 0.0;
        for (e, el) in self.elements.iter().enumerate() {
            let m = self.element_density[e] * el.volume;
            physical += density * el.volume;
            total += m;
            for &n in &self.nodes_of[e] {
                self.node_mass[n as usize] += m / 3.0;
            }
        }
        for (inv, &m) in self.inverse_mass.iter_mut().zip(&self.node_mass) {
            *inv = if m > 0.0 { 1.0 / m } else { 0.0 };
        }
        self.mass.physical = physical;
        self.mass.added = total - physical;
        self.mass.added_fraction = if physical > 0.0 {
            self.mass.added / physical
        } else {
            0.0
        };
    }

    #[inline(always)]
    fn element_displacements(&self, e: usize, u: &[f64]) -> [[f64; 3]; 3] {
        self.nodes_of[e].map(|n| {
            let n = n as usize;
            [u[3 * n], u[3 * n + 1], u[3 * n + 2]]
        })
    }

    /// `Ok` when a pass found no failing element (`first == usize::MAX`),
    /// else the failure of element `first`, recomputed serially for its
    /// message. The one-triangle kernel repeats the batched arithmetic, so it
    /// fails too; the fallback kind only guards against a mismatch.
    fn failure_at(&self, first: usize, u: &[f64]) -> Result<(), ElementFailure> {
        match first {
            usize::MAX => Ok(()),
            element => Err(ElementFailure {
                element,
                kind: self
                    .element_failure(element, u)
                    .unwrap_or(ElementFailureKind::Material(
                        MaterialError::NonFiniteResponse,
                    )),
            }),
        }
    }

    /// The failure of element `e` at `u`, if any (serial, for messages).
    fn element_failure(&self, e: usize, u: &[f64]) -> Option<ElementFailureKind> {
        match self.elements[e]
            .internal_force(&self.element_displacements(e, u), &self.model.material)
        {
            Err(err) => Some(ElementFailureKind::Material(err)),
            Ok(f) if self.check_inversion && f.orientation <= 0.0 => {
                Some(ElementFailureKind::Inverted {
                    orientation: f.orientation,
                })
            }
            Ok(_) => None,
        }
    }

    /// Element pass: the internal force of every triangle at `u` into
    /// `forces`, in parallel (each task writes only its own triangles).
    /// With the UD-NCF law on a CPU with AVX2 (x86-64-v3), [`LANES`]
    /// triangles at a time, one per SIMD lane; elsewhere one at a time.
    /// Either way each triangle's force has the same bits, those of
    /// [`FibreTriangle::internal_force`], whatever the thread count.
    ///
    /// # Errors
    /// The lowest-index failing element (the forces are then unspecified).
    pub fn element_forces(&self, u: &[f64], forces: &mut [[f64; 9]]) -> Result<(), ElementFailure> {
        let first_failure = AtomicUsize::new(usize::MAX);
        let (nodes_u, _) = u.as_chunks::<3>();
        forces
            .par_chunks_mut(ELEMENT_CHUNK)
            .zip(self.batches.par_chunks(ELEMENT_CHUNK / LANES))
            .enumerate()
            .for_each(|(chunk, (out, batches))| {
                let first = chunk * ELEMENT_CHUNK;
                if let Some(e) = self.chunk_forces(nodes_u, batches, first, out) {
                    first_failure.fetch_min(e, Ordering::Relaxed);
                }
            });
        self.failure_at(first_failure.into_inner(), u)
    }

    /// The forces of the triangles `first..first + out.len()` (the
    /// triangles of `batches`) into `out`; the first failing triangle, if
    /// any.
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))]
    fn chunk_forces(
        &self,
        u: &[[f64; 3]],
        batches: &[ElementBatch],
        first: usize,
        out: &mut [[f64; 9]],
    ) -> Option<usize> {
        #[cfg(target_arch = "x86_64")]
        if let Material::UdNcf(law) = &self.model.material
            && let Some(simd) = pulp::x86::V3::try_new()
        {
            let pass = Avx2Batches {
                system: self,
                simd,
                law,
                u,
                batches,
                out,
            };
            return <pulp::x86::V3 as pulp::Simd>::vectorize(simd, pass)
                .map(|offset| first + offset);
        }
        self.forces_one_by_one(u, first, out)
    }

    /// [`ExplicitSystem::chunk_forces`] one triangle at a time (any law,
    /// any CPU).
    fn forces_one_by_one(
        &self,
        u: &[[f64; 3]],
        first: usize,
        out: &mut [[f64; 9]],
    ) -> Option<usize> {
        let material = &self.model.material;
        for (i, out) in out.iter_mut().enumerate() {
            let e = first + i;
            let ue = self.element_displacements(e, u.as_flattened());
            match self.elements[e].internal_force(&ue, material) {
                Ok(f) if !self.check_inversion || f.orientation > 0.0 => *out = f.force,
                _ => return Some(e),
            }
        }
        None
    }

    /// The forces of `batches` into `out` (their triangles, in order), one
    /// triangle per lane of `V`; the offset in `out` of the first failing
    /// triangle, if any. Inlined into the SIMD context of the caller.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    #[inline(always)]
    fn batch_forces<V: Real<Array = [f64; LANES]>>(
        &self,
        context: V,
        law: &UdNcf,
        u: &[[f64; 3]],
        batches: &[ElementBatch],
        out: &mut [[f64; 9]],
    ) -> Option<usize> {
        let zero = context.splat(0.0);
        for (b, (batch, out)) in batches.iter().zip(out.chunks_mut(LANES)).enumerate() {
            let mut ue = [[[0.0; LANES]; 3]; 3];
            for (ua, nodes) in ue.iter_mut().zip(&batch.nodes) {
                for (l, &n) in nodes.iter().enumerate() {
                    let un = &u[n as usize];
                    for k in 0..3 {
                        ua[k][l] = un[k];
                    }
                }
            }
            // Explicit loops, no `[T; N]::map`, which the inliner may leave
            // as a call outside the SIMD context.
            let mut lanes_u = [[context; 3]; 3];
            for (lanes, ua) in lanes_u.iter_mut().zip(&ue) {
                for k in 0..3 {
                    lanes[k] = context.load(ua[k]);
                }
            }
            let f = batch.triangles.internal_forces(context, &lanes_u, law);
            let mut force = [[0.0; LANES]; 9];
            for (fi, lanes) in force.iter_mut().zip(&f.force) {
                *fi = lanes.store();
            }
            for (l, o) in out.iter_mut().enumerate() {
                for (oi, fi) in o.iter_mut().zip(&force) {
                    *oi = fi[l];
                }
            }
            let mut accepted = f.admissible;
            if self.check_inversion {
                accepted = accepted & f.orientation.gt(zero);
            }
            let rejected = !V::bits(accepted) & ((1 << out.len()) - 1);
            if rejected != 0 {
                return Some(b * LANES + rejected.trailing_zeros() as usize);
            }
        }
        None
    }

    /// `Σ` of the element forces at node `node`, dof `k`, in adjacency order.
    #[inline(always)]
    fn gather(&self, forces: &[[f64; 9]], node: usize, out: &mut [f64; 3]) {
        let flat = forces.as_flattened();
        *out = [0.0; 3];
        let range = self.offsets[node] as usize..self.offsets[node + 1] as usize;
        for &entry in &self.entries[range] {
            let i = entry as usize;
            out[0] += flat[i];
            out[1] += flat[i + 1];
            out[2] += flat[i + 2];
        }
    }

    /// The generalised reaction `R = Σ_driven p_d f_d` [N per unit λ].
    pub fn reaction(&self, forces: &[[f64; 9]]) -> f64 {
        let mut reaction = 0.0;
        let mut f = [0.0; 3];
        for &(dof, p) in &self.driven {
            self.gather(forces, dof / 3, &mut f);
            reaction += p * f[dof % 3];
        }
        reaction
    }

    /// Gather pass without update, for outputs: the internal force per dof
    /// into `internal` and, per node block, the kinetic energy of the free
    /// dofs with the velocity `v_n = v_{n−½} + (Δt/2)(a_n − α v_{n−½})`
    /// into `kinetic_partial`, and the energy the damping takes over that
    /// half step, `α m ((v_{n−½} + v_n)/2)² Δt/2`, into `damping_partial`
    /// (so that the reported damping energy reaches `t_n` like the kinetic
    /// energy does).
    #[allow(clippy::too_many_arguments)]
    pub fn gather_with_kinetic(
        &self,
        forces: &[[f64; 9]],
        v_half: &[f64],
        half_step: f64,
        damping: f64,
        internal: &mut [f64],
        kinetic_partial: &mut [f64],
        damping_partial: &mut [f64],
    ) {
        internal
            .par_chunks_mut(3 * NODE_BLOCK)
            .zip(kinetic_partial.par_iter_mut())
            .zip(damping_partial.par_iter_mut())
            .enumerate()
            .for_each(|(block, ((f_block, kinetic_sum), damping_sum))| {
                let mut kinetic = 0.0;
                let mut dissipated = 0.0;
                let mut f = [0.0; 3];
                for (i, f_node) in f_block.chunks_exact_mut(3).enumerate() {
                    let node = block * NODE_BLOCK + i;
                    self.gather(forces, node, &mut f);
                    f_node.copy_from_slice(&f);
                    let m = self.node_mass[node];
                    for (k, fk) in f.iter().enumerate() {
                        let dof = 3 * node + k;
                        if self.per_unit_load[dof].is_nan() {
                            let v = v_half[dof];
                            let vn = v + half_step * (-fk / m - damping * v);
                            kinetic += 0.5 * m * vn * vn;
                            let v_mean = 0.5 * (v + vn);
                            dissipated += damping * m * v_mean * v_mean * half_step;
                        }
                    }
                }
                *kinetic_sum = kinetic;
                *damping_sum = dissipated;
            });
    }

    /// Node pass, fused: gathers `f_n`, then per free dof
    /// `v_{n+½} = ((1 − αh/2) v_{n−½} − h f/m) / (1 + αh/2)` and
    /// `u_{n+1} = u_n + Δt v_{n+½}`; prescribed dofs take
    /// `u = p λ(t_{n+1})` and `v = Δu/Δt`. Per node block, the energy the
    /// damping dissipates over the step goes into `partial`.
    pub fn update(
        &self,
        forces: &[[f64; 9]],
        u: &mut [f64],
        v: &mut [f64],
        partial: &mut [f64],
        step: Update,
    ) {
        let Update {
            velocity_step: h,
            time_step: dt,
            damping: alpha,
            load_next,
        } = step;
        let keep = 1.0 - 0.5 * alpha * h;
        let inv_scale = 1.0 / (1.0 + 0.5 * alpha * h);
        u.par_chunks_mut(3 * NODE_BLOCK)
            .zip(v.par_chunks_mut(3 * NODE_BLOCK))
            .zip(partial.par_iter_mut())
            .enumerate()
            .for_each(|(block, ((u_block, v_block), sum))| {
                let mut dissipated = 0.0;
                let mut f = [0.0; 3];
                let first = block * NODE_BLOCK;
                for (i, (u_node, v_node)) in u_block
                    .chunks_exact_mut(3)
                    .zip(v_block.chunks_exact_mut(3))
                    .enumerate()
                {
                    let node = first + i;
                    self.gather(forces, node, &mut f);
                    let m = self.node_mass[node];
                    let h_over_m = h * self.inverse_mass[node];
                    for k in 0..3 {
                        let p = self.per_unit_load[3 * node + k];
                        if p.is_nan() {
                            let v_old = v_node[k];
                            let v_new = (keep * v_old - h_over_m * f[k]) * inv_scale;
                            v_node[k] = v_new;
                            u_node[k] += dt * v_new;
                            let v_mean = 0.5 * (v_old + v_new);
                            dissipated += alpha * m * v_mean * v_mean * h;
                        } else {
                            let u_new = p * load_next;
                            v_node[k] = (u_new - u_node[k]) / dt;
                            u_node[k] = u_new;
                        }
                    }
                }
                *sum = dissipated;
            });
    }

    /// Per element, the bound of `ω²` of
    /// [`FibreTriangle::max_frequency_squared`] at `u` with the element's
    /// (scaled) density.
    ///
    /// # Errors
    /// The lowest-index failing element.
    pub fn element_frequencies(&self, u: &[f64]) -> Result<Vec<f64>, ElementFailure> {
        let frequencies: Vec<f64> = (0..self.elements.len())
            .into_par_iter()
            .with_min_len(ELEMENT_MIN_LEN)
            .map(|e| self.element_frequency(e, u).unwrap_or(f64::INFINITY))
            .collect();
        if frequencies.iter().all(|w2| w2.is_finite()) {
            Ok(frequencies)
        } else {
            Err(self.frequency_failure(u))
        }
    }

    /// `2 / max_e ω_e`: the estimated critical step at `u` [s] (a lower
    /// bound of the true one).
    ///
    /// # Errors
    /// The lowest-index failing element.
    pub fn critical_time_step(&self, u: &[f64]) -> Result<f64, ElementFailure> {
        // A failing element maps to +∞, which no state reaches otherwise.
        let max = (0..self.elements.len())
            .into_par_iter()
            .with_min_len(ELEMENT_MIN_LEN)
            .map(|e| self.element_frequency(e, u).unwrap_or(f64::INFINITY))
            .reduce(|| 0.0, f64::max);
        if !max.is_finite() {
            return Err(self.frequency_failure(u));
        }
        Ok(if max > 0.0 {
            2.0 / max.sqrt()
        } else {
            f64::INFINITY
        })
    }

    /// The bound of `ω²` of triangle `e` at `u` with its (scaled) density.
    fn element_frequency(&self, e: usize, u: &[f64]) -> Result<f64, MaterialError> {
        self.elements[e].max_frequency_squared(
            &self.element_displacements(e, u),
            &self.model.material,
            self.element_density[e],
        )
    }

    /// The lowest-index triangle whose frequency bound fails at `u`
    /// (serial; called only after a parallel pass found one).
    fn frequency_failure(&self, u: &[f64]) -> ElementFailure {
        let (element, err) = (0..self.elements.len())
            .find_map(|e| self.element_frequency(e, u).err().map(|err| (e, err)))
            .expect("an element failed");
        ElementFailure {
            element,
            kind: ElementFailureKind::Material(err),
        }
    }

    /// Strain energy of every element at `u` into `energies`.
    ///
    /// # Errors
    /// The lowest-index failing element.
    pub fn strain_energies(&self, u: &[f64], energies: &mut [f64]) -> Result<(), ElementFailure> {
        let first_failure = AtomicUsize::new(usize::MAX);
        let material = &self.model.material;
        energies
            .par_iter_mut()
            .with_min_len(ELEMENT_MIN_LEN)
            .enumerate()
            .for_each(|(e, out)| {
                match self.elements[e].strain_energy(&self.element_displacements(e, u), material) {
                    Ok(w) => *out = w,
                    Err(_) => {
                        first_failure.fetch_min(e, Ordering::Relaxed);
                    }
                }
            });
        self.failure_at(first_failure.into_inner(), u)
    }

    /// Number of node blocks.
    pub fn node_blocks(&self) -> usize {
        self.model.nodes.len().div_ceil(NODE_BLOCK)
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    use super::*;
    use crate::material::MaterialSpec;
    use crate::mesh::generate::{GridPattern, GridResolution, OatSpecimen, oat_specimen};

    /// A 15 × 30 mm strip of 13 × 25 cells (650 triangles: 82 batches, the
    /// last one padded), sheared and perturbed at random, so that triangles
    /// sit on different branches of the law side by side.
    fn strip(seed: u64) -> (MembraneModel, DofMap, Vec<f64>) {
        let mesh = oat_specimen(&OatSpecimen {
            width: 15.0,
            length: 30.0,
            bias_angle_deg: 30.0,
            resolution: GridResolution::Counts { nx: 13, ny: 25 },
            pattern: GridPattern::RovingDiagonal,
        })
        .expect("mesh")
        .mesh;
        assert_ne!(mesh.triangles.len() % LANES, 0, "a padded last batch");
        let material = MaterialSpec::named("schaefer2024").expect("set").material;
        let model = MembraneModel::new(
            mesh.nodes.clone(),
            mesh.triangles.clone(),
            &mesh.fibres,
            material,
            0.3,
        )
        .expect("model");
        let dofs = DofMap::new(mesh.nodes.len(), &[]);
        let mut rng = StdRng::seed_from_u64(seed);
        let u = mesh
            .nodes
            .iter()
            .flat_map(|x: &Vector3<f64>| {
                let shear = 0.3 * x.y;
                [
                    shear + rng.random_range(-0.3..0.3),
                    -0.05 * x.y + rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                ]
            })
            .collect();
        (model, dofs, u)
    }

    #[test]
    fn batched_pass_repeats_the_one_by_one_pass_bit_for_bit() {
        for seed in 0..4 {
            let (model, dofs, mut u) = strip(seed);
            let system = ExplicitSystem::new(&model, &dofs, 1e-9, None, true, &u).expect("system");
            let n = model.triangles.len();
            let (nodes_u, _) = u.as_chunks::<3>();
            let mut one_by_one = vec![[0.0; 9]; n];
            assert_eq!(system.forces_one_by_one(nodes_u, 0, &mut one_by_one), None);
            let mut batched = vec![[f64::NAN; 9]; n];
            system.element_forces(&u, &mut batched).expect("forces");
            for (e, (a, b)) in batched.iter().zip(&one_by_one).enumerate() {
                assert_eq!(a.map(f64::to_bits), b.map(f64::to_bits), "element {e}");
            }
            // Turn a triangle over: both passes name the same element.
            let e = 7 + 13 * seed as usize;
            let [n0, n1, n2] = model.triangles[e];
            for k in 0..3 {
                let x = |n: usize| model.nodes[n][k] + u[3 * n + k];
                let centre = (x(n0) + x(n1)) / 2.0;
                u[3 * n2 + k] = 2.0 * centre - x(n2) - model.nodes[n2][k];
            }
            let failure = system
                .element_forces(&u, &mut batched)
                .expect_err("inverted");
            let (nodes_u, _) = u.as_chunks::<3>();
            assert_eq!(
                system.forces_one_by_one(nodes_u, 0, &mut one_by_one),
                Some(failure.element)
            );
        }
    }
}
