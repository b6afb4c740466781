//! The membrane force pass of a whole mesh: its triangles in fibre-basis
//! form ([`FibreTriangle`]), stored once as they are and once in batches of
//! [`LANES`] for the batched kernel. On a CPU with AVX2 (x86-64-v3,
//! detected at run time through `pulp`) [`LANES`] triangles go through the
//! law side by side, one per SIMD lane; elsewhere one at a time. Each
//! triangle's force has the same bits either way (the lanes repeat the
//! one-point arithmetic, no fused multiply-add), so results depend neither
//! on the CPU nor on the thread count.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::ElementFailureKind;
use super::fibre_triangle::{FibreTriangle, FibreTriangles, LaneStress, RovingMass};
use super::membrane::MembraneReference;
use crate::material::lanes::Real;
#[cfg(target_arch = "x86_64")]
use crate::material::lanes::x86::F64x8;
use crate::material::{Material, MaterialError};

/// Triangles per batch of the force pass: the lanes of the law (two AVX2
/// registers).
pub const LANES: usize = 8;
/// Triangles per task of the batched force pass (a multiple of [`LANES`]).
pub const CHUNK: usize = 256;

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

/// The triangles of a membrane in the form of the explicit force pass.
#[derive(Debug, Clone)]
pub struct FibreMesh {
    /// The triangles in fibre-basis form.
    pub elements: Vec<FibreTriangle>,
    /// The nodes of each triangle.
    pub nodes: Vec<[u32; 3]>,
    batches: Vec<ElementBatch>,
}

/// [`FibreMesh::chunk_forces`] on AVX2 lanes, as a `pulp` operation:
/// `with_simd` is inlined into pulp's function compiled for x86-64-v3, and
/// everything below it (all `#[inline(always)]`) with it.
#[cfg(target_arch = "x86_64")]
struct Avx2Batches<'s> {
    mesh: &'s FibreMesh,
    simd: pulp::x86::V3,
    law: &'s Material,
    u: &'s [[f64; 3]],
    batches: &'s [ElementBatch],
    out: &'s mut [[f64; 9]],
    check_inversion: bool,
}

#[cfg(target_arch = "x86_64")]
impl pulp::WithSimd for Avx2Batches<'_> {
    type Output = Option<usize>;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> Option<usize> {
        let context = F64x8::new(self.simd, [0.0; LANES]);
        self.mesh.batch_forces(
            context,
            self.law,
            self.u,
            self.batches,
            self.out,
            self.check_inversion,
        )
    }
}

impl FibreMesh {
    /// The fibre-basis form of the triangles `triangles` (node indices)
    /// set up by `references`, for a membrane of thickness `thickness`
    /// \[mm\].
    pub fn new(references: &[MembraneReference], triangles: &[[usize; 3]], thickness: f64) -> Self {
        let elements: Vec<FibreTriangle> = references
            .iter()
            .map(|r| FibreTriangle::new(r, thickness))
            .collect();
        let nodes: Vec<[u32; 3]> = triangles.iter().map(|t| t.map(|n| n as u32)).collect();
        let batches = (0..elements.len().div_ceil(LANES))
            .map(|b| {
                let element = |l: usize| (b * LANES + l).min(elements.len() - 1);
                ElementBatch {
                    triangles: FibreTriangles::from_fn(|l| elements[element(l)]),
                    nodes: std::array::from_fn(|a| std::array::from_fn(|l| nodes[element(l)][a])),
                }
            })
            .collect();
        Self {
            elements,
            nodes,
            batches,
        }
    }

    /// The displacements of the nodes of triangle `e` from `u` (3 per node).
    #[inline(always)]
    pub fn displacements(&self, e: usize, u: &[f64]) -> [[f64; 3]; 3] {
        self.nodes[e].map(|n| {
            let n = n as usize;
            [u[3 * n], u[3 * n + 1], u[3 * n + 2]]
        })
    }

    /// The internal force of every triangle at `u` into `forces` (9 per
    /// triangle, node-major), in parallel: each task writes only its own
    /// triangles, [`LANES`] at a time where the CPU allows. `u` may be
    /// longer than the nodes' dofs (extra dofs follow them).
    ///
    /// # Errors
    /// The lowest index of the failing triangles (the forces are then
    /// unspecified); [`FibreMesh::failure`] says why.
    pub fn forces(
        &self,
        law: &Material,
        u: &[f64],
        forces: &mut [[f64; 9]],
        check_inversion: bool,
    ) -> Result<(), usize> {
        let first_failure = AtomicUsize::new(usize::MAX);
        let (nodes_u, _) = u.as_chunks::<3>();
        forces
            .par_chunks_mut(CHUNK)
            .zip(self.batches.par_chunks(CHUNK / LANES))
            .enumerate()
            .for_each(|(chunk, (out, batches))| {
                let first = chunk * CHUNK;
                if let Some(e) =
                    self.chunk_forces(law, nodes_u, batches, first, out, check_inversion)
                {
                    first_failure.fetch_min(e, Ordering::Relaxed);
                }
            });
        match first_failure.into_inner() {
            usize::MAX => Ok(()),
            e => Err(e),
        }
    }

    /// Why triangle `e` fails at `u`, if it does (serial, for messages).
    pub fn failure(
        &self,
        e: usize,
        law: &Material,
        u: &[f64],
        check_inversion: bool,
    ) -> Option<ElementFailureKind> {
        match self.elements[e].internal_force(&self.displacements(e, u), law) {
            Err(err) => Some(ElementFailureKind::Material(err)),
            Ok(f) if check_inversion && f.orientation <= 0.0 => {
                Some(ElementFailureKind::Inverted {
                    orientation: f.orientation,
                })
            }
            Ok(_) => None,
        }
    }

    /// The forces of the triangles `first..first + out.len()` (the
    /// triangles of `batches`) into `out`; the first failing triangle, if
    /// any.
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))]
    fn chunk_forces(
        &self,
        law: &Material,
        u: &[[f64; 3]],
        batches: &[ElementBatch],
        first: usize,
        out: &mut [[f64; 9]],
        check_inversion: bool,
    ) -> Option<usize> {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            let pass = Avx2Batches {
                mesh: self,
                simd,
                law,
                u,
                batches,
                out,
                check_inversion,
            };
            return <pulp::x86::V3 as pulp::Simd>::vectorize(simd, pass)
                .map(|offset| first + offset);
        }
        self.forces_one_by_one(law, u, first, out, check_inversion)
    }

    /// `FibreMesh::chunk_forces` one triangle at a time (any CPU).
    pub fn forces_one_by_one(
        &self,
        law: &Material,
        u: &[[f64; 3]],
        first: usize,
        out: &mut [[f64; 9]],
        check_inversion: bool,
    ) -> Option<usize> {
        for (i, out) in out.iter_mut().enumerate() {
            let e = first + i;
            let ue = self.displacements(e, u.as_flattened());
            match self.elements[e].internal_force(&ue, law) {
                Ok(f) if !check_inversion || f.orientation > 0.0 => *out = f.force,
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
        law: &Material,
        u: &[[f64; 3]],
        batches: &[ElementBatch],
        out: &mut [[f64; 9]],
        check_inversion: bool,
    ) -> Option<usize>
    where
        Material: LaneStress<V>,
    {
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
            if check_inversion {
                accepted = accepted & f.orientation.gt(zero);
            }
            let rejected = !V::bits(accepted) & ((1 << out.len()) - 1);
            if rejected != 0 {
                return Some(b * LANES + rejected.trailing_zeros() as usize);
            }
        }
        None
    }

    /// The bound of `ω²` of triangle `e` at `u` with density `density`
    /// [t/mm³], with the roving mass `roving` if given
    /// ([`FibreTriangle::max_frequency_squared_with`]).
    ///
    /// # Errors
    /// When the law rejects the state.
    pub fn frequency(
        &self,
        e: usize,
        law: &Material,
        u: &[f64],
        density: f64,
        roving: Option<RovingMass>,
    ) -> Result<f64, MaterialError> {
        self.elements[e].max_frequency_squared_with(&self.displacements(e, u), law, density, roving)
    }

    /// Strain energy `t A0 W` of triangle `e` at `u` [N·mm].
    ///
    /// # Errors
    /// When the law rejects the state.
    pub fn strain_energy(&self, e: usize, law: &Material, u: &[f64]) -> Result<f64, MaterialError> {
        self.elements[e].strain_energy(&self.displacements(e, u), law)
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
    use crate::model::MembraneModel;

    /// A 15 × 30 mm strip of 13 × 25 cells (650 triangles: 82 batches, the
    /// last one padded), sheared and perturbed at random, so that triangles
    /// sit on different branches of the law side by side.
    fn strip(seed: u64) -> (MembraneModel, Vec<f64>) {
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
        (model, u)
    }

    /// Requirement: the batched force pass gives every triangle the bits of
    /// the one-triangle kernel, and both name the same failing triangle.
    #[test]
    fn batched_pass_repeats_the_one_by_one_pass_bit_for_bit() {
        for seed in 0..4 {
            let (model, mut u) = strip(seed);
            let mesh = FibreMesh::new(&model.references, &model.triangles, model.thickness);
            let law = &model.material;
            let n = model.triangles.len();
            let (nodes_u, _) = u.as_chunks::<3>();
            let mut one_by_one = vec![[0.0; 9]; n];
            assert_eq!(
                mesh.forces_one_by_one(law, nodes_u, 0, &mut one_by_one, true),
                None
            );
            let mut batched = vec![[f64::NAN; 9]; n];
            mesh.forces(law, &u, &mut batched, true).expect("forces");
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
            let failure = mesh
                .forces(law, &u, &mut batched, true)
                .expect_err("inverted");
            let (nodes_u, _) = u.as_chunks::<3>();
            assert_eq!(
                mesh.forces_one_by_one(law, nodes_u, 0, &mut one_by_one, true),
                Some(failure)
            );
            assert!(matches!(
                mesh.failure(failure, law, &u, true),
                Some(ElementFailureKind::Inverted { .. })
            ));
        }
    }
}
