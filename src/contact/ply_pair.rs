//! Geometry of contact between two deforming plies (`docs/contact.md`,
//! "Ply–ply contact"): the closest point of a triangle to a point, the
//! signed distance of a node from the other ply's mid-surface on the side
//! the node started from, and Verlet candidate lists found with a
//! bounding-volume tree (`parry3d-f64`'s [`Bvh`]) that is refitted as the
//! plies move.
//!
//! Kernels here take slices and write into buffers the caller owns; only
//! [`CandidateLists::rebuild`] allocates (when a list outgrows its
//! buffer).

use nalgebra::Vector3;
use parry3d_f64::bounding_volume::{Aabb, BoundingVolume};
use parry3d_f64::math::Vector as GlamVector;
use parry3d_f64::partitioning::{Bvh, BvhBuildStrategy, BvhWorkspace};

use super::SurfaceNormal;

/// The closest point of a triangle to a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrianglePoint {
    /// Barycentric weights of the closest point (non-negative, sum 1).
    pub weights: [f64; 3],
    /// The closest point \[mm\].
    pub point: Vector3<f64>,
    /// `true` when the point lies inside the face (all weights > 0), so
    /// the direction to it is the face normal.
    pub on_face: bool,
}

/// The closest point of the triangle `(a, b, c)` to `p` (Ericson,
/// *Real-Time Collision Detection*, Sec. 5.1.5: Voronoi regions of the
/// vertices, then the edges, then the face). A degenerate triangle answers
/// its closest vertex or edge point.
pub fn closest_on_triangle(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> TrianglePoint {
    let vertex = |k: usize, x: &Vector3<f64>| {
        let mut weights = [0.0; 3];
        weights[k] = 1.0;
        TrianglePoint {
            weights,
            point: *x,
            on_face: false,
        }
    };
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return vertex(0, a);
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return vertex(1, b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return TrianglePoint {
            weights: [1.0 - v, v, 0.0],
            point: a + v * ab,
            on_face: false,
        };
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return vertex(2, c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return TrianglePoint {
            weights: [1.0 - w, 0.0, w],
            point: a + w * ac,
            on_face: false,
        };
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return TrianglePoint {
            weights: [0.0, 1.0 - w, w],
            point: b + w * (c - b),
            on_face: false,
        };
    }
    let sum = va + vb + vc;
    if sum.is_nan() || sum <= 0.0 {
        // Degenerate (zero area): the closest of the three vertices.
        let k = [a, b, c]
            .iter()
            .map(|x| (p - *x).norm_squared())
            .enumerate()
            .fold(
                (0, f64::INFINITY),
                |m, (k, d)| if d < m.1 { (k, d) } else { m },
            )
            .0;
        return vertex(k, [a, b, c][k]);
    }
    let v = vb / sum;
    let w = vc / sum;
    TrianglePoint {
        weights: [1.0 - v - w, v, w],
        point: a + v * ab + w * ac,
        on_face: true,
    }
}

/// Smallest `|n·e|/|e|` (`n` the face normal, `e` from the closest point
/// to the node) at which a node whose closest point lies on an edge or a
/// vertex of the other ply is still in front of it: beyond that the node is
/// beside the other ply's free edge (or a fold sharper than 60°), not over
/// it, and is left open.
pub const MIN_FACING: f64 = 0.5;

/// The signed distance of a node at `x` from the other ply's mid-surface
/// at its closest point `closest` on a triangle of unit normal `face_normal`,
/// on the side `side` (±1) the node started from, and the contact normal
/// (pointing from the other ply to the node's side): the plane distance
/// `side · n·(x − c)` over the face, the point distance `±|x − c|` over an
/// edge or a vertex (continuous where the two meet). A node that has
/// crossed the mid-surface has a negative distance and a normal pointing
/// back to its side. `None` for a node beside a free edge
/// ([`MIN_FACING`]).
pub fn signed_distance(
    x: &Vector3<f64>,
    closest: &TrianglePoint,
    face_normal: &Vector3<f64>,
    side: f64,
) -> Option<SurfaceNormal> {
    let e = x - closest.point;
    let along = side * face_normal.dot(&e);
    if closest.on_face {
        return Some(SurfaceNormal {
            distance: along,
            normal: side * face_normal,
        });
    }
    let d = e.norm();
    if d <= 1e-12 * (1.0 + x.amax()) {
        return Some(SurfaceNormal {
            distance: 0.0,
            normal: side * face_normal,
        });
    }
    if along.abs() < MIN_FACING * d {
        return None;
    }
    Some(if along >= 0.0 {
        SurfaceNormal {
            distance: d,
            normal: e / d,
        }
    } else {
        SurfaceNormal {
            distance: -d,
            normal: -e / d,
        }
    })
}

/// The side (±1) of the other ply's mid-surface that a node at `x` is on,
/// from its closest point `closest` on a triangle of unit normal
/// `face_normal`: the sign of `n·(x − c)`; `None` where the node is beside
/// a free edge ([`MIN_FACING`]) or on the surface, so that no side can be
/// told.
pub fn side_of(
    x: &Vector3<f64>,
    closest: &TrianglePoint,
    face_normal: &Vector3<f64>,
) -> Option<f64> {
    let e = x - closest.point;
    let along = face_normal.dot(&e);
    (along != 0.0 && along.abs() >= MIN_FACING * e.norm()).then(|| along.signum())
}

/// The unit normal `(b − a) × (c − a) / |…|` of a triangle (zero for a
/// degenerate one).
#[inline]
pub fn face_normal(a: &Vector3<f64>, b: &Vector3<f64>, c: &Vector3<f64>) -> Vector3<f64> {
    let n = (b - a).cross(&(c - a));
    let length = n.norm();
    if length > 0.0 {
        n / length
    } else {
        Vector3::zeros()
    }
}

fn glam(v: &Vector3<f64>) -> GlamVector {
    GlamVector::new(v.x, v.y, v.z)
}

fn triangle_box(positions: &[Vector3<f64>], t: &[usize; 3]) -> Aabb {
    let (a, b, c) = (&positions[t[0]], &positions[t[1]], &positions[t[2]]);
    let mins = a.inf(b).inf(c);
    let maxs = a.sup(b).sup(c);
    Aabb::new(glam(&mins), glam(&maxs))
}

/// Verlet candidate lists of one pass (the nodes of one ply against the
/// triangles of the other): for each node, every triangle within
/// `reach + skin` of it when the lists were built. While no node of either
/// ply has moved more than `skin / 2` since then, every triangle within
/// `reach` of a node is on its list (relative motion ≤ `skin`), so the
/// lists need no update. Built with a [`Bvh`] of the triangles' boxes,
/// refitted (not rebuilt) at every update.
pub struct CandidateLists {
    reach: f64,
    skin: f64,
    bvh: Option<Bvh>,
    workspace: BvhWorkspace,
    /// CSR: the triangles of node `i` are `triangles[offsets[i]..offsets[i + 1]]`.
    offsets: Vec<u32>,
    triangles: Vec<u32>,
    /// Updates so far.
    builds: usize,
}

impl CandidateLists {
    /// Empty lists for the distance `reach` \[mm\] (the contact offset plus
    /// the cull margin) and the skin `skin` \[mm\] `> 0`.
    pub fn new(reach: f64, skin: f64) -> Self {
        Self {
            reach,
            skin,
            bvh: None,
            workspace: BvhWorkspace::default(),
            offsets: Vec::new(),
            triangles: Vec::new(),
            builds: 0,
        }
    }

    /// The skin \[mm\]: the lists hold while every node has moved less than
    /// half of it since [`CandidateLists::rebuild`].
    pub fn skin(&self) -> f64 {
        self.skin
    }

    /// How many times the lists were built.
    pub fn builds(&self) -> usize {
        self.builds
    }

    /// The candidate triangles of node `i`.
    #[inline]
    pub fn of(&self, i: usize) -> &[u32] {
        if self.offsets.is_empty() {
            return &[];
        }
        &self.triangles[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }

    /// Rebuilds the lists for the nodes at `nodes` against the triangles
    /// `triangles` (indices into `surface`, the other ply's current node
    /// positions): the tree is built at the first call and refitted to the
    /// moved triangles afterwards.
    pub fn rebuild(
        &mut self,
        nodes: &[Vector3<f64>],
        surface: &[Vector3<f64>],
        triangles: &[[usize; 3]],
    ) {
        match &mut self.bvh {
            None => {
                let leaves: Vec<Aabb> =
                    triangles.iter().map(|t| triangle_box(surface, t)).collect();
                self.bvh = Some(Bvh::from_leaves(BvhBuildStrategy::default(), &leaves));
            }
            Some(bvh) => {
                for (k, t) in triangles.iter().enumerate() {
                    bvh.insert_or_update_partially(triangle_box(surface, t), k as u32, 0.0);
                }
                bvh.refit(&mut self.workspace);
            }
        }
        let Some(bvh) = &self.bvh else { return };
        let distance = self.reach + self.skin;
        self.offsets.clear();
        self.triangles.clear();
        self.offsets.push(0);
        for x in nodes {
            let probe = Aabb::new(glam(x), glam(x)).loosened(distance);
            let start = self.triangles.len();
            self.triangles.extend(bvh.intersect_aabb(&probe));
            // A fixed order whatever the tree's layout: results do not
            // depend on the refits.
            self.triangles[start..].sort_unstable();
            self.offsets.push(self.triangles.len() as u32);
        }
        self.builds += 1;
    }
}

/// The bounding box `[min x, min y, min z, max x, max y, max z]` of each
/// triangle at the positions `surface`, into `boxes`.
pub fn triangle_boxes(surface: &[Vector3<f64>], triangles: &[[usize; 3]], boxes: &mut [[f64; 6]]) {
    for (b, t) in boxes.iter_mut().zip(triangles) {
        let (p, q, r) = (&surface[t[0]], &surface[t[1]], &surface[t[2]]);
        for k in 0..3 {
            b[k] = p[k].min(q[k]).min(r[k]);
            b[k + 3] = p[k].max(q[k]).max(r[k]);
        }
    }
}

/// The squared distance from `x` to the box `b` (as [`triangle_boxes`]
/// writes it): a lower bound of the squared distance to the triangle.
#[inline]
fn box_distance_squared(x: &Vector3<f64>, b: &[f64; 6]) -> f64 {
    let mut sum = 0.0;
    for k in 0..3 {
        let outside = (b[k] - x[k]).max(x[k] - b[k + 3]).max(0.0);
        sum += outside * outside;
    }
    sum
}

/// The closest point over the candidate triangles `candidates` of the
/// node at `x`: the triangle (index), the point, and the triangle's unit
/// normal; `None` without candidates. The triangle `hint` (the last one
/// found, if still a candidate) is tried first, and a triangle whose
/// bounding box (`boxes`, from [`triangle_boxes`] at `surface`) is not
/// nearer than the best point so far is skipped. Ties keep the earlier
/// triangle in list order (the hint first).
pub fn closest_candidate(
    x: &Vector3<f64>,
    candidates: &[u32],
    surface: &[Vector3<f64>],
    triangles: &[[usize; 3]],
    boxes: &[[f64; 6]],
    hint: Option<u32>,
) -> Option<(usize, TrianglePoint, Vector3<f64>)> {
    let mut best: Option<(usize, TrianglePoint, f64)> = None;
    let hint = hint.filter(|h| candidates.binary_search(h).is_ok());
    for &k in hint
        .iter()
        .chain(candidates.iter().filter(|k| Some(**k) != hint))
    {
        if let Some(b) = &best
            && box_distance_squared(x, &boxes[k as usize]) >= b.2
        {
            continue;
        }
        let t = &triangles[k as usize];
        let point = closest_on_triangle(x, &surface[t[0]], &surface[t[1]], &surface[t[2]]);
        let d2 = (x - point.point).norm_squared();
        if best.as_ref().is_none_or(|b| d2 < b.2) {
            best = Some((k as usize, point, d2));
        }
    }
    best.map(|(k, point, _)| {
        let t = &triangles[k];
        (
            k,
            point,
            face_normal(&surface[t[0]], &surface[t[1]], &surface[t[2]]),
        )
    })
}
