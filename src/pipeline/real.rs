//! The scalar abstraction the pipeline math is generic over: `f32` (what kernels and the
//! G-buffer use) and `f64` (references, accuracy studies, the model-clip area test).
//!
//! Only what the clipper and the lighting model need is here: arithmetic, comparisons,
//! `sqrt`, `powf`, and exact conversion to `f64` for tests. Three-component vectors are plain
//! `[T; 3]` arrays with the few helpers below, so the same source serves both precisions
//! without pulling glam's two vector families into generic code.

use std::fmt::Debug;
use std::ops::{Add, Div, Mul, Neg, Sub};

/// A floating-point scalar: `f32` or `f64`.
pub trait Real:
    Copy
    + Debug
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Send
    + Sync
    + 'static
{
    const ZERO: Self;
    const ONE: Self;
    /// Converts with rounding to nearest (exact for `f64`).
    fn from_f64(v: f64) -> Self;
    /// Exact widening (identity for `f64`).
    fn to_f64(self) -> f64;
    fn sqrt(self) -> Self;
    fn abs(self) -> Self;
    fn powf(self, e: Self) -> Self;
    fn is_finite(self) -> bool;
    /// `self` unless it is NaN, then `other`; otherwise the larger (IEEE `maxNum`).
    fn max(self, other: Self) -> Self;
    fn min(self, other: Self) -> Self;
    /// Total order on the bit patterns (`f64::total_cmp`), used to order edge endpoints
    /// canonically so shared edges clip identically from both sides.
    fn total_cmp(&self, other: &Self) -> std::cmp::Ordering;
}

macro_rules! impl_real {
    ($t:ty) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            #[inline]
            fn from_f64(v: f64) -> Self {
                v as $t
            }
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline]
            fn powf(self, e: Self) -> Self {
                <$t>::powf(self, e)
            }
            #[inline]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline]
            fn max(self, other: Self) -> Self {
                <$t>::max(self, other)
            }
            #[inline]
            fn min(self, other: Self) -> Self {
                <$t>::min(self, other)
            }
            #[inline]
            fn total_cmp(&self, other: &Self) -> std::cmp::Ordering {
                <$t>::total_cmp(self, other)
            }
        }
    };
}

impl_real!(f32);
impl_real!(f64);

/// A 3-vector of either precision.
pub type V3<T> = [T; 3];

#[inline]
pub fn add3<T: Real>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline]
pub fn sub3<T: Real>(a: V3<T>, b: V3<T>) -> V3<T> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
pub fn scale3<T: Real>(a: V3<T>, s: T) -> V3<T> {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline]
pub fn dot3<T: Real>(a: V3<T>, b: V3<T>) -> T {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub fn cross3<T: Real>(a: V3<T>, b: V3<T>) -> V3<T> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
pub fn length3<T: Real>(a: V3<T>) -> T {
    dot3(a, a).sqrt()
}

/// `a / |a|`, or `None` when `a` is zero or not finite (the caller decides the fallback).
#[inline]
pub fn normalize3<T: Real>(a: V3<T>) -> Option<V3<T>> {
    let len = length3(a);
    if len > T::ZERO && len.is_finite() {
        Some(scale3(a, T::ONE / len))
    } else {
        None
    }
}
