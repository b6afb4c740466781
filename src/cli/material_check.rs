//! `ncform material check`: the finite-difference tangent diagnostic
//! (`material::diagnostics`) on any parameter set, so a user can confirm
//! that their own parameters give a consistent law before a long run.

use std::collections::BTreeMap;

use crate::material::diagnostics::{SampleRanges, StateSampler, fd_check, stencil_on_one_branch};
use crate::material::{FibreFrame, Invariants, Material, MaterialSpec};

/// Outcome of a diagnostic run.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckReport {
    /// States checked.
    pub checked: usize,
    /// States skipped because the stencil crossed a kink.
    pub straddling: usize,
    /// States whose error exceeded the bound.
    pub failed: usize,
    /// States the law rejected (should be none: the sampler draws admissible
    /// states).
    pub rejected: usize,
    /// Largest error/tolerance ratio seen (≤ 1 passes).
    pub worst_ratio: f64,
    /// Checked states per branch label.
    pub branches: BTreeMap<String, usize>,
}

fn branch_labels(
    material: &Material,
    c: &crate::material::Sym2,
    frame: &FibreFrame,
) -> Vec<String> {
    let Material::UdNcf(law) = material else {
        return vec!["svk".to_string()];
    };
    let Ok(inv) = Invariants::new(c, frame) else {
        return vec![];
    };
    let b = law.branches(&inv);
    let opt = |v: Option<crate::material::TermBranch>| match v {
        Some(t) => format!("{t:?}"),
        None => "inactive".to_string(),
    };
    vec![
        format!("W4 {:?}", b.w4),
        format!("W6 {:?}", b.w6),
        format!("W8 {}", opt(b.w8)),
        format!("W11 {}", opt(b.w11)),
    ]
}

/// Runs the diagnostic at `states` random states (seed `seed`, default
/// ranges of [`SampleRanges`]).
pub fn run_check(spec: &MaterialSpec, states: usize, seed: u64) -> CheckReport {
    let mut sampler = StateSampler::new(seed, SampleRanges::default());
    let mut report = CheckReport {
        checked: 0,
        straddling: 0,
        failed: 0,
        rejected: 0,
        worst_ratio: 0.0,
        branches: BTreeMap::new(),
    };
    let material = &spec.material;
    while report.checked < states {
        let (c, angle) = sampler.sample();
        let d = sampler.direction();
        let frame = FibreFrame::from_angle(angle);
        if !stencil_on_one_branch(material, &c, &frame, &d) {
            report.straddling += 1;
            continue;
        }
        let here = branch_labels(material, &c, &frame);
        report.checked += 1;
        match fd_check(material, &c, &frame, &d) {
            Ok(check) => {
                let ratio = (check.stress_error / check.stress_tolerance)
                    .max(check.tangent_error / check.tangent_tolerance);
                report.worst_ratio = report.worst_ratio.max(ratio);
                if !check.passed() {
                    report.failed += 1;
                }
                for label in here {
                    *report.branches.entry(label).or_default() += 1;
                }
            }
            Err(_) => report.rejected += 1,
        }
    }
    report
}

/// The report as text lines for the terminal.
pub fn format_report(spec: &MaterialSpec, report: &CheckReport) -> String {
    let mut text = format!(
        "material check: {} ({})\n  {} states checked, {} skipped (stencil across a kink), {} rejected\n  worst error / tolerance: {:.3e} (<= 1 passes)\n  failures: {}\n  states per branch:\n",
        spec.name,
        spec.source,
        report.checked,
        report.straddling,
        report.rejected,
        report.worst_ratio,
        report.failed
    );
    for (label, count) in &report.branches {
        text += &format!("    {label:<24} {count}\n");
    }
    text
}
