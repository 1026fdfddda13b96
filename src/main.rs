//! The `primflow` binary: a thin shell over [`primflow::cli::run`].

/// mimalloc: the JIT's compiles allocate and free many small vectors (Cranelift's, ours);
/// with glibc's malloc that was ~5 % of a tier-0 compile's instructions, and mimalloc made
/// compiles ~4-7 % faster (docs/performance.md, "The release binary: LTO, mimalloc, transparent huge pages off").
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> std::process::ExitCode {
    primflow::cli::disable_transparent_huge_pages();
    let mut out = std::io::stdout().lock();
    let mut err = std::io::stderr().lock();
    let code = primflow::cli::run(std::env::args_os(), &mut out, &mut err);
    std::process::ExitCode::from(code.clamp(0, 255) as u8)
}
