//! Primitive calls (argument blocks built by the caller, call depth) and the bare
//! `interpolator_return;` with Constant and Shared bindings (inlined interpolators).

use std::sync::Arc;

use crate::support::jit::*;
use crate::support::raw_depth;
use primflow::abi::{Binding, BindingKind, VariantKey, ERR_CALL_DEPTH, ERR_NONE, MODE_BOUND};
use primflow::ir::*;
use primflow::jit::Jit;

/// inner(X, Y, Z; float depth; float r[4]; float v[]; interpolation_data d[3]):
///   setup: bound(r); pixel: Z = depth + v[len(v) - 1]; linear: interpolator_return(d[1]).
fn inner() -> Function {
    let mut fb = Fb::new("inner", FuncKind::Primitive);
    let (_x, _y, z) = fb.xyz();
    let depth = fb.param("depth", float(), ParamRole::PerPrimitive);
    let r = fb.param(
        "r",
        Type::array(Elem::Scalar(Scalar::Float), vec![4]),
        ParamRole::PerPrimitive,
    );
    let mut v_ty = float();
    v_ty.per_seq = true;
    let v = fb.param("v", v_ty, ParamRole::PerSequencePoint);
    let d = fb.param("d", Type::array(Elem::Interp, vec![3]), ParamRole::InterpData);
    let count = e(TreeKind::SeqCount, Type::int(), Variability::Uniform);
    fb.setup = vec![bound([
        index(r.clone(), ic(0), 0),
        index(r.clone(), ic(1), 0),
        index(r.clone(), ic(2), 0),
        index(r, ic(3), 0),
    ])];
    fb.pixel = vec![
        assign(&z, bin(BinOp::Add, depth, index(v, bin(BinOp::Sub, count, ic(1)), 0))),
        s(StmtKind::Interpolation {
            arms: vec![InterpArm {
                kind: ArmKind::Named("linear".into()),
                body: vec![interp_return(index(d, ic(1), 0))],
                span: Default::default(),
            }],
        }),
    ];
    fb.finish()
}

/// outer(X, Y, Z; float d; interpolation_data data[3]):
///   inner(X, Y, Z, d * 0.5, {2, 1, 6, 3}, {0.1, 0.2, 0.25}, data);
fn outer() -> Function {
    let mut fb = Fb::new("outer", FuncKind::Primitive);
    let (x, y, z) = fb.xyz();
    let d = fb.param("d", float(), ParamRole::PerPrimitive);
    let data = fb.param("data", Type::array(Elem::Interp, vec![3]), ParamRole::InterpData);
    fb.setup = vec![s(StmtKind::CallPrimitive {
        callee: FuncId(0),
        args: vec![
            x,
            y,
            z,
            bin(BinOp::Mul, d, fc(0.5)),
            list(vec![fc(2.0), fc(1.0), fc(6.0), fc(3.0)]),
            list(vec![fc(0.1), fc(0.2), fc(0.25)]),
            data,
        ],
        site: SiteId(0),
    })];
    fb.finish()
}

#[test]
fn primitive_call_renders_the_callee_with_built_arguments() {
    let mut jit = Jit::new(Arc::new(program(vec![inner(), outer()], 1))).unwrap();
    let key = kind_key(&[("linear", 1)]);
    let k = jit.kernel(FuncId(1), &key).unwrap();
    // n_seq, plane table [0], d, data[3].
    let args = [1, 0, fw(0.5), fw(10.0), fw(20.0), fw(30.0)];
    let mut tile = Tile::new(1);
    let ctx = tile.render(&k, &args);
    assert_eq!((ctx.error, ctx.call_depth), (ERR_NONE, 0));
    for y in 0..H {
        for x in 0..W {
            let inside = (2..6).contains(&x) && (1..3).contains(&y);
            let (want_z, want_p) = if inside {
                (raw_depth(0.25f32 as f64 + 0.25), 20.0)
            } else {
                (0, 0.0)
            };
            assert_eq!(
                (tile.depth_at(x, y), tile.plane_at(0, x, y)),
                (want_z, want_p),
                "pixel {x},{y}"
            );
        }
    }
    // Bound mode: the callee's bound is recorded through the call.
    let ctx = tile.run(&k, &args, MODE_BOUND, 100);
    assert_eq!((ctx.bound_set, ctx.bound), (1, [2.0, 1.0, 6.0, 3.0]));
    // The callee was compiled (and cached) for the same key.
    let callee = jit.kernel(FuncId(0), &key).unwrap();
    assert_eq!(
        callee.layout,
        primflow::abi::ArgLayout::new(jit.program(), FuncId(0), &key)
    );
}

#[test]
fn recursive_primitive_stops_at_max_call_depth() {
    let mut fb = Fb::new("rec", FuncKind::Primitive);
    let (x, y, z) = fb.xyz();
    fb.setup = vec![s(StmtKind::CallPrimitive {
        callee: FuncId(0),
        args: vec![x, y, z.clone()],
        site: SiteId(0),
    })];
    fb.pixel = vec![assign(&z, fc(0.5))];
    let mut jit = Jit::new(Arc::new(program(vec![fb.finish()], 1))).unwrap();
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    let ctx = tile.render(&k, &[1]);
    assert_eq!((ctx.error, ctx.error_site, ctx.call_depth), (ERR_CALL_DEPTH, 0, 0));
    assert!(tile.depth.iter().all(|&d| d == raw_depth(0.5)));
}

/// interpolator ix(X, Y, Z; float scale, offset) { interpolator_return(X * scale + offset); }
fn ix() -> Function {
    let mut fb = Fb::new("ix", FuncKind::Interpolator);
    let (x, _y, _z) = fb.xyz();
    let scale = fb.param("scale", float(), ParamRole::PerPrimitive);
    let offset = fb.param("offset", float(), ParamRole::PerPrimitive);
    fb.pixel = vec![interp_return(bin(BinOp::Add, bin(BinOp::Mul, x, scale), offset))];
    fb.finish()
}

/// interpolator early(X, Y, Z) { if (X < 4) interpolator_return(1.0); interpolator_return(2.0); }
fn early() -> Function {
    let mut fb = Fb::new("early", FuncKind::Interpolator);
    let (x, _y, _z) = fb.xyz();
    fb.pixel = vec![
        if_(bin(BinOp::Lt, x, fc(4.0)), vec![interp_return(fc(1.0))], vec![]),
        interp_return(fc(2.0)),
    ];
    fb.finish()
}

#[test]
fn bare_interpolator_return_writes_constants_and_shared_interpolators() {
    let mut fb = Fb::new("p", FuncKind::Primitive);
    let (x, _y, z) = fb.xyz();
    fb.pixel = vec![
        if_(bin(BinOp::Gt, x, fc(10.0)), vec![ret()], vec![]),
        assign(&z, fc(0.5)),
        s(StmtKind::InterpolatorReturn(None)),
    ];
    let key = VariantKey {
        bindings: vec![
            Binding {
                kind: BindingKind::Constant,
                components: 3,
            },
            Binding {
                kind: BindingKind::Shared("ix".into()),
                components: 1,
            },
            Binding {
                kind: BindingKind::Kind("linear".into()),
                components: 1,
            },
            Binding {
                kind: BindingKind::Shared("early".into()),
                components: 2,
            },
        ],
        count_writes: false,
        trivial_accept: false,
    };
    let mut jit = Jit::new(Arc::new(program(vec![fb.finish(), ix(), early()], 0))).unwrap();
    let k = jit.kernel(FuncId(0), &key).unwrap();
    assert_eq!(k.warnings.len(), 1, "{:?}", k.warnings);
    assert_eq!(k.warnings[0].binding, 2);
    assert_eq!(
        k.warnings[0].message_for(&["Cs", "s", "t"]),
        "`p` never writes shading parameter `t`, bound to kind `linear`: no `interpolation` arm of `p` handles kind `linear`; its pixels keep the value drawn there before"
    );
    // n_seq; plane table (7 components); constant (3 floats); ix: scale, offset; early: none.
    let mut args = vec![1, 0, 1, 2, 3, 4, 5, 6];
    args.extend([fw(0.25), fw(0.5), fw(0.75), fw(2.0), fw(-1.0)]);
    assert_eq!(args.len(), k.layout.words(1));
    let mut tile = Tile::new(7);
    let ctx = tile.render(&k, &args);
    assert_eq!(ctx.error, ERR_NONE);
    for x in 0..W {
        let cx = x as f32 + 0.5;
        let got: Vec<f32> = (0..7).map(|p| tile.plane_at(p, x, 4)).collect();
        let want = if cx > 10.0 {
            vec![0.0; 7]
        } else {
            let e = if cx < 4.0 { 1.0 } else { 2.0 };
            vec![0.25, 0.5, 0.75, cx * 2.0 - 1.0, 0.0, e, e]
        };
        assert_eq!(got, want, "lane {x}");
    }
}
