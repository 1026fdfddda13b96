//! Float -> int and float -> fixed conversions in pixel code whose operand is proven finite
//! and in range (src/mid/bounds.rs) lower to one `cvttps2dq` without the saturation
//! fix-ups (`fixed::convert_bounded`). These tests pin down that the proof is only used
//! where it holds: proven conversions give the values the saturating form gives, and
//! conversions of values that can be out of range or NaN in pixel code (a huge uniform
//! times X, 0/0, a local holding X that the pixel code reassigns, a local doubled in a loop)
//! still saturate as the language documents (Rust's `as i32`: NaN -> 0, out of range ->
//! the nearest end). Every case renders with tier 0, tier 1 and tier 1 without unrolling,
//! frames bit-identical, and each pixel against a reference computed here with the
//! primitive's own f32 operations.

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{Renderer, Value};

/// `int n` is chosen by `mode`; the depth encodes it exactly: 0.875 for i32::MAX, 0.125 for
/// i32::MIN, else 0.5 + n / 2^24 (exact in f32 and in fixed<32,32> for |n| < 2^22).
const CONVERSIONS: &str = r#"
int scaled(float v, float s) {
    return int(v * s);
}

primitive conversions(float rect[4]; float mode; float k; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float held = X * 16;
    if (X > 20)
        held = held * k;                // a pixel-code assignment of something unbounded
    float doubled = X;
    for (int i = 0; i < 40; i++)
        doubled = doubled * 2;          // grows every trip: X * 2^40
    fixed<32,8> f8 = X * 0.3 - 7;       // proven: |raw| < 2^31
    fixed<16,8> f16 = X * 10 - 100;     // not proven: saturates beyond 127.996
    int n = 0;
    if (mode == 0) n = int(X * 16);
    if (mode == 1) n = int(-X * 16 + Y * 3.5);
    if (mode == 2) n = scaled(X, 16) + scaled(Y, -2.25);
    if (mode == 3) n = int(floor(X) * 0.5 + min(Y, 3.0) - abs(X - 20) + round(Y * 0.7) * 8);
    if (mode == 4) n = int(float(f8) * 256);
    if (mode == 5) n = int(float(f16) * 256);
    if (mode == 6) n = int(X * k);
    if (mode == 7) n = int(-X * k);
    if (mode == 8) n = int((X - X) / (X - X)) + 5;
    if (mode == 9) n = int(held);
    if (mode == 10) n = int(doubled);
    if (n == 2147483647)
        Z = 0.875;
    else if (n == -2147483647 - 1)
        Z = 0.125;
    else
        Z = 0.5 + float(n) / 16777216;
}
"#;

const W: u32 = 40;
const H: u32 = 12;
const MODES: u32 = 11;
/// The huge uniform of modes 6, 7 and 9.
const K: f32 = 1e30;

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("conversions.prim", CONVERSIONS)])
}

fn scene(program: &Arc<Program>, mode: u32) -> Renderer {
    let mut r = Renderer::new(program.clone());
    r.set_image_size(W, H).unwrap();
    r.set_tile_size(16).unwrap();
    r.begin("conversions").unwrap();
    r.rast_param("rect", &Value(vec![0.0, 0.0, W as f32, H as f32]))
        .unwrap();
    r.rast_param("mode", &Value(vec![mode as f32])).unwrap();
    r.rast_param("k", &Value(vec![K])).unwrap();
    r.end().unwrap();
    r
}

/// The language's float -> fixed conversion read back as the fixed value's float: round
/// to nearest (ties to even, as the JIT's `nearest`), saturate to the raw range.
fn fixed_value(x: f32, bits: u32, frac: u32) -> f32 {
    let scale = (1u64 << frac) as f32;
    let raw = (x * scale).round_ties_even() as i64;
    let (lo, hi) = (-(1i64 << (bits - 1)), (1i64 << (bits - 1)) - 1);
    raw.clamp(lo, hi) as f32 / scale
}

/// `n` at pixel centre (x, y) for `mode`, with the primitive's f32 operations; Rust's
/// `as i32` saturates and maps NaN to 0, the language's documented conversion.
fn expected_n(mode: u32, x: f32, y: f32) -> i32 {
    match mode {
        0 => (x * 16.0) as i32,
        1 => (-x * 16.0 + y * 3.5) as i32,
        2 => ((x * 16.0) as i32).wrapping_add((y * -2.25) as i32),
        3 => (x.floor() * 0.5 + y.min(3.0) - (x - 20.0).abs() + (y * 0.7).round_ties_even() * 8.0) as i32,
        4 => (fixed_value(x * 0.3 - 7.0, 32, 8) * 256.0) as i32,
        5 => (fixed_value(x * 10.0 - 100.0, 16, 8) * 256.0) as i32,
        6 => (x * K) as i32,
        7 => (-x * K) as i32,
        // (X - X) / (X - X) is 0 / 0, NaN, at every pixel, and NaN converts to 0.
        8 => 5,
        9 => (if x > 20.0 { x * 16.0 * K } else { x * 16.0 }) as i32,
        _ => (0..40).fold(x, |d, _| d * 2.0) as i32,
    }
}

/// The depth the primitive writes for `n` (see `CONVERSIONS`), as raw fixed<32,32> bits.
fn encoded(n: i32) -> u32 {
    let z = match n {
        i32::MAX => 0.875f32,
        i32::MIN => 0.125,
        _ => 0.5 + n as f32 / 16777216.0,
    };
    (z as f64 * 4294967296.0) as u32
}

#[test]
fn conversions_match_the_saturating_reference_in_every_tier() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let mut saturated = [0usize; MODES as usize];
    for mode in 0..MODES {
        let what = format!("mode {mode}");
        let frame = support::all_tiers(&program, &scene(&program, mode), &what);
        for py in 0..H {
            for px in 0..W {
                let (x, y) = (px as f32 + 0.5, py as f32 + 0.5);
                let n = expected_n(mode, x, y);
                if n == i32::MAX || n == i32::MIN || (mode == 8 && n == 5) {
                    saturated[mode as usize] += 1;
                }
                assert!(
                    n == i32::MAX || n == i32::MIN || n.unsigned_abs() < 1 << 22,
                    "{what}: the encoding holds {n}"
                );
                assert_eq!(
                    frame.depth_at(px, py),
                    Some(encoded(n)),
                    "{what}: pixel ({px}, {py}), n = {n}"
                );
            }
        }
    }
    // The proven modes never saturate; the others do where the reference says so (every
    // pixel for 6, 7, 8 and 10; X > 20 for 9; f16 beyond its range for 5).
    let all = (W * H) as usize;
    assert_eq!(&saturated[0..5], &[0; 5]);
    assert_eq!(saturated[6..9], [all, all, all]);
    assert_eq!(saturated[10], all);
    assert_eq!(saturated[9], (H * (W - 20)) as usize);
    // f16 = X * 10 - 100 reaches its raw max 32767 (127.996) from X = 22.8 on: 17 columns.
    let f16_max = (0..W)
        .filter(|&px| expected_n(5, px as f32 + 0.5, 0.5) == 32767)
        .count();
    assert_eq!(f16_max, 17);
}

/// The CLIF of the kernel: a primitive whose vector conversions are all proven has no
/// saturating vector conversion left; the same one with a pixel-code assignment of an
/// unbounded value to the local it converts keeps one.
#[test]
fn only_proven_conversions_drop_the_saturation() {
    if !cfg!(target_arch = "x86_64") {
        return;
    }
    let proven = r#"
primitive proven(float rect[4]; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float x = X;
    int n = int(x * 16) - int(Y * 16);
    Z = 0.5 + float(n) / 16777216;
}
"#;
    let unproven = r#"
primitive unproven(float rect[4]; float k; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float x = X;
    if (Y > 3)
        x = x * k;
    int n = int(x * 16) - int(Y * 16);
    Z = 0.5 + float(n) / 16777216;
}
"#;
    let mut sources = SourceMap::new();
    let program = support::library_with(&mut sources, &[("proven.prim", proven), ("unproven.prim", unproven)]);
    for (name, want_sat) in [("proven", 0), ("unproven", 1)] {
        let mut r = Renderer::new(program.clone());
        r.set_image_size(16, 8).unwrap();
        r.begin(name).unwrap();
        r.rast_param("rect", &Value(vec![0.0, 0.0, 16.0, 8.0])).unwrap();
        if name == "unproven" {
            r.rast_param("k", &Value(vec![K])).unwrap();
        }
        r.end().unwrap();
        let inst = &r.instances()[0];
        for tier in [Tier::Fast, Tier::Optimised] {
            let jit = Jit::at_tier(program.clone(), tier).unwrap();
            let clif = jit.clif(inst.func, &inst.key).unwrap();
            let vector_sat = clif.lines().filter(|l| l.contains("fcvt_to_sint_sat.i32x4")).count();
            assert_eq!(vector_sat.min(1), want_sat, "{name} {tier:?}: saturating conversions");
        }
    }
}
