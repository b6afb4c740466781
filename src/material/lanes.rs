//! The arithmetic of the explicit force pass: the law written once over a
//! [`Real`], evaluated on one point (`f64`) or on four or eight independent
//! points in AVX2 registers (`x86::F64x4`, `x86::F64x8`, where the CPU has
//! them). Data-dependent branches become [`Real::select`]; a branch is
//! skipped only when no lane needs it, so each lane's result does not depend
//! on its neighbours. No operation fuses a multiply and an add, so every
//! lane computes bit for bit what the `f64` path computes.
//!
//! Used by the law (`generalized.rs`, `coupling.rs`, `invariants.rs`,
//! `udncf.rs`) and by the batched triangle kernel (`src/element/fibre_triangle.rs`).
//!
//! Everything here is `#[inline(always)]`: the SIMD types only reach their
//! instructions when inlined into a function compiled for them (the element
//! pass enters one through `pulp`); a call left in between would cost an
//! order of magnitude. For the same reason the hot code avoids
//! `[T; N]::map` and closures that the inliner might keep as calls.

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// One or several `f64` lanes with IEEE arithmetic lane by lane.
/// Constants come from [`Real::splat`] on an existing value (which
/// carries the SIMD context); mixed operations take the `f64` on the
/// right.
pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
{
    /// Lane conditions.
    type Mask: Copy
        + BitAnd<Output = Self::Mask>
        + BitOr<Output = Self::Mask>
        + Not<Output = Self::Mask>;
    /// The lanes as an array, `[f64; lanes]`.
    type Array: Copy;
    /// Every lane `x`, in the SIMD context of `self`.
    fn splat(self, x: f64) -> Self;
    /// The lanes `lanes`, in the SIMD context of `self`.
    fn load(self, lanes: Self::Array) -> Self;
    /// The lanes.
    fn store(self) -> Self::Array;
    /// Bit `l` set where lane `l` of `mask` is.
    fn bits(mask: Self::Mask) -> u32;
    /// `if mask { a } else { b }` per lane.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
    /// `x < y` (false for NaN).
    fn lt(self, y: Self) -> Self::Mask;
    /// `x ≤ y` (false for NaN).
    fn le(self, y: Self) -> Self::Mask;
    /// `x > y` (false for NaN).
    fn gt(self, y: Self) -> Self::Mask;
    /// `x ≥ y` (false for NaN).
    fn ge(self, y: Self) -> Self::Mask;
    /// `x ≠ y` (true for NaN).
    fn ne(self, y: Self) -> Self::Mask;
    /// Finite lanes.
    fn is_finite(self) -> Self::Mask;
    /// Any lane set.
    fn any(mask: Self::Mask) -> bool;
    /// Every lane set.
    fn all(mask: Self::Mask) -> bool;
    /// `√x`, correctly rounded.
    fn sqrt(self) -> Self;
    /// `|x|`.
    fn abs(self) -> Self;
    /// `|x|` with the sign of `sign`.
    fn copysign(self, sign: Self) -> Self;
    /// `if x > y { x } else { y }` (so `y` when `x` is NaN).
    fn max(self, y: Self) -> Self;
    /// `f` lane by lane (for the rare scalar-only function).
    fn map(self, f: impl Fn(f64) -> f64) -> Self;
    /// `2^k` from `1.5 · 2⁵² + k` (an integer `k ∈ [−1022, 1023]` held in
    /// the low bits of that sum): `k` plus the exponent bias, moved into
    /// the exponent field.
    fn exp2_of_shifted(self) -> Self;
}

/// `1.5 · 2⁵²`: adding it to `|x| < 2⁵¹` rounds `x` to an integer
/// (nearest, ties to even), which then sits in the low bits of the sum.
pub const ROUND_TO_INTEGER: f64 = 6_755_399_441_055_744.0;
/// The bits of [`ROUND_TO_INTEGER`] less the exponent bias: subtracted
/// from the bits of `1.5 · 2⁵² + k` this leaves `k + 1023`.
const SHIFTED_TO_BIASED: u64 = ROUND_TO_INTEGER.to_bits().wrapping_sub(1023);

impl Real for f64 {
    type Mask = bool;
    type Array = [f64; 1];
    #[inline(always)]
    fn splat(self, x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn load(self, lanes: [f64; 1]) -> Self {
        lanes[0]
    }
    #[inline(always)]
    fn store(self) -> [f64; 1] {
        [self]
    }
    #[inline(always)]
    fn bits(mask: bool) -> u32 {
        mask as u32
    }
    #[inline(always)]
    fn select(mask: bool, a: Self, b: Self) -> Self {
        if mask { a } else { b }
    }
    #[inline(always)]
    fn lt(self, y: Self) -> bool {
        self < y
    }
    #[inline(always)]
    fn le(self, y: Self) -> bool {
        self <= y
    }
    #[inline(always)]
    fn gt(self, y: Self) -> bool {
        self > y
    }
    #[inline(always)]
    fn ge(self, y: Self) -> bool {
        self >= y
    }
    #[inline(always)]
    fn ne(self, y: Self) -> bool {
        self != y
    }
    #[inline(always)]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    #[inline(always)]
    fn any(mask: bool) -> bool {
        mask
    }
    #[inline(always)]
    fn all(mask: bool) -> bool {
        mask
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        f64::copysign(self, sign)
    }
    #[inline(always)]
    fn max(self, y: Self) -> Self {
        if self > y { self } else { y }
    }
    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        f(self)
    }
    #[inline(always)]
    fn exp2_of_shifted(self) -> Self {
        f64::from_bits(self.to_bits().wrapping_sub(SHIFTED_TO_BIASED) << 52)
    }
}

/// Lanes in AVX2 registers, through `pulp`'s x86-64-v3 token (which proves
/// at run time that the CPU has the instructions, so none of this needs
/// `unsafe`): `F64x4`, one register, and `F64x8`, two registers
/// side by side (twice the independent work between the long chains of the
/// exponentials and divisions, measured 8 % faster on the force pass).
#[cfg(target_arch = "x86_64")]
pub mod x86 {
    use std::arch::x86_64::{__m256d, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NEQ_UQ};
    use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

    use pulp::bytemuck;
    use pulp::x86::V3;

    use super::{Real, SHIFTED_TO_BIASED};

    /// Four `f64` lanes.
    #[derive(Debug, Clone, Copy)]
    pub struct F64x4 {
        simd: V3,
        v: __m256d,
    }

    /// Four lane conditions (all bits set or clear per lane).
    #[derive(Debug, Clone, Copy)]
    pub struct M64x4 {
        simd: V3,
        m: __m256d,
    }

    impl F64x4 {
        /// The lanes `lanes`.
        #[inline(always)]
        pub fn new(simd: V3, lanes: [f64; 4]) -> Self {
            Self {
                simd,
                v: bytemuck::cast(lanes),
            }
        }

        #[inline(always)]
        fn with(self, v: __m256d) -> Self {
            Self { simd: self.simd, v }
        }

        #[inline(always)]
        fn compare<const PREDICATE: i32>(self, y: Self) -> M64x4 {
            M64x4 {
                simd: self.simd,
                m: self.simd.avx._mm256_cmp_pd::<PREDICATE>(self.v, y.v),
            }
        }
    }

    impl M64x4 {
        #[inline(always)]
        fn with(self, m: __m256d) -> Self {
            Self { simd: self.simd, m }
        }
    }

    macro_rules! binary {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for F64x4 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, rhs: Self) -> Self {
                    self.with(self.simd.avx.$intrinsic(self.v, rhs.v))
                }
            }
            impl $trait<f64> for F64x4 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, rhs: f64) -> Self {
                    self.$method(self.splat(rhs))
                }
            }
        };
    }
    binary!(Add, add, _mm256_add_pd);
    binary!(Sub, sub, _mm256_sub_pd);
    binary!(Mul, mul, _mm256_mul_pd);
    binary!(Div, div, _mm256_div_pd);

    impl Neg for F64x4 {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            self.with(self.simd.avx._mm256_xor_pd(self.v, self.splat(-0.0).v))
        }
    }

    impl BitAnd for M64x4 {
        type Output = Self;
        #[inline(always)]
        fn bitand(self, rhs: Self) -> Self {
            self.with(self.simd.avx._mm256_and_pd(self.m, rhs.m))
        }
    }

    impl BitOr for M64x4 {
        type Output = Self;
        #[inline(always)]
        fn bitor(self, rhs: Self) -> Self {
            self.with(self.simd.avx._mm256_or_pd(self.m, rhs.m))
        }
    }

    impl Not for M64x4 {
        type Output = Self;
        #[inline(always)]
        fn not(self) -> Self {
            let avx = self.simd.avx;
            let ones = avx._mm256_castsi256_pd(avx._mm256_set1_epi64x(-1));
            self.with(avx._mm256_xor_pd(self.m, ones))
        }
    }

    impl Real for F64x4 {
        type Mask = M64x4;
        type Array = [f64; 4];
        #[inline(always)]
        fn splat(self, x: f64) -> Self {
            self.with(self.simd.avx._mm256_set1_pd(x))
        }
        #[inline(always)]
        fn load(self, lanes: [f64; 4]) -> Self {
            Self::new(self.simd, lanes)
        }
        #[inline(always)]
        fn store(self) -> [f64; 4] {
            bytemuck::cast(self.v)
        }
        #[inline(always)]
        fn bits(mask: M64x4) -> u32 {
            mask.simd.avx._mm256_movemask_pd(mask.m) as u32
        }
        #[inline(always)]
        fn select(mask: M64x4, a: Self, b: Self) -> Self {
            a.with(a.simd.avx._mm256_blendv_pd(b.v, a.v, mask.m))
        }
        #[inline(always)]
        fn lt(self, y: Self) -> M64x4 {
            self.compare::<_CMP_LT_OQ>(y)
        }
        #[inline(always)]
        fn le(self, y: Self) -> M64x4 {
            self.compare::<_CMP_LE_OQ>(y)
        }
        #[inline(always)]
        fn gt(self, y: Self) -> M64x4 {
            self.compare::<_CMP_GT_OQ>(y)
        }
        #[inline(always)]
        fn ge(self, y: Self) -> M64x4 {
            self.compare::<_CMP_GE_OQ>(y)
        }
        #[inline(always)]
        fn ne(self, y: Self) -> M64x4 {
            self.compare::<_CMP_NEQ_UQ>(y)
        }
        #[inline(always)]
        fn is_finite(self) -> M64x4 {
            self.abs().lt(self.splat(f64::INFINITY))
        }
        #[inline(always)]
        fn any(mask: M64x4) -> bool {
            Self::bits(mask) != 0
        }
        #[inline(always)]
        fn all(mask: M64x4) -> bool {
            Self::bits(mask) == 0b1111
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            self.with(self.simd.avx._mm256_sqrt_pd(self.v))
        }
        #[inline(always)]
        fn abs(self) -> Self {
            self.with(self.simd.avx._mm256_andnot_pd(self.splat(-0.0).v, self.v))
        }
        #[inline(always)]
        fn copysign(self, sign: Self) -> Self {
            let avx = self.simd.avx;
            let sign_bit = self.splat(-0.0).v;
            let magnitude = avx._mm256_andnot_pd(sign_bit, self.v);
            self.with(avx._mm256_or_pd(magnitude, avx._mm256_and_pd(sign_bit, sign.v)))
        }
        #[inline(always)]
        fn max(self, y: Self) -> Self {
            // MAXPD returns its second operand unless the first is greater.
            self.with(self.simd.avx._mm256_max_pd(self.v, y.v))
        }
        #[inline(always)]
        fn map(self, f: impl Fn(f64) -> f64) -> Self {
            let mut lanes = self.store();
            for x in &mut lanes {
                *x = f(*x);
            }
            self.load(lanes)
        }
        #[inline(always)]
        fn exp2_of_shifted(self) -> Self {
            let (avx, avx2) = (self.simd.avx, self.simd.avx2);
            let bits = avx._mm256_castpd_si256(self.v);
            let bias = avx._mm256_set1_epi64x(SHIFTED_TO_BIASED as i64);
            let biased = avx2._mm256_sub_epi64(bits, bias);
            self.with(avx._mm256_castsi256_pd(avx2._mm256_slli_epi64::<52>(biased)))
        }
    }

    /// Eight `f64` lanes in two AVX2 registers.
    #[derive(Debug, Clone, Copy)]
    pub struct F64x8([F64x4; 2]);

    /// Eight lane conditions.
    #[derive(Debug, Clone, Copy)]
    pub struct M64x8([M64x4; 2]);

    impl F64x8 {
        /// The lanes `lanes`.
        #[inline(always)]
        pub fn new(simd: V3, lanes: [f64; 8]) -> Self {
            let [a, b]: [[f64; 4]; 2] = bytemuck::cast(lanes);
            Self([F64x4::new(simd, a), F64x4::new(simd, b)])
        }
    }

    macro_rules! pair_binary {
        ($trait:ident, $method:ident) => {
            impl $trait for F64x8 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, rhs: Self) -> Self {
                    let ([a0, a1], [b0, b1]) = (self.0, rhs.0);
                    Self([a0.$method(b0), a1.$method(b1)])
                }
            }
            impl $trait<f64> for F64x8 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, rhs: f64) -> Self {
                    self.each(|a| a.$method(rhs))
                }
            }
        };
    }
    pair_binary!(Add, add);
    pair_binary!(Sub, sub);
    pair_binary!(Mul, mul);
    pair_binary!(Div, div);

    impl Neg for F64x8 {
        type Output = Self;
        #[inline(always)]
        fn neg(self) -> Self {
            self.each(|a| -a)
        }
    }

    impl BitAnd for M64x8 {
        type Output = Self;
        #[inline(always)]
        fn bitand(self, rhs: Self) -> Self {
            Self([self.0[0] & rhs.0[0], self.0[1] & rhs.0[1]])
        }
    }

    impl BitOr for M64x8 {
        type Output = Self;
        #[inline(always)]
        fn bitor(self, rhs: Self) -> Self {
            Self([self.0[0] | rhs.0[0], self.0[1] | rhs.0[1]])
        }
    }

    impl Not for M64x8 {
        type Output = Self;
        #[inline(always)]
        fn not(self) -> Self {
            Self([!self.0[0], !self.0[1]])
        }
    }

    impl F64x8 {
        // Explicit halves, no `[T; 2]::map`: that goes through iterator
        // machinery the inliner may leave as calls, and a call would lose
        // the SIMD context of the intrinsics inside.
        #[inline(always)]
        fn each(self, f: impl Fn(F64x4) -> F64x4) -> Self {
            Self([f(self.0[0]), f(self.0[1])])
        }

        #[inline(always)]
        fn zip(self, y: Self, f: impl Fn(F64x4, F64x4) -> F64x4) -> Self {
            Self([f(self.0[0], y.0[0]), f(self.0[1], y.0[1])])
        }

        #[inline(always)]
        fn compare(self, y: Self, f: impl Fn(F64x4, F64x4) -> M64x4) -> M64x8 {
            M64x8([f(self.0[0], y.0[0]), f(self.0[1], y.0[1])])
        }
    }

    impl Real for F64x8 {
        type Mask = M64x8;
        type Array = [f64; 8];
        #[inline(always)]
        fn splat(self, x: f64) -> Self {
            let half = self.0[0].splat(x);
            Self([half, half])
        }
        #[inline(always)]
        fn load(self, lanes: [f64; 8]) -> Self {
            Self::new(self.0[0].simd, lanes)
        }
        #[inline(always)]
        fn store(self) -> [f64; 8] {
            bytemuck::cast([self.0[0].store(), self.0[1].store()])
        }
        #[inline(always)]
        fn bits(mask: M64x8) -> u32 {
            F64x4::bits(mask.0[0]) | (F64x4::bits(mask.0[1]) << 4)
        }
        #[inline(always)]
        fn select(mask: M64x8, a: Self, b: Self) -> Self {
            Self([
                F64x4::select(mask.0[0], a.0[0], b.0[0]),
                F64x4::select(mask.0[1], a.0[1], b.0[1]),
            ])
        }
        #[inline(always)]
        fn lt(self, y: Self) -> M64x8 {
            self.compare(y, F64x4::lt)
        }
        #[inline(always)]
        fn le(self, y: Self) -> M64x8 {
            self.compare(y, F64x4::le)
        }
        #[inline(always)]
        fn gt(self, y: Self) -> M64x8 {
            self.compare(y, F64x4::gt)
        }
        #[inline(always)]
        fn ge(self, y: Self) -> M64x8 {
            self.compare(y, F64x4::ge)
        }
        #[inline(always)]
        fn ne(self, y: Self) -> M64x8 {
            self.compare(y, F64x4::ne)
        }
        #[inline(always)]
        fn is_finite(self) -> M64x8 {
            M64x8([self.0[0].is_finite(), self.0[1].is_finite()])
        }
        #[inline(always)]
        fn any(mask: M64x8) -> bool {
            F64x4::any(mask.0[0] | mask.0[1])
        }
        #[inline(always)]
        fn all(mask: M64x8) -> bool {
            F64x4::all(mask.0[0] & mask.0[1])
        }
        #[inline(always)]
        fn sqrt(self) -> Self {
            self.each(F64x4::sqrt)
        }
        #[inline(always)]
        fn abs(self) -> Self {
            self.each(F64x4::abs)
        }
        #[inline(always)]
        fn copysign(self, sign: Self) -> Self {
            self.zip(sign, F64x4::copysign)
        }
        #[inline(always)]
        fn max(self, y: Self) -> Self {
            self.zip(y, F64x4::max)
        }
        #[inline(always)]
        fn map(self, f: impl Fn(f64) -> f64) -> Self {
            self.each(|a| a.map(&f))
        }
        #[inline(always)]
        fn exp2_of_shifted(self) -> Self {
            self.each(F64x4::exp2_of_shifted)
        }
    }
}
