//! The off-axis tension test (paper Section 4; `docs/cases.md`): a flat rectangle `x ∈ [0, W]`, `y ∈ [0, L]`, rovings at the bias
//! angle θ from the load axis `y`, `a0 = (sin θ, cos θ)`. The edge `y = 0` is
//! clamped; the edge `y = L` is fixed in `x` and `z` and pulled in `+y` to
//! the final displacement. The test is in-plane: every `z` is fixed.
//!
//! The case is read table by table (`tables.rs`: `[specimen]`, `[mesh]`,
//! `[material]`, `[loading]`, `[output]`), with the `solver` key and the
//! `[explicit]` table; `build.rs` turns it into a model. Key-by-key
//! documentation: `docs/cases.md`.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use serde::Serialize;

use super::explicit::{ExplicitSettings, SolverKind, solver_choice, validate_solver};
use crate::config::{CaseWarning, ConfigError, TomlChecker, parse_toml};
use crate::material::MaterialSpec;
use crate::mesh::Mesh;
use crate::mesh::generate::{GridPattern, GridResolution};
use crate::model::MembraneModel;
use crate::solver::{Dirichlet, NewtonParameters};

mod build;
mod raw;
mod tables;

pub use build::oat_clamps;
pub(crate) use tables::load_params;

use raw::CaseRaw;

/// Default side of the square main-deformation-zone window \[mm\].
pub const DEFAULT_MDZ_SIZE: f64 = 20.0;
/// Default membrane thickness \[mm\] (not in the paper; `docs/parameters.md`).
pub const DEFAULT_THICKNESS: f64 = 0.3;

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
    /// Line of `mesh.file` in the case file (0 for a generated mesh):
    /// errors of the mesh file name it.
    pub mesh_line: usize,
    /// The unusual values of the case (`docs/cases.md`, "Ranges"),
    /// printed by `ncform run` before the run.
    pub warnings: Vec<CaseWarning>,
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
        let check = TomlChecker::new(text, source);
        let (width, length, bias_angle_deg) = tables::specimen(&check, &raw.specimen)?;
        let mesh = tables::mesh(&check, &raw.mesh, base_dir)?;
        let (material, thickness, named_set) =
            tables::material(&check, raw.material.as_ref(), base_dir)?;
        let (displacement, mut output_displacements) =
            tables::loading(&check, &raw.loading, length)?;
        let (mdz_size, contour_displacement) = tables::output(
            &check,
            raw.output.as_ref(),
            displacement,
            &mut output_displacements,
        )?;
        let (solver_kind, solver) = solver_choice(raw.solver, &check)?;
        validate_solver(&solver, &check)?;
        crate::case::explicit::unused_explicit_table(&check, solver_kind, raw.explicit.as_ref());
        let explicit = ExplicitSettings::from_raw(raw.explicit.as_ref(), &check, displacement)?;
        let density = tables::density(&check, raw.material.as_ref(), thickness, named_set)?;
        if solver_kind == SolverKind::QuasiStatic
            && let Some(m) = &raw.material
        {
            // Read for the one-line switch to the explicit solver, as the
            // [explicit] table is, but not used by the quasi-static one.
            for (key, given) in [
                (
                    "material.areal_mass",
                    check.given("areal_mass", &m.areal_mass),
                ),
                ("material.density", check.given("density", &m.density)),
            ] {
                if let Some(g) = given {
                    check.warn(
                        g.line,
                        key,
                        g.value,
                        String::new(),
                        "the quasi-static solver does not use the mass (only the explicit one does)",
                    );
                }
            }
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
            mesh_line: raw.mesh.file.as_ref().map_or(0, |f| check.line_of(f)),
            warnings: check.take_warnings(),
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
}
