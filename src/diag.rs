//! Source files, spans and diagnostics shared by every compiler stage.
//!
//! Every stage reports problems as [`Diagnostic`]s collected in a [`Diagnostics`] sink rather
//! than stopping at the first one. A diagnostic carries a stable code (`E0xxx` for errors,
//! `W0xxx` for warnings), a message naming the construct, and labelled spans; it is rendered
//! only at the edge (the CLI, or a test snapshot) against the [`SourceMap`], rustc-style:
//! `file:line:col` and the underlined source.

use std::fmt;
use std::path::{Path, PathBuf};

/// Index of a file in the [`SourceMap`].
pub type FileId = u32;

/// A byte range in one source file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Span {
    pub file: FileId,
    pub start: u32,
    pub end: u32,
}

impl Span {
    pub fn new(file: FileId, start: usize, end: usize) -> Span {
        Span {
            file,
            start: start as u32,
            end: end as u32,
        }
    }
    /// The smallest span covering both (same file assumed; falls back to `self`).
    pub fn to(self, other: Span) -> Span {
        if self.file != other.file {
            return self;
        }
        Span {
            file: self.file,
            start: self.start.min(other.start),
            end: self.end.max(other.end),
        }
    }
    pub fn len(&self) -> usize {
        (self.end - self.start) as usize
    }
    pub fn is_empty(&self) -> bool {
        self.end == self.start
    }
}

/// One loaded source file.
#[derive(Clone, Debug)]
pub struct SourceFile {
    pub name: String,
    pub path: Option<PathBuf>,
    pub text: String,
}

/// All source files of a compilation (the prims/ directory, user directories, a scene file).
#[derive(Clone, Debug, Default)]
pub struct SourceMap {
    pub files: Vec<SourceFile>,
}

impl SourceMap {
    pub fn new() -> SourceMap {
        SourceMap::default()
    }
    pub fn add(&mut self, name: impl Into<String>, text: impl Into<String>) -> FileId {
        self.files.push(SourceFile {
            name: name.into(),
            path: None,
            text: text.into(),
        });
        (self.files.len() - 1) as FileId
    }
    pub fn load(&mut self, path: &Path) -> std::io::Result<FileId> {
        let text = std::fs::read_to_string(path)?;
        let id = self.add(path.display().to_string(), text);
        self.files[id as usize].path = Some(path.to_path_buf());
        Ok(id)
    }
    pub fn file(&self, id: FileId) -> &SourceFile {
        &self.files[id as usize]
    }
    pub fn text(&self, id: FileId) -> &str {
        &self.files[id as usize].text
    }
    /// 1-based line and column (in characters) of a byte offset.
    pub fn line_col(&self, file: FileId, offset: u32) -> (usize, usize) {
        let text = self.text(file);
        let offset = (offset as usize).min(text.len());
        let before = &text[..floor_char_boundary(text, offset)];
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        (line, col)
    }
    /// `file:line:col` of the start of a span.
    pub fn location(&self, span: Span) -> String {
        let (l, c) = self.line_col(span.file, span.start);
        format!("{}:{}:{}", self.file(span.file).name, l, c)
    }
}

fn floor_char_boundary(s: &str, mut i: usize) -> usize {
    while i > 0 && !s.is_char_boundary(i) {
        i -= 1;
    }
    i
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Severity {
    Error,
    Warning,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Label {
    pub span: Span,
    pub message: String,
    /// The primary label is the place the error is; secondary ones explain it.
    pub primary: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostic {
    pub severity: Severity,
    /// Stable code, e.g. `E0101`. Listed in docs/language.md.
    pub code: &'static str,
    pub message: String,
    pub labels: Vec<Label>,
    pub help: Option<String>,
}

impl Diagnostic {
    pub fn error(code: &'static str, message: impl Into<String>) -> Diagnostic {
        Diagnostic {
            severity: Severity::Error,
            code,
            message: message.into(),
            labels: vec![],
            help: None,
        }
    }
    pub fn warning(code: &'static str, message: impl Into<String>) -> Diagnostic {
        Diagnostic {
            severity: Severity::Warning,
            code,
            message: message.into(),
            labels: vec![],
            help: None,
        }
    }
    /// The place the problem is.
    pub fn primary(mut self, span: Span, message: impl Into<String>) -> Diagnostic {
        self.labels.push(Label {
            span,
            message: message.into(),
            primary: true,
        });
        self
    }
    /// Another place that explains it (where a value became varying, a first declaration...).
    pub fn secondary(mut self, span: Span, message: impl Into<String>) -> Diagnostic {
        self.labels.push(Label {
            span,
            message: message.into(),
            primary: false,
        });
        self
    }
    pub fn help(mut self, help: impl Into<String>) -> Diagnostic {
        self.help = Some(help.into());
        self
    }
    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
    pub fn primary_span(&self) -> Option<Span> {
        self.labels
            .iter()
            .find(|l| l.primary)
            .or(self.labels.first())
            .map(|l| l.span)
    }

    /// Render rustc-style with miette: `error[E0101]: message`, `--> file:line:col`, the
    /// underlined source and the labels. Labels in other files than the primary one are
    /// listed by location below.
    pub fn render(&self, sources: &SourceMap) -> String {
        use miette::{GraphicalReportHandler, GraphicalTheme, LabeledSpan, MietteDiagnostic, NamedSource};
        let Some(primary) = self.primary_span() else {
            let kind = if self.is_error() { "error" } else { "warning" };
            let mut s = format!("{kind}[{}]: {}\n", self.code, self.message);
            if let Some(h) = &self.help {
                s.push_str(&format!("  help: {h}\n"));
            }
            return s;
        };
        let file = sources.file(primary.file);
        let mut labels = Vec::new();
        let mut elsewhere = Vec::new();
        for l in &self.labels {
            if l.span.file == primary.file {
                let start = (l.span.start as usize).min(file.text.len());
                let len = (l.span.len()).min(file.text.len() - start);
                let msg = if l.message.is_empty() {
                    None
                } else {
                    Some(l.message.clone())
                };
                labels.push(if l.primary {
                    LabeledSpan::new_primary_with_span(msg, (start, len))
                } else {
                    LabeledSpan::new_with_span(msg, (start, len))
                });
            } else {
                elsewhere.push(format!("{}: {}", sources.location(l.span), l.message));
            }
        }
        let mut help = self.help.clone().unwrap_or_default();
        for e in elsewhere {
            if !help.is_empty() {
                help.push('\n');
            }
            help.push_str(&format!("see {e}"));
        }
        let mut d = MietteDiagnostic::new(format!("{} ({})", self.message, sources.location(primary)))
            .with_code(self.code)
            .with_severity(match self.severity {
                Severity::Error => miette::Severity::Error,
                Severity::Warning => miette::Severity::Warning,
            })
            .with_labels(labels);
        if !help.is_empty() {
            d = d.with_help(help);
        }
        let report = miette::Report::new(d).with_source_code(NamedSource::new(file.name.clone(), file.text.clone()));
        let mut out = String::new();
        let handler = GraphicalReportHandler::new_themed(GraphicalTheme::unicode_nocolor()).with_width(100);
        if handler.render_report(&mut out, report.as_ref()).is_err() {
            out = format!(
                "{}[{}]: {} at {}\n",
                if self.is_error() { "error" } else { "warning" },
                self.code,
                self.message,
                sources.location(primary)
            );
        }
        out
    }
}

/// A sink of diagnostics: every stage pushes here and goes on where it can.
#[derive(Clone, Debug, Default)]
pub struct Diagnostics {
    pub items: Vec<Diagnostic>,
}

impl Diagnostics {
    pub fn new() -> Diagnostics {
        Diagnostics::default()
    }
    pub fn push(&mut self, d: Diagnostic) {
        self.items.push(d);
    }
    pub fn extend(&mut self, other: Diagnostics) {
        self.items.extend(other.items);
    }
    pub fn has_errors(&self) -> bool {
        self.items.iter().any(|d| d.is_error())
    }
    pub fn error_count(&self) -> usize {
        self.items.iter().filter(|d| d.is_error()).count()
    }
    /// `code@line:col` per diagnostic, for compact test assertions.
    pub fn codes_at(&self, sources: &SourceMap) -> Vec<String> {
        self.items
            .iter()
            .map(|d| match d.primary_span() {
                Some(s) => {
                    let (l, c) = sources.line_col(s.file, s.start);
                    format!("{}@{}:{}", d.code, l, c)
                }
                None => d.code.to_string(),
            })
            .collect()
    }
    pub fn render(&self, sources: &SourceMap) -> String {
        self.items
            .iter()
            .map(|d| d.render(sources))
            .collect::<Vec<_>>()
            .join("\n")
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[{}] {}", self.code, self.message)
    }
}
