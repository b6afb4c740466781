//! The Abaqus deck of a hand-off (`docs/export.md`): nodes, shell or
//! membrane elements, one element-wise orientation per ply
//! (`*DISTRIBUTION` of `COORD3D` pairs, `LOCATION=ELEMENT`, referenced by a
//! `*ORIENTATION, DEFINITION=COORDINATES`), and one section per layup
//! (`*SHELL SECTION` / `*MEMBRANE SECTION` for one ply, `*SHELL SECTION,
//! COMPOSITE` for several, bottom to top).
//!
//! Per element and ply the distribution gives point `a` = the fibre
//! direction (tangent to the element) and point `b = n × a` with `n` the
//! element normal of its node order ([`ShellMesh::normal`]); Abaqus
//! projects local direction 1 onto the shell surface, so material axis 1 is
//! the fibre, axis 2 the transverse in-plane direction and axis 3 the
//! normal. Elements no ply covers go into the element set
//! `NCFORM_UNCOVERED` without a section (the analyst decides).
//!
//! [`ShellMesh::normal`]: super::ShellMesh::normal

use super::Handoff;
use super::common::{
    Frames, check, comment_lines, common_header, distinct_layups, frames, invalid, layers_of, real,
    safe_names, write_material,
};
use std::io::{self, Write};

/// Which Abaqus elements the writer chooses where the mesh does not name
/// one ([`super::ShellElement::abaqus_type`] empty).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum AbaqusElement {
    /// Shells `S3R` / `S4R` (Abaqus/Standard and Explicit).
    #[default]
    Shell,
    /// Membranes `M3D3` / `M3D4` where one ply covers the element; where
    /// several do, shells `S3R` / `S4R` with a composite section (Abaqus
    /// has no composite membrane section).
    Membrane,
}

/// Options of [`write_abaqus`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct AbaqusOptions {
    /// The element family the writer chooses.
    pub element: AbaqusElement,
}

/// One section of the deck: an element set and the plies of its layup.
#[derive(Debug, Clone, PartialEq)]
pub struct AbaqusSection {
    /// The element set's name (`NCFORM_SEC_<k>`).
    pub elset: String,
    /// The layers present, as indices into [`Handoff::layers`], bottom to
    /// top.
    pub layers: Vec<usize>,
    /// `true` for a `*MEMBRANE SECTION`, `false` for a `*SHELL SECTION`.
    pub membrane: bool,
    /// The labels of its elements.
    pub elements: Vec<u64>,
}

/// What [`write_abaqus`] wrote, for callers that add to the deck.
#[derive(Debug, Clone, PartialEq)]
pub struct AbaqusLayout {
    /// Per layer, its name in the deck (letters, digits, underscores); the
    /// orientation is `<name>_ORI`, the distribution `<name>_DIST`.
    pub ply_names: Vec<String>,
    /// The sections, one per layup and element family.
    pub sections: Vec<AbaqusSection>,
    /// The labels of the elements no ply covers (`NCFORM_UNCOVERED`).
    pub uncovered: Vec<u64>,
    /// How many (ply, element) directions could not be used (degenerate
    /// element or direction along the normal) and were left out.
    pub dropped: usize,
}

/// The Abaqus type of element `e`: the mesh's own when given, else the
/// writer's choice for `options` and whether several plies cover it.
fn element_type(handoff: &Handoff, e: usize, options: &AbaqusOptions, laminate: bool) -> String {
    let el = &handoff.mesh.elements[e];
    let given: String = el
        .abaqus_type
        .chars()
        .filter(|c| c.is_ascii_alphanumeric())
        .collect::<String>()
        .to_ascii_uppercase();
    if !given.is_empty() {
        return given;
    }
    let membrane = options.element == AbaqusElement::Membrane && !laminate;
    match (membrane, el.is_triangle()) {
        (true, true) => "M3D3".into(),
        (true, false) => "M3D4".into(),
        (false, true) => "S3R".into(),
        (false, false) => "S4R".into(),
    }
}

/// Writes labels sixteen per line (Abaqus reads at most 16 per data line).
fn write_labels(out: &mut impl Write, labels: &[u64]) -> io::Result<()> {
    for chunk in labels.chunks(16) {
        let line: Vec<String> = chunk.iter().map(|l| l.to_string()).collect();
        writeln!(out, "{}", line.join(", "))?;
    }
    Ok(())
}

/// Writes `handoff` as an Abaqus input deck to `out` (model data only: no
/// `*STEP`), with one element-wise orientation per ply and one section per
/// layup as the module documentation describes (`docs/export.md`), and
/// returns what was written.
///
/// # Errors
/// `InvalidInput` for an inconsistent hand-off (labels, node indices,
/// thicknesses, fibre lists; more than 64 plies), or a mesh-given membrane
/// type on an element several plies cover; otherwise the errors of `out`.
pub fn write_abaqus(
    handoff: &Handoff,
    options: &AbaqusOptions,
    out: &mut impl Write,
) -> io::Result<AbaqusLayout> {
    check(handoff)?;
    let Frames {
        frames,
        layups,
        dropped,
    } = frames(handoff);
    let names = safe_names(handoff);
    let mesh = &handoff.mesh;

    // Sections: per distinct layup and element family.
    let mut sections: Vec<AbaqusSection> = Vec::new();
    let mut types = Vec::with_capacity(mesh.elements.len());
    let mut uncovered = Vec::new();
    for (e, el) in mesh.elements.iter().enumerate() {
        let layers = layers_of(layups[e]);
        let ty = element_type(handoff, e, options, layers.len() > 1);
        let membrane = ty.starts_with('M');
        if layers.is_empty() {
            uncovered.push(el.label);
        } else {
            if membrane && layers.len() > 1 {
                return Err(invalid(format!(
                    "element {} is a membrane ({ty}) but {} plies cover it: \
                     Abaqus has no composite membrane section",
                    el.label,
                    layers.len()
                )));
            }
            match sections
                .iter_mut()
                .find(|s| s.layers == layers && s.membrane == membrane)
            {
                Some(s) => s.elements.push(el.label),
                None => sections.push(AbaqusSection {
                    elset: String::new(),
                    layers,
                    membrane,
                    elements: vec![el.label],
                }),
            }
        }
        types.push(ty);
    }
    // Name the sections in the order of the distinct layups.
    let order = distinct_layups(&layups);
    sections.sort_by_key(|s| {
        let bits = s.layers.iter().fold(0u64, |b, &k| b | (1u64 << k));
        (
            order.iter().position(|&l| l == bits).unwrap_or(usize::MAX),
            s.membrane,
        )
    });
    for (k, s) in sections.iter_mut().enumerate() {
        s.elset = format!("NCFORM_SEC_{}", k + 1);
    }

    // Header.
    let mut header = common_header(handoff);
    header.push(
        "orientations: one *DISTRIBUTION (LOCATION=ELEMENT, COORD3D pairs) per ply: \
         a = fibre, b = n x a; *ORIENTATION <ply>_ORI, DEFINITION=COORDINATES, \
         local 1 = a projected onto the shell, 3 = shell normal"
            .to_string(),
    );
    header.push(
        "distribution-based orientations on membrane elements work in Abaqus/Standard only; \
         Abaqus/Explicit users: write shells (S3R/S4R)"
            .to_string(),
    );
    header.push(format!(
        "composite sections list the plies bottom to top along the element normal; \
         {} section(s)",
        sections.len()
    ));
    for s in &sections {
        let plies: Vec<&str> = s.layers.iter().map(|&k| names[k].as_str()).collect();
        header.push(format!(
            "  {}: {} element(s), plies {}",
            s.elset,
            s.elements.len(),
            plies.join(" / ")
        ));
    }
    if !uncovered.is_empty() {
        header.push(format!(
            "{} element(s) no ply covers are in elset NCFORM_UNCOVERED and have NO section: \
             give them one or delete them",
            uncovered.len()
        ));
    }
    if dropped > 0 {
        header.push(format!(
            "{dropped} (ply, element) direction(s) were left out (degenerate element or \
             direction along the normal)"
        ));
    }
    for line in comment_lines("**", &header, 256) {
        writeln!(out, "{line}")?;
    }

    writeln!(out, "*HEADING")?;
    writeln!(out, "ncform hand-off: {}", mesh.source.replace('*', "_"))?;

    writeln!(out, "*NODE")?;
    for (label, x) in mesh.node_labels.iter().zip(&mesh.nodes) {
        writeln!(
            out,
            "{label}, {}, {}, {}",
            real(x[0]),
            real(x[1]),
            real(x[2])
        )?;
    }

    // Elements grouped by type, in the order of first appearance.
    let mut seen_types: Vec<&str> = Vec::new();
    for ty in &types {
        if !seen_types.contains(&ty.as_str()) {
            seen_types.push(ty);
        }
    }
    for ty in seen_types {
        writeln!(out, "*ELEMENT, TYPE={ty}, ELSET=NCFORM_{ty}")?;
        for (e, el) in mesh.elements.iter().enumerate() {
            if types[e] == ty {
                let nodes: Vec<String> = el
                    .nodes
                    .iter()
                    .map(|&n| mesh.node_labels[n].to_string())
                    .collect();
                writeln!(out, "{}, {}", el.label, nodes.join(", "))?;
            }
        }
    }
    for s in &sections {
        writeln!(out, "*ELSET, ELSET={}", s.elset)?;
        write_labels(out, &s.elements)?;
    }
    if !uncovered.is_empty() {
        writeln!(out, "*ELSET, ELSET=NCFORM_UNCOVERED")?;
        write_labels(out, &uncovered)?;
    }

    // One distribution and orientation per ply.
    for (k, name) in names.iter().enumerate() {
        writeln!(out, "** ply {} `{}`", k + 1, handoff.layers[k].name)?;
        writeln!(out, "*DISTRIBUTION TABLE, NAME={name}_TAB")?;
        writeln!(out, "COORD3D, COORD3D")?;
        writeln!(
            out,
            "*DISTRIBUTION, NAME={name}_DIST, LOCATION=ELEMENT, TABLE={name}_TAB"
        )?;
        writeln!(out, ", 1., 0., 0., 0., 1., 0.")?;
        for (e, el) in mesh.elements.iter().enumerate() {
            if let Some(f) = frames[k][e] {
                writeln!(
                    out,
                    "{}, {}, {}, {}, {}, {}, {}",
                    el.label,
                    real(f.a[0]),
                    real(f.a[1]),
                    real(f.a[2]),
                    real(f.b[0]),
                    real(f.b[1]),
                    real(f.b[2])
                )?;
            }
        }
        writeln!(out, "*ORIENTATION, NAME={name}_ORI, DEFINITION=COORDINATES")?;
        writeln!(out, "{name}_DIST")?;
        writeln!(out, "3, 0.")?;
    }

    write_material(out, &handoff.material, "")?;

    for s in &sections {
        if s.layers.len() == 1 {
            let k = s.layers[0];
            let keyword = if s.membrane {
                "MEMBRANE SECTION"
            } else {
                "SHELL SECTION"
            };
            writeln!(
                out,
                "*{keyword}, ELSET={}, MATERIAL=NCFORM_UD, ORIENTATION={}_ORI",
                s.elset, names[k]
            )?;
            if s.membrane {
                writeln!(out, "{}", real(handoff.layers[k].thickness))?;
            } else {
                writeln!(out, "{}, 5", real(handoff.layers[k].thickness))?;
            }
        } else {
            writeln!(out, "*SHELL SECTION, ELSET={}, COMPOSITE", s.elset)?;
            for &k in &s.layers {
                writeln!(
                    out,
                    "{}, 3, NCFORM_UD, {}_ORI, {}",
                    real(handoff.layers[k].thickness),
                    names[k],
                    names[k]
                )?;
            }
        }
    }
    Ok(AbaqusLayout {
        ply_names: names,
        sections,
        uncovered,
        dropped,
    })
}
