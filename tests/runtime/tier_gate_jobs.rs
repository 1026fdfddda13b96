//! The tier-up gate's job scheduling (src/runtime/tiergate.rs) against a stand-in compiler
//! whose activity the jobs themselves switch: results in job order, at most `threads - 1`
//! jobs at once while compiling, every thread once the compile lands, and no gate without a
//! busy compiler or a spare thread. `tier_gate` tests the gate through the renderer.

use std::sync::atomic::{AtomicU8, AtomicUsize, Ordering};
use std::time::Duration;

use primflow::abi::TierUpActivity;
use primflow::runtime::tiergate::{Compiler, Gate, GateStats};

/// A compiler whose activity the jobs themselves change.
struct Fake(AtomicU8);

const ACTIVITIES: [TierUpActivity; 3] = [TierUpActivity::Idle, TierUpActivity::Held, TierUpActivity::Compiling];

impl Fake {
    fn new(a: TierUpActivity) -> Fake {
        Fake(AtomicU8::new(ACTIVITIES.iter().position(|&b| b == a).unwrap() as u8))
    }
    fn set(&self, a: TierUpActivity) {
        self.0.store(Fake::new(a).0.into_inner(), Ordering::SeqCst);
    }
}

impl Compiler for Fake {
    fn activity(&self) -> TierUpActivity {
        ACTIVITIES[self.0.load(Ordering::SeqCst) as usize]
    }
}

fn pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap()
}

/// What [`gated`] saw.
struct Seen {
    results: Vec<usize>,
    stats: GateStats,
    /// Most jobs that ran at once among those that started while compiling.
    most_while_compiling: usize,
    /// Jobs that started before the switch.
    started_before_switch: usize,
}

/// Run 40 jobs under a gate on a 3-thread pool, the compiler's activity `first` until
/// job `switch_at` ends, `then` after it.
fn gated(first: TierUpActivity, switch_at: usize, then: TierUpActivity) -> Seen {
    let compiler = Fake::new(first);
    let running = AtomicUsize::new(0);
    let most_while_compiling = AtomicUsize::new(0);
    let started_before_switch = AtomicUsize::new(0);
    let switched = std::sync::atomic::AtomicBool::new(false);
    let (results, stats) = pool(3).install(|| {
        let gate = Gate::new(Some(&compiler)).expect("a busy compiler on 3 threads closes the gate");
        gate.run(40, |i| {
            let now = running.fetch_add(1, Ordering::SeqCst) + 1;
            if compiler.activity() == TierUpActivity::Compiling {
                most_while_compiling.fetch_max(now, Ordering::SeqCst);
            }
            if !switched.load(Ordering::SeqCst) {
                started_before_switch.fetch_add(1, Ordering::SeqCst);
            }
            // Long enough that the other loops are waiting when the next job is claimed.
            std::thread::sleep(Duration::from_micros(200));
            if i == switch_at {
                // In this order, a job that starts unswitched was claimed before the
                // activity changed.
                switched.store(true, Ordering::SeqCst);
                compiler.set(then);
            }
            running.fetch_sub(1, Ordering::SeqCst);
            i * 10
        })
    });
    Seen {
        results,
        stats,
        most_while_compiling: most_while_compiling.load(Ordering::SeqCst),
        started_before_switch: started_before_switch.load(Ordering::SeqCst),
    }
}

fn in_order() -> Vec<usize> {
    (0..40).map(|i| i * 10).collect()
}

#[test]
fn a_gate_that_never_opens_runs_every_job_on_all_threads_but_one() {
    let seen = gated(TierUpActivity::Compiling, usize::MAX, TierUpActivity::Idle);
    assert_eq!(seen.results, in_order());
    assert_eq!(seen.stats.gated_jobs, 40);
    assert_eq!(seen.stats.peak_threads, 2);
    assert!(
        seen.most_while_compiling <= 2,
        "{} jobs at once on 3 threads",
        seen.most_while_compiling
    );
}

#[test]
fn a_gate_opens_once_the_compile_lands() {
    let seen = gated(TierUpActivity::Compiling, 7, TierUpActivity::Idle);
    assert_eq!(seen.results, in_order());
    // Every job claimed before the switch was gated; jobs claimed after it were not. A
    // job is claimed just before it starts, and each of the two permit holders can have
    // claimed one before the switch that starts after it.
    let before = seen.started_before_switch;
    assert!(before >= 8, "{before}");
    assert!(
        (before..=before + 2).contains(&seen.stats.gated_jobs),
        "{:?}, {before}",
        seen.stats
    );
    assert!(seen.most_while_compiling <= 2, "{}", seen.most_while_compiling);
}

#[test]
fn a_held_compiler_leaves_every_thread_working_until_it_starts() {
    let seen = gated(TierUpActivity::Held, 7, TierUpActivity::Compiling);
    assert_eq!(seen.results, in_order());
    // Jobs claimed while held were not gated, all those claimed after were; a held
    // phase's jobs may still run when compiling begins, so no bound on concurrency
    // for them, but the gate still counts no more permit holders than it has.
    let before = seen.started_before_switch;
    assert!(before >= 8, "{before}");
    let after = 40 - before;
    assert!(
        (after.saturating_sub(2)..=after).contains(&seen.stats.gated_jobs),
        "{:?}, {before} before the switch",
        seen.stats
    );
    assert!(seen.stats.peak_threads <= 2, "{:?}", seen.stats);
}

#[test]
fn no_gate_without_a_busy_compiler_or_a_spare_thread() {
    let idle = Fake::new(TierUpActivity::Idle);
    let busy = Fake::new(TierUpActivity::Compiling);
    let held = Fake::new(TierUpActivity::Held);
    assert!(pool(2).install(|| Gate::new(Some(&idle)).is_none()));
    assert!(pool(1).install(|| Gate::new(Some(&busy)).is_none()));
    assert!(pool(2).install(|| Gate::new(None).is_none()));
    assert!(pool(2).install(|| Gate::new(Some(&busy)).is_some()));
    // Held now, compiling later in the pass: the gate is needed.
    assert!(pool(2).install(|| Gate::new(Some(&held)).is_some()));
}

#[test]
fn a_gate_with_no_jobs_returns_at_once() {
    let busy = Fake::new(TierUpActivity::Compiling);
    let (results, stats) = pool(2).install(|| Gate::new(Some(&busy)).expect("gate").run(0, |i| i));
    assert!(results.is_empty());
    assert_eq!(stats, GateStats::default());
}
