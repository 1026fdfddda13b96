//! Compile-time probe: how long one kernel variant takes to build and compile, in
//! wall time and in this thread's CPU time (from /proc/thread-self/schedstat, so other load on
//! the machine does not count), plus the library's parse + check time.
//!
//! Run: `cargo run --release --example compile_probe -- [rounds] [options]`.
//! Compiles the bench's `fill perspective_linear K=4` screen_triangle variant (or
//! `kind=linear|none`, `k=N`) `rounds` times (default 20) on fresh JITs, for each
//! configuration (tier 0, tier 1, unrolling off), prints the minimum of each (and of its
//! Cranelift part, `CompileCost::codegen_cpu_micros`, and that part per CLIF instruction),
//! the median wall time, and the bench's time to first pixel. Tier 0 compiles a kernel and
//! its pixel loops on two threads (`jit::lower::outline`), so its wall time, not this
//! thread's CPU time, is what a first frame waits for. Options: `timings [fast]` adds Cranelift's pass timings
//! summed over `rounds` compiles (tier 1, or tier 0 with `fast`); `clif=FILE [fast]` writes
//! the CLIF; `disasm=FILE [fast]` writes the machine code after register allocation and
//! prints its instruction and spill/reload counts; `shape=sphere_implicit|sphere_lit|polygon|nurb` compiles the first instance of
//! that bench workload instead (`scene=FILE`: of a scene file); `profile` only compiles tier 0 `rounds` times (for `perf record`); `speed`
//! times tier 1, tier 1 without unrolling, tier 0 and the hand-written kernels on the
//! bench's fill and small scenes instead; `cold` compares a tier-0 compile right after
//! another one (warm caches) with one after evicting the caches and with one in a fresh
//! tiered JIT, as the bench measures it. Every run first prints the process's first tier-0
//! compile (cold code, unrolling included). Everything runs on a thread of the render pool
//! (`runtime::render_pool`, a thread per CPU), where `primflow render` compiles its kernels:
//! a compile's helper tasks then share the CPUs with it as there (from outside a pool,
//! the calling thread and every thread of rayon's global pool would take tasks, one
//! thread more than the CPUs).

use std::sync::Arc;
use std::time::Instant;

use primflow::diag::{Diagnostics, SourceMap};
use primflow::jit::{Jit, JitOptions, Tier};
use primflow::runtime::Registry;

/// The `primflow` binary's allocator (src/main.rs), so compiles cost here what they cost there.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// This thread's CPU time in nanoseconds (the JIT's own clock, microsecond resolution).
fn thread_cpu_ns() -> u64 {
    primflow::jit::thread_cpu_micros() * 1000
}

fn main() {
    // As the binary does (src/main.rs): the first compile's figures depend on it.
    primflow::cli::disable_transparent_huge_pages();
    let pool = primflow::runtime::render_pool(0).expect("render pool");
    pool.install(probe);
}

fn probe() {
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

    // `kind=linear|none|perspective_linear` (default), `k=N` (default 4): the variant.
    let kind = args
        .iter()
        .find_map(|a| a.strip_prefix("kind="))
        .unwrap_or("perspective_linear");
    let k: usize = args
        .iter()
        .find_map(|a| a.strip_prefix("k=")?.parse().ok())
        .unwrap_or(4);
    let kind: Option<&'static str> = match kind {
        "none" => None,
        "linear" => Some("linear"),
        _ => Some("perspective_linear"),
    };
    let mut scene = primflow::workload::fill_scene(&program, 64, 1, kind, if kind.is_none() { 0 } else { k });
    // `scene=FILE`: the first instance of a scene file instead.
    if let Some(path) = args.iter().find_map(|a| a.strip_prefix("scene=")) {
        let mut sources = SourceMap::new();
        let file = sources.add(path, std::fs::read_to_string(path).expect("scene file"));
        scene = primflow::runtime::Renderer::new(program.clone());
        let mut diags = Diagnostics::new();
        primflow::scene::load_into(&sources, file, &mut scene, &mut diags);
    }
    // `shape=NAME`: the first instance of the bench workload whose name contains NAME
    // (`sphere implicit`, `sphere lit`, `polygon`, `nurb`).
    if let Some(name) = args.iter().find_map(|a| a.strip_prefix("shape=")) {
        let name = name.replace('_', " ");
        scene = primflow::workload::shape_scenes(&program, 64, 4, 1)
            .into_iter()
            .find(|(n, _, _)| n.contains(name.as_str()))
            .map(|(_, r, _)| r)
            .expect("a bench workload of that name");
    }
    let inst = &scene.instances()[0];
    println!(
        "variant: `{}` {}",
        program.func(inst.func).name,
        primflow::runtime::describe_key(&inst.key)
    );
    {
        // The process's first compile: Cranelift's code, the thread's spare contexts and
        // the allocator's arenas are all cold (see `cold`).
        let mut jit = Jit::with_options(
            program.clone(),
            JitOptions {
                tier: Tier::Fast,
                ..JitOptions::default()
            },
        )
        .expect("host ISA");
        let faults = minor_faults();
        let (w, c) = (Instant::now(), thread_cpu_ns());
        jit.kernel(inst.func, &inst.key).expect("compiles");
        println!(
            "first tier-0 compile in this process: {:.2} ms wall, {:.2} ms thread CPU, {} minor page faults",
            w.elapsed().as_secs_f64() * 1e3,
            (thread_cpu_ns() - c) as f64 / 1e6,
            minor_faults() - faults
        );
    }
    if args.iter().any(|a| a == "speed") {
        speed(&program, rounds);
        return;
    }
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
    if args.iter().any(|a| a == "cold") {
        cold_compiles(&program, inst.func, &inst.key, rounds);
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
            },
        ),
        (
            "tier 0, loops not unrolled",
            JitOptions {
                tier: Tier::Fast,
                unroll_loops: false,
            },
        ),
    ];
    for (name, opts) in configs {
        let (mut reported, mut codegen, mut insts) = (u64::MAX, u64::MAX, 0);
        let (mut walls, mut cpus) = (vec![], vec![]);
        for _ in 0..rounds {
            let mut jit = Jit::with_options(program.clone(), opts.clone()).expect("host ISA");
            let (w, c) = (Instant::now(), thread_cpu_ns());
            let k = jit.kernel(inst.func, &inst.key).expect("compiles");
            walls.push(w.elapsed().as_secs_f64() * 1e3);
            cpus.push((thread_cpu_ns() - c) as f64 / 1e6);
            reported = reported.min(k.compile_micros);
            if let Some(cost) = jit.compile_cost(inst.func, &inst.key) {
                codegen = codegen.min(cost.codegen_cpu_micros);
                insts = cost.clif_insts;
            }
        }
        cpus.sort_by(|a, b| a.total_cmp(b));
        walls.sort_by(|a, b| a.total_cmp(b));
        let (wall, cpu) = (walls[0], cpus[0]);
        let clif = Jit::with_options(program.clone(), opts.clone())
            .expect("host ISA")
            .clif(inst.func, &inst.key)
            .map(|t| t.lines().count())
            .unwrap_or(0);
        println!(
            "{name:<28} {clif:5} CLIF lines {wall:6.2} ms wall, {cpu:6.2} ms thread CPU, compile_micros {reported}, Cranelift {:.2} ms (min of {rounds}; wall median {:.2}, thread CPU median {:.2}, max {:.2})",
            codegen as f64 / 1e3,
            walls[walls.len() / 2],
            cpus[cpus.len() / 2],
            cpus[cpus.len() - 1]
        );
        // Cranelift's cost per instruction is what bounds a compile from below: the CLIF
        // a kernel needs, times this, over the threads compiling its functions.
        println!(
            "{:<28} {insts} CLIF instructions, Cranelift {:.2} us per instruction (min, all threads)",
            "",
            codegen as f64 / insts.max(1) as f64
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
    // `clif=`, `disasm=` and `timings` use this tier (`fast`: tier 0).
    let tier = if args.iter().any(|a| a == "fast") {
        Tier::Fast
    } else {
        Tier::Optimised
    };
    let print_jit = || {
        Jit::with_options(
            program.clone(),
            JitOptions {
                tier,
                ..JitOptions::default()
            },
        )
        .expect("host ISA")
    };
    if let Some(path) = args.iter().find_map(|a| a.strip_prefix("clif=")) {
        std::fs::write(path, print_jit().clif(inst.func, &inst.key).expect("lowers")).expect("writes the CLIF");
    }
    if let Some(path) = args.iter().find_map(|a| a.strip_prefix("disasm=")) {
        let d = print_jit().disassembly(inst.func, &inst.key).expect("compiles");
        println!(
            "machine code ({tier:?}): {} instructions, {} of them spills or reloads",
            d.inst_lines, d.spill_lines
        );
        std::fs::write(path, d.text).expect("writes the disassembly");
    }
    if timings {
        let _ = cranelift_codegen::timing::take_current();
        for _ in 0..rounds {
            print_jit().kernel(inst.func, &inst.key).expect("compiles");
        }
        println!("Cranelift pass timings, total of {rounds} compiles ({tier:?}):");
        println!("{}", cranelift_codegen::timing::take_current());
    }
}

/// Steady-state kernel speed, interleaved: tier 1, tier 1 without unrolling, tier 0, and the
/// hand-written scalar and AVX2 kernels on the bench's fill and small scenes (one thread,
/// median of `rounds` frames).
fn speed(program: &Arc<primflow::ir::Program>, rounds: usize) {
    use primflow::handwritten::{Flavor, Handwritten};
    use primflow::runtime::KernelSource;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("pool");
    let scenes = [
        (
            "fill perspective_linear K=4",
            primflow::workload::fill_scene(program, 512, 20, Some("perspective_linear"), 4),
        ),
        (
            "small perspective_linear K=4",
            primflow::workload::small_scene(program, 512, 20000, 4),
        ),
    ];
    for (name, r) in &scenes {
        let jit =
            |tier, unroll_loops| Jit::with_options(program.clone(), JitOptions { tier, unroll_loops }).expect("ISA");
        let mut sources: Vec<(&str, Box<dyn KernelSource + Send>)> = vec![
            ("tier 1", Box::new(jit(Tier::Optimised, true))),
            ("tier 1 no unroll", Box::new(jit(Tier::Optimised, false))),
            ("tier 0", Box::new(jit(Tier::Fast, true))),
            ("scalar", Box::new(Handwritten::new(program.clone(), Flavor::Scalar))),
            ("AVX2", Box::new(Handwritten::new(program.clone(), Flavor::Avx2))),
        ];
        let mut times = vec![vec![]; sources.len()];
        let reference = pool.install(|| r.render(sources[0].1.as_mut())).frame;
        for (i, (n, s)) in sources.iter_mut().enumerate() {
            let f = pool.install(|| r.render(s.as_mut())).frame;
            assert!(primflow::workload::same_frame(&reference, &f), "{name}: {n} differs");
            let _ = i;
        }
        for _ in 0..rounds {
            for (i, (_, s)) in sources.iter_mut().enumerate() {
                let t = Instant::now();
                pool.install(|| r.render(s.as_mut()));
                times[i].push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        let med = |v: &mut Vec<f64>| {
            v.sort_by(|a, b| a.total_cmp(b));
            v[v.len() / 2]
        };
        let meds: Vec<f64> = times.iter_mut().map(med).collect();
        println!("{name}:");
        for (i, (n, _)) in sources.iter().enumerate() {
            println!(
                "  {n:<18} {:8.2} ms  /scalar {:.2}x  /AVX2 {:.2}x",
                meds[i],
                meds[3] / meds[i],
                meds[4] / meds[i]
            );
        }
    }
}

/// This process's minor page faults so far (Linux `getrusage`; 0 elsewhere).
fn minor_faults() -> i64 {
    std::fs::read_to_string("/proc/thread-self/stat")
        .ok()
        .and_then(|s| {
            // Fields after the command name (in parentheses): state is field 3, minflt 10.
            let rest = s.rsplit_once(')')?.1;
            rest.split_whitespace().nth(7)?.parse().ok()
        })
        .unwrap_or(0)
}

/// What the bench's compile column sees: one tier-0 compile after other work has evicted
/// the compiler from the caches. Per round, interleaved: a compile right after another one
/// (warm), a compile after touching 64 MB (caches evicted, as after rendering a frame), and
/// a compile in a fresh *tiered* JIT (whose tier-1 thread starts meanwhile), also after
/// the eviction. Thread CPU time, min / median of `rounds`.
fn cold_compiles(
    program: &Arc<primflow::ir::Program>,
    func: primflow::ir::FuncId,
    key: &primflow::abi::VariantKey,
    rounds: usize,
) {
    let mut evict = vec![0u8; 64 << 20];
    let mut touch = |salt: u8| {
        for i in (0..evict.len()).step_by(64) {
            evict[i] = evict[i].wrapping_add(salt);
        }
        std::hint::black_box(&evict);
    };
    let fast = JitOptions {
        tier: Tier::Fast,
        ..JitOptions::default()
    };
    let mut times: [Vec<f64>; 3] = Default::default();
    for r in 0..rounds {
        for (i, t) in times.iter_mut().enumerate() {
            if i > 0 {
                touch(r as u8);
            }
            let mut jit = if i == 2 {
                Jit::tiered(program.clone())
            } else {
                Jit::with_options(program.clone(), fast.clone())
            }
            .expect("host ISA");
            let c = thread_cpu_ns();
            jit.kernel(func, key).expect("compiles");
            t.push((thread_cpu_ns() - c) as f64 / 1e6);
            jit.wait_for_tier_up();
        }
    }
    for (name, t) in [
        "warm (after a compile)",
        "cold (after evicting caches)",
        "cold, tiered JIT (as the bench)",
    ]
    .iter()
    .zip(times.iter_mut())
    {
        t.sort_by(|a, b| a.total_cmp(b));
        println!(
            "tier 0 {name:<34} thread CPU min {:.2} ms, median {:.2} ms, max {:.2} ms ({rounds} rounds)",
            t[0],
            t[t.len() / 2],
            t[t.len() - 1]
        );
    }
}
