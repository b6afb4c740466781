//! Triangle-mesh tools read from STL (binary or ASCII) or OBJ files, or
//! given as triangles: the [`RigidSurface`] query by point projection on a
//! bounding-volume tree (parry3d). See `docs/tools.md` §4.
//!
//! **Sign.** For a closed, consistently and outward oriented mesh, `d < 0`
//! inside the solid it bounds; for an open mesh, `d < 0` behind the closest
//! feature (a one-sided surface: the side opposite its oriented normal).
//! Both come from the angle-weighted pseudo-normal of the closest feature
//! (Bærentzen and Aanæs, IEEE TVCG 11, 2005): the face normal on a face,
//! the sum of the two face normals on an edge, the angle-weighted sum on a
//! vertex.
//!
//! **Normal and Hessian.** With `p` the closest point and `r = |x − p|`:
//! on a face, `∇d = n_face`, `∇²d = 0`; on an edge (unit direction `t`),
//! `∇d = ±(x − p)/r` and `∇²d = (I − t⊗t − ∇d⊗∇d)/d`; on a vertex,
//! `∇d = ±(x − p)/r` and `∇²d = (I − ∇d⊗∇d)/d` — the exact distance field
//! of a line or a point, as for a cylinder or sphere of radius `|d|`. For
//! `r` below `SURFACE_FRACTION` of the mesh's size the point is on the edge
//! or vertex: `∇d` is the (normalised) pseudo-normal and `∇²d = 0`.
//!
//! **Culling.** Beyond `max_distance` a point on the free side is `None`.
//! A point inside a closed mesh deeper than `max_distance` is still
//! answered (an unbounded search, run only for points in the mesh's
//! bounding box). Behind an open mesh, a point farther than `max_distance`
//! is `None`: a sheet has no inside to bound the search.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Matrix3, Vector3};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::math::Vector as GlamVector;
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::{TriMesh, TriMeshFlags, TrianglePointLocation};

use super::tessellate::Tessellation;
use super::{RigidSurface, SurfacePoint};
use crate::config::readable_number;
use crate::mesh::DEGENERATE_AREA;

/// Distance from an edge or a vertex, relative to the diagonal of the
/// mesh's bounding box, below which the point counts as on it (normal =
/// pseudo-normal, Hessian 0) rather than off it along `(x − p)/r`, whose
/// round-off `~ε|x|/r` would be large.
pub const SURFACE_FRACTION: f64 = 1e-12;

/// How to read a mesh tool.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshOptions {
    /// Factor from the file's length unit to mm (1 for mm, 1000 for
    /// metres, 25.4 for inches).
    pub scale: f64,
    /// Reject a mesh that is not closed, manifold and consistently
    /// oriented (every edge shared by exactly two triangles that run it in
    /// opposite directions).
    pub require_closed: bool,
    /// Reverse every triangle (for a file whose normals point into the
    /// tool, or an open sheet facing away from the ply).
    pub flip_normals: bool,
}

impl Default for MeshOptions {
    fn default() -> Self {
        Self {
            scale: 1.0,
            require_closed: false,
            flip_normals: false,
        }
    }
}

/// What is wrong with an edge of a mesh that should be closed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeDefect {
    /// Only one triangle has this edge (a hole's rim or a sheet's border).
    Open,
    /// More than two triangles share this edge.
    NonManifold {
        /// The number of triangles sharing it.
        triangles: usize,
    },
    /// Both triangles run the edge in the same direction (one of them is
    /// flipped).
    Inconsistent,
}

impl std::fmt::Display for EdgeDefect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EdgeDefect::Open => write!(f, "open (one triangle has it)"),
            EdgeDefect::NonManifold { triangles } => {
                write!(f, "non-manifold ({triangles} triangles share it)")
            }
            EdgeDefect::Inconsistent => write!(
                f,
                "inconsistently oriented (both triangles run it the same way)"
            ),
        }
    }
}

/// Why a mesh tool cannot be read or built. Every message names the file
/// (or the source given to [`MeshSurface::from_triangles`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshToolError {
    /// The file could not be read.
    #[error("cannot read tool mesh {file}: {reason}")]
    Io {
        /// The path as given.
        file: String,
        /// The operating system's reason.
        reason: String,
    },
    /// The extension is neither `.stl` nor `.obj`.
    #[error("tool mesh {file}: unknown format `{extension}`, expected .stl or .obj")]
    UnknownFormat {
        /// The path as given.
        file: String,
        /// The extension found (empty if none).
        extension: String,
    },
    /// The reader rejected the contents.
    #[error("tool mesh {file}: {location}: {reason}")]
    Format {
        /// The path as given.
        file: String,
        /// Where: `facet k` (STL), `line k` (OBJ), `header`, or `file`.
        location: String,
        /// What the reader found wrong.
        reason: String,
    },
    /// No triangles.
    #[error("tool mesh {file} has no triangles")]
    Empty {
        /// The path as given.
        file: String,
    },
    /// A coordinate that is NaN or infinite (after scaling).
    #[error("tool mesh {file}: {location}: non-finite coordinate {}", readable_number(*.value))]
    NonFinite {
        /// The path as given.
        file: String,
        /// Where: `facet k` (STL), `line k` (OBJ) or `vertex k`.
        location: String,
        /// The offending value.
        value: f64,
    },
    /// A triangle of (nearly) zero area.
    #[error(
        "tool mesh {file}: triangle {triangle} {}, {}, {} is degenerate: area {area:e} mm², expected > {DEGENERATE_AREA:e} × (longest edge)²",
        point(.a),
        point(.b),
        point(.c)
    )]
    Degenerate {
        /// The path as given.
        file: String,
        /// 1-based triangle number (file order; OBJ polygons triangulated).
        triangle: usize,
        /// Its first vertex \[mm\].
        a: [f64; 3],
        /// Its second vertex \[mm\].
        b: [f64; 3],
        /// Its third vertex \[mm\].
        c: [f64; 3],
        /// Its area \[mm²\].
        area: f64,
    },
    /// `require_closed` and an edge that is not shared by exactly two
    /// consistently oriented triangles.
    #[error("tool mesh {file} is not closed: the edge {} – {} is {defect}", point(.a), point(.b))]
    NotClosed {
        /// The path as given.
        file: String,
        /// One end of the first offending edge \[mm\].
        a: [f64; 3],
        /// The other end \[mm\].
        b: [f64; 3],
        /// What is wrong with it.
        defect: EdgeDefect,
    },
    /// A closed mesh whose normals point inwards.
    #[error(
        "tool mesh {file} is closed but inside out (enclosed volume {} mm³ < 0): its triangles run clockwise seen from outside (MeshOptions::flip_normals reverses them; a case's [[tool]] orients closed meshes itself)",
        readable_number(*.volume)
    )]
    InsideOut {
        /// The path as given.
        file: String,
        /// The signed enclosed volume \[mm³\].
        volume: f64,
    },
    /// An option out of range.
    #[error("tool mesh {file}: {option} = {}: expected {expected}", readable_number(*.value))]
    Option {
        /// The path as given.
        file: String,
        /// The option's name.
        option: &'static str,
        /// The value given.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// A vertex index out of range (in [`MeshSurface::from_triangles`]).
    #[error(
        "tool mesh {file}: triangle {triangle} refers to vertex {vertex}, but there are {count}"
    )]
    Index {
        /// The source name.
        file: String,
        /// 1-based triangle number.
        triangle: usize,
        /// The 0-based vertex index.
        vertex: usize,
        /// The number of vertices.
        count: usize,
    },
    /// More vertices than the tree's 32-bit indices hold, or the tree
    /// could not be built.
    #[error("tool mesh {file}: {reason}")]
    Build {
        /// The path as given.
        file: String,
        /// Why.
        reason: String,
    },
}

/// A rigid tool given by a triangle mesh, in its own frame (place it with
/// [`super::Placed`]). See the module doc for the sign, normal, Hessian and
/// culling conventions.
#[derive(Clone)]
pub struct MeshSurface {
    trimesh: TriMesh,
    vertices: Vec<Vector3<f64>>,
    triangles: Vec<[usize; 3]>,
    face_normals: Vec<Vector3<f64>>,
    aabb: Aabb,
    surface_tolerance: f64,
    closed: bool,
    source: String,
}

impl std::fmt::Debug for MeshSurface {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeshSurface")
            .field("source", &self.source)
            .field("vertices", &self.vertices.len())
            .field("triangles", &self.triangles.len())
            .field("closed", &self.closed)
            .finish_non_exhaustive()
    }
}

fn glam(v: &Vector3<f64>) -> GlamVector {
    GlamVector::new(v.x, v.y, v.z)
}

fn nalgebra(v: GlamVector) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

/// A point for messages: `(x, y, z)`, each [`readable_number`].
fn point(p: &[f64; 3]) -> String {
    format!(
        "({}, {}, {})",
        readable_number(p[0]),
        readable_number(p[1]),
        readable_number(p[2])
    )
}

fn array(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// One triangle as read, with where it came from for messages.
struct SoupTriangle {
    vertices: [Vector3<f64>; 3],
    location: String,
}

impl MeshSurface {
    /// Reads a tool mesh from an STL (binary or ASCII) or OBJ file, chosen
    /// by the extension (case-insensitive). STL facet normals are ignored:
    /// the vertex order (right-hand rule) orients each triangle. OBJ
    /// polygons are triangulated as fans; every object of the file is
    /// kept.
    ///
    /// # Errors
    /// An unreadable or malformed file, no triangles, a non-finite
    /// coordinate, a degenerate triangle, an invalid option, an open mesh
    /// with `require_closed`, a closed mesh that is inside out.
    pub fn from_file(path: &Path, options: &MeshOptions) -> Result<Self, MeshToolError> {
        let file = path.display().to_string();
        check_options(&file, options)?;
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_lowercase())
            .unwrap_or_default();
        let soup = match extension.as_str() {
            "stl" => read_stl(path, &file)?,
            "obj" => read_obj(path, &file)?,
            _ => {
                return Err(MeshToolError::UnknownFormat { file, extension });
            }
        };
        let mut vertices = Vec::with_capacity(3 * soup.len());
        let mut triangles = Vec::with_capacity(soup.len());
        for (k, triangle) in soup.iter().enumerate() {
            for v in &triangle.vertices {
                let scaled = v * options.scale;
                if let Some(value) = scaled.iter().copied().find(|c| !c.is_finite()) {
                    return Err(MeshToolError::NonFinite {
                        file,
                        location: triangle.location.clone(),
                        value,
                    });
                }
                // −0.0 and 0.0 are one position: merge them.
                vertices.push(scaled.map(|c| c + 0.0));
            }
            triangles.push([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        Self::build(
            file,
            vertices,
            triangles,
            options.flip_normals,
            options.require_closed,
        )
    }

    /// A tool mesh from vertex positions and triangles (vertex indices,
    /// counter-clockwise seen from the free side); `source` names it in
    /// messages. `options.scale` multiplies the positions.
    ///
    /// # Errors
    /// As [`MeshSurface::from_file`], and a vertex index out of range.
    pub fn from_triangles(
        source: &str,
        vertices: &[Vector3<f64>],
        triangles: &[[usize; 3]],
        options: &MeshOptions,
    ) -> Result<Self, MeshToolError> {
        let file = source.to_string();
        check_options(&file, options)?;
        for (k, t) in triangles.iter().enumerate() {
            if let Some(&vertex) = t.iter().find(|&&i| i >= vertices.len()) {
                return Err(MeshToolError::Index {
                    file,
                    triangle: k + 1,
                    vertex,
                    count: vertices.len(),
                });
            }
        }
        let mut scaled = Vec::with_capacity(vertices.len());
        for (k, v) in vertices.iter().enumerate() {
            let s = v * options.scale;
            if let Some(value) = s.iter().copied().find(|c| !c.is_finite()) {
                return Err(MeshToolError::NonFinite {
                    file,
                    location: format!("vertex {k}"),
                    value,
                });
            }
            scaled.push(s.map(|c| c + 0.0));
        }
        Self::build(
            file,
            scaled,
            triangles.to_vec(),
            options.flip_normals,
            options.require_closed,
        )
    }

    fn build(
        file: String,
        vertices: Vec<Vector3<f64>>,
        mut triangles: Vec<[usize; 3]>,
        flip: bool,
        require_closed: bool,
    ) -> Result<Self, MeshToolError> {
        if triangles.is_empty() {
            return Err(MeshToolError::Empty { file });
        }
        for (k, t) in triangles.iter().enumerate() {
            let [a, b, c] = t.map(|i| vertices[i]);
            let area = 0.5 * (b - a).cross(&(c - a)).norm();
            let longest = (b - a)
                .norm_squared()
                .max((c - b).norm_squared())
                .max((a - c).norm_squared());
            if area.is_nan() || area <= DEGENERATE_AREA * longest || longest == 0.0 {
                return Err(MeshToolError::Degenerate {
                    file,
                    triangle: k + 1,
                    a: array(&a),
                    b: array(&b),
                    c: array(&c),
                    area,
                });
            }
        }
        if flip {
            for t in &mut triangles {
                t.swap(1, 2);
            }
        }
        if vertices.len() > u32::MAX as usize {
            return Err(MeshToolError::Build {
                file,
                reason: format!(
                    "{} vertices, at most {} supported",
                    vertices.len(),
                    u32::MAX
                ),
            });
        }
        let trimesh = TriMesh::with_flags(
            vertices.iter().map(glam).collect(),
            triangles.iter().map(|t| t.map(|i| i as u32)).collect(),
            TriMeshFlags::ORIENTED | TriMeshFlags::MERGE_DUPLICATE_VERTICES,
        )
        .map_err(|e| MeshToolError::Build {
            file: file.clone(),
            reason: e.to_string(),
        })?;
        // Work on the merged mesh from here on: one index per position.
        let vertices: Vec<Vector3<f64>> = trimesh.vertices().iter().map(|v| nalgebra(*v)).collect();
        let triangles: Vec<[usize; 3]> = trimesh
            .indices()
            .iter()
            .map(|t| t.map(|i| i as usize))
            .collect();
        let defect = first_edge_defect(&triangles);
        if require_closed && let Some((a, b, defect)) = defect {
            return Err(MeshToolError::NotClosed {
                file,
                a: array(&vertices[a]),
                b: array(&vertices[b]),
                defect,
            });
        }
        let closed = defect.is_none();
        if closed {
            // Divergence theorem: V = Σ a · (b × c) / 6 over the triangles.
            let volume: f64 = triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|i| vertices[i]);
                    a.dot(&b.cross(&c)) / 6.0
                })
                .sum();
            if volume < 0.0 {
                return Err(MeshToolError::InsideOut { file, volume });
            }
        }
        let face_normals = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| vertices[i]);
                (b - a).cross(&(c - a)).normalize()
            })
            .collect();
        let aabb = trimesh.local_aabb();
        let diagonal = (aabb.maxs - aabb.mins).length();
        Ok(Self {
            trimesh,
            vertices,
            triangles,
            face_normals,
            aabb,
            surface_tolerance: SURFACE_FRACTION * diagonal,
            closed,
            source: file,
        })
    }

    /// Whether the mesh is closed, manifold and consistently oriented
    /// (then `d < 0` is the inside of the solid it bounds).
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// The file (or source) the mesh came from.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The mesh's own triangles (duplicate positions merged), in its frame
    /// \[mm\].
    pub fn tessellation(&self) -> Tessellation {
        Tessellation {
            vertices: self.vertices.clone(),
            triangles: self.triangles.clone(),
        }
    }

    /// The normal on an edge or vertex when the point is on it: the
    /// normalised pseudo-normal, or the face normal if that vanishes.
    fn pseudo_normal(&self, triangle: usize, location: &TrianglePointLocation) -> Vector3<f64> {
        let face = self.face_normals[triangle];
        let Some(pseudo) = self.trimesh.pseudo_normals() else {
            return face;
        };
        let n = match *location {
            TrianglePointLocation::OnEdge(i, _) => pseudo
                .edges_pseudo_normal
                .get(triangle)
                .map(|e| nalgebra(e[i as usize])),
            TrianglePointLocation::OnVertex(i) => pseudo
                .vertices_pseudo_normal
                .get(self.triangles[triangle][i as usize])
                .map(|v| nalgebra(*v)),
            _ => None,
        };
        n.and_then(|n| n.try_normalize(0.0)).unwrap_or(face)
    }
}

fn check_options(file: &str, options: &MeshOptions) -> Result<(), MeshToolError> {
    if options.scale.is_finite() && options.scale > 0.0 {
        Ok(())
    } else {
        Err(MeshToolError::Option {
            file: file.to_string(),
            option: "scale",
            value: options.scale,
            expected: "a positive finite factor to mm",
        })
    }
}

/// The first edge (in triangle order) not shared by exactly two triangles
/// running it in opposite directions: its two vertices and the defect.
fn first_edge_defect(triangles: &[[usize; 3]]) -> Option<(usize, usize, EdgeDefect)> {
    // Per undirected edge: (uses, uses running low → high).
    let mut edges: HashMap<(usize, usize), (usize, usize)> = HashMap::new();
    let directed = |t: &[usize; 3]| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])];
    for t in triangles {
        for (a, b) in directed(t) {
            let entry = edges.entry((a.min(b), a.max(b))).or_insert((0, 0));
            entry.0 += 1;
            entry.1 += usize::from(a < b);
        }
    }
    for t in triangles {
        for (a, b) in directed(t) {
            let (uses, forward) = edges[&(a.min(b), a.max(b))];
            let defect = match uses {
                1 => Some(EdgeDefect::Open),
                2 if forward != 1 => Some(EdgeDefect::Inconsistent),
                2 => None,
                n => Some(EdgeDefect::NonManifold { triangles: n }),
            };
            if let Some(defect) = defect {
                return Some((a, b, defect));
            }
        }
    }
    None
}

fn io_error(file: &str, error: &std::io::Error) -> MeshToolError {
    MeshToolError::Io {
        file: file.to_string(),
        reason: error.to_string(),
    }
}

/// Bytes of a binary STL: an 80-byte header, a u32 facet count, 50 bytes
/// per facet.
const STL_HEADER: usize = 84;
const STL_FACET: usize = 50;

fn read_stl(path: &Path, file: &str) -> Result<Vec<SoupTriangle>, MeshToolError> {
    let bytes = std::fs::read(path).map_err(|e| io_error(file, &e))?;
    if bytes.is_empty() {
        return Err(MeshToolError::Empty {
            file: file.to_string(),
        });
    }
    let declared = (bytes.len() >= STL_HEADER)
        .then(|| u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize);
    let binary_size_matches = declared
        .is_some_and(|n| STL_HEADER.checked_add(n.saturating_mul(STL_FACET)) == Some(bytes.len()));
    if bytes.starts_with(b"solid ") {
        match parse_stl(&bytes, file) {
            // Some binary writers start the header with "solid ": if the
            // text does not parse but the size is that of a binary file,
            // read it as binary.
            Err(_) if binary_size_matches => {
                let mut patched = bytes.clone();
                patched[0] = b'#';
                parse_stl(&patched, file)
            }
            result => result,
        }
    } else {
        match declared {
            None => Err(MeshToolError::Format {
                file: file.to_string(),
                location: "header".into(),
                reason: format!(
                    "{} bytes is too short for a binary STL ({STL_HEADER}-byte header) and the file does not start with `solid ` (ASCII STL)",
                    bytes.len()
                ),
            }),
            Some(n) if bytes.len() < STL_HEADER + n.saturating_mul(STL_FACET) => {
                Err(MeshToolError::Format {
                    file: file.to_string(),
                    location: "header".into(),
                    reason: format!(
                        "binary STL declares {n} facets ({} bytes) but has {} bytes (truncated, or not an STL file; an ASCII STL starts with `solid `)",
                        n.saturating_mul(STL_FACET).saturating_add(STL_HEADER),
                        bytes.len()
                    ),
                })
            }
            Some(_) => parse_stl(&bytes, file),
        }
    }
}

fn parse_stl(bytes: &[u8], file: &str) -> Result<Vec<SoupTriangle>, MeshToolError> {
    let mut cursor = std::io::Cursor::new(bytes);
    let reader = stl_io::create_stl_reader(&mut cursor).map_err(|e| MeshToolError::Format {
        file: file.to_string(),
        location: "header".into(),
        reason: e.to_string(),
    })?;
    let mut soup = Vec::new();
    for (k, facet) in reader.enumerate() {
        let location = format!("facet {}", k + 1);
        let facet = facet.map_err(|e| MeshToolError::Format {
            file: file.to_string(),
            location: location.clone(),
            reason: e.to_string(),
        })?;
        let vertices = facet
            .vertices
            .map(|v| Vector3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])));
        if let Some(value) = vertices.iter().flatten().copied().find(|c| !c.is_finite()) {
            return Err(MeshToolError::NonFinite {
                file: file.to_string(),
                location,
                value,
            });
        }
        soup.push(SoupTriangle { vertices, location });
    }
    Ok(soup)
}

fn obj_options() -> tobj::LoadOptions {
    tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    }
}

fn parse_obj(text: &str) -> tobj::LoadResult {
    // Materials are irrelevant to a tool: never open an `mtllib`.
    tobj::load_obj_buf(&mut text.as_bytes(), &obj_options(), |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
}

/// The 1-based line at which the reader first fails: the shortest prefix
/// of whole lines it rejects (bisection; a prefix of a valid file is valid
/// except for forward references, which OBJ does not allow).
fn obj_error_line(text: &str) -> Option<usize> {
    let ends: Vec<usize> = text
        .match_indices('\n')
        .map(|(i, _)| i + 1)
        .chain(std::iter::once(text.len()))
        .collect();
    let fails = |lines: usize| parse_obj(&text[..ends[lines - 1]]).is_err();
    let (mut good, mut bad) = (0, ends.len());
    if !fails(bad) {
        return None;
    }
    while bad - good > 1 {
        let mid = (good + bad) / 2;
        if fails(mid) {
            bad = mid;
        } else {
            good = mid;
        }
    }
    Some(bad)
}

/// The first `v` line with a coordinate that is not finite (1-based).
fn obj_non_finite_line(text: &str) -> Option<usize> {
    text.lines()
        .position(|line| {
            let mut tokens = line.split_whitespace();
            tokens.next() == Some("v")
                && tokens
                    .take(3)
                    .any(|t| t.parse::<f64>().is_ok_and(|c| !c.is_finite()))
        })
        .map(|i| i + 1)
}

fn read_obj(path: &Path, file: &str) -> Result<Vec<SoupTriangle>, MeshToolError> {
    let bytes = std::fs::read(path).map_err(|e| io_error(file, &e))?;
    let text = String::from_utf8(bytes).map_err(|e| MeshToolError::Format {
        file: file.to_string(),
        location: format!("byte {}", e.utf8_error().valid_up_to() + 1),
        reason: "not UTF-8 text (an OBJ file is text)".into(),
    })?;
    let (models, _) = parse_obj(&text).map_err(|e| MeshToolError::Format {
        file: file.to_string(),
        location: obj_error_line(&text).map_or_else(|| "file".into(), |l| format!("line {l}")),
        reason: e.to_string(),
    })?;
    let mut soup = Vec::new();
    for model in &models {
        let positions = &model.mesh.positions;
        for (k, t) in model.mesh.indices.chunks_exact(3).enumerate() {
            let mut vertices = [Vector3::zeros(); 3];
            for (v, &i) in vertices.iter_mut().zip(t) {
                let i = 3 * i as usize;
                let Some(p) = positions.get(i..i + 3) else {
                    return Err(MeshToolError::Format {
                        file: file.to_string(),
                        location: format!("object `{}`, triangle {}", model.name, k + 1),
                        reason: "vertex index out of range".into(),
                    });
                };
                *v = Vector3::new(p[0], p[1], p[2]);
            }
            if let Some(value) = vertices.iter().flatten().copied().find(|c| !c.is_finite()) {
                return Err(MeshToolError::NonFinite {
                    file: file.to_string(),
                    location: obj_non_finite_line(&text).map_or_else(
                        || format!("triangle {}", soup.len() + 1),
                        |l| format!("line {l}"),
                    ),
                    value,
                });
            }
            soup.push(SoupTriangle {
                vertices,
                location: format!("triangle {}", soup.len() + 1),
            });
        }
    }
    Ok(soup)
}

impl RigidSurface for MeshSurface {
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        if !x.iter().all(|c| c.is_finite()) {
            return None;
        }
        let point = glam(x);
        // A NaN bound answers every point, as `d > NaN` is false for the
        // analytic shapes.
        let bound = if max_distance.is_nan() {
            f64::MAX
        } else {
            max_distance.max(0.0)
        };
        let (projection, (triangle, location)) = self
            .trimesh
            .project_local_point_and_get_location_with_max_dist(point, false, bound)
            .or_else(|| {
                // Deeper inside a closed mesh than the bound: still answer.
                (self.closed && self.aabb.contains_local_point(point)).then(|| {
                    self.trimesh
                        .project_local_point_and_get_location_with_max_dist(point, false, f64::MAX)
                })?
            })?;
        let triangle = triangle as usize;
        let p = nalgebra(projection.point);
        let offset = x - p;
        let r = offset.norm();
        let sign = if projection.is_inside { -1.0 } else { 1.0 };
        let answer = match location {
            TrianglePointLocation::OnFace(..) | TrianglePointLocation::OnSolid => {
                let n = self.face_normals[triangle];
                SurfacePoint {
                    distance: offset.dot(&n),
                    normal: n,
                    hessian: Matrix3::zeros(),
                }
            }
            _ if r <= self.surface_tolerance => SurfacePoint {
                distance: sign * r,
                normal: self.pseudo_normal(triangle, &location),
                hessian: Matrix3::zeros(),
            },
            TrianglePointLocation::OnEdge(i, _) => {
                let t = self.triangles[triangle];
                let (a, b) = match i {
                    0 => (t[0], t[1]),
                    1 => (t[1], t[2]),
                    _ => (t[0], t[2]),
                };
                let tangent = (self.vertices[b] - self.vertices[a]).normalize();
                let n = offset * (sign / r);
                let distance = sign * r;
                SurfacePoint {
                    distance,
                    normal: n,
                    hessian: (Matrix3::identity()
                        - tangent * tangent.transpose()
                        - n * n.transpose())
                        / distance,
                }
            }
            TrianglePointLocation::OnVertex(_) => {
                let n = offset * (sign / r);
                let distance = sign * r;
                SurfacePoint {
                    distance,
                    normal: n,
                    hessian: (Matrix3::identity() - n * n.transpose()) / distance,
                }
            }
        };
        (answer.distance <= max_distance || max_distance.is_nan() || projection.is_inside)
            .then_some(answer)
    }
}
