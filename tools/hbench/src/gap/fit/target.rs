//! The records as the fits see them: each record's compared samples against its noise,
//! and the records of a joint analysis side by side (issue 14 item 3).

use hbmodel::Params;
use nalgebra::DVector;
use rayon::prelude::*;
use std::ops::Range;

use super::super::data::{Experiment, Measured};
use super::super::drive::simulate;
use super::super::evidence;

/// One record as the fits see it: measurement, experiment, noise per compared signal.
pub struct Record<'a> {
    pub measured: &'a Measured,
    pub experiment: &'a Experiment,
    /// (signal, noise standard deviation) of the compared signals present in the data.
    pub noise: Vec<(&'static str, f64)>,
    /// The samples compared, as ranges in time order (all of them but in a held-out
    /// check, `holdout`): the whole record is simulated, its states carry through the
    /// samples left out.
    pub window: Vec<Range<usize>>,
}

/// One contiguous range of samples as a record's compared samples (`Record::window`).
pub fn span(samples: Range<usize>) -> Vec<Range<usize>> {
    std::iter::once(samples).collect()
}

impl<'a> Record<'a> {
    /// The whole record.
    pub fn new(
        measured: &'a Measured,
        experiment: &'a Experiment,
        noise: Vec<(&'static str, f64)>,
    ) -> Self {
        let window = span(0..measured.time.len());
        Record {
            measured,
            experiment,
            noise,
            window,
        }
    }

    /// The same record compared on the samples of `window` only.
    pub fn part(&self, window: Vec<Range<usize>>) -> Self {
        Record {
            window,
            noise: self.noise.clone(),
            ..*self
        }
    }

    /// Samples per signal compared.
    pub fn samples(&self) -> usize {
        self.window.iter().map(ExactSizeIterator::len).sum()
    }

    /// Residual samples this record contributes.
    pub fn len(&self) -> usize {
        self.samples() * self.noise.len()
    }

    /// Lengths of its residual's series, one per compared signal (`Target::blocks`).
    pub fn blocks(&self) -> Vec<usize> {
        vec![self.samples(); self.noise.len()]
    }

    /// Append the record's noise-normalised residuals of `p`; None if the simulation fails.
    fn residuals_into(&self, p: &Params, r: &mut Vec<f64>) -> Option<()> {
        let sim = simulate(p, self.experiment, self.measured).ok()?;
        for (name, sigma) in &self.noise {
            let (m, s) = (self.measured.get(name)?, sim.get(name)?);
            for w in &self.window {
                let (m, s) = (m.get(w.clone())?, s.get(w.clone())?);
                r.extend(m.iter().zip(s).map(|(m, s)| (s - m) / sigma));
            }
        }
        Some(())
    }
}

/// The data as the fits see it: one or several records (issue 14 item 3: a sweep and
/// steps of the same bench), fitted jointly. Their normalised residuals are concatenated;
/// how the records weigh against each other is `variance`.
pub struct Target<'a> {
    pub records: Vec<Record<'a>>,
    pub variance: Variance,
}

/// How a joint analysis weighs its records against each other (issue 14 item 3).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Variance {
    /// One chi-square over all records, each sample against its own record's noise: a
    /// record the model is further from weighs more.
    #[default]
    Pooled,
    /// Each record's residual variance its own: a fit weighs each record by its misfit
    /// under the model before it (`Problem::weighed`) and a candidate's score sums each
    /// record's relative drop in its own independent samples (`evidence::Misfit`).
    /// Measured in session 58 (docs/gap.md): on the Rust bench's steps + chirp (seed 2,
    /// form error) it names the viscous friction the pooled analysis missed; on the
    /// peer's (seed 1) it misses the manifold volume the pooled analysis names, at 4.5
    /// times the cost. Not the default until a study says it is better. Session 59: with
    /// the fits unweighted the own scores name what the pooled ones do on three of the
    /// four cases that differ; the weights make the gains and the losses.
    Own,
}

impl Target<'_> {
    /// Noise-normalised residuals of a model, record after record and signal after
    /// signal; None if a simulation fails.
    pub fn residuals(&self, p: &Params) -> Option<DVector<f64>> {
        // the records' simulations are independent (a sweep and steps side by side)
        let parts: Vec<Vec<f64>> = self
            .records
            .par_iter()
            .map(|record| {
                let mut r = Vec::with_capacity(record.len());
                record.residuals_into(p, &mut r).map(|()| r)
            })
            .collect::<Option<_>>()?;
        let r = parts.concat();
        r.iter()
            .all(|x| x.is_finite())
            .then(|| DVector::from_vec(r))
    }

    pub fn len(&self) -> usize {
        self.records.iter().map(Record::len).sum()
    }

    /// Lengths of the residual's series, one per signal of each record: the residual's
    /// correlation is estimated within each, never across a boundary.
    pub fn blocks(&self) -> Vec<usize> {
        self.records.iter().flat_map(Record::blocks).collect()
    }

    /// Each record beside its part of a residual `r` of `residuals` (records one after
    /// the other); None when `r` is not such a residual.
    pub fn parts<'r>(&self, r: &'r [f64]) -> Option<Vec<(&Record<'_>, &'r [f64])>> {
        if r.len() != self.len() {
            return None;
        }
        let mut rest = r;
        Some(
            self.records
                .iter()
                .map(|record| {
                    let (part, after) = rest.split_at(record.len());
                    rest = after;
                    (record, part)
                })
                .collect(),
        )
    }

    /// Each series' RMS in the residual `r` of `residuals`: each signal's gap, record after
    /// record (`blocks`' order); empty when `r` is not such a residual.
    pub fn block_gaps(&self, r: &DVector<f64>) -> Vec<f64> {
        if r.len() != self.len() {
            return Vec::new();
        }
        let mut at = 0;
        self.blocks()
            .into_iter()
            .map(|n| {
                let part = r.rows(at, n);
                at += n;
                (part.norm_squared() / n.max(1) as f64).sqrt()
            })
            .collect()
    }

    /// Each record's chi-square in the residual `r` of `residuals`; empty when `r` is not
    /// such a residual.
    /// Pooled (`Variance::Pooled`), the one chi-square of all.
    pub fn record_chi2(&self, r: &DVector<f64>) -> Vec<f64> {
        let Some(parts) = self.parts(r.as_slice()) else {
            return Vec::new();
        };
        if self.variance == Variance::Pooled {
            return vec![r.norm_squared()];
        }
        parts.iter().map(|(_, part)| chi2(part)).collect()
    }

    /// The misfit of `p` record by record (`evidence::Misfit`; pooled, one record of
    /// them all) and the residual's
    /// correlation time over all records (N / N_eff); None if a simulation fails.
    pub fn misfit(&self, p: &Params) -> Option<(evidence::Misfit, f64)> {
        let r = self.residuals(p)?;
        let records = self
            .parts(r.as_slice())?
            .into_iter()
            .map(|(record, part)| {
                let effective = evidence::effective_samples(part, &record.blocks()).0;
                (chi2(part), effective)
            })
            .collect();
        let mut misfit = evidence::Misfit { records };
        if self.variance == Variance::Pooled {
            misfit.records = vec![(misfit.chi2(), misfit.effective())];
        }
        let tau = r.len() as f64 / misfit.effective().max(f64::MIN_POSITIVE);
        Some((misfit, tau))
    }

    /// Each record's weight in a joint fit from `p`, the model before it: one over the
    /// record's gap there, at least its noise (`Problem::weights`). Empty (every weight 1)
    /// for one record, or when `p` cannot be simulated.
    pub(super) fn weights(&self, p: &Params) -> Vec<f64> {
        if self.records.len() < 2 || self.variance == Variance::Pooled {
            return Vec::new();
        }
        self.residuals(p).map_or_else(Vec::new, |r| {
            self.record_chi2(&r)
                .iter()
                .zip(&self.records)
                .map(|(chi2, record)| 1.0 / (chi2 / record.len().max(1) as f64).sqrt().max(1.0))
                .collect()
        })
    }

    /// RMS of the normalised residuals: 1 at the noise floor.
    pub fn gap(&self, p: &Params) -> f64 {
        self.residuals(p).map_or(f64::INFINITY, |r| {
            (r.norm_squared() / r.len() as f64).sqrt()
        })
    }
}

/// Sum of squares of normalised residuals.
pub fn chi2(r: &[f64]) -> f64 {
    r.iter().map(|x| x * x).sum()
}
