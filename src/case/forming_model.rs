//! A validated forming case turned into a model: the plies' meshes joined
//! into one node numbering, a membrane (and bending) term per ply, a dof
//! per tool, contact terms, gravity and dead loads, rigid-body masses and
//! the Dirichlet conditions (`docs/model.md`).

use nalgebra::Vector3;

use super::forming::{FormingCase, PlyMesh, ToolMotion, ToolSpec};
use crate::mesh::Mesh;
use crate::mesh::generate::{GridPattern, OatSpecimen, oat_specimen};
use crate::model::{DeadLoad, MembraneModel, MembraneOptions, MembraneTerm, Model, RigidBodyMass};
use crate::solver::{Dirichlet, DofMap};

/// A ply of the built model.
#[derive(Debug, Clone)]
pub struct BuiltPly {
    /// Name.
    pub name: String,
    /// Its mesh, with its own node numbering (node `n` of the ply is node
    /// `node_offset + n` of the model).
    pub mesh: Mesh,
    /// First model node of the ply.
    pub node_offset: usize,
    /// The ply's membrane (model node numbering), for result fields.
    pub membrane: MembraneModel,
    /// Lumped reference area of each of the ply's nodes `Σ A0/3` [mm²].
    pub nodal_area: Vec<f64>,
    /// Thickness [mm].
    pub thickness: f64,
}

/// A tool of the built model.
#[derive(Debug, Clone)]
pub struct BuiltTool {
    /// The tool as specified.
    pub spec: ToolSpec,
    /// Its extra dof (index among the extras).
    pub extra: usize,
    /// Its global dof.
    pub dof: usize,
    /// Unit direction of its dof (the motion's direction; the axis for a
    /// fixed tool).
    pub direction: Vector3<f64>,
}

/// A forming case turned into a model.
pub struct FormingModel {
    /// The model the solvers drive.
    pub model: Model,
    /// Dirichlet conditions; the load parameter is the programme fraction.
    pub dirichlet: Vec<Dirichlet>,
    /// The plies.
    pub plies: Vec<BuiltPly>,
    /// The tools.
    pub tools: Vec<BuiltTool>,
    /// Reference positions of every node [mm].
    pub nodes: Vec<Vector3<f64>>,
    /// Per boundary condition of the case: its model nodes.
    pub boundary_nodes: Vec<Vec<usize>>,
}

impl FormingModel {
    /// The dof map.
    pub fn dofs(&self) -> DofMap {
        DofMap::with_total(self.model.dofs(), &self.dirichlet)
    }
}

/// The mesh of a ply, with its fibres set.
fn ply_mesh(case: &FormingCase, p: usize) -> Result<Mesh, String> {
    let ply = &case.plies[p];
    let context =
        |e: &dyn std::fmt::Display| format!("{}: ply \"{}\": mesh: {e}", case.source, ply.name);
    let angle = ply.fibre_angle_deg.to_radians();
    let in_plane = Vector3::new(angle.cos(), angle.sin(), 0.0);
    let mut mesh = match &ply.mesh {
        PlyMesh::Rectangle {
            size,
            centre,
            resolution,
        } => {
            // The generator's rovings make the angle θ with y: θ = 90° − α,
            // taken into (−90°, 90°] (rovings are lines).
            let mut theta = 90.0 - ply.fibre_angle_deg;
            theta -= 180.0 * ((theta + 90.0) / 180.0).floor();
            if theta <= -90.0 {
                theta += 180.0;
            }
            let mut mesh = oat_specimen(&OatSpecimen {
                width: size[0],
                length: size[1],
                bias_angle_deg: theta,
                resolution: *resolution,
                pattern: GridPattern::RovingDiagonal,
            })
            .map_err(|e| context(&e))?
            .mesh;
            let shift = centre - Vector3::new(0.5 * size[0], 0.5 * size[1], 0.0);
            for x in &mut mesh.nodes {
                *x += shift;
            }
            mesh.source = format!("generated {} x {} mm blank", size[0], size[1]);
            mesh
        }
        PlyMesh::File { path } => {
            let mut mesh = match path.extension().and_then(|e| e.to_str()) {
                Some("inp") => crate::mesh::inp::read_inp(path),
                Some("msh") => crate::mesh::msh::read_msh(path),
                _ => {
                    return Err(format!(
                        "{}: ply \"{}\": mesh.file = \"{}\": expected an Abaqus .inp or a Gmsh .msh file",
                        case.source,
                        ply.name,
                        path.display()
                    ));
                }
            }
            .map_err(|e| e.to_string())?;
            if mesh.fibres.is_empty() {
                mesh.set_fibres_from_global(in_plane)
                    .map_err(|e| e.to_string())?;
            }
            mesh
        }
        PlyMesh::Disk { .. } | PlyMesh::WrappedStrip { .. } => {
            return Err(context(&"this mesh shape is not available in this build"));
        }
    };
    if mesh.fibres.is_empty() {
        mesh.set_fibres_from_global(in_plane)
            .map_err(|e| context(&e))?;
    }
    mesh.check().map_err(|e| context(&e))?;
    Ok(mesh)
}

/// `Σ A0/3` per node of a mesh [mm²].
fn nodal_areas(mesh: &Mesh) -> Vec<f64> {
    let mut area = vec![0.0; mesh.nodes.len()];
    for (e, t) in mesh.triangles.iter().enumerate() {
        let a = mesh.triangle_area(e) / 3.0;
        for &n in t {
            area[n] += a;
        }
    }
    area
}

impl FormingCase {
    /// Builds the model: meshes, terms, tool dofs, loads and conditions.
    ///
    /// # Errors
    /// A mesh that cannot be made or read, an unknown node set, a
    /// degenerate triangle, a tool that cannot be built — naming the case
    /// file, the ply or tool and the item.
    pub fn build(&self) -> Result<FormingModel, String> {
        let meshes: Vec<Mesh> = (0..self.plies.len())
            .map(|p| ply_mesh(self, p))
            .collect::<Result<_, _>>()?;
        let mut nodes = Vec::new();
        let mut offsets = Vec::new();
        for mesh in &meshes {
            offsets.push(nodes.len());
            nodes.extend_from_slice(&mesh.nodes);
        }
        let mut model = Model::new(nodes.len());
        let mut dirichlet = Vec::new();
        let mut plies = Vec::new();
        for (p, (mesh, &offset)) in meshes.into_iter().zip(&offsets).enumerate() {
            let spec = &self.plies[p];
            let triangles: Vec<[usize; 3]> = mesh
                .triangles
                .iter()
                .map(|t| t.map(|n| n + offset))
                .collect();
            let membrane = MembraneModel::new(
                nodes.clone(),
                triangles,
                &mesh.fibres,
                spec.material.material,
                spec.thickness,
            )
            .map_err(|(e, err)| {
                format!(
                    "{}: ply \"{}\": element {}: {err}",
                    self.source,
                    spec.name,
                    mesh.element_label(e)
                )
            })?;
            let name = if self.plies.len() == 1 {
                "membrane".to_string()
            } else {
                format!("membrane of {}", spec.name)
            };
            model.add(MembraneTerm::new(
                name,
                membrane.clone(),
                MembraneOptions {
                    check_inversion: false,
                    density: spec.density,
                },
            ));
            // Nodes no triangle uses carry no stiffness: fix them.
            for n in mesh.unconnected_nodes() {
                for k in 0..3 {
                    dirichlet.push(Dirichlet::fixed(offset + n, k));
                }
            }
            plies.push(BuiltPly {
                name: spec.name.clone(),
                nodal_area: nodal_areas(&mesh),
                mesh,
                node_offset: offset,
                membrane,
                thickness: spec.thickness,
            });
        }

        // Boundary conditions on node sets.
        let mut boundary_nodes = Vec::new();
        for b in &self.boundaries {
            let ply = &plies[b.ply];
            let set = ply.mesh.node_set(&b.nodes).map_err(|e| {
                format!(
                    "{}:{}: boundary on ply \"{}\": {e}",
                    self.source, b.line, ply.name
                )
            })?;
            let global: Vec<usize> = set.iter().map(|n| n + ply.node_offset).collect();
            for &n in &global {
                for k in 0..3 {
                    if b.fixed[k] {
                        dirichlet.push(Dirichlet::driven(n, k, b.displacement[k]));
                    }
                }
            }
            boundary_nodes.push(global);
        }

        // Gravity from each ply's areal mass, at its nodes.
        if let Some(g) = &self.gravity {
            let mut forces = Vec::new();
            for (ply, spec) in plies.iter().zip(&self.plies) {
                let Some(rho) = spec.density else { continue };
                let areal = rho * spec.thickness;
                for (n, a) in ply.nodal_area.iter().enumerate() {
                    if *a > 0.0 {
                        forces.push((ply.node_offset + n, areal * a * g.acceleration));
                    }
                }
            }
            model.add(DeadLoad::new(
                "gravity",
                nodes.len(),
                forces,
                vec![],
                g.amplitude,
            ));
        }

        // Dead loads on node sets: the total shared equally.
        for (i, l) in self.loads.iter().enumerate() {
            let ply = &plies[l.ply];
            let set = ply.mesh.node_set(&l.nodes).map_err(|e| {
                format!(
                    "{}:{}: load on ply \"{}\": {e}",
                    self.source, l.line, ply.name
                )
            })?;
            let share = l.force / set.len() as f64;
            let forces = set.iter().map(|n| (n + ply.node_offset, share)).collect();
            model.add(DeadLoad::new(
                format!("load {}", i + 1),
                nodes.len(),
                forces,
                vec![],
                l.amplitude,
            ));
        }

        // Tools: one dof each (fixed, driven or free).
        let mut tools = Vec::new();
        for spec in &self.tools {
            let extra = model.add_extra(spec.name.clone());
            let dof = model.extra_dof(extra);
            let direction = match spec.motion {
                ToolMotion::Fixed => {
                    dirichlet.push(Dirichlet::dof(dof, 0.0));
                    spec.axis
                }
                ToolMotion::Prescribed {
                    direction,
                    displacement,
                } => {
                    dirichlet.push(Dirichlet::dof(dof, displacement));
                    direction
                }
                ToolMotion::Floating {
                    direction,
                    mass,
                    weight,
                } => {
                    model.add(RigidBodyMass::new(
                        format!("mass of {}", spec.name),
                        extra,
                        mass,
                    ));
                    model.add(DeadLoad::new(
                        format!("weight of {}", spec.name),
                        nodes.len(),
                        vec![],
                        vec![(extra, weight)],
                        crate::model::LoadAmplitude::Constant,
                    ));
                    direction
                }
            };
            tools.push(BuiltTool {
                spec: spec.clone(),
                extra,
                dof,
                direction,
            });
        }
        Ok(FormingModel {
            model,
            dirichlet,
            plies,
            tools,
            nodes,
            boundary_nodes,
        })
    }
}
