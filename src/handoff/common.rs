//! What the deck writers share (`docs/export.md`): the checks of a
//! [`Handoff`] before anything is written, the material frame of each layer
//! at each element, names the targets accept, and number formats that never
//! write NaN.

use super::{Handoff, cross, dot, normalized};
use std::io;

/// The material frame of one layer at one element: `a` the fibre (the
/// given direction projected onto the element plane and normalised), `n`
/// the element normal of its node order, `b = n × a`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Frame {
    /// The unit fibre direction, tangent to the element.
    pub a: [f64; 3],
    /// The unit transverse in-plane direction `n × a`.
    pub b: [f64; 3],
    /// The unit element normal.
    pub n: [f64; 3],
}

/// The frames of all layers at all elements and what follows from them.
#[derive(Debug, Clone)]
pub(crate) struct Frames {
    /// Per layer, per element: the frame where the layer covers the
    /// element and both its direction and the element are usable.
    pub frames: Vec<Vec<Option<Frame>>>,
    /// Per element, the bit set of the layers with a frame there.
    pub layups: Vec<u64>,
    /// How many (layer, element) pairs had a direction that could not be
    /// used (a degenerate element, or a direction along its normal); the
    /// layer is then treated as absent there and the header says so.
    pub dropped: usize,
}

/// An `InvalidInput` error with `message`.
pub(crate) fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

/// Checks what every writer relies on: one label per node, positive and
/// distinct labels, finite coordinates, elements of three or four valid
/// node indices, at most 64 layers with a positive finite thickness and
/// one entry per element, and a finite positive material.
pub(crate) fn check(handoff: &Handoff) -> io::Result<()> {
    let mesh = &handoff.mesh;
    if mesh.node_labels.len() != mesh.nodes.len() {
        return Err(invalid(format!(
            "{}: {} node labels for {} nodes",
            mesh.source,
            mesh.node_labels.len(),
            mesh.nodes.len()
        )));
    }
    let mut seen = std::collections::HashSet::new();
    for (&label, x) in mesh.node_labels.iter().zip(&mesh.nodes) {
        if label == 0 || !seen.insert(label) {
            return Err(invalid(format!(
                "{}: node label {label} is zero or repeated",
                mesh.source
            )));
        }
        if x.iter().any(|v| !v.is_finite()) {
            return Err(invalid(format!(
                "{}: node {label} has a non-finite coordinate",
                mesh.source
            )));
        }
    }
    let mut seen = std::collections::HashSet::new();
    for el in &mesh.elements {
        if el.label == 0 || !seen.insert(el.label) {
            return Err(invalid(format!(
                "{}: element label {} is zero or repeated",
                mesh.source, el.label
            )));
        }
        if !(3..=4).contains(&el.nodes.len()) || el.nodes.iter().any(|&n| n >= mesh.nodes.len()) {
            return Err(invalid(format!(
                "{}: element {} needs three or four valid nodes",
                mesh.source, el.label
            )));
        }
    }
    if handoff.layers.len() > 64 {
        return Err(invalid(format!(
            "{} layers: at most 64 are written",
            handoff.layers.len()
        )));
    }
    for layer in &handoff.layers {
        if !(layer.thickness.is_finite() && layer.thickness > 0.0) {
            return Err(invalid(format!(
                "ply `{}`: thickness {} is not positive",
                layer.name, layer.thickness
            )));
        }
        if layer.fibre.len() != mesh.elements.len() {
            return Err(invalid(format!(
                "ply `{}`: {} fibre entries for {} elements",
                layer.name,
                layer.fibre.len(),
                mesh.elements.len()
            )));
        }
    }
    let m = &handoff.material;
    let positive = [m.e1, m.e2, m.g12, m.g23, m.density];
    if positive.iter().any(|v| !(v.is_finite() && *v > 0.0))
        || !(m.nu12.is_finite() && m.nu23.is_finite())
    {
        return Err(invalid(format!("material {m:?}: not finite and positive")));
    }
    Ok(())
}

/// The frame of a fibre `a` on element `e` of the hand-off's mesh, `None`
/// for a degenerate element or a direction without a tangent part.
fn frame(handoff: &Handoff, e: usize, a: [f64; 3]) -> Option<Frame> {
    let n = handoff.mesh.normal(e)?;
    if a.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let along = dot(a, n);
    let a = normalized([
        a[0] - along * n[0],
        a[1] - along * n[1],
        a[2] - along * n[2],
    ])?;
    let b = normalized(cross(n, a))?;
    Some(Frame { a, b, n })
}

/// The frames of every layer at every element (after [`check`]).
pub(crate) fn frames(handoff: &Handoff) -> Frames {
    let count = handoff.mesh.elements.len();
    let mut dropped = 0;
    let frames: Vec<Vec<Option<Frame>>> = handoff
        .layers
        .iter()
        .map(|layer| {
            (0..count)
                .map(|e| {
                    let a = layer.fibre.get(e).copied().flatten()?;
                    let f = frame(handoff, e, a);
                    if f.is_none() {
                        dropped += 1;
                    }
                    f
                })
                .collect()
        })
        .collect();
    let layups = (0..count)
        .map(|e| {
            frames
                .iter()
                .enumerate()
                .filter(|(_, f)| f[e].is_some())
                .fold(0u64, |bits, (k, _)| bits | (1u64 << k))
        })
        .collect();
    Frames {
        frames,
        layups,
        dropped,
    }
}

/// The distinct non-empty layups in order of first appearance.
pub(crate) fn distinct_layups(layups: &[u64]) -> Vec<u64> {
    let mut out: Vec<u64> = Vec::new();
    for &l in layups {
        if l != 0 && !out.contains(&l) {
            out.push(l);
        }
    }
    out
}

/// The layers of a layup bit set, bottom to top.
pub(crate) fn layers_of(layup: u64) -> Vec<usize> {
    (0..64).filter(|k| layup & (1u64 << k) != 0).collect()
}

/// Ply names the keyword formats accept: upper-case letters, digits and
/// underscores, starting with a letter (`PLY_` is put in front otherwise),
/// at most 40 characters, distinct (a repeated name gets `_<k>`, the
/// 1-based layer number, appended).
pub(crate) fn safe_names(handoff: &Handoff) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for (k, layer) in handoff.layers.iter().enumerate() {
        let mut s: String = layer
            .name
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() {
                    c.to_ascii_uppercase()
                } else {
                    '_'
                }
            })
            .collect();
        if !s.starts_with(|c: char| c.is_ascii_alphabetic()) {
            s = format!("PLY_{s}");
        }
        s.truncate(40);
        if names.contains(&s) {
            s = format!("{s}_{}", k + 1);
        }
        names.push(s);
    }
    names
}

/// A real in free format with ten significant digits (`1.350000000e5`),
/// for the comma-separated formats; `0.` for zero.
pub(crate) fn real(x: f64) -> String {
    if x == 0.0 {
        "0.".to_string()
    } else {
        format!("{x:.9e}")
    }
}

/// The lines of the hand-off's header and the writer's conventions as
/// comment lines with `prefix`, each cut to at most `width` characters
/// (longer lines continue on the next comment line).
pub(crate) fn comment_lines(prefix: &str, lines: &[String], width: usize) -> Vec<String> {
    let room = width.saturating_sub(prefix.len() + 1).max(1);
    let mut out = Vec::new();
    for line in lines {
        let chars: Vec<char> = line.chars().collect();
        if chars.is_empty() {
            out.push(prefix.to_string());
            continue;
        }
        for chunk in chars.chunks(room) {
            out.push(format!("{prefix} {}", chunk.iter().collect::<String>()));
        }
    }
    out
}

/// The provenance lines, the units and the material note every deck
/// starts with.
pub(crate) fn common_header(handoff: &Handoff) -> Vec<String> {
    let mut lines = vec!["ncform hand-off of a formed part (see docs/export.md)".to_string()];
    lines.extend(handoff.header.iter().cloned());
    lines.push(format!("mesh: {}", handoff.mesh.source));
    lines.push("units: mm, N, MPa, tonne/mm^3, s".to_string());
    let m = &handoff.material;
    lines.push(
        "material NCFORM_UD is a PLACEHOLDER to replace (OrthotropicMaterial, a cured UD \
         carbon/epoxy): the forming law says nothing of the cured part"
            .to_string(),
    );
    lines.push(format!(
        "  E1 {:.1} MPa, E2 = E3 {:.1} MPa, nu12 = nu13 {}, nu23 {}, G12 = G13 {:.1} MPa, \
         G23 {:.1} MPa, density {:e} t/mm^3",
        m.e1, m.e2, m.nu12, m.nu23, m.g12, m.g23, m.density
    ));
    lines.push(
        "fibre = material axis 1, the given fibre direction a projected onto the element \
         plane; axis 2 = n x a; axis 3 = n, the element normal of its node order \
         ((x2-x1)x(x3-x1), quads (x3-x1)x(x4-x2))"
            .to_string(),
    );
    lines
}

/// The placeholder material `NCFORM_UD` as Abaqus and CalculiX read it:
/// `*MATERIAL`, `*ELASTIC, TYPE=ENGINEERING CONSTANTS` (`E1, E2, E3, ν12,
/// ν13, ν23, G12, G13` / `G23` then `after_g23`, CalculiX's temperature)
/// and `*DENSITY`, after a comment saying it is to be replaced.
pub(crate) fn write_material(
    out: &mut impl std::io::Write,
    m: &super::OrthotropicMaterial,
    after_g23: &str,
) -> io::Result<()> {
    writeln!(
        out,
        "** PLACEHOLDER material: replace with the cured laminate's"
    )?;
    writeln!(out, "*MATERIAL, NAME=NCFORM_UD")?;
    writeln!(out, "*ELASTIC, TYPE=ENGINEERING CONSTANTS")?;
    writeln!(
        out,
        "{}, {}, {}, {}, {}, {}, {}, {}",
        real(m.e1),
        real(m.e2),
        real(m.e2),
        real(m.nu12),
        real(m.nu12),
        real(m.nu23),
        real(m.g12),
        real(m.g12)
    )?;
    writeln!(out, "{}{after_g23}", real(m.g23))?;
    writeln!(out, "*DENSITY")?;
    writeln!(out, "{}", real(m.density))
}
