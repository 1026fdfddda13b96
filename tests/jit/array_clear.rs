//! Uniform stack arrays cleared by a loop and without an entry clear (`Lower::zero_stack_bytes`,
//! `src/mid/init.rs`), and dead code after `break`/`return` ending in a trap
//! (`Lower::jump_live`): the frame must be what the language says in both tiers.
//!
//! `cleared` declares `float a[103]` (412 bytes: a clear loop of 64-byte trips, one 16-byte
//! store and three words) inside a loop, writes one element per round and reads the one the
//! previous round wrote (which the declaration must have cleared again), the one it wrote,
//! and a dynamic index that may leave the array (clamped, W0801 at its line:col). A uniform
//! `if (r == stop) break;` and an early `return` put dead blocks in the loop.

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::Tier;
use support::{rect_depth_and_codes as run, rect_scene as scene};

const SOURCE: &str = r#"
primitive cleared(float rect[4]; int rounds, off, stop; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    if (rounds > 51)
        return;
    float s = 0;
    for (int r = 0; r < rounds; r++) {
        float a[103];
        a[r] = r + 1;
        s = s + a[r] + a[102 - r] * 2 + a[r + off] * 4;
        if (r == stop)
            break;
        a[101 - r] = 7;
    }
    Z = s / 16384;
}

primitive flat(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    Z = z;
}
"#;

/// The index `r + off` (the site its error names).
const OFF_SITE: &str = "W0801@11:43";

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("cleared.prim", SOURCE)])
}

/// What the language says `cleared` computes: per round `a` is all zeros but `a[r]`, so
/// `a[102 - r]` (last round's write) reads 0 and `a[r + off]`, clamped into the array,
/// reads `r + 1` exactly when it lands on `r`; the loop stops after round `stop`.
fn reference(rounds: i64, off: i64, stop: i64) -> (f32, bool) {
    let mut s = 0f32;
    let mut bad = false;
    for r in 0..rounds {
        let at = r + off;
        bad |= !(0..103).contains(&at);
        let other = if at.clamp(0, 102) == r { (r + 1) as f32 } else { 0.0 };
        s += (r + 1) as f32 + 0.0 * 2.0 + other * 4.0;
        if r == stop {
            break;
        }
    }
    (s / 16384.0, bad)
}

#[test]
fn arrays_cleared_by_a_loop_read_zero_after_partial_writes_in_both_tiers() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    // (rounds, off, stop): in range, past the end, below the start, stopped by `break`,
    // no rounds, and `rounds > 51` (returns before drawing).
    let cases = [
        (10, 0, -1),
        (10, 200, -1),
        (3, -5, -1),
        (51, 0, 20),
        (0, 0, -1),
        (52, 0, -1),
    ];
    for (rounds, off, stop) in cases {
        let (z, bad) = reference(rounds, off, stop);
        let params = [("rounds", rounds as f32), ("off", off as f32), ("stop", stop as f32)];
        for tier in [Tier::Fast, Tier::Optimised] {
            let case = format!("rounds={rounds} off={off} stop={stop} {tier:?}");
            let (got, errors) = run(&program, &sources, &scene(&program, "cleared", &params), tier);
            if rounds > 51 {
                assert_eq!((got, errors.len()), (0, 0), "{case}: returned before drawing");
                continue;
            }
            let (want, none) = run(&program, &sources, &scene(&program, "flat", &[("z", z)]), tier);
            assert!(none.is_empty());
            if rounds > 0 {
                assert_ne!(want, 0, "{case}: the reference draws");
            }
            assert_eq!(got, want, "{case}");
            let expected: Vec<&str> = if bad { vec![OFF_SITE] } else { vec![] };
            assert_eq!(errors, expected, "{case}");
        }
    }
}

/// `interpolation_data acc[40]` declared in a loop (the NURB tessellation's `known_data`
/// form: cleared as a block, 16 bytes per store, when the data has all its components):
/// round r writes `acc[r]`, reads it and `acc[39 - r]`, then writes `acc[38 - r]`, the
/// element the next round reads as its `acc[39 - r]`: zero only if that round's declaration
/// cleared the array again.
const INTERP_SOURCE: &str = r#"
primitive interp_cleared(float rect[4]; int rounds;
                         interpolator_data interp_data[];
                         varying float X, Y; inout varying fixed<32,32> Z)
{
    interpolation_data sum = interp_data[0] * 0;
    for (int r = 0; r < rounds; r++) {
        interpolation_data acc[40];
        acc[r] = interp_data[0] * (r + 1);
        sum = sum + acc[r] + acc[39 - r] * 2;
        acc[38 - r] = interp_data[0] * 100;
    }
    interpolation_data data[3] = {sum, sum, sum};
    float a[4] = {rect[0], rect[1], 0.5, 1};
    float b[4] = {rect[2], rect[1], 0.5, 1};
    float c[4] = {rect[0], rect[3], 0.5, 1};
    float v[3][4] = {a, b, c};
    screen_triangle(v, data, X, Y, Z);
}
"#;

#[test]
fn interpolation_data_arrays_declared_in_a_loop_read_zero_in_both_tiers() {
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("interp_cleared.prim", INTERP_SOURCE)]);
    let colour = [0.25f32, 0.5, 2.0];
    for rounds in [0, 1, 7, 19] {
        let mut r = primflow::runtime::Renderer::new(program.clone());
        r.set_image_size(24, 16).unwrap();
        r.material_interp("Cs", "linear", &[]).unwrap();
        r.begin("interp_cleared").unwrap();
        r.rast_param("rect", &primflow::runtime::Value(vec![2.0, 2.0, 20.0, 12.0]))
            .unwrap();
        r.rast_param("rounds", &primflow::runtime::Value(vec![rounds as f32]))
            .unwrap();
        for _ in 0..3 {
            r.material("Cs", &primflow::runtime::Value(colour.to_vec())).unwrap();
            r.sequence_point().unwrap();
        }
        r.end().unwrap();
        // Sum over rounds of (r + 1): the reads of `acc[39 - r]` see the clear.
        let factor: f32 = (0..rounds).map(|r| (r + 1) as f32).sum();
        for tier in [Tier::Fast, Tier::Optimised] {
            let mut jit = primflow::jit::Jit::at_tier(program.clone(), tier).unwrap();
            let out = r.render(&mut jit);
            assert!(out.diags.items.is_empty(), "{:?}", out.diags.items);
            let got = out.frame.param_at("Cs", 4, 4).expect("Cs is a plane");
            let want: Vec<f32> = colour.iter().map(|c| c * factor).collect();
            assert_eq!(got, want, "rounds={rounds} {tier:?}");
            assert!(out.frame.depth_at(4, 4).unwrap() > 0, "rounds={rounds} {tier:?}: drawn");
        }
    }
}
