//! The mass matrix with coupling masses along chains of nodes (roving mass
//! scaling, `docs/explicit.md`): `M = diag(m) + Σ μ_ab (e_a − e_b)(e_a −
//! e_b)ᵀ` per component, of which the solver uses the block of the free
//! dofs (as for the lumped mass, a prescribed dof passes no inertia to
//! the free ones). When every node has at most two coupled neighbours and
//! the couplings form no loop, that block is tridiagonal along each chain
//! and component, and `M a = r` is solved exactly per chain by the Thomas
//! algorithm on factors computed once.

use super::system::SetupError;
use crate::model::MassCoupling;

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
        let mut pairs: Vec<(u32, u32, f64)> = Vec::with_capacity(couplings.len());
        for c in couplings {
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
            if c.mass > 0.0 && masses[a] > 0.0 && masses[b] > 0.0 {
                pairs.push((a.min(b) as u32, a.max(b) as u32, c.mass));
            }
        }
        pairs.sort_by_key(|x| (x.0, x.1));
        let mut merged: Vec<(u32, u32, f64)> = Vec::with_capacity(pairs.len());
        for (a, b, m) in pairs {
            match merged.last_mut() {
                Some(last) if last.0 == a && last.1 == b => last.2 += m,
                _ => merged.push((a, b, m)),
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
        // Per position and component: the coupling to the previous node
        // (both free) and the diagonal m + Σ μ of the couplings at a free dof.
        let len = chains.order.len();
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
    #[inline(always)]
    pub fn on_chain(&self, n: usize) -> bool {
        self.on_chain[n]
    }

    /// `Σ μ` of the couplings \[t\].
    pub fn coupling_mass(&self) -> f64 {
        self.couplings.iter().fold(0.0, |s, c| s + c.2)
    }

    /// Solves `M a = r` in place on the chains' nodes (3 entries per node
    /// in `values`, node-major); other nodes are left as they are. The
    /// entries of prescribed dofs come out meaningless.
    pub fn solve(&self, values: &mut [f64]) {
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
    pub fn coupling_kinetic_energy(&self, v: &[f64]) -> f64 {
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
        chains.solve(&mut r);
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
        let coupled = chains.coupling_kinetic_energy(&v);
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
        chains.solve(&mut values);
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
        let coupled = chains.coupling_kinetic_energy(&v);
        assert!((0.5 * (quadratic - lumped) - coupled).abs() <= 1e-12);
    }
}
