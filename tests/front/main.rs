//! The front end: lexer and grammar (`parse`), the syntax tree printer (`ast_print`, with an
//! insta snapshot), component access (`components`), the
//! checker's diagnostics (`check_errors`, `check_ok`, with insta snapshots under
//! `snapshots/`), its passes over the IR (`check_passes`) and a fuzz of mutated sources
//! (`check_fuzz`), the depth and size limits (`limits`), long-line diagnostics and the error
//! cap (`diag_limits`), the "did you mean" rule (`did_you_mean`), the checker's type rules
//! (`type_rules`), and the IR validator's rules (`valid`).
//!
//! One test binary per layer keeps the suite to a handful of links; one module per concern.

mod ast_print;
mod check_errors;
mod check_fuzz;
mod check_ok;
mod check_passes;
mod components;
mod diag_limits;
mod did_you_mean;
mod limits;
mod parse;
#[path = "../support/mod.rs"]
mod support;
mod type_rules;
mod valid;
