//! Per-element result fields of a membrane model at a displacement: the
//! paper's strain measures (Section 4: `E22 = I8 − 1`, `γ = I10`,
//! `E⊥ = I11 − 1`, not Green–Lagrange), the invariants, `k11` and the
//! second Piola–Kirchhoff stress in global axes. Reads results, changes
//! nothing.

use super::vtu::{Field, FieldData};
use crate::material::{Invariants, MaterialError, MembraneMaterial};
use crate::model::MembraneModel;

/// Fields of one element.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ElementFields {
    /// `E22 = I8 − 1` (stitching strain).
    pub e22: f64,
    /// Shear angle `γ = I10` \[deg\].
    pub shear_angle_deg: f64,
    /// `E⊥ = I11 − 1` (strain across the current rovings).
    pub e_perp: f64,
    /// `I4`.
    pub i4: f64,
    /// `I6`.
    pub i6: f64,
    /// `I8`.
    pub i8: f64,
    /// `I11`.
    pub i11: f64,
    /// `k11(I11)` (1 for a law without coupling).
    pub k11: f64,
    /// Energy density `W` \[MPa\].
    pub energy_density: f64,
    /// `S` in global axes `[Sxx, Syy, Sxy]` \[MPa\] (reference configuration;
    /// in-plane components for a membrane in the xy-plane).
    pub stress_xy: [f64; 3],
}

/// Fields of every element at displacement `u` (all dofs, \[mm\]).
///
/// # Errors
/// The first element whose state the law rejects, with its index.
pub fn element_fields(
    model: &MembraneModel,
    u: &[f64],
) -> Result<Vec<ElementFields>, (usize, MaterialError)> {
    (0..model.triangles.len())
        .map(|e| {
            let reference = &model.references[e];
            let x = model.element_displacements(e, u);
            let kin = reference.kinematics(&x);
            let inv = Invariants::new(&kin.c, &reference.frame).map_err(|err| (e, err))?;
            let state = model
                .material
                .stress(&kin.c, &reference.frame)
                .map_err(|err| (e, err))?;
            let k11 = model.material.coupling_factor(inv.i11);
            // S_global = R S Rᵀ with R = [e1 e2] (3×2); keep xx, yy, xy.
            let s = state.stress;
            let (e1, e2) = (reference.e1, reference.e2);
            let comp = |i: usize, j: usize| {
                s[0] * e1[i] * e1[j] + s[1] * e2[i] * e2[j] + s[2] * (e1[i] * e2[j] + e2[i] * e1[j])
            };
            Ok(ElementFields {
                e22: inv.i8 - 1.0,
                shear_angle_deg: inv.i10().to_degrees(),
                e_perp: inv.i11 - 1.0,
                i4: inv.i4,
                i6: inv.i6,
                i8: inv.i8,
                i11: inv.i11,
                k11,
                energy_density: state.energy,
                stress_xy: [comp(0, 0), comp(1, 1), comp(0, 1)],
            })
        })
        .collect()
}

/// Reference-area-weighted mean of `value` over `elements`.
pub fn area_mean(model: &MembraneModel, elements: &[usize], value: impl Fn(usize) -> f64) -> f64 {
    let (sum, area) = elements.iter().fold((0.0, 0.0), |(s, a), &e| {
        let w = model.references[e].area;
        (s + w * value(e), a + w)
    });
    if area > 0.0 { sum / area } else { 0.0 }
}

/// The fields of every element as columns, for VTU cell fields.
#[derive(Debug, Clone, Default)]
pub struct FieldColumns {
    e22: Vec<f64>,
    shear_angle_deg: Vec<f64>,
    e_perp: Vec<f64>,
    i4: Vec<f64>,
    i6: Vec<f64>,
    i8: Vec<f64>,
    i11: Vec<f64>,
    k11: Vec<f64>,
    energy_density: Vec<f64>,
    stress_xy: Vec<[f64; 3]>,
}

impl FieldColumns {
    /// The columns of `fields`.
    pub fn new(fields: &[ElementFields]) -> Self {
        let column = |f: fn(&ElementFields) -> f64| fields.iter().map(f).collect::<Vec<f64>>();
        Self {
            e22: column(|f| f.e22),
            shear_angle_deg: column(|f| f.shear_angle_deg),
            e_perp: column(|f| f.e_perp),
            i4: column(|f| f.i4),
            i6: column(|f| f.i6),
            i8: column(|f| f.i8),
            i11: column(|f| f.i11),
            k11: column(|f| f.k11),
            energy_density: column(|f| f.energy_density),
            stress_xy: fields.iter().map(|f| f.stress_xy).collect(),
        }
    }

    /// The VTU cell fields `E22`, `shear_angle_deg`, `E_perp`, `I4`, `I6`,
    /// `I8`, `I11`, `k11`, `energy_density` and the tensor `S`.
    pub fn cell_fields(&self) -> Vec<Field<'_>> {
        vec![
            Field {
                name: "E22",
                data: FieldData::Scalar(&self.e22),
            },
            Field {
                name: "shear_angle_deg",
                data: FieldData::Scalar(&self.shear_angle_deg),
            },
            Field {
                name: "E_perp",
                data: FieldData::Scalar(&self.e_perp),
            },
            Field {
                name: "I4",
                data: FieldData::Scalar(&self.i4),
            },
            Field {
                name: "I6",
                data: FieldData::Scalar(&self.i6),
            },
            Field {
                name: "I8",
                data: FieldData::Scalar(&self.i8),
            },
            Field {
                name: "I11",
                data: FieldData::Scalar(&self.i11),
            },
            Field {
                name: "k11",
                data: FieldData::Scalar(&self.k11),
            },
            Field {
                name: "energy_density",
                data: FieldData::Scalar(&self.energy_density),
            },
            Field {
                name: "S",
                data: FieldData::SymTensor2(&self.stress_xy),
            },
        ]
    }
}
