//! `bench.fmu`: the whole plant (two servovalves, manifold, actuator) in one solver.

use std::path::Path;

use hbmodel::control::Measurement;
use hbmodel::effects::Effect;
use hbmodel::sensors::DelayLine;
use hbmodel::{Inputs, Outputs, Params, SimState, Simulation};
use modeldesc::DefaultExperiment;

use super::{
    effect_switches, load_params, registry_parameters, valve_model_code, valve_model_from,
    HasParams, VALVE_MODELS,
};
use super::{COMMAND_INPUT, FORCE_INPUT};
use crate::slave::{
    enum_parameter, integer_parameter, real_input, real_output, Model, ModelInfo, VarDef,
};

pub struct BenchFmu {
    params: Params,
    pub(crate) inputs: Inputs,
    sim: Option<Simulation>,
    pub(crate) out: Outputs,
    /// The acquisition's view of y, P1, P2 (delayed when `sensor_delay` is on).
    sensed: Option<DelayLine>,
    pub(crate) measured: Measurement,
    start_time: f64,
}

impl HasParams for BenchFmu {
    fn params(&self) -> &Params {
        &self.params
    }
    fn params_mut(&mut self) -> &mut Params {
        self.sim = None;
        self.sensed = None;
        &mut self.params
    }
}

/// The FMU's built-in parameters: the chapter-4 bench in mode 3.
pub fn default_params() -> Params {
    Params::thesis_bench(hbmodel::Mode::ThreeWay)
}

impl BenchFmu {
    fn sim(&mut self) -> Result<&mut Simulation, String> {
        if self.sim.is_none() {
            let mut sim = Simulation::new(&self.params).map_err(|e| e.to_string())?;
            let mut state = sim.state().clone();
            state.t = self.start_time;
            sim.set_state(state)?;
            self.sim = Some(sim);
        }
        let sim = self.sim.as_mut().ok_or("no simulation")?;
        sim.set_inputs(self.inputs);
        Ok(sim)
    }

    fn sensor_delay(&self) -> f64 {
        if self.params.has(Effect::SensorDelay) {
            self.params.sensors.delay
        } else {
            0.0
        }
    }

    /// Advance to t, recording the instants the delayed acquisition will read.
    fn advance(&mut self, t: f64) -> Result<(), String> {
        let delay = self.sensor_delay();
        let sim = self.sim()?;
        if delay == 0.0 {
            // the acquisition reads the present: no history to keep
            return sim.advance_to(t).map_err(|e| e.to_string());
        }
        let from = sim.time();
        let mut line = match self.sensed.take() {
            Some(line) => line,
            None => DelayLine::new(delay, from, Measurement::of(&self.sim()?.outputs())),
        };
        let result = (|| {
            if let Some(t_read) = line.read_instant_within(from, t) {
                let sim = self.sim()?;
                sim.advance_to(t_read).map_err(|e| e.to_string())?;
                line.record(t_read, Measurement::of(&sim.outputs()));
            }
            let sim = self.sim()?;
            sim.advance_to(t).map_err(|e| e.to_string())?;
            line.record(t, Measurement::of(&sim.outputs()));
            line.forget_before(from);
            Ok(())
        })();
        self.sensed = Some(line);
        result
    }
}

impl Model for BenchFmu {
    type Snapshot = (Params, SimState, Option<DelayLine>);

    fn info() -> ModelInfo {
        ModelInfo {
            model_name: "HydroBench.Bench",
            model_identifier: "bench",
            description: "Electro-hydraulic test bench (Xu 2013): two MOOG D765 servovalves, \
                          three-mode manifold and double-rod actuator in one stiff solver",
            default_experiment: DefaultExperiment {
                start_time: 0.0,
                stop_time: 0.2,
                tolerance: Some(1e-6),
                step_size: Some(1e-3),
            },
            equations: &[
                "(II.2) servovalve land flows; second-order spool with rate limit (valve_dynamics)",
                "(3.1)-(3.7) manifold passages C-R-I-C with abacus-based losses; (3.4) solenoid valves",
                "(4.1)-(4.2) chamber flow balances with internal and external leakage",
                "(4.4) piston motion with gravity, friction (4.5)-(4.13) and end stops",
                "(A.7)-(A.12) effective bulk modulus; (A.15)-(A.16) viscosity",
            ],
            parameters: Some(default_params()),
        }
    }

    fn variables() -> Vec<VarDef<Self>> {
        let d = default_params();
        let mut v = vec![
            real_input("u1", "Command of servovalve SV1", "V", 0.0, COMMAND_INPUT, |m: &Self| m.inputs.u1, |m, x| m.inputs.u1 = x),
            real_input("u2", "Command of servovalve SV2 (ignored in mode 1, where SV2 stays at null)", "V", 0.0, COMMAND_INPUT, |m: &Self| m.inputs.u2, |m, x| m.inputs.u2 = x),
            real_input("F_ext", "External force on the rod, opposing positive y", "N", 0.0, FORCE_INPUT, |m: &Self| m.inputs.f_ext, |m, x| m.inputs.f_ext = x),
            real_output("y", "Piston position from mid stroke (positive extends chamber 1)", "m", |m: &Self| m.out.y).depends_on(&[]),
            real_output("v", "Piston velocity", "m/s", |m: &Self| m.out.v).depends_on(&[]),
            real_output("a", "Piston acceleration", "m/s2", |m: &Self| m.out.a).depends_on(&["F_ext"]),
            real_output("P1", "Pressure in chamber 1 (absolute)", "Pa", |m: &Self| m.out.p1).depends_on(&[]),
            real_output("P2", "Pressure in chamber 2 (absolute)", "Pa", |m: &Self| m.out.p2).depends_on(&[]),
            real_output("P_A1", "Pressure at port A of SV1", "Pa", |m: &Self| m.out.p_a1).depends_on(&[]),
            real_output("P_B1", "Pressure at port B of SV1", "Pa", |m: &Self| m.out.p_b1).depends_on(&[]),
            real_output("P_A2", "Pressure at port A of SV2", "Pa", |m: &Self| m.out.p_a2).depends_on(&[]),
            real_output("P_B2", "Pressure at port B of SV2", "Pa", |m: &Self| m.out.p_b2).depends_on(&[]),
            real_output("Q1", "Flow from the manifold into chamber 1", "m3/s", |m: &Self| m.out.q1).depends_on(&["u1", "u2"]),
            real_output("Q2", "Flow from the manifold into chamber 2", "m3/s", |m: &Self| m.out.q2).depends_on(&["u1", "u2"]),
            real_output("Q_supply", "Flow both servovalves draw from the supply (pilot stages included); supply power = supply_pressure * Q_supply", "m3/s", |m: &Self| m.out.q_supply).depends_on(&["u1", "u2"]),
            real_output("x_s1", "Spool position of SV1", "m", |m: &Self| m.out.x_s1).depends_on(&["u1"]),
            real_output("x_s2", "Spool position of SV2", "m", |m: &Self| m.out.x_s2).depends_on(&["u2"]),
            real_output("y_meas", "Position as the acquisition samples it: y delayed by sensors.delay when effect.sensor_delay is on", "m", |m: &Self| m.measured.y).depends_on(&[]),
            real_output("P1_meas", "Chamber-1 pressure as the acquisition samples it (delayed like y_meas)", "Pa", |m: &Self| m.measured.p1).depends_on(&[]),
            real_output("P2_meas", "Chamber-2 pressure as the acquisition samples it (delayed like y_meas)", "Pa", |m: &Self| m.measured.p2).depends_on(&[]),
            integer_parameter("mode", "Working mode: 1 = SV1 4-way, 2 = both 4-way in parallel, 3 = each 3-way on one chamber", d.mode.number() as i32, 1, 3, |m: &Self| m.params.mode.number() as i32, |m, k| {
                if let Ok(mode) = hbmodel::Mode::try_from(k as u8) {
                    m.params_mut().mode = mode;
                }
            }),
        ];
        v.push(enum_parameter(
            "sv1.model",
            "Servovalve model of SV1",
            &VALVE_MODELS,
            1,
            |m: &Self| valve_model_code(m.params.sv1.model),
            |m, k| m.params_mut().sv1.model = valve_model_from(k),
        ));
        v.push(enum_parameter(
            "sv2.model",
            "Servovalve model of SV2 (used when valve_asymmetry is on; SV1's otherwise)",
            &VALVE_MODELS,
            1,
            |m: &Self| valve_model_code(m.params.sv2.model),
            |m, k| m.params_mut().sv2.model = valve_model_from(k),
        ));
        v.extend(effect_switches(&Effect::ALL, &d));
        v.extend(registry_parameters(|_| true, str::to_string));
        v.extend(super::fixed_step_parameter());
        v
    }

    fn instantiate(resources: Option<&Path>) -> Result<Self, String> {
        let params = load_params(resources, default_params())?;
        Ok(BenchFmu {
            params,
            inputs: Inputs::default(),
            sim: None,
            out: Outputs::default(),
            sensed: None,
            measured: Measurement::default(),
            start_time: 0.0,
        })
    }

    fn initialize(&mut self, start_time: f64) -> Result<(), String> {
        self.start_time = start_time;
        self.sim = None;
        self.sensed = None;
        self.refresh()
    }

    fn refresh(&mut self) -> Result<(), String> {
        let sim = self.sim()?;
        let (out, t) = (sim.outputs(), sim.time());
        self.out = out;
        self.measured = match &self.sensed {
            Some(line) => line.read(t),
            None => Measurement::of(&self.out),
        };
        Ok(())
    }

    fn do_step(&mut self, h: f64) -> Result<(), String> {
        let t = self.sim()?.time() + h;
        self.advance(t)
    }

    fn time(&self) -> f64 {
        self.sim.as_ref().map_or(self.start_time, |s| s.time())
    }

    fn snapshot(&self) -> Self::Snapshot {
        let state = match &self.sim {
            Some(s) => s.state().clone(),
            None => SimState {
                t: self.start_time,
                x: vec![],
                inputs: self.inputs,
                step: None,
                integrator: Default::default(),
            },
        };
        (self.params.clone(), state, self.sensed.clone())
    }

    fn restore(&mut self, (params, state, sensed): Self::Snapshot) -> Result<(), String> {
        self.params = params;
        self.sensed = sensed;
        self.inputs = state.inputs;
        self.start_time = state.t;
        self.sim = None;
        if !state.x.is_empty() {
            self.sim()?.set_state(state)?;
        }
        self.refresh()
    }

    fn relative_tolerance(&mut self) -> Option<&mut f64> {
        Some(&mut self.params_mut().solver.rtol)
    }
}
