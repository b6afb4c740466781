//! A forming run's states (`docs/cases.md`, "Forming outputs"): every
//! ply's VTU with its strain, invariant, stress, curvature and contact
//! fields, the VTU of its projection on the blank plane (the 2D
//! image-correlation view), its maps, and every tool's VTU, at each output
//! state.

use std::path::Path;

use super::maps::{write_defect_maps, write_maps};
use super::readout::{DicColumns, dic_measures};
use crate::case::forming::FormingCase;
use crate::case::forming_model::{BuiltTool, FormingModel};
use crate::model::Model;
use crate::post::defects::{
    DefectAreas, DefectThresholds, ElementDefects, defect_areas, element_defects,
    membrane_line_forces, principal_curvatures,
};
use crate::post::fields::{FieldColumns, element_fields};
use crate::post::orientation::{ElementOrientation, element_orientations};
use crate::post::vtu::{Field, FieldData, VtuPiece, write_vtu};
use crate::report::folder::Outputs;
use crate::report::{UNITS, io_err};

/// A file-name stem from a ply or tool name: the name with every
/// character but ASCII letters, digits and `-` replaced by `_` (the run's
/// `vtu/` and `maps/` files; the hand-off finds them by it).
pub fn file_stem(name: &str) -> String {
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
    /// Per node, the smallest gap to a tool acting on the ply \[mm\]
    /// (`+∞` where none answers); `None` when no tool acts on the ply.
    tool_gap: Option<Vec<f64>>,
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

/// The contact figures of ply `p` (with the nodes' gaps to the tools when
/// the displacement `u` is given).
pub(super) fn contact_fields(
    built: &FormingModel,
    p: usize,
    model: &Model,
    u: Option<&[f64]>,
) -> ContactFields {
    let ply = &built.plies[p];
    let count = ply.mesh.nodes.len();
    let mut c = ContactFields {
        status: vec![0; count],
        normal_force: vec![0.0; count],
        pressure: vec![0.0; count],
        friction_force: vec![0.0; count],
        slip: vec![0.0; count],
        tool_gap: None,
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
        let on_ply = term
            .nodes()
            .iter()
            .any(|&n| n >= ply.node_offset && n - ply.node_offset < count);
        if on_ply && let Some(u) = u {
            let gaps = c.tool_gap.get_or_insert_with(|| vec![f64::INFINITY; count]);
            for (&node, gap) in term.nodes().iter().zip(term.node_gaps(u)) {
                if let Some(n) = node.checked_sub(ply.node_offset).filter(|n| *n < count) {
                    gaps[n] = gaps[n].min(gap);
                }
            }
        }
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
    /// The ply's defect areas (`None` when the state's fields could not be
    /// evaluated).
    pub defects: Option<crate::post::defects::DefectAreas>,
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
                defects: None,
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
    let hand_off = HandOffColumns::new(case, built, p, u, &points, contact, &fields);
    let mut cell_fields = columns.cell_fields();
    cell_fields.extend(hand_off.cell_fields());
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
            ORIENTATION_NOTE.into(),
            DEFECTS_NOTE.into(),
            hand_off.thresholds_line(),
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
        let stem = map_paths
            .2
            .file_name()
            .map(|f| f.to_string_lossy().replace("-modes_", "-defects_"))
            .unwrap_or_default();
        let defects_path = map_paths.2.with_file_name(stem);
        write_defect_maps(
            (case, built, p),
            u,
            &hand_off.defects,
            &defects_path,
            caption,
            files,
        );
    }
    PlyState {
        areas: Some(crate::post::forming::mode_areas(&modes, &areas)),
        ply: ply_written,
        projection,
        defects: Some(hand_off.areas()),
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

/// What the orientation fields of a ply's VTU are (its comment line).
const ORIENTATION_NOTE: &str = "a0, b0: reference roving and stitching directions; fibre_direction a = F a0/|F a0|, transverse_direction b = F b0/|F b0| (unit, global axes); fibre_angle_deg: from the rosette's reference to a about the element normal (node order), in (-90, 90]; fibre_angle_deviation_deg: less the ply's design angle; rosette_use: 0 direction, 1 fallback, 2 degenerate (angle 0); area_ratio J; areal_mass [kg/m^2] and thickness [mm] scale with 1/J (thickness at the reference fibre volume fraction); orientation_valid 0 where the element collapsed (fields 0) (docs/cases.md)";

/// What the defect fields of a ply's VTU are (its comment line).
const DEFECTS_NOTE: &str = "tool_gap [mm]: mid-surface to the nearest tool acting on the ply less half the contact thickness (-1: no tool); curvature_1 >= curvature_2 [1/mm] principal, max_curvature |k|max; membrane_force_1 >= membrane_force_2 [N/mm] principal, fibre_line_force a.n.a [N/mm]; tension_field 0 taut, 1 wrinkled, 2 slack; gap_width = max(E_perp, 0) x roving pitch [mm]; wrinkled (gap and curvature above their thresholds), gapping, waviness_risk 0/1; defect_class 0 none, 1 wrinkled, 2 gapping, 3 waviness risk (docs/cases.md, Defect indicators)";

/// The hand-off and defect fields of one ply at one state, as VTU
/// columns (`docs/cases.md`, "Orientation fields", "Defect indicators").
struct HandOffColumns {
    thresholds: DefectThresholds,
    current_areas: Vec<f64>,
    pub(super) defects: Vec<ElementDefects>,
    vectors: [Vec<[f64; 3]>; 4],
    scalars: Vec<(&'static str, Vec<f64>)>,
    ints: Vec<(&'static str, Vec<i32>)>,
}

impl HandOffColumns {
    #[allow(clippy::too_many_arguments)]
    fn new(
        case: &FormingCase,
        built: &FormingModel,
        p: usize,
        u: &[f64],
        points: &[[f64; 3]],
        contact: &ContactFields,
        fields: &[crate::post::fields::ElementFields],
    ) -> Self {
        let ply = &built.plies[p];
        let spec = &case.plies[p];
        let triangles = &ply.mesh.triangles;
        let orientations =
            element_orientations(&ply.membrane, u, &case.rosette, spec.fibre_angle_deg);
        let thresholds = case.defects.thresholds(spec);
        let curvatures = principal_curvatures(points, triangles);
        let defects: Vec<ElementDefects> = (0..triangles.len())
            .map(|e| {
                let tool_gap = contact.tool_gap.as_ref().and_then(|gaps| {
                    let g = triangles[e].map(|n| gaps[n]);
                    if g.iter().all(|x| x.is_finite()) {
                        Some(g.iter().sum::<f64>() / 3.0)
                    } else {
                        g.into_iter().filter(|x| x.is_finite()).reduce(f64::min)
                    }
                });
                let forces = membrane_line_forces(&ply.membrane, e, u).unwrap_or(([0.0; 2], 0.0));
                element_defects(
                    tool_gap,
                    curvatures[e],
                    forces,
                    fields[e].e_perp,
                    &thresholds,
                )
            })
            .collect();
        let reference_areas: Vec<f64> = ply.membrane.references.iter().map(|r| r.area).collect();
        let zero = [0.0; 3];
        let pick = |f: fn(&ElementOrientation) -> [f64; 3]| -> Vec<[f64; 3]> {
            orientations
                .iter()
                .map(|o| o.as_ref().map_or(zero, f))
                .collect()
        };
        let vectors = [pick(|o| o.a0), pick(|o| o.b0), pick(|o| o.a), pick(|o| o.b)];
        let scalar = |f: &dyn Fn(&ElementOrientation) -> f64| -> Vec<f64> {
            orientations
                .iter()
                .map(|o| o.as_ref().map_or(0.0, f))
                .collect()
        };
        let area_ratio = scalar(&|o| o.area_ratio);
        let current_areas: Vec<f64> = orientations
            .iter()
            .zip(&reference_areas)
            .map(|(o, a)| o.as_ref().map_or(0.0, |o| o.area_ratio * a))
            .collect();
        let per_j = |base: f64| scalar(&|o| base / o.area_ratio);
        let mut scalars = vec![
            ("fibre_angle_deg", scalar(&|o| o.fibre_angle_deg)),
            (
                "fibre_angle_deviation_deg",
                scalar(&|o| o.fibre_angle_deviation_deg),
            ),
            ("area_ratio", area_ratio),
            ("thickness", per_j(spec.thickness)),
        ];
        if let Some(density) = spec.density {
            // tonne/mm² to kg/m²: 1e9.
            scalars.push(("areal_mass", per_j(density * spec.thickness * 1.0e9)));
        }
        let defect = |f: fn(&ElementDefects) -> f64| defects.iter().map(f).collect::<Vec<f64>>();
        scalars.extend([
            ("tool_gap", defect(|d| d.tool_gap.unwrap_or(-1.0))),
            ("curvature_1", defect(|d| d.curvatures[0])),
            ("curvature_2", defect(|d| d.curvatures[1])),
            ("max_curvature", defect(ElementDefects::max_curvature)),
            ("membrane_force_1", defect(|d| d.line_forces[0])),
            ("membrane_force_2", defect(|d| d.line_forces[1])),
            ("fibre_line_force", defect(|d| d.fibre_line_force)),
            ("gap_width", defect(|d| d.gap_width)),
        ]);
        let flag = |f: fn(&ElementDefects) -> bool| {
            defects
                .iter()
                .map(|d| i32::from(f(d)))
                .collect::<Vec<i32>>()
        };
        let ints = vec![
            (
                "element_label",
                (0..triangles.len())
                    .map(|e| i32::try_from(ply.mesh.element_label(e)).unwrap_or(-1))
                    .collect(),
            ),
            (
                "orientation_valid",
                orientations
                    .iter()
                    .map(|o| i32::from(o.is_some()))
                    .collect(),
            ),
            (
                "rosette_use",
                orientations
                    .iter()
                    .map(|o| o.as_ref().map_or(2, |o| o.rosette as i32))
                    .collect(),
            ),
            (
                "tension_field",
                defects.iter().map(|d| d.tension_field as i32).collect(),
            ),
            ("wrinkled", flag(|d| d.wrinkled)),
            ("gapping", flag(|d| d.gapping)),
            ("waviness_risk", flag(|d| d.waviness_risk)),
            (
                "defect_class",
                defects.iter().map(|d| i32::from(d.class())).collect(),
            ),
        ];
        Self {
            thresholds,
            current_areas,
            defects,
            vectors,
            scalars,
            ints,
        }
    }

    /// The cell fields.
    fn cell_fields(&self) -> Vec<Field<'_>> {
        let names = ["a0", "b0", "fibre_direction", "transverse_direction"];
        let mut out: Vec<Field<'_>> = names
            .iter()
            .zip(&self.vectors)
            .map(|(name, v)| Field {
                name,
                data: FieldData::Vector3(v),
            })
            .collect();
        out.extend(self.scalars.iter().map(|(name, v)| Field {
            name,
            data: FieldData::Scalar(v),
        }));
        out.extend(self.ints.iter().map(|(name, v)| Field {
            name,
            data: FieldData::Int(v),
        }));
        out
    }

    /// The thresholds, as a comment line.
    fn thresholds_line(&self) -> String {
        let t = &self.thresholds;
        format!(
            "defect thresholds: tool_gap {} mm, curvature {} 1/mm, slack_line_force {} N/mm, waviness_line_force {} N/mm, roving_pitch {} mm, gap_width {} mm",
            t.tool_gap,
            t.curvature,
            t.slack_line_force,
            t.waviness_line_force,
            t.roving_pitch,
            t.gap_width
        )
    }

    /// The areas above the thresholds.
    fn areas(&self) -> DefectAreas {
        defect_areas(&self.defects, &self.current_areas, &self.thresholds)
    }
}
