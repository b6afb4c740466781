//! The off-axis tension test (paper Section 4; `docs/cases.md`): a flat rectangle `x ∈ [0, W]`, `y ∈ [0, L]`, rovings at the bias
//! angle θ from the load axis `y`, `a0 = (sin θ, cos θ)`. The edge `y = 0` is
//! clamped; the edge `y = L` is fixed in `x` and `z` and pulled in `+y` to
//! the final displacement. The test is in-plane: every `z` is fixed.

use std::path::{Path, PathBuf};

use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};
use toml::Spanned;

use super::explicit::{
    DEFAULT_AREAL_MASS, ExplicitRaw, ExplicitSettings, KG_PER_M2_IN_T_PER_MM2, SolverChoice,
    SolverKind,
};
use crate::config::{ConfigError, TomlChecker, parse_toml};
use crate::material::MaterialSpec;
use crate::mesh::Mesh;
use crate::mesh::generate::{GridPattern, GridResolution, OatSpecimen, oat_specimen};
use crate::model::{MembraneModel, MembraneOptions, Model};
use crate::solver::{Dirichlet, DofMap, NewtonParameters};

/// Default side of the square main-deformation-zone window \[mm\].
pub const DEFAULT_MDZ_SIZE: f64 = 20.0;
/// Default membrane thickness \[mm\] (not in the paper; `docs/parameters.md`).
pub const DEFAULT_THICKNESS: f64 = 0.3;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseRaw {
    title: Option<Spanned<String>>,
    specimen: SpecimenRaw,
    mesh: MeshRaw,
    material: Option<MaterialRaw>,
    loading: LoadingRaw,
    output: Option<OutputRaw>,
    solver: Option<Spanned<SolverChoice>>,
    explicit: Option<ExplicitRaw>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SpecimenRaw {
    width: Spanned<f64>,
    length: Spanned<f64>,
    bias_angle_deg: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshRaw {
    element_size: Option<Spanned<f64>>,
    nx: Option<Spanned<i64>>,
    ny: Option<Spanned<i64>>,
    pattern: Option<Spanned<String>>,
    file: Option<Spanned<String>>,
    fixed_clamp_set: Option<String>,
    moving_clamp_set: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialRaw {
    params: Option<String>,
    thickness: Option<Spanned<f64>>,
    areal_mass: Option<Spanned<f64>>,
    density: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LoadingRaw {
    displacement: Spanned<f64>,
    output_displacements: Option<Spanned<Vec<f64>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OutputRaw {
    mdz_size: Option<Spanned<f64>>,
    contour_displacement: Option<Spanned<f64>>,
}

/// Where the specimen mesh comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshSource {
    /// Generated: every triangle with an edge along the rovings.
    Generated {
        /// Element size or grid counts.
        resolution: GridResolution,
        /// Two or four triangles per cell.
        pattern: GridPattern,
    },
    /// Read from an Abaqus `.inp` or Gmsh `.msh` file.
    File {
        /// Path (relative paths are taken from the case file's folder).
        path: PathBuf,
        /// Node set of the fixed clamp (`y = 0`).
        fixed_clamp_set: String,
        /// Node set of the moving clamp (`y = L`).
        moving_clamp_set: String,
    },
}

/// A validated OAT case.
#[derive(Debug, Clone)]
pub struct OatCase {
    /// Free-text title.
    pub title: String,
    /// The case file (or "embedded").
    pub source: String,
    /// Specimen width `W` \[mm\] (x).
    pub width: f64,
    /// Free length `L` between the clamps \[mm\] (y).
    pub length: f64,
    /// Bias angle θ between rovings and load axis \[deg\].
    pub bias_angle_deg: f64,
    /// The mesh.
    pub mesh: MeshSource,
    /// The material law.
    pub material: MaterialSpec,
    /// Membrane thickness \[mm\].
    pub thickness: f64,
    /// Final clamp displacement \[mm\].
    pub displacement: f64,
    /// Clamp displacements with VTU output \[mm\] (the final one is added).
    pub output_displacements: Vec<f64>,
    /// Side of the MDZ window \[mm\].
    pub mdz_size: f64,
    /// Displacement of the contour-map pictures \[mm\].
    pub contour_displacement: f64,
    /// Which solver runs the case.
    pub solver_kind: SolverKind,
    /// Newton parameters (quasi-static).
    pub solver: NewtonParameters,
    /// Explicit settings (read when `solver_kind` is explicit).
    pub explicit: ExplicitSettings,
    /// Mass density [t/mm³]: from `material.areal_mass` or
    /// `material.density`, 0.30 kg/m² for the named sets, `None` for a
    /// parameter file without either (the quasi-static path needs none).
    pub density: Option<f64>,
}

/// The zones of the OAT: classic two-family reading of the paper's Section
/// 4 (C: roving and stitching lines both end on a clamp, barely deforms;
/// B: one of them does; A: neither, largest strains).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Zone {
    /// Free at both ends: the main deformation zone lies here.
    A,
    /// One family clamped: intermediate.
    B,
    /// Both families clamped: barely deforms.
    C,
}

impl Zone {
    /// 0, 1, 2 for A, B, C (for VTU).
    pub fn index(self) -> i32 {
        match self {
            Zone::A => 0,
            Zone::B => 1,
            Zone::C => 2,
        }
    }
}

/// A case turned into a model.
#[derive(Debug, Clone)]
pub struct OatModel {
    /// The mesh (with fibres).
    pub mesh: Mesh,
    /// The membrane model.
    pub model: MembraneModel,
    /// Clamps and the in-plane condition; the load parameter is the clamp
    /// displacement \[mm\].
    pub dirichlet: Vec<Dirichlet>,
    /// Zone of every element.
    pub zones: Vec<Zone>,
    /// Elements of the main deformation zone.
    pub mdz: Vec<usize>,
    /// Largest angle between the rovings and the nearest edge of a triangle
    /// \[deg\] (generated meshes only).
    pub edge_deviation_deg: Option<f64>,
}

impl OatCase {
    /// Parses and validates a case; relative paths are resolved against
    /// `base_dir`.
    ///
    /// # Errors
    /// Unknown or missing keys, values out of range, an unusable material
    /// set — each naming the file, line, key and value.
    pub fn from_toml_str(text: &str, source: &str, base_dir: &Path) -> Result<Self, ConfigError> {
        let raw: CaseRaw = parse_toml(text, source)?;
        let check = TomlChecker { text, source };
        let positive =
            |v: &Spanned<f64>, key: &str| check.range(v, key, |x| x > 0.0, "a length > 0 mm");
        let width = positive(&raw.specimen.width, "specimen.width")?;
        let length = positive(&raw.specimen.length, "specimen.length")?;
        let bias_angle_deg = check.range(
            &raw.specimen.bias_angle_deg,
            "specimen.bias_angle_deg",
            |x| (-90.0..=90.0).contains(&x),
            "an angle in [-90, 90] degrees",
        )?;

        let m = &raw.mesh;
        let pattern = match &m.pattern {
            None => GridPattern::RovingDiagonal,
            Some(p) => check.choice(
                p,
                "mesh.pattern",
                &[
                    ("roving-diagonal", GridPattern::RovingDiagonal),
                    ("both-diagonals", GridPattern::BothDiagonals),
                ],
            )?,
        };
        if let (Some(_), Some(p)) = (&m.file, &m.pattern) {
            return Err(check.invalid(
                check.line_of(p),
                "mesh.pattern",
                format!("\"{}\"", p.get_ref()),
                "no pattern with mesh.file (the file's triangles are used as they are)",
            ));
        }
        let mesh = match (&m.file, &m.element_size, &m.nx, &m.ny) {
            (Some(file), None, None, None) => MeshSource::File {
                path: base_dir.join(file.get_ref()),
                fixed_clamp_set: m.fixed_clamp_set.clone().unwrap_or_else(|| "bottom".into()),
                moving_clamp_set: m.moving_clamp_set.clone().unwrap_or_else(|| "top".into()),
            },
            (None, Some(size), None, None) => MeshSource::Generated {
                resolution: GridResolution::ElementSize(positive(size, "mesh.element_size")?),
                pattern,
            },
            (None, None, Some(nx), Some(ny)) => MeshSource::Generated {
                resolution: GridResolution::Counts {
                    nx: check.count(nx, "mesh.nx", 1..=100_000)?,
                    ny: check.count(ny, "mesh.ny", 1..=100_000)?,
                },
                pattern,
            },
            _ => {
                return Err(
                    check.missing("[mesh]", "exactly one of: element_size; nx and ny; file")
                );
            }
        };
        if !matches!(mesh, MeshSource::File { .. })
            && (m.fixed_clamp_set.is_some() || m.moving_clamp_set.is_some())
        {
            return Err(check.invalid(
                0,
                "mesh.fixed_clamp_set / mesh.moving_clamp_set",
                "(given)".into(),
                "clamp sets only with mesh.file (generated meshes clamp 'bottom' and 'top')",
            ));
        }

        let (params, thickness) = match &raw.material {
            None => (None, None),
            Some(mr) => (mr.params.clone(), mr.thickness.clone()),
        };
        let named_set = params
            .as_ref()
            .is_none_or(|p| MaterialSpec::named_text(p).is_some());
        let material = match params {
            None => MaterialSpec::default_set(),
            Some(p) if MaterialSpec::named_text(&p).is_some() => MaterialSpec::load(&p)?,
            Some(p) => MaterialSpec::load(&base_dir.join(&p).display().to_string()).map_err(
                |e| match e {
                    // Say which case key asked for the missing set or file.
                    ConfigError::NotFound { requested, reason } => ConfigError::NotFound {
                        requested: format!("{source}: material.params = \"{p}\" ({requested})"),
                        reason,
                    },
                    other => other,
                },
            )?,
        };
        let thickness = match thickness {
            None => DEFAULT_THICKNESS,
            Some(t) => positive(&t, "material.thickness")?,
        };

        // A stretch of 2 along the load axis is far beyond a fabric's range
        // (the paper's OATs end at 80 mm of 300 mm).
        let displacement = check.range(
            &raw.loading.displacement,
            "loading.displacement",
            |x| x > 0.0 && x <= length,
            &format!(
                "a clamp displacement in (0, {}] mm (at most the free length)",
                crate::config::readable_number(length)
            ),
        )?;
        let mut output_displacements = match &raw.loading.output_displacements {
            None => vec![],
            Some(list) => {
                let line = check.line_of(list);
                for &d in list.get_ref() {
                    if !(d.is_finite() && d > 0.0 && d <= displacement) {
                        return Err(check.invalid(
                            line,
                            "loading.output_displacements",
                            crate::config::readable_number(d),
                            &format!(
                                "displacements in (0, {}] mm",
                                crate::config::readable_number(displacement)
                            ),
                        ));
                    }
                }
                list.get_ref().clone()
            }
        };
        output_displacements.push(displacement);
        output_displacements.sort_by(f64::total_cmp);
        output_displacements.dedup();

        let (mdz_size, contour_displacement) = match &raw.output {
            None => (DEFAULT_MDZ_SIZE, displacement),
            Some(o) => (
                match &o.mdz_size {
                    None => DEFAULT_MDZ_SIZE,
                    Some(s) => positive(s, "output.mdz_size")?,
                },
                match &o.contour_displacement {
                    None => displacement,
                    Some(d) => check.range(
                        d,
                        "output.contour_displacement",
                        |x| x > 0.0 && x <= displacement,
                        &format!("a displacement in (0, {displacement}] mm"),
                    )?,
                },
            ),
        };
        if !output_displacements.contains(&contour_displacement) {
            output_displacements.push(contour_displacement);
            output_displacements.sort_by(f64::total_cmp);
        }
        let (solver_kind, solver) = solver_choice(raw.solver, &check)?;
        validate_solver(&solver, source)?;
        let explicit = ExplicitSettings::from_raw(raw.explicit.as_ref(), &check, displacement)?;
        let material_raw = raw.material.as_ref();
        let areal_mass = material_raw.and_then(|m| m.areal_mass.as_ref());
        let given_density = material_raw.and_then(|m| m.density.as_ref());
        let density = match (areal_mass, given_density) {
            (Some(_), Some(d)) => {
                return Err(check.invalid(
                    check.line_of(d),
                    "material.density",
                    crate::config::readable_number(*d.get_ref()),
                    "either material.areal_mass [kg/m²] or material.density [t/mm³], not both",
                ));
            }
            (Some(a), None) => Some(
                check.range(
                    a,
                    "material.areal_mass",
                    |x| x > 0.0,
                    "an areal mass > 0 kg/m²",
                )? * KG_PER_M2_IN_T_PER_MM2
                    / thickness,
            ),
            (None, Some(d)) => Some(check.range(
                d,
                "material.density",
                |x| x > 0.0,
                "a density > 0 t/mm³ (1.0e-9 for 0.30 kg/m² at 0.3 mm)",
            )?),
            (None, None) if named_set => {
                Some(DEFAULT_AREAL_MASS * KG_PER_M2_IN_T_PER_MM2 / thickness)
            }
            (None, None) => None,
        };
        if let Some(rho) = density
            && !rho.is_finite()
        {
            // A finite areal mass over a thickness of 5e-324 mm.
            let (key, line) = match material_raw.and_then(|m| m.thickness.as_ref()) {
                Some(t) => ("material.thickness", check.line_of(t)),
                None => ("material.thickness", 0),
            };
            return Err(check.invalid(
                line,
                key,
                crate::config::readable_number(thickness),
                "a thickness for which the density (areal mass / thickness) is finite",
            ));
        }
        if solver_kind == SolverKind::Explicit && density.is_none() {
            return Err(check.missing(
                "material.areal_mass",
                "the fabric's mass for the explicit solver: material.areal_mass [kg/m²] or material.density [t/mm³] (the 0.30 kg/m² default belongs to the named parameter sets, not to a parameter file)",
            ));
        }
        Ok(Self {
            title: match &raw.title {
                None => format!("{bias_angle_deg}° off-axis tension test"),
                Some(t) => check.one_line(t, "title")?,
            },
            source: source.to_string(),
            width,
            length,
            bias_angle_deg,
            mesh,
            material,
            thickness,
            displacement,
            output_displacements,
            mdz_size,
            contour_displacement,
            solver_kind,
            solver,
            explicit,
            density,
        })
    }

    /// Reads and validates a case file.
    ///
    /// # Errors
    /// As [`OatCase::from_toml_str`], or an unreadable file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let (text, source, base) = crate::config::read_case_file(path)?;
        Self::from_toml_str(&text, &source, &base)
    }

    /// The unit roving direction `a0 = (sin θ, cos θ, 0)`.
    pub fn roving_direction(&self) -> Vector3<f64> {
        let theta = self.bias_angle_deg.to_radians();
        Vector3::new(theta.sin(), theta.cos(), 0.0)
    }

    /// Builds the mesh, the model, the clamps, the zones and the MDZ.
    ///
    /// # Errors
    /// A mesh that cannot be generated or read, a missing clamp set, a
    /// degenerate triangle — with the file and element named.
    pub fn build(&self) -> Result<OatModel, String> {
        let (mut mesh, edge_deviation_deg, fixed, moving) = match &self.mesh {
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
                    format!("{}: [{table}] {e}", self.source)
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
                        return Err(format!(
                            "{}: mesh.file = \"{}\": expected an Abaqus .inp or a Gmsh .msh file",
                            self.source,
                            path.display()
                        ));
                    }
                }
                .map_err(|e| format!("{}: mesh.file = \"{}\": {e}", self.source, path.display()))?;
                (
                    mesh,
                    None,
                    fixed_clamp_set.clone(),
                    moving_clamp_set.clone(),
                )
            }
        };
        let in_case = |e: &dyn std::fmt::Display| format!("{}: {e}", self.source);
        if mesh.fibres.is_empty() {
            mesh.set_fibres_from_global(self.roving_direction())
                .map_err(|e| {
                    format!(
                        "{}: specimen.bias_angle_deg = {}: {e}",
                        self.source,
                        crate::config::readable_number(self.bias_angle_deg)
                    )
                })?;
        }
        mesh.check().map_err(|e| in_case(&e))?;
        let clamp = |key: &str, name: &str| {
            mesh.node_set(name)
                .map(<[usize]>::to_vec)
                .map_err(|e| format!("{}: mesh.{key} = \"{name}\": {e}", self.source))
        };
        let fixed_nodes = clamp("fixed_clamp_set", &fixed)?;
        let moving_nodes = clamp("moving_clamp_set", &moving)?;
        for (set, nodes, key) in [
            (&fixed, &fixed_nodes, "mesh.fixed_clamp_set"),
            (&moving, &moving_nodes, "mesh.moving_clamp_set"),
        ] {
            if nodes.is_empty() {
                return Err(format!(
                    "{}: {key} = \"{set}\": the node set of {} is empty; expected the nodes of a clamped edge",
                    self.source, mesh.source
                ));
            }
        }
        let in_fixed: std::collections::HashSet<usize> = fixed_nodes.iter().copied().collect();
        if let Some(&shared) = moving_nodes.iter().find(|n| in_fixed.contains(n)) {
            return Err(format!(
                "{}: mesh.fixed_clamp_set = \"{fixed}\" and mesh.moving_clamp_set = \"{moving}\": node {} of {} is in both sets; expected two clamps without a common node (one is fixed, the other moves)",
                self.source,
                mesh.node_label(shared),
                mesh.source
            ));
        }
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
        .map_err(|(e, err)| {
            format!(
                "{}: element {}: {err}",
                mesh.source,
                mesh.element_labels.get(e).copied().unwrap_or(e as i64)
            )
        })?;
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
        Ok(OatModel {
            mesh,
            model,
            dirichlet,
            zones,
            mdz,
            edge_deviation_deg,
        })
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

/// The top-level `solver` key: a method name or a `[solver]` table of
/// Newton knobs (quasi-static).
pub(super) fn solver_choice(
    choice: Option<Spanned<SolverChoice>>,
    check: &TomlChecker,
) -> Result<(SolverKind, NewtonParameters), ConfigError> {
    Ok(match choice {
        None => (SolverKind::QuasiStatic, NewtonParameters::default()),
        Some(choice) => {
            let line = check.line_of(&choice);
            match choice.into_inner() {
                SolverChoice::Newton(p) => (SolverKind::QuasiStatic, p),
                SolverChoice::Method(m) => match m.as_str() {
                    "quasi-static" => (SolverKind::QuasiStatic, NewtonParameters::default()),
                    "explicit" => (SolverKind::Explicit, NewtonParameters::default()),
                    other => {
                        return Err(check.invalid(
                            line,
                            "solver",
                            format!("\"{other}\""),
                            "\"quasi-static\", \"explicit\" or a [solver] table of Newton knobs",
                        ));
                    }
                },
            }
        }
    })
}

/// Checks the Newton knobs of a `[solver]` table.
pub(super) fn validate_solver(p: &NewtonParameters, source: &str) -> Result<(), ConfigError> {
    let bad = |key: &str, value: String, expected: &str| ConfigError::Invalid {
        source: source.to_string(),
        line: 0,
        key: format!("solver.{key}"),
        value,
        expected: expected.to_string(),
    };
    let pos = |key: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(bad(key, crate::config::readable_number(v), "a number > 0"))
        }
    };
    pos("initial_increment", p.initial_increment)?;
    pos("max_increment", p.max_increment)?;
    pos("min_increment", p.min_increment)?;
    pos("residual_tolerance", p.residual_tolerance)?;
    pos("energy_tolerance", p.energy_tolerance)?;
    pos("force_floor", p.force_floor)?;
    if p.min_increment > p.max_increment {
        return Err(bad(
            "min_increment",
            crate::config::readable_number(p.min_increment),
            "at most max_increment",
        ));
    }
    if !(p.growth >= 1.0 && p.growth.is_finite()) {
        return Err(bad(
            "growth",
            crate::config::readable_number(p.growth),
            "a factor ≥ 1",
        ));
    }
    if !(p.cutback > 0.0 && p.cutback < 1.0) {
        return Err(bad(
            "cutback",
            crate::config::readable_number(p.cutback),
            "a factor in (0, 1)",
        ));
    }
    if p.max_iterations == 0 {
        return Err(bad("max_iterations", "0".into(), "at least 1"));
    }
    pos("stabilisation_fraction", p.stabilisation_fraction)?;
    if let Some(t) = p.max_wall_seconds {
        pos("max_wall_seconds", t)?;
    }
    if let Some(t) = p.inertia_duration {
        pos("inertia_duration", t)?;
    }
    pos("stabilisation_limit", p.stabilisation_limit)?;
    if !(p.stabilisation_factor.is_finite() && p.stabilisation_factor >= 0.0) {
        return Err(bad(
            "stabilisation_factor",
            crate::config::readable_number(p.stabilisation_factor),
            "a number ≥ 0",
        ));
    }
    Ok(())
}
