//! The physical two-stage servovalve (chapter 2) on its own, ports blocked, 215/2 bar:
//! writes docs/valve_bode.svg (amplitude and phase of the spool position at 40 % and
//! 100 % input, 1-500 Hz, as Fig. 2.29, with 5 % for the small-signal response) and
//! docs/valve_pressure_gain.svg (leakage and P_A, P_B against spool position, as Fig.
//! 2.10), then prints the check figures, the cost of the valve alone at rtol 1e-6 and in
//! the bench against the reduced valve.
use hbmodel::control::{response_time_95, run_closed_loop, Proportional, SAMPLE_PERIOD};
use hbmodel::params::{ValveModel, ValveParams, BAR, LPM};
use hbmodel::servovalve::two_stage::*;
use hbmodel::servovalve::Servovalve;
use hbmodel::solver::{integrate, SolverStats, Tolerances};
use hbmodel::{Mode, Params, Simulation};
use std::fmt::Write;
use std::time::Instant;

/// (label, command of time, simulated seconds)
type Run = (&'static str, Box<dyn Fn(f64) -> f64>, f64);

/// (label, colour, points)
type Curve = (String, &'static str, Vec<(f64, f64)>);

struct Axes {
    x: (f64, f64),
    y: (f64, f64),
    log_x: bool,
    top: f64,
    height: f64,
}

const W: f64 = 680.0;
const M: f64 = 60.0;

impl Axes {
    fn px(&self, x: f64) -> f64 {
        let (a, b, v) = if self.log_x {
            (self.x.0.log10(), self.x.1.log10(), x.log10())
        } else {
            (self.x.0, self.x.1, x)
        };
        M + (v - a) / (b - a) * (W - 2.0 * M)
    }
    fn py(&self, y: f64) -> f64 {
        self.top + (self.y.1 - y) / (self.y.1 - self.y.0) * self.height
    }
    /// Grid, tick labels, axis titles and the curves of one panel.
    fn draw(
        &self,
        s: &mut String,
        xt: &[f64],
        yt: &[f64],
        xlabel: &str,
        ylabel: &str,
        curves: &[Curve],
    ) {
        let (t, b) = (self.top, self.top + self.height);
        let _ = writeln!(
            s,
            "<rect x='{M}' y='{t}' width='{}' height='{}' fill='none' stroke='#888'/>",
            W - 2.0 * M,
            self.height
        );
        for x in xt {
            let _ = writeln!(s, "<line x1='{0:.1}' y1='{t}' x2='{0:.1}' y2='{b}' stroke='#ddd'/><text x='{0:.1}' y='{1}' text-anchor='middle'>{x}</text>", self.px(*x), b + 15.0);
        }
        for y in yt {
            let _ = writeln!(s, "<line x1='{M}' y1='{0:.1}' x2='{1}' y2='{0:.1}' stroke='#ddd'/><text x='{2}' y='{3:.1}' text-anchor='end'>{y}</text>", self.py(*y), W - M, M - 5.0, self.py(*y) + 4.0);
        }
        let _ = writeln!(
            s,
            "<text x='{}' y='{}' text-anchor='middle'>{xlabel}</text>",
            W / 2.0,
            b + 32.0
        );
        let _ = writeln!(s, "<text x='15' y='{0}' transform='rotate(-90 15 {0})' text-anchor='middle'>{ylabel}</text>", t + self.height / 2.0);
        for (k, (name, color, pts)) in curves.iter().enumerate() {
            let path: Vec<String> = pts
                .iter()
                .map(|(x, y)| format!("{:.1},{:.1}", self.px(*x), self.py(*y)))
                .collect();
            if name.starts_with("manufacturer") {
                for p in &path {
                    let (x, y) = p.split_once(',').unwrap();
                    let _ = writeln!(s, "<circle cx='{x}' cy='{y}' r='5' fill='none' stroke='{color}' stroke-width='2'/>");
                }
            } else {
                let _ = writeln!(
                    s,
                    "<polyline fill='none' stroke='{color}' stroke-width='2' points='{}'/>",
                    path.join(" ")
                );
            }
            let _ = writeln!(
                s,
                "<text x='{}' y='{}' fill='{color}'>{name}</text>",
                M + 10.0,
                t + 16.0 + 15.0 * k as f64
            );
        }
    }
}

fn svg_start(h: f64, title: &str) -> String {
    let mut s = format!("<svg xmlns='http://www.w3.org/2000/svg' width='{W}' height='{h}' font-family='sans-serif' font-size='12'>\n");
    let _ = writeln!(s, "<rect width='{W}' height='{h}' fill='white'/><text x='{M}' y='22' font-size='14'>{title}</text>");
    s
}

/// Seconds of simulated time per CPU second for the valve alone under `command(t)`, held
/// over 1 ms intervals as the bench's 1 kHz controller does (one integration each).
fn valve_speed(
    v: &TwoStageServovalve,
    command: &dyn Fn(f64) -> f64,
    t_end: f64,
) -> (f64, SolverStats) {
    let mut x = vec![0.0; N_STATES];
    v.initial_state(command(0.0), &mut x);
    let mut atol = vec![0.0; N_STATES];
    v.absolute_tolerances(&mut atol);
    let scale: Vec<f64> = atol.iter().map(|a| a * 1e4).collect();
    let tol = Tolerances {
        rtol: 1e-6,
        atol,
        fixed_step: 0.0,
    };
    let mut stats = SolverStats::default();
    let start = Instant::now();
    let n = (t_end / SAMPLE_PERIOD).round() as usize;
    for k in 0..n {
        let (ta, tb) = (k as f64 * SAMPLE_PERIOD, (k + 1) as f64 * SAMPLE_PERIOD);
        let u = command(ta);
        integrate(
            |_t, x, dx| v.derivatives(u, x, dx),
            &mut x,
            ta,
            tb,
            &tol,
            &scale,
            &mut stats,
        )
        .expect("the valve integrates");
    }
    (t_end / start.elapsed().as_secs_f64(), stats)
}

fn main() -> std::io::Result<()> {
    let docs = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs");
    std::fs::create_dir_all(&docs)?;
    let v = TwoStageServovalve::with_design(
        &ValveParams::default(),
        Design::default(),
        Environment::thesis_test(),
    );
    let (ps, pt) = (v.environment().supply, v.environment().tank);
    let stroke = v.design().rated_stroke;

    // Fig. 2.29: amplitude and phase, 40 % and 100 % (and 5 %, small signal)
    let freqs = [
        1.0, 2.0, 5.0, 10.0, 20.0, 35.0, 50.0, 70.0, 100.0, 120.0, 140.0, 160.0, 180.0, 200.0,
        230.0, 260.0, 290.0, 320.0, 360.0, 400.0, 450.0, 500.0,
    ];
    let mut amp_curves = Vec::new();
    let mut phase_curves = Vec::new();
    for (a, color) in [(0.05, "#2ca02c"), (0.4, "#1f77b4"), (1.0, "#d62728")] {
        let mut amp = Vec::new();
        let mut phase = Vec::new();
        for f in freqs {
            let (settle, measure) = if f < 10.0 { (2, 1) } else { (4, 2) };
            let h = sine_response(&v, a, f, settle, measure, 1e-6).expect("the valve integrates");
            amp.push((f, 20.0 * h.gain.log10()));
            phase.push((f, h.phase_deg));
            println!(
                "{:3.0} % {f:6.1} Hz: {:6.2} dB {:7.1} deg (flapper seated {:3.0} % of the time)",
                a * 100.0,
                20.0 * h.gain.log10(),
                h.phase_deg,
                100.0 * h.seated_fraction
            );
        }
        amp_curves.push((format!("model, {:.0} % input", a * 100.0), color, amp));
        phase_curves.push((format!("model, {:.0} % input", a * 100.0), color, phase));
    }
    amp_curves.push((
        "manufacturer -3 dB: 310 Hz at 40 %, 160 Hz at 90-100 %".into(),
        "#000",
        vec![(310.0, -3.0), (160.0, -3.0)],
    ));
    phase_curves.push((
        "manufacturer -90 deg: 310 Hz at 40 %, 160 Hz at 90-100 %".into(),
        "#000",
        vec![(310.0, -90.0), (160.0, -90.0)],
    ));
    let ft = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0];
    let mut s = svg_start(
        700.0,
        "MOOG D765 two-stage model, ports blocked, 215/2 bar: spool position / command",
    );
    let top = Axes {
        x: (1.0, 500.0),
        y: (-20.0, 5.0),
        log_x: true,
        top: 40.0,
        height: 260.0,
    };
    top.draw(
        &mut s,
        &ft,
        &[-20.0, -15.0, -10.0, -5.0, -3.0, 0.0, 5.0],
        "frequency (Hz)",
        "amplitude ratio (dB)",
        &amp_curves,
    );
    let bottom = Axes {
        x: (1.0, 500.0),
        y: (-225.0, 0.0),
        log_x: true,
        top: 380.0,
        height: 260.0,
    };
    bottom.draw(
        &mut s,
        &ft,
        &[-225.0, -180.0, -135.0, -90.0, -45.0, 0.0],
        "frequency (Hz)",
        "phase (deg)",
        &phase_curves,
    );
    std::fs::write(docs.join("valve_bode.svg"), s + "</svg>\n")?;

    // Fig. 2.10: leakage and port pressures with blocked ports
    let volts: Vec<f64> = (-80..=120).map(|k| 0.01 * k as f64).collect();
    let (mut pa, mut pb, mut dp, mut leak) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for u in &volts {
        let xs = u / 10.0 * stroke;
        let (a, b) = v.blocked_port_pressures(xs, ps, pt);
        pa.push((*u, a / BAR));
        pb.push((*u, b / BAR));
        dp.push((*u, (a - b) / BAR));
        leak.push((*u, v.blocked_port_leakage(xs, ps, pt) / LPM));
    }
    let vt = [-0.8, -0.4, 0.0, 0.4, 0.8, 1.2];
    let mut s = svg_start(
        700.0,
        "MOOG D765 second stage, ports blocked, 215/2 bar (Table 2.1 lands)",
    );
    let top = Axes {
        x: (-0.8, 1.2),
        y: (0.0, 0.6),
        log_x: false,
        top: 40.0,
        height: 240.0,
    };
    top.draw(
        &mut s,
        &vt,
        &[0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
        "spool position (V, 10 V = rated stroke)",
        "leakage (L/min)",
        &[("P to T leakage of the four lands".into(), "#2ca02c", leak)],
    );
    let bottom = Axes {
        x: (-0.8, 1.2),
        y: (-250.0, 250.0),
        log_x: false,
        top: 360.0,
        height: 280.0,
    };
    bottom.draw(
        &mut s,
        &vt,
        &[-250.0, -150.0, -50.0, 0.0, 50.0, 150.0, 250.0],
        "spool position (V, 10 V = rated stroke)",
        "pressure (bar)",
        &[
            ("P_A".into(), "#1f77b4", pa),
            ("P_B".into(), "#d62728", pb),
            ("P_A - P_B".into(), "#000", dp),
        ],
    );
    std::fs::write(docs.join("valve_pressure_gain.svg"), s + "</svg>\n")?;
    println!("wrote docs/valve_bode.svg and docs/valve_pressure_gain.svg");

    // check figures
    let gain = {
        let h = 0.002;
        let d = |u: f64| {
            let (a, b) = v.blocked_port_pressures(u / 10.0 * stroke, ps, pt);
            a - b
        };
        (d(h) - d(-h)) / (2.0 * h) / BAR
    };
    println!(
        "pressure gain at null: {gain:.1} bar/V; null leakage {:.3} L/min",
        v.blocked_port_leakage(0.0, ps, pt) / LPM
    );
    println!(
        "rated flow: {:.2} L/min at +10 V, {:.2} L/min at -10 V, 70 bar",
        v.load_flow(10.0, 70.0 * BAR) / LPM,
        -v.load_flow(-10.0, 70.0 * BAR) / LPM
    );
    let [km, kmr, l, kb, r] = v.torque_motor();
    println!("torque motor: K_m {km:.3} N.m/A, K_mr {kmr:.2} N.m/rad, L {:.1} mH, K_b {kb:.3} V.s/rad, R {r} ohm", l * 1e3);
    let mut x = vec![0.0; N_STATES];
    v.initial_state(0.0, &mut x);
    let pf = v.pilot_flows(ps, pt, x[P_L], x[P_R], 0.0);
    println!(
        "pilot at null: P_L = P_R = {:.1} bar, P_E = {:.1} bar, flow {:.3} L/min",
        x[P_L] / BAR,
        pf.p_e / BAR,
        2.0 * pf.q_pl / LPM
    );

    // cost of the valve alone at rtol 1e-6
    println!("valve alone ({N_STATES} states), rtol 1e-6, command held over 1 ms intervals:");
    let runs: [Run; 4] = [
        ("at rest, 0 V", Box::new(|_| 0.0), 1.0),
        (
            "10 Hz sine, 40 %",
            Box::new(|t: f64| 4.0 * (20.0 * std::f64::consts::PI * t).sin()),
            1.0,
        ),
        (
            "+-5 V square wave, 20 Hz",
            Box::new(|t: f64| {
                if (t * 40.0) as i64 % 2 == 0 {
                    5.0
                } else {
                    -5.0
                }
            }),
            0.5,
        ),
        (
            "160 Hz sine, 100 %",
            Box::new(|t: f64| 10.0 * (320.0 * std::f64::consts::PI * t).sin()),
            0.1,
        ),
    ];
    for (name, cmd, t_end) in &runs {
        let (speed, st) = valve_speed(&v, cmd.as_ref(), *t_end);
        println!(
            "  {name:28}: {speed:8.1} simulated s per CPU s, {} steps ({:.1} us mean step), {} rhs",
            st.steps,
            t_end / st.steps as f64 * 1e6,
            st.rhs_evaluations
        );
    }

    // the bench with each valve model: section 4.4 proportional control, -10 -> +10 mm
    for mode in Mode::ALL {
        let mut line = format!("bench mode {}:", mode.number());
        for model in [ValveModel::Reduced, ValveModel::TwoStage] {
            let mut p = Params::thesis_bench(mode);
            p.sv1.model = model;
            p.sv2.model = model;
            p.initial_position = -0.01;
            let mut sim = Simulation::new(&p).expect("valid parameters");
            let start = Instant::now();
            let trace = run_closed_loop(
                &mut sim,
                &mut Proportional { kp: 1169.0 },
                &|_| 0.01,
                0.15,
                SAMPLE_PERIOD,
                1,
            )
            .expect("the bench integrates");
            let cpu = start.elapsed().as_secs_f64();
            let t95 = response_time_95(&trace, 0.0, -0.01, 0.01).unwrap_or(f64::NAN);
            let _ = write!(
                line,
                "  {model:?}: {} states, 95 % time {t95:.4} s, {:.2} sim s/CPU s ({} steps);",
                sim.bench().n_states(),
                0.15 / cpu,
                sim.stats.steps
            );
        }
        println!("{line}");
    }
    Ok(())
}
