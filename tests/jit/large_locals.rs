//! Locals too large for SSA variables live on the stack even when every access has a
//! constant index (`jit::lower`'s `take_var_words`). Cranelift allows at most 65535
//! parameters per block and a loop header can carry every variable: `float a[65535]` filled
//! by an unrolled loop and read in the pixel part panicked Cranelift's SSA builder at tier 1
//! (found by mutating `screen_triangle.prim`'s `fa[3]`). Here one such array and two whose
//! sum is past the limit, and a kernel calling one of them: both tiers draw the exact depth
//! and report nothing. A varying array is cleared by a loop (`Lower::zero_stack_bytes`), not
//! a store per component: `varying_wide` reads what the previous group set, which the
//! clear must have zeroed, also under a varying `if`.

use crate::support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::Tier;
use support::{rect_depth_and_codes, rect_scene};

const SOURCE: &str = r#"
primitive one_wide(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[65535];
    for (int i = 0; i < 3; i++)
        a[i] = z * (i + 1);
    a[65534] = z;
    if (a[0] * X + a[1] * Y + a[65534] < 0) return;
    Z = a[2] - a[0] - a[65534];
}

primitive two_wide(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float b[40000], c[40000];
    for (int i = 0; i < 3; i++) {
        b[i] = z;
        c[39999 - i] = 2 * z;
    }
    if (b[0] * X + c[39999] * Y < 0) return;
    Z = c[39997] - b[1];
}

primitive calls_wide(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    two_wide(rect, z, X, Y, Z);
}

primitive varying_wide(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float v[65536];
    float w = z + 100 * v[0];
    v[0] = 1;
    if (X > 6) {
        float u[40000];
        w += 100 * u[39999];
        u[39999] = 1;
    }
    Z = w;
}

primitive flat(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    Z = z;
}
"#;

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("wide.prim", SOURCE)])
}

#[test]
fn constant_indexed_locals_past_the_variable_limit_render_at_both_tiers() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    for z in [0.25f32, 0.625] {
        let reference = rect_scene(&program, "flat", &[("z", z)]);
        for prim in ["one_wide", "two_wide", "calls_wide", "varying_wide"] {
            let r = rect_scene(&program, prim, &[("z", z)]);
            for tier in [Tier::Fast, Tier::Optimised] {
                let (want, none) = rect_depth_and_codes(&program, &sources, &reference, tier);
                assert!(none.is_empty(), "{none:?}");
                let (got, errors) = rect_depth_and_codes(&program, &sources, &r, tier);
                assert_eq!(got, want, "{prim} z={z} {tier:?}: depth");
                assert!(errors.is_empty(), "{prim} z={z} {tier:?}: {errors:?}");
            }
        }
    }
}

/// The clears of `varying_wide`'s 105536 varying floats are loops: its CLIF stays small at
/// both tiers (straight stores were a line per 16 bytes, 105536 lines, 11 s to compile 20
/// such arrays).
#[test]
fn a_varying_array_is_cleared_by_a_loop() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    let func = program.find("varying_wide").unwrap();
    let key = primflow::abi::VariantKey::default();
    for tier in [Tier::Fast, Tier::Optimised] {
        let jit = primflow::jit::Jit::at_tier(program.clone(), tier).unwrap();
        let lines = jit.clif(func, &key).unwrap().lines().count();
        assert!(lines < 2000, "{tier:?}: {lines} lines of CLIF");
    }
}
