//! Source files, spans and diagnostics shared by every compiler stage.
//!
//! Every stage reports problems as [`Diagnostic`]s collected in a [`Diagnostics`] sink rather
//! than stopping at the first one. A diagnostic carries a stable code (`E0xxx` for errors,
//! `W0xxx` for warnings), a message naming the construct, and labelled spans; it is rendered
//! only at the edge (the CLI, or a test snapshot) against the [`SourceMap`], rustc-style:
//! `file:line:col` and the underlined source.
//!
//! An unknown name (a variable, function, primitive, parameter, scene command...) gets a
//! "did you mean" help from [`did_you_mean`], the one place that decides what is close
//! enough to suggest.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

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
    /// Byte offset of each line's start (the first is 0), built on first use: every
    /// diagnostic's line and column is a binary search in it, not a scan of the text, so
    /// reporting n problems in a file costs n log n rather than n times the file's size.
    line_starts: OnceLock<Vec<u32>>,
}

impl SourceFile {
    /// Byte offset of each line's start; a line ends after its `\n` (or at the end of text).
    pub fn line_starts(&self) -> &[u32] {
        self.line_starts.get_or_init(|| line_starts_of(&self.text))
    }
    /// 0-based index of the line holding byte `offset` (offsets past the end: the last line).
    pub fn line_index(&self, offset: usize) -> usize {
        let starts = self.line_starts();
        starts.partition_point(|&s| s as usize <= offset) - 1
    }
    /// Byte range of line `line` without its line break.
    pub fn line_range(&self, line: usize) -> (usize, usize) {
        let starts = self.line_starts();
        let start = starts[line] as usize;
        let mut end = starts.get(line + 1).map_or(self.text.len(), |&s| s as usize);
        let bytes = self.text.as_bytes();
        if end > start && bytes[end - 1] == b'\n' {
            end -= 1;
            if end > start && bytes[end - 1] == b'\r' {
                end -= 1;
            }
        }
        (start, end)
    }
}

fn line_starts_of(text: &str) -> Vec<u32> {
    std::iter::once(0)
        .chain(
            text.bytes()
                .enumerate()
                .filter(|&(_, b)| b == b'\n')
                .map(|(i, _)| i as u32 + 1),
        )
        .collect()
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
            line_starts: OnceLock::new(),
        });
        (self.files.len() - 1) as FileId
    }
    pub fn load(&mut self, path: &Path) -> std::io::Result<FileId> {
        let text = std::fs::read_to_string(path)?;
        Ok(self.add_file(path, text))
    }
    /// Add the already read text of the file at `path`.
    pub fn add_file(&mut self, path: &Path, text: String) -> FileId {
        let id = self.add(path.display().to_string(), text);
        self.files[id as usize].path = Some(path.to_path_buf());
        id
    }
    pub fn file(&self, id: FileId) -> &SourceFile {
        &self.files[id as usize]
    }
    pub fn text(&self, id: FileId) -> &str {
        &self.files[id as usize].text
    }
    /// 1-based line and column (in characters) of a byte offset.
    pub fn line_col(&self, file: FileId, offset: u32) -> (usize, usize) {
        let file = self.file(file);
        let text = &file.text;
        let offset = floor_char_boundary(text, (offset as usize).min(text.len()));
        let line = file.line_index(offset);
        let start = file.line_starts()[line] as usize;
        (line + 1, text[start..offset].chars().count() + 1)
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

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Severity {
    Error,
    Warning,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct Label {
    pub span: Span,
    pub message: String,
    /// The primary label is the place the error is; secondary ones explain it.
    pub primary: bool,
}

#[derive(Clone, Debug, PartialEq, Eq, Hash)]
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
    /// For an unknown `name`: help "did you mean `x`?" when one of `candidates` (the names
    /// visible there) is close to it ([`did_you_mean`]); unchanged otherwise.
    pub fn suggest<'c>(self, name: &str, candidates: impl IntoIterator<Item = &'c str>) -> Diagnostic {
        match did_you_mean(name, candidates) {
            Some(help) => self.help(help),
            None => self,
        }
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
    ///
    /// Miette is shown only the lines around the labels (through [`Snippet`], with the file's
    /// line index), never asked to scan the whole file. When a line it would show is longer
    /// than [`LONG_LINE`] bytes, only the primary label's line is shown, cut to a window
    /// around the label: a column past 65,535 made miette's graphical renderer panic, and a
    /// generated line of megabytes is no help on a terminal. Labels outside that window are
    /// listed by location like labels in other files.
    pub fn render(&self, sources: &SourceMap) -> String {
        use miette::{GraphicalReportHandler, GraphicalTheme, LabeledSpan, MietteDiagnostic};
        let Some(primary) = self.primary_span() else {
            let kind = if self.is_error() { "error" } else { "warning" };
            let mut s = format!("{kind}[{}]: {}\n", self.code, self.message);
            if let Some(h) = &self.help {
                s.push_str(&format!("  help: {h}\n"));
            }
            return s;
        };
        let file = sources.file(primary.file);
        let snippet = Snippet::new(file, primary, &self.labels);
        let mut labels = Vec::new();
        let mut elsewhere = Vec::new();
        for l in &self.labels {
            match snippet.place(l) {
                Some((start, len)) => {
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
                }
                None => elsewhere.push(format!("{}: {}", sources.location(l.span), l.message)),
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
        let report = miette::Report::new(d).with_source_code(snippet);
        let mut out = String::new();
        let handler = GraphicalReportHandler::new_themed(GraphicalTheme::unicode_nocolor()).with_width(100);
        if handler.render_report(&mut out, report.as_ref()).is_err() {
            out = self.render_plain(sources);
        }
        out
    }

    /// `error[E0101]: message at file:line:col`: the rendering when the graphical one fails.
    pub fn render_plain(&self, sources: &SourceMap) -> String {
        let kind = if self.is_error() { "error" } else { "warning" };
        match self.primary_span() {
            Some(at) => format!("{kind}[{}]: {} at {}\n", self.code, self.message, sources.location(at)),
            None => format!("{kind}[{}]: {}\n", self.code, self.message),
        }
    }
}

/// Lines longer than this many bytes are shown cut to a window around the primary label
/// (see [`Diagnostic::render`]).
pub const LONG_LINE: usize = 400;
/// Bytes of a long line shown on each side of the primary label, and at most of the label.
const WINDOW_SIDE: usize = 60;
const WINDOW_LABEL: usize = 120;
/// Marks a cut end of a long line.
const CUT: &str = "…";

/// The source text miette is shown for one diagnostic: the whole file (answered from its line
/// index), or one window of a long line (`window` set). Offsets given to miette are in
/// `text`; the line and column it prints are the file's.
struct Snippet {
    file: FileId,
    name: String,
    text: std::sync::Arc<str>,
    /// Line starts of `text`.
    starts: std::sync::Arc<[u32]>,
    /// The window of a long line, when `text` is one.
    window: Option<Window>,
}

/// A window of one long line.
#[derive(Clone, Copy)]
struct Window {
    /// Byte range of the window in the file.
    start: usize,
    end: usize,
    /// The line it is on (0-based).
    line: usize,
    /// Characters of the line before `start`.
    chars_before: usize,
    /// Bytes of [`CUT`] before the window in the snippet's text.
    prefix: usize,
}

impl Snippet {
    fn new(file: &SourceFile, primary: Span, labels: &[Label]) -> Snippet {
        let text = &file.text;
        let clamp = |o: u32| floor_char_boundary(text, (o as usize).min(text.len()));
        // The lines miette would show: each label's lines and one line of context each side.
        let last_line = file.line_starts().len() - 1;
        let long = labels.iter().filter(|l| l.span.file == primary.file).any(|l| {
            let first = file.line_index(clamp(l.span.start)).saturating_sub(1);
            let last = (file.line_index(clamp(l.span.end)) + 1).min(last_line);
            // A label over thousands of lines is shown cut by the window too.
            last - first > 1000 || (first..=last).any(|i| file.line_range(i).1 - file.line_range(i).0 > LONG_LINE)
        });
        if !long {
            return Snippet {
                file: primary.file,
                name: file.name.clone(),
                text: text.as_str().into(),
                starts: file.line_starts().into(),
                window: None,
            };
        }
        let (p_start, p_end) = (clamp(primary.start), clamp(primary.end));
        let line = file.line_index(p_start);
        let (line_start, line_end) = file.line_range(line);
        let p_start = p_start.min(line_end);
        let shown_end = p_end.clamp(p_start, line_end).min(p_start + WINDOW_LABEL);
        let start = floor_char_boundary(text, p_start.saturating_sub(WINDOW_SIDE).max(line_start));
        let end = ceil_char_boundary(text, (shown_end + WINDOW_SIDE).min(line_end));
        let mut shown = String::new();
        if start > line_start {
            shown.push_str(CUT);
        }
        let prefix = shown.len();
        shown.push_str(&text[start..end]);
        if end < line_end {
            shown.push_str(CUT);
        }
        Snippet {
            file: primary.file,
            name: file.name.clone(),
            starts: vec![0].into(),
            text: shown.into(),
            window: Some(Window {
                start,
                end,
                line,
                chars_before: text[line_start..start].chars().count(),
                prefix,
            }),
        }
    }

    /// Where label `l` goes in `text` as (offset, length), or `None` when it is not shown
    /// (another file, or outside the window).
    fn place(&self, l: &Label) -> Option<(usize, usize)> {
        if l.span.file != self.file {
            return None;
        }
        let (start, end) = (l.span.start as usize, l.span.end as usize);
        match self.window {
            None => {
                let file_len = self.text.len();
                let start = start.min(file_len);
                Some((start, end.min(file_len).saturating_sub(start)))
            }
            Some(w) => {
                // The primary label always shows (cut to the window); others only when they
                // start inside it.
                if !l.primary && !(w.start <= start && start < w.end.max(w.start + 1)) {
                    return None;
                }
                let start = start.clamp(w.start, w.end);
                let end = end.clamp(start, w.end);
                Some((start - w.start + w.prefix, end - start))
            }
        }
    }

    /// 0-based line index in `text` of byte `offset`.
    fn line_of(&self, offset: usize) -> usize {
        self.starts.partition_point(|&s| s as usize <= offset) - 1
    }

    /// End of line `line` of `text` after its line break.
    fn line_end(&self, line: usize) -> usize {
        self.starts.get(line + 1).map_or(self.text.len(), |&s| s as usize)
    }
}

impl miette::SourceCode for Snippet {
    /// What miette's `[u8]` implementation answers (the same contents, lines and columns),
    /// from the line index instead of a scan from the start of the file.
    fn read_span<'a>(
        &'a self,
        span: &miette::SourceSpan,
        context_lines_before: usize,
        context_lines_after: usize,
    ) -> Result<Box<dyn miette::SpanContents<'a> + 'a>, miette::MietteError> {
        let (start, len) = (span.offset(), span.len());
        let end = start + len;
        if end > self.text.len() {
            return Err(miette::MietteError::OutOfBounds);
        }
        let first_label_line = self.line_of(start);
        let last_label_line = self.line_of(end.saturating_sub(1).max(start));
        let first = first_label_line.saturating_sub(context_lines_before);
        let last = (last_label_line + context_lines_after).min(self.starts.len() - 1);
        let data_start = if context_lines_before == 0 {
            start
        } else {
            self.starts[first] as usize
        };
        let data_end = if context_lines_after == 0 {
            end
        } else {
            self.line_end(last)
        };
        // Miette counts line breaks from the start of the source up to the end of the data.
        let breaks_before_end = self.starts.partition_point(|&s| (s as usize) <= data_end) - 1;
        let (line, column, line_count) = match self.window {
            None => {
                let column = if context_lines_before == 0 {
                    self.text[self.starts[first_label_line] as usize..start].chars().count()
                } else {
                    0
                };
                (first.min(first_label_line), column, breaks_before_end)
            }
            Some(w) => {
                let column = if context_lines_before == 0 {
                    w.chars_before + self.text[w.prefix.min(start)..start.max(w.prefix)].chars().count()
                } else {
                    0
                };
                (w.line, column, w.line + breaks_before_end)
            }
        };
        Ok(Box::new(miette::MietteSpanContents::new_named(
            self.name.clone(),
            &self.text.as_bytes()[data_start..data_end],
            (data_start, data_end - data_start).into(),
            line,
            column,
            line_count,
        )))
    }
}

fn ceil_char_boundary(s: &str, mut i: usize) -> usize {
    while i < s.len() && !s.is_char_boundary(i) {
        i += 1;
    }
    i
}

/// Names longer than this get no suggestion: the distance takes time and memory of the
/// product of the two lengths, and a generated name of megabytes is no typo.
const MAX_SUGGESTED_LEN: usize = 64;

/// The candidate an unknown `name` was most likely meant to be, as the help text
/// "did you mean `x`?"; `None` when none is close. The rule: a candidate that differs from
/// `name` only in letter case, else the one at the smallest Damerau-Levenshtein distance
/// (one insertion, deletion, substitution or swap of neighbours each), if that distance is
/// at most a third of `name`'s length in characters (so a name of 1 or 2 characters gets
/// no suggestion, one of 3 to 5 a suggestion one edit away, one of 6 to 8 two edits
/// away). Ties go to the alphabetically first, so the answer does not depend on the order
/// of `candidates`. `name` itself is never suggested.
pub fn did_you_mean<'c>(name: &str, candidates: impl IntoIterator<Item = &'c str>) -> Option<String> {
    let len = name.chars().count();
    if len > MAX_SUGGESTED_LEN {
        return None;
    }
    let limit = len / 3;
    let mut best: Option<(usize, &str)> = None;
    for c in candidates {
        // The distance is at least the difference in length (counted no further than
        // that needs: a candidate may be a generated name of megabytes).
        if c == name || c.chars().take(len + limit + 1).count().abs_diff(len) > limit {
            continue;
        }
        let distance = if c.eq_ignore_ascii_case(name) {
            0
        } else {
            strsim::damerau_levenshtein(name, c)
        };
        if distance <= limit && best.is_none_or(|b| (distance, c) < b) {
            best = Some((distance, c));
        }
    }
    best.map(|(_, c)| format!("did you mean `{c}`?"))
}

/// The most errors a [`Diagnostics`] sink keeps. The next one is replaced by an `E0099`
/// "too many errors" at its place, and any after it are only counted ([`Diagnostics::error_count`]
/// still tells them all): a generated file with a mistake on every line reports a screenful,
/// not a million lines.
pub const MAX_ERRORS: usize = 1000;

/// A sink of diagnostics: every stage pushes here and goes on where it can.
#[derive(Clone, Debug, Default)]
pub struct Diagnostics {
    pub items: Vec<Diagnostic>,
    /// Errors pushed (kept or not).
    errors: usize,
}

impl Diagnostics {
    pub fn new() -> Diagnostics {
        Diagnostics::default()
    }
    pub fn push(&mut self, d: Diagnostic) {
        if d.is_error() {
            self.errors += 1;
            if self.errors > MAX_ERRORS {
                if self.errors == MAX_ERRORS + 1 {
                    let mut notice = Diagnostic::error(
                        "E0099",
                        format!("too many errors: the first {MAX_ERRORS} are shown; this one and any after it are counted only"),
                    );
                    if let Some(at) = d.primary_span() {
                        notice = notice.primary(at, format!("error {} was [{}] {}", MAX_ERRORS + 1, d.code, d.message));
                    }
                    self.items.push(notice);
                }
                return;
            }
        }
        self.items.push(d);
    }
    pub fn extend(&mut self, other: Diagnostics) {
        for d in other.items {
            self.push(d);
        }
        // Errors `other` itself only counted.
        self.errors += other.errors.saturating_sub(MAX_ERRORS + 1);
    }
    pub fn has_errors(&self) -> bool {
        self.errors > 0 || self.items.iter().any(|d| d.is_error())
    }
    /// Errors reported, including those past [`MAX_ERRORS`] that were only counted.
    pub fn error_count(&self) -> usize {
        let kept = self.items.iter().filter(|d| d.is_error()).count();
        kept.max(self.errors)
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
