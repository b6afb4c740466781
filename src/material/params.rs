//! Material parameter sets: the named sets shipped with ncform and user
//! files in TOML, validated key by key.
//!
//! File format (see `cases/materials/schaefer2024.toml` and
//! `docs/parameters.md`): `law = "ud-ncf"` with tables `[w4]`, `[w6]`, `[w8]`,
//! `[w11]` (keys `c_ini`, optional `s_ini` + `c_mid` + `delta_s_mid`,
//! optional `c_lock` + `i_lock`) and `[coupling]` (`k_min`, `s11`, `e11`); or
//! `law = "orthotropic-svk"` with a table `[svk]` (`e1`, `e2`, `nu12`, `g12`).
//! Units: MPa.

use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use super::Material;
use super::coupling::Coupling;
use super::generalized::{GeneralizedTerm, Lock, Transition};
use super::svk::OrthotropicSvk;
use super::udncf::UdNcf;
use crate::config::{ConfigError, TomlChecker, parse_toml};

/// The named parameter sets: `(name, TOML text)`. The first is the default.
pub const NAMED_SETS: &[(&str, &str)] = &[
    (
        "schaefer2024",
        include_str!("../../cases/materials/schaefer2024.toml"),
    ),
    (
        "schaefer2024-printed",
        include_str!("../../cases/materials/schaefer2024-printed.toml"),
    ),
];

/// The default parameter set: Table D.1 with the reconstructed W11 lock.
pub const DEFAULT_SET: &str = "schaefer2024";

/// A validated parameter set: a ready-to-evaluate law and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialSpec {
    /// Name given in the file (or the file name).
    pub name: String,
    /// Free-text description from the file.
    pub description: String,
    /// Where the set was read from: a set name or a file path.
    pub source: String,
    /// The law with its parameters.
    pub material: Material,
}

/// Why a parameter set could not be used (see [`ConfigError`]).
pub type ParamsError = ConfigError;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRaw {
    law: Option<Spanned<String>>,
    name: Option<String>,
    description: Option<String>,
    w4: Option<TermRaw>,
    w6: Option<TermRaw>,
    w8: Option<TermRaw>,
    w11: Option<TermRaw>,
    coupling: Option<CouplingRaw>,
    svk: Option<SvkRaw>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TermRaw {
    c_ini: Spanned<f64>,
    s_ini: Option<Spanned<f64>>,
    c_mid: Option<Spanned<f64>>,
    delta_s_mid: Option<Spanned<f64>>,
    c_lock: Option<Spanned<f64>>,
    i_lock: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CouplingRaw {
    k_min: Spanned<f64>,
    s11: Spanned<f64>,
    e11: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SvkRaw {
    e1: Spanned<f64>,
    e2: Spanned<f64>,
    nu12: Spanned<f64>,
    g12: Spanned<f64>,
}

type Checker<'a> = TomlChecker<'a>;

/// Largest magnitude a parameter may have (moduli and stresses in MPa,
/// exponents and intensities): 1e12, five million times the modulus of
/// steel. Beyond it energies and stresses overflow `f64` in ordinary
/// strains; a larger value is a typing error, not a material.
pub const PARAMETER_MAX: f64 = 1e12;

/// Smallest magnitude a non-zero parameter may have: 1e-12 (a micro-pascal
/// in MPa). Below it the law divides by (nearly) zero.
pub const PARAMETER_MIN: f64 = 1e-12;

/// The value if `ok` accepts it and it is 0 or of a magnitude in
/// [`PARAMETER_MIN`, `PARAMETER_MAX`]; the error names the key, the value
/// and which rule it breaks.
fn param(
    check: &Checker,
    v: &Spanned<f64>,
    key: &str,
    ok: impl Fn(f64) -> bool,
    expected: &str,
) -> Result<f64, ParamsError> {
    check.range(v, key, ok, expected)?;
    check.range(
        v,
        key,
        |x| x == 0.0 || (PARAMETER_MIN..=PARAMETER_MAX).contains(&x.abs()),
        &format!("{expected}, of magnitude within [{PARAMETER_MIN:e}, {PARAMETER_MAX:e}]"),
    )
}

/// The validation of each table, on the shared checker.
trait ParamsChecks {
    fn term(&self, raw: Option<&TermRaw>, table: &str) -> Result<GeneralizedTerm, ParamsError>;
    fn coupling(&self, raw: Option<&CouplingRaw>) -> Result<Coupling, ParamsError>;
    fn svk(&self, raw: Option<&SvkRaw>) -> Result<OrthotropicSvk, ParamsError>;
}

impl ParamsChecks for Checker<'_> {
    fn term(&self, raw: Option<&TermRaw>, table: &str) -> Result<GeneralizedTerm, ParamsError> {
        let raw = raw.ok_or_else(|| {
            self.missing(
                &format!("[{table}]"),
                "a table for this term (law \"ud-ncf\")",
            )
        })?;
        let key = |k: &str| format!("{table}.{k}");
        let c_ini = param(
            self,
            &raw.c_ini,
            &key("c_ini"),
            |x| x > 0.0,
            "an initial modulus > 0 MPa",
        )?;
        let transition = match (&raw.s_ini, &raw.c_mid, &raw.delta_s_mid) {
            (None, None, None) => None,
            (Some(s), Some(c), Some(d)) => Some(Transition {
                s_ini: param(
                    self,
                    s,
                    &key("s_ini"),
                    |x| x > 0.0,
                    "an initial stress limit > 0 MPa",
                )?,
                c_mid: param(
                    self,
                    c,
                    &key("c_mid"),
                    |x| x >= 0.0,
                    "a middle modulus ≥ 0 MPa",
                )?,
                delta_s_mid: param(
                    self,
                    d,
                    &key("delta_s_mid"),
                    |x| x > 0.0,
                    "a transition stress range > 0 MPa",
                )?,
            }),
            (s, c, d) => {
                let given = [("s_ini", s), ("c_mid", c), ("delta_s_mid", d)];
                let (present, _) = given.iter().find(|(_, v)| v.is_some()).expect("one is set");
                let (absent, _) = given
                    .iter()
                    .find(|(_, v)| v.is_none())
                    .expect("one is unset");
                let line = given
                    .iter()
                    .find_map(|(_, v)| v.as_ref().map(|v| self.line_of(v)))
                    .unwrap_or(0);
                return Err(self.invalid(
                    line,
                    &key(absent),
                    "(missing)".to_string(),
                    &format!(
                        "a value: {table}.{present} is given, and a transition needs s_ini, c_mid and delta_s_mid together"
                    ),
                ));
            }
        };
        let lock = match (&raw.c_lock, &raw.i_lock) {
            (None, None) => None,
            (Some(c), Some(i)) => Some(Lock {
                c_lock: param(
                    self,
                    c,
                    &key("c_lock"),
                    |x| x >= 0.0,
                    "a lock modulus ≥ 0 MPa",
                )?,
                i_lock: param(self, i, &key("i_lock"), |x| x >= 0.0, "a lock onset ≥ 0")?,
            }),
            (Some(c), None) => {
                return Err(self.invalid(
                    self.line_of(c),
                    &key("i_lock"),
                    "(missing)".to_string(),
                    &format!("a value: {table}.c_lock is given, and a lock needs c_lock and i_lock together"),
                ));
            }
            (None, Some(i)) => {
                return Err(self.invalid(
                    self.line_of(i),
                    &key("c_lock"),
                    "(missing)".to_string(),
                    &format!("a value: {table}.i_lock is given, and a lock needs c_lock and i_lock together"),
                ));
            }
        };
        Ok(GeneralizedTerm::new(c_ini, transition, lock))
    }

    fn coupling(&self, raw: Option<&CouplingRaw>) -> Result<Coupling, ParamsError> {
        let raw = raw.ok_or_else(|| {
            self.missing("[coupling]", "a table k_min, s11, e11 (law \"ud-ncf\")")
        })?;
        Ok(Coupling {
            k_min: param(
                self,
                &raw.k_min,
                "coupling.k_min",
                |x| (0.0..=1.0).contains(&x),
                "a value in [0, 1]",
            )?,
            s11: param(
                self,
                &raw.s11,
                "coupling.s11",
                |x| x >= 0.0,
                "an intensity ≥ 0",
            )?,
            e11: param(
                self,
                &raw.e11,
                "coupling.e11",
                |x| x >= 1.0,
                "an exponent ≥ 1 (C¹ at I11 = 1 needs > 1)",
            )?,
        })
    }

    fn svk(&self, raw: Option<&SvkRaw>) -> Result<OrthotropicSvk, ParamsError> {
        let raw = raw.ok_or_else(|| {
            self.missing(
                "[svk]",
                "a table e1, e2, nu12, g12 (law \"orthotropic-svk\")",
            )
        })?;
        let e1 = param(self, &raw.e1, "svk.e1", |x| x > 0.0, "a modulus > 0 MPa")?;
        let e2 = param(self, &raw.e2, "svk.e2", |x| x > 0.0, "a modulus > 0 MPa")?;
        let g12 = param(
            self,
            &raw.g12,
            "svk.g12",
            |x| x > 0.0,
            "a shear modulus > 0 MPa",
        )?;
        let bound = (e1 / e2).sqrt();
        let nu12 = param(
            self,
            &raw.nu12,
            "svk.nu12",
            |x| x * x < e1 / e2,
            &format!(
                "|nu12| < sqrt(e1/e2) = {} (positive-definite stiffness)",
                crate::config::readable_number(bound)
            ),
        )?;
        Ok(OrthotropicSvk { e1, e2, nu12, g12 })
    }
}

impl MaterialSpec {
    /// Parses and validates a parameter set from TOML text; `source` names it
    /// in error messages.
    ///
    /// # Errors
    /// Syntax errors, unknown or missing keys, and values outside their
    /// physical range, each naming the source, key, value and allowed range.
    pub fn from_toml_str(text: &str, source: &str) -> Result<Self, ParamsError> {
        let raw: FileRaw = parse_toml(text, source)?;
        let check = Checker::new(text, source);
        let law = raw
            .law
            .as_ref()
            .map(|l| (l.get_ref().as_str(), check.line_of(l)))
            .unwrap_or(("ud-ncf", 0));
        let forbid = |present: bool, table: &str, law: &str| -> Result<(), ParamsError> {
            if present {
                Err(check.invalid(
                    0,
                    &format!("[{table}]"),
                    "(given)".to_string(),
                    &format!("no such table for law \"{law}\""),
                ))
            } else {
                Ok(())
            }
        };
        let material = match law.0 {
            "ud-ncf" => {
                forbid(raw.svk.is_some(), "svk", "ud-ncf")?;
                Material::UdNcf(UdNcf {
                    w4: check.term(raw.w4.as_ref(), "w4")?,
                    w6: check.term(raw.w6.as_ref(), "w6")?,
                    w8: check.term(raw.w8.as_ref(), "w8")?,
                    w11: check.term(raw.w11.as_ref(), "w11")?,
                    coupling: check.coupling(raw.coupling.as_ref())?,
                })
            }
            "orthotropic-svk" => {
                for (present, table) in [
                    (raw.w4.is_some(), "w4"),
                    (raw.w6.is_some(), "w6"),
                    (raw.w8.is_some(), "w8"),
                    (raw.w11.is_some(), "w11"),
                    (raw.coupling.is_some(), "coupling"),
                ] {
                    forbid(present, table, "orthotropic-svk")?;
                }
                Material::OrthotropicSvk(check.svk(raw.svk.as_ref())?)
            }
            other => {
                return Err(check.invalid(
                    law.1,
                    "law",
                    format!("\"{other}\""),
                    "\"ud-ncf\" or \"orthotropic-svk\"",
                ));
            }
        };
        Ok(Self {
            name: raw.name.unwrap_or_else(|| source.to_string()),
            description: raw.description.unwrap_or_default(),
            source: source.to_string(),
            material,
        })
    }

    /// The law's name as a parameter file's `law` key gives it.
    pub fn law_name(&self) -> &'static str {
        match self.material {
            Material::UdNcf(_) => "ud-ncf",
            Material::OrthotropicSvk(_) => "orthotropic-svk",
        }
    }

    /// The law's parameters under the keys a parameter file gives them
    /// (`w6.c_ini`, `w11.i_lock`, `coupling.k_min`, `svk.e1`), in the
    /// order of `docs/parameters.md`; a term's transition and lock keys
    /// only when it has them. The inverse of [`MaterialSpec::from_toml_str`]
    /// on the law's values (`x_t` and the rate are derived, not listed).
    pub fn parameter_values(&self) -> Vec<(String, f64)> {
        let mut values = Vec::new();
        match &self.material {
            Material::UdNcf(law) => {
                for (name, term) in [
                    ("w4", &law.w4),
                    ("w6", &law.w6),
                    ("w8", &law.w8),
                    ("w11", &law.w11),
                ] {
                    values.push((format!("{name}.c_ini"), term.c_ini));
                    if let Some(t) = term.transition {
                        values.push((format!("{name}.s_ini"), t.s_ini));
                        values.push((format!("{name}.c_mid"), t.c_mid));
                        values.push((format!("{name}.delta_s_mid"), t.delta_s_mid));
                    }
                    if let Some(l) = term.lock {
                        values.push((format!("{name}.c_lock"), l.c_lock));
                        values.push((format!("{name}.i_lock"), l.i_lock));
                    }
                }
                let c = &law.coupling;
                values.push(("coupling.k_min".into(), c.k_min));
                values.push(("coupling.s11".into(), c.s11));
                values.push(("coupling.e11".into(), c.e11));
            }
            Material::OrthotropicSvk(svk) => {
                values.push(("svk.e1".into(), svk.e1));
                values.push(("svk.e2".into(), svk.e2));
                values.push(("svk.nu12".into(), svk.nu12));
                values.push(("svk.g12".into(), svk.g12));
            }
        }
        values
    }

    /// The TOML text of a named set, if `name` is one.
    pub fn named_text(name: &str) -> Option<&'static str> {
        NAMED_SETS.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
    }

    /// A named set (`schaefer2024`, `schaefer2024-printed`), or `None`.
    pub fn named(name: &str) -> Option<Self> {
        Self::named_text(name).map(|text| {
            Self::from_toml_str(text, name).expect("the named sets shipped with ncform are valid")
        })
    }

    /// The default set, [`DEFAULT_SET`].
    pub fn default_set() -> Self {
        Self::named(DEFAULT_SET).expect("the default set exists")
    }

    /// Resolves `name_or_path`: a named set first, else a TOML file.
    ///
    /// # Errors
    /// [`ParamsError::NotFound`] when it is neither; else as
    /// [`MaterialSpec::from_toml_str`].
    pub fn load(name_or_path: &str) -> Result<Self, ParamsError> {
        if let Some(spec) = Self::named(name_or_path) {
            return Ok(spec);
        }
        let path = Path::new(name_or_path);
        let bytes = std::fs::read(path).map_err(|e| ParamsError::NotFound {
            requested: format!("material parameters '{name_or_path}'"),
            reason: format!(
                "not a named set ({}) and not a readable file ({e})",
                NAMED_SETS
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })?;
        let source = path.display().to_string();
        let text = crate::config::utf8_text(bytes, &source)?;
        Self::from_toml_str(&text, &source)
    }
}
