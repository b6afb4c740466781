//! Parameter studies: sweeps over case values (`docs/studies.md`).

pub mod keys;
pub mod slurm;
