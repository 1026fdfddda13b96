//! llvmpipe measured live beside the JIT (`primflow bench`): the worker draws the
//! workloads' own geometry — the same pixels pass its depth test as the JIT writes — and
//! the report sets its figures beside the JIT's. Where the host has no Mesa EGL the bench
//! must say so and carry on; this machine image has it, and there every assertion about
//! llvmpipe's output runs. Outcomes only: nothing here asserts a timing.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Command, Stdio};

use primflow::bench::{paired_ratio, run, BenchOptions, KernelKind};

const EXE: &str = env!("CARGO_BIN_EXE_primflow");

/// Whether this host has an EGL library at all (then llvmpipe must work).
fn has_egl() -> bool {
    [
        "/usr/lib/x86_64-linux-gnu/libEGL.so.1",
        "/usr/lib64/libEGL.so.1",
        "/usr/lib/libEGL.so.1",
    ]
    .iter()
    .any(|p| Path::new(p).exists())
}

/// A worker, spoken to line by line.
struct Worker {
    child: std::process::Child,
    output: BufReader<std::process::ChildStdout>,
}

impl Worker {
    /// A worker with `threads` rasterizer threads.
    fn start(threads: usize) -> (Worker, String) {
        let mut child = Command::new(EXE)
            .arg("llvmpipe-worker")
            .env("LP_NUM_THREADS", threads.to_string())
            .env("LIBGL_ALWAYS_SOFTWARE", "1")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let output = BufReader::new(child.stdout.take().unwrap());
        let mut w = Worker { child, output };
        let ready = w.line();
        (w, ready)
    }

    fn line(&mut self) -> String {
        let mut line = String::new();
        self.output.read_line(&mut line).unwrap();
        line.trim_end().to_string()
    }

    fn ask(&mut self, command: &str) -> String {
        let input = self.child.stdin.as_mut().unwrap();
        writeln!(input, "{command}").unwrap();
        input.flush().unwrap();
        self.line()
    }
}

/// The samples of an `ok <ms> <samples>` answer.
fn samples(answer: &str) -> u64 {
    let fields: Vec<&str> = answer.split('\t').collect();
    assert_eq!(fields.len(), 3, "{answer}");
    assert_eq!(fields[0], "ok", "{answer}");
    assert!(fields[1].parse::<f64>().unwrap() > 0.0, "{answer}");
    fields[2].parse().unwrap()
}

#[test]
fn the_worker_draws_the_workloads_own_pixels() {
    let (mut w, ready) = Worker::start(1);
    if !has_egl() {
        assert!(ready.starts_with("error\t"), "{ready}");
        return;
    }
    assert!(ready.starts_with("ready\tllvmpipe"), "{ready}");
    // One rasterizer thread: pinned to a CPU (the last field names it).
    assert!(ready.rsplit('\t').next().unwrap().parse::<usize>().is_ok(), "{ready}");
    // `frame` before any `setup`, and a workload without a twin, are errors, not crashes.
    assert!(w.ask("frame").starts_with("error\t"));
    let unknown = w.ask("setup\t1\tpolygon hither K=4");
    assert!(unknown.starts_with("error\tno llvmpipe scene"), "{unknown}");
    // The quick fill workloads: 20 full-viewport layers drawn back to front, 512 x 512:
    // every layer's every pixel passes, whatever the parameters and their interpolation.
    for name in [
        "fill perspective_linear K=4",
        "fill linear K=4",
        "fill none K=0",
        "fill perspective_linear K=1",
        "fill perspective_linear K=16",
    ] {
        let first = w.ask(&format!("setup\t1\t{name}"));
        assert_eq!(samples(&first), 20 * 512 * 512, "{name}");
        assert_eq!(samples(&w.ask("frame")), 20 * 512 * 512, "{name}");
    }
    // Multisampled (the bench's multisampling series): the query counts samples, 4 a pixel.
    let msaa = w.ask("setup\t1\tfill perspective_linear K=4\t4");
    assert_eq!(samples(&msaa), 4 * 20 * 512 * 512, "{msaa}");
    assert!(w
        .ask("setup\t1\tfill none K=0\tmany")
        .starts_with("error\tbad sample count"));
    // 20 000 triangles of 20 px: about 400 000 pixels.
    let small = samples(&w.ask("setup\t1\tsmall perspective_linear K=4"));
    assert!((390_000..410_000).contains(&small), "{small}");
    let lit = samples(&w.ask("setup\t1\tsphere lit (diffuse + specular)"));
    let unlit = samples(&w.ask("setup\t1\tsphere implicit N"));
    assert_eq!(lit, unlit, "lighting changes no coverage");
    assert!(lit > 100_000, "{lit}");
    drop(w.child.stdin.take());
    assert!(w.child.wait().unwrap().success());
}

#[test]
fn a_worker_with_a_rasterizer_thread_per_cpu_is_unpinned_and_draws_the_same_pixels() {
    let (mut w, ready) = Worker::start(2);
    if !has_egl() {
        assert!(ready.starts_with("error\t"), "{ready}");
        return;
    }
    assert!(
        ready.starts_with("ready\tllvmpipe") && ready.ends_with("\t-"),
        "{ready}"
    );
    let first = w.ask("setup\t1\tfill perspective_linear K=4");
    assert_eq!(samples(&first), 20 * 512 * 512);
    assert_eq!(samples(&w.ask("frame")), 20 * 512 * 512);
    let (mut one, _) = Worker::start(1);
    let small = "setup\t1\tsmall perspective_linear K=4";
    assert_eq!(samples(&w.ask(small)), samples(&one.ask(small)));
}

#[test]
fn the_report_sets_measured_llvmpipe_beside_the_jit_on_the_same_pixels() {
    #[allow(clippy::needless_update)]
    let opts = BenchOptions {
        filter: Some("sphere".into()),
        quick: true,
        runs: 3,
        progress: false,
        llvmpipe: Some(EXE.into()),
        ..BenchOptions::default()
    };
    let report = run(&opts).unwrap();
    assert_eq!(report.llvmpipe.len(), 2, "{:?}", report.llvmpipe);
    if !has_egl() {
        assert!(
            report.llvmpipe_status.starts_with("not measured"),
            "{}",
            report.llvmpipe_status
        );
        assert!(report.llvmpipe.iter().all(|c| c.measured.is_none()));
        return;
    }
    assert!(
        report.llvmpipe_status.starts_with("llvmpipe"),
        "{}",
        report.llvmpipe_status
    );
    for c in &report.llvmpipe {
        let w = report.workloads.iter().find(|w| w.workload == c.workload).unwrap();
        let run = w
            .llvmpipe
            .as_ref()
            .unwrap_or_else(|| panic!("{}: {:?}", w.workload, w.llvmpipe_error));
        // The same spheres from the same camera: the pixels agree to a few edge pixels.
        let (ours, theirs) = (w.pixels_written as f64, run.pixels_written as f64);
        assert!(
            (ours - theirs).abs() <= ours * 1e-3,
            "{}: {ours} vs {theirs}",
            w.workload
        );
        let row = w.timing(KernelKind::Llvmpipe, 1).unwrap();
        assert!(row.setup_ms.is_nan() && row.tiles_ms.is_nan(), "{row:?}");
        assert_eq!(c.measured, Some(row.mpixels_per_s));
        let jit = w.timing(KernelKind::Jit, 1).unwrap();
        assert_eq!(row.runs_ms.len(), jit.runs_ms.len());
        assert_eq!(c.measured_ratio, Some(paired_ratio(row, jit)));
        assert_eq!(c.measured_pixels, Some(run.pixels_written));
        // On every CPU: llvmpipe's row by its own pixel count, beside the JIT's on its pool.
        let n = report.machine.threads;
        if n > 1 {
            let all = w.timing(KernelKind::Llvmpipe, n).unwrap();
            let jit_all = w.timing(KernelKind::Jit, n).unwrap();
            assert_eq!(all.kernel, "llvmpipe, all CPUs");
            let expected = run.pixels_written as f64 / all.median_ms / 1e3;
            assert!((all.mpixels_per_s - expected).abs() <= expected * 1e-3, "{all:?}");
            assert_eq!(run.jit_vs_llvmpipe_all_threads, Some(paired_ratio(all, jit_all)));
            assert_eq!(run.thread_scaling, Some(paired_ratio(row, all)));
            assert_eq!(c.measured_all_threads, Some(all.mpixels_per_s));
            assert_eq!(c.measured_all_threads_ratio, run.jit_vs_llvmpipe_all_threads);
        } else {
            assert_eq!(run.jit_vs_llvmpipe_all_threads, None);
        }
    }
    let text = primflow::bench::format_table(&report);
    assert!(text.contains("llvmpipe here"), "{text}");
    assert!(text.contains("JIT/llvmpipe"), "{text}");
    if report.machine.threads > 1 {
        assert!(text.contains("against Mesa llvmpipe on"), "{text}");
    }
}

#[test]
fn without_a_worker_the_report_keeps_the_issues_figures() {
    #[allow(clippy::needless_update)]
    let opts = BenchOptions {
        filter: Some("sphere implicit".into()),
        quick: true,
        runs: 1,
        progress: false,
        llvmpipe: Some("/nonexistent/primflow".into()),
        ..BenchOptions::default()
    };
    let report = run(&opts).unwrap();
    assert!(
        report.llvmpipe_status.starts_with("not measured: cannot start"),
        "{}",
        report.llvmpipe_status
    );
    assert_eq!(report.llvmpipe.len(), 1);
    assert_eq!(report.llvmpipe[0].llvmpipe, 88.0);
    assert!(report.llvmpipe[0].measured.is_none());
    assert!(report.workloads[0].timing(KernelKind::Llvmpipe, 1).is_none());
}

/// The quick `fill none` workload, two rounds, timed beside a stand-in llvmpipe worker:
/// the shell `script` (its own file, named by `tag`), run for both workers.
fn bench_with_stand_in(tag: &str, script: &str) -> primflow::bench::BenchReport {
    let dir = std::env::temp_dir().join(format!("primflow-llvmpipe-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let fake = dir.join("fake-worker");
    std::fs::write(&fake, script).unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    #[allow(clippy::needless_update)]
    let opts = BenchOptions {
        filter: Some("fill none".into()),
        quick: true,
        runs: 2,
        progress: false,
        llvmpipe: Some(fake),
        ..BenchOptions::default()
    };
    run(&opts).unwrap()
}

#[test]
fn a_worker_that_dies_mid_way_loses_its_row_not_the_bench() {
    // A stand-in worker: starts, answers the setup, then ends.
    let report = bench_with_stand_in(
        "dies",
        "#!/bin/sh\nprintf 'ready\\tllvmpipe (stand-in)\\t0\\n'\nread line\nprintf 'ok\\t1.0\\t5242880\\n'\nread line\n",
    );
    assert!(
        report.llvmpipe_status.starts_with("llvmpipe (stand-in)"),
        "{}",
        report.llvmpipe_status
    );
    let w = &report.workloads[0];
    assert!(w.llvmpipe.is_none());
    let error = w.llvmpipe_error.as_deref().unwrap_or_default();
    assert!(error.contains("ended"), "{error}");
    assert!(w.timing(KernelKind::Llvmpipe, 1).is_none());
    assert!(w.timings.iter().all(|t| t.kind != KernelKind::Llvmpipe));
    assert!(w.timing(KernelKind::Jit, 1).is_some());
    assert_eq!(report.llvmpipe[0].measured, None);
}

#[test]
fn an_all_threads_worker_that_dies_loses_only_its_own_row() {
    // A stand-in: with one rasterizer thread it answers every frame (the quick `fill none`
    // workload's pixel count); with more it answers the setup and then ends.
    let report = bench_with_stand_in(
        "all",
        "#!/bin/sh\nprintf 'ready\\tllvmpipe (stand-in)\\t0\\n'\n\
         if [ \"$LP_NUM_THREADS\" != 1 ]; then read line; printf 'ok\\t1.0\\t5242880\\n'; read line; exit 0; fi\n\
         while read line; do printf 'ok\\t1.0\\t5242880\\n'; done\n",
    );
    let n = report.machine.threads;
    if n == 1 {
        return; // no all-threads worker to lose
    }
    let w = &report.workloads[0];
    let run = w.llvmpipe.as_ref().expect("the one-thread worker kept its row");
    assert_eq!(run.jit_vs_llvmpipe_all_threads, None);
    assert_eq!(run.thread_scaling, None);
    let error = w.llvmpipe_error.as_deref().unwrap_or_default();
    assert!(
        error.contains("rasterizer thread per CPU") && error.contains("ended"),
        "{error}"
    );
    assert!(w.timing(KernelKind::Llvmpipe, 1).is_some());
    assert!(w.timing(KernelKind::Llvmpipe, n).is_none());
    assert_eq!(report.llvmpipe[0].measured_all_threads, None);
    assert!(report.llvmpipe[0].measured.is_some());
}
