//! Post-processing: CSV and PNG writers. Reads results, never changes them.

pub mod csv;
pub mod plot;
