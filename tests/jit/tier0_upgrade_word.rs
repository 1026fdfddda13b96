//! A tiered JIT's tier-0 kernels forward to the entry in their upgrade word, which the tier-0
//! code itself reads on every call.

use std::sync::atomic::{AtomicUsize, Ordering};

use primflow::abi::{ErrorCounts, KernelFn, TileCtx, MODE_BOUND};
use primflow::jit::Jit;

use crate::support;

static FORWARDED_CALLS: AtomicUsize = AtomicUsize::new(0);

unsafe extern "C" fn count_call(_ctx: *mut TileCtx, _args: *const u32) {
    FORWARDED_CALLS.fetch_add(1, Ordering::SeqCst);
}

/// The tier-0 code itself reads its upgrade word: with a stand-in entry stored there, a
/// call of the tier-0 entry runs the stand-in, and with the word cleared, its own code.
#[test]
fn a_tiered_jits_tier_0_kernel_calls_the_entry_in_its_word() {
    let program = support::library();
    let r = primflow::workload::fill_scene(&program, 32, 1, Some("perspective_linear"), 4);
    let inst = &r.instances()[0];
    let mut jit = Jit::tiered(program.clone()).unwrap();
    let tier0 = jit.kernel(inst.func, &inst.key).unwrap();
    // The worker is idle after this and never writes the word again.
    jit.wait_for_tier_up();
    let word = jit.upgrade_word(inst.func, &inst.key).expect("a tier-0 kernel's word");
    assert_eq!(
        word.load(Ordering::SeqCst),
        jit.tier_up_kernel(inst.func, &inst.key).unwrap().entry as usize
    );
    let run = |mode| {
        let mut ctx = TileCtx::new(mode, 32, 32);
        let mut no_depth: Vec<u32> = Vec::new();
        ctx.depth = no_depth.as_mut_ptr();
        let mut errors = ErrorCounts::new(&program);
        ctx.setup_counts = errors.ptr();
        ctx.pixel_counts = errors.ptr();
        // SAFETY: bound mode with an empty tile touches no buffer (as `run_bound`) but
        // the error counts; the argument block is the instance's, laid out for this
        // kernel.
        unsafe { (tier0.entry)(&mut ctx, inst.args.as_ptr()) };
        ctx.bound_set
    };
    word.store(count_call as KernelFn as usize, Ordering::SeqCst);
    assert_eq!(run(MODE_BOUND), 0, "the stand-in records no bound");
    assert_eq!(FORWARDED_CALLS.load(Ordering::SeqCst), 1);
    word.store(0, Ordering::SeqCst);
    assert_eq!(run(MODE_BOUND), 1, "its own code records the bound");
    assert_eq!(FORWARDED_CALLS.load(Ordering::SeqCst), 1);
}
