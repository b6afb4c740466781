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
//!
//! [`FibreTriangles`] holds `N` triangles lane by lane (structure of arrays)
//! and computes their forces together, with the law on lanes: the same
//! expressions, so that the elements' exponentials, divisions and square
//! roots run side by side in SIMD registers.

use nalgebra::{Matrix2, Matrix3, Vector2};

use super::membrane::MembraneReference;
use crate::material::lanes::Real;
use crate::material::{FibreFrame, Material, MaterialError, MembraneMaterial, Sym2, UdNcf};

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
    /// `t A0` \[mm³\]: thickness times reference area.
    pub volume: f64,
}

/// Internal force of one triangle with its kinematic by-product.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FibreTriangleForce {
    /// `f_a` node-major `[x0, y0, z0, x1, …]` \[N\].
    pub force: [f64; 9],
    /// `(g1 × g2) · N0`: the area ratio, negative for a turned-over triangle.
    pub orientation: f64,
}

/// Relative size of `∂N/∂a0` below which a node counts as off the
/// roving edge ([`FibreTriangle::roving_edge`]).
pub const ROVING_EDGE_TOLERANCE: f64 = 1e-3;

/// Which relative motion of a roving edge's two nodes its coupling mass
/// weighs on (`docs/explicit.md`, "Roving mass scaling").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RovingCoupling {
    /// Only the component along the edge's current direction `d`: the
    /// rate of stretch of the roving, `⊗ d dᵀ`. Draping, bending and the
    /// edge's rotation gain no mass.
    #[default]
    Stretch,
    /// Every component of the relative velocity, `⊗ I3`.
    Full,
}

/// The roving mass of one triangle: the mass share
/// `(ρ t A0/3) κ (e_i − e_j)(e_i − e_j)ᵀ ⊗ P` on its roving edge
/// `[i, j]` (local nodes), `κ = ratio`, with `P = d dᵀ` (the edge's
/// current direction `d`) or `I3` by `coupling` (`docs/explicit.md`,
/// "Roving mass scaling").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RovingMass {
    /// The local nodes of the edge along the rovings.
    pub edge: [usize; 2],
    /// `κ`: the added mass per node of the edge over the lumped share.
    pub ratio: f64,
    /// The components the coupling weighs on.
    pub coupling: RovingCoupling,
}

impl FibreTriangle {
    /// The fibre-basis form of a triangle set up by [`MembraneReference`],
    /// for a membrane of thickness `thickness` \[mm\].
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

    /// `g1 = F a0`, `g2 = F b0` for the nodal displacements `u` \[mm\].
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
    /// displacements `u` \[mm\] (see the module documentation).
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
        self.max_frequency_squared_with(u, material, density, None)
    }

    /// The two local nodes of the edge that runs along the rovings: the
    /// edge opposite the node whose `∇N` has no component along `a0`
    /// (within `1e-3` of the largest), or `None` when no edge does.
    pub fn roving_edge(&self) -> Option<[usize; 2]> {
        let along = self.grad.map(|g| g[0].abs());
        let largest = along.iter().fold(0.0_f64, |m, a| m.max(*a));
        let off = (0..3).find(|&k| along[k] <= ROVING_EDGE_TOLERANCE * largest)?;
        Some([(off + 1) % 3, (off + 2) % 3])
    }

    /// [`FibreTriangle::max_frequency_squared`] with the element's mass
    /// share `(ρ t A0/3) (I + κ δ δᵀ ⊗ P)` when `roving` is given
    /// (`δ = e_i − e_j` on the roving edge, `κ = roving.ratio`: roving mass
    /// scaling, `docs/explicit.md`).
    ///
    /// - [`RovingCoupling::Full`] (`P = I3`): the inverse is
    ///   `(3/(ρ t A0)) W ⊗ I3` with `W = I − κ/(1 + 2κ) δ δᵀ`, so the bound
    ///   keeps its form with the node sums `Σ_a x_a y_a` of `B Bᵀ` and `DᵀD`
    ///   replaced by `xᵀ W y`.
    /// - [`RovingCoupling::Stretch`] (`P = â âᵀ`, `â = g1/|g1|` the edge's
    ///   current direction): the inverse is `(3/(ρ t A0)) (I − w δ δᵀ ⊗
    ///   â âᵀ)`, `w = κ/(1 + 2κ)`, so `B W Bᵀ = B Bᵀ − w p pᵀ` with
    ///   `p_r = Σ_a δ_a (v_{r,a}·â)` of the strain rows `v_{r,a}`:
    ///   `p = (δ1 √c11, δ2 c12/√c11, δ2 √c11 + δ1 c12/√c11)`. The geometric
    ///   part keeps the lumped `DᵀD` (the mass only exceeds the lumped
    ///   one, so this stays a bound).
    ///
    /// Any `δ` and `κ ≥ 0` give a bound for the mass the solver assembles
    /// from the same shares.
    ///
    /// # Errors
    /// When the law rejects the state.
    pub fn max_frequency_squared_with<M: MembraneMaterial + ?Sized>(
        &self,
        u: &[[f64; 3]; 3],
        material: &M,
        density: f64,
        roving: Option<RovingMass>,
    ) -> Result<f64, MaterialError> {
        let (g1, g2) = self.deformation(u);
        let c = Self::right_cauchy_green(&g1, &g2);
        let (state, tangent) = material.stress_tangent(&c, &FibreFrame::aligned())?;
        let (c11, c22, c12) = (c[0], c[1], c[2]);
        let mut bbt = Matrix3::<f64>::zeros();
        let mut dtd = Matrix2::<f64>::zeros();
        match roving {
            None => {
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
            }
            Some(RovingMass {
                edge: [i, j],
                ratio,
                coupling,
            }) => {
                let n1: [f64; 3] = self.grad.map(|g| g[0]);
                let n2: [f64; 3] = self.grad.map(|g| g[1]);
                let w = ratio / (1.0 + 2.0 * ratio);
                let (d1, d2) = (n1[i] - n1[j], n2[i] - n2[j]);
                let (mut p11, mut p22, mut p12) = (dot(&n1, &n1), dot(&n2, &n2), dot(&n1, &n2));
                if coupling == RovingCoupling::Full {
                    // W = I − w d dᵀ between the node sums.
                    p11 -= w * d1 * d1;
                    p22 -= w * d2 * d2;
                    p12 -= w * d1 * d2;
                }
                bbt[(0, 0)] = p11 * c11;
                bbt[(1, 1)] = p22 * c22;
                bbt[(2, 2)] = p22 * c11 + 2.0 * p12 * c12 + p11 * c22;
                bbt[(0, 1)] = p12 * c12;
                bbt[(0, 2)] = p12 * c11 + p11 * c12;
                bbt[(1, 2)] = p22 * c12 + p12 * c22;
                if coupling == RovingCoupling::Stretch {
                    // B W Bᵀ = B Bᵀ − w p pᵀ, p the rows' components along â.
                    let root = c11.sqrt();
                    let along = c12 / root;
                    let p = [d1 * root, d2 * along, d2 * root + d1 * along];
                    for r in 0..3 {
                        for q in r..3 {
                            bbt[(r, q)] -= w * p[r] * p[q];
                        }
                    }
                }
                dtd = Matrix2::new(p11, p12, p12, p22);
            }
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
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// A law evaluated over a [`Real`] (one point or several at once), for
/// [`FibreTriangles`].
pub trait LaneStress<V: Real> {
    /// `C` in the fibre basis `[C11, C22, C12]` per lane to `S` in that
    /// basis and the lanes where the law accepts the state (where
    /// [`MembraneMaterial::fibre_stress`] returns `Ok`, with the same `S`);
    /// the stress of any other lane is meaningless.
    fn stress_lanes(&self, c: &[V; 3]) -> ([V; 3], V::Mask);
}

/// The UD-NCF law on lanes.
impl<V: Real> LaneStress<V> for UdNcf {
    #[inline(always)]
    fn stress_lanes(&self, c: &[V; 3]) -> ([V; 3], V::Mask) {
        self.fibre_stress_lanes(c)
    }
}

/// Any law of [`Material`] on lanes: each law's own lane form.
impl<V: Real> LaneStress<V> for Material {
    #[inline(always)]
    fn stress_lanes(&self, c: &[V; 3]) -> ([V; 3], V::Mask) {
        self.fibre_stress_lanes(c)
    }
}

/// `N` triangles lane by lane: the sixteen numbers of [`FibreTriangle`],
/// each as `N` lanes (lane `l` is triangle `l`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FibreTriangles<const N: usize> {
    /// `∇N_a` in the fibre basis [1/mm].
    pub grad: [[[f64; N]; 2]; 3],
    /// `a0` in global coordinates.
    pub e1: [[f64; N]; 3],
    /// `b0` in global coordinates.
    pub e2: [[f64; N]; 3],
    /// The unit reference normal `a0 × b0`.
    pub normal: [[f64; N]; 3],
    /// `t A0` \[mm³\].
    pub volume: [f64; N],
}

/// Internal forces of several triangles (see
/// [`FibreTriangles::internal_forces`]).
#[derive(Clone, Copy)]
pub struct FibreTriangleForces<V: Real> {
    /// `f_a` node-major `[x0, y0, z0, x1, …]`, each component per lane \[N\].
    pub force: [V; 9],
    /// `(g1 × g2) · N0` per lane.
    pub orientation: V,
    /// The lanes the law accepted (where [`FibreTriangle::internal_force`]
    /// returns `Ok`); the force of any other lane is meaningless.
    pub admissible: V::Mask,
}

impl<const N: usize> FibreTriangles<N> {
    /// Lane `l` from `triangle(l)`.
    pub fn from_fn(triangle: impl Fn(usize) -> FibreTriangle) -> Self {
        let t: [FibreTriangle; N] = std::array::from_fn(triangle);
        let lanes = |f: &dyn Fn(&FibreTriangle) -> f64| std::array::from_fn(|l| f(&t[l]));
        Self {
            grad: std::array::from_fn(|a| std::array::from_fn(|i| lanes(&|t| t.grad[a][i]))),
            e1: std::array::from_fn(|k| lanes(&|t| t.e1[k])),
            e2: std::array::from_fn(|k| lanes(&|t| t.e2[k])),
            normal: std::array::from_fn(|k| lanes(&|t| t.normal[k])),
            volume: lanes(&|t| t.volume),
        }
    }

    /// The triangle in lane `l`.
    pub fn lane(&self, l: usize) -> FibreTriangle {
        FibreTriangle {
            grad: self.grad.map(|g| g.map(|x| x[l])),
            e1: self.e1.map(|x| x[l]),
            e2: self.e2.map(|x| x[l]),
            normal: self.normal.map(|x| x[l]),
            volume: self.volume[l],
        }
    }

    /// [`FibreTriangle::internal_force`] of every lane, with the nodal
    /// displacements `u[a][k]` per lane and the law over the lanes: the
    /// same operations in the same order as the one-triangle kernel (so
    /// the same bits), lane by lane. `context` only carries the lane type's
    /// SIMD context.
    #[inline(always)]
    pub fn internal_forces<V: Real<Array = [f64; N]>, L: LaneStress<V> + ?Sized>(
        &self,
        context: V,
        u: &[[V; 3]; 3],
        law: &L,
    ) -> FibreTriangleForces<V> {
        // Explicit loads, no `[T; 3]::map`, which the inliner may leave as a
        // call outside the SIMD context.
        let load = |x: [f64; N]| context.load(x);
        let mut g1 = [load(self.e1[0]), load(self.e1[1]), load(self.e1[2])];
        let mut g2 = [load(self.e2[0]), load(self.e2[1]), load(self.e2[2])];
        for (ua, grad) in u.iter().zip(&self.grad) {
            let (n1, n2) = (load(grad[0]), load(grad[1]));
            for k in 0..3 {
                g1[k] = g1[k] + ua[k] * n1;
                g2[k] = g2[k] + ua[k] * n2;
            }
        }
        let dot = |a: &[V; 3], b: &[V; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let c = [dot(&g1, &g1), dot(&g2, &g2), dot(&g1, &g2)];
        let (s, admissible) = law.stress_lanes(&c);
        let volume = load(self.volume);
        let mut p1 = g1;
        let mut p2 = g2;
        for k in 0..3 {
            p1[k] = volume * (s[0] * g1[k] + s[2] * g2[k]);
            p2[k] = volume * (s[2] * g1[k] + s[1] * g2[k]);
        }
        let mut force = [context; 9];
        for (a, grad) in self.grad.iter().enumerate() {
            let (n1, n2) = (load(grad[0]), load(grad[1]));
            for k in 0..3 {
                force[3 * a + k] = n1 * p1[k] + n2 * p2[k];
            }
        }
        let normal = [
            g1[1] * g2[2] - g1[2] * g2[1],
            g1[2] * g2[0] - g1[0] * g2[2],
            g1[0] * g2[1] - g1[1] * g2[0],
        ];
        FibreTriangleForces {
            force,
            orientation: dot(
                &normal,
                &[
                    load(self.normal[0]),
                    load(self.normal[1]),
                    load(self.normal[2]),
                ],
            ),
            admissible,
        }
    }
}

#[cfg(test)]
mod tests {
    //! The fibre-basis kernels against the reference element
    //! [`MembraneReference::force`] (general frame, the law's
    //! `evaluate_invariants`).
    //!
    //! # Tolerance
    //! Both sides evaluate the same law at the same `C` up to round-off: the
    //! reference rotates `C` into the fibre frame (a few ulps of `|C|` on the
    //! invariants), the force pass takes `C` in the fibre basis directly and
    //! its exponentials from a polynomial instead of the C library (a few
    //! ulps). An error `δC ~ k ε |C|` moves `S` by `‖ℂ‖ δC`, and the stress
    //! itself carries a few ulps, so the force error is bounded by
    //! `k ε · V |∇N| |g| (|S| + ‖ℂ‖ |C|)`, with `k` a few dozen (the sums of
    //! the law and of the kinematics have a few dozen terms). Measured
    //! against that scale, the accepted error is `1e-12` (`k ≈ 4500`: ample
    //! for round-off, far below any modelling or branch error, which is of
    //! order one on this scale). The scale uses `‖ℂ‖` because the stiff
    //! roving term turns an ulp of `I4` into `1000 ε` MPa of stress, which
    //! on an element whose stress is set by the soft shear term is well
    //! above `1e-12 |f|`.

    use std::collections::BTreeSet;

    use nalgebra::Vector3;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    use super::*;
    use crate::material::{Invariants, Material, MaterialSpec, UdNcf};

    use crate::material::diagnostics::{BALANCED_TEST_SET as BALANCED, SVK_TEST_SET as SVK};

    const THICKNESS: f64 = 0.3;
    const TOLERANCE: f64 = 1e-12;

    fn materials() -> Vec<Material> {
        let named = MaterialSpec::named("schaefer2024").expect("set").material;
        let balanced = MaterialSpec::from_toml_str(BALANCED, "balanced-test")
            .expect("valid")
            .material;
        let svk = MaterialSpec::from_toml_str(SVK, "svk")
            .expect("valid")
            .material;
        vec![named, balanced, svk]
    }

    fn udncf(material: &Material) -> Option<&UdNcf> {
        match material {
            Material::UdNcf(law) => Some(law),
            Material::OrthotropicSvk(_) => None,
        }
    }

    fn unit(rng: &mut StdRng) -> Vector3<f64> {
        loop {
            let v = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let n = v.norm();
            if n > 0.1 && n < 1.0 {
                return v / n;
            }
        }
    }

    /// A random element and state: a triangle of random shape (angles above
    /// about 5°), position and orientation in space, a random fibre
    /// direction in its plane, and displacements that give prescribed
    /// `(I4, I6, I8)` (drawn over every branch of the test sets) with the
    /// deformed triangle turned and moved at random.
    struct Sample {
        x: [Vector3<f64>; 3],
        reference: MembraneReference,
        u: [Vector3<f64>; 3],
        invariants: (f64, f64, f64),
    }

    fn sample(rng: &mut StdRng) -> Sample {
        let (x, reference) = loop {
            let size = 10f64.powf(rng.random_range(-1.0..1.5));
            let origin = Vector3::new(
                rng.random_range(-200.0..200.0),
                rng.random_range(-200.0..200.0),
                rng.random_range(-50.0..50.0),
            );
            let x = [0, 1, 2].map(|_| origin + size * unit(rng));
            let e = [x[1] - x[0], x[2] - x[1], x[0] - x[2]];
            let sine =
                |a: &Vector3<f64>, b: &Vector3<f64>| a.cross(b).norm() / (a.norm() * b.norm());
            if sine(&e[0], &e[1])
                .min(sine(&e[1], &e[2]))
                .min(sine(&e[2], &e[0]))
                < 0.09
            {
                continue;
            }
            let normal = e[0].cross(&e[1]).normalize();
            // A direction in the plane at a random angle, plus a random
            // out-of-plane part that the element projects away.
            let in_plane = unit(rng).cross(&normal).normalize();
            let fibre = in_plane + rng.random_range(-0.5..0.5) * normal;
            if let Ok(r) = MembraneReference::new(&x, &fibre) {
                break (x, r);
            }
        };
        let (i4, i6, i8) = loop {
            let i4: f64 = 1.0 + rng.random_range(-0.05..0.05);
            let i6: f64 = rng.random_range(-0.9..0.9);
            let i8: f64 = rng.random_range(0.6..1.6);
            if i8 - i6 * i6 / i4 >= 0.09 {
                break (i4, i6, i8);
            }
        };
        // g1, g2 with g1·g1 = I4, g1·g2 = I6, g2·g2 = I8, in a random
        // orthonormal pair (q1, q2) of space.
        let q1 = unit(rng);
        let q2 = q1.cross(&unit(rng)).normalize();
        let g1 = i4.sqrt() * q1;
        let g2 = (i6 / i4.sqrt()) * q1 + (i8 - i6 * i6 / i4).sqrt() * q2;
        let frame = &reference.frame;
        let a0 = reference.e1 * frame.a0.x + reference.e2 * frame.a0.y;
        let b0 = reference.e1 * frame.b0.x + reference.e2 * frame.b0.y;
        // x = x0 + t + F (X − X0) with F a0 = g1, F b0 = g2, F N = n.
        let n = g1.cross(&g2).normalize();
        let shift = Vector3::new(
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
        );
        let u = x.map(|xa| {
            let dx = xa - x[0];
            shift + g1 * dx.dot(&a0) + g2 * dx.dot(&b0) + n * dx.dot(&reference.normal) - dx
        });
        Sample {
            x,
            reference,
            u,
            invariants: (i4, i6, i8),
        }
    }

    /// `V max|∇N_a| |g| (|S| + ‖ℂ‖ |C|)`: the scale of the force's round-off
    /// (module docs).
    fn force_scale(
        reference: &MembraneReference,
        u: &[Vector3<f64>; 3],
        material: &Material,
    ) -> f64 {
        let kin = reference.kinematics(u);
        let (state, tangent) = material
            .stress_tangent(&kin.c, &reference.frame)
            .expect("admissible");
        let grad = reference.grad.iter().map(|g| g.norm()).fold(0.0, f64::max);
        let g = kin.g[0].norm().max(kin.g[1].norm());
        THICKNESS
            * reference.area
            * grad
            * g
            * (state.stress.norm() + tangent.norm() * kin.c.norm())
    }

    #[test]
    fn internal_force_matches_the_reference_element() {
        const STATES: usize = 4000;
        for (m, material) in materials().iter().enumerate() {
            let mut rng = StdRng::seed_from_u64(20_240 + m as u64);
            let mut seen: BTreeSet<String> = BTreeSet::new();
            let mut worst: f64 = 0.0;
            for _ in 0..STATES {
                let Sample {
                    reference,
                    u,
                    invariants,
                    ..
                } = sample(&mut rng);
                let triangle = FibreTriangle::new(&reference, THICKNESS);
                let ua = u.map(|v| [v.x, v.y, v.z]);
                let fast = triangle.internal_force(&ua, material).expect("admissible");
                let (kin, _, force) = reference
                    .force(&u, material, THICKNESS)
                    .expect("admissible");
                let scale = force_scale(&reference, &u, material);
                let error = (0..9)
                    .map(|i| (fast.force[i] - force[i]).abs())
                    .fold(0.0, f64::max);
                assert!(
                    error <= TOLERANCE * scale,
                    "force {:?} vs reference {:?}: error {error:e}, scale {scale:e}",
                    fast.force,
                    force.as_slice()
                );
                // g = E + Σ u_a ⊗ ∇N_a carries the round-off of its largest
                // terms, and the orientation is quadratic in g.
                let g_scale = 1.0
                    + (0..3)
                        .map(|a| u[a].norm() * reference.grad[a].norm())
                        .sum::<f64>();
                assert!(
                    (fast.orientation - kin.orientation).abs() <= TOLERANCE * g_scale * g_scale,
                    "orientation {} vs {}",
                    fast.orientation,
                    kin.orientation
                );
                worst = worst.max(error / scale);
                let (i4, i6, i8) = invariants;
                let reached = Invariants::new(&kin.c, &reference.frame).expect("admissible");
                for (got, wanted) in [(reached.i4, i4), (reached.i6, i6), (reached.i8, i8)] {
                    assert!(
                        (got - wanted).abs() < 1e-12,
                        "invariants {reached:?} vs {invariants:?}"
                    );
                }
                if let Some(law) = udncf(material) {
                    let inv = Invariants {
                        i4,
                        i6,
                        i8,
                        i11: (i8 - i6 * i6 / i4).sqrt(),
                    };
                    let b = law.branches(&inv);
                    seen.insert(format!("I4>=1:{}", b.roving_tension));
                    seen.insert(format!("I6>=0:{}", b.positive_shear));
                    seen.insert(format!("w4:{:?}", b.w4));
                    seen.insert(format!("w6:{:?}", b.w6));
                    seen.insert(format!("w8:{:?}", b.w8));
                    seen.insert(format!("w11:{:?}", b.w11));
                }
            }
            // Every branch each set can reach (W4 of the named set is linear;
            // no set has a lock below its transition point).
            let expected: &[&str] = match m {
                0 => &[
                    "I4>=1:false",
                    "I4>=1:true",
                    "I6>=0:false",
                    "I6>=0:true",
                    "w4:Initial",
                    "w6:Initial",
                    "w6:Middle",
                    "w8:None",
                    "w8:Some(Initial)",
                    "w8:Some(Middle)",
                    "w11:None",
                    "w11:Some(Initial)",
                    "w11:Some(Middle)",
                    "w11:Some(MiddleLocked)",
                ],
                1 => &[
                    "I4>=1:false",
                    "I4>=1:true",
                    "I6>=0:false",
                    "I6>=0:true",
                    "w4:Initial",
                    "w4:Middle",
                    "w4:MiddleLocked",
                    "w6:Initial",
                    "w6:Middle",
                    "w6:MiddleLocked",
                    "w8:None",
                    "w8:Some(Initial)",
                    "w8:Some(Middle)",
                    "w8:Some(MiddleLocked)",
                    "w11:None",
                    "w11:Some(Initial)",
                    "w11:Some(Middle)",
                    "w11:Some(MiddleLocked)",
                ],
                _ => &[],
            };
            for branch in expected {
                assert!(
                    seen.contains(*branch),
                    "set {m}: branch {branch} not reached"
                );
            }
            eprintln!("set {m}: worst error / scale = {worst:e}");
        }
    }

    /// Forces, orientations and acceptance of the four lanes through the
    /// AVX2 lanes, where the CPU has them.
    type LaneForces = ([[f64; 9]; 4], [f64; 4], [bool; 4]);

    #[cfg(target_arch = "x86_64")]
    fn avx2_forces(
        batch: &FibreTriangles<4>,
        u: &[[[f64; 3]; 3]; 4],
        law: &UdNcf,
    ) -> Option<LaneForces> {
        use crate::material::lanes::x86::{F64x4, F64x8};
        let simd = pulp::x86::V3::try_new()?;
        let context = F64x4::new(simd, [0.0; 4]);
        let ue: [[F64x4; 3]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|k| context.load(std::array::from_fn(|l| u[l][a][k])))
        });
        let f = batch.internal_forces(context, &ue, law);
        let force = f.force.map(|x| x.store());
        let bits = F64x4::bits(f.admissible);
        let four: LaneForces = (
            std::array::from_fn(|l| std::array::from_fn(|i| force[i][l])),
            f.orientation.store(),
            std::array::from_fn(|l| bits & (1 << l) != 0),
        );
        // Eight lanes in two registers: the batch twice, reversed the
        // second time, gives the same four triangles' results twice.
        let wide = FibreTriangles::<8>::from_fn(|l| batch.lane(if l < 4 { l } else { 7 - l }));
        let context = F64x8::new(simd, [0.0; 8]);
        let ue: [[F64x8; 3]; 3] = std::array::from_fn(|a| {
            std::array::from_fn(|k| {
                context.load(std::array::from_fn(|l| {
                    u[if l < 4 { l } else { 7 - l }][a][k]
                }))
            })
        });
        let f = wide.internal_forces(context, &ue, law);
        let force = f.force.map(|x| x.store());
        let bits = F64x8::bits(f.admissible);
        for l in 0..8 {
            let lane = if l < 4 { l } else { 7 - l };
            assert_eq!(
                force.map(|x| x[l].to_bits()),
                four.0[lane].map(f64::to_bits)
            );
            assert_eq!(f.orientation.store()[l].to_bits(), four.1[lane].to_bits());
            assert_eq!(bits & (1 << l) != 0, four.2[lane]);
        }
        Some(four)
    }

    #[cfg(not(target_arch = "x86_64"))]
    fn avx2_forces(_: &FibreTriangles<4>, _: &[[[f64; 3]; 3]; 4], _: &UdNcf) -> Option<LaneForces> {
        None
    }

    #[test]
    fn lanes_repeat_the_one_triangle_kernel_bit_for_bit() {
        const BATCHES: usize = 1000;
        for material in materials() {
            let Some(law) = udncf(&material) else {
                continue;
            };
            let mut rng = StdRng::seed_from_u64(4);
            let (mut accepted, mut rejected) = (0, 0);
            for _ in 0..BATCHES {
                let samples: [Sample; 4] = std::array::from_fn(|_| sample(&mut rng));
                let mut u = samples.each_ref().map(|s| s.u.map(|v| [v.x, v.y, v.z]));
                // Inadmissible lanes now and then: a triangle collapsed to a
                // line (det C = 0 up to round-off, either sign) or a point,
                // a non-finite displacement.
                if rng.random_range(0.0..1.0) < 0.2 {
                    let x = &samples[1].x;
                    let t: f64 = rng.random_range(0.0..1.0);
                    let onto = x[0] + t * (x[1] - x[0]);
                    u[1][2] = (onto - x[2]).into();
                }
                if rng.random_range(0.0..1.0) < 0.1 {
                    let x = &samples[2].x;
                    u[2] = x.map(|xa| (x[0] - xa).into());
                }
                if rng.random_range(0.0..1.0) < 0.1 {
                    u[3][0][1] = f64::NAN;
                }
                let triangles: [FibreTriangle; 4] =
                    std::array::from_fn(|l| FibreTriangle::new(&samples[l].reference, THICKNESS));
                let batch = FibreTriangles::<4>::from_fn(|l| triangles[l]);
                assert_eq!(batch.lane(2), triangles[2]);
                let lanes = avx2_forces(&batch, &u, law);
                for l in 0..4 {
                    let single = FibreTriangles::<1>::from_fn(|_| triangles[l]);
                    let generic = single.internal_forces(0.0, &u[l], law);
                    let accepted_lane = generic.admissible;
                    match triangles[l].internal_force(&u[l], &material) {
                        Ok(one) => {
                            accepted += 1;
                            assert!(accepted_lane);
                            let bits = |f: [f64; 9]| f.map(f64::to_bits);
                            assert_eq!(bits(generic.force), bits(one.force));
                            assert_eq!(generic.orientation.to_bits(), one.orientation.to_bits());
                            if let Some((force, orientation, admissible)) = lanes {
                                assert!(admissible[l]);
                                assert_eq!(bits(force[l]), bits(one.force));
                                assert_eq!(orientation[l].to_bits(), one.orientation.to_bits());
                            }
                        }
                        Err(_) => {
                            rejected += 1;
                            assert!(!accepted_lane);
                            if let Some((_, _, admissible)) = lanes {
                                assert!(!admissible[l]);
                            }
                        }
                    }
                }
            }
            assert!(rejected > 100 && accepted > 3000, "{rejected} rejected");
        }
    }
}
