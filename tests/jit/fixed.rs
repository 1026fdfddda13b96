//! Fixed-point and integer arithmetic and conversions, checked against f64 / i64
//! references: results come out through G-buffer planes (as floats) or the depth buffer
//! (as raw `fixed<32,32>` bits).

#![allow(clippy::needless_range_loop, clippy::type_complexity)]

use std::sync::Arc;

use crate::support::jit::*;
use crate::support::raw_depth;
use primflow::abi::ERR_NONE;
use primflow::ir::*;
use primflow::jit::Jit;

const F16: FixedFormat = FixedFormat { bits: 32, frac: 16 };

fn raw16(x: f64) -> u32 {
    (x * 65536.0).round() as i64 as i32 as u32
}

/// Wrap an exact value into a signed format with `int_bits` integer bits.
fn wrap_f64(x: f64, int_bits: u32) -> f64 {
    let span = 2f64.powi(int_bits as i32);
    x - span * ((x + span / 2.0) / span).floor()
}

/// Runs a primitive whose pixel part returns `outputs` (float expressions) into one linear
/// binding of that many components; `params` are fixed<32,16> per-primitive values.
fn run_outputs(params: &[f64], outputs: impl Fn(&[Tree], &Tree) -> Vec<Tree>) -> Vec<Vec<f32>> {
    let mut fb = Fb::new("fx", FuncKind::Primitive);
    let (x, _y, _z) = fb.xyz();
    let ps: Vec<Tree> = (0..params.len())
        .map(|i| fb.param(&format!("p{i}"), fixed(32, 16), ParamRole::PerPrimitive))
        .collect();
    let outs = outputs(&ps, &x);
    let n = outs.len();
    fb.pixel = vec![arm("linear", vec![interp_return(list(outs))])];
    let mut jit = Jit::new(Arc::new(program(vec![fb.finish()], 1))).unwrap();
    let k = jit.kernel(FuncId(0), &kind_key(&[("linear", n as u32)])).unwrap();
    assert!(k.warnings.is_empty(), "{:?}", k.warnings);
    let mut args = vec![1];
    args.extend(0..n as u32);
    args.extend(params.iter().map(|&p| raw16(p)));
    let mut tile = Tile::new(n);
    let ctx = tile.render(&k, &args);
    assert_eq!(ctx.error, ERR_NONE);
    (0..n)
        .map(|p| (0..W).map(|x| tile.plane_at(p, x, 0)).collect())
        .collect()
}

fn to_f(e: Tree) -> Tree {
    conv(e, Scalar::Float)
}

#[test]
fn fixed_32_16_arithmetic_matches_f64_reference() {
    let (a, b) = (1.5, 2.25);
    let outs = run_outputs(&[a, b, 30000.0, 10000.0, 300.0, 0.0, -1.5, 5.5, 2.0], |p, _| {
        vec![
            to_f(bin(BinOp::Add, p[0].clone(), p[1].clone())),
            to_f(bin(BinOp::Sub, p[0].clone(), p[1].clone())),
            to_f(bin(BinOp::Mul, p[0].clone(), p[1].clone())),
            to_f(bin(BinOp::Div, p[0].clone(), p[1].clone())),
            to_f(bin(BinOp::Div, p[6].clone(), p[1].clone())),
            to_f(bin(BinOp::Rem, p[7].clone(), p[8].clone())),
            // Overflow wraps.
            to_f(bin(BinOp::Add, p[2].clone(), p[3].clone())),
            to_f(bin(BinOp::Mul, p[4].clone(), p[4].clone())),
            // Division by zero: max, min, 0.
            to_f(bin(BinOp::Div, p[0].clone(), p[5].clone())),
            to_f(bin(BinOp::Div, p[6].clone(), p[5].clone())),
            to_f(bin(BinOp::Div, p[5].clone(), p[5].clone())),
            to_f(bin(BinOp::Rem, p[0].clone(), p[5].clone())),
            // Comparisons.
            select(bin(BinOp::Lt, p[0].clone(), p[1].clone()), fc(1.0), fc(0.0)),
            select(bin(BinOp::Ge, p[6].clone(), p[0].clone()), fc(1.0), fc(0.0)),
            select(bin(BinOp::Eq, p[8].clone(), p[8].clone()), fc(1.0), fc(0.0)),
        ]
    });
    let ulp = 1.0 / 65536.0;
    let max = (i32::MAX as f64) / 65536.0;
    let want = [
        a + b,
        a - b,
        a * b,
        a / b,
        -1.5 / b,
        1.5,
        wrap_f64(40000.0, 16),
        wrap_f64(90000.0, 16),
        max,
        -32768.0,
        0.0,
        0.0,
        1.0,
        0.0,
        1.0,
    ];
    for (i, w) in want.iter().enumerate() {
        let got = outs[i][0] as f64;
        // One fixed ulp for truncating division, plus f32 rounding of the result.
        let tol = ulp + w.abs() * f32::EPSILON as f64;
        assert!((got - w).abs() <= tol, "output {i}: got {got}, want {w}");
        assert!(outs[i].iter().all(|&v| v == outs[i][0]), "output {i} is uniform");
    }
}

#[test]
fn fixed_16_8_wraps_to_16_bits_and_varying_fixed_mul_matches() {
    let outs = run_outputs(&[100.0, 1.5], |p, x| {
        let f8 = Scalar::Fixed(FixedFormat { bits: 16, frac: 8 });
        let a8 = conv(p[0].clone(), f8);
        let x16 = conv(x.clone(), Scalar::Fixed(F16));
        vec![
            to_f(bin(BinOp::Add, a8.clone(), a8)),
            to_f(bin(BinOp::Mul, x16.clone(), p[1].clone())),
            to_f(bin(BinOp::Div, x16, p[1].clone())),
        ]
    });
    assert!(outs[0].iter().all(|&v| v as f64 == wrap_f64(200.0, 8)), "{:?}", outs[0]);
    for lane in 0..W {
        let x = lane as f64 + 0.5;
        assert_eq!(outs[1][lane] as f64, x * 1.5, "lane {lane}");
        let q = ((raw16(x) as i32 as i64) << 16) / raw16(1.5) as i64;
        assert_eq!(outs[2][lane] as f64, q as f64 / 65536.0, "lane {lane}");
    }
}

#[test]
fn int_division_never_traps() {
    // Per lane: (X as int - 5) as the divisor, so lane 5 divides by zero.
    let outs = run_outputs(&[], |_, x| {
        let xi = conv(x.clone(), Scalar::Int);
        let d = bin(BinOp::Sub, xi.clone(), ic(5));
        vec![
            to_f(bin(BinOp::Div, ic(7), d.clone())),
            to_f(bin(BinOp::Rem, ic(7), d)),
            to_f(bin(BinOp::Div, ic(i32::MIN), ic(-1))),
            to_f(bin(BinOp::Rem, ic(i32::MIN), ic(-1))),
            to_f(bin(BinOp::Div, ic(-7), ic(2))),
            to_f(bin(BinOp::Rem, ic(-7), ic(2))),
            to_f(bin(BinOp::Div, ic(3), ic(0))),
        ]
    });
    for lane in 0..W {
        let d = lane as i64 - 5;
        let (q, r) = if d == 0 { (0, 0) } else { (7 / d, 7 % d) };
        assert_eq!((outs[0][lane], outs[1][lane]), (q as f32, r as f32), "lane {lane}");
    }
    assert_eq!(outs[2][0], i32::MIN as f32);
    assert_eq!(outs[3][0], 0.0);
    assert_eq!((outs[4][0], outs[5][0], outs[6][0]), (-3.0, -1.0, 0.0));
}

/// `Z = fixed<32,32>(v)` (uniform) and `Z = fixed<32,32>(X * v)` (varying), Z declared
/// fixed<32,32>: the depth buffer receives the raw bits.
fn z_from_float(varying: bool, v: f32) -> Vec<u32> {
    let mut fb = Fb::new("zf", FuncKind::Primitive);
    let x = fb.param("X", float(), ParamRole::X);
    let _y = fb.param("Y", float(), ParamRole::Y);
    let z = fb.param("Z", fixed(32, 32), ParamRole::Z);
    let p = fb.param("v", float(), ParamRole::PerPrimitive);
    let value = if varying { bin(BinOp::Mul, x, p) } else { p };
    fb.pixel = vec![assign(
        &z,
        conv(value, Scalar::Fixed(FixedFormat { bits: 32, frac: 32 })),
    )];
    let mut jit = Jit::new(Arc::new(program(vec![fb.finish()], 0))).unwrap();
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    tile.render(&k, &[1, v.to_bits()]);
    (0..W).map(|x| tile.depth_at(x, 0)).collect()
}

#[test]
fn float_to_fixed_32_32_saturates_and_maps_nan_to_zero() {
    for varying in [false, true] {
        for (v, want) in [
            (2.0f32, u32::MAX),
            (1.0, u32::MAX),
            (-1.0, 0),
            (f32::NAN, 0),
            (f32::INFINITY, u32::MAX),
            (f32::NEG_INFINITY, 0),
            (0.25, 0x4000_0000),
            (1e-10, 0),
        ] {
            // Varying: X * v with X = 0.5 at lane 0, so use v*2 there.
            let got = z_from_float(varying, if varying { v * 2.0 } else { v })[0];
            assert_eq!(got, want, "varying={varying} v={v}");
        }
        let got = z_from_float(varying, 0.5)[0];
        assert_eq!(
            got,
            if varying { 0x4000_0000 } else { 0x8000_0000 },
            "varying={varying}"
        );
    }
    // Per lane: X / 16 = (x + 0.5) / 16 exactly representable as raw bits.
    let lanes = z_from_float(true, 1.0 / 16.0);
    for (x, &raw) in lanes.iter().enumerate() {
        assert_eq!(raw, raw_depth((x as f64 + 0.5) / 16.0), "lane {x}");
    }
}

#[test]
fn float_z_is_stored_rounded_and_saturated() {
    for (v, want) in [(0.5f32, 0x8000_0000u32), (3.0, u32::MAX), (-2.0, 0), (f32::NAN, 0)] {
        let mut fb = Fb::new("zfloat", FuncKind::Primitive);
        let (_x, _y, z) = fb.xyz();
        let p = fb.param("v", float(), ParamRole::PerPrimitive);
        fb.pixel = vec![assign(&z, p)];
        let mut jit = Jit::new(Arc::new(program(vec![fb.finish()], 0))).unwrap();
        let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
        let mut tile = Tile::new(0);
        tile.depth.fill(7);
        tile.render(&k, &[1, v.to_bits()]);
        assert!(tile.depth.iter().all(|&d| d == want), "v = {v}: {:x}", tile.depth[0]);
    }
}

/// The scalar definition of `fixed<32,32>(z)`: `z * 2^32` rounded to nearest (ties to even),
/// saturated to u32, NaN -> 0 (Rust's `as u32` saturates and maps NaN to 0).
fn fixed_32_32_ref(z: f32) -> u32 {
    (z * 4294967296.0).round_ties_even() as u32
}

/// The vector conversion to `fixed<32,32>` (the depth conversion; on x86 a `maxps` /
/// `cvttps2dq` sequence) against the scalar definition, over the boundaries (0, -0,
/// subnormals, rounding ties just above 0, 2^31 and its neighbours, 1 ulp below 1, 1, 2^32
/// overflow, negative, NaN, +-inf) and a spread of bit patterns. Lane x computes
/// `(x + 0.5) * v`, so lane 0 is `v / 2` exactly and the other lanes add nearby values.
#[test]
fn float_to_fixed_32_32_vector_matches_scalar_definition() {
    let mut fb = Fb::new("zconv", FuncKind::Primitive);
    let x = fb.param("X", float(), ParamRole::X);
    let _y = fb.param("Y", float(), ParamRole::Y);
    let z = fb.param("Z", fixed(32, 32), ParamRole::Z);
    let p = fb.param("v", float(), ParamRole::PerPrimitive);
    fb.pixel = vec![assign(
        &z,
        conv(bin(BinOp::Mul, x, p), Scalar::Fixed(FixedFormat { bits: 32, frac: 32 })),
    )];
    let mut jit = Jit::new(Arc::new(program(vec![fb.finish()], 0))).unwrap();
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();

    let ulp_below = |f: f32| f32::from_bits(f.to_bits() - 1);
    let ulp_above = |f: f32| f32::from_bits(f.to_bits() + 1);
    let two_m33 = 2f32.powi(-33);
    let mut lane0: Vec<f32> = vec![
        0.0,
        -0.0,
        f32::from_bits(1),
        f32::MIN_POSITIVE,
        two_m33,
        ulp_below(two_m33),
        ulp_above(two_m33),
        3.0 * two_m33,
        2f32.powi(-32),
        0.5,
        ulp_below(0.5),
        ulp_above(0.5),
        0.25,
        0.75,
        ulp_below(1.0),
        1.0,
        ulp_above(1.0),
        2.0,
        1e30,
        f32::MAX / 4.0,
        -1e-30,
        -0.25,
        -1.0,
        -1e30,
        f32::NAN,
        -f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
    ];
    // A deterministic spread of bit patterns over the whole float range, and a denser one
    // over [0, 1] where depths live.
    let mut seed = 0x9e37_79b9u32;
    for i in 0..600 {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        let z = if i % 2 == 0 {
            f32::from_bits(seed)
        } else {
            (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        lane0.push(z);
    }
    let mut checked = 0;
    for &z0 in &lane0 {
        // v = 2 * z0 is exact unless it overflows; then lane 0 is inf, still a case.
        let v = z0 * 2.0;
        let mut tile = Tile::new(0);
        assert_eq!(tile.render(&k, &[1, v.to_bits()]).error, ERR_NONE);
        for lane in 0..W {
            let zl = (lane as f32 + 0.5) * v;
            let got = tile.depth_at(lane, 0);
            assert_eq!(
                got,
                fixed_32_32_ref(zl),
                "z = {zl:e} ({:#x}), lane {lane}",
                zl.to_bits()
            );
            checked += 1;
        }
    }
    assert_eq!(checked, lane0.len() * W);
    // Spot values of the definition itself, so a wrong reference cannot hide a wrong kernel.
    assert_eq!(fixed_32_32_ref(ulp_below(1.0)), 0xffff_ff00);
    assert_eq!(fixed_32_32_ref(0.5), 0x8000_0000);
    assert_eq!(fixed_32_32_ref(ulp_below(0.5)), 0x7fff_ff80);
    assert_eq!(fixed_32_32_ref(two_m33), 0);
    assert_eq!(fixed_32_32_ref(3.0 * two_m33), 2);
    assert_eq!(fixed_32_32_ref(f32::NAN), 0);
}

/// `Z = a / b` in the depth format: an unsigned quotient of 2^63 or more (the u64
/// numerator `a << 32` over a tiny `b`) saturates to the format's largest value, in the
/// evaluator and at both tiers.
#[test]
fn an_unsigned_fixed_quotient_past_2_63_saturates_high() {
    use primflow::abi::{ArgLayout, ParamSlot, VariantKey};
    use primflow::diag::{Diagnostics, SourceMap};
    use primflow::ir::eval::{self, Budget};
    use primflow::jit::{JitOptions, Tier};
    const SOURCE: &str = "primitive quotient(fixed<32,32> a, b; varying float X, Y; inout varying fixed<32,32> Z)
{
    Z = a / b;
}
";
    let mut sources = SourceMap::new();
    let file = sources.add("quotient.prim", SOURCE);
    let mut diags = Diagnostics::new();
    let program = Arc::new(primflow::compile(&sources, &[file], &mut diags).expect("checks"));
    let func = program.find("quotient").expect("quotient");
    let key = VariantKey::default();
    let layout = ArgLayout::new(&program, func, &key);
    // (a, b, quotient) raw: 0.75 / 2^-32 and 0.5 / 2^-32 are far past the format's end;
    // 0.25 / 0.5 is exact; 0.75 / 0.75 saturates just below 1.
    for (a, b, want) in [
        (0xC000_0000u32, 1u32, u32::MAX),
        (0x8000_0000, 1, u32::MAX),
        (0xFFFF_FFFF, 2, u32::MAX),
        (0x4000_0000, 0x8000_0000, 0x8000_0000),
        (0xC000_0000, 0xC000_0000, u32::MAX),
    ] {
        let mut args = vec![0u32; layout.words(1)];
        args[0] = 1;
        for (i, v) in [a, b].into_iter().enumerate() {
            let ParamSlot::Fixed { offset, .. } = layout.params[i] else {
                panic!("a per-primitive parameter")
            };
            args[offset as usize] = v;
        }
        let mut t = eval::Tile::new(0, 0, W, H, 0, 64, 32);
        eval::Evaluator::new(&program, true)
            .run(func, &key, &args, &mut t, Budget::default())
            .expect("runs");
        assert!(
            t.depth.iter().all(|&z| z == want),
            "evaluator {a:#x} / {b:#x}: {:#x}",
            t.depth[0]
        );
        for tier in [Tier::Fast, Tier::Optimised] {
            let options = JitOptions {
                tier,
                unroll_loops: true,
            };
            let mut jit = Jit::with_options(program.clone(), options).expect("host ISA");
            let k = jit.kernel(func, &key).expect("kernel");
            let mut tile = Tile::new(0);
            tile.render(&k, &args);
            assert!(
                tile.depth.iter().all(|&z| z == want),
                "{tier:?} {a:#x} / {b:#x}: {:#x}",
                tile.depth[0]
            );
        }
    }
}
