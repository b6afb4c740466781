//! Post-processing writers: VTK XML files (`.vtu`, `.pvd`) and contour-map
//! PNGs. Each test names the requirement it checks.

use std::fs;
use std::io::ErrorKind;
use std::path::Path;

use ncform::post::contour::{
    ContourMap, NO_VALUE_GREY, contour_layout, viridis, write_contour_png,
};
use ncform::post::vtu::{
    Field, FieldData, PvdEntry, SYM_TENSOR2_SUFFIX, VtuPiece, write_pvd, write_vtu,
};

// ---------------------------------------------------------------- helpers

/// The text between the opening tag of the `DataArray` whose attributes
/// contain `attr` (e.g. `Name="E22"`) inside `<section>` and its closing tag,
/// with the opening tag itself.
fn data_array<'a>(xml: &'a str, section: &str, attr: &str) -> (&'a str, &'a str) {
    let open = format!("<{section}>");
    let close = format!("</{section}>");
    let s0 = xml.find(&open).unwrap_or_else(|| panic!("no <{section}>")) + open.len();
    let s1 = s0 + xml[s0..].find(&close).expect("section closed");
    let sec = &xml[s0..s1];
    let mut from = 0;
    while let Some(i) = sec[from..].find("<DataArray") {
        let start = from + i;
        let tag_end = start + sec[start..].find('>').expect("tag closed") + 1;
        let tag = &sec[start..tag_end];
        let body_end = tag_end + sec[tag_end..].find("</DataArray>").expect("array closed");
        if tag.contains(attr) {
            return (tag, &sec[tag_end..body_end]);
        }
        from = body_end;
    }
    panic!("no DataArray with {attr} in <{section}>");
}

fn floats(body: &str) -> Vec<f64> {
    body.split_whitespace()
        .map(|t| t.parse::<f64>().expect("a float"))
        .collect()
}

fn ints(body: &str) -> Vec<i64> {
    body.split_whitespace()
        .map(|t| t.parse::<i64>().expect("an integer"))
        .collect()
}

fn attr_value<'a>(tag: &'a str, name: &str) -> &'a str {
    let key = format!("{name}=\"");
    let i = tag
        .find(&key)
        .unwrap_or_else(|| panic!("no {name} in {tag}"))
        + key.len();
    &tag[i..i + tag[i..].find('"').expect("attribute closed")]
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn flat3(v: &[[f64; 3]]) -> Vec<f64> {
    v.iter().flatten().copied().collect()
}

/// Awkward values for round-tripping: many digits, tiny, huge, negative
/// zero, subnormal.
const AWKWARD: [f64; 6] = [0.1, 1.0 / 3.0, 1e-7, -2.5e300, -0.0, 5e-324];

struct TwoTriangles {
    points: Vec<[f64; 3]>,
    triangles: Vec<[usize; 3]>,
    temperature: Vec<f64>,
    displacement: Vec<[f64; 3]>,
    node_id: Vec<i32>,
    e22: Vec<f64>,
    normal: Vec<[f64; 3]>,
    stress: Vec<[f64; 3]>,
    region: Vec<i32>,
}

fn two_triangles() -> TwoTriangles {
    TwoTriangles {
        points: vec![
            [0.0, 0.0, 0.0],
            [1.0 / 3.0, 0.0, 1e-7],
            [1.0, 2.0 / 3.0, -0.0],
            [0.1, 1.0, 2.5e-300],
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        temperature: AWKWARD[..4].to_vec(),
        displacement: vec![
            [0.1, 0.2, 0.3],
            [1e-7, -1e7, 1.0 / 7.0],
            [-0.0, 5e-324, 2.0f64.sqrt()],
            [1e300, -1e-300, 0.0],
        ],
        node_id: vec![1, -2, i32::MAX, i32::MIN],
        e22: AWKWARD[4..].to_vec(),
        normal: vec![[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]],
        stress: vec![[1.5, -0.25, 1.0 / 3.0], [1e-9, 123456.789, -7.0]],
        region: vec![7, 0],
    }
}

fn piece(d: &TwoTriangles) -> VtuPiece<'_> {
    VtuPiece {
        points: &d.points,
        triangles: &d.triangles,
        point_fields: vec![
            Field {
                name: "T",
                data: FieldData::Scalar(&d.temperature),
            },
            Field {
                name: "u [mm]",
                data: FieldData::Vector3(&d.displacement),
            },
            Field {
                name: "node_id",
                data: FieldData::Int(&d.node_id),
            },
        ],
        cell_fields: vec![
            Field {
                name: "E22",
                data: FieldData::Scalar(&d.e22),
            },
            Field {
                name: "normal",
                data: FieldData::Vector3(&d.normal),
            },
            Field {
                name: "S",
                data: FieldData::SymTensor2(&d.stress),
            },
            Field {
                name: "region",
                data: FieldData::Int(&d.region),
            },
        ],
        comment: vec![
            "ncform test piece -- two triangles".into(),
            "units: mm, N, MPa".into(),
        ],
    }
}

// ---------------------------------------------------------------- VTU

/// Requirement: a `.vtu` file is a VTK XML UnstructuredGrid (version 0.1,
/// LittleEndian, ASCII arrays) of VTK_TRIANGLE cells whose counts,
/// connectivity, offsets, types and every field value read back exactly.
#[test]
fn vtu_round_trips_mesh_and_fields_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("piece.vtu");
    let d = two_triangles();
    write_vtu(&path, &piece(&d)).unwrap();
    let xml = fs::read_to_string(&path).unwrap();

    assert!(xml.starts_with("<?xml version=\"1.0\"?>\n"));
    assert!(
        xml.contains(
            r#"<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">"#
        )
    );
    // Comments on top, with "--" made legal for XML.
    let root = xml.find("<VTKFile").unwrap();
    let head = &xml[..root];
    assert!(head.contains("<!-- units: mm, N, MPa -->"), "{head}");
    assert!(head.contains("ncform test piece"), "{head}");
    assert!(!head.replace("<!--", "").replace("-->", "").contains("--"));
    assert!(xml.contains(r#"<Piece NumberOfPoints="4" NumberOfCells="2">"#));
    assert_eq!(xml.matches("<DataArray").count(), 11);
    assert_eq!(xml.matches(r#"format="ascii""#).count(), 11);

    let (tag, body) = data_array(&xml, "Points", "NumberOfComponents=\"3\"");
    assert_eq!(attr_value(tag, "type"), "Float64");
    assert_eq!(bits(&floats(body)), bits(&flat3(&d.points)));

    let (tag, body) = data_array(&xml, "Cells", r#"Name="connectivity""#);
    assert_eq!(attr_value(tag, "type"), "Int64");
    assert_eq!(ints(body), vec![0, 1, 2, 0, 2, 3]);
    let (_, body) = data_array(&xml, "Cells", r#"Name="offsets""#);
    assert_eq!(ints(body), vec![3, 6]);
    let (tag, body) = data_array(&xml, "Cells", r#"Name="types""#);
    assert_eq!(attr_value(tag, "type"), "UInt8");
    assert_eq!(ints(body), vec![5, 5]);

    // Point fields.
    let (tag, body) = data_array(&xml, "PointData", r#"Name="T""#);
    // Scalars leave NumberOfComponents at VTK's default (1): meshio then
    // reads a 1-D array.
    assert!(!tag.contains("NumberOfComponents"), "{tag}");
    assert_eq!(bits(&floats(body)), bits(&d.temperature));
    let (tag, body) = data_array(&xml, "PointData", r#"Name="u [mm]""#);
    assert_eq!(attr_value(tag, "NumberOfComponents"), "3");
    assert_eq!(bits(&floats(body)), bits(&flat3(&d.displacement)));
    let (tag, body) = data_array(&xml, "PointData", r#"Name="node_id""#);
    assert_eq!(attr_value(tag, "type"), "Int32");
    assert_eq!(
        ints(body),
        d.node_id.iter().map(|&i| i64::from(i)).collect::<Vec<_>>()
    );

    // Cell fields.
    let (_, body) = data_array(&xml, "CellData", r#"Name="E22""#);
    assert_eq!(bits(&floats(body)), bits(&d.e22));
    let (_, body) = data_array(&xml, "CellData", r#"Name="normal""#);
    assert_eq!(bits(&floats(body)), bits(&flat3(&d.normal)));
    let name = format!("Name=\"S{SYM_TENSOR2_SUFFIX}\"");
    let (tag, body) = data_array(&xml, "CellData", &name);
    assert_eq!(attr_value(tag, "NumberOfComponents"), "3");
    assert_eq!(attr_value(tag, "ComponentName0"), "xx");
    assert_eq!(attr_value(tag, "ComponentName1"), "yy");
    assert_eq!(attr_value(tag, "ComponentName2"), "xy");
    assert_eq!(bits(&floats(body)), bits(&flat3(&d.stress)));
    let (_, body) = data_array(&xml, "CellData", r#"Name="region""#);
    assert_eq!(ints(body), vec![7, 0]);
}

/// Requirement: field names are XML-escaped, so any name gives a
/// well-formed file.
#[test]
fn vtu_escapes_field_names() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("names.vtu");
    let d = two_triangles();
    let mut p = piece(&d);
    p.cell_fields[0].name = "a<b & \"c\"";
    write_vtu(&path, &p).unwrap();
    let xml = fs::read_to_string(&path).unwrap();
    assert!(xml.contains(r#"Name="a&lt;b &amp; &quot;c&quot;""#));
}

/// Requirement: never a NaN in an output file: a non-finite value is
/// rejected (InvalidInput) with the field's name and index, and no file is
/// left behind.
#[test]
fn vtu_rejects_non_finite_values_naming_field_and_index() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("nan.vtu");
    let mut d = two_triangles();
    d.e22[1] = f64::NAN;
    let err = write_vtu(&path, &piece(&d)).unwrap_err();
    assert_eq!(err.kind(), ErrorKind::InvalidInput);
    let msg = err.to_string();
    assert!(msg.contains("\"E22\"") && msg.contains("index 1"), "{msg}");
    assert!(!path.exists());

    let mut d = two_triangles();
    d.displacement[2][1] = f64::INFINITY;
    let msg = write_vtu(&path, &piece(&d)).unwrap_err().to_string();
    assert!(
        msg.contains("\"u [mm]\"") && msg.contains("index 2"),
        "{msg}"
    );

    let mut d = two_triangles();
    d.points[3][0] = f64::NAN;
    let msg = write_vtu(&path, &piece(&d)).unwrap_err().to_string();
    assert!(msg.contains("point 3"), "{msg}");
    assert!(!path.exists());
}

/// Requirement: a field whose length is not the number of points (point
/// fields) or cells (cell fields) is rejected (InvalidInput) naming the
/// field; so is a triangle that refers to a missing point.
#[test]
fn vtu_rejects_wrong_lengths_naming_field() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("len.vtu");
    let mut d = two_triangles();
    d.node_id.pop();
    let err = write_vtu(&path, &piece(&d)).unwrap_err();
    assert_eq!(err.kind(), ErrorKind::InvalidInput);
    assert!(err.to_string().contains("\"node_id\""), "{err}");

    let mut d = two_triangles();
    d.stress.push([0.0; 3]);
    let err = write_vtu(&path, &piece(&d)).unwrap_err();
    assert_eq!(err.kind(), ErrorKind::InvalidInput);
    assert!(err.to_string().contains("\"S\""), "{err}");

    let mut d = two_triangles();
    d.triangles[1] = [0, 2, 4];
    let err = write_vtu(&path, &piece(&d)).unwrap_err();
    assert_eq!(err.kind(), ErrorKind::InvalidInput);
    assert!(err.to_string().contains("triangle 1"), "{err}");
    assert!(!path.exists());
}

/// Requirement: a `.pvd` collection lists every entry, in order, with its
/// time and relative file, under the comment lines.
#[test]
fn pvd_lists_entries_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.pvd");
    let entries = vec![
        PvdEntry {
            time: 0.0,
            file: "run/step_0000.vtu".into(),
            part: 0,
        },
        PvdEntry {
            time: 0.1,
            file: "run/step_0001.vtu".into(),
            part: 0,
        },
        PvdEntry {
            time: 1e-7,
            file: "run/a&b.vtu".into(),
            part: 0,
        },
    ];
    write_pvd(&path, &entries, &["off-axis tension, units: mm, s".into()]).unwrap();
    let xml = fs::read_to_string(&path).unwrap();
    assert!(xml.contains(r#"<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">"#));
    assert!(xml.contains("<!-- off-axis tension, units: mm, s -->"));
    let sets: Vec<&str> = xml.lines().filter(|l| l.contains("<DataSet")).collect();
    assert_eq!(sets.len(), 3);
    let got: Vec<(f64, &str)> = sets
        .iter()
        .map(|l| {
            (
                attr_value(l, "timestep").parse().unwrap(),
                attr_value(l, "file"),
            )
        })
        .collect();
    assert_eq!(
        got,
        vec![
            (0.0, "run/step_0000.vtu"),
            (0.1, "run/step_0001.vtu"),
            (1e-7, "run/a&amp;b.vtu"),
        ]
    );

    let bad = [PvdEntry {
        time: f64::NAN,
        file: "x.vtu".into(),
        part: 0,
    }];
    let err = write_pvd(&dir.path().join("bad.pvd"), &bad, &[]).unwrap_err();
    assert_eq!(err.kind(), ErrorKind::InvalidInput);
}

// ---------------------------------------------------------------- contour

fn png_size(path: &Path) -> (u32, u32) {
    let bytes = fs::read(path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    assert_eq!(&bytes[12..16], b"IHDR");
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    (w, h)
}

/// RGB pixels of a PNG (decoded with the `png` crate).
fn read_rgb(path: &Path) -> (Vec<u8>, u32, u32) {
    let decoder = png::Decoder::new(fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buf.truncate(info.buffer_size());
    (buf, info.width, info.height)
}

fn pixel(img: &[u8], width: u32, (u, v): (f64, f64)) -> [u8; 3] {
    let k = 3 * (v.floor() as usize * width as usize + u.floor() as usize);
    [img[k], img[k + 1], img[k + 2]]
}

/// A structured mesh of `nx × ny` cells (two triangles each) on a
/// `width × height` mm rectangle sheared by `shear` (x += shear·y).
fn strip(nx: usize, ny: usize, width: f64, height: f64, shear: f64) -> Mesh {
    let mut points = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            let x = width * i as f64 / nx as f64;
            let y = height * j as f64 / ny as f64;
            points.push([x + shear * y, y]);
        }
    }
    let mut triangles = Vec::new();
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    for j in 0..ny {
        for i in 0..nx {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Mesh { points, triangles }
}

struct Mesh {
    points: Vec<[f64; 2]>,
    triangles: Vec<[usize; 3]>,
}

fn centroid(m: &Mesh, e: usize) -> [f64; 2] {
    let t = m.triangles[e];
    let p = |k: usize| m.points[t[k]];
    [
        (p(0)[0] + p(1)[0] + p(2)[0]) / 3.0,
        (p(0)[1] + p(1)[1] + p(2)[1]) / 3.0,
    ]
}

/// A smooth field on the triangles (strain-like, 0 … 0.3).
fn smooth_field(m: &Mesh, height: f64) -> Vec<f64> {
    (0..m.triangles.len())
        .map(|e| {
            let c = centroid(m, e);
            let s = (std::f64::consts::PI * c[1] / height).sin();
            0.3 * s * s * (1.0 + 0.2 * (c[0] / 25.0).cos()) / 1.2
        })
        .collect()
}

/// Requirement: the PNG has exactly the requested size (IHDR width and
/// height).
#[test]
fn contour_png_has_requested_size() {
    let dir = tempfile::tempdir().unwrap();
    let m = strip(4, 12, 100.0, 300.0, 0.2);
    let values = smooth_field(&m, 300.0);
    let map = ContourMap {
        title: "E22".into(),
        points: &m.points,
        triangles: &m.triangles,
        values: &values,
        label: "E22 [-]".into(),
        range: None,
    };
    for size in [(700, 900), (1203, 611)] {
        let path = dir.path().join(format!("c{}x{}.png", size.0, size.1));
        write_contour_png(&path, &[map.clone(), map.clone()], size).unwrap();
        assert_eq!(png_size(&path), size);
    }
    // Too small for two maps with axes and colour bars: an error, no panic.
    let path = dir.path().join("tiny.png");
    let err = write_contour_png(&path, &[map.clone(), map], (300, 200))
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("tiny.png") && err.contains("too small"),
        "{err}"
    );
}

/// Requirement: a constant field and a field with NaN values draw without
/// failing; NaN triangles are grey and a constant field takes a small range
/// symmetric about its value.
#[test]
fn contour_constant_and_nan_fields_draw() {
    let dir = tempfile::tempdir().unwrap();
    let m = strip(6, 18, 100.0, 300.0, 0.0);
    let constant = vec![2.0; m.triangles.len()];
    let mut with_nan = smooth_field(&m, 300.0);
    let nan_triangle = with_nan.len() / 2;
    with_nan[nan_triangle] = f64::NAN;
    with_nan[3] = f64::INFINITY;
    let all_nan = vec![f64::NAN; m.triangles.len()];
    let maps = [
        ContourMap {
            title: "constant".into(),
            points: &m.points,
            triangles: &m.triangles,
            values: &constant,
            label: "c [-]".into(),
            range: None,
        },
        ContourMap {
            title: "with NaN".into(),
            points: &m.points,
            triangles: &m.triangles,
            values: &with_nan,
            label: "E22 [-]".into(),
            range: None,
        },
        ContourMap {
            title: "all NaN".into(),
            points: &m.points,
            triangles: &m.triangles,
            values: &all_nan,
            label: "γ [deg]".into(),
            range: None,
        },
    ];
    let path = dir.path().join("special.png");
    let size = (1500, 800);
    write_contour_png(&path, &maps, size).unwrap();
    let frames = contour_layout(&maps, size).unwrap();
    let (lo, hi) = frames[0].value_range;
    assert!(lo < 2.0 && hi > 2.0 && ((lo + hi) / 2.0 - 2.0).abs() < 1e-12);
    assert!(hi - lo <= 0.1);
    let (img, w, _) = read_rgb(&path);
    let c = frames[1].to_pixel(centroid(&m, nan_triangle));
    assert_eq!(pixel(&img, w, c), NO_VALUE_GREY);
    let c = frames[2].to_pixel(centroid(&m, 0));
    assert_eq!(pixel(&img, w, c), NO_VALUE_GREY);
}

/// Requirement: the pixel at the centre of a triangle has the viridis colour
/// of its value (ends: #440154 at the bottom of the range, #fde725 at the
/// top), in every map of a picture.
#[test]
fn contour_triangle_centre_has_colour_of_its_value() {
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(viridis(0.0), [0x44, 0x01, 0x54]);
    assert_eq!(viridis(1.0), [0xfd, 0xe7, 0x25]);
    // A 40 × 40 mm square split into two triangles, values 0 and 1, and a
    // strip with a smooth field and an explicit range.
    let square = Mesh {
        points: vec![[0.0, 0.0], [40.0, 0.0], [40.0, 40.0], [0.0, 40.0]],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
    };
    let square_values = [0.0, 1.0];
    let m = strip(5, 15, 100.0, 300.0, 0.3);
    let values = smooth_field(&m, 300.0);
    let maps = [
        ContourMap {
            title: "square".into(),
            points: &square.points,
            triangles: &square.triangles,
            values: &square_values,
            label: "v [-]".into(),
            range: Some((0.0, 1.0)),
        },
        ContourMap {
            title: "strip".into(),
            points: &m.points,
            triangles: &m.triangles,
            values: &values,
            label: "E22 [-]".into(),
            range: Some((0.0, 0.25)),
        },
    ];
    let path = dir.path().join("colours.png");
    let size = (1200, 700);
    write_contour_png(&path, &maps, size).unwrap();
    let frames = contour_layout(&maps, size).unwrap();
    let (img, w, _) = read_rgb(&path);
    assert_eq!(
        pixel(&img, w, frames[0].to_pixel(centroid(&square, 0))),
        viridis(0.0)
    );
    assert_eq!(
        pixel(&img, w, frames[0].to_pixel(centroid(&square, 1))),
        viridis(1.0)
    );
    for e in [0, 7, 31, 80, 149] {
        let expected = viridis(values[e] / 0.25);
        assert_eq!(frames[1].colour(values[e]), expected);
        assert_eq!(
            pixel(&img, w, frames[1].to_pixel(centroid(&m, e))),
            expected,
            "triangle {e}"
        );
    }
    // Equal scale: the square is as many pixels wide as high.
    let (x0, y0) = frames[0].to_pixel([0.0, 0.0]);
    let (x1, y1) = frames[0].to_pixel([40.0, 40.0]);
    assert!(((x1 - x0) - (y0 - y1)).abs() < 1e-9 && x1 - x0 > 100.0);
}

/// Requirement: neighbouring triangles leave no gap: every pixel whose
/// centre lies inside a sheared, irregular mesh of one value has that
/// value's colour.
#[test]
fn contour_fill_has_no_gaps_between_triangles() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = strip(17, 43, 100.0, 300.0, 0.27);
    // Perturb the interior nodes so edges fall at arbitrary angles.
    let (nx, ny) = (17, 43);
    for j in 1..ny {
        for i in 1..nx {
            let k = j * (nx + 1) + i;
            let s = ((k * 7919) % 101) as f64 / 101.0 - 0.5;
            m.points[k][0] += 1.3 * s;
            m.points[k][1] += 2.1 * s;
        }
    }
    let values = vec![0.5; m.triangles.len()];
    let map = ContourMap {
        title: "one value".into(),
        points: &m.points,
        triangles: &m.triangles,
        values: &values,
        label: "v".into(),
        range: Some((0.0, 1.0)),
    };
    let path = dir.path().join("gaps.png");
    let size = (600, 1000);
    write_contour_png(&path, std::slice::from_ref(&map), size).unwrap();
    let frame = &contour_layout(std::slice::from_ref(&map), size).unwrap()[0];
    let (img, w, _) = read_rgb(&path);
    let expected = viridis(0.5);
    // The sheared strip's outline in pixels: inside if 0 < y < 300 and
    // 0 < x − 0.27·y < 100 (with a 1.5 px safety band at the boundary).
    let s = frame.pixels_per_mm;
    let band = 1.5 / s;
    let (ox, oy) = frame.plot_origin;
    let mut checked = 0;
    for j in 0..frame.plot_size.1 as i32 {
        for i in 0..frame.plot_size.0 as i32 {
            let (u, v) = (f64::from(ox + i) + 0.5, f64::from(oy + j) + 0.5);
            let x = frame.x_range.0 + (u - f64::from(ox) - 0.5) / s;
            let y = frame.y_range.0 + (f64::from(oy) + f64::from(frame.plot_size.1) - 0.5 - v) / s;
            let xs = x - 0.27 * y;
            if y > band && y < 300.0 - band && xs > band && xs < 100.0 - band {
                assert_eq!(pixel(&img, w, (u, v)), expected, "pixel ({i}, {j})");
                checked += 1;
            }
        }
    }
    assert!(checked > 10_000, "{checked}");
}

/// Requirement: colour-bar ticks are round values inside the range, 5 or 6
/// of them for typical ranges (never fewer than 4 or more than 7).
#[test]
fn contour_colour_bar_ticks_are_round_and_few() {
    let m = strip(1, 1, 10.0, 10.0, 0.0);
    let mut five_or_six = 0;
    let mut total = 0;
    for (lo, hi) in [
        (0.0, 1.0),
        (0.0, 0.3),
        (-0.05, 0.12),
        (0.0, 60.0),
        (3.7, 4.1),
        (-1e-4, 2.3e-4),
        (0.0, 1234.0),
        (12.0, 13.0),
        (0.0, 0.07),
        (-45.0, 45.0),
    ] {
        let values = [lo, hi];
        let map = ContourMap {
            title: String::new(),
            points: &m.points,
            triangles: &m.triangles,
            values: &values,
            label: String::new(),
            range: None,
        };
        let f = &contour_layout(&[map], (600, 600)).unwrap()[0];
        assert_eq!(f.value_range, (lo, hi));
        let n = f.ticks.len();
        assert!((4..=7).contains(&n), "{lo}..{hi}: {:?}", f.ticks);
        assert!(f.ticks.iter().all(|&t| t >= lo - 1e-12 && t <= hi + 1e-12));
        five_or_six += usize::from((5..=6).contains(&n));
        total += 1;
    }
    assert!(five_or_six >= total - 1, "{five_or_six} of {total}");
}

/// Requirement: inconsistent data are reported with the file name, not
/// drawn.
#[test]
fn contour_rejects_inconsistent_maps_naming_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.png");
    let m = strip(2, 2, 10.0, 10.0, 0.0);
    let values = vec![0.0; m.triangles.len() - 1];
    let map = ContourMap {
        title: "short".into(),
        points: &m.points,
        triangles: &m.triangles,
        values: &values,
        label: String::new(),
        range: None,
    };
    let err = write_contour_png(&path, &[map], (600, 600))
        .unwrap_err()
        .to_string();
    assert!(err.contains("bad.png") && err.contains("short"), "{err}");
    let values = vec![0.0; m.triangles.len()];
    let map = ContourMap {
        title: "bad range".into(),
        points: &m.points,
        triangles: &m.triangles,
        values: &values,
        label: String::new(),
        range: Some((1.0, 1.0)),
    };
    let err = write_contour_png(&path, &[map], (600, 600))
        .unwrap_err()
        .to_string();
    assert!(err.contains("bad range"), "{err}");
}
