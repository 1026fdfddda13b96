//! Inlined helper calls (src/mid/unroll.rs `one_trip`): the checker inlines every helper call
//! as a one-trip loop whose `return` is a `break`; a helper whose only `return` is its last
//! statement is lowered as straight-line code (no loop, no fuel check). These tests pin down
//! that doing so changes no pixel and no run-time error: helpers in setup and pixel code,
//! nested ones, one with a constant-trip loop inside (unrolled once the helper is flat), ones
//! with an early `return` under a uniform and a varying `if` (kept as loops), and a helper
//! whose loop never ends (out of fuel at the same site) — each against an exact reference,
//! at both tiers, with unrolling on and off. Once fuel has run out a flat helper still runs
//! where its loop would have been left at once (the exception unroll.rs documents).

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, JitOptions, Tier};
use primflow::runtime::{Renderer, Value};
use primflow::workload::same_frame;

const HELPERS: &str = r#"
float twice(float x)
{
    return x + x;
}

// A constant-trip loop and a nested helper call, one return at the end: flat.
float sum_of_twice_squares(float d[3])
{
    float s = 0;
    for (int i = 0; i < 3; i++)
        s += twice(d[i]) * d[i];
    return s;
}

// An early return: stays a one-trip loop.
float positive(float x)
{
    if (x < 0)
        return 0;
    return x;
}

// Never ends when n > 0: out of fuel at the `while`.
float spin(int n)
{
    int k = n;
    while (k > 0)
        k = k + 1;
    return 1;
}

primitive helpers(float rect[4]; float d[3]; int n; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float s = sum_of_twice_squares(d);
    float p = positive(d[0]) * spin(n);
    Z = (s + p + twice(X) + positive(X - 10)) / 256;
}
"#;

/// The `while` in `spin` (line:col of `while`).
const SPIN: &str = "W0801@28:5";

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("helpers.prim", HELPERS)])
}

fn scene(program: &Arc<Program>, d: [f32; 3], n: i32) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(40, 12).unwrap();
    r.set_tile_size(16).unwrap();
    r.begin("helpers").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, 40.0, 12.0])).unwrap();
    r.rast_param("d", &Value(d.to_vec())).unwrap();
    r.rast_param("n", &Value(vec![n as f32])).unwrap();
    r.end().unwrap();
    r
}

fn jit(program: &Arc<Program>, unroll_loops: bool, tier: Tier) -> Jit {
    Jit::with_options(program.clone(), JitOptions { tier, unroll_loops }).unwrap()
}

/// The exact depth of pixel column `x` (every term is a multiple of 1/2 below 256, so the
/// sum over 256 is exact in f32 and in fixed<32,32>).
fn reference_depth(d: [f32; 3], x: u32) -> u32 {
    let centre = f64::from(x) + 0.5;
    let s: f64 = d.iter().map(|&v| 2.0 * f64::from(v) * f64::from(v)).sum();
    let p = f64::from(d[0]).max(0.0);
    let z = (s + p + 2.0 * centre + (centre - 10.0).max(0.0)) / 256.0;
    (z * 4294967296.0) as u32
}

#[test]
fn inlined_helpers_give_the_same_pixels_and_errors_flat_or_as_loops() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    // (d, n, errors): positive and negative d[0] (both sides of the early return), and a
    // run that spins out of fuel in setup (no pixel drawn).
    let cases: [([f32; 3], i32, &[&str]); 3] = [
        ([1.0, 2.0, 3.0], 0, &[]),
        ([-1.5, 0.5, 2.0], 0, &[]),
        ([1.0, 2.0, 3.0], 1, &[SPIN]),
    ];
    for (d, n, codes) in cases {
        let r = scene(&program, d, n);
        let mut frames = vec![];
        for unroll in [false, true] {
            for tier in [Tier::Fast, Tier::Optimised] {
                let out = r.render(&mut jit(&program, unroll, tier));
                let mut got = out.diags.codes_at(&sources);
                got.dedup();
                assert_eq!(got, codes.to_vec(), "d={d:?} n={n} unroll={unroll} {tier:?}");
                frames.push(out.frame);
            }
        }
        // Out of fuel, every later loop head finds none and leaves its loop at once, while
        // a flat helper (like an unrolled loop) still runs: frames agree per unrolling
        // setting then (tier 0 against tier 1), and across settings otherwise.
        for (i, f) in frames.iter().enumerate().skip(1) {
            let base = if codes.is_empty() { 0 } else { i / 2 * 2 };
            assert!(
                same_frame(&frames[base], f),
                "d={d:?} n={n}: frame {i} differs from {base}"
            );
        }
        if !codes.is_empty() {
            continue;
        }
        let f = &frames[0];
        for y in 0..12 {
            for x in 0..40 {
                assert_eq!(f.depth_at(x, y), Some(reference_depth(d, x)), "d={d:?} at ({x}, {y})");
            }
        }
    }
}

/// The flat helpers leave no loop behind: with unrolling on, the kernel keeps the fuel
/// checks of `spin`'s `while` only (one load of `ctx.fuel` in a loop head), not those of
/// the five helper calls and `sum_of_twice_squares`' loop.
#[test]
fn flat_helpers_lose_their_loops() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let r = scene(&program, [1.0, 2.0, 3.0], 0);
    let inst = &r.instances()[0];
    let blocks = |clif: &str| clif.lines().filter(|l| l.starts_with("block")).count();
    for tier in [Tier::Fast, Tier::Optimised] {
        let kept = jit(&program, false, tier).clif(inst.func, &inst.key).unwrap();
        let flat = jit(&program, true, tier).clif(inst.func, &inst.key).unwrap();
        assert!(
            blocks(&flat) + 8 <= blocks(&kept),
            "{tier:?}: {} blocks flat vs {} kept",
            blocks(&flat),
            blocks(&kept)
        );
    }
}
