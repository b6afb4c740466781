//! The hand-off deck writers (`docs/export.md`): the Abaqus sections and
//! distributions, the LS-DYNA angles read back by fixed columns, and the
//! CalculiX deck run through `ccx` to show that the solver uses the
//! orientations.

use ncform::handoff::abaqus::{AbaqusElement, AbaqusOptions, write_abaqus};
use ncform::handoff::calculix::{CalculixLayout, CalculixOptions, write_calculix};
use ncform::handoff::lsdyna::{LsDynaOptions, write_lsdyna};
use ncform::handoff::{Handoff, Layer, OrthotropicMaterial, ShellElement, ShellMesh};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    a.map(|v| v / l)
}

fn element(label: u64, nodes: &[usize]) -> ShellElement {
    ShellElement {
        label,
        nodes: nodes.to_vec(),
        abaqus_type: String::new(),
    }
}

fn handoff(mesh: ShellMesh, layers: Vec<Layer>) -> Handoff {
    Handoff {
        mesh,
        layers,
        header: vec!["run: test".to_string(), "state: final".to_string()],
        material: OrthotropicMaterial::default(),
    }
}

/// A rotation matrix about a unit axis.
fn rotation(axis: [f64; 3], angle: f64) -> [[f64; 3]; 3] {
    let [x, y, z] = unit(axis);
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

fn apply(r: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    [dot(r[0], v), dot(r[1], v), dot(r[2], v)]
}

/// A small mixed mesh (two quads, three triangles) on a tilted plane, two
/// plies: `lower` covers elements 0–3, `upper` only 0 and 1; element 4 is
/// covered by none.
fn mixed_handoff() -> (Handoff, [[f64; 3]; 3]) {
    let r = rotation([0.3, -0.5, 0.8], 0.7);
    let flat = [
        [0.0, 0.0, 0.0],
        [10.0, 0.0, 0.0],
        [20.0, 0.0, 0.0],
        [0.0, 10.0, 0.0],
        [10.0, 10.0, 0.0],
        [20.0, 10.0, 0.0],
        [30.0, 0.0, 0.0],
        [30.0, 10.0, 0.0],
    ];
    let nodes = flat.iter().map(|&p| apply(&r, p)).collect();
    let mesh = ShellMesh {
        source: "test mixed mesh".to_string(),
        node_labels: vec![11, 12, 13, 14, 15, 16, 17, 18],
        nodes,
        elements: vec![
            element(101, &[0, 1, 4, 3]),
            element(102, &[1, 2, 5, 4]),
            element(103, &[2, 6, 5]),
            element(104, &[6, 7, 5]),
            element(105, &[5, 7, 6]),
        ],
    };
    let dir = |deg: f64| {
        let t = deg.to_radians();
        Some(apply(&r, [t.cos(), t.sin(), 0.0]))
    };
    let lower = Layer {
        name: "lower ply".to_string(),
        thickness: 0.3,
        fibre: vec![dir(0.0), dir(10.0), dir(20.0), dir(-30.0), None],
    };
    let upper = Layer {
        name: "upper-ply".to_string(),
        thickness: 0.25,
        fibre: vec![dir(90.0), dir(45.0), None, None, None],
    };
    (handoff(mesh, vec![lower, upper]), r)
}

/// The lines of `deck` under the keyword line starting with `keyword`
/// (case as written), up to the next keyword line, without comments.
fn block<'a>(deck: &'a str, keyword: &str) -> Vec<&'a str> {
    let mut lines = deck.lines();
    let mut out = Vec::new();
    for line in lines.by_ref() {
        if line.starts_with(keyword) {
            break;
        }
    }
    for line in lines {
        if line.starts_with("**") || line.starts_with('$') {
            continue;
        }
        if line.starts_with('*') {
            break;
        }
        out.push(line);
    }
    out
}

fn fields(line: &str) -> Vec<String> {
    line.split(',').map(|s| s.trim().to_string()).collect()
}

#[test]
fn abaqus_sections_follow_the_layups_and_distributions_the_directions() {
    let (h, _) = mixed_handoff();
    for element in [AbaqusElement::Shell, AbaqusElement::Membrane] {
        let mut deck = Vec::new();
        let layout = write_abaqus(&h, &AbaqusOptions { element }, &mut deck).unwrap();
        let deck = String::from_utf8(deck).unwrap();
        assert_eq!(layout.ply_names, ["LOWER_PLY", "UPPER_PLY"]);
        assert_eq!(layout.uncovered, [105]);
        assert!(deck.contains("NCFORM_UNCOVERED"));
        assert!(deck.contains("1 element(s) no ply covers"));
        assert!(deck.contains("** state: final"));
        assert!(!deck.contains("NaN"));
        // Two sections: the laminate on 101, 102 and the single ply on 103, 104.
        assert_eq!(layout.sections.len(), 2);
        let composite = &layout.sections[0];
        assert_eq!(composite.layers, [0, 1]);
        assert_eq!(composite.elements, [101, 102]);
        let single = &layout.sections[1];
        assert_eq!(single.layers, [0]);
        assert_eq!(single.elements, [103, 104]);
        assert_eq!(single.membrane, element == AbaqusElement::Membrane);
        let plies = block(
            &deck,
            &format!("*SHELL SECTION, ELSET={}, COMPOSITE", composite.elset),
        );
        assert_eq!(
            plies,
            [
                "3.000000000e-1, 3, NCFORM_UD, LOWER_PLY_ORI, LOWER_PLY",
                "2.500000000e-1, 3, NCFORM_UD, UPPER_PLY_ORI, UPPER_PLY"
            ]
        );
        let keyword = if single.membrane {
            "*MEMBRANE SECTION"
        } else {
            "*SHELL SECTION"
        };
        let line = format!(
            "{keyword}, ELSET={}, MATERIAL=NCFORM_UD, ORIENTATION=LOWER_PLY_ORI",
            single.elset
        );
        assert!(deck.contains(&line), "{line} missing:\n{deck}");
        assert_eq!(
            block(&deck, &format!("*ELSET, ELSET={}", single.elset)),
            ["103, 104"]
        );
        // Element types: the laminate always as shells.
        assert_eq!(
            block(&deck, "*ELEMENT, TYPE=S4R"),
            ["101, 11, 12, 15, 14", "102, 12, 13, 16, 15"]
        );
        if single.membrane {
            assert_eq!(
                block(&deck, "*ELEMENT, TYPE=M3D3"),
                ["103, 13, 17, 16", "104, 17, 18, 16", "105, 16, 18, 17"]
            );
            assert!(!deck.contains("TYPE=S3R"));
        } else {
            assert_eq!(
                block(&deck, "*ELEMENT, TYPE=S3R"),
                ["103, 13, 17, 16", "104, 17, 18, 16", "105, 16, 18, 17"]
            );
        }

        // One distribution line per covered element, a = the direction,
        // b unit, normal to a and tangent.
        for (k, name) in layout.ply_names.iter().enumerate() {
            let lines = block(
                &deck,
                &format!("*DISTRIBUTION, NAME={name}_DIST, LOCATION=ELEMENT, TABLE={name}_TAB"),
            );
            assert_eq!(lines[0], ", 1., 0., 0., 0., 1., 0.");
            let covered: Vec<usize> = (0..5).filter(|&e| h.layers[k].fibre[e].is_some()).collect();
            assert_eq!(lines.len(), 1 + covered.len());
            for (line, &e) in lines[1..].iter().zip(&covered) {
                let f = fields(line);
                assert_eq!(f[0], h.mesh.elements[e].label.to_string());
                let v: Vec<f64> = f[1..].iter().map(|s| s.parse().unwrap()).collect();
                let a = [v[0], v[1], v[2]];
                let b = [v[3], v[4], v[5]];
                let given = h.layers[k].fibre[e].unwrap();
                let n = h.mesh.normal(e).unwrap();
                for c in 0..3 {
                    assert!((a[c] - given[c]).abs() < 1e-8, "{line}");
                }
                assert!((dot(b, b) - 1.0).abs() < 1e-8);
                assert!(dot(a, b).abs() < 1e-8);
                assert!(dot(b, n).abs() < 1e-8);
                // b = n × a: a right-handed (a, b, n).
                assert!((dot(cross(a, b), n) - 1.0).abs() < 1e-8);
            }
            assert!(deck.contains(&format!(
                "*ORIENTATION, NAME={name}_ORI, DEFINITION=COORDINATES\n{name}_DIST\n3, 0.\n"
            )));
        }
    }
}

/// A random tilted triangle or planar convex quad with a random in-plane
/// fibre direction.
fn random_element(rng: &mut StdRng, quad: bool) -> (Vec<[f64; 3]>, [f64; 3]) {
    let axis = [
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    ];
    let r = rotation(axis, rng.random_range(0.0..3.0));
    let offset = [
        rng.random_range(-500.0..500.0),
        rng.random_range(-500.0..500.0),
        rng.random_range(-500.0..500.0),
    ];
    let mut flat = vec![
        [
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            0.0,
        ],
        [rng.random_range(4.0..6.0), rng.random_range(-1.0..1.0), 0.0],
        [rng.random_range(4.0..6.0), rng.random_range(4.0..6.0), 0.0],
    ];
    if quad {
        flat.push([rng.random_range(-1.0..1.0), rng.random_range(4.0..6.0), 0.0]);
    } else {
        flat[2][0] = rng.random_range(1.0..4.0);
    }
    let nodes = flat
        .iter()
        .map(|&p| {
            let q = apply(&r, p);
            [q[0] + offset[0], q[1] + offset[1], q[2] + offset[2]]
        })
        .collect();
    let t: f64 = rng.random_range(-4.0..4.0);
    (nodes, apply(&r, [t.cos(), t.sin(), 0.0]))
}

/// Parses a fixed-width real field, which must be right-aligned.
fn column_real(line: &str, from: usize, to: usize) -> f64 {
    let field = &line[from..to.min(line.len())];
    assert!(
        field.ends_with(|c: char| !c.is_whitespace()),
        "field {from}..{to} of `{line}` not right-aligned"
    );
    field
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("`{field}` in `{line}`"))
}

fn column_int(line: &str, from: usize, to: usize) -> u64 {
    let field = &line[from..to.min(line.len())];
    assert!(field.ends_with(|c: char| !c.is_whitespace()), "`{line}`");
    field
        .trim()
        .parse()
        .unwrap_or_else(|_| panic!("`{field}` in `{line}`"))
}

/// The data lines of the LS-DYNA keyword `keyword` (comment lines skipped).
fn keyword_block<'a>(deck: &'a str, keyword: &str) -> Vec<&'a str> {
    let mut out = Vec::new();
    let mut inside = false;
    for line in deck.lines() {
        if line.starts_with('*') {
            inside = line.trim_end() == keyword;
            continue;
        }
        if inside && !line.starts_with('$') {
            out.push(line);
        }
    }
    out
}

/// The fibre recovered from an angle [degrees] on the element of `nodes`.
fn fibre_from_beta(nodes: &[[f64; 3]], beta: f64) -> [f64; 3] {
    let n = if nodes.len() == 4 {
        unit(cross(sub(nodes[2], nodes[0]), sub(nodes[3], nodes[1])))
    } else {
        unit(cross(sub(nodes[1], nodes[0]), sub(nodes[2], nodes[0])))
    };
    let side = sub(nodes[1], nodes[0]);
    let along = dot(side, n);
    let e1 = unit([
        side[0] - along * n[0],
        side[1] - along * n[1],
        side[2] - along * n[2],
    ]);
    let e2 = cross(n, e1);
    let (s, c) = beta.to_radians().sin_cos();
    [
        c * e1[0] + s * e2[0],
        c * e1[1] + s * e2[1],
        c * e1[2] + s * e2[2],
    ]
}

/// The angle between two lines [rad].
fn line_angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    let c = dot(unit(a), unit(b)).abs().min(1.0);
    let s = cross(unit(a), unit(b));
    dot(s, s).sqrt().atan2(c)
}

#[test]
fn lsdyna_angles_read_back_by_columns_give_the_fibres() {
    let mut rng = StdRng::seed_from_u64(47);
    let mut nodes = Vec::new();
    let mut elements = Vec::new();
    let mut lower = Vec::new();
    let mut upper = Vec::new();
    for e in 0..200 {
        let (xs, a) = random_element(&mut rng, e % 2 == 1);
        let first = nodes.len();
        nodes.extend(xs);
        let count = if e % 2 == 1 { 4 } else { 3 };
        elements.push(element(
            1000 + e as u64,
            &(first..first + count).collect::<Vec<_>>(),
        ));
        lower.push(Some(a));
        // The upper ply covers every third element, along another direction.
        let (_, b) = random_element(&mut rng, false);
        let n = {
            let x = &nodes[first..];
            if count == 4 {
                unit(cross(sub(x[2], x[0]), sub(x[3], x[1])))
            } else {
                unit(cross(sub(x[1], x[0]), sub(x[2], x[0])))
            }
        };
        let b_in = unit(cross(n, b));
        upper.push((e % 3 == 0).then_some(b_in));
    }
    let node_labels = (0..nodes.len() as u64).map(|i| 1 + 7 * i).collect();
    let mesh = ShellMesh {
        source: "random tilted elements".to_string(),
        node_labels,
        nodes,
        elements,
    };
    let h = handoff(
        mesh,
        vec![
            Layer {
                name: "L1".into(),
                thickness: 0.3,
                fibre: lower,
            },
            Layer {
                name: "L2".into(),
                thickness: 0.2,
                fibre: upper,
            },
        ],
    );
    let mut h = h;
    h.header
        .push("plies 0° and 90° — a provenance line with non-ASCII characters".to_string());
    let mut deck = Vec::new();
    let layout = write_lsdyna(&h, &LsDynaOptions::default(), &mut deck).unwrap();
    let deck = String::from_utf8(deck).unwrap();
    assert_eq!(layout.parts.len(), 2);
    for line in deck.lines() {
        assert!(line.len() <= 80, "`{line}` is {} columns", line.len());
        assert!(line.is_ascii());
    }
    assert!(!deck.contains("NaN"));
    // INN off, explicitly.
    let accuracy = keyword_block(&deck, "*CONTROL_ACCURACY");
    assert_eq!(column_int(accuracy[0], 10, 20), 1);

    // Nodes by columns: i8, 3 e16, i8, i8.
    let mut positions: HashMap<u64, [f64; 3]> = HashMap::new();
    for line in keyword_block(&deck, "*NODE") {
        assert_eq!(line.len(), 72, "`{line}`");
        let label = column_int(line, 0, 8);
        let x = [
            column_real(line, 8, 24),
            column_real(line, 24, 40),
            column_real(line, 40, 56),
        ];
        assert_eq!(column_int(line, 56, 64), 0);
        assert_eq!(column_int(line, 64, 72), 0);
        positions.insert(label, x);
    }
    let index: HashMap<u64, usize> = h
        .mesh
        .elements
        .iter()
        .enumerate()
        .map(|(e, el)| (el.label, e))
        .collect();
    let element_nodes = |line: &str| -> Vec<[f64; 3]> {
        let labels: Vec<u64> = (0..4)
            .map(|k| column_int(line, 16 + 8 * k, 24 + 8 * k))
            .collect();
        let mut xs: Vec<[f64; 3]> = labels.iter().map(|l| positions[l]).collect();
        if labels[3] == labels[2] {
            xs.pop();
        }
        xs
    };

    let mut worst: f64 = 0.0;
    let single = keyword_block(&deck, "*ELEMENT_SHELL_BETA");
    assert_eq!(single.len() % 2, 0);
    let mut seen = 0;
    for pair in single.chunks(2) {
        let e = index[&column_int(pair[0], 0, 8)];
        assert_eq!(pair[0].len(), 48);
        assert_eq!(pair[1].len(), 80);
        for k in 0..4 {
            assert!((column_real(pair[1], 16 * k, 16 * (k + 1)) - 0.3).abs() < 1e-12);
        }
        let beta = column_real(pair[1], 64, 80);
        assert!(beta > -90.0 && beta <= 90.0);
        let xs = element_nodes(pair[0]);
        assert_eq!(xs.len(), h.mesh.elements[e].nodes.len());
        let a = h.layers[0].fibre[e].unwrap();
        worst = worst.max(line_angle(fibre_from_beta(&xs, beta), a));
        seen += 1;
    }
    let composite = keyword_block(&deck, "*ELEMENT_SHELL_COMPOSITE");
    assert_eq!(composite.len() % 2, 0);
    for pair in composite.chunks(2) {
        let e = index[&column_int(pair[0], 0, 8)];
        let xs = element_nodes(pair[0]);
        let card = pair[1];
        assert_eq!(column_int(card, 0, 10), layout.mid);
        assert!((column_real(card, 10, 20) - 0.3).abs() < 1e-12);
        assert_eq!(column_int(card, 40, 50), layout.mid);
        assert!((column_real(card, 50, 60) - 0.2).abs() < 1e-12);
        assert!(card[30..40].trim().is_empty());
        for (k, from) in [(0, 20), (1, 60)] {
            let beta = column_real(card, from, from + 10);
            let a = h.layers[k].fibre[e].unwrap();
            worst = worst.max(line_angle(fibre_from_beta(&xs, beta), a));
        }
        seen += 1;
    }
    assert_eq!(seen, 200);
    assert!(worst < 1e-6, "worst fibre error {worst} rad");
}

/// `ccx` on PATH, if any.
fn find_ccx() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("ccx"))
        .find(|p| p.is_file())
}

/// A flat strip `length × width` of triangles, one ply `thickness` thick
/// with fibres at `angle` degrees from the strip's axis x.
fn strip(length: f64, width: f64, nx: usize, ny: usize, angle: f64) -> Handoff {
    let mut nodes = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            nodes.push([
                length * i as f64 / nx as f64,
                width * j as f64 / ny as f64,
                0.0,
            ]);
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut elements = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let label = elements.len() as u64 + 1;
            elements.push(element(label, &[id(i, j), id(i + 1, j), id(i + 1, j + 1)]));
            elements.push(element(
                label + 1,
                &[id(i, j), id(i + 1, j + 1), id(i, j + 1)],
            ));
        }
    }
    let t = angle.to_radians();
    let fibre = vec![Some([t.cos(), t.sin(), 0.0]); elements.len()];
    let mesh = ShellMesh {
        source: "strip".to_string(),
        node_labels: (1..=nodes.len() as u64).collect(),
        nodes,
        elements,
    };
    handoff(
        mesh,
        vec![Layer {
            name: "ply".into(),
            thickness: 0.3,
            fibre,
        }],
    )
}

/// The test's own step: the end `x = 0` held in x (and enough else to stop
/// rigid motion, free to contract), `force` in x spread evenly over the
/// nodes at `x = length`; prints their displacements.
fn tension_step(h: &Handoff, layout: &CalculixLayout, length: f64, force: f64) -> String {
    let mut held = Vec::new();
    let mut bottom_held = Vec::new();
    let mut pulled = Vec::new();
    for (n, x) in h.mesh.nodes.iter().enumerate() {
        for (i, row) in layout.nodes.iter().enumerate() {
            let Some(label) = row[n] else { continue };
            if x[0].abs() < 1e-9 {
                held.push(label);
                if i == 0 {
                    bottom_held.push((label, x[1]));
                }
            }
            if (x[0] - length).abs() < 1e-9 {
                pulled.push(label);
            }
        }
    }
    let mut s = String::from("*NSET, NSET=TEST_END\n");
    for l in &pulled {
        s.push_str(&format!("{l}\n"));
    }
    s.push_str("*BOUNDARY\n");
    for l in &held {
        s.push_str(&format!("{l}, 1, 1\n"));
    }
    for &(l, y) in &bottom_held {
        s.push_str(&format!("{l}, 3, 3\n"));
        if y.abs() < 1e-9 {
            s.push_str(&format!("{l}, 2, 2\n"));
        }
    }
    s.push_str("*STEP\n*STATIC\n*CLOAD\n");
    let share = force / pulled.len() as f64;
    for l in &pulled {
        s.push_str(&format!("{l}, 1, {share:e}\n"));
    }
    s.push_str("*NODE PRINT, NSET=TEST_END\nU\n*END STEP\n");
    s
}

/// Runs `deck` through `ccx` in a temporary folder and returns the mean x
/// displacement of the printed nodes.
fn run_ccx(ccx: &Path, deck: &str) -> f64 {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("job.inp"), deck).unwrap();
    let output = Command::new(ccx)
        .args(["-i", "job"])
        .current_dir(dir.path())
        .env("OMP_NUM_THREADS", "1")
        .env("CCX_NPROC_EQUATION_SOLVER", "1")
        .output()
        .unwrap();
    let dat = std::fs::read_to_string(dir.path().join("job.dat")).unwrap_or_default();
    let values: Vec<f64> = dat
        .lines()
        .filter_map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f.len() == 4 && f[0].parse::<u64>().is_ok()).then(|| f[1].parse::<f64>().ok())?
        })
        .collect();
    assert!(
        !values.is_empty(),
        "ccx gave no displacements: {}\n{}",
        String::from_utf8_lossy(&output.stdout),
        dat
    );
    values.iter().sum::<f64>() / values.len() as f64
}

#[test]
fn calculix_runs_and_uses_the_orientations() {
    let (length, width, force) = (100.0, 10.0, 100.0);
    let deck_of = |angle: f64| {
        let h = strip(length, width, 20, 2, angle);
        let mut deck = Vec::new();
        let layout = write_calculix(&h, &CalculixOptions::default(), &mut deck).unwrap();
        let mut deck = String::from_utf8(deck).unwrap();
        assert!(!deck.contains("NaN"));
        assert!(
            !deck
                .lines()
                .any(|l| l.to_ascii_uppercase().starts_with("*STEP"))
        );
        assert!(deck.lines().all(|l| l.len() <= 132));
        deck.push_str(&tension_step(&h, &layout, length, force));
        (h, layout, deck)
    };
    let (h0, layout, deck0) = deck_of(0.0);
    // The label scheme: stride 100 above labels up to 80; two interfaces.
    assert_eq!(layout.stride, 100);
    assert_eq!(layout.nodes.len(), 2);
    assert_eq!(layout.nodes[0][4], Some(105));
    assert_eq!(layout.nodes[1][4], Some(205));
    assert_eq!(layout.solids[0][7], Some(108));
    assert!((layout.heights[0] + 0.15).abs() < 1e-12 && (layout.heights[1] - 0.15).abs() < 1e-12);
    assert!(
        deck0.contains("*SOLID SECTION, ELSET=PLY_EL, MATERIAL=NCFORM_UD, ORIENTATION=PLY_ORI")
    );
    assert_eq!(h0.mesh.elements.len(), 80);

    let Some(ccx) = find_ccx() else {
        println!("skipped: ccx not found (install Debian's calculix-ccx)");
        return;
    };
    let (_, _, deck90) = deck_of(90.0);
    let (_, _, deck45) = deck_of(45.0);
    let u0 = run_ccx(&ccx, &deck0);
    let u90 = run_ccx(&ccx, &deck90);
    let u45 = run_ccx(&ccx, &deck45);
    // The 90° deck without its orientation: what a writer whose
    // orientation the solver ignored would give.
    let unoriented = deck90.replace(", ORIENTATION=PLY_ORI", "");
    let u_none = run_ccx(&ccx, &unoriented);

    let m = OrthotropicMaterial::default();
    // Uniform tension σ of a strip free to contract: u = σ L / E_x, so
    // u90/u0 = E1/E2, and at 45° 1/E_x = (1/E1 + 1/E2 + 1/G12 − 2ν12/E1)/4.
    let expected90 = m.e1 / m.e2;
    let compliance45 = (1.0 / m.e1 + 1.0 / m.e2 + 1.0 / m.g12 - 2.0 * m.nu12 / m.e1) / 4.0;
    let expected45 = m.e1 * compliance45;
    let ratio90 = u90 / u0;
    let ratio45 = u45 / u0;
    println!(
        "ccx: u0 = {u0:.6e} mm, u90 = {u90:.6e} mm, u45 = {u45:.6e} mm, without orientation \
         {u_none:.6e} mm; u90/u0 = {ratio90:.4} (E1/E2 = {expected90:.4}), \
         u45/u0 = {ratio45:.4} (rotated compliance {expected45:.4})"
    );
    // The expected 0° extension itself: σ L / E1.
    let sigma = force / (width * 0.3);
    let u0_expected = sigma * length / m.e1;
    assert!(
        (u0 / u0_expected - 1.0).abs() < 0.1,
        "u0 {u0} vs {u0_expected}"
    );
    // Tolerance 10 %: the loads are lumped equally on the end nodes and the
    // held end restrains the Poisson contraction a little (end effects);
    // a uniform strip in a linear solid is otherwise exact.
    assert!(
        (ratio90 / expected90 - 1.0).abs() < 0.1,
        "{ratio90} vs {expected90}"
    );
    assert!(
        (ratio45 / expected45 - 1.0).abs() < 0.1,
        "{ratio45} vs {expected45}"
    );
    // Without the orientation the 90° strip is as stiff as the 0° one: far
    // outside the tolerance.
    assert!((u_none / u0 - 1.0).abs() < 0.05, "{u_none} vs {u0}");
    assert!(ratio90 > 5.0 * (u_none / u0));
}

#[test]
fn writers_refuse_inconsistent_handoffs() {
    let (mut h, _) = mixed_handoff();
    h.layers[1].fibre.pop();
    let mut sink = Vec::new();
    assert!(write_abaqus(&h, &AbaqusOptions::default(), &mut sink).is_err());
    assert!(write_lsdyna(&h, &LsDynaOptions::default(), &mut sink).is_err());
    assert!(write_calculix(&h, &CalculixOptions::default(), &mut sink).is_err());
    let (mut h, _) = mixed_handoff();
    h.layers[0].thickness = f64::NAN;
    assert!(write_abaqus(&h, &AbaqusOptions::default(), &mut sink).is_err());
}

#[test]
fn calculix_runs_a_tilted_laminate_of_quads_and_triangles() {
    // Two plies, the upper one on part of the mesh, one element uncovered:
    // the deck must run as written (wedges and bricks, two distributions).
    let (h, r) = mixed_handoff();
    let mut deck = Vec::new();
    let layout = write_calculix(&h, &CalculixOptions::default(), &mut deck).unwrap();
    let mut deck = String::from_utf8(deck).unwrap();
    assert_eq!(layout.stride, 1000);
    assert_eq!(layout.solids[0][0], Some(1101));
    assert_eq!(layout.solids[1][0], Some(2101));
    assert_eq!(layout.solids[1][2], None);
    assert!(layout.solids.iter().all(|s| s[4].is_none()));
    assert!(deck.contains("*ELEMENT, TYPE=C3D8"));
    assert!(deck.contains("*ELEMENT, TYPE=C3D6"));
    assert!(deck.contains("1 element(s) no ply covers have no solid"));
    // The extruded nodes lie on the averaged normals, the stack centred.
    let n = apply(&r, [0.0, 0.0, 1.0]);
    let bottom = layout.heights[0];
    assert!((bottom + 0.275).abs() < 1e-12);
    for (i, row) in layout.nodes.iter().enumerate() {
        for (k, label) in row.iter().enumerate() {
            let Some(label) = label else { continue };
            let prefix = format!("{label}, ");
            let line = deck.lines().find(|l| l.starts_with(&prefix)).unwrap();
            let x: Vec<f64> = fields(line)[1..]
                .iter()
                .map(|s| s.parse().unwrap())
                .collect();
            let p = h.mesh.nodes[k];
            for c in 0..3 {
                let expected = p[c] + layout.heights[i] * n[c];
                assert!((x[c] - expected).abs() < 1e-7, "{line}");
            }
        }
    }
    let Some(ccx) = find_ccx() else {
        println!("skipped: ccx not found (install Debian's calculix-ccx)");
        return;
    };
    // Hold the bottom, pull one top node along the fibre of its element.
    deck.push_str("*BOUNDARY\nNCFORM_BOTTOM, 1, 3\n*STEP\n*STATIC\n*CLOAD\n");
    let top = layout.nodes[2][0].unwrap();
    let a = h.layers[0].fibre[0].unwrap();
    for (c, v) in a.iter().enumerate() {
        deck.push_str(&format!("{top}, {}, {:e}\n", c + 1, 10.0 * v));
    }
    deck.push_str("*NODE PRINT, NSET=NCFORM_TOP\nU\n*END STEP\n");
    let mean = run_ccx(&ccx, &deck);
    assert!(mean.is_finite());
}

#[test]
fn calculix_refuses_elements_of_opposite_node_order() {
    // Element 105 is given the opposite node order of its neighbour 104:
    // once a ply covers it, the nodal normals cancel or its solid would be
    // inverted, and the writer says so instead of writing it.
    let (mut h, r) = mixed_handoff();
    h.layers[0].fibre[4] = Some(apply(&r, [1.0, 0.0, 0.0]));
    let mut sink = Vec::new();
    let error = write_calculix(&h, &CalculixOptions::default(), &mut sink).unwrap_err();
    assert!(
        error.to_string().contains("inconsistent node order"),
        "{error}"
    );
}
