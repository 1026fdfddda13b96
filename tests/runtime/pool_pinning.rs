//! Render thread pools (src/runtime/pool.rs): only a pool of two or more threads, at most
//! one per allowed CPU, is pinned, each thread to a CPU of its own.

use primflow::runtime::pool::{allowed_cpus, pinning_plan, render_pool};

#[test]
fn plan_pins_only_pools_of_two_to_cpu_count_threads() {
    assert_eq!(pinning_plan(1), None);
    let Some(cpus) = allowed_cpus() else {
        return; // not Linux: nothing is ever pinned
    };
    assert_eq!(pinning_plan(cpus.len() + 1), None);
    if cpus.len() >= 2 {
        let plan = pinning_plan(cpus.len()).expect("a pool of one thread per CPU is pinned");
        let mut sorted = plan.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, cpus, "every allowed CPU once");
    }
}

#[cfg(target_os = "linux")]
#[test]
fn pool_threads_are_each_allowed_only_their_planned_cpu() {
    if allowed_cpus().is_none_or(|c| c.len() < 2) {
        return;
    }
    let plan = pinning_plan(2).unwrap();
    let pool = render_pool(2).unwrap();
    // Each thread's own affinity mask, read on the thread.
    let masks = pool.broadcast(|ctx| (ctx.index(), allowed_cpus()));
    for (i, mask) in masks {
        assert_eq!(mask, Some(vec![plan[i]]), "thread {i}");
    }
    assert_ne!(plan[0], plan[1]);
    // A one-thread pool keeps the process's whole mask.
    let one = render_pool(1).unwrap();
    assert_eq!(one.install(allowed_cpus), allowed_cpus());
}
