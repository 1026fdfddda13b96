//! The campaign: inputs `start..start + inputs` run in worker processes, `jobs` at a time,
//! each worker taking a chunk of consecutive inputs.
//!
//! A worker (`primflow fuzz-worker`) prints `> i` before input `i` and `= i LEN OUTCOME`
//! after it, catching panics itself. When a worker dies (a stack overflow, an abort, any
//! signal) the input it had started is a `signal` finding; when it prints nothing for the
//! time limit, it is killed and the input is a `hang`. Either way a new worker goes on after
//! that input, so one bad input costs one finding, not the chunk. The counts do not depend
//! on `jobs` or on timing (short of hangs): every input runs exactly once.
//!
//! Findings are printed with the command that replays each; `findings` writes their texts.
//! `save_corpus` keeps, per (class, outcome), the shortest input that ended so: a corpus
//! minimised by what it reaches, which later campaigns mutate (`fuzz/corpus`).

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{mpsc, Mutex};
use std::time::{Duration, Instant};

use super::{input, run, Class, Corpus, Outcome};

/// Inputs per worker process.
const CHUNK: u64 = 250;

/// What to run.
pub struct Options {
    pub seed: u64,
    pub start: u64,
    pub inputs: u64,
    pub only: Option<Class>,
    pub jobs: usize,
    pub timeout: Duration,
    pub findings: Option<PathBuf>,
    pub save_corpus: Option<PathBuf>,
}

/// Outcome counts per class, and the findings.
#[derive(Default)]
pub struct Report {
    /// (class, outcome kind) -> inputs.
    pub counts: BTreeMap<(Class, &'static str), u64>,
    /// (input, class, outcome) of each finding, in input order.
    pub findings: Vec<(u64, Class, Outcome)>,
    /// (class, outcome key) -> (shortest length, input).
    keep: BTreeMap<(Class, String), (usize, u64)>,
}

impl Report {
    pub fn total(&self, kind: &str) -> u64 {
        self.counts
            .iter()
            .filter(|((_, k), _)| *k == kind)
            .map(|(_, n)| n)
            .sum()
    }

    fn record(&mut self, i: u64, class: Class, len: usize, outcome: Outcome) {
        *self.counts.entry((class, kind(&outcome))).or_default() += 1;
        let key = match &outcome {
            Outcome::Rejected(code) => format!("rejected-{code}"),
            o => kind(o).to_string(),
        };
        let best = self.keep.entry((class, key)).or_insert((len, i));
        if len < best.0 {
            *best = (len, i);
        }
        if outcome.is_finding() {
            self.findings.push((i, class, outcome));
        }
    }
}

/// The outcome's column in the report.
pub fn kind(o: &Outcome) -> &'static str {
    match o {
        Outcome::Accepted => "accepted",
        Outcome::Rejected(_) => "rejected",
        Outcome::Ice(_) => "ice",
        Outcome::Mismatch(_) => "mismatch",
        Outcome::Panic(_) => "panic",
        Outcome::Signal(_) => "signal",
        Outcome::Hang => "hang",
    }
}

/// The columns of the report, in order.
pub const KINDS: [&str; 7] = ["accepted", "rejected", "ice", "mismatch", "panic", "signal", "hang"];

/// Run the campaign; `progress` gets a line now and then.
pub fn campaign(opts: &Options, corpus: &Corpus, progress: &mut dyn Write) -> Result<Report, String> {
    let exe = std::env::current_exe().map_err(|e| format!("cannot find this program: {e}"))?;
    let report = Mutex::new(Report::default());
    let next_chunk = AtomicU64::new(0);
    let done = AtomicU64::new(0);
    let failed: Mutex<Option<String>> = Mutex::new(None);
    let chunks = opts.inputs.div_ceil(CHUNK);
    let started = Instant::now();
    std::thread::scope(|s| {
        for _ in 0..opts.jobs.max(1) {
            s.spawn(|| loop {
                let c = next_chunk.fetch_add(1, Ordering::Relaxed);
                if c >= chunks || failed.lock().is_ok_and(|f| f.is_some()) {
                    return;
                }
                let from = opts.start + c * CHUNK;
                let to = (from + CHUNK).min(opts.start + opts.inputs);
                if let Err(e) = run_chunk(&exe, opts, from, to, &report) {
                    if let Ok(mut f) = failed.lock() {
                        *f = Some(e);
                    }
                    return;
                }
                done.fetch_add(to - from, Ordering::Relaxed);
            });
        }
        // Progress from the scope's own thread.
        let mut last = 0;
        while done.load(Ordering::Relaxed) < opts.inputs && failed.lock().is_ok_and(|f| f.is_none()) {
            std::thread::sleep(Duration::from_millis(200));
            let d = done.load(Ordering::Relaxed);
            if d >= last + opts.inputs.div_ceil(10).max(1) {
                last = d;
                let _ = writeln!(
                    progress,
                    "{d} of {} inputs, {:.0} s",
                    opts.inputs,
                    started.elapsed().as_secs_f64()
                );
            }
        }
    });
    if let Some(e) = failed.into_inner().map_err(|_| "a worker thread failed")? {
        return Err(e);
    }
    let mut report = report.into_inner().map_err(|_| "a worker thread failed")?;
    report.findings.sort_by_key(|f| f.0);
    if let Some(dir) = &opts.findings {
        write_inputs(dir, corpus, opts, report.findings.iter().map(|f| f.0))?;
    }
    if let Some(dir) = &opts.save_corpus {
        write_inputs(dir, corpus, opts, report.keep.values().map(|v| v.1))?;
    }
    Ok(report)
}

/// Run inputs `from..to` in workers, restarting after an input that kills one.
fn run_chunk(exe: &std::path::Path, opts: &Options, from: u64, to: u64, report: &Mutex<Report>) -> Result<(), String> {
    let mut next = from;
    while next < to {
        let was = next;
        let mut cmd = Command::new(exe);
        cmd.args(["fuzz-worker", "--seed", &opts.seed.to_string()]).args([
            "--from",
            &next.to_string(),
            "--to",
            &to.to_string(),
        ]);
        if let Some(c) = opts.only {
            cmd.args(["--class", c.name()]);
        }
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("cannot start a fuzz worker: {e}"))?;
        let stdout = child.stdout.take().ok_or("worker without stdout")?;
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                let Ok(line) = line else { break };
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut current: Option<u64> = None;
        let end = loop {
            match rx.recv_timeout(opts.timeout) {
                Ok(line) => {
                    if let Some(i) = line.strip_prefix("> ").and_then(|n| n.parse().ok()) {
                        current = Some(i);
                    } else if let Some((i, len, outcome)) = parse_done(&line) {
                        record(report, opts, i, len, outcome);
                        current = None;
                        next = i + 1;
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    let _ = child.kill();
                    break Outcome::Hang;
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    let status = child.wait().map_err(|e| e.to_string())?;
                    break Outcome::Signal(format!("{status}"));
                }
            }
        };
        let _ = child.wait();
        match current {
            Some(i) => {
                record(report, opts, i, 0, end);
                next = i + 1;
            }
            // Stopped between inputs without finishing one: it cannot start at all.
            None if next == was && next < to => {
                return Err(format!("the fuzz worker stopped before its first input ({end:?})"));
            }
            None => {}
        }
    }
    Ok(())
}

fn record(report: &Mutex<Report>, opts: &Options, i: u64, len: usize, outcome: Outcome) {
    let class = opts.only.unwrap_or(Class::of(i));
    if let Ok(mut r) = report.lock() {
        r.record(i, class, len, outcome);
    }
}

/// `= i LEN OUTCOME [DETAIL]`.
fn parse_done(line: &str) -> Option<(u64, usize, Outcome)> {
    let mut parts = line.strip_prefix("= ")?.splitn(4, ' ');
    let i = parts.next()?.parse().ok()?;
    let len = parts.next()?.parse().ok()?;
    let tag = parts.next()?;
    let detail = parts.next().unwrap_or("").to_string();
    let outcome = match tag {
        "accepted" => Outcome::Accepted,
        "rejected" => Outcome::Rejected(detail),
        "ice" => Outcome::Ice(detail),
        "mismatch" => Outcome::Mismatch(detail),
        _ => Outcome::Panic(detail),
    };
    Some((i, len, outcome))
}

/// The worker: inputs `from..to`, one `>` and one `=` line each on `out`.
pub fn worker(seed: u64, from: u64, to: u64, only: Option<Class>, out: &mut dyn Write) -> i32 {
    let corpus = match Corpus::load() {
        Ok(c) => c,
        Err(e) => {
            let _ = writeln!(out, "! {e}");
            return 1;
        }
    };
    // Panics are outcomes here; their messages go in the `=` line, not to stderr.
    std::panic::set_hook(Box::new(|_| {}));
    let inject = std::env::var("PRIMFLOW_FUZZ_INJECT").unwrap_or_default();
    for i in from..to {
        let _ = writeln!(out, "> {i}");
        let _ = out.flush();
        let input = input(&corpus, seed, i, only);
        let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            injected(&inject, i);
            run(&corpus, &input)
        }))
        .unwrap_or_else(|p| {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Outcome::Panic(msg)
        });
        let detail = match &outcome {
            Outcome::Rejected(code) => code.to_string(),
            Outcome::Ice(m) | Outcome::Mismatch(m) | Outcome::Panic(m) | Outcome::Signal(m) => m.replace('\n', " | "),
            Outcome::Accepted | Outcome::Hang => String::new(),
        };
        let _ = writeln!(out, "= {i} {} {} {detail}", input.text.len(), kind(&outcome));
        let _ = out.flush();
    }
    0
}

/// The campaign's own test: `PRIMFLOW_FUZZ_INJECT` lists failures to inject at given inputs
/// (`panic:3,abort:5,hang:7`), so a test can check that each is seen and counted.
fn injected(spec: &str, i: u64) {
    for item in spec.split(',') {
        let Some((what, at)) = item.split_once(':') else {
            continue;
        };
        if at.parse() != Ok(i) {
            continue;
        }
        match what {
            "panic" => panic!("injected panic"),
            "abort" => std::process::abort(),
            "hang" => loop {
                std::thread::sleep(Duration::from_secs(1));
            },
            _ => {}
        }
    }
}

/// Write the inputs `ids` of the campaign into `dir`, one file each.
fn write_inputs(
    dir: &std::path::Path,
    corpus: &Corpus,
    opts: &Options,
    ids: impl Iterator<Item = u64>,
) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    for i in ids {
        let inp = input(corpus, opts.seed, i, opts.only);
        let ext = if inp.name.ends_with(".scene") { "scene" } else { "prim" };
        let path = dir.join(format!("{}-{}-{i}.{ext}", inp.class.name(), opts.seed));
        std::fs::write(&path, &inp.text).map_err(|e| format!("{}: {e}", path.display()))?;
    }
    Ok(())
}
