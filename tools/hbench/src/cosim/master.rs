//! A fixed-step FMI 2.0 Co-Simulation master over the `fmi` crate (jondo2010/rust-fmi):
//! loads the FMUs of an SSP system through their C ABI, binds their parameters, wires
//! their connectors and steps them in Jacobi or Gauss-Seidel order.

use std::collections::HashMap;
use std::io::Cursor;
use std::rc::Rc;

use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation as _, Common, InstanceCS};
use fmi::fmi2::schema::ScalarVariableElement;
use fmi::traits::FmiImport as _;
use hbfmu::slave::Value;

use super::ssp::{Package, System};

/// How the components exchange values within one communication step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Order {
    /// All components read their inputs at t_n, then all step (parallelisable; every
    /// coupling lags one step).
    Jacobi,
    /// The components step one after another in the SSD's order, each with the
    /// outputs its predecessors reached at t_n+1.
    GaussSeidel,
}

impl Order {
    pub fn name(self) -> &'static str {
        match self {
            Order::Jacobi => "jacobi",
            Order::GaussSeidel => "gauss-seidel",
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Real,
    Integer,
    Boolean,
}

/// One loaded component instance.
struct Slave {
    name: String,
    vars: HashMap<String, (u32, Kind)>,
    t: f64,
    // dropped before the import: fmi2FreeInstance, then the library and extracted files
    inst: InstanceCS,
    _import: Rc<Fmi2Import>,
}

fn fmi_err(who: &str, call: &str, e: impl std::fmt::Debug) -> String {
    format!("{who}: {call} failed ({e:?})")
}

impl Slave {
    fn var(&self, name: &str) -> Result<(u32, Kind), String> {
        self.vars
            .get(name)
            .copied()
            .ok_or_else(|| format!("{}: the FMU has no variable {name}", self.name))
    }

    fn set(&mut self, name: &str, v: Value) -> Result<(), String> {
        let (vr, kind) = self.var(name)?;
        let r = match (kind, v) {
            (Kind::Real, Value::Real(x)) => self.inst.set_real(&[vr], &[x]),
            (Kind::Integer, Value::Integer(k)) => self.inst.set_integer(&[vr], &[k]),
            (Kind::Integer, Value::Real(x)) if x.fract() == 0.0 => {
                self.inst.set_integer(&[vr], &[x as i32])
            }
            (Kind::Boolean, Value::Boolean(b)) => self.inst.set_boolean(&[vr], &[b as i32]),
            (k, v) => return Err(format!("{}: {name} is {k:?}, given {v:?}", self.name)),
        };
        r.map(|_| ())
            .map_err(|e| fmi_err(&self.name, &format!("set {name} = {v:?}"), e))
    }

    fn get_reals(&mut self, vrs: &[u32], out: &mut [f64]) -> Result<(), String> {
        self.inst
            .get_real(vrs, out)
            .map(|_| ())
            .map_err(|e| fmi_err(&self.name, "fmi2GetReal", e))
    }

    fn set_reals(&mut self, vrs: &[u32], xs: &[f64]) -> Result<(), String> {
        self.inst
            .set_real(vrs, xs)
            .map(|_| ())
            .map_err(|e| fmi_err(&self.name, "fmi2SetReal", e))
    }

    fn step(&mut self, h: f64) -> Result<(), String> {
        self.inst.do_step(self.t, h, true).map_err(|e| {
            fmi_err(
                &self.name,
                &format!("fmi2DoStep(t = {}, h = {h})", self.t),
                e,
            )
        })?;
        self.t += h;
        Ok(())
    }
}

/// What one component reads before it steps: (source component, its output value
/// references) and where the values go (its own input value references).
struct Links {
    from: Vec<(usize, Vec<u32>, Vec<u32>)>,
}

/// A system of FMU instances ready to step.
pub struct Master {
    slaves: Vec<Slave>,
    links: Vec<Links>,
    /// Per component: None, stepped at the communication step; Some(T), a sampled
    /// component (the controller) stepped at its own period T, a multiple of the step.
    periods: Vec<Option<f64>>,
    pub t: f64,
}

impl Master {
    /// Load every component of `pkg`, apply its parameter bindings then `overrides`
    /// (component, parameter, value; a `*` component means every one that has it), and
    /// initialize the system at t = 0 with its inputs made consistent.
    pub fn new(pkg: &Package, overrides: &[(&str, &str, Value)]) -> Result<Master, String> {
        let sys = &pkg.system;
        let mut imports: HashMap<&str, Rc<Fmi2Import>> = HashMap::new();
        let mut slaves = Vec::new();
        for c in &sys.components {
            let import = match imports.get(c.source.as_str()) {
                Some(i) => i.clone(),
                None => {
                    let bytes = &pkg.fmus[&c.source];
                    let i: Fmi2Import = fmi::import::new(Cursor::new(bytes.as_slice()))
                        .map_err(|e| format!("{}: cannot import {}: {e}", c.name, c.source))?;
                    let i = Rc::new(i);
                    imports.insert(&c.source, i.clone());
                    i
                }
            };
            let vars = import
                .model_description()
                .get_model_variables()
                .map(|v| {
                    let kind = match v.elem {
                        ScalarVariableElement::Integer(_) | ScalarVariableElement::Enumeration => {
                            Kind::Integer
                        }
                        ScalarVariableElement::Boolean(_) => Kind::Boolean,
                        _ => Kind::Real,
                    };
                    (v.name.clone(), (v.value_reference, kind))
                })
                .collect();
            let inst = import
                .instantiate_cs(&c.name, false, true)
                .map_err(|e| format!("{}: fmi2Instantiate failed: {e}", c.name))?;
            let mut s = Slave {
                name: c.name.clone(),
                vars,
                t: 0.0,
                inst,
                _import: import,
            };
            for (n, v) in &c.parameters {
                s.set(n, *v)?;
            }
            for (comp, n, v) in overrides {
                if *comp == c.name || (*comp == "*" && s.vars.contains_key(*n)) {
                    s.set(n, *v)?;
                }
            }
            s.inst
                .setup_experiment(Some(1e-6), 0.0, None)
                .map_err(|e| fmi_err(&c.name, "fmi2SetupExperiment", e))?;
            Common::enter_initialization_mode(&mut s.inst)
                .map_err(|e| fmi_err(&c.name, "fmi2EnterInitializationMode", e))?;
            slaves.push(s);
        }
        let links = wire(sys, &slaves)?;
        let mut m = Master {
            periods: vec![None; slaves.len()],
            slaves,
            links,
            t: 0.0,
        };
        // consistent initial inputs: the couplings pass through at most three components
        // (actuator -> manifold -> valve -> manifold), so three sweeps settle them
        for _ in 0..3 {
            for k in 0..m.slaves.len() {
                m.pull(k)?;
            }
        }
        for s in &mut m.slaves {
            Common::exit_initialization_mode(&mut s.inst)
                .map_err(|e| fmi_err(&s.name, "fmi2ExitInitializationMode", e))?;
        }
        Ok(m)
    }

    /// Set component `k`'s connected inputs from its sources' current outputs.
    fn pull(&mut self, k: usize) -> Result<(), String> {
        let n = self.links[k].from.len();
        for j in 0..n {
            let (src, ref out_vrs, ref in_vrs) = self.links[k].from[j];
            let (out_vrs, in_vrs) = (out_vrs.clone(), in_vrs.clone());
            let mut xs = vec![0.0; out_vrs.len()];
            self.slaves[src].get_reals(&out_vrs, &mut xs)?;
            self.slaves[k].set_reals(&in_vrs, &xs)?;
        }
        Ok(())
    }

    /// Step component `name` at its own period (s) instead of the communication step
    /// (multi-rate: a sampled controller at 1 ms around a plant at 0.1 ms).
    pub fn sample_every(&mut self, name: &str, period: f64) -> Result<(), String> {
        let k = self
            .slaves
            .iter()
            .position(|s| s.name == name)
            .ok_or_else(|| format!("the system has no component {name}"))?;
        self.periods[k] = Some(period);
        Ok(())
    }

    /// Whether the system has a component `name`.
    pub fn has(&self, name: &str) -> bool {
        self.slaves.iter().any(|s| s.name == name)
    }

    /// Component index and value reference of `Element.variable`.
    fn locate(&self, name: &str) -> Result<(usize, u32), String> {
        let (element, var) = name
            .split_once('.')
            .ok_or_else(|| format!("{name}: name a variable as Element.variable"))?;
        let k = self
            .slaves
            .iter()
            .position(|s| s.name == element)
            .ok_or_else(|| format!("the system has no component {element}"))?;
        Ok((k, self.slaves[k].var(var)?.0))
    }

    /// Set the input `Element.variable` (one a connection does not drive).
    pub fn set_input(&mut self, name: &str, x: f64) -> Result<(), String> {
        let (k, vr) = self.locate(name)?;
        self.slaves[k].set_reals(&[vr], &[x])
    }

    /// The output `Element.variable`.
    pub fn output(&mut self, name: &str) -> Result<f64, String> {
        let (k, vr) = self.locate(name)?;
        let mut x = [0.0];
        self.slaves[k].get_reals(&[vr], &mut x)?;
        Ok(x[0])
    }

    /// One communication step of `h`.
    ///
    /// A sampled component whose period begins at t_n reads its inputs first: its
    /// outputs at t_n depend on them (a controller's command on the sample it just took),
    /// so the others, in either order, then read a command computed from the state at
    /// t_n, as a sampled controller on the real bench does. It steps once its period is
    /// over; in between its outputs hold (zero-order hold).
    pub fn step(&mut self, h: f64, order: Order) -> Result<(), String> {
        let eps = 1e-9 * h;
        let sampled: Vec<(usize, f64)> = (0..self.slaves.len())
            .filter_map(|k| self.periods[k].map(|p| (k, p)))
            .collect();
        for &(k, _) in &sampled {
            if (self.slaves[k].t - self.t).abs() < eps {
                self.pull(k)?;
            }
        }
        let plant: Vec<usize> = (0..self.slaves.len())
            .filter(|&k| self.periods[k].is_none())
            .collect();
        match order {
            Order::Jacobi => {
                // every input from the outputs at t_n before anyone moves
                for &k in &plant {
                    self.pull(k)?;
                }
                for &k in &plant {
                    self.slaves[k].step(h)?;
                }
            }
            Order::GaussSeidel => {
                for &k in &plant {
                    self.pull(k)?;
                    self.slaves[k].step(h)?;
                }
            }
        }
        self.t += h;
        for (k, period) in sampled {
            if self.slaves[k].t + period <= self.t + eps {
                self.slaves[k].step(period)?;
            }
        }
        Ok(())
    }
}

impl Drop for Master {
    fn drop(&mut self) {
        for s in &mut self.slaves {
            // a failed instance may refuse; nothing more to do then
            let _ = Common::terminate(&mut s.inst);
        }
    }
}

/// Resolve the SSD's connections into value references. Both ends must be components
/// (as libcosim requires): a master drives and reads `Element.variable` directly.
fn wire(sys: &System, slaves: &[Slave]) -> Result<Vec<Links>, String> {
    let index = |name: &str| {
        slaves
            .iter()
            .position(|s| s.name == name)
            .ok_or_else(|| format!("a connection names the unknown element {name}"))
    };
    let mut links: Vec<Links> = slaves.iter().map(|_| Links { from: vec![] }).collect();
    for c in &sys.connections {
        let (Some(a), Some(b)) = (&c.start.element, &c.end.element) else {
            return Err(format!(
                "the connection {} -> {} has a system-level end: connect components",
                c.start.connector, c.end.connector
            ));
        };
        let (ka, kb) = (index(a)?, index(b)?);
        let (out, _) = slaves[ka].var(&c.start.connector)?;
        let (inp, _) = slaves[kb].var(&c.end.connector)?;
        let from = &mut links[kb].from;
        match from.iter_mut().find(|(src, _, _)| *src == ka) {
            Some((_, o, i)) => {
                o.push(out);
                i.push(inp);
            }
            None => from.push((ka, vec![out], vec![inp])),
        }
    }
    Ok(links)
}
