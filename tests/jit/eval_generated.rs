//! Generated valid programs against the IR evaluator: the seeded generator of
//! `primflow::fuzz::gen` writes primitives with float, int and fixed-point locals, a local
//! array indexed by computed ints (some out of range), uniform and varying `if`s, counted
//! and open `while` and `for` loops with `break` and `continue` (some endless: fuel), early
//! `return`s, helper calls (one with a loop and an early `return`), a primitive call in the
//! setup, Z assigned on some paths, and interpolation arms. Each checks, and is compared with the evaluator
//! as `eval_oracle` compares (random argument blocks, every key of `eval_oracle::keys`,
//! both tiers), with loop unrolling on and off.

use std::sync::Arc;

use crate::eval_oracle::{random_arg_cases, small_budget, Seen};
use primflow::fuzz::gen::program_source;

use primflow::diag::{Diagnostics, SourceMap};

#[test]
fn generated_programs_match_the_evaluator_at_both_tiers_unrolled_or_not() {
    let mut seen = Seen::default();
    let (mut compiled, total) = (0, 40);
    for seed in 0..total {
        let text = program_source(seed);
        let mut sources = SourceMap::new();
        let file = sources.add(format!("gen{seed}.prim"), text.clone());
        let mut diags = Diagnostics::new();
        let Some(program) = primflow::compile(&sources, &[file], &mut diags).filter(|_| !diags.has_errors()) else {
            eprintln!(
                "generated program {seed} does not check:\n{text}\n{}",
                diags.render(&sources)
            );
            continue;
        };
        compiled += 1;
        let program = Arc::new(program);
        for unroll in [true, false] {
            random_arg_cases(&program, &["gen"], 2, small_budget(), unroll, &mut seen);
        }
    }
    // The generator writes valid programs; a few may trip a rule it does not model.
    assert!(
        compiled * 10 >= total * 9,
        "{compiled} of {total} generated programs check"
    );
    assert!(seen.drawn > 1000 && seen.nonzero_planes > 100, "{seen:?}");
    assert!(seen.errors > 100 && seen.fuel_errors > 10, "{seen:?}");
    assert_eq!(seen.unsupported, 0, "{seen:?}");
}
