//! The membrane term of a ply: three-node total-Lagrangian triangles with
//! one law, thickness and fibre field (`docs/solver.md`). The quasi-static
//! path evaluates [`MembraneReference::force_tangent`] per triangle; the
//! explicit path the fibre-basis force pass of [`FibreMesh`] (batched where
//! the CPU allows), the element frequency bound and lumped masses
//! `ρ t A0 / 3`, with optional mass scaling.

use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::Vector3;
use rayon::prelude::*;

use super::term::{
    FrequencyBound, MassCoupling, MassScaling, Masses, State, Stencils, Term, TermEnergy,
    TermFailure,
};
use crate::element::membrane::ReferenceError;
use crate::element::{
    ElementFailureKind, FibreMesh, MembraneReference, RovingCoupling, RovingMass,
};
use crate::material::Material;

/// Smallest run of elements one rayon task takes in the element loops.
const ELEMENT_MIN_LEN: usize = 512;

/// Reference configuration and constitutive data of a membrane.
#[derive(Debug, Clone)]
pub struct MembraneModel {
    /// Reference node positions \[mm\] (all nodes of the model; the
    /// triangles index them).
    pub nodes: Vec<Vector3<f64>>,
    /// Triangles (node indices).
    pub triangles: Vec<[usize; 3]>,
    /// Reference data per triangle.
    pub references: Vec<MembraneReference>,
    /// The law.
    pub material: Material,
    /// Membrane thickness `t` \[mm\].
    pub thickness: f64,
}

impl MembraneModel {
    /// Sets up every triangle; `fibres` has one global direction per triangle.
    ///
    /// # Errors
    /// The first triangle that cannot be set up, with its index.
    pub fn new(
        nodes: Vec<Vector3<f64>>,
        triangles: Vec<[usize; 3]>,
        fibres: &[Vector3<f64>],
        material: Material,
        thickness: f64,
    ) -> Result<Self, (usize, ReferenceError)> {
        let references = triangles
            .iter()
            .zip(fibres)
            .enumerate()
            .map(|(e, (t, f))| {
                MembraneReference::new(&[nodes[t[0]], nodes[t[1]], nodes[t[2]]], f)
                    .map_err(|err| (e, err))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            nodes,
            triangles,
            references,
            material,
            thickness,
        })
    }

    /// Nodal displacements of triangle `e` from the global displacement `u`
    /// (3 per node) \[mm\].
    #[inline]
    pub fn element_displacements(&self, e: usize, u: &[f64]) -> [Vector3<f64>; 3] {
        let t = self.triangles[e];
        std::array::from_fn(|a| {
            let n = t[a];
            Vector3::new(u[3 * n], u[3 * n + 1], u[3 * n + 2])
        })
    }
}

/// How a membrane term is set up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneOptions {
    /// Reject triangles that turn over in their plane (for planar models,
    /// such as the off-axis tension test).
    pub check_inversion: bool,
    /// Mass density `ρ` [t/mm³] for the explicit path (areal mass /
    /// thickness); `None` for a quasi-static-only model.
    pub density: Option<f64>,
    /// Roving mass scaling length `ℓ` \[mm\] for the explicit path (0:
    /// off): every triangle adds `κ = 3 (ℓ/L)²` times its lumped node share
    /// as a coupling mass on its edge along the rovings, `L` that edge's
    /// length ([`crate::element::RovingMass`], `docs/explicit.md`, "Roving
    /// mass scaling"): a mode of wavelength `λ` along the rovings gains
    /// about `(2πℓ/λ)²` of its mass, whatever the mesh.
    pub roving_mass_length: f64,
    /// Which relative motion the roving masses weigh on: the stretch rate
    /// along the rovings (default) or every component.
    pub roving_mass_coupling: RovingCoupling,
}

/// The membrane of one ply as a force term.
pub struct MembraneTerm {
    name: String,
    /// The membrane.
    pub membrane: MembraneModel,
    options: MembraneOptions,
    fibre: FibreMesh,
    /// Density of each element after mass scaling [t/mm³] (empty without a
    /// density).
    element_density: Vec<f64>,
    /// Per-element energies, summed in element order.
    energies: Vec<f64>,
    /// Per element, its roving mass (edge along the rovings and `κ`),
    /// when roving mass scaling is on (empty otherwise; `None` for a
    /// triangle without such an edge, refused by `validate_explicit`).
    roving_masses: Vec<Option<RovingMass>>,
}

impl MembraneTerm {
    /// The term named `name` ("membrane", "membrane of ply 2") for
    /// `membrane`.
    pub fn new(name: impl Into<String>, membrane: MembraneModel, options: MembraneOptions) -> Self {
        let fibre = FibreMesh::new(
            &membrane.references,
            &membrane.triangles,
            membrane.thickness,
        );
        let n = membrane.triangles.len();
        let length = options.roving_mass_length;
        let roving_masses = if length > 0.0 {
            fibre
                .elements
                .iter()
                .map(|el| {
                    el.roving_edge().map(|edge| {
                        // ∂N/∂a0 = ±1/L at the edge's nodes.
                        let inverse_length = el.grad[edge[0]][0];
                        RovingMass {
                            edge,
                            ratio: 3.0 * length * length * inverse_length * inverse_length,
                            coupling: options.roving_mass_coupling,
                        }
                    })
                })
                .collect()
        } else {
            Vec::new()
        };
        Self {
            roving_masses,
            name: name.into(),
            element_density: options.density.map_or_else(Vec::new, |rho| vec![rho; n]),
            options,
            fibre,
            membrane,
            energies: vec![0.0; n],
        }
    }

    /// The roving mass of element `e` (`None` without roving mass scaling).
    #[inline]
    fn roving_mass(&self, e: usize) -> Option<RovingMass> {
        *self.roving_masses.get(e)?
    }

    /// The options the term was built with.
    pub fn options(&self) -> MembraneOptions {
        self.options
    }

    /// Density of each element after mass scaling [t/mm³].
    pub fn element_density(&self) -> &[f64] {
        &self.element_density
    }

    fn failure(&self, element: usize, kind: ElementFailureKind) -> TermFailure {
        self.failure_reason(element, kind.to_string())
    }

    fn failure_reason(&self, element: usize, reason: String) -> TermFailure {
        TermFailure {
            term: self.name.clone(),
            what: "element",
            index: element,
            reason,
        }
    }

    /// The failure of the explicit kernels at element `e`, recomputed
    /// serially for its message.
    fn explicit_failure(&self, e: usize, u: &[f64]) -> TermFailure {
        let kind = self
            .fibre
            .failure(e, &self.membrane.material, u, self.options.check_inversion)
            .unwrap_or(ElementFailureKind::Material(
                crate::material::MaterialError::NonFiniteResponse,
            ));
        self.failure(e, kind)
    }

    fn density_or_error(&self) -> Result<(), TermFailure> {
        let fail = |reason: String| TermFailure {
            term: self.name.clone(),
            what: "ply",
            index: 0,
            reason,
        };
        match self.options.density {
            None => Err(fail(
                "no mass density given (the explicit solver needs the areal mass)".into(),
            )),
            Some(rho) if !(rho.is_finite() && rho > 0.0) => Err(fail(format!(
                "density = {rho}: expected a finite number > 0 [t/mm³]"
            ))),
            Some(_) => Ok(()),
        }
    }

    /// Per element, the bound of `ω²` of
    /// [`crate::element::FibreTriangle::max_frequency_squared`] at `u` with
    /// the element's (scaled) density.
    ///
    /// # Errors
    /// The lowest-index failing element.
    pub fn element_frequencies(&self, u: &[f64]) -> Result<Vec<f64>, TermFailure> {
        self.density_or_error()?;
        let law = &self.membrane.material;
        let frequencies: Vec<f64> = (0..self.fibre.elements.len())
            .into_par_iter()
            .with_min_len(ELEMENT_MIN_LEN)
            .map(|e| {
                self.fibre
                    .frequency(e, law, u, self.element_density[e], self.roving_mass(e))
                    .unwrap_or(f64::INFINITY)
            })
            .collect();
        if frequencies.iter().all(|w2| w2.is_finite()) {
            Ok(frequencies)
        } else {
            Err(self.frequency_failure(u))
        }
    }

    /// The lowest-index triangle whose frequency bound fails at `u`
    /// (serial; called only after a parallel pass found one).
    fn frequency_failure(&self, u: &[f64]) -> TermFailure {
        let law = &self.membrane.material;
        let found = (0..self.fibre.elements.len()).find_map(|e| {
            match self.fibre.frequency(e, law, u, self.element_density[e], self.roving_mass(e)) {
                Ok(w2) if w2.is_finite() => None,
                Ok(_) => Some(self.failure_reason(
                    e,
                    format!(
                        "its highest frequency overflows (density {:e} t/mm³ against its stiffness): the stable time step would be zero; expected a realistic areal mass and stiffness",
                        self.element_density[e]
                    ),
                )),
                Err(err) => Some(self.failure(e, ElementFailureKind::Material(err))),
            }
        });
        found.unwrap_or_else(|| {
            self.failure(
                0,
                ElementFailureKind::Material(crate::material::MaterialError::NonFiniteResponse),
            )
        })
    }
}

impl Term for MembraneTerm {
    fn name(&self) -> &str {
        &self.name
    }

    fn stencils(&self) -> Stencils {
        Stencils {
            count: self.membrane.triangles.len(),
            nodes: 3,
            extras: 0,
        }
    }

    fn stencil(&self, s: usize, nodes: &mut [usize], _extras: &mut [usize]) {
        nodes.copy_from_slice(&self.membrane.triangles[s]);
    }

    /// Energy `Σ t A0 W`, forces `t A0 B_aᵀ S` and tangents
    /// `t A0 (B_aᵀ ℂ B_b + (∇N_a · S ∇N_b) I3)` per triangle, in parallel
    /// (`docs/solver.md`).
    fn evaluate(
        &mut self,
        state: &State,
        force: &mut [f64],
        tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        let model = &self.membrane;
        let check_inversion = self.options.check_inversion;
        let first_failure = AtomicUsize::new(usize::MAX);
        let u = state.u;
        let run = |e: usize, energy: &mut f64, f: &mut [f64], k: Option<&mut [f64]>| {
            let x = model.element_displacements(e, u);
            let reference = &model.references[e];
            let result = match k {
                Some(k) => reference
                    .force_tangent(&x, &model.material, model.thickness)
                    .map(|t| {
                        k.copy_from_slice(t.stiffness.as_slice());
                        (t.kinematics, t.state, t.force)
                    }),
                None => reference.force(&x, &model.material, model.thickness),
            };
            match result {
                Ok((kin, _, _)) if check_inversion && kin.orientation <= 0.0 => {
                    first_failure.fetch_min(e, Ordering::Relaxed);
                }
                Ok((_, state, fe)) => {
                    *energy = model.thickness * reference.area * state.energy;
                    f.copy_from_slice(fe.as_slice());
                }
                Err(_) => {
                    first_failure.fetch_min(e, Ordering::Relaxed);
                }
            }
        };
        match tangent {
            Some(tangent) => self
                .energies
                .par_iter_mut()
                .zip(force.par_chunks_mut(9))
                .zip(tangent.par_chunks_mut(81))
                .enumerate()
                .for_each(|(e, ((w, f), k))| run(e, w, f, Some(k))),
            None => self
                .energies
                .par_iter_mut()
                .zip(force.par_chunks_mut(9))
                .enumerate()
                .for_each(|(e, (w, f))| run(e, w, f, None)),
        }
        match first_failure.into_inner() {
            usize::MAX => Ok(self.energies.iter().sum()),
            e => {
                let x = model.element_displacements(e, u);
                let kind = match model.references[e].force(&x, &model.material, model.thickness) {
                    Err(err) => ElementFailureKind::Material(err),
                    Ok((kin, _, _)) => ElementFailureKind::Inverted {
                        orientation: kin.orientation,
                    },
                };
                Err(self.failure(e, kind))
            }
        }
    }

    /// `ρ_e t A0 / 3` at each node of every triangle, in element order;
    /// returns the physical (unscaled) mass.
    fn lumped_masses(&self, masses: &mut Masses) -> f64 {
        let Some(rho) = self.options.density else {
            return 0.0;
        };
        let mut physical = 0.0;
        for (e, el) in self.fibre.elements.iter().enumerate() {
            let m = self.element_density[e] * el.volume;
            physical += rho * el.volume;
            for &n in &self.fibre.nodes[e] {
                masses.node[n as usize] += m / 3.0;
            }
        }
        physical
    }

    /// Elements whose `safety × 2/ω_e` at the state is below `target` get
    /// `ρ_e (target / (safety × 2/ω_e))²` (`docs/explicit.md`).
    fn scale_masses(
        &mut self,
        state: &State,
        target: f64,
        safety: f64,
    ) -> Result<MassScaling, TermFailure> {
        let omega2 = self.element_frequencies(state.u)?;
        let mut scaled_elements = 0;
        for (rho, w2) in self.element_density.iter_mut().zip(omega2) {
            // ω² ∝ 1/ρ: scaling ρ by s² scales the stable step by s.
            let stable = safety * 2.0 / w2.sqrt();
            if w2 > 0.0 && stable < target {
                *rho *= (target / stable).powi(2);
                scaled_elements += 1;
            }
        }
        let rho = self.options.density.unwrap_or(0.0);
        let (physical, total) = self
            .fibre
            .elements
            .iter()
            .zip(&self.element_density)
            .fold((0.0, 0.0), |(p, t), (el, r)| {
                (p + rho * el.volume, t + r * el.volume)
            });
        Ok(MassScaling {
            physical,
            added: total - physical,
            scaled_elements,
        })
    }

    /// The density, and with roving mass scaling an edge along the
    /// rovings in every triangle.
    fn validate_explicit(&self) -> Result<(), TermFailure> {
        self.density_or_error()?;
        let length = self.options.roving_mass_length;
        if !(length.is_finite() && length >= 0.0) {
            return Err(self.failure_reason(
                0,
                format!("roving mass length {length}: expected a finite length ≥ 0 mm"),
            ));
        }
        if let Some(e) = self.roving_masses.iter().position(Option::is_none) {
            return Err(self.failure_reason(
                e,
                "no edge of this triangle runs along the rovings: roving mass scaling needs a mesh with an edge of every triangle along them (the generators' aligned patterns; docs/explicit.md)".into(),
            ));
        }
        Ok(())
    }

    /// Per triangle with a roving edge, `κ_e ρ_e t A0 / 3` on that edge.
    fn mass_couplings(&self, out: &mut Vec<MassCoupling>) {
        for (e, roving) in self.roving_masses.iter().enumerate() {
            if let Some(RovingMass {
                edge: [i, j],
                ratio,
                coupling,
            }) = roving
            {
                let nodes = &self.fibre.nodes[e];
                let (a, b) = (nodes[*i] as usize, nodes[*j] as usize);
                let stretch = match coupling {
                    RovingCoupling::Stretch => {
                        let edge = self.membrane.nodes[b] - self.membrane.nodes[a];
                        Some([edge.x, edge.y, edge.z])
                    }
                    RovingCoupling::Full => None,
                };
                out.push(MassCoupling {
                    nodes: [a, b],
                    mass: ratio * self.element_density[e] * self.fibre.elements[e].volume / 3.0,
                    stretch,
                });
            }
        }
    }

    /// The batched fibre-basis force pass ([`FibreMesh::forces`]).
    fn explicit_forces(&mut self, state: &State, out: &mut [f64]) -> Result<(), TermFailure> {
        let (forces, _) = out.as_chunks_mut::<9>();
        self.fibre
            .forces(
                &self.membrane.material,
                state.u,
                forces,
                self.options.check_inversion,
            )
            .map_err(|e| self.explicit_failure(e, state.u))
    }

    /// `max_e ω_e²` with the element's own lumped mass share: a bound of
    /// `λmax(M⁻¹K)` of the assembled membrane, since the node masses are
    /// the sums of the element shares (`docs/explicit.md`).
    fn frequency_bound(
        &self,
        state: &State,
        _masses: &Masses,
    ) -> Result<FrequencyBound, TermFailure> {
        self.density_or_error()?;
        let law = &self.membrane.material;
        // A failing element maps to +∞, which no state reaches otherwise.
        let max = (0..self.fibre.elements.len())
            .into_par_iter()
            .with_min_len(ELEMENT_MIN_LEN)
            .map(|e| {
                self.fibre
                    .frequency(
                        e,
                        law,
                        state.u,
                        self.element_density[e],
                        self.roving_mass(e),
                    )
                    .unwrap_or(f64::INFINITY)
            })
            .reduce(|| 0.0, f64::max);
        if max.is_finite() {
            Ok(FrequencyBound::nodes(max))
        } else {
            Err(self.frequency_failure(state.u))
        }
    }

    /// The strain energy `Σ t A0 W`, summed in element order.
    fn energy(&mut self, state: &State) -> Result<TermEnergy, TermFailure> {
        let first_failure = AtomicUsize::new(usize::MAX);
        let law = &self.membrane.material;
        let fibre = &self.fibre;
        self.energies
            .par_iter_mut()
            .with_min_len(ELEMENT_MIN_LEN)
            .enumerate()
            .for_each(|(e, out)| match fibre.strain_energy(e, law, state.u) {
                Ok(w) => *out = w,
                Err(_) => {
                    first_failure.fetch_min(e, Ordering::Relaxed);
                }
            });
        match first_failure.into_inner() {
            usize::MAX => Ok(TermEnergy {
                internal: self.energies.iter().sum(),
                ..Default::default()
            }),
            e => Err(self.explicit_failure(e, state.u)),
        }
    }
}
