//! Syntax errors: a pest parse failure turned into a diagnostic with a readable "expected …"
//! message and a help line. It sits between the grammar and the diagnostics so that the
//! public [`crate::error`] module does not depend on the parser's rules.

use crate::error::{CompileError, ErrorSink};
use crate::grammar::Rule;
use crate::ir::Span;

/// Friendly names for grammar rules in "expected …" messages.
fn rule_name(r: &Rule) -> String {
    match r {
        Rule::EOI => "end of file",
        Rule::model | Rule::kw_model => "`model NAME { … }`",
        Rule::kw_body => "`body`",
        Rule::kw_input => "`input`",
        Rule::kw_on => "`on`",
        Rule::kw_measure => "`measure`",
        Rule::kw_reference => "`reference`",
        Rule::kw_control => "`control`",
        Rule::kw_param => "`param`",
        Rule::kw_spring => "`spring`",
        Rule::kw_damper => "`damper`",
        Rule::kw_force => "`force`",
        Rule::kw_excite => "`excite`",
        Rule::kw_levels => "`levels [..]`",
        Rule::kw_filter => "`filter`",
        Rule::kw_corners => "`corners [..]`",
        Rule::kw_order => "`order`",
        Rule::kw_driven => "`driven by`",
        Rule::kw_by => "`by`",
        Rule::ident => "a name",
        Rule::number | Rule::signed_number | Rule::integer => "a number",
        Rule::nominal => "`~ nominal`",
        Rule::known => "`= value`",
        Rule::nodes => "`(node_a, node_b)`",
        Rule::form => "a form filter (`lowpass(corner = ..)`, `second_order(freq = .., damping = ..)`, `white`) or `moves(..)`",
        Rule::named_arg => "`name = value`",
        Rule::num_list => "a list `[a, b, ..]`",
        Rule::expr | Rule::term | Rule::unary | Rule::power | Rule::exponent => "an expression",
        Rule::param_decl => "a parameter",
        Rule::call => "a function call",
        Rule::add_op => "`+` or `-`",
        Rule::mul_op => "`*` or `/`",
        Rule::neg => "`-`",
        Rule::sigref => "a signal (`m1.x`, `m1.v`, an input)",
        _ => return format!("{r:?}"),
    }
    .to_string()
}

/// Convert a pest error into a diagnostic with a readable "expected …" message.
///
/// Longer than most functions here: where the error points (pest's position, the parse
/// attempts), what was expected and what was found are worked out together, and the
/// message depends on all three.
pub(crate) fn from_pest(sink: &ErrorSink, e: pest::error::Error<Rule>) -> CompileError {
    use pest::error::{ErrorVariant, InputLocation};
    let src: &str = &sink.text;
    let (mut start, mut end) = match e.location {
        InputLocation::Pos(p) => (p, p),
        InputLocation::Span((a, b)) => (a, b),
    };
    let mut names: Vec<String> = Vec::new();
    if let ErrorVariant::ParsingError { positives, .. } = &e.variant {
        names = positives.iter().map(rule_name).collect();
    }
    let mut statement = matches!(&e.variant, ErrorVariant::ParsingError { positives, .. } if positives.contains(&Rule::kw_body));
    if let Some(att) = e.parse_attempts() {
        if att.max_position > start && att.max_position <= src.len() {
            start = att.max_position;
            end = start;
            names.clear();
        }
        if att.max_position == start {
            for t in att.expected_tokens() {
                // Only literal tokens read well in a message; ranges, built-in rules,
                // blanks, comments and the exponent marker are left out.
                let token = t.to_string();
                let skip = token == "BUILTIN_RULE"
                    || token == "E"
                    || token == "//"
                    || token == "_"
                    || token == "."
                    || token.trim().is_empty()
                    || (token.chars().count() == 4 && token.contains(".."));
                if !skip {
                    statement |= token == "body";
                    names.push(format!("`{token}`"));
                }
            }
        }
    }
    names.sort();
    names.dedup();
    // Label the offending token (or one character) so the report has something to point at.
    let end = if end > start {
        end
    } else {
        src[start..]
            .char_indices()
            .find(|&(i, c)| i > 0 && !(c.is_alphanumeric() || c == '_' || c == '.'))
            .map(|(i, _)| start + i)
            .unwrap_or(src.len())
            .max((start + src[start..].chars().next().map_or(0, char::len_utf8)).min(src.len()))
    };
    let found = if start >= src.len() {
        "end of file".to_string()
    } else {
        crate::text::quote(&src[start..end])
    };
    let invisible = src[start.min(src.len())..end.min(src.len())]
        .chars()
        .any(|c| crate::text::invisible_name(c).is_some());
    let (message, help) = match &e.variant {
        ErrorVariant::ParsingError { .. } if invisible => (
            format!("unexpected {found}"),
            "remove the invisible character (it often comes with text copied from a web page, \
             a PDF or a word processor); the language is plain text"
                .to_string(),
        ),
        ErrorVariant::ParsingError { .. } if src[start.min(src.len())..].starts_with('\'') => (
            "`'` is not part of the language: a model names no derivatives".to_string(),
            "inside a force, `s` and `v` are the element's relative displacement and \
             velocity; a body's position and velocity are `m.x` and `m.v` (e.g. \
             `sign(v)` or `sign(m.v)`, not `sign(x')`)"
                .to_string(),
        ),
        ErrorVariant::ParsingError { .. } => {
            if statement {
                (
                    format!("expected a statement or `}}`, found {found}"),
                    "statements are `body`, `input`, `measure`, `param`, `spring`, `damper`, `force`, `excite` and `filter`; see docs/language.md".to_string(),
                )
            } else if names.is_empty() {
                (
                    format!("unexpected {found}"),
                    "see docs/language.md for the syntax".to_string(),
                )
            } else {
                let list = match names.len() {
                    1 => names[0].clone(),
                    _ => {
                        let last = names.pop().unwrap_or_default();
                        format!("{} or {last}", names.join(", "))
                    }
                };
                (
                    format!("expected {list}, found {found}"),
                    "see docs/language.md for the syntax of each statement".to_string(),
                )
            }
        }
        ErrorVariant::CustomError { message } => (message.clone(), String::new()),
    };
    CompileError::syntax(sink, message, Span::new(start, end), help)
}
