//! A kernel whose stack frame does not fit in the thread that runs it records a run-time
//! error and draws nothing, instead of running its frame past the end of the stack
//! (`abi::TileCtx::stack_limit`, the check at every kernel's entry in `jit::lower`).
//!
//! `big` keeps three 65536-float arrays (768 KiB of frame); `calls_big` has a small frame
//! and calls it. On render threads with 512 KiB stacks neither draws and W0801 names `big`
//! (the primitive whose frame did not fit, also when it was called); on 8 MiB stacks both
//! draw the exact depth. Both tiers.
//!
//! A test binary of its own: in a binary whose other tests' threads have ended, a new
//! 512 KiB thread can be given a finished thread's larger stack from glibc's stack cache,
//! and the frame then fits (seen when this test ran inside the grouped `jit` binary).

mod support;

use std::sync::Arc;

use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::Renderer;
use support::rect_scene as scene;

const SOURCE: &str = r#"
primitive big(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    bound(rect[0], rect[1], rect[2], rect[3]);
    float a[65536], b[65536], c[65536];
    int i = int(z * 1000);
    a[i] = z;
    b[i + 1] = z;
    c[65535 - i] = z;
    Z = a[i] + b[i + 1] + c[65535 - i] - 2 * z;
}

primitive calls_big(float rect[4]; float z; varying float X, Y; inout varying fixed<32,32> Z)
{
    big(rect, z, X, Y, Z);
}
"#;

/// Where W0801 points for a frame that did not fit: the name in `big`'s declaration.
const BIG_AT: &str = "W0801@2:11";

fn library(sources: &mut SourceMap) -> Arc<Program> {
    support::library_with(sources, &[("big.prim", SOURCE)])
}

/// Render on one thread with a `stack` byte stack: the depth inside the rectangle and the
/// run-time diagnostics as `code@line:col`.
fn render(program: &Arc<Program>, sources: &SourceMap, r: &Renderer, tier: Tier, stack: usize) -> (u32, Vec<String>) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .stack_size(stack)
        .build()
        .unwrap();
    let mut jit = Jit::at_tier(program.clone(), tier).unwrap();
    let out = pool.install(|| r.render(&mut jit));
    assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
    let mut codes = out.diags.codes_at(sources);
    codes.dedup();
    (out.frame.depth_at(8, 5).unwrap(), codes)
}

#[test]
fn a_frame_too_big_for_the_threads_stack_draws_nothing_and_is_reported_at_its_primitive() {
    let mut sources = SourceMap::new();
    let program = library(&mut sources);
    // z = 0.25 is exact in fixed<32,32>: a quarter of 2^32.
    let drawn = 1u32 << 30;
    for prim in ["big", "calls_big"] {
        let r = scene(&program, prim, &[("z", 0.25)]);
        for tier in [Tier::Fast, Tier::Optimised] {
            let what = format!("{prim} at {tier:?}");
            let (depth, codes) = render(&program, &sources, &r, tier, 512 << 10);
            assert_eq!(depth, 0, "{what}, 512 KiB stack: nothing drawn");
            assert_eq!(codes, [BIG_AT], "{what}, 512 KiB stack");
            let (depth, codes) = render(&program, &sources, &r, tier, 8 << 20);
            assert_eq!(depth, drawn, "{what}, 8 MiB stack");
            assert!(codes.is_empty(), "{what}, 8 MiB stack: {codes:?}");
        }
    }
}
