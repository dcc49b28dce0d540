//! The bench's right-hand side stays what it was before it became a composition of
//! components (issue 13): derivatives at saved states, written by the code before the
//! refactoring (`write_saved_points`, run once with `--ignored`), are reproduced to
//! round-off.

use std::path::PathBuf;

use hbmodel::friction::FrictionLaw;
use hbmodel::params::{Mode, ValveModel};
use hbmodel::{Bench, Effect, Inputs, Params, Simulation};

/// A saved point: configuration name, inputs, state and the derivatives then.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct Point {
    config: String,
    inputs: [f64; 3],
    x: Vec<f64>,
    dx: Vec<f64>,
}

#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct Saved {
    points: Vec<Point>,
}

fn file() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/bench_rhs_points.toml")
}

/// The configurations: each mode with every effect, the lumped manifold, no effect at
/// all, the Sidhom law with payload and a hot oil, and the two-stage valves.
fn config(name: &str) -> Params {
    let mode = |k: u8| Mode::try_from(k).unwrap();
    match name {
        "mode1" => Params::thesis_bench(mode(1)),
        "mode2" => Params::thesis_bench(mode(2)),
        "mode3" => Params::thesis_bench(mode(3)),
        "lumped" => {
            let mut p = Params::thesis_bench(mode(1));
            p.effects.set(Effect::ManifoldInertia, false);
            p.effects.set(Effect::ManifoldLosses, false);
            p
        }
        "bare" => Params {
            mode: mode(3),
            effects: hbmodel::Effects::default(),
            ..Params::default()
        },
        "sidhom" => {
            let mut p = Params::thesis_bench(mode(3));
            p.friction.law = FrictionLaw::Sidhom;
            p.effects.set(Effect::Payload, true);
            p.effects.set(Effect::ValveAsymmetry, true);
            p.sv2.null_bias = 0.05;
            p.fluid.temperature = 330.0;
            p
        }
        "two_stage1" | "two_stage3" => {
            let mut p = Params::thesis_bench(mode(if name == "two_stage1" { 1 } else { 3 }));
            p.sv1.model = ValveModel::TwoStage;
            p.sv2.model = ValveModel::TwoStage;
            p
        }
        _ => panic!("unknown configuration {name}"),
    }
}

const CONFIGS: [&str; 8] = [
    "mode1",
    "mode2",
    "mode3",
    "lumped",
    "bare",
    "sidhom",
    "two_stage1",
    "two_stage3",
];

/// States along a run with steps of the commands and of the load, plus two states
/// pushed where the clamps act: past an end stop, and a chamber in the cavitation band.
fn points_of(name: &str) -> Vec<Point> {
    let p = config(name);
    let mut sim = Simulation::new(&p).unwrap();
    let mut out = Vec::new();
    let schedule = [
        (
            0.0,
            Inputs {
                u1: 0.0,
                u2: 0.0,
                f_ext: 0.0,
            },
        ),
        (
            0.004,
            Inputs {
                u1: 4.0,
                u2: -3.0,
                f_ext: 200.0,
            },
        ),
        (
            0.012,
            Inputs {
                u1: -7.5,
                u2: 6.0,
                f_ext: -500.0,
            },
        ),
        (
            0.020,
            Inputs {
                u1: 0.3,
                u2: -0.2,
                f_ext: 0.0,
            },
        ),
    ];
    for (t, inputs) in schedule {
        sim.advance_to(t).unwrap();
        sim.set_inputs(inputs);
        out.push((inputs, sim.state().x.clone()));
    }
    sim.advance_to(0.03).unwrap();
    let (inputs, x) = (sim.inputs(), sim.state().x.clone());
    out.push((inputs, x.clone()));
    let mut stop = x.clone();
    stop[0] = 0.1502;
    stop[1] = 0.05;
    out.push((inputs, stop));
    let mut cavity = x;
    cavity[3] = 0.3e5;
    out.push((inputs, cavity));
    let bench = Bench::new(&p).unwrap();
    out.into_iter()
        .map(|(inputs, x)| {
            let mut dx = vec![0.0; x.len()];
            bench.derivatives(&x, &inputs, &mut dx);
            Point {
                config: name.into(),
                inputs: [inputs.u1, inputs.u2, inputs.f_ext],
                x,
                dx,
            }
        })
        .collect()
}

#[test]
#[ignore = "writes the saved points; run once, before a change of the right-hand side"]
fn write_saved_points() {
    let points = CONFIGS.iter().flat_map(|c| points_of(c)).collect();
    let text = toml::to_string(&Saved { points }).unwrap();
    std::fs::write(file(), text).unwrap();
}

#[test]
fn composed_bench_reproduces_the_saved_derivatives() {
    let saved: Saved = toml::from_str(&std::fs::read_to_string(file()).unwrap()).unwrap();
    assert_eq!(saved.points.len(), 7 * CONFIGS.len());
    let mut worst: f64 = 0.0;
    for (k, pt) in saved.points.iter().enumerate() {
        let bench = Bench::new(&config(&pt.config)).unwrap();
        let [u1, u2, f_ext] = pt.inputs;
        let mut dx = vec![0.0; pt.x.len()];
        bench.derivatives(&pt.x, &Inputs { u1, u2, f_ext }, &mut dx);
        for (i, (a, b)) in dx.iter().zip(&pt.dx).enumerate() {
            // round-off of sums whose terms cancel: relative to the entry, with a floor
            // at 1e-12 of the largest rate of the same state kind
            let err = (a - b).abs() / b.abs().max(1e-300);
            worst = worst.max(if (a - b).abs() < 1e-30 { 0.0 } else { err });
            assert!(
                (a - b).abs() <= 1e-10 * b.abs() + 1e-300,
                "point {k} ({}), dx[{i}]: {a} now, {b} saved",
                pt.config
            );
        }
    }
    eprintln!("largest relative change {worst:e}");
}
