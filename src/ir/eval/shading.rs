//! The shading built-ins in the evaluator: `faceforward`, `reflect`, `refract` (the
//! operations of `jit::shading`, in the same order, in the run's precision) and
//! `noise`/`cellnoise` (the same [`LibmFn`] functions kernels call, lane by lane).
//!
//! The noises are defined in f32 only: in F64 they take their coordinates rounded to f32
//! and their f32 result is widened.
//!
//! Invariant: operands of the wrong shape are an `EvalError` (malformed IR), never a panic.

use super::expr::Val;
use super::precision::{in_precision, Float, Precision};
use super::{malformed, Lanes, Res};
use crate::ir::Builtin;
use crate::ir::Scalar;
use crate::jit::libm::LibmFn;

fn g<F: Float>(w: u64) -> F {
    F::from_word(w)
}

/// `Σ a[k] * b[k]` over three components in lane `l`, left to right (`jit`'s `dot_comps`).
fn dot3<F: Float>(a: &[Lanes], b: &[Lanes], l: usize) -> F {
    let mut acc = g::<F>(a[0][l]) * g::<F>(b[0][l]);
    for k in 1..3 {
        acc = acc + g::<F>(a[k][l]) * g::<F>(b[k][l]);
    }
    acc
}

fn vec3(comps: Vec<Lanes>) -> Val {
    Val {
        comps,
        sc: Scalar::Float,
    }
}

/// The components of float[3] operands, or malformed.
fn three<'v>(vals: &'v [Val], which: &[usize]) -> Res<Vec<&'v [Lanes]>> {
    which
        .iter()
        .map(|&i| match vals.get(i) {
            Some(v) if v.comps.len() == 3 => Ok(v.comps.as_slice()),
            _ => malformed(format!("shading built-in operand {i} is not a float[3]")),
        })
        .collect()
}

/// `faceforward(N, I[, Nref])`: `N` where `dot(Nref, I) < 0`, else `-N`.
fn faceforward<F: Float>(vals: &[Val]) -> Res<Val> {
    let nref_at = if vals.len() == 3 { 2 } else { 0 };
    let v = three(vals, &[0, 1, nref_at])?;
    let (n, i, nref) = (v[0], v[1], v[2]);
    let d: [F; 4] = std::array::from_fn(|l| dot3(nref, i, l));
    Ok(vec3(
        (0..3)
            .map(|k| {
                std::array::from_fn(|l| {
                    if d[l] < F::ZERO {
                        n[k][l]
                    } else {
                        (-g::<F>(n[k][l])).word()
                    }
                })
            })
            .collect(),
    ))
}

/// `reflect(I, N)`: `I - (d + d) N` with `d = dot(N, I)`.
fn reflect<F: Float>(vals: &[Val]) -> Res<Val> {
    let v = three(vals, &[0, 1])?;
    let (i, n) = (v[0], v[1]);
    let s: [F; 4] = std::array::from_fn(|l| {
        let d: F = dot3(n, i, l);
        d + d
    });
    Ok(vec3(
        (0..3)
            .map(|k| std::array::from_fn(|l| (g::<F>(i[k][l]) - s[l] * g::<F>(n[k][l])).word()))
            .collect(),
    ))
}

/// `refract(I, N, eta)`: with `d = dot(N, I)` and `k = 1 - eta² (1 - d²)`, zero where
/// `k < 0` (total internal reflection), else `eta I - (eta d + √k) N`.
fn refract<F: Float>(vals: &[Val]) -> Res<Val> {
    let v = three(vals, &[0, 1])?;
    let (i, n) = (v[0], v[1]);
    let Some(eta) = vals.get(2).and_then(|e| e.comps.first()) else {
        return malformed("refract without eta");
    };
    let mut tir = [false; 4];
    let mut c = [F::ZERO; 4];
    for l in 0..4 {
        let e = g::<F>(eta[l]);
        let d: F = dot3(n, i, l);
        let k = F::ONE - (e * e) * (F::ONE - d * d);
        tir[l] = k < F::ZERO;
        c[l] = e * d + k.sqrt();
    }
    Ok(vec3(
        (0..3)
            .map(|k| {
                std::array::from_fn(|l| {
                    let r = g::<F>(eta[l]) * g::<F>(i[k][l]) - c[l] * g::<F>(n[k][l]);
                    if tir[l] {
                        F::ZERO.word()
                    } else {
                        r.word()
                    }
                })
            })
            .collect(),
    ))
}

/// `noise`/`cellnoise`: the arguments' components (at most 3 of an aggregate: a point's w
/// is not a coordinate) as coordinates, per lane, rounded to f32 (exact in F32).
fn noise<F: Float>(func: Builtin, vals: &[Val]) -> Res<Val> {
    let coords: Vec<&Lanes> = vals.iter().flat_map(|v| v.comps.iter().take(3)).collect();
    let Some(lib) = LibmFn::noise(func == Builtin::CellNoise, coords.len()) else {
        return malformed(format!("{func:?} of {} coordinates", coords.len()));
    };
    let lanes = std::array::from_fn(|l| {
        let p: Vec<f32> = coords.iter().map(|c| g::<F>(c[l]).to_f32()).collect();
        F::from_f32(lib.apply(&p)).word()
    });
    Ok(Val {
        comps: vec![lanes],
        sc: Scalar::Float,
    })
}

/// A shading built-in of float operands in precision `p`; `None` for the other built-ins.
pub(super) fn builtin(p: Precision, func: Builtin, vals: &[Val]) -> Option<Res<Val>> {
    in_precision!(p, F => Some(match func {
        Builtin::Faceforward => faceforward::<F>(vals),
        Builtin::Reflect => reflect::<F>(vals),
        Builtin::Refract => refract::<F>(vals),
        Builtin::Noise | Builtin::CellNoise => noise::<F>(func, vals),
        _ => return None,
    }))
}
