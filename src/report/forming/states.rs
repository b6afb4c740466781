//! A forming run's states (`docs/cases.md`, "Forming outputs"): every
//! ply's VTU with its strain, invariant, stress, curvature and contact
//! fields, the VTU of its projection on the blank plane (the 2D
//! image-correlation view), its maps, and every tool's VTU, at each output
//! state.

use std::path::Path;

use super::maps::write_maps;
use super::readout::{DicColumns, dic_measures};
use crate::case::forming::FormingCase;
use crate::case::forming_model::{BuiltTool, FormingModel};
use crate::model::Model;
use crate::post::fields::{FieldColumns, element_fields};
use crate::post::vtu::{Field, FieldData, VtuPiece, write_vtu};
use crate::report::folder::Outputs;
use crate::report::{UNITS, io_err};

/// A file-name stem from a ply or tool name.
pub(super) fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// One tool's VTU at its displacement `q` along its direction.
pub(super) fn write_tool_vtu(
    path: &Path,
    case: &FormingCase,
    tool: &BuiltTool,
    q: f64,
    load: f64,
) -> Result<(), crate::report::WriteError> {
    let shift = q * tool.direction;
    let points: Vec<[f64; 3]> = tool
        .drawing
        .vertices
        .iter()
        .map(|v| [v.x + shift.x, v.y + shift.y, v.z + shift.z])
        .collect();
    let piece = VtuPiece {
        points: &points,
        triangles: &tool.drawing.triangles,
        point_fields: vec![],
        cell_fields: vec![],
        comment: vec![
            format!(
                "ncform: {} ({}), tool \"{}\"",
                case.title, case.source, tool.spec.name
            ),
            format!("programme fraction {load}; tool displacement {q} mm along its direction"),
            format!("units: {UNITS}"),
        ],
    };
    write_vtu(path, &piece).map_err(|e| io_err(path, e))
}

/// Per node of ply `p`, the contact figures summed (forces, slip) or
/// combined (status: the largest, gap: the smallest) over every tool, and
/// likewise over every ply–ply contact.
pub(super) struct ContactFields {
    status: Vec<i32>,
    normal_force: Vec<f64>,
    pressure: Vec<f64>,
    friction_force: Vec<f64>,
    slip: Vec<f64>,
    /// Contact with other plies: status (0 open, 1 stick, 2 slip), the
    /// node's own normal force [N] and the mid-surface gap [mm] (largest
    /// status, summed forces, smallest gap over the ply contacts).
    ply_status: Vec<i32>,
    ply_normal_force: Vec<f64>,
    ply_gap: Vec<f64>,
    /// Each ply–ply contact of the ply on its own, in term order: the
    /// figures of its nodes against the other ply.
    interfaces: Vec<InterfaceFields>,
}

/// One ply–ply contact seen from one of its plies: per node of the ply,
/// its own spring's figures against the other ply (`docs/cases.md`,
/// "Forming outputs").
struct InterfaceFields {
    /// The VTU array names, `ply_contact_<quantity>[<other ply>]`.
    names: [String; 6],
    status: Vec<i32>,
    normal_force: Vec<f64>,
    pressure: Vec<f64>,
    gap: Vec<f64>,
    slip: Vec<f64>,
    friction_dissipation: Vec<f64>,
}

pub(super) fn contact_fields(built: &FormingModel, p: usize, model: &Model) -> ContactFields {
    let ply = &built.plies[p];
    let count = ply.mesh.nodes.len();
    let mut c = ContactFields {
        status: vec![0; count],
        normal_force: vec![0.0; count],
        pressure: vec![0.0; count],
        friction_force: vec![0.0; count],
        slip: vec![0.0; count],
        ply_status: vec![0; count],
        ply_normal_force: vec![0.0; count],
        ply_gap: vec![f64::INFINITY; count],
        interfaces: Vec::new(),
    };
    for term in model.terms_of::<crate::model::PlyContact>() {
        for k in 0..2 {
            if term.ply_name(k) != ply.name {
                continue;
            }
            let other = term.ply_name(1 - k);
            let mut face = InterfaceFields {
                names: [
                    "status",
                    "normal_force",
                    "pressure",
                    "gap",
                    "slip",
                    "friction_dissipation",
                ]
                .map(|q| format!("ply_contact_{q}[{other}]")),
                status: vec![0; count],
                normal_force: vec![0.0; count],
                pressure: vec![0.0; count],
                gap: vec![-1.0; count],
                slip: vec![0.0; count],
                friction_dissipation: vec![0.0; count],
            };
            for (((&node, contact), area), (slip, dissipated)) in term
                .ply_nodes(k)
                .iter()
                .zip(term.node_contacts(k))
                .zip(term.ply_areas(k))
                .zip(term.node_friction(k))
            {
                let Some(n) = node.checked_sub(ply.node_offset).filter(|n| *n < count) else {
                    continue;
                };
                c.ply_status[n] = c.ply_status[n].max(contact.status as i32);
                c.ply_normal_force[n] += contact.normal_force;
                c.ply_gap[n] = c.ply_gap[n].min(contact.gap);
                face.status[n] = contact.status as i32;
                face.normal_force[n] = contact.normal_force;
                if *area > 0.0 {
                    face.pressure[n] = contact.normal_force / area;
                }
                if contact.gap.is_finite() {
                    face.gap[n] = contact.gap;
                }
                face.slip[n] = slip;
                face.friction_dissipation[n] = dissipated;
            }
            c.interfaces.push(face);
        }
    }
    // VTU readers take finite values: a node far from every other ply
    // shows gap -1 (documented).
    for g in &mut c.ply_gap {
        if !g.is_finite() {
            *g = -1.0;
        }
    }
    for term in model.terms_of::<crate::model::ToolContact>() {
        for ((&node, contact), area) in term
            .nodes()
            .iter()
            .zip(term.node_contacts())
            .zip(term.areas())
        {
            let Some(n) = node.checked_sub(ply.node_offset).filter(|n| *n < count) else {
                continue;
            };
            c.status[n] = c.status[n].max(contact.status as i32);
            c.normal_force[n] += contact.normal_force;
            if *area > 0.0 {
                c.pressure[n] += contact.normal_force / area;
            }
            c.friction_force[n] += contact.friction_force;
            c.slip[n] += contact.slip;
        }
    }
    c
}

/// What [`write_ply_state`] wrote.
pub(super) struct PlyState {
    /// The reference area of each deformation mode (`None` when the
    /// state's fields could not be evaluated).
    pub areas: Option<[f64; crate::post::forming::MODES]>,
    /// The ply's VTU is written.
    pub ply: bool,
    /// The VTU of its projection is written.
    pub projection: bool,
}

/// One ply at an output state: its VTU (with the image-correlation fields
/// beside the true ones), the VTU of its projection on the blank plane, and
/// its maps (`paths`: ply VTU, projection VTU, the three map PNGs), each
/// recorded in `files` whatever became of the others.
#[allow(clippy::too_many_arguments)]
pub(super) fn write_ply_state(
    paths: (&Path, &Path, (&Path, &Path, &Path)),
    case: &FormingCase,
    built: &FormingModel,
    p: usize,
    (u, contact, ply_contact): (&[f64], &ContactFields, bool),
    (load, note): (f64, &str),
    caption: &str,
    files: &mut Outputs,
) -> PlyState {
    let (path, dic_path, map_paths) = paths;
    let ply = &built.plies[p];
    let offset = ply.node_offset;
    let count = ply.mesh.nodes.len();
    let points = ply.deformed_positions(u);
    let displacement: Vec<[f64; 3]> = (0..count)
        .map(|n| {
            let g = offset + n;
            [u[3 * g], u[3 * g + 1], u[3 * g + 2]]
        })
        .collect();
    let fields = match element_fields(&ply.membrane, u) {
        Ok(fields) => fields,
        Err((e, err)) => {
            files.record_missing(
                &format!(
                    "the VTU files and maps of ply \"{}\" at programme fraction {load}",
                    ply.name
                ),
                format!("element {}: {err}", ply.mesh.element_label(e)),
            );
            return PlyState {
                areas: None,
                ply: false,
                projection: false,
            };
        }
    };
    let dic = dic_measures(built, p, u);
    let dic_columns = DicColumns::new(&dic);
    let dic_fields = || dic_cell_fields(&dic_columns);
    let columns = FieldColumns::new(&fields);
    let modes: Vec<u8> = fields
        .iter()
        .map(|f| crate::post::forming::deformation_mode(f.i8, f.i11))
        .collect();
    let mode_codes: Vec<i32> = modes.iter().map(|m| i32::from(*m)).collect();
    let areas: Vec<f64> = ply.membrane.references.iter().map(|r| r.area).collect();
    let mut cell_fields = columns.cell_fields();
    cell_fields.extend(dic_fields());
    cell_fields.push(Field {
        name: "deformation_mode",
        data: FieldData::Int(&mode_codes),
    });
    let dic_note = "dic_*: gamma, E22, E_perp recomputed on the mesh projected on the blank plane (2D image correlation, docs/forming.md); 0 where dic_valid = 0 (projected triangle turned over)";
    let point_fields = ply_point_fields(&displacement, contact, ply_contact);
    let piece = VtuPiece {
        points: &points,
        triangles: &ply.mesh.triangles,
        point_fields,
        cell_fields,
        comment: vec![
            format!(
                "ncform: {} ({}), ply \"{}\"",
                case.title, case.source, ply.name
            ),
            format!("programme fraction {load}{note}"),
            format!("units: {UNITS}; E22 = I8-1, E_perp = I11-1 (paper Section 4)"),
            "S: second Piola-Kirchhoff stress [MPa] in the reference global x-y axes (xx, yy, xy)"
                .into(),
            dic_note.into(),
            "deformation_mode (to 0.1 %): 0 near the reference state, 1 I11<1 & I8<=1 (mixed-mode 1), 2 I11<1 & I8>1 (mixed-mode 2), 3 I11>=1 & I8>1, 4 I11>=1 & I8<=1 (docs/forming.md)".into(),
        ],
    };
    let ply_written = files.write(path, |p| write_vtu(p, &piece).map_err(|e| io_err(path, e)));
    let projected: Vec<[f64; 3]> = ply
        .mesh
        .nodes
        .iter()
        .zip(&points)
        .map(|(x, q)| [q[0], q[1], x.z])
        .collect();
    let dic_piece = VtuPiece {
        points: &projected,
        triangles: &ply.mesh.triangles,
        point_fields: vec![Field {
            name: "displacement",
            data: FieldData::Vector3(&displacement),
        }],
        cell_fields: dic_fields(),
        comment: vec![
            format!(
                "ncform: {} ({}), ply \"{}\", projected on the blank plane",
                case.title, case.source, ply.name
            ),
            format!("programme fraction {load}{note}"),
            format!("units: {UNITS}"),
            dic_note.into(),
        ],
    };
    let projection = files.write(dic_path, |p| {
        write_vtu(p, &dic_piece).map_err(|e| io_err(dic_path, e))
    });
    if case.maps {
        write_maps(
            (case, built, p),
            u,
            &fields,
            &dic,
            &modes,
            map_paths,
            caption,
            files,
        );
    }
    PlyState {
        areas: Some(crate::post::forming::mode_areas(&modes, &areas)),
        ply: ply_written,
        projection,
    }
}

/// The image-correlation cell fields of a ply's VTU and of its projection.
fn dic_cell_fields(dic: &DicColumns) -> Vec<Field<'_>> {
    vec![
        Field {
            name: "dic_shear_angle_deg",
            data: FieldData::Scalar(&dic.shear_angle_deg),
        },
        Field {
            name: "dic_E22",
            data: FieldData::Scalar(&dic.e22),
        },
        Field {
            name: "dic_E_perp",
            data: FieldData::Scalar(&dic.e_perp),
        },
        Field {
            name: "dic_valid",
            data: FieldData::Int(&dic.valid),
        },
    ]
}

/// The point fields of a ply's VTU: the displacement and the contact
/// figures (with the ply–ply ones when the model has ply–ply contact).
fn ply_point_fields<'a>(
    displacement: &'a [[f64; 3]],
    contact: &'a ContactFields,
    ply_contact: bool,
) -> Vec<Field<'a>> {
    let mut point_fields = vec![
        Field {
            name: "displacement",
            data: FieldData::Vector3(displacement),
        },
        Field {
            name: "contact_status",
            data: FieldData::Int(&contact.status),
        },
        Field {
            name: "contact_pressure",
            data: FieldData::Scalar(&contact.pressure),
        },
        Field {
            name: "contact_normal_force",
            data: FieldData::Scalar(&contact.normal_force),
        },
        Field {
            name: "friction_force",
            data: FieldData::Scalar(&contact.friction_force),
        },
        Field {
            name: "slip",
            data: FieldData::Scalar(&contact.slip),
        },
    ];
    if ply_contact {
        point_fields.extend([
            Field {
                name: "ply_contact_status",
                data: FieldData::Int(&contact.ply_status),
            },
            Field {
                name: "ply_contact_normal_force",
                data: FieldData::Scalar(&contact.ply_normal_force),
            },
            Field {
                name: "ply_contact_gap",
                data: FieldData::Scalar(&contact.ply_gap),
            },
        ]);
        for face in &contact.interfaces {
            let [status, normal_force, pressure, gap, slip, dissipation] = &face.names;
            point_fields.push(Field {
                name: status,
                data: FieldData::Int(&face.status),
            });
            point_fields.extend(
                [
                    (normal_force, &face.normal_force),
                    (pressure, &face.pressure),
                    (gap, &face.gap),
                    (slip, &face.slip),
                    (dissipation, &face.friction_dissipation),
                ]
                .map(|(name, values)| Field {
                    name,
                    data: FieldData::Scalar(values),
                }),
            );
        }
    }
    point_fields
}
