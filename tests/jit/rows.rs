//! The pixel loops' row structure (src/jit/lower/loops.rs, src/mid/hoist.rs) on a primitive
//! that is not screen_triangle: Y-only terms hoisted per row (a uniform frame local times Y,
//! interpolation data times Y, an int conversion of Y), uniform operations feeding varying
//! ones (evaluated per row, not per group), X carried from group to group,
//! the lane mask only at the rectangle's ends (a pass rectangle that starts and ends
//! mid-group), pass blocks run as spans, and the full-mask store fast path next to blended
//! partial groups. Every pixel is compared with a scalar reference evaluated in Rust in the
//! primitive's operation order, bit for bit.

#![allow(clippy::needless_range_loop)]

use std::sync::Arc;

use crate::support::jit::*;
use crate::support::raw_depth;
use primflow::abi::{Kernel, ERR_NONE};
use primflow::ir::Variability::{Uniform, Varying};
use primflow::ir::*;
use primflow::jit::Jit;

/// Tile size: several 16x8 blocks and partial ones in both directions.
const TW: usize = 60;
const TH: usize = 37;

/// `ramp(cx, r2, a, b, c, k, bx0, by0, bx1, by1, d[3])`:
/// ```text
/// bound(bx0, by0, bx1, by1); float bb = b * 2;        // setup
/// float dx = X - (cx + 0.25);                       // uniform operand: per row
/// if (dx * dx > r2) return;                           // guard: block culling
/// Z = a * X + bb * Y + c;
/// interpolation { linear:
///     interpolator_return(d[0] * X + float(int(Y * 16) * (k + 1)) + d[1] * Y); }
/// ```
fn ramp() -> Function {
    let mut fb = Fb::new("ramp", FuncKind::Primitive);
    let (x, y, z) = fb.xyz();
    let cx = fb.param("cx", float(), ParamRole::PerPrimitive);
    let r2 = fb.param("r2", float(), ParamRole::PerPrimitive);
    let a = fb.param("a", float(), ParamRole::PerPrimitive);
    let b = fb.param("b", float(), ParamRole::PerPrimitive);
    let c = fb.param("c", float(), ParamRole::PerPrimitive);
    let k = fb.param("k", Type::int(), ParamRole::PerPrimitive);
    let bnd: Vec<Tree> = ["bx0", "by0", "bx1", "by1"]
        .iter()
        .map(|n| fb.param(n, float(), ParamRole::PerPrimitive))
        .collect();
    let d = fb.param("d", Type::array(Elem::Interp, vec![3]), ParamRole::InterpData);
    let bb = fb.local("bb", float(), Uniform);
    let dx = fb.local("dx", float(), Varying);
    fb.setup = vec![
        bound([bnd[0].clone(), bnd[1].clone(), bnd[2].clone(), bnd[3].clone()]),
        assign(&bb, bin(BinOp::Mul, b, fc(2.0))),
    ];
    let depth = bin(
        BinOp::Add,
        bin(
            BinOp::Add,
            bin(BinOp::Mul, a, x.clone()),
            bin(BinOp::Mul, bb, y.clone()),
        ),
        c,
    );
    let yint = bin(
        BinOp::Mul,
        conv(bin(BinOp::Mul, y.clone(), fc(16.0)), Scalar::Int),
        bin(BinOp::Add, k, ic(1)),
    );
    let value = bin(
        BinOp::Add,
        bin(
            BinOp::Add,
            bin(BinOp::Mul, index(d.clone(), ic(0), 0), x.clone()),
            conv(yint, Scalar::Float),
        ),
        bin(BinOp::Mul, index(d, ic(1), 1), y),
    );
    fb.pixel = vec![
        assign(&dx, bin(BinOp::Sub, x, bin(BinOp::Add, cx, fc(0.25)))),
        if_(
            bin(BinOp::Gt, bin(BinOp::Mul, dx.clone(), dx.clone()), r2),
            vec![ret()],
            vec![],
        ),
        assign(&z, depth),
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

struct Case {
    cx: f32,
    r2: f32,
    a: f32,
    b: f32,
    c: f32,
    k: i32,
    bound: [f32; 4],
    d: [f32; 3],
}

/// Render `case` on a TW x TH tile at (x0, y0); returns depth and the one G-buffer plane.
fn render(kernel: &Kernel, case: &Case, x0: i32, y0: i32) -> (Vec<u32>, Vec<f32>) {
    let mut args: Vec<u32> = vec![1, 0];
    args.extend([case.cx, case.r2, case.a, case.b, case.c].iter().map(|v| v.to_bits()));
    args.push(case.k as u32);
    args.extend(case.bound.iter().map(|v| v.to_bits()));
    args.extend(case.d.iter().map(|v| v.to_bits()));
    assert_eq!(kernel.layout.words(1), args.len());
    let mut tile = Tile::sized(TW, TH, 1).at(x0, y0);
    tile.gbuf.fill(-7.0);
    assert_eq!(tile.render(kernel, &args).error, ERR_NONE);
    (tile.depth, tile.gbuf)
}

/// The per-pixel semantics in the primitive's operation order (f32, wrapping i32).
fn expected(case: &Case, x0: i32, y0: i32) -> (Vec<u32>, Vec<f32>) {
    let mut depth = vec![0u32; TW * TH];
    let mut plane = vec![-7.0f32; TW * TH];
    let [bx0, by0, bx1, by1] = case.bound;
    let bb = case.b * 2.0;
    for row in 0..TH {
        for col in 0..TW {
            let (x, y) = ((x0 + col as i32) as f32 + 0.5, (y0 + row as i32) as f32 + 0.5);
            if !(x >= bx0 && x <= bx1 && y >= by0 && y <= by1) {
                continue;
            }
            let dx = x - (case.cx + 0.25);
            if dx * dx > case.r2 {
                continue;
            }
            let z = case.a * x + bb * y + case.c;
            depth[row * TW + col] = raw_depth(z as f64);
            let yint = ((y * 16.0) as i32).wrapping_mul(case.k.wrapping_add(1));
            plane[row * TW + col] = case.d[0] * x + yint as f32 + case.d[1] * y;
        }
    }
    (depth, plane)
}

/// Renders `case` and compares every pixel; returns how many pixels were written.
fn check(case: &Case, x0: i32, y0: i32) -> usize {
    let mut jit = Jit::new(Arc::new(program(vec![ramp()], 2))).expect("host ISA");
    let kernel = jit.kernel(FuncId(0), &kind_key(&[("linear", 1)])).unwrap();
    assert!(kernel.warnings.is_empty(), "{:?}", kernel.warnings);
    let (got_depth, got_plane) = render(&kernel, case, x0, y0);
    let (want_depth, want_plane) = expected(case, x0, y0);
    for row in 0..TH {
        for col in 0..TW {
            let i = row * TW + col;
            let at = (x0 + col as i32, y0 + row as i32);
            assert_eq!(got_depth[i], want_depth[i], "depth at {at:?}");
            assert_eq!(
                got_plane[i].to_bits(),
                want_plane[i].to_bits(),
                "plane at {at:?}: {} vs {}",
                got_plane[i],
                want_plane[i]
            );
        }
    }
    want_depth.iter().filter(|&&v| v != 0).count()
}

#[test]
fn row_terms_and_partial_groups_match_a_scalar_reference() {
    // The bound starts at x = 101 and ends at x = 156 (both mid-group: groups start at the
    // tile's x0 = 100), rows 52..=80; the guard's circle band cuts blocks in the middle,
    // so spans of pass blocks, full blocks and skipped blocks all occur.
    let case = Case {
        cx: 128.0,
        r2: 20.0 * 20.0,
        a: 0.001,
        b: 0.0035,
        c: 0.1,
        k: 3,
        bound: [101.3, 52.2, 157.2, 80.9],
        d: [0.75, -1.25, 9.0],
    };
    let written = check(&case, 100, 50);
    // 56 columns (101..=156) inside |x - 128.25| <= 20 -> x in 108.5..=147.5 -> 40 columns,
    // times 29 rows.
    assert_eq!(written, 40 * 29);
}

#[test]
fn everything_passes_and_every_group_is_full_or_an_edge() {
    // A wide guard: every block passes, so the whole rectangle runs as spans; the
    // rectangle still starts and ends mid-group, on a tile at negative coordinates.
    let case = Case {
        cx: 0.0,
        r2: 1e8,
        a: -0.0004,
        b: 0.0021,
        c: 0.5,
        k: -7,
        bound: [-37.8, -20.1, 13.6, 14.4],
        d: [-3.5, 0.125, 0.0],
    };
    let written = check(&case, -40, -22);
    // Columns -38..=13 (centres -37.5..13.5), rows -20..=13 (centres -19.5..13.5).
    assert_eq!(written, 52 * 34);
}

/// `split(flag, k, lo, bx0, by0, bx1, by1)`, a guard prefix whose tests sit in a uniform
/// `if`, with a Y-only term on each side (the block walk evaluates those once per block row
/// and the X-dependent rest per block):
/// ```text
/// bound(bx0, by0, bx1, by1);
/// if (flag) { int sy = int(Y * 4); if (sy * k + int(X) > 300) return; }
/// else      { float fy = Y * 0.5;  if (X + fy < lo) return; }
/// Z = X * 0.001 + Y * 0.002;
/// ```
fn split() -> Function {
    let mut fb = Fb::new("split", FuncKind::Primitive);
    let (x, y, z) = fb.xyz();
    let flag = fb.param("flag", Type::bool(), ParamRole::PerPrimitive);
    let k = fb.param("k", Type::int(), ParamRole::PerPrimitive);
    let lo = fb.param("lo", float(), ParamRole::PerPrimitive);
    let bnd: Vec<Tree> = ["bx0", "by0", "bx1", "by1"]
        .iter()
        .map(|n| fb.param(n, float(), ParamRole::PerPrimitive))
        .collect();
    let sy = fb.local("sy", Type::int(), Varying);
    let fy = fb.local("fy", float(), Varying);
    fb.setup = vec![bound([bnd[0].clone(), bnd[1].clone(), bnd[2].clone(), bnd[3].clone()])];
    let int_line = bin(BinOp::Add, bin(BinOp::Mul, sy.clone(), k), conv(x.clone(), Scalar::Int));
    fb.pixel = vec![
        if_(
            flag,
            vec![
                assign(&sy, conv(bin(BinOp::Mul, y.clone(), fc(4.0)), Scalar::Int)),
                if_(bin(BinOp::Gt, int_line, ic(300)), vec![ret()], vec![]),
            ],
            vec![
                assign(&fy, bin(BinOp::Mul, y.clone(), fc(0.5))),
                if_(bin(BinOp::Lt, bin(BinOp::Add, x.clone(), fy), lo), vec![ret()], vec![]),
            ],
        ),
        assign(
            &z,
            bin(BinOp::Add, bin(BinOp::Mul, x, fc(0.001)), bin(BinOp::Mul, y, fc(0.002))),
        ),
    ];
    fb.finish()
}

/// Renders `split` on a TW x TH tile at (x0, y0) and compares every pixel's depth with the
/// per-pixel semantics; returns how many pixels were written.
fn check_split(flag: bool, k: i32, lo: f32, bound: [f32; 4], x0: i32, y0: i32) -> usize {
    let mut jit = Jit::new(Arc::new(program(vec![split()], 0))).expect("host ISA");
    let kernel = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let mut args: Vec<u32> = vec![1, flag as u32, k as u32, lo.to_bits()];
    args.extend(bound.iter().map(|v| v.to_bits()));
    assert_eq!(kernel.layout.words(1), args.len());
    let mut tile = Tile::sized(TW, TH, 0).at(x0, y0);
    assert_eq!(tile.render(&kernel, &args).error, ERR_NONE);
    let depth = tile.depth;
    let [bx0, by0, bx1, by1] = bound;
    let mut written = 0;
    for row in 0..TH {
        for col in 0..TW {
            let (x, y) = ((x0 + col as i32) as f32 + 0.5, (y0 + row as i32) as f32 + 0.5);
            let inside = x >= bx0 && x <= bx1 && y >= by0 && y <= by1;
            let survives = if flag {
                let sy = (y * 4.0) as i32;
                sy.wrapping_mul(k).wrapping_add(x as i32) <= 300
            } else {
                x + y * 0.5 >= lo
            };
            let want = if inside && survives {
                raw_depth((x * 0.001 + y * 0.002) as f64)
            } else {
                0
            };
            assert_eq!(depth[row * TW + col], want, "flag {flag}: depth at ({x}, {y})");
            written += usize::from(want != 0);
        }
    }
    written
}

#[test]
fn guards_in_a_uniform_if_with_row_terms_match_a_scalar_reference() {
    // Mixed tiles: the coarse block (the whole rectangle) is neither dead nor passing, so
    // the walk refines into 16x8 blocks; the guard line cuts them diagonally.
    // int side: 4y * 2 + x <= 300 -> x <= 300 - 8y (rows 20..56 cross it inside 20..80).
    let n = check_split(true, 2, 0.0, [20.2, 20.7, 79.9, 56.3], 20, 20);
    assert!(n > 100 && n < 60 * 36, "{n} pixels written");
    // float side: x + y / 2 >= 70.
    let n = check_split(false, 0, 70.0, [20.2, 20.7, 79.9, 56.3], 20, 20);
    assert!(n > 100 && n < 60 * 36, "{n} pixels written");
}

#[test]
fn whole_rectangle_decided_at_once_and_small_rectangles_match() {
    // Every pixel passes: the coarse block passes and the rectangle runs as one span.
    let n = check_split(false, 0, -1e6, [2.4, 3.1, 57.5, 31.0], 0, 0);
    assert_eq!(n, 56 * 28);
    // No pixel survives (int(4y) * 100 >= 600 from the first row on): the coarse block is
    // dead and nothing is written.
    assert_eq!(check_split(true, 100, 0.0, [0.0, 1.0, 60.0, 37.0], 0, 0), 0);
    // Under SMALL_RECT pixels (8 x 9): the full code over the rectangle, no block facts;
    // int(4y) + int(x) runs from 292 to 331 there, so the guard cuts the rectangle.
    let n = check_split(true, 1, 0.0, [130.0, 40.2, 137.9, 48.9], 128, 30);
    assert_eq!(n, 8 * 9 - count_cut(130, 138, 40, 49));
}

/// Pixels of columns [c0, c1) x rows [r0, r1) where `int(4y) + int(x) > 300` (y, x centres).
fn count_cut(c0: i32, c1: i32, r0: i32, r1: i32) -> usize {
    let mut n = 0;
    for r in r0..r1 {
        for c in c0..c1 {
            let (x, y) = (c as f32 + 0.5, r as f32 + 0.5);
            n += usize::from((y * 4.0) as i32 + x as i32 > 300);
        }
    }
    n
}
