//! Post-processing: CSV and PNG writers. Reads results, never changes them.

pub mod contour;
pub mod csv;
pub mod defects;
pub mod fields;
pub mod forming;
pub mod orientation;
pub mod plot;
pub mod vtu;
