//! Fitting a candidate effect's parameters to the measured data by Levenberg-Marquardt
//! (the `levenberg-marquardt` crate, the method the thesis used), within the registry's
//! physical bounds.
//!
//! The residuals are the differences between the simulated and the measured samples of
//! y, P1 and P2, each divided by its noise level estimated from the data, so that a model
//! explaining the data leaves residuals of RMS 1 (the noise floor).

use hbmodel::effects::param;
use hbmodel::Params;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Dyn, Owned};

use super::data::{Experiment, Measured};
use super::drive::simulate;
use super::effects::{Fitted, Hypothesis};

/// One record as the fits see it: measurement, experiment, noise per compared signal.
pub struct Record<'a> {
    pub measured: &'a Measured,
    pub experiment: &'a Experiment,
    /// (signal, noise standard deviation) of the compared signals present in the data.
    pub noise: Vec<(&'static str, f64)>,
}

/// Which samples a fit sees: all, or one of two interleaved halves (alternate blocks of
/// HELD_OUT_BLOCK), so that a candidate can be judged on samples it was not fitted on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    All,
    Fit,
    Judge,
}

/// Length of the interleaved blocks (s): several periods of the oil columns' resonances
/// (150-450 Hz), and short enough that each step's transient (about 50 ms) and each
/// stretch of a sweep fall into both halves. With 50 ms blocks a step's ringing fell
/// wholly into one half on the 0.65 s steps record, and a recalibration fitted without
/// it judged worse than the model it started from (measured).
pub const HELD_OUT_BLOCK: f64 = 0.02;

/// The data of one analysis: one or several records, fitted jointly.
pub struct Target<'a> {
    pub records: Vec<Record<'a>>,
}

/// Residual value given to a simulation that fails: far worse than any fit, so the
/// optimiser steps back, but finite.
const FAILED_RESIDUAL: f64 = 1e3;

impl Target<'_> {
    /// Noise-normalised residuals of a model over every record and compared signal (record
    /// by record, signal by signal, sample by sample); None if a simulation fails.
    pub fn residuals(&self, p: &Params) -> Option<DVector<f64>> {
        let mut r = Vec::with_capacity(self.len());
        for rec in &self.records {
            let sim = simulate(p, rec.experiment, rec.measured).ok()?;
            for (name, sigma) in &rec.noise {
                let (m, s) = (rec.measured.get(name)?, sim.get(name)?);
                r.extend(m.iter().zip(s).map(|(m, s)| (s - m) / sigma));
            }
        }
        r.iter()
            .all(|x| x.is_finite())
            .then(|| DVector::from_vec(r))
    }

    pub fn len(&self) -> usize {
        self.records
            .iter()
            .map(|r| r.measured.time.len() * r.noise.len())
            .sum()
    }

    /// 1 where a residual belongs to `part`, 0 elsewhere, aligned with `residuals`.
    pub fn mask(&self, part: Part) -> DVector<f64> {
        let mut w = Vec::with_capacity(self.len());
        for rec in &self.records {
            let block = (HELD_OUT_BLOCK / rec.measured.period()).round().max(1.0) as usize;
            for _ in &rec.noise {
                w.extend((0..rec.measured.time.len()).map(|k| {
                    let fit = (k / block).is_multiple_of(2);
                    match part {
                        Part::All => 1.0,
                        Part::Fit => f64::from(u8::from(fit)),
                        Part::Judge => f64::from(u8::from(!fit)),
                    }
                }));
            }
        }
        DVector::from_vec(w)
    }

    /// The residual vector cut into its (record, signal) series, for correlation estimates.
    pub fn series<'r>(&self, r: &'r DVector<f64>) -> Vec<&'r [f64]> {
        let mut out = Vec::new();
        let mut at = 0;
        for rec in &self.records {
            let n = rec.measured.time.len();
            for _ in &rec.noise {
                out.push(&r.as_slice()[at..at + n]);
                at += n;
            }
        }
        out
    }

    /// RMS of the normalised residuals: 1 at the noise floor.
    pub fn gap(&self, p: &Params) -> f64 {
        self.residuals(p).map_or(f64::INFINITY, |r| {
            (r.norm_squared() / r.len() as f64).sqrt()
        })
    }
}

/// A bounded parameter seen by the optimiser as an unbounded z: theta = lo + (hi - lo)
/// s(z), s the logistic, on a log scale for the log parameters.
struct Coordinate {
    fitted: Fitted,
    lo: f64,
    hi: f64,
}

impl Coordinate {
    fn new(f: &Fitted) -> Self {
        let spec = param(f.path).expect("candidates use registry parameters");
        let [mut lo, hi] = f.bounds.unwrap_or([spec.min, spec.max]);
        if f.log {
            // a log scale needs a positive floor: three decades under the plausible range
            lo = lo.max(f.plausible[0] * 1e-3);
        }
        Coordinate { fitted: *f, lo, hi }
    }

    fn scale(&self, v: f64) -> (f64, f64, f64) {
        if self.fitted.log {
            (self.lo.ln(), self.hi.ln(), v.max(self.lo).ln())
        } else {
            (self.lo, self.hi, v)
        }
    }

    fn value(&self, z: f64) -> f64 {
        let (a, b, _) = self.scale(self.lo);
        let w = a + (b - a) / (1.0 + (-z).exp());
        if self.fitted.log {
            w.exp()
        } else {
            w
        }
    }

    fn coordinate(&self, v: f64) -> f64 {
        let (a, b, w) = self.scale(v);
        let s = ((w - a) / (b - a)).clamp(1e-6, 1.0 - 1e-6);
        (s / (1.0 - s)).ln()
    }
}

struct Problem<'a> {
    target: &'a Target<'a>,
    /// 1 on the residuals the fit sees, 0 on those held out.
    mask: DVector<f64>,
    base: Params,
    coords: Vec<Coordinate>,
    z: DVector<f64>,
    r: DVector<f64>,
}

impl Problem<'_> {
    fn params_at(&self, z: &DVector<f64>) -> Params {
        let mut p = self.base.clone();
        for (c, zi) in self.coords.iter().zip(z.iter()) {
            param(c.fitted.path)
                .expect("registered")
                .set(&mut p, c.value(*zi));
        }
        p
    }

    fn eval(&self, z: &DVector<f64>) -> DVector<f64> {
        let n = self.target.len();
        self.target
            .residuals(&self.params_at(z))
            .unwrap_or_else(|| DVector::from_element(n, FAILED_RESIDUAL))
            .component_mul(&self.mask)
    }
}

/// Finite-difference step in the unbounded coordinate: about 1 % of a parameter's range
/// near the middle, large enough to rise above the integrator's tolerance.
const FD_STEP: f64 = 0.05;

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ParameterStorage = Owned<f64, Dyn>;
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;

    fn set_params(&mut self, z: &DVector<f64>) {
        self.z = z.clone();
        self.r = self.eval(&z.clone());
    }

    fn params(&self) -> DVector<f64> {
        self.z.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        Some(self.r.clone())
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        // the trait gives &self; the columns are independent simulations
        let mut j = DMatrix::zeros(self.r.len(), self.z.len());
        for k in 0..self.z.len() {
            let mut z = self.z.clone();
            z[k] += FD_STEP;
            j.set_column(k, &((self.eval(&z) - &self.r) / FD_STEP));
        }
        Some(j)
    }
}

/// A hypothesis fitted to the data.
#[derive(Debug, Clone)]
pub struct Fit {
    pub hypothesis: Hypothesis,
    pub params: Params,
    /// (registry path, fitted value)
    pub values: Vec<(&'static str, f64)>,
    /// RMS of the normalised residuals over the part it saw.
    pub gap: f64,
    /// Every residual of the fitted model (seen or held out); None if it failed.
    pub residuals: Option<DVector<f64>>,
}

/// Points of the first parameter's plausible range tried before the optimiser starts: the
/// residual is far from quadratic in a resonance's position, so a local method needs a
/// start in the right basin.
const SCREEN_POINTS: usize = 5;
/// Optimiser budget (the crate's patience: evaluations per parameter).
const PATIENCE: usize = 8;

/// Switch the hypothesis's effect on in `base` (with what it requires) and fit its
/// parameters on `part` of the data, together with `carried`: the parameters of the
/// effects added before, refitted jointly so that an earlier effect that took up part of
/// this one's signature gives it back. `start` (one value per fitted parameter) skips
/// the screening: a refit from a fit on part of the data.
pub fn fit(
    target: &Target,
    base: &Params,
    h: &Hypothesis,
    carried: &[Fitted],
    part: Part,
    start: Option<&[f64]>,
) -> Fit {
    let mut first_params = base.clone();
    if let Some(e) = h.effect {
        first_params.effects.set(e, true);
        for &needed in e.spec().requires {
            first_params.effects.set(needed, true);
        }
    }
    let coords: Vec<Coordinate> = h
        .fitted
        .iter()
        .chain(
            carried
                .iter()
                .filter(|c| !h.fitted.iter().any(|f| f.path == c.path)),
        )
        .map(Coordinate::new)
        .collect();
    let mut problem = Problem {
        target,
        mask: target.mask(part),
        base: first_params,
        z: DVector::zeros(coords.len()),
        r: DVector::zeros(0),
        coords,
    };
    let defaults: Vec<f64> = problem
        .coords
        .iter()
        .map(|c| {
            let v = param(c.fitted.path).expect("registered").get(&problem.base);
            c.coordinate(if c.fitted.log { v.max(c.lo) } else { v })
        })
        .collect();
    let z0 = match start {
        Some(values) => DVector::from_iterator(
            problem.coords.len(),
            problem
                .coords
                .iter()
                .zip(values.iter().chain(std::iter::repeat(&f64::NAN)))
                .zip(&defaults)
                .map(|((c, v), d)| if v.is_finite() { c.coordinate(*v) } else { *d }),
        ),
        None => screen(&problem, &defaults),
    };
    problem.set_params(&z0);
    let (problem, _report) = LevenbergMarquardt::new()
        .with_patience(PATIENCE)
        .minimize(problem);
    let chi2 = problem.r.norm_squared();
    let seen = problem.mask.sum().max(1.0);
    let params = problem.params_at(&problem.z);
    let values = problem
        .coords
        .iter()
        .zip(problem.z.iter())
        .map(|(c, z)| (c.fitted.path, c.value(*z)))
        .collect();
    let residuals = if part == Part::All {
        Some(problem.r.clone())
    } else {
        target.residuals(&params)
    };
    Fit {
        hypothesis: h.clone(),
        gap: (chi2 / seen).sqrt(),
        params,
        values,
        residuals,
    }
}

/// The start of the optimiser: the current values, and the first parameter screened over
/// its plausible range (both signs for an offset), the others at their current values.
fn screen(problem: &Problem, defaults: &[f64]) -> DVector<f64> {
    let first = problem.coords[0].fitted;
    let current = DVector::from_vec(defaults.to_vec());
    let mut best = (problem.eval(&current).norm_squared(), current);
    let signs: &[f64] = if first.either_sign {
        &[1.0, -1.0]
    } else {
        &[1.0]
    };
    for sign in signs {
        for i in 0..SCREEN_POINTS {
            let u = i as f64 / (SCREEN_POINTS - 1) as f64;
            let [lo, hi] = first.plausible;
            let v = if first.log {
                lo * (hi / lo).powf(u)
            } else {
                lo + (hi - lo) * u
            };
            let mut z = DVector::from_vec(defaults.to_vec());
            z[0] = problem.coords[0].coordinate(sign * v);
            let chi2 = problem.eval(&z).norm_squared();
            if chi2 < best.0 {
                best = (chi2, z);
            }
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coordinates_stay_in_bounds_and_invert() {
        for f in super::super::effects::all()
            .iter()
            .flat_map(|c| c.fitted.clone())
        {
            let c = Coordinate::new(&f);
            for z in [-40.0, -3.0, 0.0, 2.0, 40.0] {
                let v = c.value(z);
                let slack = 1e-12 * (c.hi - c.lo);
                assert!(v >= c.lo - slack && v <= c.hi + slack, "{} {v}", f.path);
            }
            let mid = 0.5 * (f.plausible[0] + f.plausible[1]);
            let back = c.value(c.coordinate(mid));
            assert!(
                (back / mid - 1.0).abs() < 1e-9,
                "{}: {mid} -> {back}",
                f.path
            );
        }
    }
}
