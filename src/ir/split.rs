//! Splitting a function into its uniform setup and its pixel part.

use super::Function;

/// Move the statements that must run per pixel group from `f.setup` into `f.pixel`.
pub fn split(f: &mut Function) {
    let _ = f;
    todo!("split")
}
