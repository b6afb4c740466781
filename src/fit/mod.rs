//! `ncform fit`: fitting the parameters of the UD-NCF law to measured
//! off-axis tension tests. [`input`] reads and checks the fit file (the
//! starting set, the free parameters and their bounds, the tests and the
//! optimiser's knobs); [`measured`] reads the measured CSV files and
//! resamples them to each test's schedule. Formats: `docs/fit.md`.

pub mod input;
pub mod measured;
