//! Every component's Jacobian, and the bench's, against central finite differences of
//! the right-hand side and the outputs, at random valid states and inputs, with each
//! effect on and off (issue 13). An entry is judged relative to the largest entry of its
//! row, each column weighted by its variable's typical magnitude, so entries that matter
//! must agree to `TOLERANCE`; the failure names the row and the column.

use hbmodel::component::actuator::ActuatorComponent;
use hbmodel::component::network::Network;
use hbmodel::component::valve::Valve;
use hbmodel::component::{Component, Jacobian};
use hbmodel::friction::FrictionLaw;
use hbmodel::params::{Mode, ValveModel};
use hbmodel::{actuator, manifold::Circuit, servovalve, Bench, Effect, Inputs, Params};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// Agreement required of the analytic entries, relative to the row's largest entry.
const TOLERANCE: f64 = 1e-5;

/// Agreement asked of the two-stage valve: its pilot pressure P_E is solved by Newton to
/// 1e-13 relative, so differences of the right-hand side carry that noise over their step.
const TWO_STAGE_TOLERANCE: f64 = 1e-5;

/// Typical magnitude of a variable of this unit: sizes its difference step and weights
/// its column.
fn unit_scale(unit: &str) -> f64 {
    match unit {
        "Pa" => 1e6,
        "m3/s" => 1e-5,
        "V" => 1.0,
        "N" => 1e2,
        "m" => 1e-3,
        _ => 1.0,
    }
}

/// Compare `analytic` (n_rows x n_cols) with central differences of `f` over the
/// columns, `f(column, shifted value) -> row values`.
#[allow(clippy::too_many_arguments)]
fn compare(
    what: &str,
    analytic: &[f64],
    rows: &[String],
    cols: &[(String, f64, f64)],
    f: &dyn Fn(usize, f64) -> Vec<f64>,
    tolerance: f64,
) {
    let nr = rows.len();
    let nc = cols.len();
    let mut fd = vec![0.0; nr * nc];
    for (j, (_, value, scale)) in cols.iter().enumerate() {
        let h = 1e-6 * value.abs().max(*scale);
        let (fp, fm) = (f(j, value + h), f(j, value - h));
        for i in 0..nr {
            fd[i * nc + j] = (fp[i] - fm[i]) / (2.0 * h);
        }
    }
    for i in 0..nr {
        let weighted = |m: &[f64], j: usize| m[i * nc + j] * cols[j].2;
        let row_max = (0..nc).map(|j| weighted(&fd, j).abs()).fold(0.0, f64::max);
        for j in 0..nc {
            let (a, d) = (weighted(analytic, j), weighted(&fd, j));
            // entries below a thousandth of the row's largest are judged against that
            let floor = 1e-300_f64.max(1e-3 * row_max);
            let err = (a - d).abs() / d.abs().max(floor);
            assert!(
                err <= tolerance || (a - d).abs() <= 1e-12 * row_max.max(1e-300),
                "{what}: d {} / d {}: analytic {} vs differences {} (relative error {err:e})",
                rows[i],
                cols[j].0,
                analytic[i * nc + j],
                fd[i * nc + j]
            );
        }
    }
}

/// All four blocks of a component's Jacobian at (x, u) against differences.
fn check_component(what: &str, c: &dyn Component, x: &[f64], u: &[f64], tolerance: f64) {
    let (n, m, p) = (c.states().len(), c.inputs().len(), c.outputs().len());
    let mut jac = Jacobian::zeros(n, m, p);
    c.jacobian(x, u, &mut jac);
    let dnames: Vec<String> = c
        .states()
        .iter()
        .map(|s| format!("d{}/dt", s.name))
        .collect();
    let ynames: Vec<String> = c.outputs().iter().map(|s| s.name.clone()).collect();
    let xcols: Vec<(String, f64, f64)> = c
        .states()
        .iter()
        .zip(x)
        .map(|(s, v)| (s.name.clone(), *v, s.scale))
        .collect();
    let ucols: Vec<(String, f64, f64)> = c
        .inputs()
        .iter()
        .zip(u)
        .map(|(s, v)| (s.name.clone(), *v, unit_scale(s.unit)))
        .collect();
    let at_x = |j: usize, v: f64| {
        let mut xs = x.to_vec();
        xs[j] = v;
        xs
    };
    let at_u = |j: usize, v: f64| {
        let mut us = u.to_vec();
        us[j] = v;
        us
    };
    let rhs = |x: &[f64], u: &[f64]| {
        let mut dx = vec![0.0; n];
        c.derivatives(x, u, &mut dx);
        dx
    };
    let out = |x: &[f64], u: &[f64]| {
        let mut y = vec![0.0; p];
        c.outputs_at(x, u, &mut y);
        y
    };
    // [fx | fu] and [yx | yu] as one matrix each, so that an entry is judged against
    // its row's largest over states and inputs alike
    let joined = |a: &[f64], b: &[f64], rows: usize| -> Vec<f64> {
        (0..rows)
            .flat_map(|i| a[i * n..(i + 1) * n].iter().chain(&b[i * m..(i + 1) * m]))
            .copied()
            .collect()
    };
    let cols: Vec<(String, f64, f64)> = xcols.into_iter().chain(ucols).collect();
    let shifted = |j: usize, v: f64| {
        if j < n {
            (at_x(j, v), u.to_vec())
        } else {
            (x.to_vec(), at_u(j - n, v))
        }
    };
    compare(
        &format!("{what}, derivatives"),
        &joined(&jac.fx, &jac.fu, n),
        &dnames,
        &cols,
        &|j, v| {
            let (xs, us) = shifted(j, v);
            rhs(&xs, &us)
        },
        tolerance,
    );
    compare(
        &format!("{what}, outputs"),
        &joined(&jac.yx, &jac.yu, p),
        &ynames,
        &cols,
        &|j, v| {
            let (xs, us) = shifted(j, v);
            out(&xs, &us)
        },
        tolerance,
    );
}

/// The thesis bench in `mode` with `effect` switched to `on`.
fn with(mode: u8, effect: Option<(Effect, bool)>) -> Params {
    let mut p = Params::thesis_bench(Mode::try_from(mode).unwrap());
    if let Some((e, on)) = effect {
        p.effects.set(e, on);
        if e == Effect::ManifoldInertia || e == Effect::ManifoldVolume {
            p.effects
                .set(Effect::ManifoldLosses, on && p.has(Effect::ManifoldVolume));
        }
    }
    p
}

/// Every effect off in turn, then the Sidhom law with the payload and a hot oil.
fn variants() -> Vec<(String, Params)> {
    let mut out = vec![];
    for mode in 1..=3 {
        out.push((format!("mode {mode}"), with(mode, None)));
        for e in Effect::ALL {
            let on = !Params::thesis_bench(Mode::try_from(mode).unwrap()).has(e);
            out.push((
                format!("mode {mode}, {} {on}", e.name()),
                with(mode, Some((e, on))),
            ));
        }
    }
    let mut s = with(3, Some((Effect::Payload, true)));
    s.friction.law = FrictionLaw::Sidhom;
    s.fluid.temperature = 330.0;
    out.push(("Sidhom, payload, 330 K".into(), s));
    out
}

fn random_pressure(rng: &mut Pcg64) -> f64 {
    // absolute pressures over the bench's range, some in the cavitation band
    if rng.random_bool(0.1) {
        rng.random_range(0.05e5..0.6e5)
    } else {
        rng.random_range(1e5..215e5)
    }
}

#[test]
fn reduced_valve_jacobian_matches_differences() {
    let mut rng = Pcg64::seed_from_u64(1);
    for (name, p) in variants() {
        p.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
        let v = Valve::new(servovalve::build(&p.sv1, &p).into(), "1");
        for _ in 0..4 {
            let x: Vec<f64> = (0..v.states().len())
                .map(|k| {
                    if k == 0 {
                        rng.random_range(-1.1..1.1)
                    } else {
                        rng.random_range(-300.0..300.0)
                    }
                })
                .collect();
            let u = [
                rng.random_range(-10.0..10.0),
                random_pressure(&mut rng).max(150e5),
                rng.random_range(1e5..3e5),
                random_pressure(&mut rng),
                random_pressure(&mut rng),
            ];
            check_component(&format!("valve, {name}"), &v, &x, &u, TOLERANCE);
        }
    }
}

#[test]
fn two_stage_valve_jacobian_matches_differences() {
    use hbmodel::servovalve::two_stage::{TwoStageServovalve, OMEGA, THETA, V_S, X_S};
    let mut rng = Pcg64::seed_from_u64(2);
    let mut p = Params::thesis_bench(Mode::FourWaySingle);
    p.sv1.model = ValveModel::TwoStage;
    let v = Valve::new(servovalve::build(&p.sv1, &p).into(), "1");
    let d = *TwoStageServovalve::new(&p.sv1, &p).design();
    // the flapper angle at which it touches a nozzle
    let seated = d.nozzle_gap / (d.flapper_length - 0.5 * d.tube_length);
    for (k, u0) in [0.0, 3.0, -8.0, 1.0, -1.0].into_iter().enumerate() {
        let mut x = vec![0.0; v.states().len()];
        servovalve::build(&p.sv1, &p).initial_state(u0, &mut x);
        // moving, and (the last two) pressed into a nozzle's seat
        x[OMEGA] = rng.random_range(-20.0..20.0);
        x[V_S] = rng.random_range(-0.1..0.1);
        x[X_S] += rng.random_range(-2e-5..2e-5);
        if k >= 3 {
            x[THETA] = u0 * 1.002 * seated;
        }
        let u = [
            u0 + rng.random_range(-0.5..0.5),
            p.supply_pressure,
            p.tank_pressure,
            random_pressure(&mut rng),
            random_pressure(&mut rng),
        ];
        check_component("two-stage valve", &v, &x, &u, TWO_STAGE_TOLERANCE);
    }
}

#[test]
fn network_jacobian_matches_differences() {
    let mut rng = Pcg64::seed_from_u64(3);
    for (name, p) in variants() {
        let fluid = p.fluid_in_use();
        let net = Network::new(
            Circuit::from_params(&p),
            fluid,
            p.has(Effect::EntrainedAir),
            p.tank_pressure,
        );
        let nn = net.n_nodes();
        for _ in 0..3 {
            let x: Vec<f64> = (0..net.states().len())
                .map(|k| {
                    if k < nn {
                        random_pressure(&mut rng)
                    } else {
                        rng.random_range(-4e-4..4e-4)
                    }
                })
                .collect();
            let mut u: Vec<f64> = (0..4).map(|_| rng.random_range(-4e-4..4e-4)).collect();
            u.extend([random_pressure(&mut rng), random_pressure(&mut rng)]);
            check_component(&format!("network, {name}"), &net, &x, &u, TOLERANCE);
        }
    }
}

#[test]
fn actuator_jacobian_matches_differences() {
    let mut rng = Pcg64::seed_from_u64(4);
    for (name, p) in variants() {
        let c = Circuit::from_params(&p);
        let act = ActuatorComponent::new(
            actuator::Actuator::from_params(&p, c.chamber_volume, c.added_mass),
            p.fluid_in_use(),
            p.has(Effect::EntrainedAir),
            p.tank_pressure,
        );
        for k in 0..6 {
            // inside the stroke, and past either end stop
            let y = match k {
                0 => 0.1505,
                1 => -0.1505,
                _ => rng.random_range(-0.14..0.14),
            };
            let x = [
                y,
                rng.random_range(-0.3..0.3),
                random_pressure(&mut rng),
                random_pressure(&mut rng),
            ];
            let u = [
                rng.random_range(-4e-4..4e-4),
                rng.random_range(-4e-4..4e-4),
                rng.random_range(-2e3..2e3),
            ];
            check_component(&format!("actuator, {name}"), &act, &x, &u, TOLERANCE);
        }
    }
}

/// The bench's Jacobian at states reached by a run, then perturbed at random.
fn check_bench(name: &str, p: &Params, tolerance: f64, rng: &mut Pcg64) {
    let mut sim = hbmodel::Simulation::new(p).unwrap();
    let inputs = Inputs {
        u1: 3.0,
        u2: -2.0,
        f_ext: 100.0,
    };
    sim.set_inputs(inputs);
    sim.advance_to(0.003).unwrap();
    let bench: &Bench = sim.bench();
    let states = bench.system().states().to_vec();
    let n = states.len();
    for _ in 0..2 {
        let x: Vec<f64> = sim
            .state()
            .x
            .iter()
            .zip(&states)
            .map(|(v, s)| v + rng.random_range(-0.01..0.01) * s.scale)
            .collect();
        let mut jac = vec![0.0; n * n];
        bench.jacobian(&x, &inputs, &mut jac);
        let rows: Vec<String> = states.iter().map(|s| format!("d{}/dt", s.name)).collect();
        let cols: Vec<(String, f64, f64)> = states
            .iter()
            .zip(&x)
            .map(|(s, v)| (s.name.clone(), *v, s.scale))
            .collect();
        compare(
            &format!("bench, {name}"),
            &jac,
            &rows,
            &cols,
            &|j, v| {
                let mut xs = x.clone();
                xs[j] = v;
                let mut dx = vec![0.0; n];
                bench.derivatives(&xs, &inputs, &mut dx);
                dx
            },
            tolerance,
        );
    }
}

#[test]
fn bench_jacobian_matches_differences() {
    let mut rng = Pcg64::seed_from_u64(5);
    for (name, p) in variants() {
        check_bench(&name, &p, TOLERANCE, &mut rng);
    }
}

#[test]
fn two_stage_bench_jacobian_matches_differences() {
    let mut rng = Pcg64::seed_from_u64(6);
    for mode in [1, 3] {
        let mut p = with(mode, None);
        p.sv1.model = ValveModel::TwoStage;
        p.sv2.model = ValveModel::TwoStage;
        check_bench(
            &format!("two-stage, mode {mode}"),
            &p,
            TWO_STAGE_TOLERANCE,
            &mut rng,
        );
    }
}
