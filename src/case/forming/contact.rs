//! Contact in a forming case: the `[contact]` table (the settings every
//! tool's contact shares: offset, penalties, smoothing, tolerances and the
//! explicit path's stiffness and damping) and the `[[ply_contact]]` tables
//! (friction between two plies, explicit path only). Key-by-key
//! documentation: `docs/cases.md`, "Forming cases".

use toml::Spanned;

use super::ply::{PlySpec, ply_index};
use super::quoted_names;
use super::raw::{ContactRaw, PlyContactRaw};
use crate::case::bounds::bound;
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
        let shown = format!("[{}]", quoted_names(names.iter().map(String::as_str)));
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
        if plies[a].compaction != plies[b].compaction {
            return Err(check.invalid(
                line,
                &key("plies"),
                shown,
                &format!(
                    "two plies with the same [ply.compaction] law or both without one (the layer between them is one packing law: docs/theory.md, \"Compaction of the fabric layer\"); \"{}\" and \"{}\" differ",
                    plies[a].name, plies[b].name
                ),
            ));
        }
        let friction =
            bound("ply_contact.friction").spanned(check, &c.friction, &key("friction"))?;
        let skin = match &c.skin {
            None => DEFAULT_PLY_CONTACT_SKIN,
            Some(v) => bound("ply_contact.skin").spanned(check, v, &key("skin"))?,
        };
        ply_contacts.push(PlyContactSpec {
            plies: [a, b],
            friction,
            skin,
        });
    }
    Ok(ply_contacts)
}

/// The `[contact]` keys only the quasi-static path reads (the augmented
/// Lagrangian's) and those only the explicit path reads (its penalty and
/// damping); `offset` is read by both.
const QUASI_STATIC_KEYS: &[&str] = &[
    "offset",
    "penalty",
    "penalty_scale",
    "tangential_penalty_scale",
    "normal_smoothing",
    "friction_smoothing",
    "gap_tolerance",
    "multiplier_tolerance",
];
const EXPLICIT_KEYS: &[&str] = &[
    "offset",
    "explicit_stiffness",
    "explicit_pressure_stiffness",
    "explicit_damping",
];

/// Refuses a `[contact]` key the case's solver does not read, naming the
/// keys it does.
pub(super) fn applicable_keys(
    check: &TomlChecker,
    raw: Option<&ContactRaw>,
    solver: crate::case::SolverKind,
) -> Result<(), ConfigError> {
    let Some(c) = raw else { return Ok(()) };
    let given = [
        check.given("offset", &c.offset),
        check.given("penalty", &c.penalty),
        check.given("penalty_scale", &c.penalty_scale),
        check.given("tangential_penalty_scale", &c.tangential_penalty_scale),
        check.given("normal_smoothing", &c.normal_smoothing),
        check.given("friction_smoothing", &c.friction_smoothing),
        check.given("gap_tolerance", &c.gap_tolerance),
        check.given("multiplier_tolerance", &c.multiplier_tolerance),
        check.given("explicit_stiffness", &c.explicit_stiffness),
        check.given(
            "explicit_pressure_stiffness",
            &c.explicit_pressure_stiffness,
        ),
        check.given("explicit_damping", &c.explicit_damping),
    ];
    let (takes, what) = match solver {
        crate::case::SolverKind::QuasiStatic => (QUASI_STATIC_KEYS, "the quasi-static solver"),
        crate::case::SolverKind::Explicit => (EXPLICIT_KEYS, "the explicit solver"),
    };
    check.only_keys("contact", &given, takes, what)
}

/// The `[contact]` table: the defaults of [`ContactSettings`] with the
/// keys given, each in its range ([`crate::case::bounds`]).
pub(super) fn settings(
    check: &TomlChecker,
    raw: Option<&ContactRaw>,
) -> Result<ContactSettings, ConfigError> {
    let bounded = |v: &Spanned<f64>, key: &str| bound(key).spanned(check, v, key);
    let mut contact = ContactSettings::default();
    if let Some(c) = raw {
        if let Some(v) = &c.offset {
            contact.offset = Some(bounded(v, "contact.offset")?);
        }
        if let Some(v) = &c.penalty {
            contact.penalty = Some(bounded(v, "contact.penalty")?);
        }
        if let Some(v) = &c.penalty_scale {
            contact.penalty_scale = bounded(v, "contact.penalty_scale")?;
        }
        if let Some(v) = &c.tangential_penalty_scale {
            contact.tangential_penalty_scale = bounded(v, "contact.tangential_penalty_scale")?;
        }
        if let Some(v) = &c.normal_smoothing {
            contact.smoothing.gap_width = bounded(v, "contact.normal_smoothing")?;
        }
        if let Some(v) = &c.friction_smoothing {
            contact.smoothing.friction_width = bounded(v, "contact.friction_smoothing")?;
        }
        if let Some(v) = &c.gap_tolerance {
            contact.gap_tolerance = Some(bounded(v, "contact.gap_tolerance")?);
        }
        if let Some(v) = &c.multiplier_tolerance {
            contact.multiplier_tolerance = bounded(v, "contact.multiplier_tolerance")?;
        }
        if let Some(v) = &c.explicit_damping {
            contact.explicit_damping = bounded(v, "contact.explicit_damping")?;
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
                contact.explicit_stiffness = bounded(v, "contact.explicit_stiffness")?;
            }
            (None, Some(k)) => {
                contact.explicit_pressure_stiffness =
                    Some(bounded(k, "contact.explicit_pressure_stiffness")?);
            }
            (None, None) => {}
        }
    }
    Ok(contact)
}
