//! Kernels over a real 16x8 tile: masks, varying control flow, Z, interpolation arms,
//! fuel, index clamping, bound clipping and write counting.

#![allow(clippy::needless_range_loop, clippy::type_complexity)]

use std::sync::Arc;

use crate::support::jit::*;
use crate::support::raw_depth;
use primflow::abi::{setup_fuel_ran_out, ErrorSlot, ERR_FUEL, ERR_INDEX, ERR_NONE, MODE_BOUND};
use primflow::ir::Variability::{Uniform, Varying};
use primflow::ir::*;
use primflow::jit::Jit;

fn jit_for(funcs: Vec<Function>, sites: usize) -> Jit {
    Jit::new(Arc::new(program(funcs, sites))).expect("host ISA")
}

/// `if (X > a) return; Z = 0.5; interpolation { linear: interpolator_return(d[0] * X); }`
fn half_plane() -> Function {
    let mut fb = Fb::new("half_plane", FuncKind::Primitive);
    let (x, _y, z) = fb.xyz();
    let a = fb.param("a", float(), ParamRole::PerPrimitive);
    let d = fb.param("d", Type::array(Elem::Interp, vec![3]), ParamRole::InterpData);
    let value = bin(BinOp::Mul, index(d, ic(0), 0), x.clone());
    fb.pixel = vec![
        if_(bin(BinOp::Gt, x, a), vec![ret()], vec![]),
        assign(&z, fc(0.5)),
        s(StmtKind::Interpolation {
            arms: vec![InterpArm {
                kind: ArmKind::Named("linear".into()),
                body: vec![interp_return(value)],
                span: Default::default(),
            }],
        }),
    ];
    fb.finish()
}

#[test]
fn half_plane_writes_z_and_linear_component_left_of_the_edge() {
    let mut jit = jit_for(vec![half_plane()], 1);
    let key = kind_key(&[("linear", 1)]);
    let k = jit.kernel(FuncId(0), &key).unwrap();
    assert!(k.warnings.is_empty(), "{:?}", k.warnings);
    // n_seq, plane table [0], a, d[3] (one component each).
    let mut args = vec![1, 0, fw(5.2), fw(2.0), fw(7.0), fw(9.0)];
    assert_eq!(k.layout.words(1), args.len());
    let mut tile = Tile::new(1);
    let ctx = tile.render(&k, &args);
    assert_eq!(ctx.error, ERR_NONE);
    for y in 0..H {
        for x in 0..W {
            let cx = x as f32 + 0.5;
            if cx > 5.2 {
                assert_eq!(tile.depth_at(x, y), 0, "pixel {x},{y} must not be written");
                assert_eq!(tile.plane_at(0, x, y), 0.0);
            } else {
                assert_eq!(tile.depth_at(x, y), raw_depth(0.5));
                assert_eq!(tile.plane_at(0, x, y), 2.0 * cx);
            }
        }
    }
    // A plane index past num_planes is never written.
    args[1] = 7;
    let mut tile = Tile::new(1);
    tile.render(&k, &args);
    assert!(tile.gbuf.iter().all(|&v| v == 0.0));
    assert_eq!(tile.depth_at(0, 0), raw_depth(0.5));
}

#[test]
fn kind_binding_without_arm_is_reported() {
    let mut jit = jit_for(vec![half_plane()], 1);
    let key = kind_key(&[("linear", 1), ("perspective_linear", 2)]);
    let k = jit.kernel(FuncId(0), &key).unwrap();
    assert_eq!(k.warnings.len(), 1, "{:?}", k.warnings);
    assert_eq!(k.warnings[0].binding, 1);
    assert_eq!(
        k.warnings[0].message_for(&["a", "b"]),
        "`half_plane` never writes shading parameter `b`, bound to kind `perspective_linear`: no `interpolation` arm of `half_plane` handles kind `perspective_linear`; its pixels keep the value drawn there before"
    );
}

/// `int i = 0; while (i < X) i = i + 1; Z = float(i) / 32;` — a varying loop whose lanes
/// finish at different iterations.
#[test]
fn varying_while_runs_each_lane_to_its_own_count() {
    let mut fb = Fb::new("count", FuncKind::Primitive);
    let (x, _y, z) = fb.xyz();
    let i = fb.local("i", Type::int(), Varying);
    let l = fb.new_loop();
    fb.pixel = vec![
        assign(&i, ic(0)),
        while_(
            l,
            bin(BinOp::Lt, conv(i.clone(), Scalar::Float), x),
            vec![assign(&i, bin(BinOp::Add, i.clone(), ic(1)))],
            0,
        ),
        assign(&z, bin(BinOp::Div, conv(i, Scalar::Float), fc(32.0))),
    ];
    let mut jit = jit_for(vec![fb.finish()], 1);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    let ctx = tile.render(&k, &[1]);
    assert_eq!(ctx.error, ERR_NONE);
    for x in 0..W {
        // i stops at the first integer >= x + 0.5, i.e. x + 1.
        assert_eq!(tile.depth_at(x, 3), raw_depth((x + 1) as f64 / 32.0), "lane {x}");
    }
}

/// `while (X > 0) { }` never ends: each pixel group's fuel (here 10 trips: a pixel fuel of
/// 0 and a floor of 10) runs out, ERR_FUEL is recorded at the loop's site and counted once
/// per group, and each group carries on after the loop; the setup's fuel is not touched.
#[test]
fn endless_varying_loop_runs_out_of_fuel() {
    let mut fb = Fb::new("forever", FuncKind::Primitive);
    let (x, _y, z) = fb.xyz();
    let l = fb.new_loop();
    fb.pixel = vec![while_(l, bin(BinOp::Gt, x, fc(0.0)), vec![], 3), assign(&z, fc(0.25))];
    let mut jit = jit_for(vec![fb.finish()], 4);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    tile.pixel_fuel = 0;
    tile.group_fuel_floor = 10;
    let ctx = tile.run(&k, &[1], primflow::abi::MODE_RENDER, 1000);
    assert_eq!(ctx.error, ERR_FUEL);
    assert_eq!(ctx.error_site, 3);
    assert_eq!((ctx.fuel, ctx.group_fuel), (1000, 10));
    // One out-of-fuel error in each of the tile's 4 x 8 groups.
    assert_eq!(tile.error_count(ErrorSlot::Fuel(SiteId(3)), 4), 32);
    assert!(tile.depth.iter().all(|&d| d == raw_depth(0.25)));
}

/// A uniform endless loop in setup also stops on fuel: the run ends with the loop's site in
/// the fuel, -(2 + site), for the runner to count (the kernel counts nothing).
#[test]
fn endless_uniform_loop_in_setup_runs_out_of_fuel() {
    let mut fb = Fb::new("spin", FuncKind::Primitive);
    let l = fb.new_loop();
    fb.setup = vec![while_(l, bc(true), vec![], 0)];
    let mut jit = jit_for(vec![fb.finish()], 1);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    let ctx = tile.run(&k, &[1], primflow::abi::MODE_RENDER, 50);
    assert_eq!((ctx.error, ctx.error_site), (ERR_FUEL, 0));
    assert_eq!(ctx.fuel, -2i64 as u64);
    assert_eq!(setup_fuel_ran_out(ctx.fuel), Some(SiteId(0)));
    assert_eq!(tile.error_count(ErrorSlot::Fuel(SiteId(0)), 1), 0);
}

fn index_prim(varying_index: bool) -> Function {
    let mut fb = Fb::new("idx", FuncKind::Primitive);
    let (x, _y, z) = fb.xyz();
    let k = fb.param("k", Type::int(), ParamRole::PerPrimitive);
    let arr_ty = Type::array(Elem::Scalar(Scalar::Float), vec![4]);
    let arr = fb.local("arr", arr_ty, Uniform);
    let idx = if varying_index { conv(x, Scalar::Int) } else { k };
    fb.pixel = vec![
        assign(&arr, list(vec![fc(1.0), fc(2.0), fc(3.0), fc(4.0)])),
        assign(&z, bin(BinOp::Div, index(arr, idx, 2), fc(8.0))),
    ];
    fb.finish()
}

#[test]
fn out_of_range_uniform_index_clamps_and_records() {
    let mut jit = jit_for(vec![index_prim(false)], 3);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    for (kv, want, err) in [(2, 3.0, ERR_NONE), (7, 4.0, ERR_INDEX), (-3, 1.0, ERR_INDEX)] {
        let mut tile = Tile::new(0);
        let ctx = tile.render(&k, &[1, kv as u32]);
        assert_eq!(ctx.error, err, "k = {kv}");
        if err != ERR_NONE {
            assert_eq!(ctx.error_site, 2);
        }
        assert_eq!(tile.depth_at(5, 5), raw_depth(want / 8.0), "k = {kv}");
    }
}

#[test]
fn out_of_range_varying_index_clamps_per_lane_and_records() {
    let mut jit = jit_for(vec![index_prim(true)], 3);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    let ctx = tile.render(&k, &[1, 0]);
    assert_eq!((ctx.error, ctx.error_site), (ERR_INDEX, 2));
    for x in 0..W {
        let want = (x.min(3) + 1) as f64 / 8.0;
        assert_eq!(tile.depth_at(x, 0), raw_depth(want), "lane {x}");
    }
}

/// A dynamically indexed varying local written through a varying index under a mask.
#[test]
fn varying_scatter_into_local_array_respects_mask() {
    let mut fb = Fb::new("scatter", FuncKind::Primitive);
    let (x, _y, z) = fb.xyz();
    let arr = fb.local("arr", Type::array(Elem::Scalar(Scalar::Float), vec![4]), Varying);
    let xi = conv(x.clone(), Scalar::Int);
    let slot = bin(BinOp::Rem, xi, ic(4));
    fb.pixel = vec![
        assign(&arr, e(TreeKind::Splat(Box::new(fc(0.0))), arr.ty.clone(), Uniform)),
        // Only lanes with X < 8 write 1 into arr[X % 4].
        if_(
            bin(BinOp::Lt, x, fc(8.0)),
            vec![assign_at(&arr, slot.clone(), 0, fc(1.0))],
            vec![],
        ),
        assign(
            &z,
            bin(
                BinOp::Add,
                bin(BinOp::Mul, index(arr.clone(), slot, 1), fc(0.5)),
                bin(BinOp::Mul, index(arr, ic(0), 2), fc(0.25)),
            ),
        ),
    ];
    let mut jit = jit_for(vec![fb.finish()], 3);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    let ctx = tile.render(&k, &[1]);
    assert_eq!(ctx.error, ERR_NONE);
    for x in 0..W {
        let mine = if x < 8 { 0.5 } else { 0.0 };
        let zero_slot = if x < 8 && x % 4 == 0 { 0.25 } else { 0.0 };
        assert_eq!(tile.depth_at(x, 1), raw_depth(mine + zero_slot), "lane {x}");
    }
}

fn bounded(b: [f32; 4]) -> Function {
    let mut fb = Fb::new("bounded", FuncKind::Primitive);
    let (_x, _y, z) = fb.xyz();
    fb.setup = vec![bound([fc(b[0]), fc(b[1]), fc(b[2]), fc(b[3])])];
    fb.pixel = vec![assign(&z, fc(0.5))];
    fb.finish()
}

fn written(tile: &Tile) -> Vec<(usize, usize)> {
    let mut out = vec![];
    for y in 0..H {
        for x in 0..W {
            if tile.depth_at(x, y) != 0 {
                out.push((x, y));
            }
        }
    }
    out
}

#[test]
fn bound_clips_the_pass_rectangle_by_pixel_centres() {
    let inf = f32::INFINITY;
    let cases: Vec<([f32; 4], Box<dyn Fn(usize, usize) -> bool>)> = vec![
        (
            [2.0, 1.0, 6.0, 3.0],
            Box::new(|x, y| (2..6).contains(&x) && (1..3).contains(&y)),
        ),
        ([-inf, -inf, inf, inf], Box::new(|_, _| true)),
        ([-1e30, 2.0, 1e30, 3.0], Box::new(|_, y| y == 2)),
        ([f32::NAN, 0.0, 10.0, 10.0], Box::new(|_, _| false)),
        ([5.0, 5.0, 1.0, 1.0], Box::new(|_, _| false)),
        ([14.6, 7.4, 3e38, 3e38], Box::new(|x, y| x == 15 && y == 7)),
    ];
    for (b, inside) in cases {
        let mut jit = jit_for(vec![bounded(b)], 0);
        let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
        let mut tile = Tile::new(0);
        tile.render(&k, &[1]);
        let want: Vec<(usize, usize)> = (0..H)
            .flat_map(|y| (0..W).map(move |x| (x, y)))
            .filter(|&(x, y)| inside(x, y))
            .collect();
        assert_eq!(written(&tile), want, "bound {b:?}");
    }
}

#[test]
fn bound_respects_a_tile_not_at_the_origin() {
    let mut jit = jit_for(vec![bounded([18.0, 9.0, 21.0, 10.0])], 0);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    tile.x0 = 16;
    tile.y0 = 8;
    tile.render(&k, &[1]);
    // Screen pixels 18..21 (x) and 9 (y) -> tile-local 2..5, 1.
    assert_eq!(written(&tile), vec![(2, 1), (3, 1), (4, 1)]);
}

#[test]
fn bound_mode_unions_bounds_and_ignores_nan() {
    let mut jit = jit_for(vec![bounded([2.0, 1.0, 6.0, 3.0])], 0);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    let ctx = tile.run(&k, &[1], MODE_BOUND, 100);
    assert_eq!((ctx.bound_set, ctx.bound), (1, [2.0, 1.0, 6.0, 3.0]));
    assert!(tile.depth.iter().all(|&d| d == 0), "bound mode renders nothing");

    let mut jit = jit_for(vec![bounded([f32::NAN, 1.0, 6.0, 3.0])], 0);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let ctx = tile.run(&k, &[1], MODE_BOUND, 100);
    assert_eq!(ctx.bound_set, 0);

    // No bound statement: the whole viewport (64x32 in the test context).
    let mut fb = Fb::new("unbounded", FuncKind::Primitive);
    let (_x, _y, z) = fb.xyz();
    fb.pixel = vec![assign(&z, fc(0.5))];
    let mut jit = jit_for(vec![fb.finish()], 0);
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let ctx = tile.run(&k, &[1], MODE_BOUND, 100);
    assert_eq!((ctx.bound_set, ctx.bound), (1, [0.0, 0.0, 64.0, 32.0]));
}

#[test]
fn count_writes_counts_lanes_that_assigned_z() {
    let mut fb = Fb::new("counted", FuncKind::Primitive);
    let (x, _y, z) = fb.xyz();
    // Z is assigned twice for X < 4, once for the rest, never for X > 12 (returned).
    fb.pixel = vec![
        if_(bin(BinOp::Gt, x.clone(), fc(12.0)), vec![ret()], vec![]),
        assign(&z, fc(0.25)),
        if_(bin(BinOp::Lt, x, fc(4.0)), vec![assign(&z, fc(0.75))], vec![]),
    ];
    let mut jit = jit_for(vec![fb.finish()], 0);
    let mut key = kind_key(&[]);
    key.count_writes = true;
    let k = jit.kernel(FuncId(0), &key).unwrap();
    let mut tile = Tile::new(0);
    tile.render(&k, &[1]);
    tile.render(&k, &[1]);
    for x in 0..W {
        let (count, depth) = match x {
            0..=3 => (2, raw_depth(0.75)),
            4..=11 => (2, raw_depth(0.25)),
            _ => (0, 0),
        };
        assert_eq!(
            (tile.counts[2 * W + x], tile.depth_at(x, 2)),
            (count, depth),
            "lane {x}"
        );
    }
    // Without count_writes the same program leaves the counts alone.
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    tile.render(&k, &[1]);
    assert!(tile.counts.iter().all(|&c| c == 0));
}

#[test]
fn kernels_are_cached_per_key_and_clif_is_printable() {
    let mut jit = jit_for(vec![half_plane()], 1);
    let key = kind_key(&[("linear", 1)]);
    let a = jit.kernel(FuncId(0), &key).unwrap();
    let b = jit.kernel(FuncId(0), &key).unwrap();
    assert!(Arc::ptr_eq(&a, &b));
    let c = jit.kernel(FuncId(0), &kind_key(&[("linear", 2)])).unwrap();
    assert!(!Arc::ptr_eq(&a, &c));
    let text = jit.clif(FuncId(0), &key).unwrap();
    assert!(text.starts_with("function"), "{text}");
    assert!(text.contains("vany_true") && text.contains("f32x4"), "{text}");
    assert!(jit.isa_summary().contains("4 pixels per group (f32x4)"));
    assert!(jit.kernel(FuncId(9), &key).is_err());
}

/// `Z = (c ? arr[i] : 0.5) / 8` with `i` out of range: only the taken arm may record.
fn guarded_index_prim(varying_cond: bool) -> Function {
    let mut fb = Fb::new("guarded", FuncKind::Primitive);
    let (x, _y, z) = fb.xyz();
    let k = fb.param("k", Type::int(), ParamRole::PerPrimitive);
    let arr_ty = Type::array(Elem::Scalar(Scalar::Float), vec![4]);
    let arr = fb.local("arr", arr_ty, Uniform);
    // Uniform: k < 4. Varying: X < 2, so lanes 2.. take the constant arm.
    let cond = if varying_cond {
        bin(BinOp::Lt, x, fc(2.0))
    } else {
        bin(BinOp::Lt, k.clone(), ic(4))
    };
    fb.pixel = vec![
        assign(&arr, list(vec![fc(1.0), fc(2.0), fc(3.0), fc(4.0)])),
        assign(&z, bin(BinOp::Div, select(cond, index(arr, k, 2), fc(0.5)), fc(8.0))),
    ];
    fb.finish()
}

#[test]
fn an_untaken_conditional_arm_records_no_index_error() {
    // Uniform condition: k = 7 selects the constant arm, k = 2 the in-range read.
    let mut jit = jit_for(vec![guarded_index_prim(false)], 3);
    let kern = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    for (kv, want) in [(7, 0.5), (2, 3.0)] {
        let mut tile = Tile::new(0);
        let ctx = tile.render(&kern, &[1, kv as u32]);
        assert_eq!(ctx.error, ERR_NONE, "k = {kv}");
        assert_eq!(tile.depth_at(5, 5), raw_depth(want / 8.0), "k = {kv}");
    }
    // Varying condition, k = 7 out of range: lanes X < 2 take the read and record it...
    let mut jit = jit_for(vec![guarded_index_prim(true)], 3);
    let kern = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut tile = Tile::new(0);
    let ctx = tile.render(&kern, &[1, 7]);
    assert_eq!((ctx.error, ctx.error_site), (ERR_INDEX, 2));
    assert_eq!(tile.depth_at(0, 0), raw_depth(4.0 / 8.0));
    assert_eq!(tile.depth_at(5, 0), raw_depth(0.5 / 8.0));
}

/// `Z = (k < 4 && arr[k] > 2 ? 1 : 2) / 8` and the `||` twin `k >= 4 || arr[k] <= 2`.
fn short_circuit_prim(or: bool) -> Function {
    let mut fb = Fb::new("short", FuncKind::Primitive);
    let (_x, _y, z) = fb.xyz();
    let k = fb.param("k", Type::int(), ParamRole::PerPrimitive);
    let arr = fb.local("arr", Type::array(Elem::Scalar(Scalar::Float), vec![4]), Uniform);
    let read = index(arr.clone(), k.clone(), 2);
    let cond = if or {
        bin(BinOp::Or, bin(BinOp::Ge, k, ic(4)), bin(BinOp::Le, read, fc(2.0)))
    } else {
        bin(BinOp::And, bin(BinOp::Lt, k, ic(4)), bin(BinOp::Gt, read, fc(2.0)))
    };
    fb.pixel = vec![
        assign(&arr, list(vec![fc(1.0), fc(2.0), fc(3.0), fc(4.0)])),
        assign(&z, bin(BinOp::Div, select(cond, fc(1.0), fc(2.0)), fc(8.0))),
    ];
    fb.finish()
}

#[test]
fn the_right_side_of_and_or_records_errors_only_where_it_would_be_evaluated() {
    for or in [false, true] {
        let mut jit = jit_for(vec![short_circuit_prim(or)], 3);
        let kern = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
        // k = 7: the left side decides, the out-of-range read is never "evaluated".
        // k = 3: arr[3] = 4 > 2.
        for (kv, and_true) in [(7, false), (3, true)] {
            let mut tile = Tile::new(0);
            let ctx = tile.render(&kern, &[1, kv as u32]);
            assert_eq!(ctx.error, ERR_NONE, "or = {or}, k = {kv}");
            let holds = if or { !and_true } else { and_true };
            let want = if holds { 1.0 } else { 2.0 };
            assert_eq!(tile.depth_at(3, 3), raw_depth(want / 8.0), "or = {or}, k = {kv}");
        }
    }
}
