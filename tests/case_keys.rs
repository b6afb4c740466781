//! The case keys' ranges, applicability and messages (`docs/cases.md`,
//! "Ranges" and "Keys that do not apply"; `docs/robustness.md`, "Checked
//! where the value enters"): hard bounds refused at parse time with file,
//! line, key, value and range; unusual values warned about without
//! blocking the build; keys the shape, motion or solver does not take
//! refused with the keys it does; errors of the files a case points to
//! naming the case's line; readable numbers; inside-out tool meshes
//! oriented with a warning; advice naming only keys the case format takes.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

use ncform::case::Case;
use ncform::case::bounds::BOUNDS;
use tempfile::TempDir;

/// A small forming case: a 20 × 20 mm ply on a table under a floating
/// plate, quasi-static. Every edit below replaces one of its lines.
const FORMING: &str = r#"title = "keys"

[[ply]]
name = "p"
thickness = 0.3
areal_mass = 0.30

[ply.mesh]
shape = "rectangle"
size = [20.0, 20.0]
centre = [0.0, 0.0, 0.15]
element_size = 5.0

[[tool]]
name = "table"
shape = "plane"
friction = 0.147

[[tool]]
name = "plate"
shape = "plane"
origin = [0.0, 0.0, 0.3]
axis = [0.0, 0.0, -1.0]
motion = "floating"
direction = [0.0, 0.0, -1.0]
mass = 1.0
"#;

/// A small OAT.
const OAT: &str = r#"title = "keys"

[specimen]
width = 100.0
length = 300.0
bias_angle_deg = 45.0

[mesh]
element_size = 20.0

[material]
params = "schaefer2024"
thickness = 0.3

[loading]
displacement = 40.0
"#;

/// [`FORMING`] for the explicit solver; its `[explicit]` table is last,
/// so that keys can be appended to it.
fn explicit_forming() -> String {
    edit(
        FORMING,
        "title = \"keys\"",
        "title = \"keys\"\nsolver = \"explicit\"",
    ) + "\n[explicit]\nduration = 0.1\n"
}

fn edit(base: &str, from: &str, to: &str) -> String {
    assert!(base.contains(from), "`{from}` not in the case text");
    base.replacen(from, to, 1)
}

fn write(path: &Path, text: &[u8]) -> PathBuf {
    fs::write(path, text).unwrap();
    path.to_path_buf()
}

/// 1-based line of the first line of `text` that starts with `prefix`.
fn line_of(text: &str, prefix: &str) -> usize {
    text.lines()
        .position(|l| l.trim_start().starts_with(prefix))
        .unwrap_or_else(|| panic!("no line starting with `{prefix}`"))
        + 1
}

fn load(dir: &Path, text: &str) -> Result<Case, String> {
    let path = write(&dir.join("case.toml"), text.as_bytes());
    Case::load(&path).map_err(|e| e.to_string())
}

fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message `{msg}` lacks `{p}`");
    }
}

/// Longest run of digits in `msg` (a number printed with hundreds of
/// digits has a run of hundreds).
fn longest_digit_run(msg: &str) -> usize {
    msg.split(|c: char| !c.is_ascii_digit())
        .map(str::len)
        .max()
        .unwrap_or(0)
}

/// Hard bounds: a value that is impossible or overflows the computation is
/// refused at parse time with the case file, the line, the key, the value
/// and the admissible range as `docs/cases.md` states it (the ranges come
/// from `src/case/bounds.rs`).
#[test]
fn hard_bounds_name_file_line_key_value_and_range() {
    let dir = TempDir::new().unwrap();
    let explicit = explicit_forming();
    let cases: &[(String, &str, &str, &[&str])] = &[
        (
            edit(FORMING, "friction = 0.147", "friction = 1e6"),
            "friction = ",
            "tool[0].friction = 1000000",
            &["[0, 10]"],
        ),
        (
            edit(FORMING, "friction = 0.147", "friction = 1e308"),
            "friction = ",
            "tool[0].friction = 1e308",
            &["[0, 10]"],
        ),
        (
            edit(FORMING, "areal_mass = 0.30", "areal_mass = 1e308"),
            "areal_mass",
            "ply[0].areal_mass = 1e308",
            &["[1e-4, 1000] kg/m²"],
        ),
        (
            edit(FORMING, "areal_mass = 0.30", "areal_mass = 1e-308"),
            "areal_mass",
            "ply[0].areal_mass = 1e-308",
            &["[1e-4, 1000] kg/m²"],
        ),
        (
            edit(
                FORMING,
                "areal_mass = 0.30",
                "areal_mass = 0.30\nbending = { b11 = 1e308 }",
            ),
            "bending",
            "ply[0].bending.b11 = 1e308",
            &["[0, 1e9] N·mm"],
        ),
        (
            FORMING.to_string() + "\n[contact]\noffset = 1e308\n",
            "offset",
            "contact.offset = 1e308",
            &["[0, 1000] mm"],
        ),
        (
            explicit.clone() + "mass_scaling_time_step = 1e308\n",
            "mass_scaling_time_step",
            "explicit.mass_scaling_time_step = 1e308",
            &["(0, 1] s"],
        ),
        (
            edit(FORMING, "mass = 1.0", "mass = 1e300"),
            "mass = ",
            "tool[1].mass = 1e300",
            &["(0, 1e6] kg"],
        ),
        (
            edit(FORMING, "size = [20.0, 20.0]", "size = [20.0, 1e300]"),
            "size",
            "ply[0].mesh.size = [20, 1e300]",
            &["(0, 1e6] mm"],
        ),
        (
            edit(
                FORMING,
                "origin = [0.0, 0.0, 0.3]",
                "origin = [0.0, 1e7, 0.3]",
            ),
            "origin",
            "tool[1].origin",
            &["[-1e6, 1e6] mm"],
        ),
        (
            edit(OAT, "thickness = 0.3", "thickness = 5000.0"),
            "thickness",
            "material.thickness = 5000",
            &["(0, 1000] mm"],
        ),
        (
            edit(
                OAT,
                "thickness = 0.3",
                "thickness = 0.3\nareal_mass = 1e-308",
            ),
            "areal_mass",
            "material.areal_mass = 1e-308",
            &["[1e-4, 1000] kg/m²"],
        ),
        (
            edit(
                OAT,
                "element_size = 20.0",
                "element_size = 20.0\n\n[solver]\nresidual_tolerance = 2.0",
            ),
            "residual_tolerance",
            "solver.residual_tolerance = 2",
            &["(0, 1)"],
        ),
    ];
    for (text, line_prefix, key_value, range) in cases {
        let msg = load(dir.path(), text).expect_err(key_value);
        let line = line_of(text, line_prefix);
        assert_mentions(&msg, &["case.toml", &format!(":{line}:"), key_value]);
        assert_mentions(&msg, range);
        assert!(longest_digit_run(&msg) <= 17, "{msg}");
    }
}

/// Plausibility: a value inside the hard range but outside the usual one
/// (`μ = 1.47` for 0.147, an areal mass in g/m², a 50 mm thickness) is a
/// warning — file, line, key, value, usual range, hint — and the case
/// still loads and builds.
#[test]
fn unusual_values_warn_without_blocking_the_build() {
    let dir = TempDir::new().unwrap();
    let text = edit(
        &edit(
            &edit(FORMING, "friction = 0.147", "friction = 1.47"),
            "areal_mass = 0.30",
            "areal_mass = 300.0",
        ),
        "thickness = 0.3",
        "thickness = 50.0",
    );
    let case = load(dir.path(), &text).unwrap();
    let warnings: Vec<String> = case.warnings().iter().map(ToString::to_string).collect();
    assert_eq!(warnings.len(), 3, "{warnings:#?}");
    let find = |key: &str| {
        warnings
            .iter()
            .find(|w| w.contains(key))
            .unwrap_or_else(|| panic!("no warning on {key}: {warnings:#?}"))
            .clone()
    };
    let mu = find("tool[0].friction");
    assert_mentions(
        &mu,
        &[
            &format!("case.toml:{}:", line_of(&text, "friction")),
            "= 1.47",
            "usual range [0.05, 1]",
            "0.147",
        ],
    );
    let mass = find("ply[0].areal_mass");
    assert_mentions(&mass, &["= 300", "[0.05, 5] kg/m²", "g/m²"]);
    let t = find("ply[0].thickness");
    assert_mentions(&t, &["= 50", "[0.05, 5] mm"]);
    let Case::Forming(forming) = case else {
        panic!("a forming case")
    };
    forming.build().expect("warnings do not block the build");

    // The usual range is a warning only: the hard range still refuses.
    let msg = load(
        dir.path(),
        &edit(FORMING, "friction = 0.147", "friction = 11.0"),
    )
    .unwrap_err();
    assert_mentions(&msg, &["tool[0].friction = 11", "[0, 10]"]);

    // 0 switches a quantity off and is never unusual.
    let frictionless = load(
        dir.path(),
        &edit(FORMING, "friction = 0.147", "friction = 0.0"),
    )
    .unwrap();
    assert!(frictionless.warnings().is_empty());

    // An OAT too, and an [explicit] table the quasi-static solver does not
    // use.
    let oat = edit(
        OAT,
        "thickness = 0.3",
        "thickness = 0.3\nareal_mass = 200.0",
    ) + "\n[explicit]\nclamp_speed = 50.0\n";
    let case = load(dir.path(), &oat).unwrap();
    let warnings: Vec<String> = case.warnings().iter().map(ToString::to_string).collect();
    assert_eq!(warnings.len(), 3, "{warnings:#?}");
    let find = |part: &str| warnings.iter().find(|w| w.contains(part)).unwrap().clone();
    assert_mentions(
        &find("usual range [0.05, 5] kg/m²"),
        &["material.areal_mass = 200"],
    );
    assert_mentions(
        &find("does not use the mass"),
        &["material.areal_mass = 200", "quasi-static"],
    );
    assert_mentions(
        &find("[explicit] = "),
        &[
            &format!("case.toml:{}:", line_of(&oat, "[explicit]")),
            "[explicit]",
            "quasi-static",
        ],
    );
}

/// Keys that do not apply to the ply mesh's shape, the tool's shape or
/// motion, or the solver are refused, naming the keys that do apply.
#[test]
fn keys_that_do_not_apply_are_refused_with_those_that_do() {
    let dir = TempDir::new().unwrap();
    let disk = edit(
        FORMING,
        "shape = \"rectangle\"\nsize = [20.0, 20.0]",
        "shape = \"disk\"\nradius = 10.0",
    );
    let explicit = explicit_forming();
    let cases: &[(String, &str, &str, &str)] = &[
        (
            edit(
                FORMING,
                "element_size = 5.0",
                "element_size = 5.0\nwidth = 0",
            ),
            "width = 0",
            "ply[0].mesh.width = 0",
            "shape, size, centre, element_size, cells, pattern",
        ),
        (
            edit(
                &disk,
                "element_size = 5.0",
                "element_size = 5.0\nsize = [0, 0]",
            ),
            "size = [0, 0]",
            "ply[0].mesh.size = [0, 0]",
            "shape, radius, centre, element_size",
        ),
        (
            edit(
                &disk,
                "element_size = 5.0",
                "element_size = 5.0\ntail_length = nan",
            ),
            "tail_length",
            "ply[0].mesh.tail_length = nan",
            "shape, radius, centre, element_size",
        ),
        (
            edit(
                FORMING,
                "element_size = 5.0",
                "element_size = 5.0\nradius = 0",
            ),
            "radius = 0",
            "ply[0].mesh.radius = 0",
            "shape, size, centre, element_size, cells, pattern",
        ),
        (
            edit(
                FORMING,
                "shape = \"rectangle\"\nsize = [20.0, 20.0]\ncentre = [0.0, 0.0, 0.15]\nelement_size = 5.0",
                "file = \"p.inp\"\ncentre = [0.0, 0.0, 0.15]",
            ),
            "centre",
            "ply[0].mesh.centre = [0, 0, 0.15]",
            "which takes only: file",
        ),
        (
            edit(
                FORMING,
                "friction = 0.147",
                "friction = 0.147\ndirection = [0, 0, 0]",
            ),
            "direction = [0, 0, 0]",
            "tool[0].direction = [0, 0, 0]",
            "motion \"fixed\" (a tool that does not move takes none of direction, displacement, mass, weight)",
        ),
        (
            edit(FORMING, "mass = 1.0", "mass = 1.0\ndisplacement = 5.0"),
            "displacement",
            "tool[1].displacement = 5",
            "direction, mass, weight",
        ),
        (
            edit(FORMING, "friction = 0.147", "friction = 0.147\nradius = 0"),
            "radius = 0",
            "tool[0].radius = 0",
            "shape \"plane\", which takes only: origin, axis, extent",
        ),
        (
            FORMING.to_string() + "\n[contact]\nexplicit_damping = 0.5\n",
            "explicit_damping",
            "contact.explicit_damping = 0.5",
            "the quasi-static solver, which takes only: offset, penalty",
        ),
        (
            explicit.clone() + "\n[contact]\npenalty_scale = 2.0\n",
            "penalty_scale",
            "contact.penalty_scale = 2",
            "the explicit solver, which takes only: offset, explicit_stiffness",
        ),
    ];
    for (text, line_prefix, key_value, takes) in cases {
        let msg = load(dir.path(), text).expect_err(key_value);
        let line = line_of(text, line_prefix);
        assert_mentions(&msg, &["case.toml", &format!(":{line}:"), key_value, takes]);
    }
}

/// The error of a forming case's build, which must fail.
fn forming_build_error(case: &ncform::case::forming::FormingCase) -> String {
    match case.build() {
        Ok(_) => panic!("the build should fail"),
        Err(e) => e.to_string(),
    }
}

/// Errors of the files a case points to — parameter files, ply and OAT
/// mesh files, tool meshes — name the case's line and key first.
#[test]
fn errors_of_referenced_files_name_the_case_line() {
    let dir = TempDir::new().unwrap();
    write(&dir.path().join("fabric.toml"), b"");
    let text = edit(
        FORMING,
        "thickness = 0.3",
        "params = \"fabric.toml\"\nthickness = 0.3",
    );
    let msg = load(dir.path(), &text).unwrap_err();
    assert_mentions(
        &msg,
        &[
            &format!(
                "case.toml:{}: ply[0].params = \"fabric.toml\": ",
                line_of(&text, "params")
            ),
            "fabric.toml: ",
        ],
    );
    let oat = edit(OAT, "params = \"schaefer2024\"", "params = \"fabric.toml\"");
    let msg = load(dir.path(), &oat).unwrap_err();
    assert_mentions(
        &msg,
        &[&format!(
            "case.toml:{}: material.params = \"fabric.toml\": ",
            line_of(&oat, "params")
        )],
    );
    let msg = load(
        dir.path(),
        &edit(OAT, "\"schaefer2024\"", "\"missing.toml\""),
    )
    .unwrap_err();
    assert_mentions(
        &msg,
        &[
            "case.toml:",
            "material.params = \"missing.toml\"",
            "missing.toml",
        ],
    );

    // A ply's mesh file and an OAT's, read when the model is built.
    write(&dir.path().join("bad.inp"), b"*NODE\n1, 0, 0\n2, x, 0\n");
    let text = edit(
        FORMING,
        "shape = \"rectangle\"\nsize = [20.0, 20.0]\ncentre = [0.0, 0.0, 0.15]\nelement_size = 5.0",
        "file = \"bad.inp\"",
    );
    let Case::Forming(case) = load(dir.path(), &text).unwrap() else {
        panic!("forming")
    };
    let msg = forming_build_error(&case);
    assert_mentions(
        &msg,
        &[
            &format!("case.toml:{}: ply \"p\"", line_of(&text, "file")),
            "bad.inp",
        ],
    );
    let oat = edit(OAT, "element_size = 20.0", "file = \"bad.inp\"");
    let Case::Oat(case) = load(dir.path(), &oat).unwrap() else {
        panic!("oat")
    };
    let msg = case.build().unwrap_err().to_string();
    assert_mentions(
        &msg,
        &[
            "case.toml: mesh.file = ",
            &format!("bad.inp\" (line {}): ", line_of(&oat, "file")),
        ],
    );

    // A tool's mesh file.
    write(
        &dir.path().join("bad.stl"),
        b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 nope\n",
    );
    let text = edit(
        FORMING,
        "name = \"table\"\nshape = \"plane\"",
        "name = \"table\"\nshape = \"mesh\"\nfile = \"bad.stl\"",
    );
    let Case::Forming(case) = load(dir.path(), &text).unwrap() else {
        panic!("forming")
    };
    let msg = forming_build_error(&case);
    assert_mentions(
        &msg,
        &[
            &format!(
                "case.toml:{}: tool \"table\"",
                line_of(&text, "file = \"bad.stl\"")
            ),
            "bad.stl",
        ],
    );
}

/// A case or parameter file that is not UTF-8 is named with the line and
/// the column (byte) of the first bad byte; OAT and forming cases alike.
#[test]
fn non_utf8_files_give_line_and_column() {
    let dir = TempDir::new().unwrap();
    for base in [OAT, FORMING] {
        let mut bytes = base.as_bytes().to_vec();
        // After `title = "k` on line 1: byte 11 of the line.
        bytes.insert(10, 0xff);
        let path = write(&dir.path().join("case.toml"), &bytes);
        let msg = Case::load(&path).unwrap_err().to_string();
        assert_mentions(&msg, &["case.toml", "line 1, byte 11", "not UTF-8"]);
    }
    write(
        &dir.path().join("fabric.toml"),
        b"law = \"svk\"\n\n[svk]\ne1 = 1\xff\n",
    );
    let text = edit(
        FORMING,
        "thickness = 0.3",
        "params = \"fabric.toml\"\nthickness = 0.3",
    );
    let msg = load(dir.path(), &text).unwrap_err();
    assert_mentions(
        &msg,
        &[
            &format!("case.toml:{}: ply[0].params", line_of(&text, "params")),
            "fabric.toml: line 4, byte 7",
        ],
    );
}

/// Numbers in messages carry the digits that matter: a radius of 1e300
/// (once printed as 301 digits by the tessellation) is `1e300`.
#[test]
fn numbers_in_messages_are_readable() {
    let dir = TempDir::new().unwrap();
    let texts = [
        edit(
            FORMING,
            "name = \"table\"\nshape = \"plane\"",
            "name = \"table\"\nshape = \"plate-with-hole\"\nopening_radius = 1e300\nfillet_radius = 5.0",
        ),
        edit(FORMING, "element_size = 5.0", "element_size = 1e300"),
        edit(OAT, "width = 100.0", "width = 1e300"),
        edit(FORMING, "mass = 1.0", "weight = 1e300\nmass = 1.0"),
    ];
    for text in &texts {
        let msg = load(dir.path(), text).unwrap_err();
        assert_mentions(&msg, &["1e300"]);
        assert!(longest_digit_run(&msg) <= 17, "{msg}");
    }
}

/// A closed ASCII STL cube of side 10 mm at z ∈ [−10, 0], its triangles
/// counter-clockwise seen from outside unless `inside_out`.
fn cube_stl(inside_out: bool) -> String {
    let v = |i: usize| {
        [
            if i & 1 == 0 { -5.0 } else { 5.0 },
            if i & 2 == 0 { -5.0 } else { 5.0 },
            if i & 4 == 0 { -10.0 } else { 0.0 },
        ]
    };
    // Outward-oriented faces of the unit cube's corner indices.
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let mut s = String::from("solid cube\n");
    for q in quads {
        for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            let t = if inside_out { [t[0], t[2], t[1]] } else { t };
            s.push_str("facet normal 0 0 0\nouter loop\n");
            for i in t {
                let p = v(i);
                s.push_str(&format!("vertex {} {} {}\n", p[0], p[1], p[2]));
            }
            s.push_str("endloop\nendfacet\n");
        }
    }
    s + "endsolid cube\n"
}

/// An inside-out closed tool mesh is oriented outward by its enclosed
/// volume, with a warning naming the case line; the model builds.
/// `flip_normals` is a key of open meshes only.
#[test]
fn inside_out_closed_tool_meshes_are_oriented_with_a_warning() {
    let dir = TempDir::new().unwrap();
    write(&dir.path().join("outward.stl"), cube_stl(false).as_bytes());
    write(&dir.path().join("inward.stl"), cube_stl(true).as_bytes());
    let with_file = |file: &str| {
        edit(
            FORMING,
            "name = \"table\"\nshape = \"plane\"",
            &format!("name = \"table\"\nshape = \"mesh\"\nfile = \"{file}\""),
        )
    };
    let outward = load(dir.path(), &with_file("outward.stl")).unwrap();
    assert!(outward.warnings().is_empty(), "{:?}", outward.warnings());
    let text = with_file("inward.stl");
    let inward = load(dir.path(), &text).unwrap();
    let warnings: Vec<String> = inward.warnings().iter().map(ToString::to_string).collect();
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert_mentions(
        &warnings[0],
        &[
            &format!(
                "case.toml:{}: tool[0].file = \"inward.stl\"",
                line_of(&text, "file")
            ),
            "inside out",
            "-1000 mm³",
            "reversed",
        ],
    );
    let (Case::Forming(a), Case::Forming(b)) = (outward, inward) else {
        panic!("forming")
    };
    let (a, b) = (a.build().unwrap(), b.build().unwrap());
    assert_eq!(
        a.tools[0].drawing.vertices.len(),
        b.tools[0].drawing.vertices.len()
    );

    let msg = load(
        dir.path(),
        &edit(
            &text,
            "file = \"inward.stl\"",
            "file = \"inward.stl\"\nflip_normals = true",
        ),
    )
    .unwrap_err();
    assert_mentions(&msg, &["tool[0].flip_normals = true", "closed = false"]);
    load(
        dir.path(),
        &edit(
            &text,
            "file = \"inward.stl\"",
            "file = \"inward.stl\"\nclosed = false\nflip_normals = true",
        ),
    )
    .unwrap();
}

/// Every key named as advice in a message of the sources ("set X", "raise
/// X", "lower X", …) is a key the case format takes: a key of a table of
/// `docs/cases.md` (whose keys the case structures accept; the docs test
/// below and the unknown-key tests of `tests/cases.rs` keep the two
/// together). A message advising `flip_normals`, a key `[[tool]]` did not
/// have, failed this test.
#[test]
fn advice_in_messages_names_only_accepted_keys() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let docs = fs::read_to_string(root.join("docs/cases.md")).unwrap();
    let mut accepted = BTreeSet::new();
    for line in docs.lines().filter(|l| l.starts_with("| `")) {
        let first = line.split('|').nth(1).unwrap_or("");
        for part in first.split('`').skip(1).step_by(2) {
            accepted.insert(part.to_string());
            if let Some(last) = part.rsplit('.').next() {
                accepted.insert(last.to_string());
            }
        }
    }
    assert!(accepted.contains("friction") && accepted.contains("time_step_update_interval"));
    let mut files = vec![root.join("src")];
    let mut advised = Vec::new();
    while let Some(path) = files.pop() {
        if path.is_dir() {
            files.extend(fs::read_dir(&path).unwrap().map(|e| e.unwrap().path()));
            continue;
        }
        if path.extension().is_none_or(|e| e != "rs") {
            continue;
        }
        let text = fs::read_to_string(&path).unwrap();
        for (n, line) in text.lines().enumerate() {
            if line.trim_start().starts_with("//") {
                continue;
            }
            for verb in ["set ", "raise ", "lower ", "increase ", "reduce ", "give "] {
                for (at, _) in line.match_indices(verb) {
                    let word: String = line[at + verb.len()..]
                        .trim_start_matches('`')
                        .chars()
                        .take_while(|c| c.is_ascii_lowercase() || *c == '_' || *c == '.')
                        .collect();
                    let word = word.trim_end_matches('.');
                    // A key is snake_case or dotted; plain words are prose.
                    if word.contains('_') || word.contains('.') {
                        advised.push((path.clone(), n + 1, word.to_string()));
                    }
                }
            }
        }
    }
    assert!(
        advised.iter().any(|(_, _, w)| w == "contact.penalty"),
        "the scan finds the known advice: {advised:?}"
    );
    let unknown: Vec<_> = advised
        .iter()
        .filter(|(_, _, w)| {
            !accepted.contains(w.as_str())
                && !w.rsplit('.').next().is_some_and(|l| accepted.contains(l))
        })
        .collect();
    assert!(
        unknown.is_empty(),
        "advice naming keys no case takes: {unknown:?}"
    );
}

/// `docs/cases.md` states every bound of `src/case/bounds.rs` with the same
/// keys, unit and numbers (its "Ranges" table rows begin with
/// [`Bound::doc_row`](ncform::case::bounds::Bound::doc_row)).
#[test]
fn docs_state_every_bound() {
    let docs =
        fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/cases.md")).unwrap();
    let missing: Vec<String> = BOUNDS
        .iter()
        .filter(|b| !docs.contains(b.doc_row().as_str()))
        .map(|b| format!("{} {} |", b.doc_row(), b.why))
        .collect();
    assert!(
        missing.is_empty(),
        "rows of docs/cases.md missing or with other numbers:\n{}",
        missing.join("\n")
    );
}

/// Every shipped case parses, without a warning (their values are all
/// usual), and its model builds (the OATs' and the small verification
/// cases'; the benches build in their own tests).
#[test]
fn shipped_cases_parse_without_warnings() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut count = 0;
    for folder in ["cases", "cases/verification", "cases/regularised"] {
        for entry in fs::read_dir(root.join(folder)).unwrap() {
            let path = entry.unwrap().path();
            let text = fs::read_to_string(&path).unwrap_or_default();
            // `cases/verification/` also holds parameter files.
            if path.extension().is_none_or(|e| e != "toml")
                || !(text.contains("[specimen]") || text.contains("[[ply]]"))
            {
                continue;
            }
            let case = Case::load(&path).unwrap_or_else(|e| panic!("{e}"));
            assert!(
                case.warnings().is_empty(),
                "{}: {:?}",
                path.display(),
                case.warnings()
            );
            count += 1;
        }
    }
    assert!(count >= 17, "{count} shipped cases");
}

/// `[[tool]] plies`: the plies a tool touches. An unknown name, an empty
/// list and a ply named twice are refused with the file, the line, the
/// key `tool[i].plies`, the list as written and the case's plies; a valid
/// list resolves to the plies' indices, and leaving the key out gives
/// every ply.
#[test]
fn tool_plies_name_plies_of_the_case_once_each() {
    let dir = TempDir::new().unwrap();
    let with = |list: &str| format!("{FORMING}plies = {list}\n");
    let cases: &[(&str, &[&str])] = &[
        (
            "[\"top\"]",
            &[
                "tool[1].plies = [\"top\"]",
                "\"p\"",
                "\"top\" is none of them",
            ],
        ),
        ("[]", &["tool[1].plies = []", "at least one", "\"p\""]),
        (
            "[\"p\", \"p\"]",
            &["tool[1].plies = [\"p\", \"p\"]", "each ply once"],
        ),
    ];
    for (list, parts) in cases {
        let text = with(list);
        let msg = load(dir.path(), &text).unwrap_err();
        let line = format!("case.toml:{}:", line_of(&text, "plies"));
        assert_mentions(&msg, &[line.as_str()]);
        assert_mentions(&msg, parts);
    }
    let plies_of = |text: &str| {
        let Case::Forming(c) = load(dir.path(), text).unwrap() else {
            panic!("forming")
        };
        c.tools.iter().map(|t| t.plies.clone()).collect::<Vec<_>>()
    };
    assert_eq!(plies_of(&with("[\"p\"]")), vec![vec![0], vec![0]]);
    assert_eq!(plies_of(FORMING), vec![vec![0], vec![0]]);
}
