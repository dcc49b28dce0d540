//! Exploration of the two-stage valve's unprinted constants: prints the first harmonic
//! of the spool position (ports blocked, 215/2 bar) at a few frequencies and amplitudes,
//! with the CPU time, for the design given by `key=value` arguments over the defaults.
use hbmodel::params::ValveParams;
use hbmodel::servovalve::two_stage::*;
use std::time::Instant;

fn main() {
    let mut d = Design::default();
    let mut freqs = vec![50.0, 100.0, 160.0, 250.0, 310.0, 400.0, 500.0];
    let mut amps = vec![0.05, 0.4, 1.0];
    let mut linear_only = false;
    for arg in std::env::args().skip(1) {
        let (k, v) = arg.split_once('=').expect("key=value");
        let list = || {
            v.split(',')
                .map(|s| s.parse::<f64>().unwrap())
                .collect::<Vec<_>>()
        };
        let x: f64 = v.parse().unwrap_or(0.0);
        match k {
            "f" => freqs = list(),
            "lin" => linear_only = true,
            "a" => amps = list(),
            "stroke" => d.rated_stroke = x,
            "ds" => d.spool_diameter = x,
            "ms" => d.spool_mass = x,
            "vol" => d.pilot_chamber_volume = x,
            "d0" => d.inlet_diameter = x,
            "dn" => d.nozzle_diameter = x,
            "xf0" => d.nozzle_gap = x,
            "dd" => d.drain_diameter = x,
            "j" => d.armature_inertia = x,
            "bf" => d.armature_damping = x,
            "kt" => d.tube_stiffness = x,
            "kr" => d.needle_stiffness = x,
            "nc" => d.coil_turns = x,
            "r" => d.coil_resistance = x,
            "uv" => d.driver_voltage = x,
            "kca" => d.current_loop_gain = x,
            "imax" => d.current_limit = x,
            "kp" => d.position_gain = x,
            _ => panic!("unknown key {k}"),
        }
    }
    let v = TwoStageServovalve::with_design(&ValveParams::default(), d, Environment::thesis_test());
    println!("torque motor [Km, Kmr, L, Kb, R] = {:?}", v.torque_motor());
    linear(&v);
    if linear_only {
        return;
    }
    for a in &amps {
        for f in &freqs {
            let t = Instant::now();
            match sine_response(&v, *a, *f, 4, 2, 1e-6) {
                Ok(h) => println!(
                    "A={a:4.2} f={f:6.1} Hz: {:6.2} dB {:7.1} deg  seated {:4.2} steps {:6} rhs {:7} cpu {:.3} s",
                    20.0 * h.gain.log10(),
                    h.phase_deg,
                    h.seated_fraction,
                    h.stats.steps,
                    h.stats.rhs_evaluations,
                    t.elapsed().as_secs_f64()
                ),
                Err(e) => println!("A={a} f={f}: {e}"),
            }
        }
    }
}

/// Eigenvalues and small-signal response from a finite-difference Jacobian at null.
fn linear(v: &TwoStageServovalve) {
    use hbmodel::servovalve::Servovalve;
    use nalgebra::{Complex, DMatrix};
    let n = N_STATES;
    let mut x0 = vec![0.0; n];
    v.initial_state(0.0, &mut x0);
    let mut atol = vec![0.0; n];
    v.absolute_tolerances(&mut atol);
    let f = |x: &[f64], u: f64| {
        let mut dx = vec![0.0; n];
        v.derivatives(u, x, &mut dx);
        dx
    };
    let f0 = f(&x0, 0.0);
    let mut a = DMatrix::<f64>::zeros(n, n);
    for j in 0..n {
        let h = atol[j] * 1e2;
        let mut xp = x0.clone();
        xp[j] += h;
        let mut xm = x0.clone();
        xm[j] -= h;
        let (fp, fm) = (f(&xp, 0.0), f(&xm, 0.0));
        for i in 0..n {
            a[(i, j)] = (fp[i] - fm[i]) / (2.0 * h);
        }
    }
    let du = 1e-4;
    let (fp, fm) = (f(&x0, du), f(&x0, -du));
    let b: Vec<f64> = (0..n)
        .map(|i| (fp[i] - fm[i]) / (2.0 * du) * 10.0)
        .collect();
    let _ = f0;
    let mut ev: Vec<_> = a.complex_eigenvalues().iter().cloned().collect();
    ev.sort_by(|p, q| p.re.partial_cmp(&q.re).unwrap());
    for e in &ev {
        println!(
            "  eig {:12.1} {:+12.1}i  ({:8.1} Hz, zeta {:5.2})",
            e.re,
            e.im,
            e.norm() / (2.0 * std::f64::consts::PI),
            -e.re / e.norm()
        );
    }
    let stroke = v.design().rated_stroke;
    let mut f3 = None;
    let mut f90 = None;
    let mut prev = (0.0, 1.0, 0.0);
    for k in 0..=300 {
        let fr = 10f64.powf(k as f64 / 100.0);
        let w = 2.0 * std::f64::consts::PI * fr;
        let m = DMatrix::<Complex<f64>>::from_fn(n, n, |i, j| {
            let d = if i == j {
                Complex::new(0.0, w)
            } else {
                Complex::new(0.0, 0.0)
            };
            d - Complex::new(a[(i, j)], 0.0)
        });
        let rhs = DMatrix::<Complex<f64>>::from_fn(n, 1, |i, _| Complex::new(b[i], 0.0));
        let sol = m.lu().solve(&rhs).unwrap();
        let g = sol[(X_S, 0)] / stroke;
        let (mag, ph) = (g.norm(), g.arg().to_degrees());
        let ph = if ph > 0.0 { ph - 360.0 } else { ph };
        if f3.is_none() && mag < 0.5f64.sqrt() && prev.1 >= 0.5f64.sqrt() {
            f3 = Some(fr);
        }
        if f90.is_none() && ph < -90.0 && prev.2 >= -90.0 {
            f90 = Some(fr);
        }
        if k % 20 == 0 {
            println!(
                "  lin {fr:7.1} Hz {:6.2} dB {:7.1} deg",
                20.0 * mag.log10(),
                ph
            );
        }
        prev = (fr, mag, ph);
    }
    println!("  linear: -3 dB at {f3:?} Hz, -90 deg at {f90:?} Hz");
}
