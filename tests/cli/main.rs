//! The command line: `render`, `check`, `test`, `bench` (effects, llvmpipe, `--scene`),
//! `accuracy`, `trace`, `watch` and `serve`, run in-process or as the built binary; the `# expect:` lines `test` reads
//! (`expectations`) and the bench report's arithmetic (`bench_report`).
//!
//! One test binary per layer keeps the suite to a handful of links; one module per concern.

mod accuracy_cli;
mod accuracy_coverage;
mod accuracy_knobs;
mod bench_effects;
mod bench_llvmpipe;
mod bench_report;
mod bench_scene;
mod cli_run;
mod expectations;
mod fuzz_campaign;
mod output_files;
mod serve;
#[path = "../support/mod.rs"]
mod support;
mod trace;
mod watch;
