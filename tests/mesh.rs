//! Tests of the mesh layer: the OAT specimen generator (docs/cases.md),
//! the Abaqus `.inp` and Gmsh `.msh` 4.1 readers, fibre directions and the
//! mesh checks (docs/meshes.md). Each test names the requirement it checks.

use std::collections::BTreeMap;
use std::path::Path;

use nalgebra::Vector3;
use ncform::mesh::generate::{
    GeneratedMesh, GridPattern, GridResolution, OatSpecimen, oat_specimen, roving_direction,
};
use ncform::mesh::inp::{parse_inp, read_inp};
use ncform::mesh::msh::{parse_msh, read_msh};
use ncform::mesh::{Mesh, MeshError};

fn spec(theta: f64, resolution: GridResolution, pattern: GridPattern) -> OatSpecimen {
    OatSpecimen {
        width: 100.0,
        length: 300.0,
        bias_angle_deg: theta,
        resolution,
        pattern,
    }
}

fn generate(theta: f64, resolution: GridResolution, pattern: GridPattern) -> GeneratedMesh {
    oat_specimen(&spec(theta, resolution, pattern)).expect("valid specimen")
}

/// Angle in degrees between the lines along `u` and `v`.
fn line_angle(u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    u.cross(v).norm().atan2(u.dot(v).abs()).to_degrees()
}

/// Angle between `a` and the nearest edge of triangle `e`.
fn nearest_edge_angle(mesh: &Mesh, e: usize, a: &Vector3<f64>) -> f64 {
    let [i, j, k] = mesh.triangles[e];
    let (x0, x1, x2) = (mesh.nodes[i], mesh.nodes[j], mesh.nodes[k]);
    line_angle(&(x1 - x0), a)
        .min(line_angle(&(x2 - x1), a))
        .min(line_angle(&(x0 - x2), a))
}

fn message<T: std::fmt::Debug>(r: Result<T, MeshError>) -> String {
    r.expect_err("an error was expected").to_string()
}

/// Asserts that `msg` contains every one of `parts`.
fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message `{msg}` lacks `{p}`");
    }
}

/// The paper mesh size: about 8,200 triangles on 100 × 300 mm.
fn paper_h() -> f64 {
    (2.0 * 100.0 * 300.0 / 8200.0f64).sqrt()
}

// ---------------------------------------------------------------- generator

/// Requirement: nx × ny cells give 2·nx·ny triangles and (nx+1)(ny+1) nodes,
/// and the triangle areas sum to W·L (1e-9 relative).
#[test]
fn generator_counts_and_area_sum() {
    for (theta, pattern, per_cell, centre) in [
        (30.0, GridPattern::RovingDiagonal, 2, 0),
        (-30.0, GridPattern::RovingDiagonal, 2, 0),
        (45.0, GridPattern::BothDiagonals, 4, 1),
    ] {
        let g = generate(theta, GridResolution::Counts { nx: 5, ny: 7 }, pattern);
        let m = &g.mesh;
        assert_eq!((g.nx, g.ny), (5, 7));
        assert_eq!(m.triangles.len(), 5 * 7 * per_cell);
        assert_eq!(m.nodes.len(), 6 * 8 + centre * 35);
        let total: f64 = (0..m.triangles.len()).map(|e| m.triangle_area(e)).sum();
        assert!((total / (100.0 * 300.0) - 1.0).abs() < 1e-9, "area {total}");
        m.check().expect("generated mesh passes check");
    }
}

/// Requirement: every triangle has an edge within `edge_deviation_deg`
/// (+1e-9) of a0, and the reported deviation is attained.
#[test]
fn generator_every_triangle_has_edge_within_reported_deviation() {
    let cases = [
        (30.0, GridResolution::ElementSize(10.0)),
        (45.0, GridResolution::ElementSize(7.0)),
        (60.0, GridResolution::ElementSize(12.0)),
        (-60.0, GridResolution::ElementSize(12.0)),
        (20.0, GridResolution::Counts { nx: 3, ny: 11 }),
        (-75.0, GridResolution::Counts { nx: 9, ny: 4 }),
    ];
    for (theta, res) in cases {
        for pattern in [GridPattern::RovingDiagonal, GridPattern::BothDiagonals] {
            let g = generate(theta, res, pattern);
            let a0 = roving_direction(theta);
            let mut worst: f64 = 0.0;
            for e in 0..g.mesh.triangles.len() {
                let d = nearest_edge_angle(&g.mesh, e, &a0);
                assert!(
                    d <= g.edge_deviation_deg + 1e-9,
                    "θ = {theta}: element {e} {d}° > {}°",
                    g.edge_deviation_deg
                );
                worst = worst.max(d);
            }
            assert!((worst - g.edge_deviation_deg).abs() < 1e-9);
        }
    }
}

/// Requirement (docs/cases.md): the paper-size meshes (100 × 300 mm, h for
/// about 8,200 triangles) at 30°, 45°, 60° have 8,200 triangles ± 10 %
/// (`COUNT_TOLERANCE`) and every triangle within 0.1° of the rovings (a
/// misalignment δ leaks roving stiffness of order C4·δ² ≤ 0.003 MPa, 2 % of
/// the initial shear modulus); 45° gives the exactly aligned 37 × 111 grid;
/// the chosen counts lie in the search window [0.8, 1.25] × nominal nx.
#[test]
fn generator_paper_meshes_aligned() {
    let h = paper_h();
    for theta in [30.0, 45.0, 60.0] {
        let g = generate(
            theta,
            GridResolution::ElementSize(h),
            GridPattern::RovingDiagonal,
        );
        let n = g.mesh.triangles.len();
        println!(
            "θ = {theta}°: nx = {}, ny = {}, {} triangles, deviation {:.6}°",
            g.nx, g.ny, n, g.edge_deviation_deg
        );
        assert!(g.edge_deviation_deg <= 0.1, "{}", g.edge_deviation_deg);
        let t = f64::to_radians(theta).tan();
        let nx0 = 100.0 / (h * t.sqrt());
        assert!(g.nx as f64 >= 0.8 * nx0 && g.nx as f64 <= 1.25 * nx0);
        assert!((n as f64 - 8200.0).abs() <= 0.1 * 8200.0, "{n} triangles");
        for f in &g.mesh.fibres {
            assert_eq!(*f, roving_direction(theta), "fibre is the exact a0");
        }
    }
    let g45 = generate(
        45.0,
        GridResolution::ElementSize(h),
        GridPattern::RovingDiagonal,
    );
    assert_eq!((g45.nx, g45.ny), (37, 111));
    assert_eq!(g45.mesh.triangles.len(), 8214);
    assert!(g45.edge_deviation_deg < 1e-9);
}

/// Requirement: with explicit counts near the paper's 8,200 triangles
/// (within ±10 %) the alignment is still within 0.05° at 30° and 45°
/// (docs/meshes.md lists these counts).
#[test]
fn generator_paper_counts_within_ten_percent() {
    for (theta, nx, ny, max_dev) in [(30.0, 49, 85, 0.04), (45.0, 37, 111, 1e-9)] {
        let g = generate(
            theta,
            GridResolution::Counts { nx, ny },
            GridPattern::RovingDiagonal,
        );
        let n = g.mesh.triangles.len() as f64;
        assert!((n / 8200.0 - 1.0).abs() <= 0.1);
        assert!(g.edge_deviation_deg <= max_dev, "{}", g.edge_deviation_deg);
    }
}

/// Requirement: −θ gives the mirror image of +θ (x → W − x): same counts and
/// deviation, the other diagonal, a0 = (sin θ, cos θ, 0) with sin θ < 0.
#[test]
fn generator_negative_angle_is_mirrored() {
    let res = GridResolution::ElementSize(8.0);
    let p = generate(45.0, res, GridPattern::RovingDiagonal);
    let n = generate(-45.0, res, GridPattern::RovingDiagonal);
    assert_eq!((p.nx, p.ny), (n.nx, n.ny));
    assert!((p.edge_deviation_deg - n.edge_deviation_deg).abs() < 1e-12);
    assert!(n.mesh.fibres[0].x < 0.0 && n.mesh.fibres[0].y > 0.0);
    let key = |c: Vector3<f64>| ((c.x * 1e6).round() as i64, (c.y * 1e6).round() as i64);
    let mut mirrored: Vec<_> = (0..n.mesh.triangles.len())
        .map(|e| {
            let c = n.mesh.centroid(e);
            key(Vector3::new(100.0 - c.x, c.y, 0.0))
        })
        .collect();
    let mut direct: Vec<_> = (0..p.mesh.triangles.len())
        .map(|e| key(p.mesh.centroid(e)))
        .collect();
    mirrored.sort_unstable();
    direct.sort_unstable();
    assert_eq!(mirrored, direct);
    let a0 = roving_direction(-45.0);
    for e in 0..n.mesh.triangles.len() {
        assert!(nearest_edge_angle(&n.mesh, e, &a0) < 1e-9);
    }
}

/// Requirement: at 0° and ±90° the grid has cells as square as possible and
/// its sides are the rovings (deviation 0, exact a0).
#[test]
fn generator_zero_and_ninety_degrees() {
    let g = generate(
        0.0,
        GridResolution::ElementSize(10.0),
        GridPattern::RovingDiagonal,
    );
    assert_eq!((g.nx, g.ny), (10, 30));
    assert_eq!(g.edge_deviation_deg, 0.0);
    assert_eq!(g.mesh.fibres[0], Vector3::new(0.0, 1.0, 0.0));
    for theta in [90.0, -90.0] {
        let g = generate(
            theta,
            GridResolution::ElementSize(7.0),
            GridPattern::RovingDiagonal,
        );
        assert_eq!((g.nx, g.ny), (14, 43));
        assert_eq!(g.edge_deviation_deg, 0.0);
        assert_eq!(g.mesh.fibres[0], Vector3::new(f64::signum(theta), 0.0, 0.0));
        g.mesh.check().unwrap();
    }
}

/// Requirement: `BothDiagonals` splits each cell into four triangles around
/// a centre node; at 45° every triangle has an edge along the rovings and
/// one along the stitching, and both diagonal directions occur.
#[test]
fn generator_both_diagonals_has_both_directions() {
    let g = generate(
        45.0,
        GridResolution::Counts { nx: 4, ny: 12 },
        GridPattern::BothDiagonals,
    );
    let a0 = roving_direction(45.0);
    let b0 = Vector3::new(-a0.y, a0.x, 0.0);
    for e in 0..g.mesh.triangles.len() {
        assert!(nearest_edge_angle(&g.mesh, e, &a0) < 1e-9, "roving edge");
        assert!(nearest_edge_angle(&g.mesh, e, &b0) < 1e-9, "stitching edge");
    }
    assert_eq!(g.mesh.triangles.len(), 4 * 48);
    assert_eq!(g.mesh.nodes.len(), 5 * 13 + 48);
    // The centre node of the first cell.
    assert_eq!(g.mesh.nodes[65], Vector3::new(12.5, 12.5, 0.0));
}

/// Requirement: node sets `bottom` (y = 0), `top` (y = L), `left` (x = 0),
/// `right` (x = W) hold exactly the nodes on those edges; `all` holds every
/// node and element set `all` every triangle; sets are sorted and unique.
#[test]
fn generator_node_sets_on_the_edges() {
    for pattern in [GridPattern::RovingDiagonal, GridPattern::BothDiagonals] {
        let g = generate(30.0, GridResolution::ElementSize(9.0), pattern);
        let m = &g.mesh;
        let on = |pred: &dyn Fn(&Vector3<f64>) -> bool| -> Vec<usize> {
            (0..m.nodes.len()).filter(|&n| pred(&m.nodes[n])).collect()
        };
        assert_eq!(m.node_set("bottom").unwrap(), on(&|x| x.y == 0.0));
        assert_eq!(m.node_set("top").unwrap(), on(&|x| x.y == 300.0));
        assert_eq!(m.node_set("left").unwrap(), on(&|x| x.x == 0.0));
        assert_eq!(m.node_set("right").unwrap(), on(&|x| x.x == 100.0));
        assert_eq!(m.node_set("bottom").unwrap().len(), g.nx + 1);
        assert_eq!(m.node_set("left").unwrap().len(), g.ny + 1);
        assert_eq!(m.node_set("all").unwrap().len(), m.nodes.len());
        assert_eq!(m.element_set("all").unwrap().len(), m.triangles.len());
        assert_eq!(m.node_labels[0], 1);
        assert_eq!(*m.element_labels.last().unwrap(), m.triangles.len() as i64);
        assert!(m.source.starts_with("generated"));
    }
}

/// Requirement: all generated triangles are counter-clockwise seen from +z
/// (normal (0, 0, 1)).
#[test]
fn generator_triangles_counter_clockwise() {
    for theta in [0.0, 30.0, -30.0, 45.0, -60.0, 90.0, -90.0] {
        for pattern in [GridPattern::RovingDiagonal, GridPattern::BothDiagonals] {
            let Ok(g) = oat_specimen(&spec(theta, GridResolution::ElementSize(15.0), pattern))
            else {
                assert_eq!(pattern, GridPattern::BothDiagonals);
                continue;
            };
            for e in 0..g.mesh.triangles.len() {
                let n = g.mesh.triangle_normal(e);
                assert!(
                    (n - Vector3::z()).norm() < 1e-12,
                    "θ = {theta}, element {e}"
                );
            }
        }
    }
}

/// Requirement: bad specifications are rejected with a message naming the
/// parameter, the value and what is expected.
#[test]
fn generator_rejects_bad_specs() {
    let ok = spec(
        30.0,
        GridResolution::ElementSize(5.0),
        GridPattern::RovingDiagonal,
    );
    let cases: Vec<(OatSpecimen, &[&str])> = vec![
        (OatSpecimen { width: 0.0, ..ok }, &["width = 0", "> 0 mm"]),
        (OatSpecimen { width: -5.0, ..ok }, &["width = -5"]),
        (
            OatSpecimen {
                length: f64::NAN,
                ..ok
            },
            &["length = nan", "finite"],
        ),
        (
            OatSpecimen {
                length: f64::INFINITY,
                ..ok
            },
            &["length = inf"],
        ),
        (
            OatSpecimen {
                bias_angle_deg: 91.0,
                ..ok
            },
            &["bias_angle_deg = 91", "[-90, 90]"],
        ),
        (
            OatSpecimen {
                bias_angle_deg: f64::NAN,
                ..ok
            },
            &["bias_angle_deg = nan"],
        ),
        (
            OatSpecimen {
                resolution: GridResolution::ElementSize(0.0),
                ..ok
            },
            &["element_size = 0", "> 0 mm"],
        ),
        (
            OatSpecimen {
                resolution: GridResolution::ElementSize(-1.0),
                ..ok
            },
            &["element_size = -1"],
        ),
        (
            OatSpecimen {
                resolution: GridResolution::Counts { nx: 0, ny: 4 },
                ..ok
            },
            &["nx, ny = 0, 4", "at least one cell"],
        ),
        (
            OatSpecimen {
                resolution: GridResolution::ElementSize(0.01),
                ..ok
            },
            &["element_size = 0.01", "5000000 triangles"],
        ),
        (
            OatSpecimen {
                resolution: GridResolution::Counts { nx: 3000, ny: 3000 },
                ..ok
            },
            &["nx, ny = 3000, 3000", "5000000 triangles"],
        ),
        (
            OatSpecimen {
                bias_angle_deg: 1e-9,
                ..ok
            },
            &["bias_angle_deg = 1e-9", "0 or ±90 exactly"],
        ),
        (
            OatSpecimen {
                bias_angle_deg: 0.0,
                pattern: GridPattern::BothDiagonals,
                ..ok
            },
            &[
                "pattern = \"both-diagonals\"",
                "\"roving-diagonal\" at bias angle 0°",
            ],
        ),
    ];
    for (s, parts) in cases {
        let msg = message(oat_specimen(&s));
        assert_mentions(&msg, parts);
        assert_mentions(&msg, &["specimen generator"]);
        assert!(!msg.contains("Diagonal"), "Rust enum name in {msg}");
    }
}

// ------------------------------------------------------------------ readers

const INP: &str = "** two unit squares, sparse ids, mixed case
*Heading
 a test mesh, with commas
*Node, nset=corners
  10, 0.0, 0.0
  20, 1.0, 0.0, 0.0
  30, 1.0, 1.0
  40, 0.,  1.
**  a comment between data lines
*NODE
 50, 2.0D0, 0.0
 60, 2.0,
  1.0
*Element, type=S3R, elset=Fabric
 100, 10, 20, 30
 200, 10, 30,
   40
*ELEMENT, TYPE=cps3
 300, 20, 50, 60
 400, 20, 60, 30,
*NSET, NSET=bottom, GENERATE
 10, 20, 10
*Nset, nset=Bottom
 50,
*NSET, NSET=right
 50, 60
*NSET, NSET=edges
 bottom, right, 40
*ELSET, ELSET=upper, generate
 300, 400, 100
*ELSET, ELSET=both
 Fabric, upper
*NSET, NSET=fabric_nodes, ELSET=fabric
*Material, name=ncf
*Density
 1.e-9,
*Step
*Static
 0.1, 1.0
*End Step
";

/// Requirement: the .inp reader handles keywords and options in any case,
/// `**` comments, continuation lines, sparse ids, `NSET=`/`ELSET=` on
/// *NODE/*ELEMENT, *NSET/*ELSET lists, GENERATE, set members that are sets,
/// `*NSET, ELSET=`, and skips other keywords with their data lines.
#[test]
fn inp_reads_sets_generate_comments_continuation_sparse_ids() {
    let m = parse_inp(INP, "two.inp").unwrap();
    assert_eq!(m.node_labels, vec![10, 20, 30, 40, 50, 60]);
    assert_eq!(m.element_labels, vec![100, 200, 300, 400]);
    assert_eq!(m.nodes[4], Vector3::new(2.0, 0.0, 0.0));
    assert_eq!(m.nodes[5], Vector3::new(2.0, 1.0, 0.0));
    assert_eq!(m.triangles[1], [0, 2, 3]);
    assert_eq!(m.triangles[3], [1, 5, 2]);
    assert!(m.fibres.is_empty());
    let sets: BTreeMap<&str, Vec<usize>> = m
        .node_sets
        .iter()
        .map(|(k, v)| (k.as_str(), v.clone()))
        .collect();
    assert_eq!(sets["corners"], vec![0, 1, 2, 3]);
    assert_eq!(sets["bottom"], vec![0, 1, 4]);
    assert_eq!(sets["right"], vec![4, 5]);
    assert_eq!(sets["edges"], vec![0, 1, 3, 4, 5]);
    assert_eq!(sets["fabric_nodes"], vec![0, 1, 2, 3]);
    assert_eq!(m.element_set("Fabric").unwrap(), &[0, 1]);
    assert_eq!(m.element_set("upper").unwrap(), &[2, 3]);
    assert_eq!(m.element_set("both").unwrap(), &[0, 1, 2, 3]);
    // Case-insensitive lookup when unambiguous.
    assert_eq!(m.node_set("BOTTOM").unwrap(), &[0, 1, 4]);
    assert_eq!(m.source, "two.inp");
    let total: f64 = (0..4).map(|e| m.triangle_area(e)).sum();
    assert!((total - 2.0).abs() < 1e-14);
}

/// Requirement: *PART/*ASSEMBLY/*INSTANCE are read flat (the instance
/// transform is ignored, as documented), keyword lines continue after a
/// trailing comma, and the data of skipped keywords is never parsed.
#[test]
fn inp_reads_parts_and_assemblies_flat() {
    let text = "*Heading
** Job name: strip Model name: Model-1
*Part, name=Fabric
*Node
      1,           0.,           0.
      2,         100.,           0.
      3,         100.,         300.
      4,           0.,         300.
*Element, type=M3D3,
   elset=fabric
1, 1, 2, 3
2, 1, 3, 4
*Nset, nset=bottom, generate
 1,  2,  1
*End Part
*Assembly, name=Assembly
*Instance, name=Fabric-1, part=Fabric
 10., 0., 0.
*End Instance
*Nset, nset=top, instance=Fabric-1
 3, 4
*End Assembly
*Amplitude, name=ramp
 0., 0.,, 1.
*Step, name=pull
*Static
0.01, 1., 1e-05, 0.1
*Node Output
U, RF
*End Step
";
    let m = parse_inp(text, "strip.inp").unwrap();
    assert_eq!(m.nodes.len(), 4);
    assert_eq!(
        m.nodes[2],
        Vector3::new(100.0, 300.0, 0.0),
        "no instance shift"
    );
    assert_eq!(m.element_set("fabric").unwrap(), &[0, 1]);
    assert_eq!(m.node_set("bottom").unwrap(), &[0, 1]);
    assert_eq!(m.node_set("top").unwrap(), &[2, 3]);
}

const MSH: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$Comments
anything at all
$EndComments
$PhysicalNames
2
1 5 \"clamp\"
2 7 \"fabric\"
$EndPhysicalNames
$Entities
1 1 1 0
1 0 0 0 1 9
1 0 0 0 2 0 0 1 5 2 1 -2
1 0 0 0 2 1 0 2 7 8 4 1 2 3 4
$EndEntities
$Nodes
3 6 2 60
0 1 0 1
2
0 0 0
1 1 1 2
10
20
1 0 0 0.5
2 0 0 1.0
2 1 0 3
30
40
60
2 1 0
1 1 0
0 1 0
$EndNodes
$Elements
3 7 1 104
0 1 15 1
1 2
1 1 1 2
5 2 10
6 10 20
2 1 2 4
101 2 10 40
102 2 40 60
103 10 20 30
104 10 30 40
$EndElements
";

/// Requirement: the .msh 4.1 reader maps physical groups to sets by name
/// (`physical_<tag>` without one): dimension 2 → element and node set,
/// dimensions 0 and 1 → node sets; sparse node tags, parametric node blocks,
/// point and line elements, and unknown sections are handled.
#[test]
fn msh_reads_physical_groups_sparse_tags() {
    let m = parse_msh(MSH, "two.msh").unwrap();
    assert_eq!(m.node_labels, vec![2, 10, 20, 30, 40, 60]);
    assert_eq!(m.element_labels, vec![101, 102, 103, 104]);
    assert_eq!(m.nodes[2], Vector3::new(2.0, 0.0, 0.0));
    assert_eq!(m.triangles[2], [1, 2, 3]);
    assert_eq!(m.node_set("physical_9").unwrap(), &[0]);
    assert_eq!(m.node_set("clamp").unwrap(), &[0, 1, 2]);
    assert_eq!(m.node_set("fabric").unwrap(), &[0, 1, 2, 3, 4, 5]);
    assert_eq!(m.node_set("physical_8").unwrap(), &[0, 1, 2, 3, 4, 5]);
    assert_eq!(m.element_set("fabric").unwrap(), &[0, 1, 2, 3]);
    assert_eq!(m.element_set("physical_8").unwrap(), &[0, 1, 2, 3]);
    assert!(
        m.element_set("clamp").is_err(),
        "curves give no element set"
    );
    assert!(m.fibres.is_empty());
    for e in 0..4 {
        assert_eq!(m.triangle_normal(e), Vector3::z());
    }
}

fn cases_dir() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/cases/meshes"))
}

/// Requirement: the sample strip `cases/meshes/square.{inp,msh}` read both
/// ways gives the same geometry (node coordinates, triangles as coordinate
/// triples, areas, `bottom` and `top` sets) and every triangle has an edge
/// along the +45° rovings.
#[test]
fn sample_square_same_both_ways() {
    let a = read_inp(&cases_dir().join("square.inp")).unwrap();
    let b = read_msh(&cases_dir().join("square.msh")).unwrap();
    assert!(a.source.ends_with("square.inp") && b.source.ends_with("square.msh"));
    assert_eq!(a.nodes.len(), 65);
    assert_eq!(a.triangles.len(), 96);
    assert_eq!(b.nodes.len(), a.nodes.len());
    assert_eq!(b.triangles.len(), a.triangles.len());
    let key = |x: &Vector3<f64>| [x.x, x.y, x.z].map(|c| (c * 1e9).round() as i64);
    let coords = |m: &Mesh, set: &[usize]| {
        let mut v: Vec<_> = set.iter().map(|&n| key(&m.nodes[n])).collect();
        v.sort_unstable();
        v
    };
    let all_a: Vec<usize> = (0..a.nodes.len()).collect();
    assert_eq!(coords(&a, &all_a), coords(&b, &all_a));
    for set in ["bottom", "top", "all"] {
        assert_eq!(
            coords(&a, a.node_set(set).unwrap()),
            coords(&b, b.node_set(set).unwrap()),
            "{set}"
        );
    }
    assert_eq!(a.node_set("bottom").unwrap().len(), 5);
    let tris = |m: &Mesh| {
        let mut v: Vec<_> = m
            .triangles
            .iter()
            .map(|t| t.map(|n| key(&m.nodes[n])))
            .collect();
        v.sort_unstable();
        v
    };
    assert_eq!(tris(&a), tris(&b));
    assert_eq!(a.element_set("all").unwrap().len(), 96);
    assert_eq!(b.element_set("all").unwrap().len(), 96);
    let area = |m: &Mesh| {
        (0..m.triangles.len())
            .map(|e| m.triangle_area(e))
            .sum::<f64>()
    };
    assert!((area(&a) - 30000.0).abs() < 1e-9 && (area(&b) - 30000.0).abs() < 1e-9);
    let a0 = roving_direction(45.0);
    for m in [&a, &b] {
        for e in 0..m.triangles.len() {
            assert!(nearest_edge_angle(m, e, &a0) < 1e-9);
            assert!(m.triangle_normal(e).z > 0.0);
        }
    }
}

/// Requirement: every .inp error path gives a message with the file name,
/// the line number and the offending token.
#[test]
fn inp_errors_name_file_line_and_token() {
    let head = "*NODE\n1, 0., 0.\n2, 1., 0.\n3, 0., 1.\n";
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            format!("{head}*ELEMENT, TYPE=S4R\n1, 1, 2, 3, 3\n"),
            vec![
                "non-triangle element type S4R at bad.inp:5",
                "3-node triangles",
            ],
        ),
        (
            format!("{head}*ELEMENT, type=m3d4\n"),
            vec!["m3d4 at bad.inp:5"],
        ),
        (
            format!("{head}*ELEMENT, TYPE=M3D3\n7, 1, 2, 99\n"),
            vec!["bad.inp:6", "element 7", "node 99", "not defined"],
        ),
        (
            format!("{head}2, 5., 5.\n*ELEMENT, TYPE=M3D3\n7, 1, 2, 3\n"),
            vec!["bad.inp:5", "node 2", "defined twice", "line 3"],
        ),
        (
            format!("{head}*ELEMENT, TYPE=M3D3\n7, 1, 2, 3\n7, 2, 3, 1\n"),
            vec!["bad.inp:7", "element 7", "defined twice", "line 6"],
        ),
        (
            "*NODE\n1, 0.0, 1.0x\n".to_string(),
            vec!["bad.inp:2", "`1.0x`", "coordinate"],
        ),
        (
            "*NODE\n1x, 0.0, 1.0\n".to_string(),
            vec!["bad.inp:2", "`1x`", "node id"],
        ),
        (
            format!("{head}*ELEMENT, TYPE=M3D3\n5, 1, 2,\n 3, 4\n"),
            vec!["bad.inp:7", "element 5", "4 nodes", "expected 3"],
        ),
        (
            format!("{head}*ELEMENT, TYPE=M3D3\n5, 1, 2\n"),
            vec!["bad.inp:6", "element 5", "2 nodes"],
        ),
        (
            format!("{head}*ELEMENT, TYPE=M3D3\n5, 1, 2, 3\n*NSET, NSET=s\n1, 77\n"),
            vec!["bad.inp:8", "set `s`", "node `77`"],
        ),
        (
            format!("{head}*ELEMENT, TYPE=M3D3\n5, 1, 2, 3\n*ELSET, ELSET=e, GENERATE\n5, 9, 2\n"),
            vec!["bad.inp:8", "set `e`", "element `7`"],
        ),
        (
            format!("{head}*ELEMENT, TYPE=M3D3\n5, 1, 2, 3\n*NSET, NSET=s\nghost\n"),
            vec!["bad.inp:8", "node `ghost`"],
        ),
        (
            format!("{head}*ELEMENT, TYPE=M3D3\n5, 1, 2, 3\n*NSET, NSET=s, GENERATE\n1, 2, 3, 4\n"),
            vec!["bad.inp:8", "`1, 2, 3, 4`", "GENERATE"],
        ),
        (
            head.to_string(),
            vec!["bad.inp", "no 3-node triangles", "*ELEMENT"],
        ),
        (
            format!("{head}*INCLUDE, INPUT=mesh.inp\n"),
            vec!["bad.inp:5", "*INCLUDE", "not supported"],
        ),
        (
            format!("{head}*ELEMENT, ELSET=x\n1, 1, 2, 3\n"),
            vec!["bad.inp:5", "TYPE="],
        ),
        (
            format!("{head}*ELEMENT, TYPE=M3D3\n5, 1, 1, 3\n"),
            vec!["bad.inp:6", "element 5", "three distinct"],
        ),
        (
            format!("{head}*NSET, NSET=s\n1,,2\n"),
            vec!["bad.inp:6", "`1,,2`", "empty"],
        ),
    ];
    for (text, parts) in cases {
        let msg = message(parse_inp(&text, "bad.inp"));
        assert_mentions(&msg, &parts);
    }
    let msg = message(read_inp(Path::new("/nonexistent/dir/missing.inp")));
    assert_mentions(&msg, &["missing.inp", "cannot read"]);
}

/// Requirement: every .msh error path gives a message with the file name,
/// the line number and the offending token.
#[test]
fn msh_errors_name_file_line_and_token() {
    let replace = |from: &str, to: &str| {
        assert!(MSH.contains(from), "{from}");
        MSH.replacen(from, to, 1)
    };
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            replace("4.1 0 8", "4.1 1 8"),
            vec!["bad.msh:2", "binary", "save as ASCII 4.1"],
        ),
        (
            replace("4.1 0 8", "2.2 0 8"),
            vec!["bad.msh:2", "version 2.2", "save as ASCII 4.1"],
        ),
        (
            replace("2 1 2 4\n", "2 1 3 4\n"),
            vec!["non-triangle element type 3", "Gmsh type 3", "bad.msh:43"],
        ),
        (
            replace("2 1 2 4\n", "2 1 9 4\n"),
            vec!["Gmsh type 9", "6-node triangle", "bad.msh:43"],
        ),
        (
            replace("104 10 30 40", "104 10 30 41"),
            vec!["bad.msh:47", "element 104", "node 41", "not defined"],
        ),
        (
            replace("30\n40\n60", "30\n40\n2"),
            vec!["bad.msh:31", "node 2", "defined twice", "line 21"],
        ),
        (
            replace("104 10 30 40", "101 10 30 40"),
            vec!["bad.msh:47", "element 101", "defined twice", "line 44"],
        ),
        (
            replace("\n1 1 0\n0 1 0", "\n1 1x 0\n0 1 0"),
            vec!["bad.msh:33", "`1x`", "coordinate"],
        ),
        (
            replace("103 10 20 30", "103 10 20 30 40"),
            vec!["bad.msh:46", "element 103", "4 nodes", "expected 3"],
        ),
        (
            replace("2 0 0 1.0", "2 0 0"),
            vec!["bad.msh:27", "`2 0 0`", "parametric"],
        ),
        (
            replace("3 6 2 60", "3 7 2 60"),
            vec!["bad.msh:19", "7 nodes in the header"],
        ),
        (
            replace("3 7 1 104\n", "2 3 1 104\n"),
            vec!["bad.msh", "$EndElements", "2 1 2 4"],
        ),
        (
            MSH.split("$Elements").next().unwrap().to_string(),
            vec!["bad.msh", "no 3-node triangles", "Physical Surface"],
        ),
        (
            "$Nodes\n".to_string(),
            vec!["bad.msh:1", "$MeshFormat first"],
        ),
    ];
    for (text, parts) in cases {
        let msg = message(parse_msh(&text, "bad.msh"));
        assert_mentions(&msg, &parts);
    }
    // A binary file is recognised from its ASCII header.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("binary.msh");
    let mut bytes = b"$MeshFormat\n4.1 1 8\n".to_vec();
    bytes.extend_from_slice(&[1, 0, 0, 0, 0xff, 0xfe, b'\n']);
    bytes.extend_from_slice(b"$EndMeshFormat\n");
    std::fs::write(&path, bytes).unwrap();
    let msg = message(read_msh(&path));
    assert_mentions(&msg, &["binary.msh:2", "save as ASCII 4.1"]);
}

// -------------------------------------------------------- fibres and checks

/// One triangle in the plane through the y axis tilted 30° about it, with
/// external label 7.
fn tilted_triangle() -> Mesh {
    let (s, c) = 30f64.to_radians().sin_cos();
    Mesh {
        nodes: vec![
            Vector3::zeros(),
            Vector3::new(c, 0.0, s),
            Vector3::new(0.0, 1.0, 0.0),
        ],
        triangles: vec![[0, 1, 2]],
        node_labels: vec![1, 2, 3],
        element_labels: vec![7],
        source: "tilted".to_string(),
        ..Mesh::default()
    }
}

/// Requirement: `set_fibres_from_global` projects the direction onto each
/// triangle's plane and normalises it: (1, 0, 0) on the plane tilted 30°
/// about y gives (cos 30°, 0, sin 30°); the result passes `check`.
#[test]
fn set_fibres_from_global_on_tilted_plane() {
    let mut m = tilted_triangle();
    m.set_fibres_from_global(Vector3::new(2.0, 0.0, 0.0))
        .unwrap();
    let (s, c) = 30f64.to_radians().sin_cos();
    assert!((m.fibres[0] - Vector3::new(c, 0.0, s)).norm() < 1e-15);
    m.check().unwrap();
    // A direction with a normal component gives the same in-plane fibre.
    let n = m.triangle_normal(0);
    m.set_fibres_from_global(Vector3::new(c, 0.0, s) * 3.0 + n * 5.0)
        .unwrap();
    assert!((m.fibres[0] - Vector3::new(c, 0.0, s)).norm() < 1e-14);
}

/// Requirement: a global direction along the normal (projection shorter than
/// 1e-6) is an error naming the element label; the mesh is left unchanged.
#[test]
fn set_fibres_from_global_normal_direction_is_an_error() {
    let mut m = tilted_triangle();
    let n = m.triangle_normal(0);
    let msg = message(m.set_fibres_from_global(n * 4.0));
    assert_mentions(&msg, &["tilted", "element 7", "normal", "1e-6"]);
    assert!(m.fibres.is_empty());
    let msg = message(m.set_fibres_from_global(Vector3::zeros()));
    assert_mentions(&msg, &["tilted", "non-zero"]);
}

/// Requirement: `check` catches a degenerate triangle (area <= 1e-10 ×
/// longest edge²) and names its label and area; it also catches repeated
/// nodes, out-of-range indices and bad fibres, each naming the element.
#[test]
fn check_catches_degenerate_and_names_label() {
    let mut m = tilted_triangle();
    m.nodes[2] = Vector3::new(2.0 * m.nodes[1].x, 1e-12, 2.0 * m.nodes[1].z);
    m.element_labels = vec![42];
    let err = m.check().unwrap_err();
    assert!(matches!(err, MeshError::Degenerate { element: 42, .. }));
    assert_mentions(
        &err.to_string(),
        &["tilted", "element 42", "degenerate", "area"],
    );

    let mut m = tilted_triangle();
    m.triangles[0] = [0, 1, 1];
    assert_mentions(&message(m.check()), &["element 7", "node 2 twice"]);

    let mut m = tilted_triangle();
    m.triangles[0] = [0, 1, 5];
    assert_mentions(&message(m.check()), &["element 7", "node index 5"]);

    let mut m = tilted_triangle();
    m.fibres = vec![Vector3::new(1.0, 0.0, 0.0)];
    assert_mentions(
        &message(m.check()),
        &["element 7", "leaves the element plane"],
    );

    let mut m = tilted_triangle();
    m.fibres = vec![Vector3::new(0.0, 2.0, 0.0)];
    assert_mentions(&message(m.check()), &["element 7", "unit vector"]);
}

/// Requirement: asking for a set the mesh lacks names the source and lists
/// the available sets.
#[test]
fn unknown_set_lists_available_names() {
    let g = generate(
        45.0,
        GridResolution::Counts { nx: 2, ny: 6 },
        GridPattern::RovingDiagonal,
    );
    let msg = message(g.mesh.node_set("clamp"));
    assert_mentions(
        &msg,
        &["generated OAT", "clamp", "all, bottom, left, right, top"],
    );
    let msg = message(g.mesh.element_set("fabric"));
    assert_mentions(
        &msg,
        &["element set", "fabric", "available element sets: all"],
    );
}

/// Requirement: the mirrored pattern at 0° and 90° gives a mesh that is
/// mirror-symmetric about both centre lines (every triangle's mirror image
/// is a triangle of the mesh, exactly: the node positions are mirrored
/// sums of the same grid values) with every triangle's edges along the
/// rovings and the stitching (cell sides), and is refused at other angles.
#[test]
fn mirrored_pattern_is_symmetric_about_both_centre_lines() {
    for theta in [0.0, 90.0] {
        let g = generate(
            theta,
            GridResolution::Counts { nx: 6, ny: 4 },
            GridPattern::Mirrored,
        );
        let m = &g.mesh;
        m.check().expect("generated mesh passes check");
        assert_eq!(m.triangles.len(), 48);
        assert!(g.edge_deviation_deg < 1e-9);
        let key = |x: f64, y: f64| ((x * 1e6).round() as i64, (y * 1e6).round() as i64);
        let triangle_set: std::collections::BTreeSet<Vec<(i64, i64)>> = m
            .triangles
            .iter()
            .map(|t| {
                let mut v: Vec<_> = t.iter().map(|&n| key(m.nodes[n].x, m.nodes[n].y)).collect();
                v.sort_unstable();
                v
            })
            .collect();
        for mirror in [
            |x: f64, y: f64| (100.0 - x, y),
            |x: f64, y: f64| (x, 300.0 - y),
        ] {
            for t in &m.triangles {
                let mut v: Vec<_> = t
                    .iter()
                    .map(|&n| {
                        let (x, y) = mirror(m.nodes[n].x, m.nodes[n].y);
                        key(x, y)
                    })
                    .collect();
                v.sort_unstable();
                assert!(
                    triangle_set.contains(&v),
                    "mirror of {t:?} missing at {theta}°"
                );
            }
        }
    }
    let refused = ncform::mesh::generate::oat_specimen(&ncform::mesh::generate::OatSpecimen {
        width: 100.0,
        length: 300.0,
        bias_angle_deg: 45.0,
        resolution: GridResolution::Counts { nx: 6, ny: 4 },
        pattern: GridPattern::Mirrored,
    });
    assert!(refused.is_err());
}
