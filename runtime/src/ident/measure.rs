//! The measuring pass: the first pass over every level (length, spectra, noise floors), the
//! filter bank and velocity estimates it chooses, then one streamed pass of the filters that
//! accumulates the moments of every level.

use super::*;

/// Stream every level once through the filters and accumulate the moments.
pub fn measure<'m>(
    ir: &'m ModelIr,
    eval: &dyn BasisEval,
    levels: &[&dyn LevelSource],
    opts: &IdentifyOptions,
) -> Result<Moments<'m>, IdentifyError> {
    if levels.is_empty() {
        return Err(IdentifyError::NoLevels);
    }
    if ir.unknowns().is_empty() {
        return Err(IdentifyError::NoUnknowns);
    }
    if opts.chunk_len < 2 || opts.n_blocks.is_some_and(|b| b < 2) {
        return Err(IdentifyError::BadOption {
            message: "chunk length and number of blocks must be at least 2".into(),
            help: "use the defaults".into(),
        });
    }
    // Before any sample is read: a model too large for memory is refused with the estimate.
    memory::check(ir, levels.len(), opts, 0.0, "identification")?;
    let bank = choose_bank(ir, opts)?;
    let mut plan = plan::build_structure(ir, opts.balance.unwrap_or(false), &bank)?;
    let t0 = Instant::now();
    let stats: Vec<LevelStats> = crate::first_error_in_order(
        levels
            .par_iter()
            .map(|src| level_stats(ir, &plan, *src, opts.chunk_len)),
    )?;
    let stats_time = t0.elapsed();
    let (noise_var, noise) = noise_plan(ir, &mut plan, &stats, opts.noise_correction);

    // The shortest level bounds the slowest filter.
    let min_duration = stats
        .iter()
        .map(|s| s.n.saturating_sub(1) as f64 * s.ts)
        .fold(f64::INFINITY, f64::min);
    let ts_min = stats.iter().map(|s| s.ts).fold(f64::INFINITY, f64::min);
    let omegas: Vec<f64> = stats.iter().flat_map(|s| s.omegas.clone()).collect();
    // The band above the noise floor: the lowest over the levels and the measured drivers
    // whose floor is white noise (a driver with a floor of its own content, such as a
    // controller's force, carries information up to the Nyquist frequency).
    let mut info: Option<(String, f64)> = None;
    for st in &stats {
        for (k, s) in plan.y.iter().enumerate() {
            if !plan.drivers.contains(s) || !st.noise_flat[k] {
                continue;
            }
            if let Some(w) = st.info[k] {
                if info.as_ref().is_none_or(|(_, v)| w < *v) {
                    info = Some((ir.signal(*s).name.clone(), w));
                }
            }
        }
    }
    let designed = design::fit_corners_info(
        &omegas,
        info,
        ts_min,
        min_duration,
        bank.order,
        bank.n_corners,
    );
    let given = opts.corners.is_some() || ir.filter.as_ref().is_some_and(|f| !f.corners.is_empty());
    plan.corner_source = CornerSource {
        given,
        lower: designed.as_ref().filter(|_| !given).map(|d| d.lower),
        upper: designed.as_ref().filter(|_| !given).map(|d| d.upper),
        info_signal: designed
            .as_ref()
            .and_then(|d| d.info_signal.as_ref().map(|(n, _)| n.clone())),
        info_bandwidth: designed
            .as_ref()
            .and_then(|d| d.info_signal.as_ref().map(|(_, w)| *w)),
    };
    let corners = match (&opts.corners, ir.filter.as_ref().map(|f| &f.corners)) {
        (Some(c), _) => c.clone(),
        (None, Some(c)) if !c.is_empty() => c.clone(),
        _ => match &designed {
            Some(d) => d.corners.clone(),
            // Not even the fastest admissible corners settle: fall through to the check,
            // which names the record length they need.
            None => {
                let cap = design::max_corner(ts_min);
                vec![cap / 2.0; bank.n_corners]
            }
        },
    };
    if corners.is_empty() || corners.iter().any(|c| !(c.is_finite() && *c > 0.0)) {
        return Err(IdentifyError::BadOption {
            message: format!("filter corners {corners:?}"),
            help: "corners are positive angular frequencies in rad/s".into(),
        });
    }
    // A corner at or above the Nyquist frequency of a level filters nothing there: the
    // discretised filter aliases and the estimates are wrong without any other sign.
    let ts_max = stats.iter().map(|s| s.ts).fold(0.0, f64::max);
    let nyquist = std::f64::consts::PI / ts_max;
    if let Some(c) = corners.iter().find(|c| **c >= nyquist) {
        let designed_here =
            opts.corners.is_none() && ir.filter.as_ref().is_none_or(|f| f.corners.is_empty());
        if designed_here && ts_min < ts_max {
            // No option was given: the corners come from the faster level's rate.
            let at = |ts: f64| {
                stats
                    .iter()
                    .position(|s| s.ts == ts)
                    .map_or_else(String::new, |k| levels[k].origin())
            };
            return Err(IdentifyError::MixedSampleIntervals {
                fast: at(ts_min),
                ts_fast: ts_min,
                slow: at(ts_max),
                ts_slow: ts_max,
                corner: corners.iter().copied().fold(0.0, f64::max),
            });
        }
        return Err(IdentifyError::BadOption {
            message: format!(
                "filter corner {} rad/s is at or above the Nyquist frequency π/Ts = {} rad/s \
                 of the data (Ts = {} s)",
                dynid_ir::num::sig(*c, 4, false),
                dynid_ir::num::sig(nyquist, 4, false),
                dynid_ir::num::sig(ts_max, 4, false)
            ),
            help: "use corners well below the Nyquist frequency (a few times below it), or \
                   leave them out so that they are designed from the data"
                .into(),
        });
    }
    plan.corners = vec![0.0; corners.len()];
    plan.set_corners(ir, &corners);
    let lam_min = corners.iter().copied().fold(f64::INFINITY, f64::min);
    // The slowest section must forget its start within a small part of the record.
    let tau = bank.order as f64 / lam_min;
    let settle = design::min_duration(&corners, bank.order);
    let min_samples = stats.iter().map(|s| s.n).min().unwrap_or(0);
    let n_blocks = opts
        .n_blocks
        .unwrap_or_else(|| design::blocks(min_duration, tau, min_samples));
    for (s, src) in stats.iter().zip(levels) {
        let duration = (s.n.saturating_sub(1)) as f64 * s.ts;
        if duration < settle * (1.0 - 1e-9) || s.n < n_blocks.saturating_mul(4) {
            // (Saturating: a corner of 1e-300 rad/s asks for more samples than a count holds.)
            let need = ((settle / s.ts).ceil() as usize)
                .saturating_add(1)
                .max(n_blocks.saturating_mul(4));
            let advice = match &designed {
                Some(c) if s.n >= n_blocks.saturating_mul(4) => format!(
                    "record at least {}, or use filter corners that fit this record (the \
                     lowest at least {:.4} rad/s), e.g. `--filter-corners {}`",
                    samples_needed(need, settle),
                    design::min_corner(min_duration, bank.order),
                    c.corners
                        .iter()
                        .map(|v| format!("{v:.4}"))
                        .collect::<Vec<_>>()
                        .join(",")
                ),
                _ => {
                    // The fastest corner the design allows at this sample rate.
                    let fast = design::max_corner(s.ts) / 2.0;
                    let t_fast = design::min_duration(&[fast], bank.order);
                    format!(
                        "record at least {}: with {} filter sections even the fastest \
                         corner this sample rate allows ({fast:.4} rad/s) needs {t_fast:.3} s",
                        samples_needed(
                            need.max(((t_fast / s.ts).ceil() as usize).saturating_add(1)),
                            settle.max(t_fast)
                        ),
                        bank.order,
                    )
                }
            };
            return Err(IdentifyError::TooShort {
                origin: src.origin(),
                n: s.n,
                duration,
                tau,
                need,
                advice,
            });
        }
    }
    let cols = plan.unknowns.len();
    let rows = plan.rows.len() * levels.len();
    if rows < cols {
        return Err(IdentifyError::TooFewRows { rows, cols });
    }

    // Unmeasured velocities in nonlinear terms: estimated from the positions, per level.
    let targets: Vec<(usize, usize)> = plan
        .estimated
        .iter()
        .map(|(v, x)| (v.index(), x.index()))
        .collect();
    let estimators: Vec<velocity::EstimatedVelocity> = if targets.is_empty() {
        Vec::new()
    } else {
        crate::first_error_in_order(
            levels
                .par_iter()
                .map(|src| velocity::EstimatedVelocity::design(*src, &targets, opts.chunk_len)),
        )?
    };
    let sources: Vec<&dyn LevelSource> = if estimators.is_empty() {
        levels.to_vec()
    } else {
        estimators.iter().map(|e| e as &dyn LevelSource).collect()
    };
    // Positions and velocities of acceleration-only bodies that roots read: zeros.
    let zero_filled: Vec<accel::ZeroFill> = if plan.absent.is_empty() {
        Vec::new()
    } else {
        let slots: Vec<usize> = plan.absent.iter().map(|s| s.index()).collect();
        sources
            .iter()
            .map(|s| accel::ZeroFill::new(*s, slots.clone()))
            .collect()
    };
    let sources: Vec<&dyn LevelSource> = if zero_filled.is_empty() {
        sources
    } else {
        zero_filled.iter().map(|z| z as &dyn LevelSource).collect()
    };
    let estimated = plan
        .estimated
        .iter()
        .enumerate()
        .map(|(k, (v, x))| VelocityEstimate {
            signal: ir.signal(*v).name.clone(),
            from: ir.signal(*x).name.clone(),
            method: velocity::METHOD.into(),
            cutoff: estimators.iter().map(|e| e.designs()[k].1).collect(),
            half_width: estimators.iter().map(|e| e.designs()[k].2).collect(),
        })
        .collect();

    // Rests of bodies with a Coulomb term: left out of the moments (see [`rests`]).
    let rest_bodies = if opts.keep_rests {
        Vec::new()
    } else {
        rests::bodies(ir)
    };
    let found: Vec<Option<(rests::Intervals, RestSummary)>> = if rest_bodies.is_empty() {
        vec![None; levels.len()]
    } else {
        crate::first_error_in_order(
            levels
                .par_iter()
                .map(|src| rests::find(ir, &rest_bodies, *src, opts.chunk_len).map(Some)),
        )?
    };

    // Rests are left out only where they are a real share of the level
    // ([`rests::MIN_REST_SHARE`]) and enough motion remains for the blocks of the standard
    // errors (a record that hardly moves is identified as it is).
    let moving = |r: &[(usize, usize)], summary: &RestSummary, n: usize| {
        !r.is_empty()
            && summary.samples as f64 >= rests::MIN_REST_SHARE * n as f64
            && n.saturating_sub(summary.samples) >= n_blocks.saturating_mul(4)
    };
    let found: Vec<Option<(rests::Intervals, RestSummary)>> = found
        .into_iter()
        .zip(&stats)
        .map(|(f, st)| {
            f.map(|(r, summary)| {
                if r.is_empty() || moving(&r, &summary, st.n) {
                    (r, summary)
                } else {
                    (
                        Vec::new(),
                        RestSummary {
                            intervals: 0,
                            samples: 0,
                            ..summary
                        },
                    )
                }
            })
        })
        .collect();

    let t_pass = Instant::now();
    let results: Vec<(LevelMoments, PhaseTimes)> = crate::first_error_in_order(
        sources
            .par_iter()
            .zip(&stats)
            .zip(&noise_var)
            .zip(&found)
            .enumerate()
            .map(|(level, (((src, st), var), rest))| {
                let mut acc = match rest {
                    Some((r, summary)) if moving(r, summary, st.n) => {
                        let (bounds, kept) = rests::layout(st.n, n_blocks, r);
                        LevelAccumulator::with_blocks(
                            &plan, eval, st.ts, st.n, bounds, kept, opts.hold,
                        )
                    }
                    _ => LevelAccumulator::new(&plan, eval, st.ts, st.n, n_blocks, opts.hold),
                };
                // Delayed column drivers wait out the widest velocity window of the level.
                let widest = estimators
                    .get(level)
                    .map_or(0, |e| e.designs().iter().map(|d| d.2).max().unwrap_or(0));
                acc.set_root_delay(widest + 1);
                acc.set_extra_widths(noise::extra_widths(&plan, &st.noise_var, &st.std));
                let mut read = Duration::ZERO;
                let mut t_read = Instant::now();
                src.stream(opts.chunk_len, &mut |cols, len| {
                    read += t_read.elapsed();
                    acc.push(cols, len);
                    t_read = Instant::now();
                })?;
                if let Some((root, k, value)) = acc.non_finite {
                    return Err(non_finite_term(ir, &plan, *src, root, k, value));
                }
                let (mut m, mut t) = acc.finish();
                if let Some(col) = m.overflowed_column() {
                    return Err(IdentifyError::Overflow {
                        origin: src.origin(),
                        term: column_label(ir, &plan, col),
                    });
                }
                noise::debias(&plan, &mut m, var, opts.hold);
                t.read = read;
                Ok::<_, IdentifyError>((m, t))
            }),
    )?;
    let mut times = PhaseTimes {
        read: stats_time,
        pass: t_pass.elapsed(),
        ..Default::default()
    };
    let mut lm = Vec::new();
    for (m, t) in results {
        times += t;
        lm.push(m);
    }
    let infos = stats
        .iter()
        .zip(levels)
        .zip(&lm)
        .zip(&found)
        .map(|(((s, src), m), rest)| LevelInfo {
            origin: src.origin(),
            samples: s.n,
            ts: s.ts,
            std: plan
                .y
                .iter()
                .zip(&s.std)
                .map(|(sig, sd)| (ir.signal(*sig).name.clone(), *sd))
                .collect(),
            mean: plan
                .y
                .iter()
                .zip(&s.mean)
                .map(|(sig, m)| (ir.signal(*sig).name.clone(), *m))
                .collect(),
            noise: plan
                .y
                .iter()
                .zip(&s.noise_var)
                .map(|(sig, v)| (ir.signal(*sig).name.clone(), v.sqrt()))
                .collect(),
            blocks: m.kept_blocks(),
            rests: rest.as_ref().map(|(_, summary)| summary.clone()),
        })
        .collect();
    let centred = stats
        .iter()
        .map(|s| {
            plan.drivers.iter().all(|d| {
                plan.y_of[d.index()].is_none_or(|k| {
                    s.mean[k].abs() <= CENTRED_REL * s.std[k].max(f64::MIN_POSITIVE)
                })
            })
        })
        .collect();
    Ok(Moments {
        ir,
        store: Arc::new(ColumnStore::new(plan.clone(), lm)),
        cols: None,
        plan,
        infos,
        centred,
        estimated,
        rcond: opts.rcond,
        times,
        prune_t: 0.0,
        noise,
        efficient: opts.efficient,
    })
}

/// Decide the noise corrections from the first-pass statistics: attach them to the plan
/// where a signal in a nonlinear term carries significant noise, and return per level the
/// noise variance of each measured signal to correct for (zero where it is not
/// significant or the correction is off), with the summary for the report.
fn noise_plan(
    ir: &ModelIr,
    plan: &mut Plan,
    stats: &[LevelStats],
    enabled: bool,
) -> (Vec<Vec<f64>>, NoiseSummary) {
    let significant = |st: &LevelStats, k: usize| {
        st.noise_flat[k]
            && st.std[k] > 0.0
            && st.noise_var[k].sqrt() >= noise::SIGNIFICANT * st.std[k]
    };
    let noisy: Vec<SignalId> = (0..plan.y.len())
        .filter(|&k| stats.iter().any(|st| significant(st, k)))
        .map(|k| plan.y[k])
        .collect();
    let mut summary = NoiseSummary {
        fraction: plan
            .y
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let f = stats
                    .iter()
                    .map(|st| {
                        if st.std[k] > 0.0 {
                            st.noise_var[k].sqrt() / st.std[k]
                        } else {
                            0.0
                        }
                    })
                    .fold(0.0, f64::max);
                (ir.signal(*s).name.clone(), f)
            })
            .collect(),
        enabled,
        uncertain: (0..plan.y.len())
            .filter(|&k| stats.iter().any(|st| !st.noise_flat[k]))
            .map(|k| ir.signal(plan.y[k]).name.clone())
            .collect(),
        ..Default::default()
    };
    if enabled && !noisy.is_empty() {
        noise::attach(plan, ir);
    }
    summary.uncorrected = noise::uncorrected(plan, ir, &noisy);
    let var = stats
        .iter()
        .map(|st| {
            (0..plan.y.len())
                .map(|k| {
                    if enabled && significant(st, k) {
                        st.noise_var[k]
                    } else {
                        0.0
                    }
                })
                .collect::<Vec<f64>>()
        })
        .collect::<Vec<_>>();
    for f in &plan.fixes {
        if var.iter().any(|v| noise::form_variance(&f.lin, v) > 0.0) {
            summary.corrected.push(f.label.clone());
        }
    }
    (var, summary)
}

pub(super) fn choose_bank(
    ir: &ModelIr,
    opts: &IdentifyOptions,
) -> Result<BankChoice, IdentifyError> {
    let spec = ir.filter.as_ref();
    let drivers = match (&opts.drivers, spec.map(|f| &f.driven_by)) {
        (Some(d), _) => d.clone(),
        (None, Some(d)) if !d.is_empty() => d.clone(),
        _ => ir
            .measured_signals()
            .into_iter()
            .filter(|s| {
                matches!(
                    ir.signal(*s).kind,
                    SignalKind::Position(_) | SignalKind::Input(_) | SignalKind::Acceleration(_)
                )
            })
            .collect(),
    };
    // Accelerations from positions alone need ι'' free of the driving signal: degree ≥ 3.
    let needs_second = ir.equations.iter().any(|eq| {
        eq.terms.iter().any(|t| match t.basis {
            dynid_ir::ir::Basis::Deriv { body, order: 2 } => !ir.signal(ir.velocity(body)).measured,
            _ => false,
        })
    });
    // Integrals of accelerations need band-pass instruments `ζᵢ''` with `i ≥ 4`.
    let accelerations =
        (0..ir.bodies.len()).any(|b| ir.acceleration_only(dynid_ir::ir::BodyId(b as u32)));
    let min_degree = if accelerations {
        super::plan::ACC_MIN_DEGREE
    } else if needs_second {
        3
    } else {
        2
    };
    let order = opts
        .order
        .or(spec.map(|f| f.order as usize))
        .unwrap_or(min_degree + 1);
    if order < min_degree || order > 8 {
        return Err(IdentifyError::BadOption {
            message: format!("filter order {order}"),
            help: format!("use an order between {min_degree} and 8 for this model"),
        });
    }
    let n_corners = match (&opts.corners, spec.map(|f| &f.corners)) {
        (Some(c), _) => c.len(),
        (None, Some(c)) if !c.is_empty() => c.len(),
        _ => opts.n_corners,
    };
    Ok(BankChoice {
        regressors: opts.column_chains,
        drivers,
        order,
        min_degree,
        n_corners,
    })
}

/// First-pass statistics of a level: length, spread, dominant frequencies.
struct LevelStats {
    n: usize,
    ts: f64,
    std: Vec<f64>,
    /// Mean per measured signal.
    mean: Vec<f64>,
    omegas: Vec<f64>,
    /// Estimated white-noise variance per measured signal.
    noise_var: Vec<f64>,
    /// Whether that estimate comes from a flat floor ([`noise::NoiseFloor::flat`]).
    noise_flat: Vec<bool>,
    /// Per measured signal: the highest frequency (rad/s) where it stands above its noise
    /// floor ([`noise::BandFloor::info_bandwidth`]).
    info: Vec<Option<f64>>,
}

/// Samples per piece of the first pass: a streamed chunk of a signal is cut into pieces
/// taken in parallel (over time, not only over signals) and joined in order.
const PIECE: usize = 2048;

/// The first pass's statistics of one measured signal, accumulated chunk by chunk.
#[derive(Default)]
struct SignalPass {
    /// The first sample: sums are taken about it (no cancellation for a large mean).
    shift: f64,
    s1: f64,
    s2: f64,
    /// Hysteresis zero-crossing count about a reference (mean, band) from the record's
    /// first [`REFERENCE_LEN`] samples.
    reference: (f64, f64),
    side: i8,
    crossings: usize,
    floor: noise::NoiseFloor,
    /// Third differences at octave strides: the band above the noise floor.
    band: noise::BandFloor,
    screen: screen::ColumnScreen,
}

/// One piece's share of a [`SignalPass`]: its sums, its noise floor sums, and its side
/// changes as seen without knowing the side it starts on.
struct PiecePass {
    s1: f64,
    s2: f64,
    floor: noise::NoiseFloor,
    /// The first and the last side met (0: none), and the changes of side after the first.
    first: i8,
    last: i8,
    changes: usize,
}

impl PiecePass {
    /// `c` is the piece, `floor` a floor ready to take it (its sums zero).
    fn of(c: &[f64], shift: f64, (above, below): (f64, f64), mut floor: noise::NoiseFloor) -> Self {
        // Sums in four independent lanes (no wait on the previous addition).
        let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
        let mut chunks = c.chunks_exact(4);
        for (q, ch) in (&mut chunks).enumerate() {
            if q % 2 == 0 {
                // The piece comes from memory, and is too short for the processor's own
                // prefetching to lock on.
                crate::prefetch::ahead(c, 4 * q);
            }
            for j in 0..4 {
                let d = ch[j] - shift;
                a[j] += d;
                b[j] += d * d;
            }
        }
        for (j, &v) in chunks.remainder().iter().enumerate() {
            let d = v - shift;
            a[j] += d;
            b[j] += d * d;
        }
        floor.push(c);
        // Side changes: a block of eight samples with none beyond the far side of the band
        // changes nothing (one vectorised test per block; a change of side is rare).
        let (mut first, mut side, mut changes) = (0i8, 0i8, 0usize);
        for block in c.chunks(8) {
            fn any(block: &[f64], f: impl Fn(f64) -> bool) -> bool {
                block.iter().fold(false, |a, &v| a | f(v))
            }
            let quiet = match side {
                1 => !any(block, |v| v < below),
                -1 => !any(block, |v| v > above),
                _ => !any(block, |v| v < below || v > above),
            };
            if quiet {
                continue;
            }
            for &v in block {
                let now = i8::from(v > above) - i8::from(v < below);
                if now != 0 && now != side {
                    if side != 0 {
                        changes += 1;
                    } else {
                        first = now;
                    }
                    side = now;
                }
            }
        }
        PiecePass {
            s1: (a[0] + a[1]) + (a[2] + a[3]),
            s2: (b[0] + b[1]) + (b[2] + b[3]),
            floor,
            first,
            last: side,
            changes,
        }
    }
}

/// Samples at the start of a record that give the zero-crossing count its reference (the
/// first chunk where a chunk is shorter), so that the count, and the filter corners
/// designed from it, do not depend on the chunk length above it.
const REFERENCE_LEN: usize = 8192;

impl SignalPass {
    fn push(&mut self, c: &[f64], first: bool) {
        if first {
            self.shift = c[0];
            let r = &c[..c.len().min(REFERENCE_LEN)];
            let mean = r.iter().sum::<f64>() / r.len() as f64;
            let var = r.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / r.len() as f64;
            self.reference = (mean, 0.25 * var.sqrt());
        }
        let (mid, h) = self.reference;
        let band = (mid + h, mid - h);
        let (shift, seen) = (self.shift, self.floor.seen());
        // The pieces in parallel: the first continues this signal's floor, every other one
        // starts after the nine samples before it in the chunk (`PIECE` ≥ 9).
        let base = &self.floor;
        let parts: Vec<PiecePass> = (0..c.len().div_ceil(PIECE))
            .into_par_iter()
            .map(|p| {
                let a = p * PIECE;
                let piece = &c[a..(a + PIECE).min(c.len())];
                let floor = if a == 0 {
                    base.emptied()
                } else {
                    noise::NoiseFloor::resume(&c[a - 9..a], seen + a)
                };
                PiecePass::of(piece, shift, band, floor)
            })
            .collect();
        // Joined in order: the same side changes as one sample-by-sample scan.
        for p in &parts {
            self.s1 += p.s1;
            self.s2 += p.s2;
            self.floor.absorb(&p.floor);
            if p.first != 0 {
                if self.side != 0 && p.first != self.side {
                    self.crossings += 1;
                }
                self.crossings += p.changes;
                self.side = p.last;
            }
        }
        self.band.push(c);
        self.screen.push(c);
    }
}

fn level_stats(
    ir: &ModelIr,
    plan: &Plan,
    src: &dyn LevelSource,
    chunk: usize,
) -> Result<LevelStats, IdentifyError> {
    let ny = plan.y.len();
    let mut n = 0usize;
    // Each signal on its own, and each chunk of it in pieces (in parallel: a level's
    // signals and pieces balance the threads when the levels alone do not).
    let mut sigs: Vec<SignalPass> = (0..ny).map(|_| SignalPass::default()).collect();
    src.stream(chunk, &mut |cols, len| {
        sigs.par_iter_mut()
            .zip(&plan.y)
            .for_each(|(st, s)| st.push(&cols[s.index()][..len], n == 0));
        n += len;
    })?;
    let screens: Vec<screen::ColumnScreen> = sigs
        .iter_mut()
        .map(|st| std::mem::take(&mut st.screen))
        .collect();
    let nf = n.max(1) as f64;
    let std: Vec<f64> = sigs
        .iter()
        .map(|st| {
            let m = st.s1 / nf;
            (st.s2 / nf - m * m).max(0.0).sqrt()
        })
        .collect();
    let mean: Vec<f64> = sigs.iter().map(|st| st.shift + st.s1 / nf).collect();
    check_magnitudes(ir, plan, src, &std, &mean)?;
    screen_level(ir, plan, src, &screens)?;
    let ts = src.ts();
    let duration = (n.max(2) - 1) as f64 * ts;
    Ok(LevelStats {
        n,
        ts,
        std,
        mean,
        omegas: sigs
            .iter()
            .zip(&plan.y)
            .filter(|(st, s)| plan.drivers.contains(s) && st.crossings > 0)
            .map(|(st, _)| std::f64::consts::PI * st.crossings as f64 / duration)
            .collect(),
        noise_var: sigs.iter().map(|st| st.floor.variance()).collect(),
        noise_flat: sigs.iter().map(|st| st.floor.flat()).collect(),
        info: sigs
            .iter()
            .map(|st| st.band.info_bandwidth(st.floor.variance(), ts))
            .collect(),
    })
}

/// Smallest magnitude (larger of spread and mean) of a measured column that is not zero:
/// the moments are products of filtered signals, and below this their squares leave the
/// normal range of double precision (about 2e-308), where precision is lost digit by digit
/// and row weights become infinite.
pub(crate) const TINY_SIGNAL: f64 = 1e-150;

/// Refuse a level with a column so small that the products of its values underflow double
/// precision (units legitimately scale data, but not by 10^-150).
fn check_magnitudes(
    ir: &ModelIr,
    plan: &Plan,
    src: &dyn LevelSource,
    std: &[f64],
    mean: &[f64],
) -> Result<(), IdentifyError> {
    for (k, (s, m)) in std.iter().zip(mean).enumerate() {
        let size = s.max(m.abs());
        if size > 0.0 && size < TINY_SIGNAL {
            return Err(IdentifyError::Underflow {
                origin: src.origin(),
                column: ir.signal(plan.y[k]).name.clone(),
                size,
            });
        }
    }
    Ok(())
}

/// Refuse a level without motion or with a sample far outside its column's spread
/// ([`screen`]).
fn screen_level(
    ir: &ModelIr,
    plan: &Plan,
    src: &dyn LevelSource,
    screens: &[screen::ColumnScreen],
) -> Result<(), IdentifyError> {
    let ir_name = |k: usize| ir.signal(plan.y[k]).name.clone();
    if !screens.is_empty() && screens.iter().all(|s| s.constant()) {
        return Err(IdentifyError::NoExcitation {
            origin: src.origin(),
            columns: (0..screens.len())
                .map(|k| format!("`{}`", ir_name(k)))
                .collect::<Vec<_>>()
                .join(", "),
        });
    }
    for (k, sc) in screens.iter().enumerate() {
        if let Some(o) = sc.outlier() {
            let num = |v: f64| dynid_ir::num::sig(v, 4, false);
            return Err(IdentifyError::Outlier {
                origin: src.origin(),
                at: src.locate(o.sample),
                sample: o.sample,
                column: ir_name(k),
                detail: format!(
                    "{} lies {:.1e} robust standard deviations from the column's median \
                     ({}, robust std {})",
                    num(o.value),
                    (o.value - o.median).abs() / o.scale,
                    num(o.median),
                    num(o.scale)
                ),
            });
        }
    }
    Ok(())
}

/// The name of column `col` of `w` (a basis root, a measured signal, or a noise column).
fn column_label(ir: &ModelIr, plan: &Plan, col: usize) -> String {
    let n_g = plan.roots.len();
    if col < n_g {
        dynid_ir::print::render_expr(ir, plan.roots[col])
    } else if let Some(s) = plan.y.get(col - n_g) {
        ir.signal(*s).name.clone()
    } else {
        "a noise-correction column".into()
    }
}

/// The error for a basis root that is not finite at sample `k` of `src`.
fn non_finite_term(
    ir: &ModelIr,
    plan: &Plan,
    src: &dyn LevelSource,
    root: usize,
    k: usize,
    value: f64,
) -> IdentifyError {
    let e = plan.roots[root];
    let signals = ir
        .expr_signals(e)
        .iter()
        .map(|s| format!("`{}`", ir.signal(*s).name))
        .collect::<Vec<_>>()
        .join(", ");
    let advice = if value.is_nan() {
        format!(
            "the term is undefined for the values of {signals} there (e.g. `sqrt` or `log` of \
             a negative number): write it so that it is defined for every value the data take \
             (e.g. `sqrt(abs(s))`), or check the data"
        )
    } else {
        format!(
            "the term overflows double precision for the values of {signals} there: rescale \
             the data or the term (e.g. `exp(s / s0)` with a larger `s0`, a lower power)"
        )
    };
    IdentifyError::NonFiniteTerm {
        origin: src.origin(),
        term: dynid_ir::print::render_expr(ir, e),
        at: src.locate(k),
        value,
        advice,
    }
}

/// "N samples" for a count a record can have; for a count that no record holds (a corner
/// of 1e-300 rad/s asks for more samples than a 64-bit count) the duration instead.
fn samples_needed(n: usize, seconds: f64) -> String {
    if n < 1 << 53 {
        format!("{n} samples")
    } else {
        format!(
            "{} s of data (more samples than any record holds)",
            dynid_ir::num::sig(seconds, 4, false)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A smooth random signal with noise: many crossings, every side of the band.
    fn signal(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut u = 0.0;
        (0..n)
            .map(|_| {
                u = 0.98 * u + 0.2 * (rng.random::<f64>() - 0.5);
                3.0 + u + 0.01 * (rng.random::<f64>() - 0.5)
            })
            .collect()
    }

    #[test]
    fn pieces_give_the_crossings_and_floor_of_one_scan() {
        let x = signal(50_000, 5);
        let whole = {
            let mut f = noise::NoiseFloor::default();
            f.push(&x);
            f
        };
        let mut long_chunks = None;
        for chunk in [50_000, 8192, 4097, 2048, 300, 7] {
            let mut sp = SignalPass::default();
            for (i, c) in x.chunks(chunk).enumerate() {
                sp.push(c, i == 0);
            }
            // Chunks of at least REFERENCE_LEN samples: one reference, so one count.
            if chunk >= REFERENCE_LEN {
                let got = (sp.reference, sp.crossings);
                assert_eq!(*long_chunks.get_or_insert(got), got, "chunks of {chunk}");
            }
            // The hysteresis count of a sample-by-sample scan about the same reference.
            let (mid, h) = sp.reference;
            let (mut side, mut crossings) = (0i8, 0usize);
            for &v in &x {
                let now = if v > mid + h {
                    1
                } else if v < mid - h {
                    -1
                } else {
                    0
                };
                if now != 0 && now != side {
                    crossings += usize::from(side != 0);
                    side = now;
                }
            }
            assert!(crossings > 50, "{crossings}");
            assert_eq!(
                (sp.crossings, sp.side),
                (crossings, side),
                "chunks of {chunk}"
            );
            assert_eq!(sp.floor.seen(), x.len());
            for h in 1..=3 {
                let (a, b) = (sp.floor.mean_square(h), whole.mean_square(h));
                assert!((a / b - 1.0).abs() < 1e-12, "chunks of {chunk}, stride {h}");
            }
            let mean = sp.shift + sp.s1 / x.len() as f64;
            let want = x.iter().sum::<f64>() / x.len() as f64;
            assert!((mean - want).abs() < 1e-12, "chunks of {chunk}");
        }
    }
}
