//! Contour maps with an overlay: tool outlines drawn over a map and
//! categorical fields drawn in a fixed colour per class.

use std::fs;
use std::path::Path;

use ncform::post::contour::{
    CATEGORY_COLOURS, Category, ContourMap, LabelledPolyline, MapOverlay, MapView, NO_VALUE_GREY,
    OUTLINE_COLOUR, contour_layout, contour_layout_overlaid, write_contour_png_overlaid,
    write_contour_png_viewed,
};
use ncform::post::plot::PlotError;

/// RGB pixels of a PNG read back with the `image` crate.
fn read_rgb(path: &Path) -> image::RgbImage {
    image::open(path).unwrap().to_rgb8()
}

fn pixel(img: &image::RgbImage, (u, v): (f64, f64)) -> [u8; 3] {
    img.get_pixel(u.floor() as u32, v.floor() as u32).0
}

fn centroid(points: &[[f64; 2]], t: [usize; 3]) -> [f64; 2] {
    let p = |k: usize| points[t[k]];
    [
        (p(0)[0] + p(1)[0] + p(2)[0]) / 3.0,
        (p(0)[1] + p(1)[1] + p(2)[1]) / 3.0,
    ]
}

fn categories(names: &[&str]) -> Vec<Category> {
    names
        .iter()
        .zip(CATEGORY_COLOURS)
        .map(|(n, colour)| Category {
            name: (*n).into(),
            colour,
        })
        .collect()
}

/// A 40 × 20 mm rectangle of 2 × 1 cells (4 triangles): the left half
/// (x < 20) has value 0, the right half value 1.
fn rectangle() -> (Vec<[f64; 2]>, Vec<[usize; 3]>, Vec<f64>) {
    let points = vec![
        [0.0, 0.0],
        [20.0, 0.0],
        [40.0, 0.0],
        [0.0, 20.0],
        [20.0, 20.0],
        [40.0, 20.0],
    ];
    let triangles = vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]];
    let values = vec![0.0, 0.0, 1.0, 1.0];
    (points, triangles, values)
}

/// Requirement: a categorical map draws each triangle in its class's
/// colour, a value that is not a class (NaN, out of range, not integral)
/// grey, and lists every class in a legend (also a class no triangle has).
#[test]
fn categorical_map_fills_triangles_with_class_colours() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("classes.png");
    let points = [
        [0.0, 0.0],
        [10.0, 0.0],
        [20.0, 0.0],
        [30.0, 0.0],
        [0.0, 10.0],
        [10.0, 10.0],
        [20.0, 10.0],
        [30.0, 10.0],
    ];
    let triangles = [[0, 1, 5], [0, 5, 4], [1, 2, 6], [2, 3, 7], [2, 7, 6]];
    let values = [0.0, 2.0, f64::NAN, 7.0, 1.5];
    let classes = categories(&["none", "sticking", "sliding"]);
    let map = ContourMap {
        title: "contact status".into(),
        points: &points,
        triangles: &triangles,
        values: &values,
        label: "status".into(),
        range: Some((5.0, 1.0)), // ignored for a categorical map
    };
    let overlay = MapOverlay {
        outlines: &[],
        categories: Some(&classes),
    };
    let size = (900, 500);
    let maps = [map];
    write_contour_png_overlaid(&path, &maps, size, MapView::Above, &overlay).unwrap();
    let frame = &contour_layout_overlaid(&maps, size, &overlay).unwrap()[0];
    let img = read_rgb(&path);
    assert_eq!(img.dimensions(), size);
    let expected = [
        CATEGORY_COLOURS[0],
        CATEGORY_COLOURS[2],
        NO_VALUE_GREY,
        NO_VALUE_GREY,
        NO_VALUE_GREY,
    ];
    for (e, &t) in triangles.iter().enumerate() {
        let c = frame.to_pixel(centroid(&points, t));
        assert_eq!(pixel(&img, c), expected[e], "triangle {e}");
    }
    // The legend (right of the plot) shows class 1, which no triangle has.
    let right = frame.plot_origin.0 as u32 + frame.plot_size.0 + 2;
    let legend_has =
        |rgb: [u8; 3]| (right..size.0).any(|x| (0..size.1).any(|y| img.get_pixel(x, y).0 == rgb));
    for c in &classes {
        assert!(legend_has(c.colour), "legend swatch of {}", c.name);
    }
}

/// Requirement: an outline is drawn in the outline colour over the
/// triangles, which keep their colour away from it; parts far outside the
/// map are clipped (no panic); seen from below the outline is mirrored with
/// the triangles.
#[test]
fn outline_is_drawn_over_map_and_mirrored_from_below() {
    let dir = tempfile::tempdir().unwrap();
    let (points, triangles, values) = rectangle();
    let map = ContourMap {
        title: "E22".into(),
        points: &points,
        triangles: &triangles,
        values: &values,
        label: "E22 [-]".into(),
        range: Some((0.0, 1.0)),
    };
    // An L: along y = 5 from x = 5 to 30, then up x = 30 to y = 15.
    let outlines = [
        LabelledPolyline {
            label: "punch".into(),
            points: vec![[5.0, 5.0], [30.0, 5.0], [30.0, 15.0]],
            closed: false,
        },
        LabelledPolyline {
            label: "die".into(),
            points: vec![[-1e6, 18.0], [1e300, 18.0], [1e300, -1e300]],
            closed: true,
        },
    ];
    let overlay = MapOverlay {
        outlines: &outlines,
        categories: None,
    };
    let size = (900, 500);
    let maps = [map];
    let above = dir.path().join("above.png");
    write_contour_png_overlaid(&above, &maps, size, MapView::Above, &overlay).unwrap();
    let frame = &contour_layout_overlaid(&maps, size, &overlay).unwrap()[0];
    let img = read_rgb(&above);
    let (left, right) = (frame.colour(0.0), frame.colour(1.0));
    assert_eq!(pixel(&img, frame.to_pixel([17.5, 5.0])), OUTLINE_COLOUR);
    assert_eq!(pixel(&img, frame.to_pixel([30.0, 10.0])), OUTLINE_COLOUR);
    assert_eq!(pixel(&img, frame.to_pixel([10.0, 12.0])), left);
    assert_eq!(pixel(&img, frame.to_pixel([35.0, 12.0])), right);
    assert_eq!(pixel(&img, frame.to_pixel([25.0, 10.0])), right);

    // From below: the maps and outlines are mirrored in x before the
    // layout; the vertical leg at x = 30 lands at x' = −30 over the
    // right-half triangles, and nothing is drawn at the unmirrored place.
    let mirrored_points: Vec<[f64; 2]> = points.iter().map(|p| [-p[0], p[1]]).collect();
    let mirrored = ContourMap {
        points: &mirrored_points,
        ..maps[0].clone()
    };
    let below = dir.path().join("below.png");
    write_contour_png_overlaid(&below, &maps, size, MapView::Below, &overlay).unwrap();
    let frame = &contour_layout_overlaid(&[mirrored], size, &overlay).unwrap()[0];
    let img = read_rgb(&below);
    assert_eq!(pixel(&img, frame.to_pixel([-30.0, 10.0])), OUTLINE_COLOUR);
    assert_eq!(pixel(&img, frame.to_pixel([-17.5, 5.0])), OUTLINE_COLOUR);
    assert_eq!(pixel(&img, frame.to_pixel([-35.0, 12.0])), right);
    assert_eq!(pixel(&img, frame.to_pixel([-10.0, 10.0])), left);
    assert_eq!(pixel(&img, frame.to_pixel([-25.0, 10.0])), right);
}

/// Requirement: an outline point that is not finite is an error naming the
/// map and the outline, and no file is written.
#[test]
fn non_finite_outline_point_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.png");
    let (points, triangles, values) = rectangle();
    let map = ContourMap {
        title: "E22 formed".into(),
        points: &points,
        triangles: &triangles,
        values: &values,
        label: "E22 [-]".into(),
        range: None,
    };
    let outlines = [LabelledPolyline {
        label: "blankholder".into(),
        points: vec![[0.0, 0.0], [f64::NAN, 1.0]],
        closed: false,
    }];
    let overlay = MapOverlay {
        outlines: &outlines,
        categories: None,
    };
    for view in [MapView::Above, MapView::Below] {
        let err = write_contour_png_overlaid(
            &path,
            std::slice::from_ref(&map),
            (900, 500),
            view,
            &overlay,
        )
        .unwrap_err();
        match &err {
            PlotError::Layout { error, .. } => match error.as_ref() {
                PlotError::OutlineNotFinite {
                    title,
                    outline,
                    point,
                } => {
                    assert_eq!(title, "E22 formed");
                    assert_eq!(outline, "blankholder");
                    assert_eq!(*point, 1);
                }
                other => panic!("unexpected error {other:?}"),
            },
            other => panic!("unexpected error {other:?}"),
        }
        let text = err.to_string();
        assert!(
            text.contains("bad.png") && text.contains("E22 formed"),
            "{text}"
        );
        assert!(text.contains("blankholder"), "{text}");
        assert!(!path.exists());
    }
}

/// Requirement: an empty overlay gives the picture (and layout) of
/// `write_contour_png_viewed`, byte for byte.
#[test]
fn empty_overlay_gives_the_plain_picture() {
    let dir = tempfile::tempdir().unwrap();
    let (points, triangles, values) = rectangle();
    let map = ContourMap {
        title: "E22".into(),
        points: &points,
        triangles: &triangles,
        values: &values,
        label: "E22 [-]".into(),
        range: None,
    };
    let maps = [map.clone(), map];
    let overlay = MapOverlay::default();
    for view in [MapView::Above, MapView::Below] {
        let a = dir.path().join("plain.png");
        let b = dir.path().join("overlaid.png");
        write_contour_png_viewed(&a, &maps, (1200, 500), view).unwrap();
        write_contour_png_overlaid(&b, &maps, (1200, 500), view, &overlay).unwrap();
        assert_eq!(fs::read(&a).unwrap(), fs::read(&b).unwrap(), "{view:?}");
    }
    assert_eq!(
        contour_layout(&maps, (1200, 500)).unwrap(),
        contour_layout_overlaid(&maps, (1200, 500), &overlay).unwrap()
    );
}
