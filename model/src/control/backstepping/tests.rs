//! Closed-loop checks of both laws on the control model: the error dynamics each law
//! imposes, tracking at 1 and 2 kHz, and the effect of a payload.

use super::*;

use crate::control::law::fixtures::*;
use crate::control::trajectory::Trajectory;

/// Payload of the robustness check: +20 kg, one of the Table 7.1 cases.
const PAYLOAD: f64 = 20.0;

/// Plant integration step and the bench's controller period (section 4.4).
const DT: f64 = 1e-5;
const SAMPLE: f64 = 1e-3;

/// Move: 7th-order polynomial (section 5.5), 10 mm in 0.2 s starting at T_START.
const T_START: f64 = 0.05;
const DURATION: f64 = 0.2;
const STROKE: f64 = 0.01;
const T_END: f64 = 0.6;
/// Static window: well after the move ends (0.25 s).
const T_STATIC: f64 = 0.45;

fn model(mass: f64) -> ControlModel {
    thesis_model(mass)
}

/// y_d and its first three derivatives: the 7th-order move of section 5.5.
fn position_reference(t: f64) -> [f64; 4] {
    Trajectory::new(&[(T_START, 0.0, STROKE, DURATION)])
        .expect("one valid move")
        .at(t)
}

fn reference(t: f64) -> Reference {
    Reference {
        y: position_reference(t),
        p: [P_REF_THESIS, 0.0],
    }
}

/// The control model (II.1)-(II.2) as plant, state (y, v, P1, P2). Flow is taken with
/// the sign of the land drop (sqrt of |dP| times sign dP): identical to (II.2) while
/// PT <= Pi <= PP and it stops the plant from pumping a chamber beyond supply.
#[derive(Clone, Copy)]
struct Plant {
    m: ControlModel,
}

impl Plant {
    fn land_flow(&self, drop: f64) -> f64 {
        self.m.flow_per_volt * drop.signum() * (drop.abs() / self.m.rated_drop).sqrt()
    }

    fn flow(&self, p: f64, u: f64) -> f64 {
        if u >= 0.0 {
            self.land_flow(self.m.supply - p) * u
        } else {
            self.land_flow(p - self.m.tank) * u
        }
    }

    fn acceleration(&self, s: &[f64; 4]) -> f64 {
        self.m.area / self.m.mass * (s[2] - s[3]) - GRAVITY - self.m.viscous / self.m.mass * s[1]
    }

    fn derivative(&self, s: &[f64; 4], u: [f64; 2]) -> [f64; 4] {
        let (v1, v2) = self.m.volumes(s[0]);
        let beta = self.m.bulk_modulus;
        [
            s[1],
            self.acceleration(s),
            beta / v1 * (-self.m.area * s[1] + self.flow(s[2], u[0])),
            beta / v2 * (self.m.area * s[1] + self.flow(s[3], u[1])),
        ]
    }

    fn rk4(&self, s: &[f64; 4], u: [f64; 2], h: f64) -> [f64; 4] {
        let add = |a: &[f64; 4], k: &[f64; 4], w: f64| -> [f64; 4] {
            std::array::from_fn(|i| a[i] + w * k[i])
        };
        let k1 = self.derivative(s, u);
        let k2 = self.derivative(&add(s, &k1, h / 2.0), u);
        let k3 = self.derivative(&add(s, &k2, h / 2.0), u);
        let k4 = self.derivative(&add(s, &k3, h), u);
        std::array::from_fn(|i| s[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
    }

    fn estimate(&self, s: &[f64; 4]) -> Estimate {
        Estimate {
            y: s[0],
            v: s[1],
            a: self.acceleration(s),
            p1: s[2],
            p2: s[3],
        }
    }
}

/// One plant instant (every integration step).
struct Point {
    t: f64,
    y: f64,
    p1: f64,
    p2: f64,
}

/// Closed loop: law sampled every `sample` s on exact states (and the exact
/// acceleration), commands saturated and held. Starts at rest at y = 0 with
/// P1 = `p1_start` and the plant's static pressure difference M g / A.
fn run(law: &mut dyn Law, plant_mass: f64, p1_start: f64, sample: f64) -> Vec<Point> {
    let plant = Plant {
        m: model(plant_mass),
    };
    let mut s = [0.0, 0.0, p1_start, p1_start - plant_mass * GRAVITY / AREA];
    let mut trace = Vec::new();
    let samples = (T_END / sample).round() as usize;
    let substeps = (sample / DT).round() as usize;
    for k in 0..samples {
        let t_k = k as f64 * sample;
        let u = law
            .commands(t_k, &reference(t_k), &plant.estimate(&s), sample)
            .map(|u| u.clamp(-COMMAND_LIMIT, COMMAND_LIMIT));
        for j in 0..substeps {
            s = plant.rk4(&s, u, DT);
            assert!(s.iter().all(|x| x.is_finite()), "plant diverged at {t_k}");
            trace.push(Point {
                t: t_k + (j + 1) as f64 * DT,
                y: s[0],
                p1: s[2],
                p2: s[3],
            });
        }
    }
    trace
}

struct Figures {
    /// max |y - y_d| from the start of the move to the static window (m)
    max_error: f64,
    /// mean of y - y_d over the static window (m), and its largest magnitude
    static_error: f64,
    static_max: f64,
}

fn figures(trace: &[Point]) -> Figures {
    let err = |p: &Point| p.y - position_reference(p.t)[0];
    let max_error = trace
        .iter()
        .filter(|p| p.t >= T_START && p.t < T_STATIC)
        .map(|p| err(p).abs())
        .fold(0.0, f64::max);
    let window: Vec<f64> = trace.iter().filter(|p| p.t >= T_STATIC).map(err).collect();
    Figures {
        max_error,
        static_error: window.iter().sum::<f64>() / window.len() as f64,
        static_max: window.iter().map(|e| e.abs()).fold(0.0, f64::max),
    }
}

fn max_deviation(trace: &[Point], from: f64, to: f64, value: impl Fn(&Point) -> f64) -> f64 {
    trace
        .iter()
        .filter(|p| p.t >= from && p.t < to)
        .map(|p| (value(p) - P_REF_THESIS).abs())
        .fold(0.0, f64::max)
}

fn report(name: &str, f: &Figures) {
    eprintln!(
        "{name}: max error {:.1} um, static error mean {:.2} um (max {:.2} um)",
        f.max_error * 1e6,
        f.static_error * 1e6,
        f.static_max * 1e6
    );
}

/// (5.31)-(5.35) and (5.55)-(5.58): in continuous time, without saturation and with
/// the model exact, each law imposes the printed error dynamics. Checked by central
/// differences of the errors along the closed-loop vector field, at a state away
/// from the reference so that every term is exercised and both flow directions occur.
fn check_error_dynamics(
    step: &dyn Fn(&Reference, &Estimate) -> Step,
    expected: &dyn Fn(&[f64; 4]) -> [f64; 4],
    scale: [f64; 4],
    s: [f64; 4],
) {
    let plant = Plant { m: model(MASS) };
    let t = T_START + 0.4 * DURATION;
    let r = reference(t);
    let here = step(&r, &plant.estimate(&s));
    assert!(
        here.u.iter().all(|u| u.abs() > 1e-3),
        "both valves must be active: {:?}",
        here.u
    );
    let ds = plant.derivative(&s, here.u);
    let h = 1e-8;
    let at = |w: f64| {
        let st: [f64; 4] = std::array::from_fn(|i| s[i] + w * h * ds[i]);
        step(&reference(t + w * h), &plant.estimate(&st)).e
    };
    let (ep, em) = (at(1.0), at(-1.0));
    let want = expected(&here.e);
    for i in 0..4 {
        let got = (ep[i] - em[i]) / (2.0 * h);
        assert!(
            (got - want[i]).abs() < 1e-4 * scale[i],
            "de{}/dt = {got:e}, law imposes {:e} (e = {:?})",
            i + 1,
            want[i],
            here.e
        );
    }
}

#[test]
fn y_lambda_imposes_its_error_dynamics() {
    let g = Gains::HIGH_Y_LAMBDA;
    let law = YLambda::new(model(MASS), g, LAMBDA_THESIS);
    let k = AREA / MASS;
    // (5.30) with (5.33): de3/dt = -c3 e3 - A/M e2, de4/dt = -c4 e4 + A/M e2
    let expected = |e: &[f64; 4]| {
        [
            e[1] - g.c1 * e[0],
            k * (e[2] - e[3]) - g.c2 * e[1] - e[0],
            -g.c3 * e[2] - k * e[1],
            -g.c4 * e[3] + k * e[1],
        ]
    };
    let scale = [1.0, 100.0, 1e9, 1e9];
    for s in [[0.004, 0.03, 85e5, 78e5], [-0.002, -0.05, 60e5, 95e5]] {
        check_error_dynamics(&|r, x| law.step(r, x), &expected, scale, s);
    }
}

#[test]
fn p_y_imposes_its_error_dynamics() {
    let g = Gains::HIGH_P_Y;
    let law = PY::new(model(MASS), g);
    // (5.54) with (5.41), (5.57): de3/dt = -c3 e3 - e2, de4/dt = -c4 e4
    let expected = |e: &[f64; 4]| {
        [
            e[1] - g.c1 * e[0],
            e[2] - g.c2 * e[1] - e[0],
            -g.c3 * e[2] - e[1],
            -g.c4 * e[3],
        ]
    };
    let scale = [1.0, 100.0, 1e6, 1e9];
    for s in [[0.004, 0.03, 85e5, 78e5], [-0.002, -0.05, 70e5, 95e5]] {
        check_error_dynamics(&|r, x| law.step(r, x), &expected, scale, s);
    }
}

/// The brief's bounds: ~1 mm during the move, 50 um at rest.
const MAX_ERROR_BOUND: f64 = 1e-3;
const STATIC_BOUND: f64 = 50e-6;
/// Pressure bounds: section 5.5 reports P-Y within 5 bar in the transient and about
/// 1 bar at rest (AMESim, low gains); the control model as plant must do at least as
/// well, and the Y-lambda combination is what c3, c4 hold directly.
const PRESSURE_MOVE_BOUND: f64 = 5e5;
const PRESSURE_STATIC_BOUND: f64 = 1e5;
/// A sampling period at which the thesis's high gains are inside the sampled-data
/// stability region of the 5.8 kg control model (see `high_gains_at_1_khz`).
const FAST_SAMPLE: f64 = 0.5e-3;

#[derive(Clone, Copy)]
enum Kind {
    YLambda,
    PY,
}

/// Runs `kind` with `gains` on the nominal plant at period `sample`, prints and
/// checks position and pressure tracking.
fn check_tracking(kind: Kind, gains: Gains, sample: f64) {
    let (mut law, p1_start, name): (Box<dyn Law>, f64, &str) = match kind {
        Kind::YLambda => (
            Box::new(YLambda::new(model(MASS), gains, LAMBDA_THESIS)),
            P_REF_THESIS + LAMBDA_THESIS * MASS * GRAVITY / AREA,
            "Y-lambda",
        ),
        Kind::PY => (Box::new(PY::new(model(MASS), gains)), P_REF_THESIS, "P-Y"),
    };
    let trace = run(law.as_mut(), MASS, p1_start, sample);
    let f = figures(&trace);
    report(&format!("{name} {gains:?} T = {sample:e} s"), &f);
    // Y-lambda holds (1 - lambda) P1 + lambda P2 at P0 (5.15); P-Y holds P1 at P1d
    let pressure = |p: &Point| match kind {
        Kind::YLambda => (1.0 - LAMBDA_THESIS) * p.p1 + LAMBDA_THESIS * p.p2,
        Kind::PY => p.p1,
    };
    let during = max_deviation(&trace, T_START, T_START + DURATION, pressure);
    let after = max_deviation(&trace, T_STATIC, T_END, pressure);
    eprintln!(
        "{name}: pressure error max {:.3} bar during the move, {:.4} bar at rest",
        during / 1e5,
        after / 1e5
    );
    assert!(f.max_error < MAX_ERROR_BOUND, "max error {}", f.max_error);
    assert!(f.static_max < STATIC_BOUND, "static error {}", f.static_max);
    assert!(during < PRESSURE_MOVE_BOUND, "{during}");
    assert!(after < PRESSURE_STATIC_BOUND, "{after}");
}

#[test]
fn y_lambda_low_gains_track_at_1_khz() {
    check_tracking(Kind::YLambda, Gains::LOW, SAMPLE);
}

#[test]
fn p_y_low_gains_track_at_1_khz() {
    check_tracking(Kind::PY, Gains::LOW, SAMPLE);
}

#[test]
fn y_lambda_high_gains_track_at_2_khz() {
    check_tracking(Kind::YLambda, Gains::HIGH_Y_LAMBDA, FAST_SAMPLE);
}

#[test]
fn p_y_high_gains_track_at_2_khz() {
    check_tracking(Kind::PY, Gains::HIGH_P_Y, FAST_SAMPLE);
}

/// The brief's check at the bench's 1 kHz. Not reproduced: on the 5.8 kg control
/// model with exact states, both laws fall into a period-2 (500 Hz) limit cycle with
/// saturated commands (Y-lambda: static error up to 440 um, pressures +-35 bar; P-Y:
/// up to 340 um). The error modes these gains place near c1 + c2 + c3 = 1.9-2.0e3 1/s,
/// and the 292 Hz hydraulic mode (omega T = 1.8) that the law cancels only at the
/// sample instants, are at the edge of what a 1 ms hold allows; the same gains are
/// fine at 2 kHz and, at 1 kHz, once the moving mass is ~12 kg (the bench's real
/// moving mass includes ~3.4 kg of oil, Table 3.4, which lowers that mode).
#[test]
#[ignore = "thesis high gains limit-cycle at 1 kHz on the control model (see doc)"]
fn high_gains_at_1_khz() {
    check_tracking(Kind::YLambda, Gains::HIGH_Y_LAMBDA, SAMPLE);
    check_tracking(Kind::PY, Gains::HIGH_P_Y, SAMPLE);
}

/// (7.9): static error of Y-lambda when the plant mass is M but the law uses M_hat.
fn y_lambda_static_error(g: Gains, m: f64, m_hat: f64) -> f64 {
    let (c1, c2, c3) = (g.c1, g.c2, g.c3);
    -m_hat * m_hat * (c1 + c2 + c3)
        / (2.0 * AREA * AREA * c1 + m_hat * m_hat * c3 * (c1 * c2 + 1.0))
        * (m / m_hat - 1.0)
        * GRAVITY
}

/// Table 7.1 in kind: the plant carries +20 kg the laws do not know about.
fn check_payload(y_lambda_gains: Gains, p_y_gains: Gains) {
    let plant_mass = MASS + PAYLOAD;
    let mut p_y = PY::new(model(MASS), p_y_gains);
    let f_py = figures(&run(&mut p_y, plant_mass, P_REF_THESIS, SAMPLE));
    report(&format!("P-Y {p_y_gains:?}, +20 kg unknown"), &f_py);
    let mut y_lambda = YLambda::new(model(MASS), y_lambda_gains, LAMBDA_THESIS);
    let p1_start = P_REF_THESIS + LAMBDA_THESIS * plant_mass * GRAVITY / AREA;
    let f_yl = figures(&run(&mut y_lambda, plant_mass, p1_start, SAMPLE));
    report(
        &format!("Y-lambda {y_lambda_gains:?}, +20 kg unknown"),
        &f_yl,
    );
    let predicted = y_lambda_static_error(y_lambda_gains, plant_mass, MASS);
    eprintln!("Y-lambda (7.9) predicts {:.1} um", predicted * 1e6);

    // P-Y: within a few um whatever the payload (Table 7.1: 3, 1, -2, -7 um), since
    // it feeds back the measured acceleration and gravity drops out of da/dt
    assert!(f_py.static_max < 5e-6, "{}", f_py.static_max);
    assert!(f_py.max_error < MAX_ERROR_BOUND, "{}", f_py.max_error);
    // Y-lambda: alpha1 (5.26) carries M_hat g, so it settles where (7.9) says
    assert!(
        (f_yl.static_error - predicted).abs() < 0.05 * predicted.abs(),
        "{} vs {}",
        f_yl.static_error,
        predicted
    );
    assert!(f_yl.static_error.abs() > 10.0 * f_py.static_max.max(1e-6));
}

#[test]
fn payload_p_y_invariant_y_lambda_offset_high_gains() {
    check_payload(Gains::HIGH_Y_LAMBDA, Gains::HIGH_P_Y);
}

#[test]
fn payload_p_y_invariant_y_lambda_offset_low_gains() {
    check_payload(Gains::LOW, Gains::LOW);
}
