//! ncform: finite-element forming simulation of dry unidirectional
//! non-crimp fabrics (UD-NCF) with the hyperelastic membrane law of
//! Schäfer, Dörr, Zheng, Naouar and Kärger (Composites Part A, 2024).
//!
//! Data flows mesh → material → element → assembly → solver → post.
//! This release provides the material layer ([`material`]) and the writers
//! for its curves ([`post`]).

#![warn(missing_docs)]

pub mod analytic;
pub mod case;
pub mod cli;
pub mod config;
pub mod contact;
pub mod element;
pub mod material;
pub mod mesh;
pub mod post;
pub mod solver;
