//! The `primflow` command line: `check` (diagnostics and compiler dumps for `.prim` files),
//! `render` (a scene file to PNG images), `watch` and `serve` (render again on every save,
//! in the terminal or in a browser), `trace` (why one pixel of a scene looks as it
//! does, see [`trace`](crate::trace)), `test` (scene files with expectations, see
//! [`testing`](crate::testing)), `bench` (JIT kernels against hand-written ones) and
//! `accuracy` (error vs time per accuracy knob).
//!
//! Everything a command prints goes through the `out` / `err` writers handed to [`run`], so
//! the binary and the tests drive the same code. Exit codes: 0 success, 1 the input had
//! errors (diagnostics were printed) or an output could not be written, 2 bad usage (clap).
//! No input makes it panic: every failure is a message.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use clap::{Parser, Subcommand, ValueEnum};

use crate::abi::{Binding, BindingKind, VariantKey};
use crate::diag::{Diagnostics, FileId, SourceMap};
use crate::ir::{FuncKind, Program};
use crate::jit::Jit;
use crate::runtime::{describe_key, Registry, Renderer};

mod serve;
mod sources;
mod watch;

#[derive(Parser, Debug)]
#[command(
    name = "primflow",
    version,
    about = "Compiler and JIT renderer for procedural primitives (one pixel at a time, run over tiles)"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Parse and check primitive files together with the primitive library.
    Check(CheckArgs),
    /// Render a scene file to a PNG image.
    Render(RenderArgs),
    /// Render a scene, then again each time it or a .prim file it may read is saved (until
    /// interrupted); errors are printed and the watch goes on.
    Watch(RenderArgs),
    /// A live preview in the browser: the render, depth and shading parameters, rendered
    /// again on every save; diagnostics, times, the scene's sources to edit and a pixel's
    /// trace on a click. Listens on 127.0.0.1 unless `--bind` says otherwise.
    Serve(serve::ServeArgs),
    /// Show why a pixel looks as it does: every instance that reaches it, in draw order,
    /// with the statements that ran there, the values assigned, where it retired and what
    /// it wrote, checked against the rendered frame.
    Trace(TraceArgs),
    /// Run primitive test cases: scene files with `# expect:` lines (default: prims/tests).
    Test(TestArgs),
    /// Benchmark JIT kernels against hand-written Rust kernels of the same primitives and
    /// against Mesa llvmpipe (`--scene`: a scene of your own).
    Bench(BenchArgs),
    /// Sweep the accuracy knobs: error against the f64 reference vs time, as a table, CSV,
    /// JSON and one plot per knob.
    Accuracy(AccuracyArgs),
    /// Run a fuzzing campaign: generated and mutated programs and scenes through the checker,
    /// both JIT tiers and the renderer; prints counts per class and every finding.
    Fuzz(FuzzArgs),
    /// `bench`'s llvmpipe process (see `bench::llvmpipe`): not for direct use.
    #[command(name = "llvmpipe-worker", hide = true)]
    LlvmpipeWorker,
    /// `fuzz`'s worker process (see `fuzz::campaign`): not for direct use.
    #[command(name = "fuzz-worker", hide = true)]
    FuzzWorker(FuzzWorkerArgs),
}

#[derive(clap::Args, Debug)]
pub struct FuzzArgs {
    /// Number of inputs.
    #[arg(long, default_value_t = 10_000)]
    pub inputs: u64,
    /// Campaign seed: input i of a seed is always the same text.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// First input number (to replay one finding: `--start I --inputs 1`).
    #[arg(long, default_value_t = 0)]
    pub start: u64,
    /// Only inputs of this class (default: a mix of all).
    #[arg(long, value_enum)]
    pub class: Option<crate::fuzz::Class>,
    /// Worker processes at a time (default: one per core).
    #[arg(long, value_name = "N")]
    pub jobs: Option<usize>,
    /// Seconds an input may run before it counts as a hang.
    #[arg(long, default_value_t = 20)]
    pub timeout: u64,
    /// Write each finding's input into this directory.
    #[arg(long, value_name = "DIR")]
    pub findings: Option<PathBuf>,
    /// Write the shortest input of each (class, outcome) into this directory.
    #[arg(long, value_name = "DIR")]
    pub save_corpus: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
pub struct FuzzWorkerArgs {
    #[arg(long)]
    pub seed: u64,
    #[arg(long)]
    pub from: u64,
    #[arg(long)]
    pub to: u64,
    #[arg(long, value_enum)]
    pub class: Option<crate::fuzz::Class>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Emit {
    /// The syntax tree of each given file: one node per line with its line:col.
    Ast,
    /// The checked IR of each primitive and interpolator defined in the given files
    /// (helpers are inlined into them).
    Ir,
    /// Cranelift IR of each primitive in the given files, for the `--key` variant.
    Clif,
    /// Machine code of each primitive in the given files, for the `--key` variant: the
    /// tier-1 (optimised) kernel after register allocation.
    Asm,
}

#[derive(clap::Args, Debug)]
pub struct CheckArgs {
    /// The .prim files to check.
    #[arg(required = true, value_name = "FILE.prim")]
    pub files: Vec<PathBuf>,
    /// Extra directory of .prim files (repeatable).
    #[arg(long = "prims", value_name = "DIR")]
    pub prims: Vec<PathBuf>,
    /// Also print a compiler stage's output.
    #[arg(long, value_enum)]
    pub emit: Option<Emit>,
    /// Variant key for `--emit clif` and `--emit asm`: comma-separated KIND:COMPONENTS, KIND being `linear`,
    /// `perspective_linear`, any other per-sequence-point kind, `constant`, or a shared
    /// interpolator's name.
    #[arg(long, value_name = "SPEC", default_value = "linear:1,perspective_linear:1")]
    pub key: String,
}

#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// The scene file.
    pub scene: PathBuf,
    /// Output image (PNG, RGB8).
    #[arg(short, long, value_name = "FILE.png")]
    pub output: PathBuf,
    /// Also write the depth buffer (16-bit gray PNG, nearer is brighter).
    #[arg(long, value_name = "FILE.png")]
    pub depth: Option<PathBuf>,
    /// Also write a shading parameter as an image (1 component: gray over its range,
    /// 3: RGB clamped). Repeatable.
    #[arg(long, num_args = 2, value_names = ["NAME", "FILE.png"], action = clap::ArgAction::Append)]
    pub param: Vec<String>,
    /// Worker threads for the tiles (default: one per core). Two or more, and no more than
    /// the CPUs the process may use: each is pinned to a CPU of its own.
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Extra directory of .prim files (repeatable).
    #[arg(long = "prims", value_name = "DIR")]
    pub prims: Vec<PathBuf>,
    /// Count depth writes per pixel (kernels compiled with write counting).
    #[arg(long)]
    pub count_writes: bool,
    /// Print which geometry pipeline each primitive took (seed 000 sections 5-7, with the
    /// ill-behaved cases it met), the kernel variants compiled and the shading effects.
    #[arg(long)]
    pub explain: bool,
    /// Samples per pixel (1, 2, 4, 8 or 16; the scene's `samples` line otherwise, else 1):
    /// each sample is rendered and shaded at its standard position, and the image resolves
    /// them. `--depth` and `--param` show the pixel's first sample.
    #[arg(long, value_name = "N")]
    pub samples: Option<u32>,
    /// How the samples resolve to a pixel: box (the mean of the pixel's samples) or
    /// gaussian (pbrt's, radius 1.5 pixels).
    #[arg(long, value_name = "NAME", value_parser = ["box", "gaussian"])]
    pub filter: Option<String>,
}

#[derive(clap::Args, Debug)]
pub struct TraceArgs {
    /// The scene file.
    pub scene: PathBuf,
    /// The pixel: column and row from the top-left, e.g. `12,7`.
    #[arg(long, value_name = "X,Y", value_parser = crate::trace::parse_pixel)]
    pub pixel: (u32, u32),
    /// Extra directory of .prim files (repeatable).
    #[arg(long = "prims", value_name = "DIR")]
    pub prims: Vec<PathBuf>,
}

#[derive(clap::Args, Debug)]
pub struct TestArgs {
    /// Case files or directories searched for `*.scene` files with `# expect:` lines
    /// (default: the library's own prims/tests and every `--prims` directory).
    #[arg(value_name = "PATH")]
    pub paths: Vec<PathBuf>,
    /// Extra directory of .prim files (repeatable).
    #[arg(long = "prims", value_name = "DIR")]
    pub prims: Vec<PathBuf>,
    /// Worker threads per render (default: one per core; pinned as `render`'s are).
    #[arg(long, value_name = "N")]
    pub threads: Option<usize>,
    /// Create missing golden images from this run instead of failing.
    #[arg(long)]
    pub bless: bool,
}

#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Only workloads whose name contains this text.
    #[arg(long, value_name = "NAME")]
    pub filter: Option<String>,
    /// Fewer primitives and runs (well under two minutes).
    #[arg(long)]
    pub quick: bool,
    /// Benchmark this scene file instead of the standard workloads: its first frame and
    /// where the time goes, each kernel variant's compile at both tiers, and its frames with
    /// tier-1 and tier-0 kernels, on one thread and on all, and with the hand-written
    /// kernels where they can draw it.
    #[arg(long, value_name = "FILE.scene", conflicts_with_all = ["filter", "quick"])]
    pub scene: Option<PathBuf>,
    /// Extra directory of .prim files for `--scene` (repeatable).
    #[arg(long, value_name = "DIR", requires = "scene")]
    pub prims: Vec<PathBuf>,
    /// Timed runs per kernel; the median is reported.
    #[arg(long, default_value_t = 7, value_name = "N")]
    pub runs: usize,
    /// Also write the results as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

#[derive(clap::Args, Debug)]
pub struct AccuracyArgs {
    /// Only the knobs whose standard scene name contains this: sphere, nurb,
    /// interpolation, arithmetic, lighting, depth.
    #[arg(long, value_name = "S")]
    pub scene: Option<String>,
    /// Directory for accuracy.csv, accuracy.json and one <knob>.png per knob.
    #[arg(long, value_name = "DIR", default_value = "accuracy-out")]
    pub out: PathBuf,
    /// Small scenes, fewer settings and 3 runs: under a minute on two cores (release build).
    #[arg(long)]
    pub quick: bool,
    /// Timed runs per setting (the median is reported).
    #[arg(long, value_name = "N", default_value_t = 7)]
    pub runs: usize,
    /// No progress bar.
    #[arg(long)]
    pub no_progress: bool,
    /// Measure nothing: read a saved run's accuracy.json and write its table, CSV and
    /// plots again (into `--out`).
    #[arg(long, value_name = "FILE.json", conflicts_with_all = ["scene", "quick"])]
    pub from: Option<PathBuf>,
}

/// Turn transparent huge pages off for this process (Linux; elsewhere nothing). The binary's
/// allocator, mimalloc, asks for them on its arenas (`madvise`), and the kernel zeroes a
/// whole 2 MiB page at the first touch of each: a process's first compiles touch ~50, which
/// on the 2-vCPU VM was 40 % of a first NURB compile's time and most of `primflow render`'s
/// system time, for no measured gain in a frame's time (docs/performance.md, "The release binary: LTO, mimalloc, transparent huge pages off").
/// The binary calls this first thing; the setting is the process's (`PR_SET_THP_DISABLE`),
/// so it also holds for memory mimalloc reserved before `main`. Returns whether it took.
pub fn disable_transparent_huge_pages() -> bool {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: PR_SET_THP_DISABLE takes integer arguments and touches no memory of ours.
        unsafe { libc::prctl(libc::PR_SET_THP_DISABLE, 1, 0, 0, 0) == 0 }
    }
    #[cfg(not(target_os = "linux"))]
    {
        false
    }
}

/// Run the command line `args` (the first is the program name), printing to `out` and
/// `err`; returns the exit code.
pub fn run<I, T>(args: I, out: &mut dyn Write, err: &mut dyn Write) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let text = e.render().to_string();
            let _ = if e.use_stderr() {
                err.write_all(text.as_bytes())
            } else {
                out.write_all(text.as_bytes())
            };
            return code;
        }
    };
    match cli.command {
        Command::Check(args) => check(&args, out, err),
        Command::Render(args) => render(&args, out, err),
        Command::Watch(args) => watch::watch(&args, out, err),
        Command::Serve(args) => serve::serve(&args, out, err),
        Command::Trace(args) => trace(&args, out, err),
        Command::Test(args) => test(&args, out),
        Command::Bench(args) => bench(&args, out, err),
        Command::Accuracy(args) => accuracy(&args, out, err),
        Command::Fuzz(args) => fuzz(&args, out, err),
        Command::LlvmpipeWorker => crate::bench::llvmpipe_worker(&mut std::io::stdin().lock(), out),
        Command::FuzzWorker(a) => crate::fuzz::campaign::worker(a.seed, a.from, a.to, a.class, out),
    }
}

fn fuzz(args: &FuzzArgs, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    use crate::fuzz::{campaign, Class, Corpus};
    let corpus = match Corpus::load() {
        Ok(c) => c,
        Err(e) => {
            let _ = writeln!(err, "error: the fuzz corpus: {e}");
            return 1;
        }
    };
    let opts = campaign::Options {
        seed: args.seed,
        start: args.start,
        inputs: args.inputs,
        only: args.class,
        jobs: args
            .jobs
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())),
        timeout: std::time::Duration::from_secs(args.timeout.max(1)),
        findings: args.findings.clone(),
        save_corpus: args.save_corpus.clone(),
    };
    let started = std::time::Instant::now();
    let report = match campaign::campaign(&opts, &corpus, err) {
        Ok(r) => r,
        Err(e) => {
            let _ = writeln!(err, "error: {e}");
            return 1;
        }
    };
    let _ = write!(out, "{:<8}", "class");
    for k in campaign::KINDS {
        let _ = write!(out, " {k:>9}");
    }
    let _ = writeln!(out);
    for class in Class::ALL {
        let _ = write!(out, "{:<8}", class.name());
        for k in campaign::KINDS {
            let _ = write!(out, " {:>9}", report.counts.get(&(class, k)).copied().unwrap_or(0));
        }
        let _ = writeln!(out);
    }
    let _ = writeln!(
        out,
        "{} inputs (seed {}) in {:.1} s: {} findings",
        args.inputs,
        args.seed,
        started.elapsed().as_secs_f64(),
        report.findings.len()
    );
    for (i, class, outcome) in &report.findings {
        let class_arg = args.class.map_or(String::new(), |c| format!(" --class {}", c.name()));
        let _ = writeln!(
            out,
            "finding: input {i} ({}) {}: {outcome:?}\n  replay: primflow fuzz --seed {} --start {i} --inputs 1{class_arg}",
            class.name(),
            campaign::kind(outcome),
            args.seed
        );
    }
    i32::from(!report.findings.is_empty())
}

fn test(args: &TestArgs, out: &mut dyn Write) -> i32 {
    // With no paths: the library's cases (in the source tree the binary was built from,
    // when it is still there: an installed binary embeds the library, not its cases), and
    // the cases kept beside each `--prims` directory's primitives (in it or below it).
    let paths = if args.paths.is_empty() {
        let library_cases = crate::testing::default_dir();
        if !library_cases.is_dir() && args.prims.is_empty() {
            let _ = writeln!(
                out,
                "error: no test cases given, and the library's own ({}) are not here: they stay in the \
                 source tree the binary was built from; name a directory or file of cases",
                library_cases.display()
            );
            return 1;
        }
        let mut paths: Vec<PathBuf> = library_cases.is_dir().then_some(library_cases).into_iter().collect();
        paths.extend(args.prims.iter().cloned());
        paths
    } else {
        args.paths.clone()
    };
    let options = crate::testing::TestOptions {
        prim_dirs: args.prims.clone(),
        threads: args.threads.unwrap_or(0),
        bless: args.bless,
    };
    let results = crate::testing::run_all(&paths, &options, out);
    if !results.is_empty() && results.iter().all(|r| r.passed()) {
        0
    } else {
        1
    }
}

fn print_diags(diags: &Diagnostics, sources: &SourceMap, err: &mut dyn Write) {
    if !diags.items.is_empty() {
        let _ = writeln!(err, "{}", diags.render(sources));
    }
}

/// A new source map holding the scene file; `None` after printing why it cannot be read.
fn read_scene(scene: &Path, err: &mut dyn Write) -> Option<(SourceMap, FileId)> {
    let mut sources = SourceMap::new();
    match crate::scene::read_file(scene) {
        Ok(text) => {
            let file = sources.add_file(scene, text);
            Some((sources, file))
        }
        Err(e) => {
            let _ = writeln!(err, "error: {e}");
            None
        }
    }
}

/// Print a scene's (or its primitives') errors and that nothing was `done`; exit code 1.
fn scene_errors(diags: &Diagnostics, sources: &SourceMap, done: &str, err: &mut dyn Write) -> i32 {
    print_diags(diags, sources, err);
    let _ = writeln!(
        err,
        "error: {} error(s) in the scene or the primitives it uses; nothing {done}",
        diags.error_count()
    );
    1
}

fn check(args: &CheckArgs, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    let mut sources = SourceMap::new();
    let mut diags = Diagnostics::new();
    let (loaded, given) = Registry::load_sources(&mut sources, &args.prims, &args.files, &mut diags);
    if diags.has_errors() {
        print_diags(&diags, &sources, err);
        return 1;
    }
    if args.emit == Some(Emit::Ast) {
        for &file in &given {
            // Its syntax errors are reported by the check below.
            let module = crate::syntax::parse(file, sources.text(file), &mut Diagnostics::new());
            let tree = crate::syntax::print::module_tree(&module, &sources);
            let _ = write!(out, "// {}\n{tree}", sources.file(file).name);
        }
    }
    let registry = Registry::compile(&sources, loaded, &mut diags);
    print_diags(&diags, &sources, err);
    let Some(registry) = registry else {
        let _ = writeln!(err, "error: {} error(s); nothing compiled", diags.error_count());
        return 1;
    };
    let program = &registry.program;
    let code = match args.emit {
        Some(Emit::Ir) => {
            emit_ir(program, &given, out);
            0
        }
        Some(Emit::Clif) => emit_kernels(program, &given, &args.key, Emit::Clif, out, err),
        Some(Emit::Asm) => emit_kernels(program, &given, &args.key, Emit::Asm, out, err),
        Some(Emit::Ast) | None => 0,
    };
    if code == 0 {
        // On stderr with the diagnostics, so that stdout holds only what `--emit` dumps.
        let _ = writeln!(err, "{}", check_summary(&sources, &registry.files, &diags));
    }
    code
}

/// What a successful `check` checked, one line: `ok: 10 files, 8 primitives, 3
/// interpolators, 21 helpers, 17 shaders checked (no warnings)`. The files are all those compiled (the
/// library, `--prims` directories and the given files).
fn check_summary(sources: &SourceMap, files: &[FileId], diags: &Diagnostics) -> String {
    use crate::syntax::ast::ItemKind;
    // Counted on a second parse of the files (a fraction of the check's time): the checked
    // program keeps no helpers (they are inlined) and shaders only when linked.
    let [mut prims, mut interps, mut helpers, mut shaders] = [0; 4];
    for &file in files {
        let module = crate::syntax::parse(file, sources.text(file), &mut Diagnostics::new());
        for item in &module.items {
            match item.kind {
                ItemKind::Primitive => prims += 1,
                ItemKind::Interpolator => interps += 1,
                ItemKind::Function => helpers += 1,
                ItemKind::Surface | ItemKind::Light | ItemKind::Atmosphere => shaders += 1,
            }
        }
    }
    let n = |count: usize, what: &str| format!("{count} {what}{}", if count == 1 { "" } else { "s" });
    let warnings = diags.items.iter().filter(|d| !d.is_error()).count();
    format!(
        "ok: {}, {}, {}, {}, {} checked ({})",
        n(files.len(), "file"),
        n(prims, "primitive"),
        n(interps, "interpolator"),
        n(helpers, "helper"),
        n(shaders, "shader"),
        if warnings == 0 {
            "no warnings".to_string()
        } else {
            n(warnings, "warning")
        }
    )
}

/// `--emit ir`: the functions of the checked program defined in `given`, in program order.
/// Helpers are not among them (the checker inlines every call), nor shaders (checked only
/// when a frame links them); library primitives a given one calls appear by name only
/// (`call screen_triangle#8(...)`).
fn emit_ir(program: &Program, given: &[FileId], out: &mut dyn Write) {
    let mut printed = 0;
    for f in program.functions.iter().filter(|f| given.contains(&f.span.file)) {
        if printed > 0 {
            let _ = writeln!(out);
        }
        let _ = write!(out, "{}", f.display_in(program));
        printed += 1;
    }
    if printed == 0 {
        let _ = writeln!(
            out,
            "// no primitive or interpolator in the given files (helpers are inlined into their callers)"
        );
    }
}

/// `--emit clif` / `--emit asm`: each primitive of `given` lowered for the `spec` key, as
/// Cranelift IR or as tier-1 machine code, under a `; primitive NAME key KEY` header.
fn emit_kernels(
    program: &Arc<Program>,
    given: &[FileId],
    spec: &str,
    what: Emit,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> i32 {
    let key = match parse_key(spec, program) {
        Ok(key) => key,
        Err(message) => {
            let _ = writeln!(err, "error: --key `{spec}`: {message}");
            return 1;
        }
    };
    // `Jit::new` compiles at tier 1 (opt_level=speed), the kernels a frame ends up running.
    let jit = match Jit::new(program.clone()) {
        Ok(jit) => jit,
        Err(e) => {
            let _ = writeln!(err, "error: cannot start the JIT: {e}");
            return 1;
        }
    };
    let _ = writeln!(out, "; {}", jit.isa_summary());
    let mut code = 0;
    for (i, f) in program.functions.iter().enumerate() {
        if f.kind != FuncKind::Primitive || !given.contains(&f.span.file) {
            continue;
        }
        let id = crate::ir::FuncId(i as u32);
        let text = match what {
            Emit::Asm => jit.disassembly(id, &key).map(|d| {
                format!(
                    "; primitive {} key {}: {} instructions, {} of them spills or reloads\n{}",
                    f.name,
                    describe_key(&key),
                    d.inst_lines,
                    d.spill_lines,
                    d.text
                )
            }),
            _ => jit
                .clif(id, &key)
                .map(|text| format!("; primitive {} key {}\n{text}", f.name, describe_key(&key))),
        };
        match text {
            Ok(text) => {
                let _ = writeln!(out, "{text}");
            }
            Err(e) => {
                let _ = writeln!(err, "error: cannot compile `{}`: {e}", f.name);
                code = 1;
            }
        }
    }
    code
}

/// Parse a `--key` spec: `linear:3,perspective_linear:1,constant:3,my_interp:2`.
pub fn parse_key(spec: &str, program: &Program) -> Result<VariantKey, String> {
    let mut bindings = vec![];
    for item in spec.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let (kind, count) = item
            .rsplit_once(':')
            .ok_or_else(|| format!("`{item}` is not KIND:COMPONENTS"))?;
        let components: u32 = count
            .parse()
            .ok()
            .filter(|n| (1..=64).contains(n))
            .ok_or_else(|| format!("`{count}` is not a component count (1..=64)"))?;
        let is_ident = kind.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && kind.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !is_ident {
            return Err(format!("`{kind}` is not an interpolation kind"));
        }
        let shared = program
            .find(kind)
            .is_some_and(|id| program.func(id).kind == FuncKind::Interpolator);
        let kind = if kind == "constant" {
            BindingKind::Constant
        } else if shared {
            BindingKind::Shared(kind.to_string())
        } else {
            BindingKind::Kind(kind.to_string())
        };
        bindings.push(Binding { kind, components });
    }
    Ok(VariantKey {
        bindings,
        count_writes: false,
        trivial_accept: false,
    })
}

fn render(args: &RenderArgs, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    // Every output path is checked (format, directory) before anything is loaded or rendered.
    let mut targets: Vec<(&Path, &'static str)> = vec![(&args.output, "image")];
    if let Some(path) = &args.depth {
        targets.push((path, "depth image"));
    }
    for pair in args.param.chunks(2) {
        if let [_, path] = pair {
            targets.push((Path::new(path), "parameter image"));
        }
    }
    let outputs = match OutputFiles::claim(&targets) {
        Ok(outputs) => outputs,
        Err(problems) => {
            for p in problems {
                let _ = writeln!(err, "error: {p}");
            }
            let _ = writeln!(err, "error: nothing rendered, no file written");
            return 1;
        }
    };
    // The render threads start (thread creation, the CPU topology read for pinning: ~0.5 ms)
    // while this thread loads the scene and the library.
    // (Where no helper thread can start, the pool is made in place below.)
    let wanted = args.threads.unwrap_or(0);
    let starting = std::thread::Builder::new()
        .spawn(move || crate::runtime::render_pool(wanted))
        .ok();
    let Some((mut sources, scene_file)) = read_scene(&args.scene, err) else {
        return 1;
    };
    let mut diags = Diagnostics::new();
    let base = args.scene.parent().unwrap_or(Path::new("."));
    let Some(mut renderer) = crate::scene::load_for_render(&mut sources, scene_file, base, &args.prims, &mut diags)
    else {
        return scene_errors(&diags, &sources, "rendered", err);
    };
    renderer.options.count_writes = args.count_writes;
    if let Some(filter) = args.filter.as_deref().and_then(crate::runtime::samples::Filter::parse) {
        renderer.set_filter(filter);
    }
    if let Some(n) = args.samples {
        if let Err(e) = renderer.set_samples(n) {
            let _ = writeln!(err, "error: --samples: {}", e.message);
            return 1;
        }
    }
    // A parameter written as an image keeps its planes whether or not a shader reads it.
    renderer.options.keep_params = args.param.chunks(2).map(|pair| pair[0].clone()).collect();
    // Tiered: the frame starts on tier-0 kernels (compiled in a millisecond or two) and
    // switches to tier-1 ones as the background compiler finishes them, mid-frame.
    let mut jit = match Jit::tiered(renderer.program().clone()) {
        Ok(jit) => jit,
        Err(e) => {
            print_diags(&diags, &sources, err);
            let _ = writeln!(err, "error: cannot start the JIT: {e}");
            return 1;
        }
    };
    let started = match starting.map(|helper| helper.join()) {
        Some(Ok(started)) => started,
        // The helper could not start or did not finish: make the pool here.
        _ => crate::runtime::render_pool(wanted),
    };
    let pool = match started {
        Ok(pool) => pool,
        Err(e) => {
            let _ = writeln!(err, "error: cannot start {wanted} threads: {e}");
            return 1;
        }
    };
    let threads = pool.current_num_threads();
    let mut result = pool.install(|| renderer.render(&mut jit));
    // One frame: tier-1 kernels still compiling would only delay the exit.
    jit.detach_tier_up();
    diags.extend(std::mem::take(&mut result.diags));
    print_diags(&diags, &sources, err);
    if diags.has_errors() {
        let _ = writeln!(
            err,
            "error: {} error(s) while rendering; no image written",
            diags.error_count()
        );
        return 1;
    }
    let frame = &result.frame;
    // All images first, then all files: a bad `--param` name writes nothing.
    let mut images = vec![image::DynamicImage::ImageRgb8(frame.to_rgb8())];
    if args.depth.is_some() {
        images.push(image::DynamicImage::ImageLuma16(frame.depth_image()));
    }
    let mut failures = vec![];
    for pair in args.param.chunks(2) {
        let [name, _] = pair else { continue };
        match frame.param_image(name) {
            Ok(img) => images.push(image::DynamicImage::ImageRgb8(img)),
            Err(message) => failures.push(format!("--param {name}: {message}")),
        }
    }
    let mut written = vec![];
    if failures.is_empty() {
        match outputs.commit(images) {
            Ok(files) => written = files,
            Err(e) => failures.push(e),
        }
    } else {
        failures.push("no file written".to_string());
    }
    for f in &failures {
        let _ = writeln!(err, "error: {f}");
    }
    if args.explain {
        write_explain(&renderer, &result, out);
        let _ = match crate::runtime::pool::pinning_plan(threads) {
            Some(cpus) => writeln!(out, "render threads: {threads}, pinned to CPUs {cpus:?}"),
            None => writeln!(out, "render threads: {threads}, not pinned"),
        };
    }
    let ok = failures.is_empty();
    let s = &result.stats;
    let _ = writeln!(
        out,
        "rendered {}x{}: {} primitive(s), {} kernel(s) compiled in {:.2} ms, rendered in {:.2} ms on {threads} thread(s) -> {}",
        frame.width,
        frame.height,
        s.instances,
        s.kernels_compiled,
        s.compile_micros as f64 / 1000.0,
        s.render_micros as f64 / 1000.0,
        written.join(", ")
    );
    if ok {
        0
    } else {
        1
    }
}

fn trace(args: &TraceArgs, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    let Some((mut sources, scene_file)) = read_scene(&args.scene, err) else {
        return 1;
    };
    let mut diags = Diagnostics::new();
    let base = args.scene.parent().unwrap_or(Path::new("."));
    let Some((mut renderer, objects)) =
        crate::scene::load_objects(&mut sources, scene_file, base, &args.prims, &mut diags)
    else {
        return scene_errors(&diags, &sources, "traced", err);
    };
    // The trace evaluates at the pixel centre: the frame it checks against is one sample.
    if renderer.options.samples != 1 {
        let _ = writeln!(
            out,
            "note: the scene's `samples {}` is ignored: the trace runs at the pixel centre, one sample per pixel",
            renderer.options.samples
        );
        renderer.options.samples = 1;
    }
    // Checked before rendering: the frame is clamped to the same size.
    let (width, height) = (
        renderer.options.width.min(crate::runtime::MAX_IMAGE_SIDE),
        renderer.options.height.min(crate::runtime::MAX_IMAGE_SIDE),
    );
    let (x, y) = args.pixel;
    if x >= width || y >= height {
        print_diags(&diags, &sources, err);
        let _ = writeln!(
            err,
            "error: pixel ({x}, {y}) is outside the {width}x{height} image (x in 0..={}, y in 0..={})",
            width.saturating_sub(1),
            height.saturating_sub(1)
        );
        return 1;
    }
    let mut jit = match Jit::new(renderer.program().clone()) {
        Ok(jit) => jit,
        Err(e) => {
            print_diags(&diags, &sources, err);
            let _ = writeln!(err, "error: cannot start the JIT: {e}");
            return 1;
        }
    };
    let mut result = match crate::runtime::render_pool(0) {
        Ok(pool) => pool.install(|| renderer.render(&mut jit)),
        Err(_) => renderer.render(&mut jit),
    };
    diags.extend(std::mem::take(&mut result.diags));
    print_diags(&diags, &sources, err);
    if diags.has_errors() {
        let _ = writeln!(
            err,
            "error: {} error(s) while rendering; nothing traced",
            diags.error_count()
        );
        return 1;
    }
    match crate::trace::trace(&sources, &renderer, &objects, &result.frame, args.pixel, out) {
        Ok(_) => 0,
        Err(message) => {
            let _ = writeln!(err, "error: {message}");
            1
        }
    }
}

/// The image files `render` writes, claimed before rendering and written whole or not at all.
///
/// [`OutputFiles::claim`] checks every path before any work: the format (PNG only) from the
/// file name, and the directory, by creating an empty temporary file next to the target
/// (`.NAME.primflow-PID-N.tmp`). [`OutputFiles::commit`] writes each image into its temporary
/// file and only then renames them into place, so an existing file is never truncated by a
/// refused or failed render, and a bad `--depth` / `--param` path fails before the main image
/// is written. Temporary files still there when this is dropped are removed.
struct OutputFiles {
    /// (target, its temporary file, what it is) per output, in the order given.
    files: Vec<(PathBuf, PathBuf, &'static str)>,
}

impl OutputFiles {
    fn claim(targets: &[(&Path, &'static str)]) -> Result<OutputFiles, Vec<String>> {
        let mut files = OutputFiles { files: vec![] };
        let mut problems = vec![];
        for &(path, what) in targets {
            if image::ImageFormat::from_path(path).ok() != Some(image::ImageFormat::Png) {
                problems.push(format!(
                    "cannot write the {what} to `{}`: only PNG is supported (the name must end in .png)",
                    path.display()
                ));
                continue;
            }
            let name = path
                .file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default();
            // Unique per process and claim (tests render in parallel in one process).
            static CLAIMS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
            let claim = CLAIMS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            let temp = path.with_file_name(format!(".{name}.primflow-{}-{claim}.tmp", std::process::id()));
            match std::fs::File::create(&temp) {
                Ok(_) => files.files.push((path.to_path_buf(), temp, what)),
                Err(e) => problems.push(format!("cannot write the {what} to `{}`: {e}", path.display())),
            }
        }
        if problems.is_empty() {
            Ok(files)
        } else {
            Err(problems)
        }
    }

    /// Write `images` (one per claimed file, in order) to the temporary files, then rename
    /// them all into place. On an error nothing has been renamed, except when a rename itself
    /// fails after others succeeded.
    fn commit(mut self, images: Vec<image::DynamicImage>) -> Result<Vec<String>, String> {
        for ((path, temp, what), img) in self.files.iter().zip(&images) {
            img.save_with_format(temp, image::ImageFormat::Png)
                .map_err(|e| format!("cannot write the {what} to `{}`: {e}", path.display()))?;
        }
        let files = std::mem::take(&mut self.files);
        let mut written = vec![];
        for (i, (path, temp, what)) in files.iter().enumerate() {
            if let Err(e) = std::fs::rename(temp, path) {
                for (_, left, _) in &files[i..] {
                    let _ = std::fs::remove_file(left);
                }
                return Err(format!("cannot write the {what} to `{}`: {e}", path.display()));
            }
            written.push(path.display().to_string());
        }
        Ok(written)
    }
}

impl Drop for OutputFiles {
    fn drop(&mut self) {
        for (_, temp, _) in &self.files {
            let _ = std::fs::remove_file(temp);
        }
    }
}

/// `render --explain`: pipelines, kernel variants, shading effects.
fn write_explain(renderer: &Renderer, result: &crate::runtime::RenderOutput, out: &mut dyn Write) {
    let _ = writeln!(out, "geometry pipelines:");
    let lines = renderer.explain_lines();
    if lines.is_empty() {
        let _ = writeln!(out, "  (no primitives)");
    }
    for line in lines {
        let _ = writeln!(out, "  {line}");
    }
    let _ = writeln!(out, "kernel variants compiled:");
    for k in &result.kernels {
        let _ = writeln!(
            out,
            "  {} [{}{}] {:.3} ms",
            k.primitive,
            k.key,
            if k.trivial_accept {
                ", trivially accepted: no clipping code"
            } else {
                ", with clipping code"
            },
            k.compile_micros as f64 / 1000.0
        );
    }
    let space = match renderer.shading_setup.space {
        crate::runtime::shading::LightingSpaceChoice::Lighting => "lighting coordinates",
        crate::runtime::shading::LightingSpaceChoice::World => "world coordinates",
        crate::runtime::shading::LightingSpaceChoice::Device => "device coordinates",
    };
    if result.language_shading.is_empty() {
        let _ = writeln!(
            out,
            "shading effects: {} (lights: {}, lit in {space})",
            result.effects,
            renderer.shading_setup.lights.len()
        );
    } else {
        let _ = writeln!(out, "shading:");
        for line in &result.language_shading {
            let _ = writeln!(out, "  {line}");
        }
    }
}

fn bench(args: &BenchArgs, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    if cfg!(debug_assertions) {
        let _ = writeln!(
            err,
            "note: this build has debug assertions (Cranelift's verifier and the IR validator run on every compile): its times are not a release build's; for timings build with `cargo build --release`"
        );
    }
    let report = match &args.scene {
        Some(scene) => crate::bench::run_scene(&crate::bench::SceneBenchOptions {
            scene: scene.clone(),
            prims: args.prims.clone(),
            runs: args.runs.max(1),
            progress: true,
        })
        .map(|r| (crate::bench::format_scene_report(&r), serde_json::to_string_pretty(&r))),
        None => crate::bench::run(&crate::bench::BenchOptions {
            filter: args.filter.clone(),
            quick: args.quick,
            runs: args.runs.max(1),
            progress: true,
            // This very binary times llvmpipe in a process of its own.
            llvmpipe: std::env::current_exe().ok(),
        })
        .map(|r| (crate::bench::format_table(&r), serde_json::to_string_pretty(&r))),
    };
    let (table, json) = match report {
        Ok(r) => r,
        Err(e) => {
            let _ = writeln!(err, "error: {e}");
            return 1;
        }
    };
    let _ = out.write_all(table.as_bytes());
    if let Some(path) = &args.json {
        let written = json
            .map_err(|e| e.to_string())
            .and_then(|text| std::fs::write(path, text).map_err(|e| e.to_string()));
        if let Err(e) = written {
            let _ = writeln!(err, "error: cannot write {}: {e}", path.display());
            return 1;
        }
    }
    0
}

fn accuracy(args: &AccuracyArgs, out: &mut dyn Write, err: &mut dyn Write) -> i32 {
    let opts = crate::accuracy::AccuracyOptions {
        filter: args.scene.clone(),
        quick: args.quick,
        runs: args.runs,
        progress: !args.no_progress,
    };
    let report = match &args.from {
        Some(path) => std::fs::read_to_string(path)
            .map_err(|e| e.to_string())
            .and_then(|text| serde_json::from_str(&text).map_err(|e| e.to_string()))
            .map_err(|e| format!("cannot read a saved run from `{}`: {e}", path.display())),
        None => crate::accuracy::run(&opts),
    };
    let report = match report {
        Ok(report) => report,
        Err(message) => {
            let _ = writeln!(err, "error: {message}");
            return 1;
        }
    };
    let _ = write!(out, "{}", crate::accuracy::format_table(&report));
    match crate::accuracy::write_outputs(&report, &args.out) {
        Ok(written) => {
            let _ = writeln!(out, "wrote {}", written.join(", "));
            0
        }
        Err(message) => {
            let _ = writeln!(err, "error: {message}");
            1
        }
    }
}
