//! Reference data of one bending element and its reference kernels:
//! curvature, energy, force, exact tangent and a frequency bound
//! (docs/bending.md, "Formulation", "Gradient and Hessian", "Frequency
//! bound").
//!
//! Notation (own triangle, current positions `x_0, x_1, x_2`): edge vectors
//! `e_k = x_{k+2} − x_{k+1}` (edge `k` is opposite node `k`, run
//! counter-clockwise), `N = e_0 × e_1 = 2A n`, lengths `l_k = |e_k|`,
//! `J = |N| / (2 A0)`, `ρ_i = J / l_i`, hinge measures `θ̂_i` (`2 sin(θ_i/2)`
//! on interior edges, `2 sin θ_i` on clamped ones), `φ_i = θ̂_i ρ_i`,
//! convected curvature `K = Σ_i φ_i c_i` (Voigt `[K11, K22, 2K12]` in the
//! reference fibre basis), the current fibre vectors `g1 = F a0`,
//! `g2 = F b0` with `I4 = g1·g1`, `I8 = g2·g2`, the curvature on the unit
//! material directions `κ = [K11/I4, K22/I8, 2K12/√(I4 I8)]`,
//! `Δκ = κ − κ0`, energy `W = A0 ½ Δκᵀ D Δκ`.

// Index loops mirror the indices of the formulas (nodes, edges, components).
#![allow(clippy::needless_range_loop)]

use nalgebra::{Matrix3, Vector3};

use super::{
    BendingError, BendingStiffness, CLAMP_LIMIT, DEGENERATE_AREA, FOLD_LIMIT, HingeKind,
    MIN_FIBRE_PROJECTION, StencilMatrix, StencilVector,
};

type V3 = Vector3<f64>;
type M3 = Matrix3<f64>;

/// Reference data of one bending element (built once; 29 numbers and the
/// hinge kinds).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendingElement {
    /// The kind of each edge `i` (opposite node `i`).
    pub kinds: [HingeKind; 3],
    /// `c_i = ℓ_i² / (2 A0) · Voigt(ν_i ⊗ ν_i)`, Voigt `[11, 22, 2·12]` in
    /// the fibre basis `(a0, b0)`, `ν_i` the outward unit normal of edge
    /// `i` in the reference plane \[dimensionless\] (docs/bending.md, Eq. (5)).
    pub coefficients: [[f64; 3]; 3],
    /// Reference curvature `κ0` [1/mm], Voigt `[κ11, κ22, 2κ12]`: Eq. (5a)
    /// on the reference geometry (`I4 = I8 = 1` there, so `κ0 = K0`).
    pub reference_curvature: [f64; 3],
    /// Reference area `A0` \[mm²\].
    pub area: f64,
    /// The ghost vertex of each clamped edge \[mm\] (zero for other edges):
    /// the mirror image of node `i` across the line of edge `i`.
    pub ghosts: [[f64; 3]; 3],
    /// The shape-function gradients along the reference fibre basis
    /// [1/mm]: `[∂N_a/∂a0, ∂N_a/∂b0]` for the own nodes `a = 0, 1, 2`
    /// (`∂N_a/∂a0 = −(E_a × n0)·a0 / (2 A0)`, `E_a` the reference edge
    /// opposite node `a`; each row sums to zero). They give the current
    /// fibre vectors `g1 = F a0 = Σ_a (∂N_a/∂a0) x_a` and `g2 = F b0`
    /// (docs/bending.md, Eq. (5a)).
    pub fibre_gradients: [[f64; 3]; 2],
}

/// Curvature of one element (docs/bending.md, Eqs. (5), (5a)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendingCurvature {
    /// The curvature on the current unit material directions `κ` [1/mm],
    /// Voigt `[κ11, κ22, 2κ12]`: `κ_ab = ĝ_a · II · ĝ_b`, the normal
    /// curvature along the current unit rovings `ĝ1` and stitching `ĝ2`
    /// and the twist between them (Eq. (5a)). The bending law acts on it.
    pub curvature: [f64; 3],
    /// `Δκ = κ − κ0` [1/mm], same storage.
    pub change: [f64; 3],
    /// The convected curvature `K = Fᵀ II F` [1/mm], Voigt
    /// `[K11, K22, 2K12]` in the reference fibre basis (Eq. (5)):
    /// `K11 = I4 κ11`, `K22 = I8 κ22`, `K12 = √(I4 I8) κ12`.
    pub convected: [f64; 3],
    /// The squared fibre stretches `[I4, I8] = [g1·g1, g2·g2]`
    /// \[dimensionless\], `g1 = F a0`, `g2 = F b0` (Eq. (5a)).
    pub stretches: [f64; 2],
    /// The hinge measures: `θ̂_i = 2 sin(θ_i/2)` on interior edges,
    /// `m_c = 2 sin θ_i` on clamped edges (the measure of the mirror angle
    /// `2θ_i`, docs/bending.md, Eq. (2c)), zero on free edges.
    pub hinge_measures: [f64; 3],
}

/// Energy and internal force of one element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendingForce {
    /// `W_e` [N·mm].
    pub energy: f64,
    /// `∂W_e/∂x` \[N\] over the six slots, node-major (ignored slots zero).
    pub force: StencilVector,
}

/// Energy, internal force and exact tangent of one element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendingTangent {
    /// `W_e` [N·mm].
    pub energy: f64,
    /// `∂W_e/∂x` \[N\], node-major over the six slots.
    pub force: StencilVector,
    /// `∂²W_e/∂x²` [N/mm], 18×18, symmetric to round-off; rows and columns
    /// of ignored slots are zero.
    pub stiffness: StencilMatrix,
}

/// `∂e_k/∂x_m = s(k, m) I` for `e_k = x_{k+2} − x_{k+1}`.
#[inline]
fn edge_sign(k: usize, m: usize) -> f64 {
    if m == (k + 2) % 3 {
        1.0
    } else if m == (k + 1) % 3 {
        -1.0
    } else {
        0.0
    }
}

/// One triangle's current geometry.
#[derive(Debug, Clone, Copy)]
struct Triangle {
    /// `e_k = p_{k+2} − p_{k+1}`.
    e: [V3; 3],
    /// `N = e_0 × e_1` (twice the area times the unit normal).
    big_n: V3,
    /// `|N| = 2A`.
    norm: f64,
    /// Unit normal.
    n: V3,
}

impl Triangle {
    fn new(p: [V3; 3]) -> Self {
        let e = [p[2] - p[1], p[0] - p[2], p[1] - p[0]];
        let big_n = e[0].cross(&e[1]);
        let norm = big_n.norm();
        Self {
            e,
            big_n,
            norm,
            n: big_n / norm,
        }
    }

    /// Area is positive relative to the longest edge (docs/bending.md,
    /// "Limits").
    fn is_degenerate(&self) -> bool {
        let longest = self.e.iter().map(|e| e.norm_squared()).fold(0.0, f64::max);
        !(self.norm > DEGENERATE_AREA * longest && self.norm.is_finite())
    }

    /// This triangle's part of `∂θ/∂p_k` for the hinge at its edge `h`:
    /// `G_k = (e_h·e_k)/l_h · N/|N|²` (docs/bending.md, Eq. (9)).
    fn hinge_gradient(&self, h: usize) -> [V3; 3] {
        let l = self.e[h].norm();
        let q = self.big_n / (self.norm * self.norm);
        std::array::from_fn(|k| q * (self.e[h].dot(&self.e[k]) / l))
    }

    /// `∂G_k/∂p_m` (docs/bending.md, Eq. (12)):
    /// `q ⊗ ∂w_k/∂p_m + w_k (I − 2nnᵀ)[e_m]× / |N|²`, `q = N/|N|²`,
    /// `w_k = e_h·e_k / l_h`.
    fn hinge_jacobian(&self, h: usize) -> [[M3; 3]; 3] {
        let eh = self.e[h];
        let l = eh.norm();
        let n2 = self.norm * self.norm;
        let q = self.big_n / n2;
        let reflect = M3::identity() - 2.0 * self.n * self.n.transpose();
        std::array::from_fn(|k| {
            let w = eh.dot(&self.e[k]) / l;
            std::array::from_fn(|m| {
                let (shm, skm) = (edge_sign(h, m), edge_sign(k, m));
                let dw = (self.e[k] * shm + eh * skm) / l - eh * (w * shm / (l * l));
                q * dw.transpose() + reflect * self.e[m].cross_matrix() * (w / n2)
            })
        })
    }

    /// Block norms bounding `‖∂G_k/∂p_m‖₂` (for the frequency bound).
    fn hinge_jacobian_bounds(&self, h: usize) -> [[f64; 3]; 3] {
        let eh = self.e[h];
        let l = eh.norm();
        let n2 = self.norm * self.norm;
        std::array::from_fn(|k| {
            let w = eh.dot(&self.e[k]) / l;
            std::array::from_fn(|m| {
                let (shm, skm) = (edge_sign(h, m), edge_sign(k, m));
                let dw = (self.e[k] * shm + eh * skm) / l - eh * (w * shm / (l * l));
                dw.norm() / self.norm + w.abs() * self.e[m].norm() / n2
            })
        })
    }
}

/// The hinge of one edge in the current state.
#[derive(Debug, Clone, Copy)]
struct Hinge {
    /// The partner (neighbour or ghost) triangle `(x_{i+2}, x_{i+1}, x_{3+i})`,
    /// `None` for a free edge.
    partner: Option<Triangle>,
    /// Stencil slots of the partner triangle's nodes (`None`: the ghost).
    partner_slots: [Option<usize>; 3],
    /// The hinge measure: `θ̂ = 2 sin(θ/2)` (neighbour) or
    /// `m_c = 2 sin θ` (clamped).
    measure: f64,
    /// Its first derivative: `cos(θ/2)` (neighbour) or `2 cos θ` (clamped).
    slope: f64,
    /// Its second derivative: `−θ̂/4` (neighbour) or `−m_c` (clamped).
    bend: f64,
}

/// Everything the kernels share, at one state.
#[derive(Debug, Clone, Copy)]
struct State {
    own: Triangle,
    hinges: [Hinge; 3],
    lengths: [f64; 3],
    /// `ρ_i = J / l_i`.
    rho: [f64; 3],
    /// `g1 = F a0`, `g2 = F b0`.
    fibres: [V3; 2],
    /// `[I4, I8]`.
    stretches: [f64; 2],
    /// The stretch factors `s_v(I4, I8) = [1/I4, 1/I8, 1/√(I4 I8)]`
    /// (`κ_v = s_v K_v`), their first derivatives `∂s_v/∂I_α` and second
    /// derivatives `∂²s_v/∂I_α∂I_β` (`α, β ∈ {I4, I8}`).
    scales: [f64; 3],
    scale_slopes: [[f64; 2]; 3],
    scale_bends: [[[f64; 2]; 2]; 3],
    /// `K`.
    convected: [f64; 3],
    /// `κ`.
    curvature: [f64; 3],
    /// `Δκ`.
    change: [f64; 3],
    /// `M_v = A0 D_v Δκ_v = ∂W/∂κ_v`.
    moment: [f64; 3],
    /// `μ_i = ∂W/∂φ_i = Σ_v c_iv s_v M_v`.
    mu: [f64; 3],
    /// `∂W/∂I_α = Σ_v M_v K_v ∂s_v/∂I_α` (the factors of `∇I4`, `∇I8` in
    /// the force, Eq. (8)).
    stretch_forces: [f64; 2],
    energy: f64,
}

/// The hinge angle's sine and cosine at edge `i` of `own` against the
/// partner normal: `sin θ = (n' × n)·ê_i`, `cos θ = n·n'` (docs/bending.md,
/// Eq. (1)); positive when the surface bends towards `+n`.
fn hinge_angle(own: &Triangle, i: usize, partner: &Triangle) -> (f64, f64) {
    let edge = own.e[i] / own.e[i].norm();
    (partner.n.cross(&own.n).dot(&edge), own.n.dot(&partner.n))
}

/// The measure of an interior hinge and its first two derivatives in `θ`
/// (docs/bending.md, Eq. (2)): `θ̂ = sin θ √(2/(1 + cos θ)) = 2 sin(θ/2)`,
/// `cos(θ/2) = √((1 + cos θ)/2)`, `−θ̂/4`.
fn hinge_measure(edge: usize, sin: f64, cos: f64) -> Result<(f64, f64, f64), BendingError> {
    let one_plus_cos = 1.0 + cos;
    if one_plus_cos.is_nan() || one_plus_cos <= FOLD_LIMIT {
        return Err(BendingError::FoldedHinge { edge, one_plus_cos });
    }
    let half_cos = (0.5 * one_plus_cos).sqrt();
    let measure = sin / half_cos;
    Ok((measure, half_cos, -0.25 * measure))
}

/// The measure of a clamped hinge and its first two derivatives in `θ`
/// (docs/bending.md, Eq. (2c)): the measure of the angle `2θ` between the
/// element and its mirror image across the clamp plane,
/// `m_c = 2 sin(2θ/2) = 2 sin θ`, `2 cos θ`, `−2 sin θ`. Past `90°` the
/// measure falls again and the clamp would let go: states with
/// `cos θ ≤ CLAMP_LIMIT` are rejected.
fn clamped_hinge_measure(edge: usize, sin: f64, cos: f64) -> Result<(f64, f64, f64), BendingError> {
    if cos.is_nan() || cos <= CLAMP_LIMIT {
        return Err(BendingError::OverturnedClamp { edge, cos });
    }
    let measure = 2.0 * sin;
    Ok((measure, 2.0 * cos, -measure))
}

/// The stretch factors of Eq. (5a), `κ_v = s_v K_v`, and their derivatives
/// in `(I4, I8)`: `s = [1/I4, 1/I8, 1/√(I4 I8)]`, `∂s_v/∂I_α` and
/// `∂²s_v/∂I_α∂I_β` (docs/bending.md, Eq. (11a)). One division and one
/// square root.
#[allow(clippy::type_complexity)]
fn stretch_scales(stretches: [f64; 2]) -> ([f64; 3], [[f64; 2]; 3], [[[f64; 2]; 2]; 3]) {
    let [i4, i8] = stretches;
    let inv_product = 1.0 / (i4 * i8);
    let (s1, s2, s3) = (i8 * inv_product, i4 * inv_product, inv_product.sqrt());
    let slopes = [
        [-s1 * s1, 0.0],
        [0.0, -s2 * s2],
        [-0.5 * s3 * s1, -0.5 * s3 * s2],
    ];
    let bends = [
        [[2.0 * s1 * s1 * s1, 0.0], [0.0, 0.0]],
        [[0.0, 0.0], [0.0, 2.0 * s2 * s2 * s2]],
        [
            [0.75 * s3 * s1 * s1, 0.25 * s3 * s1 * s2],
            [0.25 * s3 * s1 * s2, 0.75 * s3 * s2 * s2],
        ],
    ];
    ([s1, s2, s3], slopes, bends)
}

/// Largest eigenvalue of a symmetric 3×3 matrix (trigonometric closed form:
/// `q = tr m / 3`, `p² = ‖m − qI‖²_F / 6`, `λmax = q + 2p cos(acos(det B / 2)/3)`).
fn largest_eigenvalue(m: &M3) -> f64 {
    let q = m.trace() / 3.0;
    let shifted = m - M3::identity() * q;
    let p = (shifted.norm_squared() / 6.0).sqrt();
    if p <= 1e-14 * q.abs() || p == 0.0 {
        return q;
    }
    let half_det = (shifted / p).determinant() / 2.0;
    let angle = half_det.clamp(-1.0, 1.0).acos() / 3.0;
    q + 2.0 * p * angle.cos()
}

/// `‖v‖²_M = Σ_slots |v_slot|² / m_slot` over the slots in `slots`.
fn mass_norm_squared(v: &StencilVector, masses: &[f64; 6], slots: &[bool; 6]) -> f64 {
    let mut sum = 0.0;
    for s in 0..6 {
        if slots[s] {
            sum += v.fixed_rows::<3>(3 * s).norm_squared() / masses[s];
        }
    }
    sum
}

/// Adds `scale · block` at block `(a, b)`.
#[inline]
fn add_block(k: &mut StencilMatrix, a: usize, b: usize, block: &M3, scale: f64) {
    let mut view = k.fixed_view_mut::<3, 3>(3 * a, 3 * b);
    view += block * scale;
}

/// `k += x yᵀ s` in place: entry by entry `(x_i y_j) s`, the roundings of
/// `k += x * y.transpose() * s` without its two 18 × 18 temporaries.
#[inline(always)]
fn add_outer(k: &mut StencilMatrix, x: &StencilVector, y: &StencilVector, s: f64) {
    for j in 0..18 {
        let yj = y[j];
        for i in 0..18 {
            k[(i, j)] += (x[i] * yj) * s;
        }
    }
}

/// `k += x yᵀ s + (x yᵀ s)ᵀ` in place, with the roundings of
/// `let c = x * y.transpose() * s; k += c + c.transpose()`.
#[inline(always)]
fn add_outer_symmetric(k: &mut StencilMatrix, x: &StencilVector, y: &StencilVector, s: f64) {
    for j in 0..18 {
        for i in 0..18 {
            k[(i, j)] += (x[i] * y[j]) * s + (x[j] * y[i]) * s;
        }
    }
}

impl BendingElement {
    /// Sets up an element from the reference positions of its six slots
    /// \[mm\] (slots of free and clamped edges are not read), its hinge kinds
    /// and a global fibre direction (projected on the triangle's plane and
    /// normalised to give `a0`; `b0 = n0 × a0`). Clamped edges get their
    /// ghost vertex; `κ0` is the curvature (5a) of the reference geometry
    /// (docs/bending.md, "Reference data").
    ///
    /// # Errors
    /// A non-finite position, a degenerate triangle, a fibre perpendicular
    /// to it, a degenerate or completely folded hinge in the reference.
    pub fn new(x: &[V3; 6], kinds: [HingeKind; 3], fibre: &V3) -> Result<Self, BendingError> {
        check_finite(x, &kinds)?;
        let own = Triangle::new([x[0], x[1], x[2]]);
        if own.is_degenerate() {
            return Err(BendingError::Degenerate {
                area: 0.5 * own.norm,
            });
        }
        let area = 0.5 * own.norm;
        let n0 = own.n;
        let projected = fibre - n0 * fibre.dot(&n0);
        let projected_norm = projected.norm();
        if !fibre.norm().is_finite()
            || projected_norm.is_nan()
            || projected_norm <= MIN_FIBRE_PROJECTION * fibre.norm()
        {
            return Err(BendingError::FibreOutOfPlane {
                x: fibre.x,
                y: fibre.y,
                z: fibre.z,
            });
        }
        let a0 = projected / projected_norm;
        let b0 = n0.cross(&a0);
        let mut coefficients = [[0.0; 3]; 3];
        let mut ghosts = [[0.0; 3]; 3];
        let mut fibre_gradients = [[0.0; 3]; 2];
        for i in 0..3 {
            let edge = own.e[i];
            let length2 = edge.norm_squared();
            // Outward unit normal of edge i in the reference plane: ê × n0.
            let outward = edge.cross(&n0) / length2.sqrt();
            let (v1, v2) = (outward.dot(&a0), outward.dot(&b0));
            let scale = length2 / (2.0 * area);
            coefficients[i] = [scale * v1 * v1, scale * v2 * v2, scale * 2.0 * v1 * v2];
            // ∇N_i = −ℓ_i ν_i / (2 A0): towards node i, of size 1/altitude.
            let gradient_scale = -length2.sqrt() / (2.0 * area);
            fibre_gradients[0][i] = gradient_scale * v1;
            fibre_gradients[1][i] = gradient_scale * v2;
            if kinds[i] == HingeKind::Clamped {
                // Mirror x_i across the line through x_{i+1} along e_i.
                let start = x[(i + 1) % 3];
                let along = edge * ((x[i] - start).dot(&edge) / length2);
                let foot = start + along;
                ghosts[i] = (2.0 * foot - x[i]).into();
            }
        }
        // Node 0's gradient from the other two, so that each row sums to
        // zero exactly and g = F a0 depends on the edges only.
        for row in &mut fibre_gradients {
            row[0] = -(row[1] + row[2]);
        }
        let mut element = Self {
            kinds,
            coefficients,
            reference_curvature: [0.0; 3],
            area,
            ghosts,
            fibre_gradients,
        };
        let reference = element.state(x, &BendingStiffness::new(0.0, 0.0, 0.0)?)?;
        element.reference_curvature = reference.curvature;
        Ok(element)
    }

    /// The partner triangle of edge `i` and the slots of its nodes.
    fn partner(&self, x: &[V3; 6], i: usize) -> Option<(Triangle, [Option<usize>; 3])> {
        let (a, b) = ((i + 2) % 3, (i + 1) % 3);
        match self.kinds[i] {
            HingeKind::Free => None,
            HingeKind::Neighbour => Some((
                Triangle::new([x[a], x[b], x[3 + i]]),
                [Some(a), Some(b), Some(3 + i)],
            )),
            HingeKind::Clamped => Some((
                Triangle::new([x[a], x[b], V3::from(self.ghosts[i])]),
                [Some(a), Some(b), None],
            )),
        }
    }

    fn state(&self, x: &[V3; 6], stiffness: &BendingStiffness) -> Result<State, BendingError> {
        check_finite(x, &self.kinds)?;
        let own = Triangle::new([x[0], x[1], x[2]]);
        if own.is_degenerate() {
            return Err(BendingError::Degenerate {
                area: 0.5 * own.norm,
            });
        }
        let area_ratio = own.norm / (2.0 * self.area);
        let lengths = own.e.map(|e| e.norm());
        let mut hinges = [Hinge {
            partner: None,
            partner_slots: [None; 3],
            measure: 0.0,
            slope: 1.0,
            bend: 0.0,
        }; 3];
        let mut rho = [0.0; 3];
        let mut phi = [0.0; 3];
        for i in 0..3 {
            rho[i] = area_ratio / lengths[i];
            if let Some((partner, slots)) = self.partner(x, i) {
                if partner.is_degenerate() {
                    return Err(BendingError::DegenerateHinge {
                        edge: i,
                        area: 0.5 * partner.norm,
                    });
                }
                let (sin, cos) = hinge_angle(&own, i, &partner);
                let (measure, slope, bend) = if self.kinds[i] == HingeKind::Clamped {
                    clamped_hinge_measure(i, sin, cos)?
                } else {
                    hinge_measure(i, sin, cos)?
                };
                hinges[i] = Hinge {
                    partner: Some(partner),
                    partner_slots: slots,
                    measure,
                    slope,
                    bend,
                };
                phi[i] = measure * rho[i];
            }
        }
        let mut convected = [0.0; 3];
        for (i, c) in self.coefficients.iter().enumerate() {
            for v in 0..3 {
                convected[v] += phi[i] * c[v];
            }
        }
        // g1 = F a0 = Σ_a p_a x_a = p_1 (x_1 − x_0) + p_2 (x_2 − x_0)
        // = p_1 e_2 − p_2 e_1 (Σ_a p_a = 0), likewise g2 (Eq. (5a)).
        let fibres = self
            .fibre_gradients
            .map(|p| own.e[2] * p[1] - own.e[1] * p[2]);
        let stretches = fibres.map(|g| g.norm_squared());
        let (scales, scale_slopes, scale_bends) = stretch_scales(stretches);
        let curvature: [f64; 3] = std::array::from_fn(|v| scales[v] * convected[v]);
        let d = stiffness.diagonal();
        let change: [f64; 3] = std::array::from_fn(|v| curvature[v] - self.reference_curvature[v]);
        let moment: [f64; 3] = std::array::from_fn(|v| self.area * d[v] * change[v]);
        let scaled_moment: [f64; 3] = std::array::from_fn(|v| scales[v] * moment[v]);
        let mu = self
            .coefficients
            .map(|c| c[0] * scaled_moment[0] + c[1] * scaled_moment[1] + c[2] * scaled_moment[2]);
        let stretch_forces: [f64; 2] = std::array::from_fn(|a| {
            (0..3)
                .map(|v| moment[v] * convected[v] * scale_slopes[v][a])
                .sum()
        });
        let energy = 0.5 * (0..3).map(|v| moment[v] * change[v]).sum::<f64>();
        Ok(State {
            own,
            hinges,
            lengths,
            rho,
            fibres,
            stretches,
            scales,
            scale_slopes,
            scale_bends,
            convected,
            curvature,
            change,
            moment,
            mu,
            stretch_forces,
            energy,
        })
    }

    /// The curvature `κ` on the current unit material directions, `Δκ`,
    /// the convected curvature `K`, the squared fibre stretches `I4`, `I8`
    /// and the hinge measures at the current positions `x` \[mm\]
    /// (docs/bending.md, Eqs. (5), (5a)).
    ///
    /// # Errors
    /// A non-finite position, a degenerate own or partner triangle, a
    /// completely folded hinge, a clamped hinge turned to or past 90°
    /// ([`BendingError::OverturnedClamp`]).
    pub fn curvature(&self, x: &[V3; 6]) -> Result<BendingCurvature, BendingError> {
        let s = self.state(x, &BendingStiffness::new(0.0, 0.0, 0.0)?)?;
        Ok(BendingCurvature {
            curvature: s.curvature,
            change: s.change,
            convected: s.convected,
            stretches: s.stretches,
            hinge_measures: s.hinges.map(|h| h.measure),
        })
    }

    /// `W_e = A0 ½ Δκᵀ D Δκ` [N·mm] (docs/bending.md, Eq. (7)).
    ///
    /// # Errors
    /// As [`BendingElement::curvature`].
    pub fn energy(&self, x: &[V3; 6], stiffness: &BendingStiffness) -> Result<f64, BendingError> {
        Ok(self.state(x, stiffness)?.energy)
    }

    /// `∂θ_i/∂x` (18 values) and `∂ρ_i/∂x` (own slots) of hinge `i`
    /// (docs/bending.md, Eqs. (9)–(10)).
    fn hinge_gradients(&self, s: &State, i: usize) -> (StencilVector, StencilVector) {
        let mut grad_theta = StencilVector::zeros();
        let mut grad_rho = StencilVector::zeros();
        let hinge = &s.hinges[i];
        if let Some(partner) = &hinge.partner {
            for (k, g) in s.own.hinge_gradient(i).iter().enumerate() {
                let mut row = grad_theta.fixed_rows_mut::<3>(3 * k);
                row += g;
            }
            for (k, g) in partner.hinge_gradient(2).iter().enumerate() {
                if let Some(slot) = hinge.partner_slots[k] {
                    let mut row = grad_theta.fixed_rows_mut::<3>(3 * slot);
                    row += g;
                }
            }
        }
        let l = s.lengths[i];
        let unit_edge = s.own.e[i] / l;
        let scale = 1.0 / (2.0 * self.area * l);
        for m in 0..3 {
            let g =
                s.own.n.cross(&s.own.e[m]) * scale - unit_edge * (s.rho[i] * edge_sign(i, m) / l);
            grad_rho.fixed_rows_mut::<3>(3 * m).copy_from(&g);
        }
        (grad_theta, grad_rho)
    }

    /// `∂φ_i/∂x = ρ_i m'(θ_i) ∂θ_i/∂x + m_i ∂ρ_i/∂x` (Eq. (8); `m' = cos(θ/2)`
    /// on interior hinges, `2 cos θ` on clamped ones).
    fn phi_gradient(s: &State, i: usize, grads: &(StencilVector, StencilVector)) -> StencilVector {
        let h = &s.hinges[i];
        if h.partner.is_none() {
            return StencilVector::zeros();
        }
        grads.0 * (s.rho[i] * h.slope) + grads.1 * h.measure
    }

    /// `∇I4 = ∂(g1·g1)/∂x` and `∇I8` over the own slots:
    /// `∂I4/∂x_a = 2 (∂N_a/∂a0) g1`, `∂I8/∂x_a = 2 (∂N_a/∂b0) g2`
    /// (docs/bending.md, Eq. (10a)).
    fn stretch_gradients(&self, s: &State) -> [StencilVector; 2] {
        std::array::from_fn(|alpha| {
            let mut gradient = StencilVector::zeros();
            for a in 0..3 {
                gradient
                    .fixed_rows_mut::<3>(3 * a)
                    .copy_from(&(s.fibres[alpha] * (2.0 * self.fibre_gradients[alpha][a])));
            }
            gradient
        })
    }

    /// Energy and internal force
    /// `∂W_e/∂x = Σ_i μ_i ∂φ_i/∂x + (∂W/∂I4) ∇I4 + (∂W/∂I8) ∇I8` \[N\] at the
    /// current positions `x` \[mm\] (docs/bending.md, Eq. (8)).
    ///
    /// # Errors
    /// As [`BendingElement::curvature`].
    pub fn force(
        &self,
        x: &[V3; 6],
        stiffness: &BendingStiffness,
    ) -> Result<BendingForce, BendingError> {
        let s = self.state(x, stiffness)?;
        let mut force = StencilVector::zeros();
        for i in 0..3 {
            let grads = self.hinge_gradients(&s, i);
            force += Self::phi_gradient(&s, i, &grads) * s.mu[i];
        }
        for (gradient, factor) in self.stretch_gradients(&s).iter().zip(s.stretch_forces) {
            force += gradient * factor;
        }
        Ok(BendingForce {
            energy: s.energy,
            force,
        })
    }

    /// `∇κ_v = s_v ∇K_v + K_v Σ_α (∂s_v/∂I_α) ∇I_α` with
    /// `∇K_v = Σ_i c_iv ∇φ_i` (docs/bending.md, Eq. (11a)).
    fn curvature_gradients(
        &self,
        s: &State,
        grad_phi: &[StencilVector; 3],
        grad_stretch: &[StencilVector; 2],
    ) -> [StencilVector; 3] {
        std::array::from_fn(|v| {
            let mut gradient = StencilVector::zeros();
            for i in 0..3 {
                gradient += grad_phi[i] * (s.scales[v] * self.coefficients[i][v]);
            }
            for alpha in 0..2 {
                gradient += grad_stretch[alpha] * (s.convected[v] * s.scale_slopes[v][alpha]);
            }
            gradient
        })
    }

    /// The vectors `u_α = Σ_v M_v (∂s_v/∂I_α) ∇K_v` of the mixed terms
    /// `∇I_α u_αᵀ + u_α ∇I_αᵀ` of the tangent (docs/bending.md, Eq. (11a)).
    fn mixed_vectors(&self, s: &State, grad_phi: &[StencilVector; 3]) -> [StencilVector; 2] {
        std::array::from_fn(|alpha| {
            let mut vector = StencilVector::zeros();
            for i in 0..3 {
                let weight: f64 = (0..3)
                    .map(|v| s.moment[v] * s.scale_slopes[v][alpha] * self.coefficients[i][v])
                    .sum();
                vector += grad_phi[i] * weight;
            }
            vector
        })
    }

    /// `S_αβ = Σ_v M_v K_v ∂²s_v/∂I_α∂I_β` (docs/bending.md, Eq. (11a)).
    fn stretch_hessian(s: &State) -> [[f64; 2]; 2] {
        std::array::from_fn(|alpha| {
            std::array::from_fn(|beta| {
                (0..3)
                    .map(|v| s.moment[v] * s.convected[v] * s.scale_bends[v][alpha][beta])
                    .sum()
            })
        })
    }

    /// Energy, force and the exact tangent [N/mm]
    ///
    /// ```text
    /// ∂²W/∂x² = Σ_v A0 D_v ∇κ_v ∇κ_vᵀ + Σ_i μ_i ∇²φ_i
    ///         + Σ_α (∇I_α u_αᵀ + u_α ∇I_αᵀ) + Σ_αβ S_αβ ∇I_α ∇I_βᵀ
    ///         + Σ_α (∂W/∂I_α) ∇²I_α
    /// ```
    ///
    /// with every term of `∇²φ_i` (the hinge-angle Hessian, the area ratio
    /// and the edge lengths) and of the fibre stretches (docs/bending.md,
    /// Eqs. (11)–(13), (11a)).
    ///
    /// # Errors
    /// As [`BendingElement::curvature`].
    pub fn force_tangent(
        &self,
        x: &[V3; 6],
        stiffness: &BendingStiffness,
    ) -> Result<BendingTangent, BendingError> {
        let s = self.state(x, stiffness)?;
        let mut force = StencilVector::zeros();
        let mut k = StencilMatrix::zeros();
        let mut grad_phi = [StencilVector::zeros(); 3];
        for (i, gp) in grad_phi.iter_mut().enumerate() {
            let grads = self.hinge_gradients(&s, i);
            *gp = Self::phi_gradient(&s, i, &grads);
            force += *gp * s.mu[i];
            let hinge = &s.hinges[i];
            let mu = s.mu[i];
            let Some(partner) = &hinge.partner else {
                continue;
            };
            let (grad_theta, grad_rho) = grads;
            let (rho, measure, slope) = (s.rho[i], hinge.measure, hinge.slope);
            // ρ ∇²m = ρ (m' ∇²θ + m'' ∇θ∇θᵀ), m'' = −θ̂/4 or −m_c (Eq. (11)).
            let theta_scale = mu * rho * slope;
            let own_jac = s.own.hinge_jacobian(i);
            for a in 0..3 {
                for b in 0..3 {
                    add_block(&mut k, a, b, &own_jac[a][b], theta_scale);
                }
            }
            let partner_jac = partner.hinge_jacobian(2);
            for a in 0..3 {
                for b in 0..3 {
                    if let (Some(sa), Some(sb)) = (hinge.partner_slots[a], hinge.partner_slots[b]) {
                        add_block(&mut k, sa, sb, &partner_jac[a][b], theta_scale);
                    }
                }
            }
            add_outer(&mut k, &grad_theta, &grad_theta, mu * rho * hinge.bend);
            // ∇m ∇ρᵀ + ∇ρ ∇mᵀ.
            add_outer_symmetric(&mut k, &grad_theta, &grad_rho, mu * slope);
            // θ̂ ∇²ρ.
            let rho_hess = self.rho_hessian(&s, i);
            for a in 0..3 {
                for b in 0..3 {
                    add_block(&mut k, a, b, &rho_hess[a][b], mu * measure);
                }
            }
        }
        let grad_stretch = self.stretch_gradients(&s);
        for (gradient, factor) in grad_stretch.iter().zip(s.stretch_forces) {
            force += gradient * factor;
        }
        // Gauss–Newton part Σ_v A0 D_v ∇κ_v ∇κ_vᵀ.
        let d = stiffness.diagonal();
        let grad_kappa = self.curvature_gradients(&s, &grad_phi, &grad_stretch);
        for v in 0..3 {
            if d[v] != 0.0 {
                add_outer(&mut k, &grad_kappa[v], &grad_kappa[v], self.area * d[v]);
            }
        }
        // Mixed terms Σ_α (∇I_α u_αᵀ + u_α ∇I_αᵀ).
        for (gradient, mixed) in grad_stretch.iter().zip(self.mixed_vectors(&s, &grad_phi)) {
            // (x_i y_j)·1 is x_i y_j exactly.
            add_outer_symmetric(&mut k, gradient, &mixed, 1.0);
        }
        // Σ_αβ S_αβ ∇I_α ∇I_βᵀ + Σ_α (∂W/∂I_α) ∇²I_α, with the own-node
        // blocks ∂²I4/∂x_a∂x_b = 2 (∂N_a/∂a0)(∂N_b/∂a0) I (Eq. (11a)).
        let stretch_hessian = Self::stretch_hessian(&s);
        for alpha in 0..2 {
            for beta in 0..2 {
                add_outer(
                    &mut k,
                    &grad_stretch[alpha],
                    &grad_stretch[beta],
                    stretch_hessian[alpha][beta],
                );
            }
            let p = &self.fibre_gradients[alpha];
            for a in 0..3 {
                for b in 0..3 {
                    let value = 2.0 * s.stretch_forces[alpha] * p[a] * p[b];
                    for c in 0..3 {
                        k[(3 * a + c, 3 * b + c)] += value;
                    }
                }
            }
        }
        Ok(BendingTangent {
            energy: s.energy,
            force,
            stiffness: k,
        })
    }

    /// `∂²ρ_i/∂x_m∂x_p` over the own nodes (docs/bending.md, Eq. (13)).
    fn rho_hessian(&self, s: &State, i: usize) -> [[M3; 3]; 3] {
        let own = &s.own;
        let l = s.lengths[i];
        let unit_edge = own.e[i] / l;
        let c0 = 1.0 / (2.0 * self.area);
        let projector = M3::identity() - own.n * own.n.transpose();
        let edge_projector = M3::identity() - unit_edge * unit_edge.transpose();
        let grad_area: [V3; 3] = std::array::from_fn(|m| own.n.cross(&own.e[m]));
        let grad_length: [V3; 3] = std::array::from_fn(|m| unit_edge * edge_sign(i, m));
        std::array::from_fn(|m| {
            std::array::from_fn(|p| {
                let hess_area = -own.e[m].cross_matrix() * projector * own.e[p].cross_matrix()
                    / own.norm
                    + own.n.cross_matrix() * edge_sign(m, p);
                let hess_length = edge_projector * (edge_sign(i, m) * edge_sign(i, p) / l);
                (hess_area / l
                    - (grad_area[m] * grad_length[p].transpose()
                        + grad_length[m] * grad_area[p].transpose())
                        / (l * l)
                    + (grad_length[m] * grad_length[p].transpose() * (2.0 / (l * l * l))
                        - hess_length / (l * l))
                        * own.norm)
                    * c0
            })
        })
    }

    /// An upper bound of `λmax(M⁻¹ K_e)` [1/s²] for the element tangent
    /// `K_e` at `x` \[mm\] and lumped masses `masses` \[t\] of the six slots
    /// (only the slots the element uses are read; they must be positive).
    /// The Gauss–Newton part `Σ_v A0 D_v ∇κ_v∇κ_vᵀ` is taken exactly
    /// through a 3×3 eigenvalue; the rest (`Σ μ_i ∇²φ_i` and the
    /// fibre-stretch terms of Eq. (11a)) is bounded by block norms
    /// (docs/bending.md, "Frequency bound"). Where several stencils share a
    /// node, give each the share `m_n / count_n`
    /// ([`super::BendingTopology::stencil_counts`]): then the maximum over
    /// elements bounds the assembled bending term.
    ///
    /// # Errors
    /// As [`BendingElement::curvature`], and
    /// [`BendingError::InvalidMass`] for a used slot whose mass is not
    /// positive and finite.
    pub fn max_frequency_squared(
        &self,
        x: &[V3; 6],
        stiffness: &BendingStiffness,
        masses: &[f64; 6],
    ) -> Result<f64, BendingError> {
        let s = self.state(x, stiffness)?;
        let used = self.used_slots();
        for slot in 0..6 {
            if used[slot] && !(masses[slot] > 0.0 && masses[slot].is_finite()) {
                return Err(BendingError::InvalidMass {
                    slot,
                    mass: masses[slot],
                });
            }
        }
        let mut grad_phi = [StencilVector::zeros(); 3];
        let mut rest = 0.0;
        for (i, gp) in grad_phi.iter_mut().enumerate() {
            let grads = self.hinge_gradients(&s, i);
            *gp = Self::phi_gradient(&s, i, &grads);
            let hinge = &s.hinges[i];
            let Some(partner) = &hinge.partner else {
                continue;
            };
            let (grad_theta, grad_rho) = grads;
            let (rho, measure, slope) = (s.rho[i], hinge.measure, hinge.slope.abs());
            // ‖∇²θ‖_M from block norms over the hinge's slots.
            let blocks = theta_hessian_blocks(&s.own, partner, hinge, i);
            let theta_norm = scaled_block_bound(&blocks, masses, &used);
            let grad_theta_m2 = mass_norm_squared(&grad_theta, masses, &used);
            let grad_rho_m = mass_norm_squared(&grad_rho, masses, &used).sqrt();
            let rho_norm = self.rho_hessian_bound(&s, i, masses);
            let bound = rho * slope * theta_norm
                + rho * hinge.bend.abs() * grad_theta_m2
                + measure.abs() * rho_norm
                + 2.0 * slope * grad_theta_m2.sqrt() * grad_rho_m;
            rest += s.mu[i].abs() * bound;
        }
        // The fibre-stretch terms (Eq. (11a)): mixed terms
        // ‖∇I_α u_αᵀ + u_α ∇I_αᵀ‖ ≤ 2 ‖∇I_α‖ ‖u_α‖, rank-one terms through
        // mass norms, and ∇²I_α = 2 p pᵀ ⊗ I (p the fibre gradients), whose
        // scaled norm is exactly 2 Σ_a p_a² / m_a.
        let grad_stretch = self.stretch_gradients(&s);
        let stretch_norm = grad_stretch.map(|g| mass_norm_squared(&g, masses, &used).sqrt());
        let mixed = self.mixed_vectors(&s, &grad_phi);
        let stretch_hessian = Self::stretch_hessian(&s);
        for alpha in 0..2 {
            rest +=
                2.0 * stretch_norm[alpha] * mass_norm_squared(&mixed[alpha], masses, &used).sqrt();
            for beta in 0..2 {
                rest +=
                    stretch_hessian[alpha][beta].abs() * stretch_norm[alpha] * stretch_norm[beta];
            }
            let p = &self.fibre_gradients[alpha];
            let second: f64 = (0..3).map(|a| 2.0 * p[a] * p[a] / masses[a]).sum();
            rest += s.stretch_forces[alpha].abs() * second;
        }
        // Gauss–Newton part: A0 λmax(D^½ G D^½), G = Yᵀ M⁻¹ Y with the
        // columns Y_v = ∇κ_v.
        let grad_kappa = self.curvature_gradients(&s, &grad_phi, &grad_stretch);
        let g = M3::from_fn(|v, w| {
            let mut sum = 0.0;
            for slot in 0..6 {
                if used[slot] {
                    sum += grad_kappa[v]
                        .fixed_rows::<3>(3 * slot)
                        .dot(&grad_kappa[w].fixed_rows::<3>(3 * slot))
                        / masses[slot];
                }
            }
            sum
        });
        let d = stiffness.diagonal();
        let d_half = M3::from_diagonal(&V3::new(d[0].sqrt(), d[1].sqrt(), d[2].sqrt()));
        let reduced = d_half * g * d_half * self.area;
        let gauss_newton = largest_eigenvalue(&(0.5 * (reduced + reduced.transpose()))).max(0.0);
        Ok(gauss_newton + rest)
    }

    /// A bound of `‖M^{-½} ∇²ρ_i M^{-½}‖₂` from block norms of Eq. (13).
    fn rho_hessian_bound(&self, s: &State, i: usize, masses: &[f64; 6]) -> f64 {
        let used = [true, true, true, false, false, false];
        scaled_block_bound(&self.rho_hessian_blocks(s, i), masses, &used)
    }

    /// The stencil slots the element reads: its own three nodes, and the
    /// partner's far node of every hinge with a neighbour.
    fn used_slots(&self) -> [bool; 6] {
        let mut used = [true, true, true, false, false, false];
        for i in 0..3 {
            used[3 + i] = self.kinds[i] == HingeKind::Neighbour;
        }
        used
    }

    /// Bounds `β_ab ≥ ‖(∇²ρ_i)_ab‖₂` of the 3×3 blocks of Eq. (13) (own
    /// slots only; the others are zero).
    fn rho_hessian_blocks(&self, s: &State, i: usize) -> [[f64; 6]; 6] {
        let own = &s.own;
        let l = s.lengths[i];
        let c0 = 1.0 / (2.0 * self.area);
        let mut blocks = [[0.0; 6]; 6];
        for (m, row) in blocks.iter_mut().enumerate().take(3) {
            for (p, block) in row.iter_mut().enumerate().take(3) {
                let (sm, sp) = (edge_sign(i, m).abs(), edge_sign(i, p).abs());
                let (lm, lp) = (s.lengths[m], s.lengths[p]);
                let area_block = lm * lp / own.norm + edge_sign(m, p).abs();
                *block = c0
                    * (area_block / l
                        + (lm * sp + sm * lp) / (l * l)
                        + own.norm * (2.0 * sm * sp / (l * l * l) + sm * sp / (l * l * l)));
            }
        }
        blocks
    }

    /// Bounds `β_ab ≥ ‖(K_e)_ab‖₂` \[N/mm\] of the 3×3 blocks of the element
    /// tangent `K_e` at `x` \[mm\], slots `a, b` of the stencil (zero where a
    /// slot is unused): the Gauss–Newton part `A0 Σ_v D_v ∇κ_v ∇κ_vᵀ`
    /// through the exact Frobenius norm of each block, the rest through the
    /// block bounds of [`BendingElement::max_frequency_squared`] term by
    /// term (docs/bending.md, "Frequency bound", "Node rows"). With them a
    /// node's row of `M^{-½} K M^{-½}` sums to at most
    /// `Σ_e Σ_b β_ab/√(m_n m_b)` over the stencils at the node, a bound of
    /// the assembled `λmax(M⁻¹ K)` with each node's whole mass.
    ///
    /// # Errors
    /// As [`BendingElement::curvature`].
    pub fn block_bounds(
        &self,
        x: &[V3; 6],
        stiffness: &BendingStiffness,
    ) -> Result<[[f64; 6]; 6], BendingError> {
        let s = self.state(x, stiffness)?;
        let used = self.used_slots();
        let slot_norms = |v: &StencilVector| -> [f64; 6] {
            std::array::from_fn(|slot| {
                if used[slot] {
                    v.fixed_rows::<3>(3 * slot).norm()
                } else {
                    0.0
                }
            })
        };
        let mut beta = [[0.0; 6]; 6];
        let mut grad_phi = [StencilVector::zeros(); 3];
        for (i, gp) in grad_phi.iter_mut().enumerate() {
            let grads = self.hinge_gradients(&s, i);
            *gp = Self::phi_gradient(&s, i, &grads);
            let hinge = &s.hinges[i];
            let Some(partner) = &hinge.partner else {
                continue;
            };
            let (grad_theta, grad_rho) = grads;
            let (rho, measure, slope) = (s.rho[i], hinge.measure, hinge.slope.abs());
            let theta = theta_hessian_blocks(&s.own, partner, hinge, i);
            let rho_blocks = self.rho_hessian_blocks(&s, i);
            let (t, r) = (slot_norms(&grad_theta), slot_norms(&grad_rho));
            let mu = s.mu[i].abs();
            for a in 0..6 {
                for b in 0..6 {
                    beta[a][b] += mu
                        * (rho * slope * theta[a][b]
                            + rho * hinge.bend.abs() * t[a] * t[b]
                            + measure.abs() * rho_blocks[a][b]
                            + slope * (t[a] * r[b] + r[a] * t[b]));
                }
            }
        }
        // The fibre-stretch terms (Eq. (11a)), block by block as in
        // `max_frequency_squared`.
        let grad_stretch = self.stretch_gradients(&s);
        let stretch = grad_stretch.map(|g| slot_norms(&g));
        let mixed = self.mixed_vectors(&s, &grad_phi).map(|v| slot_norms(&v));
        let stretch_hessian = Self::stretch_hessian(&s);
        for alpha in 0..2 {
            let p = &self.fibre_gradients[alpha];
            for a in 0..6 {
                for b in 0..6 {
                    beta[a][b] +=
                        stretch[alpha][a] * mixed[alpha][b] + mixed[alpha][a] * stretch[alpha][b];
                    for gamma in 0..2 {
                        beta[a][b] += stretch_hessian[alpha][gamma].abs()
                            * stretch[alpha][a]
                            * stretch[gamma][b];
                    }
                }
            }
            for a in 0..3 {
                for b in 0..3 {
                    beta[a][b] += s.stretch_forces[alpha].abs() * 2.0 * (p[a] * p[b]).abs();
                }
            }
        }
        // Gauss–Newton part: ‖A0 Σ_v D_v g_v[a] g_v[b]ᵀ‖_F² =
        // A0² Σ_vw D_v D_w (g_v[a]·g_w[a]) (g_v[b]·g_w[b]).
        let grad_kappa = self.curvature_gradients(&s, &grad_phi, &grad_stretch);
        let d = stiffness.diagonal();
        let grams: [M3; 6] = std::array::from_fn(|slot| {
            M3::from_fn(|v, w| {
                grad_kappa[v]
                    .fixed_rows::<3>(3 * slot)
                    .dot(&grad_kappa[w].fixed_rows::<3>(3 * slot))
            })
        });
        for a in 0..6 {
            if !used[a] {
                continue;
            }
            for b in 0..6 {
                if !used[b] {
                    continue;
                }
                let mut frobenius = 0.0;
                for v in 0..3 {
                    for w in 0..3 {
                        frobenius += d[v] * d[w] * grams[a][(v, w)] * grams[b][(v, w)];
                    }
                }
                beta[a][b] += self.area * frobenius.max(0.0).sqrt();
            }
        }
        Ok(beta)
    }
}

/// Bounds `β_ab ≥ ‖(∇²θ_i)_ab‖₂` of the 3×3 blocks of hinge `i`'s angle
/// Hessian over the stencil's slots, from the block norms of both
/// triangles' hinge Jacobians (Eq. (12)).
fn theta_hessian_blocks(
    own: &Triangle,
    partner: &Triangle,
    hinge: &Hinge,
    i: usize,
) -> [[f64; 6]; 6] {
    let mut blocks = [[0.0; 6]; 6];
    let own_bounds = own.hinge_jacobian_bounds(i);
    for a in 0..3 {
        for b in 0..3 {
            blocks[a][b] += own_bounds[a][b];
        }
    }
    let partner_bounds = partner.hinge_jacobian_bounds(2);
    for a in 0..3 {
        for b in 0..3 {
            if let (Some(sa), Some(sb)) = (hinge.partner_slots[a], hinge.partner_slots[b]) {
                blocks[sa][sb] += partner_bounds[a][b];
            }
        }
    }
    blocks
}

/// `‖M^{-½} A M^{-½}‖₂ ≤ max_a Σ_b min(β_ab, β_ba)/√(m_a m_b)` for a
/// symmetric `A` whose blocks satisfy `‖A_ab‖₂ ≤ β_ab` (the spectral radius
/// of a non-negative matrix is at most its largest row sum).
fn scaled_block_bound(blocks: &[[f64; 6]; 6], masses: &[f64; 6], used: &[bool; 6]) -> f64 {
    let mut bound: f64 = 0.0;
    for a in 0..6 {
        if !used[a] {
            continue;
        }
        let mut row = 0.0;
        for b in 0..6 {
            if used[b] {
                row += blocks[a][b].min(blocks[b][a]) / (masses[a] * masses[b]).sqrt();
            }
        }
        bound = bound.max(row);
    }
    bound
}

/// Rejects non-finite positions in the slots the element reads.
fn check_finite(x: &[V3; 6], kinds: &[HingeKind; 3]) -> Result<(), BendingError> {
    for (slot, p) in x.iter().enumerate() {
        let used = slot < 3 || kinds[slot - 3] == HingeKind::Neighbour;
        if used && !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(BendingError::NonFinite { slot });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The in-place rank-one updates give the bits of the matrix
    /// expressions they replace (so the tangent, and every run, is the same
    /// as with them), on entries of mixed signs and magnitudes.
    #[test]
    fn in_place_rank_one_updates_match_the_matrix_expressions_bit_for_bit() {
        let entry =
            |k: usize, seed: f64| (seed * (k as f64 + 1.3)).sin() * 10f64.powi(k as i32 % 7 - 3);
        let x = StencilVector::from_fn(|k, _| entry(k, 0.77));
        let y = StencilVector::from_fn(|k, _| entry(k, 1.91));
        let start = StencilMatrix::from_fn(|i, j| entry(i * 18 + j, 0.13));
        let s = -0.3719;
        let mut expected = start;
        expected += x * y.transpose() * s;
        let mut k = start;
        add_outer(&mut k, &x, &y, s);
        assert_eq!(k.as_slice(), expected.as_slice());
        let mut expected = start;
        let c = x * y.transpose() * s;
        expected += c + c.transpose();
        let mut k = start;
        add_outer_symmetric(&mut k, &x, &y, s);
        assert_eq!(k.as_slice(), expected.as_slice());
        // Without a scale: `s = 1` is exact.
        let mut expected = start;
        let product = x * y.transpose();
        expected += product + product.transpose();
        let mut k = start;
        add_outer_symmetric(&mut k, &x, &y, 1.0);
        assert_eq!(k.as_slice(), expected.as_slice());
    }
}
