//! Lane vectors for the fast shading kernels: [`LANES`] values of f32 ([`F32s`]), f64
//! ([`F64s`]) or a per-lane condition ([`Mask`]), with whole-vector arithmetic, comparisons
//! and selects, so the kernels read as straight-line maths over pixels and stay branch-free.
//!
//! The types are generic over an instruction set ([`Isa`]): [`Portable`] is element-wise
//! loops over arrays that the compiler vectorises as it can (SSE2 on the baseline x86-64
//! target); [`Avx2`] and [`Avx512`] hold each vector in registers (four AVX2 or two AVX-512
//! registers per 32 f32 lanes, twice that for f64) and compute it by explicit intrinsics.
//! Left to the auto-vectoriser, the same kernels split into 4-wide halves and spilled, at
//! twice the time. Every build performs the same IEEE operations in the same order and none
//! fuses a multiply-add, so a kernel's builds are bit-identical (NaN payloads aside).

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// Pixels per lane vector: several registers, so that each operation of the (latency-bound)
/// kernels has independent work beside it (measured in `fast.rs`'s documentation).
pub const LANES: usize = 32;

/// How lane vectors are represented and computed. Each operation is the IEEE operation of
/// the same name on every lane; comparisons are ordered (false when either side is NaN)
/// except `ne`; a mask lane is all ones (true) or all zeros.
pub trait Isa: Copy {
    type F32: Copy;
    type F64: Copy;
    type M: Copy;

    fn f32_from(a: &[f32; LANES]) -> Self::F32;
    fn f32_to(a: Self::F32) -> [f32; LANES];
    fn f32_splat(x: f32) -> Self::F32;
    fn f32_add(a: Self::F32, b: Self::F32) -> Self::F32;
    fn f32_sub(a: Self::F32, b: Self::F32) -> Self::F32;
    fn f32_mul(a: Self::F32, b: Self::F32) -> Self::F32;
    fn f32_div(a: Self::F32, b: Self::F32) -> Self::F32;
    fn f32_neg(a: Self::F32) -> Self::F32;
    fn f32_sqrt(a: Self::F32) -> Self::F32;
    fn f32_lt(a: Self::F32, b: Self::F32) -> Self::M;
    fn f32_eq(a: Self::F32, b: Self::F32) -> Self::M;
    fn f32_from_f64(a: Self::F64) -> Self::F32;

    fn f64_from(a: &[f64; LANES]) -> Self::F64;
    fn f64_splat(x: f64) -> Self::F64;
    fn f64_add(a: Self::F64, b: Self::F64) -> Self::F64;
    fn f64_sub(a: Self::F64, b: Self::F64) -> Self::F64;
    fn f64_mul(a: Self::F64, b: Self::F64) -> Self::F64;
    fn f64_div(a: Self::F64, b: Self::F64) -> Self::F64;
    fn f64_neg(a: Self::F64) -> Self::F64;
    fn f64_sqrt(a: Self::F64) -> Self::F64;
    fn f64_floor(a: Self::F64) -> Self::F64;
    fn f64_lt(a: Self::F64, b: Self::F64) -> Self::M;
    fn f64_eq(a: Self::F64, b: Self::F64) -> Self::M;
    fn f64_from_f32(a: Self::F32) -> Self::F64;
    fn f64_from_u32(a: &[u32; LANES]) -> Self::F64;

    fn m_from(a: &[u32; LANES]) -> Self::M;
    fn m_to(a: Self::M) -> [u32; LANES];
    /// Set where `a` is not zero.
    fn m_nonzero(a: &[u32; LANES]) -> Self::M;
    fn m_and(a: Self::M, b: Self::M) -> Self::M;
    fn m_or(a: Self::M, b: Self::M) -> Self::M;
    fn m_not(a: Self::M) -> Self::M;
    fn m_any(a: Self::M) -> bool;
    fn select_f32(m: Self::M, a: Self::F32, b: Self::F32) -> Self::F32;
    fn select_f64(m: Self::M, a: Self::F64, b: Self::F64) -> Self::F64;
    /// `out[j] = [r[j], g[j], b[j]]`.
    fn store_rgb(r: Self::F32, g: Self::F32, b: Self::F32, out: &mut [[f32; 3]; LANES]);
}

/// `LANES` f32 values.
pub struct F32s<I: Isa>(I::F32);
/// `LANES` f64 values.
pub struct F64s<I: Isa>(#[doc(hidden)] pub I::F64);
/// A per-lane condition.
pub struct Mask<I: Isa>(I::M);

// Derives would demand `I: Copy` of the wrappers' users; the representations are Copy.
impl<I: Isa> Clone for F32s<I> {
    #[inline(always)]
    fn clone(&self) -> Self {
        *self
    }
}
impl<I: Isa> Copy for F32s<I> {}
impl<I: Isa> Clone for F64s<I> {
    #[inline(always)]
    fn clone(&self) -> Self {
        *self
    }
}
impl<I: Isa> Copy for F64s<I> {}
impl<I: Isa> Clone for Mask<I> {
    #[inline(always)]
    fn clone(&self) -> Self {
        *self
    }
}
impl<I: Isa> Copy for Mask<I> {}

/// `LANES` values of `plane` from `x0`, `fill` past its end: one fixed-size copy for a whole
/// vector (the common case), element by element for the row's tail.
#[inline(always)]
pub fn load<T: Copy>(plane: &[T], x0: usize, fill: T) -> [T; LANES] {
    let mut a = [fill; LANES];
    match plane.get(x0..x0 + LANES) {
        Some(whole) => a.copy_from_slice(whole),
        None => {
            for (dst, src) in a.iter_mut().zip(plane.get(x0..).unwrap_or(&[])) {
                *dst = *src;
            }
        }
    }
    a
}

// Macros, not closures, for the per-component expressions of the kernels: a closure is a
// function of its own, compiled without the target feature, and the intrinsics called in it
// would not inline (a call per operation, ten times slower).

/// `[e(0), e(1), e(2)]`: `xyz!(k => e)` evaluates `e` with `k` = 0, 1, 2.
macro_rules! xyz {
    ($k:ident => $e:expr) => {
        [
            {
                let $k = 0;
                $e
            },
            {
                let $k = 1;
                $e
            },
            {
                let $k = 2;
                $e
            },
        ]
    };
}

/// `map3!(v, c => e)`: `e` for each component `c` of the three-vector `v`.
macro_rules! map3 {
    ($v:expr, $c:ident => $e:expr) => {{
        let v = $v;
        [
            {
                let $c = v[0];
                $e
            },
            {
                let $c = v[1];
                $e
            },
            {
                let $c = v[2];
                $e
            },
        ]
    }};
}
pub(super) use {map3, xyz};

macro_rules! float_lanes {
    ($v:ident, $s:ty, $from:ident, $splat:ident, $add:ident, $sub:ident, $mul:ident, $div:ident,
     $neg:ident, $sqrt:ident, $lt:ident, $eq:ident, $select:ident) => {
        impl<I: Isa> $v<I> {
            #[inline(always)]
            pub fn new(a: [$s; LANES]) -> Self {
                $v(I::$from(&a))
            }
            #[inline(always)]
            pub fn splat(x: $s) -> Self {
                $v(I::$splat(x))
            }
            /// `LANES` values of `plane` from `x0` (zero past its end).
            #[inline(always)]
            pub fn load(plane: &[$s], x0: usize) -> Self {
                match plane.get(x0..x0 + LANES).map(<&[$s; LANES]>::try_from) {
                    // Straight from the plane: no copy.
                    Some(Ok(whole)) => $v(I::$from(whole)),
                    _ => Self::new(load(plane, x0, 0.0)),
                }
            }
            #[inline(always)]
            pub fn sqrt(self) -> Self {
                $v(I::$sqrt(self.0))
            }
            #[inline(always)]
            pub fn lt(self, o: Self) -> Mask<I> {
                Mask(I::$lt(self.0, o.0))
            }
            #[inline(always)]
            pub fn gt(self, o: Self) -> Mask<I> {
                Mask(I::$lt(o.0, self.0))
            }
            #[inline(always)]
            pub fn equals(self, o: Self) -> Mask<I> {
                Mask(I::$eq(self.0, o.0))
            }
            /// Lanes whose value is finite (`x - x` is zero only for finite `x`).
            #[inline(always)]
            pub fn finite(self) -> Mask<I> {
                (self - self).equals(Self::splat(0.0))
            }
            /// `self` where finite, zero elsewhere.
            #[inline(always)]
            pub fn or_zero_if_not_finite(self) -> Self {
                self.finite().select(self, Self::splat(0.0))
            }
            #[inline(always)]
            pub fn dot(a: &[Self; 3], b: &[Self; 3]) -> Self {
                a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
            }
        }
        impl<I: Isa> Select<I> for $v<I> {
            #[inline(always)]
            fn select(m: Mask<I>, a: Self, b: Self) -> Self {
                $v(I::$select(m.0, a.0, b.0))
            }
        }
        float_lanes!(@op $v, $s, Add, add, $add);
        float_lanes!(@op $v, $s, Sub, sub, $sub);
        float_lanes!(@op $v, $s, Mul, mul, $mul);
        float_lanes!(@op $v, $s, Div, div, $div);
        impl<I: Isa> Neg for $v<I> {
            type Output = Self;
            #[inline(always)]
            fn neg(self) -> Self {
                $v(I::$neg(self.0))
            }
        }
    };
    (@op $v:ident, $s:ty, $trait:ident, $method:ident, $isa:ident) => {
        impl<I: Isa> $trait for $v<I> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                $v(I::$isa(self.0, o.0))
            }
        }
    };
}

/// `vector op scalar` and `scalar op vector`: the scalar splatted.
macro_rules! scalar_operands {
    ($v:ident, $s:ty, $splat:ident, $($trait:ident $method:ident $isa:ident),*) => {$(
        impl<I: Isa> $trait<$s> for $v<I> {
            type Output = $v<I>;
            #[inline(always)]
            fn $method(self, o: $s) -> $v<I> {
                $v(I::$isa(self.0, I::$splat(o)))
            }
        }
        impl<I: Isa> $trait<$v<I>> for $s {
            type Output = $v<I>;
            #[inline(always)]
            fn $method(self, o: $v<I>) -> $v<I> {
                $v(I::$isa(I::$splat(self), o.0))
            }
        }
    )*};
}

float_lanes!(
    F32s, f32, f32_from, f32_splat, f32_add, f32_sub, f32_mul, f32_div, f32_neg, f32_sqrt, f32_lt, f32_eq, select_f32
);
float_lanes!(
    F64s, f64, f64_from, f64_splat, f64_add, f64_sub, f64_mul, f64_div, f64_neg, f64_sqrt, f64_lt, f64_eq, select_f64
);
scalar_operands!(F32s, f32, f32_splat, Add add f32_add, Sub sub f32_sub, Mul mul f32_mul, Div div f32_div);
scalar_operands!(F64s, f64, f64_splat, Add add f64_add, Sub sub f64_sub, Mul mul f64_mul, Div div f64_div);

impl<I: Isa> F32s<I> {
    /// `out[j] = [r[j], g[j], b[j]]`.
    #[inline(always)]
    pub fn store_rgb(r: Self, g: Self, b: Self, out: &mut [[f32; 3]; LANES]) {
        I::store_rgb(r.0, g.0, b.0, out)
    }
    /// The lanes as an array.
    #[inline(always)]
    pub fn lanes(self) -> [f32; LANES] {
        I::f32_to(self.0)
    }
    /// Rounded to f32, lane by lane.
    #[inline(always)]
    pub fn from_f64(v: F64s<I>) -> Self {
        F32s(I::f32_from_f64(v.0))
    }
    /// `f` of each lane and the same lane of `o`, one lane at a time (for what has no
    /// vector form).
    #[inline(always)]
    pub fn zip(self, o: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        let (a, b) = (self.lanes(), o.lanes());
        let mut r = [0f32; LANES];
        for j in 0..LANES {
            r[j] = f(a[j], b[j]);
        }
        Self::new(r)
    }
}

impl<I: Isa> F64s<I> {
    #[inline(always)]
    pub fn from_f32(v: F32s<I>) -> Self {
        F64s(I::f64_from_f32(v.0))
    }
    #[inline(always)]
    pub fn from_u32(v: &[u32; LANES]) -> Self {
        F64s(I::f64_from_u32(v))
    }
    #[inline(always)]
    pub fn floor(self) -> Self {
        F64s(I::f64_floor(self.0))
    }
    /// `a != b` lane by lane (true where either is NaN).
    #[inline(always)]
    pub fn not_equal(self, o: Self) -> Mask<I> {
        !self.equals(o)
    }
}

/// Lane vectors a [`Mask`] chooses between.
pub trait Select<I: Isa> {
    fn select(mask: Mask<I>, if_set: Self, if_clear: Self) -> Self;
}

impl<I: Isa> Select<I> for Mask<I> {
    #[inline(always)]
    fn select(m: Mask<I>, a: Self, b: Self) -> Self {
        (m & a) | (!m & b)
    }
}

impl<I: Isa> Mask<I> {
    #[inline(always)]
    pub fn all() -> Self {
        Mask(I::m_from(&[u32::MAX; LANES]))
    }
    #[inline(always)]
    pub fn none() -> Self {
        Mask(I::m_from(&[0; LANES]))
    }
    /// Set where `v` is not zero.
    #[inline(always)]
    pub fn nonzero(v: &[u32; LANES]) -> Self {
        Mask(I::m_nonzero(v))
    }
    /// Whether any lane is set.
    #[inline(always)]
    pub fn any(self) -> bool {
        I::m_any(self.0)
    }
    /// Each lane set (true) or not.
    #[inline(always)]
    pub fn lanes(self) -> [bool; LANES] {
        I::m_to(self.0).map(|m| m != 0)
    }
    /// `if_set` where the mask is set, `if_clear` elsewhere.
    #[inline(always)]
    pub fn select<V: Select<I>>(self, if_set: V, if_clear: V) -> V {
        V::select(self, if_set, if_clear)
    }
}

impl<I: Isa> BitAnd for Mask<I> {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, o: Self) -> Self {
        Mask(I::m_and(self.0, o.0))
    }
}

impl<I: Isa> BitOr for Mask<I> {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, o: Self) -> Self {
        Mask(I::m_or(self.0, o.0))
    }
}

impl<I: Isa> Not for Mask<I> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        Mask(I::m_not(self.0))
    }
}

/// 0, 1, ..., `LANES - 1`.
#[inline(always)]
pub fn lane_index() -> [u32; LANES] {
    let mut r = [0; LANES];
    for (j, lane) in r.iter_mut().enumerate() {
        *lane = j as u32;
    }
    r
}

// ---------------------------------------------------------------------------------------
// Portable: arrays and element-wise loops. Plain loops, not `array::map` or `from_fn`: those
// are not always inlined, and a call per operation would cost more than the operation.
// ---------------------------------------------------------------------------------------

/// Element-wise loops over arrays, for any target.
#[derive(Clone, Copy)]
pub struct Portable;

#[inline(always)]
fn each<T: Copy, R: Copy + Default>(a: [T; LANES], f: impl Fn(T) -> R) -> [R; LANES] {
    let mut r = [R::default(); LANES];
    for j in 0..LANES {
        r[j] = f(a[j]);
    }
    r
}

#[inline(always)]
fn zip<T: Copy, U: Copy, R: Copy + Default>(a: [T; LANES], b: [U; LANES], f: impl Fn(T, U) -> R) -> [R; LANES] {
    let mut r = [R::default(); LANES];
    for j in 0..LANES {
        r[j] = f(a[j], b[j]);
    }
    r
}

#[inline(always)]
fn flag(b: bool) -> u32 {
    if b {
        u32::MAX
    } else {
        0
    }
}

impl Isa for Portable {
    type F32 = [f32; LANES];
    type F64 = [f64; LANES];
    type M = [u32; LANES];

    #[inline(always)]
    fn f32_from(a: &[f32; LANES]) -> Self::F32 {
        *a
    }
    #[inline(always)]
    fn f32_to(a: Self::F32) -> [f32; LANES] {
        a
    }
    #[inline(always)]
    fn f32_splat(x: f32) -> Self::F32 {
        [x; LANES]
    }
    #[inline(always)]
    fn f32_add(a: Self::F32, b: Self::F32) -> Self::F32 {
        zip(a, b, |a, b| a + b)
    }
    #[inline(always)]
    fn f32_sub(a: Self::F32, b: Self::F32) -> Self::F32 {
        zip(a, b, |a, b| a - b)
    }
    #[inline(always)]
    fn f32_mul(a: Self::F32, b: Self::F32) -> Self::F32 {
        zip(a, b, |a, b| a * b)
    }
    #[inline(always)]
    fn f32_div(a: Self::F32, b: Self::F32) -> Self::F32 {
        zip(a, b, |a, b| a / b)
    }
    #[inline(always)]
    fn f32_neg(a: Self::F32) -> Self::F32 {
        each(a, |a| -a)
    }
    #[inline(always)]
    fn f32_sqrt(a: Self::F32) -> Self::F32 {
        each(a, f32::sqrt)
    }
    #[inline(always)]
    fn f32_lt(a: Self::F32, b: Self::F32) -> Self::M {
        zip(a, b, |a, b| flag(a < b))
    }
    #[inline(always)]
    fn f32_eq(a: Self::F32, b: Self::F32) -> Self::M {
        zip(a, b, |a, b| flag(a == b))
    }
    #[inline(always)]
    fn f32_from_f64(a: Self::F64) -> Self::F32 {
        each(a, |a| a as f32)
    }

    #[inline(always)]
    fn f64_from(a: &[f64; LANES]) -> Self::F64 {
        *a
    }
    #[inline(always)]
    fn f64_splat(x: f64) -> Self::F64 {
        [x; LANES]
    }
    #[inline(always)]
    fn f64_add(a: Self::F64, b: Self::F64) -> Self::F64 {
        zip(a, b, |a, b| a + b)
    }
    #[inline(always)]
    fn f64_sub(a: Self::F64, b: Self::F64) -> Self::F64 {
        zip(a, b, |a, b| a - b)
    }
    #[inline(always)]
    fn f64_mul(a: Self::F64, b: Self::F64) -> Self::F64 {
        zip(a, b, |a, b| a * b)
    }
    #[inline(always)]
    fn f64_div(a: Self::F64, b: Self::F64) -> Self::F64 {
        zip(a, b, |a, b| a / b)
    }
    #[inline(always)]
    fn f64_neg(a: Self::F64) -> Self::F64 {
        each(a, |a| -a)
    }
    #[inline(always)]
    fn f64_sqrt(a: Self::F64) -> Self::F64 {
        each(a, f64::sqrt)
    }
    #[inline(always)]
    fn f64_floor(a: Self::F64) -> Self::F64 {
        each(a, f64::floor)
    }
    #[inline(always)]
    fn f64_lt(a: Self::F64, b: Self::F64) -> Self::M {
        zip(a, b, |a, b| flag(a < b))
    }
    #[inline(always)]
    fn f64_eq(a: Self::F64, b: Self::F64) -> Self::M {
        zip(a, b, |a, b| flag(a == b))
    }
    #[inline(always)]
    fn f64_from_f32(a: Self::F32) -> Self::F64 {
        each(a, f64::from)
    }
    #[inline(always)]
    fn f64_from_u32(a: &[u32; LANES]) -> Self::F64 {
        each(*a, f64::from)
    }

    #[inline(always)]
    fn m_from(a: &[u32; LANES]) -> Self::M {
        *a
    }
    #[inline(always)]
    fn m_to(a: Self::M) -> [u32; LANES] {
        a
    }
    #[inline(always)]
    fn m_nonzero(a: &[u32; LANES]) -> Self::M {
        each(*a, |a| flag(a != 0))
    }
    #[inline(always)]
    fn m_and(a: Self::M, b: Self::M) -> Self::M {
        zip(a, b, |a, b| a & b)
    }
    #[inline(always)]
    fn m_or(a: Self::M, b: Self::M) -> Self::M {
        zip(a, b, |a, b| a | b)
    }
    #[inline(always)]
    fn m_not(a: Self::M) -> Self::M {
        each(a, |a| !a)
    }
    #[inline(always)]
    fn m_any(a: Self::M) -> bool {
        a != [0; LANES]
    }
    // Bit operations, not `if`: a select between two constants can compile to a select of
    // addresses and per-lane scalar loads.
    #[inline(always)]
    fn select_f32(m: Self::M, a: Self::F32, b: Self::F32) -> Self::F32 {
        let mut r = [0f32; LANES];
        for j in 0..LANES {
            r[j] = f32::from_bits((a[j].to_bits() & m[j]) | (b[j].to_bits() & !m[j]));
        }
        r
    }
    #[inline(always)]
    fn select_f64(m: Self::M, a: Self::F64, b: Self::F64) -> Self::F64 {
        let mut r = [0f64; LANES];
        for j in 0..LANES {
            let wide = u64::from(m[j]) | (u64::from(m[j]) << 32);
            r[j] = f64::from_bits((a[j].to_bits() & wide) | (b[j].to_bits() & !wide));
        }
        r
    }
    #[inline(always)]
    fn store_rgb(r: Self::F32, g: Self::F32, b: Self::F32, out: &mut [[f32; 3]; LANES]) {
        for (j, px) in out.iter_mut().enumerate() {
            *px = [r[j], g[j], b[j]];
        }
    }
}

// ---------------------------------------------------------------------------------------
// AVX2: explicit intrinsics.
// ---------------------------------------------------------------------------------------

/// `r[i] = op(a[i], b[i])` over the registers of a vector (the intrinsic modules' one
/// shape of operation). Loops and macros, never closures: a closure is compiled without the
/// target feature and the intrinsics in it would not inline.
#[cfg(target_arch = "x86_64")]
macro_rules! per_register {
    ($n:expr, $op:ident, $a:expr) => {{
        let a = $a;
        let mut r = a;
        for i in 0..$n {
            r[i] = unsafe { $op(a[i]) };
        }
        r
    }};
    ($n:expr, $op:ident, $a:expr, $b:expr) => {{
        let (a, b) = ($a, $b);
        let mut r = a;
        for i in 0..$n {
            r[i] = unsafe { $op(a[i], b[i]) };
        }
        r
    }};
}

/// A computation over lane vectors, to run on each instruction set with [`on_each_isa`].
#[doc(hidden)]
pub trait LaneProgram {
    fn run<I: Isa>() -> Vec<u64>;
}

/// `P` on the portable lanes, then on AVX2 and AVX-512 where this CPU has them: (build,
/// result) each, for tests that compare the builds. The AVX types are not public, and this
/// detects the CPU before it runs them, so no code outside the crate executes their
/// instructions unchecked.
#[doc(hidden)]
pub fn on_each_isa<P: LaneProgram>() -> Vec<(&'static str, Vec<u64>)> {
    let mut out = vec![("portable", P::run::<Portable>())];
    #[cfg(target_arch = "x86_64")]
    {
        if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
            #[target_feature(enable = "avx2,fma")]
            unsafe fn on_avx2<P: LaneProgram>() -> Vec<u64> {
                P::run::<Avx2>()
            }
            // SAFETY: the CPU has AVX2 and FMA (checked above).
            out.push(("AVX2", unsafe { on_avx2::<P>() }));
        }
        if is_x86_feature_detected!("avx512f") && is_x86_feature_detected!("avx512dq") {
            #[target_feature(enable = "avx512f,avx512dq")]
            unsafe fn on_avx512<P: LaneProgram>() -> Vec<u64> {
                P::run::<Avx512>()
            }
            // SAFETY: the CPU has AVX-512 F and DQ (checked above).
            out.push(("AVX-512", unsafe { on_avx512::<P>() }));
        }
    }
    out
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx2::Avx2;

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Isa, LANES};
    use std::arch::x86_64::*;

    /// AVX2 registers: `LANES / 8` per f32 vector and mask, twice that per f64 vector. Only
    /// code running on a CPU with AVX2 may use this type: its operations execute AVX2
    /// instructions unchecked. The shading pass instantiates its kernels with it only
    /// inside a `#[target_feature(enable = "avx2")]` function called after run-time
    /// detection, which is also what lets the intrinsics inline.
    #[derive(Clone, Copy)]
    pub struct Avx2;

    /// Registers per f32 vector.
    const R: usize = LANES / 8;

    #[inline(always)]
    unsafe fn neg_ps(a: __m256) -> __m256 {
        _mm256_xor_ps(a, _mm256_set1_ps(-0.0))
    }
    #[inline(always)]
    unsafe fn neg_pd(a: __m256d) -> __m256d {
        _mm256_xor_pd(a, _mm256_set1_pd(-0.0))
    }
    #[inline(always)]
    unsafe fn lt_ps(a: __m256, b: __m256) -> __m256i {
        _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LT_OQ>(a, b))
    }
    #[inline(always)]
    unsafe fn eq_ps(a: __m256, b: __m256) -> __m256i {
        _mm256_castps_si256(_mm256_cmp_ps::<_CMP_EQ_OQ>(a, b))
    }
    #[inline(always)]
    unsafe fn not_si256(a: __m256i) -> __m256i {
        _mm256_xor_si256(a, _mm256_set1_epi32(-1))
    }

    /// Two f64 comparison results (64-bit lanes, all ones or zeros) as one register of
    /// 32-bit mask lanes: the low half of each.
    #[inline(always)]
    unsafe fn narrow(lo: __m256d, hi: __m256d) -> __m256i {
        let even = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
        let lo = _mm256_permutevar8x32_epi32(_mm256_castpd_si256(lo), even);
        let hi = _mm256_permutevar8x32_epi32(_mm256_castpd_si256(hi), even);
        _mm256_permute2x128_si256::<0x20>(lo, hi)
    }

    // Every `unsafe` here: the intrinsics need AVX2 (and AVX), which the user of `Avx2`
    // guarantees (see the type's documentation); loads and stores are unaligned ones of
    // whole local arrays.
    impl Isa for Avx2 {
        type F32 = [__m256; R];
        type F64 = [__m256d; 2 * R];
        type M = [__m256i; R];

        #[inline(always)]
        fn f32_from(a: &[f32; LANES]) -> Self::F32 {
            let mut r = [unsafe { _mm256_setzero_ps() }; R];
            for (i, v) in r.iter_mut().enumerate() {
                *v = unsafe { _mm256_loadu_ps(a.as_ptr().add(8 * i)) };
            }
            r
        }
        #[inline(always)]
        fn f32_to(a: Self::F32) -> [f32; LANES] {
            let mut r = [0f32; LANES];
            for (i, v) in a.iter().enumerate() {
                unsafe { _mm256_storeu_ps(r.as_mut_ptr().add(8 * i), *v) };
            }
            r
        }
        #[inline(always)]
        fn f32_splat(x: f32) -> Self::F32 {
            [unsafe { _mm256_set1_ps(x) }; R]
        }
        #[inline(always)]
        fn f32_add(a: Self::F32, b: Self::F32) -> Self::F32 {
            per_register!(R, _mm256_add_ps, a, b)
        }
        #[inline(always)]
        fn f32_sub(a: Self::F32, b: Self::F32) -> Self::F32 {
            per_register!(R, _mm256_sub_ps, a, b)
        }
        #[inline(always)]
        fn f32_mul(a: Self::F32, b: Self::F32) -> Self::F32 {
            per_register!(R, _mm256_mul_ps, a, b)
        }
        #[inline(always)]
        fn f32_div(a: Self::F32, b: Self::F32) -> Self::F32 {
            per_register!(R, _mm256_div_ps, a, b)
        }
        #[inline(always)]
        fn f32_neg(a: Self::F32) -> Self::F32 {
            per_register!(R, neg_ps, a)
        }
        #[inline(always)]
        fn f32_sqrt(a: Self::F32) -> Self::F32 {
            per_register!(R, _mm256_sqrt_ps, a)
        }
        #[inline(always)]
        fn f32_lt(a: Self::F32, b: Self::F32) -> Self::M {
            let mut r = [unsafe { _mm256_setzero_si256() }; R];
            for i in 0..R {
                r[i] = unsafe { lt_ps(a[i], b[i]) };
            }
            r
        }
        #[inline(always)]
        fn f32_eq(a: Self::F32, b: Self::F32) -> Self::M {
            let mut r = [unsafe { _mm256_setzero_si256() }; R];
            for i in 0..R {
                r[i] = unsafe { eq_ps(a[i], b[i]) };
            }
            r
        }
        #[inline(always)]
        fn f32_from_f64(a: Self::F64) -> Self::F32 {
            let mut r = [unsafe { _mm256_setzero_ps() }; R];
            for i in 0..R {
                r[i] = unsafe { _mm256_set_m128(_mm256_cvtpd_ps(a[2 * i + 1]), _mm256_cvtpd_ps(a[2 * i])) };
            }
            r
        }

        #[inline(always)]
        fn f64_from(a: &[f64; LANES]) -> Self::F64 {
            let mut r = [unsafe { _mm256_setzero_pd() }; 2 * R];
            for (i, v) in r.iter_mut().enumerate() {
                *v = unsafe { _mm256_loadu_pd(a.as_ptr().add(4 * i)) };
            }
            r
        }
        #[inline(always)]
        fn f64_splat(x: f64) -> Self::F64 {
            [unsafe { _mm256_set1_pd(x) }; 2 * R]
        }
        #[inline(always)]
        fn f64_add(a: Self::F64, b: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm256_add_pd, a, b)
        }
        #[inline(always)]
        fn f64_sub(a: Self::F64, b: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm256_sub_pd, a, b)
        }
        #[inline(always)]
        fn f64_mul(a: Self::F64, b: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm256_mul_pd, a, b)
        }
        #[inline(always)]
        fn f64_div(a: Self::F64, b: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm256_div_pd, a, b)
        }
        #[inline(always)]
        fn f64_neg(a: Self::F64) -> Self::F64 {
            per_register!(2 * R, neg_pd, a)
        }
        #[inline(always)]
        fn f64_sqrt(a: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm256_sqrt_pd, a)
        }
        #[inline(always)]
        fn f64_floor(a: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm256_floor_pd, a)
        }
        #[inline(always)]
        fn f64_lt(a: Self::F64, b: Self::F64) -> Self::M {
            let mut r = [unsafe { _mm256_setzero_si256() }; R];
            for (i, m) in r.iter_mut().enumerate() {
                let (j, k) = (2 * i, 2 * i + 1);
                *m = unsafe {
                    narrow(
                        _mm256_cmp_pd::<_CMP_LT_OQ>(a[j], b[j]),
                        _mm256_cmp_pd::<_CMP_LT_OQ>(a[k], b[k]),
                    )
                };
            }
            r
        }
        #[inline(always)]
        fn f64_eq(a: Self::F64, b: Self::F64) -> Self::M {
            let mut r = [unsafe { _mm256_setzero_si256() }; R];
            for (i, m) in r.iter_mut().enumerate() {
                let (j, k) = (2 * i, 2 * i + 1);
                *m = unsafe {
                    narrow(
                        _mm256_cmp_pd::<_CMP_EQ_OQ>(a[j], b[j]),
                        _mm256_cmp_pd::<_CMP_EQ_OQ>(a[k], b[k]),
                    )
                };
            }
            r
        }
        #[inline(always)]
        fn f64_from_f32(a: Self::F32) -> Self::F64 {
            let mut r = [unsafe { _mm256_setzero_pd() }; 2 * R];
            for i in 0..R {
                r[2 * i] = unsafe { _mm256_cvtps_pd(_mm256_castps256_ps128(a[i])) };
                r[2 * i + 1] = unsafe { _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(a[i])) };
            }
            r
        }
        #[inline(always)]
        fn f64_from_u32(a: &[u32; LANES]) -> Self::F64 {
            // No unsigned conversion: flip the top bit, convert as signed, add 2^31 back
            // (every step exact in f64).
            let mut r = [unsafe { _mm256_setzero_pd() }; 2 * R];
            for i in 0..R {
                unsafe {
                    let v = _mm256_loadu_si256(a.as_ptr().add(8 * i).cast());
                    let v = _mm256_xor_si256(v, _mm256_set1_epi32(i32::MIN));
                    let bias = _mm256_set1_pd(2147483648.0);
                    r[2 * i] = _mm256_add_pd(_mm256_cvtepi32_pd(_mm256_castsi256_si128(v)), bias);
                    r[2 * i + 1] = _mm256_add_pd(_mm256_cvtepi32_pd(_mm256_extracti128_si256::<1>(v)), bias);
                }
            }
            r
        }

        #[inline(always)]
        fn m_from(a: &[u32; LANES]) -> Self::M {
            let mut r = [unsafe { _mm256_setzero_si256() }; R];
            for (i, v) in r.iter_mut().enumerate() {
                *v = unsafe { _mm256_loadu_si256(a.as_ptr().add(8 * i).cast()) };
            }
            r
        }
        #[inline(always)]
        fn m_to(a: Self::M) -> [u32; LANES] {
            let mut r = [0u32; LANES];
            for (i, v) in a.iter().enumerate() {
                unsafe { _mm256_storeu_si256(r.as_mut_ptr().add(8 * i).cast(), *v) };
            }
            r
        }
        #[inline(always)]
        fn m_nonzero(a: &[u32; LANES]) -> Self::M {
            let v = Self::m_from(a);
            let mut r = v;
            for i in 0..R {
                r[i] = unsafe { not_si256(_mm256_cmpeq_epi32(v[i], _mm256_setzero_si256())) };
            }
            r
        }
        #[inline(always)]
        fn m_and(a: Self::M, b: Self::M) -> Self::M {
            per_register!(R, _mm256_and_si256, a, b)
        }
        #[inline(always)]
        fn m_or(a: Self::M, b: Self::M) -> Self::M {
            per_register!(R, _mm256_or_si256, a, b)
        }
        #[inline(always)]
        fn m_not(a: Self::M) -> Self::M {
            per_register!(R, not_si256, a)
        }
        #[inline(always)]
        fn m_any(a: Self::M) -> bool {
            let mut all = a[0];
            for v in &a[1..] {
                all = unsafe { _mm256_or_si256(all, *v) };
            }
            unsafe { _mm256_testz_si256(all, all) == 0 }
        }
        #[inline(always)]
        fn select_f32(m: Self::M, a: Self::F32, b: Self::F32) -> Self::F32 {
            let mut r = a;
            for i in 0..R {
                r[i] = unsafe { _mm256_blendv_ps(b[i], a[i], _mm256_castsi256_ps(m[i])) };
            }
            r
        }
        #[inline(always)]
        fn select_f64(m: Self::M, a: Self::F64, b: Self::F64) -> Self::F64 {
            let mut r = a;
            for i in 0..R {
                unsafe {
                    let lo = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(m[i])));
                    let hi = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_extracti128_si256::<1>(m[i])));
                    r[2 * i] = _mm256_blendv_pd(b[2 * i], a[2 * i], lo);
                    r[2 * i + 1] = _mm256_blendv_pd(b[2 * i + 1], a[2 * i + 1], hi);
                }
            }
            r
        }
        #[inline(always)]
        fn store_rgb(r: Self::F32, g: Self::F32, b: Self::F32, out: &mut [[f32; 3]; LANES]) {
            let (r, g, b) = (Self::f32_to(r), Self::f32_to(g), Self::f32_to(b));
            for (j, px) in out.iter_mut().enumerate() {
                *px = [r[j], g[j], b[j]];
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx512::Avx512;

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{Isa, LANES};
    use std::arch::x86_64::*;

    /// AVX-512 registers: `LANES / 16` per f32 vector, twice that per f64 vector, and a
    /// mask register per 16 lanes. Only code running on a CPU with AVX-512 F and DQ may use
    /// this type (as for [`super::Avx2`]: instantiated only inside a
    /// `#[target_feature(enable = "avx512f,avx512dq")]` function called after run-time
    /// detection).
    #[derive(Clone, Copy)]
    pub struct Avx512;

    /// Registers per f32 vector.
    const R: usize = LANES / 16;

    #[inline(always)]
    unsafe fn neg_ps(a: __m512) -> __m512 {
        _mm512_xor_ps(a, _mm512_set1_ps(-0.0))
    }
    #[inline(always)]
    unsafe fn neg_pd(a: __m512d) -> __m512d {
        _mm512_xor_pd(a, _mm512_set1_pd(-0.0))
    }
    #[inline(always)]
    unsafe fn floor_pd(a: __m512d) -> __m512d {
        _mm512_roundscale_pd::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(a)
    }

    /// For output register k of an interleaved block of 16 pixels (floats 16 k ..= 16 k + 15
    /// of `[r0, g0, b0, r1, ...]`): the permute indices taking red and green from `(r, g)`,
    /// then those keeping that and taking blue from `(that, b)` (16 + n selects the second
    /// operand's lane n).
    const INTERLEAVE: [([i32; 16], [i32; 16]); 3] = {
        let mut t = [([0; 16], [0; 16]); 3];
        let mut k = 0;
        while k < 3 {
            let mut e = 0;
            while e < 16 {
                let q = 16 * k + e;
                let (pixel, channel) = ((q / 3) as i32, q % 3);
                t[k].0[e] = if channel == 1 { 16 + pixel } else { pixel };
                t[k].1[e] = if channel == 2 { 16 + pixel } else { e as i32 };
                e += 1;
            }
            k += 1;
        }
        t
    };

    // Every `unsafe` here: the intrinsics need AVX-512 F and DQ, which the user of
    // `Avx512` guarantees; loads and stores are unaligned ones of whole local arrays.
    impl Isa for Avx512 {
        type F32 = [__m512; R];
        type F64 = [__m512d; 2 * R];
        type M = [__mmask16; R];

        #[inline(always)]
        fn f32_from(a: &[f32; LANES]) -> Self::F32 {
            let mut r = [unsafe { _mm512_setzero_ps() }; R];
            for (i, v) in r.iter_mut().enumerate() {
                *v = unsafe { _mm512_loadu_ps(a.as_ptr().add(16 * i)) };
            }
            r
        }
        #[inline(always)]
        fn f32_to(a: Self::F32) -> [f32; LANES] {
            let mut r = [0f32; LANES];
            for (i, v) in a.iter().enumerate() {
                unsafe { _mm512_storeu_ps(r.as_mut_ptr().add(16 * i), *v) };
            }
            r
        }
        #[inline(always)]
        fn f32_splat(x: f32) -> Self::F32 {
            [unsafe { _mm512_set1_ps(x) }; R]
        }
        #[inline(always)]
        fn f32_add(a: Self::F32, b: Self::F32) -> Self::F32 {
            per_register!(R, _mm512_add_ps, a, b)
        }
        #[inline(always)]
        fn f32_sub(a: Self::F32, b: Self::F32) -> Self::F32 {
            per_register!(R, _mm512_sub_ps, a, b)
        }
        #[inline(always)]
        fn f32_mul(a: Self::F32, b: Self::F32) -> Self::F32 {
            per_register!(R, _mm512_mul_ps, a, b)
        }
        #[inline(always)]
        fn f32_div(a: Self::F32, b: Self::F32) -> Self::F32 {
            per_register!(R, _mm512_div_ps, a, b)
        }
        #[inline(always)]
        fn f32_neg(a: Self::F32) -> Self::F32 {
            per_register!(R, neg_ps, a)
        }
        #[inline(always)]
        fn f32_sqrt(a: Self::F32) -> Self::F32 {
            per_register!(R, _mm512_sqrt_ps, a)
        }
        #[inline(always)]
        fn f32_lt(a: Self::F32, b: Self::F32) -> Self::M {
            let mut r = [0; R];
            for i in 0..R {
                r[i] = unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a[i], b[i]) };
            }
            r
        }
        #[inline(always)]
        fn f32_eq(a: Self::F32, b: Self::F32) -> Self::M {
            let mut r = [0; R];
            for i in 0..R {
                r[i] = unsafe { _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(a[i], b[i]) };
            }
            r
        }
        #[inline(always)]
        fn f32_from_f64(a: Self::F64) -> Self::F32 {
            let mut r = [unsafe { _mm512_setzero_ps() }; R];
            for i in 0..R {
                r[i] = unsafe {
                    let lo = _mm512_castps256_ps512(_mm512_cvtpd_ps(a[2 * i]));
                    _mm512_insertf32x8::<1>(lo, _mm512_cvtpd_ps(a[2 * i + 1]))
                };
            }
            r
        }

        #[inline(always)]
        fn f64_from(a: &[f64; LANES]) -> Self::F64 {
            let mut r = [unsafe { _mm512_setzero_pd() }; 2 * R];
            for (i, v) in r.iter_mut().enumerate() {
                *v = unsafe { _mm512_loadu_pd(a.as_ptr().add(8 * i)) };
            }
            r
        }
        #[inline(always)]
        fn f64_splat(x: f64) -> Self::F64 {
            [unsafe { _mm512_set1_pd(x) }; 2 * R]
        }
        #[inline(always)]
        fn f64_add(a: Self::F64, b: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm512_add_pd, a, b)
        }
        #[inline(always)]
        fn f64_sub(a: Self::F64, b: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm512_sub_pd, a, b)
        }
        #[inline(always)]
        fn f64_mul(a: Self::F64, b: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm512_mul_pd, a, b)
        }
        #[inline(always)]
        fn f64_div(a: Self::F64, b: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm512_div_pd, a, b)
        }
        #[inline(always)]
        fn f64_neg(a: Self::F64) -> Self::F64 {
            per_register!(2 * R, neg_pd, a)
        }
        #[inline(always)]
        fn f64_sqrt(a: Self::F64) -> Self::F64 {
            per_register!(2 * R, _mm512_sqrt_pd, a)
        }
        #[inline(always)]
        fn f64_floor(a: Self::F64) -> Self::F64 {
            per_register!(2 * R, floor_pd, a)
        }
        #[inline(always)]
        fn f64_lt(a: Self::F64, b: Self::F64) -> Self::M {
            let mut r = [0; R];
            for (i, m) in r.iter_mut().enumerate() {
                let (j, k) = (2 * i, 2 * i + 1);
                let (lo, hi) = unsafe {
                    (
                        _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a[j], b[j]),
                        _mm512_cmp_pd_mask::<_CMP_LT_OQ>(a[k], b[k]),
                    )
                };
                *m = u16::from(lo) | (u16::from(hi) << 8);
            }
            r
        }
        #[inline(always)]
        fn f64_eq(a: Self::F64, b: Self::F64) -> Self::M {
            let mut r = [0; R];
            for (i, m) in r.iter_mut().enumerate() {
                let (j, k) = (2 * i, 2 * i + 1);
                let (lo, hi) = unsafe {
                    (
                        _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a[j], b[j]),
                        _mm512_cmp_pd_mask::<_CMP_EQ_OQ>(a[k], b[k]),
                    )
                };
                *m = u16::from(lo) | (u16::from(hi) << 8);
            }
            r
        }
        #[inline(always)]
        fn f64_from_f32(a: Self::F32) -> Self::F64 {
            let mut r = [unsafe { _mm512_setzero_pd() }; 2 * R];
            for i in 0..R {
                unsafe {
                    r[2 * i] = _mm512_cvtps_pd(_mm512_castps512_ps256(a[i]));
                    r[2 * i + 1] = _mm512_cvtps_pd(_mm512_extractf32x8_ps::<1>(a[i]));
                }
            }
            r
        }
        #[inline(always)]
        fn f64_from_u32(a: &[u32; LANES]) -> Self::F64 {
            let mut r = [unsafe { _mm512_setzero_pd() }; 2 * R];
            for (i, v) in r.iter_mut().enumerate() {
                *v = unsafe { _mm512_cvtepu32_pd(_mm256_loadu_si256(a.as_ptr().add(8 * i).cast())) };
            }
            r
        }

        #[inline(always)]
        fn m_from(a: &[u32; LANES]) -> Self::M {
            let mut r = [0; R];
            for (i, m) in r.iter_mut().enumerate() {
                let v = unsafe { _mm512_loadu_si512(a.as_ptr().add(16 * i).cast()) };
                *m = unsafe { _mm512_movepi32_mask(v) };
            }
            r
        }
        #[inline(always)]
        fn m_to(a: Self::M) -> [u32; LANES] {
            let mut r = [0u32; LANES];
            for (i, m) in a.iter().enumerate() {
                unsafe { _mm512_storeu_si512(r.as_mut_ptr().add(16 * i).cast(), _mm512_movm_epi32(*m)) };
            }
            r
        }
        #[inline(always)]
        fn m_nonzero(a: &[u32; LANES]) -> Self::M {
            let mut r = [0; R];
            for (i, m) in r.iter_mut().enumerate() {
                let v = unsafe { _mm512_loadu_si512(a.as_ptr().add(16 * i).cast()) };
                *m = unsafe { _mm512_test_epi32_mask(v, v) };
            }
            r
        }
        #[inline(always)]
        fn m_and(a: Self::M, b: Self::M) -> Self::M {
            let mut r = a;
            for i in 0..R {
                r[i] = a[i] & b[i];
            }
            r
        }
        #[inline(always)]
        fn m_or(a: Self::M, b: Self::M) -> Self::M {
            let mut r = a;
            for i in 0..R {
                r[i] = a[i] | b[i];
            }
            r
        }
        #[inline(always)]
        fn m_not(a: Self::M) -> Self::M {
            let mut r = a;
            for i in 0..R {
                r[i] = !a[i];
            }
            r
        }
        #[inline(always)]
        fn m_any(a: Self::M) -> bool {
            a.iter().fold(0, |all, m| all | m) != 0
        }
        #[inline(always)]
        fn select_f32(m: Self::M, a: Self::F32, b: Self::F32) -> Self::F32 {
            let mut r = a;
            for i in 0..R {
                r[i] = unsafe { _mm512_mask_blend_ps(m[i], b[i], a[i]) };
            }
            r
        }
        #[inline(always)]
        fn select_f64(m: Self::M, a: Self::F64, b: Self::F64) -> Self::F64 {
            let mut r = a;
            for i in 0..R {
                unsafe {
                    r[2 * i] = _mm512_mask_blend_pd(m[i] as u8, b[2 * i], a[2 * i]);
                    r[2 * i + 1] = _mm512_mask_blend_pd((m[i] >> 8) as u8, b[2 * i + 1], a[2 * i + 1]);
                }
            }
            r
        }
        #[inline(always)]
        fn store_rgb(r: Self::F32, g: Self::F32, b: Self::F32, out: &mut [[f32; 3]; LANES]) {
            // Per 16 pixels, three registers of interleaved colours, each two permutes:
            // red and green into place, then blue.
            let dst = out.as_mut_ptr().cast::<f32>();
            for i in 0..R {
                for (k, (red_green, with_blue)) in INTERLEAVE.iter().enumerate() {
                    unsafe {
                        let red_green = _mm512_loadu_si512(red_green.as_ptr().cast());
                        let with_blue = _mm512_loadu_si512(with_blue.as_ptr().cast());
                        let t = _mm512_permutex2var_ps(r[i], red_green, g[i]);
                        // SAFETY (also): `out` holds 3 * LANES floats; block i, register k
                        // covers floats 48 i + 16 k ..= 48 i + 16 k + 15.
                        _mm512_storeu_ps(dst.add(48 * i + 16 * k), _mm512_permutex2var_ps(t, with_blue, b[i]));
                    }
                }
            }
        }
    }
}
