//! A membrane model ready to solve: reference geometry, element reference
//! data, one material and the membrane thickness.

use nalgebra::Vector3;

use crate::element::MembraneReference;
use crate::element::membrane::ReferenceError;
use crate::material::Material;

/// Reference configuration and constitutive data of a membrane.
#[derive(Debug, Clone)]
pub struct MembraneModel {
    /// Reference node positions [mm].
    pub nodes: Vec<Vector3<f64>>,
    /// Triangles (node indices).
    pub triangles: Vec<[usize; 3]>,
    /// Reference data per triangle.
    pub references: Vec<MembraneReference>,
    /// The law.
    pub material: Material,
    /// Membrane thickness `t` [mm].
    pub thickness: f64,
}

impl MembraneModel {
    /// Sets up every triangle; `fibres` has one global direction per triangle.
    ///
    /// # Errors
    /// The first triangle that cannot be set up, with its index.
    pub fn new(
        nodes: Vec<Vector3<f64>>,
        triangles: Vec<[usize; 3]>,
        fibres: &[Vector3<f64>],
        material: Material,
        thickness: f64,
    ) -> Result<Self, (usize, ReferenceError)> {
        let references = triangles
            .iter()
            .zip(fibres)
            .enumerate()
            .map(|(e, (t, f))| {
                MembraneReference::new(&[nodes[t[0]], nodes[t[1]], nodes[t[2]]], f)
                    .map_err(|err| (e, err))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self {
            nodes,
            triangles,
            references,
            material,
            thickness,
        })
    }

    /// Nodal displacements of triangle `e` from the global displacement `u`
    /// (3 per node) [mm].
    #[inline]
    pub fn element_displacements(&self, e: usize, u: &[f64]) -> [Vector3<f64>; 3] {
        let t = self.triangles[e];
        std::array::from_fn(|a| {
            let n = t[a];
            Vector3::new(u[3 * n], u[3 * n + 1], u[3 * n + 2])
        })
    }
}
