//! The off-axis tension test (OAT) specimen: a flat `W × L` rectangle in the
//! xy-plane, meshed so that every triangle has an edge along the rovings.
//!
//! Rovings `a0 = (sin θ, cos θ, 0)`, θ the bias angle from the load axis y.
//! The rectangle is cut into `nx × ny` cells of `dx = W/nx`, `dy = L/ny`
//! with `dx/dy ≈ tan|θ|`, and each cell is split along the diagonal that
//! runs with the rovings (from `(i, j)` to `(i+1, j+1)` for θ > 0, from
//! `(i+1, j)` to `(i, j+1)` for θ < 0). With integer counts `dx/dy = tan|θ|`
//! holds only approximately; the fibre of every element is nevertheless the
//! exact `a0`, and [`GeneratedMesh::edge_deviation_deg`] reports the
//! remaining misalignment. See `docs/meshes.md`.

use std::collections::BTreeMap;

use nalgebra::Vector3;

use super::{Mesh, MeshError};
use crate::config::readable_number;

/// Largest number of triangles the generator accepts.
pub const MAX_TRIANGLES: usize = 5_000_000;

/// Deviations (degrees) closer than this count as equal when choosing the
/// grid; the pair closer to the target cell count then wins.
const DEVIATION_TIE_DEG: f64 = 1e-9;

/// How each grid cell is split into triangles.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GridPattern {
    /// Two triangles per cell, split along the diagonal that runs with the
    /// rovings.
    RovingDiagonal,
    /// Four triangles per cell, split by both diagonals around a centre
    /// node. At ±45° with square cells the edges follow both the rovings and
    /// the stitching. Needs 0 < |θ| < 90°.
    BothDiagonals,
    /// Two triangles per cell, split along the diagonal that points away
    /// from the rectangle's centre (`/` in the cells right-above and
    /// left-below the centre, `\` in the others), so that the mesh is
    /// mirror-symmetric about both centre lines when both counts are even.
    /// Needs θ = 0° or ±90° (the cell sides are then the rovings and the
    /// stitching).
    Mirrored,
}

/// How fine the grid is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GridResolution {
    /// Target element size `h` (mm): cells of area about `h²` (about
    /// `2·W·L/h²` triangles with [`GridPattern::RovingDiagonal`]), the counts
    /// chosen to align the cell diagonal with the rovings.
    ElementSize(f64),
    /// Exactly `nx` cells across the width and `ny` along the length.
    Counts {
        /// Cells across the width (x).
        nx: usize,
        /// Cells along the length (y).
        ny: usize,
    },
}

/// An OAT specimen to mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OatSpecimen {
    /// Width `W` along x (mm).
    pub width: f64,
    /// Free length `L` along y (the load axis) between the clamps (mm).
    pub length: f64,
    /// Bias angle θ of the rovings from the load axis (degrees), in
    /// [−90, 90]; `a0 = (sin θ, cos θ, 0)`.
    pub bias_angle_deg: f64,
    /// Grid resolution.
    pub resolution: GridResolution,
    /// Cell split.
    pub pattern: GridPattern,
}

/// A generated specimen mesh and how well it is aligned.
#[derive(Debug, Clone, PartialEq)]
pub struct GeneratedMesh {
    /// The mesh, with node sets `bottom` (y = 0), `top` (y = L), `left`
    /// (x = 0), `right` (x = W), `all`, element set `all`, and the fibres set
    /// to the exact `a0`.
    pub mesh: Mesh,
    /// Cells across the width.
    pub nx: usize,
    /// Cells along the length.
    pub ny: usize,
    /// Largest angle (degrees) between `a0` and the nearest edge of any
    /// triangle.
    pub edge_deviation_deg: f64,
}

/// The roving direction `a0 = (sin θ, cos θ, 0)` for a bias angle in
/// degrees, exact at 0° and ±90°.
pub fn roving_direction(bias_angle_deg: f64) -> Vector3<f64> {
    if bias_angle_deg == 0.0 {
        Vector3::new(0.0, 1.0, 0.0)
    } else if bias_angle_deg.abs() == 90.0 {
        Vector3::new(bias_angle_deg.signum(), 0.0, 0.0)
    } else {
        let t = bias_angle_deg.to_radians();
        Vector3::new(t.sin(), t.cos(), 0.0)
    }
}

/// Angle (degrees, 0..=90) between the line along `u` and the line along
/// `v`.
fn line_angle_deg(u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    u.cross(v).norm().atan2(u.dot(v).abs()).to_degrees()
}

/// Meshes the OAT specimen. Errors for non-positive or non-finite sizes,
/// |θ| > 90°, zero counts, more than [`MAX_TRIANGLES`] triangles, and
/// [`GridPattern::BothDiagonals`] at 0° or ±90°.
pub fn oat_specimen(spec: &OatSpecimen) -> Result<GeneratedMesh, MeshError> {
    validate(spec)?;
    let theta = spec.bias_angle_deg;
    let a0 = roving_direction(theta);
    let (nx, ny) = match spec.resolution {
        GridResolution::Counts { nx, ny } => (nx, ny),
        GridResolution::ElementSize(h) => choose_counts(spec.width, spec.length, theta, h)?,
    };
    let per_cell = match spec.pattern {
        GridPattern::RovingDiagonal | GridPattern::Mirrored => 2,
        GridPattern::BothDiagonals => 4,
    };
    let triangles = nx
        .checked_mul(ny)
        .and_then(|c| c.checked_mul(per_cell))
        .filter(|&t| t <= MAX_TRIANGLES);
    if triangles.is_none() {
        return Err(match spec.resolution {
            GridResolution::Counts { .. } => MeshError::InvalidSpec {
                parameter: "nx, ny",
                value: format!("{nx}, {ny}"),
                expected: format!("at most {MAX_TRIANGLES} triangles ({per_cell} per cell)"),
            },
            GridResolution::ElementSize(h) => MeshError::InvalidSpec {
                parameter: "element_size",
                value: readable_number(h),
                expected: format!(
                    "a size giving at most {MAX_TRIANGLES} triangles (this one gives {nx} x {ny} \
                     cells, {per_cell} triangles each)"
                ),
            },
        });
    }
    let mesh = build(spec, nx, ny, a0);
    let edge_deviation_deg = edge_deviation_deg(&mesh, &a0);
    Ok(GeneratedMesh {
        mesh,
        nx,
        ny,
        edge_deviation_deg,
    })
}

fn validate(spec: &OatSpecimen) -> Result<(), MeshError> {
    let bad = |parameter: &'static str, value: f64, expected: &str| MeshError::InvalidSpec {
        parameter,
        value: readable_number(value),
        expected: expected.to_string(),
    };
    if !(spec.width.is_finite() && spec.width > 0.0) {
        return Err(bad("width", spec.width, "a finite width > 0 mm"));
    }
    if !(spec.length.is_finite() && spec.length > 0.0) {
        return Err(bad("length", spec.length, "a finite length > 0 mm"));
    }
    let theta = spec.bias_angle_deg;
    if !(theta.is_finite() && theta.abs() <= 90.0) {
        return Err(bad(
            "bias_angle_deg",
            theta,
            "a finite angle in [-90, 90] degrees from the load axis",
        ));
    }
    match spec.resolution {
        GridResolution::ElementSize(h) => {
            if !(h.is_finite() && h > 0.0) {
                return Err(bad("element_size", h, "a finite size > 0 mm"));
            }
        }
        GridResolution::Counts { nx, ny } => {
            if nx == 0 || ny == 0 {
                return Err(MeshError::InvalidSpec {
                    parameter: "nx, ny",
                    value: format!("{nx}, {ny}"),
                    expected: "at least one cell in each direction".to_string(),
                });
            }
        }
    }
    if spec.pattern == GridPattern::BothDiagonals && (theta == 0.0 || theta.abs() == 90.0) {
        return Err(MeshError::InvalidSpec {
            parameter: "pattern",
            value: "\"both-diagonals\"".to_string(),
            expected: format!(
                "\"roving-diagonal\" at bias angle {}° (at 0° and ±90° its cell sides \
                 already follow the rovings and the stitching; the diagonals would not)",
                readable_number(theta)
            ),
        });
    }
    if spec.pattern == GridPattern::Mirrored && !(theta == 0.0 || theta.abs() == 90.0) {
        return Err(MeshError::InvalidSpec {
            parameter: "pattern",
            value: "\"mirrored\"".to_string(),
            expected: format!(
                "a bias angle of 0° or ±90°, not {}° (elsewhere only \"roving-diagonal\" \
                 keeps an edge of every triangle along the rovings)",
                readable_number(theta)
            ),
        });
    }
    Ok(())
}

fn too_many(h: f64) -> MeshError {
    MeshError::InvalidSpec {
        parameter: "element_size",
        value: readable_number(h),
        expected: format!("a size giving at most {MAX_TRIANGLES} triangles"),
    }
}

/// Relative tolerance on the triangle count of an `ElementSize` grid: grids
/// within it are preferred, then the best-aligned among them.
pub const COUNT_TOLERANCE: f64 = 0.10;

/// Chooses `(nx, ny)` for the target element size `h`.
///
/// At 0° and ±90°: `nx = round(W/h)`, `ny = round(L/h)` (at least 1).
/// Otherwise, with `t = tan|θ|` and the nominal `nx0 = W / (h √t)` (cells of
/// area `h²` with `dx/dy = t`): every `nx` in `[0.8 nx0, 1.25 nx0]` with
/// `ny = round(nx L t / W)` is a candidate. Candidates whose cell count is
/// within [`COUNT_TOLERANCE`] of `W L / h²` come first; among them the one
/// whose cell diagonal is closest in angle to the rovings wins, ties (1e-9°)
/// going to the closer count.
fn choose_counts(w: f64, l: f64, theta: f64, h: f64) -> Result<(usize, usize), MeshError> {
    let limit = (MAX_TRIANGLES / 2) as f64;
    if theta == 0.0 || theta.abs() == 90.0 {
        let nx = (w / h).round().max(1.0);
        let ny = (l / h).round().max(1.0);
        if nx * ny > limit {
            return Err(too_many(h));
        }
        return Ok((nx as usize, ny as usize));
    }
    let abs = theta.abs();
    let t = abs.to_radians().tan();
    let nx0 = w / (h * t.sqrt());
    let lo = (0.8 * nx0).ceil().max(1.0);
    let hi = (1.25 * nx0).floor().max(lo);
    if (w * l / (h * h)) > limit {
        return Err(too_many(h));
    }
    if lo > limit {
        // Cells with dx/dy = tan|θ| get absurdly slender as θ → 0 or ±90°.
        return Err(MeshError::InvalidSpec {
            parameter: "bias_angle_deg",
            value: readable_number(theta),
            expected: format!(
                "0 or ±90 exactly, or an angle whose aligned grid (dx/dy = tan|θ|) \
                 fits in {MAX_TRIANGLES} triangles at element size {} mm",
                readable_number(h)
            ),
        });
    }
    let target = w * l / (h * h);
    let a = Vector3::new(abs.to_radians().sin(), abs.to_radians().cos(), 0.0);
    let mut best: Option<(usize, usize, f64, f64)> = None;
    let (lo, hi) = (lo as usize, hi as usize);
    for nx in lo..=hi {
        let ny = (nx as f64 * l * t / w).round().max(1.0) as usize;
        let cells = (nx * ny) as f64;
        if cells > limit {
            continue;
        }
        let diagonal = Vector3::new(w / nx as f64, l / ny as f64, 0.0);
        let dev = line_angle_deg(&diagonal, &a);
        let miss = (cells - target).abs();
        // Grids within ±10 % of the target count come first; among them the
        // best-aligned wins (ties: the closer count).
        let near = miss <= COUNT_TOLERANCE * target;
        let better = match best {
            None => true,
            Some((_, _, bdev, bmiss)) => {
                let best_near = bmiss <= COUNT_TOLERANCE * target;
                (near && !best_near)
                    || (near == best_near
                        && (dev < bdev - DEVIATION_TIE_DEG
                            || (dev <= bdev + DEVIATION_TIE_DEG && miss < bmiss)))
            }
        };
        if better {
            best = Some((nx, ny, dev, miss));
        }
    }
    let (nx, ny) = best
        .map(|(nx, ny, _, _)| (nx, ny))
        .ok_or_else(|| too_many(h))?;
    // A specimen narrower than an aligned cell still gets one cell across,
    // and the alignment dx/dy = tan|θ| then shrinks every cell with it:
    // refuse grids whose cells are far below the requested size rather
    // than silently meshing with many times the triangles asked for.
    let cell_area = (w / nx as f64) * (l / ny as f64);
    if cell_area < MIN_CELL_AREA_FRACTION * h * h {
        return Err(MeshError::InvalidSpec {
            parameter: "element_size",
            value: readable_number(h),
            expected: format!(
                "a size the specimen can hold: at {}° the aligned grid of a {} mm wide specimen \
                 has cells of {:.3e} mm² ({} triangles) instead of about {:.3e} mm²; \
                 use an element size of at most about {:.3e} mm, or give nx and ny",
                readable_number(theta),
                readable_number(w),
                cell_area,
                2 * nx * ny,
                h * h,
                w * t.sqrt()
            ),
        });
    }
    Ok((nx, ny))
}

/// Smallest cell area an `ElementSize` grid may have, as a fraction of the
/// requested `h²` (a cell half the size in each direction).
pub const MIN_CELL_AREA_FRACTION: f64 = 0.25;

fn build(spec: &OatSpecimen, nx: usize, ny: usize, a0: Vector3<f64>) -> Mesh {
    let (w, l) = (spec.width, spec.length);
    let both = spec.pattern == GridPattern::BothDiagonals;
    let grid = (nx + 1) * (ny + 1);
    let node_count = grid + if both { nx * ny } else { 0 };
    let mut nodes = Vec::with_capacity(node_count);
    for j in 0..=ny {
        let y = if j == ny { l } else { l * j as f64 / ny as f64 };
        for i in 0..=nx {
            let x = if i == nx { w } else { w * i as f64 / nx as f64 };
            nodes.push(Vector3::new(x, y, 0.0));
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut triangles = Vec::with_capacity(nx * ny * if both { 4 } else { 2 });
    for j in 0..ny {
        for i in 0..nx {
            let (n00, n10, n11, n01) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            if both {
                let c = nodes.len();
                nodes.push((nodes[n00] + nodes[n11]) * 0.5);
                triangles.push([n00, n10, c]);
                triangles.push([n10, n11, c]);
                triangles.push([n11, n01, c]);
                triangles.push([n01, n00, c]);
            } else if spec.pattern == GridPattern::Mirrored {
                // Cell centre relative to the grid centre, in half cells.
                let (ci, cj) = (2 * i + 1, 2 * j + 1);
                let away_slash = (ci > nx) == (cj > ny);
                if away_slash {
                    triangles.push([n00, n10, n11]);
                    triangles.push([n00, n11, n01]);
                } else {
                    triangles.push([n00, n10, n01]);
                    triangles.push([n10, n11, n01]);
                }
            } else if spec.bias_angle_deg >= 0.0 {
                triangles.push([n00, n10, n11]);
                triangles.push([n00, n11, n01]);
            } else {
                triangles.push([n00, n10, n01]);
                triangles.push([n10, n11, n01]);
            }
        }
    }
    let mut node_sets = BTreeMap::new();
    node_sets.insert("bottom".to_string(), (0..=nx).map(|i| id(i, 0)).collect());
    node_sets.insert("top".to_string(), (0..=nx).map(|i| id(i, ny)).collect());
    node_sets.insert("left".to_string(), (0..=ny).map(|j| id(0, j)).collect());
    node_sets.insert("right".to_string(), (0..=ny).map(|j| id(nx, j)).collect());
    node_sets.insert("all".to_string(), (0..nodes.len()).collect());
    let mut element_sets = BTreeMap::new();
    element_sets.insert("all".to_string(), (0..triangles.len()).collect());
    let pattern = match spec.pattern {
        GridPattern::BothDiagonals => "both diagonals",
        GridPattern::RovingDiagonal => "roving diagonal",
        GridPattern::Mirrored => "mirrored diagonals",
    };
    Mesh {
        node_labels: (1..=nodes.len() as i64).collect(),
        element_labels: (1..=triangles.len() as i64).collect(),
        fibres: vec![a0; triangles.len()],
        nodes,
        triangles,
        node_sets,
        element_sets,
        source: format!(
            "generated OAT specimen {} x {} mm, bias {}°, {nx} x {ny} cells, {pattern}",
            readable_number(w),
            readable_number(l),
            readable_number(spec.bias_angle_deg)
        ),
    }
}

/// Largest angle (degrees) between `a0` and the nearest edge of any
/// triangle of `mesh`.
pub fn edge_deviation_deg(mesh: &Mesh, a0: &Vector3<f64>) -> f64 {
    mesh.triangles
        .iter()
        .map(|&[a, b, c]| {
            let (xa, xb, xc) = (mesh.nodes[a], mesh.nodes[b], mesh.nodes[c]);
            line_angle_deg(&(xb - xa), a0)
                .min(line_angle_deg(&(xc - xb), a0))
                .min(line_angle_deg(&(xa - xc), a0))
        })
        .fold(0.0, f64::max)
}
