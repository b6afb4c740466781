//! The `[rosette]` and `[defects]` tables of a forming case: the design
//! rosette the fibre angles are measured in, and the thresholds of the
//! defect indicators. Both are optional; key-by-key documentation:
//! `docs/cases.md`, "Orientation fields" and "Defect indicators".

use toml::Spanned;

use super::ply::{PAPER_BENDING, PlySpec};
use super::raw::{DefectsRaw, RosetteRaw};
use super::vector3;
use crate::case::bounds::bound;
use crate::config::{ConfigError, TomlChecker};
use crate::post::defects::{
    DEFAULT_CURVATURE, DEFAULT_GAP_WIDTH, DEFAULT_ROVING_PITCH, DEFAULT_SLACK_LINE_FORCE,
    DEFAULT_TOOL_GAP, DEFAULT_WAVINESS_WAVELENGTH, DefectThresholds, euler_line_force,
};
use crate::post::orientation::{Rosette, RosetteRule};

/// The validated `[defects]` table.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DefectSpec {
    /// `tool_gap` \[mm\].
    pub tool_gap: f64,
    /// `curvature` \[1/mm\].
    pub curvature: f64,
    /// `slack_line_force` \[N/mm\].
    pub slack_line_force: f64,
    /// `waviness_line_force` \[N/mm\]; `None`: the Euler force of each ply
    /// over `waviness_wavelength`.
    pub waviness_line_force: Option<f64>,
    /// `waviness_wavelength` \[mm\].
    pub waviness_wavelength: f64,
    /// `roving_pitch` \[mm\].
    pub roving_pitch: f64,
    /// `gap_width` \[mm\].
    pub gap_width: f64,
}

impl Default for DefectSpec {
    fn default() -> Self {
        Self {
            tool_gap: DEFAULT_TOOL_GAP,
            curvature: DEFAULT_CURVATURE,
            slack_line_force: DEFAULT_SLACK_LINE_FORCE,
            waviness_line_force: None,
            waviness_wavelength: DEFAULT_WAVINESS_WAVELENGTH,
            roving_pitch: DEFAULT_ROVING_PITCH,
            gap_width: DEFAULT_GAP_WIDTH,
        }
    }
}

impl DefectSpec {
    /// The thresholds of `ply`: the waviness force, unless given, is the
    /// Euler force of the ply's `B11` (the paper's without bending) over
    /// the wavelength ([`euler_line_force`]).
    pub fn thresholds(&self, ply: &PlySpec) -> DefectThresholds {
        let b11 = ply.bending.map_or(PAPER_BENDING[0], |b| b[0]);
        DefectThresholds {
            tool_gap: self.tool_gap,
            curvature: self.curvature,
            slack_line_force: self.slack_line_force,
            waviness_line_force: self
                .waviness_line_force
                .unwrap_or_else(|| euler_line_force(b11, self.waviness_wavelength)),
            roving_pitch: self.roving_pitch,
            gap_width: self.gap_width,
        }
    }
}

/// The `[rosette]` table, the default rosette when left out.
pub(super) fn rosette(
    check: &TomlChecker,
    raw: Option<&RosetteRaw>,
) -> Result<Rosette, ConfigError> {
    let mut rosette = Rosette::default();
    let Some(r) = raw else {
        return Ok(rosette);
    };
    if let Some(v) = &r.origin {
        rosette.origin = vector3(check, v, "rosette.origin", Some(bound("rosette.origin")))?.into();
    }
    if let Some(v) = &r.direction {
        rosette.direction = vector3(check, v, "rosette.direction", None)?.into();
    }
    if let Some(v) = &r.fallback {
        rosette.fallback = vector3(check, v, "rosette.fallback", None)?.into();
    }
    if let Some(v) = &r.rule {
        rosette.rule = check.choice(
            v,
            "rosette.rule",
            &[
                ("projected", RosetteRule::Projected),
                ("radial", RosetteRule::Radial),
            ],
        )?;
    }
    Ok(rosette)
}

/// The `[defects]` table, the defaults for every key left out, each key
/// in its range ([`crate::case::bounds`]).
pub(super) fn defects(
    check: &TomlChecker,
    raw: Option<&DefectsRaw>,
) -> Result<DefectSpec, ConfigError> {
    let mut spec = DefectSpec::default();
    let Some(d) = raw else {
        return Ok(spec);
    };
    let bounded = |v: &Option<Spanned<f64>>, key: &str, into: &mut f64| {
        if let Some(v) = v {
            *into = bound(key).spanned(check, v, key)?;
        }
        Ok::<(), ConfigError>(())
    };
    bounded(&d.tool_gap, "defects.tool_gap", &mut spec.tool_gap)?;
    bounded(&d.curvature, "defects.curvature", &mut spec.curvature)?;
    bounded(
        &d.slack_line_force,
        "defects.slack_line_force",
        &mut spec.slack_line_force,
    )?;
    bounded(
        &d.waviness_wavelength,
        "defects.waviness_wavelength",
        &mut spec.waviness_wavelength,
    )?;
    bounded(
        &d.roving_pitch,
        "defects.roving_pitch",
        &mut spec.roving_pitch,
    )?;
    bounded(&d.gap_width, "defects.gap_width", &mut spec.gap_width)?;
    if let Some(v) = &d.waviness_line_force {
        spec.waviness_line_force = Some(bound("defects.waviness_line_force").spanned(
            check,
            v,
            "defects.waviness_line_force",
        )?);
    }
    Ok(spec)
}
