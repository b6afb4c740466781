//! The off-axis tension test case file as written: one serde structure per
//! table (`[specimen]`, `[mesh]`, `[material]`, `[loading]`, `[output]`),
//! unknown keys refused. Key-by-key documentation: `docs/cases.md`.

use serde::Deserialize;
use toml::Spanned;

use crate::case::explicit::{ExplicitRaw, SolverChoice};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CaseRaw {
    pub(super) title: Option<Spanned<String>>,
    pub(super) specimen: SpecimenRaw,
    pub(super) mesh: MeshRaw,
    pub(super) material: Option<MaterialRaw>,
    pub(super) loading: LoadingRaw,
    pub(super) output: Option<OutputRaw>,
    pub(super) solver: Option<Spanned<SolverChoice>>,
    pub(super) explicit: Option<ExplicitRaw>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SpecimenRaw {
    pub(super) width: Spanned<f64>,
    pub(super) length: Spanned<f64>,
    pub(super) bias_angle_deg: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MeshRaw {
    pub(super) element_size: Option<Spanned<f64>>,
    pub(super) nx: Option<Spanned<i64>>,
    pub(super) ny: Option<Spanned<i64>>,
    pub(super) pattern: Option<Spanned<String>>,
    pub(super) file: Option<Spanned<String>>,
    pub(super) fixed_clamp_set: Option<String>,
    pub(super) moving_clamp_set: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MaterialRaw {
    pub(super) params: Option<Spanned<String>>,
    pub(super) thickness: Option<Spanned<f64>>,
    pub(super) areal_mass: Option<Spanned<f64>>,
    pub(super) density: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LoadingRaw {
    pub(super) displacement: Spanned<f64>,
    pub(super) output_displacements: Option<Spanned<Vec<f64>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct OutputRaw {
    pub(super) mdz_size: Option<Spanned<f64>>,
    pub(super) contour_displacement: Option<Spanned<f64>>,
}
