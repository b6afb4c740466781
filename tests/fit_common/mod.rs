//! Synthetic fits on coarse copies of the shipped OATs, shared by the fit
//! tests (`tests/fit.rs`) and the fit benchmark's coverage study
//! (`benches/fit.rs`). The synthetic data are made by ncform itself
//! through the library entry point (`report::run` with a `MemoryReport`)
//! on the same meshes as the fit uses.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use ncform::case::{Case, OatCase};
use ncform::material::{LawParameter, MaterialSpec};
use ncform::report::memory::MemoryReport;
use ncform::report::{Progress, run};
use ncform::solver::CancelToken;

/// The ten parameters the OATs inform.
pub const TEN: [&str; 10] = [
    "w6.c_ini",
    "w6.s_ini",
    "w6.c_mid",
    "w6.delta_s_mid",
    "w8.c_ini",
    "w8.s_ini",
    "w8.c_mid",
    "w8.delta_s_mid",
    "coupling.k_min",
    "coupling.s11",
];

/// Factors of the truth on the start, each within ±20 %.
pub const FACTORS: [f64; 10] = [1.15, 0.86, 1.12, 0.9, 0.83, 1.18, 0.88, 1.1, 1.16, 0.85];

pub const ANGLES: [f64; 3] = [30.0, 45.0, 60.0];
/// Final clamp displacement of the coarse copies [mm].
pub const STROKE: f64 = 60.0;
/// The schedule: every 5 mm.
pub fn schedule() -> Vec<f64> {
    (1..=12).map(|k| 5.0 * k as f64).collect()
}

/// A coarse copy of the shipped OAT at `angle` (12 mm elements, 60 mm).
pub fn coarse_case(angle: f64) -> String {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join(format!("cases/oat{angle}.toml")))
        .expect("the shipped OAT");
    text.replace("element_size = 2.7", "element_size = 12.0")
        .replace("displacement = 80.0", &format!("displacement = {STROKE}"))
        .replace(
            "output_displacements = [20.0, 40.0, 60.0]",
            "output_displacements = [20.0, 40.0]",
        )
}

pub fn truth() -> MaterialSpec {
    let start = MaterialSpec::default_set();
    let values: Vec<(LawParameter, f64)> = TEN
        .iter()
        .zip(FACTORS)
        .map(|(key, f)| {
            let p = LawParameter::from_key(key).expect("a law key");
            let v = start
                .parameter_values()
                .into_iter()
                .find(|(k, _)| k == key)
                .expect("the start has it")
                .1;
            (p, v * f)
        })
        .collect();
    start.with_parameters(&values).expect("a valid truth")
}

/// `(d, F, E22, γ, E⊥)` of the case at `angle` with `material` at the
/// schedule, from the one runner.
pub fn synthetic(
    dir: &Path,
    angle: f64,
    material: &MaterialSpec,
    displacements: &[f64],
) -> Vec<[f64; 5]> {
    let path = dir.join(format!("oat{angle}.toml"));
    let mut case = OatCase::from_toml_str(&coarse_case(angle), &path.display().to_string(), dir)
        .expect("the coarse case");
    case.material = material.clone();
    case.output_displacements = displacements.to_vec();
    case.solver.residual_tolerance = 1e-10;
    let mut report = MemoryReport::new();
    run(
        &Case::Oat(case),
        &mut report,
        &mut Progress::Quiet,
        &CancelToken::default(),
    )
    .expect("the synthetic run");
    displacements
        .iter()
        .map(|d| {
            let row = report
                .oat_rows
                .iter()
                .find(|r| (r.displacement - d).abs() < 1e-9)
                .expect("a row at each scheduled displacement");
            [
                row.displacement,
                row.force,
                row.mdz_e22,
                row.mdz_shear_angle_deg,
                row.mdz_e_perp,
            ]
        })
        .collect()
}

/// Noise levels of the fit file (`docs/fit.md`).
pub const FORCE_RELATIVE: f64 = 0.02;
pub const FORCE_ABSOLUTE: f64 = 0.01;
pub const STRAIN: f64 = 0.003;
pub const SHEAR: f64 = 0.5;

/// A seeded standard normal (Box–Muller on a 64-bit LCG: no dependency).
pub struct Normal(pub u64);
impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    pub fn sample(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The rows of the dense measured files: every 0.5 mm, ten per 5 mm bin.
pub fn dense_rows() -> Vec<f64> {
    (1..=(2.0 * STROKE) as usize)
        .map(|k| 0.5 * k as f64)
        .collect()
}

/// How the measured files are written.
#[derive(Clone, Copy)]
pub struct Data {
    /// The MDZ strain columns too (else the force alone).
    pub strains: bool,
    /// Seeded noise (`None`: exact values).
    pub seed: Option<u64>,
    /// The fit starts at the truth (else at the paper's set).
    pub start_at_truth: bool,
    /// A row every 0.5 mm (else one row per scheduled displacement).
    pub dense: bool,
}

/// Writes the cases, the measured files and a fit file freeing `free`.
pub fn write_fit(dir: &Path, free: &[&str], data: Data) -> PathBuf {
    let Data {
        strains,
        seed,
        start_at_truth,
        dense,
    } = data;
    let material = truth();
    let params = if start_at_truth {
        std::fs::write(dir.join("truth.toml"), material.to_toml("the truth")).expect("write");
        "truth.toml"
    } else {
        "schaefer2024"
    };
    let mut normal = seed.map(Normal);
    let mut tests = String::new();
    for angle in ANGLES {
        std::fs::write(dir.join(format!("oat{angle}.toml")), coarse_case(angle)).expect("write");
        let rows = synthetic(
            dir,
            angle,
            &material,
            &if dense { dense_rows() } else { schedule() },
        );
        let mut csv = String::from("# synthetic\ndisplacement [mm],force [N]");
        if strains {
            csv.push_str(",E22 [-],shear_angle [deg],E_perp [-]");
        }
        csv.push('\n');
        for r in &rows {
            let mut noisy = *r;
            if let Some(n) = normal.as_mut() {
                noisy[1] += (FORCE_RELATIVE * r[1].abs() + FORCE_ABSOLUTE) * n.sample();
                noisy[2] += STRAIN * n.sample();
                noisy[3] += SHEAR * n.sample();
                noisy[4] += STRAIN * n.sample();
            }
            csv.push_str(&format!("{},{}", noisy[0], noisy[1]));
            if strains {
                csv.push_str(&format!(",{},{},{}", noisy[2], noisy[3], noisy[4]));
            }
            csv.push('\n');
        }
        std::fs::write(dir.join(format!("oat{angle}.csv")), csv).expect("write");
        let noise = if strains {
            format!(
                "{{ force = {{ relative = {FORCE_RELATIVE}, absolute = {FORCE_ABSOLUTE} }}, E22 = {STRAIN}, shear_angle = {SHEAR}, E_perp = {STRAIN} }}"
            )
        } else {
            format!("{{ force = {{ relative = {FORCE_RELATIVE}, absolute = {FORCE_ABSOLUTE} }} }}")
        };
        tests.push_str(&format!(
            "\n[[test]]\ncase = \"oat{angle}.toml\"\nmeasured = \"oat{angle}.csv\"\nnoise = {noise}\ndisplacements = {:?}\n",
            schedule()
        ));
    }
    let free: Vec<String> = free.iter().map(|k| format!("\"{k}\"")).collect();
    let text = format!(
        "title = \"synthetic\"\nparams = \"{params}\"\nfree = [{}]\n[fit]\nmax_iterations = 40\ntolerance = 1e-10\nnewton_tolerance = 1e-10\n{tests}",
        free.join(", ")
    );
    let path = dir.join("fit.toml");
    std::fs::write(&path, text).expect("write");
    path
}

pub fn value_of(material: &MaterialSpec, key: &str) -> f64 {
    material
        .parameter_values()
        .into_iter()
        .find(|(k, _)| k == key)
        .map(|(_, v)| v)
        .expect("a key of the set")
}

/// The Mahalanobis distance `eᵀ Cov⁻¹ e` of the fit's error `e` (fitted
/// minus `truth`) under the covariance it reports, `Cov_ij = σ_i σ_j ρ_ij`.
pub fn mahalanobis(outcome: &ncform::fit::run::FitOutcome, truth: &MaterialSpec) -> f64 {
    let id = outcome.identifiability.as_ref().expect("at the optimum");
    let n = outcome.parameters.len();
    let cov = nalgebra::DMatrix::from_fn(n, n, |i, j| {
        outcome.parameters[i].sigma * outcome.parameters[j].sigma * id.correlation[i][j]
    });
    let error = nalgebra::DVector::from_fn(n, |i, _| {
        outcome.parameters[i].value - value_of(truth, &outcome.parameters[i].key)
    });
    let chol = cov.cholesky().expect("a positive definite covariance");
    error.dot(&chol.solve(&error))
}
