//! The pictures of a forming run's blanks: the outer contours of every
//! ply at the output states (`outer_contour.csv`, `.png`) and the maps of
//! γ, E22, E⊥ and the deformation modes of each ply, as the camera sees it
//! (`maps/`; `docs/forming.md`, "Outputs").

use std::path::Path;

use serde::Serialize;

use super::history::status_line;
use super::readout::Readout;
use crate::case::forming::{FormingCase, MapView};
use crate::case::forming_model::FormingModel;
use crate::post::contour::{
    CATEGORY_COLOURS, Category, ContourMap, LabelledPolyline, MapOverlay,
    write_contour_png_overlaid, write_contour_png_viewed,
};
use crate::post::csv::write_csv;
use crate::post::defects::{DEFECT_CLASSES, ElementDefects};
use crate::post::fields::ElementFields;
use crate::post::forming::StrainMeasures;
use crate::post::plot::{Series as Outline, write_outlines_png};
use crate::report::folder::Outputs;
use crate::report::{io_err, plot_suffix};
use crate::solver::RunStatus;

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
    files.write(&path, |p| write_csv(
        p,
        &[
            "ncform run: outer contour of each ply, projected on the blank plane (z dropped), in order along the boundary".to_string(),
            format!("case: {} ({})", case.title, case.source),
            status_line(status),
            format!("plies: {}", plies.join(", ")),
            "units: mm".into(),
        ],
        &header_refs,
        &rows,
    )
    .map_err(|e| io_err(&path, e)));
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
    let incomplete = plot_suffix(status);
    let path = out.join("outer_contour.png");
    files.write(&path, |p| {
        write_outlines_png(
            p,
            &format!("outer contour, seen from above{incomplete}"),
            &outlines,
            900,
        )
    });
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
        files.write(path, |p| {
            write_contour_png_viewed(p, &maps, (2100, 720), case.camera)
        });
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
    files.write(paths.2, |p| {
        write_contour_png_viewed(p, &[map], (900, 720), case.camera)
    });
}

/// The outlines of the tools at `u`, projected on the blank plane: the
/// boundary loops of each tool's drawing (a punch's rim, a die's opening
/// and outer edge), or, for a closed drawing (a spherical punch), its
/// silhouette from above (the convex hull of its vertices), labelled with
/// the tool's name.
pub fn tool_outlines(built: &FormingModel, u: &[f64]) -> Vec<LabelledPolyline> {
    let mut outlines = Vec::new();
    for tool in &built.tools {
        let shift = u[tool.dof] * tool.direction;
        let drawing = &tool.drawing;
        let loops = crate::post::forming::boundary_loops(&drawing.triangles);
        if loops.is_empty() {
            // A closed surface (a sphere, a pyramid's drawing) has no
            // boundary: its silhouette seen along z, the convex hull.
            let points: Vec<[f64; 2]> = drawing
                .vertices
                .iter()
                .map(|v| [v.x + shift.x, v.y + shift.y])
                .collect();
            outlines.push(LabelledPolyline {
                label: tool.spec.name.clone(),
                points: convex_hull(points),
                closed: true,
            });
        }
        for (k, boundary) in loops.iter().enumerate() {
            outlines.push(LabelledPolyline {
                label: if k == 0 {
                    tool.spec.name.clone()
                } else {
                    format!("{} ({})", tool.spec.name, k + 1)
                },
                points: boundary
                    .iter()
                    .map(|&n| {
                        let v = drawing.vertices[n];
                        [v.x + shift.x, v.y + shift.y]
                    })
                    .collect(),
                closed: true,
            });
        }
    }
    outlines
}

/// The convex hull of `points`, counter-clockwise (Andrew's monotone
/// chain); fewer than three points come back as they are.
fn convex_hull(mut points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    points.retain(|p| p[0].is_finite() && p[1].is_finite());
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let turn = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * points.len());
    for pass in [points.clone(), points.iter().rev().copied().collect()] {
        let start = hull.len();
        for p in pass {
            while hull.len() >= start + 2
                && turn(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// `maps/<ply>-defects_NNNN.png`: the defect class of every element of
/// ply `p` (none, wrinkled, gapping, waviness risk; `docs/cases.md`,
/// "Defect indicators") beside the gap to the tool and the largest
/// principal curvature, as `case.camera` sees the ply, with the tools'
/// outlines; recorded in `files`.
pub fn write_defect_maps(
    (case, built, p): (&FormingCase, &FormingModel, usize),
    u: &[f64],
    defects: &[ElementDefects],
    path: &Path,
    caption: &str,
    files: &mut Outputs,
) {
    let ply = &built.plies[p];
    let points: Vec<[f64; 2]> = ply
        .deformed_positions(u)
        .iter()
        .map(|x| [x[0], x[1]])
        .collect();
    let outlines = tool_outlines(built, u);
    let view = match case.camera {
        MapView::Below => "from below",
        MapView::Above => "from above",
    };
    let classes: Vec<f64> = defects.iter().map(|d| f64::from(d.class())).collect();
    let categories: Vec<Category> = DEFECT_CLASSES
        .iter()
        .zip(CATEGORY_COLOURS)
        .map(|(name, colour)| Category {
            name: (*name).to_string(),
            colour,
        })
        .collect();
    let class_map = ContourMap {
        title: format!("defects: formed ply, {view}, {caption}"),
        points: &points,
        triangles: &ply.mesh.triangles,
        values: &classes,
        label: "defect".into(),
        range: None,
    };
    files.write(path, |p| {
        write_contour_png_overlaid(
            p,
            &[class_map],
            (1000, 720),
            case.camera,
            &MapOverlay {
                outlines: &outlines,
                categories: Some(&categories),
            },
        )
    });
    let gaps: Vec<f64> = defects
        .iter()
        .map(|d| d.tool_gap.unwrap_or(f64::NAN))
        .collect();
    let curvatures: Vec<f64> = defects.iter().map(ElementDefects::max_curvature).collect();
    let thresholds = case.defects.thresholds(&case.plies[p]);
    let maps = [
        ContourMap {
            title: format!("gap to the tool: {view}, {caption}"),
            points: &points,
            triangles: &ply.mesh.triangles,
            values: &gaps,
            label: format!("gap [mm] (threshold {})", thresholds.tool_gap),
            range: Some((0.0, 4.0 * thresholds.tool_gap)),
        },
        ContourMap {
            title: format!("largest curvature: {view}, {caption}"),
            points: &points,
            triangles: &ply.mesh.triangles,
            values: &curvatures,
            label: format!("|κ| [1/mm] (threshold {})", thresholds.curvature),
            range: Some((0.0, 4.0 * thresholds.curvature)),
        },
    ];
    let wrinkle_path = path.with_file_name(
        path.file_name()
            .map(|f| {
                f.to_string_lossy()
                    .replace("-defects_", "-wrinkle-indicators_")
            })
            .unwrap_or_default(),
    );
    files.write(&wrinkle_path, |p| {
        write_contour_png_overlaid(
            p,
            &maps,
            (2000, 720),
            case.camera,
            &MapOverlay {
                outlines: &outlines,
                categories: None,
            },
        )
    });
}
