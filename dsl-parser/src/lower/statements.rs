//! The `measure`, `excite` and `filter` statements: which signals are measured, the
//! excitation of each input with its form filter and levels, and the identification
//! filter bank.

use super::names::closest;
use super::{fmt_value, Decl, Lowerer};
use crate::ast::*;
use crate::error::{Draft, ErrorKind};
use crate::ir::*;
use std::collections::HashMap;

impl Lowerer<'_> {
    /// `measure`, `excite` and `filter` statements.
    pub(super) fn statements(&mut self, ast: &AstModel, ir: &mut ModelIr) {
        // measure
        let lists: Vec<&Vec<AstSigRef>> = ast
            .items
            .iter()
            .filter_map(|it| match it {
                AstItem::Measure { signals, .. } => Some(signals),
                _ => None,
            })
            .collect();
        if !lists.is_empty() {
            // An accelerometer `b.a` adds the body's acceleration signal after the
            // references (body order), so models without one keep their signal table.
            let mut acc: Vec<BodyId> = lists
                .iter()
                .flat_map(|l| l.iter())
                .filter(|r| r.field.as_ref().is_some_and(|f| f.name == "a"))
                .filter_map(|r| match self.names.get(&r.base.name) {
                    Some(&(Decl::Body(b), _)) => Some(b),
                    _ => None,
                })
                .collect();
            acc.sort();
            acc.dedup();
            for b in acc {
                ir.signals.push(SignalIr {
                    name: format!("{}.a", ir.bodies[b.index()].name),
                    kind: SignalKind::Acceleration(b),
                    measured: true,
                });
            }
            for s in ir.signals.iter_mut() {
                s.measured = false;
            }
            for list in lists {
                for r in list {
                    if let Some(id) = self.signal_ref(r, ir) {
                        ir.signals[id.index()].measured = true;
                    }
                }
            }
            // A reference is a column of the data whether listed or not.
            for s in ir.signals.iter_mut() {
                if matches!(s.kind, SignalKind::Reference(_)) {
                    s.measured = true;
                }
            }
        }
        // excite
        let mut first: Option<(usize, Span)> = None;
        let mut seen: HashMap<SignalId, Span> = HashMap::new();
        for item in &ast.items {
            let AstItem::Excite {
                input,
                form,
                levels,
                levels_span,
                span: _,
            } = item
            else {
                continue;
            };
            let id = match self.names.get(&input.name) {
                Some(&(Decl::Input(i), _)) => {
                    if ir.control_of(i).is_some() {
                        self.err(
                            ErrorKind::InvalidControl,
                            format!("input `{}` is computed by its control law and cannot be excited", input.name),
                            input.span,
                            "controlled",
                            "excite the law's reference instead (`excite r: lowpass(corner = ..) levels [..]`)".into(),
                        );
                        None
                    } else {
                        Some(ir.input_signal(i))
                    }
                }
                Some(&(Decl::Reference(r), _)) => Some(ir.reference_signal(r)),
                _ => {
                    let inputs: Vec<&str> = ir.inputs.iter().map(|i| i.name.as_str()).collect();
                    let help = match (
                        closest(&input.name, inputs.iter().copied()),
                        inputs.is_empty(),
                    ) {
                        (Some(c), _) => format!("did you mean `{c}`?"),
                        (None, true) => "declare an input first: `input u on m1`".into(),
                        (None, false) => format!(
                            "the inputs are {}",
                            inputs
                                .iter()
                                .map(|i| format!("`{i}`"))
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    };
                    self.err(
                        ErrorKind::UnknownInput,
                        format!("`{}` is not an input or a reference", input.name),
                        input.span,
                        "not an input",
                        help,
                    );
                    None
                }
            };
            if let Some(i) = id {
                if let Some(&prev) = seen.get(&i) {
                    self.sink.draft(
                        ErrorKind::DuplicateExcitation,
                        Draft {
                            message: format!("`{}` is excited twice", input.name),
                            span: Some(input.span),
                            label: "second excitation".into(),
                            other: Some(prev),
                            other_label: "first excitation".into(),
                            help: "give each input and reference one `excite` line".into(),
                        },
                    );
                } else {
                    seen.insert(i, input.span);
                }
            }
            let filter = self.form_filter(form);
            let mut good = true;
            for l in levels {
                good &= self.check_positive(l, "an excitation level");
            }
            if levels.is_empty() {
                self.err(
                    ErrorKind::InvalidValue,
                    "no excitation levels".into(),
                    *levels_span,
                    "empty",
                    "give at least one level, e.g. `levels [6, 15, 40]`; several levels make nonlinear terms identifiable".into(),
                );
                good = false;
            }
            match first {
                None => first = Some((levels.len(), *levels_span)),
                Some((n, span)) if n != levels.len() => {
                    self.sink.draft(
                        ErrorKind::LevelCountMismatch,
                        Draft {
                            message: format!("{} here but {} in the first `excite` line", levels_text(levels.len()), levels_text(n)),
                            span: Some(*levels_span),
                            label: levels_text(levels.len()),
                            other: Some(span),
                            other_label: levels_text(n),
                            help: "every `excite` line must list the same number of levels: level k of all inputs forms experiment k".into(),
                        },
                    );
                }
                _ => {}
            }
            if let (Some(id), Some(filter), true) = (id, filter, good) {
                let levels = levels.iter().map(|l| l.value).collect();
                match ir.signal(id).kind {
                    SignalKind::Reference(reference) => {
                        ir.reference_excitation.push(ReferenceExcitationIr {
                            reference,
                            filter,
                            levels,
                        })
                    }
                    SignalKind::Input(input) => ir.excitation.push(ExcitationIr {
                        input,
                        filter,
                        levels,
                    }),
                    _ => {}
                }
            }
        }
        // filter
        let filters: Vec<&AstItem> = ast
            .items
            .iter()
            .filter(|it| matches!(it, AstItem::Filter { .. }))
            .collect();
        for (k, item) in filters.iter().enumerate() {
            let AstItem::Filter {
                corners,
                corners_span,
                order,
                driven_by,
                span,
            } = item
            else {
                continue;
            };
            if k > 0 {
                self.err(
                    ErrorKind::DuplicateName,
                    "a second `filter` statement".into(),
                    *span,
                    "second filter",
                    "a model has at most one identification filter bank; merge the corner lists"
                        .into(),
                );
                continue;
            }
            for c in corners {
                self.check_positive(c, "a corner frequency");
            }
            if corners.is_empty() {
                self.err(
                    ErrorKind::InvalidValue,
                    "no corner frequencies".into(),
                    *corners_span,
                    "empty",
                    "list the corner frequencies in rad/s, e.g. `corners [0.5, 1, 2, 4, 8, 16]`"
                        .into(),
                );
            }
            let order_v = order.map_or(2, |o| o.0);
            if let Some((o, ospan)) = order {
                if !(1..=8).contains(o) {
                    self.err(
                        ErrorKind::InvalidValue,
                        format!("filter order {o} is out of range"),
                        *ospan,
                        "order",
                        "use an order between 1 and 8 (2 is the default and works with displacement-only data)".into(),
                    );
                } else if *o < 2 {
                    if let Some(b) = ir
                        .bodies
                        .iter()
                        .enumerate()
                        .find(|(i, _)| !ir.signals[2 * i + 1].measured)
                    {
                        self.err(
                            ErrorKind::InvalidValue,
                            format!("filter order 1 cannot be used: `{}.v` is not measured", b.1.name),
                            *ospan,
                            "order 1",
                            "without velocity data the acceleration term must move twice onto the filter; use `order 2` or more".into(),
                        );
                    }
                }
            }
            let mut ids = Vec::new();
            for r in driven_by {
                if let Some(id) = self.signal_ref(r, ir) {
                    if !ir.signals[id.index()].measured {
                        let n = &ir.signals[id.index()].name;
                        self.err(
                            ErrorKind::UnmeasuredSignal,
                            format!("the filter is driven by `{n}`, which is not measured"),
                            r.span,
                            "not measured",
                            format!(
                                "add `{n}` to `measure` or drive the filter by measured signals"
                            ),
                        );
                    }
                    ids.push(id);
                }
            }
            ir.filter = Some(FilterSpecIr {
                corners: corners.iter().map(|c| c.value).collect(),
                order: order_v,
                driven_by: ids,
            });
        }
    }

    fn form_filter(&mut self, form: &AstForm) -> Option<FormFilter> {
        let expected: &[&str] = match form.name.name.as_str() {
            "lowpass" => &["corner"],
            "second_order" => &["freq", "damping"],
            "white" => &[],
            "moves" => &["distance", "speed", "accel", "dwell"],
            other => {
                self.err(
                    ErrorKind::InvalidValue,
                    format!("unknown form filter `{other}`"),
                    form.name.span,
                    "not a form filter",
                    "use `lowpass(corner = ..)`, `second_order(freq = .., damping = ..)`, `white` or `moves(distance = .., speed = .., accel = .., dwell = ..)`".into(),
                );
                return None;
            }
        };
        let mut vals = vec![None; expected.len()];
        let mut ok = true;
        for a in &form.args {
            match expected.iter().position(|e| *e == a.name.name) {
                Some(k) => {
                    ok &= if a.name.name == "dwell" {
                        self.check_not_negative(&a.value, "`dwell`")
                    } else {
                        self.check_positive(&a.value, &format!("`{}`", a.name.name))
                    };
                    vals[k] = Some(a.value.value);
                }
                None => {
                    ok = false;
                    self.err(
                        ErrorKind::InvalidValue,
                        format!("`{}` has no argument `{}`", form.name.name, a.name.name),
                        a.name.span,
                        "unknown argument",
                        format!(
                            "`{}` takes {}",
                            form.name.name,
                            if expected.is_empty() {
                                "no arguments".to_string()
                            } else {
                                expected
                                    .iter()
                                    .map(|e| format!("`{e} = ..`"))
                                    .collect::<Vec<_>>()
                                    .join(", ")
                            }
                        ),
                    );
                }
            }
        }
        for (k, v) in vals.iter().enumerate() {
            if v.is_none() {
                ok = false;
                self.err(
                    ErrorKind::InvalidValue,
                    format!("`{}` needs `{} = ..`", form.name.name, expected[k]),
                    form.span,
                    "missing argument",
                    if form.name.name == "moves" {
                        "a move goes `distance` out or back at a top `speed` and a peak `accel`, after `dwell` seconds at rest, e.g. `moves(distance = 0.1, speed = 0.4, accel = 4, dwell = 0.3)`".into()
                    } else {
                        "corner and frequencies are in rad/s, damping is a ratio, e.g. `lowpass(corner = 10)`, `second_order(freq = 20, damping = 0.3)`".into()
                    },
                );
            }
        }
        if !ok {
            return None;
        }
        let v = |k: usize| vals[k].unwrap_or(1.0);
        if form.name.name == "moves" {
            let (distance, speed, accel, dwell) = (v(0), v(1), v(2), v(3));
            // The velocity profile of a move: the fastest move reaches `speed` only if the
            // two acceleration phases (each `speed² / accel` long) fit into `distance`.
            if 2.0 * speed * speed / accel > distance {
                let at = form
                    .args
                    .iter()
                    .find(|a| a.name.name == "speed")
                    .map_or(form.span, |a| a.value.span);
                self.err(
                    ErrorKind::InvalidValue,
                    format!(
                        "`speed` {} is not reached in a move of `distance` {} at `accel` {}",
                        fmt_value(speed),
                        fmt_value(distance),
                        fmt_value(accel)
                    ),
                    at,
                    "not reached",
                    format!(
                        "speeding up and slowing down take 2 speed² / accel = {} of the distance: lower `speed` to about {} or less, or raise `accel` or `distance`",
                        crate::num::sig(2.0 * speed * speed / accel, 3, false),
                        crate::num::sig((0.5 * accel * distance).sqrt(), 3, false)
                    ),
                );
                return None;
            }
            return Some(FormFilter::Moves {
                distance,
                speed,
                accel,
                dwell,
            });
        }
        Some(match expected.len() {
            0 => FormFilter::White,
            1 => FormFilter::Lowpass { corner: v(0) },
            _ => FormFilter::SecondOrder {
                freq: v(0),
                damping: v(1),
            },
        })
    }

    /// A signal in `measure` or `driven by`: `m1.x`, `m1.v` or an input name.
    fn signal_ref(&mut self, r: &AstSigRef, ir: &ModelIr) -> Option<SignalId> {
        let full = match &r.field {
            Some(f) => format!("{}.{}", r.base.name, f.name),
            None => r.base.name.clone(),
        };
        if let Some(id) = ir.signal_id(&full) {
            return Some(id);
        }
        let is_body = matches!(self.names.get(&r.base.name), Some((Decl::Body(_), _)));
        if is_body {
            let b = &r.base.name;
            self.err(
                ErrorKind::InvalidSignal,
                format!("`{full}` is not a signal"),
                r.span,
                "not a signal",
                format!("a body has a position `{b}.x` and a velocity `{b}.v` (and, in `measure` only, an acceleration `{b}.a`)"),
            );
        } else {
            let help = match closest(&full, ir.signals.iter().map(|s| s.name.as_str())) {
                Some(c) => format!("did you mean `{c}`?"),
                None => format!(
                    "the signals are {}",
                    ir.signals
                        .iter()
                        .map(|s| format!("`{}`", s.name))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            };
            self.err(
                ErrorKind::UndefinedName,
                format!("unknown signal `{full}`"),
                r.span,
                "not a signal",
                help,
            );
        }
        None
    }
}

fn levels_text(n: usize) -> String {
    if n == 1 {
        "1 level".into()
    } else {
        format!("{n} levels")
    }
}
