//! What a forming run reads on the blanks (`docs/forming.md`, "Outputs"):
//! each ply's outer boundary and draw-in points (edge midpoints and
//! corners), each zone's elements and their means, and the 2D
//! image-correlation view (the formed mesh projected on the blank plane,
//! strains recomputed on the projection).

use crate::config::readable_number;
use serde::Serialize;

use crate::case::forming::FormingCase;
use crate::case::forming_model::FormingModel;
use crate::post::forming::{
    DrawInPoint, StrainMeasures, boundary_displacement, deformation_mode, draw_in, draw_in_points,
    mode_areas, outer_boundary, strain_measure, strain_measures, weighted_mean_std,
};

/// Why the blanks' readout cannot be set up.
#[derive(Debug, Clone, thiserror::Error)]
pub enum ReadoutError {
    /// A ply's mesh has no boundary.
    #[error(
        "{source_file}: ply \"{ply}\": the mesh has no boundary, so no outer contour or draw-in"
    )]
    NoBoundary {
        /// The case file.
        source_file: String,
        /// The ply.
        ply: String,
    },
    /// A zone holds no element of its ply.
    #[error(
        "{source_file}: zone[{index}] (\"{zone}\"): no element of ply \"{ply}\" has its centroid in the window centred at [{}, {}] mm of size [{}, {}] mm; expected a window on the blank",
        readable_number(*x),
        readable_number(*y),
        readable_number(*width),
        readable_number(*height)
    )]
    EmptyZone {
        /// The case file.
        source_file: String,
        /// The zone's index in the case.
        index: usize,
        /// Its name.
        zone: String,
        /// Its ply.
        ply: String,
        /// Its centre \[mm\].
        x: f64,
        /// Its centre \[mm\].
        y: f64,
        /// Its size \[mm\].
        width: f64,
        /// Its size \[mm\].
        height: f64,
    },
}

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
    pub fn new(case: &FormingCase, built: &FormingModel) -> Result<Self, ReadoutError> {
        let mut plies = Vec::new();
        for ply in &built.plies {
            let reference: Vec<[f64; 2]> = ply.mesh.nodes.iter().map(|x| [x.x, x.y]).collect();
            let outer = outer_boundary(&reference, &ply.mesh.triangles).ok_or_else(|| {
                ReadoutError::NoBoundary {
                    source_file: case.source.clone(),
                    ply: ply.name.clone(),
                }
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
                return Err(ReadoutError::EmptyZone {
                    source_file: case.source.clone(),
                    index: i,
                    zone: z.zone.name.clone(),
                    ply: built.plies[z.ply].name.clone(),
                    x: z.zone.centre[0],
                    y: z.zone.centre[1],
                    width: z.zone.size[0],
                    height: z.zone.size[1],
                });
            }
            zones.push(elements);
        }
        let stroke_tool = built.stroke_tool();
        let floating_tools = built.floating_tools();
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
    pub(super) fn outline_labels(&self, built: &FormingModel) -> Vec<Vec<i64>> {
        self.plies
            .iter()
            .zip(&built.plies)
            .map(|(p, ply)| p.outer.iter().map(|&n| ply.mesh.node_label(n)).collect())
            .collect()
    }
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
