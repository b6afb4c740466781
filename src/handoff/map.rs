//! Mapping a formed ply onto a structural shell mesh (`docs/export.md`):
//! per element of the target mesh, the fibre direction of the ply beneath
//! it, averaged over the element's area as an orientation tensor.
//!
//! Method ([`map_onto`]): a bounding-volume tree over the formed ply's
//! triangles (parry's [`TriMesh`]); per target element, sample points over
//! its area (a triangle cut into `n²` equal sub-triangles, a quad into
//! `n × n` cells of its bilinear map, each sample weighted by its area);
//! each sample is projected to the ply's closest point, and a sample
//! farther than [`MapOptions::tolerance`] is a miss. The hit samples add
//! their triangle's fibre `a` to the orientation tensor `T = Σ w a⊗a`
//! (`a` and `−a` are one fibre, so alternating shear bands average to
//! their bisector instead of cancelling or aliasing to one band); the
//! tensor is projected onto the element's plane, `P T P` with
//! `P = I − n⊗n` (`n` from [`ShellMesh::normal`]), and its principal
//! eigenvector is the element's fibre. An element with no hit gets no
//! direction (`None`): nothing is made up.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use parry3d_f64::math::Vector as GlamVector;
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::TriMesh;
use rayon::prelude::*;

use super::{Layer, ShellMesh, cross, dot, normalized, sub};

/// Default [`MapOptions::tolerance`] \[mm\]: a structural mesh of the tool
/// surface or of the laminate's outer face lies up to half the laminate
/// thickness from a ply's mid-surface (a few ply thicknesses of 0.2–0.5 mm)
/// plus the tool-contact offset, so 2 mm keeps such a mesh mapped while a
/// region of the part the ply does not reach (a flange beyond its edge) is
/// left unmapped.
pub const DEFAULT_TOLERANCE: f64 = 2.0;

/// Samples per median edge of the formed ply in the automatic rule: an
/// element of longest edge `h` gets `n = ⌈2 h / h_ply⌉` samples per edge
/// (spacing at most half the ply's median edge `h_ply`), so an element
/// coarser than the ply averages over the formed triangles beneath it.
pub const SAMPLES_PER_PLY_EDGE: f64 = 2.0;

/// The largest automatic number of samples per element edge (`n² ≤ 4096`
/// samples per element), bounding the cost of a very coarse target.
pub const MAX_AUTO_SAMPLES_PER_EDGE: usize = 64;

/// A formed ply as the mapping reads it: its deformed triangles and one
/// unit fibre direction per triangle.
#[derive(Debug, Clone, Copy)]
pub struct FormedSurface<'a> {
    /// Node positions \[mm\].
    pub nodes: &'a [[f64; 3]],
    /// Triangles, as indices into `nodes`.
    pub triangles: &'a [[usize; 3]],
    /// The unit fibre direction of each triangle, in its plane (its sign
    /// sets the sign of the mapped directions, see [`map_onto`]).
    pub fibre: &'a [[f64; 3]],
}

/// Options of [`map_onto`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapOptions {
    /// Largest distance from a sample point of a target element to the ply
    /// for the sample to count \[mm\]; default [`DEFAULT_TOLERANCE`].
    pub tolerance: f64,
    /// Samples per element edge (`n`: `n²` samples per element); `None`
    /// chooses per element from its size and the ply's median edge
    /// ([`SAMPLES_PER_PLY_EDGE`], at most [`MAX_AUTO_SAMPLES_PER_EDGE`]).
    /// `Some(1)` samples each element at its centre only.
    pub samples_per_edge: Option<usize>,
}

impl Default for MapOptions {
    /// [`DEFAULT_TOLERANCE`] and the automatic number of samples.
    fn default() -> Self {
        Self {
            tolerance: DEFAULT_TOLERANCE,
            samples_per_edge: None,
        }
    }
}

/// Why an element of the target got no fibre direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum UnmappedReason {
    /// The element has (nearly) zero area or no normal.
    Degenerate,
    /// No sample point lies within the tolerance of the ply; `distance`
    /// is the smallest sample distance \[mm\].
    NotCovered {
        /// The smallest distance from a sample point to the ply \[mm\].
        distance: f64,
    },
    /// The ply's fibres beneath the element are (nearly) along its normal,
    /// so they have no direction in its plane.
    FibreAlongNormal,
}

impl std::fmt::Display for UnmappedReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            UnmappedReason::Degenerate => write!(f, "degenerate element (no area or normal)"),
            UnmappedReason::NotCovered { distance } => write!(
                f,
                "not covered by the ply (nearest sample {} mm away)",
                crate::config::readable_number(*distance)
            ),
            UnmappedReason::FibreAlongNormal => {
                write!(f, "the ply's fibres there are along the element normal")
            }
        }
    }
}

/// One element of the target that got no fibre direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unmapped {
    /// Its index in the target's elements.
    pub element: usize,
    /// Its label in the target.
    pub label: u64,
    /// Why.
    pub reason: UnmappedReason,
}

/// The ply mapped onto a target mesh: per element of the target (indexed
/// like [`ShellMesh::elements`]).
#[derive(Debug, Clone, PartialEq)]
pub struct MapResult {
    /// The unit fibre direction in the element's plane, or `None` where the
    /// ply does not cover the element.
    pub fibre: Vec<Option<[f64; 3]>>,
    /// The covered fraction of the element's area: hit weight over total
    /// sample weight (0 to 1). A sample beyond the ply's edge but within
    /// the tolerance of it counts as a hit (it projects onto the edge), so
    /// at the ply's boundary the coverage is high by up to about
    /// `tolerance / element width`.
    pub coverage: Vec<f64>,
    /// The smallest distance from a sample point to the ply \[mm\] (NaN for
    /// a degenerate element).
    pub distance: Vec<f64>,
    /// The anisotropy of the averaged in-plane tensor,
    /// `(λ1 − λ2) / (λ1 + λ2)`: 1 where all hits agree, near 0 where the
    /// fibre is not defined (crossing bands); 0 for an unmapped element.
    pub anisotropy: Vec<f64>,
    /// The samples per edge used (`n²` samples per element).
    pub samples_per_edge: Vec<usize>,
    /// The elements without a direction, in element order, with the reason.
    pub unmapped: Vec<Unmapped>,
}

impl MapResult {
    /// The mapped ply as a hand-off layer of the target mesh.
    pub fn to_layer(&self, name: &str, thickness: f64) -> Layer {
        Layer {
            name: name.to_string(),
            thickness,
            fibre: self.fibre.clone(),
        }
    }
}

/// Why a mapping could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    /// The formed ply has no triangle.
    #[error("the formed ply has no triangles; expected at least one")]
    EmptySurface,
    /// The formed ply's lists do not match.
    #[error(
        "the formed ply has {fibres} fibre directions for {triangles} triangles; expected one per triangle"
    )]
    LengthMismatch {
        /// Number of fibre directions.
        fibres: usize,
        /// Number of triangles.
        triangles: usize,
    },
    /// A triangle of the ply names a node it does not have.
    #[error(
        "formed ply triangle {triangle} names node {node}; expected an index below the node count {nodes}"
    )]
    NodeOutOfRange {
        /// The triangle index.
        triangle: usize,
        /// The node index named.
        node: usize,
        /// The number of nodes.
        nodes: usize,
    },
    /// A non-finite coordinate or a zero or non-finite fibre direction.
    #[error("{what} {index} is ({}, {}, {}); expected {expected}", crate::config::readable_number(.value[0]), crate::config::readable_number(.value[1]), crate::config::readable_number(.value[2]))]
    InvalidVector {
        /// `formed ply node`, `formed ply fibre` or `target node <label>`.
        what: String,
        /// Its index (for a target node, its label).
        index: u64,
        /// The value.
        value: [f64; 3],
        /// What is allowed.
        expected: &'static str,
    },
    /// A target element that is neither a triangle nor a quad, or names a
    /// node the target does not have.
    #[error("{file}: element {label}: {what}")]
    InvalidTarget {
        /// The target's source.
        file: String,
        /// The element label.
        label: u64,
        /// What is wrong and what was expected.
        what: String,
    },
    /// An option out of range.
    #[error("mapping option {option} = {value}; expected {expected}")]
    InvalidOption {
        /// The option's name.
        option: &'static str,
        /// The value as given.
        value: String,
        /// What is allowed.
        expected: &'static str,
    },
}

/// The result of one target element.
struct ElementMap {
    fibre: Option<[f64; 3]>,
    coverage: f64,
    distance: f64,
    anisotropy: f64,
    samples: usize,
    reason: Option<UnmappedReason>,
}

/// Maps the formed ply `surface` onto the shell mesh `target` (see the
/// module documentation for the method): per target element its fibre
/// direction (the principal direction of the area-averaged orientation
/// tensor of the ply beneath it, projected onto the element's plane), the
/// covered fraction of its area, the smallest sample distance and the
/// tensor's anisotropy.
///
/// The sign of a mapped direction follows the ply's own fibre vectors
/// (the one with a non-negative dot product with their weighted sum), so
/// a ply with a continuous fibre field maps to a continuous field. The
/// work runs in parallel over the target elements.
///
/// Errors: an empty ply, fibre and triangle counts that differ, a ply
/// triangle naming a missing node, a non-finite coordinate or a zero or
/// non-finite fibre, a target element that is not a triangle or quad of
/// existing nodes, a tolerance that is not finite and positive, zero
/// samples per edge. Degenerate target elements are not errors: they are
/// unmapped ([`UnmappedReason::Degenerate`]).
pub fn map_onto(
    surface: &FormedSurface,
    target: &ShellMesh,
    options: &MapOptions,
) -> Result<MapResult, MapError> {
    check_inputs(surface, target, options)?;
    let fibres: Vec<Vector3<f64>> = surface
        .fibre
        .iter()
        .map(|a| Vector3::from(*a).normalize())
        .collect();
    let trimesh = TriMesh::new(
        surface
            .nodes
            .iter()
            .map(|x| GlamVector::new(x[0], x[1], x[2]))
            .collect(),
        surface
            .triangles
            .iter()
            .map(|t| t.map(|n| n as u32))
            .collect(),
    )
    .map_err(|_| MapError::EmptySurface)?;
    let ply_edge = median_edge(surface);
    let per_element: Vec<ElementMap> = (0..target.elements.len())
        .into_par_iter()
        .map(|e| map_element(&trimesh, &fibres, target, e, options, ply_edge))
        .collect();
    let count = per_element.len();
    let mut result = MapResult {
        fibre: Vec::with_capacity(count),
        coverage: Vec::with_capacity(count),
        distance: Vec::with_capacity(count),
        anisotropy: Vec::with_capacity(count),
        samples_per_edge: Vec::with_capacity(count),
        unmapped: Vec::new(),
    };
    for (e, m) in per_element.into_iter().enumerate() {
        result.fibre.push(m.fibre);
        result.coverage.push(m.coverage);
        result.distance.push(m.distance);
        result.anisotropy.push(m.anisotropy);
        result.samples_per_edge.push(m.samples);
        if let Some(reason) = m.reason {
            result.unmapped.push(Unmapped {
                element: e,
                label: target.elements[e].label,
                reason,
            });
        }
    }
    Ok(result)
}

fn check_inputs(
    surface: &FormedSurface,
    target: &ShellMesh,
    options: &MapOptions,
) -> Result<(), MapError> {
    if !(options.tolerance.is_finite() && options.tolerance > 0.0) {
        return Err(MapError::InvalidOption {
            option: "tolerance",
            value: crate::config::readable_number(options.tolerance),
            expected: "a finite distance > 0 mm",
        });
    }
    if options.samples_per_edge == Some(0) {
        return Err(MapError::InvalidOption {
            option: "samples_per_edge",
            value: "0".to_string(),
            expected: "at least 1 (or automatic)",
        });
    }
    if surface.triangles.is_empty() {
        return Err(MapError::EmptySurface);
    }
    if surface.fibre.len() != surface.triangles.len() {
        return Err(MapError::LengthMismatch {
            fibres: surface.fibre.len(),
            triangles: surface.triangles.len(),
        });
    }
    let u32_nodes = surface.nodes.len().min(u32::MAX as usize);
    for (t, tri) in surface.triangles.iter().enumerate() {
        if let Some(&node) = tri.iter().find(|&&n| n >= u32_nodes) {
            return Err(MapError::NodeOutOfRange {
                triangle: t,
                node,
                nodes: surface.nodes.len(),
            });
        }
    }
    let invalid = |what: String, index: u64, value: [f64; 3], expected| MapError::InvalidVector {
        what,
        index,
        value,
        expected,
    };
    for (n, x) in surface.nodes.iter().enumerate() {
        if !x.iter().all(|c| c.is_finite()) {
            return Err(invalid(
                "formed ply node".into(),
                n as u64,
                *x,
                "finite coordinates",
            ));
        }
    }
    for (t, a) in surface.fibre.iter().enumerate() {
        if normalized(*a).is_none() {
            return Err(invalid(
                "formed ply fibre of triangle".into(),
                t as u64,
                *a,
                "a finite non-zero direction",
            ));
        }
    }
    for (n, x) in target.nodes.iter().enumerate() {
        if !x.iter().all(|c| c.is_finite()) {
            let label = target.node_labels.get(n).copied().unwrap_or(n as u64 + 1);
            return Err(invalid(
                "target node".into(),
                label,
                *x,
                "finite coordinates",
            ));
        }
    }
    for el in &target.elements {
        let what = if !(3..=4).contains(&el.nodes.len()) {
            Some(format!(
                "has {} nodes; expected 3 (triangle) or 4 (quad)",
                el.nodes.len()
            ))
        } else {
            el.nodes
                .iter()
                .find(|&&n| n >= target.nodes.len())
                .map(|n| {
                    format!(
                        "names node index {n}; expected an index below the node count {}",
                        target.nodes.len()
                    )
                })
        };
        if let Some(what) = what {
            return Err(MapError::InvalidTarget {
                file: target.source.clone(),
                label: el.label,
                what,
            });
        }
    }
    Ok(())
}

/// The median edge length of the ply's triangles \[mm\].
fn median_edge(surface: &FormedSurface) -> f64 {
    let mut edges: Vec<f64> = Vec::with_capacity(3 * surface.triangles.len());
    for t in surface.triangles {
        for k in 0..3 {
            let d = sub(surface.nodes[t[(k + 1) % 3]], surface.nodes[t[k]]);
            edges.push(dot(d, d).sqrt());
        }
    }
    let mid = edges.len() / 2;
    let (_, m, _) = edges.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

/// The sample points of element `e` with `n` per edge, each with its area
/// weight, handed to `f`.
fn for_each_sample(mesh: &ShellMesh, e: usize, n: usize, mut f: impl FnMut([f64; 3], f64)) {
    let el = &mesh.elements[e];
    let x = |k: usize| mesh.nodes[el.nodes[k]];
    let nf = n as f64;
    let at = |o: [f64; 3], u: [f64; 3], v: [f64; 3], s: f64, t: f64| {
        [
            o[0] + s * u[0] + t * v[0],
            o[1] + s * u[1] + t * v[1],
            o[2] + s * u[2] + t * v[2],
        ]
    };
    if el.nodes.len() == 3 {
        let (x0, u, v) = (x(0), sub(x(1), x(0)), sub(x(2), x(0)));
        let c = cross(u, v);
        let w = 0.5 * dot(c, c).sqrt() / (nf * nf);
        for i in 0..n {
            for j in 0..n - i {
                let (fi, fj) = (i as f64, j as f64);
                f(
                    at(x0, u, v, (fi + 1.0 / 3.0) / nf, (fj + 1.0 / 3.0) / nf),
                    w,
                );
                if i + j + 1 < n {
                    f(
                        at(x0, u, v, (fi + 2.0 / 3.0) / nf, (fj + 2.0 / 3.0) / nf),
                        w,
                    );
                }
            }
        }
    } else {
        let (x0, x1, x2, x3) = (x(0), x(1), x(2), x(3));
        let (a, b) = (sub(x1, x0), sub(x2, x3));
        let (c, d) = (sub(x3, x0), sub(x2, x1));
        for i in 0..n {
            for j in 0..n {
                let s = (i as f64 + 0.5) / nf;
                let t = (j as f64 + 0.5) / nf;
                let mut p = [0.0; 3];
                let mut ds = [0.0; 3];
                let mut dt = [0.0; 3];
                for k in 0..3 {
                    p[k] = (1.0 - s) * (1.0 - t) * x0[k]
                        + s * (1.0 - t) * x1[k]
                        + s * t * x2[k]
                        + (1.0 - s) * t * x3[k];
                    ds[k] = (1.0 - t) * a[k] + t * b[k];
                    dt[k] = (1.0 - s) * c[k] + s * d[k];
                }
                let j = cross(ds, dt);
                f(p, dot(j, j).sqrt() / (nf * nf));
            }
        }
    }
}

/// The longest side of element `e` \[mm\].
fn longest_side(mesh: &ShellMesh, e: usize) -> f64 {
    let el = &mesh.elements[e];
    let k = el.nodes.len();
    (0..k)
        .map(|i| {
            let d = sub(mesh.nodes[el.nodes[(i + 1) % k]], mesh.nodes[el.nodes[i]]);
            dot(d, d).sqrt()
        })
        .fold(0.0, f64::max)
}

fn map_element(
    ply: &TriMesh,
    fibres: &[Vector3<f64>],
    target: &ShellMesh,
    e: usize,
    options: &MapOptions,
    ply_edge: f64,
) -> ElementMap {
    let h = longest_side(target, e);
    let n = options.samples_per_edge.unwrap_or_else(|| {
        // The 1e-9 keeps an element of exactly k ply edges at k·2 samples
        // despite the rounding of its coordinates.
        let n = (SAMPLES_PER_PLY_EDGE * h / ply_edge - 1e-9).ceil();
        if n.is_finite() {
            (n as usize).clamp(1, MAX_AUTO_SAMPLES_PER_EDGE)
        } else {
            MAX_AUTO_SAMPLES_PER_EDGE
        }
    });
    let unmapped = |reason, coverage, distance| ElementMap {
        fibre: None,
        coverage,
        distance,
        anisotropy: 0.0,
        samples: n,
        reason: Some(reason),
    };
    let Some(normal) = target.normal(e) else {
        return unmapped(UnmappedReason::Degenerate, 0.0, f64::NAN);
    };
    let tol = options.tolerance;
    let mut tensor = Matrix3::<f64>::zeros();
    let mut sum = Vector3::<f64>::zeros();
    let mut total = 0.0;
    let mut hit = 0.0;
    let mut nearest = f64::INFINITY;
    for_each_sample(target, e, n, |p, w| {
        total += w;
        let point = GlamVector::new(p[0], p[1], p[2]);
        let Some((proj, (tri, _))) =
            ply.project_local_point_and_get_location_with_max_dist(point, false, tol)
        else {
            return;
        };
        let d = (proj.point - point).length();
        if d.is_nan() || d > tol {
            return;
        }
        nearest = nearest.min(d);
        let Some(a) = fibres.get(tri as usize) else {
            return;
        };
        hit += w;
        tensor += w * a * a.transpose();
        sum += w * a;
    });
    if !(total > 0.0 && total.is_finite()) || total <= 1e-10 * h * h {
        return unmapped(UnmappedReason::Degenerate, 0.0, f64::NAN);
    }
    let coverage = (hit / total).clamp(0.0, 1.0);
    if hit <= 0.0 {
        // The smallest distance of the samples, without the bound.
        let mut nearest = f64::INFINITY;
        for_each_sample(target, e, n, |p, _| {
            let point = GlamVector::new(p[0], p[1], p[2]);
            if let Some((proj, _)) =
                ply.project_local_point_and_get_location_with_max_dist(point, false, f64::MAX)
            {
                nearest = nearest.min((proj.point - point).length());
            }
        });
        return unmapped(
            UnmappedReason::NotCovered { distance: nearest },
            0.0,
            nearest,
        );
    }
    let nv = Vector3::from(normal);
    let p = Matrix3::identity() - nv * nv.transpose();
    let projected = p * tensor * p;
    let eig = SymmetricEigen::new(projected);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let l1 = eig.eigenvalues[order[0]];
    let l2 = eig.eigenvalues[order[1]].max(0.0);
    if l1.is_nan() || l1 <= 1e-12 * tensor.trace() {
        return unmapped(UnmappedReason::FibreAlongNormal, coverage, nearest);
    }
    let v = p * eig.eigenvectors.column(order[0]);
    let Some(mut v) = normalized([v[0], v[1], v[2]]) else {
        return unmapped(UnmappedReason::FibreAlongNormal, coverage, nearest);
    };
    if dot(v, [sum[0], sum[1], sum[2]]) < 0.0 {
        v = v.map(|c| -c);
    }
    ElementMap {
        fibre: Some(v),
        coverage,
        distance: nearest,
        anisotropy: ((l1 - l2) / (l1 + l2)).clamp(0.0, 1.0),
        samples: n,
        reason: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::handoff::ShellElement;

    fn square(z: f64) -> ShellMesh {
        ShellMesh {
            source: "square".into(),
            node_labels: vec![11, 12, 13, 14],
            nodes: vec![[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]],
            elements: vec![ShellElement {
                label: 7,
                nodes: vec![0, 1, 2, 3],
                abaqus_type: "S4R".into(),
            }],
        }
    }

    #[test]
    fn quad_and_triangle_weights_sum_to_the_area() {
        let mut m = square(0.0);
        m.nodes[2] = [2.0, 1.5, 0.0];
        m.elements.push(ShellElement {
            label: 8,
            nodes: vec![0, 1, 2],
            abaqus_type: "S3".into(),
        });
        for n in [1, 2, 5] {
            let mut quad = 0.0;
            for_each_sample(&m, 0, n, |_, w| quad += w);
            // Shoelace area of (0,0), (1,0), (2,1.5), (0,1).
            assert!((quad - 1.75).abs() < 1e-12, "{quad}");
            let mut tri = 0.0;
            let mut count = 0;
            for_each_sample(&m, 1, n, |_, w| {
                tri += w;
                count += 1
            });
            assert!((tri - 0.75).abs() < 1e-12 && count == n * n);
        }
    }

    #[test]
    fn off_ply_and_degenerate_elements_are_unmapped() {
        let nodes = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let tris = [[0, 1, 2]];
        let fibre = [[1.0, 0.0, 0.0]];
        let s = FormedSurface {
            nodes: &nodes,
            triangles: &tris,
            fibre: &fibre,
        };
        let far = map_onto(&s, &square(5.0), &MapOptions::default()).unwrap();
        assert_eq!(far.fibre, vec![None]);
        assert_eq!(far.unmapped[0].label, 7);
        assert!((far.distance[0] - 5.0).abs() < 1e-9, "{:?}", far.distance);
        let mut flat = square(0.0);
        flat.nodes[2] = [0.5, 0.5, 0.0];
        flat.nodes[3] = [1.0, 0.0, 0.0];
        let r = map_onto(&s, &flat, &MapOptions::default()).unwrap();
        assert_eq!(r.unmapped[0].reason, UnmappedReason::Degenerate);
    }
}
