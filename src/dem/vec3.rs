//! Minimal 3-vector arithmetic on `[Real; 3]` (inlined; the contact loop lives on these).

use crate::{Real, Vec3};

#[inline(always)]
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
#[inline(always)]
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
pub fn scale(a: Vec3, s: Real) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
#[inline(always)]
pub fn dot(a: Vec3, b: Vec3) -> Real {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
#[inline(always)]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline(always)]
pub fn norm2(a: Vec3) -> Real {
    dot(a, a)
}
#[inline(always)]
pub fn norm(a: Vec3) -> Real {
    dot(a, a).sqrt()
}
#[inline(always)]
pub fn add_assign(a: &mut Vec3, b: Vec3) {
    a[0] += b[0];
    a[1] += b[1];
    a[2] += b[2];
}
#[inline(always)]
pub fn sub_assign(a: &mut Vec3, b: Vec3) {
    a[0] -= b[0];
    a[1] -= b[1];
    a[2] -= b[2];
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
