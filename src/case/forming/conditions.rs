//! The conditions on the plies of a forming case: `[[boundary]]`
//! (Dirichlet conditions and clamped rotations on node sets), `[[load]]`
//! (dead forces on node sets), `[[probe]]` (node sets the history
//! records), `[[zone]]` (evaluation windows on the blank) and `[gravity]`.
//! Key-by-key documentation: `docs/cases.md`, "Forming cases".

use nalgebra::Vector3;
use toml::Spanned;

use super::ply::{PlySpec, ply_index};
use super::raw::{BoundaryRaw, GravityRaw, LoadRaw, ProbeRaw, ZoneRaw};
use super::{STANDARD_GRAVITY, amplitude, shown_list, vector3};
use crate::case::bounds::bound;
use crate::config::{ConfigError, TomlChecker};
use crate::model::LoadAmplitude;

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

/// The default size of a zone: the paper's 20 × 20 mm windows \[mm\].
pub const DEFAULT_ZONE_SIZE: [f64; 2] = [20.0, 20.0];

/// Gravity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GravitySpec {
    /// Acceleration vector [mm/s²].
    pub acceleration: Vector3<f64>,
    /// Amplitude.
    pub amplitude: LoadAmplitude,
}

/// The `[gravity]` table, if any: its acceleration (`g` along
/// `direction`, standard gravity along −z by default) and amplitude.
pub(super) fn gravity(
    check: &TomlChecker,
    raw: Option<&GravityRaw>,
) -> Result<Option<GravitySpec>, ConfigError> {
    Ok(match raw {
        None => None,
        Some(g) => {
            let magnitude = match &g.g {
                None => STANDARD_GRAVITY,
                Some(v) => bound("gravity.g").spanned(check, v, "gravity.g")?,
            };
            let direction = match &g.direction {
                None => -Vector3::z(),
                Some(d) => vector3(check, d, "gravity.direction", None)?,
            };
            Some(GravitySpec {
                acceleration: magnitude * direction,
                amplitude: amplitude(
                    check,
                    &g.amplitude,
                    "gravity.amplitude",
                    LoadAmplitude::Constant,
                )?,
            })
        }
    })
}

/// The `[[boundary]]` tables: the ply, the fixed and driven components and
/// the rotation of each (at least one of them).
pub(super) fn boundaries(
    check: &TomlChecker,
    raw: &[BoundaryRaw],
    plies: &[PlySpec],
) -> Result<Vec<BoundarySpec>, ConfigError> {
    let mut boundaries = Vec::new();
    for (i, b) in raw.iter().enumerate() {
        let key = |k: &str| format!("boundary[{i}].{k}");
        let ply = ply_index(check, plies, &b.ply, &key("ply"))?;
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
                let v = vector3(
                    check,
                    d,
                    &key("displacement"),
                    Some(bound("boundary.displacement")),
                )?;
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
            Some(r) => check.choice(r, &key("rotation"), &[("clamped", true), ("free", false)])?,
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
    Ok(boundaries)
}

/// The `[[load]]` tables: the ply, the total force and the amplitude of
/// each.
pub(super) fn loads(
    check: &TomlChecker,
    raw: &[LoadRaw],
    plies: &[PlySpec],
) -> Result<Vec<LoadSpec>, ConfigError> {
    let mut loads = Vec::new();
    for (i, l) in raw.iter().enumerate() {
        let key = |k: &str| format!("load[{i}].{k}");
        loads.push(LoadSpec {
            ply: ply_index(check, plies, &l.ply, &key("ply"))?,
            nodes: l.nodes.get_ref().clone(),
            force: vector3(check, &l.force, &key("force"), Some(bound("load.force")))?,
            amplitude: amplitude(check, &l.amplitude, &key("amplitude"), LoadAmplitude::Ramp)?,
            line: check.line_of(&l.nodes),
        });
    }
    Ok(loads)
}

/// The `[[probe]]` tables: the ply and node set of each.
pub(super) fn probes(
    check: &TomlChecker,
    raw: &[ProbeRaw],
    plies: &[PlySpec],
) -> Result<Vec<ProbeSpec>, ConfigError> {
    let mut probes = Vec::new();
    for (i, p) in raw.iter().enumerate() {
        probes.push(ProbeSpec {
            ply: ply_index(check, plies, &p.ply, &format!("probe[{i}].ply"))?,
            nodes: p.nodes.get_ref().clone(),
            line: check.line_of(&p.nodes),
        });
    }
    Ok(probes)
}

/// The `[[zone]]` tables: the name (`A`, `B`, … by default, each its own),
/// the ply, the centre and the size of each window.
pub(super) fn zones(
    check: &TomlChecker,
    raw: &[ZoneRaw],
    plies: &[PlySpec],
) -> Result<Vec<ZoneSpec>, ConfigError> {
    let mut zones: Vec<ZoneSpec> = Vec::new();
    for (i, z) in raw.iter().enumerate() {
        let key = |k: &str| format!("zone[{i}].{k}");
        let pair = |v: &Spanned<Vec<f64>>, k: &str| {
            let values = v.get_ref();
            let b = bound(&format!("zone.{k}"));
            if values.len() == 2 && values.iter().all(|x| b.hard.contains(*x)) {
                Ok([values[0], values[1]])
            } else {
                Err(check.invalid(
                    check.line_of(v),
                    &key(k),
                    shown_list(values),
                    &if k == "size" {
                        b.expected()
                    } else {
                        format!("two {}", b.expected())
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
            ply: ply_index(check, plies, &z.ply, &key("ply"))?,
            zone: crate::post::forming::Zone {
                name,
                centre: pair(&z.centre, "centre")?,
                size: match &z.size {
                    None => DEFAULT_ZONE_SIZE,
                    Some(v) => pair(v, "size")?,
                },
            },
        });
    }
    Ok(zones)
}
