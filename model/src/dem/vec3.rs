//! Minimal 3-vector arithmetic on `[T; 3]`, `T` one value or a group of lanes
//! ([`super::lanes::Num`]); inlined, the contact loop lives on these.

use super::lanes::Num;
use crate::Vec3;

#[inline(always)]
pub fn add<T: Num>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline(always)]
pub fn sub<T: Num>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
pub fn scale<T: Num>(a: [T; 3], s: T) -> [T; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline(always)]
pub fn dot<T: Num>(a: [T; 3], b: [T; 3]) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
pub fn cross<T: Num>(a: [T; 3], b: [T; 3]) -> [T; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline(always)]
pub fn norm2<T: Num>(a: [T; 3]) -> T {
    dot(a, a)
}
#[inline(always)]
pub fn norm<T: Num>(a: [T; 3]) -> T {
    dot(a, a).sqrt()
}
#[inline(always)]
pub fn add_assign<T: Num>(a: &mut [T; 3], b: [T; 3]) {
    a[0] = a[0] + b[0];
    a[1] = a[1] + b[1];
    a[2] = a[2] + b[2];
}
#[inline(always)]
pub fn sub_assign<T: Num>(a: &mut [T; 3], b: [T; 3]) {
    a[0] = a[0] - b[0];
    a[1] = a[1] - b[1];
    a[2] = a[2] - b[2];
}
/// `a / |a|`, or zero for the zero vector.
pub fn normalized(a: Vec3) -> Vec3 {
    let n = norm(a);
    if n > 0.0 {
        scale(a, 1.0 / n)
    } else {
        [0.0; 3]
    }
}
#[inline(always)]
pub fn is_finite(a: Vec3) -> bool {
    a[0].is_finite() && a[1].is_finite() && a[2].is_finite()
}
