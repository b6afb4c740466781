//! The formed part handed on (`docs/export.md`), end to end on a coarse
//! run of the shipped [45°] hemisphere: the exported directions are the
//! formed ones, `F·a₀`, computed here independently from the VTU's
//! reference and current coordinates; CalculiX runs the exported deck of
//! the formed ply and its answer depends on the orientations; `map` onto a
//! structural mesh made here (quads on the cup, triangles on the flange,
//! labels of its own, another density) gives the formed directions and
//! reports the elements off the ply; bad run folders give clear errors.
//!
//! Each test names where its tolerance comes from.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use ncform::case::forming::FormingCase;
use ncform::handoff::calculix::{CalculixOptions, write_calculix};
use ncform::handoff::export::{
    Format, HandoffOptions, formed_handoff, mapped_handoff, write_handoff,
};
use ncform::handoff::run::{FormedPly, read_formed_state};
use ncform::report::Progress;
use ncform::report::files::run_forming;

fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("cases")
}

/// The shipped case `name` on a `cells × cells` blank, run into `out`.
fn coarse_run(name: &str, cells: usize, out: &Path) {
    let text = fs::read_to_string(cases_dir().join(name))
        .unwrap()
        .replace("cells = [84, 84]", &format!("cells = [{cells}, {cells}]"));
    let case =
        FormingCase::from_toml_str(&text, name, &cases_dir()).unwrap_or_else(|e| panic!("{e}"));
    let summary = run_forming(&case, out, Progress::Quiet).unwrap_or_else(|e| panic!("{e}"));
    assert!(summary.complete, "{name}: {:?}", summary.status);
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
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
fn unit(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    a.map(|v| v / n)
}
/// The angle between two fibres (lines) \[deg\].
fn line_angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    (dot(unit(a), unit(b)).abs().min(1.0)).acos().to_degrees()
}

/// `F a₀ / |F a₀|` of triangle `t` of `ply`: `a₀ = α dX₁ + β dX₂` on the
/// reference edges, `F a₀ = α dx₁ + β dx₂` on the current ones.
fn pushed_forward(ply: &FormedPly, t: usize, a0: [f64; 3]) -> [f64; 3] {
    let [i, j, k] = ply.triangles[t];
    let (d1, d2) = (
        sub(ply.reference[j], ply.reference[i]),
        sub(ply.reference[k], ply.reference[i]),
    );
    let (x1, x2) = (
        sub(ply.nodes[j], ply.nodes[i]),
        sub(ply.nodes[k], ply.nodes[i]),
    );
    // Solve the 2×2 normal equations for (α, β).
    let (g11, g12, g22) = (dot(d1, d1), dot(d1, d2), dot(d2, d2));
    let (r1, r2) = (dot(a0, d1), dot(a0, d2));
    let det = g11 * g22 - g12 * g12;
    let alpha = (r1 * g22 - r2 * g12) / det;
    let beta = (g11 * r2 - g12 * r1) / det;
    unit([
        alpha * x1[0] + beta * x2[0],
        alpha * x1[1] + beta * x2[1],
        alpha * x1[2] + beta * x2[2],
    ])
}

/// The Abaqus deck's distribution lines of `ply`: label → (a, b).
fn distribution(deck: &str, ply: &str) -> Vec<(u64, [f64; 3], [f64; 3])> {
    let head = format!("*DISTRIBUTION, NAME={ply}_DIST");
    let mut lines = deck.lines().skip_while(|l| !l.starts_with(&head)).skip(1);
    let _default = lines.next();
    lines
        .take_while(|l| !l.starts_with('*'))
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|v| v.trim().parse().unwrap()).collect();
            (f[0] as u64, [f[1], f[2], f[3]], [f[4], f[5], f[6]])
        })
        .collect()
}

/// The exported directions are the formed ones and tangent to their
/// elements. `F a₀` is recomputed from the VTU's coordinates (reference =
/// current − displacement) and the case's design angle, not from the
/// run's own fields. Tolerance: the deck writes ten significant digits and
/// the VTU full precision, so 1e-6 in the direction's components covers
/// the rounding of both (a wrong frame or a transposed `F` is off by
/// O(1)).
#[test]
fn exported_directions_are_the_formed_ones() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    coarse_run("hemisphere-45.toml", 16, &run);
    let state = read_formed_state(&run, &[0], None, false).unwrap();
    let ply = &state.plies[0];
    assert_eq!(ply.design_angle_deg, 45.0);
    let t = ply.design_angle_deg.to_radians();
    let a0 = [t.cos(), t.sin(), 0.0];
    let (handoff, _) = formed_handoff(&run, &HandoffOptions::default()).unwrap();
    let mut deck = Vec::new();
    write_handoff(
        &handoff,
        Format::Abaqus,
        ncform::handoff::abaqus::AbaqusElement::Shell,
        &mut deck,
    )
    .unwrap();
    let deck = String::from_utf8(deck).unwrap();
    let lines = distribution(&deck, "PLY");
    assert_eq!(lines.len(), ply.triangles.len(), "one line per element");
    let mut worst: f64 = 0.0;
    let mut turned: f64 = 0.0;
    for (label, a, b) in lines {
        let e = ply.labels.iter().position(|&l| l == label).unwrap();
        let expected = pushed_forward(ply, e, a0);
        let [i, j, k] = ply.triangles[e];
        let n = unit(cross(
            sub(ply.nodes[j], ply.nodes[i]),
            sub(ply.nodes[k], ply.nodes[i]),
        ));
        // The sign of a fibre is free: compare as lines.
        let s = dot(a, expected).signum();
        worst = worst.max(
            (0..3)
                .map(|c| (s * a[c] - expected[c]).abs())
                .fold(0.0, f64::max),
        );
        assert!(dot(a, n).abs() < 1e-6, "{label}: a not tangent");
        assert!(
            dot(b, n).abs() < 1e-6 && dot(a, b).abs() < 1e-6,
            "{label}: b"
        );
        turned = turned.max(line_angle(a, a0));
    }
    assert!(worst < 1e-6, "largest component error {worst}");
    // The formed directions are not the design's: the check has teeth.
    assert!(turned > 20.0, "fibres turned at most {turned}°");
}

/// `ccx` on PATH, if any.
fn find_ccx() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("ccx"))
        .find(|p| p.is_file())
}

/// Runs `deck` through `ccx`; the printed displacements, node by node.
fn ccx_displacements(ccx: &Path, deck: &str) -> Vec<(u64, [f64; 3])> {
    let dir = tempfile::tempdir().unwrap();
    fs::write(dir.path().join("job.inp"), deck).unwrap();
    let output = Command::new(ccx)
        .args(["-i", "job"])
        .current_dir(dir.path())
        .env("OMP_NUM_THREADS", "1")
        .env("CCX_NPROC_EQUATION_SOLVER", "1")
        .output()
        .unwrap();
    let dat = fs::read_to_string(dir.path().join("job.dat")).unwrap_or_default();
    let values: Vec<(u64, [f64; 3])> = dat
        .lines()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            if f.len() != 4 {
                return None;
            }
            let v: Vec<f64> = f[1..].iter().filter_map(|x| x.parse().ok()).collect();
            Some((f[0].parse().ok()?, [*v.first()?, *v.get(1)?, *v.get(2)?]))
        })
        .collect();
    assert!(
        !values.is_empty(),
        "ccx gave no displacements: {}\n{}",
        String::from_utf8_lossy(&output.stdout),
        dat
    );
    values
}

/// CalculiX runs the deck of the formed [0°] hemisphere ply under its own
/// weight (flange held), and its answer depends on the orientations: the
/// same deck with every fibre turned by 90° in its element's plane (a and
/// b of each distribution line swapped) gives another displacement field.
/// A consumer ignoring the orientations would give the same field for
/// both; the two differ by O(1) because the placeholder ply is 13.5 times
/// stiffer along the fibres than across, so the check asks for more than
/// 10 % (measured: see the message), far above the solver's round-off.
#[test]
fn calculix_runs_the_formed_ply_and_uses_its_orientations() {
    let Some(ccx) = find_ccx() else {
        println!("skipped: ccx not found (install Debian's calculix-ccx)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    coarse_run("hemisphere-0.toml", 16, &run);
    let (handoff, _) = formed_handoff(&run, &HandoffOptions::default()).unwrap();
    let mut deck = Vec::new();
    let layout = write_calculix(&handoff, &CalculixOptions::default(), &mut deck).unwrap();
    let deck = String::from_utf8(deck).unwrap();
    // The flange: mesh nodes within 1 mm of the blank plane's height.
    let top = handoff
        .mesh
        .nodes
        .iter()
        .map(|x| x[2])
        .fold(f64::NEG_INFINITY, f64::max);
    let mut step = String::from("*BOUNDARY\n");
    let mut printed = String::from("*NSET, NSET=TEST_ALL\n");
    for (n, x) in handoff.mesh.nodes.iter().enumerate() {
        for row in &layout.nodes {
            let Some(label) = row[n] else { continue };
            printed.push_str(&format!("{label}\n"));
            if x[2] > top - 1.0 {
                step.push_str(&format!("{label}, 1, 3\n"));
            }
        }
    }
    let elsets: Vec<String> = layout.ply_names.iter().map(|n| format!("{n}_EL")).collect();
    step.push_str("*STEP\n*STATIC\n*DLOAD\n");
    for e in &elsets {
        step.push_str(&format!("{e}, GRAV, 9810., 0., 0., -1.\n"));
    }
    step.push_str("*NODE PRINT, NSET=TEST_ALL\nU\n*END STEP\n");
    let as_exported = format!("{deck}{printed}{step}");
    // Swap a and b on every distribution line (not the default line).
    let mut in_distribution = false;
    let turned: String = as_exported
        .lines()
        .map(|l| {
            if l.starts_with('*') {
                in_distribution = l.to_ascii_uppercase().starts_with("*DISTRIBUTION,");
                return format!("{l}\n");
            }
            let f: Vec<&str> = l.split(',').map(str::trim).collect();
            if in_distribution && f.len() == 7 && !f[0].is_empty() {
                format!(
                    "{}, {}, {}, {}, {}, {}, {}\n",
                    f[0], f[4], f[5], f[6], f[1], f[2], f[3]
                )
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    let u = ccx_displacements(&ccx, &as_exported);
    let v = ccx_displacements(&ccx, &turned);
    assert_eq!(u.len(), v.len());
    let norm = |w: &[(u64, [f64; 3])]| w.iter().map(|(_, d)| dot(*d, *d)).sum::<f64>().sqrt();
    let difference = u
        .iter()
        .zip(&v)
        .map(|((_, a), (_, b))| {
            let d = sub(*a, *b);
            dot(d, d)
        })
        .sum::<f64>()
        .sqrt();
    let relative = difference / norm(&u);
    println!(
        "ccx, formed [0°] ply under its weight: |u| = {:.4e} mm as exported, {:.4e} mm turned; relative difference {relative:.3}",
        norm(&u),
        norm(&v)
    );
    assert!(u.iter().all(|(_, d)| d.iter().all(|c| c.is_finite())));
    assert!(norm(&u) > 0.0);
    assert!(relative > 0.1, "relative difference {relative}");
}

/// A structural mesh of the formed ply made here: a polar grid on the
/// blank (reference) plane, quads inside `cup_radius`, triangles beyond,
/// each node carried onto the formed ply through the ply's own
/// interpolation (the triangle holding it in the reference, its
/// barycentric weights on the current positions); node labels from 7001
/// in steps of 3, element labels from 5001. Plus `extra` triangles of a
/// ring lifted 20 mm off the ply, beyond the blank.
/// An element's label and its reference polygon on the blank.
type LabelledPolygon = (u64, Vec<[f64; 2]>);

/// Returns the deck's text and, per element on the ply, its label and its
/// reference polygon (on the blank).
fn structural_mesh(
    ply: &FormedPly,
    spacing: f64,
    cup_radius: f64,
) -> (String, Vec<LabelledPolygon>) {
    let locate = |p: [f64; 2]| -> Option<[f64; 3]> {
        for t in &ply.triangles {
            let [a, b, c] = t.map(|n| ply.reference[n]);
            let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
            let l1 = ((p[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (p[1] - a[1])) / det;
            let l2 = ((b[0] - a[0]) * (p[1] - a[1]) - (p[0] - a[0]) * (b[1] - a[1])) / det;
            let l0 = 1.0 - l1 - l2;
            if l0 >= -1e-12 && l1 >= -1e-12 && l2 >= -1e-12 {
                let [x, y, z] = t.map(|n| ply.nodes[n]);
                return Some([0, 1, 2].map(|k| l0 * x[k] + l1 * y[k] + l2 * z[k]));
            }
        }
        None
    };
    // Square grid over the blank's reference square, inside it by a margin.
    let (lo, hi) = ply.reference.iter().fold(
        ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]),
        |(lo, hi), x| {
            (
                [lo[0].min(x[0]), lo[1].min(x[1])],
                [hi[0].max(x[0]), hi[1].max(x[1])],
            )
        },
    );
    let n = ((hi[0] - lo[0]) / spacing).floor() as usize;
    let grid = |i: usize, j: usize| {
        [
            lo[0] + (hi[0] - lo[0]) * i as f64 / n as f64,
            lo[1] + (hi[1] - lo[1]) * j as f64 / n as f64,
        ]
    };
    let mut nodes = String::from("*NODE\n");
    let label = |i: usize, j: usize| 7001 + 3 * (j * (n + 1) + i);
    for j in 0..=n {
        for i in 0..=n {
            let Some(x) = locate(grid(i, j)) else {
                panic!("grid point off the blank");
            };
            nodes.push_str(&format!("{}, {}, {}, {}\n", label(i, j), x[0], x[1], x[2]));
        }
    }
    let mut quads = String::from("*ELEMENT, TYPE=S4R, ELSET=CUP\n");
    let mut tris = String::from("*ELEMENT, TYPE=S3, ELSET=FLANGE\n");
    let mut next = 5001;
    let mut polygons = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let c = grid(i, j);
            let centre = [
                c[0] + 0.5 * (hi[0] - lo[0]) / n as f64,
                c[1] + 0.5 * (hi[1] - lo[1]) / n as f64,
            ];
            let (a, b, cc, d) = (
                label(i, j),
                label(i + 1, j),
                label(i + 1, j + 1),
                label(i, j + 1),
            );
            let corners = [
                grid(i, j),
                grid(i + 1, j),
                grid(i + 1, j + 1),
                grid(i, j + 1),
            ];
            if centre[0].hypot(centre[1]) < cup_radius {
                quads.push_str(&format!("{next}, {a}, {b}, {cc}, {d}\n"));
                polygons.push((next, corners.to_vec()));
                next += 1;
            } else {
                tris.push_str(&format!(
                    "{next}, {a}, {b}, {cc}\n{}, {a}, {cc}, {d}\n",
                    next + 1
                ));
                polygons.push((next, vec![corners[0], corners[1], corners[2]]));
                polygons.push((next + 1, vec![corners[0], corners[2], corners[3]]));
                next += 2;
            }
        }
    }
    // The lifted ring: 8 triangles 20 mm above the blank's corner region.
    let mut extra_nodes = String::new();
    let mut extra = String::from("*ELEMENT, TYPE=S3, ELSET=OFF_PLY\n");
    let base = 900_001;
    for k in 0..9 {
        let x = hi[0] + 10.0 + 5.0 * k as f64;
        extra_nodes.push_str(&format!(
            "{}, {x}, 0., 20.\n{}, {x}, 5., 20.\n",
            base + 2 * k,
            base + 2 * k + 1
        ));
    }
    for k in 0..8 {
        let (a, b, c) = (base + 2 * k, base + 2 * k + 2, base + 2 * k + 3);
        extra.push_str(&format!("{}, {a}, {b}, {c}\n", 990_001 + k));
    }
    (
        format!(
            "** structural mesh made by tests/handoff.rs\n{nodes}{extra_nodes}{quads}{tris}{extra}"
        ),
        polygons,
    )
}

/// `true` when `p` lies in the convex, counter-clockwise `polygon`.
fn inside(polygon: &[[f64; 2]], p: [f64; 2]) -> bool {
    (0..polygon.len()).all(|k| {
        let (a, b) = (polygon[k], polygon[(k + 1) % polygon.len()]);
        (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) >= -1e-9
    })
}

/// The formed ply's fibre over a structural element, computed on the
/// blank without the mapping's machinery (no tree, no projection in
/// space): the principal direction of the orientation tensor `Σ a⊗a` over
/// a 12 × 12 grid of points spread over the element's reference polygon
/// (a quad's bilinear cells, a triangle's fan), each taking the fibre of
/// the ply triangle that holds it on the blank.
fn formed_fibre_over(ply: &FormedPly, polygon: &[[f64; 2]]) -> [f64; 3] {
    let holding = |p: [f64; 2]| {
        ply.triangles.iter().position(|tri| {
            let v = tri.map(|n| [ply.reference[n][0], ply.reference[n][1]]);
            let ccw = (v[1][0] - v[0][0]) * (v[2][1] - v[0][1])
                - (v[2][0] - v[0][0]) * (v[1][1] - v[0][1])
                > 0.0;
            let v = if ccw {
                v.to_vec()
            } else {
                vec![v[0], v[2], v[1]]
            };
            inside(&v, p)
        })
    };
    let m = 12;
    let mut tensor = nalgebra::Matrix3::<f64>::zeros();
    for i in 0..m {
        for j in 0..m {
            let (u, w) = ((i as f64 + 0.5) / m as f64, (j as f64 + 0.5) / m as f64);
            let p = if polygon.len() == 4 {
                let lerp = |a: [f64; 2], b: [f64; 2], t: f64| {
                    [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
                };
                lerp(
                    lerp(polygon[0], polygon[1], u),
                    lerp(polygon[3], polygon[2], u),
                    w,
                )
            } else {
                // The unit square folded onto the triangle (uniform in area).
                let (u, w) = if u + w > 1.0 {
                    (1.0 - u, 1.0 - w)
                } else {
                    (u, w)
                };
                [0, 1].map(|k| {
                    polygon[0][k]
                        + u * (polygon[1][k] - polygon[0][k])
                        + w * (polygon[2][k] - polygon[0][k])
                })
            };
            if let Some(t) = holding(p) {
                let f = nalgebra::Vector3::from(ply.fibre[t]);
                tensor += f * f.transpose();
            }
        }
    }
    let eigen = tensor.symmetric_eigen();
    let k = eigen.eigenvalues.imax();
    eigen.eigenvectors.column(k).into_owned().into()
}

/// `map` onto a structural mesh of the formed [45°] ply made here (quads
/// on the cup, triangles on the flange, labels of its own, elements 1.3
/// times the ply's 15 mm) gives, for at least 95 % of the elements on the
/// ply, a direction within 3° of the formed ply's over the element (the
/// acceptance figures of the hand-off, `docs/export.md`; computed on the
/// blank by [`formed_fibre_over`], independently of the mapping); the
/// eight elements off the ply are reported, get no direction, and the
/// labels come out as went in. (Measured 2026-12-06: 421 of 425, worst
/// 3.6°; with elements 0.75 times the ply's, 1260 of 1264.)
#[test]
fn map_onto_a_structural_mesh_gives_the_formed_directions() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("run");
    let cells = 20;
    coarse_run("hemisphere-45.toml", cells, &run);
    let state = read_formed_state(&run, &[0], None, false).unwrap();
    let ply = &state.plies[0];
    let ply_size = 300.0 / cells as f64;
    let ratio = 1.3;
    let (text, polygons) = structural_mesh(ply, ratio * ply_size, 60.0);
    let on_ply = polygons.len();
    let onto = dir.path().join("structure.inp");
    fs::write(&onto, &text).unwrap();
    let (handoff, mappings) = mapped_handoff(&run, &onto, &HandoffOptions::default()).unwrap();
    let mapping = &mappings[0].result;
    let mesh = &handoff.mesh;
    assert_eq!(mesh.elements.len(), on_ply + 8);
    // The labels as written, quads (S4R) and triangles (S3) both there.
    let mut labels: Vec<u64> = mesh.elements.iter().map(|e| e.label).collect();
    labels.sort_unstable();
    let expected: Vec<u64> = (5001..5001 + on_ply as u64)
        .chain(990_001..990_009)
        .collect();
    assert_eq!(labels, expected);
    for kind in ["S4R", "S3"] {
        assert!(
            mesh.elements.iter().any(|e| e.abaqus_type == kind),
            "no {kind}"
        );
    }
    let mut within = 0;
    let mut mapped = 0;
    let mut worst: f64 = 0.0;
    for (e, el) in mesh.elements.iter().enumerate() {
        if el.label >= 990_001 {
            assert!(
                mapping.fibre[e].is_none(),
                "{} off the ply got a direction",
                el.label
            );
            continue;
        }
        let Some(a) = mapping.fibre[e] else {
            panic!("element {} on the ply not mapped", el.label)
        };
        mapped += 1;
        let polygon = &polygons
            .iter()
            .find(|(label, _)| *label == el.label)
            .expect("a polygon per label")
            .1;
        let f = formed_fibre_over(ply, polygon);
        let n = mesh.normal(e).unwrap();
        let projected = sub(f, n.map(|v| v * dot(f, n)));
        let angle = line_angle(a, projected);
        worst = worst.max(angle);
        if angle <= 3.0 {
            within += 1;
        }
    }
    println!("worst {worst:.2}°");
    let share = within as f64 / mapped as f64;
    println!(
        "map: {within} of {mapped} elements within 3° ({:.1} %)",
        100.0 * share
    );
    assert!(share >= 0.95, "{within} of {mapped} within 3°");
    let off: Vec<u64> = mapping.unmapped.iter().map(|u| u.label).collect();
    assert_eq!(off, (990_001..990_009).collect::<Vec<u64>>());
}

/// Bad run folders and requests: a folder without a finished state, a ply
/// out of range, a state the run did not write; each message names the
/// folder and the value.
#[test]
fn bad_hand_off_requests_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty");
    fs::create_dir_all(&empty).unwrap();
    let e = formed_handoff(&empty, &HandoffOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("empty/") && e.to_string().contains("cannot read"),
        "{e}"
    );
    let run = dir.path().join("run");
    coarse_run("hemisphere-0.toml", 12, &run);
    let options = |plies: &[&str], state| HandoffOptions {
        plies: plies.iter().map(|s| s.to_string()).collect(),
        state,
        ..Default::default()
    };
    let e = formed_handoff(&run, &options(&["3"], None)).unwrap_err();
    assert!(
        e.to_string().contains("--ply 3") && e.to_string().contains("\"ply\""),
        "{e}"
    );
    let e = formed_handoff(&run, &options(&["ply"], Some(99))).unwrap_err();
    assert!(e.to_string().contains("--state 99"), "{e}");
    // A folder whose VTU files are gone: no finished state.
    fs::remove_dir_all(run.join("vtu")).unwrap();
    let e = formed_handoff(&run, &options(&[], None)).unwrap_err();
    assert!(e.to_string().contains("no finished state"), "{e}");
}

/// A stack is handed on as one mesh with a layer per ply: the [0°/90°]
/// hemisphere's second ply is mapped onto the first's formed mesh, the
/// Abaqus deck gets a composite section for the elements both plies cover
/// and a one-ply section where the 90° ply drew in differently (a partial
/// layup), with one distribution line per element each ply covers; the
/// plies' fibres stay crossed (median angle between them above 60°: the
/// two plies are laid at 90° and shear differently, so the check has room
/// on both sides). The tetrahedron's formed ply goes to LS-DYNA with a
/// BETA card for every element.
#[test]
fn a_stack_and_the_tetrahedron_hand_off() {
    let dir = tempfile::tempdir().unwrap();
    let run = dir.path().join("stack");
    coarse_run("hemisphere-0-90.toml", 12, &run);
    let (handoff, mappings) = formed_handoff(&run, &HandoffOptions::default()).unwrap();
    assert_eq!(handoff.layers.len(), 2);
    assert_eq!(mappings.len(), 1);
    let covered = |k: usize| {
        handoff.layers[k]
            .fibre
            .iter()
            .filter(|f| f.is_some())
            .count()
    };
    assert_eq!(covered(0), handoff.mesh.elements.len());
    assert!(covered(1) > handoff.mesh.elements.len() / 2);
    let mut deck = Vec::new();
    write_handoff(
        &handoff,
        Format::Abaqus,
        ncform::handoff::abaqus::AbaqusElement::Shell,
        &mut deck,
    )
    .unwrap();
    let deck = String::from_utf8(deck).unwrap();
    assert!(deck.contains("*SHELL SECTION, ELSET=") && deck.contains("COMPOSITE"));
    let names: Vec<String> = handoff
        .layers
        .iter()
        .map(|l| l.name.to_ascii_uppercase().replace('-', "_"))
        .collect();
    for (k, name) in names.iter().enumerate() {
        assert_eq!(distribution(&deck, name).len(), covered(k), "{name}");
    }
    if covered(1) < handoff.mesh.elements.len() {
        // The partial layup has a section of its own.
        assert!(deck.matches("*SHELL SECTION").count() >= 2);
    }
    let mut angles: Vec<f64> = handoff.layers[0]
        .fibre
        .iter()
        .zip(&handoff.layers[1].fibre)
        .filter_map(|(a, b)| Some(line_angle((*a)?, (*b)?)))
        .collect();
    angles.sort_by(f64::total_cmp);
    let median = angles[angles.len() / 2];
    assert!(median > 60.0, "median angle between the plies {median}°");

    let run = dir.path().join("tetrahedron");
    coarse_run("tetrahedron-0.toml", 24, &run);
    let (handoff, _) = formed_handoff(&run, &HandoffOptions::default()).unwrap();
    let mut deck = Vec::new();
    write_handoff(
        &handoff,
        Format::LsDyna,
        ncform::handoff::abaqus::AbaqusElement::Shell,
        &mut deck,
    )
    .unwrap();
    let deck = String::from_utf8(deck).unwrap();
    let cards = deck
        .lines()
        .skip_while(|l| !l.starts_with("*ELEMENT_SHELL_BETA"))
        .skip(1)
        .take_while(|l| !l.starts_with('*'))
        .filter(|l| !l.starts_with('$'))
        .count();
    assert_eq!(cards, 2 * handoff.mesh.elements.len());
}
