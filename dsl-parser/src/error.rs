//! Diagnostics of the front end.
//!
//! Every error carries the model source, a labelled span and a `help` that says what to do,
//! so that a rendered report shows `file.dyn:line:column` and the offending text. All errors
//! of a file are collected into one [`CompileErrors`].

use crate::ir::Span;
use miette::{Diagnostic, NamedSource, SourceSpan};
use std::sync::Arc;
use thiserror::Error;

/// The model source as carried by every diagnostic.
pub type Source = NamedSource<Arc<str>>;

macro_rules! error_kinds {
    ($( $(#[$doc:meta])* $variant:ident => $code:literal, )*) => {
        /// One diagnostic. All kinds share the same fields: a message, a primary label, an
        /// optional secondary label (e.g. "first declared here"), a help and the source.
        #[derive(Debug, Error, Diagnostic)]
        pub enum CompileError {
            $(
                $(#[$doc])*
                #[error("{message}")]
                #[diagnostic(code($code))]
                $variant {
                    message: String,
                    #[label(primary, "{label}")]
                    span: Option<SourceSpan>,
                    label: String,
                    #[label("{other_label}")]
                    other: Option<SourceSpan>,
                    other_label: String,
                    #[help]
                    help: String,
                    #[source_code]
                    src: Source,
                },
            )*
        }

        /// The kind of a [`CompileError`], one per diagnostic code.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum ErrorKind { $( $(#[$doc])* $variant, )* }

        impl ErrorKind {
            /// The diagnostic code, e.g. `dyn::undefined_name`.
            pub fn code(self) -> &'static str {
                match self { $( ErrorKind::$variant => $code, )* }
            }
            /// Every kind, in declaration order.
            pub const ALL: &'static [ErrorKind] = &[ $( ErrorKind::$variant, )* ];
        }

        impl CompileError {
            pub fn kind(&self) -> ErrorKind {
                match self { $( CompileError::$variant { .. } => ErrorKind::$variant, )* }
            }
            /// The primary span (byte range in the source), if the error has one.
            pub fn span(&self) -> Option<Span> {
                match self {
                    $( CompileError::$variant { span, .. } =>
                        span.map(|s| Span::new(s.offset(), s.offset() + s.len())), )*
                }
            }
            pub fn message(&self) -> &str {
                match self { $( CompileError::$variant { message, .. } => message, )* }
            }
            pub fn help_text(&self) -> &str {
                match self { $( CompileError::$variant { help, .. } => help, )* }
            }

            pub(crate) fn build(kind: ErrorKind, d: Draft, src: Source) -> CompileError {
                let Draft { message, span, label, other, other_label, help } = d;
                let span = span.map(to_source_span);
                let other = other.map(to_source_span);
                match kind {
                    $( ErrorKind::$variant => CompileError::$variant {
                        message, span, label, other, other_label, help, src,
                    }, )*
                }
            }
        }
    };
}

error_kinds! {
    /// The text does not match the grammar.
    Syntax => "dyn::syntax",
    /// The model file could not be read.
    Io => "dyn::io",
    /// A name is declared twice.
    DuplicateName => "dyn::duplicate_name",
    /// A name is used but never declared.
    UndefinedName => "dyn::undefined_name",
    /// A reserved word (`ground`, `s`, `v`, `t`, a function or keyword) is used as a name.
    ReservedName => "dyn::reserved_name",
    /// A signal suffix other than `.x` or `.v`, or a signal where a body is expected.
    InvalidSignal => "dyn::invalid_signal",
    /// An unknown function or a wrong number of arguments.
    InvalidCall => "dyn::invalid_call",
    /// A parameter that does not enter its term as a plain factor.
    NonlinearParameter => "dyn::nonlinear_parameter",
    /// A gap, limit or exponent that is not a numeric constant.
    NonConstantArgument => "dyn::non_constant_argument",
    /// A term whose basis depends on no signal (a constant force).
    ConstantTerm => "dyn::constant_term",
    /// A force that depends on time `t`.
    TimeDependent => "dyn::time_dependent",
    /// A parameter declared with `param` and used by no element.
    UnusedParameter => "dyn::unused_parameter",
    /// A body declared without a mass.
    MissingMass => "dyn::missing_mass",
    /// An element connected to itself or to ground at both ends, or an input on ground.
    InvalidConnection => "dyn::invalid_connection",
    /// A term that needs a signal the data does not contain.
    UnmeasuredSignal => "dyn::unmeasured_signal",
    /// A nonlinear term in the motion of a body measured only by its acceleration.
    /// No unknown parameter: nothing to identify.
    NothingToIdentify => "dyn::nothing_to_identify",
    /// Every coefficient is unknown, so the overall scale cannot be identified.
    NoKnownScale => "dyn::no_known_scale",
    /// `excite` names something that is not an input.
    UnknownInput => "dyn::unknown_input",
    /// Two `excite` lines for the same input.
    DuplicateExcitation => "dyn::duplicate_excitation",
    /// `excite` lines with different numbers of levels.
    LevelCountMismatch => "dyn::level_count_mismatch",
    /// A control law that cannot be simulated: an unknown gain, an input or `s`/`v` read by
    /// the law, an excited or twice-controlled input, a reference read by a force.
    InvalidControl => "dyn::invalid_control",
    /// A value out of its range (mass ≤ 0, corner ≤ 0, unknown form-filter argument …).
    InvalidValue => "dyn::invalid_value",
}

fn to_source_span(s: Span) -> SourceSpan {
    SourceSpan::new(s.start.into(), s.end.saturating_sub(s.start))
}

/// The fields of an error before the source is attached.
#[derive(Default)]
pub(crate) struct Draft {
    pub message: String,
    pub span: Option<Span>,
    pub label: String,
    pub other: Option<Span>,
    pub other_label: String,
    pub help: String,
}

/// Collects the errors of one file.
pub(crate) struct ErrorSink {
    /// The source as the diagnostics show it: invisible and control characters replaced by
    /// visible ones of the same byte length ([`crate::text::visible`]), so that an excerpt
    /// cannot act on the terminal and every span stays valid.
    pub src: Source,
    /// The source as written, for quoting offending text (escaped) in messages.
    pub text: Arc<str>,
    pub errors: Vec<CompileError>,
}

impl ErrorSink {
    pub fn new(name: &str, source: &str) -> Self {
        let shown = crate::text::visible(source);
        ErrorSink {
            src: NamedSource::new(name, Arc::from(shown)).with_language("dyn"),
            text: Arc::from(source),
            errors: Vec::new(),
        }
    }
    pub fn push(&mut self, e: CompileError) {
        self.errors.push(e);
    }
    /// Record an error with a primary label.
    pub fn error(
        &mut self,
        kind: ErrorKind,
        message: impl Into<String>,
        span: Span,
        label: impl Into<String>,
        help: impl Into<String>,
    ) {
        let d = Draft {
            message: message.into(),
            span: Some(span),
            label: label.into(),
            help: help.into(),
            ..Draft::default()
        };
        self.errors
            .push(CompileError::build(kind, d, self.src.clone()));
    }
    pub fn draft(&mut self, kind: ErrorKind, d: Draft) {
        self.errors
            .push(CompileError::build(kind, d, self.src.clone()));
    }
}

impl CompileError {
    pub(crate) fn syntax(sink: &ErrorSink, message: String, span: Span, help: String) -> Self {
        let d = Draft {
            message,
            span: Some(span),
            label: "here".into(),
            help,
            ..Draft::default()
        };
        CompileError::build(ErrorKind::Syntax, d, sink.src.clone())
    }
    pub(crate) fn invalid_value(
        sink: &ErrorSink,
        message: String,
        span: Span,
        help: String,
    ) -> Self {
        let d = Draft {
            message,
            span: Some(span),
            label: "this value".into(),
            help,
            ..Draft::default()
        };
        CompileError::build(ErrorKind::InvalidValue, d, sink.src.clone())
    }
}

/// All errors of one model file.
#[derive(Debug, Error, Diagnostic)]
#[error("could not compile `{name}`: {}", count(.errors.len()))]
#[diagnostic(code("dyn::compile"))]
pub struct CompileErrors {
    pub name: String,
    #[source_code]
    pub src: Source,
    #[related]
    pub errors: Vec<CompileError>,
}

fn count(n: usize) -> String {
    if n == 1 {
        "1 error".into()
    } else {
        format!("{n} errors")
    }
}

impl CompileErrors {
    pub fn kinds(&self) -> Vec<ErrorKind> {
        self.errors.iter().map(|e| e.kind()).collect()
    }
    /// Render all diagnostics as plain text (no colours, fixed width): for logs and tests.
    #[cfg(feature = "render")]
    pub fn render_plain(&self, width: usize) -> String {
        let handler =
            miette::GraphicalReportHandler::new_themed(miette::GraphicalTheme::unicode_nocolor())
                .with_width(width);
        let mut out = String::new();
        // Render each error on its own so the output does not depend on how the
        // handler nests related diagnostics.
        for e in &self.errors {
            let _ = handler.render_report(&mut out, e);
        }
        out
    }
}
