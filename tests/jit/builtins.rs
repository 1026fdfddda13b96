//! Built-in functions on uniform and varying operands, and transforms between named spaces
//! with matrices from the argument block, against Rust f32 / hand-computed references.

#![allow(clippy::needless_range_loop, clippy::type_complexity)]

use std::sync::Arc;

use crate::support::jit::*;
use primflow::abi::ERR_NONE;
use primflow::ir::*;
use primflow::jit::Jit;

fn call(f: Builtin, args: Vec<Tree>, ty: Type) -> Tree {
    let var = args.iter().fold(Variability::Uniform, |v, a| v.join(a.var));
    e(TreeKind::Builtin { func: f, args }, ty, var)
}

fn vec3(a: f32, b: f32, c: f32) -> Tree {
    list(vec![fc(a), fc(b), fc(c)])
}

/// Run a primitive returning `outs` (flattened into one linear binding) with `spaces`
/// matrices if given; plane p of pixel (x, 0) for each output component.
fn run(outs: impl Fn(&Tree) -> Vec<Tree>, spaces: Option<[[f32; 16]; 6]>) -> Vec<Vec<f32>> {
    let mut fb = Fb::new("b", FuncKind::Primitive);
    let (x, _y, _z) = fb.xyz();
    fb.f.uses_spaces = spaces.is_some();
    let outs = outs(&x);
    // Aggregates as their components, so the list's items share one type (the checker's
    // lists do; `primflow::ir::valid` checks it). Site 0: constant indices, never out of range.
    let several = outs.len() > 1;
    let flat: Vec<Tree> = outs
        .into_iter()
        .flat_map(|o| match o.ty.dims.first() {
            Some(&n) if several => (0..n as i32).map(|i| index(o.clone(), ic(i), 0)).collect(),
            _ => vec![o],
        })
        .collect();
    let n: u32 = flat.iter().map(|e| e.ty.fixed_len()).sum();
    // Concatenate: a list of scalars, or one aggregate.
    let value = if flat.len() == 1 {
        flat.into_iter().next().unwrap()
    } else {
        list(flat)
    };
    fb.pixel = vec![arm("linear", vec![interp_return(value)])];
    let mut jit = Jit::new(Arc::new(program(vec![fb.finish()], 1))).unwrap();
    let k = jit.kernel(FuncId(0), &kind_key(&[("linear", n)])).unwrap();
    assert!(k.warnings.is_empty(), "{:?}", k.warnings);
    let mut args: Vec<u32> = vec![1];
    args.extend(0..n);
    if let Some(sp) = spaces {
        assert_eq!(k.layout.spaces, Some(args.len() as u32));
        for m in sp {
            args.extend(m.iter().map(|v| v.to_bits()));
        }
    }
    let mut tile = Tile::new(n as usize);
    let ctx = tile.render(&k, &args);
    assert_eq!(ctx.error, ERR_NONE);
    (0..n as usize)
        .map(|p| (0..W).map(|x| tile.plane_at(p, x, 0)).collect())
        .collect()
}

#[test]
fn scalar_builtins_match_rust_f32_on_uniform_and_varying_operands() {
    let fns: Vec<(Builtin, fn(f32) -> f32)> = vec![
        (Builtin::Sqrt, f32::sqrt),
        (Builtin::Abs, f32::abs),
        (Builtin::Floor, f32::floor),
        (Builtin::Ceil, f32::ceil),
        (Builtin::Round, |x| x.round_ties_even()),
        (Builtin::Sin, f32::sin),
        (Builtin::Cos, f32::cos),
        (Builtin::Exp, f32::exp),
        (Builtin::Log, f32::ln),
        (Builtin::Atan, f32::atan),
        (Builtin::Sign, |x| {
            if x > 0.0 {
                1.0
            } else if x < 0.0 {
                -1.0
            } else {
                0.0
            }
        }),
    ];
    let outs = run(
        |x| {
            let mut v = vec![];
            for (f, _) in &fns {
                // varying: X - 7.5 (so signs vary); uniform: 2.5
                v.push(call(*f, vec![bin(BinOp::Sub, x.clone(), fc(7.0))], float()));
                v.push(call(*f, vec![fc(2.5)], float()));
            }
            v
        },
        None,
    );
    for (i, (f, reference)) in fns.iter().enumerate() {
        for lane in 0..W {
            let xv = lane as f32 + 0.5 - 7.0;
            let (got, want) = (outs[2 * i][lane], reference(xv));
            assert!(
                got == want || (got.is_nan() && want.is_nan()),
                "{f:?}({xv}) = {got}, want {want}"
            );
            assert_eq!(outs[2 * i + 1][lane], reference(2.5), "{f:?}(2.5)");
        }
    }
}

#[test]
fn multi_argument_and_vector_builtins() {
    let outs = run(
        |x| {
            vec![
                call(Builtin::Min, vec![x.clone(), fc(3.0)], float()),
                call(Builtin::Max, vec![x.clone(), fc(3.0)], float()),
                call(Builtin::Clamp, vec![x.clone(), fc(2.0), fc(5.0)], float()),
                call(Builtin::Mix, vec![fc(10.0), fc(20.0), fc(0.25)], float()),
                call(Builtin::Step, vec![fc(4.0), x.clone()], float()),
                call(Builtin::Smoothstep, vec![fc(0.0), fc(16.0), x.clone()], float()),
                call(Builtin::Pow, vec![x.clone(), fc(2.0)], float()),
                call(Builtin::Atan2, vec![fc(1.0), x.clone()], float()),
                call(Builtin::Dot, vec![vec3(1.0, 2.0, 3.0), vec3(4.0, 5.0, 6.0)], float()),
                call(Builtin::Length, vec![vec3(3.0, 4.0, 12.0)], float()),
                call(
                    Builtin::Distance,
                    vec![vec3(1.0, 1.0, 1.0), vec3(4.0, 5.0, 1.0)],
                    float(),
                ),
                call(
                    Builtin::Cross,
                    vec![vec3(1.0, 0.0, 0.0), list(vec![fc(0.0), x.clone(), fc(0.0)])],
                    Type::array(Elem::Scalar(Scalar::Float), vec![3]),
                ),
                call(
                    Builtin::Normalize,
                    vec![vec3(0.0, 3.0, 4.0)],
                    Type::array(Elem::Scalar(Scalar::Float), vec![3]),
                ),
            ]
        },
        None,
    );
    for lane in 0..W {
        let xv = lane as f32 + 0.5;
        let t = (xv / 16.0).clamp(0.0, 1.0);
        let want = [
            xv.min(3.0),
            xv.max(3.0),
            xv.clamp(2.0, 5.0),
            12.5,
            if xv < 4.0 { 0.0 } else { 1.0 },
            t * t * (3.0 - 2.0 * t),
            xv.powf(2.0),
            1f32.atan2(xv),
            32.0,
            13.0,
            5.0,
            0.0,
            0.0,
            xv,
            0.0,
            0.6,
            0.8,
        ];
        let got: Vec<f32> = outs.iter().map(|p| p[lane]).collect();
        assert_eq!(got, want, "lane {lane}");
    }
}

fn ident() -> [f32; 16] {
    let mut m = [0.0; 16];
    for i in 0..4 {
        m[i * 5] = 1.0;
    }
    m
}

#[test]
fn transforms_use_the_space_matrices() {
    // device_from_object: scale 2 then translate (10, 20, 30); object_from_device: inverse.
    let mut dfo = ident();
    let mut ofd = ident();
    for i in 0..3 {
        dfo[i * 5] = 2.0;
        ofd[i * 5] = 0.5;
    }
    dfo[3] = 10.0;
    dfo[7] = 20.0;
    dfo[11] = 30.0;
    ofd[3] = -5.0;
    ofd[7] = -10.0;
    ofd[11] = -15.0;
    let spaces = [dfo, ident(), ident(), ofd, ident(), ident()];
    let v3 = Type::array(Elem::Scalar(Scalar::Float), vec![3]);
    let outs = run(
        |x| {
            let p = list(vec![x.clone(), fc(2.0), fc(3.0)]);
            vec![
                call(
                    Builtin::TransformPoint {
                        from: Space::Object,
                        to: Space::Device,
                    },
                    vec![p.clone()],
                    v3.clone(),
                ),
                call(
                    Builtin::TransformPoint {
                        from: Space::Device,
                        to: Space::Object,
                    },
                    vec![vec3(12.0, 24.0, 36.0)],
                    v3.clone(),
                ),
                call(
                    Builtin::TransformVector {
                        from: Space::Object,
                        to: Space::World,
                    },
                    vec![p.clone()],
                    v3.clone(),
                ),
                call(
                    Builtin::TransformNormal {
                        from: Space::Object,
                        to: Space::Device,
                    },
                    vec![p],
                    v3.clone(),
                ),
            ]
        },
        Some(spaces),
    );
    for lane in 0..W {
        let xv = lane as f32 + 0.5;
        let got: Vec<f32> = outs.iter().map(|p| p[lane]).collect();
        let want = [
            2.0 * xv + 10.0,
            24.0,
            36.0,
            1.0,
            2.0,
            3.0,
            // world_from_object = world_from_device * device_from_object: scale 2, no
            // translation for a vector.
            2.0 * xv,
            4.0,
            6.0,
            // normals by the inverse transpose: scale 1/2.
            0.5 * xv,
            1.0,
            1.5,
        ];
        assert_eq!(got, want, "lane {lane}");
    }
}

#[test]
fn pow_by_an_integer_exponent_is_repeated_squaring_on_uniform_and_varying_exponents() {
    use primflow::jit::libm::{is_small_int, pow_int};
    let exponents = [-3.0f32, -0.0, 0.0, 1.0, 2.0, 5.0, 16.0, 63.0, 64.0, 65.0, 2.5, -1.5];
    let outs = run(
        |x| {
            // Base X - 7.5 + 0.25 (signs vary, no integer bases): a uniform exponent takes
            // the vector path; a varying exponent (X - 3.5, integers) and a uniform base the
            // per-lane calls.
            let base = bin(BinOp::Sub, x.clone(), fc(7.25));
            let mut v: Vec<Tree> = exponents
                .iter()
                .map(|&n| call(Builtin::Pow, vec![base.clone(), fc(n)], float()))
                .collect();
            v.push(call(
                Builtin::Pow,
                vec![fc(1.1), bin(BinOp::Sub, x.clone(), fc(3.5))],
                float(),
            ));
            v
        },
        None,
    );
    for lane in 0..W {
        let x = lane as f32 + 0.5 - 7.25;
        for (k, &n) in exponents.iter().enumerate() {
            let got = outs[k][lane];
            let want = if is_small_int(n) { pow_int(x, n) } else { x.powf(n) };
            assert!(
                got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()),
                "pow({x}, {n}) = {got}, want {want}"
            );
            if is_small_int(n) {
                // Within (2|n| + 2) roundings of the exact power (f64), or both past f32.
                let exact = f64::from(x).powi(n as i32);
                let bound = (2.0 * f64::from(n.abs()) + 2.0) * 2f64.powi(-24);
                let ok = if exact.abs() > f64::from(f32::MAX) {
                    got.is_infinite()
                } else if exact.abs() < 1e-30 {
                    f64::from(got).abs() < 1e-29
                } else {
                    ((f64::from(got) - exact) / exact).abs() <= bound
                };
                assert!(ok, "pow({x}, {n}) = {got}, exact {exact}");
            }
        }
        let y = lane as f32 + 0.5 - 3.5;
        assert_eq!(
            outs[exponents.len()][lane].to_bits(),
            pow_int(1.1, y).to_bits(),
            "pow(1.1, {y})"
        );
    }
}
