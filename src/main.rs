//! The `primflow` binary: a thin shell over [`primflow::cli::run`].

fn main() -> std::process::ExitCode {
    let mut out = std::io::stdout().lock();
    let mut err = std::io::stderr().lock();
    let code = primflow::cli::run(std::env::args_os(), &mut out, &mut err);
    std::process::ExitCode::from(code.clamp(0, 255) as u8)
}
