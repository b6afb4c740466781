//! Node-to-rigid-surface contact and Coulomb friction kernels.
//!
//! A ply node at world position `x` touches a rigid tool that may translate
//! along a fixed axis `a` by its own degree of freedom `q`. Everything is
//! written in the relative position `y = x − q a`, where the tool answers a
//! [`SurfacePoint`] (`d(y)`, `n = ∇d`, `H = ∇²d`). The gap of the ply's
//! mid-surface is `g = d − offset` (`offset` = half the ply thickness).
//!
//! Two kernels share the conventions below (all in `docs/contact-kernels.md`):
//!
//! - [`implicit`]: augmented Lagrangian (Uzawa) normal contact and
//!   Coulomb friction with the exact consistent tangent, for the Newton
//!   solver;
//! - [`explicit`]: penalty normal contact and a regularised Coulomb law
//!   (elastic–plastic tangential spring) with energy bookkeeping, for the
//!   central-difference solver; [`lanes`] runs it on four pairs at once.
//!
//! Sign convention: the contact force on the node is `f_c = t_N n − t_T`
//! (`t_N ≥ 0` the normal force, `t_T` the friction force vector, which
//! points along the slip and acts against it); the kernels return the
//! residual `r_y = −f_c` (the solver's `r = f_int − f_ext`) and, for the
//! implicit kernel, `K = ∂r_y/∂y`. [`couple_tool_translation`] expands both
//! to the four dofs `(x, q)`.
//!
//! The slip increment (both kernels, Sec. "Slip measure" of the doc) is
//! `Δs = P (y − y_ref)` with `P = I − n⊗n` at the current `y`: the
//! tangential part of the node's relative motion since the reference.

pub mod compaction;
pub mod explicit;
pub mod implicit;
pub mod lanes;

pub use compaction::{CompactionLaw, NodalCompaction};
pub use explicit::{
    PenaltyContact, PenaltyResponse, PenaltyState, max_curvature, normal_dashpot,
    stable_penalty_stiffness,
};
pub use implicit::{
    AugmentationNorms, AugmentationReport, AugmentedLagrangian, ImplicitContactState,
    ImplicitResponse, Smoothing,
};
pub use lanes::{
    PenaltyBatch, PenaltyInput, PenaltyOutput, penalty_lanes, penalty_lanes_one_by_one,
};

use nalgebra::{Matrix3, Matrix4, Vector3, Vector4};

use super::SurfacePoint;

/// The state of a node–tool pair after a kernel call.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ContactStatus {
    /// No contact force: the node is off the tool (or exactly at the
    /// opening point of the explicit law).
    Open,
    /// In contact, the friction force below the Coulomb limit: no slip in
    /// the implicit kernel, elastic tangential spring in the explicit one.
    Stick,
    /// In contact and sliding: the friction force is at the Coulomb limit
    /// `μ t_N` (always the case for frictionless contact, `μ = 0`).
    Slip,
}

impl ContactStatus {
    /// The code the outputs carry: 0 open, 1 stick, 2 slip.
    pub fn code(self) -> u8 {
        match self {
            ContactStatus::Open => 0,
            ContactStatus::Stick => 1,
            ContactStatus::Slip => 2,
        }
    }
}

/// Bad settings or inputs of a contact kernel. Never replaced by NaN.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ContactError {
    /// A contact setting out of its range.
    #[error("contact setting `{name}` = {value:e}: expected {expected}")]
    InvalidSetting {
        /// The setting's name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What was expected.
        expected: &'static str,
    },
    /// A position, surface answer or state component that is not finite or
    /// out of its range.
    #[error("contact input `{name}` = {value:e}: expected {expected}")]
    InvalidInput {
        /// The input's name.
        name: &'static str,
        /// The offending value (the first bad component of a vector).
        value: f64,
        /// What was expected.
        expected: &'static str,
    },
    /// The surface's normal is not a unit vector (the [`SurfacePoint`]
    /// contract).
    #[error("surface normal of length {length:e}: expected a unit vector (|n| − 1 within 1e-6)")]
    NormalNotUnit {
        /// `|n|`.
        length: f64,
    },
    /// The response overflowed (penalties or states so large that a force
    /// or stiffness is not representable).
    #[error("contact response `{name}` is not finite: the penalties or the state overflow")]
    NonFiniteResult {
        /// Which output.
        name: &'static str,
    },
}

/// The contact residual and tangent expanded to the four dofs `(x, q)` of a
/// node and a tool translating along `a`: see [`couple_tool_translation`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolCoupled {
    /// `[r_x; r_q] = [r_y; −a·r_y]`.
    pub residual: Vector4<f64>,
    /// `[[K, −K a]; [−aᵀK, aᵀ K a]]`.
    pub tangent: Matrix4<f64>,
}

/// Expands a residual `r_y` and tangent `K = ∂r_y/∂y`, written in the
/// relative position `y = x − q a`, to the dofs `(x, q)` of the node and
/// the tool (doc Sec. "Tool translation"): `∂/∂x = ∂/∂y` and
/// `∂/∂q = −a·∂/∂y`, so
///
/// ```text
/// r = [r_y; −a·r_y],   K4 = [[K, −K a]; [−aᵀ K, aᵀ K a]]
/// ```
///
/// `a` is the tool's (unit) translation axis; the formulas hold for any
/// `a`. For the explicit kernel pass a zero tangent: the force on the tool
/// dof is `−residual[3]`.
#[inline]
pub fn couple_tool_translation(
    axis: &Vector3<f64>,
    residual: &Vector3<f64>,
    tangent: &Matrix3<f64>,
) -> ToolCoupled {
    let k_a = tangent * axis;
    let at_k = axis.transpose() * tangent;
    let mut r4 = Vector4::zeros();
    r4.fixed_rows_mut::<3>(0).copy_from(residual);
    r4[3] = -axis.dot(residual);
    let mut k4 = Matrix4::zeros();
    k4.fixed_view_mut::<3, 3>(0, 0).copy_from(tangent);
    k4.fixed_view_mut::<3, 1>(0, 3).copy_from(&(-k_a));
    k4.fixed_view_mut::<1, 3>(3, 0).copy_from(&(-at_k));
    k4[(3, 3)] = axis.dot(&k_a);
    ToolCoupled {
        residual: r4,
        tangent: k4,
    }
}

/// The mid-surface gap `g = d − offset` \[mm\] (doc Sec. "Gap"): negative
/// when the ply penetrates the tool.
#[inline]
pub fn gap(point: &SurfacePoint, offset: f64) -> f64 {
    point.distance - offset
}

/// Tolerance on `|n| − 1` for a surface's normal.
const UNIT_TOLERANCE: f64 = 1e-6;

/// `Err` unless every component of `v` is finite.
#[inline]
pub(crate) fn check_vector(name: &'static str, v: &Vector3<f64>) -> Result<(), ContactError> {
    match v.iter().find(|c| !c.is_finite()) {
        None => Ok(()),
        Some(&value) => Err(ContactError::InvalidInput {
            name,
            value,
            expected: "a finite value",
        }),
    }
}

/// `Err` unless `value` is finite.
#[inline]
pub(crate) fn check_scalar(name: &'static str, value: f64) -> Result<(), ContactError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ContactError::InvalidInput {
            name,
            value,
            expected: "a finite value",
        })
    }
}

/// Checks a surface's answer: finite distance, normal and Hessian, unit
/// normal. The Hessian's symmetry and `H n = 0` are the surface's contract
/// and are not checked here.
#[inline]
pub(crate) fn check_point(point: &SurfacePoint) -> Result<(), ContactError> {
    check_scalar("surface distance", point.distance)?;
    check_vector("surface normal", &point.normal)?;
    if let Some(&value) = point.hessian.iter().find(|c| !c.is_finite()) {
        return Err(ContactError::InvalidInput {
            name: "surface hessian",
            value,
            expected: "a finite value",
        });
    }
    let length = point.normal.norm();
    if (length - 1.0).abs() > UNIT_TOLERANCE {
        return Err(ContactError::NormalNotUnit { length });
    }
    Ok(())
}

/// `Ok(value)` if `value` is finite and `> 0`, else the setting error.
pub(crate) fn positive(name: &'static str, value: f64) -> Result<f64, ContactError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(ContactError::InvalidSetting {
            name,
            value,
            expected: "a finite value > 0",
        })
    }
}

/// `Ok(value)` if `value` is finite and `≥ 0`, else the setting error.
pub(crate) fn non_negative(name: &'static str, value: f64) -> Result<f64, ContactError> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(ContactError::InvalidSetting {
            name,
            value,
            expected: "a finite value ≥ 0",
        })
    }
}

/// `Err(NonFiniteResult)` unless every entry is finite.
#[inline]
pub(crate) fn finite_result<'a>(
    name: &'static str,
    values: impl IntoIterator<Item = &'a f64>,
) -> Result<(), ContactError> {
    if values.into_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(ContactError::NonFiniteResult { name })
    }
}
