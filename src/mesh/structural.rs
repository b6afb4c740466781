//! Reader of a structural shell mesh in Abaqus `.inp` form, the target a
//! formed ply is mapped onto ([`crate::handoff::map`], `docs/export.md`).
//!
//! Read: `*NODE` (`label, x, y[, z]`; a missing `z` is 0) and `*ELEMENT,
//! TYPE=…` of the shell and membrane types in [`STRUCTURAL_TYPES`]
//! (triangles `S3`, `S3R`, `M3D3`; quads `S4`, `S4R`, `S4R5`, `M3D4`,
//! `M3D4R`). `ELSET=` on `*ELEMENT` is accepted and not kept (the
//! [`ShellMesh`] has no sets). Keyword lines are case-insensitive, `**`
//! starts a comment, blank lines are skipped, a data line that ends with a
//! comma continues on the next line until its record is complete, and
//! Fortran exponents (`1.5D3`) are read. Other keywords are skipped with
//! their data lines.
//!
//! Structure: a flat file, or a file with one `*PART` (read as is) and at
//! most one `*INSTANCE` of it without a transform (no data lines). Refused
//! with a message: a second `*PART` or `*INSTANCE`, an instance with a
//! translation or rotation, elements defined in the assembly, `*INCLUDE`
//! and the mesh generation keywords (`*NGEN`, `*ELGEN`, …), and
//! `INPUT=` on `*NODE`/`*ELEMENT`. Nodes defined in the assembly (reference
//! points) are skipped: no element of the part can name them.
//!
//! The user's labels and every element's type are kept
//! ([`ShellMesh::node_labels`], [`ShellElement::label`],
//! [`ShellElement::abaqus_type`], the type in upper case); node indices are
//! internal, in file order. Nodes that no element uses are kept.

use std::collections::HashMap;
use std::path::Path;

use crate::handoff::{ShellElement, ShellMesh};

/// The element types read, with their node counts.
pub const STRUCTURAL_TYPES: &[(&str, usize)] = &[
    ("S3", 3),
    ("S3R", 3),
    ("M3D3", 3),
    ("S4", 4),
    ("S4R", 4),
    ("S4R5", 4),
    ("M3D4", 4),
    ("M3D4R", 4),
];

/// Keywords that would define nodes or elements this reader cannot expand.
const REJECTED: &[&str] = &[
    "INCLUDE", "NGEN", "NFILL", "NCOPY", "NMAP", "ELGEN", "ELCOPY",
];

/// Why a structural mesh could not be read. Every message names the file,
/// the line where there is one, the offending value and what was expected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StructuralMeshError {
    /// The file could not be read.
    #[error("cannot read structural mesh file {file}: {reason}")]
    Io {
        /// The path as given.
        file: String,
        /// The operating system's reason.
        reason: String,
    },
    /// A token that is not what the format allows at this place.
    #[error("{file}:{line}: found `{found}`, expected {expected}")]
    Syntax {
        /// The file (source) name.
        file: String,
        /// 1-based line number.
        line: usize,
        /// The offending token or line.
        found: String,
        /// What the format allows here.
        expected: String,
    },
    /// A well-formed construct this reader does not read.
    #[error("{file}:{line}: {found} is not supported; {remedy}")]
    Unsupported {
        /// The file (source) name.
        file: String,
        /// 1-based line number.
        line: usize,
        /// The construct as written.
        found: String,
        /// What to do instead.
        remedy: String,
    },
    /// An element type outside [`STRUCTURAL_TYPES`].
    #[error(
        "{file}:{line}: element type `{element_type}` is not supported; expected one of {}",
        supported_list()
    )]
    UnsupportedType {
        /// The file (source) name.
        file: String,
        /// 1-based line number of the `*ELEMENT` keyword.
        line: usize,
        /// The type as written.
        element_type: String,
    },
    /// An element line with the wrong number of nodes for its type.
    #[error(
        "{file}:{line}: element {element} of type {element_type} has {found} nodes, expected {expected}"
    )]
    WrongNodeCount {
        /// The file (source) name.
        file: String,
        /// 1-based line number (the record's last line).
        line: usize,
        /// The element label.
        element: u64,
        /// The element type.
        element_type: String,
        /// Number of node labels found.
        found: usize,
        /// Number the type needs.
        expected: usize,
    },
    /// An element names a node label that is not defined.
    #[error(
        "{file}:{line}: element {element} names node {node}, which is not defined; expected the label of a node of a *NODE block"
    )]
    UnknownNode {
        /// The file (source) name.
        file: String,
        /// 1-based line number of the element.
        line: usize,
        /// The element label.
        element: u64,
        /// The undefined node label.
        node: u64,
    },
    /// An element that names one node twice.
    #[error(
        "{file}:{line}: element {element} names node {node} twice; expected {expected} distinct nodes"
    )]
    RepeatedNode {
        /// The file (source) name.
        file: String,
        /// 1-based line number of the element.
        line: usize,
        /// The element label.
        element: u64,
        /// The repeated node label.
        node: u64,
        /// The number of nodes of its type.
        expected: usize,
    },
    /// A node or element label defined twice.
    #[error(
        "{file}:{line}: {kind} label {label} is defined twice (first at line {first_line}); expected distinct labels"
    )]
    DuplicateLabel {
        /// The file (source) name.
        file: String,
        /// 1-based line number of the second definition.
        line: usize,
        /// `node` or `element`.
        kind: &'static str,
        /// The repeated label.
        label: u64,
        /// 1-based line number of the first definition.
        first_line: usize,
    },
    /// A file without any element of a supported type.
    #[error(
        "{file}: no shell elements found; expected an *ELEMENT block of type {}",
        supported_list()
    )]
    NoElements {
        /// The file (source) name.
        file: String,
    },
}

fn supported_list() -> String {
    STRUCTURAL_TYPES
        .iter()
        .map(|(t, _)| *t)
        .collect::<Vec<_>>()
        .join(", ")
}

/// Reads a structural shell mesh from an Abaqus `.inp` file (see
/// [`parse_structural_inp`] and the module documentation).
pub fn read_structural_inp(path: &Path) -> Result<ShellMesh, StructuralMeshError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| StructuralMeshError::Io {
        file: file.clone(),
        reason: e.to_string(),
    })?;
    parse_structural_inp(&String::from_utf8_lossy(&bytes), &file)
}

/// Parses the text of an Abaqus `.inp` shell mesh; `source` names it in
/// messages and becomes [`ShellMesh::source`]. See the module
/// documentation for what is read and what is refused.
pub fn parse_structural_inp(text: &str, source: &str) -> Result<ShellMesh, StructuralMeshError> {
    let mut p = Parser::new(source);
    super::inp::walk_inp(text, &mut p)?;
    p.finish()
}

/// A comma-separated field and its line.
#[derive(Debug, Clone)]
struct Field {
    text: String,
    line: usize,
}

#[derive(Debug, Clone)]
enum Block {
    Skip,
    Node,
    Element {
        ty: String,
        count: usize,
    },
    /// Data lines of an `*INSTANCE` (a transform), refused.
    Instance,
}

/// Where in the part/assembly structure the parser is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scope {
    Top,
    Part,
    Assembly,
    Instance,
}

struct Parser<'a> {
    source: &'a str,
    block: Block,
    scope: Scope,
    parts: usize,
    instances: usize,
    /// Fields of an unfinished `*NODE`/`*ELEMENT` record (continuation).
    pending: Vec<Field>,
    nodes: Vec<[f64; 3]>,
    node_labels: Vec<u64>,
    node_index: HashMap<u64, (usize, usize)>,
    /// Label, type, node labels, line.
    elements: Vec<(u64, String, Vec<u64>, usize)>,
    element_lines: HashMap<u64, usize>,
}

impl<'a> Parser<'a> {
    fn new(source: &'a str) -> Self {
        Parser {
            source,
            block: Block::Skip,
            scope: Scope::Top,
            parts: 0,
            instances: 0,
            pending: Vec::new(),
            nodes: Vec::new(),
            node_labels: Vec::new(),
            node_index: HashMap::new(),
            elements: Vec::new(),
            element_lines: HashMap::new(),
        }
    }

    fn syntax(&self, line: usize, found: &str, expected: &str) -> StructuralMeshError {
        StructuralMeshError::Syntax {
            file: self.source.to_string(),
            line,
            found: found.to_string(),
            expected: expected.to_string(),
        }
    }

    fn unsupported(&self, line: usize, found: &str, remedy: &str) -> StructuralMeshError {
        StructuralMeshError::Unsupported {
            file: self.source.to_string(),
            line,
            found: found.to_string(),
            remedy: remedy.to_string(),
        }
    }

    fn keyword(&mut self, text: &str, line: usize) -> Result<(), StructuralMeshError> {
        let (name, options) = super::inp::keyword_parts(text);
        let option = |key: &str| {
            options
                .iter()
                .find(|(k, _)| k == key)
                .map(|(_, v)| v.clone().unwrap_or_default())
        };
        if REJECTED.contains(&name.as_str()) {
            return Err(self.unsupported(
                line,
                &format!("*{name}"),
                "write the nodes and elements out in full in one file \
                 (e.g. export the input file from the pre-processor)",
            ));
        }
        if option("INPUT").is_some() && matches!(name.as_str(), "NODE" | "ELEMENT") {
            return Err(self.unsupported(
                line,
                &format!("*{name}, INPUT=..."),
                "put the data lines in the file itself",
            ));
        }
        self.block = match name.as_str() {
            "NODE" => {
                if self.scope == Scope::Assembly {
                    // Reference points of the assembly: no part element
                    // can name them.
                    Block::Skip
                } else {
                    Block::Node
                }
            }
            "ELEMENT" => {
                if self.scope == Scope::Assembly {
                    return Err(self.unsupported(
                        line,
                        "*ELEMENT in the assembly",
                        "define the shell elements in the part (or in a flat file)",
                    ));
                }
                let Some(ty) = option("TYPE").filter(|t| !t.is_empty()) else {
                    return Err(self.syntax(
                        line,
                        text,
                        &format!("*ELEMENT, TYPE=<one of {}>", supported_list()),
                    ));
                };
                let upper = ty.to_ascii_uppercase();
                let Some(&(_, count)) = STRUCTURAL_TYPES.iter().find(|(t, _)| *t == upper) else {
                    return Err(StructuralMeshError::UnsupportedType {
                        file: self.source.to_string(),
                        line,
                        element_type: ty,
                    });
                };
                Block::Element { ty: upper, count }
            }
            "PART" => {
                self.parts += 1;
                if self.parts > 1 {
                    return Err(self.unsupported(
                        line,
                        "a second *PART",
                        "export the structural mesh as one part (or a flat file)",
                    ));
                }
                self.scope = Scope::Part;
                Block::Skip
            }
            "END PART" | "END ASSEMBLY" => {
                self.scope = Scope::Top;
                Block::Skip
            }
            "ASSEMBLY" => {
                self.scope = Scope::Assembly;
                Block::Skip
            }
            "INSTANCE" => {
                self.instances += 1;
                if self.instances > 1 {
                    return Err(self.unsupported(
                        line,
                        "a second *INSTANCE",
                        "export the structural mesh as one part with at most one instance",
                    ));
                }
                self.scope = Scope::Instance;
                Block::Instance
            }
            "END INSTANCE" => {
                self.scope = Scope::Assembly;
                Block::Skip
            }
            _ => Block::Skip,
        };
        Ok(())
    }

    fn data(&mut self, text: &str, line: usize) -> Result<(), StructuralMeshError> {
        let needed = match &self.block {
            Block::Skip => return Ok(()),
            Block::Instance => {
                return Err(self.unsupported(
                    line,
                    &format!("an *INSTANCE with a transform (`{text}`)"),
                    "export the mesh with the instance's position applied \
                     (a flat file, or an instance without translation or rotation)",
                ));
            }
            Block::Node => 3,
            Block::Element { count, .. } => count + 1,
        };
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
        if fields.iter().any(|f| f.text.is_empty()) {
            return Err(self.syntax(line, text, "comma-separated values without empty fields"));
        }
        self.pending.extend(fields);
        // A record continues on the next line while it ends with a comma
        // and is still incomplete.
        if !(continued && self.pending.len() < needed) {
            self.finish_record()?;
        }
        Ok(())
    }

    fn label(&self, f: &Field, what: &str) -> Result<u64, StructuralMeshError> {
        match f.text.parse::<u64>() {
            Ok(v) if v > 0 => Ok(v),
            _ => Err(self.syntax(f.line, &f.text, &format!("a positive integer {what} label"))),
        }
    }

    fn real(&self, f: &Field) -> Result<f64, StructuralMeshError> {
        let t = f.text.replace(['d', 'D'], "e");
        match t.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.syntax(f.line, &f.text, "a finite coordinate [mm]")),
        }
    }

    /// Completes the pending `*NODE` or `*ELEMENT` record.
    fn finish_record(&mut self) -> Result<(), StructuralMeshError> {
        if self.pending.is_empty() {
            return Ok(());
        }
        let fields = std::mem::take(&mut self.pending);
        let line = fields[0].line;
        let last_line = fields.last().map_or(line, |f| f.line);
        match self.block.clone() {
            Block::Node => {
                if !(3..=4).contains(&fields.len()) {
                    let found: Vec<&str> = fields.iter().map(|f| f.text.as_str()).collect();
                    return Err(self.syntax(
                        last_line,
                        &found.join(", "),
                        "a node line `label, x, y[, z]`",
                    ));
                }
                let label = self.label(&fields[0], "node")?;
                let mut x = [0.0; 3];
                for (c, f) in x.iter_mut().zip(&fields[1..]) {
                    *c = self.real(f)?;
                }
                if let Some(&(_, first_line)) = self.node_index.get(&label) {
                    return Err(StructuralMeshError::DuplicateLabel {
                        file: self.source.to_string(),
                        line,
                        kind: "node",
                        label,
                        first_line,
                    });
                }
                self.node_index.insert(label, (self.nodes.len(), line));
                self.nodes.push(x);
                self.node_labels.push(label);
            }
            Block::Element { ty, count } => {
                let label = self.label(&fields[0], "element")?;
                if fields.len() != count + 1 {
                    return Err(StructuralMeshError::WrongNodeCount {
                        file: self.source.to_string(),
                        line: last_line,
                        element: label,
                        element_type: ty,
                        found: fields.len() - 1,
                        expected: count,
                    });
                }
                let mut nodes = Vec::with_capacity(count);
                for f in &fields[1..] {
                    nodes.push(self.label(f, "node")?);
                }
                if let Some(&first_line) = self.element_lines.get(&label) {
                    return Err(StructuralMeshError::DuplicateLabel {
                        file: self.source.to_string(),
                        line,
                        kind: "element",
                        label,
                        first_line,
                    });
                }
                self.element_lines.insert(label, line);
                self.elements.push((label, ty, nodes, line));
            }
            Block::Skip | Block::Instance => {}
        }
        Ok(())
    }

    fn finish(self) -> Result<ShellMesh, StructuralMeshError> {
        let file = self.source.to_string();
        if self.elements.is_empty() {
            return Err(StructuralMeshError::NoElements { file });
        }
        let mut elements = Vec::with_capacity(self.elements.len());
        for (label, ty, ids, line) in self.elements {
            let mut nodes = Vec::with_capacity(ids.len());
            for (k, &id) in ids.iter().enumerate() {
                let Some(&(index, _)) = self.node_index.get(&id) else {
                    return Err(StructuralMeshError::UnknownNode {
                        file,
                        line,
                        element: label,
                        node: id,
                    });
                };
                if ids[..k].contains(&id) {
                    return Err(StructuralMeshError::RepeatedNode {
                        file,
                        line,
                        element: label,
                        node: id,
                        expected: ids.len(),
                    });
                }
                nodes.push(index);
            }
            elements.push(ShellElement {
                label,
                nodes,
                abaqus_type: ty,
            });
        }
        Ok(ShellMesh {
            source: file,
            node_labels: self.node_labels,
            nodes: self.nodes,
            elements,
        })
    }
}

impl super::inp::InpLines for Parser<'_> {
    type Error = StructuralMeshError;
    fn finish_record(&mut self) -> Result<(), StructuralMeshError> {
        Parser::finish_record(self)
    }
    fn keyword(&mut self, text: &str, line: usize) -> Result<(), StructuralMeshError> {
        Parser::keyword(self, text, line)
    }
    fn data(&mut self, text: &str, line: usize) -> Result<(), StructuralMeshError> {
        Parser::data(self, text, line)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_flat_mixed_mesh() {
        let text = "*NODE\n1, 0, 0\n2, 1, 0, 0\n3, 1, 1, 0\n4, 0, 1, 0\n5, 2, 0.5, 1d-1\n\
                    *ELEMENT, TYPE=s4r, ELSET=A\n7, 1, 2,\n 3, 4\n*Element, type=M3D3\n9, 2, 5, 3\n";
        let m = parse_structural_inp(text, "t.inp").unwrap();
        assert_eq!(m.node_labels, vec![1, 2, 3, 4, 5]);
        assert_eq!(m.nodes[4], [2.0, 0.5, 0.1]);
        assert_eq!(m.elements.len(), 2);
        assert_eq!(m.elements[0].abaqus_type, "S4R");
        assert_eq!(m.elements[0].nodes, vec![0, 1, 2, 3]);
        assert_eq!(m.elements[1].label, 9);
        assert_eq!(m.elements[1].abaqus_type, "M3D3");
    }

    #[test]
    fn one_part_and_a_plain_instance_are_read() {
        let text = "*PART, NAME=P\n*NODE\n1,0,0\n2,1,0\n3,0,1\n*ELEMENT,TYPE=S3\n1,1,2,3\n\
                    *END PART\n*ASSEMBLY, NAME=A\n*INSTANCE, NAME=I, PART=P\n*END INSTANCE\n\
                    *NODE\n1, 5, 5, 5\n*END ASSEMBLY\n";
        let m = parse_structural_inp(text, "p.inp").unwrap();
        assert_eq!(m.nodes.len(), 3);
        assert_eq!(m.elements.len(), 1);
    }

    #[test]
    fn a_transformed_instance_and_a_second_part_are_refused() {
        let text = "*PART, NAME=P\n*NODE\n1,0,0\n2,1,0\n3,0,1\n*ELEMENT,TYPE=S3\n1,1,2,3\n\
                    *END PART\n*ASSEMBLY, NAME=A\n*INSTANCE, NAME=I, PART=P\n10., 0., 0.\n";
        let e = parse_structural_inp(text, "p.inp").unwrap_err().to_string();
        assert!(e.contains("p.inp:11") && e.contains("transform"), "{e}");
        let text = "*PART, NAME=P\n*END PART\n*PART, NAME=Q\n";
        let e = parse_structural_inp(text, "q.inp").unwrap_err().to_string();
        assert!(e.contains("q.inp:3") && e.contains("second *PART"), "{e}");
    }
}
