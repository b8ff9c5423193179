//! The moments of a sub-model read from those of a larger one: a structure search measures
//! one model that holds every candidate term at once, then solves each candidate as that
//! model with the other candidates left out.
//!
//! Leaving out a term whose coefficient is an unknown changes neither the instruments nor
//! the rows of a level: the filters are driven by the measured signals, the designed
//! corners come from the data, and a static term is computable with every instrument
//! (filter states of relative degree ≥ 2 and the balance signals) and never brings white
//! noise of the same sample into a row, so `Plan::set_corners` keeps the same rows with or
//! without it. Each moment `⟨ι w⟩` is accumulated column by column, so the columns of the
//! sub-model are those of the large one. The sub-model's least-squares problem is
//! therefore the large one's with the left-out columns removed — solved on its own (row
//! normalisation, SVD, standard errors), never through normal equations. The large model's
//! rows (of each level and of each of its hat windows) are formed once and shared; a
//! sub-model reads its columns of them, so a search over hundreds of candidates forms rows
//! once, not once per candidate and per fold.

use super::measurement::Measurement;
use super::plan::{BasisMoment, TermCoef};
use dynid_ir::ir::ModelIr;
use rayon::prelude::*;
use std::sync::Arc;

impl<'m> Measurement<'m> {
    /// The least-squares column of the unknown parameter `name`, if it is one.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.plan
            .unknowns
            .iter()
            .position(|&p| self.ir.params[p].name == name)
    }

    /// Form and keep the columns `cols` of the rows now: a structure search keeps the
    /// columns every candidate shares (the base model's), so that each candidate forms
    /// only its own. A sub-model's columns are already its own: nothing to keep.
    pub fn keep_columns(&self, cols: &[usize]) {
        if self.cols.is_none() {
            cols.par_iter()
                .filter(|&&c| c < self.store.rhs())
                .for_each(|&c| drop(self.store.column(c)));
        }
    }

    /// The moments of a sub-model `ir`: this model with only the unknown columns `cols`
    /// kept (the terms of every other unknown removed; known terms stay). `ir` must be that
    /// sub-model: its unknowns, in order, are the parameters of `cols`, in that order
    /// (names may differ: they are reported with `ir`'s names), and its equations are this
    /// model's without the removed terms. Noise corrections, already applied to the moments,
    /// carry over; the velocity estimates reported are those the kept terms use.
    ///
    /// The sub-model's columns are read from this model's kept columns where they are
    /// formed ([`Self::keep_columns`]), else formed for the sub-model alone.
    ///
    /// Returns `None` when `ir` has a different number of unknowns or of equations, or a
    /// column is out of range.
    ///
    /// Long: the sub-model's plan and columns are built field by field from this model's.
    pub fn restricted<'c>(&self, ir: &'c ModelIr, cols: &[usize]) -> Option<Measurement<'c>> {
        let plan = &self.plan;
        let unknowns = ir.unknowns();
        if unknowns.len() != cols.len()
            || ir.equations.len() != plan.equations.len()
            || cols.iter().any(|&c| c >= plan.unknowns.len())
        {
            return None;
        }
        // Kept terms, their unknowns renumbered. The moments stay the measured model's (the
        // levels are shared), so the terms keep its columns of `w`.
        let mut equations = plan.equations.clone();
        for eq in &mut equations {
            eq.retain_mut(|t| match t.coef {
                TermCoef::Known(_) => true,
                TermCoef::Unknown { col, scale } => match cols.iter().position(|&c| c == col) {
                    Some(k) => {
                        t.coef = TermCoef::Unknown { col: k, scale };
                        true
                    }
                    None => false,
                },
            });
        }
        // Velocity estimates still used by a kept static term.
        let n_g = plan.roots.len();
        let used_roots: Vec<_> = equations
            .iter()
            .flatten()
            .filter_map(|t| match t.basis {
                BasisMoment::Static(w) if w < n_g => Some(plan.roots[w]),
                _ => None,
            })
            .collect();
        let kept_estimates: Vec<bool> = plan
            .estimated
            .iter()
            .map(|(v, _)| {
                used_roots
                    .iter()
                    .any(|&r| self.ir.expr_signals(r).contains(v))
            })
            .collect();
        let kept_integrated: Vec<bool> = plan
            .integrated
            .iter()
            .map(|(s, _)| {
                used_roots
                    .iter()
                    .any(|&r| self.ir.expr_signals(r).contains(s))
            })
            .collect();
        let mut sub = plan.clone();
        sub.integrated = plan
            .integrated
            .iter()
            .zip(&kept_integrated)
            .filter(|(_, k)| **k)
            .map(|(e, _)| *e)
            .collect();
        sub.estimated = plan
            .estimated
            .iter()
            .zip(&kept_estimates)
            .filter(|(_, k)| **k)
            .map(|(e, _)| *e)
            .collect();
        sub.unknowns = unknowns.iter().map(|p| p.index()).collect();
        sub.equations = equations;
        sub.constant = cols.iter().map(|&c| plan.constant[c]).collect();
        // The sub-model's rows are columns of the measured model's rows; the right-hand
        // side (the known terms) is the same.
        let cols = match &self.cols {
            None => cols
                .iter()
                .map(|&c| self.store.column_unkept(c))
                .chain([self.store.column(self.store.rhs())])
                .collect(),
            Some(mine) => cols
                .iter()
                .map(|&c| Arc::clone(&mine[c]))
                .chain([Arc::clone(&mine[mine.len() - 1])])
                .collect(),
        };
        Some(Measurement {
            ir,
            plan: sub,
            store: Arc::clone(&self.store),
            cols: Some(cols),
            infos: self.infos.clone(),
            centred: self.centred.clone(),
            // Aligned with `plan.estimated` then `plan.integrated` (one report each).
            estimated: self
                .estimated
                .iter()
                .zip(kept_estimates.iter().chain(&kept_integrated))
                .filter(|(_, k)| **k)
                .map(|(e, _)| e.clone())
                .collect(),
            rcond: self.rcond,
            times: self.times,
            prune_t: self.prune_t,
            noise: self.noise.clone(),
            efficient: self.efficient,
            shrinkage: self.shrinkage,
            iterate_weights: self.iterate_weights,
        })
    }
}
