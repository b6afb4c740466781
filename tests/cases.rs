//! Tests of case files and `ncform run` (docs/cases.md; docs/cases.md):
//! validation messages, mesh files, boundary conditions, zones, the outputs
//! of a run, incomplete runs and exit codes. Each test names the requirement
//! it checks. The cases are coarse (15 mm elements, at most 40 mm) so the
//! whole file runs in a few seconds.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

use nalgebra::Vector2;
use ncform::case::oat::{DEFAULT_MDZ_SIZE, DEFAULT_THICKNESS, MeshSource};
use ncform::case::{OatCase, Zone};
use ncform::mesh::generate::{GridPattern, GridResolution};
use ncform::report::Progress;
use ncform::report::files::run_case;
use ncform::report::oat::RunSummary;
use ncform::solver::{NewtonParameters, RunStatus};
use serde_json::Value;
use tempfile::TempDir;

/// A coarse 45° OAT: 100 × 300 mm, 15 mm elements, pulled to 40 mm.
const BASE: &str = r#"title = "coarse 45° OAT"

[specimen]
width = 100.0
length = 300.0
bias_angle_deg = 45.0

[mesh]
element_size = 15.0

[loading]
displacement = 40.0
"#;

/// The sample meshes shipped with ncform.
fn sample_mesh(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("cases/meshes")
        .join(name)
}

/// `base` with each `(from, to)` replaced once; panics if `from` is absent.
fn edit(base: &str, edits: &[(&str, &str)]) -> String {
    let mut text = base.to_string();
    for (from, to) in edits {
        assert!(text.contains(from), "`{from}` not in the case text");
        text = text.replacen(from, to, 1);
    }
    text
}

/// `base` with `extra` appended (new tables).
fn append(base: &str, extra: &str) -> String {
    format!("{base}{extra}")
}

/// 1-based line of the first line of `text` that starts with `prefix`.
fn line_of(text: &str, prefix: &str) -> usize {
    text.lines()
        .position(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("no line starting with `{prefix}`"))
        + 1
}

fn write(path: &Path, text: &str) -> PathBuf {
    if let Some(parent) = path.parent() {
        fs::create_dir_all(parent).unwrap();
    }
    fs::write(path, text).unwrap();
    path.to_path_buf()
}

/// Asserts that `msg` contains every one of `parts`.
fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message `{msg}` lacks `{p}`");
    }
}

/// Writes `text` as `case.toml` in a fresh folder and loads it, expecting an
/// error; returns the message and the case file's path as printed.
fn case_error(text: &str) -> (String, String) {
    let dir = TempDir::new().unwrap();
    case_error_in(dir.path(), text)
}

fn case_error_in(dir: &Path, text: &str) -> (String, String) {
    let path = write(&dir.join("case.toml"), text);
    let err = OatCase::load(&path).expect_err("the case should be rejected");
    (err.to_string(), path.display().to_string())
}

fn load(dir: &Path, text: &str) -> OatCase {
    let path = write(&dir.join("case.toml"), text);
    OatCase::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

fn run(case: &OatCase, out: &Path) -> RunSummary {
    run_case(case, out, Progress::Quiet).unwrap_or_else(|e| panic!("{e}"))
}

/// The data rows of a CSV written by `ncform run` (after the `#` preamble
/// and the header line), and the preamble and header.
fn read_csv(path: &Path) -> (Vec<String>, String, Vec<Vec<f64>>) {
    let text = fs::read_to_string(path).unwrap();
    let mut preamble = Vec::new();
    let mut lines = text.lines();
    let header = loop {
        let line = lines.next().expect("a header line");
        match line.strip_prefix("# ") {
            Some(p) => preamble.push(p.to_string()),
            None => break line.to_string(),
        }
    };
    let rows = lines
        .filter(|l| !l.is_empty())
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    (preamble, header, rows)
}

fn read_summary(out: &Path) -> Value {
    let text = fs::read_to_string(out.join("summary.json")).unwrap();
    serde_json::from_str(&text).expect("summary.json is JSON")
}

fn png_size(path: &Path) -> (u32, u32) {
    let decoder = png::Decoder::new(fs::File::open(path).unwrap());
    let reader = decoder.read_info().unwrap();
    (reader.info().width, reader.info().height)
}

// ---------------------------------------------------------------------------
// 1. Case-file validation
// ---------------------------------------------------------------------------

/// docs/cases.md "Error messages": an unknown key in any table (and at the top
/// level) is rejected by the parser with the file, the line, the key and the
/// keys the table accepts.
#[test]
fn unknown_keys_are_rejected_in_every_table() {
    let cases: [(&str, String, &str); 7] = [
        (
            "top level",
            edit(BASE, &[("title = ", "foo = 1\ntitle = ")]),
            "foo",
        ),
        (
            "[specimen]",
            edit(BASE, &[("width = 100.0", "width = 100.0\nthicknes = 0.3")]),
            "thicknes",
        ),
        (
            "[mesh]",
            edit(
                BASE,
                &[("element_size = 15.0", "element_size = 15.0\nsize = 2")],
            ),
            "size",
        ),
        (
            "[material]",
            append(BASE, "\n[material]\nparam = \"schaefer2024\"\n"),
            "param",
        ),
        (
            "[loading]",
            edit(
                BASE,
                &[("displacement = 40.0", "displacement = 40.0\nrate = 1")],
            ),
            "rate",
        ),
        ("[output]", append(BASE, "\n[output]\nmdz = 20.0\n"), "mdz"),
        (
            "[solver]",
            append(BASE, "\n[solver]\ntolerance = 1e-6\n"),
            "tolerance",
        ),
    ];
    for (table, text, key) in cases {
        let (msg, file) = case_error(&text);
        let line = line_of(&text, &format!("{key} ="));
        assert_mentions(
            &msg,
            &[
                &file,
                &format!("line {line}"),
                &format!("unknown field `{key}`"),
                "expected",
            ],
        );
        assert!(msg.starts_with(&file), "{table}: `{msg}`");
    }
    // The message lists what the table accepts.
    let (msg, _) = case_error(&append(BASE, "\n[solver]\ntolerance = 1e-6\n"));
    assert_mentions(&msg, &["residual_tolerance", "max_iterations", "cutback"]);
}

/// docs/cases.md "Error messages": a missing required key or table is named,
/// with the line of its table.
#[test]
fn missing_required_keys_are_named() {
    let cases: [(String, &str, Option<&str>); 6] = [
        (
            edit(BASE, &[("width = 100.0\n", "")]),
            "missing field `width`",
            Some("[specimen]"),
        ),
        (
            edit(BASE, &[("length = 300.0\n", "")]),
            "missing field `length`",
            Some("[specimen]"),
        ),
        (
            edit(BASE, &[("bias_angle_deg = 45.0\n", "")]),
            "missing field `bias_angle_deg`",
            Some("[specimen]"),
        ),
        (
            edit(
                BASE,
                &[("displacement = 40.0", "output_displacements = [10.0]")],
            ),
            "missing field `displacement`",
            Some("[loading]"),
        ),
        (
            edit(BASE, &[("[loading]\ndisplacement = 40.0\n", "")]),
            "missing field `loading`",
            None,
        ),
        (
            edit(BASE, &[("[mesh]\nelement_size = 15.0\n", "")]),
            "missing field `mesh`",
            None,
        ),
    ];
    for (text, expected, table) in cases {
        let (msg, file) = case_error(&text);
        assert_mentions(&msg, &[&file, expected]);
        if let Some(table) = table {
            assert_mentions(&msg, &[&format!("line {}", line_of(&text, table))]);
        }
    }
}

/// docs/cases.md "Error messages": a value out of range is reported as
/// `file:line: key = value: expected …`.
#[test]
fn out_of_range_values_name_file_line_key_and_value() {
    let cases: [(String, &str, &str, &str); 9] = [
        (
            edit(BASE, &[("width = 100.0", "width = -100.0")]),
            "width =",
            "specimen.width = -100",
            "a length > 0 mm",
        ),
        (
            edit(BASE, &[("length = 300.0", "length = 0.0")]),
            "length =",
            "specimen.length = 0",
            "a length > 0 mm",
        ),
        (
            edit(BASE, &[("bias_angle_deg = 45.0", "bias_angle_deg = 120.0")]),
            "bias_angle_deg =",
            "specimen.bias_angle_deg = 120",
            "[-90, 90]",
        ),
        (
            edit(
                BASE,
                &[(
                    "element_size = 15.0",
                    "element_size = 15.0\npattern = \"diagonal\"",
                )],
            ),
            "pattern =",
            "mesh.pattern = \"diagonal\"",
            "\"roving-diagonal\" or \"both-diagonals\"",
        ),
        (
            edit(BASE, &[("element_size = 15.0", "element_size = -2.0")]),
            "element_size =",
            "mesh.element_size = -2",
            "a length > 0 mm",
        ),
        (
            edit(BASE, &[("element_size = 15.0", "nx = 0\nny = 12")]),
            "nx =",
            "mesh.nx = 0",
            "1..=100000",
        ),
        (
            edit(
                BASE,
                &[(
                    "displacement = 40.0",
                    "displacement = 40.0\noutput_displacements = [20.0, 50.0]",
                )],
            ),
            "output_displacements =",
            "loading.output_displacements = 50",
            "(0, 40] mm",
        ),
        (
            append(BASE, "\n[output]\ncontour_displacement = 0.0\n"),
            "contour_displacement =",
            "output.contour_displacement = 0",
            "(0, 40] mm",
        ),
        (
            append(BASE, "\n[material]\nthickness = 0.0\n"),
            "thickness =",
            "material.thickness = 0",
            "a length > 0 mm",
        ),
    ];
    for (text, line_key, key_value, expected) in cases {
        let (msg, file) = case_error(&text);
        let line = line_of(&text, line_key);
        assert_mentions(
            &msg,
            &[&format!("{file}:{line}: {key_value}: expected"), expected],
        );
    }
    // A value of the wrong type is caught by the parser, with its line.
    let text = edit(BASE, &[("width = 100.0", "width = \"100\"")]);
    let (msg, file) = case_error(&text);
    assert_mentions(&msg, &[&file, "line 4", "invalid type: string"]);
}

/// docs/cases.md `[mesh]`: exactly one of `element_size`, `nx` + `ny`,
/// `file`; clamp sets only with `file`.
#[test]
fn mesh_table_needs_exactly_one_source() {
    let both = edit(
        BASE,
        &[("element_size = 15.0", "element_size = 15.0\nnx = 4")],
    );
    let nx_alone = edit(BASE, &[("element_size = 15.0", "nx = 4")]);
    let ny_alone = edit(BASE, &[("element_size = 15.0", "ny = 12")]);
    let none = edit(
        BASE,
        &[("element_size = 15.0", "pattern = \"roving-diagonal\"")],
    );
    let file_and_size = edit(
        BASE,
        &[(
            "element_size = 15.0",
            "element_size = 15.0\nfile = \"square.inp\"",
        )],
    );
    for text in [both, nx_alone, ny_alone, none, file_and_size] {
        let (msg, file) = case_error(&text);
        assert_mentions(
            &msg,
            &[
                &file,
                "[mesh]",
                "exactly one of: element_size; nx and ny; file",
            ],
        );
    }
    for key in ["fixed_clamp_set", "moving_clamp_set"] {
        let text = edit(
            BASE,
            &[(
                "element_size = 15.0",
                &format!("element_size = 15.0\n{key} = \"bottom\""),
            )],
        );
        let (msg, file) = case_error(&text);
        assert_mentions(&msg, &[&file, key, "only with mesh.file"]);
    }
}

/// docs/cases.md `[material]`: an unknown set is named with the list of
/// named sets; an error inside a parameter file names that file (resolved
/// from the case file's folder), its line and key.
#[test]
fn material_errors_name_the_set_or_the_file() {
    let (msg, _) = case_error(&append(BASE, "\n[material]\nparams = \"schaefer2025\"\n"));
    assert_mentions(
        &msg,
        &[
            "schaefer2025",
            "not a named set",
            "schaefer2024, schaefer2024-printed",
        ],
    );

    let dir = TempDir::new().unwrap();
    let material = write(
        &dir.path().join("materials/bad.toml"),
        "law = \"ud-ncf\"\nname = \"mine\"\n\n[w4]\nc_ini = 1000.0\nc_inii = 3.0\n",
    );
    let (msg, case_file) = case_error_in(
        dir.path(),
        &append(BASE, "\n[material]\nparams = \"materials/bad.toml\"\n"),
    );
    // The case's line and key first, then the parameter file's own error.
    assert!(
        msg.starts_with(&format!("{case_file}:")),
        "`{msg}` should start with the case file {case_file}"
    );
    assert_mentions(
        &msg,
        &[
            "material.params = \"materials/bad.toml\": ",
            &format!("{}: ", material.display()),
            "line 6",
            "unknown field `c_inii`",
        ],
    );
}

/// docs/cases.md `[solver]`: every knob is checked (factor ranges, counts,
/// increments, the factorisation's name, the inertia's duration and
/// amplitude).
#[test]
fn solver_table_is_validated() {
    let cases: [(&str, &str); 9] = [
        (
            "cutback = 1.5",
            "solver.cutback = 1.5: expected a factor in (0, 1)",
        ),
        (
            "max_iterations = 0",
            "solver.max_iterations = 0: expected at least 1",
        ),
        ("growth = 0.5", "solver.growth = 0.5: expected a factor ≥ 1"),
        (
            "initial_increment = -1.0",
            "solver.initial_increment = -1: expected a number > 0",
        ),
        (
            "residual_tolerance = 0.0",
            "solver.residual_tolerance = 0: expected a number > 0",
        ),
        (
            "min_increment = 10.0\nmax_increment = 5.0",
            "solver.min_increment = 10: expected at most max_increment",
        ),
        (
            "linear_solver = \"cholesky\"",
            "unknown variant `cholesky`, expected `lu` or `ldlt`",
        ),
        (
            "inertia_duration = -1.0",
            "solver.inertia_duration = -1: expected a number > 0",
        ),
        (
            "inertia_amplitude = \"cubic\"",
            "unknown variant `cubic`, expected one of `smooth-step`, `linear`, `quadratic`",
        ),
    ];
    for (body, expected) in cases {
        let (msg, file) = case_error(&append(BASE, &format!("\n[solver]\n{body}\n")));
        assert_mentions(&msg, &[&file, expected]);
    }
}

/// docs/cases.md "Error messages": a case file that cannot be read is named.
#[test]
fn missing_case_file_is_reported() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("nothere.toml");
    let msg = OatCase::load(&path).unwrap_err().to_string();
    assert_mentions(
        &msg,
        &[&format!("case file '{}'", path.display()), "No such file"],
    );
}

/// docs/cases.md "Keys", "General rules": the defaults of every optional key,
/// integers accepted for decimal keys, and relative paths taken from the case
/// file's folder.
#[test]
fn defaults_and_relative_paths() {
    let text = edit(BASE, &[("title = \"coarse 45° OAT\"\n", "")]);
    let text = edit(&text, &[("width = 100.0", "width = 100")]);
    let case = OatCase::from_toml_str(&text, "embedded", Path::new(".")).unwrap();
    assert_eq!(case.title, "45° off-axis tension test");
    assert_eq!(case.width, 100.0);
    assert_eq!(case.material.name, "schaefer2024");
    assert_eq!(case.thickness, DEFAULT_THICKNESS);
    assert_eq!(case.thickness, 0.3);
    assert_eq!(case.mdz_size, DEFAULT_MDZ_SIZE);
    assert_eq!(case.mdz_size, 20.0);
    assert_eq!(case.contour_displacement, 40.0);
    assert_eq!(case.output_displacements, vec![40.0]);
    assert_eq!(case.solver, NewtonParameters::default());
    assert_eq!(
        case.mesh,
        MeshSource::Generated {
            resolution: GridResolution::ElementSize(15.0),
            pattern: GridPattern::RovingDiagonal,
        }
    );
    // Output displacements are sorted, deduplicated, and get the final and
    // the contour displacement.
    let text = append(
        &edit(
            BASE,
            &[(
                "displacement = 40.0",
                "displacement = 40.0\noutput_displacements = [20.0, 10.0, 20.0]",
            )],
        ),
        "\n[output]\ncontour_displacement = 30.0\n",
    );
    let case = OatCase::from_toml_str(&text, "embedded", Path::new(".")).unwrap();
    assert_eq!(case.output_displacements, vec![10.0, 20.0, 30.0, 40.0]);

    // A mesh file: default clamp sets `bottom` and `top`, path from the
    // case file's folder.
    let dir = TempDir::new().unwrap();
    let text = edit(BASE, &[("element_size = 15.0", "file = \"m/square.inp\"")]);
    let case = load(&dir.path().join("sub"), &text);
    assert_eq!(
        case.mesh,
        MeshSource::File {
            path: dir.path().join("sub/m/square.inp"),
            fixed_clamp_set: "bottom".into(),
            moving_clamp_set: "top".into(),
        }
    );
}

// ---------------------------------------------------------------------------
// 2. Mesh files
// ---------------------------------------------------------------------------

/// A case in `dir` that reads the mesh `file` (relative to `dir`), pulled to
/// `displacement` mm.
fn mesh_case(dir: &Path, file: &str, extra_mesh_keys: &str, displacement: f64) -> OatCase {
    let text = edit(
        BASE,
        &[
            (
                "element_size = 15.0",
                &format!("file = \"{file}\"{extra_mesh_keys}"),
            ),
            (
                "displacement = 40.0",
                &format!("displacement = {displacement:?}"),
            ),
        ],
    );
    load(dir, &text)
}

/// Runs `case` into `dir/out`, expecting a set-up error; checks that no
/// output was written and returns the message.
fn run_error(case: &OatCase, dir: &Path) -> String {
    let out = dir.join("out");
    let err = run_case(case, &out, Progress::Quiet).expect_err("the run should fail");
    assert!(!out.exists(), "a failed set-up must not write outputs");
    err.to_string()
}

/// docs/meshes.md, docs/cases.md `[mesh]`: a clamp set that the mesh file
/// does not have is named with the file and the sets it does have.
#[test]
fn unknown_clamp_set_lists_the_available_sets() {
    let dir = TempDir::new().unwrap();
    fs::copy(sample_mesh("square.inp"), dir.path().join("square.inp")).unwrap();
    fs::copy(sample_mesh("square.msh"), dir.path().join("square.msh")).unwrap();
    for file in ["square.inp", "square.msh"] {
        for key in ["fixed_clamp_set", "moving_clamp_set"] {
            let case = mesh_case(dir.path(), file, &format!("\n{key} = \"clamp\""), 5.0);
            let msg = run_error(&case, dir.path());
            assert_mentions(
                &msg,
                &[
                    file,
                    "no node set named `clamp`",
                    "available node sets: all, bottom, top",
                ],
            );
        }
    }
    // Set names are matched case-insensitively.
    let case = mesh_case(
        dir.path(),
        "square.inp",
        "\nfixed_clamp_set = \"BOTTOM\"\nmoving_clamp_set = \"Top\"",
        5.0,
    );
    assert!(case.build().is_ok());
}

/// docs/meshes.md: an element that is not a 3-node triangle (Abaqus S4R,
/// Gmsh type 3) is rejected naming the file and the line.
#[test]
fn quadrilaterals_are_rejected_with_file_and_line() {
    let dir = TempDir::new().unwrap();
    let inp = fs::read_to_string(sample_mesh("square.inp")).unwrap();
    let inp = edit(
        &inp,
        &[(
            "*NSET, NSET=bottom",
            "*ELEMENT, TYPE=S4R\n200, 1, 2, 7, 6\n*NSET, NSET=bottom",
        )],
    );
    write(&dir.path().join("quad.inp"), &inp);
    let line = line_of(&inp, "*ELEMENT, TYPE=S4R");
    let msg = run_error(&mesh_case(dir.path(), "quad.inp", "", 5.0), dir.path());
    assert_mentions(
        &msg,
        &[
            "non-triangle element type S4R",
            &format!("quad.inp:{line}"),
            "3-node triangles",
        ],
    );

    let msh = fs::read_to_string(sample_mesh("square.msh")).unwrap();
    let msh = edit(
        &msh,
        &[
            ("3 104 1 104", "4 105 1 105"),
            ("104 65 3 19\n", "104 65 3 19\n2 1 3 1\n105 1 5 33 32\n"),
        ],
    );
    write(&dir.path().join("quad.msh"), &msh);
    let line = line_of(&msh, "2 1 3 1");
    let msg = run_error(&mesh_case(dir.path(), "quad.msh", "", 5.0), dir.path());
    assert_mentions(
        &msg,
        &[
            "non-triangle element type 3",
            "quadrangle",
            &format!("quad.msh:{line}"),
        ],
    );
}

/// docs/meshes.md: a degenerate triangle is named by its element label.
#[test]
fn degenerate_triangle_is_named() {
    let dir = TempDir::new().unwrap();
    let inp = fs::read_to_string(sample_mesh("square.inp")).unwrap();
    let inp = edit(
        &inp,
        &[("96, 59, 65, 64\n", "96, 59, 65, 64\n97, 1, 2, 3\n")],
    );
    write(&dir.path().join("degen.inp"), &inp);
    let msg = run_error(&mesh_case(dir.path(), "degen.inp", "", 5.0), dir.path());
    assert_mentions(&msg, &["degen.inp", "element 97 is degenerate", "area 0e0"]);
}

/// docs/cases.md `[mesh] file`: only `.inp` and `.msh`; a missing file is
/// named.
#[test]
fn unsupported_or_missing_mesh_files_are_named() {
    let dir = TempDir::new().unwrap();
    write(&dir.path().join("mesh.stl"), "solid x\nendsolid x\n");
    let case = mesh_case(dir.path(), "mesh.stl", "", 5.0);
    let msg = run_error(&case, dir.path());
    assert_mentions(
        &msg,
        &[
            "case.toml",
            "mesh.file",
            "mesh.stl",
            "expected an Abaqus .inp or a Gmsh .msh file",
        ],
    );

    let case = mesh_case(dir.path(), "nothere.inp", "", 5.0);
    let msg = run_error(&case, dir.path());
    assert_mentions(&msg, &["cannot read mesh file", "nothere.inp"]);
}

/// docs/cases.md "Boundary conditions": nodes that belong to no triangle
/// (e.g. an Abaqus reference point) are fixed, so a mesh file with one
/// still runs.
#[test]
fn unconnected_nodes_are_fixed() {
    let dir = TempDir::new().unwrap();
    let inp = fs::read_to_string(sample_mesh("square.inp")).unwrap();
    let inp = edit(
        &inp,
        &[(
            "65, 100, 300, 0.\n",
            "65, 100, 300, 0.\n1000, 50, 150, 10.\n",
        )],
    );
    write(&dir.path().join("orphan.inp"), &inp);
    let case = mesh_case(dir.path(), "orphan.inp", "", 5.0);
    let summary = run(&case, &dir.path().join("out"));
    assert!(summary.complete);
}

// ---------------------------------------------------------------------------
// Boundary conditions and zones (no solve)
// ---------------------------------------------------------------------------

/// docs/cases.md "Boundary conditions" (docs/cases.md): every z fixed;
/// the `y = 0` clamp fixed in x and y; the `y = L` clamp fixed in x and
/// pulled in +y by the load parameter; nothing else constrained.
#[test]
fn clamps_and_the_in_plane_condition() {
    let case = OatCase::from_toml_str(BASE, "embedded", Path::new(".")).unwrap();
    let built = case.build().unwrap();
    let dofs = OatCase::dofs(&built);
    let mesh = &built.mesh;
    let mut expected = vec![None; 3 * mesh.nodes.len()];
    for (n, x) in mesh.nodes.iter().enumerate() {
        expected[3 * n + 2] = Some(0.0);
        if x.y.abs() < 1e-9 {
            expected[3 * n] = Some(0.0);
            expected[3 * n + 1] = Some(0.0);
        } else if (x.y - case.length).abs() < 1e-9 {
            expected[3 * n] = Some(0.0);
            expected[3 * n + 1] = Some(1.0);
        }
    }
    let mut got = vec![None; dofs.total];
    for c in &dofs.constrained {
        got[c.dof] = Some(c.per_unit_load);
    }
    assert_eq!(got, expected);
}

/// docs/cases.md "Zones and the main deformation zone": two-family
/// classification (C: the roving and the stitching line through the centroid
/// both end on a clamp; B: one does; A: neither); the MDZ is the zone-A
/// elements in the centred window, or the whole window when there is no zone A
/// (0°).
#[test]
fn zones_and_the_mdz() {
    let case = OatCase::from_toml_str(BASE, "embedded", Path::new(".")).unwrap();
    // 45°, 100 × 300 mm: the centre band is A, a clamp corner is C, a point
    // near the clamp whose stitching line ends on it is B.
    assert_eq!(case.zone_at(Vector2::new(50.0, 150.0)), Zone::A);
    assert_eq!(case.zone_at(Vector2::new(5.0, 150.0)), Zone::A);
    assert_eq!(case.zone_at(Vector2::new(50.0, 5.0)), Zone::C);
    assert_eq!(case.zone_at(Vector2::new(50.0, 295.0)), Zone::C);
    assert_eq!(case.zone_at(Vector2::new(10.0, 30.0)), Zone::B);
    let built = case.build().unwrap();
    for zone in [Zone::A, Zone::B, Zone::C] {
        assert!(built.zones.contains(&zone), "no element in zone {zone:?}");
    }
    assert!(!built.mdz.is_empty());
    for &e in &built.mdz {
        let c = built.mesh.centroid(e);
        assert_eq!(built.zones[e], Zone::A);
        assert!((c.x - 50.0).abs() <= 10.0 && (c.y - 150.0).abs() <= 10.0);
    }

    // 0°: the rovings end on the clamps everywhere, no zone A; the MDZ is
    // the window.
    let text = edit(BASE, &[("bias_angle_deg = 45.0", "bias_angle_deg = 0.0")]);
    let case = OatCase::from_toml_str(&text, "embedded", Path::new(".")).unwrap();
    let built = case.build().unwrap();
    assert!(!built.zones.contains(&Zone::A));
    let window: Vec<usize> = (0..built.mesh.triangles.len())
        .filter(|&e| {
            let c = built.mesh.centroid(e);
            (c.x - 50.0).abs() <= 10.0 && (c.y - 150.0).abs() <= 10.0
        })
        .collect();
    assert!(!window.is_empty());
    assert_eq!(built.mdz, window);
}

// ---------------------------------------------------------------------------
// 3. A run end to end
// ---------------------------------------------------------------------------

/// docs/cases.md "Outputs": a complete coarse 45° run writes every file;
/// CSV headers carry units; summary.json holds the documented keys, the
/// forces at 20 and 40 mm (positive, increasing) and agrees with the CSV;
/// one VTU per output displacement (the contour displacement included).
#[test]
fn a_coarse_45_degree_run_writes_every_output() {
    let dir = TempDir::new().unwrap();
    let text = append(
        &edit(
            BASE,
            &[(
                "displacement = 40.0",
                "displacement = 40.0\noutput_displacements = [20.0]",
            )],
        ),
        "\n[output]\ncontour_displacement = 30.0\n",
    );
    let case = load(dir.path(), &text);
    let out = dir.path().join("out");
    let summary = run(&case, &out);
    assert!(summary.complete);

    for file in [
        "force_displacement.csv",
        "force_displacement.png",
        "mdz_strains.csv",
        "mdz_strains.png",
        "contours.png",
        "oat.pvd",
        "summary.json",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    assert_eq!(png_size(&out.join("force_displacement.png")), (900, 650));
    assert_eq!(png_size(&out.join("mdz_strains.png")), (1800, 550));
    assert_eq!(png_size(&out.join("contours.png")), (1800, 1100));

    // CSVs: a commented preamble, then headers with units.
    let (preamble, header, force_rows) = read_csv(&out.join("force_displacement.csv"));
    assert_eq!(header, "displacement [mm],force [N],iterations [-]");
    assert!(preamble.contains(&"status: complete".to_string()));
    assert!(preamble.iter().any(|l| l.starts_with("units: mm, N, MPa")));
    let (_, header, strain_rows) = read_csv(&out.join("mdz_strains.csv"));
    assert_eq!(
        header,
        "displacement [mm],E22 [-],shear_angle [deg],E_perp [-]"
    );
    assert_eq!(force_rows.len(), summary.steps);
    assert_eq!(strain_rows.len(), summary.steps);
    for stop in [20.0, 30.0, 40.0] {
        assert!(
            force_rows.iter().any(|r| r[0] == stop),
            "no step lands on {stop} mm"
        );
    }

    // summary.json: the documented keys; forces at 20 and 40 mm.
    let json = read_summary(&out);
    let keys: Vec<&str> = json
        .as_object()
        .unwrap()
        .keys()
        .map(String::as_str)
        .collect();
    for key in [
        "case",
        "title",
        "complete",
        "status",
        "outputs_missing",
        "exit_status",
        "solver",
        "units",
        "material",
        "mesh",
        "forces",
        "steps",
        "newton_iterations",
        "factorisations",
        "timings",
        "output_seconds",
        "wall_seconds",
        "history",
    ] {
        assert!(keys.contains(&key), "summary.json lacks `{key}`");
    }
    assert_eq!(keys.len(), 18, "undocumented keys in {keys:?}");
    assert_eq!(json["solver"], "quasi-static");
    // docs/cases.md, "summary.json": a figure that does not apply is left
    // out, never null.
    assert!(json.get("explicit").is_none(), "{json}");
    assert_eq!(json["complete"], true);
    assert_eq!(json["status"]["status"], "complete");
    assert_eq!(json["case"], case.source.as_str());
    for key in [
        "nodes",
        "triangles",
        "unknowns",
        "nonzeros",
        "edge_deviation_deg",
        "mdz_elements",
    ] {
        assert!(json["mesh"].get(key).is_some(), "mesh.{key} missing");
    }
    for key in ["symbolic", "assembly", "factorisation", "solve"] {
        assert!(json["timings"][key].as_f64().unwrap() >= 0.0);
    }
    let forces: Vec<(f64, f64)> = json["forces"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| (p[0].as_f64().unwrap(), p[1].as_f64().unwrap()))
        .collect();
    assert_eq!(forces.len(), 2, "{forces:?}");
    assert_eq!((forces[0].0, forces[1].0), (20.0, 40.0));
    assert!(forces[0].1 > 0.0 && forces[1].1 > forces[0].1, "{forces:?}");
    assert_eq!(forces, summary.forces);
    let last = force_rows.last().unwrap();
    assert_eq!(last[0], 40.0);
    assert_eq!(last[1], forces[1].1, "CSV and summary disagree at 40 mm");
    let history = json["history"].as_array().unwrap();
    assert_eq!(history.len(), summary.steps);
    assert_eq!(history.last().unwrap()["force"].as_f64().unwrap(), last[1]);

    // VTU: one per output displacement, listed in oat.pvd, with the
    // documented fields.
    let mut vtus: Vec<String> = fs::read_dir(out.join("vtu"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    vtus.sort();
    assert_eq!(vtus.len(), case.output_displacements.len());
    assert_eq!(
        vtus,
        ["oat_d020.000.vtu", "oat_d030.000.vtu", "oat_d040.000.vtu"]
    );
    let pvd = fs::read_to_string(out.join("oat.pvd")).unwrap();
    for name in &vtus {
        assert!(pvd.contains(&format!("file=\"vtu/{name}\"")));
    }
    let vtu = fs::read_to_string(out.join("vtu/oat_d040.000.vtu")).unwrap();
    for field in [
        "displacement",
        "E22",
        "shear_angle_deg",
        "E_perp",
        "I4",
        "I6",
        "I8",
        "I11",
        "k11",
        "energy_density",
        "S_xx_yy_xy",
        "zone",
        "mdz",
    ] {
        assert!(
            vtu.contains(&format!("Name=\"{field}\"")),
            "VTU lacks {field}"
        );
    }
}

// ---------------------------------------------------------------------------
// 4. Incomplete runs
// ---------------------------------------------------------------------------

/// Checks the files of an incomplete run in `out` against `summary`;
/// returns `(load_reached, load_attempted)`.
fn check_incomplete(summary: &RunSummary, out: &Path) -> (f64, f64) {
    assert!(!summary.complete);
    let RunStatus::Incomplete {
        load_reached,
        load_attempted,
        reason,
    } = &summary.status
    else {
        panic!("expected an incomplete status, got {:?}", summary.status);
    };
    assert!(!reason.is_empty());
    let json = read_summary(out);
    assert_eq!(json["complete"], false);
    assert_eq!(json["status"]["status"], "incomplete");
    assert_eq!(json["status"]["load_reached"].as_f64(), Some(*load_reached));
    assert_eq!(
        json["status"]["load_attempted"].as_f64(),
        Some(*load_attempted)
    );
    assert_eq!(json["status"]["reason"].as_str(), Some(reason.as_str()));
    for csv in ["force_displacement.csv", "mdz_strains.csv"] {
        let (preamble, _, rows) = read_csv(&out.join(csv));
        let status = preamble
            .iter()
            .find(|l| l.starts_with("status:"))
            .expect("a status line");
        assert_mentions(
            status,
            &[
                "INCOMPLETE",
                &format!("stopped at d = {load_reached} mm"),
                &format!("the step to {load_attempted} mm failed"),
                reason,
            ],
        );
        assert_eq!(rows.len(), summary.steps);
        if let Some(last) = rows.last() {
            assert_eq!(last[0], *load_reached);
        }
    }
    assert!(out.join("force_displacement.png").is_file());
    assert!(out.join("mdz_strains.png").is_file());
    (*load_reached, *load_attempted)
}

/// docs/cases.md "Incomplete runs and exit codes": a solve that fails in its
/// first step (one Newton iteration allowed, no cut-back below 0.5 mm) is
/// marked incomplete, names the displacement and still writes the CSVs and
/// summary.json.
#[test]
fn a_run_that_fails_at_once_is_marked_incomplete() {
    let dir = TempDir::new().unwrap();
    let text = append(
        BASE,
        "\n[solver]\nmax_iterations = 1\nmin_increment = 0.5\ninitial_increment = 5.0\n",
    );
    let case = load(dir.path(), &text);
    let out = dir.path().join("out");
    let summary = run(&case, &out);
    let (reached, attempted) = check_incomplete(&summary, &out);
    assert_eq!(reached, 0.0);
    assert!(attempted > 0.0 && attempted <= 5.0);
    assert_eq!(summary.steps, 0);
    assert!(summary.forces.is_empty());
    check_largest_residual(&summary, &case);
}

/// The reason of a run stopped by "no convergence" names the largest
/// residual component and where it is (docs/solver.md, "Newton"): a node
/// of the specimen by its mesh label, at its reference position, which
/// must be that node's (to the two decimals printed), with a value between
/// the residual norm over √(3 × nodes) and the norm itself (the bounds of
/// the largest component of a vector by its 2-norm; 3 × nodes is at least
/// the number of free dofs).
fn check_largest_residual(summary: &RunSummary, case: &OatCase) {
    let RunStatus::Incomplete { reason, .. } = &summary.status else {
        panic!("{:?}", summary.status);
    };
    let number = |text: &str| -> f64 {
        let end = text
            .find(|c: char| !(c.is_ascii_digit() || "+-.e".contains(c)))
            .unwrap_or(text.len());
        text[..end]
            .parse()
            .unwrap_or_else(|_| panic!("a number at `{text}` in {reason}"))
    };
    let after = |key: &str| {
        &reason[reason
            .find(key)
            .unwrap_or_else(|| panic!("`{key}` in {reason}"))
            + key.len()..]
    };
    let residual = number(after("(residual "));
    let largest = number(after("largest residual "));
    let label = number(after(" at node ")) as i64;
    let position = after("(reference (");
    let coordinates: Vec<f64> = position[..position.find(')').unwrap()]
        .split(", ")
        .map(number)
        .collect();
    assert!(after(" at node ").contains("of the specimen"), "{reason}");
    let built = case.build().unwrap();
    let node = (0..built.mesh.nodes.len())
        .find(|&n| built.mesh.node_label(n) == label)
        .unwrap_or_else(|| panic!("no node {label}: {reason}"));
    let x = built.mesh.nodes[node];
    for (k, c) in coordinates.iter().enumerate() {
        assert!(
            (c - x[k]).abs() <= 0.005 + 1e-12,
            "node {label} is at {x:?}: {reason}"
        );
    }
    let free = 3 * built.mesh.nodes.len();
    // The printed values carry four significant digits: 1e-3 relative.
    assert!(largest <= residual * (1.0 + 1e-3), "{reason}");
    assert!(
        largest >= residual / (free as f64).sqrt() * (1.0 - 1e-3),
        "{reason}"
    );
}

/// docs/cases.md "Incomplete runs and exit codes": a solve that fails midway
/// keeps every converged step (CSV rows, VTUs reached, forces reached) and
/// marks the results incomplete. The knobs force a 20 → 40 mm step that cannot
/// be cut back (min_increment 5 mm, cutback 0.1).
#[test]
fn a_run_that_fails_midway_keeps_the_converged_steps() {
    let dir = TempDir::new().unwrap();
    let text = append(
        &edit(
            BASE,
            &[(
                "displacement = 40.0",
                "displacement = 40.0\noutput_displacements = [20.0]",
            )],
        ),
        "\n[solver]\nmax_iterations = 7\nmin_increment = 5.0\ninitial_increment = 0.5\n\
         max_increment = 40.0\ngrowth = 3.0\neasy_iterations = 8\ncutback = 0.1\n",
    );
    let case = load(dir.path(), &text);
    let out = dir.path().join("out");
    let summary = run(&case, &out);
    let (reached, attempted) = check_incomplete(&summary, &out);
    assert!(
        (20.0..40.0).contains(&reached) && attempted > reached,
        "tuned to fail between 20 and 40 mm; got {reached} → {attempted}"
    );
    assert!(summary.steps > 0);
    assert_eq!(summary.forces.len(), 1);
    assert_eq!(summary.forces[0].0, 20.0);
    assert!(out.join("vtu/oat_d020.000.vtu").is_file());
    assert!(!out.join("vtu/oat_d040.000.vtu").exists());
    assert!(out.join("contours.png").is_file());
}

/// docs/cases.md "Incomplete runs and exit codes": `ncform run` exits with 0
/// when complete, 3 when incomplete (results written), 1 on bad input with
/// `error: …` on stderr (tests/run_folder.rs checks the other codes).
#[test]
fn exit_codes() {
    let dir = TempDir::new().unwrap();
    let ncform = env!("CARGO_BIN_EXE_ncform");
    let short = edit(BASE, &[("displacement = 40.0", "displacement = 5.0")]);
    let cases = [
        ("ok.toml", short.clone(), 0),
        (
            "incomplete.toml",
            append(
                &short,
                "\n[solver]\nmax_iterations = 1\nmin_increment = 0.5\ninitial_increment = 5.0\n",
            ),
            3,
        ),
        (
            "bad.toml",
            edit(BASE, &[("width = 100.0", "width = -1.0")]),
            1,
        ),
    ];
    for (name, text, code) in cases {
        let path = write(&dir.path().join(name), &text);
        let out = dir.path().join(format!("out-{name}"));
        let output = Command::new(ncform)
            .arg("run")
            .arg(&path)
            .arg("--out")
            .arg(&out)
            .arg("--quiet")
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(code), "{name}: {stderr}");
        match code {
            0 => assert!(stderr.is_empty(), "{stderr}"),
            3 => {
                assert_mentions(&stderr, &["error: the solve failed", "marked incomplete"]);
                assert!(out.join("summary.json").is_file());
            }
            _ => {
                assert!(stderr.starts_with("error: "), "{stderr}");
                assert_mentions(&stderr, &["bad.toml:4: specimen.width = -1"]);
                assert!(!out.exists());
            }
        }
    }
}

// ---------------------------------------------------------------------------
// 5. Mesh files end to end
// ---------------------------------------------------------------------------

/// docs/cases.md `[mesh] file` (docs/meshes.md "Sample files"): the same
/// strip read from `square.inp` and from `square.msh` (relative paths from
/// the case file's folder) gives the same force, and so does the generated
/// 4 × 12 grid of the same triangles.
#[test]
fn inp_msh_and_generated_meshes_give_the_same_force() {
    let dir = TempDir::new().unwrap();
    let meshes = dir.path().join("meshes");
    fs::create_dir_all(&meshes).unwrap();
    fs::copy(sample_mesh("square.inp"), meshes.join("square.inp")).unwrap();
    fs::copy(sample_mesh("square.msh"), meshes.join("square.msh")).unwrap();
    let force = |case: &OatCase, name: &str| {
        let summary = run(case, &dir.path().join(name));
        assert!(summary.complete, "{name}: {:?}", summary.status);
        assert_eq!(summary.mesh.triangles, 96);
        assert_eq!(summary.forces.len(), 1);
        summary.forces[0].1
    };
    let inp = force(
        &mesh_case(dir.path(), "meshes/square.inp", "", 20.0),
        "out-inp",
    );
    let msh = force(
        &mesh_case(dir.path(), "meshes/square.msh", "", 20.0),
        "out-msh",
    );
    let text = edit(
        BASE,
        &[
            ("element_size = 15.0", "nx = 4\nny = 12"),
            ("displacement = 40.0", "displacement = 20.0"),
        ],
    );
    let generated = force(&load(dir.path(), &text), "out-generated");
    assert!(inp > 0.0);
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    assert!(rel(msh, inp) <= 1e-9, "inp {inp} N, msh {msh} N");
    assert!(
        rel(generated, inp) <= 1e-9,
        "inp {inp} N, generated {generated} N"
    );
}

/// docs/explicit.md "The cross-check", on a coarse mesh: the 45° OAT run
/// explicitly (default clamp speed, smooth step) gives the quasi-static
/// clamp force and MDZ strains within 2 % RMS of their peaks over 0–80 mm
/// (the required criterion), with KE below 1 % of IE from 10 % of the stroke
/// on, and writes the same outputs plus the energy history.
#[test]
fn explicit_45_degree_run_matches_the_quasi_static_one() {
    let dir = TempDir::new().unwrap();
    let text = edit(
        BASE,
        &[
            ("element_size = 15.0", "element_size = 10.0"),
            ("displacement = 40.0", "displacement = 80.0"),
        ],
    );
    let quasi_static = load(dir.path(), &text);
    let explicit = load(
        dir.path(),
        &edit(&text, &[("title = ", "solver = \"explicit\"\ntitle = ")]),
    );
    let (qs_out, ex_out) = (dir.path().join("qs"), dir.path().join("ex"));
    let qs = run(&quasi_static, &qs_out);
    let ex = run(&explicit, &ex_out);
    assert!(qs.complete && ex.complete);

    // RMS of the explicit curve (linear interpolation between its rows,
    // every 0.5 mm) at the quasi-static displacements, over the peak.
    let rms_over_peak = |reference: &[(f64, f64)], curve: &[(f64, f64)]| {
        let interpolate = |d: f64| {
            let k = curve.partition_point(|p| p.0 < d).clamp(1, curve.len() - 1);
            let ((d0, y0), (d1, y1)) = (curve[k - 1], curve[k]);
            y0 + (y1 - y0) * (d - d0) / (d1 - d0)
        };
        let peak = reference.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
        let sum: f64 = reference
            .iter()
            .map(|&(d, y)| (interpolate(d) - y).powi(2))
            .sum();
        (sum / reference.len() as f64).sqrt() / peak
    };
    type Pick = fn(&ncform::report::rows::HistoryRow) -> f64;
    let columns: [(&str, Pick); 4] = [
        ("force", |h| h.force),
        ("E22", |h| h.mdz_e22),
        ("shear angle", |h| h.mdz_shear_angle_deg),
        ("E_perp", |h| h.mdz_e_perp),
    ];
    for (name, pick) in columns {
        let curve = |s: &RunSummary| -> Vec<(f64, f64)> {
            std::iter::once((0.0, 0.0))
                .chain(s.history.iter().map(|h| (h.displacement, pick(h))))
                .collect()
        };
        let error = rms_over_peak(&curve(&qs)[1..], &curve(&ex));
        println!("{name}: RMS difference {:.3} % of the peak", 100.0 * error);
        assert!(error <= 0.02, "{name}: {:.3} % > 2 %", 100.0 * error);
    }
    let summary = ex.explicit.as_ref().expect("explicit figures");
    println!(
        "KE/IE max {:.3} %, balance {:.1e}, {} increments",
        100.0 * summary.max_kinetic_ratio,
        summary.max_relative_balance_error,
        summary.increments
    );
    assert!(summary.max_kinetic_ratio < 0.01);
    assert!(summary.warnings.is_empty(), "{:?}", summary.warnings);
    // 1 %: the level at which an energy error would show in the curves
    // compared above (docs/explicit.md, "Energy accounting").
    assert!(summary.max_relative_balance_error < 0.01);

    // Same files as the quasi-static run, plus the energy history.
    let listing = |d: &Path| {
        let mut names: Vec<String> = fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        names
    };
    let mut expected = listing(&qs_out);
    expected.extend(["energy.csv".to_string(), "energy.png".to_string()]);
    expected.sort();
    assert_eq!(listing(&ex_out), expected);
    assert_eq!(listing(&qs_out.join("vtu")), listing(&ex_out.join("vtu")));
    let (preamble, header, rows) = read_csv(&ex_out.join("energy.csv"));
    assert!(preamble.iter().any(|l| l.starts_with("units:")));
    assert!(header.starts_with("time [s],displacement [mm],internal [N*mm],kinetic [N*mm]"));
    assert_eq!(rows.len(), ex.steps);
    let (_, header, _) = read_csv(&ex_out.join("force_displacement.csv"));
    assert_eq!(
        header,
        "displacement [mm],force [N],time [s],increments [-]"
    );
    let json = read_summary(&ex_out);
    assert_eq!(json["solver"], "explicit");
    for key in [
        "increments",
        "element_cycles_per_second",
        "initial_critical_time_step",
        "mass",
        "max_kinetic_ratio",
        "max_relative_balance_error",
        "final_energies",
        "warnings",
    ] {
        assert!(
            json["explicit"].get(key).is_some(),
            "explicit.{key} missing"
        );
    }
    assert_eq!(png_size(&ex_out.join("energy.png")), (1800, 550));
}

/// docs/cases.md `[explicit]`: bad explicit settings name the file, the
/// line, the key, the value and what was expected.
#[test]
fn explicit_settings_are_checked() {
    let explicit = edit(BASE, &[("title = ", "solver = \"explicit\"\ntitle = ")]);
    let cases: Vec<(String, &str, &str)> = vec![
        (
            edit(BASE, &[("title = ", "solver = \"implicit\"\ntitle = ")]),
            "solver = ",
            "solver = \"implicit\": expected \"quasi-static\", \"explicit\"",
        ),
        (
            append(&explicit, "\n[explicit]\ntime_step = 0.0\n"),
            "time_step = ",
            "explicit.time_step = 0: expected a time step > 0 s",
        ),
        (
            append(&explicit, "\n[explicit]\nsafety_factor = 1.5\n"),
            "safety_factor = ",
            "explicit.safety_factor = 1.5: expected a factor in (0, 1]",
        ),
        (
            append(&explicit, "\n[explicit]\nclamp_speed = -5.0\n"),
            "clamp_speed = ",
            "explicit.clamp_speed = -5: expected a speed > 0 mm/s",
        ),
        (
            append(
                &explicit,
                "\n[explicit]\nclamp_speed = 5.0\nduration = 1.0\n",
            ),
            "duration = ",
            "either explicit.clamp_speed or explicit.duration, not both",
        ),
        (
            append(&explicit, "\n[explicit]\ndamping = -1.0\n"),
            "damping = ",
            "explicit.damping = -1: expected a coefficient ≥ 0 1/s",
        ),
        (
            append(&explicit, "\n[explicit]\nroving_mass_length = 2000.0\n"),
            "roving_mass_length = ",
            "explicit.roving_mass_length = 2000: expected a length in [0, 1000] mm",
        ),
        (
            append(
                &explicit,
                "\n[explicit]\nroving_mass_length = 6.5\nroving_mass_coupling = \"along\"\n",
            ),
            "roving_mass_coupling = ",
            "explicit.roving_mass_coupling = \"along\": expected \"stretch\" or \"full\"",
        ),
        (
            append(
                &explicit,
                "\n[explicit]\nroving_mass_length = 6.5\ndamping = 5.0\n",
            ),
            "damping = ",
            "explicit.damping = 5: expected 0 with explicit.roving_mass_length",
        ),
        (
            append(&explicit, "\n[explicit]\nthreads = -1\n"),
            "threads = ",
            "explicit.threads = -1: expected a count in 0..=1000000",
        ),
        (
            append(&explicit, "\n[material]\nareal_mass = -0.3\n"),
            "areal_mass = ",
            "material.areal_mass = -0.3: expected an areal mass > 0 kg/m²",
        ),
        (
            append(&explicit, "\n[material]\ndensity = 0.0\n"),
            "density = ",
            "material.density = 0: expected a density > 0 t/mm³",
        ),
        (
            append(&explicit, "\n[explicit]\nspeed = 5.0\n"),
            "speed = ",
            "unknown field `speed`",
        ),
    ];
    for (text, key, expected) in cases {
        let (msg, file) = case_error(&text);
        let line = line_of(&text, key);
        // Range errors read `file:line: key = value: …`; the parser's own
        // (unknown keys) `… line N …`.
        let at_line =
            msg.contains(&format!("{file}:{line}:")) || msg.contains(&format!("line {line}"));
        assert!(at_line, "message `{msg}` does not name line {line}");
        assert_mentions(&msg, &[&file, expected]);
    }

    // A parameter file carries no mass: an explicit run must be told it.
    let dir = TempDir::new().unwrap();
    let params = fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/materials/schaefer2024.toml"),
    )
    .unwrap();
    write(&dir.path().join("fabric.toml"), &params);
    let with_file = append(&explicit, "\n[material]\nparams = \"fabric.toml\"\n");
    let (msg, file) = case_error_in(dir.path(), &with_file);
    assert_mentions(
        &msg,
        &[&file, "material.areal_mass = (missing)", "explicit solver"],
    );
    // The same file with an areal mass, or run quasi-statically, is fine.
    load(
        dir.path(),
        &append(
            &explicit,
            "\n[material]\nparams = \"fabric.toml\"\nareal_mass = 0.3\n",
        ),
    );
    let quasi_static = load(
        dir.path(),
        &append(BASE, "\n[material]\nparams = \"fabric.toml\"\n"),
    );
    assert_eq!(quasi_static.density, None);
    // 0.30 kg/m² at 0.3 mm is 1.0e-9 t/mm³ (docs/theory.md).
    let default = load(dir.path(), &explicit);
    assert!((default.density.unwrap() - 1.0e-9).abs() <= 1e-24);
}

/// docs/cases.md, `[explicit]`: the roving mass coupling is the stretch
/// form unless the case asks for the full one (`"full"`), and the key is
/// taken only with those two spellings (the refusals are in
/// `explicit_settings_are_checked`).
#[test]
fn roving_mass_coupling_defaults_to_the_stretch_form() {
    use ncform::element::RovingCoupling;
    let base = format!("{BASE}\n[explicit]\nroving_mass_length = 6.5\n");
    let case = OatCase::from_toml_str(&base, "embedded", Path::new(".")).unwrap();
    assert_eq!(case.explicit.roving_mass_length, 6.5);
    assert_eq!(case.explicit.roving_mass_coupling, RovingCoupling::Stretch);
    let full = format!("{base}roving_mass_coupling = \"full\"\n");
    let case = OatCase::from_toml_str(&full, "embedded", Path::new(".")).unwrap();
    assert_eq!(case.explicit.roving_mass_coupling, RovingCoupling::Full);
}
