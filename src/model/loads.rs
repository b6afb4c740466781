//! External loads and rigid-body masses: dead forces on nodes and on the
//! dofs of rigid bodies (gravity from the areal mass, the weight of a
//! floating blankholder, forces on node sets), each following an amplitude
//! over the load programme; and the mass of a rigid body's dof.

use nalgebra::Vector3;

use super::term::{Masses, NO_SLOT, State, Stencils, Term, TermEnergy, TermFailure};

/// How a load follows the load programme.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LoadAmplitude {
    /// The full load from the start (`λ = 0`).
    Constant,
    /// Proportional to the programme fraction `λ / λ_final`.
    Ramp,
}

impl LoadAmplitude {
    /// The load factor at the programme fraction `fraction ∈ [0, 1]`.
    pub fn factor(self, fraction: f64) -> f64 {
        match self {
            LoadAmplitude::Constant => 1.0,
            LoadAmplitude::Ramp => fraction.clamp(0.0, 1.0),
        }
    }

    /// The name used in case files.
    pub fn name(self) -> &'static str {
        match self {
            LoadAmplitude::Constant => "constant",
            LoadAmplitude::Ramp => "ramp",
        }
    }
}

/// Dead (position-independent) forces `f = s(λ) f̂` on nodes and on extra
/// dofs: potential `−s f̂·u`, residual `−s f̂`, no stiffness.
///
/// The explicit path accounts the work `∫ f·du`: exactly
/// `s (f̂·u − f̂·u₀)` for a constant load, by the trapezoidal rule
/// `½ (s_n + s_{n+1}) (f̂·u_{n+1} − f̂·u_n)` per increment for a ramp.
pub struct DeadLoad {
    name: String,
    /// Nodes of the model: extra dof `k` is dof `3 nodes + k`.
    model_nodes: usize,
    node_forces: Vec<(usize, Vector3<f64>)>,
    extra_forces: Vec<(usize, f64)>,
    amplitude: LoadAmplitude,
    /// Explicit work so far [N·mm] (ramped loads).
    work: f64,
    /// `(s, f̂·u)` at the last explicit increment.
    previous: Option<(f64, f64)>,
    /// `f̂·u` at the start of the explicit run.
    initial_projection: Option<f64>,
    /// The scale last written into the explicit buffer (constant forces
    /// are written once).
    written_scale: Option<f64>,
}

impl DeadLoad {
    /// Forces `node_forces` \[N\] on nodes and `extra_forces` \[N\] on extra
    /// dofs (by extra index), following `amplitude`, in a model of
    /// `model_nodes` nodes.
    pub fn new(
        name: impl Into<String>,
        model_nodes: usize,
        node_forces: Vec<(usize, Vector3<f64>)>,
        extra_forces: Vec<(usize, f64)>,
        amplitude: LoadAmplitude,
    ) -> Self {
        Self {
            name: name.into(),
            model_nodes,
            node_forces,
            extra_forces,
            amplitude,
            work: 0.0,
            previous: None,
            initial_projection: None,
            written_scale: None,
        }
    }

    /// The total force on the nodes at full load \[N\].
    pub fn total_node_force(&self) -> Vector3<f64> {
        self.node_forces.iter().map(|(_, f)| f).sum()
    }

    /// `f̂·u`: the reference forces against the displacement [N·mm].
    fn projection(&self, u: &[f64]) -> f64 {
        let nodes = self.model_nodes;
        let on_nodes: f64 = self
            .node_forces
            .iter()
            .map(|(n, f)| f.x * u[3 * n] + f.y * u[3 * n + 1] + f.z * u[3 * n + 2])
            .sum();
        let on_extras: f64 = self
            .extra_forces
            .iter()
            .map(|(k, f)| f * u[3 * nodes + k])
            .sum();
        on_nodes + on_extras
    }

    /// `−s f̂` into the stencil buffer.
    fn write(&self, scale: f64, out: &mut [f64]) {
        for (chunk, (_, f)) in out.chunks_exact_mut(4).zip(&self.node_forces) {
            chunk[0] = -scale * f.x;
            chunk[1] = -scale * f.y;
            chunk[2] = -scale * f.z;
            chunk[3] = 0.0;
        }
        let skip = 4 * self.node_forces.len();
        for (chunk, (_, f)) in out[skip..].chunks_exact_mut(4).zip(&self.extra_forces) {
            chunk[..3].fill(0.0);
            chunk[3] = -scale * f;
        }
    }
}

impl Term for DeadLoad {
    fn has_stiffness(&self) -> bool {
        false
    }

    fn name(&self) -> &str {
        &self.name
    }

    fn stencils(&self) -> Stencils {
        Stencils {
            count: self.node_forces.len() + self.extra_forces.len(),
            nodes: 1,
            extras: 1,
        }
    }

    fn stencil(&self, s: usize, nodes: &mut [usize], extras: &mut [usize]) {
        if let Some((n, _)) = self.node_forces.get(s) {
            nodes[0] = *n;
            extras[0] = NO_SLOT;
        } else {
            nodes[0] = NO_SLOT;
            extras[0] = self.extra_forces[s - self.node_forces.len()].0;
        }
    }

    fn evaluate(
        &mut self,
        state: &State,
        force: &mut [f64],
        tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        let scale = self.amplitude.factor(state.load_fraction);
        self.write(scale, force);
        if let Some(k) = tangent {
            k.fill(0.0);
        }
        Ok(-scale * self.projection(state.u))
    }

    fn explicit_forces(&mut self, state: &State, out: &mut [f64]) -> Result<(), TermFailure> {
        let scale = self.amplitude.factor(state.load_fraction);
        if self.written_scale != Some(scale) {
            self.write(scale, out);
            self.written_scale = Some(scale);
        }
        match self.amplitude {
            LoadAmplitude::Constant => {
                if self.initial_projection.is_none() {
                    self.initial_projection = Some(self.projection(state.u));
                }
            }
            LoadAmplitude::Ramp => {
                let p = self.projection(state.u);
                if let Some((s0, p0)) = self.previous {
                    self.work += 0.5 * (s0 + scale) * (p - p0);
                }
                self.previous = Some((scale, p));
            }
        }
        Ok(())
    }

    fn energy(&mut self, state: &State) -> Result<TermEnergy, TermFailure> {
        let external_work = match self.amplitude {
            LoadAmplitude::Constant => {
                let p = self.projection(state.u);
                self.initial_projection.map_or(0.0, |p0| p - p0)
            }
            LoadAmplitude::Ramp => self.work,
        };
        Ok(TermEnergy {
            external_work,
            ..Default::default()
        })
    }
}

/// The mass of a rigid body's translation dof (a floating blankholder):
/// no force, no stiffness.
pub struct RigidBodyMass {
    name: String,
    extra: usize,
    mass: f64,
}

impl RigidBodyMass {
    /// Mass `mass` \[t\] on extra dof `extra`.
    pub fn new(name: impl Into<String>, extra: usize, mass: f64) -> Self {
        Self {
            name: name.into(),
            extra,
            mass,
        }
    }
}

impl Term for RigidBodyMass {
    fn has_stiffness(&self) -> bool {
        false
    }

    fn name(&self) -> &str {
        &self.name
    }

    fn stencils(&self) -> Stencils {
        Stencils {
            count: 0,
            nodes: 0,
            extras: 1,
        }
    }

    fn stencil(&self, _s: usize, _nodes: &mut [usize], _extras: &mut [usize]) {}

    fn evaluate(
        &mut self,
        _state: &State,
        _force: &mut [f64],
        _tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        Ok(0.0)
    }

    fn lumped_masses(&self, masses: &mut Masses) -> f64 {
        masses.extra[self.extra] += self.mass;
        self.mass
    }

    fn energy(&mut self, _state: &State) -> Result<TermEnergy, TermFailure> {
        Ok(TermEnergy::default())
    }
}
