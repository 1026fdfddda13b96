//! Front end: the logos lexer ([`lexer`]) and the lalrpop grammar (`grammar/primflow.lalrpop`,
//! built by build.rs) turn source text into an [`ast::Module`].
//!
//! Syntax errors have codes `E00xx`. The grammar recovers at statement (`;`) and item (`}`)
//! boundaries, so one parse reports several errors; an unrecoverable error (end of file in
//! the middle of an item) still returns the items parsed before it. After this point every
//! node has a span and names are as written: nothing is resolved yet, and the tree is within
//! the depth limits of [`crate::limits`] ([`limits::enforce`]).

pub mod ast;
pub mod build;
pub mod lexer;
pub mod limits;
pub mod print;

lalrpop_util::lalrpop_mod!(
    #[allow(clippy::all, unused_parens, unused_imports)]
    grammar,
    "/primflow.rs"
);

use lalrpop_util::ParseError;

use crate::diag::{Diagnostic, Diagnostics, FileId, Span};
use lexer::{LexError, Tok};

/// Parse one source file. Never panics; on syntax errors the returned module holds what
/// could be recovered (with `Error` nodes) and `diags` holds the errors.
pub fn parse(file: FileId, text: &str, diags: &mut Diagnostics) -> ast::Module {
    if let Some(d) = limits::source_too_large(file, text) {
        diags.push(d);
        return ast::Module::default();
    }
    let mut module = parse_unchecked(file, text, diags);
    limits::enforce(&mut module, diags);
    module
}

/// [`parse`] without the limits: the tree may be of any depth.
fn parse_unchecked(file: FileId, text: &str, diags: &mut Diagnostics) -> ast::Module {
    let mut tokens = lexer::lex(file, text, diags);
    let mut recovered = Vec::new();
    let mut extra = Vec::new();
    let result = grammar::ModuleParser::new().parse(file, &mut recovered, &mut extra, &mut tokens);
    // A parse that gave up early leaves tokens unread: their lexical errors are reported all
    // the same (before the syntax errors, as when the file was lexed first).
    tokens.for_each(drop);
    for r in recovered {
        diags.push(parse_error(file, text, r.error));
    }
    for d in extra {
        diags.push(d);
    }
    match result {
        Ok(module) => module,
        Err(e) => {
            diags.push(parse_error(file, text, e));
            ast::Module::default()
        }
    }
}

/// Parse a single expression (tests and tools).
pub fn parse_expr(file: FileId, text: &str, diags: &mut Diagnostics) -> Option<ast::Expr> {
    if let Some(d) = limits::source_too_large(file, text) {
        diags.push(d);
        return None;
    }
    let mut tokens = lexer::lex(file, text, diags);
    let mut recovered = Vec::new();
    let mut extra = Vec::new();
    let result = grammar::ExprParser::new().parse(file, &mut recovered, &mut extra, &mut tokens);
    tokens.for_each(drop);
    match result {
        Ok(mut e) if recovered.is_empty() => {
            let before = diags.error_count();
            limits::enforce_expr(&mut e, diags);
            (diags.error_count() == before).then_some(e)
        }
        Ok(_) => {
            for r in recovered {
                diags.push(parse_error(file, text, r.error));
            }
            None
        }
        Err(e) => {
            diags.push(parse_error(file, text, e));
            None
        }
    }
}

fn parse_error(file: FileId, text: &str, e: ParseError<usize, Tok, LexError>) -> Diagnostic {
    match e {
        ParseError::UnrecognizedToken {
            token: (l, tok, r),
            expected,
        } => {
            let d = Diagnostic::error("E0011", format!("unexpected {tok}")).primary(
                Span::new(file, l, r),
                format!("expected {}", describe_expected(&expected)),
            );
            match tok {
                Tok::RBrace | Tok::RParen if expected.iter().any(|x| x == "\";\"") => {
                    d.help("a statement must end with `;`")
                }
                _ => d,
            }
        }
        ParseError::UnrecognizedEof { location, expected } => {
            let at = location.min(text.len());
            Diagnostic::error("E0012", "unexpected end of file").primary(
                Span::new(file, at, at),
                format!("expected {}", describe_expected(&expected)),
            )
        }
        ParseError::ExtraToken { token: (l, tok, r) } => {
            Diagnostic::error("E0013", format!("unexpected {tok} after the end of the item"))
                .primary(Span::new(file, l, r), "not expected here")
        }
        ParseError::InvalidToken { location } => {
            Diagnostic::error("E0001", "invalid token").primary(Span::new(file, location, location + 1), "here")
        }
        // The lexer reports its own errors; the parser never sees LexError.
        ParseError::User { error: LexError } => Diagnostic::error("E0001", "invalid token"),
    }
}

/// `expected one of `;`, `)`` — short lists in full, long ones summarised.
fn describe_expected(expected: &[String]) -> String {
    let items: Vec<String> = expected
        .iter()
        .map(|e| {
            let t = e.trim_matches('"');
            match t {
                "Ident" => "a name".to_string(),
                "IntLit" => "an integer".to_string(),
                "FloatLit" => "a number".to_string(),
                "StrLit" => "a string".to_string(),
                other => format!("`{}`", other.replace("\\\"", "\"")),
            }
        })
        .collect();
    match items.len() {
        0 => "something else".to_string(),
        1 => items[0].clone(),
        n if n <= 6 => format!("one of {}", items.join(", ")),
        _ => format!("one of {}, ...", items[..5].join(", ")),
    }
}
