//! What a forming run reads on the blank and writes for it
//! (`docs/forming.md`, "Outputs"): the draw-in at the edge midpoints and
//! corners and the zone means at every history row, the outer contours at
//! the output states, the maps of γ, E22 and E⊥ as the camera sees the
//! plies, and the 2D image-correlation view (the formed mesh projected on
//! the blank plane, strains recomputed on the projection).

use std::path::Path;

use serde::Serialize;

use super::io_err;
use super::run_folder::Outputs;
use crate::case::forming::{FormingCase, MapView, ToolMotion};
use crate::case::forming_model::FormingModel;
use crate::post::contour::{ContourMap, write_contour_png_viewed};
use crate::post::csv::write_csv;
use crate::post::fields::ElementFields;
use crate::post::forming::{
    DrawInPoint, StrainMeasures, boundary_displacement, deformation_mode, draw_in, draw_in_points,
    mode_areas, outer_boundary, strain_measure, strain_measures, weighted_mean_std,
};
use crate::post::plot::{Panel, Series, Series as Outline, write_outlines_png, write_panels};
use crate::solver::RunStatus;

/// One ply's blank: its outer boundary and draw-in points.
struct PlyBlank {
    offset: usize,
    outer: Vec<usize>,
    reference: Vec<[f64; 2]>,
    points: Vec<DrawInPoint>,
}

/// The zone means of one state.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ZoneValue {
    /// Area-weighted mean shear angle γ \[deg\].
    pub shear_angle_mean: f64,
    /// Its area-weighted standard deviation \[deg\].
    pub shear_angle_std: f64,
    /// Mean `E22`.
    pub e22_mean: f64,
    /// Mean `E⊥`.
    pub e_perp_mean: f64,
    /// Share of the zone's area in each deformation mode 0–4
    /// ([`crate::post::forming::deformation_mode`]) \[-\].
    pub mode_fractions: [f64; crate::post::forming::MODES],
}

/// What is read on the blanks of a forming case.
pub struct Readout {
    plies: Vec<PlyBlank>,
    /// Per zone of the case: its elements (model element indices of its
    /// ply's membrane).
    zones: Vec<Vec<usize>>,
    /// The tool whose displacement is the stroke (the prescribed tool that
    /// moves farthest), if any.
    pub stroke_tool: Option<usize>,
    /// The floating tools, whose lift is reported.
    pub floating_tools: Vec<usize>,
}

impl Readout {
    /// Finds each ply's outer boundary, its draw-in points and each zone's
    /// elements.
    ///
    /// # Errors
    /// A ply without a boundary, or a zone without an element, naming the
    /// case file and the zone.
    pub fn new(case: &FormingCase, built: &FormingModel) -> Result<Self, String> {
        let mut plies = Vec::new();
        for ply in &built.plies {
            let reference: Vec<[f64; 2]> = ply.mesh.nodes.iter().map(|x| [x.x, x.y]).collect();
            let outer = outer_boundary(&reference, &ply.mesh.triangles).ok_or_else(|| {
                format!(
                    "{}: ply \"{}\": the mesh has no boundary, so no outer contour or draw-in",
                    case.source, ply.name
                )
            })?;
            let points = draw_in_points(&reference, &outer);
            plies.push(PlyBlank {
                offset: ply.node_offset,
                outer,
                reference,
                points,
            });
        }
        let mut zones = Vec::new();
        for (i, z) in case.zones.iter().enumerate() {
            let elements = z.zone.elements(&built.plies[z.ply].membrane);
            if elements.is_empty() {
                return Err(format!(
                    "{}: zone[{i}] (\"{}\"): no element of ply \"{}\" has its centroid in the window centred at [{}, {}] mm of size [{}, {}] mm; expected a window on the blank",
                    case.source,
                    z.zone.name,
                    built.plies[z.ply].name,
                    z.zone.centre[0],
                    z.zone.centre[1],
                    z.zone.size[0],
                    z.zone.size[1]
                ));
            }
            zones.push(elements);
        }
        let stroke_tool = built
            .tools
            .iter()
            .enumerate()
            .filter_map(|(i, t)| match t.spec.motion {
                ToolMotion::Prescribed { displacement, .. } => Some((i, displacement.abs())),
                _ => None,
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i);
        let floating_tools = built
            .tools
            .iter()
            .enumerate()
            .filter(|(_, t)| matches!(t.spec.motion, ToolMotion::Floating { .. }))
            .map(|(i, _)| i)
            .collect();
        Ok(Self {
            plies,
            zones,
            stroke_tool,
            floating_tools,
        })
    }

    /// The draw-in points of every ply.
    pub fn points(&self) -> Vec<&[DrawInPoint]> {
        self.plies.iter().map(|p| p.points.as_slice()).collect()
    }

    /// Per ply, the draw-in \[mm\] at each of its points at displacement `u`.
    pub fn draw_in(&self, u: &[f64]) -> Vec<Vec<f64>> {
        self.plies
            .iter()
            .map(|p| {
                p.points
                    .iter()
                    .map(|point| {
                        let d = boundary_displacement(point, &p.outer, |n| {
                            let g = p.offset + n;
                            [u[3 * g], u[3 * g + 1]]
                        });
                        draw_in(point, d)
                    })
                    .collect()
            })
            .collect()
    }

    /// Per zone, the means at displacement `u`, over its elements whose
    /// strain measures are defined.
    pub fn zones(&self, case: &FormingCase, built: &FormingModel, u: &[f64]) -> Vec<ZoneValue> {
        case.zones
            .iter()
            .zip(&self.zones)
            .map(|(z, elements)| {
                let membrane = &built.plies[z.ply].membrane;
                let measures: Vec<(f64, StrainMeasures)> = elements
                    .iter()
                    .filter_map(|&e| {
                        strain_measure(membrane, e, u).map(|m| (membrane.references[e].area, m))
                    })
                    .collect();
                let of = |f: fn(&StrainMeasures) -> f64| {
                    weighted_mean_std(measures.iter().map(|(a, m)| (*a, f(m))))
                };
                let (shear_angle_mean, shear_angle_std) = of(|m| m.shear_angle_deg);
                let modes: Vec<u8> = measures
                    .iter()
                    .map(|(_, m)| deformation_mode(1.0 + m.e22, 1.0 + m.e_perp))
                    .collect();
                let areas: Vec<f64> = measures.iter().map(|(a, _)| *a).collect();
                let total: f64 = areas.iter().sum();
                let mut mode_fractions = mode_areas(&modes, &areas);
                for f in &mut mode_fractions {
                    *f = if total > 0.0 { *f / total } else { 0.0 };
                }
                ZoneValue {
                    shear_angle_mean,
                    shear_angle_std,
                    e22_mean: of(|m| m.e22).0,
                    e_perp_mean: of(|m| m.e_perp).0,
                    mode_fractions,
                }
            })
            .collect()
    }

    /// Per ply, its outer contour at displacement `u`, projected on the
    /// blank plane \[mm\].
    pub fn outlines(&self, u: &[f64]) -> Vec<Vec<[f64; 2]>> {
        self.plies
            .iter()
            .map(|p| {
                p.outer
                    .iter()
                    .map(|&n| {
                        let g = p.offset + n;
                        [
                            p.reference[n][0] + u[3 * g],
                            p.reference[n][1] + u[3 * g + 1],
                        ]
                    })
                    .collect()
            })
            .collect()
    }

    /// Per ply, its outer contour in the reference configuration \[mm\].
    pub fn reference_outlines(&self) -> Vec<Vec<[f64; 2]>> {
        self.plies
            .iter()
            .map(|p| p.outer.iter().map(|&n| p.reference[n]).collect())
            .collect()
    }

    /// Per ply, the labels of its outer contour's nodes.
    fn outline_labels(&self, built: &FormingModel) -> Vec<Vec<i64>> {
        self.plies
            .iter()
            .zip(&built.plies)
            .map(|(p, ply)| p.outer.iter().map(|&n| ply.mesh.node_label(n)).collect())
            .collect()
    }
}

/// The outer contours of every ply at the output states.
#[derive(Debug, Clone, Serialize)]
pub struct OutlineState {
    /// Programme fraction.
    pub load: f64,
    /// Stroke \[mm\] (the stroke tool's displacement, or `λ` without one).
    pub stroke: f64,
    /// Per ply, the contour points projected on the blank plane \[mm\].
    #[serde(skip)]
    pub outlines: Vec<Vec<[f64; 2]>>,
}

/// `outer_contour.csv` and `outer_contour.png`: every ply's outer contour
/// at every output state, with the reference blank; `labels`: the files'
/// status line and the stroke's name. Each file is recorded in `files`,
/// whatever became of the other.
pub fn write_outer_contours(
    case: &FormingCase,
    built: &FormingModel,
    readout: &Readout,
    states: &[OutlineState],
    out: &Path,
    (status, stroke_label): (&RunStatus, &str),
    files: &mut Outputs,
) {
    let reference = readout.reference_outlines();
    let labels = readout.outline_labels(built);
    let mut header = vec![
        "ply [-]".to_string(),
        "node [-]".to_string(),
        "reference x [mm]".into(),
        "reference y [mm]".into(),
    ];
    for s in states {
        header.push(format!("x at {stroke_label} = {:.3} [mm]", s.stroke));
        header.push(format!("y at {stroke_label} = {:.3} [mm]", s.stroke));
    }
    let mut rows = Vec::new();
    for (p, outline) in reference.iter().enumerate() {
        for (k, x0) in outline.iter().enumerate() {
            let mut row = vec![(p + 1) as f64, labels[p][k] as f64, x0[0], x0[1]];
            for s in states {
                row.extend(s.outlines[p][k]);
            }
            rows.push(row);
        }
    }
    let path = out.join("outer_contour.csv");
    let header_refs: Vec<&str> = header.iter().map(String::as_str).collect();
    let plies: Vec<String> = built
        .plies
        .iter()
        .enumerate()
        .map(|(i, p)| format!("{} = \"{}\"", i + 1, p.name))
        .collect();
    let written = write_csv(
        &path,
        &[
            "ncform run: outer contour of each ply, projected on the blank plane (z dropped), in order along the boundary".to_string(),
            format!("case: {} ({})", case.title, case.source),
            super::form::status_line(status),
            format!("plies: {}", plies.join(", ")),
            "units: mm".into(),
        ],
        &header_refs,
        &rows,
    )
    .map_err(|e| io_err(&path, e));
    files.record(&path, written);
    let mut outlines = Vec::new();
    for (p, ply) in built.plies.iter().enumerate() {
        let name = if built.plies.len() > 1 {
            format!("{}: ", ply.name)
        } else {
            String::new()
        };
        outlines.push(Outline {
            label: format!("{name}blank"),
            points: reference[p].iter().map(|x| (x[0], x[1])).collect(),
        });
        for s in states {
            outlines.push(Outline {
                label: format!("{name}{stroke_label} = {:.1} mm", s.stroke),
                points: s.outlines[p].iter().map(|x| (x[0], x[1])).collect(),
            });
        }
    }
    let incomplete = super::plot_suffix(status);
    let path = out.join("outer_contour.png");
    let written = write_outlines_png(
        &path,
        &format!("outer contour, seen from above{incomplete}"),
        &outlines,
        900,
    );
    files.record(&path, written);
}

/// One history row of `forming.csv`.
pub struct BlankRow {
    /// Stroke \[mm\].
    pub stroke: f64,
    /// The stroke tool's force \[N\].
    pub force: f64,
    /// Per floating tool, its lift: displacement against its direction \[mm\].
    pub lifts: Vec<f64>,
    /// Per ply, the draw-in at its points \[mm\].
    pub draw_in: Vec<Vec<f64>>,
    /// Per zone.
    pub zones: Vec<ZoneValue>,
}

/// `forming.csv` and `forming.png`: stroke force, lift of the floating
/// tools, draw-in and zone means against the stroke; `labels`: the files'
/// status line and the stroke's name. Each file is recorded in `files`,
/// whatever became of the other.
pub fn write_forming_history(
    case: &FormingCase,
    built: &FormingModel,
    readout: &Readout,
    rows: &[BlankRow],
    out: &Path,
    (status, stroke_label): (&RunStatus, &str),
    files: &mut Outputs,
) {
    let floating: Vec<&str> = readout
        .floating_tools
        .iter()
        .map(|&t| built.tools[t].spec.name.as_str())
        .collect();
    let stroke_name = readout
        .stroke_tool
        .map_or("stroke", |t| built.tools[t].spec.name.as_str());
    let mut header = vec![
        format!("{stroke_label} [mm]"),
        format!("{stroke_name} force [N]"),
    ];
    for f in &floating {
        header.push(format!("{f} lift [mm]"));
    }
    for (ply, points) in built.plies.iter().zip(readout.points()) {
        for point in points {
            header.push(format!("{} draw-in {} [mm]", ply.name, point.name));
        }
    }
    for z in &case.zones {
        header.push(format!("zone {} shear angle mean [deg]", z.zone.name));
        header.push(format!("zone {} shear angle std [deg]", z.zone.name));
        header.push(format!("zone {} E22 mean [-]", z.zone.name));
        header.push(format!("zone {} E_perp mean [-]", z.zone.name));
        header.push(format!("zone {} mixed-mode 1 share [-]", z.zone.name));
        header.push(format!("zone {} mixed-mode 2 share [-]", z.zone.name));
    }
    let data: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| {
            let mut row = vec![r.stroke, r.force];
            row.extend(&r.lifts);
            for d in &r.draw_in {
                row.extend(d);
            }
            for z in &r.zones {
                row.extend([
                    z.shear_angle_mean,
                    z.shear_angle_std,
                    z.e22_mean,
                    z.e_perp_mean,
                    z.mode_fractions[1],
                    z.mode_fractions[2],
                ]);
            }
            row
        })
        .collect();
    let path = out.join("forming.csv");
    let header_refs: Vec<&str> = header.iter().map(String::as_str).collect();
    let zones: Vec<String> = case
        .zones
        .iter()
        .map(|z| {
            format!(
                "{} on ply \"{}\" centred at [{}, {}] mm, {} x {} mm",
                z.zone.name,
                built.plies[z.ply].name,
                z.zone.centre[0],
                z.zone.centre[1],
                z.zone.size[0],
                z.zone.size[1]
            )
        })
        .collect();
    let mut comments = vec![
        "ncform run: forming history read on the blank".to_string(),
        format!("case: {} ({})", case.title, case.source),
        super::form::status_line(status),
        "lift: displacement of a floating tool against its direction (positive when the plies push it back); draw-in: in-plane displacement of the blank's edge midpoints and corners towards the blank's centre (positive inwards)".into(),
        "zones: reference-area-weighted mean and standard deviation over the elements whose reference centroid lies in the window; gamma = I10, E22 = I8 - 1, E_perp = I11 - 1 (paper Section 4)".into(),
    ];
    if !zones.is_empty() {
        comments.push(format!("zones: {}", zones.join("; ")));
    }
    comments.push("units: mm, N; angles in degrees".into());
    let written = write_csv(&path, &comments, &header_refs, &data).map_err(|e| io_err(&path, e));
    files.record(&path, written);

    let incomplete = super::plot_suffix(status);
    let x_label = format!("{stroke_label} [mm]");
    let curve = |label: String, f: &dyn Fn(&BlankRow) -> f64| Series {
        label,
        points: rows.iter().map(|r| (r.stroke, f(r))).collect(),
    };
    let mut panels = vec![Panel {
        title: format!("{stroke_name} force{incomplete}"),
        x_label: x_label.clone(),
        y_label: "force [N]".into(),
        series: vec![curve(String::new(), &|r| r.force)],
    }];
    if !floating.is_empty() {
        panels.push(Panel {
            title: format!("lift of the floating tools{incomplete}"),
            x_label: x_label.clone(),
            y_label: "lift [mm]".into(),
            series: floating
                .iter()
                .enumerate()
                .map(|(i, f)| curve((*f).to_string(), &|r| r.lifts[i]))
                .collect(),
        });
    }
    for (p, (ply, points)) in built.plies.iter().zip(readout.points()).enumerate() {
        panels.push(Panel {
            title: format!("draw-in, ply \"{}\"{incomplete}", ply.name),
            x_label: x_label.clone(),
            y_label: "draw-in [mm]".into(),
            series: points
                .iter()
                .enumerate()
                .map(|(k, point)| curve(point.name.clone(), &|r| r.draw_in[p][k]))
                .collect(),
        });
    }
    if !case.zones.is_empty() {
        panels.push(Panel {
            title: format!("zone shear angle (mean){incomplete}"),
            x_label,
            y_label: "shear angle γ [deg]".into(),
            series: case
                .zones
                .iter()
                .enumerate()
                .map(|(k, spec)| {
                    curve(format!("zone {}", spec.zone.name), &|r| {
                        r.zones[k].shear_angle_mean
                    })
                })
                .collect(),
        });
    }
    let cols = 2.min(panels.len());
    let grid = panels.len().div_ceil(cols);
    let path = out.join("forming.png");
    let written = write_panels(
        &path,
        &panels,
        (grid, cols),
        (700 * cols as u32, 520 * grid as u32),
    );
    files.record(&path, written);
}

/// The per-element strain measures of the 2D image-correlation view, as
/// VTU columns: zero where the projected triangle is turned over (then
/// `dic_valid` is 0).
pub struct DicColumns {
    /// γ on the projection \[deg\].
    pub shear_angle_deg: Vec<f64>,
    /// `E22` on the projection.
    pub e22: Vec<f64>,
    /// `E⊥` on the projection.
    pub e_perp: Vec<f64>,
    /// 1 where defined, 0 where the projected triangle is turned over.
    pub valid: Vec<i32>,
}

impl DicColumns {
    /// The columns of `measures`.
    pub fn new(measures: &[Option<StrainMeasures>]) -> Self {
        let column = |f: fn(&StrainMeasures) -> f64| {
            measures
                .iter()
                .map(|m| m.as_ref().map_or(0.0, f))
                .collect::<Vec<f64>>()
        };
        Self {
            shear_angle_deg: column(|m| m.shear_angle_deg),
            e22: column(|m| m.e22),
            e_perp: column(|m| m.e_perp),
            valid: measures.iter().map(|m| i32::from(m.is_some())).collect(),
        }
    }
}

/// The 2D image-correlation measures of ply `p` at displacement `u`.
pub fn dic_measures(built: &FormingModel, p: usize, u: &[f64]) -> Vec<Option<StrainMeasures>> {
    let ply = &built.plies[p];
    let projected = crate::post::forming::projected_displacement(
        u,
        ply.node_offset..ply.node_offset + ply.mesh.nodes.len(),
    );
    strain_measures(&ply.membrane, &projected)
}

/// `maps/<ply>_NNNN.png` (γ, E22, E⊥ of the formed ply),
/// `maps/<ply>-dic_NNNN.png` (the same recomputed on the projection) and
/// `maps/<ply>-modes_NNNN.png` (the deformation modes) of ply `p` of the
/// case `(case, built, p)`, as `case.camera` sees the ply; each recorded
/// in `files`, whatever became of the others.
#[allow(clippy::too_many_arguments)]
pub fn write_maps(
    (case, built, p): (&FormingCase, &FormingModel, usize),
    u: &[f64],
    fields: &[ElementFields],
    dic: &[Option<StrainMeasures>],
    modes: &[u8],
    paths: (&Path, &Path, &Path),
    caption: &str,
    files: &mut Outputs,
) {
    let ply = &built.plies[p];
    let offset = ply.node_offset;
    let points: Vec<[f64; 2]> = ply
        .deformed_positions(u)
        .iter()
        .map(|x| [x[0], x[1]])
        .collect();
    // Painter's order for the camera: the triangles farthest from it first.
    let height = |e: usize| {
        ply.mesh.triangles[e]
            .iter()
            .map(|&n| ply.mesh.nodes[n].z + u[3 * (offset + n) + 2])
            .sum::<f64>()
    };
    let mut order: Vec<usize> = (0..ply.mesh.triangles.len()).collect();
    let heights: Vec<f64> = order.iter().map(|&e| height(e)).collect();
    match case.camera {
        MapView::Below => order.sort_by(|a, b| heights[*b].total_cmp(&heights[*a])),
        MapView::Above => order.sort_by(|a, b| heights[*a].total_cmp(&heights[*b])),
    }
    let triangles: Vec<[usize; 3]> = order.iter().map(|&e| ply.mesh.triangles[e]).collect();
    let view = match case.camera {
        MapView::Below => "from below",
        MapView::Above => "from above",
    };
    // γ, E22, E⊥ in drawing order; NaN (grey) where not defined.
    let columns = |measure: &dyn Fn(usize) -> Option<StrainMeasures>| -> [Vec<f64>; 3] {
        let pick = |f: fn(&StrainMeasures) -> f64| {
            order
                .iter()
                .map(|&e| measure(e).as_ref().map_or(f64::NAN, f))
                .collect()
        };
        [
            pick(|m| m.shear_angle_deg),
            pick(|m| m.e22),
            pick(|m| m.e_perp),
        ]
    };
    let true_values = columns(&|e| {
        Some(StrainMeasures {
            shear_angle_deg: fields[e].shear_angle_deg,
            e22: fields[e].e22,
            e_perp: fields[e].e_perp,
        })
    });
    let dic_values = columns(&|e| dic[e]);
    let labels = ["γ [deg]", "E22 = I8 − 1 [-]", "E⊥ = I11 − 1 [-]"];
    let names = ["γ", "E22", "E⊥"];
    for (values, path, what) in [
        (&true_values, paths.0, "formed ply"),
        (&dic_values, paths.1, "2D DIC view"),
    ] {
        let maps: Vec<ContourMap> = (0..3)
            .map(|k| ContourMap {
                title: format!("{}: {what}, {view}, {caption}", names[k]),
                points: &points,
                triangles: &triangles,
                values: &values[k],
                label: labels[k].into(),
                range: None,
            })
            .collect();
        let written = write_contour_png_viewed(path, &maps, (2100, 720), case.camera);
        files.record(path, written);
    }
    let mode_values: Vec<f64> = order.iter().map(|&e| f64::from(modes[e])).collect();
    let map = ContourMap {
        title: format!("deformation mode: formed ply, {view}, {caption}"),
        points: &points,
        triangles: &triangles,
        values: &mode_values,
        label: "mode: 0 none, 1 I11<1 I8≤1, 2 I11<1 I8>1, 3 I11≥1 I8>1, 4 I11≥1 I8≤1".into(),
        range: Some((0.0, 4.0)),
    };
    let written = write_contour_png_viewed(paths.2, &[map], (900, 720), case.camera);
    files.record(paths.2, written);
}
