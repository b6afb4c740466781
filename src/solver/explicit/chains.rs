//! The mass matrix with coupling masses along chains of nodes (roving mass
//! scaling, `docs/explicit.md`), of which the solver uses the block of the
//! free dofs (as for the lumped mass, a prescribed dof passes no inertia
//! to the free ones). Every node has at most two coupled neighbours and the
//! couplings form no loop: chains, the roving lines. Two forms:
//!
//! - **full**: `M = diag(m) + Σ μ_ab (e_a − e_b)(e_a − e_b)ᵀ ⊗ I3`. The
//!   free block is tridiagonal along each chain and component, and
//!   `M a = r` is solved exactly per chain by the Thomas algorithm on
//!   factors computed once.
//! - **stretch**: `M = diag(m) ⊗ I3 + Σ μ_p u_p u_pᵀ` with
//!   `u_p = e_a ⊗ F_a d_p − e_b ⊗ F_b d_p`, `d_p` the pair's current unit
//!   direction and `F_n` the mask of node `n`'s free dofs: the coupling
//!   weighs on the relative velocity along the pair only. By Woodbury,
//!   `M⁻¹ r = g − D⁻¹ U y` with `g = D⁻¹ r` and
//!   `(C⁻¹ + Uᵀ D⁻¹ U) y = Uᵀ g`, a symmetric positive definite scalar
//!   system that is tridiagonal along each chain (consecutive pairs share
//!   one node). It is assembled and solved every time, at the current
//!   directions: a few dozen flops per node.

use rayon::prelude::*;

use super::setup_error::SetupError;
use crate::model::MassCoupling;

/// Nodes per task of the stretch form's correction pass.
const CORRECTION_BLOCK: usize = 512;

/// Per chain position: the stretch form's per-increment values of the
/// pair from this position to the next (all zero at a chain's last
/// position).
#[derive(Debug, Clone, Copy, Default)]
pub struct StretchEntry {
    /// The chain the position belongs to.
    chain: u32,
    /// The pair's current unit direction `d_p`.
    direction: [f64; 3],
    /// `y_p` of the Woodbury system (its right-hand side on the way).
    y: f64,
    /// The Thomas algorithm's `c′_p`.
    upper: f64,
}

/// The stretch form's constant data, per chain position.
#[derive(Debug, Clone, Default)]
struct StretchChains {
    /// The reference vector from this position's node to the next one's
    /// \[mm\] (zero at a chain's last position).
    reference: Vec<[f64; 3]>,
    /// `1/μ_p` of the pair to the next position (0 at a chain's last).
    inverse_coupling: Vec<f64>,
    /// Per component: 1 for a free dof, 0 for a prescribed one.
    free: Vec<[f64; 3]>,
    /// `1/m` of the position's node.
    inverse_mass: Vec<f64>,
    /// Per node: its chain position (`u32::MAX` off the chains).
    position: Vec<u32>,
}

/// The chains of coupled nodes and their factorised mass matrices.
#[derive(Debug, Clone, Default)]
pub struct MassChains {
    /// The nodes, chain after chain, each chain in order along it.
    order: Vec<u32>,
    /// Chain `k` is `order[starts[k]..starts[k + 1]]`.
    starts: Vec<u32>,
    /// Per position and component: the coupling mass to the previous node
    /// of its chain where both dofs are free (else 0) \[t\].
    lower: Vec<[f64; 3]>,
    /// Per position and component: `1 / pivot` of the forward elimination.
    inverse_pivot: Vec<[f64; 3]>,
    /// Per position and component: `−μ_{p,p+1} / pivot`.
    upper: Vec<[f64; 3]>,
    /// Per node: whether it lies on a chain.
    on_chain: Vec<bool>,
    /// The merged couplings `(a, b, μ)`, for the kinetic energy.
    couplings: Vec<(u32, u32, f64)>,
    /// Per merged coupling and component: whether the dof is free at `a`
    /// and at `b`.
    free_components: Vec<[(bool, bool); 3]>,
    /// The stretch form's data (`None`: the full form).
    stretch: Option<StretchChains>,
}

impl MassChains {
    /// Chains from `couplings` over `masses.len()` nodes with lumped masses
    /// `masses` \[t\]; `free(n)` tells which of node `n`'s three dofs are
    /// free. Per component, a coupling between two free dofs couples them;
    /// at a free dof whose partner is prescribed it adds its mass to the
    /// diagonal (the free block of `M`). Repeated pairs add up.
    ///
    /// # Errors
    /// A coupling with a node out of range, a non-finite or negative mass,
    /// a node with more than two coupled neighbours, or a loop.
    pub fn new(
        masses: &[f64],
        couplings: &[MassCoupling],
        free: impl Fn(usize) -> [bool; 3],
    ) -> Result<Self, SetupError> {
        let nodes = masses.len();
        let stretch_form = couplings.first().is_some_and(|c| c.stretch.is_some());
        let mut pairs: Vec<(u32, u32, f64, [f64; 3])> = Vec::with_capacity(couplings.len());
        for c in couplings {
            if c.stretch.is_some() != stretch_form {
                return Err(SetupError::MassCoupling {
                    node: c.nodes[0].min(c.nodes[1]),
                    reason: "couplings on all components and on the stretch only are mixed: one model takes one form".into(),
                });
            }
            let [a, b] = c.nodes;
            if a >= nodes || b >= nodes || a == b || !(c.mass.is_finite() && c.mass >= 0.0) {
                return Err(SetupError::MassCoupling {
                    node: a.min(b),
                    reason: format!(
                        "coupling of nodes {a} and {b} with mass {:e} t: expected two distinct nodes of the model and a finite mass ≥ 0",
                        c.mass
                    ),
                });
            }
            let reference = c.stretch.unwrap_or([0.0; 3]);
            if !reference.iter().all(|x| x.is_finite()) {
                return Err(SetupError::MassCoupling {
                    node: a.min(b),
                    reason: format!(
                        "coupling of nodes {a} and {b}: a reference vector with a non-finite component"
                    ),
                });
            }
            if c.mass > 0.0 && masses[a] > 0.0 && masses[b] > 0.0 {
                // Oriented from the lower node to the higher one.
                let sign = if a < b { 1.0 } else { -1.0 };
                pairs.push((
                    a.min(b) as u32,
                    a.max(b) as u32,
                    c.mass,
                    reference.map(|x| sign * x),
                ));
            }
        }
        pairs.sort_by_key(|x| (x.0, x.1));
        let mut merged: Vec<(u32, u32, f64)> = Vec::with_capacity(pairs.len());
        let mut references: Vec<[f64; 3]> = Vec::with_capacity(pairs.len());
        for (a, b, m, reference) in pairs {
            match merged.last_mut() {
                Some(last) if last.0 == a && last.1 == b => last.2 += m,
                _ => {
                    merged.push((a, b, m));
                    references.push(reference);
                }
            }
        }
        // At most two neighbours per node.
        let mut neighbours = vec![[(u32::MAX, 0usize); 2]; nodes];
        let mut degree = vec![0u8; nodes];
        for (index, &(a, b, _)) in merged.iter().enumerate() {
            for (n, other) in [(a, b), (b, a)] {
                let d = degree[n as usize] as usize;
                if d == 2 {
                    return Err(SetupError::MassCoupling {
                        node: n as usize,
                        reason: "more than two coupled neighbours: the coupling masses must form chains (each node on one roving line)".into(),
                    });
                }
                neighbours[n as usize][d] = (other, index);
                degree[n as usize] += 1;
            }
        }
        let free_components: Vec<[(bool, bool); 3]> = merged
            .iter()
            .map(|&(a, b, _)| {
                let (fa, fb) = (free(a as usize), free(b as usize));
                std::array::from_fn(|c| (fa[c], fb[c]))
            })
            .collect();
        let mut chains = Self {
            on_chain: vec![false; nodes],
            starts: vec![0],
            ..Self::default()
        };
        // Per position, the coupling to the previous node (index into
        // `merged`), while walking every chain from an end.
        let mut previous_coupling: Vec<usize> = Vec::new();
        for end in 0..nodes {
            if degree[end] != 1 || chains.on_chain[end] {
                continue;
            }
            let mut previous = u32::MAX;
            let mut node = end as u32;
            let mut coupling_in = usize::MAX;
            loop {
                chains.on_chain[node as usize] = true;
                chains.order.push(node);
                previous_coupling.push(coupling_in);
                let next = neighbours[node as usize]
                    .iter()
                    .take(degree[node as usize] as usize)
                    .find(|(n, _)| *n != previous)
                    .copied();
                match next {
                    Some((n, index)) if !chains.on_chain[n as usize] => {
                        previous = node;
                        node = n;
                        coupling_in = index;
                    }
                    _ => break,
                }
            }
            chains.starts.push(chains.order.len() as u32);
        }
        if let Some(n) = (0..nodes).find(|&n| degree[n] > 0 && !chains.on_chain[n]) {
            return Err(SetupError::MassCoupling {
                node: n,
                reason: "the coupling masses close a loop: they must form open chains".into(),
            });
        }
        let len = chains.order.len();
        if stretch_form {
            let mut data = StretchChains {
                reference: vec![[0.0; 3]; len],
                inverse_coupling: vec![0.0; len],
                free: vec![[0.0; 3]; len],
                inverse_mass: vec![0.0; len],
                position: vec![u32::MAX; nodes],
            };
            #[allow(clippy::needless_range_loop)] // p indexes five arrays and p − 1
            for p in 0..len {
                let node = chains.order[p] as usize;
                data.position[node] = p as u32;
                data.free[p] = free(node).map(|f| if f { 1.0 } else { 0.0 });
                data.inverse_mass[p] = 1.0 / masses[node];
                // The pair to the previous position, oriented towards this one.
                let index = previous_coupling[p];
                if index != usize::MAX {
                    let (a, _, m) = merged[index];
                    let sign = if a == chains.order[p - 1] { 1.0 } else { -1.0 };
                    data.reference[p - 1] = references[index].map(|x| sign * x);
                    data.inverse_coupling[p - 1] = 1.0 / m;
                }
            }
            chains.stretch = Some(data);
            chains.couplings = merged;
            chains.free_components = free_components;
            return Ok(chains);
        }
        // Per position and component: the coupling to the previous node
        // (both free) and the diagonal m + Σ μ of the couplings at a free dof.
        let mut diagonal = vec![[0.0; 3]; len];
        chains.lower = vec![[0.0; 3]; len];
        for p in 0..len {
            let node = chains.order[p] as usize;
            let node_free = free(node);
            diagonal[p] = [masses[node]; 3];
            for &(_, index) in neighbours[node].iter().take(degree[node] as usize) {
                for c in 0..3 {
                    if node_free[c] {
                        diagonal[p][c] += merged[index].2;
                    }
                }
            }
            let index = previous_coupling[p];
            if index != usize::MAX {
                for (lower, &(fa, fb)) in chains.lower[p].iter_mut().zip(&free_components[index]) {
                    if fa && fb {
                        *lower = merged[index].2;
                    }
                }
            }
        }
        // Thomas factors.
        chains.inverse_pivot = vec![[0.0; 3]; len];
        chains.upper = vec![[0.0; 3]; len];
        for k in 0..chains.starts.len() - 1 {
            let (start, end) = (chains.starts[k] as usize, chains.starts[k + 1] as usize);
            let mut previous_upper = [0.0; 3];
            #[allow(clippy::needless_range_loop)] // p indexes four arrays and p + 1
            for p in start..end {
                let after = if p + 1 < end {
                    chains.lower[p + 1]
                } else {
                    [0.0; 3]
                };
                for c in 0..3 {
                    // pivot = d_p − l_p u_{p−1} with l_p = −μ_{p−1,p}.
                    let pivot = diagonal[p][c] + chains.lower[p][c] * previous_upper[c];
                    let inverse = 1.0 / pivot;
                    chains.inverse_pivot[p][c] = inverse;
                    previous_upper[c] = -after[c] * inverse;
                    chains.upper[p][c] = previous_upper[c];
                }
            }
        }
        chains.couplings = merged;
        chains.free_components = free_components;
        Ok(chains)
    }

    /// Whether there is any coupling.
    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// Number of nodes on chains.
    pub fn nodes(&self) -> usize {
        self.order.len()
    }

    /// Number of chains.
    pub fn count(&self) -> usize {
        self.starts.len() - 1
    }

    /// Whether node `n` lies on a chain.
    #[cfg(test)]
    #[inline(always)]
    pub fn on_chain(&self, n: usize) -> bool {
        self.on_chain[n]
    }

    /// `Σ μ` of the couplings \[t\].
    pub fn coupling_mass(&self) -> f64 {
        self.couplings.iter().fold(0.0, |s, c| s + c.2)
    }

    /// Whether the couplings weigh on the stretch only (the stretch form).
    #[cfg(test)]
    pub fn is_stretch(&self) -> bool {
        self.stretch.is_some()
    }

    /// The form, for reports: `"stretch"`, `"full"`, or `"none"` without
    /// couplings.
    pub fn form(&self) -> &'static str {
        match (&self.stretch, self.order.is_empty()) {
            (_, true) => "none",
            (Some(_), false) => "stretch",
            (None, false) => "full",
        }
    }

    /// Whether [`MassChains::solve`] takes node `n`'s right-hand side `r`
    /// itself (the full form, on a chain); otherwise it takes `r / m`
    /// (off the chains, and every node in the stretch form).
    #[inline(always)]
    pub fn takes_force(&self, n: usize) -> bool {
        self.stretch.is_none() && self.on_chain[n]
    }

    /// The scratch of the stretch form's solve: one entry per chain
    /// position (empty for the full form).
    pub fn scratch(&self) -> Vec<StretchEntry> {
        if self.stretch.is_none() {
            return Vec::new();
        }
        let mut entries = vec![StretchEntry::default(); self.order.len()];
        for k in 0..self.starts.len() - 1 {
            for e in &mut entries[self.starts[k] as usize..self.starts[k + 1] as usize] {
                e.chain = k as u32;
            }
        }
        entries
    }

    /// Solves `M a = r` on the free dofs (3 entries per node in `values`,
    /// node-major, on entry as [`MassChains::takes_force`] says, with 0 at
    /// prescribed dofs); in the stretch form at the displacements `u` (3
    /// per node, at least as many nodes as `values`), keeping the pairs'
    /// directions in `scratch` ([`MassChains::scratch`]) for
    /// [`MassChains::coupling_kinetic_energy`]. Nodes off the chains are
    /// left as they are; the entries of prescribed dofs come out
    /// meaningless in the full form and 0 in the stretch form.
    pub fn solve(&self, values: &mut [f64], u: &[f64], scratch: &mut [StretchEntry]) {
        match &self.stretch {
            Some(stretch) => {
                self.solve_stretch_chains(stretch, values, u, scratch);
                let scratch = &*scratch;
                values
                    .par_chunks_mut(3 * CORRECTION_BLOCK)
                    .enumerate()
                    .for_each(|(block, values)| {
                        for (i, a) in values.chunks_exact_mut(3).enumerate() {
                            self.correct(block * CORRECTION_BLOCK + i, a, scratch);
                        }
                    });
            }
            None => self.solve_full(values),
        }
    }

    /// [`MassChains::solve`] but for the stretch form's last step, the
    /// per-node correction `a = g − D⁻¹ U y`, which is left to the caller
    /// ([`MassChains::correct`] on every node, e.g. fused with its own
    /// pass over the nodes); the full form solves completely. Returns
    /// whether the correction is left to the caller.
    pub fn solve_without_correction(
        &self,
        values: &mut [f64],
        u: &[f64],
        scratch: &mut [StretchEntry],
    ) -> bool {
        match &self.stretch {
            Some(stretch) => {
                self.solve_stretch_chains(stretch, values, u, scratch);
                true
            }
            None => {
                self.solve_full(values);
                false
            }
        }
    }

    /// The stretch form's correction of node `node`'s entries `a` (3,
    /// `g` on entry): `a_p −= F_p (y_p d_p − y_{p−1} d_{p−1}) / m_p` with
    /// the `y` and directions in `scratch` (after
    /// [`MassChains::solve_without_correction`]); nodes off the chains and
    /// the full form are left as they are.
    #[inline(always)]
    pub fn correct(&self, node: usize, a: &mut [f64], scratch: &[StretchEntry]) {
        let Some(stretch) = &self.stretch else {
            return;
        };
        let p = stretch.position[node];
        if p == u32::MAX {
            return;
        }
        let p = p as usize;
        // The previous entry of a chain's first position is the last of
        // another chain, whose y and direction are 0.
        let own = &scratch[p];
        let mut w = own.direction.map(|d| own.y * d);
        if p > 0 {
            let before = &scratch[p - 1];
            for (wc, dc) in w.iter_mut().zip(before.direction) {
                *wc -= before.y * dc;
            }
        }
        let scale = stretch.inverse_mass[p];
        for c in 0..3 {
            a[c] -= stretch.free[p][c] * w[c] * scale;
        }
    }

    /// The stretch form's solve without its correction: per chain (in
    /// parallel) the directions, `s = Uᵀ g` and the tridiagonal
    /// `(C⁻¹ + Uᵀ D⁻¹ U) y = s` by Thomas, into `scratch`.
    fn solve_stretch_chains(
        &self,
        stretch: &StretchChains,
        g: &[f64],
        u: &[f64],
        scratch: &mut [StretchEntry],
    ) {
        let order = &self.order;
        let starts = &self.starts;
        scratch
            .par_chunk_by_mut(|a, b| a.chain == b.chain)
            .for_each(|entries| {
                let start = starts[entries[0].chain as usize] as usize;
                let len = entries.len();
                let g = &*g;
                let node3 = |p: usize| 3 * order[start + p] as usize;
                // Directions and right-hand sides s_p = d_p·(g_p − g_{p+1}).
                for (p, entry) in entries[..len - 1].iter_mut().enumerate() {
                    let (a, b) = (node3(p), node3(p + 1));
                    let reference = &stretch.reference[start + p];
                    let x: [f64; 3] = std::array::from_fn(|c| reference[c] + u[b + c] - u[a + c]);
                    let length = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
                    let d = if length > 0.0 {
                        x.map(|xc| xc / length)
                    } else {
                        [0.0; 3]
                    };
                    entry.direction = d;
                    entry.y = (0..3).fold(0.0, |s, c| s + d[c] * (g[a + c] - g[b + c]));
                }
                entries[len - 1].direction = [0.0; 3];
                entries[len - 1].y = 0.0;
                // Forward elimination: S_pp = 1/μ_p + |F_p d_p|²/m_p +
                // |F_{p+1} d_p|²/m_{p+1}, S_{p,p+1} = −(F_{p+1} d_p)·d_{p+1}/m_{p+1}.
                let masked = |p: usize, d: &[f64; 3], e: &[f64; 3]| {
                    let f = &stretch.free[start + p];
                    (0..3).fold(0.0, |s, c| s + f[c] * d[c] * e[c])
                };
                let mut previous_upper = 0.0;
                let mut previous_y = 0.0;
                #[allow(clippy::needless_range_loop)] // p indexes entries at p − 1, p, p + 1
                for p in 0..len - 1 {
                    let d = entries[p].direction;
                    let diagonal = stretch.inverse_coupling[start + p]
                        + masked(p, &d, &d) * stretch.inverse_mass[start + p]
                        + masked(p + 1, &d, &d) * stretch.inverse_mass[start + p + 1];
                    let lower = if p > 0 {
                        -masked(p, &entries[p - 1].direction, &d) * stretch.inverse_mass[start + p]
                    } else {
                        0.0
                    };
                    let upper = if p + 2 < len {
                        -masked(p + 1, &d, &entries[p + 1].direction)
                            * stretch.inverse_mass[start + p + 1]
                    } else {
                        0.0
                    };
                    let inverse = 1.0 / (diagonal - lower * previous_upper);
                    previous_upper = upper * inverse;
                    previous_y = (entries[p].y - lower * previous_y) * inverse;
                    entries[p].upper = previous_upper;
                    entries[p].y = previous_y;
                }
                // Back substitution.
                let mut next = 0.0;
                for entry in entries[..len - 1].iter_mut().rev() {
                    entry.y -= entry.upper * next;
                    next = entry.y;
                }
            });
    }

    /// The full form's solve: Thomas per chain and component on the
    /// factors computed once.
    fn solve_full(&self, values: &mut [f64]) {
        for k in 0..self.starts.len() - 1 {
            let (start, end) = (self.starts[k] as usize, self.starts[k + 1] as usize);
            let mut previous = [0.0; 3];
            for p in start..end {
                let at = 3 * self.order[p] as usize;
                // l_p = −μ_{p−1,p}: y_p = (r_p − l_p y_{p−1}) / pivot_p.
                for c in 0..3 {
                    let y = (values[at + c] + self.lower[p][c] * previous[c])
                        * self.inverse_pivot[p][c];
                    values[at + c] = y;
                    previous[c] = y;
                }
            }
            let mut next = [0.0; 3];
            for p in (start..end).rev() {
                let at = 3 * self.order[p] as usize;
                for c in 0..3 {
                    let x = values[at + c] - self.upper[p][c] * next[c];
                    values[at + c] = x;
                    next[c] = x;
                }
            }
        }
    }

    /// The couplings' part of `½ v_fᵀ M_ff v_f` at the velocities `v` (3
    /// per node): per component `½ μ (v_a − v_b)²` where both dofs are
    /// free, `½ μ v²` at a free dof whose partner is prescribed \[N·mm\].
    ///
    /// In the stretch form, `½ μ_p (d_p·(F_a v_a − F_b v_b))²` with the
    /// directions of the last [`MassChains::solve`] (in `scratch`).
    pub fn coupling_kinetic_energy(&self, v: &[f64], scratch: &[StretchEntry]) -> f64 {
        if let Some(stretch) = &self.stretch {
            return (0..scratch.len().saturating_sub(1)).fold(0.0, |sum, p| {
                let d = &scratch[p].direction;
                if stretch.inverse_coupling[p] == 0.0 {
                    return sum;
                }
                let (a, b) = (3 * self.order[p] as usize, 3 * self.order[p + 1] as usize);
                let (fa, fb) = (&stretch.free[p], &stretch.free[p + 1]);
                let rate =
                    (0..3).fold(0.0, |s, c| s + d[c] * (fa[c] * v[a + c] - fb[c] * v[b + c]));
                sum + 0.5 * rate * rate / stretch.inverse_coupling[p]
            });
        }
        self.couplings
            .iter()
            .zip(&self.free_components)
            .fold(0.0, |sum, (&(a, b, m), free)| {
                let (a, b) = (3 * a as usize, 3 * b as usize);
                let mut d2 = 0.0;
                for (c, &(fa, fb)) in free.iter().enumerate() {
                    let d = match (fa, fb) {
                        (true, true) => v[a + c] - v[b + c],
                        (true, false) => v[a + c],
                        (false, true) => v[b + c],
                        (false, false) => 0.0,
                    };
                    d2 += d * d;
                }
                sum + 0.5 * m * d2
            })
    }

    /// `M v` into `out` (3 per node, all dofs free), for tests.
    #[cfg(test)]
    pub fn multiply(&self, masses: &[f64], v: &[f64], out: &mut [f64]) {
        for (k, (o, x)) in out.iter_mut().zip(v).enumerate() {
            *o = masses[k / 3] * x;
        }
        for &(a, b, m) in &self.couplings {
            let (a, b) = (3 * a as usize, 3 * b as usize);
            for c in 0..3 {
                let d = m * (v[a + c] - v[b + c]);
                out[a + c] += d;
                out[b + c] -= d;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coupling(a: usize, b: usize, mass: f64) -> MassCoupling {
        MassCoupling {
            nodes: [a, b],
            mass,
            stretch: None,
        }
    }

    /// Two chains (0–1–2–3 given out of order and with a repeated pair,
    /// 5–6), a lone node 4: the solve inverts the multiply to round-off.
    #[test]
    fn solve_inverts_the_coupled_mass() {
        let masses = [1.0, 2.0, 1.5, 0.5, 3.0, 1.0, 2.0];
        let couplings = [
            coupling(2, 1, 4.0),
            coupling(0, 1, 10.0),
            coupling(3, 2, 2.0),
            coupling(1, 2, 1.0),
            coupling(6, 5, 7.0),
        ];
        let chains = MassChains::new(&masses, &couplings, |_| [true; 3]).unwrap();
        assert_eq!(chains.count(), 2);
        assert_eq!(chains.nodes(), 6);
        assert!(!chains.on_chain(4));
        let v: Vec<f64> = (0..21).map(|k| (k as f64 * 0.7).sin()).collect();
        let mut r = vec![0.0; 21];
        chains.multiply(&masses, &v, &mut r);
        // The lone node is not solved: divide by its mass as the solver does.
        for c in 0..3 {
            r[12 + c] /= masses[4];
        }
        chains.solve(&mut r, &[], &mut []);
        for (x, y) in r.iter().zip(&v) {
            assert!((x - y).abs() <= 1e-12, "{x} vs {y}");
        }
        // vᵀMv = Σ m v² + 2 × the couplings' kinetic energy.
        let mut mv = vec![0.0; 21];
        chains.multiply(&masses, &v, &mut mv);
        let quadratic: f64 = mv.iter().zip(&v).map(|(a, b)| a * b).sum();
        let lumped: f64 = v
            .iter()
            .enumerate()
            .map(|(k, x)| masses[k / 3] * x * x)
            .sum();
        let coupled = chains.coupling_kinetic_energy(&v, &[]);
        assert!((quadratic - lumped - 2.0 * coupled).abs() <= 1e-12 * quadratic.abs());
    }

    #[test]
    fn branches_and_loops_are_refused() {
        let masses = [1.0; 4];
        let star = [
            coupling(0, 1, 1.0),
            coupling(0, 2, 1.0),
            coupling(0, 3, 1.0),
        ];
        assert!(MassChains::new(&masses, &star, |_| [true; 3]).is_err());
        let ring = [
            coupling(0, 1, 1.0),
            coupling(1, 2, 1.0),
            coupling(2, 0, 1.0),
        ];
        assert!(MassChains::new(&masses, &ring, |_| [true; 3]).is_err());
        let bad = [coupling(0, 9, 1.0)];
        assert!(MassChains::new(&masses, &bad, |_| [true; 3]).is_err());
    }

    /// A prescribed dof keeps its chain's other dofs coupled and passes
    /// the coupling mass to its free partner's diagonal: with node 2's x
    /// fixed, the x system of 0–1–2–3–4 splits into 0–1 (+μ at 1) and
    /// 3–4 (+μ at 3), checked against the dense free block.
    #[test]
    fn prescribed_dofs_take_the_free_block() {
        let masses = [1.0, 2.0, 3.0, 1.5, 0.5];
        let line: Vec<_> = (0..4).map(|k| coupling(k, k + 1, 0.7 + k as f64)).collect();
        let chains = MassChains::new(&masses, &line, |n| [n != 2, true, true]).unwrap();
        assert_eq!(chains.count(), 1);
        // Dense free block of the x system: nodes 0, 1, 3, 4.
        let free = [0usize, 1, 3, 4];
        let mut dense = [[0.0; 4]; 4];
        for (r, &n) in free.iter().enumerate() {
            dense[r][r] = masses[n];
        }
        for c in &line {
            let [a, b] = c.nodes;
            let (ra, rb) = (
                free.iter().position(|&n| n == a),
                free.iter().position(|&n| n == b),
            );
            if let Some(ra) = ra {
                dense[ra][ra] += c.mass;
            }
            if let Some(rb) = rb {
                dense[rb][rb] += c.mass;
            }
            if let (Some(ra), Some(rb)) = (ra, rb) {
                dense[ra][rb] -= c.mass;
                dense[rb][ra] -= c.mass;
            }
        }
        let x = [0.3, -1.2, 0.8, 2.0];
        let mut values = vec![0.0; 15];
        for (r, &n) in free.iter().enumerate() {
            values[3 * n] = (0..4).map(|q| dense[r][q] * x[q]).sum();
        }
        chains.solve(&mut values, &[], &mut []);
        for (r, &n) in free.iter().enumerate() {
            assert!(
                (values[3 * n] - x[r]).abs() <= 1e-12,
                "{} vs {}",
                values[3 * n],
                x[r]
            );
        }
        // The kinetic energy of the free block: ½ xᵀ D x − ½ Σ m x².
        let mut v = vec![0.0; 15];
        for (r, &n) in free.iter().enumerate() {
            v[3 * n] = x[r];
        }
        let quadratic: f64 = (0..4)
            .map(|r| (0..4).map(|q| x[r] * dense[r][q] * x[q]).sum::<f64>())
            .sum();
        let lumped: f64 = free
            .iter()
            .zip(&x)
            .map(|(&n, xi)| masses[n] * xi * xi)
            .sum();
        let coupled = chains.coupling_kinetic_energy(&v, &[]);
        assert!((0.5 * (quadratic - lumped) - coupled).abs() <= 1e-12);
    }

    /// The stretch form against its definition: `M = D ⊗ I3 + Σ μ (e_a −
    /// e_b)(e_a − e_b)ᵀ ⊗ d dᵀ` at the current directions, assembled
    /// densely on the free dofs. Chains 0–1–2–3–4 (pairs given out of
    /// order and reversed) and 5–6, a lone node 7; node 2's x and all of
    /// node 4 prescribed. The solve inverts the free block to round-off,
    /// gives 0 at prescribed dofs and leaves the lone node alone; the
    /// couplings' kinetic energy is `½ vᵀ M v − ½ Σ m v²`.
    #[test]
    fn stretch_form_inverts_its_free_block() {
        let masses = [1.0, 2.0, 1.5, 0.5, 3.0, 1.0, 2.0, 4.0];
        let nodes = masses.len();
        let reference: Vec<[f64; 3]> = (0..nodes)
            .map(|n| {
                let t = n as f64;
                [3.0 * t, 0.5 * (1.3 * t).sin(), 0.2 * t * t / 10.0]
            })
            .collect();
        let u: Vec<f64> = (0..3 * nodes)
            .map(|k| 0.4 * (0.9 * k as f64).cos())
            .collect();
        let stretch = |a: usize, b: usize, mass: f64| MassCoupling {
            nodes: [a, b],
            mass,
            stretch: Some(std::array::from_fn(|c| reference[b][c] - reference[a][c])),
        };
        let couplings = [
            stretch(2, 1, 4.0),
            stretch(0, 1, 10.0),
            stretch(3, 2, 2.0),
            stretch(1, 2, 1.0),
            stretch(3, 4, 6.0),
            stretch(6, 5, 7.0),
        ];
        let is_free = |n: usize| -> [bool; 3] {
            match n {
                2 => [false, true, true],
                4 => [false; 3],
                _ => [true; 3],
            }
        };
        let chains = MassChains::new(&masses, &couplings, is_free).unwrap();
        assert!(chains.is_stretch());
        assert_eq!(chains.count(), 2);
        // Dense M over all dofs, then its free block.
        let dofs = 3 * nodes;
        let mut dense = vec![vec![0.0; dofs]; dofs];
        for (k, row) in dense.iter_mut().enumerate() {
            row[k] = masses[k / 3];
        }
        for c in &couplings {
            let [a, b] = c.nodes;
            let x: [f64; 3] = std::array::from_fn(|k| {
                reference[b][k] + u[3 * b + k] - reference[a][k] - u[3 * a + k]
            });
            let length = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
            let d = x.map(|xk| xk / length);
            for (na, sa) in [(a, 1.0), (b, -1.0)] {
                for (nb, sb) in [(a, 1.0), (b, -1.0)] {
                    for i in 0..3 {
                        for j in 0..3 {
                            dense[3 * na + i][3 * nb + j] += c.mass * sa * sb * d[i] * d[j];
                        }
                    }
                }
            }
        }
        let free: Vec<usize> = (0..dofs).filter(|&k| is_free(k / 3)[k % 3]).collect();
        let x: Vec<f64> = (0..dofs)
            .map(|k| {
                if free.contains(&k) {
                    (0.7 * k as f64).sin() + 0.1
                } else {
                    0.0
                }
            })
            .collect();
        // r = M_ff x, given as r/m on free dofs and 0 on prescribed ones.
        let mut values = vec![0.0; dofs];
        for &i in &free {
            let r: f64 = free.iter().map(|&j| dense[i][j] * x[j]).sum();
            values[i] = r / masses[i / 3];
        }
        let lone = values[21..24].to_vec();
        let mut scratch = chains.scratch();
        chains.solve(&mut values, &u, &mut scratch);
        for k in 0..dofs {
            if k / 3 == 7 {
                assert_eq!(values[k], lone[k - 21]);
            } else {
                assert!(
                    (values[k] - x[k]).abs() <= 1e-12,
                    "dof {k}: {} vs {}",
                    values[k],
                    x[k]
                );
            }
        }
        let quadratic: f64 = free
            .iter()
            .map(|&i| free.iter().map(|&j| x[i] * dense[i][j] * x[j]).sum::<f64>())
            .sum();
        let lumped: f64 = free.iter().map(|&i| masses[i / 3] * x[i] * x[i]).sum();
        let coupled = chains.coupling_kinetic_energy(&x, &scratch);
        assert!(
            (0.5 * (quadratic - lumped) - coupled).abs() <= 1e-12 * quadratic,
            "{} vs {coupled}",
            0.5 * (quadratic - lumped)
        );
        // A rigid translation and a rigid rotation of the free chain 5–6
        // carry no coupling energy; stretching it does.
        let mut v = vec![0.0; dofs];
        v[15..18].copy_from_slice(&[0.3, -0.2, 0.5]);
        v[18..21].copy_from_slice(&[0.3, -0.2, 0.5]);
        assert!(chains.coupling_kinetic_energy(&v, &scratch).abs() <= 1e-15);
        let segment: [f64; 3] =
            std::array::from_fn(|k| reference[6][k] + u[18 + k] - reference[5][k] - u[15 + k]);
        let omega = [0.4, -1.1, 0.7];
        let spin = [
            omega[1] * segment[2] - omega[2] * segment[1],
            omega[2] * segment[0] - omega[0] * segment[2],
            omega[0] * segment[1] - omega[1] * segment[0],
        ];
        for k in 0..3 {
            v[18 + k] += spin[k];
        }
        assert!(chains.coupling_kinetic_energy(&v, &scratch).abs() <= 1e-15);
        for k in 0..3 {
            v[18 + k] += 0.1 * segment[k];
        }
        assert!(chains.coupling_kinetic_energy(&v, &scratch) > 1e-4);
    }
}
