//! Reader for flat Abaqus `.inp` files: `*NODE`, `*ELEMENT` with 3-node
//! triangle types, `*NSET` and `*ELSET` (id lists, `GENERATE`, members that
//! are sets). Keywords and options are case-insensitive; `**` starts a
//! comment line. `*PART`, `*ASSEMBLY`, `*INSTANCE` (and their `*END ...`)
//! are ignored, so parts and instances are read as one flat mesh without
//! instance transforms; other keywords are skipped with their data lines;
//! `*INCLUDE` and the mesh generation keywords (`*NGEN`, `*ELGEN`, ...) are
//! rejected. See `docs/meshes.md`.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use nalgebra::Vector3;

use super::{Mesh, MeshError, normalise_sets};

/// The Abaqus element types read as 3-node triangles.
pub const TRIANGLE_TYPES: &[&str] = &[
    "M3D3", "S3", "S3R", "S3RS", "CPS3", "CPE3", "STRI3", "SFM3D3", "R3D3",
];

/// Keywords that would define nodes or elements ncform cannot expand.
const REJECTED: &[&str] = &[
    "INCLUDE", "NGEN", "NFILL", "NCOPY", "NMAP", "ELGEN", "ELCOPY",
];

/// Reads an Abaqus `.inp` file (see [`parse_inp`]).
pub fn read_inp(path: &Path) -> Result<Mesh, MeshError> {
    let (text, file) = super::read_text(path)?;
    parse_inp(&text, &file)
}

/// Parses the text of an Abaqus `.inp` file; `source` names it in messages.
/// The mesh is checked ([`Mesh::check`]); fibres are left empty.
pub fn parse_inp(text: &str, source: &str) -> Result<Mesh, MeshError> {
    let mut p = Parser::new(source);
    walk_inp(text, &mut p)?;
    p.finish()
}

/// What an `.inp` reader does with the lines [`walk_inp`] hands it.
pub(crate) trait InpLines {
    /// The reader's error.
    type Error;
    /// The data lines of the last keyword are over.
    fn finish_record(&mut self) -> Result<(), Self::Error>;
    /// A keyword line (continuation lines joined) at `line`.
    fn keyword(&mut self, text: &str, line: usize) -> Result<(), Self::Error>;
    /// A data line at `line`.
    fn data(&mut self, text: &str, line: usize) -> Result<(), Self::Error>;
}

/// A keyword line's parts: its name (upper case, inner blanks single) and
/// its options `KEY` or `KEY=value` (keys upper case, values unquoted), in
/// order. `text` starts with its `*`.
pub(crate) fn keyword_parts(text: &str) -> (String, Vec<(String, Option<String>)>) {
    let mut parts = text[1..].split(',');
    let name = parts
        .next()
        .unwrap_or("")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .to_ascii_uppercase();
    let mut options: Vec<(String, Option<String>)> = Vec::new();
    for part in parts {
        let part = part.trim();
        if part.is_empty() {
            continue;
        }
        match part.split_once('=') {
            Some((k, v)) => options.push((
                k.trim().to_ascii_uppercase(),
                Some(unquote(v.trim()).to_string()),
            )),
            None => options.push((part.to_ascii_uppercase(), None)),
        }
    }
    (name, options)
}

/// Hands the lines of an Abaqus `.inp` text to `reader`: comments (`**`)
/// and blank lines skipped, a keyword line continued while it ends with a
/// comma and the next line holds options (`key=value`; data lines never
/// do), each record finished before the next keyword and at the end.
pub(crate) fn walk_inp<R: InpLines>(text: &str, reader: &mut R) -> Result<(), R::Error> {
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .collect();
    let mut k = 0;
    while k < lines.len() {
        let (line, s) = lines[k];
        k += 1;
        if s.is_empty() || s.starts_with("**") {
            continue;
        }
        if s.starts_with('*') {
            reader.finish_record()?;
            let mut keyword = s.to_string();
            while keyword.ends_with(',')
                && k < lines.len()
                && !lines[k].1.starts_with('*')
                && lines[k].1.contains('=')
            {
                keyword.push_str(lines[k].1);
                k += 1;
            }
            reader.keyword(&keyword, line)?;
        } else {
            reader.data(s, line)?;
        }
    }
    reader.finish_record()
}

/// A comma-separated field and its line.
#[derive(Debug, Clone)]
struct Field {
    text: String,
    line: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum Kind {
    Node,
    Element,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Node => "node",
            Kind::Element => "element",
        }
    }
}

/// One contribution to a set, resolved after the whole file is read.
#[derive(Debug, Clone)]
enum Member {
    Id(i64, usize),
    Range(i64, i64, i64, usize),
    Set(String, usize),
    /// Mentioning a set creates it, even when it stays empty.
    Create,
    /// The nodes of an element set (`*NSET, NSET=n, ELSET=e`).
    NodesOfElset(String, usize),
}

#[derive(Debug, Clone)]
enum Block {
    Skip,
    Node {
        nset: Option<String>,
    },
    Element {
        elset: Option<String>,
    },
    Set {
        kind: Kind,
        name: String,
        generate: bool,
    },
}

struct Parser<'a> {
    source: &'a str,
    block: Block,
    /// Fields of an unfinished `*NODE`/`*ELEMENT` record (continuation).
    pending: Vec<Field>,
    nodes: Vec<Vector3<f64>>,
    node_labels: Vec<i64>,
    node_index: HashMap<i64, (usize, usize)>,
    elements: Vec<([i64; 3], usize)>,
    element_labels: Vec<i64>,
    element_index: HashMap<i64, (usize, usize)>,
    /// Set definitions in file order: kind, canonical name, members.
    set_ops: Vec<(Kind, String, Member)>,
    /// Upper-case name → canonical (first-seen) spelling, per kind.
    set_names: HashMap<(Kind, String), String>,
}

impl<'a> Parser<'a> {
    fn new(source: &'a str) -> Self {
        Parser {
            source,
            block: Block::Skip,
            pending: Vec::new(),
            nodes: Vec::new(),
            node_labels: Vec::new(),
            node_index: HashMap::new(),
            elements: Vec::new(),
            element_labels: Vec::new(),
            element_index: HashMap::new(),
            set_ops: Vec::new(),
            set_names: HashMap::new(),
        }
    }

    fn syntax(&self, line: usize, found: &str, expected: &str) -> MeshError {
        MeshError::Syntax {
            file: self.source.to_string(),
            line,
            found: found.to_string(),
            expected: expected.to_string(),
        }
    }

    /// The canonical spelling of a set name (Abaqus names are
    /// case-insensitive; the first spelling is kept).
    fn canonical(&mut self, kind: Kind, name: &str) -> String {
        self.set_names
            .entry((kind, name.to_ascii_uppercase()))
            .or_insert_with(|| name.to_string())
            .clone()
    }

    fn keyword(&mut self, text: &str, line: usize) -> Result<(), MeshError> {
        let (name, options) = keyword_parts(text);
        let option = |key: &str| {
            options
                .iter()
                .find(|(k, _)| k == key)
                .map(|(_, v)| v.clone().unwrap_or_default())
        };
        if REJECTED.contains(&name.as_str()) {
            return Err(MeshError::Unsupported {
                file: self.source.to_string(),
                line,
                found: format!("*{name}"),
                remedy: "write the nodes and elements out in full in one flat file \
                         (e.g. export the input file from the pre-processor)"
                    .to_string(),
            });
        }
        if option("INPUT").is_some()
            && matches!(name.as_str(), "NODE" | "ELEMENT" | "NSET" | "ELSET")
        {
            return Err(MeshError::Unsupported {
                file: self.source.to_string(),
                line,
                found: format!("*{name}, INPUT=..."),
                remedy: "put the data lines in the file itself".to_string(),
            });
        }
        self.block = match name.as_str() {
            "NODE" => Block::Node {
                nset: option("NSET").map(|n| self.canonical(Kind::Node, &n)),
            },
            "ELEMENT" => {
                let Some(ty) = option("TYPE") else {
                    return Err(self.syntax(
                        line,
                        text,
                        "*ELEMENT, TYPE=<a 3-node triangle type: M3D3, S3, S3R, CPS3, ...>",
                    ));
                };
                let upper = ty.to_ascii_uppercase();
                if !TRIANGLE_TYPES.contains(&upper.as_str()) {
                    return Err(MeshError::NonTriangle {
                        file: self.source.to_string(),
                        line,
                        element_type: ty,
                    });
                }
                Block::Element {
                    elset: option("ELSET").map(|n| self.canonical(Kind::Element, &n)),
                }
            }
            "NSET" | "ELSET" => {
                let kind = if name == "NSET" {
                    Kind::Node
                } else {
                    Kind::Element
                };
                let Some(set) = option(&name).filter(|s| !s.is_empty()) else {
                    return Err(self.syntax(line, text, &format!("*{name}, {name}=<set name>")));
                };
                let set = self.canonical(kind, &set);
                self.set_ops.push((kind, set.clone(), Member::Create));
                if kind == Kind::Node
                    && let Some(elset) = option("ELSET")
                {
                    self.set_ops
                        .push((kind, set.clone(), Member::NodesOfElset(elset, line)));
                }
                Block::Set {
                    kind,
                    name: set,
                    generate: option("GENERATE").is_some(),
                }
            }
            // Flat reading: part, assembly and instance structure is ignored.
            "PART" | "END PART" | "ASSEMBLY" | "END ASSEMBLY" | "END INSTANCE" => Block::Skip,
            _ => Block::Skip,
        };
        Ok(())
    }

    fn data(&mut self, text: &str, line: usize) -> Result<(), MeshError> {
        if matches!(self.block, Block::Skip) {
            return Ok(());
        }
        let continued = text.ends_with(',');
        let mut fields: Vec<Field> = text
            .split(',')
            .map(|f| Field {
                text: f.trim().to_string(),
                line,
            })
            .collect();
        if continued {
            fields.pop();
        }
        if let Some(f) = fields.iter().find(|f| f.text.is_empty()) {
            return Err(self.syntax(f.line, text, "comma-separated values without empty fields"));
        }
        match self.block.clone() {
            Block::Skip => Ok(()),
            Block::Node { .. } | Block::Element { .. } => {
                self.pending.extend(fields);
                // A record continues on the next line while it ends with a
                // comma and is still incomplete (id, x, y for a node; id and
                // three nodes for an element).
                let needed = if matches!(self.block, Block::Node { .. }) {
                    3
                } else {
                    4
                };
                if !(continued && self.pending.len() < needed) {
                    self.finish_record()?;
                }
                Ok(())
            }
            Block::Set {
                kind,
                name,
                generate,
            } => {
                if generate {
                    if !(2..=3).contains(&fields.len()) {
                        return Err(self.syntax(
                            line,
                            text,
                            "a GENERATE line `first, last[, increment]`",
                        ));
                    }
                    let first = self.integer(&fields[0], "an integer id (GENERATE first)")?;
                    let last = self.integer(&fields[1], "an integer id (GENERATE last)")?;
                    let step = match fields.get(2) {
                        Some(f) => self.integer(f, "an integer increment (GENERATE)")?,
                        None => 1,
                    };
                    if step <= 0 || last < first {
                        return Err(self.syntax(
                            line,
                            text,
                            "GENERATE `first, last, increment` with first <= last and increment > 0",
                        ));
                    }
                    self.set_ops
                        .push((kind, name, Member::Range(first, last, step, line)));
                } else {
                    for f in fields {
                        let member = match f.text.parse::<i64>() {
                            Ok(id) => Member::Id(id, f.line),
                            Err(_) => Member::Set(unquote(&f.text).to_string(), f.line),
                        };
                        self.set_ops.push((kind, name.clone(), member));
                    }
                }
                Ok(())
            }
        }
    }

    fn integer(&self, f: &Field, expected: &str) -> Result<i64, MeshError> {
        f.text
            .parse::<i64>()
            .map_err(|_| self.syntax(f.line, &f.text, expected))
    }

    fn real(&self, f: &Field, expected: &str) -> Result<f64, MeshError> {
        // Fortran-style exponents (1.5D3) are accepted.
        let t = f.text.replace(['d', 'D'], "e");
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.syntax(f.line, &f.text, expected)),
        }
    }

    /// Completes the pending `*NODE` or `*ELEMENT` record.
    fn finish_record(&mut self) -> Result<(), MeshError> {
        if self.pending.is_empty() {
            return Ok(());
        }
        let fields = std::mem::take(&mut self.pending);
        let line = fields[0].line;
        match self.block.clone() {
            Block::Node { nset } => {
                if !(3..=4).contains(&fields.len()) {
                    let found: Vec<&str> = fields.iter().map(|f| f.text.as_str()).collect();
                    return Err(self.syntax(
                        fields.last().map_or(line, |f| f.line),
                        &found.join(", "),
                        "a node line `id, x, y[, z]`",
                    ));
                }
                let id = self.integer(&fields[0], "an integer node id")?;
                let mut x = [0.0; 3];
                for (c, f) in x.iter_mut().zip(&fields[1..]) {
                    *c = self.real(f, "a finite coordinate [mm]")?;
                }
                if let Some(&(_, first_line)) = self.node_index.get(&id) {
                    return Err(MeshError::DuplicateId {
                        file: self.source.to_string(),
                        line,
                        kind: "node",
                        id,
                        first_line,
                    });
                }
                self.node_index.insert(id, (self.nodes.len(), line));
                self.nodes.push(Vector3::new(x[0], x[1], x[2]));
                self.node_labels.push(id);
                if let Some(set) = nset {
                    self.set_ops.push((Kind::Node, set, Member::Id(id, line)));
                }
            }
            Block::Element { elset } => {
                let id = self.integer(&fields[0], "an integer element id")?;
                if fields.len() != 4 {
                    return Err(MeshError::WrongNodeCount {
                        file: self.source.to_string(),
                        line: fields.last().map_or(line, |f| f.line),
                        element: id,
                        found: fields.len() - 1,
                        expected: 3,
                    });
                }
                let mut n = [0i64; 3];
                for (c, f) in n.iter_mut().zip(&fields[1..]) {
                    *c = self.integer(f, "an integer node id")?;
                }
                if let Some(&(_, first_line)) = self.element_index.get(&id) {
                    return Err(MeshError::DuplicateId {
                        file: self.source.to_string(),
                        line,
                        kind: "element",
                        id,
                        first_line,
                    });
                }
                self.element_index.insert(id, (self.elements.len(), line));
                self.elements.push((n, line));
                self.element_labels.push(id);
                if let Some(set) = elset {
                    self.set_ops
                        .push((Kind::Element, set, Member::Id(id, line)));
                }
            }
            _ => {}
        }
        Ok(())
    }

    fn finish(self) -> Result<Mesh, MeshError> {
        let file = self.source.to_string();
        if self.elements.is_empty() {
            return Err(MeshError::NoTriangles {
                file,
                hint: format!(
                    "expected an *ELEMENT block of a triangle type ({})",
                    TRIANGLE_TYPES.join(", ")
                ),
            });
        }
        let mut triangles = Vec::with_capacity(self.elements.len());
        for (e, (ids, line)) in self.elements.iter().enumerate() {
            let mut tri = [0usize; 3];
            for (t, id) in tri.iter_mut().zip(ids) {
                *t = match self.node_index.get(id) {
                    Some(&(index, _)) => index,
                    None => {
                        return Err(MeshError::UnknownNode {
                            file,
                            line: *line,
                            element: self.element_labels[e],
                            node: *id,
                        });
                    }
                };
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                return Err(MeshError::Syntax {
                    file,
                    line: *line,
                    found: format!(
                        "element {} with nodes {}, {}, {}",
                        self.element_labels[e], ids[0], ids[1], ids[2]
                    ),
                    expected: "three distinct node ids".to_string(),
                });
            }
            triangles.push(tri);
        }
        let mut node_sets: BTreeMap<String, Vec<usize>> = BTreeMap::new();
        let mut element_sets: BTreeMap<String, Vec<usize>> = BTreeMap::new();
        for (kind, set, member) in &self.set_ops {
            let unknown = |kind: Kind, member: String, line: usize| MeshError::UnknownSetMember {
                file: file.clone(),
                line,
                set: set.clone(),
                kind: kind.name(),
                member,
            };
            let index = match kind {
                Kind::Node => &self.node_index,
                Kind::Element => &self.element_index,
            };
            let mut add: Vec<usize> = Vec::new();
            match member {
                Member::Create => {}
                Member::Id(id, line) => match index.get(id) {
                    Some(&(i, _)) => add.push(i),
                    None => return Err(unknown(*kind, id.to_string(), *line)),
                },
                Member::Range(first, last, step, line) => {
                    let mut id = *first;
                    while id <= *last {
                        match index.get(&id) {
                            Some(&(i, _)) => add.push(i),
                            None => return Err(unknown(*kind, id.to_string(), *line)),
                        }
                        match id.checked_add(*step) {
                            Some(next) => id = next,
                            None => break,
                        }
                    }
                }
                Member::Set(name, line) => {
                    let sets = match kind {
                        Kind::Node => &mut node_sets,
                        Kind::Element => &mut element_sets,
                    };
                    let members = self
                        .set_names
                        .get(&(*kind, name.to_ascii_uppercase()))
                        .and_then(|canonical| sets.get_mut(canonical));
                    match members {
                        Some(members) => {
                            members.sort_unstable();
                            members.dedup();
                            add.extend_from_slice(members);
                        }
                        None => return Err(unknown(*kind, name.clone(), *line)),
                    }
                }
                Member::NodesOfElset(name, line) => {
                    let elements = self
                        .set_names
                        .get(&(Kind::Element, name.to_ascii_uppercase()))
                        .and_then(|canonical| element_sets.get(canonical));
                    match elements {
                        Some(elements) => {
                            for &e in elements {
                                add.extend_from_slice(&triangles[e]);
                            }
                        }
                        None => return Err(unknown(Kind::Element, name.clone(), *line)),
                    }
                }
            }
            let sets = match kind {
                Kind::Node => &mut node_sets,
                Kind::Element => &mut element_sets,
            };
            sets.entry(set.clone()).or_default().extend(add);
        }
        normalise_sets(&mut node_sets);
        normalise_sets(&mut element_sets);
        let mesh = Mesh {
            nodes: self.nodes,
            triangles,
            fibres: Vec::new(),
            node_sets,
            element_sets,
            node_labels: self.node_labels,
            element_labels: self.element_labels,
            source: file,
        };
        mesh.check()?;
        Ok(mesh)
    }
}

fn unquote(s: &str) -> &str {
    s.strip_prefix('"')
        .and_then(|s| s.strip_suffix('"'))
        .unwrap_or(s)
}

impl InpLines for Parser<'_> {
    type Error = MeshError;
    fn finish_record(&mut self) -> Result<(), MeshError> {
        Parser::finish_record(self)
    }
    fn keyword(&mut self, text: &str, line: usize) -> Result<(), MeshError> {
        Parser::keyword(self, text, line)
    }
    fn data(&mut self, text: &str, line: usize) -> Result<(), MeshError> {
        Parser::data(self, text, line)
    }
}
