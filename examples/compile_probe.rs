//! Compile-time probe (issue 5): how long one kernel variant takes to build and compile, in
//! wall time and in this thread's CPU time (from /proc/thread-self/schedstat, so other load on
//! the machine does not count), plus the library's parse + check time.
//!
//! Run: `cargo run --release --example compile_probe -- [rounds] [timings]`.
//! Compiles the bench's `fill perspective_linear K=4` screen_triangle variant `rounds` times
//! (default 20) on fresh JITs, for each configuration (tier 0, tier 1, unrolling off), and
//! prints the minimum of each. With `timings` it prints Cranelift's pass timings of the last
//! compile as well.

use std::sync::Arc;
use std::time::Instant;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::{Jit, JitOptions, Tier};
use primflow::runtime::Registry;

#[repr(C)]
struct Timespec {
    tv_sec: i64,
    tv_nsec: i64,
}

extern "C" {
    fn clock_gettime(clock: i32, tp: *mut Timespec) -> i32;
}

/// This thread's CPU time in nanoseconds (Linux `CLOCK_THREAD_CPUTIME_ID`).
fn thread_cpu_ns() -> u64 {
    const CLOCK_THREAD_CPUTIME_ID: i32 = 3;
    let mut t = Timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `t` is a valid, writable timespec for the duration of the call.
    unsafe { clock_gettime(CLOCK_THREAD_CPUTIME_ID, &mut t) };
    t.tv_sec as u64 * 1_000_000_000 + t.tv_nsec as u64
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rounds: usize = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(20);
    let timings = args.iter().any(|a| a == "timings");

    let mut best_parse = (f64::MAX, f64::MAX);
    let mut program = None;
    for _ in 0..rounds.min(5) {
        let (w, c) = (Instant::now(), thread_cpu_ns());
        let mut sources = SourceMap::new();
        let mut diags = Diagnostics::new();
        let p = Registry::load(&mut sources, &[], &[], &mut diags)
            .map(|r| r.program)
            .expect("the library checks");
        best_parse.0 = best_parse.0.min(w.elapsed().as_secs_f64() * 1e3);
        best_parse.1 = best_parse.1.min((thread_cpu_ns() - c) as f64 / 1e6);
        program = Some(p);
    }
    let program: Arc<_> = program.expect("parsed");
    println!(
        "parse + check library: {:.2} ms wall, {:.2} ms thread CPU (min of {})",
        best_parse.0,
        best_parse.1,
        rounds.min(5)
    );

    let scene = primflow::bench::fill_scene(&program, 64, 1, Some("perspective_linear"), 4);
    let inst = &scene.instances()[0];
    if args.iter().any(|a| a == "profile") {
        // Only tier-0 compiles, for `perf record`.
        for _ in 0..rounds {
            let opts = JitOptions {
                tier: Tier::Fast,
                ..JitOptions::default()
            };
            let mut jit = Jit::with_options(program.clone(), opts).expect("host ISA");
            jit.kernel(inst.func, &inst.key).expect("compiles");
        }
        return;
    }
    let configs = [
        (
            "tier 0 (fast)",
            JitOptions {
                tier: Tier::Fast,
                ..JitOptions::default()
            },
        ),
        (
            "tier 1 (optimised)",
            JitOptions {
                tier: Tier::Optimised,
                ..JitOptions::default()
            },
        ),
        (
            "tier 1, loops not unrolled",
            JitOptions {
                tier: Tier::Optimised,
                unroll_loops: false,
                ..JitOptions::default()
            },
        ),
        (
            "tier 0, loops not unrolled",
            JitOptions {
                tier: Tier::Fast,
                unroll_loops: false,
                ..JitOptions::default()
            },
        ),
    ];
    for (name, opts) in configs {
        let (mut wall, mut cpu, mut reported) = (f64::MAX, f64::MAX, u64::MAX);
        for _ in 0..rounds {
            let mut jit = Jit::with_options(program.clone(), opts.clone()).expect("host ISA");
            let (w, c) = (Instant::now(), thread_cpu_ns());
            let k = jit.kernel(inst.func, &inst.key).expect("compiles");
            wall = wall.min(w.elapsed().as_secs_f64() * 1e3);
            cpu = cpu.min((thread_cpu_ns() - c) as f64 / 1e6);
            reported = reported.min(k.compile_micros);
        }
        let clif = Jit::with_options(program.clone(), opts.clone())
            .expect("host ISA")
            .clif(inst.func, &inst.key)
            .map(|t| t.lines().count())
            .unwrap_or(0);
        println!(
            "{name:<28} {clif:5} CLIF lines {wall:6.2} ms wall, {cpu:6.2} ms thread CPU, compile_micros {reported} (min of {rounds})"
        );
    }
    let mut ttfp = vec![];
    for _ in 0..rounds.min(10) {
        ttfp.push(primflow::bench::time_to_first_pixel().expect("renders"));
    }
    ttfp.sort_by(|a, b| a.total_cmp(b));
    println!(
        "time to first pixel (bench): min {:.2} ms, median {:.2} ms of {}",
        ttfp[0],
        ttfp[ttfp.len() / 2],
        ttfp.len()
    );
    if let Some(path) = args.iter().find_map(|a| a.strip_prefix("clif=")) {
        let tier = if args.iter().any(|a| a == "fast") {
            Tier::Fast
        } else {
            Tier::Optimised
        };
        let jit = Jit::with_options(
            program.clone(),
            JitOptions {
                tier,
                ..JitOptions::default()
            },
        )
        .expect("host ISA");
        std::fs::write(path, jit.clif(inst.func, &inst.key).expect("lowers")).expect("writes the CLIF");
    }
    if timings {
        let tier = if args.iter().any(|a| a == "fast") {
            Tier::Fast
        } else {
            Tier::Optimised
        };
        let _ = cranelift_codegen::timing::take_current();
        for _ in 0..rounds {
            let mut jit = Jit::with_options(
                program.clone(),
                JitOptions {
                    tier,
                    ..JitOptions::default()
                },
            )
            .expect("host ISA");
            jit.kernel(inst.func, &inst.key).expect("compiles");
        }
        println!("Cranelift pass timings, total of {rounds} compiles ({tier:?}):");
        println!("{}", cranelift_codegen::timing::take_current());
    }
}
