//! `ncform fit`: fitting the parameters of the UD-NCF law to measured
//! off-axis tension tests (`docs/fit.md`).
//!
//! [`input`] reads and checks the fit file (the starting set, the free
//! parameters and their bounds, the tests and the optimiser's knobs);
//! [`measured`] reads the measured CSV files and resamples them to each
//! test's schedule. [`sensitivity`] evaluates an OAT's force and MDZ
//! strains with their exact sensitivities to the law's parameters, as a
//! report of the one runner; [`evaluate`] turns every test's run into the
//! weighted residual and its Jacobian; [`optimise`] is the bounded
//! Levenberg–Marquardt method; [`identify`] says what the data determine;
//! [`run`] is the library entry point ([`run::fit`]), [`output`] writes
//! its files and pictures.

pub mod error;
pub mod evaluate;
pub mod identify;
pub mod input;
pub mod measured;
pub mod optimise;
pub mod output;
pub mod run;
pub mod sensitivity;
