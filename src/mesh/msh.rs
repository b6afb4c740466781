//! Reader for Gmsh `.msh` files, format 4.1 ASCII.
//!
//! Sections read: `$MeshFormat` (must be `4.1 0 8`), `$PhysicalNames`,
//! `$Entities` (physical groups of each entity), `$Nodes` (sparse tags and
//! parametric coordinates allowed) and `$Elements`: 3-node triangles (type 2)
//! become triangles; points (type 15) and 2-node lines (type 1) only feed
//! node sets; any other type is an error. Other sections are skipped.
//!
//! Physical groups become sets named by their physical name (or
//! `physical_<tag>`): a surface group (dimension 2) gives an element set and
//! a node set of its nodes, a point or curve group (dimension 0 or 1) a node
//! set. See `docs/meshes.md`.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use nalgebra::Vector3;

use super::{Mesh, MeshError, normalise_sets};

/// Reads a Gmsh `.msh` 4.1 ASCII file (see [`parse_msh`]). Binary files are
/// recognised from their header and rejected with a clear message.
pub fn read_msh(path: &Path) -> Result<Mesh, MeshError> {
    let (text, file) = super::read_text(path)?;
    parse_msh(&text, &file)
}

/// The name of a Gmsh element type, for messages.
fn gmsh_type_name(t: i64) -> &'static str {
    match t {
        1 => "2-node line",
        2 => "3-node triangle",
        3 => "4-node quadrangle",
        4 => "4-node tetrahedron",
        5 => "8-node hexahedron",
        6 => "6-node prism",
        7 => "5-node pyramid",
        8 => "3-node line",
        9 => "6-node triangle",
        10 => "9-node quadrangle",
        11 => "10-node tetrahedron",
        15 => "1-node point",
        16 => "8-node quadrangle",
        20 => "9-node triangle",
        21 => "10-node triangle",
        _ => "unsupported element",
    }
}

/// Line cursor over the file, skipping blank lines.
struct Lines<'a> {
    source: &'a str,
    lines: Vec<(usize, &'a str)>,
    pos: usize,
}

impl<'a> Lines<'a> {
    fn next(&mut self, expected: &str) -> Result<(usize, &'a str), MeshError> {
        while let Some(&(line, s)) = self.lines.get(self.pos) {
            self.pos += 1;
            if !s.is_empty() {
                return Ok((line, s));
            }
        }
        Err(MeshError::Syntax {
            file: self.source.to_string(),
            line: self.lines.last().map_or(1, |l| l.0 + 1),
            found: "end of file".to_string(),
            expected: expected.to_string(),
        })
    }

    fn syntax(&self, line: usize, found: &str, expected: &str) -> MeshError {
        MeshError::Syntax {
            file: self.source.to_string(),
            line,
            found: found.to_string(),
            expected: expected.to_string(),
        }
    }

    /// The next line split into at least `min` fields.
    fn fields(&mut self, min: usize, expected: &str) -> Result<(usize, Vec<&'a str>), MeshError> {
        let (line, s) = self.next(expected)?;
        let f: Vec<&str> = s.split_whitespace().collect();
        if f.len() < min || f[0].starts_with('$') {
            return Err(self.syntax(line, s, expected));
        }
        Ok((line, f))
    }

    fn int(&self, line: usize, token: &str, expected: &str) -> Result<i64, MeshError> {
        token
            .parse::<i64>()
            .map_err(|_| self.syntax(line, token, expected))
    }

    fn count(&self, line: usize, token: &str, expected: &str) -> Result<usize, MeshError> {
        token
            .parse::<usize>()
            .map_err(|_| self.syntax(line, token, expected))
    }

    fn real(&self, line: usize, token: &str) -> Result<f64, MeshError> {
        match token.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(self.syntax(line, token, "a finite coordinate [mm]")),
        }
    }

    /// Expects the closing `$End<name>` line.
    fn end(&mut self, name: &str) -> Result<(), MeshError> {
        let expected = format!("$End{name}");
        let (line, s) = self.next(&expected)?;
        if s != expected {
            return Err(self.syntax(
                line,
                s,
                &format!("{expected} (counts in the section header do not match its data)"),
            ));
        }
        Ok(())
    }
}

/// An element block of a point or line physical group, or a triangle block.
struct Block {
    dim: i64,
    entity: i64,
    /// Triangle indices (for type 2) or node indices (types 1 and 15).
    triangles: Vec<usize>,
    nodes: Vec<usize>,
}

/// Parses the text of a Gmsh `.msh` 4.1 ASCII file; `source` names it in
/// messages. The mesh is checked ([`Mesh::check`]); fibres are left empty.
pub fn parse_msh(text: &str, source: &str) -> Result<Mesh, MeshError> {
    let mut c = Lines {
        source,
        lines: text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .collect(),
        pos: 0,
    };
    let mut format_seen = false;
    let mut physical_names: HashMap<(i64, i64), String> = HashMap::new();
    let mut entity_physicals: HashMap<(i64, i64), Vec<i64>> = HashMap::new();
    let mut nodes: Vec<Vector3<f64>> = Vec::new();
    let mut node_labels: Vec<i64> = Vec::new();
    let mut node_index: HashMap<i64, (usize, usize)> = HashMap::new();
    let mut triangles: Vec<[usize; 3]> = Vec::new();
    let mut element_labels: Vec<i64> = Vec::new();
    let mut element_lines: HashMap<i64, usize> = HashMap::new();
    let mut blocks: Vec<Block> = Vec::new();

    while c.pos < c.lines.len() {
        let Ok((line, s)) = c.next("a section") else {
            break;
        };
        let Some(section) = s.strip_prefix('$') else {
            return Err(c.syntax(line, s, "a section header such as $Nodes"));
        };
        if !format_seen && section != "MeshFormat" {
            return Err(c.syntax(line, s, "$MeshFormat first (not a Gmsh .msh file?)"));
        }
        match section {
            "MeshFormat" => {
                let (l, f) = c.fields(3, "`4.1 0 8` (version, file type, data size)")?;
                let unsupported = |found: String, remedy: &str| MeshError::Unsupported {
                    file: source.to_string(),
                    line: l,
                    found,
                    remedy: remedy.to_string(),
                };
                if f[1] != "0" {
                    return Err(unsupported(
                        format!("binary Gmsh format (file type {})", f[1]),
                        "save as ASCII 4.1 (gmsh -format msh41 without -bin, \
                         or File > Export with binary unchecked)",
                    ));
                }
                if f[0] != "4.1" {
                    return Err(unsupported(
                        format!("Gmsh format version {}", f[0]),
                        "save as ASCII 4.1 (gmsh -format msh41, or File > Export > \
                         Version 4 ASCII)",
                    ));
                }
                format_seen = true;
                c.end("MeshFormat")?;
            }
            "PhysicalNames" => {
                let (l, f) = c.fields(1, "the number of physical names")?;
                let n = c.count(l, f[0], "the number of physical names")?;
                for _ in 0..n {
                    let expected = "a physical name line `dim tag \"name\"`";
                    let (l, s) = c.next(expected)?;
                    let (dim, rest) = s.split_once(char::is_whitespace).unwrap_or((s, ""));
                    let rest = rest.trim_start();
                    let (tag, name) = rest.split_once(char::is_whitespace).unwrap_or((rest, ""));
                    let dim = c.int(l, dim, "a dimension (0-3)")?;
                    let tag = c.int(l, tag, "a physical tag")?;
                    let name = name.trim();
                    let name = name
                        .strip_prefix('"')
                        .and_then(|n| n.strip_suffix('"'))
                        .unwrap_or(name);
                    if name.is_empty() {
                        return Err(c.syntax(l, s, expected));
                    }
                    physical_names.insert((dim, tag), name.to_string());
                }
                c.end("PhysicalNames")?;
            }
            "Entities" => {
                let expected = "`numPoints numCurves numSurfaces numVolumes`";
                let (l, f) = c.fields(4, expected)?;
                let mut counts = [0usize; 4];
                for (k, n) in counts.iter_mut().enumerate() {
                    *n = c.count(l, f[k], expected)?;
                }
                for (dim, &n) in counts.iter().enumerate() {
                    // Points: tag x y z; others: tag and a bounding box.
                    let skip = if dim == 0 { 4 } else { 7 };
                    for _ in 0..n {
                        let expected = if dim == 0 {
                            "a point entity `tag x y z numPhysicalTags tags...`"
                        } else {
                            "an entity `tag minX minY minZ maxX maxY maxZ numPhysicalTags tags... numBounding tags...`"
                        };
                        let (l, f) = c.fields(skip + 1, expected)?;
                        let tag = c.int(l, f[0], "an entity tag")?;
                        let np = c.count(l, f[skip], "the number of physical tags")?;
                        if f.len() < skip + 1 + np {
                            return Err(c.syntax(l, &f.join(" "), expected));
                        }
                        let mut tags = Vec::with_capacity(np);
                        for t in &f[skip + 1..skip + 1 + np] {
                            // A negative tag reverses the orientation.
                            let tag = c.int(l, t, "a physical tag")?;
                            let Some(tag) = tag.checked_abs() else {
                                return Err(c.syntax(l, t, "a physical tag"));
                            };
                            tags.push(tag);
                        }
                        entity_physicals.insert((dim as i64, tag), tags);
                    }
                }
                c.end("Entities")?;
            }
            "Nodes" => {
                let expected = "`numEntityBlocks numNodes minNodeTag maxNodeTag`";
                let (l, f) = c.fields(4, expected)?;
                let nblocks = c.count(l, f[0], expected)?;
                let total = c.count(l, f[1], expected)?;
                let header_line = l;
                // Each node takes two lines (tag, coordinates): a header
                // count beyond what the rest of the file can hold is a
                // corrupt header, not an allocation to attempt.
                let room = c.lines.len().saturating_sub(c.pos) / 2;
                if total > room {
                    return Err(c.syntax(
                        header_line,
                        &format!("{total} nodes in the header"),
                        &format!(
                            "a node count the file can hold (at most {room} in its remaining lines)"
                        ),
                    ));
                }
                nodes.reserve(total);
                for _ in 0..nblocks {
                    let expected = "a node block `entityDim entityTag parametric numNodesInBlock`";
                    let (l, f) = c.fields(4, expected)?;
                    let dim = c.int(l, f[0], "an entity dimension (0-3)")?;
                    let parametric = c.int(l, f[2], "0 or 1 (parametric flag)")?;
                    let n = c.count(l, f[3], "the number of nodes in the block")?;
                    if !(0..=3).contains(&dim) || !(0..=1).contains(&parametric) {
                        return Err(c.syntax(l, &f.join(" "), expected));
                    }
                    // Parametric nodes carry dim extra coordinates (u, v, w).
                    let values = 3 + if parametric == 1 { dim as usize } else { 0 };
                    let first = nodes.len();
                    for _ in 0..n {
                        let (l, f) = c.fields(1, "a node tag")?;
                        if f.len() != 1 {
                            return Err(c.syntax(l, &f.join(" "), "one node tag per line"));
                        }
                        let tag = c.int(l, f[0], "an integer node tag")?;
                        if let Some(&(_, first_line)) = node_index.get(&tag) {
                            return Err(MeshError::DuplicateId {
                                file: source.to_string(),
                                line: l,
                                kind: "node",
                                id: tag,
                                first_line,
                            });
                        }
                        node_index.insert(tag, (nodes.len(), l));
                        node_labels.push(tag);
                        nodes.push(Vector3::zeros());
                    }
                    for k in 0..n {
                        let expected = if values == 3 {
                            "node coordinates `x y z`".to_string()
                        } else {
                            format!("node coordinates `x y z` and {dim} parametric coordinate(s)")
                        };
                        let (l, f) = c.fields(1, &expected)?;
                        if f.len() != values {
                            return Err(c.syntax(l, &f.join(" "), &expected));
                        }
                        nodes[first + k] =
                            Vector3::new(c.real(l, f[0])?, c.real(l, f[1])?, c.real(l, f[2])?);
                    }
                }
                if nodes.len() != total {
                    return Err(c.syntax(
                        header_line,
                        &format!("{total} nodes in the header"),
                        &format!("the node count of the blocks ({})", nodes.len()),
                    ));
                }
                c.end("Nodes")?;
            }
            "Elements" => {
                let expected = "`numEntityBlocks numElements minElementTag maxElementTag`";
                let (l, f) = c.fields(4, expected)?;
                let nblocks = c.count(l, f[0], expected)?;
                for _ in 0..nblocks {
                    let expected =
                        "an element block `entityDim entityTag elementType numElementsInBlock`";
                    let (l, f) = c.fields(4, expected)?;
                    let dim = c.int(l, f[0], "an entity dimension (0-3)")?;
                    let entity = c.int(l, f[1], "an entity tag")?;
                    let etype = c.int(l, f[2], "a Gmsh element type")?;
                    let n = c.count(l, f[3], "the number of elements in the block")?;
                    let per = match etype {
                        2 => 3,
                        1 => 2,
                        15 => 1,
                        _ => {
                            return Err(MeshError::NonTriangle {
                                file: source.to_string(),
                                line: l,
                                element_type: format!(
                                    "{} (Gmsh type {etype}, {})",
                                    f[2],
                                    gmsh_type_name(etype)
                                ),
                            });
                        }
                    };
                    let mut block = Block {
                        dim,
                        entity,
                        triangles: Vec::new(),
                        nodes: Vec::new(),
                    };
                    for _ in 0..n {
                        let (l, f) = c.fields(1, "an element line `tag node...`")?;
                        let tag = c.int(l, f[0], "an integer element tag")?;
                        if f.len() != per + 1 {
                            return Err(MeshError::WrongNodeCount {
                                file: source.to_string(),
                                line: l,
                                element: tag,
                                found: f.len() - 1,
                                expected: per,
                            });
                        }
                        if let Some(&first_line) = element_lines.get(&tag) {
                            return Err(MeshError::DuplicateId {
                                file: source.to_string(),
                                line: l,
                                kind: "element",
                                id: tag,
                                first_line,
                            });
                        }
                        element_lines.insert(tag, l);
                        let mut ids = [0usize; 3];
                        for (k, t) in f[1..].iter().enumerate() {
                            let node = c.int(l, t, "an integer node tag")?;
                            let Some(&(index, _)) = node_index.get(&node) else {
                                return Err(MeshError::UnknownNode {
                                    file: source.to_string(),
                                    line: l,
                                    element: tag,
                                    node,
                                });
                            };
                            ids[k] = index;
                        }
                        if per == 3 {
                            if ids[0] == ids[1] || ids[1] == ids[2] || ids[0] == ids[2] {
                                return Err(c.syntax(
                                    l,
                                    &f.join(" "),
                                    "a triangle with three distinct node tags",
                                ));
                            }
                            block.triangles.push(triangles.len());
                            block.nodes.extend_from_slice(&ids);
                            triangles.push(ids);
                            element_labels.push(tag);
                        } else {
                            block.nodes.extend_from_slice(&ids[..per]);
                        }
                    }
                    blocks.push(block);
                }
                c.end("Elements")?;
            }
            other => {
                // Skip an unknown section up to its end marker.
                let end = format!("$End{other}");
                loop {
                    let (_, s) = c.next(&end)?;
                    if s == end {
                        break;
                    }
                }
            }
        }
    }
    if !format_seen {
        return Err(MeshError::Syntax {
            file: source.to_string(),
            line: 1,
            found: "no $MeshFormat section".to_string(),
            expected: "a Gmsh .msh 4.1 ASCII file".to_string(),
        });
    }
    if triangles.is_empty() {
        return Err(MeshError::NoTriangles {
            file: source.to_string(),
            hint: "expected elements of Gmsh type 2 (Gmsh saves only the elements of \
                   physical groups: add a Physical Surface, or set Mesh.SaveAll = 1)"
                .to_string(),
        });
    }
    let mut node_sets: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    let mut element_sets: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for block in &blocks {
        let Some(physicals) = entity_physicals.get(&(block.dim, block.entity)) else {
            continue;
        };
        for &p in physicals {
            let name = physical_names
                .get(&(block.dim, p))
                .cloned()
                .unwrap_or_else(|| format!("physical_{p}"));
            node_sets
                .entry(name.clone())
                .or_default()
                .extend_from_slice(&block.nodes);
            if block.dim == 2 {
                element_sets
                    .entry(name)
                    .or_default()
                    .extend_from_slice(&block.triangles);
            }
        }
    }
    normalise_sets(&mut node_sets);
    normalise_sets(&mut element_sets);
    let mesh = Mesh {
        nodes,
        triangles,
        fibres: Vec::new(),
        node_sets,
        element_sets,
        node_labels,
        element_labels,
        source: source.to_string(),
    };
    mesh.check()?;
    Ok(mesh)
}
