use super::*;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;

#[test]
fn chi_square_tails_and_quantiles_match_tabulated_values() {
    // χ²(2) has the closed-form tail e^(−x/2).
    for x in [0.5, 3.0, 10.0, 40.0] {
        let t = chi2_upper_tail(x, 2);
        assert!((t / (-x / 2.0_f64).exp() - 1.0).abs() < 1e-12, "{x}: {t}");
    }
    // The 95 % and 99 % points of χ²(1), χ²(3) and χ²(5) (Abramowitz & Stegun, table 26.8).
    for (q, dof, x) in [
        (0.95, 1, 3.841_458_820_694_124),
        (0.95, 3, 7.814_727_903_251_178),
        (0.99, 3, 11.344_866_730_144_373),
        (0.99, 5, 15.086_272_469_388_99),
    ] {
        assert!((chi2_quantile(q, dof) - x).abs() < 1e-8 * x, "{q} {dof}");
        assert!(
            (chi2_upper_tail(x, dof) - (1.0 - q)).abs() < 1e-12,
            "{q} {dof}"
        );
    }
    assert!((normal_quantile(0.975) - 1.959_963_984_540_054).abs() < 1e-12);
    // Far in the tail the p-value stays a positive finite number.
    let p = chi2_upper_tail(1200.0, 3);
    assert!(p > 0.0 && p < 1e-250, "{p}");
    assert_eq!(chi2_upper_tail(0.0, 3), 1.0);
}

const NAMES: [&str; 3] = ["k", "d", "r"];
const NOMINAL: [f64; 3] = [4.0, 0.4, 0.3];

/// A machine with `values` and a covariance of relative standard errors `rel` and a
/// correlation of −0.5 between `d` and `r`.
fn machine(name: &str, values: [f64; 3], rel: f64) -> Machine {
    let se: Vec<f64> = values.iter().map(|v| rel * v.abs()).collect();
    let mut covariance = vec![0.0; 9];
    for (i, se) in se.iter().enumerate() {
        covariance[i * 3 + i] = se * se;
    }
    covariance[5] = -0.5 * se[1] * se[2];
    covariance[7] = covariance[5];
    Machine {
        name: name.into(),
        estimate: Ok(MachineEstimate {
            names: NAMES.iter().map(|s| s.to_string()).collect(),
            values: values.to_vec(),
            covariance,
            unidentifiable: Vec::new(),
            equations: vec!["m".into()],
        }),
    }
}

/// `n` machines: parameters 3 % around the nominal (between machines), estimated with 0.5 %
/// standard errors (drawn from them as well); machine `f` for `f` in `faults` with `r`
/// doubled.
fn fleet(n: usize, faults: &[usize], seed: u64) -> Vec<Machine> {
    let mut rng = StdRng::seed_from_u64(seed);
    (0..n)
        .map(|i| {
            let mut v = NOMINAL;
            for x in v.iter_mut() {
                let g: f64 = rng.sample(StandardNormal);
                let e: f64 = rng.sample(StandardNormal);
                *x *= 1.0 + 0.03 * g + 0.005 * e;
            }
            if faults.contains(&i) {
                v[2] *= 2.0;
            }
            machine(&format!("m{i:03}"), v, 0.005)
        })
        .collect()
}

#[test]
fn a_fleet_with_spread_flags_only_its_faulty_machines_and_names_what_moved() {
    let faults = [3, 50, 120];
    let machines = fleet(200, &faults, 11);
    let view = assess(&machines, &FleetOptions::default()).unwrap();
    let flagged: Vec<&str> = view.flagged().map(|m| m.name.as_str()).collect();
    assert_eq!(flagged, ["m003", "m050", "m120"]);
    for m in view.flagged() {
        assert_eq!(m.moved[0].name, "r", "{m:?}");
        let ratio = m.moved[0].ratio.unwrap();
        assert!((ratio - 2.0).abs() < 0.25, "{m:?}");
    }
    assert_eq!(view.tested, 200);
    assert_eq!(view.held, 197);
    // The between-machine spread found is the 3 % drawn (sampling spread of a standard
    // deviation from 197 machines: 5 %), the within the 0.5 %.
    for (p, nominal) in view.params.iter().zip(NOMINAL) {
        let rel = p.spread / nominal;
        assert!((rel - 0.03).abs() < 0.15 * 0.03, "{p:?}");
        assert!((p.within / nominal - 0.005).abs() < 0.001, "{p:?}");
        assert!((p.value / nominal - 1.0).abs() < 4.0 * 0.03 / 14.0, "{p:?}");
    }
    // Against the pooled value with each machine's own covariance alone, most healthy
    // machines are flagged: the spread of real parts is not a fault.
    let naive = assess(
        &machines,
        &FleetOptions {
            between: false,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(naive.flagged().count() > 100, "{}", naive.flagged().count());
}

#[test]
fn failed_and_rank_deficient_machines_are_listed_not_dropped() {
    let mut machines = fleet(30, &[], 2);
    machines[4].estimate = Err("no data".into());
    if let Ok(e) = &mut machines[7].estimate {
        // `r` not identified: only `k` and `d` are left.
        e.names.truncate(2);
        e.values.truncate(2);
        e.covariance = vec![
            e.covariance[0],
            e.covariance[1],
            e.covariance[3],
            e.covariance[4],
        ];
        e.unidentifiable = vec![("r".into(), "collinear with `d`".into())];
    }
    let view = assess(&machines, &FleetOptions::default()).unwrap();
    assert_eq!(view.machines.len(), 30);
    assert_eq!(view.tested, 28);
    assert_eq!(view.machines[4].status, Status::Failed);
    assert!(view.machines[4].note.as_ref().unwrap().contains("no data"));
    let m7 = &view.machines[7];
    assert_eq!(m7.status, Status::RankDeficient);
    assert!(m7.test.is_none());
    assert_eq!(m7.params.len(), 2);
    assert!(
        m7.note
            .as_ref()
            .unwrap()
            .contains("`r` (collinear with `d`)"),
        "{m7:?}"
    );
    assert_eq!(view.flagged().count(), 0);
}

#[test]
fn a_singular_covariance_is_tested_in_the_directions_it_determines() {
    // Every machine's `k` and `d` move together exactly (a covariance of rank 2 and no
    // spread of `d` but along `k`): the last machine moves `d` across that direction.
    let machines: Vec<Machine> = (0..20)
        .map(|i| {
            let t = 1.0 + 0.01 * (i as f64 - 9.5);
            let mut m = machine(&format!("m{i}"), [4.0 * t, 0.4 * t, 0.3], 0.0);
            if let Ok(e) = &mut m.estimate {
                e.covariance = vec![1.6e-3, 1.6e-4, 0.0, 1.6e-4, 1.6e-5, 0.0, 0.0, 0.0, 1e-6];
            }
            m
        })
        .collect();
    let view = assess(&machines, &FleetOptions::default()).unwrap();
    assert_eq!(view.flagged().count(), 0);
    let t = view.machines[0].test.as_ref().unwrap();
    assert_eq!(t.dof, 2, "{view:#?}");
    assert!(view.machines[0].note.as_ref().unwrap().contains("2 of 3"));
    assert!(t.d2.is_finite() && t.condition >= MAX_CONDITION, "{t:?}");
}

#[test]
fn machines_of_other_models_and_bad_options_are_refused() {
    let mut machines = fleet(20, &[], 1);
    let err = |m: &[Machine], o: &FleetOptions| assess(m, o).unwrap_err().to_string();
    let o = FleetOptions::default();
    assert!(err(
        &machines,
        &FleetOptions {
            alpha: 1.5,
            ..o.clone()
        }
    )
    .contains("α = 1.5"));
    assert!(
        err(&machines[..7], &o).contains("7 machine(s)"),
        "{}",
        err(&machines[..7], &o)
    );
    machines[5].name = "m004".into();
    assert!(err(&machines, &o).contains("two machines are named `m004`"));
    machines[5].name = "m005".into();
    if let Ok(e) = &mut machines[9].estimate {
        e.names[2] = "fc".into();
    }
    let e = err(&machines, &o);
    assert!(
        e.contains("m009 is not of the same model as m000") && e.contains("`fc` only in m009"),
        "{e}"
    );
    if let Ok(e) = &mut machines[9].estimate {
        e.names[2] = "r".into();
        e.equations = vec!["m2".into()];
    }
    assert!(err(&machines, &o).contains("its equations differ"));
}

#[test]
fn a_held_set_that_alternates_keeps_the_machines_held_in_every_round() {
    // Settles: the second round gives back its own set.
    let step = |h: &[bool]| Ok::<_, ()>(vec![true, h[0], true]);
    let (held, s) = settle(vec![true, false, false], MAX_ROUNDS, step).expect("no error");
    assert_eq!(held, [true, true, true]);
    assert_eq!(
        s,
        Settling {
            rounds: 2,
            alternated: None
        }
    );
    // A fit on {0, 1} rejects 1 and holds 2, a fit on {0, 2} the other way round.
    let flip = |h: &[bool]| Ok::<_, ()>(vec![true, h[2], h[1]]);
    let (held, s) = settle(vec![true, true, false], MAX_ROUNDS, flip).expect("no error");
    assert_eq!(held, [true, false, false]);
    assert_eq!(
        s,
        Settling {
            rounds: 2,
            alternated: Some(2)
        }
    );
    // One round only (no between-machine spread): whatever it gives, it stops.
    let (held, s) = settle(vec![true, true, false], 1, flip).expect("no error");
    assert_eq!(held, [true, true, false]);
    assert_eq!(
        s,
        Settling {
            rounds: 1,
            alternated: None
        }
    );
    // A walk that never repeats within the bound keeps what every round held.
    let mut round = 0;
    let walk = |_: &[bool]| {
        round += 1;
        let mut h = vec![true; 8];
        h[round % 7 + 1] = false;
        Ok::<_, ()>(h)
    };
    let (held, s) = settle(vec![true; 8], 4, walk).expect("no error");
    // Sets seen: the start, then 2, 3, 4 and 5 left out in turn.
    assert_eq!(
        s,
        Settling {
            rounds: 4,
            alternated: Some(5)
        }
    );
    assert_eq!(held, [true, true, false, false, false, false, true, true]);
}
