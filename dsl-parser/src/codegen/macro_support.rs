//! The expansion logic of `include_model!` and `model!`, kept here (not in the proc-macro
//! crate) so that it can be unit-tested and the macro crate stays a thin shim.
//!
//! The parser is passed in as a function, `compile(name, source)`, returning the IR or the
//! list of diagnostics; the diagnostics are used only through [`miette::Diagnostic`], whose
//! labels are byte offsets into `source`.

use super::naming::model_name_hint;
use super::{error_stub, generate, CodegenOptions};
use crate::ir::ModelIr;
use miette::Diagnostic;
use proc_macro2::{Delimiter, Span, TokenStream, TokenTree};
use quote::quote;
use std::fmt::Write as _;
use std::path::Path;

/// 1-based line and column (in characters) of byte `offset` in `source`.
pub fn line_col(source: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(source.len());
    while !source.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &source[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() + 1)
}

/// A diagnostic flattened into the text of a `compile_error!`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RenderedError {
    /// Byte range of the primary label in the source, if the diagnostic has one.
    pub range: Option<std::ops::Range<usize>>,
    pub message: String,
}

/// Render `diag` as `file:line:col: message [code]`, the offending source line with a
/// caret under the labelled span, and the help. Without a `file` (the `model!` macro, whose
/// error already sits on the offending token) the location and source line are left out.
pub fn render(diag: &dyn Diagnostic, source: &str, file: Option<&str>) -> RenderedError {
    let labels: Vec<_> = diag.labels().map(|l| l.collect()).unwrap_or_default();
    let label = labels
        .iter()
        .find(|l| l.primary())
        .or_else(|| labels.first());
    let mut msg = String::new();
    match (file, label) {
        (Some(file), Some(l)) => {
            let (line, col) = line_col(source, l.offset());
            let _ = write!(msg, "{file}:{line}:{col}: ");
        }
        (Some(file), None) => {
            let _ = write!(msg, "{file}: ");
        }
        (None, _) => {}
    }
    let _ = write!(msg, "{diag}");
    if let Some(code) = diag.code() {
        let _ = write!(msg, " [{code}]");
    }
    if let Some(l) = label {
        if file.is_some() {
            msg.push('\n');
            msg.push_str(&snippet(source, l.offset(), l.len(), l.label()));
        } else if let Some(text) = l.label() {
            let _ = write!(msg, "\n  {text}");
        }
    }
    if let Some(help) = diag.help() {
        let _ = write!(msg, "\n  = help: {help}");
    }
    RenderedError {
        range: label.map(|l| l.offset()..l.offset() + l.len()),
        message: msg,
    }
}

/// The source line holding `offset`, underlined from there for `len` bytes (on that line).
fn snippet(source: &str, offset: usize, len: usize, label: Option<&str>) -> String {
    let (line, col) = line_col(source, offset);
    let text = source.lines().nth(line - 1).unwrap_or("");
    let width = line.to_string().len();
    let start = offset.min(source.len());
    let end = (start + len).min(source.len());
    let underlined = source
        .get(start..end)
        .map_or(1, |s| s.split('\n').next().unwrap_or("").chars().count())
        .max(1);
    let mut out = format!(
        "{:width$} |\n{line} | {text}\n{:width$} | {}{}",
        "",
        "",
        " ".repeat(col - 1),
        "^".repeat(underlined)
    );
    if let Some(label) = label {
        let _ = write!(out, " {label}");
    }
    out
}

/// The `.dyn` text of a `model! { ... }` invocation, with the span of every token, so that a
/// byte offset in the text maps back to the token to put an error on.
#[derive(Debug)]
pub struct TokenSource {
    pub text: String,
    /// `(start, end, span)` of each token's text, in text order.
    tokens: Vec<(usize, usize, Span)>,
}

struct Leaf {
    text: String,
    span: Span,
    /// A punctuation character directly followed by another one (`-` of `->`).
    joint: bool,
}

fn flatten(tokens: TokenStream, out: &mut Vec<Leaf>) {
    for tt in tokens {
        match tt {
            TokenTree::Group(g) => {
                let (open, close) = match g.delimiter() {
                    Delimiter::Brace => ("{", "}"),
                    Delimiter::Parenthesis => ("(", ")"),
                    Delimiter::Bracket => ("[", "]"),
                    Delimiter::None => ("", ""),
                };
                if !open.is_empty() {
                    out.push(Leaf {
                        text: open.into(),
                        span: g.span_open(),
                        joint: false,
                    });
                }
                flatten(g.stream(), out);
                if !close.is_empty() {
                    out.push(Leaf {
                        text: close.into(),
                        span: g.span_close(),
                        joint: false,
                    });
                }
            }
            TokenTree::Punct(p) => out.push(Leaf {
                text: p.as_char().to_string(),
                span: p.span(),
                joint: p.spacing() == proc_macro2::Spacing::Joint,
            }),
            TokenTree::Ident(i) => out.push(Leaf {
                text: i.to_string(),
                span: i.span(),
                joint: false,
            }),
            TokenTree::Literal(l) => out.push(Leaf {
                text: l.to_string(),
                span: l.span(),
                joint: false,
            }),
        }
    }
}

impl TokenSource {
    /// Turn macro input back into `.dyn` text. Where the compiler reports token positions
    /// (Rust ≥ 1.88) the layout is reproduced (line breaks matter to line comments of the
    /// language); otherwise tokens are joined by single spaces, except around `.` and
    /// inside multi-character operators.
    pub fn new(tokens: TokenStream) -> Self {
        let mut leaves = Vec::new();
        flatten(tokens, &mut leaves);
        let positioned = leaves.iter().any(|l| l.span.start().line > 0);
        let mut text = String::new();
        let mut spans = Vec::with_capacity(leaves.len());
        let (mut line, mut col) = match leaves.first() {
            Some(l) if positioned => (l.span.start().line, 0),
            _ => (0, 0),
        };
        let mut prev: Option<&Leaf> = None;
        for leaf in &leaves {
            if positioned {
                let start = leaf.span.start();
                if start.line > line {
                    text.push_str(&"\n".repeat(start.line - line));
                    text.push_str(&" ".repeat(start.column));
                } else if start.line == line && start.column >= col {
                    text.push_str(&" ".repeat(start.column - col));
                } else {
                    // Out of order (tokens from another macro's expansion): just separate.
                    text.push(' ');
                }
                let end = leaf.span.end();
                (line, col) = (end.line, end.column);
            } else if let Some(p) = prev {
                if !(p.joint || p.text == "." || leaf.text == ".") {
                    text.push(' ');
                }
            }
            let start = text.len();
            text.push_str(&leaf.text);
            spans.push((start, text.len(), leaf.span));
            prev = Some(leaf);
        }
        TokenSource {
            text,
            tokens: spans,
        }
    }

    /// The span of the token at byte `offset` of [`Self::text`]; an offset between tokens
    /// maps to the next token and one past the end to the last token.
    pub fn span_at(&self, offset: usize) -> Span {
        self.tokens
            .iter()
            .find(|(_, end, _)| *end > offset)
            .or(self.tokens.last())
            .map_or_else(Span::call_site, |t| t.2)
    }

    /// The spans of the first and the last token that byte range `range` of
    /// [`Self::text`] touches (both [`Self::span_at`] the start for an empty range).
    pub fn span_range(&self, range: std::ops::Range<usize>) -> (Span, Span) {
        let first = self.span_at(range.start);
        let last = self
            .tokens
            .iter()
            .rev()
            .find(|(start, _, _)| *start < range.end && *start >= range.start)
            .map_or(first, |t| t.2);
        (first, last)
    }
}

/// One `compile_error!` per diagnostic, spanning from the first to the last token that
/// `spans_of` gives for the diagnostic's byte range.
fn errors_to_tokens<E: Diagnostic>(
    errors: &[E],
    source: &str,
    file: Option<&str>,
    spans_of: impl Fn(Option<std::ops::Range<usize>>) -> (Span, Span),
) -> TokenStream {
    errors
        .iter()
        .map(|e| {
            let r = render(e, source, file);
            let (first, last) = spans_of(r.range);
            // A stable proc macro cannot join spans; syn's error spans its tokens' range
            // by giving the first and last token of `compile_error!` these spans.
            let ends = quote::quote_spanned!(first=> a)
                .into_iter()
                .chain(quote::quote_spanned!(last=> b));
            syn::Error::new_spanned(ends.collect::<TokenStream>(), r.message).to_compile_error()
        })
        .collect()
}

/// `include_model!("path")`: `path` is relative to `manifest_dir`, the calling crate's
/// `CARGO_MANIFEST_DIR`.
pub fn expand_include_model<E: Diagnostic>(
    path: &syn::LitStr,
    manifest_dir: &Path,
    compile: impl FnOnce(&str, &str) -> Result<ModelIr, Vec<E>>,
    opts: &CodegenOptions,
) -> TokenStream {
    let rel = path.value();
    let abs = manifest_dir.join(&rel);
    let stem_stub = || {
        Path::new(&rel)
            .file_stem()
            .and_then(|s| s.to_str())
            .map(|n| error_stub(n, opts))
            .unwrap_or_default()
    };
    let source = match std::fs::read_to_string(&abs) {
        Ok(s) => s,
        Err(e) => {
            let help = if Path::new(&rel).is_absolute() {
                "check the path; a relative path is taken from the directory of the \
                 crate's Cargo.toml"
                    .to_string()
            } else {
                format!(
                    "the path is relative to the directory of the crate's Cargo.toml; \
                     looked for `{}`",
                    abs.display()
                )
            };
            let msg = format!("cannot read model file `{rel}`: {e} [dyn::io]\n  = help: {help}");
            let err = syn::Error::new(path.span(), msg).to_compile_error();
            let stub = stem_stub();
            return quote!(#err #stub);
        }
    };
    // Makes cargo rebuild the crate when the model file changes.
    let rebuild = abs
        .to_str()
        .map(|p| {
            quote!(
                const _: &str = ::core::include_str!(#p);
            )
        })
        .unwrap_or_default();
    match compile(&rel, &source) {
        Ok(ir) => {
            let mut opts = opts.clone();
            opts.source_name.get_or_insert(rel);
            let items = generate(&ir, &source, &opts);
            quote!(#rebuild #items)
        }
        Err(errors) => {
            let errs =
                errors_to_tokens(&errors, &source, Some(&rel), |_| (path.span(), path.span()));
            let stub = model_name_hint(&source)
                .map(|n| error_stub(&n, opts))
                .unwrap_or_else(stem_stub);
            quote!(#rebuild #errs #stub)
        }
    }
}

/// `model! { model name { ... } }`. Errors are put on the token the diagnostic points at.
pub fn expand_model<E: Diagnostic>(
    input: TokenStream,
    compile: impl FnOnce(&str, &str) -> Result<ModelIr, Vec<E>>,
    opts: &CodegenOptions,
) -> TokenStream {
    const NAME: &str = "model!";
    let src = TokenSource::new(input);
    match compile(NAME, &src.text) {
        Ok(ir) => {
            let mut opts = opts.clone();
            opts.source_name.get_or_insert_with(|| NAME.to_string());
            generate(&ir, &src.text, &opts)
        }
        Err(errors) => {
            let errs = errors_to_tokens(&errors, &src.text, None, |range| {
                range.map_or_else(
                    || (Span::call_site(), Span::call_site()),
                    |r| src.span_range(r),
                )
            });
            let stub = model_name_hint(&src.text)
                .map(|n| error_stub(&n, opts))
                .unwrap_or_default();
            quote!(#errs #stub)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::str::FromStr;

    #[derive(Debug, thiserror::Error, Diagnostic)]
    #[error("undefined name `{name}`")]
    #[diagnostic(code(dsl::undefined_name), help("declare it with `param {name}`"))]
    struct Undefined {
        name: String,
        #[label("not declared")]
        at: miette::SourceSpan,
    }

    const SRC: &str =
        "model sdof {\n  body m1 { mass = 1 }\n  spring k1 (ground, m1) = k4 * s\n}\n";

    fn undefined_k4() -> Undefined {
        let at = SRC.find("k4").unwrap();
        Undefined {
            name: "k4".into(),
            at: (at, 2).into(),
        }
    }

    #[test]
    fn line_and_column_are_one_based_and_count_characters() {
        let s = "ab\ncdé f\n";
        assert_eq!(line_col(s, 0), (1, 1));
        assert_eq!(line_col(s, 3), (2, 1));
        assert_eq!(line_col(s, s.find('f').unwrap()), (2, 5));
        assert_eq!(line_col(s, s.len()), (3, 1));
        assert_eq!(line_col(s, 1000), (3, 1));
    }

    #[test]
    fn rendered_error_names_file_line_column_and_help() {
        let r = render(&undefined_k4(), SRC, Some("models/sdof.dyn"));
        let at = SRC.find("k4").unwrap();
        assert_eq!(r.range, Some(at..at + 2));
        insta::assert_snapshot!(r.message, @r"
        models/sdof.dyn:3:28: undefined name `k4` [dsl::undefined_name]
          |
        3 |   spring k1 (ground, m1) = k4 * s
          |                            ^^ not declared
          = help: declare it with `param k4`
        ");
        let r = render(&undefined_k4(), SRC, None);
        insta::assert_snapshot!(r.message, @r"
        undefined name `k4` [dsl::undefined_name]
          not declared
          = help: declare it with `param k4`
        ");
    }

    #[test]
    fn model_name_is_recovered_outside_comments() {
        let src = "# a model of the rig\n// model other\nmodel two_mass { }";
        assert_eq!(model_name_hint(src).as_deref(), Some("two_mass"));
        assert_eq!(model_name_hint("body m1"), None);
    }

    #[test]
    fn token_source_keeps_layout_and_maps_offsets_to_tokens() {
        let input = "model sdof {\n  spring k1 (ground, m1) = k * m1.x;\n  # comment\n}";
        let src = TokenSource::new(TokenStream::from_str(input).unwrap());
        assert_eq!(src.text, input);
        let at = |needle: &str| {
            let off = src.text.find(needle).unwrap();
            let span = src.span_at(off);
            (span.start().line, span.start().column)
        };
        assert_eq!(at("k *"), (2, 27));
        assert_eq!(at("ground"), (2, 13));
        // Between tokens: the next token.
        assert_eq!(at(" = k"), (2, 25));
        let past_end = src.span_at(10_000).start();
        assert_eq!((past_end.line, past_end.column), (4, 0));

        // A range maps to its first and last token: `k * m1.x` is `k` … `x`.
        let start = src.text.find("k *").unwrap();
        let (first, last) = src.span_range(start..start + "k * m1.x".len());
        assert_eq!((first.start().column, last.start().column), (27, 34));
        let (first, last) = src.span_range(start..start);
        assert_eq!((first.start().column, last.start().column), (27, 27));
    }

    #[test]
    fn expand_model_puts_errors_on_the_offending_token_and_emits_a_stub() {
        let input = TokenStream::from_str(SRC).unwrap();
        let out = expand_model(input, |_, _| Err(vec![undefined_k4()]), &Default::default());
        let text = out.to_string();
        assert!(text.contains("compile_error"), "{text}");
        assert!(text.contains("undefined name `k4`"), "{text}");
        assert!(text.contains("pub struct Sdof ;"), "{text}");
        // The error's tokens carry the span of `k4` (line 3, column 27 zero-based).
        let first = out.into_iter().next().unwrap().span().start();
        assert_eq!((first.line, first.column), (3, 27));
    }

    #[test]
    fn include_model_reports_a_missing_file_with_the_directory() {
        // The file is never read, so the compiler is never called.
        let expand = |path: &str| {
            let lit = syn::LitStr::new(path, proc_macro2::Span::call_site());
            expand_include_model(
                &lit,
                Path::new("/nonexistent/crate"),
                |_, _| -> Result<ModelIr, Vec<Undefined>> { unreachable!() },
                &Default::default(),
            )
            .to_string()
        };
        let text = expand("models/missing.dyn");
        assert!(
            text.contains("cannot read model file `models/missing.dyn`"),
            "{text}"
        );
        assert!(text.contains("/nonexistent/crate"), "{text}");

        // An absolute path is not joined to the crate's directory.
        let text = expand("/nonexistent/missing.dyn");
        assert!(text.contains("help: check the path"), "{text}");
        assert!(!text.contains("/nonexistent/crate"), "{text}");
        assert!(text.contains("pub struct Missing ;"), "{text}");
        assert!(!text.contains("include_str"), "{text}");
    }

    #[test]
    fn include_model_reports_parse_errors_and_keeps_the_rebuild_dependency() {
        let dir = std::env::temp_dir().join(format!("dynid-codegen-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("models")).unwrap();
        std::fs::write(dir.join("models/sdof.dyn"), SRC).unwrap();
        let lit: syn::LitStr = syn::parse_quote!("models/sdof.dyn");
        let out = expand_include_model(
            &lit,
            &dir,
            |name, source| {
                assert_eq!((name, source), ("models/sdof.dyn", SRC));
                Err(vec![undefined_k4()])
            },
            &Default::default(),
        );
        std::fs::remove_dir_all(&dir).unwrap();
        let text = out.to_string();
        assert!(text.contains("include_str"), "{text}");
        assert!(
            text.contains("models/sdof.dyn:3:28: undefined name"),
            "{text}"
        );
        assert!(text.contains("pub struct Sdof ;"), "{text}");
    }
}
