//! An off-axis tension test case turned into a model: the specimen's mesh
//! (generated or read, with its fibres), the clamps' Dirichlet conditions,
//! the membrane, and the zones A, B, C with the main deformation zone
//! (`docs/cases.md`).

use nalgebra::Vector2;

use super::{MeshSource, OatCase, OatModel, Zone};
use crate::case::BuildError;
use crate::mesh::Mesh;
use crate::mesh::generate::{OatSpecimen, oat_specimen};
use crate::model::{MembraneModel, MembraneOptions, Model};
use crate::solver::{Dirichlet, DofMap};

impl OatCase {
    /// Builds the mesh, the model, the clamps, the zones and the MDZ.
    ///
    /// # Errors
    /// A mesh that cannot be generated or read, a missing clamp set, a
    /// degenerate triangle — with the file and element named.
    pub fn build(&self) -> Result<OatModel, BuildError> {
        let (mut mesh, edge_deviation_deg, fixed, moving) = self.specimen_mesh()?;
        let (fixed_nodes, moving_nodes) = self.clamp_nodes(&mut mesh, &fixed, &moving)?;
        let dirichlet = oat_clamps(
            mesh.nodes.len(),
            &fixed_nodes,
            &moving_nodes,
            &mesh.unconnected_nodes(),
        );
        let model = MembraneModel::new(
            mesh.nodes.clone(),
            mesh.triangles.clone(),
            &mesh.fibres,
            self.material.material,
            self.thickness,
        )
        .map_err(|(e, err)| BuildError::Element {
            mesh: mesh.source.clone(),
            element: mesh.element_labels.get(e).copied().unwrap_or(e as i64),
            cause: err,
        })?;
        let (zones, mdz) = self.zones_and_mdz(&mesh);
        Ok(OatModel {
            mesh,
            model,
            dirichlet,
            zones,
            mdz,
            edge_deviation_deg,
        })
    }

    /// The specimen's mesh, generated or read, with the largest deviation
    /// of the rovings from a triangle edge (generated meshes) and the names
    /// of the fixed and moving clamp sets.
    fn specimen_mesh(&self) -> Result<(Mesh, Option<f64>, String, String), BuildError> {
        Ok(match &self.mesh {
            MeshSource::Generated {
                resolution,
                pattern,
            } => {
                let generated = oat_specimen(&OatSpecimen {
                    width: self.width,
                    length: self.length,
                    bias_angle_deg: self.bias_angle_deg,
                    resolution: *resolution,
                    pattern: *pattern,
                })
                .map_err(|e| {
                    // The generator names its parameter by its key; say
                    // which table of the case file holds it.
                    let table = match &e {
                        crate::mesh::MeshError::InvalidSpec {
                            parameter: "width" | "length" | "bias_angle_deg",
                            ..
                        } => "specimen",
                        _ => "mesh",
                    };
                    BuildError::Generator {
                        file: self.source.clone(),
                        table,
                        cause: e.into(),
                    }
                })?;
                (
                    generated.mesh,
                    Some(generated.edge_deviation_deg),
                    "bottom".to_string(),
                    "top".to_string(),
                )
            }
            MeshSource::File {
                path,
                fixed_clamp_set,
                moving_clamp_set,
            } => {
                let mesh = match path.extension().and_then(|e| e.to_str()) {
                    Some("inp") => crate::mesh::inp::read_inp(path),
                    Some("msh") => crate::mesh::msh::read_msh(path),
                    _ => {
                        return Err(BuildError::MeshFormat {
                            file: self.source.clone(),
                            line: self.mesh_line,
                            path: path.clone(),
                        });
                    }
                }
                .map_err(|e| BuildError::MeshFile {
                    file: self.source.clone(),
                    line: self.mesh_line,
                    path: path.clone(),
                    cause: e.into(),
                })?;
                (
                    mesh,
                    None,
                    fixed_clamp_set.clone(),
                    moving_clamp_set.clone(),
                )
            }
        })
    }

    /// Sets the mesh's fibres along the rovings (unless it has its own),
    /// checks it, and finds the nodes of the two clamps: each set non-empty,
    /// no node in both.
    fn clamp_nodes(
        &self,
        mesh: &mut Mesh,
        fixed: &str,
        moving: &str,
    ) -> Result<(Vec<usize>, Vec<usize>), BuildError> {
        let in_case = |e: crate::mesh::MeshError| BuildError::Mesh {
            file: self.source.clone(),
            cause: e.into(),
        };
        if mesh.fibres.is_empty() {
            mesh.set_fibres_from_global(self.roving_direction())
                .map_err(|e| BuildError::Fibres {
                    file: self.source.clone(),
                    bias_angle_deg: self.bias_angle_deg,
                    cause: e.into(),
                })?;
        }
        mesh.check().map_err(in_case)?;
        let clamp = |key: &'static str, name: &str| {
            mesh.node_set(name)
                .map(<[usize]>::to_vec)
                .map_err(|e| BuildError::ClampSet {
                    file: self.source.clone(),
                    key,
                    set: name.to_string(),
                    cause: e.into(),
                })
        };
        let fixed_nodes = clamp("fixed_clamp_set", fixed)?;
        let moving_nodes = clamp("moving_clamp_set", moving)?;
        for (set, nodes, key) in [
            (&fixed, &fixed_nodes, "mesh.fixed_clamp_set"),
            (&moving, &moving_nodes, "mesh.moving_clamp_set"),
        ] {
            if nodes.is_empty() {
                return Err(BuildError::EmptyClamp {
                    file: self.source.clone(),
                    key,
                    set: set.to_string(),
                    mesh: mesh.source.clone(),
                });
            }
        }
        let in_fixed: std::collections::HashSet<usize> = fixed_nodes.iter().copied().collect();
        if let Some(&shared) = moving_nodes.iter().find(|n| in_fixed.contains(n)) {
            return Err(BuildError::SharedClampNode {
                file: self.source.clone(),
                fixed: fixed.to_string(),
                moving: moving.to_string(),
                node: mesh.node_label(shared),
                mesh: mesh.source.clone(),
            });
        }
        Ok((fixed_nodes, moving_nodes))
    }

    /// The zone of every element, and the main deformation zone: the
    /// elements of zone A in the MDZ window about the specimen's centre
    /// (the whole window when there is no zone A).
    fn zones_and_mdz(&self, mesh: &Mesh) -> (Vec<Zone>, Vec<usize>) {
        let zones: Vec<Zone> = (0..mesh.triangles.len())
            .map(|e| {
                let c = mesh.centroid(e);
                self.zone_at(Vector2::new(c.x, c.y))
            })
            .collect();
        let half = 0.5 * self.mdz_size;
        let centre = Vector2::new(0.5 * self.width, 0.5 * self.length);
        let in_window = |e: usize| {
            let c = mesh.centroid(e);
            (c.x - centre.x).abs() <= half && (c.y - centre.y).abs() <= half
        };
        let mut mdz: Vec<usize> = (0..mesh.triangles.len())
            .filter(|&e| zones[e] == Zone::A && in_window(e))
            .collect();
        if mdz.is_empty() {
            // No zone A (e.g. 0° or 90°): the window alone.
            mdz = (0..mesh.triangles.len())
                .filter(|&e| in_window(e))
                .collect();
        }
        (zones, mdz)
    }

    /// The dof map of a built model.
    pub fn dofs(model: &OatModel) -> DofMap {
        DofMap::new(model.mesh.nodes.len(), &model.dirichlet)
    }

    /// The model the solvers drive: the specimen's membrane, checked for
    /// triangles turning over in the plane (the test is in-plane), with the
    /// case's density.
    pub fn solver_model(&self, built: &OatModel) -> Model {
        let mut model = Model::membrane(
            built.model.clone(),
            MembraneOptions {
                check_inversion: true,
                density: self.density,
                roving_mass_length: self.explicit.roving_mass_length,
                roving_mass_coupling: self.explicit.roving_mass_coupling,
            },
        );
        // Messages name the specimen's nodes by their mesh labels.
        model.node_groups.push(crate::model::NodeGroup::of_mesh(
            "the specimen",
            0,
            &built.mesh,
        ));
        model
    }

    /// Does the line through `p` along `d` (both ways) end on a clamp edge
    /// (`y = 0` or `y = L`) rather than on a free edge?
    fn line_clamped(&self, p: Vector2<f64>, d: Vector2<f64>) -> bool {
        [d, -d].iter().any(|dir| self.exit_on_clamp(p, *dir))
    }

    fn exit_on_clamp(&self, p: Vector2<f64>, d: Vector2<f64>) -> bool {
        let t = |coord: f64, lo: f64, hi: f64, dc: f64| {
            if dc > 1e-12 {
                (hi - coord) / dc
            } else if dc < -1e-12 {
                (lo - coord) / dc
            } else {
                f64::INFINITY
            }
        };
        let tx = t(p.x, 0.0, self.width, d.x);
        let ty = t(p.y, 0.0, self.length, d.y);
        ty <= tx
    }

    /// The zone of a point of the reference specimen.
    pub fn zone_at(&self, p: Vector2<f64>) -> Zone {
        let theta = self.bias_angle_deg.to_radians();
        let roving = Vector2::new(theta.sin(), theta.cos());
        let stitching = Vector2::new(-theta.cos(), theta.sin());
        match (
            self.line_clamped(p, roving),
            self.line_clamped(p, stitching),
        ) {
            (false, false) => Zone::A,
            (true, true) => Zone::C,
            _ => Zone::B,
        }
    }
}

/// The OAT's Dirichlet conditions, with the clamp displacement as the load
/// parameter: every `z` fixed (in-plane), the fixed clamp fixed in `x` and
/// `y`, the moving clamp fixed in `x` and driven in `+y`, and nodes that no
/// triangle uses (reference points of a read mesh, which carry no
/// stiffness) fixed so the tangent stays regular.
pub fn oat_clamps(
    nodes: usize,
    fixed: &[usize],
    moving: &[usize],
    unconnected: &[usize],
) -> Vec<Dirichlet> {
    let mut conditions: Vec<Dirichlet> = (0..nodes).map(|n| Dirichlet::fixed(n, 2)).collect();
    for &n in fixed.iter().chain(unconnected) {
        conditions.extend([Dirichlet::fixed(n, 0), Dirichlet::fixed(n, 1)]);
    }
    for &n in moving {
        conditions.extend([Dirichlet::fixed(n, 0), Dirichlet::driven(n, 1, 1.0)]);
    }
    conditions
}
