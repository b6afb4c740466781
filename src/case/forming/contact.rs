//! Contact in a forming case: the `[contact]` table (the settings every
//! tool's contact shares: offset, penalties, smoothing, tolerances and the
//! explicit path's stiffness and damping) and the `[[ply_contact]]` tables
//! (friction between two plies, explicit path only). Key-by-key
//! documentation: `docs/cases.md`, "Forming cases".

use toml::Spanned;

use super::ply::{PlySpec, ply_index};
use super::raw::{ContactRaw, PlyContactRaw};
use crate::config::{ConfigError, TomlChecker};
use crate::contact::kernel::Smoothing;
use crate::model::ExplicitPenalty;

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

/// The `[[ply_contact]]` tables: two different plies, a pair no other
/// table names, the friction coefficient and the skin of each.
pub(super) fn ply_contacts(
    check: &TomlChecker,
    raw: &[PlyContactRaw],
    plies: &[PlySpec],
) -> Result<Vec<PlyContactSpec>, ConfigError> {
    let mut ply_contacts: Vec<PlyContactSpec> = Vec::new();
    for (i, c) in raw.iter().enumerate() {
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
        let a = ply_index(check, plies, &Some(names[0].clone()), &key("plies"))?;
        let b = ply_index(check, plies, &Some(names[1].clone()), &key("plies"))?;
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
    Ok(ply_contacts)
}

/// The `[contact]` table: the defaults of [`ContactSettings`] with the
/// keys given.
pub(super) fn settings(
    check: &TomlChecker,
    raw: Option<&ContactRaw>,
) -> Result<ContactSettings, ConfigError> {
    let positive = |v: &Spanned<f64>, key: &str, what: &str| check.range(v, key, |x| x > 0.0, what);
    let mut contact = ContactSettings::default();
    if let Some(c) = raw {
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
    Ok(contact)
}
