//! Every size and depth limit of the compiler, in one place, each with the diagnostic that
//! reports a program past it (docs/language.md, section 12, "Limits").
//!
//! Why limits at all: the parser is table-driven (lalrpop's LR automaton keeps its stack on
//! the heap), but everything after it walks the program recursively: the checker, the IR
//! passes, the JIT's lowering at both tiers, and the derived `Drop`/`Debug` of the AST. A
//! recursive walk uses stack in proportion to the program's nesting, and the smallest stack
//! a compile runs on is 2 MiB: the tier-1 compile threads (`jit::TierUp`, default std
//! stack), a rayon pool built without `stack_size` (rayon's global pool), and any
//! application thread that Rust spawned with its defaults (the test harness's too). Render
//! pools (`runtime::render_pool`) have 64 MiB and the main thread 8 MiB.
//!
//! The depth limits are checked before the walks that would overflow: [`MAX_EXPR_DEPTH`]
//! and [`MAX_BLOCK_DEPTH`] right after parsing, by an iterative walk that also takes an
//! over-deep tree apart without recursion (`syntax::limits`); [`MAX_CALL_DEPTH`] and
//! [`MAX_NESTING`] by the checker as it inlines helpers, before it recurses into the
//! callee. A program within them compiles on a 2 MiB stack at both tiers; the tests build
//! programs at each limit and compile them on a thread of exactly that size
//! (tests/front/limits.rs, tests/jit/deep_programs.rs).
//!
//! Measured stack per level (profile `tests`, x86-64, the largest of the passes, which is
//! the checker): an expression level 1.4 KiB (a sum) to 2.3 KiB (a call or a cast), a
//! statement level 1.1 KiB, a helper call in a chain 4.6 KiB (its call, its inlining and
//! the `return` statement in its body). So [`MAX_NESTING`] levels of the costliest kind
//! take about 1.2 MiB of the 2 MiB.

/// Largest source file, in bytes (E0002, at the first byte past it). Spans are 32-bit
/// offsets, and a file this size already takes the checker seconds.
pub const MAX_SOURCE_BYTES: usize = 16 << 20;

/// Deepest expression as written, in one statement (E0014, at the sub-expression one level
/// too deep). A sum `a + b + ... ` of n terms is n deep: C's operators associate, so its
/// tree is a chain. Calls, casts, indexing, `?:`, unary operators and `{...}` lists each
/// add a level; parentheses do not.
pub const MAX_EXPR_DEPTH: u32 = 256;

/// Deepest statement nesting as written, in one item (E0015, at the statement one level
/// too deep): every `{ }` block and every body of `if`, `else`, `while`, `for` and
/// `interpolation` arm is one level.
pub const MAX_BLOCK_DEPTH: u32 = 128;

/// Longest chain of helper calls inlined one inside another (E0110, at the call one level
/// too deep): `a` calling `b` calling `c` is 3 deep.
pub const MAX_CALL_DEPTH: u32 = 32;

/// Deepest nesting after inlining (E0111): expression levels, statement levels and (two
/// each) helper calls counted along a chain of calls, since the checker inlines a helper's
/// body at the depth of its call. A program without helper calls stays below it by the
/// two limits above (256 + 128 < 512).
pub const MAX_NESTING: u32 = 512;

/// Most bytes of local variables one primitive or interpolator may have, helpers' inlined
/// locals included (E0216, at the local that passes it): a varying component takes 16
/// bytes, a uniform one 4, an interpolation_data element counts as one component. A kernel's frame
/// holds its arrays, so this is the render threads' stack (`runtime::RENDER_THREAD_STACK`):
/// a primitive past it could never run, and compiling it would take seconds and, past
/// 4 GiB, fail in Cranelift.
pub const MAX_LOCAL_BYTES: u64 = 64 << 20;
