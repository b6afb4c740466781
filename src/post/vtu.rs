//! VTK XML files for ParaView (and meshio): one triangle mesh per `.vtu`
//! file (`UnstructuredGrid`, version 0.1, ASCII data arrays) and a `.pvd`
//! collection that lists the files of a run with their times.
//!
//! Values are written with full `f64` round-trip precision (Rust's `{:?}`
//! formatting: `0.1`, `1e-7`, `-2.5e300`), which VTK's and numpy's readers
//! parse exactly. Everything is validated before the file is created, so an
//! invalid piece leaves no file behind and no file ever holds a NaN.
//!
//! Layout of a `.vtu` file:
//!
//! ```text
//! <?xml version="1.0"?>
//! <!-- comment lines (what the file is, units) -->
//! <VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
//!   <UnstructuredGrid><Piece NumberOfPoints=".." NumberOfCells="..">
//!     <PointData> .. </PointData> <CellData> .. </CellData>
//!     <Points> Float64 × 3 </Points>
//!     <Cells> connectivity (Int64), offsets (Int64), types (UInt8, 5 = VTK_TRIANGLE) </Cells>
//!   </Piece></UnstructuredGrid>
//! </VTKFile>
//! ```

use std::collections::HashSet;
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

/// VTK cell type of a linear triangle.
const VTK_TRIANGLE: u8 = 5;

/// Suffix appended to the name of a [`FieldData::SymTensor2`] array, so a
/// reader sees the component order in the name.
pub const SYM_TENSOR2_SUFFIX: &str = "_xx_yy_xy";

/// The values of one field, one entry per point or per cell.
#[derive(Debug, Clone, Copy)]
pub enum FieldData<'a> {
    /// One number per entry (`Float64`; no `NumberOfComponents` attribute,
    /// VTK's default of one, so meshio reads a 1-D array).
    Scalar(&'a [f64]),
    /// A 3-vector per entry (`Float64`, three components), e.g. the
    /// displacement.
    Vector3(&'a [[f64; 3]]),
    /// A symmetric in-plane tensor per entry as `[xx, yy, xy]`: written as a
    /// three-component `Float64` array named `name` + [`SYM_TENSOR2_SUFFIX`]
    /// with `ComponentName0..2` = `xx`, `yy`, `xy` (the tensor component
    /// `xy`, not the engineering shear `2·xy`).
    SymTensor2(&'a [[f64; 3]]),
    /// One integer per entry (`Int32`, one component like a scalar), e.g. a
    /// region or contact flag.
    Int(&'a [i32]),
}

impl FieldData<'_> {
    fn len(&self) -> usize {
        match self {
            FieldData::Scalar(v) => v.len(),
            FieldData::Vector3(v) | FieldData::SymTensor2(v) => v.len(),
            FieldData::Int(v) => v.len(),
        }
    }

    /// The index of the first entry holding a NaN or infinity.
    fn first_non_finite(&self) -> Option<usize> {
        match self {
            FieldData::Scalar(v) => v.iter().position(|x| !x.is_finite()),
            FieldData::Vector3(v) | FieldData::SymTensor2(v) => {
                v.iter().position(|x| x.iter().any(|c| !c.is_finite()))
            }
            FieldData::Int(_) => None,
        }
    }
}

/// A named field.
#[derive(Debug, Clone, Copy)]
pub struct Field<'a> {
    /// The array name shown in ParaView (with its unit, e.g. `u [mm]`, if
    /// wanted; any text, it is XML-escaped).
    pub name: &'a str,
    /// The values.
    pub data: FieldData<'a>,
}

/// One triangle mesh with its fields: the content of a `.vtu` file.
#[derive(Debug, Clone)]
pub struct VtuPiece<'a> {
    /// Node coordinates (deformed) \[mm\].
    pub points: &'a [[f64; 3]],
    /// Triangles as indices into `points`.
    pub triangles: &'a [[usize; 3]],
    /// Fields with one entry per point, e.g. the displacement \[mm\].
    pub point_fields: Vec<Field<'a>>,
    /// Fields with one entry per triangle, e.g. strains, the shear angle,
    /// stresses.
    pub cell_fields: Vec<Field<'a>>,
    /// Lines written as XML comments at the top of the file: what it holds
    /// and its units (e.g. `units: mm, N, MPa`).
    pub comment: Vec<String>,
}

/// One file of a time series.
#[derive(Debug, Clone, PartialEq)]
pub struct PvdEntry {
    /// The time (or load factor) of the file.
    pub time: f64,
    /// The `.vtu` file, relative to the `.pvd` file.
    pub file: String,
    /// The part: files of the same time with different parts are shown
    /// together (a ply and its tools); 0 for a single body.
    pub part: usize,
}

fn invalid(msg: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, msg)
}

/// Escapes text for an XML attribute value or text node.
fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\n' | '\r' | '\t' => out.push(' '),
            c if (c as u32) < 0x20 => {}
            c => out.push(c),
        }
    }
    out
}

/// Makes a line safe inside `<!-- … -->`: XML forbids `--` in a comment and
/// a comment text ending in `-`.
fn comment_text(s: &str) -> String {
    let mut out: String = s
        .chars()
        .filter(|&c| c == '\t' || (c as u32) >= 0x20)
        .collect();
    while out.contains("--") {
        out = out.replace("--", "- -");
    }
    if out.ends_with('-') {
        out.push(' ');
    }
    out
}

fn write_comments(out: &mut impl Write, lines: &[String]) -> io::Result<()> {
    for block in lines {
        for line in block.lines() {
            writeln!(out, "<!-- {} -->", comment_text(line))?;
        }
    }
    Ok(())
}

/// Checks one group of fields: names present and unique, lengths equal to
/// `expected`, values finite.
fn check_fields(
    path: &Path,
    fields: &[Field],
    expected: usize,
    what: &str,
    unit: &str,
) -> io::Result<()> {
    let mut seen = HashSet::new();
    for f in fields {
        if f.name.is_empty() {
            return Err(invalid(format!(
                "{}: a {what} field has an empty name",
                path.display()
            )));
        }
        if !seen.insert(f.name) {
            return Err(invalid(format!(
                "{}: {what} field \"{}\" is given twice",
                path.display(),
                f.name
            )));
        }
        if f.data.len() != expected {
            return Err(invalid(format!(
                "{}: {what} field \"{}\" has {} values for {expected} {unit}",
                path.display(),
                f.name,
                f.data.len()
            )));
        }
        if let Some(i) = f.data.first_non_finite() {
            return Err(invalid(format!(
                "{}: {what} field \"{}\" is not finite at index {i}",
                path.display(),
                f.name
            )));
        }
    }
    Ok(())
}

fn validate(path: &Path, piece: &VtuPiece) -> io::Result<()> {
    let n = piece.points.len();
    if let Some(i) = piece
        .points
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        return Err(invalid(format!(
            "{}: point {i} is not finite",
            path.display()
        )));
    }
    for (e, t) in piece.triangles.iter().enumerate() {
        if let Some(&k) = t.iter().find(|&&k| k >= n) {
            return Err(invalid(format!(
                "{}: triangle {e} refers to point {k}, but there are {n} points",
                path.display()
            )));
        }
    }
    check_fields(path, &piece.point_fields, n, "point", "points")?;
    check_fields(
        path,
        &piece.cell_fields,
        piece.triangles.len(),
        "cell",
        "cells",
    )
}

/// Writes `values` in lines of `per_line` items.
fn write_values<T>(
    out: &mut impl Write,
    values: impl Iterator<Item = T>,
    per_line: usize,
    fmt: impl Fn(&mut dyn Write, T) -> io::Result<()>,
) -> io::Result<()> {
    for (i, v) in values.enumerate() {
        if i % per_line == 0 {
            if i > 0 {
                writeln!(out)?;
            }
            write!(out, "          ")?;
        } else {
            write!(out, " ")?;
        }
        fmt(out, v)?;
    }
    writeln!(out)
}

fn write_f64_rows(out: &mut impl Write, rows: &[[f64; 3]]) -> io::Result<()> {
    for r in rows {
        writeln!(out, "          {:?} {:?} {:?}", r[0], r[1], r[2])?;
    }
    Ok(())
}

fn write_field(out: &mut impl Write, f: &Field) -> io::Result<()> {
    let name = xml_escape(f.name);
    // `<DataArray type=… Name=…{extra} format="ascii">`
    let open = |out: &mut dyn Write, ty: &str, name: &str, extra: &str| {
        writeln!(
            out,
            r#"        <DataArray type="{ty}" Name="{name}"{extra} format="ascii">"#
        )
    };
    match f.data {
        FieldData::Scalar(v) => {
            open(out, "Float64", &name, "")?;
            write_values(out, v.iter(), 6, |o, x| write!(o, "{x:?}"))?;
        }
        FieldData::Vector3(v) => {
            open(out, "Float64", &name, r#" NumberOfComponents="3""#)?;
            write_f64_rows(out, v)?;
        }
        FieldData::SymTensor2(v) => {
            open(
                out,
                "Float64",
                &format!("{name}{SYM_TENSOR2_SUFFIX}"),
                r#" NumberOfComponents="3" ComponentName0="xx" ComponentName1="yy" ComponentName2="xy""#,
            )?;
            write_f64_rows(out, v)?;
        }
        FieldData::Int(v) => {
            open(out, "Int32", &name, "")?;
            write_values(out, v.iter(), 12, |o, x| write!(o, "{x}"))?;
        }
    }
    writeln!(out, "        </DataArray>")
}

/// Writes `piece` as a VTK XML `UnstructuredGrid` file of linear triangles
/// (cell type 5), with ASCII data arrays in full `f64` precision and the
/// piece's comment lines at the top.
///
/// # Errors
/// `InvalidInput`, before the file is created, when a field's length is not
/// the number of points (point fields) or triangles (cell fields), a field
/// holds a NaN or infinity (the message names the field and the index), a
/// field name is empty or repeated, a point is not finite or a triangle
/// refers to a missing point; otherwise the I/O error of creating or writing
/// the file.
pub fn write_vtu(path: &Path, piece: &VtuPiece) -> io::Result<()> {
    validate(path, piece)?;
    let mut out = BufWriter::new(File::create(path)?);
    writeln!(out, r#"<?xml version="1.0"?>"#)?;
    write_comments(&mut out, &piece.comment)?;
    writeln!(
        out,
        r#"<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">"#
    )?;
    writeln!(out, "  <UnstructuredGrid>")?;
    writeln!(
        out,
        r#"    <Piece NumberOfPoints="{}" NumberOfCells="{}">"#,
        piece.points.len(),
        piece.triangles.len()
    )?;
    for (tag, fields) in [
        ("PointData", &piece.point_fields),
        ("CellData", &piece.cell_fields),
    ] {
        if fields.is_empty() {
            continue;
        }
        writeln!(out, "      <{tag}>")?;
        for f in fields {
            write_field(&mut out, f)?;
        }
        writeln!(out, "      </{tag}>")?;
    }
    writeln!(out, "      <Points>")?;
    writeln!(
        out,
        r#"        <DataArray type="Float64" NumberOfComponents="3" format="ascii">"#
    )?;
    write_f64_rows(&mut out, piece.points)?;
    writeln!(out, "        </DataArray>")?;
    writeln!(out, "      </Points>")?;
    writeln!(out, "      <Cells>")?;
    writeln!(
        out,
        r#"        <DataArray type="Int64" Name="connectivity" format="ascii">"#
    )?;
    for t in piece.triangles {
        writeln!(out, "          {} {} {}", t[0], t[1], t[2])?;
    }
    writeln!(out, "        </DataArray>")?;
    writeln!(
        out,
        r#"        <DataArray type="Int64" Name="offsets" format="ascii">"#
    )?;
    write_values(
        &mut out,
        (1..=piece.triangles.len()).map(|e| 3 * e),
        12,
        |o, x| write!(o, "{x}"),
    )?;
    writeln!(out, "        </DataArray>")?;
    writeln!(
        out,
        r#"        <DataArray type="UInt8" Name="types" format="ascii">"#
    )?;
    write_values(
        &mut out,
        std::iter::repeat_n(VTK_TRIANGLE, piece.triangles.len()),
        24,
        |o, x| write!(o, "{x}"),
    )?;
    writeln!(out, "        </DataArray>")?;
    writeln!(out, "      </Cells>")?;
    writeln!(out, "    </Piece>")?;
    writeln!(out, "  </UnstructuredGrid>")?;
    writeln!(out, "</VTKFile>")?;
    out.flush()
}

/// Writes a ParaView collection (`.pvd`) listing `entries` in the given
/// order, each as `<DataSet timestep=".." group="" part="0" file=".."/>`,
/// under the `comment` lines.
///
/// # Errors
/// `InvalidInput`, before the file is created, when a time is not finite or
/// a file name is empty; otherwise the I/O error of writing the file.
pub fn write_pvd(path: &Path, entries: &[PvdEntry], comment: &[String]) -> io::Result<()> {
    for (i, e) in entries.iter().enumerate() {
        if !e.time.is_finite() {
            return Err(invalid(format!(
                "{}: entry {i} ({}) has a time that is not finite",
                path.display(),
                e.file
            )));
        }
        if e.file.is_empty() {
            return Err(invalid(format!(
                "{}: entry {i} has an empty file name",
                path.display()
            )));
        }
    }
    let mut out = BufWriter::new(File::create(path)?);
    writeln!(out, r#"<?xml version="1.0"?>"#)?;
    write_comments(&mut out, comment)?;
    writeln!(
        out,
        r#"<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">"#
    )?;
    writeln!(out, "  <Collection>")?;
    for e in entries {
        writeln!(
            out,
            r#"    <DataSet timestep="{:?}" group="" part="{}" file="{}"/>"#,
            e.time,
            e.part,
            xml_escape(&e.file)
        )?;
    }
    writeln!(out, "  </Collection>")?;
    writeln!(out, "</VTKFile>")?;
    out.flush()
}
