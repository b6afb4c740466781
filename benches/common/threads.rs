//! What the term benchmarks share: a term's increment timed on one and
//! on two threads. Included by `#[path]` (not a bench target).

use criterion::BenchmarkGroup;
use criterion::measurement::WallTime;
use ncform::model::State;

/// Benchmarks `increment` on one and on two threads as
/// `<threads>_threads<suffix>`, each iteration at the next of two states
/// (`states`, visited in turn) with the step `time_step`.
pub fn on_one_and_two_threads(
    group: &mut BenchmarkGroup<'_, WallTime>,
    suffix: &str,
    states: &[Vec<f64>],
    time_step: f64,
    mut increment: impl FnMut(&State) + Send,
) {
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let mut k = 0;
        group.bench_function(format!("{threads}_threads{suffix}"), |b| {
            b.iter(|| {
                k ^= 1;
                let state = State {
                    time_step,
                    ..State::at(&states[k])
                };
                pool.install(|| increment(&state));
            });
        });
    }
}
