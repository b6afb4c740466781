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
use super::sensitivity::{LawParameter, TermParameter};
use super::svk::OrthotropicSvk;
use super::udncf::UdNcf;
use crate::config::{ConfigError, TomlChecker, parse_toml, readable_number};

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

    /// A copy of the set with the given UD-NCF parameters set to new values
    /// (a later entry for the same parameter wins), validated by exactly the
    /// rules of a parameter file: the set is written as TOML with the new
    /// values and read back with [`MaterialSpec::from_toml_str`]. Name,
    /// description and source are kept.
    ///
    /// # Errors
    /// [`ConfigError::Invalid`] naming the key and the value: a value out of
    /// its range (as a parameter file would be refused), or a parameter the
    /// set does not have (a transition or lock key of a term without one,
    /// any key of an orthotropic-svk set), with how to add it.
    pub fn with_parameters(
        &self,
        values: &[(LawParameter, f64)],
    ) -> Result<MaterialSpec, ParamsError> {
        let source = format!("{} with edited parameters", self.source);
        let mut current = self.parameter_values();
        for &(p, value) in values {
            let key = p.key();
            match current.iter_mut().find(|(k, _)| *k == key) {
                Some(entry) => entry.1 = value,
                None => {
                    return Err(ConfigError::Invalid {
                        source,
                        line: 0,
                        expected: self.absent_parameter(p),
                        key,
                        value: readable_number(value),
                    });
                }
            }
        }
        let text = self.toml_text("", &current);
        let mut spec = Self::from_toml_str(&text, &source).map_err(|e| match e {
            // The line is one of the generated text, which nobody sees.
            ConfigError::Invalid {
                source,
                key,
                value,
                expected,
                ..
            } => ConfigError::Invalid {
                source,
                line: 0,
                key,
                value,
                expected,
            },
            other => other,
        })?;
        spec.source = self.source.clone();
        Ok(spec)
    }

    /// Why `p` is not a parameter of this set, and how to add it.
    fn absent_parameter(&self, p: LawParameter) -> String {
        let (LawParameter::Term(term, parameter), Material::UdNcf(_)) = (p, &self.material) else {
            return format!(
                "a parameter of this set: it is a \"{}\" set, which has no UD-NCF parameters",
                self.law_name()
            );
        };
        let table = term.key();
        match parameter {
            TermParameter::CLock | TermParameter::ILock => format!(
                "a parameter of this set: [{table}] has no lock; to add one, write c_lock and \
                 i_lock together into the [{table}] table of a parameter file (a copy of the set: \
                 `ncform material params NAME` prints a named one) and use that file"
            ),
            _ => format!(
                "a parameter of this set: [{table}] has no transition; to add one, write s_ini, \
                 c_mid and delta_s_mid together into the [{table}] table of a parameter file (a \
                 copy of the set: `ncform material params NAME` prints a named one) and use that \
                 file"
            ),
        }
    }

    /// The set as a complete parameter file: `header` as leading comment
    /// lines (each line prefixed with `# `), then `law`, `name`,
    /// `description` and every table with every key the set has. Numbers
    /// are written in Rust's shortest round-trip form (always as TOML
    /// floats, `1000.0`, `1e-7`), so [`MaterialSpec::from_toml_str`] reads
    /// the same law back bit for bit. Control characters in `header` (other
    /// than tab) are written as spaces, so the comment stays valid TOML.
    pub fn to_toml(&self, header: &str) -> String {
        self.toml_text(header, &self.parameter_values())
    }

    /// [`MaterialSpec::to_toml`] with the given `table.key` values (in table
    /// order) in place of the set's own.
    fn toml_text(&self, header: &str, values: &[(String, f64)]) -> String {
        let mut out = String::new();
        for line in header.lines() {
            let line: String = line
                .chars()
                .map(|c| if c.is_control() && c != '\t' { ' ' } else { c })
                .collect();
            let line = line.trim_end();
            if line.is_empty() {
                out.push_str("#\n");
            } else {
                out.push_str("# ");
                out.push_str(line);
                out.push('\n');
            }
        }
        if !out.is_empty() {
            out.push('\n');
        }
        out.push_str(&format!("law = {}\n", toml_string(self.law_name())));
        out.push_str(&format!("name = {}\n", toml_string(&self.name)));
        out.push_str(&format!(
            "description = {}\n",
            toml_string(&self.description)
        ));
        let mut table = "";
        for (key, value) in values {
            let (t, k) = key.split_once('.').unwrap_or(("", key));
            if t != table {
                out.push_str(&format!("\n[{t}]\n"));
                table = t;
            }
            out.push_str(&format!("{k} = {}\n", toml_float(*value)));
        }
        out
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

/// `x` as a TOML float that parses back to the same bits: Rust's shortest
/// round-trip form (`{:?}`), with `.0` added to an integer (`1000.0`), and
/// `nan`, `inf`, `-inf` as TOML spells them.
fn toml_float(x: f64) -> String {
    if x.is_nan() {
        return "nan".into();
    }
    if x.is_infinite() {
        return if x > 0.0 { "inf".into() } else { "-inf".into() };
    }
    let text = format!("{x:?}");
    if text.contains(['.', 'e', 'E']) {
        text
    } else {
        text + ".0"
    }
}

/// `s` as a TOML basic string: quotes, backslashes and control characters
/// escaped.
fn toml_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::sensitivity::CouplingParameter;

    const SVK: &str = r#"
law = "orthotropic-svk"
name = "svk-test"
description = "a cross-check set"
[svk]
e1 = 1000.0
e2 = 3.0
nu12 = 0.1
g12 = 0.25
"#;

    fn p(key: &str) -> LawParameter {
        LawParameter::from_key(key).expect("a known key")
    }

    fn bits(spec: &MaterialSpec) -> Vec<(String, u64)> {
        spec.parameter_values()
            .into_iter()
            .map(|(k, v)| (k, v.to_bits()))
            .collect()
    }

    fn round_trip(spec: &MaterialSpec, header: &str) -> MaterialSpec {
        let text = spec.to_toml(header);
        MaterialSpec::from_toml_str(&text, "round-trip")
            .unwrap_or_else(|e| panic!("{e}\n--- text ---\n{text}"))
    }

    #[test]
    fn to_toml_round_trips_the_named_sets_and_an_svk_set_exactly() {
        let mut sets: Vec<MaterialSpec> = NAMED_SETS
            .iter()
            .map(|(n, _)| MaterialSpec::named(n).expect("named"))
            .collect();
        sets.push(MaterialSpec::from_toml_str(SVK, "svk-test").expect("valid"));
        for spec in &sets {
            let back = round_trip(spec, "written by a test\n\nsecond line");
            assert_eq!(back.material, spec.material, "{}", spec.name);
            assert_eq!(back.name, spec.name);
            assert_eq!(back.description, spec.description);
            assert_eq!(bits(&back), bits(spec));
            let text = spec.to_toml("written by a test\n\nsecond line");
            assert!(text.starts_with("# written by a test\n#\n# second line\n"));
            assert!(text.contains(&format!("law = \"{}\"", spec.law_name())));
        }
        // Integers are written as floats.
        assert!(sets[0].to_toml("").contains("c_ini = 1000.0\n"));
        assert!(!sets[0].to_toml("").starts_with('#'));
    }

    #[test]
    fn to_toml_keeps_awkward_numbers_and_text_bit_for_bit() {
        let spec = MaterialSpec::default_set();
        let edited = spec
            .with_parameters(&[
                (p("w6.c_ini"), 0.1 + 0.2),
                (p("w8.c_lock"), 1e12),
                (p("w11.c_mid"), 1e-12),
                (p("w4.c_ini"), 123456789012.5),
                (p("coupling.k_min"), 0.0),
            ])
            .err();
        // w8 has no lock in the default set: refused, nothing else changed.
        assert!(edited.is_some());
        let mut edited = spec
            .with_parameters(&[
                (p("w6.c_ini"), 0.1 + 0.2),
                (p("w8.c_mid"), 1e12),
                (p("w11.c_mid"), 1e-12),
                (p("w4.c_ini"), 123456789012.5),
                (p("coupling.k_min"), 0.0),
                (p("coupling.e11"), 1.0 + f64::EPSILON),
            ])
            .expect("valid values");
        edited.name = "a \"quoted\" name \\ with\ttab".into();
        edited.description = "two\nlines and a bell \u{7} and é".into();
        let back = round_trip(&edited, "header with a stray \r carriage return");
        assert_eq!(back.material, edited.material);
        assert_eq!(bits(&back), bits(&edited));
        assert_eq!(back.name, edited.name);
        assert_eq!(back.description, edited.description);
    }

    #[test]
    fn with_parameters_sets_the_values_and_derives_the_rest() {
        let spec = MaterialSpec::default_set();
        let edited = spec
            .with_parameters(&[
                (p("w6.c_ini"), 0.2),
                (p("w11.i_lock"), 0.35),
                (LawParameter::Coupling(CouplingParameter::E11), 1.5),
                (p("w6.c_ini"), 0.25),
            ])
            .expect("valid values");
        let Material::UdNcf(law) = edited.material else {
            panic!("ud-ncf");
        };
        assert_eq!(law.w6.c_ini, 0.25, "the later entry wins");
        assert_eq!(law.w6.transition_point(), 0.018 / 0.25);
        assert_eq!(law.w11.lock.map(|l| l.i_lock), Some(0.35));
        assert_eq!(law.coupling.e11, 1.5);
        assert_eq!(
            (edited.name.as_str(), edited.source.as_str()),
            ("schaefer2024", "schaefer2024")
        );
        // Everything else as it was.
        let changed: Vec<String> = spec
            .parameter_values()
            .into_iter()
            .zip(edited.parameter_values())
            .filter(|(a, b)| a.1.to_bits() != b.1.to_bits())
            .map(|(a, _)| a.0)
            .collect();
        assert_eq!(changed, ["w6.c_ini", "w11.i_lock", "coupling.e11"]);
        assert_eq!(spec.with_parameters(&[]).expect("unchanged"), spec);
    }

    #[test]
    fn with_parameters_refuses_out_of_range_values_naming_key_and_value() {
        let spec = MaterialSpec::default_set();
        for (key, value, shown, rule) in [
            ("coupling.k_min", 1.5, "= 1.5", "[0, 1]"),
            ("w6.c_ini", -1.0, "= -1", "> 0"),
            ("coupling.e11", 0.5, "= 0.5", "≥ 1"),
            ("w8.delta_s_mid", f64::NAN, "= nan", "> 0"),
            ("w4.c_ini", 1e300, "= 1e300", "magnitude"),
        ] {
            let err = spec
                .with_parameters(&[(p(key), value)])
                .expect_err("out of range");
            let message = err.to_string();
            assert!(
                message.contains(&format!("{key} {shown}")) && message.contains(rule),
                "{message}"
            );
            assert!(
                matches!(err, ConfigError::Invalid { line: 0, .. }),
                "{err:?}"
            );
        }
    }

    #[test]
    fn with_parameters_refuses_a_parameter_the_set_does_not_have() {
        let spec = MaterialSpec::default_set();
        let message = spec
            .with_parameters(&[(p("w6.c_lock"), 3.0)])
            .expect_err("w6 has no lock")
            .to_string();
        assert!(
            message.contains("w6.c_lock = 3")
                && message.contains("[w6] has no lock")
                && message.contains("c_lock and i_lock together"),
            "{message}"
        );
        let message = spec
            .with_parameters(&[(p("w4.s_ini"), 3.0)])
            .expect_err("w4 has no transition")
            .to_string();
        assert!(
            message.contains("w4.s_ini = 3")
                && message.contains("[w4] has no transition")
                && message.contains("s_ini, c_mid and delta_s_mid together"),
            "{message}"
        );
        let svk = MaterialSpec::from_toml_str(SVK, "svk-test").expect("valid");
        let message = svk
            .with_parameters(&[(p("coupling.k_min"), 0.5)])
            .expect_err("an svk set")
            .to_string();
        assert!(
            message.contains("orthotropic-svk") && message.contains("coupling.k_min"),
            "{message}"
        );
    }
}
