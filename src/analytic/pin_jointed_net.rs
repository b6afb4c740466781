//! The pin-jointed-net limit of the 45° off-axis tension test
//! (`docs/verification.md`): rovings and stitching inextensible, only
//! the shear energy W6 active. With `D = L − W` and clamp displacement `d`:
//!
//! ```text
//! u   = (D + d) / (√2 D)
//! γ_A = π/2 − 2 arccos(u),   γ_B = γ_A / 2,   γ_C = 0
//! A_A = W (L − 1.5 W),  A_B = W²,  A_C = W²/2
//! F   = t [A_A f6(sin γ_A) cos γ_A + A_B f6(sin γ_B) cos γ_B / 2] dγ_A/dd
//! dγ_A/dd = √2 / (D sqrt(1 − u²))
//! ```
//!
//! by virtual work (`I6 = sin γ` in trellis shear, `dI6 = cos γ dγ`). The net
//! locks at `d = (√2 − 1) D`.

use crate::material::GeneralizedTerm;

/// Geometry of the 45° specimen and the membrane thickness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NetSpecimen {
    /// Width `W` \[mm\].
    pub width: f64,
    /// Free length `L` \[mm\], `L > 1.5 W` for the three zones to exist.
    pub length: f64,
    /// Thickness `t` \[mm\].
    pub thickness: f64,
}

impl NetSpecimen {
    /// `D = L − W`.
    fn free_diagonal(&self) -> f64 {
        self.length - self.width
    }

    /// The displacement at which the net locks, `(√2 − 1) D` \[mm\].
    pub fn locking_displacement(&self) -> f64 {
        (std::f64::consts::SQRT_2 - 1.0) * self.free_diagonal()
    }

    /// Shear angle of zone A, `γ_A(d)` \[rad\].
    pub fn shear_angle_a(&self, d: f64) -> f64 {
        let dd = self.free_diagonal();
        let u = (dd + d) / (std::f64::consts::SQRT_2 * dd);
        std::f64::consts::FRAC_PI_2 - 2.0 * u.clamp(-1.0, 1.0).acos()
    }

    /// Clamp force `F(d)` \[N\] for the shear law `w6` (its stress function
    /// `f6` in MPa), for `0 ≤ d < locking_displacement()`.
    pub fn force(&self, d: f64, w6: &GeneralizedTerm) -> f64 {
        let dd = self.free_diagonal();
        let u = (dd + d) / (std::f64::consts::SQRT_2 * dd);
        let gamma_a = self.shear_angle_a(d);
        let gamma_b = 0.5 * gamma_a;
        let area_a = self.width * (self.length - 1.5 * self.width);
        let area_b = self.width * self.width;
        let dgamma = std::f64::consts::SQRT_2 / (dd * (1.0 - u * u).sqrt());
        let f6 = |g: f64| w6.eval(g.sin()).stress;
        self.thickness
            * (area_a * f6(gamma_a) * gamma_a.cos() + area_b * f6(gamma_b) * gamma_b.cos() / 2.0)
            * dgamma
    }
}
