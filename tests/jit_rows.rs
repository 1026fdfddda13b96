//! The pixel loops' row structure (src/jit/lower.rs, src/jit/lower/hoist.rs) on a primitive
//! that is not screen_triangle: Y-only terms hoisted per row (a uniform frame local times Y,
//! interpolation data times Y, an int conversion of Y), uniform operations feeding varying
//! ones (evaluated per row, not per group), X carried from group to group,
//! the lane mask only at the rectangle's ends (a pass rectangle that starts and ends
//! mid-group), pass blocks run as spans, and the full-mask store fast path next to blended
//! partial groups. Every pixel is compared with a scalar reference evaluated in Rust in the
//! primitive's operation order, bit for bit.

#![allow(clippy::needless_range_loop)]

mod jit_util;

use std::sync::Arc;

use jit_util::*;
use primflow::abi::{TileCtx, DEFAULT_FUEL, ERR_NONE, MODE_RENDER};
use primflow::ir::Variability::{Uniform, Varying};
use primflow::ir::*;
use primflow::jit::{Jit, Kernel};

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
    let bnd: Vec<Expr> = ["bx0", "by0", "bx1", "by1"]
        .iter()
        .map(|n| fb.param(n, float(), ParamRole::PerPrimitive))
        .collect();
    let d = fb.param("d", Type::array(Elem::Interp, vec![3]), ParamRole::InterpData);
    let bb = fb.local("bb", float(), Uniform);
    let dx = fb.local("dx", float(), Varying);
    fb.f.setup = vec![
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
    fb.f.pixel = vec![
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
    fb.f
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
    let mut depth = vec![0u32; TW * TH];
    let mut gbuf = vec![-7.0f32; TW * TH];
    let mut counts = vec![0u32; TW * TH];
    let mut ctx = TileCtx {
        x0,
        y0,
        x1: x0 + TW as i32,
        y1: y0 + TH as i32,
        mode: MODE_RENDER,
        stride: TW as u32,
        depth: depth.as_mut_ptr(),
        gbuf: gbuf.as_mut_ptr(),
        plane_stride: (TW * TH) as u32,
        num_planes: 1,
        write_count: counts.as_mut_ptr(),
        bound: [0.0; 4],
        bound_set: 0,
        error: 0,
        error_site: 0,
        fuel: DEFAULT_FUEL,
        call_depth: 0,
        width: 4096,
        height: 4096,
        expand: None,
        expand_state: std::ptr::null_mut(),
    };
    // SAFETY: ctx points at live buffers of TW * TH elements (one plane); args has the
    // layout's length for one sequence point.
    unsafe { (kernel.entry)(&mut ctx, args.as_ptr()) };
    assert_eq!(ctx.error, ERR_NONE);
    (depth, gbuf)
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
