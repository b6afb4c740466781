//! The structural mesh reader ([`ncform::mesh::structural`]) and the
//! mapping of a formed ply onto a structural mesh ([`ncform::handoff::map`]):
//! labels and types kept, every error naming its line and value, an
//! analytic curved ply mapped within 3°, a region beyond the ply left
//! unmapped, and alternating shear bands averaged rather than aliased.

use std::fmt::Write as _;

use ncform::handoff::map::{FormedSurface, MapError, MapOptions, UnmappedReason, map_onto};
use ncform::handoff::{ShellElement, ShellMesh};
use ncform::mesh::structural::{
    STRUCTURAL_TYPES, StructuralMeshError, parse_structural_inp, read_structural_inp,
};

// ---------------------------------------------------------------- reader

const MIXED: &str = "** a structural mesh exported by hand\n\
*Heading\n\
 test part\n\
*Part, name=SKIN\n\
*Node\n\
      10,   0.0,   0.0,   0.0\n\
      20,  10.0,   0.0,   0.0\n\
\n\
      30,  10.0,  10.0,   1.5D-1\n\
      40,   0.0,  10.0\n\
      97,  20.0,   5.0,  -2.5e0\n\
*Element, type=S4R, elset=QUADS\n\
 1001, 10, 20,\n\
       30, 40\n\
** the rim\n\
*ELEMENT, TYPE=s3\n\
 1007, 20, 97, 30\n\
*Elset, elset=ALL\n\
 1001, 1007\n\
*End Part\n\
*Assembly, name=Assembly\n\
*Instance, name=SKIN-1, part=SKIN\n\
*End Instance\n\
*End Assembly\n\
*Step\n\
*Static\n\
1., 1.\n\
*End Step\n";

#[test]
fn mixed_mesh_keeps_labels_types_and_coordinates() {
    let m = parse_structural_inp(MIXED, "mixed.inp").unwrap();
    assert_eq!(m.source, "mixed.inp");
    assert_eq!(m.node_labels, vec![10, 20, 30, 40, 97]);
    assert_eq!(m.nodes[2], [10.0, 10.0, 0.15]);
    assert_eq!(m.nodes[3], [0.0, 10.0, 0.0], "a 2-D node line has z = 0");
    assert_eq!(m.nodes[4], [20.0, 5.0, -2.5]);
    assert_eq!(
        m.elements,
        vec![
            ShellElement {
                label: 1001,
                nodes: vec![0, 1, 2, 3],
                abaqus_type: "S4R".into()
            },
            ShellElement {
                label: 1007,
                nodes: vec![1, 4, 2],
                abaqus_type: "S3".into()
            },
        ]
    );
    // The same through a file.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mixed.inp");
    std::fs::write(&path, MIXED).unwrap();
    let from_file = read_structural_inp(&path).unwrap();
    assert_eq!(from_file.elements, m.elements);
    assert!(from_file.source.ends_with("mixed.inp"));
    let missing = read_structural_inp(&dir.path().join("nope.inp")).unwrap_err();
    assert!(missing.to_string().contains("nope.inp"), "{missing}");
}

#[test]
fn every_supported_type_is_read() {
    for (ty, count) in STRUCTURAL_TYPES {
        let nodes: Vec<String> = (1..=*count).map(|n| n.to_string()).collect();
        let text = format!(
            "*NODE\n1,0,0\n2,1,0\n3,1,1\n4,0,1\n*ELEMENT, TYPE={ty}\n5, {}\n",
            nodes.join(", ")
        );
        let m = parse_structural_inp(&text, "t.inp").unwrap();
        assert_eq!(m.elements[0].abaqus_type, *ty);
        assert_eq!(m.elements[0].nodes.len(), *count);
    }
}

fn error(text: &str) -> String {
    let e: StructuralMeshError = parse_structural_inp(text, "bad.inp").unwrap_err();
    e.to_string()
}

fn assert_mentions(message: &str, parts: &[&str]) {
    for p in parts {
        assert!(message.contains(p), "`{message}` should mention `{p}`");
    }
}

const NODES: &str = "*NODE\n1, 0, 0, 0\n2, 1, 0, 0\n3, 1, 1, 0\n4, 0, 1, 0\n";

#[test]
fn each_error_names_the_line_and_the_value() {
    let m = error(&format!("{NODES}*ELEMENT, TYPE=C3D8R\n1, 1, 2, 3, 4\n"));
    assert_mentions(&m, &["bad.inp:6", "`C3D8R`", "S3", "S4R", "M3D4R"]);

    let m = error(NODES);
    assert_mentions(&m, &["bad.inp", "no shell elements", "S4R"]);

    let m = error(&format!(
        "{NODES}3, 5, 5, 5\n*ELEMENT, TYPE=S3\n1, 1, 2, 3\n"
    ));
    assert_mentions(&m, &["bad.inp:6", "node label 3", "twice", "line 4"]);

    let m = error(&format!(
        "{NODES}*ELEMENT, TYPE=S3\n8, 1, 2, 3\n*ELEMENT, TYPE=S4\n8, 1, 2, 3, 4\n"
    ));
    assert_mentions(&m, &["bad.inp:9", "element label 8", "line 7"]);

    let m = error(&format!("{NODES}*ELEMENT, TYPE=S4R\n8, 1, 2, 33, 4\n"));
    assert_mentions(&m, &["bad.inp:7", "element 8", "node 33", "not defined"]);

    let m = error(&format!("{NODES}*ELEMENT, TYPE=S4R\n8, 1, 2, 2, 4\n"));
    assert_mentions(
        &m,
        &["bad.inp:7", "element 8", "node 2 twice", "4 distinct"],
    );

    for bad in ["nan", "inf", "1e999", "1.0.0", "abc"] {
        let m = error(&format!(
            "*NODE\n1, 0, 0, 0\n2, 1, {bad}, 0\n3, 0, 1\n*ELEMENT, TYPE=S3\n1, 1, 2, 3\n"
        ));
        assert_mentions(&m, &["bad.inp:3", &format!("`{bad}`"), "finite coordinate"]);
    }
    let m = error("*NODE\n-4, 0, 0, 0\n");
    assert_mentions(&m, &["bad.inp:2", "`-4`", "positive integer node label"]);

    let m = error(&format!("{NODES}*ELEMENT, TYPE=S4R\n8, 1, 2, 3\n"));
    assert_mentions(
        &m,
        &["bad.inp:7", "element 8", "S4R", "3 nodes", "expected 4"],
    );
    let m = error(&format!("{NODES}*ELEMENT, TYPE=M3D3\n8, 1, 2, 3, 4\n"));
    assert_mentions(
        &m,
        &["bad.inp:7", "element 8", "M3D3", "4 nodes", "expected 3"],
    );

    let m = error(&format!("{NODES}*INCLUDE, INPUT=more.inp\n"));
    assert_mentions(&m, &["bad.inp:6", "*INCLUDE", "not supported"]);
}

#[test]
fn no_panic_on_mutated_input() {
    // A small deterministic mutation loop (xorshift): every mutant is read
    // or refused, never a panic.
    let base = MIXED.as_bytes();
    let alphabet = b",*\n 0123456789.-eEDSRn";
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    for _ in 0..3000 {
        let mut bytes = base.to_vec();
        for _ in 0..1 + next() % 4 {
            let at = (next() % bytes.len() as u64) as usize;
            match next() % 3 {
                0 => bytes[at] = alphabet[(next() % alphabet.len() as u64) as usize],
                1 => {
                    bytes.remove(at);
                }
                _ => bytes.insert(at, alphabet[(next() % alphabet.len() as u64) as usize]),
            }
        }
        let text = String::from_utf8_lossy(&bytes).into_owned();
        let r = std::panic::catch_unwind(|| parse_structural_inp(&text, "m.inp"));
        match r {
            Ok(Ok(m)) => assert!(m.nodes.iter().flatten().all(|c| c.is_finite())),
            Ok(Err(e)) => assert!(e.to_string().contains("m.inp"), "{e}"),
            Err(_) => panic!("the reader panicked on:\n{text}"),
        }
    }
}

// ---------------------------------------------------------------- mapping

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|c| c / l)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `d` projected onto the plane of normal `n`, normalised.
fn tangent(d: [f64; 3], n: [f64; 3]) -> [f64; 3] {
    let dn = dot(d, n);
    normalize([d[0] - dn * n[0], d[1] - dn * n[1], d[2] - dn * n[2]])
}

/// Angle between two fibres (sign-blind) \[deg\].
fn fibre_angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    dot(normalize(a), normalize(b))
        .abs()
        .min(1.0)
        .acos()
        .to_degrees()
}

/// A structured triangulation of the grid `x0 + i h`, `y0 + j h`
/// (`cells × cells`) lifted by `z(x, y)`.
fn grid_ply(
    x0: f64,
    y0: f64,
    h: f64,
    cells: usize,
    z: impl Fn(f64, f64) -> f64,
) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let mut nodes = Vec::new();
    for j in 0..=cells {
        for i in 0..=cells {
            let (x, y) = (x0 + i as f64 * h, y0 + j as f64 * h);
            nodes.push([x, y, z(x, y)]);
        }
    }
    let id = |i: usize, j: usize| j * (cells + 1) + i;
    let mut tris = Vec::new();
    for j in 0..cells {
        for i in 0..cells {
            // Alternate the diagonal so the mesh has no preferred direction.
            if (i + j) % 2 == 0 {
                tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            } else {
                tris.push([id(i, j), id(i + 1, j), id(i, j + 1)]);
                tris.push([id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
    }
    (nodes, tris)
}

fn triangle_normal(nodes: &[[f64; 3]], t: [usize; 3]) -> [f64; 3] {
    let [a, b, c] = t.map(|k| nodes[k]);
    normalize(cross(
        [b[0] - a[0], b[1] - a[1], b[2] - a[2]],
        [c[0] - a[0], c[1] - a[1], c[2] - a[2]],
    ))
}

const R_PLY: f64 = 100.0;
/// The structural mesh lies 0.5 mm off the ply (a tool-side surface).
const R_TARGET: f64 = 100.5;

/// The exact fibre field on the sphere: the fixed direction projected on
/// the tangent plane at `q`.
fn exact_fibre(q: [f64; 3]) -> [f64; 3] {
    tangent(normalize([1.0, 0.3, 0.0]), normalize(q))
}

/// The structural mesh of the cap as an `.inp` text: a 16 × 16 grid of
/// 5 mm cells over [−40, 40]² (2.5× the ply's 2 mm), S4R quads inside and
/// S3 pairs on the outer ring, node labels 5001, 5004, … and element labels
/// from 1001; plus a flange of 8 S4R quads at 56 ≤ x ≤ 66, beyond the ply's
/// edge at x = 50. Returns the text and the flange's element labels.
fn cap_target_inp() -> (String, Vec<u64>) {
    let z = |x: f64, y: f64| (R_TARGET * R_TARGET - x * x - y * y).sqrt();
    let mut s =
        String::from("** cap, quads inside, triangles on the rim\n*PART, NAME=CAP\n*NODE\n");
    let n = 16;
    let node = |i: usize, j: usize| 5001 + 3 * (j * (n + 1) + i) as u64;
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (-40.0 + 5.0 * i as f64, -40.0 + 5.0 * j as f64);
            writeln!(s, "{}, {x}, {y}, {:.12}", node(i, j), z(x, y)).unwrap();
        }
    }
    let flange_node = |i: usize, j: usize| 90001 + (j * 3 + i) as u64;
    for j in 0..5 {
        for i in 0..3 {
            let (x, y) = (56.0 + 5.0 * i as f64, -10.0 + 5.0 * j as f64);
            writeln!(s, "{}, {x}, {y}, {:.12}", flange_node(i, j), z(x, y)).unwrap();
        }
    }
    let mut label = 1001u64;
    let mut quads = String::from("*ELEMENT, TYPE=S4R, ELSET=INNER\n");
    let mut tris = String::from("*ELEMENT, TYPE=S3, ELSET=RIM\n");
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (
                node(i, j),
                node(i + 1, j),
                node(i + 1, j + 1),
                node(i, j + 1),
            );
            if i == 0 || j == 0 || i == n - 1 || j == n - 1 {
                writeln!(tris, "{label}, {a}, {b}, {c}").unwrap();
                writeln!(tris, "{}, {a}, {c}, {d}", label + 1).unwrap();
                label += 2;
            } else {
                // Continuation lines.
                writeln!(quads, "{label}, {a}, {b},\n   {c}, {d}").unwrap();
                label += 1;
            }
        }
    }
    s.push_str(&quads);
    s.push_str(&tris);
    s.push_str("*ELEMENT, TYPE=S4R, ELSET=FLANGE\n");
    let mut flange = Vec::new();
    for j in 0..4 {
        for i in 0..2 {
            let (a, b, c, d) = (
                flange_node(i, j),
                flange_node(i + 1, j),
                flange_node(i + 1, j + 1),
                flange_node(i, j + 1),
            );
            writeln!(s, "{label}, {a}, {b}, {c}, {d}").unwrap();
            flange.push(label);
            label += 1;
        }
    }
    s.push_str("*END PART\n");
    (s, flange)
}

#[test]
fn spherical_cap_maps_within_three_degrees_and_the_flange_stays_unmapped() {
    // The ply: a 50 × 50 grid of 2 mm cells over [−50, 50]² on a sphere of
    // radius 100 mm (5000 triangles), fibre = a fixed direction projected
    // on each triangle.
    let (nodes, tris) = grid_ply(-50.0, -50.0, 2.0, 50, |x, y| {
        (R_PLY * R_PLY - x * x - y * y).sqrt()
    });
    assert_eq!(tris.len(), 5000);
    let d = normalize([1.0, 0.3, 0.0]);
    let fibre: Vec<[f64; 3]> = tris
        .iter()
        .map(|&t| tangent(d, triangle_normal(&nodes, t)))
        .collect();
    let ply = FormedSurface {
        nodes: &nodes,
        triangles: &tris,
        fibre: &fibre,
    };
    let (text, flange) = cap_target_inp();
    let target = parse_structural_inp(&text, "cap.inp").unwrap();
    let before = target.clone();
    assert!(target.elements.iter().any(|e| e.abaqus_type == "S4R"));
    assert!(target.elements.iter().any(|e| e.abaqus_type == "S3"));
    assert_eq!(target.elements.iter().map(|e| e.label).min(), Some(1001));

    let r = map_onto(&ply, &target, &MapOptions::default()).unwrap();
    assert_eq!(target, before, "the target is untouched");
    assert_eq!(r.fibre.len(), target.elements.len());

    let mut angles = Vec::new();
    for (e, el) in target.elements.iter().enumerate() {
        if flange.contains(&el.label) {
            assert_eq!(r.fibre[e], None, "flange element {}", el.label);
            assert_eq!(r.coverage[e], 0.0);
            assert!(r.distance[e] > 2.0, "{}", r.distance[e]);
            continue;
        }
        let a = r.fibre[e].unwrap_or_else(|| panic!("element {} unmapped", el.label));
        assert!((dot(a, a) - 1.0).abs() < 1e-12);
        let n = target.normal(e).unwrap();
        assert!(dot(a, n).abs() < 1e-9, "tangent to the element");
        assert!((r.coverage[e] - 1.0).abs() < 1e-12, "{}", r.coverage[e]);
        assert!(r.distance[e] < 0.6, "{}", r.distance[e]);
        angles.push(fibre_angle(a, exact_fibre(target.centroid(e))));
    }
    let within = angles.iter().filter(|&&a| a <= 3.0).count() as f64 / angles.len() as f64;
    let worst = angles.iter().copied().fold(0.0, f64::max);
    eprintln!(
        "cap: {} mapped elements (target 5 mm / ply 2 mm = 2.5x), {:.1} % within 3°, worst {worst:.3}°",
        angles.len(),
        100.0 * within
    );
    assert!(within >= 0.95, "{within}");
    // The unmapped list is exactly the flange, labels as they went in.
    let unmapped: Vec<u64> = r.unmapped.iter().map(|u| u.label).collect();
    assert_eq!(unmapped, flange);
    for u in &r.unmapped {
        assert_eq!(target.elements[u.element].label, u.label);
        assert!(matches!(u.reason, UnmappedReason::NotCovered { distance } if distance > 2.0));
    }
}

/// Nodes, triangles and fibres of a ply.
type Ply = (Vec<[f64; 3]>, Vec<[usize; 3]>, Vec<[f64; 3]>);

/// A flat ply on [−5, 25]² (0.625 mm cells, 4608 triangles) with shear
/// bands 1.25 mm wide across x alternating +30° and −30°; the −30° band's
/// vectors point the other way ((−cos 30°, sin 30°), the same fibre as
/// (cos 30°, −sin 30°)), so a plain vector average would point along y.
fn banded_ply() -> Ply {
    let (nodes, tris) = grid_ply(-5.0, -5.0, 0.625, 48, |_, _| 0.0);
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let fibre = tris
        .iter()
        .map(|t| {
            let x = (nodes[t[0]][0] + nodes[t[1]][0] + nodes[t[2]][0]) / 3.0;
            if ((x / 1.25).floor() as i64).rem_euclid(2) == 0 {
                [c, s, 0.0]
            } else {
                [-c, s, 0.0]
            }
        })
        .collect();
    (nodes, tris, fibre)
}

#[test]
fn shear_bands_narrower_than_an_element_average_to_their_bisector() {
    let (nodes, tris, fibre) = banded_ply();
    let ply = FormedSurface {
        nodes: &nodes,
        triangles: &tris,
        fibre: &fibre,
    };
    // 4 × 4 quads of 5 mm (four bands each), 0.5 mm above the ply and
    // shifted 0.3 mm in x, labels from 1001.
    let mut target = ShellMesh {
        source: "bands".into(),
        ..Default::default()
    };
    for j in 0..=4 {
        for i in 0..=4 {
            target.node_labels.push(7000 + (j * 5 + i) as u64);
            target
                .nodes
                .push([0.3 + 5.0 * i as f64, 5.0 * j as f64, 0.5]);
        }
    }
    for j in 0..4 {
        for i in 0..4 {
            let k = j * 5 + i;
            target.elements.push(ShellElement {
                label: 1001 + (j * 4 + i) as u64,
                nodes: vec![k, k + 1, k + 6, k + 5],
                abaqus_type: "S4R".into(),
            });
        }
    }
    let averaged = map_onto(&ply, &target, &MapOptions::default()).unwrap();
    let centre = map_onto(
        &ply,
        &target,
        &MapOptions {
            samples_per_edge: Some(1),
            ..Default::default()
        },
    )
    .unwrap();
    let plus = [30f64.to_radians().cos(), 30f64.to_radians().sin(), 0.0];
    let mut worst_avg: f64 = 0.0;
    for e in 0..target.elements.len() {
        let a = averaged.fibre[e].unwrap();
        let from_x = fibre_angle(a, [1.0, 0.0, 0.0]);
        worst_avg = worst_avg.max(from_x);
        assert!(from_x < 0.5, "element {e}: {from_x}° from the bisector");
        // Two fibres ±30° in equal parts: anisotropy cos 60° = 0.5.
        assert!(
            (averaged.anisotropy[e] - 0.5).abs() < 0.02,
            "{}",
            averaged.anisotropy[e]
        );
        assert!(averaged.samples_per_edge[e] >= 16);
        // The single centre sample lands in one band and aliases to it.
        let c = centre.fibre[e].unwrap();
        assert!(fibre_angle(c, plus) < 1e-6, "centre sample {c:?}");
        assert!((fibre_angle(a, c) - 30.0).abs() < 0.5);
        assert_eq!(centre.anisotropy[e], 1.0);
    }
    // 17 samples per edge do not divide the four bands evenly (9 rows of
    // one band parity, 8 of the other at worst): the quadrature error of
    // point sampling, a few degrees, still far from one band's 30°.
    let uneven = map_onto(
        &ply,
        &target,
        &MapOptions {
            samples_per_edge: Some(17),
            ..Default::default()
        },
    )
    .unwrap();
    let mut worst_uneven: f64 = 0.0;
    for e in 0..target.elements.len() {
        let from_x = fibre_angle(uneven.fibre[e].unwrap(), [1.0, 0.0, 0.0]);
        worst_uneven = worst_uneven.max(from_x);
        assert!(from_x < 5.0, "element {e}: {from_x}° from the bisector");
    }
    eprintln!(
        "bands: averaged direction within {worst_avg:.3}° of the bisector (16 samples per edge), \
         {worst_uneven:.3}° with 17; the centre sample gives the +30° band"
    );
}

#[test]
fn input_errors_are_reported() {
    let nodes = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let tris = [[0, 1, 2]];
    let fibre = [[1.0, 0.0, 0.0]];
    let target = parse_structural_inp(
        "*NODE\n1,0,0\n2,1,0\n3,0,1\n*ELEMENT,TYPE=S3\n9,1,2,3\n",
        "t.inp",
    )
    .unwrap();
    let opts = MapOptions::default();
    let ok = FormedSurface {
        nodes: &nodes,
        triangles: &tris,
        fibre: &fibre,
    };
    assert!(map_onto(&ok, &target, &opts).is_ok());
    let empty = FormedSurface {
        triangles: &[],
        fibre: &[],
        ..ok
    };
    assert_eq!(
        map_onto(&empty, &target, &opts),
        Err(MapError::EmptySurface)
    );
    let two = [[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
    let mismatch = FormedSurface { fibre: &two, ..ok };
    let e = map_onto(&mismatch, &target, &opts).unwrap_err().to_string();
    assert!(e.contains("2 fibre directions for 1 triangles"), "{e}");
    let bad_nodes = [[0.0, 0.0, 0.0], [f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let nan = FormedSurface {
        nodes: &bad_nodes,
        ..ok
    };
    let e = map_onto(&nan, &target, &opts).unwrap_err().to_string();
    assert!(e.contains("formed ply node 1") && e.contains("nan"), "{e}");
    let zero = [[0.0, 0.0, 0.0]];
    let e = map_onto(&FormedSurface { fibre: &zero, ..ok }, &target, &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("fibre") && e.contains("non-zero"), "{e}");
    let out = [[0, 1, 3]];
    let e = map_onto(
        &FormedSurface {
            triangles: &out,
            ..ok
        },
        &target,
        &opts,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("names node 3"), "{e}");
    let e = map_onto(
        &ok,
        &target,
        &MapOptions {
            tolerance: -1.0,
            ..opts
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("tolerance") && e.contains("-1"), "{e}");
    let mut broken = target.clone();
    broken.elements[0].nodes.push(0);
    broken.elements[0].nodes.push(1);
    let e = map_onto(&ok, &broken, &opts).unwrap_err().to_string();
    assert!(
        e.contains("t.inp: element 9") && e.contains("5 nodes"),
        "{e}"
    );
}
