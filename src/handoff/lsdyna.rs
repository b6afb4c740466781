//! The LS-DYNA keyword deck of a hand-off (`docs/export.md`), in the fixed
//! column format (80 columns; integers in 8- or 10-character fields, reals
//! in 10- or 16-character fields, right-aligned).
//!
//! The placeholder material is a `*MAT_ORTHOTROPIC_ELASTIC` (MAT_002) with
//! `AOPT = 0`: the material axes follow each element's own nodes, turned by
//! the element's angle. The angle `β` of a ply at an element is measured in
//! the element plane from the element's 1–2 side (`x₂ − x₁` projected onto
//! the plane) to the fibre `a`, positive about the normal `n` of the node
//! order (for quads the normal of the diagonals, [`ShellMesh::normal`]), in
//! degrees, reduced to (−90°, 90°] (a fibre is a line). Elements covered by
//! one ply are written as `*ELEMENT_SHELL_BETA` (the angle in columns
//! 65–80 of the second card), elements covered by several as
//! `*ELEMENT_SHELL_COMPOSITE` (per present ply `MID, THICK, B`, bottom to
//! top). `*CONTROL_ACCURACY` sets `INN = 1` (invariant node numbering off)
//! so that the element's 1–2 side is the reference the angles were
//! computed from. Each layup is one `*PART` with its `*SECTION_SHELL`;
//! elements no ply covers form a last part without angles.
//!
//! [`ShellMesh::normal`]: super::ShellMesh::normal

use super::common::{
    Frames, check, comment_lines, common_header, distinct_layups, frames, invalid, layers_of,
    safe_names,
};
use super::{Handoff, cross, dot, normalized, sub};
use std::io::{self, Write};

/// Options of [`write_lsdyna`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LsDynaOptions {
    /// The shell formulation `ELFORM` of every `*SECTION_SHELL` (2,
    /// Belytschko–Tsay, by default; 16 for fully integrated shells).
    pub elform: u32,
}

impl Default for LsDynaOptions {
    /// `ELFORM = 2`.
    fn default() -> Self {
        Self { elform: 2 }
    }
}

/// One part of the deck.
#[derive(Debug, Clone, PartialEq)]
pub struct LsDynaPart {
    /// Its part, section id (the same number).
    pub pid: u64,
    /// The layers present, as indices into [`Handoff::layers`], bottom to
    /// top (empty for the part of uncovered elements).
    pub layers: Vec<usize>,
    /// The labels of its elements.
    pub elements: Vec<u64>,
}

/// What [`write_lsdyna`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct LsDynaLayout {
    /// The parts, one per layup, then (if any) the one of uncovered
    /// elements.
    pub parts: Vec<LsDynaPart>,
    /// The material id of the placeholder material (1).
    pub mid: u64,
    /// How many (ply, element) directions could not be used and were left
    /// out.
    pub dropped: usize,
}

/// The angle β \[degrees, (−90, 90]\] of fibre `a` on element `e`: from
/// the element's 1–2 side projected onto the plane of normal `n` to `a`,
/// positive about `n`; `None` when nodes 1 and 2 coincide.
pub fn beta_degrees(handoff: &Handoff, e: usize, a: [f64; 3], n: [f64; 3]) -> Option<f64> {
    let mesh = &handoff.mesh;
    let el = &mesh.elements[e];
    let side = sub(mesh.nodes[el.nodes[1]], mesh.nodes[el.nodes[0]]);
    let along = dot(side, n);
    let e1 = normalized([
        side[0] - along * n[0],
        side[1] - along * n[1],
        side[2] - along * n[2],
    ])?;
    let beta = dot(cross(e1, a), n).atan2(dot(e1, a)).to_degrees();
    Some(reduce_line_angle(beta))
}

/// `angle` \[degrees\] reduced to (−90, 90] by multiples of 180°.
pub fn reduce_line_angle(angle: f64) -> f64 {
    let mut b = angle % 180.0;
    if b > 90.0 {
        b -= 180.0;
    } else if b <= -90.0 {
        b += 180.0;
    }
    b
}

/// An integer right-aligned in `width` columns.
///
/// # Errors
/// `InvalidData` when it needs more columns.
pub fn fixed_int(value: u64, width: usize) -> io::Result<String> {
    let s = format!("{value:>width$}");
    if s.len() > width {
        return Err(io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{value} does not fit {width} columns"),
        ));
    }
    Ok(s)
}

/// A real right-aligned in `width` columns, leaving the first column
/// blank: of the decimal (`-89.1234567`) and exponent (`1.2345678e-9`)
/// forms that fit, the one closest to `value`; always with a decimal
/// point, never NaN.
///
/// # Errors
/// `InvalidData` for a non-finite value or one that fits in no form.
pub fn fixed_real(value: f64, width: usize) -> io::Result<String> {
    let room = width.saturating_sub(1);
    let bad = || {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("{value} cannot be written in {width} columns"),
        )
    };
    if !value.is_finite() {
        return Err(bad());
    }
    if value == 0.0 {
        return Ok(format!("{:>width$}", "0.0"));
    }
    let mut best: Option<(f64, String)> = None;
    let mut consider = |s: String| {
        if s.len() <= room
            && let Ok(v) = s.parse::<f64>()
        {
            let err = (v - value).abs();
            if best.as_ref().is_none_or(|(e, _)| err < *e) {
                best = Some((err, s));
            }
        }
    };
    if let Some(s) = (1..=room)
        .rev()
        .map(|p| format!("{value:.p$}"))
        .find(|s| s.len() <= room)
    {
        consider(s);
    }
    if let Some(s) = (0..=room)
        .rev()
        .map(|p| {
            let s = format!("{value:.p$e}");
            // `1e5` has no decimal point: write `1.e5`.
            if s.contains('.') {
                s
            } else {
                s.replacen('e', ".e", 1)
            }
        })
        .find(|s| s.len() <= room)
    {
        consider(s);
    }
    match best {
        // A form that rounds a small value to zero (or an exponent that
        // leaves no digits) loses it: keep what is within 0.5 %, the
        // rounding of three significant digits (`-2.23e-14` in ten
        // columns).
        Some((err, s)) if err <= 5e-3 * value.abs() => Ok(format!("{s:>width$}")),
        _ => Err(bad()),
    }
}

/// Writes `handoff` as an LS-DYNA keyword deck to `out` (model data only:
/// no control cards beyond `*CONTROL_ACCURACY`, no loads), with each
/// ply's fibre angle per element as the module documentation describes
/// (`docs/export.md`), and returns the parts written.
///
/// # Errors
/// `InvalidInput` for an inconsistent hand-off (labels, node indices,
/// thicknesses, fibre lists; more than 64 plies) or an element whose
/// nodes 1 and 2 coincide; `InvalidData` for a label or number that does
/// not fit its field; otherwise the errors of `out`.
pub fn write_lsdyna(
    handoff: &Handoff,
    options: &LsDynaOptions,
    out: &mut impl Write,
) -> io::Result<LsDynaLayout> {
    check(handoff)?;
    let Frames {
        frames,
        layups,
        dropped,
    } = frames(handoff);
    let names = safe_names(handoff);
    let mesh = &handoff.mesh;
    const MID: u64 = 1;

    let order = distinct_layups(&layups);
    let mut parts: Vec<LsDynaPart> = order
        .iter()
        .enumerate()
        .map(|(k, &l)| LsDynaPart {
            pid: k as u64 + 1,
            layers: layers_of(l),
            elements: Vec::new(),
        })
        .collect();
    let mut uncovered = Vec::new();
    let mut part_of = vec![usize::MAX; mesh.elements.len()];
    for (e, el) in mesh.elements.iter().enumerate() {
        match order.iter().position(|&l| l == layups[e]) {
            Some(p) => {
                parts[p].elements.push(el.label);
                part_of[e] = p;
            }
            None => uncovered.push(el.label),
        }
    }
    let uncovered_pid = parts.len() as u64 + 1;
    if !uncovered.is_empty() {
        parts.push(LsDynaPart {
            pid: uncovered_pid,
            layers: Vec::new(),
            elements: uncovered.clone(),
        });
    }
    // Angles per (element, layer), computed before anything is written.
    let mut betas: Vec<Vec<(usize, f64)>> = Vec::with_capacity(mesh.elements.len());
    for (e, el) in mesh.elements.iter().enumerate() {
        let mut row = Vec::new();
        for (k, layer_frames) in frames.iter().enumerate() {
            if let Some(f) = layer_frames[e] {
                let beta = beta_degrees(handoff, e, f.a, f.n).ok_or_else(|| {
                    invalid(format!(
                        "element {}: nodes 1 and 2 coincide, no angle reference",
                        el.label
                    ))
                })?;
                row.push((k, beta));
            }
        }
        betas.push(row);
    }

    let mut header = common_header(handoff);
    header.push(
        "angles: MAT_002 AOPT = 0; per element BETA / B [deg] in the element plane from the \
         element's 1-2 side (x2 - x1 projected onto the plane) to the fibre, positive about \
         the normal of the node order, in (-90, 90]; INN = 1 (invariant numbering off)"
            .to_string(),
    );
    header.push(
        "one ply: *ELEMENT_SHELL_BETA (BETA in columns 65-80); several: \
         *ELEMENT_SHELL_COMPOSITE (MID, THICK, B per present ply, bottom to top)"
            .to_string(),
    );
    for p in &parts {
        if p.layers.is_empty() {
            header.push(format!(
                "  part {}: {} element(s) NO ply covers, *ELEMENT_SHELL without angles, \
                 thickness of the thinnest ply as a placeholder: give them a section or \
                 delete them",
                p.pid,
                p.elements.len()
            ));
        } else {
            let plies: Vec<&str> = p.layers.iter().map(|&k| names[k].as_str()).collect();
            header.push(format!(
                "  part {}: {} element(s), plies {}",
                p.pid,
                p.elements.len(),
                plies.join(" / ")
            ));
        }
    }
    if dropped > 0 {
        header.push(format!(
            "{dropped} (ply, element) direction(s) were left out (degenerate element or \
             direction along the normal)"
        ));
    }

    writeln!(out, "*KEYWORD")?;
    // Comments in ASCII (a `°` or `—` would take more than one column).
    let header: Vec<String> = header
        .iter()
        .map(|l| {
            l.chars()
                .map(|c| if c.is_ascii() { c } else { '?' })
                .collect()
        })
        .collect();
    for line in comment_lines("$", &header, 80) {
        writeln!(out, "{line}")?;
    }
    writeln!(out, "*CONTROL_ACCURACY")?;
    // OSU = 0 (off), INN = 1 (invariant node numbering off); the other
    // fields keep their defaults.
    writeln!(out, "$#     OSU       INN")?;
    writeln!(out, "{}{}", fixed_int(0, 10)?, fixed_int(1, 10)?)?;

    let m = &handoff.material;
    writeln!(out, "*MAT_ORTHOTROPIC_ELASTIC")?;
    writeln!(out, "$ PLACEHOLDER cured UD carbon/epoxy: replace")?;
    writeln!(
        out,
        "$#     MID        RO        EA        EB        EC      PRBA      PRCA      PRCB"
    )?;
    // PRBA = nu_ba = nu12 E2 / E1 (the minor ratio), PRCA likewise, PRCB = nu23.
    let minor = m.nu12 * m.e2 / m.e1;
    writeln!(
        out,
        "{}{}{}{}{}{}{}{}",
        fixed_int(MID, 10)?,
        fixed_real(m.density, 10)?,
        fixed_real(m.e1, 10)?,
        fixed_real(m.e2, 10)?,
        fixed_real(m.e2, 10)?,
        fixed_real(minor, 10)?,
        fixed_real(minor, 10)?,
        fixed_real(m.nu23, 10)?
    )?;
    writeln!(out, "$#     GAB       GBC       GCA      AOPT")?;
    writeln!(
        out,
        "{}{}{}{}",
        fixed_real(m.g12, 10)?,
        fixed_real(m.g23, 10)?,
        fixed_real(m.g12, 10)?,
        fixed_real(0.0, 10)?
    )?;
    writeln!(
        out,
        "$#      XP        YP        ZP        A1        A2        A3"
    )?;
    writeln!(out, "{}", fixed_real(0.0, 10)?.repeat(6))?;
    writeln!(
        out,
        "$#      V1        V2        V3        D1        D2        D3      BETA"
    )?;
    writeln!(out, "{}", fixed_real(0.0, 10)?.repeat(7))?;

    let thinnest = handoff
        .layers
        .iter()
        .map(|l| l.thickness)
        .fold(f64::INFINITY, f64::min);
    for p in &parts {
        let title = if p.layers.is_empty() {
            "NCFORM_UNCOVERED (no ply)".to_string()
        } else {
            let plies: Vec<&str> = p.layers.iter().map(|&k| names[k].as_str()).collect();
            format!("NCFORM layup {}", plies.join("/"))
        };
        let title: String = title.chars().take(70).collect();
        writeln!(out, "*PART")?;
        writeln!(out, "{title}")?;
        writeln!(out, "$#     PID     SECID       MID")?;
        writeln!(
            out,
            "{}{}{}",
            fixed_int(p.pid, 10)?,
            fixed_int(p.pid, 10)?,
            fixed_int(MID, 10)?
        )?;
        let total: f64 = if p.layers.is_empty() {
            if thinnest.is_finite() { thinnest } else { 1.0 }
        } else {
            p.layers.iter().map(|&k| handoff.layers[k].thickness).sum()
        };
        let composite = p.layers.len() > 1;
        let nip = if composite { p.layers.len() as u64 } else { 2 };
        writeln!(out, "*SECTION_SHELL")?;
        writeln!(
            out,
            "$#   SECID    ELFORM      SHRF       NIP     PROPT   QR/IRID     ICOMP     SETYP"
        )?;
        writeln!(
            out,
            "{}{}{}{}{}{}{}{}",
            fixed_int(p.pid, 10)?,
            fixed_int(u64::from(options.elform), 10)?,
            fixed_real(5.0 / 6.0, 10)?,
            fixed_int(nip, 10)?,
            fixed_int(1, 10)?,
            fixed_int(0, 10)?,
            fixed_int(u64::from(composite), 10)?,
            fixed_int(1, 10)?
        )?;
        writeln!(out, "$#      T1        T2        T3        T4")?;
        writeln!(out, "{}", fixed_real(total, 10)?.repeat(4))?;
        if composite {
            // The angles per integration point; the element cards give the
            // per-element angles.
            writeln!(out, "$#      B1        B2 ...")?;
            for chunk in p.layers.chunks(8) {
                writeln!(out, "{}", fixed_real(0.0, 10)?.repeat(chunk.len()))?;
            }
        }
    }

    writeln!(out, "*NODE")?;
    writeln!(
        out,
        "$#   NID               X               Y               Z      TC      RC"
    )?;
    for (label, x) in mesh.node_labels.iter().zip(&mesh.nodes) {
        writeln!(
            out,
            "{}{}{}{}{}{}",
            fixed_int(*label, 8)?,
            fixed_real(x[0], 16)?,
            fixed_real(x[1], 16)?,
            fixed_real(x[2], 16)?,
            fixed_int(0, 8)?,
            fixed_int(0, 8)?
        )?;
    }

    let card1 = |e: usize, pid: u64| -> io::Result<String> {
        let el = &mesh.elements[e];
        let n = |k: usize| mesh.node_labels[el.nodes[k.min(el.nodes.len() - 1)]];
        Ok(format!(
            "{}{}{}{}{}{}",
            fixed_int(el.label, 8)?,
            fixed_int(pid, 8)?,
            fixed_int(n(0), 8)?,
            fixed_int(n(1), 8)?,
            fixed_int(n(2), 8)?,
            fixed_int(n(3), 8)?
        ))
    };
    let single: Vec<usize> = (0..mesh.elements.len())
        .filter(|&e| betas[e].len() == 1)
        .collect();
    if !single.is_empty() {
        writeln!(out, "*ELEMENT_SHELL_BETA")?;
        writeln!(out, "$#   EID     PID      N1      N2      N3      N4")?;
        writeln!(
            out,
            "$#         THIC1           THIC2           THIC3           THIC4            BETA"
        )?;
        for &e in &single {
            let pid = parts[part_of[e]].pid;
            let (k, beta) = betas[e][0];
            writeln!(out, "{}", card1(e, pid)?)?;
            let t = fixed_real(handoff.layers[k].thickness, 16)?;
            writeln!(out, "{}{}", t.repeat(4), fixed_real(beta, 16)?)?;
        }
    }
    let several: Vec<usize> = (0..mesh.elements.len())
        .filter(|&e| betas[e].len() > 1)
        .collect();
    if !several.is_empty() {
        writeln!(out, "*ELEMENT_SHELL_COMPOSITE")?;
        writeln!(out, "$#   EID     PID      N1      N2      N3      N4")?;
        writeln!(
            out,
            "$#    MID1    THICK1        B1                MID2    THICK2        B2"
        )?;
        for &e in &several {
            let pid = parts[part_of[e]].pid;
            writeln!(out, "{}", card1(e, pid)?)?;
            for pair in betas[e].chunks(2) {
                let mut line = String::new();
                for &(k, beta) in pair {
                    line.push_str(&fixed_int(MID, 10)?);
                    line.push_str(&fixed_real(handoff.layers[k].thickness, 10)?);
                    line.push_str(&fixed_real(beta, 10)?);
                    line.push_str(&" ".repeat(10));
                }
                writeln!(out, "{}", line.trim_end())?;
            }
        }
    }
    if !uncovered.is_empty() {
        writeln!(out, "*ELEMENT_SHELL")?;
        writeln!(out, "$#   EID     PID      N1      N2      N3      N4")?;
        for e in (0..mesh.elements.len()).filter(|&e| layups[e] == 0) {
            writeln!(out, "{}", card1(e, uncovered_pid)?)?;
        }
    }
    writeln!(out, "*END")?;
    Ok(LsDynaLayout {
        parts,
        mid: MID,
        dropped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reals_fit_their_fields_and_keep_precision() {
        for &v in &[
            0.0,
            1.0,
            -1.0,
            0.3,
            135_000.0,
            1.55e-9,
            -89.123_456_789,
            90.0,
            1.234_567_890_123e12,
            -9.87654321e-15,
            5.0 / 6.0,
        ] {
            for width in [10, 16] {
                let s = fixed_real(v, width).unwrap();
                assert_eq!(s.len(), width, "{v} in {width}: `{s}`");
                assert!(s.starts_with(' '), "`{s}`");
                assert!(s.contains('.'), "`{s}`");
                let back: f64 = s.trim().parse().unwrap();
                let tol = if width == 16 { 1e-8 } else { 1e-3 };
                assert!((back - v).abs() <= tol * v.abs(), "{v} -> `{s}`");
            }
        }
        assert!(fixed_real(f64::NAN, 16).is_err());
        assert!(fixed_real(f64::INFINITY, 10).is_err());
        assert!(fixed_int(123_456_789, 8).is_err());
        assert_eq!(fixed_int(42, 8).unwrap(), "      42");
    }

    #[test]
    fn line_angles_reduce_to_the_half_open_range() {
        assert_eq!(reduce_line_angle(90.0), 90.0);
        assert_eq!(reduce_line_angle(-90.0), 90.0);
        assert!((reduce_line_angle(135.0) + 45.0).abs() < 1e-12);
        assert!((reduce_line_angle(-135.0) - 45.0).abs() < 1e-12);
        assert!((reduce_line_angle(270.0) - 90.0).abs() < 1e-12);
        assert!((reduce_line_angle(-179.0) - 1.0).abs() < 1e-12);
    }
}
