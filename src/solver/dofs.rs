//! Degrees of freedom: three displacements per node, `dof = 3 node + k`,
//! split into free unknowns and Dirichlet-constrained ones.

/// A Dirichlet condition: `u[dof] = per_unit_load · λ`, where `λ` is the
/// load parameter the solver drives (a clamp displacement in mm, say). A
/// fixed dof has `per_unit_load = 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dirichlet {
    /// Global dof index `3 node + component`.
    pub dof: usize,
    /// Displacement per unit load parameter [mm per unit λ].
    pub per_unit_load: f64,
}

impl Dirichlet {
    /// `u = 0` for `component` (0, 1, 2 = x, y, z) of `node`.
    pub fn fixed(node: usize, component: usize) -> Self {
        Self::driven(node, component, 0.0)
    }

    /// `u = per_unit_load · λ` for the dof `dof` (an extra dof of a rigid
    /// body, say).
    pub fn dof(dof: usize, per_unit_load: f64) -> Self {
        Self { dof, per_unit_load }
    }

    /// `u = per_unit_load · λ` for `component` of `node`.
    pub fn driven(node: usize, component: usize, per_unit_load: f64) -> Self {
        Self {
            dof: 3 * node + component,
            per_unit_load,
        }
    }
}

/// The split of the dofs into free unknowns and constrained ones.
#[derive(Debug, Clone, PartialEq)]
pub struct DofMap {
    /// Total number of dofs (3 per node).
    pub total: usize,
    /// For each dof: its index among the free unknowns, or `None`.
    pub free_index: Vec<Option<usize>>,
    /// The free dofs in order.
    pub free: Vec<usize>,
    /// The constrained dofs with their loading.
    pub constrained: Vec<Dirichlet>,
}

impl DofMap {
    /// Builds the map for `nodes` nodes (3 dofs each, no extra dofs). A dof
    /// constrained twice keeps the last condition.
    pub fn new(nodes: usize, conditions: &[Dirichlet]) -> Self {
        Self::with_total(3 * nodes, conditions)
    }

    /// Builds the map for `total` dofs (nodes and extra dofs). A dof
    /// constrained twice keeps the last condition.
    pub fn with_total(total: usize, conditions: &[Dirichlet]) -> Self {
        let mut condition_of: Vec<Option<f64>> = vec![None; total];
        for c in conditions {
            condition_of[c.dof] = Some(c.per_unit_load);
        }
        let mut free_index = vec![None; total];
        let mut free = Vec::new();
        let mut constrained = Vec::new();
        for (dof, condition) in condition_of.iter().enumerate() {
            match condition {
                Some(per_unit_load) => constrained.push(Dirichlet {
                    dof,
                    per_unit_load: *per_unit_load,
                }),
                None => {
                    free_index[dof] = Some(free.len());
                    free.push(dof);
                }
            }
        }
        Self {
            total,
            free_index,
            free,
            constrained,
        }
    }

    /// Number of free unknowns.
    pub fn n_free(&self) -> usize {
        self.free.len()
    }
}
