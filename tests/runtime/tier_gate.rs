//! The tier-up gate (src/runtime/tiergate.rs): a renderer keeps a tiered JIT's tier-1
//! worker from starting a compile until a grace period after the frame's kernels are
//! compiled; from then on, while a compile is pending, its expansion and bound pass and its
//! tiles run on one thread fewer than the pool has, so the worker gets a core. What must
//! hold whatever happens: the frame is bit for bit the tier-1 frame; the gate closes only
//! for a tiered JIT with a compile running on a pool with a thread to spare; it lets every
//! thread work once the compile has landed; and nothing waits forever (stalled, held,
//! detached or dropped worker). Assertions are on frames and counts, never on timings.

use crate::support;

use std::sync::Arc;
use std::time::{Duration, Instant};
use support::{example_scene, library_and_sources};

use primflow::abi::TierUpActivity;
use primflow::diag::SourceMap;
use primflow::ir::Program;
use primflow::jit::{Jit, Tier};
use primflow::runtime::{KernelSource, RenderOutput, Renderer};
use primflow::workload::{fill_scene, same_frame, small_scene};

/// Small scenes with many tiles (16 px) and, for `small`, more than one bound-pass job.
fn scenes(sources: &mut SourceMap, program: &Arc<Program>) -> Vec<(String, Renderer)> {
    let mut out = vec![
        (
            "fill".to_string(),
            fill_scene(program, 96, 4, Some("perspective_linear"), 4),
        ),
        ("small".to_string(), small_scene(program, 96, 1200, 4)),
    ];
    for name in ["triangles.scene", "nurb_surface.scene"] {
        out.push((name.to_string(), example_scene(sources, program, name)));
    }
    for (_, r) in &mut out {
        r.set_tile_size(16).unwrap();
    }
    out
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

fn render_on(threads: usize, r: &Renderer, source: &mut (dyn KernelSource + Send)) -> RenderOutput {
    let out = pool(threads).install(|| r.render(source));
    assert!(!out.diags.has_errors(), "{:?}", out.diags.items);
    out
}

/// Jobs a gated render runs: the bound pass's (512 instances each) and the tiles (these
/// scenes bin their few draws in one chunk, on the calling thread: no binning jobs).
fn jobs_of(r: &Renderer) -> usize {
    let side = primflow::runtime::frame::tile_side(r.options.tile_size);
    let tiles = r.options.width.div_ceil(side) * r.options.height.div_ceil(side);
    r.instances().len().div_ceil(512) + tiles as usize
}

#[test]
fn a_frame_rendered_while_tier_1_compiles_leaves_it_one_thread_and_matches_tier_1() {
    let (mut sources, program) = library_and_sources();
    for (name, r) in scenes(&mut sources, &program) {
        let reference = render_on(2, &r, &mut Jit::at_tier(program.clone(), Tier::Optimised).unwrap());
        assert!(
            reference.frame.depth_values().iter().any(|&d| d != 0),
            "{name}: the scene draws something"
        );
        // No grace, and a worker whose compile lasts until the stall drops: the whole frame
        // runs while tier 1 compiles.
        let mut jit = Jit::tiered(program.clone()).unwrap();
        jit.set_tier_up_grace(0.0);
        let stall = jit.stall_tier_up().expect("a tiered JIT has a worker to stall");
        let stalled = render_on(2, &r, &mut jit);
        let watch = jit.tier_up_watch().unwrap();
        assert_eq!(watch.activity(), TierUpActivity::Compiling, "{name}");
        assert_eq!(stalled.stats.gated_jobs, jobs_of(&r), "{name}: every job ran gated");
        assert_eq!(
            stalled.stats.gated_peak_threads, 1,
            "{name}: one thread of two rendered"
        );
        assert!(
            same_frame(&stalled.frame, &reference.frame),
            "{name}: gated tier-0 frame differs"
        );

        // Released: the compile lands, and the next frame runs on both threads.
        drop(stall);
        jit.wait_for_tier_up();
        assert_eq!(watch.activity(), TierUpActivity::Idle, "{name}");
        let after = render_on(2, &r, &mut jit);
        assert_eq!(after.stats.gated_jobs, 0, "{name}: no compile pending, no gate");
        assert_eq!(after.stats.gated_peak_threads, 0, "{name}");
        assert!(
            same_frame(&after.frame, &reference.frame),
            "{name}: tier-1 frame differs"
        );
    }
}

#[test]
fn a_frame_within_the_grace_keeps_every_thread_and_the_worker_waits_for_it() {
    let (mut sources, program) = library_and_sources();
    for (name, r) in scenes(&mut sources, &program) {
        let reference = render_on(2, &r, &mut Jit::at_tier(program.clone(), Tier::Optimised).unwrap());
        let mut jit = Jit::tiered(program.clone()).unwrap();
        // A grace of a million times the compile: hours, so the frame ends inside it.
        jit.set_tier_up_grace(1e6);
        let out = render_on(2, &r, &mut jit);
        assert_eq!(
            out.stats.gated_jobs, 0,
            "{name}: the worker was held, no thread left to it"
        );
        assert!(same_frame(&out.frame, &reference.frame), "{name}");
        // The hold outlives the frame until its deadline: the worker has compiled nothing.
        let watch = jit.tier_up_watch().unwrap();
        assert_eq!(watch.activity(), TierUpActivity::Held, "{name}");
        let inst = &r.instances()[0];
        assert!(jit.tier_up_kernel(inst.func, &inst.key).is_none(), "{name}");
        // A JIT being dropped ignores holds: its worker drains its queue and ends.
        drop(jit);
        assert_eq!(watch.activity(), TierUpActivity::Idle, "{name}");
    }
}

#[test]
fn no_gate_on_one_thread_for_a_detached_worker_or_a_single_tier_jit() {
    let (_sources, program) = library_and_sources();
    let mut r = fill_scene(&program, 96, 4, Some("perspective_linear"), 4);
    r.set_tile_size(16).unwrap();
    let reference = render_on(2, &r, &mut Jit::at_tier(program.clone(), Tier::Optimised).unwrap());

    // One thread: nothing to spare for the worker; the stalled compile stays pending.
    let mut jit = Jit::tiered(program.clone()).unwrap();
    jit.set_tier_up_grace(0.0);
    let stall = jit.stall_tier_up().unwrap();
    let one = render_on(1, &r, &mut jit);
    assert_eq!((one.stats.gated_jobs, one.stats.gated_peak_threads), (0, 0));
    assert!(same_frame(&one.frame, &reference.frame));
    let watch = jit.tier_up_watch().unwrap();
    assert_ne!(watch.activity(), TierUpActivity::Idle, "the stalled compile is pending");

    // Detached while its compile is stalled: the JIT no longer reports a compiler, the
    // worker drains its queue on its own (the stall no longer binds it), and the next
    // frame runs on every thread.
    jit.detach_tier_up();
    assert!(jit.tier_up_watch().is_none());
    let detached = render_on(2, &r, &mut jit);
    assert_eq!(detached.stats.gated_jobs, 0);
    assert!(same_frame(&detached.frame, &reference.frame));
    assert!(
        !watch.wait(Duration::from_secs(120)),
        "the detached worker finished its queue"
    );
    drop(stall);

    // Single-tier JITs have no compiler to wait for.
    for tier in [Tier::Fast, Tier::Optimised] {
        let mut single = Jit::at_tier(program.clone(), tier).unwrap();
        assert!(single.tier_up_watch().is_none() && single.stall_tier_up().is_none());
        let out = render_on(2, &r, &mut single);
        assert_eq!(out.stats.gated_jobs, 0, "{tier:?}");
        assert!(same_frame(&out.frame, &reference.frame), "{tier:?}");
    }
}

#[test]
fn a_hold_outliving_its_jit_does_not_keep_the_drop_waiting() {
    // Dropping a tiered JIT joins its worker; a hold still alive must not stall that join
    // (the worker drains its queue once its JIT is gone, then ends).
    let (_sources, program) = library_and_sources();
    let r = fill_scene(&program, 32, 1, Some("perspective_linear"), 4);
    let inst = &r.instances()[0];
    let mut jit = Jit::tiered(program.clone()).unwrap();
    let watch = jit.tier_up_watch().unwrap();
    let hold = watch.hold();
    jit.kernel(inst.func, &inst.key).unwrap();
    assert_eq!(
        watch.activity(),
        TierUpActivity::Held,
        "the request waits behind the hold"
    );
    drop(jit);
    assert_eq!(
        watch.activity(),
        TierUpActivity::Idle,
        "the worker answered the request before it ended"
    );
    drop(hold);
}

#[test]
fn a_hold_with_a_deadline_lets_the_worker_go_at_it() {
    let (_sources, program) = library_and_sources();
    let r = fill_scene(&program, 32, 1, Some("perspective_linear"), 4);
    let inst = &r.instances()[0];
    let mut jit = Jit::tiered(program.clone()).unwrap();
    let watch = jit.tier_up_watch().unwrap();
    assert_eq!(watch.activity(), TierUpActivity::Idle, "nothing requested yet");
    assert_eq!(
        watch.grace(Duration::from_millis(2)),
        Duration::from_millis(6),
        "the default grace: 3x the tier-0 compile"
    );
    assert_eq!(watch.grace(Duration::ZERO), Duration::ZERO, "no compile, no grace");
    let mut endless = Jit::tiered(program.clone()).unwrap();
    endless.set_tier_up_grace(f64::INFINITY);
    let endless = endless.tier_up_watch().unwrap();
    assert_eq!(endless.grace(Duration::ZERO), Duration::ZERO, "no compile, no grace");
    assert_eq!(
        endless.grace(Duration::from_millis(1)),
        Duration::from_secs(3600),
        "capped"
    );
    let mut hold = watch.hold();
    jit.kernel(inst.func, &inst.key).unwrap();
    assert!(
        watch.wait(Duration::from_millis(5)),
        "held: still pending after the timeout"
    );
    assert_eq!(watch.activity(), TierUpActivity::Held);
    // Never dropped before the compile lands: the deadline alone releases the worker.
    hold.release_at(Instant::now() + Duration::from_millis(1));
    assert!(!watch.wait(Duration::from_secs(120)), "released: the compile lands");
    assert!(jit.tier0_forwards_to(inst.func, &inst.key).is_some());
    drop(hold);
}
