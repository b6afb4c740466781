//! The forming case file as written: one serde structure per table, every
//! key optional or spanned so that the parse functions can name its line.
//! Unknown keys are refused. Key-by-key documentation: `docs/cases.md`,
//! "Forming cases".

use serde::Deserialize;
use toml::Spanned;

use crate::case::explicit::{ExplicitRaw, SolverChoice};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FormingRaw {
    pub(super) title: Option<Spanned<String>>,
    pub(super) ply: Vec<PlyRaw>,
    #[serde(default)]
    pub(super) tool: Vec<ToolRaw>,
    #[serde(default)]
    pub(super) boundary: Vec<BoundaryRaw>,
    #[serde(default)]
    pub(super) load: Vec<LoadRaw>,
    #[serde(default)]
    pub(super) probe: Vec<ProbeRaw>,
    #[serde(default)]
    pub(super) zone: Vec<ZoneRaw>,
    #[serde(default)]
    pub(super) ply_contact: Vec<PlyContactRaw>,
    pub(super) gravity: Option<GravityRaw>,
    pub(super) contact: Option<ContactRaw>,
    pub(super) output: Option<OutputRaw>,
    pub(super) rosette: Option<RosetteRaw>,
    pub(super) defects: Option<DefectsRaw>,
    pub(super) solver: Option<Spanned<SolverChoice>>,
    pub(super) explicit: Option<ExplicitRaw>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PlyRaw {
    pub(super) name: Option<String>,
    pub(super) params: Option<Spanned<String>>,
    pub(super) thickness: Option<Spanned<f64>>,
    pub(super) areal_mass: Option<Spanned<f64>>,
    pub(super) fibre_angle_deg: Option<Spanned<f64>>,
    pub(super) bending: Option<Spanned<BendingRaw>>,
    pub(super) compaction: Option<Spanned<CompactionRaw>>,
    pub(super) mesh: PlyMeshRaw,
}

/// `[ply.compaction]`: Toll's packing law of the ply's layer.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CompactionRaw {
    pub(super) thickness: Option<f64>,
    pub(super) pressure: Option<f64>,
    pub(super) exponent: Option<f64>,
}

/// `bending = false` or a table of stiffnesses.
#[derive(Deserialize)]
#[serde(untagged)]
pub(super) enum BendingRaw {
    Switch(bool),
    Table(BendingTableRaw),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BendingTableRaw {
    pub(super) b11: Option<f64>,
    pub(super) b22: Option<f64>,
    pub(super) b66: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PlyMeshRaw {
    pub(super) shape: Option<Spanned<String>>,
    pub(super) size: Option<Spanned<Vec<f64>>>,
    pub(super) centre: Option<Spanned<Vec<f64>>>,
    pub(super) element_size: Option<Spanned<f64>>,
    pub(super) cells: Option<Spanned<Vec<i64>>>,
    pub(super) pattern: Option<Spanned<String>>,
    pub(super) radius: Option<Spanned<f64>>,
    pub(super) width: Option<Spanned<f64>>,
    pub(super) wrap_angle_deg: Option<Spanned<f64>>,
    pub(super) tail_length: Option<Spanned<f64>>,
    pub(super) file: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ToolRaw {
    pub(super) name: Option<String>,
    pub(super) shape: Spanned<String>,
    pub(super) origin: Option<Spanned<Vec<f64>>>,
    pub(super) axis: Option<Spanned<Vec<f64>>>,
    pub(super) radius: Option<Spanned<f64>>,
    pub(super) major_radius: Option<Spanned<f64>>,
    pub(super) minor_radius: Option<Spanned<f64>>,
    pub(super) opening_radius: Option<Spanned<f64>>,
    pub(super) fillet_radius: Option<Spanned<f64>>,
    pub(super) sides: Option<Spanned<i64>>,
    pub(super) face_angle_deg: Option<Spanned<f64>>,
    pub(super) rounding_radius: Option<Spanned<f64>>,
    pub(super) height: Option<Spanned<f64>>,
    pub(super) edge_direction: Option<Spanned<Vec<f64>>>,
    pub(super) punch: Option<Spanned<String>>,
    pub(super) clearance: Option<Spanned<f64>>,
    pub(super) section_at: Option<Spanned<Vec<f64>>>,
    pub(super) side: Option<Spanned<String>>,
    pub(super) file: Option<Spanned<String>>,
    pub(super) scale: Option<Spanned<f64>>,
    pub(super) closed: Option<Spanned<bool>>,
    pub(super) flip_normals: Option<Spanned<bool>>,
    pub(super) extent: Option<Spanned<f64>>,
    pub(super) friction: Option<Spanned<f64>>,
    pub(super) motion: Option<Spanned<String>>,
    pub(super) direction: Option<Spanned<Vec<f64>>>,
    pub(super) displacement: Option<Spanned<f64>>,
    pub(super) mass: Option<Spanned<f64>>,
    pub(super) weight: Option<Spanned<f64>>,
    pub(super) plies: Option<Spanned<Vec<String>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BoundaryRaw {
    pub(super) ply: Option<String>,
    pub(super) nodes: Spanned<String>,
    pub(super) fix: Option<Spanned<Vec<String>>>,
    pub(super) displacement: Option<Spanned<Vec<f64>>>,
    pub(super) rotation: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LoadRaw {
    pub(super) ply: Option<String>,
    pub(super) nodes: Spanned<String>,
    pub(super) force: Spanned<Vec<f64>>,
    pub(super) amplitude: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ProbeRaw {
    pub(super) ply: Option<String>,
    pub(super) nodes: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ZoneRaw {
    pub(super) name: Option<String>,
    pub(super) ply: Option<String>,
    pub(super) centre: Spanned<Vec<f64>>,
    pub(super) size: Option<Spanned<Vec<f64>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PlyContactRaw {
    pub(super) plies: Spanned<Vec<String>>,
    pub(super) friction: Spanned<f64>,
    pub(super) skin: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GravityRaw {
    pub(super) g: Option<Spanned<f64>>,
    pub(super) direction: Option<Spanned<Vec<f64>>>,
    pub(super) amplitude: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ContactRaw {
    pub(super) offset: Option<Spanned<f64>>,
    pub(super) penalty: Option<Spanned<f64>>,
    pub(super) penalty_scale: Option<Spanned<f64>>,
    pub(super) tangential_penalty_scale: Option<Spanned<f64>>,
    pub(super) normal_smoothing: Option<Spanned<f64>>,
    pub(super) friction_smoothing: Option<Spanned<f64>>,
    pub(super) gap_tolerance: Option<Spanned<f64>>,
    pub(super) multiplier_tolerance: Option<Spanned<f64>>,
    pub(super) explicit_stiffness: Option<Spanned<f64>>,
    pub(super) explicit_pressure_stiffness: Option<Spanned<f64>>,
    pub(super) explicit_damping: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct OutputRaw {
    pub(super) states: Option<Spanned<i64>>,
    pub(super) history: Option<Spanned<i64>>,
    pub(super) camera: Option<Spanned<String>>,
    pub(super) maps: Option<bool>,
}

/// `[rosette]`: the design rosette of the fibre angles.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RosetteRaw {
    pub(super) origin: Option<Spanned<Vec<f64>>>,
    pub(super) direction: Option<Spanned<Vec<f64>>>,
    pub(super) rule: Option<Spanned<String>>,
    pub(super) fallback: Option<Spanned<Vec<f64>>>,
}

/// `[defects]`: the thresholds of the defect indicators.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct DefectsRaw {
    pub(super) tool_gap: Option<Spanned<f64>>,
    pub(super) curvature: Option<Spanned<f64>>,
    pub(super) slack_line_force: Option<Spanned<f64>>,
    pub(super) waviness_line_force: Option<Spanned<f64>>,
    pub(super) waviness_wavelength: Option<Spanned<f64>>,
    pub(super) roving_pitch: Option<Spanned<f64>>,
    pub(super) gap_width: Option<Spanned<f64>>,
}
