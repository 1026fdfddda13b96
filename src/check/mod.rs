//! The checker: name resolution, types and conversions, fixed-point formats and
//! uniform/varying inference, lowering the AST to the typed IR.

use crate::diag::{Diagnostics, SourceMap};
use crate::{ir, syntax::ast};

/// Check every module as one program and lower it to IR (helpers inlined, functions split
/// into setup and pixel parts). Errors go to `diags`; the returned program is only
/// meaningful when there are none.
pub fn check(modules: &[ast::Module], sources: &SourceMap, diags: &mut Diagnostics) -> ir::Program {
    let _ = (modules, sources, diags);
    todo!("checker")
}
