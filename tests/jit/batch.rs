//! A kernel batch (a root primitive and the primitives it calls) is lowered and compiled on
//! the caller's rayon pool, in parallel when it has threads (`src/jit/batch.rs`): the
//! kernels are the same as a one-thread pool's, and a function of the batch that fails
//! fails the batch, which then defines nothing.

use crate::support;
use crate::support::raw_depth;

use std::sync::Arc;

use crate::support::jit::*;
use primflow::abi::{ERR_NONE, MODE_BOUND};
use primflow::ir::*;
use primflow::jit::{Jit, JitOptions, Tier};

/// The NURB scene's batch (nurb_surface, polygon, screen_triangle) compiled on pools of 1,
/// 2 and 4 threads renders the same frame bit for bit, at both tiers, each compile
/// reporting its batch's wall time and CPU time.
#[test]
fn a_batch_compiled_in_parallel_renders_what_a_one_thread_pool_renders() {
    let (mut sources, program) = support::library_and_sources();
    let r = support::example_scene(&mut sources, &program, "nurb_surface.scene");
    for tier in [Tier::Fast, Tier::Optimised] {
        let mut frames = vec![];
        for threads in [1, 2, 4] {
            let mut jit = Jit::with_options(
                program.clone(),
                JitOptions {
                    tier,
                    ..JitOptions::default()
                },
            )
            .unwrap();
            frames.push(support::render_with(&r, &mut jit, threads));
            let nurb = program.find("nurb_surface").unwrap();
            let inst = r.instances().iter().find(|i| i.func == nurb).unwrap();
            let cost = jit.compile_cost(nurb, &inst.key).expect("compiled");
            assert!(cost.batch_wall_micros > 0, "{tier:?}, {threads} threads: {cost:?}");
            if cfg!(target_os = "linux") {
                assert!(
                    cost.batch_cpu_micros >= cost.cpu_micros && cost.cpu_micros > 0,
                    "{tier:?}, {threads} threads: {cost:?}"
                );
            }
            for callee in ["polygon", "screen_triangle"] {
                let f = program.find(callee).unwrap();
                let callee_cost = jit.compile_cost(f, &inst.key).expect("compiled with its caller");
                assert_eq!(callee_cost.batch_cpu_micros, cost.batch_cpu_micros, "one batch");
            }
        }
        for (f, threads) in frames[1..].iter().zip([2, 4]) {
            assert!(
                primflow::workload::same_frame(&frames[0], f),
                "{tier:?}: {threads} threads differ from one"
            );
        }
    }
}

/// inner(X, Y, Z): setup: bound(1, 2, 5, 4); pixel: Z = 0.5.
fn inner() -> Function {
    let mut fb = Fb::new("inner", FuncKind::Primitive);
    let (_x, _y, z) = fb.xyz();
    fb.setup = vec![bound([fc(1.0), fc(2.0), fc(5.0), fc(4.0)])];
    fb.pixel = vec![assign(&z, fc(0.5))];
    fb.finish()
}

/// NAME(X, Y, Z): calls each of `callees` with (X, Y, Z), then `tail` per pixel.
fn caller(name: &str, callees: &[u32], tail: Vec<Stmt<Tree>>) -> Function {
    let mut fb = Fb::new(name, FuncKind::Primitive);
    let (x, y, z) = fb.xyz();
    fb.setup = callees
        .iter()
        .map(|&c| {
            s(StmtKind::CallPrimitive {
                callee: FuncId(c),
                args: vec![x.clone(), y.clone(), z.clone()],
                site: SiteId(0),
            })
        })
        .collect();
    fb.pixel = tail;
    fb.finish()
}

/// `broken` (which calls `inner`, then fails to lower: a `bound` in per-pixel code) fails
/// every batch it is in with its own error, in every pool; the healthy functions lowered
/// and compiled with it are not defined, and a later batch that calls `inner` compiles it.
#[test]
fn a_function_that_fails_to_lower_fails_its_batch_and_defines_nothing() {
    let bad_bound = bound([fc(0.0), fc(0.0), fc(1.0), fc(1.0)]);
    let program = Arc::new(program(
        vec![
            inner(),                                 // 0
            caller("broken", &[0], vec![bad_bound]), // 1
            caller("outer_broken", &[0, 1], vec![]), // 2
            caller("outer", &[0], vec![]),           // 3
        ],
        1,
    ));
    let key = kind_key(&[]);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut jit = Jit::at_tier(program.clone(), Tier::Fast).unwrap();
        let err = pool
            .install(|| jit.kernel(FuncId(2), &key))
            .expect_err("the batch of outer_broken includes broken");
        // Test and debug builds find it in the validator (`ir::valid`), release builds
        // where lowering meets it.
        let expected = if cfg!(debug_assertions) {
            "internal compiler error: IR invalid after forward: IR rule `PixelPart` (no primitive call or `bound` in the pixel part) broken in `broken` at statement `Bound` (file 0, bytes 0..0): `bound` in the pixel part"
        } else {
            "`bound` in per-pixel code"
        };
        assert_eq!(err.message, expected, "{threads} threads");
        for f in 0..3 {
            assert!(
                jit.compile_cost(FuncId(f), &key).is_none(),
                "{threads} threads: function {f} defined by a failed batch"
            );
        }
        let again = pool.install(|| jit.kernel(FuncId(1), &key)).expect_err("broken alone");
        assert_eq!(again.message, err.message);
        // `inner` was declared by the failed batches but never defined: a batch calling it
        // defines it.
        let outer = pool.install(|| jit.kernel(FuncId(3), &key)).expect("outer compiles");
        assert!(jit.compile_cost(FuncId(0), &key).is_some(), "inner compiled with outer");
        let mut tile = Tile::new(0);
        let ctx = tile.render(&outer, &[1]);
        assert_eq!(ctx.error, ERR_NONE);
        assert_eq!(tile.depth_at(2, 2), raw_depth(0.5), "inner's pixels through outer");
        assert_eq!(tile.depth_at(0, 0), 0, "outside inner's bound");
        let ctx = tile.run(&outer, &[1], MODE_BOUND, 100);
        assert_eq!((ctx.bound_set, ctx.bound), (1, [1.0, 2.0, 5.0, 4.0]), "inner's bound");
    }
}
