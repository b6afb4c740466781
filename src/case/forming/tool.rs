//! The `[[tool]]` tables of a forming case: each rigid tool's shape and
//! its geometry keys, its side, origin, axis, friction and drawn extent,
//! its motion (fixed, prescribed or floating) and the plies it touches;
//! then the openings of the plates that follow a pyramid punch. Key-by-key documentation:
//! `docs/cases.md`, "Forming cases".

use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use toml::Spanned;

use super::ply::PlySpec;
use super::raw::ToolRaw;
use super::{GravitySpec, KG_IN_T, STANDARD_GRAVITY, quoted_names, shown_list, vector3};
use crate::case::bounds::bound;
use crate::config::{ConfigError, TomlChecker};

/// A tool's surface.
#[derive(Debug, Clone, PartialEq)]
pub enum ToolShape {
    /// The plane through the origin normal to the axis (free side along it).
    Plane,
    /// A sphere of radius `radius` about the origin.
    Sphere {
        /// Radius \[mm\].
        radius: f64,
    },
    /// An infinite cylinder of radius `radius` about the axis.
    Cylinder {
        /// Radius \[mm\].
        radius: f64,
    },
    /// A torus about the axis.
    Torus {
        /// Radius of the centre circle \[mm\].
        major_radius: f64,
        /// Radius of the tube \[mm\].
        minor_radius: f64,
    },
    /// A plate whose face (normal = axis, towards the ply) has a round
    /// opening with a fillet (a die or a blankholder).
    PlateWithHole {
        /// Opening radius \[mm\].
        opening_radius: f64,
        /// Fillet radius \[mm\].
        fillet_radius: f64,
    },
    /// A rounded regular pyramid, apex first along the axis reversed (the
    /// axis points from the apex to the base; the origin is the solid's
    /// lowest point), [`crate::contact::Pyramid`].
    Pyramid {
        /// Number of lateral faces.
        sides: usize,
        /// Angle of the lateral faces to the base plane \[rad\].
        face_angle: f64,
        /// Rounding radius of the apex and every edge \[mm\].
        rounding_radius: f64,
        /// Height of the sharp core from its apex to its base \[mm\].
        height: f64,
        /// Direction of one base edge (unit, normal to the axis).
        edge_direction: Vector3<f64>,
    },
    /// A plate whose face (normal = axis, towards the ply) has a rounded
    /// polygonal opening with a fillet, following a pyramid punch's section
    /// at the punch's full stroke grown by a clearance
    /// ([`crate::contact::PlateWithPolygonHole`],
    /// [`crate::contact::punch_opening`]).
    PlateWithPolygonHole {
        /// The name of the pyramid tool the opening follows.
        punch: String,
        /// Clearance between the punch's section and the opening \[mm\].
        clearance: f64,
        /// Fillet radius \[mm\].
        fillet_radius: f64,
        /// A point of the plane where the section is taken \[mm\] (`None`:
        /// the plate's origin).
        section_at: Option<Vector3<f64>>,
        /// The opening's polygon in the plate's local `(x, y)` \[mm\]
        /// (counter-clockwise), computed from the punch when the case is
        /// read.
        polygon: Vec<[f64; 2]>,
        /// The opening's corner radius \[mm\], computed likewise.
        corner_radius: f64,
    },
    /// A triangle mesh from an STL or OBJ file.
    Mesh {
        /// Path (relative paths from the case file's folder).
        path: PathBuf,
        /// Scale to mm.
        scale: f64,
        /// Require a closed, consistently oriented mesh.
        closed: bool,
        /// Reverse every triangle: the free side of an open sheet is
        /// then the other one (a closed mesh is oriented by its volume).
        flip_normals: bool,
    },
}

/// How a tool moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ToolMotion {
    /// It does not move.
    Fixed,
    /// It translates by `displacement` \[mm\] along `direction` over the
    /// programme.
    Prescribed {
        /// Unit direction.
        direction: Vector3<f64>,
        /// Displacement at `λ = 1` \[mm\].
        displacement: f64,
    },
    /// It translates freely along `direction` with its mass under its
    /// weight.
    Floating {
        /// Unit direction.
        direction: Vector3<f64>,
        /// Mass \[t\].
        mass: f64,
        /// Dead force along `direction` \[N\] (its weight's component).
        weight: f64,
    },
}

/// One rigid tool.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolSpec {
    /// Name.
    pub name: String,
    /// Surface.
    pub shape: ToolShape,
    /// The surface's local origin \[mm\].
    pub origin: Vector3<f64>,
    /// The surface's local z axis (unit).
    pub axis: Vector3<f64>,
    /// `true` when the ply is inside a sphere, cylinder or torus.
    pub inside: bool,
    /// Coulomb friction coefficient.
    pub friction: f64,
    /// Motion.
    pub motion: ToolMotion,
    /// Half-size of the drawn surface (planes, plates) \[mm\].
    pub extent: f64,
    /// The plies the tool has a contact term with (indices into
    /// [`FormingCase::plies`](super::FormingCase::plies), ascending):
    /// the key `plies`, every ply by default (`docs/cases.md`,
    /// "`[[tool]]`").
    pub plies: Vec<usize>,
    /// Line of the tool's `file` (a mesh tool) or `shape` in the case
    /// file: errors of its surface name it.
    pub line: usize,
}

/// Validates the `[[tool]]` tables in order, each with a name no other
/// tool has and the plies it touches among `plies`, then computes the
/// openings that follow a punch ([`resolve_openings`]).
pub(super) fn tools(
    check: &TomlChecker,
    raw: &[ToolRaw],
    base_dir: &Path,
    gravity: Option<&GravitySpec>,
    plies: &[PlySpec],
) -> Result<Vec<ToolSpec>, ConfigError> {
    let mut tools = Vec::new();
    for (i, t) in raw.iter().enumerate() {
        let mut tool = tool_spec(check, t, i, base_dir, gravity)?;
        tool.plies = tool_plies(check, t, i, plies)?;
        if tools.iter().any(|q: &ToolSpec| q.name == tool.name) {
            return Err(check.invalid(
                0,
                &format!("tool[{i}].name"),
                format!("\"{}\"", tool.name),
                "a name no other tool has",
            ));
        }
        tools.push(tool);
    }
    resolve_openings(check, raw, &mut tools)?;
    Ok(tools)
}

/// A tool's `plies`: the names of the plies it has a contact term with,
/// each a ply of the case and each once, at least one; every ply when
/// the key is left out. Returned as ply indices in ascending order (the
/// order of the plies in the case, whatever the order of the list).
fn tool_plies(
    check: &TomlChecker,
    t: &ToolRaw,
    i: usize,
    plies: &[PlySpec],
) -> Result<Vec<usize>, ConfigError> {
    let Some(given) = &t.plies else {
        return Ok((0..plies.len()).collect());
    };
    let key = format!("tool[{i}].plies");
    let line = check.line_of(given);
    let names = given.get_ref();
    let shown = format!("[{}]", quoted_names(names.iter().map(String::as_str)));
    let known = quoted_names(plies.iter().map(|p| p.name.as_str()));
    if names.is_empty() {
        return Err(check.invalid(
            line,
            &key,
            shown,
            &format!(
                "the names of the plies the tool touches, at least one (the case's plies: {known}; leave the key out for every ply)"
            ),
        ));
    }
    let mut indices = Vec::with_capacity(names.len());
    for name in names {
        let Some(k) = plies.iter().position(|p| &p.name == name) else {
            return Err(check.invalid(
                line,
                &key,
                shown,
                &format!(
                    "the names of plies of the case, one of: {known} (\"{name}\" is none of them)"
                ),
            ));
        };
        if indices.contains(&k) {
            return Err(check.invalid(
                line,
                &key,
                shown,
                &format!("each ply once (\"{name}\" is named twice)"),
            ));
        }
        indices.push(k);
    }
    indices.sort_unstable();
    Ok(indices)
}

/// A pyramid tool's shape and its placement (the local frame of
/// `Placement::new(origin, axis, None)`, in which the base edge's azimuth
/// is measured), as the model builds it.
///
/// # Errors
/// The shape's or the placement's [`ShapeError`](crate::contact::ShapeError).
pub(crate) fn pyramid_of(
    spec: &ToolSpec,
) -> Result<Option<(crate::contact::Pyramid, crate::contact::Placement)>, crate::contact::ShapeError>
{
    let ToolShape::Pyramid {
        sides,
        face_angle,
        rounding_radius,
        height,
        edge_direction,
    } = &spec.shape
    else {
        return Ok(None);
    };
    let placement = crate::contact::Placement::new(spec.origin, spec.axis, None)?;
    let local = placement.vector_to_local(edge_direction);
    let pyramid = crate::contact::Pyramid::new(
        *sides,
        *face_angle,
        *rounding_radius,
        *height,
        local.y.atan2(local.x),
    )?;
    Ok(Some((pyramid, placement)))
}

/// Computes the opening of every `plate-with-polygon-hole` from its punch
/// (the named pyramid tool at its full stroke, `docs/cases.md`).
fn resolve_openings(
    check: &TomlChecker,
    raw: &[ToolRaw],
    tools: &mut [ToolSpec],
) -> Result<(), ConfigError> {
    for i in 0..tools.len() {
        let ToolShape::PlateWithPolygonHole {
            punch,
            clearance,
            section_at,
            ..
        } = &tools[i].shape
        else {
            continue;
        };
        let line = raw[i].punch.as_ref().map_or(0, |p| check.line_of(p));
        let key = format!("tool[{i}].punch");
        let shown = format!("\"{punch}\"");
        let Some(punch_spec) = tools.iter().find(|t| &t.name == punch) else {
            let names: Vec<String> = tools
                .iter()
                .filter(|t| matches!(t.shape, ToolShape::Pyramid { .. }))
                .map(|t| format!("\"{}\"", t.name))
                .collect();
            return Err(check.invalid(
                line,
                &key,
                shown,
                &format!(
                    "the name of a pyramid tool (here: {})",
                    if names.is_empty() {
                        "none".to_string()
                    } else {
                        names.join(", ")
                    }
                ),
            ));
        };
        let invalid = |why: String| check.invalid(line, &key, shown.clone(), &why);
        let (pyramid, placement) = match pyramid_of(punch_spec) {
            Ok(Some(p)) => p,
            Ok(None) => {
                return Err(invalid(format!(
                    "the name of a pyramid tool (\"{punch}\" is not a pyramid)"
                )));
            }
            Err(e) => return Err(invalid(format!("a valid pyramid ({e})"))),
        };
        let stroke = match punch_spec.motion {
            ToolMotion::Prescribed {
                direction,
                displacement,
            } => direction * displacement,
            _ => Vector3::zeros(),
        };
        let plate = &tools[i];
        let frame = crate::contact::Placement::new(plate.origin, plate.axis, None)
            .map_err(|e| invalid(format!("a valid plate placement ({e})")))?;
        let at = section_at.unwrap_or(plate.origin);
        let (polygon, corner) =
            crate::contact::punch_opening(&pyramid, &placement, &stroke, &frame, &at, *clearance)
                .map_err(|e| {
                invalid(format!(
                    "a pyramid whose section by the plate's plane at full stroke \
                         gives the opening ({e})"
                ))
            })?;
        let polygon: Vec<[f64; 2]> = polygon.iter().map(|p| [p.x, p.y]).collect();
        if let ToolShape::PlateWithPolygonHole {
            polygon: p,
            corner_radius,
            ..
        } = &mut tools[i].shape
        {
            *p = polygon;
            *corner_radius = corner;
        }
    }
    Ok(())
}

/// The surfaces a `shape` key names.
#[derive(Clone, Copy)]
enum Kind {
    Plane,
    Sphere,
    Cylinder,
    Torus,
    Plate,
    Pyramid,
    PolygonPlate,
    Mesh,
}

/// The placement and contact keys of a tool besides its shape.
struct Frame {
    inside: bool,
    origin: Vector3<f64>,
    axis: Vector3<f64>,
    friction: f64,
    extent: f64,
}

/// One `[[tool]]` table: its shape, its geometry keys checked against the
/// shape, its frame, friction and extent, and its motion, in that order
/// (the weight of a floating tool without one is its mass under
/// `gravity`, or under standard gravity along −z).
fn tool_spec(
    check: &TomlChecker,
    t: &ToolRaw,
    i: usize,
    base_dir: &Path,
    gravity: Option<&GravitySpec>,
) -> Result<ToolSpec, ConfigError> {
    let name = t.name.clone().unwrap_or_else(|| format!("tool{}", i + 1));
    let (kind, shape) = tool_shape(check, t, i, base_dir)?;
    check_geometry_keys(check, t, i, kind)?;
    let Frame {
        inside,
        origin,
        axis,
        friction,
        extent,
    } = frame(check, t, i)?;
    let motion = tool_motion(check, t, i, gravity)?;
    Ok(ToolSpec {
        name,
        shape,
        origin,
        axis,
        inside,
        friction,
        motion,
        extent,
        plies: Vec::new(),
        line: t
            .file
            .as_ref()
            .map_or(check.line_of(&t.shape), |f| check.line_of(f)),
    })
}

/// A tool's `shape` and the geometry keys the shape needs.
fn tool_shape(
    check: &TomlChecker,
    t: &ToolRaw,
    i: usize,
    base_dir: &Path,
) -> Result<(Kind, ToolShape), ConfigError> {
    let key = |k: &str| format!("tool[{i}].{k}");
    let positive = |v: &Option<Spanned<f64>>, k: &str, what: &str| match v {
        None => Err(check.missing(&key(k), what)),
        Some(v) => bound(&format!("tool.{k}")).spanned(check, v, &key(k)),
    };
    let kind = check.choice(
        &t.shape,
        &key("shape"),
        &[
            ("plane", Kind::Plane),
            ("sphere", Kind::Sphere),
            ("cylinder", Kind::Cylinder),
            ("torus", Kind::Torus),
            ("plate-with-hole", Kind::Plate),
            ("pyramid", Kind::Pyramid),
            ("plate-with-polygon-hole", Kind::PolygonPlate),
            ("mesh", Kind::Mesh),
        ],
    )?;
    let shape = match kind {
        Kind::Plane => ToolShape::Plane,
        Kind::Sphere => ToolShape::Sphere {
            radius: positive(&t.radius, "radius", "a radius > 0 mm")?,
        },
        Kind::Cylinder => ToolShape::Cylinder {
            radius: positive(&t.radius, "radius", "a radius > 0 mm")?,
        },
        Kind::Torus => ToolShape::Torus {
            major_radius: positive(&t.major_radius, "major_radius", "a radius > 0 mm")?,
            minor_radius: positive(&t.minor_radius, "minor_radius", "a radius > 0 mm")?,
        },
        Kind::Plate => ToolShape::PlateWithHole {
            opening_radius: positive(&t.opening_radius, "opening_radius", "a radius > 0 mm")?,
            fillet_radius: positive(&t.fillet_radius, "fillet_radius", "a radius > 0 mm")?,
        },
        Kind::Pyramid => pyramid_shape(check, t, i)?,
        Kind::PolygonPlate => polygon_plate_shape(check, t, i)?,
        Kind::Mesh => mesh_shape(check, t, i, base_dir)?,
    };
    Ok((kind, shape))
}

/// A `mesh` tool's keys: the file, its scale, whether it must be closed,
/// and `flip_normals` (open sheets only). A closed mesh whose triangles
/// run inside out is oriented outward by its enclosed volume when the
/// model is built; that is recorded as a warning here (the file is read
/// once more for it; an unreadable file is reported by the build).
fn mesh_shape(
    check: &TomlChecker,
    t: &ToolRaw,
    i: usize,
    base_dir: &Path,
) -> Result<ToolShape, ConfigError> {
    let key = |k: &str| format!("tool[{i}].{k}");
    let Some(file) = &t.file else {
        return Err(check.missing(&key("file"), "an STL or OBJ file"));
    };
    let path = base_dir.join(file.get_ref());
    let scale = match &t.scale {
        None => 1.0,
        Some(s) => bound("tool.scale").spanned(check, s, &key("scale"))?,
    };
    let closed = t.closed.as_ref().is_none_or(|c| *c.get_ref());
    let flip_normals = t.flip_normals.as_ref().is_some_and(|f| *f.get_ref());
    if let Some(f) = &t.flip_normals
        && closed
    {
        return Err(check.invalid(
            check.line_of(f),
            &key("flip_normals"),
            f.get_ref().to_string(),
            "flip_normals only with closed = false (a closed mesh is oriented outward by its \
             enclosed volume)",
        ));
    }
    let options = crate::contact::MeshOptions {
        scale,
        require_closed: false,
        flip_normals,
    };
    if let Err(crate::contact::MeshToolError::InsideOut { volume, .. }) =
        crate::contact::MeshSurface::from_file(&path, &options)
    {
        check.warn(
            check.line_of(file),
            &key("file"),
            format!("{:?}", file.get_ref()),
            String::new(),
            &format!(
                "the closed mesh is inside out (enclosed volume {} mm³): its triangles are \
                 reversed so that its normals point out of the tool",
                crate::config::readable_number(crate::config::significant(volume, 6))
            ),
        );
    }
    Ok(ToolShape::Mesh {
        path,
        scale,
        closed,
        flip_normals,
    })
}

/// A `pyramid`'s keys: sides, face angle, axis and base edge direction
/// (not along the axis), rounding radius and height.
fn pyramid_shape(check: &TomlChecker, t: &ToolRaw, i: usize) -> Result<ToolShape, ConfigError> {
    let key = |k: &str| format!("tool[{i}].{k}");
    let positive = |v: &Option<Spanned<f64>>, k: &str, what: &str| match v {
        None => Err(check.missing(&key(k), what)),
        Some(v) => bound(&format!("tool.{k}")).spanned(check, v, &key(k)),
    };
    let sides = match &t.sides {
        None => 3,
        Some(n) => bound("tool.sides").count(check, n, &key("sides"))?,
    };
    let face_angle = match &t.face_angle_deg {
        // The regular tetrahedron: cos α = 1/3 (α ≈ 70.53°).
        None => (1.0_f64 / 3.0).acos(),
        Some(a) => bound("tool.face_angle_deg")
            .spanned(check, a, &key("face_angle_deg"))?
            .to_radians(),
    };
    let axis = match &t.axis {
        None => Vector3::z(),
        Some(a) => vector3(check, a, &key("axis"), None)?,
    };
    let edge_direction = match &t.edge_direction {
        None => Vector3::x(),
        Some(e) => vector3(check, e, &key("edge_direction"), None)?,
    };
    let projected = edge_direction - axis * edge_direction.dot(&axis);
    if projected.norm() <= 1e-6 {
        let line = t.edge_direction.as_ref().map_or(0, |e| check.line_of(e));
        return Err(check.invalid(
            line,
            &key("edge_direction"),
            shown_list(edge_direction.as_slice()),
            &format!(
                "a direction not parallel to the axis {}",
                shown_list(axis.as_slice())
            ),
        ));
    }
    Ok(ToolShape::Pyramid {
        sides,
        face_angle,
        rounding_radius: positive(
            &t.rounding_radius,
            "rounding_radius",
            "the radius of the apex and the edges > 0 mm",
        )?,
        height: positive(
            &t.height,
            "height",
            "the pyramid's height from the apex to the base > 0 mm (enough to reach \
             through the die at full depth)",
        )?,
        edge_direction: projected.normalize(),
    })
}

/// A `plate-with-polygon-hole`'s keys: the punch it follows, the
/// clearance, the fillet radius and where the section is taken (the
/// opening itself is computed by [`resolve_openings`]).
fn polygon_plate_shape(
    check: &TomlChecker,
    t: &ToolRaw,
    i: usize,
) -> Result<ToolShape, ConfigError> {
    let key = |k: &str| format!("tool[{i}].{k}");
    let positive = |v: &Option<Spanned<f64>>, k: &str, what: &str| match v {
        None => Err(check.missing(&key(k), what)),
        Some(v) => bound(&format!("tool.{k}")).spanned(check, v, &key(k)),
    };
    Ok(ToolShape::PlateWithPolygonHole {
        punch: match &t.punch {
            None => {
                return Err(check.missing(
                    &key("punch"),
                    "the name of the pyramid tool whose section the opening follows",
                ));
            }
            Some(p) => p.get_ref().clone(),
        },
        clearance: match &t.clearance {
            None => {
                return Err(check.missing(
                    &key("clearance"),
                    "the clearance between the punch and the opening ≥ 0 mm",
                ));
            }
            Some(c) => bound("tool.clearance").spanned(check, c, &key("clearance"))?,
        },
        fillet_radius: positive(&t.fillet_radius, "fillet_radius", "a radius > 0 mm")?,
        section_at: match &t.section_at {
            None => None,
            Some(v) => Some(vector3(
                check,
                v,
                &key("section_at"),
                Some(bound("tool.section_at")),
            )?),
        },
        polygon: Vec::new(),
        corner_radius: 0.0,
    })
}

/// The keys of a `[[tool]]` table that depend on its shape, and those
/// that depend on its motion; `name`, `shape`, `friction` and `motion` are
/// taken by every tool. `docs/cases.md`, "Keys that do not apply".
fn shape_keys(kind: Kind) -> &'static [&'static str] {
    match kind {
        Kind::Plane => &["origin", "axis", "extent"],
        Kind::Sphere => &["origin", "radius", "side"],
        Kind::Cylinder => &["origin", "axis", "radius", "side", "extent"],
        Kind::Torus => &["origin", "axis", "major_radius", "minor_radius", "side"],
        Kind::Plate => &[
            "origin",
            "axis",
            "opening_radius",
            "fillet_radius",
            "extent",
        ],
        Kind::Pyramid => &[
            "origin",
            "axis",
            "sides",
            "face_angle_deg",
            "rounding_radius",
            "height",
            "edge_direction",
        ],
        Kind::PolygonPlate => &[
            "origin",
            "axis",
            "punch",
            "clearance",
            "fillet_radius",
            "section_at",
            "extent",
        ],
        Kind::Mesh => &["origin", "file", "scale", "closed", "flip_normals"],
    }
}

/// The keys each motion takes (`fixed`, `prescribed`, `floating`).
const FIXED_KEYS: &[&str] = &[];
const PRESCRIBED_KEYS: &[&str] = &["direction", "displacement"];
const FLOATING_KEYS: &[&str] = &["direction", "mass", "weight"];

/// Refuses a key the tool's shape does not take, naming those it does.
fn check_geometry_keys(
    check: &TomlChecker,
    t: &ToolRaw,
    i: usize,
    kind: Kind,
) -> Result<(), ConfigError> {
    let given = [
        check.given("origin", &t.origin),
        check.given("axis", &t.axis),
        check.given("radius", &t.radius),
        check.given("major_radius", &t.major_radius),
        check.given("minor_radius", &t.minor_radius),
        check.given("opening_radius", &t.opening_radius),
        check.given("fillet_radius", &t.fillet_radius),
        check.given("sides", &t.sides),
        check.given("face_angle_deg", &t.face_angle_deg),
        check.given("rounding_radius", &t.rounding_radius),
        check.given("height", &t.height),
        check.given("edge_direction", &t.edge_direction),
        check.given("punch", &t.punch),
        check.given("clearance", &t.clearance),
        check.given("section_at", &t.section_at),
        check.given("side", &t.side),
        check.given("file", &t.file),
        check.given("scale", &t.scale),
        check.given("closed", &t.closed),
        check.given("flip_normals", &t.flip_normals),
        check.given("extent", &t.extent),
    ];
    check.only_keys(
        &format!("tool[{i}]"),
        &given,
        shape_keys(kind),
        &format!("shape \"{}\"", t.shape.get_ref()),
    )
}

/// A tool's side (spheres, cylinders and tori only), origin, axis,
/// friction coefficient and drawn extent.
fn frame(check: &TomlChecker, t: &ToolRaw, i: usize) -> Result<Frame, ConfigError> {
    let key = |k: &str| format!("tool[{i}].{k}");
    let inside = match &t.side {
        None => false,
        Some(s) => check.choice(s, &key("side"), &[("outside", false), ("inside", true)])?,
    };
    let origin = match &t.origin {
        None => Vector3::zeros(),
        Some(o) => vector3(check, o, &key("origin"), Some(bound("tool.origin")))?,
    };
    let axis = match &t.axis {
        None => Vector3::z(),
        Some(a) => vector3(check, a, &key("axis"), None)?,
    };
    let friction = match &t.friction {
        None => 0.0,
        Some(f) => bound("tool.friction").spanned(check, f, &key("friction"))?,
    };
    let extent = match &t.extent {
        None => 200.0,
        // Drawn only: a kilometre is far beyond any press, and keeps the
        // drawn points finite.
        Some(e) => bound("tool.extent").spanned(check, e, &key("extent"))?,
    };
    Ok(Frame {
        inside,
        origin,
        axis,
        friction,
        extent,
    })
}

/// A tool's `motion` and the keys it takes (`direction`, `displacement`,
/// `mass`, `weight`), refusing those of another motion.
fn tool_motion(
    check: &TomlChecker,
    t: &ToolRaw,
    i: usize,
    gravity: Option<&GravitySpec>,
) -> Result<ToolMotion, ConfigError> {
    let key = |k: &str| format!("tool[{i}].{k}");
    #[derive(Clone, Copy)]
    enum Move {
        Fixed,
        Prescribed,
        Floating,
    }
    let motion_kind = match &t.motion {
        None => Move::Fixed,
        Some(m) => check.choice(
            m,
            &key("motion"),
            &[
                ("fixed", Move::Fixed),
                ("prescribed", Move::Prescribed),
                ("floating", Move::Floating),
            ],
        )?,
    };
    let direction = || match &t.direction {
        None => Err(check.missing(
            &key("direction"),
            "the unit direction [x, y, z] the tool moves along",
        )),
        Some(d) => vector3(check, d, &key("direction"), None),
    };
    let given = [
        check.given("direction", &t.direction),
        check.given("displacement", &t.displacement),
        check.given("mass", &t.mass),
        check.given("weight", &t.weight),
    ];
    let (takes, what) = match motion_kind {
        Move::Fixed => (
            FIXED_KEYS,
            "motion \"fixed\" (a tool that does not move takes none of direction, displacement, mass, weight)",
        ),
        Move::Prescribed => (PRESCRIBED_KEYS, "motion \"prescribed\""),
        Move::Floating => (FLOATING_KEYS, "motion \"floating\""),
    };
    check.only_keys(&format!("tool[{i}]"), &given, takes, what)?;
    let motion = match motion_kind {
        Move::Fixed => ToolMotion::Fixed,
        Move::Prescribed => {
            let displacement = match &t.displacement {
                None => {
                    return Err(check.missing(
                        &key("displacement"),
                        "the tool's displacement at the end of the programme [mm]",
                    ));
                }
                Some(d) => bound("tool.displacement").spanned(check, d, &key("displacement"))?,
            };
            ToolMotion::Prescribed {
                direction: direction()?,
                displacement,
            }
        }
        Move::Floating => {
            let direction = direction()?;
            floating(check, t, i, gravity, direction)?
        }
    };
    Ok(motion)
}

/// A floating tool's mass and weight (its mass under gravity along its
/// direction when no weight is given).
fn floating(
    check: &TomlChecker,
    t: &ToolRaw,
    i: usize,
    gravity: Option<&GravitySpec>,
    direction: Vector3<f64>,
) -> Result<ToolMotion, ConfigError> {
    let key = |k: &str| format!("tool[{i}].{k}");
    let Some(given_mass) = &t.mass else {
        return Err(check.missing(
            &key("mass"),
            "the floating tool's mass [kg] (a floating tool needs a mass and a weight)",
        ));
    };
    // An overflowing weight is the more telling reason (`mass = 1e308`).
    let g = gravity.map_or(-STANDARD_GRAVITY * Vector3::z(), |g| g.acceleration);
    if t.weight.is_none() && !(given_mass.get_ref() * KG_IN_T * g.dot(&direction)).is_finite() {
        return Err(check.invalid(
            check.line_of(given_mass),
            &key("mass"),
            crate::config::readable_number(*given_mass.get_ref()),
            "a mass whose weight (mass × gravity) is finite",
        ));
    }
    let mass = bound("tool.mass").spanned(check, given_mass, &key("mass"))? * KG_IN_T;
    let weight = match &t.weight {
        Some(w) => bound("tool.weight").spanned(check, w, &key("weight"))?,
        None => {
            let g = gravity.map_or(-STANDARD_GRAVITY * Vector3::z(), |g| g.acceleration);
            let weight = mass * g.dot(&direction);
            if !weight.is_finite() {
                return Err(check.invalid(
                    check.line_of(given_mass),
                    &key("mass"),
                    crate::config::readable_number(*given_mass.get_ref()),
                    "a mass whose weight (mass × gravity) is finite",
                ));
            }
            weight
        }
    };
    Ok(ToolMotion::Floating {
        direction,
        mass,
        weight,
    })
}
