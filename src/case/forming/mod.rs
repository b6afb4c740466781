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
//!
//! The case is read table by table: `ply.rs` (`[[ply]]`), `contact.rs`
//! (`[[ply_contact]]`, `[contact]`), `conditions.rs` (`[gravity]`,
//! `[[boundary]]`, `[[load]]`, `[[probe]]`, `[[zone]]`), `tool.rs`
//! (`[[tool]]`) and `output.rs` (`[output]`); this module checks what
//! spans tables (gravity and the explicit solver need every ply's areal
//! mass, ply–ply contact needs the explicit solver, a run where nothing
//! moves needs a duration) and computes the prescribed travel. `build.rs` turns the
//! validated case into a model.

use std::path::Path;

use nalgebra::Vector3;
use toml::Spanned;

use super::explicit::{
    ExplicitRaw, ExplicitSettings, SolverChoice, SolverKind, solver_choice, validate_solver,
};
use crate::config::{CaseWarning, ConfigError, TomlChecker, parse_toml};
use crate::model::LoadAmplitude;
use crate::solver::NewtonParameters;

pub(crate) mod build;
mod conditions;
mod contact;
mod defects;
mod output;
mod ply;
mod raw;
mod tool;

pub use conditions::{BoundarySpec, DEFAULT_ZONE_SIZE, GravitySpec, LoadSpec, ProbeSpec, ZoneSpec};
pub use contact::{ContactSettings, DEFAULT_PLY_CONTACT_SKIN, PlyContactSpec};
pub use defects::DefectSpec;
pub use ply::{PAPER_BENDING, PlyMesh, PlySpec};
pub(crate) use tool::pyramid_of;
pub use tool::{ToolMotion, ToolShape, ToolSpec};

use raw::{FormingRaw, PlyContactRaw};

/// Standard gravity [mm/s²].
pub const STANDARD_GRAVITY: f64 = 9810.0;
/// `1 kg = 1e-3 t`.
pub const KG_IN_T: f64 = 1.0e-3;
/// Default number of VTU states over the programme (besides `λ = 0`).
pub const DEFAULT_STATES: usize = 10;
/// Default number of history rows of an explicit run.
pub const DEFAULT_HISTORY_ROWS: usize = 100;

/// How the maps of a forming run look at the plies.
pub use crate::post::contour::MapView;

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
    /// Whether the PNG maps of every output state are written (`output.maps`).
    pub maps: bool,
    /// The design rosette the fibre angles are measured in (`[rosette]`).
    pub rosette: crate::post::orientation::Rosette,
    /// The thresholds of the defect indicators (`[defects]`).
    pub defects: DefectSpec,
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
    /// The largest prescribed displacement of a tool or a boundary \[mm\],
    /// if anything moves: what an explicit run's speed is applied to to
    /// give its duration. (The stroke reported on every state is the
    /// stroke tool's displacement: [`FormingModel::stroke`](crate::case::forming_model::FormingModel::stroke).)
    pub prescribed_travel: Option<f64>,
    /// The unusual values of the case and what it reads but does not use
    /// (`docs/cases.md`, "Ranges"), printed by `ncform run` before the
    /// run.
    pub warnings: Vec<CaseWarning>,
}

/// `true` when a case text describes a forming set-up (it has plies).
pub fn is_forming(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| t.contains_key("ply"))
}

/// Names quoted and joined, `"a", "b", "c"` (messages).
fn quoted_names<'a>(names: impl IntoIterator<Item = &'a str>) -> String {
    names
        .into_iter()
        .map(|n| format!("\"{n}\""))
        .collect::<Vec<_>>()
        .join(", ")
}

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

/// A 3-vector key: three finite numbers, each in `bound`'s hard range
/// (a position, a displacement, a force), or a direction when `bound` is
/// `None` (normalised, then not zero).
fn vector3(
    check: &TomlChecker,
    v: &Spanned<Vec<f64>>,
    key: &str,
    bound: Option<&crate::case::bounds::Bound>,
) -> Result<Vector3<f64>, ConfigError> {
    let unit = bound.is_none();
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
    if let Some(b) = bound
        && values.iter().any(|x| !b.hard.contains(*x))
    {
        return Err(check.invalid(
            check.line_of(v),
            key,
            shown,
            &format!("three {}", b.expected()),
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

/// A load amplitude key (`"constant"` or `"ramp"`), `default` when left
/// out.
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
        let check = TomlChecker::new(text, source);
        let plies = ply::plies(&check, &raw.ply, base_dir)?;
        let ply_contacts = contact::ply_contacts(&check, &raw.ply_contact, &plies)?;
        let gravity = conditions::gravity(&check, raw.gravity.as_ref())?;
        if gravity.is_some()
            && let Some(p) = plies.iter().find(|p| p.density.is_none())
        {
            return Err(check.missing(
                &format!("ply \"{}\": areal_mass", p.name),
                "the ply's areal mass [kg/m²] for gravity (a parameter file has none)",
            ));
        }
        let tools = tool::tools(&check, &raw.tool, base_dir, gravity.as_ref(), &plies)?;
        let boundaries = conditions::boundaries(&check, &raw.boundary, &plies)?;
        let loads = conditions::loads(&check, &raw.load, &plies)?;
        let probes = conditions::probes(&check, &raw.probe, &plies)?;
        let zones = conditions::zones(&check, &raw.zone, &plies)?;
        let contact = contact::settings(&check, raw.contact.as_ref())?;
        let travel = prescribed_travel(&tools, &boundaries);
        let (solver_kind, solver, explicit) = solver_settings(
            &check,
            raw.solver,
            raw.explicit.as_ref(),
            &raw.ply_contact,
            &plies,
            travel,
        )?;
        contact::applicable_keys(&check, raw.contact.as_ref(), solver_kind)?;
        let output::Outputs {
            camera,
            maps,
            states,
            history_rows,
        } = output::output(&check, raw.output.as_ref(), solver_kind)?;
        let rosette = defects::rosette(&check, raw.rosette.as_ref())?;
        let defects = defects::defects(&check, raw.defects.as_ref())?;
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
            maps,
            rosette,
            defects,
            gravity,
            contact,
            solver_kind,
            solver,
            explicit,
            states: (1..=states).map(|k| k as f64 / states as f64).collect(),
            history_rows,
            prescribed_travel: travel,
            warnings: check.take_warnings(),
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

/// The largest prescribed displacement of a tool or a boundary \[mm\],
/// `None` when nothing moves.
fn prescribed_travel(tools: &[ToolSpec], boundaries: &[BoundarySpec]) -> Option<f64> {
    tools
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
        .reduce(f64::max)
}

/// The `solver` key and the `[explicit]` table, with the checks that span
/// tables: an explicit run where nothing moves needs a duration,
/// `[[ply_contact]]` needs the explicit solver, and the explicit solver
/// needs every ply's areal mass.
fn solver_settings(
    check: &TomlChecker,
    choice: Option<Spanned<SolverChoice>>,
    explicit_raw: Option<&ExplicitRaw>,
    ply_contact: &[PlyContactRaw],
    plies: &[PlySpec],
    travel: Option<f64>,
) -> Result<(SolverKind, NewtonParameters, ExplicitSettings), ConfigError> {
    let (solver_kind, solver) = solver_choice(choice, check)?;
    validate_solver(&solver, check)?;
    super::explicit::unused_explicit_table(check, solver_kind, explicit_raw);
    if travel.is_none()
        && solver_kind == SolverKind::Explicit
        && explicit_raw.is_none_or(|e| e.duration.is_none())
    {
        return Err(check.missing(
            "explicit.duration",
            "the duration of the run [s] (no tool or boundary moves, so no speed sets it)",
        ));
    }
    let explicit = ExplicitSettings::from_raw(explicit_raw, check, travel.unwrap_or(1.0))?;
    if solver_kind == SolverKind::QuasiStatic
        && let Some(c) = ply_contact.first()
    {
        return Err(check.invalid(
            check.line_of(&c.plies),
            "ply_contact",
            "[[ply_contact]]".to_string(),
            "a case for the explicit solver: the quasi-static path does not take ply–ply contact (set solver = \"explicit\")",
        ));
    }
    if solver_kind == SolverKind::QuasiStatic
        && let Some(p) = plies.iter().find(|p| p.compaction.is_some())
    {
        return Err(check.invalid(
            p.compaction_line,
            &format!("ply \"{}\": compaction", p.name),
            "[ply.compaction]".to_string(),
            "a case for the explicit solver: the quasi-static path's augmented Lagrangian contact has no compliant layer (set solver = \"explicit\" or remove [ply.compaction])",
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
    Ok((solver_kind, solver, explicit))
}
