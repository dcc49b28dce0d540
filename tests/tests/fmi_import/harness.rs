//! What every FMU test shares: finding the packaged FMUs, capturing their log messages,
//! importing an FMU with the checks of its model description, and `Sim`, a
//! Co-Simulation instance driven through the importer.

use std::collections::{HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::{Mutex, Once};

use fmi::fmi2::import::Fmi2Import;
use fmi::fmi2::instance::{CoSimulation as _, Common, InstanceCS};
use fmi::fmi2::schema::{Causality, ScalarVariableElement};
use fmi::fmi2::{Fmi2Error, Fmi2Res};
use fmi::traits::{FmiImport as _, FmiStatus as _};

pub const BUILD_HINT: &str = "build and package them first: `cargo build --release --workspace && \
     ./target/release/hbench fmu --out target/fmu --force` (or run `bash tools/test.sh`), \
     or point HB_FMU_DIR at a directory holding them";

pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("the test crate lives inside the workspace")
        .to_path_buf()
}

/// The directory holding the packaged FMUs; fails with the command that makes them.
pub fn fmu_dir() -> PathBuf {
    let dir = match std::env::var_os("HB_FMU_DIR") {
        Some(d) if Path::new(&d).is_absolute() => PathBuf::from(d),
        Some(d) => workspace_root().join(d),
        None => workspace_root().join("target").join("fmu"),
    };
    assert!(
        dir.is_dir(),
        "no FMU directory at {}: {BUILD_HINT}",
        dir.display()
    );
    dir
}

// ---------------------------------------------------------------------------------------
// The FMUs' log messages: fmi-sys's logger callback formats them and passes them to the
// `log` facade with the instance name as target. Kept to show on failure and to check
// that an FMU's message reaches the host.

pub static RECORDS: Mutex<Vec<(String, log::Level, String)>> = Mutex::new(Vec::new());

pub struct Capture;

impl log::Log for Capture {
    fn enabled(&self, _: &log::Metadata) -> bool {
        true
    }
    fn log(&self, r: &log::Record) {
        let msg = r.args().to_string();
        eprintln!("[{}] {}: {msg}", r.target(), r.level());
        RECORDS.lock().unwrap_or_else(|e| e.into_inner()).push((
            r.target().to_string(),
            r.level(),
            msg,
        ));
    }
    fn flush(&self) {}
}

pub fn capture_logs() {
    static INIT: Once = Once::new();
    INIT.call_once(|| {
        if log::set_logger(&Capture).is_ok() {
            // the importer's own debug/trace chatter stays out; the FMU callback's records
            // are handed to the logger directly, whatever their level
            log::set_max_level(log::LevelFilter::Warn);
        }
    });
}

pub fn messages_of(instance: &str) -> Vec<(log::Level, String)> {
    RECORDS
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .iter()
        .filter(|(t, _, _)| t == instance)
        .map(|(_, l, m)| (*l, m.clone()))
        .collect()
}

// ---------------------------------------------------------------------------------------
// Import and model-description checks

/// Import `<id>.fmu` and check what the importer parsed: FMI version, Co-Simulation
/// element and capabilities, default experiment, every ScalarVariable of the XML (unique
/// names, no aliases), the named inputs and outputs (Real, right causality) and
/// ModelStructure/Outputs.
pub fn import(id: &str, inputs: &[&str], outputs: &[&str]) -> Fmi2Import {
    capture_logs();
    let path = fmu_dir().join(format!("{id}.fmu"));
    assert!(
        path.is_file(),
        "{} is missing: {BUILD_HINT}",
        path.display()
    );
    let import: Fmi2Import = fmi::import::from_path(&path)
        .unwrap_or_else(|e| panic!("fmi::import::from_path({}) failed: {e}", path.display()));
    let md = import.model_description();
    assert_eq!(md.fmi_version, "2.0", "{id}: fmiVersion");
    assert!(md.model_exchange.is_none(), "{id}: declares Model Exchange");
    let cs = md
        .co_simulation
        .as_ref()
        .unwrap_or_else(|| panic!("{id}: no CoSimulation element parsed"));
    assert_eq!(cs.model_identifier, id, "{id}: modelIdentifier");
    assert_eq!(cs.can_get_and_set_fmu_state, Some(true), "{id}");
    assert_eq!(cs.can_serialize_fmu_state, Some(true), "{id}");
    assert_eq!(
        cs.can_handle_variable_communication_step_size,
        Some(true),
        "{id}"
    );
    let de = md
        .default_experiment
        .as_ref()
        .unwrap_or_else(|| panic!("{id}: no DefaultExperiment parsed"));
    assert!(de.step_size.is_some_and(|h| h > 0.0), "{id}: stepSize");

    // every ScalarVariable of the XML parsed; names unique; no aliases (the HydroBench
    // FMUs give each variable its own value reference)
    let xml = std::fs::read_to_string(import.archive_path().join("modelDescription.xml"))
        .unwrap_or_else(|e| panic!("{id}: cannot read the extracted modelDescription.xml: {e}"));
    assert_eq!(
        md.num_variables(),
        xml.matches("<ScalarVariable ").count(),
        "{id}: number of variables parsed"
    );
    assert!(
        md.model_name.starts_with("HydroBench."),
        "{id}: modelName {}",
        md.model_name
    );
    assert!(!md.guid.is_empty(), "{id}: empty GUID");
    let mut names = HashSet::new();
    let mut refs = HashSet::new();
    for v in md.get_model_variables() {
        assert!(
            names.insert(v.name.as_str()),
            "{id}: {} declared twice",
            v.name
        );
        let base = std::mem::discriminant(&v.elem);
        assert!(
            refs.insert((base, v.value_reference)),
            "{id}: value reference {} of {} used twice",
            v.value_reference,
            v.name
        );
    }

    // the named interface
    for (names, causality) in [(inputs, Causality::Input), (outputs, Causality::Output)] {
        for &n in names {
            let v = md
                .model_variable_by_name(n)
                .unwrap_or_else(|e| panic!("{id}: {e}"));
            assert_eq!(v.causality, causality, "{id}: causality of {n}");
            assert!(
                matches!(v.elem, ScalarVariableElement::Real(_)),
                "{id}: {n} is not Real"
            );
        }
    }

    // ModelStructure/Outputs lists exactly the outputs (1-based indices, in order)
    let listed: Vec<u32> = md
        .model_structure
        .outputs
        .unknowns
        .iter()
        .map(|u| u.index)
        .collect();
    let expected: Vec<u32> = md
        .get_model_variables()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Output)
        .map(|(k, _)| k as u32 + 1)
        .collect();
    assert_eq!(listed, expected, "{id}: ModelStructure/Outputs");
    import
}

// ---------------------------------------------------------------------------------------
// A Co-Simulation instance driven through the importer; every failing call panics with
// the call, its arguments and the status the importer returned.

pub struct Sim {
    pub id: &'static str,
    pub name: String,
    pub vrs: HashMap<String, u32>,
    pub t: f64,
    // dropped before the import: fmi2FreeInstance, then the extracted FMU goes
    pub inst: InstanceCS,
    pub _import: Rc<Fmi2Import>,
}

impl Sim {
    /// A new instance; instances made from one import share its loaded library.
    pub fn new(id: &'static str, import: impl Into<Rc<Fmi2Import>>, name: &str) -> Sim {
        let import = import.into();
        let vrs = import
            .model_description()
            .get_model_variables()
            .map(|v| (v.name.clone(), v.value_reference))
            .collect();
        let inst = import
            .instantiate_cs(name, false, true)
            .unwrap_or_else(|e| panic!("{id}: fmi2Instantiate({name}) failed: {e}"));
        assert_eq!(inst.get_version(), "2.0", "{id}: fmi2GetVersion");
        assert_eq!(
            inst.get_types_platform(),
            "default",
            "{id}: fmi2GetTypesPlatform"
        );
        Sim {
            id,
            name: name.to_string(),
            vrs,
            t: 0.0,
            inst,
            _import: import,
        }
    }

    pub fn vr(&self, name: &str) -> u32 {
        *self
            .vrs
            .get(name)
            .unwrap_or_else(|| panic!("{}: no variable {name}", self.id))
    }

    pub fn check(&self, call: &str, r: Result<Fmi2Res, Fmi2Error>) {
        match r {
            Ok(Fmi2Res::OK) => {}
            other => panic!(
                "{} ({}) at t = {}: {call} returned {other:?}; FMU messages: {:?}",
                self.id,
                self.name,
                self.t,
                messages_of(&self.name)
            ),
        }
    }

    /// Setup (start 0, tolerance 1e-6, no stop time), parameters, enter and exit
    /// initialization.
    pub fn initialize(&mut self, reals: &[(&str, f64)], ints: &[(&str, i32)]) {
        let r = self.inst.setup_experiment(Some(1e-6), 0.0, None);
        self.check("fmi2SetupExperiment(tol 1e-6, start 0)", r);
        self.set(reals);
        for &(n, k) in ints {
            let r = self.inst.set_integer(&[self.vr(n)], &[k]);
            self.check(&format!("fmi2SetInteger({n} = {k})"), r);
        }
        let r = Common::enter_initialization_mode(&mut self.inst);
        self.check("fmi2EnterInitializationMode", r);
        let r = Common::exit_initialization_mode(&mut self.inst);
        self.check("fmi2ExitInitializationMode", r);
    }

    pub fn set(&mut self, values: &[(&str, f64)]) {
        let vrs: Vec<u32> = values.iter().map(|(n, _)| self.vr(n)).collect();
        let xs: Vec<f64> = values.iter().map(|(_, x)| *x).collect();
        let r = self.inst.set_real(&vrs, &xs);
        self.check(&format!("fmi2SetReal({values:?})"), r);
    }

    pub fn get(&mut self, names: &[&str]) -> Vec<f64> {
        let vrs: Vec<u32> = names.iter().map(|n| self.vr(n)).collect();
        let mut xs = vec![f64::NAN; names.len()];
        let r = self.inst.get_real(&vrs, &mut xs);
        self.check(&format!("fmi2GetReal({names:?})"), r);
        for (n, x) in names.iter().zip(&xs) {
            assert!(x.is_finite(), "{}: {n} = {x} at t = {}", self.id, self.t);
        }
        xs
    }

    pub fn get1(&mut self, name: &str) -> f64 {
        self.get(&[name])[0]
    }

    pub fn step(&mut self, h: f64) {
        let r = self.inst.do_step(self.t, h, true);
        self.check(&format!("fmi2DoStep(t = {}, h = {h})", self.t), r);
        self.t += h;
    }

    /// `n` steps of `h`; the outputs `names` after each.
    pub fn run(&mut self, n: usize, h: f64, names: &[&str]) -> Vec<Vec<f64>> {
        (0..n)
            .map(|_| {
                self.step(h);
                self.get(names)
            })
            .collect()
    }

    /// Save the state, run `n` steps of `h`, restore and run them again, once from the
    /// saved state and once from its serialized bytes: both replays give the outputs
    /// `names` bit for bit, and the deserialized state serializes to the same bytes.
    pub fn check_rollback(&mut self, n: usize, h: f64, names: &[&str]) {
        let id = self.id;
        let t0 = self.t;
        let saved = self
            .inst
            .get_fmu_state()
            .unwrap_or_else(|e| panic!("{id}: fmi2GetFMUstate returned {e:?}"));
        let first = self.run(n, h, names);

        let r = self.inst.set_fmu_state(&saved).ok();
        self.check("fmi2SetFMUstate", r);
        self.t = t0;
        let replay = self.run(n, h, names);
        assert_replays(id, "get/set FMU state", names, &first, &replay);

        let bytes = self
            .inst
            .serialize_fmu_state(&saved)
            .unwrap_or_else(|e| panic!("{id}: fmi2SerializeFMUstate returned {e:?}"));
        let restored = self
            .inst
            .deserialize_fmu_state(&bytes)
            .unwrap_or_else(|e| panic!("{id}: fmi2DeSerializeFMUstate returned {e:?}"));
        let again = self
            .inst
            .serialize_fmu_state(&restored)
            .unwrap_or_else(|e| panic!("{id}: fmi2SerializeFMUstate returned {e:?}"));
        if bytes != again {
            // show the first difference in the readable body (after the binary
            // header, whose length and checksum differ too) when there is one
            let body = |b: &[u8]| b.windows(2).position(|w| w == b"{\"").unwrap_or(0);
            let (a, b) = (&bytes[body(&bytes)..], &again[body(&again)..]);
            let k = a.iter().zip(b).position(|(x, y)| x != y).unwrap_or(0);
            let span = |s: &[u8]| {
                String::from_utf8_lossy(&s[k.saturating_sub(40)..(k + 24).min(s.len())])
                    .into_owned()
            };
            panic!(
                "{id}: fmi2DeSerializeFMUstate then fmi2SerializeFMUstate changes the \
                 state ({} bytes, then {}): {:?} became {:?}",
                bytes.len(),
                again.len(),
                span(a),
                span(b)
            );
        }
        let r = self.inst.set_fmu_state(&restored).ok();
        self.check("fmi2SetFMUstate(deserialized state)", r);
        self.t = t0;
        let replay = self.run(n, h, names);
        let how = "serialize/deserialize FMU state";
        assert_replays(id, how, names, &first, &replay);
    }

    pub fn terminate(mut self) {
        let r = Common::terminate(&mut self.inst);
        self.check("fmi2Terminate", r);
    }
}

/// `b` replays `a` bit for bit.
pub fn assert_replays(id: &str, how: &str, names: &[&str], a: &[Vec<f64>], b: &[Vec<f64>]) {
    for (k, (ra, rb)) in a.iter().zip(b).enumerate() {
        for (n, (x, y)) in names.iter().zip(ra.iter().zip(rb)) {
            assert!(
                x.to_bits() == y.to_bits(),
                "{id}: the rollback through {how} does not replay: {n} after step {} was \
                 {x:e}, now {y:e}",
                k + 1
            );
        }
    }
}

pub fn rel_close(x: f64, y: f64, rtol: f64) -> bool {
    (x - y).abs() <= rtol * y.abs().max(f64::MIN_POSITIVE)
}

/// Output `k` of a trajectory from [`Sim::run`].
pub fn column(traj: &[Vec<f64>], k: usize) -> Vec<f64> {
    traj.iter().map(|r| r[k]).collect()
}

pub fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}

/// The pair of two outputs, for the few tests that read exactly two.
pub fn pair(xs: Vec<f64>) -> (f64, f64) {
    match xs[..] {
        [a, b] => (a, b),
        _ => panic!("expected two values, got {xs:?}"),
    }
}
