//! The logos lexer. [`lex`] turns a whole file into `(start, Tok, end)` triples for the
//! lalrpop parser, reporting bad characters and malformed numbers (E0001, E0002) as it goes
//! and skipping them, so the parser only ever sees valid tokens.

use logos::Logos;

use crate::diag::{Diagnostic, Diagnostics, FileId, Span};

#[derive(Logos, Clone, Debug, PartialEq)]
#[logos(skip r"[ \t\r\n\f]+")]
#[logos(skip(r"//[^\n]*", allow_greedy = true))]
#[logos(skip r"/\*([^*]|\*+[^*/])*\*+/")]
pub enum Tok {
    #[token("primitive")]
    Primitive,
    #[token("interpolator")]
    Interpolator,
    #[token("uniform")]
    Uniform,
    #[token("varying")]
    Varying,
    #[token("inout")]
    Inout,
    #[token("float")]
    Float,
    #[token("int")]
    Int,
    #[token("bool")]
    Bool,
    #[token("fixed")]
    Fixed,
    // Figure 6 writes `Point`.
    #[token("point")]
    #[token("Point")]
    Point,
    #[token("vector")]
    Vector,
    #[token("normal")]
    Normal,
    #[token("color")]
    Color,
    #[token("matrix")]
    Matrix,
    // The paper uses both spellings.
    #[token("interpolation_data")]
    #[token("interpolator_data")]
    InterpolationData,
    #[token("string")]
    String,
    #[token("void")]
    Void,
    #[token("if")]
    If,
    #[token("else")]
    Else,
    #[token("for")]
    For,
    #[token("while")]
    While,
    #[token("break")]
    Break,
    #[token("continue")]
    Continue,
    #[token("return")]
    Return,
    #[token("interpolation")]
    Interpolation,
    // The paper's prose calls it `interpolation_return` once.
    #[token("interpolator_return")]
    #[token("interpolation_return")]
    InterpolatorReturn,
    #[token("default")]
    Default,
    #[token("bound")]
    Bound,
    #[token("true")]
    True,
    #[token("false")]
    False,

    #[regex(r"[A-Za-z_][A-Za-z0-9_]*", |lex| lex.slice().to_string())]
    Ident(std::string::String),
    #[regex(r"[0-9]+", |lex| lex.slice().parse::<i64>().ok())]
    IntLit(i64),
    #[regex(r"([0-9]+\.[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?[fF]?", parse_float)]
    #[regex(r"[0-9]+[eE][+-]?[0-9]+[fF]?", parse_float)]
    #[regex(r"[0-9]+[fF]", parse_float)]
    FloatLit(f64),
    #[regex(r#""[^"\n]*""#, |lex| { let s = lex.slice(); s[1..s.len() - 1].to_string() })]
    StrLit(std::string::String),

    #[token("(")]
    LParen,
    #[token(")")]
    RParen,
    #[token("{")]
    LBrace,
    #[token("}")]
    RBrace,
    #[token("[")]
    LBracket,
    #[token("]")]
    RBracket,
    #[token(";")]
    Semi,
    #[token(",")]
    Comma,
    #[token(":")]
    Colon,
    #[token("?")]
    Question,
    #[token("<")]
    Lt,
    #[token(">")]
    Gt,
    #[token("<=")]
    Le,
    #[token(">=")]
    Ge,
    #[token("==")]
    EqEq,
    #[token("!=")]
    Ne,
    #[token("=")]
    Assign,
    #[token("+=")]
    PlusAssign,
    #[token("-=")]
    MinusAssign,
    #[token("*=")]
    StarAssign,
    #[token("/=")]
    SlashAssign,
    #[token("++")]
    PlusPlus,
    #[token("--")]
    MinusMinus,
    #[token("+")]
    Plus,
    #[token("-")]
    Minus,
    #[token("*")]
    Star,
    #[token("/")]
    Slash,
    #[token("%")]
    Percent,
    #[token("&&")]
    AndAnd,
    #[token("||")]
    OrOr,
    #[token("!")]
    Bang,
}

fn parse_float(lex: &mut logos::Lexer<Tok>) -> Option<f64> {
    lex.slice().trim_end_matches(['f', 'F']).parse::<f64>().ok()
}

impl std::fmt::Display for Tok {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Tok::Ident(s) => write!(f, "identifier `{s}`"),
            Tok::IntLit(i) => write!(f, "integer `{i}`"),
            Tok::FloatLit(x) => write!(f, "number `{x}`"),
            Tok::StrLit(s) => write!(f, "string \"{s}\""),
            other => write!(f, "`{}`", token_text(other)),
        }
    }
}

/// The source text of a fixed token, for messages.
pub fn token_text(t: &Tok) -> &'static str {
    use Tok::*;
    match t {
        Primitive => "primitive",
        Interpolator => "interpolator",
        Uniform => "uniform",
        Varying => "varying",
        Inout => "inout",
        Float => "float",
        Int => "int",
        Bool => "bool",
        Fixed => "fixed",
        Point => "point",
        Vector => "vector",
        Normal => "normal",
        Color => "color",
        Matrix => "matrix",
        InterpolationData => "interpolation_data",
        String => "string",
        Void => "void",
        If => "if",
        Else => "else",
        For => "for",
        While => "while",
        Break => "break",
        Continue => "continue",
        Return => "return",
        Interpolation => "interpolation",
        InterpolatorReturn => "interpolator_return",
        Default => "default",
        Bound => "bound",
        True => "true",
        False => "false",
        Ident(_) => "identifier",
        IntLit(_) => "integer",
        FloatLit(_) => "number",
        StrLit(_) => "string",
        LParen => "(",
        RParen => ")",
        LBrace => "{",
        RBrace => "}",
        LBracket => "[",
        RBracket => "]",
        Semi => ";",
        Comma => ",",
        Colon => ":",
        Question => "?",
        Lt => "<",
        Gt => ">",
        Le => "<=",
        Ge => ">=",
        EqEq => "==",
        Ne => "!=",
        Assign => "=",
        PlusAssign => "+=",
        MinusAssign => "-=",
        StarAssign => "*=",
        SlashAssign => "/=",
        PlusPlus => "++",
        MinusMinus => "--",
        Plus => "+",
        Minus => "-",
        Star => "*",
        Slash => "/",
        Percent => "%",
        AndAnd => "&&",
        OrOr => "||",
        Bang => "!",
    }
}

/// Never produced: lexical errors are reported by [`lex`] and the bad text skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct LexError;

/// Lex a whole file. Bad characters and numbers out of range are reported and skipped.
pub fn lex(file: FileId, text: &str, diags: &mut Diagnostics) -> Vec<(usize, Tok, usize)> {
    // The library's files have one token per 5-8 bytes: reserve for the densest so the
    // vector is not regrown (and copied) on the way.
    let mut out = Vec::with_capacity(text.len() / 4);
    let mut lexer = Tok::lexer(text);
    // Merge runs of bad characters into one diagnostic.
    let mut bad: Option<(usize, usize)> = None;
    let flush = |bad: &mut Option<(usize, usize)>, diags: &mut Diagnostics| {
        if let Some((s, e)) = bad.take() {
            let what = &text[s..e];
            let d = if what.starts_with('"') {
                Diagnostic::error("E0003", "unterminated string literal")
                    .primary(Span::new(file, s, e), "no closing `\"` on this line")
            } else {
                Diagnostic::error(
                    "E0001",
                    format!(
                        "unexpected character{} `{}`",
                        if e - s > 1 { "s" } else { "" },
                        what.escape_debug()
                    ),
                )
                .primary(Span::new(file, s, e), "not part of the language")
            };
            diags.push(d);
        }
    };
    while let Some(tok) = lexer.next() {
        let span = lexer.span();
        match tok {
            // A `/*` the skip rule did not consume has no `*/`: the rest is an open comment.
            Ok(Tok::Slash) if text[span.end..].starts_with('*') => {
                flush(&mut bad, diags);
                diags.push(Diagnostic::error("E0003", "unterminated block comment").primary(
                    Span::new(file, span.start, span.end + 1),
                    "this comment is never closed",
                ));
                break;
            }
            Ok(t) => {
                flush(&mut bad, diags);
                out.push((span.start, t, span.end));
            }
            Err(()) => {
                let slice = lexer.slice();
                if slice.chars().all(|c| c.is_ascii_digit())
                    || slice.contains(['.', 'e', 'E']) && slice.starts_with(|c: char| c.is_ascii_digit())
                {
                    flush(&mut bad, diags);
                    diags.push(
                        Diagnostic::error("E0002", "number literal out of range")
                            .primary(Span::new(file, span.start, span.end), "does not fit in 64 bits"),
                    );
                    out.push((span.start, Tok::IntLit(0), span.end));
                    continue;
                }
                match &mut bad {
                    Some((_, e)) if *e == span.start => *e = span.end,
                    _ => {
                        flush(&mut bad, diags);
                        bad = Some((span.start, span.end));
                    }
                }
            }
        }
    }
    flush(&mut bad, diags);
    out
}
