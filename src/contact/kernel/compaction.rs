//! The through-thickness (compaction) response of a fabric layer as the
//! normal law of the explicit penalty contact (`docs/theory.md`, "Compaction
//! of the fabric layer"; `docs/contact.md`, "A compliant layer").
//!
//! A dry fabric is not a membrane of fixed thickness: under a rigid tool it
//! compacts, softly at the low pressures of a blankholder and ever more
//! stiffly as the fibres pack. The layer between a ply's mid-surface and
//! the tool (half the ply's uncompacted thickness, the contact offset `H`)
//! carries the pressure of Toll's packing law (Toll 1998, with the fibre
//! volume fraction inversely proportional to the layer's thickness):
//!
//! ```text
//! p(δ) = p_c ((H/(H − δ))^n − 1),  0 ≤ δ < H                (Eq. C1)
//! ```
//!
//! for a compression `δ` (the penetration of the penalty law), the
//! pressure scale `p_c` \[MPa\] and the packing exponent `n > 1`. A node
//! of tributary area `A` carries `f = A p`; its tangent
//! `f'(δ) = A n (p + p_c)/(H − δ)` (Eq. C2) grows without bound as the
//! layer closes, so past the knee `δ*` where it reaches the node's penalty
//! stiffness `k` (the explicit step's bound on contact, which this law must
//! not exceed) the force goes on linearly with `k` (Eq. C3). The stored
//! energy is the integral of the force (Eq. C4), so the energy balance
//! holds as for the linear law.

use super::{ContactError, positive};

/// Toll's packing law of one fabric layer (Eq. C1): the pressure scale
/// `p_c` \[MPa\] and the exponent `n > 1`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompactionLaw {
    /// `p_c` \[MPa\]: the pressure at which the layer's thickness has
    /// dropped by the factor `2^(−1/n)`.
    pub pressure_scale: f64,
    /// `n` (dimensionless, `> 1`): how fast the layer stiffens as it
    /// compacts.
    pub exponent: f64,
}

impl CompactionLaw {
    /// The law with `p_c > 0` \[MPa\] and `n > 1`.
    ///
    /// # Errors
    /// A scale that is not positive and finite, or an exponent not above 1.
    pub fn new(pressure_scale: f64, exponent: f64) -> Result<Self, ContactError> {
        let pressure_scale = positive("compaction pressure", pressure_scale)?;
        if !(exponent > 1.0 && exponent.is_finite()) {
            return Err(ContactError::InvalidSetting {
                name: "compaction exponent",
                value: exponent,
                expected: "a finite value above 1",
            });
        }
        Ok(Self {
            pressure_scale,
            exponent,
        })
    }

    /// `p(δ)` \[MPa\] of Eq. C1 for a layer of thickness `layer` \[mm\]
    /// compressed by `compression` \[mm\] (`∞` at or beyond `layer`, 0 for
    /// `compression ≤ 0`).
    pub fn pressure(&self, layer: f64, compression: f64) -> f64 {
        if compression <= 0.0 {
            return 0.0;
        }
        if compression >= layer {
            return f64::INFINITY;
        }
        self.pressure_scale * power_minus_one(self.exponent, compression / layer)
    }

    /// The layer's thickness ratio `(H − δ)/H` under the pressure
    /// `pressure` \[MPa\] (Eq. C1 solved for `δ`).
    pub fn thickness_ratio(&self, pressure: f64) -> f64 {
        (1.0 + pressure.max(0.0) / self.pressure_scale).powf(-1.0 / self.exponent)
    }
}

/// `(1/(1 − s))^m − 1` for `0 ≤ s < 1` without cancellation at small `s`.
#[inline]
fn power_minus_one(m: f64, s: f64) -> f64 {
    (-m * (-s).ln_1p()).exp_m1()
}

/// The law of Eq. C1–C4 for one node: area, layer and the penalty
/// stiffness that caps its tangent, with the knee precomputed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodalCompaction {
    /// `A p_c` \[N\].
    force_scale: f64,
    /// `H` \[mm\].
    layer: f64,
    /// `n`.
    exponent: f64,
    /// The cap `k` [N/mm] of the tangent.
    stiffness: f64,
    /// `δ*` \[mm\]: where `f'(δ*) = k` (0 when the law starts stiffer).
    knee: f64,
    /// `f(δ*)` \[N\].
    knee_force: f64,
    /// `E(δ*)` [N·mm].
    knee_energy: f64,
}

impl NodalCompaction {
    /// The law `law` on a node of tributary area `area` \[mm²\], for a
    /// layer of thickness `layer` \[mm\] (the contact offset), with its
    /// tangent capped at the node's penalty stiffness `stiffness` [N/mm].
    ///
    /// # Errors
    /// An area, layer or stiffness that is not positive and finite.
    pub fn new(
        law: &CompactionLaw,
        area: f64,
        layer: f64,
        stiffness: f64,
    ) -> Result<Self, ContactError> {
        let area = positive("nodal area", area)?;
        let layer = positive("compaction layer", layer)?;
        let stiffness = positive("normal_stiffness", stiffness)?;
        let n = law.exponent;
        let force_scale = area * law.pressure_scale;
        // Eq. C2 at the knee: (H/(H − δ*))^(n+1) = k H/(A p_c n).
        let ratio = stiffness * layer / (force_scale * n);
        let mut nodal = Self {
            force_scale,
            layer,
            exponent: n,
            stiffness,
            knee: 0.0,
            knee_force: 0.0,
            knee_energy: 0.0,
        };
        if ratio > 1.0 {
            nodal.knee = layer * -(-ratio.ln() / (n + 1.0)).exp_m1();
            (nodal.knee_force, nodal.knee_energy) = nodal.law(nodal.knee);
        }
        Ok(nodal)
    }

    /// `A p(δ)` (Eq. C1) and `∫₀^δ A p = A p_c (H/(n − 1) ((H/(H − δ))^(n−1)
    /// − 1) − δ)` (Eq. C4) on the law's branch, from one logarithm
    /// `ln(H/(H − δ))`.
    #[inline]
    fn law(&self, compression: f64) -> (f64, f64) {
        let n = self.exponent;
        let log_ratio = -(-compression / self.layer).ln_1p();
        let force = self.force_scale * (n * log_ratio).exp_m1();
        let energy = self.force_scale
            * (self.layer / (n - 1.0) * ((n - 1.0) * log_ratio).exp_m1() - compression);
        (force, energy)
    }

    /// The normal force \[N\] and the stored energy [N·mm] at the
    /// compression `compression` \[mm\] (Eq. C1, C3, C4): zero for
    /// `compression ≤ 0`, the law up to the knee, linear with the cap
    /// beyond.
    #[inline]
    pub fn force_and_energy(&self, compression: f64) -> (f64, f64) {
        if compression <= 0.0 {
            (0.0, 0.0)
        } else if compression <= self.knee {
            self.law(compression)
        } else {
            let beyond = compression - self.knee;
            (
                self.knee_force + self.stiffness * beyond,
                self.knee_energy + beyond * (self.knee_force + 0.5 * self.stiffness * beyond),
            )
        }
    }

    /// The tangent `df/dδ` [N/mm] at `compression` (Eq. C2, capped): never
    /// above the penalty stiffness.
    pub fn tangent(&self, compression: f64) -> f64 {
        if compression <= 0.0 {
            0.0
        } else if compression <= self.knee {
            let remaining = self.layer - compression;
            self.exponent * (self.law(compression).0 + self.force_scale) / remaining
        } else {
            self.stiffness
        }
    }

    /// `δ*` \[mm\].
    pub fn knee(&self) -> f64 {
        self.knee
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn nodal(k: f64) -> NodalCompaction {
        let law = CompactionLaw::new(6e-4, 10.0).unwrap();
        NodalCompaction::new(&law, 12.7, 0.275, k).unwrap()
    }

    /// The energy is the integral of the force (Simpson's rule on a fine
    /// grid: its error, `O(h⁴ f⁗)`, is far below the 1e-9 relative
    /// tolerance here), through the knee.
    #[test]
    fn energy_is_the_integral_of_the_force() {
        let c = nodal(2.0);
        assert!(c.knee() > 0.0 && c.knee() < 0.275);
        let end = c.knee() * 1.5;
        let steps = 20_000;
        let h = end / f64::from(steps);
        let mut integral = 0.0;
        let mut previous = 0.0;
        for i in 0..steps {
            let (a, b) = (f64::from(i) * h, f64::from(i + 1) * h);
            // Simpson on each cell, exact on the linear branch.
            let m = c.force_and_energy(0.5 * (a + b)).0;
            let fb = c.force_and_energy(b).0;
            integral += h / 6.0 * (previous + 4.0 * m + fb);
            previous = fb;
            let energy = c.force_and_energy(b).1;
            assert!(
                (energy - integral).abs() <= 1e-9 * energy.max(1e-12),
                "at {b}: {energy} vs {integral}"
            );
        }
    }

    /// The tangent is the force's derivative (central differences), never
    /// above the cap, and continuous at the knee.
    #[test]
    fn tangent_is_the_derivative_and_capped() {
        let c = nodal(2.0);
        for i in 1..60 {
            let d = c.knee() * f64::from(i) / 40.0;
            let h = 1e-7;
            let numeric = (c.force_and_energy(d + h).0 - c.force_and_energy(d - h).0) / (2.0 * h);
            let t = c.tangent(d);
            assert!((numeric - t).abs() <= 1e-5 * t, "{d}: {numeric} vs {t}");
            assert!(t <= 2.0 * (1.0 + 1e-12));
        }
        let below = c.tangent(c.knee() * (1.0 - 1e-12));
        assert!((below - 2.0).abs() < 1e-8, "{below}");
    }

    /// Force at most `k δ` (the step estimate's bound holds), and the
    /// pressure–thickness relation inverts Eq. C1.
    #[test]
    fn force_below_the_linear_cap_and_law_inverts() {
        let c = nodal(2.0);
        for i in 1..100 {
            let d = 0.3 * f64::from(i) / 100.0;
            assert!(c.force_and_energy(d).0 <= 2.0 * d * (1.0 + 1e-12));
        }
        let law = CompactionLaw::new(6e-4, 10.0).unwrap();
        for p in [1e-5, 2.4e-4, 1e-2, 0.1] {
            let ratio = law.thickness_ratio(p);
            let back = law.pressure(1.0, 1.0 - ratio);
            assert!((back - p).abs() <= 1e-10 * p, "{p} {back}");
        }
    }

    /// A law stiffer than the cap from the start is the linear penalty.
    #[test]
    fn stiff_law_is_the_linear_penalty() {
        let c = nodal(1e-6);
        assert_eq!(c.knee(), 0.0);
        let (f, e) = c.force_and_energy(0.01);
        assert_eq!(f, 1e-6 * 0.01);
        assert!((e - 0.5e-6 * 1e-4).abs() < 1e-20);
    }

    #[test]
    fn bad_settings_are_refused() {
        assert!(CompactionLaw::new(0.0, 10.0).is_err());
        assert!(CompactionLaw::new(1e-3, 1.0).is_err());
        assert!(CompactionLaw::new(1e-3, f64::NAN).is_err());
        let law = CompactionLaw::new(1e-3, 8.0).unwrap();
        assert!(NodalCompaction::new(&law, 0.0, 0.1, 1.0).is_err());
        assert!(NodalCompaction::new(&law, 1.0, -0.1, 1.0).is_err());
    }
}
