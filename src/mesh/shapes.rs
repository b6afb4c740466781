//! Generated meshes of two verification shapes (see `docs/references.md`
//! §2): a flat circular membrane ([`disk`]) and a strip wrapped over a
//! cylinder with two straight tangent tails ([`wrapped_strip`]). Labels are
//! 1-based indices, every triangle is counter-clockwise about the stated
//! normal, and [`Mesh::check`] passes.

use std::collections::BTreeMap;
use std::f64::consts::TAU;

use nalgebra::Vector3;

use super::generate::MAX_TRIANGLES;
use super::{Mesh, MeshError};
use crate::config::readable_number;

fn invalid(generator: &str, parameter: &str, value: f64, expected: &str) -> MeshError {
    MeshError::Invalid {
        file: generator.to_string(),
        what: format!(
            "{parameter} = {}: expected {expected}",
            readable_number(value)
        ),
    }
}

fn positive(generator: &str, parameter: &str, value: f64, unit: &str) -> Result<(), MeshError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            generator,
            parameter,
            value,
            &format!("a finite {parameter} > 0 {unit}"),
        ))
    }
}

fn too_many(generator: &str, triangles: f64, element_size: f64) -> MeshError {
    invalid(
        generator,
        "element_size",
        element_size,
        &format!(
            "a size giving at most {MAX_TRIANGLES} triangles (this one gives {triangles:.3e})"
        ),
    )
}

const DISK: &str = "disk generator";

/// A flat disk of radius `R` (mm) in the xy-plane, centred at the origin,
/// meshed in `n = ceil(R/h)` concentric rings: ring `k` (radius `kR/n`,
/// `k = 1..n`) has `6k` nodes at the angles `2πj/(6k)`, and the band between
/// rings `k−1` and `k` is triangulated by merging the two rings in angle
/// (`6(2k−1)` triangles, in each 60° sector alternately against the outer
/// and the inner ring as in a hexagonal lattice). So the mesh has
/// `3n(n+1) + 1` nodes and `6n²` triangles, radial spacing `R/n ≤ h`, hoop
/// spacing `≈ 1.05 R/n`, every angle in `[43.7°, 90°)` and every edge
/// `≤ 1.45 R/n` (measured for n up to 300); the rim nodes lie on the circle
/// (to rounding) and the triangles cover the inscribed `6n`-gon, of area
/// `3n R² sin(π/(3n))`.
///
/// Triangles are counter-clockwise seen from +z (normal +z). Node sets
/// `centre` (node 0), `rim` (ring `n`) and `all`; element set `all`; fibres
/// along global x.
///
/// # Errors
/// `radius` or `element_size` not finite and > 0, or more than
/// [`MAX_TRIANGLES`] triangles.
pub fn disk(radius: f64, element_size: f64) -> Result<Mesh, MeshError> {
    positive(DISK, "radius", radius, "mm")?;
    positive(DISK, "element_size", element_size, "mm")?;
    let rings = (radius / element_size).ceil().max(1.0);
    let triangles_f = 6.0 * rings * rings;
    if triangles_f > MAX_TRIANGLES as f64 {
        return Err(too_many(DISK, triangles_f, element_size));
    }
    let n = rings as usize;
    let ring_start = |k: usize| if k == 0 { 0 } else { 1 + 3 * k * (k - 1) };
    let node_count = ring_start(n + 1);
    let mut nodes = Vec::with_capacity(node_count);
    nodes.push(Vector3::zeros());
    for k in 1..=n {
        let r = if k == n {
            radius
        } else {
            radius * k as f64 / n as f64
        };
        let count = 6 * k;
        for j in 0..count {
            let phi = TAU * (j as f64 / count as f64);
            let (sin, cos) = phi.sin_cos();
            nodes.push(Vector3::new(r * cos, r * sin, 0.0));
        }
    }
    let mut triangles = Vec::with_capacity(6 * n * n);
    for j in 0..6 {
        triangles.push([0, 1 + j, 1 + (j + 1) % 6]);
    }
    for k in 2..=n {
        let (inner, outer) = (6 * (k - 1), 6 * k);
        let (i0, o0) = (ring_start(k - 1), ring_start(k));
        let (mut i, mut o) = (0, 0);
        while i < inner || o < outer {
            // Advance along the ring whose next node comes first in angle,
            // (o+1)/(6k) < (i+1)/(6(k−1)) compared exactly in integers; at a
            // tie (the sector corners) the inner ring goes first, which
            // gives the hexagonal-lattice pattern (outer, inner, outer, …).
            let outer_first = i == inner || (o < outer && (o + 1) * (k - 1) < (i + 1) * k);
            let (a, b) = (i0 + i % inner, o0 + o % outer);
            if outer_first {
                triangles.push([a, b, o0 + (o + 1) % outer]);
                o += 1;
            } else {
                triangles.push([a, b, i0 + (i + 1) % inner]);
                i += 1;
            }
        }
    }
    let mut node_sets = BTreeMap::new();
    node_sets.insert("centre".to_string(), vec![0]);
    node_sets.insert("rim".to_string(), (ring_start(n)..node_count).collect());
    node_sets.insert("all".to_string(), (0..node_count).collect());
    let mut element_sets = BTreeMap::new();
    element_sets.insert("all".to_string(), (0..triangles.len()).collect());
    let mut mesh = Mesh {
        node_labels: (1..=nodes.len() as i64).collect(),
        element_labels: (1..=triangles.len() as i64).collect(),
        fibres: Vec::new(),
        source: format!(
            "generated disk, radius {} mm, {n} rings, {} triangles",
            readable_number(radius),
            triangles.len()
        ),
        nodes,
        triangles,
        node_sets,
        element_sets,
    };
    mesh.set_fibres_from_global(Vector3::x())?;
    Ok(mesh)
}

const STRIP: &str = "wrapped strip generator";

/// A strip of width `w` wrapped over a cylinder whose axis is the global y
/// axis: its mid-surface lies on the circle of radius `r` (cylinder radius
/// plus half the ply thickness) over the wrap angle `α`, centred on the top
/// (`+z`) of the cylinder, and continues in two straight tangent tails of
/// length `L_t`. The parametrisation is [`WrappedStrip::point`]; end `a`
/// is at `u = 0` (the tail on the −x side), end `b` at `u = α r + 2 L_t`
/// (the +x side). For `α = π` both tails hang straight down (−z) at
/// `x = ∓r`. For `α > π` the tails converge below the cylinder (the
/// generator does not check that they do not cross).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WrappedStrip {
    /// Width `w` along y \[mm\]; the strip spans `y ∈ [−w/2, w/2]`.
    pub width: f64,
    /// Radius `r` of the mid-surface arc \[mm\].
    pub radius: f64,
    /// Wrap angle `α` \[rad\], in `[0, 2π)`.
    pub wrap_angle: f64,
    /// Length `L_t` of each straight tail \[mm\], `≥ 0`.
    pub tail_length: f64,
    /// Target element size `h` \[mm\].
    pub element_size: f64,
}

impl WrappedStrip {
    /// Length of the mid-surface along the rovings, `α r + 2 L_t` \[mm\].
    pub fn length(&self) -> f64 {
        self.wrap_angle * self.radius + 2.0 * self.tail_length
    }

    /// The reference mid-surface point at arc length `u ∈ [0, α r + 2 L_t]`
    /// from end `a` and width coordinate `y` \[mm\]. With `φ = −α/2 +
    /// (u − L_t)/r`:
    ///
    /// ```text
    /// tail a (u < L_t):          (−r sin(α/2), y, r cos(α/2)) − (L_t − u) (cos(α/2), 0,  sin(α/2))
    /// arc (L_t ≤ u ≤ L_t + α r): (r sin φ, y, r cos φ)
    /// tail b (u > L_t + α r):    ( r sin(α/2), y, r cos(α/2)) + (u − L_t − α r) (cos(α/2), 0, −sin(α/2))
    /// ```
    ///
    /// The unit tangent along increasing `u` is `(cos φ, 0, −sin φ)` (φ held
    /// at `∓α/2` on the tails) and `tangent × e_y = (sin φ, 0, cos φ)` is the
    /// outward normal.
    pub fn point(&self, u: f64, y: f64) -> Vector3<f64> {
        let (r, lt, half) = (self.radius, self.tail_length, 0.5 * self.wrap_angle);
        let (sin, cos) = half.sin_cos();
        if u < lt {
            Vector3::new(-r * sin - (lt - u) * cos, y, r * cos - (lt - u) * sin)
        } else if u <= lt + self.wrap_angle * r {
            let (sp, cp) = (-half + (u - lt) / r).sin_cos();
            Vector3::new(r * sp, y, r * cp)
        } else {
            let d = u - lt - self.wrap_angle * r;
            Vector3::new(r * sin + d * cos, y, r * cos - d * sin)
        }
    }

    fn validate(&self) -> Result<(), MeshError> {
        positive(STRIP, "width", self.width, "mm")?;
        positive(STRIP, "radius", self.radius, "mm")?;
        positive(STRIP, "element_size", self.element_size, "mm")?;
        if !(self.wrap_angle.is_finite() && (0.0..TAU).contains(&self.wrap_angle)) {
            return Err(invalid(
                STRIP,
                "wrap_angle",
                self.wrap_angle,
                "a finite angle in [0, 2π) rad",
            ));
        }
        if !(self.tail_length.is_finite() && self.tail_length >= 0.0) {
            return Err(invalid(
                STRIP,
                "tail_length",
                self.tail_length,
                "a finite tail length >= 0 mm",
            ));
        }
        if self.length() <= 0.0 {
            return Err(invalid(
                STRIP,
                "wrap_angle",
                self.wrap_angle,
                "a wrap angle > 0 or tails of positive length (the strip has zero length)",
            ));
        }
        Ok(())
    }
}

/// Meshes a [`WrappedStrip`]: a structured grid in `(u, y)` with
/// `n_t = ceil(L_t/h)` segments per tail, `n_a = ceil(α r/h)` along the arc
/// (nodes on the circle, so the arc is meshed by chords) and
/// `n_w = ceil(w/h)` across the width; each cell `(u_m, u_m+1) × (y_j,
/// y_j+1)` is a planar rectangle cut by its diagonal from `(m, j)` to
/// `(m+1, j+1)`, so every triangle has one edge along the rovings (the
/// chord in u) and one across. Node `(m, j)` has index `m (n_w + 1) + j`.
///
/// Fibres: the unit chord of each cell (exactly in the triangle's plane).
/// Normals: outward from the cylinder (`(sin φ, 0, cos φ)`). Node sets
/// `end_a` (`u = 0`), `end_b` (`u = α r + 2 L_t`), `all`; element sets
/// `tail_a`, `arc`, `tail_b`, `all`. The reference configuration is this
/// wrapped shape (stress free).
///
/// # Errors
/// Sizes not finite and positive (`tail_length ≥ 0`), `α` outside
/// `[0, 2π)`, a strip of zero length, or more than [`MAX_TRIANGLES`]
/// triangles.
pub fn wrapped_strip(spec: &WrappedStrip) -> Result<Mesh, MeshError> {
    spec.validate()?;
    let h = spec.element_size;
    let (r, lt, alpha) = (spec.radius, spec.tail_length, spec.wrap_angle);
    let n_tail = (lt / h).ceil();
    let n_arc = (alpha * r / h).ceil();
    let n_width = (spec.width / h).ceil().max(1.0);
    let triangles_f = 2.0 * (2.0 * n_tail + n_arc) * n_width;
    if triangles_f > MAX_TRIANGLES as f64 {
        return Err(too_many(STRIP, triangles_f, h));
    }
    let (n_tail, n_arc, n_width) = (n_tail as usize, n_arc as usize, n_width as usize);
    let half = 0.5 * alpha;
    let (sin, cos) = half.sin_cos();
    // Stations along u, as (x, z) of the mid-line, and the segment each
    // cell belongs to: 0 tail a, 1 arc, 2 tail b.
    let mut stations: Vec<(f64, f64)> = Vec::with_capacity(2 * n_tail + n_arc + 1);
    let mut cell_segment: Vec<u8> = Vec::with_capacity(2 * n_tail + n_arc);
    for i in 0..n_tail {
        let back = lt * ((n_tail - i) as f64 / n_tail as f64);
        stations.push((-r * sin - back * cos, r * cos - back * sin));
        cell_segment.push(0);
    }
    for j in 0..=n_arc {
        let phi = if j == n_arc {
            half
        } else {
            -half + alpha * (j as f64 / n_arc as f64)
        };
        let (sp, cp) = phi.sin_cos();
        stations.push((r * sp, r * cp));
        if j < n_arc {
            cell_segment.push(1);
        }
    }
    for i in 1..=n_tail {
        let d = lt * (i as f64 / n_tail as f64);
        stations.push((r * sin + d * cos, r * cos - d * sin));
        cell_segment.push(2);
    }
    let columns = n_width + 1;
    let width_at = |j: usize| {
        if j == n_width {
            0.5 * spec.width
        } else {
            spec.width * (j as f64 / n_width as f64 - 0.5)
        }
    };
    let mut nodes = Vec::with_capacity(stations.len() * columns);
    for &(x, z) in &stations {
        for j in 0..columns {
            nodes.push(Vector3::new(x, width_at(j), z));
        }
    }
    let id = |m: usize, j: usize| m * columns + j;
    let cells = stations.len() - 1;
    let mut triangles = Vec::with_capacity(2 * cells * n_width);
    let mut fibres = Vec::with_capacity(2 * cells * n_width);
    let mut element_sets: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for (m, &segment) in cell_segment.iter().enumerate() {
        let chord = nodes[id(m + 1, 0)] - nodes[id(m, 0)];
        let fibre = chord / chord.norm();
        let name = ["tail_a", "arc", "tail_b"][segment as usize];
        for j in 0..n_width {
            let (n00, n10, n11, n01) = (id(m, j), id(m + 1, j), id(m + 1, j + 1), id(m, j + 1));
            let set = element_sets.entry(name.to_string()).or_default();
            set.push(triangles.len());
            set.push(triangles.len() + 1);
            triangles.push([n00, n10, n11]);
            triangles.push([n00, n11, n01]);
            fibres.push(fibre);
            fibres.push(fibre);
        }
    }
    element_sets.insert("all".to_string(), (0..triangles.len()).collect());
    let mut node_sets = BTreeMap::new();
    node_sets.insert(
        "end_a".to_string(),
        (0..columns).map(|j| id(0, j)).collect(),
    );
    node_sets.insert(
        "end_b".to_string(),
        (0..columns).map(|j| id(cells, j)).collect(),
    );
    node_sets.insert("all".to_string(), (0..nodes.len()).collect());
    let mesh = Mesh {
        node_labels: (1..=nodes.len() as i64).collect(),
        element_labels: (1..=triangles.len() as i64).collect(),
        source: format!(
            "generated wrapped strip, width {} mm, radius {} mm, wrap {} rad, tails {} mm, {} x {n_width} cells",
            readable_number(spec.width),
            readable_number(r),
            readable_number(alpha),
            readable_number(lt),
            cells
        ),
        nodes,
        triangles,
        fibres,
        node_sets,
        element_sets,
    };
    mesh.check()?;
    Ok(mesh)
}
