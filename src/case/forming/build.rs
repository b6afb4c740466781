//! A validated forming case turned into a model: the plies' meshes joined
//! into one node numbering, a membrane (and bending) term per ply, a dof
//! per tool, contact terms, gravity and dead loads, rigid-body masses and
//! the Dirichlet conditions (`docs/model.md`).
//! The stages, in order: the plies' meshes and membranes, the boundary
//! conditions, bending, the probes, gravity and dead loads, the tools with
//! their contact terms, and the ply–ply contacts. Field-by-field
//! documentation of the case: `docs/cases.md`, "Forming cases".

use std::sync::Arc;

use nalgebra::{SymmetricEigen, Vector3};

use super::{FormingCase, PlyMesh, PlySpec, ToolMotion, ToolShape, ToolSpec, pyramid_of};
use crate::case::error::{BuildError, ToolSurfaceError};
use crate::config::readable_number;
use crate::contact::{
    Cylinder, MeshOptions, MeshSurface, Placed, Placement, Plane, PlateWithHole,
    PlateWithPolygonHole, RigidSurface, Side, Sphere, Tessellation, Torus,
};
use crate::element::BendingStiffness;
use crate::material::{FibreFrame, MembraneMaterial, Sym2};
use crate::mesh::generate::{OatSpecimen, oat_specimen};
use crate::mesh::{Mesh, MeshError};
use crate::model::{
    BendingTerm, ContactOptions, DeadLoad, MembraneModel, MembraneOptions, MembraneTerm, Model,
    PlyContact, PlyContactOptions, PlySurface, RigidBodyMass, ToolContact,
};
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
    /// Lumped reference area of each of the ply's nodes `Σ A0/3` \[mm²\].
    pub nodal_area: Vec<f64>,
    /// Thickness its contacts see \[mm\] ([`PlySpec::contact_thickness`]).
    pub contact_thickness: f64,
}

impl BuiltPly {
    /// The current position `x + u` of each of the ply's nodes \[mm\], from
    /// the model's displacement `u` (all dofs).
    pub fn deformed_positions(&self, u: &[f64]) -> Vec<[f64; 3]> {
        self.mesh
            .nodes
            .iter()
            .enumerate()
            .map(|(n, x)| {
                let g = self.node_offset + n;
                [x.x + u[3 * g], x.y + u[3 * g + 1], x.z + u[3 * g + 2]]
            })
            .collect()
    }
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
    /// Its surface drawn as triangles, world frame, at `q = 0`.
    pub drawing: Tessellation,
}

/// Segments of a drawn circle (tessellation of round tools).
const DRAWN_SEGMENTS: usize = 72;

/// A tool's surface in the world frame at `q = 0`, and its drawing.
fn tool_surface(
    case: &FormingCase,
    spec: &ToolSpec,
) -> Result<(Arc<dyn RigidSurface>, Tessellation), BuildError> {
    let context = |e: ToolSurfaceError| BuildError::Tool {
        file: case.source.clone(),
        line: spec.line,
        tool: spec.name.clone(),
        cause: e.into(),
    };
    let placement = Placement::new(spec.origin, spec.axis, None).map_err(|e| context(e.into()))?;
    let side = if spec.inside {
        Side::Inside
    } else {
        Side::Outside
    };
    fn placed<S: RigidSurface + 'static>(
        shape: S,
        placement: Placement,
        drawing: Tessellation,
    ) -> (Arc<dyn RigidSurface>, Tessellation) {
        let world = drawing.to_world(&placement);
        (Arc::new(Placed::new(shape, placement)), world)
    }
    let e = spec.extent;
    Ok(match &spec.shape {
        ToolShape::Plane => {
            let shape = Plane::new();
            let drawing = shape.tessellate(e, 8).map_err(|x| context(x.into()))?;
            placed(shape, placement, drawing)
        }
        ToolShape::Sphere { radius } => {
            let shape = Sphere::new(*radius, side).map_err(|x| context(x.into()))?;
            let drawing = shape
                .tessellate(std::f64::consts::PI, DRAWN_SEGMENTS)
                .map_err(|x| context(x.into()))?;
            placed(shape, placement, drawing)
        }
        ToolShape::Cylinder { radius } => {
            let shape = Cylinder::new(*radius, side).map_err(|x| context(x.into()))?;
            let drawing = shape
                .tessellate(-e, e, DRAWN_SEGMENTS)
                .map_err(|x| context(x.into()))?;
            placed(shape, placement, drawing)
        }
        ToolShape::Torus {
            major_radius,
            minor_radius,
        } => {
            let shape =
                Torus::new(*major_radius, *minor_radius, side).map_err(|x| context(x.into()))?;
            let drawing = shape
                .tessellate(DRAWN_SEGMENTS)
                .map_err(|x| context(x.into()))?;
            placed(shape, placement, drawing)
        }
        ToolShape::PlateWithHole {
            opening_radius,
            fillet_radius,
        } => {
            let shape = PlateWithHole::new(*opening_radius, *fillet_radius)
                .map_err(|x| context(x.into()))?;
            let outer = (opening_radius + fillet_radius + e).max(e);
            let drawing = shape
                .tessellate(outer, fillet_radius + 10.0, DRAWN_SEGMENTS)
                .map_err(|x| context(x.into()))?;
            placed(shape, placement, drawing)
        }
        ToolShape::Pyramid { .. } => {
            let (shape, placement) = pyramid_of(spec)
                .map_err(|x| context(x.into()))?
                .ok_or_else(|| context(ToolSurfaceError::NotAPyramid))?;
            let drawing = shape
                .tessellate(DRAWN_SEGMENTS)
                .map_err(|x| context(x.into()))?;
            placed(shape, placement, drawing)
        }
        ToolShape::PlateWithPolygonHole {
            polygon,
            corner_radius,
            fillet_radius,
            ..
        } => {
            let polygon: Vec<nalgebra::Vector2<f64>> = polygon
                .iter()
                .map(|p| nalgebra::Vector2::new(p[0], p[1]))
                .collect();
            let shape = PlateWithPolygonHole::new(&polygon, *corner_radius, *fillet_radius)
                .map_err(|x| context(x.into()))?;
            let drawing = shape
                .tessellate(e, fillet_radius + 10.0, DRAWN_SEGMENTS)
                .map_err(|x| context(x.into()))?;
            placed(shape, placement, drawing)
        }
        ToolShape::Mesh {
            path,
            scale,
            closed,
            flip_normals,
        } => {
            let options = MeshOptions {
                scale: *scale,
                require_closed: *closed,
                flip_normals: *flip_normals,
            };
            // A closed mesh is oriented outward by its enclosed volume,
            // whatever the file's winding (the case's warnings say so).
            let shape = match MeshSurface::from_file(path, &options) {
                Err(crate::contact::MeshToolError::InsideOut { .. }) => MeshSurface::from_file(
                    path,
                    &MeshOptions {
                        flip_normals: !options.flip_normals,
                        ..options
                    },
                ),
                other => other,
            }
            .map_err(|x| context(x.into()))?;
            let drawing = shape.tessellation();
            let translation = Placement::translation(spec.origin).map_err(|x| context(x.into()))?;
            placed(shape, translation, drawing)
        }
    })
}

/// The largest eigenvalue of a law's tangent at the reference state
/// (`C = I`) [MPa]: the membrane's stiffest modulus, the scale of the
/// automatic contact penalty.
fn reference_modulus(material: &crate::material::Material) -> f64 {
    let identity = Sym2::new(1.0, 1.0, 0.0);
    match material.stress_tangent(&identity, &FibreFrame::aligned()) {
        Ok((_, tangent)) => {
            let symmetric = 0.5 * (tangent + tangent.transpose());
            SymmetricEigen::new(symmetric)
                .eigenvalues
                .iter()
                .fold(0.0_f64, |m, &v| m.max(v))
        }
        Err(_) => 0.0,
    }
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
    /// Reference positions of every node \[mm\].
    pub nodes: Vec<Vector3<f64>>,
    /// Per boundary condition of the case: its model nodes.
    pub boundary_nodes: Vec<Vec<usize>>,
    /// Per probe of the case: its model nodes.
    pub probe_nodes: Vec<Vec<usize>>,
}

impl FormingModel {
    /// The dof map.
    pub fn dofs(&self) -> DofMap {
        DofMap::with_total(self.model.dofs(), &self.dirichlet)
    }
}

/// The mesh of a ply, with its fibres set.
fn ply_mesh(case: &FormingCase, p: usize) -> Result<Mesh, BuildError> {
    let ply = &case.plies[p];
    let context = |e: MeshError| BuildError::PlyMesh {
        file: case.source.clone(),
        line: ply.mesh_line,
        ply: ply.name.clone(),
        cause: e.into(),
    };
    let angle = ply.fibre_angle_deg.to_radians();
    let in_plane = Vector3::new(angle.cos(), angle.sin(), 0.0);
    let mut mesh = match &ply.mesh {
        PlyMesh::Rectangle {
            size,
            centre,
            resolution,
            pattern,
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
                pattern: *pattern,
            })
            .map_err(|e| context(generator_key(e)))?
            .mesh;
            let shift = centre - Vector3::new(0.5 * size[0], 0.5 * size[1], 0.0);
            for x in &mut mesh.nodes {
                *x += shift;
            }
            mesh.source = format!(
                "generated {} x {} mm blank",
                readable_number(size[0]),
                readable_number(size[1])
            );
            mesh
        }
        PlyMesh::File { path } => {
            let mut mesh = match path.extension().and_then(|e| e.to_str()) {
                Some("inp") => crate::mesh::inp::read_inp(path),
                Some("msh") => crate::mesh::msh::read_msh(path),
                _ => {
                    return Err(BuildError::PlyMeshFormat {
                        file: case.source.clone(),
                        line: ply.mesh_line,
                        ply: ply.name.clone(),
                        path: path.clone(),
                    });
                }
            }
            .map_err(|e| BuildError::PlyMeshFile {
                file: case.source.clone(),
                line: ply.mesh_line,
                ply: ply.name.clone(),
                path: path.clone(),
                cause: e.into(),
            })?;
            if mesh.fibres.is_empty() {
                mesh.set_fibres_from_global(in_plane).map_err(context)?;
            }
            mesh
        }
        PlyMesh::Disk {
            radius,
            centre,
            element_size,
        } => {
            let mut mesh = crate::mesh::shapes::disk(*radius, *element_size).map_err(context)?;
            for x in &mut mesh.nodes {
                *x += centre;
            }
            // The generator's fibres run along x: turn them to the ply's angle.
            mesh.fibres.clear();
            mesh
        }
        PlyMesh::WrappedStrip {
            radius,
            wrap_angle_deg,
            tail_length,
            width,
            element_size,
            centre,
        } => {
            let mut mesh = crate::mesh::shapes::wrapped_strip(&crate::mesh::shapes::WrappedStrip {
                width: *width,
                radius: *radius,
                wrap_angle: wrap_angle_deg.to_radians(),
                tail_length: *tail_length,
                element_size: *element_size,
            })
            .map_err(context)?;
            for x in &mut mesh.nodes {
                *x += centre;
            }
            mesh
        }
    };
    if mesh.fibres.is_empty() {
        mesh.set_fibres_from_global(in_plane).map_err(context)?;
    }
    mesh.check().map_err(context)?;
    Ok(mesh)
}

/// A generator error with the parameter spelled as the `[ply.mesh]` key
/// (`size`, `cells`) rather than as the OAT case's.
fn generator_key(e: MeshError) -> MeshError {
    match e {
        MeshError::InvalidSpec {
            parameter: "width" | "length",
            value,
            expected,
        } => MeshError::InvalidSpec {
            parameter: "size",
            value,
            expected,
        },
        MeshError::InvalidSpec {
            parameter: "nx, ny",
            value,
            expected,
        } => MeshError::InvalidSpec {
            parameter: "cells",
            value: format!("[{value}]"),
            expected,
        },
        other => other,
    }
}

impl FormingCase {
    /// Builds the model: meshes, terms, tool dofs, loads and conditions.
    ///
    /// # Errors
    /// A mesh that cannot be made or read, an unknown node set, a
    /// degenerate triangle, a tool that cannot be built — naming the case
    /// file, the ply or tool and the item.
    pub fn build(&self) -> Result<FormingModel, BuildError> {
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
        let plies = self.ply_terms(meshes, &offsets, &nodes, &mut model, &mut dirichlet)?;
        let boundary_nodes = self.boundary_conditions(&plies, &mut dirichlet)?;
        self.bending_terms(&plies, &nodes, &boundary_nodes, &mut model)?;
        let probe_nodes = self.probe_nodes(&plies)?;
        self.gravity_and_loads(&plies, nodes.len(), &mut model)?;
        let tools = self.tool_terms(&plies, nodes.len(), &mut model, &mut dirichlet)?;
        self.ply_contact_terms(&plies, &mut model)?;
        Ok(FormingModel {
            model,
            dirichlet,
            plies,
            tools,
            nodes,
            boundary_nodes,
            probe_nodes,
        })
    }

    /// Each ply's membrane term on its meshes' nodes (numbered from its
    /// offset), its node group, and a fixed node for every node no
    /// triangle uses.
    fn ply_terms(
        &self,
        meshes: Vec<Mesh>,
        offsets: &[usize],
        nodes: &[Vector3<f64>],
        model: &mut Model,
        dirichlet: &mut Vec<Dirichlet>,
    ) -> Result<Vec<BuiltPly>, BuildError> {
        let mut plies = Vec::new();
        for (p, (mesh, &offset)) in meshes.into_iter().zip(offsets).enumerate() {
            let spec = &self.plies[p];
            let triangles: Vec<[usize; 3]> = mesh
                .triangles
                .iter()
                .map(|t| t.map(|n| n + offset))
                .collect();
            let membrane = MembraneModel::new(
                nodes.to_vec(),
                triangles,
                &mesh.fibres,
                spec.material.material,
                spec.thickness,
            )
            .map_err(|(e, err)| BuildError::PlyElement {
                file: self.source.clone(),
                ply: spec.name.clone(),
                element: mesh.element_label(e),
                cause: err,
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
                    roving_mass_length: self.explicit.roving_mass_length,
                    roving_mass_coupling: self.explicit.roving_mass_coupling,
                },
            ));
            // Nodes no triangle uses carry no stiffness: fix them.
            for n in mesh.unconnected_nodes() {
                for k in 0..3 {
                    dirichlet.push(Dirichlet::fixed(offset + n, k));
                }
            }
            model.node_groups.push(crate::model::NodeGroup::of_mesh(
                format!("ply \"{}\"", spec.name),
                offset,
                &mesh,
            ));
            plies.push(BuiltPly {
                name: spec.name.clone(),
                nodal_area: mesh.nodal_areas(),
                mesh,
                node_offset: offset,
                membrane,
                contact_thickness: spec.contact_thickness(),
            });
        }
        Ok(plies)
    }

    /// The Dirichlet conditions of the boundaries on their node sets, and
    /// the model nodes of each set.
    fn boundary_conditions(
        &self,
        plies: &[BuiltPly],
        dirichlet: &mut Vec<Dirichlet>,
    ) -> Result<Vec<Vec<usize>>, BuildError> {
        // Boundary conditions on node sets.
        let mut boundary_nodes = Vec::new();
        for b in &self.boundaries {
            let ply = &plies[b.ply];
            let set = ply
                .mesh
                .node_set(&b.nodes)
                .map_err(|e| BuildError::Boundary {
                    file: self.source.clone(),
                    line: b.line,
                    ply: ply.name.clone(),
                    cause: e.into(),
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
        Ok(boundary_nodes)
    }

    /// A bending term per ply with bending.
    fn bending_terms(
        &self,
        plies: &[BuiltPly],
        nodes: &[Vector3<f64>],
        boundary_nodes: &[Vec<usize>],
        model: &mut Model,
    ) -> Result<(), BuildError> {
        // Bending per ply, with a fixed rotation on edges whose nodes are in
        // a boundary set with rotation = "clamped".
        let mut clamped = vec![false; nodes.len()];
        for (b, set) in self.boundaries.iter().zip(boundary_nodes) {
            if b.clamp_rotation {
                for &n in set {
                    clamped[n] = true;
                }
            }
        }
        for (ply, spec) in plies.iter().zip(&self.plies) {
            let Some([b11, b22, b66]) = spec.bending else {
                continue;
            };
            let stiffness =
                BendingStiffness::new(b11, b22, b66).map_err(|e| BuildError::BendingStiffness {
                    file: self.source.clone(),
                    ply: spec.name.clone(),
                    cause: e,
                })?;
            let name = if self.plies.len() == 1 {
                "bending".to_string()
            } else {
                format!("bending of {}", spec.name)
            };
            let term = BendingTerm::new(
                name,
                nodes,
                &ply.membrane.triangles,
                &ply.mesh.fibres,
                &clamped,
                stiffness,
            )
            .map_err(|e| BuildError::Bending {
                file: self.source.clone(),
                ply: spec.name.clone(),
                cause: e.into(),
            })?;
            model.add(term);
        }
        Ok(())
    }

    /// The model nodes of each probe's node set.
    fn probe_nodes(&self, plies: &[BuiltPly]) -> Result<Vec<Vec<usize>>, BuildError> {
        let mut probe_nodes = Vec::new();
        for p in &self.probes {
            let ply = &plies[p.ply];
            let set = ply.mesh.node_set(&p.nodes).map_err(|e| BuildError::Probe {
                file: self.source.clone(),
                line: p.line,
                ply: ply.name.clone(),
                cause: e.into(),
            })?;
            probe_nodes.push(set.iter().map(|n| n + ply.node_offset).collect());
        }
        Ok(probe_nodes)
    }

    /// The gravity term (from each ply's areal mass) and a dead-load term
    /// per `[[load]]`.
    fn gravity_and_loads(
        &self,
        plies: &[BuiltPly],
        node_count: usize,
        model: &mut Model,
    ) -> Result<(), BuildError> {
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
                node_count,
                forces,
                vec![],
                g.amplitude,
            ));
        }

        // Dead loads on node sets: the total shared equally.
        for (i, l) in self.loads.iter().enumerate() {
            let ply = &plies[l.ply];
            let set = ply.mesh.node_set(&l.nodes).map_err(|e| BuildError::Load {
                file: self.source.clone(),
                line: l.line,
                ply: ply.name.clone(),
                cause: e.into(),
            })?;
            let share = l.force / set.len() as f64;
            let forces = set.iter().map(|n| (n + ply.node_offset, share)).collect();
            model.add(DeadLoad::new(
                format!("load {}", i + 1),
                node_count,
                forces,
                vec![],
                l.amplitude,
            ));
        }
        Ok(())
    }

    /// Each tool's surface, its dof with its condition or its mass and
    /// weight, and its contact term with each ply it touches (its
    /// `plies`; a ply it does not touch is neither in contact with it nor
    /// checked against it).
    fn tool_terms(
        &self,
        plies: &[BuiltPly],
        node_count: usize,
        model: &mut Model,
        dirichlet: &mut Vec<Dirichlet>,
    ) -> Result<Vec<BuiltTool>, BuildError> {
        // Tools: one dof each (fixed, driven or free), and a contact term
        // per tool and ply it touches.
        let mut tools = Vec::new();
        for spec in &self.tools {
            let (surface, drawing) = tool_surface(self, spec)?;
            let (extra, dof, direction) = tool_dof(spec, node_count, model, dirichlet);
            let tool = BuiltTool {
                spec: spec.clone(),
                extra,
                dof,
                direction,
                drawing,
            };
            for &k in &spec.plies {
                model.add(self.tool_contact(
                    &tool,
                    &surface,
                    &plies[k],
                    &self.plies[k],
                    node_count,
                )?);
            }
            tools.push(tool);
        }
        Ok(tools)
    }

    /// The contact term of a tool with a ply, its penalties checked and
    /// the ply checked not to start inside the tool.
    fn tool_contact(
        &self,
        tool: &BuiltTool,
        surface: &Arc<dyn RigidSurface>,
        ply: &BuiltPly,
        ply_spec: &PlySpec,
        node_count: usize,
    ) -> Result<ToolContact, BuildError> {
        let (spec, direction, extra) = (&tool.spec, tool.direction, tool.extra);
        let offset = self
            .contact
            .offset
            .unwrap_or(0.5 * ply_spec.contact_thickness());
        let count = ply.mesh.nodes.len();
        let mean_area = ply.nodal_area.iter().sum::<f64>() / count.max(1) as f64;
        let penalties = self.contact_penalties(spec, ply, ply_spec, mean_area)?;
        check_outside(self, spec, surface, ply, offset)?;
        let name = if self.plies.len() == 1 {
            format!("contact with {}", spec.name)
        } else {
            format!("contact of {} with {}", ply.name, spec.name)
        };
        Ok(ToolContact::new(
            name,
            surface.clone(),
            direction,
            extra,
            node_count,
            (0..count).map(|n| n + ply.node_offset).collect(),
            ply.mesh.nodes.to_vec(),
            vec![offset; count],
            ply.nodal_area.clone(),
            penalties,
            ContactOptions {
                friction: spec.friction,
                gap_tolerance: self
                    .contact
                    .gap_tolerance
                    .unwrap_or(0.01 * ply_spec.thickness),
                multiplier_tolerance: self.contact.multiplier_tolerance,
                tangential_penalty_scale: self.contact.tangential_penalty_scale,
                smoothing: self.contact.smoothing,
                explicit_stiffness: self.contact.explicit_penalty(),
                explicit_damping: self.contact.explicit_damping,
                compaction: ply_spec.compaction.map(|c| c.law),
            },
        ))
    }

    /// The normal penalty of each of a ply's nodes against a tool: the
    /// given one, or the automatic one scaled by the node's area; each must
    /// be a positive number.
    fn contact_penalties(
        &self,
        spec: &ToolSpec,
        ply: &BuiltPly,
        ply_spec: &PlySpec,
        mean_area: f64,
    ) -> Result<Vec<f64>, BuildError> {
        let automatic = reference_modulus(&ply_spec.material.material) * ply_spec.thickness;
        let penalties: Vec<f64> = ply
            .nodal_area
            .iter()
            .map(|a| match self.contact.penalty {
                Some(p) => p,
                None => self.contact.penalty_scale * automatic * a / mean_area,
            })
            .collect();
        if let Some((n, p)) = penalties
            .iter()
            .enumerate()
            .find(|(_, p)| !(p.is_finite() && **p > 0.0))
        {
            return Err(BuildError::ContactPenalty {
                file: self.source.clone(),
                ply: ply.name.clone(),
                tool: spec.name.clone(),
                node: ply.mesh.node_label(n),
                penalty: *p,
            });
        }
        Ok(penalties)
    }

    /// A contact term per `[[ply_contact]]` (explicit path only; the case
    /// refuses them on the quasi-static one).
    fn ply_contact_terms(&self, plies: &[BuiltPly], model: &mut Model) -> Result<(), BuildError> {
        for spec in &self.ply_contacts {
            let surface = |k: usize| {
                let ply = &plies[k];
                PlySurface {
                    name: ply.name.clone(),
                    nodes: (0..ply.mesh.nodes.len())
                        .map(|n| n + ply.node_offset)
                        .collect(),
                    reference: ply.mesh.nodes.to_vec(),
                    triangles: ply.mesh.triangles.clone(),
                    thickness: ply.contact_thickness,
                }
            };
            let [a, b] = spec.plies;
            let name = format!("contact of {} with {}", plies[a].name, plies[b].name);
            let term = PlyContact::new(
                name,
                surface(a),
                surface(b),
                PlyContactOptions {
                    friction: spec.friction,
                    explicit_stiffness: self.contact.explicit_penalty(),
                    explicit_damping: self.contact.explicit_damping,
                    skin: spec.skin,
                    compaction: self.plies[a].compaction.map(|c| c.law),
                },
            )
            .map_err(|e| BuildError::PlyContact {
                file: self.source.clone(),
                cause: e,
            })?;
            model.add(term);
        }
        Ok(())
    }
}

/// A tool's extra dof: fixed, driven to its displacement, or free with its
/// mass and weight; its index among the extras, its global dof and the
/// unit direction it moves along.
fn tool_dof(
    spec: &ToolSpec,
    node_count: usize,
    model: &mut Model,
    dirichlet: &mut Vec<Dirichlet>,
) -> (usize, usize, Vector3<f64>) {
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
                node_count,
                vec![],
                vec![(extra, weight)],
                crate::model::LoadAmplitude::Constant,
            ));
            direction
        }
    };
    (extra, dof, direction)
}

/// Refuses a ply whose mid-surface starts inside a tool (more than the
/// contact `offset` into the contact layer): a set-up error.
fn check_outside(
    case: &FormingCase,
    spec: &ToolSpec,
    surface: &Arc<dyn RigidSurface>,
    ply: &BuiltPly,
    offset: f64,
) -> Result<(), BuildError> {
    for (n, x) in ply.mesh.nodes.iter().enumerate() {
        if let Some(point) = surface.closest(x, offset)
            && point.distance < 0.0
        {
            return Err(BuildError::ToolInsidePly {
                file: case.source.clone(),
                tool: spec.name.clone(),
                ply: ply.name.clone(),
                node: ply.mesh.node_label(n),
                position: [x.x, x.y, x.z],
                depth: -point.distance,
                offset,
            });
        }
    }
    Ok(())
}
