//! Forming results read on the blank (`docs/forming.md`, "Outputs"): the
//! outer contour of a ply projected on the blank plane, the draw-in at the
//! edge midpoints and corners of the blank, area-weighted means over
//! evaluation zones of the blank, and the strain measures recomputed on the
//! formed mesh projected on the blank plane (the 2D image-correlation view
//! of the paper's Appendix C).
//!
//! The blank plane is the global xy-plane (the generated blanks lie in it);
//! "projected" means the z coordinate dropped. Everything here reads a
//! state and changes nothing.

use std::collections::HashMap;

use crate::material::Invariants;
use crate::model::MembraneModel;

/// The closed loops of boundary edges (edges of exactly one triangle) of a
/// triangle mesh, each as its node indices in order along the loop (the
/// direction of the triangles' own edges, so that for a mesh whose normals
/// point to +z the outer loop runs counter-clockwise seen from +z), the
/// longest loop first. An edge shared by more than two triangles is not a
/// boundary edge.
pub fn boundary_loops(triangles: &[[usize; 3]]) -> Vec<Vec<usize>> {
    let mut uses: HashMap<(usize, usize), (usize, (usize, usize))> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let key = (a.min(b), a.max(b));
            uses.entry(key).or_insert((0, (a, b))).0 += 1;
        }
    }
    let mut next: HashMap<usize, usize> = HashMap::new();
    let mut starts: Vec<usize> = Vec::new();
    for &(count, (a, b)) in uses.values() {
        if count == 1 {
            next.insert(a, b);
            starts.push(a);
        }
    }
    // Deterministic order whatever the hash map does.
    starts.sort_unstable();
    let mut loops = Vec::new();
    for start in starts {
        if !next.contains_key(&start) {
            continue;
        }
        let mut nodes = vec![start];
        let mut at = start;
        while let Some(to) = next.remove(&at) {
            if to == start {
                break;
            }
            nodes.push(to);
            at = to;
        }
        if nodes.len() >= 3 {
            loops.push(nodes);
        }
    }
    loops.sort_by_key(|l| std::cmp::Reverse(l.len()));
    loops
}

/// Signed area of a closed polygon in the plane (positive counter-clockwise).
pub fn polygon_area(points: &[[f64; 2]]) -> f64 {
    let n = points.len();
    (0..n)
        .map(|i| {
            let (p, q) = (points[i], points[(i + 1) % n]);
            p[0] * q[1] - q[0] * p[1]
        })
        .sum::<f64>()
        * 0.5
}

/// The outer boundary of a flat or formed sheet: the boundary loop that
/// encloses the largest area in the reference xy-plane, oriented
/// counter-clockwise seen from +z. `None` for a mesh without a boundary.
pub fn outer_boundary(nodes: &[[f64; 2]], triangles: &[[usize; 3]]) -> Option<Vec<usize>> {
    let loops = boundary_loops(triangles);
    let area = |l: &Vec<usize>| polygon_area(&l.iter().map(|&n| nodes[n]).collect::<Vec<_>>());
    let mut best = loops
        .into_iter()
        .map(|l| (area(&l), l))
        .max_by(|a, b| a.0.abs().total_cmp(&b.0.abs()))?;
    if best.0 < 0.0 {
        best.1.reverse();
    }
    Some(best.1)
}

/// A point of the blank's outer boundary at which the draw-in is measured:
/// where it lies on the boundary loop and which way is "in".
#[derive(Debug, Clone, PartialEq)]
pub struct DrawInPoint {
    /// Name: `+x edge`, `+y edge`, `-x edge`, `-y edge` (midpoints of the
    /// bounding box's sides) or `+x+y corner`, … (its corners).
    pub name: String,
    /// Reference position on the boundary \[mm\].
    pub reference: [f64; 2],
    /// The boundary segment it lies on: position in the loop of its first
    /// node (the second is the next one, cyclically).
    pub segment: usize,
    /// Position along the segment, 0 at its first node, 1 at its second.
    pub along: f64,
    /// Unit direction from the point to the blank's centre (the centre of
    /// the bounding box): the draw-in is the in-plane displacement along it.
    pub inward: [f64; 2],
}

/// The eight draw-in points of a blank: the midpoints of the four sides and
/// the four corners of the bounding box of the reference outer boundary
/// `outer` (positions `nodes`), each moved to the closest point of the
/// boundary polyline.
pub fn draw_in_points(nodes: &[[f64; 2]], outer: &[usize]) -> Vec<DrawInPoint> {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &n in outer {
        for k in 0..2 {
            lo[k] = lo[k].min(nodes[n][k]);
            hi[k] = hi[k].max(nodes[n][k]);
        }
    }
    let centre = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
    let targets = [
        ("+x edge", [hi[0], centre[1]]),
        ("+y edge", [centre[0], hi[1]]),
        ("-x edge", [lo[0], centre[1]]),
        ("-y edge", [centre[0], lo[1]]),
        ("+x+y corner", [hi[0], hi[1]]),
        ("-x+y corner", [lo[0], hi[1]]),
        ("-x-y corner", [lo[0], lo[1]]),
        ("+x-y corner", [hi[0], lo[1]]),
    ];
    let m = outer.len();
    targets
        .iter()
        .map(|(name, target)| {
            let mut best = (f64::INFINITY, 0, 0.0, *target);
            for s in 0..m {
                let (p, q) = (nodes[outer[s]], nodes[outer[(s + 1) % m]]);
                let d = [q[0] - p[0], q[1] - p[1]];
                let len2 = d[0] * d[0] + d[1] * d[1];
                let t = if len2 > 0.0 {
                    (((target[0] - p[0]) * d[0] + (target[1] - p[1]) * d[1]) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let x = [p[0] + t * d[0], p[1] + t * d[1]];
                let dist = (x[0] - target[0]).hypot(x[1] - target[1]);
                if dist < best.0 {
                    best = (dist, s, t, x);
                }
            }
            let (_, segment, along, reference) = best;
            let to_centre = [centre[0] - reference[0], centre[1] - reference[1]];
            let len = to_centre[0].hypot(to_centre[1]);
            let inward = if len > 0.0 {
                [to_centre[0] / len, to_centre[1] / len]
            } else {
                [0.0, 0.0]
            };
            DrawInPoint {
                name: (*name).to_string(),
                reference,
                segment,
                along,
                inward,
            }
        })
        .collect()
}

/// The in-plane displacement `(ux, uy)` at a draw-in point, interpolated
/// linearly along its boundary segment from the nodal displacements
/// `displacement(node)`.
pub fn boundary_displacement(
    point: &DrawInPoint,
    outer: &[usize],
    displacement: impl Fn(usize) -> [f64; 2],
) -> [f64; 2] {
    let a = displacement(outer[point.segment]);
    let b = displacement(outer[(point.segment + 1) % outer.len()]);
    let t = point.along;
    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
}

/// The draw-in at `point`: the in-plane displacement along its inward
/// direction \[mm\] (positive when the edge moved towards the centre).
pub fn draw_in(point: &DrawInPoint, in_plane: [f64; 2]) -> f64 {
    in_plane[0] * point.inward[0] + in_plane[1] * point.inward[1]
}

/// An evaluation zone: a rectangular window of the blank, in reference
/// coordinates. An element belongs to it when its reference centroid lies
/// inside (edges included).
#[derive(Debug, Clone, PartialEq)]
pub struct Zone {
    /// Name (`A`, `B`, `C` for the paper's zones).
    pub name: String,
    /// Centre `(x, y)` on the blank \[mm\].
    pub centre: [f64; 2],
    /// Size `(x, y)` \[mm\].
    pub size: [f64; 2],
}

impl Zone {
    /// The elements of `model` whose reference centroid lies in the zone.
    pub fn elements(&self, model: &MembraneModel) -> Vec<usize> {
        (0..model.triangles.len())
            .filter(|&e| {
                let t = model.triangles[e];
                let c = (model.nodes[t[0]] + model.nodes[t[1]] + model.nodes[t[2]]) / 3.0;
                (c.x - self.centre[0]).abs() <= 0.5 * self.size[0]
                    && (c.y - self.centre[1]).abs() <= 0.5 * self.size[1]
            })
            .collect()
    }
}

/// Weighted mean and standard deviation of `(weight, value)` pairs (zero
/// and zero without weight).
pub fn weighted_mean_std(pairs: impl IntoIterator<Item = (f64, f64)>) -> (f64, f64) {
    let (mut w, mut s, mut s2) = (0.0, 0.0, 0.0);
    for (a, v) in pairs {
        w += a;
        s += a * v;
        s2 += a * v * v;
    }
    if w <= 0.0 {
        return (0.0, 0.0);
    }
    let mean = s / w;
    (mean, (s2 / w - mean * mean).max(0.0).sqrt())
}

/// The paper's strain measures of one element (Section 4): `γ = I10`
/// \[deg\], `E22 = I8 − 1`, `E⊥ = I11 − 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrainMeasures {
    /// Shear angle `γ` \[deg\].
    pub shear_angle_deg: f64,
    /// `E22 = I8 − 1`.
    pub e22: f64,
    /// `E⊥ = I11 − 1`.
    pub e_perp: f64,
}

/// The strain measures of every element of `model` at displacement `u`
/// (all dofs), from the kinematics alone (no law): `None` where the
/// triangle is turned over or collapsed (signed area ratio ≤ 0) or its
/// invariants are not defined.
pub fn strain_measures(model: &MembraneModel, u: &[f64]) -> Vec<Option<StrainMeasures>> {
    (0..model.triangles.len())
        .map(|e| strain_measure(model, e, u))
        .collect()
}

/// The strain measures of element `e` of `model` at displacement `u`, as in
/// [`strain_measures`].
pub fn strain_measure(model: &MembraneModel, e: usize, u: &[f64]) -> Option<StrainMeasures> {
    let reference = &model.references[e];
    let kin = reference.kinematics(&model.element_displacements(e, u));
    if kin.orientation.is_nan() || kin.orientation <= 0.0 {
        return None;
    }
    let inv = Invariants::new(&kin.c, &reference.frame).ok()?;
    let m = StrainMeasures {
        shear_angle_deg: inv.i10().to_degrees(),
        e22: inv.i8 - 1.0,
        e_perp: inv.i11 - 1.0,
    };
    (m.shear_angle_deg.is_finite() && m.e22.is_finite() && m.e_perp.is_finite()).then_some(m)
}

/// The displacement of the 2D image-correlation view (Appendix C): `u` with
/// the z component of `nodes` (global node indices) set to zero, so that
/// the formed mesh lies projected on the blank plane at its reference
/// height.
pub fn projected_displacement(u: &[f64], nodes: std::ops::Range<usize>) -> Vec<f64> {
    let mut projected = u.to_vec();
    for n in nodes {
        projected[3 * n + 2] = 0.0;
    }
    projected
}

/// Strain below which `I8 − 1` and `I11 − 1` count as zero when an element
/// is classified ([`deformation_mode`]): 0.1 %, far above round-off and
/// below any strain the maps show.
pub const MODE_TOLERANCE: f64 = 1.0e-3;

/// The deformation mode of an element from the signs of `I8 − 1`
/// (stitching) and `I11 − 1` (across the rovings), after the paper's
/// Fig. 2d (Section 5.3), each sign counted only beyond
/// [`MODE_TOLERANCE`] (`tol`): 0 near the reference state (both within
/// `tol` of 0); 1 mixed-mode 1, `I11 < 1 − tol` with `I8 ≤ 1 + tol`
/// (shear and compaction, the stitching not stretched); 2 mixed-mode 2,
/// `I11 < 1 − tol` with `I8 > 1 + tol` (compaction with the stitching
/// stretched: roving slippage); 3 `I11 ≥ 1 − tol` with `I8 > 1 + tol`
/// (transverse tension); 4 `I11 ≥ 1 − tol` with `I8 ≤ 1 + tol`, not 0.
pub fn deformation_mode(i8: f64, i11: f64) -> u8 {
    let (stitching, across) = (i8 - 1.0, i11 - 1.0);
    if stitching.abs() <= MODE_TOLERANCE && across.abs() <= MODE_TOLERANCE {
        return 0;
    }
    let stretched = stitching > MODE_TOLERANCE;
    let compacted = across < -MODE_TOLERANCE;
    match (compacted, stretched) {
        (true, false) => 1,
        (true, true) => 2,
        (false, true) => 3,
        (false, false) => 4,
    }
}

/// Number of deformation modes ([`deformation_mode`] gives `0..MODES`).
pub const MODES: usize = 5;

/// The reference area \[mm²\] of the elements in each deformation mode:
/// `modes[e]` of element `e` of reference area `areas[e]`.
pub fn mode_areas(modes: &[u8], areas: &[f64]) -> [f64; MODES] {
    let mut sums = [0.0; MODES];
    for (m, a) in modes.iter().zip(areas) {
        sums[(*m as usize).min(MODES - 1)] += a;
    }
    sums
}
