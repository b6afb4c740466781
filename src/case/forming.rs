//! Forming set-ups from case files: plies (generated blanks or mesh files,
//! each with its law, thickness, areal mass, fibre angle and bending
//! stiffness), rigid tools (analytic shapes or triangle meshes, fixed,
//! prescribed or floating, each with its friction), boundary conditions on
//! node sets, gravity and dead loads, the load programme, the solver and
//! the outputs. Only this layer knows what a ply or a punch is; it builds a
//! [`Model`](crate::model::Model) of force terms and the Dirichlet conditions the solvers drive.
//! Key-by-key documentation: `docs/cases.md`, "Forming cases".
//!
//! The load parameter of a forming case is the programme fraction
//! `λ ∈ [0, 1]`: prescribed tools and boundaries reach their displacement
//! at `λ = 1`, ramped loads their full value.

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use serde::Deserialize;
use toml::Spanned;

use super::explicit::{
    DEFAULT_AREAL_MASS, ExplicitRaw, ExplicitSettings, KG_PER_M2_IN_T_PER_MM2, SolverChoice,
    SolverKind,
};
use crate::config::{ConfigError, TomlChecker, parse_toml};
use crate::contact::kernel::Smoothing;
use crate::material::MaterialSpec;
use crate::model::{ExplicitPenalty, LoadAmplitude};
use crate::solver::NewtonParameters;

/// Standard gravity [mm/s²].
pub const STANDARD_GRAVITY: f64 = 9810.0;
/// `1 kg = 1e-3 t`.
pub const KG_IN_T: f64 = 1.0e-3;
/// Default number of VTU states over the programme (besides `λ = 0`).
pub const DEFAULT_STATES: usize = 10;
/// Default number of history rows of an explicit run.
pub const DEFAULT_HISTORY_ROWS: usize = 100;

// --- the file as written --------------------------------------------------

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FormingRaw {
    title: Option<Spanned<String>>,
    ply: Vec<PlyRaw>,
    #[serde(default)]
    tool: Vec<ToolRaw>,
    #[serde(default)]
    boundary: Vec<BoundaryRaw>,
    #[serde(default)]
    load: Vec<LoadRaw>,
    #[serde(default)]
    probe: Vec<ProbeRaw>,
    #[serde(default)]
    zone: Vec<ZoneRaw>,
    #[serde(default)]
    ply_contact: Vec<PlyContactRaw>,
    gravity: Option<GravityRaw>,
    contact: Option<ContactRaw>,
    output: Option<OutputRaw>,
    solver: Option<Spanned<SolverChoice>>,
    explicit: Option<ExplicitRaw>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlyRaw {
    name: Option<String>,
    params: Option<String>,
    thickness: Option<Spanned<f64>>,
    areal_mass: Option<Spanned<f64>>,
    fibre_angle_deg: Option<Spanned<f64>>,
    bending: Option<BendingRaw>,
    mesh: PlyMeshRaw,
}

/// `bending = false` or a table of stiffnesses.
#[derive(Deserialize)]
#[serde(untagged)]
enum BendingRaw {
    Switch(bool),
    Table(BendingTableRaw),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BendingTableRaw {
    b11: Option<f64>,
    b22: Option<f64>,
    b66: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlyMeshRaw {
    shape: Option<Spanned<String>>,
    size: Option<Spanned<Vec<f64>>>,
    centre: Option<Spanned<Vec<f64>>>,
    element_size: Option<Spanned<f64>>,
    cells: Option<Spanned<Vec<i64>>>,
    pattern: Option<Spanned<String>>,
    radius: Option<Spanned<f64>>,
    width: Option<Spanned<f64>>,
    wrap_angle_deg: Option<Spanned<f64>>,
    tail_length: Option<Spanned<f64>>,
    file: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ToolRaw {
    name: Option<String>,
    shape: Spanned<String>,
    origin: Option<Spanned<Vec<f64>>>,
    axis: Option<Spanned<Vec<f64>>>,
    radius: Option<Spanned<f64>>,
    major_radius: Option<Spanned<f64>>,
    minor_radius: Option<Spanned<f64>>,
    opening_radius: Option<Spanned<f64>>,
    fillet_radius: Option<Spanned<f64>>,
    sides: Option<Spanned<i64>>,
    face_angle_deg: Option<Spanned<f64>>,
    rounding_radius: Option<Spanned<f64>>,
    height: Option<Spanned<f64>>,
    edge_direction: Option<Spanned<Vec<f64>>>,
    punch: Option<Spanned<String>>,
    clearance: Option<Spanned<f64>>,
    section_at: Option<Spanned<Vec<f64>>>,
    side: Option<Spanned<String>>,
    file: Option<Spanned<String>>,
    scale: Option<Spanned<f64>>,
    closed: Option<bool>,
    extent: Option<Spanned<f64>>,
    friction: Option<Spanned<f64>>,
    motion: Option<Spanned<String>>,
    direction: Option<Spanned<Vec<f64>>>,
    displacement: Option<Spanned<f64>>,
    mass: Option<Spanned<f64>>,
    weight: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct BoundaryRaw {
    ply: Option<String>,
    nodes: Spanned<String>,
    fix: Option<Spanned<Vec<String>>>,
    displacement: Option<Spanned<Vec<f64>>>,
    rotation: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LoadRaw {
    ply: Option<String>,
    nodes: Spanned<String>,
    force: Spanned<Vec<f64>>,
    amplitude: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProbeRaw {
    ply: Option<String>,
    nodes: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ZoneRaw {
    name: Option<String>,
    ply: Option<String>,
    centre: Spanned<Vec<f64>>,
    size: Option<Spanned<Vec<f64>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlyContactRaw {
    plies: Spanned<Vec<String>>,
    friction: Spanned<f64>,
    skin: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GravityRaw {
    g: Option<Spanned<f64>>,
    direction: Option<Spanned<Vec<f64>>>,
    amplitude: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ContactRaw {
    offset: Option<Spanned<f64>>,
    penalty: Option<Spanned<f64>>,
    penalty_scale: Option<Spanned<f64>>,
    tangential_penalty_scale: Option<Spanned<f64>>,
    normal_smoothing: Option<Spanned<f64>>,
    friction_smoothing: Option<Spanned<f64>>,
    gap_tolerance: Option<Spanned<f64>>,
    multiplier_tolerance: Option<Spanned<f64>>,
    explicit_stiffness: Option<Spanned<f64>>,
    explicit_pressure_stiffness: Option<Spanned<f64>>,
    explicit_damping: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OutputRaw {
    states: Option<Spanned<i64>>,
    history: Option<Spanned<i64>>,
    camera: Option<Spanned<String>>,
}

// --- the validated case ----------------------------------------------------

/// Where a ply's mesh comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum PlyMesh {
    /// A flat rectangle `size` in x and y centred at `centre`, meshed so
    /// that every triangle has an edge along the rovings.
    Rectangle {
        /// Extents along x and y \[mm\].
        size: [f64; 2],
        /// Centre \[mm\].
        centre: Vector3<f64>,
        /// Element size or cell counts.
        resolution: crate::mesh::generate::GridResolution,
        /// How the cells are cut into triangles.
        pattern: crate::mesh::generate::GridPattern,
    },
    /// A flat circular membrane of radius `radius` centred at `centre`.
    Disk {
        /// Radius \[mm\].
        radius: f64,
        /// Centre \[mm\].
        centre: Vector3<f64>,
        /// Element size \[mm\].
        element_size: f64,
    },
    /// A strip pre-wrapped over a cylinder along y through `centre`.
    WrappedStrip {
        /// Radius of the strip's mid-surface arc \[mm\].
        radius: f64,
        /// Wrap angle \[deg\].
        wrap_angle_deg: f64,
        /// Length of each straight tail \[mm\].
        tail_length: f64,
        /// Width of the strip \[mm\].
        width: f64,
        /// Element size \[mm\].
        element_size: f64,
        /// Centre of the cylinder's axis \[mm\].
        centre: Vector3<f64>,
    },
    /// An Abaqus `.inp` or Gmsh `.msh` file.
    File {
        /// Path (relative paths from the case file's folder).
        path: PathBuf,
    },
}

/// One ply.
#[derive(Debug, Clone)]
pub struct PlySpec {
    /// Name (messages, outputs, node-set references).
    pub name: String,
    /// The mesh.
    pub mesh: PlyMesh,
    /// The law.
    pub material: MaterialSpec,
    /// Thickness \[mm\].
    pub thickness: f64,
    /// Mass density [t/mm³] (`None`: a parameter file without areal mass,
    /// quasi-static without gravity only).
    pub density: Option<f64>,
    /// Roving angle from the global x axis in the blank's plane \[deg\]
    /// (rovings `(cos α, sin α, 0)`), for generated rectangles and mesh
    /// files; a wrapped strip has its rovings along its length.
    pub fibre_angle_deg: f64,
    /// Bending stiffnesses `(B11, B22, B66)` [N·mm], `None` for a membrane
    /// without bending.
    pub bending: Option<[f64; 3]>,
}

/// A tool's surface.
#[derive(Debug, Clone, PartialEq)]
pub enum ToolShape {
    /// The plane through the origin normal to the axis (free side along it).
    Plane,
    /// A sphere of radius `radius` about the origin.
    Sphere {
        /// Radius \[mm\].
        radius: f64,
    },
    /// An infinite cylinder of radius `radius` about the axis.
    Cylinder {
        /// Radius \[mm\].
        radius: f64,
    },
    /// A torus about the axis.
    Torus {
        /// Radius of the centre circle \[mm\].
        major_radius: f64,
        /// Radius of the tube \[mm\].
        minor_radius: f64,
    },
    /// A plate whose face (normal = axis, towards the ply) has a round
    /// opening with a fillet (a die or a blankholder).
    PlateWithHole {
        /// Opening radius \[mm\].
        opening_radius: f64,
        /// Fillet radius \[mm\].
        fillet_radius: f64,
    },
    /// A rounded regular pyramid, apex first along the axis reversed (the
    /// axis points from the apex to the base; the origin is the solid's
    /// lowest point), [`crate::contact::Pyramid`].
    Pyramid {
        /// Number of lateral faces.
        sides: usize,
        /// Angle of the lateral faces to the base plane \[rad\].
        face_angle: f64,
        /// Rounding radius of the apex and every edge \[mm\].
        rounding_radius: f64,
        /// Height of the sharp core from its apex to its base \[mm\].
        height: f64,
        /// Direction of one base edge (unit, normal to the axis).
        edge_direction: Vector3<f64>,
    },
    /// A plate whose face (normal = axis, towards the ply) has a rounded
    /// polygonal opening with a fillet, following a pyramid punch's section
    /// at the punch's full stroke grown by a clearance
    /// ([`crate::contact::PlateWithPolygonHole`],
    /// [`crate::contact::punch_opening`]).
    PlateWithPolygonHole {
        /// The name of the pyramid tool the opening follows.
        punch: String,
        /// Clearance between the punch's section and the opening \[mm\].
        clearance: f64,
        /// Fillet radius \[mm\].
        fillet_radius: f64,
        /// A point of the plane where the section is taken \[mm\] (`None`:
        /// the plate's origin).
        section_at: Option<Vector3<f64>>,
        /// The opening's polygon in the plate's local `(x, y)` \[mm\]
        /// (counter-clockwise), computed from the punch when the case is
        /// read.
        polygon: Vec<[f64; 2]>,
        /// The opening's corner radius \[mm\], computed likewise.
        corner_radius: f64,
    },
    /// A triangle mesh from an STL or OBJ file.
    Mesh {
        /// Path (relative paths from the case file's folder).
        path: PathBuf,
        /// Scale to mm.
        scale: f64,
        /// Require a closed, consistently oriented mesh.
        closed: bool,
    },
}

/// How a tool moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ToolMotion {
    /// It does not move.
    Fixed,
    /// It translates by `displacement` \[mm\] along `direction` over the
    /// programme.
    Prescribed {
        /// Unit direction.
        direction: Vector3<f64>,
        /// Displacement at `λ = 1` \[mm\].
        displacement: f64,
    },
    /// It translates freely along `direction` with its mass under its
    /// weight.
    Floating {
        /// Unit direction.
        direction: Vector3<f64>,
        /// Mass \[t\].
        mass: f64,
        /// Dead force along `direction` \[N\] (its weight's component).
        weight: f64,
    },
}

/// One rigid tool.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolSpec {
    /// Name.
    pub name: String,
    /// Surface.
    pub shape: ToolShape,
    /// The surface's local origin \[mm\].
    pub origin: Vector3<f64>,
    /// The surface's local z axis (unit).
    pub axis: Vector3<f64>,
    /// `true` when the ply is inside a sphere, cylinder or torus.
    pub inside: bool,
    /// Coulomb friction coefficient.
    pub friction: f64,
    /// Motion.
    pub motion: ToolMotion,
    /// Half-size of the drawn surface (planes, plates) \[mm\].
    pub extent: f64,
}

/// A Dirichlet condition on a node set of a ply.
#[derive(Debug, Clone, PartialEq)]
pub struct BoundarySpec {
    /// Ply index.
    pub ply: usize,
    /// Node set.
    pub nodes: String,
    /// Fixed components (x, y, z); a driven component is fixed too.
    pub fixed: [bool; 3],
    /// Displacement at `λ = 1` of the fixed components \[mm\].
    pub displacement: [f64; 3],
    /// Fix the rotation of bending about edges on this set (a clamp).
    pub clamp_rotation: bool,
    /// Line of the condition in the case file (messages).
    pub line: usize,
}

/// A dead force on a node set.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadSpec {
    /// Ply index.
    pub ply: usize,
    /// Node set.
    pub nodes: String,
    /// Total force \[N\], shared equally by the set's nodes.
    pub force: Vector3<f64>,
    /// Amplitude.
    pub amplitude: LoadAmplitude,
    /// Line in the case file.
    pub line: usize,
}

/// A node set whose mean displacement is written to the history.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeSpec {
    /// Ply index.
    pub ply: usize,
    /// Node set.
    pub nodes: String,
    /// Line in the case file.
    pub line: usize,
}

/// An evaluation zone of a ply (`[[zone]]`): a rectangular window of the
/// blank in reference coordinates, over which the strain measures are
/// averaged (`docs/forming.md`, "Zones").
#[derive(Debug, Clone, PartialEq)]
pub struct ZoneSpec {
    /// The ply.
    pub ply: usize,
    /// The window: name, centre and size on the blank.
    pub zone: crate::post::forming::Zone,
}

/// Contact with friction between two plies (`[[ply_contact]]`, explicit
/// path only).
#[derive(Debug, Clone, PartialEq)]
pub struct PlyContactSpec {
    /// The two plies (indices into [`FormingCase::plies`]).
    pub plies: [usize; 2],
    /// Coulomb coefficient.
    pub friction: f64,
    /// Skin of the candidate lists \[mm\].
    pub skin: f64,
}

/// The default skin of the ply–ply candidate lists \[mm\]: the lists are
/// rebuilt after a node moves half of it (`docs/contact.md`).
pub const DEFAULT_PLY_CONTACT_SKIN: f64 = 1.0;

/// The default size of a zone: the paper's 20 × 20 mm windows \[mm\].
pub const DEFAULT_ZONE_SIZE: [f64; 2] = [20.0, 20.0];

/// How the maps of a forming run look at the plies.
pub use crate::post::contour::MapView;

/// Gravity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GravitySpec {
    /// Acceleration vector [mm/s²].
    pub acceleration: Vector3<f64>,
    /// Amplitude.
    pub amplitude: LoadAmplitude,
}

/// Contact settings shared by every tool.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ContactSettings {
    /// Distance of the contact surface from the ply's mid-surface \[mm\];
    /// `None`: half of each ply's thickness.
    pub offset: Option<f64>,
    /// Normal penalty of the augmented Lagrangian [N/mm] (the tangential one
    /// is `tangential_penalty_scale` times it);
    /// `None`: automatic (`docs/contact.md`).
    pub penalty: Option<f64>,
    /// Factor on the automatic penalty.
    pub penalty_scale: f64,
    /// Ratio `ε_T/ε_N` of the tangential (stick) to the normal penalty.
    pub tangential_penalty_scale: f64,
    /// The rounding of the augmented Lagrangian's kinks (quasi-static
    /// path; docs/contact.md, "Smoothed kinks"): `normal_smoothing` \[mm\]
    /// and `friction_smoothing` (a fraction), both 0 by default.
    pub smoothing: Smoothing,
    /// Largest accepted penetration \[mm\]; `None`: 1 % of the offset.
    pub gap_tolerance: Option<f64>,
    /// Largest accepted relative change of the multipliers per
    /// augmentation.
    pub multiplier_tolerance: f64,
    /// Explicit penalty as a fraction of the central-difference limit
    /// `4m/Δt²` of each node (used unless `explicit_pressure_stiffness`
    /// is given).
    pub explicit_stiffness: f64,
    /// Explicit penalty per unit area \[N/mm³\], instead of the fraction.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub explicit_pressure_stiffness: Option<f64>,
    /// Explicit normal contact damping, a fraction of the critical damping
    /// of each node's penalty spring.
    pub explicit_damping: f64,
}

impl ContactSettings {
    /// How the explicit path chooses each node's penalty.
    pub fn explicit_penalty(&self) -> ExplicitPenalty {
        match self.explicit_pressure_stiffness {
            Some(k_p) => ExplicitPenalty::PerArea(k_p),
            None => ExplicitPenalty::StableFraction(self.explicit_stiffness),
        }
    }
}

impl Default for ContactSettings {
    fn default() -> Self {
        Self {
            offset: None,
            penalty: None,
            penalty_scale: 1.0,
            tangential_penalty_scale: 1.0,
            smoothing: Smoothing::default(),
            gap_tolerance: None,
            multiplier_tolerance: 1e-3,
            explicit_stiffness: 0.1,
            explicit_pressure_stiffness: None,
            explicit_damping: 0.2,
        }
    }
}

/// A validated forming case.
#[derive(Debug, Clone)]
pub struct FormingCase {
    /// Title.
    pub title: String,
    /// The case file (or the name given).
    pub source: String,
    /// The plies.
    pub plies: Vec<PlySpec>,
    /// The tools.
    pub tools: Vec<ToolSpec>,
    /// Boundary conditions.
    pub boundaries: Vec<BoundarySpec>,
    /// Dead loads.
    pub loads: Vec<LoadSpec>,
    /// Node sets whose mean displacement the history records.
    pub probes: Vec<ProbeSpec>,
    /// Evaluation zones.
    pub zones: Vec<ZoneSpec>,
    /// Ply–ply contacts.
    pub ply_contacts: Vec<PlyContactSpec>,
    /// How the PNG maps look at the plies (`output.camera`).
    pub camera: MapView,
    /// Gravity, if on.
    pub gravity: Option<GravitySpec>,
    /// Contact settings.
    pub contact: ContactSettings,
    /// Which solver.
    pub solver_kind: SolverKind,
    /// Newton knobs.
    pub solver: NewtonParameters,
    /// Explicit settings.
    pub explicit: ExplicitSettings,
    /// Programme fractions with VTU output (the last is 1).
    pub states: Vec<f64>,
    /// History rows of an explicit run.
    pub history_rows: usize,
    /// Largest prescribed displacement \[mm\] (the stroke), if anything moves.
    pub stroke: Option<f64>,
}

/// `true` when a case text describes a forming set-up (it has plies).
pub fn is_forming(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| t.contains_key("ply"))
}

/// A 3-vector key.
/// A list of numbers as the case file writes it, `[a, b, c]` (messages).
fn shown_list(values: &[f64]) -> String {
    format!(
        "[{}]",
        values
            .iter()
            .map(|&x| crate::config::readable_number(x))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

fn vector3(
    check: &TomlChecker,
    v: &Spanned<Vec<f64>>,
    key: &str,
    unit: bool,
) -> Result<Vector3<f64>, ConfigError> {
    let values = v.get_ref();
    let shown = shown_list(values);
    if values.len() != 3 || values.iter().any(|x| !x.is_finite()) {
        return Err(check.invalid(
            check.line_of(v),
            key,
            shown,
            "three finite numbers [x, y, z]",
        ));
    }
    let x = Vector3::new(values[0], values[1], values[2]);
    if !x.norm().is_finite() {
        return Err(check.invalid(
            check.line_of(v),
            key,
            shown,
            "three numbers [x, y, z] whose length is finite",
        ));
    }
    if unit {
        let n = x.norm();
        if n.is_nan() || n <= 1e-12 {
            return Err(check.invalid(check.line_of(v), key, shown, "a non-zero direction"));
        }
        return Ok(x / n);
    }
    Ok(x)
}

fn amplitude(
    check: &TomlChecker,
    v: &Option<Spanned<String>>,
    key: &str,
    default: LoadAmplitude,
) -> Result<LoadAmplitude, ConfigError> {
    match v {
        None => Ok(default),
        Some(a) => check.choice(
            a,
            key,
            &[
                ("constant", LoadAmplitude::Constant),
                ("ramp", LoadAmplitude::Ramp),
            ],
        ),
    }
}

impl FormingCase {
    /// Parses and validates a forming case; relative paths are resolved
    /// against `base_dir`.
    ///
    /// # Errors
    /// Unknown or missing keys, values out of range, unknown ply names or
    /// node-set references — each naming the file, line, key and value.
    pub fn from_toml_str(text: &str, source: &str, base_dir: &Path) -> Result<Self, ConfigError> {
        let raw: FormingRaw = parse_toml(text, source)?;
        let check = TomlChecker { text, source };
        let positive =
            |v: &Spanned<f64>, key: &str, what: &str| check.range(v, key, |x| x > 0.0, what);

        if raw.ply.is_empty() {
            return Err(check.missing("[[ply]]", "at least one ply"));
        }
        let mut plies = Vec::new();
        for (i, p) in raw.ply.iter().enumerate() {
            let key = |k: &str| format!("ply[{i}].{k}");
            let name = p.name.clone().unwrap_or_else(|| {
                if raw.ply.len() == 1 {
                    "ply".to_string()
                } else {
                    format!("ply{}", i + 1)
                }
            });
            if plies.iter().any(|q: &PlySpec| q.name == name) {
                return Err(check.invalid(
                    0,
                    &key("name"),
                    format!("\"{name}\""),
                    "a name no other ply has",
                ));
            }
            let (material, named_set) = match &p.params {
                None => (MaterialSpec::default_set(), true),
                Some(name) if MaterialSpec::named_text(name).is_some() => {
                    (MaterialSpec::load(name)?, true)
                }
                Some(file) => (
                    MaterialSpec::load(&base_dir.join(file).display().to_string()).map_err(
                        |e| match e {
                            ConfigError::NotFound { requested, reason } => ConfigError::NotFound {
                                requested: format!(
                                    "{source}: {} = \"{file}\" ({requested})",
                                    key("params")
                                ),
                                reason,
                            },
                            other => other,
                        },
                    )?,
                    false,
                ),
            };
            let thickness = match &p.thickness {
                None => super::oat::DEFAULT_THICKNESS,
                Some(t) => positive(t, &key("thickness"), "a thickness > 0 mm")?,
            };
            let density = match &p.areal_mass {
                Some(a) => Some(
                    positive(a, &key("areal_mass"), "an areal mass > 0 kg/m²")?
                        * KG_PER_M2_IN_T_PER_MM2
                        / thickness,
                ),
                None if named_set => Some(DEFAULT_AREAL_MASS * KG_PER_M2_IN_T_PER_MM2 / thickness),
                None => None,
            };
            if let (Some(rho), Some(t)) = (density, &p.thickness)
                && !rho.is_finite()
            {
                return Err(check.invalid(
                    check.line_of(t),
                    &key("thickness"),
                    crate::config::readable_number(thickness),
                    "a thickness for which the density (areal mass / thickness) is finite",
                ));
            }
            let fibre_angle_deg = match &p.fibre_angle_deg {
                None => 0.0,
                Some(a) => check.range(
                    a,
                    &key("fibre_angle_deg"),
                    |x| (-360.0..=360.0).contains(&x),
                    "an angle in [-360, 360] degrees",
                )?,
            };
            let bending = match &p.bending {
                None => Some(PAPER_BENDING),
                Some(b) => match b {
                    BendingRaw::Switch(false) => None,
                    BendingRaw::Switch(true) => Some(PAPER_BENDING),
                    BendingRaw::Table(t) => {
                        let value = |v: &Option<f64>, k: &str, default: f64| match v {
                            None => Ok(default),
                            Some(x) if x.is_finite() && *x >= 0.0 => Ok(*x),
                            Some(x) => Err(check.invalid(
                                0,
                                &key(&format!("bending.{k}")),
                                crate::config::readable_number(*x),
                                "a bending stiffness ≥ 0 N·mm",
                            )),
                        };
                        Some([
                            value(&t.b11, "b11", PAPER_BENDING[0])?,
                            value(&t.b22, "b22", PAPER_BENDING[1])?,
                            value(&t.b66, "b66", PAPER_BENDING[2])?,
                        ])
                    }
                },
            };
            let mesh = ply_mesh(&check, &p.mesh, i, base_dir)?;
            plies.push(PlySpec {
                name,
                mesh,
                material,
                thickness,
                density,
                fibre_angle_deg,
                bending,
            });
        }
        let ply_index = |name: &Option<String>, key: &str| -> Result<usize, ConfigError> {
            match name {
                None if plies.len() == 1 => Ok(0),
                None => Err(check.missing(key, "the ply's name (the case has several plies)")),
                Some(n) => plies.iter().position(|p| &p.name == n).ok_or_else(|| {
                    check.invalid(
                        0,
                        key,
                        format!("\"{n}\""),
                        &format!(
                            "one of the plies: {}",
                            plies
                                .iter()
                                .map(|p| format!("\"{}\"", p.name))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    )
                }),
            }
        };

        let mut ply_contacts: Vec<PlyContactSpec> = Vec::new();
        for (i, c) in raw.ply_contact.iter().enumerate() {
            let key = |k: &str| format!("ply_contact[{i}].{k}");
            let names = c.plies.get_ref();
            let line = check.line_of(&c.plies);
            let shown = format!(
                "[{}]",
                names
                    .iter()
                    .map(|n| format!("\"{n}\""))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            if names.len() != 2 || names[0] == names[1] {
                return Err(check.invalid(
                    line,
                    &key("plies"),
                    shown,
                    "the names of two different plies",
                ));
            }
            let a = ply_index(&Some(names[0].clone()), &key("plies"))?;
            let b = ply_index(&Some(names[1].clone()), &key("plies"))?;
            let pair = [a.min(b), a.max(b)];
            if ply_contacts.iter().any(|p| p.plies == pair) {
                return Err(check.invalid(
                    line,
                    &key("plies"),
                    shown,
                    "a pair of plies no other [[ply_contact]] names",
                ));
            }
            let friction = check.range(
                &c.friction,
                &key("friction"),
                |x| x >= 0.0,
                "a Coulomb coefficient ≥ 0",
            )?;
            let skin = match &c.skin {
                None => DEFAULT_PLY_CONTACT_SKIN,
                Some(v) => check.range(
                    v,
                    &key("skin"),
                    |x| x > 0.0 && x <= 1.0e3,
                    "a distance in (0, 1000] mm",
                )?,
            };
            ply_contacts.push(PlyContactSpec {
                plies: [a, b],
                friction,
                skin,
            });
        }

        let gravity = match &raw.gravity {
            None => None,
            Some(g) => {
                let magnitude = match &g.g {
                    None => STANDARD_GRAVITY,
                    Some(v) => check.range(
                        v,
                        "gravity.g",
                        |x| x >= 0.0,
                        "an acceleration ≥ 0 mm/s² (9810 on Earth)",
                    )?,
                };
                let direction = match &g.direction {
                    None => -Vector3::z(),
                    Some(d) => vector3(&check, d, "gravity.direction", true)?,
                };
                Some(GravitySpec {
                    acceleration: magnitude * direction,
                    amplitude: amplitude(
                        &check,
                        &g.amplitude,
                        "gravity.amplitude",
                        LoadAmplitude::Constant,
                    )?,
                })
            }
        };
        if gravity.is_some()
            && let Some(p) = plies.iter().find(|p| p.density.is_none())
        {
            return Err(check.missing(
                &format!("ply \"{}\": areal_mass", p.name),
                "the ply's areal mass [kg/m²] for gravity (a parameter file has none)",
            ));
        }

        let mut tools = Vec::new();
        for (i, t) in raw.tool.iter().enumerate() {
            let tool = tool_spec(&check, t, i, base_dir, gravity.as_ref())?;
            if tools.iter().any(|q: &ToolSpec| q.name == tool.name) {
                return Err(check.invalid(
                    0,
                    &format!("tool[{i}].name"),
                    format!("\"{}\"", tool.name),
                    "a name no other tool has",
                ));
            }
            tools.push(tool);
        }
        resolve_openings(&check, &raw.tool, &mut tools)?;

        let mut boundaries = Vec::new();
        for (i, b) in raw.boundary.iter().enumerate() {
            let key = |k: &str| format!("boundary[{i}].{k}");
            let ply = ply_index(&b.ply, &key("ply"))?;
            let mut fixed = [false; 3];
            if let Some(list) = &b.fix {
                for c in list.get_ref() {
                    let k = match c.as_str() {
                        "x" => 0,
                        "y" => 1,
                        "z" => 2,
                        other => {
                            return Err(check.invalid(
                                check.line_of(list),
                                &key("fix"),
                                format!("\"{other}\""),
                                "components among \"x\", \"y\", \"z\"",
                            ));
                        }
                    };
                    fixed[k] = true;
                }
            }
            let displacement = match &b.displacement {
                None => [0.0; 3],
                Some(d) => {
                    let v = vector3(&check, d, &key("displacement"), false)?;
                    for k in 0..3 {
                        if v[k] != 0.0 {
                            fixed[k] = true;
                        }
                    }
                    [v.x, v.y, v.z]
                }
            };
            let clamp_rotation = match &b.rotation {
                None => false,
                Some(r) => {
                    check.choice(r, &key("rotation"), &[("clamped", true), ("free", false)])?
                }
            };
            if !fixed.iter().any(|f| *f) && !clamp_rotation {
                return Err(check.invalid(
                    check.line_of(&b.nodes),
                    &key("fix"),
                    "(none)".into(),
                    "at least one fixed component or rotation = \"clamped\"",
                ));
            }
            boundaries.push(BoundarySpec {
                ply,
                nodes: b.nodes.get_ref().clone(),
                fixed,
                displacement,
                clamp_rotation,
                line: check.line_of(&b.nodes),
            });
        }

        let mut loads = Vec::new();
        for (i, l) in raw.load.iter().enumerate() {
            let key = |k: &str| format!("load[{i}].{k}");
            loads.push(LoadSpec {
                ply: ply_index(&l.ply, &key("ply"))?,
                nodes: l.nodes.get_ref().clone(),
                force: vector3(&check, &l.force, &key("force"), false)?,
                amplitude: amplitude(&check, &l.amplitude, &key("amplitude"), LoadAmplitude::Ramp)?,
                line: check.line_of(&l.nodes),
            });
        }

        let mut probes = Vec::new();
        for (i, p) in raw.probe.iter().enumerate() {
            probes.push(ProbeSpec {
                ply: ply_index(&p.ply, &format!("probe[{i}].ply"))?,
                nodes: p.nodes.get_ref().clone(),
                line: check.line_of(&p.nodes),
            });
        }

        let mut zones: Vec<ZoneSpec> = Vec::new();
        for (i, z) in raw.zone.iter().enumerate() {
            let key = |k: &str| format!("zone[{i}].{k}");
            let pair = |v: &Spanned<Vec<f64>>, k: &str, positive: bool| {
                let values = v.get_ref();
                let ok = values.len() == 2
                    && values
                        .iter()
                        .all(|x| x.is_finite() && (!positive || *x > 0.0));
                if ok {
                    Ok([values[0], values[1]])
                } else {
                    Err(check.invalid(
                        check.line_of(v),
                        &key(k),
                        shown_list(values),
                        if positive {
                            "two sizes > 0 mm [x, y]"
                        } else {
                            "two finite coordinates [x, y] in mm"
                        },
                    ))
                }
            };
            let name = z
                .name
                .clone()
                .unwrap_or_else(|| char::from(b'A' + (i % 26) as u8).to_string());
            if zones.iter().any(|q| q.zone.name == name) {
                return Err(check.invalid(
                    check.line_of(&z.centre),
                    &key("name"),
                    format!("\"{name}\""),
                    "a name no other zone has",
                ));
            }
            zones.push(ZoneSpec {
                ply: ply_index(&z.ply, &key("ply"))?,
                zone: crate::post::forming::Zone {
                    name,
                    centre: pair(&z.centre, "centre", false)?,
                    size: match &z.size {
                        None => DEFAULT_ZONE_SIZE,
                        Some(v) => pair(v, "size", true)?,
                    },
                },
            });
        }

        let mut contact = ContactSettings::default();
        if let Some(c) = &raw.contact {
            if let Some(v) = &c.offset {
                contact.offset =
                    Some(check.range(v, "contact.offset", |x| x >= 0.0, "a distance ≥ 0 mm")?);
            }
            if let Some(v) = &c.penalty {
                contact.penalty = Some(positive(v, "contact.penalty", "a stiffness > 0 N/mm")?);
            }
            if let Some(v) = &c.penalty_scale {
                contact.penalty_scale = positive(v, "contact.penalty_scale", "a factor > 0")?;
            }
            if let Some(v) = &c.tangential_penalty_scale {
                contact.tangential_penalty_scale = positive(
                    v,
                    "contact.tangential_penalty_scale",
                    "a ratio > 0 of the tangential to the normal penalty",
                )?;
            }
            if let Some(v) = &c.normal_smoothing {
                contact.smoothing.gap_width = check.range(
                    v,
                    "contact.normal_smoothing",
                    |x| x >= 0.0,
                    "a gap width ≥ 0 mm",
                )?;
            }
            if let Some(v) = &c.friction_smoothing {
                contact.smoothing.friction_width = check.range(
                    v,
                    "contact.friction_smoothing",
                    |x| (0.0..1.0).contains(&x),
                    "a fraction in [0, 1) of the friction limit",
                )?;
            }
            if let Some(v) = &c.gap_tolerance {
                contact.gap_tolerance =
                    Some(positive(v, "contact.gap_tolerance", "a distance > 0 mm")?);
            }
            if let Some(v) = &c.multiplier_tolerance {
                contact.multiplier_tolerance =
                    positive(v, "contact.multiplier_tolerance", "a fraction > 0")?;
            }
            if let Some(v) = &c.explicit_damping {
                contact.explicit_damping = check.range(
                    v,
                    "contact.explicit_damping",
                    |x| (0.0..=1.0).contains(&x),
                    "a fraction in [0, 1] of the critical damping",
                )?;
            }
            match (&c.explicit_stiffness, &c.explicit_pressure_stiffness) {
                (Some(_), Some(k)) => {
                    return Err(check.invalid(
                        check.line_of(k),
                        "contact.explicit_pressure_stiffness",
                        crate::config::readable_number(*k.get_ref()),
                        "either contact.explicit_stiffness (a fraction of the stability limit) or contact.explicit_pressure_stiffness (per unit area), not both",
                    ));
                }
                (Some(v), None) => {
                    contact.explicit_stiffness = check.range(
                        v,
                        "contact.explicit_stiffness",
                        |x| x > 0.0 && x <= 1.0,
                        "a fraction in (0, 1] of the stability limit",
                    )?;
                }
                (None, Some(k)) => {
                    contact.explicit_pressure_stiffness = Some(check.range(
                        k,
                        "contact.explicit_pressure_stiffness",
                        |x| x > 0.0 && x <= 1.0e12,
                        "a stiffness per unit area in (0, 1e12] N/mm³ (MPa per mm of penetration)",
                    )?);
                }
                (None, None) => {}
            }
        }

        let stroke = tools
            .iter()
            .filter_map(|t| match t.motion {
                ToolMotion::Prescribed { displacement, .. } => Some(displacement.abs()),
                _ => None,
            })
            .chain(
                boundaries
                    .iter()
                    .map(|b| Vector3::from(b.displacement).norm()),
            )
            .filter(|d| *d > 0.0)
            .reduce(f64::max);

        let (solver_kind, solver) = super::oat::solver_choice(raw.solver, &check)?;
        super::oat::validate_solver(&solver, source)?;
        if stroke.is_none()
            && solver_kind == SolverKind::Explicit
            && raw.explicit.as_ref().is_none_or(|e| e.duration.is_none())
        {
            return Err(check.missing(
                "explicit.duration",
                "the duration of the run [s] (no tool or boundary moves, so no speed sets it)",
            ));
        }
        let explicit =
            ExplicitSettings::from_raw(raw.explicit.as_ref(), &check, stroke.unwrap_or(1.0))?;
        if solver_kind == SolverKind::QuasiStatic
            && let Some(c) = raw.ply_contact.first()
        {
            return Err(check.invalid(
                check.line_of(&c.plies),
                "ply_contact",
                "[[ply_contact]]".to_string(),
                "a case for the explicit solver: the quasi-static path does not take ply–ply contact (set solver = \"explicit\")",
            ));
        }
        if solver_kind == SolverKind::Explicit
            && let Some(p) = plies.iter().find(|p| p.density.is_none())
        {
            return Err(check.missing(
                &format!("ply \"{}\": areal_mass", p.name),
                "the ply's areal mass [kg/m²] for the explicit solver (a parameter file has none)",
            ));
        }
        let camera = match raw.output.as_ref().and_then(|o| o.camera.as_ref()) {
            None => MapView::Below,
            Some(c) => check.choice(
                c,
                "output.camera",
                &[("below", MapView::Below), ("above", MapView::Above)],
            )?,
        };
        let (states, history_rows) = match &raw.output {
            None => (DEFAULT_STATES, DEFAULT_HISTORY_ROWS),
            Some(o) => (
                match &o.states {
                    None => DEFAULT_STATES,
                    Some(n) => check.count(n, "output.states", 1..=10_000)?,
                },
                match &o.history {
                    None => DEFAULT_HISTORY_ROWS,
                    Some(n) => check.count(n, "output.history", 1..=1_000_000)?,
                },
            ),
        };
        Ok(Self {
            title: match &raw.title {
                None => "forming".to_string(),
                Some(t) => check.one_line(t, "title")?,
            },
            source: source.to_string(),
            plies,
            tools,
            boundaries,
            loads,
            probes,
            zones,
            ply_contacts,
            camera,
            gravity,
            contact,
            solver_kind,
            solver,
            explicit,
            states: (1..=states).map(|k| k as f64 / states as f64).collect(),
            history_rows,
            stroke,
        })
    }

    /// Reads and validates a forming case file.
    ///
    /// # Errors
    /// As [`FormingCase::from_toml_str`], or an unreadable file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let (text, source, base) = crate::config::read_case_file(path)?;
        Self::from_toml_str(&text, &source, &base)
    }
}

/// The paper's bending stiffnesses `(B11, B22)` [N·mm] (Section 3) and the
/// default twist stiffness `B66 = B22` (not in the paper; `docs/theory.md`).
pub const PAPER_BENDING: [f64; 3] = [4.06, 0.018, 0.018];

fn ply_mesh(
    check: &TomlChecker,
    m: &PlyMeshRaw,
    i: usize,
    base_dir: &Path,
) -> Result<PlyMesh, ConfigError> {
    let key = |k: &str| format!("ply[{i}].mesh.{k}");
    let positive = |v: &Option<Spanned<f64>>, k: &str, what: &str| match v {
        None => Err(check.missing(&key(k), what)),
        Some(v) => check.range(v, &key(k), |x| x > 0.0, what),
    };
    let centre = match &m.centre {
        None => Vector3::zeros(),
        Some(c) => vector3(check, c, &key("centre"), false)?,
    };
    if let Some(file) = &m.file {
        if m.shape.is_some() {
            return Err(check.invalid(
                check.line_of(file),
                &key("shape"),
                "(given)".into(),
                "no shape with a mesh file",
            ));
        }
        return Ok(PlyMesh::File {
            path: base_dir.join(file.get_ref()),
        });
    }
    let Some(shape) = &m.shape else {
        return Err(check.missing(
            &key("shape"),
            "\"rectangle\", \"disk\" or \"wrapped-strip\" (or a mesh file)",
        ));
    };
    #[derive(Clone, Copy)]
    enum Kind {
        Rectangle,
        Disk,
        Strip,
    }
    let kind = check.choice(
        shape,
        &key("shape"),
        &[
            ("rectangle", Kind::Rectangle),
            ("disk", Kind::Disk),
            ("wrapped-strip", Kind::Strip),
        ],
    )?;
    Ok(match kind {
        Kind::Rectangle => {
            let size = match &m.size {
                None => return Err(check.missing(&key("size"), "the blank's extents [x, y] in mm")),
                Some(s) => {
                    let v = s.get_ref();
                    if v.len() != 2 || v.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
                        return Err(check.invalid(
                            check.line_of(s),
                            &key("size"),
                            shown_list(v),
                            "two lengths > 0 mm [x, y]",
                        ));
                    }
                    [v[0], v[1]]
                }
            };
            let resolution = match (&m.element_size, &m.cells) {
                (Some(h), None) => crate::mesh::generate::GridResolution::ElementSize(
                    check.range(h, &key("element_size"), |x| x > 0.0, "a length > 0 mm")?,
                ),
                (None, Some(c)) => {
                    let v = c.get_ref();
                    if v.len() != 2 || v.iter().any(|n| !(1..=100_000).contains(n)) {
                        return Err(check.invalid(
                            check.line_of(c),
                            &key("cells"),
                            format!("{v:?}"),
                            "two counts in 1..=100000 [nx, ny]",
                        ));
                    }
                    crate::mesh::generate::GridResolution::Counts {
                        nx: v[0] as usize,
                        ny: v[1] as usize,
                    }
                }
                _ => {
                    return Err(check.missing(
                        &key("element_size"),
                        "exactly one of element_size and cells",
                    ));
                }
            };
            let pattern = match &m.pattern {
                None => crate::mesh::generate::GridPattern::RovingDiagonal,
                Some(p) => check.choice(
                    p,
                    &key("pattern"),
                    &[
                        (
                            "roving-diagonal",
                            crate::mesh::generate::GridPattern::RovingDiagonal,
                        ),
                        (
                            "both-diagonals",
                            crate::mesh::generate::GridPattern::BothDiagonals,
                        ),
                        ("mirrored", crate::mesh::generate::GridPattern::Mirrored),
                    ],
                )?,
            };
            PlyMesh::Rectangle {
                size,
                centre,
                resolution,
                pattern,
            }
        }
        Kind::Disk => PlyMesh::Disk {
            radius: positive(&m.radius, "radius", "a radius > 0 mm")?,
            centre,
            element_size: positive(&m.element_size, "element_size", "a length > 0 mm")?,
        },
        Kind::Strip => PlyMesh::WrappedStrip {
            radius: positive(
                &m.radius,
                "radius",
                "the radius of the strip's mid-surface > 0 mm",
            )?,
            wrap_angle_deg: match &m.wrap_angle_deg {
                None => {
                    return Err(
                        check.missing(&key("wrap_angle_deg"), "the wrap angle in (0, 360) degrees")
                    );
                }
                Some(a) => check.range(
                    a,
                    &key("wrap_angle_deg"),
                    |x| x > 0.0 && x < 360.0,
                    "an angle in (0, 360) degrees",
                )?,
            },
            tail_length: match &m.tail_length {
                None => 0.0,
                Some(t) => check.range(t, &key("tail_length"), |x| x >= 0.0, "a length ≥ 0 mm")?,
            },
            width: positive(&m.width, "width", "a width > 0 mm")?,
            element_size: positive(&m.element_size, "element_size", "a length > 0 mm")?,
            centre,
        },
    })
}

/// A pyramid tool's shape and its placement (the local frame of
/// `Placement::new(origin, axis, None)`, in which the base edge's azimuth
/// is measured), as the model builds it.
///
/// # Errors
/// The shape's or the placement's [`ShapeError`](crate::contact::ShapeError).
pub(crate) fn pyramid_of(
    spec: &ToolSpec,
) -> Result<Option<(crate::contact::Pyramid, crate::contact::Placement)>, crate::contact::ShapeError>
{
    let ToolShape::Pyramid {
        sides,
        face_angle,
        rounding_radius,
        height,
        edge_direction,
    } = &spec.shape
    else {
        return Ok(None);
    };
    let placement = crate::contact::Placement::new(spec.origin, spec.axis, None)?;
    let local = placement.vector_to_local(edge_direction);
    let pyramid = crate::contact::Pyramid::new(
        *sides,
        *face_angle,
        *rounding_radius,
        *height,
        local.y.atan2(local.x),
    )?;
    Ok(Some((pyramid, placement)))
}

/// Computes the opening of every `plate-with-polygon-hole` from its punch
/// (the named pyramid tool at its full stroke, `docs/cases.md`).
fn resolve_openings(
    check: &TomlChecker,
    raw: &[ToolRaw],
    tools: &mut [ToolSpec],
) -> Result<(), ConfigError> {
    for i in 0..tools.len() {
        let ToolShape::PlateWithPolygonHole {
            punch,
            clearance,
            section_at,
            ..
        } = &tools[i].shape
        else {
            continue;
        };
        let line = raw[i].punch.as_ref().map_or(0, |p| check.line_of(p));
        let key = format!("tool[{i}].punch");
        let shown = format!("\"{punch}\"");
        let Some(punch_spec) = tools.iter().find(|t| &t.name == punch) else {
            let names: Vec<String> = tools
                .iter()
                .filter(|t| matches!(t.shape, ToolShape::Pyramid { .. }))
                .map(|t| format!("\"{}\"", t.name))
                .collect();
            return Err(check.invalid(
                line,
                &key,
                shown,
                &format!(
                    "the name of a pyramid tool (here: {})",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            ));
        };
        let invalid = |why: String| check.invalid(line, &key, shown.clone(), &why);
        let (pyramid, placement) = match pyramid_of(punch_spec) {
            Ok(Some(p)) => p,
            Ok(None) => {
                return Err(invalid(format!(
                    "the name of a pyramid tool (\"{punch}\" is not a pyramid)"
                )));
            }
            Err(e) => return Err(invalid(format!("a valid pyramid ({e})"))),
        };
        let stroke = match punch_spec.motion {
            ToolMotion::Prescribed {
                direction,
                displacement,
            } => direction * displacement,
            _ => Vector3::zeros(),
        };
        let plate = &tools[i];
        let frame = crate::contact::Placement::new(plate.origin, plate.axis, None)
            .map_err(|e| invalid(format!("a valid plate placement ({e})")))?;
        let at = section_at.unwrap_or(plate.origin);
        let (polygon, corner) =
            crate::contact::punch_opening(&pyramid, &placement, &stroke, &frame, &at, *clearance)
                .map_err(|e| {
                invalid(format!(
                    "a pyramid whose section by the plate's plane at full stroke \
                         gives the opening ({e})"
                ))
            })?;
        let polygon: Vec<[f64; 2]> = polygon.iter().map(|p| [p.x, p.y]).collect();
        if let ToolShape::PlateWithPolygonHole {
            polygon: p,
            corner_radius,
            ..
        } = &mut tools[i].shape
        {
            *p = polygon;
            *corner_radius = corner;
        }
    }
    Ok(())
}

fn tool_spec(
    check: &TomlChecker,
    t: &ToolRaw,
    i: usize,
    base_dir: &Path,
    gravity: Option<&GravitySpec>,
) -> Result<ToolSpec, ConfigError> {
    let key = |k: &str| format!("tool[{i}].{k}");
    let name = t.name.clone().unwrap_or_else(|| format!("tool{}", i + 1));
    let positive = |v: &Option<Spanned<f64>>, k: &str, what: &str| match v {
        None => Err(check.missing(&key(k), what)),
        Some(v) => check.range(v, &key(k), |x| x > 0.0, what),
    };
    #[derive(Clone, Copy)]
    enum Kind {
        Plane,
        Sphere,
        Cylinder,
        Torus,
        Plate,
        Pyramid,
        PolygonPlate,
        Mesh,
    }
    let kind = check.choice(
        &t.shape,
        &key("shape"),
        &[
            ("plane", Kind::Plane),
            ("sphere", Kind::Sphere),
            ("cylinder", Kind::Cylinder),
            ("torus", Kind::Torus),
            ("plate-with-hole", Kind::Plate),
            ("pyramid", Kind::Pyramid),
            ("plate-with-polygon-hole", Kind::PolygonPlate),
            ("mesh", Kind::Mesh),
        ],
    )?;
    let shape = match kind {
        Kind::Plane => ToolShape::Plane,
        Kind::Sphere => ToolShape::Sphere {
            radius: positive(&t.radius, "radius", "a radius > 0 mm")?,
        },
        Kind::Cylinder => ToolShape::Cylinder {
            radius: positive(&t.radius, "radius", "a radius > 0 mm")?,
        },
        Kind::Torus => ToolShape::Torus {
            major_radius: positive(&t.major_radius, "major_radius", "a radius > 0 mm")?,
            minor_radius: positive(&t.minor_radius, "minor_radius", "a radius > 0 mm")?,
        },
        Kind::Plate => ToolShape::PlateWithHole {
            opening_radius: positive(&t.opening_radius, "opening_radius", "a radius > 0 mm")?,
            fillet_radius: positive(&t.fillet_radius, "fillet_radius", "a radius > 0 mm")?,
        },
        Kind::Pyramid => {
            let sides = match &t.sides {
                None => 3,
                Some(n) => check.count(n, &key("sides"), 3..=64)?,
            };
            let face_angle = match &t.face_angle_deg {
                // The regular tetrahedron: cos α = 1/3 (α ≈ 70.53°).
                None => (1.0_f64 / 3.0).acos(),
                Some(a) => check
                    .range(
                        a,
                        &key("face_angle_deg"),
                        |x| x > 0.0 && x < 90.0,
                        "an angle in (0, 90) degrees between the faces and the base plane",
                    )?
                    .to_radians(),
            };
            let axis = match &t.axis {
                None => Vector3::z(),
                Some(a) => vector3(check, a, &key("axis"), true)?,
            };
            let edge_direction = match &t.edge_direction {
                None => Vector3::x(),
                Some(e) => vector3(check, e, &key("edge_direction"), true)?,
            };
            let projected = edge_direction - axis * edge_direction.dot(&axis);
            if projected.norm() <= 1e-6 {
                let line = t.edge_direction.as_ref().map_or(0, |e| check.line_of(e));
                return Err(check.invalid(
                    line,
                    &key("edge_direction"),
                    shown_list(edge_direction.as_slice()),
                    &format!(
                        "a direction not parallel to the axis {}",
                        shown_list(axis.as_slice())
                    ),
                ));
            }
            ToolShape::Pyramid {
                sides,
                face_angle,
                rounding_radius: positive(
                    &t.rounding_radius,
                    "rounding_radius",
                    "the radius of the apex and the edges > 0 mm",
                )?,
                height: positive(
                    &t.height,
                    "height",
                    "the pyramid's height from the apex to the base > 0 mm (enough to reach \
                     through the die at full depth)",
                )?,
                edge_direction: projected.normalize(),
            }
        }
        Kind::PolygonPlate => ToolShape::PlateWithPolygonHole {
            punch: match &t.punch {
                None => {
                    return Err(check.missing(
                        &key("punch"),
                        "the name of the pyramid tool whose section the opening follows",
                    ));
                }
                Some(p) => p.get_ref().clone(),
            },
            clearance: match &t.clearance {
                None => {
                    return Err(check.missing(
                        &key("clearance"),
                        "the clearance between the punch and the opening ≥ 0 mm",
                    ));
                }
                Some(c) => check.range(
                    c,
                    &key("clearance"),
                    |x| x >= 0.0,
                    "a clearance ≥ 0 mm between the punch and the opening",
                )?,
            },
            fillet_radius: positive(&t.fillet_radius, "fillet_radius", "a radius > 0 mm")?,
            section_at: match &t.section_at {
                None => None,
                Some(v) => Some(vector3(check, v, &key("section_at"), false)?),
            },
            polygon: Vec::new(),
            corner_radius: 0.0,
        },
        Kind::Mesh => ToolShape::Mesh {
            path: match &t.file {
                None => return Err(check.missing(&key("file"), "an STL or OBJ file")),
                Some(f) => base_dir.join(f.get_ref()),
            },
            scale: match &t.scale {
                None => 1.0,
                Some(s) => check.range(s, &key("scale"), |x| x > 0.0, "a factor > 0 to mm")?,
            },
            closed: t.closed.unwrap_or(true),
        },
    };
    let geometry_keys: [(&str, bool); 15] = [
        ("radius", t.radius.is_some()),
        ("major_radius", t.major_radius.is_some()),
        ("minor_radius", t.minor_radius.is_some()),
        ("opening_radius", t.opening_radius.is_some()),
        ("fillet_radius", t.fillet_radius.is_some()),
        ("sides", t.sides.is_some()),
        ("face_angle_deg", t.face_angle_deg.is_some()),
        ("rounding_radius", t.rounding_radius.is_some()),
        ("height", t.height.is_some()),
        ("edge_direction", t.edge_direction.is_some()),
        ("punch", t.punch.is_some()),
        ("clearance", t.clearance.is_some()),
        ("section_at", t.section_at.is_some()),
        ("file", t.file.is_some()),
        ("scale", t.scale.is_some()),
    ];
    let needed: &[&str] = match kind {
        Kind::Plane => &[],
        Kind::Sphere | Kind::Cylinder => &["radius"],
        Kind::Torus => &["major_radius", "minor_radius"],
        Kind::Plate => &["opening_radius", "fillet_radius"],
        Kind::Pyramid => &[
            "sides",
            "face_angle_deg",
            "rounding_radius",
            "height",
            "edge_direction",
        ],
        Kind::PolygonPlate => &["punch", "clearance", "fillet_radius", "section_at"],
        Kind::Mesh => &["file", "scale"],
    };
    if let Some((extra, _)) = geometry_keys
        .iter()
        .find(|(k, given)| *given && !needed.contains(k))
    {
        return Err(check.invalid(
            check.line_of(&t.shape),
            &key(extra),
            "(given)".into(),
            &format!("no {extra} for shape \"{}\"", t.shape.get_ref()),
        ));
    }
    let inside = match &t.side {
        None => false,
        Some(s) => {
            if !matches!(kind, Kind::Sphere | Kind::Cylinder | Kind::Torus) {
                return Err(check.invalid(
                    check.line_of(s),
                    &key("side"),
                    format!("\"{}\"", s.get_ref()),
                    "no side for this shape (only spheres, cylinders and tori)",
                ));
            }
            check.choice(s, &key("side"), &[("outside", false), ("inside", true)])?
        }
    };
    let origin = match &t.origin {
        None => Vector3::zeros(),
        Some(o) => vector3(check, o, &key("origin"), false)?,
    };
    let axis = match &t.axis {
        None => Vector3::z(),
        Some(a) => vector3(check, a, &key("axis"), true)?,
    };
    let friction = match &t.friction {
        None => 0.0,
        Some(f) => check.range(
            f,
            &key("friction"),
            |x| x >= 0.0,
            "a friction coefficient ≥ 0",
        )?,
    };
    let extent = match &t.extent {
        None => 200.0,
        // Drawn only: a kilometre is far beyond any press, and keeps the
        // drawn points finite.
        Some(e) => check.range(
            e,
            &key("extent"),
            |x| x > 0.0 && x <= 1e6,
            "a half-size in (0, 1e6] mm",
        )?,
    };
    #[derive(Clone, Copy)]
    enum Move {
        Fixed,
        Prescribed,
        Floating,
    }
    let motion_kind = match &t.motion {
        None => Move::Fixed,
        Some(m) => check.choice(
            m,
            &key("motion"),
            &[
                ("fixed", Move::Fixed),
                ("prescribed", Move::Prescribed),
                ("floating", Move::Floating),
            ],
        )?,
    };
    let direction = || match &t.direction {
        None => Err(check.missing(
            &key("direction"),
            "the unit direction [x, y, z] the tool moves along",
        )),
        Some(d) => vector3(check, d, &key("direction"), true),
    };
    let unused = |v: &Option<Spanned<f64>>, k: &str, why: &str| match v {
        Some(v) => Err(check.invalid(
            check.line_of(v),
            &key(k),
            crate::config::readable_number(*v.get_ref()),
            why,
        )),
        None => Ok(()),
    };
    let motion = match motion_kind {
        Move::Fixed => {
            unused(
                &t.displacement,
                "displacement",
                "no displacement for a fixed tool (motion = \"prescribed\")",
            )?;
            unused(
                &t.mass,
                "mass",
                "no mass for a fixed tool (motion = \"floating\")",
            )?;
            unused(
                &t.weight,
                "weight",
                "no weight for a fixed tool (motion = \"floating\")",
            )?;
            ToolMotion::Fixed
        }
        Move::Prescribed => {
            unused(&t.mass, "mass", "no mass for a prescribed tool")?;
            unused(&t.weight, "weight", "no weight for a prescribed tool")?;
            let displacement = match &t.displacement {
                None => {
                    return Err(check.missing(
                        &key("displacement"),
                        "the tool's displacement at the end of the programme [mm]",
                    ));
                }
                Some(d) => check.range(
                    d,
                    &key("displacement"),
                    |_| true,
                    "a finite displacement [mm]",
                )?,
            };
            ToolMotion::Prescribed {
                direction: direction()?,
                displacement,
            }
        }
        Move::Floating => {
            unused(
                &t.displacement,
                "displacement",
                "no displacement for a floating tool (it moves under its weight)",
            )?;
            let direction = direction()?;
            let Some(given_mass) = &t.mass else {
                return Err(check.missing(
                    &key("mass"),
                    "the floating tool's mass [kg] (a floating tool needs a mass and a weight)",
                ));
            };
            let mass =
                check.range(given_mass, &key("mass"), |x| x > 0.0, "a mass > 0 kg")? * KG_IN_T;
            let weight = match &t.weight {
                Some(w) => check.range(
                    w,
                    &key("weight"),
                    |x| x >= 0.0,
                    "a dead force ≥ 0 N along the tool's direction",
                )?,
                None => {
                    let g = gravity.map_or(-STANDARD_GRAVITY * Vector3::z(), |g| g.acceleration);
                    let weight = mass * g.dot(&direction);
                    if !weight.is_finite() {
                        return Err(check.invalid(
                            check.line_of(given_mass),
                            &key("mass"),
                            crate::config::readable_number(*given_mass.get_ref()),
                            "a mass whose weight (mass × gravity) is finite",
                        ));
                    }
                    weight
                }
            };
            ToolMotion::Floating {
                direction,
                mass,
                weight,
            }
        }
    };
    Ok(ToolSpec {
        name,
        shape,
        origin,
        axis,
        inside,
        friction,
        motion,
        extent,
    })
}
