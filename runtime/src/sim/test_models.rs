//! Small models for tests of the back ends, written in the modelling language and compiled
//! by the front end; nominal values and form filters are then set on the IR directly.
//! Not part of the stable API.

use dynid_ir::ir::*;

/// Parameters of `m x'' + d x' + k x + k3 x³ + r sign(x') = u`; `m` is known, the others
/// are unknown with these nominal values. A `None` term is left out of the model.
#[derive(Clone, Debug)]
pub struct SdofParams {
    pub m: f64,
    pub d: f64,
    pub k: f64,
    pub k3: Option<f64>,
    pub r: Option<f64>,
}

impl SdofParams {
    /// The benchmark of the method note: m=1, d=0.4, k=4, k3=2, r=0.3.
    pub fn benchmark() -> Self {
        SdofParams {
            m: 1.0,
            d: 0.4,
            k: 4.0,
            k3: Some(2.0),
            r: Some(0.3),
        }
    }
    pub fn linear(m: f64, d: f64, k: f64) -> Self {
        SdofParams {
            m,
            d,
            k,
            k3: None,
            r: None,
        }
    }
}

/// The SDOF oscillator on body `m1` (signals `m1.x`, `m1.v`, `u`) excited through `filter`.
pub fn sdof(p: &SdofParams, filter: FormFilter, levels: Vec<f64>) -> ModelIr {
    let mut force = Vec::new();
    if p.k3.is_some() {
        force.push("k3 ~ 1 * s^3");
    }
    if p.r.is_some() {
        force.push("r ~ 1 * sign(v)");
    }
    let force = if force.is_empty() {
        String::new()
    } else {
        format!("force nl (ground, m1) = {}\n", force.join(" + "))
    };
    let mut ir = compile(&format!(
        "model sdof {{
            body m1 = {m:?}
            input u on m1
            damper d (ground, m1) ~ 1
            spring k (ground, m1) ~ 1
            {force}
            excite u: white levels [1]
        }}",
        m = p.m
    ));
    let nominal = [("d", Some(p.d)), ("k", Some(p.k)), ("k3", p.k3), ("r", p.r)];
    for (name, value) in nominal {
        if let Some(v) = value {
            set_nominal(&mut ir, name, v);
        }
    }
    excite(&mut ir, filter, levels);
    ir
}

/// Two bodies in a chain, ground –(k1, d1)– m1 –(k2, d2)– m2, force `u` on `m2`; the
/// masses are known, the springs and dampers unknown with these nominal values.
pub fn two_mass_chain(
    m: [f64; 2],
    k: [f64; 2],
    d: [f64; 2],
    filter: FormFilter,
    levels: Vec<f64>,
) -> ModelIr {
    let mut ir = compile(&format!(
        "model two_mass_chain {{
            body m1 = {:?}
            body m2 = {:?}
            input u on m2
            spring k1 (ground, m1) ~ {:?}
            damper d1 (ground, m1) ~ {:?}
            spring k2 (m1, m2) ~ {:?}
            damper d2 (m1, m2) ~ {:?}
            excite u: white levels [1]
        }}",
        m[0], m[1], k[0], d[0], k[1], d[1]
    ));
    excite(&mut ir, filter, levels);
    ir
}

/// The source of a chain of `n` unit masses from a wall, springs and dampers between
/// neighbours, driven at the free end, every position measured: a model whose size grows
/// with `n` (for memory estimates and limits).
pub fn chain_source(n: usize) -> String {
    let mut s = format!("model chain{n} {{\n");
    for i in 1..=n {
        s += &format!("    body m{i} = 1.0\n");
    }
    s += &format!("    input u on m{n}\n    measure ");
    for i in 1..=n {
        s += &format!("m{i}.x, ");
    }
    s += "u\n";
    for i in 1..=n {
        let a = if i == 1 {
            "ground".to_string()
        } else {
            format!("m{}", i - 1)
        };
        s += &format!("    spring k{i} ({a}, m{i}) ~ 4.0\n    damper d{i} ({a}, m{i}) ~ 0.4\n");
    }
    s + "    excite u: lowpass(corner = 10) levels [6, 15, 40]\n}\n"
}

fn compile(src: &str) -> ModelIr {
    dsl_parser::compile_str("test_model.dyn", src)
        .unwrap_or_else(|e| panic!("test model does not compile: {e:?}\n{src}"))
}

/// Nominal values are set on the IR, not in the text, so tests may use values the
/// language would reject (negative damping for divergence tests).
fn set_nominal(ir: &mut ModelIr, name: &str, value: f64) {
    let p = ir.params.iter_mut().find(|p| p.name == name).unwrap();
    p.kind = ParamKind::Unknown {
        nominal: Some(value),
    };
}

/// The form filter is set on the IR for the same reason (a zero corner must reach the
/// simulator's own check).
fn excite(ir: &mut ModelIr, filter: FormFilter, levels: Vec<f64>) {
    ir.excitation[0].filter = filter;
    ir.excitation[0].levels = levels;
}

/// A servo axis: one body of unknown mass on a guide with viscous and Coulomb friction,
/// driven by the force `u` of a PD position controller, its position read by an encoder;
/// velocity is not recorded. [`ServoAxis::model`] and [`ServoAxis::config`] give the model
/// and the closed-loop simulation settings; [`ServoAxis::true_model`] is the model to
/// simulate, with the forces of [`ServoAxis::model_error`] that the identification model
/// lacks.
#[derive(Clone, Debug)]
pub struct ServoAxis {
    /// Nominal value of the unknown mass `m`.
    pub mass: f64,
    /// Nominal viscous friction `d` (force per velocity).
    pub viscous: f64,
    /// Nominal Coulomb friction `r` (`r·sign(v)`).
    pub coulomb: f64,
    /// Further forces on the body as `(element name, right-hand side in the modelling
    /// language)`, each added as `force <name> (ground, m) = <rhs>`.
    pub extra_forces: Vec<(String, String)>,
    /// Forces of the simulated axis that the identification model [`ServoAxis::model`]
    /// does not contain, as `extra_forces` (all known: e.g. [`ServoAxis::stribeck`],
    /// [`ServoAxis::friction_ripple`], [`ServoAxis::cogging`]); only
    /// [`ServoAxis::true_model`] has them.
    pub model_error: Vec<(String, String)>,
    /// Encoder resolution in metres.
    pub resolution: f64,
    pub sample: f64,
    pub duration: f64,
    pub kp: f64,
    pub kd: f64,
    pub reference: crate::sim::ReferenceSpec,
}

impl ServoAxis {
    /// m = 50, d = 120, r = 15, 1 µm encoder, 1 kHz for 25 s. The loop: `kp = m ω²`,
    /// `kd = 2 ζ ω m − d` with ω = 40 rad/s, ζ = 0.7 (for the linear part); the reference
    /// has an RMS of 3 cm and a corner of 5 rad/s, so its velocity RMS is 0.15 m/s.
    pub fn standard() -> Self {
        let (m, d, w, z) = (50.0, 120.0, 40.0, 0.7);
        ServoAxis {
            mass: m,
            viscous: d,
            coulomb: 15.0,
            extra_forces: Vec::new(),
            model_error: Vec::new(),
            resolution: 1e-6,
            sample: 1e-3,
            duration: 25.0,
            kp: m * w * w,
            kd: 2.0 * z * w * m - d,
            reference: crate::sim::ReferenceSpec {
                rms: 0.03,
                corner: 5.0,
                smooth: true,
                planned: None,
            },
        }
    }

    /// [`ServoAxis::standard`] following planned moves instead of a random reference:
    /// [`crate::sim::Moves::servo_standard`] (10 cm out and back at 0.4, 0.2 and 0.1 m/s,
    /// peak acceleration 4 m/s², 0.33 s at rest before each move; cycles of 6.18 s, four
    /// in the 25 s record at 1 kHz), the same axis and controller.
    pub fn planned() -> Self {
        ServoAxis {
            reference: crate::sim::ReferenceSpec::planned(crate::sim::Moves::servo_standard()),
            ..ServoAxis::standard()
        }
    }

    /// A Stribeck term: friction that rises above the Coulomb value by `excess` at rest and
    /// falls back to it with speed, `excess · exp(−(v/speed)²) · sign(v)` (newtons, m/s).
    pub fn stribeck(excess: f64, speed: f64) -> (String, String) {
        (
            "stribeck".into(),
            format!("{excess:?} * exp(-(v / {speed:?})^2) * sign(v)"),
        )
    }

    /// Position-dependent friction: `amplitude · sin(2π x / period) · sign(v)` (a guide
    /// whose friction varies along the travel with `period` metres).
    pub fn friction_ripple(amplitude: f64, period: f64) -> (String, String) {
        let k = 2.0 * std::f64::consts::PI / period;
        (
            "friction_ripple".into(),
            format!("{amplitude:?} * sin({k:?} * s) * sign(v)"),
        )
    }

    /// A position-periodic force (cogging of a linear motor): `amplitude · sin(2π x /
    /// period)`.
    pub fn cogging(amplitude: f64, period: f64) -> (String, String) {
        let k = 2.0 * std::f64::consts::PI / period;
        ("cogging".into(), format!("{amplitude:?} * sin({k:?} * s)"))
    }

    /// The model to simulate: [`ServoAxis::model`] with the forces of
    /// [`ServoAxis::model_error`]. Identify its records with [`ServoAxis::model`].
    pub fn true_model(&self) -> ModelIr {
        let mut with_error = self.clone();
        with_error
            .extra_forces
            .extend(self.model_error.iter().cloned());
        with_error.model_error.clear();
        with_error.model()
    }

    /// The model `servo_axis`: body `m`, input `u`, measured `m.x` and `u`. The velocity
    /// is marked unmeasured on the IR (the language rejects `sign(v)` without a measured
    /// velocity), so records carry no `m.v` column.
    pub fn model(&self) -> ModelIr {
        let extra: String = self
            .extra_forces
            .iter()
            .map(|(name, rhs)| format!("force {name} (ground, m) = {rhs}\n"))
            .collect();
        let mut ir = compile(&format!(
            "model servo_axis {{
                body m ~ {m:?}
                input u on m
                damper d (ground, m) ~ {d:?}
                force friction (ground, m) = r ~ {r:?} * sign(v)
                {extra}
            }}",
            m = self.mass,
            d = self.viscous,
            r = self.coulomb,
        ));
        // Body 0 owns signals 0 (`m.x`) and 1 (`m.v`).
        ir.signals[1].measured = false;
        ir
    }

    /// Closed-loop settings: the controller on `u`/`m` with a position difference as its
    /// velocity, quantised positions, no measurement noise, 2 s of burn-in.
    pub fn config(&self, seed: u64) -> crate::sim::SimConfig {
        crate::sim::SimConfig {
            duration: self.duration,
            sample: self.sample,
            seed,
            burn_in: 2.0,
            quantise: Some(self.resolution),
            control: Some(crate::sim::PdControl {
                input: "u".into(),
                body: "m".into(),
                kp: self.kp,
                kd: self.kd,
                kf: 0.0,
                velocity: crate::sim::VelocitySource::Difference,
                reference: self.reference,
            }),
            ..crate::sim::SimConfig::default()
        }
    }
}

/// Add white noise of `fraction` of the spread of `column` to it, drawn from `seed`: a
/// planned record has nothing random in it (the encoder's rounding is deterministic), so
/// the seed draws the noise a drive's current measurement carries, and every seed gives
/// another record.
pub fn add_noise(rec: &mut crate::record::Record, column: &str, fraction: f64, seed: u64) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let Some(k) = rec.names.iter().position(|n| n == column) else {
        return;
    };
    let col = &mut rec.columns[k];
    let mean = col.iter().sum::<f64>() / col.len().max(1) as f64;
    let sd = (col.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / col.len().max(1) as f64).sqrt();
    let Ok(noise) = Normal::new(0.0, fraction * sd) else {
        return;
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    col.iter_mut().for_each(|v| *v += noise.sample(&mut rng));
}

/// The benchmark SDOF model at its three levels (6, 15, 40; low-pass 10 rad/s), `duration`
/// seconds after a 30 s burn-in, simulated with `substeps` and with `4 × substeps` RK4
/// sub-steps: the largest (over levels and signals) RMS difference relative to the
/// signal's std. The integration error of `substeps`.
pub fn integration_error(substeps: usize, duration: f64) -> f64 {
    let ir = sdof(
        &SdofParams::benchmark(),
        FormFilter::Lowpass { corner: 10.0 },
        vec![6.0, 15.0, 40.0],
    );
    let run = |s| {
        let cfg = super::SimConfig {
            duration,
            burn_in: 30.0,
            substeps: s,
            ..super::SimConfig::default()
        };
        super::simulate(&ir, &cfg).expect("the benchmark simulates")
    };
    let (a, b) = (run(substeps), run(4 * substeps));
    a.records
        .iter()
        .zip(&b.records)
        .flat_map(|(ra, rb)| {
            ["m1.x", "m1.v"].map(|n| {
                let (x, y) = (ra.column(n).unwrap(), rb.column(n).unwrap());
                let d: Vec<f64> = x.iter().zip(y).map(|(a, b)| a - b).collect();
                mean_square(&d).sqrt() / crate::describe::std_dev(y)
            })
        })
        .fold(0.0, f64::max)
}

/// `(RMS of the tracking error / std of the reference, lag-1 autocorrelation of u)` of a
/// servo-axis record (columns `m.x`, `m.x_ref`, `u`).
pub fn tracking(r: &crate::record::Record) -> (f64, f64) {
    let col = |n: &str| r.column(n).expect("a servo-axis record");
    let (x, xr, u) = (col("m.x"), col("m.x_ref"), col("u"));
    let e: Vec<f64> = x.iter().zip(xr).map(|(x, r)| x - r).collect();
    let err = mean_square(&e).sqrt() / crate::describe::std_dev(xr);
    let mu = crate::describe::mean(u);
    let uc: Vec<f64> = u.iter().map(|u| u - mu).collect();
    let lag1 = uc[1..].iter().zip(&uc).map(|(a, b)| a * b).sum::<f64>() / (uc.len() - 1) as f64;
    (err, lag1 / mean_square(&uc))
}

fn mean_square(x: &[f64]) -> f64 {
    x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64
}
