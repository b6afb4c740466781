//! The three-node membrane triangle in 3D, total Lagrangian.
//!
//! Each triangle carries an orthonormal reference basis `(e1, e2)` in its
//! plane, the gradients `∇N_a` of its linear shape functions in that basis,
//! its reference area `A0` and its fibre frame. The deformation gradient
//! `F = Σ_a x_a ⊗ ∇N_a = [e1 e2] + Σ_a u_a ⊗ ∇N_a` (3×2) has columns
//! `g1 = F E1`, `g2 = F E2`; `C = FᵀF` (2×2) goes to the law. The kernels
//! take nodal *displacements* `u_a`: building `F` from them avoids the
//! cancellation of `Σ x_a ⊗ ∇N_a` at large coordinates.
//!
//! With `B_a` the map from the nodal displacement `δx_a` to the engineering
//! strain `[δE11, δE22, 2δE12]`:
//!
//! ```text
//! B_a = [ N_a,1 g1ᵀ ; N_a,2 g2ᵀ ; N_a,2 g1ᵀ + N_a,1 g2ᵀ ]      (3×3)
//! f_a = t A0 B_aᵀ S                                          (internal force)
//! K_ab = t A0 ( B_aᵀ ℂ B_b + (∇N_a · S ∇N_b) I3 )             (material + geometric)
//! ```
//!
//! with `S = [S11, S22, S12]` and `ℂ` in the Voigt storage of
//! [`crate::material::Tangent`]. See `docs/solver.md`.

use nalgebra::{Matrix3, SMatrix, SVector, Vector2, Vector3};

use crate::material::{FibreFrame, MaterialError, MembraneMaterial, StressState, Sym2};

/// Element stiffness (9×9, node-major: `[x0, y0, z0, x1, …]`).
pub type ElementMatrix = SMatrix<f64, 9, 9>;
/// Element force vector (node-major).
pub type ElementVector = SVector<f64, 9>;

/// Why a triangle cannot be set up.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    /// Zero or negative reference area (collinear or repeated nodes).
    #[error("degenerate triangle: reference area {area:e} mm² is not positive")]
    Degenerate {
        /// The reference area \[mm²\].
        area: f64,
    },
    /// The fibre direction has no component in the triangle's plane.
    #[error("the fibre direction is perpendicular to the triangle")]
    FibreOutOfPlane,
}

/// Reference data of one membrane triangle, computed once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneReference {
    /// Shape-function gradients `∇N_a` in the reference basis [1/mm].
    pub grad: [Vector2<f64>; 3],
    /// Reference area `A0` \[mm²\].
    pub area: f64,
    /// First in-plane reference basis vector (global coordinates).
    pub e1: Vector3<f64>,
    /// Second in-plane reference basis vector (global coordinates).
    pub e2: Vector3<f64>,
    /// Unit reference normal `e1 × e2`.
    pub normal: Vector3<f64>,
    /// Fibre frame in the reference basis.
    pub frame: FibreFrame,
}

impl MembraneReference {
    /// Sets up a triangle from its reference node positions \[mm\] and a fibre
    /// direction (global, projected on the triangle's plane).
    ///
    /// # Errors
    /// A degenerate triangle or a fibre perpendicular to it.
    pub fn new(x: &[Vector3<f64>; 3], fibre: &Vector3<f64>) -> Result<Self, ReferenceError> {
        let edge1 = x[1] - x[0];
        let edge2 = x[2] - x[0];
        let cross = edge1.cross(&edge2);
        let double_area = cross.norm();
        let scale = edge1.norm_squared().max(edge2.norm_squared());
        if double_area.is_nan() || double_area <= 1e-12 * scale || !double_area.is_finite() {
            return Err(ReferenceError::Degenerate {
                area: 0.5 * double_area,
            });
        }
        let normal = cross / double_area;
        let e1 = edge1 / edge1.norm();
        let e2 = normal.cross(&e1);
        // Local coordinates of the nodes: node 0 at the origin.
        let p1 = Vector2::new(edge1.dot(&e1), edge1.dot(&e2));
        let p2 = Vector2::new(edge2.dot(&e1), edge2.dot(&e2));
        let det = p1.x * p2.y - p2.x * p1.y; // 2 A0 > 0 by construction
        let grad = [
            Vector2::new(p1.y - p2.y, p2.x - p1.x) / det,
            Vector2::new(p2.y, -p2.x) / det,
            Vector2::new(-p1.y, p1.x) / det,
        ];
        let local = Vector2::new(fibre.dot(&e1), fibre.dot(&e2));
        if local.norm().is_nan() || local.norm() <= 1e-6 * fibre.norm() {
            return Err(ReferenceError::FibreOutOfPlane);
        }
        let frame = FibreFrame::from_direction(local).ok_or(ReferenceError::FibreOutOfPlane)?;
        Ok(Self {
            grad,
            area: 0.5 * det,
            e1,
            e2,
            normal,
            frame,
        })
    }

    /// `g1 = F E1`, `g2 = F E2` (the columns of `F`) for the nodal
    /// displacements `u` \[mm\].
    #[inline]
    pub fn deformation(&self, u: &[Vector3<f64>; 3]) -> [Vector3<f64>; 2] {
        let mut g1 = self.e1;
        let mut g2 = self.e2;
        for (ua, grad) in u.iter().zip(&self.grad) {
            g1 += ua * grad.x;
            g2 += ua * grad.y;
        }
        [g1, g2]
    }

    /// The kinematics for the nodal displacements `u` \[mm\].
    #[inline]
    pub fn kinematics(&self, u: &[Vector3<f64>; 3]) -> MembraneKinematics {
        let [g1, g2] = self.deformation(u);
        let c = Sym2::new(g1.dot(&g1), g2.dot(&g2), g1.dot(&g2));
        // Signed area ratio: the deformed area vector on the reference normal.
        let orientation = g1.cross(&g2).dot(&self.normal);
        MembraneKinematics {
            g: [g1, g2],
            c,
            orientation,
        }
    }

    #[inline]
    fn b_matrix(&self, a: usize, g: &[Vector3<f64>; 2]) -> Matrix3<f64> {
        let (n1, n2) = (self.grad[a].x, self.grad[a].y);
        Matrix3::from_rows(&[
            (g[0] * n1).transpose(),
            (g[1] * n2).transpose(),
            (g[0] * n2 + g[1] * n1).transpose(),
        ])
    }

    /// Energy, stress and internal force `f_a = t A0 B_aᵀ S` for the nodal
    /// displacements `u` \[mm\].
    ///
    /// # Errors
    /// When the law rejects the state (collapsed element, …).
    #[inline]
    pub fn force<M: MembraneMaterial + ?Sized>(
        &self,
        u: &[Vector3<f64>; 3],
        material: &M,
        thickness: f64,
    ) -> Result<(MembraneKinematics, StressState, ElementVector), MaterialError> {
        let kin = self.kinematics(u);
        let state = material.stress(&kin.c, &self.frame)?;
        let force = self.stress_force(&kin.g, &state.stress, thickness);
        Ok((kin, state, force))
    }

    /// The nodal forces `f_a = t A0 B_aᵀ s` of a stress-like `s` (in
    /// [`Sym2`] storage, reference basis) at the deformation `g` (the
    /// columns of `F`): the internal force for `s = S`, its derivative
    /// with respect to a law parameter at fixed `u` for `s = ∂S/∂p`.
    #[inline]
    pub fn stress_force(&self, g: &[Vector3<f64>; 2], s: &Sym2, thickness: f64) -> ElementVector {
        let scale = thickness * self.area;
        let mut force = ElementVector::zeros();
        for a in 0..3 {
            let fa = scale * self.b_matrix(a, g).transpose() * s;
            force.fixed_rows_mut::<3>(3 * a).copy_from(&fa);
        }
        force
    }

    /// `dg_i = Σ_a du_a ∂N_a/∂X_i`: the change of the columns of `F` for
    /// a change `du` of the nodal displacements (`F` is linear in `u`).
    #[inline]
    pub fn deformation_change(&self, du: &[Vector3<f64>; 3]) -> [Vector3<f64>; 2] {
        let mut dg = [Vector3::zeros(); 2];
        for (d, grad) in du.iter().zip(&self.grad) {
            dg[0] += d * grad.x;
            dg[1] += d * grad.y;
        }
        dg
    }

    /// Energy, stress, internal force and consistent tangent
    /// `K_ab = t A0 (B_aᵀ ℂ B_b + (∇N_a · S ∇N_b) I3)` for the nodal
    /// displacements `u` \[mm\].
    ///
    /// # Errors
    /// When the law rejects the state.
    #[inline]
    pub fn force_tangent<M: MembraneMaterial + ?Sized>(
        &self,
        u: &[Vector3<f64>; 3],
        material: &M,
        thickness: f64,
    ) -> Result<MembraneTangent, MaterialError> {
        let kin = self.kinematics(u);
        let (state, tangent) = material.stress_tangent(&kin.c, &self.frame)?;
        let scale = thickness * self.area;
        let s = &state.stress;
        let b = [
            self.b_matrix(0, &kin.g),
            self.b_matrix(1, &kin.g),
            self.b_matrix(2, &kin.g),
        ];
        let mut force = ElementVector::zeros();
        let mut stiffness = ElementMatrix::zeros();
        for a in 0..3 {
            let bt = b[a].transpose();
            force
                .fixed_rows_mut::<3>(3 * a)
                .copy_from(&(scale * bt * s));
            let bt_c = bt * tangent;
            let ga = self.grad[a];
            // S ∇N_a with S as the 2×2 tensor [[S11, S12], [S12, S22]].
            let s_ga = Vector2::new(s[0] * ga.x + s[2] * ga.y, s[2] * ga.x + s[1] * ga.y);
            for (bb, (b_b, grad_b)) in b.iter().zip(&self.grad).enumerate() {
                let geometric = s_ga.dot(grad_b);
                let mut kab = bt_c * b_b;
                for d in 0..3 {
                    kab[(d, d)] += geometric;
                }
                stiffness
                    .fixed_view_mut::<3, 3>(3 * a, 3 * bb)
                    .copy_from(&(scale * kab));
            }
        }
        Ok(MembraneTangent {
            kinematics: kin,
            state,
            force,
            stiffness,
        })
    }
}

/// Deformation of a triangle at its current node positions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneKinematics {
    /// Columns of `F`: `g1 = F E1`, `g2 = F E2`.
    pub g: [Vector3<f64>; 2],
    /// `C = FᵀF` in [`Sym2`] storage, in the reference basis.
    pub c: Sym2,
    /// `(g1 × g2) · N0`: the deformed-to-reference area ratio, negative when
    /// the triangle has turned over relative to its reference normal.
    pub orientation: f64,
}

/// Force and consistent tangent of one triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneTangent {
    /// The kinematics.
    pub kinematics: MembraneKinematics,
    /// Energy density and stress.
    pub state: StressState,
    /// Internal force `f` \[N\], node-major.
    pub force: ElementVector,
    /// Tangent `K = ∂f/∂x` [N/mm], node-major, symmetric.
    pub stiffness: ElementMatrix,
}
