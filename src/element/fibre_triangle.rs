//! The membrane triangle of the explicit solver: the same total-Lagrangian
//! element as [`super::membrane`], stored compactly in the *fibre basis*.
//!
//! The reference basis of each triangle is turned so that `E1 = a0` (the
//! rovings) and `E2 = b0` (the stitching). Then `C = FᵀF` holds the
//! pseudo-invariants directly, `C = [I4, I8, I6]` (Eq. 3–5), the law needs no
//! frame, and a triangle is 16 numbers: the shape-function gradients in that
//! basis, the two basis vectors, the reference normal and `t A0`. The force
//! pass streams through these once per time step.
//!
//! With `g1 = F E1`, `g2 = F E2` and `S` in the fibre basis, the internal
//! force of node `a` is
//!
//! ```text
//! f_a = t A0 (N_a,1 P1 + N_a,2 P2),   P1 = S11 g1 + S12 g2,   P2 = S12 g1 + S22 g2
//! ```
//!
//! the same `t A0 B_aᵀ S` as [`super::membrane`], written without `B`.

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

use super::membrane::MembraneReference;
use crate::material::{FibreFrame, MaterialError, MembraneMaterial, Sym2};

/// One triangle in its fibre basis (reference data for the explicit solver).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FibreTriangle {
    /// `∇N_a` in the fibre basis `(a0, b0)` [1/mm].
    pub grad: [[f64; 2]; 3],
    /// `a0` in global coordinates (the first basis vector).
    pub e1: [f64; 3],
    /// `b0` in global coordinates (the second basis vector).
    pub e2: [f64; 3],
    /// The unit reference normal `a0 × b0`.
    pub normal: [f64; 3],
    /// `t A0` [mm³]: thickness times reference area.
    pub volume: f64,
}

/// Internal force of one triangle with its kinematic by-product.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FibreTriangleForce {
    /// `f_a` node-major `[x0, y0, z0, x1, …]` [N].
    pub force: [f64; 9],
    /// `(g1 × g2) · N0`: the area ratio, negative for a turned-over triangle.
    pub orientation: f64,
}

impl FibreTriangle {
    /// The fibre-basis form of a triangle set up by [`MembraneReference`],
    /// for a membrane of thickness `thickness` [mm].
    pub fn new(reference: &MembraneReference, thickness: f64) -> Self {
        let a0 = reference.frame.a0;
        let b0 = reference.frame.b0;
        let e1 = reference.e1 * a0.x + reference.e2 * a0.y;
        let e2 = reference.e1 * b0.x + reference.e2 * b0.y;
        let grad = reference.grad.map(|g| [g.dot(&a0), g.dot(&b0)]);
        Self {
            grad,
            e1: e1.into(),
            e2: e2.into(),
            normal: reference.normal.into(),
            volume: thickness * reference.area,
        }
    }

    /// `g1 = F a0`, `g2 = F b0` for the nodal displacements `u` [mm].
    #[inline(always)]
    pub fn deformation(&self, u: &[[f64; 3]; 3]) -> ([f64; 3], [f64; 3]) {
        let mut g1 = self.e1;
        let mut g2 = self.e2;
        for (ua, grad) in u.iter().zip(&self.grad) {
            for k in 0..3 {
                g1[k] += ua[k] * grad[0];
                g2[k] += ua[k] * grad[1];
            }
        }
        (g1, g2)
    }

    /// `C = [g1·g1, g2·g2, g1·g2] = [I4, I8, I6]`.
    #[inline(always)]
    fn right_cauchy_green(g1: &[f64; 3], g2: &[f64; 3]) -> Sym2 {
        Sym2::new(dot(g1, g1), dot(g2, g2), dot(g1, g2))
    }

    /// Internal force `f_a = t A0 (N_a,1 P1 + N_a,2 P2)` for the nodal
    /// displacements `u` [mm] (see the module documentation).
    ///
    /// # Errors
    /// When the law rejects the state.
    #[inline(always)]
    pub fn internal_force<M: MembraneMaterial + ?Sized>(
        &self,
        u: &[[f64; 3]; 3],
        material: &M,
    ) -> Result<FibreTriangleForce, MaterialError> {
        let (g1, g2) = self.deformation(u);
        let c = Self::right_cauchy_green(&g1, &g2);
        let s = material.fibre_stress(&c)?;
        let mut p1 = [0.0; 3];
        let mut p2 = [0.0; 3];
        for k in 0..3 {
            p1[k] = self.volume * (s[0] * g1[k] + s[2] * g2[k]);
            p2[k] = self.volume * (s[2] * g1[k] + s[1] * g2[k]);
        }
        let mut force = [0.0; 9];
        for (a, grad) in self.grad.iter().enumerate() {
            for k in 0..3 {
                force[3 * a + k] = grad[0] * p1[k] + grad[1] * p2[k];
            }
        }
        let orientation = dot(&cross(&g1, &g2), &self.normal);
        Ok(FibreTriangleForce { force, orientation })
    }

    /// Strain energy `t A0 W` [N·mm] at the nodal displacements `u`.
    ///
    /// # Errors
    /// When the law rejects the state.
    pub fn strain_energy<M: MembraneMaterial + ?Sized>(
        &self,
        u: &[[f64; 3]; 3],
        material: &M,
    ) -> Result<f64, MaterialError> {
        let (g1, g2) = self.deformation(u);
        let c = Self::right_cauchy_green(&g1, &g2);
        Ok(self.volume * material.energy(&c, &FibreFrame::aligned())?)
    }

    /// An upper bound of the highest squared eigenfrequency `ω²` [1/s²] of
    /// the triangle with lumped masses `ρ t A0 / 3` at each node, linearised
    /// at the displacements `u`; `2/ω` bounds its critical central-difference
    /// step from below.
    ///
    /// The element stiffness is `K = t A0 (Bᵀ ℂ B + G ⊗ I3)` with
    /// `G_ab = ∇N_a · S ∇N_b`, so with the mass `M = (ρ t A0/3) I`
    ///
    /// ```text
    /// ω² ≤ (3/ρ) [ λmax(B Bᵀ ℂ) + max(λmax(S), 0) λmax(DᵀD) ]
    /// ```
    ///
    /// where `D` (3×2) stacks the `∇N_a`. The first term is exact (the
    /// non-zero eigenvalues of `Bᵀ ℂ B` are those of the 3×3 `B Bᵀ ℂ`); the
    /// sum bounds the sum of the two parts (Weyl). `B Bᵀ` needs only `C`:
    /// row by row it is `Σ_a` of
    /// `[n1² C11, n2² C22, n2² C11 + 2 n1 n2 C12 + n1² C22]` on the diagonal
    /// and `n1 n2 C12`, `n1 (n2 C11 + n1 C12)`, `n2 (n2 C12 + n1 C22)` off it.
    ///
    /// # Errors
    /// When the law rejects the state.
    pub fn max_frequency_squared<M: MembraneMaterial + ?Sized>(
        &self,
        u: &[[f64; 3]; 3],
        material: &M,
        density: f64,
    ) -> Result<f64, MaterialError> {
        let (g1, g2) = self.deformation(u);
        let c = Self::right_cauchy_green(&g1, &g2);
        let (state, tangent) = material.stress_tangent(&c, &FibreFrame::aligned())?;
        let (c11, c22, c12) = (c[0], c[1], c[2]);
        let mut bbt = Matrix3::<f64>::zeros();
        let mut dtd = Matrix2::<f64>::zeros();
        for grad in &self.grad {
            let (n1, n2) = (grad[0], grad[1]);
            bbt[(0, 0)] += n1 * n1 * c11;
            bbt[(1, 1)] += n2 * n2 * c22;
            bbt[(2, 2)] += n2 * n2 * c11 + 2.0 * n1 * n2 * c12 + n1 * n1 * c22;
            bbt[(0, 1)] += n1 * n2 * c12;
            bbt[(0, 2)] += n1 * (n2 * c11 + n1 * c12);
            bbt[(1, 2)] += n2 * (n2 * c12 + n1 * c22);
            let g = Vector2::new(n1, n2);
            dtd += g * g.transpose();
        }
        bbt[(1, 0)] = bbt[(0, 1)];
        bbt[(2, 0)] = bbt[(0, 2)];
        bbt[(2, 1)] = bbt[(1, 2)];
        // λmax(B Bᵀ ℂ) = λmax(Lᵀ ℂ L) with B Bᵀ = L Lᵀ (positive definite for
        // a non-degenerate triangle).
        let material_part = match bbt.cholesky() {
            Some(chol) => {
                let l = chol.l();
                let m: Matrix3<f64> = l.transpose() * tangent * l;
                largest_eigenvalue(&(0.5 * (m + m.transpose())))
            }
            None => {
                return Err(MaterialError::NonPositiveDeterminant {
                    det: c11 * c22 - c12 * c12,
                });
            }
        };
        let s = Matrix2::new(
            state.stress[0],
            state.stress[2],
            state.stress[2],
            state.stress[1],
        );
        let stress_max = largest_eigenvalue_2(&s).max(0.0);
        let geometric_part = stress_max * largest_eigenvalue_2(&dtd);
        Ok(3.0 * (material_part.max(0.0) + geometric_part) / density)
    }
}

/// The largest eigenvalue of a symmetric 3×3 matrix, in closed form (the
/// trigonometric solution of the characteristic cubic, Smith 1961): with
/// `q = tr m / 3`, `p² = ‖m − qI‖²_F / 6`, `B = (m − qI)/p`,
/// `λmax = q + 2p cos(acos(det B / 2) / 3)`.
fn largest_eigenvalue(m: &Matrix3<f64>) -> f64 {
    let q = m.trace() / 3.0;
    let shifted = m - Matrix3::identity() * q;
    let p = (shifted.norm_squared() / 6.0).sqrt();
    if p <= 1e-14 * q.abs() || p == 0.0 {
        return q;
    }
    let half_det = (shifted / p).determinant() / 2.0;
    let phi = half_det.clamp(-1.0, 1.0).acos() / 3.0;
    q + 2.0 * p * phi.cos()
}

/// The largest eigenvalue of a symmetric 2×2 matrix `[[a, b], [b, c]]`.
fn largest_eigenvalue_2(m: &Matrix2<f64>) -> f64 {
    let (a, b, c) = (m[(0, 0)], m[(0, 1)], m[(1, 1)]);
    let mean = 0.5 * (a + c);
    let radius = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    mean + radius
}

#[inline(always)]
fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    let v = Vector3::from(*a).cross(&Vector3::from(*b));
    [v.x, v.y, v.z]
}
