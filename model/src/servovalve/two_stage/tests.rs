use super::*;
use crate::servovalve::Servovalve;

fn valve() -> TwoStageServovalve {
    TwoStageServovalve::with_design(
        &ValveParams::default(),
        Design::default(),
        Environment::thesis_test(),
    )
}

/// d(P_A - P_B)/d(spool position in volts) with blocked ports (Pa/V).
fn pressure_gain(v: &TwoStageServovalve, volts: f64) -> f64 {
    let (ps, pt) = (v.env.supply, v.env.tank);
    let dv = 0.002;
    let diff = |u: f64| {
        let (pa, pb) = v.blocked_port_pressures(u / 10.0 * v.d.rated_stroke, ps, pt);
        pa - pb
    };
    (diff(volts + dv) - diff(volts - dv)) / (2.0 * dv)
}

#[test]
fn blocked_ports_pressure_gain_matches_the_thesis_model() {
    // Fig. 2.10(b): 827 bar/V (model), 850 bar/V (measured); 215/2 bar
    let v = valve();
    let g = pressure_gain(&v, 0.0) / BAR;
    println!("pressure gain at null: {g:.1} bar/V");
    assert!(
        (g / 827.0 - 1.0).abs() < 0.05,
        "pressure gain at null {g:.1} bar/V"
    );
    // the shape of Fig. 2.10(b): P_A rises from tank to supply over the plotted range,
    // P_B falls, P_A - P_B grows monotonically
    let (ps, pt) = (v.env.supply, v.env.tank);
    let mut prev = f64::NEG_INFINITY;
    for k in -40..=60 {
        let volts = 0.02 * k as f64;
        let (pa, pb) = v.blocked_port_pressures(volts / 10.0 * v.d.rated_stroke, ps, pt);
        assert!(pa - pb > prev, "P_A - P_B not increasing at {volts} V");
        prev = pa - pb;
    }
    let (pa, pb) = v.blocked_port_pressures(-0.08 * v.d.rated_stroke, ps, pt);
    assert!(
        pa < pt + 5.0 * BAR && pb > ps - 5.0 * BAR,
        "{pa} {pb} at -0.8 V"
    );
    let (pa, pb) = v.blocked_port_pressures(0.12 * v.d.rated_stroke, ps, pt);
    assert!(
        pa > ps - 5.0 * BAR && pb < pt + 5.0 * BAR,
        "{pa} {pb} at 1.2 V"
    );
}

#[test]
fn blocked_ports_leakage_peaks_at_null() {
    let v = valve();
    let (ps, pt) = (v.env.supply, v.env.tank);
    let leak = |volts: f64| v.blocked_port_leakage(volts / 10.0 * v.d.rated_stroke, ps, pt);
    let grid: Vec<f64> = (-40..=60).map(|k| 0.02 * k as f64).collect();
    let q: Vec<f64> = grid.iter().map(|u| leak(*u)).collect();
    let k_max = (0..q.len()).max_by(|a, b| q[*a].total_cmp(&q[*b])).unwrap();
    println!(
        "leakage peak {:.3} L/min at {} V",
        q[k_max] / LPM,
        grid[k_max]
    );
    assert!(
        grid[k_max].abs() <= 0.04,
        "leakage peaks at {} V, not at null",
        grid[k_max]
    );
    // and falls on both sides of it
    for k in 1..q.len() {
        if k <= k_max {
            assert!(
                q[k] >= q[k - 1],
                "leakage not rising towards null at {} V",
                grid[k]
            );
        } else {
            assert!(
                q[k] <= q[k - 1],
                "leakage not falling after null at {} V",
                grid[k]
            );
        }
    }
    assert!(leak(0.8) < 0.5 * q[k_max] && leak(-0.8) < 0.5 * q[k_max]);
}

#[test]
fn rated_flow_at_rated_command_and_70_bar() {
    // Table 1.1: 19 L/min at 70 bar total drop (two lands in series) and 10 V
    let v = valve();
    let q = v.load_flow(10.0, 70.0 * BAR) / LPM;
    println!("rated flow {q:.2} L/min");
    assert!((q / 19.0 - 1.0).abs() < 0.05, "rated flow {q:.2} L/min");
    let q_neg = -v.load_flow(-10.0, 70.0 * BAR) / LPM;
    println!("rated flow at -10 V {q_neg:.2} L/min");
    assert!(
        (q_neg / 19.0 - 1.0).abs() < 0.05,
        "rated flow at -10 V {q_neg:.2} L/min"
    );
}

#[test]
fn rest_state_is_an_equilibrium() {
    let v = valve();
    for command in [0.0, 4.0, -10.0, 10.0] {
        let mut x = vec![0.0; N_STATES];
        v.initial_state(command, &mut x);
        let mut dx = vec![0.0; N_STATES];
        v.derivatives(command, &x, &mut dx);
        let mut atol = vec![0.0; N_STATES];
        v.absolute_tolerances(&mut atol);
        // the proportional electronics with the calibrated feedforward leave a static
        // error below 0.1 % of the stroke (the flapper's own springs and hydraulic forces)
        let error = x[X_S] / v.d.rated_stroke - command / 10.0;
        println!("static error at {command} V: {error:.2e} of the stroke");
        assert!(
            error.abs() < 1e-3,
            "spool {error} of the stroke off at {command} V"
        );
        // every rate below what one atol per microsecond would be
        for i in 0..N_STATES {
            assert!(
                dx[i].abs() < atol[i] * 1e6,
                "state {i}: {} at {command} V",
                dx[i]
            );
        }
    }
}

/// Frequency where a sampled curve first crosses `level` downwards, interpolated in
/// log frequency; None when it does not cross within the grid.
fn crossing(points: &[(f64, f64)], level: f64) -> Option<f64> {
    points.windows(2).find_map(|w| {
        let ((f0, y0), (f1, y1)) = (w[0], w[1]);
        (y0 >= level && y1 < level).then(|| {
            let s = (y0 - level) / (y0 - y1);
            (f0.ln() + s * (f1.ln() - f0.ln())).exp()
        })
    })
}

/// (-3 dB, -90 deg) frequencies of the spool position at `amplitude`, found on `grid`.
fn bandwidths(v: &TwoStageServovalve, amplitude: f64, grid: &[f64]) -> (Option<f64>, Option<f64>) {
    let mut gain = Vec::new();
    let mut phase = Vec::new();
    for f in grid {
        let h = sine_response(v, amplitude, *f, 4, 2, 1e-6).expect("the valve integrates");
        println!(
            "  {amplitude} {f} Hz: {:.2} dB {:.1} deg",
            20.0 * h.gain.log10(),
            h.phase_deg
        );
        gain.push((*f, 20.0 * h.gain.log10()));
        phase.push((*f, h.phase_deg));
    }
    (crossing(&gain, -3.0), crossing(&phase, -90.0))
}

#[test]
fn frequency_response_matches_the_manufacturer() {
    // Fig. 2.3 / Table 1.1: about 310 Hz at 40 % and 160 Hz at 90-100 % input; ports
    // blocked, 215/2 bar. Each grid reaches past the +-25 % band on both sides.
    let v = valve();
    for (amplitude, target, grid) in [
        (
            0.4,
            310.0,
            &[200.0, 230.0, 260.0, 290.0, 320.0, 350.0, 400.0, 450.0][..],
        ),
        (
            1.0,
            160.0,
            &[100.0, 115.0, 130.0, 145.0, 160.0, 180.0, 205.0, 240.0][..],
        ),
    ] {
        let (f3, f90) = bandwidths(&v, amplitude, grid);
        let f3 = f3.unwrap_or_else(|| panic!("no -3 dB crossing at {amplitude} in {grid:?}"));
        let f90 = f90.unwrap_or_else(|| panic!("no -90 deg crossing at {amplitude} in {grid:?}"));
        println!(
            "{} %: -3 dB at {f3:.0} Hz, -90 deg at {f90:.0} Hz",
            amplitude * 100.0
        );
        assert!(
            (f3 / target - 1.0).abs() < 0.25,
            "-3 dB at {} %: {f3:.0} Hz",
            amplitude * 100.0
        );
        assert!(
            (f90 / target - 1.0).abs() < 0.25,
            "-90 deg at {} %: {f90:.0} Hz",
            amplitude * 100.0
        );
    }
}

#[test]
fn bandwidth_loss_at_large_input_is_the_pilot_stage_flow_saturating() {
    let v = valve();
    // small input: no loss at 160 Hz, the flapper far from its nozzles
    let small = sine_response(&v, 0.05, 160.0, 4, 2, 1e-6).unwrap();
    assert!(20.0 * small.gain.log10() > -1.0, "{small:?}");
    assert!(small.seated_fraction == 0.0, "{small:?}");
    // full input: the flapper seats on its nozzles, so the pilot flow is at its
    // ceiling (the upstream orifice's), and the response drops
    let full = sine_response(&v, 1.0, 160.0, 4, 2, 1e-6).unwrap();
    assert!(full.seated_fraction > 0.2, "{full:?}");
    assert!(20.0 * full.gain.log10() < -2.0, "{full:?}");
    // the electronics' limits are not what sets the loss: without the driver's current
    // and voltage limits the amplitude ratio barely moves
    let d = Design {
        driver_voltage: 1e4,
        current_limit: 1e2,
        ..Design::default()
    };
    let unlimited = TwoStageServovalve::with_design(&ValveParams::default(), d, v.env);
    let free = sine_response(&unlimited, 1.0, 160.0, 4, 2, 1e-6).unwrap();
    let change = 20.0 * (free.gain / full.gain).log10();
    println!(
        "100 % at 160 Hz: {:.2} dB, flapper seated {:.0} % of the time; without driver limits {change:+.2} dB",
        20.0 * full.gain.log10(),
        100.0 * full.seated_fraction
    );
    assert!(change.abs() < 0.5, "{change} dB without the driver limits");
    // while a pilot stage passing 40 % more flow (larger inlet orifices and nozzles,
    // same bridge ratio) moves the spool faster and loses less
    let d = Design {
        inlet_diameter: INLET_DIAMETER * 1.4f64.sqrt(),
        nozzle_gap: NOZZLE_GAP * 1.4,
        ..Design::default()
    };
    let bigger = TwoStageServovalve::with_design(&ValveParams::default(), d, v.env);
    let more = sine_response(&bigger, 1.0, 160.0, 4, 2, 1e-6).unwrap();
    assert!(more.gain > 1.15 * full.gain, "{more:?} vs {full:?}");
}

#[test]
fn selected_by_parameter_file_and_steps_the_bench_like_the_reduced_valve() {
    use crate::control::{response_time_95, run_closed_loop, Proportional, SAMPLE_PERIOD};
    use crate::params::{Mode, ValveModel};
    let text = "[sv1]\nmodel = \"two_stage\"\n[sv2]\nmodel = \"two_stage\"\n";
    let p = Params::from_toml_named(text, "two_stage.toml").unwrap();
    assert_eq!(p.sv1.model, ValveModel::TwoStage);
    assert!(p.to_toml().contains("model = \"two_stage\""));
    // section 4.4: proportional control Kp = 1169 V/m, -10 -> +10 mm, mode 3
    let t95 = |model: ValveModel| {
        let mut p = Params::thesis_bench(Mode::ThreeWay);
        p.sv1.model = model;
        p.sv2.model = model;
        p.initial_position = -0.01;
        let mut sim = crate::Simulation::new(&p).unwrap();
        let tr = run_closed_loop(
            &mut sim,
            &mut Proportional { kp: 1169.0 },
            &|_| 0.01,
            0.12,
            SAMPLE_PERIOD,
            1,
        )
        .expect("the bench integrates");
        (
            response_time_95(&tr, 0.0, -0.01, 0.01).unwrap(),
            sim.bench().n_states(),
        )
    };
    let (reduced, n_reduced) = t95(ValveModel::Reduced);
    let (physical, n_physical) = t95(ValveModel::TwoStage);
    assert_eq!(n_physical, n_reduced + 2 * (N_STATES - 2));
    println!("95 % step time: reduced {reduced:.4} s, two-stage {physical:.4} s");
    assert!(
        (physical / reduced - 1.0).abs() < 0.1,
        "{physical} vs {reduced} s"
    );
}
