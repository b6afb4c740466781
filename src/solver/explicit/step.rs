//! The stable-step re-estimates of a run, with the bounds of terms whose
//! share of `ω²` is small refreshed less often (`docs/explicit.md`,
//! "The stable time step").
//!
//! Every re-estimate refreshes the bound of each term whose last bound was
//! at least [`SMALL_SHARE`] of the sum of all terms' bounds, of each term
//! whose bound is zero, and of each penalty term (contact: its bound
//! follows the contact set, which can change at once). A term below that
//! share (bending next to the membrane: about 3 % on the forming
//! benches, yet the costliest bound) is refreshed at every
//! [`REFRESH_EVERY`]-th re-estimate only, and in between enters the sum
//! with [`STALE_MARGIN`] times its last bound. The step then keeps the
//! safety factor's margin unless such a term's bound grows by more than
//! `STALE_MARGIN + (1/s² − 1)/SMALL_SHARE` (6.7 times for the safety
//! factor `s = 0.9`) between two refreshes; each refresh that finds the
//! bound grown past `STALE_MARGIN` times its last value is counted, and
//! the run reports it.

use super::system::{ExplicitSystem, critical_step};
use crate::model::{FrequencyBound, Model, State, TermFailure};

/// A term whose bound is below this share of the sum is refreshed at every
/// [`REFRESH_EVERY`]-th re-estimate only.
pub const SMALL_SHARE: f64 = 0.05;
/// Re-estimates between two refreshes of a small term's bound.
pub const REFRESH_EVERY: usize = 10;
/// Factor on a small term's last bound between its refreshes.
pub const STALE_MARGIN: f64 = 2.0;

/// A refresh that found a small term's bound grown past [`STALE_MARGIN`]
/// times its last value.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StaleGrowth {
    /// Such refreshes.
    pub count: usize,
    /// The largest ratio of a refreshed bound to the last one.
    pub largest_ratio: f64,
}

/// The terms' last bounds and their ages, for the re-estimates of a run.
#[derive(Debug, Clone)]
pub struct StepEstimator {
    /// Each term's last refreshed bound.
    bounds: Vec<FrequencyBound>,
    /// Re-estimates since each term's last refresh.
    ages: Vec<usize>,
    /// Per term: the refreshes that found the bound grown past the margin.
    growth: Vec<StaleGrowth>,
    /// The bounds entering the sum (scratch).
    in_use: Vec<FrequencyBound>,
    /// Each term's bound at the start.
    initial: Vec<FrequencyBound>,
}

impl StepEstimator {
    /// Every term's bound at `state`, and the critical step they give
    /// \[s\] (as [`ExplicitSystem::critical_time_step`]).
    ///
    /// # Errors
    /// The first term that fails.
    pub fn new(
        system: &ExplicitSystem,
        model: &Model,
        state: &State,
    ) -> Result<(Self, f64), TermFailure> {
        let bounds = system.term_bounds(model, state, true)?;
        let critical = critical_step(system.combined_frequency(&bounds));
        let terms = bounds.len();
        Ok((
            Self {
                in_use: bounds.clone(),
                initial: bounds.clone(),
                bounds,
                ages: vec![0; terms],
                growth: vec![StaleGrowth::default(); terms],
            },
            critical,
        ))
    }

    /// The critical step at `state` \[s\], refreshing the bounds that are
    /// due (module documentation).
    ///
    /// # Errors
    /// The first refreshed term that fails.
    pub fn estimate(
        &mut self,
        system: &ExplicitSystem,
        model: &Model,
        state: &State,
    ) -> Result<f64, TermFailure> {
        let total = self.bounds.iter().fold(0.0, |s, b| s + b.total());
        for (t, term) in model.terms.iter().enumerate() {
            let last = self.bounds[t].total();
            let small =
                last > 0.0 && last < SMALL_SHARE * total && !term.stiffness_from_time_step();
            if small && self.ages[t] + 1 < REFRESH_EVERY {
                self.ages[t] += 1;
                self.in_use[t] = self.bounds[t].scaled(STALE_MARGIN);
                continue;
            }
            let fresh = term.frequency_bound(state, &system.masses)?;
            if small && fresh.total() > STALE_MARGIN * last {
                let growth = &mut self.growth[t];
                growth.count += 1;
                growth.largest_ratio = growth.largest_ratio.max(fresh.total() / last);
            }
            self.bounds[t] = fresh;
            self.ages[t] = 0;
            self.in_use[t] = fresh;
        }
        Ok(critical_step(system.combined_frequency(&self.in_use)))
    }

    /// Per term (in term order): its bound at the start and its last
    /// refreshed bound.
    pub fn first_and_last(&self) -> impl Iterator<Item = (&FrequencyBound, &FrequencyBound)> {
        self.initial.iter().zip(&self.bounds)
    }

    /// Per term (in term order), the refreshes that found its bound grown
    /// past [`STALE_MARGIN`] times the last one.
    pub fn growth(&self) -> &[StaleGrowth] {
        &self.growth
    }
}
