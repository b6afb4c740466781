//! What the ply–ply contact bench and tests share: two plies of the same
//! triangles as one ply–ply contact term. Included by `#[path]` (not a
//! bench target).

use nalgebra::Vector3;
use ncform::model::{ExplicitPenalty, PlyContact, PlyContactOptions, PlySurface};

/// The contact of the plies `lower` (model nodes `0..n`) and `upper`
/// (`n..2n`), both meshed with `triangles`, `thickness` mm thick, with
/// the paper's ply–ply friction 0.336, the default penalty, 20 % of
/// critical normal damping and candidate lists of skin `skin` mm.
pub fn ply_stack(
    lower: Vec<Vector3<f64>>,
    upper: Vec<Vector3<f64>>,
    triangles: &[[usize; 3]],
    thickness: f64,
    skin: f64,
) -> PlyContact {
    let n = lower.len();
    let surface = |name: &str, first: usize, reference: Vec<Vector3<f64>>| PlySurface {
        name: name.into(),
        nodes: (first..first + n).collect(),
        reference,
        triangles: triangles.to_vec(),
        thickness,
    };
    PlyContact::new(
        "lower with upper",
        surface("lower", 0, lower),
        surface("upper", n, upper),
        PlyContactOptions {
            friction: 0.336,
            explicit_stiffness: ExplicitPenalty::DEFAULT,
            explicit_damping: 0.2,
            skin,
            compaction: None,
        },
    )
    .expect("ply contact")
}
