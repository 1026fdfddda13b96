//! Block-level culling (src/mid/block.rs, src/jit/lower/block.rs): a kernel whose pixel
//! part opens with coverage tests runs them per block by interval arithmetic, skipping
//! blocks no lane survives and dropping the tests in blocks every lane passes. Whatever the
//! blocks decide, every pixel must come out exactly as the per-pixel semantics say: these
//! tests render tiles larger than one block (with a partial last block row and column and a
//! pass rectangle that starts mid-group) and compare every pixel with an f32 / wrapping-i32
//! reference evaluated in Rust in the same operation order.

#![allow(clippy::needless_range_loop)]

use std::sync::Arc;

use crate::support::jit::*;
use crate::support::raw_depth;
use primflow::abi::{Kernel, ERR_NONE};
use primflow::ir::Variability::Varying;
use primflow::ir::*;
use primflow::jit::Jit;

/// Tile size: 3 blocks of 16 and a partial one across, 4 blocks of 8 and a partial one down.
const TW: usize = 60;
const TH: usize = 37;

/// `disc(cx, cy, r2, k, bx0, by0, bx1, by1)`:
/// ```text
/// bound(bx0, by0, bx1, by1);            // in setup
/// float dx = X - cx, dy = Y - cy;
/// if (dx * dx + dy * dy > r2) return;   // float guard
/// if (int(X) * k + int(Y) > 1000) return; // int guard (wraps for large k)
/// Z = 0.5;
/// ```
fn disc() -> Function {
    let mut fb = Fb::new("disc", FuncKind::Primitive);
    let (x, y, z) = fb.xyz();
    let cx = fb.param("cx", float(), ParamRole::PerPrimitive);
    let cy = fb.param("cy", float(), ParamRole::PerPrimitive);
    let r2 = fb.param("r2", float(), ParamRole::PerPrimitive);
    let k = fb.param("k", Type::int(), ParamRole::PerPrimitive);
    let b: Vec<Tree> = ["bx0", "by0", "bx1", "by1"]
        .iter()
        .map(|n| fb.param(n, float(), ParamRole::PerPrimitive))
        .collect();
    let dx = fb.local("dx", float(), Varying);
    let dy = fb.local("dy", float(), Varying);
    fb.setup = vec![bound([b[0].clone(), b[1].clone(), b[2].clone(), b[3].clone()])];
    let dist = bin(
        BinOp::Add,
        bin(BinOp::Mul, dx.clone(), dx.clone()),
        bin(BinOp::Mul, dy.clone(), dy.clone()),
    );
    let line = bin(
        BinOp::Add,
        bin(BinOp::Mul, conv(x.clone(), Scalar::Int), k),
        conv(y.clone(), Scalar::Int),
    );
    fb.pixel = vec![
        assign(&dx, bin(BinOp::Sub, x, cx)),
        assign(&dy, bin(BinOp::Sub, y, cy)),
        if_(bin(BinOp::Gt, dist, r2), vec![ret()], vec![]),
        if_(bin(BinOp::Gt, line, ic(1000)), vec![ret()], vec![]),
        assign(&z, fc(0.5)),
    ];
    fb.finish()
}

struct Case {
    cx: f32,
    cy: f32,
    r2: f32,
    k: i32,
    bound: [f32; 4],
}

/// Render `case` on a TW x TH tile at (x0, y0); returns the depth buffer.
fn render(k: &Kernel, case: &Case, x0: i32, y0: i32) -> Vec<u32> {
    let args: Vec<u32> = [1, fw(case.cx), fw(case.cy), fw(case.r2), case.k as u32]
        .into_iter()
        .chain(case.bound.iter().map(|v| v.to_bits()))
        .collect();
    assert_eq!(k.layout.words(1), args.len());
    let mut tile = Tile::sized(TW, TH, 0).at(x0, y0);
    assert_eq!(tile.render(k, &args).error, ERR_NONE);
    tile.depth
}

/// The per-pixel semantics, in the prim's operation order.
fn expected(case: &Case, x0: i32, y0: i32) -> Vec<u32> {
    let mut out = vec![0u32; TW * TH];
    let [bx0, by0, bx1, by1] = case.bound;
    for row in 0..TH {
        for col in 0..TW {
            let (px, py) = (x0 + col as i32, y0 + row as i32);
            let (x, y) = (px as f32 + 0.5, py as f32 + 0.5);
            // Pixels whose centres lie in the bound.
            if !(x >= bx0 && x <= bx1 && y >= by0 && y <= by1) {
                continue;
            }
            let (dx, dy) = (x - case.cx, y - case.cy);
            if dx * dx + dy * dy > case.r2 {
                continue;
            }
            if (x as i32).wrapping_mul(case.k).wrapping_add(y as i32) > 1000 {
                continue;
            }
            out[row * TW + col] = raw_depth(0.5);
        }
    }
    out
}

fn check(case: Case, x0: i32, y0: i32) -> usize {
    let mut jit = Jit::new(Arc::new(program(vec![disc()], 1))).expect("host ISA");
    let k = jit.kernel(FuncId(0), &kind_key(&[])).unwrap();
    let got = render(&k, &case, x0, y0);
    let want = expected(&case, x0, y0);
    for row in 0..TH {
        for col in 0..TW {
            let i = row * TW + col;
            assert_eq!(
                got[i],
                want[i],
                "pixel ({}, {}) of disc centre ({}, {}) r2 {} k {}",
                x0 + col as i32,
                y0 + row as i32,
                case.cx,
                case.cy,
                case.r2,
                case.k
            );
        }
    }
    want.iter().filter(|&&d| d != 0).count()
}

const EVERYTHING: [f32; 4] = [-1e9, -1e9, 1e9, 1e9];

#[test]
fn disc_inside_outside_and_across_blocks_matches_every_pixel() {
    // Centre mid-tile: blocks wholly inside (pass variant), wholly outside (skipped) and
    // across the circle (full code).
    let written = check(
        Case {
            cx: 130.0,
            cy: 70.3,
            r2: 18.0 * 18.0,
            k: 1,
            bound: EVERYTHING,
        },
        100,
        50,
    );
    assert!(written > 500 && written < TW * TH, "{written}");
}

#[test]
fn disc_covering_the_tile_writes_every_pixel_but_the_int_guard() {
    // Every block passes the float guard; the int guard cuts a diagonal.
    let written = check(
        Case {
            cx: 30.0,
            cy: 20.0,
            r2: 1e6,
            k: 30,
            bound: EVERYTHING,
        },
        0,
        0,
    );
    assert!(written > 300 && written < TW * TH, "{written}");
}

#[test]
fn disc_away_from_the_tile_writes_nothing() {
    let written = check(
        Case {
            cx: -500.0,
            cy: 20.0,
            r2: 100.0,
            k: 1,
            bound: EVERYTHING,
        },
        0,
        0,
    );
    assert_eq!(written, 0);
}

#[test]
fn nan_radius_never_fires_the_float_guard() {
    // `d > NaN` is false for every pixel: the block evaluator must not decide "dead".
    let written = check(
        Case {
            cx: 10.0,
            cy: 10.0,
            r2: f32::NAN,
            k: 0,
            bound: EVERYTHING,
        },
        0,
        0,
    );
    assert_eq!(written, TW * TH);
}

#[test]
fn wrapping_int_guard_is_evaluated_per_pixel() {
    // int(X) * k wraps around for most pixels: an interval in i64 would say "always above
    // 1000" or "never"; the evaluator must see the overflow and leave it to the pixels.
    let written = check(
        Case {
            cx: 0.0,
            cy: 0.0,
            r2: f32::INFINITY,
            k: 0x3000_0001,
            bound: EVERYTHING,
        },
        0,
        0,
    );
    assert!(written > 0 && written < TW * TH, "{written}");
}

#[test]
fn bound_starting_mid_group_and_huge_coordinates() {
    // The pass rectangle starts at x = 6 (mid-group) and ends mid-block; then a tile far
    // from the origin where X * X loses precision (still bit-exact with the reference).
    let written = check(
        Case {
            cx: 20.0,
            cy: 15.0,
            r2: 15.0 * 15.0,
            k: 1,
            bound: [6.2, 3.7, 41.5, 30.0],
        },
        0,
        0,
    );
    assert!(written > 100, "{written}");
    // A pass rectangle under 128 pixels takes the path without block facts.
    let written = check(
        Case {
            cx: 10.0,
            cy: 8.0,
            r2: 16.0,
            k: 1,
            bound: [6.2, 3.7, 14.5, 12.0],
        },
        0,
        0,
    );
    assert!(written > 20 && written < 81, "{written}");
    let written = check(
        Case {
            cx: 3_000_000.0,
            cy: 2_000_000.0,
            r2: 400.0,
            k: -1,
            bound: EVERYTHING,
        },
        3_000_000 - 28,
        2_000_000 - 16,
    );
    assert!(written > 0, "{written}");
}
