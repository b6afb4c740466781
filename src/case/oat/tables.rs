//! The tables of an off-axis tension test case, one parse function each:
//! `[specimen]`, `[mesh]`, `[material]` (the law and thickness, then the
//! mass once the solver is known), `[loading]` and `[output]`. Key-by-key
//! documentation: `docs/cases.md`.

use std::path::Path;

use toml::Spanned;

use super::raw::{LoadingRaw, MaterialRaw, MeshRaw, OutputRaw, SpecimenRaw};
use super::{DEFAULT_MDZ_SIZE, DEFAULT_THICKNESS, MeshSource};
use crate::case::bounds::bound;
use crate::case::explicit::{DEFAULT_AREAL_MASS, KG_PER_M2_IN_T_PER_MM2};
use crate::config::{ConfigError, TomlChecker};
use crate::material::MaterialSpec;
use crate::mesh::generate::{GridPattern, GridResolution};

/// The `[specimen]` table: width and length \[mm\], bias angle \[deg\].
pub(super) fn specimen(
    check: &TomlChecker,
    raw: &SpecimenRaw,
) -> Result<(f64, f64, f64), ConfigError> {
    let width = bound("specimen.width").spanned(check, &raw.width, "specimen.width")?;
    let length = bound("specimen.length").spanned(check, &raw.length, "specimen.length")?;
    let bias_angle_deg = bound("specimen.bias_angle_deg").spanned(
        check,
        &raw.bias_angle_deg,
        "specimen.bias_angle_deg",
    )?;
    Ok((width, length, bias_angle_deg))
}

/// The `[mesh]` table: a generated grid (element size or counts, and the
/// pattern) or a mesh file with its clamp sets.
pub(super) fn mesh(
    check: &TomlChecker,
    m: &MeshRaw,
    base_dir: &Path,
) -> Result<MeshSource, ConfigError> {
    let positive = |v: &Spanned<f64>, key: &str| bound(key).spanned(check, v, key);
    let pattern = match &m.pattern {
        None => GridPattern::RovingDiagonal,
        Some(p) => check.choice(
            p,
            "mesh.pattern",
            &[
                ("roving-diagonal", GridPattern::RovingDiagonal),
                ("both-diagonals", GridPattern::BothDiagonals),
            ],
        )?,
    };
    if let (Some(_), Some(p)) = (&m.file, &m.pattern) {
        return Err(check.invalid(
            check.line_of(p),
            "mesh.pattern",
            format!("\"{}\"", p.get_ref()),
            "no pattern with mesh.file (the file's triangles are used as they are)",
        ));
    }
    let mesh = match (&m.file, &m.element_size, &m.nx, &m.ny) {
        (Some(file), None, None, None) => MeshSource::File {
            path: base_dir.join(file.get_ref()),
            fixed_clamp_set: m.fixed_clamp_set.clone().unwrap_or_else(|| "bottom".into()),
            moving_clamp_set: m.moving_clamp_set.clone().unwrap_or_else(|| "top".into()),
        },
        (None, Some(size), None, None) => MeshSource::Generated {
            resolution: GridResolution::ElementSize(positive(size, "mesh.element_size")?),
            pattern,
        },
        (None, None, Some(nx), Some(ny)) => MeshSource::Generated {
            resolution: GridResolution::Counts {
                nx: bound("mesh.nx").count(check, nx, "mesh.nx")?,
                ny: bound("mesh.ny").count(check, ny, "mesh.ny")?,
            },
            pattern,
        },
        _ => {
            return Err(check.missing("[mesh]", "exactly one of: element_size; nx and ny; file"));
        }
    };
    if !matches!(mesh, MeshSource::File { .. })
        && (m.fixed_clamp_set.is_some() || m.moving_clamp_set.is_some())
    {
        return Err(check.invalid(
            0,
            "mesh.fixed_clamp_set / mesh.moving_clamp_set",
            "(given)".into(),
            "clamp sets only with mesh.file (generated meshes clamp 'bottom' and 'top')",
        ));
    }
    Ok(mesh)
}

/// The `[material]` table's law and thickness \[mm\], and whether the law
/// is a named set (which carries the default areal mass).
pub(super) fn material(
    check: &TomlChecker,
    raw: Option<&MaterialRaw>,
    base_dir: &Path,
) -> Result<(MaterialSpec, f64, bool), ConfigError> {
    let (params, thickness) = match raw {
        None => (None, None),
        Some(mr) => (mr.params.as_ref(), mr.thickness.as_ref()),
    };
    let named_set = params.is_none_or(|p| MaterialSpec::named_text(p.get_ref()).is_some());
    let material = match params {
        None => MaterialSpec::default_set(),
        Some(p) => load_params(check, p, "material.params", base_dir)?,
    };
    let thickness = match thickness {
        None => DEFAULT_THICKNESS,
        Some(t) => bound("material.thickness").spanned(check, t, "material.thickness")?,
    };
    Ok((material, thickness, named_set))
}

/// The `[loading]` table: the final clamp displacement \[mm\] (at most the
/// free `length`) and the sorted displacements with VTU output (the final
/// one included).
pub(super) fn loading(
    check: &TomlChecker,
    raw: &LoadingRaw,
    length: f64,
) -> Result<(f64, Vec<f64>), ConfigError> {
    // A stretch of 2 along the load axis is far beyond a fabric's range
    // (the paper's OATs end at 80 mm of 300 mm).
    let displacement = check.range(
        &raw.displacement,
        "loading.displacement",
        |x| x > 0.0 && x <= length,
        &format!(
            "a clamp displacement in (0, {}] mm (at most the free length)",
            crate::config::readable_number(length)
        ),
    )?;
    let mut output_displacements = match &raw.output_displacements {
        None => vec![],
        Some(list) => {
            let line = check.line_of(list);
            for &d in list.get_ref() {
                if !(d.is_finite() && d > 0.0 && d <= displacement) {
                    return Err(check.invalid(
                        line,
                        "loading.output_displacements",
                        crate::config::readable_number(d),
                        &format!(
                            "displacements in (0, {}] mm",
                            crate::config::readable_number(displacement)
                        ),
                    ));
                }
            }
            list.get_ref().clone()
        }
    };
    output_displacements.push(displacement);
    output_displacements.sort_by(f64::total_cmp);
    output_displacements.dedup();
    Ok((displacement, output_displacements))
}

/// The `[output]` table: the MDZ window's side and the displacement of the
/// contour maps \[mm\] (added to `output_displacements`).
pub(super) fn output(
    check: &TomlChecker,
    raw: Option<&OutputRaw>,
    displacement: f64,
    output_displacements: &mut Vec<f64>,
) -> Result<(f64, f64), ConfigError> {
    let positive = |v: &Spanned<f64>, key: &str| bound(key).spanned(check, v, key);
    let (mdz_size, contour_displacement) = match raw {
        None => (DEFAULT_MDZ_SIZE, displacement),
        Some(o) => (
            match &o.mdz_size {
                None => DEFAULT_MDZ_SIZE,
                Some(s) => positive(s, "output.mdz_size")?,
            },
            match &o.contour_displacement {
                None => displacement,
                Some(d) => check.range(
                    d,
                    "output.contour_displacement",
                    |x| x > 0.0 && x <= displacement,
                    &format!("a displacement in (0, {displacement}] mm"),
                )?,
            },
        ),
    };
    if !output_displacements.contains(&contour_displacement) {
        output_displacements.push(contour_displacement);
        output_displacements.sort_by(f64::total_cmp);
    }
    Ok((mdz_size, contour_displacement))
}

/// The `[material]` table's mass: the density [t/mm³] from `areal_mass` or
/// `density` (not both), the default areal mass for a named set, `None`
/// for a parameter file without either; finite over the `thickness`.
pub(super) fn density(
    check: &TomlChecker,
    material_raw: Option<&MaterialRaw>,
    thickness: f64,
    named_set: bool,
) -> Result<Option<f64>, ConfigError> {
    let areal_mass = material_raw.and_then(|m| m.areal_mass.as_ref());
    let given_density = material_raw.and_then(|m| m.density.as_ref());
    let density = match (areal_mass, given_density) {
        (Some(_), Some(d)) => {
            return Err(check.invalid(
                check.line_of(d),
                "material.density",
                crate::config::readable_number(*d.get_ref()),
                "either material.areal_mass [kg/m²] or material.density [t/mm³], not both",
            ));
        }
        (Some(a), None) => Some(
            bound("material.areal_mass").spanned(check, a, "material.areal_mass")?
                * KG_PER_M2_IN_T_PER_MM2
                / thickness,
        ),
        (None, Some(d)) => Some(bound("material.density").spanned(check, d, "material.density")?),
        (None, None) if named_set => Some(DEFAULT_AREAL_MASS * KG_PER_M2_IN_T_PER_MM2 / thickness),
        (None, None) => None,
    };
    if let Some(rho) = density
        && !rho.is_finite()
    {
        // A finite areal mass over a thickness of 5e-324 mm.
        let (key, line) = match material_raw.and_then(|m| m.thickness.as_ref()) {
            Some(t) => ("material.thickness", check.line_of(t)),
            None => ("material.thickness", 0),
        };
        return Err(check.invalid(
            line,
            key,
            crate::config::readable_number(thickness),
            "a thickness for which the density (areal mass / thickness) is finite",
        ));
    }
    Ok(density)
}

/// A `params` key's law (`key` names it in messages): a named set, or a
/// parameter file relative to `base_dir` whose errors are prefixed with
/// the case file's line and key (`case.toml:12: ply[0].params =
/// "fabric.toml": fabric.toml: …`).
///
/// # Errors
/// [`ConfigError::Referenced`] around the set's or file's error.
pub(crate) fn load_params(
    check: &TomlChecker,
    params: &Spanned<String>,
    key: &str,
    base_dir: &Path,
) -> Result<MaterialSpec, ConfigError> {
    let name = params.get_ref();
    let loaded = if MaterialSpec::named_text(name).is_some() {
        MaterialSpec::load(name)
    } else {
        MaterialSpec::load(&base_dir.join(name).display().to_string())
    };
    loaded.map_err(|e| check.referenced(check.line_of(params), key, &format!("\"{name}\""), e))
}
