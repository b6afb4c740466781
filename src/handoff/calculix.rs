//! The CalculiX deck of a hand-off (`docs/export.md`): the plies as layers
//! of solids extruded from the shell mesh, one layer per ply, with
//! element-wise orientations CalculiX honours on solids.
//!
//! CalculiX applies a `*DISTRIBUTION` of local systems only through a
//! `*SOLID SECTION` (and composite shell sections only for S8R/S6
//! elements), so the writer builds the laminate explicitly: every mesh node
//! gets one node per ply interface, `x + z_i m` with `m` the node's averaged
//! normal (the mean of the unit normals of the elements around it that
//! get solids, normalised; the node orders must agree) and `z_i` the interface's height, the plies stacked bottom
//! to top with their thicknesses and the stack's mid-surface on the mesh
//! (`z_0 = −T/2`). Ply `k` covering element `e` becomes a `C3D6` wedge
//! (triangles) or a `C3D8` brick (quads, not split) between interfaces `k`
//! and `k + 1`, written only where the ply covers the element — where a
//! ply between two others is missing, the solids above and below are not
//! connected there.
//!
//! Labels: with `stride` the smallest power of ten above every node and
//! element label of the mesh, the node of mesh node label `L` on interface
//! `i` (0 bottom) is `(i + 1)·stride + L`, and the solid of ply `k` (0
//! bottom) on element label `L` is `(k + 1)·stride + L`; [`CalculixLayout`]
//! returns them. Per ply one `*DISTRIBUTION` (solid label, point `a` = the
//! fibre, point `b = n × a`, `n` the element normal of its node order), an
//! `*ORIENTATION` that names it and a `*SOLID SECTION` with it: local axis
//! 1 is the fibre, 2 the transverse in-plane direction, 3 the normal.
//! The deck has no `*STEP`: the analyst adds boundary conditions, loads
//! and the step.

use super::common::{
    Frames, check, comment_lines, common_header, frames, invalid, real, safe_names, write_material,
};
use super::{Handoff, dot, normalized};
use std::io::{self, Write};

/// Options of [`write_calculix`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CalculixOptions {
    /// Write a node set per ply interface (`NCFORM_INTERFACE_<i>`, 0 the
    /// bottom) besides `NCFORM_BOTTOM` and `NCFORM_TOP`.
    pub interface_sets: bool,
}

impl Default for CalculixOptions {
    /// All node sets.
    fn default() -> Self {
        Self {
            interface_sets: true,
        }
    }
}

/// The labels [`write_calculix`] gave, for callers that write boundary
/// conditions and loads.
#[derive(Debug, Clone, PartialEq)]
pub struct CalculixLayout {
    /// The power of ten the labels are built with (see the module
    /// documentation).
    pub stride: u64,
    /// Per interface (`0` bottom … number of plies, top), per mesh node:
    /// the label of its extruded node, `None` where no solid uses it (not
    /// written).
    pub nodes: Vec<Vec<Option<u64>>>,
    /// Per ply, per mesh element: the label of its solid, `None` where the
    /// ply does not cover the element.
    pub solids: Vec<Vec<Option<u64>>>,
    /// Per interface, its height above the mesh along the nodal normal
    /// \[mm\].
    pub heights: Vec<f64>,
    /// Per ply, its name in the deck (`<name>_EL` element set,
    /// `<name>_DIST`, `<name>_ORI`).
    pub ply_names: Vec<String>,
    /// How many (ply, element) directions could not be used and were left
    /// out.
    pub dropped: usize,
}

/// The largest label CalculiX reads (a 32-bit signed integer).
const LABEL_MAX: u64 = i32::MAX as u64;

/// Writes `handoff` as a CalculiX (`ccx`) input deck to `out`: the plies
/// as layers of oriented solids as the module documentation describes
/// (`docs/export.md`), node sets `NCFORM_BOTTOM`, `NCFORM_TOP` (and per
/// interface on request), no `*STEP`; returns the labels written.
///
/// # Errors
/// `InvalidInput` for an inconsistent hand-off (labels, node indices,
/// thicknesses, fibre lists; more than 64 plies), a node whose elements'
/// normals cancel or an element whose normal is opposite to its
/// neighbours' (inconsistent node order: its solids would be inverted), or
/// labels beyond CalculiX's 32-bit range; otherwise the errors of `out`.
pub fn write_calculix(
    handoff: &Handoff,
    options: &CalculixOptions,
    out: &mut impl Write,
) -> io::Result<CalculixLayout> {
    check(handoff)?;
    let Frames {
        frames, dropped, ..
    } = frames(handoff);
    let names = safe_names(handoff);
    let mesh = &handoff.mesh;
    let plies = handoff.layers.len();

    let largest = mesh
        .node_labels
        .iter()
        .copied()
        .chain(mesh.elements.iter().map(|e| e.label))
        .max()
        .unwrap_or(0);
    let mut stride: u64 = 10;
    while stride <= largest {
        stride = stride
            .checked_mul(10)
            .ok_or_else(|| invalid("labels too large".into()))?;
    }
    let top_label = (plies as u64 + 2)
        .checked_mul(stride)
        .ok_or_else(|| invalid("labels too large".into()))?;
    if top_label > LABEL_MAX {
        return Err(invalid(format!(
            "labels up to {top_label} exceed CalculiX's {LABEL_MAX}: renumber the mesh"
        )));
    }

    // Interface heights.
    let total: f64 = handoff.layers.iter().map(|l| l.thickness).sum();
    let mut heights = vec![-0.5 * total];
    for l in &handoff.layers {
        let last = heights[heights.len() - 1];
        heights.push(last + l.thickness);
    }

    // Which interface nodes the solids use, and the solids' labels.
    let mut used = vec![vec![false; mesh.nodes.len()]; plies + 1];
    let mut solids = vec![vec![None; mesh.elements.len()]; plies];
    for (k, layer_frames) in frames.iter().enumerate() {
        for (e, el) in mesh.elements.iter().enumerate() {
            if layer_frames[e].is_some() {
                solids[k][e] = Some((k as u64 + 1) * stride + el.label);
                for &n in &el.nodes {
                    used[k][n] = true;
                    used[k + 1][n] = true;
                }
            }
        }
    }
    // Averaged nodal normals over the elements that get solids.
    let extruded: Vec<bool> = (0..mesh.elements.len())
        .map(|e| solids.iter().any(|s| s[e].is_some()))
        .collect();
    let mut sums = vec![[0.0f64; 3]; mesh.nodes.len()];
    let mut counts = vec![0usize; mesh.nodes.len()];
    for (e, el) in mesh.elements.iter().enumerate() {
        if !extruded[e] {
            continue;
        }
        if let Some(n) = mesh.normal(e) {
            for &i in &el.nodes {
                for c in 0..3 {
                    sums[i][c] += n[c];
                }
                counts[i] += 1;
            }
        }
    }
    let mut normals = vec![[0.0; 3]; mesh.nodes.len()];
    for i in 0..mesh.nodes.len() {
        if used.iter().any(|u| u[i]) {
            let length = dot(sums[i], sums[i]).sqrt();
            normals[i] = normalized(sums[i])
                .filter(|_| length > 1e-6 * counts[i] as f64)
                .ok_or_else(|| {
                    invalid(format!(
                        "node {}: the normals of its elements cancel (inconsistent node \
                         order?), no extrusion direction",
                        mesh.node_labels[i]
                    ))
                })?;
        }
    }
    // Every solid must extrude along its own side: its nodes' normals on
    // the side of its element normal.
    for (e, el) in mesh.elements.iter().enumerate() {
        if let (true, Some(n)) = (extruded[e], mesh.normal(e))
            && el.nodes.iter().any(|&i| dot(normals[i], n) <= 0.0)
        {
            return Err(invalid(format!(
                "element {}: its normal is opposite to its neighbours' (inconsistent node \
                 order?), its solids would be inverted",
                el.label
            )));
        }
    }
    let nodes: Vec<Vec<Option<u64>>> = used
        .iter()
        .enumerate()
        .map(|(i, u)| {
            u.iter()
                .zip(&mesh.node_labels)
                .map(|(&on, &label)| on.then_some((i as u64 + 1) * stride + label))
                .collect()
        })
        .collect();

    let mut header = common_header(handoff);
    header.push(
        "plies as layers of solids: C3D6 wedges from triangles, C3D8 bricks from quads \
         (not split), extruded along averaged nodal normals, bottom to top, the stack's \
         mid-surface on the mesh"
            .to_string(),
    );
    header.push(format!(
        "labels: stride {stride}; node of mesh node L on interface i (0 bottom) = \
         (i+1)*{stride} + L; solid of ply k (0 bottom) on element L = (k+1)*{stride} + L"
    ));
    header.push(
        "orientations: per ply *DISTRIBUTION <ply>_DIST (solid label, point a = fibre, \
         point b = n x a), *ORIENTATION <ply>_ORI, *SOLID SECTION on elset <ply>_EL; \
         local 1 = fibre, 2 = n x a, 3 = normal"
            .to_string(),
    );
    header.push(
        "node sets NCFORM_BOTTOM, NCFORM_TOP (and NCFORM_INTERFACE_<i>); where a middle \
         ply is missing the plies above and below are not connected"
            .to_string(),
    );
    header.push("this deck has NO *STEP: add boundary conditions, loads and the step".to_string());
    let uncovered = (0..mesh.elements.len())
        .filter(|&e| solids.iter().all(|s| s[e].is_none()))
        .count();
    if uncovered > 0 {
        header.push(format!(
            "{uncovered} element(s) no ply covers have no solid"
        ));
    }
    if dropped > 0 {
        header.push(format!(
            "{dropped} (ply, element) direction(s) were left out (degenerate element or \
             direction along the normal)"
        ));
    }
    for line in comment_lines("**", &header, 130) {
        writeln!(out, "{line}")?;
    }
    writeln!(out, "*HEADING")?;
    writeln!(out, "ncform hand-off, plies as oriented solids")?;

    writeln!(out, "*NODE, NSET=NCFORM_NODES")?;
    for (i, row) in nodes.iter().enumerate() {
        for (n, label) in row.iter().enumerate() {
            if let Some(label) = label {
                let x = mesh.nodes[n];
                let m = normals[n];
                let z = heights[i];
                writeln!(
                    out,
                    "{label}, {}, {}, {}",
                    real(x[0] + z * m[0]),
                    real(x[1] + z * m[1]),
                    real(x[2] + z * m[2])
                )?;
            }
        }
    }

    for (k, name) in names.iter().enumerate() {
        writeln!(out, "** ply {} `{}`", k + 1, handoff.layers[k].name)?;
        for (ty, count) in [("C3D6", 3), ("C3D8", 4)] {
            let mut lines = Vec::new();
            for (e, el) in mesh.elements.iter().enumerate() {
                let Some(label) = solids[k][e] else { continue };
                if el.nodes.len() != count {
                    continue;
                }
                let below = el.nodes.iter().filter_map(|&n| nodes[k][n]);
                let above = el.nodes.iter().filter_map(|&n| nodes[k + 1][n]);
                let labels: Vec<String> = below.chain(above).map(|l| l.to_string()).collect();
                lines.push(format!("{label}, {}", labels.join(", ")));
            }
            if !lines.is_empty() {
                writeln!(out, "*ELEMENT, TYPE={ty}")?;
                for line in lines {
                    writeln!(out, "{line}")?;
                }
            }
        }
        let labels: Vec<u64> = solids[k].iter().flatten().copied().collect();
        if labels.is_empty() {
            writeln!(out, "** ply `{}` covers no element", handoff.layers[k].name)?;
            continue;
        }
        writeln!(out, "*ELSET, ELSET={name}_EL")?;
        write_labels(out, &labels)?;
        writeln!(out, "*DISTRIBUTION, NAME={name}_DIST")?;
        writeln!(out, ", 1., 0., 0., 0., 1., 0.")?;
        for (e, f) in frames[k].iter().enumerate() {
            if let (Some(f), Some(label)) = (f, solids[k][e]) {
                writeln!(
                    out,
                    "{label}, {}, {}, {}, {}, {}, {}",
                    real(f.a[0]),
                    real(f.a[1]),
                    real(f.a[2]),
                    real(f.b[0]),
                    real(f.b[1]),
                    real(f.b[2])
                )?;
            }
        }
        writeln!(out, "*ORIENTATION, NAME={name}_ORI, SYSTEM=RECTANGULAR")?;
        writeln!(out, "{name}_DIST")?;
    }

    for (set, i) in [("NCFORM_BOTTOM", 0), ("NCFORM_TOP", plies)] {
        write_node_set(out, set, &nodes[i])?;
    }
    if options.interface_sets {
        for (i, row) in nodes.iter().enumerate() {
            write_node_set(out, &format!("NCFORM_INTERFACE_{i}"), row)?;
        }
    }

    // CalculiX reads a temperature after G23.
    write_material(out, &handoff.material, ", 0.")?;
    for (k, name) in names.iter().enumerate() {
        if solids[k].iter().any(Option::is_some) {
            writeln!(
                out,
                "*SOLID SECTION, ELSET={name}_EL, MATERIAL=NCFORM_UD, ORIENTATION={name}_ORI"
            )?;
        }
    }
    Ok(CalculixLayout {
        stride,
        nodes,
        solids,
        heights,
        ply_names: names,
        dropped,
    })
}

/// Writes labels sixteen per line.
fn write_labels(out: &mut impl Write, labels: &[u64]) -> io::Result<()> {
    for chunk in labels.chunks(16) {
        let line: Vec<String> = chunk.iter().map(|l| l.to_string()).collect();
        writeln!(out, "{}", line.join(", "))?;
    }
    Ok(())
}

/// Writes the node set `name` of the written labels in `row` (nothing when
/// there are none).
fn write_node_set(out: &mut impl Write, name: &str, row: &[Option<u64>]) -> io::Result<()> {
    let labels: Vec<u64> = row.iter().flatten().copied().collect();
    if labels.is_empty() {
        return Ok(());
    }
    writeln!(out, "*NSET, NSET={name}")?;
    write_labels(out, &labels)
}
