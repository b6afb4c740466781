//! Law evaluations per second on one core: stress only, and stress plus
//! tangent, at states spread over every branch of the default set
//! (`StateSampler` with the default ranges: both signs of I4 − 1 and I6,
//! I8 ≷ 1, I11 ≷ 1 including the W11 lock, fibre angles over [0°, 180°)).
//!
//! Run: `cargo bench --bench material`. Throughput is reported in
//! elements (= evaluations) per second; criterion prints the median.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ncform::material::diagnostics::{SampleRanges, StateSampler};
use ncform::material::{FibreFrame, MaterialSpec, MembraneMaterial, Sym2};

const STATES: usize = 4096;

fn states() -> Vec<(Sym2, FibreFrame)> {
    let mut sampler = StateSampler::new(2024, SampleRanges::default());
    (0..STATES)
        .map(|_| {
            let (c, angle) = sampler.sample();
            (c, FibreFrame::from_angle(angle))
        })
        .collect()
}

fn law_evaluations(criterion: &mut Criterion) {
    let states = states();
    for name in ["schaefer2024", "schaefer2024-printed"] {
        let material = MaterialSpec::named(name).unwrap().material;
        let mut group = criterion.benchmark_group(format!("ud-ncf/{name}"));
        group.throughput(Throughput::Elements(STATES as u64));
        group.bench_function("stress", |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for (c, frame) in &states {
                    let s = material.stress(black_box(c), black_box(frame)).unwrap();
                    sum += s.stress[0];
                }
                sum
            })
        });
        group.bench_function("stress+tangent", |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for (c, frame) in &states {
                    let (s, t) = material
                        .stress_tangent(black_box(c), black_box(frame))
                        .unwrap();
                    sum += s.stress[0] + t[(0, 0)];
                }
                sum
            })
        });
        group.finish();
    }
}

criterion_group! {
    name = benches;
    // No HTML plots: the numbers are what we quote.
    config = Criterion::default().without_plots();
    targets = law_evaluations
}
criterion_main!(benches);
