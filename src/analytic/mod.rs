//! Closed-form solutions used by tests and verification, so a test reads as
//! "solver vs. theory".

pub mod elastica;
pub mod pin_jointed_net;
