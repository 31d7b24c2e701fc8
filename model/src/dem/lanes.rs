//! The number type the contact laws are written in: one contact (`Real`, walls) or
//! [`LANES`] contacts at once ([`Lanes`], grain pairs). A law written once over [`Num`] runs
//! both ways; on `Lanes` every operation is a fixed-length element loop with no branches,
//! which the compiler turns into vector instructions (sqrt and division included), so four
//! independent contacts advance together instead of queueing on one chain of latencies.
//! Each lane computes exactly what the scalar code computes (IEEE operations, no fusing),
//! so results do not depend on how many contacts share a group.

use std::ops::{Add, Div, Mul, Neg, Sub};

use crate::Real;

/// Contacts per group in the pair phase.
pub const LANES: usize = 4;

/// Arithmetic the contact laws need, with branch-free selection.
pub trait Num:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    /// Per-lane truth value.
    type Mask: Copy;
    /// Every lane `x`.
    fn splat(x: Real) -> Self;
    fn sqrt(self) -> Self;
    /// Lane-wise maximum (`self` when either is NaN, like `f64::max` on a NaN `other`).
    fn max(self, other: Self) -> Self;
    /// Lane-wise `self > other`.
    fn gt(self, other: Self) -> Self::Mask;
    /// Lane-wise `a && b`.
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// True when the mask holds in some lane: lets a law skip work no lane needs (one
    /// predictable branch per group, not one per contact).
    fn any(mask: Self::Mask) -> bool;
    /// Lane-wise `if mask { a } else { b }`; both are computed, so a lane not taken may
    /// hold inf or NaN harmlessly.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;
}

impl Num for Real {
    type Mask = bool;
    #[inline(always)]
    fn splat(x: Real) -> Self {
        x
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Real::sqrt(self)
    }
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        if other > self {
            other
        } else {
            self
        }
    }
    #[inline(always)]
    fn gt(self, other: Self) -> bool {
        self > other
    }
    #[inline(always)]
    fn and(a: bool, b: bool) -> bool {
        a & b
    }
    #[inline(always)]
    fn any(mask: bool) -> bool {
        mask
    }
    #[inline(always)]
    fn select(mask: bool, a: Self, b: Self) -> Self {
        if mask {
            a
        } else {
            b
        }
    }
}

/// [`LANES`] values, one per contact of a group.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lanes(pub [Real; LANES]);

impl Lanes {
    #[inline(always)]
    fn map2(self, o: Self, f: impl Fn(Real, Real) -> Real) -> Self {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = f(self.0[l], o.0[l]);
        }
        Lanes(r)
    }
}

macro_rules! lane_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl $tr for Lanes {
            type Output = Lanes;
            #[inline(always)]
            fn $f(self, o: Lanes) -> Lanes {
                self.map2(o, |a, b| a $op b)
            }
        }
    };
}
lane_op!(Add, add, +);
lane_op!(Sub, sub, -);
lane_op!(Mul, mul, *);
lane_op!(Div, div, /);

impl Neg for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn neg(self) -> Lanes {
        Lanes(self.0.map(|a| -a))
    }
}

impl Num for Lanes {
    type Mask = [bool; LANES];
    #[inline(always)]
    fn splat(x: Real) -> Self {
        Lanes([x; LANES])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        Lanes(self.0.map(Real::sqrt))
    }
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        self.map2(other, <Real as Num>::max)
    }
    #[inline(always)]
    fn gt(self, other: Self) -> Self::Mask {
        let mut m = [false; LANES];
        for l in 0..LANES {
            m[l] = self.0[l] > other.0[l];
        }
        m
    }
    #[inline(always)]
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask {
        let mut m = [false; LANES];
        for l in 0..LANES {
            m[l] = a[l] & b[l];
        }
        m
    }
    #[inline(always)]
    fn any(mask: Self::Mask) -> bool {
        mask.iter().fold(false, |a, &m| a | m)
    }
    #[inline(always)]
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self {
        let mut r = [0.0; LANES];
        for l in 0..LANES {
            r[l] = if mask[l] { a.0[l] } else { b.0[l] };
        }
        Lanes(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_compute_what_each_scalar_computes() {
        let a = Lanes([1.0, -2.0, 0.0, 9.0]);
        let b = Lanes([3.0, 0.5, 0.0, -1.0]);
        let q = (a * b - a / Lanes::splat(7.0)).sqrt().max(b);
        for l in 0..LANES {
            let (x, y) = (a.0[l], b.0[l]);
            let s = <Real as Num>::max((x * y - x / 7.0).sqrt(), y);
            assert_eq!(q.0[l].to_bits(), s.to_bits(), "lane {l}");
        }
        let over_half = a.gt(Lanes::splat(0.5));
        let pick = Lanes::select(Lanes::and(over_half, Lanes::splat(9.0).gt(a)), a, b);
        assert_eq!(pick.0, [1.0, 0.5, 0.0, -1.0]);
        assert!(Lanes::any(a.gt(b)) && !Lanes::any(a.gt(Lanes::splat(10.0))));
    }
}
