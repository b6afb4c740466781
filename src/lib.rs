//! ncform: finite-element forming simulation of dry unidirectional
//! non-crimp fabrics (UD-NCF) with the hyperelastic membrane law of
//! Schäfer, Dörr, Zheng, Naouar and Kärger (Composites Part A, 2024).
//!
//! Data flows mesh → material → element → model → solver → post: a mesh
//! and a law make elements; plies, tools and loads make a [`model::Model`]
//! of force terms; the solvers ([`solver`]) drive any model; [`post`] reads
//! the results. [`case`] builds models from case files; [`report`] runs
//! a case with either solver and hands its results to a report (a run
//! folder, or values in memory); [`cli`] is the command line over it
//! (`docs/architecture.md`).

#![warn(missing_docs)]

pub mod analytic;
pub mod case;
pub mod cli;
pub mod config;
pub mod contact;
pub mod element;
pub mod fit;
pub mod handoff;
pub mod material;
pub mod mesh;
pub mod model;
pub mod post;
pub mod report;
pub mod solver;
pub mod study;
