//! The `[[ply]]` tables of a forming case: each ply's name, parameter set
//! (`params`), thickness, areal mass, fibre angle, bending stiffnesses
//! (`bending`) and mesh (`[ply.mesh]`: a generated rectangle, disk or
//! wrapped strip, or a mesh file), and how the other tables name a ply.
//! Key-by-key documentation: `docs/cases.md`, "Forming cases".

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use toml::Spanned;

use super::raw::{BendingRaw, CompactionRaw, PlyMeshRaw, PlyRaw};
use super::{quoted_names, shown_list, vector3};
use crate::case::bounds::bound;
use crate::case::explicit::{DEFAULT_AREAL_MASS, KG_PER_M2_IN_T_PER_MM2};
use crate::config::{ConfigError, TomlChecker};
use crate::contact::kernel::CompactionLaw;
use crate::material::MaterialSpec;

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
    /// The through-thickness packing law of the ply's layer in its
    /// contacts (explicit path; `docs/theory.md`, "Compaction of the
    /// fabric layer"), `None`: the rigid-membrane penalty of the paper's
    /// model.
    pub compaction: Option<PlyCompaction>,
    /// Line of the `compaction` table (0 when absent).
    pub compaction_line: usize,
    /// Line of the `[ply.mesh]` key the mesh comes from (`file` or
    /// `shape`) in the case file: errors of the mesh name it.
    pub mesh_line: usize,
}

/// A ply's compliant layer: its uncompacted thickness and its packing law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlyCompaction {
    /// The layer's thickness at zero pressure \[mm\]: the contacts' offsets
    /// (half of it to a tool, the mean of two plies' between them). The
    /// membrane keeps [`PlySpec::thickness`], the thickness its law's
    /// parameters were identified with.
    pub thickness: f64,
    /// Toll's packing law (Eq. C1).
    pub law: CompactionLaw,
}

impl PlySpec {
    /// The thickness its contacts see \[mm\]: the uncompacted layer's
    /// when the ply has one, else the membrane's.
    pub fn contact_thickness(&self) -> f64 {
        self.compaction.map_or(self.thickness, |c| c.thickness)
    }
}

/// The paper's bending stiffnesses `(B11, B22)` [N·mm] (Section 3) and the
/// default twist stiffness `B66 = B22` (not in the paper; `docs/theory.md`).
pub const PAPER_BENDING: [f64; 3] = [4.06, 0.018, 0.018];

/// Validates the `[[ply]]` tables in order: at least one ply, each with a
/// name no other ply has (`ply`, or `ply1`, `ply2`, … when unnamed).
pub(super) fn plies(
    check: &TomlChecker,
    raw: &[PlyRaw],
    base_dir: &Path,
) -> Result<Vec<PlySpec>, ConfigError> {
    if raw.is_empty() {
        return Err(check.missing("[[ply]]", "at least one ply"));
    }
    let mut plies = Vec::new();
    for (i, p) in raw.iter().enumerate() {
        let key = |k: &str| format!("ply[{i}].{k}");
        let name = p.name.clone().unwrap_or_else(|| {
            if raw.len() == 1 {
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
        plies.push(ply_spec(check, p, i, name, base_dir)?);
    }
    Ok(plies)
}

/// One ply's table: its law, thickness, density, fibre angle, bending and
/// mesh, checked in that order.
fn ply_spec(
    check: &TomlChecker,
    p: &PlyRaw,
    i: usize,
    name: String,
    base_dir: &Path,
) -> Result<PlySpec, ConfigError> {
    let key = |k: &str| format!("ply[{i}].{k}");
    let bounded = |v: &Spanned<f64>, k: &str| bound(&format!("ply.{k}")).spanned(check, v, &key(k));
    let (material, named_set) = match &p.params {
        None => (MaterialSpec::default_set(), true),
        Some(params) => (
            crate::case::oat::load_params(check, params, &key("params"), base_dir)?,
            MaterialSpec::named_text(params.get_ref()).is_some(),
        ),
    };
    let thickness = match &p.thickness {
        None => crate::case::oat::DEFAULT_THICKNESS,
        Some(t) => bounded(t, "thickness")?,
    };
    let density = match &p.areal_mass {
        Some(a) => Some(bounded(a, "areal_mass")? * KG_PER_M2_IN_T_PER_MM2 / thickness),
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
        Some(a) => bounded(a, "fibre_angle_deg")?,
    };
    let bending = bending(check, &p.bending, i)?;
    let compaction = compaction(check, &p.compaction, i, thickness)?;
    let mesh = ply_mesh(check, &p.mesh, i, base_dir)?;
    let mesh_line = match (&p.mesh.file, &p.mesh.shape) {
        (Some(f), _) => check.line_of(f),
        (None, Some(s)) => check.line_of(s),
        (None, None) => 0,
    };
    Ok(PlySpec {
        name,
        mesh,
        material,
        thickness,
        density,
        fibre_angle_deg,
        bending,
        compaction,
        compaction_line: p.compaction.as_ref().map_or(0, |c| check.line_of(c)),
        mesh_line,
    })
}

/// A ply's `[ply.compaction]` table: the law's two keys, each within its
/// bounds, and the layer's thickness (the membrane's `thickness` when left
/// out).
fn compaction(
    check: &TomlChecker,
    c: &Option<Spanned<CompactionRaw>>,
    i: usize,
    membrane_thickness: f64,
) -> Result<Option<PlyCompaction>, ConfigError> {
    let Some(table) = c else {
        return Ok(None);
    };
    let key = |k: &str| format!("ply[{i}].compaction.{k}");
    // The values carry no span of their own: the line of the table.
    let line = check.line_of(table);
    let value = |v: Option<f64>, k: &str, what: &str| match v {
        None => Err(check.missing(&key(k), what)),
        Some(x) => bound(&format!("ply.compaction.{k}")).check(check, x, line, &key(k)),
    };
    let t = table.get_ref();
    let thickness = match t.thickness {
        None => membrane_thickness,
        Some(x) => bound("ply.thickness").check(check, x, line, &key("thickness"))?,
    };
    let pressure = value(
        t.pressure,
        "pressure",
        "the pressure scale p_c [MPa] of the packing law (docs/theory.md, \"Compaction of the fabric layer\")",
    )?;
    let exponent = value(
        t.exponent,
        "exponent",
        "the packing exponent n > 1 (docs/theory.md, \"Compaction of the fabric layer\")",
    )?;
    let law = CompactionLaw::new(pressure, exponent).map_err(|e| {
        check.invalid(
            line,
            &key("exponent"),
            crate::config::readable_number(exponent),
            &e.to_string(),
        )
    })?;
    Ok(Some(PlyCompaction { thickness, law }))
}

/// A ply's bending stiffnesses `(B11, B22, B66)` [N·mm] from its `bending`
/// key: the paper's by default, `None` for `bending = false`, a table's
/// values (each defaulting to the paper's).
fn bending(
    check: &TomlChecker,
    b: &Option<Spanned<BendingRaw>>,
    i: usize,
) -> Result<Option<[f64; 3]>, ConfigError> {
    let key = |k: &str| format!("ply[{i}].{k}");
    // The stiffnesses carry no span of their own: the line of `bending`.
    let line = b.as_ref().map_or(0, |b| check.line_of(b));
    Ok(match b.as_ref().map(Spanned::get_ref) {
        None => Some(PAPER_BENDING),
        Some(b) => match b {
            BendingRaw::Switch(false) => None,
            BendingRaw::Switch(true) => Some(PAPER_BENDING),
            BendingRaw::Table(t) => {
                let value = |v: &Option<f64>, k: &str, default: f64| match v {
                    None => Ok(default),
                    Some(x) => bound(&format!("ply.bending.{k}")).check(
                        check,
                        *x,
                        line,
                        &key(&format!("bending.{k}")),
                    ),
                };
                Some([
                    value(&t.b11, "b11", PAPER_BENDING[0])?,
                    value(&t.b22, "b22", PAPER_BENDING[1])?,
                    value(&t.b66, "b66", PAPER_BENDING[2])?,
                ])
            }
        },
    })
}

/// The index of the ply a table names (`key` its `ply` key): the only ply
/// when the name is left out, an error naming the plies when it is unknown.
pub(super) fn ply_index(
    check: &TomlChecker,
    plies: &[PlySpec],
    name: &Option<String>,
    key: &str,
) -> Result<usize, ConfigError> {
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
                    quoted_names(plies.iter().map(|p| p.name.as_str()))
                ),
            )
        }),
    }
}

/// The `[ply.mesh]` keys each source takes: every other key given is
/// refused, naming these (`docs/cases.md`, "Keys that do not apply").
const RECTANGLE_KEYS: &[&str] = &[
    "shape",
    "size",
    "centre",
    "element_size",
    "cells",
    "pattern",
];
const DISK_KEYS: &[&str] = &["shape", "radius", "centre", "element_size"];
const STRIP_KEYS: &[&str] = &[
    "shape",
    "radius",
    "wrap_angle_deg",
    "tail_length",
    "width",
    "element_size",
    "centre",
];
const FILE_KEYS: &[&str] = &["file"];

/// A ply's `[ply.mesh]` table: a mesh file or a generated shape with the
/// keys it takes.
fn ply_mesh(
    check: &TomlChecker,
    m: &PlyMeshRaw,
    i: usize,
    base_dir: &Path,
) -> Result<PlyMesh, ConfigError> {
    let table = format!("ply[{i}].mesh");
    let key = |k: &str| format!("{table}.{k}");
    let positive = |v: &Option<Spanned<f64>>, k: &str, what: &str| match v {
        None => Err(check.missing(&key(k), what)),
        Some(v) => bound(&format!("ply.mesh.{k}")).spanned(check, v, &key(k)),
    };
    let given = [
        check.given("shape", &m.shape),
        check.given("size", &m.size),
        check.given("centre", &m.centre),
        check.given("element_size", &m.element_size),
        check.given("cells", &m.cells),
        check.given("pattern", &m.pattern),
        check.given("radius", &m.radius),
        check.given("width", &m.width),
        check.given("wrap_angle_deg", &m.wrap_angle_deg),
        check.given("tail_length", &m.tail_length),
        check.given("file", &m.file),
    ];
    if let Some(file) = &m.file {
        check.only_keys(&table, &given, FILE_KEYS, "a mesh file")?;
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
    let takes = match kind {
        Kind::Rectangle => RECTANGLE_KEYS,
        Kind::Disk => DISK_KEYS,
        Kind::Strip => STRIP_KEYS,
    };
    check.only_keys(
        &table,
        &given,
        takes,
        &format!("shape \"{}\"", shape.get_ref()),
    )?;
    let centre = match &m.centre {
        None => Vector3::zeros(),
        Some(c) => vector3(check, c, &key("centre"), Some(bound("ply.mesh.centre")))?,
    };
    Ok(match kind {
        Kind::Rectangle => rectangle(check, m, i, centre)?,
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
            wrap_angle_deg: positive(
                &m.wrap_angle_deg,
                "wrap_angle_deg",
                "the wrap angle in (0, 360) degrees",
            )?,
            tail_length: match &m.tail_length {
                None => 0.0,
                Some(t) => bound("ply.mesh.tail_length").spanned(check, t, &key("tail_length"))?,
            },
            width: positive(&m.width, "width", "a width > 0 mm")?,
            element_size: positive(&m.element_size, "element_size", "a length > 0 mm")?,
            centre,
        },
    })
}

/// A generated rectangle's `[ply.mesh]` keys: its size, the element size
/// or cell counts, and the cutting pattern.
fn rectangle(
    check: &TomlChecker,
    m: &PlyMeshRaw,
    i: usize,
    centre: Vector3<f64>,
) -> Result<PlyMesh, ConfigError> {
    let key = |k: &str| format!("ply[{i}].mesh.{k}");
    let size = match &m.size {
        None => return Err(check.missing(&key("size"), "the blank's extents [x, y] in mm")),
        Some(s) => {
            let v = s.get_ref();
            let b = bound("ply.mesh.size");
            if v.len() != 2 || v.iter().any(|x| !b.hard.contains(*x)) {
                return Err(check.invalid(
                    check.line_of(s),
                    &key("size"),
                    shown_list(v),
                    &b.expected(),
                ));
            }
            [v[0], v[1]]
        }
    };
    let resolution = match (&m.element_size, &m.cells) {
        (Some(h), None) => crate::mesh::generate::GridResolution::ElementSize(
            bound("ply.mesh.element_size").spanned(check, h, &key("element_size"))?,
        ),
        (None, Some(c)) => {
            let v = c.get_ref();
            let b = bound("ply.mesh.cells");
            if v.len() != 2 || v.iter().any(|n| !b.hard.contains(*n as f64)) {
                return Err(check.invalid(
                    check.line_of(c),
                    &key("cells"),
                    format!("{v:?}"),
                    &b.expected(),
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
    Ok(PlyMesh::Rectangle {
        size,
        centre,
        resolution,
        pattern,
    })
}
