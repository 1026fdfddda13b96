//! The shading built-ins in the evaluator: `faceforward`, `reflect`, `refract` (the f32
//! operations of `jit::shading`, in the same order) and `noise`/`cellnoise` (the same
//! [`LibmFn`] functions kernels call, lane by lane).
//!
//! Invariant: operands of the wrong shape are an `EvalError` (malformed IR), never a panic.

use super::expr::Val;
use super::{malformed, Lanes, Res};
use crate::ir::Builtin;
use crate::ir::Scalar;
use crate::jit::libm::LibmFn;

fn g(w: u32) -> f32 {
    f32::from_bits(w)
}

/// `Σ a[k] * b[k]` over three components in lane `l`, left to right (`jit`'s `dot_comps`).
fn dot3(a: &[Lanes], b: &[Lanes], l: usize) -> f32 {
    let mut acc = g(a[0][l]) * g(b[0][l]);
    for k in 1..3 {
        acc += g(a[k][l]) * g(b[k][l]);
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
fn faceforward(vals: &[Val]) -> Res<Val> {
    let nref_at = if vals.len() == 3 { 2 } else { 0 };
    let v = three(vals, &[0, 1, nref_at])?;
    let (n, i, nref) = (v[0], v[1], v[2]);
    let d: [f32; 4] = std::array::from_fn(|l| dot3(nref, i, l));
    Ok(vec3(
        (0..3)
            .map(|k| std::array::from_fn(|l| if d[l] < 0.0 { n[k][l] } else { n[k][l] ^ 0x8000_0000 }))
            .collect(),
    ))
}

/// `reflect(I, N)`: `I - (d + d) N` with `d = dot(N, I)`.
fn reflect(vals: &[Val]) -> Res<Val> {
    let v = three(vals, &[0, 1])?;
    let (i, n) = (v[0], v[1]);
    let s: [f32; 4] = std::array::from_fn(|l| {
        let d = dot3(n, i, l);
        d + d
    });
    Ok(vec3(
        (0..3)
            .map(|k| std::array::from_fn(|l| (g(i[k][l]) - s[l] * g(n[k][l])).to_bits()))
            .collect(),
    ))
}

/// `refract(I, N, eta)`: with `d = dot(N, I)` and `k = 1 - eta² (1 - d²)`, zero where
/// `k < 0` (total internal reflection), else `eta I - (eta d + √k) N`.
fn refract(vals: &[Val]) -> Res<Val> {
    let v = three(vals, &[0, 1])?;
    let (i, n) = (v[0], v[1]);
    let Some(eta) = vals.get(2).and_then(|e| e.comps.first()) else {
        return malformed("refract without eta");
    };
    let mut tir = [false; 4];
    let mut c = [0f32; 4];
    for l in 0..4 {
        let e = g(eta[l]);
        let d = dot3(n, i, l);
        let k = 1.0 - (e * e) * (1.0 - d * d);
        tir[l] = k < 0.0;
        c[l] = e * d + k.sqrt();
    }
    Ok(vec3(
        (0..3)
            .map(|k| {
                std::array::from_fn(|l| {
                    let r = g(eta[l]) * g(i[k][l]) - c[l] * g(n[k][l]);
                    if tir[l] {
                        0
                    } else {
                        r.to_bits()
                    }
                })
            })
            .collect(),
    ))
}

/// `noise`/`cellnoise`: the arguments' components (at most 3 of an aggregate: a point's w
/// is not a coordinate) as coordinates, per lane.
fn noise(func: Builtin, vals: &[Val]) -> Res<Val> {
    let coords: Vec<&Lanes> = vals.iter().flat_map(|v| v.comps.iter().take(3)).collect();
    let Some(lib) = LibmFn::noise(func == Builtin::CellNoise, coords.len()) else {
        return malformed(format!("{func:?} of {} coordinates", coords.len()));
    };
    let lanes = std::array::from_fn(|l| {
        let p: Vec<f32> = coords.iter().map(|c| g(c[l])).collect();
        lib.apply(&p).to_bits()
    });
    Ok(Val {
        comps: vec![lanes],
        sc: Scalar::Float,
    })
}

/// A shading built-in of float operands; `None` for the other built-ins.
pub(super) fn builtin(func: Builtin, vals: &[Val]) -> Option<Res<Val>> {
    Some(match func {
        Builtin::Faceforward => faceforward(vals),
        Builtin::Reflect => reflect(vals),
        Builtin::Refract => refract(vals),
        Builtin::Noise | Builtin::CellNoise => noise(func, vals),
        _ => return None,
    })
}
