//! Front end: the logos lexer ([`lexer`]) and the lalrpop grammar (`grammar/primflow.lalrpop`,
//! built by build.rs) turn source text into an [`ast::Module`].
//!
//! Syntax errors have codes `E00xx`. The grammar recovers at statement (`;`) and item (`}`)
//! boundaries, so one parse reports several errors; an unrecoverable error (end of file in
//! the middle of an item) still returns the items parsed before it. After this point every
//! node has a span and names are as written: nothing is resolved yet, and the tree is within
//! the depth limits of [`crate::limits`] ([`limits::enforce`]). [`print`] writes a tree as
//! indented text (`primflow check --emit ast`).

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
    let (module, last) = match result {
        Ok(module) => (module, None),
        Err(e) => (ast::Module::default(), Some(e)),
    };
    let recovered_count = recovered.len();
    let errors = recovered.into_iter().map(|r| r.error).chain(last);
    let mut syntax = syntax_errors(file, text, errors.collect()).into_iter();
    // The recovered errors, the grammar's own, then the one that ended the parse.
    syntax.by_ref().take(recovered_count).for_each(|d| diags.push(d));
    extra.into_iter().for_each(|d| diags.push(d));
    syntax.for_each(|d| diags.push(d));
    module
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
            let errors = recovered.into_iter().map(|r| r.error).collect();
            syntax_errors(file, text, errors)
                .into_iter()
                .for_each(|d| diags.push(d));
            None
        }
        Err(e) => {
            syntax_errors(file, text, vec![e])
                .into_iter()
                .for_each(|d| diags.push(d));
            None
        }
    }
}

type SyntaxError = ParseError<usize, Tok, LexError>;

/// The diagnostics of the parser's `errors`, in order. Where a `;` could have ended what came
/// before an unexpected token on a later line, the error points at the end of the token
/// before it, as a missing `;` (one lexer pass over the file finds those ends, only when
/// some error needs one).
fn syntax_errors(file: FileId, text: &str, errors: Vec<SyntaxError>) -> Vec<Diagnostic> {
    let mut wanted: Vec<usize> = errors
        .iter()
        .filter_map(|e| match e {
            ParseError::UnrecognizedToken {
                token: (l, _, _),
                expected,
            } if expects_semicolon(expected) => Some(*l),
            _ => None,
        })
        .collect();
    wanted.sort_unstable();
    wanted.dedup();
    let ends = token_ends_before(file, text, &wanted);
    errors
        .into_iter()
        .map(|e| {
            let before = match &e {
                ParseError::UnrecognizedToken { token: (l, _, _), .. } => wanted
                    .binary_search(l)
                    .ok()
                    .and_then(|i| ends[i])
                    // Only across a line break: on the same line the unexpected token is
                    // the clearer place.
                    .filter(|&end| text.get(end..*l).is_some_and(|gap| gap.contains('\n'))),
                _ => None,
            };
            parse_error(file, text, e, before)
        })
        .collect()
}

fn expects_semicolon(expected: &[String]) -> bool {
    expected.iter().any(|x| x == "\";\"")
}

/// For each offset of `starts` (sorted; each the start of a token), the end of the token
/// before it, if any: one pass of the lexer over the text up to the last of them.
fn token_ends_before(file: FileId, text: &str, starts: &[usize]) -> Vec<Option<usize>> {
    let Some(&last) = starts.last() else {
        return vec![];
    };
    // Its lexical errors were reported by the parse.
    let mut scratch = Diagnostics::new();
    let mut ends = Vec::with_capacity(starts.len());
    let mut previous_end = None;
    let mut pending = starts.iter().peekable();
    for (start, _, end) in lexer::lex(file, text.get(..last).unwrap_or(text), &mut scratch) {
        while pending.next_if(|&&s| s <= start).is_some() {
            ends.push(previous_end);
        }
        previous_end = Some(end);
    }
    ends.resize(starts.len(), previous_end);
    ends
}

/// The diagnostic of one syntax error; `missing_semicolon_at`: the end of the token before
/// the unexpected one, where a `;` would have ended the statement (see [`syntax_errors`]).
fn parse_error(file: FileId, text: &str, e: SyntaxError, missing_semicolon_at: Option<usize>) -> Diagnostic {
    match e {
        ParseError::UnrecognizedToken {
            token: (l, tok, r),
            expected,
        } => {
            if let Some(at) = missing_semicolon_at {
                return Diagnostic::error("E0011", format!("expected `;`, found {tok}"))
                    .primary(Span::new(file, at, at), "expected `;` here")
                    .secondary(Span::new(file, l, r), format!("unexpected {tok}"))
                    .help("a statement must end with `;`: add one at the end of the line");
            }
            let d = Diagnostic::error("E0011", format!("unexpected {tok}")).primary(
                Span::new(file, l, r),
                format!("expected {}", describe_expected(&expected)),
            );
            match tok {
                Tok::RBrace | Tok::RParen if expects_semicolon(&expected) => d.help("a statement must end with `;`"),
                Tok::Comma if expected.len() == 1 && expected[0] == "\")\"" => d.help(
                    "parentheses hold one expression; several values are a list `{1, 2, 3}` or a constructor such as `color(1, 2, 3)`",
                ),
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
