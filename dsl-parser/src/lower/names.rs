//! The namespace of a model: reserved words, declaring and resolving names, and the
//! "did you mean" suggestions of the errors about unknown names.

use super::{Decl, Lowerer};
use crate::ast::*;
use crate::error::{Draft, ErrorKind};
use crate::ir::*;

pub(super) const FUNCTIONS: &[(&str, usize)] = &[
    ("abs", 1),
    ("sign", 1),
    ("tanh", 1),
    ("sqrt", 1),
    ("exp", 1),
    ("sin", 1),
    ("cos", 1),
    ("deadzone", 2),
    ("saturate", 2),
];

const KEYWORDS: &[&str] = &[
    "model",
    "body",
    "input",
    "reference",
    "control",
    "on",
    "measure",
    "param",
    "spring",
    "damper",
    "force",
    "excite",
    "levels",
    "filter",
    "corners",
    "order",
    "driven",
    "by",
];

pub(super) fn is_reserved(name: &str) -> bool {
    matches!(name, "ground" | "s" | "v" | "t")
        || FUNCTIONS.iter().any(|(f, _)| *f == name)
        || KEYWORDS.contains(&name)
}

/// The candidate nearest to `name` by Levenshtein distance, if it is at most 2 edits away
/// (and less than the longer of the two lengths). Ties go to the first in byte order.
pub(super) fn closest<'a>(
    name: &str,
    candidates: impl Iterator<Item = &'a str>,
) -> Option<&'a str> {
    candidates
        .map(|c| (strsim::levenshtein(name, c), c))
        .filter(|&(d, c)| d <= 2 && d < c.len().max(name.len()))
        .min()
        .map(|(_, c)| c)
}

impl Lowerer<'_> {
    pub(super) fn register(&mut self, ident: &AstIdent, decl: Decl, what: &str) -> bool {
        if is_reserved(&ident.name) {
            self.err(
                ErrorKind::ReservedName,
                format!("`{}` is a reserved word and cannot name a {what}", ident.name),
                ident.span,
                "reserved",
                "choose another name; `ground`, `s`, `v`, `t`, the functions and the keywords are reserved".into(),
            );
            // Still declared, so that its uses are not reported again as unknown names.
            self.names
                .entry(ident.name.clone())
                .or_insert((decl, ident.span));
            return false;
        }
        if let Some(&(_, first)) = self.names.get(&ident.name) {
            self.sink.draft(
                ErrorKind::DuplicateName,
                Draft {
                    message: format!("`{}` is declared twice", ident.name),
                    span: Some(ident.span),
                    label: "declared again here".into(),
                    other: Some(first),
                    other_label: "first declared here".into(),
                    help: "bodies, inputs, elements and parameters share one namespace; rename one of them (to share a parameter, declare it once and refer to it by name)".into(),
                },
            );
            return false;
        }
        self.names.insert(ident.name.clone(), (decl, ident.span));
        true
    }

    pub(super) fn param_of(&self, name: &str) -> Option<usize> {
        match self.names.get(name) {
            Some(&(Decl::Param(p), _)) | Some(&(Decl::Element(Some(p)), _)) => Some(p),
            _ => None,
        }
    }

    fn body_names(&self) -> Vec<&str> {
        self.bodies.iter().map(|b| b.name.as_str()).collect()
    }

    /// A node of an element or the body of an input.
    pub(super) fn resolve_body(&mut self, ident: &AstIdent, allow_ground: bool) -> Option<Node> {
        if ident.name == "ground" && allow_ground {
            return Some(Node::Ground);
        }
        match self.names.get(&ident.name) {
            Some(&(Decl::Body(b), _)) => Some(Node::Body(b)),
            Some(_) => {
                self.err(
                    ErrorKind::InvalidConnection,
                    format!("`{}` is not a body", ident.name),
                    ident.span,
                    "not a body",
                    "elements connect bodies (or `ground`); inputs act on a body".into(),
                );
                None
            }
            None => {
                let bodies = self.body_names();
                let help = match closest(&ident.name, bodies.into_iter().chain(["ground"])) {
                    Some(c) => {
                        format!("did you mean `{c}`? Declare bodies with `body NAME = mass`")
                    }
                    None => {
                        "declare the body with `body NAME = mass`, or connect to `ground`".into()
                    }
                };
                self.err(
                    ErrorKind::UndefinedName,
                    format!("unknown body `{}`", ident.name),
                    ident.span,
                    "not declared",
                    help,
                );
                None
            }
        }
    }

    pub(super) fn resolve_inputs(&mut self) -> Vec<BodyId> {
        let inputs = self.inputs.clone();
        inputs
            .iter()
            .map(|(name, body, span)| {
                if body.name == "ground" {
                    self.err(
                        ErrorKind::InvalidConnection,
                        format!("input `{name}` acts on ground"),
                        *span,
                        "on ground",
                        "an input force must act on a body".into(),
                    );
                    return BodyId(0);
                }
                match self.resolve_body(body, false) {
                    Some(Node::Body(b)) => b,
                    _ => BodyId(0),
                }
            })
            .collect()
    }

    pub(super) fn undefined(&mut self, ident: &AstIdent, span: Span, extra: &str) {
        let mut cands: Vec<String> = self.names.keys().cloned().collect();
        cands.extend(["s", "v"].map(String::from));
        for b in &self.bodies {
            cands.push(format!("{}.x", b.name));
            cands.push(format!("{}.v", b.name));
        }
        cands.sort();
        let help = match closest(&ident.name, cands.iter().map(String::as_str)) {
            Some(c) => format!("did you mean `{c}`? {extra}"),
            None => format!("a force may use `s`, `v`, signals `m1.x`/`m1.v`, inputs and parameters; a new parameter must be a plain factor of a term (`k ~ 1.0 * s`). {extra}"),
        };
        self.err(
            ErrorKind::UndefinedName,
            format!("`{}` is not defined", ident.name),
            span,
            "not declared",
            help.trim_end().to_string(),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::closest;

    #[test]
    fn closest_takes_the_nearest_within_two_edits_and_breaks_ties_by_byte_order() {
        let fns = ["abs", "sign", "tanh", "sqrt", "exp", "deadzone", "saturate"];
        assert_eq!(closest("sgn", fns.into_iter()), Some("sign"));
        assert_eq!(closest("deadzon", fns.into_iter()), Some("deadzone"));
        assert_eq!(closest("sinh", fns.into_iter()), Some("sign"));
        // Equal distance: the first in byte order wins, whatever the candidates' order.
        assert_eq!(closest("ab", ["ac", "aa"].into_iter()), Some("aa"));
        // Three edits, or a rewrite of every character of a short name: no suggestion.
        assert_eq!(closest("cosine", fns.into_iter()), None);
        assert_eq!(closest("k", ["m"].into_iter()), None);
        assert_eq!(closest("m3", ["m1.x", "m1.v"].into_iter()), None);
    }
}
